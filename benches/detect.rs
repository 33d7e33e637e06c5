//! Speed of per-frame detection: sub-pixel edge points + robust circle fit on
//! 512×384 8-bit frames already in memory, 1 and 2 threads.
//!
//!     cargo bench --bench detect
//!
//! Frames: the "realistic" synthetic look (background 200, sphere 40, blur
//! σ = 1 px, noise σ = 2 levels, ±3 % flicker, 10 % vignetting, pillar band
//! at row 330 with a 0.004 tilt), sphere radius 60 and 100 px (3 and 5 mm at
//! 0.05 mm/px), 64 frames each at fractional positions from free flight to
//! contact. The prediction handed to the measurement is the truth moved by
//! up to ±0.5 px (a ballistic prediction); the radius is held (after
//! calibration) or free. Accuracy of the same runs is printed too.
//! `-- profile` runs only the in-cache loop; `-- fit` times the circle fit
//! alone (free, then held), as the tracker runs it per frame.

#[path = "common/mod.rs"]
mod common;
use common::thread_cpu_s;
use dropscope::detect::background::{Background, GainRegion};
use dropscope::detect::circle::Circle;
use dropscope::detect::edges::{measure_circle, EdgeParams, EdgeScratch};
use dropscope::detect::surface::SurfaceLine;
use dropscope::detect::synth::{self, Scene};
use dropscope::detect::Band;
use dropscope::source::Frame;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::time::Instant;

const W: usize = 512;
const H: usize = 384;

fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = rng.gen_range(f64::EPSILON..1.0);
    let u2: f64 = rng.gen();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

struct Case {
    frame: Frame,
    truth: Circle,
    predicted: Circle,
}

fn band() -> synth::PillarBand {
    synth::PillarBand {
        row0_px: 330.0,
        slope: 0.004,
        pillar_level: 60.0,
        channel_level: 90.0,
        period_px: 40.0,
        solid_fraction: 0.625,
    }
}

fn scene(disk: Option<(f64, f64, f64)>) -> Scene {
    Scene {
        width: W,
        height: H,
        background: 200.0,
        vignetting: 0.1,
        sphere_transmission: 0.2,
        disk,
        band: Some(band()),
        blur_px: 1.0,
    }
}

fn make_cases(r: f64, n: usize, rng: &mut ChaCha8Rng) -> Vec<Case> {
    let b = band();
    (0..n)
        .map(|k| {
            let cx = 256.0 + rng.gen_range(-20.0..20.0);
            let surface_z = b.row0_px + b.slope * cx;
            // From a diameter above the surface to 0.2 R into it.
            let cz = surface_z - r - 2.0 * r * (1.0 - k as f64 / n as f64)
                + 0.2 * r * (k as f64 / n as f64);
            let truth = Circle {
                x_px: cx,
                z_px: cz,
                r_px: r,
            };
            let img = scene(Some((cx, cz, r))).render();
            let gain = 1.0 + 0.03 * (2.0 * rng.gen::<f64>() - 1.0);
            let frame = synth::quantize(&img, gain, 255, || 2.0 * gauss(rng));
            let predicted = Circle {
                x_px: cx + rng.gen_range(-0.5..0.5),
                z_px: cz + rng.gen_range(-0.5..0.5),
                r_px: r,
            };
            Case {
                frame,
                truth,
                predicted,
            }
        })
        .collect()
}

fn background(rng: &mut ChaCha8Rng) -> Background {
    let img = scene(None).render();
    let frames: Vec<Frame> = (0..8)
        .map(|_| {
            let gain = 1.0 + 0.03 * (2.0 * rng.gen::<f64>() - 1.0);
            synth::quantize(&img, gain, 255, || 2.0 * gauss(rng))
        })
        .collect();
    let views: Vec<_> = frames.iter().map(|f| f.view()).collect();
    Background::from_frames(&views, GainRegion::default()).expect("background")
}

fn surface() -> SurfaceLine {
    SurfaceLine::given(band().row0_px, band().slope)
}

/// Rates over `rounds` passes through `cases` on `threads` threads:
/// `(frames per wall second, frames per CPU second per thread)`. The second
/// is what a core delivers when it is not shared with other processes.
fn time(
    cases: &[Case],
    bg: &Background,
    params: &EdgeParams,
    hold: bool,
    threads: usize,
    rounds: usize,
) -> (f64, f64) {
    let s = surface();
    let start = Instant::now();
    let cpu: Vec<f64> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                let s = &s;
                scope.spawn(move || {
                    let cpu0 = thread_cpu_s();
                    let mut scratch = EdgeScratch::default();
                    let mut sink = 0.0;
                    for _ in 0..rounds {
                        for c in cases.iter().skip(t).step_by(threads) {
                            let band = Band::frame(&c.frame).expect("band");
                            let hold_r = hold.then_some(c.truth.r_px);
                            if let Ok(f) = measure_circle(
                                &band,
                                bg,
                                &c.predicted,
                                Some(s),
                                hold_r,
                                params,
                                &mut scratch,
                            ) {
                                sink += f.z_px;
                            }
                        }
                    }
                    std::hint::black_box(sink);
                    match (cpu0, thread_cpu_s()) {
                        (Some(a), Some(b)) => b - a,
                        _ => f64::NAN,
                    }
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("bench thread"))
            .collect()
    });
    let frames = (cases.len() * rounds) as f64;
    let wall = frames / start.elapsed().as_secs_f64();
    let per_core = frames / cpu.iter().sum::<f64>();
    (wall, per_core)
}

