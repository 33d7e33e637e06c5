//! Folders of numbered frames, as Phantom Camera Control exports them
//! (formats/phantom.md §12): `<prefix><number>.<ext>` with TIFF (8/16-bit,
//! any compression), PNG (8/16-bit), BMP (8-bit grey read as is) or JPEG,
//! plus PCC's XML side file for frame rate, exposure, bit depth and times.
//!
//! Naming: the number is the run of digits before the extension, negative
//! when the character before it is a `-` that is itself at the start of the
//! name or preceded by a non-alphanumeric character (`run_-00005.tif` is
//! −5, `run-00005.tif` is 5 with prefix `run-`). Numbers need not be
//! zero-padded and are sorted numerically. One sequence per folder: the
//! largest group of files sharing prefix and extension; files outside it
//! (notes, a stray `background.tif`) are ignored and listed in the warnings.
//! Missing numbers are reported as gaps; frame index `i` is the `i`-th file
//! present, and its time comes from its number, so a gap never shifts time.
//!
//! Every file's header is read when the folder is opened: a file whose size
//! or bit depth differs from the first frame's is an error naming it.
//!
//! Speed: uncompressed single-sample TIFFs are parsed here (a whole frame
//! with one read of the file into a reused buffer, a band of fewer than half
//! the rows by its first 4 KiB and the band's rows only); PNGs are
//! decoded row by row with the `png` crate into reused buffers and stop after
//! the last requested row; BMP 8-bit is parsed here; everything else goes
//! through the `image` crate.

use std::fs::File;
use std::io::{Cursor, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use ndarray::{s, ArrayViewMut2};

use super::pcc_xml::{self, PccXml};
use super::widen::widen_u8;
use super::{
    check_band, fill_row, fill_rows, Frame, FrameSource, OpenOptions, SourceDetails, SourceError,
    SourceMeta,
};

/// Image file kinds a folder may hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum ImageKind {
    Tiff,
    Png,
    Bmp,
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
    fn name(self) -> &'static str {
        match self {
            ImageKind::Tiff => "tiff",
            ImageKind::Png => "png",
            ImageKind::Bmp => "bmp",
            ImageKind::Jpeg => "jpeg",
        }
    }
}

/// Split a file name into `(prefix, number, kind)`, or `None` when it is not
/// a numbered image (see the module documentation for the sign rule).
pub fn parse_frame_name(name: &str) -> Option<(String, i64, ImageKind)> {
    let (stem, ext) = name.rsplit_once('.')?;
    let kind = ImageKind::from_extension(ext)?;
    let digits_start = stem
        .char_indices()
        .rev()
        .take_while(|(_, c)| c.is_ascii_digit())
        .last()
        .map(|(i, _)| i)?;
    let digits = &stem[digits_start..];
    if digits.len() > 18 {
        return None;
    }
    let value: i64 = digits.parse().ok()?;
    let before = &stem[..digits_start];
    let negative = before.strip_suffix('-').is_some_and(|rest| {
        rest.chars()
            .last()
            .is_none_or(|c| !c.is_ascii_alphanumeric())
    });
    if negative {
        Some((before[..before.len() - 1].to_string(), -value, kind))
    } else {
        Some((before.to_string(), value, kind))
    }
}

/// How one file's pixels are laid out, found by reading its header only.
#[derive(Debug, Clone, PartialEq)]
struct Probe {
    width: usize,
    height: usize,
    /// Container bits per sample: 8 or 16.
    bits: u8,
    layout: Layout,
}

#[derive(Debug, Clone, PartialEq)]
enum Layout {
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

/// Buffers reused from frame to frame: header bytes, IFD entries, strip
/// offsets, file bytes / rows read.
#[derive(Debug, Default)]
struct Scratch {
    head: Vec<u8>,
    entries: Vec<u8>,
    raw: Vec<u8>,
    strips: Vec<u64>,
    bytes: Vec<u8>,
    /// Grey value of each BMP palette index.
    palette: Vec<u8>,
    /// `head` holds the whole file (small TIFFs), not just its start.
    whole: bool,
    /// Read small TIFFs whole (frame reads) or only their headers (open).
    read_whole: bool,
    /// The current request is a band of fewer than half the rows: a TIFF
    /// is read by its header and the band's rows only, not whole.
    small_band: bool,
}

/// TIFFs up to this size are read with one call and decoded from memory.
const WHOLE_FILE_MAX: u64 = 16 << 20;

/// A folder of numbered frames opened for random access.
pub struct FolderSource {
    meta: SourceMeta,
    /// Shared by the copies of [`FrameSource::try_clone`].
    files: std::sync::Arc<[PathBuf]>,
    kind: ImageKind,
    /// Bits per sample of the files (8 or 16).
    container_bits: u8,
    scratch: Scratch,
    row_scratch: Vec<u16>,
    u16_scratch: Vec<u16>,
}

impl std::fmt::Debug for FolderSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FolderSource")
            .field("meta", &self.meta)
            .field("files", &self.files.len())
            .finish()
    }
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> SourceError + '_ {
    move |source| SourceError::Io {
        path: path.to_path_buf(),
        source,
    }
}

