//! `dropscope render`: synthetic drops with exact truth, written the way
//! Phantom Camera Control exports a recording (SPEC §4).
//!
//! | file | does |
//! | --- | --- |
//! | [`physics`] | the contact ODE, its events and the exact motion |
//! | [`coverage`] | exact pixel coverage of disk, line and pillars |
//! | [`raster`] | one frame from the sphere centres over the exposure |
//! | [`export`] | frame files, the PCC XML side file, `truth.json` |
//! | [`truth`] | the `truth.json` schema |
//! | [`campaign`] | the paper's grid and the `runs.csv` manifest |
//!
//! # Conventions
//!
//! Image number `n` (the camera's, negative before the trigger) has its
//! mid-exposure at `t = n / fps` after the trigger; motion blur integrates
//! over `[t − exposure/2, t + exposure/2]`. The first contact falls at a
//! random phase within image 0's frame interval, `t_contact ∈ [0, 1/fps)`,
//! as when a PCC user triggers on the impact; the movie starts
//! `frames_before` images earlier and ends `frames_after` images after the
//! loss of contact. The sphere falls straight down column `impact_column_px`;
//! the centre row is `z = y_s(x) − R_px + d / s` with `d` the signed depth of
//! the sphere's lowest point below the surface (physics) and `s` the scale.
//!
//! Randomness: every frame's noise comes from a ChaCha8 generator seeded by
//! `(seed, run, image number)`, the run's layout (contact phase, column,
//! surface row, pillar phase) from `(seed, run)`, the dust from `seed` alone.
//! Frames are rendered in parallel; the bytes do not depend on the number of
//! threads.

pub mod campaign;
pub mod coverage;
pub mod export;
pub mod physics;
pub mod raster;
pub mod truth;

use std::path::{Path, PathBuf};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;

use crate::config::Surface;
use campaign::{DropSpec, ManifestRow};
use export::{FolderSink, FrameFormat, FrameSink, PccHeader};
use physics::{DropParams, Trajectory};
use raster::{Look, Raster, Scene};
use truth::{BounceTruth, FrameTruth, SurfaceTruth, Truth};

/// Why rendering failed.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("render option `--{name}` = {value}: {allowed}")]
    Invalid {
        name: &'static str,
        value: String,
        allowed: String,
    },
    #[error("run {run}: {source}")]
    Physics {
        run: String,
        #[source]
        source: physics::PhysicsError,
    },
    #[error("run {run}: {source}")]
    Raster {
        run: String,
        #[source]
        source: raster::RasterError,
    },
    #[error(transparent)]
    Export(#[from] export::ExportError),
    #[error("{path}: cannot create folder: {source}")]
    CreateDir {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

/// A starting set of effects; every effect can still be set on its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// Ideal pictures: 12-bit, uniform light, exact silhouette at mid-exposure,
    /// no blur, no noise, no flicker, no dust.
    Clean,
    /// A good experiment: 8-bit, gentle light gradient, optical blur σ 0.7 px,
    /// motion blur, read + shot noise, 1 % flicker, 5 dust specks.
    Realistic,
    /// A difficult one: strong gradient, blur σ 1.2 px, more noise and
    /// flicker, 12 specks, a faint mirror reflection under the surface line,
    /// a slight surface tilt.
    Harsh,
}

impl Preset {
    pub fn name(self) -> &'static str {
        match self {
            Preset::Clean => "clean",
            Preset::Realistic => "realistic",
            Preset::Harsh => "harsh",
        }
    }

    /// The preset's look.
    pub fn look(self) -> Look {
        let base = Look {
            bit_depth: 8,
            background_level: 0.75,
            gradient: 0.0,
            sphere_transmission: 0.06,
            pillar_grey: 0.45,
            channel_grey: 0.7,
            base_grey: 0.55,
            blur_sigma_px: 0.0,
            motion_blur: false,
            read_noise_dn: 0.0,
            full_well_e: 0.0,
            flicker: 0.0,
            dust_count: 0,
            reflection: 0.0,
            reflection_depth_px: 6.0,
        };
        match self {
            Preset::Clean => Look {
                bit_depth: 12,
                ..base
            },
            Preset::Realistic => Look {
                gradient: 0.12,
                blur_sigma_px: 0.7,
                motion_blur: true,
                read_noise_dn: 0.8,
                full_well_e: 20_000.0,
                flicker: 0.01,
                dust_count: 5,
                ..base
            },
            Preset::Harsh => Look {
                gradient: 0.3,
                blur_sigma_px: 1.2,
                motion_blur: true,
                read_noise_dn: 2.0,
                full_well_e: 5_000.0,
                flicker: 0.03,
                dust_count: 12,
                reflection: 0.25,
                ..base
            },
        }
    }

    /// The preset's surface tilt (rows per column).
    pub fn tilt(self) -> f64 {
        match self {
            Preset::Harsh => 0.004,
            _ => 0.0,
        }
    }
}

