//! Why the overlay drawing and the renderer's Gaussian blur are hand-written
//! instead of calling `imageproc` (the coarse detector's
//! labelling is compared in `coarse_vs_imageproc.rs`).
//!
//! Overlay: a 512 × 384 8-bit frame enlarged 3× with a fitted circle, a
//! surface line and 150 edge points, drawn by `detect::overlay::overlay`
//! and, on the same enlarged frame, by `imageproc`'s
//! `draw_line_segment_mut` (sub-pixel ends), `draw_hollow_circle_mut` and
//! `draw_filled_circle_mut` (whole-pixel centres and radii). Times the
//! drawing alone (the enlargement, common to both, is timed apart and
//! subtracted) and how far the drawn pixels lie from where the geometry is.
//!
//! Blur: a 512 × 384 f32 frame (backlight, a sharp dark disc, a pillar
//! band) blurred at σ = 0.6, 1.2, 2.5 px by the renderer's blur and by
//! `imageproc::filter::gaussian_blur_f32`; the error of each is against
//! the sampled Gaussian kernel taken to 8σ in f64 (same edge clamping).
//! imageproc blurs with one σ per image; the renderer's defocus needs σ to
//! change with the row, which imageproc can only do by blurring the whole
//! frame once per σ: that is timed too (σ from 0.6 to 2.5 px down the
//! frame, in 0.05 px steps).
//!
//!     cargo run --release --example draw_blur_vs_imageproc
//!
//! Prints medians over 5 rounds.

use dropscope::detect::circle::Circle;
use dropscope::detect::edges::EdgePoint;
use dropscope::detect::surface::SurfaceLine;
use dropscope::detect::Band;
use dropscope::figures::overlay::{
    overlay, point_radius_px, OverlayView, CIRCLE_RGB, POINT_RGB, SURFACE_RGB,
};
use dropscope::render::raster::blur_frame;
use image::{ImageBuffer, Luma, Rgb, RgbImage};
use imageproc::drawing::{draw_filled_circle_mut, draw_hollow_circle_mut, draw_line_segment_mut};
use imageproc::filter::gaussian_blur_f32;
use ndarray::Array2;
use std::time::Instant;

const W: usize = 512;
const H: usize = 384;
const ZOOM: u32 = 3;

/// Median over 5 rounds of `n` calls, in µs a call.
fn median_us(n: usize, mut f: impl FnMut()) -> f64 {
    let mut rounds: Vec<f64> = (0..5)
        .map(|_| {
            let t = Instant::now();
            for _ in 0..n {
                f();
            }
            t.elapsed().as_secs_f64() / n as f64 * 1e6
        })
        .collect();
    rounds.sort_by(f64::total_cmp);
    rounds[2]
}

/// Mean and largest of `v`.
fn mean_max(v: &[f64]) -> (f64, f64) {
    let mean = v.iter().sum::<f64>() / v.len().max(1) as f64;
    (mean, v.iter().copied().fold(0.0, f64::max))
}

/// Overlay pixels of exactly `rgb`, as their centres in frame pixels.
fn drawn(img: &RgbImage, rgb: [u8; 3]) -> Vec<(f64, f64)> {
    let z = f64::from(ZOOM);
    img.enumerate_pixels()
        .filter(|(_, _, p)| p.0 == rgb)
        .map(|(u, v, _)| {
            (
                (f64::from(u) + 0.5) / z - 0.5,
                (f64::from(v) + 0.5) / z - 0.5,
            )
        })
        .collect()
}

/// How far the drawing in `img` lies from the geometry, frame px:
/// (circle pixels from the circle, line pixels from the line, edge-point
/// discs' centroids from the points), each as (mean, max).
fn placement(img: &RgbImage, c: &Circle, s: &SurfaceLine, shown: &[(f64, f64)]) -> [(f64, f64); 3] {
    let circ: Vec<f64> = drawn(img, CIRCLE_RGB)
        .iter()
        .map(|&(x, z)| ((x - c.x_px).hypot(z - c.z_px) - c.r_px).abs())
        .collect();
    let line: Vec<f64> = drawn(img, SURFACE_RGB)
        .iter()
        .map(|&(x, z)| (z - s.row_at(x)).abs() / s.slope.hypot(1.0))
        .collect();
    let dots = drawn(img, POINT_RGB);
    let reach = (point_radius_px(ZOOM) + 1.0) / f64::from(ZOOM);
    let pts: Vec<f64> = shown
        .iter()
        .map(|&(px, pz)| {
            let mine: Vec<_> = dots
                .iter()
                .filter(|&&(x, z)| (x - px).hypot(z - pz) <= reach)
                .collect();
            let n = mine.len() as f64;
            let cx = mine.iter().map(|p| p.0).sum::<f64>() / n;
            let cz = mine.iter().map(|p| p.1).sum::<f64>() / n;
            (cx - px).hypot(cz - pz)
        })
        .collect();
    [mean_max(&circ), mean_max(&line), mean_max(&pts)]
}

