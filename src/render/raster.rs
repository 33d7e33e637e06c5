//! One frame of a backlit side view: background with an illumination
//! gradient, the sphere's dark silhouette (exact area coverage, motion blur),
//! the pillar band below the surface line hiding the sphere, an optional faint
//! mirror reflection, Gaussian optical blur, static dust, frame-to-frame
//! flicker, shot and read noise, quantisation to 8 or 12 bits.
//!
//! The raster knows nothing of physics: it is handed the sphere centre at
//! `K` instants spread uniformly over the exposure (midpoint rule) and draws
//! the time average of the silhouette. Pixel convention (SPEC §1): pixel
//! `(i, j)` covers `[j − ½, j + ½] × [i − ½, i + ½]`, rows grow downward.
//!
//! Image formation, in fractions of the white level, for pixel `p`:
//!
//! ```text
//! S(p)  = B(p) · T(p)                       static scene: background × band transmission
//! M(p)  = B(p) · (1 − τs) · C(p) · (1 − f(p))   light removed by the sphere
//! I(p)  = D(p) · [G ∗ (S − M − Mr)](p)      optics (Gaussian G), then sensor dust D
//! DN(p) = quantise(noise(g_frame · I(p) · white))
//! ```
//!
//! `B` is the illumination, `T` the band (1 above the line, pillar/channel
//! grey in the band, base grey below the pillars), `τs` the sphere's
//! transmission, `C` the time-averaged disk coverage, `f` the fraction of the
//! pixel below the surface line (so pixels wholly below the line never see
//! the sphere), `Mr` the reflection in a thin strip under the line, `g_frame`
//! the flicker gain. `C·(1 − f)` is exact except in the few pixels crossed by
//! both the line and the silhouette edge, where it is the product
//! approximation of the intersection. Because the blur is linear,
//! `G ∗ S` is computed once per run and `G ∗ M` only around the sphere.

use ndarray::Array2;
use rand::Rng;
use rand_distr::{Distribution, Poisson, StandardNormal};
use serde::{Deserialize, Serialize};

use super::coverage::{below_line_fraction, pillar_fraction, DiskBlock};
use crate::source::Frame;

/// The look of the pictures: every effect with its setting (0 turns it off).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Look {
    /// Significant bits: 8 (values 0‥255) or 12 (0‥4095 in 16-bit files).
    pub bit_depth: u8,
    /// Background brightness at the frame centre, fraction of white.
    pub background_level: f64,
    /// Illumination gradient: a ramp and a vignette of this relative amplitude.
    pub gradient: f64,
    /// Light let through the sphere's silhouette, fraction of the local background.
    pub sphere_transmission: f64,
    /// Transmission of the pillars, of the channels between them, and of the
    /// base below the pillars, relative to the background.
    pub pillar_grey: f64,
    /// Transmission of the channels between the pillars, relative to the background.
    pub channel_grey: f64,
    /// Transmission of the base below the pillars, relative to the background.
    pub base_grey: f64,
    /// Standard deviation of the Gaussian optical blur, px (0 = none).
    pub blur_sigma_px: f64,
    /// Integrate the silhouette over the exposure (else: the mid-exposure instant).
    pub motion_blur: bool,
    /// Gaussian read noise, DN at the output bit depth (0 = none).
    pub read_noise_dn: f64,
    /// Electrons at the white level, for Poisson shot noise (0 = none).
    pub full_well_e: f64,
    /// Relative r.m.s. frame-to-frame gain fluctuation (0 = none).
    pub flicker: f64,
    /// Number of static dust specks (0 = none).
    pub dust_count: usize,
    /// Strength of the sphere's mirror image just below the surface line (0 = none).
    pub reflection: f64,
    /// Depth of the strip below the line in which the reflection shows, px.
    pub reflection_depth_px: f64,
}

impl Look {
    /// The largest DN value: 255 for 8 bits, else 4095.
    pub fn white_dn(&self) -> u16 {
        if self.bit_depth == 8 {
            255
        } else {
            4095
        }
    }
}

