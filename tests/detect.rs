//! Detection against exact truth: anti-aliased synthetic scenes
//! (`dropscope::detect::synth`, exact area coverage) with blur, flicker,
//! vignetting, 8-bit quantisation and seeded Gaussian noise, at many
//! fractional centre positions.
//!
//! The "realistic" look used throughout: background 200 (8-bit), sphere 40,
//! 10 % vignetting, optics blur σ = 1.0 px, noise σ = 2 levels, flicker gain
//! ±3 % per frame, background from 8 sphere-free frames.

use dropscope::detect::background::{Background, GainRegion};
use dropscope::detect::circle::{fit_circle, Circle, FitOptions, FitScratch};
use dropscope::detect::coarse::{detect_coarse, CoarseParams, CoarseScratch};
use dropscope::detect::edges::{measure_circle, EdgeParams, EdgePoint, EdgeScratch};
use dropscope::detect::surface::{fit_surface, SurfaceLine, SurfaceParams};
use dropscope::detect::synth::{self, Scene};
use dropscope::detect::Band;
use dropscope::source::Frame;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The look of a test movie.
#[derive(Clone, Copy)]
struct Look {
    blur_px: f64,
    noise: f64,
    flicker: f64,
}

const REALISTIC: Look = Look {
    blur_px: 1.0,
    noise: 2.0,
    flicker: 0.03,
};

fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    // Box–Muller.
    let u1: f64 = rng.gen_range(f64::EPSILON..1.0);
    let u2: f64 = rng.gen();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

fn scene(
    w: usize,
    h: usize,
    look: Look,
    disk: Option<(f64, f64, f64)>,
    band: Option<synth::Band>,
) -> Scene {
    Scene {
        width: w,
        height: h,
        background: 200.0,
        vignetting: 0.1,
        sphere: 40.0,
        disk,
        band,
        blur_px: look.blur_px,
    }
}

fn shoot(s: &Scene, look: Look, rng: &mut ChaCha8Rng) -> Frame {
    let img = s.render();
    let gain = 1.0 + look.flicker * (2.0 * rng.gen::<f64>() - 1.0);
    let noise = look.noise;
    synth::quantize(&img, gain, 255, || noise * gauss(rng))
}

fn background(s: &Scene, look: Look, rng: &mut ChaCha8Rng) -> Background {
    let empty = Scene {
        disk: None,
        ..s.clone()
    };
    let img = empty.render();
    let frames: Vec<Frame> = (0..8)
        .map(|_| {
            let gain = 1.0 + look.flicker * (2.0 * rng.gen::<f64>() - 1.0);
            synth::quantize(&img, gain, 255, || look.noise * gauss(rng))
        })
        .collect();
    let views: Vec<_> = frames.iter().map(|f| f.view()).collect();
    Background::from_frames(&views, GainRegion::default()).unwrap()
}

fn pillar_band(row0: f64, slope: f64) -> synth::Band {
    synth::Band {
        row0_px: row0,
        slope,
        pillar_level: 60.0,
        channel_level: 90.0,
        period_px: 40.0,
        solid_fraction: 0.625,
    }
}

/// Percentile (0..100) of |values| by sorting.
fn pct_abs(v: &[f64], p: f64) -> f64 {
    let mut a: Vec<f64> = v.iter().map(|x| x.abs()).collect();
    a.sort_by(f64::total_cmp);
    let k = ((p / 100.0) * (a.len() - 1) as f64).round() as usize;
    a[k]
}

struct Trial {
    err_x: f64,
    err_z: f64,
    err_r: f64,
    sigma_z: f64,
    frac_z: f64,
}

