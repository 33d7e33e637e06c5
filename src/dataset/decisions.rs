//! `review.csv`: what a person decided about the drops of an output folder
//! (`dropscope review`), one decision a row, read by `process` and `run`.
//!
//! | column | holds |
//! | --- | --- |
//! | `run` | the run the decision is about (a run name of drops.csv) |
//! | `decision` | `reject` (the drop is left out), `exclude` (frames left out of every fit), `surface` (the surface row set by hand), `accept` (a flagged drop accepted) |
//! | `frames` | `exclude` only: a camera image number, or `first:last` (both included; numbers may be negative, `-12:-9`) |
//! | `value` | `surface` only: the surface row at the impact column, px (the same quantity as drops.csv's `surface_row_px`) |
//! | `reason` | why, in the person's words (required) |
//! | `time` | when it was decided (UTC, `YYYY-MM-DDTHH:MM:SSZ`; informative, not used) |
//!
//! A run has at most one `reject`, `accept` and `surface` decision (the
//! last row of each counts); its `exclude` rows add up. Text cells (`run`,
//! `reason`) are written so that a spreadsheet never reads them as a
//! formula (a leading `=`, `+`, `-`, `@`, tab or carriage return gets a `'`
//! in front, which reading takes off again) and on one line (control and
//! format characters as `\u{…}`).
//!
//! Pure but for [`Decisions::read`] and `Decisions::write`: bytes in,
//! bytes out, the file written whole or not at all.

use serde::Serialize;
use std::path::{Path, PathBuf};

use crate::util::text::{csv_cell, csv_cell_back};

/// The decisions file's name in an output folder.
pub const REVIEW_FILE: &str = "review.csv";

/// The columns of `review.csv`, in the order written.
pub const COLUMNS: [&str; 6] = ["run", "decision", "frames", "value", "reason", "time"];

/// The largest `review.csv` read (a million decisions are ~100 MB; a
/// folder of 1 000 drops with a few decisions each is kilobytes).
pub const MAX_FILE_BYTES: u64 = 64 << 20;

/// The longest reason, in characters.
pub const MAX_REASON_CHARS: usize = 500;

/// The uncertainty given to a surface row set by hand, px: a row placed by
/// eye on the frame enlarged in the review page (8 screen pixels a frame
/// pixel at the contact zoom) is good to a quarter of a pixel, not to the
/// image line's ~0.002 px.
pub const HAND_SURFACE_ERR_PX: f64 = 0.25;

/// What a decision does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// The drop is left out: its row keeps its numbers with status `rejected`.
    Reject,
    /// Frames left out of every fit.
    Exclude,
    /// The surface row set by hand.
    Surface,
    /// A flagged drop accepted: status `accepted`.
    Accept,
}

impl Kind {
    /// Every kind of decision.
    pub const ALL: [Kind; 4] = [Kind::Reject, Kind::Exclude, Kind::Surface, Kind::Accept];

    /// Its word in the `decision` column.
    pub fn word(self) -> &'static str {
        match self {
            Kind::Reject => "reject",
            Kind::Exclude => "exclude",
            Kind::Surface => "surface",
            Kind::Accept => "accept",
        }
    }

    /// The kind a word names.
    pub fn from_word(w: &str) -> Option<Kind> {
        Kind::ALL.into_iter().find(|k| k.word() == w)
    }
}

/// Camera image numbers `first` to `last`, both included.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
pub struct Frames {
    /// The first camera image number left out.
    pub first: i64,
    /// The last camera image number left out (at least `first`).
    pub last: i64,
}

impl Frames {
    /// `N` or `A:B` (A ≤ B), numbers possibly negative.
    pub fn parse(text: &str) -> Result<Frames, String> {
        let t = text.trim();
        let num = |s: &str| -> Result<i64, String> {
            s.trim().parse::<i64>().map_err(|_| {
                format!("`{text}` is not a frame number or a range first:last of frame numbers")
            })
        };
        let (first, last) = match t.split_once(':') {
            Some((a, b)) => (num(a)?, num(b)?),
            None => {
                let n = num(t)?;
                (n, n)
            }
        };
        if first > last {
            return Err(format!(
                "`{text}`: the first frame comes after the last (write first:last)"
            ));
        }
        Ok(Frames { first, last })
    }