/// Where things are in the picture, in px.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Scene {
    /// Image width, px.
    pub width_px: usize,
    /// Image height, px.
    pub height_px: usize,
    /// Sphere radius R / s.
    pub radius_px: f64,
    /// Undeformed surface row at column 0; the line is `z = row + slope·x`.
    pub surface_row_px: f64,
    /// Tilt of the surface line, rows per column.
    pub surface_slope: f64,
    /// Pillar height h, pillar width b and channel width c in px.
    pub pillar_height_px: f64,
    /// Pillar width b, px.
    pub pillar_width_px: f64,
    /// Channel width c, px.
    pub channel_width_px: f64,
    /// Column where a pillar starts.
    pub pillar_phase_px: f64,
}

impl Scene {
    /// The surface row at column `x`.
    pub fn surface_row_at(&self, x: f64) -> f64 {
        self.surface_row_px + self.surface_slope * x
    }
}

/// Why a raster cannot be set up.
#[derive(Debug, thiserror::Error)]
pub enum RasterError {
    /// A render setting is out of range.
    #[error("render setting `{name}` = {value}: {allowed}")]
    Invalid {
        /// The setting's name.
        name: &'static str,
        /// The value given.
        value: String,
        /// What is allowed instead.
        allowed: &'static str,
    },
}

/// The per-run renderer: static layers precomputed, frames drawn on demand
/// (shareable between threads).
#[derive(Debug)]
pub struct Raster {
    scene: Scene,
    look: Look,
    /// Illumination B, fraction of white.
    background: Array2<f32>,
    /// G ∗ S, the blurred static scene.
    static_blurred: Array2<f32>,
    /// Band transmission of the pillar/channel pattern per column.
    band_grey: Vec<f64>,
    /// Sensor dust attenuation D (None when there is no dust).
    dust: Option<Array2<f32>>,
    kernel: Vec<f32>,
}

/// Rows and columns (half-open) where a layer is non-zero.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Region {
    pub(super) r0: usize,
    pub(super) r1: usize,
    pub(super) c0: usize,
    pub(super) c1: usize,
}

impl Region {
    fn union(self, o: Region) -> Region {
        Region {
            r0: self.r0.min(o.r0),
            r1: self.r1.max(o.r1),
            c0: self.c0.min(o.c0),
            c1: self.c1.max(o.c1),
        }
    }

    /// Grown by `by` on every side, clipped to an `h × w` image.
    pub(super) fn grow(self, by: usize, h: usize, w: usize) -> Region {
        Region {
            r0: self.r0.saturating_sub(by),
            r1: (self.r1 + by).min(h),
            c0: self.c0.saturating_sub(by),
            c1: (self.c1 + by).min(w),
        }
    }
}

impl Raster {
    /// Precompute the static layers. `dust_rng` places the dust specks (the
    /// caller seeds it from the campaign seed only, so dust stays put from run
    /// to run, as on a real sensor).
    pub fn new<R: Rng>(scene: Scene, look: Look, dust_rng: &mut R) -> Result<Self, RasterError> {
        validate(&scene, &look)?;
        let (h, w) = (scene.height_px, scene.width_px);
        let background = Array2::from_shape_fn((h, w), |(i, j)| {
            illumination(&look, i as f64, j as f64, h as f64, w as f64) as f32
        });
        let period = scene.pillar_width_px + scene.channel_width_px;
        let band_grey: Vec<f64> = (0..w)
            .map(|j| {
                let p = pillar_fraction(
                    j as f64 - 0.5,
                    j as f64 + 0.5,
                    scene.pillar_phase_px,
                    scene.pillar_width_px,
                    period,
                );
                p * look.pillar_grey + (1.0 - p) * look.channel_grey
            })
            .collect();
        let mut stat = Array2::from_shape_fn((h, w), |(i, j)| {
            let (x0, x1, row) = (j as f64 - 0.5, j as f64 + 0.5, i as f64);
            let f_top = below_line_fraction(x0, x1, row, scene.surface_row_px, scene.surface_slope);
            let f_bot = below_line_fraction(
                x0,
                x1,
                row,
                scene.surface_row_px + scene.pillar_height_px,
                scene.surface_slope,
            )
            .min(f_top);
            let t = (1.0 - f_top) + (f_top - f_bot) * band_grey[j] + f_bot * look.base_grey;
            background[[i, j]] * t as f32
        });
        let kernel = gaussian_kernel(look.blur_sigma_px);
        if kernel.len() > 1 {
            let all = Region {
                r0: 0,
                r1: h,
                c0: 0,
                c1: w,
            };
            blur_region(&mut stat, &kernel, all);
        }
        let dust = (look.dust_count > 0).then(|| dust_mask(h, w, look.dust_count, dust_rng));
        Ok(Raster {
            scene,
            look,
            background,
            static_blurred: stat,
            band_grey,
            dust,
            kernel,
        })
    }

