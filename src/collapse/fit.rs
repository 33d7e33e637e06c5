//! The collapse fits (SPEC §3), each with a standard error and a
//! seeded 95 % bootstrap interval:
//!
//! - per sphere radius, the local exponents ν of Π ∝ η^ν and μ of τc ∝ v^μ
//!   (straight lines in log–log);
//! - across all drops, Ψ = A1 + A2 Ξ + A3 Ξ² (Eq. (8) of Maruoka 2019) and
//!   its τc analogue Ω = B1 + B2 Ξ + B3 Ξ² (from Eq. (10));
//! - the two intermediate asymptotics with fixed exponents, Eq. (5)
//!   Π = c1 (κ/φ)^{1/3} η^{1/3} (i.e. Ψ = c1) and Eq. (7)
//!   Π' = c2 (ξ κ' η / φ)^{1/6} (i.e. Ψ/Ξ = c2), and their τc analogues
//!   Ω = d1 (Eq. (1e)) and Ω/Ξ = d2 (Eq. (11));
//! - the crossover Ξ× = A1/A2 where the two leading terms of Eq. (8) are equal.
//!
//! **Weights.** Every fit is linear least squares of y on 1, x, … x^d. Both
//! x and y carry errors and, within one drop, are correlated (Ψ and Ξ both
//! contain v), so each point is weighted by its *effective variance*
//! (Orear, Am. J. Phys. 50, 912 (1982)): the first-order variance of the
//! residual y − f(x), Var = Σ_i (∂y/∂p_i − f'(x) ∂x/∂p_i)² σ_i² over the
//! measured inputs p = (v, δ, a, τc). f' comes from the previous iterate
//! (three iterations from f' = 0). If any point of a fit has an unknown
//! error (an empty `_err` cell) or a zero variance, that fit is unweighted
//! and says so (`weighted: false` and a warning).
//!
//! **Standard errors** are from the covariance scaled by the reduced χ²
//! (valid when the stated errors are only relative). **Intervals** are
//! percentile intervals (2.5 %, 97.5 %) of a case-resampling (pairs)
//! bootstrap (Efron & Tibshirani 1993, ch. 9) with a ChaCha8 generator
//! seeded from the user's seed and the fit's name, so every interval is
//! reproducible and independent of the order the fits run in.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::collections::BTreeMap;

use super::groups::{DropGroups, Quantity};
use super::stats::{quantile_sorted, weighted_poly_fit, LsFit};

/// 2^{1/3}: Ψ at small Ξ from the energy balance (Eq. (4) of Maruoka 2019).
pub fn psi_theory() -> f64 {
    2f64.cbrt()
}

/// B(1/3, 1/2) = Γ(1/3) Γ(1/2) / Γ(5/6) ≈ 4.20655 (Eq. (1d)).
pub fn beta_third_half() -> f64 {
    super::stats::beta(1.0 / 3.0, 0.5)
}

/// C0 = (2·2^{1/3}/3) B(1/3, 1/2) ≈ 3.5333: Ω at small Ξ (Eq. (1e)).
pub fn omega_theory() -> f64 {
    2.0 * 2f64.cbrt() / 3.0 * beta_third_half()
}

/// How to bootstrap.
#[derive(Debug, Clone, Copy)]
pub struct FitSettings {
    /// Number of bootstrap resamples (0 = no intervals).
    pub resamples: usize,
    /// Base seed; each fit mixes in a hash of its name.
    pub seed: u64,
}

/// One fitted number.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Estimate {
    /// The fitted value.
    pub value: f64,
    /// First-order standard error (from the χ²-scaled covariance).
    pub stderr: Option<f64>,
    /// 95 % percentile bootstrap interval [lo, hi].
    pub ci95: Option<[f64; 2]>,
}

