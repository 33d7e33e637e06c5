//! The contact law fitted to the trajectory ([`fit_force_law`]; the
//! models, the integrator and the least squares are [`crate::measure::force`]'s):
//! the frames around the contact, the fits under each contact model, and the
//! law with its errors.

use crate::measure::events::{Events, Geometry, TrackPoint, FLIGHT_FRAMES};
use crate::measure::force::{
    integrate_counted, levenberg_marquardt, ContactModel, Damping, ForceFitError, ForceLaw, Ledger,
    Limits, LmFit, ModelFit, CONTACT_STEPS_PER_FRAME, LM_REL_TOL,
};
use crate::measure::kinematics::{Measured, SphereParams};
use crate::util::timings::{time, Stage};
use nalgebra::DVector;

/// Fit F = K·δⁿ + c·δ̇ to the trajectory (see the module doc). Uses the
/// contact and up to [`FLIGHT_FRAMES`] flight frames either side, within the
/// flight fits' frames (a second bounce is left out). `exposure_s` is a
/// frame's exposure time (0: the frames are instants). The fit stops with
/// [`ForceFitError::Limit`] after `max_trajectories` trajectories' work
/// (the product's is `FORCE_FIT_MAX_TRAJECTORIES`, set by
/// `EventConfig::force_fit_max_trajectories`) or [`FORCE_FIT_TIME_LIMIT_S`](crate::measure::force::FORCE_FIT_TIME_LIMIT_S).
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
pub(crate) fn fit_force_law_to(
    track: &[TrackPoint],
    ev: &Events,
    geom: &Geometry,
    sphere: &SphereParams,
    g_m_s2: f64,
    exposure_s: f64,
    rel_tol: f64,
    max_trajectories: usize,
) -> Result<ForceLaw, ForceFitError> {
    let frames = FitFrames::around_contact(track, ev, geom, exposure_s)?;
    let theta0 = frames.start(ev, geom, g_m_s2);
    let limits = frames.limits(ev, max_trajectories);
    let fitter = Fitter {
        frames: &frames,
        g_m_s2,
        rel_tol,
        limits: &limits,
    };
    let fits = TrajectoryFits::run(&fitter, &theta0)?;
    Ok(fits.law(&frames, geom, sphere.mass_kg()))
}

/// The frames a trajectory fit is held to, and the times its model is
/// integrated at.
struct FitFrames {
    /// Metres per px.
    s_m: f64,
    /// Each frame's penetration δ, m.
    obs: Vec<f64>,
    /// Each frame's one-sigma error of δ, m.
    sig: Vec<f64>,
    /// The times the trajectory is computed at, s: each frame's, or the
    /// start, middle and end of each frame's exposure.
    times: Vec<f64>,
    /// Half a frame's exposure, s (0: the frames are instants).
    half_exposure: f64,
    /// The longest contact step of the integration, s.
    h_max: f64,
}

