//! `pipeline.toml`: raw TOML → validated [`PipelineConfig`] with typed units.
//!
//! Two stages, as in ripgrep: serde reads the raw tables (unknown keys are
//! rejected, with the key's name and where it stands), then
//! [`RawConfig::validate`] checks every value and converts it to SI. An error
//! names the key, the value and what is allowed.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The default configuration shipped with the binary (the repository's
/// `pipeline.toml`, pointing at the committed fixtures).
pub const EMBEDDED_DEFAULT: &str = include_str!("../pipeline.toml");

/// How messages name the embedded default when no file was found.
pub const EMBEDDED_NAME: &str = "(embedded pipeline.toml)";

/// Why a configuration could not be used.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The configuration file.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not valid TOML, or holds a key or table that is not known; `message` says where.
    #[error("{path}: {message}")]
    Parse {
        /// The configuration file.
        path: PathBuf,
        /// The parser's message: the line, the column and what was expected.
        message: String,
    },
    /// A key's value is out of range or inconsistent with another key.
    #[error("{path}: key `{key}` = {value}: {allowed}")]
    Invalid {
        /// The configuration file.
        path: PathBuf,
        /// The key, in dotted form (`detect.background_frames`).
        key: String,
        /// The value as given.
        value: String,
        /// What is allowed instead.
        allowed: String,
    },
}

// ---------------------------------------------------------------- raw tables

/// The TOML file as written. Every table rejects keys it does not know.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawConfig {
    /// The `[input]` table.
    #[serde(default)]
    pub input: RawInput,
    /// The `[camera]` table.
    #[serde(default)]
    pub camera: RawCamera,
    /// The `[sphere]` table.
    #[serde(default)]
    pub sphere: RawSphere,
    /// The `[surface.<name>]` tables, by name.
    #[serde(default)]
    pub surface: BTreeMap<String, RawSurface>,
    /// The `[detect]` table.
    #[serde(default)]
    pub detect: RawDetect,
    /// The `[output]` table.
    #[serde(default)]
    pub output: RawOutput,
}

/// The `[input]` table as written: where the runs are.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawInput {
    /// A `runs.csv` manifest (docs/outputs.md), relative to the configuration file.
    pub manifest: Option<PathBuf>,
    /// Run folders, `.cine` files, or directories holding them (used when no manifest).
    #[serde(default)]
    pub paths: Vec<PathBuf>,
    /// The `[surface.<name>]` used by runs whose manifest row names none.
    pub surface: Option<String>,
    /// The decisions of `dropscope review` to apply, relative to the
    /// configuration file; default `review.csv` in the output folder.
    pub review: Option<PathBuf>,
}

/// The `[camera]` table as written: frame rate, scale and optics.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawCamera {
    /// Frames per second, used only when neither the file nor the manifest gives one.
    pub fps: Option<f64>,
    /// A fixed scale; otherwise the scale comes from free fall (or the sphere).
    pub mm_per_px: Option<f64>,
    /// The lens's radial distortion k1 (1/px², r_d = r_u (1 + k1 r_u²)), from a calibration.
    pub distortion_k1_per_px2: Option<f64>,
    /// Without k1: the largest corner displacement the lens may have (px).
    pub distortion_bound_px: Option<f64>,
    /// Runs the manifest gives no `setup` are grouped by what their images show.
    pub infer_setups: Option<bool>,
    /// The silhouette's apparent minus true radius (px) for runs scaled by it.
    pub edge_offset_px: Option<f64>,
    /// Its one-sigma spread from drop to drop (px).
    pub edge_offset_spread_px: Option<f64>,
    /// Apply the viewer flips a recording's header records (default true).
    pub apply_flips: Option<bool>,
    /// Measure P10 cines linearised to 12 bits (default true), else on their codes.
    pub p10_linear: Option<bool>,
}

/// The `[sphere]` table as written.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawSphere {
    /// The spheres' density, kg/m³ (default 7800, steel).
    pub density_kg_m3: Option<f64>,
    /// Radius for runs given without a manifest.
    pub radius_mm: Option<f64>,
}