/// `dropscope render`: one drop (`--radius-mm`, `--height-cm`), a list
/// (`--drop R:H`, repeatable), or the paper's grid (`--campaign`).
#[derive(Debug, Clone, clap::Args)]
pub struct RenderArgs {
    /// Output folder; each drop gets a sub-folder named after its run.
    #[arg(long)]
    pub out: PathBuf,
    /// Render the grid --radii-mm × --heights-cm (the paper's by default) and write runs.csv.
    #[arg(long)]
    pub campaign: bool,
    /// Radii of the campaign grid, mm.
    #[arg(long, value_delimiter = ',', default_values_t = campaign::PAPER_RADII_MM)]
    pub radii_mm: Vec<f64>,
    /// Drop heights of the campaign grid, cm.
    #[arg(long, value_delimiter = ',', default_values_t = campaign::PAPER_HEIGHTS_CM)]
    pub heights_cm: Vec<f64>,
    /// Repeats of every grid point (each a new contact phase, column and noise).
    #[arg(long, default_value_t = 1)]
    pub repeats: usize,
    /// Render exactly these drops, RADIUS_MM:HEIGHT_CM (repeatable or comma-separated), and write runs.csv.
    #[arg(long = "drop", value_delimiter = ',', conflicts_with = "campaign")]
    pub drops: Vec<String>,
    /// Sphere radius of a single drop, mm.
    #[arg(long, default_value_t = 4.5)]
    pub radius_mm: f64,
    /// Drop height of a single drop (lowest point of the sphere to the surface), cm.
    #[arg(long, default_value_t = 12.0)]
    pub height_cm: f64,
    /// Seed of every random choice; the same seed gives byte-identical files.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Starting set of effects; the options below override it one by one.
    #[arg(long, value_enum, default_value_t = Preset::Realistic)]
    pub preset: Preset,
    /// Frame files: tiff (uncompressed) or png.
    #[arg(long, value_enum, default_value_t = FrameFormat::Tiff)]
    pub format: FrameFormat,

    // ---- physics
    /// Sphere density, kg/m³.
    #[arg(long, default_value_t = 7800.0)]
    pub density_kg_m3: f64,
    /// Young's modulus of the pillars, Pa.
    #[arg(long, default_value_t = 1.6e6)]
    pub modulus_pa: f64,
    /// Pillar height h, mm.
    #[arg(long, default_value_t = 3.5)]
    pub pillar_height_mm: f64,
    /// Pillar width b, mm.
    #[arg(long, default_value_t = 2.5)]
    pub pillar_width_mm: f64,
    /// Channel width c, mm (φ = b / (b + c)).
    #[arg(long, default_value_t = 1.5)]
    pub channel_width_mm: f64,
    /// Coefficient of restitution; below 1 adds linear damping solved to give it.
    #[arg(long, default_value_t = 1.0)]
    pub restitution: f64,
    /// Gravity, m/s².
    #[arg(long, default_value_t = physics::STANDARD_GRAVITY_M_S2)]
    pub gravity_m_s2: f64,
    /// Name of the surface written to runs.csv (a [surface.<name>] of pipeline.toml).
    #[arg(long, default_value = "pdms")]
    pub surface_name: String,

    // ---- camera
    /// Frame width, px.
    #[arg(long, default_value_t = 512)]
    pub width_px: usize,
    /// Frame height, px.
    #[arg(long, default_value_t = 384)]
    pub height_px: usize,
    /// Frames per second.
    #[arg(long, default_value_t = 10_000.0)]
    pub fps: f64,
    /// Exposure time, µs.
    #[arg(long, default_value_t = 50.0)]
    pub exposure_us: f64,
    /// Scale, mm/px [default: 0.04 + 0.01·(R − 3 mm) per mm of R, times 384 / height].
    #[arg(long)]
    pub mm_per_px: Option<f64>,
    /// Bits per sample, 8 or 12 [default: the preset's].
    #[arg(long)]
    pub bit_depth: Option<u8>,
    /// Frames before the first contact.
    #[arg(long, default_value_t = 30)]
    pub frames_before: usize,
    /// Frames after the loss of contact.
    #[arg(long, default_value_t = 30)]
    pub frames_after: usize,
    /// Undeformed surface row at column 0, px [default: 0.72·height plus a random fraction].
    #[arg(long)]
    pub surface_row_px: Option<f64>,
    /// Surface tilt, rows per column [default: the preset's].
    #[arg(long)]
    pub tilt: Option<f64>,

