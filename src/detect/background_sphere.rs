//! The background of frames that may show the sphere
//! ([`Background::from_frames_with_sphere`]): passes 1 and 2 find each
//! sample frame's sphere with the coarse detector, against a coarse
//! background and a preliminary surface line, so that pass 3 takes its
//! medians where the sphere is not.

use ndarray::ArrayView2;

use super::background::{
    check_frames, fill_covered, fill_row, median_columns, reference_gains, Background, GainRegion,
    ReferenceGains, SphereMedian,
};
use super::circle::Circle;
use super::coarse;
use super::columns::{near_columns, MIN_COLUMNS};
use super::types::SurfaceLine;
use super::{Band, DetectError};

impl Background {
    /// Build from frames in which the sphere may already be in view (a
    /// movie that starts with the sphere in the picture, so there are no
    /// sphere-free frames). Three passes:
    ///
    /// 1. the per-pixel maximum of `I_f / g_f` over the frames: background
    ///    wherever the sphere uncovered the pixel at least once (biased up by
    ///    about two noise σ, harmless for a coarse threshold); pixels covered
    ///    in every frame (darker than half their row's 90th percentile,
    ///    taken over every 4th pixel), and the ring around them that only
    ///    the sphere's blurred edge uncovers (`grow_unseen`), are filled
    ///    along their row;
    /// 2. in each frame, the sphere's coarse circle against that maximum
    ///    ([`super::coarse::detect_coarse`], above a preliminary surface
    ///    line fitted to it); the pixels within `r + pad_px` of it are
    ///    "covered" in that frame. Passes 1 and 2 only need circles to
    ///    about a pixel (the pad is 6 px), so for frames of at least
    ///    128 × 128 px they run on the frames binned 2×2
    ///    ([`super::coarse::bin_frame`]): a quarter of the pixels;
    /// 3. the per-pixel median of `I_f / g_f` over the frames in which the
    ///    pixel is not covered: each row of every frame is scaled by `1/g_f`,
    ///    its covered run (one interval per frame and row) set to +∞, the
    ///    rows sorted pixel by pixel by an odd–even transposition network
    ///    (branch-free, vectorised across the row), and the median read at
    ///    the ranks of the `m` uncovered values. Pixels covered in every
    ///    frame (the core of a slow sphere's path, and the ring just outside
    ///    it at the deepest point) get a smooth model of the light: a
    ///    quadratic in `(x, z)` fitted to the filled pixels above the surface
    ///    (two rounds, the second without pixels more than 3 MAD off: dust).
    ///    Outside the sphere, `B` sets the zero of every edge profile, and a
    ///    straight row interpolation across a 160-px gap of a vignetted
    ///    light is off by ~0.5 %, which moves edges by ~0.03 px; the
    ///    quadratic follows a ramp-and-vignette light exactly.
    ///
    /// The gains come from the reference strips, which the sphere must not
    /// cross. Frames where no sphere is found count as sphere-free.
    pub fn from_frames_with_sphere(
        frames: &[ArrayView2<u16>],
        region: GainRegion,
        coarse: &super::coarse::CoarseParams,
        pad_px: f64,
    ) -> Result<Self, DetectError> {
        let (h, w, region) = check_frames(frames, region)?;
        let ReferenceGains {
            pooled: gains,
            inverse_by_column: inv,
        } = reference_gains(frames, w, h, region)?;
        let data: Vec<&[u16]> = frames
            .iter()
            .map(|f| f.as_slice().ok_or(DetectError::NotContiguous))
            .collect::<Result<_, _>>()?;
        let seen: Vec<Vec<u16>> = if binned_pass(w, h) {
            data.iter().map(|d| coarse_view(d, w, h)).collect()
        } else {
            Vec::new()
        };
        let seen: Vec<&[u16]> = if binned_pass(w, h) {
            seen.iter().map(|b| b.as_slice()).collect()
        } else {
            data.clone()
        };
        let (circles, surface) = circles_and_line(&seen, w, h, &gains, region, coarse)?;
        // Pass 3: per-pixel median over uncovered frames, in the columns near
        // the sphere and the strips; pixels never uncovered get a smooth
        // model of the light (below).
        let near_cols = near_columns(&circles, w, MIN_COLUMNS);
        let mut levels = vec![f32::NAN; w * h];
        let mut median = SphereMedian::new(
            &inv,
            &circles,
            pad_px,
            w,
            median_columns(near_cols, w, region),
        );
        for (r, out) in levels.chunks_exact_mut(w).enumerate() {
            median.row(r, |k| &data[k][r * w..(r + 1) * w], out);
        }
        fill_covered(&mut levels, w, h, surface.as_ref(), near_cols);
        Ok(Background {
            width: w,
            height: h,
            levels,
            region,
            gains,
            near_cols,
        })
    }
}

