//! One drop, from its track to its record: events → kinematics → force law
//! → [`DropRecord`] and the per-frame [`TrackRow`]s. Pure: no I/O.

use crate::dataset::{DropRecord, DropStatus, TrackRow};
use crate::measure::events::{
    find_events, EventConfig, EventError, Events, Geometry, SurfaceFrame, TrackPoint,
};
use crate::measure::force::{force_table, Damping, ForceFitError, ForceLaw};
use crate::measure::force_fit::fit_force_law;
use crate::measure::kinematics::{kinematics, Kinematics, Measured, SphereParams};
use crate::measure::quality;

/// What the measurement of one drop produced.
#[derive(Debug, Clone, PartialEq)]
pub struct DropMeasurement {
    /// The drop's row of drops.csv.
    pub record: DropRecord,
    /// The contact law fit, or why there is none.
    pub law: Result<ForceLaw, ForceFitError>,
    /// F = m(g − z̈) per contact frame: (image number, force in N).
    pub forces: Vec<(i64, f64)>,
    /// Image numbers of the frames in contact, ascending.
    pub in_contact: Vec<i64>,
}

/// Identity of the drop being measured.
#[derive(Debug, Clone, PartialEq)]
pub struct DropInfo {
    /// The run's name.
    pub run: String,
    /// Sphere radius R, mm.
    pub sphere_radius_mm: f64,
    /// Sphere density ρ, kg/m³.
    pub sphere_density_kg_m3: f64,
    /// The `[surface.<name>]` the drop hit.
    pub surface: String,
}

impl DropInfo {
    /// The sphere's radius and density in SI.
    pub fn sphere(&self) -> SphereParams {
        SphereParams {
            radius_m: self.sphere_radius_mm * 1e-3,
            density_kg_m3: self.sphere_density_kg_m3,
        }
    }
}

/// Half-width (frames) of the local cubic giving z̈ in the force table.
pub const FORCE_TABLE_HALF_WINDOW: usize = 2;

/// Measure one drop. Returns the record with status `ok`, or `warning` with
/// the warnings in `reason`; the event errors are returned for the caller to
/// turn into a `failed` row.
pub fn measure_drop(
    info: &DropInfo,
    track: &[TrackPoint],
    geom: &Geometry,
    cfg: &EventConfig,
) -> Result<DropMeasurement, EventError> {
    measure_drop_with(info, track, geom, cfg, None)
}

/// [`measure_drop`] with the contact law already fitted (`Some`: a second
/// pass on a surface the law moved keeps the first pass's law).
pub fn measure_drop_with(
    info: &DropInfo,
    track: &[TrackPoint],
    geom: &Geometry,
    cfg: &EventConfig,
    law: Option<&Result<ForceLaw, ForceFitError>>,
) -> Result<DropMeasurement, EventError> {
    let sphere = info.sphere();
    // Measured in the surface's frame (normal speeds and penetration); the
    // surface row reported is the image's, at the impact column.
    let image_geom = geom;
    let frame = surface_frame(track, geom);
    let level: Vec<TrackPoint> = track.iter().map(|p| frame.level(p)).collect();
    let (track, geom) = (&level[..], &frame.level_geometry(geom));
    let ev = find_events(track, geom, cfg)?;
    let kin = kinematics(track, &ev, geom, &sphere, cfg.exposure_s)?;
    check_penetration(&kin, info)?;
    let law = match law {
        Some(l) => l.clone(),
        None => fit_force_law(
            track,
            &ev,
            geom,
            &sphere,
            cfg.g_m_s2,
            cfg.exposure_s,
            cfg.force_fit_max_trajectories,
        ),
    };
    let table = force_table(
        track,
        &ev,
        geom,
        &sphere,
        cfg.g_m_s2,
        FORCE_TABLE_HALF_WINDOW,
    );
    let mut warnings = event_warnings(track, &ev, &kin, cfg);
    warnings.extend(law_warnings(&law));
    let surface_row_px = image_geom.surface_row_at(frame.image_col(ev.impact_column_px));
    let mut record = kinematics_record(info, &kin, &ev, geom, surface_row_px);
    set_law_columns(&mut record, law.as_ref().ok());
    for (word, message) in warnings {
        quality::flag(&mut record, word, message);
    }
    let (c0, c1) = ev.contact_span;
    Ok(DropMeasurement {
        law,
        record,
        forces: table.iter().map(|p| (p.frame, p.force_n)).collect(),
        in_contact: track[c0..=c1].iter().map(|p| p.frame).collect(),
    })
}