fn overlay_comparison() {
    let c = Circle {
        x_px: 250.3,
        z_px: 180.7,
        r_px: 70.2,
    };
    let s = SurfaceLine::given(300.2, 0.013);
    let frame = Array2::from_shape_fn((H, W), |(i, j)| {
        let (x, z) = (j as f64, i as f64);
        if (x - c.x_px).hypot(z - c.z_px) < c.r_px {
            40u16
        } else if z > s.row_at(x) {
            90
        } else {
            200
        }
    });
    let band = Band::new(frame.view(), 0).expect("band");
    // 150 edge points on the circle, each a little off it as fitted ones are.
    let points: Vec<EdgePoint> = (0..150)
        .map(|k| {
            let t = std::f64::consts::TAU * k as f64 / 150.0;
            let r = c.r_px + 0.3 * (7.0 * t).sin();
            EdgePoint {
                x_px: c.x_px + r * t.cos(),
                z_px: c.z_px + r * t.sin(),
                weight: 1.0,
            }
        })
        .collect();
    let view = OverlayView {
        x0: 0,
        z0: 0,
        width: W,
        height: H,
        zoom: ZOOM,
    };
    let z = f64::from(ZOOM);
    let to_img = |x: f64, y: f64| ((x + 0.5) * z, (y + 0.5) * z);
    // The points the overlay draws (it skips those within 3 radii of one
    // drawn); imageproc is given the same ones.
    let r_img = point_radius_px(ZOOM);
    let mut shown: Vec<(f64, f64)> = Vec::new();
    for p in &points {
        let (u, v) = to_img(p.x_px, p.z_px);
        if shown.iter().all(|&(a, b)| {
            let (su, sv) = to_img(a, b);
            (su - u).powi(2) + (sv - v).powi(2) >= (3.0 * r_img).powi(2)
        }) {
            shown.push((p.x_px, p.z_px));
        }
    }
    let imageproc_draw = |img: &mut RgbImage| {
        // imageproc truncates the line's ends to whole pixels and draws its
        // circles about whole pixels: each is given the pixel that holds the
        // point (overlay pixel (i, j) covers [i, i + 1) × [j, j + 1)).
        let (u0, v0) = to_img(-0.5, s.row_at(-0.5));
        let (u1, v1) = to_img(W as f64 - 0.5, s.row_at(W as f64 - 0.5));
        draw_line_segment_mut(
            img,
            (u0 as f32, v0 as f32),
            (u1 as f32, v1 as f32),
            Rgb(SURFACE_RGB),
        );
        let (uc, vc) = to_img(c.x_px, c.z_px);
        draw_hollow_circle_mut(
            img,
            (uc.floor() as i32, vc.floor() as i32),
            (c.r_px * z).round() as i32,
            Rgb(CIRCLE_RGB),
        );
        for &(x, y) in &shown {
            let (u, v) = to_img(x, y);
            draw_filled_circle_mut(
                img,
                (u.floor() as i32, v.floor() as i32),
                r_img.round() as i32,
                Rgb(POINT_RGB),
            );
        }
    };
    // The overlay draws inside `overlay`: its drawing is the whole call less
    // the bare enlargement. imageproc's is timed alone, drawing again and
    // again on one enlarged frame.
    let n = 200;
    let base = median_us(n, || {
        std::hint::black_box(overlay(&band, 8, &view, &[], None, None));
    });
    let ours = median_us(n, || {
        std::hint::black_box(overlay(&band, 8, &view, &points, Some(&c), Some(&s)));
    });
    let mut canvas = overlay(&band, 8, &view, &[], None, None);
    let theirs = median_us(n, || {
        imageproc_draw(&mut canvas);
        std::hint::black_box(&canvas);
    });
    let mine = overlay(&band, 8, &view, &points, Some(&c), Some(&s));
    let mut other = overlay(&band, 8, &view, &[], None, None);
    imageproc_draw(&mut other);
    println!(
        "overlay {}x{} (zoom {ZOOM}), {} of 150 edge points drawn: enlargement {base:.0} us; \
         drawing: dropscope {:.0} us, imageproc {theirs:.0} us",
        W as u32 * ZOOM,
        H as u32 * ZOOM,
        shown.len(),
        ours - base
    );
    let names = [
        "circle pixels from the circle",
        "line pixels from the line",
        "point discs' centroids from the points",
    ];
    let a = placement(&mine, &c, &s, &shown);
    let b = placement(&other, &c, &s, &shown);
    for ((name, m), t) in names.iter().zip(a).zip(b) {
        println!(
            "  {name} (frame px, mean / max): dropscope {:.3} / {:.3}, imageproc {:.3} / {:.3}",
            m.0, m.1, t.0, t.1
        );
    }
}

