//! A recording whose sphere is tracked but never reaches the surface (a
//! calibration drop, a new rig, a clip cut before the impact): its free
//! flight alone, as the `tracked` row gives it.
//!
//! The centre row is fitted with the same parabola as a drop's flights
//! ([`crate::measure::events::fit_flight`]): z(t) = z0 + v0·τ + ½·g_px·τ², g_px = g /
//! s with g known, and the vertical velocity (positive downward) is read at
//! the last tracked frame. In metres per second v = s·v(t_last) =
//! s·v0 + g·(t_last − t_ref): the scale s enters through s·v0 only, and its
//! error is carried by a derivative in s. Gravity with g free (a quadratic
//! in t) is the check on the frame rate and the scale, as for a drop; over
//! a short clip it is imprecise and its error says so. An exposure-averaged
//! position is z(t) + z̈·T²/24, a constant shift of a parabola: the
//! velocity is unchanged.

use crate::measure::events::{fit_flight, TrackPoint};
use crate::measure::kinematics::Measured;

/// The free flight of a run without a contact.
#[derive(Debug, Clone, PartialEq)]
pub struct FreeFlight {
    /// Time of the last tracked frame (mid-exposure, after the trigger).
    pub t_last_s: f64,
    /// Vertical velocity at `t_last_s`, positive downward, m/s.
    pub v_last_m_s: Measured,
    /// Gravity from the fit with g free, m/s² (`None`: too few frames).
    pub g_fit_m_s2: Option<Measured>,
    /// Frames fitted.
    pub frames: usize,
}

/// Fewest tracked frames for a free-flight fit.
pub const MIN_FLIGHT_FRAMES: usize = 5;

/// Why there is no free-flight fit.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FlightError {
    /// Fewer tracked frames than the fit needs (the count).
    #[error("only {0} tracked frames: a free-flight fit needs at least {MIN_FLIGHT_FRAMES}")]
    TooFewFrames(usize),
    /// The least-squares fit was degenerate.
    #[error("the free-flight fit failed (degenerate frames)")]
    FitFailed,
}

/// Fit the free flight of `points` (held-radius centres, in time order)
/// at scale `mm_per_px` (relative one-sigma error `scale_rel_err`) under
/// gravity `g_m_s2`.
pub fn free_flight(
    points: &[TrackPoint],
    mm_per_px: f64,
    scale_rel_err: f64,
    g_m_s2: f64,
) -> Result<FreeFlight, FlightError> {
    if points.len() < MIN_FLIGHT_FRAMES {
        return Err(FlightError::TooFewFrames(points.len()));
    }
    let t_last_s = points[points.len() - 1].t_s;
    // v at the last frame (m/s) and its fit's σ, at scale `s`.
    let v_at = |s: f64| {
        let to_m = s * 1e-3;
        let fit = fit_flight(points, g_m_s2 / to_m)?;
        let v = fit.v_at(t_last_s) * to_m;
        Some((v, fit.cov[1][1].max(0.0).sqrt() * to_m, fit))
    };
    let (v, v_fit_err, fit) = v_at(mm_per_px).ok_or(FlightError::FitFailed)?;
    let h = 1e-6 * mm_per_px;
    let dv_ds = match (v_at(mm_per_px + h), v_at(mm_per_px - h)) {
        (Some((a, _, _)), Some((b, _, _))) => (a - b) / (2.0 * h),
        _ => return Err(FlightError::FitFailed),
    };
    let v_err = v_fit_err.hypot(dv_ds * mm_per_px * scale_rel_err);
    let g_fit_m_s2 = fit.g_free_px_s2.map(|(g_px, err_px)| {
        let g = g_px * mm_per_px * 1e-3;
        Measured {
            value: g,
            err: (err_px * mm_per_px * 1e-3).hypot(g * scale_rel_err),
        }
    });
    Ok(FreeFlight {
        t_last_s,
        v_last_m_s: Measured {
            value: v,
            err: v_err,
        },
        g_fit_m_s2,
        frames: points.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// A sphere falling under g at 30 000 frames/s, seen at 0.02 mm/px with
    /// 0.03 px of noise: v at the last frame within 3σ of the truth, its σ
    /// the fit's (its r.m.s. over 200 seeds against their spread, within 20 %),
    /// and the scale's error carried in full (1 % of s is 1 % of v).
    #[test]
    fn the_velocity_at_the_last_frame_is_the_truth_within_its_error() {
        let (g, s, fps, v0) = (9.81, 0.02, 30_000.0, 1.5);
        let track = |seed: u64, n: usize| -> Vec<TrackPoint> {
            let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
            let noise = Normal::new(0.0, 0.03).unwrap();
            (0..n)
                .map(|i| {
                    let t = i as f64 / fps;
                    let z_m = v0 * t + 0.5 * g * t * t;
                    TrackPoint {
                        frame: i as i64,
                        t_s: t,
                        x_px: 100.0,
                        z_px: 50.0 + z_m / (s * 1e-3) + noise.sample(&mut rng),
                        sigma_z_px: 0.03,
                        half_width_px: None,
                        sigma_half_width_px: None,
                    }
                })
                .collect()
        };
        let n = 15;
        let truth = v0 + g * (n - 1) as f64 / fps;
        let fits: Vec<FreeFlight> = (0..200)
            .map(|seed| free_flight(&track(seed, n), s, 0.0, g).unwrap())
            .collect();
        let vs: Vec<f64> = fits.iter().map(|f| f.v_last_m_s.value).collect();
        let mean = vs.iter().sum::<f64>() / vs.len() as f64;
        let sd =
            (vs.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (vs.len() - 1) as f64).sqrt();
        // Each fit's σ is scaled by its own χ²_red (13 degrees of
        // freedom: ±40 % from fit to fit); their r.m.s. is the spread's.
        let rms =
            (fits.iter().map(|f| f.v_last_m_s.err.powi(2)).sum::<f64>() / fits.len() as f64).sqrt();
        assert!(
            (mean - truth).abs() < 3.0 * sd / (vs.len() as f64).sqrt(),
            "{mean} vs {truth}"
        );
        let stated = fits[0].v_last_m_s.err;
        assert!((rms / sd - 1.0).abs() < 0.2, "stated {rms}, spread {sd}");
        assert_eq!(fits[0].t_last_s, (n - 1) as f64 / fps);
        let f = free_flight(&track(0, n), s, 0.01, g).unwrap();
        let scale_part = (f.v_last_m_s.err.powi(2) - stated.powi(2)).sqrt();
        // s·v0 is v less g·(t_last − t_ref): 1 % of it.
        let sv0 = truth - g * 0.5 * (n - 1) as f64 / fps;
        assert!(
            (scale_part / (0.01 * sv0) - 1.0).abs() < 1e-3,
            "{scale_part}"
        );
        // Gravity with g free: right within its (large, 15 frames) error.
        let gf = f.g_fit_m_s2.unwrap();
        assert!((gf.value - g).abs() < 4.0 * gf.err, "{gf:?}");
        assert_eq!(
            free_flight(&track(0, 4), s, 0.0, g),
            Err(FlightError::TooFewFrames(4))
        );
    }
}
