//! The dimensionless groups of SPEC §3, per drop, with first-order
//! uncertainties.
//!
//! Every group is a power-law monomial of the four measured quantities
//! p = (v, δ, a, τc) times material and sphere constants (R, ρ, E, h, φ,
//! taken as exact): G = C · v^e_v · δ^e_δ · a^e_a · τc^e_τ. First-order
//! propagation with independent errors then gives the relative error
//! σ_G / G = |(e_v r_v, e_δ r_δ, e_a r_a, e_τ r_τ)|, r_i = σ_i / p_i.
//! We keep that vector (the *relative sensitivity*) rather than only its
//! norm, because groups of one drop share inputs (Ψ and Ξ both contain v),
//! and the fits need the covariance of what they regress on what.
//!
//! A missing `_err` cell (or a negative / non-finite one) is **unknown**, not
//! zero: any group that depends on that input then has an unknown error
//! (an empty `_err` cell in collapse.csv), and the fits that use it fall back
//! to unweighted least squares with a warning (see `fit.rs`).
//!
//! Definitions (Eqs. (2), (4), (6), (9), (10) of Maruoka 2019; SPEC §3):
//! Π = δ/R, ξ = a/R, η = ρv²/E, κ = h/R, ω = τc v/R,
//! Ψ = Π φ^{1/3} κ^{-1/3} η^{-1/3}, Ξ = ξ φ^{1/6} κ^{-1/6} η^{-1/6},
//! Ω = ω φ^{1/3} κ^{-1/3} η^{-1/3}, and for Eq. (7) Π' = δ/a, κ' = h/a.

use crate::config::Surface;
use crate::dataset::{DropRecord, DropStatus};

/// Index of each measured input in a sensitivity vector.
pub const V: usize = 0;
/// Index of δ_max.
pub const DELTA: usize = 1;
/// Index of the contact radius a.
pub const A: usize = 2;
/// Index of τc.
pub const TAU: usize = 3;

/// Relative one-sigma errors of (v, δ, a, τc); `None` = unknown.
pub type RelErrors = [Option<f64>; 4];

/// A group's value and its relative sensitivity vector `(e_i r_i)`, whose
/// Euclidean norm is σ_G / G. `rel_sens` is `None` when an input the group
/// depends on has an unknown error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quantity {
    /// The group's value.
    pub value: f64,
    /// Relative sensitivity `(e_i r_i)` over (v, δ, a, τc); `None`: an input's error unknown.
    pub rel_sens: Option<[f64; 4]>,
}

impl Quantity {
    /// A monomial with exponents `exps` of (v, δ, a, τc).
    fn monomial(value: f64, exps: [f64; 4], rel: &RelErrors) -> Self {
        let mut s = [0.0; 4];
        for i in 0..4 {
            if exps[i] != 0.0 {
                match rel[i] {
                    Some(r) => s[i] = exps[i] * r,
                    None => {
                        return Quantity {
                            value,
                            rel_sens: None,
                        }
                    }
                }
            }
        }
        Quantity {
            value,
            rel_sens: Some(s),
        }
    }

    /// One-sigma error (first order), `None` if unknown.
    pub fn err(&self) -> Option<f64> {
        self.rel_sens
            .map(|s| self.value.abs() * s.iter().map(|x| x * x).sum::<f64>().sqrt())
    }

    /// Absolute sensitivity vector ∂G/∂p_i · σ_i.
    pub fn abs_sens(&self) -> Option<[f64; 4]> {
        self.rel_sens.map(|s| s.map(|x| x * self.value))
    }
}

/// Where the contact radius a used for ξ and Ξ came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ASource {
    /// The measured half-width at the surface row (`a_max_mm`), the default.
    Measured,
    /// `a_max_mm` equals √(R² − (R − δ)²) to 1 ppm: measured, but geometric in effect.
    MeasuredEqualsGeometric,
    /// `a_max_mm` was missing: `a_geom_mm` (or √(R² − (R − δ)²)) used instead.
    GeometricFallback,
    /// The geometric value was requested (`--contact-radius geometric`).
    Geometric,
}

impl ASource {
    /// Its word in collapse.csv (`measured`, `geometric_fallback`, …).
    pub fn as_str(self) -> &'static str {
        match self {
            ASource::Measured => "measured",
            ASource::MeasuredEqualsGeometric => "measured_equals_geometric",
            ASource::GeometricFallback => "geometric_fallback",
            ASource::Geometric => "geometric",
        }
    }

    /// True when Ξ² = Ψ(2 − Π) holds by construction for this drop.
    pub fn is_geometric(self) -> bool {
        self != ASource::Measured
    }
}

