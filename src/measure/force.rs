//! The force–penetration law during contact (SPEC §2, "Kinematics").
//!
//! Two views of the same physics:
//! - [`force_table`]: F = m·(g − z̈) per contact frame, z̈ from a cubic fitted
//!   by weighted least squares to the frames within ±`half_window` (a
//!   Savitzky–Golay derivative that tolerates missing frames), tabulated
//!   against δ. This is what the track file and the F(δ) plot show. Any
//!   local smoothing flattens the force peak, so a power law fitted to this
//!   table is biased (n ≈ 1.94 for ±2 frames on a 24-frame contact).
//! - [`fit_force_law`](crate::measure::force_fit::fit_force_law): the law F = K·δⁿ plus a damping term fitted to the
//!   trajectory itself: the equation of motion m·δ̈ = m·g − F(δ, δ̇) while
//!   δ > 0 is integrated (exact in flight, RK4 in contact, touchdown and
//!   lift-off located exactly) from the first flight frame and its δ(t),
//!   averaged over each frame's exposure as the camera averages it, fitted
//!   to every frame of the flight–contact–flight sequence by
//!   Levenberg–Marquardt. The exponent n is free: it is a measurement, not
//!   the elastic-foundation model's 2. The damping is not presumed either:
//!   four contact models are fitted ([`ContactModel`]: damping linear,
//!   c·δ̇, or Hunt–Crossley, K·δⁿ·α·δ̇; a force that may pull the sphere
//!   back at the end of the contact, or one that cannot, F ≥ 0), the one
//!   with the lowest χ² is reported, and the spread of n and K over the
//!   models, weighted by their Akaike weights, is part of their errors.
//!   This has no smoothing bias;
//!   K, n and the damping come with errors from the fit's covariance, plus what the
//!   uncertainties of the geometry do to them: δ = (z + R − y_s)·s moves
//!   as a whole with the surface row y_s and the radius R_px (and scales
//!   with the scale s, which follows R_px when it comes from it), which the
//!   frames' own scatter does not show. Each enters through the fit's
//!   linear response, `Δθ = −(JᵀJ)⁻¹Jᵀ ∂r/∂q · Δq`.

use crate::measure::events::{Events, Geometry, TrackPoint};
use crate::measure::kinematics::{Measured, SphereParams};
use crate::util::lsq::PolyFit;
use nalgebra::{DMatrix, DVector};

/// One row of the tabulated force curve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForcePoint {
    /// The frame's image number.
    pub frame: i64,
    /// Penetration δ, m.
    pub delta_m: f64,
    /// Contact force F = m·(g − z̈), N.
    pub force_n: f64,
    /// One-sigma error of `force_n`, from z̈'s, N.
    pub force_err_n: f64,
}

/// F = m·(g − z̈) at each contact frame (see the module doc).
pub fn force_table(
    track: &[TrackPoint],
    ev: &Events,
    geom: &Geometry,
    sphere: &SphereParams,
    g_m_s2: f64,
    half_window: usize,
) -> Vec<ForcePoint> {
    let s_m = geom.mm_per_px * 1e-3;
    let mass = sphere.mass_kg();
    let (c0, c1) = ev.contact_span;
    let mut out = Vec::new();
    for k in c0..=c1 {
        let lo = k.saturating_sub(half_window);
        let hi = (k + half_window).min(track.len() - 1);
        if hi - lo < 2 * half_window {
            continue;
        }
        let w = &track[lo..=hi];
        let t: Vec<f64> = w.iter().map(|p| p.t_s).collect();
        let z: Vec<f64> = w.iter().map(|p| p.z_px).collect();
        let s: Vec<f64> = w.iter().map(|p| p.sigma_z_px).collect();
        let Some(fit) = PolyFit::fit(&t, &z, &s, 3, track[k].t_s) else {
            continue;
        };
        let zdd = fit.derivative_at_x0(2) * s_m;
        let zdd_err = fit.derivative_at_x0_err(2) * s_m;
        out.push(ForcePoint {
            frame: track[k].frame,
            delta_m: geom.penetration_px(track[k].x_px, track[k].z_px) * s_m,
            force_n: mass * (g_m_s2 - zdd),
            force_err_n: mass * zdd_err,
        });
    }
    out
}

