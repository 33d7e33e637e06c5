//! Exact synthetic scenes for testing detection: an anti-aliased dark disk
//! (a backlit silhouette of transmission τ) in front of a bright background, and a (tilted) dark pillar band in front of
//! both, with pixel values the exact area means of the scene (pixel
//! convention in [`super`]).
//!
//! Area coverage is integrated exactly along `z` and by the midpoint rule over
//! [`SUBCOLUMNS`] sub-columns along `x`, only in pixels the boundary crosses;
//! the coverage error is below 1e-4 except in the few pixels at the disk's
//! left and right extremes (square-root behaviour of the chord), where it
//! stays below 3e-4. The optional optics blur is a separable Gaussian;
//! noise and quantisation take the caller's random numbers, so this module
//! needs no random generator and stays deterministic.

use ndarray::Array2;

/// Sub-columns per pixel in the coverage integral.
pub const SUBCOLUMNS: usize = 64;

/// A scene: bright background, dark sphere, pillar band in front of both.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Frame width, px.
    pub width: usize,
    /// Frame height, px.
    pub height: usize,
    /// Background level at the frame centre.
    pub background: f64,
    /// Relative change of the background from the centre to a corner
    /// (vignetting, `1 − v·ρ²/ρ_corner²`).
    pub vignetting: f64,
    /// The sphere's transmission τ: fully covered pixels show `τ·background`
    /// (a backlit silhouette).
    pub sphere_transmission: f64,
    /// The sphere's circle: centre column, centre row, radius (px).
    pub disk: Option<(f64, f64, f64)>,
    /// The pillar band: everything below `row = row0 + slope · column`.
    pub band: Option<PillarBand>,
    /// Gaussian blur of the optics (px, standard deviation); 0 = none.
    pub blur_px: f64,
}

/// The pillar band's look: top line and a column-periodic level (pillars
/// and the darker gaps between pillar rows).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PillarBand {
    /// Row of the top line at column 0.
    pub row0_px: f64,
    /// Rows per column.
    pub slope: f64,
    /// Level of a pillar seen from the side.
    pub pillar_level: f64,
    /// Level of a channel between pillars.
    pub channel_level: f64,
    /// Period of the pillar pattern (px) and the pillar's share of it.
    pub period_px: f64,
    /// The pillar's share of the period, in (0, 1].
    pub solid_fraction: f64,
}

impl PillarBand {
    fn level(&self, x: f64) -> f64 {
        let phase = (x / self.period_px).rem_euclid(1.0);
        if phase < self.solid_fraction {
            self.pillar_level
        } else {
            self.channel_level
        }
    }
}

/// Fraction of pixel `(row i, column j)` covered by the disk `(cx, cz, r)`.
pub fn disk_coverage(cx: f64, cz: f64, r: f64, i: usize, j: usize) -> f64 {
    let (x, z) = (j as f64, i as f64);
    let d = (x - cx).hypot(z - cz);
    const HALF_DIAG: f64 = std::f64::consts::FRAC_1_SQRT_2;
    if d + HALF_DIAG <= r {
        return 1.0;
    }
    if d - HALF_DIAG >= r {
        return 0.0;
    }
    let mut sum = 0.0;
    for s in 0..SUBCOLUMNS {
        let xs = x - 0.5 + (s as f64 + 0.5) / SUBCOLUMNS as f64;
        let dx = xs - cx;
        if dx.abs() >= r {
            continue;
        }
        let h = (r * r - dx * dx).sqrt();
        let lo = (cz - h).max(z - 0.5);
        let hi = (cz + h).min(z + 0.5);
        sum += (hi - lo).max(0.0);
    }
    sum / SUBCOLUMNS as f64
}

/// Fraction of pixel `(i, j)` below the line `row = row0 + slope·column`.
pub fn band_coverage(row0: f64, slope: f64, i: usize, j: usize) -> f64 {
    let (x, z) = (j as f64, i as f64);
    let at = |xs: f64| ((z + 0.5) - (row0 + slope * xs)).clamp(0.0, 1.0);
    let (a, b) = (at(x - 0.5), at(x + 0.5));
    if a == b && (a == 0.0 || a == 1.0) {
        return a;
    }
    (0..SUBCOLUMNS)
        .map(|s| at(x - 0.5 + (s as f64 + 0.5) / SUBCOLUMNS as f64))
        .sum::<f64>()
        / SUBCOLUMNS as f64
}