fn format_err(path: &Path, reason: impl Into<String>) -> SourceError {
    SourceError::Format {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

impl FolderSource {
    /// List `dir`, pick its frame sequence, read every file's header and the
    /// PCC XML side file if there is one.
    pub fn open(dir: &Path, options: &OpenOptions) -> Result<Self, SourceError> {
        let entries = std::fs::read_dir(dir).map_err(io_err(dir))?;
        let mut names = Vec::new();
        // Named pipes, sockets and devices are never opened (a pipe would
        // block `open` for ever); links are followed to what they name.
        let mut not_files = Vec::new();
        for e in entries {
            let e = e.map_err(io_err(dir))?;
            let Some(name) = e.file_name().to_str().map(str::to_string) else {
                continue;
            };
            // The entry's own type costs no system call; only a link is
            // followed to see what it names.
            let (is_dir, is_file) = match e.file_type() {
                Ok(t) if !t.is_symlink() => (t.is_dir(), t.is_file()),
                _ => match std::fs::metadata(e.path()) {
                    Ok(m) => (m.is_dir(), m.is_file()),
                    Err(_) => (false, false),
                },
            };
            if is_file {
                names.push(name);
            } else if !is_dir {
                not_files.push(name);
            }
        }
        names.sort();
        not_files.sort();
        // Group numbered images by (prefix, kind); pick the largest group.
        let mut groups: std::collections::BTreeMap<(String, ImageKind), Vec<(i64, String)>> =
            Default::default();
        let mut xmls = Vec::new();
        let mut others = Vec::new();
        for name in &names {
            if let Some((prefix, number, kind)) = parse_frame_name(name) {
                groups
                    .entry((prefix, kind))
                    .or_default()
                    .push((number, name.clone()));
            } else if name.to_ascii_lowercase().ends_with(".xml") {
                xmls.push(name.clone());
            } else {
                others.push(name.clone());
            }
        }
        let Some(best) = groups.values().map(Vec::len).max() else {
            let has_folders = std::fs::read_dir(dir)
                .is_ok_and(|entries| entries.flatten().any(|e| e.path().is_dir()));
            return Err(format_err(
                dir,
                if has_folders {
                    "no numbered frames (<prefix><number>.tif|png|bmp|jpg) in this folder, \
                     only sub-folders: give the run folders themselves, or list them in a \
                     runs.csv and use --manifest"
                } else {
                    "no numbered frames (<prefix><number>.tif|png|bmp|jpg) in this folder"
                },
            ));
        };
        let mut tied = groups.iter().filter(|(_, v)| v.len() == best);
        let ((prefix, kind), _) = tied.next().expect("a largest group exists");
        if let Some(((p2, k2), _)) = tied.next() {
            return Err(format_err(
                dir,
                format!(
                    "two frame sequences of {best} files each ({prefix:?}… {} files and \
                     {p2:?}… {} files): keep one sequence per folder",
                    kind.name(),
                    k2.name()
                ),
            ));
        }
        let (prefix, kind) = (prefix.clone(), *kind);
        let mut warnings = Vec::new();
        for ((p, k), v) in &groups {
            if (p, *k) != (&prefix, kind) {
                warnings.push(format!(
                    "ignored {} file(s) outside the sequence, e.g. {}",
                    v.len(),
                    v[0].1
                ));
            }
        }
        if !others.is_empty() {
            let shown: Vec<&str> = others.iter().take(5).map(String::as_str).collect();
            warnings.push(format!(
                "ignored {} non-frame file(s): {}{}",
                others.len(),
                shown.join(", "),
                if others.len() > 5 { ", …" } else { "" }
            ));
        }
        if !not_files.is_empty() {
            warnings.push(format!(
                "ignored {} entries that are not regular files (named pipes, sockets, \
                 devices or broken links), e.g. {}",
                not_files.len(),
                not_files[0]
            ));
        }
        let mut frames = groups.remove(&(prefix.clone(), kind)).unwrap_or_default();
        frames.sort();
        if let Some(w) = frames.windows(2).find(|w| w[0].0 == w[1].0) {
            return Err(format_err(
                &dir.join(&w[1].1),
                format!("frame number {} also belongs to {}", w[0].0, w[0].1),
            ));
        }
        let files: Vec<PathBuf> = frames.iter().map(|(_, n)| dir.join(n)).collect();
        let frame_numbers: Vec<i64> = frames.iter().map(|(n, _)| *n).collect();
        let gaps = gaps_of(&frame_numbers);

        // Every header: same size and depth as the first frame.
        // Headers only: opening must not read the movie.
        let mut scratch = Scratch::default();
        let (_, first) = open_and_probe(&files[0], kind, &mut scratch)?;
        // On every thread, in chunks; the first bad file in order is named,
        // as one thread would name it.
        use rayon::prelude::*;
        let bad = files[1..]
            .par_chunks(256)
            .map(|chunk| {
                let mut scratch = Scratch::default();
                for f in chunk {
                    match open_and_probe(f, kind, &mut scratch) {
                        Ok((_, p))
                            if (p.width, p.height, p.bits)
                                == (first.width, first.height, first.bits) => {}
                        Ok((_, p)) => return Some(Ok((f, p))),
                        Err(e) => return Some(Err(e)),
                    }
                }
                None
            })
            .find_first(Option::is_some)
            .flatten();
        if let Some(bad) = bad {
            let (f, p) = bad?;
            {
                return Err(format_err(
                    f,
                    format!(
                        "{}×{} {}-bit, but the sequence's first frame {} is {}×{} {}-bit: \
                         one size and bit depth per folder",
                        p.width,
                        p.height,
                        p.bits,
                        files[0].display(),
                        first.width,
                        first.height,
                        first.bits
                    ),
                ));
            }
        }

        // The PCC XML side file.
        let xml = pick_xml(dir, &prefix, &xmls, &mut warnings)?;
        let (xml_path, xml) = match xml {
            Some((p, x)) => (Some(p), Some(x)),
            None => (None, None),
        };
        let fps = match xml.as_ref().and_then(|x| x.fps) {
            Some(f) if f.is_finite() && f > 0.0 => f,
            _ => match options.fps_fallback {
                Some(f) if f.is_finite() && f > 0.0 => f,
                _ => {
                    return Err(SourceError::NoFrameRate {
                        path: dir.to_path_buf(),
                    })
                }
            },
        };
        // Bit depth: the XML's RealBPP when it fits the container, else the container's.
        let bit_depth = match xml.as_ref().and_then(|x| x.real_bpp) {
            Some(b) if (1..=first.bits).contains(&b) => b,
            _ => first.bits,
        };
        let timestamps_s = xml
            .as_ref()
            .and_then(|x| per_frame(&x.times, &frame_numbers));
        let exposures_s = xml
            .as_ref()
            .and_then(|x| per_frame(&x.exposures, &frame_numbers));
        if let Some(x) = &xml {
            if let Some(f0) = x.first_image_no {
                if x.image_count == Some(frame_numbers.len() as u64) && f0 != frame_numbers[0] {
                    warnings.push(format!(
                        "XML FirstImageNo {f0} differs from the first file number {}; \
                         file numbers are used",
                        frame_numbers[0]
                    ));
                }
            }
        }
        let meta = SourceMeta {
            path: dir.to_path_buf(),
            format: kind.name().into(),
            frame_count: files.len(),
            width: first.width,
            height: first.height,
            bit_depth,
            fps,
            exposure_s: xml.as_ref().and_then(|x| x.exposure_s),
            first_frame: frame_numbers[0],
            frame_numbers,
            gaps,
            timestamps_s,
            details: SourceDetails {
                container: format!("{} {}-bit", kind.name(), first.bits),
                black_level: xml.as_ref().and_then(|x| x.black_level),
                white_level: xml.as_ref().and_then(|x| x.white_level),
                flip_h: xml.as_ref().and_then(|x| x.flip_h).unwrap_or(false),
                flip_v: xml.as_ref().and_then(|x| x.flip_v).unwrap_or(false),
                rotate_deg: 0,
                flips_applied: false,
                exposures_s,
                acquisition_fps: None,
                decimation: 1.0,
                camera: None,
                software_version: None,
                setup_length: None,
                side_file: xml_path,
                warnings,
            },
        };
        scratch.read_whole = true;
        let mut src = FolderSource {
            meta,
            files: files.into(),
            kind,
            container_bits: first.bits,
            scratch,
            row_scratch: Vec::new(),
            u16_scratch: Vec::new(),
        };
        super::validate::check_meta(&mut src.meta)?;
        src.check_real_bpp()?;
        Ok(src)
    }

    /// PCC's 16-bit TIFF exports hold values scaled to 0‥65535 while their
    /// XML still says RealBPP 12 (it describes the camera data): when frame
    /// 0 holds a value above `2^RealBPP − 1`, the bit depth is the
    /// container's and a warning says why.
    fn check_real_bpp(&mut self) -> Result<(), SourceError> {
        let bits = self.meta.bit_depth;
        let container = self.container_bits;
        if bits >= container {
            return Ok(());
        }
        let mut f = Frame::zeros((self.meta.height, self.meta.width));
        self.read_into(0, &mut f)?;
        let max = f.iter().copied().max().unwrap_or(0);
        if u32::from(max) >= 1 << bits {
            self.meta.bit_depth = container;
            self.meta.details.warnings.push(format!(
                "frame 0 holds {max}, above the XML's RealBPP {bits} range: \
                 the frames are scaled to {container} bits (a PCC 16-bit export), \
                 bit_depth set to {container}"
            ));
        }
        Ok(())
    }

    /// The frame files in index order.
    pub fn files(&self) -> &[PathBuf] {
        &self.files
    }
}

/// Missing numbers between consecutive present ones, as inclusive ranges.
fn gaps_of(numbers: &[i64]) -> Vec<(i64, i64)> {
    numbers
        .windows(2)
        .filter(|w| w[1] > w[0] + 1)
        .map(|w| (w[0] + 1, w[1] - 1))
        .collect()
}

/// Values for exactly the present frame numbers, or `None` if any is missing.
fn per_frame(by_number: &[(i64, f64)], numbers: &[i64]) -> Option<Vec<f64>> {
    if by_number.is_empty() {
        return None;
    }
    let mut sorted: Vec<(i64, f64)> = by_number.to_vec();
    sorted.sort_by_key(|t| t.0);
    numbers
        .iter()
        .map(|n| {
            sorted
                .binary_search_by_key(n, |t| t.0)
                .ok()
                .map(|i| sorted[i].1)
        })
        .collect()
}

/// The folder's PCC XML: the one named like the sequence prefix, else the
/// only `<chd>` XML there. Several candidates without a name match → error.
/// An XML that is not PCC's (no `<chd`, not UTF-8 text, larger than any
/// side file) is ignored with a warning, unless it is named like the
/// sequence: that one must be a readable side file.
fn pick_xml(
    dir: &Path,
    prefix: &str,
    xmls: &[String],
    warnings: &mut Vec<String>,
) -> Result<Option<(PathBuf, PccXml)>, SourceError> {
    let trimmed = prefix.trim_end_matches(['_', '-', ' ', '.']);
    let mut parsed = Vec::new();
    for name in xmls {
        let path = dir.join(name);
        let named_like_sequence = path.file_stem().and_then(|s| s.to_str()) == Some(trimmed);
        let bytes = crate::io_util::read_bounded(&path, pcc_xml::MAX_XML_BYTES as u64)
            .map_err(io_err(&path))?;
        let problem = match &bytes {
            None => Some(format!(
                "larger than any PCC side file ({} MiB at most)",
                pcc_xml::MAX_XML_BYTES >> 20
            )),
            Some(b) if std::str::from_utf8(b).is_err() => Some("not UTF-8 text".to_string()),
            Some(b) if !named_like_sequence && !contains(b, b"<chd") => {
                continue; // some other XML, not PCC's
            }
            Some(_) => None,
        };
        if let Some(p) = problem {
            if named_like_sequence {
                return Err(format_err(&path, format!("the PCC side file is {p}")));
            }
            warnings.push(format!("ignored {name}: {p}, not a PCC side file"));
            continue;
        }
        let text = String::from_utf8(bytes.unwrap_or_default()).unwrap_or_default();
        if !text.contains("<chd") {
            continue; // named like the sequence, but some other XML
        }
        let x = pcc_xml::parse(&text).map_err(|r| format_err(&path, r))?;
        parsed.push((path, x));
    }
    if parsed.len() <= 1 {
        return Ok(parsed.pop());
    }
    let matching: Vec<_> = parsed
        .into_iter()
        .filter(|(p, _)| p.file_stem().and_then(|s| s.to_str()) == Some(trimmed))
        .collect();
    match matching.len() {
        1 => Ok(matching.into_iter().next()),
        _ => Err(format_err(
            dir,
            format!(
                "several PCC XML side files and none named {trimmed}.xml: keep the one of this sequence"
            ),
        )),
    }
}

fn contains(hay: &[u8], needle: &[u8]) -> bool {
    hay.windows(needle.len()).any(|w| w == needle)
}

/// Read `buf.len()` bytes at `offset` (one positioned read on Unix).
fn read_at(file: &mut File, offset: u64, buf: &mut [u8]) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        std::os::unix::fs::FileExt::read_exact_at(file, buf, offset)
    }
    #[cfg(not(unix))]
    {
        file.seek(SeekFrom::Start(offset))?;
        file.read_exact(buf)
    }
}

