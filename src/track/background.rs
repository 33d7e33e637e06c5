//! Step 1 of [`super::track`]: the background and the surface line.

use super::error::TrackError;
use super::settings::TrackSettings;
use crate::detect::background::GainRegion;
use crate::detect::background_rows::{from_sample_rows, SampleRows};
use crate::detect::surface::fit_surface;
use crate::detect::{Background, SurfaceLine};
use crate::source::{FrameSource, SourceError};
use crate::util::timings::{self, Stage};

/// Stage 1 of `track`: the background from `st.background_frames` whole
/// frames spread evenly over the movie, with the sphere masked out of each
/// (the plain median when no sphere is found in them), read a band of rows
/// at a time on every thread ([`from_sample_rows`]), and the surface line
/// fitted to it, or the configuration's: `(background, line, from_config)`.
/// Its cost does not depend on the movie's length.
pub fn background_and_surface(
    source: &mut dyn FrameSource,
    st: &TrackSettings,
) -> Result<(Background, SurfaceLine, bool), TrackError> {
    let meta = source.meta().clone();
    let n = meta.frame_count;
    if n < 8 {
        return Err(TrackError::TooShort(n));
    }
    let (h, w) = (meta.height, meta.width);
    let k = st.background_frames.clamp(3, n);
    let indices: Vec<usize> = (0..k)
        .map(|i| ((i * (n - 1) + (k - 1) / 2) / (k - 1).max(1)).min(n - 1))
        .collect();
    // Read on every thread, each with its own copy of the source.
    let threads = rayon::current_num_threads().min(k);
    let mut copies: Vec<Box<dyn FrameSource>> = if threads > 1 {
        (1..threads).map_while(|_| source.try_clone()).collect()
    } else {
        Vec::new()
    };
    let mut readers: Vec<SampleReader> = std::iter::once(source)
        .chain(copies.iter_mut().map(|c| c.as_mut()))
        .map(|source| SampleReader {
            source,
            indices: &indices,
        })
        .collect();
    // With the sphere masked out of each sample; if no circle can be fitted
    // to any dark group (no sphere in these frames), the plain median.
    let bg = timings::time(Stage::Background, || {
        from_sample_rows(
            &mut readers,
            k,
            (h, w),
            GainRegion::default(),
            &st.coarse,
            6.0,
        )
    })?
    .map_err(TrackError::Background)?;
    Ok(match &st.surface_override {
        Some(s) => (bg, *s, true),
        None => {
            let s = timings::time(Stage::Surface, || fit_surface(&bg, &st.surface))
                .map_err(TrackError::Surface)?;
            (bg, s, false)
        }
    })
}

/// The background's sample frames, frame `k` being `indices[k]` of `source`.
pub(super) struct SampleReader<'a> {
    pub(super) source: &'a mut dyn FrameSource,
    pub(super) indices: &'a [usize],
}

impl SampleRows for SampleReader<'_> {
    type Error = SourceError;

    fn read_rows(
        &mut self,
        k: usize,
        row0: usize,
        cols: &[std::ops::Range<usize>],
        out: &mut ndarray::ArrayViewMut2<u16>,
    ) -> Result<(), SourceError> {
        timings::time(Stage::Read, || {
            self.source
                .read_window_into(self.indices[k], row0, cols, out)
        })
    }
}
