//! Radial lens distortion: the one-term model `r_d = r_u (1 + k1 r_u²)`
//! about the image centre `((W − 1)/2, (H − 1)/2)`, `k1 < 0` for barrel
//! distortion (the usual for the macro lenses of this experiment).
//!
//! The tracker measures silhouettes in the recorded (distorted) image. A
//! circle of radius `R` centred at `c` (relative to the image centre) is
//! recorded as a slightly oval outline whose fitted circle has, to first
//! order in `k1` (the first and zeroth Fourier terms of the outline's
//! radial displacement `k1 (c·n + R)(|c|² + R² + 2R c·n)`):
//!
//! - centre `c (1 + k1 (|c|² + 3R²))`: a point's distortion, and 3k1R² more
//!   because the outline's far side is pulled in harder than its near side;
//! - radius `R (1 + k1 (2|c|² + R²))`.
//!
//! [`Lens::disc`] inverts these. With `k1` known (a lens calibration,
//! `camera.distortion_k1_per_px2`) the track is corrected before anything is
//! measured ([`undistort_track`]). Without it, `k1` is measured in the
//! images: the undeformed surface is straight, and its line's bow is the
//! lens's ([`k1_from_bow`]); the track is corrected with it, and the
//! measurement repeated on the track corrected by its error (times √3,
//! the half-width of the uniform spread the systematic term assumes). Where
//! the bow says little (the surface near the centre row), the measurement
//! is repeated on the track corrected for the largest distortion the lens
//! may have (`camera.distortion_bound_px` at the sensor's corner). The
//! change enters the errors as a systematic term (`process`): on the real
//! preset the per-drop free-fall scale differs from the magnification at
//! the impact by 1–4e-4, more than the speeds' statistical errors.

use super::free_fall::Curvature;
use super::scale::{resolve, Scale, ScaleInputs};
use crate::detect::{CircleFit, SurfaceLine};
use crate::measure::events::{find_events, EventConfig, Geometry, TrackPoint};
use crate::measure::kinematics::{kinematics, SphereParams};
use crate::track::{FrameTrack, Track};

/// The lens `k1` (1/px²) that the surface line's bow measures, and its
/// standard error ([`BOW_ERROR_SCALE`], [`BOW_STRUCTURE_PX`]), in a `width × height` image: a straight surface row
/// `v` px from the centre row is bowed by `c = k1·v` through the lens
/// ([`SurfaceLine::bow_per_px2`]), so `k1 = c / v`. `None` where the line
/// passes within [`BOW_MIN_OFFSET`] of the height from the centre row (its
/// bow says little of the lens there) or has no bow measured.
pub fn k1_from_bow(line: &SurfaceLine, width: usize, height: usize) -> Option<(f64, f64)> {
    let (xc, zc) = (0.5 * (width as f64 - 1.0), 0.5 * (height as f64 - 1.0));
    let v = line.row_at(xc) - zc;
    let informative = v.abs() >= BOW_MIN_OFFSET * height as f64 && line.bow_err_per_px2 > 0.0;
    let structure = (line.model_err_px / BOW_STRUCTURE_PX).max(1.0);
    informative.then(|| {
        (
            line.bow_per_px2 / v,
            BOW_ERROR_SCALE * structure * line.bow_err_per_px2 / v.abs(),
        )
    })
}

/// On a structured band top (a glossy strip, a row of pillar tops) the
/// flank fit follows the structure from column to column, and the bow
/// takes some of it: the bow's error is multiplied by the edge models'
/// disagreement ([`SurfaceLine::model_err_px`]) over this, when larger. On
/// 107 `real`-preset renders every k1 more than 2.5σ off had a
/// disagreement of 0.2–1.2 px; the independent renders' tops (0.06–0.26 px)
/// were within 1.1σ but one (2.9σ).
pub const BOW_STRUCTURE_PX: f64 = 0.1;

