//! Untrusted input, beyond tests/hostile.rs: what a planted link, a file
//! name, a cell, a cache entry, a side file or a shared pipeline.toml
//! could make dropscope do. Each test is one class of fault, made as a
//! user (or an attacker) would make it, and run through the command line:
//! nothing may escape the output folder, run as a command, reach a
//! terminal or a spreadsheet as active content, or stand as a number
//! marked ok that a file lied about; no panic and no hang.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use dropscope::dataset::{read_csv, DropStatus};

const DROP: &str = "R4.5mm_H12cm_01";

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn dropscope() -> Command {
    Command::new(env!("CARGO_BIN_EXE_dropscope"))
}

/// A copy of the fixture drop in `dir/name`, its XML through `edit`.
fn copy_drop(dir: &Path, name: &str, edit: impl Fn(String) -> String) -> PathBuf {
    let from = root().join("fixtures").join(DROP);
    let to = dir.join(name);
    std::fs::create_dir_all(&to).unwrap();
    for e in std::fs::read_dir(&from).unwrap() {
        let p = e.unwrap().path();
        let file = p.file_name().unwrap().to_str().unwrap().to_string();
        if file.ends_with(".xml") {
            let text = std::fs::read_to_string(&p).unwrap();
            std::fs::write(to.join(&file), edit(text)).unwrap();
        } else if file.ends_with(".png") {
            std::fs::copy(&p, to.join(&file)).unwrap();
        }
    }
    to
}

