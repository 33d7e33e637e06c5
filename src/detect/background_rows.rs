//! The background from sample frames read a few rows at a time, so that
//! they are never all held whole: the same numbers as
//! [`Background::from_frames_with_sphere`] (or, where that fails,
//! [`Background::from_frames`]) on those frames held in memory.
//!
//! Holding the samples whole cost 2 bytes a pixel a frame, first touched
//! (eight 1280 × 800 frames: 16 MB, about 10 ms of page faults on the
//! project's VM). Here each thread reads its sample frames whole, one after
//! another, into one buffer, keeping of each only what passes 1 and 2 need
//! (the frame binned 2×2, a quarter of it; whole when small) and its sums
//! over the flicker strips; pass 3 then reads a band of rows of every
//! sample at a time into that same buffer (a second read of each frame,
//! from the page cache) and takes the per-pixel medians of those rows.

use super::background::{
    clamp_region, fill_covered, gains_from_sums, median_columns, plain_median_row, reference_sum,
    Background, GainRegion, ReferenceGains, SphereMedian,
};
use super::background_sphere::{binned_pass, circles_and_line, coarse_view};
use super::coarse::CoarseParams;
use super::columns::{near_columns, MIN_COLUMNS};
use super::DetectError;
use ndarray::{s, Array2, ArrayViewMut2};
use std::ops::Range;

/// Where [`from_sample_rows`] reads its `n` sample frames, all of one shape.
pub trait SampleRows: Send {
    /// What a read can fail with.
    type Error: Send;
    /// Rows `row0..row0 + out.nrows()` of sample frame `k` into `out`: at
    /// least the columns `cols` (ranges in increasing order), the others
    /// may keep what they held
    /// ([`crate::source::FrameSource::read_window_into`]).
    fn read_rows(
        &mut self,
        k: usize,
        row0: usize,
        cols: &[Range<usize>],
        out: &mut ArrayViewMut2<u16>,
    ) -> Result<(), Self::Error>;
}

/// Most rows of every sample that pass 3 reads at once.
const BAND_ROWS_MAX: usize = 64;

