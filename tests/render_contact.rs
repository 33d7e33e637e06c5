//! The renderer's contact laws beyond the model (`--contact wide`,
//! `--force-exponent`, `--damping`, `--no-adhesion`): the physics against
//! closed forms, the force's zero without adhesion, the restitution solved
//! over the whole range, and `truth.json`.

use dropscope::config::Surface;
use dropscope::render::contact::{self, ContactDraw};
use dropscope::render::physics::{
    ContactLaw, Damping, DropParams, Trajectory, BETA_THIRD_HALF, STANDARD_GRAVITY_M_S2,
};
use dropscope::render::render;
use dropscope::render::truth::Truth;

use crate::render::{args, files};

fn drop_params(radius_mm: f64, v_m_s: f64, g: f64) -> DropParams {
    DropParams {
        sphere_radius_m: radius_mm * 1e-3,
        sphere_density_kg_m3: 7800.0,
        surface: Surface::paper_pdms(),
        gravity_m_s2: g,
        impact_speed_m_s: v_m_s,
        damping_n_s_m: 0.0,
        law: ContactLaw::MODEL,
    }
}

/// The drop's parameters under an exponent-`n` law with `K_n = K δ_ref^{2−n}`.
fn with_law(p: &DropParams, n: f64, adhesion: bool) -> DropParams {
    DropParams {
        law: ContactLaw {
            exponent: n,
            stiffness_n_per_m_n: Some(p.stiffness_for_exponent(n)),
            hunt_crossley_s_m: 0.0,
            adhesion,
        },
        ..*p
    }
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

fn speed(h_cm: f64) -> f64 {
    (2.0 * STANDARD_GRAVITY_M_S2 * h_cm * 1e-2).sqrt()
}

/// `∫₀¹ du / √(1 − u^p)`; with `u = 1 − s²` the integrand
/// `2 s / √(1 − (1 − s²)^p)` is smooth (→ 2/√p at s = 0). Simpson with
/// 20 000 panels: ~1e-12.
fn contact_integral(p: f64) -> f64 {
    let f = |s: f64| {
        if s == 0.0 {
            2.0 / p.sqrt()
        } else {
            2.0 * s / (1.0 - (1.0 - s * s).powf(p)).sqrt()
        }
    };
    let n = 20_000;
    let h = 1.0 / n as f64;
    let mut sum = f(0.0) + f(1.0);
    for i in 1..n {
        sum += f(i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    sum * h / 3.0
}

/// The law's own path with n = 2 (the elastic force `K |d|^n` through the
/// general code, the force clamped at 0) and no gravity or damping gives
/// Eq. (4) and Eq. (5) of Maruoka 2019 to 1e-6, as the model's path does
/// (tests/render.rs). The quadrature reproduces B(1/3, 1/2) = 3·I(3).
#[test]
fn the_laws_path_at_n_2_follows_eq4_and_eq5() {
    assert!((3.0 * contact_integral(3.0) - BETA_THIRD_HALF).abs() < 1e-10);
    for (r_mm, v) in [(3.0, 3.13), (7.0, 0.54)] {
        let p0 = drop_params(r_mm, v, 0.0);
        let p = with_law(&p0, 2.0, false);
        assert_eq!(p.elastic_stiffness(), p0.stiffness_n_m2());
        let step = p.default_step_s(1e-6);
        let b = Trajectory::simulate(&p, 0.0, 1.0, step).unwrap().bounces()[0];
        assert!(rel(b.delta_max_m, p.delta_max_eq4_m()) < 1e-6);
        assert!(rel(b.tau_c_s(), p.tau_c_eq5_s()) < 1e-6);
        assert!(rel(b.v_rebound_m_s, v) < 1e-9);
        assert_eq!(
            b.force_zero, None,
            "no damping: the force is 0 only at δ = 0"
        );
    }
}

/// Without gravity and damping, for any n, energy conservation gives
/// `δmax = ((n + 1) m v² / (2 K_n))^{1/(n+1)}` and
/// `τc = 2 (δmax / v) ∫₀¹ du / √(1 − u^{n+1})`; the rebound speed is the
/// impact speed. Held to 1e-6 (RK4 at τc/2000 and events on the
/// continuous solution leave ~1e-9; `|δ|^n` is not smooth at δ = 0 for
/// non-integer n, which costs RK4 its order in the first step only). With
/// `K_n = K δ_ref^{2−n}`, δmax/δ_ref = ((n + 1)/3)^{1/(n+1)}.
#[test]
fn any_exponent_follows_energy_conservation_without_gravity() {
    for (r_mm, v) in [(3.0, 0.54), (4.5, 1.53), (7.0, 3.13)] {
        for n in [1.4, 1.7, 2.3, 2.6] {
            let p0 = drop_params(r_mm, v, 0.0);
            let p = with_law(&p0, n, true);
            let step = p.default_step_s(1e-6);
            let b = Trajectory::simulate(&p, 0.0, 1.0, step).unwrap().bounces()[0];
            let closed = ((n + 1.0) * p.mass_kg() * v * v / (2.0 * p.elastic_stiffness()))
                .powf(1.0 / (n + 1.0));
            assert!(
                rel(b.delta_max_m, closed) < 1e-6,
                "R {r_mm} n {n}: δmax {} vs {closed}",
                b.delta_max_m
            );
            assert!(rel(p.delta_max_energy_m(), closed) < 1e-14);
            let scaled = p0.delta_max_eq4_m() * ((n + 1.0) / 3.0).powf(1.0 / (n + 1.0));
            assert!(rel(closed, scaled) < 1e-12, "{closed} vs {scaled}");
            let tau = 2.0 * closed / v * contact_integral(n + 1.0);
            assert!(
                rel(b.tau_c_s(), tau) < 1e-6,
                "R {r_mm} n {n}: τc {} vs {tau}",
                b.tau_c_s()
            );
            assert!(rel(b.v_rebound_m_s, v) < 1e-8, "{}", b.v_rebound_m_s);
        }
    }
}

/// With gravity and no damping, `½ m ḋ² − m g d + K_n d^{n+1}/(n + 1)` is
/// conserved for any n. Sampled off the grid across contact and flight: the
/// relative drift stays below 1e-8 (measured ≲ 1e-10; the margin covers
/// the non-smooth `|δ|^n` at the contact's ends).
#[test]
fn energy_is_conserved_for_any_exponent_with_gravity() {
    for (r_mm, h_cm) in [(3.0, 50.0), (7.0, 1.5)] {
        for n in [1.4, 2.6] {
            let v = speed(h_cm);
            let p = with_law(&drop_params(r_mm, v, STANDARD_GRAVITY_M_S2), n, true);
            let step = p.default_step_s(1e-6);
            let tr = Trajectory::simulate(&p, 1e-4, 0.02, step).unwrap();
            let b = tr.bounces()[0];
            let e0 = p.energy_j(0.0, v);
            let mut worst: f64 = 0.0;
            for k in 0..=4000 {
                let t = b.t_contact_s - 1e-3 + (b.tau_c_s() + 2e-3) * (k as f64 + 0.37) / 4000.0;
                let (d, w) = tr.state(t);
                worst = worst.max(rel(p.energy_j(d, w), e0));
            }
            assert!(worst < 1e-8, "R {r_mm} H {h_cm} n {n}: {worst:e}");
            assert!(rel(b.restitution(), 1.0) < 1e-8);
        }
    }
}

/// Without adhesion the force `K_n δ^n + c ḋ` is clamped at 0: the sphere
/// leaves the surface where it reaches 0 on the way out (δ still > 0), then
/// flies freely — the depth follows the parabola from there, reaches 0 at
/// `t_rebound` with the speed `√(ḋ_f² − 2 g δ_f)`, and the unclamped force
/// along that flight stays negative (the sphere does not touch again). With
/// adhesion the same law keeps the sphere until δ = 0, the force pulling at
/// the end.
#[test]
fn without_adhesion_the_sphere_leaves_where_the_force_reaches_zero() {
    let g = STANDARD_GRAVITY_M_S2;
    for (r_mm, h_cm, n, e) in [
        (3.0, 1.5, 1.4, 0.3),
        (4.5, 12.0, 2.0, 0.7),
        (7.0, 50.0, 2.6, 0.9),
    ] {
        let base = drop_params(r_mm, speed(h_cm), g);
        let step = base.default_step_s(1e-6);
        for adhesion in [false, true] {
            let c = ContactDraw {
                exponent: n,
                damping: Damping::Linear,
                adhesion,
                restitution: e,
            };
            let p = contact::apply(&base, &c, step).unwrap();
            let k = p.elastic_stiffness();
            let force = |(d, w): (f64, f64)| k * d.abs().powf(n) + p.damping_n_s_m * w;
            let tr = Trajectory::simulate(&p, 0.0, 0.0, step).unwrap();
            let b = tr.bounces()[0];
            let peak = p.elastic_stiffness() * b.delta_max_m.powf(n);
            assert!((b.restitution() - e).abs() < 1e-9, "{}", b.restitution());
            if adhesion {
                assert_eq!(b.force_zero, None);
                let late = tr.state(b.t_rebound_s - 1e-3 * b.tau_c_s());
                assert!(
                    force(late) < 0.0,
                    "with adhesion the force pulls at the end"
                );
                continue;
            }
            let (t_f, d_f) = b.force_zero.expect("linear damping: F = 0 before δ = 0");
            let what = format!("R {r_mm} H {h_cm} n {n}");
            assert!(
                t_f > b.t_max_s && t_f < b.t_rebound_s && d_f > 0.0,
                "{what}"
            );
            let (d, w) = tr.state(t_f);
            assert!(rel(d, d_f) < 1e-12, "{what}: {d} vs {d_f}");
            assert!(
                force((d, w)).abs() < 1e-9 * peak,
                "{what}: F = {}",
                force((d, w))
            );
            let before = tr.state(t_f - 1e-3 * b.tau_c_s());
            assert!(force(before) > 0.0, "{what}");
            for q in 1..50 {
                let tau = (b.t_rebound_s - t_f) * q as f64 / 50.0;
                let (d_t, w_t) = tr.state(t_f + tau);
                assert!(
                    (d_t - (d_f + w * tau + 0.5 * g * tau * tau)).abs() < 1e-15,
                    "{what}"
                );
                assert!((w_t - (w + g * tau)).abs() < 1e-12, "{what}");
                assert!(
                    force((d_t, w_t)) < 0.0,
                    "{what}: the clamped force would push again"
                );
            }
            assert!(tr.state(b.t_rebound_s).0.abs() < 1e-15, "{what}");
            let v_out = (w * w - 2.0 * g * d_f).sqrt();
            assert!(rel(b.v_rebound_m_s, v_out) < 1e-12, "{what}");
        }
    }
}

/// The damping solved for a restitution gives it, over the whole range the
/// wide contact draws (0.3–0.98), at the grid's corners, for both damped
/// kinds, both exponent ends, with and without adhesion: within 1e-9
/// (the solver stops at 1e-13 where floating point allows).
#[test]
fn the_restitution_is_achieved_over_the_range() {
    let mut worst: f64 = 0.0;
    for (r_mm, h_cm) in [(3.0, 1.5), (7.0, 50.0)] {
        let base = drop_params(r_mm, speed(h_cm), STANDARD_GRAVITY_M_S2);
        let step = base.default_step_s(1e-6);
        for n in [1.4, 2.6] {
            for damping in [Damping::Linear, Damping::HuntCrossley] {
                for adhesion in [true, false] {
                    for e in [0.3, 0.98] {
                        let c = ContactDraw {
                            exponent: n,
                            damping,
                            adhesion,
                            restitution: e,
                        };
                        let p = contact::apply(&base, &c, step).unwrap();
                        let b = Trajectory::simulate(&p, 0.0, 0.0, step).unwrap().bounces()[0];
                        worst = worst.max((b.restitution() - e).abs());
                        let coefficient = match damping {
                            Damping::Linear => p.damping_n_s_m,
                            _ => p.law.hunt_crossley_s_m,
                        };
                        assert!(coefficient > 0.0, "{c:?}");
                    }
                }
            }
        }
    }
    assert!(worst < 1e-9, "{worst:e}");
}

const SMALL: [&str; 10] = [
    "--width-px",
    "160",
    "--height-px",
    "120",
    "--mm-per-px",
    "0.2",
    "--frames-before",
    "4",
    "--frames-after",
    "4",
];

fn wide_render(out: &std::path::Path, seed: &str) -> dropscope::render::RenderReport {
    let mut a = vec![
        "--out",
        out.to_str().unwrap(),
        "--campaign",
        "--radii-mm",
        "3,7",
        "--heights-cm",
        "1.5,6,50",
        "--repeats",
        "2",
        "--contact",
        "wide",
        "--scaled-manifest",
        "--seed",
        seed,
    ];
    a.extend_from_slice(&SMALL);
    render(&args(&a)).unwrap()
}

/// A wide campaign: every drop rendered, and its `truth.json` holds the law
/// (n in range, K_n = K δ_ref^{2−n}, δ_ref from Eq. (4), the damping's kind
/// and coefficient, adhesion, the force's zero exactly when the law has
/// one), the restitution asked for, and contact flags from δ;
/// `--scaled-manifest` writes runs_scaled.csv with the true scale. The same
/// seed gives the same bytes; another seed another draw.
#[test]
fn a_wide_campaign_records_its_laws_and_is_deterministic() {
    let (d1, d2, d3) = (
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
    );
    let report = wide_render(d1.path(), "5");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    assert_eq!(report.drops.len(), 12);
    let mut kinds = std::collections::BTreeSet::new();
    for d in &report.drops {
        let text = std::fs::read_to_string(d.dir.join("truth.json")).unwrap();
        let t: Truth = serde_json::from_str(&text).unwrap();
        let c = t
            .contact
            .as_ref()
            .expect("a wide render records its contact");
        let json: serde_json::Value = serde_json::from_str(&text).unwrap();
        for key in [
            "force_n",
            "K_n_N_per_m_n",
            "K_N_per_m2",
            "delta_ref_mm",
            "damping_model",
            "damping_c_N_s_per_m",
            "hunt_crossley_alpha_s_per_m",
            "adhesion",
            "t_force_zero_s",
            "delta_force_zero_mm",
            "contact_law",
        ] {
            assert!(json.get(key).is_some(), "{}: no `{key}`", t.run);
        }
        assert_eq!(c.contact_physics, "wide");
        assert!((1.4..=2.6).contains(&c.force_n), "{}", c.force_n);
        let p = drop_params(t.sphere_radius_mm, t.v_impact_m_s, 0.0);
        assert!(rel(c.delta_ref_mm, p.delta_max_eq4_m() * 1e3) < 1e-12);
        assert!(rel(c.model_stiffness_n_per_m2, p.stiffness_n_m2()) < 1e-12);
        let k_n = c.model_stiffness_n_per_m2 * (c.delta_ref_mm * 1e-3).powf(2.0 - c.force_n);
        assert!(rel(c.stiffness_n_per_m_n, k_n) < 1e-12);
        kinds.insert((c.damping_model.clone(), c.adhesion));
        match c.damping_model.as_str() {
            "none" => {
                assert_eq!(t.restitution_requested, 1.0);
                assert!(c.damping_c_n_s_per_m.is_none() && c.hunt_crossley_alpha_s_per_m.is_none());
            }
            "linear" => {
                assert!(c.damping_c_n_s_per_m.unwrap() > 0.0);
                assert_eq!(c.damping_c_n_s_per_m, Some(t.damping_n_s_m));
                assert!((0.3..=0.98).contains(&t.restitution_requested));
                // a linear force that cannot pull always reaches 0 first
                assert_eq!(c.t_force_zero_s.is_some(), !c.adhesion, "{}", t.run);
            }
            "hunt_crossley" => {
                assert!(c.hunt_crossley_alpha_s_per_m.unwrap() > 0.0);
                assert_eq!(t.damping_n_s_m, 0.0);
            }
            other => panic!("damping_model {other}"),
        }
        assert!((t.restitution - t.restitution_requested).abs() < 1e-9);
        if let (Some(tf), Some(df)) = (c.t_force_zero_s, c.delta_force_zero_mm) {
            assert!(tf > t.t_max_s && tf < t.t_rebound_s && df > 0.0 && df < t.delta_max_mm);
        } else {
            assert_eq!(c.delta_force_zero_mm, None);
        }
        for f in &t.frames {
            assert_eq!(f.in_contact, f.t_s > t.t_contact_s && f.t_s < t.t_rebound_s);
        }
    }
    assert!(kinds.len() >= 4, "12 drops drew only {kinds:?}");
    // runs.csv leaves the scale to the pipeline; runs_scaled.csv gives the truth's
    let plain = dropscope::dataset::manifest::read_manifest(&d1.path().join("runs.csv")).unwrap();
    let scaled =
        dropscope::dataset::manifest::read_manifest(&d1.path().join("runs_scaled.csv")).unwrap();
    assert_eq!(plain.len(), 12);
    for ((a, b), d) in plain.iter().zip(&scaled).zip(&report.drops) {
        assert_eq!((&a.run, &a.path, a.mm_per_px), (&b.run, &b.path, None));
        assert_eq!(b.mm_per_px, Some(d.truth.mm_per_px));
    }

    wide_render(d2.path(), "5");
    let (f1, f2) = (files(d1.path()), files(d2.path()));
    assert_eq!(f1.len(), f2.len());
    for (a, b) in f1.iter().zip(&f2) {
        assert!(
            std::fs::read(a).unwrap() == std::fs::read(b).unwrap(),
            "{}",
            a.display()
        );
    }
    wide_render(d3.path(), "6");
    let truth = |d: &std::path::Path| std::fs::read(d.join("R3mm_H6cm_01/truth.json")).unwrap();
    assert!(truth(d1.path()) != truth(d3.path()));
}

/// One law set on the command line: n, the damping kind and no adhesion,
/// recorded as `set`; a default render's truth has no contact keys.
#[test]
fn a_law_set_by_options_is_rendered_and_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("set");
    let mut a = vec![
        "--out",
        out.to_str().unwrap(),
        "--drop",
        "4.5:12",
        "--force-exponent",
        "1.6",
        "--damping",
        "hunt-crossley",
        "--restitution",
        "0.6",
        "--no-adhesion",
    ];
    a.extend_from_slice(&SMALL);
    let report = render(&args(&a)).unwrap();
    let t = &report.drops[0].truth;
    let c = t.contact.as_ref().unwrap();
    assert_eq!(
        (
            c.contact_physics.as_str(),
            c.force_n,
            c.damping_model.as_str(),
            c.adhesion
        ),
        ("set", 1.6, "hunt_crossley", false)
    );
    assert!((t.restitution - 0.6).abs() < 1e-9);

    let plain = dir.path().join("plain");
    let mut a = vec!["--out", plain.to_str().unwrap(), "--drop", "4.5:12"];
    a.extend_from_slice(&SMALL);
    render(&args(&a)).unwrap();
    let text = std::fs::read_to_string(plain.join("R4.5mm_H12cm_01/truth.json")).unwrap();
    assert!(!text.contains("force_n") && !text.contains("damping_model"));
    let t: Truth = serde_json::from_str(&text).unwrap();
    assert_eq!(t.contact, None);
}

/// Contact options that contradict each other are refused, naming the option.
#[test]
fn contradictory_contact_options_name_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    for (bad, name, says) in [
        (
            vec!["--out", out, "--damping", "none", "--restitution", "0.8"],
            "restitution",
            "--damping none",
        ),
        (
            vec!["--out", out, "--damping", "linear"],
            "damping",
            "--restitution below 1",
        ),
        (
            vec!["--out", out, "--force-exponent", "5"],
            "force-exponent",
            "[1, 4]",
        ),
    ] {
        let err = render(&args(&bad)).unwrap_err().to_string();
        assert!(err.contains(name) && err.contains(says), "{err}");
    }
}
