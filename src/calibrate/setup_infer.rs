//! Camera set-ups found from the images, for runs whose manifest row names
//! none (`camera.infer_setups`).
//!
//! Runs filmed through one camera set-up (same zoom, same position) share
//! one scale, and their free flights pooled measure it 10–100× better than
//! a fast drop's own short flight or its apparent radius (see
//! [`crate::calibrate::scale`]). The manifest's `setup` column says which runs do;
//! without it, the images do: a set-up fixes the frame's size, where the
//! surface line lies and how many pixels a millimetre is, and so
//!
//! - the frames have the same size;
//! - the surface lines lie within [`SURFACE_ROW_TOL_PX`] of each other at
//!   the frame's middle column and have the same tilt within
//!   [`SURFACE_SLOPE_TOL`];
//! - the apparent radii, per millimetre of sphere radius, agree within
//!   [`EDGE_SPREAD_PX`] at the sphere's size (the silhouette's edge offset
//!   differs from drop to drop by less) plus [`AGREEMENT_SIGMAS`] of their
//!   statistical errors;
//! - the scales of their own free flights agree within [`AGREEMENT_SIGMAS`]
//!   of their errors (each with its distortion bound's systematic).
//!
//! Runs are grouped so that every member of a group agrees with every
//! other (complete linkage), the most precise free flights first; a run
//! that agrees with two groups joins neither (its set-up is not decided by
//! the images), so two set-ups are never joined through it. A group of two
//! runs or more is a set-up, named `auto<k>` in the order of its first run.
//!
//! What the test cannot tell apart: two set-ups whose surface rows lie
//! within 3 px, whose tilts agree and whose scales differ by less than
//! about 0.6 % at the slow drops' free-fall precision. In a campaign filmed
//! that way give the `setup` column, or set `camera.infer_setups = false`.

use serde::{Deserialize, Serialize};

/// Surface lines of one set-up lie within this of each other (px) at the
/// frame's middle column: the image's line moves by up to 2.5 px from drop to
/// drop with the band top's look (a glossy strip, a darker or brighter top
/// row; measured on 120 `--preset real` drops of 20 set-ups).
pub const SURFACE_ROW_TOL_PX: f64 = 3.0;

/// Surface lines of one set-up have the same tilt within this (rows per
/// column, 0.14°): measured within 1.3e-3 of each other in the 20 set-ups of
/// 120 `--preset real` drops (whose rolls are drawn within ±0.5°, ±8.7e-3).
pub const SURFACE_SLOPE_TOL: f64 = 2.5e-3;

/// The silhouette's edge offset (a polished ball's light rim and halo)
/// differs between drops of one set-up by up to this (px): 0.1–0.5 px small
/// on realistic footage, 0.46 px at most between two drops of one set-up
/// on 120 `--preset real` drops.
pub const EDGE_SPREAD_PX: f64 = 0.5;

/// Statistical disagreement tolerated, in combined standard errors.
pub const AGREEMENT_SIGMAS: f64 = 4.0;

/// What a run's images say of its camera set-up.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SceneSignature {
    /// Frame width, px.
    pub width_px: usize,
    /// Frame height, px.
    pub height_px: usize,
    /// The surface line's row at the middle column and its tilt.
    pub surface_row_px: f64,
    /// The surface line's tilt, rows per column.
    pub surface_slope: f64,
    /// The sphere's apparent radius and its statistical error.
    pub r_app_px: f64,
    /// Statistical error of `r_app_px`, px.
    pub r_app_err_px: f64,
    /// The sphere's radius from the manifest, mm.
    pub radius_mm: f64,
    /// The scale of the run's own free flights and its one-sigma error
    /// (statistical and the distortion bound's), mm/px.
    pub free_fall_mm_per_px: Option<(f64, f64)>,
}

impl SceneSignature {
    /// Apparent pixels per millimetre of sphere radius.
    fn px_per_mm(&self) -> f64 {
        self.r_app_px / self.radius_mm
    }

    /// Whether `self` and `other` can be one camera set-up (module doc).
    pub fn agrees_with(&self, other: &SceneSignature) -> bool {
        let (a, b) = (self, other);
        if (a.width_px, a.height_px) != (b.width_px, b.height_px) {
            return false;
        }
        if (a.surface_row_px - b.surface_row_px).abs() > SURFACE_ROW_TOL_PX
            || (a.surface_slope - b.surface_slope).abs() > SURFACE_SLOPE_TOL
        {
            return false;
        }
        let (qa, qb) = (a.px_per_mm(), b.px_per_mm());
        let rel = |r: f64, e: f64| e / r;
        let tol = EDGE_SPREAD_PX / a.r_app_px.min(b.r_app_px)
            + AGREEMENT_SIGMAS
                * rel(a.r_app_px, a.r_app_err_px).hypot(rel(b.r_app_px, b.r_app_err_px));
        if ((qa - qb) / (0.5 * (qa + qb))).abs() > tol {
            return false;
        }
        match (a.free_fall_mm_per_px, b.free_fall_mm_per_px) {
            (Some((sa, ea)), Some((sb, eb))) => (sa - sb).abs() <= AGREEMENT_SIGMAS * ea.hypot(eb),
            _ => true,
        }
    }

