//! The collapse stage end to end: known laws in, the same laws out; groups
//! against a hand computation; plots that parse and show every point and
//! byte-identical reruns ([`plots`]); clear errors ([`command`]).

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

use dropscope::collapse::groups::ContactRadius;
use dropscope::collapse::synthetic::{
    contact_track, eq8_dataset, power_law_dataset, write_track, SyntheticSpec,
};
use dropscope::config::{PipelineConfig, EMBEDDED_DEFAULT};
use dropscope::dataset::{self, DropRecord};
use dropscope::job::collapse_job::{self, CollapseOptions};

mod command;
mod plots;

fn config() -> PipelineConfig {
    PipelineConfig::from_toml_str(EMBEDDED_DEFAULT, Path::new("pipeline.toml"), Path::new("."))
        .unwrap()
}

fn args(drops: &Path, out: &Path, plots: bool) -> CollapseOptions {
    CollapseOptions {
        drops: drops.to_path_buf(),
        out: Some(out.to_path_buf()),
        config: None,
        contact_radius: ContactRadius::Measured,
        bootstrap: 1000,
        seed: 11,
        no_plots: !plots,
    }
}

/// Write `records` as drops.csv in a fresh folder, run the collapse, and
/// return (folder, fits.json).
fn run(records: &[DropRecord], plots: bool) -> (tempfile::TempDir, serde_json::Value) {
    let dir = tempfile::tempdir().unwrap();
    let drops = dir.path().join("drops.csv");
    dataset::write_csv(&drops, records).unwrap();
    let out = dir.path().join("out");
    collapse_job::run(&args(&drops, &out, plots), &config(), "pipeline.toml").unwrap();
    let fits = serde_json::from_slice(&std::fs::read(out.join("fits.json")).unwrap()).unwrap();
    (dir, fits)
}

