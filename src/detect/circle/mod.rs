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

// Small fixed-size matrix code reads best with explicit indices.
#![allow(clippy::needless_range_loop)]

use super::types::EdgePoint;
use super::DetectError;

/// A circle in frame pixels (see the module convention in [`super`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Circle {
    /// Centre column.
    pub x_px: f64,
    /// Centre row (grows downward).
    pub z_px: f64,
    /// Radius.
    pub r_px: f64,
}

/// The covariance of a fit's parameters, in px²: the upper triangle of the
/// symmetric matrix, row by row (a track holds two fits a frame: 24 bytes
/// less each than the whole matrix).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Covariance {
    /// `(x, z, r)` fitted: `[xx, xz, xr, zz, zr, rr]`.
    Full([f64; 6]),
    /// Radius held: `(x, z)` only, `[xx, xz, zz]`.
    CentreOnly([f64; 3]),
}

impl Covariance {
    /// `(x, z, r)` from the whole matrix (its upper triangle).
    pub fn full(c: &[[f64; 3]; 3]) -> Self {
        Covariance::Full([c[0][0], c[0][1], c[0][2], c[1][1], c[1][2], c[2][2]])
    }
    /// `(x, z)` from the whole matrix (its upper triangle).
    pub fn centre_only(c: &[[f64; 2]; 2]) -> Self {
        Covariance::CentreOnly([c[0][0], c[0][1], c[1][1]])
    }
    /// Standard deviation of the centre column.
    pub fn sigma_x_px(&self) -> f64 {
        match self {
            Covariance::Full(c) => c[0].sqrt(),
            Covariance::CentreOnly(c) => c[0].sqrt(),
        }
    }
    /// Standard deviation of the centre row.
    pub fn sigma_z_px(&self) -> f64 {
        match self {
            Covariance::Full(c) => c[3].sqrt(),
            Covariance::CentreOnly(c) => c[2].sqrt(),
        }
    }
    /// Standard deviation of the radius; `None` when it was held.
    pub fn sigma_r_px(&self) -> Option<f64> {
        match self {
            Covariance::Full(c) => Some(c[5].sqrt()),
            Covariance::CentreOnly(_) => None,
        }
    }
}

/// The result of a robust circle fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CircleFit {
    /// Centre column (px).
    pub x_px: f64,
    /// Centre row (px, grows downward).
    pub z_px: f64,
    /// Radius (px); the held value when the radius was held.
    pub r_px: f64,
    /// Covariance of the fitted parameters (px²).
    pub cov: Covariance,
    /// RMS orthogonal residual of the inliers (px).
    pub residual_px: f64,
    /// Points given to the fit (the counts are 32-bit: a long movie's
    /// track holds two fits a frame).
    pub n_used: u32,
    /// Points with non-zero final weight.
    pub inliers: u32,
    /// IRLS iterations taken.
    pub iterations: u32,
    /// The residual scale of the last iteration (px): 1.4826·MAD, floored
    /// at `min_scale_px`, or the one given in [`FitOptions::scale_px`].
    pub scale_px: f64,
}

impl CircleFit {
    /// The fitted circle: centre and radius.
    pub fn circle(&self) -> Circle {
        Circle {
            x_px: self.x_px,
            z_px: self.z_px,
            r_px: self.r_px,
        }
    }
}

/// Settings of [`fit_circle`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// Hold the radius at this value and fit only the centre.
    pub hold_radius: Option<f64>,
    /// Huber iterations before switching to Tukey's biweight.
    pub huber_iterations: usize,
    /// Maximum IRLS iterations in all.
    pub max_iterations: usize,
    /// Tukey's tuning constant in units of the residual scale (4.685 gives
    /// 95 % efficiency for Gaussian errors).
    pub tukey_c: f64,
    /// Floor of the residual scale (px), so that noiseless points do not
    /// reject each other over rounding.
    pub min_scale_px: f64,
    /// Fewest inliers for a valid fit.
    pub min_points: usize,
    /// Iterations stop once no parameter moves by more than this (px). The
    /// default, 1e-4 px, stops within 5e-5 px of the converged fit on noisy
    /// short arcs (tested), ~1/100 of the centre's statistical error on
    /// rendered drops.
    pub tolerance_px: f64,
    /// Standard deviation (px) of an error shared by all points along their
    /// radii (e.g. from the sphere's level or the frame's gain). A free radius
    /// absorbs it; with the radius held it moves the centre, and its share
    /// `σ_b² v vᵀ` is added to the covariance, `v` the fit's response to a
    /// unit radial shift of every point.
    pub radial_sigma_px: f64,
    /// Use this residual scale (px) throughout instead of the residuals'
    /// MAD: for a refit of points whose scale is already known (the
    /// held-radius refit of a free fit's points).
    pub scale_px: Option<f64>,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            hold_radius: None,
            huber_iterations: 2,
            max_iterations: 30,
            tukey_c: 4.685,
            min_scale_px: 1e-3,
            min_points: 6,
            tolerance_px: 1e-4,
            radial_sigma_px: 0.0,
            scale_px: None,
        }
    }
}

/// Reusable buffers of [`fit_circle`], so a loop over frames allocates nothing.
#[derive(Debug, Default, Clone)]
pub struct FitScratch {
    /// Final weight of each point (0 = rejected), in the order given.
    pub weights: Vec<f64>,
    /// The points as columns (`x`, `z`, prior weight ≥ 0), padded to a
    /// multiple of [`LANES`] with weight-0 points at the origin.
    xs: Vec<f64>,
    zs: Vec<f64>,
    prior: Vec<f64>,
    /// Residuals and unit vectors of the last re-scaling iteration.
    residuals: Vec<f64>,
    ux: Vec<f64>,
    uz: Vec<f64>,
    work: Vec<f64>,
}

