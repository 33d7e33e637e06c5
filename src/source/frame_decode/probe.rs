//! Reading a frame file's header (`probe`): the TIFF, PNG and BMP
//! layouts parsed here, anything else left to the `image` crate.

use std::io::{Cursor, Seek, SeekFrom};
use std::path::Path;

use super::types::{
    format_err, io_err, FrameBytes, ImageKind, Layout, Probe, Scratch, WHOLE_FILE_MAX,
};
use crate::source::{grown, SourceError};

/// Read a file's header and decide how to decode it. `bytes` is scratch.
pub(super) fn probe<F: FrameBytes>(
    path: &Path,
    file: &mut F,
    len: u64,
    kind: ImageKind,
    scratch: &mut Scratch,
) -> Result<Probe, SourceError> {
    if len > crate::source::validate::MAX_DECODE_BYTES {
        return Err(format_err(
            path,
            format!(
                "{len} bytes is more than a frame file may hold ({} bytes: a frame of at most \
                 {} pixels)",
                crate::source::validate::MAX_DECODE_BYTES,
                crate::source::MAX_FRAME_PIXELS
            ),
        ));
    }
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
                bytes
                    .try_reserve(len as usize)
                    .map_err(|e| format_err(path, format!("no memory for its {len} bytes: {e}")))?;
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
    let mut reader = image::ImageReader::new(std::io::BufReader::new(&mut *file))
        .with_guessed_format()
        .map_err(io_err(path))?;
    reader.limits(crate::source::decode_limits());
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
            colour: dec.color_type().has_color(),
            layout: Layout::Generic,
        },
        len,
    )
}

/// Most pixels a compressed frame may claim per byte of its file. Deflate
/// cannot do better than ~1 032:1 (a black 8-bit PNG), a flat JPEG or LZW
/// TIFF ~200:1, so no camera frame comes near; but a BMP's RLE8 "end of
/// bitmap" or a forged header can claim any size in a few bytes, and the
/// decoder then spends seconds and hundreds of MB on it (found by fuzzing:
/// a 1.9 kB BMP claiming 3 072 × 45 319 takes 16 s per read).
const MAX_PIXELS_PER_BYTE: u64 = 4096;

/// `probe` for a frame the decoders decompress: refused when its size is
/// implausible for its file's (see [`MAX_PIXELS_PER_BYTE`]).
fn check_compressed_size(path: &Path, p: Probe, len: u64) -> Result<Probe, SourceError> {
    if let Some(why) = crate::source::frame_too_large(p.width as u64, p.height as u64) {
        return Err(format_err(path, why));
    }
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
    let colour = match info.color_type {
        png::ColorType::Rgb | png::ColorType::Rgba => true,
        png::ColorType::Indexed => !info
            .palette
            .as_ref()
            .is_some_and(|p| p.chunks_exact(3).all(|c| c[0] == c[1] && c[1] == c[2])),
        png::ColorType::Grayscale | png::ColorType::GrayscaleAlpha => false,
    };
    Ok(Probe {
        width: info.width as usize,
        height: info.height as usize,
        bits,
        colour,
        layout: if grey {
            Layout::PngGrey
        } else {
            Layout::Generic
        },
    })
}

