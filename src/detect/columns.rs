//! Which columns of a wide frame the background and the surface line look
//! at: those within reach of the sphere's path, so that what a frame costs
//! follows the sphere and not the sensor.
//!
//! The background's per-pixel median and the surface line's fit per column
//! are taken over [`near_columns`]: the columns from [`REACH_RADII`] sphere
//! radii left of the leftmost circle found in the background's sample
//! frames to as far right of the rightmost, widened to at least
//! [`MIN_COLUMNS`]. A 512-px frame is always seen whole, so footage of the
//! size every accuracy figure was measured on gives the same bits as
//! before. On a wider frame the line is fitted over the window: its row
//! under the sphere — what δ is measured from — comes from the columns
//! around the impact, and its tilt from a baseline of at least 512 px
//! (≥ 8 radii); the columns beyond, which only the search for a sphere
//! that is not being followed reads, hold the first sample frame.

use super::circle::Circle;

/// Radii of the sphere each side of its path within which the background is
/// a median and the surface line is fitted.
pub const REACH_RADII: f64 = 4.0;

/// Fewest columns of the window (px): the width every accuracy figure was
/// measured at, so that such frames are seen whole.
pub const MIN_COLUMNS: usize = 512;

/// Columns `c0..c1` of a `width`-px frame within [`REACH_RADII`] radii of
/// the `circles` found (the largest radius), at least `min_columns` wide
/// (widened evenly, moved inside the frame); the whole width without a
/// circle.
pub fn near_columns(
    circles: &[Option<Circle>],
    width: usize,
    min_columns: usize,
) -> (usize, usize) {
    let found = circles.iter().flatten();
    let (mut x0, mut x1, mut r) = (f64::INFINITY, f64::NEG_INFINITY, 0f64);
    for c in found {
        x0 = x0.min(c.x_px);
        x1 = x1.max(c.x_px);
        r = r.max(c.r_px);
    }
    if !(x0 <= x1 && r.is_finite()) {
        return (0, width);
    }
    let reach = REACH_RADII * r;
    let lo = (x0 - reach).floor().clamp(0.0, width as f64) as usize;
    let hi = ((x1 + reach).ceil() + 1.0).clamp(0.0, width as f64) as usize;
    widened((lo, hi.max(lo)), width, min_columns)
}

/// `cols` widened evenly to at least `min` columns, moved to lie inside
/// `0..width`.
fn widened((lo, hi): (usize, usize), width: usize, min: usize) -> (usize, usize) {
    if min >= width {
        return (0, width);
    }
    let n = hi - lo;
    if n >= min {
        return (lo, hi);
    }
    let lo = lo.saturating_sub((min - n) / 2);
    let lo = lo.min(width - min);
    (lo, lo + min.max(n))
}

/// The columns a band around the sphere needs: `window` and the strips of
/// `strip` columns at each edge of a `width`-wide frame, in increasing
/// order, merged where they overlap or lie less than `WINDOW_GAP_PX`
/// apart (converting a short gap costs less than another run).
pub fn window_columns(
    window: std::ops::Range<usize>,
    strip: usize,
    width: usize,
) -> Vec<std::ops::Range<usize>> {
    let mut cols: Vec<std::ops::Range<usize>> = Vec::with_capacity(3);
    for c in [0..strip, window, width.saturating_sub(strip)..width] {
        match cols.last_mut() {
            Some(last) if c.start <= last.end + WINDOW_GAP_PX => last.end = last.end.max(c.end),
            _ if c.start < c.end => cols.push(c),
            _ => {}
        }
    }
    cols
}

/// Column runs of a window read closer than this (px) are converted as one.
const WINDOW_GAP_PX: usize = 128;

#[cfg(test)]
mod tests {
    use super::*;

    fn at(x_px: f64, r_px: f64) -> Option<Circle> {
        Some(Circle {
            x_px,
            z_px: 100.0,
            r_px,
        })
    }

    #[test]
    fn the_window_follows_the_path_and_is_never_narrower_than_512_px() {
        // A 512-px frame is always whole, wherever the sphere is.
        for x in [10.0, 256.0, 500.0] {
            assert_eq!(near_columns(&[at(x, 20.0)], 512, MIN_COLUMNS), (0, 512));
        }
        // No circle: the whole width.
        assert_eq!(near_columns(&[None, None], 1280, MIN_COLUMNS), (0, 1280));
        // R = 75 px at x 600–660: 4 R = 300 each side.
        assert_eq!(
            near_columns(&[at(600.0, 75.0), None, at(660.0, 70.0)], 1280, MIN_COLUMNS),
            (300, 961)
        );
        // A small sphere: 512 columns around it, moved inside the frame.
        assert_eq!(
            near_columns(&[at(640.0, 20.0)], 1280, MIN_COLUMNS),
            (385, 897)
        );
        assert_eq!(near_columns(&[at(30.0, 20.0)], 1280, MIN_COLUMNS), (0, 512));
        assert_eq!(
            near_columns(&[at(1270.0, 20.0)], 1280, MIN_COLUMNS),
            (768, 1280)
        );
    }

    #[test]
    fn window_columns_merge_near_runs_and_keep_far_ones_apart() {
        assert_eq!(
            window_columns(300..700, 16, 1280),
            vec![0..16, 300..700, 1264..1280]
        );
        assert_eq!(window_columns(100..400, 16, 512), vec![0..512]);
        assert_eq!(window_columns(0..1280, 16, 1280), vec![0..1280]);
    }
}