/// The hyper algebraic circle fit (Al-Sharadqah & Chernov 2009) of weighted
/// points; unbiased to second order in the noise, also on short arcs.
///
/// Derivation, for data centred on its weighted mean and scaled to unit RMS
/// distance: with `z = x² + y²` and moments `Mxx, Mxy, …`, the conditions
/// `(M − ηN)a = 0` eliminate `D = (2η − Mz)A` and give, with
/// `Δ(η) = (Mxx − η)(Myy − η) − Mxy²`,
/// `F(η) = [Mzz − (Mz + 2η)²]Δ(η) − Mxz²(Myy − η) − Myz²(Mxx − η) + 2MxzMyzMxy = 0`,
/// the centre `a = [Mxz(Myy − η) − MyzMxy] / 2Δ`, `b = [Myz(Mxx − η) − MxzMxy] / 2Δ`
/// and `r² = a² + b² + Mz − 2η`. `F(0) = det M ≥ 0`; Newton's method from 0
/// climbs to the smallest non-negative root.
pub fn hyper_fit(points: &[EdgePoint]) -> Result<Circle, DetectError> {
    const WHAT: &str = "hyper circle fit";
    let mut sw = 0.0;
    let (mut mx, mut mz) = (0.0, 0.0);
    for p in points.iter().filter(|p| p.weight > 0.0) {
        sw += p.weight;
        mx += p.weight * p.x_px;
        mz += p.weight * p.z_px;
    }
    let n = points.iter().filter(|p| p.weight > 0.0).count();
    if n < 3 {
        return Err(DetectError::TooFewPoints {
            what: WHAT,
            found: n,
            needed: 3,
        });
    }
    mx /= sw;
    mz /= sw;
    let mut s2 = 0.0;
    for p in points.iter().filter(|p| p.weight > 0.0) {
        s2 += p.weight * ((p.x_px - mx).powi(2) + (p.z_px - mz).powi(2));
    }
    let scale = (s2 / sw).sqrt();
    if !(scale.is_finite() && scale > 0.0) {
        return Err(DetectError::Degenerate {
            what: WHAT,
            reason: "all points coincide".into(),
        });
    }
    let (mut sxx, mut syy, mut sxy, mut sxz, mut syz, mut szz, mut sz) =
        (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for p in points.iter().filter(|p| p.weight > 0.0) {
        let x = (p.x_px - mx) / scale;
        let y = (p.z_px - mz) / scale;
        let z = x * x + y * y;
        let w = p.weight;
        sxx += w * x * x;
        syy += w * y * y;
        sxy += w * x * y;
        sxz += w * x * z;
        syz += w * y * z;
        szz += w * z * z;
        sz += w * z;
    }
    let (mxx, myy, mxy, mxz, myz, mzz, mz_) = (
        sxx / sw,
        syy / sw,
        sxy / sw,
        sxz / sw,
        syz / sw,
        szz / sw,
        sz / sw,
    );
    let f = |eta: f64| -> (f64, f64) {
        let delta = (mxx - eta) * (myy - eta) - mxy * mxy;
        let d_delta = 2.0 * eta - mxx - myy;
        let q = mz_ + 2.0 * eta;
        let g = mzz - q * q;
        let val =
            g * delta - mxz * mxz * (myy - eta) - myz * myz * (mxx - eta) + 2.0 * mxz * myz * mxy;
        let der = -4.0 * q * delta + g * d_delta + mxz * mxz + myz * myz;
        (val, der)
    };
    let mut eta = 0.0;
    for _ in 0..100 {
        let (val, der) = f(eta);
        if val == 0.0 || der == 0.0 {
            break;
        }
        let next = eta - val / der;
        if !next.is_finite() || next < 0.0 {
            break;
        }
        let done = (next - eta).abs() <= 1e-15 * next.abs().max(1e-300);
        eta = next;
        if done {
            break;
        }
    }
    let delta = (mxx - eta) * (myy - eta) - mxy * mxy;
    if delta.abs() < 1e-14 {
        return Err(DetectError::Degenerate {
            what: WHAT,
            reason: "the points are collinear".into(),
        });
    }
    let a = (mxz * (myy - eta) - myz * mxy) / (2.0 * delta);
    let b = (myz * (mxx - eta) - mxz * mxy) / (2.0 * delta);
    let r2 = a * a + b * b + mz_ - 2.0 * eta;
    if !(r2.is_finite() && r2 > 0.0) {
        return Err(DetectError::Degenerate {
            what: WHAT,
            reason: format!("radius² = {r2}"),
        });
    }
    Ok(Circle {
        x_px: mx + a * scale,
        z_px: mz + b * scale,
        r_px: r2.sqrt() * scale,
    })
}

/// Median of `v` (reordered in place); 0 for an empty slice.
fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f64::total_cmp);
    *m
}

