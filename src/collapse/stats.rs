//! Small, dependency-free statistics for the collapse fits: weighted linear
//! least squares on a polynomial basis, percentiles, and Γ / B functions.
//!
//! Degenerate cases are guarded and reported as `None`, never as NaN.

/// Result of a (weighted) linear least-squares fit `y ≈ Σ_k b_k x^k`.
#[derive(Debug, Clone, PartialEq)]
pub struct LsFit {
    /// Coefficients `b_0 … b_d`, lowest power first.
    pub coef: Vec<f64>,
    /// Covariance of `coef`, scaled by the reduced χ² (as scipy's
    /// `curve_fit(absolute_sigma=False)`): valid whether the weights are
    /// absolute (1/σ²) or only relative; `None` when n ≤ number of parameters.
    pub cov: Option<Vec<Vec<f64>>>,
    /// χ² / (n − p) with the weights used (unweighted: the residual variance).
    pub chi2_red: Option<f64>,
}

impl LsFit {
    /// Standard error of coefficient `k`, if defined.
    pub fn stderr(&self, k: usize) -> Option<f64> {
        self.cov
            .as_ref()
            .map(|c| c[k][k].max(0.0).sqrt())
            .filter(|s| s.is_finite())
    }

    /// The fitted polynomial at `x`.
    pub fn eval(&self, x: f64) -> f64 {
        self.coef.iter().rev().fold(0.0, |acc, b| acc * x + b)
    }

    /// Its derivative at `x`.
    pub fn slope(&self, x: f64) -> f64 {
        self.coef
            .iter()
            .enumerate()
            .skip(1)
            .rev()
            .fold(0.0, |acc, (k, b)| acc * x + k as f64 * b)
    }
}

/// Weighted least squares of `y` on `1, x, …, x^degree` (through
/// [`crate::util::lsq::weighted_lsq`], a QR solve). `w` are the weights (1/σ²);
/// `None` means all equal. Returns `None` when fewer points than parameters,
/// a weight or value is not finite (weights also positive), or the design
/// matrix is (numerically) singular, e.g. all `x` equal.
pub fn weighted_poly_fit(x: &[f64], y: &[f64], w: Option<&[f64]>, degree: usize) -> Option<LsFit> {
    let n = x.len();
    let p = degree + 1;
    if n != y.len() || n < p || w.is_some_and(|w| w.len() != n) {
        return None;
    }
    if x.iter().chain(y).any(|v| !v.is_finite()) {
        return None;
    }
    // Fitted in the scaled variable x' = x / s, s = max |x| (powers of x'
    // stay O(1) whatever the unit of x: seconds or Ξ alike); then
    // b_k = b'_k / s^k and cov_kl = cov'_kl / (s^k s^l).
    let scale = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let scale = if scale.is_finite() && scale > 0.0 {
        scale
    } else {
        1.0
    };
    let design = nalgebra::DMatrix::from_fn(n, p, |i, k| (x[i] / scale).powi(k as i32));
    let sigma: Vec<f64> = match w {
        Some(w) => w.iter().map(|wi| 1.0 / wi.sqrt()).collect(),
        None => vec![1.0; n],
    };
    let fit = crate::util::lsq::weighted_lsq(&design, y, &sigma)?;
    let sk: Vec<f64> = (0..p).map(|k| scale.powi(k as i32)).collect();
    let coef: Vec<f64> = (0..p).map(|r| fit.coef[r] / sk[r]).collect();
    if fit.dof == 0 {
        return Some(LsFit {
            coef,
            cov: None,
            chi2_red: None,
        });
    }
    // Covariance scaled by the reduced χ² (see `LsFit::cov`).
    let chi2_red = fit.chi2_red();
    let cov = (0..p)
        .map(|r| {
            (0..p)
                .map(|c| fit.cov[(r, c)] * chi2_red / (sk[r] * sk[c]))
                .collect()
        })
        .collect();
    Some(LsFit {
        coef,
        cov: Some(cov),
        chi2_red: Some(chi2_red),
    })
}

/// The `q`-quantile (0 ≤ q ≤ 1) of already sorted values, by linear
/// interpolation between order statistics (Hyndman & Fan 1996, definition 7,
/// the default of R and NumPy). `None` for an empty slice.
pub fn quantile_sorted(sorted: &[f64], q: f64) -> Option<f64> {
    let n = sorted.len();
    if n == 0 {
        return None;
    }
    let h = (n - 1) as f64 * q.clamp(0.0, 1.0);
    let lo = h.floor() as usize;
    let hi = (lo + 1).min(n - 1);
    Some(sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo]))
}

