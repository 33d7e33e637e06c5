//! Tracking: from a frame source to the sphere's trajectory.
//!
//! 1. The background and flicker reference from frames spread evenly over the
//!    movie (the sphere may be in view in some or all of them: it moves, so
//!    each pixel is uncovered in most), and the surface line from it (or the
//!    configuration's line).
//! 2. Pass 1, radius free: the sphere is found by the coarse detector (on
//!    the frame binned 2×2), then followed frame to frame. The next centre is predicted from the last
//!    three fits (constant acceleration: ballistic in flight, the contact's
//!    deceleration in contact), and only the band of rows around the
//!    predicted circle is read, through [`FrameSource::read_window_into`]:
//!    of its rows only the columns within the same reach of the circle and
//!    the flicker reference strips at the frame's edges are converted, so
//!    the cost per frame follows the sphere, not the sensor (except the
//!    copy of the band's whole rows out of the file, which are contiguous
//!    there). A frame whose
//!    fit fails is marked `missing` (never guessed); after two misses the
//!    coarse detector searches the whole frame again (`recovered`), but
//!    where the sphere was lost rising through the top of the frame: the
//!    parabola of its rise says when it is back at that height, and the
//!    frames until the last quarter of that time are not looked at
//!    ([`Look::Away`]). A long movie's bounces out of view cost nothing
//!    then. What a search would still have found there is a sliver of the
//!    sphere's cap just after the loss (fits with σ_z of pixels, marked
//!    `missing` by pass 2), and the first predictions after the return,
//!    made from the last fits, differ with it: on one real-preset drop of
//!    60, 34 poor frames moved, and one field of drops.csv in its 16th digit.
//! 3. Calibration ([`calibrate_radius`]): R_px is the median radius of the
//!    pass-1 fits whose whole circle is in view, clear of the frame's border
//!    and of the surface line.
//! 4. Pass 2: every frame refitted with the radius held at R_px (centre
//!    only), on the edge points pass 1 sampled: pass 1 keeps them (offsets
//!    from the centre of their normals, two `f32` each: 8 bytes a point, at
//!    most `8 × edge.max_normals` = 1.5 kB a frame, ~1.3 kB for R = 80 px,
//!    for the frames with a fit only, up to `kept_points_max` points: 16 MB
//!    by default, ~14 000 frames of R = 75 px; the frames past it keep only
//!    how pass 1 looked at them and are measured again that way in pass 2,
//!    to the same points, so memory stops growing with the movie there),
//!    so each frame is read and sampled once. The edge estimator does not depend on where along the normal
//!    the window sits, and a centre off by `e` moves the points by
//!    `O(e σ²/R²)` only (see [`crate::detect::edges`]), so the points of
//!    normals centred on the free circle serve the held fit as well as new
//!    ones, under the same rule as [`measure_circle`]: they are used when
//!    the held circle lies within `edge.recentre_px` of the circle their
//!    normals were centred on (centre and radius). Otherwise (a free radius
//!    far off on a short arc, or a failed fit) the frame's band is read
//!    again and measured around the held circle ([`Track::reread_frames`]).
//! 5. The frames in free flight far off the path of their neighbours are
//!    flagged [`Flag::Outlier`] ([`outliers`]); the measurement leaves them
//!    out.

mod frame;
pub mod outliers;

pub use frame::{Flag, FrameFlags, FrameTrack};

use crate::detect::background::GainRegion;
use crate::detect::background_rows::{from_sample_rows, SampleRows};
use crate::detect::calibrate::{calibrate_radius, full_circle};
use crate::detect::circle::FitScratch;
use crate::detect::coarse::{detect_coarse, BinnedBackground, CoarseParams, CoarseScratch};
pub(crate) use crate::detect::columns::window_columns;
use crate::detect::surface::{fit_surface, SurfaceParams};
use crate::detect::{
    fit_circle, measure_circle, Background, Band, Circle, CircleFit, DetectError, EdgeParams,
    EdgePoint, EdgeScratch, FitOptions, SurfaceLine,
};
use crate::records::{Put, Record, Records, Take};
use crate::source::{Frame, FrameSource, SourceError};
use crate::timings::{self, Stage};
use ndarray::s;

/// Systematic uncertainty of the calibrated R_px (see `track`).
pub const RADIUS_SYSTEMATIC_PX: f64 = 0.002;

/// Settings of the tracker.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackSettings {
    /// Frames, spread evenly over the movie, that make the background.
    pub background_frames: usize,
    pub edge: EdgeParams,
    pub coarse: CoarseParams,
    pub surface: SurfaceParams,
    /// A fixed surface line (from the configuration) instead of the detected one.
    pub surface_override: Option<SurfaceLine>,
    /// Rows read beyond the predicted circle on each side, besides the
    /// window of the edge normals.
    pub band_margin_px: f64,
    /// Most edge points pass 1 keeps for pass 2 (8 bytes each). Past it, a
    /// frame keeps only how pass 1 looked at it, and pass 2 measures it
    /// again that way: the same points, bit for bit (see [`Track`]'s
    /// `remeasured_frames`), so that the memory does not grow with the
    /// movie's length beyond this.
    pub kept_points_max: usize,
    /// Most frames in one chunk of pass 1 measured ahead by another thread
    /// (see [`speculate`]): what is measured ahead and not yet taken is at
    /// most `CHUNKS_PER_THREAD × threads − 1` such chunks, whatever the
    /// movie's length.
    pub chunk_frames_max: usize,
    /// Most frames whose records (the track's, and what pass 1 keeps of
    /// each for pass 2) are held in memory; past it, all of them go to a
    /// temporary file ([`crate::records`]) and are read back a block at a
    /// time, so that they do not grow the memory with the movie's length.
    pub frames_in_memory_max: usize,
    /// Frames are not looked at while a sphere that left through the top of
    /// the frame is on its way back ([`Look::Away`]); off, every frame
    /// without the sphere is searched whole.
    pub skip_away: bool,
    /// While no sphere is followed, one frame in a
    /// [`search_stride`] is searched whole, and on a find the frames since
    /// the last empty search are searched one by one ([`Walk::frame`]);
    /// off, every such frame is searched.
    pub probe_searches: bool,
}