    /// Where things are in the picture.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The picture's look.
    pub fn look(&self) -> &Look {
        &self.look
    }

    /// The largest DN value: 255 or 4095.
    pub fn white_dn(&self) -> u16 {
        self.look.white_dn()
    }

    /// The noise-free image in fractions of white, for a sphere whose centre
    /// `(x, z)` (px) was at `centres` at instants spread uniformly over the
    /// exposure (an empty slice: no sphere in view).
    pub fn signal(&self, centres: &[(f64, f64)]) -> Array2<f32> {
        let term = self.sphere_term(centres);
        let (h, w) = (self.scene.height_px, self.scene.width_px);
        let mut out = Array2::<f32>::zeros((h, w));
        for i in 0..h {
            for j in 0..w {
                out[[i, j]] = self.pixel(i, j, term.as_ref());
            }
        }
        out
    }

    /// `D · (G∗S − G∗(M + Mr))` at one pixel.
    #[inline]
    fn pixel(&self, i: usize, j: usize, term: Option<&Term>) -> f32 {
        let mut s = self.static_blurred[[i, j]];
        if let Some(t) = term {
            s -= t.get(i, j);
        }
        if let Some(d) = &self.dust {
            s *= d[[i, j]];
        }
        s
    }

    /// One frame: [`Raster::signal`], times the flicker gain, with shot and
    /// read noise, rounded and clipped to `0..=white`. Shot noise is exact
    /// Poisson below 50 electrons and its normal approximation above, where
    /// the two agree far below one DN. `rng` must be seeded for this frame
    /// alone; draws: the gain, then pixels row by row.
    pub fn frame<R: Rng>(&self, centres: &[(f64, f64)], rng: &mut R) -> Frame {
        let term = self.sphere_term(centres);
        let (h, w) = (self.scene.height_px, self.scene.width_px);
        let white = f64::from(self.white_dn());
        expose(
            &self.look,
            white,
            (h, w),
            |i, j| f64::from(self.pixel(i, j, term.as_ref())),
            rng,
        )
    }

