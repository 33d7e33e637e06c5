//! The scale s (mm/px) of a run and where it came from (SPEC §2, Calibration).
//!
//! In order of preference:
//! 1. **given** — the manifest's `mm_per_px`, else `camera.mm_per_px`
//!    (a calibration target); taken as exact for lengths; the speeds take
//!    precise free fall's magnification where it disagrees
//!    ([`Scale::for_speeds`]: lens distortion);
//! 2. **setup free fall** — the frame rate is exact, so the curvature of the
//!    free flight in px/s² against g gives s = g / z̈_px; runs that the
//!    manifest's `setup` column puts on one camera set-up share one scale,
//!    and their curvatures are pooled (weighted mean, error scaled by the
//!    pool's √χ²_red when above 1);
//! 3. **free fall** — the run's own flights; 2 and 3 only where more
//!    precise than 4 (a set-up of fast drops only pools flights of a few
//!    frames each, 1–5 %);
//! 4. **radius** — R_mm / R_px, the last resort: a polished ball's
//!    silhouette is not its outline (a light rim inside, a halo outside), so
//!    the apparent radius is off by a fraction of a pixel. Where the job's
//!    other runs measured that offset (their own precise free falls, see
//!    [`EdgeOffset`]) the apparent radius is corrected by their mean and
//!    carries their spread; else the offset, [`EDGE_OFFSET_SYSTEMATIC_PX`],
//!    is carried as a systematic error.
//!
//! With 1–3 the sphere's true radius in pixels is R_mm / s, its bottom is
//! z_c + R_mm / s, and `edge_offset_px` = R_px − R_mm / s is reported as a
//! diagnostic of the optics. The circle fits keep the apparent radius (the
//! silhouette's own size), so the fitted centre stays unbiased.

use super::free_fall::Curvature;

/// One-sigma systematic error of the apparent radius as the sphere's true
/// radius (px): polished steel balls in backlight measure 0.1–0.5 px small.
pub const EDGE_OFFSET_SYSTEMATIC_PX: f64 = 0.3;

/// The silhouette's edge offset (apparent minus true radius, px) that runs
/// scaled by their apparent radius are corrected by, and its one-sigma
/// spread from drop to drop: given (`camera.edge_offset_px`) or measured
/// on the job's runs whose own free fall is precise ([`EdgeOffset::measure`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct EdgeOffset {
    /// The edge offset, apparent minus true radius, px.
    pub offset_px: f64,
    /// Its one-sigma spread from drop to drop, px.
    pub spread_px: f64,
}

/// A run's own free fall measures its edge offset when its scale is this
/// precise (relative): 1e-3 of an 80 px radius is 0.08 px.
pub const EDGE_OFFSET_FREE_FALL_REL_ERR: f64 = 1e-3;

/// Fewest such runs to measure a job's edge offset from.
pub const EDGE_OFFSET_MIN_RUNS: usize = 3;

/// The least drop-to-drop standard deviation assumed for a measured edge
/// offset (px), before it is widened for the runs' number: a few runs of
/// one look can agree by chance more closely than the next drop will
/// (three drops of `--preset real` within 0.003 px of each other, the
/// fourth 0.13 px off; over 120 drops of their own set-ups the offsets
/// spread by 0.10 px).
pub const EDGE_OFFSET_MIN_SPREAD_PX: f64 = 0.05;

/// Student's t at 97.5 % with `df` degrees of freedom (df ≥ 1), over the
/// normal's 1.96: how much wider a 95 % interval from a sample standard
/// deviation of df + 1 values is than one from a known σ.
fn student_t_975_over_normal(df: usize) -> f64 {
    const T975: [f64; 30] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
        2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
        2.052, 2.048, 2.045, 2.042,
    ];
    let t = T975
        .get(df.max(1) - 1)
        .copied()
        // Beyond 30: t ≈ z (1 + (z² + 1) / 4df).
        .unwrap_or(1.96 * (1.0 + (1.96 * 1.96 + 1.0) / (4.0 * df as f64)));
    t / 1.96
}

impl EdgeOffset {
    /// The edge offset the configuration gives (`camera.edge_offset_px`),
    /// with its spread (`camera.edge_offset_spread_px`, else
    /// [`crate::config::DEFAULT_EDGE_OFFSET_SPREAD_PX`]).
    pub fn from_config(camera: &crate::config::CameraConfig) -> Option<Self> {
        camera.edge_offset_px.map(|o| EdgeOffset {
            offset_px: o,
            spread_px: camera
                .edge_offset_spread_px
                .unwrap_or(crate::config::DEFAULT_EDGE_OFFSET_SPREAD_PX),
        })
    }

