//! One drop: its layout and motion, where it is in the picture, the camera
//! that records it, its frames written as PCC exports them, its
//! `truth.json` ([`render_drop`]).

use std::path::{Path, PathBuf};

use rand::Rng;
use rayon::prelude::*;

use super::camera::CameraRaster;
use super::campaign::DropSpec;
use super::contact;
use super::error::RenderError;
use super::export::{self, CineSink, FolderSink, FrameFormat, FrameSink, PccHeader};
use super::optics::{self, Optics};
use super::options::{positive, RenderSettings};
use super::physics::{self, ContactLaw, Damping, DropParams, Trajectory};
use super::raster::{Look, Raster, Scene};
use super::rng::rng_for;
use super::truth::{BounceTruth, ContactTruth, FrameTruth, SurfaceTruth, Truth};

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

/// Render one drop into `<out>/<run>/`: its layout, its motion, its scene
/// and camera, its frames, then its side file and `truth.json`.
pub fn render_drop(
    spec: &DropSpec,
    st: &RenderSettings,
    out: &Path,
) -> Result<DropSummary, RenderError> {
    let run = spec.run.as_str();
    let radius_m = positive("radius-mm", spec.radius_mm)? * 1e-3;
    let height_m = positive("height-cm", spec.height_cm)? * 1e-2;
    let layout = Layout::draw(st.seed, run);
    let optics_on = st.optics.active();
    let motion = Motion::simulate(st, run, radius_m, height_m, &layout, optics_on)?;
    let place = Placement::of(spec, st, &layout, optics_on);
    let (look, mut camera) = camera(spec, st, run, optics_on, place.radius_px);
    let window = Window::of(st, run, &motion, &place, camera.as_mut())?;
    let jpeg_quality = (st.format == FrameFormat::Jpeg).then(|| {
        let (lo, hi) = st.jpeg_quality;
        rng_for(st.seed, run, "jpeg", 0).gen_range(lo..=hi)
    });
    let painter = painter(st, run, place.scene.clone(), &look, camera)?;

    // ---- frames
    let dir = out.join(run);
    std::fs::create_dir_all(&dir).map_err(|source| RenderError::CreateDir {
        path: dir.clone(),
        source,
    })?;
    let numbers: Vec<i64> = (window.n0..=window.n1).collect();
    let header = header(spec, st, window.n0, numbers.len());
    write_frames(
        st,
        run,
        &dir,
        &header,
        jpeg_quality,
        &painter,
        &numbers,
        &window,
        &place,
    )?;

    // ---- side file (a .cine carries its own header) and truth
    if st.format != FrameFormat::Cine {
        export::write_pcc_xml(&dir.join(format!("{run}.xml")), &header)?;
    }
    let truth = truth(
        spec,
        st,
        &motion,
        &place,
        &window,
        &painter,
        &numbers,
        look,
        jpeg_quality,
    );
    export::write_truth(&dir.join("truth.json"), &truth)?;
    Ok(DropSummary {
        run: run.to_string(),
        dir,
        frames: numbers.len(),
        truth,
    })
}

/// The run's layout, drawn from its own generator in this order.
struct Layout {
    /// Where in image 0's frame interval the first contact falls, 0‥1.
    contact_phase: f64,
    /// The impact column's offset from the middle, in sixteenths of the width.
    column_offset: f64,
    /// The surface row's fraction of a pixel.
    row_fraction: f64,
    /// The pillars' phase, a fraction of their period.
    pillar_phase_frac: f64,
}

impl Layout {
    fn draw(seed: u64, run: &str) -> Layout {
        let mut layout = rng_for(seed, run, "layout", 0);
        let contact_phase: f64 = layout.gen_range(0.0..1.0);
        let column_offset: f64 = layout.gen_range(-1.0..1.0);
        let row_fraction: f64 = layout.gen_range(0.0..1.0);
        let pillar_phase_frac: f64 = layout.gen_range(0.0..1.0);
        Layout {
            contact_phase,
            column_offset,
            row_fraction,
            pillar_phase_frac,
        }
    }
}

