//! Why a run could not be tracked ([`TrackError`]), said in a user's words.

use crate::detect::{Background, CircleFit, DetectError, SurfaceLine};
use crate::source::SourceError;

/// Why a run could not be tracked.
#[derive(Debug, thiserror::Error)]
pub enum TrackError {
    /// The recording could not be read.
    #[error(transparent)]
    Source(#[from] SourceError),
    /// A frame's detection failed in a way that stops the run.
    #[error("frame {frame}: {}", plain_detect(source))]
    Detect {
        /// The frame's image number.
        frame: i64,
        /// Why detection failed.
        #[source]
        source: DetectError,
    },
    /// No background could be built (no backlight to measure against).
    #[error("no sphere found: no backlit background to measure against: {0}")]
    Background(DetectError),
    /// No surface line was found in the background.
    #[error(
        "no sphere found: no surface line in the background ({}); if the surface is out of \
         view, give its row with --surface-row-px (or detect.surface_row_px in pipeline.toml)",
        surface_problem(.0)
    )]
    Surface(DetectError),
    /// No frame shows a dark round shape.
    #[error(
        "no sphere found in any of the {frames} frames: dropscope measures a dark, round \
         sphere against a bright backlit background, falling onto a surface whose top is a \
         horizontal line below it; no dark round shape was seen in these frames"
    )]
    NoSphere {
        /// Frames searched.
        frames: usize,
    },
    /// Fewer than 3 frames show the whole sphere clear of the surface, so its radius in pixels cannot be measured.
    #[error(
        "no sphere found whole: the sphere's outline is clear of the picture's border and of \
         the surface in {} (3 needed to measure its radius in pixels): a sphere only partly \
         in view, or a dark shape that is not round{upside_down}",
        frames_text(*found)
    )]
    NoCalibration {
        /// How many frames do.
        found: usize,
        /// When the picture looks upside down: the question whether it is
        /// ([`upside_down_hint`]); else empty.
        upside_down: String,
    },
    /// The movie has fewer than 8 frames (the count).
    #[error("only {0} frames: too short a movie to find a drop in (at least 8 needed)")]
    TooShort(usize),
    /// The temporary file of the per-frame records failed.
    #[error("a temporary file for the track's per-frame records (set TMPDIR to a folder with room): {0}")]
    Records(#[from] std::io::Error),
}

/// What dropscope measures, said where a frame shows something else.
pub(super) const SCOPE: &str = "dropscope measures a sphere seen dark against a bright background \
     (backlit, side view) above a surface, and footage of anything else is beyond what it reads";

/// A detection failure in a frame in a user's words: a fit that found no
/// circle says so first, the fit's own words after it in parentheses,
/// then what dropscope measures.
pub(super) fn plain_detect(e: &DetectError) -> String {
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
pub(super) fn frames_text(n: usize) -> String {
    match n {
        0 => "no frame".into(),
        1 => "1 frame only".into(),
        n => format!("{n} frames only"),
    }
}

/// Why no surface line was found, in the words of the picture.
pub(super) fn surface_problem(e: &DetectError) -> String {
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

pub(super) fn detect_err(frame: i64, source: DetectError) -> TrackError {
    TrackError::Detect { frame, source }
}
