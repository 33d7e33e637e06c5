//! The run manifest `runs.csv` (SPEC §4): one row per drop.
//!
//! Required columns `run, path, sphere_radius_mm`; optional `drop_height_cm,
//! fps, mm_per_px, surface, sphere_density_kg_m3, setup` (runs sharing one
//! camera set-up: the same zoom and position), `number_digits` (the digits
//! ending a frame file's name that are its number). Paths are relative to the
//! manifest's folder. The header is checked first (every required column,
//! no unknown or repeated one), then every value; an error names the file,
//! the row (its line, as a spreadsheet shows it: header = row 1), the column
//! and the text found there.

use super::decisions::RunReview;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The columns of a manifest: name, required, and what a value is (for
/// messages). The same names, in the same order, as [`ManifestRow`]'s fields.
pub const COLUMNS: [(&str, bool, &str); 10] = [
    ("run", true, "the run's name"),
    ("path", true, "the run's folder of frames or .cine file"),
    ("sphere_radius_mm", true, "mm"),
    ("drop_height_cm", false, "cm"),
    ("fps", false, "frames/s"),
    ("mm_per_px", false, "mm/px"),
    ("surface", false, "a [surface.<name>] of the configuration"),
    ("sphere_density_kg_m3", false, "kg/m³"),
    ("setup", false, "the camera set-up's name"),
    (
        "number_digits",
        false,
        "how many digits at the end of a frame file's name are its number (1‥18)",
    ),
];

/// One row as written in the file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManifestRow {
    /// The run's name, unique in the manifest.
    pub run: String,
    /// The run's folder of frames or `.cine` file, as written (relative to the manifest's folder).
    pub path: PathBuf,
    /// Sphere radius R, mm.
    pub sphere_radius_mm: f64,
    /// Fall height of the sphere's lowest point to the surface, cm.
    #[serde(default)]
    pub drop_height_cm: Option<f64>,
    /// Frame rate, frames/s, for a recording that holds none.
    #[serde(default)]
    pub fps: Option<f64>,
    /// A fixed scale for this run, mm per px.
    #[serde(default)]
    pub mm_per_px: Option<f64>,
    /// The `[surface.<name>]` of the configuration; empty: its default.
    #[serde(default)]
    pub surface: Option<String>,
    /// Sphere density, kg/m³; empty: the configuration's.
    #[serde(default)]
    pub sphere_density_kg_m3: Option<f64>,
    /// Camera set-up shared with other runs (same zoom and position).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub setup: Option<String>,
    /// How many digits at the end of a frame file's name are its number (1‥18).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub number_digits: Option<u32>,
}

/// A validated run: the path resolved against the manifest's folder.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunSpec {
    /// The run's name, unique in the manifest.
    pub run: String,
    /// The run's input, resolved against the manifest's folder.
    pub path: PathBuf,
    /// Sphere radius R, mm.
    pub sphere_radius_mm: f64,
    /// Fall height of the sphere's lowest point to the surface, cm; `None`: not given.
    pub drop_height_cm: Option<f64>,
    /// Frame rate from the manifest, frames/s; `None`: not given.
    pub fps: Option<f64>,
    /// A fixed scale from the manifest, mm per px; `None`: not given.
    pub mm_per_px: Option<f64>,
    /// Surface name; `None` means the configuration's default.
    pub surface: Option<String>,
    /// Sphere density, kg/m³; `None`: the configuration's.
    pub sphere_density_kg_m3: Option<f64>,
    /// Camera set-up shared with other runs (same zoom and position); `None`: not given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub setup: Option<String>,
    /// What `dropscope review` decided about the run (`review.csv`; not a
    /// manifest column): none from a manifest, filled in by the job. In
    /// the run's cache key, but only when there is something.
    #[serde(skip_serializing_if = "RunReview::is_empty")]
    pub review: RunReview,
    /// A folder of frames: the digits at the end of a file's name that are
    /// its number (the others are part of its name); `None`: all of them,
    /// unless the names read two ways (`source::folder::number_split`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub number_digits: Option<usize>,
}