/// Open a frame file and read its header.
fn open_and_probe(
    path: &Path,
    kind: ImageKind,
    scratch: &mut Scratch,
) -> Result<(File, Probe), SourceError> {
    let (mut file, len) = crate::io_util::open_regular_len(path).map_err(io_err(path))?;
    let p = probe(path, &mut file, len, kind, scratch)?;
    Ok((file, p))
}

/// Read a file's header and decide how to decode it. `bytes` is scratch.
fn probe(
    path: &Path,
    file: &mut File,
    len: u64,
    kind: ImageKind,
    scratch: &mut Scratch,
) -> Result<Probe, SourceError> {
    let bytes = &mut scratch.bytes;
    match kind {
        ImageKind::Tiff => {
            if let Some(p) = probe_tiff(file, len, scratch).map_err(|r| format_err(path, r))? {
                return Ok(p);
            }
        }
        ImageKind::Bmp => {
            if let Some(p) = probe_bmp(file, len, scratch).map_err(|r| format_err(path, r))? {
                return Ok(p);
            }
        }
        ImageKind::Png => {
            // Frame reads keep the whole file in `bytes` for the decoder;
            // opening reads only as far as the header chunks.
            let info = if scratch.read_whole {
                bytes.clear();
                bytes.reserve(len as usize);
                file.read_to_end(bytes).map_err(io_err(path))?;
                png_info(Cursor::new(&bytes[..]))
            } else {
                png_info(std::io::BufReader::new(&mut *file))
            }
            .map_err(|e| format_err(path, format!("not a readable PNG: {e}")))?;
            return check_compressed_size(path, info, len);
        }
        ImageKind::Jpeg => {}
    }
    // Generic: dimensions and depth from the image crate's header reader.
    file.seek(SeekFrom::Start(0)).map_err(io_err(path))?;
    let reader = image::ImageReader::new(std::io::BufReader::new(&mut *file))
        .with_guessed_format()
        .map_err(io_err(path))?;
    let dec = reader
        .into_decoder()
        .map_err(|e| format_err(path, format!("not a readable image: {e}")))?;
    use image::ImageDecoder;
    let (w, h) = dec.dimensions();
    let bits = if dec.color_type().bytes_per_pixel() / dec.color_type().channel_count() >= 2 {
        16
    } else {
        8
    };
    check_compressed_size(
        path,
        Probe {
            width: w as usize,
            height: h as usize,
            bits,
            layout: Layout::Generic,
        },
        len,
    )
}

