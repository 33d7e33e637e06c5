//! `dropscope collapse` on bad input: a bad cell or an unknown surface exits
//! 2 naming it, failed rows are skipped and counted, two datasets' outputs
//! are not mixed.

use super::*;

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
