//! Per-drop accuracy of `dropscope process` against each run's `truth.json`,
//! on a rendered campaign or on the independent drops
//! (`../shared/data/independent-drops/`, whose truth keys it also reads).
//!
//!     dropscope render --campaign --preset realistic --contact wide --repeats 2 --seed 7 --scaled-manifest --out /tmp/wide7
//!     dropscope process --manifest /tmp/wide7/runs_scaled.csv --out /tmp/wide7-out
//!     cargo run --release --example accuracy_campaign -- /tmp/wide7/runs_scaled.csv /tmp/wide7-out
//!
//! The first argument is the manifest that was processed (or a folder
//! holding `runs.csv`); each run's `truth.json` is in its folder (the run's
//! path, or the folder of its movie file). Several manifest/output pairs
//! may follow one another; their drops are pooled.
//!
//! Prints, for all drops and then per damping kind, per contact model (a
//! force that may pull or not) and per band of the true exponent n: per
//! quantity the median, 95th percentile and maximum of the relative error
//! |measured/true − 1|, how many drops' reported 2σ covers the true error,
//! and the median of |error|/σ (0.67 for an honest Gaussian error bar;
//! smaller: bars too wide, larger: too narrow); for the force law,
//! |n − n_true| (n_true = `force_n`, 2 for renders without a contact
//! section) with the same statistics; on drops under the model's law, K
//! fitted with n held at 2 against π E φ R / h.

use dropscope::dataset::manifest::read_manifest;
use dropscope::dataset::{read_csv, DropRecord, DropStatus};
use std::path::{Path, PathBuf};

/// The p-quantile (nearest rank) of `v`.
fn pct(v: &[f64], p: f64) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p).round() as usize]
}

/// One measured quantity against its truth.
struct Quantity {
    name: &'static str,
    get: fn(&DropRecord) -> (Option<f64>, Option<f64>),
    /// Truth keys, first present wins, and the factor to the record's unit.
    keys: &'static [(&'static str, f64)],
}

const QUANTITIES: [Quantity; 8] = [
    Quantity {
        name: "v_impact",
        get: |r| (r.v_impact_m_s, r.v_impact_m_s_err),
        keys: &[("v_impact_m_s", 1.0)],
    },
    Quantity {
        name: "v_rebound",
        get: |r| (r.v_rebound_m_s, r.v_rebound_m_s_err),
        keys: &[("v_rebound_m_s", 1.0)],
    },
    Quantity {
        name: "restitution",
        get: |r| (r.restitution, r.restitution_err),
        keys: &[("restitution", 1.0)],
    },
    Quantity {
        name: "delta_max",
        get: |r| (r.delta_max_mm, r.delta_max_mm_err),
        keys: &[("delta_max_mm", 1.0)],
    },
    Quantity {
        name: "tau_c",
        get: |r| (r.tau_c_ms, r.tau_c_ms_err),
        keys: &[("tau_c_s", 1e3), ("tau_c_ms", 1.0)],
    },
    Quantity {
        name: "a_max",
        get: |r| (r.a_max_mm, r.a_max_mm_err),
        keys: &[("a_max_mm", 1.0)],
    },
    Quantity {
        name: "a_geom",
        get: |r| (r.a_geom_mm, r.a_geom_mm_err),
        keys: &[("a_max_mm", 1.0)],
    },
    Quantity {
        name: "mm_per_px",
        get: |r| (r.mm_per_px, r.mm_per_px_err),
        keys: &[("mm_per_px", 1.0), ("pixel_scale_mm_per_px", 1.0)],
    },
];

/// What the truth says about a drop's contact.
#[derive(Debug, Clone)]
struct Contact {
    n_true: f64,
    damping: String,
    adhesion: bool,
}

impl Contact {
    /// From our `truth.json` (contact keys, or the model's law without
    /// them) or the independent renderer's (`force_n`, `damping_model`, a
    /// `contact_law.force` that says whether it is clamped).
    fn of(t: &serde_json::Value) -> Contact {
        let n_true = t["force_n"].as_f64().unwrap_or(2.0);
        let damping = match t["damping_model"].as_str() {
            Some(d) => d.to_string(),
            None if t["damping_n_s_m"].as_f64().unwrap_or(0.0) > 0.0 => "linear".into(),
            None => "none".into(),
        };
        let adhesion = match t["adhesion"].as_bool() {
            Some(a) => a,
            None => !t["contact_law"]["force"]
                .as_str()
                .is_some_and(|f| f.contains("clamped")),
        };
        Contact {
            n_true,
            damping,
            adhesion,
        }
    }
}

