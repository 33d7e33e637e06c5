//! [`PhotronSource`]: the frames of a Photron `.mraw`, described by the
//! `.cihx` or `.cih` of the same name beside it (see [`super`] for the
//! layout and [`super::cih`] for the header).
//!
//! Opening reads the header and checks that the MRAW holds every frame it
//! announces: a file cut short is an error naming it and the first frame
//! that does not fit, before any pixel is read. Frames (or bands of rows)
//! are read on demand with positioned reads, so copies of a source share
//! nothing but the file.

use std::fs::File;
use std::path::{Path, PathBuf};

use ndarray::ArrayViewMut2;

use super::cih::{self, BitSide, Cih};
use crate::source::{
    check_band, fill_rows, grown, FrameNumbers, FrameSource, OpenOptions, SourceDetails,
    SourceError, SourceMeta,
};
use crate::util::io::read_at;

/// The extensions of a Photron header, preferred first.
const HEADER_EXTENSIONS: [&str; 2] = ["cihx", "cih"];

/// Whether `path`'s extension is `.mraw`, `.cihx` or `.cih` (any case).
pub fn is_photron_name(path: &Path) -> bool {
    path.extension().and_then(|e| e.to_str()).is_some_and(|e| {
        e.eq_ignore_ascii_case("mraw")
            || HEADER_EXTENSIONS.iter().any(|h| e.eq_ignore_ascii_case(h))
    })
}

/// The file beside `path` with the same stem and extension `ext` (any case), if there.
fn sibling(path: &Path, ext: &str) -> Option<PathBuf> {
    let stem = path.file_stem()?.to_str()?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    [ext.to_string(), ext.to_ascii_uppercase()]
        .iter()
        .map(|e| dir.join(format!("{stem}.{e}")))
        .find(|p| p.is_file())
        .or_else(|| {
            // Mixed case (`Ball.Cihx`): look through the folder.
            std::fs::read_dir(dir)
                .ok()?
                .flatten()
                .map(|e| e.path())
                .find(|p| {
                    p.file_stem().and_then(|s| s.to_str()) == Some(stem)
                        && p.extension()
                            .and_then(|e| e.to_str())
                            .is_some_and(|e| e.eq_ignore_ascii_case(ext))
                        && p.is_file()
                })
        })
}

/// The MRAW and its header for `path`, either of the two.
pub fn pair(path: &Path) -> Result<(PathBuf, PathBuf), SourceError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let missing = |reason: String| SourceError::Format {
        path: path.to_path_buf(),
        reason,
    };
    if ext == "mraw" {
        let header = HEADER_EXTENSIONS
            .iter()
            .find_map(|e| sibling(path, e))
            .ok_or_else(|| {
                missing(
                    "no .cihx or .cih of the same name beside it: the Photron header holds \
                     the frame size, bit depth and frame rate the MRAW cannot be read without"
                        .into(),
                )
            })?;
        Ok((path.to_path_buf(), header))
    } else {
        let mraw = sibling(path, "mraw").ok_or_else(|| {
            missing(
                "no .mraw of the same name beside this Photron header: the frames are in it".into(),
            )
        })?;
        Ok((mraw, path.to_path_buf()))
    }
}

/// A Photron MRAW opened for random access.
#[derive(Debug)]
pub struct PhotronSource {
    meta: SourceMeta,
    cih: std::sync::Arc<Cih>,
    file: File,
    options: OpenOptions,
    bytes: Vec<u8>,
    row_scratch: Vec<u16>,
}

