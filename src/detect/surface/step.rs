//! The blurred-step model of the band's top (module doc, step 2): one step
//! or two with one blur, fitted by Levenberg–Marquardt.

/// The standard normal density.
fn phi(u: f64) -> f64 {
    (-0.5 * u * u).exp() / (2.0 * std::f64::consts::PI).sqrt()
}

/// The standard normal distribution function.
fn cdf(u: f64) -> f64 {
    0.5 * libm::erfc(-u * std::f64::consts::FRAC_1_SQRT_2)
}

/// `IΦ(u) = uΦ(u) + φ(u)`, the integral of Φ (inlined in [`step_edge_row`]
/// and [`UnitStep`], which share each pixel boundary's value between two
/// samples).
#[cfg(test)]
pub(super) fn int_cdf(u: f64) -> f64 {
    u * cdf(u) + phi(u)
}

/// Row of a bright-to-dark step from the samples `v[k]` of rows
/// `first_row + k`, by a Levenberg–Marquardt fit of
/// `hi − (hi − lo)·A(z; e, σ)` (module doc, step 2), started at `e0`.
/// `None` when the fit does not end on a step inside the samples.
pub fn step_edge_row(v: &[f64], first_row: f64, e0: f64) -> Option<f64> {
    step_edge_fit(v, first_row, e0).map(|(row, _)| row)
}

/// [`step_edge_row`] with the fitted blur σ (px): `(row, σ)`.
pub(super) fn step_edge_fit(v: &[f64], first_row: f64, e0: f64) -> Option<(f64, f64)> {
    let n = v.len();
    let (p, _) = fit_one_step(v, first_row, e0)?;
    let inside = p[0] > first_row && p[0] < first_row + n as f64 - 1.0;
    (p[0].is_finite() && p[2] > p[3] && inside).then_some((p[0], p[1]))
}

