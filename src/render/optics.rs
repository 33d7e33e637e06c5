//! A real camera's optics and sensor: which effects are on, how strong each
//! is for one drop (drawn from the seed, or fixed by an option), and the
//! geometric mapping from the scene to the recorded image (roll, then barrel
//! distortion). The realised values are the `camera` section of
//! `truth.json` ([`CameraTruth`], whose doc states every formula).
//!
//! Camera-level values (scale, surface position, distortion, roll, focus,
//! column pattern, hot pixels) are drawn once per camera *set-up* from
//! `(seed, setup)`; the look of the sphere and the band, the drift and the
//! missing frame are drawn per drop from `(seed, run)`. Every value is drawn
//! whether or not an option fixes it, so fixing one effect leaves the others'
//! draws unchanged.

use rand::Rng;
use rand_distr::StandardNormal;

use super::raster::Look;
use super::rng_for;
use super::truth::CameraTruth;

/// How one effect's strength is chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Strength {
    /// The effect is off (strength 0).
    Off,
    /// The same value for every drop (an explicit option).
    Fixed(f64),
    /// Uniform in `[lo, hi]`, drawn per drop (or per set-up).
    Drawn(f64, f64),
}

impl Strength {
    /// The value for a uniform draw `u ∈ [0, 1)`.
    pub fn realise(self, u: f64) -> f64 {
        match self {
            Strength::Off => 0.0,
            Strength::Fixed(v) => v,
            Strength::Drawn(lo, hi) => lo + (hi - lo) * u,
        }
    }

    fn is_on(self) -> bool {
        match self {
            Strength::Off => false,
            Strength::Fixed(v) => v != 0.0,
            Strength::Drawn(lo, hi) => lo != 0.0 || hi != 0.0,
        }
    }
}

/// Every real-camera effect of a render, before the per-drop draws.
#[derive(Debug, Clone, PartialEq)]
pub struct OpticsSpec {
    /// Light rim inside the outline, fraction of the backlight.
    pub rim: Strength,
    /// Width of the rim's fade, px.
    pub rim_width_px: Strength,
    /// Halo outside the outline, fraction of the backlight.
    pub halo: Strength,
    /// Width of the halo's fade, px.
    pub halo_width_px: Strength,
    /// Highlight on the sphere, fraction of the backlight (its size and place are drawn per drop).
    pub highlight: Strength,
    /// Light added in a strip below the glossy band top, fraction of the backlight.
    pub gloss: Strength,
    /// Height of the gloss strip, px.
    pub gloss_width_px: Strength,
    /// Extra transmission of the band's top rows (pillar tops seen edge-on), fraction (may be negative).
    pub top_row: Strength,
    /// Height of those top rows, px.
    pub top_row_width_px: Strength,
    /// How far the band's top edge dips under the sphere, as a fraction of the sphere bottom's depth below the line.
    pub dip: Strength,
    /// σ at the focal row, px.
    pub blur_sigma0_px: Strength,
    /// Growth of σ per row away from the focal row, px/row; `Drawn(0, 1)`
    /// means "up to the largest that keeps σ ≤ [`MAX_SIGMA_PX`]".
    pub defocus_px_per_row: Strength,
    /// The row in best focus, px; `Drawn(lo, hi)` draws it as a fraction of the height.
    pub focus_row_px: Strength,
    /// Barrel distortion: the inward displacement of the image corners, px.
    pub corner_displacement_px: Strength,
    /// Camera roll θ, degrees.
    pub roll_deg: Strength,
    /// Column fixed pattern: the rms of the per-column gain (and of the offset, as a fraction of the background level).
    pub column_noise: Strength,
    /// Number of stuck-bright hot pixels (the draw's integer part).
    pub hot_pixels: Strength,
    /// Illumination drift's amplitude on each side of the image, fraction.
    pub drift: Strength,
    /// Saturated backlight: the dimmest background pixel reads `1 + this`
    /// times white before the sensor clips (0: the light as the look says).
    pub saturation: Strength,
    /// Central glint on the ball, fraction of the backlight (may exceed 1:
    /// the sensor clips it).
    pub glint: Strength,
    /// σ of the glint, fraction of the sphere's radius.
    pub glint_sigma: Strength,
    /// Frame files in flight left unwritten per drop.
    pub missing_frames: usize,
    /// Start the movie as the sphere enters at the top edge (or at its release, when in view).
    pub start_at_entry: bool,
    /// Longest flight (frames) between the first and second contact for
    /// which the movie goes on through the second contact; 0: never.
    pub second_bounce_frames: usize,
    /// Per set-up, the scale is the default times `1 ± scale_spread`.
    pub scale_spread: f64,
    /// Per set-up, the surface row moves by up to ± this many px.
    pub surface_spread_px: f64,
}

