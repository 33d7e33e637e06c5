//! The collapse stage end to end: known laws in, the same laws out; groups
//! against a hand computation; plots that parse and show every point;
//! byte-identical reruns; clear errors.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use dropscope::collapse::groups::ContactRadius;
use dropscope::collapse::synthetic::{
    contact_track, eq8_dataset, power_law_dataset, write_track, SyntheticSpec,
};
use dropscope::config::{PipelineConfig, EMBEDDED_DEFAULT};
use dropscope::dataset::{self, DropRecord};
use dropscope::job::collapse_job::{self, CollapseOptions};

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

fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push(p.strip_prefix(dir).unwrap().to_path_buf());
            }
        }
    }
    out.sort();
    out
}

/// A dataset for the plot tests: R = 3 mm (blue circles) and 7 mm (red
/// squares) on distinct power laws, small errors, with one track.
fn plot_dataset(dir: &Path) -> PathBuf {
    let mut spec = SyntheticSpec::paper(12, 4);
    spec.rel_noise = [0.001, 0.003, 0.003, 0.003];
    let mut recs = power_law_dataset(&spec, &[(3.0, 1.0 / 6.0, -2.0 / 3.0)]);
    spec.per_radius = 9;
    recs.extend(power_law_dataset(&spec, &[(7.0, 1.0 / 3.0, -1.0 / 3.0)]));
    let first = &mut recs[0];
    let (rows, t_in, t_out) = contact_track(
        3.0,
        7800.0,
        first.v_impact_m_s.unwrap(),
        &spec.surface,
        10_000.0,
        0.05,
    );
    first.t_contact_s = Some(t_in);
    first.t_rebound_s = Some(t_out);
    std::fs::create_dir_all(dir.join("tracks")).unwrap();
    let mut w =
        csv::Writer::from_path(dir.join("tracks").join(format!("{}.csv", first.run))).unwrap();
    for r in rows {
        w.serialize(r).unwrap();
    }
    w.flush().unwrap();
    let drops = dir.join("drops.csv");
    dataset::write_csv(&drops, &recs).unwrap();
    drops
}

#[test]
fn plots_are_valid_svg_and_png_showing_every_point() {
    let dir = tempfile::tempdir().unwrap();
    let drops = plot_dataset(dir.path());
    let out = dir.path().join("out");
    let s = collapse_job::run(&args(&drops, &out, true), &config(), "pipeline.toml").unwrap();
    // DROPSCOPE_KEEP=DIR keeps the figures for a look by eye.
    if let Ok(keep) = std::env::var("DROPSCOPE_KEEP") {
        for p in files(dir.path()) {
            let to = Path::new(&keep).join(&p);
            std::fs::create_dir_all(to.parent().unwrap()).unwrap();
            std::fs::copy(dir.path().join(&p), to).unwrap();
        }
    }
    assert_eq!(s.n_used, 21);
    let plots = ["pi_vs_eta", "tau_vs_v", "psi_vs_xi", "omega_vs_xi"];
    for name in plots {
        // SVG: well-formed XML; each point is one marker of its radius's
        // colour, plus one in the legend, plus one in the residual panel
        // under the fit (every radius has its power law, Ψ and Ω their
        // series): 12 + 1 + 12 blue circles, 9 + 1 + 9 red squares.
        let text = std::fs::read_to_string(out.join(format!("plots/{name}.svg"))).unwrap();
        let doc = roxmltree::Document::parse(&text).unwrap_or_else(|e| panic!("{name}.svg: {e}"));
        let count = |tag: &str, fill: &str| {
            doc.descendants()
                .filter(|n| n.has_tag_name(tag) && n.attribute("fill") == Some(fill))
                .count()
        };
        assert_eq!(count("circle", "#0000E6"), 25, "{name}: blue circles");
        assert_eq!(count("polygon", "#DC0000"), 19, "{name}: red squares");
        assert!(text.contains("fit"), "{name}: the residual panel's axis");
        assert!(
            text.contains("R = 3 mm") && text.contains("R = 7 mm"),
            "{name}: legend"
        );

        // PNG: decodes, right size, not blank.
        let img = image::open(out.join(format!("plots/{name}.png")))
            .unwrap_or_else(|e| panic!("{name}.png: {e}"))
            .to_rgb8();
        assert_eq!(img.dimensions(), (1100, 1040));
        let mut colours = std::collections::BTreeSet::new();
        for p in img.pixels() {
            colours.insert(p.0);
        }
        assert!(
            colours.len() > 20,
            "{name}.png looks blank ({} colours)",
            colours.len()
        );
        // In the log–log figures the points are spread out, and the blue and
        // red marker pixels form 13 and 10 separate blobs (fitted lines are
        // drawn in lighter shades, so only markers and their error bars
        // count). In Ψ(Ξ) and Ω(Ξ) this data set's R = 7 mm points overlap.
        if !name.ends_with("_xi") {
            // The fit's panel ends above row 740 (in the residual panel
            // under it, points of both radii overlap).
            count_blobs(&img, name, 0..740, [13, 10]);
        }
    }
    // The per-drop figure exists for the one drop with a track, and its
    // force law recovers the model it was integrated with (F = πEφR/h δ²).
    let run = "R3_00";
    for ext in ["svg", "png"] {
        assert!(out.join(format!("plots/drops/{run}.{ext}")).is_file());
    }
    let fits: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("fits.json")).unwrap()).unwrap();
    let law = &fits["force_laws"][0];
    assert_eq!(law["run"], run);
    assert!((f(&law["n"]["value"]) - 2.0).abs() < 1e-9);
    let k = f(&law["k_n_per_mm_pow_n"]["value"]);
    assert!((k / f(&law["model_k_n_per_mm2"]) - 1.0).abs() < 1e-9);
    assert_eq!(fits["force_laws"].as_array().unwrap().len(), 1);
}

