//! The surface line: the top of the pillar band as a sub-pixel straight line
//! `row = row0_px + slope · column` (the camera may be tilted).
//!
//! Method, on the background image (many frames averaged, so little noise):
//! 1. per column, the first bright-to-dark step going down (`B(z) − B(z+1)`
//!    a local maximum) of at least a fifth of the column's largest within
//!    the search rows: the band's top, even where a glossy strip's lower
//!    edge below it is the larger step;
//! 2. a sub-pixel row by fitting a blurred step to the step's flank: rows
//!    `z_s − w ..= z_s + 2` (the flat background above, the step, one row
//!    into the band) against `hi − (hi − lo)·A(z)`, with `A` the Gaussian-
//!    blurred unit step averaged over the pixel,
//!    `A(z) = σ·[IΦ((z + ½ − e)/σ) − IΦ((z − ½ − e)/σ)]`, `IΦ(u) = uΦ(u) + φ(u)`
//!    (Levenberg–Marquardt on `e, σ, hi, lo`). Where a strip's lower edge
//!    is resolved within 6 rows below the top (a rise, or a further drop of
//!    its own, of at least 4 % of the largest step: a pillar-top row
//!    darker than the band, a glossy strip brighter than it), the
//!    window reaches 3 rows past it and the model is two blurred steps with
//!    one σ ([`two_step_edge_row`]), the top one's row kept. It is exact for a blurred,
//!    area-sampled straight edge at any tilt (no pixel locking), and it looks
//!    only at the flank, so what lies inside the band — a darker or brighter
//!    top row of pillar tops seen edge-on, a glossy strip reflecting the
//!    backlight — moves it far less than a moment over the whole step does.
//!    The area (coverage-sum) row of the same step,
//!    `e_a = z_top − ½ + Σ (B − lo)/(hi − lo)` over `2w + 2` rows, is exact for
//!    a clean step too; where the band's top is structured the two disagree,
//!    and their median disagreement is kept as the line's edge-model error
//!    ([`SurfaceLine::model_err_px`]);
//! 3. a robust line through the column edges: Theil–Sen start (median of
//!    slopes between columns half the width apart, median intercept), then
//!    Tukey-weighted least squares with the scale from the MAD. Columns where
//!    the band's top is not the strongest step (channels, dust) are rejected.
//!
//! The uncertainty is that of the weighted least-squares line,
//! `σ̂²(XᵀWX)⁻¹`, with `σ̂²` the weighted residual variance.

use super::background::Background;
pub use super::types::SurfaceLine;
use super::DetectError;

/// Settings of [`fit_surface`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceParams {
    /// Rows searched for the band's top (default: the whole frame).
    pub rows: Option<(usize, usize)>,
    /// Half-height `w` of the area window (rows each side of the step).
    pub half_window: usize,
    /// Smallest relative step `(hi − lo)/hi` for a column to count.
    pub min_contrast: f64,
    /// Tukey's constant in units of the MAD scale.
    pub tukey_c: f64,
    /// Floor of the residual scale (px).
    pub min_scale_px: f64,
    /// Fit the blurred step to each column's flank (module doc, step 2);
    /// `false`: the area row alone, a line to a small fraction of a pixel
    /// on a clean band top and to half a pixel on a structured one — enough
    /// where the line is only a bound (the background's coarse passes),
    /// without the flank fits' cost (most of the line's).
    pub flank_fits: bool,
}

impl Default for SurfaceParams {
    fn default() -> Self {
        SurfaceParams {
            rows: None,
            half_window: 5,
            min_contrast: 0.2,
            tukey_c: 4.685,
            min_scale_px: 0.005,
            flank_fits: true,
        }
    }
}

/// The band's top in one column.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColumnEdge {
    /// The column, px.
    pub x_px: f64,
    /// Row of the blurred-step fit to the flank (module doc, step 2).
    pub row_px: f64,
    /// Row by the area method over the whole step.
    pub row_area_px: f64,
}

/// Sub-pixel row of the band's top in every column of the background's
/// [`Background::near_cols`] where one is found.
pub fn column_edges(bg: &Background, params: &SurfaceParams) -> Vec<ColumnEdge> {
    let w = params.half_window;
    let (r_lo, r_hi) = params.rows.unwrap_or((0, bg.height));
    let r_hi = r_hi.min(bg.height);
    let (c0, c1) = (bg.near_cols.0.min(bg.width), bg.near_cols.1.min(bg.width));
    let mut out = Vec::with_capacity(c1.saturating_sub(c0));
    if r_hi < r_lo + 2 * w + 2 || c0 >= c1 {
        return out;
    }
    // Row by row (the image is row-major): per column, the first row of
    // the largest step.
    let (width, cols) = (bg.width, c1 - c0);
    let mut best_row = vec![0usize; cols];
    let mut best_step = vec![f64::NEG_INFINITY; cols];
    for i in r_lo + w..r_hi - w - 1 {
        let (upper, lower) = (
            &bg.levels[i * width + c0..][..cols],
            &bg.levels[(i + 1) * width + c0..][..cols],
        );
        for j in 0..cols {
            let step = upper[j] as f64 - lower[j] as f64;
            if step > best_step[j] {
                best_step[j] = step;
                best_row[j] = i;
            }
        }
    }
    // Each column on its own (on every thread), in order.
    use rayon::prelude::*;
    let edge = |flank: &mut Vec<f64>, j: usize| -> Option<ColumnEdge> {
        let (best_row, best_step) = (best_row[j - c0], best_step[j - c0]);
        if best_step <= 0.0 {
            return None;
        }
        let zs = top_step_row(bg, j, r_lo + w, best_row, best_step);
        // Window rows zs − w ..= zs + 1 + w.
        let top = zs - w;
        let bot = zs + 1 + w;
        let row_area_px = area_row(bg, j, (top, bot), params)?;
        if !params.flank_fits {
            return Some(ColumnEdge {
                x_px: j as f64,
                row_px: row_area_px,
                row_area_px,
            });
        }
        flank.clear();
        let strip = strip_edge_row(bg, j, zs, best_step).filter(|&z| z + 3 < r_hi);
        let two = strip.and_then(|z2| {
            // A strip below the top (a glossy or pillar-top row): both edges.
            flank.extend((top..=z2 + 3).map(|i| bg.at(i, j) as f64));
            two_step_edge_fit(flank, top as f64, [zs as f64 + 0.5, z2 as f64 + 0.5])
        });
        let (row_px, sigma_px) = match two {
            Some(fit) => fit,
            None => {
                flank.clear();
                flank.extend((top..=zs + 2).map(|i| bg.at(i, j) as f64));
                step_edge_fit(flank, top as f64, zs as f64 + 0.5)?
            }
        };
        // A step blurred beyond these windows (a defocused band top): its
        // derivative is wide and the flank fit's own blur says so. Then the
        // whole step, on windows as wide as its blur.
        if sigma_px >= WIDE_STEP_SIGMA_PX {
            if let Some(sigma0) = wide_step_sigma(bg, j, best_row, best_step, (r_lo, r_hi)) {
                return wide_step_edge(bg, j, best_row, sigma0.max(sigma_px), (r_lo, r_hi), params);
            }
        }
        Some(ColumnEdge {
            x_px: j as f64,
            row_px,
            row_area_px,
        })
    };
    let edges: Vec<Option<ColumnEdge>> = (c0..c1)
        .into_par_iter()
        .with_min_len(32)
        .map_init(|| Vec::with_capacity(w + 3), edge)
        .collect();
    out.extend(edges.into_iter().flatten());
    out
}

/// The flank fit's blur σ (px) from which a column's step may be wider than
/// the fit's window ([`wide_step_sigma`] decides).
pub const WIDE_STEP_SIGMA_PX: f64 = 1.3;

/// Full width at half maximum (rows) of a column's largest step down,
/// `B(z) − B(z + 1)`, from which the band's top counts as blurred beyond
/// the flank fit's window (`half_window` rows above, 2 below): a Gaussian
/// blur of σ = FWHM / 2.355 ≥ 1.7 px, a defocused band top. The windows are
/// then made as wide as the step ([`wide_step_edge`]).
pub const WIDE_STEP_FWHM_ROWS: usize = 4;

