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

use super::circle::Circle;
use super::columns::window_columns;
use super::types::SurfaceLine;
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
    /// Frame width, px.
    pub width: usize,
    /// Frame height, px.
    pub height: usize,
    /// Row-major background levels, in the units of the frames.
    pub levels: Vec<f32>,
    /// The flicker reference strips.
    pub region: GainRegion,
    /// Gains of the frames the background was built from.
    pub gains: Vec<f64>,
    /// Columns `near_cols.0..near_cols.1` ([`super::columns::near_columns`]):
    /// within reach of the sphere's path in the sample frames (all of them
    /// when no sphere was found there). The levels are the samples' medians
    /// in these columns and in the reference strips, and the surface line is
    /// fitted in them; elsewhere the levels are the first sample frame's.
    pub near_cols: (usize, usize),
}

impl Background {
    /// Build from the first frames of a run (before the sphere appears).
    pub fn from_frames(
        frames: &[ArrayView2<u16>],
        region: GainRegion,
    ) -> Result<Self, DetectError> {
        let (height, width, region) = check_frames(frames, region)?;
        let ReferenceGains {
            pooled: gains,
            inverse_by_column: inv,
        } = reference_gains(frames, width, height, region)?;
        let mut levels = vec![0f32; width * height];
        let mut column = vec![0f64; frames.len()];
        for (i, out) in levels.chunks_exact_mut(width).enumerate() {
            plain_median_row(|k, j| frames[k][[i, j]], &inv, &mut column, out);
        }
        Ok(Background {
            width,
            height,
            levels,
            region,
            gains,
            near_cols: (0, width),
        })
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
    /// `σ_g = √(Σ(I − gB)² / (n − 1) / ΣB²)`; and the same for the left and
    /// the right strip alone, between which [`FrameGain::at`] interpolates
    /// (a light that drifts differently across the frame).
    pub fn gain(&self, band: &Band) -> Result<FrameGain, DetectError> {
        if band.width != self.width || band.row0 + band.nrows > self.height {
            return Err(DetectError::ShapeMismatch {
                width: band.width,
                height: band.row0 + band.nrows,
                bg_width: self.width,
                bg_height: self.height,
            });
        }
        let mut sides = [StripSums::default(); 2];
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
                sides[strip_side(j, self.width)].add(row[j] as f64, bg_row[j] as f64);
            }
        }
        let all = sides[0].merged(&sides[1]);
        let whole = all.gain().ok_or_else(|| DetectError::DarkReference {
            what: format!(
                "{}-px strips at the left and right edges, rows {}..{}",
                self.region.strip_px,
                band.row0,
                band.row0 + band.nrows
            ),
        })?;
        let side = |k: usize| {
            sides[k].gain().map(|(gain, sigma)| StripGain {
                column_px: strip_mean_column(self.width, self.region, k),
                gain,
                sigma,
            })
        };
        Ok(FrameGain {
            gain: whole.0,
            sigma: whole.1,
            sides: side(0).zip(side(1)).map(|(l, r)| [l, r]),
        })
    }
}

/// Sums over the reference pixels of one strip (or both).
#[derive(Debug, Clone, Copy, Default)]
struct StripSums {
    si: f64,
    sb: f64,
    sii: f64,
    sib: f64,
    sbb: f64,
    n: usize,
}

impl StripSums {
    fn add(&mut self, v: f64, b: f64) {
        self.si += v;
        self.sb += b;
        self.sii += v * v;
        self.sib += v * b;
        self.sbb += b * b;
        self.n += 1;
    }

    fn merged(&self, o: &StripSums) -> StripSums {
        StripSums {
            si: self.si + o.si,
            sb: self.sb + o.sb,
            sii: self.sii + o.sii,
            sib: self.sib + o.sib,
            sbb: self.sbb + o.sbb,
            n: self.n + o.n,
        }
    }

    /// `(g, σ_g)`, `None` without light.
    fn gain(&self) -> Option<(f64, f64)> {
        if !(self.sb > 0.0) {
            return None;
        }
        let g = self.si / self.sb;
        let ss = (self.sii - 2.0 * g * self.sib + g * g * self.sbb).max(0.0);
        Some((g, (ss / (self.n.max(2) - 1) as f64 / self.sbb).sqrt()))
    }
}

/// A frame's flicker gain and its standard error, over both reference
/// strips, and each strip's own (left, right).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameGain {
    /// The frame's gain relative to the background, over both strips.
    pub gain: f64,
    /// Standard error of `gain`.
    pub sigma: f64,
    /// Each strip's own (left, right); `None` unless both strips are lit.
    pub sides: Option<[StripGain; 2]>,
}

