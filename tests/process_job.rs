//! `dropscope process` as a user runs it: the result
//! cache and `--force`, `--threads`, one line per run with its own speed
//! off a terminal and bars on one, "with warnings" counted apart, and the
//! per-drop figures written without a collapse.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures")
}

fn process(out: &Path, extra: &[&str]) -> (Output, String) {
    let o = dropscope()
        .arg("process")
        .arg("--manifest")
        .arg(fixtures().join("runs.csv"))
        .arg("--out")
        .arg(out)
        .args(extra)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    (o, err)
}

fn dropscope() -> Command {
    Command::new(env!("CARGO_BIN_EXE_dropscope"))
}

/// Run `cmd`, which must exit 0 (else fail with its stderr).
fn succeeded(cmd: &mut Command) -> Output {
    let o = cmd.output().unwrap();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

/// The last line's "N reused from the cache".
fn reused(err: &str) -> usize {
    let line = err.lines().last().unwrap();
    let at = line.find(" reused from the cache").expect(line);
    line[..at].rsplit(' ').next().unwrap().parse().unwrap()
}

/// A second `process` into the same folder reuses every run and writes the
/// same drops.csv; `--force` measures them again, to the same bytes;
/// `--threads 1` runs on one thread. Off a terminal every run prints one
/// line with its own frames and speed, and no bar is drawn.
#[test]
fn process_reuses_its_runs_and_force_measures_them_again() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let (o, err) = process(&out, &[]);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert_eq!(reused(&err), 0, "{err}");
    assert!(
        !err.contains('\x1b') && !err.contains('\r'),
        "a bar off a terminal: {err:?}"
    );
    for run in ["R3mm_H1.5cm_01", "R4.5mm_H12cm_01", "R7mm_H50cm_01"] {
        // "[k/3] R…: measured (90 frames in 0.20 s, 443 frames/s)"
        let line = err
            .lines()
            .find(|l| l.contains(&format!("] {run}: measured (")))
            .unwrap_or_else(|| panic!("no line for {run}: {err}"));
        let frames: usize = line
            .split(" (")
            .nth(1)
            .unwrap()
            .split(' ')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        let track = std::fs::read_to_string(out.join(format!("tracks/{run}.csv"))).unwrap();
        assert_eq!(frames, track.lines().count() - 1, "{line}");
        assert!(line.ends_with(" frames/s)"), "{line}");
    }
    let first = std::fs::read(out.join("drops.csv")).unwrap();

    let (o, err) = process(&out, &["--threads", "1"]);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert_eq!(reused(&err), 3, "{err}");
    assert_eq!(err.matches(": measured (cached)").count(), 3, "{err}");
    assert!(err.contains("no frames read"), "{err}");
    assert_eq!(std::fs::read(out.join("drops.csv")).unwrap(), first);

    let (o, err) = process(&out, &["--force", "--threads", "1"]);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert_eq!(reused(&err), 0, "{err}");
    assert!(err.contains(" s on 1 thread ("), "{err}");
    assert_eq!(std::fs::read(out.join("drops.csv")).unwrap(), first);

    let (o, err) = process(&out, &["--threads", "0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(err.contains("--threads") && err.contains("1.."), "{err}");
}

/// On a terminal (a pseudo-terminal from util-linux's `script`) the runs
/// are shown as bars, not as one line each; the summary still ends the output.
#[test]
fn process_on_a_terminal_shows_bars_instead_of_lines() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let cmd = format!(
        "{} process --manifest {} --out {}",
        env!("CARGO_BIN_EXE_dropscope"),
        fixtures().join("runs.csv").display(),
        out.display()
    );
    let o = Command::new("script")
        .args(["-qec", &cmd, "/dev/null"])
        .output()
        .expect("util-linux's `script` (Debian: bsdutils) runs the command on a terminal");
    let shown = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{shown}");
    assert!(shown.contains("3 runs: 3 measured"), "{shown}");
    assert!(
        !shown.contains("[1/3]"),
        "plain lines on a terminal: {shown}"
    );
    assert_eq!(std::fs::read_dir(out.join("runs")).unwrap().count(), 3);
}

/// `process` alone draws each measured drop's figure (z(t), δ(t), F(δ)),
/// tagged with its drops.csv's id, so the report shows the diagnostics
/// without a collapse; a run with the wrong radius is counted "with
/// warnings", apart from "measured".
#[test]
fn process_draws_the_per_drop_figures_without_a_collapse() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    // Every run as a 4.5 mm sphere: the 3 mm drop's free fall is then off.
    let o = dropscope()
        .arg("process")
        .arg(fixtures())
        .args(["--radius-mm", "4.5", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("3 runs: 2 measured, 1 with warnings, 0 failed"),
        "{err}"
    );
    let id = dropscope::dataset::id::of_file(&out.join("drops.csv")).unwrap();
    for run in ["R3mm_H1.5cm_01", "R4.5mm_H12cm_01", "R7mm_H50cm_01"] {
        let svg = std::fs::read_to_string(out.join(format!("plots/drops/{run}.svg"))).unwrap();
        assert_eq!(dropscope::dataset::id::of_svg(&svg), Some(id.as_str()));
        assert!(svg.contains("penetration"), "{run}");
        let png = image::open(out.join(format!("plots/drops/{run}.png")))
            .unwrap()
            .to_rgb8();
        assert!(png.width() > 1000, "{run}");
        // Nothing runs off the figure's right edge, where a long F(δ)
        // legend would be clipped ("K = 4.04 N" of "K = 4.04 N/mm^n").
        let (w, h) = png.dimensions();
        let inked = (w - 6..w)
            .flat_map(|x| (0..h).map(move |y| (x, y)))
            .filter(|&(x, y)| png.get_pixel(x, y).0.iter().any(|&c| c < 200))
            .count();
        assert_eq!(inked, 0, "{run}: {inked} dark pixels at the right edge");
    }
    assert!(!out.join("fits.json").exists(), "process ran a collapse");
    succeeded(dropscope().arg("report").arg(&out));
    let page = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert_eq!(page.matches("class=\"diagram\"").count(), 3);
}

/// The overlay at δmax carries its caption band with a scale bar of the
/// drop's own scale, and the animated impact covers the whole contact.
#[test]
fn overlays_have_a_scale_bar_and_the_impact_is_animated() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    succeeded(
        dropscope()
            .arg("process")
            .arg(fixtures().join("R4.5mm_H12cm_01"))
            .args(["--radius-mm", "4.5", "--out"])
            .arg(&out),
    );
    let rec = &dropscope::dataset::read_csv(&out.join("drops.csv")).unwrap()[0];
    let img = image::open(out.join("plots/overlays/R4.5mm_H12cm_01.png"))
        .unwrap()
        .to_rgb8();
    let (w, h) = img.dimensions();
    // The bar: the longest run of white in the band's rows.
    let longest_white = |y: u32| {
        let (mut best, mut run) = (0, 0);
        for x in 0..w {
            run = if img.get_pixel(x, y).0 == dropscope::plot::BAR_RGB {
                run + 1
            } else {
                0
            };
            best = best.max(run);
        }
        best
    };
    let bar_px = (h - 60..h).map(longest_white).max().unwrap();
    let (mm, px) =
        dropscope::plot::scale_bar(rec.mm_per_px.unwrap(), 3, 0.4 * f64::from(w)).unwrap();
    assert_eq!(f64::from(bar_px), px.round(), "bar of {mm} mm");
    assert!(px > 0.15 * f64::from(w), "a bar of {px} px in {w}");
    assert_eq!(img.get_pixel(0, h - 1).0, dropscope::plot::BAND_RGB);

    let apng = std::fs::read(out.join("plots/impacts/R4.5mm_H12cm_01.png")).unwrap();
    let reader = png::Decoder::new(std::io::Cursor::new(apng))
        .read_info()
        .unwrap();
    let frames = reader.info().animation_control().unwrap().num_frames;
    let contact_frames = rec.tau_c_ms.unwrap() * 1e-3 * 10_000.0;
    assert!(
        f64::from(frames) > contact_frames + 4.0 && frames <= 100,
        "{frames} frames for a contact of {contact_frames} frames"
    );
}

