//! Per-drop diagnostics from `tracks/<run>.csv` (SPEC §4), when it exists
//! beside drops.csv: the free-flight parabolas before and after contact, and
//! the force law F = K δⁿ fitted to the contact force.
//!
//! The model of Chastel et al. (Maruoka 2019, text above Eq. (1b)) predicts
//! F = π E φ R δ² / h, i.e. n = 2 and K = π E φ R / h.

use serde::Serialize;
use std::path::{Path, PathBuf};

use super::fit::Estimate;
use super::stats::weighted_poly_fit;
use crate::config::Surface;
use crate::dataset::{DropRecord, TrackRow};

/// z(t) = c0 + c1 (t − t0) + c2 (t − t0)², z in px, t in s.
#[derive(Debug, Clone, PartialEq)]
pub struct FlightFit {
    pub t0_s: f64,
    pub coef: [f64; 3],
    /// Times of the first and last frame used.
    pub t_range_s: [f64; 2],
}

impl FlightFit {
    pub fn eval(&self, t: f64) -> f64 {
        let u = t - self.t0_s;
        self.coef[0] + u * (self.coef[1] + u * self.coef[2])
    }
}

/// F = K δⁿ (F in N, δ in mm) fitted by least squares on ln F = ln K + n ln δ
/// over contact frames with δ > 0 and F > 0 (unweighted: the track has no
/// force uncertainty).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ForceLaw {
    pub run: String,
    pub n_points: usize,
    /// The exponent n (model: 2).
    pub n: Estimate,
    /// K in N/mmⁿ.
    pub k_n_per_mm_pow_n: Estimate,
    /// The model's K = π E φ R / h in N/mm² (for n = 2).
    pub model_k_n_per_mm2: f64,
    /// Where the law comes from: `trajectory` (the fit of the equation of
    /// motion that `process` wrote to drops.csv, free of smoothing bias) or
    /// `table` (a fit of the track's F(δ) table here, for drops.csv files
    /// without those columns).
    pub source: &'static str,
}

/// What the diagnostics and the drop figure use of one track row: its time,
/// centre row, penetration, force and contact flag (64 bytes; a whole
/// [`TrackRow`] read back is 168 and its flags' text).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackSample {
    pub t_s: f64,
    pub z_px: Option<f64>,
    pub delta_mm: Option<f64>,
    pub force_n: Option<f64>,
    pub in_contact: bool,
}

impl TrackSample {
    fn of(r: &TrackRow) -> TrackSample {
        TrackSample {
            t_s: r.t_s,
            z_px: r.z_px,
            delta_mm: r.delta_mm,
            force_n: r.force_n,
            in_contact: r.in_contact,
        }
    }
}

/// A track as its figure and fits use it: the samples of the frames with a
/// centre, a penetration or contact (a frame without any of them is in no
/// fit and no panel), and the range of every frame's time in ms (the time
/// axis when no frame has a centre).
#[derive(Debug, Clone, PartialEq)]
pub struct TrackSamples {
    pub samples: Vec<TrackSample>,
    /// The least and greatest `t_s · 1e3` over all rows (±∞ for none).
    pub all_t_ms: [f64; 2],
}