/// One reference strip's gain, its standard error, and its mean column.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StripGain {
    /// The strip's mean column, px.
    pub column_px: f64,
    /// The strip's gain relative to the background.
    pub gain: f64,
    /// Standard error of `gain`.
    pub sigma: f64,
}

impl FrameGain {
    /// The gain at column `x_px` and its standard error: linear between
    /// the two strips' (a backlight that drifts differently on the left and
    /// on the right of the frame changes the light at the sphere by as
    /// much as at the strips, not by their mean: on the real preset's 5 %
    /// drifts, a 2.8e-4 error of v_impact), constant beyond them.
    pub fn at(&self, x_px: f64) -> (f64, f64) {
        let Some([l, r]) = self.sides else {
            return (self.gain, self.sigma);
        };
        if !(r.column_px > l.column_px) {
            return (self.gain, self.sigma);
        }
        let u = ((x_px - l.column_px) / (r.column_px - l.column_px)).clamp(0.0, 1.0);
        (
            l.gain + u * (r.gain - l.gain),
            ((1.0 - u) * l.sigma).hypot(u * r.sigma),
        )
    }
}

/// The pixels pass 3 of [`Background::from_frames_with_sphere`] left NaN
/// (covered in every frame): above the surface line by [`fill_smooth`],
/// the rest along their rows.
pub(super) fn fill_covered(
    levels: &mut [f32],
    w: usize,
    h: usize,
    surface: Option<&SurfaceLine>,
    near_cols: (usize, usize),
) {
    fill_smooth(levels, w, h, surface, near_cols);
    for row in levels.chunks_exact_mut(w) {
        fill_row(row);
    }
}

/// Fill the NaN pixels above the surface line (all of them without one)
/// from a quadratic `B = a₀ + a₁x + a₂z + a₃x² + a₄xz + a₅z²` fitted to the
/// finite pixels above the line (minus 4 px) on a 4-px grid in columns
/// `near_cols` (thousands of
/// pixels for six coefficients, each a median of several frames), refitted
/// once without residuals over 3 MAD. Coordinates are scaled to ±1 for
/// conditioning. Leaves the rest (below the line) to the caller.
// Small fixed-size matrix code reads best with explicit indices.
#[allow(clippy::needless_range_loop)]
fn fill_smooth(
    levels: &mut [f32],
    w: usize,
    h: usize,
    surface: Option<&super::types::SurfaceLine>,
    (c0, c1): (usize, usize),
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
    const GRID: usize = 4;
    let samples: Vec<([f64; 6], f64)> = (0..h)
        .step_by(GRID)
        .flat_map(|r| (0..w).step_by(GRID).map(move |c| (r, c)))
        .filter(|&(_, c)| (c0..c1).contains(&c))
        .filter(|&(r, c)| !levels[r * w + c].is_nan() && above(r, c, 4.0))
        .map(|(r, c)| (basis(r, c), levels[r * w + c] as f64))
        .collect();
    let model = |b: &[f64; 6], k: &[f64; 6]| -> f64 { b.iter().zip(k).map(|(p, q)| p * q).sum() };
    let solve = |cut: f64, coef: Option<&[f64; 6]>| -> Option<[f64; 6]> {
        let mut ata = [[0.0; 6]; 6];
        let mut atb = [0.0; 6];
        for (b, v) in &samples {
            if let Some(k) = coef {
                if (v - model(b, k)).abs() > cut {
                    continue;
                }
            }
            for i in 0..6 {
                atb[i] += b[i] * v;
                for j in 0..=i {
                    ata[i][j] += b[i] * b[j];
                }
            }
        }
        for i in 0..6 {
            for j in i + 1..6 {
                ata[i][j] = ata[j][i];
            }
        }
        super::circle::solve_spd(&ata, &atb)
    };
    let Some(first) = solve(f64::INFINITY, None) else {
        return;
    };
    // The cut for the second round, from the first round's residuals.
    let mut resid: Vec<f64> = samples
        .iter()
        .map(|(b, v)| (v - model(b, &first)).abs())
        .collect();
    if resid.is_empty() {
        return;
    }
    let mid = resid.len() / 2;
    let mad = *resid.select_nth_unstable_by(mid, f64::total_cmp).1;
    let Some(k) = solve(3.0 * 1.4826 * mad, Some(&first)) else {
        return;
    };
    for r in 0..h {
        for c in 0..w {
            let v = &mut levels[r * w + c];
            if v.is_nan() && above(r, c, 0.0) {
                *v = model(&basis(r, c), &k) as f32;
            }
        }
    }
}

