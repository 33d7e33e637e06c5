//! The per-drop record and `drops.csv` (SPEC §4). The struct is the schema:
//! its field names are the CSV columns, in this order, with their units in
//! their names. A run that could not be measured still has a row, with its
//! status and reason and the measured columns empty.

use serde::{Deserialize, Serialize};
use std::path::Path;

/// Outcome of one run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DropStatus {
    /// Every quantity measured.
    Ok,
    /// Measured, with quality flags in `flags` and their sentences in `reason`.
    Warning,
    /// Nothing measured; `reason` says why.
    Failed,
    /// The sphere was tracked but never reached the surface (a calibration
    /// drop, a clip cut before the impact): its track, overlay and free
    /// flight (`v_last_m_s`, `g_fit_m_s2`, the scale) are kept, no impact;
    /// `reason` says why, with any flags' sentences. Not in the collapse.
    Tracked,
    /// Left out by a person in `dropscope review` (`review.csv`): measured
    /// as any other, its reason first, and left out of the collapse.
    Rejected,
    /// Flagged (a `warning`), and accepted by a person in `dropscope
    /// review`: its flags and their sentences kept, the acceptance's
    /// reason first.
    Accepted,
}

impl DropStatus {
    /// Its word in drops.csv.
    pub fn word(self) -> &'static str {
        match self {
            DropStatus::Ok => "ok",
            DropStatus::Warning => "warning",
            DropStatus::Failed => "failed",
            DropStatus::Tracked => "tracked",
            DropStatus::Rejected => "rejected",
            DropStatus::Accepted => "accepted",
        }
    }

    /// Whether the run's impact was measured (`ok`, `warning`, and the
    /// review's `accepted` and `rejected`, measured as any other): the rows
    /// with values, tracks and per-drop figures.
    pub fn measured(self) -> bool {
        matches!(
            self,
            DropStatus::Ok | DropStatus::Warning | DropStatus::Accepted | DropStatus::Rejected
        )
    }

    /// Whether the drop's numbers enter the collapse: measured, and not
    /// rejected.
    pub fn collapses(self) -> bool {
        self.measured() && self != DropStatus::Rejected
    }
}

