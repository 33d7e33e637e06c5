//! `truth.json`: the exact values behind one rendered drop. The struct is the
//! schema; keys appear in field order (serde), numbers as shortest
//! round-trip decimals, so the file is byte-stable.
//!
//! Geometry is self-consistent by construction: for every frame
//! `delta_mm = max(0, (z_px + radius_px − y_s(x_px)) · mm_per_px)` with
//! `y_s(x) = surface_row_px + surface_slope · x` (SPEC §1); `z_px` and
//! `x_px` are the sphere centre at mid-exposure `t_s = frame / fps`.
//!
//! # Under a real camera's optics (`camera` present)
//!
//! Every geometric field — `x_px`, `z_px`, `radius_px`, `impact_column_px`,
//! `surface_row_px`, `surface_slope`, `mm_per_px` — is in the **scene
//! frame**: the undistorted, unrolled image, in which the surface line is
//! `y_s(x)`, gravity points along +z (down the columns) and the scale is
//! `mm_per_px` everywhere. The scale at the image centre of the recorded
//! picture is the same `mm_per_px` (distortion leaves the centre's scale
//! unchanged). Physical truths (`v_impact_m_s`, `delta_max_mm`, `a_max_mm`,
//! `tau_c_s`, `t_contact_s`, …) do not depend on the optics.
//!
//! A scene point `(x, z)` appears in the recorded image at `(x_d, z_d)`:
//! with `c = camera.centre_px = ((W − 1)/2, (H − 1)/2)` (pixel-centre
//! convention) and `θ = camera.roll_deg`, first the roll
//! `(x', z') − c = Rot(θ)·((x, z) − c)`, `Rot(θ) = [[cos θ, −sin θ], [sin θ, cos θ]]`
//! (θ > 0: the surface line's row grows to the right by tan θ per column, and
//! the sphere falls along `(−sin θ, cos θ)` in (column, row)); then the
//! barrel distortion `(x_d, z_d) − c = ((x', z') − c)·(1 + k1·r²)`,
//! `r = |(x', z') − c|`, `k1 = camera.k1_per_px2 < 0`; the corner pixel moves
//! inward by `camera.corner_displacement_px = |k1|·r_corner³`. Each frame's
//! `image_x_px, image_z_px` is its sphere centre mapped this way.

use serde::{Deserialize, Serialize};

use super::raster::Look;

/// The surface as rendered, in mm and Pa.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SurfaceTruth {
    /// Young's modulus E of the pillars' material, Pa.
    pub modulus_pa: f64,
    /// Pillar height h, mm.
    pub pillar_height_mm: f64,
    /// Pillar width b, mm.
    pub pillar_width_mm: f64,
    /// Width c of the channels between pillars, mm.
    pub channel_width_mm: f64,
    /// Solid fraction φ = b / (b + c) of the surface, dimensionless.
    pub solid_fraction: f64,
}

/// A later contact within the rendered window.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BounceTruth {
    /// When this contact starts (δ crosses 0 going down), s after the trigger.
    pub t_contact_s: f64,
    /// When δ reaches its maximum in this contact, s after the trigger.
    pub t_max_s: f64,
    /// When δ returns to 0 at the end of this contact, s after the trigger.
    pub t_rebound_s: f64,
    /// Contact time τc = `t_rebound_s − t_contact_s`, s.
    pub tau_c_s: f64,
    /// Speed at the start of this contact, m/s.
    pub v_impact_m_s: f64,
    /// Speed when this contact ends, m/s.
    pub v_rebound_m_s: f64,
    /// Restitution e = `v_rebound_m_s / v_impact_m_s` of this contact.
    pub restitution: f64,
    /// Maximum penetration δmax of this contact, mm.
    pub delta_max_mm: f64,
    /// Without adhesion: when the force reached 0 and the sphere left the
    /// deformed surface (δ still > 0); absent when it stayed until δ = 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub t_force_zero_s: Option<f64>,
}

