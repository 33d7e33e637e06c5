//! What a PCC export looks like on disk (SPEC §4): one folder per drop with
//! the frames `<run>_NNNNNN.<ext>`, the PCC XML side file `<run>.xml` and
//! `truth.json`.
//!
//! File names carry the camera image number, zero-padded to six digits; a
//! negative number keeps its sign before the digits: `<run>_-000030.tif` is
//! image −30 (readers must sort numerically, formats/phantom.md §11 pitfall 10).
//!
//! Frames go through a [`FrameSink`], so a container format that holds the
//! whole movie (`.cine`) is one more implementation beside [`FolderSink`].

use std::io::Cursor;
use std::path::{Path, PathBuf};

use image::codecs::jpeg::JpegEncoder;
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::codecs::tiff::TiffEncoder;
use image::{ExtendedColorType, ImageEncoder};
use rayon::prelude::*;
use serde::Serialize;

use super::truth::Truth;
use crate::source::Frame;
use crate::util::io::{write_atomic, write_atomic_unsynced};

/// Why an output could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// A file could not be written.
    #[error("{path}: cannot write: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A frame could not be encoded into the file's format.
    #[error("{path}: cannot encode frame {frame}: {message}")]
    Encode {
        /// The file.
        path: PathBuf,
        /// The frame's image number.
        frame: i64,
        /// The encoder's message.
        message: String,
    },
}

/// How the frames of a run are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FrameFormat {
    /// Uncompressed baseline TIFF, one file per frame (as PCC's TIF8/TIF16).
    Tiff,
    /// PNG (fast deflate, adaptive filters: smaller than `Best` on noisy
    /// frames here and 100× faster), one file per frame.
    Png,
    /// Baseline JPEG (8-bit only), one file per frame, as PCC's JPEG export;
    /// the quality is drawn per drop (85–98) unless `--jpeg-quality` fixes it.
    Jpeg,
    /// One raw Phantom `.cine` per drop (8-bit, or 16-bit containers holding
    /// 12-bit data), `<run>/<run>.cine`, with no XML side file.
    Cine,
}

/// How a rendered `.cine` stores its samples (`--packing`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum CinePackingChoice {
    /// One byte a sample for 8-bit frames, a 16-bit container for 12-bit ones.
    #[default]
    Unpacked,
    /// P10: the 12-bit values encoded to Vision Research's log-encoded
    /// 10-bit codes (the nearest code of its linearisation table), packed
    /// 4 samples in 5 bytes, as a Phantom saves "10-bit" cines.
    P10,
    /// P12L: the 12-bit values packed 2 samples in 3 bytes.
    P12l,
}

impl FrameFormat {
    /// The file extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            FrameFormat::Tiff => "tif",
            FrameFormat::Png => "png",
            FrameFormat::Jpeg => "jpg",
            FrameFormat::Cine => "cine",
        }
    }
}

/// The input path of a rendered run, relative to the campaign folder: the
/// run folder for image sequences, the `.cine` inside it otherwise.
pub fn run_input_path(run: &str, format: FrameFormat) -> PathBuf {
    match format {
        FrameFormat::Cine => Path::new(run).join(format!("{run}.cine")),
        FrameFormat::Tiff | FrameFormat::Png | FrameFormat::Jpeg => PathBuf::from(run),
    }
}

/// `<run>_NNNNNN.<ext>`, or `<run>_-NNNNNN.<ext>` for a negative image number.
pub fn frame_file_name(run: &str, image_no: i64, format: FrameFormat) -> String {
    let ext = format.extension();
    if image_no < 0 {
        format!("{run}_-{:06}.{ext}", image_no.unsigned_abs())
    } else {
        format!("{run}_{image_no:06}.{ext}")
    }
}

