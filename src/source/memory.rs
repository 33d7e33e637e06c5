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
        let f = self.frames.get(index).ok_or(SourceError::FrameOutOfRange {
            path: self.meta.path.clone(),
            index,
            count: self.frames.len(),
        })?;
        let (n, w) = out.dim();
        if row0 + n > self.meta.height || w != self.meta.width {
            return Err(SourceError::RowsOutOfRange {
                path: self.meta.path.clone(),
                row0,
                row_end: row0 + n,
                height: self.meta.height,
            });
        }
        out.assign(&f.slice(s![row0..row0 + n, ..]));
        Ok(())
    }
}
