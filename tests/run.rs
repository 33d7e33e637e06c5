//! The main job as users run it (`dropscope run`): bad runs mixed
//! into a campaign, the result cache, kill-and-resume, and byte-identical
//! outputs across repeats and thread counts.

use dropscope::dataset::{read_csv, DropStatus};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub(crate) fn fixture(name: &str) -> PathBuf {
    root().join("fixtures").join(name)
}

/// `dropscope run --config CONFIG ARGS…`.
pub(crate) fn run(config: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dropscope"))
        .arg("run")
        .arg("--config")
        .arg(config)
        .args(args)
        .output()
        .unwrap()
}

/// A configuration beside `manifest` (no camera.fps: a folder without an
/// XML has no frame rate anywhere), writing to `out` next to it.
pub(crate) fn write_config(dir: &Path, extra: &str) -> PathBuf {
    let cfg = dir.join("pipeline.toml");
    std::fs::write(
        &cfg,
        format!(
            "[input]\nmanifest = \"runs.csv\"\nsurface = \"pdms\"\n\
             [surface.pdms]\nmodulus_pa = 1.6e6\npillar_height_mm = 3.5\n\
             pillar_width_mm = 2.5\nchannel_width_mm = 1.5\n\
             [detect]\n{extra}\n[output]\ndir = \"out\"\n"
        ),
    )
    .unwrap();
    cfg
}

/// The three fixture drops, by absolute path.
pub(crate) fn fixture_manifest(dir: &Path) {
    let mut m = String::from("run,path,sphere_radius_mm\n");
    for (run, r) in [
        ("R3mm_H1.5cm_01", 3.0),
        ("R4.5mm_H12cm_01", 4.5),
        ("R7mm_H50cm_01", 7.0),
    ] {
        m += &format!("{run},{},{r}\n", fixture(run).display());
    }
    std::fs::write(dir.join("runs.csv"), m).unwrap();
}

