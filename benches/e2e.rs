//! End to end: frames/s of `dropscope process` — every output
//! written: `drops.csv`, `tracks/`, the overlays — beside the plain decode
//! rate of the same frames in the same run, for one long 8-bit TIFF movie,
//! a campaign of short drops, a 10 000-frame `.cine`, a 31 000-frame
//! `.cine` of small frames (for the peak memory of a long movie), and the
//! same drop at 512 × 384 and at 1280 × 800.
//!
//!     cargo bench --bench e2e                 (DROPSCOPE_E2E_DATA=DIR, REPEATS=N)
//!
//! The data are rendered once into `DROPSCOPE_E2E_DATA` (default
//! `target/e2e-data`, ≈ 7.5 GB) by the `render` commands printed (and listed
//! in docs/performance.md); a later run reuses them. Each figure is from
//! the page cache: every input file is read whole again right before each
//! timed run: this virtual machine's kernel pages out what has not been
//! touched for about a minute (a DAMON `pageout` scheme, `kdamond`: age
//! ≥ 12 intervals of 5 s, in `/sys/kernel/mm/damon/admin`), so a set read
//! a minute before is mostly gone (`wide`: 1 126 of its 2 218 MB resident,
//! 322 a minute later), and the disk's reads then show in the child's
//! wall and CPU time.
//!
//! - decode: every frame read whole (`FrameSource::read_into`, 16-bit out)
//!   on 2 threads, each with its own sources, frames split evenly;
//! - end to end: `dropscope process --manifest runs.csv --out TMP` as a
//!   child process with `RAYON_NUM_THREADS` = 2 (and 1 for the single
//!   movies, the two interleaved so that the machine's drift falls on
//!   both), `REPEATS` times (default 3): wall time best and range, the
//!   child's CPU time (user + system) and peak memory (`wait4`'s rusage);
//!   the 1 → 2 ratio of the best runs and of the medians;
//! - the outputs of 1 and 2 threads compared byte for byte.
//!
//! The machine is shared: the CPU figures are what the work costs, the wall
//! figures what it took at the load of the moment (printed).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use dropscope::dataset::manifest::read_manifest;
use dropscope::source::{open, Frame, OpenOptions};

const BIN: &str = env!("CARGO_BIN_EXE_dropscope");

/// A data set: its folder under the data root and the render arguments.
struct DataSet {
    name: &'static str,
    what: &'static str,
    render: &'static [&'static str],
}

const LONG: &[&str] = &[
    "--drop",
    "3:1.5",
    "--fps",
    "60000",
    "--exposure-us",
    "10",
    "--frames-before",
    "3000",
    "--frames-after",
    "3000",
    "--format",
    "tiff",
];
const CAMPAIGN: &[&str] = &[
    "--campaign",
    "--repeats",
    "2",
    "--preset",
    "realistic",
    "--tilt",
    "0.003",
    "--restitution",
    "0.9",
    "--seed",
    "11",
    "--format",
    "tiff",
];
const CINE: &[&str] = &[
    "--drop",
    "4.5:12",
    "--frames-before",
    "300",
    "--frames-after",
    "9700",
    "--format",
    "cine",
];
const LONG_CINE: &[&str] = &[
    "--drop",
    "3:1.5",
    "--fps",
    "60000",
    "--exposure-us",
    "10",
    "--frames-before",
    "1000",
    "--frames-after",
    "30000",
    "--width-px",
    "256",
    "--height-px",
    "192",
    "--mm-per-px",
    "0.08",
    "--format",
    "cine",
];
const SMALL: &[&str] = &[
    "--drop",
    "3:1.5",
    "--fps",
    "60000",
    "--exposure-us",
    "10",
    "--frames-before",
    "1000",
    "--frames-after",
    "1000",
    "--format",
    "tiff",
    "--width-px",
    "512",
    "--height-px",
    "384",
];
const WIDE: &[&str] = &[
    "--drop",
    "3:1.5",
    "--fps",
    "60000",
    "--exposure-us",
    "10",
    "--frames-before",
    "1000",
    "--frames-after",
    "1000",
    "--format",
    "tiff",
    "--width-px",
    "1280",
    "--height-px",
    "800",
];

