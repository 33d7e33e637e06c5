//! Runs tracked ahead of their set-up's calibration ([`prepare`]), kept in
//! memory or on the shelf, and a run opened and tracked.

use super::failure::{caught, RunFailure};
use super::tracked::{bounded_of, open_run, track_run, Tracked};
use crate::calibrate::free_fall::Curvature;
use crate::calibrate::setup_infer::SceneSignature;
use crate::config::PipelineConfig;
use crate::dataset::manifest::RunSpec;
use crate::pipeline::shelf::{Shelf, ShelvedTrack};
use crate::track::TrackSettings;
use rayon::prelude::*;
use std::sync::Arc;

/// A job's runs and configuration as they are processed.
pub struct Prepared {
    /// The runs, with the camera set-ups their images show filled in where
    /// the manifest names none ([`crate::calibrate::setup_infer`], `camera.infer_setups`).
    pub runs: Vec<RunSpec>,
    /// The configuration, with the edge offset the runs measured
    /// ([`crate::calibrate::scale::EdgeOffset::measure`]) where it gives none.
    pub cfg: PipelineConfig,
    /// The runs tracked to read their scenes, kept for `process_setup`.
    pub kept: KeptRuns,
}

/// The runs [`prepare`] tracked, by their index in its runs: each track on
/// a [`Shelf`] (its background and records in the job's temporary file),
/// or the reason it could not be made, for `process_setup` to take
/// instead of tracking the run again. A run whose track could not be
/// shelved (no temporary file) is not kept: it is tracked again.
#[derive(Default)]
pub struct KeptRuns {
    pub(super) runs: Vec<std::sync::Mutex<Option<KeptRun>>>,
}

impl KeptRuns {
    /// Run `i`'s, once.
    pub fn take(&self, i: usize) -> Option<KeptRun> {
        self.runs.get(i)?.lock().ok()?.take()
    }
}

/// A run [`prepare`] tracked (see [`KeptRuns`]).
pub struct KeptRun(pub(super) Result<ShelvedRun, RunFailure>);

/// A [`Tracked`] without its source (opened again: a job's runs are not
/// all held open) and the distortion bound's track (made again from the
/// track), its track on the shelf.
pub(super) struct ShelvedRun {
    pub(super) shelf: Arc<Shelf>,
    pub(super) meta: crate::source::SourceMeta,
    pub(super) track: ShelvedTrack,
    pub(super) settings: TrackSettings,
    pub(super) surface_name: String,
    pub(super) curvature: Option<Curvature>,
    pub(super) fps_source: String,
}

impl KeptRun {
    /// What [`track_run`] gave, or `t`'s track put on `shelf`; `None` when
    /// it could not be put there.
    pub(super) fn new(
        t: Result<Tracked, RunFailure>,
        shelf: Option<&Arc<Shelf>>,
    ) -> Option<KeptRun> {
        let t = match t {
            Ok(t) => t,
            Err(e) => return Some(KeptRun(Err(e))),
        };
        let shelf = shelf?;
        let track =
            crate::util::timings::time(crate::util::timings::Stage::Shelf, || shelf.put(t.tr))
                .ok()?;
        Some(KeptRun(Ok(ShelvedRun {
            shelf: Arc::clone(shelf),
            meta: t.meta,
            track,
            settings: t.settings,
            surface_name: t.surface_name,
            curvature: t.curvature,
            fps_source: t.fps_source,
        })))
    }

    /// The run as [`track_run`] gave it; `None` when its track cannot be
    /// read back (the run is then tracked again).
    pub(super) fn restore(
        self,
        run: &RunSpec,
        cfg: &PipelineConfig,
    ) -> Option<Result<Tracked, RunFailure>> {
        let s = match self.0 {
            Ok(s) => s,
            Err(e) => return Some(Err(e)),
        };
        let tr = crate::util::timings::time(crate::util::timings::Stage::Shelf, || {
            s.shelf.take(s.track)
        })
        .ok()?;
        Some(caught(run, || {
            // The same recording, opened again: its frame rate is the one
            // it was tracked at.
            let (source, _) = open_run(run, cfg)?;
            let bounded = bounded_of(&tr, &s.meta, cfg);
            tr.frames
                .check()
                .map_err(|e| format!("{}: {e}", run.path.display()))?;
            Ok(Tracked {
                source,
                meta: s.meta,
                tr,
                settings: s.settings,
                surface_name: s.surface_name,
                curvature: s.curvature,
                bounded,
                fps_source: s.fps_source,
            })
        }))
    }
}

