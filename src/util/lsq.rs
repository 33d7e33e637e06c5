//! Weighted linear least squares with parameter covariance, and polynomial
//! fits built on it. Small dense problems (a handful of parameters, tens to
//! thousands of points), solved by a QR decomposition of the whitened design
//! matrix (numerically safer than the normal equations).

use nalgebra::{DMatrix, DVector};

/// The result of a weighted linear least-squares fit `y ≈ A·p`.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearFit {
    /// The fitted parameters p.
    pub coef: Vec<f64>,
    /// Covariance of p from the stated σ of the data: (Aᵀ W A)⁻¹, W = diag(1/σ²).
    /// Multiply by [`LinearFit::chi2_red`] (when above 1) for a covariance that
    /// also honours the observed scatter.
    pub cov: DMatrix<f64>,
    /// Σ ((y − A·p)/σ)².
    pub chi2: f64,
    /// Degrees of freedom: points − parameters.
    pub dof: usize,
}

impl LinearFit {
    /// χ² per degree of freedom (1.0 when there is no degree of freedom).
    pub fn chi2_red(&self) -> f64 {
        if self.dof == 0 {
            1.0
        } else {
            self.chi2 / self.dof as f64
        }
    }

    /// The covariance scaled by max(1, χ²_red): never smaller than the stated
    /// errors imply, larger when the points scatter more than their σ.
    pub fn cov_scaled(&self) -> DMatrix<f64> {
        &self.cov * self.chi2_red().max(1.0)
    }

    /// Standard error of parameter `i` from [`LinearFit::cov_scaled`].
    pub fn stderr(&self, i: usize) -> f64 {
        (self.cov[(i, i)] * self.chi2_red().max(1.0)).sqrt()
    }
}

/// Fit `y ≈ A·p` with independent Gaussian errors `sigma` (all > 0).
/// `design` has one row per point. Returns `None` when there are fewer points
/// than parameters, a σ is not positive and finite, or A is rank-deficient.
pub fn weighted_lsq(design: &DMatrix<f64>, y: &[f64], sigma: &[f64]) -> Option<LinearFit> {
    weighted_lsq_built(|| design.clone(), y, sigma)
}

/// [`weighted_lsq`] on the design that `build` makes, called twice (for the
/// decomposition, then for the residuals) so that no copy of the design is
/// held beside the decomposition: at most two n × p matrices at once (five
/// with a design held by the caller and copied). The same numbers, bit for
/// bit: the same operations on the same values. A run's free-fall fit has a
/// row per frame in flight and two columns per flight
/// ([`crate::calibrate::free_fall::free_fall_curvature`]): 7.5 MB a copy for a
/// 124 166-frame movie.
pub fn weighted_lsq_built(
    build: impl Fn() -> DMatrix<f64>,
    y: &[f64],
    sigma: &[f64],
) -> Option<LinearFit> {
    let n = y.len();
    if sigma.len() != n || sigma.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
        return None;
    }
    // The design divided row by row by σ.
    let whitened = || {
        let mut aw = build();
        let p = aw.ncols();
        if aw.nrows() != n || n < p || p == 0 {
            return None;
        }
        for i in 0..n {
            let w = 1.0 / sigma[i];
            for j in 0..p {
                aw[(i, j)] *= w;
            }
        }
        Some(aw)
    };
    let qr = whitened()?.qr();
    let r = qr.r();
    let p = r.ncols();
    let yw = DVector::from_iterator(n, y.iter().zip(sigma).map(|(y, s)| y * (1.0 / s)));
    // Rank check on the diagonal of R relative to its largest entry.
    let rmax = (0..p).map(|i| r[(i, i)].abs()).fold(0.0, f64::max);
    if rmax.is_nan() || rmax <= 0.0 || (0..p).any(|i| r[(i, i)].abs() <= rmax * 1e-13) {
        return None;
    }
    let q = qr.q();
    drop(qr);
    let q_t = q.transpose();
    drop(q);
    let qty = q_t * &yw;
    let coef = r.solve_upper_triangular(&qty)?;
    let r_inv = r.solve_upper_triangular(&DMatrix::identity(p, p))?;
    let cov = &r_inv * r_inv.transpose();
    let resid = &whitened()? * &coef - &yw;
    Some(LinearFit {
        coef: coef.iter().copied().collect(),
        cov,
        chi2: resid.norm_squared(),
        dof: n - p,
    })
}

/// Least squares fed one row at a time: each row `a·p ≈ y` (already
/// weighted) is rotated into a p × p upper triangle R and Qᵀy by Givens
/// rotations, its remainder added to the residual sum of squares. The
/// triangle of a QR of the whole design (up to the rows' signs) without
/// holding the design: a fit over any number of rows in a few numbers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RowQr<const P: usize> {
    /// R, upper triangular.
    pub r: [[f64; P]; P],
    /// Qᵀy.
    pub qty: [f64; P],
    /// The residual sum of squares, Σ (y − a·p)² at the fit.
    pub rss: f64,
    /// Rows taken.
    pub rows: usize,
}