/// One drop: what was measured, with one-sigma uncertainties in the `_err`
/// columns. Measured fields are `None` (an empty CSV cell) when the run failed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DropRecord {
    /// Run name (the manifest's `run` column, or the folder / file stem);
    /// in the file as a text cell ([`crate::util::text::csv_cell`]).
    #[serde(serialize_with = "text_out", deserialize_with = "text_in")]
    pub run: String,
    /// Sphere radius R, mm, as the run was given it (manifest, `--radius-mm` or `sphere.radius_mm`).
    pub sphere_radius_mm: f64,
    /// Sphere density, kg/m³ (from the manifest or `sphere.density_kg_m3`).
    #[serde(default = "default_density")]
    pub sphere_density_kg_m3: f64,
    /// Key of the `[surface.<name>]` table of pipeline.toml holding the material.
    #[serde(default, serialize_with = "dash_out", deserialize_with = "dash_in")]
    pub surface: String,
    /// The release height from the manifest (`drop_height_cm`), kept for
    /// the record; empty when the manifest has none.
    #[serde(default)]
    pub drop_height_cm: Option<f64>,
    /// The run's input (a folder of frames or a `.cine`) as the manifest
    /// resolved it.
    #[serde(default, serialize_with = "dash_out", deserialize_with = "dash_in")]
    pub path: String,
    /// The frame rate the run was measured at (frames/s): the recording's
    /// own, else the fallback `fps_source` names.
    #[serde(default)]
    pub fps: Option<f64>,
    /// Where `fps` came from: `xml` (the PCC XML side file), `cine` (the
    /// cine header), or another reader's format: the recording's own; else
    /// `manifest`, `flag` (`--fps`), `config` (`camera.fps`) or `default`
    /// ([`crate::config::DEFAULT_FPS`], nothing gave one). The last two are
    /// flagged `fps_assumed`.
    #[serde(default, serialize_with = "dash_out", deserialize_with = "dash_in")]
    pub fps_source: String,
    /// Speed at contact onset, m/s.
    pub v_impact_m_s: Option<f64>,
    /// One-sigma error of `v_impact_m_s`, m/s.
    #[serde(default)]
    pub v_impact_m_s_err: Option<f64>,
    /// Speed at loss of contact, m/s.
    pub v_rebound_m_s: Option<f64>,
    /// One-sigma error of `v_rebound_m_s`, m/s.
    #[serde(default)]
    pub v_rebound_m_s_err: Option<f64>,
    /// Restitution e = v_rebound / v_impact.
    pub restitution: Option<f64>,
    /// One-sigma error of `restitution`.
    #[serde(default)]
    pub restitution_err: Option<f64>,
    /// Maximum penetration δmax, mm.
    pub delta_max_mm: Option<f64>,
    /// One-sigma error of `delta_max_mm`, mm.
    #[serde(default)]
    pub delta_max_mm_err: Option<f64>,
    /// Measured contact radius at δmax (the collapse's default `a`), mm.
    pub a_max_mm: Option<f64>,
    /// One-sigma error of `a_max_mm`, mm.
    #[serde(default)]
    pub a_max_mm_err: Option<f64>,
    /// Geometric contact radius √(R² − (R − δmax)²), mm.
    pub a_geom_mm: Option<f64>,
    /// One-sigma error of `a_geom_mm`, mm.
    #[serde(default)]
    pub a_geom_mm_err: Option<f64>,
    /// Contact time τc, ms.
    pub tau_c_ms: Option<f64>,
    /// One-sigma error of `tau_c_ms`, ms.
    #[serde(default)]
    pub tau_c_ms_err: Option<f64>,
    /// Time of contact onset, s after the trigger.
    pub t_contact_s: Option<f64>,
    /// One-sigma error of `t_contact_s`, s.
    #[serde(default)]
    pub t_contact_s_err: Option<f64>,
    /// Time of loss of contact, s after the trigger.
    pub t_rebound_s: Option<f64>,
    /// One-sigma error of `t_rebound_s`, s.
    #[serde(default)]
    pub t_rebound_s_err: Option<f64>,
    /// The scale the run was measured at, mm per px (`scale_source` says where it came from).
    pub mm_per_px: Option<f64>,
    /// One-sigma error of `mm_per_px`, mm per px.
    #[serde(default)]
    pub mm_per_px_err: Option<f64>,
    /// The undeformed surface row at the impact column, px.
    pub surface_row_px: Option<f64>,
    /// One-sigma error of `surface_row_px`, with the edge model's systematic, px.
    #[serde(default)]
    pub surface_row_px_err: Option<f64>,
    /// Camera set-up (the manifest's `setup`; empty when none, written `-`).
    #[serde(default, serialize_with = "dash_out", deserialize_with = "dash_in")]
    pub setup: String,
    /// Where `mm_per_px` came from: `given`, `setup_free_fall`, `free_fall`
    /// or `radius` (see `calibrate/scale.rs`).
    #[serde(default, serialize_with = "dash_out", deserialize_with = "dash_in")]
    pub scale_source: String,
    /// The scale from free fall (the set-up's pooled, else the run's own),
    /// whether used or not: a check on a given scale.
    #[serde(default)]
    pub free_fall_mm_per_px: Option<f64>,
    /// One-sigma error of `free_fall_mm_per_px`, mm per px.
    #[serde(default)]
    pub free_fall_mm_per_px_err: Option<f64>,
    /// Apparent (silhouette) radius minus R_mm / mm_per_px, px: a diagnostic
    /// of the optics (a steel ball's rim and halo); empty when the scale is
    /// the radius's.
    #[serde(default)]
    pub edge_offset_px: Option<f64>,
    /// One-sigma error of `edge_offset_px` (with `scale_source` `radius`: the spread of the runs' offsets), px.
    #[serde(default)]
    pub edge_offset_px_err: Option<f64>,
    /// Systematic error of the surface line's edge model, px (in
    /// `surface_row_px_err` and every error that depends on the line).
    #[serde(default)]
    pub surface_model_err_px: Option<f64>,
    /// Where `surface_row_px` came from: `image` (the band's top edge in
    /// the frames before the impact) or `config` (`detect.surface_row_px`).
    #[serde(default, serialize_with = "dash_out", deserialize_with = "dash_in")]
    pub surface_source: String,
    /// Offset (px, positive down) from the image's line of the surface the
    /// trajectory puts under the sphere when fitted with the contact law
    /// and the surface free: a cross-check of the line, never used in its
    /// place (`surface_law_disagreement` when beyond 3σ).
    #[serde(default)]
    pub surface_law_offset_px: Option<f64>,
    /// One-sigma error of `surface_law_offset_px`, px.
    #[serde(default)]
    pub surface_law_offset_px_err: Option<f64>,
    /// The lens's radial distortion k1 (1/px²) undone on the track: the
    /// configuration's (`camera.distortion_k1_per_px2`) or the one the
    /// surface line's bow measures; its error (measured only).
    #[serde(default)]
    pub distortion_k1_per_px2: Option<f64>,
    /// One-sigma error of a measured `distortion_k1_per_px2`, 1/px²; it enters every error as a systematic term.
    #[serde(default)]
    pub distortion_k1_per_px2_err: Option<f64>,
    /// Where the lens came from: `config` (a calibration), `surface_bow`
    /// (measured in the images; its error a systematic term), `bound` (not
    /// measured: `camera.distortion_bound_px` a systematic term) or `none`.
    #[serde(default, serialize_with = "dash_out", deserialize_with = "dash_in")]
    pub distortion_source: String,
    /// Without a calibrated k1: how far the distortion bound
    /// (`camera.distortion_bound_px` at the image corner) moves the scale,
    /// v_impact, δmax and τc; each enters its `_err` as a systematic term
    /// (÷√3, k1 anywhere between ± the bound). See `calibrate/lens.rs`.
    #[serde(default)]
    pub distortion_mm_per_px: Option<f64>,
    /// How far the distortion left unknown changes v_impact, m/s (see `distortion_mm_per_px`).
    #[serde(default)]
    pub distortion_v_impact_m_s: Option<f64>,
    /// How far the distortion left unknown changes δmax, mm (see `distortion_mm_per_px`).
    #[serde(default)]
    pub distortion_delta_max_mm: Option<f64>,
    /// How far the distortion left unknown changes τc, ms (see `distortion_mm_per_px`).
    #[serde(default)]
    pub distortion_tau_c_ms: Option<f64>,
    /// Time of the maximum penetration.
    #[serde(default)]
    pub t_max_s: Option<f64>,
    /// Start of a second contact, when the recording shows one (never mixed
    /// into this drop's numbers).
    #[serde(default)]
    pub second_contact_s: Option<f64>,
    /// Gravity from the pre-contact flight with g free: a check on frame rate and scale.
    #[serde(default)]
    pub g_fit_m_s2: Option<f64>,
    /// One-sigma error of `g_fit_m_s2`, m/s².
    #[serde(default)]
    pub g_fit_m_s2_err: Option<f64>,
    /// Status `tracked` only: the vertical velocity (positive downward) at
    /// the last tracked frame, from its free flight ([`crate::measure::flight`]).
    #[serde(default)]
    pub v_last_m_s: Option<f64>,
    /// One-sigma error of `v_last_m_s`, m/s.
    #[serde(default)]
    pub v_last_m_s_err: Option<f64>,
    /// Status `tracked` only: the time of that last tracked frame.
    #[serde(default)]
    pub t_last_s: Option<f64>,
    /// Contact law F = K·δⁿ fitted to the trajectory: K in SI units (N/mⁿ, δ in m).
    #[serde(default)]
    pub force_k_si: Option<f64>,
    /// Error of `force_k_si`: the Akaike-weighted spread over the contact models, N/mⁿ.
    #[serde(default)]
    pub force_k_si_err: Option<f64>,
    /// The exponent n of F = K·δⁿ (the elastic-foundation model predicts 2).
    #[serde(default)]
    pub force_exponent: Option<f64>,
    /// Error of `force_exponent`: the Akaike-weighted spread over the contact models.
    #[serde(default)]
    pub force_exponent_err: Option<f64>,
    /// K fitted with n held at 2 (N/m²): compare with π E φ R / h.
    #[serde(default)]
    pub force_k2_n_m2: Option<f64>,
    /// One-sigma error of `force_k2_n_m2`, N/m².
    #[serde(default)]
    pub force_k2_n_m2_err: Option<f64>,
    /// The contact model of the law's best fit: `linear` (F = K·δⁿ + c·δ̇),
    /// `hunt_crossley` (F = K·δⁿ·(1 + α·δ̇)), each with `_no_pull` where the
    /// force cannot pull (F ≥ 0). See `force::ContactModel`.
    #[serde(default, serialize_with = "dash_out", deserialize_with = "dash_in")]
    pub force_model: String,
    /// Linear damping c of F = K·δⁿ + c·δ̇ (when `force_model` is linear).
    #[serde(default)]
    pub damping_n_s_m: Option<f64>,
    /// One-sigma error of `damping_n_s_m`, N·s/m.
    #[serde(default)]
    pub damping_n_s_m_err: Option<f64>,
    /// Hunt–Crossley damping α of F = K·δⁿ·(1 + α·δ̇) (when `force_model`
    /// is hunt_crossley).
    #[serde(default)]
    pub hunt_crossley_alpha_s_m: Option<f64>,
    /// One-sigma error of `hunt_crossley_alpha_s_m`, s/m.
    #[serde(default)]
    pub hunt_crossley_alpha_s_m_err: Option<f64>,
    /// How the recording's stored samples became the grey picture measured,
    /// space-separated words ([`crate::source::SourceMeta::reading`]):
    /// `bayer_<pattern>_luminance` or `rgb_luminance` (colour read as grey),
    /// `flip_v`, `flip_h` (recorded viewer flips applied),
    /// `flips_not_applied`, `p10_linear` or `p10_codes`; empty (written `-`)
    /// when the frames were measured as stored.
    #[serde(default, serialize_with = "dash_out", deserialize_with = "dash_in")]
    pub reading: String,
    /// Outcome of the run: measured, flagged, tracked only, failed, or decided in review.
    pub status: DropStatus,
    /// Quality flags, space-separated words ([`crate::measure::quality::FLAGS`]);
    /// empty (written `-`) when nothing weakens the measurement. Any flag makes the
    /// status `warning`, with its sentence in `reason`.
    #[serde(default, serialize_with = "dash_out", deserialize_with = "dash_in")]
    pub flags: String,
    /// Why the run failed, or its warnings; empty (written `-`) when all is well.
    #[serde(default, serialize_with = "dash_out", deserialize_with = "dash_in")]
    pub reason: String,
    /// What `dropscope review` decided about the drop (`review.csv`), in a
    /// few words: rejected, accepted, frames excluded, surface set by hand
    /// ([`crate::dataset::decisions::RunReview::summary`]); empty (written
    /// `-`) when nothing.
    #[serde(default, serialize_with = "dash_out", deserialize_with = "dash_in")]
    pub review: String,
}