    /// From runs' offsets (apparent radius minus R_mm / free-fall scale):
    /// their mean, and as spread the standard deviation of one more drop
    /// about that mean (s·√(1 + 1/n), s at least
    /// [`EDGE_OFFSET_MIN_SPREAD_PX`]), widened so that its 2σ is a 95 %
    /// prediction interval for so few runs (Student's t over 1.96). `None` below
    /// [`EDGE_OFFSET_MIN_RUNS`].
    pub fn measure(offsets_px: &[f64]) -> Option<EdgeOffset> {
        let n = offsets_px.len();
        if n < EDGE_OFFSET_MIN_RUNS {
            return None;
        }
        let mean = offsets_px.iter().sum::<f64>() / n as f64;
        let var = offsets_px.iter().map(|o| (o - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
        let sd = var.sqrt().max(EDGE_OFFSET_MIN_SPREAD_PX);
        let spread = sd * (1.0 + 1.0 / n as f64).sqrt() * student_t_975_over_normal(n - 1);
        (mean.is_finite() && spread.is_finite()).then_some(EdgeOffset {
            offset_px: mean,
            spread_px: spread,
        })
    }
}

/// Where a run's scale came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScaleSource {
    /// The manifest's or configuration's scale.
    Given,
    /// Free fall, pooled over the camera set-up's runs.
    SetupFreeFall,
    /// The run's own free flights.
    FreeFall,
    /// The sphere's radius: R_mm over its apparent radius in px (the last resort).
    Radius,
}

impl ScaleSource {
    /// The word written in `drops.csv`'s `scale_source` column.
    pub fn name(self) -> &'static str {
        match self {
            ScaleSource::Given => "given",
            ScaleSource::SetupFreeFall => "setup_free_fall",
            ScaleSource::FreeFall => "free_fall",
            ScaleSource::Radius => "radius",
        }
    }
}

/// How many of free fall's σ a given scale must be off before the speeds
/// take free fall's magnification into account ([`Scale::for_speeds`]); the
/// same three σ beyond which the run warns of a scale disagreement.
pub const SPEED_SCALE_SIGNIFICANCE: f64 = 3.0;

/// The largest relative error of free fall's scale that [`Scale::for_speeds`]
/// uses against a given scale: lens distortion moves the magnification at
/// the impact by a few 1e-4, which a less precise free fall cannot resolve
/// (one drop's own flight is 0.2–2 % precise, a set-up's pool of ten
/// 0.01–0.03 %); a grosser disagreement is warned of and the given scale
/// kept.
pub const SPEED_SCALE_MAX_REL_ERR: f64 = 1e-3;

/// What a run's scale is chosen from.
#[derive(Debug, Clone, PartialEq)]
pub struct ScaleInputs {
    /// Sphere radius R, mm.
    pub radius_mm: f64,
    /// Gravity g, m/s².
    pub g_m_s2: f64,
    /// The manifest's or configuration's scale.
    pub given_mm_per_px: Option<f64>,
    /// The pooled curvature of the run's set-up (two runs or more).
    pub setup: Option<Curvature>,
    /// The run's own flights.
    pub own: Option<Curvature>,
    /// The apparent radius and its statistical error.
    pub r_app_px: f64,
    /// Statistical error of `r_app_px`, px.
    pub r_app_err_px: f64,
    /// The edge offset known from elsewhere, for the radius's scale.
    pub edge_offset: Option<EdgeOffset>,
    /// The set-up's and the run's own curvature through a lens at the
    /// distortion bound (see [`crate::calibrate::lens`]): how much free fall's scale
    /// may be off by the lens, when comparing it with the sphere's.
    pub setup_at_bound: Option<Curvature>,
    /// The run's own curvature through that lens (`setup_at_bound` is the set-up's).
    pub own_at_bound: Option<Curvature>,
}

impl ScaleInputs {
    /// The sphere's true radius from its apparent one (px) and the one-sigma
    /// error: corrected by the known edge offset, else with
    /// [`EDGE_OFFSET_SYSTEMATIC_PX`] as its error.
    fn radius_from_silhouette_px(&self) -> (f64, f64) {
        let e = self.edge_offset.unwrap_or(EdgeOffset {
            offset_px: 0.0,
            spread_px: EDGE_OFFSET_SYSTEMATIC_PX,
        });
        (
            self.r_app_px - e.offset_px,
            self.r_app_err_px.hypot(e.spread_px),
        )
    }
}

