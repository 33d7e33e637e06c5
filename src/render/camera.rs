//! One frame as a real camera records it: the scene of [`super::raster`]
//! (backlight, band, sphere, motion blur, noise) plus the optics and sensor
//! effects of [`super::optics`] — the steel ball's rim, halo and highlight,
//! the glossy band top and its darkening by the sphere's mirror image, the
//! pillar tops' top row, the band dipping under the sphere, defocus that
//! varies with the row, camera roll, barrel distortion, column fixed-pattern
//! noise, hot pixels, a slow illumination drift, a saturated backlight and
//! a central glint on the ball.
//!
//! # Image formation
//!
//! Every pixel `(i, j)` of the recorded image looks at the scene point
//! `p(i, j) = G⁻¹(j, i)` ([`Geometry::inverse`]: distortion undone, then the
//! roll); the pixel integrates the scene over the unit square centred on
//! `p(i, j)` — exact area coverage of the disk, the band's lines and the
//! strips, as in the plain raster. (The mapping's Jacobian differs from a
//! translation by under 1 %: ≤ 0.5° of roll and ≤ 0.3 % of scale change, so
//! treating the pre-image of a pixel as a translated unit square moves no
//! edge and changes a pixel's value by under 1 % of an edge pixel's
//! contrast, symmetric about the edge.) The sharp picture, in fractions of
//! the backlight `B`:
//!
//! ```text
//! T(p)   band: 1 above the top edge y_t(x), pillar/channel grey below it,
//!        × (1 + top_row) over the top row(s), + gloss over the glossy strip
//! S(p)   = B · T(p)                                   (static; y_t = y_s)
//! Δ(p)   = B · vis · [−(1 − τs) C + rim·g(R − ρ) C + halo·g(ρ − R)(1 − C) + highlight·H(p) C
//!                      + glint·⟨Gl(p − c_k) C_k⟩]
//!        − B · C_m · (gloss · strip + reflection · grey · strip_r)
//!        + B · (T_dipped − T)                         (during contact, with dip)
//! ```
//!
//! `C` is the disk coverage averaged over the exposure, `ρ` the distance to
//! the centre, `vis` the part of the pixel above the band's top edge (dipped
//! during contact), `C_m` the coverage by the sphere's mirror image in the
//! surface line. Then `I = D · Blur_σ(row)(S + Δ)` (σ of the output row; the
//! static part blurred once per run, `Δ` only around the sphere), and the
//! sensor: `DN = white · (I · (1 + γ_j) + o_j) · drift(j, t) · G_sat · flicker`,
//! with shot and read noise as in [`super::raster`] and clipped at white,
//! then the hot pixels. `G_sat` (1 unless the backlight is saturated) lifts
//! the dimmest background pixel to `1 + saturation` times white. `Gl` is the
//! glint's Gaussian about each exposure sample's centre `c_k` (plus an
//! offset), weighted by that sample's disk coverage `C_k` and averaged.

use ndarray::Array2;
use rand::Rng;

use super::coverage::{below_line_fraction, disk_rect_area, pillar_fraction};
use super::optics::{Geometry, Optics};
use super::raster::{
    dust_mask, expose, gaussian_kernel, illumination, validate, Look, RasterError, Region, Scene,
};
use crate::source::Frame;

/// Half the diagonal of a unit pixel: a pixel whose centre is farther than
/// this from an edge lies wholly on one side of it.
const HALF_DIAGONAL: f64 = std::f64::consts::SQRT_2 / 2.0;

/// `g(u; w) = ½ (1 + cos(π u / w))` for `0 ≤ u < w`, else 0.
fn fade(u: f64, w: f64) -> f64 {
    if u < w {
        0.5 * (1.0 + (std::f64::consts::PI * u / w).cos())
    } else {
        0.0
    }
}

/// The per-run renderer of a real camera (shareable between threads).
#[derive(Debug)]
pub struct CameraRaster {
    scene: Scene,
    look: Look,
    optics: Optics,
    /// Scene coordinates `(x, z)` of every pixel centre, row-major.
    map: Vec<(f64, f64)>,
    background: Array2<f32>,
    /// `D · Blur(S)`: the static scene, blurred, with the dust.
    static_blurred: Array2<f32>,
    /// The blur kernel of every output row.
    kernels: Vec<Vec<f32>>,
    dust: Option<Array2<f32>>,
}