impl FitFrames {
    /// The contact and up to [`FLIGHT_FRAMES`] flight frames on either side,
    /// within the flight fits' frames; at least 12 of them.
    fn around_contact(
        track: &[TrackPoint],
        ev: &Events,
        geom: &Geometry,
        exposure_s: f64,
    ) -> Result<Self, ForceFitError> {
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
            ts
        };
        Ok(Self {
            s_m,
            obs,
            sig,
            times,
            half_exposure,
            h_max,
        })
    }

    /// The fits' start θ = (δ0, v0, ln K/m, n, damping, surface offset):
    /// the initial state from the pre-contact parabola; K/m from energy
    /// balance ½v² = (K/m)·δ³/3 at n = 2; no damping.
    fn start(&self, ev: &Events, geom: &Geometry, g_m_s2: f64) -> [f64; 6] {
        let s_m = self.s_m;
        let t0 = self.times[0];
        let y_imp = ev.surface_row_at_impact_px;
        let d0 = (ev.pre.z_at(t0) + geom.radius_px - y_imp) * s_m;
        let v0 = ev.pre.v_at(t0) * s_m;
        let z_peak = ev.peak.poly.eval(ev.peak.t_max_s);
        let dmax = ((z_peak + geom.radius_px - y_imp) * s_m).max(1e-6);
        let v_in = (v0 * v0 + 2.0 * g_m_s2 * (-d0).max(0.0)).sqrt();
        [
            d0,
            v0,
            (1.5 * v_in * v_in / dmax.powi(3)).ln(),
            2.0,
            0.0,
            0.0,
        ]
    }

    /// The work and time limits, shared by the fits as if they ran one after
    /// another (see [`Ledger`]), the clock started now.
    fn limits(&self, ev: &Events, max_trajectories: usize) -> Limits {
        let (c0, c1) = ev.contact_span;
        let usual_steps = CONTACT_STEPS_PER_FRAME as usize * (c1 - c0 + 2) + self.times.len();
        Limits {
            max_steps: max_trajectories * usual_steps,
            max_trajectories,
            started: std::time::Instant::now(),
        }
    }

    /// The scaled residuals of a θ under `model` (see [`Residuals`]).
    fn residuals(
        &self,
        model: ContactModel,
        g_m_s2: f64,
    ) -> impl Fn(&[f64]) -> (DVector<f64>, usize) + Sync + '_ {
        let m_pts = self.obs.len();
        move |th: &[f64]| -> (DVector<f64>, usize) {
            let (traj, taken) = integrate_counted(&self.times, th, g_m_s2, self.h_max, model);
            let seen = |i: usize| {
                if self.half_exposure > 0.0 {
                    (traj[3 * i] + 4.0 * traj[3 * i + 1] + traj[3 * i + 2]) / 6.0
                } else {
                    traj[i]
                }
            };
            // θ[5]: the surface's offset below the line, in metres of δ.
            let r = DVector::from_fn(m_pts, |i, _| {
                (seen(i) - (self.obs[i] - th[5])) / self.sig[i]
            });
            (r, taken)
        }
    }

    /// A change of the observations, `f(i)` m at frame i, as the change of
    /// the residuals it makes.
    fn per_frame(&self, f: &dyn Fn(usize) -> f64) -> DVector<f64> {
        DVector::from_fn(self.obs.len(), |i, _| -f(i) / self.sig[i])
    }

    /// The geometry's errors (see the module doc) as changes of the
    /// residuals, one standard deviation each: the surface row, the radius,
    /// the scale when given independently, and the contact's edge.
    fn nuisances(&self, geom: &Geometry) -> Vec<DVector<f64>> {
        let (s_m, obs) = (self.s_m, &self.obs);
        // ∂r_i/∂q = −(∂obs_i/∂q)/σ_i with obs_i = δ_i·s, times σ_q. With the
        // scale from the radius, s = R_mm/R_px, so ∂obs/∂R = s·(1 − δ_px/R_px);
        // a scale given independently adds its own relative error.
        let px: Vec<f64> = obs.iter().map(|o| o / s_m).collect();
        let mut nuisances = vec![
            self.per_frame(&|_| -s_m) * geom.surface_row_err_px,
            if geom.scale_from_radius {
                self.per_frame(&|i| s_m * (1.0 - px[i] / geom.radius_px)) * geom.radius_err_px
            } else {
                self.per_frame(&|_| s_m) * geom.radius_err_px
            },
        ];
        if !geom.scale_from_radius && geom.mm_per_px > 0.0 {
            nuisances.push(self.per_frame(&|i| obs[i]) * (geom.mm_per_px_err / geom.mm_per_px));
        }
        // The silhouette's edge in contact, its lower outline hidden and the
        // band dipping under it, is not the flight's: the centre moves by a
        // step as the contact starts and by a part growing with the depth,
        // the same in every frame of a drop ([`CONTACT_STEP_SYSTEMATIC_PX`],
        // [`CONTACT_DEPTH_SYSTEMATIC_PX`]).
        let deepest = obs.iter().copied().fold(0.0, f64::max);
        if deepest > 0.0 {
            let in_contact = |i: usize| if obs[i] > 0.0 { s_m } else { 0.0 };
            nuisances.push(self.per_frame(&in_contact) * CONTACT_STEP_SYSTEMATIC_PX);
            nuisances.push(
                self.per_frame(&|i| in_contact(i) * obs[i] / deepest) * CONTACT_DEPTH_SYSTEMATIC_PX,
            );
        }
        nuisances
    }
}