/// Ψ(Ξ) or Ω(Ξ) as a quadratic series.
#[derive(Debug, Clone, PartialEq)]
pub struct SeriesFit {
    /// Constant, linear and quadratic coefficients (A1, A2, A3 or B1, B2, B3).
    pub coef: [Estimate; 3],
    /// Number of drops fitted.
    pub n_drops: usize,
    /// Whether the points were weighted by their effective variance (false: some error unknown or zero, unweighted).
    pub weighted: bool,
    /// Reduced χ² of the fit (of unit weights when unweighted); `None` without degrees of freedom.
    pub chi2_red: Option<f64>,
    /// Ξ range covered by the drops (the series is not valid outside it).
    pub xi_range: [f64; 2],
    /// Condition number of the design matrix [1, Ξ, Ξ²] (Ξ scaled by its
    /// largest value, as fitted): how nearly the three terms can stand in
    /// for each other over the drops' Ξ range. Above ~1e3 the coefficients
    /// trade off and their individual values mean little.
    pub condition_number: Option<f64>,
    /// `Some(Ξ_min)` when the constant term is read at Ξ = 0 from drops at
    /// Ξ ≥ Ξ_min farther from 0 than their own span: an extrapolation, not
    /// a measurement of the small-Ξ (theory's) side.
    pub extrapolated_from_xi: Option<f64>,
}

impl SeriesFit {
    /// The series at Ξ = `xi`: c1 + c2 Ξ + c3 Ξ².
    pub fn eval(&self, xi: f64) -> f64 {
        let c = &self.coef;
        c[0].value + xi * (c[1].value + xi * c[2].value)
    }
}

/// Whether a fit over `xi_range` reaches Ξ = 0's side: 0 no farther from
/// the data than their own span (the plots dash the series to 0 only then).
pub fn reaches_zero(xi_range: [f64; 2]) -> bool {
    xi_range[0] <= xi_range[1] - xi_range[0]
}

/// Condition number (largest over smallest singular value) of the design
/// matrix of a polynomial of `degree` in x scaled by max |x|.
fn condition_number(x: &[f64], degree: usize) -> Option<f64> {
    let scale = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if !(scale.is_finite() && scale > 0.0) || x.len() <= degree {
        return None;
    }
    let design =
        nalgebra::DMatrix::from_fn(x.len(), degree + 1, |i, k| (x[i] / scale).powi(k as i32));
    let sv = design.singular_values();
    let (lo, hi) = sv.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &v| {
        (lo.min(v), hi.max(v))
    });
    (lo > 0.0).then(|| hi / lo)
}

/// The words a warning uses for a fit's internal name.
fn display_name(name: &str) -> &str {
    match name {
        "psi_series" => "the series Psi(Xi) = A1 + A2 Xi + A3 Xi^2",
        "omega_series" => "the series Omega(Xi) = B1 + B2 Xi + B3 Xi^2",
        "eq5_c1" => "the constant c1 of Psi = c1 (Eq. 5)",
        "eq7_c2" => "the constant c2 of Psi/Xi = c2 (Eq. 7)",
        "eq1e_d1" => "the constant d1 of Omega = d1 (Eq. 1e)",
        "eq11_d2" => "the constant d2 of Omega/Xi = d2 (Eq. 11)",
        other => other,
    }
}

/// A fixed-exponent asymptote: the constant c in y = c · (known power law).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AsymptoteFit {
    /// The formula, e.g. "Pi = c1 (kappa/phi)^(1/3) eta^(1/3)  (Eq. 5)".
    pub law: String,
    /// The fitted constant (c1, c2, d1 or d2).
    pub constant: Estimate,
    /// Number of drops fitted.
    pub n_drops: usize,
    /// Which drops were used, e.g. "Xi < 1.32 (first term of Eq. 8 dominant)".
    pub selection: String,
    /// RMS of ln(y / law) over those drops: how well one power law describes them.
    pub rms_log_residual: Option<f64>,
    /// Whether the points were weighted by their effective variance (false: some error unknown or zero, unweighted).
    pub weighted: bool,
}

