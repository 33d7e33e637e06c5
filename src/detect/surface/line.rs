//! Step 3 of the module doc: the robust line through the column edges, its
//! edge-model error and its bow.

use super::columns::column_edges;
use super::params::SurfaceParams;
use crate::detect::background::Background;
use crate::detect::types::SurfaceLine;
use crate::detect::DetectError;

/// Disagreement (px) between the flank fit and the area method beyond which
/// the band's top counts as structured and the flank fit's line is used.
/// Below it the area method's is: it is exact for any blur kernel and any
/// step height, where the flank fit assumes a Gaussian blur and flat levels
/// over its short window. On clean band tops the flank fit alone is off by
/// up to 0.053 px (120 `realistic` renders; the area row within 0.008 px),
/// so a smaller disagreement is no evidence of structure; a glossy strip or
/// a row of pillar tops moves the two 0.06–0.5 px apart (independent
/// renders: the flank fit within 0.06 px of the truth there, the area row
/// up to 0.19 px off).
pub const STRUCTURED_TOP_PX: f64 = 0.06;

/// The area row's systematic error (px) on a clean band top: 0.003 px
/// root-mean-square off the truth on 60 `realistic` renders (within
/// 0.008 px), up to 0.007 px on `harsh` ones.
pub const AREA_SYSTEMATIC_PX: f64 = 0.005;

/// The flank fit's systematic error (px) on a structured band top, at
/// least: within 0.06 px of the truth on the independent renders (median
/// 0.043 px), where its disagreement with the area row was 0.06–0.26 px.
pub const FLANK_SYSTEMATIC_PX: f64 = 0.04;

impl SurfaceLine {
    /// The systematic error (px) of the edge model this line was taken
    /// with: [`AREA_SYSTEMATIC_PX`] for a clean top (the area row), and for
    /// a structured one (the flank fit) half the two models' disagreement,
    /// at least [`FLANK_SYSTEMATIC_PX`]. 0 for a line given.
    pub fn edge_model_sigma_px(&self) -> f64 {
        if self.n_used == 0 {
            0.0
        } else if self.model_err_px < STRUCTURED_TOP_PX {
            AREA_SYSTEMATIC_PX
        } else {
            (0.5 * self.model_err_px).max(FLANK_SYSTEMATIC_PX)
        }
    }
}

/// The surface line from the background image (see the module doc), with
/// its edge-model error.
pub fn fit_surface(bg: &Background, params: &SurfaceParams) -> Result<SurfaceLine, DetectError> {
    let edges = column_edges(bg, params);
    let pts: Vec<(f64, f64)> = edges.iter().map(|e| (e.x_px, e.row_px)).collect();
    let flank = fit_line(&pts, params)?;
    let mut diff: Vec<f64> = edges
        .iter()
        .filter(|e| (e.row_px - flank.row_at(e.x_px)).abs() < 1.0)
        .map(|e| e.row_px - e.row_area_px)
        .collect();
    let model_err_px = if diff.is_empty() {
        0.0
    } else {
        median(&mut diff).abs()
    };
    let (mut line, pts) = if model_err_px < STRUCTURED_TOP_PX {
        let pts: Vec<(f64, f64)> = edges.iter().map(|e| (e.x_px, e.row_area_px)).collect();
        (fit_line(&pts, params)?, pts)
    } else {
        (flank, pts)
    };
    line.model_err_px = model_err_px;
    if let Some((c, c_err)) = bow(&pts, &line, params) {
        line.bow_per_px2 = c;
        line.bow_err_per_px2 = c_err;
    }
    Ok(line)
}

/// Columns per block in [`bow`]: neighbouring columns' edges share their
/// errors (the blur, a pillar's face), so the bow is fitted to block means,
/// whose scatter gives an honest error.
const BOW_BLOCK_COLUMNS: f64 = 16.0;

