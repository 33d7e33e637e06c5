//! Tests of [`crate::measure::force`].

use super::*;
use crate::measure::events::FORCE_FIT_MAX_TRAJECTORIES;
use crate::measure::force_fit::{fit_force_law, fit_force_law_to};

/// The product's fit: [`fit_force_law`] on the test sphere at g = 9.81
/// with the default work limit.
fn fit(
    tr: &[TrackPoint],
    ev: &Events,
    geom: &Geometry,
    exposure_s: f64,
) -> Result<ForceLaw, ForceFitError> {
    fit_force_law(
        tr,
        ev,
        geom,
        &sphere(),
        9.81,
        exposure_s,
        FORCE_FIT_MAX_TRAJECTORIES,
    )
}
use crate::measure::events::{find_events, EventConfig};
use crate::test_support::{geometry, sphere, track, Drop};

fn k_model() -> f64 {
    // K = π E φ R / h for the paper's PDMS and R = 4.5 mm.
    std::f64::consts::PI * 1.6e6 * 0.625 * 4.5e-3 / 3.5e-3
}

#[test]
fn trajectory_fit_recovers_the_elastic_foundation_law() {
    let drop = Drop::new(4.5e-3, 1.7, 0.5e-4);
    let geom = geometry();
    for (sigma, tol_n, tol_k) in [(0.0, 1e-3, 1e-3), (0.03, 0.05, 0.03)] {
        let tr = track(&drop, &geom, sigma, 7);
        let ev = find_events(&tr, &geom, &EventConfig::default()).unwrap();
        let f = fit(&tr, &ev, &geom, 0.0).unwrap();
        assert!((f.n.value - 2.0).abs() < tol_n, "σ={sigma}: n = {:?}", f.n);
        // K with n free carries n's error (δ^Δn): check it against its own σ.
        assert!(
            (f.k.value - k_model()).abs() < 3.0 * f.k.err.max(tol_k * k_model() / 3.0),
            "σ={sigma}: K = {:?} vs {}",
            f.k,
            k_model()
        );
        assert!(f.damping.value.abs() < 3.0 * f.damping.err.max(1e-9));
        assert!(
            (f.k_at_n2.value / k_model() - 1.0).abs() < tol_k,
            "σ={sigma}: K(n=2) = {:?}",
            f.k_at_n2
        );
    }
}

/// Frames of a drop whose contact is `model` with K/m = `km`, exponent
/// `n` and damping `b` (c/m or α), integrated finely, at 10 000 frames/s
/// from 35 frames before the touchdown, on the test geometry's true
/// surface with Gaussian noise of `sigma_px` (seed 7).
fn drop_of(model: ContactModel, km: f64, n: f64, b: f64, sigma_px: f64) -> Vec<TrackPoint> {
    let truth = geometry();
    let s_m = truth.mm_per_px * 1e-3;
    let v_in = 1.2;
    let ts: Vec<f64> = (-35..75).map(|k| k as f64 * 1e-4).collect();
    let d0 = -v_in * 35e-4 - 0.5 * 9.81 * 35e-4f64.powi(2);
    let v0 = v_in - 9.81 * 35e-4;
    let theta = [d0, v0, km.ln(), n, b, 0.0];
    let delta = integrate_counted(&ts, &theta, 9.81, 1e-6, model).0;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let noise = Normal::new(0.0, sigma_px.max(1e-12)).unwrap();
    ts.iter()
        .zip(&delta)
        .enumerate()
        .map(|(k, (&t, &d))| TrackPoint {
            frame: k as i64 - 35,
            t_s: t,
            x_px: 256.0,
            z_px: truth.surface_row_px - truth.radius_px + d / s_m + noise.sample(&mut rng),
            sigma_z_px: sigma_px.max(1e-4),
            half_width_px: None,
            sigma_half_width_px: None,
        })
        .collect()
}

/// K/m for a δmax of about 1 mm at 1.2 m/s with exponent n:
/// ½v² = (K/m)·δ^(n+1)/(n+1).
fn km_for(n: f64) -> f64 {
    (n + 1.0) * 0.5 * 1.2f64.powi(2) / 1e-3f64.powf(n + 1.0)
}