/// Local exponents for one sphere radius.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ExponentFit {
    /// The sphere radius of these drops, mm.
    pub radius_mm: f64,
    /// Number of drops of this radius.
    pub n_drops: usize,
    /// ν of Π ∝ η^ν.
    pub nu: Option<f64>,
    /// Standard error of ν.
    pub nu_stderr: Option<f64>,
    /// 95 % bootstrap interval of ν [lo, hi].
    pub nu_ci: Option<[f64; 2]>,
    /// ln of the prefactor: ln Π = nu_intercept + ν ln η.
    pub nu_intercept: Option<f64>,
    /// μ of τc ∝ v^μ (τc in s, v in m/s).
    pub mu: Option<f64>,
    /// Standard error of μ.
    pub mu_stderr: Option<f64>,
    /// 95 % bootstrap interval of μ [lo, hi].
    pub mu_ci: Option<[f64; 2]>,
    /// ln τc\[s\] = mu_intercept + μ ln v\[m/s\].
    pub mu_intercept: Option<f64>,
    /// Drops with a contact time (those in the μ fit).
    pub n_tau: usize,
    /// True when ν and μ were both fitted with effective-variance weights.
    pub weighted: bool,
}

/// Everything fitted, plus the warnings met on the way.
#[derive(Debug, Clone, PartialEq)]
pub struct Fits {
    /// Ψ = A1 + A2 Ξ + A3 Ξ² (Eq. (8) of Maruoka 2019).
    pub psi_series: Option<SeriesFit>,
    /// Ω = B1 + B2 Ξ + B3 Ξ², the τc analogue (from Eq. (10)).
    pub omega_series: Option<SeriesFit>,
    /// The crossover Ξ× = A1/A2, where the two leading terms of Eq. (8) are equal.
    pub crossover_xi: Option<Estimate>,
    /// Ψ = c1 at small Ξ (Eq. (5)).
    pub eq5: Option<AsymptoteFit>,
    /// Ψ/Ξ = c2 at large Ξ (Eq. (7)).
    pub eq7: Option<AsymptoteFit>,
    /// Ω = d1 at small Ξ (Eq. (1e)).
    pub eq1e: Option<AsymptoteFit>,
    /// Ω/Ξ = d2 at large Ξ (Eq. (11)).
    pub eq11: Option<AsymptoteFit>,
    /// The local exponents ν and μ, per sphere radius.
    pub exponents: Vec<ExponentFit>,
    /// Warnings met on the way (an unweighted fit, too few drops, …), one sentence each.
    pub warnings: Vec<String>,
    /// When no exponent and no series could be fitted for lack of drops
    /// (a radius needs 3, a series 4): what these drops can and cannot
    /// show, and how to see more, said once instead of a warning per fit.
    pub few_drops: Option<String>,
}

/// One regression point: x, y and their absolute sensitivity vectors
/// ∂/∂p_i · σ_i over (v, δ, a, τc) (`None` = unknown error).
#[derive(Debug, Clone, Copy)]
pub struct Obs {
    /// The abscissa, as the fit takes it (Ξ, or a logarithm).
    pub x: f64,
    /// The ordinate, as the fit takes it.
    pub y: f64,
    /// ∂x/∂p_i · σ_i over (v, δ, a, τc); `None`: an error unknown.
    pub sx: Option<[f64; 4]>,
    /// ∂y/∂p_i · σ_i over (v, δ, a, τc); `None`: an error unknown.
    pub sy: Option<[f64; 4]>,
}

impl Obs {
    /// ln y against ln x: the sensitivities of a log are the relative ones.
    fn log_log(x: &Quantity, y: &Quantity) -> Self {
        Obs {
            x: x.value.ln(),
            y: y.value.ln(),
            sx: x.rel_sens,
            sy: y.rel_sens,
        }
    }
    /// y against x, both linear.
    fn linear(x: &Quantity, y: &Quantity) -> Self {
        Obs {
            x: x.value,
            y: y.value,
            sx: x.abs_sens(),
            sy: y.abs_sens(),
        }
    }
}