/// How long (s) pass 1 may go without searching a frame while it follows
/// no sphere ([`TrackSettings::probe_searches`]). A sphere that can be
/// found stays findable much longer: one of R ≥ 3 mm at up to 5 m/s (a
/// drop from 1.3 m) takes 1.2 ms to move by its own diameter, and it is in
/// view from where it enters to where it leaves, a whole fall or rise. So
/// a stride of half a millisecond skips no frame where a search would have
/// found it, the first frame of each find is still the first frame
/// searched one by one, and a movie without the sphere for most of its
/// frames (the 10 027-frame `.cine` searched 2 393 frames whole, 41 % of
/// its CPU time on one thread) searches about one in five at 10 000
/// frames/s.
pub const SEARCH_STRIDE_S: f64 = 0.5e-3;

/// Most frames in a stride ([`SEARCH_STRIDE_S`]).
pub const SEARCH_STRIDE_MAX: usize = 16;

/// Frames in a stride at `fps` frames/s: at least 1 (every frame).
pub fn search_stride(fps: f64) -> usize {
    let frames = (fps * SEARCH_STRIDE_S).floor();
    if frames.is_finite() && frames >= 1.0 {
        (frames as usize).min(SEARCH_STRIDE_MAX)
    } else {
        1
    }
}

/// [`TrackSettings::kept_points_max`] by default: 16 MB of points, about
/// 14 000 frames of a sphere of R = 75 px (150 points a frame).
pub const KEPT_POINTS_MAX: usize = 2 << 20;

/// [`TrackSettings::chunk_frames_max`] by default: on 2 threads at most 7
/// chunks of 4 096 frames are held ahead (~40 MB with the points of a
/// sphere of R = 75 px). Smaller chunks hold less but cost more: each round
/// of chunks ends waiting for its slowest chunk (chunks of 2 048 made a
/// 31 000-frame movie 13 % slower on 2 threads than chunks of 8 192, in
/// four rounds instead of one, with 2 chunks a thread).
pub const CHUNK_FRAMES_MAX: usize = 4096;

/// Chunks of pass 1 per thread in a round: the threads take them as they
/// become free, so the round ends within about one chunk of even (a
/// stretch of frames searched whole, without the sphere, costs more than
/// one followed in bands: with 2 chunks a thread the long TIFF movie's
/// walker had one searched chunk more than the other thread).
const CHUNKS_PER_THREAD: usize = 4;

/// [`TrackSettings::frames_in_memory_max`] by default: 8 MB of the track's
/// records (256 bytes a frame) and 1.8 MB of pass 1's (56).
pub const FRAMES_IN_MEMORY_MAX: usize = 32_768;

/// A tracked run.
#[derive(Debug)]
pub struct Track {
    pub surface: SurfaceLine,
    /// True when the surface line came from the configuration.
    pub surface_from_config: bool,
    pub radius_px: f64,
    pub radius_err_px: f64,
    /// Frames whose full circle gave the radius.
    pub radius_frames: usize,
    /// A record a frame, in memory or in a temporary file past
    /// [`TrackSettings::frames_in_memory_max`]: walk them with
    /// [`Records::iter`], then [`Records::check`] that none failed to be
    /// read back.
    pub frames: Records<FrameTrack>,
    pub background: Background,
    /// Frames that pass 2 had to read again (see the module doc, step 4).
    pub reread_frames: usize,
    /// Frames of pass 1 measured ahead by other threads and taken as they
    /// were (see [`speculate`]); 0 on one thread.
    pub measured_ahead: usize,
    /// Edge points pass 1 kept for pass 2 (at most
    /// [`TrackSettings::kept_points_max`]).
    pub kept_points: usize,
    /// Frames with a fit whose points were past that budget: pass 2
    /// measured them again as pass 1 did (the same points).
    pub remeasured_frames: usize,
    /// Most frames measured ahead and not yet taken at any one time (0 on
    /// one thread).
    pub ahead_frames_max: usize,
    /// Frames pass 1 did not look at: the sphere was away above the frame
    /// ([`TrackSettings::skip_away`]).
    pub away_frames: usize,
    /// Frames of pass 1 searched whole on every thread at once, ahead of
    /// the walk in order, and taken (see [`Walk::search_ahead`]); 0 on one
    /// thread.
    pub searched_ahead: usize,
    /// Frames pass 1 did not search: a search further on, within a
    /// [`search_stride`], found nothing ([`TrackSettings::probe_searches`]).
    pub unsearched_frames: usize,
    /// Frames flagged [`Flag::Outlier`].
    pub outlier_frames: usize,
}

/// Why a run could not be tracked.
#[derive(Debug, thiserror::Error)]
pub enum TrackError {
    #[error(transparent)]
    Source(#[from] SourceError),
    #[error("frame {frame}: {}", plain_detect(source))]
    Detect {
        frame: i64,
        #[source]
        source: DetectError,
    },
    #[error("no sphere found: no backlit background to measure against: {0}")]
    Background(DetectError),
    #[error(
        "no sphere found: no surface line in the background ({}); if the surface is out of \
         view, give its row with --surface-row-px (or detect.surface_row_px in pipeline.toml)",
        surface_problem(.0)
    )]
    Surface(DetectError),
    #[error(
        "no sphere found in any of the {frames} frames: dropscope measures a dark, round \
         sphere against a bright backlit background, falling onto a surface whose top is a \
         horizontal line below it; no dark round shape was seen in these frames"
    )]
    NoSphere { frames: usize },
    #[error(
        "no sphere found whole: the sphere's outline is clear of the picture's border and of \
         the surface in {} (3 needed to measure its radius in pixels): a sphere only partly \
         in view, or a dark shape that is not round{upside_down}",
        frames_text(*found)
    )]
    NoCalibration {
        found: usize,
        /// When the picture looks upside down: the question whether it is
        /// ([`upside_down_hint`]); else empty.
        upside_down: String,
    },
    #[error("only {0} frames: too short a movie to find a drop in (at least 8 needed)")]
    TooShort(usize),
    #[error("a temporary file for the track's per-frame records (set TMPDIR to a folder with room): {0}")]
    Records(#[from] std::io::Error),
}

