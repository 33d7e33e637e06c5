//! The surface line: the top of the pillar band as a sub-pixel straight line
//! `row = row0_px + slope · column` (the camera may be tilted).
//!
//! Method, on the background image (many frames averaged, so little noise):
//! 1. per column, the first bright-to-dark step going down (`B(z) − B(z+1)`
//!    a local maximum) of at least a fifth of the column's largest within
//!    the search rows: the band's top, even where a glossy strip's lower
//!    edge below it is the larger step;
//! 2. a sub-pixel row by fitting a blurred step to the step's flank: rows
//!    `z_s − w ..= z_s + 2` (the flat background above, the step, one row
//!    into the band) against `hi − (hi − lo)·A(z)`, with `A` the Gaussian-
//!    blurred unit step averaged over the pixel,
//!    `A(z) = σ·[IΦ((z + ½ − e)/σ) − IΦ((z − ½ − e)/σ)]`, `IΦ(u) = uΦ(u) + φ(u)`
//!    (Levenberg–Marquardt on `e, σ, hi, lo`). Where a strip's lower edge
//!    is resolved within 6 rows below the top (a rise, or a further drop of
//!    its own, of at least 4 % of the largest step: a pillar-top row
//!    darker than the band, a glossy strip brighter than it), the
//!    window reaches 3 rows past it and the model is two blurred steps with
//!    one σ ([`two_step_edge_row`]), the top one's row kept. It is exact for a blurred,
//!    area-sampled straight edge at any tilt (no pixel locking), and it looks
//!    only at the flank, so what lies inside the band — a darker or brighter
//!    top row of pillar tops seen edge-on, a glossy strip reflecting the
//!    backlight — moves it far less than a moment over the whole step does.
//!    The area (coverage-sum) row of the same step,
//!    `e_a = z_top − ½ + Σ (B − lo)/(hi − lo)` over `2w + 2` rows, is exact for
//!    a clean step too; where the band's top is structured the two disagree,
//!    and their median disagreement is kept as the line's edge-model error
//!    ([`SurfaceLine::model_err_px`]);
//! 3. a robust line through the column edges: Theil–Sen start (median of
//!    slopes between columns half the width apart, median intercept), then
//!    Tukey-weighted least squares with the scale from the MAD. Columns where
//!    the band's top is not the strongest step (channels, dust) are rejected.
//!
//! The uncertainty is that of the weighted least-squares line,
//! `σ̂²(XᵀWX)⁻¹`, with `σ̂²` the weighted residual variance.
//!
//! | file | what |
//! | --- | --- |
//! | `params` | [`SurfaceParams`], the fit's settings |
//! | `columns` | steps 1 and 2: [`column_edges`], the band's top in each column |
//! | `step` | the blurred-step model and its fits ([`step_edge_row`], [`two_step_edge_row`]) |
//! | `line` | step 3: [`fit_line`], [`fit_surface`] and the edge-model error |

mod columns;
mod line;
mod params;
mod step;

pub use super::types::SurfaceLine;
pub use columns::{
    column_edges, ColumnEdge, STRIP_STEP_FRACTION, TOP_STEP_FRACTION, WIDE_STEP_FWHM_ROWS,
    WIDE_STEP_SIGMA_PX,
};
pub use line::{fit_line, fit_surface, AREA_SYSTEMATIC_PX, FLANK_SYSTEMATIC_PX, STRUCTURED_TOP_PX};
pub use params::SurfaceParams;
pub use step::{step_edge_row, two_step_edge_row};

#[cfg(test)]
mod tests;
