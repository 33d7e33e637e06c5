//! Reading the header region (module doc, layout): `CINEFILEHEADER`,
//! `BITMAPINFOHEADER`, `SETUP` and the tagged blocks, each size checked
//! against the file's length.

use std::fs::File;

use super::header::{CineHeader, CineLayout, CineStorage};
use crate::source::colour::Bayer;
use crate::source::index::Time64;

/// Largest accepted frame (pixels): the cap of every reader.
const MAX_PIXELS: u64 = crate::source::validate::MAX_FRAME_PIXELS;

/// Bytes at an offset: of a file, or of a copy of it in memory (the fuzz
/// target's).
pub trait ReadAt {
    /// Fill `dst` with the bytes at `offset`; an error when they are not all there.
    fn read_at(&self, offset: u64, dst: &mut [u8]) -> std::io::Result<()>;
}

impl ReadAt for File {
    fn read_at(&self, offset: u64, dst: &mut [u8]) -> std::io::Result<()> {
        crate::util::io::read_at(self, offset, dst)
    }
}

impl ReadAt for [u8] {
    fn read_at(&self, offset: u64, dst: &mut [u8]) -> std::io::Result<()> {
        let src = usize::try_from(offset)
            .ok()
            .and_then(|o| self.get(o..o.checked_add(dst.len())?))
            .ok_or(std::io::ErrorKind::UnexpectedEof)?;
        dst.copy_from_slice(src);
        Ok(())
    }
}

/// `len` bytes at `offset` of `r`, a failure said as text.
fn bytes_at<R: ReadAt + ?Sized>(r: &R, offset: u64, len: usize) -> Result<Vec<u8>, String> {
    let mut b = vec![0u8; len];
    r.read_at(offset, &mut b)
        .map_err(|e| format!("reading bytes {offset}..{}: {e}", offset + len as u64))?;
    Ok(b)
}

fn u16_at(b: &[u8], off: usize) -> Option<u16> {
    b.get(off..off + 2)
        .map(|s| u16::from_le_bytes([s[0], s[1]]))
}
fn u32_at(b: &[u8], off: usize) -> Option<u32> {
    b.get(off..off + 4)
        .map(|s| u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
}
fn i32_at(b: &[u8], off: usize) -> Option<i32> {
    u32_at(b, off).map(|v| v as i32)
}
fn u64_at(b: &[u8], off: usize) -> Option<u64> {
    b.get(off..off + 8).map(|s| {
        let mut a = [0u8; 8];
        a.copy_from_slice(s);
        u64::from_le_bytes(a)
    })
}

/// A view of SETUP that only yields fields lying within `Length` (§0.3).
struct Setup<'a> {
    bytes: &'a [u8],
}

impl Setup<'_> {
    fn u32(&self, off: usize) -> Option<u32> {
        u32_at(self.bytes, off)
    }
    fn i32(&self, off: usize) -> Option<i32> {
        i32_at(self.bytes, off)
    }
    fn f32(&self, off: usize) -> Option<f32> {
        self.u32(off).map(f32::from_bits)
    }
    fn f64(&self, off: usize) -> Option<f64> {
        u64_at(self.bytes, off).map(f64::from_bits)
    }
    /// A NUL-terminated string field of `len` bytes (256 for CameraModel, §0.4).
    fn text(&self, off: usize, len: usize) -> Option<String> {
        let raw = self.bytes.get(off..off + len)?;
        let end = raw.iter().position(|&c| c == 0).unwrap_or(len);
        let s = String::from_utf8_lossy(&raw[..end]).trim().to_string();
        (!s.is_empty()).then_some(s)
    }
}

/// Bytes needed from the start of the file to parse the header region and
/// the offset table, from the first 44 bytes. Errors when the header is not
/// a cine or points outside a file of `file_len` bytes.
pub fn header_region_len(first44: &[u8], file_len: u64) -> Result<u64, String> {
    if first44.len() < 44 {
        return Err(format!(
            "too short for a cine header ({} bytes, need 44)",
            first44.len()
        ));
    }
    if &first44[0..2] != b"CI" {
        return Err("not a cine file (no \"CI\" magic at byte 0)".into());
    }
    let count = u64::from(u32_at(first44, 20).unwrap_or(0));
    let off_offsets = u64::from(u32_at(first44, 32).unwrap_or(0));
    let end = off_offsets + 8 * count;
    if end > file_len {
        return Err(format!(
            "header claims {count} images with their offset table at byte {off_offsets}, \
             which runs past the end of the file ({file_len} bytes): truncated or corrupt"
        ));
    }
    Ok(end)
}

