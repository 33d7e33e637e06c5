//! The background: what every pixel shows without the sphere, and the
//! lamp's flicker as one gain per frame.
//!
//! Model: frame `f` shows `I_f(p) = g_f · B(p) + noise` wherever the sphere is
//! not, with one gain `g_f` per frame (the backlight's flicker). The gain is
//! measured on a reference region the sphere never crosses — by default two
//! strips at the left and right edges of the frame — as
//! `g_f = Σ_ref I_f / Σ_ref B`. The background is the per-pixel median of
//! `I_f / g_f` over the first frames, normalised so that `g = 1` on the first
//! frame; the median resists a frame or two with a passing speck.

use super::{Band, DetectError};

/// The median of a non-empty slice (the mean of the two middle values for an
/// even count); reorders the slice. The background takes one per pixel over
/// a handful of frames, where a plain insertion sort beats both the standard
/// sort and selection (measured: `cargo bench --bench track`).
fn median_of(v: &mut [f64]) -> f64 {
    let n = v.len();
    if n <= 24 {
        for i in 1..n {
            let x = v[i];
            let mut j = i;
            while j > 0 && v[j - 1] > x {
                v[j] = v[j - 1];
                j -= 1;
            }
            v[j] = x;
        }
    } else {
        v.sort_unstable_by(f64::total_cmp);
    }
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}
use ndarray::ArrayView2;

/// Most rows of the reference strips read by [`Background::gain`].
pub const MAX_GAIN_ROWS: usize = 48;

/// Columns of the flicker reference region: two strips of this width at the
/// left and right edges of the frame (all rows).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GainRegion {
    /// Width of each strip (px).
    pub strip_px: usize,
    /// Use every `step`-th pixel along rows and columns (speed; 1 = all).
    pub step: usize,
}

impl Default for GainRegion {
    fn default() -> Self {
        GainRegion {
            strip_px: 16,
            step: 2,
        }
    }
}

/// Per-pixel background and the flicker reference region.
#[derive(Debug, Clone, PartialEq)]
pub struct Background {
    pub width: usize,
    pub height: usize,
    /// Row-major background levels, in the units of the frames.
    pub levels: Vec<f32>,
    pub region: GainRegion,
    /// Gains of the frames the background was built from.
    pub gains: Vec<f64>,
}

impl Background {
    /// Build from the first frames of a run (before the sphere appears).
    pub fn from_frames(
        frames: &[ArrayView2<u16>],
        region: GainRegion,
    ) -> Result<Self, DetectError> {
        let first = frames.first().ok_or(DetectError::NoBackgroundFrames)?;
        let (height, width) = first.dim();
        for f in frames {
            let (h, w) = f.dim();
            if (h, w) != (height, width) {
                return Err(DetectError::ShapeMismatch {
                    width: w,
                    height: h,
                    bg_width: width,
                    bg_height: height,
                });
            }
        }
        let region = GainRegion {
            strip_px: region.strip_px.clamp(1, (width / 2).max(1)),
            step: region.step.max(1),
        };
        // Gains relative to the first frame, from the raw reference sums.
        let ref_sum = |f: &ArrayView2<u16>| -> f64 {
            let mut s = 0.0;
            for i in (0..height).step_by(region.step) {
                for j in strip_columns(width, region) {
                    s += f[[i, j]] as f64;
                }
            }
            s
        };
        let s0 = ref_sum(first);
        if !(s0 > 0.0) {
            return Err(DetectError::DarkReference {
                what: format!("{}-px strips at the left and right edges", region.strip_px),
            });
        }
        let gains: Vec<f64> = frames.iter().map(|f| ref_sum(f) / s0).collect();
        let mut levels = vec![0f32; width * height];
        let mut column = vec![0f64; frames.len()];
        for i in 0..height {
            for j in 0..width {
                for (k, f) in frames.iter().enumerate() {
                    column[k] = f[[i, j]] as f64 / gains[k];
                }
                levels[i * width + j] = median_of(&mut column) as f32;
            }
        }
        Ok(Background {
            width,
            height,
            levels,
            region,
            gains,
        })
    }

