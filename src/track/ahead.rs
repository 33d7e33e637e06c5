//! Pass 1 measured ahead: chunks of the movie followed on other threads
//! ([`speculate`]).

use super::error::TrackError;
use super::look::{Look, Pass1, ScratchPool, Seen};
use super::pass1::Pass1State;
use super::walk::Walk;
use crate::source::FrameSource;
use crate::source::SourceMeta;
use crate::util::timings::{self, Stage};

/// Chunks of pass 1 per thread in a round: the threads take them as they
/// become free, so the round ends within about one chunk of even (a
/// stretch of frames searched whole, without the sphere, costs more than
/// one followed in bands: with 2 chunks a thread the long TIFF movie's
/// walker had one searched chunk more than the other thread).
pub(super) const CHUNKS_PER_THREAD: usize = 4;

/// Pass 1's frames are measured ahead in chunks of at least this many
/// frames when more than one thread is available.
pub(super) const MIN_CHUNK_FRAMES: usize = 256;

/// Longest stride of a chunk's probes before its first find (see
/// [`speculate`]): of a stretch without the sphere, one frame in this many
/// is searched ahead.
pub(super) const PROBE_STRIDE_MAX: usize = 32;

/// Most frames the walk searches at once on every thread (see
/// [`Walk::search_ahead`]); it stops at the first find, so this bounds only
/// what an error or the chunk's end leaves unused.
pub(super) const SEARCH_AHEAD_MAX: usize = 256;

/// Pass 1 measured ahead: chunk `k + 1` of the movie (frames
/// `bounds[k + 1]..bounds[k + 2]`, for each of the `bounds.len() − 2`
/// chunks after the first) followed by another thread on one of `copies`
/// of the source (one a thread: a chunk finds none free only if a thread
/// took up a second chunk while it waited inside the first, and is then
/// left to the walk), from a search at its first frame, while the calling
/// thread walks the first chunk. Per chunk, what was seen in each frame
/// looked at (`None` for the others), up to the end or an error. Pass 1
/// proper then walks on in order and takes a frame's result from here when
/// it looks at the frame in the same way, measuring it itself otherwise
/// (the first frames of a chunk, until the predictions from its own fits
/// and from the other thread's meet on the [`PREDICTION_GRID_PX`] grid).
/// So the track is the same bits for any number of threads, and the work
/// ahead is lost only where the two disagree.
///
/// Until a chunk first finds the sphere, it probes: frames searched whole
/// with a stride doubled after each empty search up to `stride_max`
/// ([`PROBE_STRIDE_MAX`]), the frames between left out. A chunk that starts
/// while the sphere is away above the frame would otherwise search every
/// frame of a stretch that the walk does not look at ([`Look::Away`]). On
/// a find it goes back to the frame after the last empty probe and follows
/// the state machine frame by frame from there: from a state without fits
/// an empty search changes nothing that a look depends on, so from there
/// on it sees what it would have seen searching every frame.
pub(super) fn speculate(
    copies: &std::sync::Mutex<Vec<Box<dyn FrameSource>>>,
    bounds: &[usize],
    ctx: &Pass1,
    meta: &crate::source::SourceMeta,
    pool: &ScratchPool,
    stride_max: usize,
) -> Vec<Vec<Option<Seen>>> {
    use rayon::prelude::*;
    let lock = || copies.lock().unwrap_or_else(|e| e.into_inner());
    (0..bounds.len().saturating_sub(2))
        .into_par_iter()
        .map(|k| {
            let Some(mut src) = lock().pop() else {
                return Vec::new();
            };
            let _pass1 = timings::start(Stage::Pass1);
            // At most one buffer set per thread measuring ahead, kept
            // from chunk to chunk and round to round.
            let mut sc = pool.take(meta.height, meta.width);
            let mut state = Pass1State::default();
            let (first, last) = (bounds[k + 1], bounds[k + 2]);
            let mut seen: Vec<Option<Seen>> = Vec::new();
            let mut put = |i: usize, s: Seen| {
                let k = i - first;
                if seen.len() <= k {
                    seen.resize_with(k + 1, || None);
                }
                seen[k] = Some(s);
            };
            // Probing: the stride to the next probe, the frame after the
            // last empty one, and a probe's find to go back from.
            let (mut probing, mut stride, mut after_empty) = (true, 1, first);
            let mut found: Option<(usize, Seen)> = None;
            let mut i = first;
            while i < last {
                // A time or a frame that cannot be read: the walk in
                // order meets it and says so.
                let Ok(t) = meta.time_s(i) else {
                    break;
                };
                let look = state.look(t);
                let s = match found.take() {
                    Some((j, s)) if j == i && s.look.same(&look) => s,
                    other => {
                        found = other;
                        let Ok(s) = ctx.look_at(src.as_mut(), i, look, &mut sc) else {
                            break;
                        };
                        s
                    }
                };
                if probing && state.fits == 0 && matches!(look, Look::Search) {
                    if !s.found {
                        state.step(meta, i, t, &s, meta.width, ctx.st.skip_away);
                        put(i, s);
                        after_empty = i + 1;
                        i += stride;
                        stride = (2 * stride).min(stride_max.max(1));
                        continue;
                    }
                    probing = false;
                    if i > after_empty {
                        found = Some((i, s));
                        i = after_empty;
                        continue;
                    }
                }
                state.step(meta, i, t, &s, meta.width, ctx.st.skip_away);
                put(i, s);
                i += 1;
            }
            pool.give(sc);
            lock().push(src);
            seen
        })
        .collect()
}

