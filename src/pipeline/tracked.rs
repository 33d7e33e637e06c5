//! A run opened and tracked ([`Tracked`]): its source, its track and what the
//! scale needs of it.

use super::failure::{Recording, RunFailure};
use super::points::{bounded_points, exclude_frames, held_points};
use crate::calibrate::free_fall::{free_fall_curvature, Curvature};
use crate::calibrate::lens::{undistort_track, Lens};
use crate::calibrate::setup_infer::SceneSignature;
use crate::config::PipelineConfig;
use crate::dataset::manifest::RunSpec;
use crate::measure::events::{EventConfig, SurfaceFrame};
use crate::pipeline::settings::open_options;
use crate::source::open;
use crate::track::{track, Track, TrackSettings};

/// A run tracked but not yet measured.
pub(super) struct Tracked {
    pub(super) source: Box<dyn crate::source::FrameSource>,
    pub(super) meta: crate::source::SourceMeta,
    pub(super) tr: Track,
    pub(super) settings: TrackSettings,
    pub(super) surface_name: String,
    /// The curvature of the run's own free flights.
    pub(super) curvature: Option<Curvature>,
    /// The track through a lens at `camera.distortion_bound_px`, when no
    /// k1 is given and the bound is not 0.
    pub(super) bounded: Option<crate::calibrate::lens::Bounded>,
    /// Where `meta.fps` came from (the `fps_source` word, [`open_run`]).
    pub(super) fps_source: String,
}

impl Tracked {
    /// What the run's row says of its recording.
    pub(super) fn recording(&self) -> Recording {
        Recording {
            frames: self.tr.frames.len(),
            fps: self.meta.fps,
            fps_source: self.fps_source.clone(),
        }
    }

    /// What the run's images say of its camera set-up.
    pub(super) fn scene(&self, radius_mm: f64) -> SceneSignature {
        let g_m_s2 = EventConfig::default().g_m_s2;
        let scale = |c: &Curvature| c.mm_per_px(g_m_s2);
        let free_fall_mm_per_px = self.curvature.as_ref().map(|c| {
            let s = scale(c);
            // The distortion bound's change of the scale, as in the errors.
            let at_bound = self
                .bounded
                .as_ref()
                .and_then(|b| b.curvature.as_ref())
                .map_or(0.0, |b| (scale(b) - s).abs() / 3f64.sqrt());
            (s, (s * c.rel_err()).hypot(at_bound))
        });
        SceneSignature {
            width_px: self.meta.width,
            height_px: self.meta.height,
            surface_row_px: self.tr.surface.row_at(0.5 * self.meta.width as f64),
            surface_slope: self.tr.surface.slope,
            r_app_px: self.tr.radius_px,
            r_app_err_px: self.tr.radius_err_px,
            radius_mm,
            free_fall_mm_per_px,
        }
    }
}

/// `run`'s frames, opened, and where their frame rate came from (the
/// `fps_source` column): the recording's own when it holds one, else the
/// fallback [`PipelineConfig::fps_fallback`] names. A recording without a
/// rate of its own is opened twice, the first time to learn that.
pub(super) fn open_run(
    run: &RunSpec,
    cfg: &PipelineConfig,
) -> Result<(Box<dyn crate::source::FrameSource>, String), String> {
    use crate::config::FpsSource;
    let open_with = |fps_fallback: Option<f64>| {
        let options = open_options(cfg, run.number_digits, fps_fallback);
        crate::util::timings::time(crate::util::timings::Stage::Open, || {
            open(&run.path, &options)
        })
    };
    let has_fps = |m: &crate::source::SourceMeta| m.fps.is_finite() && m.fps > 0.0;
    match open_with(None) {
        Ok(src) if has_fps(src.meta()) => {
            let word = FpsSource::Recording.word(&recording_fps_word(src.meta()));
            return Ok((src, word));
        }
        Ok(_) | Err(crate::source::SourceError::NoFrameRate { .. }) => {}
        Err(e) => return Err(e.to_string()),
    }
    let (fps, from) = cfg.fps_fallback(run.fps);
    let src = open_with(Some(fps)).map_err(|e| e.to_string())?;
    Ok((src, from.word("")))
}

/// The `fps_source` word of a recording's own frame rate: `cine` for a
/// cine header, `xml` for a PCC XML side file, else the reader's format.
pub(super) fn recording_fps_word(meta: &crate::source::SourceMeta) -> String {
    match meta.format.as_str() {
        "cine" => "cine".into(),
        _ if meta.details.side_file.is_some() => "xml".into(),
        other => other.to_string(),
    }
}

pub(super) fn bounded_of(
    tr: &Track,
    meta: &crate::source::SourceMeta,
    cfg: &PipelineConfig,
) -> Option<crate::calibrate::lens::Bounded> {
    use crate::util::timings::{time, Stage};
    let lens = match lens_of(tr, meta, cfg) {
        LensUsed::Measured { err, .. } => Lens::new(-err * 3f64.sqrt(), meta.width, meta.height),
        LensUsed::Bound(lens) => lens,
        LensUsed::Calibrated(_) | LensUsed::None => return None,
    };
    Some({
        let (surface, radius_px, curvature) = time(Stage::Events, || {
            let (surface, radius_px) = crate::calibrate::lens::undistorted_line(tr, &lens);
            let level = SurfaceFrame::of_line(surface.row0_px, surface.slope, 0.0);
            let c = free_fall_curvature(
                || bounded_points(tr, &lens, radius_px).map(|p| level.level(&p)),
                |_| level.row_px,
                radius_px,
            );
            (surface, radius_px, c)
        });
        crate::calibrate::lens::Bounded {
            lens,
            surface_row0_px: surface.row0_px,
            surface_slope: surface.slope,
            radius_px,
            curvature,
        }
    })
}

