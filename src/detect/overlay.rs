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

/// Radius of an edge point's disc in overlay pixels at enlargement `zoom`.
pub fn point_radius_px(zoom: u32) -> f64 {
    (0.8 * zoom as f64).max(2.0)
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
    // Each edge point a disc, large enough to see at any zoom, with the
    // circle showing between them.
    let r = point_radius_px(zoom);
    let reach = r.ceil() as i64;
    let mut shown: Vec<(f64, f64)> = Vec::with_capacity(points.len());
    for p in points {
        let (u, v) = to_img(p.x_px, p.z_px);
        // Points closer than 3 radii to one drawn would merge into a band
        // that hides the circle (at zoom 1 they are ~3 px apart): skipped.
        if shown
            .iter()
            .any(|&(su, sv)| (su - u).hypot(sv - v) < 3.0 * r)
        {
            continue;
        }
        shown.push((u, v));
        for dv in -reach..=reach {
            for du in -reach..=reach {
                let (pu, pv) = (u.floor() + du as f64, v.floor() + dv as f64);
                if (pu + 0.5 - u).hypot(pv + 0.5 - v) <= r {
                    put(&mut img, pu, pv, POINT_RGB);
                }
            }
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

/// Grey levels of the animation's palette; the colours of the drawing follow.
const GREYS: usize = 32;

/// The animation's palette: [`GREYS`] greys from black to white, then the
/// circle's, the points' and the surface line's colours.
fn palette() -> Vec<u8> {
    let mut p: Vec<u8> = (0..GREYS)
        .flat_map(|i| [((i * 255 + (GREYS - 1) / 2) / (GREYS - 1)) as u8; 3])
        .collect();
    for c in [CIRCLE_RGB, POINT_RGB, SURFACE_RGB] {
        p.extend_from_slice(&c);
    }
    p
}

/// The palette index of an overlay pixel: a drawing colour's own, else the
/// nearest grey (of the channels' mean: the frame, the caption and its
/// anti-aliased text are grey).
fn palette_index(px: [u8; 3]) -> u8 {
    match [CIRCLE_RGB, POINT_RGB, SURFACE_RGB]
        .iter()
        .position(|c| *c == px)
    {
        Some(k) => (GREYS + k) as u8,
        None => {
            let mean = (u32::from(px[0]) + u32::from(px[1]) + u32::from(px[2])) as f64 / 3.0;
            (mean * (GREYS - 1) as f64 / 255.0).round() as u8
        }
    }
}

/// Animated-PNG bytes of `frames` (shown `frame_ms` each, looping), as
/// 8-bit indexed colour ([`palette`]: greys within 0.5 % of the frame's
/// level, the drawing's colours exact), a third of RGB's bytes. Frames of
/// different sizes are padded at the right and bottom with the first
/// frame's last pixel's colour.
pub fn encode_apng(frames: &[RgbImage], frame_ms: u16) -> Result<Vec<u8>, png::EncodingError> {
    let w = frames.iter().map(|f| f.width()).max().unwrap_or(1);
    let h = frames.iter().map(|f| f.height()).max().unwrap_or(1);
    let fill = frames
        .first()
        .filter(|f| f.width() > 0 && f.height() > 0)
        .map_or(0, |f| {
            palette_index(f.get_pixel(f.width() - 1, f.height() - 1).0)
        });
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, w, h);
        enc.set_color(png::ColorType::Indexed);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_palette(palette());
        enc.set_compression(png::Compression::Fast);
        enc.set_animated(frames.len() as u32, 0)?;
        enc.set_frame_delay(frame_ms, 1000)?;
        let mut writer = enc.write_header()?;
        let mut data = vec![fill; (w * h) as usize];
        for f in frames {
            data.fill(fill);
            for (x, y, px) in f.enumerate_pixels() {
                data[(y * w + x) as usize] = palette_index(px.0);
            }
            writer.write_image_data(&data)?;
        }
        writer.finish()?;
    }
    Ok(out)
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
        // The edge point (30, 25) → (22, 62), drawn last, on top of the
        // circle: a disc of radius 3.2 px at zoom 4, 32 pixels (not a 1-px cross).
        assert_eq!(img.get_pixel(22, 62).0, POINT_RGB);
        let green = (0..124)
            .flat_map(|u| (0..124).map(move |v| (u, v)))
            .filter(|&(u, v)| img.get_pixel(u, v).0 == POINT_RGB)
            .count();
        assert_eq!(green, 32);
        assert_eq!(img.get_pixel(20, 62).0, POINT_RGB);
        assert_ne!(img.get_pixel(22, 65).0, POINT_RGB);
        // Grey elsewhere.
        assert_eq!(img.get_pixel(2, 2).0, [200, 200, 200]);
        // The surface line is outside this crop; the whole frame shows it.
        let whole = overlay(&band, 8, &OverlayView::whole(&band), &[], None, Some(&line));
        assert_eq!(whole.get_pixel(10, 50).0, SURFACE_RGB);
        let png = encode_png(&img).unwrap();
        assert_eq!(&png[1..4], b"PNG");
    }

    #[test]
    fn points_closer_than_three_radii_are_drawn_once() {
        let band_frame = Frame::from_elem((40, 40), 100);
        let band = Band::frame(&band_frame).unwrap();
        let at = |x_px: f64| EdgePoint {
            x_px,
            z_px: 20.0,
            weight: 1.0,
        };
        let view = OverlayView::whole(&band);
        let count = |pts: &[EdgePoint]| {
            let img = overlay(&band, 8, &view, pts, None, None);
            img.pixels().filter(|p| p.0 == POINT_RGB).count()
        };
        let one = count(&[at(10.0)]);
        assert!(one >= 9, "{one}");
        // 2 px apart at zoom 1 (radius 2): the second is skipped; 7 px: both drawn.
        assert_eq!(count(&[at(10.0), at(12.0)]), one);
        assert_eq!(count(&[at(10.0), at(17.0)]), 2 * one);
    }

    #[test]
    fn the_animation_has_every_frame_and_the_drawing_colours_exact() {
        let mut a = RgbImage::from_pixel(20, 10, Rgb([128, 128, 128]));
        a.put_pixel(3, 4, Rgb(CIRCLE_RGB));
        let mut b = RgbImage::from_pixel(20, 12, Rgb([250, 250, 250]));
        b.put_pixel(5, 6, Rgb(POINT_RGB));
        let bytes = encode_apng(&[a, b.clone(), b], 80).unwrap();
        let mut reader = png::Decoder::new(std::io::Cursor::new(bytes))
            .read_info()
            .unwrap();
        let info = reader.info();
        assert_eq!((info.width, info.height), (20, 12));
        let actl = info.animation_control().unwrap();
        assert_eq!((actl.num_frames, actl.num_plays), (3, 0));
        let palette = info.palette.clone().unwrap().into_owned();
        let rgb = |data: &[u8], x: usize, y: usize| {
            let i = data[y * 20 + x] as usize;
            [palette[3 * i], palette[3 * i + 1], palette[3 * i + 2]]
        };
        let mut data = vec![0; reader.output_buffer_size().unwrap()];
        reader.next_frame(&mut data).unwrap();
        assert_eq!(rgb(&data, 3, 4), CIRCLE_RGB);
        // Grey to within half a palette step (255 / 31 / 2).
        assert!((i32::from(rgb(&data, 0, 0)[0]) - 128).abs() <= 5);
        reader.next_frame(&mut data).unwrap();
        assert_eq!(rgb(&data, 5, 6), POINT_RGB);
        assert!((i32::from(rgb(&data, 19, 11)[0]) - 250).abs() <= 5);
    }
}
