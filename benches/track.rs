//! Speed of tracking (issue 4, stage 7) and of one drop's whole measurement
//! on 512×384 8-bit frames already in memory, 1 and 2 threads.
//!
//!     cargo bench --bench track
//!
//! Frames: rendered drops (realistic preset, R = 3 and 7 mm, H = 12 cm, 90
//! frames each, the sphere in view in all of them) decoded once into a
//! [`MemorySource`], so file decoding is not timed. Timed: the whole tracker
//! (background from 8 frames, surface line, pass 1 with the radius free
//! through row bands, calibration, pass 2 with the radius held), then the
//! same plus events, kinematics and the force-law fit (`process_run` minus
//! the overlay and file output). Two threads run two drops at once.

use clap::Parser;
use dropscope::config::DetectConfig;
use dropscope::detect::background::{Background, GainRegion};
use dropscope::detect::coarse::CoarseParams;
use dropscope::detect::surface::{fit_surface, SurfaceParams};
use dropscope::source::memory::MemorySource;
use dropscope::source::{open, OpenOptions};
use dropscope::track::{track, TrackSettings};
use std::time::Instant;

#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    args: dropscope::render::RenderArgs,
}

fn movie(radius_mm: f64, dir: &std::path::Path) -> MemorySource {
    let drop = format!("{radius_mm}:12");
    let out = dir.to_str().expect("temp dir is UTF-8");
    let a = Cli::parse_from([
        "render",
        "--drop",
        &drop,
        "--preset",
        "realistic",
        "--seed",
        "5",
        "--out",
        out,
    ])
    .args;
    let report = dropscope::render::render(&a).expect("render");
    let mut src = open(&report.drops[0].dir, &OpenOptions::default()).expect("open");
    MemorySource::load(src.as_mut()).expect("load")
}

fn settings() -> TrackSettings {
    TrackSettings::from_config(&DetectConfig {
        background_frames: 8,
        surface_row_px: None,
        surface_slope: 0.0,
        contact_margin_px: 2.0,
        edge_half_window_px: 6,
        edge_spacing_px: 3.0,
    })
}

fn main() {
    let dir = tempfile::tempdir().expect("temp dir");
    let st = settings();
    for r in [3.0, 7.0] {
        let m = movie(r, &dir.path().join(format!("r{r}")));
        let n = m.meta().frame_count;
        use dropscope::source::FrameSource;
        // One copy of the movie per thread, made before timing; warm up.
        let (mut a, mut b) = (m.clone(), m);
        track(&mut a, &st).expect("track");
        let reps = 20;
        let t0 = Instant::now();
        for _ in 0..reps {
            track(&mut a, &st).expect("track");
        }
        let one = (n * reps) as f64 / t0.elapsed().as_secs_f64();
        let t0 = Instant::now();
        rayon::join(
            || (0..reps).for_each(|_| drop(track(&mut a, &st))),
            || (0..reps).for_each(|_| drop(track(&mut b, &st))),
        );
        let two = (2 * n * reps) as f64 / t0.elapsed().as_secs_f64();
        // The fixed cost per run: the background (8 frames) and the surface.
        let t0 = Instant::now();
        for _ in 0..reps {
            let views: Vec<_> = (0..8).map(|i| a.frame(i * (n - 1) / 7).view()).collect();
            let bg = Background::from_frames_with_sphere(
                &views,
                GainRegion::default(),
                &CoarseParams::default(),
                6.0,
            )
            .expect("background");
            drop(fit_surface(&bg, &SurfaceParams::default()));
        }
        let fixed_s = t0.elapsed().as_secs_f64() / reps as f64;
        let per_frame_s = (n as f64 / one - fixed_s) / n as f64;
        println!(
            "R = {r} mm ({n} frames, R_px ≈ {:.0}): {one:.0} frames/s on 1 thread, {two:.0} on 2 threads; \
             fixed cost per run {:.1} ms (background, surface), then {:.0} frames/s per thread (two passes)",
            r / (0.04 + 0.01 * (r - 3.0)),
            fixed_s * 1e3,
            1.0 / per_frame_s
        );
    }
}
