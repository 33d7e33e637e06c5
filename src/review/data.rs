//! What the review page shows of an output folder, as JSON: the drop list
//! (drops.csv with each run's decisions) and one run (its record, its track
//! CSV a column at a time, the frames of its events). Pure: records and
//! rows in, JSON out.

use serde_json::{json, Value};

use crate::dataset::decisions::{Decisions, Frames};
use crate::dataset::{DropRecord, TrackRow};

/// The drop list: every record of drops.csv in order, with what the page
/// lists, sorts and filters by, and the decisions about it.
pub fn drops_json(records: &[DropRecord], decisions: &Decisions) -> Value {
    let drops: Vec<Value> = records
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let kinds: Vec<&str> = decisions
                .rows
                .iter()
                .filter(|d| d.run == r.run)
                .map(|d| d.decision.word())
                .collect();
            json!({
                "n": i + 1,
                "run": r.run,
                "status": r.status.word(),
                "flags": r.flags,
                "reason": r.reason,
                "review": r.review,
                "radius_mm": r.sphere_radius_mm,
                "v": [r.v_impact_m_s, r.v_impact_m_s_err],
                "delta": [r.delta_max_mm, r.delta_max_mm_err],
                "a": [r.a_max_mm, r.a_max_mm_err],
                "tau": [r.tau_c_ms, r.tau_c_ms_err],
                "e": [r.restitution, r.restitution_err],
                "surface_source": r.surface_source,
                "decided": kinds,
            })
        })
        .collect();
    json!({ "drops": drops })
}

/// The camera image number of the row nearest time `t_s`, if any row.
pub fn frame_at(rows: &[TrackRow], t_s: Option<f64>) -> Option<i64> {
    let t = t_s.filter(|t| t.is_finite())?;
    rows.iter()
        .min_by(|a, b| (a.t_s - t).abs().total_cmp(&(b.t_s - t).abs()))
        .map(|r| r.frame)
}

/// The column of the sphere's centre at the impact: that of the fitted
/// row nearest the contact onset (else nearest the peak).
pub fn impact_column(rows: &[TrackRow], record: &DropRecord) -> Option<f64> {
    let t = record.t_contact_s.or(record.t_max_s)?;
    rows.iter()
        .filter(|r| r.x_px.is_some())
        .min_by(|a, b| (a.t_s - t).abs().total_cmp(&(b.t_s - t).abs()))
        .and_then(|r| r.x_px)
}

/// What the page needs of one run: its record, its decisions, its frames
/// (the track CSV a column at a time, or only the numbers when it has no
/// track), the frames of its events and its surface line.
pub struct RunData<'a> {
    /// The run's row of drops.csv.
    pub record: &'a DropRecord,
    /// The run's track, one row per frame (empty when it has none).
    pub rows: &'a [TrackRow],
    /// Every camera image number of the run, in order (the source's).
    pub frames: &'a [i64],
    /// Every decision of the review file (the run's are picked out).
    pub decisions: &'a Decisions,
    /// The image's surface line (row at column 0, tilt), when found.
    pub image_surface: Option<(f64, f64)>,
    /// Frame width, px.
    pub width_px: usize,
    /// Frame height, px.
    pub height_px: usize,
    /// Frame rate, frames/s.
    pub fps: f64,
    /// Why frames show no overlay, when they do not.
    pub problem: Option<String>,
}

