use super::*;

fn paper_drop(radius_mm: f64, height_cm: f64, g: f64) -> DropParams {
    DropParams {
        sphere_radius_m: radius_mm * 1e-3,
        sphere_density_kg_m3: 7800.0,
        surface: Surface::paper_pdms(),
        gravity_m_s2: g,
        impact_speed_m_s: (2.0 * STANDARD_GRAVITY_M_S2 * height_cm * 1e-2).sqrt(),
        damping_n_s_m: 0.0,
        law: ContactLaw::MODEL,
    }
}

/// B(1/3, 1/2) = 3 ∫₀¹ du / √(1 − u³); with u = 1 − s² the integrand is
/// smooth: 6 ∫₀¹ s / √(1 − (1 − s²)³) ds. Simpson with 20 000 panels is
/// accurate to ~1e-12 on this smooth integrand.
#[test]
fn beta_constant_matches_quadrature() {
    let f = |s: f64| {
        if s == 0.0 {
            // limit s / √(3 s² − 3 s⁴ + s⁶) → 1/√3
            1.0 / 3f64.sqrt()
        } else {
            s / (1.0 - (1.0 - s * s).powi(3)).sqrt()
        }
    };
    let n = 20_000;
    let h = 1.0 / n as f64;
    let mut sum = f(0.0) + f(1.0);
    for i in 1..n {
        sum += f(i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    let b = 6.0 * sum * h / 3.0;
    assert!((b - BETA_THIRD_HALF).abs() < 1e-10, "{b}");
}

#[test]
fn contact_starts_and_ends_exactly_on_the_surface() {
    let p = paper_drop(4.5, 12.0, STANDARD_GRAVITY_M_S2);
    let step = p.default_step_s(1e-6);
    let tr = Trajectory::simulate(&p, 1e-4, 0.02, step).unwrap();
    let b = tr.bounces()[0];
    assert!(tr.state(b.t_contact_s).0.abs() < 1e-15);
    assert!(
        tr.state(b.t_rebound_s).0.abs() < 1e-12,
        "{:?}",
        tr.state(b.t_rebound_s)
    );
    // continuity across the rebound (contact piece vs flight piece)
    let eps = 1e-9;
    let before = tr.state(b.t_rebound_s - eps).0;
    let after = tr.state(b.t_rebound_s + eps).0;
    assert!((before + after).abs() < 1e-12 && before > 0.0 && after < 0.0);
    // the maximum is a maximum
    let dm = tr.delta_m(b.t_max_s);
    assert!((dm - b.delta_max_m).abs() < 1e-15);
    assert!(tr.delta_m(b.t_max_s - 1e-6) < dm && tr.delta_m(b.t_max_s + 1e-6) < dm);
}

#[test]
fn released_from_rest_at_the_drop_height() {
    let p = paper_drop(3.0, 6.0, STANDARD_GRAVITY_M_S2);
    let tr = Trajectory::simulate(&p, 0.0, 0.01, 1e-6).unwrap();
    let t_release = -p.impact_speed_m_s / STANDARD_GRAVITY_M_S2;
    let (d, w) = tr.state(t_release);
    assert!((d + 0.06).abs() < 1e-12 && w.abs() < 1e-12, "{d} {w}");
    assert_eq!(tr.state(t_release - 1.0), (d, 0.0));
}
