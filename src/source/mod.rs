//! Frame sequences: one trait, [`FrameSource`], that every input implements.
//!
//! Frames are grey, row-major, rows top-down (row 0 is the top of the
//! picture), held as `u16` whatever the file's container: 8-bit data keeps its
//! values 0‥255, 12-bit data its values 0‥4095. [`SourceMeta::bit_depth`] gives
//! the real number of significant bits. Readers fill a caller's buffer, so a
//! loop over a movie allocates nothing per frame, and frames are read on
//! demand in any order.

use ndarray::{Array2, ArrayViewMut2};
use std::path::PathBuf;

/// One grey frame, shape `(height, width)`, rows top-down, values as stored.
pub type Frame = Array2<u16>;

/// What a frame sequence holds, read from its headers or side files.
#[derive(Debug, Clone, PartialEq)]
pub struct SourceMeta {
    /// The file or folder the frames come from.
    pub path: PathBuf,
    /// A short name of the container: `"cine"`, `"tiff"`, `"png"`, `"bmp"`, `"jpeg"`.
    pub format: String,
    /// Number of frames that can be read (indices `0..frame_count`).
    pub frame_count: usize,
    pub width: usize,
    pub height: usize,
    /// Significant bits per sample (8, 10, 12, 14 or 16).
    pub bit_depth: u8,
    /// Spacing of the saved frames in frames per second (after any decimation).
    pub fps: f64,
    /// Exposure time of one frame, when known.
    pub exposure_s: Option<f64>,
    /// Camera image number of frame index 0 (negative = before the trigger).
    pub first_frame: i64,
    /// The camera image number of every readable frame, ascending.
    /// Consecutive unless the sequence has gaps.
    pub frame_numbers: Vec<i64>,
    /// Missing image numbers as inclusive ranges `(first, last)`.
    pub gaps: Vec<(i64, i64)>,
    /// Per-frame time in seconds relative to the trigger, where the file has it.
    pub timestamps_s: Option<Vec<f64>>,
}

impl SourceMeta {
    /// Time of frame `index` in seconds: the file's own time stamp where it has
    /// one, else `frame_number / fps`.
    pub fn time_s(&self, index: usize) -> f64 {
        match &self.timestamps_s {
            Some(t) if index < t.len() => t[index],
            _ => {
                self.frame_numbers
                    .get(index)
                    .copied()
                    .unwrap_or(index as i64) as f64
                    / self.fps
            }
        }
    }
}

/// A readable sequence of grey frames.
pub trait FrameSource: Send {
    /// The sequence's metadata.
    fn meta(&self) -> &SourceMeta;

    /// Fill `out` (shape `(height, width)`) with frame `index`.
    fn read_into(&mut self, index: usize, out: &mut Frame) -> Result<(), SourceError> {
        let h = self.meta().height;
        self.read_rows_into(
            index,
            0,
            &mut out.view_mut().slice_move(ndarray::s![0..h, ..]),
        )
    }

    /// Fill `out` (shape `(n, width)`) with rows `row0..row0 + n` of frame
    /// `index`. Detection reads only the band of rows near the sphere.
    fn read_rows_into(
        &mut self,
        index: usize,
        row0: usize,
        out: &mut ArrayViewMut2<u16>,
    ) -> Result<(), SourceError>;
}

/// Why a frame sequence could not be opened or read.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {reason}")]
    Format { path: PathBuf, reason: String },
    #[error("{path}: unsupported: {reason}")]
    Unsupported { path: PathBuf, reason: String },
    #[error("{path}: frame index {index} out of range (the sequence has {count} frames)")]
    FrameOutOfRange {
        path: PathBuf,
        index: usize,
        count: usize,
    },
    #[error("{path}: rows {row0}..{row_end} out of range (the frame has {height} rows)")]
    RowsOutOfRange {
        path: PathBuf,
        row0: usize,
        row_end: usize,
        height: usize,
    },
}