/// The guide fan of an SVG log–log figure: each guide's dashes (black,
/// 2 px), its label's box (x0, y0, x1, y1) and the legend's frame.
struct Fan {
    guides: Vec<Vec<Vec<(f64, f64)>>>,
    labels: Vec<[f64; 4]>,
    legend: [f64; 4],
}

fn fan(svg: &str) -> Fan {
    let doc = roxmltree::Document::parse(svg).unwrap();
    let num = |n: roxmltree::Node, a: &str| n.attribute(a).unwrap().parse::<f64>().unwrap();
    let dashes: Vec<Vec<(f64, f64)>> = doc
        .descendants()
        .filter(|n| {
            n.has_tag_name("polyline")
                && n.attribute("stroke") == Some("#000000")
                && n.attribute("stroke-width") == Some("2")
        })
        .map(|n| {
            n.attribute("points")
                .unwrap()
                .split_whitespace()
                .map(|p| {
                    let (x, y) = p.split_once(',').unwrap();
                    (x.parse().unwrap(), y.parse().unwrap())
                })
                .collect()
        })
        .collect();
    // Both guides run right from one start: a dash belongs to the guide in
    // its direction from there (the two differ by degrees; the dashes split
    // at the widest gap between directions). Within 40 px of the start the
    // direction is not sure: those dashes form a third group, checked for
    // kinks and the legend only.
    let start = *dashes
        .iter()
        .flatten()
        .min_by(|p, q| p.0.total_cmp(&q.0))
        .unwrap();
    let angle = |d: &Vec<(f64, f64)>| {
        let p = d[d.len() - 1];
        (p.1 - start.1).atan2(p.0 - start.0)
    };
    let (mut far, near): (Vec<_>, Vec<_>) = dashes.into_iter().partition(|d| {
        let p = d[d.len() - 1];
        (p.0 - start.0).hypot(p.1 - start.1) >= 40.0
    });
    far.sort_by(|a, b| angle(a).total_cmp(&angle(b)));
    let gap = (1..far.len())
        .max_by(|&i, &j| {
            (angle(&far[i]) - angle(&far[i - 1])).total_cmp(&(angle(&far[j]) - angle(&far[j - 1])))
        })
        .unwrap();
    let second = far.split_off(gap);
    let guides = vec![far, second, near];
    let labels = doc
        .descendants()
        .filter(|n| n.has_tag_name("text"))
        .filter(|n| {
            let t = n.text().unwrap_or_default().trim();
            ["1/3", "2/3", "1/6"].iter().any(|g| t.ends_with(g)) && t.chars().count() <= 4
        })
        .map(|n| {
            let (x, y, size) = (num(n, "x"), num(n, "y"), num(n, "font-size"));
            let chars = n.text().unwrap().trim().chars().count() as f64;
            [x, y, x + 0.55 * size * chars, y + size]
        })
        .collect();
    let frame = doc
        .descendants()
        .find(|n| n.has_tag_name("rect") && n.attribute("stroke") == Some("#787878"))
        .unwrap();
    let (x, y) = (num(frame, "x"), num(frame, "y"));
    Fan {
        guides,
        labels,
        legend: [x, y, x + num(frame, "width"), y + num(frame, "height")],
    }
}

