//! Why a frame sequence could not be opened or read.

use std::path::PathBuf;

/// What dropscope reads, for messages refusing something else.
pub const SUPPORTED_INPUTS: &str = "a folder of numbered TIFF/PNG/BMP/JPEG frames (as Phantom \
     Camera Control exports them), a Phantom .cine, or a Photron .mraw with its .cihx/.cih";

/// Why a frame sequence could not be opened or read.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// The input could not be opened or read.
    #[error("{path}: {source}")]
    Io {
        /// The input: file or folder.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The input is not what its name says: a bad header, a file too short, an unreadable frame file.
    #[error("{path}: {reason}")]
    Format {
        /// The input: file or folder.
        path: PathBuf,
        /// What is wrong, where.
        reason: String,
    },
    /// The input is valid but in a variant dropscope does not read (a compression, a bit depth, …).
    #[error("{path}: unsupported: {reason}")]
    Unsupported {
        /// The input: file or folder.
        path: PathBuf,
        /// What is not supported.
        reason: String,
    },
    /// The input carries no frame rate and none was given as a fallback.
    #[error(
        "{path}: no frame rate: no PCC XML side file with FrameRateDouble/FrameRate here; \
         give fps in the run manifest or camera.fps in pipeline.toml (or --fps)"
    )]
    NoFrameRate {
        /// The input.
        path: PathBuf,
    },
    /// A frame was asked for past the end of the sequence.
    #[error("{path}: frame index {index} out of range (the sequence has {count} frames)")]
    FrameOutOfRange {
        /// The input.
        path: PathBuf,
        /// The index asked for (0-based, in the sequence's order).
        index: usize,
        /// Number of frames in the sequence.
        count: usize,
    },
    /// A band of rows was asked for that does not lie inside the frame.
    #[error("{path}: rows {row0}..{row_end} out of range (the frame has {height} rows)")]
    RowsOutOfRange {
        /// The input.
        path: PathBuf,
        /// First row asked for.
        row0: usize,
        /// One past the last row asked for.
        row_end: usize,
        /// The frame's height, rows.
        height: usize,
    },
    /// The caller's buffer does not have the frames' width.
    #[error("{path}: the output buffer has {got} columns but the frames are {width} wide")]
    BufferShape {
        /// The input.
        path: PathBuf,
        /// The frames' width, px.
        width: usize,
        /// The buffer's number of columns.
        got: usize,
    },
    /// One frame could not be read or decoded.
    #[error("{path}: frame {index}: {reason}")]
    Frame {
        /// The input.
        path: PathBuf,
        /// The frame's index (0-based, in the sequence's order).
        index: usize,
        /// What went wrong.
        reason: String,
    },
}
