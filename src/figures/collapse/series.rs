//! The series figures, Ψ vs Ξ and Ω vs Ξ: the points of each radius, the
//! fitted series with its extrapolation to Ξ = 0, the theory constant, the
//! crossover of the series' leading terms, and the residuals under them.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::kit::{
    draw_points, fit_and_residuals, legend, mesh, no_data, pt, residual_panel, title, RadiusSet,
};
use crate::collapse::fit::{self, SeriesFit};
use crate::collapse::groups::{DropGroups, Quantity};
use crate::plot::layout::{
    along_bars, free_corner, legend_box, normalised, range, residuals, with_band, Pt,
};
use crate::plot::{axis_tick, tick, Backend, DrawResult, Plane, LEGEND_FONT};

/// The x axis's name.
const XI_DESC: &str = "Ξ = ξ φ^(1/6) κ^(−1/6) η^(−1/6)";

/// What differs between the two series figures.
pub(super) struct Series<'s> {
    /// The figure's title.
    pub(super) heading: &'s str,
    /// The y axis's name, and y in hover texts.
    pub(super) y_desc: &'s str,
    /// A drop's y (`None`: the drop has none).
    pub(super) y_of: fn(&DropGroups) -> Option<Quantity>,
    /// The fitted series, if any.
    pub(super) fit: Option<&'s SeriesFit>,
    /// The names of the series' three coefficients.
    pub(super) names: [&'s str; 3],
    /// The theory constant and its legend text.
    pub(super) theory: (f64, &'s str),
    /// Ξ where the series' leading terms are equal, if known.
    pub(super) crossover: Option<f64>,
}

/// A series figure's lines and axes, in data coordinates.
struct Lines {
    /// The fitted series over the data.
    curve: Vec<(f64, f64)>,
    /// The fitted series from Ξ = 0 to the data (empty: not drawn).
    extrapolation: Vec<(f64, f64)>,
    /// The x axis's range.
    xr: [f64; 2],
    /// The y axis's range.
    yr: [f64; 2],
    /// The crossover, where it is inside the x range.
    crossover: Option<f64>,
}

/// Ψ vs Ξ or Ω vs Ξ with the series and the theory constant.
pub(super) fn series_plot<DB: Backend>(
    root: &DrawingArea<DB, Shift>,
    sets: &[RadiusSet],
    spec: &Series,
) -> DrawResult {
    let area = title(root, spec.heading)?;
    let (pts, run_names) = spec.points(sets);
    let all = pts.concat();
    if all.is_empty() {
        return no_data(&area);
    }
    let res: Vec<Vec<Pt>> = pts
        .iter()
        .map(|p| match spec.fit {
            Some(s) => residuals(p, &|x| s.eval(x), false),
            None => Vec::new(),
        })
        .collect();
    let (area, below) = fit_and_residuals(area, &res);
    let mut lines = spec.lines(&all);
    let fit_label = spec.fit_label(!lines.extrapolation.is_empty());
    let cross_label = lines
        .crossover
        .map(|x| format!("Ξ× = A1/A2 = {x:.3} (leading terms equal)"));
    let mut labels = vec![spec.theory.1.to_string()];
    labels.extend(cross_label.clone());
    labels.extend(fit_label.clone());
    for (set, p) in sets.iter().zip(&pts) {
        labels.push(format!("R = {} mm (n = {})", tick(set.radius_mm), p.len()));
    }
    let corner = spec.legend_corner(&all, &labels, &mut lines);
    let alarms = spec.alarms(sets, all.len());
    draw_alarms(&area, &alarms)?;
    let Lines { xr, yr, .. } = lines;
    // With a residual panel, the x axis is named under it.
    let (x_desc, x_label_px) = match below {
        Some(_) => ("", 50),
        None => (XI_DESC, 80),
    };
    let mut chart = ChartBuilder::on(&area)
        .margin(18)
        .margin_top(18 + 28 * alarms.len() as u32)
        .x_label_area_size(x_label_px)
        .y_label_area_size(110)
        .build_cartesian_2d(xr[0]..xr[1], yr[0]..yr[1])?;
    let fx = |v: &f64| axis_tick(*v, xr[1] - xr[0]);
    mesh(
        &mut chart,
        x_desc,
        spec.y_desc,
        &fx,
        &|v| axis_tick(*v, yr[1] - yr[0]),
        10,
    )?;
    draw_lines(&mut chart, spec.theory, lines, cross_label, fit_label)?;
    // Markers last, so that no line hides a point.
    for ((set, p), runs) in sets.iter().zip(&pts).zip(&run_names) {
        if !p.is_empty() {
            let label = format!("R = {} mm (n = {})", tick(set.radius_mm), p.len());
            draw_points(&mut chart, set, (p, runs), false, label, ["Ξ", spec.y_desc])?;
        }
    }
    legend(&mut chart, corner)?;
    if let Some(below) = below {
        residual_panel(
            &below,
            xr[0]..xr[1],
            xr,
            XI_DESC,
            &fx,
            &format!("{} − fit", spec.y_desc),
            sets,
            &res,
        )?;
    }
    Ok(())
}

impl Series<'_> {
    /// The points of each radius set that have a y, and the runs they are.
    fn points<'a>(&self, sets: &[RadiusSet<'a>]) -> (Vec<Vec<Pt>>, Vec<Vec<&'a str>>) {
        let y_of = self.y_of;
        let pts: Vec<Vec<Pt>> = sets
            .iter()
            .map(|s| {
                s.drops
                    .iter()
                    .filter_map(|g| y_of(g).map(|y| pt(&g.big_xi, &y, 1.0, 1.0)))
                    .collect()
            })
            .collect();
        let run_names: Vec<Vec<&str>> = sets
            .iter()
            .map(|s| {
                s.drops
                    .iter()
                    .filter(|g| y_of(g).is_some())
                    .map(|g| g.run.as_str())
                    .collect()
            })
            .collect();
        (pts, run_names)
    }

    /// The fitted series over the data, and its extrapolation to Ξ = 0,
    /// where it is to be compared with the theory constant (A1 vs 2^(1/3),
    /// B1 vs C0); the axes' ranges over all of it.
    fn lines(&self, all: &[Pt]) -> Lines {
        let (series, theory) = (self.fit, self.theory);
        let poly = |s: &SeriesFit, lo: f64, hi: f64| -> Vec<(f64, f64)> {
            (0..=60)
                .map(|i| {
                    let x = lo + (hi - lo) * i as f64 / 60.0;
                    (x, s.eval(x))
                })
                .collect()
        };
        let curve = series.map_or(Vec::new(), |s| poly(s, s.xi_range[0], s.xi_range[1]));
        // Extrapolate only when Ξ = 0 is no farther from the data than their own
        // span, and let the axis grow for it by at most 30 % of the data's range.
        let extrapolation = series
            .filter(|s| fit::reaches_zero(s.xi_range))
            .map_or(Vec::new(), |s| poly(s, 0.0, s.xi_range[0]));
        let (xr, yr0) = range(all, false, &[theory.0]);
        let span = yr0[1] - yr0[0];
        let extra_y: Vec<f64> = extrapolation
            .iter()
            .map(|p| p.1)
            .filter(|y| *y > yr0[0] - 0.3 * span && *y < yr0[1] + 0.3 * span)
            .chain([theory.0])
            .collect();
        let (_, yr) = range(all, false, &extra_y);
        let xr = if extrapolation.is_empty() {
            xr
        } else {
            [0.0, xr[1]]
        };
        let crossover = self.crossover.filter(|x| *x > xr[0] && *x < xr[1]);
        Lines {
            curve,
            extrapolation,
            xr,
            yr,
            crossover,
        }
    }

    /// The fit's legend text: its coefficients with their errors, and
    /// whether it is `extrapolated` (dashed) to Ξ = 0.
    fn fit_label(&self, extrapolated: bool) -> Option<String> {
        let names = self.names;
        self.fit.map(|s| {
            let pm = |k: usize| match s.coef[k].stderr {
                Some(e) => format!("{} = {:.3} ± {:.3}", names[k], s.coef[k].value, e),
                None => format!("{} = {:.3}", names[k], s.coef[k].value),
            };
            let extra = if extrapolated {
                " (dashed: to Ξ = 0)"
            } else {
                ""
            };
            format!("fit: {}, {}, {}{extra}", pm(0), pm(1), pm(2))
        })
    }

    /// The legend's corner: one free of points and lines, else a band
    /// added above them (which widens `lines.yr`).
    fn legend_corner(
        &self,
        all: &[Pt],
        labels: &[String],
        lines: &mut Lines,
    ) -> SeriesLabelPosition {
        use SeriesLabelPosition::*;
        let theory = self.theory;
        let (xr, crossover) = (lines.xr, lines.crossover);
        let lbox = legend_box(labels);
        let yr = lines.yr;
        let mut occupied = normalised(&along_bars(all), xr, yr, false);
        let extra: Vec<Pt> = (0..=40)
            .map(|i| {
                (
                    xr[0] + (xr[1] - xr[0]) * i as f64 / 40.0,
                    theory.0,
                    None,
                    None,
                )
            })
            .chain(
                lines
                    .curve
                    .iter()
                    .chain(&lines.extrapolation)
                    .map(|&(x, y)| (x, y, None, None)),
            )
            .chain(crossover.into_iter().flat_map(|x| {
                (0..=20).map(move |i| (x, yr[0] + (yr[1] - yr[0]) * i as f64 / 20.0, None, None))
            }))
            .collect();
        occupied.extend(normalised(&extra, xr, yr, false));
        match free_corner(
            &occupied,
            lbox,
            &[UpperRight, UpperLeft, LowerLeft, LowerRight],
        ) {
            Some(c) => c,
            None => {
                lines.yr = with_band(yr, lbox.1, false);
                // In the band only the vertical crossover line can be in the way.
                match crossover.map(|x| (x - xr[0]) / (xr[1] - xr[0])) {
                    Some(fx) if fx > 1.0 - lbox.0 - 0.03 => UpperLeft,
                    _ => UpperRight,
                }
            }
        }
    }

    /// The warnings the figure carries over its chart: a geometric contact
    /// radius makes Ψ(Ξ) hold by construction (docs/physics.md), and a
    /// constant term read far from Ξ = 0 is no measurement (`n_points`:
    /// the points drawn).
    fn alarms(&self, sets: &[RadiusSet], n_points: usize) -> Vec<String> {
        // Far from Ξ = 0 the constant term is no measurement: the figure says so.
        let far_from_zero = self.fit.and_then(|s| s.extrapolated_from_xi);
        let n_geo = sets
            .iter()
            .flat_map(|s| &s.drops)
            .filter(|g| g.a_source.is_geometric())
            .count();
        let mut alarms = Vec::new();
        if n_geo > 0 {
            alarms.push(format!(
                "WARNING: {n_geo} of {n_points} drops use the geometric contact radius: Ξ² = Ψ(2 − Π) by construction"
            ));
        }
        if let Some(lo) = far_from_zero {
            alarms.push(format!(
                "EXTRAPOLATED: {} is read at Ξ = 0 from Ξ ≥ {lo:.3}, no measurement",
                self.names[0]
            ));
        }
        alarms
    }
}