impl CameraRaster {
    /// Precompute the mapping, the static scene and the blur kernels.
    pub fn new<R: Rng>(
        scene: Scene,
        look: Look,
        optics: Optics,
        dust_rng: &mut R,
    ) -> Result<Self, RasterError> {
        validate(&scene, &look)?;
        let (h, w) = (scene.height_px, scene.width_px);
        let geometry: Geometry = optics.geometry;
        let mut map = Vec::with_capacity(h * w);
        for i in 0..h {
            for j in 0..w {
                map.push(geometry.inverse(j as f64, i as f64));
            }
        }
        let background = Array2::from_shape_fn((h, w), |(i, j)| {
            illumination(&look, i as f64, j as f64, h as f64, w as f64) as f32
        });
        let kernels: Vec<Vec<f32>> = (0..h)
            .map(|i| gaussian_kernel(optics.sigma_at_row(i as f64)))
            .collect();
        let mut optics = optics;
        if optics.truth.saturation > 0.0 {
            let dimmest = background.iter().fold(f32::MAX, |a, &b| a.min(b));
            optics.truth.saturation_gain = (1.0 + optics.truth.saturation) / f64::from(dimmest);
        }
        let dust = (look.dust_count > 0).then(|| dust_mask(h, w, look.dust_count, dust_rng));
        let mut raster = CameraRaster {
            scene,
            look,
            optics,
            map,
            background,
            static_blurred: Array2::zeros((h, w)),
            kernels,
            dust,
        };
        let sharp: Vec<f32> = (0..h * w)
            .map(|k| {
                let (mx, mz) = raster.map[k];
                let t = raster.band(
                    mx,
                    mz,
                    raster.scene.surface_row_px,
                    raster.scene.surface_slope,
                );
                (f64::from(raster.background[[k / w, k % w]]) * t) as f32
            })
            .collect();
        let all = Region {
            r0: 0,
            r1: h,
            c0: 0,
            c1: w,
        };
        let (_, blurred) = raster.blur(&sharp, all);
        let mut stat =
            Array2::from_shape_vec((h, w), blurred).expect("the blur keeps the image's size");
        if let Some(d) = &raster.dust {
            stat *= d;
        }
        raster.static_blurred = stat;
        Ok(raster)
    }

    /// The realised camera this raster draws through.
    pub fn optics(&self) -> &Optics {
        &self.optics
    }

    /// The band's transmission `T` of the unit square centred on the scene
    /// point `(mx, mz)`, with the band's top edge `z = a + b·x`.
    fn band(&self, mx: f64, mz: f64, a: f64, b: f64) -> f64 {
        let sc = &self.scene;
        let lk = &self.look;
        let o = &self.optics.truth;
        let (x0, x1) = (mx - 0.5, mx + 0.5);
        let f_top = below_line_fraction(x0, x1, mz, a, b);
        if f_top <= 0.0 {
            return 1.0;
        }
        let f_bot = below_line_fraction(
            x0,
            x1,
            mz,
            sc.surface_row_px + sc.pillar_height_px,
            sc.surface_slope,
        )
        .min(f_top);
        let p = pillar_fraction(
            x0,
            x1,
            sc.pillar_phase_px,
            sc.pillar_width_px,
            sc.pillar_width_px + sc.channel_width_px,
        );
        let grey = p * lk.pillar_grey + (1.0 - p) * lk.channel_grey;
        let mut t = (1.0 - f_top) + (f_top - f_bot) * grey + f_bot * lk.base_grey;
        if o.top_row != 0.0 {
            let strip = f_top - below_line_fraction(x0, x1, mz, a + o.top_row_width_px, b);
            t += o.top_row * grey * strip;
        }
        if o.gloss != 0.0 {
            t += o.gloss * (f_top - below_line_fraction(x0, x1, mz, a + o.gloss_width_px, b));
        }
        t
    }

    /// The largest DN value: 255 or 4095.
    pub fn white_dn(&self) -> u16 {
        self.look.white_dn()
    }

