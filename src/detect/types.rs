//! What the detection stages hand each other: the band of rows of a frame
//! they read ([`Band`]), edge points ([`EdgePoint`]), the surface line
//! ([`SurfaceLine`]).

use super::error::DetectError;

/// A view of rows `row0..row0 + view.nrows()` of a frame, with its first row,
/// as one contiguous row-major slice. Detection reads only such bands.
#[derive(Debug, Clone, Copy)]
pub struct Band<'a> {
    /// Pixel values, row-major, `nrows × width`.
    pub data: &'a [u16],
    /// Frame row of the first row of `data`.
    pub row0: usize,
    /// Number of rows in `data`.
    pub nrows: usize,
    /// Frame width, px (the length of a row of `data`).
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

/// The undeformed surface's top line, in frame pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceLine {
    /// Row of the line at column 0 (px).
    pub row0_px: f64,
    /// Tilt (rows per column).
    pub slope: f64,
    /// Covariance of `(row0_px, slope)`; zero when given by the configuration.
    pub cov: [[f64; 2]; 2],
    /// RMS residual of the column edges about the line (px); 0 when given.
    pub residual_px: f64,
    /// Columns used in the fit (0 when given).
    pub n_used: usize,
    /// Systematic error of the edge model (px): the median over the columns
    /// of the step fit's row minus the area method's row (module doc, step 2);
    /// near 0 for a clean step, the size of the bias a structured band top
    /// (a dark or bright top row, a glossy strip) can give. 0 when given.
    pub model_err_px: f64,
    /// The line's bow: the coefficient c of `c·x²` fitted beside the line
    /// to the same column edges (1/px; positive: the ends lower than the
    /// middle), and its standard error. A straight surface seen through a
    /// lens with radial distortion `k1` about a centre row `z_c` is bowed by
    /// `c = k1·(row − z_c)`: the lens measured in the images
    /// (`lens::k1_from_bow`). 0 when given.
    pub bow_per_px2: f64,
    /// Standard error of `bow_per_px2`, 1/px².
    pub bow_err_per_px2: f64,
}

impl SurfaceLine {
    /// The line's row at column `x`.
    #[inline]
    pub fn row_at(&self, x: f64) -> f64 {
        self.row0_px + self.slope * x
    }

    /// Standard deviation of [`row_at`](Self::row_at)`(x)`:
    /// `√(c₀₀ + 2x c₀₁ + x² c₁₁)`.
    pub fn sigma_row_at(&self, x: f64) -> f64 {
        let c = &self.cov;
        (c[0][0] + 2.0 * x * c[0][1] + x * x * c[1][1])
            .max(0.0)
            .sqrt()
    }

    /// A line given, not fitted: row `row0_px` at column 0 and `slope`, with
    /// no covariance, residual or edge-model error.
    pub fn given(row0_px: f64, slope: f64) -> Self {
        SurfaceLine {
            row0_px,
            slope,
            cov: [[0.0; 2]; 2],
            residual_px: 0.0,
            n_used: 0,
            model_err_px: 0.0,
            bow_per_px2: 0.0,
            bow_err_per_px2: 0.0,
        }
    }
}
