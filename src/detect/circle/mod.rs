//! Circle fits to edge points: an algebraic start that is unbiased on short
//! arcs, then a robust geometric refinement with the centre's covariance.
//!
//! * [`hyper_fit`] — the "hyper" algebraic fit of Al-Sharadqah & Chernov
//!   (Electron. J. Statist. 3, 2009): the circle `A(x²+z²) + Bx + Cz + D = 0`
//!   minimising `aᵀMa` subject to `aᵀNa = 1` with `N = 2·N_Taubin − N_Pratt`.
//!   Its essential bias vanishes to second order, so it stays centred on short
//!   arcs where Kåsa's fit shrinks the circle. With centred data it reduces to
//!   the smallest non-negative root η of a quartic `F(η)` (derived at
//!   [`hyper_fit`]), found by Newton's method from η = 0; exact points give
//!   η = 0 exactly.
//! * [`fit_circle`] — geometric least squares on the orthogonal residuals
//!   `dᵢ = |pᵢ − c| − r` by damped Gauss–Newton (Levenberg–Marquardt), inside
//!   iteratively reweighted least squares: Huber weights first (convex, safe
//!   from a rough start), then Tukey's biweight (redescending: dust, glints,
//!   pillar edges and a mirror image get weight 0). The scale is
//!   1.4826·MAD of the residuals. With `hold_radius` only the centre is fitted.
//!
//! Covariance: the M-estimator sandwich `A⁻¹BA⁻¹·n/(n − p)` at the solution,
//! `A = Σ ψ'(dᵢ) jᵢjᵢᵀ`, `B = Σ ψ(dᵢ)² jᵢjᵢᵀ` (Huber 1967), `j` the gradient of the
//! residuals and `p` the number of fitted parameters — the asymptotic
//! covariance of a robust least-squares estimate (the plain `σ̂²(JᵀWJ)⁻¹`
//! understates it under Tukey weights); it assumes independent point errors.
//! Errors shared by all points along their radii (`radial_sigma_px`) are
//! added through the fit's response to a uniform radial shift.
//!
//! Speed: the passes over the points take four at a time (`Lanes`): with
//! AVX2 (chosen at run time) each step is one instruction on four `f64`
//! lanes, without it the same IEEE operations lane by lane, and the lane
//! sums are added in a fixed order, so both give the same bits.
//!
//! | file | what |
//! | --- | --- |
//! | `types` | [`Circle`], [`Covariance`], [`CircleFit`], [`FitOptions`] |
//! | `hyper` | [`hyper_fit`], the algebraic start |
//! | `fit` | [`fit_circle`], the robust geometric fit, and its [`FitScratch`] |
//! | `lanes` | the passes' four-lane arithmetic, portable and AVX2 |
//! | `spd` | small symmetric positive definite solves and the sandwich covariance |

// Small fixed-size matrix code reads best with explicit indices.
#![allow(clippy::needless_range_loop)]

mod fit;
mod hyper;
mod lanes;
mod spd;
mod types;

pub use fit::{fit_circle, FitScratch};
pub use hyper::hyper_fit;
pub(crate) use spd::solve_spd;
pub use types::{Circle, CircleFit, Covariance, FitOptions};

#[cfg(test)]
mod tests;
