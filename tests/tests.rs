//! The integration tests, compiled into one binary (one module per stage).
//!
//! A test that needs what a fresh machine may lack (the project's
//! `../shared/` data, Chromium, chromedriver, a running Slurm) starts with `need!(…)`:
//! without it the test prints `SKIPPED: <test>: <what is missing and how to
//! get it>` on the terminal and returns, unless `DROPSCOPE_REQUIRE_ALL=1`
//! (CI's `.ci/run` sets it), under which it fails saying the same.

use std::io::Write;
use std::path::{Path, PathBuf};

/// Return from the calling test unless every [`Need`] given is met
/// ([`available`]).
macro_rules! need {
    ($($need:expr),+) => {
        if !($($crate::available($need))&&+) {
            return;
        }
    };
}

mod accuracy_effects;
mod cli;
mod collapse;
mod detect;
mod footage;
mod hostile;
mod independent;
mod layers;
mod parallel;
mod pcc_xml;
mod process;
mod process_formats;
mod process_job;
mod render;
mod render_contact;
mod render_real;
mod render_saturated;
mod report;
mod review;
mod run;
mod setup_infer;
mod shards;
mod slurm;
mod source;
mod source_colour;
mod source_inputs;
mod source_photron;
mod source_tiff;
mod timings;
mod track;
mod untrusted;
mod webdriver;
mod wide_frames;

/// What a test needs from the machine beyond the checkout.
#[derive(Debug, Clone, Copy)]
pub enum Need {
    /// `../shared/data/phantom-samples/`: the real Phantom files.
    PhantomSamples,
    /// `../shared/data/<path>`.
    SharedData(&'static str),
    /// Headless Chromium at `/usr/bin/chromium`.
    Chromium,
    /// Debian's chromedriver at `/usr/bin/chromedriver` (WebDriver for Chromium).
    ChromeDriver,
    /// A reachable Slurm cluster with a node that can take jobs.
    Slurm,
}

/// Whether a node state printed by `sinfo -o %t` can take jobs now.
fn usable_slurm_state(state: &str) -> bool {
    state
        .split_whitespace()
        .any(|s| matches!(s.trim_end_matches('-'), "idle" | "mix" | "alloc"))
}

/// The node states `sinfo` prints, waited for up to a minute while they
/// are passing ones (`comp` after a cancelled job, a node coming back):
/// the empty string when `sinfo` cannot run or fails.
fn slurm_node_state() -> String {
    let read = || {
        std::process::Command::new("sinfo")
            .args(["-h", "-o", "%t"])
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).into_owned())
    };
    let start = std::time::Instant::now();
    loop {
        let Some(state) = read() else {
            return String::new();
        };
        if usable_slurm_state(&state) || start.elapsed() > std::time::Duration::from_secs(60) {
            return state;
        }
        std::thread::sleep(std::time::Duration::from_millis(500));
    }
}

/// The project's `shared/` folder beside the checkout.
fn shared() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared")
}

/// Whether CI asked for every test: `DROPSCOPE_REQUIRE_ALL=1`.
pub fn require_all() -> bool {
    std::env::var("DROPSCOPE_REQUIRE_ALL").is_ok_and(|v| v == "1")
}

/// Whether `need` is met. When it is not: under `DROPSCOPE_REQUIRE_ALL=1`
/// the test fails saying what is missing and how to get it; otherwise that
/// is printed as `SKIPPED: <test>: …` on the terminal (written to stderr
/// itself, past the test harness's capture of `eprintln!`, so that it shows
/// for a passing test) and `false` is returned.
pub fn available(need: Need) -> bool {
    available_with(need, require_all(), &mut std::io::stderr())
}

/// [`available`] with `require_all` given, its notice written to `notice`.
fn available_with(need: Need, require_all: bool, notice: &mut dyn Write) -> bool {
    let shared_data = "the project's shared/ folder must sit beside the checkout (the \
                       repository's sibling `shared/`, holding data/): clone or copy it there";
    let (met, what, how) = match need {
        Need::PhantomSamples => (
            shared().join("data/phantom-samples").is_dir(),
            format!("{}", shared().join("data/phantom-samples").display()),
            shared_data.to_string(),
        ),
        Need::SharedData(rel) => (
            shared().join("data").join(rel).exists(),
            format!("{}", shared().join("data").join(rel).display()),
            shared_data.to_string(),
        ),
        Need::Chromium => (
            Path::new("/usr/bin/chromium").is_file(),
            "/usr/bin/chromium".to_string(),
            "as root: apt-get install chromium (.ci/run does it)".to_string(),
        ),
        Need::ChromeDriver => (
            Path::new("/usr/bin/chromedriver").is_file(),
            "/usr/bin/chromedriver".to_string(),
            "as root: apt-get install chromium chromium-driver (.ci/run does it)".to_string(),
        ),
        Need::Slurm => {
            let state = slurm_node_state();
            (
                usable_slurm_state(&state),
                format!(
                    "a Slurm cluster with a usable node (sinfo shows {:?})",
                    state.trim()
                ),
                "as root: apt-get install slurm-wlm munge && .ci/slurm-up (a one-node cluster on \
                 this machine; .ci/run does both)"
                    .to_string(),
            )
        }
    };
    if met {
        return true;
    }
    let test = std::thread::current()
        .name()
        .unwrap_or("a test")
        .to_string();
    assert!(
        !require_all,
        "{test}: {what} is missing: {how} (DROPSCOPE_REQUIRE_ALL=1: every test must run)"
    );
    let _ = writeln!(
        notice,
        "SKIPPED: {test}: {what} is missing: {how} (set DROPSCOPE_REQUIRE_ALL=1 to fail instead)"
    );
    false
}