/// What dropscope measures, said where a frame shows something else.
const SCOPE: &str = "dropscope measures a sphere seen dark against a bright background \
     (backlit, side view) above a surface, and footage of anything else is beyond what it reads";

/// A detection failure in a frame in a user's words: a fit that found no
/// circle says so first, the fit's own words after it in parentheses,
/// then what dropscope measures.
fn plain_detect(e: &DetectError) -> String {
    match e {
        DetectError::Degenerate { .. } | DetectError::TooFewPoints { .. } => {
            format!("the dark shape there does not outline a circle ({e}); {SCOPE}")
        }
        _ => format!("{e}; {SCOPE}"),
    }
}

/// The question a failure asks when the picture looks upside down: the
/// darkest rows of the background (the surface band, in an upright picture
/// at the bottom) are at the top, and most circles found lie below the
/// surface line; empty otherwise. The mean background level of the top
/// tenth of the rows (in the columns the sphere's path reaches) is compared
/// with the bottom tenth's: a drop on a dark substrate filmed upright (the
/// substrate at the bottom) asks nothing, whatever its circles.
pub fn upside_down_hint(fits: &[CircleFit], surface: &SurfaceLine, bg: &Background) -> String {
    let below = fits
        .iter()
        .filter(|c| c.z_px > surface.row_at(c.x_px))
        .count();
    if fits.is_empty() || 2 * below <= fits.len() {
        return String::new();
    }
    let (c0, c1) = bg.near_cols;
    let (c0, c1) = if c1 > c0 { (c0, c1) } else { (0, bg.width) };
    let tenth = (bg.height / 10).max(1);
    let mean_of = |rows: std::ops::Range<usize>| {
        let n = (rows.len() * (c1 - c0)).max(1);
        rows.flat_map(|r| (c0..c1).map(move |c| (r, c)))
            .map(|(r, c)| f64::from(bg.at(r, c)))
            .sum::<f64>()
            / n as f64
    };
    let top = mean_of(0..tenth.min(bg.height));
    let bottom = mean_of(bg.height.saturating_sub(tenth)..bg.height);
    if top.partial_cmp(&bottom) != Some(std::cmp::Ordering::Less) {
        return String::new();
    }
    let mean_x = fits.iter().map(|c| c.x_px).sum::<f64>() / fits.len() as f64;
    format!(
        "; the picture is darkest at its top (mean level {top:.0} in the top tenth of the \
         rows, {bottom:.0} in the bottom tenth) and the sphere was seen below the surface \
         line found at row {:.0} in {below} of the {} frames where one was seen: is the \
         picture upside down? (a .cine's or Photron header's recorded flips are applied \
         unless camera.apply_flips = false or --no-flips; frame files are read as stored)",
        surface.row_at(mean_x),
        fits.len()
    )
}

/// "no frame", "1 frame only", "N frames only".
fn frames_text(n: usize) -> String {
    match n {
        0 => "no frame".into(),
        1 => "1 frame only".into(),
        n => format!("{n} frames only"),
    }
}