/// Pass 1 (step 2 of [`super::track`]) over the whole movie: in rounds of
/// chunks, the first of each walked here in order while the others are
/// measured ahead on copies of the source by other threads ([`speculate`]),
/// then taken by the walk ([`take_ahead`]); on one thread (or a source that
/// cannot be copied, or a short movie) one chunk, walked. The walk, and the
/// most frames measured ahead and not yet taken at any one time.
pub(super) fn pass1(
    source: &mut dyn FrameSource,
    ctx: &Pass1,
    meta: &SourceMeta,
    pool: &ScratchPool,
) -> Result<(Walk, usize), TrackError> {
    let (n, st) = (meta.frame_count, ctx.st);
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
    let mut walk = Walk::new(meta, st);
    let mut ahead_frames_max = 0;
    timings::time(Stage::Pass1, || -> Result<(), TrackError> {
        for first in (0..chunks).step_by(per_round) {
            // This round: chunk `first` walked here, the next `ahead`
            // measured ahead meanwhile, then taken.
            let ahead = per_round.min(chunks - first) - 1;
            let (head, memo) = rayon::join(
                || -> Result<(), TrackError> {
                    for i in bounds[first]..bounds[first + 1] {
                        walk.frame(source, ctx, meta, i, None, &mut |_| None)?;
                    }
                    Ok(())
                },
                || {
                    copies.as_ref().map(|c| {
                        let b = &bounds[first..=first + 1 + ahead];
                        speculate(c, b, ctx, meta, pool, PROBE_STRIDE_MAX)
                    })
                },
            );
            head?;
            if let Some(memo) = memo {
                let held = memo.iter().flatten().filter(|s| s.is_some()).count();
                ahead_frames_max = ahead_frames_max.max(held);
                let c = copies.as_ref();
                take_ahead(
                    &mut walk, source, c, threads, &bounds, first, memo, ctx, meta, pool,
                )?;
            }
        }
        Ok(())
    })?;
    drop(copies);
    Ok((walk, ahead_frames_max))
}

/// A round's chunks measured ahead (`memo`: chunk `first + 1 + k` of
/// `bounds` the `k`-th) taken by the walk in order, each frame as
/// [`Walk::frame`] takes it. The copies are free again: the frames the walk
/// searches whole that no chunk searched are searched on them too
/// ([`Walk::search_ahead`]), one reader a thread.
#[allow(clippy::too_many_arguments)]
fn take_ahead(
    walk: &mut Walk,
    source: &mut dyn FrameSource,
    copies: Option<&std::sync::Mutex<Vec<Box<dyn FrameSource>>>>,
    threads: usize,
    bounds: &[usize],
    first: usize,
    memo: Vec<Vec<Option<Seen>>>,
    ctx: &Pass1,
    meta: &SourceMeta,
    pool: &ScratchPool,
) -> Result<(), TrackError> {
    // The copies are free again: the frames the walk searches
    // whole that no chunk searched are searched on them too.
    let mut copies = copies.map(|c| c.lock().unwrap_or_else(|e| e.into_inner()));
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
                let next = walk.searches_from(meta, i, hi.min(i + SEARCH_AHEAD_MAX));
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
                    walk.search_ahead(source, c, ctx, pool, &todo);
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
            walk.frame(source, ctx, meta, i, a, &mut search_of)?;
        }
    }
    Ok(())
}