/// Encode one frame: 8-bit grey for `bit_depth` 8, else 16-bit grey holding
/// the values as they are (12-bit data stays 0‥4095, LSB-aligned). JPEG
/// (8-bit only) at `jpeg_quality` (1‥100).
pub fn encode_frame(
    frame: &Frame,
    format: FrameFormat,
    bit_depth: u8,
    jpeg_quality: u8,
) -> Result<Vec<u8>, image::ImageError> {
    let (h, w) = frame.dim();
    let (bytes, color): (Vec<u8>, _) = if bit_depth == 8 {
        (
            frame.iter().map(|&v| v.min(255) as u8).collect(),
            ExtendedColorType::L8,
        )
    } else {
        (
            frame.iter().flat_map(|v| v.to_ne_bytes()).collect(),
            ExtendedColorType::L16,
        )
    };
    let mut out = Vec::with_capacity(bytes.len() + 1024);
    let format = match format {
        FrameFormat::Cine => {
            return Err(image::ImageError::Unsupported(
                image::error::UnsupportedError::from_format_and_kind(
                    image::error::ImageFormatHint::Name("cine".into()),
                    image::error::UnsupportedErrorKind::GenericFeature(
                        "a .cine holds the whole movie: use CineSink".into(),
                    ),
                ),
            ))
        }
        f => f,
    };
    match format {
        FrameFormat::Tiff => TiffEncoder::new(Cursor::new(&mut out))
            .write_image(&bytes, w as u32, h as u32, color)?,
        FrameFormat::Png => {
            PngEncoder::new_with_quality(&mut out, CompressionType::Fast, FilterType::Adaptive)
                .write_image(&bytes, w as u32, h as u32, color)?
        }
        FrameFormat::Jpeg => JpegEncoder::new_with_quality(&mut out, jpeg_quality)
            .write_image(&bytes, w as u32, h as u32, color)?,
        FrameFormat::Cine => unreachable!("handled above"),
    }
    Ok(out)
}

/// Where the frames of one run go, in batches of ascending image numbers.
pub trait FrameSink: Send {
    /// Store `frames` (`(image number, frame)`, ascending, continuing the
    /// previous batch).
    fn write_batch(&mut self, frames: &[(i64, Frame)]) -> Result<(), ExportError>;
    /// Complete the output (a movie container writes its index here).
    fn finish(self: Box<Self>) -> Result<(), ExportError>;
}

/// The whole movie in one `.cine`, streamed frame by frame through the
/// loader's [`CineWriter`](crate::source::cine_write::CineWriter) (written to
/// a temporary file and moved into place by `finish`).
pub struct CineSink {
    path: PathBuf,
    writer: crate::source::cine_write::CineWriter,
    /// P10: each 12-bit frame is written as its log-encoded codes (in `coded`).
    p10: bool,
    coded: Frame,
}

impl CineSink {
    /// Create `path` for the movie `header` describes: 8-bit samples, or
    /// 16-bit containers for deeper data, or the packed layouts of
    /// `packing` (12-bit data only); time stamps n/fps from the trigger.
    pub fn create(
        path: &Path,
        header: &PccHeader,
        packing: CinePackingChoice,
    ) -> Result<Self, ExportError> {
        use crate::source::cine_write::{CinePacking, CineSpec, CineWriter};
        let (packing, bit_depth) = match (packing, header.bit_depth) {
            (CinePackingChoice::P10, _) => (CinePacking::P10, 10),
            (CinePackingChoice::P12l, _) => (CinePacking::P12L, 12),
            (CinePackingChoice::Unpacked, 8) => (CinePacking::Gray8, 8),
            (CinePackingChoice::Unpacked, b) => (CinePacking::Gray16, b),
        };
        let spec = CineSpec {
            width: header.width_px,
            height: header.height_px,
            frame_count: header.image_count,
            packing,
            bit_depth,
            fps: header.fps,
            exposure_s: header.exposure_s,
            first_image_no: header.first_image_no as i32,
            trigger_unix_s: (header.trigger_10ns.div_euclid(TICKS_PER_S)) as u32,
            timestamps_s: None,
            ..CineSpec::default()
        };
        let writer = CineWriter::create(path, &spec).map_err(|e| ExportError::Encode {
            path: path.to_path_buf(),
            frame: header.first_image_no,
            message: e.to_string(),
        })?;
        Ok(CineSink {
            path: path.to_path_buf(),
            writer,
            p10: packing == CinePacking::P10,
            coded: Frame::zeros((0, 0)),
        })
    }
}

