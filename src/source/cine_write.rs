//! A `.cine` writer for grey movies: 8-bit, 16-bit (any RealBPP up to 16),
//! packed P10 and P12L — the layout every public reader accepts
//! (formats/phantom.md §13.3).
//!
//! The file is streamed: [`CineWriter::create`] writes the headers, the tagged
//! blocks (1002 time stamps, 1003 exposures) and the image offset table (all
//! sizes are known from the [`CineSpec`]), then each [`CineWriter::write_frame`]
//! appends one image, and [`CineWriter::finish`] renames the finished file into
//! place — a reader never sees a half-written cine.
//!
//! ```no_run
//! use dropscope::source::cine_write::{CinePacking, CineSpec, CineWriter};
//! let spec = CineSpec { width: 64, height: 32, frame_count: 2, ..CineSpec::default() };
//! let mut w = CineWriter::create("out.cine".as_ref(), &spec)?;
//! let frame = ndarray::Array2::<u16>::zeros((32, 64));
//! w.write_frame(&frame)?;
//! w.write_frame(&frame)?;
//! w.finish()?;
//! # Ok::<(), dropscope::source::cine_write::CineWriteError>(())
//! ```

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use super::p10_lut::P10_TO_LINEAR12;
use super::packing::{pack_msb, packed_span};
use super::Frame;

/// The P10 code whose linear value in Vision Research's table is nearest
/// the 12-bit value `v` (ties: the smaller code; values above 4095 as
/// 4095): what a camera saving P10 stores for `v`. Read back linearised
/// (`P10Mode::Linear`), a code gives its table value, within half a step
/// of `v` (1 count in the darks, up to 16 near white).
pub fn p10_code_of_linear12(v: u16) -> u16 {
    static TABLE: std::sync::OnceLock<Vec<u16>> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        (0..4096u16)
            .map(|v| {
                let lut = &P10_TO_LINEAR12;
                let i = lut.partition_point(|&x| x < v);
                let dist = |c: usize| lut[c].abs_diff(v);
                match (i.checked_sub(1), (i < lut.len()).then_some(i)) {
                    (Some(a), Some(b)) if dist(a) <= dist(b) => a as u16,
                    (_, Some(b)) => b as u16,
                    (Some(a), None) => a as u16,
                    (None, None) => 0,
                }
            })
            .collect()
    });
    table[usize::from(v.min(4095))]
}

/// SETUP.Length of the "modern" layout written (software 771, through SensorMode).
pub const SETUP_LENGTH: u16 = 10412;
const OFF_SETUP: usize = 84;

/// How the writer stores samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CinePacking {
    /// One byte per pixel, rows bottom-up (biBitCount 8).
    #[default]
    Gray8,
    /// Little-endian u16 per pixel, rows bottom-up (biBitCount 16).
    Gray16,
    /// 10-bit MSB-first packed, rows top-down (biCompression 256).
    P10,
    /// 12-bit MSB-first packed, rows top-down (biCompression 1024).
    P12L,
}

impl CinePacking {
    fn bits(self) -> u32 {
        match self {
            CinePacking::Gray8 => 8,
            CinePacking::Gray16 => 16,
            CinePacking::P10 => 10,
            CinePacking::P12L => 12,
        }
    }
}

