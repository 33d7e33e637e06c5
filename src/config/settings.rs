//! The validated configuration ([`PipelineConfig`]): lengths in metres,
//! paths resolved; loading it from a file, the command line's values and
//! the embedded default.

use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::error::ConfigError;
use super::raw::RawConfig;

/// The default configuration shipped with the binary (the repository's
/// `pipeline.toml`, pointing at the committed fixtures).
pub const EMBEDDED_DEFAULT: &str = include_str!("../../pipeline.toml");

/// How messages name the embedded default when no file was found.
pub const EMBEDDED_NAME: &str = "(embedded pipeline.toml)";

/// A validated configuration; lengths in metres, paths resolved.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PipelineConfig {
    /// Where the runs are.
    pub input: InputConfig,
    /// Frame rate, scale and optics of the camera.
    pub camera: CameraConfig,
    /// The spheres dropped.
    pub sphere: SphereConfig,
    /// Named surfaces (`[surface.<name>]`), at least one.
    pub surfaces: BTreeMap<String, Surface>,
    /// Settings of the per-frame detection, as in the file (see [`PipelineConfig::detect_settings`] for the command line's).
    pub detect: DetectConfig,
    /// Where and what to write.
    pub output: OutputConfig,
    /// Values given on the command line (`--fps`, `--mm-per-px`,
    /// `--surface-row-px`), not in the file: in the cache key, printed by
    /// neither `check-config` nor the file's keys in `provenance.json`
    /// (which records them beside, as `command_line`).
    #[serde(skip_serializing_if = "CommandLineValues::is_empty")]
    pub command_line: CommandLineValues,
}

/// Values a job's command line gives for its runs (`process` and `run`
/// take `--fps`, `--mm-per-px` and `--surface-row-px`). Each stands where
/// the run's manifest row gives none, above the configuration's value:
///
/// - frame rate: the recording's own (PCC XML, cine header, …) > the
///   manifest's `fps` > `--fps` > `camera.fps` > [`DEFAULT_FPS`]; a
///   value given that disagrees with the recording's own is flagged
///   `fps_mismatch` and the recording's is used;
/// - scale: the manifest's `mm_per_px` > `--mm-per-px` > `camera.mm_per_px`
///   > measured (free fall, else the sphere);
/// - surface row: `--surface-row-px` > `detect.surface_row_px` > found in
///   the images.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct CommandLineValues {
    /// `--fps`: frame rate for recordings that hold none, frames/s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fps: Option<f64>,
    /// `--mm-per-px`: a fixed scale, mm per px.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mm_per_px: Option<f64>,
    /// `--surface-row-px`: the undeformed surface row at column 0, px.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub surface_row_px: Option<f64>,
}

impl CommandLineValues {
    /// None given.
    pub fn is_empty(&self) -> bool {
        *self == Self::default()
    }
}

/// The frame rate of a recording that holds none, when neither its
/// manifest row, `--fps` nor `camera.fps` gives one (frames/s): a guess,
/// used so that the recording is still tracked, and said in its row
/// (`fps_source` `default`, flag `fps_assumed`) and on the console.
pub const DEFAULT_FPS: f64 = 10_000.0;

/// Where a run's frame rate came from: the `fps_source` column of drops.csv.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FpsSource {
    /// The recording's own record: its PCC XML side file (`xml`), its cine
    /// header (`cine`), or another reader's header, named by its format.
    Recording,
    /// The manifest's `fps` column.
    Manifest,
    /// `--fps` on the command line.
    Flag,
    /// `camera.fps` of the configuration.
    Config,
    /// [`DEFAULT_FPS`]: nothing gave one.
    Default,
}

impl FpsSource {
    /// The word of the `fps_source` column; `recording` names the
    /// recording's own record (`xml`, `cine`, …).
    pub fn word(self, recording: &str) -> String {
        match self {
            FpsSource::Recording => recording,
            FpsSource::Manifest => "manifest",
            FpsSource::Flag => "flag",
            FpsSource::Config => "config",
            FpsSource::Default => "default",
        }
        .to_string()
    }
}

impl PipelineConfig {
    /// The frame rate for `run`'s recording should it hold none, and where
    /// it comes from: the manifest's `fps`, else `--fps`, else
    /// `camera.fps`, else [`DEFAULT_FPS`].
    pub fn fps_fallback(&self, manifest_fps: Option<f64>) -> (f64, FpsSource) {
        manifest_fps
            .map(|f| (f, FpsSource::Manifest))
            .or(self.command_line.fps.map(|f| (f, FpsSource::Flag)))
            .or(self.camera.fps.map(|f| (f, FpsSource::Config)))
            .unwrap_or((DEFAULT_FPS, FpsSource::Default))
    }