fn f(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

fn collapse_rows(path: &Path) -> Vec<BTreeMap<String, String>> {
    let mut r = csv::Reader::from_path(path).unwrap();
    let head: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
    r.records()
        .map(|rec| {
            head.iter()
                .cloned()
                .zip(rec.unwrap().iter().map(String::from))
                .collect()
        })
        .collect()
}

fn dropscope() -> Command {
    Command::new(env!("CARGO_BIN_EXE_dropscope"))
}

#[test]
fn eq8_dataset_recovers_its_coefficients_within_their_intervals() {
    // 150 drops (5 radii × 30 velocities), Ξ uniform in [0.5, 1.6], noise
    // 0.3 % on v and 1 % on δ, a, τc (stated in the _err columns).
    let truth_a = [1.26, -0.30, 0.05];
    let truth_b = [3.53, -0.80, 0.20];
    let recs = eq8_dataset(&SyntheticSpec::paper(30, 5), truth_a, truth_b, [0.5, 1.6]);
    let (_dir, fits) = run(&recs, false);
    assert_eq!(fits["n_used"], 150);
    for (series, names, truth) in [
        ("psi_series", ["A1", "A2", "A3"], truth_a),
        ("omega_series", ["B1", "B2", "B3"], truth_b),
    ] {
        assert_eq!(fits[series]["weighted"], true);
        for (name, t) in names.iter().zip(truth) {
            let e = &fits[series][name];
            let (v, se) = (f(&e["value"]), f(&e["stderr"]));
            let (lo, hi) = (f(&e["ci95"][0]), f(&e["ci95"][1]));
            eprintln!("{name}: truth {t}, fit {v:.4} ± {se:.4}, 95 % CI [{lo:.4}, {hi:.4}]");
            assert!(lo <= t && t <= hi, "{name} = {t} outside [{lo}, {hi}]");
            assert!((v - t).abs() < 3.0 * se, "{name}: {v} ± {se} vs {t}");
            // The bootstrap interval and ±1.96σ agree to within a factor 1.5
            // (both estimate one sampling spread).
            let ratio = (hi - lo) / (2.0 * 1.96 * se);
            assert!((0.67..1.5).contains(&ratio), "{name}: CI/σ ratio {ratio}");
        }
    }
    // Theory constants beside them (Maruoka 2019 Eqs. 4, 1e).
    assert!((f(&fits["theory"]["psi_small_xi"]) - 1.259_921).abs() < 1e-6);
    assert!((f(&fits["theory"]["omega_small_xi_c0"]) - 3.5333).abs() < 1e-4);
    // A1/A2 < 0 here: the crossover is reported, negative, with a warning.
    assert!(f(&fits["crossover_xi"]["value"]) < 0.0);
    let w = fits["warnings"].to_string();
    assert!(w.contains("opposite signs"), "{w}");
}

#[test]
fn fixed_exponent_asymptotes_recover_their_constants() {
    // Ψ = 1.26 for every drop (Eq. 5 with c1 = 1.26), then Ψ = 0.9 Ξ
    // (Eq. 7 with c2 = 0.9): each constant lies in its 95 % interval.
    let spec = SyntheticSpec::paper(20, 21);
    let recs = eq8_dataset(&spec, [1.26, 0.0, 0.0], [3.53, 0.0, 0.0], [0.5, 1.6]);
    let (_d, fits) = run(&recs, false);
    let c1 = &fits["asymptotes"]["eq5_c1"]["constant"];
    let (lo, hi) = (f(&c1["ci95"][0]), f(&c1["ci95"][1]));
    assert!(lo <= 1.26 && 1.26 <= hi, "c1 {c1}");
    let d1 = &fits["asymptotes"]["eq1e_d1"]["constant"];
    let (lo, hi) = (f(&d1["ci95"][0]), f(&d1["ci95"][1]));
    assert!(lo <= 3.53 && 3.53 <= hi, "d1 {d1}");
    let recs = eq8_dataset(&spec, [0.0, 0.9, 0.0], [0.0, 2.8, 0.0], [0.5, 1.6]);
    let (_d, fits) = run(&recs, false);
    let c2 = &fits["asymptotes"]["eq7_c2"]["constant"];
    let (lo, hi) = (f(&c2["ci95"][0]), f(&c2["ci95"][1]));
    assert!(lo <= 0.9 && 0.9 <= hi, "c2 {c2}");
    let d2 = &fits["asymptotes"]["eq11_d2"]["constant"];
    let (lo, hi) = (f(&d2["ci95"][0]), f(&d2["ci95"][1]));
    assert!(lo <= 2.8 && 2.8 <= hi, "d2 {d2}");
}

#[test]
fn the_crossover_splits_the_regimes_of_the_asymptotes() {
    // Ψ = 1.26 + 0.9 Ξ − 0.15 Ξ²: the leading terms of Eq. 8 are equal at
    // Ξ× = 1.26/0.9 = 1.4.
    let recs = eq8_dataset(
        &SyntheticSpec::paper(30, 8),
        [1.26, 0.9, -0.15],
        [3.53, 1.5, -0.3],
        [0.5, 1.5],
    );
    let (_d, fits) = run(&recs, false);
    assert_eq!(fits["n_skipped"], 0);
    let x = &fits["crossover_xi"];
    let (lo, hi) = (f(&x["ci95"][0]), f(&x["ci95"][1]));
    assert!(lo <= 1.4 && 1.4 <= hi, "crossover {x}");
    // Each asymptote is fitted on its own side of the crossover.
    let sel5 = fits["asymptotes"]["eq5_c1"]["selection"].as_str().unwrap();
    let sel7 = fits["asymptotes"]["eq7_c2"]["selection"].as_str().unwrap();
    assert!(
        sel5.starts_with("Xi < 1.") && sel7.starts_with("Xi >= 1."),
        "{sel5} / {sel7}"
    );
    let n5 = fits["asymptotes"]["eq5_c1"]["n_drops"].as_u64().unwrap();
    let n7 = fits["asymptotes"]["eq7_c2"]["n_drops"].as_u64().unwrap();
    assert_eq!(n5 + n7, 150);
}

#[test]
fn pure_power_laws_give_their_exponents() {
    // R = 3 mm: Π ∝ η^(1/6), τc ∝ v^(−2/3); R = 7 mm: Π ∝ η^(1/3), τc ∝ v^(−1/3).
    // Noise 0.1 % on v, 0.3 % on δ, a, τc: the slope's standard error is
    // ≈ 0.001, so ±0.01 is a ~10σ tolerance that only a wrong fit can miss.
    let mut spec = SyntheticSpec::paper(30, 9);
    spec.rel_noise = [0.001, 0.003, 0.003, 0.003];
    let laws = [(3.0, 1.0 / 6.0, -2.0 / 3.0), (7.0, 1.0 / 3.0, -1.0 / 3.0)];
    let recs = power_law_dataset(&spec, &laws);
    let (_dir, fits) = run(&recs, false);
    let ex = fits["exponents"].as_array().unwrap();
    assert_eq!(ex.len(), 2);
    for (e, (r, nu, mu)) in ex.iter().zip(laws) {
        assert_eq!(f(&e["radius_mm"]), r);
        assert_eq!(e["n_drops"], 30);
        let (got_nu, got_mu) = (f(&e["nu"]), f(&e["mu"]));
        eprintln!("R = {r}: nu {got_nu:.5} (truth {nu:.5}), mu {got_mu:.5} (truth {mu:.5})");
        assert!((got_nu - nu).abs() <= 0.01, "nu {got_nu} vs {nu}");
        assert!((got_mu - mu).abs() <= 0.01, "mu {got_mu} vs {mu}");
        for (key, t) in [("nu_ci", nu), ("mu_ci", mu)] {
            let (lo, hi) = (f(&e[key][0]), f(&e[key][1]));
            assert!(lo <= t && t <= hi, "{key} [{lo}, {hi}] misses {t}");
        }
    }
}

#[test]
fn groups_match_a_hand_computation() {
    // One drop: R = 4.5 mm, ρ = 7800 kg/m³, v = 2.0 ± 0.02 m/s,
    // δ = 1.2 ± 0.012 mm, a = 2.5 ± 0.05 mm, τc = 5.0 ± 0.1 ms; the paper's
    // PDMS (E = 1.6 MPa, h = 3.5 mm, φ = 0.625).
    // By hand (bc -l, 15 digits):
    //   Π = 1.2/4.5 = 0.266667, ξ = 2.5/4.5 = 0.555556, η = 7800·4/1.6e6 = 0.0195,
    //   κ = 3.5/4.5 = 0.777778, ω = 0.005·2/0.0045 = 2.222222,
    //   φ/(κη) = 41.2087912, its cube root 3.45406065, sixth root 1.85851033,
    //   Ψ = 0.921082839, Ξ = 1.032505739, Ω = 7.675690322, Π' = 0.48, κ' = 1.4.
    // Errors (relative errors r_v = r_δ = 1 %, r_a = r_τ = 2 %, independent):
    //   σΠ = 0.00266667, σξ = 0.0111111, ση = 0.00039, σω = ω·√(0.02²+0.01²) = 0.0496904,
    //   σΨ = Ψ·√(0.01² + (2/3·0.01)²) = 0.0110700, σΞ = Ξ·√(0.02² + (0.01/3)²) = 0.0209350,
    //   σΩ = Ω·√(0.02² + (0.01/3)²) = 0.155631, σΠ' = 0.48·√(0.01²+0.02²) = 0.0107331,
    //   σκ' = 1.4·0.02 = 0.028.
    let dir = tempfile::tempdir().unwrap();
    let drops = dir.path().join("drops.csv");
    std::fs::write(
        &drops,
        "run,sphere_radius_mm,v_impact_m_s,v_impact_m_s_err,v_rebound_m_s,restitution,\
         delta_max_mm,delta_max_mm_err,a_max_mm,a_max_mm_err,a_geom_mm,tau_c_ms,tau_c_ms_err,\
         t_contact_s,t_rebound_s,mm_per_px,surface_row_px,status\n\
         hand,4.5,2.0,0.02,1.5,0.75,1.2,0.012,2.5,0.05,3.0,5.0,0.1,,,,,ok\n",
    )
    .unwrap();
    let out = dir.path().join("out");
    collapse_job::run(&args(&drops, &out, false), &config(), "pipeline.toml").unwrap();
    let rows = collapse_rows(&out.join("collapse.csv"));
    assert_eq!(rows.len(), 1);
    let row = &rows[0];
    let want = [
        ("Pi", 0.266_666_666_667),
        ("Pi_err", 0.002_666_666_667),
        ("xi", 0.555_555_555_556),
        ("xi_err", 0.011_111_111_111),
        ("eta", 0.0195),
        ("eta_err", 0.000_39),
        ("kappa", 0.777_777_777_778),
        ("omega", 2.222_222_222_222),
        ("omega_err", 0.049_690_399_500),
        ("Psi", 0.921_082_838_674),
        ("Psi_err", 0.011_070_038_013),
        ("Xi", 1.032_505_738_637),
        ("Xi_err", 0.020_934_957_398),
        ("Omega", 7.675_690_322_286),
        ("Omega_err", 0.155_631_338_289),
        ("Pi_prime", 0.48),
        ("Pi_prime_err", 0.010_733_126_292),
        ("kappa_prime", 1.4),
        ("kappa_prime_err", 0.028),
    ];
    for (col, w) in want {
        let got: f64 = row[col]
            .parse()
            .unwrap_or_else(|_| panic!("{col} = {:?}", row[col]));
        // 1e-9 relative: far above f64 round-off and bc's 15 digits, far
        // below any formula error (a wrong exponent moves Ψ by > 1 %).
        assert!(((got - w) / w).abs() < 1e-9, "{col}: {got} vs {w}");
    }
    assert_eq!(row["a_source"], "measured");
    assert_eq!(row["used"], "true");
}

#[test]
fn geometric_contact_radius_is_flagged_loudly() {
    let mut recs = eq8_dataset(
        &SyntheticSpec::paper(6, 3),
        [1.26, -0.3, 0.05],
        [3.5, 0.0, 0.0],
        [0.6, 1.4],
    );
    for r in recs.iter_mut().take(4) {
        r.a_max_mm = None;
    }
    let (dir, fits) = run(&recs, true);
    assert_eq!(fits["n_geometric_contact_radius"], 4);
    // … and on the collapse figures themselves.
    for name in ["psi_vs_xi", "omega_vs_xi"] {
        let svg =
            std::fs::read_to_string(dir.path().join(format!("out/plots/{name}.svg"))).unwrap();
        assert!(
            svg.contains("WARNING: 4 of 30 drops use the geometric contact radius"),
            "{name}"
        );
    }
    assert!(fits["warnings"][0]
        .as_str()
        .unwrap()
        .starts_with("GEOMETRIC CONTACT RADIUS: 4 of 30"));
    let rows = collapse_rows(&dir.path().join("out/collapse.csv"));
    let geo: Vec<_> = rows
        .iter()
        .filter(|r| r["a_source"] == "geometric_fallback")
        .collect();
    assert_eq!(geo.len(), 4);
    for r in geo {
        // SPEC §3: with a geometric a, Ξ² = Ψ (2 − Π) by construction
        // (a_geom_mm is computed from the noisy δ in the generator; 1e-9).
        let p = |k: &str| r[k].parse::<f64>().unwrap();
        let (xi, psi, pi) = (p("Xi"), p("Psi"), p("Pi"));
        assert!((xi * xi - psi * (2.0 - pi)).abs() < 1e-9 * xi * xi);
        assert!(r["note"].contains("by construction"));
    }
}

#[test]
fn flight_parabolas_of_a_track_have_free_fall_curvature() {
    // The contact ODE's free flight has z̈ = g; in px with 0.05 mm/px that is
    // 9.81 / 5e-5 = 196 200 px/s², so the parabola's t² coefficient is
    // 98 100 px/s² before and after contact (RK4 at 1 µs steps: 1e-6 relative).
    let s = dropscope::config::Surface::paper_pdms();
    let (rows, t_in, t_out) = contact_track(4.5, 7800.0, 1.2, &s, 10_000.0, 0.05);
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("r.csv");
    write_track(&p, &rows).unwrap();
    let mut rec = DropRecord::failed("r", 4.5, "");
    rec.t_contact_s = Some(t_in);
    rec.t_rebound_s = Some(t_out);
    let d = dropscope::collapse::diagnostics::diagnose(&rec, &s, &p).unwrap();
    for f in [d.flight_in.unwrap(), d.flight_out.unwrap()] {
        assert!((f.coef[2] / 98_100.0 - 1.0).abs() < 1e-6, "{:?}", f.coef);
    }
    let law = d.force_law.unwrap();
    assert!((law.n.value - 2.0).abs() < 1e-9);
}

/// The figure and fits keep only a track's frames with a centre, a
/// penetration or contact (a long movie's whole track read back would be
/// its peak memory): frames without any — before the sphere enters,
/// after it leaves, missed in between — change neither its fits nor a byte
/// of its figure.
#[test]
fn untracked_frames_change_neither_the_fits_nor_the_figure() {
    let s = dropscope::config::Surface::paper_pdms();
    let (rows, t_in, t_out) = contact_track(4.5, 7800.0, 1.2, &s, 10_000.0, 0.05);
    let untracked = |t_s: f64| dataset::TrackRow {
        frame: 0,
        t_s,
        x_px: None,
        z_px: None,
        r_px: None,
        residual_px: None,
        edge_points: 0,
        in_contact: false,
        delta_mm: None,
        sigma_z_px: None,
        sigma_x_px: None,
        r_free_px: None,
        sigma_r_free_px: None,
        force_n: None,
        flags: "missing".into(),
    };
    let (t0, t1) = (rows[0].t_s, rows[rows.len() - 1].t_s);
    let mut padded: Vec<_> = (1..400)
        .rev()
        .map(|k| untracked(t0 - 1e-4 * f64::from(k)))
        .collect();
    for (i, r) in rows.iter().enumerate() {
        padded.push(r.clone());
        if i % 7 == 3 && i + 1 < rows.len() {
            padded.push(untracked(0.5 * (r.t_s + rows[i + 1].t_s)));
        }
    }
    padded.extend((1..300).map(|k| untracked(t1 + 1e-4 * f64::from(k))));
    let dir = tempfile::tempdir().unwrap();
    let mut rec = DropRecord::failed("r", 4.5, "");
    rec.t_contact_s = Some(t_in);
    rec.t_rebound_s = Some(t_out);
    let figure = |name: &str, rows: &[dataset::TrackRow]| {
        let p = dir.path().join(name);
        write_track(&p, rows).unwrap();
        let d = dropscope::collapse::diagnostics::diagnose(&rec, &s, &p).unwrap();
        let figures = dropscope::figures::drop_figures(&d).unwrap();
        (
            d.track.samples.len(),
            d.flight_in,
            d.flight_out,
            d.force_law,
            figures,
        )
    };
    let bare = figure("bare.csv", &rows);
    let with_gaps = figure("padded.csv", &padded);
    assert!(padded.len() > rows.len() + 700);
    assert_eq!(bare.0, rows.len());
    assert_eq!(bare, with_gaps);
}

/// A series fitted far from Ξ = 0 reads its constant term
/// by extrapolation; fits.json, the report's fits section and the figure
/// say so, and lead with the exponents and fixed-exponent constants.
#[test]
fn a_series_far_from_zero_is_called_an_extrapolation() {
    let law = ([1.26, -0.3, 0.05], [3.53, -0.5, 0.1]);
    let narrow = eq8_dataset(&SyntheticSpec::paper(6, 3), law.0, law.1, [1.35, 1.55]);
    let (dir, fits) = run(&narrow, true);
    let s = &fits["psi_series"];
    let lo = f(&s["extrapolated_from_xi"]);
    assert!((1.35..1.4).contains(&lo), "{s}");
    assert!(f(&s["condition_number"]) > 1e3, "{s}");
    assert!(!fits["omega_series"]["extrapolated_from_xi"].is_null());
    let warnings = fits["warnings"].to_string();
    assert!(
        warnings.contains("EXTRAPOLATED: A1 of the series Psi(Xi)")
            && warnings.contains(&format!("Xi >= {lo:.3}")),
        "{warnings}"
    );
    // fits.json leads with what the data support.
    let text = std::fs::read_to_string(dir.path().join("out/fits.json")).unwrap();
    let at = |k: &str| text.find(&format!("\"{k}\"")).unwrap();
    assert!(at("exponents") < at("asymptotes") && at("asymptotes") < at("psi_series"));
    let page = dropscope::report::fits::fits_section(&fits);
    let at = |k: &str| page.find(k).unwrap_or_else(|| panic!("{k} missing"));
    assert!(at("Local exponents") < at("Asymptotic constants"));
    assert!(at("Asymptotic constants") < at("Series in Ξ"));
    assert!(page.contains("EXTRAPOLATED: A1 is read at Ξ = 0 from drops at Ξ ≥ 1.3"));
    assert!(page.contains("extrapolated to Ξ = 0 from Ξ ≥"));
    let svg = std::fs::read_to_string(dir.path().join("out/plots/psi_vs_xi.svg")).unwrap();
    assert!(
        svg.contains("EXTRAPOLATED: A1 is read at Ξ = 0 from Ξ ≥ 1.3"),
        "{svg}"
    );

    // Drops reaching small Ξ: the constant is measured, nothing is flagged.
    let wide = eq8_dataset(&SyntheticSpec::paper(6, 3), law.0, law.1, [0.1, 1.6]);
    let (dir, fits) = run(&wide, true);
    assert!(fits["psi_series"]["extrapolated_from_xi"].is_null());
    assert!(!fits["warnings"].to_string().contains("EXTRAPOLATED"));
    assert!(!dropscope::report::fits::fits_section(&fits).contains("EXTRAPOLATED"));
    let svg = std::fs::read_to_string(dir.path().join("out/plots/psi_vs_xi.svg")).unwrap();
    assert!(!svg.contains("EXTRAPOLATED"));
}