/// `../shared/data/phantom-samples/` beside the checkout, with `rel` joined:
/// the real Phantom files some tests read (each starts with
/// `need!(Need::PhantomSamples)`). Without that folder, the test stops
/// saying where it looked and what to do, not with a bare "file not found".
pub fn phantom_sample(rel: &str) -> PathBuf {
    let root = shared().join("data/phantom-samples");
    assert!(
        root.is_dir(),
        "the real Phantom sample files are missing: looked for {}. These tests need the \
         project's shared/ folder beside the checkout (shared/data/phantom-samples/); \
         clone or copy it there, or run the tests from a checkout that sits beside it",
        root.display()
    );
    root.join(rel)
}

/// `../shared/data/real-footage/` beside the checkout, with `rel` joined:
/// real recordings of falling balls and drops (each folder's SOURCE.md
/// gives its origin and known values). Missing, the test stops saying where
/// it looked, as [`phantom_sample`] does.
pub fn real_footage(rel: &str) -> std::path::PathBuf {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real-footage");
    assert!(
        root.is_dir(),
        "the real footage files are missing: looked for {}. These tests need the \
         project's shared/ folder beside the checkout (shared/data/real-footage/)",
        root.display()
    );
    root.join(rel)
}

/// `../shared/data/<rel>` when it is there; else `None` after
/// [`available`]'s notice (or its failure under `DROPSCOPE_REQUIRE_ALL=1`).
pub fn shared_data(rel: &'static str) -> Option<PathBuf> {
    available(Need::SharedData(rel)).then(|| shared().join("data").join(rel))
}

/// A need that is not met skips its test (`false`, with the notice) unless
/// every test is required, when the test fails naming what is missing and
/// how to get it; one that is met lets the test run.
#[test]
fn a_missing_need_skips_out_loud_or_fails_when_every_test_is_required() {
    let missing = Need::SharedData("no-such-folder-of-this-test");
    let mut notice = Vec::new();
    assert!(!available_with(missing, false, &mut notice));
    let notice = String::from_utf8(notice).unwrap();
    assert!(
        notice.starts_with(
            "SKIPPED: a_missing_need_skips_out_loud_or_fails_when_every_test_is_required: "
        ) && notice.contains("no-such-folder-of-this-test is missing")
            && notice.contains("set DROPSCOPE_REQUIRE_ALL=1 to fail instead"),
        "{notice}"
    );
    let failed = std::panic::catch_unwind(|| available_with(missing, true, &mut Vec::new()))
        .expect_err("required and missing must fail");
    let message = failed.downcast_ref::<String>().cloned().unwrap_or_default();
    assert!(
        message.contains("no-such-folder-of-this-test is missing")
            && message.contains("shared/ folder must sit beside the checkout")
            && message.contains("DROPSCOPE_REQUIRE_ALL=1"),
        "{message}"
    );
    // The checkout itself is always there: `shared/..` is its parent.
    assert!(Path::new(env!("CARGO_MANIFEST_DIR")).is_dir());
    if shared().is_dir() {
        assert!(available_with(Need::SharedData("."), true, &mut Vec::new()));
    }
}

/// A node that is taking jobs counts, whatever its load; one completing a
/// cancelled job, down, drained or not responding does not (yet).
#[test]
fn a_slurm_node_counts_when_it_can_take_jobs() {
    for state in ["idle\n", "mix\n", "alloc\n", "idle-\n", "comp\nidle\n"] {
        assert!(usable_slurm_state(state), "{state:?}");
    }
    for state in [
        "", "comp\n", "idle*\n", "down\n", "drain\n", "drng\n", "unk*\n",
    ] {
        assert!(!usable_slurm_state(state), "{state:?}");
    }
}