/// Solve the symmetric positive definite system `A x = b` (small n) by
/// Cholesky; `None` when `A` is not positive definite.
pub(crate) fn solve_spd<const N: usize>(a: &[[f64; N]; N], b: &[f64; N]) -> Option<[f64; N]> {
    let mut l = [[0.0; N]; N];
    for i in 0..N {
        for j in 0..=i {
            let mut s = a[i][j];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            if i == j {
                if !(s > 0.0) {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    let mut y = [0.0; N];
    for i in 0..N {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i][k] * y[k];
        }
        y[i] = s / l[i][i];
    }
    let mut x = [0.0; N];
    for i in (0..N).rev() {
        let mut s = y[i];
        for k in i + 1..N {
            s -= l[k][i] * x[k];
        }
        x[i] = s / l[i][i];
    }
    Some(x)
}

/// Inverse of a symmetric positive definite matrix (n ≤ 3) by solving for the
/// unit vectors.
fn inverse_spd<const N: usize>(a: &[[f64; N]; N]) -> Option<[[f64; N]; N]> {
    let mut inv = [[0.0; N]; N];
    for j in 0..N {
        let mut e = [0.0; N];
        e[j] = 1.0;
        let col = solve_spd(a, &e)?;
        for i in 0..N {
            inv[i][j] = col[i];
        }
    }
    Some(inv)
}

/// The M-estimator ("sandwich") covariance `A⁻¹ B A⁻¹ · n/(n − p)` with
/// `A = Σ ψ'(d) j jᵀ` (given inverted) and `B = Σ ψ(d)² j jᵀ`, ψ(d) = w·d
/// (Huber 1967): honest under robust weights, where `σ̂²(JᵀWJ)⁻¹`
/// understates the spread.
fn sandwich<const N: usize>(
    a_inv: &[[f64; N]; N],
    b: &[[f64; N]; N],
    n: usize,
    p: usize,
) -> [[f64; N]; N] {
    let scale = n as f64 / (n as f64 - p as f64).max(1.0);
    let mut tmp = [[0.0; N]; N];
    for i in 0..N {
        for j in 0..N {
            tmp[i][j] = (0..N).map(|k| a_inv[i][k] * b[k][j]).sum();
        }
    }
    let mut out = [[0.0; N]; N];
    for i in 0..N {
        for j in 0..N {
            out[i][j] = scale * (0..N).map(|k| tmp[i][k] * a_inv[k][j]).sum::<f64>();
        }
    }
    out
}

/// Once an IRLS step moves no parameter by more than this (px), the
/// residual scale is held for the remaining iterations (one median less per
/// iteration). Raising it from 1e-3 to 1e-2, together with the looser stop
/// and the held refit's reuse of the free fit's scale, moved the centres of
/// the 30-drop rendered campaign by at most 0.0014 px and left its accuracy
/// table unchanged.
const FREEZE_SCALE_PX: f64 = 1e-2;

/// The sums of the covariance, taken once at the solution.
#[derive(Debug, Default, Clone, Copy)]
struct LastSums {
    /// `JᵀWJ`, the fallback when `bread` is not positive definite.
    jtj: [[f64; 3]; 3],
    /// `Σ ψ'(d) j jᵀ`: the outer parts of the sandwich covariance.
    bread: [[f64; 3]; 3],
    /// `Σ w² d² j jᵀ`: the middle of the sandwich covariance.
    meat: [[f64; 3]; 3],
    /// `Σ ψ'(d) j`: the estimating equations' response to a uniform radial shift.
    jtw1: [f64; 3],
    /// The plain `Σ d²` and count over points with w > 0.
    ss_unweighted: f64,
    n_in: usize,
}

/// Robust geometric circle fit to `points` (their `weight` multiplies the
/// robust weight), starting from `start` or, without one, from [`hyper_fit`].
///
/// IRLS: each iteration computes the residuals `dᵢ`, their scale
/// `s = max(1.4826·MAD, min_scale_px)` (held once a step moves less than
/// `FREEZE_SCALE_PX`, or given throughout by `opts.scale_px`) and
/// weights — Huber's `min(1, 1.345 s / |d|)` for the first
/// `huber_iterations`, then Tukey's
/// biweight `(1 − (d / (c s))²)²` for `|d| < c s`, else 0 — and takes one
/// Gauss–Newton step on the weighted normal equations (with a tiny
/// Levenberg damping, 1e-9 of the diagonal, for safety). Stops when no
/// parameter moves by more than `tolerance_px`. The cost is one pass over
/// the points per iteration (two, and a median, while the scale is
/// re-estimated), and one pass more at the solution for the covariance's
/// sums, with no allocation once `scratch` has grown. Final weights (at the
/// solution) are left in `scratch.weights`.
pub fn fit_circle(
    points: &[EdgePoint],
    start: Option<Circle>,
    opts: &FitOptions,
    scratch: &mut FitScratch,
) -> Result<CircleFit, DetectError> {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2, checked just above.
        return unsafe { fit_circle_avx2(points, start, opts, scratch) };
    }
    fit_circle_lanes::<F4>(points, start, opts, scratch)
}

/// [`fit_circle`] compiled with AVX2, its passes four points per
/// instruction ([`Y4`]). The same bits as the portable [`F4`] (tested).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn fit_circle_avx2(
    points: &[EdgePoint],
    start: Option<Circle>,
    opts: &FitOptions,
    scratch: &mut FitScratch,
) -> Result<CircleFit, DetectError> {
    fit_circle_lanes::<Y4>(points, start, opts, scratch)
}

