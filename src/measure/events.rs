//! Contact onset, maximum penetration and loss of contact from a track
//! (SPEC §2, "Events").
//!
//! The free flight before contact is a parabola in time with the known
//! gravity g: z(t) = z0 + v0·τ + ½·g_px·τ², τ = t − t_ref, fitted by weighted
//! least squares to the frames whose sphere bottom is clear of the surface
//! line by a margin. Contact onset is where that parabola's bottom,
//! z + R_px, meets the undeformed surface row y_s at the impact column — a
//! sub-frame time. Loss of contact is the same with the flight after the
//! bounce (its ascending root). The maximum penetration comes from a local
//! polynomial fit of z(t) around its peak, not from the largest sample.
//!
//! Rows grow downward: z increases as the sphere falls, and the penetration
//! is δ = (z + R_px − y_s)·s, positive in contact.

use crate::util::lsq::{LinearFit, PolyFit};
use nalgebra::DMatrix;

/// One measured frame of a track, as detection hands it on. Frames where the
/// sphere was not measured are simply absent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackPoint {
    /// Camera image number.
    pub frame: i64,
    /// Mid-exposure time relative to the trigger.
    pub t_s: f64,
    /// Centre column.
    pub x_px: f64,
    /// Centre row.
    pub z_px: f64,
    /// One-sigma uncertainty of `z_px` (> 0).
    pub sigma_z_px: f64,
    /// Half-width of the silhouette along the surface line, where measured.
    pub half_width_px: Option<f64>,
    /// One-sigma uncertainty of `half_width_px`.
    pub sigma_half_width_px: Option<f64>,
}

/// Calibration of a run: the surface line, the sphere's radius in pixels and
/// the scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Geometry {
    /// Undeformed surface row at column 0; the line is row = y0 + slope·column.
    pub surface_row_px: f64,
    /// Surface tilt, rows per column.
    pub surface_slope: f64,
    /// One-sigma uncertainty of the surface row near the impact column.
    pub surface_row_err_px: f64,
    /// The sphere's radius in the image, px.
    pub radius_px: f64,
    /// One-sigma uncertainty of `radius_px`, px.
    pub radius_err_px: f64,
    /// Scale s in mm per pixel.
    pub mm_per_px: f64,
    /// One-sigma uncertainty of an independently given scale; ignored when
    /// `scale_from_radius` (then s = R_mm / R_px and its error follows R_px's).
    pub mm_per_px_err: f64,
    /// True when s was measured as R_mm / R_px.
    pub scale_from_radius: bool,
}

impl Geometry {
    /// Surface row at column `x_px`.
    pub fn surface_row_at(&self, x_px: f64) -> f64 {
        self.surface_row_px + self.surface_slope * x_px
    }

    /// Penetration in pixels of a sphere centred at (x, z), along the
    /// surface's normal: R − (y_s(x) − z)·cos θ, tan θ the line's slope
    /// (the row distance to a tilted line is longer than the normal one).
    pub fn penetration_px(&self, x_px: f64, z_px: f64) -> f64 {
        self.radius_px - (self.surface_row_at(x_px) - z_px) * self.cos_tilt()
    }

    /// cos θ of the surface line's tilt θ = atan(slope).
    pub fn cos_tilt(&self) -> f64 {
        1.0 / self.surface_slope.hypot(1.0)
    }

    /// Gravity in pixels per second squared (rows downward).
    pub fn g_px_s2(&self, g_m_s2: f64) -> f64 {
        g_m_s2 / (self.mm_per_px * 1e-3)
    }
}

/// The surface's own frame: image coordinates turned by the line's tilt θ
/// about a point of the line, so that the line is level (row `row_px`)
/// and rows run along its normal. An impact happens along the normal:
/// the speed that compresses the surface is the normal one, the
/// penetration is measured along it, and a sphere drifting along the
/// surface moves along the level frame's columns only. With the camera
/// rolled by θ (the surface level, the fall along its normal) gravity
/// points down the level frame's rows exactly; with the camera level and
/// the surface tilted it would point 1 − cos θ off them (1.5e-4 at 1°).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceFrame {
    /// The pivot's column, px (kept by the turn).
    pub col_px: f64,
    /// The pivot's row, on the line: the level line's row, px.
    pub row_px: f64,
    /// cos θ.
    pub cos: f64,
    /// sin θ.
    pub sin: f64,
}