/// `render` of one drop writes its runs.csv too, and drops.csv keeps the
/// manifest's drop height and the run's input path.
#[test]
fn one_rendered_drop_has_a_manifest_and_drops_csv_keeps_height_and_path() {
    let dir = tempfile::tempdir().unwrap();
    succeeded(
        dropscope()
            .args(["render", "--radius-mm", "4.5", "--height-cm", "12"])
            .args(["--frames-before", "20", "--frames-after", "20", "--out"])
            .arg(dir.path()),
    );
    let manifest = dir.path().join("runs.csv");
    let runs =
        dropscope::dataset::manifest::read_manifest(&manifest).expect("render wrote runs.csv");
    assert_eq!(runs.len(), 1);
    assert_eq!(runs[0].drop_height_cm, Some(12.0));
    assert!(runs[0].path.is_dir(), "{}", runs[0].path.display());
    let out = dir.path().join("out");
    succeeded(
        dropscope()
            .args(["process", "--manifest"])
            .arg(&manifest)
            .arg("--out")
            .arg(&out),
    );
    let rec = &dropscope::dataset::read_csv(&out.join("drops.csv")).unwrap()[0];
    assert_eq!(rec.drop_height_cm, Some(12.0));
    assert_eq!(rec.path, runs[0].path.display().to_string());
    let text = std::fs::read_to_string(out.join("drops.csv")).unwrap();
    let header = text.lines().next().unwrap();
    assert!(
        header
            .starts_with("run,sphere_radius_mm,sphere_density_kg_m3,surface,drop_height_cm,path,"),
        "{header}"
    );
}

