//! Finding the sphere: coarse detection entering through the top, in an
//! empty frame and in contact, and the robust fit against a mirrored arc.

use super::*;
use dropscope::detect::circle::{fit_circle, FitOptions, FitScratch};
use dropscope::detect::edges::EdgePoint;

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