fn default_density() -> f64 {
    7800.0
}

impl DropRecord {
    /// A row for a run that could not be measured: every measured column
    /// empty (and the start of a measured row).
    pub fn failed(run: &str, sphere_radius_mm: f64, reason: impl Into<String>) -> Self {
        DropRecord {
            run: run.to_string(),
            sphere_radius_mm,
            sphere_density_kg_m3: default_density(),
            surface: String::new(),
            drop_height_cm: None,
            path: String::new(),
            fps: None,
            fps_source: String::new(),
            v_impact_m_s: None,
            v_impact_m_s_err: None,
            v_rebound_m_s: None,
            v_rebound_m_s_err: None,
            restitution: None,
            restitution_err: None,
            delta_max_mm: None,
            delta_max_mm_err: None,
            a_max_mm: None,
            a_max_mm_err: None,
            a_geom_mm: None,
            a_geom_mm_err: None,
            tau_c_ms: None,
            tau_c_ms_err: None,
            t_contact_s: None,
            t_contact_s_err: None,
            t_rebound_s: None,
            t_rebound_s_err: None,
            mm_per_px: None,
            mm_per_px_err: None,
            surface_row_px: None,
            surface_row_px_err: None,
            setup: String::new(),
            scale_source: String::new(),
            free_fall_mm_per_px: None,
            free_fall_mm_per_px_err: None,
            edge_offset_px: None,
            edge_offset_px_err: None,
            surface_model_err_px: None,
            surface_source: String::new(),
            surface_law_offset_px: None,
            surface_law_offset_px_err: None,
            distortion_k1_per_px2: None,
            distortion_k1_per_px2_err: None,
            distortion_source: String::new(),
            distortion_mm_per_px: None,
            distortion_v_impact_m_s: None,
            distortion_delta_max_mm: None,
            distortion_tau_c_ms: None,
            t_max_s: None,
            second_contact_s: None,
            g_fit_m_s2: None,
            g_fit_m_s2_err: None,
            v_last_m_s: None,
            v_last_m_s_err: None,
            t_last_s: None,
            force_k_si: None,
            force_k_si_err: None,
            force_exponent: None,
            force_exponent_err: None,
            force_k2_n_m2: None,
            force_k2_n_m2_err: None,
            force_model: String::new(),
            damping_n_s_m: None,
            damping_n_s_m_err: None,
            hunt_crossley_alpha_s_m: None,
            hunt_crossley_alpha_s_m_err: None,
            reading: String::new(),
            status: DropStatus::Failed,
            flags: String::new(),
            reason: reason.into(),
            review: String::new(),
        }
    }
}