fn accuracy(cases: &[Case], bg: &Background, params: &EdgeParams, hold: bool) -> String {
    let s = surface();
    let mut scratch = EdgeScratch::default();
    let mut ez = Vec::new();
    let mut covered = 0;
    let mut points = 0;
    let mut iterations = 0;
    for c in cases {
        let band = Band::frame(&c.frame).expect("band");
        let hold_r = hold.then_some(c.truth.r_px);
        match measure_circle(
            &band,
            bg,
            &c.predicted,
            Some(&s),
            hold_r,
            params,
            &mut scratch,
        ) {
            Ok(f) => {
                let e = f.z_px - c.truth.z_px;
                if e.abs() <= 2.0 * f.cov.sigma_z_px() {
                    covered += 1;
                }
                points += f.inliers;
                iterations += f.iterations;
                ez.push(e.abs());
            }
            Err(e) => println!("  fit failed: {e}"),
        }
    }
    ez.sort_by(f64::total_cmp);
    let q = |p: f64| ez[((ez.len() - 1) as f64 * p).round() as usize];
    format!(
        "z error median {:.4} px, 95th {:.4} px, max {:.4} px; |e| ≤ 2σ_z in {:.0} %; {:.0} edge points/frame, {:.1} IRLS iterations/fit",
        q(0.5),
        q(0.95),
        q(1.0),
        100.0 * covered as f64 / ez.len() as f64,
        points as f64 / ez.len() as f64,
        iterations as f64 / ez.len() as f64
    )
}

/// `-- fit`: the circle fit alone, as the tracker runs it per frame — a free
/// fit from a start 0.1 px off, then the held-radius refit at its scale —
/// on 64 sets of 147 points around R = 75 px (noise ±0.05 px, one point in
/// 40 an outlier 2 px out), in cache; best of 30 rounds, µs per frame.
fn fit_only() {
    use dropscope::detect::circle::{fit_circle, FitOptions, FitScratch};
    use dropscope::detect::EdgePoint;
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let sets: Vec<Vec<EdgePoint>> = (0..64)
        .map(|_| {
            (0..147)
                .map(|k| {
                    let a = std::f64::consts::TAU * k as f64 / 157.0;
                    let out = if k % 40 == 7 { 2.0 } else { 0.0 };
                    let r = 75.0 + 0.1 * (rng.gen::<f64>() - 0.5) + out;
                    EdgePoint {
                        x_px: 250.3 + r * a.cos(),
                        z_px: 180.7 + r * a.sin(),
                        weight: 1.0,
                    }
                })
                .collect()
        })
        .collect();
    let start = Circle {
        x_px: 250.35,
        z_px: 180.6,
        r_px: 75.1,
    };
    let mut fs = FitScratch::default();
    let mut best = f64::INFINITY;
    for _ in 0..30 {
        let t = Instant::now();
        for _ in 0..20 {
            for p in &sets {
                let f = fit_circle(p, Some(start), &FitOptions::default(), &mut fs).expect("fit");
                let held = FitOptions {
                    hold_radius: Some(75.0),
                    huber_iterations: 0,
                    scale_px: Some(f.scale_px),
                    ..FitOptions::default()
                };
                std::hint::black_box(
                    fit_circle(p, Some(f.circle()), &held, &mut fs).expect("held"),
                );
            }
        }
        best = best.min(t.elapsed().as_secs_f64() / (20.0 * 64.0));
    }
    println!(
        "fit: free + held fit of 147 points: {:.2} µs per frame (best of 30 rounds, in cache)",
        best * 1e6
    );
}

fn main() {
    if std::env::args().any(|a| a == "fit") {
        fit_only();
        return;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(2024);
    let bg = background(&mut rng);
    // `cargo bench --bench detect -- profile`: only the in-cache loop, for
    // perf stat / perf record.
    if std::env::args().any(|a| a == "profile") {
        let cases = make_cases(60.0, 1, &mut rng);
        for (spacing_px, half_window) in [(2.0, 6), (3.0, 6), (2.0, 5), (3.0, 5)] {
            let params = EdgeParams {
                spacing_px,
                half_window,
                ..EdgeParams::default()
            };
            let (wall, cpu) = time(&cases, &bg, &params, true, 1, 50_000);
            println!("profile: R = 60 px, radius held, spacing {spacing_px} px, window ±{half_window}, one frame in cache: {wall:.0} wall / {cpu:.0} cpu frames/s");
        }
        return;
    }
    println!("wall = frames per elapsed second (the machine may be shared); cpu = frames per second of thread CPU time");
    for r in [60.0, 100.0] {
        let cases = make_cases(r, 64, &mut rng);
        for passes in [1, 2] {
            for hold in [true, false] {
                let params = EdgeParams {
                    passes,
                    ..EdgeParams::default()
                };
                let rounds = 100;
                time(&cases, &bg, &params, hold, 1, 5); // warm-up
                let (hot_wall, hot_cpu) = time(&cases[..1], &bg, &params, hold, 1, rounds * 64);
                let (one_wall, one_cpu) = time(&cases, &bg, &params, hold, 1, rounds);
                let (two_wall, two_cpu) = time(&cases, &bg, &params, hold, 2, rounds);
                println!(
                    "R = {r:>3} px, passes ≤ {passes}, radius {}: 1 thread {one_wall:>6.0} wall / {one_cpu:>6.0} cpu frames/s ({:.1} µs cpu/frame); 2 threads {two_wall:>6.0} wall / {:>6.0} cpu frames/s; one frame in cache {hot_wall:>6.0} wall / {hot_cpu:>6.0} cpu",
                    if hold { "held" } else { "free" },
                    1e6 / one_cpu,
                    2.0 * two_cpu,
                );
                println!("  {}", accuracy(&cases, &bg, &params, hold));
            }
        }
    }
}
