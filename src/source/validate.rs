//! What a file says about its frames, checked before anything uses it:
//! a frame rate that a camera can have, an exposure that fits
//! in a frame interval, and frame times that are finite, strictly
//! increasing and on the frame rate's grid. A file that breaks one of these
//! is an error naming it (and the frame); a small disagreement is a warning
//! in [`SourceDetails::warnings`](super::SourceDetails::warnings).

use super::{FrameValues, SourceError, SourceMeta};

/// Frame rates outside this range (frames/s) are no camera's: the slowest
/// sample here records at 24, the fastest Phantoms at under 2 000 000.
pub const FPS_RANGE: (f64, f64) = (0.1, 1e7);

/// Save decimation (cine `fDecimation`) outside this range is corrupt: one
/// frame saved of every 1 to 1 000 000.
pub const DECIMATION_RANGE: (f64, f64) = (1.0, 1e6);

/// An exposure may exceed the frame interval by this fraction (the two are
/// stored rounded, in ns or µs and in frames/s).
const EXPOSURE_SLACK: f64 = 1e-3;

/// A frame time off the regular grid by more than this share of a frame
/// interval is a corrupt time block (an error).
pub const TIME_ERROR_INTERVALS: f64 = 0.25;

/// A frame time off the grid by more than this share of an interval (and
/// more than the PCC XML's 10 ns resolution) gives a warning.
pub const TIME_WARNING_INTERVALS: f64 = 0.01;

/// The frame interval the time stamps show may differ from 1/fps by this
/// fraction before a warning.
pub const FPS_AGREEMENT: f64 = 1e-3;

/// How the warning about frame times a little off their grid starts.
pub const IRREGULAR_TIMES: &str = "frame times are not evenly spaced";

/// How the warning about a time block that lists no time for some frames starts.
pub const TIMES_INCOMPLETE: &str = "frame times incomplete";

/// How the warning about frame times spaced otherwise than the frame rate says starts.
pub const TIMES_AND_RATE_DISAGREE: &str = "the frame times are";

/// Largest frame any reader accepts, in pixels, checked from its header
/// before anything is allocated: 8192 × 4096, over three times the largest
/// Phantom sensor (4096 × 2304). A 16-bit frame of this size is 64 MB; a
/// worker holds a few.
pub const MAX_FRAME_PIXELS: u64 = 1 << 25;

/// Most bytes a general-purpose decoder (the `image` crate: colour PNG,
/// JPEG, compressed TIFF) may allocate for one frame: its largest frame as
/// 16-bit RGBA is 256 MB.
pub const MAX_DECODE_BYTES: u64 = 256 << 20;

/// The limits every `image` decoder runs under ([`MAX_FRAME_PIXELS`],
/// [`MAX_DECODE_BYTES`]): a frame beyond them is an error, not an
/// allocation that aborts the job.
pub fn decode_limits() -> image::Limits {
    let mut l = image::Limits::default();
    l.max_image_width = Some(MAX_FRAME_PIXELS as u32);
    l.max_image_height = Some(MAX_FRAME_PIXELS as u32);
    l.max_alloc = Some(MAX_DECODE_BYTES);
    l
}

/// Why a frame of `width` × `height` is refused before it is decoded, or
/// `None` when it is within [`MAX_FRAME_PIXELS`].
pub fn frame_too_large(width: u64, height: u64) -> Option<String> {
    let pixels = width.saturating_mul(height);
    (width == 0 || height == 0 || pixels > MAX_FRAME_PIXELS).then(|| {
        format!(
            "implausible frame size {width}×{height} ({pixels} pixels; a frame may hold 1 to \
             {MAX_FRAME_PIXELS}, 8192 × 4096): corrupt or forged header"
        )
    })
}

