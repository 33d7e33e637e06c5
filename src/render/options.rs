//! The options of `dropscope render`: the presets, the options as asked
//! ([`RenderOptions`], from the command line's `crate::cli::render`) and
//! their validated form ([`RenderSettings`]). Errors name the option, its value and what is allowed.

use std::path::PathBuf;

use serde::Serialize;

use super::campaign::{self, DropSpec};
use super::contact::{ContactMode, ContactSpec, DampingArg};
use super::export::{CinePackingChoice, FrameFormat};
use super::optics::{OpticsSpec, Strength};
use super::physics::Damping;
use super::raster::Look;
use super::RenderError;
use crate::config::Surface;

/// A starting set of effects; every effect can still be set on its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
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
    /// Real backlit Phantom footage: `realistic`'s sensor plus every effect of
    /// a real camera, each drawn per drop (or per camera set-up) from a wide
    /// range: steel-ball rim 0–20 % over 1–4 px, halo 0–8 % over 1–4 px,
    /// highlight 0–15 %; glossy strip 0–30 % over 1–4 px; top row −25…+25 %
    /// over 1–2 px; dip 0–30 % of δ; blur σ 0.6–1.2 px at the focal row
    /// growing to at most 2.5 px; barrel distortion 0–0.5 px at the corners;
    /// roll −0.5…+0.5°; column pattern 0–1.5 %; 0–50 hot pixels; drift
    /// 0–5 %; the movie starts as the sphere enters, goes on through a second
    /// contact when the flight between takes at most 1 500 frames, and misses
    /// one frame file in flight. Scale ±8 % and surface row ±10 px per set-up
    /// (one set-up per radius and repeat).
    Real,
    /// `real` with a saturated backlight and a glinting ball, as in many real
    /// rigs: the background clipped at white (the light 10–50 % above full
    /// scale, so the background has no noise), and a central glint of
    /// 0.5–3 times the backlight with σ 0.08–0.2 R, clipped at white.
    RealSaturated,
}

