//! An overlay picture of one frame's detection — the frame, the edge points,
//! the fitted circle and the surface line — so a person can check it by eye.
//!
//! Pure: returns an RGB image (and PNG bytes with [`encode_png`]), or the
//! same drawing in the animated impact's palette ([`Scene::indexed`],
//! [`encode_indexed_apng`]); the caller writes it (`io_util::write_atomic`).
//! A crop can be enlarged by an integer `zoom` so that sub-pixel placement
//! is visible: frame point
//! `(x, z)` lands at overlay pixel `((x − x0 + ½)·zoom, (z − z0 + ½)·zoom)`,
//! i.e. frame pixel `(i, j)` becomes the `zoom × zoom` block whose centre is
//! the pixel's centre.

use image::RgbImage;

use crate::detect::{Band, Circle, EdgePoint, SurfaceLine};

/// Colours: fitted circle, edge points, surface line.
pub const CIRCLE_RGB: [u8; 3] = [255, 40, 40];
/// Colour of the edge points.
pub const POINT_RGB: [u8; 3] = [40, 255, 40];
/// Colour of the surface line.
pub const SURFACE_RGB: [u8; 3] = [60, 140, 255];

/// Which part of the frame to draw and how large.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OverlayView {
    /// First column and row of the crop (frame pixels).
    pub x0: usize,
    /// First row of the crop (frame pixels); `x0` is its first column.
    pub z0: usize,
    /// Crop size (frame pixels).
    pub width: usize,
    /// Crop height (frame pixels); `width` is its width.
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

/// What the detection draws over a frame. Each has its colour and, after
/// the greys, its index in the animation's palette.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mark {
    /// The fitted circle.
    Circle,
    /// An edge point used by the fit.
    Point,
    /// The surface line.
    Surface,
}

impl Mark {
    /// Every mark, in the palette's order.
    pub const ALL: [Mark; 3] = [Mark::Circle, Mark::Point, Mark::Surface];

    /// Its colour in an RGB overlay.
    pub const fn rgb(self) -> [u8; 3] {
        match self {
            Mark::Circle => CIRCLE_RGB,
            Mark::Point => POINT_RGB,
            Mark::Surface => SURFACE_RGB,
        }
    }

    /// Its index in the animation's palette (after the `GREYS` greys).
    pub const fn index(self) -> u8 {
        GREYS as u8 + self as u8
    }
}

/// Draw the crop of `band` (grey, `bit_depth` significant bits scaled to 8)
/// with the detection on top ([`Scene::rgb`]).
pub fn overlay(
    band: &Band,
    bit_depth: u8,
    view: &OverlayView,
    points: &[EdgePoint],
    circle: Option<&Circle>,
    surface: Option<&SurfaceLine>,
) -> RgbImage {
    Scene {
        band,
        bit_depth,
        view,
        points,
        circle,
        surface,
    }
    .rgb()
}

impl OverlayView {
    /// The overlay's width and height, pixels.
    pub fn size_px(&self) -> (usize, usize) {
        let zoom = self.zoom.max(1) as usize;
        (self.width * zoom, self.height * zoom)
    }
}

/// What an overlay shows: the crop `view` of `band` (grey, `bit_depth`
/// significant bits scaled to 8) with the detection on top.
#[derive(Debug, Clone, Copy)]
pub struct Scene<'a> {
    /// The rows of the frame drawn.
    pub band: &'a Band<'a>,
    /// Significant bits of the band's samples.
    pub bit_depth: u8,
    /// The crop and its enlargement.
    pub view: &'a OverlayView,
    /// The edge points to mark.
    pub points: &'a [EdgePoint],
    /// The fitted circle, when there is one.
    pub circle: Option<&'a Circle>,
    /// The surface line, when there is one.
    pub surface: Option<&'a SurfaceLine>,
}