/// Which contact radius to use (`--contact-radius`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ContactRadius {
    /// `a_max_mm`, the measured half-width (falls back to geometric, loudly, when missing).
    #[default]
    Measured,
    /// `a_geom_mm` = √(R² − (R − δ)²): makes Ψ(Ξ) hold by construction.
    Geometric,
}

/// Every group of SPEC §3 for one drop.
#[derive(Debug, Clone, PartialEq)]
pub struct DropGroups {
    /// The run's name.
    pub run: String,
    /// Sphere radius R, mm.
    pub sphere_radius_mm: f64,
    /// Name of the surface whose E, h, φ were used.
    pub surface: String,
    /// Where the contact radius a came from.
    pub a_source: ASource,
    /// Relative errors of (v, δ, a, τc) as read.
    pub rel_err: RelErrors,
    /// v (m/s) and τc (s) themselves, for the τc ∝ v^μ fit.
    pub v_m_s: Quantity,
    /// τc, s; `None` when the drop has none.
    pub tau_c_s: Option<Quantity>,
    /// Π = δ/R.
    pub pi: Quantity,
    /// ξ = a/R.
    pub xi: Quantity,
    /// η = ρv²/E, the Cauchy number.
    pub eta: Quantity,
    /// κ = h/R, exact.
    pub kappa: f64,
    /// ω = τc v/R; `None` without τc.
    pub omega: Option<Quantity>,
    /// Ψ = Π φ^{1/3} κ^{-1/3} η^{-1/3}.
    pub psi: Quantity,
    /// Ξ = ξ φ^{1/6} κ^{-1/6} η^{-1/6}.
    pub big_xi: Quantity,
    /// Ω = ω φ^{1/3} κ^{-1/3} η^{-1/3}; `None` without τc.
    pub big_omega: Option<Quantity>,
    /// Π' = δ/a (Eq. (6)).
    pub pi_prime: Quantity,
    /// κ' = h/a (Eq. (6)).
    pub kappa_prime: Quantity,
}

/// Why a drop does not enter the collapse (it is skipped and counted).
#[derive(Debug, Clone, PartialEq)]
pub struct SkipReason(pub String);

fn positive(name: &str, v: Option<f64>) -> Result<f64, SkipReason> {
    match v {
        Some(x) if x.is_finite() && x > 0.0 => Ok(x),
        Some(x) => Err(SkipReason(format!("{name} = {x} is not a positive number"))),
        None => Err(SkipReason(format!("{name} is empty"))),
    }
}

/// A relative error from an absolute one; negative, NaN or missing → unknown.
fn rel(err: Option<f64>, value: f64) -> Option<f64> {
    err.filter(|e| e.is_finite() && *e >= 0.0)
        .map(|e| e / value.abs())
}

/// Compute every group for one record with the surface `surface` (named
/// `surface_name`). Failed rows and rows lacking v, δ or a are skipped with
/// the reason; τc may be missing (then ω and Ω are absent).
pub fn compute(
    rec: &DropRecord,
    surface_name: &str,
    surface: &Surface,
    choice: ContactRadius,
) -> Result<DropGroups, SkipReason> {
    measured_status(rec)?;
    let (r_mm, rho) = sphere(rec)?;
    let v = positive("v_impact_m_s", rec.v_impact_m_s)?;
    let delta_mm = positive("delta_max_mm", rec.delta_max_mm)?;
    if delta_mm >= r_mm {
        return Err(SkipReason(format!(
            "delta_max_mm = {delta_mm} is not smaller than the radius {r_mm} mm"
        )));
    }
    let (a_mm, a_err, a_source) = contact_radius(rec, r_mm, delta_mm, choice)?;
    let tau_ms = rec.tau_c_ms.filter(|t| t.is_finite() && *t > 0.0);

    let rel_err: RelErrors = [
        rel(rec.v_impact_m_s_err, v),
        rel(rec.delta_max_mm_err, delta_mm),
        rel(a_err, a_mm),
        tau_ms.and_then(|t| rel(rec.tau_c_ms_err, t)),
    ];
    let q = |value: f64, exps: [f64; 4]| Quantity::monomial(value, exps, &rel_err);

    let r = r_mm * 1e-3;
    let delta = delta_mm * 1e-3;
    let a = a_mm * 1e-3;
    let h = surface.pillar_height_m;
    let phi = surface.solid_fraction;
    let e_mod = surface.modulus_pa;

    let pi = delta / r;
    let xi = a / r;
    let eta = rho * v * v / e_mod;
    let kappa = h / r;
    // (φ / (κ η))^{1/3} and its square root, the collapse's common factors.
    let f3 = (phi / (kappa * eta)).cbrt();
    let f6 = f3.sqrt();
    let tau = tau_ms.map(|t| t * 1e-3);
    let omega = tau.map(|t| t * v / r);

    // Every group a finite number above 0 (Ψ = Ξ = 0 from an η that
    // overflowed would sit on the plots as data).
    let big_omega = omega.map(|w| w * f3);
    all_normal([
        ("Pi", Some(pi)),
        ("xi", Some(xi)),
        ("eta", Some(eta)),
        ("Psi", Some(pi * f3)),
        ("Xi", Some(xi * f6)),
        ("Omega", big_omega),
    ])?;

    Ok(DropGroups {
        run: rec.run.clone(),
        sphere_radius_mm: r_mm,
        surface: surface_name.to_string(),
        a_source,
        rel_err,
        v_m_s: q(v, [1.0, 0.0, 0.0, 0.0]),
        tau_c_s: tau.map(|t| q(t, [0.0, 0.0, 0.0, 1.0])),
        pi: q(pi, [0.0, 1.0, 0.0, 0.0]),
        xi: q(xi, [0.0, 0.0, 1.0, 0.0]),
        eta: q(eta, [2.0, 0.0, 0.0, 0.0]),
        kappa,
        omega: omega.map(|w| q(w, [1.0, 0.0, 0.0, 1.0])),
        psi: q(pi * f3, [-2.0 / 3.0, 1.0, 0.0, 0.0]),
        big_xi: q(xi * f6, [-1.0 / 3.0, 0.0, 1.0, 0.0]),
        big_omega: omega.map(|w| q(w * f3, [1.0 / 3.0, 0.0, 0.0, 1.0])),
        pi_prime: q(delta / a, [0.0, 1.0, -1.0, 0.0]),
        kappa_prime: q(h / a, [0.0, 0.0, -1.0, 0.0]),
    })
}

