//! What the header region says: the storage of the pixels, the header's
//! fields and where the per-frame values and image offsets are.

use std::io::Read;
use std::path::Path;

use crate::source::colour::Bayer;
use crate::source::index::Time64;
use crate::source::packing::packed_span;
use crate::source::ColourInput;

/// Does the file start with the cine magic `"CI"`?
pub fn has_cine_magic(path: &Path) -> bool {
    let mut magic = [0u8; 2];
    crate::util::io::open_regular(path)
        .and_then(|mut f| f.read_exact(&mut magic))
        .is_ok()
        && &magic == b"CI"
}

/// How pixels are stored (BITMAPINFOHEADER biBitCount / biCompression).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CineStorage {
    /// biBitCount 8, biCompression 0: one byte per pixel, rows bottom-up.
    Gray8,
    /// biBitCount 16, biCompression 0: LE u16 per pixel, rows bottom-up.
    Gray16,
    /// biCompression 256: 10-bit MSB-first packed, rows top-down.
    P10,
    /// biCompression 1024: 12-bit MSB-first packed, rows top-down.
    P12L,
    /// biBitCount 24: interpolated colour, B G R bytes per pixel, rows bottom-up.
    Bgr24,
    /// biBitCount 48: interpolated colour, B G R little-endian u16 per pixel, rows bottom-up.
    Bgr48,
}

impl CineStorage {
    /// Bits per stored pixel.
    pub fn bits(self) -> u32 {
        match self {
            CineStorage::Gray8 => 8,
            CineStorage::Gray16 => 16,
            CineStorage::P10 => 10,
            CineStorage::P12L => 12,
            CineStorage::Bgr24 => 24,
            CineStorage::Bgr48 => 48,
        }
    }
    /// Bits of one sample (a colour pixel holds three).
    pub fn sample_bits(self) -> u32 {
        match self {
            CineStorage::Bgr24 => 8,
            CineStorage::Bgr48 => 16,
            other => other.bits(),
        }
    }
    /// Packed layouts store rows top-down; unpacked ones bottom-up.
    pub fn top_down(self) -> bool {
        matches!(self, CineStorage::P10 | CineStorage::P12L)
    }
    pub(super) fn describe(self) -> &'static str {
        match self {
            CineStorage::Gray8 => "8-bit unpacked, bottom-up",
            CineStorage::Gray16 => "16-bit unpacked, bottom-up",
            CineStorage::P10 => "P10 packed 10-bit, top-down",
            CineStorage::P12L => "P12L packed 12-bit, top-down",
            CineStorage::Bgr24 => "24-bit BGR interpolated colour, bottom-up",
            CineStorage::Bgr48 => "48-bit BGR interpolated colour, bottom-up",
        }
    }
}

/// The header fields dropscope uses, with SETUP fields `None` when they lie
/// beyond `SETUP.Length`.
#[derive(Debug, Clone, PartialEq)]
pub struct CineHeader {
    /// CINEFILEHEADER Compression: 0 grey or interpolated colour, 1 JPEG, 2 raw colour (Bayer).
    pub compression: u16,
    /// CINEFILEHEADER Version (1 in every file seen).
    pub version: u16,
    /// FirstMovieImage: the number of the first image recorded in camera memory.
    pub first_movie_image: i32,
    /// TotalImageCount: images recorded in camera memory.
    pub total_image_count: u32,
    /// FirstImageNo: the number of the first image saved in this file (may be negative).
    pub first_image_no: i32,
    /// ImageCount: images saved in this file (the length of the offset table).
    pub image_count: u32,
    /// OffImageHeader: byte offset of the BITMAPINFOHEADER.
    pub off_image_header: u32,
    /// OffSetup: byte offset of the SETUP block.
    pub off_setup: u32,
    /// OffImageOffsets: byte offset of the table of int64 image offsets.
    pub off_image_offsets: u32,
    /// TriggerTime: when the camera was triggered.
    pub trigger_time: Time64,
    /// biWidth: image width, px.
    pub width: u32,
    /// biHeight: image height, px.
    pub height: u32,
    /// biBitCount: container bits per pixel (8, 16, 24 or 48).
    pub bit_count: u16,
    /// biCompression: 0 unpacked, 256 packed P10, 1024 packed P12L.
    pub bi_compression: u32,
    /// biSizeImage: bytes of one image's pixel data.
    pub size_image: u32,
    /// How the pixels are stored, from `bit_count` and `bi_compression`.
    pub storage: CineStorage,
    /// A raw colour cine's (Compression 2) Bayer pattern; `None`: one grey
    /// sample a pixel, or interpolated colour ([`CineStorage::Bgr24`], [`CineStorage::Bgr48`]).
    pub bayer: Option<Bayer>,
    /// SETUP.Length: how many SETUP bytes this file holds.
    pub setup_length: u16,
    /// SETUP FrameRate16: frame rate, frames/s, capped at 65535 (legacy).
    pub frame_rate16: u16,
    /// SETUP Shutter16: exposure, µs (legacy).
    pub shutter16_us: u16,
    /// SETUP FrameRate: integer frame rate, frames/s.
    pub frame_rate: Option<u32>,
    /// SETUP Shutter: exposure, µs.
    pub shutter_us: Option<u32>,
    /// SETUP bFlipH: the viewer flips the picture left to right.
    pub flip_h: Option<bool>,
    /// SETUP bFlipV: the viewer flips the picture upside down.
    pub flip_v: Option<bool>,
    /// SETUP CameraVersion: the camera's model code (73: Phantom v7.3, …).
    pub camera_version: Option<u32>,
    /// SETUP SoftwareVersion: the PCC or SDK build that wrote the file.
    pub software_version: Option<u32>,
    /// SETUP CFA: the colour filter array (its low byte: 0 grey, 3–6 Bayer patterns).
    pub cfa: Option<u32>,
    /// SETUP Rotate: the viewer's rotation, degrees (0, +90 counter-clockwise, −90).
    pub rotate: Option<i32>,
    /// SETUP RealBPP: significant bits of a sample.
    pub real_bpp: Option<u32>,
    /// SETUP ShutterNs: exposure, ns.
    pub shutter_ns: Option<u32>,
    /// SETUP BlackLevel: the raw black level, counts.
    pub black_level: Option<i32>,
    /// SETUP WhiteLevel: the raw white level, counts.
    pub white_level: Option<i32>,
    /// Viewer image adjustments PCC applies when exporting (fOffset, fGain, fGamma).
    pub f_offset: Option<f32>,
    /// SETUP fGain (see `f_offset`).
    pub f_gain: Option<f32>,
    /// SETUP fGamma (see `f_offset`).
    pub f_gamma: Option<f32>,
    /// SETUP CameraModel: the camera's name (`Phantom v2012`, …).
    pub camera_model: Option<String>,
    /// SETUP fDecimation: the decimation applied when saving (1 when absent).
    pub f_decimation: Option<f32>,
    /// SETUP dFrameRate: the acquisition frame rate in full precision, frames/s.
    pub d_frame_rate: Option<f64>,
}