/// `dropscope process INPUTS --radius-mm 4.5 --no-animation --out OUT ARGS`.
fn process(inputs: &[&Path], out: &Path, args: &[&str]) -> Output {
    dropscope()
        .arg("process")
        .args(inputs)
        .args(["--radius-mm", "4.5", "--no-animation", "--out"])
        .arg(out)
        .args(args)
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `cmd` run to its end, or killed after `limit`: `None` when it was.
fn within(mut cmd: Command, limit: Duration) -> Option<Output> {
    let mut child = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            return Some(child.wait_with_output().unwrap());
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Every file under `dir` with its bytes, by path relative to it.
fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                todo.push(p);
            } else {
                let rel = p.strip_prefix(dir).unwrap().display().to_string();
                out.push((rel, std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

/// A folder of someone's pictures, and the files in it.
fn photos(dir: &Path) -> (PathBuf, Vec<(String, Vec<u8>)>) {
    let photos = dir.join("photos");
    std::fs::create_dir_all(&photos).unwrap();
    std::fs::write(photos.join("holiday.png"), b"\x89PNG not really").unwrap();
    std::fs::write(photos.join("drawing.svg"), b"<svg></svg>").unwrap();
    let before = files(&photos);
    (photos, before)
}

/// Class: a link planted inside the output folder (`OUT/plots/drops`, or
/// `OUT/plots`) is never followed: nothing is deleted or written where it
/// points, and the job stops naming the link.
#[cfg(unix)]
#[test]
fn a_planted_link_in_the_output_folder_is_never_followed() {
    let dir = tempfile::tempdir().unwrap();
    let run = copy_drop(dir.path(), DROP, |x| x);
    for planted in ["plots/drops", "plots"] {
        let out = dir
            .path()
            .join(format!("out-{}", planted.replace('/', "-")));
        let (photos, before) = photos(&dir.path().join(format!("p-{}", planted.replace('/', "-"))));
        let link = out.join(planted);
        std::fs::create_dir_all(link.parent().unwrap()).unwrap();
        std::os::unix::fs::symlink(&photos, &link).unwrap();
        let o = process(&[&run], &out, &[]);
        let e = stderr(&o);
        assert_eq!(
            files(&photos),
            before,
            "{planted}: files changed where the link points: {e}"
        );
        assert_eq!(o.status.code(), Some(2), "{planted}: {e}");
        assert!(
            e.contains(&format!("{} is a symbolic link", link.display())),
            "{planted}: {e}"
        );
    }
}

/// Class: only files an earlier job of dropscope listed as its own are
/// removed. A figure of yours in `OUT/plots/drops/` (and one of
/// dropscope's that you edited) survives `process`, `collapse` and a
/// second `process` with other runs; dropscope's own figure of a run no
/// longer in the job goes.
#[test]
fn your_own_figures_in_the_output_folder_stay() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let a = copy_drop(dir.path(), "a", |x| x);
    let b = copy_drop(dir.path(), "b", |x| x);
    let o = process(&[&a, &b], &out, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let drops = out.join("plots/drops");
    assert!(drops.join("a.svg").is_file() && drops.join("b.png").is_file());
    std::fs::write(drops.join("mine.svg"), b"<svg>mine</svg>").unwrap();
    std::fs::write(drops.join("mine.png"), b"my png").unwrap();
    let o = dropscope()
        .arg("collapse")
        .arg(out.join("drops.csv"))
        .output()
        .unwrap();
    assert!(o.status.code().is_some_and(|c| c < 2), "{}", stderr(&o));
    std::fs::write(drops.join("b.svg"), b"<svg>b, edited by hand</svg>").unwrap();
    // Run b leaves the job: its (unchanged) PNG is dropscope's and goes.
    let o = process(&[&a], &out, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(drops.join("mine.svg")).unwrap(),
        b"<svg>mine</svg>"
    );
    assert_eq!(std::fs::read(drops.join("mine.png")).unwrap(), b"my png");
    assert_eq!(
        std::fs::read(drops.join("b.svg")).unwrap(),
        b"<svg>b, edited by hand</svg>"
    );
    assert!(
        !drops.join("b.png").exists(),
        "dropscope's figure of a run gone stayed"
    );
    assert!(drops.join("a.svg").is_file());
}

/// `process DIR --out DIR` twice: the second job does not take its own
/// `plots/` (overlays are PNG frames) for runs.
#[test]
fn processing_a_folder_into_itself_twice_measures_the_same_runs() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    copy_drop(&data, DROP, |x| x);
    for _ in 0..2 {
        let o = process(&[&data], &data, &[]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let rows = read_csv(&data.join("drops.csv")).unwrap();
        let runs: Vec<&str> = rows.iter().map(|r| r.run.as_str()).collect();
        assert_eq!(runs, [DROP], "{}", stderr(&o));
    }
}

/// Class: active content. An SVG dropped into `plots/` carrying the
/// dataset's id and a script, even under a collapse figure's name, is never
/// inlined into report.html (only the figures dropscope wrote are); an SVG
/// of yours without an id does not make `report` refuse the folder.
#[test]
fn a_foreign_svg_never_brings_its_script_into_the_report() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let run = copy_drop(dir.path(), DROP, |x| x);
    let o = process(&[&run], &out, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o = dropscope()
        .arg("collapse")
        .arg(out.join("drops.csv"))
        .output()
        .unwrap();
    assert!(o.status.code().is_some_and(|c| c < 2), "{}", stderr(&o));
    let id = dropscope::dataset::id::of_file(&out.join("drops.csv")).unwrap();
    let evil = |n: u32| {
        dropscope::dataset::id::tag_svg(
            format!("<svg xmlns=\"http://www.w3.org/2000/svg\"><script>alert({n})</script></svg>")
                .into_bytes(),
            &id,
        )
    };
    std::fs::write(out.join("plots/evil.svg"), evil(1)).unwrap();
    std::fs::write(out.join("plots/psi_vs_xi.svg"), evil(2)).unwrap();
    std::fs::write(out.join("plots/drops").join(format!("{DROP}.svg")), evil(3)).unwrap();
    std::fs::write(out.join("plots/mine.svg"), b"<svg><rect/></svg>").unwrap();
    let o = dropscope().arg("report").arg(&out).output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(!html.contains("alert("), "a planted script is in the page");
    // The collapse figures dropscope wrote are there, inline.
    assert!(
        html.contains("id=\"plot-omega_vs_xi\"><svg"),
        "no figure inlined"
    );
}

/// A configuration and manifest for `slurm` and `check-config` in `dir`,
/// with `output` as its `[output] dir` (a TOML string's inside).
fn slurm_config(dir: &Path, output: &str) -> PathBuf {
    let fixtures = root().join("fixtures");
    std::fs::write(
        dir.join("runs.csv"),
        format!(
            "run,path,sphere_radius_mm\n{DROP},{},4.5\n",
            fixtures.join(DROP).display()
        ),
    )
    .unwrap();
    let cfg = dir.join("pipeline.toml");
    std::fs::write(
        &cfg,
        format!("[input]\nmanifest = \"runs.csv\"\n[output]\ndir = \"{output}\"\n"),
    )
    .unwrap();
    cfg
}

/// Class: shell injection through the Slurm scripts. A newline in
/// `--partition`, `--time`, `--mem` or in a shared pipeline.toml's
/// `[output] dir` would end the `#SBATCH` comment and run the rest: each
/// is refused naming the field, no script is written, and check-config
/// refuses the control character in the path.
#[test]
fn nothing_from_a_flag_or_a_shared_configuration_runs_in_the_slurm_scripts() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cfg = slurm_config(d, "res\\ntouch INJECTED; echo ");
    let o = dropscope()
        .current_dir(d)
        .args(["check-config", "--config"])
        .arg(&cfg)
        .output()
        .unwrap();
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "check-config accepted it: {e}");
    assert!(e.contains("output.dir") && e.contains("control"), "{e}");
    slurm_config(d, "res");
    for (flag, value) in [
        ("--partition", "debug\ntouch INJECTED"),
        ("--time", "1:00:00\ntouch INJECTED"),
        ("--mem", "4G $(touch INJECTED)"),
    ] {
        let o = dropscope()
            .current_dir(d)
            .args(["slurm", "--array", "2", flag, value])
            .output()
            .unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{flag}: {e}");
        assert!(
            e.contains(flag) && e.contains("may hold only"),
            "{flag}: {e}"
        );
        assert!(!d.join("res.slurm").exists(), "{flag}: scripts written");
    }
    // Accepted values give scripts whose every line is a comment or the
    // one command, and a hint that pastes as it reads.
    let o = dropscope()
        .current_dir(d)
        .args([
            "slurm",
            "--array",
            "2",
            "--partition",
            "debug",
            "--time",
            "1:00:00",
        ])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let hint = String::from_utf8_lossy(&o.stdout).into_owned();
    let scripts = d.canonicalize().unwrap().join("res.slurm");
    assert!(
        hint.contains(&format!(
            "sbatch --parsable '{}'",
            scripts.join("shards.sbatch").display()
        )),
        "{hint}"
    );
    let script = std::fs::read_to_string(scripts.join("shards.sbatch")).unwrap();
    let commands: Vec<&str> = script.lines().filter(|l| !l.starts_with('#')).collect();
    assert_eq!(commands.len(), 1, "{script}");
    assert!(!d.join("INJECTED").exists());
}

/// Class: spreadsheet formulas. A run named from its folder
/// (`=cmd|' -c calc'!A1`), a manifest's `setup` (`=HYPERLINK(…)`) and a
/// run `@SUM(…)` reach drops.csv and collapse.csv as text cells a
/// spreadsheet does not run (a `'` before them), and read back as they were.
#[test]
fn no_cell_of_drops_csv_or_collapse_csv_is_a_formula() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let named = "=cmd|' -c calc'!A1";
    copy_drop(d, named, |x| x);
    copy_drop(d, "plain", |x| x);
    std::fs::write(
        d.join("runs.csv"),
        format!(
            "run,path,sphere_radius_mm,setup\n\"{named}\",\"{named}\",4.5,\n@SUM(1+1),plain,4.5,\"=HYPERLINK(\"\"http://x\"\")\"\n"
        ),
    )
    .unwrap();
    let out = d.join("out");
    let o = dropscope()
        .args(["process", "--no-animation", "--manifest"])
        .arg(d.join("runs.csv"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.code().is_some_and(|c| c < 2), "{}", stderr(&o));
    let o = dropscope()
        .arg("collapse")
        .arg(out.join("drops.csv"))
        .output()
        .unwrap();
    assert!(o.status.code().is_some_and(|c| c < 2), "{}", stderr(&o));
    for file in ["drops.csv", "collapse.csv"] {
        let text = std::fs::read_to_string(out.join(file)).unwrap();
        let mut r = csv::Reader::from_reader(text.as_bytes());
        for row in r.records() {
            for cell in row.unwrap().iter() {
                let first = cell.chars().next();
                let formula = first.is_some_and(|c| "=+@\t\r".contains(c))
                    || (first == Some('-') && cell != "-" && cell.parse::<f64>().is_err());
                assert!(!formula, "{file}: a formula cell {cell:?}");
            }
        }
    }
    let rows = read_csv(&out.join("drops.csv")).unwrap();
    assert_eq!(rows[0].run, named);
    assert_eq!(rows[1].run, "@SUM(1+1)");
    assert_eq!(rows[1].setup, "=HYPERLINK(\"http://x\")");
}

/// Class: terminal escapes. A file name holding escape sequences (set the
/// window title, clear the screen, write the clipboard) reaches stderr,
/// stdout and drops.csv's `reason` shown, not sent.
#[test]
fn escape_sequences_in_names_never_reach_the_terminal_or_a_cell() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let nasty = "run\u{1b}]0;pwned\u{7}\u{1b}[2J\u{1b}]52;c;ZWNobyBoaQ==\u{7}";
    let run = d.join(nasty);
    std::fs::create_dir(&run).unwrap();
    std::fs::write(run.join("notes.txt"), b"no frames").unwrap();
    let out = d.join("out");
    let o = process(&[&run], &out, &[]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        !o.stderr.contains(&0x1b) && !o.stderr.contains(&0x07),
        "{}",
        stderr(&o)
    );
    assert!(stderr(&o).contains("\\u{1b}]0;pwned"), "{}", stderr(&o));
    let csv = std::fs::read(out.join("drops.csv")).unwrap();
    assert!(!csv.contains(&0x1b) && !csv.contains(&0x07));
    // inspect prints what the input says, the name included.
    let good = copy_drop(d, &format!("{DROP}\u{1b}[31m"), |x| x);
    for json in [false, true] {
        let o = dropscope()
            .arg("inspect")
            .arg(&good)
            .args(json.then_some("--json"))
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        assert!(
            !o.stdout.contains(&0x1b),
            "{}",
            String::from_utf8_lossy(&o.stdout)
        );
        if json {
            let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
            assert!(v["path"].as_str().unwrap().ends_with("\u{1b}[31m"));
        }
    }
    // A cine whose camera text (SETUP.CameraModel, 256 bytes at 10128)
    // sets the window title and clears the screen.
    let mut cine = std::fs::read(crate::phantom_sample("pims/cine_781.cine")).unwrap();
    let setup = u32::from_le_bytes(cine[28..32].try_into().unwrap()) as usize;
    let camera = b"Phantom\x1b]0;pwned\x07\x1b[2J\x1b]52;c;ZWNobyBoaQ==\x07\0";
    cine[setup + 10128..setup + 10128 + camera.len()].copy_from_slice(camera);
    let path = d.join("camera.cine");
    std::fs::write(&path, cine).unwrap();
    for json in [false, true] {
        let o = dropscope()
            .arg("inspect")
            .arg(&path)
            .args(json.then_some("--json"))
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let shown = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(
            !o.stdout.contains(&0x1b) && !o.stdout.contains(&0x07),
            "{shown}"
        );
        if json {
            let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
            assert!(v["camera"].to_string().contains("pwned"), "{v}");
        } else {
            assert!(shown.contains("Phantom\\u{1b}]0;pwned"), "{shown}");
        }
    }
}

/// Class: look-alike run names. A zero-width space or a right-to-left
/// override in a manifest's run name is refused naming the row and the
/// character.
#[test]
fn run_names_with_invisible_characters_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    copy_drop(d, DROP, |x| x);
    for (name, code) in [("r\u{200b}un", "U+200B"), ("evil\u{202e}gnp.exe", "U+202E")] {
        std::fs::write(
            d.join("runs.csv"),
            format!("run,path,sphere_radius_mm\n{DROP},{DROP},4.5\n{name},{DROP},4.5\n"),
        )
        .unwrap();
        let o = dropscope()
            .args(["process", "--manifest"])
            .arg(d.join("runs.csv"))
            .arg("--out")
            .arg(d.join("out"))
            .output()
            .unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{name:?}: {e}");
        assert!(e.contains("row 3") && e.contains(code), "{e}");
    }
}