/// What every fit of a drop shares: its frames, g, the tolerance and the
/// limits.
struct Fitter<'a> {
    /// The frames fitted.
    frames: &'a FitFrames,
    /// Gravity, m/s².
    g_m_s2: f64,
    /// The fits' relative tolerance (see [`LM_REL_TOL`]).
    rel_tol: f64,
    /// The work and time limits of all the fits together.
    limits: &'a Limits,
}

impl Fitter<'_> {
    /// One fit of θ[free] from `theta` under `model`, and the work it took.
    fn lm(
        &self,
        model: ContactModel,
        theta: &[f64],
        free: &[usize],
    ) -> (Result<LmFit, ForceFitError>, Ledger) {
        let mut ledger = Ledger::default();
        let resid = self.frames.residuals(model, self.g_m_s2);
        let fit = levenberg_marquardt(theta, free, &resid, self.rel_tol, self.limits, &mut ledger);
        (fit, ledger)
    }
}

/// The trajectory fits of a drop: every contact model's with n free, and
/// two more under the best one.
struct TrajectoryFits {
    /// Each contact model that converged and its fit, n free, in
    /// [`ContactModel::ALL`]'s order.
    per_model: Vec<(ContactModel, LmFit)>,
    /// The index in `per_model` of the lowest χ².
    best: usize,
    /// The best model's fit with n held at 2.
    held: LmFit,
    /// The best model's fit with the surface free too (`None`: it failed).
    on_surface: Option<LmFit>,
}

impl TrajectoryFits {
    /// (δ0, v0, ln K/m, n, damping) free under each contact model, beside
    /// each other (on every thread there is); then, under the best one, n
    /// held at the model's 2, and the surface free too (the cross-check of
    /// the image's line). The work limit counts them in that order.
    fn run(fitter: &Fitter<'_>, theta0: &[f64]) -> Result<Self, ForceFitError> {
        let mut done = 0usize;
        let per_model = Self::free_fits(fitter, theta0, &mut done)?;
        let best = per_model
            .iter()
            .enumerate()
            .min_by(|a, b| a.1 .1.cost.total_cmp(&b.1 .1.cost))
            .map(|(i, _)| i)
            .ok_or(ForceFitError::NoSolution)?;
        let (model, free) = (per_model[best].0, &per_model[best].1);
        let mut at_n2 = free.theta.clone();
        at_n2[3] = 2.0;
        let ((held, held_work), (on_surface, surface_work)) = rayon::join(
            || time(Stage::ForceN2, || fitter.lm(model, &at_n2, &[0, 1, 2, 4])),
            || {
                time(Stage::ForceSurface, || {
                    fitter.lm(model, &free.theta, &[0, 1, 2, 3, 4, 5])
                })
            },
        );
        let held = fitter.limits.replay(&mut done, &held_work, held)?;
        let on_surface = fitter
            .limits
            .replay(&mut done, &surface_work, on_surface)
            .ok();
        Ok(Self {
            per_model,
            best,
            held,
            on_surface,
        })
    }