    /// The noise-free image in fractions of white (before the sensor's
    /// column pattern, drift and flicker), for sphere centres (scene px) at
    /// instants spread uniformly over the exposure.
    pub fn signal(&self, centres: &[(f64, f64)]) -> Array2<f32> {
        let mut out = self.static_blurred.clone();
        if let Some((region, layer)) = self.sphere_layer(centres) {
            let (reg, blurred) = self.blur(&layer, region);
            let cw = reg.c1 - reg.c0;
            for i in reg.r0..reg.r1 {
                for j in reg.c0..reg.c1 {
                    let d = self.dust.as_ref().map_or(1.0, |d| d[[i, j]]);
                    out[[i, j]] += d * blurred[(i - reg.r0) * cw + (j - reg.c0)];
                }
            }
        }
        out
    }

    /// One frame: [`CameraRaster::signal`] through the sensor (column
    /// pattern, drift at `movie_fraction ∈ [0, 1]` of the movie, flicker,
    /// shot and read noise, quantisation), then the hot pixels.
    pub fn frame<R: Rng>(&self, centres: &[(f64, f64)], movie_fraction: f64, rng: &mut R) -> Frame {
        let sig = self.signal(centres);
        let (h, w) = sig.dim();
        let o = &self.optics;
        let drift: Vec<f64> = (0..w).map(|j| o.drift_gain(j, movie_fraction)).collect();
        let white = f64::from(self.white_dn());
        let gain = o.truth.saturation_gain;
        let mut frame = expose(
            &self.look,
            white,
            (h, w),
            |i, j| {
                let v = (f64::from(sig[[i, j]]) * o.column_gain[j] + o.column_offset[j]) * drift[j];
                if gain != 1.0 {
                    v * gain
                } else {
                    v
                }
            },
            rng,
        );
        for &[i, j] in &o.truth.hot_pixels {
            frame[[i, j]] = o.truth.hot_pixel_dn;
        }
        frame
    }

    /// The surface row `y_s(x)` (scene).
    fn surface_at(&self, x: f64) -> f64 {
        self.scene.surface_row_at(x)
    }

    /// The band top's depth below `y_s(x)` under a sphere centred at
    /// `(xm, zm)` with the dip on, and its slope `d depth / dx`.
    fn dip_at(&self, x: f64, xm: f64, zm: f64) -> (f64, f64) {
        let r = self.scene.radius_px;
        let u = x - xm;
        if u.abs() >= r {
            return (0.0, 0.0);
        }
        let s = (r * r - u * u).sqrt();
        let below = zm + s - self.surface_at(x);
        if below <= 0.0 {
            return (0.0, 0.0);
        }
        let dip = self.optics.truth.dip;
        (dip * below, dip * (-u / s - self.scene.surface_slope))
    }

    /// `Δ` (before the blur) on the region of the recorded image the sphere,
    /// its halo, its mirror image in the glossy strip and the dip can reach.
    fn sphere_layer(&self, centres: &[(f64, f64)]) -> Option<(Region, Vec<f32>)> {
        if centres.is_empty() {
            return None;
        }
        let reach_of = self.sphere_reach(centres)?;
        let SphereReach {
            region,
            k,
            xm,
            zm,
            rim_w,
            halo_w,
            dip_on,
            mirror_on,
        } = reach_of;
        let sc = &self.scene;
        let lk = &self.look;
        let o = &self.optics.truth;
        let r = sc.radius_px;
        let w = sc.width_px;
        let cw = region.c1 - region.c0;
        let mut layer = vec![0.0_f32; (region.r1 - region.r0) * cw];
        let dark = 1.0 - lk.sphere_transmission;
        let reach = r + halo_w.max(HALF_DIAGONAL) + 0.75;
        let inner = (r - rim_w - HALF_DIAGONAL).max(0.0);
        let two_sigma2 = 2.0 * o.highlight_sigma_px * o.highlight_sigma_px;
        let two_glint2 = 2.0 * o.glint_sigma_px * o.glint_sigma_px;
        let (hx, hz) = (xm + o.highlight_offset_px[0], zm + o.highlight_offset_px[1]);
        let lit = Lit {
            r,
            k,
            rim_w,
            halo_w,
            dark,
            reach,
            inner,
            two_sigma2,
            two_glint2,
            highlight_at: (hx, hz),
        };
        let mirrored: Vec<(f64, f64)> = centres
            .iter()
            .map(|&(x, z)| (x, 2.0 * self.surface_at(x) - z))
            .collect();
        for i in region.r0..region.r1 {
            for j in region.c0..region.c1 {
                let (mx, mz) = self.map[i * w + j];
                let b = f64::from(self.background[[i, j]]);
                let (depth, dslope) = if dip_on {
                    self.dip_at(mx, xm, zm)
                } else {
                    (0.0, 0.0)
                };
                let slope = sc.surface_slope + dslope;
                let a = self.surface_at(mx) + depth - slope * mx;
                let f_hide = below_line_fraction(mx - 0.5, mx + 0.5, mz, a, slope);
                let mut delta = 0.0;
                if depth > 0.0 {
                    delta += b
                        * (self.band(mx, mz, a, slope)
                            - self.band(mx, mz, sc.surface_row_px, sc.surface_slope));
                }
                let vis = 1.0 - f_hide;
                if vis > 0.0 {
                    let light = self.sphere_light((mx, mz), centres, &lit);
                    delta += b * vis * light;
                }
                if mirror_on && f_hide > 0.0 {
                    if let Some(dark) =
                        self.mirror_darkening((mx, mz), (a, slope), f_hide, b, &mirrored, &lit)
                    {
                        delta -= dark;
                    }
                }
                layer[(i - region.r0) * cw + (j - region.c0)] = delta as f32;
            }
        }
        Some((region, layer))
    }