/// Most pixels a compressed frame may claim per byte of its file. Deflate
/// cannot do better than ~1 032:1 (a black 8-bit PNG), a flat JPEG or LZW
/// TIFF ~200:1, so no camera frame comes near; but a BMP's RLE8 "end of
/// bitmap" or a forged header can claim any size in a few bytes, and the
/// decoder then spends seconds and hundreds of MB on it (issue 14's
/// fuzzing: a 1.9 kB BMP claiming 3 072 × 45 319 took 16 s per read).
const MAX_PIXELS_PER_BYTE: u64 = 4096;

/// `probe` for a frame the decoders decompress: refused when its size is
/// implausible for its file's (see [`MAX_PIXELS_PER_BYTE`]).
fn check_compressed_size(path: &Path, p: Probe, len: u64) -> Result<Probe, SourceError> {
    let pixels = p.width as u64 * p.height as u64;
    if pixels > len.saturating_mul(MAX_PIXELS_PER_BYTE) {
        return Err(format_err(
            path,
            format!(
                "implausible size {}×{} for a {len}-byte file (more than {MAX_PIXELS_PER_BYTE} \
                 pixels per byte): corrupt or forged header",
                p.width, p.height
            ),
        ));
    }
    Ok(p)
}

/// Size, depth and layout of a PNG from its header chunks.
fn png_info<R: std::io::BufRead + Seek>(r: R) -> Result<Probe, png::DecodingError> {
    let reader = png::Decoder::new(r).read_info()?;
    let info = reader.info();
    let bits = match info.bit_depth {
        png::BitDepth::Sixteen => 16,
        _ => 8,
    };
    let grey = info.color_type == png::ColorType::Grayscale
        && matches!(
            info.bit_depth,
            png::BitDepth::Eight | png::BitDepth::Sixteen
        )
        && !info.interlaced;
    Ok(Probe {
        width: info.width as usize,
        height: info.height as usize,
        bits,
        layout: if grey {
            Layout::PngGrey
        } else {
            Layout::Generic
        },
    })
}

