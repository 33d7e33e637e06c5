#[cfg(target_arch = "x86_64")]
use super::fit::fit_circle_avx2;
use super::fit::fit_circle_lanes;
use super::lanes::F4;
use super::*;
use crate::detect::types::EdgePoint;
use crate::detect::DetectError;

fn arc(c: Circle, from_deg: f64, to_deg: f64, n: usize) -> Vec<EdgePoint> {
    (0..n)
        .map(|i| {
            let t = (from_deg + (to_deg - from_deg) * i as f64 / (n - 1) as f64).to_radians();
            EdgePoint {
                x_px: c.x_px + c.r_px * t.cos(),
                z_px: c.z_px + c.r_px * t.sin(),
                weight: 1.0,
            }
        })
        .collect()
}

#[test]
fn hyper_recovers_a_noiseless_60_degree_arc_to_1e_9() {
    // Exact points: the hyper fit is exact (η = 0) up to rounding; 1e-9 px
    // leaves room for rounding in moments of ~1e4 px² values.
    for (k, c) in [
        Circle {
            x_px: 256.3,
            z_px: 190.71,
            r_px: 83.17,
        },
        Circle {
            x_px: -12.0,
            z_px: 4000.5,
            r_px: 3.5,
        },
        Circle {
            x_px: 40.25,
            z_px: 60.125,
            r_px: 140.0,
        },
    ]
    .into_iter()
    .enumerate()
    {
        let start = -120.0 + 37.0 * k as f64;
        let pts = arc(c, start, start + 60.0, 25);
        let f = hyper_fit(&pts).unwrap();
        assert!((f.x_px - c.x_px).abs() < 1e-9, "{f:?} vs {c:?}");
        assert!((f.z_px - c.z_px).abs() < 1e-9, "{f:?} vs {c:?}");
        assert!((f.r_px - c.r_px).abs() < 1e-9, "{f:?} vs {c:?}");
    }
}

#[test]
fn collinear_points_are_an_error_not_a_circle() {
    let pts: Vec<_> = (0..10)
        .map(|i| EdgePoint {
            x_px: i as f64,
            z_px: 2.0 * i as f64,
            weight: 1.0,
        })
        .collect();
    assert!(hyper_fit(&pts).is_err());
    let mut s = FitScratch::default();
    assert!(fit_circle(&pts, None, &FitOptions::default(), &mut s).is_err());
    // No points, or none finite, from a start: an error too, not a panic.
    let start = Some(Circle {
        x_px: 1.0,
        z_px: 2.0,
        r_px: 3.0,
    });
    let nan = [EdgePoint {
        x_px: f64::NAN,
        z_px: 0.0,
        weight: 1.0,
    }; 7];
    for pts in [&[][..], &nan[..]] {
        let e = fit_circle(pts, start, &FitOptions::default(), &mut s).unwrap_err();
        assert!(
            matches!(e, DetectError::TooFewPoints { found: 0, .. }),
            "{e:?}"
        );
    }
}

#[test]
fn robust_fit_ignores_a_cluster_of_outliers() {
    let c = Circle {
        x_px: 100.4,
        z_px: 80.7,
        r_px: 50.0,
    };
    let mut pts = arc(c, 180.0, 360.0, 90);
    // A "mirror image" cluster and dust: 15 % of the points, far off.
    for (i, p) in pts.iter_mut().enumerate() {
        if i % 7 == 0 {
            p.z_px += 3.0 + (i % 3) as f64;
        }
    }
    let mut s = FitScratch::default();
    let f = fit_circle(&pts, None, &FitOptions::default(), &mut s).unwrap();
    assert!((f.x_px - c.x_px).abs() < 1e-6, "{f:?}");
    assert!((f.z_px - c.z_px).abs() < 1e-6, "{f:?}");
    assert!((f.r_px - c.r_px).abs() < 1e-6, "{f:?}");
    assert_eq!(f.inliers, 90 - 13);
    let held = FitOptions {
        hold_radius: Some(50.0),
        ..FitOptions::default()
    };
    let f = fit_circle(&pts, None, &held, &mut s).unwrap();
    assert!((f.z_px - c.z_px).abs() < 1e-6, "{f:?}");
    assert!(matches!(f.cov, Covariance::CentreOnly(_)));
}