/// Why no surface line was found, in the words of the picture.
fn surface_problem(e: &DetectError) -> String {
    match e {
        DetectError::TooFewPoints { found, .. } => format!(
            "a horizontal edge from bright above to dark below was found in {} of the \
             background's columns, too few",
            found
        ),
        DetectError::Degenerate { .. } => {
            "the edges from bright above to dark below do not lie on one line".into()
        }
        other => other.to_string(),
    }
}

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
fn flight_outliers(
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

/// Pass 2's result `h` put into the frame's record (a fit that failed flags
/// it `missing`), or the circle to read the frame again around.
fn settle(ft: &mut FrameTrack, h: Held) -> Option<Circle> {
    ft.held = match h {
        Held::NoFit => return None,
        Held::Fit(f) => f,
        Held::Reread(p) => return Some(p),
    };
    if ft.held.is_none() {
        ft.flags.insert(Flag::Missing);
    }
    None
}

/// Pass 2 of the frames `again` (indices into `frames`, with pass 1's look
/// at each) on every thread, each with its own copy of the source: each
/// frame measured again as pass 1 looked at it — the same edge points, a
/// measurement being a pure function of the frame and the look — and held
/// on them. In `again`'s order; the first error in that order.
fn remeasure(
    source: &mut dyn FrameSource,
    ctx: &Pass1,
    frames: &[FrameTrack],
    again: &[(usize, Look)],
    radius_px: f64,
    st: &TrackSettings,
    pool: &ScratchPool,
) -> Result<Vec<Held>, TrackError> {
    use rayon::prelude::*;
    let (h, w) = (source.meta().height, source.meta().width);
    let threads = rayon::current_num_threads().min(again.len()).max(1);
    let mut copies: Vec<Box<dyn FrameSource>> =
        (1..threads).map_while(|_| source.try_clone()).collect();
    let mut sources: Vec<&mut dyn FrameSource> = std::iter::once(source)
        .chain(copies.iter_mut().map(|c| c.as_mut()))
        .collect();
    let (n, groups) = (again.len(), sources.len());
    let done: Vec<Result<Vec<Held>, TrackError>> = sources
        .par_iter_mut()
        .enumerate()
        .map(|(g, src)| {
            let _pass2 = timings::start(Stage::Pass2);
            let mut sc = pool.take(h, w);
            let (mut points, mut fs) = (Vec::new(), FitScratch::default());
            let held = again[g * n / groups..(g + 1) * n / groups]
                .iter()
                .map(|&(i, look)| {
                    let ft = &frames[i];
                    let seen = ctx.look_at(&mut **src, ft.index, look, &mut sc)?;
                    let k = seen.points.as_ref().map(|(c, sigma, pts)| KeptRef {
                        points: pts,
                        centre: *c,
                        radial_sigma_px: *sigma,
                    });
                    Ok(hold(ft, k, radius_px, st, &mut points, &mut fs))
                })
                .collect();
            pool.give(sc);
            held
        })
        .collect();
    let mut out = Vec::with_capacity(n);
    for d in done {
        out.extend(d?);
    }
    Ok(out)
}

impl Track {
    /// One-sigma uncertainty of the surface row at column `x_px`: the line
    /// fit's, plus the systematic error of the edge model it was taken with
    /// ([`SurfaceLine::edge_model_sigma_px`]) in quadrature for a detected
    /// line (a line from the configuration is taken as given).
    pub fn surface_row_err_px(&self, x_px: f64) -> f64 {
        let fit = self.surface.sigma_row_at(x_px);
        if self.surface_from_config {
            fit
        } else {
            fit.hypot(self.surface.edge_model_sigma_px())
        }
    }
}

/// Pass 2's result in one frame.
enum Held {
    /// No free fit in pass 1: nothing to hold.
    NoFit,
    /// The held fit on pass 1's points (`None`: it failed).
    Fit(Option<CircleFit>),
    /// The held circle lies too far from the normals' centre: the frame is
    /// read again and measured around this circle.
    Reread(Circle),
}

/// Pass 2 of one frame on the points pass 1 kept (see [`track`], step 4).
fn hold(
    ft: &FrameTrack,
    k: Option<KeptRef>,
    radius_px: f64,
    st: &TrackSettings,
    points: &mut Vec<EdgePoint>,
    fs: &mut FitScratch,
) -> Held {
    let (Some(f1), Some(k)) = (ft.free, k) else {
        return Held::NoFit;
    };
    let p = Circle {
        r_px: radius_px,
        ..f1.circle()
    };
    let c = k.centre;
    points.clear();
    points.extend(k.points.iter().map(|q| EdgePoint {
        x_px: c.x_px + q[0] as f64,
        z_px: c.z_px + q[1] as f64,
        weight: 1.0,
    }));
    // Tukey's weights from the first iteration, at the free fit's
    // residual scale: the start is the free fit on the same points,
    // whose Huber iterations already brought it from the prediction,
    // and holding the radius moves it by hundredths of a pixel.
    let opts = FitOptions {
        hold_radius: Some(radius_px),
        radial_sigma_px: k.radial_sigma_px,
        huber_iterations: 0,
        scale_px: Some(f1.scale_px),
        ..FitOptions::default()
    };
    let held = fit_circle(points, Some(p), &opts, fs).ok();
    let near = held.is_some_and(|f| {
        (f.x_px - c.x_px)
            .abs()
            .max((f.z_px - c.z_px).abs())
            .max((radius_px - c.r_px).abs())
            <= st.edge.recentre_px
    });
    if near {
        Held::Fit(held)
    } else {
        Held::Reread(p)
    }
}

/// What pass 1 keeps of a frame with a fit for pass 2.
#[derive(Debug, Clone, Copy)]
enum Kept {
    /// Where its edge points sit in the kept buffer, and the circle their
    /// normals were centred on (the origin of their offsets).
    Points {
        start: usize,
        len: usize,
        centre: Circle,
        radial_sigma_px: f64,
    },
    /// Past [`TrackSettings::kept_points_max`]: how pass 1 looked at it,
    /// to measure it again in pass 2.
    Again(Look),
}

/// A tag (0 nothing kept, 1 points, 2 and 3 a look to measure again: a
/// search, a circle), the points' place, a circle and the radial σ.
impl Record for Option<Kept> {
    const BYTES: usize = 1 + 8 * 2 + 8 * 4;

    fn put(&self, out: &mut Vec<u8>) {
        let none = Circle {
            x_px: 0.0,
            z_px: 0.0,
            r_px: 0.0,
        };
        let (tag, start, len, c, sigma) = match *self {
            None => (0, 0, 0, none, 0.0),
            Some(Kept::Points {
                start,
                len,
                centre,
                radial_sigma_px,
            }) => (1, start, len, centre, radial_sigma_px),
            Some(Kept::Again(Look::Search)) => (2, 0, 0, none, 0.0),
            Some(Kept::Again(Look::At(c))) => (3, 0, 0, c, 0.0),
            Some(Kept::Again(Look::Away)) => (4, 0, 0, none, 0.0),
        };
        let mut p = Put(out);
        p.u8(tag);
        p.u64(start as u64);
        p.u64(len as u64);
        for v in [c.x_px, c.z_px, c.r_px, sigma] {
            p.f64(v);
        }
    }

    fn get(b: &[u8]) -> Self {
        let mut t = Take(b);
        let (tag, start, len) = (t.u8(), t.u64() as usize, t.u64() as usize);
        let c = Circle {
            x_px: t.f64(),
            z_px: t.f64(),
            r_px: t.f64(),
        };
        let radial_sigma_px = t.f64();
        match tag {
            0 => None,
            1 => Some(Kept::Points {
                start,
                len,
                centre: c,
                radial_sigma_px,
            }),
            2 => Some(Kept::Again(Look::Search)),
            4 => Some(Kept::Again(Look::Away)),
            _ => Some(Kept::Again(Look::At(c))),
        }
    }
}

/// One frame's kept points as [`hold`] takes them.
#[derive(Debug, Clone, Copy)]
struct KeptRef<'a> {
    /// Offsets from `centre`.
    points: &'a [[f32; 2]],
    centre: Circle,
    radial_sigma_px: f64,
}

/// Predictions are rounded to multiples of this (px) before a frame is
/// measured around them. A frame's measurement is then the same bits
/// whether its prediction came from this thread's fits or from another
/// thread's fits of the same frames, which differ by ~1e-8 px once both
/// have a few frames behind them (see [`speculate`]); the rounding moves a
/// fit by `O(e σ²/R²)` with `e` ≤ 1/2048 px, below 1e-7 px.
const PREDICTION_GRID_PX: f64 = 1.0 / 1024.0;

/// Pass 1's frames are measured ahead in chunks of at least this many
/// frames when more than one thread is available.
const MIN_CHUNK_FRAMES: usize = 256;

/// Longest stride of a chunk's probes before its first find (see
/// [`speculate`]): of a stretch without the sphere, one frame in this many
/// is searched ahead.
const PROBE_STRIDE_MAX: usize = 32;

/// Most frames the walk searches at once on every thread (see
/// [`Walk::search_ahead`]); it stops at the first find, so this bounds only
/// what an error or the chunk's end leaves unused.
const SEARCH_AHEAD_MAX: usize = 256;

