//! The tracker's settings ([`TrackSettings`]) and their defaults.

use crate::detect::coarse::CoarseParams;
use crate::detect::surface::SurfaceParams;
use crate::detect::{EdgeParams, SurfaceLine};

/// Settings of the tracker.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackSettings {
    /// Frames, spread evenly over the movie, that make the background.
    pub background_frames: usize,
    /// How edge points are measured along the normals.
    pub edge: EdgeParams,
    /// How a frame is searched for the sphere without a prediction.
    pub coarse: CoarseParams,
    /// How the surface line is found in the background.
    pub surface: SurfaceParams,
    /// A fixed surface line (from the configuration) instead of the detected one.
    pub surface_override: Option<SurfaceLine>,
    /// Rows read beyond the predicted circle on each side, besides the
    /// window of the edge normals.
    pub band_margin_px: f64,
    /// Most edge points pass 1 keeps for pass 2 (8 bytes each). Past it, a
    /// frame keeps only how pass 1 looked at it, and pass 2 measures it
    /// again that way: the same points, bit for bit (see `Track`'s
    /// `remeasured_frames`), so that the memory does not grow with the
    /// movie's length beyond this.
    pub kept_points_max: usize,
    /// Most frames in one chunk of pass 1 measured ahead by another thread
    /// (see `speculate`): what is measured ahead and not yet taken is at
    /// most `CHUNKS_PER_THREAD × threads − 1` such chunks, whatever the
    /// movie's length.
    pub chunk_frames_max: usize,
    /// Most frames whose records (the track's, and what pass 1 keeps of
    /// each for pass 2) are held in memory; past it, all of them go to a
    /// temporary file ([`crate::util::records`]) and are read back a block at a
    /// time, so that they do not grow the memory with the movie's length.
    pub frames_in_memory_max: usize,
    /// Frames are not looked at while a sphere that left through the top of
    /// the frame is on its way back (`Look::Away`); off, every frame
    /// without the sphere is searched whole.
    pub skip_away: bool,
    /// While no sphere is followed, one frame in a
    /// [`search_stride`] is searched whole, and on a find the frames since
    /// the last empty search are searched one by one (`Walk::frame`);
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

/// [`TrackSettings::frames_in_memory_max`] by default: 8 MB of the track's
/// records (256 bytes a frame) and 1.8 MB of pass 1's (56).
pub const FRAMES_IN_MEMORY_MAX: usize = 32_768;