const SETS: &[DataSet] = &[
    DataSet {
        name: "long",
        what: "one long 8-bit TIFF movie, 512×384",
        render: LONG,
    },
    DataSet {
        name: "campaign",
        what: "60 short drops, 8-bit TIFF, 512×384",
        render: CAMPAIGN,
    },
    DataSet {
        name: "cine",
        what: "one 10 000-frame 8-bit .cine, 512×384",
        render: CINE,
    },
    DataSet {
        name: "longcine",
        what: "one 31 166-frame 8-bit .cine, 256×192, the sphere in 15 091 frames (peak memory)",
        render: LONG_CINE,
    },
    DataSet {
        name: "small",
        what: "one drop at 512×384 (TIFF)",
        render: SMALL,
    },
    DataSet {
        name: "wide",
        what: "the same drop at 1280×800 (TIFF)",
        render: WIDE,
    },
];

/// One timed child process.
#[derive(Debug, Clone, Copy)]
struct Run {
    wall_s: f64,
    cpu_s: f64,
    peak_mb: f64,
}

/// Run `cmd` to its end; its wall time and its own rusage (`wait4`, which
/// reaps it: `Child::wait` gives no rusage).
#[allow(clippy::zombie_processes)]
fn timed(cmd: &mut Command) -> Run {
    let t0 = Instant::now();
    let child = cmd.spawn().expect("start dropscope");
    let pid = child.id() as libc::pid_t;
    let mut status = 0;
    // SAFETY: an all-zero rusage is valid; wait4 fills it for our own child.
    let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
    let r = unsafe { libc::wait4(pid, &mut status, 0, &mut ru) };
    let wall_s = t0.elapsed().as_secs_f64();
    assert_eq!(r, pid, "wait4");
    let code = libc::WEXITSTATUS(status);
    assert!(code <= 1, "{cmd:?} exited with {code}");
    let tv = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    Run {
        wall_s,
        cpu_s: tv(ru.ru_utime) + tv(ru.ru_stime),
        peak_mb: ru.ru_maxrss as f64 / 1024.0,
    }
}

fn render(root: &Path, set: &DataSet) -> PathBuf {
    let dir = root.join(set.name);
    let manifest = dir.join("runs.csv");
    if !manifest.exists() {
        let _ = std::fs::remove_dir_all(&dir);
        let mut cmd = Command::new(BIN);
        cmd.arg("render").args(set.render).arg("--out").arg(&dir);
        println!(
            "rendering: dropscope render {} --out {}",
            set.render.join(" "),
            dir.display()
        );
        let st = cmd
            .stdout(std::process::Stdio::null())
            .status()
            .expect("render");
        assert!(st.success(), "render {} failed", set.name);
    }
    manifest
}