/// Parse a classic TIFF's first IFD. `Ok(None)` = valid but not the simple
/// uncompressed grey layout (left to the generic decoder).
fn probe_tiff(file: &mut File, len: u64, sc: &mut Scratch) -> Result<Option<Probe>, String> {
    // Files up to WHOLE_FILE_MAX are read whole, in one call, and decoded
    // from memory; larger ones by their first 4 KiB, then the rows needed.
    let head_len = if sc.read_whole && !sc.small_band && len <= WHOLE_FILE_MAX {
        len
    } else {
        len.min(4096)
    };
    // Grow the reused buffer only when needed and never shrink it (no
    // zeroing frame after frame): the file's bytes are `head[..head_len]`.
    let head_usize = head_len as usize;
    if sc.head.len() < head_usize {
        sc.head.resize(head_usize, 0);
    }
    file.read_exact(&mut sc.head[..head_usize])
        .map_err(|e| format!("not a TIFF (reading {head_len} bytes: {e})"))?;
    sc.whole = head_len == len;
    if head_len < 8 {
        return Err(format!("not a TIFF ({len} bytes)"));
    }
    let head = &sc.head[..head_usize];
    let fetch = |file: &mut File, off: u64, out: &mut Vec<u8>, n: usize| {
        out.clear();
        if off + n as u64 <= head.len() as u64 {
            out.extend_from_slice(&head[off as usize..off as usize + n]);
            Ok(())
        } else {
            out.resize(n, 0);
            read_at(file, off, out).map_err(|e| e.to_string())
        }
    };
    let big_endian = match &head[0..4] {
        b"II*\0" => false,
        b"MM\0*" => true,
        _ => return Ok(None), // BigTIFF or not a TIFF: let the generic path decide
    };
    let u16_ = |b: &[u8]| {
        let a = [b[0], b[1]];
        if big_endian {
            u16::from_be_bytes(a)
        } else {
            u16::from_le_bytes(a)
        }
    };
    let u32_ = |b: &[u8]| {
        let a = [b[0], b[1], b[2], b[3]];
        if big_endian {
            u32::from_be_bytes(a)
        } else {
            u32::from_le_bytes(a)
        }
    };
    let ifd = u64::from(u32_(&head[4..8]));
    if ifd + 2 > len {
        return Err(format!("IFD offset {ifd} is past the end ({len} bytes)"));
    }
    fetch(file, ifd, &mut sc.entries, 2)?;
    let n = usize::from(u16_(&sc.entries));
    if ifd + 2 + 12 * n as u64 > len {
        return Err(format!("IFD with {n} entries runs past the end"));
    }
    fetch(file, ifd + 2, &mut sc.entries, 12 * n)?;
    let entries = &sc.entries;
    // (type, count, value-or-offset bytes)
    let tag = |t: u16| {
        entries
            .chunks_exact(12)
            .find(|e| u16_(&e[0..2]) == t)
            .map(|e| (u16_(&e[2..4]), u32_(&e[4..8]), [e[8], e[9], e[10], e[11]]))
    };
    let scalar = |e: Option<(u16, u32, [u8; 4])>| -> Option<u64> {
        let (ty, count, v) = e?;
        if count < 1 {
            return None;
        }
        match ty {
            3 => Some(u64::from(u16_(&v[0..2]))),
            4 => Some(u64::from(u32_(&v))),
            _ => None,
        }
    };
    let width = scalar(tag(256)).ok_or("TIFF without ImageWidth")? as usize;
    let height = scalar(tag(257)).ok_or("TIFF without ImageLength")? as usize;
    let bits = scalar(tag(258)).unwrap_or(1);
    let compression = scalar(tag(259)).unwrap_or(1);
    let photometric = scalar(tag(262)).unwrap_or(1);
    let spp = scalar(tag(277)).unwrap_or(1);
    let rows_per_strip = scalar(tag(278)).unwrap_or(u64::from(u32::MAX));
    let sample_format = scalar(tag(339)).unwrap_or(1);
    let predictor = scalar(tag(317)).unwrap_or(1);
    let tiled = tag(322).is_some();
    if width == 0 || height == 0 || (width as u64) * (height as u64) > 1 << 28 {
        return Err(format!("implausible TIFF size {width}×{height}"));
    }
    let simple = compression == 1
        && photometric == 1
        && spp == 1
        && (bits == 8 || bits == 16)
        && sample_format == 1
        && predictor == 1
        && !tiled;
    if !simple {
        return Ok(None);
    }
    let strips = tag(273).ok_or("TIFF without StripOffsets")?;
    let (ty, count, v) = strips;
    let rps = rows_per_strip.clamp(1, height as u64) as usize;
    let need = height.div_ceil(rps);
    if (count as usize) < need {
        return Err(format!(
            "{count} strip offsets for {height} rows of {rps} per strip"
        ));
    }
    let size = match ty {
        3 => 2,
        4 => 4,
        _ => return Err(format!("StripOffsets of TIFF type {ty}")),
    };
    if need * size <= 4 {
        sc.raw.clear();
        sc.raw.extend_from_slice(&v[..need * size]);
    } else {
        let off = u64::from(u32_(&v));
        if off + (need * size) as u64 > len {
            return Err("StripOffsets array runs past the end".into());
        }
        fetch(file, off, &mut sc.raw, need * size)?;
    }
    sc.strips.clear();
    for c in sc.raw.chunks_exact(size) {
        sc.strips.push(if size == 2 {
            u64::from(u16_(c))
        } else {
            u64::from(u32_(c))
        });
    }
    let row_bytes = width as u64 * bits / 8;
    for (i, &o) in sc.strips.iter().enumerate() {
        let rows = rps.min(height - i * rps) as u64;
        if o + rows * row_bytes > len {
            return Err(format!(
                "strip {i} runs past the end of the file: truncated?"
            ));
        }
    }
    // Strips back to back: one strip of all rows, read in one call.
    let strip_bytes = rps as u64 * row_bytes;
    let contiguous = sc.strips.windows(2).all(|w| w[1] == w[0] + strip_bytes);
    let rps = if contiguous {
        sc.strips.truncate(1);
        height
    } else {
        rps
    };
    Ok(Some(Probe {
        width,
        height,
        bits: bits as u8,
        layout: Layout::TiffRaw {
            big_endian,
            rows_per_strip: rps,
        },
    }))
}