    // ---- look (0 switches an effect off)
    /// Illumination gradient amplitude (relative).
    #[arg(long)]
    pub gradient: Option<f64>,
    /// Gaussian optical blur σ, px.
    #[arg(long)]
    pub blur_px: Option<f64>,
    /// Motion blur over the exposure (true/false).
    #[arg(long)]
    pub motion_blur: Option<bool>,
    /// Gaussian read noise, DN.
    #[arg(long)]
    pub read_noise_dn: Option<f64>,
    /// Full-well electrons at white for Poisson shot noise.
    #[arg(long)]
    pub full_well_e: Option<f64>,
    /// Relative r.m.s. frame-to-frame flicker.
    #[arg(long)]
    pub flicker: Option<f64>,
    /// Number of dust specks.
    #[arg(long)]
    pub dust: Option<usize>,
    /// Strength of the mirror reflection below the surface line.
    #[arg(long)]
    pub reflection: Option<f64>,
    /// Background brightness at the centre, fraction of white.
    #[arg(long)]
    pub background_level: Option<f64>,
    /// Light through the silhouette, fraction of the background.
    #[arg(long)]
    pub sphere_transmission: Option<f64>,

    /// Write mm_per_px into runs.csv (by default the pipeline must measure it).
    #[arg(long)]
    pub manifest_scale: bool,
}

/// Validated settings shared by every drop of a render.
#[derive(Debug, Clone)]
pub struct RenderSettings {
    pub preset: Preset,
    pub look: Look,
    pub format: FrameFormat,
    pub seed: u64,
    pub fps: f64,
    pub exposure_s: f64,
    pub width_px: usize,
    pub height_px: usize,
    pub mm_per_px: Option<f64>,
    pub frames_before: usize,
    pub frames_after: usize,
    pub surface_row_px: Option<f64>,
    pub surface_slope: f64,
    pub density_kg_m3: f64,
    pub surface: Surface,
    pub restitution: f64,
    pub gravity_m_s2: f64,
}

fn invalid(name: &'static str, value: impl ToString, allowed: &str) -> RenderError {
    RenderError::Invalid {
        name,
        value: value.to_string(),
        allowed: allowed.to_string(),
    }
}

fn positive(name: &'static str, v: f64) -> Result<f64, RenderError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(invalid(name, v, "must be a finite number > 0"))
    }
}

