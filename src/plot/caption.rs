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
    /// The picture's enlargement of the frame (`mm_per_px` is the frame's scale).
    pub zoom: u32,
}

/// Text height and line pitch in the band, pixels.
pub const FONT_PX: u32 = 18;
const LINE_PX: u32 = 24;
/// Band grey level and colour (the text and the bar are white on it).
pub const BAND_GREY: u8 = 32;
/// The band's colour.
pub const BAND_RGB: [u8; 3] = [BAND_GREY; 3];
/// Grey level of the scale bar and the text.
pub const BAR_GREY: u8 = 255;
/// Colour of the scale bar and the text.
pub const BAR_RGB: [u8; 3] = [BAR_GREY; 3];
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

/// `img` with the caption band under it ([`caption_band`]).
pub fn with_caption(img: &RgbImage, c: &Caption) -> Result<RgbImage, String> {
    let (w, h) = img.dimensions();
    let band = caption_band(w, c)?;
    let picture = img.as_raw();
    let mut buf = vec![0u8; picture.len() + 3 * band.grey.len()];
    let (top, bottom) = buf.split_at_mut(picture.len());
    top.copy_from_slice(picture);
    for (px, &g) in bottom.chunks_exact_mut(3).zip(&band.grey) {
        px.copy_from_slice(&[g; 3]);
    }
    RgbImage::from_raw(w, h + band.height, buf).ok_or_else(|| "caption buffer size".to_string())
}

/// A caption band: `height` rows of the picture's width, in grey levels
/// (everything in it is grey: the band, the white bar and the white text's
/// anti-aliasing over them), row by row.
#[derive(Debug, Clone, PartialEq)]
pub struct CaptionBand {
    /// The band's height, pixels.
    pub height: u32,
    /// Its grey levels, row by row, the picture's width each.
    pub grey: Vec<u8>,
}

/// The caption band of a picture `w` pixels wide: the texts on one line
/// when they fit, else one per line, then the scale bar (at most 40 % of
/// the width) right-aligned on a line of its own. Every text's ink lies
/// within the band (a test), so the band is drawn on its own.
pub fn caption_band(w: u32, c: &Caption) -> Result<CaptionBand, String> {
    super::draw::register_fonts();
    let font = ("sans-serif", FONT_PX).into_font();
    let items = texts(c);
    let one_line = items.join("  ·  ");
    // Plotters measures text without a backend through its font loader.
    let width = |s: &str| font.box_size(s).map_or(u32::MAX, |(w, _)| w);
    let lines = if width(&one_line) + 12 <= w {
        vec![one_line]
    } else {
        items
    };
    let bar = scale_bar(c.mm_per_px, c.zoom, 0.4 * f64::from(w));
    let height = 6 + LINE_PX * (lines.len() as u32 + u32::from(bar.is_some())) + 4;
    let mut grey = vec![BAND_GREY; (w * height) as usize];
    // Each text with the point plotters would draw it at.
    let mut y = 6;
    let mut placed = Vec::with_capacity(lines.len() + 1);
    for line in lines {
        placed.push((line, (6, y)));
        y += LINE_PX as i32;
    }
    if let Some((mm, px)) = bar {
        let x1 = w as i32 - 8;
        let x0 = x1 - px.round() as i32;
        let yb = y + (LINE_PX as i32 - BAR_THICK_PX as i32) / 2;
        // The rectangle from (x0, yb) to (x1, yb + BAR_THICK_PX − 1) as
        // plotters' bitmap backend fills it: its right column and bottom
        // row left out (a test).
        let cols = x0.clamp(0, w as i32) as usize..x1.clamp(0, w as i32) as usize;
        for row in yb.max(0)..(yb + BAR_THICK_PX as i32 - 1).min(height as i32) {
            let at = row as usize * w as usize;
            grey[at + cols.start..at + cols.end.max(cols.start)].fill(BAR_GREY);
        }
        let label = mm_text(mm);
        let lx = x0 - width(&label) as i32 - 8;
        placed.push((label, (lx.max(6), y)));
    }
    let glyphs = glyphs()?;
    for (text, at) in &placed {
        glyphs.draw_white(&mut grey, (w, height), text, at);
    }
    Ok(CaptionBand { height, grey })
}

/// One glyph of the caption's font as plotters' ab_glyph font draws it:
/// its ink (pixel offsets and coverage, the glyph's left bearing dropped as
/// plotters drops it) and its row offset.
struct Ink {
    rows_down: i32,
    coverage: Vec<(i32, i32, f32)>,
}

