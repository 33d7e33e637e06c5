//! Output folders shared by several processes: a second
//! job into a busy folder is refused (or waits), shards of one job started
//! side by side end byte-identical to one machine, and a killed shard loses
//! nothing it had committed.

use crate::run::{assert_same_tree, fixture, run, stderr, write_config};
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// `runs.csv` in `dir`: the three fixture drops, `copies` times each under
/// other names (24 runs for 8 copies: about 2 s of work on one thread).
pub(crate) fn repeated_manifest(dir: &Path, copies: usize) {
    let mut m = String::from("run,path,sphere_radius_mm\n");
    for k in 1..=copies {
        for (run, r) in [
            ("R3mm_H1.5cm_01", 3.0),
            ("R4.5mm_H12cm_01", 4.5),
            ("R7mm_H50cm_01", 7.0),
        ] {
            m += &format!("{run}_{k},{},{r}\n", fixture(run).display());
        }
    }
    std::fs::write(dir.join("runs.csv"), m).unwrap();
}

/// `dropscope run --config CONFIG ARGS…` started in the background.
fn spawn(config: &Path, args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_dropscope"))
        .arg("run")
        .arg("--config")
        .arg(config)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn finish(child: Child) -> Output {
    child.wait_with_output().unwrap()
}

/// Wait until `cond` holds, failing the test with `what` after a minute.
fn wait_for(what: &str, mut cond: impl FnMut() -> bool) {
    let start = Instant::now();
    while !cond() {
        assert!(start.elapsed() < Duration::from_secs(60), "{what}");
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Whether a ticket in `out`'s lock folder holds it.
fn held(out: &Path) -> bool {
    std::fs::read_dir(out.join(".dropscope.lock")).is_ok_and(|entries| {
        entries.flatten().any(|e| {
            e.path().extension().is_some_and(|x| x == "json")
                && std::fs::read_to_string(e.path()).is_ok_and(|t| t.contains("\"held\": true"))
        })
    })
}

/// The number of committed runs (cache entries) in `out`.
pub(crate) fn committed(out: &Path) -> usize {
    std::fs::read_dir(out.join("runs")).map_or(0, |e| {
        e.flatten()
            .filter(|e| e.path().extension().is_some_and(|x| x == "json"))
            .count()
    })
}

/// The number in "… N reused from the cache" of a job's last line.
fn reused(o: &Output) -> usize {
    let e = stderr(o);
    let tail = e.lines().last().unwrap_or_default();
    let k = tail.find(" reused").unwrap_or_else(|| panic!("{e}"));
    tail[..k].rsplit(' ').next().unwrap().parse().unwrap()
}

/// Assert that `out` holds byte for byte what the whole job on one
/// machine writes there: `out` is moved aside, the job run into a fresh
/// `out` (at the same path: fits.json names it), and the two compared.
pub(crate) fn assert_same_as_one_machine(cfg: &Path, out: &Path, what: &str) {
    let moved = out.with_extension("under-test");
    std::fs::rename(out, &moved).unwrap();
    let o = run(cfg, &["--threads", "2", "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_same_tree(out, &moved, what);
}

/// While a job writes into a folder, the same job started
/// again and another configuration's job are refused with a message naming
/// the holder and --wait; a job with --wait starts once the first is done;
/// the first's output is complete, byte for byte that of a job alone.
#[test]
fn a_second_job_into_a_busy_folder_is_refused_and_the_first_completes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    repeated_manifest(d, 8);
    let cfg = write_config(d, "");
    let other = d.join("other");
    std::fs::create_dir(&other).unwrap();
    repeated_manifest(&other, 1);
    let other_cfg = write_config(&other, "contact_margin_px = 2.5");
    let out = d.join("out");
    let out_arg = ["--out", out.to_str().unwrap()];

    let first = spawn(&cfg, &[&["--threads", "1"][..], &out_arg].concat());
    let pid = first.id();
    wait_for("the first job never took the folder", || held(&out));
    let waiter = spawn(&cfg, &[&["--wait"][..], &out_arg].concat());
    let same = run(&cfg, &out_arg);
    let another = run(&other_cfg, &out_arg);
    for (o, says) in [(&same, "the same job"), (&another, "another job")] {
        let e = stderr(o);
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert!(
            e.contains(&format!("{} is in use by job", out.display()))
                && e.contains(&format!("pid {pid} on host"))
                && e.contains(says)
                && e.contains("--wait"),
            "{e}"
        );
    }
    let first = finish(first);
    assert_eq!(first.status.code(), Some(0), "{}", stderr(&first));
    let waiter = finish(waiter);
    assert_eq!(waiter.status.code(), Some(0), "{}", stderr(&waiter));
    assert!(
        stderr(&waiter).contains("waiting for job"),
        "{}",
        stderr(&waiter)
    );
    assert_eq!(
        reused(&waiter),
        24,
        "the waiting job did not start after the first"
    );
    assert_same_as_one_machine(&cfg, &out, "the first job's output");
}

/// Three shards started side by side, and four run one after the
/// other in reverse order, each into one folder, then the whole job there:
/// it reuses every run, and the folder is byte-identical to one machine's.
#[test]
fn shards_side_by_side_end_byte_identical_to_one_machine() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    repeated_manifest(d, 8);
    let cfg = write_config(d, "");

    let out3 = d.join("out3");
    let o3 = ["--threads", "1", "--out", out3.to_str().unwrap()];
    let shards: Vec<Child> = (0..3)
        .map(|k| spawn(&cfg, &[&["--shard", &format!("{k}/3")][..], &o3].concat()))
        .collect();
    let mut runs = 0;
    for (k, s) in shards.into_iter().enumerate() {
        let o = finish(s);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(0), "{e}");
        let line = e.lines().last().unwrap();
        assert!(line.starts_with(&format!("shard {k}/3: ")), "{line}");
        runs += line["shard 0/3: ".len()..]
            .split(' ')
            .next()
            .unwrap()
            .parse::<usize>()
            .unwrap();
    }
    assert_eq!(runs, 24);
    assert_eq!(committed(&out3), 24);
    assert!(
        !out3.join("drops.csv").exists(),
        "a shard assembled drops.csv"
    );
    let o = run(&cfg, &o3);
    assert_eq!(reused(&o), 24);
    assert_same_as_one_machine(&cfg, &out3, "3 shards side by side");

    let out4 = d.join("out4");
    let o4 = ["--out", out4.to_str().unwrap()];
    for k in (0..4).rev() {
        let o = run(&cfg, &[&["--shard", &format!("{k}/4")][..], &o4].concat());
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    }
    assert_eq!(reused(&run(&cfg, &o4)), 24);
    assert_same_as_one_machine(&cfg, &out4, "4 shards in reverse order");
}

/// A shard killed (SIGKILL) half-way loses none of the runs it committed:
/// started again it reuses them and does the rest, taking over the lock it
/// left; with the other shard and the whole job the folder ends
/// byte-identical to one machine's.
#[test]
fn a_killed_shard_loses_nothing_and_its_rerun_completes_the_folder() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    repeated_manifest(d, 8);
    // Copies of one drop are one camera set-up to `camera.infer_setups`,
    // and a set-up is committed whole; here every run is its own, so that
    // a kill falls between two of them.
    let cfg = write_config(d, "\n[camera]\ninfer_setups = false");
    let out = d.join("out");
    let args = [
        "--threads",
        "1",
        "--shard",
        "0/2",
        "--out",
        out.to_str().unwrap(),
    ];
    let mut victim = spawn(&cfg, &args);
    wait_for("the shard committed nothing", || committed(&out) >= 2);
    victim.kill().unwrap();
    victim.wait().unwrap();
    let done = committed(&out);
    assert!(
        done < 12,
        "the shard finished its 12 runs before it was killed"
    );
    assert!(
        out.join(".dropscope.lock").is_dir(),
        "the killed shard left no lock"
    );

    let again = run(&cfg, &args);
    let e = stderr(&again);
    assert_eq!(again.status.code(), Some(0), "{e}");
    assert!(e.contains("took over the lock of shard 0/2"), "{e}");
    assert_eq!(reused(&again), done, "{e}");
    let o = run(&cfg, &["--shard", "1/2", "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(reused(&run(&cfg, &["--out", out.to_str().unwrap()])), 24);
    assert_same_as_one_machine(&cfg, &out, "killed shard, rerun");
}

/// `--shard` outside what it accepts, and `--shard slurm` outside an
/// array job, stop with exit status 2 and say what to do.
#[test]
fn bad_shards_and_slurm_outside_an_array_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    repeated_manifest(d, 1);
    let cfg = write_config(d, "");
    let o = run(&cfg, &["--shard", "3/3"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("--shard 3/3: expected K/N with 0 <= K < N"),
        "{}",
        stderr(&o)
    );
    let o = Command::new(env!("CARGO_BIN_EXE_dropscope"))
        .args(["run", "--shard", "slurm", "--config"])
        .arg(&cfg)
        .env_remove("SLURM_ARRAY_TASK_ID")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o)
            .contains("SLURM_ARRAY_TASK_ID is not set: this is not a task of a Slurm array job"),
        "{}",
        stderr(&o)
    );
    assert!(
        !d.join("out").exists(),
        "a refused shard wrote into the folder"
    );
}

/// `process`, `collapse` and `report` hold their folder too: while another
/// job holds it (here this test process), each stops with exit status 2
/// naming the holder, and writes nothing; once it is free they run.
#[test]
fn process_collapse_and_report_are_refused_a_held_folder() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    repeated_manifest(d, 1);
    let out = d.join("out");
    let held = dropscope::job::lock::acquire(
        &out,
        &dropscope::job::lock::Holder::this_process("another job", None),
        false,
        &|_| {},
    )
    .unwrap();
    let cmd = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_dropscope"))
            .current_dir(d)
            .args(args)
            .output()
            .unwrap()
    };
    let out_s = out.to_str().unwrap();
    let drops = d.join("out/drops.csv");
    let commands: [Vec<&str>; 3] = [
        vec!["process", "--manifest", "runs.csv", "--out", out_s],
        vec!["collapse", drops.to_str().unwrap()],
        vec!["report", out_s],
    ];
    for args in &commands {
        let o = cmd(args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
        assert!(
            e.contains("is in use by job") && e.contains(&format!("pid {}", std::process::id())),
            "{args:?}: {e}"
        );
    }
    let files: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(
        files,
        [".dropscope.lock"],
        "a refused command wrote into the folder"
    );
    drop(held);
    for args in &commands {
        let o = cmd(args);
        assert!(
            o.status.code().is_some_and(|c| c < 2),
            "{args:?}: {}",
            stderr(&o)
        );
    }
    assert!(out.join("report.html").is_file());
}
