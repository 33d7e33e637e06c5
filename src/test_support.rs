//! Test support: an exact drop (the renderer's physics) and its noisy
//! track, for the event and kinematics tests; the AVX2 check of the tests
//! that compare a vector path with its portable twin.

use crate::config::Surface;
use crate::measure::events::{Geometry, TrackPoint};
use crate::measure::kinematics::SphereParams;
use crate::render::physics::{ContactLaw, DropParams, Trajectory};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// An exact drop for the tests: the renderer's contact physics
/// ([`Trajectory`]: free-flight parabolas, elastic-foundation contact
/// F = K·δ² integrated by RK4, no damping) with the paper's PDMS and
/// ρ = 7800 kg/m³, first contact at `t0` with speed `v_in`.
pub struct Drop {
    pub v_in: f64,
    pub t0: f64,
    pub t_r: f64,
    pub v_out: f64,
    pub delta_max: f64,
    traj: Trajectory,
}

impl Drop {
    pub fn new(radius_m: f64, v_in: f64, t0: f64) -> Self {
        let params = DropParams {
            sphere_radius_m: radius_m,
            sphere_density_kg_m3: 7800.0,
            surface: Surface::paper_pdms(),
            gravity_m_s2: 9.81,
            impact_speed_m_s: v_in,
            damping_n_s_m: 0.0,
            law: ContactLaw::MODEL,
        };
        let traj = Trajectory::simulate(&params, t0, t0 + 0.01, params.default_step_s(1e-6))
            .expect("valid test drop");
        let b = traj.bounces()[0];
        Drop {
            v_in,
            t0,
            t_r: b.t_rebound_s,
            v_out: b.v_rebound_m_s,
            delta_max: b.delta_max_m,
            traj,
        }
    }

    /// Penetration at time t (m; negative above the surface).
    pub fn delta(&self, t: f64) -> f64 {
        self.traj.state(t).0
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
    track_exposed(drop, geom, sigma_px, seed, 0.0)
}

/// [`track`] as a camera with exposure `exposure_s` sees it: each frame's
/// position is the mean of the position over its exposure (a 64-point
/// midpoint rule), as the renderer's motion blur gives it.
pub fn track_exposed(
    drop: &Drop,
    geom: &Geometry,
    sigma_px: f64,
    seed: u64,
    exposure_s: f64,
) -> Vec<TrackPoint> {
    let fps = 10_000.0;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 1.0).unwrap();
    let s_m = geom.mm_per_px * 1e-3;
    (-35..70)
        .map(|n: i64| {
            let t = n as f64 / fps;
            const SUB: usize = 64;
            let d = if exposure_s > 0.0 {
                (0..SUB)
                    .map(|k| drop.delta(t + exposure_s * ((k as f64 + 0.5) / SUB as f64 - 0.5)))
                    .sum::<f64>()
                    / SUB as f64
            } else {
                drop.delta(t)
            };
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

/// A fresh output folder `out/` (in the returned temporary folder) holding
/// `tracks/<name>` with `bytes` for each of `tracks`.
pub fn out_with_tracks(tracks: &[(&str, &[u8])]) -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir_all(out.join("tracks")).unwrap();
    for (name, bytes) in tracks {
        std::fs::write(out.join("tracks").join(name), bytes).unwrap();
    }
    (dir, out)
}

/// A cache entry of `run` under `key` that wrote `outputs` (its record a
/// failed row, its input unreadable).
pub fn cache_entry(
    run: &str,
    key: &str,
    outputs: Vec<crate::job::cache::OutputFile>,
) -> crate::job::cache::Entry {
    crate::job::cache::Entry {
        schema: crate::job::cache::CACHE_SCHEMA,
        dropscope_version: env!("CARGO_PKG_VERSION").into(),
        key: key.into(),
        input: crate::job::cache::Fingerprint::unreadable(std::path::Path::new("x")),
        outputs,
        frames: 1,
        record: crate::dataset::DropRecord::failed(run, 4.5, "why"),
        scene: None,
        scene_key: None,
        entry_sha256: String::new(),
    }
}

pub fn sphere() -> SphereParams {
    SphereParams {
        radius_m: 4.5e-3,
        density_kg_m3: 7800.0,
    }
}

/// Fail a test that compares `what` with AVX2 and without when the CPU has
/// no AVX2: passing would then say nothing.
pub fn require_avx2(what: &str) {
    #[cfg(target_arch = "x86_64")]
    assert!(
        std::arch::is_x86_feature_detected!("avx2"),
        "this test compares {what} with AVX2 and without: run it on a CPU with AVX2"
    );
    #[cfg(not(target_arch = "x86_64"))]
    let _ = what;
}

/// A manifest row `name` (path `name`, R = 3 mm) of camera set-up `setup`.
pub fn run_spec(name: &str, setup: Option<&str>) -> crate::dataset::manifest::RunSpec {
    crate::dataset::manifest::RunSpec {
        run: name.into(),
        path: std::path::PathBuf::from(name),
        sphere_radius_mm: 3.0,
        drop_height_cm: None,
        fps: None,
        mm_per_px: None,
        surface: None,
        sphere_density_kg_m3: None,
        setup: setup.map(String::from),
        review: Default::default(),
        number_digits: None,
    }
}

/// The embedded default configuration (`pipeline.toml`), its relative
/// paths taken from the working folder.
pub fn default_config() -> crate::config::PipelineConfig {
    crate::config::PipelineConfig::from_toml_str(
        crate::config::EMBEDDED_DEFAULT,
        std::path::Path::new("pipeline.toml"),
        std::path::Path::new(""),
    )
    .expect("the embedded pipeline.toml is valid")
}
