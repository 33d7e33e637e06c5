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
#![no_main]

use dropscope::config::Surface;
use dropscope::events::{EventConfig, Geometry, TrackPoint};
use dropscope::measure::{measure_drop, DropInfo};
use dropscope::render::physics::{DropParams, Trajectory};
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
const MAX_CONTACT_FRAMES: f64 = 40.0;

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
    };
    // At most MAX_CONTACT_FRAMES frames in the contact: the fit integrates
    // every trajectory over them (20 steps a frame), and that sets the cost
    // of one execution (a few ms at 40 frames).
    let fps = fps_asked.min(MAX_CONTACT_FRAMES / params.tau_c_eq5_s());
    let exposure_s = exposure_frac / fps;
    let t_end = 0.012;
    let Ok(traj) = Trajectory::simulate(&params, 0.0, t_end, params.default_step_s(2e-6)) else {
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
    let before = (b.range(5.0, 40.0) as i64).max(1);
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
        ..EventConfig::default()
    };
    let _ = measure_drop(&info(r_m * 1e3), &track, &geom, &cfg);
});
