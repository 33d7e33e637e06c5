//! Pass 1 in order, frame by frame ([`Walk`]), taking what other threads saw
//! ahead where they looked the same way.

use super::error::TrackError;
use super::frame::FrameTrack;
use super::kept::Kept;
use super::look::{Look, LookScratch, Pass1, ScratchPool, Seen};
use super::pass1::Pass1State;
use super::settings::{search_stride, TrackSettings};
use crate::source::FrameSource;
use crate::source::SourceMeta;
use crate::util::records::Records;
use crate::util::timings::{self, Stage};

/// Pass 1 in order, frame by frame.
pub(super) struct Walk {
    pub(super) frames: Records<FrameTrack>,
    /// Pass 1's edge points, kept for pass 2 (one flat buffer), at most
    /// `kept_points_max`.
    pub(super) kept_points: Vec<[f32; 2]>,
    pub(super) kept_points_max: usize,
    pub(super) kept: Records<Option<Kept>>,
    pub(super) state: Pass1State,
    pub(super) scratch: LookScratch,
    pub(super) measured_ahead: usize,
    /// Frames not looked at: the sphere was away ([`Look::Away`]).
    pub(super) away_frames: usize,
    /// Frames searched whole ahead of the walk on every thread
    /// ([`Walk::search_ahead`]), in order, not yet taken.
    pub(super) searched: std::collections::VecDeque<(usize, Seen)>,
    /// Frames taken from `searched`.
    pub(super) searched_ahead: usize,
    /// Frames in a stride of searches ([`search_stride`], 1: every frame).
    pub(super) stride: usize,
    /// The frame the walk searched at the end of the stride it is in, and
    /// whether that search found anything: frames before it are then
    /// searched one by one, else not at all.
    pub(super) probe: Option<(usize, bool)>,
    /// That search, until the walk is at its frame.
    pub(super) probed: Option<(usize, Seen)>,
    /// Frames not searched: the search at their stride's end found nothing.
    pub(super) unsearched_frames: usize,
}

impl Walk {
    /// A walk from the first frame of `meta`'s movie, nothing seen yet.
    pub(super) fn new(meta: &SourceMeta, st: &TrackSettings) -> Walk {
        let (n, in_memory) = (meta.frame_count, st.frames_in_memory_max);
        let (h, w) = (meta.height, meta.width);
        Walk {
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
        }
    }

    /// Frame `i`: taken from `ahead` (what another thread saw there) when
    /// that thread looked at it as this walk does — a frame's measurement is
    /// a pure function of the frame and the look — else measured here.
    ///
    /// A frame the walk would search whole is searched only if the search at
    /// the end of its stride ([`search_stride`]) finds something (of the
    /// frames it looks at, from `search_of`, another thread's search of a
    /// frame further on, when it has one); else it is recorded as a search
    /// that found nothing, which is what it would have been (see
    /// [`SEARCH_STRIDE_S`]), and changes nothing a look depends on.
    pub(super) fn frame(
        &mut self,
        source: &mut dyn FrameSource,
        ctx: &Pass1,
        meta: &crate::source::SourceMeta,
        i: usize,
        ahead: Option<Seen>,
        search_of: &mut dyn FnMut(usize) -> Option<Seen>,
    ) -> Result<(), TrackError> {
        let t = meta.time_s(i)?;
        let look = self.state.look(t);
        while self.searched.front().is_some_and(|(j, _)| *j < i) {
            self.searched.pop_front();
        }
        let searched = match self.searched.front() {
            Some((j, _)) if *j == i => self.searched.pop_front().map(|(_, s)| s),
            _ => None,
        };
        // Out of view, an empty stride's frame is the search it would have
        // been; else the search made at the end of a stride
        // ([`Walk::empty_stride`]), another thread's look, or this thread's.
        let seen = if matches!(look, Look::Search)
            && self.state.out_of_view()
            && self.empty_stride(source, ctx, meta, i, search_of)?
        {
            self.unsearched_frames += 1;
            Seen {
                look,
                found: false,
                fit: None,
                points: None,
            }
        } else {
            let probed = self.probed.take_if(|(j, _)| *j == i).map(|(_, s)| s);
            match probed.filter(|m| m.look.same(&look)) {
                Some(m) => m,
                None => match ahead.filter(|m| m.look.same(&look)) {
                    Some(m) => {
                        self.measured_ahead += 1;
                        m
                    }
                    None => match searched.filter(|m| m.look.same(&look)) {
                        Some(m) => {
                            self.searched_ahead += 1;
                            m
                        }
                        None => ctx.look_at(source, i, look, &mut self.scratch)?,
                    },
                },
            }
        };
        let (kept_points, max) = (&mut self.kept_points, self.kept_points_max);
        self.kept.push(seen.points.as_ref().map(|(c, sigma, pts)| {
            let start = kept_points.len();
            let end = start + pts.len();
            if end > max {
                return Kept::Again(seen.look);
            }
            reserve_within(kept_points, end, max);
            kept_points.extend_from_slice(pts);
            Kept::Points {
                start,
                len: pts.len(),
                centre: *c,
                radial_sigma_px: *sigma,
            }
        }))?;
        let w = meta.width;
        if matches!(seen.look, Look::Away) {
            self.away_frames += 1;
        }
        let skip_away = ctx.st.skip_away;
        self.frames
            .push(self.state.step(meta, i, t, &seen, w, skip_away))?;
        Ok(())
    }

