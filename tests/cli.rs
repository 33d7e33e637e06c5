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
        "report",
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
    // Times to the nanosecond, without float noise (-0.0030000000000001137).
    let track = std::fs::read_to_string(results.join("tracks/R3mm_H1.5cm_01.csv")).unwrap();
    let first = track.lines().nth(1).unwrap();
    assert!(first.starts_with("-30,-0.003,"), "{first}");
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
    // Three drops of three radii: said once, plainly, what they can and
    // cannot show and where to see more, not nine warnings of fits that
    // need more drops, and no empty fit tables in the report.
    assert!(!err.contains("warning:"), "{err}");
    assert_eq!(err.matches("note: ").count(), 1, "{err}");
    assert!(
        err.contains("note: 3 drops of 3 radii")
            && err.contains("needs 3 drops of one radius")
            && err.contains("dropscope render --campaign"),
        "{err}"
    );
    let fits: serde_json::Value =
        serde_json::from_slice(&std::fs::read(results.join("fits.json")).unwrap()).unwrap();
    assert!(fits["few_drops"].as_str().unwrap().starts_with("3 drops"));
    assert_eq!(fits["warnings"].as_array().unwrap().len(), 1, "{fits}");
    let report = std::fs::read_to_string(results.join("report.html")).unwrap();
    assert!(report.contains("<p class=\"few-drops\">3 drops of 3 radii"));
    assert!(!report.contains("not fitted") && !report.contains("Warnings of the collapse"));
}

/// A job started from another folder on the same configuration reuses the
/// first one's results: the cache key names the manifest and the runs as
/// the file system does, not as relative to where the job was started
/// (`--config a.toml` from `ux/` and `--config ux/a.toml` from its parent
/// reprocessed every run, each time).
#[test]
fn a_job_started_from_another_folder_reuses_the_cached_runs() {
    let dir = tempfile::tempdir().unwrap();
    let ux = dir.path().join("ux");
    std::fs::create_dir(&ux).unwrap();
    let fixtures = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures");
    let text = std::fs::read_to_string(fixtures.join("runs.csv")).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    // One run, its path relative to the manifest (and so to the folder the
    // job is started from).
    let row = lines.next().unwrap();
    let run = row.split(',').nth(1).unwrap();
    let from = fixtures.join(run);
    std::fs::create_dir(ux.join(run)).unwrap();
    for f in std::fs::read_dir(&from).unwrap().flatten() {
        std::fs::copy(f.path(), ux.join(run).join(f.file_name())).unwrap();
    }
    std::fs::write(ux.join("runs.csv"), format!("{header}\n{row}\n")).unwrap();
    std::fs::write(
        ux.join("a.toml"),
        "[input]\nmanifest = \"runs.csv\"\n[output]\ndir = \"out\"\n",
    )
    .unwrap();
    let job = |cwd: &std::path::Path, config: &str| {
        let out = dropscope()
            .args([
                "run",
                "--threads",
                "1",
                "--no-animation",
                "--config",
                config,
            ])
            .current_dir(cwd)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert_eq!(out.status.code(), Some(0), "{err}");
        err
    };
    let first = job(&ux, "a.toml");
    assert!(first.contains("0 reused from the cache"), "{first}");
    for (cwd, config) in [(dir.path(), "ux/a.toml"), (ux.as_path(), "a.toml")] {
        let again = job(cwd, config);
        assert!(
            again.contains("1 reused from the cache"),
            "from {}: {again}",
            cwd.display()
        );
    }
}