impl RenderArgs {
    /// Check the options and build the settings (errors name the option).
    pub fn settings(&self) -> Result<RenderSettings, RenderError> {
        let mut look = self.preset.look();
        if let Some(b) = self.bit_depth {
            if !matches!(b, 8 | 12) {
                return Err(invalid("bit-depth", b, "must be 8 or 12"));
            }
            look.bit_depth = b;
        }
        let set = |target: &mut f64, v: Option<f64>, name: &'static str, max: f64| {
            if let Some(v) = v {
                if !(v.is_finite() && (0.0..=max).contains(&v)) {
                    return Err(invalid(name, v, &format!("must lie in [0, {max}]")));
                }
                *target = v;
            }
            Ok(())
        };
        set(&mut look.gradient, self.gradient, "gradient", 1.0)?;
        set(&mut look.blur_sigma_px, self.blur_px, "blur-px", 20.0)?;
        set(
            &mut look.read_noise_dn,
            self.read_noise_dn,
            "read-noise-dn",
            1e4,
        )?;
        set(&mut look.full_well_e, self.full_well_e, "full-well-e", 1e9)?;
        set(&mut look.flicker, self.flicker, "flicker", 0.5)?;
        set(&mut look.reflection, self.reflection, "reflection", 1.0)?;
        set(
            &mut look.background_level,
            self.background_level,
            "background-level",
            1.0,
        )?;
        set(
            &mut look.sphere_transmission,
            self.sphere_transmission,
            "sphere-transmission",
            1.0,
        )?;
        if let Some(m) = self.motion_blur {
            look.motion_blur = m;
        }
        if let Some(d) = self.dust {
            if d > 1000 {
                return Err(invalid("dust", d, "must be ≤ 1000"));
            }
            look.dust_count = d;
        }
        let fps = positive("fps", self.fps)?;
        let exposure_s = positive("exposure-us", self.exposure_us)? / 1e6;
        if exposure_s > 1.0 / fps {
            return Err(invalid(
                "exposure-us",
                self.exposure_us,
                "must not exceed the frame interval 1e6 / fps",
            ));
        }
        for (name, v) in [("width-px", self.width_px), ("height-px", self.height_px)] {
            if !(32..=8192).contains(&v) {
                return Err(invalid(name, v, "must lie in 32‥8192"));
            }
        }
        let mm_per_px = self
            .mm_per_px
            .map(|v| positive("mm-per-px", v))
            .transpose()?;
        let slope = self.tilt.unwrap_or(self.preset.tilt());
        if !(slope.is_finite() && slope.abs() <= 0.2) {
            return Err(invalid(
                "tilt",
                slope,
                "must lie in [−0.2, 0.2] rows per column",
            ));
        }
        if let Some(r) = self.surface_row_px {
            if !(r.is_finite() && r > 0.0 && r < self.height_px as f64) {
                return Err(invalid("surface-row-px", r, "must lie inside the frame"));
            }
        }
        let b = positive("pillar-width-mm", self.pillar_width_mm)?;
        let c = positive("channel-width-mm", self.channel_width_mm)?;
        let surface = Surface {
            modulus_pa: positive("modulus-pa", self.modulus_pa)?,
            pillar_height_m: positive("pillar-height-mm", self.pillar_height_mm)? * 1e-3,
            pillar_width_m: b * 1e-3,
            channel_width_m: c * 1e-3,
            solid_fraction: b / (b + c),
        };
        if !(self.restitution.is_finite() && self.restitution >= 0.05 && self.restitution <= 1.0) {
            return Err(invalid(
                "restitution",
                self.restitution,
                "must lie in [0.05, 1]",
            ));
        }
        positive("gravity-m-s2", self.gravity_m_s2)?;
        if self.repeats == 0 || self.repeats > 1000 {
            return Err(invalid("repeats", self.repeats, "must lie in 1‥1000"));
        }
        Ok(RenderSettings {
            preset: self.preset,
            look,
            format: self.format,
            seed: self.seed,
            fps,
            exposure_s,
            width_px: self.width_px,
            height_px: self.height_px,
            mm_per_px,
            frames_before: self.frames_before,
            frames_after: self.frames_after,
            surface_row_px: self.surface_row_px,
            surface_slope: slope,
            density_kg_m3: positive("density-kg-m3", self.density_kg_m3)?,
            surface,
            restitution: self.restitution,
            gravity_m_s2: self.gravity_m_s2,
        })
    }

    /// The drops these options ask for.
    pub fn drops(&self) -> Result<Vec<DropSpec>, RenderError> {
        if self.campaign {
            for (name, list) in [
                ("radii-mm", &self.radii_mm),
                ("heights-cm", &self.heights_cm),
            ] {
                if list.is_empty() || list.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
                    return Err(invalid(name, format!("{list:?}"), "must be numbers > 0"));
                }
            }
            Ok(campaign::grid(
                &self.radii_mm,
                &self.heights_cm,
                self.repeats,
            ))
        } else if !self.drops.is_empty() {
            let pairs = self
                .drops
                .iter()
                .map(|d| campaign::parse_pair(d))
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| invalid("drop", e, "RADIUS_MM:HEIGHT_CM"))?;
            Ok(campaign::from_pairs(&pairs))
        } else {
            positive("radius-mm", self.radius_mm)?;
            positive("height-cm", self.height_cm)?;
            Ok(campaign::from_pairs(&[(self.radius_mm, self.height_cm)]))
        }
    }

    /// Whether a `runs.csv` manifest is written (campaigns and drop lists).
    pub fn writes_manifest(&self) -> bool {
        self.campaign || !self.drops.is_empty()
    }
}

/// What one rendered drop produced.
#[derive(Debug, Clone)]
pub struct DropSummary {
    pub run: String,
    /// The run's folder.
    pub dir: PathBuf,
    pub frames: usize,
    pub truth: Truth,
}

