//! The command line of `dropscope render` ([`RenderArgs`]), parsed into
//! [`RenderOptions`], and the values its choices take (presets, contact
//! modes, damping, frame formats, `.cine` packing), each with its help.

use crate::render::contact::ContactMode;
use crate::render::contact::DampingArg;
use crate::render::export::CinePackingChoice;
use crate::render::export::FrameFormat;
use crate::render::Preset;
use crate::render::{campaign, physics, RenderOptions};
use clap::builder::PossibleValue;
use clap::ValueEnum;
use std::path::PathBuf;

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
    /// Radii of the campaign grid, mm (with --campaign).
    #[arg(long, value_delimiter = ',', num_args = 1.., default_values_t = campaign::PAPER_RADII_MM, requires = "campaign", value_parser = crate::util::flag_values::positive, allow_negative_numbers = true)]
    pub radii_mm: Vec<f64>,
    /// Drop heights of the campaign grid, cm (with --campaign).
    #[arg(long, value_delimiter = ',', num_args = 1.., default_values_t = campaign::PAPER_HEIGHTS_CM, requires = "campaign", value_parser = crate::util::flag_values::positive, allow_negative_numbers = true)]
    pub heights_cm: Vec<f64>,
    /// Repeats of every grid point (each a new contact phase, column and noise; with --campaign).
    #[arg(long, default_value_t = 1, requires = "campaign")]
    pub repeats: usize,
    /// Render exactly these drops, RADIUS_MM:HEIGHT_CM (repeatable or comma-separated), and write runs.csv.
    #[arg(long = "drop", value_delimiter = ',', conflicts_with = "campaign")]
    pub drops: Vec<String>,
    /// Sphere radius of a single drop, mm.
    #[arg(long, default_value_t = 4.5, conflicts_with_all = ["campaign", "drops"], value_parser = crate::util::flag_values::positive, allow_negative_numbers = true)]
    pub radius_mm: f64,
    /// Drop height of a single drop (lowest point of the sphere to the surface), cm.
    #[arg(long, default_value_t = 12.0, conflicts_with_all = ["campaign", "drops"], value_parser = crate::util::flag_values::positive, allow_negative_numbers = true)]
    pub height_cm: f64,
    /// Seed of every random choice; the same seed gives byte-identical files.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Starting set of effects; the options below override it one by one.
    #[arg(long, value_enum, default_value_t = Preset::Realistic)]
    pub preset: Preset,
    /// Frame files: tiff (uncompressed), png, jpeg (8-bit) or one cine.
    #[arg(long, value_enum, default_value_t = FrameFormat::Tiff)]
    pub format: FrameFormat,
    /// How --format cine stores 12-bit frames: unpacked (16-bit containers),
    /// p10 (log-encoded 10-bit codes, as Phantom's "10-bit" saves) or p12l.
    #[arg(long, value_enum, default_value_t = CinePackingChoice::Unpacked)]
    pub packing: CinePackingChoice,

    // ---- physics
    /// Sphere density, kg/m³.
    #[arg(long, default_value_t = 7800.0, value_parser = crate::util::flag_values::positive, allow_negative_numbers = true)]
    pub density_kg_m3: f64,
    /// Young's modulus of the pillars, Pa.
    #[arg(long, default_value_t = 1.6e6, value_parser = crate::util::flag_values::positive, allow_negative_numbers = true)]
    pub modulus_pa: f64,
    /// Pillar height h, mm.
    #[arg(long, default_value_t = 3.5, value_parser = crate::util::flag_values::positive, allow_negative_numbers = true)]
    pub pillar_height_mm: f64,
    /// Pillar width b, mm.
    #[arg(long, default_value_t = 2.5, value_parser = crate::util::flag_values::positive, allow_negative_numbers = true)]
    pub pillar_width_mm: f64,
    /// Channel width c, mm (φ = b / (b + c)).
    #[arg(long, default_value_t = 1.5, value_parser = crate::util::flag_values::positive, allow_negative_numbers = true)]
    pub channel_width_mm: f64,
    /// Coefficient of restitution (speeds where δ crosses 0); below 1 adds damping solved to give it (linear unless --damping says otherwise) [default: 1; with --contact wide: drawn in 0.3‥0.98].
    #[arg(long, allow_negative_numbers = true)]
    pub restitution: Option<f64>,
    /// The contact law: `model` (π E φ R δ²/h, the measurement's) or `wide` (per drop: n 1.4‥2.6, damping none / linear / Hunt–Crossley, adhesion or not, restitution 0.3‥0.98; truth.json records each); the three options below fix one value.
    #[arg(long, value_enum, default_value_t = ContactMode::Model)]
    pub contact: ContactMode,
    /// Elastic exponent n of the force K_n·δ^n, 1‥4, with K_n = K·δ_ref^(2−n) (δ_ref: the model's δmax for the drop) [default: 2; wide: drawn].
    #[arg(long, allow_negative_numbers = true)]
    pub force_exponent: Option<f64>,
    /// Damping solved for the restitution: none (restitution 1), linear (c·dδ/dt) or hunt-crossley (α·K_n·δ^n·dδ/dt) [default: linear when --restitution < 1; wide: drawn].
    #[arg(long, value_enum)]
    pub damping: Option<DampingArg>,
    /// A force that cannot pull: clamped at F ≥ 0, so the sphere leaves the surface where the force reaches 0, before δ returns to 0 [default: the force may pull; wide: drawn].
    #[arg(long)]
    pub no_adhesion: bool,
    /// Gravity, m/s².
    #[arg(long, default_value_t = physics::STANDARD_GRAVITY_M_S2, value_parser = crate::util::flag_values::positive, allow_negative_numbers = true)]
    pub gravity_m_s2: f64,
    /// Name of the surface written to runs.csv (a `[surface.<name>]` of pipeline.toml).
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
    #[arg(long, default_value_t = 10_000.0, value_parser = crate::util::flag_values::positive, allow_negative_numbers = true)]
    pub fps: f64,
    /// Exposure time, µs.
    #[arg(long, default_value_t = 50.0, value_parser = crate::util::flag_values::positive, allow_negative_numbers = true)]
    pub exposure_us: f64,
    /// Scale, mm/px [default: 0.04 + 0.01 per mm of R above 3 mm: R_px 75‥87.5].
    #[arg(long, value_parser = crate::util::flag_values::positive, allow_negative_numbers = true)]
    pub mm_per_px: Option<f64>,
    /// Bits per sample, 8 or 12 [default: the preset's].
    #[arg(long)]
    pub bit_depth: Option<u8>,
    /// Frames before the first contact (unless the movie starts at the sphere's entry, --start-at-entry).
    #[arg(long, default_value_t = 30)]
    pub frames_before: usize,
    /// Frames after the loss of contact.
    #[arg(long, default_value_t = 30)]
    pub frames_after: usize,
    /// Undeformed surface row at column 0, px [default: 0.72·height plus a random fraction].
    #[arg(long, allow_negative_numbers = true)]
    pub surface_row_px: Option<f64>,
    /// Surface tilt, rows per column [default: the preset's].
    #[arg(long, allow_negative_numbers = true)]
    pub tilt: Option<f64>,

    // ---- look (0 switches an effect off)
    /// Illumination gradient amplitude (relative).
    #[arg(long, allow_negative_numbers = true)]
    pub gradient: Option<f64>,
    /// Gaussian optical blur σ, px.
    #[arg(long, allow_negative_numbers = true)]
    pub blur_px: Option<f64>,
    /// Motion blur over the exposure (true/false).
    #[arg(long)]
    pub motion_blur: Option<bool>,
    /// Gaussian read noise, DN.
    #[arg(long, allow_negative_numbers = true)]
    pub read_noise_dn: Option<f64>,
    /// Full-well electrons at white for Poisson shot noise.
    #[arg(long, allow_negative_numbers = true)]
    pub full_well_e: Option<f64>,
    /// Relative r.m.s. frame-to-frame flicker.
    #[arg(long, allow_negative_numbers = true)]
    pub flicker: Option<f64>,
    /// Number of dust specks.
    #[arg(long)]
    pub dust: Option<usize>,
    /// Strength of the mirror reflection below the surface line.
    #[arg(long, allow_negative_numbers = true)]
    pub reflection: Option<f64>,
    /// Background brightness at the centre, fraction of white.
    #[arg(long, allow_negative_numbers = true)]
    pub background_level: Option<f64>,
    /// Light through the silhouette, fraction of the background.
    #[arg(long, allow_negative_numbers = true)]
    pub sphere_transmission: Option<f64>,

    // ---- a real camera (off unless given, drawn per drop with --preset real)
    /// Steel ball's light rim just inside the outline, fraction of the backlight [real: 0–0.2].
    #[arg(long, allow_negative_numbers = true)]
    pub rim: Option<f64>,
    /// Width over which the rim fades, px [real: 1–4; else 2].
    #[arg(long, allow_negative_numbers = true)]
    pub rim_width_px: Option<f64>,
    /// Faint bright halo just outside the outline, fraction of the backlight [real: 0–0.08].
    #[arg(long, allow_negative_numbers = true)]
    pub halo: Option<f64>,
    /// Width over which the halo fades, px [real: 1–4; else 2].
    #[arg(long, allow_negative_numbers = true)]
    pub halo_width_px: Option<f64>,
    /// Soft highlight near the sphere's middle (Gaussian, σ 0.2–0.35 R), fraction of the backlight [real: 0–0.15].
    #[arg(long, allow_negative_numbers = true)]
    pub highlight: Option<f64>,
    /// Glossy band top: bright strip just below the band's top edge, fraction of the backlight [real: 0–0.3].
    #[arg(long, allow_negative_numbers = true)]
    pub gloss: Option<f64>,
    /// Depth of the glossy strip, px [real: 1–4; else 2].
    #[arg(long, allow_negative_numbers = true)]
    pub gloss_width_px: Option<f64>,
    /// Pillar tops seen edge-on: the band's top rows times (1 + this) [real: −0.25…0.25].
    #[arg(long, allow_hyphen_values = true)]
    pub top_row: Option<f64>,
    /// Depth of the top row, px [real: 1–2; else 1].
    #[arg(long, allow_negative_numbers = true)]
    pub top_row_width_px: Option<f64>,
    /// Band top dipping under the sphere in contact, fraction of the sphere's local depth (≤ δ) [real: 0–0.3].
    #[arg(long, allow_negative_numbers = true)]
    pub dip: Option<f64>,
    /// Defocus: blur σ grows by this many px per row away from --focus-row-px (σ at the focus: --blur-px) [real: up to σ 2.5 px].
    #[arg(long, allow_negative_numbers = true)]
    pub defocus_px_per_row: Option<f64>,
    /// The row in best focus, px [real: anywhere in the frame; else 0].
    #[arg(long, allow_negative_numbers = true)]
    pub focus_row_px: Option<f64>,
    /// Barrel distortion: inward displacement of the image corners, px [real: 0–0.5].
    #[arg(long, allow_negative_numbers = true)]
    pub distortion_px: Option<f64>,
    /// Camera roll about the image centre, degrees [real: −0.5…0.5].
    #[arg(long, allow_hyphen_values = true)]
    pub roll_deg: Option<f64>,
    /// Column fixed-pattern noise: r.m.s. per-column gain and offset (fraction) [real: 0–0.015].
    #[arg(long, allow_negative_numbers = true)]
    pub column_noise: Option<f64>,
    /// Number of stuck-bright hot pixels [real: 0–50].
    #[arg(long)]
    pub hot_pixels: Option<usize>,
    /// Slow illumination drift over the movie, amplitude on each side (fraction) [real: 0–0.05].
    #[arg(long, allow_negative_numbers = true)]
    pub drift: Option<f64>,
    /// Frame files in flight left unwritten per drop [real: 1].
    #[arg(long)]
    pub missing_frames: Option<usize>,
    /// Start the movie as the sphere enters at the top edge (or at its release, when in view) [real: true].
    #[arg(long)]
    pub start_at_entry: Option<bool>,
    /// JPEG quality 1‥100 with --format jpeg [real: drawn per drop in 85‥98; else 95].
    #[arg(long)]
    pub jpeg_quality: Option<u8>,
    /// Saturated backlight: the dimmest background pixel reads 1 + this times white before the sensor clips [real-saturated: 0.1–0.5].
    #[arg(long, allow_negative_numbers = true)]
    pub saturation: Option<f64>,
    /// Central glint on the ball (Gaussian), fraction of the backlight; above 1 it clips at white [real-saturated: 0.5–3].
    #[arg(long, allow_negative_numbers = true)]
    pub glint: Option<f64>,
    /// σ of the glint, fraction of the sphere's radius [real-saturated: 0.08–0.2; else 0.15].
    #[arg(long, allow_negative_numbers = true)]
    pub glint_sigma: Option<f64>,
    /// Go on through a second contact when the flight to it takes at most this many frames; 0: never [real: 1500].
    #[arg(long)]
    pub second_bounce_frames: Option<usize>,

    /// Write mm_per_px into runs.csv (by default the pipeline must measure it).
    #[arg(long)]
    pub manifest_scale: bool,
    /// Also write runs_scaled.csv: runs.csv's rows with the true mm_per_px, as from a calibration target.
    #[arg(long)]
    pub scaled_manifest: bool,
}

