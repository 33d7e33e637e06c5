//! Footage that was not made for dropscope, through the command line alone:
//! a recording without its frame rate, the scale and the surface row given
//! as flags, where each value came from in its row, and what is said when
//! a value is assumed.

use dropscope::dataset::{read_csv, DropRecord, DropStatus};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

fn dropscope(cwd: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_dropscope"));
    c.current_dir(cwd);
    c
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A 4.5 mm sphere from 12 cm filmed at 30 000 frames/s (20 µs exposure),
/// rendered once for this module: (its folder with the PCC XML, its truth).
fn drop_30k() -> &'static (tempfile::TempDir, PathBuf, serde_json::Value) {
    static DROP: OnceLock<(tempfile::TempDir, PathBuf, serde_json::Value)> = OnceLock::new();
    DROP.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let o = dropscope(dir.path())
            .args([
                "render",
                "--drop",
                "4.5:12",
                "--fps",
                "30000",
                "--exposure-us",
                "20",
                "--out",
                "r",
            ])
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let run = dir.path().join("r/R4.5mm_H12cm_01");
        let truth =
            serde_json::from_slice(&std::fs::read(run.join("truth.json")).unwrap()).unwrap();
        (dir, run, truth)
    })
}

/// A copy of the rendered drop's frames, without its XML side file (and
/// without the frames numbered `cut_from` and later, when given).
fn frames_only(dir: &Path, name: &str, cut_from: Option<i64>) -> PathBuf {
    let (_, run, _) = drop_30k();
    let out = dir.join(name);
    std::fs::create_dir_all(&out).unwrap();
    for e in std::fs::read_dir(run).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_none_or(|x| x != "tif") {
            continue;
        }
        let stem = p.file_stem().unwrap().to_string_lossy().into_owned();
        let number: i64 = stem.rsplit('_').next().unwrap().parse().unwrap();
        if cut_from.is_some_and(|c| number >= c) {
            continue;
        }
        std::fs::copy(&p, out.join(p.file_name().unwrap())).unwrap();
    }
    out
}

/// `dropscope process INPUT --radius-mm 4.5 ARGS --out OUT` from `cwd`
/// (no pipeline.toml there: the embedded default): its output and the row.
fn process(cwd: &Path, input: &Path, args: &[&str]) -> (Output, DropRecord) {
    let out = cwd.join("out");
    let o = dropscope(cwd)
        .arg("process")
        .arg(input)
        .args(["--radius-mm", "4.5", "--force", "--no-animation"])
        .args(args)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let rows = read_csv(&out.join("drops.csv")).unwrap_or_else(|e| panic!("{e}: {}", stderr(&o)));
    assert_eq!(rows.len(), 1);
    (o, rows.into_iter().next().unwrap())
}

fn flags(r: &DropRecord) -> Vec<&str> {
    r.flags.split(' ').filter(|w| !w.is_empty()).collect()
}