/// One `[surface.<name>]` table as written, lengths in mm.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawSurface {
    /// Young's modulus E of the pillars' material.
    pub modulus_pa: f64,
    /// Pillar height h.
    pub pillar_height_mm: f64,
    /// Pillar width b.
    pub pillar_width_mm: f64,
    /// Channel width c.
    pub channel_width_mm: f64,
    /// Solid fraction φ; default b / (b + c).
    pub solid_fraction: Option<f64>,
}

/// The `[detect]` table as written: settings of the per-frame detection.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawDetect {
    /// Frames at the start of each run used for the background and surface.
    pub background_frames: Option<usize>,
    /// Fixed undeformed surface row (px) at column 0, overriding detection.
    pub surface_row_px: Option<f64>,
    /// Surface tilt in rows per column, used with `surface_row_px`.
    pub surface_slope: Option<f64>,
    /// Edge points closer than this to the surface line are not used (px).
    pub contact_margin_px: Option<f64>,
    /// Samples each side of the predicted edge along every normal (1 px
    /// apart); must cover the blurred edge (±3σ of the optics, half the
    /// motion-blur travel) plus the prediction error.
    pub edge_half_window_px: Option<usize>,
    /// Arc length between neighbouring normals (px).
    pub edge_spacing_px: Option<f64>,
}

/// The `[output]` table as written.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawOutput {
    /// Output folder, relative to the configuration file.
    pub dir: Option<PathBuf>,
    /// Draw each drop's animated impact (`plots/impacts/<run>.png`).
    pub animation: Option<bool>,
}

// ---------------------------------------------------------- validated config

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
    /// A calibrated radial distortion, undone on every track ([`crate::lens`]).
    pub distortion_k1_per_px2: Option<f64>,
    /// Without a calibration: the distortion at the image corner (px) whose
    /// effect enters the errors as a systematic term; 0 leaves it out.
    pub distortion_bound_px: f64,
    /// Runs without a manifest `setup` share one when their images say they
    /// were filmed through one camera set-up ([`crate::setup_infer`]).
    pub infer_setups: bool,
    /// The silhouette's edge offset (apparent minus true radius, px) and its
    /// spread, for runs whose scale comes from their apparent radius: given,
    /// or measured on the job's runs ([`crate::scale::EdgeOffset`]).
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

struct Checker<'a> {
    path: &'a Path,
}

impl Checker<'_> {
    fn invalid(&self, key: &str, value: impl ToString, allowed: &str) -> ConfigError {
        ConfigError::Invalid {
            path: self.path.to_path_buf(),
            key: key.to_string(),
            value: value.to_string(),
            allowed: allowed.to_string(),
        }
    }

    /// A finite number strictly above zero.
    fn positive(&self, key: &str, v: f64) -> Result<f64, ConfigError> {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(self.invalid(key, v, "must be a finite number greater than 0"))
        }
    }

    /// A number within its physical range ([`crate::util::ranges`]).
    fn ranged(
        &self,
        key: &str,
        range: crate::util::ranges::Range,
        v: f64,
    ) -> Result<f64, ConfigError> {
        let v = self.positive(key, v)?;
        range
            .check(v)
            .map_err(|allowed| self.invalid(key, crate::util::ranges::show(v), &allowed))
    }

    fn ranged_opt(
        &self,
        key: &str,
        range: crate::util::ranges::Range,
        v: Option<f64>,
    ) -> Result<Option<f64>, ConfigError> {
        v.map(|v| self.ranged(key, range, v)).transpose()
    }

    /// A path without a control character (a newline in `[output] dir`
    /// would reach a Slurm script as a command).
    fn path(&self, key: &str, p: PathBuf) -> Result<PathBuf, ConfigError> {
        let text = p.to_string_lossy();
        if text
            .chars()
            .any(|c| c.is_control() || crate::util::text::is_format(c))
        {
            return Err(self.invalid(
                key,
                format!("{:?}", crate::util::text::one_line(&text)),
                "must be a path without control or invisible format characters",
            ));
        }
        Ok(p)
    }
}

