//! Why the coarse detector labels its own connected components instead of
//! calling `imageproc`: times `detect_coarse` whole
//! (threshold against the background, largest 4-connected group, outline,
//! robust circle fit) against `imageproc`'s thresholding plus
//! `connected_components` alone on the same 512 × 384 8-bit frame, which
//! is only the first half of what an imageproc-based detector would do.
//!
//!     cargo run --release --example coarse_vs_imageproc
//!
//! Prints the median time per frame over 5 rounds of 500 frames each.

use dropscope::detect::background::{Background, GainRegion};
use dropscope::detect::coarse::{detect_coarse, CoarseParams, CoarseScratch};
use dropscope::detect::surface::{fit_surface, SurfaceParams};
use dropscope::detect::synth::{self, PillarBand, Scene};
use dropscope::detect::Band;
use image::{GrayImage, Luma};
use imageproc::region_labelling::{connected_components, Connectivity};
use std::time::Instant;

fn median_us(mut f: impl FnMut()) -> f64 {
    let mut rounds: Vec<f64> = (0..5)
        .map(|_| {
            let t = Instant::now();
            for _ in 0..500 {
                f();
            }
            t.elapsed().as_secs_f64() / 500.0 * 1e6
        })
        .collect();
    rounds.sort_by(f64::total_cmp);
    rounds[2]
}

fn main() {
    let band = PillarBand {
        row0_px: 300.2,
        slope: 0.0,
        pillar_level: 60.0,
        channel_level: 90.0,
        period_px: 40.0,
        solid_fraction: 0.625,
    };
    let scene = Scene {
        width: 512,
        height: 384,
        background: 200.0,
        vignetting: 0.1,
        sphere_transmission: 0.2,
        disk: Some((250.3, 180.7, 70.2)),
        band: Some(band),
        blur_px: 1.0,
    };
    let empty = Scene {
        disk: None,
        ..scene.clone()
    };
    let bg_frames: Vec<_> = (0..8)
        .map(|_| synth::quantize(&empty.render(), 1.0, 255, || 0.0))
        .collect();
    let views: Vec<_> = bg_frames.iter().map(|f| f.view()).collect();
    let bg = Background::from_frames(&views, GainRegion::default()).expect("background");
    let surface = fit_surface(&bg, &SurfaceParams::default()).expect("surface");
    let frame = synth::quantize(&scene.render(), 1.0, 255, || 0.0);
    let b = Band::frame(&frame).expect("band");
    let gain = bg.gain(&b).expect("gain").gain;
    let params = CoarseParams::default();
    let mut scratch = CoarseScratch::default();
    let ours = median_us(|| {
        let c = detect_coarse(&b, &bg, gain, Some(&surface), &params, &mut scratch);
        std::hint::black_box(c.expect("detect").expect("found"));
    });
    // imageproc: the same threshold (70 % of the background, here its
    // level 200) into a mask, then its labelling (4-connected).
    let (h, w) = frame.dim();
    let cut = (0.7 * 200.0) as u16;
    let theirs = median_us(|| {
        let mask = GrayImage::from_fn(w as u32, h as u32, |x, y| {
            Luma([u8::from(frame[[y as usize, x as usize]] < cut) * 255])
        });
        std::hint::black_box(connected_components(&mask, Connectivity::Four, Luma([0u8])));
    });
    println!(
        "detect_coarse whole: {ours:.1} us/frame; imageproc threshold + connected_components \
         alone: {theirs:.1} us/frame ({:.1}x)",
        theirs / ours
    );
}