    /// Whether camera image `frame` lies in the range.
    pub fn contains(&self, frame: i64) -> bool {
        (self.first..=self.last).contains(&frame)
    }

    /// How many frames.
    pub fn count(&self) -> u64 {
        self.last.abs_diff(self.first) + 1
    }
}

impl std::fmt::Display for Frames {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.first == self.last {
            write!(f, "{}", self.first)
        } else {
            write!(f, "{}:{}", self.first, self.last)
        }
    }
}

/// One row of `review.csv`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Decision {
    /// The run the decision is about.
    pub run: String,
    /// What the decision does.
    pub decision: Kind,
    /// `exclude` only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frames: Option<Frames>,
    /// `surface` only: the row at the impact column, px.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub value: Option<f64>,
    /// Why, in the reviewer's words.
    pub reason: String,
    /// When it was decided (UTC, `YYYY-MM-DDTHH:MM:SSZ`); informative, not used.
    pub time: String,
}

impl Decision {
    /// A decision made now (`time` the current UTC time), checked as a
    /// row of the file is ([`Decision::check`]).
    pub fn new(
        run: &str,
        decision: Kind,
        frames: Option<Frames>,
        value: Option<f64>,
        reason: &str,
    ) -> Result<Decision, String> {
        let d = Decision {
            run: run.to_string(),
            decision,
            frames,
            value,
            reason: reason.trim().to_string(),
            time: utc_now(),
        };
        d.check()?;
        Ok(d)
    }

    /// Whether the row is complete and consistent: a run name, a reason,
    /// frames for `exclude` only, a finite value for `surface` only.
    pub fn check(&self) -> Result<(), String> {
        crate::dataset::run_name::check(&self.run)?;
        let word = self.decision.word();
        if self.reason.trim().is_empty() {
            return Err(format!("`{word}` needs a reason"));
        }
        if self.reason.chars().count() > MAX_REASON_CHARS {
            return Err(format!(
                "the reason is longer than {MAX_REASON_CHARS} characters"
            ));
        }
        match (self.decision, self.frames) {
            (Kind::Exclude, None) => {
                return Err("`exclude` needs frames (N or first:last)".into());
            }
            (Kind::Exclude, Some(_)) | (_, None) => {}
            (_, Some(_)) => return Err(format!("`{word}` takes no frames")),
        }
        match (self.decision, self.value) {
            (Kind::Surface, Some(v)) if !(v.is_finite() && v.abs() < 1e6) => {
                Err(format!("surface row {v}: must be a finite row in px"))
            }
            (Kind::Surface, None) => Err("`surface` needs the row (px) in `value`".into()),
            (Kind::Surface, Some(_)) | (_, None) => Ok(()),
            (_, Some(_)) => Err(format!("`{word}` takes no value")),
        }
    }
}

/// What the review decided about one run, as processing applies it.
/// Serialised into the run's cache key ([`crate::job::cache::key`], through its
/// [`super::manifest::RunSpec`]): a run without decisions serialises to
/// nothing, so only the runs a decision touches are measured again. The
/// decisions' times are not in it.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct RunReview {
    /// Why the drop was rejected.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rejected: Option<String>,
    /// Why its flags were accepted.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub accepted: Option<String>,
    /// Frames left out of every fit, with why, in the file's order.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub excluded: Vec<(Frames, String)>,
    /// The surface row at the impact column set by hand (px), with why.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub surface_row_px: Option<(f64, String)>,
}

impl RunReview {
    /// No decision touches the run.
    pub fn is_empty(&self) -> bool {
        self.rejected.is_none()
            && self.accepted.is_none()
            && self.excluded.is_empty()
            && self.surface_row_px.is_none()
    }

    /// Whether camera image `frame` is excluded.
    pub fn excludes(&self, frame: i64) -> bool {
        self.excluded.iter().any(|(f, _)| f.contains(frame))
    }

