//! Per-drop diagnostics from `tracks/<run>.csv`: one figure, three panels —
//! z(t) with the free-flight parabolas and the contact / rebound events,
//! δ(t), and F(δ) with the fitted F = K δⁿ and the model F = (πEφR/h) δ².

use plotters::coord::{CoordTranslate, Shift};
use plotters::prelude::*;

use crate::collapse::diagnostics::{DropDiagnostics, ForceLaw, TrackSamples};
use crate::plot::PlotError;
use crate::plot::{axis_tick, file_stem, render, tick, Backend, DrawResult, Plane, LIGHT_LINES};

/// Size of a per-drop figure in pixels.
pub const DROP_FIGURE_SIZE: (u32, u32) = (1650, 560);

/// A panel's series of more points than this is drawn one marker a pixel:
/// a marker drawn again where one is adds nothing to see (its anti-aliased
/// rim only darkens), and a long movie's panels would hold and write one
/// a frame (86 bytes of SVG each, 10 MB for 124 166 frames). Above every
/// drop of the e2e bench's data (the 31 166-frame movie: 15 091 points),
/// whose figures stay the same bytes.
pub const ONE_MARKER_A_PIXEL_ABOVE: usize = 1 << 14;

/// `points` (`n` of them) as a panel with the coordinates `coord` draws
/// them: all of them, or past [`ONE_MARKER_A_PIXEL_ABOVE`] the first at
/// each pixel of the figure, so that what is drawn is bounded by the
/// figure's size, not the movie's length.
fn markers<'a, C: CoordTranslate<From = (f64, f64)>>(
    coord: &'a C,
    points: impl Iterator<Item = (f64, f64)> + 'a,
    n: usize,
) -> impl Iterator<Item = (f64, f64)> + 'a {
    let (w, h) = (DROP_FIGURE_SIZE.0 as usize, DROP_FIGURE_SIZE.1 as usize);
    let thin = n > ONE_MARKER_A_PIXEL_ABOVE;
    let mut seen = vec![0u64; if thin { (w * h).div_ceil(64) } else { 0 }];
    points.filter(move |p| {
        let (x, y) = coord.translate(p);
        let (Ok(x), Ok(y)) = (usize::try_from(x), usize::try_from(y)) else {
            return true;
        };
        if !thin || x >= w || y >= h {
            return true;
        }
        let (word, bit) = ((y * w + x) / 64, 1u64 << ((y * w + x) % 64));
        let first = seen[word] & bit == 0;
        seen[word] |= bit;
        first
    })
}

const EVENT: RGBColor = RGBColor(200, 0, 0);
const FIT: RGBColor = RGBColor(0, 110, 220);

fn span(v: impl Iterator<Item = f64>) -> [f64; 2] {
    let (lo, hi) = v.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
        (a.min(x), b.max(x))
    });
    with_margin(lo, hi)
}

/// `[lo, hi]` widened by 6 % each side; `[0, 1]` unless both are finite.
fn with_margin(lo: f64, hi: f64) -> [f64; 2] {
    if !(lo.is_finite() && hi.is_finite()) {
        return [0.0, 1.0];
    }
    let m = ((hi - lo) * 0.06).max(1e-9 + hi.abs() * 1e-3);
    [lo - m, hi + m]
}

/// The time axis (ms): the frames with a centre, as a movie may run for
/// hundreds of milliseconds before the sphere comes into view; all frames
/// when none has one.
fn time_span_ms(track: &TrackSamples) -> [f64; 2] {
    let rows = &track.samples;
    let tracked = rows.iter().filter(|r| r.z_px.is_some());
    if rows.iter().any(|r| r.z_px.is_some()) {
        span(tracked.map(|r| r.t_s * 1e3))
    } else {
        with_margin(track.all_t_ms[0], track.all_t_ms[1])
    }
}