/// Least squares of y on 1..x^degree weighted by effective variance (see
/// the module doc). Returns the fit and whether it was weighted.
pub fn fit_effective_variance(obs: &[Obs], degree: usize) -> Option<(LsFit, bool)> {
    let x: Vec<f64> = obs.iter().map(|o| o.x).collect();
    let y: Vec<f64> = obs.iter().map(|o| o.y).collect();
    let known = obs
        .iter()
        .all(|o| o.sy.is_some() && (degree == 0 || o.sx.is_some()));
    let mut fit = weighted_poly_fit(&x, &y, None, degree)?;
    if !known {
        return Some((fit, false));
    }
    let mut slope_prev: Option<LsFit> = None;
    for _ in 0..3 {
        let w: Option<Vec<f64>> = obs
            .iter()
            .map(|o| {
                let fp = slope_prev.as_ref().map_or(0.0, |f| f.slope(o.x));
                let sy = o.sy?;
                let sx = o.sx.unwrap_or([0.0; 4]);
                let var: f64 = (0..4).map(|i| (sy[i] - fp * sx[i]).powi(2)).sum();
                (var > 0.0 && var.is_finite()).then(|| 1.0 / var)
            })
            .collect();
        let Some(w) = w else {
            return Some((fit, false));
        };
        fit = weighted_poly_fit(&x, &y, Some(&w), degree)?;
        slope_prev = Some(fit.clone());
    }
    Some((fit, true))
}

/// FNV-1a of a fit's name, mixed into the seed so fits draw independent streams.
fn salt(name: &str) -> u64 {
    name.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0100_0000_01b3)
    })
}

/// Pairs bootstrap: refit on `resamples` resamples with replacement and
/// return, per derived quantity, the sorted finite values, plus the number of
/// resamples whose fit failed (e.g. every drawn point at one x).
fn bootstrap(
    obs: &[Obs],
    degree: usize,
    settings: FitSettings,
    name: &str,
    derive: &dyn Fn(&LsFit) -> Vec<f64>,
) -> (Vec<Vec<f64>>, usize) {
    let mut rng = ChaCha8Rng::seed_from_u64(settings.seed ^ salt(name));
    let n = obs.len();
    let mut out: Vec<Vec<f64>> = Vec::new();
    let mut failed = 0;
    let mut draw = Vec::with_capacity(n);
    for _ in 0..settings.resamples {
        draw.clear();
        // u32 draws keep the stream identical on 32- and 64-bit targets.
        draw.extend((0..n).map(|_| obs[rng.gen_range(0..n as u32) as usize]));
        match fit_effective_variance(&draw, degree) {
            Some((f, _)) => {
                let d = derive(&f);
                if out.is_empty() {
                    out = vec![Vec::with_capacity(settings.resamples); d.len()];
                }
                for (k, v) in d.into_iter().enumerate() {
                    if v.is_finite() {
                        out[k].push(v);
                    }
                }
            }
            None => failed += 1,
        }
    }
    for v in &mut out {
        v.sort_by(f64::total_cmp);
    }
    (out, failed)
}

/// 95 % interval from sorted bootstrap values; `None` if more than 10 % of
/// the resamples gave no value.
fn ci95(sorted: Option<&Vec<f64>>, resamples: usize) -> Option<[f64; 2]> {
    let s = sorted?;
    if resamples == 0 || (s.len() as f64) < 0.9 * resamples as f64 {
        return None;
    }
    Some([quantile_sorted(s, 0.025)?, quantile_sorted(s, 0.975)?])
}

struct Fitted {
    fit: LsFit,
    weighted: bool,
    boot: Vec<Vec<f64>>,
    failed: usize,
}

fn fit_and_bootstrap(
    obs: &[Obs],
    degree: usize,
    settings: FitSettings,
    name: &str,
    derive: &dyn Fn(&LsFit) -> Vec<f64>,
    warnings: &mut Vec<String>,
) -> Option<Fitted> {
    let (fit, weighted) = fit_effective_variance(obs, degree)?;
    if !weighted {
        warnings.push(format!(
            "{}: unweighted least squares (some of its {} have no uncertainty, \
             or a zero one)",
            display_name(name),
            crate::util::text::plural(obs.len(), "drop")
        ));
    }
    let (boot, failed) = bootstrap(obs, degree, settings, name, derive);
    if settings.resamples > 0 && failed * 10 > settings.resamples {
        warnings.push(format!(
            "{}: {failed} of {} bootstrap resamples could not be fitted; no interval given",
            display_name(name),
            settings.resamples
        ));
    }
    Some(Fitted {
        fit,
        weighted,
        boot,
        failed,
    })
}

