//! The main job on a real Slurm cluster: `dropscope slurm
//! --submit` over a rendered campaign ends byte-identical to one machine,
//! and a task cancelled half-way is redone by submitting again. They need a
//! reachable Slurm — `.ci/slurm-up` starts a one-node cluster, and CI runs
//! it — and are skipped with a notice without one (failed under
//! `DROPSCOPE_REQUIRE_ALL=1`, as CI runs them).

use crate::run::{stderr, write_config};
use crate::shards::{assert_same_as_one_machine, committed};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::{Mutex, MutexGuard, OnceLock};
use std::time::{Duration, Instant};

fn dropscope() -> Command {
    Command::new(env!("CARGO_BIN_EXE_dropscope"))
}

/// `program args…`, its stdout; the test fails with its stderr when it fails.
fn must(program: &str, args: &[&str]) -> String {
    let o = Command::new(program)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("{program}: {e}"));
    assert!(o.status.success(), "{program} {args:?}: {}", stderr(&o));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The one-node cluster, held by one test at a time: a job cancelled by
/// one test leaves the node completing while the other would look at it,
/// and the tests' timing assumes the node is theirs.
fn cluster() -> MutexGuard<'static, ()> {
    static CLUSTER: Mutex<()> = Mutex::new(());
    CLUSTER.lock().unwrap_or_else(|e| e.into_inner())
}

/// A small campaign rendered once for the tests of this module: 3 radii ×
/// 2 heights × 2 repeats, 12 drops (4 per shard of 3).
fn campaign() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let o = dropscope()
            .args([
                "render",
                "--campaign",
                "--radii-mm",
                "3,5,7",
                "--heights-cm",
                "3,12",
            ])
            .args(["--repeats", "2", "--seed", "9", "--out"])
            .arg(dir.path())
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        dir
    })
    .path()
}

/// A folder for one test: its configuration (the campaign's manifest) and
/// the output folder's path.
fn job_folder(d: &Path) -> (PathBuf, PathBuf) {
    let manifest = campaign().join("runs.csv");
    std::fs::copy(&manifest, d.join("runs.csv")).unwrap();
    // The manifest's paths are relative to it: point them at the campaign.
    let text = std::fs::read_to_string(&manifest).unwrap();
    let mut lines = text.lines();
    let mut m = format!("{}\n", lines.next().unwrap());
    for l in lines {
        let (run, rest) = l.split_once(',').unwrap();
        let (path, rest) = rest.split_once(',').unwrap();
        m += &format!("{run},{},{rest}\n", campaign().join(path).display());
    }
    std::fs::write(d.join("runs.csv"), m).unwrap();
    // The manifest names no set-ups: with `camera.infer_setups` all its
    // runs would be one shard's; these tests need them spread.
    (
        write_config(d, "\n[camera]\ninfer_setups = false"),
        d.join("out"),
    )
}

/// `dropscope slurm --submit` from `d`: (array job id, finishing job id).
fn submit(d: &Path, cfg: &Path, out: &Path, cpus: usize) -> (String, String) {
    let o: Output = dropscope()
        .current_dir(d)
        .args([
            "slurm",
            "--array",
            "3",
            "--cpus-per-task",
            &cpus.to_string(),
            "--submit",
        ])
        .arg("--config")
        .arg(cfg)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert_eq!(o.status.code(), Some(0), "{text}{}", stderr(&o));
    let id = |prefix: &str| -> String {
        let line = text
            .lines()
            .find(|l| l.starts_with(prefix))
            .unwrap_or_else(|| panic!("no `{prefix}` in\n{text}"));
        line[prefix.len()..].split(' ').next().unwrap().to_string()
    };
    (id("array job "), id("finishing job "))
}

/// `JobState` of job (or array task) `id`, while the controller knows it.
fn job_state(id: &str) -> String {
    let show = must("scontrol", &["show", "job", "-o", id]);
    let k = show.find("JobState=").unwrap_or_else(|| panic!("{show}")) + "JobState=".len();
    show[k..].split(' ').next().unwrap().to_string()
}

