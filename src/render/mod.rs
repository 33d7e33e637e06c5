//! `dropscope render`: synthetic drops with exact truth, written the way
//! Phantom Camera Control exports a recording (SPEC §4).
//!
//! | file | does |
//! | --- | --- |
//! | [`physics`] | the contact ODE, its events and the exact motion |
//! | [`contact`] | each drop's contact law: the model's, set, or drawn (`--contact wide`) |
//! | [`coverage`] | exact pixel coverage of disk, line and pillars |
//! | [`raster`] | one frame from the sphere centres over the exposure |
//! | [`optics`] | a real camera's effects: strengths per drop and set-up, roll and distortion |
//! | [`camera`] | one frame as a real camera records it (`--preset real`) |
//! | [`export`] | frame files, the PCC XML side file, `truth.json` |
//! | [`truth`] | the `truth.json` schema |
//! | `options` | presets, [`RenderArgs`] and [`RenderSettings`] |
//! | [`campaign`] | the paper's grid and the `runs.csv` manifest |
//!
//! # Conventions
//!
//! Image number `n` (the camera's, negative before the trigger) has its
//! mid-exposure at `t = n / fps` after the trigger; motion blur integrates
//! over `[t − exposure/2, t + exposure/2]`. The first contact falls at a
//! random phase within image 0's frame interval, `t_contact ∈ [0, 1/fps)`,
//! as when a PCC user triggers on the impact; the movie starts
//! `frames_before` images earlier and ends `frames_after` images after the
//! loss of contact. The sphere falls straight down column `impact_column_px`;
//! the centre row is `z = y_s(x) − R_px + d / s` with `d` the signed depth of
//! the sphere's lowest point below the surface (physics) and `s` the scale.
//!
//! Randomness: every frame's noise comes from a ChaCha8 generator seeded by
//! `(seed, run, image number)`, the run's layout (contact phase, column,
//! surface row, pillar phase) from `(seed, run)`, the dust from `seed` alone.
//! Frames are rendered in parallel; the bytes do not depend on the number of
//! threads.

pub mod camera;
pub mod campaign;
pub mod contact;
pub mod coverage;
mod error;
pub mod export;
pub mod optics;
mod options;
pub mod physics;
pub mod raster;
mod rng;
pub mod truth;

pub use error::RenderError;
use options::positive;
pub use options::{Preset, RenderArgs, RenderSettings};
pub use rng::rng_for;

use std::path::{Path, PathBuf};

use crate::manifest::ManifestRow;
use camera::CameraRaster;
use campaign::DropSpec;
use export::{CineSink, FolderSink, FrameFormat, FrameSink, PccHeader};
use physics::{ContactLaw, Damping, DropParams, Trajectory};
use rand::Rng;
use raster::{Raster, Scene};
use rayon::prelude::*;
use truth::{BounceTruth, ContactTruth, FrameTruth, SurfaceTruth, Truth};

/// What one rendered drop produced.
#[derive(Debug, Clone)]
pub struct DropSummary {
    /// The run's name.
    pub run: String,
    /// The run's folder.
    pub dir: PathBuf,
    /// Number of frames written.
    pub frames: usize,
    /// The exact values behind the drop (its `truth.json`).
    pub truth: Truth,
}

/// What a render produced.
#[derive(Debug, Default)]
pub struct RenderReport {
    /// The drops rendered, in order.
    pub drops: Vec<DropSummary>,
    /// Runs that failed, with the reason; the others were still rendered.
    pub failures: Vec<(String, String)>,
    /// The `runs.csv` written for the drops, ready for `dropscope process --manifest`.
    pub manifest: Option<PathBuf>,
}

impl RenderReport {
    /// Frames written over every drop.
    pub fn frames(&self) -> usize {
        self.drops.iter().map(|d| d.frames).sum()
    }
}