/// How pass 1 looks for the sphere in one frame.
#[derive(Debug, Clone, Copy)]
enum Look {
    /// The coarse detector over the whole frame.
    Search,
    /// Measured around this circle, predicted from the last fits (on the
    /// [`PREDICTION_GRID_PX`] grid).
    At(Circle),
    /// Not looked at: the sphere left through the top of the frame and is
    /// on its way back ([`Pass1State::back_in_view_s`]).
    Away,
}

impl Look {
    /// The same look, bit for bit.
    fn same(&self, other: &Look) -> bool {
        let bits = |c: &Circle| [c.x_px.to_bits(), c.z_px.to_bits(), c.r_px.to_bits()];
        match (self, other) {
            (Look::Search, Look::Search) => true,
            (Look::At(a), Look::At(b)) => bits(a) == bits(b),
            (Look::Away, Look::Away) => true,
            _ => false,
        }
    }
}

/// What pass 1 saw in one frame with one look: a pure function of the
/// frame and the look.
#[derive(Debug, Clone)]
struct Seen {
    look: Look,
    /// A search found a sphere (and measured around it).
    found: bool,
    fit: Option<CircleFit>,
    /// With a fit: the circle its normals were centred on, the radial σ and
    /// the edge points' offsets from that centre.
    points: Option<(Circle, f64, Vec<[f32; 2]>)>,
}

/// Pass 1's state between frames: the last three fits (for the
/// prediction), how many fits so far, misses in a row, searching or not,
/// the heights of the sphere's rise and, when it left through the top of
/// the frame, until when it is away.
#[derive(Debug, Clone, Default)]
struct Pass1State {
    history: Vec<(f64, Circle)>,
    fits: usize,
    misses: usize,
    following: bool,
    /// `(t, z + r)` (px) of the fits since the sphere's lowest point last
    /// moved down (its rise from the bottom of the contact), the newest
    /// [`RISE_KEPT`].
    rise: std::collections::VecDeque<(f64, f64)>,
    /// Frames before this time are not looked at ([`Look::Away`]).
    away_until_s: Option<f64>,
}

/// The return of a sphere that left rising through the top of the frame
/// ([`Pass1State::return_s`]).
#[derive(Debug, Clone, Copy)]
struct Return {
    /// The time of its last fit.
    t_last_s: f64,
    /// The time from there until its lowest point is back in the frame.
    away_s: f64,
    /// The standard error of `away_s`.
    away_err_s: f64,
    /// The rise's heights the parabola was fitted to.
    heights: usize,
}

/// The row where a sphere coming back down through the top of the frame
/// comes into view: the top edge of row 0 (pixel centres at whole rows).
const ENTRY_ROW_PX: f64 = -0.5;

/// A systematic error of the rise's heights (the lowest points of caps
/// leaving through the top of the frame), px, as a bend over the fitted
/// span ([`Pass1State::return_s`]). Measured on the bench's movies (the
/// first fit after each time away against the predicted return): on the
/// 60 000 frames/s `.cine`, whose 128 kept heights span 2.1 ms, 8–11 % of
/// the time away off, 1.3–2.0 times the scatter's standard error alone,
/// and within 0.9 σ with this bend (σ 13–15 % of the time away); on the
/// 10 000 frames/s one within 0.3 % (σ 1.3 %).
const RISE_SYSTEMATIC_PX: f64 = 0.005;

/// Heights of the rise kept for [`Pass1State::back_in_view_s`].
const RISE_KEPT: usize = 128;

/// Least fits of the rise that [`Pass1State::back_in_view_s`] takes.
const RISE_FITS_MIN: usize = 8;

/// Standard errors of the predicted return ([`Pass1State::return_s`])
/// searched before it.
const AWAY_SEARCHED_SIGMAS: f64 = 4.0;

/// Least share of the time away, at its end, searched again whatever the
/// parabola's scatter: what its error leaves out. A barrel lens bends the
/// rise's heights towards the centre harder near the top, so the apparent
/// curvature is larger and the return predicted early (searched longer);
/// air drag on a steel sphere of R ≥ 3 mm is below 1 % of its weight at
/// up to 3 m/s.
const AWAY_SEARCHED_MIN_SHARE: f64 = 0.05;

/// Least heights of the rise whose scatter is trusted for the margin
/// (the standard deviation of 21 degrees of freedom is under 0.65 of the
/// true one in 1 % of rises); a shorter rise searches the last
/// [`AWAY_SEARCHED_SHORT_SHARE`] of the time away, or more.
const AWAY_SCATTER_FITS_MIN: usize = 24;

/// Share of the time away searched after a rise of fewer than
/// [`AWAY_SCATTER_FITS_MIN`] heights: a quarter covers an error of a
/// quarter in its curvature.
const AWAY_SEARCHED_SHORT_SHARE: f64 = 0.25;

impl Pass1State {
    /// Whether a sphere that a search could find is out of view: none
    /// fitted yet, or the last fit was leaving through the top of the
    /// frame (its circle past row 0). It then comes into view and stays
    /// there much longer than a stride of searches ([`SEARCH_STRIDE_S`]);
    /// one lost in view may be hidden or unmeasurable a frame or two at a
    /// time, and every frame is searched.
    fn out_of_view(&self) -> bool {
        self.history
            .last()
            .is_none_or(|(_, c)| c.z_px - c.r_px < 0.0)
    }

    /// How to look at the frame of time `t`.
    fn look(&self, t: f64) -> Look {
        if !self.following && self.away_until_s.is_some_and(|u| t < u) {
            return Look::Away;
        }
        if self.following {
            let p = predict(&self.history, t);
            let grid = |v: f64| (v / PREDICTION_GRID_PX).round() * PREDICTION_GRID_PX;
            Look::At(Circle {
                x_px: grid(p.x_px),
                z_px: grid(p.z_px),
                r_px: grid(p.r_px),
            })
        } else {
            Look::Search
        }
    }

