//! The drawing kit shared by every figure: one description drawn twice, as
//! SVG (text left to the viewer's sans-serif) and as PNG (text rasterised
//! from the embedded DejaVu Sans, so no system font is needed); the font,
//! tick labels, hover targets and the PNG encoding.

use plotters::coord::Shift;
use plotters::prelude::*;
use std::sync::Once;

use super::error::PlotError;

/// The error type of the drawing functions (plotters' errors, boxed).
pub(crate) type DrawResult = Result<(), Box<dyn std::error::Error>>;

/// A plotters backend whose errors box into [`DrawResult`] (every backend
/// dropscope draws on: SVG and bitmap).
pub(crate) trait Backend: DrawingBackend<ErrorType = Self::Error> {
    type Error: std::error::Error + Send + Sync + 'static;
}

impl<B: DrawingBackend> Backend for B
where
    B::ErrorType: 'static,
{
    type Error = B::ErrorType;
}

/// A chart's coordinates: data (x, y) in f64 to pixels.
pub(crate) trait Plane: CoordTranslate<From = (f64, f64)> {}

impl<C: CoordTranslate<From = (f64, f64)>> Plane for C {}

/// Light grid lines between two labelled ones. Plotters draws up to 10,
/// which on a linear axis is a graph-paper grey behind the points and a
/// third of a figure's SVG bytes.
pub(crate) const LIGHT_LINES: usize = 4;

/// Font sizes (plotters' units; an SVG's font-size is 1/1.24 of them),
/// chosen so that a 1100 px figure shown 650 px wide, two to a row in the
/// report at a 1400 px window, keeps its tick labels at 11 px or more.
pub(crate) const TICK_FONT: u32 = 26;
/// Axis titles.
pub(crate) const DESC_FONT: u32 = 28;
/// Legends, guide labels and notes on a figure.
pub(crate) const LEGEND_FONT: u32 = 24;

thread_local! {
    /// Hover targets of the SVG being drawn: pixel position and text.
    static HOVER: std::cell::RefCell<Option<Vec<(i32, i32, String)>>> =
        const { std::cell::RefCell::new(None) };
}

/// Give the point drawn at pixel (x, y) a hover text (an SVG `<title>`);
/// does nothing while the PNG is drawn.
pub(crate) fn hover(x: i32, y: i32, text: String) {
    HOVER.with(|h| {
        if let Some(v) = h.borrow_mut().as_mut() {
            v.push((x, y, text));
        }
    });
}

/// `svg` with one invisible circle per hover target, each holding its text
/// as `<title>` (shown by every browser on hover), on top of the drawing.
/// Written into `svg` itself: a copy of a long movie's figure (10.7 MB for
/// 124 166 frames) was, grown by doubling, 21 MB.
fn with_hover(mut svg: String, targets: &[(i32, i32, String)]) -> String {
    let Some(end) = svg.rfind("</svg>") else {
        return svg;
    };
    let tail = svg.split_off(end);
    svg.reserve_exact(tail.len() + 40 + targets.len() * 120);
    svg.push_str("<g fill=\"#000\" fill-opacity=\"0\">");
    for (x, y, text) in targets {
        let text = text
            .replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;");
        svg.push_str(&format!(
            "<circle cx=\"{x}\" cy=\"{y}\" r=\"9\"><title>{text}</title></circle>"
        ));
    }
    svg.push_str("</g>");
    svg.push_str(&tail);
    svg
}

/// Register DejaVu Sans as plotters' "sans-serif" (all styles fall back to
/// regular, bold and oblique are registered). Idempotent.
pub fn register_fonts() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let fonts: [(FontStyle, &'static [u8]); 3] = [
            (FontStyle::Normal, dejavu::sans::regular()),
            (FontStyle::Bold, dejavu::sans::bold()),
            (FontStyle::Oblique, dejavu::sans::oblique()),
        ];
        for (style, bytes) in fonts {
            // The font is compiled in; failing to parse it is a build defect.
            if plotters::style::register_font("sans-serif", style, bytes).is_err() {
                panic!("the embedded DejaVu Sans font could not be parsed");
            }
        }
    });
}