/// What a render produced.
#[derive(Debug, Default)]
pub struct RenderReport {
    pub drops: Vec<DropSummary>,
    /// Runs that failed, with the reason; the others were still rendered.
    pub failures: Vec<(String, String)>,
    pub manifest: Option<PathBuf>,
}

impl RenderReport {
    pub fn frames(&self) -> usize {
        self.drops.iter().map(|d| d.frames).sum()
    }
}

/// Run `dropscope render`: every drop asked for, then the manifest.
/// A drop that fails is reported and the others carry on.
pub fn render(args: &RenderArgs) -> Result<RenderReport, RenderError> {
    let settings = args.settings()?;
    let drops = args.drops()?;
    std::fs::create_dir_all(&args.out).map_err(|source| RenderError::CreateDir {
        path: args.out.clone(),
        source,
    })?;
    let mut report = RenderReport::default();
    for spec in &drops {
        match render_drop(spec, &settings, &args.out) {
            Ok(d) => report.drops.push(d),
            Err(e @ RenderError::Export(_)) | Err(e @ RenderError::CreateDir { .. }) => {
                return Err(e)
            }
            Err(e) => report.failures.push((spec.run.clone(), e.to_string())),
        }
    }
    if args.writes_manifest() {
        let rows: Vec<ManifestRow> = report
            .drops
            .iter()
            .map(|d| ManifestRow {
                run: d.run.clone(),
                path: d.run.clone(),
                sphere_radius_mm: d.truth.sphere_radius_mm,
                drop_height_cm: d.truth.drop_height_cm,
                fps: d.truth.fps,
                mm_per_px: args.manifest_scale.then_some(d.truth.mm_per_px),
                surface: args.surface_name.clone(),
                sphere_density_kg_m3: d.truth.sphere_density_kg_m3,
            })
            .collect();
        let path = args.out.join("runs.csv");
        let bytes = campaign::manifest_csv(&rows).map_err(|e| export::ExportError::Io {
            path: path.clone(),
            source: std::io::Error::other(e),
        })?;
        crate::io_util::write_atomic(&path, &bytes).map_err(|source| export::ExportError::Io {
            path: path.clone(),
            source,
        })?;
        report.manifest = Some(path);
    }
    Ok(report)
}

/// A ChaCha8 generator for one purpose, seeded from `(seed, run, stream,
/// index)` through FNV-1a and SplitMix64 (stable across platforms and
/// versions, unlike `std`'s hashers).
pub fn rng_for(seed: u64, run: &str, stream: &str, index: i64) -> ChaCha8Rng {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
        // a separator so that ("ab", "c") and ("a", "bc") differ
        h ^= 0xff;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    };
    eat(&seed.to_le_bytes());
    eat(run.as_bytes());
    eat(stream.as_bytes());
    eat(&index.to_le_bytes());
    let mut state = h;
    let mut key = [0u8; 32];
    for chunk in key.chunks_mut(8) {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        chunk.copy_from_slice(&z.to_le_bytes());
    }
    ChaCha8Rng::from_seed(key)
}

/// The default scale: 0.04 mm/px at R = 3 mm, +0.01 per mm of radius (R_px
/// from 75 px at 3 mm to 87.5 px at 7 mm on a 384-row frame), scaled with
/// the frame height so a smaller frame keeps the same framing.
pub fn default_mm_per_px(radius_mm: f64, height_px: usize) -> f64 {
    let at_384 = if radius_mm >= 3.0 {
        0.04 + 0.01 * (radius_mm - 3.0)
    } else {
        radius_mm / 75.0
    };
    at_384 * 384.0 / height_px as f64
}

/// The trigger of campaign drop `index`: 2019-06-13 10:00:00 local time
/// (the paper's arXiv month) plus one minute per drop, in 10 ns ticks.
fn trigger_10ns(index: usize) -> i64 {
    let day = export::days_from_civil(2019, 6, 13);
    (day * 86_400 + 10 * 3600 + 60 * index as i64) * 100_000_000
}