impl Fitted {
    fn estimate(&self, k: usize, value: f64, stderr: Option<f64>, resamples: usize) -> Estimate {
        let ci = if self.failed * 10 > resamples {
            None
        } else {
            ci95(self.boot.get(k), resamples)
        };
        Estimate {
            value,
            stderr,
            ci95: ci,
        }
    }
}

fn series(
    obs: &[Obs],
    name: &str,
    settings: FitSettings,
    warnings: &mut Vec<String>,
    few: &mut Vec<usize>,
) -> Option<(SeriesFit, Option<Estimate>)> {
    if obs.len() < 4 {
        few.push(warnings.len());
        warnings.push(format!(
            "{}: {}, at least 4 are needed for three coefficients with errors",
            display_name(name),
            crate::util::text::plural(obs.len(), "drop")
        ));
        return None;
    }
    let derive = |f: &LsFit| vec![f.coef[0], f.coef[1], f.coef[2], f.coef[0] / f.coef[1]];
    let Some(r) = fit_and_bootstrap(obs, 2, settings, name, &derive, warnings) else {
        warnings.push(format!(
            "{}: the quadratic fit is singular (fewer than 3 distinct Xi values)",
            display_name(name)
        ));
        return None;
    };
    let c = &r.fit.coef;
    let coef = [0, 1, 2].map(|k| r.estimate(k, c[k], r.fit.stderr(k), settings.resamples));
    // Ξ× = A1/A2 with first-order error from the covariance of (A1, A2).
    let cross = (c[1] != 0.0).then(|| {
        let x = c[0] / c[1];
        let se = r.fit.cov.as_ref().map(|cov| {
            let (a1, a2) = (c[0], c[1]);
            let var = cov[0][0] / (a2 * a2) + a1 * a1 * cov[1][1] / a2.powi(4)
                - 2.0 * a1 * cov[0][1] / a2.powi(3);
            var.max(0.0).sqrt()
        });
        r.estimate(3, x, se, settings.resamples)
    });
    let lo = obs.iter().map(|o| o.x).fold(f64::INFINITY, f64::min);
    let hi = obs.iter().map(|o| o.x).fold(f64::NEG_INFINITY, f64::max);
    let xs: Vec<f64> = obs.iter().map(|o| o.x).collect();
    let condition_number = condition_number(&xs, 2);
    let extrapolated_from_xi = (!reaches_zero([lo, hi])).then_some(lo);
    if extrapolated_from_xi.is_some() {
        let constant = if name == "omega_series" { "B1" } else { "A1" };
        warnings.push(format!(
            "EXTRAPOLATED: {constant} of {} is read at Xi = 0 from drops at Xi >= {lo:.3} \
             (they span Xi {lo:.3}-{hi:.3}; condition number {}): no measurement of the \
             small-Xi constant. The fixed-exponent constants and the exponents per radius \
             are what these drops support",
            display_name(name),
            condition_number.map_or("-".into(), |c| format!("{c:.2e}")),
        ));
    }
    Some((
        SeriesFit {
            coef,
            n_drops: obs.len(),
            weighted: r.weighted,
            chi2_red: r.fit.chi2_red,
            xi_range: [lo, hi],
            condition_number,
            extrapolated_from_xi,
        },
        cross,
    ))
}

/// Fit y = ln c (a weighted mean of ln y); the constant is exp of it.
fn asymptote(
    obs: &[Obs],
    law: &str,
    name: &str,
    selection: String,
    settings: FitSettings,
    warnings: &mut Vec<String>,
) -> Option<AsymptoteFit> {
    if obs.len() < 2 {
        warnings.push(format!(
            "{}: {} selected, need 2",
            display_name(name),
            crate::util::text::plural(obs.len(), "drop")
        ));
        return None;
    }
    let derive = |f: &LsFit| vec![f.coef[0].exp()];
    let r = fit_and_bootstrap(obs, 0, settings, name, &derive, warnings)?;
    let c = r.fit.coef[0].exp();
    // Delta method: σ_c = c σ_{ln c}.
    let se = r.fit.stderr(0).map(|s| c * s);
    let rms = (obs
        .iter()
        .map(|o| (o.y - r.fit.coef[0]).powi(2))
        .sum::<f64>()
        / obs.len() as f64)
        .sqrt();
    Some(AsymptoteFit {
        law: law.to_string(),
        constant: r.estimate(0, c, se, settings.resamples),
        n_drops: obs.len(),
        selection,
        rms_log_residual: Some(rms),
        weighted: r.weighted,
    })
}

