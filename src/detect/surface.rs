//! The surface line: the top of the pillar band as a sub-pixel straight line
//! `row = row0_px + slope · column` (the camera may be tilted).
//!
//! Method, on the background image (many frames averaged, so little noise):
//! 1. per column, the strongest bright-to-dark step going down (the largest
//!    `B(z) − B(z+1)`) within the search rows;
//! 2. a sub-pixel row by the area method in a window of `2w + 2` rows around
//!    it: with `hi`, `lo` the means of the two top and two bottom rows,
//!    `e = z_top − ½ + Σ (B − lo)/(hi − lo)`. For an area-sampled straight
//!    edge this is exact whatever the tilt or blur (each pixel's coverage
//!    sums to the distance of the edge from the window's top), so there is no
//!    pixel locking;
//! 3. a robust line through the column edges: Theil–Sen start (median of
//!    slopes between columns half the width apart, median intercept), then
//!    Tukey-weighted least squares with the scale from the MAD. Columns where
//!    the band's top is not the strongest step (channels, dust) are rejected.
//!
//! The uncertainty is that of the weighted least-squares line,
//! `σ̂²(XᵀWX)⁻¹`, with `σ̂²` the weighted residual variance.

use crate::config::DetectConfig;

use super::background::Background;
use super::DetectError;

/// The undeformed surface's top line, in frame pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceLine {
    /// Row of the line at column 0 (px).
    pub row0_px: f64,
    /// Tilt (rows per column).
    pub slope: f64,
    /// Covariance of `(row0_px, slope)`; zero when given by the configuration.
    pub cov: [[f64; 2]; 2],
    /// RMS residual of the column edges about the line (px); 0 when given.
    pub residual_px: f64,
    /// Columns used in the fit (0 when given).
    pub n_used: usize,
}

impl SurfaceLine {
    /// The line's row at column `x`.
    #[inline]
    pub fn row_at(&self, x: f64) -> f64 {
        self.row0_px + self.slope * x
    }

    /// Standard deviation of [`row_at`](Self::row_at)`(x)`:
    /// `√(c₀₀ + 2x c₀₁ + x² c₁₁)`.
    pub fn sigma_row_at(&self, x: f64) -> f64 {
        let c = &self.cov;
        (c[0][0] + 2.0 * x * c[0][1] + x * x * c[1][1])
            .max(0.0)
            .sqrt()
    }

    /// The line fixed by the configuration (`detect.surface_row_px`,
    /// `detect.surface_slope`), if it sets one.
    pub fn from_config(cfg: &DetectConfig) -> Option<Self> {
        cfg.surface_row_px.map(|row0_px| SurfaceLine {
            row0_px,
            slope: cfg.surface_slope,
            cov: [[0.0; 2]; 2],
            residual_px: 0.0,
            n_used: 0,
        })
    }
}

/// Settings of [`fit_surface`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceParams {
    /// Rows searched for the band's top (default: the whole frame).
    pub rows: Option<(usize, usize)>,
    /// Half-height `w` of the area window (rows each side of the step).
    pub half_window: usize,
    /// Smallest relative step `(hi − lo)/hi` for a column to count.
    pub min_contrast: f64,
    /// Tukey's constant in units of the MAD scale.
    pub tukey_c: f64,
    /// Floor of the residual scale (px).
    pub min_scale_px: f64,
}

impl Default for SurfaceParams {
    fn default() -> Self {
        SurfaceParams {
            rows: None,
            half_window: 5,
            min_contrast: 0.2,
            tukey_c: 4.685,
            min_scale_px: 0.005,
        }
    }
}

/// Sub-pixel row of the band's top in every column where one is found:
/// `(column, row)` pairs.
pub fn column_edges(bg: &Background, params: &SurfaceParams) -> Vec<(f64, f64)> {
    let w = params.half_window;
    let (r_lo, r_hi) = params.rows.unwrap_or((0, bg.height));
    let r_hi = r_hi.min(bg.height);
    let mut out = Vec::with_capacity(bg.width);
    if r_hi < r_lo + 2 * w + 2 {
        return out;
    }
    // Row by row (the image is row-major): per column, the first row of
    // the largest step.
    let width = bg.width;
    let mut best_row = vec![0usize; width];
    let mut best_step = vec![f64::NEG_INFINITY; width];
    for i in r_lo + w..r_hi - w - 1 {
        let (upper, lower) = (
            &bg.levels[i * width..][..width],
            &bg.levels[(i + 1) * width..][..width],
        );
        for j in 0..width {
            let step = upper[j] as f64 - lower[j] as f64;
            if step > best_step[j] {
                best_step[j] = step;
                best_row[j] = i;
            }
        }
    }
    for j in 0..width {
        let zs = best_row[j];
        if best_step[j] <= 0.0 {
            continue;
        }
        // Window rows zs − w ..= zs + 1 + w.
        let top = zs - w;
        let bot = zs + 1 + w;
        let hi = 0.5 * (bg.at(top, j) as f64 + bg.at(top + 1, j) as f64);
        let lo = 0.5 * (bg.at(bot, j) as f64 + bg.at(bot - 1, j) as f64);
        if !(hi > 0.0 && (hi - lo) >= params.min_contrast * hi) {
            continue;
        }
        let sum: f64 = (top..=bot)
            .map(|i| (bg.at(i, j) as f64 - lo) / (hi - lo))
            .sum();
        out.push((j as f64, top as f64 - 0.5 + sum));
    }
    out
}

/// The surface line from the background image (see the module doc).
pub fn fit_surface(bg: &Background, params: &SurfaceParams) -> Result<SurfaceLine, DetectError> {
    let pts = column_edges(bg, params);
    fit_line(&pts, params)
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