    /// Whether frame `i`, which the walk would search whole, is left
    /// unsearched: the search at the end of its stride found nothing (that
    /// search is made here when the stride starts at `i`, and kept for the
    /// frame it is of).
    pub(super) fn empty_stride(
        &mut self,
        source: &mut dyn FrameSource,
        ctx: &Pass1,
        meta: &crate::source::SourceMeta,
        i: usize,
        search_of: &mut dyn FnMut(usize) -> Option<Seen>,
    ) -> Result<bool, TrackError> {
        // Frames before a stride's end were searched one by one, or not at
        // all; its end was searched.
        match self.probe {
            Some((end, found)) if i < end => return Ok(!found),
            Some((end, _)) if i == end => {
                self.probe = None;
                return Ok(false);
            }
            _ => {}
        }
        let end = (i + self.stride - 1).min(meta.frame_count.saturating_sub(1));
        if end <= i {
            self.probe = None;
            return Ok(false);
        }
        let held = self.searched.iter().position(|(j, _)| *j == end);
        let seen = match held.and_then(|k| self.searched.remove(k)) {
            Some((_, s)) => {
                self.searched_ahead += 1;
                s
            }
            None => match search_of(end) {
                Some(s) => {
                    self.measured_ahead += 1;
                    s
                }
                None => ctx.look_at(source, end, Look::Search, &mut self.scratch)?,
            },
        };
        let found = seen.found;
        self.probe = Some((end, found));
        self.probed = Some((end, seen));
        Ok(!found)
    }

    /// The frames the walk searches whole from frame `i` on, while they
    /// find nothing, before `end`: every frame while the sphere it lost may
    /// be in view, or where it goes back over a stride after a find, else
    /// the last of each stride; none when it does not search frame `i` (or
    /// cannot read its time: [`Walk::frame`] says so) or holds the first
    /// one's search already.
    pub(super) fn searches_from(
        &self,
        meta: &crate::source::SourceMeta,
        i: usize,
        end: usize,
    ) -> std::iter::StepBy<std::ops::Range<usize>> {
        let none = (0..0).step_by(1);
        let searching = meta
            .time_s(i)
            .is_ok_and(|t| matches!(self.state.look(t), Look::Search));
        if !searching {
            return none;
        }
        let frames = match self.probe {
            _ if !self.state.out_of_view() => (i..end).step_by(1),
            Some((probe, true)) if i < probe => (i..probe.min(end)).step_by(1),
            Some((probe, _)) if i <= probe => return none,
            _ => (i + self.stride - 1..end).step_by(self.stride),
        };
        let held = |j: usize| self.searched.iter().any(|(k, _)| *k == j);
        match frames.clone().next() {
            Some(j) if !held(j) => frames,
            _ => none,
        }
    }

    /// The frames `todo` (increasing; frames the walk is about to search
    /// whole, each the same pure function of its frame alone) searched on
    /// `source` and each of `copies` at once, each reader taking the next
    /// frame in order when it is free, until one finds a sphere and fits
    /// it: the walk follows it from there (its next looks are circles), so
    /// the frames after it are left (after a find without a fit, the walk
    /// searches on). Kept for [`Walk::frame`], which takes a frame's
    /// search when it looks at the frame the same way. A frame that cannot
    /// be read is left out, and the frames after it: the walk reads it
    /// itself and reports the error.
    pub(super) fn search_ahead(
        &mut self,
        source: &mut dyn FrameSource,
        copies: &mut [Box<dyn FrameSource>],
        ctx: &Pass1,
        pool: &ScratchPool,
        todo: &[usize],
    ) {
        use rayon::prelude::*;
        use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};
        let (h, w) = self.scratch.buf.dim();
        let mut scratch: Vec<LookScratch> = copies.iter().map(|_| pool.take(h, w)).collect();
        let mut readers: Vec<(&mut dyn FrameSource, &mut LookScratch)> =
            std::iter::once((source, &mut self.scratch))
                .chain(
                    copies
                        .iter_mut()
                        .map(|c| c.as_mut() as &mut dyn FrameSource)
                        .zip(scratch.iter_mut()),
                )
                .collect();
        // The next frame of `todo` to take, and the end: past the first
        // find or failure.
        let (next, end) = (AtomicUsize::new(0), AtomicUsize::new(todo.len()));
        let done: Vec<Vec<(usize, Seen)>> = readers
            .par_iter_mut()
            .map(|(src, sc)| {
                let _pass1 = timings::start(Stage::Pass1);
                let mut out = Vec::new();
                loop {
                    let k = next.fetch_add(1, Relaxed);
                    if k >= end.load(Relaxed) {
                        break;
                    }
                    match ctx.look_at(&mut **src, todo[k], Look::Search, sc) {
                        Ok(s) => {
                            if s.fit.is_some() {
                                end.fetch_min(k + 1, Relaxed);
                            }
                            out.push((todo[k], s));
                        }
                        Err(_) => {
                            end.fetch_min(k, Relaxed);
                            break;
                        }
                    }
                }
                out
            })
            .collect();
        drop(readers);
        for sc in scratch {
            pool.give(sc);
        }
        let end = todo.get(end.into_inner()).copied().unwrap_or(usize::MAX);
        let mut done: Vec<(usize, Seen)> = done
            .into_iter()
            .flatten()
            .filter(|(i, _)| *i < end)
            .collect();
        done.sort_by_key(|(i, _)| *i);
        self.searched.extend(done);
    }
}

/// Room in `buf` for `end` items (`end` ≤ `max`): grown by doubling as
/// `extend` would, but never past `max` (doubling took a long movie's kept
/// points to 22 MB for a 16 MB budget).
pub(super) fn reserve_within<T>(buf: &mut Vec<T>, end: usize, max: usize) {
    if end > buf.capacity() {
        let cap = (2 * buf.capacity()).max(end).min(max);
        buf.reserve_exact(cap - buf.len());
    }
}