/// Why a manifest could not be read.
#[derive(Debug, thiserror::Error)]
pub enum ManifestError {
    /// The manifest could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The manifest file.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The header row is wrong: a required column missing, an unknown or repeated one.
    #[error("{path}: row {row} (the header): {message}")]
    Header {
        /// The manifest file.
        path: PathBuf,
        /// The header's row (1).
        row: u64,
        /// What is wrong, and what is allowed.
        message: String,
    },
    /// A row's value could not be read or is out of range.
    #[error("{path}: row {row}: {message}")]
    Row {
        /// The manifest file.
        path: PathBuf,
        /// The row, as a spreadsheet shows it (the header is row 1).
        row: u64,
        /// The column, the text found and what is allowed.
        message: String,
    },
    /// The manifest has a header and no run.
    #[error("{path}: the manifest lists no run")]
    Empty {
        /// The manifest file.
        path: PathBuf,
    },
    /// None of the runs' inputs exists: a drive not mounted or a manifest moved without its runs.
    #[error(
        "{path}: none of its {runs} runs' inputs is there (the first, {}, does not exist): \
         nothing was written; is their drive mounted, or was the manifest moved without \
         them? (a run's path is taken from the manifest's folder)",
        first.display()
    )]
    NoneThere {
        /// The manifest file.
        path: PathBuf,
        /// How many runs it lists.
        runs: usize,
        /// The first run's input, which does not exist.
        first: PathBuf,
    },
}

/// The runs of manifest `path` for a job to process: [`read_manifest`]'s,
/// refused when none of their inputs is there. One missing input is that
/// run's failed row; all of them missing is a drive not mounted or a
/// manifest moved without its runs, and a job that measured nothing would
/// replace the output folder's earlier results with rows of failures.
pub fn read_job_manifest(path: &Path) -> Result<Vec<RunSpec>, ManifestError> {
    let runs = read_manifest(path)?;
    match runs.first() {
        Some(first) if !runs.iter().any(|r| r.path.exists()) => Err(ManifestError::NoneThere {
            path: path.to_path_buf(),
            runs: runs.len(),
            first: first.path.clone(),
        }),
        _ => Ok(runs),
    }
}

/// Read and validate a manifest.
pub fn read_manifest(path: &Path) -> Result<Vec<RunSpec>, ManifestError> {
    let bytes = crate::util::io::read_input(path, crate::util::io::TEXT_INPUT_MAX_BYTES).map_err(
        |source| ManifestError::Io {
            path: path.to_path_buf(),
            source,
        },
    )?;
    parse_manifest(&bytes, path)
}

/// Parse manifest bytes; `path` locates relative run paths and names the file in errors.
pub fn parse_manifest(bytes: &[u8], path: &Path) -> Result<Vec<RunSpec>, ManifestError> {
    let base = path.parent().unwrap_or(Path::new(""));
    let row_err = |row: u64, message: String| ManifestError::Row {
        path: path.to_path_buf(),
        row,
        message,
    };
    let mut rdr = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(bytes);
    // As csv's own `deserialize` does: a header that cannot be read (not
    // UTF-8) leaves the fields to be taken in order.
    let headers = rdr.headers().ok().cloned();
    if let Some(h) = headers.as_ref().filter(|h| !h.is_empty()) {
        header_problems(h).map_err(|message| ManifestError::Header {
            path: path.to_path_buf(),
            row: h.position().map_or(1, |p| p.line()),
            message,
        })?;
    }
    let mut runs: Vec<RunSpec> = Vec::new();
    for (i, rec) in rdr.records().enumerate() {
        let rec = rec.map_err(|e| {
            let row = e.position().map_or(i as u64 + 2, |p| p.line());
            row_err(row, read_message(&e))
        })?;
        let row = rec.position().map_or(i as u64 + 2, |p| p.line());
        let r: ManifestRow = rec
            .deserialize(headers.as_ref())
            .map_err(|e| row_err(row, value_message(&e, &rec, headers.as_ref())))?;
        crate::dataset::run_name::check(&r.run)
            .map_err(|e| row_err(row, format!("column `run`: {e}")))?;
        if runs.iter().any(|x| x.run == r.run) {
            return Err(row_err(row, format!("run `{}` is listed twice", r.run)));
        }
        runs.push(run_of(r, base).map_err(|message| row_err(row, message))?);
    }
    if runs.is_empty() {
        return Err(ManifestError::Empty {
            path: path.to_path_buf(),
        });
    }
    Ok(runs)
}

