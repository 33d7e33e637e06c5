//! The force–penetration law during contact (SPEC §2, "Kinematics").
//!
//! Two views of the same physics:
//! - [`force_table`]: F = m·(g − z̈) per contact frame, z̈ from a cubic fitted
//!   by weighted least squares to the frames within ±`half_window` (a
//!   Savitzky–Golay derivative that tolerates missing frames), tabulated
//!   against δ. This is what the track file and the F(δ) plot show. Any
//!   local smoothing flattens the force peak, so a power law fitted to this
//!   table is biased (n ≈ 1.94 for ±2 frames on a 24-frame contact).
//! - [`fit_force_law`]: the law F = K·δⁿ plus a damping term fitted to the
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

use crate::measure::events::{Events, Geometry, TrackPoint, FLIGHT_FRAMES};
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
    fn acceleration(&self, g: f64, d: f64, v: f64, km: f64, n: f64, b: f64) -> f64 {
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
const CONTACT_STEPS_PER_FRAME: f64 = 20.0;

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
fn integrate_counted(
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

/// Fit F = K·δⁿ + c·δ̇ to the trajectory (see the module doc). Uses the
/// contact and up to [`FLIGHT_FRAMES`] flight frames either side, within the
/// flight fits' frames (a second bounce is left out). `exposure_s` is a
/// frame's exposure time (0: the frames are instants). The fit stops with
/// [`ForceFitError::Limit`] after `max_trajectories` trajectories' work
/// (the product's is `FORCE_FIT_MAX_TRAJECTORIES`, set by
/// `EventConfig::force_fit_max_trajectories`) or [`FORCE_FIT_TIME_LIMIT_S`].
pub fn fit_force_law(
    track: &[TrackPoint],
    ev: &Events,
    geom: &Geometry,
    sphere: &SphereParams,
    g_m_s2: f64,
    exposure_s: f64,
    max_trajectories: usize,
) -> Result<ForceLaw, ForceFitError> {
    fit_force_law_to(
        track,
        ev,
        geom,
        sphere,
        g_m_s2,
        exposure_s,
        LM_REL_TOL,
        max_trajectories,
    )
}

/// [`fit_force_law`] with the fits stopped at `rel_tol` (see [`LM_REL_TOL`])
/// and after `max_trajectories` (see [`FORCE_FIT_MAX_TRAJECTORIES`]).
#[allow(clippy::too_many_arguments)]
fn fit_force_law_to(
    track: &[TrackPoint],
    ev: &Events,
    geom: &Geometry,
    sphere: &SphereParams,
    g_m_s2: f64,
    exposure_s: f64,
    rel_tol: f64,
    max_trajectories: usize,
) -> Result<ForceLaw, ForceFitError> {
    let s_m = geom.mm_per_px * 1e-3;
    // The contact and up to FLIGHT_FRAMES flight frames on either side: they
    // fix the state at onset and after the rebound; more flight adds nothing
    // to K, n or c but cost.
    let (c0, c1) = ev.contact_span;
    let lo = track[c0.saturating_sub(FLIGHT_FRAMES)]
        .frame
        .max(ev.pre.frames.0);
    let hi = track[(c1 + FLIGHT_FRAMES).min(track.len() - 1)]
        .frame
        .min(ev.post.frames.1);
    let pts: Vec<&TrackPoint> = track
        .iter()
        .filter(|p| p.frame >= lo && p.frame <= hi)
        .collect();
    let m_pts = pts.len();
    if m_pts < 12 {
        return Err(ForceFitError::TooFewFrames(m_pts));
    }
    let ts: Vec<f64> = pts.iter().map(|p| p.t_s).collect();
    let obs: Vec<f64> = pts
        .iter()
        .map(|p| geom.penetration_px(p.x_px, p.z_px) * s_m)
        .collect();
    let sig: Vec<f64> = pts.iter().map(|p| p.sigma_z_px * s_m).collect();
    let dt = (ts[m_pts - 1] - ts[0]) / (m_pts - 1) as f64;
    let h_max = dt / CONTACT_STEPS_PER_FRAME;
    // A frame shows the mean of δ over its exposure: the model is averaged
    // the same way, by Simpson's rule on δ at the exposure's start, middle
    // and end (exact for the flight parabolas; in contact its error is
    // O(T⁴·δ⁗), and across touchdown and lift-off it still weighs both
    // sides). The integrator returns δ at all three times of every frame
    // (an exposure never exceeds the frame interval, so they stay in order).
    let half_exposure = 0.5 * exposure_s.clamp(0.0, dt);
    let times: Vec<f64> = if half_exposure > 0.0 {
        ts.iter()
            .flat_map(|&t| [t - half_exposure, t, t + half_exposure])
            .collect()
    } else {
        ts.clone()
    };

    // Start: initial state from the pre-contact parabola; K/m from energy
    // balance ½v² = (K/m)·δ³/3 at n = 2; no damping.
    let t0 = times[0];
    let y_imp = ev.surface_row_at_impact_px;
    let d0 = (ev.pre.z_at(t0) + geom.radius_px - y_imp) * s_m;
    let v0 = ev.pre.v_at(t0) * s_m;
    let z_peak = ev.peak.poly.eval(ev.peak.t_max_s);
    let dmax = ((z_peak + geom.radius_px - y_imp) * s_m).max(1e-6);
    let v_in = (v0 * v0 + 2.0 * g_m_s2 * (-d0).max(0.0)).sqrt();

    // The work and time limits, shared by the fits as if they ran one after
    // another (see [`Ledger`]).
    let usual_steps = CONTACT_STEPS_PER_FRAME as usize * (c1 - c0 + 2) + times.len();
    let limits = Limits {
        max_steps: max_trajectories * usual_steps,
        max_trajectories,
        started: std::time::Instant::now(),
    };
    let resid_of = |model: ContactModel| {
        let (times, obs, sig) = (&times, &obs, &sig);
        move |th: &[f64]| -> (DVector<f64>, usize) {
            let (traj, taken) = integrate_counted(times, th, g_m_s2, h_max, model);
            let seen = |i: usize| {
                if half_exposure > 0.0 {
                    (traj[3 * i] + 4.0 * traj[3 * i + 1] + traj[3 * i + 2]) / 6.0
                } else {
                    traj[i]
                }
            };
            // θ[5]: the surface's offset below the line, in metres of δ.
            let r = DVector::from_fn(m_pts, |i, _| (seen(i) - (obs[i] - th[5])) / sig[i]);
            (r, taken)
        }
    };
    let theta0 = [
        d0,
        v0,
        (1.5 * v_in * v_in / dmax.powi(3)).ln(),
        2.0,
        0.0,
        0.0,
    ];
    // (δ0, v0, ln K/m, n, damping) free under each contact model, beside
    // each other (on every thread there is); then, under the best one, n
    // held at the model's 2, and the surface free too (the cross-check of
    // the image's line). The work limit counts them in that order.
    use crate::util::timings::{time, Stage};
    let lm = |model: ContactModel, theta: &[f64], free: &[usize]| {
        let mut ledger = Ledger::default();
        let resid = resid_of(model);
        let fit = levenberg_marquardt(theta, free, &resid, rel_tol, &limits, &mut ledger);
        (fit, ledger)
    };
    let per_model: Vec<_> = {
        use rayon::prelude::*;
        ContactModel::ALL
            .par_iter()
            .map(|&model| time(Stage::ForceFree, || lm(model, &theta0, &[0, 1, 2, 3, 4])))
            .collect()
    };
    let mut done = 0usize;
    let mut fits: Vec<(ContactModel, LmFit)> = Vec::with_capacity(per_model.len());
    for (&model, (fit, work)) in ContactModel::ALL.iter().zip(per_model) {
        match limits.replay(&mut done, &work, fit) {
            Ok(f) => fits.push((model, f)),
            Err(e @ ForceFitError::Limit(_)) => return Err(e),
            Err(_) => {}
        }
    }
    let best = fits
        .iter()
        .enumerate()
        .min_by(|a, b| a.1 .1.cost.total_cmp(&b.1 .1.cost))
        .map(|(i, _)| i)
        .ok_or(ForceFitError::NoSolution)?;
    let (model, free) = (fits[best].0, &fits[best].1);
    let mut at_n2 = free.theta.clone();
    at_n2[3] = 2.0;
    let ((held, held_work), (on_surface, surface_work)) = rayon::join(
        || time(Stage::ForceN2, || lm(model, &at_n2, &[0, 1, 2, 4])),
        || {
            time(Stage::ForceSurface, || {
                lm(model, &free.theta, &[0, 1, 2, 3, 4, 5])
            })
        },
    );
    let held = limits.replay(&mut done, &held_work, held)?;
    let on_surface = limits.replay(&mut done, &surface_work, on_surface).ok();
    let surface_offset_px = on_surface.as_ref().map(|f| Measured {
        value: f.theta[5] / s_m,
        err: f.sd_with(5, &[]) / s_m,
    });
    // The geometry's errors (see the module doc): ∂r_i/∂q = −(∂obs_i/∂q)/σ_i
    // with obs_i = δ_i·s, times σ_q. With the scale from the radius,
    // s = R_mm/R_px, so ∂obs/∂R = s·(1 − δ_px/R_px); a scale given
    // independently adds its own relative error.
    let px: Vec<f64> = obs.iter().map(|o| o / s_m).collect();
    let per_frame = |f: &dyn Fn(usize) -> f64| DVector::from_fn(m_pts, |i, _| -f(i) / sig[i]);
    let mut nuisances = vec![
        per_frame(&|_| -s_m) * geom.surface_row_err_px,
        if geom.scale_from_radius {
            per_frame(&|i| s_m * (1.0 - px[i] / geom.radius_px)) * geom.radius_err_px
        } else {
            per_frame(&|_| s_m) * geom.radius_err_px
        },
    ];
    if !geom.scale_from_radius && geom.mm_per_px > 0.0 {
        nuisances.push(per_frame(&|i| obs[i]) * (geom.mm_per_px_err / geom.mm_per_px));
    }
    // The silhouette's edge in contact, its lower outline hidden and the
    // band dipping under it, is not the flight's: the centre moves by a
    // step as the contact starts and by a part growing with the depth,
    // the same in every frame of a drop ([`CONTACT_STEP_SYSTEMATIC_PX`],
    // [`CONTACT_DEPTH_SYSTEMATIC_PX`]).
    let deepest = obs.iter().copied().fold(0.0, f64::max);
    if deepest > 0.0 {
        let in_contact = |i: usize| if obs[i] > 0.0 { s_m } else { 0.0 };
        nuisances.push(per_frame(&in_contact) * CONTACT_STEP_SYSTEMATIC_PX);
        nuisances
            .push(per_frame(&|i| in_contact(i) * obs[i] / deepest) * CONTACT_DEPTH_SYSTEMATIC_PX);
    }
    // The residuals' change per px of surface moved down (obs shrinks by s).
    let per_surface_px = per_frame(&|_| -s_m);
    let sd = |fit: &LmFit, i: usize| fit.sd_with(i, &nuisances);
    let mass = sphere.mass_kg();
    // The models' Akaike weights (equal parameter counts), with the χ²
    // differences scaled by the best fit's χ²/dof where the frames scatter
    // more than their σ say (quasi-likelihood).
    let c_hat = (free.cost / free.dof as f64).max(1.0);
    let raw: Vec<f64> = fits
        .iter()
        .map(|(_, f)| (-(f.cost - free.cost) / (2.0 * c_hat)).exp())
        .collect();
    let total: f64 = raw.iter().sum();
    let models: Vec<ModelFit> = fits
        .iter()
        .zip(&raw)
        .map(|((m, f), w)| ModelFit {
            model: *m,
            chi2: f.cost,
            n: f.theta[3],
            weight: w / total,
        })
        .collect();
    // The spread over the models, about the best one's value, added to
    // each error (Burnham & Anderson's model-averaged variance).
    let spread = |value: &dyn Fn(&LmFit) -> f64| -> f64 {
        let v0 = value(free);
        fits.iter()
            .zip(&models)
            .map(|((_, f), m)| m.weight * (value(f) - v0).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let k_of = |fit: &LmFit| {
        let km = fit.theta[2].exp();
        Measured {
            value: km * mass,
            err: km * mass * sd(fit, 2),
        }
    };
    let k_free = k_of(free);
    let ln_k_spread = spread(&|f| f.theta[2]);
    Ok(ForceLaw {
        model,
        k: Measured {
            value: k_free.value,
            err: k_free.err.hypot(k_free.value * ln_k_spread),
        },
        n: Measured {
            value: free.theta[3],
            err: sd(free, 3).hypot(spread(&|f| f.theta[3])),
        },
        damping: Measured {
            value: match model.damping {
                Damping::Linear => free.theta[4] * mass,
                Damping::HuntCrossley => free.theta[4],
            },
            err: match model.damping {
                Damping::Linear => mass * sd(free, 4),
                Damping::HuntCrossley => sd(free, 4),
            },
        },
        k_at_n2: k_of(&held),
        surface_offset_px,
        n_per_surface_px: free.response_to(3, &per_surface_px),
        k_per_surface_px: free.theta[2].exp() * mass * free.response_to(2, &per_surface_px),
        chi2_red: free.cost / free.dof as f64,
        models,
        n_frames: m_pts,
    })
}

/// The spread of the step the tracked centre makes, against the truth, as a
/// contact starts, px: the silhouette's edge offset in contact differs
/// from the flight's. On the `realistic` renders with contacts beyond the
/// model (120 drops, the centre's error fitted per drop as a step at
/// contact plus a part proportional to δ/δmax) the step's spread is
/// 0.0027 px rms, of which the frames' own noise is 0.0020.
pub const CONTACT_STEP_SYSTEMATIC_PX: f64 = 0.002;

/// The spread of the tracked centre's error that grows with the depth in
/// contact, px at the deepest frame (the lower outline hidden, the band
/// dipping): on the renders of [`CONTACT_STEP_SYSTEMATIC_PX`] −0.0038 px
/// mean, 0.0068 px rms, of which the frames' own noise is 0.0029.
pub const CONTACT_DEPTH_SYSTEMATIC_PX: f64 = 0.006;

/// A Levenberg–Marquardt fit of some parameters of θ.
struct LmFit {
    theta: Vec<f64>,
    /// Indices of θ that were fitted, in the order of `cov`.
    free: Vec<usize>,
    /// (JᵀJ)⁻¹ over the fitted parameters, scaled by max(1, χ²_red).
    cov: DMatrix<f64>,
    /// (JᵀJ)⁻¹Jᵀ at the solution: the fitted parameters' response to a
    /// change of the residuals is minus this times it.
    response: DMatrix<f64>,
    cost: f64,
    dof: usize,
}

impl LmFit {
    /// Standard error of θ[i] (0 when θ[i] was held), with independent
    /// nuisances added: each
    /// `dr` is the change of the residuals that one standard deviation of
    /// a nuisance makes.
    /// How θ[i] moves when the residuals change by `dr` (0 when held).
    fn response_to(&self, i: usize, dr: &DVector<f64>) -> f64 {
        self.free
            .iter()
            .position(|&k| k == i)
            .map_or(0.0, |p| -self.response.row(p).dot(&dr.transpose()))
    }

    fn sd_with(&self, i: usize, nuisances: &[DVector<f64>]) -> f64 {
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
const LM_REL_TOL: f64 = 1e-10;

/// The scaled residuals of a θ and the integrator's steps they took.
type Residuals<'a> = dyn Fn(&[f64]) -> (DVector<f64>, usize) + Sync + 'a;

/// The trajectory fits' work and time limits (see [`fit_force_law`]).
struct Limits {
    /// Integrator steps of all the fits together.
    max_steps: usize,
    max_trajectories: usize,
    started: std::time::Instant,
}

/// The integrator's steps of each trajectory a fit computed, in the order
/// the fit asked for them. The fits run beside each other and the columns
/// of a Jacobian on every thread, yet the work limit counts their work as
/// one thread computing the fits in turn would: each trajectory is refused
/// once the steps of those before it pass the limit ([`Limits::replay`]),
/// so where a fit stops does not depend on the threads.
#[derive(Default)]
struct Ledger {
    steps: Vec<usize>,
    /// This fit's own steps so far.
    total: usize,
}

impl Limits {
    /// Why a fit that has taken `ledger`'s steps stops before its next
    /// trajectories: its own steps alone past the limit (those of the fits
    /// before it only add to them, see [`Self::replay`]), or the time limit.
    fn reached(&self, ledger: &Ledger) -> Option<ForceFitError> {
        if ledger.total > self.max_steps {
            Some(self.work_limit())
        } else if self.started.elapsed().as_secs_f64() > FORCE_FIT_TIME_LIMIT_S {
            Some(ForceFitError::Limit(format!("{FORCE_FIT_TIME_LIMIT_S} s")))
        } else {
            None
        }
    }

    fn work_limit(&self) -> ForceFitError {
        ForceFitError::Limit(format!("{} trajectories' work", self.max_trajectories))
    }

    /// A fit's outcome as it is when the fits run one after another, `done`
    /// steps taken before it: the work limit reached before one of its
    /// trajectories (or before the next it would have asked for) stops it
    /// there; else its own outcome. Adds its steps to `done`.
    fn replay(
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
    fn trajectories(
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
    fn trajectory(
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
fn levenberg_marquardt(
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