/// The damping term of a contact law.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Damping {
    /// c·δ̇ (c in N·s/m): the dashpot beside the spring.
    Linear,
    /// K·δⁿ·α·δ̇ (α in s/m): Hunt and Crossley's, vanishing with the
    /// elastic force at touchdown and lift-off.
    HuntCrossley,
}

/// One of the contact laws the trajectory is fitted with: F = K·δⁿ plus
/// its damping, while δ > 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ContactModel {
    /// The damping term: linear (c·δ̇) or Hunt–Crossley (K·δⁿ·α·δ̇).
    pub damping: Damping,
    /// Whether the force may pull (adhesion): `false` clamps F ≥ 0, so the
    /// sphere leaves the surface where the force falls to zero, before δ
    /// is back at 0, and flies freely from there.
    pub pulls: bool,
}

impl ContactModel {
    /// The models every drop is fitted with, in the order their fits are
    /// counted against the work limit.
    pub const ALL: [ContactModel; 4] = [
        ContactModel {
            damping: Damping::Linear,
            pulls: true,
        },
        ContactModel {
            damping: Damping::Linear,
            pulls: false,
        },
        ContactModel {
            damping: Damping::HuntCrossley,
            pulls: true,
        },
        ContactModel {
            damping: Damping::HuntCrossley,
            pulls: false,
        },
    ];

    /// Its word in `drops.csv`'s `force_model`.
    pub fn name(&self) -> &'static str {
        match (self.damping, self.pulls) {
            (Damping::Linear, true) => "linear",
            (Damping::Linear, false) => "linear_no_pull",
            (Damping::HuntCrossley, true) => "hunt_crossley",
            (Damping::HuntCrossley, false) => "hunt_crossley_no_pull",
        }
    }

    /// The acceleration (m/s², positive down) at penetration `d` (m,
    /// clamped at 0) and rate `v` (m/s) with K/m = `km`, exponent `n`
    /// and damping coefficient over mass `b` (c/m in 1/s for linear
    /// damping, α in s/m for Hunt–Crossley).
    #[inline]
    pub(super) fn acceleration(&self, g: f64, d: f64, v: f64, km: f64, n: f64, b: f64) -> f64 {
        let d = d.max(0.0);
        // n held at the model's 2 multiplies instead of pow.
        let elastic = km * if n == 2.0 { d * d } else { d.powf(n) };
        let f = match self.damping {
            Damping::Linear => elastic + b * v,
            Damping::HuntCrossley => elastic * (1.0 + b * v),
        };
        g - if self.pulls { f } else { f.max(0.0) }
    }
}

/// One contact model's fit with n free, for the record of how the models
/// compare.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelFit {
    /// The contact model fitted.
    pub model: ContactModel,
    /// χ² of its fit.
    pub chi2: f64,
    /// Its fitted exponent n.
    pub n: f64,
    /// Its Akaike weight among the models that converged (equal parameter
    /// counts: ∝ exp(−Δχ²/2ĉ), ĉ the best fit's χ²/dof when above 1).
    pub weight: f64,
}

