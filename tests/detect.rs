//! Detection against exact truth: anti-aliased synthetic scenes
//! (`dropscope::detect::synth`, exact area coverage) with blur, flicker,
//! vignetting, 8-bit quantisation and seeded Gaussian noise, at many
//! fractional centre positions.
//!
//! The "realistic" look used throughout: background 200 (8-bit), sphere
//! transmission 0.2, 10 % vignetting, optics blur σ = 1.0 px, noise σ = 2
//! levels, flicker gain ±3 % per frame, background from 8 sphere-free
//! frames; the prediction handed to the measurement is the truth moved by up
//! to ±1.5 px in each coordinate (and ±1 px in radius).
//!
//! Tolerances: the accuracy tests assert the detector's targets (centre row
//! median ≤ 0.02 px and 95th percentile ≤ 0.06 px in free flight, 0.03 /
//! 0.08 px on the arc above the surface, R error ≤ 0.02 px, |e| ≤ 2σ in
//! ≥ 90 % of frames). Measured values are 3–5× better (docs/accuracy.md), so
//! a failure means a real regression, not an unlucky seed.

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
    /// 8 or 12; the background is 200 (8-bit) or 3200 (12-bit).
    bits: u8,
}

const REALISTIC: Look = Look {
    blur_px: 1.0,
    noise: 2.0,
    flicker: 0.03,
    bits: 8,
};

fn max_level(look: Look) -> u16 {
    ((1u32 << look.bits) - 1) as u16
}

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
    band: Option<synth::PillarBand>,
) -> Scene {
    Scene {
        width: w,
        height: h,
        background: if look.bits == 8 { 200.0 } else { 3200.0 },
        vignetting: 0.1,
        sphere_transmission: 0.2,
        disk,
        band,
        blur_px: look.blur_px,
    }
}

fn shoot(s: &Scene, look: Look, rng: &mut ChaCha8Rng) -> Frame {
    let img = s.render();
    let gain = 1.0 + look.flicker * (2.0 * rng.gen::<f64>() - 1.0);
    let noise = look.noise;
    synth::quantize(&img, gain, max_level(look), || noise * gauss(rng))
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
            synth::quantize(&img, gain, max_level(look), || look.noise * gauss(rng))
        })
        .collect();
    let views: Vec<_> = frames.iter().map(|f| f.view()).collect();
    Background::from_frames(&views, GainRegion::default()).unwrap()
}

