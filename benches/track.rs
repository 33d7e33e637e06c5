//! Speed of detect + track on 512×384 8-bit frames
//! already in memory, 1 and 2 threads.
//!
//!     cargo bench --bench track
//!
//! Movies: rendered drops (realistic preset) decoded once into memory, so
//! file decoding is not timed:
//! * `R = 3 mm` and `R = 7 mm` dropped from 12 cm at 10 000 frames/s, ~90
//!   frames each (30 before contact, the contact, 30 after);
//! * a 600-frame movie: R = 3 mm from 1.5 cm at 60 000 frames/s (exposure
//!   10 µs), 200 frames before contact and 200 after.
//!
//! The sphere is in view in every frame of every movie, and every frame is
//! tracked: "frames" are the movie's frames, each measured twice (radius
//! free, then held). Timed: [`track`] whole — the background from 8 frames
//! and the surface line (the fixed cost per run), then per frame the band
//! read, edge points and free fit (pass 1), the calibration, and the
//! held-radius fit (pass 2). The fixed cost is also timed alone
//! ([`background_and_surface`]); the per-frame cost is the rest divided by
//! the frame count. Two threads track two copies of the movie at once (as a
//! batch runs one drop per thread), sharing the frames in memory.
//!
//! Rates are given by the wall clock (the machine may be shared: note the
//! load) and by each thread's CPU time (what a core delivers unshared).
//! `-- fixed` times only the fixed cost (200 runs on the first movie) and
//! `-- frames` only the long movie's tracking (40 runs, or `TRACK_RUNS`;
//! `-- frames0` the first movie's), for a profiler.

#[path = "common/mod.rs"]
mod common;
use clap::Parser;
use common::thread_cpu_s;
use dropscope::config::DetectConfig;
use dropscope::source::memory::MemorySource;
use dropscope::source::{open, FrameSource, OpenOptions};
use dropscope::track::{background_and_surface, track, Flag, TrackSettings};
use std::time::Instant;

#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    args: dropscope::cli::render::RenderArgs,
}

fn movie(args: &[&str], dir: &std::path::Path) -> MemorySource {
    let out = dir.to_str().expect("temp dir is UTF-8");
    let mut argv = vec!["render", "--preset", "realistic", "--seed", "5"];
    argv.extend_from_slice(args);
    argv.extend_from_slice(&["--out", out]);
    let report = dropscope::render::render(&Cli::parse_from(argv).args.options()).expect("render");
    let mut src = open(&report.drops[0].dir, &OpenOptions::default()).expect("open");
    MemorySource::load(src.as_mut()).expect("load")
}

fn settings() -> TrackSettings {
    TrackSettings::from_config(&DetectConfig::default())
}

/// `reps` calls of `work` on each of `threads` threads: (wall seconds, CPU
/// seconds summed over the threads).
fn timed(threads: usize, reps: usize, work: impl Fn() + Sync) -> (f64, f64) {
    let start = Instant::now();
    let cpu: f64 = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads)
            .map(|_| {
                scope.spawn(|| {
                    let c0 = thread_cpu_s();
                    for _ in 0..reps {
                        work();
                    }
                    match (c0, thread_cpu_s()) {
                        (Some(a), Some(b)) => b - a,
                        _ => f64::NAN,
                    }
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("bench thread"))
            .sum()
    });
    (start.elapsed().as_secs_f64(), cpu)
}

