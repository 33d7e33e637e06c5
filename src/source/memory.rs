//! Frames already in memory as a [`FrameSource`]: for benchmarks of the
//! stages after decoding, and for tests that build frames themselves.

use super::widen::widen_u8;
use super::{Frame, FrameSource, SourceError, SourceMeta};
use ndarray::ArrayViewMut2;

/// A movie held in memory, one contiguous buffer of row-major frames: bytes
/// when every value fits in 8 bits and the movie says it is 8-bit (half the
/// memory, and half the bytes to move per read, widened on the way out),
/// 16-bit words otherwise.
#[derive(Debug, Clone)]
pub struct MemorySource {
    meta: SourceMeta,
    pixels: Pixels,
}

#[derive(Debug, Clone)]
enum Pixels {
    Bytes(Vec<u8>),
    Words(Vec<u16>),
}

impl MemorySource {
    /// Wrap `frames` (all of `meta`'s size; `meta.frame_count` is set from them).
    pub fn new(mut meta: SourceMeta, frames: Vec<Frame>) -> Result<Self, SourceError> {
        if let Some(f) = frames.iter().find(|f| f.dim() != (meta.height, meta.width)) {
            return Err(SourceError::Format {
                path: meta.path.clone(),
                reason: format!(
                    "a frame is {:?} (rows, columns) but the movie is {}×{}",
                    f.dim(),
                    meta.height,
                    meta.width
                ),
            });
        }
        meta.frame_count = frames.len();
        let mut words = Vec::with_capacity(frames.len() * meta.width * meta.height);
        for f in &frames {
            words.extend(f.iter());
        }
        Ok(Self::packed(meta, words))
    }

    /// Read every frame of another source into memory.
    pub fn load(source: &mut dyn FrameSource) -> Result<Self, SourceError> {
        let meta = source.meta().clone();
        let mut frame = Frame::zeros((meta.height, meta.width));
        let mut words = Vec::with_capacity(meta.frame_count * meta.width * meta.height);
        for i in 0..meta.frame_count {
            source.read_into(i, &mut frame)?;
            words.extend(frame.iter());
        }
        Ok(Self::packed(meta, words))
    }

    fn packed(meta: SourceMeta, words: Vec<u16>) -> Self {
        let pixels = if meta.bit_depth <= 8 && words.iter().all(|&v| v <= 0xFF) {
            Pixels::Bytes(words.iter().map(|&v| v as u8).collect())
        } else {
            Pixels::Words(words)
        };
        MemorySource { meta, pixels }
    }

    /// Rows `row0..row0 + out.nrows()` of frame `index` into `out`, through a
    /// shared reference (several threads may read one movie at once).
    pub fn read_rows(
        &self,
        index: usize,
        row0: usize,
        out: &mut ArrayViewMut2<u16>,
    ) -> Result<(), SourceError> {
        super::check_band(&self.meta, index, row0, out)?;
        let w = self.meta.width;
        let start = (index * self.meta.height + row0) * w;
        let end = start + out.nrows() * w;
        if let Some(dst) = out.as_slice_mut() {
            match &self.pixels {
                Pixels::Bytes(b) => widen_u8(&b[start..end], dst),
                Pixels::Words(v) => dst.copy_from_slice(&v[start..end]),
            }
            return Ok(());
        }
        for (k, mut row) in out.rows_mut().into_iter().enumerate() {
            let at = start + k * w;
            match &self.pixels {
                Pixels::Bytes(b) => row
                    .zip_mut_with(&ndarray::ArrayView1::from(&b[at..at + w]), |d, s| {
                        *d = u16::from(*s)
                    }),
                Pixels::Words(v) => row.assign(&ndarray::ArrayView1::from(&v[at..at + w])),
            }
        }
        Ok(())
    }
}

impl FrameSource for MemorySource {
    fn meta(&self) -> &SourceMeta {
        &self.meta
    }

    fn read_rows_into(
        &mut self,
        index: usize,
        row0: usize,
        out: &mut ArrayViewMut2<u16>,
    ) -> Result<(), SourceError> {
        self.read_rows(index, row0, out)
    }
}

/// A shared reference is a source too: several threads read one movie held
/// once (the track benchmark).
impl FrameSource for &MemorySource {
    fn meta(&self) -> &SourceMeta {
        &self.meta
    }

    fn read_rows_into(
        &mut self,
        index: usize,
        row0: usize,
        out: &mut ArrayViewMut2<u16>,
    ) -> Result<(), SourceError> {
        self.read_rows(index, row0, out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn movie() -> MemorySource {
        let meta = SourceMeta {
            width: 4,
            height: 3,
            bit_depth: 8,
            fps: 1000.0,
            frame_numbers: (0..2).collect(),
            ..SourceMeta::default()
        };
        let frames = (0..2)
            .map(|k| Frame::from_shape_fn((3, 4), |(i, j)| (100 * k + 10 * i + j) as u16))
            .collect();
        MemorySource::new(meta, frames).unwrap()
    }

    #[test]
    fn bands_are_the_frames_rows_and_out_of_range_is_an_error() {
        let mut m = movie();
        assert_eq!(m.meta().frame_count, 2);
        let mut band = Frame::zeros((2, 4));
        m.read_rows_into(1, 1, &mut band.view_mut()).unwrap();
        assert_eq!(band[[0, 0]], 110);
        assert_eq!(band[[1, 3]], 123);
        assert!(m.read_rows_into(2, 0, &mut band.view_mut()).is_err());
        assert!(m.read_rows_into(0, 2, &mut band.view_mut()).is_err());
        let wrong = MemorySource::new(m.meta().clone(), vec![Frame::zeros((2, 2))]);
        assert!(wrong.unwrap_err().to_string().contains("3×4"));
    }

    #[test]
    fn bytes_and_words_read_back_exactly_into_whole_and_strided_buffers() {
        // Values ≤ 255 in an 8-bit movie are held as bytes; a 300 in a movie
        // that says 8-bit, or any 12-bit movie, as words.
        for (bit_depth, top, bytes) in [(8, 255u16, true), (8, 300, false), (12, 255, false)] {
            let meta = SourceMeta {
                width: 5,
                height: 4,
                bit_depth,
                fps: 1000.0,
                ..SourceMeta::default()
            };
            let frames: Vec<Frame> = (0..3)
                .map(|k| {
                    Frame::from_shape_fn((4, 5), |(i, j)| {
                        ((37 * k + 11 * i + j) as u16 * 7) % (top + 1)
                    })
                })
                .collect();
            let m = MemorySource::new(meta, frames.clone()).unwrap();
            assert_eq!(
                matches!(m.pixels, Pixels::Bytes(_)),
                bytes,
                "{bit_depth} bits, top {top}"
            );
            for (k, f) in frames.iter().enumerate() {
                let mut band = Frame::zeros((2, 5));
                m.read_rows(k, 1, &mut band.view_mut()).unwrap();
                assert_eq!(band, f.slice(ndarray::s![1..3, ..]));
                // Every other column of a wider buffer: not one slice.
                let mut wide = Frame::zeros((4, 10));
                let mut view = wide.slice_mut(ndarray::s![.., ..;2]);
                m.read_rows(k, 0, &mut view).unwrap();
                assert_eq!(view, *f);
            }
        }
    }
}