/// The contact law of a drop rendered with a contact option (`--contact
/// wide`, `--force-exponent`, `--damping`, `--no-adhesion`); absent from
/// `truth.json` under the model's law (n = 2, `K = π E φ R / h`, linear
/// damping `damping_n_s_m`, a force that may pull). Key names follow the
/// independent drops' `truth.json`.
///
/// The force is `F = K_n δ^n (1 + α ḋ) + c ḋ` (ḋ > 0 going in). With
/// adhesion it may pull and the contact lasts until δ = 0; without, it is
/// clamped at F ≥ 0 and the sphere leaves the deformed surface at
/// `t_force_zero_s`, δ = `delta_force_zero_mm` > 0, then flies freely. The
/// contact times stay those of δ: `t_contact_s` where δ crosses 0 going
/// down, `t_rebound_s` where δ returns to 0 (the sphere's bottom back on the
/// undeformed line), `tau_c_s` between them, `v_rebound_m_s` the speed there
/// and `restitution` = `v_rebound_m_s / v_impact_m_s`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ContactTruth {
    /// `wide` (drawn per drop) or `set` (by the options).
    pub contact_physics: String,
    /// The law in words.
    pub contact_law: String,
    /// Elastic exponent n.
    pub force_n: f64,
    /// K_n = `K_N_per_m2` · δ_ref^{2 − n}, N/m^n.
    #[serde(rename = "K_n_N_per_m_n")]
    pub stiffness_n_per_m_n: f64,
    /// The model's K = π E φ R / h, N/m².
    #[serde(rename = "K_N_per_m2")]
    pub model_stiffness_n_per_m2: f64,
    /// The model's δmax for this drop (Eq. (4) of Maruoka 2019), mm.
    pub delta_ref_mm: f64,
    /// `none`, `linear` or `hunt_crossley`.
    pub damping_model: String,
    /// Linear damping c, N·s/m (with `linear`).
    #[serde(rename = "damping_c_N_s_per_m")]
    pub damping_c_n_s_per_m: Option<f64>,
    /// Hunt–Crossley α, s/m (with `hunt_crossley`).
    pub hunt_crossley_alpha_s_per_m: Option<f64>,
    /// The force may pull (true) or is clamped at F ≥ 0.
    pub adhesion: bool,
    /// When the force reached 0 on the way out (no adhesion), s; null when
    /// the sphere stayed on the surface until δ = 0.
    pub t_force_zero_s: Option<f64>,
    /// δ at that instant, mm.
    pub delta_force_zero_mm: Option<f64>,
}

/// The sphere at one frame's mid-exposure.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameTruth {
    /// Camera image number (negative before the trigger).
    pub frame: i64,
    /// Mid-exposure time relative to the trigger, `frame / fps`.
    pub t_s: f64,
    /// Sphere centre column and row, px.
    pub x_px: f64,
    /// Sphere centre row (its column is `x_px`), px.
    pub z_px: f64,
    /// Penetration δ (0 out of contact), mm.
    pub delta_mm: f64,
    /// δ > 0 at mid-exposure.
    pub in_contact: bool,
    /// The sphere centre in the recorded image (after roll and distortion),
    /// when a camera model is on.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image_x_px: Option<f64>,
    /// Row of the sphere centre in the recorded image; pairs with `image_x_px`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image_z_px: Option<f64>,
}