/// The state of `id` once `done(state)`; fails after five minutes.
fn wait_state(id: &str, done: impl Fn(&str) -> bool) -> String {
    let start = Instant::now();
    loop {
        let s = job_state(id);
        if done(&s) {
            return s;
        }
        assert!(
            start.elapsed() < Duration::from_secs(300),
            "job {id} still {s} after 5 minutes"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn ended(s: &str) -> bool {
    !matches!(
        s,
        "PENDING" | "RUNNING" | "CONFIGURING" | "COMPLETING" | "SUSPENDED"
    )
}

/// Every log the jobs wrote, for failure messages.
fn logs(out: &Path) -> String {
    let dir = out.with_extension("slurm").join("logs");
    let mut s = String::new();
    for e in std::fs::read_dir(&dir).into_iter().flatten().flatten() {
        s += &format!(
            "--- {}\n{}",
            e.path().display(),
            std::fs::read_to_string(e.path()).unwrap_or_default()
        );
    }
    s
}

/// The last line of task `task` of array job `job`'s log.
fn shard_line(out: &Path, job: &str, task: usize) -> String {
    let p = out
        .with_extension("slurm")
        .join("logs")
        .join(format!("shard-{job}_{task}.out"));
    let text = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    text.lines().last().unwrap_or_default().to_string()
}

/// (runs, reused) of a shard's summary line.
fn runs_and_reused(line: &str) -> (usize, usize) {
    let field = |before: &str| -> usize {
        let k = line.find(before).unwrap_or_else(|| panic!("{line}"));
        line[..k].rsplit(' ').next().unwrap().parse().unwrap()
    };
    (field(" runs:"), field(" reused"))
}

/// A 3-task array and its finishing job through the real sbatch: the
/// folder ends byte-identical to the whole job on one machine.
#[test]
fn a_slurm_array_ends_byte_identical_to_one_machine() {
    let _cluster = cluster();
    need!(crate::Need::Slurm);
    let dir = tempfile::tempdir().unwrap();
    let (cfg, out) = job_folder(dir.path());
    let (array, finish) = submit(dir.path(), &cfg, &out, 1);
    let state = wait_state(&finish, ended);
    assert_eq!(state, "COMPLETED", "{}", logs(&out));
    let mut runs = 0;
    for task in 0..3 {
        let line = shard_line(&out, &array, task);
        assert!(line.starts_with(&format!("shard {task}/3: ")), "{line}");
        runs += runs_and_reused(&line).0;
    }
    assert_eq!(runs, 12);
    assert!(out.join("report.html").is_file(), "{}", logs(&out));
    assert_same_as_one_machine(&cfg, &out, "Slurm array of 3");
}

/// Task 1 cancelled (scancel) after it committed a run: the finishing job
/// never starts (its dependency cannot be met) and is cancelled as the
/// README says; submitting again redoes only the missing runs, and the
/// folder ends byte-identical to one machine's.
#[test]
fn a_cancelled_task_is_redone_by_submitting_again() {
    let _cluster = cluster();
    need!(crate::Need::Slurm);
    let dir = tempfile::tempdir().unwrap();
    let (cfg, out) = job_folder(dir.path());
    // Tasks as wide as the node: one runs at a time, so runs committed
    // while task 1 runs are its own.
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    let (array, finish) = submit(dir.path(), &cfg, &out, cpus);
    let task1 = format!("{array}_1");
    wait_state(&task1, |s| s != "PENDING");
    let before = committed(&out);
    let start = Instant::now();
    while committed(&out) == before && job_state(&task1) == "RUNNING" {
        assert!(
            start.elapsed() < Duration::from_secs(300),
            "task 1 commits nothing"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    must("scancel", &[&task1]);
    let state = wait_state(&task1, ended);
    assert_eq!(
        state,
        "CANCELLED",
        "task 1 ended before it could be cancelled\n{}",
        logs(&out)
    );
    let state = wait_state(&format!("{array}_2"), ended);
    assert_eq!(state, "COMPLETED", "{}", logs(&out));
    // The finishing job waits for a dependency that can no longer be met.
    let start = Instant::now();
    loop {
        let reason = must("squeue", &["-h", "-j", &finish, "-o", "%T %r"]);
        if reason.trim() == "PENDING DependencyNeverSatisfied" {
            break;
        }
        assert!(
            reason.starts_with("PENDING") && start.elapsed() < Duration::from_secs(120),
            "finishing job: {reason}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    assert!(!out.join("drops.csv").exists());
    must("scancel", &[&finish]);

    let (again, finish) = submit(dir.path(), &cfg, &out, 1);
    let state = wait_state(&finish, ended);
    assert_eq!(state, "COMPLETED", "{}", logs(&out));
    for task in 0..3 {
        let (runs, reused) = runs_and_reused(&shard_line(&out, &again, task));
        if task == 1 {
            assert!(
                reused >= 1 && reused < runs,
                "task 1: {reused} of {runs} reused"
            );
        } else {
            assert_eq!(reused, runs, "task {task} redid finished runs");
        }
    }
    assert_same_as_one_machine(&cfg, &out, "cancelled task, submitted again");
}
