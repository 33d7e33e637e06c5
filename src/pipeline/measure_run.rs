//! One tracked run measured: lens, scale, events, kinematics and its row
//! ([`measure_run`]), or the row of a run that never reached the surface.

use super::corrections::{
    distortion_systematic, half_width, speed_factor, speeds_at_the_impact_scale, widen_a_max_err,
};
use super::outputs::{track_row, with_files, Files, RecordingRow};
use super::points::{bounded_points, held_points};
use super::tracked::{lens_of, LensUsed, Tracked};
use super::types::RunOutcome;
use crate::calibrate::free_fall::Curvature;
use crate::calibrate::lens::Bounded;
use crate::calibrate::scale::{Scale, ScaleInputs};
use crate::config::PipelineConfig;
use crate::dataset::manifest::RunSpec;
use crate::dataset::{DropRecord, TrackRow};
use crate::measure::events::{EventConfig, EventError, Geometry, TrackPoint};
use crate::measure::quality;
use crate::measure::{annotate_track, measure_drop, measure_drop_with, DropInfo, DropMeasurement};
use crate::track::{FrameTrack, Track};

pub(super) fn measure_run(
    t: Tracked,
    run: &RunSpec,
    cfg: &PipelineConfig,
    [setup, setup_at_bound]: [Option<Curvature>; 2],
    overlay_frames: &[i64],
) -> Result<RunOutcome, String> {
    let scene = t.scene(run.sphere_radius_mm);
    let Tracked {
        mut source,
        meta,
        tr,
        settings,
        surface_name,
        curvature,
        bounded,
        fps_source,
    } = t;
    let event_cfg = EventConfig {
        exposure_s: meta.exposure_s.unwrap_or(0.0),
        ..EventConfig::default()
    };
    let own = [curvature, bounded.as_ref().and_then(|b| b.curvature)];
    let inputs = scale_inputs(
        run,
        cfg,
        &tr,
        event_cfg.g_m_s2,
        [setup, setup_at_bound],
        own,
    );
    let sc = crate::calibrate::scale::resolve(&inputs);
    let edge_offset = sc.edge_offset_px(&inputs);
    let geom = image_geometry(&tr, &sc, &inputs);
    let info = drop_info(run, cfg, surface_name);
    // The free-radius circle measures the silhouette: its radius, less the
    // edge offset, is the sphere's.
    let offset_px_edge = edge_offset.map_or(0.0, |(o, _)| o);
    let steps = Steps {
        run,
        tr: &tr,
        info,
        event_cfg,
        offset_px_edge,
    };
    let first_geom = geom;
    let points = match steps.window(&geom, &geom) {
        Err(e @ EventError::NeverLands { .. }) => {
            // Tracked, never landing: its free flight and files, no impact.
            let row_of = |f: &FrameTrack| clearance_row(f, &geom);
            let files = Files {
                recording: RecordingRow::new(run, cfg, &meta, &tr, &sc, edge_offset, &fps_source),
                source: source.as_mut(),
                settings: &settings,
                row_of: &row_of,
                still_at_s: None,
                impact: None,
                overlay_frames,
                scene,
            };
            let g_m_s2 = steps.event_cfg.g_m_s2;
            return tracked_only(steps.failed(e), &steps.info, &geom, g_m_s2, files);
        }
        points => points.map_err(|e| steps.failed(e))?,
    };
    let surface = steps.surface(points, geom, tr.surface_from_config)?;
    let (m, geom) = (&surface.measured, &surface.geom);
    // A frame's row of the track CSV, with contact, δ and force: made
    // when written, one at a time (a long movie's rows, 168 bytes a frame,
    // were held beside its track).
    let row_of = |f: &FrameTrack| {
        let mut row = track_row(f);
        annotate_track(std::slice::from_mut(&mut row), m, geom);
        row
    };
    let mut record = surface.record(edge_offset.map_or(0.0, |(_, e)| e));
    let at_bound = bounded.as_ref().map(|b| AtBound {
        first_geom: &first_geom,
        geom,
        sc: &sc,
        inputs: &inputs,
        bounded: b,
        setup_at_bound,
    });
    steps.lens_columns(&mut record, lens_of(&tr, &meta, cfg), &sc, at_bound);
    crate::measure::flag_restitution_above_one(&mut record);
    // The overlays draw the line used.
    let mut tr = tr;
    tr.surface.row0_px += surface.hand_offset_px;
    let recording = RecordingRow::new(run, cfg, &meta, &tr, &sc, edge_offset, &fps_source);
    recording.describe(&mut record);
    let impact = record
        .t_contact_s
        .filter(|_| cfg.output.animation)
        .map(|t| (t, record.t_rebound_s));
    // The overlay at the frame nearest the maximum penetration.
    let still_at_s = record.t_max_s;
    with_files(
        record,
        Files {
            recording,
            source: source.as_mut(),
            settings: &settings,
            row_of: &row_of,
            still_at_s,
            impact,
            overlay_frames,
            scene,
        },
    )
}