    /// The decisions in a few words, for drops.csv's `review` column:
    /// `rejected: …; accepted: …; excluded 12:14 (…), 20 (…); surface
    /// 207.25 px (…)`; empty without any.
    pub fn summary(&self) -> String {
        let mut parts = Vec::new();
        if let Some(r) = &self.rejected {
            parts.push(format!("rejected: {r}"));
        }
        if let Some(r) = &self.accepted {
            parts.push(format!("accepted: {r}"));
        }
        if !self.excluded.is_empty() {
            let each: Vec<String> = self
                .excluded
                .iter()
                .map(|(f, r)| format!("{f} ({r})"))
                .collect();
            parts.push(format!("excluded frames {}", each.join(", ")));
        }
        if let Some((row, r)) = &self.surface_row_px {
            parts.push(format!("surface row {row} px set by hand ({r})"));
        }
        parts.join("; ")
    }

    /// `record` as the review leaves it: its `review` column; a rejected
    /// drop's status `rejected` and its reason first (a run whose impact was
    /// not measured, `failed` or `tracked`, keeps its status: it is in no
    /// collapse to leave); a flagged (`warning`) drop accepted as
    /// `accepted`, its flags and their sentences kept.
    pub fn apply(&self, record: &mut crate::dataset::DropRecord) {
        use crate::dataset::DropStatus;
        record.review = self.summary();
        let prefix = |record: &mut crate::dataset::DropRecord, head: String| {
            record.reason = if record.reason.is_empty() {
                head
            } else {
                format!("{head}; {}", record.reason)
            };
        };
        if let (Some(why), true) = (&self.rejected, record.status.measured()) {
            record.status = DropStatus::Rejected;
            prefix(record, format!("rejected in review: {why}"));
        } else if let (Some(why), DropStatus::Warning) = (&self.accepted, record.status) {
            record.status = DropStatus::Accepted;
            prefix(record, format!("accepted in review: {why}"));
        }
    }
}

/// Why `review.csv` could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum ReviewError {
    /// The file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The decisions file.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A line of the file is not a valid decision.
    #[error("{path}: line {line}: {message}")]
    Row {
        /// The decisions file.
        path: PathBuf,
        /// The line (the header is line 1).
        line: u64,
        /// What is wrong with it.
        message: String,
    },
    /// The file is larger than [`MAX_FILE_BYTES`]: not a decisions file.
    #[error("{path}: larger than {MAX_FILE_BYTES} bytes: not a decisions file")]
    TooLarge {
        /// The file.
        path: PathBuf,
    },
    /// `input.review` names a file outside the output folder, where the review could not save.
    #[error(
        "input.review names {path}, outside the output folder {out}: `dropscope review` saves \
         its decisions only inside the output folder it shows; name a file in that folder, or \
         leave input.review out (review.csv there)"
    )]
    Outside {
        /// The decisions file named.
        path: PathBuf,
        /// The output folder.
        out: PathBuf,
    },
}

/// The decisions of one file, in its order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Decisions {
    /// The decisions, in the file's order.
    pub rows: Vec<Decision>,
}

