//! The four collapse figures (cf. Figs. 3–4 of Maruoka 2019):
//! `pi_vs_eta` and `tau_vs_v` (log–log, one colour and marker per sphere
//! radius, the local power-law fit of each radius, guide slopes),
//! `psi_vs_xi` and `omega_vs_xi` (the fitted series and the theory
//! constants). Error bars are the first-order one-sigma errors of collapse.csv.

use plotters::coord::combinators::{BindKeyPoints, LogCoord, WithKeyPoints};
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::collapse::fit::{self, Fits};
use crate::collapse::groups::DropGroups;
use crate::plot::layout::{
    along_bars, free_corner, guide_lines, label_corners, legend_box, log_ticks, normalised, range,
    residuals, with_band, Pt,
};
use crate::plot::PlotError;
use crate::plot::{render, tick, DrawResult};
use crate::plot::{Backend, Plane};

mod kit;
mod series;
use kit::*;
use series::{series_plot, Series};

pub use kit::FIGURE_SIZE;

type LogAxis = WithKeyPoints<LogCoord<f64>>;

/// A log–log chart with ticks from [`log_ticks`].
fn log_log_chart<'a, DB: Backend + 'a>(
    area: &DrawingArea<DB, Shift>,
    xr: [f64; 2],
    yr: [f64; 2],
    x_label_px: u32,
) -> Result<ChartContext<'a, DB, Cartesian2d<LogAxis, LogAxis>>, Box<dyn std::error::Error>> {
    Ok(ChartBuilder::on(area)
        .margin(18)
        .x_label_area_size(x_label_px)
        .y_label_area_size(110)
        .build_cartesian_2d(log_axis(xr), log_axis(yr))?)
}

/// A log axis over `r` with ticks from [`log_ticks`].
fn log_axis(r: [f64; 2]) -> LogAxis {
    let (major, minor) = log_ticks(r[0], r[1]);
    (r[0]..r[1])
        .log_scale()
        .with_key_points(major)
        .with_light_points(minor)
}

/// Fitted power law y = scale · exp(b) x^k over the x range of `p`.
fn power_line<'a, DB: Backend + 'a, CT: Plane>(
    chart: &mut ChartContext<'a, DB, CT>,
    p: &[Pt],
    (k, b, scale): (f64, f64, f64),
    color: RGBColor,
) -> DrawResult {
    let lo = p.iter().map(|q| q.0).fold(f64::INFINITY, f64::min);
    let hi = p.iter().map(|q| q.0).fold(0.0, f64::max);
    if !(lo > 0.0 && hi > lo) {
        return Ok(());
    }
    // A straight line on log axes: its two ends (intermediate points,
    // rounded to pixels, made it wobble).
    chart.draw_series(LineSeries::new(
        [lo, hi].map(|x| (x, scale * (b + k * x.ln()).exp())),
        light(color).stroke_width(2),
    ))?;
    Ok(())
}

