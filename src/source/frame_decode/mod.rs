//! Decoding one frame file's bytes (TIFF, PNG, BMP or JPEG): its header
//! (`probe`, which opening a folder runs on its first file and every read
//! on the file it reads) and its rows. The
//! bytes are read from the file by [`super::folder::FolderSource`], or
//! taken from memory by [`FrameDecoder::probe_bytes`] and
//! [`FrameDecoder::read_rows_from_bytes`] (the `folder_frame` fuzz target):
//! one decoding path for both, generic over [`FrameBytes`].
//!
//! Speed: uncompressed single-sample TIFFs are parsed here (a whole frame
//! with one read of the file into a reused buffer, a band of fewer than half
//! the rows by its first 4 KiB and the band's rows only); PNGs are
//! decoded row by row with the `png` crate into reused buffers and stop after
//! the last requested row; BMP 8-bit is parsed here; everything else goes
//! through the `image` crate.
//!
//! | file | what |
//! | --- | --- |
//! | `types` | [`ImageKind`], [`FrameBytes`], what a header says and the reused buffers |
//! | `probe` | a file's header: TIFF, PNG and BMP parsed here |
//! | `decode` | [`FrameDecoder`]: a file's header and rows |

mod decode;
mod probe;
mod types;

pub use decode::FrameDecoder;
pub(crate) use types::{format_err, io_err, Probe, Shape};
pub use types::{FrameBytes, ImageKind};