#[test]
fn the_avx2_and_portable_passes_give_the_same_bits() {
    use rand::{Rng, SeedableRng};
    crate::test_support::require_avx2("the circle fit's passes");
    // Noisy arcs with outliers, one point not finite and a weight-0
    // point, free and held, from starts near and far (Huber and Tukey
    // passes, rescaled and fused): every field of the fit, to the bit.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let mut fitted = 0;
    for k in 0..30 {
        let c = Circle {
            x_px: 200.0 + rng.gen::<f64>(),
            z_px: 150.0 + rng.gen::<f64>(),
            r_px: 40.0 + 40.0 * rng.gen::<f64>(),
        };
        let span = 100.0 + 260.0 * rng.gen::<f64>();
        let n = 50 + k * 5;
        let mut pts = arc(c, 270.0 - span / 2.0, 270.0 + span / 2.0, n);
        for (i, p) in pts.iter_mut().enumerate() {
            p.x_px += 0.05 * (rng.gen::<f64>() - 0.5) + if i % 17 == 3 { 2.0 } else { 0.0 };
            p.z_px += 0.05 * (rng.gen::<f64>() - 0.5);
        }
        pts[1].weight = 0.0;
        pts[2].z_px = f64::NAN;
        let off = 2.0 * rng.gen::<f64>();
        let start = Circle {
            x_px: c.x_px + off,
            z_px: c.z_px - off,
            r_px: c.r_px + 0.5 * off,
        };
        let (mut s1, mut s2) = (FitScratch::default(), FitScratch::default());
        for opts in [
            FitOptions::default(),
            FitOptions {
                hold_radius: Some(c.r_px),
                ..FitOptions::default()
            },
            FitOptions {
                hold_radius: Some(c.r_px),
                huber_iterations: 0,
                scale_px: Some(0.03),
                ..FitOptions::default()
            },
        ] {
            let portable = fit_circle_lanes::<F4>(&pts, Some(start), &opts, &mut s1);
            #[cfg(target_arch = "x86_64")]
            {
                // SAFETY: AVX2 is present (asserted above).
                let avx2 = unsafe { fit_circle_avx2(&pts, Some(start), &opts, &mut s2) };
                assert_eq!(portable, avx2, "arc {k}, {opts:?}");
                assert_eq!(s1.weights, s2.weights, "arc {k}");
            }
            if portable.is_ok() {
                fitted += 1;
                assert_eq!(s1.weights[2], 0.0, "arc {k}: the NaN point has weight 0");
            }
        }
    }
    // Most fits succeed (a fixed scale of 0.03 px from a start up to
    // 2 px off rejects every point: an error, equal on both paths).
    assert!(fitted >= 70, "{fitted} of 90 fits");
}

#[test]
fn the_default_tolerance_stops_within_5e_5_px_of_the_converged_fit() {
    use rand::{Rng, SeedableRng};
    // Noisy short arcs (σ 0.05 px, 5 % outliers) from a start 0.4 px
    // off, as pass 1 gets them from the prediction: stopping at a
    // 1e-4 px step must land where iterating to 1e-12 px does.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let mut worst = 0.0f64;
    for k in 0..40 {
        let c = Circle {
            x_px: 200.0 + rng.gen::<f64>(),
            z_px: 150.0 + rng.gen::<f64>(),
            r_px: 60.0 + 10.0 * rng.gen::<f64>(),
        };
        let span = 140.0 + 220.0 * rng.gen::<f64>();
        let mut pts = arc(c, 270.0 - span / 2.0, 270.0 + span / 2.0, 120);
        for (i, p) in pts.iter_mut().enumerate() {
            let t = (p.z_px - c.z_px).atan2(p.x_px - c.x_px);
            let e = 0.05 * (rng.gen::<f64>() + rng.gen::<f64>() + rng.gen::<f64>() - 1.5) * 2.0
                + if i % 20 == 7 { 1.5 } else { 0.0 };
            p.x_px += e * t.cos();
            p.z_px += e * t.sin();
        }
        let start = Circle {
            x_px: c.x_px + 0.4,
            z_px: c.z_px - 0.3,
            r_px: c.r_px + 0.2,
        };
        let mut s = FitScratch::default();
        let tight = FitOptions {
            tolerance_px: 1e-12,
            ..FitOptions::default()
        };
        let a = fit_circle(&pts, Some(start), &FitOptions::default(), &mut s).unwrap();
        let b = fit_circle(&pts, Some(start), &tight, &mut s).unwrap();
        let held = |tolerance_px| FitOptions {
            hold_radius: Some(c.r_px),
            huber_iterations: 0,
            scale_px: Some(a.scale_px),
            tolerance_px,
            ..FitOptions::default()
        };
        let ha = fit_circle(&pts, Some(a.circle()), &held(1e-4), &mut s).unwrap();
        let hb = fit_circle(&pts, Some(a.circle()), &held(1e-12), &mut s).unwrap();
        assert_eq!(ha.scale_px, a.scale_px, "arc {k}: a given scale is kept");
        for (u, v) in [(a, b), (ha, hb)] {
            let d = (u.x_px - v.x_px)
                .abs()
                .max((u.z_px - v.z_px).abs())
                .max((u.r_px - v.r_px).abs());
            worst = worst.max(d);
        }
        assert!(
            b.iterations > a.iterations,
            "arc {k}: {} vs {}",
            a.iterations,
            b.iterations
        );
    }
    assert!(worst < 5e-5, "worst difference {worst} px");
}