impl DropRecord {
    /// The numeric columns whose value is not finite (`inf`, `NaN`): none
    /// in a measured row ([`crate::pipeline::process_setup`] fails the run).
    pub fn non_finite_columns(&self) -> Vec<String> {
        const TEXT: [&str; 9] = [
            "run",
            "surface",
            "path",
            "setup",
            "scale_source",
            "surface_source",
            "status",
            "flags",
            "reason",
        ];
        let bytes = csv_bytes([self]);
        let mut r = csv::Reader::from_reader(bytes.as_slice());
        let Ok(header) = r.headers().cloned() else {
            return Vec::new();
        };
        let Some(Ok(row)) = r.records().next() else {
            return Vec::new();
        };
        header
            .iter()
            .zip(row.iter())
            .filter(|(h, v)| !TEXT.contains(h) && v.parse::<f64>().is_ok_and(|x| !x.is_finite()))
            .map(|(h, _)| h.to_string())
            .collect()
    }
}

/// One frame of a drop's track (`tracks/<run>.csv`, SPEC §4). Rows are in
/// frame order; a frame where the sphere was not measured keeps its row with
/// the measured columns empty and `flags` saying why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrackRow {
    /// Camera image number.
    pub frame: i64,
    /// Time of the frame's mid-exposure, relative to the trigger.
    pub t_s: f64,
    /// Centre column.
    pub x_px: Option<f64>,
    /// Centre row (rows grow downward).
    pub z_px: Option<f64>,
    /// Fitted (or held) radius.
    pub r_px: Option<f64>,
    /// RMS distance of the edge points used from the fitted circle.
    pub residual_px: Option<f64>,
    /// Number of edge points used in the fit.
    pub edge_points: usize,
    /// True while the sphere bottom is below the undeformed surface line.
    pub in_contact: bool,
    /// Penetration δ = (z + R − y_s)·s; negative in flight.
    pub delta_mm: Option<f64>,
    /// One-sigma uncertainty of `z_px` from the fit's covariance.
    #[serde(default)]
    pub sigma_z_px: Option<f64>,
    /// One-sigma uncertainty of `x_px` from the same fit.
    #[serde(default)]
    pub sigma_x_px: Option<f64>,
    /// The frame's own circle with its radius free (the silhouette's
    /// apparent radius, pass 1), where fitted; `r_px` is the radius held
    /// for the run.
    #[serde(default)]
    pub r_free_px: Option<f64>,
    /// One-sigma uncertainty of `r_free_px` from its fit's covariance.
    #[serde(default)]
    pub sigma_r_free_px: Option<f64>,
    /// Contact force F = m (g − z̈) from the smoothed trajectory, in contact only.
    #[serde(default)]
    pub force_n: Option<f64>,
    /// Space-separated flags (`missing`, `partial`, `recovered`, …); empty
    /// when clean, written as [`NO_TEXT`].
    #[serde(default, serialize_with = "dash_out", deserialize_with = "dash_in")]
    pub flags: String,
}

