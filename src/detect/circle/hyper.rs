//! The hyper algebraic circle fit (module doc, first item).

use super::types::Circle;
use crate::detect::types::EdgePoint;
use crate::detect::DetectError;

/// The hyper algebraic circle fit (Al-Sharadqah & Chernov 2009) of weighted
/// points; unbiased to second order in the noise, also on short arcs.
///
/// Derivation, for data centred on its weighted mean and scaled to unit RMS
/// distance: with `z = x² + y²` and moments `Mxx, Mxy, …`, the conditions
/// `(M − ηN)a = 0` eliminate `D = (2η − Mz)A` and give, with
/// `Δ(η) = (Mxx − η)(Myy − η) − Mxy²`,
/// `F(η) = [Mzz − (Mz + 2η)²]Δ(η) − Mxz²(Myy − η) − Myz²(Mxx − η) + 2MxzMyzMxy = 0`,
/// the centre `a = [Mxz(Myy − η) − MyzMxy] / 2Δ`, `b = [Myz(Mxx − η) − MxzMxy] / 2Δ`
/// and `r² = a² + b² + Mz − 2η`. `F(0) = det M ≥ 0`; Newton's method from 0
/// climbs to the smallest non-negative root.
pub fn hyper_fit(points: &[EdgePoint]) -> Result<Circle, DetectError> {
    const WHAT: &str = "hyper circle fit";
    let mut sw = 0.0;
    let (mut mx, mut mz) = (0.0, 0.0);
    for p in points.iter().filter(|p| p.weight > 0.0) {
        sw += p.weight;
        mx += p.weight * p.x_px;
        mz += p.weight * p.z_px;
    }
    let n = points.iter().filter(|p| p.weight > 0.0).count();
    if n < 3 {
        return Err(DetectError::TooFewPoints {
            what: WHAT,
            found: n,
            needed: 3,
        });
    }
    mx /= sw;
    mz /= sw;
    let mut s2 = 0.0;
    for p in points.iter().filter(|p| p.weight > 0.0) {
        s2 += p.weight * ((p.x_px - mx).powi(2) + (p.z_px - mz).powi(2));
    }
    let scale = (s2 / sw).sqrt();
    if !(scale.is_finite() && scale > 0.0) {
        return Err(DetectError::Degenerate {
            what: WHAT,
            reason: "all points coincide".into(),
        });
    }
    let (mut sxx, mut syy, mut sxy, mut sxz, mut syz, mut szz, mut sz) =
        (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for p in points.iter().filter(|p| p.weight > 0.0) {
        let x = (p.x_px - mx) / scale;
        let y = (p.z_px - mz) / scale;
        let z = x * x + y * y;
        let w = p.weight;
        sxx += w * x * x;
        syy += w * y * y;
        sxy += w * x * y;
        sxz += w * x * z;
        syz += w * y * z;
        szz += w * z * z;
        sz += w * z;
    }
    let (mxx, myy, mxy, mxz, myz, mzz, mz_) = (
        sxx / sw,
        syy / sw,
        sxy / sw,
        sxz / sw,
        syz / sw,
        szz / sw,
        sz / sw,
    );
    let f = |eta: f64| -> (f64, f64) {
        let delta = (mxx - eta) * (myy - eta) - mxy * mxy;
        let d_delta = 2.0 * eta - mxx - myy;
        let q = mz_ + 2.0 * eta;
        let g = mzz - q * q;
        let val =
            g * delta - mxz * mxz * (myy - eta) - myz * myz * (mxx - eta) + 2.0 * mxz * myz * mxy;
        let der = -4.0 * q * delta + g * d_delta + mxz * mxz + myz * myz;
        (val, der)
    };
    let mut eta = 0.0;
    for _ in 0..100 {
        let (val, der) = f(eta);
        if val == 0.0 || der == 0.0 {
            break;
        }
        let next = eta - val / der;
        if !next.is_finite() || next < 0.0 {
            break;
        }
        let done = (next - eta).abs() <= 1e-15 * next.abs().max(1e-300);
        eta = next;
        if done {
            break;
        }
    }
    let delta = (mxx - eta) * (myy - eta) - mxy * mxy;
    if delta.abs() < 1e-14 {
        return Err(DetectError::Degenerate {
            what: WHAT,
            reason: "the points are collinear".into(),
        });
    }
    let a = (mxz * (myy - eta) - myz * mxy) / (2.0 * delta);
    let b = (myz * (mxx - eta) - mxz * mxy) / (2.0 * delta);
    let r2 = a * a + b * b + mz_ - 2.0 * eta;
    if !(r2.is_finite() && r2 > 0.0) {
        return Err(DetectError::Degenerate {
            what: WHAT,
            reason: format!("radius² = {r2}"),
        });
    }
    Ok(Circle {
        x_px: mx + a * scale,
        z_px: mz + b * scale,
        r_px: r2.sqrt() * scale,
    })
}