impl PhotronSource {
    /// Open `path` (the `.mraw`, or its `.cihx`/`.cih`): read the header,
    /// check that the MRAW holds the frames it announces. No pixel is read.
    pub fn open(path: &Path, options: &OpenOptions) -> Result<Self, SourceError> {
        let (mraw, header) = pair(path)?;
        let io = |p: &Path| {
            let p = p.to_path_buf();
            move |source| SourceError::Io {
                path: p.clone(),
                source,
            }
        };
        let bytes = crate::util::io::read_bounded(&header, cih::MAX_HEADER_BYTES)
            .map_err(io(&header))?
            .ok_or_else(|| SourceError::Format {
                path: header.clone(),
                reason: format!(
                    "larger than {} MiB: not a Photron header",
                    cih::MAX_HEADER_BYTES >> 20
                ),
            })?;
        let cih =
            cih::parse(&bytes).map_err(|reason| match reason.strip_prefix("unsupported: ") {
                Some(r) => SourceError::Unsupported {
                    path: header.clone(),
                    reason: r.to_string(),
                },
                None => SourceError::Format {
                    path: header.clone(),
                    reason,
                },
            })?;
        let (file, len) = crate::util::io::open_regular_len(&mraw).map_err(io(&mraw))?;
        let frame_bytes = cih.frame_bytes();
        let need = frame_bytes.saturating_mul(cih.total_frames);
        let mut warnings = Vec::new();
        if len < need {
            let whole = len / frame_bytes;
            return Err(SourceError::Frame {
                path: mraw,
                index: whole as usize,
                reason: format!(
                    "image number {} ends at byte {} but the file has {len} bytes: truncated \
                     or corrupt ({} announces {} frames of {frame_bytes} bytes, {need} bytes)",
                    cih.start_frame + whole as i64,
                    (whole + 1) * frame_bytes,
                    header.display(),
                    cih.total_frames
                ),
            });
        }
        if len > need {
            warnings.push(format!(
                "{} bytes after the last of the {} frames the header announces are ignored",
                len - need,
                cih.total_frames
            ));
        }
        if cih.skip_frame > 1 {
            warnings.push(format!(
                "one frame saved of every {} recorded: frame numbers count the saved frames, \
                 at {} frames/s",
                cih.skip_frame,
                cih.saved_fps()
            ));
        }
        let n = usize::try_from(cih.total_frames).map_err(|_| SourceError::Format {
            path: header.clone(),
            reason: format!("{} frames is too many", cih.total_frames),
        })?;
        let apply = options.apply_flips && (cih.flip_h || cih.flip_v);
        let mut meta = SourceMeta {
            path: mraw.clone(),
            format: "mraw".into(),
            frame_count: n,
            width: cih.width as usize,
            height: cih.height as usize,
            bit_depth: cih.effective_bits as u8,
            fps: cih.saved_fps(),
            exposure_s: cih.exposure_s,
            first_frame: cih.start_frame,
            frame_numbers: FrameNumbers::consecutive(cih.start_frame, n),
            gaps: Vec::new(),
            timestamps_s: None,
            details: SourceDetails {
                container: cih.describe_storage(),
                black_level: None,
                white_level: None,
                flip_h: cih.flip_h,
                flip_v: cih.flip_v,
                rotate_deg: cih.rotate_deg.round() as i32,
                flips_applied: apply,
                exposures_s: None,
                acquisition_fps: Some(cih.record_rate_fps),
                decimation: f64::from(cih.skip_frame),
                camera: cih.camera.clone(),
                software_version: None,
                setup_length: None,
                side_file: Some(header),
                warnings,
                ..SourceDetails::default()
            },
        };
        crate::source::validate::check_meta(&mut meta)?;
        Ok(PhotronSource {
            meta,
            cih: cih.into(),
            file,
            options: options.clone(),
            bytes: Vec::new(),
            row_scratch: Vec::new(),
        })
    }

    /// The parsed header.
    pub fn cih(&self) -> &Cih {
        &self.cih
    }
}

impl FrameSource for PhotronSource {
    fn meta(&self) -> &SourceMeta {
        &self.meta
    }

    fn try_clone(&self) -> Option<Box<dyn FrameSource>> {
        Some(Box::new(PhotronSource {
            meta: self.meta.clone(),
            cih: self.cih.clone(),
            file: self.file.try_clone().ok()?,
            options: self.options.clone(),
            bytes: Vec::new(),
            row_scratch: Vec::new(),
        }))
    }