/// A run's scale.
#[derive(Debug, Clone, PartialEq)]
pub struct Scale {
    /// The scale, mm per px.
    pub mm_per_px: f64,
    /// Relative one-sigma error of `mm_per_px`.
    pub rel_err: f64,
    /// Where it came from.
    pub source: ScaleSource,
    /// The scale from free fall (the set-up's, else the run's own) and its
    /// one-sigma error, mm/px, whether used or not.
    pub free_fall_mm_per_px: Option<(f64, f64)>,
    /// Two sources disagree beyond their errors.
    pub warning: Option<String>,
}

impl Scale {
    /// The sphere's radius in pixels that the scale implies (R_px itself
    /// when the scale comes from it) and its one-sigma error.
    pub fn radius_px(&self, inp: &ScaleInputs) -> (f64, f64) {
        match self.source {
            ScaleSource::Radius => inp.radius_from_silhouette_px(),
            _ => {
                let r = inp.radius_mm / self.mm_per_px;
                (r, r * self.rel_err)
            }
        }
    }

    /// The scale for the speeds at the contact, mm/px, and its relative
    /// one-sigma error, when it is not [`Scale::mm_per_px`] taken as exact.
    ///
    /// A speed is a velocity in px/s at the point of impact, so it needs the
    /// magnification there. A given scale is a nominal one (a calibration
    /// target, somewhere in the field); lens distortion moves the magnification
    /// at the impact by a few 1e-4, and the centre of a distorted disc moves
    /// faster still than the distortion of one point. The free flight
    /// measures the magnification on the same pixels, against gravity and
    /// the exact frame rate. So when both exist, the given scale carries
    /// their disagreement beyond the free fall's error as a systematic
    /// (σ² = d² − σ_ff², the way inconsistent measurements are combined) and
    /// the two are averaged with inverse-variance weights: the given scale
    /// stands where free fall agrees with it or is imprecise, free fall takes
    /// over where it is precise and disagrees. A disagreement within
    /// [`SPEED_SCALE_SIGNIFICANCE`] of free fall's σ is no evidence, and a
    /// free fall less precise than [`SPEED_SCALE_MAX_REL_ERR`] cannot see
    /// what distortion does. `None`: the speeds use `mm_per_px` (no given
    /// scale, no precise free fall, or no significant disagreement).
    pub fn for_speeds(&self) -> Option<(f64, f64)> {
        let (ScaleSource::Given, Some((ff, ff_err))) = (self.source, self.free_fall_mm_per_px)
        else {
            return None;
        };
        let given = self.mm_per_px;
        let d = ff - given;
        let precise = ff_err > 0.0 && ff_err < SPEED_SCALE_MAX_REL_ERR * ff;
        if !(precise && d.abs() > SPEED_SCALE_SIGNIFICANCE * ff_err) {
            return None;
        }
        let systematic_sq = d * d - ff_err * ff_err;
        let (w_given, w_ff) = (1.0 / systematic_sq, 1.0 / (ff_err * ff_err));
        let s = (w_given * given + w_ff * ff) / (w_given + w_ff);
        Some((s, (w_given + w_ff).sqrt().recip() / s))
    }

    /// Apparent minus true radius (px) and its error: the known edge offset
    /// when the scale comes from the apparent radius (`None` without one).
    pub fn edge_offset_px(&self, inp: &ScaleInputs) -> Option<(f64, f64)> {
        if self.source == ScaleSource::Radius {
            return inp.edge_offset.map(|e| (e.offset_px, e.spread_px));
        }
        Some({
            let (r, e) = self.radius_px(inp);
            (inp.r_app_px - r, inp.r_app_err_px.hypot(e))
        })
    }
}