    /// `G ∗ (M + Mr)` on the region around the sphere (and its reflection).
    fn sphere_term(&self, centres: &[(f64, f64)]) -> Option<Term> {
        if centres.is_empty() {
            return None;
        }
        let sc = &self.scene;
        let (h, w) = (sc.height_px as f64, sc.width_px as f64);
        let r = sc.radius_px;
        let weight = 1.0 / centres.len() as f64;
        let (mut zmin, mut zmax, mut xmin, mut xmax) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for &(x, z) in centres {
            zmin = zmin.min(z);
            zmax = zmax.max(z);
            xmin = xmin.min(x);
            xmax = xmax.max(x);
        }
        // Lowest row the line reaches over the sphere's columns: nothing of
        // the sphere is seen below it.
        let l0 = sc.surface_row_at(xmin - r);
        let l1 = sc.surface_row_at(xmax + r);
        let direct = clip_region(
            zmin - r - 1.0,
            (zmax + r + 1.0).min(l0.max(l1) + 1.0),
            xmin - r - 1.0,
            xmax + r + 1.0,
            h,
            w,
        );
        let mirrored: Vec<(f64, f64)> = centres
            .iter()
            .map(|&(x, z)| (x, 2.0 * sc.surface_row_at(x) - z))
            .collect();
        let depth = self.look.reflection_depth_px;
        let reflected = if self.look.reflection > 0.0 {
            clip_region(
                (2.0 * l0.min(l1) - zmax - r - 1.0).max(l0.min(l1) - 1.0),
                l0.max(l1) + depth + 1.0,
                xmin - r - 1.0,
                xmax + r + 1.0,
                h,
                w,
            )
        } else {
            None
        };
        let source = match (direct, reflected) {
            (Some(a), Some(b)) => a.union(b),
            (Some(a), None) | (None, Some(a)) => a,
            (None, None) => return None,
        };
        let rad = self.kernel.len() / 2;
        let mut term = Term::zeros(source.grow(rad, sc.height_px, sc.width_px));
        let dark = 1.0 - self.look.sphere_transmission;
        if let Some(reg) = direct {
            let cov = disk_coverage(reg, centres, r, weight);
            let cw = reg.c1 - reg.c0;
            for i in reg.r0..reg.r1 {
                for j in reg.c0..reg.c1 {
                    let c = cov[(i - reg.r0) * cw + (j - reg.c0)];
                    if c > 0.0 {
                        let above = 1.0
                            - below_line_fraction(
                                j as f64 - 0.5,
                                j as f64 + 0.5,
                                i as f64,
                                sc.surface_row_px,
                                sc.surface_slope,
                            );
                        *term.at(i, j) +=
                            (f64::from(self.background[[i, j]]) * dark * c * above) as f32;
                    }
                }
            }
        }
        if let Some(reg) = reflected {
            // The mirror image in the surface line, seen in a strip of
            // `reflection_depth_px` below it: the band darkened by
            // `reflection · band grey · coverage`.
            let cov = disk_coverage(reg, &mirrored, r, weight);
            let cw = reg.c1 - reg.c0;
            for i in reg.r0..reg.r1 {
                for j in reg.c0..reg.c1 {
                    let c = cov[(i - reg.r0) * cw + (j - reg.c0)];
                    if c > 0.0 {
                        let (x0, x1, row) = (j as f64 - 0.5, j as f64 + 0.5, i as f64);
                        let f_top =
                            below_line_fraction(x0, x1, row, sc.surface_row_px, sc.surface_slope);
                        let f_strip = below_line_fraction(
                            x0,
                            x1,
                            row,
                            sc.surface_row_px + depth,
                            sc.surface_slope,
                        );
                        let strip = (f_top - f_strip).max(0.0);
                        *term.at(i, j) += (f64::from(self.background[[i, j]])
                            * self.band_grey[j]
                            * self.look.reflection
                            * c
                            * strip) as f32;
                    }
                }
            }
        }
        if self.kernel.len() > 1 {
            term.blur(&self.kernel, source, sc.height_px, sc.width_px);
        }
        Some(term)
    }
}

/// The sensor: `signal(i, j)` (fraction of white) times the flicker gain,
/// with shot and read noise, rounded and clipped to `0..=white`. Shot noise
/// is exact Poisson below 50 electrons and its normal approximation above,
/// where the two agree far below one DN. `rng` must be seeded for this frame
/// alone; draws: the gain, then pixels row by row.
pub(super) fn expose<R: Rng>(
    look: &Look,
    white: f64,
    (h, w): (usize, usize),
    signal: impl Fn(usize, usize) -> f64,
    rng: &mut R,
) -> Frame {
    let gain = if look.flicker > 0.0 {
        1.0 + look.flicker * rng.sample::<f64, _>(StandardNormal)
    } else {
        1.0
    };
    let e_per_dn = look.full_well_e / white;
    let read = look.read_noise_dn;
    let read_var = read * read;
    let mut frame = Frame::zeros((h, w));
    for i in 0..h {
        for j in 0..w {
            let v = signal(i, j) * gain * white;
            let noisy = if e_per_dn > 0.0 {
                let lambda = v.max(0.0) * e_per_dn;
                if lambda < 50.0 {
                    // Exact Poisson where the normal approximation would be poor.
                    let e = Poisson::new(lambda.max(1e-12)).map_or(0.0, |p| p.sample(rng));
                    let r: f64 = if read > 0.0 {
                        rng.sample(StandardNormal)
                    } else {
                        0.0
                    };
                    e / e_per_dn + read * r
                } else {
                    // Shot (λ/e² DN²) and read noise as one normal draw.
                    let sd = (lambda / (e_per_dn * e_per_dn) + read_var).sqrt();
                    v + sd * rng.sample::<f64, _>(StandardNormal)
                }
            } else if read > 0.0 {
                v + read * rng.sample::<f64, _>(StandardNormal)
            } else {
                v
            };
            // round half up (values are ≥ 0 after the clamp)
            frame[[i, j]] = (noisy.clamp(0.0, white) + 0.5) as u16;
        }
    }
    frame
}