#[test]
fn the_contact_model_and_its_exponent_are_measured_not_presumed() {
    // Each of the four contact models with an exponent that is not the
    // elastic foundation's 2, damped to a restitution of 0.6–0.8, frames
    // with 0.01 px of noise: the fit must pick the damping the frames
    // were made with and find n within 3 of its σ and within 0.02, with
    // its σ below 0.03.
    let hc = Damping::HuntCrossley;
    let cases = [
        (ContactModel::ALL[0], 1.6, 180.0),
        (ContactModel::ALL[1], 2.4, 250.0),
        (
            ContactModel {
                damping: hc,
                pulls: true,
            },
            1.8,
            0.5,
        ),
        (
            ContactModel {
                damping: hc,
                pulls: false,
            },
            2.3,
            0.6,
        ),
    ];
    let geom = geometry();
    for (model, n_true, b) in cases {
        let tr = drop_of(model, km_for(n_true), n_true, b, 0.01);
        let ev = find_events(&tr, &geom, &EventConfig::default()).unwrap();
        let f = fit(&tr, &ev, &geom, 0.0).unwrap();
        let miss = (f.n.value - n_true).abs();
        assert!(
            miss < 0.02 && miss < 3.0 * f.n.err && f.n.err < 0.03,
            "{}: n = {:?} (true {n_true}); models {:?}",
            model.name(),
            f.n,
            f.models
        );
        // A force that cannot pull, against one that can, differs only
        // in the last frames of a lightly damped contact: the damping
        // kind must be right, the pull may be either when they tie.
        assert_eq!(
            f.model.damping,
            model.damping,
            "{}: {:?}",
            model.name(),
            f.models
        );
        let weights: f64 = f.models.iter().map(|m| m.weight).sum();
        assert!((weights - 1.0).abs() < 1e-12);
    }
}

#[test]
fn a_surface_line_that_is_off_is_caught_by_the_trajectory_with_the_surface_free() {
    // Frames made on the true surface (row 300) with F = K·δ^1.7 and
    // linear damping, measured against a line put 0.8 px too high or
    // 0.5 px too low, as a glossy band top or a dark top row moves the
    // image's line. On a wrong line n is pulled off; the trajectory
    // fitted with the surface free too (n free, nothing presumed) must
    // put the surface back within 3 of its σ, and with the
    // line right say 0 within 3σ. n and the surface trade off, so the
    // surface's σ is several times the frames' (seen 0.07 px), yet the
    // cross-check flags the wrong lines.
    let truth = geometry();
    let n_true = 1.7;
    let tr = drop_of(ContactModel::ALL[0], km_for(n_true), n_true, 100.0, 0.005);
    for line_error_px in [-0.8, 0.0, 0.5] {
        let geom = Geometry {
            surface_row_px: truth.surface_row_px + line_error_px,
            ..truth
        };
        let ev = find_events(&tr, &geom, &EventConfig::default()).unwrap();
        let f = fit(&tr, &ev, &geom, 0.0).unwrap();
        let d = f.surface_offset_px.expect("the surface fit converges");
        let miss = d.value + line_error_px;
        assert!(
            miss.abs() < 3.0 * d.err && d.err < 0.15,
            "line off by {line_error_px} px: law offset {d:?}"
        );
        let flagged = crate::measure::surface_law_check(&f, 0.02).is_some();
        assert_eq!(flagged, line_error_px != 0.0, "{line_error_px}: {d:?}");
        if line_error_px != 0.0 {
            assert!((f.n.value - n_true).abs() > 0.05, "on the line {:?}", f.n);
        }
    }
}