    /// When the sphere that was just lost is back in view, if it left
    /// through the top of the frame while rising: the return predicted by
    /// [`Pass1State::return_s`] less a margin of [`AWAY_SEARCHED_SIGMAS`]
    /// standard errors, at least [`AWAY_SEARCHED_MIN_SHARE`] of the time
    /// away ([`AWAY_SEARCHED_SHORT_SHARE`] after a rise of fewer than
    /// [`AWAY_SCATTER_FITS_MIN`] heights), at most all of it. `None`
    /// (search every frame) when it left any other way, or the rise is
    /// short or not a parabola that falls back.
    fn back_in_view_s(&self) -> Option<f64> {
        let back = self.return_s()?;
        let least = if back.heights < AWAY_SCATTER_FITS_MIN {
            AWAY_SEARCHED_SHORT_SHARE
        } else {
            AWAY_SEARCHED_MIN_SHARE
        };
        let margin_s = (AWAY_SEARCHED_SIGMAS * back.away_err_s)
            .max(least * back.away_s)
            .min(back.away_s);
        let t = back.t_last_s + back.away_s - margin_s;
        t.is_finite().then_some(t)
    }

    /// The parabola of the sphere's rise (least squares over the newer half
    /// of the rise's heights of its lowest point, at least
    /// [`RISE_FITS_MIN`]) brings that point back into the frame (to the top
    /// edge of row 0, [`ENTRY_ROW_PX`]) at its later root, with the
    /// standard error of that time: from the heights' scatter about the
    /// parabola and [`RISE_SYSTEMATIC_PX`] in quadrature. `None` when the last fit is not near the top of the frame
    /// (its top within a radius of row 0), the rise is short or not a
    /// parabola that falls back, or its lowest point never leaves the
    /// frame (a cap stays in view: it is searched for).
    fn return_s(&self) -> Option<Return> {
        let &(t_last, last) = self.history.last()?;
        if last.z_px - last.r_px >= last.r_px {
            return None;
        }
        let n = self.rise.len();
        let used = if n == RISE_KEPT { n } else { n / 2 };
        if used < RISE_FITS_MIN {
            return None;
        }
        // h = a + b·u + c·u² (the lowest point's row less the entry row),
        // u = (t − t_last) / span.
        let (t, h): (Vec<f64>, Vec<f64>) = self
            .rise
            .iter()
            .skip(n - used)
            .map(|&(t, bottom)| (t, bottom - ENTRY_ROW_PX))
            .unzip();
        let fit = crate::lsq::PolyFit::fit(&t, &h, &vec![1.0; used], 2, t_last)?;
        let (a, b, c, span) = (fit.coef()[0], fit.coef()[1], fit.coef()[2], fit.x_scale);
        // Rising (h falls) at the last fit, and falling back (h″ > 0).
        if b >= 0.0 || c <= 0.0 || b.is_nan() || c.is_nan() {
            return None;
        }
        // Out of the frame only if the parabola's lowest h is below 0.
        let disc = b * b - 4.0 * a * c;
        if disc.is_nan() || disc <= 0.0 {
            return None;
        }
        let root = disc.sqrt();
        let u = (-b + root) / (2.0 * c);
        // The root's gradient in (a, b, c) is −(1, u, u²)/h′(u), h′(u) =
        // √disc; the coefficients' covariance scaled to the heights'
        // scatter (their stated σ of 1 px is no measurement).
        let cov = &fit.fit.cov * fit.fit.chi2_red();
        let g = [1.0 / root, u / root, u * u / root];
        let var_u = crate::lsq::quad_form(&g, &cov);
        // A systematic bend of the heights the fit cannot take up in a and
        // b: RISE_SYSTEMATIC_PX times the shifted Legendre P₂(2u + 1) =
        // 6u² + 6u + 1 over the fitted span (u from −1 to 0).
        let sys_u = RISE_SYSTEMATIC_PX * (g[0] + 6.0 * g[1] + 6.0 * g[2]);
        let (away_s, away_err_s) = (u * span, (var_u.max(0.0) + sys_u * sys_u).sqrt() * span);
        (away_s.is_finite() && away_s > 0.0 && away_err_s.is_finite()).then_some(Return {
            t_last_s: t_last,
            away_s,
            away_err_s,
            heights: used,
        })
    }

    /// Take frame `i`'s result: its track entry, the state moved on.
    fn step(
        &mut self,
        meta: &crate::source::SourceMeta,
        i: usize,
        t: f64,
        seen: &Seen,
        w: usize,
        skip_away: bool,
    ) -> FrameTrack {
        let number = meta.frame_number(i);
        let mut flags = FrameFlags::default();
        let looked = match seen.look {
            Look::Search => {
                if seen.found && self.fits > 0 {
                    flags.insert(Flag::Recovered);
                }
                seen.found
            }
            Look::At(_) => true,
            Look::Away => false,
        };
        match seen.fit {
            Some(f) => {
                // The rise in the sphere's lowest point, z + r: on a cap
                // leaving through the top of the frame the free fit's
                // centre and radius wander together (r 72–79 px for a
                // 75 px sphere), its lowest edge does not. Higher than the
                // last fit also after a loss: a cap leaving slowly is lost
                // and found again frame after frame.
                let bottom = f.z_px + f.r_px;
                match self.history.last() {
                    Some(&(_, last)) if bottom < last.z_px + last.r_px => {
                        if self.rise.len() == RISE_KEPT {
                            self.rise.pop_front();
                        }
                        self.rise.push_back((t, bottom));
                    }
                    _ => self.rise.clear(),
                }
                self.away_until_s = None;
                self.misses = 0;
                self.following = true;
                self.fits += 1;
                if self.history.len() == 3 {
                    self.history.remove(0);
                }
                self.history.push((t, f.circle()));
                if f.z_px - f.r_px < 0.0 || f.x_px - f.r_px < 0.0 || f.x_px + f.r_px > w as f64 {
                    flags.insert(Flag::Partial);
                }
            }
            None => {
                if looked {
                    flags.insert(Flag::Missing);
                }
                self.misses += 1;
                if self.misses >= 2 && self.following {
                    self.following = false;
                    if skip_away {
                        self.away_until_s = self.back_in_view_s();
                    }
                }
            }
        }
        FrameTrack {
            index: i,
            frame: number,
            t_s: t,
            free: seen.fit,
            held: None,
            flags,
        }
    }
}

/// What pass 1 measures with, the same for every frame.
struct Pass1<'a> {
    bg: &'a Background,
    surface: &'a SurfaceLine,
    st: &'a TrackSettings,
    binned: Option<BinnedBackground>,
    /// The quick look's grid points, for the frames searched whole.
    dark_grid: DarkGrid,
}