/// What to write. `bit_depth` is SETUP.RealBPP: 8 for Gray8, 9‥16 for
/// Gray16, 10 for P10, 12 for P12L; every sample must be below `2^bit_depth`.
#[derive(Debug, Clone, PartialEq)]
pub struct CineSpec {
    /// Frame width, px.
    pub width: usize,
    /// Frame height, px.
    pub height: usize,
    /// Number of frames that will be written (the offset table is sized by it).
    pub frame_count: usize,
    /// How the samples are packed in the file.
    pub packing: CinePacking,
    /// Significant bits per sample (SETUP.RealBPP).
    pub bit_depth: u8,
    /// Frames per second of the saved frames (written as dFrameRate, FrameRate, FrameRate16).
    pub fps: f64,
    /// Exposure per frame, seconds (ShutterNs, Shutter, tag 1003); must be < 1 s.
    pub exposure_s: f64,
    /// Image number of the first frame (negative = before the trigger).
    pub first_image_no: i32,
    /// Trigger time, whole seconds since 1970-01-01 UTC (TIME64 seconds).
    pub trigger_unix_s: u32,
    /// Per-frame times relative to the trigger (tag 1002); default
    /// `(first_image_no + i) / fps`.
    pub timestamps_s: Option<Vec<f64>>,
    /// SETUP.bFlipV (a viewer flip; pixels are stored as given regardless).
    pub flip_v: bool,
    /// SETUP.CameraVersion (73 = Phantom v7.3).
    pub camera_version: u32,
}

impl Default for CineSpec {
    fn default() -> Self {
        CineSpec {
            width: 512,
            height: 384,
            frame_count: 1,
            packing: CinePacking::Gray8,
            bit_depth: 8,
            fps: 10_000.0,
            exposure_s: 50e-6,
            first_image_no: 0,
            trigger_unix_s: 1_560_000_000,
            timestamps_s: None,
            flip_v: false,
            camera_version: 73,
        }
    }
}

/// Why a cine could not be written.
#[derive(Debug, thiserror::Error)]
pub enum CineWriteError {
    /// The file could not be created or written.
    #[error("{path}: {source}")]
    Io {
        /// The cine being written.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The [`CineSpec`] asks for something the format cannot hold.
    #[error("{path}: cannot write this cine: {reason}")]
    Spec {
        /// The cine being written.
        path: PathBuf,
        /// What cannot be written, and why.
        reason: String,
    },
    /// A frame does not fit the spec (its shape, a sample too large, one frame too many).
    #[error("{path}: frame {index}: {reason}")]
    Frame {
        /// The cine being written.
        path: PathBuf,
        /// The frame's index, 0-based, in the order written.
        index: usize,
        /// What is wrong with it.
        reason: String,
    },
}

/// Streams frames into a `.cine` (see the module documentation).
pub struct CineWriter {
    path: PathBuf,
    tmp: PathBuf,
    out: Option<BufWriter<File>>,
    spec: CineSpec,
    written: usize,
    image_bytes: usize,
    scratch: Vec<u8>,
    samples: Vec<u16>,
}

impl CineWriter {
    /// Check `spec`, create `path` (via a temporary beside it) and write
    /// everything up to the first image.
    pub fn create(path: &Path, spec: &CineSpec) -> Result<CineWriter, CineWriteError> {
        let bad = |reason: String| CineWriteError::Spec {
            path: path.to_path_buf(),
            reason,
        };
        validate(spec).map_err(bad)?;
        let header = header_bytes(spec).map_err(bad)?;
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        let name = path
            .file_name()
            .ok_or_else(|| bad("the path has no file name".into()))?;
        let tmp = dir.join(format!(
            ".{}.tmp{}",
            name.to_string_lossy(),
            std::process::id()
        ));
        let io = |source| CineWriteError::Io {
            path: path.to_path_buf(),
            source,
        };
        let mut out = BufWriter::with_capacity(1 << 20, File::create(&tmp).map_err(io)?);
        out.write_all(&header).map_err(io)?;
        Ok(CineWriter {
            path: path.to_path_buf(),
            tmp,
            out: Some(out),
            spec: spec.clone(),
            written: 0,
            image_bytes: image_bytes(spec),
            scratch: Vec::new(),
            samples: Vec::new(),
        })
    }