/// Class: a cache entry changed by hand (`v_impact_m_s` → 9.99 in
/// runs/<run>.json) is not reused: the run is measured again, with a note.
#[test]
fn a_cache_entry_edited_by_hand_is_not_believed() {
    let dir = tempfile::tempdir().unwrap();
    let run = copy_drop(dir.path(), DROP, |x| x);
    let out = dir.path().join("out");
    let o = process(&[&run], &out, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let measured = read_csv(&out.join("drops.csv")).unwrap()[0]
        .v_impact_m_s
        .unwrap();
    let entry = out.join("runs").join(format!("{DROP}.json"));
    let text = std::fs::read_to_string(&entry).unwrap();
    let field = format!("\"v_impact_m_s\": {measured}");
    assert!(text.contains(&field), "{text}");
    std::fs::write(&entry, text.replace(&field, "\"v_impact_m_s\": 9.99")).unwrap();
    let o = process(&[&run], &out, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let row = &read_csv(&out.join("drops.csv")).unwrap()[0];
    assert_eq!(row.v_impact_m_s, Some(measured));
    assert!(
        stderr(&o).contains("changed since dropscope wrote it"),
        "{}",
        stderr(&o)
    );
}

/// `dropscope inspect DIR --json` as JSON.
fn inspect(dir: &Path) -> Result<serde_json::Value, String> {
    let o = dropscope()
        .arg("inspect")
        .arg(dir)
        .arg("--json")
        .output()
        .unwrap();
    if o.status.success() {
        Ok(serde_json::from_slice(&o.stdout).unwrap())
    } else {
        Err(stderr(&o))
    }
}

/// `xml` with `from` replaced by `to`, which must be there.
fn edit(xml: &str, from: &str, to: &str) -> String {
    assert!(xml.contains(from), "{from} not in the side file");
    xml.replacen(from, to, 1)
}

/// Class: the PCC side file says what it says, or is refused. A comment
/// inside a value does not cut it; a value given twice differently is
/// refused; a TIMEBLOCK missing a frame, or listing one under a stray
/// number, is kept (the irregular time beside it still flagged) and said; files renumbered from 0 get the side
/// file's numbers and times; a side file of other frames is refused.
#[test]
fn a_side_file_is_read_whole_and_applied_only_to_its_frames() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let shutter = "<ShutterNs>50000</ShutterNs>";
    let split = copy_drop(d, "split", |x| {
        edit(&x, shutter, "<ShutterNs>50<!---->000</ShutterNs>")
    });
    let v = inspect(&split).unwrap();
    assert_eq!(v["exposure_s"].as_f64(), Some(50e-6), "{v}");
    let twice = copy_drop(d, "twice", |x| {
        edit(
            &x,
            shutter,
            "<ShutterNs>50000</ShutterNs><ShutterNs>50</ShutterNs>",
        )
    });
    let e = inspect(&twice).unwrap_err();
    assert!(e.contains("<ShutterNs> is given twice"), "{e}");

    // An irregular time (3 µs off, 3 % of an interval) beside a missing one.
    let out = d.join("out");
    let irregular = copy_drop(d, "irregular", |x| {
        let x = edit(
            &x,
            "<Time frame=\"-25\">10:00:59.997 500.00</Time>",
            "<Time frame=\"-25\">10:00:59.997 503.00</Time>",
        );
        let x = edit(
            &x,
            "<Date frame=\"-20\">Thu Jun 13 2019</Date><Time frame=\"-20\">10:00:59.998 000.00</Time>",
            "",
        );
        // A stray frame number: frame -15's time listed under 9999.
        edit(
            &x,
            "<Date frame=\"-15\">Thu Jun 13 2019</Date><Time frame=\"-15\">",
            "<Date frame=\"9999\">Thu Jun 13 2019</Date><Time frame=\"9999\">",
        )
    });
    let o = process(&[&irregular], &out, &[]);
    assert!(o.status.code().is_some_and(|c| c < 2), "{}", stderr(&o));
    let row = &read_csv(&out.join("drops.csv")).unwrap()[0];
    assert_eq!(row.status, DropStatus::Warning, "{}", row.reason);
    assert!(row.flags.contains("time_irregular"), "{}", row.flags);
    assert!(
        row.reason.contains("no time for 2 of the 87 frames"),
        "{}",
        row.reason
    );

    // The frames renumbered from 0, as `dropscope export` names them.
    let plain = copy_drop(d, "plain", |x| x);
    let renumbered = d.join("renumbered");
    std::fs::create_dir(&renumbered).unwrap();
    let mut pngs: Vec<(i64, PathBuf)> = std::fs::read_dir(&plain)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "png"))
        .map(|p| {
            let stem = p.file_stem().unwrap().to_str().unwrap().to_string();
            let n: i64 = stem.rsplit_once('_').unwrap().1.parse().unwrap();
            (n, p)
        })
        .collect();
    pngs.sort();
    for (i, (_, p)) in pngs.iter().enumerate() {
        std::fs::copy(p, renumbered.join(format!("renumbered_{i:03}.png"))).unwrap();
    }
    std::fs::copy(
        plain.join(format!("{DROP}.xml")),
        renumbered.join("renumbered.xml"),
    )
    .unwrap();
    let out2 = d.join("out2");
    let o = process(&[&plain, &renumbered], &out2, &[]);
    assert!(o.status.code().is_some_and(|c| c < 2), "{}", stderr(&o));
    let rows = read_csv(&out2.join("drops.csv")).unwrap();
    let (a, b) = (rows[0].t_contact_s.unwrap(), rows[1].t_contact_s.unwrap());
    assert!((a - b).abs() < 1e-9, "t_contact {a} s, renumbered {b} s");

    // A side file of other frames (another export's count) is not applied.
    let other = copy_drop(d, "other", |x| {
        edit(&x, "<ImageCount>87<", "<ImageCount>40<")
    });
    std::fs::remove_file(other.join(format!("{DROP}_-000030.png"))).unwrap();
    let e = inspect(&other).unwrap_err();
    assert!(
        e.contains("not their side file") && e.contains(".xml"),
        "{e}"
    );
}

