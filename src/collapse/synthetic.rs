//! Synthetic drops with known collapse laws, for tests and demonstrations:
//! the truth is exact, the "measured" columns carry seeded Gaussian noise of
//! a stated relative size, and the `_err` columns state that size.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::config::Surface;
use crate::dataset::{DropRecord, DropStatus};

/// What to generate.
#[derive(Debug, Clone)]
pub struct SyntheticSpec {
    /// Sphere radii, mm.
    pub radii_mm: Vec<f64>,
    /// Drops per radius, at velocities spaced log-uniformly over `v_range_m_s`.
    pub per_radius: usize,
    /// Impact speeds, from the lowest to the highest, m/s.
    pub v_range_m_s: [f64; 2],
    /// Relative one-sigma noise of (v, δ, a, τc); also written as the `_err`s.
    pub rel_noise: [f64; 4],
    /// Sphere density, kg/m³.
    pub density_kg_m3: f64,
    /// The surface the drops hit.
    pub surface: Surface,
    /// Seed of the noise.
    pub seed: u64,
}

impl SyntheticSpec {
    /// The paper's set-up: R = 3, 4, 4.5, 5, 7 mm, v = 0.5–3.1 m/s, PDMS.
    pub fn paper(per_radius: usize, seed: u64) -> Self {
        SyntheticSpec {
            radii_mm: vec![3.0, 4.0, 4.5, 5.0, 7.0],
            per_radius,
            v_range_m_s: [0.5, 3.1],
            rel_noise: [0.003, 0.01, 0.01, 0.01],
            density_kg_m3: 7800.0,
            surface: Surface::paper_pdms(),
            seed,
        }
    }
}

/// A standard normal deviate (Box–Muller).
fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = 1.0 - rng.gen::<f64>(); // (0, 1]
    let u2: f64 = rng.gen::<f64>();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

fn record(
    spec: &SyntheticSpec,
    rng: &mut ChaCha8Rng,
    run: String,
    r_mm: f64,
    [v, delta_mm, a_mm, tau_ms]: [f64; 4],
) -> DropRecord {
    let mut noisy = |x: f64, rel: f64| {
        let m = x * (1.0 + rel * normal(rng));
        (m, m * rel)
    };
    let (v_m, v_e) = noisy(v, spec.rel_noise[0]);
    let (d_m, d_e) = noisy(delta_mm, spec.rel_noise[1]);
    let (a_m, a_e) = noisy(a_mm, spec.rel_noise[2]);
    let (t_m, t_e) = noisy(tau_ms, spec.rel_noise[3]);
    let mut rec = DropRecord::failed(&run, r_mm, "");
    rec.status = DropStatus::Ok;
    rec.sphere_density_kg_m3 = spec.density_kg_m3;
    rec.v_impact_m_s = Some(v_m);
    rec.v_impact_m_s_err = Some(v_e);
    rec.delta_max_mm = Some(d_m);
    rec.delta_max_mm_err = Some(d_e);
    rec.a_max_mm = Some(a_m);
    rec.a_max_mm_err = Some(a_e);
    rec.a_geom_mm = Some((r_mm * r_mm - (r_mm - d_m).powi(2)).sqrt());
    rec.tau_c_ms = Some(t_m);
    rec.tau_c_ms_err = Some(t_e);
    rec
}

fn velocities(spec: &SyntheticSpec) -> Vec<f64> {
    let [lo, hi] = spec.v_range_m_s;
    let n = spec.per_radius.max(2);
    (0..spec.per_radius)
        .map(|i| lo * (hi / lo).powf(i as f64 / (n - 1) as f64))
        .collect()
}

/// Drops obeying Ψ = A1 + A2 Ξ + A3 Ξ² (Eq. (8)) and Ω = B1 + B2 Ξ + B3 Ξ²
/// exactly before noise, with Ξ drawn uniformly from `xi_range` for each drop.
/// (Given R, v and Ξ: ξ = Ξ (κη/φ)^{1/6}, Π = Ψ (κη/φ)^{1/3}, ω = Ω (κη/φ)^{1/3}.)
pub fn eq8_dataset(
    spec: &SyntheticSpec,
    a: [f64; 3],
    b: [f64; 3],
    xi_range: [f64; 2],
) -> Vec<DropRecord> {
    let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
    let s = &spec.surface;
    let mut out = Vec::new();
    for &r_mm in &spec.radii_mm {
        for (i, v) in velocities(spec).into_iter().enumerate() {
            let big_xi = xi_range[0] + (xi_range[1] - xi_range[0]) * rng.gen::<f64>();
            let r = r_mm * 1e-3;
            let eta = spec.density_kg_m3 * v * v / s.modulus_pa;
            let kappa = s.pillar_height_m / r;
            let f3 = (kappa * eta / s.solid_fraction).cbrt();
            let psi = a[0] + a[1] * big_xi + a[2] * big_xi * big_xi;
            let omega_big = b[0] + b[1] * big_xi + b[2] * big_xi * big_xi;
            let delta_mm = psi * f3 * r_mm;
            let a_mm = big_xi * f3.sqrt() * r_mm;
            let tau_ms = omega_big * f3 * r / v * 1e3;
            let run = format!("R{r_mm}_{i:02}");
            out.push(record(
                spec,
                &mut rng,
                run,
                r_mm,
                [v, delta_mm, a_mm, tau_ms],
            ));
        }
    }
    out
}