    /// Where the sphere layer of `centres` (not empty) reaches: the region
    /// of the recorded image, and what its pixels need.
    fn sphere_reach(&self, centres: &[(f64, f64)]) -> Option<SphereReach> {
        let sc = &self.scene;
        let lk = &self.look;
        let o = &self.optics.truth;
        let r = sc.radius_px;
        let k = centres.len() as f64;
        let (mut zmin, mut zmax, mut xmin, mut xmax) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        let (mut xm, mut zm) = (0.0, 0.0);
        for &(x, z) in centres {
            zmin = zmin.min(z);
            zmax = zmax.max(z);
            xmin = xmin.min(x);
            xmax = xmax.max(x);
            xm += x / k;
            zm += z / k;
        }
        let rim_w = if o.rim > 0.0 { o.rim_width_px } else { 0.0 };
        let halo_w = if o.halo > 0.0 { o.halo_width_px } else { 0.0 };
        let margin = rim_w.max(halo_w) + 2.0;
        let (xa, xb) = (xmin - r - margin, xmax + r + margin);
        let line_lo = self.surface_at(xa).min(self.surface_at(xb));
        let line_hi = self.surface_at(xa).max(self.surface_at(xb));
        let dip_on = o.dip > 0.0 && zm + r > self.surface_at(xm);
        let dip_max = if dip_on {
            o.dip * (zm + r - self.surface_at(xm)).max(0.0) + 1.0
        } else {
            0.0
        };
        let mirror_on = o.gloss != 0.0 || lk.reflection > 0.0;
        let strip = o
            .gloss_width_px
            .max(o.top_row_width_px)
            .max(if lk.reflection > 0.0 {
                lk.reflection_depth_px
            } else {
                0.0
            })
            + 1.0;
        let z0 = zmin - r - margin;
        let mut z1 = (zmax + r + margin).min(line_hi + dip_max + 1.0);
        if (mirror_on && zmax + r + 1.0 > line_lo - strip) || dip_on {
            z1 = z1.max(line_hi + strip + dip_max + 1.0);
        }
        if z1 <= z0 {
            return None;
        }
        let g = &self.optics.geometry;
        let (h, w) = (sc.height_px, sc.width_px);
        let (mut x_lo, mut x_hi, mut z_lo, mut z_hi) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for (x, z) in [(xa, z0), (xb, z0), (xa, z1), (xb, z1)] {
            let (xd, zd) = g.forward(x, z);
            x_lo = x_lo.min(xd);
            x_hi = x_hi.max(xd);
            z_lo = z_lo.min(zd);
            z_hi = z_hi.max(zd);
        }
        let r0 = (z_lo - 2.0).floor().max(0.0);
        let r1 = (z_hi + 3.0).ceil().min(h as f64);
        let c0 = (x_lo - 2.0).floor().max(0.0);
        let c1 = (x_hi + 3.0).ceil().min(w as f64);
        if r0 >= r1 || c0 >= c1 {
            return None;
        }
        let region = Region {
            r0: r0 as usize,
            r1: r1 as usize,
            c0: c0 as usize,
            c1: c1 as usize,
        };
        Some(SphereReach {
            region,
            k,
            xm,
            zm,
            rim_w,
            halo_w,
            dip_on,
            mirror_on,
        })
    }