impl Decisions {
    /// Parse `review.csv`'s bytes; `path` names the file in errors, each
    /// with its line and the column at fault.
    pub fn parse(bytes: &[u8], path: &Path) -> Result<Decisions, ReviewError> {
        let err = |line: u64, message: String| ReviewError::Row {
            path: path.to_path_buf(),
            line,
            message,
        };
        let mut rdr = csv::ReaderBuilder::new().flexible(false).from_reader(bytes);
        let headers = rdr
            .headers()
            .map_err(|e| err(1, format!("the header: {e}")))?
            .clone();
        let mut at = [usize::MAX; 6];
        for (i, h) in headers.iter().enumerate() {
            match COLUMNS.iter().position(|c| *c == h.trim()) {
                Some(k) if at[k] == usize::MAX => at[k] = i,
                Some(_) => return Err(err(1, format!("the header names `{h}` twice"))),
                None => {
                    return Err(err(
                        1,
                        format!(
                            "the header names `{h}`, not a column of a decisions file ({})",
                            COLUMNS.join(", ")
                        ),
                    ))
                }
            }
        }
        if let Some(k) = at.iter().position(|&i| i == usize::MAX) {
            return Err(err(
                1,
                format!("the header lacks the column `{}`", COLUMNS[k]),
            ));
        }
        let mut rows = Vec::new();
        for rec in rdr.records() {
            let rec = rec.map_err(|e| {
                let line = e.position().map_or(0, |p| p.line());
                err(line, e.to_string())
            })?;
            let line = rec.position().map_or(0, |p| p.line());
            let cell = |k: usize| rec.get(at[k]).unwrap_or("").trim();
            let decision = Kind::from_word(cell(1)).ok_or_else(|| {
                err(
                    line,
                    format!(
                        "decision `{}`: must be reject, exclude, surface or accept",
                        cell(1)
                    ),
                )
            })?;
            let frames = match cell(2) {
                "" => None,
                t => Some(Frames::parse(t).map_err(|m| err(line, format!("frames {m}")))?),
            };
            let value = match cell(3) {
                "" => None,
                t => Some(t.parse::<f64>().map_err(|_| {
                    err(
                        line,
                        format!("value `{t}`: not a number (the surface row in px)"),
                    )
                })?),
            };
            let d = Decision {
                run: csv_cell_back(cell(0)).to_string(),
                decision,
                frames,
                value,
                reason: csv_cell_back(cell(4)).to_string(),
                time: cell(5).to_string(),
            };
            d.check().map_err(|m| err(line, m))?;
            rows.push(d);
        }
        Ok(Decisions { rows })
    }

    /// The file's bytes: the header, then a row a decision in order, text
    /// cells made safe for spreadsheets ([`csv_cell`]). Parsing them gives
    /// the same decisions back.
    pub fn to_csv_bytes(&self) -> Vec<u8> {
        let mut w = csv::WriterBuilder::new()
            .terminator(csv::Terminator::Any(b'\n'))
            .from_writer(Vec::new());
        let _ = w.write_record(COLUMNS);
        for d in &self.rows {
            let value = d.value.map(|v| format!("{v}")).unwrap_or_default();
            let frames = d.frames.map(|f| f.to_string()).unwrap_or_default();
            let _ = w.write_record([
                &*csv_cell(&d.run),
                d.decision.word(),
                &frames,
                &value,
                &*csv_cell(&d.reason),
                &*csv_cell(&d.time),
            ]);
        }
        w.into_inner().unwrap_or_default()
    }

    /// The decisions in `path`; none when there is no such file.
    pub fn read(path: &Path) -> Result<Decisions, ReviewError> {
        let io = |source| ReviewError::Io {
            path: path.to_path_buf(),
            source,
        };
        match std::fs::symlink_metadata(path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Decisions::default()),
            Err(e) => return Err(io(e)),
            Ok(_) => {}
        }
        let bytes = crate::util::io::read_bounded(path, MAX_FILE_BYTES)
            .map_err(io)?
            .ok_or_else(|| ReviewError::TooLarge {
                path: path.to_path_buf(),
            })?;
        Decisions::parse(&bytes, path)
    }

    /// The decisions in `out/rel`, read through no link below the output
    /// folder `out` ([`crate::util::out_folder::read`]); none when there is no
    /// such file.
    pub fn read_in(out: &Path, rel: &str) -> Result<Decisions, ReviewError> {
        let path = out.join(rel);
        match crate::util::out_folder::read(out, rel, MAX_FILE_BYTES) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Decisions::default()),
            Err(source) => Err(ReviewError::Io { path, source }),
            Ok(None) => Err(ReviewError::TooLarge { path }),
            Ok(Some(bytes)) => Decisions::parse(&bytes, &path),
        }
    }

    /// Write the decisions to `out/rel`, inside the output folder `out`,
    /// whole or not at all (a temporary beside it, synced, renamed over
    /// it), through no link ([`crate::util::out_folder::write`]).
    pub fn write_in(&self, out: &Path, rel: &str) -> Result<(), ReviewError> {
        crate::util::out_folder::write(out, rel, &self.to_csv_bytes())
            .map(|_| ())
            .map_err(|source| ReviewError::Io {
                path: out.join(rel),
                source,
            })
    }

    /// What the decisions say of `run`.
    pub fn for_run(&self, run: &str) -> RunReview {
        let mut r = RunReview::default();
        for d in self.rows.iter().filter(|d| d.run == run) {
            match d.decision {
                Kind::Reject => r.rejected = Some(d.reason.clone()),
                Kind::Accept => r.accepted = Some(d.reason.clone()),
                Kind::Surface => {
                    r.surface_row_px = d.value.map(|v| (v, d.reason.clone()));
                }
                Kind::Exclude => {
                    if let Some(f) = d.frames {
                        r.excluded.push((f, d.reason.clone()));
                    }
                }
            }
        }
        r
    }

    /// Add `d`: a `reject`, `accept` or `surface` replaces the run's
    /// earlier one of its kind; an `exclude` is added (the same frames
    /// again replace their earlier row).
    pub fn add(&mut self, d: Decision) {
        let same = |o: &Decision| {
            o.run == d.run
                && o.decision == d.decision
                && (d.decision != Kind::Exclude || o.frames == d.frames)
        };
        self.rows.retain(|o| !same(o));
        self.rows.push(d);
    }

    /// Remove run `run`'s decisions of kind `kind` (of `exclude`, those of
    /// frames `frames` only when given); how many were removed.
    pub fn withdraw(&mut self, run: &str, kind: Kind, frames: Option<Frames>) -> usize {
        let before = self.rows.len();
        self.rows.retain(|o| {
            !(o.run == run && o.decision == kind && (frames.is_none() || o.frames == frames))
        });
        before - self.rows.len()
    }

    /// The runs named, in the order first named.
    pub fn runs(&self) -> Vec<&str> {
        let mut seen: Vec<&str> = Vec::new();
        for d in &self.rows {
            if !seen.contains(&d.run.as_str()) {
                seen.push(&d.run);
            }
        }
        seen
    }
}