/// The largest blur σ the `real` preset draws, px.
pub const MAX_SIGMA_PX: f64 = 2.5;

impl OpticsSpec {
    /// Everything off: the renderer's plain path.
    pub fn off() -> Self {
        OpticsSpec {
            rim: Strength::Off,
            rim_width_px: Strength::Fixed(2.0),
            halo: Strength::Off,
            halo_width_px: Strength::Fixed(2.0),
            highlight: Strength::Off,
            gloss: Strength::Off,
            gloss_width_px: Strength::Fixed(2.0),
            top_row: Strength::Off,
            top_row_width_px: Strength::Fixed(1.0),
            dip: Strength::Off,
            blur_sigma0_px: Strength::Off,
            defocus_px_per_row: Strength::Off,
            focus_row_px: Strength::Off,
            corner_displacement_px: Strength::Off,
            roll_deg: Strength::Off,
            column_noise: Strength::Off,
            hot_pixels: Strength::Off,
            drift: Strength::Off,
            saturation: Strength::Off,
            glint: Strength::Off,
            glint_sigma: Strength::Fixed(0.15),
            missing_frames: 0,
            start_at_entry: false,
            second_bounce_frames: 0,
            scale_spread: 0.0,
            surface_spread_px: 0.0,
        }
    }

    /// The `real` preset's ranges (see `--preset real` in the help).
    pub fn real() -> Self {
        OpticsSpec {
            rim: Strength::Drawn(0.0, 0.20),
            rim_width_px: Strength::Drawn(1.0, 4.0),
            halo: Strength::Drawn(0.0, 0.08),
            halo_width_px: Strength::Drawn(1.0, 4.0),
            highlight: Strength::Drawn(0.0, 0.15),
            gloss: Strength::Drawn(0.0, 0.30),
            gloss_width_px: Strength::Drawn(1.0, 4.0),
            top_row: Strength::Drawn(-0.25, 0.25),
            top_row_width_px: Strength::Drawn(1.0, 2.0),
            dip: Strength::Drawn(0.0, 0.30),
            blur_sigma0_px: Strength::Drawn(0.6, 1.2),
            defocus_px_per_row: Strength::Drawn(0.0, 1.0),
            focus_row_px: Strength::Drawn(0.0, 1.0),
            corner_displacement_px: Strength::Drawn(0.0, 0.5),
            roll_deg: Strength::Drawn(-0.5, 0.5),
            column_noise: Strength::Drawn(0.0, 0.015),
            hot_pixels: Strength::Drawn(0.0, 51.0),
            drift: Strength::Drawn(0.0, 0.05),
            saturation: Strength::Off,
            glint: Strength::Off,
            glint_sigma: Strength::Fixed(0.15),
            missing_frames: 1,
            start_at_entry: true,
            second_bounce_frames: 1500,
            scale_spread: 0.08,
            surface_spread_px: 10.0,
        }
    }

    /// The `real-saturated` preset's ranges: `real`'s, plus a backlight
    /// saturated by 10–50 % (the background clipped at white, as in many
    /// real rigs) and a central glint of 0.5–3 times the backlight with σ
    /// 0.08–0.2 R (clipped where it exceeds white).
    pub fn real_saturated() -> Self {
        OpticsSpec {
            saturation: Strength::Drawn(0.1, 0.5),
            glint: Strength::Drawn(0.5, 3.0),
            glint_sigma: Strength::Drawn(0.08, 0.2),
            ..Self::real()
        }
    }

