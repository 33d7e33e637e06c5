//! What a frame file's header says ([`Probe`], [`Layout`]), what every file
//! of a folder must hold ([`Shape`]), the buffers reused from frame to
//! frame, the image kinds and the bytes a frame is read from.

use std::fs::File;
use std::io::{Cursor, Read, Seek};
use std::path::Path;

use crate::source::SourceError;

/// How one file's pixels are laid out, found by reading its header only.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Probe {
    pub(crate) width: usize,
    pub(crate) height: usize,
    /// Container bits per sample: 8 or 16.
    pub(crate) bits: u8,
    /// The file holds colour (RGB, RGBA, a colour palette): read as its luminance.
    pub(crate) colour: bool,
    pub(super) layout: Layout,
}

#[derive(Debug, Clone, PartialEq)]
pub(super) enum Layout {
    /// Uncompressed one-sample TIFF: strips of `rows_per_strip` rows at the
    /// offsets left in [`Scratch::strips`] (merged into one when contiguous).
    TiffRaw {
        big_endian: bool,
        rows_per_strip: usize,
    },
    /// 8-bit paletted BMP with a grey palette, rows bottom-up unless `top_down`.
    Bmp8 {
        data_offset: u64,
        stride: usize,
        top_down: bool,
    },
    /// Grey 8/16-bit PNG decoded row by row.
    PngGrey,
    /// Anything else: whole-image decode by the `image` crate, then grey.
    Generic,
}

/// What every frame file of a folder must hold: the first frame's size and
/// container bits per sample; `first` names that file in the error.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Shape<'a> {
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) bits: u8,
    pub(crate) first: &'a Path,
}

/// Buffers reused from frame to frame: header bytes, IFD entries, strip
/// offsets, file bytes / rows read.
#[derive(Debug, Default)]
pub(super) struct Scratch {
    pub(super) head: Vec<u8>,
    pub(super) entries: Vec<u8>,
    pub(super) raw: Vec<u8>,
    pub(super) strips: Vec<u64>,
    pub(super) bytes: Vec<u8>,
    /// Grey value of each BMP palette index.
    pub(super) palette: Vec<u8>,
    /// `head` holds the whole file (small TIFFs), not just its start.
    pub(super) whole: bool,
    /// Read small TIFFs whole (frame reads) or only their headers (open).
    pub(super) read_whole: bool,
    /// The current request is a band of fewer than half the rows: a TIFF
    /// is read by its header and the band's rows only, not whole.
    pub(super) small_band: bool,
}

/// TIFFs up to this size are read with one call and decoded from memory.
pub(super) const WHOLE_FILE_MAX: u64 = 16 << 20;

pub(crate) fn io_err(path: &Path) -> impl Fn(std::io::Error) -> SourceError + '_ {
    move |source| SourceError::Io {
        path: path.to_path_buf(),
        source,
    }
}

pub(crate) fn format_err(path: &Path, reason: impl Into<String>) -> SourceError {
    SourceError::Format {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

/// Image file kinds a folder may hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum ImageKind {
    /// TIFF (`.tif`, `.tiff`).
    Tiff,
    /// PNG (`.png`).
    Png,
    /// Windows bitmap (`.bmp`).
    Bmp,
    /// JPEG (`.jpg`, `.jpeg`).
    Jpeg,
}

impl ImageKind {
    /// The kind of a file extension (case-insensitive), if it is an image.
    pub fn from_extension(ext: &str) -> Option<ImageKind> {
        match ext.to_ascii_lowercase().as_str() {
            "tif" | "tiff" => Some(ImageKind::Tiff),
            "png" => Some(ImageKind::Png),
            "bmp" => Some(ImageKind::Bmp),
            "jpg" | "jpeg" => Some(ImageKind::Jpeg),
            _ => None,
        }
    }
    pub(crate) fn name(self) -> &'static str {
        match self {
            ImageKind::Tiff => "tiff",
            ImageKind::Png => "png",
            ImageKind::Bmp => "bmp",
            ImageKind::Jpeg => "jpeg",
        }
    }
}

/// Where a frame file's bytes are read from: the open file, or memory.
pub trait FrameBytes: Read + Seek {
    /// Read `buf.len()` bytes at `offset`.
    fn read_at(&mut self, offset: u64, buf: &mut [u8]) -> std::io::Result<()>;
}

impl FrameBytes for File {
    /// One positioned read on Unix.
    fn read_at(&mut self, offset: u64, buf: &mut [u8]) -> std::io::Result<()> {
        #[cfg(unix)]
        {
            std::os::unix::fs::FileExt::read_exact_at(self, buf, offset)
        }
        #[cfg(not(unix))]
        {
            self.seek(SeekFrom::Start(offset))?;
            self.read_exact(buf)
        }
    }
}

impl FrameBytes for Cursor<&[u8]> {
    fn read_at(&mut self, offset: u64, buf: &mut [u8]) -> std::io::Result<()> {
        self.set_position(offset);
        self.read_exact(buf)
    }
}
