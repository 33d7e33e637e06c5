//! `pipeline.toml`: raw TOML → validated [`PipelineConfig`] with typed units.
//!
//! Two stages, as in ripgrep: serde reads the raw tables (unknown keys are
//! rejected, with the key's name and where it stands), then
//! [`RawConfig::validate`] checks every value and converts it to SI. An error
//! names the key, the value and what is allowed. A leaf: plain numbers and
//! paths, no stage.
//!
//! | file | what it holds |
//! | --- | --- |
//! | `error.rs` | [`ConfigError`]: why a configuration could not be used |
//! | `raw.rs` | the tables as written ([`RawConfig`] and its tables) |
//! | `validate.rs` | [`RawConfig::validate`]: one function a table, each value checked and converted to SI |
//! | `settings.rs` | the validated [`PipelineConfig`], loading it, the command line's values, the embedded default |
//! | `to_toml.rs` | a [`PipelineConfig`] printed back as `pipeline.toml` text ([`PipelineConfig::to_toml`]) |

mod error;
mod raw;
mod settings;
mod to_toml;
mod validate;

pub use error::ConfigError;
pub use raw::{RawCamera, RawConfig, RawDetect, RawInput, RawOutput, RawSphere, RawSurface};
pub use settings::{
    CameraConfig, CommandLineValues, DetectConfig, FpsSource, InputConfig, OutputConfig,
    PipelineConfig, SphereConfig, Surface, DEFAULT_DISTORTION_BOUND_PX,
    DEFAULT_EDGE_OFFSET_SPREAD_PX, DEFAULT_FPS, EMBEDDED_DEFAULT, EMBEDDED_NAME,
};