    /// Whether any effect is on (else the plain renderer draws the drop,
    /// byte for byte as without these effects).
    pub fn active(&self) -> bool {
        [
            self.rim,
            self.halo,
            self.highlight,
            self.gloss,
            self.top_row,
            self.dip,
            self.defocus_px_per_row,
            self.corner_displacement_px,
            self.roll_deg,
            self.column_noise,
            self.hot_pixels,
            self.drift,
            self.saturation,
            self.glint,
        ]
        .iter()
        .any(|s| s.is_on())
            || self.missing_frames > 0
            || self.start_at_entry
            || self.second_bounce_frames > 0
            || self.scale_spread > 0.0
            || self.surface_spread_px > 0.0
    }
}

/// Roll about the image centre, then radial (barrel) distortion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Geometry {
    /// Column of the centre of distortion and roll, `(W − 1)/2`, px.
    pub cx: f64,
    /// Row of the centre of distortion and roll, `(H − 1)/2`, px.
    pub cz: f64,
    /// Radial distortion coefficient k1 (≤ 0: barrel), 1/px².
    pub k1: f64,
    cos: f64,
    sin: f64,
}

impl Geometry {
    /// The geometry of a `width_px` × `height_px` image with distortion `k1` (1/px²) and roll `roll_deg` (degrees), about the image centre.
    pub fn new(width_px: usize, height_px: usize, k1: f64, roll_deg: f64) -> Self {
        let th = roll_deg.to_radians();
        Geometry {
            cx: 0.5 * (width_px as f64 - 1.0),
            cz: 0.5 * (height_px as f64 - 1.0),
            k1,
            cos: th.cos(),
            sin: th.sin(),
        }
    }

    /// The distance from the centre to the corner pixels' centres, px.
    pub fn corner_radius_px(&self) -> f64 {
        self.cx.hypot(self.cz)
    }

    /// Scene (undistorted, unrolled) → recorded image.
    pub fn forward(&self, x: f64, z: f64) -> (f64, f64) {
        let (u, v) = (x - self.cx, z - self.cz);
        let (u, v) = (self.cos * u - self.sin * v, self.sin * u + self.cos * v);
        let f = 1.0 + self.k1 * (u * u + v * v);
        (self.cx + u * f, self.cz + v * f)
    }

    /// Recorded image → scene: the distortion inverted by Newton's method on
    /// `r_d = r_u (1 + k1 r_u²)` (to 1e-12 px), then the roll undone.
    pub fn inverse(&self, xd: f64, zd: f64) -> (f64, f64) {
        let (ud, vd) = (xd - self.cx, zd - self.cz);
        let rd = ud.hypot(vd);
        let scale = if self.k1 == 0.0 || rd == 0.0 {
            1.0
        } else {
            let mut ru = rd;
            for _ in 0..20 {
                let f = ru * (1.0 + self.k1 * ru * ru) - rd;
                let step = f / (1.0 + 3.0 * self.k1 * ru * ru);
                ru -= step;
                if step.abs() < 1e-13 {
                    break;
                }
            }
            ru / rd
        };
        let (u, v) = (ud * scale, vd * scale);
        (
            self.cx + self.cos * u + self.sin * v,
            self.cz - self.sin * u + self.cos * v,
        )
    }
}

/// The realised camera of one drop, with what the raster needs beyond truth.
#[derive(Debug, Clone, PartialEq)]
pub struct Optics {
    /// The camera's values, as written into `truth.json`.
    pub truth: CameraTruth,
    /// Its roll and distortion.
    pub geometry: Geometry,
    /// Per-column gain and offset (fraction of white).
    pub column_gain: Vec<f64>,
    /// Per-column offset, fraction of white (`column_gain` is the gain).
    pub column_offset: Vec<f64>,
}

/// What a set-up fixes beside the optics: scale factor and surface shift.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SetupDraw {
    /// Multiplies the default scale.
    pub scale_factor: f64,
    /// Added to the default surface row, px.
    pub surface_shift_px: f64,
}

/// The scale and surface position of a camera set-up, from `(seed, setup)`.
pub fn draw_setup(spec: &OpticsSpec, seed: u64, setup: &str) -> SetupDraw {
    let mut s = rng_for(seed, setup, "placement", 0);
    let mut u = || -> f64 { s.gen_range(0.0..1.0) };
    SetupDraw {
        scale_factor: 1.0 + spec.scale_spread * (2.0 * u() - 1.0),
        surface_shift_px: spec.surface_spread_px * (2.0 * u() - 1.0),
    }
}