/// The guide slopes must not look bent (drawn through 21 points rounded
/// to pixels, each dash kinks where it crosses one: up to 1.0 px off a
/// straight line), nor the legend, in a band above the data when no corner
/// is free, cover the guides' start. On a campaign-like dataset (five
/// radii whose points fill both lower corners): every guide is a straight
/// dashed line (each dash two points, all within 0.71 px of one line), and
/// no dash nor label is under the legend.
#[test]
fn guide_slopes_are_straight_and_clear_of_the_legend() {
    let spec = SyntheticSpec::paper(6, 3);
    let laws: Vec<(f64, f64, f64)> = spec
        .radii_mm
        .iter()
        .map(|&r| (r, 1.0 / 3.0, -1.0 / 3.0))
        .collect();
    let mut recs = power_law_dataset(&spec, &laws);
    for r in &mut recs {
        let k = r.sphere_radius_mm / 3.0;
        r.tau_c_ms = r.tau_c_ms.map(|t| t * k);
        r.tau_c_ms_err = r.tau_c_ms_err.map(|e| e * k);
    }
    let dir = tempfile::tempdir().unwrap();
    let drops = dir.path().join("drops.csv");
    dataset::write_csv(&drops, &recs).unwrap();
    let out = dir.path().join("out");
    collapse_job::run(&args(&drops, &out, true), &config(), "pipeline.toml").unwrap();
    for name in ["tau_vs_v", "pi_vs_eta"] {
        let svg = std::fs::read_to_string(out.join(format!("plots/{name}.svg"))).unwrap();
        let Fan {
            guides,
            labels,
            legend,
        } = fan(&svg);
        assert_eq!(labels.len(), 2, "{name}: guide labels");
        let inside =
            |(x, y): (f64, f64)| x > legend[0] && x < legend[2] && y > legend[1] && y < legend[3];
        for (i, g) in guides.iter().enumerate() {
            for dash in g {
                assert_eq!(dash.len(), 2, "{name}: a kinked dash {dash:?}");
                for &p in dash {
                    assert!(
                        !inside(p),
                        "{name}: guide at {p:?} under the legend {legend:?}"
                    );
                }
            }
            if i == 2 {
                continue;
            }
            // Distance from the line fitted through all its dash ends (total
            // least squares): pixel rounding alone keeps it under √2/2.
            let pts: Vec<(f64, f64)> = g.iter().flatten().copied().collect();
            let n = pts.len() as f64;
            let (mx, my) = (
                pts.iter().map(|p| p.0).sum::<f64>() / n,
                pts.iter().map(|p| p.1).sum::<f64>() / n,
            );
            let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
            for p in &pts {
                sxx += (p.0 - mx).powi(2);
                syy += (p.1 - my).powi(2);
                sxy += (p.0 - mx) * (p.1 - my);
            }
            let th = 0.5 * (2.0 * sxy).atan2(sxx - syy);
            let reach = pts.iter().map(|p| (p.0 - mx).hypot(p.1 - my));
            assert!(reach.fold(0.0, f64::max) > 50.0, "{name}: a short guide");
            for &p in &pts {
                let off = (-(p.0 - mx) * th.sin() + (p.1 - my) * th.cos()).abs();
                assert!(off <= 0.71, "{name}: {p:?} is {off:.2} px off the guide");
            }
        }
        for l in labels {
            for corner in [(l[0], l[1]), (l[2], l[1]), (l[0], l[3]), (l[2], l[3])] {
                assert!(
                    !inside(corner),
                    "{name}: label {l:?} under the legend {legend:?}"
                );
            }
        }
    }
}