/// Most frames whose per-pixel median [`sort_rows`] takes; more go pixel by
/// pixel through [`median_of`].
const MAX_NETWORK_FRAMES: usize = 32;

/// Sort `n` rows of `w` values pixel by pixel (after it, `rows[k·w + j]` is
/// the `k`-th smallest of column `j`; no NaN) with the network `pairs` of
/// [`batcher_pairs`]`(n)` (Batcher's odd–even merge sort: 19
/// compare-exchanges for 8 rows), each compare-exchange a branch-free min/max between two whole
/// rows. On CPUs with AVX2 the same loop runs 8 lanes wide (chosen at run
/// time; min and max give the same bits at any width).
fn sort_rows(rows: &mut [f32], w: usize, pairs: &[(usize, usize)]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2, checked just above.
        unsafe { sort_rows_avx2(rows, w, pairs) };
        return;
    }
    sort_rows_portable(rows, w, pairs);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn sort_rows_avx2(rows: &mut [f32], w: usize, pairs: &[(usize, usize)]) {
    sort_rows_portable(rows, w, pairs);
}

#[inline(always)]
fn sort_rows_portable(rows: &mut [f32], w: usize, pairs: &[(usize, usize)]) {
    for &(lo, hi) in pairs {
        let (a, b) = rows.split_at_mut(hi * w);
        let (a, b) = (&mut a[lo * w..][..w], &mut b[..w]);
        for (x, y) in a.iter_mut().zip(b.iter_mut()) {
            let (p, q) = (*x, *y);
            // Plain comparisons, not f32::min/max: the values are never NaN
            // (levels or +∞), and these compile to one minps/maxps each
            // instead of a NaN-aware sequence.
            let lt = p < q;
            (*x, *y) = (if lt { p } else { q }, if lt { q } else { p });
        }
    }
}

/// The compare-exchanges `(lo, hi)` of Batcher's odd–even merge sort for `n`
/// inputs (Knuth, TAOCP vol. 3, §5.3.4), in order; for `n` not a power of
/// two, the network of the next power of two without the comparators that
/// touch the missing inputs (which would hold +∞ and never move).
fn batcher_pairs(n: usize) -> Vec<(usize, usize)> {
    let mut pairs = Vec::new();
    let mut p = 1;
    while p < n {
        let mut k = p;
        while k >= 1 {
            let mut j = k % p;
            while j + k < n {
                for i in 0..k.min(n - j - k) {
                    if (i + j) / (2 * p) == (i + j + k) / (2 * p) {
                        pairs.push((i + j, i + j + k));
                    }
                }
                j += 2 * k;
            }
            k /= 2;
        }
        p *= 2;
    }
    pairs
}

/// "Above the line by `margin`", true without a line.
trait AboveLine {
    fn is_none_or_above(&self, z: f64, x: f64, margin: f64) -> bool;
}

