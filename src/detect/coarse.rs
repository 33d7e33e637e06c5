//! Coarse detection: is the sphere in the frame, and roughly where.
//!
//! A pixel is "sphere" when it is darker than the flicker-corrected
//! background by more than `threshold · g·B` and lies above the surface line
//! minus the margin (the pillar band is dark too). The largest 4-connected
//! group of such pixels is the sphere candidate; groups smaller than
//! `min_area_px` (dust) are ignored. Its outline — every pixel of the group
//! next to a non-group pixel that is itself inside the frame, above the
//! surface and outside the group, not in a hole of it (a polished ball's
//! glint: `mark_outside`) — gives boundary points placed at the
//! linear-interpolated threshold crossing between the two pixels, and a
//! robust circle fit
//! ([`fit_circle`]) through them gives the coarse circle. Boundary points
//! along the frame's border are not edges and are not used, so a sphere
//! entering through the top, only partly visible, is fitted on its visible
//! arc. The coarse circle is accurate to a fraction of a pixel (the
//! threshold is not at half contrast); [`super::edges::measure_circle`]
//! refines it. [`BinnedBackground`] runs the same search on whole frames
//! binned 2×2 (a quarter of the pixels, the circle to about a pixel), for
//! the tracker's searches and the background's masks.

use super::background::Background;
use super::circle::{fit_circle, Circle, FitOptions, FitScratch};
use super::types::EdgePoint;
use super::types::SurfaceLine;
use super::{Band, DetectError};

/// Settings of [`detect_coarse`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoarseParams {
    /// Relative darkening `(g·B − I)/(g·B)` that marks a sphere pixel.
    pub threshold: f64,
    /// Fewest pixels of a sphere candidate.
    pub min_area_px: usize,
    /// Pixels closer than this above the surface line are not searched (px).
    pub surface_margin_px: f64,
}

impl Default for CoarseParams {
    fn default() -> Self {
        CoarseParams {
            threshold: 0.3,
            min_area_px: 50,
            surface_margin_px: 2.0,
        }
    }
}

/// A coarse sphere detection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coarse {
    /// The coarse circle (frame pixels).
    pub circle: Circle,
    /// Pixels in the sphere's group.
    pub area_px: usize,
    /// The group touches the top row of the band (the sphere is entering).
    pub touches_top: bool,
    /// Boundary points used for the circle.
    pub boundary_points: usize,
}

/// Reusable buffers of [`detect_coarse`].
#[derive(Debug, Default, Clone)]
pub struct CoarseScratch {
    /// Per pixel: 0 background, 1 dark, 2.. group label.
    labels: Vec<u32>,
    stack: Vec<usize>,
    /// Per column, the surface line's row minus the margin.
    limits: Vec<f32>,
    points: Vec<EdgePoint>,
    fit: FitScratch,
    /// The frame [`BinnedBackground::detect`] bins.
    binned_frame: Vec<u16>,
}