/// The legend keeps clear of the error bars, not only of the markers: on
/// the fixtures' three drops the Ω(Ξ) legend could lie over the 3 mm
/// drop's one-sigma bar (the report's first screen).
#[test]
fn the_legend_keeps_clear_of_the_error_bars() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let o = dropscope()
        .args(["process", "--no-animation", "--manifest"])
        .arg(root.join("fixtures/runs.csv"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let drops = out.join("drops.csv");
    collapse_job::run(&args(&drops, &out, true), &config(), "pipeline.toml").unwrap();
    for name in ["psi_vs_xi", "omega_vs_xi", "pi_vs_eta", "tau_vs_v"] {
        let svg = std::fs::read_to_string(out.join(format!("plots/{name}.svg"))).unwrap();
        let doc = roxmltree::Document::parse(&svg).unwrap();
        let num = |n: roxmltree::Node, a: &str| n.attribute(a).unwrap().parse::<f64>().unwrap();
        let frame = doc
            .descendants()
            .find(|n| n.has_tag_name("rect") && n.attribute("stroke") == Some("#787878"))
            .unwrap();
        let (x0, y0) = (num(frame, "x"), num(frame, "y"));
        let (x1, y1) = (x0 + num(frame, "width"), y0 + num(frame, "height"));
        let mut bars = 0;
        // The 3 mm (blue) and 7 mm (red) drops' bars: two-point lines.
        for n in doc.descendants().filter(|n| {
            n.has_tag_name("polyline")
                && n.attribute("stroke-width") == Some("1")
                && matches!(n.attribute("stroke"), Some("#0000E6" | "#DC0000"))
        }) {
            let p: Vec<(f64, f64)> = n
                .attribute("points")
                .unwrap()
                .split_whitespace()
                .map(|p| {
                    let (x, y) = p.split_once(',').unwrap();
                    (x.parse().unwrap(), y.parse().unwrap())
                })
                .collect();
            let (lx, hx) = (p[0].0.min(p[1].0), p[0].0.max(p[1].0));
            let (ly, hy) = (p[0].1.min(p[1].1), p[0].1.max(p[1].1));
            assert!(
                hx < x0 || lx > x1 || hy < y0 || ly > y1,
                "{name}: the bar {p:?} runs under the legend ({x0}, {y0})-({x1}, {y1})"
            );
            bars += 1;
        }
        assert!(bars >= 4, "{name}: {bars} bars");
    }
}

#[test]
fn two_runs_write_identical_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let drops = plot_dataset(dir.path());
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    collapse_job::run(&args(&drops, &a, true), &config(), "pipeline.toml").unwrap();
    collapse_job::run(&args(&drops, &b, true), &config(), "pipeline.toml").unwrap();
    let (fa, fb) = (files(&a), files(&b));
    assert_eq!(fa, fb);
    assert!(fa.len() >= 12, "{fa:?}");
    for p in fa {
        assert!(
            std::fs::read(a.join(&p)).unwrap() == std::fs::read(b.join(&p)).unwrap(),
            "{} differs",
            p.display()
        );
    }
}

fn dropscope() -> Command {
    Command::new(env!("CARGO_BIN_EXE_dropscope"))
}

const HEADER: &str = "run,sphere_radius_mm,v_impact_m_s,v_rebound_m_s,restitution,delta_max_mm,\
                      a_max_mm,a_geom_mm,tau_c_ms,t_contact_s,t_rebound_s,mm_per_px,surface_row_px,status";

