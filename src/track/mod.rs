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
//!    predicted circle is read, through `FrameSource::read_window_into`:
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
//!    (`Look::Away`). A long movie's bounces out of view cost nothing
//!    then. What a search would still have found there is a sliver of the
//!    sphere's cap just after the loss (fits with σ_z of pixels, marked
//!    `missing` by pass 2), and the first predictions after the return,
//!    made from the last fits, differ with it: on one real-preset drop of
//!    60, 34 poor frames moved, and one field of drops.csv in its 16th digit.
//! 3. Calibration (`calibrate_radius`): R_px is the median radius of the
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
//!    ones, under the same rule as `measure_circle`: they are used when
//!    the held circle lies within `edge.recentre_px` of the circle their
//!    normals were centred on (centre and radius). Otherwise (a free radius
//!    far off on a short arc, or a failed fit) the frame's band is read
//!    again and measured around the held circle ([`Track::reread_frames`]).
//! 5. The frames in free flight far off the path of their neighbours are
//!    flagged [`Flag::Outlier`] ([`outliers`]); the measurement leaves them
//!    out.
//!
//! | file | what |
//! | --- | --- |
//! | `settings.rs` | [`TrackSettings`] and the defaults of its limits |
//! | `types.rs` | [`Track`], a tracked run |
//! | `error.rs` | [`TrackError`] in a user's words, [`upside_down_hint`] |
//! | `run.rs` | [`track`]: the steps in order, the outliers of step 5 |
//! | `background.rs` | step 1: [`background_and_surface`] |
//! | `pass1.rs` | pass 1's state between frames, [`predict`] |
//! | `look.rs` | how pass 1 looks at one frame, the quick look for anything dark |
//! | `walk.rs` | pass 1 in order, frame by frame |
//! | `ahead.rs` | pass 1 measured ahead on other threads |
//! | `kept.rs` | what pass 1 keeps of a frame for pass 2, as a record |
//! | `pass2.rs` | pass 2: the radius held, on the kept points or measured again |
//! | `band.rs` | a circle measured in a band of rows, [`edge_points_in`] |
//! | `frame.rs` | [`FrameTrack`], a frame's record, and its flags |
//! | `outliers.rs` | the frames in flight far off their neighbours |

mod ahead;
mod background;
mod band;
mod error;
mod frame;
mod kept;
mod look;
pub mod outliers;
mod pass1;
mod pass2;
mod run;
mod settings;
#[cfg(test)]
mod tests;
mod types;
mod walk;

pub use background::background_and_surface;
pub use band::edge_points_in;
pub use error::{upside_down_hint, TrackError};
pub use frame::{Flag, FrameFlags, FrameTrack};
pub use pass1::predict;
pub use run::{track, RADIUS_SYSTEMATIC_PX};
pub use settings::{
    search_stride, TrackSettings, CHUNK_FRAMES_MAX, FRAMES_IN_MEMORY_MAX, KEPT_POINTS_MAX,
    SEARCH_STRIDE_MAX, SEARCH_STRIDE_S,
};
pub use types::Track;

pub(crate) use crate::detect::columns::window_columns;