impl Scene<'_> {
    /// The overlay in RGB: the frame's greys, the marks' colours.
    pub fn rgb(&self) -> RgbImage {
        let (w, h) = self.view.size_px();
        let mut pixels = vec![0u8; w * h * 3];
        self.draw(&mut pixels, |grey| grey, Mark::rgb);
        RgbImage::from_raw(w as u32, h as u32, pixels).expect("w × h × 3 bytes")
    }

    /// The overlay drawn straight in the animation's palette, with rows of
    /// grey levels `below` it (the caption band, as wide as the overlay):
    /// the indices the RGB overlay with those rows under it has in the
    /// palette (a test), from a third of the bytes and no pixel converted.
    /// A partial last row of `below` is left out.
    pub fn indexed(&self, below: &[u8]) -> IndexedFrame {
        let (w, h) = self.view.size_px();
        let below = &below[..below.len() / w.max(1) * w];
        // Black, where the band has no row, is index 0.
        let mut data = vec![GREY_INDEX[0]; w * h + below.len()];
        let (picture, caption) = data.split_at_mut(w * h);
        self.draw(
            picture,
            |grey| GREY_INDEX[usize::from(grey)],
            |m| [m.index()],
        );
        for (o, &grey) in caption.iter_mut().zip(below) {
            *o = GREY_INDEX[usize::from(grey)];
        }
        IndexedFrame {
            width: w as u32,
            height: (h + below.len() / w.max(1)) as u32,
            data,
        }
    }

    /// The overlay drawn into `pixels` (`N` bytes a pixel, row by row, the
    /// view's size, black): a frame pixel of grey level `g` (0 to 255) is
    /// `level(g)` in each of its bytes, a mark `mark(m)`. The one drawing
    /// of both the RGB overlay and the palette's.
    fn draw<const N: usize>(
        &self,
        pixels: &mut [u8],
        level: impl Fn(u8) -> u8,
        mark: impl Fn(Mark) -> [u8; N],
    ) {
        let Scene {
            band,
            view,
            points,
            circle,
            surface,
            ..
        } = *self;
        let zoom = view.zoom.max(1);
        let (w, h) = view.size_px();
        let shift = self.bit_depth.saturating_sub(8);
        // Row by row: the crop's columns of a frame row, each repeated `zoom`
        // times across and the row `zoom` times down (black outside the band).
        let row_bytes = w * N;
        let z = zoom as usize;
        for (k, out) in pixels.chunks_exact_mut(row_bytes * z).enumerate() {
            let i = view.z0 + k;
            if i < band.row0 || i >= band.row0 + band.nrows {
                continue;
            }
            let cols = view.width.min(band.width.saturating_sub(view.x0));
            let row = &band.data[(i - band.row0) * band.width..][..band.width];
            let (first, rest) = out.split_at_mut(row_bytes);
            let grey = |v: u16| level((v >> shift).min(255) as u8);
            let row = row[view.x0.min(band.width)..][..cols].iter();
            // A pixel's `zoom` copies across are its level in every byte.
            if N * z == 1 {
                for (&v, px) in row.zip(first.iter_mut()) {
                    *px = grey(v);
                }
            } else {
                for (&v, block) in row.zip(first.chunks_exact_mut(N * z)) {
                    block.fill(grey(v));
                }
            }
            for copy in rest.chunks_exact_mut(row_bytes) {
                copy.copy_from_slice(first);
            }
        }
        let to_img = |x: f64, z: f64| -> (f64, f64) {
            (
                (x - view.x0 as f64 + 0.5) * zoom as f64,
                (z - view.z0 as f64 + 0.5) * zoom as f64,
            )
        };
        let put = |pixels: &mut [u8], u: f64, v: f64, m: Mark| {
            if u >= 0.0 && v >= 0.0 && (u as usize) < w && (v as usize) < h {
                let at = (v as usize * w + u as usize) * N;
                pixels[at..at + N].copy_from_slice(&mark(m));
            }
        };
        if let Some(s) = surface {
            let steps = w * 2;
            for k in 0..=steps {
                let x = view.x0 as f64 - 0.5 + view.width as f64 * k as f64 / steps as f64;
                let (u, v) = to_img(x, s.row_at(x));
                put(pixels, u, v, Mark::Surface);
            }
        }
        if let Some(c) = circle {
            let steps = ((std::f64::consts::TAU * c.r_px * zoom as f64) * 2.0).ceil() as usize + 8;
            for k in 0..steps {
                let t = std::f64::consts::TAU * k as f64 / steps as f64;
                let (u, v) = to_img(c.x_px + c.r_px * t.cos(), c.z_px + c.r_px * t.sin());
                put(pixels, u, v, Mark::Circle);
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
            let apart = 3.0 * r;
            if shown
                .iter()
                .any(|&(su, sv)| (su - u).powi(2) + (sv - v).powi(2) < apart * apart)
            {
                continue;
            }
            shown.push((u, v));
            for dv in -reach..=reach {
                for du in -reach..=reach {
                    let (pu, pv) = (u.floor() + du as f64, v.floor() + dv as f64);
                    if (pu + 0.5 - u).powi(2) + (pv + 0.5 - v).powi(2) <= r * r {
                        put(pixels, pu, pv, Mark::Point);
                    }
                }
            }
        }
    }
}