/// One measured drop with its truth.
struct Scored {
    record: DropRecord,
    truth: serde_json::Value,
    contact: Contact,
}

/// The folder holding a run's `truth.json`.
fn truth_dir(path: &Path) -> Option<PathBuf> {
    [Some(path), path.parent()]
        .into_iter()
        .flatten()
        .find(|d| d.join("truth.json").is_file())
        .map(Path::to_path_buf)
}

/// Median / p95 / max of |x|, as a table's cells.
fn spread(v: &[f64]) -> String {
    if v.is_empty() {
        return "– | – | –".into();
    }
    format!(
        "{:.2e} | {:.2e} | {:.2e}",
        pct(v, 0.5),
        pct(v, 0.95),
        pct(v, 1.0)
    )
}

/// The table of one group of drops.
fn table(title: &str, drops: &[&Scored]) {
    println!("\n### {title} ({} drops)\n", drops.len());
    println!("| quantity | median | p95 | max | 2σ covers | median \\|err\\|/σ |");
    println!("| --- | --- | --- | --- | --- | --- |");
    for q in &QUANTITIES {
        let (mut rel, mut z) = (Vec::new(), Vec::new());
        let mut covered = 0;
        for d in drops {
            let Some(truth) = q
                .keys
                .iter()
                .find_map(|(k, f)| d.truth[*k].as_f64().map(|v| v * f))
            else {
                continue;
            };
            let (Some(m), err) = (q.get)(&d.record) else {
                continue;
            };
            rel.push((m / truth - 1.0).abs());
            if let Some(e) = err.filter(|e| *e > 0.0) {
                z.push((m - truth).abs() / e);
                covered += usize::from((m - truth).abs() <= 2.0 * e);
            }
        }
        if rel.is_empty() {
            continue;
        }
        // coverage over the drops with an error bar (none: a given value)
        let (cover, z_med) = if z.is_empty() {
            ("–".to_string(), "–".to_string())
        } else {
            (
                format!("{covered}/{}", z.len()),
                format!("{:.2}", pct(&z, 0.5)),
            )
        };
        println!("| {} | {} | {cover} | {z_med} |", q.name, spread(&rel));
    }
    let (mut dn, mut z) = (Vec::new(), Vec::new());
    let mut covered = 0;
    let mut fitted = Vec::new();
    for d in drops {
        let Some(n) = d.record.force_exponent else {
            continue;
        };
        let miss = n - d.contact.n_true;
        dn.push(miss.abs());
        fitted.push(n);
        if let Some(e) = d.record.force_exponent_err.filter(|e| *e > 0.0) {
            z.push(miss.abs() / e);
            covered += usize::from(miss.abs() <= 2.0 * e);
        }
    }
    if !dn.is_empty() {
        let z_med = if z.is_empty() {
            "–".to_string()
        } else {
            format!("{:.2}", pct(&z, 0.5))
        };
        println!(
            "| \\|n − n_true\\| (absolute) | {} | {covered}/{} | {z_med} |",
            spread(&dn),
            dn.len()
        );
        println!(
            "\nfitted n {:.3} … {:.3}; true n {:.3} … {:.3}",
            pct(&fitted, 0.0),
            pct(&fitted, 1.0),
            drops
                .iter()
                .map(|d| d.contact.n_true)
                .fold(f64::MAX, f64::min),
            drops
                .iter()
                .map(|d| d.contact.n_true)
                .fold(f64::MIN, f64::max),
        );
    }
    // K with n held at 2 against π E φ R / h, on drops under the model's law.
    let (mut dk, mut k_covered) = (Vec::new(), 0);
    for d in drops.iter().filter(|d| d.truth.get("force_n").is_none()) {
        let s = &d.truth["surface"];
        let k_model = std::f64::consts::PI
            * s["modulus_pa"].as_f64().unwrap_or(f64::NAN)
            * s["solid_fraction"].as_f64().unwrap_or(f64::NAN)
            * d.truth["sphere_radius_mm"].as_f64().unwrap_or(f64::NAN)
            / s["pillar_height_mm"].as_f64().unwrap_or(f64::NAN);
        if let Some(k) = d.record.force_k2_n_m2 {
            dk.push((k / k_model - 1.0).abs());
            let e = d.record.force_k2_n_m2_err;
            k_covered += usize::from(e.is_some_and(|e| (k - k_model).abs() <= 2.0 * e));
        }
    }
    if !dk.is_empty() {
        println!(
            "K at n = 2 against π E φ R / h: |K/K_model − 1| {} (median | p95 | max), 2σ covers {k_covered}/{}",
            spread(&dk),
            dk.len()
        );
    }
    let mut sources: Vec<(String, usize)> = Vec::new();
    for d in drops {
        let s = &d.record.surface_source;
        match sources.iter_mut().find(|(k, _)| k == s) {
            Some((_, c)) => *c += 1,
            None => sources.push((s.clone(), 1)),
        }
    }
    sources.sort();
    let listed: Vec<String> = sources.iter().map(|(k, c)| format!("{k} {c}")).collect();
    println!("surface_source: {}", listed.join(", "));
}