impl RenderArgs {
    /// What the renderer takes.
    pub fn options(self) -> RenderOptions {
        RenderOptions {
            out: self.out,
            campaign: self.campaign,
            radii_mm: self.radii_mm,
            heights_cm: self.heights_cm,
            repeats: self.repeats,
            drops: self.drops,
            radius_mm: self.radius_mm,
            height_cm: self.height_cm,
            seed: self.seed,
            preset: self.preset,
            format: self.format,
            packing: self.packing,
            density_kg_m3: self.density_kg_m3,
            modulus_pa: self.modulus_pa,
            pillar_height_mm: self.pillar_height_mm,
            pillar_width_mm: self.pillar_width_mm,
            channel_width_mm: self.channel_width_mm,
            restitution: self.restitution,
            contact: self.contact,
            force_exponent: self.force_exponent,
            damping: self.damping,
            no_adhesion: self.no_adhesion,
            gravity_m_s2: self.gravity_m_s2,
            surface_name: self.surface_name,
            width_px: self.width_px,
            height_px: self.height_px,
            fps: self.fps,
            exposure_us: self.exposure_us,
            mm_per_px: self.mm_per_px,
            bit_depth: self.bit_depth,
            frames_before: self.frames_before,
            frames_after: self.frames_after,
            surface_row_px: self.surface_row_px,
            tilt: self.tilt,
            gradient: self.gradient,
            blur_px: self.blur_px,
            motion_blur: self.motion_blur,
            read_noise_dn: self.read_noise_dn,
            full_well_e: self.full_well_e,
            flicker: self.flicker,
            dust: self.dust,
            reflection: self.reflection,
            background_level: self.background_level,
            sphere_transmission: self.sphere_transmission,
            rim: self.rim,
            rim_width_px: self.rim_width_px,
            halo: self.halo,
            halo_width_px: self.halo_width_px,
            highlight: self.highlight,
            gloss: self.gloss,
            gloss_width_px: self.gloss_width_px,
            top_row: self.top_row,
            top_row_width_px: self.top_row_width_px,
            dip: self.dip,
            defocus_px_per_row: self.defocus_px_per_row,
            focus_row_px: self.focus_row_px,
            distortion_px: self.distortion_px,
            roll_deg: self.roll_deg,
            column_noise: self.column_noise,
            hot_pixels: self.hot_pixels,
            drift: self.drift,
            missing_frames: self.missing_frames,
            start_at_entry: self.start_at_entry,
            jpeg_quality: self.jpeg_quality,
            saturation: self.saturation,
            glint: self.glint,
            glint_sigma: self.glint_sigma,
            second_bounce_frames: self.second_bounce_frames,
            manifest_scale: self.manifest_scale,
            scaled_manifest: self.scaled_manifest,
        }
    }
}

