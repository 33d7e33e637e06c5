//! Why a detection step could not give an answer.

/// Why a detection step could not give an answer.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DetectError {
    /// A frame view is not in standard row-major layout (e.g. a column slice).
    #[error("frame view is not contiguous row-major: pass whole rows (a band of rows is fine)")]
    NotContiguous,
    /// A frame does not have the background's shape.
    #[error(
        "frame is {width}×{height} px but the background is {bg_width}×{bg_height} px: \
         the background must come from the same movie"
    )]
    ShapeMismatch {
        /// The frame's width, px.
        width: usize,
        /// The frame's height, px.
        height: usize,
        /// The background's width, px.
        bg_width: usize,
        /// The background's height, px.
        bg_height: usize,
    },
    /// No frame was given to build the background from.
    #[error("no frames to build the background from: set detect.background_frames ≥ 1")]
    NoBackgroundFrames,
    /// The flicker reference region holds no light (all zero), so no gain can be measured.
    #[error(
        "the frames' {what} are dark, where the backlight's brightness is measured: dropscope \
         needs a bright backlit background there (is the movie underexposed, or something dark \
         standing at the frame's edges?)"
    )]
    DarkReference {
        /// Which reference region is dark, in words.
        what: String,
    },
    /// Too few usable points for a fit.
    #[error("{what}: only {found} usable points, at least {needed} needed")]
    TooFewPoints {
        /// The fit, in words (e.g. `circle measurement`).
        what: &'static str,
        /// Usable points found.
        found: usize,
        /// The fewest the fit needs.
        needed: usize,
    },
    /// The fit has no unique solution (collinear points, zero radius, NaN).
    #[error("{what}: degenerate fit ({reason})")]
    Degenerate {
        /// The fit, in words.
        what: &'static str,
        /// Why it has no unique solution.
        reason: String,
    },
}
