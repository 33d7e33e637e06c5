//! The stages' own settings from the configuration: how a run's recording
//! is opened ([`open_options`]), and the tracker's and the detector's
//! settings from `[detect]` ([`crate::config::DetectConfig`]). The
//! configuration keeps plain numbers, the stages take their own parameters
//! ([`OpenOptions`], [`EdgeParams`], [`SurfaceLine`], [`TrackSettings`]),
//! and this file, above them, joins the two.

use crate::config::{DetectConfig, PipelineConfig};
use crate::detect::coarse::CoarseParams;
use crate::detect::surface::SurfaceParams;
use crate::detect::{EdgeParams, SurfaceLine};
use crate::source::{OpenOptions, P10Mode};
use crate::track::{TrackSettings, CHUNK_FRAMES_MAX, FRAMES_IN_MEMORY_MAX, KEPT_POINTS_MAX};

/// How a run's recording is read under `cfg` (flips, P10), with the
/// manifest's `number_digits` and the frame rate for an input without one.
pub fn open_options(
    cfg: &PipelineConfig,
    number_digits: Option<usize>,
    fps_fallback: Option<f64>,
) -> OpenOptions {
    OpenOptions {
        fps_fallback,
        apply_flips: cfg.camera.apply_flips,
        p10: if cfg.camera.p10_linear {
            P10Mode::Linear
        } else {
            P10Mode::Raw
        },
        number_digits,
    }
}

impl TrackSettings {
    /// The tracking settings of a `[detect]` table: its values, and the defaults for the rest (at least 3 background frames).
    pub fn from_config(cfg: &DetectConfig) -> Self {
        TrackSettings {
            background_frames: cfg.background_frames.max(3),
            edge: EdgeParams::from_config(cfg),
            coarse: CoarseParams::default(),
            surface: SurfaceParams::default(),
            surface_override: SurfaceLine::from_config(cfg),
            band_margin_px: 6.0,
            kept_points_max: KEPT_POINTS_MAX,
            chunk_frames_max: CHUNK_FRAMES_MAX,
            frames_in_memory_max: FRAMES_IN_MEMORY_MAX,
            skip_away: true,
            probe_searches: true,
        }
    }
}

impl EdgeParams {
    /// The settings of `[detect]` in pipeline.toml, defaults for the rest.
    pub fn from_config(cfg: &DetectConfig) -> Self {
        EdgeParams {
            spacing_px: cfg.edge_spacing_px,
            half_window: cfg.edge_half_window_px,
            surface_margin_px: cfg.contact_margin_px,
            ..EdgeParams::default()
        }
    }
}

impl SurfaceLine {
    /// The line fixed by the configuration (`detect.surface_row_px`,
    /// `detect.surface_slope`), if it sets one.
    pub fn from_config(cfg: &DetectConfig) -> Option<Self> {
        cfg.surface_row_px
            .map(|row0_px| SurfaceLine::given(row0_px, cfg.surface_slope))
    }
}