/// The bow's error from its blocks' scatter takes the blocks as
/// independent; neighbouring blocks share the pillar field's and the
/// blur's structure. On 107 `real`-preset renders whose lens was measured
/// that way, |k1 − k1_true| / σ had a median of 0.81 (0.67 for a right σ):
/// the error is scaled by 1.25.
pub const BOW_ERROR_SCALE: f64 = 1.25;

/// See [`k1_from_bow`].
pub const BOW_MIN_OFFSET: f64 = 0.15;

/// A radial distortion about the image centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lens {
    /// Distortion coefficient (1/px²); negative for barrel distortion.
    pub k1_per_px2: f64,
    /// Centre of distortion (column, row), px.
    pub centre_px: (f64, f64),
}

impl Lens {
    /// `k1` about the centre of a `width × height` image.
    pub fn new(k1_per_px2: f64, width: usize, height: usize) -> Self {
        Lens {
            k1_per_px2,
            centre_px: (0.5 * (width as f64 - 1.0), 0.5 * (height as f64 - 1.0)),
        }
    }

    /// The barrel distortion that moves the image's corner pixel inward by
    /// `corner_px`: `k1 = −corner / r³` with `r` the corner's distance from
    /// the centre.
    pub fn barrel_at_corner(corner_px: f64, width: usize, height: usize) -> Self {
        let r = 0.5 * (width as f64 - 1.0).hypot(height as f64 - 1.0);
        Lens::new(-corner_px / (r * r * r).max(1.0), width, height)
    }

    /// Scene position of the recorded point `(x, z)`.
    pub fn point(&self, x_px: f64, z_px: f64) -> (f64, f64) {
        self.invert(x_px, z_px, 0.0)
    }

    /// Scene centre and radius of a disc whose recorded outline was fitted
    /// by the circle `(x, z, r)` (module doc).
    pub fn disc(&self, x_px: f64, z_px: f64, r_px: f64) -> (f64, f64, f64) {
        // R to first order first: the centre's term needs the scene radius.
        let (u, v) = (x_px - self.centre_px.0, z_px - self.centre_px.1);
        let r_u = r_px / (1.0 + self.k1_per_px2 * (2.0 * (u * u + v * v) + r_px * r_px));
        let (xu, zu) = self.invert(x_px, z_px, 3.0 * r_u * r_u);
        let (u, v) = (xu - self.centre_px.0, zu - self.centre_px.1);
        let r_u = r_px / (1.0 + self.k1_per_px2 * (2.0 * (u * u + v * v) + r_u * r_u));
        (xu, zu, r_u)
    }

    /// Solve `d = p (1 + k1 (|p|² + extra))` for `p` (relative to the
    /// centre) by fixed-point iteration: |k1|·r² is below 1e-2 for any
    /// plausible lens, so each step gains two orders of magnitude.
    fn invert(&self, x_px: f64, z_px: f64, extra_px2: f64) -> (f64, f64) {
        let (u, v) = (x_px - self.centre_px.0, z_px - self.centre_px.1);
        let (mut pu, mut pv) = (u, v);
        for _ in 0..8 {
            let f = 1.0 + self.k1_per_px2 * (pu * pu + pv * pv + extra_px2);
            (pu, pv) = (u / f, v / f);
        }
        (self.centre_px.0 + pu, self.centre_px.1 + pv)
    }
}

