//! A track's held fits as the event stage's points, the excluded frames left
//! out.

use crate::calibrate::lens::Lens;
use crate::measure::events::TrackPoint;
use crate::track::{FrameTrack, Track};

/// Mark the frames a person excluded (`review.csv`) in `tr`: their fits
/// stay in the track (and its CSV, flagged `excluded`) but no fit uses
/// them ([`points_of`] leaves them out).
pub(super) fn exclude_frames(
    tr: &mut Track,
    review: &crate::dataset::decisions::RunReview,
) -> std::io::Result<()> {
    if review.excluded.is_empty() {
        return Ok(());
    }
    tr.frames.update(|_, block: &mut [FrameTrack]| {
        for f in block.iter_mut().filter(|f| review.excludes(f.frame)) {
            f.flags.insert(crate::track::Flag::Excluded);
        }
        Ok::<(), std::io::Error>(())
    })
}

/// The held-radius fits as event-stage points, with the contact
/// half-width that `half_width` gives from the free-radius fit, made as
/// they are walked: none held.
pub(super) fn held_points<'a>(
    tr: &'a Track,
    half_width: impl Fn(&crate::detect::CircleFit) -> (Option<f64>, Option<f64>) + 'a,
) -> impl Iterator<Item = TrackPoint> + 'a {
    points_of(
        tr.frames.iter().filter_map(|f| f.held.map(|h| (f, h))),
        half_width,
    )
}

/// The held fits through `lens` ([`crate::calibrate::lens::undistort_held`]) as points
/// without half-widths, as they are walked.
pub(super) fn bounded_points<'a>(
    tr: &'a Track,
    lens: &'a Lens,
    r_px: f64,
) -> impl Iterator<Item = TrackPoint> + 'a {
    points_of(
        crate::calibrate::lens::undistort_held(tr, lens, r_px),
        |_| (None, None),
    )
}

/// [`held_points`] of frames given with their held fits (the track's, or
/// moved by a lens: [`crate::calibrate::lens::undistort_held`]); a circle leaving the
/// frame is no point, nor a frame the tracker found off its neighbours'
/// flight ([`crate::track::Flag::Outlier`]), nor one a person excluded
/// ([`crate::track::Flag::Excluded`]).
pub(super) fn points_of(
    held: impl Iterator<Item = (FrameTrack, crate::detect::CircleFit)>,
    half_width: impl Fn(&crate::detect::CircleFit) -> (Option<f64>, Option<f64>),
) -> impl Iterator<Item = TrackPoint> {
    use crate::track::Flag;
    held.filter(|(f, _)| {
        ![Flag::Partial, Flag::Outlier, Flag::Excluded]
            .into_iter()
            .any(|flag| f.flags.contains(flag))
    })
    .map(move |(f, h)| {
        let (hw, hw_err) = f.free.as_ref().map_or((None, None), &half_width);
        TrackPoint {
            frame: f.frame,
            t_s: f.t_s,
            x_px: h.x_px,
            z_px: h.z_px,
            sigma_z_px: h.cov.sigma_z_px().max(1e-4),
            half_width_px: hw,
            sigma_half_width_px: hw_err,
        }
    })
}