/// Draw `draw` into an SVG string and an RGB PNG of `size` pixels, and
/// return `[(stem.svg, bytes), (stem.png, bytes)]`.
pub(crate) fn render_both<F1, F2>(
    stem: &str,
    size: (u32, u32),
    draw_svg: F1,
    draw_png: F2,
) -> Result<Vec<(String, Vec<u8>)>, PlotError>
where
    F1: FnOnce(&DrawingArea<SVGBackend, Shift>) -> DrawResult + Send,
    F2: FnOnce(&DrawingArea<BitMapBackend, Shift>) -> DrawResult + Send,
{
    register_fonts();
    let perr = |e: Box<dyn std::error::Error>| PlotError {
        name: stem.to_string(),
        message: e.to_string(),
    };
    // The two formats at once (a single drop's figures are the end of its
    // `process`, one core otherwise idle). The SVG is drawn on this thread,
    // whose hover list it fills and empties; the PNG draws no hover target.
    let svg = || -> Result<String, PlotError> {
        let mut svg = String::new();
        HOVER.with(|h| *h.borrow_mut() = Some(Vec::new()));
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        let drawn = root
            .fill(&WHITE)
            .map_err(|e| perr(e.into()))
            .and_then(|()| draw_svg(&root).map_err(perr))
            .and_then(|()| root.present().map_err(|e| perr(e.into())));
        let targets = HOVER.with(|h| h.borrow_mut().take()).unwrap_or_default();
        drawn?;
        drop(root);
        Ok(with_hover(svg, &targets))
    };
    let stage = crate::util::timings::current();
    let png = || -> Result<Vec<u8>, PlotError> {
        let _timed = stage.and_then(crate::util::timings::start);
        let mut rgb = vec![255u8; size.0 as usize * size.1 as usize * 3];
        {
            let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
            root.fill(&WHITE).map_err(|e| perr(e.into()))?;
            draw_png(&root).map_err(perr)?;
            root.present().map_err(|e| perr(e.into()))?;
        }
        rgb_png(&rgb, size.0, size.1).map_err(|e| perr(e.into()))
    };
    let (svg, png) = rayon::join(svg, png);
    Ok(vec![
        (format!("{stem}.svg"), svg?.into_bytes()),
        (format!("{stem}.png"), png?),
    ])
}

/// PNG bytes of `width × height` RGB pixels, as the overlay stills and the
/// figures are written: the fast deflate with every row filtered by
/// "Paeth". Against the adaptive choice per row, re-encoding the 60-drop
/// campaign's figures (1650 × 560) took 1.1 instead of 2.6 ms each and
/// its overlay stills 0.8 instead of 1.2 ms, for 1.7 % more bytes.
pub fn rgb_png(rgb: &[u8], width: u32, height: u32) -> Result<Vec<u8>, image::ImageError> {
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    use image::ImageEncoder;
    let mut out = Vec::new();
    PngEncoder::new_with_quality(&mut out, CompressionType::Fast, FilterType::Paeth).write_image(
        rgb,
        width,
        height,
        image::ExtendedColorType::Rgb8,
    )?;
    Ok(out)
}

/// Draw with one generic function into both formats.
macro_rules! render {
    ($stem:expr, $size:expr, $f:expr) => {
        $crate::plot::render_both($stem, $size, |a| $f(a), |a| $f(a))
    };
}
pub(crate) use render;

/// A tick label: plain decimals between 0.001 and 10 000, else "m·10^k"
/// written as "me-k" would be; we write the decimal with up to 3 significant
/// digits, or `1e-4` style for very small or large values.
pub(crate) fn tick(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if (1e-3..1e4).contains(&a) {
        let digits = (2 - a.log10().floor() as i32).max(0) as usize;
        let s = format!("{v:.digits$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        format!("{v:.1e}").replace(".0e", "e")
    }
}

/// A tick label on a linear axis spanning `span`: as many decimals as a
/// twentieth of the span needs (ticks are about a tenth apart; the factor 2
/// is to spare), so neighbouring ticks never print alike (3 significant
/// digits gave "1.22, 1.22" on a Ψ axis from 1.215 to 1.262); trailing
/// zeros dropped.
pub(crate) fn axis_tick(v: f64, span: f64) -> String {
    let a = v.abs();
    if !(span.is_finite() && span > 0.0) || a >= 1e4 || (a < 1e-3 && a > span * 1e-6) {
        return tick(v);
    }
    let decimals = (-(span / 20.0).log10()).ceil().clamp(0.0, 8.0) as usize;
    let s = format!("{v:.decimals$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    };
    if s == "-0" {
        "0".into()
    } else {
        s
    }
}

/// A run name made safe as a file name (path separators and the like → `_`).
pub fn file_stem(run: &str) -> String {
    let s: String = run
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() || s.starts_with('.') {
        format!("_{s}")
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_read_like_numbers() {
        assert_eq!(tick(0.01), "0.01");
        assert_eq!(tick(0.025), "0.025");
        assert_eq!(tick(2.0), "2");
        assert_eq!(tick(1.25), "1.25");
        assert_eq!(tick(100.0), "100");
        assert_eq!(tick(1e-5), "1e-5");
    }

    #[test]
    fn axis_ticks_never_repeat_on_a_narrow_axis() {
        let labels: Vec<String> = (0..10)
            .map(|k| axis_tick(1.215 + 0.005 * f64::from(k), 0.047))
            .collect();
        assert_eq!(labels[..3], ["1.215", "1.22", "1.225"]);
        let mut unique = labels.clone();
        unique.dedup();
        assert_eq!(unique.len(), labels.len(), "{labels:?}");
        assert_eq!(axis_tick(40.0, 120.0), "40");
        assert_eq!(axis_tick(-1e-17, 0.5), "0");
        assert_eq!(axis_tick(0.25, 1.0), "0.25");
    }

    #[test]
    fn run_names_cannot_escape_the_plot_folder() {
        assert_eq!(file_stem("../etc/passwd"), "_.._etc_passwd");
        assert_eq!(file_stem("R3_h10_07"), "R3_h10_07");
    }
}