/// Choose the scale (module doc) and check the sources against each other.
pub fn resolve(inp: &ScaleInputs) -> Scale {
    let (r_px, r_err_px) = inp.radius_from_silhouette_px();
    let by_radius = inp.radius_mm / r_px;
    let radius_rel = r_err_px / r_px;
    let ff = inp
        .setup
        .map(|c| (c, ScaleSource::SetupFreeFall))
        .or(inp.own.map(|c| (c, ScaleSource::FreeFall)));
    let free_fall_mm_per_px = ff.map(|(c, _)| {
        let s = c.mm_per_px(inp.g_m_s2);
        (s, s * c.rel_err())
    });
    let (mut mm_per_px, mut rel_err, source) = match (inp.given_mm_per_px, ff) {
        (Some(s), _) => (s, 0.0, ScaleSource::Given),
        (None, Some((c, src))) if c.rel_err() < radius_rel => {
            (c.mm_per_px(inp.g_m_s2), c.rel_err(), src)
        }
        _ => (by_radius, radius_rel, ScaleSource::Radius),
    };
    // Free fall against the sphere, beyond three of their combined sigma
    // (free fall's with what the distortion bound does to it, ÷ √3 as in
    // the errors; the radius's with its edge offset's): one of them is wrong
    // (a short flight's curvature, an odd silhouette, a wrong radius or
    // frame rate, another set-up), and which is not known. A run's own free
    // fall is then averaged with the sphere's scale, each error widened by
    // the same systematic σ_x, σ_x² = (d² − σ₁² − σ₂²) / 2, that makes them
    // agree (χ² = 1): the mean lies between them and its error reaches both;
    // a set-up's, which other runs share, is kept. Either way the run says so.
    let at_bound = match source {
        ScaleSource::SetupFreeFall => inp.setup_at_bound,
        _ => inp.own_at_bound,
    };
    let disagreement = (inp.given_mm_per_px.is_none() && source != ScaleSource::Radius)
        .then(|| {
            let lens = at_bound.map_or(0.0, |b| {
                (b.mm_per_px(inp.g_m_s2) - mm_per_px).abs() / 3f64.sqrt()
            });
            let e = (mm_per_px * rel_err).hypot(lens);
            let e_r = by_radius * radius_rel;
            ((by_radius - mm_per_px).abs() > 3.0 * e.hypot(e_r)).then_some((mm_per_px, e, e_r))
        })
        .flatten();
    if let (Some((s, e, e_r)), ScaleSource::FreeFall) = (disagreement, source) {
        let x2 = 0.5 * ((by_radius - s).powi(2) - e * e - e_r * e_r);
        let (w, w_r) = (1.0 / (e * e + x2), 1.0 / (e_r * e_r + x2));
        mm_per_px = (w * s + w_r * by_radius) / (w + w_r);
        rel_err = (w + w_r).sqrt().recip() / mm_per_px;
    }
    // A given scale is checked against free fall (beyond three of its
    // sigma, with what the distortion bound does to it ÷ √3 as in the
    // errors, and 0.02 %: a set-up's free fall averages the magnification
    // over its flights, which barrel distortion makes a few 1e-4 larger
    // than at the image's centre) and against the sphere (beyond 1 %: the
    // edge offset alone moves R_mm / R_px by up to about 0.6 %).
    let mut said = Vec::new();
    if let Some(given) = inp.given_mm_per_px {
        if let (Some((s, e)), Some((_, src))) = (free_fall_mm_per_px, ff) {
            let ff_at_bound = match src {
                ScaleSource::SetupFreeFall => inp.setup_at_bound,
                _ => inp.own_at_bound,
            };
            let lens =
                ff_at_bound.map_or(0.0, |b| (b.mm_per_px(inp.g_m_s2) - s).abs() / 3f64.sqrt());
            let e = e.hypot(lens);
            if (s - given).abs() > (3.0 * e).max(2e-4 * given) {
                said.push(format!(
                    "scale disagreement: mm_per_px {given} given, {s:.6} ± {e:.6} from free fall \
                     ({:+.2} %): check the scale or the frame rate",
                    100.0 * (s / given - 1.0)
                ));
            }
        }
        if (by_radius / given - 1.0).abs() > 0.01 {
            said.push(format!(
                "scale disagreement: mm_per_px {given} given, {by_radius:.6} from the sphere \
                 (R {} mm = {:.3} px) ({:+.2} %): check the radius or the scale",
                inp.radius_mm,
                inp.r_app_px,
                100.0 * (by_radius / given - 1.0)
            ));
        }
    }
    if let Some((s, e, e_r)) = disagreement {
        let used = match source {
            ScaleSource::FreeFall => {
                format!("{mm_per_px:.6} between them is used, its error reaching both")
            }
            _ => "the set-up's is used".to_string(),
        };
        said.push(format!(
            "scale disagreement: {s:.6} ± {e:.6} mm/px from free fall, {by_radius:.6} ± {e_r:.6} \
             from the sphere (R {} mm = {:.3} px less its edge offset) ({:+.2} %): {used}; \
             check the radius, the frame rate or the set-up",
            inp.radius_mm,
            inp.r_app_px,
            100.0 * (by_radius / s - 1.0),
        ));
    }
    let warning = (!said.is_empty()).then(|| said.join("; "));
    Scale {
        mm_per_px,
        rel_err,
        source,
        free_fall_mm_per_px,
        warning,
    }
}