    /// The scale given for a run whose manifest row gives `manifest`: it,
    /// else `--mm-per-px`, else `camera.mm_per_px`.
    pub fn given_mm_per_px(&self, manifest: Option<f64>) -> Option<f64> {
        manifest
            .or(self.command_line.mm_per_px)
            .or(self.camera.mm_per_px)
    }

    /// The detection settings, with `--surface-row-px` over
    /// `detect.surface_row_px`.
    pub fn detect_settings(&self) -> DetectConfig {
        DetectConfig {
            surface_row_px: self
                .command_line
                .surface_row_px
                .or(self.detect.surface_row_px),
            ..self.detect.clone()
        }
    }
}

/// The validated `[input]` table: where the runs are.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InputConfig {
    /// A `runs.csv` manifest, resolved against the configuration's folder.
    pub manifest: Option<PathBuf>,
    /// Run folders, `.cine` files, or directories holding them (used when no manifest), resolved against the configuration's folder.
    pub paths: Vec<PathBuf>,
    /// Name of the default surface; always a key of [`PipelineConfig::surfaces`].
    pub surface: String,
    /// The decisions file of `dropscope review` (`review.csv`); `None`:
    /// `review.csv` in the output folder.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub review: Option<PathBuf>,
}

/// The validated `[camera]` table: frame rate, scale and optics.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CameraConfig {
    /// Frames per second for recordings that hold none and whose manifest row gives none.
    pub fps: Option<f64>,
    /// A fixed scale, mm per px; `None`: from free fall, else from the sphere.
    pub mm_per_px: Option<f64>,
    /// A calibrated radial distortion, undone on every track ([`crate::calibrate::lens`]).
    pub distortion_k1_per_px2: Option<f64>,
    /// Without a calibration: the distortion at the image corner (px) whose
    /// effect enters the errors as a systematic term; 0 leaves it out.
    pub distortion_bound_px: f64,
    /// Runs without a manifest `setup` share one when their images say they
    /// were filmed through one camera set-up ([`crate::calibrate::setup_infer`]).
    pub infer_setups: bool,
    /// The silhouette's edge offset (apparent minus true radius, px) and its
    /// spread, for runs whose scale comes from their apparent radius: given,
    /// or measured on the job's runs ([`crate::calibrate::scale::EdgeOffset`]).
    pub edge_offset_px: Option<f64>,
    /// The one-sigma spread of `edge_offset_px` from drop to drop, px.
    pub edge_offset_spread_px: Option<f64>,
    /// Runs are measured as Phantom Camera Control shows them: the viewer
    /// flips a `.cine` (bFlipV, bFlipH) or a Photron header records are
    /// applied to the frames; false measures the storage orientation.
    pub apply_flips: bool,
    /// P10 packed cines (log-encoded 10-bit codes) are measured linearised
    /// to 12 bits through Vision Research's table; false measures the codes.
    pub p10_linear: bool,
}

/// `camera.edge_offset_spread_px` when only the offset is given (px).
pub const DEFAULT_EDGE_OFFSET_SPREAD_PX: f64 = 0.1;

/// The default `camera.distortion_bound_px`: the barrel distortion of the
/// macro lenses this experiment is filmed with reaches about half a pixel
/// at the corners of a 512 × 384 frame (realistic footage).
pub const DEFAULT_DISTORTION_BOUND_PX: f64 = 0.5;

/// The validated `[sphere]` table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SphereConfig {
    /// The spheres' density, kg/m³.
    pub density_kg_m3: f64,
    /// Radius for runs given without a manifest, m.
    pub radius_m: Option<f64>,
}

/// A pillar-textured elastic surface (SPEC §1).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Surface {
    /// Young's modulus E.
    pub modulus_pa: f64,
    /// Pillar height h.
    pub pillar_height_m: f64,
    /// Pillar width b.
    pub pillar_width_m: f64,
    /// Channel width c.
    pub channel_width_m: f64,
    /// Solid fraction φ in (0, 1].
    pub solid_fraction: f64,
}

impl Surface {
    /// The paper's PDMS surface: E = 1.6 MPa, h = 3.5 mm, b = 2.5 mm, c = 1.5 mm, φ = 0.625.
    pub fn paper_pdms() -> Self {
        Surface {
            modulus_pa: 1.6e6,
            pillar_height_m: 3.5e-3,
            pillar_width_m: 2.5e-3,
            channel_width_m: 1.5e-3,
            solid_fraction: 2.5 / 4.0,
        }
    }
}