/// Everything known exactly about one rendered drop.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    /// Run name, as in the manifest and the frames' folder.
    pub run: String,
    /// Seed of the random draws that made this drop.
    pub seed: u64,
    /// `clean`, `realistic` or `harsh` (the look's starting point; see `look`).
    pub preset: String,
    /// Sphere radius R, mm.
    pub sphere_radius_mm: f64,
    /// Sphere density, kg/m³.
    pub sphere_density_kg_m3: f64,
    /// Fall height of the sphere's lowest point to the surface; v = √(2gH).
    pub drop_height_cm: f64,
    /// The surface as rendered.
    pub surface: SurfaceTruth,
    /// Restitution asked for (1 = no damping).
    pub restitution_requested: f64,
    /// Frame rate, frames per second.
    pub fps: f64,
    /// Exposure time of each frame, s.
    pub exposure_s: f64,
    /// Image width, px.
    pub width_px: usize,
    /// Image height, px.
    pub height_px: usize,
    /// 8 or 12 (12-bit data in 16-bit files).
    pub bit_depth: u8,
    /// Scale of the scene frame, mm per px.
    pub mm_per_px: f64,
    /// The sphere's radius in the image, `sphere_radius_mm / mm_per_px`, px.
    pub radius_px: f64,
    /// Undeformed surface row at column 0.
    pub surface_row_px: f64,
    /// Surface tilt, rows per column.
    pub surface_slope: f64,
    /// The sphere centre's column (it falls straight down the image).
    pub impact_column_px: f64,
    /// When the first contact starts (δ crosses 0 going down), s after the trigger.
    pub t_contact_s: f64,
    /// When δ returns to 0 at the end of the first contact, s after the trigger.
    pub t_rebound_s: f64,
    /// Contact time τc = `t_rebound_s − t_contact_s` of the first contact, s.
    pub tau_c_s: f64,
    /// When δ reaches its maximum in the first contact, s after the trigger.
    pub t_max_s: f64,
    /// Speed at impact, m/s.
    pub v_impact_m_s: f64,
    /// Speed when the first contact ends, m/s.
    pub v_rebound_m_s: f64,
    /// Restitution e = `v_rebound_m_s / v_impact_m_s` of the first contact.
    pub restitution: f64,
    /// Maximum penetration δmax of the first contact, mm.
    pub delta_max_mm: f64,
    /// Geometric contact radius at δmax: √(R² − (R − δmax)²).
    pub a_max_mm: f64,
    /// The next contact, when it starts before the last frame's exposure ends.
    pub second_bounce: Option<BounceTruth>,
    /// Start of a later contact that damping holds on the surface (the
    /// sphere then rests there), when it starts within the window; else null.
    pub resting_contact_s: Option<f64>,
    /// g used in the simulation, m/s².
    pub gravity_m_s2: f64,
    /// Linear damping c solved for `restitution_requested`, N·s/m.
    pub damping_n_s_m: f64,
    /// The contact law, when it is not the model's (keys flattened here).
    #[serde(flatten, default, skip_serializing_if = "Option::is_none")]
    pub contact: Option<ContactTruth>,
    /// RK4 step of the contact integration, s.
    pub integration_step_s: f64,
    /// Camera image number of the first frame (the XML's FirstImageNo).
    pub first_image_no: i64,
    /// Every effect as rendered.
    pub look: Look,
    /// A real camera's optics and sensor as realised for this drop (absent
    /// when every one of those effects is off, as in `clean`, `realistic`
    /// and `harsh`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<CameraTruth>,
    /// Quality (1‥100) of JPEG frame files; absent for other formats.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub jpeg_quality: Option<u8>,
    /// The sphere at every frame's mid-exposure, in image order.
    pub frames: Vec<FrameTruth>,
}