/// What a text column holds for none: in a track's `flags` a frame without
/// flags; in drops.csv's `surface`, `path`, `fps_source`, `setup`, `scale_source`,
/// `surface_source`, `distortion_source`, `force_model`, `flags` and
/// `reason` a row without one. A word, never
/// an empty field, so that a reader takes the column as text in every file
/// (pandas reads an all-empty column as float64).
pub const NO_TEXT: &str = "-";

/// A text cell: no control or format character, and nothing a spreadsheet
/// runs as a formula ([`crate::util::text::csv_cell`]).
fn text_out<S: serde::Serializer>(text: &str, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(&crate::util::text::csv_cell(text))
}

/// A text cell back ([`crate::util::text::csv_cell_back`]).
fn text_in<'de, D: serde::Deserializer<'de>>(d: D) -> Result<String, D::Error> {
    let text = String::deserialize(d)?;
    Ok(crate::util::text::csv_cell_back(&text).to_string())
}

/// A text cell that may hold none ([`NO_TEXT`]).
fn dash_out<S: serde::Serializer>(text: &str, s: S) -> Result<S::Ok, S::Error> {
    text_out(if text.is_empty() { NO_TEXT } else { text }, s)
}

/// [`NO_TEXT`] (or an empty field, as written before) reads as none.
fn dash_in<'de, D: serde::Deserializer<'de>>(d: D) -> Result<String, D::Error> {
    let text = String::deserialize(d)?;
    Ok(if text.trim() == NO_TEXT {
        String::new()
    } else {
        crate::util::text::csv_cell_back(&text).to_string()
    })
}