/// Find the sphere in `band` (see the module doc); `Ok(None)` when there is
/// no dark group of at least `min_area_px` pixels, or when no circle fits
/// the largest one's outline (a straight bar across the frame, a frame
/// dark all over).
pub fn detect_coarse(
    band: &Band,
    bg: &Background,
    gain: f64,
    surface: Option<&SurfaceLine>,
    params: &CoarseParams,
    scratch: &mut CoarseScratch,
) -> Result<Option<Coarse>, DetectError> {
    let (h, w) = (band.nrows, band.width);
    if w != bg.width || band.row0 + h > bg.height {
        return Err(DetectError::ShapeMismatch {
            width: w,
            height: band.row0 + h,
            bg_width: bg.width,
            bg_height: bg.height,
        });
    }
    let searchable = |i: usize, j: usize| -> bool {
        let z = (band.row0 + i) as f64;
        match surface {
            Some(s) => z < s.row_at(j as f64) - params.surface_margin_px,
            None => true,
        }
    };
    let darkening = |i: usize, j: usize| -> (f64, f64) {
        let gb = gain * bg.at(band.row0 + i, j) as f64;
        (gb - band.data[i * w + j] as f64, params.threshold * gb)
    };
    mark_dark(band, bg, gain, surface, params, scratch);
    let (label, area, top, bottom, left, right) =
        largest_group(&mut scratch.labels, &mut scratch.stack, (h, w));
    if area < params.min_area_px.max(1) {
        return Ok(None);
    }
    mark_outside(scratch, (h, w), label, (top, bottom), (left, right));
    // Outline points at the threshold crossing towards each outside neighbour.
    scratch.points.clear();
    let mut touches_top = false;
    for i in top..=bottom {
        for j in 0..w {
            if scratch.labels[i * w + j] != label {
                continue;
            }
            if i == 0 {
                touches_top = true;
            }
            let (d_in, thr_in) = darkening(i, j);
            let neighbours = [
                (i.wrapping_sub(1), j, 0.0, -1.0),
                (i + 1, j, 0.0, 1.0),
                (i, j.wrapping_sub(1), -1.0, 0.0),
                (i, j + 1, 1.0, 0.0),
            ];
            for (ni, nj, dx, dz) in neighbours {
                // Only towards the outside: not into a hole of the group.
                if ni >= h || nj >= w || scratch.labels[ni * w + nj] != OUTSIDE {
                    continue;
                }
                if !searchable(ni, nj) {
                    continue;
                }
                let (d_out, thr_out) = darkening(ni, nj);
                let a = d_in - thr_in;
                let b = d_out - thr_out;
                let f = if a - b > 0.0 {
                    (a / (a - b)).clamp(0.0, 1.0)
                } else {
                    0.5
                };
                scratch.points.push(EdgePoint {
                    x_px: j as f64 + f * dx,
                    z_px: (band.row0 + i) as f64 + f * dz,
                    weight: 1.0,
                });
            }
        }
    }
    // A group whose outline no circle fits (a bar or a line across the
    // frame, a frame dark all over: no outline inside it) is not a sphere.
    let fit = match fit_circle(
        &scratch.points,
        None,
        &FitOptions::default(),
        &mut scratch.fit,
    ) {
        Ok(fit) => fit,
        Err(DetectError::TooFewPoints { .. } | DetectError::Degenerate { .. }) => return Ok(None),
        Err(e) => return Err(e),
    };
    Ok(Some(Coarse {
        circle: fit.circle(),
        area_px: area,
        touches_top,
        boundary_points: scratch.points.len(),
    }))
}

/// Each pixel of `band` dark (`I < (1 − threshold)·g·B`) and above the
/// surface line minus the margin marked 1 in `scratch.labels`, the others 0.
fn mark_dark(
    band: &Band,
    bg: &Background,
    gain: f64,
    surface: Option<&SurfaceLine>,
    params: &CoarseParams,
    scratch: &mut CoarseScratch,
) {
    let (h, w) = (band.nrows, band.width);
    scratch.labels.clear();
    scratch.labels.resize(h * w, 0);
    // Row by row, branch-free (f32, four pixels at a time): dark
    // (I < (1 − threshold)·g·B) and above the line minus the margin, whose
    // row at each column is computed once.
    scratch.limits.clear();
    scratch.limits.extend((0..w).map(|j| match surface {
        Some(s) => (s.row_at(j as f64) - params.surface_margin_px) as f32,
        None => f32::INFINITY,
    }));
    let level = ((1.0 - params.threshold) * gain) as f32;
    for i in 0..h {
        let z = (band.row0 + i) as f32;
        let row = &band.data[i * w..][..w];
        let bg_row = &bg.levels[(band.row0 + i) * bg.width..][..w];
        let labels = &mut scratch.labels[i * w..][..w];
        let limits = &scratch.limits[..w];
        for j in 0..w {
            let dark = (row[j] as f32) < level * bg_row[j];
            labels[j] = (dark & (z < limits[j])) as u32;
        }
    }
}

