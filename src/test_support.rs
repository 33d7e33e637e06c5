//! Test support: an exact drop and its noisy track, for the event and
//! kinematics tests.

use crate::events::{Geometry, TrackPoint};
use crate::kinematics::SphereParams;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// An exact drop for the tests: free flight, elastic-foundation contact
/// F = k·δ² (k = π E φ R / h, no damping), free flight. Contact starts at
/// t = t0; before it δ(t) = v_in·u + ½ g u² (u = t − t0), during it the
/// ODE is integrated by RK4 with a 10 ns step, after it the flight is
/// analytic again.
pub struct Drop {
    pub g: f64,
    pub k_over_m: f64,
    pub v_in: f64,
    pub t0: f64,
    pub t_r: f64,
    pub v_out: f64,
    pub delta_max: f64,
}

const H_SIM: f64 = 1e-8;

fn accel(d: f64, g: f64, km: f64) -> f64 {
    g - if d > 0.0 { km * d * d } else { 0.0 }
}

/// One classic RK4 step of δ'' = a(δ) on the state (δ, δ').
fn rk4(d: f64, v: f64, h: f64, g: f64, km: f64) -> (f64, f64) {
    let (k1x, k1v) = (v, accel(d, g, km));
    let (k2x, k2v) = (v + 0.5 * h * k1v, accel(d + 0.5 * h * k1x, g, km));
    let (k3x, k3v) = (v + 0.5 * h * k2v, accel(d + 0.5 * h * k2x, g, km));
    let (k4x, k4v) = (v + h * k3v, accel(d + h * k3x, g, km));
    (
        d + h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x),
        v + h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v),
    )
}

impl Drop {
    pub fn new(radius_m: f64, v_in: f64, t0: f64) -> Self {
        let s = SphereParams {
            radius_m,
            density_kg_m3: 7800.0,
        };
        let k = std::f64::consts::PI * 1.6e6 * 0.625 * radius_m / 3.5e-3;
        let (g, km) = (9.81, k / s.mass_kg());
        let (mut d, mut v, mut t) = (0.0, v_in, 0.0);
        let mut delta_max: f64 = 0.0;
        loop {
            let (d2, v2) = rk4(d, v, H_SIM, g, km);
            if d2 <= 0.0 && v2 < 0.0 {
                // Refine the crossing inside the step by bisection.
                let (mut lo, mut hi) = (0.0, H_SIM);
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if rk4(d, v, mid, g, km).0 > 0.0 {
                        lo = mid
                    } else {
                        hi = mid
                    }
                }
                let (_, vr) = rk4(d, v, hi, g, km);
                return Drop {
                    g,
                    k_over_m: km,
                    v_in,
                    t0,
                    t_r: t0 + t + hi,
                    v_out: -vr,
                    delta_max,
                };
            }
            if v > 0.0 && v2 <= 0.0 {
                let (mut lo, mut hi) = (0.0, H_SIM);
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if rk4(d, v, mid, g, km).1 > 0.0 {
                        lo = mid
                    } else {
                        hi = mid
                    }
                }
                delta_max = delta_max.max(rk4(d, v, lo, g, km).0);
            }
            d = d2;
            v = v2;
            t += H_SIM;
        }
    }

    /// Penetration at time t (m).
    pub fn delta(&self, t: f64) -> f64 {
        if t <= self.t0 {
            let u = t - self.t0;
            return self.v_in * u + 0.5 * self.g * u * u;
        }
        if t >= self.t_r {
            let u = t - self.t_r;
            return -self.v_out * u + 0.5 * self.g * u * u;
        }
        let (mut d, mut v, mut u) = (0.0, self.v_in, 0.0);
        let target = t - self.t0;
        while u + H_SIM < target {
            (d, v) = rk4(d, v, H_SIM, self.g, self.k_over_m);
            u += H_SIM;
        }
        rk4(d, v, target - u, self.g, self.k_over_m).0
    }
}

pub fn geometry() -> Geometry {
    Geometry {
        surface_row_px: 300.0,
        surface_slope: 0.0,
        surface_row_err_px: 0.01,
        radius_px: 90.0,
        radius_err_px: 0.01,
        mm_per_px: 0.05,
        mm_per_px_err: 0.0,
        scale_from_radius: true,
    }
}

pub fn track(drop: &Drop, geom: &Geometry, sigma_px: f64, seed: u64) -> Vec<TrackPoint> {
    let fps = 10_000.0;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 1.0).unwrap();
    let s_m = geom.mm_per_px * 1e-3;
    (-35..70)
        .map(|n: i64| {
            let t = n as f64 / fps;
            let d = drop.delta(t);
            let z = geom.surface_row_px - geom.radius_px + d / s_m;
            TrackPoint {
                frame: n,
                t_s: t,
                x_px: 256.0,
                z_px: z + sigma_px * noise.sample(&mut rng),
                sigma_z_px: sigma_px.max(1e-4),
                half_width_px: None,
                sigma_half_width_px: None,
            }
        })
        .collect()
}

pub fn sphere() -> SphereParams {
    SphereParams {
        radius_m: 4.5e-3,
        density_kg_m3: 7800.0,
    }
}
