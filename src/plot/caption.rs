//! The caption band under an overlay picture: which frame it is (camera
//! image number and time after the trigger), the penetration δ at that
//! frame, and a scale bar of a round length in millimetres, drawn with the
//! embedded DejaVu Sans so that no system font is needed.

use image::RgbImage;
use plotters::prelude::*;

/// What the caption says of one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Caption {
    /// Camera image number.
    pub frame: i64,
    /// Time after the trigger, seconds.
    pub t_s: f64,
    /// Penetration at this frame (negative: above the surface), mm.
    pub delta_mm: Option<f64>,
    /// Scale of the frame, and the picture's enlargement of it.
    pub mm_per_px: f64,
    pub zoom: u32,
}

/// Text height and line pitch in the band, pixels.
pub const FONT_PX: u32 = 18;
const LINE_PX: u32 = 24;
/// Band colour (the text and the bar are white on it).
pub const BAND_RGB: [u8; 3] = [32, 32, 32];
pub const BAR_RGB: [u8; 3] = [255, 255, 255];
/// Thickness of the scale bar, pixels.
pub const BAR_THICK_PX: u32 = 4;

/// The longest of 1, 2, 5 × 10^k mm (k from −2 to 2) whose bar is at most
/// `max_px` long, with its length in picture pixels.
pub fn scale_bar(mm_per_px: f64, zoom: u32, max_px: f64) -> Option<(f64, f64)> {
    let px_per_mm = f64::from(zoom.max(1)) / mm_per_px;
    if !(px_per_mm.is_finite() && px_per_mm > 0.0) {
        return None;
    }
    (-2..=2)
        .flat_map(|k| [1.0, 2.0, 5.0].map(|m| m * 10f64.powi(k)))
        .map(|mm| (mm, mm * px_per_mm))
        .rfind(|&(_, px)| px <= max_px && px >= 8.0)
}

/// A length in mm as a person writes it: "0.5 mm", "2 mm".
fn mm_text(mm: f64) -> String {
    let s = format!("{mm:.2}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    format!("{s} mm")
}

/// The caption's texts: frame, time, δ.
pub fn texts(c: &Caption) -> Vec<String> {
    let mut t = vec![
        format!("frame {}", c.frame),
        format!("t = {:.3} ms", c.t_s * 1e3),
    ];
    if let Some(d) = c.delta_mm {
        t.push(format!("δ = {d:.3} mm"));
    }
    t
}

/// `img` with the caption band under it: the texts on one line when they
/// fit, else one per line, then the scale bar (at most 40 % of the width)
/// right-aligned on a line of its own.
pub fn with_caption(img: &RgbImage, c: &Caption) -> Result<RgbImage, String> {
    super::register_fonts();
    let (w, h) = img.dimensions();
    let font = ("sans-serif", FONT_PX).into_font().color(&WHITE);
    let items = texts(c);
    let one_line = items.join("  ·  ");
    // Plotters measures text without a backend through its font loader.
    let width = |s: &str| font.font.box_size(s).map_or(u32::MAX, |(w, _)| w);
    let lines = if width(&one_line) + 12 <= w {
        vec![one_line]
    } else {
        items
    };
    let bar = scale_bar(c.mm_per_px, c.zoom, 0.4 * f64::from(w));
    let band = 6 + LINE_PX * (lines.len() as u32 + u32::from(bar.is_some())) + 4;
    let mut buf = Vec::with_capacity((w * (h + band) * 3) as usize);
    buf.extend_from_slice(img.as_raw());
    buf.resize(buf.len() + (w * band * 3) as usize, 0);
    for px in buf[img.as_raw().len()..].chunks_exact_mut(3) {
        px.copy_from_slice(&BAND_RGB);
    }
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h + band)).into_drawing_area();
        let err = |e: DrawingAreaErrorKind<_>| e.to_string();
        let mut y = h as i32 + 6;
        for line in &lines {
            root.draw_text(line, &font, (6, y)).map_err(err)?;
            y += LINE_PX as i32;
        }
        if let Some((mm, px)) = bar {
            let x1 = w as i32 - 8;
            let x0 = x1 - px.round() as i32;
            let yb = y + (LINE_PX as i32 - BAR_THICK_PX as i32) / 2;
            let white = RGBColor(BAR_RGB[0], BAR_RGB[1], BAR_RGB[2]);
            root.draw(&Rectangle::new(
                [(x0, yb), (x1, yb + BAR_THICK_PX as i32 - 1)],
                white.filled(),
            ))
            .map_err(err)?;
            let label = mm_text(mm);
            let lx = x0 - width(&label) as i32 - 8;
            root.draw_text(&label, &font, (lx.max(6), y)).map_err(err)?;
        }
        root.present().map_err(err)?;
    }
    RgbImage::from_raw(w, h + band, buf).ok_or_else(|| "caption buffer size".to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scale_bar_is_a_round_length_that_fits() {
        // 0.04 mm/px at zoom 3: 75 px per mm; at most 200 px: 2 mm = 150 px.
        assert_eq!(scale_bar(0.04, 3, 200.0), Some((2.0, 150.0)));
        // A coarse scale: 0.5 mm/px at zoom 1 → 2 px per mm; within 90 px: 20 mm.
        let (mm, px) = scale_bar(0.5, 1, 90.0).unwrap();
        assert_eq!(mm, 20.0);
        assert!((px - 40.0).abs() < 1e-9);
        assert_eq!(scale_bar(f64::NAN, 3, 200.0), None);
        assert_eq!(mm_text(0.5), "0.5 mm");
        assert_eq!(mm_text(2.0), "2 mm");
    }

    #[test]
    fn the_band_holds_the_texts_and_a_bar_of_the_stated_length() {
        let img = RgbImage::from_pixel(500, 400, image::Rgb([200, 200, 200]));
        let c = Caption {
            frame: -12,
            t_s: -0.0012,
            delta_mm: Some(-0.75),
            mm_per_px: 0.04,
            zoom: 3,
        };
        assert_eq!(texts(&c), ["frame -12", "t = -1.200 ms", "δ = -0.750 mm"]);
        let out = with_caption(&img, &c).unwrap();
        let (w, h) = out.dimensions();
        assert_eq!(w, 500);
        // One line of text (it fits in 500 px) and the bar's line.
        assert_eq!(h, 400 + 6 + 2 * LINE_PX + 4);
        // The picture is untouched.
        assert_eq!(out.get_pixel(10, 10).0, [200, 200, 200]);
        // The bar: 2 mm = 150 px (at most 40 % of 500), 8 px from the right edge.
        let y = 400 + 6 + LINE_PX + LINE_PX / 2;
        let white: Vec<u32> = (0..w)
            .filter(|&x| out.get_pixel(x, y).0 == BAR_RGB)
            .collect();
        let bar: Vec<u32> = white.iter().copied().filter(|&x| x > 250).collect();
        assert_eq!(bar.len(), 150, "{white:?}");
        assert_eq!(*bar.last().unwrap(), 500 - 9);
        // Text drawn on the first line (white-ish pixels on the band).
        let text_px = (0..w)
            .flat_map(|x| (406..406 + LINE_PX).map(move |y| (x, y)))
            .filter(|&(x, y)| out.get_pixel(x, y).0[0] > 128)
            .count();
        assert!(text_px > 100, "{text_px}");
        // A narrow picture puts one text per line.
        let narrow = with_caption(&RgbImage::new(150, 100), &c).unwrap();
        assert_eq!(narrow.height(), 100 + 6 + 4 * LINE_PX + 4);
    }
}