/// Dashed vertical lines at contact and rebound, labelled near the top
/// (`at_top`) or the bottom of the panel.
fn events<'a, DB: Backend + 'a, CT: Plane>(
    chart: &mut ChartContext<'a, DB, CT>,
    d: &DropDiagnostics,
    yr: [f64; 2],
    at_top: bool,
) -> DrawResult {
    use plotters::style::text_anchor::{HPos, Pos, VPos};
    // Each label sits outside the contact interval: "contact" left of its
    // line, "rebound" right of its line.
    let sides = [
        (d.t_contact_s, "contact ", HPos::Right),
        (d.t_rebound_s, " rebound", HPos::Left),
    ];
    for (t, name, side) in sides {
        if let Some(t) = t {
            let t_ms = t * 1e3;
            chart.draw_series(DashedLineSeries::new(
                vec![(t_ms, yr[0]), (t_ms, yr[1])],
                6,
                4,
                EVENT.stroke_width(2),
            ))?;
            chart.draw_series(std::iter::once(Text::new(
                name.to_string(),
                (
                    t_ms,
                    if at_top {
                        yr[1] - 0.04 * (yr[1] - yr[0])
                    } else {
                        yr[0] + 0.08 * (yr[1] - yr[0])
                    },
                ),
                ("sans-serif", 16)
                    .into_font()
                    .color(&EVENT)
                    .pos(Pos::new(side, VPos::Center)),
            )))?;
        }
    }
    Ok(())
}

/// The panels' tick labels and legends.
const LABEL: (&str, u32) = ("sans-serif", crate::plot::LEGEND_FONT);
/// The panels' axis names.
const DESC: (&str, u32) = ("sans-serif", crate::plot::DESC_FONT - 4);
/// The track's markers.
const TRACK: RGBColor = RGBColor(40, 40, 40);

/// The figure under its title: z(t) and δ(t) side by side, then F(δ).
fn panels<DB: Backend>(root: &DrawingArea<DB, Shift>, d: &DropDiagnostics) -> DrawResult {
    let root = root.titled(
        &format!("Drop {}: trajectory, penetration, force", d.run),
        ("sans-serif", 24),
    )?;
    // F(δ) gets 40 % of the width: its legend carries the fit's numbers.
    let (w, _) = root.dim_in_pixel();
    let (left, force) = root.split_horizontally((f64::from(w) * 0.6) as i32);
    let cols = left.split_evenly((1, 2));
    let t_range = time_span_ms(&d.track);
    // Each panel's points are walked from the track as they are drawn (a
    // long movie's would be copied once for the SVG and once for the PNG).
    trajectory_panel(&cols[0], d, t_range)?;
    penetration_panel(&cols[1], d, t_range)?;
    force_panel(&force, d)
}

/// z(t) with the free-flight parabolas and the events, over `t_range` (ms).
fn trajectory_panel<DB: Backend>(
    area: &DrawingArea<DB, Shift>,
    d: &DropDiagnostics,
    t_range: [f64; 2],
) -> DrawResult {
    // z(t): rows grow downward, so the axis is reversed (up on the page is up in the lab).
    let samples = &d.track.samples;
    let zs = || {
        samples
            .iter()
            .filter_map(|r| r.z_px.map(|z| (r.t_s * 1e3, z)))
    };
    let zr = span(zs().map(|p| p.1));
    let mut c = ChartBuilder::on(area)
        .margin(14)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(t_range[0]..t_range[1], zr[1]..zr[0])?;
    c.configure_mesh()
        .x_desc("t (ms)")
        .y_desc("centre row z (px, downward)")
        .axis_desc_style(DESC)
        .label_style(LABEL)
        .x_label_formatter(&|v| axis_tick(*v, t_range[1] - t_range[0]))
        .y_label_formatter(&|v| axis_tick(*v, zr[1] - zr[0]))
        .light_line_style(RGBColor(238, 238, 238))
        .max_light_lines(LIGHT_LINES)
        .draw()?;
    let coord = c.as_coord_spec().clone();
    c.draw_series(markers(&coord, zs(), zs().count()).map(|p| Circle::new(p, 2, TRACK.filled())))?
        .label("track")
        .legend(|(x, y)| Circle::new((x + 10, y), 3, TRACK.filled()));
    for (i, f) in [&d.flight_in, &d.flight_out].into_iter().enumerate() {
        let Some(f) = f else { continue };
        // Drawn from the first frame used to the event it was fitted for.
        let (a, b) = if i == 0 {
            (f.t_range_s[0], f.t0_s)
        } else {
            (f.t0_s, f.t_range_s[1])
        };
        let s = c.draw_series(LineSeries::new(
            (0..=40).map(|k| {
                let t = a + (b - a) * k as f64 / 40.0;
                (t * 1e3, f.eval(t))
            }),
            FIT.stroke_width(2),
        ))?;
        if i == 0 {
            s.label("free-flight parabolas")
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], FIT.stroke_width(2)));
        }
    }
    // Near the events the sphere is far from both extremes of z: labels at the
    // bottom, legend at the top middle (above the lowest point).
    events(&mut c, d, [zr[1], zr[0]], false)?;
    c.configure_series_labels()
        .position(SeriesLabelPosition::UpperMiddle)
        .background_style(WHITE.mix(0.9))
        .border_style(RGBColor(120, 120, 120))
        .label_font(LABEL)
        .draw()?;
    Ok(())
}