/// A layer that is zero outside `region`, stored row-major over it.
#[derive(Debug)]
struct Term {
    region: Region,
    data: Vec<f32>,
}

impl Term {
    fn zeros(region: Region) -> Self {
        let n = (region.r1 - region.r0) * (region.c1 - region.c0);
        Term {
            region,
            data: vec![0.0; n],
        }
    }

    fn width(&self) -> usize {
        self.region.c1 - self.region.c0
    }

    fn at(&mut self, i: usize, j: usize) -> &mut f32 {
        let w = self.width();
        &mut self.data[(i - self.region.r0) * w + (j - self.region.c0)]
    }

    #[inline]
    fn get(&self, i: usize, j: usize) -> f32 {
        let r = &self.region;
        if i >= r.r0 && i < r.r1 && j >= r.c0 && j < r.c1 {
            self.data[(i - r.r0) * self.width() + (j - r.c0)]
        } else {
            0.0
        }
    }

    /// Separable Gaussian blur in place. The layer is zero outside `source`
    /// (inside `self.region`, which is `source` grown by the kernel radius);
    /// image borders are edge-clamped, as for the static scene, so the blur
    /// is the same linear operator on every layer.
    fn blur(&mut self, kernel: &[f32], source: Region, image_h: usize, full_w: usize) {
        let image_w_clamp = |j: isize, reg: &Region, full_w: usize| -> Option<usize> {
            let jj = j.clamp(0, full_w as isize - 1) as usize;
            (jj >= reg.c0 && jj < reg.c1).then_some(jj)
        };
        let rad = kernel.len() / 2;
        let out = self.region;
        let ow = self.width();
        let mut tmp = vec![0.0_f32; (source.r1 - source.r0) * ow];
        for i in source.r0..source.r1 {
            let row = &self.data[(i - out.r0) * ow..(i - out.r0 + 1) * ow];
            let trow = &mut tmp[(i - source.r0) * ow..(i - source.r0 + 1) * ow];
            for (jo, t) in trow.iter_mut().enumerate() {
                let j = (out.c0 + jo) as isize;
                let mut acc = 0.0;
                for (k, kv) in kernel.iter().enumerate() {
                    if let Some(jj) = image_w_clamp(j + k as isize - rad as isize, &source, full_w)
                    {
                        acc += kv * row[jj - out.c0];
                    }
                }
                *t = acc;
            }
        }
        for i in out.r0..out.r1 {
            let orow = &mut self.data[(i - out.r0) * ow..(i - out.r0 + 1) * ow];
            orow.fill(0.0);
            for (k, kv) in kernel.iter().enumerate() {
                let ii = (i as isize + k as isize - rad as isize).clamp(0, image_h as isize - 1)
                    as usize;
                if ii >= source.r0 && ii < source.r1 {
                    let trow = &tmp[(ii - source.r0) * ow..(ii - source.r0 + 1) * ow];
                    for (o, t) in orow.iter_mut().zip(trow) {
                        *o += kv * t;
                    }
                }
            }
        }
    }
}

