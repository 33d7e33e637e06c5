//! One run's flow and a failure caught into its row ([`process_run`]), and
//! the runs of one camera set-up tracked and measured together
//! ([`process_setup`]). The job level writes what these return
//! ([`crate::job::run_outputs`]).

use super::failure::{caught, Recording, RunFailure};
use super::measure_run::measure_run;
use super::prepare::KeptRun;
use super::tracked::{open_run, track_run, Tracked};
use super::types::RunOutcome;
use crate::calibrate::free_fall::Curvature;
use crate::config::PipelineConfig;
use crate::dataset::manifest::RunSpec;
use crate::dataset::DropRecord;
use crate::measure::quality;
use crate::util::io::Spool;
use rayon::prelude::*;

/// Process one run; never fails: problems become a `failed` record, and so
/// does a panic in any stage (caught here, at the run's boundary, so that
/// one bad input never ends the job).
pub fn process_run(run: &RunSpec, cfg: &PipelineConfig, overlay_frames: &[i64]) -> RunOutcome {
    process_setup(&[run], cfg, overlay_frames, Vec::new())
        .pop()
        .expect("one outcome per run")
}

/// Process runs that share one camera set-up (the manifest's `setup`
/// column; a run without one is a set-up of its own): each is tracked, the
/// curvatures of their free flights are pooled into one scale (see
/// [`crate::calibrate::scale`]), and each is measured with it. Never fails: a run that
/// cannot be measured, or panics, gets a `failed` record; the outcomes come in `runs`'
/// order.
///
/// `kept` holds, member by member, the track [`super::prepare::prepare`] made of it, if
/// any: taken off its shelf rather than made again (the same track).
pub fn process_setup(
    runs: &[&RunSpec],
    cfg: &PipelineConfig,
    overlay_frames: &[i64],
    mut kept: Vec<Option<KeptRun>>,
) -> Vec<RunOutcome> {
    kept.resize_with(runs.len(), || None);
    let (tracked, track_s): (Vec<Result<Tracked, RunFailure>>, Vec<f64>) = runs
        .par_iter()
        .zip(kept)
        .map(|(r, kept)| {
            let start = std::time::Instant::now();
            let t = kept
                .and_then(|k| k.restore(r, cfg))
                .unwrap_or_else(|| caught(r, || track_run(r, cfg)));
            (t, start.elapsed().as_secs_f64())
        })
        .unzip();
    // A drop a person rejected is left out of its set-up's scale and of
    // the comparison of its apparent sizes.
    let pooled_in = |r: &&RunSpec| r.review.rejected.is_none();
    let curvatures: Vec<Curvature> = tracked
        .iter()
        .zip(runs)
        .filter(|(_, r)| pooled_in(r))
        .filter_map(|(t, _)| t.as_ref().ok()?.curvature)
        .collect();
    let pool = |curvatures: Vec<Curvature>| {
        (curvatures.len() >= 2)
            .then(|| crate::calibrate::free_fall::pool(&curvatures))
            .flatten()
    };
    let pooled_at_bound = pool(
        tracked
            .iter()
            .zip(runs)
            .filter(|(_, r)| pooled_in(r))
            .filter_map(|(t, _)| t.as_ref().ok()?.bounded.as_ref()?.curvature)
            .collect(),
    );
    let pooled = pool(curvatures);
    // The members' apparent sizes per mm, compared once all are measured.
    let sizes: Vec<Option<crate::calibrate::scale::ApparentSize>> = tracked
        .iter()
        .zip(runs)
        .map(|(t, r)| {
            let t = t.as_ref().ok().filter(|_| pooled_in(r))?;
            Some(crate::calibrate::scale::ApparentSize {
                r_app_px: t.tr.radius_px,
                r_app_err_px: t.tr.radius_err_px,
                radius_mm: r.sphere_radius_mm,
            })
        })
        .collect();
    let mut outcomes: Vec<RunOutcome> = runs
        .par_iter()
        .zip(tracked)
        .zip(track_s)
        .map(|((run, t), track_s)| {
            let start = std::time::Instant::now();
            let recording = match &t {
                Ok(t) => Some(t.recording()),
                Err(f) => f.recording.clone(),
            };
            let mut o = caught(run, || {
                let _timed = crate::util::timings::start(crate::util::timings::Stage::Events);
                measure_run(
                    t.map_err(|f| f.reason)?,
                    run,
                    cfg,
                    [pooled, pooled_at_bound],
                    overlay_frames,
                )
            })
            .unwrap_or_else(|reason| failed_outcome(run, cfg, reason, recording.as_ref()));
            if let Some(reason) = non_finite(&o.record) {
                o = failed_outcome(run, cfg, reason, recording.as_ref());
            }
            o.seconds = track_s + start.elapsed().as_secs_f64();
            o
        })
        .collect();
    if runs.len() >= 2 {
        let found = crate::calibrate::scale::size_disagreements(
            &sizes,
            crate::calibrate::scale::EdgeOffset::from_config(&cfg.camera),
        );
        for ((o, run), d) in outcomes.iter_mut().zip(runs).zip(found) {
            if let Some(d) = d {
                let setup = run.setup.as_deref().unwrap_or("-");
                quality::flag(
                    &mut o.record,
                    quality::RADIUS_DISAGREEMENT,
                    d.sentence(setup),
                );
            }
        }
    }
    // The review's decisions last, on the row with every flag.
    for (o, run) in outcomes.iter_mut().zip(runs) {
        run.review.apply(&mut o.record);
    }
    outcomes
}

/// Why a measured record cannot stand: a number in it that is not finite
/// (an input value far out of range overflowed). `None` when all are.
pub(super) fn non_finite(record: &DropRecord) -> Option<String> {
    if record.status == crate::dataset::DropStatus::Failed {
        return None;
    }
    let columns = record.non_finite_columns();
    (!columns.is_empty()).then(|| {
        format!(
            "the measurement gave a number that is not finite in {}: an input value (density, \
             radius, frame rate, scale) is out of any physical range",
            columns.join(", ")
        )
    })
}

/// The `failed` outcome of `run`, with its reason and what is known of its
/// recording.
pub(super) fn failed_outcome(
    run: &RunSpec,
    cfg: &PipelineConfig,
    reason: String,
    recording: Option<&Recording>,
) -> RunOutcome {
    let mut record = DropRecord::failed(&run.run, run.sphere_radius_mm, reason);
    record.surface = run
        .surface
        .clone()
        .unwrap_or_else(|| cfg.input.surface.clone());
    record.sphere_density_kg_m3 = run.sphere_density_kg_m3.unwrap_or(cfg.sphere.density_kg_m3);
    record.setup = run.setup.clone().unwrap_or_default();
    record.drop_height_cm = run.drop_height_cm;
    record.path = run.path.display().to_string();
    record.fps = recording.map(|r| r.fps);
    record.fps_source = recording.map(|r| r.fps_source.clone()).unwrap_or_default();
    // What its input says of itself (colour, flips, frame names) helps read
    // why it failed: opened again for that (its header only).
    let meta = open_run(run, cfg).ok().map(|(s, _)| s.meta().clone());
    record.reading = meta.as_ref().map(|m| m.reading()).unwrap_or_default();
    RunOutcome {
        record,
        track_csv: Spool::new(0),
        track_rows: recording.map_or(0, |r| r.frames),
        overlay: None,
        frame_overlays: Vec::new(),
        impact: None,
        scene: None,
        seconds: 0.0,
        notes: meta.map(|m| m.reading_notes()).unwrap_or_default(),
    }
}