/// The background of `n` sample frames of `h × w` px read through
/// `readers` (one per thread, each reading every frame), with the sphere
/// masked out of each ([`Background::from_frames_with_sphere`], with
/// `coarse` and `pad_px`); where passes 1 and 2 fail (no sphere found in
/// the samples), the plain median ([`Background::from_frames`]). The outer
/// error is the first read that failed, in the frames' order; the inner
/// one what the background could not do.
pub fn from_sample_rows<R: SampleRows>(
    readers: &mut [R],
    n: usize,
    (h, w): (usize, usize),
    region: GainRegion,
    coarse: &CoarseParams,
    pad_px: f64,
) -> Result<Result<Background, DetectError>, R::Error> {
    use rayon::prelude::*;
    if n == 0 || readers.is_empty() {
        return Ok(Err(DetectError::NoBackgroundFrames));
    }
    let region = clamp_region(w, region);
    let binned = binned_pass(w, h);
    let groups = readers.len().min(n);
    // Rows of every sample read at once in pass 3 (even: binned rows pair
    // up), and one buffer per thread that holds a whole frame or them.
    let band = (h / n).clamp(2, BAND_ROWS_MAX) & !1;
    let mut buffers: Vec<Array2<u16>> = (0..groups)
        .map(|_| Array2::zeros((h.max(n * band), w)))
        .collect();
    // Passes 1 and 2's view of each frame and its strip sum.
    let seen = first_views(
        &mut readers[..groups],
        &mut buffers,
        n,
        (h, w),
        region,
        binned,
    )?;
    let sums: Vec<[f64; 2]> = seen.iter().map(|s| s.1).collect();
    let ReferenceGains {
        pooled: gains,
        inverse_by_column: inv,
    } = match gains_from_sums(&sums, w, region) {
        Ok(g) => g,
        Err(e) => return Ok(Err(e)),
    };
    let views: Vec<&[u16]> = seen.iter().map(|s| s.0.as_slice()).collect();
    let found = circles_and_line(&views, w, h, &gains, region, coarse).ok();
    drop(views);
    drop(seen);
    // The columns near the sphere and the strips are read for every sample,
    // the first sample's whole rows (its levels elsewhere).
    let near_cols = found
        .as_ref()
        .map_or((0, w), |f| near_columns(&f.0, w, MIN_COLUMNS));
    let cols = median_columns(near_cols, w, region);
    let whole = 0..w;
    // Pass 3, a band of rows at a time, the bands shared out between the
    // threads in order.
    let mut levels = vec![f32::NAN; w * h];
    let bands = h.div_ceil(band);
    let mut parts: Vec<(usize, &mut [f32])> = Vec::with_capacity(groups);
    let mut rest = levels.as_mut_slice();
    for g in 0..groups {
        let (first, end) = (g * bands / groups, (g + 1) * bands / groups);
        let rows = (end * band).min(h) - (first * band).min(h);
        let (part, tail) = rest.split_at_mut(rows * w);
        parts.push((first * band, part));
        rest = tail;
    }
    let circles = found.as_ref().map(|f| f.0.as_slice());
    let read = readers[..groups]
        .par_iter_mut()
        .zip(buffers.par_iter_mut())
        .zip(parts)
        .map(|((reader, buf), (row0, part))| {
            let mut sphere = circles.map(|c| SphereMedian::new(&inv, c, pad_px, w, cols.clone()));
            let mut column = vec![0f64; n];
            for (b, out) in part.chunks_mut(band * w).enumerate() {
                let r0 = row0 + b * band;
                let rows = out.len() / w;
                for k in 0..n {
                    let mut dst = buf.slice_mut(s![k * band..k * band + rows, ..]);
                    let read = if k == 0 {
                        std::slice::from_ref(&whole)
                    } else {
                        &cols[..]
                    };
                    reader.read_rows(k, r0, read, &mut dst)?;
                }
                let data = buf.as_slice().expect("a whole buffer is contiguous");
                let at = |k: usize, i: usize| &data[(k * band + i) * w..][..w];
                for (i, out) in out.chunks_exact_mut(w).enumerate() {
                    match sphere.as_mut() {
                        Some(m) => m.row(r0 + i, |k| at(k, i), out),
                        None => plain_median_row(|k, j| at(k, i)[j], &inv, &mut column, out),
                    }
                }
            }
            Ok(())
        })
        .collect::<Vec<Result<(), R::Error>>>();
    for r in read {
        r?;
    }
    if let Some((_, surface)) = &found {
        fill_covered(&mut levels, w, h, surface.as_ref(), near_cols);
    }
    Ok(Ok(Background {
        width: w,
        height: h,
        levels,
        region,
        gains,
        near_cols,
    }))
}