/// Ln of a ratio of two quantities of one drop, as an observation of a constant.
fn log_ratio(num: &Quantity, den: Option<&Quantity>) -> Obs {
    let (v, s) = match den {
        None => (num.value.ln(), num.rel_sens),
        Some(d) => (
            (num.value / d.value).ln(),
            num.rel_sens
                .zip(d.rel_sens)
                .map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3]]),
        ),
    };
    Obs {
        x: 0.0,
        y: v,
        sx: None,
        sy: s,
    }
}

/// Local exponents per sphere radius.
fn exponents(
    groups: &[DropGroups],
    settings: FitSettings,
    warnings: &mut Vec<String>,
    few: &mut Vec<usize>,
) -> Vec<ExponentFit> {
    // Radii keyed in whole micrometres: 4.5 and 4.500000001 are one sphere size.
    let mut by_r: BTreeMap<i64, Vec<&DropGroups>> = BTreeMap::new();
    for g in groups {
        by_r.entry((g.sphere_radius_mm * 1000.0).round() as i64)
            .or_default()
            .push(g);
    }
    let slope = |f: &LsFit| vec![f.coef[1]];
    // The slope of one log–log fit with its bootstrap, or a warning saying why not.
    let mut exponent = |obs: &[Obs], what: &str, name: &str| -> Option<(Estimate, f64, bool)> {
        if obs.len() < 3 {
            few.push(warnings.len());
            warnings.push(format!(
                "{name}: {} {what}, need 3 for an exponent",
                crate::util::text::plural(obs.len(), "drop")
            ));
            return None;
        }
        let Some(r) = fit_and_bootstrap(obs, 1, settings, name, &slope, warnings) else {
            warnings.push(format!("{name}: all drops at one velocity; no exponent"));
            return None;
        };
        let est = r.estimate(0, r.fit.coef[1], r.fit.stderr(1), settings.resamples);
        Some((est, r.fit.coef[0], r.weighted))
    };
    let mut out = Vec::new();
    for (key, gs) in by_r {
        let radius_mm = key as f64 / 1000.0;
        let pi_obs: Vec<Obs> = gs.iter().map(|g| Obs::log_log(&g.eta, &g.pi)).collect();
        let tau_obs: Vec<Obs> = gs
            .iter()
            .filter_map(|g| g.tau_c_s.map(|t| Obs::log_log(&g.v_m_s, &t)))
            .collect();
        let mut e = ExponentFit {
            radius_mm,
            n_drops: gs.len(),
            nu: None,
            nu_stderr: None,
            nu_ci: None,
            nu_intercept: None,
            mu: None,
            mu_stderr: None,
            mu_ci: None,
            mu_intercept: None,
            n_tau: tau_obs.len(),
            weighted: false,
        };
        // Each exponent: (estimate, intercept, weighted) when its fit ran.
        let nu = exponent(&pi_obs, "in all", &format!("nu (R = {radius_mm} mm)"));
        let mu = exponent(
            &tau_obs,
            "with a contact time",
            &format!("mu (R = {radius_mm} mm)"),
        );
        if let Some((est, intercept, _)) = &nu {
            e.nu = Some(est.value);
            e.nu_stderr = est.stderr;
            e.nu_ci = est.ci95;
            e.nu_intercept = Some(*intercept);
        }
        if let Some((est, intercept, _)) = &mu {
            e.mu = Some(est.value);
            e.mu_stderr = est.stderr;
            e.mu_ci = est.ci95;
            e.mu_intercept = Some(*intercept);
        }
        // Weighted only when a fit ran and every fit that ran was weighted.
        let ran: Vec<bool> = [&nu, &mu]
            .iter()
            .filter_map(|f| f.as_ref().map(|f| f.2))
            .collect();
        e.weighted = !ran.is_empty() && ran.iter().all(|&w| w);
        out.push(e);
    }
    out
}