/// The caption's font (DejaVu Sans at [`FONT_PX`]) with the ink of its
/// common characters rasterised once. Plotters rasterises every glyph of
/// every text anew, most of a caption's cost (an animation captions ~50
/// frames a drop); this draws the same pixels from the stored ink: the
/// placement is plotters' `ab_glyph` font's (advances, kerning, the row
/// offset) and the blending its bitmap backend's (`draw_pixel`). A test
/// compares the two byte for byte.
struct Glyphs {
    font: ab_glyph::PxScaleFont<ab_glyph::FontRef<'static>>,
    ink: std::collections::HashMap<char, Ink>,
}

/// The characters whose ink is kept: printable ASCII and the caption's
/// symbols.
const KEPT_GLYPHS: &str = "·δ×−";

fn glyphs() -> Result<&'static Glyphs, String> {
    use ab_glyph::Font;
    static GLYPHS: std::sync::OnceLock<Option<Glyphs>> = std::sync::OnceLock::new();
    GLYPHS
        .get_or_init(|| {
            let font = ab_glyph::FontRef::try_from_slice(dejavu::sans::regular()).ok()?;
            let font = font.into_scaled(FONT_PX as f32);
            let ink = (' '..='~')
                .chain(KEPT_GLYPHS.chars())
                .map(|c| (c, ink_of(&font, c)))
                .collect();
            Some(Glyphs { font, ink })
        })
        .as_ref()
        .ok_or_else(|| "the embedded DejaVu Sans font could not be parsed".to_string())
}

/// The ink of `c` (see [`Ink`]).
fn ink_of(font: &ab_glyph::PxScaleFont<ab_glyph::FontRef<'static>>, c: char) -> Ink {
    use ab_glyph::ScaleFont;
    let Some(outline) = font.outline_glyph(font.scaled_glyph(c)) else {
        return Ink {
            rows_down: 0,
            coverage: Vec::new(),
        };
    };
    let rows_down = (FONT_PX as f32 / 2.0 + outline.px_bounds().min.y) as i32;
    let mut coverage = Vec::new();
    outline.draw(|x, y, a| {
        if a > 0.0 {
            coverage.push((x as i32, y as i32, a));
        }
    });
    Ink {
        rows_down,
        coverage,
    }
}

impl Glyphs {
    /// Draw `text` in white into `grey` (`size` pixels of grey levels)
    /// with its top left at `at`, as plotters' `draw_text` would in RGB.
    fn draw_white(&self, grey: &mut [u8], size: (u32, u32), text: &str, at: &(i32, i32)) {
        use ab_glyph::ScaleFont;
        let (w, h) = (size.0 as i32, size.1 as i32);
        let mut advance = 0f32;
        let mut prev = None;
        for c in text.chars() {
            let id = self.font.glyph_id(c);
            if let Some(p) = prev {
                advance += self.font.kern(p, id);
            }
            prev = Some(id);
            let computed;
            let ink = match self.ink.get(&c) {
                Some(ink) => ink,
                None => {
                    computed = ink_of(&self.font, c);
                    &computed
                }
            };
            let (dx, dy) = (at.0 + advance as i32, at.1 + ink.rows_down);
            for &(x, y, a) in &ink.coverage {
                let (x, y) = (x + dx, y + dy);
                if (0..w).contains(&x) && (0..h).contains(&y) {
                    let i = y as usize * size.0 as usize + x as usize;
                    blend_white(&mut grey[i], f64::from(a));
                }
            }
            advance += self.font.h_advance(id);
        }
    }
}

