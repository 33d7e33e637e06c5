//! Quality flags of a measured drop: the `flags` column of `drops.csv`
//! (space-separated words) and, for each, a sentence in `reason`. Any flag
//! makes the status `warning`: the numbers are there, but something weakens
//! them. The words are stable (scripts may filter on them) and listed in
//! [`FLAGS`] with what each means.

use crate::dataset::{DropRecord, DropStatus};
use crate::measure::events::TrackPoint;

/// Frames missing (not in the file, or not measured) between the last
/// flight frame before contact and the first one after it.
pub const GAP_IN_CONTACT: &str = "gap_in_contact";
/// Frames missing around the maximum penetration (within the peak fit's
/// frames, or next to them): δmax and t_max are interpolated over them.
pub const GAP_AT_PEAK: &str = "gap_at_peak";
/// Fewer than [`MIN_GOOD_FLIGHT_FRAMES`] free-flight frames before or after
/// the contact: the flight parabolas and the contact law rest on few.
pub const SHORT_FLIGHT: &str = "short_flight";
/// The sphere lands again within the recording (only the first contact is measured).
pub const SECOND_CONTACT: &str = "second_contact";
/// The background is clipped at the white level near the sphere's path:
/// the sub-pixel edges there are biased.
pub const SATURATED: &str = "saturated";
/// The scale given (manifest or configuration) and the sphere's radius in
/// pixels disagree by more than 1 %.
pub const SCALE_DISAGREEMENT: &str = "scale_disagreement";
/// Gravity fitted to the free flight is more than 2 % (and 3σ) off g:
/// the frame rate or the scale is wrong.
pub const GRAVITY_OFF: &str = "gravity_off";
/// The manifest's `fps`, `--fps`, or the file's frame times disagree with
/// the file's frame rate.
pub const FPS_MISMATCH: &str = "fps_mismatch";
/// The recording holds no frame rate and none was given for it (manifest
/// `fps`, `--fps`): it was measured at `camera.fps` or at dropscope's
/// default, a guess.
pub const FPS_ASSUMED: &str = "fps_assumed";
/// The file's frame times are off their regular spacing by more than 1 %
/// of a frame interval (used as they are), or the side file's TIMEBLOCK
/// lists no time for some frames (placed on the frame rate's grid).
pub const TIME_IRREGULAR: &str = "time_irregular";
/// The sphere's apparent size per mm of its radius disagrees with its
/// set-up's other runs beyond their errors: a wrong `sphere_radius_mm`, or
/// a run in the wrong set-up ([`crate::calibrate::scale::size_disagreements`]).
pub const RADIUS_DISAGREEMENT: &str = "radius_disagreement";
/// The contact law could not be fitted (or its fit hit its limits).
pub const NO_FORCE_LAW: &str = "no_force_law";
/// The fitted exponent n lies outside [`FORCE_EXPONENT_RANGE`].
pub const FORCE_EXPONENT_IMPLAUSIBLE: &str = "force_exponent_implausible";
/// The fitted damping is negative by more than 3σ: no passive surface does that.
pub const NEGATIVE_DAMPING: &str = "negative_damping";
/// The restitution exceeds 1 by more than 3σ: the sphere cannot gain energy.
pub const RESTITUTION_ABOVE_ONE: &str = "restitution_above_one";
/// The trajectory, fitted with a power-law contact and the surface free,
/// puts the undeformed surface more than 3σ away from the image's line:
/// the line may be off (a reflection or a glossy band top moves it), or the
/// contact is no power law. The image's line is kept.
pub const SURFACE_LAW_DISAGREEMENT: &str = "surface_law_disagreement";

