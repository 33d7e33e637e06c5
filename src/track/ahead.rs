//! Pass 1 measured ahead: chunks of the movie followed on other threads
//! ([`speculate`]).

use super::look::{Look, Pass1, ScratchPool, Seen};
use super::pass1::Pass1State;
use crate::source::FrameSource;
use crate::timings::{self, Stage};

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