    /// Every number finite (a scene that is not is never grouped: NaN would
    /// pass every "beyond tolerance" test).
    fn is_finite(&self) -> bool {
        [
            self.surface_row_px,
            self.surface_slope,
            self.r_app_px,
            self.r_app_err_px,
            self.radius_mm,
        ]
        .iter()
        .all(|v| v.is_finite())
            && self.r_app_px > 0.0
            && self.radius_mm > 0.0
            && self
                .free_fall_mm_per_px
                .is_none_or(|(s, e)| s.is_finite() && e.is_finite() && s > 0.0)
    }

    /// Relative error of the free-fall scale (infinite without one).
    fn free_fall_rel_err(&self) -> f64 {
        self.free_fall_mm_per_px
            .map_or(f64::INFINITY, |(s, e)| e / s)
    }
}

/// Group runs by set-up (module doc). `signatures[i]` is run i's, `None`
/// for a run whose images could not be read (it stays alone). Returns the
/// groups of two runs or more, each in the runs' order, groups in the order
/// of their first run.
pub fn infer_groups(signatures: &[Option<SceneSignature>]) -> Vec<Vec<usize>> {
    let mut order: Vec<usize> = (0..signatures.len())
        .filter(|&i| signatures[i].is_some_and(|s| s.is_finite()))
        .collect();
    let sig = |i: usize| signatures[i].as_ref().expect("filtered to Some");
    order.sort_by(|&i, &j| {
        sig(i)
            .free_fall_rel_err()
            .total_cmp(&sig(j).free_fall_rel_err())
            .then(i.cmp(&j))
    });
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for i in order {
        let fits: Vec<usize> = (0..groups.len())
            .filter(|&g| groups[g].iter().all(|&m| sig(i).agrees_with(sig(m))))
            .collect();
        match fits[..] {
            [g] => groups[g].push(i),
            _ => groups.push(vec![i]),
        }
    }
    let mut groups: Vec<Vec<usize>> = groups.into_iter().filter(|g| g.len() >= 2).collect();
    for g in &mut groups {
        g.sort_unstable();
    }
    groups.sort_by_key(|g| g[0]);
    groups
}

/// A name `auto<k>` for the k-th inferred set-up (from 1), not among
/// `taken` (the manifest's own set-up names).
pub fn setup_name(k: usize, taken: &[&str]) -> String {
    let mut name = format!("auto{k}");
    while taken.contains(&name.as_str()) {
        name.push('_');
    }
    name
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run of a set-up with surface row `row`, `px_per_mm` apparent
    /// pixels per mm of a 4 mm sphere and free-fall scale `1 / px_per_mm`
    /// with relative error `ff_rel`.
    fn run(row: f64, px_per_mm: f64, ff_rel: Option<f64>) -> Option<SceneSignature> {
        let s = 1.0 / px_per_mm;
        Some(SceneSignature {
            width_px: 512,
            height_px: 384,
            surface_row_px: row,
            surface_slope: 1e-3,
            r_app_px: 4.0 * px_per_mm,
            r_app_err_px: 0.01,
            radius_mm: 4.0,
            free_fall_mm_per_px: ff_rel.map(|r| (s, s * r)),
        })
    }

    #[test]
    fn runs_of_one_setup_group_and_other_setups_stay_apart() {
        let sigs = vec![
            run(280.0, 20.0, Some(1e-4)),
            run(281.5, 20.02, Some(5e-3)),
            run(300.0, 20.0, Some(1e-4)), // another row: another set-up
            run(279.0, 20.0 * 1.03, Some(1e-4)), // another zoom
            run(282.0, 19.99, None),
            run(301.0, 20.01, Some(2e-4)),
        ];
        assert_eq!(infer_groups(&sigs), vec![vec![0, 1, 4], vec![2, 5]]);
    }

    #[test]
    fn precise_free_falls_that_disagree_are_two_setups() {
        // Same row and apparent size, scales 0.2 % apart at 1e-4: two zooms
        // the silhouette cannot tell apart, free fall can.
        let mut b = run(280.0, 20.0, Some(1e-4)).unwrap();
        b.free_fall_mm_per_px = Some((0.05 * 1.002, 0.05 * 1e-4));
        let sigs = vec![run(280.0, 20.0, Some(1e-4)), Some(b)];
        assert!(infer_groups(&sigs).is_empty());
    }

    #[test]
    fn a_run_that_fits_two_setups_joins_neither() {
        // Two set-ups 0.3 % apart in scale, told apart by their precise
        // free falls; a fast drop between them (1 % own free fall) fits both.
        let mut b = run(280.0, 20.0 * 1.003, Some(1e-4)).unwrap();
        b.free_fall_mm_per_px = Some((0.05 / 1.003, 0.05e-4));
        let sigs = vec![
            run(280.0, 20.0, Some(1e-4)),
            Some(b),
            run(280.5, 20.03, Some(1e-2)),
            run(280.2, 20.0, Some(2e-4)),
        ];
        assert_eq!(infer_groups(&sigs), vec![vec![0, 3]]);
    }

    #[test]
    fn unreadable_runs_and_other_frame_sizes_stay_alone() {
        let mut wide = run(280.0, 20.0, Some(1e-4)).unwrap();
        wide.width_px = 1280;
        let mut nan = run(280.0, 20.0, Some(1e-4)).unwrap();
        nan.surface_row_px = f64::NAN;
        let sigs = vec![run(280.0, 20.0, Some(1e-4)), None, Some(wide), Some(nan)];
        assert!(infer_groups(&sigs).is_empty());
    }

    #[test]
    fn names_avoid_the_manifests_own() {
        assert_eq!(setup_name(1, &[]), "auto1");
        assert_eq!(setup_name(2, &["auto2", "auto2_"]), "auto2__");
    }
}