/// The run of a manifest row `r` whose run name is checked: each number
/// within its physical range ([`crate::util::ranges`]), no control
/// character in a path or name, a relative path taken from `base`; or what
/// is wrong with the row.
fn run_of(r: ManifestRow, base: &Path) -> Result<RunSpec, String> {
    // Each number within its physical range ([`crate::util::ranges`]).
    let ranged = |col: &str,
                  range: crate::util::ranges::Range,
                  v: Option<f64>|
     -> Result<Option<f64>, String> {
        match v {
            Some(x) if x.is_finite() && x <= 0.0 => Err(format!(
                "column `{col}` = {x}: must be a number greater than 0"
            )),
            Some(x) => match range.check(x) {
                Ok(_) => Ok(v),
                Err(allowed) => Err(format!(
                    "column `{col}` = {}: {allowed}",
                    crate::util::ranges::show(x)
                )),
            },
            None => Ok(v),
        }
    };
    use crate::util::ranges::{DENSITY_KG_M3, DROP_HEIGHT_CM, FPS, MM_PER_PX, SPHERE_RADIUS_MM};
    ranged(
        "sphere_radius_mm",
        SPHERE_RADIUS_MM,
        Some(r.sphere_radius_mm),
    )?;
    let fps = ranged("fps", FPS, r.fps)?;
    let mm_per_px = ranged("mm_per_px", MM_PER_PX, r.mm_per_px)?;
    let density = ranged(
        "sphere_density_kg_m3",
        DENSITY_KG_M3,
        r.sphere_density_kg_m3,
    )?;
    let height = ranged("drop_height_cm", DROP_HEIGHT_CM, r.drop_height_cm)?;
    if r.path
        .as_os_str()
        .to_string_lossy()
        .chars()
        .any(|c| c.is_control())
    {
        return Err(format!(
            "column `path` = {:?}: holds a control character",
            crate::util::text::one_line(&r.path.to_string_lossy())
        ));
    }
    for (col, v) in [("surface", &r.surface), ("setup", &r.setup)] {
        if let Some(v) = v.as_deref().filter(|v| {
            v.chars()
                .any(|c| c.is_control() || crate::util::text::is_format(c))
        }) {
            return Err(format!(
                "column `{col}` = {:?}: holds a control or invisible format character",
                crate::util::text::one_line(v)
            ));
        }
    }
    if let Some(d) = r.number_digits.filter(|d| !(1..=18).contains(d)) {
        return Err(format!(
            "column `number_digits` = {d}: must be a whole number from 1 to 18"
        ));
    }
    let p = if r.path.is_absolute() {
        r.path.clone()
    } else {
        base.join(&r.path)
    };
    Ok(RunSpec {
        run: r.run,
        path: p,
        sphere_radius_mm: r.sphere_radius_mm,
        drop_height_cm: height,
        fps,
        mm_per_px,
        surface: r.surface.filter(|s| !s.is_empty()),
        sphere_density_kg_m3: density,
        setup: r.setup.filter(|s| !s.is_empty()),
        review: Default::default(),
        number_digits: r.number_digits.map(|d| d as usize),
    })
}