/// Why `drops.csv` could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// The file could not be opened, read or written.
    #[error("{path}: {source}")]
    Io {
        /// The `drops.csv` file.
        path: std::path::PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A row could not be read as a drop record.
    #[error("{path}: row {row}: {source}")]
    Csv {
        /// The `drops.csv` file.
        path: std::path::PathBuf,
        /// The line of the file the row stands on (the header is line 1).
        row: u64,
        /// The CSV reader's error.
        #[source]
        source: csv::Error,
    },
}

/// Serialise rows as CSV bytes, the header from the first row's field names.
/// Floats are written with Rust's shortest round-trip formatting, so the same
/// rows always give the same bytes. Every CSV dropscope writes goes through
/// here (drops.csv, tracks, the manifest).
pub fn csv_bytes<T: Serialize>(rows: impl IntoIterator<Item = T>) -> Vec<u8> {
    let mut bytes = Vec::new();
    write_csv_rows(&mut bytes, rows).expect("serialising plain rows into memory cannot fail");
    bytes
}

/// [`csv_bytes`] written into `out` as they are made (a long movie's track
/// into an [`crate::util::io::Spool`]).
pub fn write_csv_rows<T: Serialize>(
    out: impl std::io::Write,
    rows: impl IntoIterator<Item = T>,
) -> std::io::Result<()> {
    let mut w = csv::Writer::from_writer(out);
    for r in rows {
        w.serialize(r)?;
    }
    w.flush()
}

/// `drops.csv` as bytes (see [`csv_bytes`]).
pub fn to_csv_bytes(records: &[DropRecord]) -> Vec<u8> {
    csv_bytes(records)
}

