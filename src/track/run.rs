//! The tracker's steps in order ([`track`]): background and surface, pass 1,
//! calibration, pass 2, outliers.

use super::ahead::pass1;
use super::background::background_and_surface;
use super::error::{upside_down_hint, TrackError};
use super::frame::{Flag, FrameTrack};
use super::look::{LookScratch, Pass1, ScratchPool};
use super::outliers;
use super::pass2::{hold_all, read_again};
use super::settings::TrackSettings;
use super::types::Track;
use super::walk::Walk;
use crate::detect::calibrate::{calibrate_radius, full_circle, RadiusCalibration};
use crate::detect::{Background, CircleFit, SurfaceLine};
use crate::source::FrameSource;
use crate::util::records::Records;
use crate::util::timings::{self, Stage};

/// Systematic uncertainty of the calibrated R_px (see `track`).
pub const RADIUS_SYSTEMATIC_PX: f64 = 0.002;

/// Track the sphere through `source` (see the module doc).
pub fn track(source: &mut dyn FrameSource, st: &TrackSettings) -> Result<Track, TrackError> {
    let meta = source.meta().clone();
    let n = meta.frame_count;
    if n < 8 {
        return Err(TrackError::TooShort(n));
    }
    let (h, w) = (meta.height, meta.width);

    // 1. Background and surface.
    let (bg, surface, surface_from_config) = background_and_surface(source, st)?;

    // 2. Pass 1, radius free.
    let ctx = Pass1::new(&bg, &surface, st);
    let pool = ScratchPool::default();
    let (walk, ahead_frames_max) = pass1(source, &ctx, &meta, &pool)?;
    let Walk {
        mut frames,
        kept_points,
        mut kept,
        state,
        scratch,
        measured_ahead,
        away_frames,
        searched_ahead,
        unsearched_frames,
        ..
    } = walk;
    frames.flush()?;
    kept.flush()?;
    let history = state.fits;
    if history == 0 {
        return Err(TrackError::NoSphere { frames: n });
    }

    // 3. Calibration (its list of the free fits gone before pass 2, the
    // tracker's peak of memory).
    let cal = calibrate(&frames, w, h, &surface, &bg, st)?;
    // The statistical error of a median misses the method's systematic
    // error, measured on rendered drops at up to 0.0016 px (realistic
    // preset) and 0.0037 px (harsh): a floor of 0.002 px is added in quadrature.
    let radius_err_px = cal.sigma_px.hypot(RADIUS_SYSTEMATIC_PX);
    let (radius_px, m) = (cal.r_px, cal.frames);

    // 4. Pass 2, radius held, on pass 1's points: each frame on its own
    // (on every thread), then the frames whose held circle moved too far
    // from their normals' centre read again, in order, on this thread.
    let LookScratch {
        mut buf, mut es, ..
    } = scratch;
    let (reread, remeasured_frames) = hold_all(
        source,
        &ctx,
        &mut frames,
        &kept,
        &kept_points,
        radius_px,
        &pool,
    )?;
    let kept_points = kept_points.len();
    drop(kept);
    drop(pool);
    // In the frames' order: the first that cannot be read is the error.
    let reread_frames = reread.len();
    let _pass2 = timings::start(Stage::Pass2);
    read_again(
        source,
        &ctx,
        &mut frames,
        reread,
        &mut buf,
        &mut es,
        radius_px,
    )?;
    // 5. The frames in flight far off their neighbours.
    let outlier_frames = flag_outliers(&mut frames, radius_px, &surface, st)?;
    Ok(Track {
        surface,
        surface_from_config,
        radius_px,
        radius_err_px,
        radius_frames: m,
        frames,
        background: bg,
        reread_frames,
        measured_ahead,
        kept_points,
        remeasured_frames,
        ahead_frames_max,
        away_frames,
        searched_ahead,
        unsearched_frames,
        outlier_frames,
    })
}

/// Step 3 of [`track`]: R_px from the pass-1 fits whose whole circle is in
/// view (the only fits the calibration takes), or why there are too few.
fn calibrate(
    frames: &Records<FrameTrack>,
    w: usize,
    h: usize,
    surface: &SurfaceLine,
    bg: &Background,
    st: &TrackSettings,
) -> Result<RadiusCalibration, TrackError> {
    let whole: Vec<CircleFit> = frames
        .iter()
        .filter_map(|f| f.free)
        .filter(|f| full_circle(f, w, h, Some(surface), &st.edge))
        .collect();
    frames.check()?;
    match timings::time(Stage::Pass1, || {
        calibrate_radius(&whole, w, h, Some(surface), &st.edge, 3)
    }) {
        Some(cal) => Ok(cal),
        None => {
            let fits: Vec<CircleFit> = frames.iter().filter_map(|f| f.free).collect();
            frames.check()?;
            Err(TrackError::NoCalibration {
                found: whole.len(),
                upside_down: upside_down_hint(&fits, surface, bg),
            })
        }
    }
}

/// Step 5 of [`track`]: the frames in flight far off their neighbours
/// ([`flight_outliers`]) flagged [`Flag::Outlier`]; how many.
fn flag_outliers(
    frames: &mut Records<FrameTrack>,
    radius_px: f64,
    surface: &SurfaceLine,
    st: &TrackSettings,
) -> Result<usize, TrackError> {
    let outliers = flight_outliers(frames, radius_px, surface, st.edge.surface_margin_px);
    frames.check()?;
    for &i in &outliers {
        let mut ft = frames.get(i)?;
        ft.flags.insert(Flag::Outlier);
        frames.set(i, ft)?;
    }
    Ok(outliers.len())
}

/// Step 5 of [`track`]: the indices of the frames in free flight far off
/// their neighbours ([`outliers`]). A frame is in flight when it has a held
/// fit, its circle stays in the frame (not [`Flag::Partial`]) and its
/// bottom is above the surface line by more than `margin_px`; it is
/// checked on its held centre and, where its free fit has one, its free
/// radius with their reported errors.
pub(super) fn flight_outliers(
    frames: &Records<FrameTrack>,
    radius_px: f64,
    surface: &SurfaceLine,
    margin_px: f64,
) -> Vec<usize> {
    use outliers::{Outliers, Sample, Seen};
    let mut check = Outliers::default();
    // The records' positions (the frames' indices: a record a frame, in order).
    for (k, f) in frames.iter().enumerate() {
        let seen = match f.held {
            None => Seen::Skip,
            Some(_) if f.flags.contains(Flag::Partial) => Seen::Skip,
            Some(h) if h.z_px + radius_px >= surface.row_at(h.x_px) - margin_px => Seen::Break,
            Some(h) => {
                let r = f
                    .free
                    .and_then(|c| c.cov.sigma_r_px().map(|s| (c.r_px, s)))
                    .unwrap_or((f64::NAN, f64::NAN));
                Seen::Flight(Sample {
                    index: k,
                    t_s: f.t_s,
                    values: [
                        (h.x_px, h.cov.sigma_x_px()),
                        (h.z_px, h.cov.sigma_z_px()),
                        r,
                    ],
                })
            }
        };
        check.push(seen);
    }
    check.finish()
}
