//! Free fall's scale: the curvature z̈ (px/s²) of a run's free flights,
//! fitted jointly over every flight, and the weighted pool of a camera
//! set-up's runs. The frame rate is exact, so s = g / z̈ (mm/px) with its
//! error ([`Curvature::mm_per_px`]).

use crate::measure::events::TrackPoint;
use crate::util::lsq::{weighted_lsq_built, RowQr};
use nalgebra::DMatrix;

/// A flight frame has the sphere's apparent bottom at least this far above
/// the surface line (px), clear of any contact.
pub const FLIGHT_CLEARANCE_PX: f64 = 1.5;

/// Fewest frames in one flight segment for it to enter the curvature fit.
pub const MIN_SEGMENT_FRAMES: usize = 6;

/// The free flight's curvature z̈ (px/s²) with its one-sigma error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Curvature {
    /// The curvature z̈, px/s².
    pub g_px_s2: f64,
    /// Its one-sigma error, px/s².
    pub err_px_s2: f64,
    /// Frames (over all flights, or all runs when pooled) behind it.
    pub frames: usize,
}

impl Curvature {
    /// The scale it gives, mm/px, for gravity `g_m_s2`.
    pub fn mm_per_px(&self, g_m_s2: f64) -> f64 {
        1e3 * g_m_s2 / self.g_px_s2
    }

    /// Relative one-sigma error of that scale.
    pub fn rel_err(&self) -> f64 {
        self.err_px_s2 / self.g_px_s2
    }
}

/// The curvature of every free flight of a run (before the contact, after
/// the rebound, after later bounces), fitted jointly: one parabola per
/// flight with its own position and velocity and one shared z̈. A frame is
/// in flight when the apparent bottom `z + r_app_px` is
/// [`FLIGHT_CLEARANCE_PX`] above the surface row `row_at(x)`. `None` with
/// no flight of [`MIN_SEGMENT_FRAMES`] frames.
///
/// `points` walks the run's points from the start each time it is called
/// (two to four times): none is held. The fit is one QR of the whole
/// design while it and the data have at most [`DENSE_FIT_MAX_NUMBERS`] numbers; beyond
/// (a long movie's many flights), the same least squares fed a row at a
/// time ([`RowQr`]), each flight's own parameters eliminated as it ends:
/// a few numbers a flight, whatever the movie's length. The two agree to
/// rounding (1e-12 relative in a test).
pub fn free_fall_curvature<I: Iterator<Item = TrackPoint>>(
    points: impl Fn() -> I,
    row_at: impl Fn(f64) -> f64,
    r_app_px: f64,
) -> Option<Curvature> {
    let segments = flight_segments(points(), row_at, r_app_px);
    let k = segments.len();
    let n: usize = segments.iter().map(|s| s.len).sum();
    if k == 0 || n < 2 * k + 2 {
        return None;
    }
    if n * (2 * k + 3) <= DENSE_FIT_MAX_NUMBERS {
        curvature_dense(&segments, || in_flight(points(), &segments))
    } else {
        curvature_by_rows(&segments, in_flight(points(), &segments))
    }
}

/// The most numbers (frames in flight × (2·flights + 3): the design, z and
/// σ) for which the free-fall fit is one QR of the whole design (two copies
/// of it at once: at most 8 MiB): every drop of the e2e bench's data but
/// the 124 166-frame movie's eight flights (7.9 MB a copy).
pub const DENSE_FIT_MAX_NUMBERS: usize = 1 << 19;

/// A flight: consecutive points in flight, from point `start` (in the
/// order walked), `len` of them, about their mean time `t_ref_s`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Segment {
    start: usize,
    len: usize,
    t_ref_s: f64,
}

/// The flights of [`MIN_SEGMENT_FRAMES`] or more points among `points`.
fn flight_segments(
    points: impl Iterator<Item = TrackPoint>,
    row_at: impl Fn(f64) -> f64,
    r_app_px: f64,
) -> Vec<Segment> {
    let mut segments = Vec::new();
    // The open segment: its start, length and the sum of its times (in
    // order, as `Iterator::sum` adds them).
    let mut open: Option<(usize, usize, f64)> = None;
    let mut close = |open: Option<(usize, usize, f64)>| {
        if let Some((start, len, sum_t)) = open.filter(|o| o.1 >= MIN_SEGMENT_FRAMES) {
            segments.push(Segment {
                start,
                len,
                t_ref_s: sum_t / len as f64,
            });
        }
    };
    for (i, p) in points.enumerate() {
        let flying = p.z_px + r_app_px + FLIGHT_CLEARANCE_PX < row_at(p.x_px);
        open = match (flying, open) {
            (true, None) => Some((i, 1, p.t_s)),
            (true, Some((s, len, sum_t))) => Some((s, len + 1, sum_t + p.t_s)),
            (false, o) => {
                close(o);
                None
            }
        };
    }
    close(open);
    segments
}