/// The fitted contact law.
#[derive(Debug, Clone, PartialEq)]
pub struct ForceLaw {
    /// The contact model of lowest χ², whose K, n and damping these are.
    pub model: ContactModel,
    /// F = K·δⁿ, K in N/mⁿ (δ in metres); its error includes the spread
    /// over the contact models.
    pub k: Measured,
    /// The exponent, fitted free; its error includes the spread over the
    /// contact models.
    pub n: Measured,
    /// The damping coefficient in `model`'s unit: c (N·s/m) for linear
    /// damping, α (s/m) for Hunt–Crossley.
    pub damping: Measured,
    /// K with n held at the elastic-foundation model's 2 (under `model`):
    /// the number to compare with π E φ R / h (K and n are strongly
    /// correlated when both are free: with δ in metres, an error Δn moves
    /// K by δ^Δn ≈ −7·Δn).
    pub k_at_n2: Measured,
    /// A cross-check of the image's surface line, never a replacement: the
    /// offset (px, positive down) of the undeformed surface from the
    /// geometry's line where the trajectory puts it when the surface is
    /// free too (under `model`, n free). n and the surface trade off, so its
    /// error is several times a good line's. `None` when that fit fails.
    pub surface_offset_px: Option<Measured>,
    /// How n and K (n free) move per px that the surface moves down: to
    /// widen their errors by an uncertainty of the surface found later.
    pub n_per_surface_px: f64,
    /// How K moves per px that the surface moves down, N/mⁿ per px.
    pub k_per_surface_px: f64,
    /// χ² per degree of freedom of the best model's fit.
    pub chi2_red: f64,
    /// Every contact model that converged, in [`ContactModel::ALL`]'s order.
    pub models: Vec<ModelFit>,
    /// Frames used.
    pub n_frames: usize,
}

/// Contact steps of the integration per frame interval (RK4; the flight
/// between contacts is exact, so only the smooth contact phase is stepped).
pub(super) const CONTACT_STEPS_PER_FRAME: f64 = 20.0;

/// Steps one trajectory may take, per time asked for: a trajectory takes
/// at most [`CONTACT_STEPS_PER_FRAME`] RK4 steps per mean frame interval in
/// contact, plus one step split at each time and a few at each touchdown
/// and lift-off, so 8 times that is reached only by a θ that chatters at
/// the surface (steps shrinking to nothing), whose trajectory is then NaN.
const STEPS_PER_TIME: usize = 8 * (CONTACT_STEPS_PER_FRAME as usize + 3);

/// The model trajectory δ(t) at the times `ts` (ascending) under `model`,
/// starting at `ts[0]` from (δ0, v0), with K/m = exp(ln_km), exponent n and
/// damping b = θ[4] (c/m or α, [`ContactModel::acceleration`]), and the
/// steps taken (flight jumps and RK4 steps).
///
/// In flight (δ < 0) the motion is the exact parabola, and the touchdown
/// time is solved for exactly, so a step never straddles the onset, where
/// the damping makes δ̈ jump. In contact, RK4 steps of at most `h_max`; a
/// step that ends above the surface is redone up to the lift-off, found on
/// the step's cubic Hermite interpolant of (δ, δ̇), and flight resumes there.
pub(super) fn integrate_counted(
    ts: &[f64],
    theta: &[f64],
    g: f64,
    h_max: f64,
    model: ContactModel,
) -> (Vec<f64>, usize) {
    let (d0, v0, ln_km, n, b) = (theta[0], theta[1], theta[2], theta[3], theta[4]);
    let km = ln_km.exp();
    // In contact, the contact dynamics throughout the step, also where a
    // substep lands at δ ≤ 0: at touchdown δ = 0 the damping is already on,
    // and a step past the lift-off is the smooth continuation whose root
    // the Hermite search finds. A force that cannot pull is clamped at 0:
    // from there the sphere is in free flight above the deformed surface.
    let acc = |d: f64, v: f64| -> f64 { model.acceleration(g, d, v, km, n, b) };
    let rk4 = |d: f64, v: f64, h: f64| -> (f64, f64) {
        let (k1x, k1v) = (v, acc(d, v));
        let (k2x, k2v) = (v + 0.5 * h * k1v, acc(d + 0.5 * h * k1x, v + 0.5 * h * k1v));
        let (k3x, k3v) = (v + 0.5 * h * k2v, acc(d + 0.5 * h * k2x, v + 0.5 * h * k2v));
        let (k4x, k4v) = (v + h * k3v, acc(d + h * k3x, v + h * k3v));
        (
            d + h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x),
            v + h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v),
        )
    };
    let mut out = Vec::with_capacity(ts.len());
    let (mut d, mut v, mut t) = (d0, v0, ts[0]);
    // Far more steps than any sane θ needs (see STEPS_PER_TIME); a θ that
    // chatters at the surface gets a NaN trajectory, which the fit rejects.
    let max_steps = STEPS_PER_TIME * ts.len();
    let mut steps = 0;
    for &target in ts {
        while t < target {
            steps += 1;
            if steps > max_steps {
                out.resize(ts.len(), f64::NAN);
                return (out, steps);
            }
            let span = target - t;
            let in_flight = d < 0.0 || (d == 0.0 && v < 0.0);
            if in_flight {
                // First τ > 0 with d + v·τ + g·τ²/2 = 0 (none if g ≤ 0 and rising away).
                let disc = v * v - 2.0 * g * d;
                let touch = if g > 0.0 && disc >= 0.0 {
                    Some((-v + disc.sqrt()) / g).filter(|&tau| tau > 0.0)
                } else {
                    None
                };
                match touch.filter(|&tau| tau < span) {
                    Some(tau) => {
                        (d, v) = (0.0, v + g * tau);
                        t += tau;
                    }
                    None => {
                        (d, v) = (d + v * span + 0.5 * g * span * span, v + g * span);
                        t = target;
                    }
                }
                continue;
            }
            let h = span.min(h_max);
            let (d1, v1) = rk4(d, v, h);
            if d1 >= 0.0 {
                (d, v, t) = (d1, v1, if h == span { target } else { t + h });
                continue;
            }
            // Lift-off inside the step: the root of the Hermite cubic.
            let hermite = |s: f64| {
                let (s2, s3) = (s * s, s * s * s);
                (2.0 * s3 - 3.0 * s2 + 1.0) * d
                    + (s3 - 2.0 * s2 + s) * h * v
                    + (-2.0 * s3 + 3.0 * s2) * d1
                    + (s3 - s2) * h * v1
            };
            let (mut lo, mut hi) = (0.0, 1.0);
            for _ in 0..40 {
                let mid = 0.5 * (lo + hi);
                if hermite(mid) >= 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let tau = h * hi;
            let (_, ve) = rk4(d, v, tau);
            (d, v) = (0.0, ve.min(0.0));
            t += tau;
        }
        out.push(d);
    }
    (out, steps)
}