impl<const P: usize> Default for RowQr<P> {
    fn default() -> Self {
        RowQr {
            r: [[0.0; P]; P],
            qty: [0.0; P],
            rss: 0.0,
            rows: 0,
        }
    }
}

impl<const P: usize> RowQr<P> {
    /// Take the row `a·p ≈ y`.
    pub fn push(&mut self, mut a: [f64; P], mut y: f64) {
        for i in 0..P {
            if a[i] == 0.0 {
                continue;
            }
            let h = self.r[i][i].hypot(a[i]);
            let (c, s) = (self.r[i][i] / h, a[i] / h);
            for (r, w) in self.r[i][i..].iter_mut().zip(&mut a[i..]) {
                (*r, *w) = (c * *r + s * *w, c * *w - s * *r);
            }
            let (x, w) = (self.qty[i], y);
            self.qty[i] = c * x + s * w;
            y = c * w - s * x;
        }
        self.rss += y * y;
        self.rows += 1;
    }
}

/// A polynomial `y = Σ c_k u^k`, u = (x − x0)/x_scale, fitted by weighted
/// least squares. The scaling keeps the design matrix well conditioned
/// whatever the units of x (e.g. seconds over a millisecond).
#[derive(Debug, Clone, PartialEq)]
pub struct PolyFit {
    /// The expansion point.
    pub x0: f64,
    /// The half-range of the data about x0 (1 when the data have none).
    pub x_scale: f64,
    /// Coefficients `c_k` are in powers of the scaled u.
    pub fit: LinearFit,
}

impl PolyFit {
    /// Fit a polynomial of `degree` about `x0` (choose x0 inside the data for
    /// a well-conditioned fit).
    pub fn fit(x: &[f64], y: &[f64], sigma: &[f64], degree: usize, x0: f64) -> Option<Self> {
        let span = x.iter().map(|x| (x - x0).abs()).fold(0.0, f64::max);
        let x_scale = if span > 0.0 && span.is_finite() {
            span
        } else {
            1.0
        };
        let a = DMatrix::from_fn(x.len(), degree + 1, |i, k| {
            ((x[i] - x0) / x_scale).powi(k as i32)
        });
        weighted_lsq(&a, y, sigma).map(|fit| PolyFit { x0, x_scale, fit })
    }

    /// Coefficients in powers of the scaled u = (x − x0)/x_scale.
    pub fn coef(&self) -> &[f64] {
        &self.fit.coef
    }

    /// The k-th derivative's coefficient at x0 in the units of x:
    /// d^k y/dx^k (x0) = k!·c_k / x_scale^k.
    pub fn derivative_at_x0(&self, k: usize) -> f64 {
        let fact: f64 = (1..=k).map(|i| i as f64).product();
        self.fit.coef.get(k).copied().unwrap_or(0.0) * fact / self.x_scale.powi(k as i32)
    }

    /// Standard error of [`PolyFit::derivative_at_x0`].
    pub fn derivative_at_x0_err(&self, k: usize) -> f64 {
        let fact: f64 = (1..=k).map(|i| i as f64).product();
        self.fit.stderr(k) * fact / self.x_scale.powi(k as i32)
    }

    fn u(&self, x: f64) -> f64 {
        (x - self.x0) / self.x_scale
    }

    /// Value at x.
    pub fn eval(&self, x: f64) -> f64 {
        let u = self.u(x);
        self.fit.coef.iter().rev().fold(0.0, |acc, c| acc * u + c)
    }

    /// First derivative at x.
    pub fn deriv(&self, x: f64) -> f64 {
        let u = self.u(x);
        self.fit
            .coef
            .iter()
            .enumerate()
            .skip(1)
            .rev()
            .fold(0.0, |acc, (k, c)| acc * u + k as f64 * c)
            / self.x_scale
    }

    /// Second derivative at x.
    pub fn deriv2(&self, x: f64) -> f64 {
        let u = self.u(x);
        self.fit
            .coef
            .iter()
            .enumerate()
            .skip(2)
            .rev()
            .fold(0.0, |acc, (k, c)| acc * u + (k * (k - 1)) as f64 * c)
            / (self.x_scale * self.x_scale)
    }

    /// The gradient of the value at x with respect to the coefficients:
    /// [1, u, u², …] with u = (x − x0)/x_scale.
    pub fn value_gradient(&self, x: f64) -> Vec<f64> {
        let u = self.u(x);
        (0..self.fit.coef.len()).map(|k| u.powi(k as i32)).collect()
    }