pub(super) fn validate(scene: &Scene, look: &Look) -> Result<(), RasterError> {
    let bad = |name, value: f64, allowed| RasterError::Invalid {
        name,
        value: value.to_string(),
        allowed,
    };
    if !matches!(look.bit_depth, 8 | 12) {
        return Err(RasterError::Invalid {
            name: "bit_depth",
            value: look.bit_depth.to_string(),
            allowed: "must be 8 or 12",
        });
    }
    if scene.width_px < 8 || scene.height_px < 8 || scene.width_px > 8192 || scene.height_px > 8192
    {
        return Err(RasterError::Invalid {
            name: "width/height",
            value: format!("{}×{}", scene.width_px, scene.height_px),
            allowed: "each must lie in 8‥8192 px",
        });
    }
    let unit = [
        ("background_level", look.background_level),
        ("sphere_transmission", look.sphere_transmission),
        ("pillar_grey", look.pillar_grey),
        ("channel_grey", look.channel_grey),
        ("base_grey", look.base_grey),
        ("reflection", look.reflection),
        ("gradient", look.gradient),
    ];
    for (name, v) in unit {
        if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
            return Err(bad(name, v, "must lie in [0, 1]"));
        }
    }
    let nonneg = [
        ("blur_sigma_px", look.blur_sigma_px),
        ("read_noise_dn", look.read_noise_dn),
        ("full_well_e", look.full_well_e),
        ("flicker", look.flicker),
        ("reflection_depth_px", look.reflection_depth_px),
    ];
    for (name, v) in nonneg {
        if !(v.is_finite() && v >= 0.0) {
            return Err(bad(name, v, "must be a finite number ≥ 0"));
        }
    }
    if look.blur_sigma_px > 20.0 {
        return Err(bad("blur_sigma_px", look.blur_sigma_px, "must be ≤ 20 px"));
    }
    let positive = [
        ("radius_px", scene.radius_px),
        ("pillar_height_px", scene.pillar_height_px),
        ("pillar_width_px", scene.pillar_width_px),
        ("channel_width_px", scene.channel_width_px),
    ];
    for (name, v) in positive {
        if !(v.is_finite() && v > 0.0) {
            return Err(bad(name, v, "must be a finite number > 0"));
        }
    }
    for (name, v) in [
        ("surface_row_px", scene.surface_row_px),
        ("surface_slope", scene.surface_slope),
        ("pillar_phase_px", scene.pillar_phase_px),
    ] {
        if !v.is_finite() {
            return Err(bad(name, v, "must be finite"));
        }
    }
    if scene.surface_slope.abs() > 0.2 {
        return Err(bad(
            "surface_slope",
            scene.surface_slope,
            "must lie in [−0.2, 0.2] rows per column",
        ));
    }
    Ok(())
}

/// Illumination: `L · (1 + G·(0.6 u + 0.4 v) − 0.5 G·(u² + v²)/2)` with
/// `u, v ∈ [−1, 1]` the normalised column and row from the frame centre: a
/// ramp brighter to the lower right and a vignette, both scaled by `G`.
pub(super) fn illumination(look: &Look, i: f64, j: f64, h: f64, w: f64) -> f64 {
    let u = (j - 0.5 * (w - 1.0)) / (0.5 * w);
    let v = (i - 0.5 * (h - 1.0)) / (0.5 * h);
    let g = look.gradient;
    look.background_level * (1.0 + g * (0.6 * u + 0.4 * v) - 0.25 * g * (u * u + v * v))
}

/// The rows and columns of the box `[z0, z1] × [x0, x1]` clipped to the image.
fn clip_region(z0: f64, z1: f64, x0: f64, x1: f64, h: f64, w: f64) -> Option<Region> {
    let r0 = z0.floor().max(0.0);
    let r1 = (z1.ceil() + 1.0).min(h);
    let c0 = x0.floor().max(0.0);
    let c1 = (x1.ceil() + 1.0).min(w);
    (r0 < r1 && c0 < c1).then_some(Region {
        r0: r0 as usize,
        r1: r1 as usize,
        c0: c0 as usize,
        c1: c1 as usize,
    })
}