    /// Append the next frame (shape `(height, width)`, rows top-down).
    pub fn write_frame(&mut self, frame: &Frame) -> Result<(), CineWriteError> {
        let index = self.written;
        let spec = &self.spec;
        let frame_err = |reason: String| CineWriteError::Frame {
            path: self.path.clone(),
            index,
            reason,
        };
        if index >= spec.frame_count {
            return Err(frame_err(format!(
                "the spec announced {} frames",
                spec.frame_count
            )));
        }
        if frame.dim() != (spec.height, spec.width) {
            return Err(frame_err(format!(
                "shape {:?} differs from the spec's {}×{} (height × width)",
                frame.dim(),
                spec.height,
                spec.width
            )));
        }
        let max = (1u32 << spec.bit_depth) - 1;
        if let Some(v) = frame.iter().find(|&&v| u32::from(v) > max) {
            return Err(frame_err(format!(
                "value {v} exceeds the {}-bit range (max {max})",
                spec.bit_depth
            )));
        }
        self.scratch.clear();
        self.scratch.extend_from_slice(&8u32.to_le_bytes());
        self.scratch
            .extend_from_slice(&(self.image_bytes as u32).to_le_bytes());
        match spec.packing {
            CinePacking::Gray8 => {
                for row in frame.rows().into_iter().rev() {
                    self.scratch.extend(row.iter().map(|&v| v as u8));
                }
            }
            CinePacking::Gray16 => {
                for row in frame.rows().into_iter().rev() {
                    for &v in row {
                        self.scratch.extend_from_slice(&v.to_le_bytes());
                    }
                }
            }
            CinePacking::P10 | CinePacking::P12L => {
                self.samples.clear();
                self.samples.extend(frame.iter().copied());
                pack_msb(&self.samples, spec.packing.bits(), &mut self.scratch);
            }
        }
        let out = self
            .out
            .as_mut()
            .ok_or_else(|| frame_err("writer already finished".into()))?;
        out.write_all(&self.scratch)
            .map_err(|source| CineWriteError::Io {
                path: self.path.clone(),
                source,
            })?;
        self.written += 1;
        Ok(())
    }