    /// The sphere's light at image point `(mx, mz)` over the exposure's
    /// centres: its shadow (`−dark` times its coverage), rim, halo, glint
    /// and highlight, averaged over the `k` centres.
    fn sphere_light(&self, (mx, mz): (f64, f64), centres: &[(f64, f64)], lit: &Lit) -> f64 {
        let o = &self.optics.truth;
        let Lit {
            r,
            k,
            rim_w,
            halo_w,
            dark,
            reach,
            inner,
            two_sigma2,
            two_glint2,
            highlight_at: (hx, hz),
        } = *lit;
        let coverage = |dx: f64, dz: f64, rho: f64| disk_coverage(dx, dz, rho, r);
        let (mut c_sum, mut s_sum) = (0.0, 0.0);
        for &(cx, cz) in centres {
            let (dx, dz) = (mx - cx, mz - cz);
            let d2 = dx * dx + dz * dz;
            if d2 >= reach * reach {
                continue;
            }
            if o.glint > 0.0 {
                let (gx, gz) = (dx - o.glint_offset_px[0], dz - o.glint_offset_px[1]);
                let g = o.glint * (-(gx * gx + gz * gz) / two_glint2).exp();
                s_sum += if d2 <= inner * inner {
                    g
                } else {
                    g * coverage(dx, dz, d2.sqrt())
                };
            }
            if d2 <= inner * inner {
                c_sum += 1.0;
                continue;
            }
            let rho = d2.sqrt();
            let c = coverage(dx, dz, rho);
            c_sum += c;
            if o.rim > 0.0 {
                s_sum += o.rim * fade((r - rho).max(0.0), rim_w) * c;
            }
            if o.halo > 0.0 {
                s_sum += o.halo * fade((rho - r).max(0.0), halo_w) * (1.0 - c);
            }
        }
        let c = c_sum / k;
        let mut light = -dark * c + s_sum / k;
        if o.highlight > 0.0 && c > 0.0 {
            let d2 = (mx - hx).powi(2) + (mz - hz).powi(2);
            light += o.highlight * (-d2 / two_sigma2).exp() * c;
        }
        light
    }

    /// What the sphere's mirror image (`mirrored` centres) in the glossy
    /// strip and the reflection takes from image point `(mx, mz)` of
    /// background `b`, under the line `(a, slope)` that hides `f_hide` of
    /// it; `None` where it takes nothing.
    #[allow(clippy::too_many_arguments)]
    fn mirror_darkening(
        &self,
        (mx, mz): (f64, f64),
        (a, slope): (f64, f64),
        f_hide: f64,
        b: f64,
        mirrored: &[(f64, f64)],
        lit: &Lit,
    ) -> Option<f64> {
        let sc = &self.scene;
        let lk = &self.look;
        let o = &self.optics.truth;
        let (r, k) = (lit.r, lit.k);
        let coverage = |dx: f64, dz: f64, rho: f64| disk_coverage(dx, dz, rho, r);
        let below = |depth_px: f64| {
            f_hide - below_line_fraction(mx - 0.5, mx + 0.5, mz, a + depth_px, slope)
        };
        let gloss_strip = if o.gloss != 0.0 {
            below(o.gloss_width_px)
        } else {
            0.0
        };
        let refl_strip = if lk.reflection > 0.0 {
            below(lk.reflection_depth_px)
        } else {
            0.0
        };
        if gloss_strip > 0.0 || refl_strip > 0.0 {
            let mut cm = 0.0;
            for &(cx, cz) in mirrored {
                let (dx, dz) = (mx - cx, mz - cz);
                let d2 = dx * dx + dz * dz;
                if d2 < (r + HALF_DIAGONAL).powi(2) {
                    cm += coverage(dx, dz, d2.sqrt());
                }
            }
            cm /= k;
            if cm > 0.0 {
                let grey = {
                    let p = pillar_fraction(
                        mx - 0.5,
                        mx + 0.5,
                        sc.pillar_phase_px,
                        sc.pillar_width_px,
                        sc.pillar_width_px + sc.channel_width_px,
                    );
                    p * lk.pillar_grey + (1.0 - p) * lk.channel_grey
                };
                return Some(b * cm * (o.gloss * gloss_strip + lk.reflection * grey * refl_strip));
            }
        }
        None
    }