/// What differs between the two log–log figures.
struct LogLog<'s> {
    heading: &'s str,
    x_desc: &'s str,
    y_desc: &'s str,
    /// Points per radius set, and the runs they are.
    pts: Vec<Vec<Pt>>,
    names: Vec<Vec<&'s str>>,
    /// x and y in hover texts.
    axes: [&'s str; 2],
    /// Per set: (exponent, ln prefactor, y scale) of the fitted line.
    lines: Vec<Option<(f64, f64, f64)>>,
    /// Legend text per set.
    labels: Vec<String>,
    /// Extra headroom above the data, as a fraction of the log y range.
    headroom: f64,
    /// Guide fan: start (fx, fy) and slopes with labels.
    guide_at: (f64, f64),
    guides: [(f64, &'s str); 2],
    /// Legend corners to try, best first; the last is used in a band
    /// added above the data when none is free.
    legend_corners: [SeriesLabelPosition; 3],
}

fn log_log<DB: Backend>(
    root: &DrawingArea<DB, Shift>,
    sets: &[RadiusSet],
    spec: &LogLog,
) -> DrawResult {
    let area = title(root, spec.heading)?;
    let all = spec.pts.concat();
    if all.is_empty() {
        return no_data(&area);
    }
    let res: Vec<Vec<Pt>> = spec
        .pts
        .iter()
        .zip(&spec.lines)
        .map(|(p, line)| match line {
            Some((k, b, scale)) => residuals(p, &|x| scale * (b + k * x.ln()).exp(), true),
            None => Vec::new(),
        })
        .collect();
    let (area, below) = fit_and_residuals(area, &res);
    let (xr, yr) = range(&all, true, &[]);
    let mut yr = [yr[0], yr[1] * (yr[1] / yr[0]).powf(spec.headroom)];
    let lbox = legend_box(&spec.labels);
    let guides = |yr: [f64; 2], x_free: [f64; 2]| {
        guide_lines(xr, yr, spec.guide_at, 0.3, x_free, &spec.guides)
    };
    // The points, and each guide along its length with its label.
    let occupied = |yr: [f64; 2]| {
        let bars: Vec<Pt> = along_bars(&all)
            .into_iter()
            .filter(|p| p.0 > 0.0 && p.1 > 0.0)
            .collect();
        let mut o = normalised(&bars, xr, yr, true);
        for (g, label, at) in guides(yr, [0.0, 1.0]) {
            let ends: Vec<Pt> = g.iter().map(|&(x, y)| (x, y, None, None)).collect();
            let ends = normalised(&ends, xr, yr, true);
            let (a, b) = (ends[0], ends[ends.len() - 1]);
            o.extend((0..=20).map(|i| {
                let t = f64::from(i) / 20.0;
                (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1))
            }));
            let at = normalised(&[(at.0, at.1, None, None)], xr, yr, true)[0];
            o.extend(label_corners(at, &label));
        }
        o
    };
    // With no corner free, the legend goes into a band above the data, and
    // the guides beside it.
    let (corner, x_free) = match free_corner(&occupied(yr), lbox, &spec.legend_corners) {
        Some(c) => (c, [0.0, 1.0]),
        None => {
            yr = with_band(yr, lbox.1, true);
            let c = spec.legend_corners[2].clone();
            let x_free = match c {
                SeriesLabelPosition::UpperLeft => [(lbox.0 + 0.03).min(0.7), 1.0],
                SeriesLabelPosition::UpperRight => [0.0, (0.97 - lbox.0).max(0.3)],
                _ => [0.0, 1.0],
            };
            (c, x_free)
        }
    };
    // With a residual panel, the x axis is named under it.
    let (x_desc, x_label_px) = match below {
        Some(_) => ("", 50),
        None => (spec.x_desc, 80),
    };
    let mut chart = log_log_chart(&area, xr, yr, x_label_px)?;
    mesh(
        &mut chart,
        x_desc,
        spec.y_desc,
        &|v| tick(*v),
        &|v| tick(*v),
        10,
    )?;
    // Lines first, markers last, so that no line hides a point.
    for ((set, p), line) in sets.iter().zip(&spec.pts).zip(&spec.lines) {
        if let Some(l) = line {
            power_line(&mut chart, p, *l, set.color)?;
        }
    }
    draw_guides(&mut chart, &guides(yr, x_free))?;
    for (((set, p), label), names) in sets
        .iter()
        .zip(&spec.pts)
        .zip(&spec.labels)
        .zip(&spec.names)
    {
        if !p.is_empty() {
            draw_points(&mut chart, set, (p, names), true, label.clone(), spec.axes)?;
        }
    }
    legend(&mut chart, corner)?;
    if let Some(below) = below {
        residual_panel(
            &below,
            log_axis(xr),
            xr,
            spec.x_desc,
            &|v| tick(*v),
            &format!(
                "{} / fit − 1 (%)",
                spec.axes[1].split(" (").next().unwrap_or_default()
            ),
            sets,
            &res,
        )?;
    }
    Ok(())
}

fn pi_vs_eta<DB: Backend>(root: &DrawingArea<DB, Shift>, sets: &[RadiusSet]) -> DrawResult {
    use SeriesLabelPosition::*;
    let spec = LogLog {
        heading: "Penetration Π = δ/R vs Cauchy number η = ρv²/E (cf. Fig. 3a)",
        x_desc: "η = ρv²/E",
        y_desc: "Π = δ/R",
        pts: sets
            .iter()
            .map(|s| {
                s.drops
                    .iter()
                    .map(|g| pt(&g.eta, &g.pi, 1.0, 1.0))
                    .collect()
            })
            .collect(),
        names: sets
            .iter()
            .map(|s| s.drops.iter().map(|g| g.run.as_str()).collect())
            .collect(),
        axes: ["η", "Π"],
        lines: sets
            .iter()
            .map(|s| {
                s.exponent
                    .and_then(|e| e.nu.zip(e.nu_intercept))
                    .map(|(k, b)| (k, b, 1.0))
            })
            .collect(),
        labels: sets
            .iter()
            .map(|s| {
                let e = s.exponent;
                format!(
                    "R = {} mm (n = {}): ν = {}",
                    tick(s.radius_mm),
                    s.drops.len(),
                    ci_text(e.and_then(|e| e.nu), e.and_then(|e| e.nu_ci))
                )
            })
            .collect(),
        headroom: 0.0,
        guide_at: (0.04, 0.95),
        guides: [(1.0 / 3.0, "1/3"), (1.0 / 6.0, "1/6")],
        legend_corners: [LowerRight, LowerLeft, UpperRight],
    };
    log_log(root, sets, &spec)
}

fn tau_vs_v<DB: Backend>(root: &DrawingArea<DB, Shift>, sets: &[RadiusSet]) -> DrawResult {
    use SeriesLabelPosition::*;
    let pts: Vec<Vec<Pt>> = sets
        .iter()
        .map(|s| {
            s.drops
                .iter()
                .filter_map(|g| g.tau_c_s.map(|t| pt(&g.v_m_s, &t, 1.0, 1e3)))
                .collect()
        })
        .collect();
    let names: Vec<Vec<&str>> = sets
        .iter()
        .map(|s| {
            s.drops
                .iter()
                .filter(|g| g.tau_c_s.is_some())
                .map(|g| g.run.as_str())
                .collect()
        })
        .collect();
    let spec = LogLog {
        heading: "Contact time τc vs impact velocity v (cf. Fig. 4a)",
        names,
        axes: ["v (m/s)", "τc (ms)"],
        x_desc: "impact velocity v (m/s)",
        y_desc: "contact time τc (ms)",
        lines: sets
            .iter()
            .map(|s| {
                s.exponent
                    .and_then(|e| e.mu.zip(e.mu_intercept))
                    .map(|(k, b)| (k, b, 1e3))
            })
            .collect(),
        labels: sets
            .iter()
            .zip(&pts)
            .map(|(s, p)| {
                let e = s.exponent;
                format!(
                    "R = {} mm (n = {}): μ = {}",
                    tick(s.radius_mm),
                    p.len(),
                    ci_text(e.and_then(|e| e.mu), e.and_then(|e| e.mu_ci))
                )
            })
            .collect(),
        pts,
        // Room above the data for the guide slopes.
        headroom: 0.25,
        guide_at: (0.55, 0.95),
        guides: [(-1.0 / 3.0, "−1/3"), (-2.0 / 3.0, "−2/3")],
        legend_corners: [LowerLeft, LowerRight, UpperLeft],
    };
    log_log(root, sets, &spec)
}

/// File stems of the figures [`collapse_figures`] draws, in its order.
pub const FIGURE_STEMS: [&str; 4] = ["pi_vs_eta", "tau_vs_v", "psi_vs_xi", "omega_vs_xi"];

/// The four collapse figures as `(file name, bytes)`, SVG and PNG each.
pub fn collapse_figures(
    groups: &[DropGroups],
    fits: &Fits,
) -> Result<Vec<(String, Vec<u8>)>, PlotError> {
    let sets = by_radius(groups, fits);
    let mut out = Vec::new();
    out.extend(render!(FIGURE_STEMS[0], FIGURE_SIZE, |a| pi_vs_eta(
        a, &sets
    ))?);
    out.extend(render!(FIGURE_STEMS[1], FIGURE_SIZE, |a| tau_vs_v(
        a, &sets
    ))?);
    let psi_label = format!("Ψ → 2^(1/3) = {:.4} (energy balance)", fit::psi_theory());
    let psi = Series {
        heading: "Collapse Ψ(Ξ), Ψ = Π φ^(1/3) κ^(−1/3) η^(−1/3) (Eq. 8, cf. Fig. 3b)",
        y_desc: "Ψ",
        y_of: |g| Some(g.psi),
        fit: fits.psi_series.as_ref(),
        names: ["A1", "A2", "A3"],
        theory: (fit::psi_theory(), &psi_label),
        crossover: fits.crossover_xi.as_ref().map(|c| c.value),
    };
    out.extend(render!(FIGURE_STEMS[2], FIGURE_SIZE, |a| series_plot(
        a, &sets, &psi
    ))?);
    let omega_label = format!("Ω → C0 = {:.4} (energy balance)", fit::omega_theory());
    let omega = Series {
        heading: "Collapse Ω(Ξ), Ω = ω φ^(1/3) κ^(−1/3) η^(−1/3), ω = τc v/R (cf. Fig. 4b)",
        y_desc: "Ω",
        y_of: |g| g.big_omega,
        fit: fits.omega_series.as_ref(),
        names: ["B1", "B2", "B3"],
        theory: (fit::omega_theory(), &omega_label),
        crossover: None,
    };
    out.extend(render!(FIGURE_STEMS[3], FIGURE_SIZE, |a| series_plot(
        a, &sets, &omega
    ))?);
    Ok(out)
}