/// White drawn over grey level `v` at coverage `alpha`, in the integers of
/// plotters' bitmap backend (each channel alike): opaque from 255/256, else
/// `alpha` in 256ths.
fn blend_white(v: &mut u8, alpha: f64) {
    if alpha >= 1.0 - 1.0 / 256.0 {
        *v = 255;
    } else if alpha > 0.0 {
        let a = (alpha * 256.0).floor() as u64;
        *v += (u64::from(255 - *v) * a / 256) as u8;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_kept_glyphs_draw_the_pixels_plotters_draws() {
        super::super::register_fonts();
        let (w, h) = (420u32, 60u32);
        // A background of every grey, for the blending.
        let background: Vec<u8> = (0..w * h).map(|i| (i % 256) as u8).collect();
        let rgb = |grey: &[u8]| grey.iter().flat_map(|&g| [g; 3]).collect::<Vec<u8>>();
        let font = ("sans-serif", FONT_PX).into_font().color(&WHITE);
        for (text, at) in [
            ("frame -12  ·  t = -1.200 ms  ·  δ = -0.750 mm", (6, 10)),
            ("AVWa fi Ty 0.5 mm ×−", (-3, 40)),
            ("Ωжé€ outside the kept set", (100, 5)),
        ] {
            let mut by_plotters = rgb(&background);
            {
                let root = BitMapBackend::with_buffer(&mut by_plotters, (w, h)).into_drawing_area();
                root.draw_text(text, &font, at).unwrap();
                root.present().unwrap();
            }
            let mut kept = background.clone();
            glyphs().unwrap().draw_white(&mut kept, (w, h), text, &at);
            assert!(kept != background, "{text}: nothing drawn");
            assert!(rgb(&kept) == by_plotters, "{text}: pixels differ");
        }
    }

    #[test]
    fn every_kept_glyph_inks_below_the_band_top() {
        // A text line starts 6 rows into the band: its ink may rise at most
        // 6 rows above it, or it would fall on the picture.
        let glyphs = glyphs().unwrap();
        for (c, ink) in &glyphs.ink {
            let top = ink.coverage.iter().map(|&(_, y, _)| y).min().unwrap_or(0);
            assert!(ink.rows_down + top >= -6, "{c:?}: {}", ink.rows_down + top);
        }
    }

    /// `img` with its caption band as plotters drew it before the band was
    /// drawn on its own in grey: the band filled, the bar a plotters
    /// rectangle, the texts plotters' (on the picture, had they reached it).
    fn with_caption_by_plotters(img: &RgbImage, c: &Caption) -> RgbImage {
        super::super::register_fonts();
        let (w, h) = img.dimensions();
        let font = ("sans-serif", FONT_PX).into_font().color(&WHITE);
        let items = texts(c);
        let one_line = items.join("  ·  ");
        let width = |s: &str| font.font.box_size(s).map_or(u32::MAX, |(w, _)| w);
        let lines = if width(&one_line) + 12 <= w {
            vec![one_line]
        } else {
            items
        };
        let bar = scale_bar(c.mm_per_px, c.zoom, 0.4 * f64::from(w));
        let band = 6 + LINE_PX * (lines.len() as u32 + u32::from(bar.is_some())) + 4;
        let mut buf = img.as_raw().clone();
        buf.extend(std::iter::repeat_n(BAND_RGB, (w * band) as usize).flatten());
        let root = BitMapBackend::with_buffer(&mut buf, (w, h + band)).into_drawing_area();
        let mut y = h as i32 + 6;
        for line in lines {
            root.draw_text(&line, &font, (6, y)).unwrap();
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
            .unwrap();
            let label = mm_text(mm);
            let lx = x0 - width(&label) as i32 - 8;
            root.draw_text(&label, &font, (lx.max(6), y)).unwrap();
        }
        root.present().unwrap();
        drop(root);
        RgbImage::from_raw(w, h + band, buf).unwrap()
    }

    #[test]
    fn the_band_drawn_in_grey_is_the_pixels_plotters_draws() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(18);
        let caption = |frame, t_s, delta_mm, mm_per_px, zoom| Caption {
            frame,
            t_s,
            delta_mm,
            mm_per_px,
            zoom,
        };
        let cases = [
            caption(-12, -0.0012, Some(-0.75), 0.04, 3),
            caption(4187, 0.41876, Some(1.234), 0.0437, 1),
            caption(0, 0.0, None, 0.02, 1),
            caption(-3, f64::INFINITY, Some(f64::NAN), f64::NAN, 1),
            caption(1_000_000, -1e6, Some(-12345.678), 0.5, 2),
        ];
        for (w, h) in [
            (500, 40),
            (175, 199),
            (150, 30),
            (60, 12),
            (9, 3),
            (1000, 2),
        ] {
            // A picture of coloured noise, on which any text would show.
            let img = RgbImage::from_fn(w, h, |_, _| image::Rgb(rng.gen()));
            for c in &cases {
                let want = with_caption_by_plotters(&img, c);
                let got = with_caption(&img, c).unwrap();
                assert!(got == want, "{w} × {h}, {c:?}");
                let band = caption_band(w, c).unwrap();
                assert_eq!(band.height, want.height() - h);
            }
        }
    }

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