/// What a run's apparent size per millimetre is made of: its apparent
/// (silhouette) radius, that radius's statistical error, and the sphere's
/// radius as the manifest gives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ApparentSize {
    /// The apparent (silhouette) radius, px.
    pub r_app_px: f64,
    /// Its statistical error, px.
    pub r_app_err_px: f64,
    /// The sphere's radius as the manifest gives it, mm.
    pub radius_mm: f64,
}

/// A run whose apparent size per mm disagrees with its set-up's other runs
/// ([`size_disagreements`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SizeDisagreement {
    /// The run's (R_app − edge offset) / R_mm and its one-sigma error, px/mm.
    pub px_per_mm: f64,
    /// One-sigma error of `px_per_mm`, px/mm.
    pub err: f64,
    /// The other runs' weighted mean and its error, px/mm.
    pub others_px_per_mm: f64,
    /// One-sigma error of `others_px_per_mm`, px/mm.
    pub others_err: f64,
    /// How many other runs.
    pub others: usize,
    /// The disagreement in combined standard errors.
    pub sigmas: f64,
}

impl SizeDisagreement {
    /// The sentence of a row's `radius_disagreement` flag.
    pub fn sentence(&self, setup: &str) -> String {
        format!(
            "apparent size {:.3} ± {:.3} px per mm of sphere radius, set-up {setup}'s {} other \
             {} {:.3} ± {:.3} ({:+.2} %, {:.1} σ): check this run's sphere_radius_mm (or its \
             set-up): its bottom, δ and contact law rest on it",
            self.px_per_mm,
            self.err,
            self.others,
            if self.others == 1 { "run" } else { "runs" },
            self.others_px_per_mm,
            self.others_err,
            100.0 * (self.px_per_mm / self.others_px_per_mm - 1.0),
            self.sigmas
        )
    }
}

/// The silhouette's edge offset's drop-to-drop standard deviation (px)
/// where the job knows none: over 120 `--preset real` drops of their own
/// set-ups the offsets spread by 0.10 px.
pub const SILHOUETTE_SPREAD_PX: f64 = 0.1;

/// How many combined standard errors a run's apparent size per mm may lie
/// from its set-up's other runs': with the drop-to-drop spread of the
/// silhouette in each error, a wrong radius of 1.7 % (3.05 mm for 3) is
/// 9–10 of them at 55–60 px.
pub const SIZE_AGREEMENT_SIGMAS: f64 = 4.0;

