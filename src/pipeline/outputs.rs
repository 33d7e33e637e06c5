//! A run's files drawn, as bytes for the job level to write: overlays, the
//! animated impact, the track CSV (spooled, never whole in memory).

use super::checks::{frame_rate_checks, saturated_share};
use super::types::{RunOutcome, TRACK_CSV_IN_MEMORY_MAX};
use crate::calibrate::setup_infer::SceneSignature;
use crate::config::PipelineConfig;
use crate::dataset::manifest::RunSpec;
use crate::dataset::{DropRecord, TrackRow};
use crate::measure::quality;
use crate::track::{FrameTrack, Track, TrackSettings};
use crate::util::io::Spool;

/// What a run's files are drawn and written from.
pub(super) struct Files<'a> {
    pub(super) recording: RecordingRow<'a>,
    pub(super) source: &'a mut dyn crate::source::FrameSource,
    pub(super) settings: &'a TrackSettings,
    /// A frame's row of the track CSV.
    pub(super) row_of: &'a (dyn Fn(&FrameTrack) -> TrackRow + Sync),
    /// The main overlay is the held frame nearest this time.
    pub(super) still_at_s: Option<f64>,
    /// The animated impact's contact and rebound times.
    pub(super) impact: Option<(f64, Option<f64>)>,
    pub(super) overlay_frames: &'a [i64],
    pub(super) scene: SceneSignature,
}

/// The run's outcome: `record`, with its overlays, animated impact and
/// track CSV (drawn and written beside each other).
pub(super) fn with_files(record: DropRecord, f: Files<'_>) -> Result<RunOutcome, String> {
    let Files {
        recording,
        source,
        settings,
        row_of,
        still_at_s,
        impact,
        overlay_frames,
        scene,
    } = f;
    let RecordingRow {
        run, meta, tr, sc, ..
    } = recording;
    let pictures = || {
        let mut pictures = crate::figures::pictures::Pictures {
            source,
            meta,
            track: tr,
            settings,
            delta_mm: &|f| row_of(f).delta_mm,
            mm_per_px: sc.mm_per_px,
        };
        let overlay = still_at_s.and_then(|at| {
            let ft = tr
                .frames
                .iter()
                .filter(|f| f.held.is_some() && !f.flags.contains(crate::track::Flag::Excluded))
                .min_by(|a, b| (a.t_s - at).abs().total_cmp(&(b.t_s - at).abs()))?;
            pictures.still(&ft)
        });
        let frame_overlays: Vec<(i64, Vec<u8>)> = overlay_frames
            .iter()
            .filter_map(|&n| {
                let ft = tr.frames.iter().find(|f| f.frame == n)?;
                pictures.still(&ft).map(|png| (n, png))
            })
            .collect();
        let impact = impact.and_then(|(t, rebound)| pictures.impact(t, rebound));
        (overlay, frame_overlays, impact)
    };
    let track_csv = || {
        let mut track_csv = Spool::new(TRACK_CSV_IN_MEMORY_MAX);
        crate::dataset::write_csv_rows(&mut track_csv, tr.frames.iter().map(|f| row_of(&f)))
            .map(|()| track_csv)
            .map_err(|e| {
                format!(
                    "{}: cannot hold its track CSV in a temporary file: {e}",
                    run.path.display()
                )
            })
    };
    let ((overlay, frame_overlays, impact), track_csv) = rayon::join(pictures, track_csv);
    let track_csv = track_csv?;
    // Everything above walked the track's records: none failed to be read.
    tr.frames
        .check()
        .map_err(|e| format!("{}: {e}", run.path.display()))?;
    Ok(RunOutcome {
        record,
        track_csv,
        track_rows: tr.frames.len(),
        overlay,
        frame_overlays,
        impact,
        scene: Some(scene),
        seconds: 0.0,
        notes: meta.reading_notes(),
    })
}