/// Why the contact law could not be fitted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ForceFitError {
    /// Fewer than 12 frames around the contact (the count).
    #[error("only {0} frames around the contact (at least 12 needed)")]
    TooFewFrames(usize),
    /// The fit found no solution (singular or not finite).
    #[error("the trajectory fit found no solution (singular or not finite)")]
    NoSolution,
    /// The fit stopped at its work or time limit (which, in words).
    #[error("the trajectory fit stopped at its limit of {0}")]
    Limit(String),
}

/// The trajectory fit's time limit, in seconds, a guard beside the work
/// limit (a clean drop's two fits take 6–54 ms here).
pub const FORCE_FIT_TIME_LIMIT_S: f64 = 20.0;

/// A Levenberg–Marquardt fit of some parameters of θ.
pub(super) struct LmFit {
    pub(super) theta: Vec<f64>,
    /// Indices of θ that were fitted, in the order of `cov`.
    pub(super) free: Vec<usize>,
    /// (JᵀJ)⁻¹ over the fitted parameters, scaled by max(1, χ²_red).
    pub(super) cov: DMatrix<f64>,
    /// (JᵀJ)⁻¹Jᵀ at the solution: the fitted parameters' response to a
    /// change of the residuals is minus this times it.
    pub(super) response: DMatrix<f64>,
    pub(super) cost: f64,
    pub(super) dof: usize,
}

impl LmFit {
    /// Standard error of θ[i] (0 when θ[i] was held), with independent
    /// nuisances added: each
    /// `dr` is the change of the residuals that one standard deviation of
    /// a nuisance makes.
    /// How θ[i] moves when the residuals change by `dr` (0 when held).
    pub(super) fn response_to(&self, i: usize, dr: &DVector<f64>) -> f64 {
        self.free
            .iter()
            .position(|&k| k == i)
            .map_or(0.0, |p| -self.response.row(p).dot(&dr.transpose()))
    }

    pub(super) fn sd_with(&self, i: usize, nuisances: &[DVector<f64>]) -> f64 {
        let Some(p) = self.free.iter().position(|&k| k == i) else {
            return 0.0;
        };
        let var: f64 = nuisances
            .iter()
            .map(|dr| self.response.row(p).dot(&dr.transpose()).powi(2))
            .sum();
        (self.cov[(p, p)].max(0.0) + var).sqrt()
    }
}

