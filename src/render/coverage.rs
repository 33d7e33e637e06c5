//! Exact area coverage of pixels by the shapes the renderer draws: a disk,
//! the half-plane below a (tilted) line, and a periodic pillar pattern.
//!
//! Pixel convention (SPEC §1): pixel `(i, j)` (row `i`, column `j`) is the
//! unit square `[j − ½, j + ½] × [i − ½, i + ½]` in (x, z) with z growing
//! downward. Every function returns the exact covered fraction of that area in
//! closed form (no supersampling), to floating-point rounding.

use std::f64::consts::PI;

/// `∫_{−r}^{t} √(r² − u²) du` for `t` clamped to `[−r, r]`: the area of the
/// upper half of a disk of radius `r` left of the abscissa `t`.
///
/// `asin(t/r)` is evaluated as `atan2(t, h)` with `h = √((r − t)(r + t))`:
/// near the tangent points `t → ±r` the naive `asin(t / r)` turns the
/// rounding of `t / r` into errors of order `r²·√ε` (1e-6 px² here), while
/// this form keeps the full precision of the well-conditioned integral.
fn half_disk_area_left_of(t: f64, r: f64) -> f64 {
    let t = t.clamp(-r, r);
    let h = ((r - t) * (r + t)).max(0.0).sqrt();
    0.5 * (t * h + r * r * t.atan2(h)) + 0.25 * PI * r * r
}

/// Area of `{(u, v) : u² + v² ≤ r², u ≤ x, v ≤ y}` — the part of a disk
/// centred at the origin lying left of `x` and above (smaller than) `y`.
///
/// With `c = √(r² − y²)`, the chord at abscissa `u` contributes
/// `max(0, min(y, h) + h)`, `h = √(r² − u²)`: `2h` where `|u| ≥ c` and `y ≥ 0`,
/// `y + h` where `|u| < c`, and nothing where `|u| ≥ c` and `y < 0`.
pub fn disk_quadrant_area(x: f64, y: f64, r: f64) -> f64 {
    if x <= -r || y <= -r {
        return 0.0;
    }
    let x = x.min(r);
    let a = |lo: f64, hi: f64| {
        if hi > lo {
            half_disk_area_left_of(hi, r) - half_disk_area_left_of(lo, r)
        } else {
            0.0
        }
    };
    if y >= r {
        return 2.0 * a(-r, x);
    }
    let c = ((r - y) * (r + y)).max(0.0).sqrt();
    // middle strip |u| < c: y + h
    let mid_hi = x.min(c);
    let mid = if mid_hi > -c {
        y * (mid_hi + c) + a(-c, mid_hi)
    } else {
        0.0
    };
    if y >= 0.0 {
        2.0 * a(-r, x.min(-c)) + mid + 2.0 * a(c, x)
    } else {
        mid
    }
}

/// Area of the disk (centre at the origin, radius `r`) inside the rectangle
/// `[x0, x1] × [y0, y1]`, by inclusion–exclusion of [`disk_quadrant_area`].
pub fn disk_rect_area(x0: f64, x1: f64, y0: f64, y1: f64, r: f64) -> f64 {
    let v = disk_quadrant_area(x1, y1, r)
        - disk_quadrant_area(x0, y1, r)
        - disk_quadrant_area(x1, y0, r)
        + disk_quadrant_area(x0, y0, r);
    v.clamp(0.0, (x1 - x0) * (y1 - y0))
}

/// Fraction of pixel `(i, j)` covered by the disk of centre `(cx, cz)` and
/// radius `r` (all in px).
pub fn disk_pixel_coverage(i: f64, j: f64, cx: f64, cz: f64, r: f64) -> f64 {
    let x0 = j - 0.5 - cx;
    let y0 = i - 0.5 - cz;
    disk_rect_area(x0, x0 + 1.0, y0, y0 + 1.0, r)
}

/// `∫₀^u clamp(s, 0, 1) ds`.
fn clamp_integral(u: f64) -> f64 {
    if u <= 0.0 {
        0.0
    } else if u < 1.0 {
        0.5 * u * u
    } else {
        u - 0.5
    }
}

/// Fraction of the pixel rectangle `[x0, x1] × [i − ½, i + ½]` lying below
/// (at larger z than) the line `z = a + b·x`. At abscissa x that fraction of
/// the pixel's height is `clamp(i + ½ − a − b x, 0, 1)`; its average over
/// `[x0, x1]` is taken in closed form.
pub fn below_line_fraction(x0: f64, x1: f64, i: f64, a: f64, b: f64) -> f64 {
    let u = |x: f64| i + 0.5 - a - b * x;
    if b.abs() < 1e-12 {
        return u(0.5 * (x0 + x1)).clamp(0.0, 1.0);
    }
    ((clamp_integral(u(x0)) - clamp_integral(u(x1))) / (b * (x1 - x0))).clamp(0.0, 1.0)
}

