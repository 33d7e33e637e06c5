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
//! Covariance: `σ̂²·(JᵀWJ)⁻¹` at the solution, `σ̂² = Σwᵢdᵢ² / (Σwᵢ − p)`,
//! where `J` is the Jacobian of the residuals and `p` the number of fitted
//! parameters — the usual asymptotic covariance of a (robust) least-squares
//! estimate; it assumes independent point errors.

use super::edges::EdgePoint;
use super::DetectError;

/// A circle in frame pixels (see the module convention in [`super`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Circle {
    /// Centre column.
    pub x_px: f64,
    /// Centre row (grows downward).
    pub z_px: f64,
    /// Radius.
    pub r_px: f64,
}

/// The covariance of a fit's parameters, in px².
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Covariance {
    /// `(x, z, r)` fitted: 3×3 in that order.
    Full([[f64; 3]; 3]),
    /// Radius held: `(x, z)` only.
    CentreOnly([[f64; 2]; 2]),
}

impl Covariance {
    /// Standard deviation of the centre column.
    pub fn sigma_x_px(&self) -> f64 {
        match self {
            Covariance::Full(c) => c[0][0].sqrt(),
            Covariance::CentreOnly(c) => c[0][0].sqrt(),
        }
    }
    /// Standard deviation of the centre row.
    pub fn sigma_z_px(&self) -> f64 {
        match self {
            Covariance::Full(c) => c[1][1].sqrt(),
            Covariance::CentreOnly(c) => c[1][1].sqrt(),
        }
    }
    /// Standard deviation of the radius; `None` when it was held.
    pub fn sigma_r_px(&self) -> Option<f64> {
        match self {
            Covariance::Full(c) => Some(c[2][2].sqrt()),
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
    /// Points given to the fit.
    pub n_used: usize,
    /// Points with non-zero final weight.
    pub inliers: usize,
}

impl CircleFit {
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
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            hold_radius: None,
            huber_iterations: 3,
            max_iterations: 30,
            tukey_c: 4.685,
            min_scale_px: 1e-3,
            min_points: 6,
        }
    }
}

