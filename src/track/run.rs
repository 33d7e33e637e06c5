//! The tracker's steps in order ([`track`]): background and surface, pass 1,
//! calibration, pass 2, outliers.

use super::ahead::{
    speculate, CHUNKS_PER_THREAD, MIN_CHUNK_FRAMES, PROBE_STRIDE_MAX, SEARCH_AHEAD_MAX,
};
use super::background::background_and_surface;
use super::band::measure_in_band;
use super::error::{upside_down_hint, TrackError};
use super::frame::{Flag, FrameTrack};
use super::kept::{Kept, KeptRef};
use super::look::{Look, LookScratch, Pass1, ScratchPool, Seen};
use super::outliers;
use super::pass1::Pass1State;
use super::pass2::{hold, remeasure, settle, Held};
use super::settings::{search_stride, TrackSettings};
use super::types::Track;
use super::walk::Walk;
use crate::detect::calibrate::{calibrate_radius, full_circle};
use crate::detect::circle::FitScratch;
use crate::detect::{Circle, CircleFit, SurfaceLine};
use crate::records::Records;
use crate::source::FrameSource;
use crate::timings::{self, Stage};

/// Systematic uncertainty of the calibrated R_px (see `track`).
pub const RADIUS_SYSTEMATIC_PX: f64 = 0.002;