/// The bow `c` of `row = a + b·x + c·x²` by least squares over the column
/// edges within 4 of the line's residual scales of it (the robust line's
/// inliers), averaged in blocks of [`BOW_BLOCK_COLUMNS`], with its standard
/// error from the blocks' scatter: `(c, σ_c)`. `None` with fewer than 8
/// blocks.
fn bow(pts: &[(f64, f64)], line: &SurfaceLine, params: &SurfaceParams) -> Option<(f64, f64)> {
    let scale = line.residual_px.max(params.min_scale_px);
    let kept = pts
        .iter()
        .copied()
        .filter(|&(x, z)| (z - line.row_at(x)).abs() <= 4.0 * scale);
    let mut blocks: std::collections::BTreeMap<i64, (f64, f64, f64)> = Default::default();
    for (x, z) in kept {
        let b = blocks
            .entry((x / BOW_BLOCK_COLUMNS).floor() as i64)
            .or_insert((0.0, 0.0, 0.0));
        *b = (b.0 + x, b.1 + z, b.2 + 1.0);
    }
    let means: Vec<(f64, f64)> = blocks
        .values()
        .filter(|b| b.2 >= 0.5 * BOW_BLOCK_COLUMNS)
        .map(|b| (b.0 / b.2, b.1 / b.2))
        .collect();
    if means.len() < 8 {
        return None;
    }
    let mid = means.iter().map(|p| p.0).sum::<f64>() / means.len() as f64;
    let half = means
        .iter()
        .map(|p| (p.0 - mid).abs())
        .fold(0.0, f64::max)
        .max(1.0);
    // In u = (x − mid)/half, for conditioning.
    let mut ata = nalgebra::Matrix3::<f64>::zeros();
    let mut atz = nalgebra::Vector3::<f64>::zeros();
    for &(x, z) in &means {
        let u = (x - mid) / half;
        let row = nalgebra::Vector3::new(1.0, u, u * u);
        ata += row * row.transpose();
        atz += row * z;
    }
    let inv = ata.try_inverse()?;
    let coef = inv * atz;
    let ss: f64 = means
        .iter()
        .map(|&(x, z)| {
            let u = (x - mid) / half;
            (z - coef[0] - coef[1] * u - coef[2] * u * u).powi(2)
        })
        .sum();
    let s2 = ss / (means.len() - 3) as f64;
    let c = coef[2] / (half * half);
    let c_err = (s2 * inv[(2, 2)]).max(0.0).sqrt() / (half * half);
    (c.is_finite() && c_err.is_finite()).then_some((c, c_err))
}

fn median(v: &mut [f64]) -> f64 {
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Robust line `z = a + b x` through `(x, z)` points (steps 3 of the module doc).
pub fn fit_line(pts: &[(f64, f64)], params: &SurfaceParams) -> Result<SurfaceLine, DetectError> {
    const WHAT: &str = "surface line";
    let n = pts.len();
    if n < 4 {
        return Err(DetectError::TooFewPoints {
            what: WHAT,
            found: n,
            needed: 4,
        });
    }
    let half = n / 2;
    let mut slopes: Vec<f64> = (0..n - half)
        .filter_map(|i| {
            let (p, q) = (pts[i], pts[i + half]);
            (q.0 != p.0).then(|| (q.1 - p.1) / (q.0 - p.0))
        })
        .collect();
    if slopes.is_empty() {
        return Err(DetectError::Degenerate {
            what: WHAT,
            reason: "all points in one column".into(),
        });
    }
    let mut b = median(&mut slopes);
    let mut resid: Vec<f64> = pts.iter().map(|p| p.1 - b * p.0).collect();
    let mut a = median(&mut resid);
    let mut weights = vec![0.0; n];
    let mut abs_r = vec![0.0; n];
    let mut result = None;
    for _ in 0..50 {
        for (k, p) in pts.iter().enumerate() {
            abs_r[k] = (p.1 - a - b * p.0).abs();
        }
        let mut tmp = abs_r.clone();
        let s = (1.4826 * median(&mut tmp)).max(params.min_scale_px);
        for k in 0..n {
            let u = abs_r[k] / (params.tukey_c * s);
            weights[k] = if u < 1.0 { (1.0 - u * u).powi(2) } else { 0.0 };
        }
        let (mut sw, mut sx, mut sz, mut sxx, mut sxz) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (p, &w) in pts.iter().zip(&weights) {
            sw += w;
            sx += w * p.0;
            sz += w * p.1;
            sxx += w * p.0 * p.0;
            sxz += w * p.0 * p.1;
        }
        let det = sw * sxx - sx * sx;
        if !(det > 0.0) {
            return Err(DetectError::Degenerate {
                what: WHAT,
                reason: "fewer than two distinct columns kept".into(),
            });
        }
        let nb = (sw * sxz - sx * sz) / det;
        let na = (sz - nb * sx) / sw;
        let moved = (na - a).abs() + (nb - b).abs() * 100.0;
        a = na;
        b = nb;
        // Covariance of (a, b): σ̂² (XᵀWX)⁻¹.
        let ss: f64 = pts
            .iter()
            .zip(&weights)
            .map(|(p, &w)| w * (p.1 - a - b * p.0).powi(2))
            .sum();
        let s2 = ss / (sw - 2.0).max(1.0);
        let cov = [
            [s2 * sxx / det, -s2 * sx / det],
            [-s2 * sx / det, s2 * sw / det],
        ];
        let used = weights.iter().filter(|&&w| w > 0.0).count();
        let rms = {
            let (s, c) = pts
                .iter()
                .zip(&weights)
                .filter(|(_, &w)| w > 0.0)
                .fold((0.0, 0usize), |(s, c), (p, _)| {
                    (s + (p.1 - a - b * p.0).powi(2), c + 1)
                });
            (s / c.max(1) as f64).sqrt()
        };
        result = Some(SurfaceLine {
            row0_px: a,
            slope: b,
            cov,
            residual_px: rms,
            n_used: used,
            model_err_px: 0.0,
            bow_per_px2: 0.0,
            bow_err_per_px2: 0.0,
        });
        if moved < 1e-10 {
            break;
        }
    }
    result.ok_or(DetectError::Degenerate {
        what: WHAT,
        reason: "no iteration".into(),
    })
}