/// One thread's buffers for [`Pass1::look_at`].
struct LookScratch {
    buf: Frame,
    es: EdgeScratch,
    cs: CoarseScratch,
}

impl LookScratch {
    fn new(h: usize, w: usize) -> Self {
        LookScratch {
            buf: Frame::zeros((h, w)),
            es: EdgeScratch::default(),
            cs: CoarseScratch::default(),
        }
    }
}

/// Buffers for [`Pass1::look_at`] handed from chunk to chunk: a chunk takes
/// one (or makes one) and gives it back, so that a thread first-touches a
/// whole frame and the search's buffers once, not once a chunk (at
/// 1280 × 800 about 4 MB each time).
#[derive(Default)]
struct ScratchPool(std::sync::Mutex<Vec<LookScratch>>);

impl ScratchPool {
    fn take(&self, h: usize, w: usize) -> LookScratch {
        let mut pool = self.0.lock().unwrap_or_else(|e| e.into_inner());
        pool.pop().unwrap_or_else(|| LookScratch::new(h, w))
    }

    fn give(&self, sc: LookScratch) {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).push(sc);
    }
}

impl<'a> Pass1<'a> {
    fn new(bg: &'a Background, surface: &'a SurfaceLine, st: &'a TrackSettings) -> Self {
        let (h, w) = (bg.height, bg.width);
        Pass1 {
            bg,
            surface,
            st,
            // The coarse search runs on frames binned 2×2 (a quarter of the
            // pixels); the measurement's re-centring absorbs its ~1 px error.
            binned: (w >= 128 && h >= 128).then(|| BinnedBackground::new(bg)),
            dark_grid: DarkGrid::new(bg, surface),
        }
    }

    /// Look at frame `i` as `look` says.
    fn look_at(
        &self,
        source: &mut dyn FrameSource,
        i: usize,
        look: Look,
        sc: &mut LookScratch,
    ) -> Result<Seen, TrackError> {
        let (bg, surface, st) = (self.bg, self.surface, self.st);
        let number = source_number(source, i);
        let predicted = match look {
            Look::Away => {
                return Ok(Seen {
                    look,
                    found: false,
                    fit: None,
                    points: None,
                })
            }
            Look::At(p) => Some(p),
            Look::Search => {
                timings::time(Stage::Read, || source.read_into(i, &mut sc.buf))?;
                let band = Band::frame(&sc.buf).map_err(|e| detect_err(number, e))?;
                let gain = bg.gain(&band).map_err(|e| detect_err(number, e))?.gain;
                if self.dark_grid.any_dark(&sc.buf, bg, gain, surface) {
                    match self.binned.as_ref() {
                        Some(b) => b.detect(&band, gain, Some(surface), &st.coarse, &mut sc.cs),
                        None => {
                            detect_coarse(&band, bg, gain, Some(surface), &st.coarse, &mut sc.cs)
                        }
                    }
                    .map_err(|e| detect_err(number, e))?
                    .map(|c| c.circle)
                } else {
                    None
                }
            }
        };
        let fit = match predicted {
            Some(p) => measure_in_band(
                source,
                i,
                &mut sc.buf,
                bg,
                &p,
                surface,
                None,
                st,
                &mut sc.es,
            )?,
            None => None,
        };
        let points = fit.map(|_| {
            let c = sc.es.centre;
            let pts = sc
                .es
                .points
                .iter()
                .map(|p| [(p.x_px - c.x_px) as f32, (p.z_px - c.z_px) as f32])
                .collect();
            (c, sc.es.radial_sigma_px, pts)
        });
        Ok(Seen {
            look,
            found: predicted.is_some(),
            fit,
            points,
        })
    }
}

fn source_number(source: &dyn FrameSource, i: usize) -> i64 {
    source.meta().frame_number(i)
}

/// Pass 1 in order, frame by frame.
struct Walk {
    frames: Records<FrameTrack>,
    /// Pass 1's edge points, kept for pass 2 (one flat buffer), at most
    /// `kept_points_max`.
    kept_points: Vec<[f32; 2]>,
    kept_points_max: usize,
    kept: Records<Option<Kept>>,
    state: Pass1State,
    scratch: LookScratch,
    measured_ahead: usize,
    /// Frames not looked at: the sphere was away ([`Look::Away`]).
    away_frames: usize,
    /// Frames searched whole ahead of the walk on every thread
    /// ([`Walk::search_ahead`]), in order, not yet taken.
    searched: std::collections::VecDeque<(usize, Seen)>,
    /// Frames taken from `searched`.
    searched_ahead: usize,
    /// Frames in a stride of searches ([`search_stride`], 1: every frame).
    stride: usize,
    /// The frame the walk searched at the end of the stride it is in, and
    /// whether that search found anything: frames before it are then
    /// searched one by one, else not at all.
    probe: Option<(usize, bool)>,
    /// That search, until the walk is at its frame.
    probed: Option<(usize, Seen)>,
    /// Frames not searched: the search at their stride's end found nothing.
    unsearched_frames: usize,
}

