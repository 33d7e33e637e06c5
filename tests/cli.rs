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
    assert!(text.contains("check-config"), "{text}");
    assert!(text.contains("render"), "{text}");
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
