//! Small symmetric positive definite systems: solve, invert, and the
//! sandwich covariance.

/// Solve the symmetric positive definite system `A x = b` (small n) by
/// Cholesky; `None` when `A` is not positive definite.
pub(crate) fn solve_spd<const N: usize>(a: &[[f64; N]; N], b: &[f64; N]) -> Option<[f64; N]> {
    let mut l = [[0.0; N]; N];
    for i in 0..N {
        for j in 0..=i {
            let mut s = a[i][j];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            if i == j {
                if !(s > 0.0) {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    let mut y = [0.0; N];
    for i in 0..N {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i][k] * y[k];
        }
        y[i] = s / l[i][i];
    }
    let mut x = [0.0; N];
    for i in (0..N).rev() {
        let mut s = y[i];
        for k in i + 1..N {
            s -= l[k][i] * x[k];
        }
        x[i] = s / l[i][i];
    }
    Some(x)
}

/// Inverse of a symmetric positive definite matrix (n ≤ 3) by solving for the
/// unit vectors.
pub(super) fn inverse_spd<const N: usize>(a: &[[f64; N]; N]) -> Option<[[f64; N]; N]> {
    let mut inv = [[0.0; N]; N];
    for j in 0..N {
        let mut e = [0.0; N];
        e[j] = 1.0;
        let col = solve_spd(a, &e)?;
        for i in 0..N {
            inv[i][j] = col[i];
        }
    }
    Some(inv)
}

/// The M-estimator ("sandwich") covariance `A⁻¹ B A⁻¹ · n/(n − p)` with
/// `A = Σ ψ'(d) j jᵀ` (given inverted) and `B = Σ ψ(d)² j jᵀ`, ψ(d) = w·d
/// (Huber 1967): honest under robust weights, where `σ̂²(JᵀWJ)⁻¹`
/// understates the spread.
pub(super) fn sandwich<const N: usize>(
    a_inv: &[[f64; N]; N],
    b: &[[f64; N]; N],
    n: usize,
    p: usize,
) -> [[f64; N]; N] {
    let scale = n as f64 / (n as f64 - p as f64).max(1.0);
    let mut tmp = [[0.0; N]; N];
    for i in 0..N {
        for j in 0..N {
            tmp[i][j] = (0..N).map(|k| a_inv[i][k] * b[k][j]).sum();
        }
    }
    let mut out = [[0.0; N]; N];
    for i in 0..N {
        for j in 0..N {
            out[i][j] = scale * (0..N).map(|k| tmp[i][k] * a_inv[k][j]).sum::<f64>();
        }
    }
    out
}
