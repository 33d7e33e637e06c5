//! Pass 2: each frame held at the calibrated radius, on the points pass 1
//! kept, or measured again as pass 1 looked at it.

use super::band::measure_in_band;
use super::error::TrackError;
use super::frame::{Flag, FrameTrack};
use super::kept::{Kept, KeptRef};
use super::look::{Look, Pass1, ScratchPool};
use super::settings::TrackSettings;
use crate::detect::circle::FitScratch;
use crate::detect::EdgeScratch;
use crate::detect::{fit_circle, Circle, CircleFit, EdgePoint, FitOptions};
use crate::source::Frame;
use crate::source::FrameSource;
use crate::util::records::Records;
use crate::util::timings::{self, Stage};

/// Pass 2's result `h` put into the frame's record (a fit that failed flags
/// it `missing`), or the circle to read the frame again around.
pub(super) fn settle(ft: &mut FrameTrack, h: Held) -> Option<Circle> {
    ft.held = match h {
        Held::NoFit => return None,
        Held::Fit(f) => f,
        Held::Reread(p) => return Some(p),
    };
    if ft.held.is_none() {
        ft.flags.insert(Flag::Missing);
    }
    None
}

/// Pass 2 of the frames `again` (indices into `frames`, with pass 1's look
/// at each) on every thread, each with its own copy of the source: each
/// frame measured again as pass 1 looked at it — the same edge points, a
/// measurement being a pure function of the frame and the look — and held
/// on them. In `again`'s order; the first error in that order.
pub(super) fn remeasure(
    source: &mut dyn FrameSource,
    ctx: &Pass1,
    frames: &[FrameTrack],
    again: &[(usize, Look)],
    radius_px: f64,
    st: &TrackSettings,
    pool: &ScratchPool,
) -> Result<Vec<Held>, TrackError> {
    use rayon::prelude::*;
    let (h, w) = (source.meta().height, source.meta().width);
    let threads = rayon::current_num_threads().min(again.len()).max(1);
    let mut copies: Vec<Box<dyn FrameSource>> =
        (1..threads).map_while(|_| source.try_clone()).collect();
    let mut sources: Vec<&mut dyn FrameSource> = std::iter::once(source)
        .chain(copies.iter_mut().map(|c| c.as_mut()))
        .collect();
    let (n, groups) = (again.len(), sources.len());
    let done: Vec<Result<Vec<Held>, TrackError>> = sources
        .par_iter_mut()
        .enumerate()
        .map(|(g, src)| {
            let _pass2 = timings::start(Stage::Pass2);
            let mut sc = pool.take(h, w);
            let (mut points, mut fs) = (Vec::new(), FitScratch::default());
            let held = again[g * n / groups..(g + 1) * n / groups]
                .iter()
                .map(|&(i, look)| {
                    let ft = &frames[i];
                    let seen = ctx.look_at(&mut **src, ft.index, look, &mut sc)?;
                    let k = seen.points.as_ref().map(|(c, sigma, pts)| KeptRef {
                        points: pts,
                        centre: *c,
                        radial_sigma_px: *sigma,
                    });
                    Ok(hold(ft, k, radius_px, st, &mut points, &mut fs))
                })
                .collect();
            pool.give(sc);
            held
        })
        .collect();
    let mut out = Vec::with_capacity(n);
    for d in done {
        out.extend(d?);
    }
    Ok(out)
}

/// Pass 2's result in one frame.
pub(super) enum Held {
    /// No free fit in pass 1: nothing to hold.
    NoFit,
    /// The held fit on pass 1's points (`None`: it failed).
    Fit(Option<CircleFit>),
    /// The held circle lies too far from the normals' centre: the frame is
    /// read again and measured around this circle.
    Reread(Circle),
}

/// Pass 2 of one frame on the points pass 1 kept (see [`track`], step 4).
pub(super) fn hold(
    ft: &FrameTrack,
    k: Option<KeptRef>,
    radius_px: f64,
    st: &TrackSettings,
    points: &mut Vec<EdgePoint>,
    fs: &mut FitScratch,
) -> Held {
    let (Some(f1), Some(k)) = (ft.free, k) else {
        return Held::NoFit;
    };
    let p = Circle {
        r_px: radius_px,
        ..f1.circle()
    };
    let c = k.centre;
    points.clear();
    points.extend(k.points.iter().map(|q| EdgePoint {
        x_px: c.x_px + q[0] as f64,
        z_px: c.z_px + q[1] as f64,
        weight: 1.0,
    }));
    // Tukey's weights from the first iteration, at the free fit's
    // residual scale: the start is the free fit on the same points,
    // whose Huber iterations already brought it from the prediction,
    // and holding the radius moves it by hundredths of a pixel.
    let opts = FitOptions {
        hold_radius: Some(radius_px),
        radial_sigma_px: k.radial_sigma_px,
        huber_iterations: 0,
        scale_px: Some(f1.scale_px),
        ..FitOptions::default()
    };
    let held = fit_circle(points, Some(p), &opts, fs).ok();
    let near = held.is_some_and(|f| {
        (f.x_px - c.x_px)
            .abs()
            .max((f.z_px - c.z_px).abs())
            .max((radius_px - c.r_px).abs())
            <= st.edge.recentre_px
    });
    if near {
        Held::Fit(held)
    } else {
        Held::Reread(p)
    }
}