/// Class: numbers out of any physical range. A frame rate of 1e300 in
/// pipeline.toml is refused by check-config naming the key; a density of
/// 1e308 or 1e-308 in a manifest naming the column; in a hand-made drops.csv given
/// to `collapse`, the row is skipped saying why, never used as Ψ = Ξ = 0.
#[test]
fn numbers_out_of_physical_range_are_refused_where_they_enter() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cfg = d.join("p.toml");
    std::fs::write(&cfg, "[camera]\nfps = 1e300\n").unwrap();
    let o = dropscope()
        .args(["check-config", "--config"])
        .arg(&cfg)
        .output()
        .unwrap();
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("camera.fps") && e.contains("1e7"), "{e}");
    copy_drop(d, DROP, |x| x);
    // 1e308 overflows the force constants; 1e-308 sent the log axes' tick
    // code into an unbounded loop.
    for density in ["1e308", "1e-308"] {
        std::fs::write(
            d.join("runs.csv"),
            format!(
                "run,path,sphere_radius_mm,sphere_density_kg_m3\n{DROP},{DROP},4.5,{density}\n"
            ),
        )
        .unwrap();
        let mut c = dropscope();
        c.args(["process", "--no-animation", "--manifest"])
            .arg(d.join("runs.csv"))
            .arg("--out")
            .arg(d.join("out"));
        let o = within(c, Duration::from_secs(120))
            .unwrap_or_else(|| panic!("density {density}: still running after 120 s"));
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{density}: {e}");
        assert!(
            e.contains("sphere_density_kg_m3") && e.contains("row 2") && e.contains("1e5 kg/m³"),
            "{e}"
        );
    }
    // A drops.csv edited by hand.
    let out = d.join("made");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(
        out.join("drops.csv"),
        "run,sphere_radius_mm,sphere_density_kg_m3,v_impact_m_s,v_rebound_m_s,restitution,\
         delta_max_mm,a_max_mm,a_geom_mm,tau_c_ms,t_contact_s,t_rebound_s,mm_per_px,\
         surface_row_px,status\n\
         a,4.5,7800,2.0,,,1.2,2.5,,5.0,,,,,ok\n\
         b,4.5,1e308,2.0,,,1.2,2.5,,5.0,,,,,ok\n\
         c,4.5,7800,1e-160,,,1.2,2.5,,5.0,,,,,ok\n",
    )
    .unwrap();
    let mut c = dropscope();
    c.arg("collapse").arg(out.join("drops.csv"));
    let o = within(c, Duration::from_secs(120)).expect("collapse still running after 120 s");
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let text = std::fs::read_to_string(out.join("collapse.csv")).unwrap();
    let mut r = csv::Reader::from_reader(text.as_bytes());
    let h = r.headers().unwrap().clone();
    let col = |n: &str| h.iter().position(|c| c == n).unwrap();
    let rows: Vec<csv::StringRecord> = r.records().map(|x| x.unwrap()).collect();
    assert_eq!(&rows[0][col("used")], "true");
    for row in &rows[1..] {
        assert_eq!(&row[col("used")], "false", "{row:?}");
        assert_eq!(&row[col("Psi")], "", "{row:?}");
    }
    assert!(
        rows[1][col("note")].contains("sphere_density_kg_m3 = 1e308"),
        "{:?}",
        rows[1]
    );
}

