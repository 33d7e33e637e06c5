//! Camera set-ups found from the images (`camera.infer_setups`):
//! a manifest without a `setup` column, as independent footage comes, still
//! gets each set-up's pooled free-fall scale.

use dropscope::config::{PipelineConfig, EMBEDDED_DEFAULT};
use dropscope::dataset::manifest::{read_manifest, RunSpec};
use dropscope::dataset::{DropRecord, DropStatus};
use dropscope::job::batch::{process_runs, JobOptions};
use dropscope::job::cache::cached_scene;
use dropscope::render::render;
use std::path::Path;

use crate::render::args;

/// A `--preset real` campaign of a 4 mm sphere (seed 7) from
/// `heights_cm`, `repeats` times (each repeat its own camera set-up:
/// zoom, surface row and roll), rendered into `out`; its manifest's runs.
pub(crate) fn real_r4_campaign(out: &Path, heights_cm: &str, repeats: &str) -> Vec<RunSpec> {
    let a = [
        "--out",
        out.to_str().unwrap(),
        "--campaign",
        "--preset",
        "real",
        "--radii-mm",
        "4",
        "--heights-cm",
        heights_cm,
        "--repeats",
        repeats,
        "--seed",
        "7",
    ];
    render(&args(&a)).unwrap_or_else(|e| panic!("render {a:?}: {e}"));
    read_manifest(&out.join("runs.csv")).unwrap()
}

/// Two set-ups, three heights each, and the manifest written without its
/// `setup` column. Returns the runs with their true set-ups and the
/// manifest's path.
fn two_setups(dir: &Path) -> (Vec<RunSpec>, std::path::PathBuf) {
    let runs = real_r4_campaign(&dir.join("c"), "1.5,6,25", "2");
    let mut csv = String::from("run,path,sphere_radius_mm,drop_height_cm\n");
    for r in &runs {
        csv += &format!(
            "{},{},{},{}\n",
            r.run,
            r.path.display(),
            r.sphere_radius_mm,
            r.drop_height_cm.unwrap()
        );
    }
    let manifest = dir.join("nosetup.csv");
    std::fs::write(&manifest, csv).unwrap();
    (runs, manifest)
}

fn truth(run: &RunSpec) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(run.path.join("truth.json")).unwrap()).unwrap()
}

/// Without a `setup` column the two set-ups are found from the images
/// (every run of one and none of the other), each run takes its set-up's
/// pooled free-fall scale, and v_impact meets the free-fall target
/// (0.05 %) — where each run alone, with `infer_setups = false`,
/// has the 25 cm drop's scale from its own 2 cm of flight or its
/// silhouette, 10× less precise. The scenes are kept in the cache, and a
/// second job reuses every run.
#[test]
fn setups_are_found_from_the_images_when_the_manifest_names_none() {
    let dir = tempfile::tempdir().unwrap();
    let (runs, manifest) = two_setups(dir.path());
    let read = read_manifest(&manifest).unwrap();
    assert!(read.iter().all(|r| r.setup.is_none()));
    let cfg =
        PipelineConfig::from_toml_str(EMBEDDED_DEFAULT, Path::new("pipeline.toml"), dir.path())
            .unwrap();
    let out = dir.path().join("out");
    let process = || {
        let done = process_runs(&read, &cfg, &out, &JobOptions::default(), &[], &|_| {})
            .unwrap()
            .done;
        let hits = done.iter().filter(|(_, hit)| *hit).count();
        let records: Vec<DropRecord> = done.into_iter().map(|(e, _)| e.record).collect();
        (records, hits)
    };
    let (records, hits) = process();
    assert_eq!(hits, 0);
    for ((r, run), alone) in records.iter().zip(&runs).zip(&read) {
        assert_ne!(r.status, DropStatus::Failed, "{}: {}", run.run, r.reason);
        let t = truth(run);
        assert!(
            r.setup.starts_with("auto"),
            "{}: setup {:?}",
            run.run,
            r.setup
        );
        for (other, o) in records.iter().zip(&runs) {
            // Together exactly when filmed together.
            assert_eq!(
                other.setup == r.setup,
                o.setup == run.setup,
                "{} and {}",
                run.run,
                o.run
            );
        }
        assert_eq!(r.scale_source, "setup_free_fall", "{}", run.run);
        let s_true = t["mm_per_px"].as_f64().unwrap();
        let (s, s_err) = (r.mm_per_px.unwrap(), r.mm_per_px_err.unwrap());
        assert!(
            (s - s_true).abs() < 2.0 * s_err,
            "{}: scale {s} ± {s_err} against {s_true}",
            run.run
        );
        let v_true = t["v_impact_m_s"].as_f64().unwrap();
        let (v, v_err) = (r.v_impact_m_s.unwrap(), r.v_impact_m_s_err.unwrap());
        eprintln!(
            "{} ({}): v {:+.1e} (σ {:.1e})",
            run.run,
            r.setup,
            v / v_true - 1.0,
            v_err / v_true
        );
        // The speed at contact rests on the surface line (the time the
        // flight crosses it): where the contact law's cross-check flags
        // the line (a band top the images hide), v is held to its error;
        // elsewhere to the free-fall target. (Its error bar is not asserted
        // here: through a lens measured from a structured band top's bow it
        // is too small on the 25 cm drop, 4σ; accuracy_campaign measures
        // the coverage over campaigns.)
        if r.flags.contains("surface_law_disagreement") {
            assert!(
                (v - v_true).abs() < 3.0 * v_err,
                "{}: v {v} ± {v_err} against {v_true}",
                run.run
            );
        } else {
            assert!(
                (v / v_true - 1.0).abs() < 5e-4,
                "{}: v {v} against {v_true}",
                run.run
            );
        }
        assert!(cached_scene(&out, &cfg, alone).is_some(), "{}", run.run);
    }
    let (again, hits) = process();
    assert_eq!(hits, runs.len());
    assert_eq!(again, records);

    // Each run alone: the fastest drop's scale is its own 2 cm of flight or
    // its silhouette.
    let mut alone_cfg = cfg.clone();
    alone_cfg.camera.infer_setups = false;
    let fast = read.iter().position(|r| r.run.contains("H25cm")).unwrap();
    let alone = dropscope::pipeline::process_run(&read[fast], &alone_cfg, &[]).record;
    let pooled_err = records[fast].v_impact_m_s_err.unwrap();
    assert!(
        alone.v_impact_m_s_err.unwrap() > 10.0 * pooled_err,
        "alone {:?} against pooled {pooled_err}",
        alone.v_impact_m_s_err
    );
}