/// A 30 000 frames/s drop whose XML is gone was measured at the 10 000
/// frames/s of the shipped configuration without a word (its free flight
/// then looks like 1.1 m/s² of gravity, and other drops fail outright).
/// Now its row says the rate was assumed (`fps_source` `default`, flag
/// `fps_assumed`, a reason naming 10000 and --fps), and so does the
/// console; with `--fps 30000` the same frames give the true speed.
#[test]
fn a_recording_without_its_frame_rate_says_it_was_assumed_and_takes_fps() {
    let (_, _, truth) = drop_30k();
    let dir = tempfile::tempdir().unwrap();
    let frames = frames_only(dir.path(), "no_xml", None);

    let (o, r) = process(dir.path(), &frames, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(r.status, DropStatus::Warning, "{}", r.reason);
    assert_eq!((r.fps, r.fps_source.as_str()), (Some(10_000.0), "default"));
    assert!(flags(&r).contains(&"fps_assumed"), "{}", r.flags);
    assert!(
        r.reason.contains("10000 frames/s") && r.reason.contains("--fps"),
        "{}",
        r.reason
    );
    let err = stderr(&o);
    assert!(
        err.contains("warning: frame rate assumed")
            && err.contains("fps_source default")
            && err.contains("--fps")
            && err.contains("no_xml"),
        "{err}"
    );

    let (o, r) = process(dir.path(), &frames, &["--fps", "30000"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(r.status, DropStatus::Ok, "{}", r.reason);
    assert_eq!((r.fps, r.fps_source.as_str()), (Some(30_000.0), "flag"));
    // The fixtures' v_impact target (0.02 %), times 5 for a single
    // realistic drop measured on its own free fall.
    let v = truth["v_impact_m_s"].as_f64().unwrap();
    let rel = r.v_impact_m_s.unwrap() / v - 1.0;
    assert!(rel.abs() < 1e-3, "v_impact {:?} vs {v}", r.v_impact_m_s);
    assert!(!stderr(&o).contains("frame rate assumed"), "{}", stderr(&o));
    let provenance: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("out/provenance.json")).unwrap())
            .unwrap();
    assert_eq!(
        provenance["command_line"]["fps"],
        serde_json::json!(30000.0),
        "{provenance}"
    );
    assert!(provenance["configuration"].get("command_line").is_none());
}

/// Precedence: the recording's own rate over `--fps` (which disagrees: flag
/// `fps_mismatch`, said on the console), the manifest's `fps` over `--fps`,
/// `--fps` over `camera.fps`, and `camera.fps` flagged as assumed.
#[test]
fn the_frame_rate_comes_from_the_recording_then_manifest_flag_and_configuration() {
    let (_, run, _) = drop_30k();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();

    let (o, r) = process(d, run, &["--fps", "25000"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!((r.fps, r.fps_source.as_str()), (Some(30_000.0), "xml"));
    assert!(flags(&r).contains(&"fps_mismatch"), "{}", r.flags);
    assert!(r.reason.contains("--fps 25000"), "{}", r.reason);
    assert!(
        stderr(&o).contains("R4.5mm_H12cm_01: --fps 25000 disagrees"),
        "{}",
        stderr(&o)
    );

    let frames = frames_only(d, "no_xml", None);
    std::fs::write(
        d.join("runs.csv"),
        "run,path,sphere_radius_mm,fps\nno_xml,no_xml,4.5,30000\n",
    )
    .unwrap();
    let o = dropscope(d)
        .args(["process", "--manifest", "runs.csv", "--fps", "20000"])
        .args(["--no-animation", "--out", "by_manifest"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let r = &read_csv(&d.join("by_manifest/drops.csv")).unwrap()[0];
    assert_eq!((r.fps, r.fps_source.as_str()), (Some(30_000.0), "manifest"));

    let cfg = d.join("cam.toml");
    std::fs::write(
        &cfg,
        dropscope::config::EMBEDDED_DEFAULT
            .replace("# fps = 10000.0", "fps = 30000.0")
            .replace("manifest = \"fixtures/runs.csv\"", ""),
    )
    .unwrap();
    let cfg = cfg.to_str().unwrap();
    let (o, r) = process(d, &frames, &["--config", cfg]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!((r.fps, r.fps_source.as_str()), (Some(30_000.0), "config"));
    assert!(flags(&r).contains(&"fps_assumed"), "{}", r.flags);
    assert!(r.reason.contains("camera.fps"), "{}", r.reason);
    assert!(stderr(&o).contains("fps_source config"), "{}", stderr(&o));
    let (_, r) = process(d, &frames, &["--config", cfg, "--fps", "30000"]);
    assert_eq!(r.fps_source, "flag");
    assert!(!flags(&r).contains(&"fps_assumed"), "{}", r.flags);
}

/// `--mm-per-px` is the scale (`given`) and `--surface-row-px` the surface
/// row, for `process` and for the main job's manifest-less inputs.
#[test]
fn scale_and_surface_row_come_from_the_command_line() {
    let (_, run, truth) = drop_30k();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = truth["mm_per_px"].as_f64().unwrap();
    // A row one pixel below the true line: used as given, not found again.
    let row = truth["surface_row_px"].as_f64().unwrap().round() + 1.0;
    let (o, r) = process(
        d,
        run,
        &[
            "--mm-per-px",
            &s.to_string(),
            "--surface-row-px",
            &row.to_string(),
        ],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!((r.mm_per_px, r.scale_source.as_str()), (Some(s), "given"));
    assert_eq!(r.surface_row_px, Some(row));

    // `run` on a configuration naming input paths, no manifest.
    let cfg = d.join("paths.toml");
    std::fs::write(
        &cfg,
        dropscope::config::EMBEDDED_DEFAULT
            .replace(
                "manifest = \"fixtures/runs.csv\"",
                &format!("paths = [{:?}]", run.display().to_string()),
            )
            .replace("# radius_mm = 4.5", "radius_mm = 4.5"),
    )
    .unwrap();
    let o = dropscope(d)
        .args(["run", "--config"])
        .arg(&cfg)
        .args(["--no-animation", "--mm-per-px", &s.to_string(), "--out"])
        .arg(d.join("job"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let r = &read_csv(&d.join("job/drops.csv")).unwrap()[0];
    assert_eq!((r.mm_per_px, r.scale_source.as_str()), (Some(s), "given"));
    assert_eq!(r.fps_source, "xml");
}

/// `export` of frames without a frame rate of their own says the times it
/// writes are at the configuration's assumed rate; with --fps it does not.
#[test]
fn export_warns_when_its_times_are_at_an_assumed_rate() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let frames = frames_only(d, "no_xml", None);
    std::fs::write(d.join("pipeline.toml"), "[camera]\nfps = 12500\n").unwrap();
    let export = |extra: &[&str]| {
        dropscope(d)
            .arg("export")
            .arg(&frames)
            .args(["--frames", "0:1", "--out", "x"])
            .args(extra)
            .output()
            .unwrap()
    };
    let o = export(&[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("warning: ")
            && err.contains("holds no frame rate")
            && err.contains("12500")
            && err.contains("camera.fps")
            && err.contains("--fps"),
        "{err}"
    );
    let o = export(&["--fps", "30000"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
}