impl SurfaceFrame {
    /// The frame of `geom`'s line, pivoting at column `col_px`.
    pub fn of(geom: &Geometry, col_px: f64) -> Self {
        Self::of_line(geom.surface_row_px, geom.surface_slope, col_px)
    }

    /// The frame of the line row = `row0_px` + `slope`·column, pivoting at
    /// column `col_px`.
    pub fn of_line(row0_px: f64, slope: f64, col_px: f64) -> Self {
        let cos = 1.0 / slope.hypot(1.0);
        SurfaceFrame {
            col_px,
            row_px: row0_px + slope * col_px,
            cos,
            sin: slope * cos,
        }
    }

    /// A point in the level frame: its column along the line, its row
    /// along the normal (σ of the row kept: the turn mixes in sin θ ≪ 1
    /// of the column's).
    pub fn level(&self, p: &TrackPoint) -> TrackPoint {
        let (dx, dz) = (p.x_px - self.col_px, p.z_px - self.row_px);
        TrackPoint {
            x_px: self.col_px + dx * self.cos + dz * self.sin,
            z_px: self.row_px + dz * self.cos - dx * self.sin,
            ..*p
        }
    }

    /// `geom` in the level frame: the line at `row_px`, no slope.
    pub fn level_geometry(&self, geom: &Geometry) -> Geometry {
        Geometry {
            surface_row_px: self.row_px,
            surface_slope: 0.0,
            ..*geom
        }
    }

    /// The image column of the line's point at level column `x_px`.
    pub fn image_col(&self, x_px: f64) -> f64 {
        self.col_px + (x_px - self.col_px) * self.cos
    }
}

/// Settings of the event stage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EventConfig {
    /// Gravitational acceleration.
    pub g_m_s2: f64,
    /// Flight frames must have their bottom at least this far above the line.
    pub flight_margin_px: f64,
    /// Fewest flight frames on either side of the contact for a fit.
    pub min_flight_frames: usize,
    /// The peak fit (a quartic in t) uses the contact frames with δ above this
    /// fraction of the largest sampled δ, and at least the seven deepest.
    /// Wider windows average more noise but bias the quartic: on a 24-frame
    /// contact, 0.5 gives −4·10⁻⁴ relative, 0.75 about −5·10⁻⁵.
    pub peak_fraction: f64,
    /// Exposure time T of a frame. A frame shows the silhouette averaged over
    /// its exposure, so a measured position is the mean of z over
    /// [t − T/2, t + T/2] = z(t) + z̈(t)·T²/24 + O(T⁴). The peak values are
    /// corrected by that term (0 switches the correction off).
    pub exposure_s: f64,
    /// The contact-law fit's work limit, in trajectories' worth of steps
    /// (default [`FORCE_FIT_MAX_TRAJECTORIES`]; a clean drop
    /// needs about 400). The fit stops beyond it with a reason.
    pub force_fit_max_trajectories: usize,
}

impl Default for EventConfig {
    fn default() -> Self {
        EventConfig {
            g_m_s2: 9.81,
            flight_margin_px: 1.0,
            min_flight_frames: 5,
            peak_fraction: 0.75,
            exposure_s: 0.0,
            force_fit_max_trajectories: FORCE_FIT_MAX_TRAJECTORIES,
        }
    }
}

/// Flight frames on either side of the contact used by [`crate::measure::force_fit::fit_force_law`].
pub const FLIGHT_FRAMES: usize = 12;

/// The trajectory fit's work limit, in trajectories' worth of steps (a
/// trajectory at its usual cost: `CONTACT_STEPS_PER_FRAME` (20) RK4 steps per
/// frame interval of the contact, one step per time asked for): a clean
/// drop's six fits (four contact models, n = 2, the surface free)
/// integrate about 400 trajectories (the unit tests' drop), so this is
/// reached only by a fit that wanders (frame times off their grid, a track
/// that is no bounce), which it stops within a second or so.
pub const FORCE_FIT_MAX_TRAJECTORIES: usize = 2_500;

