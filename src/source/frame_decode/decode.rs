//! [`FrameDecoder`]: a frame file's header and rows, into reused buffers.

use std::io::{Cursor, SeekFrom};
use std::path::Path;

use ndarray::{s, ArrayViewMut2};

use super::probe::probe;
use super::types::{io_err, FrameBytes, ImageKind, Layout, Probe, Scratch, Shape};
use crate::source::widen::widen_u8;
use crate::source::{fill_row, fill_rows, for_cols, grown, SourceError};

/// Decodes frame files one after another, keeping its buffers from one to
/// the next.
#[derive(Debug, Default)]
pub struct FrameDecoder {
    scratch: Scratch,
    row_scratch: Vec<u16>,
    u16_scratch: Vec<u16>,
}

impl FrameDecoder {
    /// For reading headers, as opening a folder does: a file is read only as
    /// far as its header.
    pub fn for_headers() -> Self {
        FrameDecoder::default()
    }

    /// For reading frames: small TIFFs and PNGs are read whole in one call.
    pub fn for_frames() -> Self {
        let mut d = FrameDecoder::default();
        d.scratch.read_whole = true;
        d
    }

    /// Read a file's header and decide how to decode it.
    pub(crate) fn probe<F: FrameBytes>(
        &mut self,
        path: &Path,
        file: &mut F,
        len: u64,
        kind: ImageKind,
    ) -> Result<Probe, SourceError> {
        probe(path, file, len, kind, &mut self.scratch)
    }

    /// The header of a frame file held in memory, read as a folder's
    /// opening reads each file's: `(width, height, bits per sample)`.
    /// `name` names it in errors.
    pub fn probe_bytes(
        &mut self,
        name: &Path,
        kind: ImageKind,
        bytes: &[u8],
    ) -> Result<(usize, usize, u8), SourceError> {
        let p = self.probe(name, &mut Cursor::new(bytes), bytes.len() as u64, kind)?;
        Ok((p.width, p.height, p.bits))
    }

    /// Rows `row0..row0 + out.nrows()` of a frame file held in memory whose
    /// header said `(width, height, bits per sample)`, decoded as a folder's
    /// frame reads decode them (another header is an error).
    pub fn read_rows_from_bytes(
        &mut self,
        name: &Path,
        kind: ImageKind,
        bytes: &[u8],
        (width, height, bits): (usize, usize, u8),
        row0: usize,
        out: &mut ArrayViewMut2<u16>,
    ) -> Result<(), SourceError> {
        let row_end = row0.saturating_add(out.nrows());
        if row_end > height {
            return Err(SourceError::RowsOutOfRange {
                path: name.to_path_buf(),
                row0,
                row_end,
                height,
            });
        }
        if out.ncols() != width {
            return Err(SourceError::BufferShape {
                path: name.to_path_buf(),
                width,
                got: out.ncols(),
            });
        }
        let len = bytes.len() as u64;
        let mut file = Cursor::new(bytes);
        self.read_rows(
            name,
            0,
            &mut file,
            len,
            kind,
            Shape {
                width,
                height,
                bits,
                first: name,
            },
            row0,
            None,
            out,
        )
    }