/// PNG bytes of an overlay ([`crate::plot::rgb_png`]).
pub fn encode_png(img: &RgbImage) -> Result<Vec<u8>, image::ImageError> {
    crate::plot::rgb_png(img.as_raw(), img.width(), img.height())
}

/// Grey levels of the animation's palette; the colours of the drawing follow.
const GREYS: usize = 32;

/// The animation's palette: [`GREYS`] greys from black to white, then the
/// marks' colours ([`Mark::index`]).
fn palette() -> Vec<u8> {
    let mut p: Vec<u8> = (0..GREYS)
        .flat_map(|i| [((i * 255 + (GREYS - 1) / 2) / (GREYS - 1)) as u8; 3])
        .collect();
    for m in Mark::ALL {
        p.extend_from_slice(&m.rgb());
    }
    p
}

/// The palette index of the grey nearest to a pixel whose channels sum to
/// `sum`: round(mean · (GREYS − 1) / 255) in integers (no sum lies on a tie).
const fn grey_index(sum: u32) -> u8 {
    ((2 * sum * (GREYS as u32 - 1) + 765) / 1530) as u8
}

/// The palette index of each grey level, 0 to 255 ([`grey_index`] of three
/// equal channels): the animation's frame pixels and its caption band.
const GREY_INDEX: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut g = 0;
    while g < 256 {
        t[g] = grey_index(3 * g as u32);
        g += 1;
    }
    t
};

/// One frame of an animation in the animation's palette (see
/// [`Scene::indexed`]): `width × height` indices, row by row.
pub struct IndexedFrame {
    /// Width of the frame, px.
    pub width: u32,
    /// Height of the frame, px.
    pub height: u32,
    /// Palette indices, `width × height`, row by row.
    pub data: Vec<u8>,
}

/// An RGB overlay in the animation's palette, pixel by pixel: a mark's
/// colour its own index, any other pixel the grey nearest to its channels'
/// mean. [`Scene::indexed`] is held to it.
#[cfg(test)]
pub fn to_indexed(img: &RgbImage) -> IndexedFrame {
    let index = |p: &[u8]| {
        Mark::ALL.into_iter().find(|m| m.rgb() == p).map_or_else(
            || grey_index(p.iter().map(|&c| u32::from(c)).sum()),
            Mark::index,
        )
    };
    IndexedFrame {
        width: img.width(),
        height: img.height(),
        data: img.as_raw().chunks_exact(3).map(index).collect(),
    }
}