/// One measured frame: truth `(cx, cz, r)`, predicted circle off by up to
/// `offset_px` in each coordinate (a coarse detection or a ballistic
/// prediction), optional band and held radius.
#[allow(clippy::too_many_arguments)]
fn trial(
    rng: &mut ChaCha8Rng,
    look: Look,
    size: (usize, usize),
    truth: (f64, f64, f64),
    band: Option<synth::Band>,
    hold: bool,
    dust: usize,
    bg_cache: &mut Option<Background>,
) -> Trial {
    let s = scene(size.0, size.1, look, Some(truth), band);
    if bg_cache.is_none() {
        *bg_cache = Some(background(&s, look, rng));
    }
    let bg = bg_cache.as_ref().unwrap();
    let mut frame = shoot(&s, look, rng);
    // Dust not in the background: dark 2×2 specks on and near the edge.
    for _ in 0..dust {
        let a = rng.gen_range(0.0..std::f64::consts::TAU);
        let d = rng.gen_range(-1.0..3.0);
        let x = (truth.0 + (truth.2 + d) * a.cos()).round() as isize;
        let z = (truth.1 + (truth.2 + d) * a.sin()).round() as isize;
        for (di, dj) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
            let (i, j) = (z + di, x + dj);
            if i >= 0 && j >= 0 && (i as usize) < size.1 && (j as usize) < size.0 {
                frame[[i as usize, j as usize]] = 30;
            }
        }
    }
    let surface = band.map(|b| SurfaceLine {
        row0_px: b.row0_px,
        slope: b.slope,
        cov: [[0.0; 2]; 2],
        residual_px: 0.0,
        n_used: 0,
    });
    let predicted = Circle {
        x_px: truth.0 + rng.gen_range(-1.5..1.5),
        z_px: truth.1 + rng.gen_range(-1.5..1.5),
        r_px: if hold {
            truth.2
        } else {
            truth.2 + rng.gen_range(-1.0..1.0)
        },
    };
    let mut scratch = EdgeScratch::default();
    let band_view = Band::frame(&frame).unwrap();
    let fit = measure_circle(
        &band_view,
        bg,
        &predicted,
        surface.as_ref(),
        hold.then_some(truth.2),
        &EdgeParams::default(),
        &mut scratch,
    )
    .unwrap();
    Trial {
        err_x: fit.x_px - truth.0,
        err_z: fit.z_px - truth.1,
        err_r: fit.r_px - truth.2,
        sigma_z: fit.cov.sigma_z_px(),
        frac_z: truth.1.rem_euclid(1.0),
    }
}

fn summary(name: &str, t: &[Trial]) -> (f64, f64) {
    let ez: Vec<f64> = t.iter().map(|t| t.err_z).collect();
    let ex: Vec<f64> = t.iter().map(|t| t.err_x).collect();
    let er: Vec<f64> = t.iter().map(|t| t.err_r).collect();
    let cover = t
        .iter()
        .filter(|t| t.err_z.abs() <= 2.0 * t.sigma_z)
        .count() as f64
        / t.len() as f64;
    let mean_r = er.iter().sum::<f64>() / er.len() as f64;
    let (m50, m95) = (pct_abs(&ez, 50.0), pct_abs(&ez, 95.0));
    println!(
        "{name}: n={} z median {:.4} 95th {:.4} | x median {:.4} 95th {:.4} | r mean {:+.4} median|e| {:.4} | 2σ_z coverage {:.0} % | mean σ_z {:.4}",
        t.len(),
        m50,
        m95,
        pct_abs(&ex, 50.0),
        pct_abs(&ex, 95.0),
        mean_r,
        pct_abs(&er, 50.0),
        100.0 * cover,
        t.iter().map(|t| t.sigma_z).sum::<f64>() / t.len() as f64,
    );
    (m50, m95)
}

#[test]
fn explore() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for r in [30.0, 60.0, 100.0] {
        let size = (2 * r as usize + 60, 2 * r as usize + 60);
        let mut bg = None;
        let trials: Vec<Trial> = (0..60)
            .map(|_| {
                let c = (
                    size.0 as f64 / 2.0 + rng.gen_range(-3.0..3.0),
                    size.1 as f64 / 2.0 + rng.gen_range(-3.0..3.0),
                    r + rng.gen::<f64>(),
                );
                trial(&mut rng, REALISTIC, size, c, None, false, 0, &mut bg)
            })
            .collect();
        summary(&format!("free R={r}"), &trials);
        // arc only
        let mut bg = None;
        let yline = size.1 as f64 / 2.0 + 0.37;
        let band = pillar_band(yline, 0.004);
        let trials: Vec<Trial> = (0..60)
            .map(|_| {
                let delta = rng.gen_range(0.0..0.3 * r);
                let cx = size.0 as f64 / 2.0 + rng.gen_range(-3.0..3.0);
                let c = (
                    cx,
                    band.row0_px + band.slope * cx - r + delta,
                    r + rng.gen::<f64>(),
                );
                trial(&mut rng, REALISTIC, size, c, Some(band), false, 0, &mut bg)
            })
            .collect();
        summary(&format!("arc R={r}"), &trials);
    }
}
