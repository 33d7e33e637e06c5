//! What `process` and `run` take for recordings that lack a frame rate, a
//! scale or a surface row: [`RecordingArgs`], each checked as clap parses it
//! ([`crate::util::flag_values`]).

use crate::util::flag_values::{finite, positive};

/// What `process` and `run` take for recordings that lack it
/// ([`crate::config::CommandLineValues`] says what each stands above and below).
#[derive(Debug, Default, Clone, Copy, clap::Args)]
pub struct RecordingArgs {
    /// Frame rate (frames/s) of recordings that hold none (a folder of
    /// frames without its PCC XML), where the manifest's `fps` gives none;
    /// over camera.fps. A recording's own rate (XML, cine header) is always
    /// used: a different --fps is flagged `fps_mismatch`. Without any, such
    /// a recording is measured at 10000 frames/s and flagged `fps_assumed`.
    #[arg(long, value_parser = positive, allow_negative_numbers = true)]
    pub fps: Option<f64>,
    /// Scale (mm per pixel) for runs whose manifest row gives no
    /// `mm_per_px`; over camera.mm_per_px. Default: measured (free fall,
    /// else the sphere's radius).
    #[arg(long, value_parser = positive, allow_negative_numbers = true)]
    pub mm_per_px: Option<f64>,
    /// The undeformed surface's row (px, at column 0; tilt from
    /// detect.surface_slope), over detect.surface_row_px: for footage whose
    /// surface is out of view or not found. Default: found in the images.
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    pub surface_row_px: Option<f64>,
}

impl RecordingArgs {
    /// As the configuration's command-line values.
    pub fn values(&self) -> crate::config::CommandLineValues {
        crate::config::CommandLineValues {
            fps: self.fps,
            mm_per_px: self.mm_per_px,
            surface_row_px: self.surface_row_px,
        }
    }
}