/// A frame's row of the track CSV, without the measurement's columns
/// (contact, δ, force: [`annotate_track`]).
pub(super) fn track_row(f: &FrameTrack) -> TrackRow {
    let fit = f.held.or(f.free);
    TrackRow {
        frame: f.frame,
        // To the nanosecond: a time computed as frame / fps carries
        // float noise (-0.0030000000000001137) no clock has.
        t_s: (f.t_s * 1e9).round() / 1e9,
        x_px: fit.map(|c| c.x_px),
        z_px: fit.map(|c| c.z_px),
        r_px: fit.map(|c| c.r_px),
        residual_px: fit.map(|c| c.residual_px),
        edge_points: fit.map_or(0, |c| c.inliers as usize),
        in_contact: false,
        delta_mm: None,
        sigma_z_px: fit.map(|c| c.cov.sigma_z_px()),
        sigma_x_px: fit.map(|c| c.cov.sigma_x_px()),
        r_free_px: f.free.map(|c| c.r_px),
        sigma_r_free_px: f.free.and_then(|c| c.cov.sigma_r_px()),
        force_n: None,
        flags: f.flags.text(),
    }
}

/// What a run's row says of its recording, its scale and its checks,
/// whatever became of its impact.
pub(super) struct RecordingRow<'a> {
    pub(super) run: &'a RunSpec,
    pub(super) cfg: &'a PipelineConfig,
    pub(super) meta: &'a crate::source::SourceMeta,
    pub(super) tr: &'a Track,
    pub(super) sc: &'a crate::calibrate::scale::Scale,
    /// Apparent minus true radius and its error, px.
    pub(super) edge_offset: Option<(f64, f64)>,
    pub(super) fps_source: &'a str,
}

impl<'a> RecordingRow<'a> {
    /// The parts of a run's row that its recording gives.
    pub(super) fn new(
        run: &'a RunSpec,
        cfg: &'a PipelineConfig,
        meta: &'a crate::source::SourceMeta,
        tr: &'a Track,
        sc: &'a crate::calibrate::scale::Scale,
        edge_offset: Option<(f64, f64)>,
        fps_source: &'a str,
    ) -> Self {
        RecordingRow {
            run,
            cfg,
            meta,
            tr,
            sc,
            edge_offset,
            fps_source,
        }
    }

    /// Fill `record`'s manifest, scale and frame-rate columns and flag what
    /// weakens them (scale disagreement, saturation, frame times, an
    /// assumed or disagreeing frame rate).
    pub(super) fn describe(&self, record: &mut DropRecord) {
        let (run, sc, meta, tr) = (self.run, self.sc, self.meta, self.tr);
        record.setup = run.setup.clone().unwrap_or_default();
        record.drop_height_cm = run.drop_height_cm;
        record.path = run.path.display().to_string();
        record.reading = meta.reading();
        record.scale_source = sc.source.name().to_string();
        record.free_fall_mm_per_px = sc.free_fall_mm_per_px.map(|(s, _)| s);
        record.free_fall_mm_per_px_err = sc.free_fall_mm_per_px.map(|(_, e)| e);
        record.edge_offset_px = self.edge_offset.map(|(o, _)| o);
        record.edge_offset_px_err = self.edge_offset.map(|(_, e)| e);
        record.surface_model_err_px = Some(tr.surface.model_err_px);
        if let Some(w) = &sc.warning {
            quality::flag(record, quality::SCALE_DISAGREEMENT, w.clone());
        }
        if let Some(share) = saturated_share(tr, meta.bit_depth) {
            quality::flag(
                record,
                quality::SATURATED,
                format!(
                    "{:.1} % of the background near the sphere's path is clipped at the white level",
                    share * 100.0
                ),
            );
        }
        for w in &meta.details.warnings {
            if w.starts_with(crate::source::validate::IRREGULAR_TIMES)
                || w.starts_with(crate::source::validate::TIMES_INCOMPLETE)
            {
                quality::flag(record, quality::TIME_IRREGULAR, w.clone());
            } else if w.starts_with(crate::source::validate::TIMES_AND_RATE_DISAGREE) {
                quality::flag(record, quality::FPS_MISMATCH, w.clone());
            }
        }
        frame_rate_checks(record, run, self.cfg, meta.fps, self.fps_source);
    }
}