/// The 4-connected groups of the pixels marked 1 in `labels` (`h × w`),
/// labelled 2, 3, …; the largest one's (label, size, first row, last row,
/// first column, last column).
fn largest_group(
    labels: &mut [u32],
    stack: &mut Vec<usize>,
    (h, w): (usize, usize),
) -> (u32, usize, usize, usize, usize, usize) {
    // Label 4-connected groups; keep the largest.
    // (label, size, first row, last row, first column, last column) of
    // the largest group.
    let mut best = (0u32, 0usize, 0usize, 0usize, 0usize, 0usize);
    let mut next = 2u32;
    let n = h * w;
    let mut start = 0;
    while start < n {
        // Skip 16 pixels at a time where no new group starts (most of
        // the frame), then one at a time.
        if start + 16 <= n && !labels[start..start + 16].contains(&1) {
            start += 16;
            continue;
        }
        start += 1;
        let start = start - 1;
        if labels[start] != 1 {
            continue;
        }
        let label = next;
        next += 1;
        let mut size = 0;
        let (mut top, mut bottom) = (h, 0);
        let (mut left, mut right) = (w, 0);
        stack.clear();
        stack.push(start);
        labels[start] = label;
        while let Some(k) = stack.pop() {
            size += 1;
            let (i, j) = (k / w, k % w);
            top = top.min(i);
            bottom = bottom.max(i);
            left = left.min(j);
            right = right.max(j);
            let mut visit = |kk: usize| {
                if labels[kk] == 1 {
                    labels[kk] = label;
                    stack.push(kk);
                }
            };
            if i > 0 {
                visit(k - w);
            }
            if i + 1 < h {
                visit(k + w);
            }
            if j > 0 {
                visit(k - 1);
            }
            if j + 1 < w {
                visit(k + 1);
            }
        }
        if size > best.1 {
            best = (label, size, top, bottom, left, right);
        }
    }
    best
}

/// The label [`mark_outside`] gives the pixels outside the sphere's group.
const OUTSIDE: u32 = u32::MAX;

/// Label [`OUTSIDE`] every pixel of the group's bounding box (rows `top..=bottom`,
/// columns `left..=right`, widened by one pixel within the band) that is
/// not in the group `label` and is reached from the box's border without
/// crossing the group. What stays unmarked and is not the group is a hole
/// in it: a bright glint in a polished ball (a specular reflection of the
/// backlight), lighter than the threshold. Its outline is not the sphere's
/// edge and would pull the circle in (on a real ball with a central glint
/// of a third of its diameter, the coarse radius came out 7 px small).
fn mark_outside(
    scratch: &mut CoarseScratch,
    (h, w): (usize, usize),
    label: u32,
    (top, bottom): (usize, usize),
    (left, right): (usize, usize),
) {
    let (i0, i1) = (top.saturating_sub(1), (bottom + 1).min(h - 1));
    let (j0, j1) = (left.saturating_sub(1), (right + 1).min(w - 1));
    let labels = &mut scratch.labels;
    let stack = &mut scratch.stack;
    stack.clear();
    let seed = |k: usize, labels: &mut Vec<u32>, stack: &mut Vec<usize>| {
        if labels[k] != label && labels[k] != OUTSIDE {
            labels[k] = OUTSIDE;
            stack.push(k);
        }
    };
    for j in j0..=j1 {
        seed(i0 * w + j, labels, stack);
        seed(i1 * w + j, labels, stack);
    }
    for i in i0..=i1 {
        seed(i * w + j0, labels, stack);
        seed(i * w + j1, labels, stack);
    }
    while let Some(k) = stack.pop() {
        let (i, j) = (k / w, k % w);
        if i > i0 {
            seed(k - w, labels, stack);
        }
        if i < i1 {
            seed(k + w, labels, stack);
        }
        if j > j0 {
            seed(k - 1, labels, stack);
        }
        if j < j1 {
            seed(k + 1, labels, stack);
        }
    }
}

/// A background binned 2×2, for [`BinnedBackground::detect`]: a coarse
/// search of whole frames on a quarter of the pixels (see [`bin_frame`] for
/// the geometry). The coarse circle comes back to within about a pixel,
/// which the sub-pixel measurement's re-centring absorbs.
#[derive(Debug, Clone)]
pub struct BinnedBackground {
    binned: Background,
}