#[inline(always)]
fn fit_circle_lanes<V: Lanes>(
    points: &[EdgePoint],
    start: Option<Circle>,
    opts: &FitOptions,
    scratch: &mut FitScratch,
) -> Result<CircleFit, DetectError> {
    const WHAT: &str = "robust circle fit";
    let n = points.len();
    let mut c = match start {
        Some(c) => c,
        None => hyper_fit(points)?,
    };
    if let Some(r) = opts.hold_radius {
        c.r_px = r;
    }
    let held = opts.hold_radius.is_some();
    scratch.load(points);
    let mut iterations = 0;
    let mut scale: Option<f64> = opts.scale_px.map(|s| s.max(opts.min_scale_px));
    let fixed_scale = scale.is_some();
    let mut last_step = f64::INFINITY;
    let mut huber = true;
    for it in 0..opts.max_iterations.max(1) {
        iterations = it + 1;
        // The scale follows the fit while it still moves by more than
        // `FREEZE_SCALE_PX`, then is held (one median less per iteration).
        huber = it < opts.huber_iterations;
        let rescale = !fixed_scale && (scale.is_none() || last_step > FREEZE_SCALE_PX || huber);
        if rescale {
            scratch.residuals_at::<V>(&c);
            scale = Some((1.4826 * median(&mut scratch.work)).max(opts.min_scale_px));
        }
        let rw = RobustWeight::new(scale.unwrap_or(opts.min_scale_px), opts);
        let s = &*scratch;
        let (jtj, jtd) = match (rescale, huber) {
            (true, true) => s.normal_equations::<V, true>(rw, |i| s.stored(i)),
            (true, false) => s.normal_equations::<V, false>(rw, |i| s.stored(i)),
            (false, true) => s.normal_equations::<V, true>(rw, |i| s.fresh(i, &c)),
            (false, false) => s.normal_equations::<V, false>(rw, |i| s.fresh(i, &c)),
        };
        let step = if held {
            let m2 = [[jtj[0][0], jtj[0][1]], [jtj[1][0], jtj[1][1]]];
            solve_spd(&m2, &[-jtd[0], -jtd[1]]).map(|s| [s[0], s[1], 0.0])
        } else {
            solve_spd(&jtj, &jtd.map(|v| -v))
        };
        let Some(step) = step.filter(|s| s.iter().all(|v| v.is_finite())) else {
            break;
        };
        c.x_px += step[0];
        c.z_px += step[1];
        c.r_px += step[2];
        let moved = step.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        last_step = moved;
        if !huber && moved < opts.tolerance_px {
            break;
        }
    }
    if !(c.x_px.is_finite() && c.z_px.is_finite() && c.r_px.is_finite() && c.r_px > 0.0) {
        return Err(DetectError::Degenerate {
            what: WHAT,
            reason: format!("circle ({}, {}, r {})", c.x_px, c.z_px, c.r_px),
        });
    }
    // The sums of the covariance, once, at the solution (the last
    // iteration's weight function and scale).
    let rw = RobustWeight::new(scale.unwrap_or(opts.min_scale_px), opts);
    let last = if huber {
        scratch.final_sums::<V, true>(&c, rw, n)
    } else {
        scratch.final_sums::<V, false>(&c, rw, n)
    };
    let inliers = last.n_in;
    let p = if held { 2 } else { 3 };
    if inliers < opts.min_points.max(p + 1) {
        return Err(DetectError::TooFewPoints {
            what: WHAT,
            found: inliers,
            needed: opts.min_points.max(p + 1),
        });
    }
    // Residual and covariance from the sums at the solution.
    let residual_px = (last.ss_unweighted / last.n_in.max(1) as f64).sqrt();
    let degenerate = || DetectError::Degenerate {
        what: WHAT,
        reason: "singular normal matrix (points on too short an arc?)".into(),
    };
    // A = Σψ'jjᵀ; where many residuals sit on Tukey's descending part it
    // may fail to be positive definite: then JᵀWJ stands in.
    let bread_ok = inverse_spd(&last.bread).is_some();
    let jtj = if bread_ok { last.bread } else { last.jtj };
    let sb2 = opts.radial_sigma_px * opts.radial_sigma_px;
    let meat = last.meat;
    let cov = if held {
        let m2 = [[jtj[0][0], jtj[0][1]], [jtj[1][0], jtj[1][1]]];
        let b2 = [[meat[0][0], meat[0][1]], [meat[1][0], meat[1][1]]];
        let inv = inverse_spd(&m2).ok_or_else(degenerate)?;
        let mut cov = sandwich(&inv, &b2, last.n_in, 2);
        // Response of the centre to a unit outward shift of every point:
        // v = −A⁻¹ Σψ'(d) j.
        let g = [last.jtw1[0], last.jtw1[1]];
        let v = [
            -(inv[0][0] * g[0] + inv[0][1] * g[1]),
            -(inv[1][0] * g[0] + inv[1][1] * g[1]),
        ];
        for a in 0..2 {
            for b in 0..2 {
                cov[a][b] += sb2 * v[a] * v[b];
            }
        }
        Covariance::centre_only(&cov)
    } else {
        let inv = inverse_spd(&jtj).ok_or_else(degenerate)?;
        let mut cov = sandwich(&inv, &meat, last.n_in, 3);
        // A free radius absorbs a uniform shift: it adds σ_b² to var(r) only.
        cov[2][2] += sb2;
        Covariance::full(&cov)
    };
    Ok(CircleFit {
        x_px: c.x_px,
        z_px: c.z_px,
        r_px: c.r_px,
        cov,
        residual_px,
        n_used: count(n),
        inliers: count(inliers),
        iterations: count(iterations),
        scale_px: scale.unwrap_or(opts.min_scale_px),
    })
}

/// A count as [`CircleFit`] keeps it.
fn count(n: usize) -> u32 {
    u32::try_from(n).unwrap_or(u32::MAX)
}

/// Points per step of the passes over the points. Every quantity of a step
/// holds four points' values ([`Lanes`]), and the sums are kept per lane and
/// added in a fixed order at the end.
const LANES: usize = 4;

/// Four `f64` lanes and the operations the fit's passes need, each the same
/// IEEE operation on every lane (no fused multiply-add), so that the two
/// implementations, [`F4`] (portable) and [`Y4`] (AVX2, one instruction per
/// operation), give the same bits (tested).
trait Lanes:
    Copy
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
    + std::ops::Neg<Output = Self>
    + std::ops::AddAssign
{
    const ZERO: Self;
    fn splat(v: f64) -> Self;
    /// The first four values of `v`.
    fn load(v: &[f64]) -> Self;
    /// Into the first four values of `out`.
    fn store(self, out: &mut [f64]);
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    /// `max(self, o)`; `o` where `self` is NaN.
    fn max(self, o: Self) -> Self;
    /// `self` where `a < b`, 0 elsewhere (also where either is NaN).
    fn where_lt(self, a: Self, b: Self) -> Self;
    /// `self` where `a ≤ b`, 0 elsewhere (also where either is NaN).
    fn where_le(self, a: Self, b: Self) -> Self;
    /// The sum of the lanes, `(l₀ + l₁) + (l₂ + l₃)`.
    fn total(self) -> f64;
}

/// Portable [`Lanes`].
#[derive(Debug, Clone, Copy, PartialEq)]
struct F4([f64; LANES]);

impl F4 {
    #[inline(always)]
    fn zip(self, o: F4, f: impl Fn(f64, f64) -> f64) -> F4 {
        let mut r = [0.0; LANES];
        for l in 0..LANES {
            r[l] = f(self.0[l], o.0[l]);
        }
        F4(r)
    }
}

impl Lanes for F4 {
    const ZERO: F4 = F4([0.0; LANES]);

    #[inline(always)]
    fn splat(v: f64) -> F4 {
        F4([v; LANES])
    }

    #[inline(always)]
    fn load(v: &[f64]) -> F4 {
        F4([v[0], v[1], v[2], v[3]])
    }

