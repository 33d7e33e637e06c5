//! Step 1 and 2 of the module doc: the band's top in each column, the
//! step picked by its height and sub-pixel rows by the flank fit and the
//! area method.

use super::params::SurfaceParams;
use super::step::*;
use crate::detect::background::Background;

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
/// the fit's window (`wide_step_sigma` decides).
pub const WIDE_STEP_SIGMA_PX: f64 = 1.3;

/// Full width at half maximum (rows) of a column's largest step down,
/// `B(z) − B(z + 1)`, from which the band's top counts as blurred beyond
/// the flank fit's window (`half_window` rows above, 2 below): a Gaussian
/// blur of σ = FWHM / 2.355 ≥ 1.7 px, a defocused band top. The windows are
/// then made as wide as the step (`wide_step_edge`).
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
pub(super) fn top_step_row(
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
pub(super) fn strip_edge_row(bg: &Background, j: usize, top: usize, largest: f64) -> Option<usize> {
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