    /// Check every announced frame was written, flush, sync and move the file
    /// into place.
    pub fn finish(mut self) -> Result<(), CineWriteError> {
        if self.written != self.spec.frame_count {
            return Err(CineWriteError::Spec {
                path: self.path.clone(),
                reason: format!(
                    "{} frames written but the spec announced {}",
                    self.written, self.spec.frame_count
                ),
            });
        }
        let io = |source| CineWriteError::Io {
            path: self.path.clone(),
            source,
        };
        if let Some(out) = self.out.take() {
            let file = out.into_inner().map_err(|e| io(e.into_error()))?;
            file.sync_all().map_err(io)?;
        }
        std::fs::rename(&self.tmp, &self.path).map_err(io)
    }
}

impl Drop for CineWriter {
    fn drop(&mut self) {
        // An unfinished writer leaves no temporary behind.
        if self.out.take().is_some() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

fn validate(spec: &CineSpec) -> Result<(), String> {
    let (w, h) = (spec.width, spec.height);
    if w == 0 || h == 0 || w > 65535 || h > 65535 {
        return Err(format!("size {w}×{h} must be 1‥65535 in each direction"));
    }
    if spec.frame_count == 0 || spec.frame_count > 50_000_000 {
        return Err(format!("frame_count {} must be 1‥5e7", spec.frame_count));
    }
    let ok_depth = match spec.packing {
        CinePacking::Gray8 => spec.bit_depth == 8,
        CinePacking::Gray16 => (9..=16).contains(&spec.bit_depth),
        CinePacking::P10 => spec.bit_depth == 10,
        CinePacking::P12L => spec.bit_depth == 12,
    };
    if !ok_depth {
        return Err(format!(
            "bit_depth {} does not fit packing {:?} (Gray8: 8, Gray16: 9‥16, P10: 10, P12L: 12)",
            spec.bit_depth, spec.packing
        ));
    }
    if !(spec.fps.is_finite() && spec.fps > 0.0) {
        return Err(format!("fps {} must be positive", spec.fps));
    }
    if !(spec.exposure_s.is_finite() && spec.exposure_s > 0.0 && spec.exposure_s < 1.0) {
        return Err(format!(
            "exposure_s {} must be in (0, 1) s",
            spec.exposure_s
        ));
    }
    if let Some(t) = &spec.timestamps_s {
        if t.len() != spec.frame_count {
            return Err(format!(
                "{} timestamps for {} frames",
                t.len(),
                spec.frame_count
            ));
        }
    }
    let image = image_bytes(spec) as u64;
    if image + 8 > u64::from(u32::MAX) {
        return Err("one image would exceed 4 GB".into());
    }
    Ok(())
}

fn image_bytes(spec: &CineSpec) -> usize {
    packed_span(0, (spec.width * spec.height) as u64, spec.packing.bits()) as usize
}

fn put_u16(b: &mut [u8], off: usize, v: u16) {
    b[off..off + 2].copy_from_slice(&v.to_le_bytes());
}
fn put_u32(b: &mut [u8], off: usize, v: u32) {
    b[off..off + 4].copy_from_slice(&v.to_le_bytes());
}
fn put_i32(b: &mut [u8], off: usize, v: i32) {
    b[off..off + 4].copy_from_slice(&v.to_le_bytes());
}
fn put_text(b: &mut [u8], off: usize, len: usize, text: &str) {
    let t = text.as_bytes();
    let n = t.len().min(len - 1);
    b[off..off + n].copy_from_slice(&t[..n]);
}

/// TIME64 of `trigger + rel_s`, as the LE u64 `seconds<<32 | fractions`.
/// The two flag bits of the fraction are set to 3 as in real files
/// (not IRIG-synchronised, no event; §10).
fn time64(trigger_unix_s: u32, rel_s: f64) -> u64 {
    let ticks = (i128::from(trigger_unix_s) << 32) + (rel_s * 4_294_967_296.0).round() as i128;
    let ticks = ticks.clamp(0, i128::from(u64::MAX)) as u64;
    (ticks & !3) | 3
}

/// Everything before the first image: header, bitmap header, SETUP,
/// tagged blocks 1002 + 1003, offset table.
fn header_bytes(spec: &CineSpec) -> Result<Vec<u8>, String> {
    let n = spec.frame_count;
    let setup_len = usize::from(SETUP_LENGTH);
    let blocks = (8 + 8 * n) + (8 + 4 * n);
    let off_offsets = OFF_SETUP + setup_len + blocks;
    if off_offsets > u32::MAX as usize {
        return Err("too many frames for the header".into());
    }
    let first_image = off_offsets + 8 * n;
    let mut b = vec![0u8; first_image];
    // CINEFILEHEADER
    b[0..2].copy_from_slice(b"CI");
    put_u16(&mut b, 2, 44);
    put_u16(&mut b, 4, 0);
    put_u16(&mut b, 6, 1);
    put_i32(&mut b, 8, spec.first_image_no);
    put_u32(&mut b, 12, n as u32);
    put_i32(&mut b, 16, spec.first_image_no);
    put_u32(&mut b, 20, n as u32);
    put_u32(&mut b, 24, 44);
    put_u32(&mut b, 28, OFF_SETUP as u32);
    put_u32(&mut b, 32, off_offsets as u32);
    put_u32(&mut b, 36, 0);
    put_u32(&mut b, 40, spec.trigger_unix_s);
    // BITMAPINFOHEADER
    let bi = 44;
    let image = image_bytes(spec) as u32;
    put_u32(&mut b, bi, 40);
    put_i32(&mut b, bi + 4, spec.width as i32);
    put_i32(&mut b, bi + 8, spec.height as i32);
    put_u16(&mut b, bi + 12, 1);
    put_u16(
        &mut b,
        bi + 14,
        if spec.packing == CinePacking::Gray8 {
            8
        } else {
            16
        },
    );
    let compression = match spec.packing {
        CinePacking::P10 => 256,
        CinePacking::P12L => 1024,
        _ => 0,
    };
    put_u32(&mut b, bi + 16, compression);
    put_u32(&mut b, bi + 20, image);
    put_i32(&mut b, bi + 24, 45454);
    put_i32(&mut b, bi + 28, 45454);
    put_u32(&mut b, bi + 36, 1u32 << spec.bit_depth);
    // SETUP (offsets: formats/phantom.md Appendix A)
    let st = OFF_SETUP;
    let fps_u32 = spec.fps.round().min(f64::from(u32::MAX)) as u32;
    let shutter_us = (spec.exposure_s * 1e6).round() as u32;
    let shutter_ns = (spec.exposure_s * 1e9).round() as u32;
    put_u16(&mut b, st, fps_u32.min(65535) as u16);
    put_u16(&mut b, st + 2, shutter_us.min(65535) as u16);
    b[st + 140..st + 142].copy_from_slice(b"ST");
    put_u16(&mut b, st + 142, SETUP_LENGTH);
    put_i32(&mut b, st + 429, -100);
    put_u32(&mut b, st + 433, 1000);
    put_u16(&mut b, st + 737, spec.width as u16);
    put_u16(&mut b, st + 739, spec.height as u16);
    put_i32(&mut b, st + 760, i32::from(spec.flip_v));
    put_u32(&mut b, st + 768, fps_u32);
    put_u32(&mut b, st + 772, shutter_us);
    put_u32(&mut b, st + 792, spec.camera_version);
    put_u32(&mut b, st + 796, 1);
    put_u32(&mut b, st + 800, 771);
    put_u32(&mut b, st + 808, 0);
    put_u32(&mut b, st + 896, u32::from(spec.bit_depth));
    put_u32(&mut b, st + 1568, shutter_ns);
    put_i32(&mut b, st + 5732, 0);
    put_i32(&mut b, st + 5736, (1i32 << spec.bit_depth) - 1);
    put_u32(&mut b, st + 6012, 1.0f32.to_bits()); // fGain
    put_u32(&mut b, st + 6024, 1.0f32.to_bits()); // fGamma
    put_text(&mut b, st + 9856, 256, "dropscope");
    put_u32(&mut b, st + 10112, u32::from(spec.bit_depth));
    put_text(&mut b, st + 10128, 256, "dropscope synthetic");
    put_u32(&mut b, st + 10388, 1.0f32.to_bits()); // fDecimation
    b[st + 10400..st + 10408].copy_from_slice(&spec.fps.to_bits().to_le_bytes());
    // Tagged blocks: 1002 (Reserved 1 = more follow), 1003 (Reserved 0 = last).
    let mut p = OFF_SETUP + setup_len;
    put_u32(&mut b, p, (8 + 8 * n) as u32);
    put_u16(&mut b, p + 4, 1002);
    put_u16(&mut b, p + 6, 1);
    p += 8;
    for i in 0..n {
        let rel = match &spec.timestamps_s {
            Some(t) => t[i],
            None => (f64::from(spec.first_image_no) + i as f64) / spec.fps,
        };
        b[p..p + 8].copy_from_slice(&time64(spec.trigger_unix_s, rel).to_le_bytes());
        p += 8;
    }
    put_u32(&mut b, p, (8 + 4 * n) as u32);
    put_u16(&mut b, p + 4, 1003);
    put_u16(&mut b, p + 6, 0);
    p += 8;
    let exp = (spec.exposure_s * 4_294_967_296.0).round() as u32;
    for _ in 0..n {
        put_u32(&mut b, p, exp);
        p += 4;
    }
    debug_assert_eq!(p, off_offsets);
    for i in 0..n {
        let off = (first_image + i * (8 + image as usize)) as u64;
        b[p..p + 8].copy_from_slice(&off.to_le_bytes());
        p += 8;
    }
    Ok(b)
}
