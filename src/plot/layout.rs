//! Layout arithmetic of the collapse figures, free of any drawing: axis
//! ranges and log ticks, guide-slope fans, and where a legend fits without
//! hiding a point. Coordinates "normalised" run 0..1 across the plotting
//! area, y upward.

use plotters::prelude::SeriesLabelPosition;

/// Tick values for a log axis over [lo, hi]: 1, 2, 5 × 10^k when that gives
/// 4–12 labels, else every decade, else 1–9 × 10^k; and the minor grid 1–9 × 10^k.
///
/// Any finite range gives a bounded number of ticks: an end at or below 0,
/// or not finite, is taken at the smallest positive double (a decade
/// count then stays under 620); more than 12 decades are labelled every
/// few, and more than 24 get no minor grid.
pub(crate) fn log_ticks(lo: f64, hi: f64) -> (Vec<f64>, Vec<f64>) {
    let lo = if lo.is_finite() && lo > 0.0 {
        lo
    } else {
        f64::MIN_POSITIVE
    };
    let hi = if hi.is_finite() && hi >= lo { hi } else { lo };
    let (k0, k1) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    if k1 - k0 > 24 {
        let decades: Vec<f64> = (k0..=k1)
            .map(|k| 10f64.powi(k))
            .filter(|v| *v >= lo && *v <= hi)
            .collect();
        let step = decades.len().div_ceil(12).max(1);
        return (decades.into_iter().step_by(step).collect(), Vec::new());
    }
    let pick = |mant: &[f64]| -> Vec<f64> {
        (k0..=k1)
            .flat_map(|k| mant.iter().map(move |m| m * 10f64.powi(k)))
            .filter(|v| *v >= lo && *v <= hi)
            .collect()
    };
    let all = pick(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
    let major = {
        let f = pick(&[1.0, 2.0, 5.0]);
        if (4..=12).contains(&f.len()) {
            f
        } else if f.len() > 12 {
            pick(&[1.0])
        } else if all.len() >= 3 {
            all.clone()
        } else {
            // Less than a factor of ~3 (τc from 2.5 to 3.3 ms gave the one
            // label "3"): evenly spaced round values, as on a linear axis.
            linear_ticks(lo, hi)
        }
    };
    (major, all)
}

/// 3–7 round values (1, 2 or 5 × 10^k apart) within [lo, hi].
fn linear_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let raw = (hi - lo) / 5.0;
    if !(raw.is_finite() && raw > 0.0) {
        return vec![lo];
    }
    let p = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * p)
        .find(|s| (hi - lo) / s <= 7.0)
        .unwrap_or(10.0 * p);
    let first = (lo / step).ceil();
    let last = (hi / step).floor();
    // A step lost in the ends' precision (or none): the ends themselves.
    let usable = step.is_finite()
        && step > 0.0
        && first.is_finite()
        && last.is_finite()
        && (0.0..=20.0).contains(&(last - first));
    if !usable {
        return vec![lo, hi];
    }
    (first as i64..=last as i64)
        .map(|k| k as f64 * step)
        .collect()
}

/// Points normalised to the plot area (log or linear axes).
pub(crate) fn normalised(points: &[Pt], xr: [f64; 2], yr: [f64; 2], log: bool) -> Vec<(f64, f64)> {
    let f = |v: f64, r: [f64; 2]| {
        if log {
            (v.ln() - r[0].ln()) / (r[1].ln() - r[0].ln())
        } else {
            (v - r[0]) / (r[1] - r[0])
        }
    };
    points.iter().map(|p| (f(p.0, xr), f(p.1, yr))).collect()
}

/// Points along each one-sigma error bar of `points` (5 on each), for the
/// legend to keep clear of the bars as of the markers.
pub(crate) fn along_bars(points: &[Pt]) -> Vec<Pt> {
    let mut out = Vec::new();
    for &(x, y, ex, ey) in points {
        for t in [-1.0, -0.5, 0.0, 0.5, 1.0] {
            if let Some(e) = ey.filter(|e| e.is_finite()) {
                out.push((x, y + t * e, None, None));
            }
            if let Some(e) = ex.filter(|e| e.is_finite()) {
                out.push((x + t * e, y, None, None));
            }
        }
    }
    out
}

/// x, y, σx, σy of one point.
pub(crate) type Pt = (f64, f64, Option<f64>, Option<f64>);