    /// Build from frames in which the sphere may already be in view (a
    /// movie that starts with the sphere in the picture, so there are no
    /// sphere-free frames). Three passes:
    ///
    /// 1. the per-pixel maximum of `I_f / g_f` over the frames: background
    ///    wherever the sphere uncovered the pixel at least once (biased up by
    ///    about two noise σ, harmless for a coarse threshold); pixels covered
    ///    in every frame (darker than half their row's 90th percentile) are
    ///    filled along their row;
    /// 2. in each frame, the sphere's coarse circle against that maximum
    ///    ([`super::coarse::detect_coarse`], above a preliminary surface
    ///    line fitted to it); the pixels within `r + pad_px` of it are
    ///    "covered" in that frame;
    /// 3. the per-pixel median of `I_f / g_f` over the frames in which the
    ///    pixel is not covered. Pixels covered in every frame (the core of a
    ///    slow sphere's path, and the ring just outside it at the deepest
    ///    point) get a smooth model of the light: a quadratic in `(x, z)`
    ///    fitted to the filled pixels above the surface (two rounds, the
    ///    second without pixels more than 3 MAD off: dust). Outside the
    ///    sphere, `B` sets the zero of every edge profile, and a straight
    ///    row interpolation across a 160-px gap of a vignetted light is off by
    ///    ~0.5 %, which moves edges by ~0.03 px; the quadratic follows a
    ///    ramp-and-vignette light exactly.
    ///
    /// The gains come from the reference strips, which the sphere must not
    /// cross. Frames where no sphere is found count as sphere-free.
    pub fn from_frames_with_sphere(
        frames: &[ArrayView2<u16>],
        region: GainRegion,
        coarse: &super::coarse::CoarseParams,
        pad_px: f64,
    ) -> Result<Self, DetectError> {
        // Pass 1: the maximum (and the gains) via an all-frames "background".
        let mut bg = Self::from_frames(frames, region)?;
        let (h, w) = (bg.height, bg.width);
        for (i, v) in bg.levels.iter_mut().enumerate() {
            let (r, c) = (i / w, i % w);
            *v = frames
                .iter()
                .zip(&bg.gains)
                .map(|(f, g)| f[[r, c]] as f64 / g)
                .fold(0.0, f64::max) as f32;
        }
        // Pixels the sphere covers in every frame stay dark in the maximum:
        // those below half their row's 90th percentile are refilled along
        // the row, so that the sphere is darker than this background in
        // every frame, whole.
        let mut sorted = vec![0f32; w];
        for r in 0..h {
            let row = &mut bg.levels[r * w..(r + 1) * w];
            sorted.copy_from_slice(row);
            let k = (w * 9) / 10;
            let p90 = *sorted
                .select_nth_unstable_by(k.min(w - 1), f32::total_cmp)
                .1;
            for v in row.iter_mut() {
                if *v < 0.5 * p90 {
                    *v = f32::NAN;
                }
            }
            fill_row(row);
        }
        // Pass 2: coarse circles, from their outline above a preliminary
        // surface line (below it the pillars hide the sphere, and the
        // mask's flat bottom there is no edge of the sphere).
        let surface =
            super::surface::fit_surface(&bg, &super::surface::SurfaceParams::default()).ok();
        let mut scratch = super::coarse::CoarseScratch::default();
        let mut circles = Vec::with_capacity(frames.len());
        for (f, &g) in frames.iter().zip(&bg.gains) {
            let band = Band::new(f.view(), 0)?;
            let c = super::coarse::detect_coarse(
                &band,
                &bg,
                g,
                surface.as_ref(),
                coarse,
                &mut scratch,
            )?;
            circles.push(c.map(|c| c.circle));
        }
        // Pass 3: per-pixel median over uncovered frames; pixels never
        // uncovered get a smooth model of the light (below).
        let mut values = Vec::with_capacity(frames.len());
        let mut levels = vec![f32::NAN; w * h];
        for r in 0..h {
            for c in 0..w {
                values.clear();
                for ((f, &g), circle) in frames.iter().zip(&bg.gains).zip(&circles) {
                    let covered = circle.is_some_and(|k| {
                        let d2 = (c as f64 - k.x_px).powi(2) + (r as f64 - k.z_px).powi(2);
                        d2 < (k.r_px + pad_px).powi(2)
                    });
                    if !covered {
                        values.push(f[[r, c]] as f64 / g);
                    }
                }
                if !values.is_empty() {
                    levels[r * w + c] = median_of(&mut values) as f32;
                }
            }
        }
        fill_smooth(&mut levels, w, h, surface.as_ref());
        for r in 0..h {
            fill_row(&mut levels[r * w..(r + 1) * w]);
        }
        bg.levels = levels;
        Ok(bg)
    }

    /// The background level at a pixel.
    #[inline]
    pub fn at(&self, row: usize, col: usize) -> f32 {
        self.levels[row * self.width + col]
    }

    /// Bilinear interpolation at frame coordinates; `None` outside.
    #[inline]
    pub fn bilinear(&self, x: f64, z: f64) -> Option<f64> {
        if !(x >= 0.0 && z >= 0.0) {
            return None;
        }
        let (j, i) = (x as usize, z as usize);
        if j + 1 >= self.width || i + 1 >= self.height {
            return None;
        }
        let (fx, fz) = (x - j as f64, z - i as f64);
        let k = i * self.width + j;
        let l = &self.levels;
        let top = l[k] as f64 + fx * (l[k + 1] as f64 - l[k] as f64);
        let bot = l[k + self.width] as f64
            + fx * (l[k + self.width + 1] as f64 - l[k + self.width] as f64);
        Some(top + fz * (bot - top))
    }

