//! The settings of the surface line's fit.

/// Settings of `fit_surface`.
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
    /// Fit the blurred step to each column's flank (module doc, step 2);
    /// `false`: the area row alone, a line to a small fraction of a pixel
    /// on a clean band top and to half a pixel on a structured one — enough
    /// where the line is only a bound (the background's coarse passes),
    /// without the flank fits' cost (most of the line's).
    pub flank_fits: bool,
}

impl Default for SurfaceParams {
    fn default() -> Self {
        SurfaceParams {
            rows: None,
            half_window: 5,
            min_contrast: 0.2,
            tukey_c: 4.685,
            min_scale_px: 0.005,
            flank_fits: true,
        }
    }
}
