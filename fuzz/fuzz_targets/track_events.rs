//! Fuzz the path from frame times and a track to the events, the
//! kinematics and the contact-law fit (`measure_drop`): where the
//! `f64::clamp` panic on reversed times and the 260 s fit on jittered times
//! lived. Two modes by the first byte's low bit:
//! - raw: every track point (time, x, z, σ) and the geometry taken from the
//!   bytes as they come (NaN, reversed, huge);
//! - shaped: an exact drop (the renderer's physics) whose size, speed,
//!   frame rate, noise and scale come from the bytes, then damaged frame by
//!   frame (times jittered by up to 1.5 intervals, frames deleted, positions
//!   moved), so that the fits themselves are reached.
//! Any input must give a record or an error, never a panic.
//!
//! Cost per execution (a campaign is 10 million of them): the contact-law fit
//! integrates a trajectory over the contact frames for every step of its
//! search, 2–16 ms an execution with 40-frame contacts and the product's
//! work limit (1 000 trajectories), 82 % of the time in its integrator.
//! Here a shaped drop's contact spans at most 12 frames and its track ends
//! 24 frames after the contact, and the fit is given a work limit of
//! [`FIT_MAX_TRAJECTORIES`] through `EventConfig::force_fit_max_trajectories`
//! (the product's configuration of it): a wandering fit (jittered or
//! reversed times) is stopped early by the same check that stops it in the
//! product, and a fit that converges within it still reaches the law's
//! checks.
#![no_main]

use dropscope::config::Surface;
use dropscope::measure::events::{EventConfig, Geometry, TrackPoint};
use dropscope::measure::{measure_drop, DropInfo};
use dropscope::render::physics::{ContactLaw, DropParams, Trajectory};
use libfuzzer_sys::fuzz_target;

struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn u8(&mut self) -> u8 {
        match self.0.split_first() {
            Some((&b, rest)) => {
                self.0 = rest;
                b
            }
            None => 0,
        }
    }
    fn f64(&mut self) -> f64 {
        let mut b = [0u8; 8];
        for x in &mut b {
            *x = self.u8();
        }
        f64::from_le_bytes(b)
    }
    /// A value in [lo, hi] from one byte.
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * f64::from(self.u8()) / 255.0
    }
}

/// The most frames a shaped drop's contact spans (see the frame rate).
const MAX_CONTACT_FRAMES: f64 = 12.0;

/// Frames of a shaped drop's track after its contact: the force fit uses
/// 12 of them (`events::FLIGHT_FRAMES`), the rebound's parabola at least 5.
const FRAMES_AFTER_CONTACT: f64 = 24.0;

/// The contact-law fit's work limit here, in trajectories (the product's is
/// 1 000; a clean drop's fits need 113–259): about five Levenberg–Marquardt
/// steps of its first fit (one trajectory per parameter for the Jacobian).
/// Chosen on the corpus (libFuzzer's `cov`, docs/input.md): 24 reached 1 287
/// edges, 30 1 363, 40 1 381, 1 000 1 399, for 0.68, 0.81, 1.03 and about
/// 14 s over its 925 inputs.
const FIT_MAX_TRAJECTORIES: usize = 30;

fn info(r_mm: f64) -> DropInfo {
    DropInfo {
        run: "fuzz".into(),
        sphere_radius_mm: r_mm,
        sphere_density_kg_m3: 7800.0,
        surface: "pdms".into(),
    }
}