/// δ(t) with the surface's zero and the events, over `t_range` (ms).
fn penetration_panel<DB: Backend>(
    area: &DrawingArea<DB, Shift>,
    d: &DropDiagnostics,
    t_range: [f64; 2],
) -> DrawResult {
    let samples = &d.track.samples;
    let ds = || {
        samples
            .iter()
            .filter_map(|r| r.delta_mm.map(|v| (r.t_s * 1e3, v)))
    };
    let dr = span(ds().map(|p| p.1).chain([0.0]));
    let mut c = ChartBuilder::on(area)
        .margin(14)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(t_range[0]..t_range[1], dr[0]..dr[1])?;
    c.configure_mesh()
        .x_desc("t (ms)")
        .y_desc("penetration δ (mm)")
        .axis_desc_style(DESC)
        .label_style(LABEL)
        .x_label_formatter(&|v| axis_tick(*v, t_range[1] - t_range[0]))
        .y_label_formatter(&|v| axis_tick(*v, dr[1] - dr[0]))
        .light_line_style(RGBColor(238, 238, 238))
        .max_light_lines(LIGHT_LINES)
        .draw()?;
    c.draw_series(LineSeries::new(
        vec![(t_range[0], 0.0), (t_range[1], 0.0)],
        RGBColor(150, 150, 150).stroke_width(1),
    ))?;
    let coord = c.as_coord_spec().clone();
    c.draw_series(markers(&coord, ds(), ds().count()).map(|p| Circle::new(p, 2, TRACK.filled())))?;
    events(&mut c, d, dr, false)
}