    /// Variance of the fitted value at x (scaled covariance).
    pub fn value_variance(&self, x: f64) -> f64 {
        quad_form(&self.value_gradient(x), &self.fit.cov_scaled())
    }
}

/// gᵀ C g.
pub fn quad_form(g: &[f64], c: &DMatrix<f64>) -> f64 {
    let mut s = 0.0;
    for i in 0..g.len() {
        for j in 0..g.len() {
            s += g[i] * c[(i, j)] * g[j];
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_polynomial_is_recovered() {
        let x: Vec<f64> = (0..20).map(|i| i as f64 * 0.1).collect();
        let y: Vec<f64> = x.iter().map(|x| 1.5 - 2.0 * x + 0.25 * x * x).collect();
        let s = vec![0.01; x.len()];
        let p = PolyFit::fit(&x, &y, &s, 2, 1.0).unwrap();
        assert!((p.eval(0.3) - (1.5 - 0.6 + 0.25 * 0.09)).abs() < 1e-12);
        assert!((p.deriv(1.0) - (-2.0 + 0.5)).abs() < 1e-12);
        assert!((p.deriv2(0.0) - 0.5).abs() < 1e-10);
        assert!(p.fit.chi2 < 1e-18);
    }

    #[test]
    fn straight_line_errors_match_the_textbook_formula() {
        // y = a + b x with equal σ: var(b) = σ² / Σ (x − x̄)².
        let x: Vec<f64> = (0..11).map(|i| i as f64).collect();
        let y: Vec<f64> = x.iter().map(|x| 2.0 + 3.0 * x).collect();
        let s = vec![0.5; x.len()];
        let p = PolyFit::fit(&x, &y, &s, 1, 5.0).unwrap();
        let sxx: f64 = x.iter().map(|x| (x - 5.0) * (x - 5.0)).sum();
        let slope_err = p.derivative_at_x0_err(1);
        assert!((p.derivative_at_x0(1) - 3.0).abs() < 1e-12);
        assert!((slope_err * slope_err - 0.25 / sxx).abs() < 1e-14);
        assert!((p.fit.cov[(0, 0)] - 0.25 / 11.0).abs() < 1e-14);
    }

    #[test]
    fn rows_fed_one_at_a_time_give_the_whole_designs_fit() {
        // A weighted quadratic with noise: the same coefficients, covariance
        // and χ² as the QR of the whole design, to rounding.
        let n = 500;
        let x: Vec<f64> = (0..n).map(|i| i as f64 * 0.01 - 2.0).collect();
        let s: Vec<f64> = (0..n).map(|i| 0.1 + 0.05 * (i % 7) as f64).collect();
        let y: Vec<f64> = (0..n)
            .map(|i| {
                1.0 + 0.5 * x[i] - 3.0 * x[i] * x[i] + s[i] * ((i * 7919 % 13) as f64 / 6.0 - 1.0)
            })
            .collect();
        let a = DMatrix::from_fn(n, 3, |i, k| x[i].powi(k as i32));
        let whole = weighted_lsq(&a, &y, &s).unwrap();
        let mut rows = RowQr::<3>::default();
        for i in 0..n {
            let w = 1.0 / s[i];
            rows.push([w, x[i] * w, x[i] * x[i] * w], y[i] * w);
        }
        let r = DMatrix::from_fn(3, 3, |i, j| rows.r[i][j]);
        let coef = r
            .solve_upper_triangular(&nalgebra::DVector::from_column_slice(&rows.qty))
            .unwrap();
        let r_inv = r.solve_upper_triangular(&DMatrix::identity(3, 3)).unwrap();
        let cov = &r_inv * r_inv.transpose();
        for k in 0..3 {
            assert!((coef[k] / whole.coef[k] - 1.0).abs() < 1e-12, "{k}");
            assert!((cov[(k, k)] / whole.cov[(k, k)] - 1.0).abs() < 1e-12, "{k}");
        }
        assert!((rows.rss / whole.chi2 - 1.0).abs() < 1e-10);
        assert_eq!(rows.rows, n);
    }

    #[test]
    fn degenerate_inputs_give_none() {
        assert!(PolyFit::fit(&[1.0, 1.0, 1.0], &[1.0, 2.0, 3.0], &[1.0; 3], 1, 0.0).is_none());
        assert!(PolyFit::fit(&[1.0, 2.0], &[1.0, 2.0], &[1.0; 2], 2, 0.0).is_none());
        assert!(
            PolyFit::fit(&[1.0, 2.0, 3.0], &[1.0, 2.0, 3.0], &[1.0, 0.0, 1.0], 1, 0.0).is_none()
        );
    }
}