impl Walk {
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
    fn frame(
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
    fn empty_stride(
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
    fn searches_from(
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
    fn search_ahead(
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
fn reserve_within<T>(buf: &mut Vec<T>, end: usize, max: usize) {
    if end > buf.capacity() {
        let cap = (2 * buf.capacity()).max(end).min(max);
        buf.reserve_exact(cap - buf.len());
    }
}

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
fn speculate(
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

/// Stage 1 of [`track`]: the background from `st.background_frames` whole
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
struct SampleReader<'a> {
    source: &'a mut dyn FrameSource,
    indices: &'a [usize],
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

/// Grid step (px) of the quick look for a dark object before the coarse search.
const QUICK_STEP_PX: usize = 6;

/// Whether at least three points of a sparse grid above the surface line are
/// darker than half their background: a sphere of radius ≥ 10 px always
/// covers several. Saves the full coarse search on frames without a sphere.
fn anything_dark(frame: &Frame, bg: &Background, gain: f64, surface: &SurfaceLine) -> bool {
    let (h, w) = frame.dim();
    let mut dark = 0;
    for i in (QUICK_STEP_PX / 2..h).step_by(QUICK_STEP_PX) {
        for j in (QUICK_STEP_PX / 2..w).step_by(QUICK_STEP_PX) {
            if i as f64 > surface.row_at(j as f64) - 2.0 {
                continue;
            }
            if (frame[[i, j]] as f64) < 0.5 * gain * bg.at(i, j) as f64 {
                dark += 1;
                if dark >= 3 {
                    return true;
                }
            }
        }
    }
    false
}

/// The points of [`anything_dark`]'s grid above the surface line, found
/// once for a movie with their background levels, so that a frame searched
/// whole (most of a long movie's, where the sphere is out of view) is
/// checked by one pass over its grid: the same comparisons, the same
/// answer.
struct DarkGrid {
    /// Frame size the points were taken for (rows, columns).
    dim: (usize, usize),
    /// Row-major index of each point in the frame, and its background level.
    points: Vec<(u32, f32)>,
}

impl DarkGrid {
    fn new(bg: &Background, surface: &SurfaceLine) -> DarkGrid {
        let (h, w) = (bg.height, bg.width);
        let mut points = Vec::new();
        // A frame of 2^32 pixels or more is checked by `anything_dark`.
        let fits = u32::try_from(h * w).is_ok();
        if fits {
            for i in (QUICK_STEP_PX / 2..h).step_by(QUICK_STEP_PX) {
                for j in (QUICK_STEP_PX / 2..w).step_by(QUICK_STEP_PX) {
                    if i as f64 > surface.row_at(j as f64) - 2.0 {
                        continue;
                    }
                    points.push(((i * w + j) as u32, bg.at(i, j)));
                }
            }
        }
        DarkGrid {
            dim: if fits { (h, w) } else { (0, 0) },
            points,
        }
    }

    /// [`anything_dark`] of `frame`, from the points when the frame is the
    /// size they were taken for and contiguous.
    fn any_dark(&self, frame: &Frame, bg: &Background, gain: f64, surface: &SurfaceLine) -> bool {
        let data = match frame.as_slice() {
            Some(d) if frame.dim() == self.dim && !d.is_empty() => d,
            _ => return anything_dark(frame, bg, gain, surface),
        };
        let mut dark = 0;
        for &(k, level) in &self.points {
            // As `anything_dark` computes it: (0.5 · gain) · level.
            if (data[k as usize] as f64) < 0.5 * gain * level as f64 {
                dark += 1;
                if dark >= 3 {
                    return true;
                }
            }
        }
        false
    }
}

fn detect_err(frame: i64, source: DetectError) -> TrackError {
    TrackError::Detect { frame, source }
}

/// The next circle from the last three fits: constant acceleration through
/// them (Newton's divided differences), or constant velocity / position
/// with fewer.
pub fn predict(history: &[(f64, Circle)], t: f64) -> Circle {
    let m = history.len();
    let (t2, c2) = history[m - 1];
    if m < 2 {
        return c2;
    }
    let (t1, c1) = history[m - 2];
    let lin = |a: f64, b: f64| b + (b - a) / (t2 - t1) * (t - t2);
    let mut x = lin(c1.x_px, c2.x_px);
    let mut z = lin(c1.z_px, c2.z_px);
    if m >= 3 {
        let (t0, c0) = history[m - 3];
        let d01 = |a: f64, b: f64| (b - a) / (t1 - t0);
        let d12 = |a: f64, b: f64| (b - a) / (t2 - t1);
        let acc_z = (d12(c1.z_px, c2.z_px) - d01(c0.z_px, c1.z_px)) / (t2 - t0);
        let acc_x = (d12(c1.x_px, c2.x_px) - d01(c0.x_px, c1.x_px)) / (t2 - t0);
        z += acc_z * (t - t2) * (t - t1);
        x += acc_x * (t - t2) * (t - t1);
    }
    Circle {
        x_px: x,
        z_px: z,
        r_px: c2.r_px,
    }
}

/// Read the band of rows around `p` and measure the circle there.
#[allow(clippy::too_many_arguments)]
fn measure_in_band(
    source: &mut dyn FrameSource,
    index: usize,
    buf: &mut Frame,
    bg: &Background,
    p: &Circle,
    surface: &SurfaceLine,
    hold: Option<f64>,
    st: &TrackSettings,
    es: &mut EdgeScratch,
) -> Result<Option<CircleFit>, TrackError> {
    let (h, w) = buf.dim();
    let reach = p.r_px + st.edge.half_window as f64 + st.band_margin_px;
    let span = |c: f64, n: usize| {
        let lo = (c - reach).floor().max(0.0) as usize;
        (lo, ((c + reach).ceil().max(0.0) as usize + 1).min(n))
    };
    let (lo, hi) = span(p.z_px, h);
    let (left, right) = span(p.x_px, w);
    if lo >= hi || left >= right {
        return Ok(None);
    }
    // The same reach in columns, and the flicker reference strips at the
    // frame's edges: only these columns are converted.
    let strip = bg.region.strip_px.min(w);
    let cols = window_columns(left..right, strip, w);
    let mut view = buf.slice_mut(s![0..hi - lo, ..]);
    timings::time(Stage::Read, || {
        source.read_window_into(index, lo, &cols, &mut view)
    })?;
    let band = match Band::window(buf.slice(s![0..hi - lo, ..]), lo, left..right) {
        Ok(b) => b,
        Err(_) => return Ok(None),
    };
    Ok(measure_circle(&band, bg, p, Some(surface), hold, &st.edge, es).ok())
}

/// The edge points of the held-radius fit of one frame (for overlays), from
/// `band`: that frame's rows, already read by the caller (whole, or the
/// columns around the circle and the flicker strips: see [`Band::window`]).
pub fn edge_points_in(
    band: &Band,
    track: &Track,
    ft: &FrameTrack,
    st: &TrackSettings,
) -> Vec<EdgePoint> {
    let Some(f) = ft.held.or(ft.free) else {
        return Vec::new();
    };
    let mut es = EdgeScratch::default();
    let fit = measure_circle(
        band,
        &track.background,
        &f.circle(),
        Some(&track.surface),
        Some(track.radius_px),
        &st.edge,
        &mut es,
    );
    if fit.is_ok() {
        es.points
    } else {
        Vec::new()
    }
}

#[cfg(test)]
mod tests;