/// Animated-PNG bytes of `frames` (shown `frame_ms` each, looping), in
/// the animation's palette (8-bit indices, a third of RGB's bytes). Frames
/// of different sizes are padded at the right and bottom with the first
/// frame's last pixel's colour. Rows are filtered by their left neighbour ("Sub"): with the fast deflate it is 0.67× the CPU
/// time of the adaptive choice for 3 % more bytes (`cargo run --release
/// --example apng_encode`).
///
/// The frames are compressed each on its own, on every thread: APNG
/// compresses each frame's data stream separately, so the streams are
/// made as the `png` crate's writer makes them (its filter, its fast
/// deflate, stored where that is smaller; `frame_stream`) and the chunks
/// written in order through it: the same bytes as that writer fed the
/// frames one after the other (a test), which left an animation's
/// compression, a twelfth of a short drop's CPU, on one thread.
pub fn encode_indexed_apng(
    frames: &[IndexedFrame],
    frame_ms: u16,
) -> Result<Vec<u8>, png::EncodingError> {
    use rayon::prelude::*;
    let (w, h, fill) = animation_canvas(frames);
    let streams = frames
        .par_iter()
        .map(|f| frame_stream(&padded(f, w, h, fill), w as usize))
        .collect::<Result<Vec<Vec<u8>>, _>>()?;
    let mut out = Vec::new();
    {
        let mut writer = animation_encoder(&mut out, w, h, frames.len(), frame_ms)?;
        let mut sequence = 0u32;
        for (i, stream) in streams.iter().enumerate() {
            let control = png::FrameControl {
                sequence_number: sequence,
                width: w,
                height: h,
                delay_num: frame_ms,
                delay_den: 1000,
                ..png::FrameControl::default()
            };
            writer.write_chunk(png::chunk::fcTL, &frame_control_data(&control))?;
            sequence += 1;
            if i == 0 {
                writer.write_chunk(png::chunk::IDAT, stream)?;
            } else {
                let mut data = Vec::with_capacity(4 + stream.len());
                data.extend_from_slice(&sequence.to_be_bytes());
                data.extend_from_slice(stream);
                writer.write_chunk(png::chunk::fdAT, &data)?;
                sequence += 1;
            }
        }
        writer.finish()?;
    }
    Ok(out)
}

/// An animation's size (its largest frame's) and the colour its smaller
/// frames are padded with (the first frame's last pixel's).
fn animation_canvas(frames: &[IndexedFrame]) -> (u32, u32, u8) {
    let w = frames.iter().map(|f| f.width).max().unwrap_or(1);
    let h = frames.iter().map(|f| f.height).max().unwrap_or(1);
    let fill = frames
        .first()
        .and_then(|f| f.data.last().copied())
        .unwrap_or(0);
    (w, h, fill)
}

/// `f`'s indices on a `w × h` canvas, padded at the right and bottom with
/// `fill` when smaller.
fn padded(f: &IndexedFrame, w: u32, h: u32, fill: u8) -> std::borrow::Cow<'_, [u8]> {
    if (f.width, f.height) == (w, h) {
        return std::borrow::Cow::Borrowed(&f.data);
    }
    let mut padded = vec![fill; (w * h) as usize];
    for (row, src) in padded
        .chunks_exact_mut(w as usize)
        .zip(f.data.chunks_exact(f.width.max(1) as usize))
    {
        row[..src.len()].copy_from_slice(src);
    }
    std::borrow::Cow::Owned(padded)
}

/// The writer of an animation of `frames` frames, `w × h`, each shown
/// `frame_ms`, looping, in the palette, with its header written.
fn animation_encoder(
    out: &mut Vec<u8>,
    w: u32,
    h: u32,
    frames: usize,
    frame_ms: u16,
) -> Result<png::Writer<&mut Vec<u8>>, png::EncodingError> {
    let mut enc = png::Encoder::new(out, w, h);
    enc.set_color(png::ColorType::Indexed);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_palette(palette());
    enc.set_compression(png::Compression::Fast);
    enc.set_filter(png::Filter::Sub);
    enc.set_animated(frames as u32, 0)?;
    enc.set_frame_delay(frame_ms, 1000)?;
    // The frames' chunks are written here, not by the writer, which
    // would otherwise count them.
    enc.validate_sequence(false);
    enc.write_header()
}

