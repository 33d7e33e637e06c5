//! The drawing steps the collapse figures share: the points of each
//! radius with their error bars, the fit and residual panels, axes, legends,
//! titles, the sizes of a figure.

use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::collections::BTreeMap;

use crate::collapse::fit::{ExponentFit, Fits};
use crate::collapse::groups::{DropGroups, Quantity};
use crate::plot::layout::{residual_range, Guide, Pt};
use crate::plot::{
    axis_tick, hover, tick, DrawResult, DESC_FONT, LEGEND_FONT, LIGHT_LINES, TICK_FONT,
};
use crate::plot::{radius_style, Marker, MarkerKind};
use crate::plot::{Backend, Plane};

/// Size of every collapse figure, in pixels (SVG user units).
pub const FIGURE_SIZE: (u32, u32) = (1100, 1040);
/// Share of a figure's height (below its title) taken by the fit; the
/// residual panel under it has the rest. Without a fit, the figure is all
/// points.
pub const FIT_SHARE: f64 = 0.72;
pub(super) const MARKER: i32 = 5;

/// Drops of one sphere radius with its plotting style and exponent fit.
pub(super) struct RadiusSet<'a> {
    pub(super) radius_mm: f64,
    pub(super) color: RGBColor,
    pub(super) kind: MarkerKind,
    pub(super) drops: Vec<&'a DropGroups>,
    pub(super) exponent: Option<&'a ExponentFit>,
}

pub(super) fn by_radius<'a>(groups: &'a [DropGroups], fits: &'a Fits) -> Vec<RadiusSet<'a>> {
    let mut map: BTreeMap<i64, Vec<&DropGroups>> = BTreeMap::new();
    for g in groups {
        map.entry((g.sphere_radius_mm * 1000.0).round() as i64)
            .or_default()
            .push(g);
    }
    let mut other = 0;
    map.into_iter()
        .map(|(k, drops)| {
            let radius_mm = k as f64 / 1000.0;
            let (color, kind) = radius_style(radius_mm, other);
            if ![3.0, 4.0, 4.5, 5.0, 7.0]
                .iter()
                .any(|r| (r - radius_mm).abs() < 1e-3)
            {
                other += 1;
            }
            RadiusSet {
                radius_mm,
                color,
                kind,
                drops,
                exponent: fits
                    .exponents
                    .iter()
                    .find(|e| (e.radius_mm - radius_mm).abs() < 1e-6),
            }
        })
        .collect()
}

/// A value to 4 significant digits, for hover texts.
pub(super) fn sig4(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let digits = (3 - v.abs().log10().floor() as i32).max(0) as usize;
    if (1e-3..1e5).contains(&v.abs()) {
        format!("{v:.digits$}")
    } else {
        format!("{v:.3e}")
    }
}

/// A lighter shade of `c` (for fitted lines, so they never hide the points).
pub(super) fn light(c: RGBColor) -> RGBColor {
    let m = |v: u8| ((v as u16 * 5 + 255 * 3) / 8) as u8;
    RGBColor(m(c.0), m(c.1), m(c.2))
}

pub(super) fn pt(x: &Quantity, y: &Quantity, xs: f64, ys: f64) -> Pt {
    (
        x.value * xs,
        y.value * ys,
        x.err().map(|e| e * xs),
        y.err().map(|e| e * ys),
    )
}

/// Error bars (1σ, both directions) and markers of one radius.
/// `points[i]` is the drop named `names[i]`; `axes` names x and y in its
/// hover text.
pub(super) fn draw_points<'a, DB: Backend + 'a, CT: Plane>(
    chart: &mut ChartContext<'a, DB, CT>,
    set: &RadiusSet,
    (points, names): (&[Pt], &[&str]),
    log: bool,
    label: String,
    axes: [&str; 2],
) -> DrawResult {
    let pm = |v: f64, e: Option<f64>| match e {
        Some(e) => format!("{} ± {}", sig4(v), sig4(e)),
        None => sig4(v),
    };
    for (&(x, y, ex, ey), name) in points.iter().zip(names) {
        let (px, py) = chart.plotting_area().map_coordinate(&(x, y));
        hover(
            px,
            py,
            format!(
                "{name} · R = {} mm · {} = {} · {} = {}",
                tick(set.radius_mm),
                axes[0],
                pm(x, ex),
                axes[1],
                pm(y, ey)
            ),
        );
    }
    draw_bars(chart, set, points, log)?;
    let (kind, color) = (set.kind, set.color);
    chart
        .draw_series(
            points
                .iter()
                .map(|&(x, y, _, _)| Marker::new((x, y), kind, color, MARKER)),
        )?
        .label(label)
        .legend(move |(x, y)| Marker::new((x + 10, y), kind, color, MARKER));
    Ok(())
}

/// The one-sigma error bars of `points` in the colour of `set` (on a log
/// axis the lower end stays positive).
pub(super) fn draw_bars<'a, DB: Backend + 'a, CT: Plane>(
    chart: &mut ChartContext<'a, DB, CT>,
    set: &RadiusSet,
    points: &[Pt],
    log: bool,
) -> DrawResult {
    let bar = set.color.stroke_width(1);
    let clamp = |v: f64, e: f64| if log { (v - e).max(v * 0.5) } else { v - e };
    let mut bars = Vec::new();
    for &(x, y, ex, ey) in points {
        if let Some(e) = ey.filter(|e| *e > 0.0) {
            bars.push(PathElement::new(vec![(x, clamp(y, e)), (x, y + e)], bar));
        }
        if let Some(e) = ex.filter(|e| *e > 0.0) {
            bars.push(PathElement::new(vec![(clamp(x, e), y), (x + e, y)], bar));
        }
    }
    chart.draw_series(bars)?;
    Ok(())
}