/// The blur σ (px) of column `j`'s largest step at `best_row` (`best` its
/// size) when it is wide ([`WIDE_STEP_FWHM_ROWS`]): the rows around it whose
/// steps are at least half of it, counted until one is not (within `rows`).
fn wide_step_sigma(
    bg: &Background,
    j: usize,
    best_row: usize,
    best: f64,
    (r_lo, r_hi): (usize, usize),
) -> Option<f64> {
    let step = |i: usize| bg.at(i, j) as f64 - bg.at(i + 1, j) as f64;
    let half = 0.5 * best;
    let up = (r_lo..best_row)
        .rev()
        .take_while(|&i| step(i) >= half)
        .count();
    let down = (best_row + 1..r_hi.saturating_sub(1))
        .take_while(|&i| step(i) >= half)
        .count();
    let fwhm = 1 + up + down;
    (fwhm >= WIDE_STEP_FWHM_ROWS).then(|| fwhm as f64 / 2.355)
}

/// The band's top in column `j` under a blur wider than the usual windows
/// (σ ≈ `sigma0` px around `best_row`): one blurred step fitted to a window
/// of ±(3σ + 2) rows about its row, the window moved and widened with the
/// fit until it settles (three rounds at most); the area row over the same
/// window. Structure inside the band's top (a strip, a top row) is not
/// resolved under such a blur: the one step is the model.
fn wide_step_edge(
    bg: &Background,
    j: usize,
    best_row: usize,
    sigma0: f64,
    (r_lo, r_hi): (usize, usize),
    params: &SurfaceParams,
) -> Option<ColumnEdge> {
    let (mut e, mut sigma) = (best_row as f64 + 0.5, sigma0);
    let mut window = None;
    for _ in 0..3 {
        let half = (3.0 * sigma + 2.0).ceil().min(24.0) as usize;
        let centre = e.round().max(0.0) as usize;
        let (top, bot) = (centre.checked_sub(half)?, centre + half);
        if top < r_lo || bot + 1 > r_hi {
            return None;
        }
        if window == Some((top, bot)) {
            break;
        }
        let v: Vec<f64> = (top..=bot).map(|i| bg.at(i, j) as f64).collect();
        let (p, _) = fit_one_step(&v, top as f64, e)?;
        let inside = p[0] > top as f64 && p[0] < bot as f64;
        if !(p[0].is_finite() && p[2] > p[3] && inside) {
            return None;
        }
        (e, sigma, window) = (p[0], p[1], Some((top, bot)));
    }
    let (top, bot) = window?;
    let row_area_px = area_row(bg, j, (top, bot), params)?;
    Some(ColumnEdge {
        x_px: j as f64,
        row_px: if params.flank_fits { e } else { row_area_px },
        row_area_px,
    })
}

/// The area (coverage-sum) row of column `j`'s step over rows `top..=bot`:
/// the levels from the window's two end pairs of rows, each row's share of
/// the upper level summed. `None` where the step's contrast is below
/// [`SurfaceParams::min_contrast`].
fn area_row(
    bg: &Background,
    j: usize,
    (top, bot): (usize, usize),
    params: &SurfaceParams,
) -> Option<f64> {
    let hi = 0.5 * (bg.at(top, j) as f64 + bg.at(top + 1, j) as f64);
    let lo = 0.5 * (bg.at(bot, j) as f64 + bg.at(bot - 1, j) as f64);
    if !(hi > 0.0 && (hi - lo) >= params.min_contrast * hi) {
        return None;
    }
    let sum: f64 = (top..=bot)
        .map(|i| (bg.at(i, j) as f64 - lo) / (hi - lo))
        .sum();
    Some(top as f64 - 0.5 + sum)
}

/// A step down of at least this fraction of a column's largest counts as the
/// band's top when it comes first (module doc, step 1). On 8-bit footage a
/// fifth of the band's contrast is still ≥ 10 DN, far above the noise of a
/// background made of tens of frames; a dust speck that passes it moves a
/// few columns, which the line's robust fit rejects.
pub const TOP_STEP_FRACTION: f64 = 0.2;

/// The band's top in column `j`: the first row, going down from `first`, of a
/// step down `B(z) − B(z + 1)` that is a local maximum and at least
/// [`TOP_STEP_FRACTION`] of the column's largest (`largest` at row
/// `largest_row`). The top edge is where the backlight ends: a glossy strip
/// just below it, reflecting the backlight, can make the strip's own lower
/// edge the larger step, and taking the largest would put the line at the
/// strip's bottom, its depth (1–4 px) too low.
fn top_step_row(
    bg: &Background,
    j: usize,
    first: usize,
    largest_row: usize,
    largest: f64,
) -> usize {
    let step = |i: usize| bg.at(i, j) as f64 - bg.at(i + 1, j) as f64;
    let threshold = TOP_STEP_FRACTION * largest;
    (first.max(1)..largest_row)
        .find(|&i| {
            let s = step(i);
            s >= threshold
                && s >= step(i - 1)
                && s >= step(i + 1)
                && separated(s, (i + 1..largest_row).map(step), largest)
        })
        .unwrap_or(largest_row)
}

/// Whether a peak `peak` of the steps is its own, not a ripple on another's
/// flank: the steps between it and the other (`between`) fall below it by
/// at least [`PEAK_PROMINENCE`] of the column's `largest` step. (Under a
/// wide blur the band's one step spreads over many rows, and the
/// background's noise ripples its flank.)
fn separated(peak: f64, between: impl Iterator<Item = f64>, largest: f64) -> bool {
    between.fold(f64::INFINITY, f64::min) <= peak - PEAK_PROMINENCE * largest
}

/// See [`separated`]: ≥ 2 DN on 8-bit footage, many times a background's
/// noise; a glossy strip 3 px deep under σ = 0.8 px gives 0.08.
const PEAK_PROMINENCE: f64 = 0.04;

/// A strip's lower edge counts when its step, up or down, is at least this
/// fraction of the column's largest. A pillar-top row 25 % darker than the
/// band over 1.4 px gives 0.09 of it under a blur of σ = 0.65 px; 0.04 is
/// still ≥ 2 DN on 8-bit footage, above a background's noise. A step that
/// is noise leaves the two-step fit's second step without weight: its row
/// wanders off and the one-step fit is used.
pub const STRIP_STEP_FRACTION: f64 = 0.04;

/// Deepest strip below the band's top that is told from its blur (px).
const STRIP_MAX_PX: usize = 6;

/// The lower edge of a strip just below the band's top at row `top` in
/// column `j`, within [`STRIP_MAX_PX`] rows: the first row where the step
/// `B(z) − B(z + 1)` is, at least [`STRIP_STEP_FRACTION`] of the column's
/// `largest`, either a rise (a strip darker than the band below it: a
/// pillar-top row) at its most negative, or a further drop at a local
/// maximum of its own, separate from the top's (a glossy strip brighter
/// than the band). `None`: no strip is resolved (it may still be there,
/// narrower than the blur).
fn strip_edge_row(bg: &Background, j: usize, top: usize, largest: f64) -> Option<usize> {
    let step = |i: usize| bg.at(i, j) as f64 - bg.at(i + 1, j) as f64;
    let least = STRIP_STEP_FRACTION * largest;
    let last = (top + STRIP_MAX_PX).min(bg.height.saturating_sub(2));
    (top + 1..=last).find(|&i| {
        let (before, s, after) = (step(i - 1), step(i), step(i + 1));
        let rise = s <= -least && s <= before && s <= after;
        let drop = i >= top + 2
            && s >= least
            && s >= before
            && s >= after
            && separated(s, (top + 1..i).map(step), largest);
        rise || drop
    })
}

/// The standard normal density.
fn phi(u: f64) -> f64 {
    (-0.5 * u * u).exp() / (2.0 * std::f64::consts::PI).sqrt()
}

/// The standard normal distribution function.
fn cdf(u: f64) -> f64 {
    0.5 * libm::erfc(-u * std::f64::consts::FRAC_1_SQRT_2)
}

/// `IΦ(u) = uΦ(u) + φ(u)`, the integral of Φ (inlined in [`step_edge_row`]
/// and [`UnitStep`], which share each pixel boundary's value between two
/// samples).
#[cfg(test)]
fn int_cdf(u: f64) -> f64 {
    u * cdf(u) + phi(u)
}

/// Row of a bright-to-dark step from the samples `v[k]` of rows
/// `first_row + k`, by a Levenberg–Marquardt fit of
/// `hi − (hi − lo)·A(z; e, σ)` (module doc, step 2), started at `e0`.
/// `None` when the fit does not end on a step inside the samples.
pub fn step_edge_row(v: &[f64], first_row: f64, e0: f64) -> Option<f64> {
    step_edge_fit(v, first_row, e0).map(|(row, _)| row)
}