impl FrameSink for CineSink {
    fn write_batch(&mut self, frames: &[(i64, Frame)]) -> Result<(), ExportError> {
        for (n, frame) in frames {
            let frame = if self.p10 {
                if self.coded.dim() != frame.dim() {
                    self.coded = Frame::zeros(frame.dim());
                }
                self.coded.zip_mut_with(frame, |c, &v| {
                    *c = crate::source::cine_write::p10_code_of_linear12(v)
                });
                &self.coded
            } else {
                frame
            };
            self.writer
                .write_frame(frame)
                .map_err(|e| ExportError::Encode {
                    path: self.path.clone(),
                    frame: *n,
                    message: e.to_string(),
                })?;
        }
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<(), ExportError> {
        let path = self.path.clone();
        self.writer.finish().map_err(|e| ExportError::Encode {
            path,
            frame: 0,
            message: e.to_string(),
        })
    }
}

/// One image file per frame in the run folder, encoded and written in parallel.
pub struct FolderSink {
    dir: PathBuf,
    run: String,
    format: FrameFormat,
    bit_depth: u8,
    jpeg_quality: u8,
}

impl FolderSink {
    /// `jpeg_quality` (1‥100) is used by JPEG frames only.
    pub fn new(
        dir: &Path,
        run: &str,
        format: FrameFormat,
        bit_depth: u8,
        jpeg_quality: u8,
    ) -> Self {
        FolderSink {
            dir: dir.to_path_buf(),
            run: run.to_string(),
            format,
            bit_depth,
            jpeg_quality,
        }
    }
}

impl FrameSink for FolderSink {
    fn write_batch(&mut self, frames: &[(i64, Frame)]) -> Result<(), ExportError> {
        frames.par_iter().try_for_each(|(n, frame)| {
            let path = self.dir.join(frame_file_name(&self.run, *n, self.format));
            let bytes = encode_frame(frame, self.format, self.bit_depth, self.jpeg_quality)
                .map_err(|e| ExportError::Encode {
                    path: path.clone(),
                    frame: *n,
                    message: e.to_string(),
                })?;
            // Frames are renamed into place whole but not synced one by one
            // (a sync per file cost more than rendering the frame).
            write_atomic_unsynced(&path, &bytes).map_err(|source| ExportError::Io { path, source })
        })
    }