/// Run `dropscope render`: every drop asked for, then the manifest.
/// A drop that fails is reported and the others carry on.
pub fn render(args: &RenderArgs) -> Result<RenderReport, RenderError> {
    render_with_progress(args, &mut |_, _, _| {})
}

/// [`render`], calling `progress(done, total, run)` after each drop.
pub fn render_with_progress(
    args: &RenderArgs,
    progress: &mut dyn FnMut(usize, usize, &str),
) -> Result<RenderReport, RenderError> {
    let settings = args.settings()?;
    let drops = args.drops()?;
    std::fs::create_dir_all(&args.out).map_err(|source| RenderError::CreateDir {
        path: args.out.clone(),
        source,
    })?;
    let mut report = RenderReport::default();
    for (k, spec) in drops.iter().enumerate() {
        progress(k, drops.len(), &spec.run);
        match render_drop(spec, &settings, &args.out) {
            Ok(d) => report.drops.push(d),
            Err(e @ RenderError::Export(_)) | Err(e @ RenderError::CreateDir { .. }) => {
                return Err(e)
            }
            Err(e) => report.failures.push((spec.run.clone(), e.to_string())),
        }
    }
    // The manifest of what was rendered, one drop or many, ready for
    // `dropscope process --manifest`; with --scaled-manifest the same rows
    // with the true scale beside it.
    let path = args.out.join("runs.csv");
    write_manifest(&path, &report, args, &settings, args.manifest_scale)?;
    report.manifest = Some(path);
    if args.scaled_manifest {
        write_manifest(
            &args.out.join("runs_scaled.csv"),
            &report,
            args,
            &settings,
            true,
        )?;
    }
    Ok(report)
}

/// Write the manifest of the rendered drops to `path`, with the true
/// `mm_per_px` when `with_scale`.
fn write_manifest(
    path: &Path,
    report: &RenderReport,
    args: &RenderArgs,
    settings: &RenderSettings,
    with_scale: bool,
) -> Result<(), RenderError> {
    let bytes = if settings.preset.is_real() {
        let rows: Vec<campaign::SetupManifestRow> = report
            .drops
            .iter()
            .map(|d| campaign::SetupManifestRow {
                run: d.run.clone(),
                path: export::run_input_path(&d.run, args.format),
                sphere_radius_mm: d.truth.sphere_radius_mm,
                drop_height_cm: d.truth.drop_height_cm,
                setup: d
                    .truth
                    .camera
                    .as_ref()
                    .map_or_else(String::new, |c| c.setup.clone()),
                mm_per_px: with_scale.then_some(d.truth.mm_per_px),
            })
            .collect();
        crate::dataset::csv_bytes(&rows)
    } else {
        let rows: Vec<ManifestRow> = report
            .drops
            .iter()
            .map(|d| ManifestRow {
                run: d.run.clone(),
                path: export::run_input_path(&d.run, args.format),
                sphere_radius_mm: d.truth.sphere_radius_mm,
                drop_height_cm: Some(d.truth.drop_height_cm),
                fps: Some(d.truth.fps),
                mm_per_px: with_scale.then_some(d.truth.mm_per_px),
                surface: Some(args.surface_name.clone()),
                sphere_density_kg_m3: Some(d.truth.sphere_density_kg_m3),
                setup: None,
                number_digits: None,
            })
            .collect();
        crate::manifest::to_csv_bytes(&rows)
    };
    crate::util::io::write_atomic(path, &bytes).map_err(|source| {
        RenderError::Export(export::ExportError::Io {
            path: path.to_path_buf(),
            source,
        })
    })
}

/// The default scale: 0.04 mm/px at R = 3 mm, +0.01 per mm of radius, so
/// that R_px runs from 75 px (3 mm) to 87.5 px (7 mm) and a 384-row frame
/// holds the sphere, its approach and its rebound; below 3 mm, R_px = 75.
pub fn default_mm_per_px(radius_mm: f64) -> f64 {
    if radius_mm >= 3.0 {
        0.04 + 0.01 * (radius_mm - 3.0)
    } else {
        radius_mm / 75.0
    }
}

