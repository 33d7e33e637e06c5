//! The frame rate's and the background's checks of a run's row.

use crate::config::PipelineConfig;
use crate::dataset::manifest::RunSpec;
use crate::dataset::DropRecord;
use crate::measure::quality;
use crate::track::Track;

/// Fill the row's `fps` and `fps_source` and flag what is doubtful about
/// them: a frame rate assumed (`camera.fps` or [`crate::config::DEFAULT_FPS`]:
/// [`quality::FPS_ASSUMED`]), or one given (manifest, `--fps`) that
/// disagrees with the recording's own, which is used
/// ([`quality::FPS_MISMATCH`]).
pub(super) fn frame_rate_checks(
    record: &mut DropRecord,
    run: &RunSpec,
    cfg: &PipelineConfig,
    fps: f64,
    fps_source: &str,
) {
    record.fps = Some(fps);
    record.fps_source = fps_source.to_string();
    match fps_source {
        "config" => quality::flag(
            record,
            quality::FPS_ASSUMED,
            format!(
                "the recording holds no frame rate: measured at {fps} frames/s, camera.fps of \
                 the configuration; if that is not this recording's, pass --fps (or the \
                 manifest's fps column)"
            ),
        ),
        "default" => quality::flag(
            record,
            quality::FPS_ASSUMED,
            format!(
                "the recording holds no frame rate and none was given: measured at {fps} \
                 frames/s, dropscope's default, a guess; times and speeds scale with it: pass \
                 --fps (or the manifest's fps column, or camera.fps)"
            ),
        ),
        "manifest" | "flag" => {}
        _ => {
            let given = [
                (run.fps, "the manifest's fps"),
                (cfg.command_line.fps, "--fps"),
            ];
            if let Some((f, by)) = given.iter().find_map(|(f, by)| Some((f.as_ref()?, by))) {
                if (f / fps - 1.0).abs() > crate::source::validate::FPS_AGREEMENT {
                    quality::flag(
                        record,
                        quality::FPS_MISMATCH,
                        format!(
                            "{by} {f} disagrees with the recording's own frame rate {fps} \
                             frames/s ({fps_source}); the recording's is used"
                        ),
                    );
                }
            }
        }
    }
}

/// The share of the background at the white level (within 1 % of
/// 2^bits − 1: the background is a median divided by the frames' flicker
/// gains) in the box the sphere swept above the surface line, when above
/// [`quality::SATURATED_SHARE`].
pub(super) fn saturated_share(tr: &Track, bit_depth: u8) -> Option<f64> {
    let white = 0.99 * ((1u32 << bit_depth.min(16)) - 1) as f32;
    // The box of the held centres, walked once (none held).
    let (mut any, mut x_lo, mut x_hi, mut z_lo) =
        (false, f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY);
    for c in tr.frames.iter().filter_map(|f| f.held) {
        any = true;
        (x_lo, x_hi, z_lo) = (x_lo.min(c.x_px), x_hi.max(c.x_px), z_lo.min(c.z_px));
    }
    let bg = &tr.background;
    let (w, h) = (bg.width as f64, bg.height as f64);
    let r = tr.radius_px;
    let clampf = |v: f64, hi: f64| v.clamp(0.0, (hi - 1.0).max(0.0)) as usize;
    let x0 = clampf(x_lo - 1.2 * r, w);
    let x1 = clampf(x_hi + 1.2 * r, w);
    let z0 = clampf(z_lo - 1.2 * r, h);
    let (mut clipped, mut total) = (0usize, 0usize);
    for col in x0..=x1 {
        let z1 = clampf(tr.surface.row_at(col as f64) - 2.0, h);
        for row in z0..=z1.max(z0) {
            total += 1;
            clipped += usize::from(bg.at(row, col) >= white);
        }
    }
    let share = clipped as f64 / total.max(1) as f64;
    (any && share > quality::SATURATED_SHARE).then_some(share)
}