/// Track the sphere through `source` (see the module doc).
pub fn track(source: &mut dyn FrameSource, st: &TrackSettings) -> Result<Track, TrackError> {
    let meta = source.meta().clone();
    let n = meta.frame_count;
    if n < 8 {
        return Err(TrackError::TooShort(n));
    }
    let (h, w) = (meta.height, meta.width);

    // 1. Background and surface.
    let (bg, surface, surface_from_config) = background_and_surface(source, st)?;

    // 2. Pass 1, radius free.
    let ctx = Pass1::new(&bg, &surface, st);
    // Chunks of the movie measured ahead by other threads, while this one
    // walks the first of each round of `per_round` chunks (see
    // `speculate`); chunks of at most `chunk_frames_max` frames.
    let threads = rayon::current_num_threads();
    let per_round = (threads * CHUNKS_PER_THREAD).min(n / MIN_CHUNK_FRAMES);
    // One copy of the source a thread measuring ahead, not one a chunk: a
    // copy's buffers hold a whole frame file (1 MB at 1280 × 800).
    let copies: Option<std::sync::Mutex<Vec<Box<dyn FrameSource>>>> =
        if threads >= 2 && per_round >= 2 {
            (0..threads.min(per_round - 1))
                .map(|_| source.try_clone())
                .collect::<Option<Vec<_>>>()
                .map(std::sync::Mutex::new)
        } else {
            None
        };
    // Whole rounds, so that every round has work for every thread.
    let (per_round, chunks) = match &copies {
        Some(_) => (
            per_round,
            per_round * n.div_ceil(per_round * st.chunk_frames_max.max(1)),
        ),
        None => (1, 1),
    };
    let bounds: Vec<usize> = (0..=chunks).map(|k| k * n / chunks).collect();
    let pool = ScratchPool::default();
    let in_memory = st.frames_in_memory_max;
    let mut walk = Walk {
        frames: Records::with_capacity(n, in_memory),
        kept_points: Vec::new(),
        kept_points_max: st.kept_points_max,
        kept: Records::with_capacity(n, in_memory),
        state: Pass1State::default(),
        scratch: LookScratch::new(h, w),
        measured_ahead: 0,
        away_frames: 0,
        searched: std::collections::VecDeque::new(),
        searched_ahead: 0,
        stride: if st.probe_searches {
            search_stride(meta.fps)
        } else {
            1
        },
        probe: None,
        probed: None,
        unsearched_frames: 0,
    };
    let mut ahead_frames_max = 0;
    timings::time(Stage::Pass1, || -> Result<(), TrackError> {
        for first in (0..chunks).step_by(per_round) {
            // This round: chunk `first` walked here, the next `ahead`
            // measured ahead meanwhile, then taken.
            let ahead = per_round.min(chunks - first) - 1;
            let (head, memo) = rayon::join(
                || -> Result<(), TrackError> {
                    for i in bounds[first]..bounds[first + 1] {
                        walk.frame(source, &ctx, &meta, i, None, &mut |_| None)?;
                    }
                    Ok(())
                },
                || {
                    copies.as_ref().map(|c| {
                        let b = &bounds[first..=first + 1 + ahead];
                        speculate(c, b, &ctx, &meta, &pool, PROBE_STRIDE_MAX)
                    })
                },
            );
            head?;
            if let Some(memo) = memo {
                let held = memo.iter().flatten().filter(|s| s.is_some()).count();
                ahead_frames_max = ahead_frames_max.max(held);
                // The copies are free again: the frames the walk searches
                // whole that no chunk searched are searched on them too.
                let mut copies = copies
                    .as_ref()
                    .map(|c| c.lock().unwrap_or_else(|e| e.into_inner()));
                for (k, mut ahead) in memo.into_iter().enumerate() {
                    let (lo, hi) = (bounds[first + k + 1], bounds[first + k + 2]);
                    // A chunk's search of a frame, and whether it fitted
                    // a sphere (after a find without a fit the walk
                    // searches on).
                    let searched = |ahead: &[Option<Seen>], j: usize| match ahead.get(j - lo) {
                        Some(Some(s)) if matches!(s.look, Look::Search) => Some(s.fit.is_some()),
                        _ => None,
                    };
                    for i in lo..hi {
                        if let Some(c) = copies.as_deref_mut() {
                            let next = walk.searches_from(&meta, i, hi.min(i + SEARCH_AHEAD_MAX));
                            if next
                                .clone()
                                .next()
                                .is_some_and(|j| searched(&ahead, j).is_none())
                            {
                                let mut todo = Vec::new();
                                for j in next {
                                    match searched(&ahead, j) {
                                        Some(true) => break,
                                        Some(false) => {}
                                        None => todo.push(j),
                                    }
                                }
                                // One reader a thread.
                                let readers = threads.saturating_sub(1).min(c.len());
                                let c = &mut c[..readers];
                                walk.search_ahead(source, c, &ctx, &pool, &todo);
                            }
                        }
                        let a = ahead.get_mut(i - lo).and_then(Option::take);
                        // A frame further on that the walk searches
                        // before this one: the chunk's search of it.
                        let mut search_of = |j: usize| {
                            j.checked_sub(lo)
                                .and_then(|k| ahead.get_mut(k))
                                .and_then(|s| s.take_if(|s| matches!(s.look, Look::Search)))
                        };
                        walk.frame(source, &ctx, &meta, i, a, &mut search_of)?;
                    }
                }
            }
        }
        Ok(())
    })?;
    drop(copies);
    let Walk {
        mut frames,
        kept_points,
        mut kept,
        state,
        scratch,
        measured_ahead,
        away_frames,
        searched_ahead,
        unsearched_frames,
        ..
    } = walk;
    frames.flush()?;
    kept.flush()?;
    let history = state.fits;
    if history == 0 {
        return Err(TrackError::NoSphere { frames: n });
    }

    // 3. Calibration (its list of the free fits gone before pass 2, the
    // tracker's peak of memory).
    // Only the whole circles: the only fits the calibration takes.
    let cal = {
        let whole: Vec<CircleFit> = frames
            .iter()
            .filter_map(|f| f.free)
            .filter(|f| full_circle(f, w, h, Some(&surface), &st.edge))
            .collect();
        frames.check()?;
        match timings::time(Stage::Pass1, || {
            calibrate_radius(&whole, w, h, Some(&surface), &st.edge, 3)
        }) {
            Some(cal) => cal,
            None => {
                let fits: Vec<CircleFit> = frames.iter().filter_map(|f| f.free).collect();
                frames.check()?;
                return Err(TrackError::NoCalibration {
                    found: whole.len(),
                    upside_down: upside_down_hint(&fits, &surface, &bg),
                });
            }
        }
    };
    // The statistical error of a median misses the method's systematic
    // error, measured on rendered drops at up to 0.0016 px (realistic
    // preset) and 0.0037 px (harsh): a floor of 0.002 px is added in quadrature.
    let radius_err_px = cal.sigma_px.hypot(RADIUS_SYSTEMATIC_PX);
    let (radius_px, m) = (cal.r_px, cal.frames);

    // 4. Pass 2, radius held, on pass 1's points: each frame on its own
    // (on every thread), then the frames whose held circle moved too far
    // from their normals' centre read again, in order, on this thread.
    let LookScratch {
        mut buf, mut es, ..
    } = scratch;
    // Each frame's held fit goes straight into its record (a `Held` a frame
    // held until all were done was 144 bytes a frame at the tracker's
    // peak); only the frames to read again are listed. A block of records
    // at a time (all of them when in memory): each frame on its own, then
    // the block's frames past the points' budget measured again as pass 1
    // did and held like the others.
    let mut reread: Vec<(usize, Circle)> = Vec::new();
    let mut remeasured_frames = 0;
    frames.update(|lo, block| -> Result<(), TrackError> {
        use rayon::prelude::*;
        let hi = lo + block.len();
        kept.with_block(lo, hi, |kept| -> Result<(), TrackError> {
            reread.par_extend(
                block
                    .par_iter_mut()
                    .zip(kept)
                    .enumerate()
                    .with_min_len(64)
                    .map_init(
                        || (Vec::new(), FitScratch::default()),
                        |(points, fs), (i, (ft, k))| {
                            let h = timings::time(Stage::Pass2, || match k {
                                Some(Kept::Points {
                                    start,
                                    len,
                                    centre,
                                    radial_sigma_px,
                                }) => {
                                    let k = KeptRef {
                                        points: &kept_points[*start..start + len],
                                        centre: *centre,
                                        radial_sigma_px: *radial_sigma_px,
                                    };
                                    hold(ft, Some(k), radius_px, st, points, fs)
                                }
                                // Below, with a source.
                                Some(Kept::Again(_)) => Held::NoFit,
                                None => hold(ft, None, radius_px, st, points, fs),
                            });
                            settle(ft, h).map(|p| (lo + i, p))
                        },
                    )
                    .flatten(),
            );
            let again: Vec<(usize, Look)> = kept
                .iter()
                .enumerate()
                .filter_map(|(i, k)| match k {
                    Some(Kept::Again(look)) => Some((i, *look)),
                    _ => None,
                })
                .collect();
            remeasured_frames += again.len();
            if !again.is_empty() {
                let redone = timings::time(Stage::Pass2, || {
                    remeasure(source, &ctx, block, &again, radius_px, st, &pool)
                })?;
                for ((i, _), h) in again.iter().zip(redone) {
                    reread.extend(settle(&mut block[*i], h).map(|p| (lo + *i, p)));
                }
            }
            Ok(())
        })?
    })?;
    reread.sort_by_key(|r| r.0);
    let kept_points = kept_points.len();
    drop(kept);
    drop(pool);
    // In the frames' order: the first that cannot be read is the error.
    let reread_frames = reread.len();
    let _pass2 = timings::start(Stage::Pass2);
    for (i, p) in reread {
        let mut ft = frames.get(i)?;
        ft.held = measure_in_band(
            source,
            ft.index,
            &mut buf,
            &bg,
            &p,
            &surface,
            Some(radius_px),
            st,
            &mut es,
        )?;
        if ft.held.is_none() {
            ft.flags.insert(Flag::Missing);
        }
        frames.set(i, ft)?;
    }
    // 5. The frames in flight far off their neighbours.
    let outliers = flight_outliers(&frames, radius_px, &surface, st.edge.surface_margin_px);
    frames.check()?;
    for &i in &outliers {
        let mut ft = frames.get(i)?;
        ft.flags.insert(Flag::Outlier);
        frames.set(i, ft)?;
    }
    Ok(Track {
        surface,
        surface_from_config,
        radius_px,
        radius_err_px,
        radius_frames: m,
        frames,
        background: bg,
        reread_frames,
        measured_ahead,
        kept_points,
        remeasured_frames,
        ahead_frames_max,
        away_frames,
        searched_ahead,
        unsearched_frames,
        outlier_frames: outliers.len(),
    })
}