/// The trigger of campaign drop `index`: 2019-06-13 10:00:00 local time
/// (the paper's arXiv month) plus one minute per drop, in 10 ns ticks.
fn trigger_10ns(index: usize) -> i64 {
    let day = export::days_from_civil(2019, 6, 13);
    (day * 86_400 + 10 * 3600 + 60 * index as i64) * 100_000_000
}

/// Sphere centres (px) at `k` instants spread over the exposure of a frame
/// with mid-exposure `t_s` (midpoint rule), or only at `t_s` without motion blur.
fn exposure_samples(
    centre: &impl Fn(f64) -> (f64, f64),
    t_s: f64,
    exposure_s: f64,
    motion_blur: bool,
) -> Vec<(f64, f64)> {
    if !motion_blur {
        return vec![centre(t_s)];
    }
    // Path length over the exposure → about 0.1 px between samples.
    let probe: Vec<f64> = (0..=16)
        .map(|q| centre(t_s + exposure_s * (q as f64 / 16.0 - 0.5)).1)
        .collect();
    let path: f64 = probe.windows(2).map(|w| (w[1] - w[0]).abs()).sum();
    let k = ((path / 0.1).ceil() as usize).clamp(1, 64);
    (0..k)
        .map(|q| centre(t_s + exposure_s * ((q as f64 + 0.5) / k as f64 - 0.5)))
        .collect()
}

/// The plain renderer, or a real camera's.
enum Painter {
    Plain(Box<Raster>),
    Camera(Box<CameraRaster>),
}