/// The track with its circles and surface line moved to the scene's
/// undistorted coordinates: each circle by [`Lens::disc`], the calibrated
/// radius at the circle nearest the surface (where δ and a are measured),
/// and the surface line through the scene positions of its points at the
/// sphere's columns ±R_px. Takes the track (a long movie's is tens of
/// megabytes): [`undistort_held`] moves the held circles without a copy.
pub fn undistort_track(tr: Track, lens: &Lens) -> std::io::Result<Track> {
    let mut out = tr;
    let mut lowest: Option<(f64, f64)> = None;
    out.frames.update(|_, block| -> std::io::Result<()> {
        for f in block {
            if let Some(fit) = f.free.as_mut() {
                (fit.x_px, fit.z_px, fit.r_px) = lens.disc(fit.x_px, fit.z_px, fit.r_px);
            }
            if let Some(fit) = f.held.as_mut() {
                let (x, z, _) = lens.disc(fit.x_px, fit.z_px, fit.r_px);
                (fit.x_px, fit.z_px) = (x, z);
                lowest = lower(lowest, (x, z));
            }
        }
        Ok(())
    })?;
    let (r, surface) = radius_and_line(lens, lowest, out.radius_px, out.surface);
    out.frames.update(|_, block| -> std::io::Result<()> {
        for h in block.iter_mut().filter_map(|f| f.held.as_mut()) {
            h.r_px = r;
        }
        Ok(())
    })?;
    out.radius_px = r;
    out.surface = surface;
    Ok(out)
}

/// The surface line and the calibrated radius that [`undistort_track`]
/// gives `tr` through `lens`, without a copy of the track (one walk of it).
pub fn undistorted_line(tr: &Track, lens: &Lens) -> (SurfaceLine, f64) {
    let lowest = held_centres(tr, lens).fold(None, |lowest, (_, x, z, _)| lower(lowest, (x, z)));
    let (r, surface) = radius_and_line(lens, lowest, tr.radius_px, tr.surface);
    (surface, r)
}

/// What [`undistort_track`] makes of `tr`'s held circles, without a copy
/// of the track: each frame with a held fit and that fit moved, with the
/// calibrated radius `r_px` ([`undistorted_line`]), made as the iterator is
/// walked, in the track's order.
pub fn undistort_held<'a>(
    tr: &'a Track,
    lens: &'a Lens,
    r_px: f64,
) -> impl Iterator<Item = (FrameTrack, CircleFit)> + 'a {
    held_centres(tr, lens).map(move |(f, x, z, h)| {
        let fit = CircleFit {
            x_px: x,
            z_px: z,
            r_px,
            ..h
        };
        (f, fit)
    })
}

/// `tr`'s frames with a held fit, with that fit's centre moved by `lens`.
fn held_centres<'a>(
    tr: &'a Track,
    lens: &'a Lens,
) -> impl Iterator<Item = (FrameTrack, f64, f64, CircleFit)> + 'a {
    tr.frames.iter().filter_map(|f: FrameTrack| {
        let h = f.held?;
        let (x, z, _) = lens.disc(h.x_px, h.z_px, h.r_px);
        Some((f, x, z, h))
    })
}

/// The lower (larger row) of the centre so far and `(x, z)`; the first
/// of equals.
fn lower(lowest: Option<(f64, f64)>, (x, z): (f64, f64)) -> Option<(f64, f64)> {
    if lowest.is_none_or(|(_, zl)| z > zl) {
        Some((x, z))
    } else {
        lowest
    }
}

/// The calibrated radius and the surface line in the scene: the radius
/// corrected at the lowest held centre (where δ and a are measured; the
/// image centre without one), the line through the scene positions of its
/// points at that centre's columns ±R_px.
fn radius_and_line(
    lens: &Lens,
    lowest: Option<(f64, f64)>,
    radius_px: f64,
    surface: SurfaceLine,
) -> (f64, SurfaceLine) {
    let (x_c, z_c) = lowest.unwrap_or(lens.centre_px);
    // The held radius is one number for the whole track: corrected where
    // the measurement uses it, at the deepest frame.
    let r = lens.disc(x_c, z_c, radius_px).2;
    let half = radius_px.max(1.0);
    let (xa, xb) = (x_c - half, x_c + half);
    let (ua, ra) = lens.point(xa, surface.row_at(xa));
    let (ub, rb) = lens.point(xb, surface.row_at(xb));
    let slope = (rb - ra) / (ub - ua);
    let line = SurfaceLine {
        slope,
        row0_px: ra - slope * ua,
        ..surface
    };
    (r, line)
}