/// Split drops at the crossover: (below, above, description) when both
/// sides hold at least 3 drops, else everything on both sides.
fn regimes<'a>(
    groups: &'a [DropGroups],
    cross: Option<&Estimate>,
    warnings: &mut Vec<String>,
) -> (Vec<&'a DropGroups>, Vec<&'a DropGroups>, [String; 2]) {
    if let Some(x) = cross.map(|c| c.value).filter(|x| *x > 0.0) {
        let (lo, hi): (Vec<_>, Vec<_>) = groups.iter().partition(|g| g.big_xi.value < x);
        if lo.len() >= 3 && hi.len() >= 3 {
            return (
                lo,
                hi,
                [
                    format!("Xi < {x:.4} (first term of Eq. 8 dominant)"),
                    format!("Xi >= {x:.4} (second term of Eq. 8 dominant)"),
                ],
            );
        }
        warnings.push(format!(
            "crossover Xi = {x:.4} leaves fewer than 3 drops on one side; \
             the asymptotic constants are fitted to all drops"
        ));
    } else {
        warnings.push(
            "no positive crossover Xi (A1 and A2 of opposite sign, or no series fit); \
             the asymptotic constants are fitted to all drops"
                .to_string(),
        );
    }
    let all: Vec<_> = groups.iter().collect();
    (all.clone(), all, ["all drops".into(), "all drops".into()])
}

/// Every fit of the collapse stage over the drops that have groups.
pub fn fit_all(groups: &[DropGroups], settings: FitSettings) -> Fits {
    let mut warnings = Vec::new();
    // Where the warnings that only say a fit had too few drops are.
    let mut few = Vec::new();
    let psi_obs: Vec<Obs> = groups
        .iter()
        .map(|g| Obs::linear(&g.big_xi, &g.psi))
        .collect();
    let omega_obs: Vec<Obs> = groups
        .iter()
        .filter_map(|g| g.big_omega.map(|o| Obs::linear(&g.big_xi, &o)))
        .collect();
    let (psi_series, crossover_xi) =
        match series(&psi_obs, "psi_series", settings, &mut warnings, &mut few) {
            Some((s, c)) => (Some(s), c),
            None => (None, None),
        };
    if let Some(c) = &crossover_xi {
        if c.value <= 0.0 {
            warnings.push(format!(
                "crossover Xi = A1/A2 = {:.4} is not positive: the two leading terms of Eq. 8 \
                 have opposite signs and never balance",
                c.value
            ));
        }
    }
    let omega_series = series(
        &omega_obs,
        "omega_series",
        settings,
        &mut warnings,
        &mut few,
    )
    .map(|s| s.0);

    if psi_series.is_none() && psi_obs.len() < 4 {
        // No crossover for want of a series: the same lack of drops.
        few.push(warnings.len());
    }
    let (lo, hi, sel) = regimes(groups, crossover_xi.as_ref(), &mut warnings);
    let eq5_obs: Vec<Obs> = lo.iter().map(|g| log_ratio(&g.psi, None)).collect();
    let eq7_obs: Vec<Obs> = hi
        .iter()
        .map(|g| log_ratio(&g.psi, Some(&g.big_xi)))
        .collect();
    let eq1e_obs: Vec<Obs> = lo
        .iter()
        .filter_map(|g| g.big_omega.map(|o| log_ratio(&o, None)))
        .collect();
    let eq11_obs: Vec<Obs> = hi
        .iter()
        .filter_map(|g| g.big_omega.map(|o| log_ratio(&o, Some(&g.big_xi))))
        .collect();
    let [sel_lo, sel_hi] = sel;
    let eq5 = asymptote(
        &eq5_obs,
        "Pi = c1 (kappa/phi)^(1/3) eta^(1/3), i.e. Psi = c1 (Eq. 5)",
        "eq5_c1",
        sel_lo.clone(),
        settings,
        &mut warnings,
    );
    let eq7 = asymptote(
        &eq7_obs,
        "Pi' = c2 (xi kappa' eta / phi)^(1/6), i.e. Psi/Xi = c2 (Eq. 7)",
        "eq7_c2",
        sel_hi.clone(),
        settings,
        &mut warnings,
    );
    let eq1e = asymptote(
        &eq1e_obs,
        "tau_c/R = d1 phi^(-1/3) (h/R)^(1/3) (rho/(E v))^(1/3), i.e. Omega = d1 (Eq. 1e)",
        "eq1e_d1",
        sel_lo,
        settings,
        &mut warnings,
    );
    let eq11 = asymptote(
        &eq11_obs,
        "omega = d2 xi (kappa/phi)^(1/6) eta^(1/6), i.e. Omega/Xi = d2 (Eq. 11)",
        "eq11_d2",
        sel_hi,
        settings,
        &mut warnings,
    );
    let exponents = exponents(groups, settings, &mut warnings, &mut few);
    let nothing_fitted = psi_series.is_none()
        && omega_series.is_none()
        && exponents.iter().all(|e| e.nu.is_none() && e.mu.is_none());
    let few_drops = (nothing_fitted && !groups.is_empty() && !few.is_empty()).then(|| {
        let mut k = 0;
        warnings.retain(|_| {
            k += 1;
            !few.contains(&(k - 1))
        });
        let text = few_drops_text(groups);
        warnings.insert(0, text.clone());
        text
    });
    Fits {
        psi_series,
        omega_series,
        crossover_xi,
        eq5,
        eq7,
        eq1e,
        eq11,
        exponents,
        warnings,
        few_drops,
    }
}