/// The frame a camera is drawn for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameGeometry {
    /// Image width, px.
    pub width_px: usize,
    /// Image height, px.
    pub height_px: usize,
    /// The sphere's radius in the image, px.
    pub radius_px: f64,
}

/// Draw the camera of one drop: set-up values from `(seed, setup)`, drop
/// values from `(seed, run)`. `missing_frames` and the release fields are
/// filled by the caller once the movie's frames are known.
pub fn draw(
    spec: &OpticsSpec,
    seed: u64,
    setup: &str,
    run: &str,
    frame: FrameGeometry,
    look: &Look,
) -> Optics {
    let FrameGeometry {
        width_px,
        height_px,
        radius_px,
    } = frame;
    let background_level = look.background_level;
    let white_dn = look.white_dn();
    let mut s = rng_for(seed, setup, "setup", 0);
    let mut u = || -> f64 { s.gen_range(0.0..1.0) };
    let geometry0 = Geometry::new(width_px, height_px, 0.0, 0.0);
    let r_corner = geometry0.corner_radius_px();
    let corner = spec.corner_displacement_px.realise(u()).abs();
    let k1 = -corner / r_corner.powi(3);
    let roll_deg = spec.roll_deg.realise(u());
    let sigma0 = spec.blur_sigma0_px.realise(u());
    let focus_row = match spec.focus_row_px {
        Strength::Drawn(lo, hi) => (lo + (hi - lo) * u()) * (height_px as f64 - 1.0),
        other => other.realise(u()),
    };
    let far = focus_row.max(height_px as f64 - 1.0 - focus_row);
    let gradient = match spec.defocus_px_per_row {
        Strength::Drawn(lo, hi) => {
            (lo + (hi - lo) * u()) * ((MAX_SIGMA_PX - sigma0).max(0.0) / far.max(1.0))
        }
        other => other.realise(u()),
    };
    let column_rms = spec.column_noise.realise(u());
    let hot_count = (spec.hot_pixels.realise(u()).floor() as usize).min(width_px * height_px);
    let (column_gain, column_offset, hot_pixels) = sensor_pattern(
        seed,
        setup,
        [height_px, width_px],
        column_rms,
        background_level,
        hot_count,
    );
    let hot_pixel_dn = (0.92 * f64::from(white_dn)).round() as u16;

    let mut d = rng_for(seed, run, "optics", 0);
    let mut v = || -> f64 { d.gen_range(0.0..1.0) };
    let rim = spec.rim.realise(v());
    let rim_width_px = spec.rim_width_px.realise(v());
    let halo = spec.halo.realise(v());
    let halo_width_px = spec.halo_width_px.realise(v());
    let highlight = spec.highlight.realise(v());
    let highlight_sigma_px = (0.2 + 0.15 * v()) * radius_px;
    let highlight_offset_px = [0.3 * (2.0 * v() - 1.0) * radius_px, -0.35 * v() * radius_px];
    let gloss = spec.gloss.realise(v());
    let gloss_width_px = spec.gloss_width_px.realise(v());
    let top_row = spec.top_row.realise(v());
    let top_row_width_px = spec.top_row_width_px.realise(v());
    let dip = spec.dip.realise(v());
    let drift_left = spec.drift.realise(v());
    let drift_right = spec.drift.realise(v());
    let drift_phase_left = std::f64::consts::TAU * v();
    let drift_phase_right = std::f64::consts::TAU * v();
    let drift_cycles = 0.5 + v();
    let (saturation, glint, glint_sigma_px, glint_offset_px) = glare(spec, seed, run, radius_px);
    let sigma_at = |row: f64| sigma0 + gradient * (row - focus_row).abs();
    let truth = CameraTruth {
        setup: setup.to_string(),
        centre_px: [geometry0.cx, geometry0.cz],
        k1_per_px2: k1,
        corner_displacement_px: corner,
        roll_deg,
        blur_sigma0_px: sigma0,
        defocus_px_per_row: gradient,
        focus_row_px: focus_row,
        blur_sigma_min_px: sigma_at(focus_row.clamp(0.0, height_px as f64 - 1.0)),
        blur_sigma_max_px: sigma_at(0.0).max(sigma_at(height_px as f64 - 1.0)),
        rim,
        rim_width_px,
        halo,
        halo_width_px,
        highlight,
        highlight_sigma_px,
        highlight_offset_px,
        gloss,
        gloss_width_px,
        top_row,
        top_row_width_px,
        dip,
        column_gain_rms: column_rms,
        column_offset_rms: column_rms * background_level,
        hot_pixels,
        hot_pixel_dn,
        drift_left,
        drift_right,
        drift_phase_left,
        drift_phase_right,
        drift_cycles,
        saturation,
        saturation_gain: 1.0,
        glint,
        glint_sigma_px,
        glint_offset_px,
        missing_frames: Vec::new(),
        start_at_entry: spec.start_at_entry,
        release_in_view: false,
        t_release_s: 0.0,
    };
    Optics {
        geometry: Geometry::new(width_px, height_px, k1, roll_deg),
        truth,
        column_gain,
        column_offset,
    }
}