/// Every flag with its meaning, in the order they are checked.
pub const FLAGS: [(&str, &str); 16] = [
    (GAP_IN_CONTACT, "frames missing during the contact"),
    (GAP_AT_PEAK, "frames missing at the maximum penetration"),
    (
        SHORT_FLIGHT,
        "fewer than 8 free-flight frames before or after the contact",
    ),
    (
        SECOND_CONTACT,
        "the sphere lands again; only the first contact is measured",
    ),
    (
        SATURATED,
        "background clipped at the white level near the sphere's path",
    ),
    (
        SCALE_DISAGREEMENT,
        "given scale and sphere radius in pixels disagree by > 1 %",
    ),
    (GRAVITY_OFF, "free-flight gravity > 2 % off g"),
    (
        FPS_MISMATCH,
        "manifest fps, --fps or frame times disagree with the file's frame rate",
    ),
    (
        FPS_ASSUMED,
        "no frame rate in the recording nor given for it: camera.fps or the 10000 default",
    ),
    (
        TIME_IRREGULAR,
        "frame times off their regular spacing by > 1 % of an interval, or missing from the side file for some frames",
    ),
    (
        RADIUS_DISAGREEMENT,
        "apparent size per mm of radius disagrees with the set-up's other runs",
    ),
    (NO_FORCE_LAW, "the contact law could not be fitted"),
    (FORCE_EXPONENT_IMPLAUSIBLE, "force exponent n outside 1–4"),
    (
        NEGATIVE_DAMPING,
        "fitted damping negative by more than 3 sigma",
    ),
    (
        RESTITUTION_ABOVE_ONE,
        "restitution above 1 by more than 3 sigma",
    ),
    (
        SURFACE_LAW_DISAGREEMENT,
        "the contact law's surface is > 3 sigma off the image's line",
    ),
];

/// Free-flight frames on each side of the contact below which a drop is
/// flagged [`SHORT_FLIGHT`] (fewer than 5 is an error). A 3 m/s drop at
/// 10 000 frames/s in a 288-row view has 8.
pub const MIN_GOOD_FLIGHT_FRAMES: usize = 8;

/// Exponents n of F = K·δⁿ that a contact law can have: Hertz gives 1.5,
/// the elastic foundation 2.
pub const FORCE_EXPONENT_RANGE: (f64, f64) = (1.0, 4.0);

/// Share of the background near the sphere's path that may be clipped
/// before the drop is flagged [`SATURATED`].
pub const SATURATED_SHARE: f64 = 0.01;

/// Add a flag and its sentence to a measured record (status `warning`;
/// a `tracked` one keeps its status). A flag already there is not
/// repeated; a failed record takes none.
pub fn flag(record: &mut DropRecord, word: &str, message: impl Into<String>) {
    if record.status == DropStatus::Failed || record.flags.split(' ').any(|w| w == word) {
        return;
    }
    if record.status == DropStatus::Ok {
        record.status = DropStatus::Warning;
    }
    if !record.flags.is_empty() {
        record.flags.push(' ');
    }
    record.flags.push_str(word);
    let message = message.into();
    if !record.reason.is_empty() {
        record.reason.push_str("; ");
    }
    record.reason.push_str(&message);
}

/// Image numbers absent from `track` strictly between frames `lo` and `hi`.
pub fn missing_between(track: &[TrackPoint], lo: i64, hi: i64) -> Vec<i64> {
    let present: std::collections::BTreeSet<i64> = track.iter().map(|p| p.frame).collect();
    (lo.saturating_add(1)..hi)
        .filter(|n| !present.contains(n))
        .collect()
}

/// `[a, b, c, e, f]` as `a–c, e–f`, for messages.
pub fn ranges(numbers: &[i64]) -> String {
    let mut out: Vec<String> = Vec::new();
    let mut i = 0;
    while i < numbers.len() {
        let mut j = i;
        while j + 1 < numbers.len() && numbers[j + 1] == numbers[j] + 1 {
            j += 1;
        }
        out.push(if i == j {
            numbers[i].to_string()
        } else {
            format!("{}–{}", numbers[i], numbers[j])
        });
        i = j + 1;
    }
    out.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_make_a_warning_once_each_and_never_touch_a_failed_row() {
        let mut r = DropRecord::failed("a", 3.0, "why");
        flag(&mut r, SATURATED, "clipped");
        assert_eq!((r.flags.as_str(), r.reason.as_str()), ("", "why"));
        r.status = DropStatus::Ok;
        r.reason.clear();
        flag(&mut r, SATURATED, "clipped");
        flag(&mut r, SHORT_FLIGHT, "few");
        flag(&mut r, SATURATED, "clipped again");
        assert_eq!(r.status, DropStatus::Warning);
        assert_eq!(r.flags, "saturated short_flight");
        assert_eq!(r.reason, "clipped; few");
        let words: Vec<&str> = FLAGS.iter().map(|f| f.0).collect();
        assert!(words
            .iter()
            .all(|w| w.bytes().all(|b| b.is_ascii_lowercase() || b == b'_')));
    }

    #[test]
    fn ranges_are_compact() {
        assert_eq!(ranges(&[3, 4, 5, 9, 11, 12]), "3–5, 9, 11–12");
        assert_eq!(ranges(&[]), "");
    }
}