/// Step 4 of [`super::track`], on pass 1's points: each frame held on its
/// own (on every thread), the frames past the points' budget measured again
/// as pass 1 did and held like the others. Each frame's held fit goes
/// straight into its record (a `Held` a frame held until all were done was
/// 144 bytes a frame at the tracker's peak), a block of records at a time
/// (all of them when in memory); only the frames to read again are listed,
/// in order, with the circle to read them around. Also how many frames were
/// measured again.
pub(super) fn hold_all(
    source: &mut dyn FrameSource,
    ctx: &Pass1,
    frames: &mut Records<FrameTrack>,
    kept: &Records<Option<Kept>>,
    kept_points: &[[f32; 2]],
    radius_px: f64,
    pool: &ScratchPool,
) -> Result<(Vec<(usize, Circle)>, usize), TrackError> {
    let st = ctx.st;
    let mut reread: Vec<(usize, Circle)> = Vec::new();
    let mut remeasured_frames = 0;
    frames.update(|lo, block| -> Result<(), TrackError> {
        use rayon::prelude::*;
        let hi = lo + block.len();
        kept.with_block(lo, hi, |kept| -> Result<(), TrackError> {
            reread.par_extend(
                block
                    .par_iter_mut()
                    .zip(kept)
                    .enumerate()
                    .with_min_len(64)
                    .map_init(
                        || (Vec::new(), FitScratch::default()),
                        |(points, fs), (i, (ft, k))| {
                            let h = timings::time(Stage::Pass2, || match k {
                                Some(Kept::Points {
                                    start,
                                    len,
                                    centre,
                                    radial_sigma_px,
                                }) => {
                                    let k = KeptRef {
                                        points: &kept_points[*start..start + len],
                                        centre: *centre,
                                        radial_sigma_px: *radial_sigma_px,
                                    };
                                    hold(ft, Some(k), radius_px, st, points, fs)
                                }
                                // Below, with a source.
                                Some(Kept::Again(_)) => Held::NoFit,
                                None => hold(ft, None, radius_px, st, points, fs),
                            });
                            settle(ft, h).map(|p| (lo + i, p))
                        },
                    )
                    .flatten(),
            );
            let again: Vec<(usize, Look)> = kept
                .iter()
                .enumerate()
                .filter_map(|(i, k)| match k {
                    Some(Kept::Again(look)) => Some((i, *look)),
                    _ => None,
                })
                .collect();
            remeasured_frames += again.len();
            if !again.is_empty() {
                let redone = timings::time(Stage::Pass2, || {
                    remeasure(source, ctx, block, &again, radius_px, st, pool)
                })?;
                for ((i, _), h) in again.iter().zip(redone) {
                    reread.extend(settle(&mut block[*i], h).map(|p| (lo + *i, p)));
                }
            }
            Ok(())
        })?
    })?;
    reread.sort_by_key(|r| r.0);
    Ok((reread, remeasured_frames))
}

/// The frames `reread` of [`hold_all`] read again, in the frames' order (the
/// first that cannot be read is the error), and measured around their held
/// circle; a frame without a fit there is flagged `missing`.
pub(super) fn read_again(
    source: &mut dyn FrameSource,
    ctx: &Pass1,
    frames: &mut Records<FrameTrack>,
    reread: Vec<(usize, Circle)>,
    buf: &mut Frame,
    es: &mut EdgeScratch,
    radius_px: f64,
) -> Result<(), TrackError> {
    for (i, p) in reread {
        let mut ft = frames.get(i)?;
        ft.held = measure_in_band(
            source,
            ft.index,
            buf,
            ctx.bg,
            &p,
            ctx.surface,
            Some(radius_px),
            ctx.st,
            es,
        )?;
        if ft.held.is_none() {
            ft.flags.insert(Flag::Missing);
        }
        frames.set(i, ft)?;
    }
    Ok(())
}