    /// Gaussian blur with the σ of each output row (separable: rows with
    /// their own σ, then columns with the output row's σ; σ changes by under
    /// 0.1 px over a kernel, so this is the Gaussian of σ(row) to that
    /// order). `layer` is zero outside `src`; image borders are
    /// edge-clamped, the same linear operator for every layer. Returns the
    /// region where the result can be non-zero and the result on it.
    fn blur(&self, layer: &[f32], src: Region) -> (Region, Vec<f32>) {
        let (h, w) = (self.scene.height_px, self.scene.width_px);
        let rad_max = self.kernels.iter().map(|k| k.len() / 2).max().unwrap_or(0);
        let out = src.grow(rad_max, h, w);
        let (sw, ow) = (src.c1 - src.c0, out.c1 - out.c0);
        let clamp = |k: isize, n: usize| k.clamp(0, n as isize - 1) as usize;
        let mut tmp = vec![0.0_f32; (src.r1 - src.r0) * ow];
        for i in src.r0..src.r1 {
            let kernel = &self.kernels[i];
            let rad = (kernel.len() / 2) as isize;
            let row = &layer[(i - src.r0) * sw..(i - src.r0 + 1) * sw];
            for (jo, t) in tmp[(i - src.r0) * ow..(i - src.r0 + 1) * ow]
                .iter_mut()
                .enumerate()
            {
                let j = (out.c0 + jo) as isize;
                let mut acc = 0.0_f32;
                for (q, kv) in kernel.iter().enumerate() {
                    let jj = clamp(j + q as isize - rad, w);
                    if jj >= src.c0 && jj < src.c1 {
                        acc += kv * row[jj - src.c0];
                    }
                }
                *t = acc;
            }
        }
        let mut res = vec![0.0_f32; (out.r1 - out.r0) * ow];
        for i in out.r0..out.r1 {
            let kernel = &self.kernels[i];
            let rad = (kernel.len() / 2) as isize;
            let orow = &mut res[(i - out.r0) * ow..(i - out.r0 + 1) * ow];
            for (q, kv) in kernel.iter().enumerate() {
                let ii = clamp(i as isize + q as isize - rad, h);
                if ii >= src.r0 && ii < src.r1 {
                    let trow = &tmp[(ii - src.r0) * ow..(ii - src.r0 + 1) * ow];
                    for (o, t) in orow.iter_mut().zip(trow) {
                        *o += kv * t;
                    }
                }
            }
        }
        (out, res)
    }
}

/// Where a frame's sphere layer reaches ([`CameraRaster::sphere_layer`]).
struct SphereReach {
    region: Region,
    /// The number of centres over the exposure, and their mean.
    k: f64,
    xm: f64,
    zm: f64,
    /// The rim's and the halo's widths (px), 0 without them.
    rim_w: f64,
    halo_w: f64,
    /// The sphere presses the surface down (the dip) / a mirror image shows.
    dip_on: bool,
    mirror_on: bool,
}

/// What the sphere's light at a pixel needs, the same for every pixel of a
/// frame.
#[derive(Clone, Copy)]
struct Lit {
    r: f64,
    k: f64,
    rim_w: f64,
    halo_w: f64,
    dark: f64,
    /// Beyond this distance (px) a centre adds nothing; within `inner` the
    /// pixel is wholly covered.
    reach: f64,
    inner: f64,
    two_sigma2: f64,
    two_glint2: f64,
    highlight_at: (f64, f64),
}

/// The part of the unit pixel at `(dx, dz)` from a disk's centre (at
/// distance `rho`) that the disk of radius `r` covers.
fn disk_coverage(dx: f64, dz: f64, rho: f64, r: f64) -> f64 {
    if rho <= r - HALF_DIAGONAL {
        1.0
    } else if rho >= r + HALF_DIAGONAL {
        0.0
    } else {
        disk_rect_area(dx - 0.5, dx + 0.5, dz - 0.5, dz + 0.5, r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fade_is_one_at_the_edge_and_zero_beyond_its_width() {
        assert_eq!(fade(0.0, 2.0), 1.0);
        assert!((fade(1.0, 2.0) - 0.5).abs() < 1e-15);
        assert_eq!(fade(2.0, 2.0), 0.0);
        assert_eq!(fade(0.5, 0.0), 0.0);
    }
}