fuzz_target!(|data: &[u8]| {
    let mut b = Bytes(data);
    let mode = b.u8();
    if mode & 1 == 1 {
        let geom = Geometry {
            surface_row_px: b.f64(),
            surface_slope: b.f64(),
            surface_row_err_px: b.f64(),
            radius_px: b.f64(),
            radius_err_px: b.f64(),
            mm_per_px: b.f64(),
            mm_per_px_err: b.f64(),
            scale_from_radius: b.u8() & 1 == 1,
        };
        let cfg = EventConfig {
            exposure_s: b.f64(),
            force_fit_max_trajectories: FIT_MAX_TRAJECTORIES,
            ..EventConfig::default()
        };
        let mut track = Vec::new();
        while b.0.len() >= 32 && track.len() < 400 {
            track.push(TrackPoint {
                frame: track.len() as i64,
                t_s: b.f64(),
                x_px: b.f64(),
                z_px: b.f64(),
                sigma_z_px: b.f64(),
                half_width_px: None,
                sigma_half_width_px: None,
            });
        }
        let _ = measure_drop(&info(b.f64()), &track, &geom, &cfg);
        return;
    }
    // Shaped: a real bounce, then damage.
    let r_m = b.range(1.5e-3, 8e-3);
    let v_in = b.range(0.3, 3.5);
    let fps_asked = b.range(4_000.0, 40_000.0);
    let sigma_px = b.range(0.0, 0.3);
    let mm_per_px = b.range(0.02, 0.12);
    let exposure_frac = b.range(0.0, 1.0);
    let params = DropParams {
        sphere_radius_m: r_m,
        sphere_density_kg_m3: 7800.0,
        surface: Surface::paper_pdms(),
        gravity_m_s2: 9.81,
        impact_speed_m_s: v_in,
        damping_n_s_m: 0.0,
        law: ContactLaw::MODEL,
    };
    // At most MAX_CONTACT_FRAMES frames in the contact: the fit integrates
    // every trajectory over them (20 steps a frame), and that sets the cost
    // of one execution.
    let fps = fps_asked.min(MAX_CONTACT_FRAMES / params.tau_c_eq5_s());
    let exposure_s = exposure_frac / fps;
    let t_end = params.tau_c_eq5_s() + FRAMES_AFTER_CONTACT / fps;
    // 200 RK4 steps over the contact (the renderer's default takes 2 000):
    // ample for a track that is damaged next, at a tenth of the cost.
    let step_s = params.tau_c_eq5_s() / 200.0;
    let Ok(traj) = Trajectory::simulate(&params, 0.0, t_end, step_s) else {
        return;
    };
    let geom = Geometry {
        surface_row_px: 300.0,
        surface_slope: b.range(-0.01, 0.01),
        surface_row_err_px: 0.01,
        radius_px: r_m * 1e3 / mm_per_px,
        radius_err_px: 0.01,
        mm_per_px,
        mm_per_px_err: 0.0,
        scale_from_radius: true,
    };
    let before = (b.range(5.0, FRAMES_AFTER_CONTACT) as i64).max(1);
    let n_frames = (t_end * fps) as i64;
    let s_m = mm_per_px * 1e-3;
    let mut noise = 0x9E37_79B9_7F4A_7C15u64 ^ u64::from(b.u8());
    let mut gauss = move || {
        // A cheap deterministic noise in [-1, 1].
        noise ^= noise << 13;
        noise ^= noise >> 7;
        noise ^= noise << 17;
        (noise >> 11) as f64 / (1u64 << 52) as f64 * 2.0 - 1.0
    };
    let mut track: Vec<TrackPoint> = (-before..n_frames)
        .map(|n| {
            let t = n as f64 / fps;
            let z = geom.surface_row_px - geom.radius_px + traj.state(t).0 / s_m;
            TrackPoint {
                frame: n,
                t_s: t,
                x_px: 256.0,
                z_px: z + sigma_px * gauss(),
                sigma_z_px: sigma_px.max(1e-3),
                half_width_px: None,
                sigma_half_width_px: None,
            }
        })
        .collect();
    // Damage: (frame, what, amount) triples.
    while b.0.len() >= 3 && !track.is_empty() {
        let k = usize::from(b.u8()) * track.len() / 256;
        let what = b.u8() % 4;
        let amount = (f64::from(b.u8()) / 255.0 * 2.0 - 1.0) * 1.5;
        match what {
            0 => track[k].t_s += amount / fps,
            1 => {
                track.remove(k);
            }
            2 => track[k].z_px += amount * 5.0,
            _ => track[k].sigma_z_px *= 1.0 + amount.abs() * 10.0,
        }
    }
    let cfg = EventConfig {
        exposure_s,
        force_fit_max_trajectories: FIT_MAX_TRAJECTORIES,
        ..EventConfig::default()
    };
    let _ = measure_drop(&info(r_m * 1e3), &track, &geom, &cfg);
});
