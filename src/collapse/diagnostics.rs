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
use crate::util::lsq::RowQr;
use crate::util::records::{Put, Record, Records, Take};

/// z(t) = c0 + c1 (t − t0) + c2 (t − t0)², z in px, t in s.
#[derive(Debug, Clone, PartialEq)]
pub struct FlightFit {
    /// The expansion time t0, s.
    pub t0_s: f64,
    /// c0 (px), c1 (px/s), c2 (px/s²).
    pub coef: [f64; 3],
    /// Times of the first and last frame used.
    pub t_range_s: [f64; 2],
}

impl FlightFit {
    /// z at time `t` (s), px.
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
    /// The run's name.
    pub run: String,
    /// Number of contact frames the law was fitted on.
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
    /// Time of the frame, s after the trigger.
    pub t_s: f64,
    /// Sphere centre row, px; `None` where the frame has no centre.
    pub z_px: Option<f64>,
    /// Penetration δ, mm (negative: the clearance above the surface).
    pub delta_mm: Option<f64>,
    /// Contact force F = m (g − z̈) from the smoothed trajectory, N; in contact only.
    pub force_n: Option<f64>,
    /// Whether the frame is in contact.
    pub in_contact: bool,
}

/// A sample as the bits of its fields: its time, each optional value as a
/// flag and a number, the contact flag (36 bytes).
impl Record for TrackSample {
    const BYTES: usize = 8 + 3 * 9 + 1;

    fn put(&self, out: &mut Vec<u8>) {
        let mut p = Put(out);
        p.f64(self.t_s);
        for v in [self.z_px, self.delta_mm, self.force_n] {
            p.u8(u8::from(v.is_some()));
            p.f64(v.unwrap_or(0.0));
        }
        p.u8(u8::from(self.in_contact));
    }

    fn get(b: &[u8]) -> Self {
        let mut t = Take(b);
        let t_s = t.f64();
        let mut value = || {
            let some = t.u8() == 1;
            let v = t.f64();
            some.then_some(v)
        };
        let (z_px, delta_mm, force_n) = (value(), value(), value());
        TrackSample {
            t_s,
            z_px,
            delta_mm,
            force_n,
            in_contact: t.u8() == 1,
        }
    }
}

/// The columns of a track file's row ([`TrackRow`]) that a sample takes,
/// read by name; the others are not parsed (a long movie's figures read
/// its whole track back).
#[derive(serde::Deserialize)]
struct SampleColumns {
    t_s: f64,
    z_px: Option<f64>,
    in_contact: bool,
    delta_mm: Option<f64>,
    #[serde(default)]
    force_n: Option<f64>,
}