/// The exact discrete Gaussian blur: kernel sampled to 8σ, f64, edge-clamped.
fn reference_blur(img: &Array2<f32>, sigma: f64) -> Array2<f64> {
    let rad = (8.0 * sigma).ceil() as isize;
    let raw: Vec<f64> = (-rad..=rad)
        .map(|k| (-0.5 * (k as f64 / sigma).powi(2)).exp())
        .collect();
    let sum: f64 = raw.iter().sum();
    let kernel: Vec<f64> = raw.iter().map(|v| v / sum).collect();
    let (h, w) = img.dim();
    let clamp = |k: isize, n: usize| k.clamp(0, n as isize - 1) as usize;
    let tmp = Array2::from_shape_fn((h, w), |(i, j)| {
        kernel
            .iter()
            .enumerate()
            .map(|(q, kv)| kv * f64::from(img[[i, clamp(j as isize + q as isize - rad, w)]]))
            .sum::<f64>()
    });
    Array2::from_shape_fn((h, w), |(i, j)| {
        kernel
            .iter()
            .enumerate()
            .map(|(q, kv)| kv * tmp[[clamp(i as isize + q as isize - rad, h), j]])
            .sum::<f64>()
    })
}

fn blur_comparison() {
    // Backlight with vignetting, a sharp dark disc, a pillar band: the
    // renderer's static scene before the optics.
    let sharp = Array2::from_shape_fn((H, W), |(i, j)| {
        let (x, z) = (j as f64, i as f64);
        let light = 1.0 - 0.1 * ((x - 256.0).powi(2) + (z - 192.0).powi(2)) / 320.0_f64.powi(2);
        let v = if (x - 250.3).hypot(z - 180.7) < 70.2 {
            0.2 * light
        } else if z > 300.2 {
            if (x / 40.0).fract() < 0.625 {
                0.3
            } else {
                0.45
            }
        } else {
            light
        };
        v as f32
    });
    let as_image = |a: &Array2<f32>| {
        ImageBuffer::<Luma<f32>, Vec<f32>>::from_raw(
            W as u32,
            H as u32,
            a.iter().copied().collect(),
        )
        .expect("w × h values")
    };
    let img = as_image(&sharp);
    for sigma in [0.6, 1.2, 2.5] {
        let n = 40;
        let ours = median_us(n, || {
            let mut a = sharp.clone();
            blur_frame(&mut a, sigma);
            std::hint::black_box(a);
        });
        let theirs = median_us(n, || {
            std::hint::black_box(gaussian_blur_f32(&img, sigma as f32));
        });
        let exact = reference_blur(&sharp, sigma);
        let mut mine = sharp.clone();
        blur_frame(&mut mine, sigma);
        let other = gaussian_blur_f32(&img, sigma as f32);
        let err = |f: &dyn Fn(usize, usize) -> f32| {
            let e: Vec<f64> = exact
                .indexed_iter()
                .map(|((i, j), v)| (f64::from(f(i, j)) - v).abs())
                .collect();
            mean_max(&e)
        };
        let (em, ex) = err(&|i, j| mine[[i, j]]);
        let (tm, tx) = err(&|i, j| other.get_pixel(j as u32, i as u32).0[0]);
        println!(
            "blur sigma {sigma} px: dropscope {ours:.0} us, imageproc {theirs:.0} us; error vs \
             exact Gaussian (mean / max, of a 0.8 contrast): dropscope {em:.1e} / {ex:.1e}, \
             imageproc {tm:.1e} / {tx:.1e}"
        );
    }
    // σ growing down the frame (defocus), whole-frame blurs one per σ step.
    let sigma_at = |i: usize| ((0.6 + 1.9 * i as f64 / (H - 1) as f64) / 0.05).round() * 0.05;
    let steps = {
        let mut s: Vec<f64> = (0..H).map(sigma_at).collect();
        s.dedup();
        s
    };
    let per_row = median_us(3, || {
        let mut out = vec![0.0_f32; W * H];
        for &sg in &steps {
            let b = gaussian_blur_f32(&img, sg as f32);
            for i in (0..H).filter(|&i| sigma_at(i) == sg) {
                for j in 0..W {
                    out[i * W + j] = b.get_pixel(j as u32, i as u32).0[0];
                }
            }
        }
        std::hint::black_box(out);
    });
    println!(
        "blur with sigma(row) 0.6 -> 2.5 px by imageproc ({} whole-frame blurs): {per_row:.0} us",
        steps.len()
    );
}

fn main() {
    overlay_comparison();
    blur_comparison();
}
