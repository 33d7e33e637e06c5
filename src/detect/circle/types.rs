//! What a circle fit takes and gives: [`Circle`], its [`Covariance`], the
//! [`CircleFit`] and the [`FitOptions`].

/// A circle in frame pixels (see the module convention in [`crate::detect`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Circle {
    /// Centre column.
    pub x_px: f64,
    /// Centre row (grows downward).
    pub z_px: f64,
    /// Radius.
    pub r_px: f64,
}

/// The covariance of a fit's parameters, in px²: the upper triangle of the
/// symmetric matrix, row by row (a track holds two fits a frame: 24 bytes
/// less each than the whole matrix).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Covariance {
    /// `(x, z, r)` fitted: `[xx, xz, xr, zz, zr, rr]`.
    Full([f64; 6]),
    /// Radius held: `(x, z)` only, `[xx, xz, zz]`.
    CentreOnly([f64; 3]),
}

impl Covariance {
    /// `(x, z, r)` from the whole matrix (its upper triangle).
    pub fn full(c: &[[f64; 3]; 3]) -> Self {
        Covariance::Full([c[0][0], c[0][1], c[0][2], c[1][1], c[1][2], c[2][2]])
    }
    /// `(x, z)` from the whole matrix (its upper triangle).
    pub fn centre_only(c: &[[f64; 2]; 2]) -> Self {
        Covariance::CentreOnly([c[0][0], c[0][1], c[1][1]])
    }
    /// Standard deviation of the centre column.
    pub fn sigma_x_px(&self) -> f64 {
        match self {
            Covariance::Full(c) => c[0].sqrt(),
            Covariance::CentreOnly(c) => c[0].sqrt(),
        }
    }
    /// Standard deviation of the centre row.
    pub fn sigma_z_px(&self) -> f64 {
        match self {
            Covariance::Full(c) => c[3].sqrt(),
            Covariance::CentreOnly(c) => c[2].sqrt(),
        }
    }
    /// Standard deviation of the radius; `None` when it was held.
    pub fn sigma_r_px(&self) -> Option<f64> {
        match self {
            Covariance::Full(c) => Some(c[5].sqrt()),
            Covariance::CentreOnly(_) => None,
        }
    }
}

/// The result of a robust circle fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CircleFit {
    /// Centre column (px).
    pub x_px: f64,
    /// Centre row (px, grows downward).
    pub z_px: f64,
    /// Radius (px); the held value when the radius was held.
    pub r_px: f64,
    /// Covariance of the fitted parameters (px²).
    pub cov: Covariance,
    /// RMS orthogonal residual of the inliers (px).
    pub residual_px: f64,
    /// Points given to the fit (the counts are 32-bit: a long movie's
    /// track holds two fits a frame).
    pub n_used: u32,
    /// Points with non-zero final weight.
    pub inliers: u32,
    /// IRLS iterations taken.
    pub iterations: u32,
    /// The residual scale of the last iteration (px): 1.4826·MAD, floored
    /// at `min_scale_px`, or the one given in [`FitOptions::scale_px`].
    pub scale_px: f64,
}

impl CircleFit {
    /// The fitted circle: centre and radius.
    pub fn circle(&self) -> Circle {
        Circle {
            x_px: self.x_px,
            z_px: self.z_px,
            r_px: self.r_px,
        }
    }
}

/// Settings of `fit_circle`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// Hold the radius at this value and fit only the centre.
    pub hold_radius: Option<f64>,
    /// Huber iterations before switching to Tukey's biweight.
    pub huber_iterations: usize,
    /// Maximum IRLS iterations in all.
    pub max_iterations: usize,
    /// Tukey's tuning constant in units of the residual scale (4.685 gives
    /// 95 % efficiency for Gaussian errors).
    pub tukey_c: f64,
    /// Floor of the residual scale (px), so that noiseless points do not
    /// reject each other over rounding.
    pub min_scale_px: f64,
    /// Fewest inliers for a valid fit.
    pub min_points: usize,
    /// Iterations stop once no parameter moves by more than this (px). The
    /// default, 1e-4 px, stops within 5e-5 px of the converged fit on noisy
    /// short arcs (tested), ~1/100 of the centre's statistical error on
    /// rendered drops.
    pub tolerance_px: f64,
    /// Standard deviation (px) of an error shared by all points along their
    /// radii (e.g. from the sphere's level or the frame's gain). A free radius
    /// absorbs it; with the radius held it moves the centre, and its share
    /// `σ_b² v vᵀ` is added to the covariance, `v` the fit's response to a
    /// unit radial shift of every point.
    pub radial_sigma_px: f64,
    /// Use this residual scale (px) throughout instead of the residuals'
    /// MAD: for a refit of points whose scale is already known (the
    /// held-radius refit of a free fit's points).
    pub scale_px: Option<f64>,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            hold_radius: None,
            huber_iterations: 2,
            max_iterations: 30,
            tukey_c: 4.685,
            min_scale_px: 1e-3,
            min_points: 6,
            tolerance_px: 1e-4,
            radial_sigma_px: 0.0,
            scale_px: None,
        }
    }
}