/// [`step_edge_row`] with the fitted blur σ (px): `(row, σ)`.
fn step_edge_fit(v: &[f64], first_row: f64, e0: f64) -> Option<(f64, f64)> {
    let n = v.len();
    let (p, _) = fit_one_step(v, first_row, e0)?;
    let inside = p[0] > first_row && p[0] < first_row + n as f64 - 1.0;
    (p[0].is_finite() && p[2] > p[3] && inside).then_some((p[0], p[1]))
}

/// [`step_edge_row`]'s fit: `(e, σ, hi, lo)` where it ended, and its cost
/// (the sum of squared residuals).
fn fit_one_step(v: &[f64], first_row: f64, e0: f64) -> Option<([f64; 4], f64)> {
    let n = v.len();
    if n < 5 {
        return None;
    }
    // The model at every sample, and its gradient in (e, σ, hi, lo). Sample
    // k's upper pixel boundary is sample k + 1's lower one: Φ and φ there
    // are computed once (the same arguments, so the same bits as computing
    // them twice), one erfc and one exp per boundary instead of four each
    // per sample; the fit's cost is in these.
    let model = |p: &[f64; 4], out: &mut Vec<(f64, [f64; 4])>| {
        let (e, s, hi, lo) = (p[0], p[1], p[2], p[3]);
        out.clear();
        let mut prev: Option<(u64, f64, f64)> = None;
        for k in 0..n {
            let z = first_row + k as f64;
            let (up, um) = ((z + 0.5 - e) / s, (z - 0.5 - e) / s);
            let (cm, fm) = match prev {
                Some((u, c, f)) if u == um.to_bits() => (c, f),
                _ => (cdf(um), phi(um)),
            };
            let (cp, fp) = (cdf(up), phi(up));
            prev = Some((up.to_bits(), cp, fp));
            let a = s * ((up * cp + fp) - (um * cm + fm));
            let da_de = -(cp - cm);
            let da_ds = fp - fm;
            let grad = [-(hi - lo) * da_de, -(hi - lo) * da_ds, 1.0 - a, a];
            out.push((hi - (hi - lo) * a, grad));
        }
    };
    // The model at `p` into `at`, and its cost.
    let cost = |p: &[f64; 4], at: &mut Vec<(f64, [f64; 4])>| -> f64 {
        model(p, at);
        at.iter().zip(v).map(|(m, vk)| (m.0 - vk).powi(2)).sum()
    };
    // The model at the current point (an accepted trial's evaluation is
    // the next step's: the same bits as evaluating it again) and at a trial.
    let (mut at_p, mut at_q) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let mut p = [e0, 1.0, v[0].max(v[1]), v[n - 1]];
    let mut c = cost(&p, &mut at_p);
    let mut lambda = 1e-3;
    for _ in 0..60 {
        let mut jtj = [[0.0; 4]; 4];
        let mut jtr = [0.0; 4];
        for (&(m, g), &vk) in at_p.iter().zip(v) {
            let r = m - vk;
            for a in 0..4 {
                jtr[a] += g[a] * r;
                for b in 0..4 {
                    jtj[a][b] += g[a] * g[b];
                }
            }
        }
        let mut improved = false;
        for _ in 0..12 {
            let mut m = jtj;
            for (a, row) in m.iter_mut().enumerate() {
                row[a] += lambda * jtj[a][a].max(1e-12);
            }
            let Some(step) = solve4(m, jtr) else {
                lambda *= 10.0;
                continue;
            };
            let mut q = p;
            for a in 0..4 {
                q[a] -= step[a];
            }
            q[1] = q[1].clamp(SIGMA_BOUNDS_PX.0, SIGMA_BOUNDS_PX.1);
            let cq = cost(&q, &mut at_q);
            if cq.is_finite() && cq <= c {
                improved = c - cq > 1e-14 * (1.0 + c);
                p = q;
                c = cq;
                std::mem::swap(&mut at_p, &mut at_q);
                lambda = (lambda * 0.3).max(1e-9);
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    Some((p, c))
}

/// The pixel-averaged blurred unit step `A(z; e, σ)` (module doc, step 2)
/// at the rows `first_row + k` of `n` samples, and its derivatives
/// `∂A/∂e = −(Φ(u₊) − Φ(u₋))` and `∂A/∂σ = φ(u₊) − φ(u₋)`, `u± = (z ± ½ −
/// e)/σ`, from Φ and φ at the `n + 1` pixel boundaries: row k's upper
/// boundary is row k + 1's lower one (the same number for integer rows),
/// so each is computed once.
#[derive(Debug, Default)]
struct UnitStep {
    a: Vec<f64>,
    da_de: Vec<f64>,
    da_ds: Vec<f64>,
}

impl UnitStep {
    fn set(&mut self, n: usize, first_row: f64, e: f64, s: f64) {
        self.a.clear();
        self.da_de.clear();
        self.da_ds.clear();
        let mut prev = (0.0, 0.0, 0.0);
        for k in 0..=n {
            let u = (first_row + k as f64 - 0.5 - e) / s;
            let (c, f) = (cdf(u), phi(u));
            let int = u * c + f;
            if k > 0 {
                self.a.push(s * (int - prev.2));
                self.da_de.push(-(c - prev.0));
                self.da_ds.push(f - prev.1);
            }
            prev = (c, f, int);
        }
    }
}

/// The levels `(c₀, c₁, c₂)` of `c₀ + c₁·a₁ + c₂·a₂` fitted to `v` by their
/// normal equations (3 × 3, Cholesky), that Cholesky, and the residuals
/// (model − data); `None` where the two steps' columns are too alike to
/// tell apart.
fn two_step_levels(
    a1: &[f64],
    a2: &[f64],
    v: &[f64],
    resid: &mut Vec<f64>,
) -> Option<(
    nalgebra::Cholesky<f64, nalgebra::U3>,
    nalgebra::Vector3<f64>,
)> {
    use nalgebra::{Matrix3, Vector3};
    let (mut ata, mut aty) = (Matrix3::zeros(), Vector3::zeros());
    for ((&p, &q), &y) in a1.iter().zip(a2).zip(v) {
        let row = Vector3::new(1.0, p, q);
        ata += row * row.transpose();
        aty += row * y;
    }
    let chol = ata.cholesky()?;
    let levels = chol.solve(&aty);
    resid.clear();
    resid.extend(
        a1.iter()
            .zip(a2)
            .zip(v)
            .map(|((&p, &q), &y)| levels[0] + levels[1] * p + levels[2] * q - y),
    );
    Some((chol, levels))
}

/// Row of the upper of two bright-to-dark steps blurred alike, from the
/// samples `v[k]` of rows `first_row + k`: a strip of its own level between
/// the band's top and a larger step below it (module doc, step 2). The model
/// is `c₀ + c₁·A(z; e₁, σ) + c₂·A(z; e₂, σ)`; the levels `c` are solved
/// linearly for each `θ = (e₁, e₂, σ)` (variable projection), which a small
/// Levenberg–Marquardt fits from `e0` with the projected residual's exact
/// Jacobian (Golub and Pereyra's), from the steps' analytic derivatives.
/// `None` when the fit does not end on two ordered steps inside the
/// samples (the model is symmetric in its steps, and a fit can end with
/// them swapped: then the caller's one-step fit is used — taking the
/// swapped fit's upper step instead moves one of 120 real-preset drops'
/// δmax from 8e-4 to 7e-3 off by hiding its band top's disagreement).
/// `None` too when the strip is not told from noise: the two-step model must explain the samples better than one
/// step does on the same rows by more than its two further parameters
/// would by chance ([`strip_is_resolved`]); else noise below the top makes
/// the strip search try columns with none, and the two-step fit splits
/// their one blurred step into two sharper ones and returns the upper, up
/// to 0.4 px above the edge. The fit is given up (`None`) as soon as it has
/// settled above the cost the F-test needs ([`TwoStepFit::gave_up`]): most
/// strips the search tries are not there, and running their fits to the
/// last digit, only to reject them, was most of the surface line's cost.
/// `first_row` is a row number (an integer).
pub fn two_step_edge_row(v: &[f64], first_row: f64, e0: [f64; 2]) -> Option<f64> {
    two_step_edge_fit(v, first_row, e0).map(|(row, _)| row)
}

/// [`two_step_edge_row`] with the fitted blur σ (px): `(row, σ)`.
fn two_step_edge_fit(v: &[f64], first_row: f64, e0: [f64; 2]) -> Option<(f64, f64)> {
    let n = v.len();
    // The one-step fit on the same rows, fitted when first needed: by the
    // test, or by the two-step fit once it has settled.
    let mut cost_one = None;
    let mut one = || {
        *cost_one.get_or_insert_with(|| {
            fit_one_step(v, first_row, e0[0]).map_or(f64::INFINITY, |(_, c)| c)
        })
    };
    let fit = fit_two_steps(v, first_row, e0, &mut || strip_cost_limit(one(), n))?;
    let th = fit.th;
    let inside = |e: f64| e > first_row && e < first_row + n as f64 - 1.0;
    let ordered =
        th.iter().all(|x| x.is_finite()) && th[0] < th[1] && inside(th[0]) && inside(th[1]);
    if fit.gave_up || !ordered {
        return None;
    }
    strip_is_resolved(one(), fit.cost, n).then_some((th[0], th[2]))
}

/// Chance, at most, that noise alone lets the two-step model's two further
/// parameters (the second step's row and level) lower the cost as much as
/// a strip taken for real: the F-test's level.
const STRIP_TEST_LEVEL: f64 = 0.01;

/// Whether two steps (6 parameters) fit `n` samples significantly better
/// than one (4): the F statistic `((c₁ − c₂)/2) / (c₂/(n − 6))` above its
/// `1 − STRIP_TEST_LEVEL` quantile, which for 2 degrees of freedom in the
/// numerator is closed-form: `P(F > f) = (1 + 2f/d)^(−d/2)`, `d = n − 6`.
fn strip_is_resolved(cost_one: f64, cost_two: f64, n: usize) -> bool {
    if n <= 6 || !(cost_two <= cost_one) {
        return false;
    }
    let d = (n - 6) as f64;
    // `cost_two` = 0 (a noiseless profile the model fits exactly): resolved.
    (cost_one - cost_two) * d > 2.0 * strip_f_crit(d) * cost_two
}

/// The F-test's critical value for `d` = n − 6 degrees of freedom in the
/// denominator ([`strip_is_resolved`]).
fn strip_f_crit(d: f64) -> f64 {
    0.5 * d * (STRIP_TEST_LEVEL.powf(-2.0 / d) - 1.0)
}

/// The two-step cost above which [`strip_is_resolved`] rejects the strip,
/// for the one-step cost `cost_one` on the same `n` samples: the test
/// holds for `c₂ < c₁·d/(d + 2f)`. `−∞` where it never holds (`n ≤ 6`).
fn strip_cost_limit(cost_one: f64, n: usize) -> f64 {
    if n <= 6 {
        return f64::NEG_INFINITY;
    }
    let d = (n - 6) as f64;
    cost_one * d / (d + 2.0 * strip_f_crit(d))
}

/// A Levenberg–Marquardt step that lowers the cost by at most this fraction
/// of it, σ off its bounds, has settled the fit: what it falls after that
/// is far less than its way down to the F-test's limit. Measured, by
/// replaying the logged iterations of every two-step fit on the e2e
/// campaign and the 60 real-preset drops (seed 7): of the 6 220 strips the
/// F-test kept there, none is given up with it (at 1e-4, 3 were).
const SETTLED_FRACTION: f64 = 1e-5;

/// The blur σ's range in the step fits (px).
const SIGMA_BOUNDS_PX: (f64, f64) = (0.2, 6.0);

/// Where [`fit_two_steps`] ended.
#[derive(Debug, Clone, Copy)]
struct TwoStepFit {
    /// `θ = (e₁, e₂, σ)`.
    th: nalgebra::Vector3<f64>,
    /// The sum of squared residuals at `th`.
    cost: f64,
    /// Levenberg–Marquardt iterations (at most 60; read by the tests).
    #[cfg_attr(not(test), allow(dead_code))]
    iterations: usize,
    /// Stopped once settled above the cost limit it was given: a strip the
    /// F-test would reject (`th` and `cost` are where it stopped).
    gave_up: bool,
}

/// [`two_step_edge_row`]'s fit, to its minimum; or given up where a step
/// has settled it ([`SETTLED_FRACTION`]) at a cost above `cost_limit()`
/// (called then, at most once), σ 5 % or more inside its bounds: a fit
/// whose σ lies on a bound creeps along it under heavy damping, its steps
/// small, and can still fall far (on a real-preset drop from 264 to 4 in
/// ten steps). `&mut || f64::INFINITY`: never given up.
fn fit_two_steps(
    v: &[f64],
    first_row: f64,
    e0: [f64; 2],
    cost_limit: &mut dyn FnMut() -> f64,
) -> Option<TwoStepFit> {
    use nalgebra::{Matrix3, Vector3};
    let n = v.len();
    if n < 8 {
        return None;
    }
    debug_assert_eq!(first_row.fract(), 0.0, "a row number");
    let cost = |r: &[f64]| r.iter().map(|x| x * x).sum::<f64>();
    // The steps, levels and residuals at the current θ, and at a trial.
    let (mut s1, mut s2) = (UnitStep::default(), UnitStep::default());
    let (mut t1, mut t2) = (UnitStep::default(), UnitStep::default());
    let (mut r, mut rq) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let mut th = Vector3::new(e0[0], e0[1], 1.0);
    s1.set(n, first_row, th[0], th[2]);
    s2.set(n, first_row, th[1], th[2]);
    let (mut chol, mut levels) = two_step_levels(&s1.a, &s2.a, v, &mut r)?;
    let mut c = cost(&r);
    let mut lambda = 1e-3;
    let mut jac = Vec::with_capacity(n);
    let mut iterations = 0;
    while iterations < 60 {
        iterations += 1;
        two_step_jacobian([&s1, &s2], &levels, &chol, &r, &mut jac);
        let (mut jtj, mut jtr) = (Matrix3::zeros(), Vector3::zeros());
        for (jk, &rk) in jac.iter().zip(&r) {
            jtj += jk * jk.transpose();
            jtr += jk * rk;
        }
        let (mut improved, mut settled) = (false, false);
        for _ in 0..12 {
            let mut m = jtj;
            for a in 0..3 {
                m[(a, a)] += lambda * jtj[(a, a)].max(1e-12);
            }
            let Some(step) = m.lu().solve(&jtr) else {
                lambda *= 10.0;
                continue;
            };
            let mut q = th - step;
            q[2] = q[2].clamp(SIGMA_BOUNDS_PX.0, SIGMA_BOUNDS_PX.1);
            t1.set(n, first_row, q[0], q[2]);
            t2.set(n, first_row, q[1], q[2]);
            let trial =
                two_step_levels(&t1.a, &t2.a, v, &mut rq).map(|(ch, lv)| (ch, lv, cost(&rq)));
            match trial {
                Some((chol_q, levels_q, cq)) if cq <= c => {
                    improved = c - cq > 1e-14 * (1.0 + c);
                    settled = c - cq <= SETTLED_FRACTION * cq
                        && q[2] > 1.05 * SIGMA_BOUNDS_PX.0
                        && q[2] < 0.95 * SIGMA_BOUNDS_PX.1;
                    (th, c, chol, levels) = (q, cq, chol_q, levels_q);
                    std::mem::swap(&mut r, &mut rq);
                    std::mem::swap(&mut s1, &mut t1);
                    std::mem::swap(&mut s2, &mut t2);
                    lambda = (lambda * 0.3).max(1e-9);
                    break;
                }
                _ => lambda *= 10.0,
            }
        }
        if !improved {
            break;
        }
        if settled && c > cost_limit() {
            return Some(TwoStepFit {
                th,
                cost: c,
                iterations,
                gave_up: true,
            });
        }
    }
    Some(TwoStepFit {
        th,
        cost: c,
        iterations,
        gave_up: false,
    })
}

/// The Jacobian of the projected residual `r(θ) = A c(θ) − v`, `c(θ) =
/// (AᵀA)⁻¹Aᵀv`, of the two-step model (Golub and Pereyra's variable
/// projection), one row per sample into `out`: differentiating the normal
/// equations gives `∂c = −(AᵀA)⁻¹(Aᵀ G + W)`, so that
/// `∂r/∂θ = G − A(AᵀA)⁻¹(AᵀG + W)`, with `G = (∂A/∂θ) c` the model's
/// derivative at fixed levels and `W`'s columns `(∂A/∂θ)ᵀ r`; row k is
/// `gₖ − (AᵀG + W)ᵀ(AᵀA)⁻¹ bₖ`, `bₖ = (1, a₁ₖ, a₂ₖ)`. (The noiseless
/// tests cannot see `W`'s sign, since `r` is 0 there: with it flipped the
/// Jacobian is off by O(r), and on the 60 real-preset drops the surface
/// line moves by up to 0.0004 px.)
fn two_step_jacobian(
    [s1, s2]: [&UnitStep; 2],
    levels: &nalgebra::Vector3<f64>,
    chol: &nalgebra::Cholesky<f64, nalgebra::U3>,
    r: &[f64],
    out: &mut Vec<nalgebra::Vector3<f64>>,
) {
    use nalgebra::{Matrix3, Vector3};
    out.clear();
    let (mut atg, mut w) = (Matrix3::zeros(), Matrix3::zeros());
    for (k, &rk) in r.iter().enumerate() {
        let gk = Vector3::new(
            levels[1] * s1.da_de[k],
            levels[2] * s2.da_de[k],
            levels[1] * s1.da_ds[k] + levels[2] * s2.da_ds[k],
        );
        atg += Vector3::new(1.0, s1.a[k], s2.a[k]) * gk.transpose();
        w[(1, 0)] += s1.da_de[k] * rk;
        w[(2, 1)] += s2.da_de[k] * rk;
        w[(1, 2)] += s1.da_ds[k] * rk;
        w[(2, 2)] += s2.da_ds[k] * rk;
        out.push(gk);
    }
    let mix = chol.solve(&(atg + w)).transpose();
    for (k, jk) in out.iter_mut().enumerate() {
        *jk -= mix * Vector3::new(1.0, s1.a[k], s2.a[k]);
    }
}

/// Solve the 4×4 system `m·x = b` (LU with partial pivoting).
fn solve4(m: [[f64; 4]; 4], b: [f64; 4]) -> Option<[f64; 4]> {
    let x = nalgebra::Matrix4::from_fn(|i, j| m[i][j])
        .lu()
        .solve(&nalgebra::Vector4::from(b))?;
    x.iter()
        .all(|v| v.is_finite())
        .then(|| [x[0], x[1], x[2], x[3]])
}

/// Disagreement (px) between the flank fit and the area method beyond which
/// the band's top counts as structured and the flank fit's line is used.
/// Below it the area method's is: it is exact for any blur kernel and any
/// step height, where the flank fit assumes a Gaussian blur and flat levels
/// over its short window. On clean band tops the flank fit alone is off by
/// up to 0.053 px (120 `realistic` renders; the area row within 0.008 px),
/// so a smaller disagreement is no evidence of structure; a glossy strip or
/// a row of pillar tops moves the two 0.06–0.5 px apart (independent
/// renders: the flank fit within 0.06 px of the truth there, the area row
/// up to 0.19 px off).
pub const STRUCTURED_TOP_PX: f64 = 0.06;

/// The area row's systematic error (px) on a clean band top: 0.003 px
/// root-mean-square off the truth on 60 `realistic` renders (within
/// 0.008 px), up to 0.007 px on `harsh` ones.
pub const AREA_SYSTEMATIC_PX: f64 = 0.005;

/// The flank fit's systematic error (px) on a structured band top, at
/// least: within 0.06 px of the truth on the independent renders (median
/// 0.043 px), where its disagreement with the area row was 0.06–0.26 px.
pub const FLANK_SYSTEMATIC_PX: f64 = 0.04;

impl SurfaceLine {
    /// The systematic error (px) of the edge model this line was taken
    /// with: [`AREA_SYSTEMATIC_PX`] for a clean top (the area row), and for
    /// a structured one (the flank fit) half the two models' disagreement,
    /// at least [`FLANK_SYSTEMATIC_PX`]. 0 for a line given.
    pub fn edge_model_sigma_px(&self) -> f64 {
        if self.n_used == 0 {
            0.0
        } else if self.model_err_px < STRUCTURED_TOP_PX {
            AREA_SYSTEMATIC_PX
        } else {
            (0.5 * self.model_err_px).max(FLANK_SYSTEMATIC_PX)
        }
    }
}

/// The surface line from the background image (see the module doc), with
/// its edge-model error.
pub fn fit_surface(bg: &Background, params: &SurfaceParams) -> Result<SurfaceLine, DetectError> {
    let edges = column_edges(bg, params);
    let pts: Vec<(f64, f64)> = edges.iter().map(|e| (e.x_px, e.row_px)).collect();
    let flank = fit_line(&pts, params)?;
    let mut diff: Vec<f64> = edges
        .iter()
        .filter(|e| (e.row_px - flank.row_at(e.x_px)).abs() < 1.0)
        .map(|e| e.row_px - e.row_area_px)
        .collect();
    let model_err_px = if diff.is_empty() {
        0.0
    } else {
        median(&mut diff).abs()
    };
    let (mut line, pts) = if model_err_px < STRUCTURED_TOP_PX {
        let pts: Vec<(f64, f64)> = edges.iter().map(|e| (e.x_px, e.row_area_px)).collect();
        (fit_line(&pts, params)?, pts)
    } else {
        (flank, pts)
    };
    line.model_err_px = model_err_px;
    if let Some((c, c_err)) = bow(&pts, &line, params) {
        line.bow_per_px2 = c;
        line.bow_err_per_px2 = c_err;
    }
    Ok(line)
}

/// Columns per block in [`bow`]: neighbouring columns' edges share their
/// errors (the blur, a pillar's face), so the bow is fitted to block means,
/// whose scatter gives an honest error.
const BOW_BLOCK_COLUMNS: f64 = 16.0;

/// The bow `c` of `row = a + b·x + c·x²` by least squares over the column
/// edges within 4 of the line's residual scales of it (the robust line's
/// inliers), averaged in blocks of [`BOW_BLOCK_COLUMNS`], with its standard
/// error from the blocks' scatter: `(c, σ_c)`. `None` with fewer than 8
/// blocks.
fn bow(pts: &[(f64, f64)], line: &SurfaceLine, params: &SurfaceParams) -> Option<(f64, f64)> {
    let scale = line.residual_px.max(params.min_scale_px);
    let kept = pts
        .iter()
        .copied()
        .filter(|&(x, z)| (z - line.row_at(x)).abs() <= 4.0 * scale);
    let mut blocks: std::collections::BTreeMap<i64, (f64, f64, f64)> = Default::default();
    for (x, z) in kept {
        let b = blocks
            .entry((x / BOW_BLOCK_COLUMNS).floor() as i64)
            .or_insert((0.0, 0.0, 0.0));
        *b = (b.0 + x, b.1 + z, b.2 + 1.0);
    }
    let means: Vec<(f64, f64)> = blocks
        .values()
        .filter(|b| b.2 >= 0.5 * BOW_BLOCK_COLUMNS)
        .map(|b| (b.0 / b.2, b.1 / b.2))
        .collect();
    if means.len() < 8 {
        return None;
    }
    let mid = means.iter().map(|p| p.0).sum::<f64>() / means.len() as f64;
    let half = means
        .iter()
        .map(|p| (p.0 - mid).abs())
        .fold(0.0, f64::max)
        .max(1.0);
    // In u = (x − mid)/half, for conditioning.
    let mut ata = nalgebra::Matrix3::<f64>::zeros();
    let mut atz = nalgebra::Vector3::<f64>::zeros();
    for &(x, z) in &means {
        let u = (x - mid) / half;
        let row = nalgebra::Vector3::new(1.0, u, u * u);
        ata += row * row.transpose();
        atz += row * z;
    }
    let inv = ata.try_inverse()?;
    let coef = inv * atz;
    let ss: f64 = means
        .iter()
        .map(|&(x, z)| {
            let u = (x - mid) / half;
            (z - coef[0] - coef[1] * u - coef[2] * u * u).powi(2)
        })
        .sum();
    let s2 = ss / (means.len() - 3) as f64;
    let c = coef[2] / (half * half);
    let c_err = (s2 * inv[(2, 2)]).max(0.0).sqrt() / (half * half);
    (c.is_finite() && c_err.is_finite()).then_some((c, c_err))
}

fn median(v: &mut [f64]) -> f64 {
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Robust line `z = a + b x` through `(x, z)` points (steps 3 of the module doc).
pub fn fit_line(pts: &[(f64, f64)], params: &SurfaceParams) -> Result<SurfaceLine, DetectError> {
    const WHAT: &str = "surface line";
    let n = pts.len();
    if n < 4 {
        return Err(DetectError::TooFewPoints {
            what: WHAT,
            found: n,
            needed: 4,
        });
    }
    let half = n / 2;
    let mut slopes: Vec<f64> = (0..n - half)
        .filter_map(|i| {
            let (p, q) = (pts[i], pts[i + half]);
            (q.0 != p.0).then(|| (q.1 - p.1) / (q.0 - p.0))
        })
        .collect();
    if slopes.is_empty() {
        return Err(DetectError::Degenerate {
            what: WHAT,
            reason: "all points in one column".into(),
        });
    }
    let mut b = median(&mut slopes);
    let mut resid: Vec<f64> = pts.iter().map(|p| p.1 - b * p.0).collect();
    let mut a = median(&mut resid);
    let mut weights = vec![0.0; n];
    let mut abs_r = vec![0.0; n];
    let mut result = None;
    for _ in 0..50 {
        for (k, p) in pts.iter().enumerate() {
            abs_r[k] = (p.1 - a - b * p.0).abs();
        }
        let mut tmp = abs_r.clone();
        let s = (1.4826 * median(&mut tmp)).max(params.min_scale_px);
        for k in 0..n {
            let u = abs_r[k] / (params.tukey_c * s);
            weights[k] = if u < 1.0 { (1.0 - u * u).powi(2) } else { 0.0 };
        }
        let (mut sw, mut sx, mut sz, mut sxx, mut sxz) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (p, &w) in pts.iter().zip(&weights) {
            sw += w;
            sx += w * p.0;
            sz += w * p.1;
            sxx += w * p.0 * p.0;
            sxz += w * p.0 * p.1;
        }
        let det = sw * sxx - sx * sx;
        if !(det > 0.0) {
            return Err(DetectError::Degenerate {
                what: WHAT,
                reason: "fewer than two distinct columns kept".into(),
            });
        }
        let nb = (sw * sxz - sx * sz) / det;
        let na = (sz - nb * sx) / sw;
        let moved = (na - a).abs() + (nb - b).abs() * 100.0;
        a = na;
        b = nb;
        // Covariance of (a, b): σ̂² (XᵀWX)⁻¹.
        let ss: f64 = pts
            .iter()
            .zip(&weights)
            .map(|(p, &w)| w * (p.1 - a - b * p.0).powi(2))
            .sum();
        let s2 = ss / (sw - 2.0).max(1.0);
        let cov = [
            [s2 * sxx / det, -s2 * sx / det],
            [-s2 * sx / det, s2 * sw / det],
        ];
        let used = weights.iter().filter(|&&w| w > 0.0).count();
        let rms = {
            let (s, c) = pts
                .iter()
                .zip(&weights)
                .filter(|(_, &w)| w > 0.0)
                .fold((0.0, 0usize), |(s, c), (p, _)| {
                    (s + (p.1 - a - b * p.0).powi(2), c + 1)
                });
            (s / c.max(1) as f64).sqrt()
        };
        result = Some(SurfaceLine {
            row0_px: a,
            slope: b,
            cov,
            residual_px: rms,
            n_used: used,
            model_err_px: 0.0,
            bow_per_px2: 0.0,
            bow_err_per_px2: 0.0,
        });
        if moved < 1e-10 {
            break;
        }
    }
    result.ok_or(DetectError::Degenerate {
        what: WHAT,
        reason: "no iteration".into(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pixel-averaged values of a Gaussian-blurred profile made of levels
    /// `levels[k]` on `[bounds[k], bounds[k + 1])` (rows grow down).
    #[test]
    fn two_clean_blurred_steps_are_found_exactly_at_any_phase_width_and_blur() {
        // A strip of its own level (brighter or darker) under the band's
        // top: the model is exact, so the fit must end on both edges to
        // rounding from a start up to half a pixel off, whatever the strip's
        // width (1.5–4 px, at least twice the blur's σ: a narrower one is
        // a valley the fit need not resolve) and level, or its Jacobian is
        // wrong.
        let (mut cases, mut swapped) = (0, 0);
        for &sigma in &[0.5, 0.75, 1.4] {
            for &(width, strip) in &[(1.5, 0.45), (2.5, 0.2), (4.0, 0.6)] {
                if width < 2.0 * sigma {
                    continue;
                }
                cases += 5;
                for k in 0..5 {
                    let e1 = 20.0 + k as f64 / 5.0;
                    let e2 = e1 + width;
                    let v = blurred(&[-1e3, e1, e2, 1e3], &[0.75, strip, 0.3], sigma, 40);
                    let first = 14usize;
                    let window = &v[first..(e2 as usize + 4)];
                    let start = [e1.floor() + 0.5, e2.floor() + 0.5];
                    // (`None`: the fit ended with its steps swapped.)
                    let Some(row) = two_step_edge_row(window, first as f64, start) else {
                        swapped += 1;
                        continue;
                    };
                    assert!(
                        (row - e1).abs() < 1e-6,
                        "σ {sigma} w {width} e₁ {e1}: {row}"
                    );
                }
            }
        }
        assert!(swapped * 10 <= cases, "{swapped} of {cases} swapped");
    }

    /// A glossy strip under the band's top, 8-bit-like levels, with
    /// Gaussian noise of `noise` DN (seeded): the fits' real case, where the
    /// residual at the minimum is not zero.
    fn noisy_two_steps(e1: f64, width: f64, sigma: f64, noise: f64, seed: u64) -> Vec<f64> {
        use rand::SeedableRng;
        use rand_distr::Distribution;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let normal = rand_distr::Normal::new(0.0, noise).unwrap();
        blurred(
            &[-1e3, e1, e1 + width, 1e3],
            &[190.0, 120.0, 60.0],
            sigma,
            40,
        )
        .into_iter()
        .map(|x| x + normal.sample(&mut rng))
        .collect()
    }

    /// The two-step model of `window` (rows from `first`) at `θ = (e₁, e₂,
    /// σ)`: its steps, the levels' Cholesky, the levels and the residuals.
    fn two_steps_at(
        window: &[f64],
        first: usize,
        th: [f64; 3],
    ) -> (
        UnitStep,
        UnitStep,
        nalgebra::Cholesky<f64, nalgebra::U3>,
        nalgebra::Vector3<f64>,
        Vec<f64>,
    ) {
        let n = window.len();
        let (mut s1, mut s2) = (UnitStep::default(), UnitStep::default());
        s1.set(n, first as f64, th[0], th[2]);
        s2.set(n, first as f64, th[1], th[2]);
        let mut r = Vec::new();
        let (chol, levels) = two_step_levels(&s1.a, &s2.a, window, &mut r).unwrap();
        (s1, s2, chol, levels, r)
    }

    #[test]
    fn the_two_step_jacobian_is_the_derivative_of_the_projected_residual() {
        // Central differences of r(θ) = A c(θ) − v against the analytic
        // rows, off the minimum on a noisy profile (at a noiseless one's
        // minimum r = 0 and the second-order term W vanishes: the clean
        // tests cannot see its sign).
        let first = 14usize;
        let v = noisy_two_steps(20.3, 2.5, 0.8, 3.0, 7);
        let window = &v[first..28];
        let n = window.len();
        let residual = |th: [f64; 3]| two_steps_at(window, first, th);
        let th = [20.6, 22.5, 1.1];
        let (s1, s2, chol, levels, r) = residual(th);
        let mut jac = Vec::new();
        two_step_jacobian([&s1, &s2], &levels, &chol, &r, &mut jac);
        let h = 1e-5;
        let mut largest: f64 = 0.0;
        let mut worst: f64 = 0.0;
        for j in 0..3 {
            let (mut up, mut down) = (th, th);
            up[j] += h;
            down[j] -= h;
            let (ru, rd) = (residual(up).4, residual(down).4);
            for k in 0..n {
                let fd = (ru[k] - rd[k]) / (2.0 * h);
                largest = largest.max(fd.abs());
                worst = worst.max((jac[k][j] - fd).abs());
            }
        }
        assert!(largest > 1.0, "a Jacobian to compare: {largest}");
        assert!(worst < 1e-6 * largest, "off by {worst} of {largest}");
    }

    /// A profile, the two-step fit's start and the end of its window.
    type ProfileCase = (Vec<f64>, [f64; 2], usize);

    /// Case `seed` of the strip tests: the top's true row, and two profiles
    /// with 1.5 DN of noise, each with the two-step fit's start and the end
    /// of its window (rows from 14): one blurred step started as if a strip
    /// ended two rows below it (what the strip search finds in noise), and
    /// a strip 3 px deep.
    fn step_and_strip(seed: u64) -> (f64, [ProfileCase; 2]) {
        use rand::SeedableRng;
        use rand_distr::Distribution;
        let e1 = 20.0 + (seed % 5) as f64 / 5.0;
        let sigma = 0.6 + 0.1 * (seed % 4) as f64;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let normal = rand_distr::Normal::new(0.0, 1.5).unwrap();
        let one = blurred(&[-1e3, e1, 1e3], &[190.0, 60.0], sigma, 40)
            .into_iter()
            .map(|x| x + normal.sample(&mut rng))
            .collect();
        let strip = noisy_two_steps(e1, 3.0, sigma, 1.5, seed);
        (
            e1,
            [
                (one, [e1.floor() + 0.5, e1.floor() + 2.5], e1 as usize + 6),
                (
                    strip,
                    [e1.floor() + 0.5, (e1 + 3.0).floor() + 0.5],
                    e1 as usize + 7,
                ),
            ],
        )
    }

    #[test]
    fn a_single_noisy_step_is_not_taken_for_a_strip() {
        // The two-step model splits a single noisy step in two, and its
        // upper row is up to 0.4 px off; the F-test sends it to the
        // caller's one-step fit (`None`). A real strip under the same
        // noise is kept, its top row within the noise's reach.
        let first = 14usize;
        let (mut single, mut strips) = (0, 0);
        for seed in 0..40u64 {
            let (e1, [(one, start, end), (strip, strip_start, strip_end)]) = step_and_strip(seed);
            if two_step_edge_row(&one[first..end], first as f64, start).is_none() {
                single += 1;
            }
            let window = &strip[first..strip_end];
            if let Some(row) = two_step_edge_row(window, first as f64, strip_start) {
                assert!((row - e1).abs() < 0.25, "seed {seed}: {row} for {e1}");
                strips += 1;
            }
        }
        // At the test's 1 % level, about 0.4 of 40 single steps pass.
        assert!(
            single >= 38,
            "{} of 40 single steps taken for strips",
            40 - single
        );
        assert_eq!(strips, 40, "strips kept");
    }

    #[test]
    fn a_two_step_fit_is_given_up_only_where_the_f_test_rejects_it() {
        // The strip tests' profiles, each fitted to its minimum and with the
        // give-up: a fit given up is one the F-test rejects at its minimum
        // (the noisy single steps), a fit not given up ends on the same
        // bits, and no strip is given up. The single steps' fits are given
        // up, in fewer iterations.
        let first = 14usize;
        let (mut given_up, mut strips_given_up) = (0, 0);
        let (mut iterations_full, mut iterations_given_up) = (0, 0);
        for seed in 0..40u64 {
            let (_, cases) = step_and_strip(seed);
            for (k, (v, start, end)) in cases.into_iter().enumerate() {
                let window = &v[first..end];
                let n = window.len();
                let full =
                    fit_two_steps(window, first as f64, start, &mut || f64::INFINITY).unwrap();
                assert!(!full.gave_up);
                let cost_one = fit_one_step(window, first as f64, start[0]).unwrap().1;
                let limit = strip_cost_limit(cost_one, n);
                let early = fit_two_steps(window, first as f64, start, &mut || limit).unwrap();
                if early.gave_up {
                    given_up += 1;
                    strips_given_up += k;
                    iterations_full += full.iterations;
                    iterations_given_up += early.iterations;
                    assert!(
                        !strip_is_resolved(cost_one, full.cost, n),
                        "seed {seed}: a fit the F-test keeps was given up"
                    );
                    assert!(early.cost > limit && early.cost >= full.cost);
                } else {
                    let bits = |f: &TwoStepFit| (f.th.map(f64::to_bits), f.cost.to_bits());
                    assert_eq!(bits(&early), bits(&full), "seed {seed}");
                }
            }
        }
        assert_eq!(strips_given_up, 0, "strips given up");
        assert!(given_up >= 35, "{given_up} of 40 single steps given up");
        assert!(
            2 * iterations_given_up < iterations_full,
            "{iterations_given_up} iterations given up against {iterations_full} to the minimum"
        );
    }

    #[test]
    fn noisy_two_step_profiles_are_fitted_to_their_minimum() {
        // From half a pixel off, the fit ends before its limit of 60
        // iterations (7–18 here) where no small move of either edge or of
        // σ lowers the cost.
        let first = 14usize;
        let mut most = 0;
        for seed in 0..40u64 {
            let (e1, width, sigma) = (
                20.0 + (seed % 5) as f64 / 5.0,
                2.0 + (seed % 3) as f64,
                0.6 + 0.2 * (seed % 4) as f64,
            );
            let v = noisy_two_steps(e1, width, sigma, 2.0, seed);
            let window = &v[first..(e1 + width) as usize + 4];
            let start = [e1.floor() + 0.5, (e1 + width).floor() + 0.5];
            let TwoStepFit { th, iterations, .. } =
                fit_two_steps(window, first as f64, start, &mut || f64::INFINITY).unwrap();
            most = most.max(iterations);
            let cost = |th: [f64; 3]| {
                two_steps_at(window, first, th)
                    .4
                    .iter()
                    .map(|x| x * x)
                    .sum::<f64>()
            };
            let at = [th[0], th[1], th[2]];
            let c = cost(at);
            for j in 0..3 {
                for d in [-1e-4, 1e-4] {
                    let mut moved = at;
                    moved[j] += d;
                    if j == 2 && !(0.2..=6.0).contains(&moved[2]) {
                        continue;
                    }
                    assert!(
                        cost(moved) >= c * (1.0 - 1e-12),
                        "seed {seed}: θ {at:?} is not a minimum along {j}"
                    );
                }
            }
        }
        assert!(most < 60, "{most} iterations");
    }

    fn blurred(bounds: &[f64], levels: &[f64], sigma: f64, rows: usize) -> Vec<f64> {
        // Mean over the pixel of the blurred indicator of [a, b).
        let piece = |a: f64, b: f64, z: f64| {
            let f = |u: f64| sigma * (int_cdf((u - a) / sigma) - int_cdf((u - b) / sigma));
            f(z + 0.5) - f(z - 0.5)
        };
        (0..rows)
            .map(|i| {
                (0..levels.len())
                    .map(|k| levels[k] * piece(bounds[k], bounds[k + 1], i as f64))
                    .sum()
            })
            .collect()
    }

    fn both_rows(v: &[f64]) -> (f64, f64) {
        // The largest step, then the same windows as `column_edges` (w = 5).
        let zs = (0..v.len() - 1)
            .max_by(|&a, &b| (v[a] - v[a + 1]).total_cmp(&(v[b] - v[b + 1])))
            .unwrap();
        let (top, bot) = (zs - 5, zs + 6);
        let hi = 0.5 * (v[top] + v[top + 1]);
        let lo = 0.5 * (v[bot] + v[bot - 1]);
        let area = top as f64 - 0.5 + (top..=bot).map(|i| (v[i] - lo) / (hi - lo)).sum::<f64>();
        let step = step_edge_row(&v[top..=zs + 2], top as f64, zs as f64 + 0.5).unwrap();
        (step, area)
    }

    #[test]
    fn a_clean_blurred_step_is_found_exactly_at_any_phase_and_blur() {
        // The model is exact for this profile, so only rounding remains.
        for &sigma in &[0.3, 0.6, 1.2, 2.5] {
            for k in 0..10 {
                let e = 20.0 + k as f64 / 10.0;
                let v = blurred(&[-1e3, e, 1e3], &[0.75, 0.34], sigma, 40);
                let (step, area) = both_rows(&v);
                assert!((step - e).abs() < 1e-6, "σ {sigma} e {e}: {step}");
                // The area method agrees on a clean step (its window holds ±3σ).
                if sigma <= 1.2 {
                    assert!((area - e).abs() < 2e-3, "σ {sigma} e {e}: {area}");
                }
            }
        }
    }

    /// A background whose every column is `profile` (rows grow down).
    fn background_of(profile: &[f64], width: usize) -> Background {
        let levels = profile
            .iter()
            .flat_map(|&v| std::iter::repeat_n(v as f32, width))
            .collect();
        Background {
            width,
            height: profile.len(),
            levels,
            region: Default::default(),
            gains: vec![1.0],
            near_cols: (0, width),
        }
    }

    #[test]
    fn the_line_is_fitted_in_the_columns_near_the_sphere_whatever_the_others_hold() {
        // A tilted band top (0.01 rows a column), 400 columns; the line
        // taken in columns 100..300.
        let (w, h) = (400, 48);
        let mut bg = background_of(&vec![0.0; h], w);
        for j in 0..w {
            let e = 20.3 + 0.01 * j as f64;
            let v = blurred(&[-1e3, e, 1e3], &[200.0, 80.0], 0.8, h);
            for (i, v) in v.into_iter().enumerate() {
                bg.levels[i * w + j] = v as f32;
            }
        }
        bg.near_cols = (100, 300);
        let bits = |l: SurfaceLine| (l.row0_px.to_bits(), l.slope.to_bits(), l.n_used);
        let near = fit_surface(&bg, &SurfaceParams::default()).unwrap();
        assert!((near.row_at(200.0) - 22.3).abs() < 1e-3, "{near:?}");
        assert!((near.slope - 0.01).abs() < 1e-5, "{near:?}");
        assert_eq!(near.n_used, 200);
        // The other columns: a step 10 rows higher, noise, NaN.
        let mut x = 7u64;
        for i in 0..h {
            for j in (0..100).chain(300..w) {
                x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
                bg.levels[i * w + j] = match (x >> 59, i < 12) {
                    (0, _) => f32::NAN,
                    (_, true) => 200.0 + (x >> 61) as f32,
                    (_, false) => 60.0,
                };
            }
        }
        assert_eq!(
            bits(fit_surface(&bg, &SurfaceParams::default()).unwrap()),
            bits(near)
        );
        // Over every column, they move it (or leave no line).
        bg.near_cols = (0, w);
        let all = fit_surface(&bg, &SurfaceParams::default()).ok();
        assert_ne!(all.map(bits), Some(bits(near)));
    }

    #[test]
    fn a_strip_below_the_band_top_brighter_or_darker_is_fitted_not_followed() {
        // Backlight 200 DN over a band at 0.7 of it, a glossy strip adding
        // 0.22 of the backlight over the band's top 3 px (σ = 0.8 px): the
        // step into the strip (16 DN) is a third of the strip's lower edge
        // (44 DN). The line is the band's top: the largest step would put it
        // at the strip's bottom, 3 px too low. Two blurred steps are this
        // profile's exact model: only f32 rounding remains.
        let e = 30.3;
        let v: Vec<f64> = blurred(&[-1e3, e, e + 3.0, 1e3], &[200.0, 184.0, 140.0], 0.8, 64)
            .into_iter()
            .collect();
        let line = fit_surface(&background_of(&v, 40), &SurfaceParams::default()).unwrap();
        assert!((line.row0_px - e).abs() < 0.001, "{}", line.row0_px);
        assert!(line.slope.abs() < 1e-9);
        // A strip darker than the backlight by more than the band below:
        // the top step is the largest, and the strip's edge is fitted too
        // (a single step's flank, which reaches 2 rows into the strip, was
        // 0.053 px off here).
        let v = blurred(&[-1e3, e, e + 3.0, 1e3], &[200.0, 160.0, 140.0], 0.8, 64);
        let line = fit_surface(&background_of(&v, 40), &SurfaceParams::default()).unwrap();
        assert!((line.row0_px - e).abs() < 0.001, "{}", line.row0_px);
        // A pillar-top row 25 % darker than the band over 1.4 px, σ = 0.65:
        // the step up out of it is found and fitted too (the flank fit of
        // the top step alone was 0.0xx px high here).
        let v = blurred(
            &[-1e3, e, e + 1.4, 1e3],
            &[200.0, 0.75 * 90.0, 90.0],
            0.65,
            64,
        );
        let line = fit_surface(&background_of(&v, 40), &SurfaceParams::default()).unwrap();
        assert!((line.row0_px - e).abs() < 0.001, "{}", line.row0_px);
    }

    #[test]
    fn in_a_noisy_background_strips_are_fitted_and_noise_goes_to_the_one_step_fit() {
        // 300 columns of the band top at row 30.3 (σ = 0.8 px) with noise.
        // Plain, 1.5 DN (a background of few frames): the strip search fires
        // on the noise in most columns, and all of them but for the F-test's
        // 1 % take the one-step fit's row. With a glossy strip 3 px deep,
        // 0.5 DN: the columns where the search finds the strip from the
        // band's top keep the two-step fit, its top within 0.3 px and 0.03
        // on average, where the one-step fit is 0.2 px or more low.
        use rand::SeedableRng;
        use rand_distr::Distribution;
        let (e, cols, rows) = (30.3, 300, 64);
        let noisy = |bounds: &[f64], levels: &[f64], noise: f64, seed: u64| {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let normal = rand_distr::Normal::new(0.0, noise).unwrap();
            let mut bg = background_of(&blurred(bounds, levels, 0.8, rows), cols);
            for x in bg.levels.iter_mut() {
                *x += normal.sample(&mut rng) as f32;
            }
            bg
        };
        let params = SurfaceParams::default();
        let w = params.half_window;
        // Per column: the top step's row as `column_edges` finds it, whether
        // the strip search fires, and the one-step fit's row.
        let column = |bg: &Background, j: usize| {
            let step = |i: usize| bg.at(i, j) as f64 - bg.at(i + 1, j) as f64;
            let (best_row, best) = (w..rows - w - 1)
                .map(|i| (i, step(i)))
                .fold((0, f64::NEG_INFINITY), |a, b| if b.1 > a.1 { b } else { a });
            let zs = top_step_row(bg, j, w, best_row, best);
            let flank: Vec<f64> = (zs - w..=zs + 2).map(|i| bg.at(i, j) as f64).collect();
            let one = step_edge_row(&flank, (zs - w) as f64, zs as f64 + 0.5);
            (zs, strip_edge_row(bg, j, zs, best).is_some(), one)
        };
        let plain = noisy(&[-1e3, e, 1e3], &[200.0, 140.0], 1.5, 7);
        let (mut searched, mut one_step) = (0, 0);
        for edge in column_edges(&plain, &params) {
            let (_, strip, one) = column(&plain, edge.x_px as usize);
            searched += strip as usize;
            one_step += (strip && one.map(f64::to_bits) == Some(edge.row_px.to_bits())) as usize;
        }
        assert!(
            searched >= 200,
            "the strip search fired in {searched} columns"
        );
        assert!(
            100 * one_step >= 98 * searched,
            "{one_step} of {searched} columns with noise took the one-step fit"
        );
        let glossy = noisy(&[-1e3, e, e + 3.0, 1e3], &[200.0, 184.0, 140.0], 0.5, 8);
        let (mut fitted, mut sum_px, mut sum_one_px) = (0, 0.0, 0.0);
        for edge in column_edges(&glossy, &params) {
            let (zs, strip, one) = column(&glossy, edge.x_px as usize);
            if strip && (zs as f64 + 0.5 - e).abs() < 1.0 {
                fitted += 1;
                sum_px += edge.row_px - e;
                sum_one_px += one.unwrap_or(f64::NAN) - e;
                assert!((edge.row_px - e).abs() < 0.3, "{edge:?}");
            }
        }
        // The one-step fit's flank reaches into the strip: ~0.3 px low.
        let (mean_px, mean_one_px) = (sum_px / fitted as f64, sum_one_px / fitted as f64);
        assert!(fitted >= 200, "{fitted} columns with the strip fitted");
        assert!(mean_px.abs() < 0.03, "the strip's top {mean_px} px off");
        assert!(mean_one_px > 0.2, "the one-step fit {mean_one_px} px off");
    }

    #[test]
    fn a_structured_band_top_moves_the_flank_fit_far_less_than_the_area_row() {
        // A darker top row (pillar tops edge-on, −25 % over 1.5 px) and a
        // glossy strip (+20 % of the backlight over 2.5 px) under σ = 0.8 px:
        // the area method is pulled by the band's inside, the flank fit much
        // less, and their disagreement is of the size of the area method's bias.
        let e = 20.3;
        let band = 0.34;
        for (levels, bounds) in [
            (vec![0.75, band * 0.75, band], vec![-1e3, e, e + 1.5, 1e3]),
            (vec![0.75, band + 0.15, band], vec![-1e3, e, e + 2.5, 1e3]),
        ] {
            let v = blurred(&bounds, &levels, 0.8, 40);
            let (step, area) = both_rows(&v);
            assert!((area - e).abs() > 0.15, "area {area}");
            assert!(
                (step - e).abs() < 0.5 * (area - e).abs(),
                "step {step} area {area}"
            );
            assert!(
                (step - area).abs() > 0.5 * (area - e).abs(),
                "step {step} area {area}"
            );
        }
    }
}