fn main() {
    let dir = tempfile::tempdir().expect("temp dir");
    let st = settings();
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "load average at start: {}",
        load.split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    );
    println!("wall = by the clock (shared machine); cpu = per second of thread CPU time");
    let movies: [(&str, Vec<&str>, usize); 3] = [
        ("R 3 mm, H 12 cm", vec!["--drop", "3:12"], 40),
        ("R 7 mm, H 12 cm", vec!["--drop", "7:12"], 40),
        (
            "R 3 mm, H 1.5 cm, 60 000 fps",
            vec![
                "--drop",
                "3:1.5",
                "--fps",
                "60000",
                "--exposure-us",
                "10",
                "--frames-before",
                "200",
                "--frames-after",
                "200",
            ],
            8,
        ),
    ];
    // `-- fixed`: only the fixed cost of the first movie, 200 times (for a
    // profiler); `-- frames`: only the long movie's tracking, 40 times.
    let only = std::env::args()
        .skip(1)
        .find(|a| a == "fixed" || a == "frames" || a == "frames0");
    for (k, (name, args, reps)) in movies.into_iter().enumerate() {
        match only.as_deref() {
            Some("fixed") if k > 0 => break,
            Some("frames") if k < 2 => continue,
            Some("frames0") if k > 0 => break,
            _ => {}
        }
        let m = movie(&args, &dir.path().join(format!("m{k}")));
        if only.as_deref() == Some("fixed") {
            let (wf, cf) = timed(1, 200, || {
                std::hint::black_box(background_and_surface(&mut &m, &st).expect("background"));
            });
            println!(
                "{name}: fixed cost {:.2} ms cpu, {:.2} ms wall",
                5.0 * cf,
                5.0 * wf
            );
            break;
        }
        if only.as_deref().is_some_and(|o| o.starts_with("frames")) {
            let runs: usize = std::env::var("TRACK_RUNS")
                .ok()
                .and_then(|v| v.parse().ok())
                .unwrap_or(40);
            let (w1, c1) = timed(1, runs, || {
                std::hint::black_box(track(&mut &m, &st).expect("track"));
            });
            let f = (runs * m.meta().frame_count) as f64;
            println!("{name}: {:.0} wall / {:.0} cpu frames/s", f / w1, f / c1);
            break;
        }
        let n = m.meta().frame_count;
        // Warm up, and check what is timed.
        let t = track(&mut &m, &st).expect("track");
        let held = t.frames.iter().filter(|f| f.held.is_some()).count();
        let mean_iter = |g: &dyn Fn(&dropscope::track::FrameTrack) -> Option<u32>| {
            let v: Vec<u32> = t.frames.iter().filter_map(|f| g(&f)).collect();
            v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len().max(1) as f64
        };
        let (it_free, it_held) = (
            mean_iter(&|f| f.free.map(|c| c.iterations)),
            mean_iter(&|f| f.held.map(|c| c.iterations)),
        );
        let pts = mean_iter(&|f| f.held.map(|c| c.n_used));
        let flagged = |f: Flag| t.frames.iter().filter(|x| x.flags.contains(f)).count();
        let (partial, missing) = (flagged(Flag::Partial), flagged(Flag::Missing));
        let run = || {
            std::hint::black_box(track(&mut &m, &st).expect("track"));
        };
        let (w1, c1) = timed(1, reps, run);
        let (w2, c2) = timed(2, reps, run);
        let (wf, cf) = timed(1, reps, || {
            std::hint::black_box(background_and_surface(&mut &m, &st).expect("background"));
        });
        let frames = (n * reps) as f64;
        let fixed_ms = 1e3 * cf / reps as f64;
        let per_frame_us = 1e6 * (c1 - cf) / frames;
        println!(
            "{name}: {n} frames (sphere in all, {held} measured with R_px = {:.1} held, {} read twice), R_px {:.1}",
            t.radius_px, t.reread_frames, t.radius_px
        );
        println!(
            "  {pts:.0} edge points a frame; IRLS iterations per fit {it_free:.1} (free), {it_held:.1} (held); {partial} partial, {missing} missing"
        );
        println!(
            "  1 thread : {:>6.0} wall / {:>6.0} cpu frames/s",
            frames / w1,
            frames / c1
        );
        println!(
            "  2 threads: {:>6.0} wall / {:>6.0} cpu frames/s (per core {:.0})",
            2.0 * frames / w2,
            2.0 * 2.0 * frames / c2,
            2.0 * frames / c2
        );
        println!(
            "  fixed cost per run (background from 8 frames, surface): {fixed_ms:.2} ms cpu ({:.2} ms wall); \
             per frame (both passes): {per_frame_us:.1} µs cpu = {:.0} frames/s per core",
            1e3 * wf / reps as f64,
            1e6 / per_frame_us
        );
    }
}