/// `dropscope` alone takes `run`'s options, as the README shows them
/// (`dropscope --force` is not an "unexpected argument").
#[test]
fn the_main_job_takes_runs_options_without_the_subcommand() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/runs.csv");
    let keep_one = dir.path().join("runs.csv");
    let text = std::fs::read_to_string(&manifest).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let row = lines.next().unwrap();
    let base = manifest.parent().unwrap();
    let (run, rest) = row.split_once(',').unwrap();
    let (path, rest) = rest.split_once(',').unwrap();
    std::fs::write(
        &keep_one,
        format!("{header}\n{run},{},{rest}\n", base.join(path).display()),
    )
    .unwrap();
    std::fs::write(
        dir.path().join("pipeline.toml"),
        "[input]\nmanifest = \"runs.csv\"\n",
    )
    .unwrap();
    let go = || {
        dropscope()
            .args(["--force", "--threads", "1", "--out", "elsewhere"])
            .current_dir(dir.path())
            .output()
            .unwrap()
    };
    for _ in 0..2 {
        let out = go();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{err}");
        // --force: the second job reuses nothing from the first.
        assert!(err.contains("0 reused from the cache"), "{err}");
    }
    assert!(dir.path().join("elsewhere/drops.csv").is_file());
    // Options before a subcommand are refused rather than silently dropped.
    let out = dropscope()
        .args(["--force", "check-config"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
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

/// A folder of three 8-bit PNG frames and no PCC XML: no frame rate of its own.
fn folder_without_xml(dir: &std::path::Path) -> std::path::PathBuf {
    let run = dir.join("run");
    std::fs::create_dir(&run).unwrap();
    for i in 0..3u8 {
        image::GrayImage::from_pixel(4, 3, image::Luma([10 * i]))
            .save(run.join(format!("img_{i}.png")))
            .unwrap();
    }
    run
}

/// `inspect --json` of `input` run in `cwd` with `extra` arguments: (exit code, stdout, stderr).
fn inspect(
    cwd: &std::path::Path,
    input: &std::path::Path,
    extra: &[&str],
) -> (i32, String, String) {
    let out = dropscope()
        .current_dir(cwd)
        .arg("inspect")
        .arg(input)
        .arg("--json")
        .args(extra)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn json_fps(stdout: &str) -> f64 {
    let v: serde_json::Value = serde_json::from_str(stdout).unwrap();
    v["fps"].as_f64().unwrap()
}

/// Without a PCC XML the frame rate comes from `--fps`, else camera.fps of
/// `--config`, else of ./pipeline.toml; the embedded default sets none, so
/// without either inspect asks for --fps. The values are distinct, so each
/// assertion can only pass if that source was used.
#[test]
fn inspect_takes_a_folders_missing_fps_from_the_flag_or_the_configuration() {
    let dir = tempfile::tempdir().unwrap();
    let run = folder_without_xml(dir.path());
    let cfg = dir.path().join("cam.toml");
    std::fs::write(&cfg, "[camera]\nfps = 2500\n").unwrap();
    let cfg_arg = cfg.to_str().unwrap();
    let work = dir.path().join("work");
    std::fs::create_dir(&work).unwrap();

    // No ./pipeline.toml in `work`: the embedded default, which assumes no
    // frame rate.
    let embedded = dropscope::config::PipelineConfig::from_toml_str(
        dropscope::config::EMBEDDED_DEFAULT,
        std::path::Path::new("embedded"),
        std::path::Path::new(""),
    )
    .unwrap();
    assert_eq!(embedded.camera.fps, None);
    let (code, _, err) = inspect(&work, &run, &[]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("no frame rate") && err.contains("--fps"),
        "{err}"
    );

    // --config FILE.
    let (code, out, err) = inspect(&work, &run, &["--config", cfg_arg]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(json_fps(&out), 2500.0);
    assert!(
        out.contains("from camera.fps in") && out.contains("cam.toml"),
        "{out}"
    );

    // ./pipeline.toml.
    std::fs::write(work.join("pipeline.toml"), "[camera]\nfps = 3125\n").unwrap();
    let (code, out, err) = inspect(&work, &run, &[]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(json_fps(&out), 3125.0);

    // --fps wins over any configuration.
    let (code, out, err) = inspect(&work, &run, &["--config", cfg_arg, "--fps", "777"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(json_fps(&out), 777.0);
    assert!(out.contains("fps 777 from --fps"), "{out}");
}

/// `export --help` names the files as `export` writes them: by index from
/// 0, zero-padded to the movie's last (it said "named by frame number",
/// and a PCC folder's frames are numbered from its trigger, -30 here).
#[test]
fn export_names_its_files_as_its_help_says() {
    let dir = tempfile::tempdir().unwrap();
    let run = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/R3mm_H1.5cm_01");
    let help = dropscope().args(["export", "--help"]).output().unwrap();
    let help = String::from_utf8_lossy(&help.stdout);
    assert!(help.contains("`<input>_<index>.png`"), "{help}");
    let out = dropscope()
        .arg("export")
        .arg(&run)
        .args(["--frames", "0:2", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    // 90 frames: indices 00 to 89.
    assert_eq!(
        names,
        [
            "R3mm_H1.5cm_01_00.png",
            "R3mm_H1.5cm_01_01.png",
            "R3mm_H1.5cm_01_frames.csv"
        ]
    );
    let side = std::fs::read_to_string(dir.path().join("R3mm_H1.5cm_01_frames.csv")).unwrap();
    let first = side.lines().nth(1).unwrap();
    assert!(first.starts_with("R3mm_H1.5cm_01_00.png,0,-30,"), "{side}");
}

/// A configuration without camera.fps and no `--fps`: exit 2, and the
/// message names the folder and both places to set a frame rate.
#[test]
fn inspect_and_export_without_any_fps_say_where_to_set_it() {
    let dir = tempfile::tempdir().unwrap();
    let run = folder_without_xml(dir.path());
    let cfg = dir.path().join("nofps.toml");
    std::fs::write(&cfg, "[camera]\n").unwrap();
    let cfg_arg = cfg.to_str().unwrap();
    let (code, _, err) = inspect(dir.path(), &run, &["--config", cfg_arg]);
    assert_eq!(code, 2, "{err}");
    for needle in ["no frame rate", "--fps", "camera.fps", "nofps.toml", "run"] {
        assert!(err.contains(needle), "{needle:?} missing from: {err}");
    }
    let out = dropscope()
        .current_dir(dir.path())
        .arg("export")
        .arg(&run)
        .args(["--frames", "0:1", "--out"])
        .arg(dir.path().join("out"))
        .args(["--config", cfg_arg])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("no frame rate") && err.contains("--fps") && err.contains("camera.fps"),
        "{err}"
    );
    // With --fps the same export works.
    let out = dropscope()
        .current_dir(dir.path())
        .arg("export")
        .arg(&run)
        .args(["--frames", "0:1", "--fps", "100", "--out"])
        .arg(dir.path().join("out"))
        .args(["--config", cfg_arg])
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(dir.path().join("out/run_0.png").is_file());
}

/// Outside the checkout, `dropscope` says what to do, and says it once,
/// not "fixtures/runs.csv: No such file … (os error 2): No such file … (os error 2)".
#[test]
fn outside_the_checkout_the_errors_say_what_to_do_once() {
    let dir = tempfile::tempdir().unwrap();
    let out = dropscope().current_dir(dir.path()).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("no pipeline.toml in this folder")
            && err.contains("fixtures/runs.csv")
            && err.contains("--config"),
        "{err}"
    );
    let out = dropscope()
        .args(["collapse", "missing.csv"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        err.trim(),
        "error: missing.csv: No such file or directory (os error 2)"
    );
    // check-config prints TOML with the file's key names, to save and edit.
    let out = dropscope()
        .arg("check-config")
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("[surface.pdms]") && text.contains("pillar_height_mm = 3.5"),
        "{text}"
    );
    assert!(
        !text.contains("radius_m ") && !text.contains("surfaces"),
        "{text}"
    );
}

/// The advice of the error above, followed to the letter in a shell: the
/// shell makes an empty ./pipeline.toml before dropscope runs, so the
/// plain `check-config > pipeline.toml` it gave saved the resolved empty
/// file (no manifest line to set, no comments) and the next `dropscope`
/// said "the configuration names no input".
#[test]
fn the_advice_outside_the_checkout_saves_a_configuration_to_start_from() {
    let dir = tempfile::tempdir().unwrap();
    let out = dropscope().current_dir(dir.path()).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    let advice = "dropscope check-config --default > pipeline.toml";
    assert!(err.contains(&format!("`{advice}`")), "{err}");
    let bin = env!("CARGO_BIN_EXE_dropscope");
    let saved = Command::new("sh")
        .arg("-c")
        .arg(advice.replacen("dropscope", &format!("'{bin}'"), 1))
        .current_dir(dir.path())
        .status()
        .unwrap();
    assert!(saved.success());
    let text = std::fs::read_to_string(dir.path().join("pipeline.toml")).unwrap();
    assert_eq!(text, dropscope::config::EMBEDDED_DEFAULT);
    assert!(
        text.contains("\nmanifest = ") && text.contains("# The run manifest"),
        "{text}"
    );
    // With its manifest set to a runs.csv here, it is the main job's.
    let fixtures = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures");
    let runs = std::fs::read_to_string(fixtures.join("runs.csv")).unwrap();
    let (header, rest) = runs.split_once('\n').unwrap();
    let row = rest.lines().next().unwrap();
    let (run, tail) = row.split_once(',').unwrap();
    let (path, tail) = tail.split_once(',').unwrap();
    let row = format!("{run},{},{tail}", fixtures.join(path).display());
    std::fs::write(dir.path().join("my_runs.csv"), format!("{header}\n{row}\n")).unwrap();
    let edited = text.replace(
        "manifest = \"fixtures/runs.csv\"",
        "manifest = \"my_runs.csv\"",
    );
    assert_ne!(edited, text);
    std::fs::write(dir.path().join("pipeline.toml"), edited).unwrap();
    let out = dropscope()
        .args(["--no-animation", "--threads", "1"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(err.contains("1 run: 1 measured"), "{err}");
    // --default and --config are one or the other.
    let out = dropscope()
        .args(["check-config", "--default", "--config", "pipeline.toml"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
}

/// `--radii-mm 3 5 7` as `render --help` shows its default.
#[test]
fn list_options_take_spaces_as_well_as_commas() {
    let dir = tempfile::tempdir().unwrap();
    let out = dropscope()
        .args([
            "render",
            "--campaign",
            "--radii-mm",
            "3",
            "7",
            "--heights-cm",
            "1.5",
        ])
        .args(["--frames-before", "2", "--frames-after", "2", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    let manifest = std::fs::read_to_string(dir.path().join("runs.csv")).unwrap();
    assert_eq!(manifest.lines().count(), 3, "{manifest}");
}

/// The grid's options without `--campaign`, or a single drop's beside
/// `--drop`, are refused, naming the option, rather than silently ignored
/// (`render --radii-mm 3 5 7 --out D` rendering the one default 4.5 mm drop).
/// One drop is "1 drop", not "1 drops".
#[test]
fn render_refuses_options_it_would_ignore() {
    let dir = tempfile::tempdir().unwrap();
    for (args, named) in [
        (&["--radii-mm", "3", "5"][..], "--campaign"),
        (&["--heights-cm", "3"][..], "--campaign"),
        (&["--repeats", "2"][..], "--campaign"),
        (&["--drop", "3:1.5", "--radius-mm", "5"][..], "--radius-mm"),
        (&["--campaign", "--height-cm", "5"][..], "--height-cm"),
    ] {
        let out = dropscope()
            .arg("render")
            .args(args)
            .arg("--out")
            .arg(dir.path().join("x"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(named), "{args:?}: {err}");
        assert!(!dir.path().join("x").exists(), "{args:?} rendered");
    }
    let out = dropscope()
        .args([
            "render",
            "--frames-before",
            "2",
            "--frames-after",
            "2",
            "--out",
        ])
        .arg(dir.path().join("one"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("rendered 1 drop, "), "{err}");
}

/// `process --help` says what INPUTS may be: it said "one drop each",
/// though a folder of run folders works too (the test below).
#[test]
fn process_help_says_a_folder_of_runs_is_an_input() {
    let out = dropscope().args(["process", "--help"]).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("or folders holding them (searched at any depth; each run found is a drop)"),
        "{text}"
    );
}

/// `process` on a folder of run folders finds the runs (rather than
/// saying "no numbered frames"), and counts "with warnings" apart.
#[test]
fn process_finds_the_runs_in_a_folder_of_run_folders() {
    let dir = tempfile::tempdir().unwrap();
    let fixtures = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures");
    let out = dropscope()
        .arg("process")
        .arg(&fixtures)
        .args(["--radius-mm", "4.5", "--out"])
        .arg(dir.path())
        .current_dir(dir.path())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("3 runs: ") && err.contains(" with warnings, 0 failed"),
        "{err}"
    );
    let drops = dropscope::dataset::read_csv(&dir.path().join("drops.csv")).unwrap();
    let runs: Vec<&str> = drops.iter().map(|r| r.run.as_str()).collect();
    assert_eq!(runs, ["R3mm_H1.5cm_01", "R4.5mm_H12cm_01", "R7mm_H50cm_01"]);
}

/// A nonsense number for a flag (≤ 0, NaN, infinite) is refused by the
/// command line itself, naming the flag and the value, exit 2; a negative
/// number is taken as the flag's value, not as another flag. `inspect
/// --fps=-1` said "no frame rate … (or --fps)" although --fps was given;
/// `process --radius-mm -3` said "unexpected argument '-3'" with a tip that
/// made -3 an input path.
#[test]
fn numeric_flags_refuse_nonsense_naming_the_flag_and_the_value() {
    let dir = tempfile::tempdir().unwrap();
    let run = folder_without_xml(dir.path());
    let run_arg = run.to_str().unwrap();
    let out_dir = dir.path().join("out");
    let out_arg = out_dir.to_str().unwrap();
    let cases: &[(&[&str], &str, &str)] = &[
        (&["inspect", run_arg, "--fps=-1"], "--fps", "-1"),
        (&["inspect", run_arg, "--fps", "-1"], "--fps", "-1"),
        (&["inspect", run_arg, "--fps", "0"], "--fps", "0"),
        (&["inspect", run_arg, "--fps", "NaN"], "--fps", "NaN"),
        (&["inspect", run_arg, "--fps", "inf"], "--fps", "inf"),
        (
            &[
                "export", run_arg, "--frames", "0:1", "--out", out_arg, "--fps", "-5",
            ],
            "--fps",
            "-5",
        ),
        (
            &["process", run_arg, "--radius-mm", "-3", "--out", out_arg],
            "--radius-mm",
            "-3",
        ),
        (
            &["process", run_arg, "--radius-mm", "0", "--out", out_arg],
            "--radius-mm",
            "0",
        ),
        (&["render", "--fps", "-1", "--out", out_arg], "--fps", "-1"),
        (
            &["render", "--radius-mm", "-3", "--out", out_arg],
            "--radius-mm",
            "-3",
        ),
        (
            &["render", "--mm-per-px", "-0.04", "--out", out_arg],
            "--mm-per-px",
            "-0.04",
        ),
        (
            &[
                "render",
                "--campaign",
                "--radii-mm",
                "3",
                "-5",
                "--out",
                out_arg,
            ],
            "--radii-mm",
            "-5",
        ),
    ];
    for (args, flag, value) in cases {
        let out = dropscope()
            .current_dir(dir.path())
            .args(*args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains(&format!("invalid value '{value}' for '{flag} "))
                && err.contains("must be a number greater than 0"),
            "{args:?}: {err}"
        );
        assert!(!out_dir.exists(), "{args:?} wrote {}", out_dir.display());
    }
    // A flag whose range the command checks gets its negative value there.
    let out = dropscope()
        .args(["render", "--blur-px", "-1", "--out", out_arg])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("`--blur-px` = -1: must lie in [0, 20]"),
        "{err}"
    );
}

/// A command missing what it needs names every way to give it: `process`
/// without inputs said `<INPUTS>` was required, not `--manifest`; `export`
/// without a range said `--frames`, not `--numbers`. Giving both is
/// refused too.
#[test]
fn a_missing_requirement_names_its_alternatives() {
    let dir = tempfile::tempdir().unwrap();
    let run = folder_without_xml(dir.path());
    let run_arg = run.to_str().unwrap();
    let manifest = dir.path().join("runs.csv");
    std::fs::write(
        &manifest,
        format!("run,path,sphere_radius_mm\nrun,{run_arg},3\n"),
    )
    .unwrap();
    let m_arg = manifest.to_str().unwrap();
    for (args, needles) in [
        (
            &["process", "--out", "o"][..],
            &["INPUTS", "--manifest"][..],
        ),
        (
            &["export", run_arg, "--out", "d"],
            &["--frames", "--numbers"],
        ),
        (
            &["process", run_arg, "--manifest", m_arg, "--out", "o"],
            &["--manifest", "cannot be used with"],
        ),
        (
            &[
                "export",
                run_arg,
                "--frames",
                "0:1",
                "--numbers",
                "0:1",
                "--out",
                "d",
            ],
            &["--frames", "--numbers", "cannot be used with"],
        ),
    ] {
        let out = dropscope()
            .current_dir(dir.path())
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        let first = err.split("Usage:").next().unwrap();
        for n in needles {
            assert!(
                first.contains(n),
                "{args:?}: {n:?} missing from the message: {err}"
            );
        }
        assert!(!dir.path().join("o").exists() && !dir.path().join("d").exists());
    }
}

/// A configuration whose `input.manifest` is not there: `check-config`
/// and the main job both name the key, the path as resolved and the
/// configuration file, exit 2 (not "valid", nor only
/// "fixtures/runs.csv: No such file or directory"). The built-in
/// default outside the checkout gets a warning saying how to start a
/// configuration, and is still printed.
#[test]
fn a_missing_manifest_is_named_by_its_key_and_configuration() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("ux.toml");
    std::fs::write(&cfg, "[input]\nmanifest = \"fixtures/runs.csv\"\n").unwrap();
    let cfg_arg = cfg.to_str().unwrap();
    let resolved = dir.path().join("fixtures/runs.csv");
    let resolved = resolved.to_str().unwrap();
    let work = dir.path().join("work");
    std::fs::create_dir(&work).unwrap();
    for args in [
        &["check-config", "--config", cfg_arg][..],
        &["run", "--config", cfg_arg, "--out", "o"],
        &["--config", cfg_arg, "--out", "o"],
    ] {
        let out = dropscope().current_dir(&work).args(args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(
            err.trim(),
            format!(
                "error: {cfg_arg}: key `input.manifest` = {resolved}: no such file (a relative \
                 path is taken from the configuration file's folder): correct the path, or \
                 write the manifest there"
            ),
            "{args:?}"
        );
        assert!(!String::from_utf8_lossy(&out.stdout).contains("valid"));
    }
    // ./pipeline.toml: the same, named so.
    std::fs::copy(&cfg, work.join("pipeline.toml")).unwrap();
    let out = dropscope()
        .current_dir(&work)
        .arg("check-config")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("./pipeline.toml: key `input.manifest` = ")
            && err.contains(&work.join("fixtures/runs.csv").display().to_string()),
        "{err}"
    );
    // Once the manifest is there, valid.
    std::fs::create_dir(dir.path().join("fixtures")).unwrap();
    std::fs::write(resolved, "run,path,sphere_radius_mm\na,a,3\n").unwrap();
    let out = dropscope()
        .args(["check-config", "--config", cfg_arg])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&out.stdout).contains(": valid;"));
    // The built-in default outside the checkout: a warning, and the template.
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let out = dropscope()
        .current_dir(&empty)
        .arg("check-config")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(
        err.starts_with("warning: (embedded pipeline.toml): key `input.manifest` = ")
            && err.contains("`dropscope check-config --default > pipeline.toml`")
            && err.contains("set [input] manifest to your runs.csv"),
        "{err}"
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("[surface.pdms]"));
}