#[test]
fn exposure_averaged_frames_give_the_law_when_the_model_is_averaged_too() {
    // Noise-free frames that each show the mean position over a 50 µs
    // exposure (half the 100 µs frame interval, as the renderer's
    // default): fitted as instants the law comes out biased; averaged
    // like the frames, exact.
    let drop = Drop::new(4.5e-3, 1.7, 0.5e-4);
    let geom = geometry();
    let exposure_s = 50e-6;
    let tr = crate::test_support::track_exposed(&drop, &geom, 0.0, 1, exposure_s);
    let cfg = EventConfig {
        exposure_s,
        ..EventConfig::default()
    };
    let ev = find_events(&tr, &geom, &cfg).unwrap();
    let naive = fit(&tr, &ev, &geom, 0.0).unwrap();
    let averaged = fit(&tr, &ev, &geom, exposure_s).unwrap();
    // Averaged: n within 2e-5 and K(n = 2) within 2e-5 (seen: 2.2e-7 and
    // 1e-7); as instants n came out 1.9977, the −0.002 of the rendered
    // campaign.
    assert!(
        (averaged.n.value - 2.0).abs() < 2e-5,
        "n = {:?}",
        averaged.n
    );
    let k_rel = averaged.k_at_n2.value / k_model() - 1.0;
    assert!(k_rel.abs() < 2e-5, "K = {:?}", averaged.k_at_n2);
    assert!(
        (naive.n.value - 2.0).abs() > 1e-3,
        "the instants fit should be visibly biased: n = {:?}",
        naive.n
    );
}

#[test]
fn the_geometrys_errors_reach_the_law_as_a_refit_on_the_shifted_geometry_does() {
    // The surface row and the radius (with the scale from it) off by
    // 0.05 px: the error each adds to K(n = 2), n and K, by the fit's
    // linear response, must be what refitting the same frames on the
    // shifted geometry changes them by (within 10 %).
    let drop = Drop::new(4.5e-3, 1.7, 0.5e-4);
    let exact = Geometry {
        surface_row_err_px: 0.0,
        radius_err_px: 0.0,
        ..geometry()
    };
    let tr = track(&drop, &exact, 0.03, 5);
    let fit_with = |g: &Geometry| {
        let ev = find_events(&tr, g, &EventConfig::default()).unwrap();
        fit(&tr, &ev, g, 0.0).unwrap()
    };
    let base = fit_with(&exact);
    let shift = 0.05;
    let r_mm = exact.radius_px * exact.mm_per_px;
    for (with_error, shifted) in [
        (
            Geometry {
                surface_row_err_px: shift,
                ..exact
            },
            Geometry {
                surface_row_px: exact.surface_row_px + shift,
                ..exact
            },
        ),
        (
            Geometry {
                radius_err_px: shift,
                ..exact
            },
            Geometry {
                radius_px: exact.radius_px + shift,
                mm_per_px: r_mm / (exact.radius_px + shift),
                ..exact
            },
        ),
    ] {
        let (e, s) = (fit_with(&with_error), fit_with(&shifted));
        for (b, e, s, what) in [
            (base.k_at_n2, e.k_at_n2, s.k_at_n2, "K(n = 2)"),
            (base.n, e.n, s.n, "n"),
            (base.k, e.k, s.k, "K"),
        ] {
            let added = (e.err * e.err - b.err * b.err).max(0.0).sqrt();
            let moved = (s.value - b.value).abs();
            assert!(
                (added / moved - 1.0).abs() < 0.1,
                "{what}: error added {added:.4e}, refit moved {moved:.4e}"
            );
            // And not negligible next to the frames' own scatter.
            assert!(added > 0.1 * b.err, "{what}: {added:.3e} vs {:.3e}", b.err);
        }
    }
}

#[test]
fn stopping_at_the_relative_tolerance_leaves_the_fit_within_1e_3_sigma() {
    let drop = Drop::new(4.5e-3, 1.7, 0.5e-4);
    let geom = geometry();
    for seed in [3, 7, 11] {
        let tr = track(&drop, &geom, 0.03, seed);
        let ev = find_events(&tr, &geom, &EventConfig::default()).unwrap();
        let fit =
            |tol| fit_force_law_to(&tr, &ev, &geom, &sphere(), 9.81, 0.0, tol, 10_000).unwrap();
        let (ours, tight) = (fit(LM_REL_TOL), fit(1e-15));
        for (a, b, what) in [
            (ours.n, tight.n, "n"),
            (ours.k, tight.k, "K"),
            (ours.k_at_n2, tight.k_at_n2, "K(n = 2)"),
            (ours.damping, tight.damping, "damping"),
        ] {
            assert!(
                (a.value - b.value).abs() <= 1e-3 * b.err,
                "seed {seed}, {what}: {a:?} against {b:?}"
            );
        }
    }
}