/// The figure's warnings in red, one a line, at its top.
fn draw_alarms<DB: Backend>(area: &DrawingArea<DB, Shift>, alarms: &[String]) -> DrawResult {
    for (i, text) in alarms.iter().enumerate() {
        area.draw(&Text::new(
            text.as_str(),
            (60, 4 + 28 * i as i32),
            ("sans-serif", LEGEND_FONT)
                .into_font()
                .color(&RGBColor(200, 0, 0)),
        ))?;
    }
    Ok(())
}

/// The theory constant's line across the chart, the crossover's vertical
/// line and the fitted series with its extrapolation, each with its legend
/// entry.
fn draw_lines<'a, DB: Backend + 'a, CT: Plane>(
    chart: &mut ChartContext<'a, DB, CT>,
    theory: (f64, &str),
    lines: Lines,
    cross_label: Option<String>,
    fit_label: Option<String>,
) -> DrawResult {
    const THEORY: RGBColor = RGBColor(90, 90, 90);
    const CROSS: RGBColor = RGBColor(120, 60, 160);
    let (xr, yr) = (lines.xr, lines.yr);
    chart
        .draw_series(DashedLineSeries::new(
            vec![(xr[0], theory.0), (xr[1], theory.0)],
            10,
            6,
            THEORY.stroke_width(2),
        ))?
        .label(theory.1.to_string())
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], THEORY.stroke_width(2)));
    if let (Some(x), Some(label)) = (lines.crossover, cross_label) {
        chart
            .draw_series(DashedLineSeries::new(
                vec![(x, yr[0]), (x, yr[1])],
                3,
                5,
                CROSS.stroke_width(2),
            ))?
            .label(label)
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], CROSS.stroke_width(2)));
    }
    if let Some(label) = fit_label {
        chart.draw_series(DashedLineSeries::new(
            lines.extrapolation,
            6,
            6,
            BLACK.stroke_width(1),
        ))?;
        chart
            .draw_series(LineSeries::new(lines.curve, BLACK.stroke_width(2)))?
            .label(label)
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
    }
    Ok(())
}