/// A grey PNG of `width` × `height` pixels whose rows are all zero,
/// compressed as far as deflate goes (~1 kB per MB of pixels).
fn flat_png(path: &Path, width: u32, height: u32) {
    let f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut enc = png::Encoder::new(f, width, height);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_compression(png::Compression::High);
    let mut w = enc.write_header().unwrap().into_stream_writer().unwrap();
    let row = vec![0u8; width as usize];
    for _ in 0..height {
        std::io::Write::write_all(&mut w, &row).unwrap();
    }
    w.finish().unwrap();
}

/// Class: a frame too large to decode within a worker's memory is
/// refused from its header, in every format (a 30 000² PNG of 0.9 MB took
/// 8.8 GB), naming the file and its size.
#[test]
fn a_frame_too_large_to_decode_is_refused_from_its_header() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("huge");
    std::fs::create_dir(&run).unwrap();
    flat_png(&run.join("huge_000001.png"), 30_000, 30_000);
    let e = inspect(&run).unwrap_err();
    assert!(
        e.contains("huge_000001.png") && e.contains("30000×30000") && e.contains("8192 × 4096"),
        "{e}"
    );
    // A deflate TIFF of 16 000² (3.75 GB a worker to decode) from a
    // 1 kB file: refused from its tags.
    let deflated = dir.path().join("deflated");
    std::fs::create_dir(&deflated).unwrap();
    let strip = fdeflate::compress_to_vec(&vec![0u8; 1 << 20]);
    for i in 0..3 {
        std::fs::write(
            deflated.join(format!("t_{i:03}.tif")),
            tiff(16_000, 16_000, 1, 8, strip.clone()),
        )
        .unwrap();
    }
    let e = inspect(&deflated).unwrap_err();
    assert!(
        e.contains("t_000.tif") && e.contains("16000×16000") && e.contains("8192 × 4096"),
        "{e}"
    );
    // In a job, the run fails and the next one is measured.
    copy_drop(dir.path(), DROP, |x| x);
    let manifest = dir.path().join("runs.csv");
    std::fs::write(
        &manifest,
        format!(
            "run,path,sphere_radius_mm,fps\nhuge,huge,4.5,10000\ndeflated,deflated,4.5,10000\n\
             {DROP},{DROP},4.5,10000\n"
        ),
    )
    .unwrap();
    let out = dir.path().join("out");
    let o = dropscope()
        .args(["process", "--no-animation", "--manifest"])
        .arg(&manifest)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let rows = read_csv(&out.join("drops.csv")).unwrap();
    let status: Vec<(&str, DropStatus)> = rows.iter().map(|r| (r.run.as_str(), r.status)).collect();
    assert_eq!(
        status,
        [
            ("huge", DropStatus::Failed),
            ("deflated", DropStatus::Failed),
            (DROP, DropStatus::Ok)
        ],
        "{}",
        stderr(&o)
    );
    assert!(rows[0].reason.contains("30000×30000"), "{}", rows[0].reason);
}