/// ln Γ(x) for x > 0 by the Lanczos approximation (g = 7, 9 coefficients;
/// relative error below 1e-15 over the positive reals), with the reflection
/// formula below x = 0.5. Numerical Recipes 3rd ed. §6.1; coefficients as
/// published by Godfrey (2001).
pub fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Γ(x) Γ(1 − x) = π / sin(πx)
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut s = C[0];
    for (i, c) in C.iter().enumerate().skip(1) {
        s += c / (x + i as f64);
    }
    let t = x + G + 0.5;
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + s.ln()
}

/// The Beta function B(a, b) = Γ(a) Γ(b) / Γ(a + b), for a, b > 0.
pub fn beta(a: f64, b: f64) -> f64 {
    (ln_gamma(a) + ln_gamma(b) - ln_gamma(a + b)).exp()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gamma_matches_tabulated_values() {
        // Γ(1/2) = √π, Γ(1/3) = 2.678938534707747 (Abramowitz & Stegun 6.1),
        // Γ(5) = 24; tolerance 1e-13 relative (Lanczos is good to ~1e-15).
        let cases = [
            (0.5, std::f64::consts::PI.sqrt()),
            (1.0 / 3.0, 2.678_938_534_707_748),
            (5.0, 24.0),
            (5.0 / 6.0, 1.128_787_029_908_126),
        ];
        for (x, g) in cases {
            let got = ln_gamma(x).exp();
            assert!(((got - g) / g).abs() < 1e-13, "Γ({x}) = {got}, want {g}");
        }
        // B(1/3, 1/2) ≈ 4.20655 (docs/physics.md), to the 6 digits quoted there.
        assert!((beta(1.0 / 3.0, 0.5) - 4.20655).abs() < 5e-6);
    }

    #[test]
    fn exact_quadratic_is_recovered_and_singular_design_is_refused() {
        let x: Vec<f64> = (0..7).map(|i| 0.5 + 0.25 * i as f64).collect();
        let y: Vec<f64> = x.iter().map(|x| 1.26 - 0.3 * x + 0.05 * x * x).collect();
        let f = weighted_poly_fit(&x, &y, None, 2).unwrap();
        for (got, want) in f.coef.iter().zip([1.26, -0.3, 0.05]) {
            assert!((got - want).abs() < 1e-10, "{got} vs {want}");
        }
        assert!((f.slope(2.0) - (-0.3 + 0.2)).abs() < 1e-10);
        assert!(weighted_poly_fit(&[1.0, 1.0, 1.0], &[1.0, 2.0, 3.0], None, 1).is_none());
        assert!(weighted_poly_fit(&[1.0, 2.0], &[1.0, 2.0], None, 2).is_none());
    }

    #[test]
    fn small_units_do_not_make_the_design_singular() {
        // A free-flight parabola in seconds over 1 ms: t⁴ ~ 1e-12.
        let t: Vec<f64> = (0..10).map(|i| i as f64 * 1e-4).collect();
        let z: Vec<f64> = t
            .iter()
            .map(|t| 120.0 + 3.0e4 * t + 9.81e4 * t * t)
            .collect();
        let f = weighted_poly_fit(&t, &z, None, 2).unwrap();
        assert!((f.coef[2] / 9.81e4 - 1.0).abs() < 1e-8, "{:?}", f.coef);
        assert!((f.coef[1] / 3.0e4 - 1.0).abs() < 1e-8);
    }

    #[test]
    fn straight_line_standard_error_matches_textbook_formula() {
        // y = 2 + 3x + e with e = ±0.1 alternating: OLS slope s.e. is
        // sqrt(s² / Sxx), s² = RSS/(n − 2). Computed here from the definitions.
        let x: Vec<f64> = (0..10).map(|i| i as f64).collect();
        let y: Vec<f64> = x
            .iter()
            .enumerate()
            .map(|(i, x)| 2.0 + 3.0 * x + if i % 2 == 0 { 0.1 } else { -0.1 })
            .collect();
        let f = weighted_poly_fit(&x, &y, None, 1).unwrap();
        let mx = 4.5;
        let sxx: f64 = x.iter().map(|x| (x - mx) * (x - mx)).sum();
        let rss: f64 = x
            .iter()
            .zip(&y)
            .map(|(x, y)| (y - f.eval(*x)).powi(2))
            .sum();
        let want = (rss / 8.0 / sxx).sqrt();
        assert!((f.stderr(1).unwrap() - want).abs() < 1e-12);
    }

    #[test]
    fn quantiles_interpolate() {
        let v = [1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(quantile_sorted(&v, 0.5), Some(3.0));
        assert_eq!(quantile_sorted(&v, 0.125), Some(1.5));
        assert_eq!(quantile_sorted(&[], 0.5), None);
    }
}