/// Prepare a job's runs (see [`Prepared`]). With `camera.infer_setups` and
/// two runs or more without a `setup`, each of those is tracked to read its
/// scene, and its track kept for its processing ([`KeptRuns`]); `scene_of`
/// gives a run's scene when it is already known (a cache). A run that cannot be
/// tracked stays without a set-up (its processing says why). The edge
/// offset is measured on those runs whose own free fall gives their scale
/// within [`crate::calibrate::scale::EDGE_OFFSET_FREE_FALL_REL_ERR`].
pub fn prepare(
    runs: &[RunSpec],
    cfg: &PipelineConfig,
    scene_of: &(dyn Fn(&RunSpec) -> Option<SceneSignature> + Sync),
    notice: &dyn Fn(&str),
) -> Prepared {
    let mut out = Prepared {
        runs: runs.to_vec(),
        cfg: cfg.clone(),
        kept: KeptRuns::default(),
    };
    let open: Vec<usize> = (0..runs.len())
        .filter(|&i| runs[i].setup.is_none())
        .collect();
    if !cfg.camera.infer_setups || open.len() < 2 {
        return out;
    }
    let known: Vec<Option<SceneSignature>> = open.par_iter().map(|&i| scene_of(&runs[i])).collect();
    let unknown = known.iter().filter(|s| s.is_none()).count();
    if unknown > 0 {
        notice(&format!(
            "camera set-ups: reading the scenes of {unknown} run(s) without a `setup` (camera.infer_setups)"
        ));
    }
    let shelf = (unknown > 0)
        .then(|| Shelf::new().ok().map(Arc::new))
        .flatten();
    let (scenes, kept): (Vec<Option<SceneSignature>>, Vec<Option<KeptRun>>) = open
        .par_iter()
        .zip(known)
        .map(|(&i, known)| {
            let run = &runs[i];
            if known.is_some() {
                return (known, None);
            }
            let t = caught(run, || track_run(run, cfg));
            let scene = t.as_ref().ok().map(|t| t.scene(run.sphere_radius_mm));
            (scene, KeptRun::new(t, shelf.as_ref()))
        })
        .unzip();
    out.kept.runs = (0..runs.len()).map(|_| Default::default()).collect();
    for (&i, k) in open.iter().zip(kept) {
        out.kept.runs[i] = std::sync::Mutex::new(k);
    }
    let taken: Vec<&str> = runs.iter().filter_map(|r| r.setup.as_deref()).collect();
    let groups = crate::calibrate::setup_infer::infer_groups(&scenes);
    for (k, group) in groups.iter().enumerate() {
        let name = crate::calibrate::setup_infer::setup_name(k + 1, &taken);
        for &j in group {
            out.runs[open[j]].setup = Some(name.clone());
        }
    }
    let grouped: usize = groups.iter().map(Vec::len).sum();
    if grouped > 0 {
        notice(&format!(
            "camera set-ups from the images: {} run(s) in {} set-up(s) (auto1 …), {} alone",
            grouped,
            groups.len(),
            open.len() - grouped
        ));
    }
    if cfg.camera.edge_offset_px.is_none() {
        let offsets: Vec<f64> = scenes
            .iter()
            .flatten()
            .filter_map(|sc| {
                let (s, err) = sc.free_fall_mm_per_px?;
                (err < crate::calibrate::scale::EDGE_OFFSET_FREE_FALL_REL_ERR * s)
                    .then(|| sc.r_app_px - sc.radius_mm / s)
            })
            .collect();
        if let Some(e) = crate::calibrate::scale::EdgeOffset::measure(&offsets) {
            out.cfg.camera.edge_offset_px = Some(e.offset_px);
            out.cfg.camera.edge_offset_spread_px = Some(e.spread_px);
            notice(&format!(
                "edge offset from {} runs' own free falls: {:+.3} ± {:.3} px",
                offsets.len(),
                e.offset_px,
                e.spread_px
            ));
        }
    }
    out
}
