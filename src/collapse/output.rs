//! What the collapse stage writes: `collapse.csv` (one row per drop of the
//! input, skipped ones included with the reason) and `fits.json`. Both are
//! returned as bytes; the same input gives the same bytes.

use serde::Serialize;

use super::diagnostics::ForceLaw;
use super::fit::{self, AsymptoteFit, Estimate, ExponentFit, Fits, SeriesFit};
use super::groups::{DropGroups, Quantity};
use super::DropOutcome;

/// A row of collapse.csv. Column names follow the paper's symbols
/// (capitalised names are the capital Greek letters: `Pi` = Π, `Xi` = Ξ,
/// `Omega` = Ω, `Psi` = Ψ; `omega` = ω, `xi` = ξ). Every group is
/// dimensionless; `_err` is its first-order one-sigma error, empty when unknown.
#[derive(Debug, Serialize)]
#[allow(non_snake_case)]
struct Row<'a> {
    row: u64,
    run: &'a str,
    sphere_radius_mm: f64,
    surface: &'a str,
    used: bool,
    a_source: &'a str,
    note: &'a str,
    Pi: Option<f64>,
    Pi_err: Option<f64>,
    xi: Option<f64>,
    xi_err: Option<f64>,
    eta: Option<f64>,
    eta_err: Option<f64>,
    kappa: Option<f64>,
    omega: Option<f64>,
    omega_err: Option<f64>,
    Psi: Option<f64>,
    Psi_err: Option<f64>,
    Xi: Option<f64>,
    Xi_err: Option<f64>,
    Omega: Option<f64>,
    Omega_err: Option<f64>,
    Pi_prime: Option<f64>,
    Pi_prime_err: Option<f64>,
    kappa_prime: Option<f64>,
    kappa_prime_err: Option<f64>,
    /// The drops.csv this row was computed from ([`crate::dataset::id`]).
    dataset_id: &'a str,
}

fn v(q: &Quantity) -> Option<f64> {
    Some(q.value)
}

/// collapse.csv as bytes.
pub fn collapse_csv(outcomes: &[DropOutcome], dataset_id: &str) -> Vec<u8> {
    let mut w = csv::Writer::from_writer(Vec::new());
    for o in outcomes {
        let g: Option<&DropGroups> = o.groups.as_ref().ok();
        let note = match &o.groups {
            Ok(g) if g.a_source.is_geometric() => {
                "geometric contact radius: Xi^2 = Psi (2 - Pi) by construction"
            }
            Ok(_) => "",
            Err(reason) => reason.0.as_str(),
        };
        // Text cells: nothing a spreadsheet runs ([`crate::util::text::csv_cell`]).
        let (run, surface) = (
            crate::util::text::csv_cell(&o.run),
            crate::util::text::csv_cell(&o.surface),
        );
        let note = crate::util::text::csv_cell(note);
        let row = Row {
            row: o.row,
            run: &run,
            sphere_radius_mm: o.sphere_radius_mm,
            surface: &surface,
            used: g.is_some(),
            a_source: g.map_or("", |g| g.a_source.as_str()),
            note: &note,
            Pi: g.and_then(|g| v(&g.pi)),
            Pi_err: g.and_then(|g| g.pi.err()),
            xi: g.and_then(|g| v(&g.xi)),
            xi_err: g.and_then(|g| g.xi.err()),
            eta: g.and_then(|g| v(&g.eta)),
            eta_err: g.and_then(|g| g.eta.err()),
            kappa: g.map(|g| g.kappa),
            omega: g.and_then(|g| g.omega.map(|q| q.value)),
            omega_err: g.and_then(|g| g.omega.and_then(|q| q.err())),
            Psi: g.and_then(|g| v(&g.psi)),
            Psi_err: g.and_then(|g| g.psi.err()),
            Xi: g.and_then(|g| v(&g.big_xi)),
            Xi_err: g.and_then(|g| g.big_xi.err()),
            Omega: g.and_then(|g| g.big_omega.map(|q| q.value)),
            Omega_err: g.and_then(|g| g.big_omega.and_then(|q| q.err())),
            Pi_prime: g.and_then(|g| v(&g.pi_prime)),
            Pi_prime_err: g.and_then(|g| g.pi_prime.err()),
            kappa_prime: g.and_then(|g| v(&g.kappa_prime)),
            kappa_prime_err: g.and_then(|g| g.kappa_prime.err()),
            dataset_id,
        };
        w.serialize(row)
            .expect("serialising a collapse row into memory cannot fail");
    }
    w.into_inner().expect("flushing into memory cannot fail")
}