fn main() -> anyhow::Result<()> {
    let args: Vec<PathBuf> = std::env::args().skip(1).map(PathBuf::from).collect();
    if args.is_empty() || !args.len().is_multiple_of(2) {
        anyhow::bail!("usage: accuracy_campaign MANIFEST_OR_DIR PROCESS_OUT_DIR [MANIFEST_OR_DIR PROCESS_OUT_DIR ...]");
    }
    let mut scored = Vec::new();
    let (mut listed, mut failed) = (0, 0);
    for pair in args.chunks(2) {
        let manifest = if pair[0].is_dir() {
            pair[0].join("runs.csv")
        } else {
            pair[0].clone()
        };
        let runs = read_manifest(&manifest)?;
        let records = read_csv(&pair[1].join("drops.csv"))?;
        listed += runs.len();
        for run in &runs {
            let Some(r) = records.iter().find(|r| r.run == run.run) else {
                println!(
                    "{}: no row in {}",
                    run.run,
                    pair[1].join("drops.csv").display()
                );
                failed += 1;
                continue;
            };
            if r.status == DropStatus::Failed {
                println!("{}: failed: {}", r.run, r.reason);
                failed += 1;
                continue;
            }
            let Some(dir) = truth_dir(&run.path) else {
                anyhow::bail!("{}: no truth.json beside {}", run.run, run.path.display());
            };
            let truth: serde_json::Value =
                serde_json::from_slice(&std::fs::read(dir.join("truth.json"))?)?;
            scored.push(Scored {
                record: r.clone(),
                contact: Contact::of(&truth),
                truth,
            });
        }
    }
    println!(
        "{} of {listed} drops measured ({failed} failed or missing)",
        scored.len()
    );
    let all: Vec<&Scored> = scored.iter().collect();
    let count = |f: &dyn Fn(&Contact) -> bool| all.iter().filter(|d| f(&d.contact)).count();
    println!(
        "damping none / linear / hunt_crossley: {} / {} / {}; adhesion / none: {} / {}",
        count(&|c| c.damping == "none"),
        count(&|c| c.damping == "linear"),
        count(&|c| c.damping == "hunt_crossley"),
        count(&|c| c.adhesion),
        count(&|c| !c.adhesion),
    );
    table("all drops", &all);
    // each group that is not the whole set
    let shown = |g: &[&Scored]| !g.is_empty() && g.len() < all.len();
    for kind in ["none", "linear", "hunt_crossley"] {
        let group: Vec<&Scored> = all
            .iter()
            .copied()
            .filter(|d| d.contact.damping == kind)
            .collect();
        if shown(&group) {
            table(&format!("damping {kind}"), &group);
        }
    }
    for (adhesion, name) in [
        (true, "contact: the force may pull (adhesion)"),
        (false, "contact: the force cannot pull (no adhesion)"),
    ] {
        let group: Vec<&Scored> = all
            .iter()
            .copied()
            .filter(|d| d.contact.adhesion == adhesion)
            .collect();
        if shown(&group) {
            table(name, &group);
        }
    }
    for (lo, hi) in [(0.0, 1.8), (1.8, 2.2), (2.2, 9.0)] {
        let group: Vec<&Scored> = all
            .iter()
            .copied()
            .filter(|d| d.contact.n_true >= lo && d.contact.n_true < hi)
            .collect();
        if shown(&group) {
            table(&format!("true n in [{lo}, {hi})"), &group);
        }
    }
    Ok(())
}
