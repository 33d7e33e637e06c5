//! The robust geometric circle fit (module doc, second item) and its
//! covariance.

use super::hyper::hyper_fit;
#[cfg(target_arch = "x86_64")]
use super::lanes::Y4;
use super::lanes::{geometry, normal_matrix, normal_terms, Lanes, F4, LANES};
use super::spd::{inverse_spd, sandwich, solve_spd};
use super::types::{Circle, CircleFit, Covariance, FitOptions};
use crate::detect::types::EdgePoint;
use crate::detect::DetectError;

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
pub(super) unsafe fn fit_circle_avx2(
    points: &[EdgePoint],
    start: Option<Circle>,
    opts: &FitOptions,
    scratch: &mut FitScratch,
) -> Result<CircleFit, DetectError> {
    fit_circle_lanes::<Y4>(points, start, opts, scratch)
}

#[inline(always)]
pub(super) fn fit_circle_lanes<V: Lanes>(
    points: &[EdgePoint],
    start: Option<Circle>,
    opts: &FitOptions,
    scratch: &mut FitScratch,
) -> Result<CircleFit, DetectError> {
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
    let cov = covariance(&last, held, opts)?;
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

/// What the errors of [`fit_circle`] name.
const WHAT: &str = "robust circle fit";

/// The centre's (and with a free radius the radius's) covariance from the
/// sums at the solution (module doc, covariance), with the errors shared
/// by all points along their radii (`radial_sigma_px`) added.
#[inline(always)]
fn covariance(last: &LastSums, held: bool, opts: &FitOptions) -> Result<Covariance, DetectError> {
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
    Ok(if held {
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
    })
}

/// A count as [`CircleFit`] keeps it.
fn count(n: usize) -> u32 {
    u32::try_from(n).unwrap_or(u32::MAX)
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