impl CineHeader {
    /// Acquisition rate: dFrameRate, else FrameRate, else FrameRate16 (§0.9).
    pub fn acquisition_fps(&self) -> f64 {
        match (self.d_frame_rate, self.frame_rate) {
            (Some(d), _) if d.is_finite() && d > 0.0 => d,
            (_, Some(f)) if f > 0 => f64::from(f),
            _ => f64::from(self.frame_rate16),
        }
    }
    /// Save decimation: fDecimation when present and > 0, else 1.
    pub fn decimation(&self) -> f64 {
        match self.f_decimation {
            Some(d) if d.is_finite() && d > 0.0 => f64::from(d),
            _ => 1.0,
        }
    }
    /// Spacing of the saved frames: acquisition rate / decimation.
    pub fn saved_fps(&self) -> f64 {
        self.acquisition_fps() / self.decimation()
    }
    /// Exposure: ShutterNs, else Shutter (µs), else Shutter16 (µs) (§0.10).
    pub fn exposure_s(&self) -> Option<f64> {
        match (self.shutter_ns, self.shutter_us) {
            (Some(ns), _) if ns > 0 => Some(f64::from(ns) * 1e-9),
            (_, Some(us)) if us > 0 => Some(f64::from(us) * 1e-6),
            _ if self.shutter16_us > 0 => Some(f64::from(self.shutter16_us) * 1e-6),
            _ => None,
        }
    }
    /// Significant bits: RealBPP when present and plausible, else the container's.
    pub fn bit_depth(&self) -> u8 {
        match self.real_bpp {
            Some(b) if (1..=self.storage.sample_bits()).contains(&b) => b as u8,
            _ => self.storage.sample_bits() as u8,
        }
    }
    /// What a colour cine held, read as grey luminance; `None` for grey.
    pub fn colour(&self) -> Option<ColourInput> {
        match (self.bayer, self.storage) {
            (Some(b), _) => Some(ColourInput::Bayer(b)),
            (None, CineStorage::Bgr24 | CineStorage::Bgr48) => Some(ColourInput::Rgb),
            _ => None,
        }
    }
    /// Bytes from one stored row to the next for the unpacked layouts:
    /// `width × bytes`, or that padded to 4 bytes (the DIB rule) when
    /// biSizeImage says the rows are padded (§8.1). Packed layouts have no
    /// row stride (rows run on bit by bit).
    pub fn row_stride(&self) -> u64 {
        let natural = u64::from(self.width) * u64::from(self.storage.bits()) / 8;
        let padded = natural.div_ceil(4) * 4;
        if !self.storage.top_down()
            && padded != natural
            && u64::from(self.size_image) == padded * u64::from(self.height)
        {
            padded
        } else {
            natural
        }
    }
    /// Bytes of one image's pixels.
    pub fn image_bytes(&self) -> u64 {
        if self.storage.top_down() {
            packed_span(
                0,
                u64::from(self.width) * u64::from(self.height),
                self.storage.bits(),
            )
        } else {
            self.row_stride() * u64::from(self.height)
        }
    }
}

/// Everything located in the header region: the header, where the
/// per-frame times and exposures are (tagged blocks), and where the image
/// offsets are. The per-frame values stay in the file (a long movie's
/// index would be 36 bytes a frame in memory).
#[derive(Debug, Clone, PartialEq)]
pub struct CineLayout {
    /// The header fields.
    pub header: CineHeader,
    /// Byte where tag 1002's time stamps (a TIME64 an image) start.
    pub times_at: Option<u64>,
    /// Byte where tag 1003's exposures (a u32 an image) start.
    pub exposures_at: Option<u64>,
    /// Tagged block types in file order.
    pub block_types: Vec<u16>,
}

impl CineLayout {
    /// The end of the header region: the end of the image offset table.
    pub fn region_len(&self) -> u64 {
        u64::from(self.header.off_image_offsets) + 8 * u64::from(self.header.image_count)
    }
}