/// [lo, hi] of values ± errors; on a log axis the lower end stays positive.
pub(crate) fn range(points: &[Pt], log: bool, extra: &[f64]) -> ([f64; 2], [f64; 2]) {
    let mut xr = [f64::INFINITY, f64::NEG_INFINITY];
    let mut yr = xr;
    let grow = |r: &mut [f64; 2], v: f64, e: Option<f64>| {
        let e = e.unwrap_or(0.0);
        let lo = if log { (v - e).max(v * 0.5) } else { v - e };
        r[0] = r[0].min(lo);
        r[1] = r[1].max(v + e);
    };
    for &(x, y, ex, ey) in points {
        grow(&mut xr, x, ex);
        grow(&mut yr, y, ey);
    }
    for &v in extra {
        grow(&mut yr, v, None);
    }
    let pad = |r: [f64; 2]| {
        if !(r[0].is_finite() && r[1].is_finite()) {
            return if log { [0.1, 10.0] } else { [0.0, 1.0] };
        }
        if log {
            let (a, b) = (r[0].ln(), r[1].ln());
            let m = ((b - a) * 0.08).max(0.05);
            // Ends kept positive and finite (a value near 1e-300 padded
            // below underflows to 0, where a log axis has no end).
            let lo = (a - m).exp().max(f64::MIN_POSITIVE);
            let hi = (b + m).exp().min(f64::MAX);
            [lo, hi.max(lo * (1.0 + 1e-9))]
        } else {
            let m = ((r[1] - r[0]) * 0.08).max(1e-3 * r[1].abs().max(1e-9));
            [r[0] - m, r[1] + m]
        }
    };
    (pad(xr), pad(yr))
}

/// A guide line: its two ends (data coordinates: a straight line on log
/// axes), label and label position (the label's top-left corner).
pub(crate) type Guide = (Vec<(f64, f64)>, String, (f64, f64));

/// Fan of guide lines with the given slopes in a log–log plot, starting at
/// fraction (fx, fy) of the log ranges and running `len` of the x range,
/// within the fraction `x_free` of the x range (the fan and its labels keep
/// out of a legend in a band above the data); the start is lowered so that
/// the steepest rising guide ends 5 % below the top. Each guide is its two
/// ends: drawn through intermediate points rounded to pixels, a dashed
/// guide looked bent.
pub(crate) fn guide_lines(
    xr: [f64; 2],
    yr: [f64; 2],
    (fx, fy): (f64, f64),
    len: f64,
    x_free: [f64; 2],
    slopes: &[(f64, &str)],
) -> Vec<Guide> {
    let (lx0, lx1) = (xr[0].ln(), xr[1].ln());
    let (ly0, ly1) = (yr[0].ln(), yr[1].ln());
    let span = lx1 - lx0;
    // Every guide stays inside the axes, 5 % from their edges: the fan is
    // shortened when it would be taller than the y range, and its start
    // moved so that neither the steepest rising nor the steepest falling
    // guide leaves the plot (where it would be clipped).
    let (top, bottom) = (ly1 - 0.05 * (ly1 - ly0), ly0 + 0.05 * (ly1 - ly0));
    let up = slopes.iter().map(|s| s.0).fold(0.0, f64::max);
    let down = slopes.iter().map(|s| s.0).fold(0.0, f64::min);
    // Room for the labels right of the fan.
    let (left, right) = (
        lx0 + x_free[0] * span,
        lx0 + x_free[1] * span - GUIDE_LABEL_ROOM * span,
    );
    let mut dx = (len * span).min((right - left).max(0.05 * span));
    if (up - down) * dx > top - bottom {
        dx = (top - bottom) / (up - down);
    }
    let x0 = (lx0 + fx * span).min(right - dx).max(left);
    let x1 = x0 + dx;
    let (rise, fall) = (up * dx, down * dx);
    let y0 = (ly0 + fy * (ly1 - ly0)).min(top - rise).max(bottom - fall);
    slopes
        .iter()
        .map(|&(s, label)| {
            let pts = vec![(x0.exp(), y0.exp()), (x1.exp(), (y0 + s * dx).exp())];
            let at = ((x1 + 0.01 * span).exp(), (y0 + s * dx).exp());
            (pts, label.to_string(), at)
        })
        .collect()
}

/// The fraction of the x range kept right of a guide fan for its labels.
const GUIDE_LABEL_ROOM: f64 = 0.12;

/// The corners of a guide's label (normalised coordinates, y up), from its
/// position `at` (normalised: the text's top-left corner).
pub(crate) fn label_corners(at: (f64, f64), label: &str) -> [(f64, f64); 4] {
    const FONT: f64 = super::draw::LEGEND_FONT as f64;
    let w = (label.chars().count() as f64 * 0.6 * FONT + 4.0) / PLOT_AREA_PX.0;
    let h = 1.2 * FONT / PLOT_AREA_PX.1;
    [at, (at.0 + w, at.1), (at.0, at.1 - h), (at.0 + w, at.1 - h)]
}

