//! The run manifest `runs.csv` (SPEC §4): one row per drop.
//!
//! Required columns `run, path, sphere_radius_mm`; optional `drop_height_cm,
//! fps, mm_per_px, surface, sphere_density_kg_m3, setup` (runs sharing one
//! camera set-up: the same zoom and position). Paths are relative to the
//! manifest's folder. Every value is checked; an error names the file, the
//! row (as a spreadsheet shows it, header = row 1) and the column.

use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// One row as written in the file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManifestRow {
    pub run: String,
    pub path: PathBuf,
    pub sphere_radius_mm: f64,
    #[serde(default)]
    pub drop_height_cm: Option<f64>,
    #[serde(default)]
    pub fps: Option<f64>,
    #[serde(default)]
    pub mm_per_px: Option<f64>,
    #[serde(default)]
    pub surface: Option<String>,
    #[serde(default)]
    pub sphere_density_kg_m3: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub setup: Option<String>,
}

/// A validated run: the path resolved against the manifest's folder.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunSpec {
    pub run: String,
    pub path: PathBuf,
    pub sphere_radius_mm: f64,
    pub drop_height_cm: Option<f64>,
    pub fps: Option<f64>,
    pub mm_per_px: Option<f64>,
    /// Surface name; `None` means the configuration's default.
    pub surface: Option<String>,
    pub sphere_density_kg_m3: Option<f64>,
    /// Camera set-up shared with other runs (same zoom and position); `None`: not given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub setup: Option<String>,
}

/// Why a manifest could not be read.
#[derive(Debug, thiserror::Error)]
pub enum ManifestError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: row {row}: {message}")]
    Row {
        path: PathBuf,
        row: u64,
        message: String,
    },
    #[error("{path}: the manifest lists no run")]
    Empty { path: PathBuf },
}

/// Read and validate a manifest.
pub fn read_manifest(path: &Path) -> Result<Vec<RunSpec>, ManifestError> {
    let bytes = std::fs::read(path).map_err(|source| ManifestError::Io {
        path: path.to_path_buf(),
        source,
    })?;
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
    let mut runs: Vec<RunSpec> = Vec::new();
    for (i, rec) in rdr.deserialize::<ManifestRow>().enumerate() {
        let row = i as u64 + 2;
        let r = rec.map_err(|e| row_err(row, csv_message(&e)))?;
        crate::run_name::check(&r.run).map_err(|e| row_err(row, format!("column `run`: {e}")))?;
        if runs.iter().any(|x| x.run == r.run) {
            return Err(row_err(row, format!("run `{}` is listed twice", r.run)));
        }
        let positive = |col: &str, v: Option<f64>| -> Result<Option<f64>, ManifestError> {
            match v {
                Some(x) if !(x.is_finite() && x > 0.0) => Err(row_err(
                    row,
                    format!("column `{col}` = {x}: must be a number greater than 0"),
                )),
                _ => Ok(v),
            }
        };
        positive("sphere_radius_mm", Some(r.sphere_radius_mm))?;
        let fps = positive("fps", r.fps)?;
        let mm_per_px = positive("mm_per_px", r.mm_per_px)?;
        let density = positive("sphere_density_kg_m3", r.sphere_density_kg_m3)?;
        let height = positive("drop_height_cm", r.drop_height_cm)?;
        let p = if r.path.is_absolute() {
            r.path.clone()
        } else {
            base.join(&r.path)
        };
        runs.push(RunSpec {
            run: r.run,
            path: p,
            sphere_radius_mm: r.sphere_radius_mm,
            drop_height_cm: height,
            fps,
            mm_per_px,
            surface: r.surface.filter(|s| !s.is_empty()),
            sphere_density_kg_m3: density,
            setup: r.setup.filter(|s| !s.is_empty()),
        });
    }
    if runs.is_empty() {
        return Err(ManifestError::Empty {
            path: path.to_path_buf(),
        });
    }
    Ok(runs)
}

/// csv's messages carry their own position; keep the part a user needs.
fn csv_message(e: &csv::Error) -> String {
    match e.kind() {
        csv::ErrorKind::Deserialize { err, .. } => match err.field() {
            Some(_) => format!("{}", err.kind()),
            None => err.to_string(),
        },
        _ => e.to_string(),
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