    #[inline(always)]
    fn store(self, out: &mut [f64]) {
        out[..LANES].copy_from_slice(&self.0);
    }

    #[inline(always)]
    fn sqrt(self) -> F4 {
        F4(self.0.map(f64::sqrt))
    }

    #[inline(always)]
    fn abs(self) -> F4 {
        F4(self.0.map(f64::abs))
    }

    #[inline(always)]
    fn max(self, o: F4) -> F4 {
        self.zip(o, |a, b| if a > b { a } else { b })
    }

    #[inline(always)]
    fn where_lt(self, a: F4, b: F4) -> F4 {
        let mut r = [0.0; LANES];
        for l in 0..LANES {
            r[l] = if a.0[l] < b.0[l] { self.0[l] } else { 0.0 };
        }
        F4(r)
    }

    #[inline(always)]
    fn where_le(self, a: F4, b: F4) -> F4 {
        let mut r = [0.0; LANES];
        for l in 0..LANES {
            r[l] = if a.0[l] <= b.0[l] { self.0[l] } else { 0.0 };
        }
        F4(r)
    }

    #[inline(always)]
    fn total(self) -> f64 {
        (self.0[0] + self.0[1]) + (self.0[2] + self.0[3])
    }
}

macro_rules! f4_ops {
    ($($op:ident $f:ident $sym:tt),*) => {$(
        impl std::ops::$op for F4 {
            type Output = F4;
            #[inline(always)]
            fn $f(self, o: F4) -> F4 {
                self.zip(o, |a, b| a $sym b)
            }
        }
    )*};
}
f4_ops!(Add add +, Sub sub -, Mul mul *, Div div /);

impl std::ops::Neg for F4 {
    type Output = F4;
    #[inline(always)]
    fn neg(self) -> F4 {
        F4(self.0.map(|a| -a))
    }
}

impl std::ops::AddAssign for F4 {
    #[inline(always)]
    fn add_assign(&mut self, o: F4) {
        *self = *self + o;
    }
}

/// [`Lanes`] in one AVX2 register. Only used inside [`fit_circle_avx2`],
/// which runs only on CPUs with AVX2: that is what makes its intrinsics
/// sound.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Y4(std::arch::x86_64::__m256d);

#[cfg(target_arch = "x86_64")]
mod y4 {
    use super::{Lanes, LANES, Y4};
    use std::arch::x86_64::*;

    // SAFETY (every block below): AVX2 is present (see `Y4`); loads and
    // stores touch the first LANES values of slices checked to hold them.
    impl Lanes for Y4 {
        const ZERO: Y4 = Y4(unsafe { std::mem::transmute::<[f64; LANES], __m256d>([0.0; LANES]) });

        #[inline(always)]
        fn splat(v: f64) -> Y4 {
            Y4(unsafe { _mm256_set1_pd(v) })
        }

        #[inline(always)]
        fn load(v: &[f64]) -> Y4 {
            let v = &v[..LANES];
            Y4(unsafe { _mm256_loadu_pd(v.as_ptr()) })
        }

        #[inline(always)]
        fn store(self, out: &mut [f64]) {
            let out = &mut out[..LANES];
            unsafe { _mm256_storeu_pd(out.as_mut_ptr(), self.0) }
        }

        #[inline(always)]
        fn sqrt(self) -> Y4 {
            Y4(unsafe { _mm256_sqrt_pd(self.0) })
        }

        #[inline(always)]
        fn abs(self) -> Y4 {
            Y4(unsafe { _mm256_andnot_pd(_mm256_set1_pd(-0.0), self.0) })
        }

        #[inline(always)]
        fn max(self, o: Y4) -> Y4 {
            // maxpd gives its second operand where either is NaN; with the
            // operands swapped that is `self` where `o` is NaN, matching
            // `if a > b { a } else { b }` lane by lane.
            Y4(unsafe { _mm256_max_pd(o.0, self.0) })
        }

        #[inline(always)]
        fn where_lt(self, a: Y4, b: Y4) -> Y4 {
            Y4(unsafe { _mm256_and_pd(self.0, _mm256_cmp_pd::<_CMP_LT_OQ>(a.0, b.0)) })
        }

        #[inline(always)]
        fn where_le(self, a: Y4, b: Y4) -> Y4 {
            Y4(unsafe { _mm256_and_pd(self.0, _mm256_cmp_pd::<_CMP_LE_OQ>(a.0, b.0)) })
        }

        #[inline(always)]
        fn total(self) -> f64 {
            // A plain bit copy, no intrinsic (so it inlines anywhere).
            let l = unsafe { std::mem::transmute::<__m256d, [f64; LANES]>(self.0) };
            (l[0] + l[1]) + (l[2] + l[3])
        }
    }

    macro_rules! y4_ops {
        ($($op:ident $f:ident $intr:ident),*) => {$(
            impl std::ops::$op for Y4 {
                type Output = Y4;
                #[inline(always)]
                fn $f(self, o: Y4) -> Y4 {
                    Y4(unsafe { $intr(self.0, o.0) })
                }
            }
        )*};
    }
    y4_ops!(Add add _mm256_add_pd, Sub sub _mm256_sub_pd, Mul mul _mm256_mul_pd, Div div _mm256_div_pd);

    impl std::ops::Neg for Y4 {
        type Output = Y4;
        #[inline(always)]
        fn neg(self) -> Y4 {
            Y4(unsafe { _mm256_xor_pd(self.0, _mm256_set1_pd(-0.0)) })
        }
    }

    impl std::ops::AddAssign for Y4 {
        #[inline(always)]
        fn add_assign(&mut self, o: Y4) {
            *self = *self + o;
        }
    }
}

/// Four points' residuals `ρ − r` at distances `ρ` from the centre and their
/// unit vectors `(dx, dz)/ρ` (`(0, 0)` at `ρ = 0`): a square root and a
/// division per point, the costliest operations of a pass.
#[inline(always)]
fn geometry<V: Lanes>(x: V, z: V, c: &Circle) -> (V, V, V) {
    let (dx, dz) = (x - V::splat(c.x_px), z - V::splat(c.z_px));
    let rho = (dx * dx + dz * dz).sqrt();
    let inv = (V::splat(1.0) / rho).where_lt(V::ZERO, rho);
    (rho - V::splat(c.r_px), dx * inv, dz * inv)
}