    /// Rows `row0..row0 + out.nrows()` of frame `index` (for messages) from
    /// `file` of `len` bytes, whose header must say `shape`'s size and bits
    /// (else an error naming the file, the frame and `shape.first`); with
    /// `cols`, only those columns of raw TIFF and BMP rows are converted
    /// (see [`crate::source::FrameSource::read_window_into`]). The caller has
    /// checked the band against that size.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn read_rows<F: FrameBytes>(
        &mut self,
        path: &Path,
        index: usize,
        file: &mut F,
        len: u64,
        kind: ImageKind,
        shape: Shape,
        row0: usize,
        cols: Option<&[std::ops::Range<usize>]>,
        out: &mut ArrayViewMut2<u16>,
    ) -> Result<(), SourceError> {
        let frame_err = |reason: String| SourceError::Frame {
            path: path.to_path_buf(),
            index,
            reason,
        };
        self.scratch.small_band = 2 * out.nrows() < shape.height;
        let p = probe(path, file, len, kind, &mut self.scratch).map_err(|e| match e {
            SourceError::Format { reason, .. } => frame_err(reason),
            other => other,
        })?;
        if (p.width, p.height, p.bits) != (shape.width, shape.height, shape.bits) {
            return Err(frame_err(format!(
                "{}×{} {}-bit, but the sequence's first frame {} is {}×{} {}-bit: \
                 one size and bit depth per folder",
                p.width,
                p.height,
                p.bits,
                shape.first.display(),
                shape.width,
                shape.height,
                shape.bits
            )));
        }
        let n = out.nrows();
        let w = p.width;
        match &p.layout {
            Layout::TiffRaw {
                big_endian,
                rows_per_strip,
            } => self.tiff_rows(
                file,
                (*big_endian, *rows_per_strip),
                &p,
                row0,
                cols,
                out,
                &frame_err,
            )?,
            Layout::Bmp8 {
                data_offset,
                stride,
                top_down,
            } => {
                let palette = &self.scratch.palette;
                let h = p.height;
                // Stored rows for the band are contiguous; bottom-up reverses them.
                let first_stored = if *top_down { row0 } else { h - row0 - n };
                let bytes = grown(&mut self.scratch.bytes, n * stride);
                file.read_at(data_offset + (first_stored * stride) as u64, bytes)
                    .map_err(|e| frame_err(format!("reading rows: {e}")))?;
                let bytes = &*bytes;
                for j in 0..n {
                    let k = if *top_down { j } else { n - 1 - j };
                    let src = &bytes[k * stride..k * stride + w];
                    fill_row(out.slice_mut(s![j, ..]), &mut self.row_scratch, |dst| {
                        for_cols(dst, cols, |c, dst| {
                            for (d, s) in dst.iter_mut().zip(&src[c]) {
                                *d = u16::from(palette[usize::from(*s)]);
                            }
                        });
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
            Layout::Generic => self.generic_rows(path, file, &p, row0, out, &frame_err)?,
        }
        Ok(())
    }
    /// Rows of a raw TIFF (`big_endian`, `rps` rows per strip): from the
    /// file's bytes read whole at the probe, else only the band's rows read,
    /// one read per strip they lie in.
    #[allow(clippy::too_many_arguments)]
    fn tiff_rows<F: FrameBytes>(
        &mut self,
        file: &mut F,
        (big_endian, rps): (bool, usize),
        p: &Probe,
        row0: usize,
        cols: Option<&[std::ops::Range<usize>]>,
        out: &mut ArrayViewMut2<u16>,
        frame_err: &dyn Fn(String) -> SourceError,
    ) -> Result<(), SourceError> {
        let n = out.nrows();
        let w = p.width;
        let sc = &mut self.scratch;
        let bpp = usize::from(p.bits / 8);
        let row_bytes = w * bpp;
        let row_at = |strips: &[u64], r: usize| strips[r / rps] as usize + (r % rps) * row_bytes;
        if !sc.whole {
            // A small band or a large file: read only the band's
            // rows, one read per strip they lie in.
            grown(&mut sc.bytes, n * row_bytes);
            let mut r = row0;
            while r < row0 + n {
                let take = (rps - r % rps).min(row0 + n - r);
                let dst = &mut sc.bytes[(r - row0) * row_bytes..(r - row0 + take) * row_bytes];
                file.read_at(row_at(&sc.strips, r) as u64, dst)
                    .map_err(|e| frame_err(format!("reading rows: {e}")))?;
                r += take;
            }
        }
        let (whole, head, bytes, strips) = (sc.whole, &sc.head, &sc.bytes, &sc.strips);
        fill_rows(out, &mut self.row_scratch, |j, dst| {
            let src = if whole {
                let o = row_at(strips, row0 + j);
                &head[o..o + row_bytes]
            } else {
                &bytes[j * row_bytes..(j + 1) * row_bytes]
            };
            for_cols(dst, cols, |c, dst| {
                let src = &src[c.start * bpp..c.end * bpp];
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
        });
        Ok(())
    }

    /// Rows of a frame decoded whole by the `image` crate, within the
    /// decode limits.
    fn generic_rows<F: FrameBytes>(
        &mut self,
        path: &Path,
        file: &mut F,
        p: &Probe,
        row0: usize,
        out: &mut ArrayViewMut2<u16>,
        frame_err: &dyn Fn(String) -> SourceError,
    ) -> Result<(), SourceError> {
        let n = out.nrows();
        let w = p.width;
        let bytes = &mut self.scratch.bytes;
        bytes.clear();
        file.seek(SeekFrom::Start(0)).map_err(io_err(path))?;
        file.read_to_end(bytes).map_err(io_err(path))?;
        let mut reader = image::ImageReader::new(Cursor::new(&bytes[..]))
            .with_guessed_format()
            .map_err(io_err(path))?;
        // A frame the caps admit, decoded within a memory bound: a
        // failed allocation is this frame's error, not an abort.
        reader.limits(crate::source::decode_limits());
        let img = reader
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
        Ok(())
    }
}