/// An accepted step that lowers |r|² by less than this fraction of it ends
/// the fit. At the minimum a step δθ lowers the cost by δθᵀJᵀJδθ, so with
/// ~100 residuals the parameters have then settled to ~1e-4 of their
/// standard errors (tested against a fit run to 1e-15). Without it the fit
/// went on for up to 25 iterations that each gained ~1e-13 of the cost,
/// then spent 20 trials failing.
pub(super) const LM_REL_TOL: f64 = 1e-10;

/// The scaled residuals of a θ and the integrator's steps they took.
type Residuals<'a> = dyn Fn(&[f64]) -> (DVector<f64>, usize) + Sync + 'a;

/// The trajectory fits' work and time limits (see [`fit_force_law`](crate::measure::force_fit::fit_force_law)).
pub(super) struct Limits {
    /// Integrator steps of all the fits together.
    pub(super) max_steps: usize,
    pub(super) max_trajectories: usize,
    pub(super) started: std::time::Instant,
}

/// The integrator's steps of each trajectory a fit computed, in the order
/// the fit asked for them. The fits run beside each other and the columns
/// of a Jacobian on every thread, yet the work limit counts their work as
/// one thread computing the fits in turn would: each trajectory is refused
/// once the steps of those before it pass the limit ([`Limits::replay`]),
/// so where a fit stops does not depend on the threads.
#[derive(Default)]
pub(super) struct Ledger {
    pub(super) steps: Vec<usize>,
    /// This fit's own steps so far.
    pub(super) total: usize,
}

impl Limits {
    /// Why a fit that has taken `ledger`'s steps stops before its next
    /// trajectories: its own steps alone past the limit (those of the fits
    /// before it only add to them, see [`Self::replay`]), or the time limit.
    pub(super) fn reached(&self, ledger: &Ledger) -> Option<ForceFitError> {
        if ledger.total > self.max_steps {
            Some(self.work_limit())
        } else if self.started.elapsed().as_secs_f64() > FORCE_FIT_TIME_LIMIT_S {
            Some(ForceFitError::Limit(format!("{FORCE_FIT_TIME_LIMIT_S} s")))
        } else {
            None
        }
    }

    pub(super) fn work_limit(&self) -> ForceFitError {
        ForceFitError::Limit(format!("{} trajectories' work", self.max_trajectories))
    }

    /// A fit's outcome as it is when the fits run one after another, `done`
    /// steps taken before it: the work limit reached before one of its
    /// trajectories (or before the next it would have asked for) stops it
    /// there; else its own outcome. Adds its steps to `done`.
    pub(super) fn replay(
        &self,
        done: &mut usize,
        ledger: &Ledger,
        outcome: Result<LmFit, ForceFitError>,
    ) -> Result<LmFit, ForceFitError> {
        for &taken in &ledger.steps {
            if *done > self.max_steps {
                return Err(self.work_limit());
            }
            *done += taken;
        }
        match outcome {
            // It stopped before its next trajectory.
            Err(ForceFitError::Limit(_)) if *done > self.max_steps => Err(self.work_limit()),
            other => other,
        }
    }
}

impl Ledger {
    /// The residuals of the trajectories `thetas`, computed on every thread,
    /// their steps entered in order; `None` when the limits stop the fit
    /// first.
    pub(super) fn trajectories(
        &mut self,
        thetas: &[Vec<f64>],
        resid: &Residuals<'_>,
        limits: &Limits,
    ) -> Result<Vec<DVector<f64>>, ForceFitError> {
        use rayon::prelude::*;
        if let Some(e) = limits.reached(self) {
            return Err(e);
        }
        let out: Vec<(DVector<f64>, usize)> = if thetas.len() == 1 {
            vec![resid(&thetas[0])]
        } else {
            thetas.par_iter().map(|th| resid(th)).collect()
        };
        Ok(out
            .into_iter()
            .map(|(r, taken)| {
                self.steps.push(taken);
                self.total += taken;
                r
            })
            .collect())
    }

