//! The job's surroundings: a closed or full terminal, a named pipe or a
//! device as an input, thousands of threads, a signal and a left ticket.

use super::*;
use std::io::Read;

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