/// The runs of one camera set-up (`None`: not tracked) whose apparent size
/// per millimetre of sphere radius, q = (R_app − e) / R_mm, disagrees with
/// the other runs' by more than [`SIZE_AGREEMENT_SIGMAS`]: one zoom gives
/// every sphere of a set-up one q, so a run off it has a wrong radius in
/// the manifest (or belongs to another set-up).
///
/// Each q carries its radius's statistical error and the silhouette's
/// drop-to-drop spread (`edge`'s, else [`SILHOUETTE_SPREAD_PX`]);
/// the edge offset e itself (`edge`'s, else 0 with
/// [`EDGE_OFFSET_SYSTEMATIC_PX`]) is common to the set-up: it cancels
/// between spheres of one size and enters as e·(1/R_i − 1/R_others). The
/// run furthest off is flagged and left out, and the others compared
/// again, so that one wrong run does not make the good ones look wrong; of
/// two runs that disagree, both are flagged (which is wrong cannot be told).
pub fn size_disagreements(
    runs: &[Option<ApparentSize>],
    edge: Option<EdgeOffset>,
) -> Vec<Option<SizeDisagreement>> {
    let (e, e_err, spread) = match edge {
        Some(e) => (e.offset_px, EDGE_OFFSET_SYSTEMATIC_PX, e.spread_px),
        None => (0.0, EDGE_OFFSET_SYSTEMATIC_PX, SILHOUETTE_SPREAD_PX),
    };
    let q = |a: &ApparentSize| {
        (
            (a.r_app_px - e) / a.radius_mm,
            a.r_app_err_px.hypot(spread) / a.radius_mm,
        )
    };
    let valid = |a: &ApparentSize| {
        let (v, err) = q(a);
        v.is_finite() && err.is_finite() && err > 0.0 && a.radius_mm > 0.0
    };
    let mut active: Vec<usize> = (0..runs.len())
        .filter(|&i| runs[i].as_ref().is_some_and(valid))
        .collect();
    let mut out = vec![None; runs.len()];
    let against_others = |i: usize, active: &[usize]| {
        let a = runs[i]?;
        let (qi, si) = q(&a);
        let (mut sw, mut swq, mut swr) = (0.0, 0.0, 0.0);
        for &j in active.iter().filter(|&&j| j != i) {
            let b = runs[j]?;
            let (qj, sj) = q(&b);
            let w = 1.0 / (sj * sj);
            (sw, swq, swr) = (sw + w, swq + w * qj, swr + w / b.radius_mm);
        }
        let (m, inv_r) = (swq / sw, swr / sw);
        let common = e_err * (1.0 / a.radius_mm - inv_r);
        let sigma = (si * si + 1.0 / sw + common * common).sqrt();
        Some(SizeDisagreement {
            px_per_mm: qi,
            err: si,
            others_px_per_mm: m,
            others_err: sw.sqrt().recip(),
            others: active.len() - 1,
            sigmas: (qi - m).abs() / sigma,
        })
    };
    while active.len() >= 2 {
        let worst = active
            .iter()
            .filter_map(|&i| Some((i, against_others(i, &active)?)))
            .max_by(|a, b| a.1.sigmas.total_cmp(&b.1.sigmas));
        let Some((i, d)) = worst.filter(|(_, d)| d.sigmas > SIZE_AGREEMENT_SIGMAS) else {
            break;
        };
        if active.len() == 2 {
            for &j in &active {
                out[j] = against_others(j, &active);
            }
            break;
        }
        out[i] = Some(d);
        active.retain(|&j| j != i);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4.8 mm sphere seen 79.7 px in radius (80 px at 0.06 mm/px), no
    /// scale known.
    fn sphere_of_4_8_mm() -> ScaleInputs {
        ScaleInputs {
            radius_mm: 4.8,
            g_m_s2: 9.81,
            given_mm_per_px: None,
            setup: None,
            own: None,
            r_app_px: 79.7,
            r_app_err_px: 0.002,
            edge_offset: None,
            setup_at_bound: None,
            own_at_bound: None,
        }
    }

    #[test]
    fn the_source_follows_the_preference_and_disagreements_are_said() {
        let good = Curvature {
            g_px_s2: 9.81 / 0.06e-3,
            err_px_s2: 9.81 / 0.06e-3 * 1e-4,
            frames: 80,
        };
        let base = sphere_of_4_8_mm();
        let s = resolve(&base);
        assert_eq!(s.source, ScaleSource::Radius);
        assert!((s.rel_err - 0.3 / 79.7).abs() < 1e-6);
        let own = ScaleInputs {
            own: Some(good),
            ..base.clone()
        };
        let s = resolve(&own);
        assert_eq!(s.source, ScaleSource::FreeFall);
        assert!((s.mm_per_px - 0.06).abs() < 1e-12);
        // The true radius is 80 px; the apparent one 0.3 px smaller.
        let (r, _) = s.radius_px(&own);
        assert!((r - 80.0).abs() < 1e-9);
        assert!((s.edge_offset_px(&own).unwrap().0 + 0.3).abs() < 1e-9);
        let s = resolve(&ScaleInputs {
            setup: Some(good),
            ..own.clone()
        });
        assert_eq!(s.source, ScaleSource::SetupFreeFall);
        let s = resolve(&ScaleInputs {
            given_mm_per_px: Some(0.06),
            ..own.clone()
        });
        assert_eq!((s.source, s.warning.is_none()), (ScaleSource::Given, true));
        let s = resolve(&ScaleInputs {
            given_mm_per_px: Some(0.0603),
            ..own
        });
        let w = s.warning.unwrap();
        assert!(w.contains("0.0603") && w.contains("free fall"), "{w}");
    }

    #[test]
    fn a_given_scale_is_checked_against_free_fall_with_the_distortion_bound() {
        // A set-up's free fall 0.03 % above the given (true, centre) scale,
        // its statistical error 1e-5: barrel distortion makes the flights'
        // mean magnification larger. On 120 real-preset drops with the true
        // scale given, 88 were flagged so. With the bound's curvature 0.06 %
        // away (σ 0.035 %) the 0.03 % is within it and is not said; a scale
        // 1 % off still is.
        let g = 9.81 / 0.06e-3;
        let curvature = |rel: f64| Curvature {
            g_px_s2: g / (1.0 + rel),
            err_px_s2: g * 1e-5,
            frames: 400,
        };
        let inputs = |given: f64, bound: Option<Curvature>| ScaleInputs {
            given_mm_per_px: Some(given),
            setup: Some(curvature(3e-4)),
            setup_at_bound: bound,
            ..sphere_of_4_8_mm()
        };
        let said = |given, bound| resolve(&inputs(given, bound)).warning;
        assert!(said(0.06, None).is_some_and(|w| w.contains("free fall")));
        assert_eq!(said(0.06, Some(curvature(9e-4))), None);
        let w = said(0.0606, Some(curvature(9e-4))).unwrap();
        assert!(w.contains("0.0606") && w.contains("free fall"), "{w}");
    }

    #[test]
    fn an_edge_offset_measured_on_few_runs_claims_a_prediction_interval() {
        assert_eq!(EdgeOffset::measure(&[-0.2, -0.3]), None);
        // n = 3: mean −0.25, s = 0.1, s·√(4/3) = 0.115, × 4.303 / 1.96.
        let e = EdgeOffset::measure(&[-0.15, -0.35, -0.25]).unwrap();
        assert!((e.offset_px + 0.25).abs() < 1e-12);
        assert!((e.spread_px - 0.1 * (4.0f64 / 3.0).sqrt() * 4.303 / 1.96).abs() < 1e-9);
        // Many runs: close to s·√(1 + 1/n); identical runs: the floor,
        // widened like a measured s (five runs: t = 2.776).
        let many: Vec<f64> = (0..100)
            .map(|i| if i % 2 == 0 { -0.1 } else { -0.3 })
            .collect();
        let e = EdgeOffset::measure(&many).unwrap();
        assert!((e.spread_px / 0.1 - 1.0).abs() < 0.03, "{e:?}");
        let e = EdgeOffset::measure(&[-0.2; 5]).unwrap();
        let floor = EDGE_OFFSET_MIN_SPREAD_PX * (1.2f64).sqrt() * 2.776 / 1.96;
        assert!((e.spread_px - floor).abs() < 1e-9, "{e:?}");
    }

    #[test]
    fn a_known_edge_offset_corrects_the_radius_and_carries_its_spread() {
        let inp = ScaleInputs {
            edge_offset: Some(EdgeOffset {
                offset_px: -0.3,
                spread_px: 0.1,
            }),
            ..sphere_of_4_8_mm()
        };
        let s = resolve(&inp);
        assert_eq!(s.source, ScaleSource::Radius);
        assert!((s.mm_per_px - 0.06).abs() < 1e-12);
        assert!((s.rel_err - 0.002f64.hypot(0.1) / 80.0).abs() < 1e-12);
        let (r, e) = s.radius_px(&inp);
        assert!((r - 80.0).abs() < 1e-12 && (e - 0.002f64.hypot(0.1)).abs() < 1e-12);
        assert_eq!(s.edge_offset_px(&inp), Some((-0.3, 0.1)));
    }

    /// The curvature that gives scale `s_mm` (g = 9.81) to `rel`.
    fn curvature_for(s_mm: f64, rel: f64) -> Curvature {
        Curvature {
            g_px_s2: 9.81 / (s_mm * 1e-3),
            err_px_s2: 9.81 / (s_mm * 1e-3) * rel,
            frames: 80,
        }
    }

    #[test]
    fn free_fall_and_the_sphere_disagreeing_is_said_and_an_own_free_fall_is_averaged() {
        // The sphere says 0.06 ± 7.5e-5 (0.1 px of 80); free fall 0.5 % less
        // to 1e-4: four sigma apart.
        let inp = ScaleInputs {
            own: Some(curvature_for(0.06 / 1.005, 1e-4)),
            edge_offset: Some(EdgeOffset {
                offset_px: -0.3,
                spread_px: 0.1,
            }),
            ..sphere_of_4_8_mm()
        };
        let s = resolve(&inp);
        assert_eq!(s.source, ScaleSource::FreeFall);
        let w = s.warning.clone().unwrap();
        assert!(
            w.contains("scale disagreement") && w.contains("between them"),
            "{w}"
        );
        // Near half-way (nearer the one whose own error is smaller), its
        // error about half the distance: both within about 1σ.
        let ff = 0.06 / 1.005;
        let e = s.mm_per_px * s.rel_err;
        assert!(
            (s.mm_per_px - 0.5 * (ff + 0.06)).abs() < 0.1 * (0.06 - ff),
            "{}",
            s.mm_per_px
        );
        assert!((0.06 - s.mm_per_px).max(s.mm_per_px - ff) < 1.1 * e, "{e}");
        // The same through a lens whose bound moves free fall's scale by
        // 1 %: no longer a disagreement, and free fall is kept.
        let s = resolve(&ScaleInputs {
            own_at_bound: Some(curvature_for(ff * 1.01, 1e-4)),
            ..inp.clone()
        });
        assert!(s.warning.is_none() && (s.mm_per_px / ff - 1.0).abs() < 1e-12);
        // A set-up's free fall is kept, and the run says so.
        let s = resolve(&ScaleInputs {
            own: None,
            setup: Some(curvature_for(ff, 1e-4)),
            ..inp
        });
        assert_eq!(s.source, ScaleSource::SetupFreeFall);
        assert!((s.mm_per_px / ff - 1.0).abs() < 1e-12);
        assert!(s.warning.unwrap().contains("the set-up's is used"));
    }

    #[test]
    fn speeds_take_free_fall_where_it_is_precise_and_disagrees_with_a_given_scale() {
        let scale = |given: f64, ff: Option<(f64, f64)>| Scale {
            mm_per_px: given,
            rel_err: 0.0,
            source: ScaleSource::Given,
            free_fall_mm_per_px: ff,
            warning: None,
        };
        // Agreement within free fall's error: the given scale stands.
        assert_eq!(scale(0.06, Some((0.06001, 0.00002))).for_speeds(), None);
        // Free fall 20 σ off: the given scale's systematic is √(d² − σ²),
        // and the weighted mean sits near free fall.
        let (ff, ff_err) = (0.0602, 0.00001);
        let (s, rel) = scale(0.06, Some((ff, ff_err))).for_speeds().unwrap();
        let sys_sq = 0.0002f64.powi(2) - ff_err * ff_err;
        let w = (1.0 / sys_sq, 1.0 / (ff_err * ff_err));
        let want = (w.0 * 0.06 + w.1 * ff) / (w.0 + w.1);
        assert!((s - want).abs() < 1e-15, "{s} {want}");
        assert!((s - ff).abs() < 0.01 * 0.0002, "{s}");
        assert!((rel * s - (w.0 + w.1).sqrt().recip()).abs() < 1e-15);
        // Beyond 3 σ only, and free fall precise to 0.1 % (a 5 % error
        // 5 σ off is a wrong scale or frame rate, warned of, not averaged)...
        assert_eq!(scale(0.06, Some((0.06008, 0.00003))).for_speeds(), None);
        assert!(scale(0.06, Some((0.06010, 0.00003))).for_speeds().is_some());
        assert_eq!(scale(0.06, Some((0.063, 0.0006))).for_speeds(), None);
        // ...and scales that are not given are not touched.
        let mut sc = scale(0.06, Some((0.0602, 0.00001)));
        sc.source = ScaleSource::SetupFreeFall;
        assert_eq!(sc.for_speeds(), None);
        assert_eq!(scale(0.06, None).for_speeds(), None);
    }

    /// One zoom, 20 px per mm of radius, each silhouette 0.3 px small with
    /// 0.1 px of drop-to-drop spread (seeded): spheres of 3, 4.5 and 7 mm
    /// agree (the common offset, unknown, in their errors); 3.05 mm written
    /// for a 3 mm sphere (1.6 %) is flagged, alone; of two
    /// runs that disagree both are flagged; a run not tracked is no run.
    #[test]
    fn a_wrong_radius_in_a_setup_is_found_and_the_right_ones_are_not() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let spread = Normal::new(0.0, 0.1).unwrap();
        let mut size = |true_mm: f64, written_mm: f64| {
            Some(ApparentSize {
                r_app_px: 20.0 * true_mm - 0.3 + spread.sample(&mut rng),
                r_app_err_px: 0.01,
                radius_mm: written_mm,
            })
        };
        let good: Vec<Option<ApparentSize>> = [3.0, 3.0, 4.5, 4.5, 7.0, 7.0, 3.0]
            .iter()
            .map(|&r| size(r, r))
            .collect();
        assert!(size_disagreements(&good, None).iter().all(Option::is_none));
        let mut typo = good.clone();
        typo[1] = size(3.0, 3.05);
        typo[3] = None;
        let found = size_disagreements(&typo, None);
        for (i, f) in found.iter().enumerate() {
            assert_eq!(f.is_some(), i == 1, "run {i}: {f:?}");
        }
        let d = found[1].unwrap();
        // Among 3 to 7 mm spheres the unknown common offset (0.3 px)
        // weighs too: 6 σ here, 10 among spheres of one size (tests/footage.rs).
        assert!(d.sigmas > 5.0 && d.sigmas < 8.0, "{d:?}");
        assert!(
            (d.px_per_mm / d.others_px_per_mm - 3.0 / 3.05).abs() < 0.005,
            "{d:?}"
        );
        assert_eq!(d.others, 5);
        assert!(d.sentence("cam").contains("set-up cam's 5 other runs"));
        let pair = size_disagreements(&[size(3.0, 3.0), size(3.0, 3.05)], None);
        assert!(pair.iter().all(Option::is_some), "{pair:?}");
    }
}