impl ValueEnum for Preset {
    fn value_variants<'a>() -> &'a [Self] {
        &[
            Preset::Clean,
            Preset::Realistic,
            Preset::Harsh,
            Preset::Real,
            Preset::RealSaturated,
        ]
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        let (name, help) = match self {
            Preset::Clean => ("clean", "Ideal pictures: 12-bit, uniform light, exact silhouette at mid-exposure, no blur, no noise, no flicker, no dust"),
            Preset::Realistic => ("realistic", "A good experiment: 8-bit, gentle light gradient, optical blur σ 0.7 px, motion blur, read + shot noise, 1 % flicker, 5 dust specks"),
            Preset::Harsh => ("harsh", "A difficult one: strong gradient, blur σ 1.2 px, more noise and flicker, 12 specks, a faint mirror reflection under the surface line, a slight surface tilt"),
            Preset::Real => ("real", "Real backlit Phantom footage: `realistic`'s sensor plus every effect of a real camera, each drawn per drop (or per camera set-up) from a wide range: steel-ball rim 0–20 % over 1–4 px, halo 0–8 % over 1–4 px, highlight 0–15 %; glossy strip 0–30 % over 1–4 px; top row −25…+25 % over 1–2 px; dip 0–30 % of δ; blur σ 0.6–1.2 px at the focal row growing to at most 2.5 px; barrel distortion 0–0.5 px at the corners; roll −0.5…+0.5°; column pattern 0–1.5 %; 0–50 hot pixels; drift 0–5 %; the movie starts as the sphere enters, goes on through a second contact when the flight between takes at most 1 500 frames, and misses one frame file in flight. Scale ±8 % and surface row ±10 px per set-up (one set-up per radius and repeat)"),
            Preset::RealSaturated => ("real-saturated", "`real` with a saturated backlight and a glinting ball, as in many real rigs: the background clipped at white (the light 10–50 % above full scale, so the background has no noise), and a central glint of 0.5–3 times the backlight with σ 0.08–0.2 R, clipped at white"),
        };
        Some(PossibleValue::new(name).help(help))
    }
}