/// Time-averaged coverage of the pixels of `region` by disks of radius `r`
/// centred at `centres`, each weighted by `weight`, row-major in the region.
///
/// Per centre and row, the pixels wholly inside the disk are found from the
/// farthest point of the row band and filled through a difference array; only
/// the pixels the circle crosses get the exact coverage ([`DiskBlock`]).
fn disk_coverage(region: Region, centres: &[(f64, f64)], r: f64, weight: f64) -> Vec<f64> {
    let cw = region.c1 - region.c0;
    let mut cov = vec![0.0_f64; (region.r1 - region.r0) * cw];
    // diff[i][k]: +weight at the first fully-covered column, −weight after the last
    let mut diff = vec![0.0_f64; (region.r1 - region.r0) * (cw + 1)];
    for &(cx, cz) in centres {
        let i0 = ((cz - r - 0.5).floor().max(region.r0 as f64)) as usize;
        let i1 = ((cz + r + 1.5).ceil().min(region.r1 as f64)).max(i0 as f64) as usize;
        if i1 <= i0 {
            continue;
        }
        let block = DiskBlock::new(
            cx,
            cz,
            r,
            (region.c0 as i64, region.c1 as i64 - 1),
            (i0 as i64, i1 as i64 - 1),
        );
        for i in i0..i1 {
            let dz = (i as f64 - cz).abs();
            let near = (dz - 0.5).max(0.0);
            if near >= r {
                continue;
            }
            let w_out = (r * r - near * near).sqrt();
            let far = dz + 0.5;
            // fully inside: |j − cx| + ½ ≤ w_in
            let (in_lo, in_hi) = if far < r {
                let w_in = (r * r - far * far).sqrt();
                ((cx - w_in + 0.5).ceil(), (cx + w_in - 0.5).floor())
            } else {
                (1.0, 0.0)
            };
            let j_lo = (cx - w_out - 0.5).floor().max(region.c0 as f64);
            let j_hi = (cx + w_out + 0.5).ceil().min(region.c1 as f64 - 1.0);
            let row = (i - region.r0) * cw;
            let mut j = j_lo;
            while j <= j_hi {
                if j >= in_lo && j <= in_hi {
                    // jump over the inside run
                    let run_end = in_hi.min(j_hi);
                    let a = (j as usize) - region.c0;
                    let b = (run_end as usize) - region.c0 + 1;
                    let drow = (i - region.r0) * (cw + 1);
                    diff[drow + a] += weight;
                    diff[drow + b] -= weight;
                    j = run_end + 1.0;
                    continue;
                }
                let c = block.pixel(i as i64, j as i64);
                if c > 0.0 {
                    cov[row + (j as usize - region.c0)] += weight * c;
                }
                j += 1.0;
            }
        }
    }
    for i in 0..(region.r1 - region.r0) {
        let mut acc = 0.0;
        for k in 0..cw {
            acc += diff[i * (cw + 1) + k];
            cov[i * cw + k] += acc;
        }
    }
    cov
}

/// A normalised Gaussian kernel of standard deviation `sigma` (px) sampled
/// at integer offsets over ±⌈4σ⌉; `[1]` when `sigma` is 0.
pub(super) fn gaussian_kernel(sigma: f64) -> Vec<f32> {
    if sigma <= 0.0 {
        return vec![1.0];
    }
    let radius = (4.0 * sigma).ceil() as i64;
    let raw: Vec<f64> = (-radius..=radius)
        .map(|k| (-0.5 * (k as f64 / sigma).powi(2)).exp())
        .collect();
    let sum: f64 = raw.iter().sum();
    raw.iter().map(|v| (v / sum) as f32).collect()
}

/// The renderer's Gaussian blur (σ in px, kernel to 4σ, edge-clamped) of a
/// whole frame, in place. Only for `examples/draw_blur_vs_imageproc.rs`,
/// which measures it against `imageproc`.
#[doc(hidden)]
pub fn blur_frame(img: &mut Array2<f32>, sigma_px: f64) {
    let (h, w) = img.dim();
    let all = Region {
        r0: 0,
        r1: h,
        c0: 0,
        c1: w,
    };
    blur_region(img, &gaussian_kernel(sigma_px), all);
}