/// Parse the header region of a cine held in `data` (at least
/// [`header_region_len`] bytes from the file's start) for a file of
/// `file_len` bytes. Pure and allocation-bounded by `data.len()`: this is the
/// function the fuzz target drives.
pub fn parse_layout(data: &[u8], file_len: u64) -> Result<CineLayout, String> {
    parse_layout_at(data, file_len)
}

/// Parse the header region of the cine `r` (a file of `file_len` bytes),
/// reading only the fixed headers and the tagged blocks' own headers, and
/// checking the image offset table a block at a time: what it holds does
/// not grow with the number of images.
pub fn parse_layout_at<R: ReadAt + ?Sized>(r: &R, file_len: u64) -> Result<CineLayout, String> {
    let first = bytes_at(r, 0, 44.min(file_len) as usize)?;
    let region = header_region_len(&first, file_len)?;
    let data = &first[..];
    let h = |off| u32_at(data, off).unwrap_or(0);
    let header_size = u16_at(data, 2).unwrap_or(0);
    let compression = u16_at(data, 4).unwrap_or(0);
    let version = u16_at(data, 6).unwrap_or(0);
    let (off_ih, off_setup, off_offsets) = (h(24), h(28), h(32));
    let image_count = h(20);
    check_file_header(
        header_size,
        version,
        image_count,
        [off_ih, off_setup, off_offsets],
    )?;
    let bih = Bitmap::read(r, off_ih, region)?;
    let (width, height) = (bih.width, bih.height);
    let (setup_bytes, setup_length) = read_setup(r, off_setup, region)?;
    let setup_end = u64::from(off_setup) + u64::from(setup_length);
    let setup = Setup {
        bytes: &setup_bytes,
    };
    let cfa = setup.u32(808);
    let bayer = bayer_of(compression, cfa)?;
    let storage = storage_of(bih.bit_count, bih.bi_compression, bayer.is_some())?;
    let header = CineHeader {
        compression,
        version,
        first_movie_image: i32_at(data, 8).unwrap_or(0),
        total_image_count: h(12),
        first_image_no: i32_at(data, 16).unwrap_or(0),
        image_count,
        off_image_header: off_ih,
        off_setup,
        off_image_offsets: off_offsets,
        trigger_time: Time64 {
            fractions: h(36),
            seconds: h(40),
        },
        width,
        height,
        bit_count: bih.bit_count,
        bi_compression: bih.bi_compression,
        size_image: bih.size_image,
        storage,
        bayer,
        setup_length,
        frame_rate16: u16_at(setup.bytes, 0).unwrap_or(0),
        shutter16_us: u16_at(setup.bytes, 2).unwrap_or(0),
        frame_rate: setup.u32(768),
        shutter_us: setup.u32(772),
        flip_h: setup.i32(756).map(|v| v != 0),
        flip_v: setup.i32(760).map(|v| v != 0),
        camera_version: setup.u32(792),
        software_version: setup.u32(800),
        cfa,
        rotate: setup.i32(884),
        real_bpp: setup.u32(896),
        shutter_ns: setup.u32(1568),
        black_level: setup.i32(5732),
        white_level: setup.i32(5736),
        f_offset: setup.f32(6008),
        f_gain: setup.f32(6012),
        f_gamma: setup.f32(6024),
        camera_model: setup.text(10128, 256),
        f_decimation: setup.f32(10388),
        d_frame_rate: setup.f64(10400),
    };
    if header.storage == CineStorage::P10 && header.bit_depth() > 10 {
        return Err(format!(
            "P10 packing with RealBPP {} is contradictory",
            header.bit_depth()
        ));
    }
    // Tagged blocks from OffSetup + Length to OffImageOffsets (§5): where
    // the per-image values start.
    let (times_at, exposures_at, block_types) =
        tagged_blocks(r, setup_end, u64::from(off_offsets), u64::from(image_count))?;
    // Image offsets: int64, absolute (§6). Checked against the file length,
    // a block at a time.
    let layout = CineLayout {
        header,
        times_at,
        exposures_at,
        block_types,
    };
    check_offsets(r, &layout, file_len)?;
    Ok(layout)
}

