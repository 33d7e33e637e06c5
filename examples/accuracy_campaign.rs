//! Per-drop accuracy of `dropscope process` on a rendered campaign, against
//! each run's `truth.json` (issue 5's benchmark table).
//!
//!     dropscope render --campaign --preset realistic --tilt 0.003 --restitution 0.9 --seed 7 --out /tmp/camp
//!     dropscope process --manifest /tmp/camp/runs.csv --out /tmp/camp-out
//!     cargo run --release --example accuracy_campaign -- /tmp/camp /tmp/camp-out
//!
//! Prints, per quantity, the median, 95th percentile and maximum of the
//! relative error |measured/true − 1|, and how many drops' reported 2σ
//! covers the true error; then the contact law's n − 2 (n free) and
//! K/K_model − 1 (K fitted with n held at 2, K_model = π E φ R / h).

use dropscope::dataset::{read_csv, DropStatus};
use dropscope::manifest::read_manifest;
use std::path::PathBuf;

fn pct(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p).round() as usize]
}

fn main() -> anyhow::Result<()> {
    let args: Vec<PathBuf> = std::env::args().skip(1).map(PathBuf::from).collect();
    let [campaign, out] = args.as_slice() else {
        anyhow::bail!("usage: accuracy_campaign CAMPAIGN_DIR PROCESS_OUT_DIR");
    };
    let runs = read_manifest(&campaign.join("runs.csv"))?;
    let records = read_csv(&out.join("drops.csv"))?;
    // (name, measured, its σ, truth key, truth scale to the record's unit)
    type Get = fn(&dropscope::dataset::DropRecord) -> (Option<f64>, Option<f64>);
    let quantities: [(&str, Get, &str, f64); 7] = [
        (
            "v_impact",
            |r| (r.v_impact_m_s, r.v_impact_m_s_err),
            "v_impact_m_s",
            1.0,
        ),
        (
            "v_rebound",
            |r| (r.v_rebound_m_s, r.v_rebound_m_s_err),
            "v_rebound_m_s",
            1.0,
        ),
        (
            "restitution",
            |r| (r.restitution, r.restitution_err),
            "restitution",
            1.0,
        ),
        (
            "delta_max",
            |r| (r.delta_max_mm, r.delta_max_mm_err),
            "delta_max_mm",
            1.0,
        ),
        ("tau_c", |r| (r.tau_c_ms, r.tau_c_ms_err), "tau_c_s", 1e3),
        ("a_max", |r| (r.a_max_mm, r.a_max_mm_err), "a_max_mm", 1.0),
        (
            "a_geom",
            |r| (r.a_geom_mm, r.a_geom_mm_err),
            "a_max_mm",
            1.0,
        ),
    ];
    let mut errs: Vec<Vec<f64>> = vec![Vec::new(); quantities.len()];
    let mut covered = vec![0usize; quantities.len()];
    let (mut dn, mut dk) = (Vec::new(), Vec::new());
    let (mut n_covered, mut k_covered) = (0, 0);
    let mut measured = 0;
    for run in &runs {
        let Some(r) = records.iter().find(|r| r.run == run.run) else {
            println!("{}: no row in drops.csv", run.run);
            continue;
        };
        if r.status == DropStatus::Failed {
            println!("{}: failed: {}", r.run, r.reason);
            continue;
        }
        measured += 1;
        let dir = run.path.parent().unwrap_or(&run.path).join(&run.run);
        let dir = if dir.join("truth.json").exists() {
            dir
        } else {
            run.path.clone()
        };
        let t: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("truth.json"))?)?;
        for (k, (_, get, key, scale)) in quantities.iter().enumerate() {
            let truth = t[*key].as_f64().unwrap_or(f64::NAN) * scale;
            if let (Some(m), e) = get(r) {
                errs[k].push((m / truth - 1.0).abs());
                if e.is_some_and(|e| (m - truth).abs() <= 2.0 * e) {
                    covered[k] += 1;
                }
            }
        }
        let k_model = std::f64::consts::PI
            * t["surface"]["modulus_pa"].as_f64().unwrap_or(f64::NAN)
            * t["surface"]["solid_fraction"].as_f64().unwrap_or(f64::NAN)
            * t["sphere_radius_mm"].as_f64().unwrap_or(f64::NAN)
            / t["surface"]["pillar_height_mm"]
                .as_f64()
                .unwrap_or(f64::NAN);
        if let (Some(n), Some(k)) = (r.force_exponent, r.force_k2_n_m2) {
            dn.push(n - 2.0);
            dk.push(k / k_model - 1.0);
            let within = |d: f64, e: Option<f64>| e.is_some_and(|e| d.abs() <= 2.0 * e);
            n_covered += usize::from(within(n - 2.0, r.force_exponent_err));
            k_covered += usize::from(within(k - k_model, r.force_k2_n_m2_err));
        }
    }
    println!("{measured} of {} drops measured\n", runs.len());
    println!("| quantity | median | 95th pct | max | 2σ covers |");
    println!("| --- | --- | --- | --- | --- |");
    for (k, (name, ..)) in quantities.iter().enumerate() {
        let v = &mut errs[k];
        if v.is_empty() {
            continue;
        }
        let n = v.len();
        println!(
            "| {name} | {:.1e} | {:.1e} | {:.1e} | {}/{n} |",
            pct(v, 0.5),
            pct(v, 0.95),
            pct(v, 1.0),
            covered[k]
        );
    }
    let absmax = |v: &[f64]| v.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    println!(
        "\ncontact law: max |n − 2| = {:.4} (n free, 2σ covers {n_covered}/{}), max |K/K_model − 1| = {:.4} (K at n = 2, 2σ covers {k_covered}/{}) over {} drops",
        absmax(&dn),
        dn.len(),
        absmax(&dk),
        dk.len(),
        dn.len()
    );
    Ok(())
}