/// Passes 1 and 2 of [`Background::from_frames_with_sphere`] on frames
/// `w × h` (row-major): the per-pixel maximum of `I_f/g_f` (pixels darker
/// than half their row's 90th percentile, taken over every 4th pixel,
/// refilled along the row), a preliminary surface line fitted to it, and
/// each frame's coarse circle against it above that line — all in these
/// frames' pixels.
#[allow(clippy::type_complexity)]
fn coarse_pass(
    data: &[&[u16]],
    (w, h): (usize, usize),
    gains: &[f64],
    region: GainRegion,
    params: &coarse::CoarseParams,
) -> Result<(Vec<Option<Circle>>, Option<SurfaceLine>), DetectError> {
    let mut max = vec![0f32; w * h];
    for (d, &g) in data.iter().zip(gains) {
        let ig = (1.0 / g) as f32;
        for (m, &v) in max.iter_mut().zip(d.iter()) {
            let q = v as f32 * ig;
            *m = if q > *m { q } else { *m };
        }
    }
    let mut sorted = Vec::with_capacity(w.div_ceil(4));
    let mut p90s = Vec::with_capacity(h);
    for row in max.chunks_exact_mut(w) {
        sorted.clear();
        sorted.extend(row.iter().step_by(4).copied());
        let len = sorted.len();
        let p90 = *sorted
            .select_nth_unstable_by((len * 9 / 10).min(len - 1), f32::total_cmp)
            .1;
        for v in row.iter_mut() {
            if *v < 0.5 * p90 {
                *v = f32::NAN;
            }
        }
        p90s.push(p90);
    }
    grow_unseen(&mut max, w, &p90s);
    for row in max.chunks_exact_mut(w) {
        fill_row(row);
    }
    let bg = Background {
        width: w,
        height: h,
        levels: max,
        region,
        gains: gains.to_vec(),
        near_cols: (0, w),
    };
    // The line only bounds the coarse search and the light's smooth model
    // (margins of pixels): the area rows suffice.
    let params_line = super::surface::SurfaceParams {
        flank_fits: false,
        ..Default::default()
    };
    let surface = super::surface::fit_surface(&bg, &params_line).ok();
    let mut scratch = coarse::CoarseScratch::default();
    let circles = data
        .iter()
        .zip(gains)
        .map(|(d, &g)| {
            let band = Band {
                data: d,
                row0: 0,
                nrows: h,
                width: w,
                cols: (0, w),
            };
            let c = coarse::detect_coarse(&band, &bg, g, surface.as_ref(), params, &mut scratch)?;
            Ok(c.map(|c| c.circle))
        })
        .collect::<Result<_, DetectError>>()?;
    Ok((circles, surface))
}

/// Steps (pixels of the frames passes 1 and 2 see) by which
/// [`grow_unseen`] widens the region that no sample frame showed bare.
const UNSEEN_GROW_STEPS: usize = 4;