#[test]
fn a_bad_cell_exits_2_naming_file_and_row() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("mine.csv");
    std::fs::write(
        &p,
        format!("{HEADER}\na,3.0,1.2,0.9,0.75,0.9,2.1,2.17,4.1,,,,,ok\nb,3.0,fast,0.9,0.75,0.9,2.1,2.17,4.1,,,,,ok\n"),
    )
    .unwrap();
    let o = dropscope()
        .arg("collapse")
        .arg(&p)
        .arg("--out")
        .arg(dir.path().join("o"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("mine.csv") && err.contains("row 3"), "{err}");
}

#[test]
fn an_unknown_surface_exits_2_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("drops.csv");
    std::fs::write(
        &p,
        format!("{HEADER},surface\na,3.0,1.2,0.9,0.75,0.9,2.1,2.17,4.1,,,,,ok,pdms\nb,3.0,1.2,0.9,0.75,0.9,2.1,2.17,4.1,,,,,ok,glass\n"),
    )
    .unwrap();
    let o = dropscope()
        .arg("collapse")
        .arg(&p)
        .arg("--out")
        .arg(dir.path().join("o"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("drops.csv")
            && err.contains("row 3")
            && err.contains("\"glass\"")
            && err.contains("known: pdms"),
        "{err}"
    );
}

#[test]
fn failed_rows_are_skipped_counted_and_exit_1() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("drops.csv");
    let mut body = String::from(HEADER);
    body.push('\n');
    for (i, v) in [0.6, 0.9, 1.3, 1.8, 2.5].iter().enumerate() {
        let delta = 3.0 * 0.9 * (7800.0 * v * v / 1.6e6f64).powf(0.25);
        body.push_str(&format!(
            "d{i},3.0,{v},,,{delta},{},,{},,,,,ok\n",
            1.6 + 0.1 * i as f64,
            4.0 / v
        ));
    }
    body.push_str("bad,3.0,,,,,,,,,,,,failed\n");
    std::fs::write(&p, body).unwrap();
    let out = dir.path().join("o");
    let o = dropscope()
        .arg("collapse")
        .arg(&p)
        .arg("--out")
        .arg(&out)
        .arg("--no-plots")
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let fits: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("fits.json")).unwrap()).unwrap();
    assert_eq!(fits["n_used"], 5);
    assert_eq!(fits["n_skipped"], 1);
    assert_eq!(fits["skipped"][0]["row"], 7);
    // No _err columns at all: every fit says it is unweighted.
    assert_eq!(fits["psi_series"]["weighted"], false);
    assert!(fits["warnings"].to_string().contains("unweighted"));
    let rows = collapse_rows(&out.join("collapse.csv"));
    assert_eq!(rows.len(), 6);
    assert_eq!(rows[5]["used"], "false");
    assert!(rows[5]["note"].starts_with("status failed"));
    assert_eq!(
        rows[0]["Psi_err"], "",
        "unknown errors stay empty, not zero"
    );
}