impl AboveLine for Option<&super::types::SurfaceLine> {
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
pub(super) fn fill_row(row: &mut [f32]) {
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

/// The frames' common shape `(height, width)` and the region clamped to it.
pub(super) fn check_frames(
    frames: &[ArrayView2<u16>],
    region: GainRegion,
) -> Result<(usize, usize, GainRegion), DetectError> {
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
    Ok((height, width, clamp_region(width, region)))
}

/// `region` made usable on frames `width` px wide: strips of 1 to half the
/// width, a step of at least 1.
pub(super) fn clamp_region(width: usize, region: GainRegion) -> GainRegion {
    GainRegion {
        strip_px: region.strip_px.clamp(1, (width / 2).max(1)),
        step: region.step.max(1),
    }
}

/// The background frames' gains relative to the first, from the raw sums
/// over the reference strips: over both strips, and per column, linear
/// between the left strip's and the right strip's own (see
/// [`FrameGain::at`]). A light that drifts differently on the two sides
/// would otherwise leave each pixel's median a different mixture of the
/// frames' lights where the sphere hid some of them: a step in `B` along
/// the sphere's path that moves its edges.
pub(super) struct ReferenceGains {
    pub(super) pooled: Vec<f64>,
    /// Per frame, `1/g` at every column.
    pub(super) inverse_by_column: Vec<Vec<f32>>,
}

pub(super) fn reference_gains(
    frames: &[ArrayView2<u16>],
    width: usize,
    height: usize,
    region: GainRegion,
) -> Result<ReferenceGains, DetectError> {
    let ref_sum = |f: &ArrayView2<u16>| -> [f64; 2] {
        let mut s = [0.0; 2];
        for i in (0..height).step_by(region.step) {
            for j in strip_columns(width, region) {
                s[strip_side(j, width)] += f[[i, j]] as f64;
            }
        }
        s
    };
    let sums: Vec<[f64; 2]> = frames.iter().map(ref_sum).collect();
    gains_from_sums(&sums, width, region)
}

/// 0 for a column of the left strip, 1 for the right's.
fn strip_side(column: usize, width: usize) -> usize {
    usize::from(column >= width / 2)
}

/// The mean column of the left (`side` 0) or the right (1) strip's
/// reference pixels.
fn strip_mean_column(width: usize, region: GainRegion, side: usize) -> f64 {
    let (sum, n) = strip_columns(width, region)
        .filter(|&j| strip_side(j, width) == side)
        .fold((0, 0), |(sum, n), j| (sum + j, n + 1));
    sum as f64 / n.max(1) as f64
}

/// [`ReferenceGains`] from each frame's sums over its left and right
/// reference strips ([`reference_gains`], [`reference_sum`]), relative to
/// the first frame.
pub(super) fn gains_from_sums(
    sums: &[[f64; 2]],
    width: usize,
    region: GainRegion,
) -> Result<ReferenceGains, DetectError> {
    let s0 = sums.first().copied().unwrap_or([0.0; 2]);
    if !(s0[0] + s0[1] > 0.0) {
        return Err(DetectError::DarkReference {
            what: format!("{}-px strips at the left and right edges", region.strip_px),
        });
    }
    let pooled: Vec<f64> = sums
        .iter()
        .map(|s| (s[0] + s[1]) / (s0[0] + s0[1]))
        .collect();
    let both_lit = s0[0] > 0.0 && s0[1] > 0.0;
    let inverse_by_column = sums
        .iter()
        .zip(&pooled)
        .map(|(s, &gain)| {
            let side = |k: usize| StripGain {
                column_px: strip_mean_column(width, region, k),
                gain: s[k] / s0[k],
                sigma: 0.0,
            };
            let light = FrameGain {
                gain,
                sigma: 0.0,
                sides: both_lit.then(|| [side(0), side(1)]),
            };
            (0..width)
                .map(|j| (1.0 / light.at(j as f64).0) as f32)
                .collect()
        })
        .collect();
    Ok(ReferenceGains {
        pooled,
        inverse_by_column,
    })
}

/// The reference columns: `0..strip` and `width − strip..width`, every `step`-th.
fn strip_columns(width: usize, region: GainRegion) -> impl Iterator<Item = usize> {
    let s = region.strip_px.min(width);
    (0..s)
        .step_by(region.step)
        .chain((width - s..width).step_by(region.step))
}

/// The columns where pass 3 takes medians: those near the sphere
/// (`near_cols`) and the reference strips, which set every frame's gain
/// ([`window_columns`]).
pub(super) fn median_columns(
    (c0, c1): (usize, usize),
    w: usize,
    region: GainRegion,
) -> Vec<std::ops::Range<usize>> {
    window_columns(c0..c1, region.strip_px.min(w), w)
}

/// Pass 3 of [`Background::from_frames_with_sphere`], row by row: the
/// per-pixel median of `I_f / g_f` (the gain at the pixel's column,
/// [`ReferenceGains`]) over the frames whose circle (plus the pad) does
/// not cover the pixel, in the columns `cols` ([`median_columns`]); NaN
/// where every frame covers it; the first frame's `I / g` in the other
/// columns.
pub(super) struct SphereMedian<'a> {
    inv: &'a [Vec<f32>],
    circles: &'a [Option<Circle>],
    pad_px: f64,
    w: usize,
    cols: Vec<std::ops::Range<usize>>,
    rows: Vec<f32>,
    count: Vec<usize>,
    values: Vec<f64>,
    pairs: Vec<(usize, usize)>,
}

impl<'a> SphereMedian<'a> {
    pub(super) fn new(
        inverse: &'a [Vec<f32>],
        circles: &'a [Option<Circle>],
        pad_px: f64,
        w: usize,
        cols: Vec<std::ops::Range<usize>>,
    ) -> Self {
        let n = inverse.len();
        let widest = cols.iter().map(|c| c.len()).max().unwrap_or(0);
        SphereMedian {
            inv: inverse,
            circles,
            pad_px,
            w,
            cols,
            rows: vec![0f32; n * widest],
            count: vec![0usize; widest],
            values: Vec::with_capacity(n),
            pairs: batcher_pairs(n),
        }
    }