/// Why a row that is no measured impact (failed, rejected, or tracked
/// without a contact) is skipped.
fn measured_status(rec: &DropRecord) -> Result<(), SkipReason> {
    if rec.status == DropStatus::Failed {
        let why = if rec.reason.is_empty() {
            "no reason given"
        } else {
            &rec.reason
        };
        return Err(SkipReason(format!("status failed ({why})")));
    }
    if rec.status == DropStatus::Rejected {
        return Err(SkipReason(format!("status rejected ({})", rec.reason)));
    }
    if rec.status == DropStatus::Tracked {
        return Err(SkipReason(
            "status tracked: no contact, so no impact to collapse".into(),
        ));
    }
    Ok(())
}

/// The sphere's radius (mm) and density (kg/m³), positive and within their
/// physical ranges.
fn sphere(rec: &DropRecord) -> Result<(f64, f64), SkipReason> {
    let r_mm = positive("sphere_radius_mm", Some(rec.sphere_radius_mm))?;
    let rho = positive("sphere_density_kg_m3", Some(rec.sphere_density_kg_m3))?;
    // A hand-made drops.csv's radius and density within their physical
    // ranges, so that every group below is a finite number.
    for (name, range, x) in [
        (
            "sphere_radius_mm",
            crate::util::ranges::SPHERE_RADIUS_MM,
            r_mm,
        ),
        (
            "sphere_density_kg_m3",
            crate::util::ranges::DENSITY_KG_M3,
            rho,
        ),
    ] {
        range.check(x).map_err(|allowed| {
            SkipReason(format!(
                "{name} = {}: {allowed}",
                crate::util::ranges::show(x)
            ))
        })?;
    }
    Ok((r_mm, rho))
}

/// The contact radius a (mm), its error and where it came from, as
/// `choice` asks, for a sphere of radius `r_mm` at penetration `delta_mm`.
fn contact_radius(
    rec: &DropRecord,
    r_mm: f64,
    delta_mm: f64,
    choice: ContactRadius,
) -> Result<(f64, Option<f64>, ASource), SkipReason> {
    // The geometric contact radius √(R² − (R − δ)²) and its first-order error
    // σ_a = (R − δ)/a · σ_δ, used when `a_geom_mm_err` is empty (its
    // correlation with δ is not carried: such drops are flagged as collapsing
    // by construction anyway).
    let a_geo_calc = (r_mm * r_mm - (r_mm - delta_mm).powi(2)).sqrt();
    let geometric = |rec: &DropRecord| -> (f64, Option<f64>) {
        let from_delta = |a: f64| rec.delta_max_mm_err.map(|e| (r_mm - delta_mm) / a * e);
        match rec.a_geom_mm.filter(|a| a.is_finite() && *a > 0.0) {
            Some(a) => (a, rec.a_geom_mm_err.or_else(|| from_delta(a))),
            None => (a_geo_calc, from_delta(a_geo_calc)),
        }
    };
    Ok(match choice {
        ContactRadius::Geometric => {
            let (a, e) = geometric(rec);
            (a, e, ASource::Geometric)
        }
        ContactRadius::Measured => match rec.a_max_mm {
            Some(a) if a.is_finite() && a > 0.0 => {
                let src = if ((a - a_geo_calc) / a_geo_calc).abs() < 1e-6 {
                    ASource::MeasuredEqualsGeometric
                } else {
                    ASource::Measured
                };
                (a, rec.a_max_mm_err, src)
            }
            Some(a) => {
                return Err(SkipReason(format!(
                    "a_max_mm = {a} is not a positive number"
                )))
            }
            None => {
                let (a, e) = geometric(rec);
                (a, e, ASource::GeometricFallback)
            }
        },
    })
}

