//! `truth.json`: the exact values behind one rendered drop. The struct is the
//! schema; keys appear in field order (serde), numbers as shortest
//! round-trip decimals, so the file is byte-stable.
//!
//! Geometry is self-consistent by construction: for every frame
//! `delta_mm = max(0, (z_px + radius_px − y_s(x_px)) · mm_per_px)` with
//! `y_s(x) = surface_row_px + surface_slope · x` (SPEC §1); `z_px` and
//! `x_px` are the sphere centre at mid-exposure `t_s = frame / fps`.

use serde::{Deserialize, Serialize};

use super::raster::Look;

/// The surface as rendered, in mm and Pa.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SurfaceTruth {
    pub modulus_pa: f64,
    pub pillar_height_mm: f64,
    pub pillar_width_mm: f64,
    pub channel_width_mm: f64,
    pub solid_fraction: f64,
}

/// A later contact within the rendered window.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BounceTruth {
    pub t_contact_s: f64,
    pub t_max_s: f64,
    pub t_rebound_s: f64,
    pub tau_c_s: f64,
    pub v_impact_m_s: f64,
    pub v_rebound_m_s: f64,
    pub restitution: f64,
    pub delta_max_mm: f64,
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
    pub z_px: f64,
    /// Penetration δ (0 out of contact), mm.
    pub delta_mm: f64,
    /// δ > 0 at mid-exposure.
    pub in_contact: bool,
}

/// Everything known exactly about one rendered drop.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    pub run: String,
    pub seed: u64,
    /// `clean`, `realistic` or `harsh` (the look's starting point; see `look`).
    pub preset: String,
    pub sphere_radius_mm: f64,
    pub sphere_density_kg_m3: f64,
    /// Fall height of the sphere's lowest point to the surface; v = √(2gH).
    pub drop_height_cm: f64,
    pub surface: SurfaceTruth,
    /// Restitution asked for (1 = no damping).
    pub restitution_requested: f64,
    pub fps: f64,
    pub exposure_s: f64,
    pub width_px: usize,
    pub height_px: usize,
    /// 8 or 12 (12-bit data in 16-bit files).
    pub bit_depth: u8,
    pub mm_per_px: f64,
    pub radius_px: f64,
    /// Undeformed surface row at column 0.
    pub surface_row_px: f64,
    /// Surface tilt, rows per column.
    pub surface_slope: f64,
    /// The sphere centre's column (it falls straight down the image).
    pub impact_column_px: f64,
    pub t_contact_s: f64,
    pub t_rebound_s: f64,
    pub tau_c_s: f64,
    pub t_max_s: f64,
    pub v_impact_m_s: f64,
    pub v_rebound_m_s: f64,
    pub restitution: f64,
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
    /// RK4 step of the contact integration, s.
    pub integration_step_s: f64,
    /// Camera image number of the first frame (the XML's FirstImageNo).
    pub first_image_no: i64,
    /// Every effect as rendered.
    pub look: Look,
    pub frames: Vec<FrameTruth>,
}