impl BinnedBackground {
    /// Bin `bg` (an odd last row or column is dropped).
    pub fn new(bg: &Background) -> Self {
        let (wb, hb) = (bg.width / 2, bg.height / 2);
        let mut levels = Vec::with_capacity(wb * hb);
        for i in 0..hb {
            let a = &bg.levels[2 * i * bg.width..][..2 * wb];
            let b = &bg.levels[(2 * i + 1) * bg.width..][..2 * wb];
            levels.extend(
                a.chunks_exact(2)
                    .zip(b.chunks_exact(2))
                    .map(|(p, q)| 0.25 * (p[0] + p[1] + q[0] + q[1])),
            );
        }
        BinnedBackground {
            binned: Background {
                width: wb,
                height: hb,
                levels,
                region: bg.region,
                gains: Vec::new(),
                near_cols: ((bg.near_cols.0 / 2).min(wb), (bg.near_cols.1 / 2).min(wb)),
            },
        }
    }

    /// [`detect_coarse`] on `frame` (a whole frame: `row0` 0, the
    /// background's full size) binned 2×2, with the parameters of
    /// [`binned_params`]; the circle in full frame pixels.
    pub fn detect(
        &self,
        frame: &Band,
        gain: f64,
        surface: Option<&SurfaceLine>,
        params: &CoarseParams,
        scratch: &mut CoarseScratch,
    ) -> Result<Option<Coarse>, DetectError> {
        let (wb, hb) = (self.binned.width, self.binned.height);
        if frame.row0 != 0 || frame.width / 2 != wb || frame.nrows / 2 != hb {
            return Err(DetectError::ShapeMismatch {
                width: frame.width,
                height: frame.row0 + frame.nrows,
                bg_width: 2 * wb,
                bg_height: 2 * hb,
            });
        }
        // The binned frame lives in the scratch, which the search needs
        // whole: take it out for the call.
        let mut binned = std::mem::take(&mut scratch.binned_frame);
        bin_frame(frame.data, frame.width, wb, hb, &mut binned);
        let band = Band {
            data: &binned,
            row0: 0,
            nrows: hb,
            width: wb,
            cols: (0, wb),
        };
        let line = surface.map(to_binned_line);
        let found = detect_coarse(
            &band,
            &self.binned,
            gain,
            line.as_ref(),
            &binned_params(params),
            scratch,
        );
        scratch.binned_frame = binned;
        Ok(found?.map(|c| Coarse {
            circle: from_binned_circle(&c.circle),
            area_px: 4 * c.area_px,
            ..c
        }))
    }
}

/// Bin a row-major frame `w` columns wide 2×2 into `out` (`hb` rows of
/// `wb` columns; an odd last row or column is dropped): binned pixel
/// `(i, j)` is the rounded mean of full pixels `2i..2i+2 × 2j..2j+2`, centred
/// at full coordinates `(X, Z) = (2j + ½, 2i + ½)`.
pub fn bin_frame(frame: &[u16], w: usize, wb: usize, hb: usize, out: &mut Vec<u16>) {
    out.clear();
    out.resize(wb * hb, 0);
    for (i, o) in out.chunks_exact_mut(wb).enumerate() {
        let a = &frame[2 * i * w..][..2 * wb];
        let b = &frame[(2 * i + 1) * w..][..2 * wb];
        // Pairs by chunks (no index checks: the loop vectorises).
        for ((o, p), q) in o.iter_mut().zip(a.chunks_exact(2)).zip(b.chunks_exact(2)) {
            let sum = p[0] as u32 + p[1] as u32 + q[0] as u32 + q[1] as u32;
            *o = ((sum + 2) / 4) as u16;
        }
    }
}

/// `params` in binned pixels: a quarter of the area, half the margin.
pub fn binned_params(params: &CoarseParams) -> CoarseParams {
    CoarseParams {
        min_area_px: params.min_area_px.div_ceil(4),
        surface_margin_px: 0.5 * params.surface_margin_px,
        ..*params
    }
}