/// The saturated backlight and the glint of run `run`, from their own
/// stream, so that the other draws are those of a camera without them:
/// `(saturation, glint, glint_sigma_px, glint_offset_px)`.
fn glare(spec: &OpticsSpec, seed: u64, run: &str, radius_px: f64) -> (f64, f64, f64, [f64; 2]) {
    let mut gl = rng_for(seed, run, "glare", 0);
    let mut w = || -> f64 { gl.gen_range(0.0..1.0) };
    let saturation = spec.saturation.realise(w());
    let glint = spec.glint.realise(w());
    let glint_sigma_px = spec.glint_sigma.realise(w()) * radius_px;
    let glint_offset_px = [
        0.05 * (2.0 * w() - 1.0) * radius_px,
        0.05 * (2.0 * w() - 1.0) * radius_px,
    ];
    (saturation, glint, glint_sigma_px, glint_offset_px)
}

/// A set-up's sensor pattern, each from its own stream of `(seed, setup)`:
/// each column's gain and offset (rms `column_rms`, the offset's in units
/// of `background_level`) and `hot_count` distinct hot pixels `[row, column]`
/// in a frame of `[height_px, width_px]`.
fn sensor_pattern(
    seed: u64,
    setup: &str,
    [height_px, width_px]: [usize; 2],
    column_rms: f64,
    background_level: f64,
    hot_count: usize,
) -> (Vec<f64>, Vec<f64>, Vec<[usize; 2]>) {
    let mut cols = rng_for(seed, setup, "columns", 0);
    let column_gain: Vec<f64> = (0..width_px)
        .map(|_| 1.0 + column_rms * cols.sample::<f64, _>(StandardNormal))
        .collect();
    let column_offset: Vec<f64> = (0..width_px)
        .map(|_| column_rms * background_level * cols.sample::<f64, _>(StandardNormal))
        .collect();
    let mut hot = rng_for(seed, setup, "hot", 0);
    let mut hot_pixels: Vec<[usize; 2]> = Vec::with_capacity(hot_count);
    while hot_pixels.len() < hot_count {
        let p = [hot.gen_range(0..height_px), hot.gen_range(0..width_px)];
        if !hot_pixels.contains(&p) {
            hot_pixels.push(p);
        }
    }
    (column_gain, column_offset, hot_pixels)
}

impl Optics {
    /// σ of the optical blur at image row `row`, px.
    pub fn sigma_at_row(&self, row: f64) -> f64 {
        let t = &self.truth;
        t.blur_sigma0_px + t.defocus_px_per_row * (row - t.focus_row_px).abs()
    }

    /// The illumination drift's gain at column `j` and movie fraction `s ∈ [0, 1]`.
    pub fn drift_gain(&self, j: usize, s: f64) -> f64 {
        let t = &self.truth;
        if t.drift_left == 0.0 && t.drift_right == 0.0 {
            return 1.0;
        }
        let w = self.column_gain.len().max(2) as f64 - 1.0;
        let u = j as f64 / w;
        let arg = std::f64::consts::PI * t.drift_cycles * s;
        1.0 + (1.0 - u) * t.drift_left * (t.drift_phase_left + arg).sin()
            + u * t.drift_right * (t.drift_phase_right + arg).sin()
    }
}