/// A manifest of some fixture runs, with absolute paths, at `path`.
fn manifest_of(path: &Path, runs: &[&str]) {
    let text = std::fs::read_to_string(fixtures().join("runs.csv")).unwrap();
    let mut lines = text.lines();
    let mut out = format!("{}\n", lines.next().unwrap());
    for line in lines.filter(|l| runs.iter().any(|r| l.starts_with(&format!("{r},")))) {
        let (run, rest) = line.split_once(',').unwrap();
        let (_, rest) = rest.split_once(',').unwrap();
        let dir = fixtures().join(run);
        out += &format!("{run},{},{rest}\n", dir.display());
    }
    std::fs::write(path, out).unwrap();
}

/// A second job into a folder with fewer runs (and no `--overlay-frames`)
/// removes what the first wrote and it did not — the tracks, overlays,
/// animations and cache entries of the runs it no longer has, the extra
/// overlays of the one it kept, their per-drop figures, and the collapse
/// and report computed from the first job's drops.csv (the report refused
/// the folder) — and nothing else: the user's own files, also in
/// `plots/drops/` (the folder was removed whole), and a track the user
/// edited, stay.
#[test]
fn a_rerun_with_fewer_runs_leaves_no_file_of_the_earlier_job() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let (all, one) = (dir.path().join("all.csv"), dir.path().join("one.csv"));
    let runs = ["R3mm_H1.5cm_01", "R4.5mm_H12cm_01", "R7mm_H50cm_01"];
    manifest_of(&all, &runs);
    manifest_of(&one, &runs[..1]);
    let job = |manifest: &Path, extra: &[&str]| {
        let o = dropscope()
            .args(["process", "--manifest"])
            .arg(manifest)
            .arg("--out")
            .arg(&out)
            .args(extra)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert_eq!(o.status.code(), Some(0), "{err}");
        err
    };
    job(&all, &["--overlay-frames", "0"]);
    let files = |run: &str| {
        [
            format!("tracks/{run}.csv"),
            format!("plots/overlays/{run}.png"),
            format!("plots/overlays/{run}_0.png"),
            format!("plots/impacts/{run}.png"),
            format!("runs/{run}.json"),
        ]
    };
    for run in runs {
        for f in files(run) {
            assert!(out.join(&f).is_file(), "the first job wrote no {f}");
        }
    }
    succeeded(dropscope().arg("collapse").arg(out.join("drops.csv")));
    succeeded(dropscope().arg("report").arg(&out));
    let collapse_files = [
        "collapse.csv",
        "fits.json",
        "report.html",
        "plots/tau_vs_v.svg",
        "plots/tau_vs_v.png",
        "plots/psi_vs_xi.svg",
    ];
    for f in collapse_files {
        assert!(out.join(f).is_file(), "the collapse wrote no {f}");
    }
    let figures = |run: &str| [".svg", ".png"].map(|x| format!("plots/drops/{run}{x}"));
    let kept_figure = std::fs::read(out.join(&figures(runs[0])[1])).unwrap();
    std::fs::write(out.join("plots/overlays/my_sketch.png"), b"mine").unwrap();
    std::fs::write(out.join("plots/drops/my_notes.txt"), b"mine").unwrap();
    std::fs::write(out.join("notes.txt"), b"mine").unwrap();
    let edited = out.join(format!("tracks/{}.csv", runs[2]));
    let mut edited_bytes = std::fs::read(&edited).unwrap();
    edited_bytes.extend_from_slice(b"# checked by hand\n");
    std::fs::write(&edited, &edited_bytes).unwrap();

    let err = job(&one, &[]);
    // R4.5: track, overlays, animation; R7: the same but its edited track;
    // R3: its extra overlay.
    assert!(err.contains("removed 8 files"), "{err}");
    let [track, overlay, extra, impact, entry] = files(runs[0]);
    for f in [&track, &overlay, &impact, &entry] {
        assert!(out.join(f).is_file(), "the kept run's {f} was removed");
    }
    assert!(!out.join(&extra).exists(), "{extra} was not written again");
    for run in &runs[1..] {
        for f in files(run) {
            let kept = f == format!("tracks/{}.csv", runs[2]);
            assert_eq!(out.join(&f).exists(), kept, "{f}");
        }
    }
    assert_eq!(std::fs::read(&edited).unwrap(), edited_bytes);
    for f in [
        "plots/overlays/my_sketch.png",
        "plots/drops/my_notes.txt",
        "notes.txt",
    ] {
        assert_eq!(std::fs::read(out.join(f)).unwrap(), b"mine", "{f}");
    }
    let drops = dropscope::dataset::read_csv(&out.join("drops.csv")).unwrap();
    assert_eq!(drops.len(), 1);
    // The per-drop figures: the kept run's (its PNG the same bytes, its
    // SVG tagged with the new dataset); the others gone.
    assert!(out.join(&figures(runs[0])[0]).is_file());
    assert!(std::fs::read(out.join(&figures(runs[0])[1])).unwrap() == kept_figure);
    for run in &runs[1..] {
        for f in figures(run) {
            assert!(!out.join(&f).exists(), "{f}");
        }
    }
    // The first job's collapse and report are gone, said so, and the
    // folder's report can be written again.
    assert!(err.contains("computed from another drops.csv"), "{err}");
    for f in collapse_files {
        assert!(!out.join(f).exists(), "{f} of the earlier job remains");
    }
    succeeded(dropscope().arg("report").arg(&out));
}