/// Class: a write to a closed or full standard output or error is no
/// panic (exit 101): the job finishes and writes its results.
#[test]
fn a_closed_or_full_terminal_does_not_stop_a_job() {
    let dir = tempfile::tempdir().unwrap();
    let a = copy_drop(dir.path(), "a", |x| x);
    let b = copy_drop(dir.path(), "b", |x| x);
    let full = || {
        std::fs::File::options()
            .write(true)
            .open("/dev/full")
            .unwrap()
    };
    // 2>/dev/full, and >/dev/full for inspect and check-config.
    let out = dir.path().join("out");
    let o = dropscope()
        .arg("process")
        .args([&a, &b])
        .args(["--radius-mm", "4.5", "--no-animation", "--out"])
        .arg(&out)
        .stderr(full())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0));
    assert_eq!(read_csv(&out.join("drops.csv")).unwrap().len(), 2);
    for args in [
        vec!["inspect", a.to_str().unwrap()],
        vec!["check-config", "--default"],
    ] {
        let o = dropscope().args(&args).stdout(full()).output().unwrap();
        assert_eq!(o.status.code(), Some(0), "{args:?}: {}", stderr(&o));
    }
    // `| head -c 20`: the pipe closes after the first line.
    let out = dir.path().join("out2");
    let mut child = dropscope()
        .arg("process")
        .args([&a, &b])
        .args([
            "--radius-mm",
            "4.5",
            "--no-animation",
            "--threads",
            "1",
            "--out",
        ])
        .arg(&out)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = [0u8; 20];
    child.stderr.take().unwrap().read_exact(&mut first).unwrap();
    // (the pipe's read end is dropped here)
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(0));
    assert_eq!(read_csv(&out.join("drops.csv")).unwrap().len(), 2);
}

