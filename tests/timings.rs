//! `--timings`: `process` and the main job print where their
//! time went, stage by stage, and write the same bytes as without it.

use crate::run::{assert_same_tree, fixture_manifest, run, stderr, tree, write_config};
use dropscope::util::timings::Stage;
use std::path::Path;
use std::process::Command;

/// The table's row for every stage: six numbers, none negative (wall and
/// CPU seconds, their shares, and the per-drop means); the stages of
/// `absent` (those this command does not run) at zero.
fn check_table(err: &str, drops: usize, absent: &[Stage]) {
    let head = format!("timings, summed over runs and threads ({drops} drops measured):");
    let table = &err[err.find(&head).unwrap_or_else(|| panic!("no table: {err}"))..];
    for s in Stage::ALL {
        let line = table
            .lines()
            .find(|l| l.starts_with(s.name()))
            .unwrap_or_else(|| panic!("no row for {}:\n{table}", s.name()));
        let numbers: Vec<f64> = line[s.name().len()..]
            .split_whitespace()
            .map(|v| {
                v.trim_end_matches('%')
                    .parse()
                    .unwrap_or_else(|_| panic!("{v:?} in {line:?}"))
            })
            .collect();
        assert_eq!(numbers.len(), 6, "{line}");
        assert!(numbers.iter().all(|v| *v >= 0.0), "{line}");
        if absent.contains(&s) {
            assert!(numbers.iter().all(|v| *v == 0.0), "{line}");
        }
    }
    assert!(
        table.lines().any(|l| l.starts_with("sum of the stages")),
        "{table}"
    );
    assert!(table.contains(" s wall on "), "{table}");
}

#[test]
fn timings_change_no_output_and_name_every_stage() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // `process` on the fixtures, with and without.
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/runs.csv");
    let process = |out: &str, extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_dropscope"))
            .arg("process")
            .arg("--manifest")
            .arg(&manifest)
            .arg("--out")
            .arg(d.join(out))
            .args(extra)
            .output()
            .unwrap()
    };
    let timed = process("p-timed", &["--timings"]);
    assert_eq!(timed.status.code(), Some(0), "{}", stderr(&timed));
    let plain = process("p-plain", &[]);
    assert_eq!(plain.status.code(), Some(0), "{}", stderr(&plain));
    assert!(!stderr(&plain).contains("timings"), "{}", stderr(&plain));
    assert_same_tree(&d.join("p-timed"), &d.join("p-plain"), "process --timings");
    check_table(&stderr(&timed), 3, &[Stage::Collapse, Stage::Report]);

    // The main job without, then with (--force: measured again) in the same
    // folder (its configuration's path is in provenance.json).
    let job = d.join("job");
    std::fs::create_dir_all(&job).unwrap();
    fixture_manifest(&job);
    let config = write_config(&job, "");
    let plain = run(&config, &[]);
    assert_eq!(plain.status.code(), Some(0), "{}", stderr(&plain));
    let before = tree(&job.join("out"));
    let timed = run(&config, &["--timings", "--force"]);
    assert_eq!(timed.status.code(), Some(0), "{}", stderr(&timed));
    check_table(&stderr(&timed), 3, &[]);
    let after = tree(&job.join("out"));
    assert_eq!(
        before.keys().collect::<Vec<_>>(),
        after.keys().collect::<Vec<_>>()
    );
    for (rel, bytes) in &before {
        assert!(
            bytes == &after[rel],
            "dropscope run --timings: {rel} differs"
        );
    }
    // All from the cache: no drop measured, no per-drop mean.
    let again = run(&config, &["--timings"]);
    assert_eq!(again.status.code(), Some(0), "{}", stderr(&again));
    let err = stderr(&again);
    assert!(err.contains("(0 drops measured)"), "{err}");
}

/// `--threads 1` bounds every stage, the per-drop figures and the collapse
/// with the runs: `--timings` counts the worker threads that did a stage's
/// work (the figures and the collapse were drawn on rayon's global pool, one
/// thread per core, beside the runs' one).
#[test]
fn one_thread_asked_is_one_thread_for_every_stage() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/runs.csv");
    let timed = Command::new(env!("CARGO_BIN_EXE_dropscope"))
        .arg("process")
        .arg("--manifest")
        .arg(&manifest)
        .args(["--threads", "1", "--timings", "--out"])
        .arg(d.join("p"))
        .output()
        .unwrap();
    let err = stderr(&timed);
    assert_eq!(timed.status.code(), Some(0), "{err}");
    assert!(
        err.contains("on 1 thread (") && err.contains("its stages ran on 1 worker thread"),
        "{err}"
    );
    let job = d.join("job");
    std::fs::create_dir_all(&job).unwrap();
    fixture_manifest(&job);
    let config = write_config(&job, "");
    let timed = run(&config, &["--threads", "1", "--timings"]);
    let err = stderr(&timed);
    assert_eq!(timed.status.code(), Some(0), "{err}");
    assert!(err.contains("collapse done"), "{err}");
    assert!(err.contains("its stages ran on 1 worker thread"), "{err}");
}