/// A run's track seen through the lens at the distortion bound: what
/// [`shift_at_bound`] measures again.
#[derive(Debug, Clone)]
pub struct Bounded {
    /// The lens at the bound: the track's points through it are made again
    /// when measured ([`undistort_held`]), never held.
    pub lens: Lens,
    /// The surface line and the calibrated radius, corrected.
    pub surface_row0_px: f64,
    /// The corrected surface tilt, rows per column.
    pub surface_slope: f64,
    /// The corrected calibrated radius, px.
    pub radius_px: f64,
    /// The corrected track's free-flight curvature.
    pub curvature: Option<Curvature>,
}

/// How far a lens at the bound moves a drop's numbers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shift {
    /// The scale (0 when it is given).
    pub mm_per_px: f64,
    /// The change of v_impact, m/s.
    pub v_impact_m_s: f64,
    /// The change of v_rebound, m/s.
    pub v_rebound_m_s: f64,
    /// The change of δmax, mm.
    pub delta_max_mm: f64,
    /// The change of τc, ms.
    pub tau_c_ms: f64,
}

/// What the drop's scale, speeds (through `speed_factor`, the scale's
/// magnification at the impact), δmax and τc become when its track, its
/// set-up's `pooled` curvature and its surface line are corrected for the
/// lens at the bound, less what the same events and kinematics give
/// without it (on `geom` at the scale `sc` resolved from `inputs`).
/// `points_at(geom)` and `bounded_points_at(geom)` give the track's points
/// and its points through the lens that the events under `geom` use
/// ([`crate::measure::events::first_contact_window`]). `surface_shift_px` is what
/// the measurement moved the image's line by (the contact law), kept.
/// `None` when either side cannot be measured.
#[allow(clippy::too_many_arguments)]
pub fn shift_at_bound(
    points_at: impl Fn(&Geometry) -> Option<Vec<TrackPoint>>,
    bounded_points_at: impl Fn(&Geometry) -> Option<Vec<TrackPoint>>,
    geom: &Geometry,
    sc: &Scale,
    inputs: &ScaleInputs,
    bounded: &Bounded,
    pooled: Option<Curvature>,
    surface_shift_px: f64,
    sphere: &SphereParams,
    cfg: &EventConfig,
    speed_factor: impl Fn(&Scale) -> f64,
) -> Option<Shift> {
    let measure = |points: Vec<TrackPoint>, geom: &Geometry, sc: &Scale| {
        let ev = find_events(&points, geom, cfg).ok()?;
        let kin = kinematics(&points, &ev, geom, sphere, cfg.exposure_s).ok()?;
        let f = speed_factor(sc);
        Some(Shift {
            mm_per_px: sc.mm_per_px,
            v_impact_m_s: kin.v_impact_m_s.value * f,
            v_rebound_m_s: kin.v_rebound_m_s.value * f,
            delta_max_mm: kin.delta_max_m.value * 1e3,
            tau_c_ms: kin.tau_c_s.value * 1e3,
        })
    };
    let base = measure(points_at(geom)?, geom, sc)?;
    // Seen from the bound, the lens's change of the scale is the same.
    let inputs_b = ScaleInputs {
        setup: pooled,
        own: bounded.curvature,
        r_app_px: bounded.radius_px,
        setup_at_bound: inputs.setup,
        own_at_bound: inputs.own,
        ..inputs.clone()
    };
    let sc = resolve(&inputs_b);
    let (radius_px, radius_err_px) = sc.radius_px(&inputs_b);
    let geom_b = Geometry {
        surface_row_px: bounded.surface_row0_px + surface_shift_px,
        surface_slope: bounded.surface_slope,
        radius_px,
        radius_err_px,
        mm_per_px: sc.mm_per_px,
        mm_per_px_err: sc.mm_per_px * sc.rel_err,
        ..*geom
    };
    let at = measure(bounded_points_at(&geom_b)?, &geom_b, &sc)?;
    Some(Shift {
        mm_per_px: at.mm_per_px - base.mm_per_px,
        v_impact_m_s: at.v_impact_m_s - base.v_impact_m_s,
        v_rebound_m_s: at.v_rebound_m_s - base.v_rebound_m_s,
        delta_max_mm: at.delta_max_mm - base.delta_max_mm,
        tau_c_ms: at.tau_c_ms - base.tau_c_ms,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points of a scene circle, distorted by `lens`.
    fn recorded_outline(lens: &Lens, x: f64, z: f64, r: f64) -> Vec<(f64, f64)> {
        (0..720)
            .map(|i| {
                let a = i as f64 * std::f64::consts::TAU / 720.0;
                let (u, v) = (
                    x + r * a.cos() - lens.centre_px.0,
                    z + r * a.sin() - lens.centre_px.1,
                );
                let f = 1.0 + lens.k1_per_px2 * (u * u + v * v);
                (lens.centre_px.0 + u * f, lens.centre_px.1 + v * f)
            })
            .collect()
    }

    /// Least-squares circle (Kåsa) through the points: exact for a circle,
    /// and for a slightly oval outline sampled evenly its centre and mean
    /// radius to second order.
    fn fit(points: &[(f64, f64)]) -> (f64, f64, f64) {
        let pts: Vec<crate::detect::EdgePoint> = points
            .iter()
            .map(|&(x, z)| crate::detect::EdgePoint {
                x_px: x,
                z_px: z,
                weight: 1.0,
            })
            .collect();
        let c = crate::detect::circle::hyper_fit(&pts).expect("a circle");
        (c.x_px, c.z_px, c.r_px)
    }

    #[test]
    fn a_distorted_disc_is_put_back_where_it_was() {
        // Twice the real preset's strongest barrel (1 px at the corner of
        // 512 × 384), a sphere of R 80 px high and to the side.
        let lens = Lens::barrel_at_corner(1.0, 512, 384);
        for &(x, z, r) in &[
            (250.0, 60.0, 80.0),
            (100.0, 300.0, 40.0),
            (400.0, 191.5, 90.0),
        ] {
            let (xf, zf, rf) = fit(&recorded_outline(&lens, x, z, r));
            // What is corrected: up to half a pixel.
            assert!((xf - x).abs() + (zf - z).abs() > 0.05, "{x} {z}: {xf} {zf}");
            let (xu, zu, ru) = lens.disc(xf, zf, rf);
            // Left: the second order in k1 r², below 1e-3 px.
            assert!((xu - x).abs() < 1e-3, "x {xu} vs {x}");
            assert!((zu - z).abs() < 1e-3, "z {zu} vs {z}");
            assert!((ru - r).abs() < 1e-3, "r {ru} vs {r}");
        }
    }

    #[test]
    fn a_point_round_trips_and_the_corner_moves_by_the_bound() {
        let lens = Lens::barrel_at_corner(0.5, 512, 384);
        let corner = (0.0, 0.0);
        let (u, v) = (corner.0 - lens.centre_px.0, corner.1 - lens.centre_px.1);
        // The scene point recorded at the corner lies 0.5 px further out.
        let (xs, zs) = lens.point(corner.0, corner.1);
        let moved = (xs - lens.centre_px.0).hypot(zs - lens.centre_px.1) - u.hypot(v);
        assert!((moved - 0.5).abs() < 5e-3, "{moved}");
        let (x, z) = (300.0, 20.0);
        let (xs, zs) = lens.point(x, z);
        let (a, b) = (xs - lens.centre_px.0, zs - lens.centre_px.1);
        let f = 1.0 + lens.k1_per_px2 * (a * a + b * b);
        assert!((lens.centre_px.0 + a * f - x).abs() < 1e-9);
        assert!((lens.centre_px.1 + b * f - z).abs() < 1e-9);
    }
}
