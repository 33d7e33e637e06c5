//! Values of command-line flags, checked as clap parses them: one rule per
//! kind of value, shared by every command that takes such a flag, so that a
//! nonsense value is refused naming the flag and the value before anything
//! runs (exit status 2), e.g.
//! `invalid value '-1' for '--fps <FPS>': must be a number greater than 0`.
//!
//! A flag using these also takes `allow_negative_numbers = true`, so that
//! `--radius-mm -3` reaches the check instead of being read as a flag.

/// A number greater than 0 (a frame rate, a length, a scale, a density):
/// 0, negative numbers, NaN and infinity are refused.
pub fn positive(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err("must be a number greater than 0".into()),
    }
}

/// A finite number (a row, which may lie above the picture): NaN and
/// infinity are refused.
pub fn finite(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err("must be a finite number".into()),
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positive_takes_numbers_above_zero_only() {
        for ok in ["1", "0.04", "1e4", "+3", "10000.0"] {
            assert!(positive(ok).is_ok(), "{ok}");
        }
        for bad in [
            "0", "-0", "-1", "-3", "NaN", "inf", "-inf", "1e400", "", "abc", "3mm",
        ] {
            assert_eq!(
                positive(bad).unwrap_err(),
                "must be a number greater than 0",
                "{bad}"
            );
        }
    }
}