impl RunData<'_> {
    /// The run as the review page's JSON.
    pub fn to_json(&self) -> Value {
        let r = self.rows;
        let col = |f: &dyn Fn(&TrackRow) -> Value| Value::Array(r.iter().map(f).collect());
        let decisions: Vec<&crate::dataset::decisions::Decision> = self
            .decisions
            .rows
            .iter()
            .filter(|d| d.run == self.record.run)
            .collect();
        let x_impact = impact_column(r, self.record);
        let slope = self.image_surface.map(|(_, s)| s);
        json!({
            "record": self.record,
            "frames": self.frames,
            "track": {
                "frame": col(&|t| json!(t.frame)),
                "t_s": col(&|t| json!(t.t_s)),
                "x_px": col(&|t| json!(t.x_px)),
                "z_px": col(&|t| json!(t.z_px)),
                "r_px": col(&|t| json!(t.r_px)),
                "residual_px": col(&|t| json!(t.residual_px)),
                "edge_points": col(&|t| json!(t.edge_points)),
                "in_contact": col(&|t| json!(t.in_contact)),
                "delta_mm": col(&|t| json!(t.delta_mm)),
                "flags": col(&|t| json!(t.flags)),
            },
            "events": {
                "onset": frame_at(r, self.record.t_contact_s),
                "max": frame_at(r, self.record.t_max_s),
                "rebound": frame_at(r, self.record.t_rebound_s),
            },
            "surface": {
                "row_at_impact_px": self.record.surface_row_px,
                "source": self.record.surface_source,
                "image_row_at_impact_px": self.image_surface.zip(x_impact).map(|((r0, s), x)| r0 + s * x),
                "slope": slope,
                "impact_column_px": x_impact,
            },
            "decisions": decisions,
            "width_px": self.width_px,
            "height_px": self.height_px,
            "fps": self.fps,
            "problem": self.problem,
        })
    }
}

/// Whether every frame of `f` is a frame of the run (`frames` ascending).
pub fn frames_in(frames: &[i64], f: Frames) -> bool {
    frames.binary_search(&f.first).is_ok() && frames.binary_search(&f.last).is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::DropStatus;

    fn row(frame: i64, x: Option<f64>) -> TrackRow {
        TrackRow {
            frame,
            t_s: frame as f64 * 1e-4,
            x_px: x,
            z_px: x.map(|_| 100.0 + frame as f64),
            r_px: x.map(|_| 40.0),
            residual_px: x.map(|_| 0.05),
            edge_points: 30,
            in_contact: frame >= 3,
            delta_mm: x.map(|_| 0.01 * frame as f64),
            sigma_z_px: None,
            sigma_x_px: None,
            r_free_px: None,
            sigma_r_free_px: None,
            force_n: None,
            flags: if x.is_none() {
                "missing".into()
            } else {
                String::new()
            },
        }
    }

    #[test]
    fn a_run_gives_its_events_as_frames_and_its_track_by_columns() {
        let rows: Vec<TrackRow> = (-2..8)
            .map(|k| row(k, (k != 1).then_some(120.0 + k as f64)))
            .collect();
        let mut rec = DropRecord::failed("R3", 3.0, "");
        rec.status = DropStatus::Ok;
        rec.t_contact_s = Some(0.96e-4);
        rec.t_max_s = Some(4.4e-4);
        rec.t_rebound_s = None;
        rec.surface_row_px = Some(207.5);
        let frames: Vec<i64> = (-2..8).collect();
        let d = Decisions::default();
        let j = RunData {
            record: &rec,
            rows: &rows,
            frames: &frames,
            decisions: &d,
            image_surface: Some((200.0, 0.01)),
            width_px: 384,
            height_px: 288,
            fps: 1e4,
            problem: None,
        }
        .to_json();
        assert_eq!(j["events"]["onset"], json!(1));
        assert_eq!(j["events"]["max"], json!(4));
        assert_eq!(j["events"]["rebound"], Value::Null);
        // The impact column is the fitted frame nearest the onset (frame 1
        // has no fit; frame 0 is nearer than 2).
        assert_eq!(j["surface"]["impact_column_px"], json!(120.0));
        let row = j["surface"]["image_row_at_impact_px"].as_f64().unwrap();
        assert!((row - 201.2).abs() < 1e-12, "{row}");
        assert_eq!(j["track"]["x_px"][3], Value::Null);
        assert_eq!(j["track"]["flags"][3], json!("missing"));
        assert_eq!(j["track"]["frame"].as_array().unwrap().len(), 10);
        assert!(frames_in(&frames, Frames { first: -2, last: 7 }));
        assert!(!frames_in(&frames, Frames { first: -3, last: 0 }));
        assert!(!frames_in(&frames, Frames { first: 0, last: 8 }));
    }
}