/// The drop's physics: its parameters, its first contact, and the movie's
/// last contact.
struct Motion {
    params: DropParams,
    /// The integration step (s).
    step: f64,
    /// The contact law drawn, when the contact options ask for one.
    drawn: Option<contact::ContactDraw>,
    restitution_requested: f64,
    /// Gravity (m/s²) and the impact speed (m/s).
    g: f64,
    v: f64,
    t_contact: f64,
    /// The first contact's trajectory.
    first: Trajectory,
    /// The movie's last contact ends here (s).
    t_last_rebound: f64,
}

impl Motion {
    fn simulate(
        st: &RenderSettings,
        run: &str,
        radius_m: f64,
        height_m: f64,
        layout: &Layout,
        optics_on: bool,
    ) -> Result<Motion, RenderError> {
        let phys_err = |source| RenderError::Physics {
            run: run.to_string(),
            source,
        };
        let frame_dt = 1.0 / st.fps;
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
                params.damping_n_s_m =
                    physics::damping_for_restitution(&params, st.restitution, step)
                        .map_err(phys_err)?;
                st.restitution
            }
            Some(c) => {
                params = contact::apply(&params, c, step).map_err(phys_err)?;
                c.restitution
            }
        };
        let t_contact = layout.contact_phase / st.fps;
        let first = Trajectory::simulate(&params, t_contact, t_contact, step).map_err(phys_err)?;
        let b0 = first.bounces()[0];
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
        Ok(Motion {
            params,
            step,
            drawn,
            restitution_requested,
            g,
            v,
            t_contact,
            first,
            t_last_rebound,
        })
    }
}

/// Where the drop is in the picture (a camera set-up may rescale and move
/// things).
struct Placement {
    mm_per_px: f64,
    m_per_px: f64,
    radius_px: f64,
    surface_row_px: f64,
    impact_column_px: f64,
    scene: Scene,
    /// The surface's row at the impact column.
    y_s: f64,
}

impl Placement {
    fn of(spec: &DropSpec, st: &RenderSettings, layout: &Layout, optics_on: bool) -> Placement {
        let setup = optics_on.then(|| optics::draw_setup(&st.optics, st.seed, &spec.setup));
        let mm_per_px = st.mm_per_px.unwrap_or_else(|| {
            default_mm_per_px(spec.radius_mm) * setup.map_or(1.0, |s| s.scale_factor)
        });
        let m_per_px = mm_per_px * 1e-3;
        let radius_px = spec.radius_mm / mm_per_px;
        let surface_row_px = st.surface_row_px.unwrap_or_else(|| match setup {
            Some(s) => (0.72 * st.height_px as f64).round() + s.surface_shift_px,
            None => (0.72 * st.height_px as f64).round() + layout.row_fraction,
        });
        let impact_column_px =
            0.5 * st.width_px as f64 + layout.column_offset * st.width_px as f64 / 16.0;
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
            pillar_phase_px: layout.pillar_phase_frac * (pillar_width_px + channel_width_px),
        };
        let y_s = scene.surface_row_at(impact_column_px);
        Placement {
            mm_per_px,
            m_per_px,
            radius_px,
            surface_row_px,
            impact_column_px,
            scene,
            y_s,
        }
    }

    /// The sphere's centre (px) at time `t` (s) on `traj`.
    fn centre(&self, traj: &Trajectory, t: f64) -> (f64, f64) {
        let (d, _) = traj.state(t);
        (
            self.impact_column_px,
            self.y_s - self.radius_px + d / self.m_per_px,
        )
    }
}

