//! The overlay a person checks the detection with: the frame, the fitted
//! circle (red), the edge points used (yellow), the undeformed surface line
//! (green) and the circle's chord on it (cyan, the contact half-width), with
//! a 4× enlargement of the contact region below the full frame.

use crate::detect::{Circle, EdgePoint, SurfaceLine};
use crate::source::Frame;
use image::{Rgb, RgbImage};
use imageproc::drawing::draw_line_segment_mut;

const ZOOM: u32 = 4;
const RED: Rgb<u8> = Rgb([230, 40, 40]);
const YELLOW: Rgb<u8> = Rgb([250, 220, 0]);
const GREEN: Rgb<u8> = Rgb([40, 200, 60]);
const CYAN: Rgb<u8> = Rgb([0, 200, 230]);

/// A mapping from frame pixel coordinates to canvas coordinates.
#[derive(Clone, Copy)]
struct View {
    x0: f64,
    z0: f64,
    scale: f64,
    left: f64,
    top: f64,
}

impl View {
    /// Frame point (x, z) → canvas point. Pixel j covers [j − ½, j + ½], so
    /// its left edge j − ½ maps to the left edge of its canvas block.
    fn map(&self, x: f64, z: f64) -> (f32, f32) {
        (
            (self.left + (x - self.x0 + 0.5) * self.scale) as f32,
            (self.top + (z - self.z0 + 0.5) * self.scale) as f32,
        )
    }
}

/// Draw the overlay and return it as PNG bytes.
pub fn overlay_png(
    frame: &Frame,
    bit_depth: u8,
    circle: &Circle,
    points: &[EdgePoint],
    surface: &SurfaceLine,
) -> Result<Vec<u8>, image::ImageError> {
    let (h, w) = frame.dim();
    let shift = bit_depth.saturating_sub(8);
    let grey = |i: usize, j: usize| -> u8 { (frame[[i, j]] >> shift).min(255) as u8 };

    // The enlarged region: the bottom of the sphere around the surface line.
    let y_s = surface.row_at(circle.x_px);
    let half_w = (circle.r_px * 0.9).max(20.0);
    let cx0 = (circle.x_px - half_w).floor().max(0.0) as usize;
    let cx1 = ((circle.x_px + half_w).ceil() as usize).min(w - 1);
    let cz0 = (y_s - 24.0).floor().max(0.0) as usize;
    let cz1 = ((y_s + 12.0).ceil() as usize).min(h - 1);
    let (cw, ch) = ((cx1 - cx0 + 1) as u32, (cz1 - cz0 + 1) as u32);
    let gap = 8u32;
    let canvas_w = (w as u32).max(cw * ZOOM);
    let canvas_h = h as u32 + gap + ch * ZOOM;
    let mut img = RgbImage::from_pixel(canvas_w, canvas_h, Rgb([32, 32, 32]));
    for i in 0..h {
        for j in 0..w {
            let v = grey(i, j);
            img.put_pixel(j as u32, i as u32, Rgb([v, v, v]));
        }
    }
    let top = h as u32 + gap;
    for i in 0..ch {
        for j in 0..cw {
            let v = grey(cz0 + i as usize, cx0 + j as usize);
            for di in 0..ZOOM {
                for dj in 0..ZOOM {
                    img.put_pixel(j * ZOOM + dj, top + i * ZOOM + di, Rgb([v, v, v]));
                }
            }
        }
    }

    let full = View {
        x0: 0.0,
        z0: 0.0,
        scale: 1.0,
        left: 0.0,
        top: 0.0,
    };
    let zoom = View {
        x0: cx0 as f64,
        z0: cz0 as f64,
        scale: ZOOM as f64,
        left: 0.0,
        top: top as f64,
    };
    for (view, x_range, z_range) in [
        (full, (0.0, w as f64), (0.0, h as f64)),
        (
            zoom,
            (cx0 as f64, cx1 as f64 + 1.0),
            (cz0 as f64, cz1 as f64 + 1.0),
        ),
    ] {
        let inside = |x: f64, z: f64| {
            x >= x_range.0 - 0.5
                && x <= x_range.1 - 0.5
                && z >= z_range.0 - 0.5
                && z <= z_range.1 - 0.5
        };
        // Surface line.
        let (a, b) = (x_range.0 - 0.5, x_range.1 - 0.5);
        draw_line_segment_mut(
            &mut img,
            view.map(a, surface.row_at(a)),
            view.map(b, surface.row_at(b)),
            GREEN,
        );
        // Circle as a polyline.
        let n = 720;
        for k in 0..n {
            let (t0, t1) = (
                k as f64 / n as f64 * std::f64::consts::TAU,
                (k + 1) as f64 / n as f64 * std::f64::consts::TAU,
            );
            let p0 = (
                circle.x_px + circle.r_px * t0.cos(),
                circle.z_px + circle.r_px * t0.sin(),
            );
            let p1 = (
                circle.x_px + circle.r_px * t1.cos(),
                circle.z_px + circle.r_px * t1.sin(),
            );
            if inside(p0.0, p0.1) && inside(p1.0, p1.1) {
                draw_line_segment_mut(&mut img, view.map(p0.0, p0.1), view.map(p1.0, p1.1), RED);
            }
        }
        // The chord on the surface line: the contact diameter 2a.
        let d = y_s - circle.z_px;
        if d.abs() < circle.r_px {
            let a = (circle.r_px * circle.r_px - d * d).sqrt();
            let (l, r) = (circle.x_px - a, circle.x_px + a);
            if inside(l, y_s) && inside(r, y_s) {
                draw_line_segment_mut(
                    &mut img,
                    view.map(l, y_s - 1.0),
                    view.map(r, y_s - 1.0),
                    CYAN,
                );
            }
        }
        // Edge points as small crosses.
        let arm = if view.scale > 1.0 { 3.0 } else { 1.5 };
        for p in points
            .iter()
            .filter(|p| p.weight > 0.0 && inside(p.x_px, p.z_px))
        {
            let (u, v) = view.map(p.x_px, p.z_px);
            draw_line_segment_mut(&mut img, (u - arm, v), (u + arm, v), YELLOW);
            draw_line_segment_mut(&mut img, (u, v - arm), (u, v + arm), YELLOW);
        }
    }
    let mut out = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)?;
    Ok(out)
}
