//! Sub-pixel edge points of the sphere along normals to a predicted circle.
//!
//! # Method: the radial area (moment) estimator
//!
//! Along the ray from the predicted centre `c` in direction `u`, samples are
//! taken at unit spacing `t_j = r − w + j` (`j = 0..=2w`) by bilinear
//! interpolation of the frame `I` and of the background `B`, at full bit
//! depth. With the frame's flicker gain `g` and the sphere's level `S` (the
//! median of the innermost samples over all normals), the sphere's share of
//! each sample is `P_j = (g·B_j − I_j) / (g·B_j − S)`: 1 inside, 0 outside.
//! The edge radius is then
//!
//! `t_e² = t_a² + 2 Σ_j P_j t_j`,   `t_a = t_0 − ½`,
//!
//! the midpoint rule for `t_e² = t_a² + 2∫ P(t) t dt`. For a disk of radius `R`
//! under any rotationally symmetric blur, `∫₀^∞ P(ρ) ρ dρ = R²/2` exactly
//! (blur preserves the disk's area), so `t_e = R` with no curved-edge bias:
//! the ½-level contour and the gradient peak of a blurred disk both lie at
//! `R − σ²/2R` (σ the blur), which this estimator does not share. A ray
//! through a centre off by `e` shifts `t_e` by `−e·u` (what the circle fit
//! needs) plus `O(e σ²/R²)`, negligible after one refinement pass.
//!
//! Because the estimator integrates the profile instead of locating a peak
//! between samples, it has no pixel locking for a straight axis-aligned
//! edge: the sum of linearly interpolated samples at unit spacing does not
//! depend on their phase. Residual phase structure for oblique normals is
//! measured in the tests.
//!
//! # What is used
//!
//! A normal is used only when its whole window lies inside the band of rows
//! (and one pixel from the frame's border, for the interpolation), above the
//! surface line minus `surface_margin_px` (the part below is hidden by
//! pillars and, near contact, may dip or mirror the sphere), when the
//! contrast `g·B − S` is at least `min_contrast` of `g·B` everywhere on it,
//! and when the window holds the edge (`P` > ½ at its inner end and < ½ at
//! its outer end).
//!
//! # Cost
//!
//! `normals × (2w + 1)` pairs of bilinear samples: proportional to the
//! perimeter, independent of the frame size. All buffers live in
//! [`EdgeScratch`], reused from frame to frame.

use super::background::Background;
use super::circle::{fit_circle, Circle, CircleFit, FitOptions, FitScratch};
use super::surface::SurfaceLine;
use super::{Band, DetectError};

/// One sub-pixel edge point of the silhouette, in frame pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgePoint {
    /// Column (px).
    pub x_px: f64,
    /// Row (px, grows downward).
    pub z_px: f64,
    /// Relative weight in fits (> 0; 0 excludes the point).
    pub weight: f64,
}

/// Settings of [`edge_points`] and [`measure_circle`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeParams {
    /// Arc length between neighbouring normals (px). 2 px keeps neighbouring
    /// windows on mostly different pixels, so point errors are nearly
    /// independent (the covariance assumes it).
    pub spacing_px: f64,
    /// At most this many normals around the full circle.
    pub max_normals: usize,
    /// Half-width `w` of the window along each normal (samples each side of
    /// the predicted edge, 1 px apart). It must cover the blurred transition
    /// (±3σ of the blur) plus the prediction error.
    pub half_window: usize,
    /// Windows must stay this far above the surface line (px).
    pub surface_margin_px: f64,
    /// Smallest sphere contrast `(g·B − S) / (g·B)` on a window.
    pub min_contrast: f64,
    /// Edge-and-fit passes in [`measure_circle`]; each re-centres the normals
    /// on the previous fit.
    pub passes: usize,
}

impl Default for EdgeParams {
    fn default() -> Self {
        EdgeParams {
            spacing_px: 2.0,
            max_normals: 256,
            half_window: 6,
            surface_margin_px: 2.0,
            min_contrast: 0.15,
            passes: 2,
        }
    }
}

/// Reusable buffers: one per thread, reused for every frame.
#[derive(Debug, Default, Clone)]
pub struct EdgeScratch {
    /// The edge points of the last call.
    pub points: Vec<EdgePoint>,
    /// Frame samples, `2w + 1` per accepted normal.
    frame_samples: Vec<f32>,
    /// Background samples, same layout.
    bg_samples: Vec<f32>,
    /// Direction (cos, sin) of each accepted normal.
    dirs: Vec<(f64, f64)>,
    /// Work buffer for the sphere level's median.
    inner: Vec<f64>,
    /// The circle fit's buffers.
    pub fit: FitScratch,
}

