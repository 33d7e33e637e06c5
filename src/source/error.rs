//! Why a frame sequence could not be opened or read.

use std::path::PathBuf;

/// What dropscope reads, for messages refusing something else.
pub const SUPPORTED_INPUTS: &str = "a folder of numbered TIFF/PNG/BMP/JPEG frames (as Phantom \
     Camera Control exports them), a Phantom .cine, or a Photron .mraw with its .cihx/.cih";

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
    /// The input carries no frame rate and none was given as a fallback.
    #[error(
        "{path}: no frame rate: no PCC XML side file with FrameRateDouble/FrameRate here; \
         give fps in the run manifest or camera.fps in pipeline.toml (or --fps)"
    )]
    NoFrameRate { path: PathBuf },
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
    #[error("{path}: the output buffer has {got} columns but the frames are {width} wide")]
    BufferShape {
        path: PathBuf,
        width: usize,
        got: usize,
    },
    #[error("{path}: frame {index}: {reason}")]
    Frame {
        path: PathBuf,
        index: usize,
        reason: String,
    },
}