#[derive(Serialize)]
struct Psi<'a> {
    #[serde(rename = "A1")]
    a1: &'a Estimate,
    #[serde(rename = "A2")]
    a2: &'a Estimate,
    #[serde(rename = "A3")]
    a3: &'a Estimate,
    law: &'static str,
    n_drops: usize,
    weighted: bool,
    chi2_red: Option<f64>,
    xi_range: [f64; 2],
    condition_number: Option<f64>,
    /// Ξ_min when the constant is an extrapolation to Ξ = 0 (else null).
    extrapolated_from_xi: Option<f64>,
}

#[derive(Serialize)]
struct Omega<'a> {
    #[serde(rename = "B1")]
    b1: &'a Estimate,
    #[serde(rename = "B2")]
    b2: &'a Estimate,
    #[serde(rename = "B3")]
    b3: &'a Estimate,
    law: &'static str,
    n_drops: usize,
    weighted: bool,
    chi2_red: Option<f64>,
    xi_range: [f64; 2],
    condition_number: Option<f64>,
    /// Ξ_min when the constant is an extrapolation to Ξ = 0 (else null).
    extrapolated_from_xi: Option<f64>,
}

#[derive(Serialize)]
struct Crossover<'a> {
    #[serde(flatten)]
    estimate: &'a Estimate,
    definition: &'static str,
}

#[derive(Serialize)]
struct Asymptotes<'a> {
    eq5_c1: Option<&'a AsymptoteFit>,
    eq7_c2: Option<&'a AsymptoteFit>,
    eq1e_d1: Option<&'a AsymptoteFit>,
    eq11_d2: Option<&'a AsymptoteFit>,
}

#[derive(Serialize)]
struct Theory {
    /// 2^{1/3}: Ψ at small Ξ (energy balance, Eq. (4)).
    psi_small_xi: f64,
    /// C0 = (2·2^{1/3}/3) B(1/3, 1/2): Ω at small Ξ (Eq. (1e)).
    omega_small_xi_c0: f64,
    /// B(1/3, 1/2) = Γ(1/3)Γ(1/2)/Γ(5/6).
    beta_1_3_1_2: f64,
    /// (A1 − 2^{1/3}) / σ_A1.
    a1_minus_theory_in_stderr: Option<f64>,
    /// (B1 − C0) / σ_B1.
    b1_minus_theory_in_stderr: Option<f64>,
    source: &'static str,
}

#[derive(Serialize)]
struct Skipped<'a> {
    row: u64,
    run: &'a str,
    reason: &'a str,
}

/// What was run, for traceability.
#[derive(Debug, Clone, Serialize)]
pub struct Provenance {
    /// The version of dropscope that ran the collapse.
    pub dropscope_version: &'static str,
    /// The input table's file name (not its path: the same data in two
    /// folders gives the same bytes).
    pub drops_csv: String,
    /// [`crate::dataset::id`] of the drops.csv read.
    pub dataset_id: String,
    /// Which contact radius was asked for: `measured` or `geometric` (`--contact-radius`).
    pub contact_radius: &'static str,
    /// Number of bootstrap resamples per fit (0: no intervals).
    pub bootstrap_resamples: usize,
    /// The bootstrap's base seed.
    pub seed: u64,
    /// The surfaces used, by name.
    pub surfaces: Vec<SurfaceUsed>,
}

/// A material of pipeline.toml that entered the groups.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SurfaceUsed {
    /// The `[surface.<name>]` name.
    pub name: String,
    /// Young's modulus E, Pa.
    pub modulus_pa: f64,
    /// Pillar height h, m.
    pub pillar_height_m: f64,
    /// Solid fraction φ.
    pub solid_fraction: f64,
}