/// Reusable buffers of [`fit_circle`], so a loop over frames allocates nothing.
#[derive(Debug, Default, Clone)]
pub struct FitScratch {
    /// Final weight of each point (0 = rejected), in the order given.
    pub weights: Vec<f64>,
    residuals: Vec<f64>,
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

/// Solve the symmetric positive definite system `A x = b` (n ≤ 3) by
/// Cholesky; `None` when `A` is not positive definite.
fn solve_spd<const N: usize>(a: &[[f64; N]; N], b: &[f64; N]) -> Option<[f64; N]> {
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

/// Weighted normal equations of the orthogonal residuals around `c`:
/// returns `(JᵀWJ, JᵀWd, Σw d², Σw)`; `N = 3` fits `(x, z, r)`, `N = 2` only
/// the centre (with `r` fixed).
fn normal_equations<const N: usize>(
    points: &[EdgePoint],
    weights: &[f64],
    c: &Circle,
) -> ([[f64; N]; N], [f64; N], f64, f64) {
    let mut jtj = [[0.0; N]; N];
    let mut jtd = [0.0; N];
    let (mut ss, mut sw) = (0.0, 0.0);
    for (p, &w) in points.iter().zip(weights) {
        if w <= 0.0 {
            continue;
        }
        let (dx, dz) = (p.x_px - c.x_px, p.z_px - c.z_px);
        let rho = (dx * dx + dz * dz).sqrt();
        if rho == 0.0 {
            continue;
        }
        let d = rho - c.r_px;
        // ∂d/∂x = −dx/ρ, ∂d/∂z = −dz/ρ, ∂d/∂r = −1.
        let j3 = [-dx / rho, -dz / rho, -1.0];
        for i in 0..N {
            jtd[i] += w * j3[i] * d;
            for k in 0..=i {
                jtj[i][k] += w * j3[i] * j3[k];
            }
        }
        ss += w * d * d;
        sw += w;
    }
    for i in 0..N {
        for k in i + 1..N {
            jtj[i][k] = jtj[k][i];
        }
    }
    (jtj, jtd, ss, sw)
}

/// Weighted sum of squared residuals of `c`.
fn cost(points: &[EdgePoint], weights: &[f64], c: &Circle) -> f64 {
    points
        .iter()
        .zip(weights)
        .filter(|(_, &w)| w > 0.0)
        .map(|(p, &w)| {
            let d = (p.x_px - c.x_px).hypot(p.z_px - c.z_px) - c.r_px;
            w * d * d
        })
        .sum()
}

/// One Levenberg–Marquardt minimisation of the weighted orthogonal distances
/// with fixed weights, from `c`.
fn lm_refine<const N: usize>(points: &[EdgePoint], weights: &[f64], mut c: Circle) -> Circle {
    let mut lambda = 1e-3;
    let mut current = cost(points, weights, &c);
    for _ in 0..20 {
        let (jtj, jtd, _, _) = normal_equations::<N>(points, weights, &c);
        let mut a = jtj;
        for (i, row) in a.iter_mut().enumerate() {
            row[i] += lambda * jtj[i][i].max(1e-12);
        }
        let mut rhs = jtd;
        for v in rhs.iter_mut() {
            *v = -*v;
        }
        let Some(step) = solve_spd(&a, &rhs) else {
            break;
        };
        let mut trial = c;
        trial.x_px += step[0];
        trial.z_px += step[1];
        if N == 3 {
            trial.r_px += step[2];
        }
        let trial_cost = cost(points, weights, &trial);
        if trial_cost <= current {
            let small = step.iter().all(|s| s.abs() < 1e-10);
            c = trial;
            current = trial_cost;
            lambda = (lambda * 0.1).max(1e-9);
            if small {
                break;
            }
        } else {
            lambda *= 10.0;
            if lambda > 1e6 {
                break;
            }
        }
    }
    c
}

/// Robust geometric circle fit to `points` (their `weight` multiplies the
/// robust weight), starting from `start` or, without one, from [`hyper_fit`].
///
/// IRLS: residual scale `s = max(1.4826·MAD, min_scale_px)`; Huber weights
/// `min(1, 1.345 s / |d|)` for the first iterations, then Tukey's biweight
/// `(1 − (d / (c s))²)²` for `|d| < c s`, else 0; each iteration a
/// Levenberg–Marquardt solve with those weights. Stops when the centre moves
/// less than 1e-7 px. Final weights are left in `scratch.weights`.
pub fn fit_circle(
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
    scratch.weights.clear();
    scratch
        .weights
        .extend(points.iter().map(|p| p.weight.max(0.0)));
    scratch.residuals.clear();
    scratch.residuals.resize(n, 0.0);
    let held = opts.hold_radius.is_some();
    for it in 0..opts.max_iterations {
        // Residuals and their robust scale (over points with a prior weight).
        scratch.work.clear();
        for (i, p) in points.iter().enumerate() {
            let d = (p.x_px - c.x_px).hypot(p.z_px - c.z_px) - c.r_px;
            scratch.residuals[i] = d;
            if p.weight > 0.0 {
                scratch.work.push(d.abs());
            }
        }
        let s = (1.4826 * median(&mut scratch.work)).max(opts.min_scale_px);
        let huber = it < opts.huber_iterations;
        for (i, p) in points.iter().enumerate() {
            let d = scratch.residuals[i].abs();
            let w = if huber {
                let k = 1.345 * s;
                if d <= k {
                    1.0
                } else {
                    k / d
                }
            } else {
                let u = d / (opts.tukey_c * s);
                if u < 1.0 {
                    (1.0 - u * u).powi(2)
                } else {
                    0.0
                }
            };
            scratch.weights[i] = w * p.weight.max(0.0);
        }
        let next = if held {
            lm_refine::<2>(points, &scratch.weights, c)
        } else {
            lm_refine::<3>(points, &scratch.weights, c)
        };
        let moved = (next.x_px - c.x_px)
            .abs()
            .max((next.z_px - c.z_px).abs())
            .max((next.r_px - c.r_px).abs());
        c = next;
        if !huber && moved < 1e-7 {
            break;
        }
    }
    if !(c.x_px.is_finite() && c.z_px.is_finite() && c.r_px.is_finite() && c.r_px > 0.0) {
        return Err(DetectError::Degenerate {
            what: WHAT,
            reason: format!("circle ({}, {}, r {})", c.x_px, c.z_px, c.r_px),
        });
    }
    let inliers = scratch.weights.iter().filter(|&&w| w > 0.0).count();
    let p = if held { 2 } else { 3 };
    if inliers < opts.min_points.max(p + 1) {
        return Err(DetectError::TooFewPoints {
            what: WHAT,
            found: inliers,
            needed: opts.min_points.max(p + 1),
        });
    }
    let (mut ss_in, mut n_in) = (0.0, 0usize);
    for (p, &w) in points.iter().zip(&scratch.weights) {
        if w > 0.0 {
            let d = (p.x_px - c.x_px).hypot(p.z_px - c.z_px) - c.r_px;
            ss_in += d * d;
            n_in += 1;
        }
    }
    let residual_px = (ss_in / n_in as f64).sqrt();
    let degenerate = || DetectError::Degenerate {
        what: WHAT,
        reason: "singular normal matrix (points on too short an arc?)".into(),
    };
    let cov = if held {
        let (jtj, _, ss, sw) = normal_equations::<2>(points, &scratch.weights, &c);
        let s2 = ss / (sw - 2.0).max(1.0);
        let inv = inverse_spd(&jtj).ok_or_else(degenerate)?;
        let inv = inv.map(|row| row.map(|v| v * s2));
        Covariance::CentreOnly(inv)
    } else {
        let (jtj, _, ss, sw) = normal_equations::<3>(points, &scratch.weights, &c);
        let s2 = ss / (sw - 3.0).max(1.0);
        let inv = inverse_spd(&jtj).ok_or_else(degenerate)?;
        let inv = inv.map(|row| row.map(|v| v * s2));
        Covariance::Full(inv)
    };
    Ok(CircleFit {
        x_px: c.x_px,
        z_px: c.z_px,
        r_px: c.r_px,
        cov,
        residual_px,
        n_used: n,
        inliers,
    })
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
}