/// Class: inputs that are not regular files. A named pipe given as
/// `--manifest`, `--config` or the drops.csv of `collapse`, and
/// `/dev/zero` as `--config`, are refused at once naming them, never read
/// (a pipe would block for ever, /dev/zero until memory runs out).
#[cfg(unix)]
#[test]
fn a_named_pipe_or_a_device_is_refused_for_every_input() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe.csv");
    let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o644) }, 0);
    let out = dir.path().join("out");
    let cases: Vec<(Vec<&std::ffi::OsStr>, &str)> = vec![
        (
            vec![
                "process".as_ref(),
                "--manifest".as_ref(),
                fifo.as_os_str(),
                "--out".as_ref(),
                out.as_os_str(),
            ],
            "named pipe",
        ),
        (
            vec![
                "check-config".as_ref(),
                "--config".as_ref(),
                fifo.as_os_str(),
            ],
            "named pipe",
        ),
        (
            vec![
                "collapse".as_ref(),
                fifo.as_os_str(),
                "--out".as_ref(),
                out.as_os_str(),
            ],
            "named pipe",
        ),
        (
            vec![
                "check-config".as_ref(),
                "--config".as_ref(),
                "/dev/zero".as_ref(),
            ],
            "device",
        ),
        (
            vec![
                "process".as_ref(),
                "--manifest".as_ref(),
                "/dev/zero".as_ref(),
                "--out".as_ref(),
                out.as_os_str(),
            ],
            "device",
        ),
    ];
    for (args, what) in cases {
        let mut cmd = dropscope();
        cmd.args(&args);
        let o = within(cmd, Duration::from_secs(20))
            .unwrap_or_else(|| panic!("{args:?} still running after 20 s"));
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
        assert!(e.contains(what), "{args:?}: {e}");
    }
}

/// Class: `--threads` far above the cores is refused with the bound.
#[test]
fn thousands_of_threads_are_refused_with_the_bound() {
    let dir = tempfile::tempdir().unwrap();
    let run = copy_drop(dir.path(), DROP, |x| x);
    let mut cmd = dropscope();
    cmd.arg("process")
        .arg(&run)
        .args(["--radius-mm", "4.5", "--threads", "4096", "--out"])
        .arg(dir.path().join("out"));
    let o = within(cmd, Duration::from_secs(30)).expect("still running after 30 s");
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("--threads 4096: at most"), "{e}");
    assert!(
        !dir.path().join("out").exists(),
        "the output folder was touched"
    );
}

/// Whether `out`'s lock folder holds a ticket.
fn ticket_in(out: &Path) -> bool {
    std::fs::read_dir(out.join(".dropscope.lock")).is_ok_and(|e| {
        e.flatten()
            .any(|e| e.file_name().to_string_lossy().ends_with(".json"))
    })
}