/// [`step_edge_row`]'s fit: `(e, σ, hi, lo)` where it ended, and its cost
/// (the sum of squared residuals).
pub(super) fn fit_one_step(v: &[f64], first_row: f64, e0: f64) -> Option<([f64; 4], f64)> {
    let n = v.len();
    if n < 5 {
        return None;
    }
    // The model at every sample, and its gradient in (e, σ, hi, lo). Sample
    // k's upper pixel boundary is sample k + 1's lower one: Φ and φ there
    // are computed once (the same arguments, so the same bits as computing
    // them twice), one erfc and one exp per boundary instead of four each
    // per sample; the fit's cost is in these.
    let model = |p: &[f64; 4], out: &mut Vec<(f64, [f64; 4])>| {
        let (e, s, hi, lo) = (p[0], p[1], p[2], p[3]);
        out.clear();
        let mut prev: Option<(u64, f64, f64)> = None;
        for k in 0..n {
            let z = first_row + k as f64;
            let (up, um) = ((z + 0.5 - e) / s, (z - 0.5 - e) / s);
            let (cm, fm) = match prev {
                Some((u, c, f)) if u == um.to_bits() => (c, f),
                _ => (cdf(um), phi(um)),
            };
            let (cp, fp) = (cdf(up), phi(up));
            prev = Some((up.to_bits(), cp, fp));
            let a = s * ((up * cp + fp) - (um * cm + fm));
            let da_de = -(cp - cm);
            let da_ds = fp - fm;
            let grad = [-(hi - lo) * da_de, -(hi - lo) * da_ds, 1.0 - a, a];
            out.push((hi - (hi - lo) * a, grad));
        }
    };
    // The model at `p` into `at`, and its cost.
    let cost = |p: &[f64; 4], at: &mut Vec<(f64, [f64; 4])>| -> f64 {
        model(p, at);
        at.iter().zip(v).map(|(m, vk)| (m.0 - vk).powi(2)).sum()
    };
    // The model at the current point (an accepted trial's evaluation is
    // the next step's: the same bits as evaluating it again) and at a trial.
    let (mut at_p, mut at_q) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let mut p = [e0, 1.0, v[0].max(v[1]), v[n - 1]];
    let mut c = cost(&p, &mut at_p);
    let mut lambda = 1e-3;
    for _ in 0..60 {
        let mut jtj = [[0.0; 4]; 4];
        let mut jtr = [0.0; 4];
        for (&(m, g), &vk) in at_p.iter().zip(v) {
            let r = m - vk;
            for a in 0..4 {
                jtr[a] += g[a] * r;
                for b in 0..4 {
                    jtj[a][b] += g[a] * g[b];
                }
            }
        }
        let mut improved = false;
        for _ in 0..12 {
            let mut m = jtj;
            for (a, row) in m.iter_mut().enumerate() {
                row[a] += lambda * jtj[a][a].max(1e-12);
            }
            let Some(step) = solve4(m, jtr) else {
                lambda *= 10.0;
                continue;
            };
            let mut q = p;
            for a in 0..4 {
                q[a] -= step[a];
            }
            q[1] = q[1].clamp(SIGMA_BOUNDS_PX.0, SIGMA_BOUNDS_PX.1);
            let cq = cost(&q, &mut at_q);
            if cq.is_finite() && cq <= c {
                improved = c - cq > 1e-14 * (1.0 + c);
                p = q;
                c = cq;
                std::mem::swap(&mut at_p, &mut at_q);
                lambda = (lambda * 0.3).max(1e-9);
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    Some((p, c))
}

/// The pixel-averaged blurred unit step `A(z; e, σ)` (module doc, step 2)
/// at the rows `first_row + k` of `n` samples, and its derivatives
/// `∂A/∂e = −(Φ(u₊) − Φ(u₋))` and `∂A/∂σ = φ(u₊) − φ(u₋)`, `u± = (z ± ½ −
/// e)/σ`, from Φ and φ at the `n + 1` pixel boundaries: row k's upper
/// boundary is row k + 1's lower one (the same number for integer rows),
/// so each is computed once.
#[derive(Debug, Default)]
pub(super) struct UnitStep {
    pub(super) a: Vec<f64>,
    pub(super) da_de: Vec<f64>,
    pub(super) da_ds: Vec<f64>,
}

impl UnitStep {
    pub(super) fn set(&mut self, n: usize, first_row: f64, e: f64, s: f64) {
        self.a.clear();
        self.da_de.clear();
        self.da_ds.clear();
        let mut prev = (0.0, 0.0, 0.0);
        for k in 0..=n {
            let u = (first_row + k as f64 - 0.5 - e) / s;
            let (c, f) = (cdf(u), phi(u));
            let int = u * c + f;
            if k > 0 {
                self.a.push(s * (int - prev.2));
                self.da_de.push(-(c - prev.0));
                self.da_ds.push(f - prev.1);
            }
            prev = (c, f, int);
        }
    }
}

/// The levels `(c₀, c₁, c₂)` of `c₀ + c₁·a₁ + c₂·a₂` fitted to `v` by their
/// normal equations (3 × 3, Cholesky), that Cholesky, and the residuals
/// (model − data); `None` where the two steps' columns are too alike to
/// tell apart.
pub(super) fn two_step_levels(
    a1: &[f64],
    a2: &[f64],
    v: &[f64],
    resid: &mut Vec<f64>,
) -> Option<(
    nalgebra::Cholesky<f64, nalgebra::U3>,
    nalgebra::Vector3<f64>,
)> {
    use nalgebra::{Matrix3, Vector3};
    let (mut ata, mut aty) = (Matrix3::zeros(), Vector3::zeros());
    for ((&p, &q), &y) in a1.iter().zip(a2).zip(v) {
        let row = Vector3::new(1.0, p, q);
        ata += row * row.transpose();
        aty += row * y;
    }
    let chol = ata.cholesky()?;
    let levels = chol.solve(&aty);
    resid.clear();
    resid.extend(
        a1.iter()
            .zip(a2)
            .zip(v)
            .map(|((&p, &q), &y)| levels[0] + levels[1] * p + levels[2] * q - y),
    );
    Some((chol, levels))
}

/// Row of the upper of two bright-to-dark steps blurred alike, from the
/// samples `v[k]` of rows `first_row + k`: a strip of its own level between
/// the band's top and a larger step below it (module doc, step 2). The model
/// is `c₀ + c₁·A(z; e₁, σ) + c₂·A(z; e₂, σ)`; the levels `c` are solved
/// linearly for each `θ = (e₁, e₂, σ)` (variable projection), which a small
/// Levenberg–Marquardt fits from `e0` with the projected residual's exact
/// Jacobian (Golub and Pereyra's), from the steps' analytic derivatives.
/// `None` when the fit does not end on two ordered steps inside the
/// samples (the model is symmetric in its steps, and a fit can end with
/// them swapped: then the caller's one-step fit is used — taking the
/// swapped fit's upper step instead moves one of 120 real-preset drops'
/// δmax from 8e-4 to 7e-3 off by hiding its band top's disagreement).
/// `None` too when the strip is not told from noise: the two-step model must explain the samples better than one
/// step does on the same rows by more than its two further parameters
/// would by chance (`strip_is_resolved`); else noise below the top makes
/// the strip search try columns with none, and the two-step fit splits
/// their one blurred step into two sharper ones and returns the upper, up
/// to 0.4 px above the edge. The fit is given up (`None`) as soon as it has
/// settled above the cost the F-test needs (`TwoStepFit::gave_up`): most
/// strips the search tries are not there, and running their fits to the
/// last digit, only to reject them, was most of the surface line's cost.
/// `first_row` is a row number (an integer).
pub fn two_step_edge_row(v: &[f64], first_row: f64, e0: [f64; 2]) -> Option<f64> {
    two_step_edge_fit(v, first_row, e0).map(|(row, _)| row)
}

/// [`two_step_edge_row`] with the fitted blur σ (px): `(row, σ)`.
pub(super) fn two_step_edge_fit(v: &[f64], first_row: f64, e0: [f64; 2]) -> Option<(f64, f64)> {
    let n = v.len();
    // The one-step fit on the same rows, fitted when first needed: by the
    // test, or by the two-step fit once it has settled.
    let mut cost_one = None;
    let mut one = || {
        *cost_one.get_or_insert_with(|| {
            fit_one_step(v, first_row, e0[0]).map_or(f64::INFINITY, |(_, c)| c)
        })
    };
    let fit = fit_two_steps(v, first_row, e0, &mut || strip_cost_limit(one(), n))?;
    let th = fit.th;
    let inside = |e: f64| e > first_row && e < first_row + n as f64 - 1.0;
    let ordered =
        th.iter().all(|x| x.is_finite()) && th[0] < th[1] && inside(th[0]) && inside(th[1]);
    if fit.gave_up || !ordered {
        return None;
    }
    strip_is_resolved(one(), fit.cost, n).then_some((th[0], th[2]))
}

/// Chance, at most, that noise alone lets the two-step model's two further
/// parameters (the second step's row and level) lower the cost as much as
/// a strip taken for real: the F-test's level.
const STRIP_TEST_LEVEL: f64 = 0.01;

/// Whether two steps (6 parameters) fit `n` samples significantly better
/// than one (4): the F statistic `((c₁ − c₂)/2) / (c₂/(n − 6))` above its
/// `1 − STRIP_TEST_LEVEL` quantile, which for 2 degrees of freedom in the
/// numerator is closed-form: `P(F > f) = (1 + 2f/d)^(−d/2)`, `d = n − 6`.
pub(super) fn strip_is_resolved(cost_one: f64, cost_two: f64, n: usize) -> bool {
    if n <= 6 || !(cost_two <= cost_one) {
        return false;
    }
    let d = (n - 6) as f64;
    // `cost_two` = 0 (a noiseless profile the model fits exactly): resolved.
    (cost_one - cost_two) * d > 2.0 * strip_f_crit(d) * cost_two
}

/// The F-test's critical value for `d` = n − 6 degrees of freedom in the
/// denominator ([`strip_is_resolved`]).
fn strip_f_crit(d: f64) -> f64 {
    0.5 * d * (STRIP_TEST_LEVEL.powf(-2.0 / d) - 1.0)
}

/// The two-step cost above which [`strip_is_resolved`] rejects the strip,
/// for the one-step cost `cost_one` on the same `n` samples: the test
/// holds for `c₂ < c₁·d/(d + 2f)`. `−∞` where it never holds (`n ≤ 6`).
pub(super) fn strip_cost_limit(cost_one: f64, n: usize) -> f64 {
    if n <= 6 {
        return f64::NEG_INFINITY;
    }
    let d = (n - 6) as f64;
    cost_one * d / (d + 2.0 * strip_f_crit(d))
}

/// A Levenberg–Marquardt step that lowers the cost by at most this fraction
/// of it, σ off its bounds, has settled the fit: what it falls after that
/// is far less than its way down to the F-test's limit. Measured, by
/// replaying the logged iterations of every two-step fit on the e2e
/// campaign and the 60 real-preset drops (seed 7): of the 6 220 strips the
/// F-test kept there, none is given up with it (at 1e-4, 3 were).
const SETTLED_FRACTION: f64 = 1e-5;

/// The blur σ's range in the step fits (px).
const SIGMA_BOUNDS_PX: (f64, f64) = (0.2, 6.0);

/// Where [`fit_two_steps`] ended.
#[derive(Debug, Clone, Copy)]
pub(super) struct TwoStepFit {
    /// `θ = (e₁, e₂, σ)`.
    pub(super) th: nalgebra::Vector3<f64>,
    /// The sum of squared residuals at `th`.
    pub(super) cost: f64,
    /// Levenberg–Marquardt iterations (at most 60; read by the tests).
    #[cfg_attr(not(test), allow(dead_code))]
    pub(super) iterations: usize,
    /// Stopped once settled above the cost limit it was given: a strip the
    /// F-test would reject (`th` and `cost` are where it stopped).
    pub(super) gave_up: bool,
}

/// [`two_step_edge_row`]'s fit, to its minimum; or given up where a step
/// has settled it ([`SETTLED_FRACTION`]) at a cost above `cost_limit()`
/// (called then, at most once), σ 5 % or more inside its bounds: a fit
/// whose σ lies on a bound creeps along it under heavy damping, its steps
/// small, and can still fall far (on a real-preset drop from 264 to 4 in
/// ten steps). `&mut || f64::INFINITY`: never given up.
pub(super) fn fit_two_steps(
    v: &[f64],
    first_row: f64,
    e0: [f64; 2],
    cost_limit: &mut dyn FnMut() -> f64,
) -> Option<TwoStepFit> {
    use nalgebra::{Matrix3, Vector3};
    let n = v.len();
    if n < 8 {
        return None;
    }
    debug_assert_eq!(first_row.fract(), 0.0, "a row number");
    let cost = |r: &[f64]| r.iter().map(|x| x * x).sum::<f64>();
    // The steps, levels and residuals at the current θ, and at a trial.
    let (mut s1, mut s2) = (UnitStep::default(), UnitStep::default());
    let (mut t1, mut t2) = (UnitStep::default(), UnitStep::default());
    let (mut r, mut rq) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let mut th = Vector3::new(e0[0], e0[1], 1.0);
    s1.set(n, first_row, th[0], th[2]);
    s2.set(n, first_row, th[1], th[2]);
    let (mut chol, mut levels) = two_step_levels(&s1.a, &s2.a, v, &mut r)?;
    let mut c = cost(&r);
    let mut lambda = 1e-3;
    let mut jac = Vec::with_capacity(n);
    let mut iterations = 0;
    while iterations < 60 {
        iterations += 1;
        two_step_jacobian([&s1, &s2], &levels, &chol, &r, &mut jac);
        let (mut jtj, mut jtr) = (Matrix3::zeros(), Vector3::zeros());
        for (jk, &rk) in jac.iter().zip(&r) {
            jtj += jk * jk.transpose();
            jtr += jk * rk;
        }
        let (mut improved, mut settled) = (false, false);
        for _ in 0..12 {
            let mut m = jtj;
            for a in 0..3 {
                m[(a, a)] += lambda * jtj[(a, a)].max(1e-12);
            }
            let Some(step) = m.lu().solve(&jtr) else {
                lambda *= 10.0;
                continue;
            };
            let mut q = th - step;
            q[2] = q[2].clamp(SIGMA_BOUNDS_PX.0, SIGMA_BOUNDS_PX.1);
            t1.set(n, first_row, q[0], q[2]);
            t2.set(n, first_row, q[1], q[2]);
            let trial =
                two_step_levels(&t1.a, &t2.a, v, &mut rq).map(|(ch, lv)| (ch, lv, cost(&rq)));
            match trial {
                Some((chol_q, levels_q, cq)) if cq <= c => {
                    improved = c - cq > 1e-14 * (1.0 + c);
                    settled = c - cq <= SETTLED_FRACTION * cq
                        && q[2] > 1.05 * SIGMA_BOUNDS_PX.0
                        && q[2] < 0.95 * SIGMA_BOUNDS_PX.1;
                    (th, c, chol, levels) = (q, cq, chol_q, levels_q);
                    std::mem::swap(&mut r, &mut rq);
                    std::mem::swap(&mut s1, &mut t1);
                    std::mem::swap(&mut s2, &mut t2);
                    lambda = (lambda * 0.3).max(1e-9);
                    break;
                }
                _ => lambda *= 10.0,
            }
        }
        if !improved {
            break;
        }
        if settled && c > cost_limit() {
            return Some(TwoStepFit {
                th,
                cost: c,
                iterations,
                gave_up: true,
            });
        }
    }
    Some(TwoStepFit {
        th,
        cost: c,
        iterations,
        gave_up: false,
    })
}

/// The Jacobian of the projected residual `r(θ) = A c(θ) − v`, `c(θ) =
/// (AᵀA)⁻¹Aᵀv`, of the two-step model (Golub and Pereyra's variable
/// projection), one row per sample into `out`: differentiating the normal
/// equations gives `∂c = −(AᵀA)⁻¹(Aᵀ G + W)`, so that
/// `∂r/∂θ = G − A(AᵀA)⁻¹(AᵀG + W)`, with `G = (∂A/∂θ) c` the model's
/// derivative at fixed levels and `W`'s columns `(∂A/∂θ)ᵀ r`; row k is
/// `gₖ − (AᵀG + W)ᵀ(AᵀA)⁻¹ bₖ`, `bₖ = (1, a₁ₖ, a₂ₖ)`. (The noiseless
/// tests cannot see `W`'s sign, since `r` is 0 there: with it flipped the
/// Jacobian is off by O(r), and on the 60 real-preset drops the surface
/// line moves by up to 0.0004 px.)
pub(super) fn two_step_jacobian(
    [s1, s2]: [&UnitStep; 2],
    levels: &nalgebra::Vector3<f64>,
    chol: &nalgebra::Cholesky<f64, nalgebra::U3>,
    r: &[f64],
    out: &mut Vec<nalgebra::Vector3<f64>>,
) {
    use nalgebra::{Matrix3, Vector3};
    out.clear();
    let (mut atg, mut w) = (Matrix3::zeros(), Matrix3::zeros());
    for (k, &rk) in r.iter().enumerate() {
        let gk = Vector3::new(
            levels[1] * s1.da_de[k],
            levels[2] * s2.da_de[k],
            levels[1] * s1.da_ds[k] + levels[2] * s2.da_ds[k],
        );
        atg += Vector3::new(1.0, s1.a[k], s2.a[k]) * gk.transpose();
        w[(1, 0)] += s1.da_de[k] * rk;
        w[(2, 1)] += s2.da_de[k] * rk;
        w[(1, 2)] += s1.da_ds[k] * rk;
        w[(2, 2)] += s2.da_ds[k] * rk;
        out.push(gk);
    }
    let mix = chol.solve(&(atg + w)).transpose();
    for (k, jk) in out.iter_mut().enumerate() {
        *jk -= mix * Vector3::new(1.0, s1.a[k], s2.a[k]);
    }
}

/// Solve the 4×4 system `m·x = b` (LU with partial pivoting).
fn solve4(m: [[f64; 4]; 4], b: [f64; 4]) -> Option<[f64; 4]> {
    let x = nalgebra::Matrix4::from_fn(|i, j| m[i][j])
        .lu()
        .solve(&nalgebra::Vector4::from(b))?;
    x.iter()
        .all(|v| v.is_finite())
        .then(|| [x[0], x[1], x[2], x[3]])
}