/// The points of `segments` among `points`, each with its segment's index.
fn in_flight<'a>(
    points: impl Iterator<Item = TrackPoint> + 'a,
    segments: &'a [Segment],
) -> impl Iterator<Item = (usize, TrackPoint)> + 'a {
    let mut j = 0;
    points.enumerate().filter_map(move |(i, p)| {
        while j < segments.len() && i >= segments[j].start + segments[j].len {
            j += 1;
        }
        let s = segments.get(j)?;
        (i >= s.start).then_some((j, p))
    })
}

/// The curvature fit by one QR of the whole design ([`weighted_lsq_built`]),
/// the points in flight walked again for each copy of it.
fn curvature_dense<J: Iterator<Item = (usize, TrackPoint)>>(
    segments: &[Segment],
    flight: impl Fn() -> J,
) -> Option<Curvature> {
    let (k, n) = (segments.len(), segments.iter().map(|s| s.len).sum());
    // Columns: per segment an offset and a velocity about its mean time,
    // then ½τ² shared. The design is made when the fit needs it (twice),
    // never held beside it.
    let design = || {
        let mut design = DMatrix::zeros(n, 2 * k + 1);
        for (row, (j, p)) in flight().enumerate().take(n) {
            let tau = p.t_s - segments[j].t_ref_s;
            design[(row, 2 * j)] = 1.0;
            design[(row, 2 * j + 1)] = tau;
            design[(row, 2 * k)] = 0.5 * tau * tau;
        }
        design
    };
    let (y, sigma): (Vec<f64>, Vec<f64>) = flight().map(|(_, p)| (p.z_px, p.sigma_z_px)).unzip();
    let fit = weighted_lsq_built(design, &y, &sigma)?;
    curvature_of(fit.coef[2 * k], fit.stderr(2 * k), n)
}

/// The same fit as [`curvature_dense`], a row at a time: each flight's rows
/// `[1, τ, ½τ²]/σ ≈ z/σ` rotated into its own 3 × 3 triangle, whose last
/// row (z̈'s alone, once the flight's offset and velocity are solved for)
/// goes into the shared one when the flight ends.
fn curvature_by_rows(
    segments: &[Segment],
    points: impl Iterator<Item = (usize, TrackPoint)>,
) -> Option<Curvature> {
    let (k, n): (usize, usize) = (segments.len(), segments.iter().map(|s| s.len).sum());
    let mut shared = RowQr::<1>::default();
    let mut rss = 0.0;
    let mut diagonal = Vec::with_capacity(2 * k + 1);
    let mut flight: Option<(usize, RowQr<3>)> = None;
    let mut end = |f: RowQr<3>, shared: &mut RowQr<1>, rss: &mut f64| {
        diagonal.extend([f.r[0][0].abs(), f.r[1][1].abs()]);
        shared.push([f.r[2][2]], f.qty[2]);
        *rss += f.rss;
    };
    for (j, p) in points {
        if !(p.sigma_z_px.is_finite() && p.sigma_z_px > 0.0) {
            return None;
        }
        let w = 1.0 / p.sigma_z_px;
        let tau = p.t_s - segments[j].t_ref_s;
        match &mut flight {
            Some((jf, _)) if *jf == j => {}
            _ => {
                if let Some((_, f)) = flight.take() {
                    end(f, &mut shared, &mut rss);
                }
                flight = Some((j, RowQr::default()));
            }
        }
        if let Some((_, f)) = &mut flight {
            f.push([w, tau * w, 0.5 * tau * tau * w], p.z_px * w);
        }
    }
    if let Some((_, f)) = flight {
        end(f, &mut shared, &mut rss);
    }
    // As the QR's rank check: no diagonal of R at or below 1e-13 of the largest.
    let r_g = shared.r[0][0].abs();
    let rmax = diagonal.iter().copied().fold(r_g, f64::max);
    let rank_deficient = diagonal.iter().chain([&r_g]).any(|d| *d <= rmax * 1e-13);
    if rmax.is_nan() || rmax <= 0.0 || rank_deficient || shared.rows != k {
        return None;
    }
    let g = shared.qty[0] / shared.r[0][0];
    let (chi2, dof) = (rss + shared.rss, n - (2 * k + 1));
    let chi2_red = if dof == 0 { 1.0 } else { chi2 / dof as f64 };
    let cov_g = 1.0 / (shared.r[0][0] * shared.r[0][0]);
    curvature_of(g, (cov_g * chi2_red.max(1.0)).sqrt(), n)
}