/// Frames/s and CPU s of reading every frame of `inputs` whole on
/// `threads` threads (frames split evenly, sources opened before the clock).
fn decode(inputs: &[PathBuf], threads: usize) -> (f64, f64, usize) {
    let opts = OpenOptions {
        fps_fallback: Some(10_000.0),
        ..OpenOptions::default()
    };
    // (input, frame range) per thread.
    let counts: Vec<usize> = inputs
        .iter()
        .map(|p| open(p, &opts).expect("open").meta().frame_count)
        .collect();
    let total: usize = counts.iter().sum();
    let mut jobs: Vec<Vec<(usize, usize, usize)>> = vec![Vec::new(); threads];
    let mut k = 0usize;
    for (i, &c) in counts.iter().enumerate() {
        for f in 0..c {
            jobs[k * threads / total].push((i, f, f));
            k += 1;
        }
    }
    let spans: Vec<(Instant, Instant, f64)> = std::thread::scope(|s| {
        let hs: Vec<_> = jobs
            .iter()
            .map(|job| {
                let opts = &opts;
                s.spawn(move || {
                    let mut srcs: Vec<Option<Box<dyn dropscope::source::FrameSource>>> =
                        inputs.iter().map(|_| None).collect();
                    for &(i, _, _) in job {
                        if srcs[i].is_none() {
                            srcs[i] = Some(open(&inputs[i], opts).expect("open"));
                        }
                    }
                    let m = srcs.iter().flatten().next().map(|s| s.meta().clone());
                    let mut buf =
                        m.map_or(Frame::zeros((1, 1)), |m| Frame::zeros((m.height, m.width)));
                    let c0 = dropscope::util::timings::thread_cpu_s();
                    let t0 = Instant::now();
                    for &(i, f, _) in job {
                        srcs[i]
                            .as_mut()
                            .unwrap()
                            .read_into(f, &mut buf)
                            .expect("read");
                    }
                    (
                        t0,
                        Instant::now(),
                        dropscope::util::timings::thread_cpu_s() - c0,
                    )
                })
            })
            .collect();
        hs.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let t0 = spans.iter().map(|s| s.0).min().unwrap();
    let t1 = spans.iter().map(|s| s.1).max().unwrap();
    let cpu: f64 = spans.iter().map(|s| s.2).sum();
    (total as f64 / (t1 - t0).as_secs_f64(), cpu, total)
}

/// Every input file read whole, untimed, into the page cache.
fn warm(inputs: &[PathBuf]) {
    use std::io::Read;
    let mut buf = vec![0u8; 1 << 20];
    let mut read = |p: &Path| {
        if let Ok(mut f) = std::fs::File::open(p) {
            while f.read(&mut buf).is_ok_and(|n| n > 0) {}
        }
    };
    for input in inputs {
        if input.is_dir() {
            for e in std::fs::read_dir(input).unwrap().flatten() {
                read(&e.path());
            }
        } else {
            read(input);
        }
    }
}

/// `process` of `manifest` into `out` on `threads` threads, once, its
/// inputs warmed first.
fn end_to_end(manifest: &Path, inputs: &[PathBuf], out: &Path, threads: usize) -> Run {
    let _ = std::fs::remove_dir_all(out);
    warm(inputs);
    timed(
        Command::new(BIN)
            .args(["process", "--manifest"])
            .arg(manifest)
            .arg("--out")
            .arg(out)
            .env("RAYON_NUM_THREADS", threads.to_string())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null()),
    )
}

/// Every file under `dir`, relative, with its bytes.
fn tree(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if !p.to_string_lossy().contains(".dropscope.lock") {
                out.push((
                    p.strip_prefix(dir).unwrap().to_path_buf(),
                    std::fs::read(&p).unwrap(),
                ));
            }
        }
    }
    out.sort();
    out
}

/// The per-drop cost of `manifest`'s runs stage by stage: the table of
/// `dropscope process --timings` on one thread (`RAYON_NUM_THREADS=1`).
fn stages(manifest: &Path, out: &Path) {
    let _ = std::fs::remove_dir_all(out);
    let o = Command::new(BIN)
        .args(["process", "--timings", "--manifest"])
        .arg(manifest)
        .arg("--out")
        .arg(out)
        .env("RAYON_NUM_THREADS", "1")
        .output()
        .expect("start dropscope");
    let err = String::from_utf8_lossy(&o.stderr);
    let table = err.find("timings, ").map_or("", |at| &err[at..]);
    assert!(!table.is_empty(), "no --timings table: {err}");
    for line in table.lines() {
        println!("          {line}");
    }
}

fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_default()
}

struct Summary {
    frames: usize,
    best: Run,
    worst_wall_s: f64,
    median_wall_s: f64,
}