/// Blobs of blue and red marker pixels in the rows `rows` of `img`.
fn count_blobs(img: &image::RgbImage, name: &str, rows: std::ops::Range<u32>, want: [u32; 2]) {
    for (rgb, want) in [([0u8, 0, 230], want[0]), ([220, 0, 0], want[1])] {
        let mask = image::GrayImage::from_fn(img.width(), img.height(), |x, y| {
            let on = rows.contains(&y) && img.get_pixel(x, y).0 == rgb;
            image::Luma([if on { 255 } else { 0 }])
        });
        let labels = imageproc::region_labelling::connected_components(
            &mask,
            imageproc::region_labelling::Connectivity::Eight,
            image::Luma([0u8]),
        );
        let blobs = labels.pixels().map(|p| p.0[0]).max().unwrap_or(0);
        assert_eq!(blobs, want, "{name}.png: blobs of {rgb:?}");
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

/// `collapse` writes beside its drops.csv, and the report
/// refuses a folder holding two datasets' files instead of mixing them.
#[test]
fn outputs_of_two_datasets_cannot_be_mixed() {
    let dir = tempfile::tempdir().unwrap();
    let recs = eq8_dataset(
        &SyntheticSpec::paper(2, 9),
        [1.26, -0.3, 0.05],
        [3.53, -0.5, 0.1],
        [0.6, 1.8],
    );
    for (name, rows) in [("a", &recs[..]), ("b", &recs[..6])] {
        std::fs::create_dir(dir.path().join(name)).unwrap();
        dataset::write_csv(&dir.path().join(name).join("drops.csv"), rows).unwrap();
    }
    let go = |args: &[&str]| {
        let o = dropscope()
            .args(args)
            .current_dir(dir.path())
            .output()
            .unwrap();
        let text =
            String::from_utf8_lossy(&o.stderr).into_owned() + &String::from_utf8_lossy(&o.stdout);
        (o.status.code(), text)
    };
    let (code, text) = go(&["collapse", "a/drops.csv", "--bootstrap", "50"]);
    assert_eq!(code, Some(0), "{text}");
    assert!(dir.path().join("a/fits.json").is_file(), "{text}");
    assert!(dir.path().join("a/plots/psi_vs_xi.svg").is_file());
    assert!(!dir.path().join("out").exists(), "wrote into ./out: {text}");
    let (code, text) = go(&["report", "a"]);
    assert_eq!(code, Some(0), "{text}");
    let page = std::fs::read_to_string(dir.path().join("a/report.html")).unwrap();
    let id = dropscope::dataset::id::of_file(&dir.path().join("a/drops.csv")).unwrap();
    assert!(page.contains(&id), "the page names its dataset");

    // One figure of b's collapse dropped into a.
    let (code, text) = go(&["collapse", "b/drops.csv", "--out", "c", "--bootstrap", "50"]);
    assert_eq!(code, Some(0), "{text}");
    std::fs::copy(
        dir.path().join("c/plots/omega_vs_xi.svg"),
        dir.path().join("a/plots/omega_vs_xi.svg"),
    )
    .unwrap();
    let (code, text) = go(&["report", "a"]);
    assert_eq!(code, Some(2), "{text}");
    assert!(
        text.contains("omega_vs_xi.svg was computed from another drops.csv"),
        "{text}"
    );
    // b's whole collapse into a: a's drops.csv with b's fits.
    let (code, text) = go(&["collapse", "b/drops.csv", "--out", "a", "--bootstrap", "50"]);
    assert_eq!(code, Some(0), "{text}");
    let (code, text) = go(&["report", "a"]);
    assert_eq!(code, Some(2), "{text}");
    assert!(
        text.contains("a/fits.json was computed from another drops.csv than a/drops.csv")
            && text.contains("mixes the outputs of two jobs")
            && text.contains(&id),
        "{text}"
    );
    // Collapsing a again (even without plots) leaves nothing of b's.
    let (code, text) = go(&["collapse", "a/drops.csv", "--bootstrap", "50", "--no-plots"]);
    assert_eq!(code, Some(0), "{text}");
    let (code, text) = go(&["report", "a"]);
    assert_eq!(code, Some(0), "{text}");
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

/// With no drop to show, a figure says so instead of
/// drawing axes over nothing.
#[test]
fn figures_without_data_say_so() {
    let fits = dropscope::collapse::fit::fit_all(
        &[],
        dropscope::collapse::fit::FitSettings {
            resamples: 10,
            seed: 1,
        },
    );
    let figures = dropscope::figures::collapse_figures(&[], &fits).unwrap();
    let svgs: Vec<String> = figures
        .iter()
        .filter(|(name, _)| name.ends_with(".svg"))
        .map(|(_, b)| String::from_utf8(b.clone()).unwrap())
        .collect();
    assert_eq!(svgs.len(), 4);
    for svg in svgs {
        assert!(svg.contains("No measured drop to show"), "{svg}");
        assert!(!svg.contains("<line"), "axes drawn over nothing: {svg}");
    }
}