    /// The flicker gain of a band of rows of a frame: `g = Σ_ref I / Σ_ref B`
    /// over the reference strips in the band's rows (every `step`-th row, at
    /// most [`MAX_GAIN_ROWS`] rows), with its standard error
    /// `σ_g = √(Σ(I − gB)² / (n − 1) / ΣB²)`.
    pub fn gain(&self, band: &Band) -> Result<FrameGain, DetectError> {
        if band.width != self.width || band.row0 + band.nrows > self.height {
            return Err(DetectError::ShapeMismatch {
                width: band.width,
                height: band.row0 + band.nrows,
                bg_width: self.width,
                bg_height: self.height,
            });
        }
        let (mut si, mut sb, mut sii, mut sib, mut sbb) = (0.0, 0.0, 0.0, 0.0, 0.0);
        let mut n = 0usize;
        // At most `MAX_GAIN_ROWS` rows, evenly spaced: enough light for a
        // gain to ~4e-4 and few cache lines touched per frame.
        let row_step = self
            .region
            .step
            .max(band.nrows.div_ceil(MAX_GAIN_ROWS))
            .max(1);
        let first = band.row0.div_ceil(row_step) * row_step;
        for i in (first..band.row0 + band.nrows).step_by(row_step) {
            let row = &band.data[(i - band.row0) * band.width..][..band.width];
            let bg_row = &self.levels[i * self.width..][..self.width];
            for j in strip_columns(self.width, self.region) {
                let (v, b) = (row[j] as f64, bg_row[j] as f64);
                si += v;
                sb += b;
                sii += v * v;
                sib += v * b;
                sbb += b * b;
                n += 1;
            }
        }
        if !(sb > 0.0) {
            return Err(DetectError::DarkReference {
                what: format!(
                    "{}-px strips at the left and right edges, rows {}..{}",
                    self.region.strip_px,
                    band.row0,
                    band.row0 + band.nrows
                ),
            });
        }
        let g = si / sb;
        let ss = (sii - 2.0 * g * sib + g * g * sbb).max(0.0);
        let sigma = (ss / (n.max(2) - 1) as f64 / sbb).sqrt();
        Ok(FrameGain { gain: g, sigma })
    }
}

/// A frame's flicker gain and its standard error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameGain {
    pub gain: f64,
    pub sigma: f64,
}

/// Fill the NaN pixels above the surface line (all of them without one)
/// from a quadratic `B = a₀ + a₁x + a₂z + a₃x² + a₄xz + a₅z²` fitted to the
/// finite pixels above the line (minus 4 px) on a 2-px grid, refitted once
/// without residuals over 3 MAD. Coordinates are scaled to ±1 for
/// conditioning. Leaves the rest (below the line) to the caller.
fn fill_smooth(
    levels: &mut [f32],
    w: usize,
    h: usize,
    surface: Option<&super::surface::SurfaceLine>,
) {
    if !levels.iter().any(|v| v.is_nan()) {
        return;
    }
    let above = |r: usize, c: usize, margin: f64| -> bool {
        surface.is_none_or_above(r as f64, c as f64, margin)
    };
    let (sx, sz) = (0.5 * w as f64, 0.5 * h as f64);
    let basis = |r: usize, c: usize| -> [f64; 6] {
        let x = (c as f64 - sx) / sx;
        let z = (r as f64 - sz) / sz;
        [1.0, x, z, x * x, x * z, z * z]
    };
    let mut coef: Option<[f64; 6]> = None;
    let mut cut = f64::INFINITY;
    for _round in 0..2 {
        let mut ata = [[0.0; 6]; 6];
        let mut atb = [0.0; 6];
        let mut resid = Vec::new();
        for r in (0..h).step_by(2) {
            for c in (0..w).step_by(2) {
                let v = levels[r * w + c];
                if v.is_nan() || !above(r, c, 4.0) {
                    continue;
                }
                let b = basis(r, c);
                if let Some(k) = coef {
                    let model: f64 = b.iter().zip(&k).map(|(p, q)| p * q).sum();
                    let d = v as f64 - model;
                    resid.push(d.abs());
                    if d.abs() > cut {
                        continue;
                    }
                }
                for i in 0..6 {
                    atb[i] += b[i] * v as f64;
                    for j in 0..6 {
                        ata[i][j] += b[i] * b[j];
                    }
                }
            }
        }
        match super::circle::solve_spd(&ata, &atb) {
            Some(k) => coef = Some(k),
            None => return,
        }
        // The cut for the next round, from this round's residuals.
        if let Some(k) = coef {
            resid.clear();
            for r in (0..h).step_by(2) {
                for c in (0..w).step_by(2) {
                    let v = levels[r * w + c];
                    if v.is_nan() || !above(r, c, 4.0) {
                        continue;
                    }
                    let model: f64 = basis(r, c).iter().zip(&k).map(|(p, q)| p * q).sum();
                    resid.push((v as f64 - model).abs());
                }
            }
            if resid.is_empty() {
                return;
            }
            let mid = resid.len() / 2;
            let mad = *resid.select_nth_unstable_by(mid, f64::total_cmp).1;
            cut = 3.0 * 1.4826 * mad;
        }
    }
    let Some(k) = coef else { return };
    for r in 0..h {
        for c in 0..w {
            let v = &mut levels[r * w + c];
            if v.is_nan() && above(r, c, 0.0) {
                *v = basis(r, c).iter().zip(&k).map(|(p, q)| p * q).sum::<f64>() as f32;
            }
        }
    }
}