/// Where a job's decisions are: the configuration's `input.review`, else
/// `review.csv` in the output folder.
pub fn review_path(configured: Option<&Path>, out: &Path) -> PathBuf {
    configured.map_or_else(|| out.join(REVIEW_FILE), Path::to_path_buf)
}

/// Where `dropscope review` keeps the decisions of output folder `out`:
/// the path below `out` of the configuration's `input.review`, else
/// [`REVIEW_FILE`]. A file outside the folder is refused
/// ([`ReviewError::Outside`]): the page writes only inside the folder it
/// shows.
pub fn review_rel(configured: Option<&Path>, out: &Path) -> Result<String, ReviewError> {
    let Some(path) = configured else {
        return Ok(REVIEW_FILE.to_string());
    };
    let below = path
        .strip_prefix(out)
        .ok()
        .map(Path::to_path_buf)
        .or_else(|| {
            // The same folder written two ways (relative, through a link).
            let out = out.canonicalize().ok()?;
            let parent = path.parent()?.canonicalize().ok()?;
            Some(parent.strip_prefix(out).ok()?.join(path.file_name()?))
        });
    below
        .and_then(|rel| rel.to_str().map(str::to_string))
        .filter(|rel| crate::util::io::inside(out, rel).is_ok())
        .ok_or_else(|| ReviewError::Outside {
            path: path.to_path_buf(),
            out: out.to_path_buf(),
        })
}

/// The current time in UTC as `YYYY-MM-DDTHH:MM:SSZ`.
pub fn utc_now() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    utc_text(secs)
}