    fn finish(self: Box<Self>) -> Result<(), ExportError> {
        Ok(())
    }
}

/// What the PCC XML side file states about a run.
#[derive(Debug, Clone, PartialEq)]
pub struct PccHeader {
    /// Shown in `CameraSetup/Description`.
    pub description: String,
    /// Image number of the first frame (negative before the trigger).
    pub first_image_no: i64,
    /// Number of frames.
    pub image_count: usize,
    /// Frame width, px.
    pub width_px: usize,
    /// Frame height, px.
    pub height_px: usize,
    /// 8 or 12.
    pub bit_depth: u8,
    /// Frame rate, frames/s.
    pub fps: f64,
    /// Exposure time of each frame, s.
    pub exposure_s: f64,
    /// Trigger instant, in units of 10 ns since 1970-01-01 00:00 local time.
    pub trigger_10ns: i64,
}

/// The PCC XML template (structure of a real SW 800 export, `cam_1.xml` of
/// the samples) with `{{Name}}` placeholders.
const PCC_TEMPLATE: &str = include_str!("pcc_chd_template.xml");

/// Ten-nanosecond ticks per second.
const TICKS_PER_S: i64 = 100_000_000;

/// The time stamp of image `n`: `trigger + n / fps`, in 10 ns ticks. The
/// renderer's convention is that this is the frame's mid-exposure time.
pub fn frame_time_10ns(h: &PccHeader, n: i64) -> i64 {
    h.trigger_10ns + (n as f64 * TICKS_PER_S as f64 / h.fps).round() as i64
}

/// The side file `<run>.xml`, element for element like a real PCC export
/// (formats/phantom.md §12.4): one line after the prolog, root `<chd>`,
/// `TIMEBLOCK` with `<Date frame="n">` and `<Time frame="n">HH:MM:SS.mmm uuu.uu</Time>`
/// per image, `EXPOSUREBLOCK` with `<Exp frame="n">` in µs. The data are
/// stored as they are: `BlackLevel` 0, `WhiteLevel` 2^bits − 1.
pub fn pcc_xml(h: &PccHeader) -> String {
    let bits = u32::from(h.bit_depth);
    let container_bits = if h.bit_depth == 8 { 8 } else { 16 };
    let white = (1u64 << bits) - 1;
    let shutter_ns = (h.exposure_s * 1e9).round() as i64;
    let exp_us = format!("{:.3}", h.exposure_s * 1e6);
    let mut timeblock = String::with_capacity(h.image_count * 90);
    let mut expblock = String::with_capacity(h.image_count * 40);
    for k in 0..h.image_count {
        let n = h.first_image_no + k as i64;
        let t = frame_time_10ns(h, n);
        timeblock.push_str(&format!(
            "<Date frame=\"{n}\">{}</Date><Time frame=\"{n}\">{}</Time>",
            pcc_date(t),
            pcc_time(t)
        ));
        expblock.push_str(&format!("<Exp frame=\"{n}\">{exp_us}</Exp>"));
    }
    let last = h.first_image_no + h.image_count as i64 - 1;
    let values: [(&str, String); 33] = [
        ("FirstMovieImage", h.first_image_no.to_string()),
        ("TotalImageCount", h.image_count.to_string()),
        ("FirstImageNo", h.first_image_no.to_string()),
        ("ImageCount", h.image_count.to_string()),
        ("TriggerDate", pcc_date(h.trigger_10ns)),
        ("TriggerTime", pcc_time(h.trigger_10ns)),
        ("biWidth", h.width_px.to_string()),
        ("biHeight", h.height_px.to_string()),
        ("biBitCount", container_bits.to_string()),
        (
            "biSizeImage",
            (h.width_px * h.height_px * container_bits / 8).to_string(),
        ),
        // Phantom v7.3 pixel pitch 22 µm → 45 455 px/m.
        ("biXPelsPerMeter", "45455".to_string()),
        ("biYPelsPerMeter", "45455".to_string()),
        ("biClrImportant", (white + 1).to_string()),
        ("ImWidth", h.width_px.to_string()),
        ("ImHeight", h.height_px.to_string()),
        ("FrameRateDouble", format!("{}", h.fps)),
        ("PostTrigger", (last.max(0) + 1).to_string()),
        ("RecordingTimeZone", "0".to_string()),
        ("RealBPP", bits.to_string()),
        ("Conv8Max", white.to_string()),
        ("CalibWidth", h.width_px.to_string()),
        ("CalibHeight", h.height_px.to_string()),
        ("CalibRate", format!("{}", h.fps.round())),
        ("CalibExp", shutter_ns.to_string()),
        ("ShutterNs", shutter_ns.to_string()),
        ("ImWidthAcq", h.width_px.to_string()),
        ("ImHeightAcq", h.height_px.to_string()),
        ("Description", xml_escape(&h.description)),
        ("BlackLevel", "0".to_string()),
        ("WhiteLevel", white.to_string()),
        ("ResampleWidth", h.width_px.to_string()),
        ("ResampleHeight", h.height_px.to_string()),
        ("fGain16_8", "1.000000".to_string()),
    ];
    let mut s = PCC_TEMPLATE.to_string();
    for (name, v) in values.iter() {
        s = s.replace(&format!("{{{{{name}}}}}"), v);
    }
    let crop = [
        ("CropLeft", h.width_px / 2),
        ("CropRight", (h.width_px / 2).saturating_sub(1)),
        ("CropTop", h.height_px / 2),
        ("CropBottom", (h.height_px / 2).saturating_sub(1)),
    ];
    for (name, v) in crop {
        s = s.replace(&format!("{{{{{name}}}}}"), &v.to_string());
    }
    s = s.replace("{{TIMEBLOCK}}", &timeblock);
    s.replace("{{EXPOSUREBLOCK}}", &expblock)
}

fn xml_escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Days since 1970-01-01 → (year, month 1‥12, day 1‥31), proleptic Gregorian
/// (the "civil from days" algorithm of H. Hinnant).
fn civil_from_days(z: i64) -> (i64, u32, u32) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let y = yoe + era * 400 + i64::from(m <= 2);
    (y, m, d)
}

