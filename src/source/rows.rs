//! Filling a caller's buffer a row at a time: the band checks and row
//! helpers every reader shares.

use ndarray::{ArrayViewMut1, ArrayViewMut2};

use super::error::SourceError;
use super::frame::SourceMeta;

/// Check a band request against the metadata: frame index, row range, buffer width.
pub(crate) fn check_band(
    meta: &SourceMeta,
    index: usize,
    row0: usize,
    out: &ArrayViewMut2<u16>,
) -> Result<(), SourceError> {
    if index >= meta.frame_count {
        return Err(SourceError::FrameOutOfRange {
            path: meta.path.clone(),
            index,
            count: meta.frame_count,
        });
    }
    let row_end = row0.saturating_add(out.nrows());
    if row_end > meta.height {
        return Err(SourceError::RowsOutOfRange {
            path: meta.path.clone(),
            row0,
            row_end,
            height: meta.height,
        });
    }
    if out.ncols() != meta.width {
        return Err(SourceError::BufferShape {
            path: meta.path.clone(),
            width: meta.width,
            got: out.ncols(),
        });
    }
    Ok(())
}

/// The first `n` bytes of `v`, grown (zero-filled) only when shorter: a
/// buffer a read is about to fill is not cleared frame after frame (a
/// 1280-px band's 224 kB memset cost about as much as converting its window).
pub(crate) fn grown(v: &mut Vec<u8>, n: usize) -> &mut [u8] {
    if v.len() < n {
        v.resize(n, 0);
    }
    &mut v[..n]
}

/// Run `fill(j, row)` on every row `j` of `out` as a plain slice: straight
/// on the caller's memory when `out` is contiguous, else through `scratch`.
pub(crate) fn fill_rows(
    out: &mut ArrayViewMut2<u16>,
    scratch: &mut Vec<u16>,
    mut fill: impl FnMut(usize, &mut [u16]),
) {
    let w = out.ncols();
    if w == 0 {
        return;
    }
    if let Some(all) = out.as_slice_mut() {
        for (j, row) in all.chunks_exact_mut(w).enumerate() {
            fill(j, row);
        }
    } else {
        for (j, row) in out.rows_mut().into_iter().enumerate() {
            fill_row(row, scratch, |d| fill(j, d));
        }
    }
}

/// Run `fill` on row `row` of `out` as a plain slice; when the view's row is
/// not contiguous, fill `scratch` and copy it over.
/// `conv(range, dst)` for each column range of `cols` (all of the row
/// without), `dst` that range of `row`: the conversion of only the
/// columns [`FrameSource::read_window_into`] asks for.
pub(crate) fn for_cols(
    row: &mut [u16],
    cols: Option<&[std::ops::Range<usize>]>,
    mut conv: impl FnMut(std::ops::Range<usize>, &mut [u16]),
) {
    let w = row.len();
    match cols {
        None => conv(0..w, row),
        Some(cols) => {
            for c in cols {
                let c = c.start.min(w)..c.end.min(w);
                if c.start < c.end {
                    conv(c.clone(), &mut row[c]);
                }
            }
        }
    }
}

pub(crate) fn fill_row(
    mut row: ArrayViewMut1<u16>,
    scratch: &mut Vec<u16>,
    fill: impl FnOnce(&mut [u16]),
) {
    if let Some(s) = row.as_slice_mut() {
        fill(s);
    } else {
        scratch.clear();
        scratch.resize(row.len(), 0);
        fill(scratch);
        for (d, s) in row.iter_mut().zip(scratch.iter()) {
            *d = *s;
        }
    }
}