/// Every file under `dir`, by path relative to it.
pub(crate) fn tree(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    fn walk(base: &Path, d: &Path, out: &mut BTreeMap<String, Vec<u8>>) {
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(base, &p, out);
            } else {
                let rel = p.strip_prefix(base).unwrap().display().to_string();
                out.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

pub(crate) fn assert_same_tree(a: &Path, b: &Path, what: &str) {
    let (ta, tb) = (tree(a), tree(b));
    assert_eq!(
        ta.keys().collect::<Vec<_>>(),
        tb.keys().collect::<Vec<_>>(),
        "{what}: not the same files"
    );
    for (rel, bytes) in &ta {
        assert!(bytes == &tb[rel], "{what}: {rel} differs");
    }
}

pub(crate) fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A campaign with the good fixture drops and, mixed in, a truncated TIFF,
/// a folder with no XML and no frame rate anywhere, a corrupt cine, a
/// sphere that never lands and an empty folder: the good runs are measured,
/// each bad one has a failed row that says what is wrong (the folder
/// without a frame rate is measured at an assumed one, flagged; the sphere
/// that never lands is `tracked`), the job exits 1.
#[test]
fn broken_runs_get_reasons_and_the_good_ones_finish() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let good = fixture("R4.5mm_H12cm_01");
    let frames: Vec<PathBuf> = {
        let mut v: Vec<PathBuf> = std::fs::read_dir(&good)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "png"))
            .collect();
        v.sort();
        v
    };
    // The good drop as 8-bit TIFFs, with one frame cut in half.
    let tiff = d.join("truncated_tiff");
    std::fs::create_dir(&tiff).unwrap();
    std::fs::copy(good.join("R4.5mm_H12cm_01.xml"), tiff.join("t.xml")).unwrap();
    for p in &frames {
        let name = p
            .file_stem()
            .unwrap()
            .to_string_lossy()
            .replace("R4.5mm_H12cm_01", "t");
        image::open(p)
            .unwrap()
            .save(tiff.join(format!("{name}.tif")))
            .unwrap();
    }
    let victim = tiff.join("t_000010.tif");
    let bytes = std::fs::read(&victim).unwrap();
    std::fs::write(&victim, &bytes[..bytes.len() / 2]).unwrap();
    // The same frames without their XML.
    let no_xml = d.join("no_xml");
    std::fs::create_dir(&no_xml).unwrap();
    for p in &frames {
        std::fs::copy(p, no_xml.join(p.file_name().unwrap())).unwrap();
    }
    // Cut before contact: the sphere never lands.
    let cut = d.join("never_lands");
    std::fs::create_dir(&cut).unwrap();
    std::fs::copy(good.join("R4.5mm_H12cm_01.xml"), cut.join("c.xml")).unwrap();
    for p in frames
        .iter()
        .filter(|p| p.to_string_lossy().contains("_-0000"))
    {
        std::fs::copy(p, cut.join(p.file_name().unwrap())).unwrap();
    }
    std::fs::write(d.join("corrupt.cine"), b"CI\x2c\x00garbage that is no cine").unwrap();
    std::fs::create_dir(d.join("empty")).unwrap();
    std::fs::write(
        d.join("runs.csv"),
        format!(
            "run,path,sphere_radius_mm\n\
             good_r3,{},3\ntruncated_tiff,truncated_tiff,4.5\nno_xml,no_xml,4.5\n\
             corrupt_cine,corrupt.cine,4.5\nnever_lands,never_lands,4.5\nempty,empty,4.5\n\
             good_r7,{},7\n",
            fixture("R3mm_H1.5cm_01").display(),
            fixture("R7mm_H50cm_01").display()
        ),
    )
    .unwrap();
    let cfg = write_config(d, "");
    let o = run(&cfg, &[]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let rows = read_csv(&d.join("out/drops.csv")).unwrap();
    assert_eq!(rows.len(), 7);
    let by = |run: &str| rows.iter().find(|r| r.run == run).unwrap();
    for run in ["good_r3", "good_r7"] {
        assert_eq!(by(run).status, DropStatus::Ok, "{run}: {}", by(run).reason);
        assert!(by(run).delta_max_mm.is_some());
    }
    for (run, says) in [
        ("truncated_tiff", "t_000010.tif"),
        ("corrupt_cine", "corrupt.cine"),
        ("empty", "empty"),
    ] {
        let r = by(run);
        assert_eq!(r.status, DropStatus::Failed, "{run}");
        assert!(
            r.reason.contains(says),
            "{run}: `{}` lacks `{says}`",
            r.reason
        );
        assert!(r.delta_max_mm.is_none());
        // Each reason is printed as the run fails, not only in drops.csv.
        assert!(stderr(&o).contains(&r.reason), "{run}");
    }
    // Cut before the contact: tracked, with its free flight, no impact.
    let r = by("never_lands");
    assert_eq!(r.status, DropStatus::Tracked, "{}", r.reason);
    assert!(
        r.reason.contains("never reaches the surface"),
        "{}",
        r.reason
    );
    assert!(r.v_last_m_s.is_some() && r.delta_max_mm.is_none());
    assert!(stderr(&o).contains(&r.reason));
    // The frames without their XML: measured at the frame rate dropscope
    // assumes (the fixture's own, 10 000 frames/s), and said so.
    let r = by("no_xml");
    assert_eq!(r.status, DropStatus::Warning, "{}", r.reason);
    assert_eq!((r.fps, r.fps_source.as_str()), (Some(10_000.0), "default"));
    assert_eq!(r.flags, "fps_assumed");
    assert!(
        stderr(&o).contains("frame rate assumed") && stderr(&o).contains("no_xml"),
        "{}",
        stderr(&o)
    );
    assert!(d.join("out/plots/psi_vs_xi.svg").is_file(), "no collapse");
}