/// Step 5 of [`track`]: the indices of the frames in free flight far off
/// their neighbours ([`outliers`]). A frame is in flight when it has a held
/// fit, its circle stays in the frame (not [`Flag::Partial`]) and its
/// bottom is above the surface line by more than `margin_px`; it is
/// checked on its held centre and, where its free fit has one, its free
/// radius with their reported errors.
pub(super) fn flight_outliers(
    frames: &Records<FrameTrack>,
    radius_px: f64,
    surface: &SurfaceLine,
    margin_px: f64,
) -> Vec<usize> {
    use outliers::{Outliers, Sample, Seen};
    let mut check = Outliers::default();
    // The records' positions (the frames' indices: a record a frame, in order).
    for (k, f) in frames.iter().enumerate() {
        let seen = match f.held {
            None => Seen::Skip,
            Some(_) if f.flags.contains(Flag::Partial) => Seen::Skip,
            Some(h) if h.z_px + radius_px >= surface.row_at(h.x_px) - margin_px => Seen::Break,
            Some(h) => {
                let r = f
                    .free
                    .and_then(|c| c.cov.sigma_r_px().map(|s| (c.r_px, s)))
                    .unwrap_or((f64::NAN, f64::NAN));
                Seen::Flight(Sample {
                    index: k,
                    t_s: f.t_s,
                    values: [
                        (h.x_px, h.cov.sigma_x_px()),
                        (h.z_px, h.cov.sigma_z_px()),
                        r,
                    ],
                })
            }
        };
        check.push(seen);
    }
    check.finish()
}
