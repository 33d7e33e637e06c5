//! Detection: from one grey frame to the sphere's circle, at sub-pixel accuracy.
//!
//! Every function here is pure: it takes frames (or views of a band of rows
//! of a frame) that are already in memory and returns numbers; nothing reads
//! files or prints. The stages, in the order a run uses them:
//!
//! | module | does |
//! | --- | --- |
//! | [`background`] | per-pixel background from the frames before the sphere, and a per-frame flicker gain |
//! | [`background_rows`] | the same from sample frames read a band of rows at a time (never all held whole) |
//! | [`columns`] | the columns within reach of the sphere's path that the background and the line look at |
//! | [`surface`] | the top of the pillar band as a sub-pixel line `row = row0 + slope · column` |
//! | [`coarse`] | the sphere's first appearance and a coarse circle (also when it enters through the top) |
//! | [`edges`] | sub-pixel edge points along normals to a predicted circle |
//! | [`circle`] | algebraic (hyper) start, robust geometric refinement, covariance, radius-held variant |
//! | [`calibrate`] | R_px from the full-circle frames; the scale and its check against the manifest |
//! | [`overlay`] | a picture of one frame's detection (frame, edge points, circle, surface line) |
//! | [`synth`] | exact anti-aliased test scenes (disk, tilted pillar band) with known truth |
//!
//! # Pixel convention
//!
//! The centre of pixel `(row 0, column 0)` is at `(x, z) = (0.0, 0.0)`; `x`
//! (columns) grows to the right and `z` (rows) grows downward. Pixel `(i, j)`
//! (row `i`, column `j`) covers `[j − ½, j + ½] × [i − ½, i + ½]` and its value
//! is the mean of the scene over that square. Frames are indexed
//! `frame[[row, column]]`. Every `_px` quantity in this module uses this
//! convention; a view of a band of rows carries its first row (`row0`) so
//! that coordinates stay those of the whole frame.

// `!(x > 0.0)` is meant throughout: it rejects NaN as well as non-positive values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod background;
pub mod background_rows;
pub mod calibrate;
pub mod circle;
pub mod coarse;
pub mod columns;
pub mod edges;
pub mod overlay;
pub mod surface;
pub mod synth;

pub use background::Background;
pub use circle::{fit_circle, hyper_fit, Circle, CircleFit, Covariance, FitOptions};
pub use edges::{edge_points, measure_circle, EdgeParams, EdgePoint, EdgeScratch};
pub use surface::SurfaceLine;

/// Why a detection step could not give an answer.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DetectError {
    /// A frame view is not in standard row-major layout (e.g. a column slice).
    #[error("frame view is not contiguous row-major: pass whole rows (a band of rows is fine)")]
    NotContiguous,
    /// A frame does not have the background's shape.
    #[error(
        "frame is {width}×{height} px but the background is {bg_width}×{bg_height} px: \
         the background must come from the same movie"
    )]
    ShapeMismatch {
        width: usize,
        height: usize,
        bg_width: usize,
        bg_height: usize,
    },
    /// No frame was given to build the background from.
    #[error("no frames to build the background from: set detect.background_frames ≥ 1")]
    NoBackgroundFrames,
    /// The flicker reference region holds no light (all zero), so no gain can be measured.
    #[error(
        "the frames' {what} are dark, where the backlight's brightness is measured: dropscope \
         needs a bright backlit background there (is the movie underexposed, or something dark \
         standing at the frame's edges?)"
    )]
    DarkReference { what: String },
    /// Too few usable points for a fit.
    #[error("{what}: only {found} usable points, at least {needed} needed")]
    TooFewPoints {
        what: &'static str,
        found: usize,
        needed: usize,
    },
    /// The fit has no unique solution (collinear points, zero radius, NaN).
    #[error("{what}: degenerate fit ({reason})")]
    Degenerate { what: &'static str, reason: String },
}

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
    /// flicker reference strips ([`background::GainRegion`]) must
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