/// Why events could not be found.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EventError {
    /// Fewer measured frames than the fits need (the count).
    #[error("too few measured frames ({0}) to find any event")]
    TooFewFrames(usize),
    /// The sphere's bottom never comes down to the surface line.
    #[error(
        "the sphere never reaches the surface line (closest approach {gap_px:.2} px above it)"
    )]
    NeverLands {
        /// The smallest gap between the sphere's bottom and the line, px.
        gap_px: f64,
    },
    /// The first measured frame is already in contact.
    #[error("the sphere is already in contact in the first measured frame ({frame}): no free flight before contact")]
    NoFlightBeforeContact {
        /// That first measured frame's image number.
        frame: i64,
    },
    /// Too few free-flight frames before the contact to fit the impact.
    #[error("only {found} free-flight frames before contact (at least {needed} needed)")]
    ShortFlightBeforeContact {
        /// Free-flight frames before the contact.
        found: usize,
        /// The fewest the fit accepts.
        needed: usize,
    },
    /// The last measured frame is still in contact.
    #[error(
        "the sphere is still in contact at the last measured frame ({frame}): no rebound recorded"
    )]
    NoRebound {
        /// That last measured frame's image number.
        frame: i64,
    },
    /// Too few free-flight frames after the contact to fit the rebound.
    #[error("only {found} free-flight frames after the rebound (at least {needed} needed)")]
    ShortFlightAfterContact {
        /// Free-flight frames after the contact.
        found: usize,
        /// The fewest the fit accepts.
        needed: usize,
    },
    /// Too few frames around the maximum penetration to fit the peak (the count).
    #[error("only {0} frames around the maximum penetration: cannot fit the peak")]
    ShortPeak(usize),
    /// A least-squares fit was degenerate; names the fit (`pre-contact flight`, `peak`, …).
    #[error("the {0} fit failed (degenerate frames)")]
    FitFailed(&'static str),
    /// A flight parabola never meets the surface line; names the flight (`pre-contact`, …).
    #[error("the {0} parabola never meets the surface line")]
    NoCrossing(&'static str),
    /// A frame's time is not finite or not after the previous frame's.
    #[error("frame {frame}: its time {t_s} s is not after the previous frame's (frame times must be finite and increasing)")]
    TimesNotIncreasing {
        /// The frame's image number.
        frame: i64,
        /// Its time, s.
        t_s: f64,
    },
    /// The numbers measured are physically impossible (δmax not below the sphere's radius, or not finite); says which.
    #[error("impossible result: {0}")]
    Impossible(String),
    /// A frame's position or uncertainty is not finite, or its σ is not positive.
    #[error("frame {frame}: its position or uncertainty is not a finite number")]
    NotFinite {
        /// The frame's image number.
        frame: i64,
    },
}

/// A free-flight parabola z(t) = z0 + v0·τ + ½·g·τ² with g fixed, and a
/// straight line x(t) = x0 + vx·τ, τ = t − t_ref.
#[derive(Debug, Clone, PartialEq)]
pub struct FlightFit {
    /// Reference time t_ref (the mean time of the points), s.
    pub t_ref_s: f64,
    /// Centre row z0 at `t_ref_s`, px.
    pub z0_px: f64,
    /// Vertical velocity v0 at `t_ref_s` (positive downward), px/s.
    pub v0_px_s: f64,
    /// Gravity g held fixed in the fit, px/s².
    pub g_px_s2: f64,
    /// Scaled covariance of (z0, v0).
    pub cov: [[f64; 2]; 2],
    /// Reduced χ² of the z fit.
    pub chi2_red: f64,
    /// Centre column x0 at `t_ref_s`, px.
    pub x0_px: f64,
    /// Horizontal velocity vx, px/s.
    pub vx_px_s: f64,
    /// First and last image numbers used.
    pub frames: (i64, i64),
    /// Number of frames fitted.
    pub n_points: usize,
    /// Gravity from a fit with g free, in px/s², and its one-sigma error: a
    /// check on the frame rate and the scale.
    pub g_free_px_s2: Option<(f64, f64)>,
}

impl FlightFit {
    /// The fitted centre row at time `t_s`, px.
    pub fn z_at(&self, t_s: f64) -> f64 {
        let u = t_s - self.t_ref_s;
        self.z0_px + self.v0_px_s * u + 0.5 * self.g_px_s2 * u * u
    }
    /// The fitted vertical velocity at time `t_s` (positive downward), px/s.
    pub fn v_at(&self, t_s: f64) -> f64 {
        self.v0_px_s + self.g_px_s2 * (t_s - self.t_ref_s)
    }
    /// The fitted centre column at time `t_s`, px.
    pub fn x_at(&self, t_s: f64) -> f64 {
        self.x0_px + self.vx_px_s * (t_s - self.t_ref_s)
    }
}

/// Fit a flight parabola with fixed gravity to `points`.
pub fn fit_flight(points: &[TrackPoint], g_px_s2: f64) -> Option<FlightFit> {
    let n = points.len();
    if n < 3 {
        return None;
    }
    let t_ref = points.iter().map(|p| p.t_s).sum::<f64>() / n as f64;
    let a = DMatrix::from_fn(
        n,
        2,
        |i, j| if j == 0 { 1.0 } else { points[i].t_s - t_ref },
    );
    let y: Vec<f64> = points
        .iter()
        .map(|p| p.z_px - 0.5 * g_px_s2 * (p.t_s - t_ref).powi(2))
        .collect();
    let s: Vec<f64> = points.iter().map(|p| p.sigma_z_px).collect();
    let fit: LinearFit = crate::util::lsq::weighted_lsq(&a, &y, &s)?;
    let c = fit.cov_scaled();
    let ts: Vec<f64> = points.iter().map(|p| p.t_s).collect();
    let xs: Vec<f64> = points.iter().map(|p| p.x_px).collect();
    let xfit = PolyFit::fit(&ts, &xs, &vec![1.0; n], 1, t_ref)?;
    let zs: Vec<f64> = points.iter().map(|p| p.z_px).collect();
    let g_free = PolyFit::fit(&ts, &zs, &s, 2, t_ref)
        .map(|q| (q.derivative_at_x0(2), q.derivative_at_x0_err(2)));
    Some(FlightFit {
        t_ref_s: t_ref,
        z0_px: fit.coef[0],
        v0_px_s: fit.coef[1],
        g_px_s2,
        cov: [[c[(0, 0)], c[(0, 1)]], [c[(1, 0)], c[(1, 1)]]],
        chi2_red: fit.chi2_red(),
        x0_px: xfit.derivative_at_x0(0),
        vx_px_s: xfit.derivative_at_x0(1),
        frames: (points[0].frame, points[n - 1].frame),
        n_points: n,
        g_free_px_s2: g_free,
    })
}

/// The time τ (relative to t_ref) where ½·g·τ² + v0·τ + c = 0 with the sphere
/// moving down (`descending`, velocity > 0) or up. Written in the forms that
/// avoid cancellation.
pub fn crossing_time(g: f64, v0: f64, c: f64, descending: bool) -> Option<f64> {
    let a = 0.5 * g;
    let disc = v0 * v0 - 4.0 * a * c;
    if disc < 0.0 {
        return None;
    }
    let sq = disc.sqrt();
    // Roots (−v0 ± √D)/(2a); the descending crossing has velocity +√D.
    let tau = if descending {
        if v0 >= 0.0 {
            -2.0 * c / (v0 + sq)
        } else {
            (-v0 + sq) / (2.0 * a)
        }
    } else if v0 <= 0.0 {
        2.0 * c / (-v0 + sq)
    } else {
        (-v0 - sq) / (2.0 * a)
    };
    tau.is_finite().then_some(tau)
}

/// A polynomial fit of z(t) around the deepest point of the contact.
#[derive(Debug, Clone, PartialEq)]
pub struct PeakFit {
    /// The polynomial z(t) fitted to the frames around the peak.
    pub poly: PolyFit,
    /// Time of the fitted maximum of z.
    pub t_max_s: f64,
    /// First and last image numbers used.
    pub frames: (i64, i64),
}

/// Find the maximum of a polynomial near `t_start` by Newton's method on its
/// derivative, staying within [lo, hi].
pub fn poly_max(p: &PolyFit, t_start: f64, lo: f64, hi: f64) -> f64 {
    if lo
        .partial_cmp(&hi)
        .is_none_or(|o| o == std::cmp::Ordering::Greater)
    {
        return t_start; // no interval to search (f64::clamp would panic)
    }
    let mut t = t_start;
    for _ in 0..50 {
        let d1 = p.deriv(t);
        let d2 = p.deriv2(t);
        if d2 >= 0.0 || !d2.is_finite() {
            break;
        }
        let step = d1 / d2;
        let next = (t - step).clamp(lo, hi);
        if (next - t).abs() < 1e-15 * (1.0 + t.abs()) {
            t = next;
            break;
        }
        t = next;
    }
    t
}

/// Everything the event stage finds in one track.
#[derive(Debug, Clone, PartialEq)]
pub struct Events {
    /// The free flight before the contact.
    pub pre: FlightFit,
    /// The free flight after the rebound.
    pub post: FlightFit,
    /// The fit around the maximum penetration.
    pub peak: PeakFit,
    /// Impact column (x of the pre-contact flight at contact onset).
    pub impact_column_px: f64,
    /// Surface row at the impact column.
    pub surface_row_at_impact_px: f64,
    /// Indices into the track of the first and last frame in contact.
    pub contact_span: (usize, usize),
    /// Start of a second contact (the post-rebound parabola's landing), when
    /// the recording shows one. Never mixed into the first contact's numbers.
    pub second_contact_s: Option<f64>,
}

/// Times finite and strictly increasing; positions and uncertainties finite
/// (σ > 0). Every fit below relies on it.
pub fn check_track(track: &[TrackPoint]) -> Result<(), EventError> {
    let mut prev_t_s = None;
    for p in track {
        check_point(p, prev_t_s)?;
        prev_t_s = Some(p.t_s);
    }
    Ok(())
}

/// [`check_track`] of one point after a point at `prev_t_s`.
fn check_point(p: &TrackPoint, prev_t_s: Option<f64>) -> Result<(), EventError> {
    let finite =
        p.x_px.is_finite() && p.z_px.is_finite() && p.sigma_z_px.is_finite() && p.sigma_z_px > 0.0;
    if !finite {
        return Err(EventError::NotFinite { frame: p.frame });
    }
    if !p.t_s.is_finite() || prev_t_s.is_some_and(|t| p.t_s <= t) {
        return Err(EventError::TimesNotIncreasing {
            frame: p.frame,
            t_s: p.t_s,
        });
    }
    Ok(())
}

/// The points of `points` that [`find_events`] and everything measured
/// from its events (kinematics, the contact law, the force table, the
/// quality checks) use, under `geom`: the first points up to the second
/// contact (the first point past the post-contact flight) and at least
/// [`FLIGHT_FRAMES`] past the contact, or the whole track
/// when it has no second contact. On them every result and every error
/// is the same as on the whole track; an error is returned as
/// [`find_events`] would return it, without the points. Walked once, in
/// order: what a long movie holds for its measurement is its first
/// bounce's points, not every frame with the sphere (a resting sphere's,
/// later bounces'), except a sphere still in its first contact at the
/// movie's end (which fails, "no rebound").
pub fn first_contact_window(
    points: impl Iterator<Item = TrackPoint>,
    geom: &Geometry,
    cfg: &EventConfig,
) -> Result<Vec<TrackPoint>, EventError> {
    let mut kept: Vec<TrackPoint> = Vec::new();
    let (mut n, mut prev_t) = (0usize, None::<f64>);
    let mut bad: Option<EventError> = None;
    let mut max_pen = f64::NEG_INFINITY;
    // Indices of the first and last contact frame, and where the window ends.
    let (mut first, mut last, mut end) = (None::<usize>, None::<usize>, None::<usize>);
    let mut last_frame = 0;
    for p in points {
        if bad.is_none() {
            bad = check_point(&p, prev_t).err();
        }
        prev_t = Some(p.t_s);
        last_frame = p.frame;
        let pen = geom.penetration_px(p.x_px, p.z_px);
        let i = n;
        n += 1;
        if end.is_none() && bad.is_none() {
            max_pen = max_pen.max(pen);
            match (first, last) {
                (None, _) if pen > 0.0 => first = Some(i),
                (Some(_), None) if pen <= 0.0 => last = Some(i - 1),
                (Some(_), Some(c1)) if pen > 0.0 => {
                    // The second contact: the window ends past it and
                    // past the contact law's flight frames.
                    end = Some((i + 1).max(c1 + FLIGHT_FRAMES + 1));
                }
                _ => {}
            }
        }
        if bad.is_none() && end.is_none_or(|e| kept.len() < e.max(2 * cfg.min_flight_frames + 1)) {
            kept.push(p);
        }
    }
    // In find_events's order.
    if n < 2 * cfg.min_flight_frames + 1 {
        return Err(EventError::TooFewFrames(n));
    }
    if let Some(e) = bad {
        return Err(e);
    }
    match (first, last) {
        (None, _) => Err(EventError::NeverLands { gap_px: -max_pen }),
        (Some(0), _) => Err(EventError::NoFlightBeforeContact {
            frame: kept[0].frame,
        }),
        (Some(_), None) => Err(EventError::NoRebound { frame: last_frame }),
        _ => Ok(kept),
    }
}

/// Split the track into flight, contact and flight, and fit each part.
pub fn find_events(
    track: &[TrackPoint],
    geom: &Geometry,
    cfg: &EventConfig,
) -> Result<Events, EventError> {
    if track.len() < 2 * cfg.min_flight_frames + 1 {
        return Err(EventError::TooFewFrames(track.len()));
    }
    check_track(track)?;
    let g_px = geom.g_px_s2(cfg.g_m_s2);
    let pen: Vec<f64> = track
        .iter()
        .map(|p| geom.penetration_px(p.x_px, p.z_px))
        .collect();
    let (first_contact, last_contact) = first_contact_span(track, &pen)?;

    // Flight before: clear of the line by the margin.
    let pre_pts = flight_points(track, &pen, 0..first_contact, cfg);
    if pre_pts.len() < cfg.min_flight_frames {
        return Err(EventError::ShortFlightBeforeContact {
            found: pre_pts.len(),
            needed: cfg.min_flight_frames,
        });
    }
    // Flight after: from loss of contact up to a second contact, if any.
    let after = last_contact + 1;
    let second = pen[after..]
        .iter()
        .position(|&d| d > 0.0)
        .map(|k| after + k);
    let end = second.unwrap_or(track.len());
    let post_pts = flight_points(track, &pen, after..end, cfg);
    if post_pts.len() < cfg.min_flight_frames {
        return Err(EventError::ShortFlightAfterContact {
            found: post_pts.len(),
            needed: cfg.min_flight_frames,
        });
    }
    let pre = fit_flight(&pre_pts, g_px).ok_or(EventError::FitFailed("pre-contact flight"))?;
    let post = fit_flight(&post_pts, g_px).ok_or(EventError::FitFailed("post-contact flight"))?;
    let x_imp = impact_column(&pre, track[first_contact].t_s, geom, g_px)?;
    let peak = fit_peak(track, &pen, (first_contact, last_contact), cfg)?;

    let second_contact_s = second.and_then(|_| {
        let c = post.z0_px + geom.radius_px - geom.surface_row_at(x_imp);
        crossing_time(g_px, post.v0_px_s, c, true).map(|tau| post.t_ref_s + tau)
    });

    Ok(Events {
        surface_row_at_impact_px: geom.surface_row_at(x_imp),
        impact_column_px: x_imp,
        pre,
        post,
        peak,
        contact_span: (first_contact, last_contact),
        second_contact_s,
    })
}

/// The indices of the first contact's first and last frames, from each
/// frame's penetration `pen` (px): the first with δ > 0, and the last
/// before δ ≤ 0 again.
fn first_contact_span(track: &[TrackPoint], pen: &[f64]) -> Result<(usize, usize), EventError> {
    let first_contact =
        pen.iter()
            .position(|&d| d > 0.0)
            .ok_or_else(|| EventError::NeverLands {
                gap_px: -pen.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            })?;
    if first_contact == 0 {
        return Err(EventError::NoFlightBeforeContact {
            frame: track[0].frame,
        });
    }
    let last_contact = first_contact
        + pen[first_contact..]
            .iter()
            .position(|&d| d <= 0.0)
            .map(|k| k - 1)
            .ok_or(EventError::NoRebound {
                frame: track[track.len() - 1].frame,
            })?;
    Ok((first_contact, last_contact))
}

/// The points of `range` clear of the line by the flight margin.
fn flight_points(
    track: &[TrackPoint],
    pen: &[f64],
    range: std::ops::Range<usize>,
    cfg: &EventConfig,
) -> Vec<TrackPoint> {
    range
        .filter(|&i| pen[i] < -cfg.flight_margin_px)
        .map(|i| track[i])
        .collect()
}

/// The impact column: x at the crossing of the pre-contact flight `pre`
/// (from x at the first contact frame's `t_contact_s`), iterated with the
/// tilted line (converges at once for the small tilts and drifts of real
/// set-ups).
fn impact_column(
    pre: &FlightFit,
    t_contact_s: f64,
    geom: &Geometry,
    g_px: f64,
) -> Result<f64, EventError> {
    let mut x_imp = pre.x_at(t_contact_s);
    for _ in 0..3 {
        let c = pre.z0_px + geom.radius_px - geom.surface_row_at(x_imp);
        let tau = crossing_time(g_px, pre.v0_px_s, c, true)
            .ok_or(EventError::NoCrossing("pre-contact"))?;
        x_imp = pre.x_at(pre.t_ref_s + tau);
    }
    Ok(x_imp)
}

/// The peak's polynomial over the contact frames `(c0, c1)` with δ above a
/// fraction of the largest sample.
fn fit_peak(
    track: &[TrackPoint],
    pen: &[f64],
    (first_contact, last_contact): (usize, usize),
    cfg: &EventConfig,
) -> Result<PeakFit, EventError> {
    let (k_max, d_max) = (first_contact..=last_contact).map(|k| (k, pen[k])).fold(
        (first_contact, f64::NEG_INFINITY),
        |a, b| if b.1 > a.1 { b } else { a },
    );
    // The top of the contact: δ above the fraction of the largest sample, and
    // at least the seven deepest frames, so that a quartic can be fitted.
    let mut by_depth: Vec<usize> = (first_contact..=last_contact).collect();
    by_depth.sort_by(|&a, &b| pen[b].total_cmp(&pen[a]));
    let mut peak_idx: Vec<usize> = by_depth
        .iter()
        .enumerate()
        .filter(|&(rank, &k)| rank < 7 || pen[k] >= cfg.peak_fraction * d_max)
        .map(|(_, &k)| k)
        .collect();
    peak_idx.sort_unstable();
    let degree = if peak_idx.len() >= 7 { 4 } else { 2 };
    if peak_idx.len() < degree + 2 {
        return Err(EventError::ShortPeak(peak_idx.len()));
    }
    let ts: Vec<f64> = peak_idx.iter().map(|&k| track[k].t_s).collect();
    let zs: Vec<f64> = peak_idx.iter().map(|&k| track[k].z_px).collect();
    let ss: Vec<f64> = peak_idx.iter().map(|&k| track[k].sigma_z_px).collect();
    let t0 = track[k_max].t_s;
    let poly = PolyFit::fit(&ts, &zs, &ss, degree, t0).ok_or(EventError::FitFailed("peak"))?;
    let t_max = poly_max(&poly, t0, ts[0], ts[ts.len() - 1]);
    Ok(PeakFit {
        poly,
        t_max_s: t_max,
        frames: (
            track[peak_idx[0]].frame,
            track[*peak_idx.last().unwrap_or(&k_max)].frame,
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A centre at a known normal distance from a line tilted by 30° (far
    /// beyond any camera's roll, so that the row distance differs): its
    /// penetration is R less that distance, and in the level frame the
    /// centre sits that distance above the line, the line's points on its
    /// row, a step along the line a step along the level columns.
    #[test]
    fn a_tilted_line_is_measured_along_its_normal_and_levelled() {
        let (theta, r, d) = (30f64.to_radians(), 50.0, 47.5);
        let geom = Geometry {
            surface_row_px: 200.0,
            surface_slope: theta.tan(),
            surface_row_err_px: 0.01,
            radius_px: r,
            radius_err_px: 0.01,
            mm_per_px: 0.02,
            mm_per_px_err: 0.0,
            scale_from_radius: false,
        };
        // The line's point at column 100, then d along the upward normal.
        let (x0, y0) = (100.0, geom.surface_row_at(100.0));
        let (x, z) = (x0 + d * theta.sin(), y0 - d * theta.cos());
        assert!((geom.penetration_px(x, z) - (r - d)).abs() < 1e-9);

        let frame = SurfaceFrame::of(&geom, 80.0);
        let point = |x_px: f64, z_px: f64| TrackPoint {
            frame: 0,
            t_s: 0.0,
            x_px,
            z_px,
            sigma_z_px: 0.01,
            half_width_px: None,
            sigma_half_width_px: None,
        };
        let level = frame.level_geometry(&geom);
        let p = frame.level(&point(x, z));
        assert!((level.penetration_px(p.x_px, p.z_px) - (r - d)).abs() < 1e-9);
        assert!((p.z_px - (frame.row_px - d)).abs() < 1e-9);
        let on_line = frame.level(&point(x0, y0));
        assert!((on_line.z_px - frame.row_px).abs() < 1e-9);
        let along = frame.level(&point(x0 + theta.cos(), y0 + theta.sin()));
        assert!((along.x_px - on_line.x_px - 1.0).abs() < 1e-9);
        assert!((frame.image_col(on_line.x_px) - x0).abs() < 1e-9);
    }
}