/// The error for a maximum penetration no sphere makes (not below its
/// radius, or not finite): the numbers are no measurement.
fn check_penetration(kin: &Kinematics, info: &DropInfo) -> Result<(), EventError> {
    if kin.delta_max_m.value >= info.sphere().radius_m || !kin.delta_max_m.value.is_finite() {
        return Err(EventError::Impossible(format!(
            "maximum penetration {:.4} mm is not below the sphere's radius {} mm",
            kin.delta_max_m.value * 1e3,
            info.sphere_radius_mm
        )));
    }
    Ok(())
}

/// The flags of the events and the flights: frames missing in the contact
/// and at its deepest point, short flights, a free-flight gravity off the
/// configured one, a second bounce.
fn event_warnings(
    track: &[TrackPoint],
    ev: &Events,
    kin: &Kinematics,
    cfg: &EventConfig,
) -> Vec<(&'static str, String)> {
    let mut warnings: Vec<(&'static str, String)> = Vec::new();
    // Frames missing in the contact, and at its deepest point.
    let (c0, c1) = ev.contact_span;
    let gap = quality::missing_between(track, track[c0 - 1].frame, track[c1 + 1].frame);
    if !gap.is_empty() {
        warnings.push((
            quality::GAP_IN_CONTACT,
            format!(
                "{} frame(s) missing in the contact ({})",
                gap.len(),
                quality::ranges(&gap)
            ),
        ));
    }
    let at_peak = quality::missing_between(track, ev.peak.frames.0 - 1, ev.peak.frames.1 + 1);
    if !at_peak.is_empty() {
        warnings.push((
            quality::GAP_AT_PEAK,
            format!(
                "{} frame(s) missing at the maximum penetration ({}): δmax is interpolated over them",
                at_peak.len(),
                quality::ranges(&at_peak)
            ),
        ));
    }
    let flight = ev.pre.n_points.min(ev.post.n_points);
    if flight < quality::MIN_GOOD_FLIGHT_FRAMES {
        warnings.push((
            quality::SHORT_FLIGHT,
            format!(
                "only {} free-flight frames before and {} after the contact (fewer than {})",
                ev.pre.n_points,
                ev.post.n_points,
                quality::MIN_GOOD_FLIGHT_FRAMES
            ),
        ));
    }
    if let Some(g) = kin.g_fit_m_s2[0] {
        // Off by more than 2 % and more than three of its own σ.
        let off = g.value / cfg.g_m_s2 - 1.0;
        if off.abs() > 0.02 && (g.value - cfg.g_m_s2).abs() > 3.0 * g.err {
            warnings.push((quality::GRAVITY_OFF, format!(
                "free-flight gravity {:.3} ± {:.3} m/s² is {:+.1} % off {} m/s²: check the frame rate and the scale",
                g.value,
                g.err,
                off * 100.0,
                cfg.g_m_s2
            )));
        }
    }
    if ev.second_contact_s.is_some() {
        warnings.push((
            quality::SECOND_CONTACT,
            "a second bounce follows; only the first contact is measured".into(),
        ));
    }
    warnings
}

/// The drop's record with status `ok`: its kinematics, the level frame's
/// scale (`geom`) and the image's surface row at the impact column; no
/// contact law yet.
fn kinematics_record(
    info: &DropInfo,
    kin: &Kinematics,
    ev: &Events,
    geom: &Geometry,
    surface_row_px: f64,
) -> DropRecord {
    let v = |m: Measured| (Some(m.value), Some(m.err));
    let mm = |m: Measured| (Some(m.value * 1e3), Some(m.err * 1e3));
    let (v_in, v_in_err) = v(kin.v_impact_m_s);
    let (v_out, v_out_err) = v(kin.v_rebound_m_s);
    let (e_val, e_err) = v(kin.restitution);
    let (d, d_err) = mm(kin.delta_max_m);
    let (a_geom, a_geom_err) = mm(kin.a_geom_m);
    let (a_max, a_max_err) = kin.a_max_m.map(mm).unwrap_or((None, None));
    let (tau, tau_err) = mm(kin.tau_c_s);
    let (tc, tc_err) = v(kin.t_contact_s);
    let (tr, tr_err) = v(kin.t_rebound_s);
    DropRecord {
        run: info.run.clone(),
        sphere_radius_mm: info.sphere_radius_mm,
        sphere_density_kg_m3: info.sphere_density_kg_m3,
        surface: info.surface.clone(),
        drop_height_cm: None,
        path: String::new(),
        v_impact_m_s: v_in,
        v_impact_m_s_err: v_in_err,
        v_rebound_m_s: v_out,
        v_rebound_m_s_err: v_out_err,
        restitution: e_val,
        restitution_err: e_err,
        delta_max_mm: d,
        delta_max_mm_err: d_err,
        a_max_mm: a_max,
        a_max_mm_err: a_max_err,
        a_geom_mm: a_geom,
        a_geom_mm_err: a_geom_err,
        tau_c_ms: tau,
        tau_c_ms_err: tau_err,
        t_contact_s: tc,
        t_contact_s_err: tc_err,
        t_rebound_s: tr,
        t_rebound_s_err: tr_err,
        mm_per_px: Some(geom.mm_per_px),
        mm_per_px_err: Some(if geom.scale_from_radius {
            geom.mm_per_px * geom.radius_err_px / geom.radius_px
        } else {
            geom.mm_per_px_err
        }),
        surface_row_px: Some(surface_row_px),
        surface_row_px_err: Some(geom.surface_row_err_px),
        t_max_s: Some(kin.t_max_s),
        second_contact_s: ev.second_contact_s,
        g_fit_m_s2: kin.g_fit_m_s2[0].map(|g| g.value),
        g_fit_m_s2_err: kin.g_fit_m_s2[0].map(|g| g.err),
        status: DropStatus::Ok,
        ..DropRecord::failed(&info.run, info.sphere_radius_mm, "")
    }
}

/// The record's contact-law columns from `law` (`None`: not fitted, all
/// empty); the damping in the column of its model's kind.
fn set_law_columns(record: &mut DropRecord, law: Option<&ForceLaw>) {
    let damping_of = |kind: Damping| law.filter(|l| l.model.damping == kind).map(|l| l.damping);
    let (linear, hunt_crossley) = (
        damping_of(Damping::Linear),
        damping_of(Damping::HuntCrossley),
    );
    record.force_k_si = law.map(|l| l.k.value);
    record.force_k_si_err = law.map(|l| l.k.err);
    record.force_exponent = law.map(|l| l.n.value);
    record.force_exponent_err = law.map(|l| l.n.err);
    record.force_k2_n_m2 = law.map(|l| l.k_at_n2.value);
    record.force_k2_n_m2_err = law.map(|l| l.k_at_n2.err);
    record.force_model = law.map_or(String::new(), |l| l.model.name().to_string());
    record.damping_n_s_m = linear.map(|c| c.value);
    record.damping_n_s_m_err = linear.map(|c| c.err);
    record.hunt_crossley_alpha_s_m = hunt_crossley.map(|a| a.value);
    record.hunt_crossley_alpha_s_m_err = hunt_crossley.map(|a| a.err);
}

/// The surface's frame for `track`, pivoting at the column of its deepest
/// point (the impact's, where the turn moves nothing).
fn surface_frame(track: &[TrackPoint], geom: &Geometry) -> SurfaceFrame {
    let deepest = track
        .iter()
        .max_by(|a, b| {
            geom.penetration_px(a.x_px, a.z_px)
                .total_cmp(&geom.penetration_px(b.x_px, b.z_px))
        })
        .map_or(0.0, |p| p.x_px);
    SurfaceFrame::of(geom, deepest)
}

/// The contact law's cross-check of the image's surface line: a flag
/// and its sentence when the surface the trajectory puts under the sphere
/// ([`ForceLaw::surface_offset_px`], n free) is more than 3σ of their
/// combined error from the line (error `image_err_px`). The line is never
/// replaced: the surface is measured in the image, the law is what the
/// experiment measures.
pub fn surface_law_check(law: &ForceLaw, image_err_px: f64) -> Option<(&'static str, String)> {
    let d = law.surface_offset_px?;
    if !(d.value.is_finite() && d.err.is_finite()) {
        return None;
    }
    let combined = d.err.hypot(image_err_px);
    (d.value.abs() > 3.0 * combined).then(|| {
        (
            quality::SURFACE_LAW_DISAGREEMENT,
            format!(
                "the trajectory, fitted with a power-law contact ({}) and the surface free, \
                 puts the undeformed surface {:.2} ± {:.2} px {} the image's line, whose \
                 errors now include that disagreement: check the surface line in the overlay \
                 (a reflection or a glossy band top moves it) and F(δ) in the drop's figure \
                 (a contact that is no power law moves the fit)",
                law.model.name(),
                d.value.abs(),
                combined,
                if d.value > 0.0 { "below" } else { "above" },
            ),
        )
    })
}

/// Flag a restitution above 1 by more than 3σ: the sphere cannot gain
/// energy. Called once the restitution's error holds every term (the
/// distortion's is added after the measurement).
pub fn flag_restitution_above_one(record: &mut DropRecord) {
    let (Some(e), Some(err)) = (record.restitution, record.restitution_err) else {
        return;
    };
    if e > 1.0 + 3.0 * err {
        quality::flag(
            record,
            quality::RESTITUTION_ABOVE_ONE,
            format!("restitution {e:.4} ± {err:.4} is above 1: the sphere cannot gain energy"),
        );
    }
}

/// The flags of a contact law fit: none fitted, or a fit no physics allows
/// (n outside [`quality::FORCE_EXPONENT_RANGE`], damping negative by more
/// than 3σ).
fn law_warnings(law: &Result<ForceLaw, ForceFitError>) -> Vec<(&'static str, String)> {
    let l = match law {
        Err(e) => {
            return vec![(
                quality::NO_FORCE_LAW,
                format!("the force law could not be fitted: {e}"),
            )]
        }
        Ok(l) => l,
    };
    let mut out = Vec::new();
    let (lo, hi) = quality::FORCE_EXPONENT_RANGE;
    if !(lo..=hi).contains(&l.n.value) {
        out.push((
            quality::FORCE_EXPONENT_IMPLAUSIBLE,
            format!(
                "force exponent n = {:.3} is outside {lo}–{hi}: the contact law fit is not credible",
                l.n.value
            ),
        ));
    }
    let c = l.damping;
    if c.value < -3.0 * c.err {
        let unit = match l.model.damping {
            Damping::Linear => "N·s/m",
            Damping::HuntCrossley => "s/m",
        };
        out.push((
            quality::NEGATIVE_DAMPING,
            format!(
                "damping {:.4e} ± {:.1e} {unit} is negative: the contact law fit is not credible",
                c.value, c.err
            ),
        ));
    }
    out
}

/// Fill the contact flag, δ and force columns of track rows from a measurement.
pub fn annotate_track(rows: &mut [TrackRow], m: &DropMeasurement, geom: &Geometry) {
    for row in rows.iter_mut() {
        row.in_contact = m.in_contact.binary_search(&row.frame).is_ok();
        row.delta_mm = match (row.x_px, row.z_px) {
            (Some(x), Some(z)) => Some(geom.penetration_px(x, z) * geom.mm_per_px),
            _ => None,
        };
        row.force_n = m
            .forces
            .iter()
            .find(|(f, _)| *f == row.frame)
            .map(|(_, f)| *f);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measure::events::TrackPoint;
    use crate::measure::kinematics::Measured;
    use crate::test_support::{geometry, track, Drop};

    /// A contact law with the given surface cross-check (offset, its σ).
    fn law_with(n: f64, damping: f64, offset: Option<(f64, f64)>) -> ForceLaw {
        let m = |value, err| Measured { value, err };
        ForceLaw {
            model: crate::measure::force::ContactModel::ALL[0],
            k: m(1e9, 1e8),
            n: m(n, 0.5),
            damping: m(damping, 0.01),
            k_at_n2: m(8e8, 1e6),
            surface_offset_px: offset.map(|(value, err)| m(value, err)),
            n_per_surface_px: 0.0,
            k_per_surface_px: 0.0,
            chi2_red: 1.0,
            models: Vec::new(),
            n_frames: 60,
        }
    }

    #[test]
    fn the_laws_surface_flags_an_image_line_it_contradicts_and_never_moves_it() {
        // 1 px above a line of 0.1 px error, the law's σ 0.03: flagged, the
        // sentence saying where and what to check.
        let (word, why) = surface_law_check(&law_with(2.0, 0.0, Some((-1.0, 0.03))), 0.1).unwrap();
        assert_eq!(word, "surface_law_disagreement");
        assert!(
            why.contains("1.00 ± 0.10 px above the image's line"),
            "{why}"
        );
        assert!(why.contains("overlay"), "{why}");
        // Within 3σ of their combined error: nothing to say.
        assert_eq!(
            surface_law_check(&law_with(2.0, 0.0, Some((-0.3, 0.03))), 0.1),
            None
        );
        // No law's surface, or a degenerate one: nothing.
        assert_eq!(surface_law_check(&law_with(2.0, 0.0, None), 0.1), None);
        assert_eq!(
            surface_law_check(&law_with(2.0, 0.0, Some((0.2, f64::NAN))), 0.1),
            None
        );
    }

    #[test]
    fn an_impossible_contact_law_is_flagged_never_ok() {
        let law = |n, c| law_with(n, c, None);
        let words = |l| -> Vec<&str> { law_warnings(&l).iter().map(|w| w.0).collect() };
        assert!(words(Ok(law(2.01, -0.02))).is_empty());
        assert_eq!(
            words(Ok(law(106.0, -0.5))),
            ["force_exponent_implausible", "negative_damping"]
        );
        assert_eq!(words(Ok(law(0.7, 0.0))), ["force_exponent_implausible"]);
        let e = law_warnings(&Err(ForceFitError::Limit("20 s".into())));
        assert_eq!(e[0].0, "no_force_law");
        assert!(
            e[0].1.contains("stopped at its limit of 20 s"),
            "{}",
            e[0].1
        );
    }

    #[test]
    fn a_long_movie_is_measured_on_its_first_bounce_alone_to_the_same_bits() {
        use crate::measure::events::{find_events, first_contact_window};
        let drop = Drop::new(4.5e-3, 1.7, 0.4e-4);
        let geom = geometry();
        let cfg = EventConfig::default();
        let info = DropInfo {
            run: "r".into(),
            sphere_radius_mm: 4.5,
            sphere_density_kg_m3: 7800.0,
            surface: "pdms".into(),
        };
        let first = track(&drop, &geom, 0.02, 3);
        let end = first.last().unwrap().frame + 1;
        // Then the sphere lands again and rests on the surface.
        let resting = |n: i64| TrackPoint {
            frame: n,
            t_s: n as f64 / 1e4,
            x_px: 256.0,
            z_px: geom.surface_row_px - geom.radius_px + 2.0 + 0.01 * (n % 7) as f64,
            sigma_z_px: 0.02,
            half_width_px: None,
            sigma_half_width_px: None,
        };
        let movie = |rest: i64| -> Vec<TrackPoint> {
            first
                .iter()
                .copied()
                .chain((end..end + rest).map(resting))
                .collect()
        };
        let window = |pts: &[TrackPoint]| first_contact_window(pts.iter().copied(), &geom, &cfg);
        let (short, long) = (movie(1_000), movie(100_000));
        let w = window(&long).unwrap();
        // What is held does not grow with the movie: the first bounce, the
        // second contact's first frame and the contact law's flight frames.
        assert_eq!(w, window(&short).unwrap());
        assert!(
            w.len() <= first.len() + crate::measure::events::FLIGHT_FRAMES,
            "{}",
            w.len()
        );
        assert_eq!(w[..], long[..w.len()]);
        let whole = measure_drop(&info, &long, &geom, &cfg).unwrap();
        assert!(whole.record.second_contact_s.is_some());
        assert_eq!(measure_drop(&info, &w, &geom, &cfg).unwrap(), whole);

        // Every error of the whole track, the same from the window's walk.
        let events = |pts: &[TrackPoint]| find_events(pts, &geom, &cfg).map(|_| ());
        let windowed = |pts: &[TrackPoint]| window(pts).and_then(|w| events(&w));
        let mut not_finite = long.clone();
        not_finite[50_000].z_px = f64::NAN;
        let mut backwards = long.clone();
        backwards[60_000].t_s = backwards[59_999].t_s;
        let above: Vec<TrackPoint> = first
            .iter()
            .map(|p| TrackPoint {
                z_px: p.z_px - 40.0,
                ..*p
            })
            .collect();
        let c0 = first
            .iter()
            .position(|p| geom.penetration_px(p.x_px, p.z_px) > 0.0)
            .unwrap();
        let never_leaves: Vec<TrackPoint> = first[..c0]
            .iter()
            .copied()
            .chain((first[c0].frame..end + 500).map(resting))
            .collect();
        for (what, pts) in [
            ("not finite", &not_finite[..]),
            ("times", &backwards[..]),
            ("never lands", &above[..]),
            ("already in contact", &long[c0..]),
            ("no rebound", &never_leaves[..]),
            ("too few", &long[..8]),
        ] {
            let e = events(pts).unwrap_err();
            assert_eq!(windowed(pts), Err(e), "{what}");
        }
    }

    #[test]
    fn a_clean_drop_gives_an_ok_record_with_every_column_and_a_warning_past_the_fit_limit() {
        let drop = Drop::new(4.5e-3, 1.7, 0.4e-4);
        let geom = geometry();
        let tr = track(&drop, &geom, 0.02, 3);
        let info = DropInfo {
            run: "r".into(),
            sphere_radius_mm: 4.5,
            sphere_density_kg_m3: 7800.0,
            surface: "pdms".into(),
        };
        let m = measure_drop(&info, &tr, &geom, &EventConfig::default()).unwrap();
        let r = &m.record;
        assert_eq!(r.status, DropStatus::Ok, "{}", r.reason);
        let tau_true_ms = (drop.t_r - drop.t0) * 1e3;
        assert!((r.tau_c_ms.unwrap() / tau_true_ms - 1.0).abs() < 1e-3);
        assert!((r.delta_max_mm.unwrap() / (drop.delta_max * 1e3) - 1.0).abs() < 1e-3);
        assert!((r.force_exponent.unwrap() - 2.0).abs() < 0.05);
        assert!(r.restitution.unwrap() > 0.99 && r.restitution.unwrap() < 1.01);
        // Every contact frame is flagged, and the force table covers most of them.
        assert!(m.in_contact.len() >= 20, "{}", m.in_contact.len());
        assert!(m.forces.len() + 2 * FORCE_TABLE_HALF_WINDOW >= m.in_contact.len());
        let bytes = crate::dataset::to_csv_bytes(std::slice::from_ref(r));
        let text = String::from_utf8(bytes).unwrap();
        assert!(
            text.lines().nth(1).unwrap().ends_with(",ok,-,-,-"),
            "{text}"
        );

        // The configured work limit reaches the contact-law fit: these fits
        // need about 400 trajectories, 20 stop them, and the record says why
        // (a warning, never ok).
        let cfg = EventConfig {
            force_fit_max_trajectories: 20,
            ..EventConfig::default()
        };
        let m = measure_drop(&info, &tr, &geom, &cfg).unwrap();
        assert_eq!(
            m.law,
            Err(ForceFitError::Limit("20 trajectories' work".into()))
        );
        assert_eq!(m.record.status, DropStatus::Warning);
        assert!(
            m.record
                .reason
                .contains("stopped at its limit of 20 trajectories' work"),
            "{}",
            m.record.reason
        );
    }
}