#[derive(Serialize)]
struct FitsJson<'a> {
    provenance: &'a Provenance,
    n_used: usize,
    n_skipped: usize,
    n_geometric_contact_radius: usize,
    // What the data support first: the exponents per radius and the
    // fixed-exponent constants; then the series, whose constant terms may
    // be extrapolations (see `extrapolated_from_xi`).
    exponents: &'a [ExponentFit],
    asymptotes: Asymptotes<'a>,
    psi_series: Option<Psi<'a>>,
    omega_series: Option<Omega<'a>>,
    crossover_xi: Option<Crossover<'a>>,
    theory: Theory,
    force_laws: &'a [ForceLaw],
    skipped: Vec<Skipped<'a>>,
    /// Too few drops for any exponent or series: what they can and cannot
    /// show (also the first warning).
    #[serde(skip_serializing_if = "Option::is_none")]
    few_drops: Option<&'a str>,
    warnings: &'a [String],
}

fn z(s: Option<&SeriesFit>, theory: f64) -> Option<f64> {
    let c = &s?.coef[0];
    c.stderr
        .filter(|e| *e > 0.0)
        .map(|e| (c.value - theory) / e)
}

/// fits.json as pretty-printed bytes (fields in a fixed order).
pub fn fits_json(
    prov: &Provenance,
    outcomes: &[DropOutcome],
    fits: &Fits,
    force_laws: &[ForceLaw],
    warnings: &[String],
) -> Vec<u8> {
    let used: Vec<&DropGroups> = outcomes
        .iter()
        .filter_map(|o| o.groups.as_ref().ok())
        .collect();
    let doc = FitsJson {
        provenance: prov,
        n_used: used.len(),
        n_skipped: outcomes.iter().filter(|o| o.skipped()).count(),
        n_geometric_contact_radius: used.iter().filter(|g| g.a_source.is_geometric()).count(),
        psi_series: fits.psi_series.as_ref().map(|s| Psi {
            a1: &s.coef[0],
            a2: &s.coef[1],
            a3: &s.coef[2],
            law: "Psi = A1 + A2 Xi + A3 Xi^2 (Eq. 8)",
            n_drops: s.n_drops,
            weighted: s.weighted,
            chi2_red: s.chi2_red,
            xi_range: s.xi_range,
            condition_number: s.condition_number,
            extrapolated_from_xi: s.extrapolated_from_xi,
        }),
        omega_series: fits.omega_series.as_ref().map(|s| Omega {
            b1: &s.coef[0],
            b2: &s.coef[1],
            b3: &s.coef[2],
            law: "Omega = B1 + B2 Xi + B3 Xi^2 (Eq. 10 expanded as Eq. 8)",
            n_drops: s.n_drops,
            weighted: s.weighted,
            chi2_red: s.chi2_red,
            xi_range: s.xi_range,
            condition_number: s.condition_number,
            extrapolated_from_xi: s.extrapolated_from_xi,
        }),
        crossover_xi: fits.crossover_xi.as_ref().map(|e| Crossover {
            estimate: e,
            definition: "Xi = A1/A2, where the two leading terms of Eq. 8 are equal",
        }),
        asymptotes: Asymptotes {
            eq5_c1: fits.eq5.as_ref(),
            eq7_c2: fits.eq7.as_ref(),
            eq1e_d1: fits.eq1e.as_ref(),
            eq11_d2: fits.eq11.as_ref(),
        },
        theory: Theory {
            psi_small_xi: fit::psi_theory(),
            omega_small_xi_c0: fit::omega_theory(),
            beta_1_3_1_2: fit::beta_third_half(),
            a1_minus_theory_in_stderr: z(fits.psi_series.as_ref(), fit::psi_theory()),
            b1_minus_theory_in_stderr: z(fits.omega_series.as_ref(), fit::omega_theory()),
            source: "energy balance of the elastic-foundation model (Chastel et al.), \
                     Eqs. 4 and 1e of Maruoka 2019",
        },
        exponents: &fits.exponents,
        force_laws,
        skipped: outcomes
            .iter()
            .filter(|o| o.skipped())
            .filter_map(|o| {
                o.groups.as_ref().err().map(|r| Skipped {
                    row: o.row,
                    run: &o.run,
                    reason: &r.0,
                })
            })
            .collect(),
        few_drops: fits.few_drops.as_deref(),
        warnings,
    };
    let mut bytes = serde_json::to_vec_pretty(&doc).expect("fits serialise to JSON");
    bytes.push(b'\n');
    bytes
}