/// Parse an 8-bit paletted BMP with a grey palette; `Ok(None)` for any
/// other BMP (decoded generically).
fn probe_bmp(file: &mut File, len: u64, sc: &mut Scratch) -> Result<Option<Probe>, String> {
    let mut h = [0u8; 54];
    read_at(file, 0, &mut h).map_err(|e| format!("not a BMP (header: {e})"))?;
    if &h[0..2] != b"BM" {
        return Err("not a BMP (no \"BM\" magic)".into());
    }
    let le32 = |o: usize| u32::from_le_bytes([h[o], h[o + 1], h[o + 2], h[o + 3]]);
    let data_offset = u64::from(le32(10));
    let dib = le32(14);
    let width = le32(18) as i32;
    let height = le32(22) as i32;
    let bpp = u16::from_le_bytes([h[28], h[29]]);
    let compression = le32(30);
    let colours = le32(46);
    if dib < 40 || bpp != 8 || compression != 0 || width <= 0 || height == 0 {
        return Ok(None);
    }
    let (w, hh) = (width as usize, height.unsigned_abs() as usize);
    if (w as u64) * (hh as u64) > 1 << 28 {
        return Err(format!("implausible BMP size {w}×{hh}"));
    }
    let n_pal = if colours == 0 {
        256
    } else {
        colours.min(256) as usize
    };
    let pal_off = 14 + u64::from(dib);
    if pal_off + 4 * n_pal as u64 > len {
        return Err("BMP palette runs past the end".into());
    }
    let pal = &mut sc.raw;
    pal.clear();
    pal.resize(4 * n_pal, 0);
    read_at(file, pal_off, pal).map_err(|e| e.to_string())?;
    // Grey palette: B = G = R for every entry; the value is that grey.
    sc.palette.clear();
    sc.palette.resize(256, 0);
    for (p, c) in sc.palette.iter_mut().zip(pal.chunks_exact(4)) {
        if c[0] != c[1] || c[1] != c[2] {
            return Ok(None);
        }
        *p = c[0];
    }
    let stride = w.div_ceil(4) * 4;
    if data_offset + (stride * hh) as u64 > len {
        return Err("BMP pixel data runs past the end: truncated?".into());
    }
    Ok(Some(Probe {
        width: w,
        height: hh,
        bits: 8,
        layout: Layout::Bmp8 {
            data_offset,
            stride,
            top_down: height < 0,
        },
    }))
}