/// A track whose frames have no flag must not write an empty `flags`
/// column, which pandas reads as float (text in the other files): every
/// frame's field is a word — `-` for none — and reads back as no flag.
#[test]
fn the_tracks_flags_column_is_text_in_every_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let manifest = dir.path().join("runs.csv");
    // R3's frames have no flag at all; R4.5's first ones are `partial`.
    let runs = ["R3mm_H1.5cm_01", "R4.5mm_H12cm_01"];
    manifest_of(&manifest, &runs);
    let o = dropscope()
        .args(["process", "--manifest"])
        .arg(&manifest)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0));
    let words = ["-", "partial", "recovered", "missing"];
    for (run, flagged) in runs.iter().zip([false, true]) {
        let path = out.join(format!("tracks/{run}.csv"));
        let mut rdr = csv::Reader::from_path(&path).unwrap();
        let col = rdr.headers().unwrap().iter().position(|h| h == "flags");
        let col = col.expect("a flags column");
        let fields: Vec<String> = rdr.records().map(|r| r.unwrap()[col].to_string()).collect();
        assert!(!fields.is_empty());
        for f in &fields {
            assert!(
                !f.is_empty() && f.split(' ').all(|w| words.contains(&w)),
                "{run}: flags {f:?}"
            );
        }
        let rows = dropscope::collapse::diagnostics::read_track(&path).unwrap();
        assert!(rows.iter().all(|r| r.flags != "-"), "{run}");
        let any = rows.iter().any(|r| !r.flags.is_empty());
        assert_eq!(any, flagged, "{run}: {fields:?}");
        assert!(
            fields.iter().any(|f| f == "-"),
            "{run}: no frame without flags"
        );
    }
}