/// A full-frame line `Z = a + b·X` in binned pixels (`X = 2x + ½`, `Z = 2z + ½`).
pub fn to_binned_line(s: &SurfaceLine) -> SurfaceLine {
    SurfaceLine {
        row0_px: 0.5 * (s.row0_px + 0.5 * s.slope - 0.5),
        ..*s
    }
}

/// A binned line back in full-frame pixels (the inverse of [`to_binned_line`]).
pub fn from_binned_line(s: &SurfaceLine) -> SurfaceLine {
    SurfaceLine {
        row0_px: 2.0 * s.row0_px + 0.5 - 0.5 * s.slope,
        ..*s
    }
}

/// A binned circle in full-frame pixels.
pub fn from_binned_circle(c: &Circle) -> Circle {
    Circle {
        x_px: 2.0 * c.x_px + 0.5,
        z_px: 2.0 * c.z_px + 0.5,
        r_px: 2.0 * c.r_px,
    }
}

/// The first of `frames` (with its index) in which [`detect_coarse`] finds
/// the sphere, each frame's gain measured on its own reference strips.
pub fn first_appearance<'a>(
    frames: impl IntoIterator<Item = Band<'a>>,
    bg: &Background,
    surface: Option<&SurfaceLine>,
    params: &CoarseParams,
    scratch: &mut CoarseScratch,
) -> Result<Option<(usize, Coarse)>, DetectError> {
    for (k, band) in frames.into_iter().enumerate() {
        let gain = bg.gain(&band)?.gain;
        if let Some(c) = detect_coarse(&band, bg, gain, surface, params, scratch)? {
            return Ok(Some((k, c)));
        }
    }
    Ok(None)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::synth::Scene;

    fn scene(disk: (f64, f64, f64)) -> Scene {
        Scene {
            width: 256,
            height: 192,
            background: 200.0,
            vignetting: 0.1,
            sphere_transmission: 0.2,
            disk: Some(disk),
            band: None,
            blur_px: 1.0,
        }
    }

    #[test]
    fn the_binned_search_finds_the_circle_to_a_pixel_also_entering_at_the_top() {
        let empty = Scene {
            disk: None,
            ..scene((0.0, 0.0, 1.0))
        }
        .render()
        .mapv(|v| v.round() as u16);
        let views = [empty.view()];
        let bg = Background::from_frames(&views, Default::default()).unwrap();
        let binned = BinnedBackground::new(&bg);
        let mut scratch = CoarseScratch::default();
        // Whole, and entering through the top (centre above the frame).
        for disk in [(101.37, 80.62, 40.0), (140.8, -15.3, 45.0)] {
            let frame = scene(disk).render().mapv(|v| v.round() as u16);
            let c = binned
                .detect(
                    &Band::new(frame.view(), 0).unwrap(),
                    1.0,
                    None,
                    &CoarseParams::default(),
                    &mut scratch,
                )
                .unwrap()
                .expect("a sphere")
                .circle;
            // The threshold sits at 30 % darkening, not at half contrast,
            // and the 2×2 bins widen the blur: the outline lies outside the
            // edge (measured +0.4 px on the radius), evenly around it, so
            // the centre is off by little (measured ≤ 0.02 px). Bounds: the
            // centre to 0.1 px, the radius to 1 px (the tracker's
            // measurement re-centres; the background's mask pads by 6 px).
            let err = [c.x_px - disk.0, c.z_px - disk.1, c.r_px - disk.2];
            println!("{disk:?}: error (x, z, r) {err:.3?} px");
            assert!(
                err[0].abs() < 0.1 && err[1].abs() < 0.1 && err[2].abs() < 1.0,
                "{disk:?}: {c:?}"
            );
        }
    }

    #[test]
    fn a_glint_in_the_ball_does_not_pull_the_circle() {
        // A polished ball shows the backlight in its middle: full light
        // within 15 px of the centre and in three pixels of ten out to
        // 25 px. Those holes in the dark group are not its outline (kept,
        // their outlines made the circle 22 px small).
        let empty = Scene {
            disk: None,
            ..scene((0.0, 0.0, 1.0))
        }
        .render();
        let bg = Background::from_frames(
            &[empty.mapv(|v| v.round() as u16).view()],
            Default::default(),
        )
        .unwrap();
        let disk = (128.4, 90.7, 60.0);
        let mut img = scene(disk).render();
        for ((i, j), v) in img.indexed_iter_mut() {
            let d = (j as f64 - disk.0).hypot(i as f64 - disk.1);
            if d < 15.0 || (d < 25.0 && (i * 7919 + j * 104_729) % 10 < 3) {
                *v = empty[[i, j]];
            }
        }
        let frame = img.mapv(|v| v.round() as u16);
        let band = Band::new(frame.view(), 0).unwrap();
        let mut scratch = CoarseScratch::default();
        let c = detect_coarse(
            &band,
            &bg,
            1.0,
            None,
            &CoarseParams::default(),
            &mut scratch,
        )
        .unwrap()
        .expect("a sphere")
        .circle;
        let err = [c.x_px - disk.0, c.z_px - disk.1, c.r_px - disk.2];
        println!("error (x, z, r) {err:.3?} px");
        // As a ball without a glint (the outline outside the edge by a few
        // tenths: the threshold is not at half contrast).
        assert!(
            err[0].abs() < 0.1 && err[1].abs() < 0.1 && err[2].abs() < 1.0,
            "{c:?}"
        );
    }

    /// Dark shapes no circle fits — a line or a bar across the frame, a
    /// frame dark all over — are no sphere (`None`), in the full and the
    /// binned search alike, not an error that stops the run; a dark disk
    /// beside them is still found.
    #[test]
    fn a_dark_shape_no_circle_fits_is_no_sphere() {
        let (w, h) = (256usize, 192usize);
        let empty = ndarray::Array2::<u16>::from_elem((h, w), 2000);
        let bg = Background::from_frames(&[empty.view()], Default::default()).unwrap();
        let binned = BinnedBackground::new(&bg);
        type Shape = fn(usize, usize) -> bool;
        let shapes: [(&str, Shape); 5] = [
            ("a one-pixel line across", |i, _| i == 50),
            ("a one-pixel column", |_, j| j == 50),
            ("a bar across", |i, _| (40..60).contains(&i)),
            ("dark from the top down", |i, _| i < 30),
            ("dark all over", |_, _| true),
        ];
        let mut scratch = CoarseScratch::default();
        for (what, dark) in shapes {
            let frame =
                ndarray::Array2::from_shape_fn(
                    (h, w),
                    |(i, j)| {
                        if dark(i, j) {
                            300u16
                        } else {
                            2000
                        }
                    },
                );
            let band = Band::new(frame.view(), 0).unwrap();
            let params = CoarseParams::default();
            let full = detect_coarse(&band, &bg, 1.0, None, &params, &mut scratch);
            assert!(matches!(full, Ok(None)), "{what}: {full:?}");
            let half = binned.detect(&band, 1.0, None, &params, &mut scratch);
            assert!(matches!(half, Ok(None)), "{what} (binned): {half:?}");
        }
        // A disk of radius 20 at (120, 100): found to a pixel.
        let frame = ndarray::Array2::from_shape_fn((h, w), |(i, j)| {
            let (x, z) = (j as f64 - 120.0, i as f64 - 100.0);
            if x.hypot(z) < 20.0 {
                300u16
            } else {
                2000
            }
        });
        let band = Band::new(frame.view(), 0).unwrap();
        let c = detect_coarse(
            &band,
            &bg,
            1.0,
            None,
            &CoarseParams::default(),
            &mut scratch,
        )
        .unwrap()
        .expect("the disk")
        .circle;
        assert!(
            (c.x_px - 120.0).abs() < 1.0
                && (c.z_px - 100.0).abs() < 1.0
                && (c.r_px - 20.0).abs() < 1.0,
            "{c:?}"
        );
    }
}