    fn read_rows_into(
        &mut self,
        index: usize,
        row0: usize,
        out: &mut ArrayViewMut2<u16>,
    ) -> Result<(), SourceError> {
        check_band(&self.meta, index, row0, out)?;
        let n = out.nrows();
        if n == 0 {
            return Ok(());
        }
        let (h, w) = (self.meta.height, self.meta.width);
        let flip_v = self.meta.details.flips_applied && self.cih.flip_v;
        let flip_h = self.meta.details.flips_applied && self.cih.flip_h;
        // The stored rows of the band: the same rows, or their mirror.
        let lo = if flip_v { h - row0 - n } else { row0 };
        let bits = u64::from(self.cih.container_bits);
        let first_bit = lo as u64 * w as u64 * bits;
        let end_bit = (lo + n) as u64 * w as u64 * bits;
        let (b0, b1) = (first_bit / 8, end_bit.div_ceil(8));
        let at = index as u64 * self.cih.frame_bytes() + b0;
        let buf = grown(&mut self.bytes, (b1 - b0) as usize);
        read_at(&self.file, at, buf).map_err(|e| SourceError::Frame {
            path: self.meta.path.clone(),
            index,
            reason: format!(
                "reading image number {}'s pixels at byte {at}: {e}",
                self.meta.frame_number(index)
            ),
        })?;
        let bytes = &self.bytes[..(b1 - b0) as usize];
        let shift = match self.cih.side {
            BitSide::Higher => self.cih.container_bits - self.cih.effective_bits,
            BitSide::Lower => 0,
        };
        let container = self.cih.container_bits;
        let row_bits = w as u64 * bits;
        let start_nibble = (first_bit % 8) as usize / 4;
        fill_rows(out, &mut self.row_scratch, |j, dst| {
            let k = if flip_v { n - 1 - j } else { j };
            match container {
                8 => {
                    for (d, s) in dst.iter_mut().zip(&bytes[k * w..(k + 1) * w]) {
                        *d = u16::from(*s);
                    }
                }
                16 => {
                    for (d, s) in dst.iter_mut().zip(bytes[2 * k * w..].chunks_exact(2)) {
                        *d = u16::from_le_bytes([s[0], s[1]]);
                    }
                }
                _ => {
                    // Row k starts `k·w·12` bits after the band's first bit.
                    let nibble = start_nibble + (k as u64 * row_bits / 4) as usize;
                    unpack12(&bytes[nibble / 2..], nibble % 2 == 1, dst);
                }
            }
            if shift > 0 {
                for v in dst.iter_mut() {
                    *v >>= shift;
                }
            }
            if flip_h {
                dst.reverse();
            }
        });
        Ok(())
    }
}

/// 12-bit samples packed two in three bytes, high nibble first:
/// `p0 = b0<<4 | b1>>4`, `p1 = (b1&0xF)<<8 | b2`. With `odd` the first
/// sample starts in the low nibble of `src[0]` (a row of an odd width).
/// `src` holds at least the `⌈(odd + 3·out.len())/2⌉` bytes needed.
fn unpack12(src: &[u8], odd: bool, out: &mut [u16]) {
    let mut out = out;
    let mut src = src;
    if odd {
        let Some((first, rest)) = out.split_first_mut() else {
            return;
        };
        *first = (u16::from(src[0] & 0x0F) << 8) | u16::from(src[1]);
        out = rest;
        src = &src[2..];
    }
    let pairs = out.len() / 2;
    for (o, s) in out.chunks_exact_mut(2).zip(src.chunks_exact(3)) {
        let (b0, b1, b2) = (u16::from(s[0]), u16::from(s[1]), u16::from(s[2]));
        o[0] = (b0 << 4) | (b1 >> 4);
        o[1] = ((b1 & 0x0F) << 8) | b2;
    }
    if out.len() % 2 == 1 {
        let s = &src[3 * pairs..];
        out[2 * pairs] = (u16::from(s[0]) << 4) | (u16::from(s[1]) >> 4);
    }
}

#[cfg(test)]
mod tests {
    use super::unpack12;

    /// Pack `v` as the format says, most significant nibble first.
    fn pack(v: &[u16]) -> Vec<u8> {
        let mut nibbles: Vec<u8> = v
            .iter()
            .flat_map(|&x| [(x >> 8) as u8 & 0xF, (x >> 4) as u8 & 0xF, x as u8 & 0xF])
            .collect();
        if nibbles.len() % 2 == 1 {
            nibbles.push(0);
        }
        nibbles.chunks(2).map(|c| (c[0] << 4) | c[1]).collect()
    }

    #[test]
    fn twelve_bit_samples_unpack_at_either_nibble_and_any_count() {
        let v: Vec<u16> = (0..11u16).map(|i| (i * 977 + 5) & 0xFFF).collect();
        let bytes = pack(&v);
        for start in 0..v.len() {
            for end in start..=v.len() {
                let mut out = vec![0u16; end - start];
                let nibble = 3 * start;
                unpack12(&bytes[nibble / 2..], nibble % 2 == 1, &mut out);
                assert_eq!(out, &v[start..end], "samples {start}..{end}");
            }
        }
        // The documented example: bytes AB CD EF → 0xABC, 0xDEF.
        let mut out = [0u16; 2];
        unpack12(&[0xAB, 0xCD, 0xEF], false, &mut out);
        assert_eq!(out, [0xABC, 0xDEF]);
    }
}
