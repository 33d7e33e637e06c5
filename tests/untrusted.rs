//! Untrusted input, beyond tests/hostile.rs: what a planted link, a file
//! name, a cell, a cache entry, a side file or a shared pipeline.toml
//! could make dropscope do. Each test is one class of fault, made as a
//! user (or an attacker) would make it, and run through the command line:
//! nothing may escape the output folder, run as a command, reach a
//! terminal or a spreadsheet as active content, or stand as a number
//! marked ok that a file lied about; no panic and no hang.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use dropscope::dataset::read_csv;

mod environment;
mod injected;
mod lying_files;

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