/// F(δ) of the contact frames, with the fitted law and the model's, and
/// the legend that gives their numbers.
fn force_panel<DB: Backend>(area: &DrawingArea<DB, Shift>, d: &DropDiagnostics) -> DrawResult {
    let samples = &d.track.samples;
    let fs = || {
        samples
            .iter()
            .filter(|r| r.in_contact)
            .filter_map(|r| r.delta_mm.zip(r.force_n))
    };
    let xr = span(fs().map(|p| p.0).chain([0.0]));
    let mut y_all: Vec<f64> = fs().map(|p| p.1).chain([0.0]).collect();
    if let Some(l) = &d.force_law {
        y_all.push(l.model_k_n_per_mm2 * xr[1].powi(2));
        y_all.push(l.k_n_per_mm_pow_n.value * xr[1].max(0.0).powf(l.n.value));
    }
    let labels = force_labels(d);
    let (font, band) = force_legend(area, &labels)?;
    let fr = crate::plot::layout::with_band(span(y_all.into_iter()), band, false);
    let mut c = ChartBuilder::on(area)
        .margin(14)
        .margin_right(30)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(xr[0]..xr[1], fr[0]..fr[1])?;
    c.configure_mesh()
        .x_desc("penetration δ (mm)")
        .y_desc("contact force F (N)")
        .axis_desc_style(DESC)
        .label_style(LABEL)
        .x_label_formatter(&|v| axis_tick(*v, xr[1] - xr[0]))
        .y_label_formatter(&|v| axis_tick(*v, fr[1] - fr[0]))
        .light_line_style(RGBColor(238, 238, 238))
        .max_light_lines(LIGHT_LINES)
        .draw()?;
    let coord = c.as_coord_spec().clone();
    c.draw_series(markers(&coord, fs(), fs().count()).map(|p| Circle::new(p, 2, TRACK.filled())))?
        .label(&labels[0])
        .legend(|(x, y)| Circle::new((x + 10, y), 3, TRACK.filled()));
    if let Some(l) = &d.force_law {
        let top = fs().map(|p| p.0).fold(0.0, f64::max);
        draw_force_laws(&mut c, l, top, &labels)?;
    }
    c.configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.9))
        .border_style(RGBColor(120, 120, 120))
        .label_font(("sans-serif", font))
        .draw()?;
    Ok(())
}

/// The F(δ) panel's legend lines: the measured force, and with a fitted
/// law its numbers and the model's K.
fn force_labels(d: &DropDiagnostics) -> Vec<String> {
    let mut labels = vec!["F = m(g − d²z/dt²)".to_string()];
    if let Some(l) = &d.force_law {
        let digits = |e: Option<f64>| if e.is_some_and(|e| e < 0.01) { 4 } else { 2 };
        let p = digits(l.n.stderr);
        let se = l.n.stderr.map_or(String::new(), |e| format!(" ± {e:.p$}"));
        labels.push(format!(
            "fit ({}): n = {:.p$}{se}, K = {} N/mmⁿ",
            l.source,
            l.n.value,
            tick(l.k_n_per_mm_pow_n.value)
        ));
        labels.push(format!(
            "model πEφR/h · δ²: K = {} N/mm²",
            tick(l.model_k_n_per_mm2)
        ));
    }
    labels
}

/// The F(δ) legend's font and the band (a share of the plotting area's
/// height) kept for it above the data. The legend sits upper left, in a
/// band kept free above the data and in a font small enough for its
/// longest line to fit the panel (it ran off the figure's right edge).
fn force_legend<DB: Backend>(
    area: &DrawingArea<DB, Shift>,
    labels: &[String],
) -> Result<(u32, f64), Box<dyn std::error::Error>> {
    let (panel_w, panel_h) = area.dim_in_pixel();
    // Plotting area: the panel less its margins (14, and 30 on the right
    // for the last x tick label at the figure's edge) and label areas.
    let (plot_w, plot_h) = (
        f64::from(panel_w) - 70.0 - 44.0,
        f64::from(panel_h) - 50.0 - 28.0,
    );
    let font = legend_font(area, labels, plot_w)?;
    let band = (labels.len() as f64 * 1.3 * f64::from(font) + 24.0) / plot_h;
    Ok((font, band))
}

/// The fitted F = K δⁿ from 0 to the deepest contact frame (`top`, mm), and
/// the model's K δ² dashed, with their legend lines (`labels[1]`, `[2]`).
fn draw_force_laws<'a, DB: Backend + 'a, CT: Plane>(
    c: &mut ChartContext<'a, DB, CT>,
    l: &ForceLaw,
    top: f64,
    labels: &[String],
) -> DrawResult {
    let (k, n) = (l.k_n_per_mm_pow_n.value, l.n.value);
    let curve = |kk: f64, nn: f64| {
        (0..=50).map(move |i| {
            let x = top * i as f64 / 50.0;
            (x, kk * x.powf(nn))
        })
    };
    c.draw_series(LineSeries::new(curve(k, n), FIT.stroke_width(2)))?
        .label(&labels[1])
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], FIT.stroke_width(2)));
    let km = l.model_k_n_per_mm2;
    c.draw_series(DashedLineSeries::new(
        curve(km, 2.0),
        8,
        5,
        RGBColor(90, 90, 90).stroke_width(2),
    ))?
    .label(&labels[2])
    .legend(|(x, y)| {
        PathElement::new(
            vec![(x, y), (x + 20, y)],
            RGBColor(90, 90, 90).stroke_width(2),
        )
    });
    Ok(())
}