/// Parse a classic TIFF's first IFD. `Ok(None)` = valid but not the simple
/// uncompressed grey layout (left to the generic decoder).
fn probe_tiff<F: FrameBytes>(
    file: &mut F,
    len: u64,
    sc: &mut Scratch,
) -> Result<Option<Probe>, String> {
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
    file.read_exact(grown(&mut sc.head, head_usize))
        .map_err(|e| format!("not a TIFF (reading {head_len} bytes: {e})"))?;
    sc.whole = head_len == len;
    if head_len < 8 {
        return Err(format!("not a TIFF ({len} bytes)"));
    }
    let head = &sc.head[..head_usize];
    let order = match &head[0..4] {
        b"II*\0" => ByteOrder { big_endian: false },
        b"MM\0*" => ByteOrder { big_endian: true },
        _ => return Ok(None), // BigTIFF or not a TIFF: let the generic path decide
    };
    let ifd = u64::from(order.u32(&head[4..8]));
    if ifd + 2 > len {
        return Err(format!("IFD offset {ifd} is past the end ({len} bytes)"));
    }
    fetch(file, head, ifd, &mut sc.entries, 2)?;
    let n = usize::from(order.u16(&sc.entries));
    if ifd + 2 + 12 * n as u64 > len {
        return Err(format!("IFD with {n} entries runs past the end"));
    }
    fetch(file, head, ifd + 2, &mut sc.entries, 12 * n)?;
    let entries = &sc.entries;
    let tag = |t: u16| order.tag(entries, t);
    let scalar = |e: Option<(u16, u32, [u8; 4])>| order.scalar(e);
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
    check_orientation(scalar(tag(274)))?;
    if let Some(why) = crate::source::frame_too_large(width as u64, height as u64) {
        return Err(format!("TIFF: {why}"));
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
    let rps = rows_per_strip.clamp(1, height as u64) as usize;
    let need = height.div_ceil(rps);
    read_strip_offsets(
        file,
        head,
        order,
        strips,
        (need, height, rps),
        len,
        &mut sc.raw,
        &mut sc.strips,
    )?;
    let row_bytes = width as u64 * bits / 8;
    let rps = check_strips(&mut sc.strips, rps, height, row_bytes, len)?;
    Ok(Some(Probe {
        width,
        height,
        bits: bits as u8,
        colour: false,
        layout: Layout::TiffRaw {
            big_endian: order.big_endian,
            rows_per_strip: rps,
        },
    }))
}

/// A TIFF's byte order, read from its first two bytes.
#[derive(Debug, Clone, Copy)]
struct ByteOrder {
    big_endian: bool,
}

impl ByteOrder {
    fn u16(self, b: &[u8]) -> u16 {
        let a = [b[0], b[1]];
        if self.big_endian {
            u16::from_be_bytes(a)
        } else {
            u16::from_le_bytes(a)
        }
    }

    fn u32(self, b: &[u8]) -> u32 {
        let a = [b[0], b[1], b[2], b[3]];
        if self.big_endian {
            u32::from_be_bytes(a)
        } else {
            u32::from_le_bytes(a)
        }
    }

    /// Tag `t` of the IFD `entries` (12 bytes each): (type, count,
    /// value-or-offset bytes).
    fn tag(self, entries: &[u8], t: u16) -> Option<(u16, u32, [u8; 4])> {
        entries
            .chunks_exact(12)
            .find(|e| self.u16(&e[0..2]) == t)
            .map(|e| {
                (
                    self.u16(&e[2..4]),
                    self.u32(&e[4..8]),
                    [e[8], e[9], e[10], e[11]],
                )
            })
    }

    /// The value of a SHORT or LONG tag `e`.
    fn scalar(self, e: Option<(u16, u32, [u8; 4])>) -> Option<u64> {
        let (ty, count, v) = e?;
        if count < 1 {
            return None;
        }
        match ty {
            3 => Some(u64::from(self.u16(&v[0..2]))),
            4 => Some(u64::from(self.u32(&v))),
            _ => None,
        }
    }
}

/// `n` bytes at `off` of a file whose first bytes are `head`: from `head`
/// when they lie in it, else read.
fn fetch<F: FrameBytes>(
    file: &mut F,
    head: &[u8],
    off: u64,
    out: &mut Vec<u8>,
    n: usize,
) -> Result<(), String> {
    out.clear();
    if off + n as u64 <= head.len() as u64 {
        out.extend_from_slice(&head[off as usize..off as usize + n]);
        Ok(())
    } else {
        out.resize(n, 0);
        file.read_at(off, out).map_err(|e| e.to_string())
    }
}

/// The stored rows are read top row first, as PCC writes them: a frame
/// whose Orientation tag (`orientation`) says it is to be shown flipped or
/// turned would be measured upside down or mirrored without a word.
fn check_orientation(orientation: Option<u64>) -> Result<(), String> {
    match orientation {
        None | Some(1) => {}
        Some(o) => {
            let how = match o {
                2 => "mirrored left to right",
                3 => "turned 180°",
                4 => "flipped top to bottom",
                5..=8 => "turned by 90° (rows and columns swapped)",
                _ => "in an orientation TIFF does not define",
            };
            return Err(format!(
                "TIFF Orientation tag {o}: the picture is to be shown {how}, which dropscope \
                 does not undo (it reads the rows as stored, top row first); save the frames \
                 without an Orientation tag (or with 1), as PCC exports them"
            ));
        }
    }
    Ok(())
}

/// The strip offsets (tag `strips`) of `need` strips of `rps` rows (of
/// `height`) into `strips`, read through `raw`.
#[allow(clippy::too_many_arguments)]
fn read_strip_offsets<F: FrameBytes>(
    file: &mut F,
    head: &[u8],
    order: ByteOrder,
    strips: (u16, u32, [u8; 4]),
    (need, height, rps): (usize, usize, usize),
    len: u64,
    raw: &mut Vec<u8>,
    offsets: &mut Vec<u64>,
) -> Result<(), String> {
    let (ty, count, v) = strips;
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
        raw.clear();
        raw.extend_from_slice(&v[..need * size]);
    } else {
        let off = u64::from(order.u32(&v));
        if off + (need * size) as u64 > len {
            return Err("StripOffsets array runs past the end".into());
        }
        fetch(file, head, off, raw, need * size)?;
    }
    offsets.clear();
    for c in raw.chunks_exact(size) {
        offsets.push(if size == 2 {
            u64::from(order.u16(c))
        } else {
            u64::from(order.u32(c))
        });
    }
    Ok(())
}

/// Each strip (`strips`, of `rps` rows of `row_bytes` of `height`) checked
/// to lie inside the file (`len` bytes); strips back to back become one
/// strip of all rows, read in one call. Returns the rows per strip.
fn check_strips(
    strips: &mut Vec<u64>,
    rps: usize,
    height: usize,
    row_bytes: u64,
    len: u64,
) -> Result<usize, String> {
    for (i, &o) in strips.iter().enumerate() {
        let rows = rps.min(height - i * rps) as u64;
        if o + rows * row_bytes > len {
            return Err(format!(
                "strip {i} runs past the end of the file: truncated?"
            ));
        }
    }
    // Strips back to back: one strip of all rows, read in one call.
    let strip_bytes = rps as u64 * row_bytes;
    let contiguous = strips.windows(2).all(|w| w[1] == w[0] + strip_bytes);
    Ok(if contiguous {
        strips.truncate(1);
        height
    } else {
        rps
    })
}

/// Parse an 8-bit paletted BMP with a grey palette; `Ok(None)` for any
/// other BMP (decoded generically).
fn probe_bmp<F: FrameBytes>(
    file: &mut F,
    len: u64,
    sc: &mut Scratch,
) -> Result<Option<Probe>, String> {
    let mut h = [0u8; 54];
    file.read_at(0, &mut h)
        .map_err(|e| format!("not a BMP (header: {e})"))?;
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
    if let Some(why) = crate::source::frame_too_large(w as u64, hh as u64) {
        return Err(format!("BMP: {why}"));
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
    file.read_at(pal_off, pal).map_err(|e| e.to_string())?;
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
        colour: false,
        layout: Layout::Bmp8 {
            data_offset,
            stride,
            top_down: height < 0,
        },
    }))
}