/// A second job reuses every run; touching one input reprocesses only that
/// run; another configuration or `--force` reprocesses all; the outputs of
/// a cached and a forced job are byte-identical to the first job's; a run
/// that fails later leaves none of its earlier files.
#[test]
fn unchanged_runs_come_from_the_cache_and_changes_are_seen() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A copy of one drop, so that it can be touched.
    let r3 = d.join("r3");
    std::fs::create_dir(&r3).unwrap();
    for e in std::fs::read_dir(fixture("R3mm_H1.5cm_01")).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, r3.join(p.file_name().unwrap())).unwrap();
    }
    std::fs::write(
        d.join("runs.csv"),
        format!(
            "run,path,sphere_radius_mm\nr3,r3,3\nr7,{},7\n",
            fixture("R7mm_H50cm_01").display()
        ),
    )
    .unwrap();
    let cfg = write_config(d, "");
    let reused = |o: &Output| -> String {
        let e = stderr(o);
        assert_eq!(o.status.code(), Some(0), "{e}");
        let tail = e.lines().last().unwrap_or_default();
        let k = tail.find(" reused").unwrap_or_else(|| panic!("{tail}"));
        tail[..k].rsplit(' ').next().unwrap().to_string()
    };
    assert_eq!(reused(&run(&cfg, &[])), "0");
    assert_eq!(reused(&run(&cfg, &[])), "2");
    let snapshot = d.join("snapshot");
    copy_tree(&d.join("out"), &snapshot);

    // One frame file's time changes: that run only.
    let f = std::fs::File::options()
        .write(true)
        .open(r3.join("R3mm_H1.5cm_01_000005.png"))
        .unwrap();
    f.set_modified(std::time::SystemTime::UNIX_EPOCH + Duration::from_secs(1_700_000_000))
        .unwrap();
    drop(f);
    assert_eq!(reused(&run(&cfg, &[])), "1");

    // Another configuration: nothing reused. --force: nothing reused, and
    // the outputs are those of the first job bar the touched input's time.
    write_config(d, "contact_margin_px = 2.5");
    assert_eq!(reused(&run(&cfg, &[])), "0");
    write_config(d, "");
    assert_eq!(reused(&run(&cfg, &["--force"])), "0");
    let (a, b) = (tree(&snapshot), tree(&d.join("out")));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (rel, bytes) in &a {
        // The touched input's fingerprint (and so its key) changed.
        let keyed = rel == "provenance.json" || rel.ends_with("r3.json");
        assert_eq!(bytes == &b[rel], !keyed, "{rel}");
    }

    // A run that now fails leaves none of its earlier files behind.
    let out = d.join("out");
    for rel in [
        "tracks/r7.csv",
        "plots/overlays/r7.png",
        "plots/drops/r7.svg",
    ] {
        assert!(out.join(rel).is_file(), "{rel}");
    }
    std::fs::write(
        d.join("runs.csv"),
        "run,path,sphere_radius_mm\nr3,r3,3\nr7,nowhere,7\n",
    )
    .unwrap();
    let o = run(&cfg, &[]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    for rel in [
        "tracks/r7.csv",
        "plots/overlays/r7.png",
        "plots/drops/r7.svg",
    ] {
        assert!(!out.join(rel).exists(), "{rel} survived");
    }
    assert!(out.join("plots/drops/r3.svg").is_file());
}

fn copy_tree(from: &Path, to: &Path) {
    for (rel, bytes) in tree(from) {
        let p = to.join(rel);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, bytes).unwrap();
    }
}

/// A job killed (SIGKILL) again and again at growing delays, and started
/// again each time, ends with exactly the files of an uninterrupted job,
/// which ran on two threads while the killed ones run on one.
#[test]
fn a_killed_job_resumes_to_the_outputs_of_an_uninterrupted_one() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fixture_manifest(d);
    let cfg = write_config(d, "");
    let o = run(&cfg, &["--threads", "2"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let reference = d.join("reference");
    std::fs::rename(d.join("out"), &reference).unwrap();

    let (mut kills, mut incomplete_kills) = (0, 0);
    let mut delay = Duration::from_millis(0);
    let started = Instant::now();
    loop {
        assert!(
            started.elapsed() < Duration::from_secs(300),
            "never finished"
        );
        let mut child = Command::new(env!("CARGO_BIN_EXE_dropscope"))
            .args(["run", "--threads", "1", "--config"])
            .arg(&cfg)
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(delay);
        if child.try_wait().unwrap().is_some() {
            break;
        }
        child.kill().unwrap();
        child.wait().unwrap();
        kills += 1;
        if !d.join("out/drops.csv").exists() {
            incomplete_kills += 1;
        }
        delay += Duration::from_millis(60);
    }
    let last = run(&cfg, &[]);
    assert_eq!(last.status.code(), Some(0), "{}", stderr(&last));
    assert!(
        incomplete_kills >= 2,
        "only {incomplete_kills} of {kills} kills landed before drops.csv"
    );
    assert_same_tree(&reference, &d.join("out"), "killed and resumed");
}
