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
use dropscope::detect::circle::Circle;
use dropscope::detect::coarse::{detect_coarse, CoarseParams, CoarseScratch};
use dropscope::detect::edges::{measure_circle, EdgeParams, EdgeScratch};
use dropscope::detect::surface::{fit_surface, SurfaceLine, SurfaceParams};
use dropscope::detect::synth::{self, Scene};
use dropscope::detect::Band;
use dropscope::source::Frame;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

mod background;
mod coarse;
mod columns;

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
/// One drop rendered into `dir` by `dropscope render` (R 4 mm from 8 cm,
/// the realistic preset, PNG frames), with its truth and frames.
fn rendered_drop(dir: &std::path::Path) -> (dropscope::render::truth::Truth, Vec<Frame>) {
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
        .arg(dir)
        .status()
        .unwrap();
    assert!(status.success());
    let run_dir = std::fs::read_dir(dir)
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
    (truth, frames)
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
    let (truth, frames) = rendered_drop(dir.path());
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