/// The exact-flight, located-crossing integration agrees with brute
/// force RK4 (1 000 steps a frame) through a damped bounce and back into
/// flight, for n = 2 and n ≠ 2, under each contact model.
#[test]
fn integration_matches_fine_brute_force_through_touchdown_and_lift_off() {
    let brute = |ts: &[f64], th: &[f64], g: f64, h_max: f64, model: ContactModel| {
        let (km, n, b) = (th[2].exp(), th[3], th[4]);
        let acc = |d: f64, v: f64| {
            if d > 0.0 {
                let f = match model.damping {
                    Damping::Linear => km * d.powf(n) + b * v,
                    Damping::HuntCrossley => km * d.powf(n) * (1.0 + b * v),
                };
                g - if model.pulls { f } else { f.max(0.0) }
            } else {
                g
            }
        };
        let (mut d, mut v, mut t) = (th[0], th[1], ts[0]);
        let mut out = Vec::new();
        for &target in ts {
            while t < target {
                let h = (target - t).min(h_max);
                let (k1x, k1v) = (v, acc(d, v));
                let (k2x, k2v) = (v + 0.5 * h * k1v, acc(d + 0.5 * h * k1x, v + 0.5 * h * k1v));
                let (k3x, k3v) = (v + 0.5 * h * k2v, acc(d + 0.5 * h * k2x, v + 0.5 * h * k2v));
                let (k4x, k4v) = (v + h * k3v, acc(d + h * k3x, v + h * k3v));
                d += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
                v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
                t += h;
            }
            out.push(d);
        }
        out
    };
    // R = 4.5 mm steel on the paper's PDMS at 1 m/s, 10 000 frames/s:
    // a contact of ~25 frames; damping for e ≈ 0.9.
    let mass = 7800.0 * 4.0 / 3.0 * std::f64::consts::PI * 4.5e-3f64.powi(3);
    let dt = 1e-4;
    let ts: Vec<f64> = (0..60).map(|i| i as f64 * dt).collect();
    for (model, n, b) in [
        (ContactModel::ALL[0], 2.0, 8.0),
        (ContactModel::ALL[0], 1.9, 8.0),
        (ContactModel::ALL[1], 2.0, 60.0),
        (ContactModel::ALL[2], 2.2, 0.3),
        (ContactModel::ALL[3], 1.6, 1.5),
    ] {
        // K for about the same δmax whatever n: K₂·(1 mm)^(2−n).
        let theta = [
            -0.4e-3,
            1.0,
            (k_model() / mass).ln() + (2.0 - n) * 1e-3f64.ln(),
            n,
            b,
        ];
        let ours = integrate_counted(&ts, &theta, 9.81, dt / CONTACT_STEPS_PER_FRAME, model).0;
        let reference = brute(&ts, &theta, 9.81, dt / 1000.0, model);
        let dmax = reference.iter().cloned().fold(0.0, f64::max);
        assert!(dmax > 5e-4, "no contact: δmax {dmax}");
        assert!(reference.last().unwrap() < &-1e-4, "no lift-off");
        let worst = ours
            .iter()
            .zip(&reference)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        // Measured 5e-11 (n = 2) and 1.3e-10 m (n = 1.9), the same at 50
        // and 100 steps a frame; brute force at 100 steps, which straddles
        // the touchdown, is off by 3e-9 and 5e-9 m.
        assert!(
            worst < 5e-7 * dmax,
            "{}, n = {n}: worst {worst:e} of δmax {dmax:e}",
            model.name()
        );
    }
}

#[test]
fn the_fit_stops_at_its_work_limit_with_a_reason() {
    let drop = Drop::new(4.5e-3, 1.7, 0.5e-4);
    let geom = geometry();
    let tr = track(&drop, &geom, 0.03, 3);
    let ev = find_events(&tr, &geom, &EventConfig::default()).unwrap();
    let fit = |max| fit_force_law_to(&tr, &ev, &geom, &sphere(), 9.81, 0.0, LM_REL_TOL, max);
    // A clean drop needs 113–259 trajectories: 10 stop it, 1 000 do not.
    let e = fit(10).unwrap_err();
    assert_eq!(e, ForceFitError::Limit("10 trajectories' work".into()));
    assert!(e
        .to_string()
        .contains("stopped at its limit of 10 trajectories"));
    assert!(fit(FORCE_FIT_MAX_TRAJECTORIES).is_ok());
}