/// Level, as a fraction of its row's 90th percentile, below which a pixel
/// next to the unseen region joins it ([`grow_unseen`]).
const UNSEEN_GROW_LEVEL: f32 = 0.9;

/// Widen the NaN region of the per-pixel maximum (pixels dark in every
/// sample frame: the sphere covered them in all) by the ring around it
/// whose maximum is still below [`UNSEEN_GROW_LEVEL`] of its row's 90th
/// percentile (`p90s`), at most [`UNSEEN_GROW_STEPS`] pixels out.
///
/// Where the sphere is in view in every sample frame and moves less than
/// its diameter between them, the pixels just outside that region are on
/// the sphere's blurred edge in the frame that uncovers them most: their
/// maximum is a fraction of the light (half of it at the region's border,
/// where the threshold put it). Kept, they make a dark ring in the coarse
/// background, and filling the region along its rows interpolates
/// between those darkened borders: the sphere's pixels are then measured
/// against half the light, and its coarse circle (which masks it out of
/// the background) comes out pixels small and off centre. Filled from
/// the light beyond that ring instead, the coarse background is the light.
fn grow_unseen(max: &mut [f32], w: usize, p90s: &[f32]) {
    let h = p90s.len();
    let mut front: Vec<usize> = (0..max.len()).filter(|&k| max[k].is_nan()).collect();
    let mut next = Vec::new();
    for _ in 0..UNSEEN_GROW_STEPS {
        next.clear();
        for &k in &front {
            let (i, j) = (k / w, k % w);
            let neighbours = [
                (i > 0).then(|| k - w),
                (i + 1 < h).then(|| k + w),
                (j > 0).then(|| k - 1),
                (j + 1 < w).then(|| k + 1),
            ];
            for kk in neighbours.into_iter().flatten() {
                let v = max[kk];
                if v < UNSEEN_GROW_LEVEL * p90s[kk / w] {
                    max[kk] = f32::NAN;
                    next.push(kk);
                }
            }
        }
        if next.is_empty() {
            break;
        }
        std::mem::swap(&mut front, &mut next);
    }
}

/// Whether passes 1 and 2 of [`Background::from_frames_with_sphere`] run on
/// the frames binned 2×2: when they are large enough (a quarter of the
/// pixels; the circles come back to within a pixel, well inside the pad).
pub(super) fn binned_pass(w: usize, h: usize) -> bool {
    w >= 128 && h >= 128
}

/// A `w × h` frame as passes 1 and 2 see it when [`binned_pass`]: binned
/// 2×2 ([`coarse::bin_frame`]).
pub(super) fn coarse_view(frame: &[u16], w: usize, h: usize) -> Vec<u16> {
    let (wb, hb) = (w / 2, h / 2);
    let mut out = Vec::with_capacity(wb * hb);
    coarse::bin_frame(frame, w, wb, hb, &mut out);
    out
}

/// Passes 1 and 2 of [`Background::from_frames_with_sphere`]: each sample
/// frame's coarse circle and the preliminary surface line, in full-frame
/// pixels, from the frames as passes 1 and 2 see them (`seen`: binned
/// 2×2 by [`coarse_view`] when [`binned_pass`], else whole).
#[allow(clippy::type_complexity)]
pub(super) fn circles_and_line(
    seen: &[&[u16]],
    w: usize,
    h: usize,
    gains: &[f64],
    region: GainRegion,
    coarse: &coarse::CoarseParams,
) -> Result<(Vec<Option<Circle>>, Option<SurfaceLine>), DetectError> {
    if !binned_pass(w, h) {
        return coarse_pass(seen, (w, h), gains, region, coarse);
    }
    let params = coarse::binned_params(coarse);
    let (circles, line) = coarse_pass(seen, (w / 2, h / 2), gains, region, &params)?;
    Ok((
        circles
            .iter()
            .map(|c| c.as_ref().map(coarse::from_binned_circle))
            .collect(),
        line.as_ref().map(coarse::from_binned_line),
    ))
}
