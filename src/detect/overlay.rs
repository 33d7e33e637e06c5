//! An overlay picture of one frame's detection — the frame, the edge points,
//! the fitted circle and the surface line — so a person can check it by eye.
//!
//! Pure: returns an RGB image (and PNG bytes with [`encode_png`]); the
//! caller writes it (`io_util::write_atomic`). A crop can be enlarged by an
//! integer `zoom` so that sub-pixel placement is visible: frame point
//! `(x, z)` lands at overlay pixel `((x − x0 + ½)·zoom, (z − z0 + ½)·zoom)`,
//! i.e. frame pixel `(i, j)` becomes the `zoom × zoom` block whose centre is
//! the pixel's centre.

use image::{Rgb, RgbImage};

use super::circle::Circle;
use super::edges::EdgePoint;
use super::surface::SurfaceLine;
use super::Band;

/// Colours: fitted circle, edge points, surface line.
pub const CIRCLE_RGB: [u8; 3] = [255, 40, 40];
pub const POINT_RGB: [u8; 3] = [40, 255, 40];
pub const SURFACE_RGB: [u8; 3] = [60, 140, 255];

/// Which part of the frame to draw and how large.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OverlayView {
    /// First column and row of the crop (frame pixels).
    pub x0: usize,
    pub z0: usize,
    /// Crop size (frame pixels).
    pub width: usize,
    pub height: usize,
    /// Enlargement (≥ 1).
    pub zoom: u32,
}

impl OverlayView {
    /// The whole band at zoom 1.
    pub fn whole(band: &Band) -> Self {
        OverlayView {
            x0: 0,
            z0: band.row0,
            width: band.width,
            height: band.nrows,
            zoom: 1,
        }
    }

    /// A crop around `c` (its bounding box plus `margin_px`), clipped to the band.
    pub fn around(band: &Band, c: &Circle, margin_px: f64, zoom: u32) -> Self {
        let clip = |v: f64, lo: usize, hi: usize| (v.max(lo as f64) as usize).min(hi);
        let x0 = clip(c.x_px - c.r_px - margin_px, 0, band.width.saturating_sub(1));
        let x1 = clip(c.x_px + c.r_px + margin_px + 1.0, x0 + 1, band.width);
        let z_end = band.row0 + band.nrows;
        let z0 = clip(
            c.z_px - c.r_px - margin_px,
            band.row0,
            z_end.saturating_sub(1),
        );
        let z1 = clip(c.z_px + c.r_px + margin_px + 1.0, z0 + 1, z_end);
        OverlayView {
            x0,
            z0,
            width: x1 - x0,
            height: z1 - z0,
            zoom: zoom.max(1),
        }
    }
}

/// Draw the crop of `band` (grey, `bit_depth` significant bits scaled to 8)
/// with the detection on top.
pub fn overlay(
    band: &Band,
    bit_depth: u8,
    view: &OverlayView,
    points: &[EdgePoint],
    circle: Option<&Circle>,
    surface: Option<&SurfaceLine>,
) -> RgbImage {
    let zoom = view.zoom.max(1);
    let (w, h) = (view.width as u32 * zoom, view.height as u32 * zoom);
    let shift = bit_depth.saturating_sub(8);
    let mut img = RgbImage::from_fn(w, h, |px, pz| {
        let j = view.x0 + (px / zoom) as usize;
        let i = view.z0 + (pz / zoom) as usize;
        let v = if j < band.width && i >= band.row0 && i < band.row0 + band.nrows {
            (band.data[(i - band.row0) * band.width + j] >> shift).min(255) as u8
        } else {
            0
        };
        Rgb([v, v, v])
    });
    let to_img = |x: f64, z: f64| -> (f64, f64) {
        (
            (x - view.x0 as f64 + 0.5) * zoom as f64,
            (z - view.z0 as f64 + 0.5) * zoom as f64,
        )
    };
    let put = |img: &mut RgbImage, u: f64, v: f64, rgb: [u8; 3]| {
        if u >= 0.0 && v >= 0.0 && (u as u32) < w && (v as u32) < h {
            img.put_pixel(u as u32, v as u32, Rgb(rgb));
        }
    };
    if let Some(s) = surface {
        let steps = (w as usize) * 2;
        for k in 0..=steps {
            let x = view.x0 as f64 - 0.5 + view.width as f64 * k as f64 / steps as f64;
            let (u, v) = to_img(x, s.row_at(x));
            put(&mut img, u, v, SURFACE_RGB);
        }
    }
    if let Some(c) = circle {
        let steps = ((std::f64::consts::TAU * c.r_px * zoom as f64) * 2.0).ceil() as usize + 8;
        for k in 0..steps {
            let t = std::f64::consts::TAU * k as f64 / steps as f64;
            let (u, v) = to_img(c.x_px + c.r_px * t.cos(), c.z_px + c.r_px * t.sin());
            put(&mut img, u, v, CIRCLE_RGB);
        }
    }
    let arm = (zoom as f64 / 2.0).max(1.0);
    for p in points {
        let (u, v) = to_img(p.x_px, p.z_px);
        for d in [-arm, 0.0, arm] {
            put(&mut img, u + d, v, POINT_RGB);
            put(&mut img, u, v + d, POINT_RGB);
        }
    }
    img
}

/// PNG bytes of an overlay.
pub fn encode_png(img: &RgbImage) -> Result<Vec<u8>, image::ImageError> {
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png)?;
    Ok(out.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::Frame;

    #[test]
    fn circle_points_and_surface_land_where_they_belong() {
        let frame = Frame::from_elem((60, 80), 200);
        let band = Band::frame(&frame).unwrap();
        let c = Circle {
            x_px: 40.0,
            z_px: 25.0,
            r_px: 10.0,
        };
        let line = SurfaceLine {
            row0_px: 50.0,
            slope: 0.0,
            cov: [[0.0; 2]; 2],
            residual_px: 0.0,
            n_used: 0,
            model_err_px: 0.0,
        };
        let p = [EdgePoint {
            x_px: 30.0,
            z_px: 25.0,
            weight: 1.0,
        }];
        let view = OverlayView::around(&band, &c, 5.0, 4);
        assert_eq!(
            (view.x0, view.z0, view.width, view.height),
            (25, 10, 31, 31)
        );
        let img = overlay(&band, 8, &view, &p, Some(&c), Some(&line));
        assert_eq!(img.dimensions(), (124, 124));
        // The circle's top (40, 15) → ((40 − 25 + ½)·4, (15 − 10 + ½)·4) = (62, 22).
        assert_eq!(img.get_pixel(62, 22).0, CIRCLE_RGB);
        // The edge point (30, 25) → (22, 62), drawn last, on top of the circle.
        assert_eq!(img.get_pixel(22, 62).0, POINT_RGB);
        // Grey elsewhere.
        assert_eq!(img.get_pixel(2, 2).0, [200, 200, 200]);
        // The surface line is outside this crop; the whole frame shows it.
        let whole = overlay(&band, 8, &OverlayView::whole(&band), &[], None, Some(&line));
        assert_eq!(whole.get_pixel(10, 50).0, SURFACE_RGB);
        let png = encode_png(&img).unwrap();
        assert_eq!(&png[1..4], b"PNG");
    }
}