/// The normal equations' sums of four points (`j = (−uₓ, −u_z, −1)`):
/// `JᵀWd`, then the lower triangle of `JᵀWJ`, `(x x), (z x), (z z), (r x),
/// (r z), (r r)`.
#[inline(always)]
fn normal_terms<V: Lanes>(w: V, ux: V, uz: V, d: V) -> [V; 9] {
    let (wx, wz) = (w * ux, w * uz);
    [
        -(wx * d),
        -(wz * d),
        -(w * d),
        wx * ux,
        wz * ux,
        wz * uz,
        wx,
        wz,
        w,
    ]
}

/// `(JᵀWJ, JᵀWd)` from the sums of [`normal_terms`], with a tiny Levenberg
/// damping of 1e-9 on the diagonal.
fn normal_matrix<V: Lanes>(sums: [V; 9]) -> ([[f64; 3]; 3], [f64; 3]) {
    let t = sums.map(V::total);
    let d = 1.0 + 1e-9;
    (
        [
            [t[3] * d, t[4], t[6]],
            [t[4], t[5] * d, t[7]],
            [t[6], t[7], t[8] * d],
        ],
        [t[0], t[1], t[2]],
    )
}

impl FitScratch {
    /// The points into columns, padded to a multiple of [`LANES`].
    fn load(&mut self, points: &[EdgePoint]) {
        let n = points.len();
        let padded = n.div_ceil(LANES) * LANES;
        self.xs.clear();
        self.zs.clear();
        self.prior.clear();
        // A point with a coordinate that is not finite is kept at the origin
        // with weight 0, so that it adds exact zeros to every sum.
        for p in points {
            let ok = p.x_px.is_finite() && p.z_px.is_finite();
            self.xs.push(if ok { p.x_px } else { 0.0 });
            self.zs.push(if ok { p.z_px } else { 0.0 });
            self.prior.push(if ok { p.weight.max(0.0) } else { 0.0 });
        }
        self.xs.resize(padded, 0.0);
        self.zs.resize(padded, 0.0);
        self.prior.resize(padded, 0.0);
        for v in [&mut self.residuals, &mut self.ux, &mut self.uz] {
            v.clear();
            v.resize(padded, 0.0);
        }
        self.weights.clear();
        self.weights.resize(n, 0.0);
    }

    /// Residuals `dᵢ = |pᵢ − c| − r` and unit vectors from the centre, and
    /// `|dᵢ|` of the points with weight > 0 into `work` (for the scale).
    #[inline(always)]
    fn residuals_at<V: Lanes>(&mut self, c: &Circle) {
        for i in (0..self.xs.len()).step_by(LANES) {
            let (d, ux, uz) = self.fresh::<V>(i, c);
            d.store(&mut self.residuals[i..]);
            ux.store(&mut self.ux[i..]);
            uz.store(&mut self.uz[i..]);
        }
        self.work.clear();
        self.work.extend(
            self.prior
                .iter()
                .zip(&self.residuals)
                .filter(|(p, _)| **p > 0.0)
                .map(|(_, d)| d.abs()),
        );
    }

    /// The weighted normal equations, the residuals and unit vectors of
    /// each four points from `at(i)` (`i` the first point's index).
    #[inline(always)]
    fn normal_equations<V: Lanes, const HUBER: bool>(
        &self,
        rw: RobustWeight,
        at: impl Fn(usize) -> (V, V, V),
    ) -> ([[f64; 3]; 3], [f64; 3]) {
        let mut sums = [V::ZERO; 9];
        for i in (0..self.xs.len()).step_by(LANES) {
            let (d, ux, uz) = at(i);
            let (w, _) = rw.at::<V, HUBER>(d, V::load(&self.prior[i..]));
            let t = normal_terms(w, ux, uz, d);
            for k in 0..9 {
                sums[k] += t[k];
            }
        }
        normal_matrix(sums)
    }

    /// The residuals and unit vectors of [`FitScratch::residuals_at`] for
    /// the four points from `i`.
    #[inline(always)]
    fn stored<V: Lanes>(&self, i: usize) -> (V, V, V) {
        let load = |v: &[f64]| V::load(&v[i..]);
        (load(&self.residuals), load(&self.ux), load(&self.uz))
    }

    /// The residuals and unit vectors at circle `c` of the four points from
    /// `i`, computed afresh (the iterations whose scale is held: one pass).
    #[inline(always)]
    fn fresh<V: Lanes>(&self, i: usize, c: &Circle) -> (V, V, V) {
        geometry(V::load(&self.xs[i..]), V::load(&self.zs[i..]), c)
    }

    /// The sums of [`LastSums`] at circle `c`, with the final weights of the
    /// `n` points left in `weights`.
    #[inline(always)]
    fn final_sums<V: Lanes, const HUBER: bool>(
        &mut self,
        c: &Circle,
        rw: RobustWeight,
        n: usize,
    ) -> LastSums {
        // JᵀWJ, bread, meat (lower triangles in the order of
        // `normal_terms`), Σψ'j, Σd² and the count of the inliers.
        let (mut jtj, mut bread, mut meat) = ([V::ZERO; 6], [V::ZERO; 6], [V::ZERO; 6]);
        let (mut jtw1, mut ss, mut count) = ([V::ZERO; 3], V::ZERO, V::ZERO);
        for i in (0..self.xs.len()).step_by(LANES) {
            let (d, ux, uz) = self.fresh::<V>(i, c);
            let (w, dpsi) = rw.at::<V, HUBER>(d, V::load(&self.prior[i..]));
            // The weights go to `residuals`, free until the next rescale.
            w.store(&mut self.residuals[i..]);
            let inside = V::splat(1.0).where_lt(V::ZERO, w);
            let wd2 = w * w * d * d;
            let quad = |a: V| [a * ux * ux, a * uz * ux, a * uz * uz, a * ux, a * uz, a];
            let (qj, qb, qm) = (quad(w), quad(dpsi), quad(wd2));
            for k in 0..6 {
                jtj[k] += qj[k];
                bread[k] += qb[k];
                meat[k] += qm[k];
            }
            jtw1[0] += -(dpsi * ux);
            jtw1[1] += -(dpsi * uz);
            jtw1[2] += -dpsi;
            ss += inside * d * d;
            count += inside;
        }
        self.weights.copy_from_slice(&self.residuals[..n]);
        let sym = |q: [V; 6]| {
            let t = q.map(V::total);
            [[t[0], t[1], t[3]], [t[1], t[2], t[4]], [t[3], t[4], t[5]]]
        };
        LastSums {
            jtj: sym(jtj),
            bread: sym(bread),
            meat: sym(meat),
            jtw1: jtw1.map(V::total),
            ss_unweighted: ss.total(),
            n_in: count.total() as usize,
        }
    }
}