/// Why a drop is skipped when one of its groups (named, `None`: absent) is
/// no finite number above 0.
fn all_normal(groups: [(&str, Option<f64>); 6]) -> Result<(), SkipReason> {
    for (name, x) in groups {
        // Normal doubles only: a subnormal (below 2.2e-308) has lost its
        // precision, and a log axis cannot reach it.
        if let Some(x) = x.filter(|x| !(x.is_normal() && *x > 0.0)) {
            return Err(SkipReason(format!(
                "{name} = {} is not a finite positive number (a value of the row is out of \
                 any physical range)",
                crate::util::ranges::show(x)
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record() -> DropRecord {
        let mut r = DropRecord::failed("d", 4.5, "");
        r.status = DropStatus::Ok;
        r.v_impact_m_s = Some(2.0);
        r.delta_max_mm = Some(1.2);
        r.a_max_mm = Some(2.5);
        r.tau_c_ms = Some(5.0);
        r
    }

    #[test]
    fn missing_error_is_unknown_not_zero() {
        let mut rec = record();
        rec.delta_max_mm_err = Some(0.012);
        let g = compute(
            &rec,
            "pdms",
            &Surface::paper_pdms(),
            ContactRadius::Measured,
        )
        .unwrap();
        // Π depends on δ only: its error is known (1 % of Π).
        assert!((g.pi.err().unwrap() / g.pi.value - 0.01).abs() < 1e-12);
        // Ψ also needs σ_v, which is missing: unknown.
        assert_eq!(g.psi.err(), None);
        assert_eq!(g.a_source, ASource::Measured);
    }

    #[test]
    fn geometric_radius_is_flagged_however_it_arrives() {
        let mut rec = record();
        let geo = (4.5f64 * 4.5 - 3.3 * 3.3).sqrt();
        rec.a_max_mm = None;
        let s = Surface::paper_pdms();
        let g = compute(&rec, "pdms", &s, ContactRadius::Measured).unwrap();
        assert_eq!(g.a_source, ASource::GeometricFallback);
        assert!((g.xi.value * 4.5 - geo).abs() < 1e-12);
        rec.a_max_mm = Some(geo);
        let g = compute(&rec, "pdms", &s, ContactRadius::Measured).unwrap();
        assert_eq!(g.a_source, ASource::MeasuredEqualsGeometric);
        // By construction Ξ² = Ψ (2 − Π) (docs/physics.md).
        let lhs = g.big_xi.value.powi(2);
        let rhs = g.psi.value * (2.0 - g.pi.value);
        assert!((lhs - rhs).abs() < 1e-12 * lhs, "{lhs} vs {rhs}");
    }

    #[test]
    fn unusable_rows_say_why() {
        let mut rec = record();
        rec.v_impact_m_s = None;
        let e = compute(
            &rec,
            "pdms",
            &Surface::paper_pdms(),
            ContactRadius::Measured,
        );
        assert!(e.unwrap_err().0.contains("v_impact_m_s"));
        let failed = DropRecord::failed("x", 3.0, "no sphere found");
        let e = compute(
            &failed,
            "pdms",
            &Surface::paper_pdms(),
            ContactRadius::Measured,
        );
        assert!(e.unwrap_err().0.contains("no sphere found"));
        // A density that makes η overflow: skipped, never Ψ = Ξ = Ω = 0.
        let mut rec = record();
        rec.sphere_density_kg_m3 = 1e308;
        let e = compute(
            &rec,
            "pdms",
            &Surface::paper_pdms(),
            ContactRadius::Measured,
        );
        assert!(e.unwrap_err().0.contains("sphere_density_kg_m3 = 1e308"));
        let mut rec = record();
        rec.v_impact_m_s = Some(1e-160);
        let e = compute(
            &rec,
            "pdms",
            &Surface::paper_pdms(),
            ContactRadius::Measured,
        );
        assert!(e.unwrap_err().0.contains("not a finite positive number"));
    }
}