/// Write `drops.csv` whole or not at all.
pub fn write_csv(path: &Path, records: &[DropRecord]) -> Result<(), DatasetError> {
    crate::util::io::write_atomic(path, &to_csv_bytes(records)).map_err(|source| DatasetError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Read a `drops.csv` (from `process`, or any CSV with those columns, so
/// hand-measured data works too; the `_err` columns and `surface` may be absent).
pub fn read_csv(path: &Path) -> Result<Vec<DropRecord>, DatasetError> {
    // Opened here, not by csv, so that a missing file is an I/O error on
    // the path rather than a CSV error in "row 0".
    let bytes = crate::util::io::read_input(path, crate::util::io::TEXT_INPUT_MAX_BYTES).map_err(
        |source| DatasetError::Io {
            path: path.to_path_buf(),
            source,
        },
    )?;
    let mut rdr = csv::Reader::from_reader(bytes.as_slice());
    let mut out = Vec::new();
    for (i, rec) in rdr.deserialize().enumerate() {
        out.push(rec.map_err(|source| DatasetError::Csv {
            path: path.to_path_buf(),
            row: i as u64 + 2,
            source,
        })?);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `collapse missing.csv` names the file, not a "row 0".
    #[test]
    fn a_missing_file_is_named_without_a_row() {
        let e = read_csv(Path::new("no/such/drops.csv"))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("no/such/drops.csv: No such file"), "{e}");
        assert!(!e.contains("row"), "{e}");
    }

    #[test]
    fn csv_round_trip_keeps_every_field_and_failed_rows() {
        let mut ok = DropRecord::failed("r1", 4.5, "");
        ok.status = DropStatus::Ok;
        ok.v_impact_m_s = Some(1.7155);
        ok.delta_max_mm = Some(0.812_345_678_9);
        ok.surface = "pdms".into();
        ok.flags = "gap_at_peak saturated".into();
        let bad = DropRecord::failed("r2", 3.0, "no sphere found in 40 frames");
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("drops.csv");
        write_csv(&p, &[ok.clone(), bad.clone()]).unwrap();
        let back = read_csv(&p).unwrap();
        assert_eq!(back, vec![ok, bad]);
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.starts_with("run,sphere_radius_mm,"));
        assert!(text.contains(",ok,gap_at_peak saturated,-,-\n"), "{text}");
        assert!(text.contains(",failed,-,no sphere found in 40 frames"));
    }

    /// drops.csv's text columns hold `-` for none, so that a reader takes
    /// them as text even when every row has none (pandas read an all-empty
    /// `flags`, `reason` or `setup` as float64); `-` and an empty field (as
    /// written before) both read back as none.
    #[test]
    fn text_columns_are_never_empty_and_read_back_as_none() {
        let mut ok = DropRecord::failed("r1", 4.5, "");
        ok.status = DropStatus::Ok;
        ok.v_impact_m_s = Some(1.5);
        let rows = [ok, DropRecord::failed("r2", 3.0, "")];
        let bytes = to_csv_bytes(&rows);
        let mut r = csv::Reader::from_reader(bytes.as_slice());
        let header = r.headers().unwrap().clone();
        let text = [
            "surface",
            "path",
            "fps_source",
            "setup",
            "scale_source",
            "surface_source",
            "distortion_source",
            "force_model",
            "flags",
            "reason",
        ];
        let cols: Vec<usize> = text
            .iter()
            .map(|c| header.iter().position(|h| h == *c).expect(c))
            .collect();
        for row in r.records() {
            let row = row.unwrap();
            for (&c, name) in cols.iter().zip(text) {
                assert_eq!(&row[c], NO_TEXT, "{name}");
            }
        }
        let back: Vec<DropRecord> = csv::Reader::from_reader(bytes.as_slice())
            .deserialize()
            .map(Result::unwrap)
            .collect();
        assert_eq!(back, rows);
        let emptied = String::from_utf8(bytes).unwrap().replace(",-", ",");
        let back: Vec<DropRecord> = csv::Reader::from_reader(emptied.as_bytes())
            .deserialize()
            .map(Result::unwrap)
            .collect();
        assert_eq!(back, rows);
    }

    #[test]
    fn hand_made_csv_without_error_columns_reads() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("hand.csv");
        std::fs::write(
            &p,
            "run,sphere_radius_mm,v_impact_m_s,v_rebound_m_s,restitution,delta_max_mm,a_max_mm,a_geom_mm,tau_c_ms,t_contact_s,t_rebound_s,mm_per_px,surface_row_px,status\n\
             a,3.0,1.2,0.9,0.75,0.9,2.1,2.17,4.1,,,,,ok\n",
        )
        .unwrap();
        let r = read_csv(&p).unwrap();
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].tau_c_ms, Some(4.1));
        assert_eq!(r[0].t_contact_s, None);
        assert_eq!(r[0].sphere_density_kg_m3, 7800.0);
    }

    #[test]
    fn non_finite_numbers_are_found_by_column_and_text_is_not() {
        let mut r = DropRecord::failed("inf", 4.5, "NaN");
        r.status = DropStatus::Ok;
        r.v_impact_m_s = Some(1.0);
        r.force_k_si = Some(f64::INFINITY);
        r.restitution = Some(f64::NAN);
        assert_eq!(r.non_finite_columns(), ["restitution", "force_k_si"]);
        r.force_k_si = Some(1.0);
        r.restitution = None;
        assert!(r.non_finite_columns().is_empty());
    }

    #[test]
    fn a_bad_cell_names_the_file_and_row() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.csv");
        std::fs::write(
            &p,
            "run,sphere_radius_mm,v_impact_m_s,v_rebound_m_s,restitution,delta_max_mm,a_max_mm,a_geom_mm,tau_c_ms,t_contact_s,t_rebound_s,mm_per_px,surface_row_px,status\n\
             a,three,1.2,0.9,0.75,0.9,2.1,2.17,4.1,,,,,ok\n",
        )
        .unwrap();
        let e = read_csv(&p).unwrap_err().to_string();
        assert!(e.contains("bad.csv") && e.contains("row 2"), "{e}");
    }
}