#[test]
fn where_the_work_limit_stops_the_fits_does_not_depend_on_the_threads() {
    // The fits run beside each other and a Jacobian's trajectories on
    // every thread; the limit counts their work in the one-thread order.
    // Limits from one that stops the first fit to a little past the
    // least that none reaches, so that it stops each fit at many places.
    let drop = Drop::new(4.5e-3, 1.7, 0.5e-4);
    let geom = geometry();
    let tr = track(&drop, &geom, 0.03, 3);
    let ev = find_events(&tr, &geom, &EventConfig::default()).unwrap();
    let on = |threads: usize, max: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let f = fit_force_law_to(&tr, &ev, &geom, &sphere(), 9.81, 0.0, LM_REL_TOL, max);
                format!("{f:?}")
            })
    };
    // The least limit the fits pass, by bisection on one thread.
    let (mut lo, mut hi) = (2, FORCE_FIT_MAX_TRAJECTORIES);
    assert!(!on(1, hi).contains("Limit"));
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if on(1, mid).contains("Limit") {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    eprintln!("the fits pass a limit of {hi} trajectories");
    let step = (hi / 60).max(1);
    let (mut stopped, mut tried) = (0, 0);
    for max in (2..=hi + hi / 8).step_by(step) {
        let one = on(1, max);
        assert_eq!(one, on(2, max), "limit of {max} trajectories");
        stopped += usize::from(one.contains("Limit"));
        tried += 1;
    }
    assert!(
        stopped > 10 && stopped < tried,
        "{stopped} of {tried} stopped"
    );
}

#[test]
fn the_work_limit_counts_a_trajectory_at_its_real_cost_with_an_exposure() {
    // Frames averaged over a 50 µs exposure: the model is asked for
    // three times per frame. This fit integrates ~240 trajectories of
    // ~580 steps each; the former count (23 steps per time asked for,
    // 3 300 per trajectory) saw ~42 of them and let 100 pass, so that
    // 5 000 allowed a wandering fit to run for seconds.
    let drop = Drop::new(4.5e-3, 1.7, 0.5e-4);
    let geom = geometry();
    let tr = crate::test_support::track_exposed(&drop, &geom, 0.0, 1, 50e-6);
    let cfg = EventConfig {
        exposure_s: 50e-6,
        ..EventConfig::default()
    };
    let ev = find_events(&tr, &geom, &cfg).unwrap();
    let fit = |max| fit_force_law_to(&tr, &ev, &geom, &sphere(), 9.81, 50e-6, LM_REL_TOL, max);
    assert_eq!(
        fit(100).unwrap_err(),
        ForceFitError::Limit("100 trajectories' work".into())
    );
    assert!(fit(FORCE_FIT_MAX_TRAJECTORIES).is_ok());
}

#[test]
fn tabulated_force_follows_k_delta_squared_away_from_the_peak_smoothing() {
    let drop = Drop::new(4.5e-3, 1.7, 0.5e-4);
    let geom = geometry();
    let tr = track(&drop, &geom, 0.0, 1);
    let ev = find_events(&tr, &geom, &EventConfig::default()).unwrap();
    let table = force_table(&tr, &ev, &geom, &sphere(), 9.81, 2);
    assert!(table.len() >= 15, "{} rows", table.len());
    // With a ±2-frame cubic the table is within 10 % of K·δ² where
    // δ > 30 % of its maximum (the smoothing bias the module doc states).
    let dmax = table.iter().map(|p| p.delta_m).fold(0.0, f64::max);
    for p in table.iter().filter(|p| p.delta_m > 0.3 * dmax) {
        let f_true = k_model() * p.delta_m * p.delta_m;
        assert!((p.force_n / f_true - 1.0).abs() < 0.1, "{p:?} vs {f_true}");
    }
}