/// Fraction of `[x0, x1]` covered by pillars of width `pillar_px`, repeating
/// every `period_px`, one starting at `phase_px`.
pub fn pillar_fraction(x0: f64, x1: f64, phase_px: f64, pillar_px: f64, period_px: f64) -> f64 {
    let cumulative = |x: f64| {
        let u = x - phase_px;
        let k = (u / period_px).floor();
        k * pillar_px + (u - k * period_px).min(pillar_px)
    };
    ((cumulative(x1) - cumulative(x0)) / (x1 - x0)).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Independent check by quadrature of the chord length: the area of the
    /// disk in `[x0, x1] × [y0, y1]` is `∫ |[y0, y1] ∩ [−h(u), h(u)]| du`,
    /// `h = √(r² − u²)`. With `u = r sin θ` the integrand becomes smooth
    /// between the breakpoints where `h = |y0|` or `h = |y1|`; composite
    /// Simpson on each smooth piece (2 000 panels) is then accurate to ~1e-13.
    fn quadrature(x0: f64, x1: f64, y0: f64, y1: f64, r: f64) -> f64 {
        let f = |th: f64| {
            let h = r * th.cos();
            (y1.min(h) - y0.max(-h)).max(0.0) * h
        };
        let t0 = (x0.clamp(-r, r) / r).asin();
        let t1 = (x1.clamp(-r, r) / r).asin();
        let mut cuts = vec![t0, t1];
        for y in [y0, y1] {
            if y.abs() < r {
                let a = (y.abs() / r).acos();
                cuts.extend([a, -a]);
            }
        }
        cuts.retain(|&c| c >= t0 && c <= t1);
        cuts.sort_by(|a, b| a.total_cmp(b));
        let n = 2000;
        cuts.windows(2)
            .map(|w| {
                let dx = (w[1] - w[0]) / n as f64;
                let mut s = f(w[0]) + f(w[1]);
                for k in 1..n {
                    s += f(w[0] + k as f64 * dx) * if k % 2 == 1 { 4.0 } else { 2.0 };
                }
                s * dx / 3.0
            })
            .sum()
    }

    #[test]
    fn disk_rectangle_area_matches_quadrature_everywhere_around_the_edge() {
        let r = 7.3;
        let mut worst: f64 = 0.0;
        for (k, &(x0, y0)) in [
            (7.3, 0.2),
            (-8.3, -0.2),
            (0.1, 7.3),
            (-0.3, 6.8),
            (6.9, -0.4),
            (-7.6, -0.5),
            (4.8, 4.9),
            (-5.6, -5.4),
            (5.0, -5.7),
            (-1.0, -7.5),
            (-0.5, -0.5),
            (7.2, 0.1),
            (10.0, 10.0),
        ]
        .iter()
        .enumerate()
        {
            let w = 1.0 + 0.1 * k as f64;
            let exact = disk_rect_area(x0, x0 + w, y0, y0 + 1.0, r);
            let q = quadrature(x0, x0 + w, y0, y0 + 1.0, r);
            worst = worst.max((exact - q).abs());
        }
        assert!(worst < 1e-11, "worst difference {worst}");
    }

    #[test]
    fn coverage_of_all_pixels_sums_to_the_disk_area() {
        let (cx, cz, r) = (20.37, 18.81, 11.13);
        let mut sum = 0.0;
        for i in 0..40 {
            for j in 0..42 {
                sum += disk_pixel_coverage(i as f64, j as f64, cx, cz, r);
            }
        }
        assert!((sum - PI * r * r).abs() < 1e-10, "{sum} vs {}", PI * r * r);
    }

    #[test]
    fn line_fraction_is_exact_for_horizontal_and_tilted_lines() {
        // horizontal line at z = 10.3: pixel 10 spans [9.5, 10.5] → 0.2 below
        assert!((below_line_fraction(-0.5, 0.5, 10.0, 10.3, 0.0) - 0.2).abs() < 1e-15);
        // tilted line z = 10 + 0.5 x over x ∈ [−0.5, 0.5]: below-fraction is
        // 0.5 − 0.5 x, average 0.5 (the line stays inside the pixel)
        assert!((below_line_fraction(-0.5, 0.5, 10.0, 10.0, 0.5) - 0.5).abs() < 1e-15);
        // steep: z = 10 + 4x crosses the pixel; below-fraction clamp(0.5 − 4x, 0, 1),
        // integral over [−0.5, 0.5] = 0.5 (antisymmetric about the centre)
        assert!((below_line_fraction(-0.5, 0.5, 10.0, 10.0, 4.0) - 0.5).abs() < 1e-15);
    }

    #[test]
    fn pillar_fraction_counts_pillar_width_per_period() {
        // pillars of 2.5 every 4: [0, 2.5), [4, 6.5), …
        assert!((pillar_fraction(0.0, 4.0, 0.0, 2.5, 4.0) - 0.625).abs() < 1e-15);
        assert!((pillar_fraction(2.0, 3.0, 0.0, 2.5, 4.0) - 0.5).abs() < 1e-15);
        assert!((pillar_fraction(-1.0, 0.0, 0.0, 2.5, 4.0)).abs() < 1e-15);
        assert!((pillar_fraction(4.5, 5.5, 0.0, 2.5, 4.0) - 1.0).abs() < 1e-15);
    }
}