    /// The residuals of one trajectory (see [`Self::trajectories`]).
    pub(super) fn trajectory(
        &mut self,
        theta: &[f64],
        resid: &Residuals<'_>,
        limits: &Limits,
    ) -> Result<DVector<f64>, ForceFitError> {
        Ok(self
            .trajectories(&[theta.to_vec()], resid, limits)?
            .remove(0))
    }
}

/// Minimise |r(θ)|² over θ[free] from θ0 (central-difference Jacobian,
/// its columns' trajectories on every thread; multiplicative damping of
/// the diagonal). Stops when an accepted step lowers the cost by less than
/// `rel_tol` of it ([`LM_REL_TOL`]), or no step helps. Each trajectory's
/// steps go to `ledger`.
pub(super) fn levenberg_marquardt(
    theta0: &[f64],
    free: &[usize],
    resid: &Residuals<'_>,
    rel_tol: f64,
    limits: &Limits,
    ledger: &mut Ledger,
) -> Result<LmFit, ForceFitError> {
    const STEPS: [f64; 6] = [1e-9, 1e-6, 1e-6, 1e-6, 1e-3, 1e-9];
    let p = free.len();
    let jacobian = |th: &[f64], rows: usize, ledger: &mut Ledger| {
        // θ ± h along each free parameter, in the order one thread takes them.
        let mut thetas = Vec::with_capacity(2 * p);
        let mut hs = Vec::with_capacity(p);
        for &k in free {
            let h = STEPS[k] * (1.0 + th[k].abs());
            let mut tp = th.to_vec();
            let mut tm = th.to_vec();
            tp[k] += h;
            tm[k] -= h;
            thetas.push(tp);
            thetas.push(tm);
            hs.push(h);
        }
        let rs = ledger.trajectories(&thetas, resid, limits)?;
        let mut j = DMatrix::zeros(rows, p);
        for (col, h) in hs.into_iter().enumerate() {
            j.set_column(col, &((&rs[2 * col] - &rs[2 * col + 1]) / (2.0 * h)));
        }
        Ok::<_, ForceFitError>(j)
    };
    let mut theta = theta0.to_vec();
    let mut r = ledger.trajectory(&theta, resid, limits)?;
    let mut cost = r.norm_squared();
    let mut lambda = 1e-3;
    let mut converged = false;
    for _ in 0..100 {
        let j = jacobian(&theta, r.len(), ledger)?;
        let jtj = j.transpose() * &j;
        let g = j.transpose() * &r;
        let mut improved = false;
        for _ in 0..20 {
            let mut a = jtj.clone();
            for k in 0..p {
                a[(k, k)] += lambda * jtj[(k, k)].max(1e-12);
            }
            let Some(step) = a.cholesky().map(|c| c.solve(&(-&g))) else {
                lambda *= 10.0;
                continue;
            };
            let mut cand = theta.clone();
            for (col, &k) in free.iter().enumerate() {
                cand[k] += step[col];
            }
            let rc = ledger.trajectory(&cand, resid, limits)?;
            let cc = rc.norm_squared();
            if cc.is_finite() && cc < cost {
                converged = cost - cc < rel_tol * cost;
                theta = cand;
                r = rc;
                cost = cc;
                lambda = (lambda / 10.0).max(1e-12);
                improved = true;
                break;
            }
            lambda *= 10.0;
        }
        if converged || !improved || lambda > 1e12 {
            break;
        }
    }
    let j = jacobian(&theta, r.len(), ledger)?;
    let dof = r.len().saturating_sub(p).max(1);
    let inv = (j.transpose() * &j)
        .try_inverse()
        .filter(|m| cost.is_finite() && m.iter().all(|v| v.is_finite()))
        .ok_or(ForceFitError::NoSolution)?;
    Ok(LmFit {
        theta,
        free: free.to_vec(),
        cov: &inv * (cost / dof as f64).max(1.0),
        response: inv * j.transpose(),
        cost,
        dof,
    })
}

#[cfg(test)]
mod tests;