fn summarize(frames: usize, runs: &[Run]) -> Summary {
    let best = *runs
        .iter()
        .min_by(|a, b| a.wall_s.total_cmp(&b.wall_s))
        .unwrap();
    let mut walls: Vec<f64> = runs.iter().map(|r| r.wall_s).collect();
    walls.sort_by(f64::total_cmp);
    let m = walls.len() / 2;
    let median_wall_s = if walls.len() % 2 == 1 {
        walls[m]
    } else {
        0.5 * (walls[m - 1] + walls[m])
    };
    Summary {
        frames,
        best,
        worst_wall_s: walls[walls.len() - 1],
        median_wall_s,
    }
}

fn main() {
    // `cargo bench` passes `--bench`; a filter selects data sets by name.
    let filter: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let root = std::env::var_os("DROPSCOPE_E2E_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("target/e2e-data"));
    let repeats: usize = std::env::var("REPEATS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    std::fs::create_dir_all(&root).unwrap();
    let work = tempfile::tempdir().unwrap();
    println!(
        "dropscope end to end, 2 threads unless said; load average at start {}",
        load()
    );
    println!(
        "{:<9} {:>6} {:>12} {:>22} {:>8} {:>8} {:>14} {:>6}",
        "data",
        "frames",
        "decode f/s",
        "end to end f/s [range]",
        "CPU s",
        "peak MB",
        "1 thread f/s",
        "1→2"
    );
    let mut per_frame = Vec::new();
    for set in SETS {
        if !filter.is_empty() && !filter.iter().any(|f| f == set.name) {
            continue;
        }
        let manifest = render(&root, set);
        let runs = read_manifest(&manifest).expect("manifest");
        let inputs: Vec<PathBuf> = runs.iter().map(|r| r.path.clone()).collect();
        // Into the page cache, untimed.
        let _ = decode(&inputs, 2);
        let (decode_fps, _, frames) = decode(&inputs, 2);
        let out1 = work.path().join(format!("{}-1", set.name));
        let out2 = work.path().join(format!("{}-2", set.name));
        let single = runs.len() == 1;
        // 2 threads, then (for a single movie) 1, `repeats` times.
        let (mut runs2, mut runs1) = (Vec::new(), Vec::new());
        for _ in 0..repeats {
            runs2.push(end_to_end(&manifest, &inputs, &out2, 2));
            if single {
                runs1.push(end_to_end(&manifest, &inputs, &out1, 1));
            }
        }
        let two = summarize(frames, &runs2);
        let one = single.then(|| (summarize(frames, &runs1), tree(&out1) == tree(&out2)));
        let fps = |s: &Summary| s.frames as f64 / s.best.wall_s;
        println!(
            "{:<9} {:>6} {:>12.0} {:>9.0} [{:>5.0}–{:>5.0}] {:>8.2} {:>8.1} {:>14} {:>6}",
            set.name,
            frames,
            decode_fps,
            fps(&two),
            frames as f64 / two.worst_wall_s,
            fps(&two),
            two.best.cpu_s,
            two.best.peak_mb,
            one.as_ref()
                .map_or("—".into(), |(s, _)| format!("{:.0}", fps(s))),
            one.as_ref().map_or("—".into(), |(s, _)| format!(
                "{:.2}× (medians {:.2}×)",
                s.best.wall_s / two.best.wall_s,
                s.median_wall_s / two.median_wall_s
            )),
        );
        if let Some((_, same)) = &one {
            println!(
                "          ({}; outputs of 1 and 2 threads {})",
                set.what,
                if *same { "byte-identical" } else { "DIFFER" }
            );
        } else {
            println!("          ({})", set.what);
        }
        if set.name == "campaign" {
            stages(&manifest, &work.path().join("stages"));
        }
        per_frame.push((
            set.name,
            two.best.wall_s / frames as f64,
            two.best.cpu_s / frames as f64,
        ));
    }
    let get = |n: &str| per_frame.iter().find(|p| p.0 == n).copied();
    if let (Some(s), Some(w)) = (get("small"), get("wide")) {
        println!(
            "1280×800 against 512×384, same sphere: {:.2}× the wall time per frame, {:.2}× the CPU time",
            w.1 / s.1,
            w.2 / s.2
        );
    }
    println!("load average at end {}", load());
}