/// "Above the line by `margin`", true without a line.
trait AboveLine {
    fn is_none_or_above(&self, z: f64, x: f64, margin: f64) -> bool;
}

impl AboveLine for Option<&super::surface::SurfaceLine> {
    fn is_none_or_above(&self, z: f64, x: f64, margin: f64) -> bool {
        match self {
            Some(s) => z < s.row_at(x) - margin,
            None => true,
        }
    }
}

/// Replace the NaN runs of a row by linear interpolation between their
/// neighbours (or the nearest value at the row's ends); a row of NaN only
/// becomes 0.
fn fill_row(row: &mut [f32]) {
    let n = row.len();
    let mut j = 0;
    while j < n {
        if !row[j].is_nan() {
            j += 1;
            continue;
        }
        let start = j;
        while j < n && row[j].is_nan() {
            j += 1;
        }
        let left = (start > 0).then(|| row[start - 1]);
        let right = (j < n).then(|| row[j]);
        for (k, v) in row.iter_mut().enumerate().take(j).skip(start) {
            *v = match (left, right) {
                (Some(a), Some(b)) => {
                    let f = (k + 1 - start) as f32 / (j + 1 - start) as f32;
                    a + f * (b - a)
                }
                (Some(a), None) => a,
                (None, Some(b)) => b,
                (None, None) => 0.0,
            };
        }
    }
}

/// The reference columns: `0..strip` and `width − strip..width`, every `step`-th.
fn strip_columns(width: usize, region: GainRegion) -> impl Iterator<Item = usize> {
    let s = region.strip_px.min(width);
    (0..s)
        .step_by(region.step)
        .chain((width - s..width).step_by(region.step))
}

#[cfg(test)]
mod tests {
    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(super::median_of(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(super::median_of(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(super::median_of(&mut [7.0]), 7.0);
    }

    use super::*;
    use ndarray::Array2;

    #[test]
    fn flicker_is_divided_out_and_a_passing_speck_is_ignored() {
        let (h, w) = (40, 64);
        let truth = Array2::from_shape_fn((h, w), |(i, j)| 100.0 + i as f64 + 0.5 * j as f64);
        let gains = [1.0, 1.03, 0.97, 1.01, 0.99];
        let frames: Vec<Array2<u16>> = gains
            .iter()
            .enumerate()
            .map(|(k, g)| {
                let mut f = truth.mapv(|v| (v * g) as u16);
                if k == 2 {
                    f[[20, 30]] = 0; // a speck in one frame
                }
                f
            })
            .collect();
        let views: Vec<_> = frames.iter().map(|f| f.view()).collect();
        let bg = Background::from_frames(
            &views,
            GainRegion {
                strip_px: 8,
                step: 1,
            },
        )
        .unwrap();
        for (k, g) in gains.iter().enumerate() {
            // Truncation to integers moves each gain by < 1/100 of a level.
            assert!(
                (bg.gains[k] - g).abs() < 0.01,
                "{k}: {} vs {g}",
                bg.gains[k]
            );
        }
        // Median of 5 gain-corrected values: within 1 level of the truth.
        assert!((bg.at(20, 30) as f64 - truth[[20, 30]]).abs() < 1.5);
        let band = Band::new(frames[1].slice(ndarray::s![10..30, ..]), 10).unwrap();
        let g = bg.gain(&band).unwrap();
        assert!((g.gain - 1.03).abs() < 0.01, "{g:?}");
        // Truncation residuals (≤ 1 level of ~130) give σ_g of order 1e-4.
        assert!(g.sigma > 0.0 && g.sigma < 1e-3, "{g:?}");
    }
}