/// The look of the pictures and, with the optics on, the real camera drawn
/// for the run (its blur sets the look's).
fn camera(
    spec: &DropSpec,
    st: &RenderSettings,
    run: &str,
    optics_on: bool,
    radius_px: f64,
) -> (Look, Option<Optics>) {
    let mut look = st.look.clone();
    let camera = optics_on.then(|| {
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
    (look, camera)
}

/// The movie's images `n0..=n1` and the trajectory over them.
struct Window {
    n0: i64,
    n1: i64,
    /// The end of the last image's exposure (s).
    t_window_end: f64,
    traj: Trajectory,
}

impl Window {
    /// The movie's first image (from the sphere's entry when the camera
    /// asks, noting the release in its truth) and last, the trajectory over
    /// them, and the camera's missing images.
    fn of(
        st: &RenderSettings,
        run: &str,
        motion: &Motion,
        place: &Placement,
        camera: Option<&mut Optics>,
    ) -> Result<Window, RenderError> {
        let mut camera = camera;
        let n0 = match &mut camera {
            Some(cam) if cam.truth.start_at_entry => {
                let entry = optics::entry_frame(
                    &motion.first,
                    &cam.geometry,
                    st.fps,
                    (place.impact_column_px, place.y_s - place.radius_px),
                    place.radius_px,
                    place.m_per_px,
                );
                cam.truth.release_in_view = entry.release_in_view;
                cam.truth.t_release_s = entry.t_release_s;
                entry.first_frame
            }
            Some(cam) => {
                cam.truth.t_release_s = motion.t_contact - motion.v / motion.g;
                -(st.frames_before as i64)
            }
            None => -(st.frames_before as i64),
        };
        let n1 = (motion.t_last_rebound * st.fps).ceil() as i64 + st.frames_after as i64;
        let t_window_end = n1 as f64 / st.fps + 0.5 * st.exposure_s;
        let traj =
            Trajectory::simulate(&motion.params, motion.t_contact, t_window_end, motion.step)
                .map_err(|source| RenderError::Physics {
                    run: run.to_string(),
                    source,
                })?;
        if let Some(cam) = camera {
            if st.format != FrameFormat::Cine {
                let mut pick = rng_for(st.seed, run, "missing", 0);
                cam.truth.missing_frames =
                    optics::missing_frames(n0, st.optics.missing_frames, &mut pick);
            }
        }
        Ok(Window {
            n0,
            n1,
            t_window_end,
            traj,
        })
    }
}

/// The renderer of the frames, its dust drawn from the seed alone.
fn painter(
    st: &RenderSettings,
    run: &str,
    scene: Scene,
    look: &Look,
    camera: Option<Optics>,
) -> Result<Painter, RenderError> {
    let mut dust_rng = rng_for(st.seed, "", "dust", 0);
    let raster_err = |source| RenderError::Raster {
        run: run.to_string(),
        source,
    };
    Ok(match camera {
        Some(cam) => Painter::Camera(Box::new(
            CameraRaster::new(scene, look.clone(), cam, &mut dust_rng).map_err(raster_err)?,
        )),
        None => Painter::Plain(Box::new(
            Raster::new(scene, look.clone(), &mut dust_rng).map_err(raster_err)?,
        )),
    })
}

/// What the camera would state about the movie (the XML side file; a
/// movie container such as .cine takes its header from here too).
fn header(spec: &DropSpec, st: &RenderSettings, n0: i64, image_count: usize) -> PccHeader {
    PccHeader {
        description: format!("dropscope render {} (synthetic)", spec.run),
        first_image_no: n0,
        image_count,
        width_px: st.width_px,
        height_px: st.height_px,
        bit_depth: st.look.bit_depth,
        fps: st.fps,
        exposure_s: st.exposure_s,
        trigger_10ns: trigger_10ns(spec.index),
    }
}

/// Render and write the images `numbers` (but the camera's missing ones),
/// 64 at a time in parallel.
#[allow(clippy::too_many_arguments)]
fn write_frames(
    st: &RenderSettings,
    run: &str,
    dir: &Path,
    header: &PccHeader,
    jpeg_quality: Option<u8>,
    painter: &Painter,
    numbers: &[i64],
    window: &Window,
    place: &Placement,
) -> Result<(), RenderError> {
    let mut sink: Box<dyn FrameSink> = match st.format {
        FrameFormat::Tiff | FrameFormat::Png | FrameFormat::Jpeg => Box::new(FolderSink::new(
            dir,
            run,
            st.format,
            st.look.bit_depth,
            jpeg_quality.unwrap_or(95),
        )),
        FrameFormat::Cine => Box::new(CineSink::create(
            &dir.join(format!("{run}.cine")),
            header,
            st.packing,
        )?),
    };
    let missing: &[i64] = match painter {
        Painter::Camera(c) => &c.optics().truth.missing_frames,
        Painter::Plain(_) => &[],
    };
    let (n0, n1) = (window.n0, window.n1);
    let centre = |t: f64| place.centre(&window.traj, t);
    let span = (n1 - n0).max(1) as f64;
    for chunk in numbers.chunks(64) {
        let frames: Vec<(i64, crate::source::Frame)> = chunk
            .par_iter()
            .filter(|n| !missing.contains(n))
            .map(|&n| {
                let t = n as f64 / st.fps;
                let centres = exposure_samples(&centre, t, st.exposure_s, st.look.motion_blur);
                let mut rng = rng_for(st.seed, run, "frame", n);
                let frame = match painter {
                    Painter::Plain(r) => r.frame(&centres, &mut rng),
                    Painter::Camera(c) => c.frame(&centres, (n - n0) as f64 / span, &mut rng),
                };
                (n, frame)
            })
            .collect();
        sink.write_batch(&frames)?;
    }
    sink.finish()?;
    Ok(())
}

/// The exact values behind the drop (its `truth.json`).
#[allow(clippy::too_many_arguments)]
fn truth(
    spec: &DropSpec,
    st: &RenderSettings,
    motion: &Motion,
    place: &Placement,
    window: &Window,
    painter: &Painter,
    numbers: &[i64],
    look: Look,
    jpeg_quality: Option<u8>,
) -> Truth {
    let (traj, t_window_end) = (&window.traj, window.t_window_end);
    let params = &motion.params;
    let b = traj.bounces()[0];
    let frames_truth = frame_truths(st, place, traj, painter, numbers);
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
    let contact = motion.drawn.as_ref().map(|c| ContactTruth {
        contact_physics: match st.contact.mode {
            contact::ContactMode::Wide => "wide",
            contact::ContactMode::Model => "set",
        }
        .to_string(),
        contact_law: contact::describe(c),
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
    Truth {
        run: spec.run.clone(),
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
        restitution_requested: motion.restitution_requested,
        fps: st.fps,
        exposure_s: st.exposure_s,
        width_px: st.width_px,
        height_px: st.height_px,
        bit_depth: st.look.bit_depth,
        mm_per_px: place.mm_per_px,
        radius_px: place.radius_px,
        surface_row_px: place.surface_row_px,
        surface_slope: st.surface_slope,
        impact_column_px: place.impact_column_px,
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
        gravity_m_s2: motion.g,
        damping_n_s_m: params.damping_n_s_m,
        contact,
        integration_step_s: motion.step,
        first_image_no: window.n0,
        camera: match painter {
            Painter::Camera(c) => Some(c.optics().truth.clone()),
            Painter::Plain(_) => None,
        },
        look,
        jpeg_quality,
        frames: frames_truth,
    }
}

/// The sphere's exact place in each image `numbers`, and with a real
/// camera where its lens puts it.
fn frame_truths(
    st: &RenderSettings,
    place: &Placement,
    traj: &Trajectory,
    painter: &Painter,
    numbers: &[i64],
) -> Vec<FrameTruth> {
    numbers
        .iter()
        .map(|&n| {
            let t = n as f64 / st.fps;
            let (x, z) = place.centre(traj, t);
            let d = traj.state(t).0;
            let image = match painter {
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
        .collect()
}