/// Approximate plotting-area size of a collapse figure, for legend layout.
pub(crate) const PLOT_AREA_PX: (f64, f64) = (1000.0, 660.0);

/// Legend box size as fractions of the plotting area (DejaVu Sans at
/// `LEGEND_FONT`: about 0.45 of it per character, 1.3 of it per entry, plus
/// the marker and margins).
pub(crate) fn legend_box(labels: &[String]) -> (f64, f64) {
    const LEGEND: f64 = super::draw::LEGEND_FONT as f64;
    let chars = labels.iter().map(|l| l.chars().count()).max().unwrap_or(0) as f64;
    (
        ((chars * 0.45 * LEGEND + 60.0) / PLOT_AREA_PX.0).min(0.95),
        ((labels.len() as f64 * 1.3 * LEGEND + 30.0) / PLOT_AREA_PX.1).min(0.9),
    )
}

/// Where the legend goes: the allowed corner whose legend-sized box holds
/// no point (normalised coordinates, y up; `occupied` includes lines),
/// else `None`.
pub(crate) fn free_corner(
    occupied: &[(f64, f64)],
    (w, h): (f64, f64),
    allowed: &[SeriesLabelPosition],
) -> Option<SeriesLabelPosition> {
    allowed
        .iter()
        .find(|p| {
            let (left, up) = match p {
                SeriesLabelPosition::UpperLeft => (true, true),
                SeriesLabelPosition::UpperRight => (false, true),
                SeriesLabelPosition::LowerLeft => (true, false),
                _ => (false, false),
            };
            !occupied.iter().any(|&(x, y)| {
                let in_x = if left {
                    x < w + 0.03
                } else {
                    x > 1.0 - w - 0.03
                };
                let in_y = if up { y > 1.0 - h - 0.03 } else { y < h + 0.03 };
                in_x && in_y
            })
        })
        .cloned()
}

/// Raise the top of a y range so that a band of height fraction `h` above
/// the current top is free for the legend (log or linear axis).
pub(crate) fn with_band(yr: [f64; 2], h: f64, log: bool) -> [f64; 2] {
    let k = 1.0 / (1.0 - h - 0.04);
    if log {
        [yr[0], yr[0] * (yr[1] / yr[0]).powf(k)]
    } else {
        [yr[0], yr[0] + (yr[1] - yr[0]) * k]
    }
}

/// Residuals of `points` from a fitted curve `fit`: `(x, y − fit(x), −,
/// σy)`, or with `relative` (log axes) `(x, 100·(y/fit(x) − 1), −,
/// 100·σy/fit(x))` in percent. Points where the fit is not finite (or, for
/// `relative`, not positive) are left out.
pub(crate) fn residuals(points: &[Pt], fit: &dyn Fn(f64) -> f64, relative: bool) -> Vec<Pt> {
    points
        .iter()
        .filter_map(|&(x, y, _, ey)| {
            let f = fit(x);
            if !f.is_finite() || (relative && f <= 0.0) {
                return None;
            }
            Some(if relative {
                (x, 100.0 * (y / f - 1.0), None, ey.map(|e| 100.0 * e / f))
            } else {
                (x, y - f, None, ey)
            })
        })
        .collect()
}