fn pillar_band(row0: f64, slope: f64) -> synth::PillarBand {
    synth::PillarBand {
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
    band: Option<synth::PillarBand>,
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
    let surface = band.map(|b| SurfaceLine::given(b.row0_px, b.slope));
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

fn run_trials(
    seed: u64,
    radii: &[f64],
    per_radius: usize,
    contact: bool,
    hold: bool,
    dust: usize,
) -> Vec<Trial> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::new();
    for &r in radii {
        let size = (2 * r as usize + 60, 2 * r as usize + 60);
        let mut bg = None;
        let band = contact.then(|| pillar_band(size.1 as f64 / 2.0 + 0.37, 0.004));
        for _ in 0..per_radius {
            let cx = size.0 as f64 / 2.0 + rng.gen_range(-3.0..3.0);
            let r_true = r + rng.gen::<f64>();
            let cz = match band {
                // Lowest point from on the line to 0.3 R below it.
                Some(b) => b.row0_px + b.slope * cx - r_true + rng.gen_range(0.0..0.3 * r),
                None => size.1 as f64 / 2.0 + rng.gen_range(-3.0..3.0),
            };
            out.push(trial(
                &mut rng,
                REALISTIC,
                size,
                (cx, cz, r_true),
                band,
                hold,
                dust,
                &mut bg,
            ));
        }
    }
    out
}

#[test]
fn free_flight_centre_and_radius_meet_the_issue_targets() {
    let t = run_trials(11, &[30.0, 60.0, 100.0], 40, false, false, 0);
    let (m50, m95) = summary("free flight, radius free", &t);
    assert!(
        m50 <= 0.02 && m95 <= 0.06,
        "centre row median {m50}, 95th {m95}"
    );
    let ex: Vec<f64> = t.iter().map(|t| t.err_x).collect();
    assert!(pct_abs(&ex, 50.0) <= 0.02 && pct_abs(&ex, 95.0) <= 0.06);
    // Radius: mean over frames (the calibration averages many frames) and
    // the single-frame 95th percentile.
    let er: Vec<f64> = t.iter().map(|t| t.err_r).collect();
    let mean_r = er.iter().sum::<f64>() / er.len() as f64;
    assert!(mean_r.abs() <= 0.02, "mean R error {mean_r}");
    assert!(
        pct_abs(&er, 95.0) <= 0.06,
        "R error 95th {}",
        pct_abs(&er, 95.0)
    );
}

#[test]
fn arc_above_the_surface_meets_the_contact_targets() {
    for hold in [false, true] {
        let t = run_trials(12 + hold as u64, &[30.0, 60.0, 100.0], 40, true, hold, 0);
        let (m50, m95) = summary(&format!("arc only, radius held {hold}"), &t);
        assert!(
            m50 <= 0.03 && m95 <= 0.08,
            "hold {hold}: median {m50}, 95th {m95}"
        );
    }
}

#[test]
fn dust_on_the_edge_is_rejected() {
    // Eight dark 2×2 specks per frame on or just outside the edge, not in
    // the background (dust moving with the air). Without rejection each
    // would pull its edge point by up to ~1 px.
    let t = run_trials(13, &[40.0, 80.0], 40, false, false, 8);
    let (m50, m95) = summary("free flight with dust", &t);
    assert!(m50 <= 0.02 && m95 <= 0.06, "median {m50}, 95th {m95}");
}

#[test]
fn centre_uncertainty_is_honest() {
    let mut t = run_trials(14, &[30.0, 60.0, 100.0], 30, false, false, 0);
    t.extend(run_trials(15, &[30.0, 60.0, 100.0], 30, true, true, 0));
    let covered = t
        .iter()
        .filter(|t| t.err_z.abs() <= 2.0 * t.sigma_z)
        .count();
    let frac = covered as f64 / t.len() as f64;
    println!(
        "|e_z| ≤ 2σ_z in {:.1} % of {} frames",
        100.0 * frac,
        t.len()
    );
    // ≥ 90 % (a Gaussian gives 95.4 %) — the coverage target; and σ
    // neither understated nor inflated: the rms of e/σ within [0.7, 1.4]
    // (measured ≈ 1.0).
    assert!(frac >= 0.90, "{frac}");
    let rms =
        (t.iter().map(|t| (t.err_z / t.sigma_z).powi(2)).sum::<f64>() / t.len() as f64).sqrt();
    println!("rms of e_z/σ_z: {rms:.2}");
    assert!((0.7..=1.4).contains(&rms), "rms of e/σ = {rms}");
}

#[test]
fn no_pixel_locking_across_fractional_positions() {
    // 12-bit, noiseless, light blur (the worst case for locking: sharp
    // edges and no noise to dither them); 200 centres stepping through a
    // pixel in z (and an incommensurate step in x). The mean error in each
    // of 10 bins of the fractional row must stay within 0.005 px (a quarter
    // of the median target); measured ≤ 0.002.
    let look = Look {
        blur_px: 0.6,
        noise: 0.0,
        flicker: 0.0,
        bits: 12,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(16);
    let mut bg = None;
    let mut bins = [(0.0, 0usize); 10];
    let mut bins_x = [(0.0, 0usize); 10];
    for k in 0..200 {
        let c = (70.0 + 0.0137 * k as f64, 65.0 + 0.005 * k as f64, 40.123);
        let t = trial(&mut rng, look, (140, 140), c, None, false, 0, &mut bg);
        let b = ((t.frac_z * 10.0) as usize).min(9);
        bins[b].0 += t.err_z;
        bins[b].1 += 1;
        let bx = ((c.0.rem_euclid(1.0) * 10.0) as usize).min(9);
        bins_x[bx].0 += t.err_x;
        bins_x[bx].1 += 1;
    }
    for (name, bins) in [("z", bins), ("x", bins_x)] {
        let means: Vec<f64> = bins.iter().map(|(s, n)| s / (*n).max(1) as f64).collect();
        println!("{name} bin means: {means:+.4?}");
        assert!(bins.iter().all(|(_, n)| *n > 0));
        assert!(means.iter().all(|m| m.abs() <= 0.005), "{name}: {means:?}");
    }
}

#[test]
fn no_curved_edge_bias_under_heavy_blur() {
    // Blur σ = 2 px on a small disk (R = 25 px): the ½-level contour and the
    // gradient peak sit σ_eff²/2R ≈ 0.08 px inside the true edge. The radial
    // area estimator must stay within 0.01 px (measured ≈ 0.002).
    let look = Look {
        blur_px: 2.0,
        noise: 0.0,
        flicker: 0.0,
        bits: 12,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let mut bg = None;
    let mut sum = 0.0;
    for k in 0..20 {
        let c = (50.0 + 0.07 * k as f64, 50.0 + 0.031 * k as f64, 25.0);
        let t = trial(&mut rng, look, (100, 100), c, None, false, 0, &mut bg);
        sum += t.err_r;
        assert!(t.err_z.abs() < 0.005 && t.err_x.abs() < 0.005);
    }
    let mean = sum / 20.0;
    assert!(mean.abs() <= 0.01, "mean radius error {mean}");
}

#[test]
fn surface_line_with_tilt_is_found_to_003_px() {
    for (row0, slope) in [(280.37, 0.0), (271.81, 0.012), (300.05, -0.0075)] {
        let mut rng = ChaCha8Rng::seed_from_u64(18);
        let s = scene(512, 384, REALISTIC, None, Some(pillar_band(row0, slope)));
        let bg = background(&s, REALISTIC, &mut rng);
        let line = fit_surface(&bg, &SurfaceParams::default()).unwrap();
        for x in [0.0, 256.0, 511.0] {
            let err = line.row_at(x) - (row0 + slope * x);
            println!(
                "surface ({row0}, {slope}) at column {x}: error {err:+.4} px, σ {:.4} px, {} columns",
                line.sigma_row_at(x),
                line.n_used
            );
            // 0.03 px: the target for the surface row.
            assert!(err.abs() <= 0.03, "{err}");
        }
        assert!(
            (line.slope - slope).abs() <= 1e-4,
            "slope {} vs {slope}",
            line.slope
        );
    }
}

#[test]
fn coarse_detection_finds_a_sphere_entering_through_the_top() {
    let mut rng = ChaCha8Rng::seed_from_u64(19);
    let truth = (250.3, -22.6, 60.4); // only the lowest 38 px are in the frame
    let s = scene(
        512,
        384,
        REALISTIC,
        Some(truth),
        Some(pillar_band(300.2, 0.0)),
    );
    let bg = background(&s, REALISTIC, &mut rng);
    let frame = shoot(&s, REALISTIC, &mut rng);
    let band = Band::frame(&frame).unwrap();
    let gain = bg.gain(&band).unwrap().gain;
    let surface = fit_surface(&bg, &SurfaceParams::default()).unwrap();
    let mut scratch = CoarseScratch::default();
    let c = detect_coarse(
        &band,
        &bg,
        gain,
        Some(&surface),
        &CoarseParams::default(),
        &mut scratch,
    )
    .unwrap()
    .expect("the sphere is in the frame");
    assert!(c.touches_top);
    // Coarse: within 1 px (it only has to put the normals' windows on the edge).
    assert!((c.circle.x_px - truth.0).abs() < 1.0, "{c:?}");
    assert!((c.circle.z_px - truth.1).abs() < 1.0, "{c:?}");
    assert!((c.circle.r_px - truth.2).abs() < 1.0, "{c:?}");
    let mut es = EdgeScratch::default();
    let fit = measure_circle(
        &band,
        &bg,
        &c.circle,
        Some(&surface),
        None,
        &EdgeParams::default(),
        &mut es,
    )
    .unwrap();
    // A 100° arc only: the arc-only tolerance (0.08 px, the 95th percentile target).
    assert!((fit.z_px - truth.1).abs() < 0.08, "{fit:?}");
    assert!((fit.r_px - truth.2).abs() < 0.08, "{fit:?}");
}

#[test]
fn coarse_detection_sees_nothing_in_an_empty_frame_and_finds_a_sphere_in_contact() {
    let mut rng = ChaCha8Rng::seed_from_u64(20);
    let band_look = pillar_band(300.2, 0.003);
    let empty = scene(512, 384, REALISTIC, None, Some(band_look));
    let bg = background(&empty, REALISTIC, &mut rng);
    let surface = fit_surface(&bg, &SurfaceParams::default()).unwrap();
    let mut scratch = CoarseScratch::default();
    let frame = shoot(&empty, REALISTIC, &mut rng);
    let band = Band::frame(&frame).unwrap();
    let gain = bg.gain(&band).unwrap().gain;
    let none = detect_coarse(
        &band,
        &bg,
        gain,
        Some(&surface),
        &CoarseParams::default(),
        &mut scratch,
    )
    .unwrap();
    assert!(none.is_none(), "{none:?}");
    // In contact: the lowest 12 px hidden in the pillar band.
    let truth = (240.7, 300.2 + 0.003 * 240.7 - 70.0 + 12.0, 70.0);
    let s = scene(512, 384, REALISTIC, Some(truth), Some(band_look));
    let frame = shoot(&s, REALISTIC, &mut rng);
    let band = Band::frame(&frame).unwrap();
    let gain = bg.gain(&band).unwrap().gain;
    let c = detect_coarse(
        &band,
        &bg,
        gain,
        Some(&surface),
        &CoarseParams::default(),
        &mut scratch,
    )
    .unwrap()
    .expect("sphere");
    assert!(!c.touches_top);
    assert!(
        (c.circle.z_px - truth.1).abs() < 1.0 && (c.circle.r_px - truth.2).abs() < 1.0,
        "{c:?}"
    );
}

#[test]
fn robust_fit_rejects_a_mirror_image_arc() {
    // A glossy surface mirrors the sphere: an arc of a circle reflected about
    // the surface line, 25 % as many points as the real arc. The robust fit
    // must ignore it (weights 0) and recover the circle from the real points.
    let c = Circle {
        x_px: 200.3,
        z_px: 150.7,
        r_px: 70.2,
    };
    let surface_z = 150.7 + 70.2 - 10.0;
    let mut pts = Vec::new();
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    for k in 0..120 {
        let a = std::f64::consts::PI * (1.0 + k as f64 / 120.0); // upper half
        pts.push(EdgePoint {
            x_px: c.x_px + c.r_px * a.cos() + 0.02 * gauss(&mut rng),
            z_px: c.z_px + c.r_px * a.sin() + 0.02 * gauss(&mut rng),
            weight: 1.0,
        });
    }
    for k in 0..30 {
        let a = 0.35 + 2.4 * k as f64 / 30.0; // lower arc, mirrored
        let z = c.z_px + c.r_px * a.sin();
        pts.push(EdgePoint {
            x_px: c.x_px + c.r_px * a.cos(),
            z_px: 2.0 * surface_z - z,
            weight: 1.0,
        });
    }
    let mut s = FitScratch::default();
    let f = fit_circle(&pts, None, &FitOptions::default(), &mut s).unwrap();
    assert!(
        (f.z_px - c.z_px).abs() < 0.02 && (f.x_px - c.x_px).abs() < 0.02,
        "{f:?}"
    );
    // Where the mirrored arc crosses the true circle a mirror point lies on
    // it and is rightly kept; every other mirror point gets weight 0.
    for (p, &w) in pts[120..].iter().zip(&s.weights[120..]) {
        let d = (p.x_px - c.x_px).hypot(p.z_px - c.z_px) - c.r_px;
        assert!(
            w == 0.0 || d.abs() < 0.1,
            "mirror point {p:?} kept with weight {w}"
        );
    }
}

/// A slow drop for the background tests: the sphere (R 75 px) at column
/// `x_px` moves 40 px down over 24 frames of 512 × 384, so its path's core
/// is covered in every frame; each frame's pixel at column `j` is scaled by
/// `light(k, j)` (frame `k`). The sphere-free light and the background
/// built from the frames.
fn background_of_a_slow_drop(
    x_px: f64,
    seed: u64,
    light: impl Fn(usize, usize) -> f64,
) -> (ndarray::Array2<f64>, Background) {
    background_of_a_slow_glinting_drop(x_px, seed, (0.2, 0.0), 24, light)
}

/// [`background_of_a_slow_drop`] over `frames` frames, the sphere of
/// transmission `look.0` showing the full light (a polished ball's
/// specular reflection of the backlight) within `0.6 look.1` of its centre
/// and in three pixels of ten, speckled, out to `look.1`.
fn background_of_a_slow_glinting_drop(
    x_px: f64,
    seed: u64,
    (transmission, glint_px): (f64, f64),
    frames: usize,
    light: impl Fn(usize, usize) -> f64,
) -> (ndarray::Array2<f64>, Background) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let band = pillar_band(300.4, 0.002);
    let truth = scene(512, 384, REALISTIC, None, Some(band)).render();
    let n = frames;
    let frames: Vec<Frame> = (0..n)
        .map(|k| {
            let centre = (x_px, 150.0 + 40.0 * k as f64 / (n - 1) as f64, 75.0);
            let s = Scene {
                sphere_transmission: transmission,
                ..scene(512, 384, REALISTIC, Some(centre), Some(band))
            };
            let mut img = s.render();
            for ((i, j), v) in img.indexed_iter_mut() {
                let d = (j as f64 - centre.0).hypot(i as f64 - centre.1);
                let speckle = (i * 7919 + j * 104_729 + k * 31) % 10 < 3;
                if d < 0.6 * glint_px || (d < glint_px && speckle) {
                    *v = truth[[i, j]];
                }
            }
            let gain = 1.0 + REALISTIC.flicker * (2.0 * rng.gen::<f64>() - 1.0);
            let noise = REALISTIC.noise;
            let mut f =
                synth::quantize(&img, gain, max_level(REALISTIC), || noise * gauss(&mut rng));
            for ((_, j), v) in f.indexed_iter_mut() {
                *v = (*v as f64 * light(k, j)).round().min(u16::MAX as f64) as u16;
            }
            f
        })
        .collect();
    let views: Vec<_> = frames.iter().map(|f| f.view()).collect();
    let bg = Background::from_frames_with_sphere(
        &views,
        GainRegion::default(),
        &CoarseParams::default(),
        6.0,
    )
    .unwrap();
    (truth, bg)
}

/// The background's relative error against the light, one value per degree
/// on the circle of radius `r_px` about `(x_px, z_px)`, above the band and
/// inside `columns`. The gains are relative to frame 0: the shapes are
/// compared, not the levels (the ratio of the means over the sphere-free
/// block of rows 0..40 and `block` columns).
fn ring_errors(
    truth: &ndarray::Array2<f64>,
    bg: &Background,
    (x_px, z_px, r_px): (f64, f64, f64),
    block: std::ops::Range<usize>,
    columns: std::ops::Range<usize>,
) -> Vec<f64> {
    let (mut st, mut sb) = (0.0, 0.0);
    for i in 0..40 {
        for j in block.clone() {
            st += truth[[i, j]];
            sb += bg.at(i, j) as f64;
        }
    }
    let k = st / sb;
    (0..360)
        .filter_map(|a| {
            let t = (a as f64).to_radians();
            let (x, z) = (x_px + r_px * t.cos(), z_px + r_px * t.sin());
            let (i, j) = (z.round() as usize, x.round() as usize);
            (z < 296.0 && columns.contains(&j))
                .then(|| (bg.at(i, j) as f64 * k - truth[[i, j]]) / truth[[i, j]])
        })
        .collect()
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

#[test]
fn background_is_recovered_when_the_sphere_is_in_every_frame() {
    // Against the exact sphere-free light, the background must be right to
    // 1 % around the sphere's edges (where edge profiles take their zero) —
    // noise σ 2 on 200 gives ~0.5 % per frame, and the median of the
    // uncovered frames or the quadratic fill does better.
    let (truth, bg) = background_of_a_slow_drop(250.3, 22, |_, _| 1.0);
    for zc in [150.0, 190.0] {
        for dr in [-6.0, 0.0, 6.0] {
            let rel = ring_errors(&truth, &bg, (250.3, zc, 75.0 + dr), 0..40, 0..512);
            let mean = mean(&rel);
            let rms = (rel.iter().map(|v| v * v).sum::<f64>() / rel.len() as f64).sqrt();
            println!("ring centre {zc} radius 75{dr:+}: mean {mean:+.4}, rms {rms:.4}");
            // Systematic part (what biases edges): ≤ 0.3 %. Scatter: one
            // frame's noise is 1 %, a median of several less.
            assert!(
                mean.abs() <= 0.003 && rms <= 0.012,
                "mean {mean}, rms {rms}"
            );
        }
    }
}

/// The background's ring errors around the slow drop's first and last
/// positions within the bounds of
/// [`background_is_recovered_when_the_sphere_is_in_every_frame`].
fn assert_rings_within_bounds(truth: &ndarray::Array2<f64>, bg: &Background) {
    for zc in [150.0, 190.0] {
        for dr in [-6.0, 0.0, 6.0] {
            let rel = ring_errors(truth, bg, (250.3, zc, 75.0 + dr), 0..40, 0..512);
            let mean = mean(&rel);
            let rms = (rel.iter().map(|v| v * v).sum::<f64>() / rel.len() as f64).sqrt();
            println!("ring centre {zc} radius 75{dr:+}: mean {mean:+.4}, rms {rms:.4}");
            assert!(
                mean.abs() <= 0.003 && rms <= 0.012,
                "ring {zc} {dr}: mean {mean}, rms {rms}"
            );
        }
    }
}

#[test]
fn background_is_recovered_when_the_sphere_in_every_frame_has_a_speckled_glint() {
    // A polished ball shows the backlight in its middle, ragged at the
    // rim of the reflection: its dark pixels are a ring around many holes.
    // The holes' outlines are not the sphere's edge and must not pull the
    // circles that mask the sphere out of the background (they came out
    // 49 px in radius instead of 75, and the sphere's own edges stayed in
    // the background: 45 % off on the ring inside the edge). Eight
    // frames, as the tracker samples.
    let (truth, bg) = background_of_a_slow_glinting_drop(250.3, 24, (0.2, 25.0), 8, |_, _| 1.0);
    assert_rings_within_bounds(&truth, &bg);
}

#[test]
fn background_is_recovered_when_a_pale_sphere_is_in_every_frame() {
    // A sphere showing 40 % of the light (a polished ball reflecting its
    // surroundings), in view in every sample frame and moving less than
    // its diameter: the pixels no sample shows bare are bordered by a ring
    // that only the sphere's blurred edge uncovers. Taken for the light,
    // that ring made the coarse background half the light inside the
    // path, the pale sphere was not dark against it, and its mask came out
    // 9 px small in the first frame (28 % off inside the edge).
    let (truth, bg) = background_of_a_slow_glinting_drop(250.3, 24, (0.4, 0.0), 8, |_, _| 1.0);
    assert_rings_within_bounds(&truth, &bg);
}

/// A backlight that drifts differently on the left and on the right of the
/// frame (the real preset's slow drift, here 5 % and −2 % over the movie).
/// The sphere hides each pixel of its path in different frames, so with
/// one gain per frame each pixel's median mixes different frames' lights:
/// a step in the background along the path, which moves the edges (a
/// 2–3e-4 error of v_impact on the real preset). With the gain per column,
/// linear between the two reference strips, the background around the
/// sphere is the light's shape to the same 0.3 % as without drift (it was
/// 0.42 % off on the inner ring at the top).
#[test]
fn a_light_drifting_differently_on_the_two_sides_leaves_no_step_in_the_background() {
    let x = 130.3;
    let (truth, bg) = background_of_a_slow_drop(x, 23, |k, j| {
        let (left, right) = (0.05 * k as f64 / 23.0, -0.02 * k as f64 / 23.0);
        let u = j as f64 / 511.0;
        1.0 + (1.0 - u) * left + u * right
    });
    for zc in [150.0, 190.0] {
        for dr in [-6.0, 0.0, 6.0] {
            // Frame 0 has no drift: its light is the reference.
            let rel = ring_errors(&truth, &bg, (x, zc, 75.0 + dr), 20..60, 20..492);
            let (lower, upper) = rel.split_at(rel.len() / 2);
            let (mean, lower, upper) = (mean(&rel), mean(lower), mean(upper));
            println!("ring centre {zc} radius 75{dr:+}: mean {mean:+.4}, lower half {lower:+.4}, upper half {upper:+.4}");
            assert!(mean.abs() <= 0.003, "ring {zc} {dr}: mean {mean}");
            assert!(
                (lower - upper).abs() <= 0.003,
                "ring {zc} {dr}: halves {lower} {upper}"
            );
        }
    }
}

#[test]
fn rendered_drop_meets_the_issue_targets() {
    // A drop from `dropscope render` (the realistic preset: 8-bit, light
    // gradient, blur σ 0.7 px, motion blur, shot and read noise, flicker,
    // static dust), everything found from the images: background with the
    // sphere in view from the first frame, surface line, coarse circle,
    // per-frame sub-pixel circle, R_px from the full-circle frames, then
    // the centre with R_px held. The tolerances below are the detector's
    // accuracy targets.
    let dir = tempfile::tempdir().unwrap();
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_dropscope"))
        .args([
            "render",
            "--drop",
            "4:8",
            "--preset",
            "realistic",
            "--format",
            "png",
        ])
        .args([
            "--width-px",
            "384",
            "--height-px",
            "288",
            "--restitution",
            "0.9",
            "--seed",
            "7",
        ])
        .arg("--out")
        .arg(dir.path())
        .status()
        .unwrap();
    assert!(status.success());
    let run_dir = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.join("truth.json").exists())
        .expect("a run folder");
    let truth: dropscope::render::truth::Truth =
        serde_json::from_slice(&std::fs::read(run_dir.join("truth.json")).unwrap()).unwrap();
    let frames: Vec<Frame> = truth
        .frames
        .iter()
        .map(|f| {
            let name = dropscope::render::export::frame_file_name(
                &truth.run,
                f.frame,
                dropscope::render::export::FrameFormat::Png,
            );
            let img = image::open(run_dir.join(name)).unwrap().to_luma8();
            let (w, h) = (img.width() as usize, img.height() as usize);
            Frame::from_shape_vec((h, w), img.into_raw().into_iter().map(u16::from).collect())
                .unwrap()
        })
        .collect();
    let views: Vec<_> = frames.iter().map(|f| f.view()).collect();
    let coarse = CoarseParams::default();
    let bg =
        Background::from_frames_with_sphere(&views, GainRegion::default(), &coarse, 6.0).unwrap();
    let surface = fit_surface(&bg, &SurfaceParams::default()).unwrap();
    let xi = truth.impact_column_px;
    let s_err = surface.row_at(xi) - (truth.surface_row_px + truth.surface_slope * xi);
    // Surface row at the impact column: the 0.03 px target (measured ~0.002).
    assert!(s_err.abs() <= 0.03, "surface error {s_err}");

    let params = EdgeParams::default();
    let mut es = EdgeScratch::default();
    let mut cs = CoarseScratch::default();
    let mut fits = Vec::new();
    let mut prev: Option<Circle> = None;
    for f in &frames {
        let band = Band::frame(f).unwrap();
        let predicted = prev.or_else(|| {
            let g = bg.gain(&band).unwrap().gain;
            detect_coarse(&band, &bg, g, Some(&surface), &coarse, &mut cs)
                .unwrap()
                .map(|c| c.circle)
        });
        let fit = predicted.and_then(|p| {
            measure_circle(&band, &bg, &p, Some(&surface), None, &params, &mut es).ok()
        });
        prev = fit.map(|f| f.circle());
        fits.push(fit);
    }
    let free: Vec<_> = fits.iter().flatten().copied().collect();
    let (h, w) = frames[0].dim();
    let cal =
        dropscope::detect::calibrate::calibrate_radius(&free, w, h, Some(&surface), &params, 5)
            .expect("at least 5 full-circle frames");
    let r_px = cal.r_px;
    // R_px: the 0.02 px target (measured ~0.001).
    assert!(
        (r_px - truth.radius_px).abs() <= 0.02,
        "R_px {r_px} vs {}",
        truth.radius_px
    );

    let (mut free, mut contact, mut covered, mut n) = (Vec::new(), Vec::new(), 0, 0);
    for ((f, fit1), t) in frames.iter().zip(&fits).zip(&truth.frames) {
        let fit1 = fit1.expect("every frame measured");
        let band = Band::frame(f).unwrap();
        let fit = measure_circle(
            &band,
            &bg,
            &fit1.circle(),
            Some(&surface),
            Some(r_px),
            &params,
            &mut es,
        )
        .unwrap();
        let e = fit.z_px - t.z_px;
        n += 1;
        if e.abs() <= 2.0 * fit.cov.sigma_z_px() {
            covered += 1;
        }
        if t.in_contact {
            contact.push(e);
        } else {
            free.push(e);
        }
    }
    let (f50, f95) = (pct_abs(&free, 50.0), pct_abs(&free, 95.0));
    let (c50, c95) = (pct_abs(&contact, 50.0), pct_abs(&contact, 95.0));
    let cover = covered as f64 / n as f64;
    println!(
        "rendered R 4 mm H 8 cm: free flight z median {f50:.4} 95th {f95:.4} ({} frames); contact z median {c50:.4} 95th {c95:.4} ({} frames); R_px error {:+.4}; surface {:+.4}; 2σ coverage {:.1} %",
        free.len(),
        contact.len(),
        r_px - truth.radius_px,
        s_err,
        100.0 * cover
    );
    assert!(f50 <= 0.02 && f95 <= 0.06, "free flight {f50} / {f95}");
    assert!(c50 <= 0.03 && c95 <= 0.08, "contact {c50} / {c95}");
    // ≥ 90 % over the three fixture drops (93 %); one drop of ~90 frames
    // has a binomial spread of ±3 %, hence 85 % here.
    assert!(cover >= 0.85, "2σ coverage {cover}");
}

#[test]
fn detect_settings_come_from_pipeline_toml() {
    let text = "[detect]\nsurface_row_px = 300.25\nsurface_slope = 0.004\ncontact_margin_px = 3.5\nedge_half_window_px = 8\nedge_spacing_px = 2.0\n";
    let cfg = dropscope::config::PipelineConfig::from_toml_str(
        text,
        std::path::Path::new("p.toml"),
        std::path::Path::new(""),
    )
    .unwrap();
    let p = EdgeParams::from_config(&cfg.detect);
    assert_eq!(p.half_window, 8);
    assert_eq!(p.spacing_px, 2.0);
    assert_eq!(p.surface_margin_px, 3.5);
    let line = SurfaceLine::from_config(&cfg.detect).expect("the override");
    assert!((line.row_at(100.0) - 300.65).abs() < 1e-12);
    assert_eq!(line.sigma_row_at(100.0), 0.0);
    let none = dropscope::config::PipelineConfig::from_toml_str(
        "",
        std::path::Path::new("p.toml"),
        std::path::Path::new(""),
    )
    .unwrap();
    assert!(SurfaceLine::from_config(&none.detect).is_none());
    assert_eq!(EdgeParams::from_config(&none.detect), EdgeParams::default());
}

/// A band read as a column window (`Band::window`, as the tracker reads
/// wide frames: the columns within the band's reach of the prediction and
/// the flicker strips) measures the same bits as the same rows read whole,
/// whatever its other columns hold; and when the fit moves far from the
/// prediction (normals leave the window), still the same bits whatever they
/// hold: nothing outside the window is read.
#[test]
fn a_column_window_measures_what_whole_rows_do() {
    let (w, h) = (480, 200);
    let look = REALISTIC;
    let mut rng = ChaCha8Rng::seed_from_u64(77);
    let truth = (231.37, 92.81, 40.0);
    let s = scene(w, h, look, Some(truth), None);
    let bg = background(&s, look, &mut rng);
    let frame = shoot(&s, look, &mut rng);
    let params = EdgeParams::default();
    let strip = GainRegion::default().strip_px;
    let measure = |band: &Band, p: &Circle| {
        let mut es = EdgeScratch::default();
        let fit = measure_circle(band, &bg, p, None, None, &params, &mut es).ok();
        (fit, es.points)
    };
    for (dx, dz, far) in [(0.0, 0.0, false), (1.3, -0.8, false), (-9.0, 2.0, true)] {
        let p = Circle {
            x_px: truth.0 + dx,
            z_px: truth.1 + dz,
            r_px: truth.2 + 0.5,
        };
        let reach = p.r_px + params.half_window as f64 + 6.0;
        let span = |c: f64| {
            (
                (c - reach).floor() as usize,
                (c + reach).ceil() as usize + 1,
            )
        };
        let ((lo, hi), (left, right)) = (span(p.z_px), span(p.x_px));
        let rows = frame.slice(ndarray::s![lo..hi, ..]);
        let whole = measure(&Band::new(rows, lo).unwrap(), &p);
        assert!(whole.0.is_some(), "no fit at offset ({dx}, {dz})");
        let read = |c: usize| c < strip || (left..right).contains(&c) || c >= w - strip;
        let mut seen = Vec::new();
        for fill in [0u16, 255, 9999] {
            let mut band = rows.to_owned();
            for ((_, c), v) in band.indexed_iter_mut() {
                if !read(c) {
                    *v = fill;
                }
            }
            seen.push(measure(
                &Band::window(band.view(), lo, left..right).unwrap(),
                &p,
            ));
        }
        assert!(
            seen.iter().all(|m| *m == seen[0]),
            "offset ({dx}, {dz}): depends on unread columns"
        );
        if far {
            // Normals on the left side run out of the window: fewer points.
            assert!(seen[0].1.len() < whole.1.len(), "offset ({dx}, {dz})");
        } else {
            assert_eq!(seen[0], whole, "offset ({dx}, {dz})");
        }
    }
}

/// A sensor's column fixed pattern — a gain per column, here 3 % rms — is in
/// every frame and in the background alike and cancels pixel by pixel: the
/// edge points divide each sample by its own background: 0.002 px rms, 0.005
/// at worst, the 12-bit rounding of the patterned frames. (With `1/B`
/// interpolated linearly between a window's ends it would stay in every
/// sample of a window crossing columns: the edge points move by 0.17 px rms,
/// 0.37 px at worst, on this disk.) Noise-free frames, blur σ = 1 px.
#[test]
fn a_column_gain_pattern_cancels_in_the_edge_points() {
    let look = Look {
        blur_px: 1.0,
        noise: 0.0,
        flicker: 0.0,
        bits: 12,
    };
    let (w, h) = (160, 160);
    let mut rng = ChaCha8Rng::seed_from_u64(29);
    let column_gain: Vec<f64> = (0..w).map(|_| 1.0 + 0.03 * gauss(&mut rng)).collect();
    let truth = (80.3, 79.6, 50.0);
    // The edge points' radii about the true centre, with and without the
    // pattern.
    let radii = |pattern: bool| -> Vec<(f64, f64)> {
        let shot = |s: &Scene| {
            let mut img = s.render();
            if pattern {
                for ((_, j), v) in img.indexed_iter_mut() {
                    *v *= column_gain[j];
                }
            }
            synth::quantize(&img, 1.0, max_level(look), || 0.0)
        };
        let with_disk = scene(w, h, look, Some(truth), None);
        let empty = scene(w, h, look, None, None);
        let frames: Vec<Frame> = (0..4).map(|_| shot(&empty)).collect();
        let views: Vec<_> = frames.iter().map(|f| f.view()).collect();
        let bg = Background::from_frames(&views, GainRegion::default()).unwrap();
        let frame = shot(&with_disk);
        let band = Band::frame(&frame).unwrap();
        let predicted = Circle {
            x_px: truth.0 + 0.4,
            z_px: truth.1 - 0.3,
            r_px: truth.2 + 0.2,
        };
        let mut scratch = EdgeScratch::default();
        measure_circle(
            &band,
            &bg,
            &predicted,
            None,
            None,
            &EdgeParams::default(),
            &mut scratch,
        )
        .unwrap();
        scratch
            .points
            .iter()
            .map(|p| {
                let (dx, dz) = (p.x_px - truth.0, p.z_px - truth.1);
                (dz.atan2(dx), dx.hypot(dz))
            })
            .collect()
    };
    let (plain, patterned) = (radii(false), radii(true));
    assert_eq!(plain.len(), patterned.len());
    assert!(plain.len() > 90, "{} points", plain.len());
    let (mut worst, mut sum2): (f64, f64) = (0.0, 0.0);
    for (a, b) in plain.iter().zip(&patterned) {
        assert!((a.0 - b.0).abs() < 1e-3, "the same normals");
        worst = worst.max((a.1 - b.1).abs());
        sum2 += (a.1 - b.1).powi(2);
    }
    let rms = (sum2 / plain.len() as f64).sqrt();
    eprintln!("column gain pattern: edge points moved {rms:.4} px rms, {worst:.4} at worst");
    // 12-bit rounding of the patterned frames moves them by up to 0.005.
    assert!(worst < 0.01, "an edge point moved by {worst} px");
}