/// The scale's inputs: given (manifest, then configuration), else free fall
/// (the set-up's, else the run's `own`), else the sphere's apparent radius;
/// each pair as measured and at the recording's bound.
fn scale_inputs(
    run: &RunSpec,
    cfg: &PipelineConfig,
    tr: &Track,
    g_m_s2: f64,
    [setup, setup_at_bound]: [Option<Curvature>; 2],
    [own, own_at_bound]: [Option<Curvature>; 2],
) -> ScaleInputs {
    ScaleInputs {
        radius_mm: run.sphere_radius_mm,
        g_m_s2,
        given_mm_per_px: cfg.given_mm_per_px(run.mm_per_px),
        setup,
        own,
        r_app_px: tr.radius_px,
        r_app_err_px: tr.radius_err_px,
        edge_offset: crate::calibrate::scale::EdgeOffset::from_config(&cfg.camera),
        setup_at_bound,
        own_at_bound,
    }
}

/// The drop's description: the run's sphere (its density the
/// configuration's where the manifest gives none) and surface.
fn drop_info(run: &RunSpec, cfg: &PipelineConfig, surface: String) -> DropInfo {
    DropInfo {
        run: run.run.clone(),
        sphere_radius_mm: run.sphere_radius_mm,
        sphere_density_kg_m3: run.sphere_density_kg_m3.unwrap_or(cfg.sphere.density_kg_m3),
        surface,
    }
}

/// A frame's row of the track CSV for a drop that never lands: δ is the
/// clearance (negative).
fn clearance_row(f: &FrameTrack, geom: &Geometry) -> TrackRow {
    let mut row = track_row(f);
    row.delta_mm = row
        .x_px
        .zip(row.z_px)
        .map(|(x, z)| geom.penetration_px(x, z) * geom.mm_per_px);
    row
}

/// The geometry the image gives: its surface line (with its error at the
/// track's mean column) and the scale, with the true radius in pixels tied
/// to it (R_px = R_mm / s, whatever the scale's source), so that the
/// kinematics carries them as one.
fn image_geometry(tr: &Track, sc: &Scale, inputs: &ScaleInputs) -> Geometry {
    let (radius_px, radius_err_px) = sc.radius_px(inputs);
    let mut held = 0usize;
    let x_sum: f64 = tr
        .frames
        .iter()
        .filter_map(|f| f.held.map(|h| h.x_px))
        .inspect(|_| held += 1)
        .sum();
    let x_mid = x_sum / held.max(1) as f64;
    Geometry {
        surface_row_px: tr.surface.row0_px,
        surface_slope: tr.surface.slope,
        surface_row_err_px: tr.surface_row_err_px(x_mid),
        radius_px,
        radius_err_px,
        mm_per_px: sc.mm_per_px,
        mm_per_px_err: sc.mm_per_px * sc.rel_err,
        scale_from_radius: true,
    }
}

/// What the steps of [`measure_run`] share: the run, its track, the drop's
/// description and how its events are found.
struct Steps<'a> {
    run: &'a RunSpec,
    tr: &'a Track,
    info: DropInfo,
    event_cfg: EventConfig,
    /// The free-radius circle's edge offset (px).
    offset_px_edge: f64,
}

/// The drop measured on the surface finally used, and what chose it.
struct Surface {
    measured: DropMeasurement,
    geom: Geometry,
    /// `image`, `config` or `review`.
    source: &'static str,
    /// A surface set by hand less the line found at the impact (px).
    hand_offset_px: f64,
    /// The contact law's surface disagreeing with the image's line: the
    /// flag, and the law's offset from the line (px).
    disagreement: Option<((&'static str, String), f64)>,
}

/// What the lens's shift at the recording's bound is measured with.
struct AtBound<'a> {
    first_geom: &'a Geometry,
    geom: &'a Geometry,
    sc: &'a Scale,
    inputs: &'a ScaleInputs,
    bounded: &'a Bounded,
    setup_at_bound: Option<Curvature>,
}

impl Steps<'_> {
    /// The points of the first bounce that the events under `geom` use,
    /// with the contact half-widths of `half_widths`: made again from the
    /// track when needed, never every frame's.
    fn window(
        &self,
        half_widths: &Geometry,
        geom: &Geometry,
    ) -> Result<Vec<TrackPoint>, EventError> {
        let held = held_points(self.tr, |f| half_width(f, self.offset_px_edge, half_widths));
        crate::measure::events::first_contact_window(held, geom, &self.event_cfg)
    }

