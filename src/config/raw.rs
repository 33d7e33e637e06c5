//! The TOML file as written: serde reads its tables, and every table
//! rejects the keys it does not know, naming them and where they stand.

use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::PathBuf;

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