/// Days since 1970-01-01 → (year, month, day) for a calendar date (inverse of
/// `civil_from_days`).
pub fn days_from_civil(y: i64, m: u32, d: u32) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y.rem_euclid(400);
    let m = i64::from(m);
    let doy = (153 * (if m > 2 { m - 3 } else { m + 9 }) + 2) / 5 + i64::from(d) - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

const TICKS_PER_DAY: i64 = 86_400 * TICKS_PER_S;

/// PCC's date: `Thu Jun 13 2019`.
pub fn pcc_date(t_10ns: i64) -> String {
    const WEEKDAYS: [&str; 7] = ["Sun", "Mon", "Tue", "Wed", "Thu", "Fri", "Sat"];
    const MONTHS: [&str; 12] = [
        "Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct", "Nov", "Dec",
    ];
    let days = t_10ns.div_euclid(TICKS_PER_DAY);
    let (y, m, d) = civil_from_days(days);
    // 1970-01-01 was a Thursday.
    let wd = (days + 4).rem_euclid(7) as usize;
    format!("{} {} {:02} {}", WEEKDAYS[wd], MONTHS[m as usize - 1], d, y)
}

/// PCC's time of day: `HH:MM:SS.mmm uuu.uu` (milliseconds, then the
/// microseconds within the millisecond to 10 ns).
pub fn pcc_time(t_10ns: i64) -> String {
    let tod = t_10ns.rem_euclid(TICKS_PER_DAY);
    let s = tod / TICKS_PER_S;
    let sub = tod % TICKS_PER_S; // 10 ns ticks within the second
    let ms = sub / 100_000;
    let within_ms = sub % 100_000; // 10 ns ticks within the millisecond
    format!(
        "{:02}:{:02}:{:02}.{:03} {:03}.{:02}",
        s / 3600,
        (s / 60) % 60,
        s % 60,
        ms,
        within_ms / 100,
        within_ms % 100
    )
}

/// Write `truth.json` (pretty, keys in schema order, trailing newline).
pub fn write_truth(path: &Path, truth: &Truth) -> Result<(), ExportError> {
    let mut text = serde_json::to_string_pretty(truth).map_err(|e| ExportError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(e),
    })?;
    text.push('\n');
    write_atomic(path, text.as_bytes()).map_err(|source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Write the XML side file.
pub fn write_pcc_xml(path: &Path, header: &PccHeader) -> Result<(), ExportError> {
    write_atomic(path, pcc_xml(header).as_bytes()).map_err(|source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pcc_time_and_date_match_the_real_files_format() {
        // 12bpp.xml: trigger "Sat Aug 24 2019" "14:53:32.338 196.00"
        let day = days_from_civil(2019, 8, 24);
        let t =
            day * TICKS_PER_DAY + (14 * 3600 + 53 * 60 + 32) * TICKS_PER_S + 338 * 100_000 + 19_600;
        assert_eq!(pcc_date(t), "Sat Aug 24 2019");
        assert_eq!(pcc_time(t), "14:53:32.338 196.00");
        // packed_10.xml: "14:18:53.225 065.54" keeps the zero padding
        let t2 = day * TICKS_PER_DAY + (14 * 3600 + 18 * 60 + 53) * TICKS_PER_S + 22_506_554;
        assert_eq!(pcc_time(t2), "14:18:53.225 065.54");
        // before the epoch and across midnight backwards
        assert_eq!(pcc_date(-1), "Wed Dec 31 1969");
        assert_eq!(pcc_time(-1), "23:59:59.999 999.99");
        assert_eq!(days_from_civil(1970, 1, 1), 0);
        assert_eq!(civil_from_days(days_from_civil(2000, 2, 29)), (2000, 2, 29));
    }

    #[test]
    fn negative_image_numbers_keep_their_sign_in_file_names() {
        assert_eq!(
            frame_file_name("a", -30, FrameFormat::Tiff),
            "a_-000030.tif"
        );
        assert_eq!(frame_file_name("a", 7, FrameFormat::Png), "a_000007.png");
    }
}