    /// Each contact model's fit with n free, those that converged, their
    /// work counted into `done` in [`ContactModel::ALL`]'s order.
    fn free_fits(
        fitter: &Fitter<'_>,
        theta0: &[f64],
        done: &mut usize,
    ) -> Result<Vec<(ContactModel, LmFit)>, ForceFitError> {
        let per_model: Vec<_> = {
            use rayon::prelude::*;
            ContactModel::ALL
                .par_iter()
                .map(|&model| {
                    time(Stage::ForceFree, || {
                        fitter.lm(model, theta0, &[0, 1, 2, 3, 4])
                    })
                })
                .collect()
        };
        let mut fits: Vec<(ContactModel, LmFit)> = Vec::with_capacity(per_model.len());
        for (&model, (fit, work)) in ContactModel::ALL.iter().zip(per_model) {
            match fitter.limits.replay(done, &work, fit) {
                Ok(f) => fits.push((model, f)),
                Err(e @ ForceFitError::Limit(_)) => return Err(e),
                Err(_) => {}
            }
        }
        Ok(fits)
    }

    /// The best model's fit, n free.
    fn free(&self) -> &LmFit {
        &self.per_model[self.best].1
    }

    /// The models' Akaike weights (equal parameter counts), with the χ²
    /// differences scaled by the best fit's χ²/dof where the frames scatter
    /// more than their σ say (quasi-likelihood).
    fn model_weights(&self) -> Vec<ModelFit> {
        let free = self.free();
        let c_hat = (free.cost / free.dof as f64).max(1.0);
        let raw: Vec<f64> = self
            .per_model
            .iter()
            .map(|(_, f)| (-(f.cost - free.cost) / (2.0 * c_hat)).exp())
            .collect();
        let total: f64 = raw.iter().sum();
        self.per_model
            .iter()
            .zip(&raw)
            .map(|((m, f), w)| ModelFit {
                model: *m,
                chi2: f.cost,
                n: f.theta[3],
                weight: w / total,
            })
            .collect()
    }

    /// The spread of `value` over the models weighted by `models`, about the
    /// best one's value (Burnham & Anderson's model-averaged variance).
    fn spread(&self, models: &[ModelFit], value: &dyn Fn(&LmFit) -> f64) -> f64 {
        let v0 = value(self.free());
        self.per_model
            .iter()
            .zip(models)
            .map(|((_, f), m)| m.weight * (value(f) - v0).powi(2))
            .sum::<f64>()
            .sqrt()
    }

    /// The contact law of the best model: its fits' values, their errors
    /// with the geometry's (`frames`' nuisances) and the spread over the
    /// models added to each.
    fn law(&self, frames: &FitFrames, geom: &Geometry, mass: f64) -> ForceLaw {
        let s_m = frames.s_m;
        let (model, free) = (self.per_model[self.best].0, self.free());
        let surface_offset_px = self.on_surface.as_ref().map(|f| Measured {
            value: f.theta[5] / s_m,
            err: f.sd_with(5, &[]) / s_m,
        });
        let nuisances = frames.nuisances(geom);
        // The residuals' change per px of surface moved down (obs shrinks by s).
        let per_surface_px = frames.per_frame(&|_| -s_m);
        let sd = |fit: &LmFit, i: usize| fit.sd_with(i, &nuisances);
        let models = self.model_weights();
        let k_of = |fit: &LmFit| {
            let km = fit.theta[2].exp();
            Measured {
                value: km * mass,
                err: km * mass * sd(fit, 2),
            }
        };
        let k_free = k_of(free);
        let ln_k_spread = self.spread(&models, &|f| f.theta[2]);
        ForceLaw {
            model,
            k: Measured {
                value: k_free.value,
                err: k_free.err.hypot(k_free.value * ln_k_spread),
            },
            n: Measured {
                value: free.theta[3],
                err: sd(free, 3).hypot(self.spread(&models, &|f| f.theta[3])),
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
            k_at_n2: k_of(&self.held),
            surface_offset_px,
            n_per_surface_px: free.response_to(3, &per_surface_px),
            k_per_surface_px: free.theta[2].exp() * mass * free.response_to(2, &per_surface_px),
            chi2_red: free.cost / free.dof as f64,
            models,
            n_frames: frames.obs.len(),
        }
    }
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