/// The data of an `fcTL` chunk.
fn frame_control_data(c: &png::FrameControl) -> [u8; 26] {
    let mut data = [0u8; 26];
    data[..4].copy_from_slice(&c.sequence_number.to_be_bytes());
    data[4..8].copy_from_slice(&c.width.to_be_bytes());
    data[8..12].copy_from_slice(&c.height.to_be_bytes());
    data[12..16].copy_from_slice(&c.x_offset.to_be_bytes());
    data[16..20].copy_from_slice(&c.y_offset.to_be_bytes());
    data[20..22].copy_from_slice(&c.delay_num.to_be_bytes());
    data[22..24].copy_from_slice(&c.delay_den.to_be_bytes());
    data[24] = c.dispose_op as u8;
    data[25] = c.blend_op as u8;
    data
}

/// The zlib stream of one frame of 8-bit indices, `width` a row, as the
/// `png` crate's writer makes it with `Filter::Sub` and
/// `Compression::Fast`: each row led by its filter type (1) and each byte
/// less its left neighbour, through `fdeflate`; stored blocks when those
/// are smaller.
fn frame_stream(data: &[u8], width: usize) -> Result<Vec<u8>, png::EncodingError> {
    const SUB: u8 = 1;
    let mut compressor = fdeflate::Compressor::new(std::io::Cursor::new(Vec::new()))?;
    let mut row = vec![0u8; width + 1];
    row[0] = SUB;
    for line in data.chunks(width.max(1)) {
        row[1] = line[0];
        for (o, pair) in row[2..].iter_mut().zip(line.windows(2)) {
            *o = pair[1].wrapping_sub(pair[0]);
        }
        compressor.write_data(&row[..line.len() + 1])?;
    }
    let compressed = compressor.finish()?.into_inner();
    let rows = data.len() / width.max(1);
    if compressed.len() <= fdeflate::StoredOnlyCompressor::<()>::compressed_size((width + 1) * rows)
    {
        return Ok(compressed);
    }
    let mut stored = fdeflate::StoredOnlyCompressor::new(std::io::Cursor::new(Vec::new()))?;
    for line in data.chunks(width.max(1)) {
        stored.write_data(&[0])?;
        stored.write_data(line)?;
    }
    Ok(stored.finish()?.into_inner())
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
        let line = SurfaceLine::given(50.0, 0.0);
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
    fn the_palette_grey_is_the_nearest_to_the_channels_mean() {
        for sum in 0..=765u32 {
            let mean = f64::from(sum) / 3.0;
            let nearest = (mean * (GREYS - 1) as f64 / 255.0).round() as u8;
            assert_eq!(grey_index(sum), nearest, "sum {sum}");
        }
        for g in 0..=255u8 {
            assert_eq!(GREY_INDEX[usize::from(g)], grey_index(3 * u32::from(g)));
        }
        let index = |rgb: [u8; 3]| to_indexed(&RgbImage::from_pixel(1, 1, image::Rgb(rgb))).data[0];
        assert_eq!(index([90, 90, 90]), 11);
        // Not a drawing colour: the grey of its mean, 85 → 10.
        assert_eq!(index([255, 0, 0]), 10);
        assert_eq!(index(SURFACE_RGB), GREYS as u8 + 2);
        // The palette holds each mark's colour at its index.
        let p = palette();
        for m in Mark::ALL {
            let i = 3 * usize::from(m.index());
            assert_eq!(p[i..i + 3], m.rgb());
        }
        assert_eq!(p.len(), 3 * (GREYS + 3));
    }

    #[test]
    fn a_crop_past_the_band_is_black_and_each_pixel_a_zoom_block() {
        // Rows 5..15 of a 12-bit frame whose pixel (i, j) is 16 · (10 i + j).
        let frame = Frame::from_shape_fn((10, 12), |(i, j)| (16 * (10 * (i + 5) + j)) as u16);
        let band = Band {
            data: frame.as_slice().unwrap(),
            row0: 5,
            nrows: 10,
            width: 12,
            cols: (0, 12),
        };
        let view = OverlayView {
            x0: 9,
            z0: 3,
            width: 5,
            height: 14,
            zoom: 2,
        };
        let img = overlay(&band, 12, &view, &[], None, None);
        assert_eq!(img.dimensions(), (10, 28));
        for (u, v, px) in img.enumerate_pixels() {
            let (i, j) = (3 + v as usize / 2, 9 + u as usize / 2);
            let want = if (5..15).contains(&i) && j < 12 {
                (10 * i + j) as u8
            } else {
                0
            };
            assert_eq!(px.0, [want; 3], "pixel ({u}, {v}), frame ({j}, {i})");
        }
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

    /// The `png` crate's writer fed the frames one after the other, as
    /// [`encode_indexed_apng`] did before it compressed them on every
    /// thread.
    fn apng_one_frame_after_the_other(frames: &[IndexedFrame], frame_ms: u16) -> Vec<u8> {
        let (w, h, fill) = animation_canvas(frames);
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, w, h);
        enc.set_color(png::ColorType::Indexed);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_palette(palette());
        enc.set_compression(png::Compression::Fast);
        enc.set_filter(png::Filter::Sub);
        enc.set_animated(frames.len() as u32, 0).unwrap();
        enc.set_frame_delay(frame_ms, 1000).unwrap();
        let mut writer = enc.write_header().unwrap();
        for f in frames {
            writer.write_image_data(&padded(f, w, h, fill)).unwrap();
        }
        writer.finish().unwrap();
        out
    }

    #[test]
    fn frames_compressed_on_every_thread_are_the_bytes_of_the_png_writer() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(16);
        // Noisy greys with a drawn disc (fast deflate), pure noise over the
        // whole palette (stored blocks are smaller), a flat frame, frames of
        // other sizes (padded), one frame, one row, one column.
        let frame = |w: u32, h: u32, kind: u8, rng: &mut rand_chacha::ChaCha8Rng| {
            let data = (0..w * h)
                .map(|i| match kind {
                    0 => {
                        let (x, z) = ((i % w) as f64 - 20.0, (i / w) as f64 - 15.0);
                        if x.hypot(z) < 9.0 {
                            Mark::Circle.index()
                        } else {
                            GREY_INDEX[rng.gen_range(120..128usize)]
                        }
                    }
                    1 => rng.gen(),
                    _ => 7,
                })
                .collect();
            IndexedFrame {
                width: w,
                height: h,
                data,
            }
        };
        let cases: Vec<Vec<IndexedFrame>> = vec![
            (0..12).map(|k| frame(48, 36, k % 3, &mut rng)).collect(),
            vec![
                frame(48, 36, 0, &mut rng),
                frame(40, 30, 1, &mut rng),
                frame(48, 20, 0, &mut rng),
            ],
            vec![frame(31, 17, 0, &mut rng)],
            vec![frame(1, 9, 1, &mut rng), frame(1, 9, 0, &mut rng)],
            vec![frame(64, 1, 1, &mut rng), frame(64, 1, 2, &mut rng)],
        ];
        for (k, frames) in cases.iter().enumerate() {
            let threads = |n| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .unwrap()
                    .install(|| encode_indexed_apng(frames, 80).unwrap())
            };
            let reference = apng_one_frame_after_the_other(frames, 80);
            assert!(threads(1) == reference, "case {k}: 1 thread");
            assert!(threads(3) == reference, "case {k}: 3 threads");
        }
    }

    #[test]
    fn the_animation_has_every_frame_and_the_drawing_colours_exact() {
        use image::Rgb;
        let mut a = RgbImage::from_pixel(20, 10, Rgb([128, 128, 128]));
        a.put_pixel(3, 4, Rgb(CIRCLE_RGB));
        let mut b = RgbImage::from_pixel(20, 12, Rgb([250, 250, 250]));
        b.put_pixel(5, 6, Rgb(POINT_RGB));
        let frames = [&a, &b, &b].map(to_indexed);
        let bytes = encode_indexed_apng(&frames, 80).unwrap();
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
        // The shorter first frame padded below with its last pixel's grey.
        assert_eq!(rgb(&data, 19, 11), rgb(&data, 0, 0));
        assert_eq!(rgb(&data, 0, 10), rgb(&data, 0, 0));
        reader.next_frame(&mut data).unwrap();
        assert_eq!(rgb(&data, 5, 6), POINT_RGB);
        assert!((i32::from(rgb(&data, 19, 11)[0]) - 250).abs() <= 5);
    }
}