/// The animated impact can be turned off, by `--no-animation` (process
/// and the main job) or by `output.animation = false`: no
/// `plots/impacts/<run>.png` (an earlier job's is removed), the still
/// overlay unchanged, and no "▶ impact" link in the report.
#[test]
fn the_animation_can_be_turned_off() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let manifest = dir.path().join("runs.csv");
    let run = "R4.5mm_H12cm_01";
    manifest_of(&manifest, &[run]);
    let impact = format!("plots/impacts/{run}.png");
    let overlay = format!("plots/overlays/{run}.png");
    let dropscope = |args: &[&str]| {
        let o = dropscope().args(args).output().unwrap();
        let text = String::from_utf8_lossy(&o.stdout).into_owned();
        assert_eq!(
            o.status.code(),
            Some(0),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        text
    };
    let (m, o) = (manifest.to_str().unwrap(), out.to_str().unwrap());
    dropscope(&["process", "--manifest", m, "--out", o]);
    assert!(out.join(&impact).is_file());
    dropscope(&["process", "--manifest", m, "--out", o, "--no-animation"]);
    assert!(!out.join(&impact).exists(), "--no-animation drew {impact}");
    assert!(out.join(&overlay).is_file());

    let config = dir.path().join("pipeline.toml");
    let out2 = dir.path().join("out2");
    let text = dropscope::config::EMBEDDED_DEFAULT
        .replace("fixtures/runs.csv", &m.replace('\\', "/"))
        .replace("animation = true", "animation = false");
    std::fs::write(&config, text).unwrap();
    let c = config.to_str().unwrap();
    let printed = dropscope(&["check-config", "--config", c]);
    assert!(printed.contains("animation = false"), "{printed}");
    dropscope(&["run", "--config", c, "--out", out2.to_str().unwrap()]);
    assert!(
        !out2.join(&impact).exists(),
        "animation = false drew {impact}"
    );
    assert!(out2.join(&overlay).is_file());
    let page = std::fs::read_to_string(out2.join("report.html")).unwrap();
    assert!(
        !page.contains("plots/impacts/"),
        "the report links an animation"
    );
    let page = {
        dropscope(&["report", o]);
        std::fs::read_to_string(out.join("report.html")).unwrap()
    };
    assert!(
        !page.contains("plots/impacts/"),
        "the report links an animation"
    );
}

/// Every file under `dir` (recursively), by its path relative to `dir`,
/// with its bytes; a folder as `None`.
fn snapshot(dir: &Path) -> std::collections::BTreeMap<PathBuf, Option<Vec<u8>>> {
    let mut all = std::collections::BTreeMap::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let rel = p.strip_prefix(dir).unwrap().to_path_buf();
            if p.is_dir() {
                all.insert(rel, None);
                todo.push(p);
            } else {
                all.insert(rel, Some(std::fs::read(&p).unwrap()));
            }
        }
    }
    all
}

/// A typo such as `process d1/R4.5mm_H12cm_01_typo --out wipe` into a
/// folder holding a finished process and collapse must not remove those
/// results for a drops.csv of one failed row. An INPUT that does not
/// exist, or cannot be a run, is refused before the output folder is
/// touched: exit 2, the path named, every file of the folder as it was —
/// also beside a good INPUT, and into a folder not yet there (not made).
#[test]
fn a_mistyped_input_stops_before_the_output_folder_is_touched() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("wipe");
    let (o, err) = process(&out, &[]);
    assert_eq!(o.status.code(), Some(0), "{err}");
    succeeded(dropscope().arg("collapse").arg(out.join("drops.csv")));
    let before = snapshot(&out);
    for f in ["drops.csv", "collapse.csv", "fits.json", "provenance.json"] {
        assert!(before.contains_key(Path::new(f)), "no {f} to keep");
    }
    std::fs::create_dir(dir.path().join("d1")).unwrap();
    let typo = dir.path().join("d1/R4.5mm_H12cm_01_typo");
    let notes = dir.path().join("runs.txt");
    std::fs::write(&notes, b"not a run").unwrap();
    let good = fixtures().join("R4.5mm_H12cm_01");
    for (inputs, named, says) in [
        (vec![&typo], &typo, "does not exist"),
        (vec![&good, &typo], &typo, "does not exist"),
        (vec![&notes], &notes, "not a folder of frames"),
    ] {
        let o = dropscope()
            .arg("process")
            .args(&inputs)
            .args(["--radius-mm", "4.5", "--out"])
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{inputs:?}: {err}");
        assert!(
            err.starts_with(&format!("error: {}: {says}", named.display())),
            "{inputs:?}: {err}"
        );
        assert_eq!(err.lines().count(), 1, "{inputs:?}: {err}");
        assert!(
            snapshot(&out) == before,
            "{inputs:?} changed {}",
            out.display()
        );
    }
    let fresh = dir.path().join("fresh");
    let o = dropscope()
        .arg("process")
        .arg(&typo)
        .args(["--radius-mm", "4.5", "--out"])
        .arg(&fresh)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(!fresh.exists(), "the refused job made {}", fresh.display());
}