/// Drops obeying pure power laws per radius: Π = 0.9 η^ν and τc = 3 ms ·
/// (v / 1 m/s)^μ, with a = 0.8 × the geometric value; `laws` gives (R, ν, μ).
pub fn power_law_dataset(spec: &SyntheticSpec, laws: &[(f64, f64, f64)]) -> Vec<DropRecord> {
    let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
    let mut out = Vec::new();
    for &(r_mm, nu, mu) in laws {
        for (i, v) in velocities(spec).into_iter().enumerate() {
            let eta = spec.density_kg_m3 * v * v / spec.surface.modulus_pa;
            let delta_mm = 0.9 * eta.powf(nu) * r_mm;
            let a_mm = 0.8 * (r_mm * r_mm - (r_mm - delta_mm).powi(2)).sqrt();
            let tau_ms = 3.0 * v.powf(mu);
            let run = format!("R{r_mm}_{i:02}");
            out.push(record(
                spec,
                &mut rng,
                run,
                r_mm,
                [v, delta_mm, a_mm, tau_ms],
            ));
        }
    }
    out
}

/// Write `rows` as a track file at `path`, as `process` writes one.
pub fn write_track(path: &std::path::Path, rows: &[crate::dataset::TrackRow]) -> csv::Result<()> {
    let mut w = csv::Writer::from_path(path)?;
    for r in rows {
        w.serialize(r)?;
    }
    w.flush()?;
    Ok(())
}

/// A track (`tracks/<run>.csv` rows) for a drop falling at `v_m_s` onto the
/// elastic-foundation contact F = (πEφR/h) δ² (Maruoka 2019 above Eq. (1b)),
/// integrated with RK4 at 100 substeps per frame and sampled at `fps`;
/// scale `mm_per_px`, undeformed surface at row 300. The force column is the
/// model force (no noise). Returns the rows and (t_contact, t_rebound) in s.
pub fn contact_track(
    r_mm: f64,
    density_kg_m3: f64,
    v_m_s: f64,
    surface: &Surface,
    fps: f64,
    mm_per_px: f64,
) -> (Vec<crate::dataset::TrackRow>, f64, f64) {
    const G: f64 = 9.81;
    let r = r_mm * 1e-3;
    let m = density_kg_m3 * 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    let k = std::f64::consts::PI * surface.modulus_pa * surface.solid_fraction * r
        / surface.pillar_height_m;
    // State: penetration δ (m, positive into the surface) and its rate.
    let acc = |d: f64| G - if d > 0.0 { k * d * d / m } else { 0.0 };
    let dt_frame = 1.0 / fps;
    let h = dt_frame / 100.0;
    // Start 2 mm above the surface, with the speed that reaches v at contact.
    let d0 = -2e-3;
    let mut state = (d0, (v_m_s * v_m_s - 2.0 * G * 2e-3).max(0.0).sqrt());
    let mut t = 0.0;
    let mut rows = Vec::new();
    let (mut t_in, mut t_out) = (f64::NAN, f64::NAN);
    let y_s = 300.0;
    let r_px = r_mm / mm_per_px;
    for frame in 0..2000i64 {
        let (d, _) = state;
        let delta_mm = d * 1e3;
        let z_px = y_s - r_px + delta_mm / mm_per_px;
        rows.push(crate::dataset::TrackRow {
            frame,
            t_s: t,
            x_px: Some(256.0),
            z_px: Some(z_px),
            r_px: Some(r_px),
            residual_px: Some(0.05),
            edge_points: 400,
            in_contact: d > 0.0,
            delta_mm: Some(delta_mm),
            sigma_z_px: Some(0.02),
            sigma_x_px: Some(0.02),
            r_free_px: None,
            sigma_r_free_px: None,
            force_n: (d > 0.0).then_some(k * d * d),
            flags: String::new(),
        });
        for _ in 0..100 {
            let (d, u) = state;
            let k1 = (u, acc(d));
            let k2 = (u + 0.5 * h * k1.1, acc(d + 0.5 * h * k1.0));
            let k3 = (u + 0.5 * h * k2.1, acc(d + 0.5 * h * k2.0));
            let k4 = (u + h * k3.1, acc(d + h * k3.0));
            let nd = d + h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
            let nu = u + h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
            if d <= 0.0 && nd > 0.0 && t_in.is_nan() {
                t_in = t + h * (-d) / (nd - d);
            }
            if d > 0.0 && nd <= 0.0 && t_out.is_nan() {
                t_out = t + h * d / (d - nd);
            }
            state = (nd, nu);
            t += h;
        }
        // Stop 2 mm above the surface on the way up.
        if !t_out.is_nan() && state.0 < -2e-3 {
            break;
        }
    }
    (rows, t_in, t_out)
}