/// Read a track file as [`TrackSamples`], one row at a time: a long movie's
/// track read back whole was its largest allocation (22 MB for 124 166
/// frames). Every row is read and checked as by [`read_track`]; the error
/// names the file and the CSV row.
pub fn read_track_samples(path: &Path) -> Result<TrackSamples, String> {
    let mut rdr = csv::Reader::from_path(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut samples = Vec::new();
    let mut all_t_ms = [f64::INFINITY, f64::NEG_INFINITY];
    for (i, r) in rdr.deserialize::<TrackRow>().enumerate() {
        let r = r.map_err(|e| format!("{}: row {}: {e}", path.display(), i + 2))?;
        let t_ms = r.t_s * 1e3;
        all_t_ms = [all_t_ms[0].min(t_ms), all_t_ms[1].max(t_ms)];
        if r.z_px.is_some() || r.delta_mm.is_some() || r.in_contact {
            samples.push(TrackSample::of(&r));
        }
    }
    samples.shrink_to_fit();
    Ok(TrackSamples { samples, all_t_ms })
}

/// One drop's track and what was fitted to it.
#[derive(Debug, Clone, PartialEq)]
pub struct DropDiagnostics {
    pub run: String,
    pub track_path: PathBuf,
    pub track: TrackSamples,
    pub t_contact_s: Option<f64>,
    pub t_rebound_s: Option<f64>,
    pub flight_in: Option<FlightFit>,
    pub flight_out: Option<FlightFit>,
    pub force_law: Option<ForceLaw>,
}

/// Read a track file; the error names the file and the CSV row.
pub fn read_track(path: &Path) -> Result<Vec<TrackRow>, String> {
    let mut rdr = csv::Reader::from_path(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut out = Vec::new();
    for (i, r) in rdr.deserialize().enumerate() {
        out.push(r.map_err(|e| format!("{}: row {}: {e}", path.display(), i + 2))?);
    }
    Ok(out)
}

fn flight(rows: &[&TrackSample], t0: f64) -> Option<FlightFit> {
    let pts: Vec<(f64, f64)> = rows
        .iter()
        .filter_map(|r| r.z_px.map(|z| (r.t_s - t0, z)))
        .collect();
    if pts.len() < 4 {
        return None;
    }
    let t: Vec<f64> = pts.iter().map(|p| p.0).collect();
    let z: Vec<f64> = pts.iter().map(|p| p.1).collect();
    let f = weighted_poly_fit(&t, &z, None, 2)?;
    Some(FlightFit {
        t0_s: t0,
        coef: [f.coef[0], f.coef[1], f.coef[2]],
        t_range_s: [t[0] + t0, t[t.len() - 1] + t0],
    })
}

/// Fit F = K δⁿ to the contact frames of a track.
pub fn force_law(run: &str, rows: &[TrackSample], model_k_n_per_mm2: f64) -> Option<ForceLaw> {
    let (x, y): (Vec<f64>, Vec<f64>) = rows
        .iter()
        .filter(|r| r.in_contact)
        .filter_map(|r| match (r.delta_mm, r.force_n) {
            (Some(d), Some(f)) if d > 0.0 && f > 0.0 => Some((d.ln(), f.ln())),
            _ => None,
        })
        .unzip();
    let f = weighted_poly_fit(&x, &y, None, 1)?;
    let k = f.coef[0].exp();
    Some(ForceLaw {
        run: run.to_string(),
        n_points: x.len(),
        n: Estimate {
            value: f.coef[1],
            stderr: f.stderr(1),
            ci95: None,
        },
        k_n_per_mm_pow_n: Estimate {
            value: k,
            stderr: f.stderr(0).map(|s| k * s),
            ci95: None,
        },
        model_k_n_per_mm2,
        source: "table",
    })
}

/// The law `process` fitted to the trajectory, from the record, with K
/// converted to N/mmⁿ (F = K_SI·(δ_mm·10⁻³)ⁿ).
fn record_force_law(rec: &DropRecord, n_points: usize, model_k_n_per_mm2: f64) -> Option<ForceLaw> {
    let (n, k) = (rec.force_exponent?, rec.force_k_si?);
    let to_mm = 1e-3f64.powf(n);
    Some(ForceLaw {
        run: rec.run.clone(),
        n_points,
        n: Estimate {
            value: n,
            stderr: rec.force_exponent_err,
            ci95: None,
        },
        k_n_per_mm_pow_n: Estimate {
            value: k * to_mm,
            stderr: rec.force_k_si_err.map(|e| e * to_mm),
            ci95: None,
        },
        model_k_n_per_mm2,
        source: "trajectory",
    })
}

/// Diagnostics for one record whose track is at `track_path`.
pub fn diagnose(
    rec: &DropRecord,
    surface: &Surface,
    track_path: &Path,
) -> Result<DropDiagnostics, String> {
    let track = read_track_samples(track_path)?;
    let rows = &track.samples;
    let first_contact = rows.iter().find(|r| r.in_contact).map(|r| r.t_s);
    let last_contact = rows.iter().rev().find(|r| r.in_contact).map(|r| r.t_s);
    let t_in = rec.t_contact_s.or(first_contact);
    let t_out = rec.t_rebound_s.or(last_contact);
    let before: Vec<&TrackSample> = rows
        .iter()
        .filter(|r| !r.in_contact && t_in.is_some_and(|t| r.t_s < t))
        .collect();
    let after: Vec<&TrackSample> = rows
        .iter()
        .filter(|r| !r.in_contact && t_out.is_some_and(|t| r.t_s > t))
        .collect();
    let r_m = rec.sphere_radius_mm * 1e-3;
    let model_k = std::f64::consts::PI * surface.modulus_pa * surface.solid_fraction * r_m
        / surface.pillar_height_m
        * 1e-6;
    Ok(DropDiagnostics {
        run: rec.run.clone(),
        track_path: track_path.to_path_buf(),
        flight_in: t_in.and_then(|t| flight(&before, t)),
        flight_out: t_out.and_then(|t| flight(&after, t)),
        force_law: record_force_law(rec, rows.iter().filter(|r| r.in_contact).count(), model_k)
            .or_else(|| force_law(&rec.run, rows, model_k)),
        t_contact_s: t_in,
        t_rebound_s: t_out,
        track,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(t: f64, delta_mm: f64, force: Option<f64>) -> TrackRow {
        TrackRow {
            frame: 0,
            t_s: t,
            x_px: Some(100.0),
            z_px: Some(200.0 + delta_mm * 20.0),
            r_px: Some(90.0),
            residual_px: Some(0.05),
            edge_points: 300,
            in_contact: delta_mm > 0.0,
            delta_mm: Some(delta_mm),
            sigma_z_px: None,
            force_n: force,
            flags: String::new(),
        }
    }

    #[test]
    fn exact_force_law_is_recovered() {
        // F = 3.5 δ^2 (N, mm): n = 2 and K = 3.5 to round-off.
        let rows: Vec<TrackSample> = (1..20)
            .map(|i| {
                let d = 0.05 * i as f64;
                TrackSample::of(&row(i as f64 * 1e-4, d, Some(3.5 * d * d)))
            })
            .collect();
        let f = force_law("r", &rows, 1.0).unwrap();
        assert!((f.n.value - 2.0).abs() < 1e-9);
        assert!((f.k_n_per_mm_pow_n.value - 3.5).abs() < 1e-9);
        assert_eq!(f.n_points, 19);
    }
}