/// What `groups`, too few for any exponent or series, can and cannot show
/// ([`Fits::few_drops`]).
fn few_drops_text(groups: &[DropGroups]) -> String {
    let mut by_r: BTreeMap<i64, usize> = BTreeMap::new();
    for g in groups {
        *by_r
            .entry((g.sphere_radius_mm * 1000.0).round() as i64)
            .or_default() += 1;
    }
    let most = by_r.values().copied().max().unwrap_or(0);
    format!(
        "{} of {} ({} of one radius at most): each drop is measured (v, δ, a, τc, its \
         contact law) and the fixed-exponent constants are fitted to them, but the \
         collapse's fits need more drops: an exponent ν or μ needs 3 drops of one radius \
         at different heights, the series Ψ(Ξ) and Ω(Ξ) need 4. To see them, render and \
         measure a campaign: `dropscope render --campaign --repeats 2 --out campaign` \
         (60 drops), then `dropscope process --manifest campaign/runs.csv --out \
         campaign-results` and `dropscope collapse campaign-results/drops.csv`",
        crate::util::text::plural(groups.len(), "drop"),
        match by_r.len() {
            1 => "1 radius".to_string(),
            n => format!("{n} radii"),
        },
        most
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn theory_constants_match_the_paper() {
        // Maruoka 2019 below Eq. (1e): C0 ≈ 3.533; docs/physics.md: 3.5333, B ≈ 4.20655.
        assert!((omega_theory() - 3.5333).abs() < 1e-4, "{}", omega_theory());
        assert!((beta_third_half() - 4.20655).abs() < 1e-5);
        assert!((psi_theory() - 1.259_921).abs() < 1e-6);
    }

    #[test]
    fn bootstrap_is_reproducible_and_seed_dependent() {
        let obs: Vec<Obs> = (0..20)
            .map(|i| {
                let x = i as f64 * 0.1;
                Obs {
                    x,
                    y: 1.0 + 0.5 * x + if i % 3 == 0 { 0.05 } else { -0.02 },
                    sx: None,
                    sy: None,
                }
            })
            .collect();
        let s = FitSettings {
            resamples: 200,
            seed: 7,
        };
        let d = |f: &LsFit| vec![f.coef[1]];
        let a = bootstrap(&obs, 1, s, "x", &d);
        let b = bootstrap(&obs, 1, s, "x", &d);
        assert_eq!(a, b);
        let c = bootstrap(&obs, 1, FitSettings { seed: 8, ..s }, "x", &d);
        assert_ne!(a, c);
    }
}