/// Separable Gaussian blur of `img`, which is zero outside `region`, with
/// edge-clamped borders (the same rule for every layer, so blurring is
/// linear across layers). Writes the result in place and returns the region
/// where it can be non-zero (`region` grown by the kernel radius).
fn blur_region(img: &mut Array2<f32>, kernel: &[f32], region: Region) -> Region {
    let (h, w) = img.dim();
    let rad = kernel.len() / 2;
    let out = Region {
        r0: region.r0.saturating_sub(rad),
        r1: (region.r1 + rad).min(h),
        c0: region.c0.saturating_sub(rad),
        c1: (region.c1 + rad).min(w),
    };
    let clamp = |k: isize, n: usize| k.clamp(0, n as isize - 1) as usize;
    let data = img
        .as_slice_mut()
        .expect("frames are allocated in standard layout");
    // horizontal pass, rows of the source region only
    let ow = out.c1 - out.c0;
    let mut tmp = vec![0.0_f32; (region.r1 - region.r0) * ow];
    for i in region.r0..region.r1 {
        let row = &data[i * w..(i + 1) * w];
        let trow = &mut tmp[(i - region.r0) * ow..(i - region.r0 + 1) * ow];
        for (jo, t) in trow.iter_mut().enumerate() {
            let j = out.c0 + jo;
            *t = if j >= rad && j + rad < w {
                row[j - rad..=j + rad]
                    .iter()
                    .zip(kernel)
                    .map(|(a, b)| a * b)
                    .sum()
            } else {
                kernel
                    .iter()
                    .enumerate()
                    .map(|(k, kv)| kv * row[clamp(j as isize + k as isize - rad as isize, w)])
                    .sum()
            };
        }
    }
    // vertical pass; tmp is zero outside the source rows
    for i in out.r0..out.r1 {
        let orow = &mut data[i * w + out.c0..i * w + out.c1];
        orow.fill(0.0);
        for (k, kv) in kernel.iter().enumerate() {
            let ii = clamp(i as isize + k as isize - rad as isize, h);
            if ii >= region.r0 && ii < region.r1 {
                let trow = &tmp[(ii - region.r0) * ow..(ii - region.r0 + 1) * ow];
                for (o, t) in orow.iter_mut().zip(trow) {
                    *o += kv * t;
                }
            }
        }
    }
    out
}

/// Multiplicative sensor dust: a few soft dark specks, `1 − a·exp(−ρ²/2s²)`.
pub(super) fn dust_mask<R: Rng>(h: usize, w: usize, count: usize, rng: &mut R) -> Array2<f32> {
    let mut mask = Array2::<f32>::ones((h, w));
    for _ in 0..count {
        let cx = rng.gen_range(0.0..w as f64);
        let cz = rng.gen_range(0.0..h as f64);
        let s = rng.gen_range(0.8..2.5);
        let a = rng.gen_range(0.08..0.3);
        let reach = (4.0 * s) as isize + 1;
        for i in (cz as isize - reach).max(0)..(cz as isize + reach + 1).min(h as isize) {
            for j in (cx as isize - reach).max(0)..(cx as isize + reach + 1).min(w as isize) {
                let d2 = (j as f64 - cx).powi(2) + (i as f64 - cz).powi(2);
                mask[[i as usize, j as usize]] *= (1.0 - a * (-0.5 * d2 / (s * s)).exp()) as f32;
            }
        }
    }
    mask
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blurring_preserves_the_total_away_from_borders() {
        let k = gaussian_kernel(1.3);
        let mut img = Array2::<f32>::zeros((40, 40));
        img[[20, 20]] = 1.0;
        img[[21, 19]] = 2.0;
        let reg = Region {
            r0: 20,
            r1: 22,
            c0: 19,
            c1: 21,
        };
        let out = blur_region(&mut img, &k, reg);
        assert!(out.r0 == 14 && out.r1 == 28);
        let s: f32 = img.sum();
        assert!((s - 3.0).abs() < 1e-5, "{s}");
    }

    #[test]
    fn clean_disk_coverage_sums_to_its_area() {
        let region = Region {
            r0: 0,
            r1: 60,
            c0: 0,
            c1: 60,
        };
        let r = 17.3;
        let cov = disk_coverage(region, &[(30.2, 29.7), (30.2, 31.1)], r, 0.5);
        let sum: f64 = cov.iter().sum();
        assert!((sum - std::f64::consts::PI * r * r).abs() < 1e-9, "{sum}");
        assert!(cov.iter().all(|&c| (0.0..=1.0 + 1e-12).contains(&c)));
    }
}