/// CINEFILEHEADER's own checks: its size, its version (1: 64-bit image
/// offsets), some images, and offsets `[OffImageHeader, OffSetup,
/// OffImageOffsets]` past it.
fn check_file_header(
    header_size: u16,
    version: u16,
    image_count: u32,
    offsets: [u32; 3],
) -> Result<(), String> {
    let [off_ih, off_setup, off_offsets] = offsets;
    if header_size < 44 {
        return Err(format!("CINEFILEHEADER.Headersize {header_size} < 44"));
    }
    if version != 1 {
        return Err(format!(
            "unsupported: cine header version {version} (only version 1, with 64-bit image offsets, is known)"
        ));
    }
    if image_count == 0 {
        return Err("the cine holds no images (ImageCount 0)".into());
    }
    for (name, off) in [
        ("OffImageHeader", off_ih),
        ("OffSetup", off_setup),
        ("OffImageOffsets", off_offsets),
    ] {
        if off < u32::from(header_size) {
            return Err(format!(
                "{name} = {off} points inside the 44-byte file header"
            ));
        }
    }
    Ok(())
}

/// The BITMAPINFOHEADER fields read.
struct Bitmap {
    width: u32,
    height: u32,
    bit_count: u16,
    bi_compression: u32,
    size_image: u32,
}

impl Bitmap {
    /// BITMAPINFOHEADER at `off_ih`, inside the header region (`region`
    /// bytes), with a plausible positive size.
    fn read<R: ReadAt + ?Sized>(r: &R, off_ih: u32, region: u64) -> Result<Bitmap, String> {
        if u64::from(off_ih) + 40 > region {
            return Err(format!(
                "BITMAPINFOHEADER at {off_ih} lies outside the header region"
            ));
        }
        let bih = &bytes_at(r, u64::from(off_ih), 40)?[..];
        let width = i32_at(bih, 4).unwrap_or(0);
        let height = i32_at(bih, 8).unwrap_or(0);
        let bit_count = u16_at(bih, 14).unwrap_or(0);
        let bi_compression = u32_at(bih, 16).unwrap_or(0);
        let size_image = u32_at(bih, 20).unwrap_or(0);
        if width <= 0 || height <= 0 {
            return Err(format!(
                "unsupported image size {width}×{height} (biWidth and biHeight must be positive)"
            ));
        }
        let (width, height) = (width as u32, height as u32);
        if u64::from(width) * u64::from(height) > MAX_PIXELS {
            return Err(format!("image size {width}×{height} is implausibly large"));
        }
        Ok(Bitmap {
            width,
            height,
            bit_count,
            bi_compression,
            size_image,
        })
    }
}

/// SETUP at `off_setup`: its "ST" mark checked and its first `Length`
/// bytes (inside the header region, `region` bytes) read, with `Length`.
fn read_setup<R: ReadAt + ?Sized>(
    r: &R,
    off_setup: u32,
    region: u64,
) -> Result<(Vec<u8>, u16), String> {
    let setup_start = u64::from(off_setup);
    let setup_head = if setup_start + 144 <= region {
        bytes_at(r, setup_start, 144)?
    } else {
        Vec::new()
    };
    if setup_head.get(140..142) != Some(b"ST".as_slice()) {
        return Err(format!(
            "SETUP at {off_setup} has no \"ST\" mark at +140: corrupt header"
        ));
    }
    let setup_length = u16_at(&setup_head, 142).unwrap_or(0);
    if setup_length < 144 {
        return Err(format!("SETUP.Length {setup_length} is too small (< 144)"));
    }
    let setup_end = setup_start + u64::from(setup_length);
    if setup_end > region {
        return Err(format!(
            "SETUP (Length {setup_length}) runs past the header region"
        ));
    }
    Ok((
        bytes_at(r, setup_start, usize::from(setup_length))?,
        setup_length,
    ))
}

/// Raw colour (Compression 2): a Bayer mosaic, one sample a pixel, its
/// pattern from CFA as ffmpeg maps it (phantom.md §8.3); `None` for
/// Compression 0; an error for any other.
fn bayer_of(compression: u16, cfa: Option<u32>) -> Result<Option<Bayer>, String> {
    let cfa_name = |c: u32| match c {
        0 => "0 = gray",
        1 => "1 = VRI gbrg/rggb",
        2 => "2 = VRIV6 bggr/grbg",
        3 => "3 = BAYER gb/rg",
        4 => "4 = BAYERFLIP rg/gb",
        5 => "5 = BAYERFLIPB gr/bg",
        6 => "6 = BAYERFLIPH bg/gr",
        _ => "unknown pattern",
    };
    let cfa_low = cfa.map_or(0, |c| c & 0xFF);
    Ok(match compression {
        2 => Some(match cfa_low {
            3 => Bayer::Gbrg,
            4 => Bayer::Rggb,
            5 => Bayer::Grbg,
            6 => Bayer::Bggr,
            c => {
                return Err(format!(
                    "unsupported: raw colour cine with CFA {} (Compression 2); dropscope reads \
                     the Bayer patterns CFA 3–6 (GBRG, RGGB, GRBG, BGGR) and interpolated \
                     colour — re-save it as interpolated colour or grey in PCC",
                    cfa_name(c)
                ))
            }
        }),
        0 => None,
        c => {
            return Err(format!(
                "unsupported: cine Compression {c} (1 = JPEG .cci); dropscope reads \
                 uncompressed grey, interpolated colour and raw Bayer cines"
            ))
        }
    })
}

