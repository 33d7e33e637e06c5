//! A saturated backlight and a glinting ball (`--saturation`, `--glint`,
//! `--preset real-saturated`): the background clipped at white with no
//! noise, the edge's half level moved inside the outline by the amount the
//! clipped profile predicts, the glint's stated shape, and the preset's
//! draws.

use dropscope::render::optics::{OpticsSpec, Strength};
use dropscope::render::raster::Look;
use dropscope::render::truth::Truth;
use dropscope::render::{render, rng_for, Preset};

use crate::render::{args, clean_scene};
use crate::render_real::{camera, camera_with};

/// Φ(x), the standard normal distribution function, from erf by its
/// continued Taylor series (|x| ≤ 4 here: the series converges to 1e-15).
fn phi(x: f64) -> f64 {
    let z = x / std::f64::consts::SQRT_2;
    let (mut term, mut sum, mut k) = (z, z, 0.0);
    while term.abs() > 1e-17 {
        k += 1.0;
        term *= 2.0 * z * z / (2.0 * k + 1.0);
        sum += term;
    }
    0.5 + (-z * z).exp() * sum / std::f64::consts::PI.sqrt()
}

/// The x with Φ(x) = p, by bisection.
fn phi_inverse(p: f64) -> f64 {
    let (mut lo, mut hi) = (-8.0, 8.0);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if phi(mid) < p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Where a row's profile crosses `level` walking in from the left, px.
fn crossing(row: &[f64], level: f64, from: usize) -> f64 {
    let j = (from..row.len()).find(|&j| row[j] < level).unwrap();
    let (a, b) = (row[j - 1], row[j]);
    (j - 1) as f64 + (a - level) / (a - b)
}

/// The `realistic` sensor (8-bit, gradient 0.12, read and shot noise, 1 %
/// flicker) behind a backlight saturated by 30 %: every background pixel
/// reads exactly white, frame after frame (std 0, as on the real Photron
/// footage), while the sphere's inside keeps its noise.
#[test]
fn a_saturated_backlight_reads_white_without_noise() {
    let look = Look {
        dust_count: 0,
        ..Preset::Realistic.look()
    };
    let spec = OpticsSpec {
        saturation: Strength::Fixed(0.3),
        blur_sigma0_px: Strength::Fixed(0.7),
        ..OpticsSpec::off()
    };
    let cam = camera_with(look, &spec, clean_scene(200, 160, 40.0, 130.0, 0.0));
    let t = &cam.optics().truth;
    assert_eq!(t.saturation, 0.3);
    // the dimmest background pixel of a 0.12 gradient around 0.75
    assert!(t.saturation_gain > 1.3 / 0.75 && t.saturation_gain < 1.3 / 0.6);
    let mut inside = Vec::new();
    for n in 0..5 {
        let f = cam.frame(&[(100.0, 60.0)], 0.0, &mut rng_for(1, "r", "frame", n));
        for i in 0..120 {
            for j in 0..200 {
                let outside =
                    ((i as f64 - 60.0).powi(2) + (j as f64 - 100.0).powi(2)).sqrt() > 46.0;
                if outside {
                    assert_eq!(f[[i, j]], 255, "frame {n} pixel ({i}, {j})");
                }
            }
        }
        inside.push(f64::from(f[[60, 100]]));
    }
    assert!(inside.iter().any(|&v| v != inside[0]), "{inside:?}");
}

/// A blurred outline (σ 1 px, 12-bit, no noise) behind a backlight
/// saturated by 50 %: the half level between the clipped background and
/// the sphere's inside lies inside the outline where the unclipped
/// profile `G·B·(τs + (1 − τs)·Φ(x/σ'))` meets it, `σ'² = σ² + 1/12` (the
/// pixel's box), i.e. 0.47 px in; without saturation the crossing is on
/// the outline. Held to 0.06 px (the 40 px circle's curvature moves the
/// 50 % level by σ²/2R = 0.01 px, linear interpolation by a few 0.01 px).
#[test]
fn a_saturated_backlight_moves_the_edges_half_level_inside_the_outline() {
    let sigma = 1.0;
    let (cx, cz, r) = (100.25, 60.0, 40.0);
    let edge = |saturation: f64| {
        let spec = OpticsSpec {
            saturation: Strength::Fixed(saturation),
            blur_sigma0_px: Strength::Fixed(sigma),
            ..OpticsSpec::off()
        };
        let cam = camera(&spec, clean_scene(200, 160, r, 130.0, 0.0));
        let f = cam.frame(&[(cx, cz)], 0.0, &mut rng_for(1, "r", "frame", 0));
        let row: Vec<f64> = (0..200).map(|j| f64::from(f[[60, j]]) / 4095.0).collect();
        let half = 0.5 * (row[5] + row[100]);
        (
            crossing(&row, half, 40) - (cx - r),
            half,
            cam.optics().truth.saturation_gain,
        )
    };
    let (plain, _, gain) = edge(0.0);
    assert_eq!(gain, 1.0);
    assert!(plain.abs() < 0.06, "{plain}");
    let (moved, half, gain) = edge(0.5);
    assert!((gain - 1.5 / 0.75).abs() < 1e-6, "{gain}");
    let tau = 0.06;
    let p = (half / 1.5 - tau) / (1.0 - tau);
    let s_eff = (sigma * sigma + 1.0 / 12.0).sqrt();
    // x is measured outward from the outline; the crossing walks inward
    let predicted = -s_eff * phi_inverse(p);
    assert!(
        (moved - predicted).abs() < 0.06 && predicted > 0.4,
        "the half level is {moved:.3} px inside the outline, predicted {predicted:.3}"
    );
}

/// A glint of twice the backlight, σ 0.15 R, on a still sphere (clean
/// 12-bit look, no blur): inside the disk the signal is
/// `B·(τs + glint·exp(−|p − c − o|²/2σ²))` to f32 precision; the frame
/// clips it at white over its core; the outline's pixels are those of a
/// ball without the glint (its tail there is 1e-10). Moving 6 px over the
/// exposure, the glint is the average of the samples' Gaussians.
#[test]
fn a_glint_has_its_stated_shape_and_clips_at_white() {
    let spec = OpticsSpec {
        glint: Strength::Fixed(2.0),
        glint_sigma: Strength::Fixed(0.15),
        ..OpticsSpec::off()
    };
    let (cx, cz, r) = (100.0, 60.0, 40.0);
    let cam = camera(&spec, clean_scene(200, 160, r, 130.0, 0.0));
    let plain = camera(&OpticsSpec::off(), clean_scene(200, 160, r, 130.0, 0.0));
    let t = cam.optics().truth.clone();
    assert!((t.glint_sigma_px - 6.0).abs() < 1e-12);
    assert!(t.glint_offset_px.iter().all(|o| o.abs() <= 0.05 * r));
    let gl = |x: f64, z: f64, c: (f64, f64)| {
        let (dx, dz) = (
            x - c.0 - t.glint_offset_px[0],
            z - c.1 - t.glint_offset_px[1],
        );
        2.0 * (-(dx * dx + dz * dz) / (2.0 * 36.0)).exp()
    };
    let b = 0.75;
    let sig = cam.signal(&[(cx, cz)]);
    let sig0 = plain.signal(&[(cx, cz)]);
    for i in 30..90 {
        for j in 70..130 {
            let rho = ((i as f64 - cz).powi(2) + (j as f64 - cx).powi(2)).sqrt();
            let v = f64::from(sig[[i, j]]);
            if rho < r - 1.0 {
                let want = b * (0.06 + gl(j as f64, i as f64, (cx, cz)));
                assert!((v - want).abs() < 2e-6, "({i}, {j}): {v} vs {want}");
            }
        }
    }
    for j in [59, 60, 61, 139, 140, 141] {
        assert!((sig[[60, j]] - sig0[[60, j]]).abs() < 1e-6, "column {j}");
    }
    let f = cam.frame(&[(cx, cz)], 0.0, &mut rng_for(1, "r", "frame", 0));
    assert_eq!(f[[60, 100]], 4095);
    assert!(f[[60, 80]] < 400, "{}", f[[60, 80]]);

    let path: Vec<(f64, f64)> = (0..8)
        .map(|k| (cx, cz + 6.0 * (k as f64 + 0.5) / 8.0 - 3.0))
        .collect();
    let smeared = cam.signal(&path);
    for i in [57, 60, 66] {
        let want = b * (0.06 + path.iter().map(|&c| gl(cx, i as f64, c)).sum::<f64>() / 8.0);
        let v = f64::from(smeared[[i, 100]]);
        assert!((v - want).abs() < 2e-6, "row {i}: {v} vs {want}");
    }
}

/// `--preset real-saturated`: `real`'s camera, set-ups and draws, plus a
/// saturation in 0.1–0.5 and a glint in 0.5–3 with σ 0.08–0.2 R per drop;
/// every other realised value is the `real` preset's for the same seed.
#[test]
fn the_real_saturated_preset_adds_the_two_effects_to_reals_draws() {
    let dir = tempfile::tempdir().unwrap();
    let render_with = |preset: &str| {
        let out = dir.path().join(preset);
        render(&args(&[
            "--out",
            out.to_str().unwrap(),
            "--campaign",
            "--preset",
            preset,
            "--radii-mm",
            "3,7",
            "--heights-cm",
            "50",
            "--start-at-entry",
            "false",
            "--frames-before",
            "2",
            "--frames-after",
            "1",
            "--seed",
            "4",
        ]))
        .unwrap()
    };
    let real = render_with("real");
    let saturated = render_with("real-saturated");
    assert_eq!(real.drops.len(), 2);
    for (a, b) in real.drops.iter().zip(&saturated.drops) {
        let text = std::fs::read_to_string(b.dir.join("truth.json")).unwrap();
        let t: Truth = serde_json::from_str(&text).unwrap();
        assert_eq!(t.preset, "real-saturated");
        let (ca, mut cb) = (a.truth.camera.clone().unwrap(), t.camera.clone().unwrap());
        assert!((0.1..=0.5).contains(&cb.saturation), "{}", cb.saturation);
        assert!((0.5..=3.0).contains(&cb.glint), "{}", cb.glint);
        let s = cb.glint_sigma_px / t.radius_px;
        assert!((0.08..=0.2).contains(&s), "{s}");
        assert!(cb.saturation_gain > 1.1 / 0.75);
        assert_eq!(
            (ca.saturation, ca.glint, ca.saturation_gain),
            (0.0, 0.0, 1.0)
        );
        cb.saturation = 0.0;
        cb.saturation_gain = 1.0;
        cb.glint = 0.0;
        cb.glint_sigma_px = ca.glint_sigma_px;
        cb.glint_offset_px = ca.glint_offset_px;
        assert_eq!(ca, cb, "{}", t.run);
        assert_eq!(a.truth.mm_per_px, t.mm_per_px);
    }
    let csv = std::fs::read_to_string(dir.path().join("real-saturated/runs.csv")).unwrap();
    assert!(csv.starts_with("run,path,sphere_radius_mm,drop_height_cm,setup\n"));
}