impl RawConfig {
    /// Check every value and convert to SI.
    pub fn validate(self, path: &Path, base_dir: &Path) -> Result<PipelineConfig, ConfigError> {
        let c = Checker { path };
        let resolve = |p: PathBuf| if p.is_absolute() { p } else { base_dir.join(p) };

        let mut surfaces = BTreeMap::new();
        for (name, s) in self.surface {
            let key = |k: &str| format!("surface.{name}.{k}");
            use crate::util::ranges::{MODULUS_PA, PILLAR_MM};
            let modulus_pa = c.ranged(&key("modulus_pa"), MODULUS_PA, s.modulus_pa)?;
            let h = c.ranged(&key("pillar_height_mm"), PILLAR_MM, s.pillar_height_mm)?;
            let b = c.ranged(&key("pillar_width_mm"), PILLAR_MM, s.pillar_width_mm)?;
            let ch = c.ranged(&key("channel_width_mm"), PILLAR_MM, s.channel_width_mm)?;
            let phi = s.solid_fraction.unwrap_or(b / (b + ch));
            if !(phi.is_finite() && phi > 0.0 && phi <= 1.0) {
                return Err(c.invalid(&key("solid_fraction"), phi, "must lie in (0, 1]"));
            }
            surfaces.insert(
                name,
                Surface {
                    modulus_pa,
                    pillar_height_m: h * 1e-3,
                    pillar_width_m: b * 1e-3,
                    channel_width_m: ch * 1e-3,
                    solid_fraction: phi,
                },
            );
        }
        if surfaces.is_empty() {
            surfaces.insert("pdms".to_string(), Surface::paper_pdms());
        }
        let surface = match self.input.surface {
            Some(s) if surfaces.contains_key(&s) => s,
            Some(s) => {
                let known: Vec<_> = surfaces.keys().cloned().collect();
                return Err(c.invalid(
                    "input.surface",
                    format!("\"{s}\""),
                    &format!("must name a [surface.<name>] table: {}", known.join(", ")),
                ));
            }
            None if surfaces.len() == 1 => surfaces.keys().next().cloned().unwrap_or_default(),
            None => {
                return Err(c.invalid(
                    "input.surface",
                    "(missing)",
                    "several [surface.<name>] tables are defined: say which is the default",
                ))
            }
        };

        use crate::util::ranges::{DENSITY_KG_M3, FPS, MM_PER_PX, SPHERE_RADIUS_MM};
        let density = c.ranged(
            "sphere.density_kg_m3",
            DENSITY_KG_M3,
            self.sphere.density_kg_m3.unwrap_or(7800.0),
        )?;
        let radius_m = c
            .ranged_opt("sphere.radius_mm", SPHERE_RADIUS_MM, self.sphere.radius_mm)?
            .map(|r| r * 1e-3);
        let fps = c.ranged_opt("camera.fps", FPS, self.camera.fps)?;
        let mm_per_px = c.ranged_opt("camera.mm_per_px", MM_PER_PX, self.camera.mm_per_px)?;
        let distortion_k1_per_px2 = match self.camera.distortion_k1_per_px2 {
            // |k1| r² above 5 % at 1 000 px from the centre is no lens of
            // this experiment, and the one-term model would not hold.
            Some(k) if !(k.is_finite() && k.abs() <= 5e-8) => {
                return Err(c.invalid(
                    "camera.distortion_k1_per_px2",
                    k,
                    "must be a finite number between -5e-8 and 5e-8 (1/px²)",
                ))
            }
            k => k,
        };
        let distortion_bound_px = self
            .camera
            .distortion_bound_px
            .unwrap_or(DEFAULT_DISTORTION_BOUND_PX);
        if !(distortion_bound_px.is_finite() && (0.0..=20.0).contains(&distortion_bound_px)) {
            return Err(c.invalid(
                "camera.distortion_bound_px",
                distortion_bound_px,
                "must be a number of pixels from 0 to 20",
            ));
        }
        if let Some(o) = self.camera.edge_offset_px {
            if !(o.is_finite() && o.abs() <= 5.0) {
                return Err(c.invalid(
                    "camera.edge_offset_px",
                    o,
                    "must be a number of pixels from -5 to 5",
                ));
            }
        }
        let edge_offset_spread_px = match (
            self.camera.edge_offset_spread_px,
            self.camera.edge_offset_px,
        ) {
            (Some(s), _) if !(s.is_finite() && s > 0.0 && s <= 5.0) => {
                return Err(c.invalid(
                    "camera.edge_offset_spread_px",
                    s,
                    "must be a number of pixels above 0 and at most 5",
                ))
            }
            (Some(s), None) => {
                return Err(c.invalid(
                    "camera.edge_offset_spread_px",
                    s,
                    "is the spread of camera.edge_offset_px, which is not given",
                ))
            }
            (s, _) => s,
        };

        let defaults = DetectConfig::default();
        let background_frames = self
            .detect
            .background_frames
            .unwrap_or(defaults.background_frames);
        if background_frames == 0 {
            return Err(c.invalid("detect.background_frames", 0, "must be at least 1"));
        }
        let contact_margin_px = self
            .detect
            .contact_margin_px
            .unwrap_or(defaults.contact_margin_px);
        if !(contact_margin_px.is_finite() && contact_margin_px >= 0.0) {
            return Err(c.invalid(
                "detect.contact_margin_px",
                contact_margin_px,
                "must be a finite number ≥ 0",
            ));
        }
        let surface_slope = self.detect.surface_slope.unwrap_or(defaults.surface_slope);
        if !surface_slope.is_finite() || surface_slope.abs() > 0.2 {
            return Err(c.invalid(
                "detect.surface_slope",
                surface_slope,
                "must be a finite tilt in rows per column, |slope| ≤ 0.2",
            ));
        }
        let edge_half_window_px = self
            .detect
            .edge_half_window_px
            .unwrap_or(defaults.edge_half_window_px);
        if !(3..=30).contains(&edge_half_window_px) {
            return Err(c.invalid(
                "detect.edge_half_window_px",
                edge_half_window_px,
                "must be an integer from 3 to 30",
            ));
        }
        let edge_spacing_px = self
            .detect
            .edge_spacing_px
            .unwrap_or(defaults.edge_spacing_px);
        if !(edge_spacing_px.is_finite() && (1.0..=20.0).contains(&edge_spacing_px)) {
            return Err(c.invalid(
                "detect.edge_spacing_px",
                edge_spacing_px,
                "must be a number of px from 1 to 20",
            ));
        }
        if let Some(r) = self.detect.surface_row_px {
            if !r.is_finite() {
                return Err(c.invalid("detect.surface_row_px", r, "must be a finite row"));
            }
        }

        let manifest = self
            .input
            .manifest
            .map(|p| c.path("input.manifest", p))
            .transpose()?;
        let paths = self
            .input
            .paths
            .into_iter()
            .map(|p| c.path("input.paths", p))
            .collect::<Result<Vec<_>, _>>()?;
        let review = self
            .input
            .review
            .map(|p| c.path("input.review", p))
            .transpose()?;
        let dir = c.path(
            "output.dir",
            self.output.dir.unwrap_or_else(|| PathBuf::from("out")),
        )?;
        Ok(PipelineConfig {
            input: InputConfig {
                manifest: manifest.map(resolve),
                paths: paths.into_iter().map(resolve).collect(),
                surface,
                review: review.map(resolve),
            },
            camera: CameraConfig {
                fps,
                mm_per_px,
                distortion_k1_per_px2,
                distortion_bound_px,
                infer_setups: self.camera.infer_setups.unwrap_or(true),
                edge_offset_px: self.camera.edge_offset_px,
                edge_offset_spread_px,
                apply_flips: self.camera.apply_flips.unwrap_or(true),
                p10_linear: self.camera.p10_linear.unwrap_or(true),
            },
            sphere: SphereConfig {
                density_kg_m3: density,
                radius_m,
            },
            surfaces,
            detect: DetectConfig {
                background_frames,
                surface_row_px: self.detect.surface_row_px,
                surface_slope,
                contact_margin_px,
                edge_half_window_px,
                edge_spacing_px,
            },
            output: OutputConfig {
                dir: resolve(dir),
                animation: self.output.animation.unwrap_or(true),
            },
            command_line: CommandLineValues::default(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<PipelineConfig, ConfigError> {
        PipelineConfig::from_toml_str(text, Path::new("pipeline.toml"), Path::new("/base"))
    }

    #[test]
    fn embedded_default_is_valid_and_points_at_fixtures() {
        let c = parse(EMBEDDED_DEFAULT).unwrap();
        let s = &c.surfaces[&c.input.surface];
        assert!((s.solid_fraction - 0.625).abs() < 1e-12);
        assert!((s.modulus_pa - 1.6e6).abs() < 1e-6);
        let m = c.input.manifest.expect("the default names a manifest");
        assert!(m.starts_with("/base/fixtures"), "{}", m.display());
        // The shipped file spells out the defaults; without its [detect]
        // table the same values come from DetectConfig::default().
        assert_eq!(c.detect, DetectConfig::default());
        let (head, tail) = EMBEDDED_DEFAULT
            .split_once("[detect]")
            .expect("a [detect] table");
        let rest = tail.find("\n[").map_or("", |i| &tail[i..]);
        let without = parse(&format!("{head}{rest}")).unwrap();
        assert_eq!(without.detect, DetectConfig::default());
    }

    #[test]
    fn unknown_key_is_rejected_with_its_name() {
        let e = parse("[camera]\nfsp = 10000\n").unwrap_err().to_string();
        assert!(e.contains("fsp"), "{e}");
        assert!(e.contains("pipeline.toml"), "{e}");
    }

    #[test]
    fn impossible_values_name_the_key_and_the_value() {
        let cases = [
            ("[sphere]\nradius_mm = -3\n", "sphere.radius_mm", "-3"),
            ("[camera]\nfps = 0\n", "camera.fps", "0"),
            (
                "[camera]\ndistortion_bound_px = -1\n",
                "camera.distortion_bound_px",
                "-1",
            ),
            (
                "[camera]\ndistortion_k1_per_px2 = 0.001\n",
                "camera.distortion_k1_per_px2",
                "0.001",
            ),
            (
                "[camera]\nedge_offset_px = 30\n",
                "camera.edge_offset_px",
                "30",
            ),
            (
                "[camera]\nedge_offset_px = -0.2\nedge_offset_spread_px = 0\n",
                "camera.edge_offset_spread_px",
                "0",
            ),
            (
                "[camera]\nedge_offset_spread_px = 0.1\n",
                "camera.edge_offset_spread_px",
                "0.1",
            ),
            (
                "[surface.p]\nmodulus_pa = 1e6\npillar_height_mm = 3\npillar_width_mm = 2\nchannel_width_mm = 1\nsolid_fraction = 1.5\n",
                "surface.p.solid_fraction",
                "1.5",
            ),
            ("[detect]\nbackground_frames = 0\n", "detect.background_frames", "0"),
            ("[detect]\nedge_half_window_px = 2\n", "detect.edge_half_window_px", "2"),
            ("[detect]\nedge_spacing_px = 0.5\n", "detect.edge_spacing_px", "0.5"),
        ];
        for (text, key, value) in cases {
            let e = parse(text).unwrap_err().to_string();
            assert!(e.contains(key) && e.contains(value), "{text} → {e}");
        }
    }

    #[test]
    fn several_surfaces_need_a_named_default() {
        let two = "[surface.a]\nmodulus_pa = 1e6\npillar_height_mm = 3\npillar_width_mm = 2\nchannel_width_mm = 1\n\
                   [surface.b]\nmodulus_pa = 2e6\npillar_height_mm = 3\npillar_width_mm = 2\nchannel_width_mm = 2\n";
        let e = parse(two).unwrap_err().to_string();
        assert!(e.contains("input.surface"), "{e}");
        let c = parse(&format!("[input]\nsurface = \"b\"\n{two}")).unwrap();
        assert_eq!(c.input.surface, "b");
        assert!((c.surfaces["b"].solid_fraction - 0.5).abs() < 1e-12);
        let e = parse(&format!("[input]\nsurface = \"zz\"\n{two}"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("\"zz\"") && e.contains("a, b"), "{e}");
    }
}