impl Preset {
    /// The preset's name, as `--preset` takes it.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Clean => "clean",
            Preset::Realistic => "realistic",
            Preset::Harsh => "harsh",
            Preset::Real => "real",
            Preset::RealSaturated => "real-saturated",
        }
    }

    /// A real camera's presets: every camera effect drawn per drop, one
    /// camera set-up per radius and repeat, `runs.csv` without the scale.
    pub fn is_real(self) -> bool {
        matches!(self, Preset::Real | Preset::RealSaturated)
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
            Preset::Realistic | Preset::Real | Preset::RealSaturated => Look {
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

/// What `dropscope render` is asked for (the command line's
/// `crate::cli::render::RenderOptions`): one drop (`--radius-mm`, `--height-cm`), a list
/// (`--drop R:H`, repeatable), or the paper's grid (`--campaign`).
#[derive(Debug, Clone)]
pub struct RenderOptions {
    /// Output folder; each drop gets a sub-folder named after its run.
    pub out: PathBuf,
    /// Render the grid --radii-mm × --heights-cm (the paper's by default) and write runs.csv.
    pub campaign: bool,
    /// Radii of the campaign grid, mm (with --campaign).
    pub radii_mm: Vec<f64>,
    /// Drop heights of the campaign grid, cm (with --campaign).
    pub heights_cm: Vec<f64>,
    /// Repeats of every grid point (each a new contact phase, column and noise; with --campaign).
    pub repeats: usize,
    /// Render exactly these drops, RADIUS_MM:HEIGHT_CM (repeatable or comma-separated), and write runs.csv.
    pub drops: Vec<String>,
    /// Sphere radius of a single drop, mm.
    pub radius_mm: f64,
    /// Drop height of a single drop (lowest point of the sphere to the surface), cm.
    pub height_cm: f64,
    /// Seed of every random choice; the same seed gives byte-identical files.
    pub seed: u64,
    /// Starting set of effects; the options below override it one by one.
    pub preset: Preset,
    /// Frame files: tiff (uncompressed), png, jpeg (8-bit) or one cine.
    pub format: FrameFormat,
    /// How --format cine stores 12-bit frames: unpacked (16-bit containers),
    /// p10 (log-encoded 10-bit codes, as Phantom's "10-bit" saves) or p12l.
    pub packing: CinePackingChoice,

    // ---- physics
    /// Sphere density, kg/m³.
    pub density_kg_m3: f64,
    /// Young's modulus of the pillars, Pa.
    pub modulus_pa: f64,
    /// Pillar height h, mm.
    pub pillar_height_mm: f64,
    /// Pillar width b, mm.
    pub pillar_width_mm: f64,
    /// Channel width c, mm (φ = b / (b + c)).
    pub channel_width_mm: f64,
    /// Coefficient of restitution (speeds where δ crosses 0); below 1 adds damping solved to give it (linear unless --damping says otherwise) [default: 1; with --contact wide: drawn in 0.3‥0.98].
    pub restitution: Option<f64>,
    /// The contact law: `model` (π E φ R δ²/h, the measurement's) or `wide` (per drop: n 1.4‥2.6, damping none / linear / Hunt–Crossley, adhesion or not, restitution 0.3‥0.98; truth.json records each); the three options below fix one value.
    pub contact: ContactMode,
    /// Elastic exponent n of the force K_n·δ^n, 1‥4, with K_n = K·δ_ref^(2−n) (δ_ref: the model's δmax for the drop) [default: 2; wide: drawn].
    pub force_exponent: Option<f64>,
    /// Damping solved for the restitution: none (restitution 1), linear (c·dδ/dt) or hunt-crossley (α·K_n·δ^n·dδ/dt) [default: linear when --restitution < 1; wide: drawn].
    pub damping: Option<DampingArg>,
    /// A force that cannot pull: clamped at F ≥ 0, so the sphere leaves the surface where the force reaches 0, before δ returns to 0 [default: the force may pull; wide: drawn].
    pub no_adhesion: bool,
    /// Gravity, m/s².
    pub gravity_m_s2: f64,
    /// Name of the surface written to runs.csv (a `[surface.<name>]` of pipeline.toml).
    pub surface_name: String,

    // ---- camera
    /// Frame width, px.
    pub width_px: usize,
    /// Frame height, px.
    pub height_px: usize,
    /// Frames per second.
    pub fps: f64,
    /// Exposure time, µs.
    pub exposure_us: f64,
    /// Scale, mm/px [default: 0.04 + 0.01 per mm of R above 3 mm: R_px 75‥87.5].
    pub mm_per_px: Option<f64>,
    /// Bits per sample, 8 or 12 [default: the preset's].
    pub bit_depth: Option<u8>,
    /// Frames before the first contact (unless the movie starts at the sphere's entry, --start-at-entry).
    pub frames_before: usize,
    /// Frames after the loss of contact.
    pub frames_after: usize,
    /// Undeformed surface row at column 0, px [default: 0.72·height plus a random fraction].
    pub surface_row_px: Option<f64>,
    /// Surface tilt, rows per column [default: the preset's].
    pub tilt: Option<f64>,

    // ---- look (0 switches an effect off)
    /// Illumination gradient amplitude (relative).
    pub gradient: Option<f64>,
    /// Gaussian optical blur σ, px.
    pub blur_px: Option<f64>,
    /// Motion blur over the exposure (true/false).
    pub motion_blur: Option<bool>,
    /// Gaussian read noise, DN.
    pub read_noise_dn: Option<f64>,
    /// Full-well electrons at white for Poisson shot noise.
    pub full_well_e: Option<f64>,
    /// Relative r.m.s. frame-to-frame flicker.
    pub flicker: Option<f64>,
    /// Number of dust specks.
    pub dust: Option<usize>,
    /// Strength of the mirror reflection below the surface line.
    pub reflection: Option<f64>,
    /// Background brightness at the centre, fraction of white.
    pub background_level: Option<f64>,
    /// Light through the silhouette, fraction of the background.
    pub sphere_transmission: Option<f64>,

    // ---- a real camera (off unless given, drawn per drop with --preset real)
    /// Steel ball's light rim just inside the outline, fraction of the backlight [real: 0–0.2].
    pub rim: Option<f64>,
    /// Width over which the rim fades, px [real: 1–4; else 2].
    pub rim_width_px: Option<f64>,
    /// Faint bright halo just outside the outline, fraction of the backlight [real: 0–0.08].
    pub halo: Option<f64>,
    /// Width over which the halo fades, px [real: 1–4; else 2].
    pub halo_width_px: Option<f64>,
    /// Soft highlight near the sphere's middle (Gaussian, σ 0.2–0.35 R), fraction of the backlight [real: 0–0.15].
    pub highlight: Option<f64>,
    /// Glossy band top: bright strip just below the band's top edge, fraction of the backlight [real: 0–0.3].
    pub gloss: Option<f64>,
    /// Depth of the glossy strip, px [real: 1–4; else 2].
    pub gloss_width_px: Option<f64>,
    /// Pillar tops seen edge-on: the band's top rows times (1 + this) [real: −0.25…0.25].
    pub top_row: Option<f64>,
    /// Depth of the top row, px [real: 1–2; else 1].
    pub top_row_width_px: Option<f64>,
    /// Band top dipping under the sphere in contact, fraction of the sphere's local depth (≤ δ) [real: 0–0.3].
    pub dip: Option<f64>,
    /// Defocus: blur σ grows by this many px per row away from --focus-row-px (σ at the focus: --blur-px) [real: up to σ 2.5 px].
    pub defocus_px_per_row: Option<f64>,
    /// The row in best focus, px [real: anywhere in the frame; else 0].
    pub focus_row_px: Option<f64>,
    /// Barrel distortion: inward displacement of the image corners, px [real: 0–0.5].
    pub distortion_px: Option<f64>,
    /// Camera roll about the image centre, degrees [real: −0.5…0.5].
    pub roll_deg: Option<f64>,
    /// Column fixed-pattern noise: r.m.s. per-column gain and offset (fraction) [real: 0–0.015].
    pub column_noise: Option<f64>,
    /// Number of stuck-bright hot pixels [real: 0–50].
    pub hot_pixels: Option<usize>,
    /// Slow illumination drift over the movie, amplitude on each side (fraction) [real: 0–0.05].
    pub drift: Option<f64>,
    /// Frame files in flight left unwritten per drop [real: 1].
    pub missing_frames: Option<usize>,
    /// Start the movie as the sphere enters at the top edge (or at its release, when in view) [real: true].
    pub start_at_entry: Option<bool>,
    /// JPEG quality 1‥100 with --format jpeg [real: drawn per drop in 85‥98; else 95].
    pub jpeg_quality: Option<u8>,
    /// Saturated backlight: the dimmest background pixel reads 1 + this times white before the sensor clips [real-saturated: 0.1–0.5].
    pub saturation: Option<f64>,
    /// Central glint on the ball (Gaussian), fraction of the backlight; above 1 it clips at white [real-saturated: 0.5–3].
    pub glint: Option<f64>,
    /// σ of the glint, fraction of the sphere's radius [real-saturated: 0.08–0.2; else 0.15].
    pub glint_sigma: Option<f64>,
    /// Go on through a second contact when the flight to it takes at most this many frames; 0: never [real: 1500].
    pub second_bounce_frames: Option<usize>,

    /// Write mm_per_px into runs.csv (by default the pipeline must measure it).
    pub manifest_scale: bool,
    /// Also write runs_scaled.csv: runs.csv's rows with the true mm_per_px, as from a calibration target.
    pub scaled_manifest: bool,
}

/// Validated settings shared by every drop of a render.
#[derive(Debug, Clone)]
pub struct RenderSettings {
    /// The preset the settings started from.
    pub preset: Preset,
    /// The picture's look: sensor, light and blur.
    pub look: Look,
    /// A real camera's effects (all off outside `--preset real` unless given).
    pub optics: OpticsSpec,
    /// How each drop's frames are written.
    pub format: FrameFormat,
    /// How a `.cine` stores its samples.
    pub packing: CinePackingChoice,
    /// JPEG quality: fixed, or drawn per drop in the range (`--preset real`).
    pub jpeg_quality: (u8, u8),
    /// Seed of every random choice; the same seed gives byte-identical files.
    pub seed: u64,
    /// Frame rate, frames/s.
    pub fps: f64,
    /// Exposure time of each frame (at most the frame interval), s.
    pub exposure_s: f64,
    /// Frame width, px.
    pub width_px: usize,
    /// Frame height, px.
    pub height_px: usize,
    /// Scale, mm per px; `None`: chosen from the sphere's radius.
    pub mm_per_px: Option<f64>,
    /// Frames before the first contact (unless the movie starts at the sphere's entry).
    pub frames_before: usize,
    /// Frames after the loss of contact.
    pub frames_after: usize,
    /// Undeformed surface row at column 0, px; `None`: drawn near 0.72 of the height.
    pub surface_row_px: Option<f64>,
    /// Surface tilt, rows per column.
    pub surface_slope: f64,
    /// Sphere density, kg/m³.
    pub density_kg_m3: f64,
    /// The pillar surface the spheres hit.
    pub surface: Surface,
    /// The model's restitution (linear damping solved for it).
    pub restitution: f64,
    /// The contact law's options ([`ContactSpec::is_model`]: the model).
    pub contact: ContactSpec,
    /// Gravity, m/s².
    pub gravity_m_s2: f64,
}

fn invalid(name: &'static str, value: impl ToString, allowed: &str) -> RenderError {
    RenderError::Invalid {
        name,
        value: value.to_string(),
        allowed: allowed.to_string(),
    }
}

pub(super) fn positive(name: &'static str, v: f64) -> Result<f64, RenderError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(invalid(name, v, "must be a finite number > 0"))
    }
}

impl RenderOptions {
    /// Check the options and build the settings (errors name the option).
    pub fn settings(&self) -> Result<RenderSettings, RenderError> {
        let look = self.look()?;
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
        let restitution = self.restitution.unwrap_or(1.0);
        if !(restitution.is_finite() && (0.05..=1.0).contains(&restitution)) {
            return Err(invalid("restitution", restitution, "must lie in [0.05, 1]"));
        }
        let contact = self.contact_spec()?;
        positive("gravity-m-s2", self.gravity_m_s2)?;
        if self.repeats == 0 || self.repeats > 1000 {
            return Err(invalid("repeats", self.repeats, "must lie in 1‥1000"));
        }
        let optics = self.optics(&look)?;
        self.check_format(&look)?;
        let jpeg_quality = match (self.jpeg_quality, self.preset) {
            (Some(q), _) if !(1..=100).contains(&q) => {
                return Err(invalid("jpeg-quality", q, "must lie in 1‥100"))
            }
            (Some(q), _) => (q, q),
            (None, p) if p.is_real() => (85, 98),
            (None, _) => (95, 95),
        };
        Ok(RenderSettings {
            preset: self.preset,
            look,
            optics,
            format: self.format,
            packing: self.packing,
            jpeg_quality,
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
            restitution,
            contact,
            gravity_m_s2: self.gravity_m_s2,
        })
    }

    /// The preset's look with the look options applied, each checked.
    fn look(&self) -> Result<Look, RenderError> {
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
        Ok(look)
    }

    /// The frame format against the bit depth, and the packing against both.
    fn check_format(&self, look: &Look) -> Result<(), RenderError> {
        if self.format == FrameFormat::Jpeg && look.bit_depth != 8 {
            return Err(invalid(
                "format",
                "jpeg",
                "JPEG frames hold 8 bits: add --bit-depth 8",
            ));
        }
        if self.packing != CinePackingChoice::Unpacked {
            let name = match self.packing {
                CinePackingChoice::P10 => "p10",
                _ => "p12l",
            };
            if self.format != FrameFormat::Cine {
                return Err(invalid(
                    "packing",
                    name,
                    "packs the samples of a .cine: add --format cine",
                ));
            }
            if look.bit_depth != 12 {
                return Err(invalid(
                    "packing",
                    name,
                    "packs 12-bit frames: add --bit-depth 12",
                ));
            }
        }
        Ok(())
    }

    /// The contact options, checked against each other.
    fn contact_spec(&self) -> Result<ContactSpec, RenderError> {
        if let Some(n) = self.force_exponent {
            if !(n.is_finite() && (1.0..=4.0).contains(&n)) {
                return Err(invalid("force-exponent", n, "must lie in [1, 4]"));
            }
        }
        let damping = self.damping.map(Damping::from);
        let e = self.restitution;
        match (damping, e) {
            (Some(Damping::None), Some(e)) if e < 1.0 => {
                return Err(invalid(
                    "restitution",
                    e,
                    "must be 1 with --damping none (no damping: nothing is lost)",
                ))
            }
            (Some(kind @ (Damping::Linear | Damping::HuntCrossley)), e)
                if self.contact == ContactMode::Model && e.unwrap_or(1.0) >= 1.0 =>
            {
                return Err(invalid(
                    "damping",
                    kind.name(),
                    "damps nothing at restitution 1: add --restitution below 1 (or --contact wide to draw it)",
                ))
            }
            _ => {}
        }
        Ok(ContactSpec {
            mode: self.contact,
            exponent: self.force_exponent,
            damping,
            no_adhesion: self.no_adhesion,
            restitution: e,
        })
    }

    /// The real-camera effects: the preset's ranges, each replaced by its
    /// option when given.
    fn optics(&self, look: &Look) -> Result<OpticsSpec, RenderError> {
        let mut o = match self.preset {
            Preset::Real => OpticsSpec::real(),
            Preset::RealSaturated => OpticsSpec::real_saturated(),
            _ => OpticsSpec::off(),
        };
        if self.preset.is_real() {
            if let Some(b) = self.blur_px {
                o.blur_sigma0_px = Strength::Fixed(b);
            }
        } else {
            o.blur_sigma0_px = Strength::Fixed(look.blur_sigma_px);
        }
        let fix = |target: &mut Strength,
                   v: Option<f64>,
                   name: &'static str,
                   (lo, hi): (f64, f64)|
         -> Result<(), RenderError> {
            if let Some(v) = v {
                if !(v.is_finite() && (lo..=hi).contains(&v)) {
                    return Err(invalid(name, v, &format!("must lie in [{lo}, {hi}]")));
                }
                *target = Strength::Fixed(v);
            }
            Ok(())
        };
        fix(&mut o.rim, self.rim, "rim", (0.0, 1.0))?;
        fix(
            &mut o.rim_width_px,
            self.rim_width_px,
            "rim-width-px",
            (0.1, 20.0),
        )?;
        fix(&mut o.halo, self.halo, "halo", (0.0, 1.0))?;
        fix(
            &mut o.halo_width_px,
            self.halo_width_px,
            "halo-width-px",
            (0.1, 20.0),
        )?;
        fix(&mut o.highlight, self.highlight, "highlight", (0.0, 1.0))?;
        fix(&mut o.gloss, self.gloss, "gloss", (0.0, 1.0))?;
        fix(
            &mut o.gloss_width_px,
            self.gloss_width_px,
            "gloss-width-px",
            (0.1, 20.0),
        )?;
        fix(&mut o.top_row, self.top_row, "top-row", (-1.0, 1.0))?;
        fix(
            &mut o.top_row_width_px,
            self.top_row_width_px,
            "top-row-width-px",
            (0.1, 20.0),
        )?;
        fix(&mut o.dip, self.dip, "dip", (0.0, 1.0))?;
        fix(
            &mut o.defocus_px_per_row,
            self.defocus_px_per_row,
            "defocus-px-per-row",
            (0.0, 0.1),
        )?;
        fix(
            &mut o.focus_row_px,
            self.focus_row_px,
            "focus-row-px",
            (0.0, self.height_px as f64),
        )?;
        fix(
            &mut o.corner_displacement_px,
            self.distortion_px,
            "distortion-px",
            (0.0, 5.0),
        )?;
        fix(&mut o.roll_deg, self.roll_deg, "roll-deg", (-5.0, 5.0))?;
        fix(
            &mut o.column_noise,
            self.column_noise,
            "column-noise",
            (0.0, 0.2),
        )?;
        fix(
            &mut o.hot_pixels,
            self.hot_pixels.map(|n| n as f64),
            "hot-pixels",
            (0.0, 10_000.0),
        )?;
        fix(&mut o.drift, self.drift, "drift", (0.0, 0.5))?;
        fix(&mut o.saturation, self.saturation, "saturation", (0.0, 2.0))?;
        fix(&mut o.glint, self.glint, "glint", (0.0, 10.0))?;
        fix(
            &mut o.glint_sigma,
            self.glint_sigma,
            "glint-sigma",
            (0.01, 1.0),
        )?;
        if let Some(n) = self.missing_frames {
            if n > 100 {
                return Err(invalid("missing-frames", n, "must be ≤ 100"));
            }
            o.missing_frames = n;
        }
        if let Some(b) = self.start_at_entry {
            o.start_at_entry = b;
        }
        if let Some(n) = self.second_bounce_frames {
            o.second_bounce_frames = n;
        }
        Ok(o)
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
}