/// Four camera set-ups, one drop each (nothing to pool): three slow drops
/// whose own free falls give their scales to 3e-4 measure the silhouette's
/// edge offset (0.1–0.5 px small in `--preset real`), and the fast drop,
/// scaled by its apparent radius, is corrected by their mean and carries
/// their spread as a 95 % prediction interval. Without that (no
/// inference, so no scenes) it carries the fixed 0.3 px instead.
#[test]
fn a_run_alone_is_scaled_by_its_silhouette_less_the_jobs_edge_offset() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("c");
    let a = [
        "--out",
        out.to_str().unwrap(),
        "--preset",
        "real",
        "--seed",
        "7",
        "--drop",
        "4:1.5,4:1.5,4:1.5,4:25,4:25,4:25,4:25",
    ];
    render(&args(&a)).unwrap_or_else(|e| panic!("render {a:?}: {e}"));
    let all = read_manifest(&out.join("runs.csv")).unwrap();
    // The slow drops of set-ups 1–3 and the fast one of set-up 4.
    let runs: Vec<RunSpec> = all
        .into_iter()
        .filter(|r| r.run.contains("H1.5cm") || r.run.ends_with("H25cm_04"))
        .map(|mut r| {
            r.setup = None;
            r
        })
        .collect();
    assert_eq!(runs.len(), 4);
    let cfg =
        PipelineConfig::from_toml_str(EMBEDDED_DEFAULT, Path::new("pipeline.toml"), dir.path())
            .unwrap();
    let records =
        dropscope::job::run_outputs::process_all(&runs, &cfg, &dir.path().join("out"), &|_| {})
            .unwrap();
    let slow: Vec<f64> = records[..3]
        .iter()
        .map(|r| {
            assert_eq!(r.scale_source, "free_fall", "{}", r.run);
            r.edge_offset_px.unwrap()
        })
        .collect();
    let fast = &records[3];
    assert_eq!(fast.setup, "", "no set-up to share");
    assert_eq!(fast.scale_source, "radius");
    let mean = slow.iter().sum::<f64>() / 3.0;
    assert!(
        (fast.edge_offset_px.unwrap() - mean).abs() < 1e-9,
        "{fast:?}"
    );
    let t = truth(&runs[3]);
    let s_true = t["mm_per_px"].as_f64().unwrap();
    let (s, err) = (fast.mm_per_px.unwrap(), fast.mm_per_px_err.unwrap());
    let r_px = 4.0 / s_true;
    eprintln!(
        "edge offset {:.3} ± {:.3} px from {slow:?}; fast drop's scale {:+.1e} (σ {:.1e})",
        mean,
        fast.edge_offset_px_err.unwrap(),
        s / s_true - 1.0,
        err / s
    );
    assert!(
        (s - s_true).abs() < 2.0 * err,
        "{s} ± {err} against {s_true}"
    );
    assert!(
        err / s < 0.3 / r_px,
        "no more precise than the fixed 0.3 px"
    );
    // Each run alone: the fixed 0.3 px, uncorrected.
    let mut alone = cfg.clone();
    alone.camera.infer_setups = false;
    let r = dropscope::pipeline::process_run(&runs[3], &alone, &[]).record;
    assert_eq!(
        (r.scale_source.as_str(), r.edge_offset_px),
        ("radius", None)
    );
    assert!((r.mm_per_px_err.unwrap() / r.mm_per_px.unwrap() * r_px / 0.3 - 1.0).abs() < 0.01);
}