/// Seconds since 1970 in UTC as `YYYY-MM-DDTHH:MM:SSZ` (the civil date of
/// a day count: H. Hinnant, "chrono-Compatible Low-Level Date Algorithms").
pub fn utc_text(secs: u64) -> String {
    let days = (secs / 86_400) as i64;
    let rem = secs % 86_400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p() -> &'static Path {
        Path::new("out/review.csv")
    }

    #[test]
    fn dates_are_the_civil_ones() {
        assert_eq!(utc_text(0), "1970-01-01T00:00:00Z");
        // 2000-02-29 (a leap day of a century year) 12:34:56.
        assert_eq!(utc_text(951_827_696), "2000-02-29T12:34:56Z");
        assert_eq!(utc_text(1_709_251_199), "2024-02-29T23:59:59Z");
        assert_eq!(utc_text(4_102_444_800), "2100-01-01T00:00:00Z");
    }

    #[test]
    fn a_file_reads_back_as_written_and_formulas_are_neutralised() {
        let mut d = Decisions::default();
        let row = |run: &str, k, frames: Option<&str>, value, reason: &str| Decision {
            run: run.into(),
            decision: k,
            frames: frames.map(|f| Frames::parse(f).unwrap()),
            value,
            reason: reason.into(),
            time: "2024-05-01T10:00:00Z".into(),
        };
        d.add(row(
            "R3",
            Kind::Exclude,
            Some("-12:-9"),
            None,
            "dust, \"big\"",
        ));
        d.add(row(
            "=HYPERLINK(\"x\")",
            Kind::Reject,
            None,
            None,
            "=cmd|' /c calc'!A1",
        ));
        d.add(row(
            "R3",
            Kind::Surface,
            None,
            Some(207.25),
            "+glossy\nband",
        ));
        d.add(row("R3", Kind::Accept, None, None, "@gravity checked"));
        let bytes = d.to_csv_bytes();
        let text = String::from_utf8(bytes.clone()).unwrap();
        assert_eq!(
            text,
            "run,decision,frames,value,reason,time\n\
             R3,exclude,-12:-9,,\"dust, \"\"big\"\"\",2024-05-01T10:00:00Z\n\
             \"'=HYPERLINK(\"\"x\"\")\",reject,,,'=cmd|' /c calc'!A1,2024-05-01T10:00:00Z\n\
             R3,surface,,207.25,'+glossy\\u{a}band,2024-05-01T10:00:00Z\n\
             R3,accept,,,'@gravity checked,2024-05-01T10:00:00Z\n"
        );
        // No cell a spreadsheet would evaluate: none starts with = + - @
        // but frame numbers, which are checked to be numbers.
        let back = Decisions::parse(&bytes, p()).unwrap();
        let mut want = d.clone();
        want.rows[2].reason = "+glossy\\u{a}band".into();
        assert_eq!(back, want);
        let r = back.for_run("R3");
        assert!(r.excludes(-10) && r.excludes(-12) && !r.excludes(-8));
        assert_eq!(r.surface_row_px, Some((207.25, "+glossy\\u{a}band".into())));
        assert_eq!(
            r.summary(),
            "accepted: @gravity checked; excluded frames -12:-9 (dust, \"big\"); surface row \
             207.25 px set by hand (+glossy\\u{a}band)"
        );
        assert!(back.for_run("other").is_empty());
    }

    #[test]
    fn bad_rows_are_refused_naming_the_line_and_the_column() {
        let head = "run,decision,frames,value,reason,time\n";
        for (body, says) in [
            ("a,delete,,,x,\n", "line 2: decision `delete`"),
            ("a,exclude,,,x,\n", "line 2: `exclude` needs frames"),
            (
                "a,exclude,9:3,,x,\n",
                "line 2: frames `9:3`: the first frame comes after",
            ),
            (
                "a,exclude,x:3,,x,\n",
                "line 2: frames `x:3` is not a frame number",
            ),
            ("a,reject,,,,\n", "line 2: `reject` needs a reason"),
            ("a,reject,3,,x,\n", "line 2: `reject` takes no frames"),
            ("a,surface,,,x,\n", "line 2: `surface` needs the row"),
            ("a,surface,,abc,x,\n", "line 2: value `abc`: not a number"),
            (
                "a,surface,,inf,x,\n",
                "line 2: surface row inf: must be a finite row",
            ),
            ("a,accept,,1,x,\n", "line 2: `accept` takes no value"),
            (
                "ok,reject,,,x,\n../etc,reject,,,x,\n",
                "line 3: run name \"../etc\" holds a path separator",
            ),
            ("a,reject,,,x\n", "line 2: "),
        ] {
            let e = Decisions::parse(format!("{head}{body}").as_bytes(), p())
                .unwrap_err()
                .to_string();
            assert!(
                e.starts_with("out/review.csv: ") && e.contains(says),
                "{body:?}: {e}"
            );
        }
        let e = Decisions::parse(b"run,decision,frames,value,why,time\n", p())
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 1: the header names `why`"), "{e}");
        let e = Decisions::parse(b"run,decision,frames,value,reason\n", p())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("line 1: the header lacks the column `time`"),
            "{e}"
        );
        // Columns in another order are read by their names.
        let d = Decisions::parse(
            b"decision,run,reason,time,frames,value\nreject,a,blurred,,,\n",
            p(),
        )
        .unwrap();
        assert_eq!(d.for_run("a").rejected.as_deref(), Some("blurred"));
    }

    #[test]
    fn the_last_of_a_kind_counts_and_excludes_add_up() {
        let mut d = Decisions::default();
        let mk = |k, frames: Option<Frames>, value, reason: &str| {
            Decision::new("a", k, frames, value, reason).unwrap()
        };
        d.add(mk(Kind::Surface, None, Some(200.0), "first"));
        d.add(mk(Kind::Surface, None, Some(201.5), "second"));
        d.add(mk(
            Kind::Exclude,
            Some(Frames::parse("3").unwrap()),
            None,
            "dust",
        ));
        d.add(mk(
            Kind::Exclude,
            Some(Frames::parse("5:6").unwrap()),
            None,
            "glint",
        ));
        d.add(mk(
            Kind::Exclude,
            Some(Frames::parse("3").unwrap()),
            None,
            "dust again",
        ));
        assert_eq!(d.rows.len(), 3);
        let r = d.for_run("a");
        assert_eq!(r.surface_row_px, Some((201.5, "second".into())));
        assert_eq!(
            r.excluded,
            vec![
                (Frames { first: 5, last: 6 }, "glint".into()),
                (Frames { first: 3, last: 3 }, "dust again".into())
            ]
        );
        assert_eq!(
            d.withdraw("a", Kind::Exclude, Some(Frames { first: 5, last: 6 })),
            1
        );
        assert_eq!(d.withdraw("a", Kind::Reject, None), 0);
        assert_eq!(d.withdraw("a", Kind::Surface, None), 1);
        assert_eq!(d.rows.len(), 1);
        assert!(Decision::new("a", Kind::Reject, None, None, "  ").is_err());
        assert!(Decision::new("a", Kind::Reject, None, None, &"x".repeat(501)).is_err());
    }

    #[test]
    fn a_rejected_drop_keeps_its_numbers_and_an_accepted_warning_its_flags() {
        use crate::dataset::{DropRecord, DropStatus};
        let mut rec = DropRecord::failed("a", 3.0, "");
        rec.status = DropStatus::Warning;
        rec.flags = "gravity_off".into();
        rec.reason = "the fitted gravity is 3 % off".into();
        rec.delta_max_mm = Some(0.5);
        let accepted = RunReview {
            accepted: Some("fps checked".into()),
            ..RunReview::default()
        };
        let mut a = rec.clone();
        accepted.apply(&mut a);
        assert_eq!(a.status, DropStatus::Accepted);
        assert_eq!(a.flags, "gravity_off");
        assert_eq!(
            a.reason,
            "accepted in review: fps checked; the fitted gravity is 3 % off"
        );
        assert_eq!(a.review, "accepted: fps checked");
        // Accepting a drop with nothing flagged changes its status not.
        let mut ok = rec.clone();
        ok.status = DropStatus::Ok;
        accepted.apply(&mut ok);
        assert_eq!(ok.status, DropStatus::Ok);
        let rejected = RunReview {
            rejected: Some("two spheres in view".into()),
            ..accepted
        };
        let mut r = rec.clone();
        rejected.apply(&mut r);
        assert_eq!(r.status, DropStatus::Rejected);
        assert_eq!(r.delta_max_mm, Some(0.5));
        assert!(r
            .reason
            .starts_with("rejected in review: two spheres in view; "));
        // A run whose impact was not measured keeps its status (it is in
        // no collapse to leave), its decision in its review column.
        for status in [DropStatus::Failed, DropStatus::Tracked] {
            let mut f = rec.clone();
            f.status = status;
            rejected.apply(&mut f);
            assert_eq!(f.status, status);
            assert!(
                f.review.starts_with("rejected: two spheres in view"),
                "{}",
                f.review
            );
        }
    }
}