/// Render one drop into `<out>/<run>/`.
pub fn render_drop(
    spec: &DropSpec,
    st: &RenderSettings,
    out: &Path,
) -> Result<DropSummary, RenderError> {
    let run = spec.run.as_str();
    let phys_err = |source| RenderError::Physics {
        run: run.to_string(),
        source,
    };
    let radius_m = positive("radius-mm", spec.radius_mm)? * 1e-3;
    let height_m = positive("height-cm", spec.height_cm)? * 1e-2;
    let frame_dt = 1.0 / st.fps;

    // ---- layout, from the run's own generator
    let mut layout = rng_for(st.seed, run, "layout", 0);
    let contact_phase: f64 = layout.gen_range(0.0..1.0);
    let column_offset: f64 = layout.gen_range(-1.0..1.0);
    let row_fraction: f64 = layout.gen_range(0.0..1.0);
    let pillar_phase_frac: f64 = layout.gen_range(0.0..1.0);

    // ---- physics
    let g = st.gravity_m_s2;
    let v = (2.0 * g * height_m).sqrt();
    let mut params = DropParams {
        sphere_radius_m: radius_m,
        sphere_density_kg_m3: st.density_kg_m3,
        surface: st.surface,
        gravity_m_s2: g,
        impact_speed_m_s: v,
        damping_n_s_m: 0.0,
        law: ContactLaw::MODEL,
    };
    let step = params.default_step_s(frame_dt / 100.0);
    // The model's law exactly as it always was, or the law of the contact options.
    let drawn = (!st.contact.is_model()).then(|| contact::draw(&st.contact, st.seed, run));
    let restitution_requested = match &drawn {
        None => {
            params.damping_n_s_m = physics::damping_for_restitution(&params, st.restitution, step)
                .map_err(phys_err)?;
            st.restitution
        }
        Some(c) => {
            params = contact::apply(&params, c, step).map_err(phys_err)?;
            c.restitution
        }
    };
    let t_contact = contact_phase / st.fps;
    let first = Trajectory::simulate(&params, t_contact, t_contact, step).map_err(phys_err)?;
    let b0 = first.bounces()[0];
    let optics_on = st.optics.active();
    // The movie's last contact: the first, or the second when the optics ask
    // for it and the flight between is short enough.
    let mut t_last_rebound = b0.t_rebound_s;
    let flight_s = if g > 0.0 {
        2.0 * b0.v_rebound_m_s / g
    } else {
        f64::INFINITY
    };
    if optics_on && flight_s * st.fps <= st.optics.second_bounce_frames as f64 {
        let probe = Trajectory::simulate(
            &params,
            t_contact,
            b0.t_rebound_s + flight_s + frame_dt,
            step,
        )
        .map_err(phys_err)?;
        if let Some(b1) = probe.bounces().get(1) {
            t_last_rebound = b1.t_rebound_s;
        }
    }
    if b0.delta_max_m >= st.surface.pillar_height_m {
        return Err(RenderError::OutsideModel {
            run: run.to_string(),
            delta_max_mm: b0.delta_max_m * 1e3,
            pillar_height_mm: st.surface.pillar_height_m * 1e3,
        });
    }

    // ---- geometry (a camera set-up may rescale and move things)
    let setup = optics_on.then(|| optics::draw_setup(&st.optics, st.seed, &spec.setup));
    let mm_per_px = st.mm_per_px.unwrap_or_else(|| {
        default_mm_per_px(spec.radius_mm) * setup.map_or(1.0, |s| s.scale_factor)
    });
    let m_per_px = mm_per_px * 1e-3;
    let radius_px = spec.radius_mm / mm_per_px;
    let surface_row_px = st.surface_row_px.unwrap_or_else(|| match setup {
        Some(s) => (0.72 * st.height_px as f64).round() + s.surface_shift_px,
        None => (0.72 * st.height_px as f64).round() + row_fraction,
    });
    let impact_column_px = 0.5 * st.width_px as f64 + column_offset * st.width_px as f64 / 16.0;
    let pillar_width_px = st.surface.pillar_width_m / m_per_px;
    let channel_width_px = st.surface.channel_width_m / m_per_px;
    let scene = Scene {
        width_px: st.width_px,
        height_px: st.height_px,
        radius_px,
        surface_row_px,
        surface_slope: st.surface_slope,
        pillar_height_px: st.surface.pillar_height_m / m_per_px,
        pillar_width_px,
        channel_width_px,
        pillar_phase_px: pillar_phase_frac * (pillar_width_px + channel_width_px),
    };
    let y_s = scene.surface_row_at(impact_column_px);
    let mut look = st.look.clone();
    let mut camera = optics_on.then(|| {
        let frame = optics::FrameGeometry {
            width_px: st.width_px,
            height_px: st.height_px,
            radius_px,
        };
        optics::draw(&st.optics, st.seed, &spec.setup, run, frame, &st.look)
    });
    if let Some(cam) = &camera {
        look.blur_sigma_px = cam.truth.blur_sigma0_px;
    }

    // ---- the movie's frames
    let n0 = match &mut camera {
        Some(cam) if cam.truth.start_at_entry => {
            let entry = optics::entry_frame(
                &first,
                &cam.geometry,
                st.fps,
                (impact_column_px, y_s - radius_px),
                radius_px,
                m_per_px,
            );
            cam.truth.release_in_view = entry.release_in_view;
            cam.truth.t_release_s = entry.t_release_s;
            entry.first_frame
        }
        Some(cam) => {
            cam.truth.t_release_s = t_contact - v / g;
            -(st.frames_before as i64)
        }
        None => -(st.frames_before as i64),
    };
    let n1 = (t_last_rebound * st.fps).ceil() as i64 + st.frames_after as i64;
    let t_window_end = n1 as f64 / st.fps + 0.5 * st.exposure_s;
    let traj = Trajectory::simulate(&params, t_contact, t_window_end, step).map_err(phys_err)?;
    let b = traj.bounces()[0];
    let centre = |t: f64| -> (f64, f64) {
        let (d, _) = traj.state(t);
        (impact_column_px, y_s - radius_px + d / m_per_px)
    };
    if let Some(cam) = &mut camera {
        if st.format != FrameFormat::Cine {
            let mut pick = rng_for(st.seed, run, "missing", 0);
            cam.truth.missing_frames =
                optics::missing_frames(n0, st.optics.missing_frames, &mut pick);
        }
    }
    let jpeg_quality = (st.format == FrameFormat::Jpeg).then(|| {
        let (lo, hi) = st.jpeg_quality;
        rng_for(st.seed, run, "jpeg", 0).gen_range(lo..=hi)
    });
    let mut dust_rng = rng_for(st.seed, "", "dust", 0);
    let raster_err = |source| RenderError::Raster {
        run: run.to_string(),
        source,
    };
    let painter = match camera {
        Some(cam) => Painter::Camera(Box::new(
            CameraRaster::new(scene, look.clone(), cam, &mut dust_rng).map_err(raster_err)?,
        )),
        None => Painter::Plain(Box::new(
            Raster::new(scene, look.clone(), &mut dust_rng).map_err(raster_err)?,
        )),
    };

    // ---- frames
    let dir = out.join(run);
    std::fs::create_dir_all(&dir).map_err(|source| RenderError::CreateDir {
        path: dir.clone(),
        source,
    })?;
    let numbers: Vec<i64> = (n0..=n1).collect();
    // What the camera would state about the movie (the XML side file; a
    // movie container such as .cine takes its header from here too).
    let header = PccHeader {
        description: format!("dropscope render {run} (synthetic)"),
        first_image_no: n0,
        image_count: numbers.len(),
        width_px: st.width_px,
        height_px: st.height_px,
        bit_depth: st.look.bit_depth,
        fps: st.fps,
        exposure_s: st.exposure_s,
        trigger_10ns: trigger_10ns(spec.index),
    };
    let mut sink: Box<dyn FrameSink> = match st.format {
        FrameFormat::Tiff | FrameFormat::Png | FrameFormat::Jpeg => Box::new(FolderSink::new(
            &dir,
            run,
            st.format,
            st.look.bit_depth,
            jpeg_quality.unwrap_or(95),
        )),
        FrameFormat::Cine => Box::new(CineSink::create(
            &dir.join(format!("{run}.cine")),
            &header,
            st.packing,
        )?),
    };
    let missing: &[i64] = match &painter {
        Painter::Camera(c) => &c.optics().truth.missing_frames,
        Painter::Plain(_) => &[],
    };
    let span = (n1 - n0).max(1) as f64;
    for chunk in numbers.chunks(64) {
        let frames: Vec<(i64, crate::source::Frame)> = chunk
            .par_iter()
            .filter(|n| !missing.contains(n))
            .map(|&n| {
                let t = n as f64 / st.fps;
                let centres = exposure_samples(&centre, t, st.exposure_s, st.look.motion_blur);
                let mut rng = rng_for(st.seed, run, "frame", n);
                let frame = match &painter {
                    Painter::Plain(r) => r.frame(&centres, &mut rng),
                    Painter::Camera(c) => c.frame(&centres, (n - n0) as f64 / span, &mut rng),
                };
                (n, frame)
            })
            .collect();
        sink.write_batch(&frames)?;
    }
    sink.finish()?;

    // ---- side file (a .cine carries its own header) and truth
    if st.format != FrameFormat::Cine {
        export::write_pcc_xml(&dir.join(format!("{run}.xml")), &header)?;
    }

    let frames_truth: Vec<FrameTruth> = numbers
        .iter()
        .map(|&n| {
            let t = n as f64 / st.fps;
            let (x, z) = centre(t);
            let d = traj.state(t).0;
            let image = match &painter {
                Painter::Camera(c) => Some(c.optics().geometry.forward(x, z)),
                Painter::Plain(_) => None,
            };
            FrameTruth {
                frame: n,
                t_s: t,
                x_px: x,
                z_px: z,
                delta_mm: d.max(0.0) * 1e3,
                in_contact: d > 0.0,
                image_x_px: image.map(|p| p.0),
                image_z_px: image.map(|p| p.1),
            }
        })
        .collect();
    let second_bounce = traj
        .bounces()
        .get(1)
        .filter(|s| s.t_contact_s <= t_window_end)
        .map(|s| BounceTruth {
            t_contact_s: s.t_contact_s,
            t_max_s: s.t_max_s,
            t_rebound_s: s.t_rebound_s,
            tau_c_s: s.tau_c_s(),
            v_impact_m_s: s.v_impact_m_s,
            v_rebound_m_s: s.v_rebound_m_s,
            restitution: s.restitution(),
            delta_max_mm: s.delta_max_m * 1e3,
            t_force_zero_s: s.force_zero.map(|(t, _)| t),
        });
    let contact = drawn.map(|c| ContactTruth {
        contact_physics: match st.contact.mode {
            contact::ContactMode::Wide => "wide",
            contact::ContactMode::Model => "set",
        }
        .to_string(),
        contact_law: contact::describe(&c),
        force_n: params.law.exponent,
        stiffness_n_per_m_n: params.elastic_stiffness(),
        model_stiffness_n_per_m2: params.stiffness_n_m2(),
        delta_ref_mm: params.delta_max_eq4_m() * 1e3,
        damping_model: c.damping.name().to_string(),
        damping_c_n_s_per_m: (c.damping == Damping::Linear).then_some(params.damping_n_s_m),
        hunt_crossley_alpha_s_per_m: (c.damping == Damping::HuntCrossley)
            .then_some(params.law.hunt_crossley_s_m),
        adhesion: params.law.adhesion,
        t_force_zero_s: b.force_zero.map(|(t, _)| t),
        delta_force_zero_mm: b.force_zero.map(|(_, d)| d * 1e3),
    });
    let r_mm = spec.radius_mm;
    let dmax_mm = b.delta_max_m * 1e3;
    let truth = Truth {
        run: run.to_string(),
        seed: st.seed,
        preset: st.preset.name().to_string(),
        sphere_radius_mm: r_mm,
        sphere_density_kg_m3: st.density_kg_m3,
        drop_height_cm: spec.height_cm,
        surface: SurfaceTruth {
            modulus_pa: st.surface.modulus_pa,
            pillar_height_mm: st.surface.pillar_height_m * 1e3,
            pillar_width_mm: st.surface.pillar_width_m * 1e3,
            channel_width_mm: st.surface.channel_width_m * 1e3,
            solid_fraction: st.surface.solid_fraction,
        },
        restitution_requested,
        fps: st.fps,
        exposure_s: st.exposure_s,
        width_px: st.width_px,
        height_px: st.height_px,
        bit_depth: st.look.bit_depth,
        mm_per_px,
        radius_px,
        surface_row_px,
        surface_slope: st.surface_slope,
        impact_column_px,
        t_contact_s: b.t_contact_s,
        t_rebound_s: b.t_rebound_s,
        tau_c_s: b.tau_c_s(),
        t_max_s: b.t_max_s,
        v_impact_m_s: b.v_impact_m_s,
        v_rebound_m_s: b.v_rebound_m_s,
        restitution: b.restitution(),
        delta_max_mm: dmax_mm,
        a_max_mm: (r_mm * r_mm - (r_mm - dmax_mm).powi(2)).max(0.0).sqrt(),
        second_bounce,
        resting_contact_s: traj.resting_contact_s().filter(|&t| t <= t_window_end),
        gravity_m_s2: g,
        damping_n_s_m: params.damping_n_s_m,
        contact,
        integration_step_s: step,
        first_image_no: n0,
        camera: match &painter {
            Painter::Camera(c) => Some(c.optics().truth.clone()),
            Painter::Plain(_) => None,
        },
        look,
        jpeg_quality,
        frames: frames_truth,
    };
    export::write_truth(&dir.join("truth.json"), &truth)?;
    Ok(DropSummary {
        run: run.to_string(),
        dir,
        frames: numbers.len(),
        truth,
    })
}