/// Passes 1 and 2's view of each of the `n` sample frames (binned when the
/// frame is large, [`binned_pass`]) and its strip sum, the frames shared out
/// in order between `readers` (one buffer each); the first read that
/// failed, in the frames' order.
#[allow(clippy::type_complexity)]
fn first_views<R: SampleRows>(
    readers: &mut [R],
    buffers: &mut [Array2<u16>],
    n: usize,
    (h, w): (usize, usize),
    region: GainRegion,
    binned: bool,
) -> Result<Vec<(Vec<u16>, [f64; 2])>, R::Error> {
    use rayon::prelude::*;
    let groups = readers.len();
    readers
        .par_iter_mut()
        .zip(buffers.par_iter_mut())
        .enumerate()
        .map(|(g, (reader, buf))| {
            let mut out = Vec::new();
            for k in g * n / groups..(g + 1) * n / groups {
                let mut frame = buf.slice_mut(s![..h, ..]);
                if let Err(e) = reader.read_rows(k, 0, std::slice::from_ref(&(0..w)), &mut frame) {
                    return (out, Some(e));
                }
                let data = frame
                    .as_slice()
                    .expect("a buffer's leading rows are contiguous");
                let sum = reference_sum(data, w, region);
                let view = if binned {
                    coarse_view(data, w, h)
                } else {
                    data.to_vec()
                };
                out.push((view, sum));
            }
            (out, None)
        })
        .collect::<Vec<_>>()
        .into_iter()
        .try_fold(Vec::with_capacity(n), |mut all, (part, err)| {
            all.extend(part);
            err.map_or(Ok(all), Err)
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::surface::{fit_surface, SurfaceParams};
    use crate::detect::synth::{self, PillarBand, Scene};
    use crate::source::Frame;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Sample frames held in memory; frame `fail` cannot be read.
    struct Held<'a> {
        frames: &'a [Frame],
        fail: Option<usize>,
    }

    impl SampleRows for Held<'_> {
        type Error = String;
        fn read_rows(
            &mut self,
            k: usize,
            row0: usize,
            cols: &[Range<usize>],
            out: &mut ArrayViewMut2<u16>,
        ) -> Result<(), String> {
            if self.fail == Some(k) {
                return Err(format!("frame {k} unreadable"));
            }
            // Only `cols`; the others hold what no frame does.
            out.fill(7);
            let rows = row0..row0 + out.nrows();
            for c in cols {
                out.slice_mut(s![.., c.clone()])
                    .assign(&self.frames[k].slice(s![rows.clone(), c.clone()]));
            }
            Ok(())
        }
    }

    /// `n` frames `w × h` with flicker and noise, a pillar band near the
    /// bottom, and (with `radius`) a sphere moving down by 6 px a frame.
    fn frames(w: usize, h: usize, n: usize, radius: Option<f64>, seed: u64) -> Vec<Frame> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|k| {
                let scene = Scene {
                    width: w,
                    height: h,
                    background: 200.0,
                    vignetting: 0.1,
                    sphere_transmission: 0.2,
                    disk: radius.map(|r| (0.45 * w as f64, r + 2.0 + 6.0 * k as f64, r)),
                    band: Some(PillarBand {
                        row0_px: 0.85 * h as f64,
                        slope: 0.002,
                        pillar_level: 60.0,
                        channel_level: 90.0,
                        period_px: 40.0,
                        solid_fraction: 0.625,
                    }),
                    blur_px: 1.0,
                };
                let gain = 1.0 + 0.03 * (2.0 * rng.gen::<f64>() - 1.0);
                synth::quantize(&scene.render(), gain, 255, || {
                    2.0 * (rng.gen::<f64>() - 0.5)
                })
            })
            .collect()
    }

    fn bits(bg: &Background) -> (Vec<u32>, Vec<u64>, usize, usize, GainRegion) {
        (
            bg.levels.iter().map(|v| v.to_bits()).collect(),
            bg.gains.iter().map(|g| g.to_bits()).collect(),
            bg.width,
            bg.height,
            bg.region,
        )
    }

    #[test]
    fn rows_read_in_bands_give_the_bits_of_whole_frames() {
        let coarse = CoarseParams::default();
        // Binned passes (even and odd sizes), whole-frame passes (small),
        // and no sphere but a dark bar no circle fits (no circle: every
        // frame counts as sphere-free).
        for (w, h, n, radius) in [
            (512, 384, 8, Some(40.0)),
            // Wider than the window near the sphere (columns 240..752).
            (1100, 140, 8, Some(12.0)),
            (301, 203, 7, Some(25.0)),
            (100, 90, 8, Some(12.0)),
            (256, 192, 8, None),
        ] {
            let mut held = frames(w, h, n, radius, (w * h) as u64);
            if radius.is_none() {
                // A dark straight bar, to which no circle can be fitted.
                for f in held.iter_mut() {
                    f.slice_mut(s![40..42, 30..200]).fill(20);
                }
            }
            let views: Vec<_> = held.iter().map(|f| f.view()).collect();
            let whole =
                Background::from_frames_with_sphere(&views, GainRegion::default(), &coarse, 6.0);
            let whole = whole.unwrap_or_else(|e| panic!("{w}×{h}: {e}"));
            for threads in [1, 2, 3] {
                let mut readers: Vec<Held> = (0..threads)
                    .map(|_| Held {
                        frames: &held,
                        fail: None,
                    })
                    .collect();
                let rows =
                    from_sample_rows(&mut readers, n, (h, w), GainRegion::default(), &coarse, 6.0)
                        .unwrap()
                        .unwrap();
                assert!(
                    bits(&rows) == bits(&whole),
                    "{w}×{h}, {threads} readers: not the same background"
                );
            }
        }
    }

    #[test]
    fn columns_far_from_the_sphere_change_nothing_near_it() {
        // 1 100 px wide, the sphere (R 12 px) at x 495: the medians are
        // taken in columns 240..752 and the strips; columns 880..1076 lie
        // beyond them.
        let (w, h, n) = (1100, 140, 8);
        let held = frames(w, h, n, Some(12.0), 11);
        let coarse = CoarseParams::default();
        let background = |frames: &[Frame]| {
            let mut readers = [Held { frames, fail: None }];
            from_sample_rows(&mut readers, n, (h, w), GainRegion::default(), &coarse, 6.0)
                .unwrap()
                .unwrap()
        };
        // Two different darkenings (10–20 %) of those columns in every
        // sample but the first, whose pixels they are in the levels (and,
        // the others darker, in the samples' maximum).
        let darkened = |seed: u64| -> Vec<Frame> {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut f = held.clone();
            for frame in f.iter_mut().skip(1) {
                for v in frame.slice_mut(s![.., 880..1076]).iter_mut() {
                    *v = (*v as f64 * rng.gen_range(0.8..0.9)).round() as u16;
                }
            }
            f
        };
        let (a, b) = (darkened(1), darkened(2));
        let (bg_a, bg_b) = (background(&a), background(&b));
        assert_eq!(bg_a.near_cols, (240, 752));
        assert!(
            bits(&bg_a) == bits(&bg_b),
            "the far columns moved the background"
        );
        let line = |bg: &Background| {
            let l = fit_surface(bg, &SurfaceParams::default()).unwrap();
            (
                l.row0_px.to_bits(),
                l.slope.to_bits(),
                l.model_err_px.to_bits(),
            )
        };
        assert_eq!(line(&bg_a), line(&bg_b), "the far columns moved the line");
        // A median over every column sees them.
        let plain = |f: &[Frame]| {
            let views: Vec<_> = f.iter().map(|f| f.view()).collect();
            Background::from_frames(&views, GainRegion::default()).unwrap()
        };
        assert!(bits(&plain(&a)) != bits(&plain(&b)));
    }

    #[test]
    fn a_sample_that_cannot_be_read_is_the_error() {
        let held = frames(160, 140, 8, Some(20.0), 5);
        for threads in [1, 2] {
            let mut readers: Vec<Held> = (0..threads)
                .map(|_| Held {
                    frames: &held,
                    fail: Some(5),
                })
                .collect();
            let got = from_sample_rows(
                &mut readers,
                8,
                (140, 160),
                GainRegion::default(),
                &CoarseParams::default(),
                6.0,
            );
            assert_eq!(got.err().as_deref(), Some("frame 5 unreadable"));
        }
        let mut none: Vec<Held> = Vec::new();
        let got = from_sample_rows(
            &mut none,
            8,
            (140, 160),
            GainRegion::default(),
            &CoarseParams::default(),
            6.0,
        );
        assert!(matches!(got, Ok(Err(DetectError::NoBackgroundFrames))));
    }
}