/// How the pixels are stored, from `biBitCount` and `biCompression`.
fn storage_of(
    bit_count: u16,
    bi_compression: u32,
    raw_colour: bool,
) -> Result<CineStorage, String> {
    Ok(match (bit_count, bi_compression, raw_colour) {
        (8, 0, _) => CineStorage::Gray8,
        (16, 0, _) => CineStorage::Gray16,
        (24, 0, false) => CineStorage::Bgr24,
        (48, 0, false) => CineStorage::Bgr48,
        (_, 256, _) => CineStorage::P10,
        (_, 1024, _) => CineStorage::P12L,
        (b, c, _) => {
            return Err(format!(
                "unsupported: biBitCount {b} with biCompression {c}{}",
                if raw_colour {
                    " in a raw colour cine"
                } else {
                    ""
                }
            ))
        }
    })
}

/// The tagged blocks between `pos` (the end of SETUP) and `blocks_end`
/// (OffImageOffsets): where the time stamps (1002) and exposures (1003) of
/// `n` images start, and the blocks' types in file order.
#[allow(clippy::type_complexity)]
fn tagged_blocks<R: ReadAt + ?Sized>(
    r: &R,
    pos: u64,
    blocks_end: u64,
    n: u64,
) -> Result<(Option<u64>, Option<u64>, Vec<u16>), String> {
    let mut times_at = None;
    let mut exposures_at = None;
    let mut block_types = Vec::new();
    let mut pos = pos;
    while pos + 8 <= blocks_end {
        let head = bytes_at(r, pos, 8)?;
        let size = u64::from(u32_at(&head, 0).unwrap_or(0));
        let kind = u16_at(&head, 4).unwrap_or(0);
        if size < 8 || pos + size > blocks_end {
            break;
        }
        block_types.push(kind);
        let body = size - 8;
        match kind {
            1002 if body >= 8 * n => times_at = Some(pos + 8),
            1003 if body >= 4 * n => exposures_at = Some(pos + 8),
            _ => {}
        }
        pos += size;
    }
    Ok((times_at, exposures_at, block_types))
}

/// Every image offset of `layout` checked against the file's length
/// (`file_len`), a block at a time.
fn check_offsets<R: ReadAt + ?Sized>(
    r: &R,
    layout: &CineLayout,
    file_len: u64,
) -> Result<(), String> {
    let image_count = layout.header.image_count;
    let mut table = Vec::new();
    for lo in (0..image_count as usize).step_by(OFFSETS_BLOCK) {
        let hi = (lo + OFFSETS_BLOCK).min(image_count as usize);
        read_offsets(r, layout, file_len, lo..hi, lo, &mut table)
            .map_err(|(frame, reason)| format!("frame {frame}: {reason}"))?;
    }
    Ok(())
}

/// Image offsets read from a table at once.
pub(super) const OFFSETS_BLOCK: usize = 4096;

/// The image offsets of frames `frames` into `out`, each checked to leave
/// room for its image before the end of the file. An error names its frame:
/// the one whose offset is wrong, or `asked` when the table cannot be read.
pub(super) fn read_offsets<R: ReadAt + ?Sized>(
    r: &R,
    layout: &CineLayout,
    file_len: u64,
    frames: std::ops::Range<usize>,
    asked: usize,
    out: &mut Vec<u64>,
) -> Result<(), (usize, String)> {
    let at = u64::from(layout.header.off_image_offsets) + 8 * frames.start as u64;
    let mut b = vec![0u8; 8 * frames.len()];
    r.read_at(at, &mut b).map_err(|e| {
        let (lo, hi) = (frames.start, frames.end);
        let reason = format!("reading the image offsets of frames {lo}..{hi} at byte {at}: {e}");
        (asked, reason)
    })?;
    let region = layout.region_len();
    let min_record = 8 + layout.header.image_bytes();
    out.clear();
    for (i, c) in frames.zip(b.chunks_exact(8)) {
        let v = i64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]);
        if v < region as i64 || (v as u64).saturating_add(min_record) > file_len {
            let reason = format!(
                "image offset {v} does not leave room for the image \
                 (file is {file_len} bytes): truncated or corrupt"
            );
            return Err((i, reason));
        }
        out.push(v as u64);
    }
    Ok(())
}
