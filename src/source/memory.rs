//! Frames already in memory as a [`FrameSource`]: for benchmarks of the
//! stages after decoding, and for tests that build frames themselves.

use super::{Frame, FrameSource, SourceError, SourceMeta};
use ndarray::{s, ArrayViewMut2};

/// A movie held in memory.
#[derive(Debug, Clone)]
pub struct MemorySource {
    meta: SourceMeta,
    frames: Vec<Frame>,
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
        Ok(MemorySource { meta, frames })
    }

    /// Frame `index` (panics when out of range: for benchmarks and tests).
    pub fn frame(&self, index: usize) -> &Frame {
        &self.frames[index]
    }

    /// Read every frame of another source into memory.
    pub fn load(source: &mut dyn FrameSource) -> Result<Self, SourceError> {
        let meta = source.meta().clone();
        let mut frames = Vec::with_capacity(meta.frame_count);
        for i in 0..meta.frame_count {
            let mut f = Frame::zeros((meta.height, meta.width));
            source.read_into(i, &mut f)?;
            frames.push(f);
        }
        Self::new(meta, frames)
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
        super::check_band(&self.meta, index, row0, out)?;
        let (n, f) = (out.nrows(), &self.frames[index]);
        out.assign(&f.slice(s![row0..row0 + n, ..]));
        Ok(())
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
            frame_numbers: vec![0, 1],
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
}