pub(super) fn track_run(run: &RunSpec, cfg: &PipelineConfig) -> Result<Tracked, RunFailure> {
    crate::dataset::run_name::check(&run.run)?;
    let surface_name = run
        .surface
        .clone()
        .unwrap_or_else(|| cfg.input.surface.clone());
    if !cfg.surfaces.contains_key(&surface_name) {
        return Err(format!(
            "surface `{surface_name}` is not defined in pipeline.toml (known: {})",
            cfg.surfaces.keys().cloned().collect::<Vec<_>>().join(", ")
        )
        .into());
    }
    use crate::util::timings::{time, Stage};
    let (mut source, fps_source) = open_run(run, cfg)?;
    let meta = source.meta().clone();
    // A failure from here on has a recording: its frames and frame rate
    // are in the failed row.
    let failed = |e: &dyn std::fmt::Display| RunFailure {
        reason: format!("{}: {e}", run.path.display()),
        recording: Some(Recording {
            frames: meta.frame_count,
            fps: meta.fps,
            fps_source: fps_source.clone(),
        }),
    };
    let settings = TrackSettings::from_config(&cfg.detect_settings());
    let mut tr = track(source.as_mut(), &settings).map_err(|e| failed(&e))?;
    let lens = lens_of(&tr, &meta, cfg);
    if let LensUsed::Calibrated(k1) | LensUsed::Measured { k1, .. } = lens {
        tr =
            undistort_track(tr, &Lens::new(k1, meta.width, meta.height)).map_err(|e| failed(&e))?;
    }
    exclude_frames(&mut tr, &run.review).map_err(|e| failed(&e))?;
    // The free falls' curvature, and the track through the lens at the
    // distortion bound with its own: each on a thread.
    let (curvature, bounded) = rayon::join(
        || {
            time(Stage::Events, || {
                // Along the surface's normal, as the drops are measured.
                let level = SurfaceFrame::of_line(tr.surface.row0_px, tr.surface.slope, 0.0);
                free_fall_curvature(
                    || held_points(&tr, |_| (None, None)).map(|p| level.level(&p)),
                    |_| level.row_px,
                    tr.radius_px,
                )
            })
        },
        || bounded_of(&tr, &meta, cfg),
    );
    tr.frames.check().map_err(|e| failed(&e))?;
    Ok(Tracked {
        source,
        meta,
        tr,
        settings,
        surface_name,
        curvature,
        bounded,
        fps_source,
    })
}

/// The track through a lens at `camera.distortion_bound_px`, when no k1 is
/// given and the bound is not 0.
/// The lens a run's track is seen through (see `lens.rs`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum LensUsed {
    /// `camera.distortion_k1_per_px2`: the track is corrected with it.
    Calibrated(f64),
    /// Measured by the surface line's bow: the track is corrected with
    /// `k1`, and `err` is a systematic term.
    Measured { k1: f64, err: f64 },
    /// Not measured: the distortion bound's lens is a systematic term.
    Bound(Lens),
    /// No distortion considered (`camera.distortion_bound_px = 0`).
    None,
}

impl LensUsed {
    /// The `k1` the track is corrected with, its error, and where it came
    /// from (`drops.csv`'s `distortion_source`).
    pub(super) fn describe(&self) -> (Option<f64>, Option<f64>, &'static str) {
        match *self {
            LensUsed::Calibrated(k1) => (Some(k1), None, "config"),
            LensUsed::Measured { k1, err } => (Some(k1), Some(err), "surface_bow"),
            LensUsed::Bound(_) => (None, None, "bound"),
            LensUsed::None => (None, None, "none"),
        }
    }
}

/// Which lens a track is seen through: the configuration's calibration;
/// else the one its surface line's bow measures, where that is informative
/// and tighter than the distortion bound; else the bound (or none).
pub(super) fn lens_of(
    tr: &Track,
    meta: &crate::source::SourceMeta,
    cfg: &PipelineConfig,
) -> LensUsed {
    let camera = &cfg.camera;
    if let Some(k1) = camera.distortion_k1_per_px2 {
        return LensUsed::Calibrated(k1);
    }
    if camera.distortion_bound_px <= 0.0 {
        return LensUsed::None;
    }
    let bound = Lens::barrel_at_corner(camera.distortion_bound_px, meta.width, meta.height);
    match crate::calibrate::lens::k1_from_bow(&tr.surface, meta.width, meta.height) {
        Some((k1, err)) if err * 3f64.sqrt() < bound.k1_per_px2.abs() => {
            LensUsed::Measured { k1, err }
        }
        _ => LensUsed::Bound(bound),
    }
}