    /// The run's reason for `e`.
    fn failed(&self, e: EventError) -> String {
        format!("{}: {e}", self.run.path.display())
    }

    /// The drop measured on the surface used. The surface is the image's
    /// line (or the configuration's), never the contact law's: the law is
    /// what the experiment measures. The law's surface only cross-checks
    /// the line: where they disagree beyond 3σ the drop is flagged, and the
    /// line's error takes in their disagreement (which of the two is off,
    /// the image cannot tell), so that every error resting on the line says
    /// so; the values stay the line's. A surface row set by hand in
    /// `dropscope review` replaces the line found, wherever it came from:
    /// through the row given at the impact column, with the image's tilt.
    /// Like the configuration's, it is given, not cross-checked.
    fn surface(
        &self,
        points: Vec<TrackPoint>,
        geom: Geometry,
        from_config: bool,
    ) -> Result<Surface, String> {
        let failed = |e| self.failed(e);
        let (info, event_cfg) = (&self.info, &self.event_cfg);
        let mut m = measure_drop(info, &points, &geom, event_cfg).map_err(failed)?;
        drop(points);
        let mut source = if from_config { "config" } else { "image" };
        let mut geom = geom;
        let by_hand = self.run.review.surface_row_px.as_ref().map(|(row, _)| *row);
        let mut hand_offset_px = 0.0;
        if let Some(row_px) = by_hand {
            let at_impact = m.record.surface_row_px.unwrap_or(geom.surface_row_px);
            hand_offset_px = row_px - at_impact;
            geom.surface_row_px += hand_offset_px;
            geom.surface_row_err_px = crate::dataset::decisions::HAND_SURFACE_ERR_PX;
            source = "review";
            let points = self.window(&geom, &geom).map_err(failed)?;
            m = measure_drop(info, &points, &geom, event_cfg).map_err(failed)?;
        }
        let disagreement = match &m.law {
            Ok(law) if source == "image" => {
                crate::measure::surface_law_check(law, geom.surface_row_err_px)
                    .map(|flag| (flag, law.surface_offset_px.map_or(0.0, |d| d.value)))
            }
            _ => None,
        };
        if let Some((_, offset_px)) = disagreement {
            geom.surface_row_err_px = geom.surface_row_err_px.hypot(offset_px);
            let points = self.window(&geom, &geom).map_err(failed)?;
            m = measure_drop_with(info, &points, &geom, event_cfg, Some(&m.law)).map_err(failed)?;
        }
        Ok(Surface {
            measured: m,
            geom,
            source,
            hand_offset_px,
            disagreement,
        })
    }

    /// The lens's columns of `record`: the speeds at the impact's scale
    /// (through `lens` where it corrects them), the lens's k1 and source,
    /// and, for a recording bounded by the frame, the systematic the lens's
    /// shift at that bound puts on the speeds.
    fn lens_columns(
        &self,
        record: &mut DropRecord,
        lens: LensUsed,
        sc: &Scale,
        at_bound: Option<AtBound<'_>>,
    ) {
        let corrected = matches!(lens, LensUsed::Calibrated(_) | LensUsed::Measured { .. });
        speeds_at_the_impact_scale(record, sc, corrected);
        let (k1, k1_err, lens_source) = lens.describe();
        record.distortion_k1_per_px2 = k1;
        record.distortion_k1_per_px2_err = k1_err;
        record.distortion_source = lens_source.to_string();
        if let Some(shift) = at_bound.and_then(|b| self.shift_at_bound(&b, corrected)) {
            distortion_systematic(record, &shift);
        }
    }

    /// The lens's shift of the speeds at the recording's bound: the first
    /// look's points (their half-widths on the image's line) and the
    /// lens's, each under the geometry measured on them; `corrected`: the
    /// speeds are already corrected for the lens.
    fn shift_at_bound(
        &self,
        b: &AtBound<'_>,
        corrected: bool,
    ) -> Option<crate::calibrate::lens::Shift> {
        crate::calibrate::lens::shift_at_bound(
            |g| self.window(b.first_geom, g).ok(),
            |g| {
                let held = bounded_points(self.tr, &b.bounded.lens, b.bounded.radius_px);
                crate::measure::events::first_contact_window(held, g, &self.event_cfg).ok()
            },
            b.geom,
            b.sc,
            b.inputs,
            b.bounded,
            b.setup_at_bound,
            b.geom.surface_row_px - self.tr.surface.row0_px,
            &self.info.sphere(),
            &self.event_cfg,
            |sc| if corrected { 1.0 } else { speed_factor(sc).0 },
        )
    }
}