/// The legend font size, at most [`crate::plot::LEGEND_FONT`] (and at least 12),
/// at which the longest of `labels`, with the legend's marker and margins,
/// fits `width_px`.
fn legend_font<DB: Backend>(
    area: &DrawingArea<DB, Shift>,
    labels: &[String],
    width_px: f64,
) -> Result<u32, Box<dyn std::error::Error>> {
    // Marker, gaps and box margins around the text (plotters' series labels).
    const CHROME_PX: f64 = 60.0;
    let base = crate::plot::LEGEND_FONT;
    let mut widest = 0.0f64;
    for l in labels {
        let (w, _) = area.estimate_text_size(l, &("sans-serif", base).into_text_style(area))?;
        widest = widest.max(f64::from(w));
    }
    let room = 0.97 * width_px - CHROME_PX;
    if widest <= room {
        return Ok(base);
    }
    Ok(((f64::from(base) * room / widest).floor() as u32).max(12))
}

/// The diagnostics figure of one drop as `(file name, bytes)`, SVG and PNG.
pub fn drop_figures(d: &DropDiagnostics) -> Result<Vec<(String, Vec<u8>)>, PlotError> {
    let figures = render!(&file_stem(&d.run), DROP_FIGURE_SIZE, |a| panels(a, d))?;
    // The panels walked the samples (from their file, past its budget):
    // none failed to be read.
    d.track.samples.check().map_err(|e| PlotError {
        name: file_stem(&d.run),
        message: e.to_string(),
    })?;
    Ok(figures)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collapse::diagnostics::{read_track_samples, DropDiagnostics};
    use crate::dataset::TrackRow;

    fn row(t_s: f64, z_px: Option<f64>) -> TrackRow {
        TrackRow {
            frame: 0,
            t_s,
            x_px: z_px,
            z_px,
            r_px: z_px,
            residual_px: None,
            edge_points: 0,
            in_contact: false,
            delta_mm: None,
            sigma_z_px: None,
            sigma_x_px: None,
            r_free_px: None,
            sigma_r_free_px: None,
            force_n: None,
            flags: String::new(),
        }
    }

    /// `rows` written as a track file and read back as the figure reads it.
    fn samples_of(rows: &[TrackRow]) -> TrackSamples {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.csv");
        crate::collapse::synthetic::write_track(&path, rows).unwrap();
        read_track_samples(&path).unwrap()
    }

    #[test]
    fn a_long_series_is_drawn_once_at_every_pixel_it_touches() {
        use plotters::coord::cartesian::Cartesian2d;
        use plotters::coord::types::RangedCoordf64;
        let coord: Cartesian2d<RangedCoordf64, RangedCoordf64> =
            Cartesian2d::new(0.0..2.0, 300.0..0.0, (84..975, 60..480));
        // A bouncing sphere's z(t) sampled 200 000 times, with noise.
        let n = 200_000;
        let z = |k: usize| {
            let t = 2.0 * k as f64 / n as f64;
            let u = (t * 4.0).fract();
            250.0 - 900.0 * u * (1.0 - u) + 0.3 * ((k * 7919 % 13) as f64 / 6.0 - 1.0)
        };
        let points = || (0..n).map(move |k| (2.0 * k as f64 / n as f64, z(k)));
        let every: std::collections::HashSet<(i32, i32)> =
            points().map(|p| coord.translate(&p)).collect();
        let drawn: Vec<(i32, i32)> = markers(&coord, points(), n)
            .map(|p| coord.translate(&p))
            .collect();
        let distinct: std::collections::HashSet<(i32, i32)> = drawn.iter().copied().collect();
        // Each pixel the series touches, once: far fewer markers than points.
        assert_eq!(distinct.len(), drawn.len());
        assert_eq!(distinct, every);
        assert!(drawn.len() < n / 10, "{}", drawn.len());
        // A series of at most ONE_MARKER_A_PIXEL_ABOVE points: every one, in order.
        let short: Vec<(f64, f64)> = points().take(ONE_MARKER_A_PIXEL_ABOVE).collect();
        let kept: Vec<(f64, f64)> = markers(&coord, short.iter().copied(), short.len()).collect();
        assert_eq!(kept, short);
    }

    #[test]
    fn a_long_movies_figure_holds_a_marker_a_pixel_not_a_frame() {
        use crate::collapse::diagnostics::TrackSample;
        // The samples held in memory, or in a file past `memory_max`.
        let figure = |frames: usize, memory_max: usize| {
            let mut samples = crate::util::records::Records::new(memory_max);
            for s in (0..frames).map(|k| {
                let t_s = 2.0 * k as f64 / frames as f64;
                let u = (t_s * 4.0).fract();
                let z = 250.0 - 900.0 * u * (1.0 - u);
                TrackSample {
                    t_s,
                    z_px: Some(z),
                    delta_mm: Some(0.08 * (z - 240.0)),
                    force_n: None,
                    in_contact: false,
                }
            }) {
                samples.push(s).unwrap();
            }
            samples.flush().unwrap();
            assert_eq!(samples.spilled(), frames > memory_max);
            let d = DropDiagnostics {
                run: "long".into(),
                track_path: "long.csv".into(),
                track: TrackSamples {
                    samples,
                    all_t_ms: [0.0, 2000.0],
                },
                t_contact_s: None,
                t_rebound_s: None,
                flight_in: None,
                flight_out: None,
                force_law: None,
            };
            let figs = drop_figures(&d).unwrap();
            let svg = String::from_utf8(figs[0].1.clone()).unwrap();
            (svg.matches("<circle").count(), svg.len(), figs)
        };
        let (c1, len1, in_memory) = figure(50_000, usize::MAX);
        let (c4, len4, _) = figure(200_000, usize::MAX);
        // Four times the frames, about the same figure: at most the pixels
        // the two panels' curves touch.
        assert!(c1 < 20_000 && c4 < 20_000, "{c1} {c4}");
        assert!(len4 < len1 + len1 / 4, "{len1} {len4}");
        // Below the bound, a marker a frame.
        let (c, _, _) = figure(ONE_MARKER_A_PIXEL_ABOVE, usize::MAX);
        assert!(c >= 2 * ONE_MARKER_A_PIXEL_ABOVE, "{c}");
        // Samples read back from their file draw the same bytes.
        let (_, _, from_file) = figure(50_000, 1_000);
        assert!(from_file == in_memory);
    }

    #[test]
    fn the_time_axis_spans_the_tracked_frames_not_the_whole_movie() {
        // 300 ms of movie before the sphere enters, then 5 ms tracked.
        let mut rows: Vec<TrackRow> = (0..3000)
            .map(|k| row(-0.3 + 1e-4 * f64::from(k), None))
            .collect();
        rows.extend((0..50).map(|k| row(1e-4 * f64::from(k), Some(100.0))));
        let track = samples_of(&rows);
        // The frames without a centre are not kept.
        assert_eq!(track.samples.len(), 50);
        let [lo, hi] = time_span_ms(&track);
        assert!(lo > -0.5 && lo < 0.0 && hi > 4.9 && hi < 5.5, "{lo}..{hi}");
        // Nothing tracked: the whole movie, though no frame is kept.
        let untracked = samples_of(&rows[..3000]);
        assert!(untracked.samples.is_empty());
        let [lo, hi] = time_span_ms(&untracked);
        assert!(lo < -300.0 && hi > 0.0 && hi - lo > 300.0, "{lo}..{hi}");
    }
}