impl Scene {
    /// The noiseless scene as real-valued pixel means.
    pub fn render(&self) -> Array2<f64> {
        let (w, h) = (self.width, self.height);
        let (xc, zc) = ((w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0);
        let corner2 = xc * xc + zc * zc;
        let mut img = Array2::zeros((h, w));
        for ((i, j), v) in img.indexed_iter_mut() {
            let rho2 = (j as f64 - xc).powi(2) + (i as f64 - zc).powi(2);
            let bg = self.background * (1.0 - self.vignetting * rho2 / corner2);
            let mut val = bg;
            if let Some((cx, cz, r)) = self.disk {
                let c = disk_coverage(cx, cz, r, i, j);
                val = bg * (1.0 - c + self.sphere_transmission * c);
            }
            if let Some(b) = &self.band {
                let c = band_coverage(b.row0_px, b.slope, i, j);
                if c > 0.0 {
                    val = val * (1.0 - c) + b.level(j as f64) * c;
                }
            }
            *v = val;
        }
        if self.blur_px > 0.0 {
            gaussian_blur(&mut img, self.blur_px);
        }
        img
    }
}

/// Separable Gaussian blur (standard deviation `sigma_px`, kernel ±4σ,
/// normalised), edges extended by their last value.
pub fn gaussian_blur(img: &mut Array2<f64>, sigma_px: f64) {
    let half = (4.0 * sigma_px).ceil() as isize;
    let mut k: Vec<f64> = (-half..=half)
        .map(|t| (-(t * t) as f64 / (2.0 * sigma_px * sigma_px)).exp())
        .collect();
    let s: f64 = k.iter().sum();
    k.iter_mut().for_each(|v| *v /= s);
    let (h, w) = img.dim();
    let mut tmp = Array2::zeros((h, w));
    for i in 0..h {
        for j in 0..w {
            let mut acc = 0.0;
            for (t, kv) in (-half..=half).zip(&k) {
                let jj = (j as isize + t).clamp(0, w as isize - 1) as usize;
                acc += kv * img[[i, jj]];
            }
            tmp[[i, j]] = acc;
        }
    }
    for i in 0..h {
        for j in 0..w {
            let mut acc = 0.0;
            for (t, kv) in (-half..=half).zip(&k) {
                let ii = (i as isize + t).clamp(0, h as isize - 1) as usize;
                acc += kv * tmp[[ii, j]];
            }
            img[[i, j]] = acc;
        }
    }
}

/// Quantise `gain · img + noise()` to integers in `0..=max_level` (e.g. 255
/// for 8-bit data), rounding to nearest. `noise` is called once per pixel in
/// row-major order.
pub fn quantize(
    img: &Array2<f64>,
    gain: f64,
    max_level: u16,
    mut noise: impl FnMut() -> f64,
) -> Array2<u16> {
    img.mapv(|v| (gain * v + noise()).round().clamp(0.0, max_level as f64) as u16)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disk_coverage_sums_to_the_disk_area() {
        // Σ coverage = πr² up to the midpoint-rule error (≤ 1e-4 per crossed
        // pixel × ~2πr·1.4 crossed pixels ≈ 0.02 px² here).
        let (cx, cz, r) = (20.37, 19.81, 12.3);
        let total: f64 = (0..40)
            .flat_map(|i| (0..40).map(move |j| disk_coverage(cx, cz, r, i, j)))
            .sum();
        let exact = std::f64::consts::PI * r * r;
        assert!((total - exact).abs() < 0.02, "{total} vs {exact}");
    }

    #[test]
    fn band_coverage_puts_the_line_where_it_should_be() {
        // Column sums of the band coverage over rows 0..40 = 40 − (line + ½)
        // exactly (a linear edge across a pixel averages to its centre value).
        let (row0, slope) = (17.3, 0.037);
        for j in 0..30 {
            let s: f64 = (0..40).map(|i| band_coverage(row0, slope, i, j)).sum();
            let want = 40.0 - (row0 + slope * j as f64 + 0.5);
            assert!((s - want).abs() < 1e-9, "column {j}: {s} vs {want}");
        }
    }
}