/// The fit's area and, when some points have a fit, the residual panel
/// under it.
pub(super) type Panels<DB> = (DrawingArea<DB, Shift>, Option<DrawingArea<DB, Shift>>);

pub(super) fn fit_and_residuals<DB: Backend>(
    area: DrawingArea<DB, Shift>,
    res: &[Vec<Pt>],
) -> Panels<DB> {
    if res.iter().all(Vec::is_empty) {
        return (area, None);
    }
    let h = f64::from(area.dim_in_pixel().1);
    let (top, bottom) = area.split_vertically((h * FIT_SHARE) as i32);
    (top, Some(bottom))
}

/// The residual panel under a fit: each point's residual from its fit
/// (`res[i]` for `sets[i]`) with its error bar, in its radius's colour and
/// marker, about a zero line; the x axis is the fit's (`x`, spanning `xr`).
#[allow(clippy::too_many_arguments)]
pub(super) fn residual_panel<DB, X>(
    area: &DrawingArea<DB, Shift>,
    x: X,
    xr: [f64; 2],
    x_desc: &str,
    fx: &dyn Fn(&f64) -> String,
    y_desc: &str,
    sets: &[RadiusSet],
    res: &[Vec<Pt>],
) -> DrawResult
where
    DB: Backend,
    X: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
{
    let yr = residual_range(&res.concat());
    let mut chart = ChartBuilder::on(area)
        .margin(18)
        .margin_top(4)
        .x_label_area_size(80)
        .y_label_area_size(110)
        .build_cartesian_2d(x, yr[0]..yr[1])?;
    // Five y labels in the short panel (plotters' ten crowd it).
    let fy = |v: &f64| axis_tick(*v, yr[1] - yr[0]);
    mesh(&mut chart, x_desc, y_desc, fx, &fy, 5)?;
    chart.draw_series(LineSeries::new(
        vec![(xr[0], 0.0), (xr[1], 0.0)],
        BLACK.stroke_width(1),
    ))?;
    for (set, r) in sets.iter().zip(res) {
        draw_bars(&mut chart, set, r, false)?;
        let (kind, color) = (set.kind, set.color);
        chart.draw_series(
            r.iter()
                .map(|&(x, y, _, _)| Marker::new((x, y), kind, color, MARKER)),
        )?;
    }
    Ok(())
}

pub(super) fn mesh<'a, DB, X, Y>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    x_desc: &str,
    y_desc: &str,
    fx: &dyn Fn(&X::ValueType) -> String,
    fy: &dyn Fn(&Y::ValueType) -> String,
    y_labels: usize,
) -> DrawResult
where
    DB: Backend + 'a,
    X: Ranged + ValueFormatter<<X as Ranged>::ValueType>,
    Y: Ranged + ValueFormatter<<Y as Ranged>::ValueType>,
{
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .axis_desc_style(("sans-serif", DESC_FONT))
        .label_style(("sans-serif", TICK_FONT))
        .x_label_formatter(fx)
        .y_label_formatter(fy)
        .y_labels(y_labels)
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(200, 200, 200))
        .max_light_lines(LIGHT_LINES)
        .draw()?;
    Ok(())
}

pub(super) fn legend<'a, DB: Backend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    pos: SeriesLabelPosition,
) -> DrawResult {
    chart
        .configure_series_labels()
        .position(pos)
        .background_style(WHITE.mix(0.9))
        .border_style(RGBColor(120, 120, 120))
        .label_font(("sans-serif", LEGEND_FONT))
        .margin(12)
        .draw()?;
    Ok(())
}

pub(super) fn ci_text(v: Option<f64>, ci: Option<[f64; 2]>) -> String {
    match (v, ci) {
        (Some(v), Some([lo, hi])) => format!("{v:.3} [{lo:.3}, {hi:.3}]"),
        (Some(v), None) => format!("{v:.3}"),
        _ => "n/a".to_string(),
    }
}

pub(super) fn draw_guides<'a, DB: Backend + 'a, CT: Plane>(
    chart: &mut ChartContext<'a, DB, CT>,
    guides: &[Guide],
) -> DrawResult {
    for (pts, label, at) in guides {
        chart.draw_series(DashedLineSeries::new(
            pts.iter().copied(),
            8,
            5,
            BLACK.stroke_width(2),
        ))?;
        chart.draw_series(std::iter::once(Text::new(
            label.clone(),
            *at,
            ("sans-serif", LEGEND_FONT).into_font().color(&BLACK),
        )))?;
    }
    Ok(())
}

/// An empty figure says why, instead of axes over nothing.
pub(super) fn no_data<DB: Backend>(area: &DrawingArea<DB, Shift>) -> DrawResult {
    let (w, h) = area.dim_in_pixel();
    area.draw(&Text::new(
        "No measured drop to show: see the drops table and the collapse's warnings",
        (w as i32 / 2, h as i32 / 2),
        ("sans-serif", DESC_FONT)
            .into_font()
            .color(&RGBColor(110, 110, 110))
            .pos(plotters::style::text_anchor::Pos::new(
                plotters::style::text_anchor::HPos::Center,
                plotters::style::text_anchor::VPos::Center,
            )),
    ))?;
    Ok(())
}

pub(super) fn title<DB: Backend>(
    root: &DrawingArea<DB, Shift>,
    text: &str,
) -> Result<DrawingArea<DB, Shift>, Box<dyn std::error::Error>> {
    Ok(root.titled(text, ("sans-serif", 24))?)
}