    /// Row `r` of the levels into `out` (NaN left where no frame is
    /// uncovered), from `frame_row(k)`, row `r` of sample frame `k` (of
    /// which only the median columns are read, but in the first frame).
    pub(super) fn row<'r>(
        &mut self,
        r: usize,
        frame_row: impl Fn(usize) -> &'r [u16],
        out: &mut [f32],
    ) {
        // The first frame's `I / g` in columns `c`.
        let first = |out: &mut [f32], inv: &[f32], c: std::ops::Range<usize>| {
            for ((o, &v), &ig) in out[c.clone()]
                .iter_mut()
                .zip(&frame_row(0)[c.clone()])
                .zip(&inv[c])
            {
                *o = v as f32 * ig;
            }
        };
        let mut end = 0;
        for k in 0..self.cols.len() {
            let c = self.cols[k].clone();
            first(out, &self.inv[0], end..c.start);
            end = c.end;
            self.median_run(r, c.clone(), &frame_row, &mut out[c]);
        }
        first(out, &self.inv[0], end..self.w);
    }

    /// Columns `c` of row `r` (see [`Self::row`]) into `out`.
    fn median_run<'r>(
        &mut self,
        r: usize,
        c: std::ops::Range<usize>,
        frame_row: &impl Fn(usize) -> &'r [u16],
        out: &mut [f32],
    ) {
        let (n, w) = (self.inv.len(), c.len());
        let (rows, count) = (&mut self.rows[..n * w], &mut self.count[..w]);
        count.fill(n);
        for (k, ig) in self.inv.iter().enumerate() {
            let row = &mut rows[k * w..(k + 1) * w];
            for ((o, &v), &ig) in row
                .iter_mut()
                .zip(&frame_row(k)[c.clone()])
                .zip(&ig[c.clone()])
            {
                *o = v as f32 * ig;
            }
            if let Some(circle) = self.circles[k] {
                // Covered: (j − x)² + (r − z)² < (R + pad)².
                let (reach, dz) = (circle.r_px + self.pad_px, r as f64 - circle.z_px);
                let s2 = reach * reach - dz * dz;
                if s2 > 0.0 {
                    let s = s2.sqrt();
                    let lo = ((circle.x_px - s).floor() + 1.0).max(0.0);
                    let hi = ((circle.x_px + s).ceil() - 1.0).min(self.w as f64 - 1.0);
                    if lo <= hi {
                        // In this run's columns.
                        let (lo, hi) = ((lo as usize).max(c.start), (hi as usize + 1).min(c.end));
                        if lo < hi {
                            let span = lo - c.start..hi - c.start;
                            row[span.clone()].fill(f32::INFINITY);
                            count[span].iter_mut().for_each(|c| *c -= 1);
                        }
                    }
                }
            }
        }
        if n <= MAX_NETWORK_FRAMES {
            sort_rows(rows, w, &self.pairs);
            for (j, (o, &m)) in out.iter_mut().zip(count.iter()).enumerate() {
                if m > 0 {
                    let (a, b) = (rows[((m - 1) / 2) * w + j], rows[(m / 2) * w + j]);
                    *o = 0.5 * (a + b);
                }
            }
        } else {
            for (j, o) in out.iter_mut().enumerate() {
                self.values.clear();
                self.values.extend(
                    (0..n)
                        .map(|k| rows[k * w + j] as f64)
                        .filter(|v| v.is_finite()),
                );
                if !self.values.is_empty() {
                    *o = median_of(&mut self.values) as f32;
                }
            }
        }
    }
}

/// A row of [`Background::from_frames`]: at each column `j` of `out`, the
/// median of `value(k, j) / g_k(j)` over the frames `k` (`inverse[k][j]` is
/// `1/g_k(j)`, [`ReferenceGains`]; `column` is scratch of one value per
/// frame).
pub(super) fn plain_median_row(
    value: impl Fn(usize, usize) -> u16,
    inverse: &[Vec<f32>],
    column: &mut [f64],
    out: &mut [f32],
) {
    for (j, o) in out.iter_mut().enumerate() {
        for (k, c) in column.iter_mut().enumerate() {
            *c = value(k, j) as f64 * inverse[k][j] as f64;
        }
        *o = median_of(column) as f32;
    }
}

/// Sum of a whole row-major frame's reference strips (every
/// `region.step`-th row and column), added in the order
/// [`reference_gains`] adds them.
pub(super) fn reference_sum(frame: &[u16], width: usize, region: GainRegion) -> [f64; 2] {
    let mut sum = [0.0; 2];
    for row in frame.chunks_exact(width).step_by(region.step) {
        for j in strip_columns(width, region) {
            sum[strip_side(j, width)] += row[j] as f64;
        }
    }
    sum
}

#[cfg(test)]
mod tests;