impl ValueEnum for ContactMode {
    fn value_variants<'a>() -> &'a [Self] {
        &[ContactMode::Model, ContactMode::Wide]
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        let (name, help) = match self {
            ContactMode::Model => ("model", "The measurement's model, `π E φ R δ² / h`, with linear damping solved for `--restitution`; or the law the options below set"),
            ContactMode::Wide => ("wide", "Per drop: n in 1.4–2.6, damping none / linear / Hunt–Crossley, adhesion or not, restitution 0.3–0.98; the options below fix any one"),
        };
        Some(PossibleValue::new(name).help(help))
    }
}

impl ValueEnum for DampingArg {
    fn value_variants<'a>() -> &'a [Self] {
        &[
            DampingArg::None,
            DampingArg::Linear,
            DampingArg::HuntCrossley,
        ]
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        let (name, help) = match self {
            DampingArg::None => ("none", "No damping: restitution 1"),
            DampingArg::Linear => ("linear", "Linear damping `c ḋ`"),
            DampingArg::HuntCrossley => ("hunt-crossley", "Hunt–Crossley damping `α K_n δ^n ḋ`"),
        };
        Some(PossibleValue::new(name).help(help))
    }
}

impl ValueEnum for FrameFormat {
    fn value_variants<'a>() -> &'a [Self] {
        &[
            FrameFormat::Tiff,
            FrameFormat::Png,
            FrameFormat::Jpeg,
            FrameFormat::Cine,
        ]
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        let (name, help) = match self {
            FrameFormat::Tiff => ("tiff", "Uncompressed baseline TIFF, one file per frame (as PCC's TIF8/TIF16)"),
            FrameFormat::Png => ("png", "PNG (fast deflate, adaptive filters: smaller than `Best` on noisy frames here and 100× faster), one file per frame"),
            FrameFormat::Jpeg => ("jpeg", "Baseline JPEG (8-bit only), one file per frame, as PCC's JPEG export; the quality is drawn per drop (85–98) unless `--jpeg-quality` fixes it"),
            FrameFormat::Cine => ("cine", "One raw Phantom `.cine` per drop (8-bit, or 16-bit containers holding 12-bit data), `<run>/<run>.cine`, with no XML side file"),
        };
        Some(PossibleValue::new(name).help(help))
    }
}

impl ValueEnum for CinePackingChoice {
    fn value_variants<'a>() -> &'a [Self] {
        &[
            CinePackingChoice::Unpacked,
            CinePackingChoice::P10,
            CinePackingChoice::P12l,
        ]
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        let (name, help) = match self {
            CinePackingChoice::Unpacked => ("unpacked", "One byte a sample for 8-bit frames, a 16-bit container for 12-bit ones"),
            CinePackingChoice::P10 => ("p10", "P10: the 12-bit values encoded to Vision Research's log-encoded 10-bit codes (the nearest code of its linearisation table), packed 4 samples in 5 bytes, as a Phantom saves \"10-bit\" cines"),
            CinePackingChoice::P12l => ("p12l", "P12L: the 12-bit values packed 2 samples in 3 bytes"),
        };
        Some(PossibleValue::new(name).help(help))
    }
}