/// Sub-pixel edge points around `predicted` in `band` (see the module doc).
/// `gain` is the frame's flicker gain ([`Background::gain`]); `surface`, when
/// given, hides everything below its line minus the margin. The points are
/// left in `scratch.points` and returned.
pub fn edge_points<'s>(
    band: &Band,
    bg: &Background,
    gain: f64,
    predicted: &Circle,
    surface: Option<&SurfaceLine>,
    params: &EdgeParams,
    scratch: &'s mut EdgeScratch,
) -> Result<&'s [EdgePoint], DetectError> {
    if band.width != bg.width || band.row0 + band.nrows > bg.height {
        return Err(DetectError::ShapeMismatch {
            width: band.width,
            height: band.row0 + band.nrows,
            bg_width: bg.width,
            bg_height: bg.height,
        });
    }
    let w = params.half_window;
    let m = 2 * w + 1;
    let (cx, cz, r) = (predicted.x_px, predicted.z_px, predicted.r_px);
    scratch.points.clear();
    scratch.frame_samples.clear();
    scratch.bg_samples.clear();
    scratch.dirs.clear();
    scratch.inner.clear();
    if !(r.is_finite() && r > w as f64 + 1.0 && cx.is_finite() && cz.is_finite()) {
        return Ok(&scratch.points);
    }
    let circumference = std::f64::consts::TAU * r;
    let n = ((circumference / params.spacing_px.max(0.5)).round() as usize)
        .clamp(8, params.max_normals.max(8));
    let t0 = r - w as f64;
    let t1 = r + w as f64;
    // Valid rows for interpolation: the band, one pixel in from the frame's edges.
    let z_lo = (band.row0 as f64).max(1.0);
    let z_hi = ((band.row0 + band.nrows) as f64 - 1.0).min(bg.height as f64 - 2.0);
    let x_hi = band.width as f64 - 2.0;
    let visible = |x: f64, z: f64| -> bool {
        let inside = x >= 1.0 && x <= x_hi && z >= z_lo && z < z_hi;
        let above = match surface {
            Some(s) => z < s.row_at(x) - params.surface_margin_px,
            None => true,
        };
        inside && above
    };
    for k in 0..n {
        let theta = std::f64::consts::TAU * k as f64 / n as f64;
        let (s, c) = theta.sin_cos();
        if !(visible(cx + t0 * c, cz + t0 * s) && visible(cx + t1 * c, cz + t1 * s)) {
            continue;
        }
        for j in 0..m {
            let t = t0 + j as f64;
            let (x, z) = (cx + t * c, cz + t * s);
            // Inside by the checks above (the window is a segment, the
            // region convex), so the fallbacks are never taken.
            let fi = band.bilinear(x, z).unwrap_or(f64::NAN);
            let fb = bg.bilinear(x, z).unwrap_or(f64::NAN);
            scratch.frame_samples.push(fi as f32);
            scratch.bg_samples.push(fb as f32);
        }
        scratch.dirs.push((c, s));
    }
    if scratch.dirs.is_empty() {
        return Ok(&scratch.points);
    }
    // The sphere's level: median over normals of the two innermost samples.
    for win in scratch.frame_samples.chunks_exact(m) {
        scratch.inner.push(0.5 * (win[0] as f64 + win[1] as f64));
    }
    let mid = scratch.inner.len() / 2;
    let sphere = *scratch.inner.select_nth_unstable_by(mid, f64::total_cmp).1;
    let ta = t0 - 0.5;
    'normals: for (k, &(c, s)) in scratch.dirs.iter().enumerate() {
        let fi = &scratch.frame_samples[k * m..(k + 1) * m];
        let fb = &scratch.bg_samples[k * m..(k + 1) * m];
        let mut area = 0.0;
        let mut first = 0.0;
        let mut last = 0.0;
        for j in 0..m {
            let gb = gain * fb[j] as f64;
            let den = gb - sphere;
            if !(den >= params.min_contrast * gb && den > 0.0) {
                continue 'normals;
            }
            let p = (gb - fi[j] as f64) / den;
            if j == 0 {
                first = p;
            }
            last = p;
            area += p * (t0 + j as f64);
        }
        if !(first > 0.5 && last < 0.5) {
            continue;
        }
        let te2 = ta * ta + 2.0 * area;
        if !(te2 > 0.0) {
            continue;
        }
        let te = te2.sqrt();
        scratch.points.push(EdgePoint {
            x_px: cx + te * c,
            z_px: cz + te * s,
            weight: 1.0,
        });
    }
    Ok(&scratch.points)
}

/// Edge points and a robust circle fit, `params.passes` times, each pass
/// re-centring the normals on the previous fit. With `hold_radius` the radius
/// is held at that value (after calibration) and only the centre is fitted.
pub fn measure_circle(
    band: &Band,
    bg: &Background,
    predicted: &Circle,
    surface: Option<&SurfaceLine>,
    hold_radius: Option<f64>,
    params: &EdgeParams,
    scratch: &mut EdgeScratch,
) -> Result<CircleFit, DetectError> {
    let gain = bg.gain(band)?;
    let opts = FitOptions {
        hold_radius,
        ..FitOptions::default()
    };
    let mut circle = *predicted;
    if let Some(r) = hold_radius {
        circle.r_px = r;
    }
    let mut fit = None;
    for _ in 0..params.passes.max(1) {
        edge_points(band, bg, gain, &circle, surface, params, scratch)?;
        let f = fit_circle(&scratch.points, Some(circle), &opts, &mut scratch.fit)?;
        circle = f.circle();
        fit = Some(f);
    }
    fit.ok_or(DetectError::TooFewPoints {
        what: "circle measurement",
        found: 0,
        needed: 1,
    })
}
