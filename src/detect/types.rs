//! The band of rows of a frame that detection reads ([`Band`]).

use super::error::DetectError;

/// A view of rows `row0..row0 + view.nrows()` of a frame, with its first row,
/// as one contiguous row-major slice. Detection reads only such bands.
#[derive(Debug, Clone, Copy)]
pub struct Band<'a> {
    /// Pixel values, row-major, `nrows × width`.
    pub data: &'a [u16],
    /// Frame row of the first row of `data`.
    pub row0: usize,
    pub nrows: usize,
    pub width: usize,
    /// Columns `cols.0..cols.1` hold the frame's pixels (`0..width` for
    /// whole rows). A band read as a window ([`Band::window`]) holds
    /// arbitrary values elsewhere, which the edge points never sample.
    pub cols: (usize, usize),
}

impl<'a> Band<'a> {
    /// A band from a view of rows `row0..` of a frame (whole rows, row-major).
    pub fn new(view: ndarray::ArrayView2<'a, u16>, row0: usize) -> Result<Self, DetectError> {
        let width = view.ncols();
        Self::window(view, row0, 0..width)
    }

    /// A band of which only columns `cols` were read (see
    /// [`crate::source::FrameSource::read_window_into`]): edge points are
    /// measured only along normals whose windows lie inside them. The
    /// flicker reference strips ([`super::background::GainRegion`]) must
    /// be read too.
    pub fn window(
        view: ndarray::ArrayView2<'a, u16>,
        row0: usize,
        cols: std::ops::Range<usize>,
    ) -> Result<Self, DetectError> {
        let (nrows, width) = view.dim();
        let data = view.to_slice().ok_or(DetectError::NotContiguous)?;
        Ok(Band {
            data,
            row0,
            nrows,
            width,
            cols: (cols.start.min(width), cols.end.min(width)),
        })
    }

    /// The whole frame (a [`crate::source::Frame`]) as a band starting at
    /// row 0.
    pub fn frame(frame: &'a ndarray::Array2<u16>) -> Result<Self, DetectError> {
        Self::new(frame.view(), 0)
    }

    /// Bilinear interpolation at frame coordinates `(x, z)`; `None` when any
    /// of the four neighbours lies outside the band.
    #[inline]
    pub fn bilinear(&self, x: f64, z: f64) -> Option<f64> {
        let zl = z - self.row0 as f64;
        if !(x >= 0.0 && zl >= 0.0) {
            return None;
        }
        let (j, i) = (x as usize, zl as usize);
        if j + 1 >= self.width || i + 1 >= self.nrows {
            return None;
        }
        let (fx, fz) = (x - j as f64, zl - i as f64);
        let k = i * self.width + j;
        let (a, b) = (self.data[k] as f64, self.data[k + 1] as f64);
        let (c, d) = (
            self.data[k + self.width] as f64,
            self.data[k + self.width + 1] as f64,
        );
        let top = a + fx * (b - a);
        let bottom = c + fx * (d - c);
        Some(top + fz * (bottom - top))
    }
}
