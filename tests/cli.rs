//! The command line as a user meets it: help text, errors and exit codes.

use std::process::Command;

fn dropscope() -> Command {
    Command::new(env!("CARGO_BIN_EXE_dropscope"))
}

#[test]
fn help_lists_the_built_subcommands() {
    let out = dropscope().arg("--help").output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for sub in [
        "run",
        "render",
        "inspect",
        "export",
        "process",
        "collapse",
        "check-config",
    ] {
        assert!(text.contains(sub), "{sub} missing from: {text}");
    }
}

#[test]
fn a_bad_configuration_exits_2_and_names_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("pipeline.toml");
    std::fs::write(&cfg, "[camera]\nfps = -5\n").unwrap();
    let out = dropscope()
        .args(["check-config", "--config"])
        .arg(&cfg)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("camera.fps") && err.contains("-5"), "{err}");
}

/// `dropscope` with no argument is the main job on ./pipeline.toml:
/// every run of the manifest processed, then the collapse.
#[test]
fn no_argument_runs_the_main_job_on_the_local_pipeline_toml() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/runs.csv");
    std::fs::write(
        dir.path().join("pipeline.toml"),
        format!(
            "[input]\nmanifest = \"{}\"\n[output]\ndir = \"results\"\n",
            manifest.display()
        ),
    )
    .unwrap();
    let out = dropscope().current_dir(dir.path()).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(
        err.contains("3 runs: 3 measured, 0 with warnings, 0 failed, 0 reused from the cache")
            && err.contains("collapse done"),
        "{err}"
    );
    let results = dir.path().join("results");
    let drops = dropscope::dataset::read_csv(&results.join("drops.csv")).unwrap();
    assert_eq!(drops.len(), 3);
    for f in [
        "collapse.csv",
        "fits.json",
        "plots/pi_vs_eta.svg",
        "tracks/R3mm_H1.5cm_01.csv",
        "runs/R3mm_H1.5cm_01.json",
        "provenance.json",
    ] {
        assert!(results.join(f).is_file(), "{f} missing");
    }
}

/// The main job names a missing manifest and exits 2.
#[test]
fn the_main_job_names_a_missing_manifest() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("pipeline.toml"),
        "[input]\nmanifest = \"nope.csv\"\n",
    )
    .unwrap();
    let out = dropscope()
        .arg("run")
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("nope.csv"));
}
