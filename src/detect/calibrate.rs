//! Calibration: the sphere's radius in pixels from the
//! free-flight frames where its whole circle is visible, and the scale.
//!
//! `R_px` is the median radius of the radius-free fits whose circle, widened
//! by the edge window, stays inside the frame and above the surface line
//! minus the margin; its uncertainty is `1.4826·MAD/√n`. The scale is
//! `s = R_mm / R_px` unless the run manifest gives `mm_per_px`; then the
//! manifest wins and a disagreement over 1 % is reported (SPEC §2).

use super::circle::CircleFit;
use super::edges::EdgeParams;
use super::types::SurfaceLine;

/// The calibrated radius.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RadiusCalibration {
    /// Median radius of the full-circle frames (px).
    pub r_px: f64,
    /// Its standard error, `1.4826·MAD/√n` (px).
    pub sigma_px: f64,
    /// Full-circle frames used.
    pub frames: usize,
}

/// Whether `fit`'s whole circle, widened by the edge window and one pixel,
/// lies inside a `width × height` frame and above the surface line minus
/// the margin — so that every normal of the circle was measurable.
pub fn full_circle(
    fit: &CircleFit,
    width: usize,
    height: usize,
    surface: Option<&SurfaceLine>,
    params: &EdgeParams,
) -> bool {
    let pad = params.half_window as f64 + 2.0;
    let (x, z, r) = (fit.x_px, fit.z_px, fit.r_px);
    let inside = x - r > pad
        && z - r > pad
        && x + r < width as f64 - 1.0 - pad
        && z + r < height as f64 - 1.0 - pad;
    let above = match surface {
        // The circle's lowest point against the line at that column (the
        // tilt moves the line by far less than the pad across the sphere).
        Some(s) => z + r < s.row_at(x) - params.surface_margin_px - pad,
        None => true,
    };
    inside && above
}

/// `R_px` from radius-free fits (see the module doc); `None` when fewer than
/// `min_frames` of them show the whole circle.
pub fn calibrate_radius(
    fits: &[CircleFit],
    width: usize,
    height: usize,
    surface: Option<&SurfaceLine>,
    params: &EdgeParams,
    min_frames: usize,
) -> Option<RadiusCalibration> {
    let mut r: Vec<f64> = fits
        .iter()
        .filter(|f| full_circle(f, width, height, surface, params))
        .map(|f| f.r_px)
        .collect();
    if r.is_empty() || r.len() < min_frames {
        return None;
    }
    r.sort_by(f64::total_cmp);
    let n = r.len();
    let median = if n % 2 == 1 {
        r[n / 2]
    } else {
        0.5 * (r[n / 2 - 1] + r[n / 2])
    };
    let mut dev: Vec<f64> = r.iter().map(|v| (v - median).abs()).collect();
    dev.sort_by(f64::total_cmp);
    let mad = dev[n / 2];
    Some(RadiusCalibration {
        r_px: median,
        sigma_px: 1.4826 * mad / (n as f64).sqrt(),
        frames: n,
    })
}

/// The scale of a run and where it came from.
#[derive(Debug, Clone, PartialEq)]
pub struct Scale {
    /// mm per px used downstream.
    pub mm_per_px: f64,
    /// `R_mm / R_px` from the sphere.
    pub from_sphere_mm_per_px: f64,
    /// Relative disagreement `from_sphere / manifest − 1`, when the manifest
    /// gives a scale.
    pub disagreement: Option<f64>,
    /// Set when the manifest and the sphere disagree by more than 1 %.
    pub warning: Option<String>,
}

/// The scale from the sphere (`R_mm / R_px`), or the manifest's when given,
/// with a warning when they disagree by more than 1 %.
pub fn scale(radius_mm: f64, cal: &RadiusCalibration, manifest_mm_per_px: Option<f64>) -> Scale {
    let from_sphere = radius_mm / cal.r_px;
    match manifest_mm_per_px {
        Some(m) => {
            let d = from_sphere / m - 1.0;
            Scale {
                mm_per_px: m,
                from_sphere_mm_per_px: from_sphere,
                disagreement: Some(d),
                warning: (d.abs() > 0.01).then(|| {
                    format!(
                        "mm_per_px {m} from the manifest and {from_sphere:.6} from the sphere \
                         (R {radius_mm} mm = {:.3} px) disagree by {:+.2} %: check the radius or the scale",
                        cal.r_px,
                        100.0 * d
                    )
                }),
            }
        }
        None => Scale {
            mm_per_px: from_sphere,
            from_sphere_mm_per_px: from_sphere,
            disagreement: None,
            warning: None,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::circle::Covariance;

    fn fit(x: f64, z: f64, r: f64) -> CircleFit {
        CircleFit {
            x_px: x,
            z_px: z,
            r_px: r,
            cov: Covariance::Full([0.0; 6]),
            residual_px: 0.0,
            n_used: 100,
            inliers: 100,
            iterations: 5,
            scale_px: 0.02,
        }
    }

    #[test]
    fn only_full_circles_count_and_the_median_wins() {
        let p = EdgeParams::default();
        let line = SurfaceLine::given(300.0, 0.0);
        let fits = [
            fit(256.0, 100.0, 80.01),
            fit(256.0, 110.0, 79.99),
            fit(256.0, 120.0, 80.00),
            fit(256.0, 50.0, 75.0),  // cut by the top of the frame
            fit(256.0, 225.0, 70.0), // in contact: too close to the line
        ];
        let c = calibrate_radius(&fits, 512, 384, Some(&line), &p, 3).unwrap();
        assert_eq!(c.frames, 3);
        assert!((c.r_px - 80.0).abs() < 1e-12);
        assert!(calibrate_radius(&fits, 512, 384, Some(&line), &p, 4).is_none());
        let s = scale(4.0, &c, None);
        assert!((s.mm_per_px - 0.05).abs() < 1e-12 && s.warning.is_none());
        let s = scale(4.0, &c, Some(0.0502));
        assert!(s.warning.is_none() && s.mm_per_px == 0.0502);
        let s = scale(4.0, &c, Some(0.051));
        let w = s.warning.expect("2 % off");
        assert!(w.contains("0.051") && w.contains('%'), "{w}");
    }
}