/// Where a movie that starts at the sphere's entry begins.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Entry {
    /// The first image number: the first whose mid-exposure shows the
    /// sphere's lowest point at or below row 0 of the recorded image, or the
    /// release's image when the sphere hangs in view before it.
    pub first_frame: i64,
    /// The sphere's release is in view: it hangs still until `t_release_s`.
    pub release_in_view: bool,
    /// Release instant, s after the trigger.
    pub t_release_s: f64,
}

/// The first frame of a movie that starts as the sphere enters at the top
/// edge. `first` is the motion up to the first contact; the sphere's centre
/// is `(x, z_touch + d(t) / m_per_px)` in the scene, `z_touch` its row at
/// first contact.
pub fn entry_frame(
    first: &super::physics::Trajectory,
    geometry: &Geometry,
    fps: f64,
    (x, z_touch): (f64, f64),
    radius_px: f64,
    m_per_px: f64,
) -> Entry {
    let p = first.params();
    let t_contact = first.bounces()[0].t_contact_s;
    let t_release_s = t_contact - p.impact_speed_m_s / p.gravity_m_s2.max(1e-9);
    let bottom_row = |n: i64| {
        let d = first.state(n as f64 / fps).0;
        geometry.forward(x, z_touch + d / m_per_px + radius_px).1
    };
    let n_release = (t_release_s * fps).floor() as i64;
    if bottom_row(n_release) >= 0.0 {
        return Entry {
            first_frame: n_release,
            release_in_view: true,
            t_release_s,
        };
    }
    let first_frame = (n_release + 1..0)
        .find(|&n| bottom_row(n) >= 0.0)
        .unwrap_or(-1);
    Entry {
        first_frame,
        release_in_view: false,
        t_release_s,
    }
}

/// `count` distinct image numbers in the flight before the first contact
/// (from two frames after `first_frame` to three before contact), ascending.
pub fn missing_frames<R: Rng>(first_frame: i64, count: usize, rng: &mut R) -> Vec<i64> {
    let mut pool: Vec<i64> = (first_frame + 2..=-3).collect();
    let mut out = Vec::with_capacity(count);
    while out.len() < count && !pool.is_empty() {
        let k = rng.gen_range(0..pool.len());
        out.push(pool.swap_remove(k));
    }
    out.sort_unstable();
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_inverse_mapping_undoes_the_forward_one_to_1e_9_px() {
        let g = Geometry::new(512, 384, -0.5 / 319.3_f64.powi(3), 0.4);
        let mut worst: f64 = 0.0;
        for &(x, z) in &[(0.0, 0.0), (511.0, 383.0), (255.5, 191.5), (100.3, 300.7)] {
            let (xd, zd) = g.forward(x, z);
            let (xb, zb) = g.inverse(xd, zd);
            worst = worst.max((xb - x).abs()).max((zb - z).abs());
        }
        assert!(worst < 1e-9, "{worst}");
        // the corner moves inward by 0.5 px (radial) when unrolled
        let g = Geometry::new(512, 384, -0.5 / g.corner_radius_px().powi(3), 0.0);
        let (xd, zd) = g.forward(0.0, 0.0);
        let moved = (xd - 0.0).hypot(zd - 0.0);
        assert!((moved - 0.5).abs() < 1e-12, "{moved}");
    }

    #[test]
    fn fixing_one_effect_leaves_the_others_draws_unchanged() {
        let spec = OpticsSpec::real();
        let fg = FrameGeometry {
            width_px: 512,
            height_px: 384,
            radius_px: 80.0,
        };
        let look = super::super::Preset::Real.look();
        let a = draw(&spec, 3, "S", "r", fg, &look);
        let fixed = OpticsSpec {
            rim: Strength::Fixed(0.2),
            ..spec
        };
        let b = draw(&fixed, 3, "S", "r", fg, &look);
        assert_eq!(b.truth.rim, 0.2);
        assert_eq!(a.truth.halo, b.truth.halo);
        assert_eq!(a.truth.k1_per_px2, b.truth.k1_per_px2);
        assert_ne!(a.truth.rim, 0.2);
    }
}