impl TrackSample {
    fn of(r: &SampleColumns) -> TrackSample {
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
/// fit and no panel), in memory up to [`SAMPLES_IN_MEMORY_MAX`] of them,
/// past it in a temporary file, walked as they are used; and the range of
/// every frame's time in ms (the time axis when no frame has a centre).
#[derive(Debug)]
pub struct TrackSamples {
    /// The rows' samples, in the track's order.
    pub samples: Records<TrackSample>,
    /// The least and greatest `t_s · 1e3` over all rows (±∞ for none).
    pub all_t_ms: [f64; 2],
}

/// The most samples of a track held in memory (2 MB); a longer track's go
/// to a temporary file (`TMPDIR`): more than any drop of the e2e bench's
/// data has (the 31 166-frame movie: 15 091).
pub const SAMPLES_IN_MEMORY_MAX: usize = 1 << 15;

/// Read a track file as [`TrackSamples`], one row at a time: a long movie's
/// track read back whole was its largest allocation (22 MB for 124 166
/// frames). Every row is read and checked as by [`read_track`]; the error
/// names the file and the CSV row.
pub fn read_track_samples(path: &Path) -> Result<TrackSamples, String> {
    read_track_samples_within(path, SAMPLES_IN_MEMORY_MAX)
}

/// [`read_track_samples`] with at most `memory_max` samples in memory.
pub fn read_track_samples_within(path: &Path, memory_max: usize) -> Result<TrackSamples, String> {
    let mut rdr = csv::Reader::from_path(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let held = |e: std::io::Error| {
        format!(
            "{}: cannot hold its samples in a temporary file: {e}",
            path.display()
        )
    };
    let mut samples = Records::new(memory_max);
    let mut all_t_ms = [f64::INFINITY, f64::NEG_INFINITY];
    for (i, r) in rdr.deserialize::<SampleColumns>().enumerate() {
        let r = r.map_err(|e| format!("{}: row {}: {e}", path.display(), i + 2))?;
        let t_ms = r.t_s * 1e3;
        all_t_ms = [all_t_ms[0].min(t_ms), all_t_ms[1].max(t_ms)];
        if r.z_px.is_some() || r.delta_mm.is_some() || r.in_contact {
            samples.push(TrackSample::of(&r)).map_err(held)?;
        }
    }
    samples.flush().map_err(held)?;
    Ok(TrackSamples { samples, all_t_ms })
}

/// One drop's track and what was fitted to it.
#[derive(Debug)]
pub struct DropDiagnostics {
    /// The run's name.
    pub run: String,
    /// The track file, `tracks/<run>.csv`.
    pub track_path: PathBuf,
    /// The track's samples.
    pub track: TrackSamples,
    /// Contact onset from drops.csv, s after the trigger.
    pub t_contact_s: Option<f64>,
    /// Loss of contact from drops.csv, s after the trigger.
    pub t_rebound_s: Option<f64>,
    /// The free-flight parabola before contact.
    pub flight_in: Option<FlightFit>,
    /// The free-flight parabola after the rebound.
    pub flight_out: Option<FlightFit>,
    /// The force law F = K δⁿ, from drops.csv or fitted to the track's table.
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

/// The most points of a flight fitted by one QR of them
/// ([`weighted_poly_fit`]); a longer flight (every later bounce of a long
/// movie) is fitted a row at a time ([`quadratic_by_rows`]).
const FLIGHT_FIT_IN_MEMORY_MAX: usize = 1 << 14;

/// The parabola through the samples `rows()` walks (with a centre), in
/// τ = t − t0.
fn flight<I: Iterator<Item = TrackSample>>(rows: impl Fn() -> I, t0: f64) -> Option<FlightFit> {
    let pts = || rows().filter_map(move |r| r.z_px.map(|z| (r.t_s - t0, z)));
    let n = pts().count();
    if n < 4 {
        return None;
    }
    let coef = if n <= FLIGHT_FIT_IN_MEMORY_MAX {
        let (t, z): (Vec<f64>, Vec<f64>) = pts().unzip();
        let f = weighted_poly_fit(&t, &z, None, 2)?;
        [f.coef[0], f.coef[1], f.coef[2]]
    } else {
        quadratic_by_rows(pts)?
    };
    let (first, last) = (pts().next()?.0, pts().last()?.0);
    Some(FlightFit {
        t0_s: t0,
        coef,
        t_range_s: [first + t0, last + t0],
    })
}

/// The coefficients of [`weighted_poly_fit`]`(x, y, None, 2)` of the points
/// `points()` walks, fed a row at a time ([`RowQr`]): the same least squares
/// in the same scaled variable, to rounding, without holding the points.
fn quadratic_by_rows<I: Iterator<Item = (f64, f64)>>(points: impl Fn() -> I) -> Option<[f64; 3]> {
    if points().any(|(x, y)| !(x.is_finite() && y.is_finite())) {
        return None;
    }
    let scale = points().fold(0.0f64, |m, (x, _)| m.max(x.abs()));
    let scale = if scale.is_finite() && scale > 0.0 {
        scale
    } else {
        1.0
    };
    let mut rows = RowQr::<3>::default();
    for (x, y) in points() {
        let u = x / scale;
        rows.push([1.0, u, u.powi(2)], y);
    }
    // As weighted_lsq's rank check: no diagonal of R at or below 1e-13 of the largest.
    let diagonal = [0, 1, 2].map(|i| rows.r[i][i].abs());
    let rmax = diagonal.iter().copied().fold(0.0, f64::max);
    if rmax.is_nan() || rmax <= 0.0 || diagonal.iter().any(|d| *d <= rmax * 1e-13) {
        return None;
    }
    let r = &rows.r;
    let c2 = rows.qty[2] / r[2][2];
    let c1 = (rows.qty[1] - r[1][2] * c2) / r[1][1];
    let c0 = (rows.qty[0] - r[0][1] * c1 - r[0][2] * c2) / r[0][0];
    Some([c0, c1 / scale, c2 / scale.powi(2)])
}

/// Fit F = K δⁿ to the contact frames of a track.
pub fn force_law(
    run: &str,
    rows: impl Iterator<Item = TrackSample>,
    model_k_n_per_mm2: f64,
) -> Option<ForceLaw> {
    let (x, y): (Vec<f64>, Vec<f64>) = rows
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
    let last_contact = rows.iter().filter(|r| r.in_contact).last().map(|r| r.t_s);
    let t_in = rec.t_contact_s.or(first_contact);
    let t_out = rec.t_rebound_s.or(last_contact);
    let before = || {
        rows.iter()
            .filter(move |r| !r.in_contact && t_in.is_some_and(|t| r.t_s < t))
    };
    let after = || {
        rows.iter()
            .filter(move |r| !r.in_contact && t_out.is_some_and(|t| r.t_s > t))
    };
    let r_m = rec.sphere_radius_mm * 1e-3;
    let model_k = std::f64::consts::PI * surface.modulus_pa * surface.solid_fraction * r_m
        / surface.pillar_height_m
        * 1e-6;
    let d = DropDiagnostics {
        run: rec.run.clone(),
        track_path: track_path.to_path_buf(),
        flight_in: t_in.and_then(|t| flight(before, t)),
        flight_out: t_out.and_then(|t| flight(after, t)),
        force_law: record_force_law(rec, rows.iter().filter(|r| r.in_contact).count(), model_k)
            .or_else(|| force_law(&rec.run, rows.iter(), model_k)),
        t_contact_s: t_in,
        t_rebound_s: t_out,
        track,
    };
    // The fits walked the samples (from their file, past its budget): none
    // failed to be read.
    d.track
        .samples
        .check()
        .map_err(|e| format!("{}: {e}", track_path.display()))?;
    Ok(d)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sample in contact at penetration `delta_mm`.
    fn sample(t: f64, delta_mm: f64, force: Option<f64>) -> TrackSample {
        TrackSample {
            t_s: t,
            z_px: Some(200.0 + delta_mm * 20.0),
            delta_mm: Some(delta_mm),
            force_n: force,
            in_contact: delta_mm > 0.0,
        }
    }

    #[test]
    fn a_long_flight_fitted_a_row_at_a_time_agrees_with_one_qr() {
        // 40 000 points of a parabola with noise, in seconds about a
        // contact (as a long movie's later bounces).
        let pts: Vec<(f64, f64)> = (0..40_000)
            .map(|i| {
                let t = 1e-3 + i as f64 / 60_000.0;
                let noise = 0.05 * ((i * 7919 % 13) as f64 / 6.0 - 1.0);
                (t, 120.0 - 800.0 * t + 61_000.0 * t * t + noise)
            })
            .collect();
        let (x, y): (Vec<f64>, Vec<f64>) = pts.iter().copied().unzip();
        let whole = weighted_poly_fit(&x, &y, None, 2).unwrap();
        let rows = quadratic_by_rows(|| pts.iter().copied()).unwrap();
        for k in 0..3 {
            assert!(
                (rows[k] / whole.coef[k] - 1.0).abs() < 1e-9,
                "{k}: {rows:?} {:?}",
                whole.coef
            );
        }
        // And the flight fit of so many samples takes that path.
        let samples: Vec<TrackSample> = pts
            .iter()
            .map(|&(t, z)| TrackSample {
                t_s: t,
                z_px: Some(z),
                delta_mm: None,
                force_n: None,
                in_contact: false,
            })
            .collect();
        let f = flight(|| samples.iter().copied(), 0.0).unwrap();
        assert_eq!(f.coef, rows);
        assert_eq!(f.t_range_s, [x[0], x[x.len() - 1]]);
        assert!(quadratic_by_rows(|| [(0.0, 1.0), (0.0, 2.0), (0.0, 3.0)].into_iter()).is_none());
    }

    #[test]
    fn exact_force_law_is_recovered() {
        // F = 3.5 δ^2 (N, mm): n = 2 and K = 3.5 to round-off.
        let rows: Vec<TrackSample> = (1..20)
            .map(|i| {
                let d = 0.05 * i as f64;
                sample(i as f64 * 1e-4, d, Some(3.5 * d * d))
            })
            .collect();
        let f = force_law("r", rows.into_iter(), 1.0).unwrap();
        assert!((f.n.value - 2.0).abs() < 1e-9);
        assert!((f.k_n_per_mm_pow_n.value - 3.5).abs() < 1e-9);
        assert_eq!(f.n_points, 19);
    }
}