impl FrameSource for FolderSource {
    fn meta(&self) -> &SourceMeta {
        &self.meta
    }

    /// The same files, with buffers of its own.
    fn try_clone(&self) -> Option<Box<dyn FrameSource>> {
        Some(Box::new(FolderSource {
            meta: self.meta.clone(),
            files: self.files.clone(),
            kind: self.kind,
            container_bits: self.container_bits,
            scratch: Scratch {
                read_whole: true,
                ..Scratch::default()
            },
            row_scratch: Vec::new(),
            u16_scratch: Vec::new(),
        }))
    }

    fn read_rows_into(
        &mut self,
        index: usize,
        row0: usize,
        out: &mut ArrayViewMut2<u16>,
    ) -> Result<(), SourceError> {
        check_band(&self.meta, index, row0, out)?;
        let path = &self.files[index];
        let frame_err = |reason: String| SourceError::Frame {
            path: path.clone(),
            index,
            reason,
        };
        self.scratch.small_band = 2 * out.nrows() < self.meta.height;
        let (mut file, p) =
            open_and_probe(path, self.kind, &mut self.scratch).map_err(|e| match e {
                SourceError::Format { reason, .. } => frame_err(reason),
                other => other,
            })?;
        if (p.width, p.height) != (self.meta.width, self.meta.height) {
            return Err(frame_err(format!(
                "size changed to {}×{} since the folder was opened",
                p.width, p.height
            )));
        }
        let n = out.nrows();
        let w = p.width;
        match &p.layout {
            Layout::TiffRaw {
                big_endian,
                rows_per_strip,
            } => {
                let sc = &mut self.scratch;
                let bpp = usize::from(p.bits / 8);
                let row_bytes = w * bpp;
                let rps = *rows_per_strip;
                let row_at =
                    |strips: &[u64], r: usize| strips[r / rps] as usize + (r % rps) * row_bytes;
                if !sc.whole {
                    // A small band or a large file: read only the band's
                    // rows, one read per strip they lie in.
                    sc.bytes.clear();
                    sc.bytes.resize(n * row_bytes, 0);
                    let mut r = row0;
                    while r < row0 + n {
                        let take = (rps - r % rps).min(row0 + n - r);
                        let dst =
                            &mut sc.bytes[(r - row0) * row_bytes..(r - row0 + take) * row_bytes];
                        read_at(&mut file, row_at(&sc.strips, r) as u64, dst)
                            .map_err(|e| frame_err(format!("reading rows: {e}")))?;
                        r += take;
                    }
                }
                let (whole, head, bytes, strips) = (sc.whole, &sc.head, &sc.bytes, &sc.strips);
                let big_endian = *big_endian;
                fill_rows(out, &mut self.row_scratch, |j, dst| {
                    let src = if whole {
                        let o = row_at(strips, row0 + j);
                        &head[o..o + row_bytes]
                    } else {
                        &bytes[j * row_bytes..(j + 1) * row_bytes]
                    };
                    if bpp == 1 {
                        widen_u8(src, dst);
                    } else if big_endian {
                        for (d, s) in dst.iter_mut().zip(src.chunks_exact(2)) {
                            *d = u16::from_be_bytes([s[0], s[1]]);
                        }
                    } else {
                        for (d, s) in dst.iter_mut().zip(src.chunks_exact(2)) {
                            *d = u16::from_le_bytes([s[0], s[1]]);
                        }
                    }
                });
            }
            Layout::Bmp8 {
                data_offset,
                stride,
                top_down,
            } => {
                let palette = &self.scratch.palette;
                let h = p.height;
                // Stored rows for the band are contiguous; bottom-up reverses them.
                let first_stored = if *top_down { row0 } else { h - row0 - n };
                let bytes = &mut self.scratch.bytes;
                bytes.clear();
                bytes.resize(n * stride, 0);
                read_at(
                    &mut file,
                    data_offset + (first_stored * stride) as u64,
                    bytes,
                )
                .map_err(|e| frame_err(format!("reading rows: {e}")))?;
                for j in 0..n {
                    let k = if *top_down { j } else { n - 1 - j };
                    let src = &bytes[k * stride..k * stride + w];
                    fill_row(out.slice_mut(s![j, ..]), &mut self.row_scratch, |dst| {
                        for (d, s) in dst.iter_mut().zip(src) {
                            *d = u16::from(palette[usize::from(*s)]);
                        }
                    });
                }
            }
            Layout::PngGrey => {
                // `probe` left the whole file in `self.bytes`.
                let mut reader = png::Decoder::new(Cursor::new(&self.scratch.bytes[..]))
                    .read_info()
                    .map_err(|e| frame_err(format!("PNG: {e}")))?;
                let sixteen = p.bits == 16;
                for r in 0..row0 + n {
                    let row = reader
                        .next_row()
                        .map_err(|e| frame_err(format!("PNG: {e}")))?
                        .ok_or_else(|| frame_err("PNG ends early".into()))?;
                    if r < row0 {
                        continue;
                    }
                    let src = row.data();
                    fill_row(
                        out.slice_mut(s![r - row0, ..]),
                        &mut self.row_scratch,
                        |dst| {
                            if sixteen {
                                for (d, s) in dst.iter_mut().zip(src.chunks_exact(2)) {
                                    *d = u16::from_be_bytes([s[0], s[1]]);
                                }
                            } else {
                                widen_u8(src, dst);
                            }
                        },
                    );
                }
            }
            Layout::Generic => {
                let bytes = &mut self.scratch.bytes;
                bytes.clear();
                file.seek(SeekFrom::Start(0)).map_err(io_err(path))?;
                file.read_to_end(bytes).map_err(io_err(path))?;
                let img = image::ImageReader::new(Cursor::new(&bytes[..]))
                    .with_guessed_format()
                    .map_err(io_err(path))?
                    .decode()
                    .map_err(|e| frame_err(format!("cannot decode: {e}")))?;
                self.u16_scratch.clear();
                if p.bits == 16 {
                    self.u16_scratch.extend(img.into_luma16().into_raw());
                } else {
                    self.u16_scratch
                        .extend(img.into_luma8().into_raw().into_iter().map(u16::from));
                }
                if self.u16_scratch.len() < (row0 + n) * w {
                    return Err(frame_err("decoded image is smaller than its header".into()));
                }
                for j in 0..n {
                    let src = &self.u16_scratch[(row0 + j) * w..(row0 + j + 1) * w];
                    fill_row(out.slice_mut(s![j, ..]), &mut self.row_scratch, |dst| {
                        dst.copy_from_slice(src)
                    });
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_split_into_prefix_number_and_kind() {
        let p = |n: &str| parse_frame_name(n).map(|(a, b, _)| (a, b));
        assert_eq!(p("run_000012.tif"), Some(("run_".into(), 12)));
        assert_eq!(p("run_-00005.tif"), Some(("run_".into(), -5)));
        assert_eq!(p("-3.png"), Some(("".into(), -3)));
        assert_eq!(p("img-0004.png"), Some(("img-".into(), 4)));
        assert_eq!(p("img--4.png"), Some(("img-".into(), -4)));
        assert_eq!(p("Img7.BMP"), Some(("Img".into(), 7)));
        assert_eq!(p("notes.txt"), None);
        assert_eq!(p("background.tif"), None);
        assert_eq!(p("run.xml"), None);
    }

    #[test]
    fn gaps_are_inclusive_ranges_of_missing_numbers() {
        assert_eq!(gaps_of(&[-2, -1, 0, 3, 4, 6]), vec![(1, 2), (5, 5)]);
        assert!(gaps_of(&[5]).is_empty());
    }
}