/// A manifest none of whose inputs is there (its drive not mounted, or it
/// was moved without its runs) stops `process` and the main job with exit
/// 2 before the output folder is touched: a job that measured nothing
/// would replace the earlier results with rows of failures and remove
/// their collapse. One input missing among others is still that run's failed row.
#[test]
fn a_manifest_whose_inputs_are_all_missing_touches_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("kept");
    let (o, err) = process(&out, &[]);
    assert_eq!(o.status.code(), Some(0), "{err}");
    succeeded(dropscope().arg("collapse").arg(out.join("drops.csv")));
    let before = snapshot(&out);
    // The fixtures' manifest copied alone: its relative paths reach nothing.
    let moved = dir.path().join("moved.csv");
    std::fs::copy(fixtures().join("runs.csv"), &moved).unwrap();
    let o = dropscope()
        .args(["process", "--manifest"])
        .arg(&moved)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.starts_with(&format!(
            "error: {}: none of its 3 runs' inputs is there (the first, {}, does not exist)",
            moved.display(),
            dir.path().join("R3mm_H1.5cm_01").display()
        )),
        "{err}"
    );
    assert!(snapshot(&out) == before, "changed {}", out.display());
    // The main job on a configuration naming it: the same.
    let cfg = dir.path().join("moved.toml");
    std::fs::write(
        &cfg,
        "[input]\nmanifest = \"moved.csv\"\n[output]\ndir = \"kept\"\n",
    )
    .unwrap();
    let o = dropscope().arg("--config").arg(&cfg).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("none of its 3 runs' inputs is there"), "{err}");
    assert!(
        snapshot(&out) == before,
        "the main job changed {}",
        out.display()
    );
    // One input there of three: the two others are failed rows, exit 1.
    let text = std::fs::read_to_string(&moved).unwrap();
    let good = fixtures().join("R7mm_H50cm_01");
    std::fs::write(
        &moved,
        text.replacen(
            "R7mm_H50cm_01,R7mm_H50cm_01,",
            &format!("R7mm_H50cm_01,{},", good.display()),
            1,
        ),
    )
    .unwrap();
    let some = dir.path().join("some");
    let o = dropscope()
        .args(["process", "--no-animation", "--manifest"])
        .arg(&moved)
        .arg("--out")
        .arg(&some)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    let drops = dropscope::dataset::read_csv(&some.join("drops.csv")).unwrap();
    assert_eq!(drops.len(), 3);
}

/// A run is named after its folder, dots and all, or its `.cine` file less
/// `.cine`: a cine saved without that extension (found by its magic) is
/// not cut at its first dot (`R4.5mm_H12cm_02`, not `R4`), and a path that
/// is not there (`R4.5mm_H12cm_01_typo`) is refused.
#[test]
fn runs_are_named_after_their_whole_folder_name() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let dotted = dir.path().join("R4.5mm_H12cm_01.take2");
    std::fs::create_dir(&dotted).unwrap();
    for e in std::fs::read_dir(fixtures().join("R4.5mm_H12cm_01")).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, dotted.join(p.file_name().unwrap())).unwrap();
    }
    // Not a real cine: its row fails, under its whole name.
    let bare = dir.path().join("R4.5mm_H12cm_02");
    std::fs::write(&bare, b"CI and nothing more").unwrap();
    let o = dropscope()
        .arg("process")
        .args([&dotted, &bare])
        .args(["--radius-mm", "4.5", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    let drops = dropscope::dataset::read_csv(&out.join("drops.csv")).unwrap();
    let runs: Vec<(&str, _)> = drops.iter().map(|r| (r.run.as_str(), r.status)).collect();
    use dropscope::dataset::DropStatus;
    assert_eq!(
        runs,
        [
            ("R4.5mm_H12cm_01.take2", DropStatus::Ok),
            ("R4.5mm_H12cm_02", DropStatus::Failed)
        ],
        "{err}"
    );
    assert!(out.join("tracks/R4.5mm_H12cm_01.take2.csv").is_file());
}