/// Sphere centres (px) at `k` instants spread over the exposure of a frame
/// with mid-exposure `t_s` (midpoint rule), or only at `t_s` without motion blur.
fn exposure_samples(
    centre: &impl Fn(f64) -> (f64, f64),
    t_s: f64,
    exposure_s: f64,
    motion_blur: bool,
) -> Vec<(f64, f64)> {
    if !motion_blur {
        return vec![centre(t_s)];
    }
    // Path length over the exposure → about 0.1 px between samples.
    let probe: Vec<f64> = (0..=16)
        .map(|q| centre(t_s + exposure_s * (q as f64 / 16.0 - 0.5)).1)
        .collect();
    let path: f64 = probe.windows(2).map(|w| (w[1] - w[0]).abs()).sum();
    let k = ((path / 0.1).ceil() as usize).clamp(1, 64);
    (0..k)
        .map(|q| centre(t_s + exposure_s * ((q as f64 + 0.5) / k as f64 - 0.5)))
        .collect()
}

/// Render one drop into `<out>/<run>/`.
pub fn render_drop(
    spec: &DropSpec,
    st: &RenderSettings,
    out: &Path,
) -> Result<DropSummary, RenderError> {
    let run = spec.run.as_str();
    let phys_err = |source| RenderError::Physics {
        run: run.to_string(),
        source,
    };
    let radius_m = positive("radius-mm", spec.radius_mm)? * 1e-3;
    let height_m = positive("height-cm", spec.height_cm)? * 1e-2;
    let frame_dt = 1.0 / st.fps;

    // ---- layout, from the run's own generator
    let mut layout = rng_for(st.seed, run, "layout", 0);
    let contact_phase: f64 = layout.gen_range(0.0..1.0);
    let column_offset: f64 = layout.gen_range(-1.0..1.0);
    let row_fraction: f64 = layout.gen_range(0.0..1.0);
    let pillar_phase_frac: f64 = layout.gen_range(0.0..1.0);

    // ---- physics
    let g = st.gravity_m_s2;
    let v = (2.0 * g * height_m).sqrt();
    let mut params = DropParams {
        sphere_radius_m: radius_m,
        sphere_density_kg_m3: st.density_kg_m3,
        surface: st.surface,
        gravity_m_s2: g,
        impact_speed_m_s: v,
        damping_n_s_m: 0.0,
    };
    let step = params.default_step_s(frame_dt / 100.0);
    params.damping_n_s_m =
        physics::damping_for_restitution(&params, st.restitution, step).map_err(phys_err)?;
    let t_contact = contact_phase / st.fps;
    let first = Trajectory::simulate(&params, t_contact, t_contact, step).map_err(phys_err)?;
    let t_rebound = first.bounces()[0].t_rebound_s;
    let n0 = -(st.frames_before as i64);
    let n1 = (t_rebound * st.fps).ceil() as i64 + st.frames_after as i64;
    let t_window_end = n1 as f64 / st.fps + 0.5 * st.exposure_s;
    let traj = Trajectory::simulate(&params, t_contact, t_window_end, step).map_err(phys_err)?;
    let b = traj.bounces()[0];

    // ---- geometry
    let mm_per_px = st
        .mm_per_px
        .unwrap_or_else(|| default_mm_per_px(spec.radius_mm, st.height_px));
    let m_per_px = mm_per_px * 1e-3;
    let radius_px = spec.radius_mm / mm_per_px;
    let surface_row_px = st
        .surface_row_px
        .unwrap_or((0.72 * st.height_px as f64).round() + row_fraction);
    let impact_column_px = 0.5 * st.width_px as f64 + column_offset * st.width_px as f64 / 16.0;
    let pillar_width_px = st.surface.pillar_width_m / m_per_px;
    let channel_width_px = st.surface.channel_width_m / m_per_px;
    let scene = Scene {
        width_px: st.width_px,
        height_px: st.height_px,
        radius_px,
        surface_row_px,
        surface_slope: st.surface_slope,
        pillar_height_px: st.surface.pillar_height_m / m_per_px,
        pillar_width_px,
        channel_width_px,
        pillar_phase_px: pillar_phase_frac * (pillar_width_px + channel_width_px),
    };
    let y_s = scene.surface_row_at(impact_column_px);
    let centre = |t: f64| -> (f64, f64) {
        let (d, _) = traj.state(t);
        (impact_column_px, y_s - radius_px + d / m_per_px)
    };
    let mut dust_rng = rng_for(st.seed, "", "dust", 0);
    let raster = Raster::new(scene, st.look.clone(), &mut dust_rng).map_err(|source| {
        RenderError::Raster {
            run: run.to_string(),
            source,
        }
    })?;

    // ---- frames
    let dir = out.join(run);
    std::fs::create_dir_all(&dir).map_err(|source| RenderError::CreateDir {
        path: dir.clone(),
        source,
    })?;
    let numbers: Vec<i64> = (n0..=n1).collect();
    let mut sink: Box<dyn FrameSink> = match st.format {
        FrameFormat::Tiff | FrameFormat::Png => {
            Box::new(FolderSink::new(&dir, run, st.format, st.look.bit_depth))
        }
    };
    for chunk in numbers.chunks(64) {
        let frames: Vec<(i64, crate::source::Frame)> = chunk
            .par_iter()
            .map(|&n| {
                let t = n as f64 / st.fps;
                let centres = exposure_samples(&centre, t, st.exposure_s, st.look.motion_blur);
                let mut rng = rng_for(st.seed, run, "frame", n);
                (n, raster.frame(&centres, &mut rng))
            })
            .collect();
        sink.write_batch(&frames)?;
    }
    sink.finish()?;

    // ---- side file and truth
    let header = PccHeader {
        description: format!("dropscope render {run} (synthetic)"),
        first_image_no: n0,
        image_count: numbers.len(),
        width_px: st.width_px,
        height_px: st.height_px,
        bit_depth: st.look.bit_depth,
        fps: st.fps,
        exposure_s: st.exposure_s,
        trigger_10ns: trigger_10ns(spec.index),
    };
    export::write_pcc_xml(&dir.join(format!("{run}.xml")), &header)?;

    let frames_truth: Vec<FrameTruth> = numbers
        .iter()
        .map(|&n| {
            let t = n as f64 / st.fps;
            let (x, z) = centre(t);
            let d = traj.state(t).0;
            FrameTruth {
                frame: n,
                t_s: t,
                x_px: x,
                z_px: z,
                delta_mm: d.max(0.0) * 1e3,
                in_contact: d > 0.0,
            }
        })
        .collect();
    let second_bounce = traj
        .bounces()
        .get(1)
        .filter(|s| s.t_contact_s <= t_window_end)
        .map(|s| BounceTruth {
            t_contact_s: s.t_contact_s,
            t_max_s: s.t_max_s,
            t_rebound_s: s.t_rebound_s,
            tau_c_s: s.tau_c_s(),
            v_impact_m_s: s.v_impact_m_s,
            v_rebound_m_s: s.v_rebound_m_s,
            restitution: s.restitution(),
            delta_max_mm: s.delta_max_m * 1e3,
        });
    let r_mm = spec.radius_mm;
    let dmax_mm = b.delta_max_m * 1e3;
    let truth = Truth {
        run: run.to_string(),
        seed: st.seed,
        preset: st.preset.name().to_string(),
        sphere_radius_mm: r_mm,
        sphere_density_kg_m3: st.density_kg_m3,
        drop_height_cm: spec.height_cm,
        surface: SurfaceTruth {
            modulus_pa: st.surface.modulus_pa,
            pillar_height_mm: st.surface.pillar_height_m * 1e3,
            pillar_width_mm: st.surface.pillar_width_m * 1e3,
            channel_width_mm: st.surface.channel_width_m * 1e3,
            solid_fraction: st.surface.solid_fraction,
        },
        restitution_requested: st.restitution,
        fps: st.fps,
        exposure_s: st.exposure_s,
        width_px: st.width_px,
        height_px: st.height_px,
        bit_depth: st.look.bit_depth,
        mm_per_px,
        radius_px,
        surface_row_px,
        surface_slope: st.surface_slope,
        impact_column_px,
        t_contact_s: b.t_contact_s,
        t_rebound_s: b.t_rebound_s,
        tau_c_s: b.tau_c_s(),
        t_max_s: b.t_max_s,
        v_impact_m_s: b.v_impact_m_s,
        v_rebound_m_s: b.v_rebound_m_s,
        restitution: b.restitution(),
        delta_max_mm: dmax_mm,
        a_max_mm: (r_mm * r_mm - (r_mm - dmax_mm).powi(2)).max(0.0).sqrt(),
        second_bounce,
        resting_contact_s: traj.resting_contact_s().filter(|&t| t <= t_window_end),
        gravity_m_s2: g,
        damping_n_s_m: params.damping_n_s_m,
        integration_step_s: step,
        first_image_no: n0,
        look: st.look.clone(),
        frames: frames_truth,
    };
    export::write_truth(&dir.join("truth.json"), &truth)?;
    Ok(DropSummary {
        run: run.to_string(),
        dir,
        frames: numbers.len(),
        truth,
    })
}
