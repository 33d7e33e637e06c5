//! Text that could act: a flag or a shared configuration in the Slurm
//! scripts, a formula in a CSV cell, terminal escapes in a name, invisible
//! characters in a run name.

use super::*;

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