/// The optics and sensor of a real camera, as realised for one drop. The
/// strengths are fractions of the local backlight `B` unless a unit says
/// otherwise; a shape `g(u; w) = ½(1 + cos(π u / w))` for `0 ≤ u < w` (else
/// 0) is 1 at `u = 0` and fades smoothly to 0 at `u = w`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraTruth {
    /// The camera set-up this drop was filmed with: runs sharing it share the
    /// scale, surface position, distortion, roll, focus, column pattern and
    /// hot pixels.
    pub setup: String,
    /// Centre of distortion and roll, `((W − 1)/2, (H − 1)/2)`, px.
    pub centre_px: [f64; 2],
    /// Radial distortion coefficient (px⁻², ≤ 0: barrel), applied after the roll.
    pub k1_per_px2: f64,
    /// Inward displacement of the image corners, `|k1|·r_corner³`, px.
    pub corner_displacement_px: f64,
    /// Camera roll θ, degrees (see the module doc for the sign).
    pub roll_deg: f64,
    /// Optical blur σ(row) = `blur_sigma0_px + defocus_px_per_row·|row − focus_row_px|`
    /// (Gaussian, in the recorded image's rows).
    pub blur_sigma0_px: f64,
    /// Growth of σ per row away from `focus_row_px`, px per row.
    pub defocus_px_per_row: f64,
    /// The row in best focus, px.
    pub focus_row_px: f64,
    /// σ at the best and worst row of the frame, px.
    pub blur_sigma_min_px: f64,
    /// σ at the worst row of the frame, px (`blur_sigma_min_px` is the best).
    pub blur_sigma_max_px: f64,
    /// Light rim inside the outline: `rim · g(R − ρ; rim_width_px)` at distance ρ from the centre.
    pub rim: f64,
    /// Width of the rim's fade inward from the outline, px.
    pub rim_width_px: f64,
    /// Halo outside the outline: `halo · g(ρ − R; halo_width_px)`.
    pub halo: f64,
    /// Width of the halo's fade outward from the outline, px.
    pub halo_width_px: f64,
    /// Highlight on the sphere: `highlight · exp(−|p − c − offset|² / (2 σ²))`,
    /// `c` the centre averaged over the exposure.
    pub highlight: f64,
    /// Width σ of the highlight's Gaussian, px.
    pub highlight_sigma_px: f64,
    /// Offset of the highlight from the centre (column, row), px.
    pub highlight_offset_px: [f64; 2],
    /// Glossy band top: light `gloss` added in the strip of `gloss_width_px`
    /// just below the band's top edge, where the sphere's mirror image (in the
    /// surface line) does not cover it.
    pub gloss: f64,
    /// Height of the gloss strip below the band's top edge, px.
    pub gloss_width_px: f64,
    /// Pillar tops seen edge-on: the band's top `top_row_width_px` rows have
    /// `(1 + top_row)` times the band's transmission.
    pub top_row: f64,
    /// Height of the band's top strip whose transmission is scaled by `1 + top_row`, px.
    pub top_row_width_px: f64,
    /// Pillars dipping under the sphere: during contact the band's top edge at
    /// column x lies `dip · max(0, sphere bottom at x − y_s(x))` below `y_s(x)`
    /// (at most `dip · δ`, at the sphere's column, zero beyond the contact width).
    pub dip: f64,
    /// Column fixed pattern: per-column gain `1 + column_gain_rms·n₁` and
    /// offset `column_offset_rms·n₂` (fraction of white), `n` standard normal.
    pub column_gain_rms: f64,
    /// Column offset's standard deviation, as a fraction of white (see `column_gain_rms`).
    pub column_offset_rms: f64,
    /// Stuck-bright pixels `[row, column]` and the value they read (DN).
    pub hot_pixels: Vec<[usize; 2]>,
    /// Value the hot pixels read, DN.
    pub hot_pixel_dn: u16,
    /// Illumination drift: gain `1 + (1 − u)·drift_left·sin(φ_l + π·cycles·s)
    /// + u·drift_right·sin(φ_r + π·cycles·s)` with `u = column/(W − 1)` and
    /// `s ∈ [0, 1]` the time through the movie.
    pub drift_left: f64,
    /// Drift amplitude at the right edge (see `drift_left`).
    pub drift_right: f64,
    /// Phase φ_l of the left edge's drift, radians.
    pub drift_phase_left: f64,
    /// Phase φ_r of the right edge's drift, radians.
    pub drift_phase_right: f64,
    /// Number of half-periods of drift over the movie (`cycles`).
    pub drift_cycles: f64,
    /// Saturated backlight: the light is multiplied by `saturation_gain =
    /// (1 + saturation) / B_min` (`B_min` the dimmest background pixel of
    /// the look) before the sensor, which clips at white: the background
    /// reads white with no noise, and an edge's half level lies inside the
    /// true outline. 0 and 1: off.
    pub saturation: f64,
    /// The light's multiplier before the sensor clips, `(1 + saturation) / B_min` (1: off).
    pub saturation_gain: f64,
    /// Central glint (the backlight's specular image on the ball):
    /// `glint · exp(−|p − c_k − offset|² / (2 σ²))` inside the disk for each
    /// sphere centre `c_k` over the exposure (so it smears with the motion),
    /// a fraction of the backlight that may exceed 1 (clipped at white).
    pub glint: f64,
    /// Width σ of the glint's Gaussian, px.
    pub glint_sigma_px: f64,
    /// Offset of the glint from the centre (column, row), px.
    pub glint_offset_px: [f64; 2],
    /// Image numbers whose frame file was not written.
    pub missing_frames: Vec<i64>,
    /// The movie starts as the sphere enters at the top edge (or at its
    /// release when that is in view), not `frames_before` images before contact.
    pub start_at_entry: bool,
    /// The sphere's release is in view (it hangs still until `t_release_s`).
    pub release_in_view: bool,
    /// Release instant, s after the trigger.
    pub t_release_s: f64,
}