/// The validated `[detect]` table: settings of the per-frame detection.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DetectConfig {
    /// Frames at the start of each run used for the background and surface (at least 1).
    pub background_frames: usize,
    /// Fixed undeformed surface row at column 0, px, overriding detection; `None`: found in the images.
    pub surface_row_px: Option<f64>,
    /// Surface tilt, rows per column, used with `surface_row_px`.
    pub surface_slope: f64,
    /// Edge points closer than this to the surface line are not used, px.
    pub contact_margin_px: f64,
    /// Half-width of the edge window along each normal (samples, 1 px apart).
    pub edge_half_window_px: usize,
    /// Arc length between neighbouring normals (px).
    pub edge_spacing_px: f64,
}

/// The values a `[detect]` table without the key gets.
impl Default for DetectConfig {
    fn default() -> Self {
        DetectConfig {
            background_frames: 8,
            surface_row_px: None,
            surface_slope: 0.0,
            contact_margin_px: 2.0,
            edge_half_window_px: 6,
            edge_spacing_px: 3.0,
        }
    }
}

/// The validated `[output]` table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutputConfig {
    /// Output folder, resolved against the configuration's folder.
    pub dir: PathBuf,
    /// Draw each drop's animated impact (`plots/impacts/<run>.png`, about
    /// 0.5 MB and 80 ms a drop); default true.
    pub animation: bool,
}

impl PipelineConfig {
    /// Read and validate a configuration file. Relative paths inside it are
    /// taken relative to the file's folder.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        // A named pipe or a device is refused before it is opened; a file
        // of more than 16 MiB is no configuration.
        let io = |source| ConfigError::Io {
            path: path.to_path_buf(),
            source,
        };
        let bytes = crate::util::io::read_input(path, 16 << 20).map_err(io)?;
        let text = String::from_utf8(bytes).map_err(|e| {
            io(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("not UTF-8 text: {e}"),
            ))
        })?;
        let base = path.parent().unwrap_or(Path::new("")).to_path_buf();
        Self::from_toml_str(&text, path, &base)
    }

    /// Parse and validate TOML text; `path` is only used in messages.
    pub fn from_toml_str(text: &str, path: &Path, base_dir: &Path) -> Result<Self, ConfigError> {
        let raw: RawConfig = toml::from_str(text).map_err(|e| ConfigError::Parse {
            path: path.to_path_buf(),
            message: e.to_string().trim_end().to_string(),
        })?;
        raw.validate(path, base_dir)
    }

    /// The configuration every command uses: `explicit` (a `--config`
    /// path), else `./pipeline.toml` when it exists, else the embedded
    /// default. Returns it with its name for messages.
    pub fn load_resolved(explicit: Option<&Path>) -> Result<(Self, String), ConfigError> {
        let local = Path::new("pipeline.toml");
        match explicit {
            Some(p) => Ok((Self::load(p)?, p.display().to_string())),
            None if local.exists() => Ok((Self::load(local)?, "./pipeline.toml".into())),
            None => {
                let name = EMBEDDED_NAME;
                let cfg = Self::from_toml_str(EMBEDDED_DEFAULT, Path::new(name), Path::new(""))?;
                Ok((cfg, name.into()))
            }
        }
    }
}

impl PipelineConfig {
    /// `input.manifest`, when set, names a file; else an error naming the
    /// key, the path as resolved (made absolute) and `name`, the
    /// configuration it comes from. Not part of [`RawConfig::validate`]:
    /// the commands that read no runs (`render`, `inspect`, `collapse`, …)
    /// take a configuration whose manifest is elsewhere.
    pub fn check_manifest(&self, name: &str) -> Result<(), ConfigError> {
        let Some(m) = &self.input.manifest else {
            return Ok(());
        };
        if m.is_file() {
            return Ok(());
        }
        let allowed = if m.exists() {
            "is not a file: name the runs.csv manifest itself"
        } else {
            "no such file (a relative path is taken from the configuration file's folder): \
             correct the path, or write the manifest there"
        };
        Err(ConfigError::Invalid {
            path: PathBuf::from(name),
            key: "input.manifest".into(),
            value: std::path::absolute(m)
                .unwrap_or_else(|_| m.clone())
                .display()
                .to_string(),
            allowed: allowed.into(),
        })
    }
}