/// z̈ and its error as a [`Curvature`], when physical.
fn curvature_of(g: f64, err: f64, frames: usize) -> Option<Curvature> {
    (g.is_finite() && g > 0.0 && err.is_finite()).then_some(Curvature {
        g_px_s2: g,
        err_px_s2: err,
        frames,
    })
}

/// The weighted mean of runs' curvatures (one camera set-up), its error
/// scaled by √χ²_red when the runs scatter more than their errors say.
pub fn pool(curvatures: &[Curvature]) -> Option<Curvature> {
    let w: Vec<f64> = curvatures
        .iter()
        .map(|c| 1.0 / (c.err_px_s2 * c.err_px_s2))
        .collect();
    let sw: f64 = w.iter().sum();
    if curvatures.is_empty() || !(sw.is_finite() && sw > 0.0) {
        return None;
    }
    let mean = curvatures
        .iter()
        .zip(&w)
        .map(|(c, w)| c.g_px_s2 * w)
        .sum::<f64>()
        / sw;
    let chi2: f64 = curvatures
        .iter()
        .zip(&w)
        .map(|(c, w)| (c.g_px_s2 - mean).powi(2) * w)
        .sum();
    let dof = curvatures.len().saturating_sub(1).max(1) as f64;
    Some(Curvature {
        g_px_s2: mean,
        err_px_s2: (1.0 / sw).sqrt() * (chi2 / dof).max(1.0).sqrt(),
        frames: curvatures.iter().map(|c| c.frames).sum(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A drop's track: flights under `g_px` before t = 0 and after the
    /// rebound at t = τ, contact between, with noise σ from a fixed sequence.
    fn flights(g_px: f64, sigma: f64) -> Vec<TrackPoint> {
        let fps = 10_000.0;
        let v = 30_000.0; // px/s at contact
        let tau = 0.003;
        let surface = 300.0;
        let r = 80.0;
        let mut out = Vec::new();
        for i in -40..70 {
            let t = i as f64 / fps;
            let z = if t < 0.0 {
                surface - r + v * t + 0.5 * g_px * t * t
            } else if t > tau {
                let u = t - tau;
                surface - r - 0.9 * v * u + 0.5 * g_px * u * u
            } else {
                surface - r + 5.0 // in contact: below the clearance
            };
            let noise = sigma * ((i * 7919 % 13) as f64 / 6.0 - 1.0);
            out.push(TrackPoint {
                frame: i,
                t_s: t,
                x_px: 256.0,
                z_px: z + noise,
                sigma_z_px: sigma,
                half_width_px: None,
                sigma_half_width_px: None,
            });
        }
        out
    }

    #[test]
    fn free_fall_gives_the_curvature_and_the_scale() {
        let s_mm = 0.06;
        let g_px = 9.81 / (s_mm * 1e-3);
        let c = free_fall_curvature(|| flights(g_px, 0.003).into_iter(), |_| 300.0, 80.0).unwrap();
        // Both flights: 40 + ~36 frames; the noise is ±0.003 px.
        assert!((c.g_px_s2 / g_px - 1.0).abs() < 3.0 * c.rel_err(), "{c:?}");
        assert!(c.rel_err() < 0.01, "{c:?}");
        assert!((c.mm_per_px(9.81) / s_mm - 1.0).abs() < 3.0 * c.rel_err());
        // Exact without noise.
        let c = free_fall_curvature(|| flights(g_px, 1e-9).into_iter(), |_| 300.0, 80.0).unwrap();
        assert!((c.g_px_s2 / g_px - 1.0).abs() < 1e-9, "{c:?}");
        assert_eq!(c.frames, 40 + 39);
    }

    /// `flights` bounces of `frames` frames each at 60 000 frames/s under
    /// `g_px`, five contact frames between, with noise σ varying by frame.
    fn bounces(g_px: f64, flights: usize, frames: usize) -> Vec<TrackPoint> {
        let fps = 60_000.0;
        let (surface, r) = (300.0, 40.0);
        let v0 = 0.5 * g_px * frames as f64 / fps;
        let mut out = Vec::new();
        let mut i = 0i64;
        for b in 0..flights {
            for k in 0..frames + 5 {
                let u = k as f64 / fps;
                let z = if k < frames {
                    surface - r - (0.97f64.powi(b as i32) * v0 * u - 0.5 * g_px * u * u)
                } else {
                    surface - r + 3.0
                };
                let sigma = 0.01 + 0.002 * (i % 5) as f64;
                out.push(TrackPoint {
                    frame: i,
                    t_s: i as f64 / fps,
                    x_px: 128.0,
                    z_px: z + sigma * ((i * 7919 % 13) as f64 / 6.0 - 1.0),
                    sigma_z_px: sigma,
                    half_width_px: None,
                    sigma_half_width_px: None,
                });
                i += 1;
            }
        }
        out
    }

    #[test]
    fn a_long_movies_flights_fitted_a_row_at_a_time_agree_with_one_qr() {
        // Eight flights of 6 000 frames: past the dense fit's size, as the
        // 124 166-frame movie.
        let g_px = 9.81 / 0.08e-3;
        let pts = bounces(g_px, 8, 6000);
        let row_at = |_: f64| 300.0;
        let segments = flight_segments(pts.iter().copied(), row_at, 40.0);
        assert_eq!(segments.len(), 8);
        let n: usize = segments.iter().map(|s| s.len).sum();
        assert!(n * (2 * 8 + 3) > DENSE_FIT_MAX_NUMBERS);
        let flight = || in_flight(pts.iter().copied(), &segments);
        let dense = curvature_dense(&segments, flight).unwrap();
        let rows = curvature_by_rows(&segments, flight()).unwrap();
        assert_eq!(
            free_fall_curvature(|| pts.iter().copied(), row_at, 40.0),
            Some(rows)
        );
        assert!(
            (rows.g_px_s2 / dense.g_px_s2 - 1.0).abs() < 1e-12,
            "{rows:?} {dense:?}"
        );
        assert!(
            (rows.err_px_s2 / dense.err_px_s2 - 1.0).abs() < 1e-9,
            "{rows:?} {dense:?}"
        );
        assert_eq!(rows.frames, dense.frames);
        // And both measure gravity: ±0.01 px of noise on 47 000 frames.
        assert!(
            (rows.g_px_s2 / g_px - 1.0).abs() < 3.0 * rows.rel_err(),
            "{rows:?}"
        );
        assert!(rows.rel_err() < 1e-4, "{rows:?}");
        // A small track takes the dense fit: the same bits as the dense QR.
        let short = bounces(g_px, 2, 300);
        let segments = flight_segments(short.iter().copied(), row_at, 40.0);
        assert_eq!(
            free_fall_curvature(|| short.iter().copied(), row_at, 40.0),
            curvature_dense(&segments, || in_flight(short.iter().copied(), &segments))
        );
        // A point without a usable σ leaves no fit either way.
        let mut bad = pts.clone();
        bad[100].sigma_z_px = 0.0;
        assert_eq!(
            free_fall_curvature(|| bad.iter().copied(), row_at, 40.0),
            None
        );
    }

    #[test]
    fn pooling_weights_by_error_and_widens_on_scatter() {
        let c = |g: f64, e: f64| Curvature {
            g_px_s2: g,
            err_px_s2: e,
            frames: 10,
        };
        let p = pool(&[c(100.0, 1.0), c(102.0, 2.0)]).unwrap();
        assert!((p.g_px_s2 - (100.0 + 102.0 / 4.0) / 1.25).abs() < 1e-12);
        assert!((p.err_px_s2 - (1.0f64 / 1.25).sqrt()).abs() < 1e-12);
        let p = pool(&[c(100.0, 1.0), c(110.0, 1.0)]).unwrap();
        assert!(p.err_px_s2 > 4.0, "{p:?}");
        assert!(pool(&[]).is_none());
    }
}