/// A y range symmetric about 0 holding every residual with its error bar,
/// 15 % to spare; [−1, 1] when there is nothing to show.
pub(crate) fn residual_range(res: &[Pt]) -> [f64; 2] {
    let m = res
        .iter()
        .map(|&(_, r, _, e)| r.abs() + e.unwrap_or(0.0))
        .fold(0.0, f64::max);
    let m = if m.is_finite() && m > 0.0 {
        1.15 * m
    } else {
        1.0
    };
    [-m, m]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn residuals_are_taken_from_the_fit_with_the_points_errors() {
        let pts: Vec<Pt> = vec![
            (1.0, 2.0, Some(0.1), Some(0.2)),
            (2.0, 4.4, None, Some(0.4)),
            (3.0, 5.7, None, None),
        ];
        let line = |x: f64| 2.0 * x;
        let r = residuals(&pts, &line, false);
        let want = [(0.0, Some(0.2)), (0.4, Some(0.4)), (-0.3, None)];
        for (got, (res, err)) in r.iter().zip(want) {
            assert!((got.1 - res).abs() < 1e-12, "{r:?}");
            assert_eq!(got.3, err);
        }
        // Relative, in percent: 10 % above the fit, its 0.4 as 10 %.
        let r = residuals(&pts, &line, true);
        assert!((r[1].1 - 10.0).abs() < 1e-9 && (r[1].3.unwrap() - 10.0).abs() < 1e-9);
        // A fit that is not positive has no relative residual.
        assert!(residuals(&pts, &|x| x - 2.0, true).len() == 1);
        let [lo, hi] = residual_range(&residuals(&pts, &line, false));
        assert!((hi - 1.15 * 0.8).abs() < 1e-12 && lo == -hi);
    }

    #[test]
    fn any_finite_range_gives_few_ticks_at_once() {
        for (lo, hi) in [
            (1e-300, 1e-299),
            (1e-308, 1.0),
            (5e-324, 1e308),
            (0.0, 1e-300),
            (-1.0, 3.0),
            (1.0, f64::INFINITY),
            (f64::NAN, 2.0),
            (1e300, 1e300 * (1.0 + 1e-15)),
        ] {
            let (major, minor) = log_ticks(lo, hi);
            assert!(major.len() <= 21 && minor.len() <= 250, "{lo} {hi}");
            assert!(!major.is_empty(), "{lo} {hi}");
        }
        assert!(linear_ticks(1e300, 1e300 * (1.0 + 1e-15)).len() <= 21);
    }

    #[test]
    fn log_ticks_are_round_numbers_inside_the_range() {
        let (major, minor) = log_ticks(0.0011, 0.06);
        let want = [0.002, 0.005, 0.01, 0.02, 0.05];
        assert_eq!(major.len(), want.len(), "{major:?}");
        for (m, w) in major.iter().zip(want) {
            assert!((m / w - 1.0).abs() < 1e-12, "{major:?}");
        }
        assert!(minor.len() > major.len());
        // A narrow range falls back to 1–9 × 10^k: τc from 1.5 to 6 ms.
        let (major, _) = log_ticks(1.5, 6.5);
        assert_eq!(major, vec![2.0, 3.0, 4.0, 5.0, 6.0]);
        // Narrower still (the fixtures' τc, 2.5–3.3 ms): several round
        // values, not a single "3".
        let (major, _) = log_ticks(2.5, 3.3);
        assert!(major.len() >= 3, "{major:?}");
        assert!(major.iter().all(|v| (2.5..=3.3).contains(v)), "{major:?}");
    }

    /// The τc–v guides (slopes −1/3, −2/3) stay inside a narrow y axis
    /// instead of running off its bottom and being clipped into a line
    /// along it.
    #[test]
    fn guide_slopes_stay_inside_the_axes() {
        for (xr, yr, slopes) in [
            (
                [0.5, 3.2],
                [2.4, 3.4],
                [(-1.0 / 3.0, "a"), (-2.0 / 3.0, "b")],
            ),
            (
                [1e-4, 1e-2],
                [0.05, 0.07],
                [(1.0 / 3.0, "a"), (1.0 / 6.0, "b")],
            ),
            (
                [0.5, 3.2],
                [0.1, 30.0],
                [(-1.0 / 3.0, "a"), (-2.0 / 3.0, "b")],
            ),
        ] {
            for at in [(0.04, 0.95), (0.55, 0.95), (0.9, 0.05)] {
                for x_free in [[0.0, 1.0], [0.62, 1.0], [0.0, 0.4]] {
                    // Beside a legend, inside the free part of the x range.
                    let lo = xr[0] * f64::powf(xr[1] / xr[0], x_free[0]);
                    let hi = xr[0] * f64::powf(xr[1] / xr[0], x_free[1]);
                    for (pts, _, at) in guide_lines(xr, yr, at, 0.3, x_free, &slopes) {
                        assert!(at.0 < hi, "label at {} beyond {hi}", at.0);
                        for (x, y) in pts {
                            assert!(x >= lo * 0.999 && x <= hi, "x {x} outside {lo}..{hi}");
                            assert!(y >= yr[0] && y <= yr[1], "y {y} outside {yr:?}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn the_legend_goes_where_there_is_no_point() {
        use SeriesLabelPosition::*;
        // Points along the rising diagonal: the upper-left and lower-right are free.
        let pts: Vec<(f64, f64)> = (0..50)
            .map(|i| (i as f64 / 49.0, i as f64 / 49.0))
            .collect();
        let c = free_corner(&pts, (0.3, 0.2), &[UpperRight, UpperLeft, LowerRight]);
        assert_eq!(c, Some(UpperLeft));
        // A box as wide as the plot fits nowhere.
        assert_eq!(
            free_corner(&pts, (0.95, 0.5), &[UpperRight, UpperLeft]),
            None
        );
    }
}
