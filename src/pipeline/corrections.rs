//! Physics corrections of a run's row: the speeds at the impact's scale, the
//! lens's distortion and the edge model's systematic error of a_max.

use crate::dataset::DropRecord;
use crate::measure::events::Geometry;

/// With a given scale and a lens that is not corrected (`corrected`:
/// calibrated or measured by the surface's bow, the track then in the
/// scene's pixels, where the given scale holds at the impact as anywhere),
/// the speeds use [`crate::calibrate::scale::Scale::for_speeds`]:
/// the magnification at the impact that free fall measures, where it is
/// precise and disagrees with the given one. Where free fall is too
/// imprecise to be used (one drop's own flight), its disagreement beyond
/// its error is still added to the speeds' errors, since the given scale
/// need not be the magnification at the impact. On the real preset with
/// the true scale given, v_impact was 0.03 % high (barrel distortion) with
/// the given scale alone.
pub(super) fn speeds_at_the_impact_scale(
    record: &mut DropRecord,
    sc: &crate::calibrate::scale::Scale,
    corrected: bool,
) {
    if corrected {
        return;
    }
    let (factor, rel) = speed_factor(sc);
    for (v, err) in [
        (&mut record.v_impact_m_s, &mut record.v_impact_m_s_err),
        (&mut record.v_rebound_m_s, &mut record.v_rebound_m_s_err),
    ] {
        if let (Some(v), Some(e)) = (v.as_mut(), err.as_mut()) {
            *v *= factor;
            *e = (*e * factor).hypot(v.abs() * rel);
        }
    }
}

/// The factor that takes speeds at `sc` to speeds at the impact's
/// magnification, and the relative error that adds (see
/// [`speeds_at_the_impact_scale`]); (1, 0) unless the scale is given and
/// free fall measured one.
pub(super) fn speed_factor(sc: &crate::calibrate::scale::Scale) -> (f64, f64) {
    let (crate::calibrate::scale::ScaleSource::Given, Some((ff, ff_err))) =
        (sc.source, sc.free_fall_mm_per_px)
    else {
        return (1.0, 0.0);
    };
    match sc.for_speeds() {
        Some((s, rel)) => (s / sc.mm_per_px, rel),
        None => (
            1.0,
            ((ff / sc.mm_per_px - 1.0).abs() - ff_err / ff).max(0.0),
        ),
    }
}

/// Add the distortion bound's [`Shift`](crate::calibrate::lens::Shift) to the errors
/// as a systematic term: k1 anywhere between minus and plus the bound,
/// uniformly, moves each number by up to the shift, a standard deviation
/// of |shift| / √3. The shifts are written beside them.
pub(super) fn distortion_systematic(
    record: &mut DropRecord,
    shift: &crate::calibrate::lens::Shift,
) {
    let sd = |d: f64| d.abs() / 3f64.sqrt();
    let widen = |err: &mut Option<f64>, d: f64| *err = err.map(|e| e.hypot(sd(d)));
    widen(&mut record.mm_per_px_err, shift.mm_per_px);
    widen(&mut record.v_impact_m_s_err, shift.v_impact_m_s);
    widen(&mut record.v_rebound_m_s_err, shift.v_rebound_m_s);
    // The restitution v_out / v_in moves with both speeds' shifts at once
    // (the same k1): by e·(Δv_out/v_out − Δv_in/v_in).
    if let (Some(e), Some(vi), Some(vo)) = (
        record.restitution,
        record.v_impact_m_s,
        record.v_rebound_m_s,
    ) {
        let de = e * (shift.v_rebound_m_s / vo - shift.v_impact_m_s / vi);
        widen(&mut record.restitution_err, de);
    }
    widen(&mut record.delta_max_mm_err, shift.delta_max_mm);
    widen(&mut record.tau_c_ms_err, shift.tau_c_ms);
    record.distortion_mm_per_px = Some(shift.mm_per_px);
    record.distortion_v_impact_m_s = Some(shift.v_impact_m_s);
    record.distortion_delta_max_mm = Some(shift.delta_max_mm);
    record.distortion_tau_c_ms = Some(shift.tau_c_ms);
}

/// The standard deviation of the difference between the silhouette's edge
/// offset in the flight, where it is measured, and at the peak, where a_max
/// uses it (motion smear, the lower outline hidden in contact), px. On the
/// `realistic` renders with contacts beyond the model (120 drops) that
/// difference is 0.003 px at the median and 0.008 px at the 95th
/// percentile: a normal spread of 0.0045 px gives both (0.67σ and 1.96σ).
pub const A_MAX_EDGE_SYSTEMATIC_PX: f64 = 0.0045;

/// Add to a_max's error what is common to every frame of the peak and so
/// not in its fit's: the surface row's error (∂a/∂y_s = (R − δ)/a) and the
/// edge offset's (∂a/∂r = R/a), with [`A_MAX_EDGE_SYSTEMATIC_PX`].
pub(super) fn widen_a_max_err(record: &mut DropRecord, geom: &Geometry, edge_offset_err_px: f64) {
    let (Some(a_mm), Some(err_mm), Some(d_mm)) =
        (record.a_max_mm, record.a_max_mm_err, record.delta_max_mm)
    else {
        return;
    };
    let s = geom.mm_per_px;
    let (a, r, d) = (a_mm / s, geom.radius_px, d_mm / s);
    if a <= 0.0 {
        return;
    }
    let from_surface = (r - d) / a * geom.surface_row_err_px;
    let from_edge = r / a * edge_offset_err_px.hypot(A_MAX_EDGE_SYSTEMATIC_PX);
    record.a_max_mm_err = Some(err_mm.hypot(from_surface * s).hypot(from_edge * s));
}

/// a = √(r² − d²), d = (y_s(x) − z)·cos θ, with r the fit's radius less the
/// silhouette's edge offset, and its σ from the fit's covariance.
pub(super) fn half_width(
    f: &crate::detect::CircleFit,
    edge_offset_px: f64,
    geom: &Geometry,
) -> (Option<f64>, Option<f64>) {
    // The centre's distance from the line along its normal.
    let cos = geom.cos_tilt();
    let d = (geom.surface_row_at(f.x_px) - f.z_px) * cos;
    let r = f.r_px - edge_offset_px;
    if d.abs() >= r {
        return (None, None);
    }
    let a = (r * r - d * d).sqrt();
    let err = match f.cov {
        crate::detect::Covariance::Full([_, _, _, zz, zr, rr]) => {
            let (gr, gz) = (r / a, d / a * cos);
            (gr * gr * rr + gz * gz * zz + 2.0 * gr * gz * zr)
                .max(0.0)
                .sqrt()
        }
        crate::detect::Covariance::CentreOnly(_) => return (Some(a), None),
    };
    (Some(a), Some(err.max(1e-4)))
}