/// A number as a person reads it: plain when moderate, else in e-notation
/// (Rust prints 1e300 with all its 301 digits).
fn show(v: f64) -> String {
    if v == 0.0 || !v.is_finite() || (1e-4..1e8).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

fn bad(meta: &SourceMeta, reason: String) -> SourceError {
    SourceError::Format {
        path: meta.path.clone(),
        reason,
    }
}

/// Check `meta` (see the module doc); warnings are added to its details.
pub fn check_meta(meta: &mut SourceMeta) -> Result<(), SourceError> {
    let fps = meta.fps;
    if fps.is_nan() {
        return Err(SourceError::NoFrameRate {
            path: meta.path.clone(),
        });
    }
    let in_range = |v: f64, (lo, hi): (f64, f64)| v.is_finite() && v >= lo && v <= hi;
    let d = &meta.details;
    if let Some(acq) = d.acquisition_fps {
        if !in_range(acq, FPS_RANGE) {
            return Err(bad(
                meta,
                format!(
                    "acquisition frame rate {} frames/s is outside {}–{} frames/s: corrupt header",
                    show(acq),
                    FPS_RANGE.0,
                    show(FPS_RANGE.1)
                ),
            ));
        }
    }
    if !in_range(d.decimation, DECIMATION_RANGE) {
        return Err(bad(
            meta,
            format!(
                "save decimation {} is outside {}–{}: corrupt header",
                show(d.decimation),
                DECIMATION_RANGE.0,
                DECIMATION_RANGE.1
            ),
        ));
    }
    if !in_range(fps, FPS_RANGE) {
        return Err(bad(
            meta,
            format!(
                "frame rate {} frames/s is outside {}–{} frames/s: corrupt header",
                show(fps),
                FPS_RANGE.0,
                show(FPS_RANGE.1)
            ),
        ));
    }
    // The exposure fits in the camera's frame interval (before decimation).
    let interval_s = 1.0 / d.acquisition_fps.unwrap_or(fps);
    if let Some(e) = meta.exposure_s {
        if !(e.is_finite() && e > 0.0 && e <= interval_s * (1.0 + EXPOSURE_SLACK)) {
            return Err(bad(
                meta,
                format!(
                    "exposure {} s is not within 0 and the frame interval {} s \
                     (1/{} frames/s): corrupt header",
                    show(e),
                    show(interval_s),
                    show(1.0 / interval_s)
                ),
            ));
        }
    }
    if let Some(ts) = meta.timestamps_s.clone() {
        check_times(meta, &ts)?;
    }
    Ok(())
}

/// Frame times: finite, strictly increasing, on a regular grid of the
/// frame numbers, and spaced as the frame rate says. The times are walked,
/// not copied: a long `.cine`'s stay in the file.
fn check_times(meta: &mut SourceMeta, ts: &FrameValues) -> Result<(), SourceError> {
    let numbers = meta.frame_numbers.clone();
    let number = |i: usize| numbers.get(i).unwrap_or(i as i64);
    let n = ts.len();
    let t = |i: usize| Ok(ts.get(i)?.unwrap_or(f64::NAN));
    // The first time that is not a number, and the first not after the one
    // before it.
    let (mut not_finite, mut not_after) = (None, None);
    let mut prev = f64::NAN;
    ts.try_for_each(|i, x| {
        if not_finite.is_none() && !x.is_finite() {
            not_finite = Some((i, x));
        }
        if not_after.is_none() && i > 0 && x <= prev {
            not_after = Some((i, x, prev));
        }
        prev = x;
    })?;
    if let Some((i, x)) = not_finite {
        return Err(bad(
            meta,
            format!(
                "frame {}: time stamp {x} is not a number: corrupt time block",
                number(i),
            ),
        ));
    }
    if let Some((i, x, before)) = not_after {
        return Err(bad(
            meta,
            format!(
                "frame {}: time stamp {} s is not after frame {}'s {} s: \
                 the frame times must increase (corrupt time block)",
                number(i),
                show(x),
                number(i - 1),
                show(before)
            ),
        ));
    }
    if n < 3 {
        return Ok(());
    }
    // The grid: the median interval per frame number over pairs of frames
    // half the movie apart (stamps rounded to the XML's 10 ns are then
    // exact to 10 ns over thousands of intervals; neighbours' differences
    // would carry that rounding into every interval, 0.6 intervals over
    // 3 000 frames at 60 000 frames/s), through the median offset.
    let lag = n / 2;
    let step = median_of(n - lag, |k| {
        let i = lag + k;
        Ok((t(i)? - t(i - lag)?) / (number(i) - number(i - lag)) as f64)
    })?;
    let t0 = median_of(n, |i| Ok(t(i)? - (number(i) - number(0)) as f64 * step))?;
    let (mut worst, mut off) = (0, 0.0f64);
    ts.try_for_each(|i, x| {
        let o = x - t0 - (number(i) - number(0)) as f64 * step;
        // The last of equal largest, as `Iterator::max_by`.
        if off.abs().total_cmp(&o.abs()) != std::cmp::Ordering::Greater {
            (worst, off) = (i, o);
        }
    })?;
    let intervals = off.abs() / step;
    if intervals > TIME_ERROR_INTERVALS {
        return Err(bad(
            meta,
            format!(
                "frame {}: time stamp {} s is {intervals:.2} frame intervals off the other \
                 frames' regular spacing of {step} s: corrupt time block",
                number(worst),
                show(t(worst)?)
            ),
        ));
    }
    if intervals > TIME_WARNING_INTERVALS && off.abs() > 1e-8 {
        meta.details.warnings.push(format!(
            "{IRREGULAR_TIMES}: frame {} is {intervals:.3} frame intervals off the regular \
             spacing of {step} s; the times are used as they are",
            number(worst)
        ));
    }
    let fps_times = 1.0 / step;
    if (fps_times / meta.fps - 1.0).abs() > FPS_AGREEMENT {
        meta.details.warnings.push(format!(
            "{TIMES_AND_RATE_DISAGREE} {step} s apart ({fps_times:.6} frames/s) but the frame rate \
             is {} frames/s; the times are used",
            meta.fps
        ));
    }
    Ok(())
}

/// Values a median is taken of in memory (2 MB); more are walked.
const MEDIAN_IN_MEMORY_MAX: usize = 1 << 18;

/// The median of `value(0..n)` (`n` ≥ 1): sorted in memory when there are
/// at most [`MEDIAN_IN_MEMORY_MAX`], else found by walking them (four
/// walks for the middle value, 16 bits of its order at a time, and one
/// for its neighbour) — the same value either way.
fn median_of(
    n: usize,
    mut value: impl FnMut(usize) -> Result<f64, SourceError>,
) -> Result<f64, SourceError> {
    if n <= MEDIAN_IN_MEMORY_MAX {
        let mut v = (0..n).map(&mut value).collect::<Result<Vec<f64>, _>>()?;
        return Ok(median(&mut v));
    }
    let k = n / 2;
    let upper = nth_smallest(n, k, &mut value)?;
    if n % 2 == 1 {
        return Ok(upper);
    }
    // The (k − 1)-th: the largest of those below the k-th when there are k
    // of them, else equal to it.
    let (mut below, mut largest_below) = (0, None::<u64>);
    for i in 0..n {
        let key = order_key(value(i)?);
        if key < order_key(upper) {
            below += 1;
            largest_below = largest_below.max(Some(key));
        }
    }
    let lower = match largest_below {
        Some(key) if below >= k => from_order_key(key),
        _ => upper,
    };
    Ok(0.5 * (lower + upper))
}

/// A key whose unsigned order is [`f64::total_cmp`]'s order of the values.
fn order_key(x: f64) -> u64 {
    let b = x.to_bits();
    if b >> 63 == 1 {
        !b
    } else {
        b | 1 << 63
    }
}

fn from_order_key(key: u64) -> f64 {
    if key >> 63 == 1 {
        f64::from_bits(key & !(1 << 63))
    } else {
        f64::from_bits(!key)
    }
}

/// The `k`-th smallest (from 0) of `value(0..n)` in [`f64::total_cmp`]'s
/// order, by a radix selection on the value's order key, 16 bits a walk.
fn nth_smallest(
    n: usize,
    mut k: usize,
    value: &mut impl FnMut(usize) -> Result<f64, SourceError>,
) -> Result<f64, SourceError> {
    let mut prefix = 0u64;
    let mut counts = vec![0usize; 1 << 16];
    for digit in (0..4).rev() {
        let shift = 16 * digit;
        let high = if digit == 3 { 0 } else { !0u64 << (shift + 16) };
        counts.iter_mut().for_each(|c| *c = 0);
        for i in 0..n {
            let key = order_key(value(i)?);
            if key & high == prefix {
                counts[((key >> shift) & 0xFFFF) as usize] += 1;
            }
        }
        let mut d = 0;
        while d < 0xFFFF && k >= counts[d] {
            k -= counts[d];
            d += 1;
        }
        prefix |= (d as u64) << shift;
    }
    Ok(from_order_key(prefix))
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::SourceDetails;

    fn meta(fps: f64, exposure_s: Option<f64>, ts: Option<Vec<f64>>) -> SourceMeta {
        let n = ts.as_ref().map_or(10, Vec::len);
        SourceMeta {
            path: "run.cine".into(),
            fps,
            exposure_s,
            frame_numbers: (0..n as i64).collect(),
            frame_count: n,
            timestamps_s: ts.map(Into::into),
            details: SourceDetails {
                decimation: 1.0,
                ..SourceDetails::default()
            },
            ..SourceMeta::default()
        }
    }

    fn grid(n: usize, fps: f64) -> Vec<f64> {
        (0..n).map(|i| i as f64 / fps).collect()
    }

    fn err(m: &mut SourceMeta) -> String {
        check_meta(m).unwrap_err().to_string()
    }

    #[test]
    fn a_regular_recording_passes_without_warning() {
        let mut m = meta(10_000.0, Some(50e-6), Some(grid(50, 10_000.0)));
        check_meta(&mut m).unwrap();
        assert!(m.details.warnings.is_empty(), "{:?}", m.details.warnings);
        // The exposure may fill the whole frame interval.
        check_meta(&mut meta(10_000.0, Some(100e-6), None)).unwrap();
    }

    #[test]
    fn impossible_rates_and_exposures_are_errors_naming_the_file() {
        for (m, expect) in [
            (meta(1e300, None, None), "frame rate 1e300"),
            (meta(-5.0, None, None), "frame rate -5"),
            (meta(f64::INFINITY, None, None), "frame rate inf"),
            (meta(10_000.0, Some(4.0), None), "exposure 4 s"),
            (meta(10_000.0, Some(0.0), None), "exposure 0 s"),
            (meta(10_000.0, Some(f64::NAN), None), "exposure NaN s"),
        ] {
            let mut m = m;
            let e = err(&mut m);
            assert!(e.starts_with("run.cine: ") && e.contains(expect), "{e}");
        }
        let mut m = meta(10_000.0, None, None);
        m.details.decimation = 1e-30;
        assert!(err(&mut m).contains("save decimation 1e-30"));
        let mut m = meta(10_000.0, None, None);
        m.details.acquisition_fps = Some(1e300);
        assert!(err(&mut m).contains("acquisition frame rate 1e300"));
        assert!(matches!(
            check_meta(&mut meta(f64::NAN, None, None)),
            Err(SourceError::NoFrameRate { .. })
        ));
    }

    #[test]
    fn reversed_garbled_or_jittered_times_are_errors_naming_the_frame() {
        let mut rev = grid(30, 10_000.0);
        rev.reverse();
        let e = err(&mut meta(10_000.0, None, Some(rev)));
        assert!(
            e.contains("frame 1: time stamp") && e.contains("must increase"),
            "{e}"
        );
        let mut nan = grid(30, 10_000.0);
        nan[7] = f64::NAN;
        assert!(err(&mut meta(10_000.0, None, Some(nan))).contains("frame 7: time stamp NaN"));
        // Three frames jittered by 0.1–1 ms at 10 000 frames/s.
        for (k, jitter) in [(5, 0.1e-3), (12, -0.4e-3), (20, 1e-3)] {
            let mut t = grid(40, 10_000.0);
            t[k] += jitter;
            let e = err(&mut meta(10_000.0, None, Some(t)));
            assert!(e.contains("corrupt time block"), "{e}");
        }
        // Still increasing but half an interval off: an error naming it.
        let mut t = grid(40, 10_000.0);
        t[12] += 0.45e-4;
        let e = err(&mut meta(10_000.0, None, Some(t)));
        assert!(
            e.contains("frame 12: time stamp") && e.contains("0.45 frame intervals"),
            "{e}"
        );
    }

    #[test]
    fn stamps_rounded_to_10_ns_pass_at_any_length() {
        // PCC's XML gives times to 10 ns: at 60 000 frames/s the interval
        // 16.666… µs is stored as 16.67 or 16.66 µs apart. 6 000 frames
        // (3 000 on each side of the trigger, as a long render has) pass
        // without an error or a warning.
        let t: Vec<f64> = (0..6000)
            .map(|i| ((i as f64 - 3000.0) / 60_000.0 * 1e8).round() / 1e8)
            .collect();
        let mut m = meta(60_000.0, None, Some(t));
        check_meta(&mut m).unwrap();
        assert!(m.details.warnings.is_empty(), "{:?}", m.details.warnings);
    }

    #[test]
    fn a_median_walked_is_the_median_sorted() {
        // Values with ties, both signs and ±0, above the in-memory budget.
        let n = MEDIAN_IN_MEMORY_MAX + 7;
        let mut x = 12345u64;
        let values: Vec<f64> = (0..n)
            .map(|i| {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                match i % 5 {
                    0 => 0.0,
                    1 => -0.0,
                    _ => ((x >> 40) as f64 - 8e6) * 1e-9,
                }
            })
            .collect();
        for len in [n, n - 1] {
            let v = &values[..len];
            let walked = median_of(len, |i| Ok(v[i])).unwrap();
            let sorted = median(&mut v.to_vec());
            assert_eq!(walked.to_bits(), sorted.to_bits(), "{len} values");
        }
    }

    #[test]
    fn small_irregularities_and_a_disagreeing_rate_are_warnings() {
        let mut t = grid(40, 10_000.0);
        t[12] += 0.05e-4;
        let mut m = meta(10_000.0, None, Some(t));
        check_meta(&mut m).unwrap();
        assert!(m.details.warnings[0].contains("frame 12 is 0.050 frame intervals off"));
        let mut m = meta(9_000.0, None, Some(grid(40, 10_000.0)));
        check_meta(&mut m).unwrap();
        assert!(
            m.details.warnings[0].contains("10000.000000 frames/s")
                && m.details.warnings[0].contains("frame rate is 9000"),
            "{:?}",
            m.details.warnings
        );
    }
}