/// The weight function of one IRLS iteration: Huber's or Tukey's biweight
/// at residual scale `s`, with its constants worked out once.
#[derive(Debug, Clone, Copy)]
struct RobustWeight {
    /// Huber's corner `1.345 s`.
    k: f64,
    /// `1 / (c s)²` for Tukey's biweight.
    inv_cs2: f64,
}

impl RobustWeight {
    fn new(s: f64, opts: &FitOptions) -> Self {
        let cs = opts.tukey_c * s;
        RobustWeight {
            k: 1.345 * s,
            inv_cs2: 1.0 / (cs * cs),
        }
    }

    /// Weights `w = ψ(d)/d` and slopes `ψ'(d)` of Huber's (`HUBER`) or
    /// Tukey's ρ-function at four residuals `d`, times the points' prior
    /// weights (≥ 0).
    #[inline(always)]
    fn at<V: Lanes, const HUBER: bool>(&self, d: V, prior: V) -> (V, V) {
        let one = V::splat(1.0);
        let (w, dpsi) = if HUBER {
            // k / max(|d|, k) is exactly 1 inside the corner.
            let (k, a) = (V::splat(self.k), d.abs());
            (k / a.max(k), one.where_le(a, k))
        } else {
            // u² = (d / c s)², no division or square root per point.
            let u2 = d * d * V::splat(self.inv_cs2);
            let q = one - u2;
            (
                (q * q).where_lt(u2, one),
                (q * (one - V::splat(5.0) * u2)).where_lt(u2, one),
            )
        };
        (w * prior, dpsi * prior)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn arc(c: Circle, from_deg: f64, to_deg: f64, n: usize) -> Vec<EdgePoint> {
        (0..n)
            .map(|i| {
                let t = (from_deg + (to_deg - from_deg) * i as f64 / (n - 1) as f64).to_radians();
                EdgePoint {
                    x_px: c.x_px + c.r_px * t.cos(),
                    z_px: c.z_px + c.r_px * t.sin(),
                    weight: 1.0,
                }
            })
            .collect()
    }

    #[test]
    fn hyper_recovers_a_noiseless_60_degree_arc_to_1e_9() {
        // Exact points: the hyper fit is exact (η = 0) up to rounding; 1e-9 px
        // leaves room for rounding in moments of ~1e4 px² values.
        for (k, c) in [
            Circle {
                x_px: 256.3,
                z_px: 190.71,
                r_px: 83.17,
            },
            Circle {
                x_px: -12.0,
                z_px: 4000.5,
                r_px: 3.5,
            },
            Circle {
                x_px: 40.25,
                z_px: 60.125,
                r_px: 140.0,
            },
        ]
        .into_iter()
        .enumerate()
        {
            let start = -120.0 + 37.0 * k as f64;
            let pts = arc(c, start, start + 60.0, 25);
            let f = hyper_fit(&pts).unwrap();
            assert!((f.x_px - c.x_px).abs() < 1e-9, "{f:?} vs {c:?}");
            assert!((f.z_px - c.z_px).abs() < 1e-9, "{f:?} vs {c:?}");
            assert!((f.r_px - c.r_px).abs() < 1e-9, "{f:?} vs {c:?}");
        }
    }

    #[test]
    fn collinear_points_are_an_error_not_a_circle() {
        let pts: Vec<_> = (0..10)
            .map(|i| EdgePoint {
                x_px: i as f64,
                z_px: 2.0 * i as f64,
                weight: 1.0,
            })
            .collect();
        assert!(hyper_fit(&pts).is_err());
        let mut s = FitScratch::default();
        assert!(fit_circle(&pts, None, &FitOptions::default(), &mut s).is_err());
        // No points, or none finite, from a start: an error too, not a panic.
        let start = Some(Circle {
            x_px: 1.0,
            z_px: 2.0,
            r_px: 3.0,
        });
        let nan = [EdgePoint {
            x_px: f64::NAN,
            z_px: 0.0,
            weight: 1.0,
        }; 7];
        for pts in [&[][..], &nan[..]] {
            let e = fit_circle(pts, start, &FitOptions::default(), &mut s).unwrap_err();
            assert!(
                matches!(e, DetectError::TooFewPoints { found: 0, .. }),
                "{e:?}"
            );
        }
    }

    #[test]
    fn robust_fit_ignores_a_cluster_of_outliers() {
        let c = Circle {
            x_px: 100.4,
            z_px: 80.7,
            r_px: 50.0,
        };
        let mut pts = arc(c, 180.0, 360.0, 90);
        // A "mirror image" cluster and dust: 15 % of the points, far off.
        for (i, p) in pts.iter_mut().enumerate() {
            if i % 7 == 0 {
                p.z_px += 3.0 + (i % 3) as f64;
            }
        }
        let mut s = FitScratch::default();
        let f = fit_circle(&pts, None, &FitOptions::default(), &mut s).unwrap();
        assert!((f.x_px - c.x_px).abs() < 1e-6, "{f:?}");
        assert!((f.z_px - c.z_px).abs() < 1e-6, "{f:?}");
        assert!((f.r_px - c.r_px).abs() < 1e-6, "{f:?}");
        assert_eq!(f.inliers, 90 - 13);
        let held = FitOptions {
            hold_radius: Some(50.0),
            ..FitOptions::default()
        };
        let f = fit_circle(&pts, None, &held, &mut s).unwrap();
        assert!((f.z_px - c.z_px).abs() < 1e-6, "{f:?}");
        assert!(matches!(f.cov, Covariance::CentreOnly(_)));
    }

    #[test]
    fn the_avx2_and_portable_passes_give_the_same_bits() {
        use rand::{Rng, SeedableRng};
        crate::test_support::require_avx2("the circle fit's passes");
        // Noisy arcs with outliers, one point not finite and a weight-0
        // point, free and held, from starts near and far (Huber and Tukey
        // passes, rescaled and fused): every field of the fit, to the bit.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut fitted = 0;
        for k in 0..30 {
            let c = Circle {
                x_px: 200.0 + rng.gen::<f64>(),
                z_px: 150.0 + rng.gen::<f64>(),
                r_px: 40.0 + 40.0 * rng.gen::<f64>(),
            };
            let span = 100.0 + 260.0 * rng.gen::<f64>();
            let n = 50 + k * 5;
            let mut pts = arc(c, 270.0 - span / 2.0, 270.0 + span / 2.0, n);
            for (i, p) in pts.iter_mut().enumerate() {
                p.x_px += 0.05 * (rng.gen::<f64>() - 0.5) + if i % 17 == 3 { 2.0 } else { 0.0 };
                p.z_px += 0.05 * (rng.gen::<f64>() - 0.5);
            }
            pts[1].weight = 0.0;
            pts[2].z_px = f64::NAN;
            let off = 2.0 * rng.gen::<f64>();
            let start = Circle {
                x_px: c.x_px + off,
                z_px: c.z_px - off,
                r_px: c.r_px + 0.5 * off,
            };
            let (mut s1, mut s2) = (FitScratch::default(), FitScratch::default());
            for opts in [
                FitOptions::default(),
                FitOptions {
                    hold_radius: Some(c.r_px),
                    ..FitOptions::default()
                },
                FitOptions {
                    hold_radius: Some(c.r_px),
                    huber_iterations: 0,
                    scale_px: Some(0.03),
                    ..FitOptions::default()
                },
            ] {
                let portable = fit_circle_lanes::<F4>(&pts, Some(start), &opts, &mut s1);
                #[cfg(target_arch = "x86_64")]
                {
                    // SAFETY: AVX2 is present (asserted above).
                    let avx2 = unsafe { fit_circle_avx2(&pts, Some(start), &opts, &mut s2) };
                    assert_eq!(portable, avx2, "arc {k}, {opts:?}");
                    assert_eq!(s1.weights, s2.weights, "arc {k}");
                }
                if portable.is_ok() {
                    fitted += 1;
                    assert_eq!(s1.weights[2], 0.0, "arc {k}: the NaN point has weight 0");
                }
            }
        }
        // Most fits succeed (a fixed scale of 0.03 px from a start up to
        // 2 px off rejects every point: an error, equal on both paths).
        assert!(fitted >= 70, "{fitted} of 90 fits");
    }

    #[test]
    fn the_default_tolerance_stops_within_5e_5_px_of_the_converged_fit() {
        use rand::{Rng, SeedableRng};
        // Noisy short arcs (σ 0.05 px, 5 % outliers) from a start 0.4 px
        // off, as pass 1 gets them from the prediction: stopping at a
        // 1e-4 px step must land where iterating to 1e-12 px does.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut worst = 0.0f64;
        for k in 0..40 {
            let c = Circle {
                x_px: 200.0 + rng.gen::<f64>(),
                z_px: 150.0 + rng.gen::<f64>(),
                r_px: 60.0 + 10.0 * rng.gen::<f64>(),
            };
            let span = 140.0 + 220.0 * rng.gen::<f64>();
            let mut pts = arc(c, 270.0 - span / 2.0, 270.0 + span / 2.0, 120);
            for (i, p) in pts.iter_mut().enumerate() {
                let t = (p.z_px - c.z_px).atan2(p.x_px - c.x_px);
                let e = 0.05 * (rng.gen::<f64>() + rng.gen::<f64>() + rng.gen::<f64>() - 1.5) * 2.0
                    + if i % 20 == 7 { 1.5 } else { 0.0 };
                p.x_px += e * t.cos();
                p.z_px += e * t.sin();
            }
            let start = Circle {
                x_px: c.x_px + 0.4,
                z_px: c.z_px - 0.3,
                r_px: c.r_px + 0.2,
            };
            let mut s = FitScratch::default();
            let tight = FitOptions {
                tolerance_px: 1e-12,
                ..FitOptions::default()
            };
            let a = fit_circle(&pts, Some(start), &FitOptions::default(), &mut s).unwrap();
            let b = fit_circle(&pts, Some(start), &tight, &mut s).unwrap();
            let held = |tolerance_px| FitOptions {
                hold_radius: Some(c.r_px),
                huber_iterations: 0,
                scale_px: Some(a.scale_px),
                tolerance_px,
                ..FitOptions::default()
            };
            let ha = fit_circle(&pts, Some(a.circle()), &held(1e-4), &mut s).unwrap();
            let hb = fit_circle(&pts, Some(a.circle()), &held(1e-12), &mut s).unwrap();
            assert_eq!(ha.scale_px, a.scale_px, "arc {k}: a given scale is kept");
            for (u, v) in [(a, b), (ha, hb)] {
                let d = (u.x_px - v.x_px)
                    .abs()
                    .max((u.z_px - v.z_px).abs())
                    .max((u.r_px - v.r_px).abs());
                worst = worst.max(d);
            }
            assert!(
                b.iterations > a.iterations,
                "arc {k}: {} vs {}",
                a.iterations,
                b.iterations
            );
        }
        assert!(worst < 5e-5, "worst difference {worst} px");
    }
}