impl Surface {
    /// The drop's record: the law's disagreement flagged, with the widened
    /// line error reaching n and K through their response to the surface;
    /// where the surface came from; a_max's error with the edge offset's
    /// (`edge_offset_err_px`).
    fn record(&self, edge_offset_err_px: f64) -> DropRecord {
        let m = &self.measured;
        let law_offset = m.law.as_ref().ok().and_then(|l| l.surface_offset_px);
        let mut record = m.record.clone();
        if let (Some(((word, message), offset_px)), Ok(law)) = (&self.disagreement, &m.law) {
            quality::flag(&mut record, word, message.clone());
            let widen = |err: &mut Option<f64>, per_px: f64| {
                *err = err.map(|e| e.hypot(per_px * offset_px));
            };
            widen(&mut record.force_exponent_err, law.n_per_surface_px);
            widen(&mut record.force_k_si_err, law.k_per_surface_px);
        }
        record.surface_source = self.source.to_string();
        record.surface_law_offset_px = law_offset.map(|d| d.value);
        record.surface_law_offset_px_err = law_offset.map(|d| d.err);
        widen_a_max_err(&mut record, &self.geom, edge_offset_err_px);
        record
    }
}

/// The outcome of a run whose sphere was tracked but never reached the
/// surface (`why`): status `tracked`, its free flight ([`crate::measure::flight`]:
/// v at the last tracked frame, g) at the run's scale, its scale and frame
/// rate columns, its track (δ negative: the clearance) and the overlay of
/// its last tracked frame, no impact.
pub(super) fn tracked_only(
    why: String,
    info: &DropInfo,
    geom: &Geometry,
    g_m_s2: f64,
    f: Files<'_>,
) -> Result<RunOutcome, String> {
    let (run, tr, sc) = (f.recording.run, f.recording.tr, f.recording.sc);
    let mut record = DropRecord::failed(&run.run, run.sphere_radius_mm, String::new());
    record.status = crate::dataset::DropStatus::Tracked;
    record.sphere_density_kg_m3 = info.sphere_density_kg_m3;
    record.surface = info.surface.clone();
    record.mm_per_px = Some(sc.mm_per_px);
    record.mm_per_px_err = Some(sc.mm_per_px * sc.rel_err);
    let points: Vec<TrackPoint> = held_points(tr, |_| (None, None)).collect();
    record.surface_row_px = points
        .last()
        .map(|p| geom.surface_row_at(p.x_px))
        .or(Some(geom.surface_row_px));
    record.surface_row_px_err = Some(geom.surface_row_err_px);
    record.surface_source = "image".into();
    record.reason =
        match crate::measure::flight::free_flight(&points, sc.mm_per_px, sc.rel_err, g_m_s2) {
            Ok(ff) => {
                // To the nanosecond, as the track's times.
                record.t_last_s = Some((ff.t_last_s * 1e9).round() / 1e9);
                record.v_last_m_s = Some(ff.v_last_m_s.value);
                record.v_last_m_s_err = Some(ff.v_last_m_s.err);
                record.g_fit_m_s2 = ff.g_fit_m_s2.map(|g| g.value);
                record.g_fit_m_s2_err = ff.g_fit_m_s2.map(|g| g.err);
                format!(
                    "{why}: tracked only, no impact measured: {} frames of free flight, v = \
                 {:.4} ± {:.4} m/s at the last one",
                    ff.frames, ff.v_last_m_s.value, ff.v_last_m_s.err
                )
            }
            Err(e) => format!("{why}: tracked only, no impact measured; no free-flight fit: {e}"),
        };
    if let Some(g) = record.g_fit_m_s2.zip(record.g_fit_m_s2_err) {
        // As a drop's flight is checked (crate::measure).
        let off = g.0 / g_m_s2 - 1.0;
        if off.abs() > 0.02 && (g.0 - g_m_s2).abs() > 3.0 * g.1 {
            quality::flag(
                &mut record,
                quality::GRAVITY_OFF,
                format!(
                    "free-flight gravity {:.3} ± {:.3} m/s² is {:+.1} % off {g_m_s2} m/s²: \
                     check the frame rate and the scale",
                    g.0,
                    g.1,
                    off * 100.0
                ),
            );
        }
    }
    f.recording.describe(&mut record);
    let still_at_s = points.last().map(|p| p.t_s);
    with_files(
        record,
        Files {
            still_at_s,
            impact: None,
            ..f
        },
    )
}