/// What is wrong with a header, if anything: required columns missing,
/// columns no manifest has, a column given twice. Exactly what would make
/// every row fail to read, said once, before any row.
fn header_problems(header: &csv::StringRecord) -> Result<(), String> {
    let known = |c: &str| COLUMNS.iter().any(|(name, ..)| *name == c);
    let quoted = |names: &[&str]| {
        names
            .iter()
            .map(|n| match *n {
                "" => "`` (a column without a name: a comma too many?)".to_string(),
                n => format!("`{n}`"),
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    let missing: Vec<&str> = COLUMNS
        .iter()
        .filter(|(name, required, _)| *required && !header.iter().any(|h| h == *name))
        .map(|(name, ..)| *name)
        .collect();
    let unknown: Vec<&str> = header.iter().filter(|h| !known(h)).collect();
    // Each repeated name once, where it first stands.
    let twice: Vec<&str> = header
        .iter()
        .enumerate()
        .filter(|&(i, h)| {
            header.iter().position(|o| o == h) == Some(i)
                && header.iter().filter(|o| *o == h).count() > 1
        })
        .map(|(_, h)| h)
        .collect();
    let mut problems = Vec::new();
    if !missing.is_empty() {
        problems.push(format!("no column {} (required)", quoted(&missing)));
    }
    if !unknown.is_empty() {
        problems.push(format!("unknown column {}", quoted(&unknown)));
    }
    if !twice.is_empty() {
        problems.push(format!("column {} given twice", quoted(&twice)));
    }
    if problems.is_empty() {
        return Ok(());
    }
    let names = |required: bool| {
        COLUMNS
            .iter()
            .filter(|c| c.1 == required)
            .map(|c| c.0)
            .collect::<Vec<_>>()
            .join(", ")
    };
    Err(format!(
        "{}; a manifest's first row names its columns: required {}; optional {}",
        problems.join("; "),
        names(true),
        names(false)
    ))
}

/// A row that could not be read as CSV (csv's message carries its own
/// position, which the error already gives).
fn read_message(e: &csv::Error) -> String {
    match e.kind() {
        csv::ErrorKind::UnequalLengths {
            expected_len, len, ..
        } => format!(
            "{len} cells where the rows above have {expected_len}: give every column a \
             cell (empty for an optional value)"
        ),
        _ => e.to_string(),
    }
}

/// A value that could not be read, with its column and its text: "column
/// `fps` = \"abc\": not a number (frames/s)", "column `sphere_radius_mm` is
/// empty: it is required (mm)".
fn value_message(
    e: &csv::Error,
    rec: &csv::StringRecord,
    headers: Option<&csv::StringRecord>,
) -> String {
    let csv::ErrorKind::Deserialize { err, .. } = e.kind() else {
        return e.to_string();
    };
    let Some(i) = err.field().map(|i| i as usize) else {
        return err.to_string();
    };
    let column = match headers {
        Some(h) => h.get(i),
        None => COLUMNS.get(i).map(|c| c.0),
    }
    .unwrap_or("?");
    let text = rec.get(i).unwrap_or("");
    let what = COLUMNS.iter().find(|c| c.0 == column).map_or("", |c| c.2);
    match err.kind() {
        csv::DeserializeErrorKind::ParseFloat(_) if text.is_empty() => {
            format!("column `{column}` is empty: it is required ({what})")
        }
        csv::DeserializeErrorKind::ParseFloat(_) => {
            format!("column `{column}` = {text:?}: not a number ({what})")
        }
        kind => format!("column `{column}` = {text:?}: {kind}"),
    }
}

/// Serialise manifest rows (used by `render --campaign`).
pub fn to_csv_bytes(rows: &[ManifestRow]) -> Vec<u8> {
    crate::dataset::csv_bytes(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Vec<RunSpec>, ManifestError> {
        parse_manifest(text.as_bytes(), Path::new("/data/runs.csv"))
    }

    #[test]
    fn minimal_and_full_rows_read_with_paths_resolved() {
        let runs = parse(
            "run,path,sphere_radius_mm,drop_height_cm,fps,mm_per_px,surface,sphere_density_kg_m3\n\
             a,a/,3.0,1.5,10000,0.04,pdms,7800\n\
             b,/abs/b.cine,7.0,,,,,\n",
        )
        .unwrap();
        assert_eq!(runs.len(), 2);
        assert_eq!(runs[0].path, PathBuf::from("/data/a/"));
        assert_eq!(runs[0].fps, Some(10000.0));
        assert_eq!(runs[1].path, PathBuf::from("/abs/b.cine"));
        assert_eq!(runs[1].surface, None);
        let only_required = parse("run,path,sphere_radius_mm\nx,x,4.5\n").unwrap();
        assert_eq!(only_required[0].mm_per_px, None);
        assert_eq!(only_required[0].setup, None);
        let with_setup = parse(
            "run,path,sphere_radius_mm,drop_height_cm,setup\na,a,3,1.5,cam_R3mm_01\nb,b,3,3,\n",
        )
        .unwrap();
        assert_eq!(with_setup[0].setup.as_deref(), Some("cam_R3mm_01"));
        assert_eq!(with_setup[1].setup, None);
    }

    #[test]
    fn errors_name_file_row_and_column() {
        let e = parse("run,path,sphere_radius_mm\na,a,3\nb,b,-1\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("runs.csv") && e.contains("row 3") && e.contains("sphere_radius_mm"),
            "{e}"
        );
        let e = parse("run,path,sphere_radius_mm\na,a,three\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("row 2"), "{e}");
        let e = parse("run,path\na,a\n").unwrap_err().to_string();
        assert!(e.contains("sphere_radius_mm"), "{e}");
        let e = parse("run,path,sphere_radius_mm,colour\na,a,3,red\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("colour"), "{e}");
        let e = parse("run,path,sphere_radius_mm\na,a,3\na,b,4\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("twice"), "{e}");
        let e = parse("run,path,sphere_radius_mm\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("no run"), "{e}");
    }

    /// Each message names the file, the row, the column and the text found
    /// (not "row 2: invalid float literal", the same for every column).
    #[test]
    fn bad_values_name_the_column_and_the_text() {
        for (text, want) in [
            (
                "run,path,sphere_radius_mm\na,a,3mm\n",
                "/data/runs.csv: row 2: column `sphere_radius_mm` = \"3mm\": not a number (mm)",
            ),
            (
                "run,path,sphere_radius_mm,fps\na,a,3,1e4\nb,b,3,abc\n",
                "/data/runs.csv: row 3: column `fps` = \"abc\": not a number (frames/s)",
            ),
            (
                "run,path,sphere_radius_mm,mm_per_px\na,a,3,0.04 mm\n",
                "row 2: column `mm_per_px` = \"0.04 mm\": not a number (mm/px)",
            ),
            (
                "run,path,sphere_radius_mm\na,a,\n",
                "row 2: column `sphere_radius_mm` is empty: it is required (mm)",
            ),
            (
                "run,path,sphere_radius_mm\na,a, \n",
                "row 2: column `sphere_radius_mm` is empty: it is required (mm)",
            ),
            (
                "run,path,sphere_radius_mm\na,a,3\nb,b\n",
                "row 3: 2 cells where the rows above have 3",
            ),
            (
                "run,path,sphere_radius_mm\na,a,-3\n",
                "row 2: column `sphere_radius_mm` = -3: must be a number greater than 0",
            ),
        ] {
            let e = parse(text).unwrap_err().to_string();
            assert!(e.contains(want), "{text:?}\n → {e}\n wanted {want}");
        }
    }

    /// A header lacking a required column (or with one unknown or
    /// repeated) is the header's fault, said before any row.
    #[test]
    fn header_problems_are_the_headers() {
        for (text, want) in [
            (
                "run,path,fps\na,a,100\n",
                "no column `sphere_radius_mm` (required)",
            ),
            (
                "run,fps\na,100\n",
                "no column `path`, `sphere_radius_mm` (required)",
            ),
            (
                "run,path,sphere_radius\na,a,3\n",
                "no column `sphere_radius_mm` (required); unknown column `sphere_radius`",
            ),
            (
                "run,path,sphere_radius_mm,fps,fps\na,a,3,1,2\n",
                "column `fps` given twice",
            ),
            (
                "run,path,sphere_radius_mm,\na,a,3,\n",
                "a column without a name",
            ),
            // No row at all: still the header's fault.
            ("run,path\n", "no column `sphere_radius_mm`"),
        ] {
            let e = parse(text).unwrap_err().to_string();
            assert!(
                e.starts_with("/data/runs.csv: row 1 (the header): ") && e.contains(want),
                "{text:?}\n → {e}\n wanted {want}"
            );
            assert!(
                e.contains("required run, path, sphere_radius_mm; optional drop_height_cm, fps"),
                "{e}"
            );
        }
    }

    /// What the messages' checks let through is what was read before
    /// them: numbers as Rust reads them, cells trimmed, optional cells
    /// empty, columns in any order.
    #[test]
    fn accepted_values_are_unchanged() {
        let runs = parse(
            "fps , sphere_radius_mm,run,path,mm_per_px\n\
             ,+3,a,a,\n\
             1e4, 4.5 ,b,b, .04\n",
        )
        .unwrap();
        assert_eq!(runs[0].sphere_radius_mm, 3.0);
        assert_eq!((runs[0].fps, runs[0].mm_per_px), (None, None));
        assert_eq!(runs[1].sphere_radius_mm, 4.5);
        assert_eq!((runs[1].fps, runs[1].mm_per_px), (Some(1e4), Some(0.04)));
    }

    /// [`COLUMNS`] is [`ManifestRow`]'s fields, in order.
    #[test]
    fn the_column_table_is_the_row_struct() {
        let row = ManifestRow {
            run: "a".into(),
            path: "a".into(),
            sphere_radius_mm: 3.0,
            drop_height_cm: None,
            fps: None,
            mm_per_px: None,
            surface: None,
            sphere_density_kg_m3: None,
            setup: Some("s".into()),
            number_digits: Some(10),
        };
        let bytes = to_csv_bytes(&[row]);
        let header = String::from_utf8(bytes).unwrap();
        let names: Vec<&str> = COLUMNS.iter().map(|c| c.0).collect();
        assert_eq!(header.lines().next().unwrap(), names.join(","));
    }

    #[test]
    fn written_rows_read_back() {
        let mut rows = vec![ManifestRow {
            run: "R3_H1.5".into(),
            path: "R3_H1.5".into(),
            sphere_radius_mm: 3.0,
            drop_height_cm: Some(1.5),
            fps: None,
            mm_per_px: Some(0.04),
            surface: Some("pdms".into()),
            sphere_density_kg_m3: None,
            setup: None,
            number_digits: None,
        }];
        // A second row with other optional cells empty: every row keeps every column.
        rows.push(ManifestRow {
            run: "b".into(),
            drop_height_cm: None,
            mm_per_px: None,
            fps: Some(9000.0),
            ..rows[0].clone()
        });
        let bytes = to_csv_bytes(&rows);
        let back = parse_manifest(&bytes, Path::new("m/runs.csv")).unwrap();
        assert_eq!(back[0].path, PathBuf::from("m/R3_H1.5"));
        assert_eq!(back[0].drop_height_cm, Some(1.5));
        assert_eq!(back[1].fps, Some(9000.0));
        assert_eq!(back[1].mm_per_px, None);
    }
}