/// Class: SIGTERM (a Slurm cancel or time limit) and SIGINT (Ctrl-C) end
/// a job and release its output folder: no ticket is left for another
/// host to be refused by. An empty ticket (what a power cut leaves) is
/// taken over saying so.
#[cfg(unix)]
#[test]
fn a_signal_releases_the_output_folder_and_an_empty_ticket_is_taken_over() {
    let dir = tempfile::tempdir().unwrap();
    let runs: Vec<PathBuf> = (0..6)
        .map(|i| copy_drop(dir.path(), &format!("r{i}"), |x| x))
        .collect();
    for signal in [libc::SIGTERM, libc::SIGINT] {
        let out = dir.path().join(format!("out{signal}"));
        let mut child = dropscope()
            .arg("process")
            .args(&runs)
            .args(["--radius-mm", "4.5", "--threads", "1", "--out"])
            .arg(&out)
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let start = Instant::now();
        while !ticket_in(&out) {
            assert!(start.elapsed() < Duration::from_secs(30), "no ticket taken");
            std::thread::sleep(Duration::from_millis(10));
        }
        std::thread::sleep(Duration::from_millis(300));
        unsafe { libc::kill(child.id() as libc::pid_t, signal) };
        let status = child.wait().unwrap();
        assert!(!status.success(), "{signal}: the job did not stop");
        assert!(!ticket_in(&out), "{signal}: the ticket was left");
    }
    let out = dir.path().join("out-empty-ticket");
    std::fs::create_dir_all(out.join(".dropscope.lock")).unwrap();
    std::fs::write(out.join(".dropscope.lock/0000000001.json"), b"").unwrap();
    let o = process(&[&runs[0]], &out, &[]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(0), "{e}");
    assert!(e.contains("0000000001.json was empty or damaged"), "{e}");
}

/// An 8-bit grey little-endian TIFF of `w` × `h` with `orientation`.
fn tiff_with_orientation(w: u16, h: u16, orientation: u16) -> Vec<u8> {
    let pixels = (0..u32::from(w) * u32::from(h)).map(|i| (i % 251) as u8);
    tiff(w, h, orientation, 1, pixels.collect())
}

/// An 8-bit grey little-endian TIFF of `w` × `h` with `orientation` and
/// `compression` (1 none, 8 deflate), one strip holding `data`.
fn tiff(w: u16, h: u16, orientation: u16, compression: u16, data: Vec<u8>) -> Vec<u8> {
    let entries: [(u16, u16, u32, u32); 9] = [
        (256, 3, 1, u32::from(w)),
        (257, 3, 1, u32::from(h)),
        (258, 3, 1, 8),
        (259, 3, 1, u32::from(compression)),
        (262, 3, 1, 1),
        (273, 4, 1, 8 + 2 + 9 * 12 + 4),
        (274, 3, 1, u32::from(orientation)),
        (277, 3, 1, 1),
        (279, 4, 1, data.len() as u32),
    ];
    let mut b = b"II*\0".to_vec();
    b.extend_from_slice(&8u32.to_le_bytes());
    b.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for (tag, ty, count, value) in entries {
        b.extend_from_slice(&tag.to_le_bytes());
        b.extend_from_slice(&ty.to_le_bytes());
        b.extend_from_slice(&count.to_le_bytes());
        b.extend_from_slice(&value.to_le_bytes());
    }
    b.extend_from_slice(&0u32.to_le_bytes());
    b.extend(data);
    b
}

/// Unclear cases made clear: a TIFF whose Orientation tag says it is shown
/// turned is refused saying so (not measured upside down and blamed on
/// the sphere); a run named with a space and non-ASCII letters has its
/// overlay and figure in the report.
#[test]
fn a_turned_tiff_is_refused_and_any_valid_name_gets_its_overlay() {
    let dir = tempfile::tempdir().unwrap();
    let turned = dir.path().join("turned");
    std::fs::create_dir(&turned).unwrap();
    for i in 0..3 {
        std::fs::write(
            turned.join(format!("t_{i:03}.tif")),
            tiff_with_orientation(16, 12, 3),
        )
        .unwrap();
    }
    let e = inspect(&turned).unwrap_err();
    assert!(
        e.contains("Orientation tag 3") && e.contains("turned 180°"),
        "{e}"
    );
    let upright = dir.path().join("upright");
    std::fs::create_dir(&upright).unwrap();
    for i in 0..3 {
        std::fs::write(
            upright.join(format!("t_{i:03}.tif")),
            tiff_with_orientation(16, 12, 1),
        )
        .unwrap();
    }
    let mut opts = dropscope();
    opts.arg("inspect")
        .arg(&upright)
        .args(["--fps", "1000", "--json"]);
    let o = opts.output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));

    let name = "drop 7 Größe";
    let run = copy_drop(dir.path(), name, |x| x);
    let out = dir.path().join("out");
    let o = process(&[&run], &out, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o = dropscope()
        .arg("collapse")
        .arg(out.join("drops.csv"))
        .output()
        .unwrap();
    assert!(o.status.code().is_some_and(|c| c < 2), "{}", stderr(&o));
    let o = dropscope().arg("report").arg(&out).output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(out
        .join("plots/drops")
        .join(format!("{name}.svg"))
        .is_file());
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    let url = "plots/overlays/drop%207%20Gr%C3%B6%C3%9Fe.png";
    assert!(html.contains(url), "no overlay for {name:?}");
    assert!(html.contains("plots/drops/drop%207%20Gr%C3%B6%C3%9Fe.svg"));
}
