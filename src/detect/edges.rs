//! Sub-pixel edge points of the sphere along normals to a predicted circle.
//!
//! # Method: the radial area (moment) estimator
//!
//! The sphere is a backlit silhouette: where it covers a pixel fully, the
//! pixel shows `τ·g·B` — the background `B` times the frame's flicker gain
//! `g` times the sphere's (small) transmission `τ`. So the sphere's share of
//! a pixel's area is `P = (1 − I/(g·B)) / (1 − τ)`: 1 inside, 0 outside,
//! exact under area sampling and any linear blur.
//!
//! Along the ray from the predicted centre `c` in direction `u`, the frame and
//! the background are sampled by bilinear interpolation at unit spacing
//! `t_j = r − w + j` (`j = 0..=2w`), at full bit depth, and each sample is
//! divided by its own background: `I_j/B_j`. (The background is not smooth
//! across columns: a sensor's column fixed pattern — a gain and an offset per
//! column — is in every frame and in `B` alike, and cancels only pixel by
//! pixel. Interpolating `1/B` linearly between the window's ends would
//! leave it in every sample of a window that crosses columns: at the real
//! preset's strongest pattern (1.5 %) the contact law's surface comes out
//! 0.1 px off.) `1/g` is interpolated linearly between the window's ends
//! (the flicker gain varies linearly across the frame). `τ` is the trimmed mean of
//! `I/(g·B)` over ~256 pixels of the upper half of a ring inside `r − 2w`,
//! clear of the blurred transition and the same part of the ball in flight
//! and in contact (`transmission`): a `τ` off by `ε` moves every edge
//! outward by `ε·w/(1 − τ)`, which a free radius absorbs but a held radius
//! on a short arc turns into a centre error, so it is averaged well. The
//! edge radius is then
//!
//! `t_e² = t_a² + 2 Σ_j P_j t_j`,   `t_a = t_0 − ½`,
//!
//! the midpoint rule for `t_e² = t_a² + 2∫ P(t) t dt`. For a disk of radius `R`
//! under any rotationally symmetric blur, `∫₀^∞ P(ρ) ρ dρ = R²/2` exactly
//! (blur preserves the disk's area), so `t_e = R`: no curved-edge bias. (The
//! ½-level contour and the gradient peak of a Gaussian-blurred disk both lie
//! at `R − σ²/2R`; this estimator does not share that bias.) Vertical motion
//! blur over a travel `L` moves the sides in by `L²/24R` only (0.01 px for
//! `L` = 4 px, `R` = 70 px) and leaves the centre at mid-exposure. A ray
//! through a centre off by `e` shifts `t_e` by `−e·u` (what the circle fit
//! needs) plus `O(e σ²/R²)`, negligible after one refinement pass.
//!
//! Because `P` enters linearly, the sum is accumulated while sampling:
//! `Σ P_j t_j = (Σ t_j − Σ q_j t_j)/(1 − τ)` with `q_j = I_j/(g·B_j)`, and
//! with `1/g_j = i_a + j·d` linear, `Σ q_j t_j` is a combination of the
//! three sample moments of `r_j = I_j/B_j`, `Σ r_j`, `Σ j r_j`, `Σ j² r_j`:
//! no sample is stored. Because the estimator integrates the profile instead of
//! locating a peak between samples, it has no pixel locking for an
//! axis-aligned edge (a sum of linearly interpolated samples at unit spacing
//! does not depend on their phase); the residual phase structure for oblique
//! normals is measured in the tests.
//!
//! # What is used
//!
//! A normal is used only when its whole window lies inside the band of rows
//! and its read columns ([`Band::cols`]: all of them, unless the band was
//! read as a window around the prediction), one pixel from the frame's
//! border (for the interpolation), above the
//! surface line minus `surface_margin_px` (the part below is hidden by
//! pillars and, near contact, may dip or mirror the sphere), when the
//! sphere's contrast `1 − τ` is at least `min_contrast`, and when the window
//! holds the edge (`P` > ½ at its inner end and < ½ at its outer end).
//!
//! # Cost
//!
//! `normals × (2w + 1)` bilinear samples of the frame and of the
//! background: proportional to the perimeter, independent of the frame
//! size. The windows are set up first, then sampled eight at a time with
//! AVX2 (two 32-bit gathers per sample fetch the frame's four neighbours,
//! four more the background's) or one at a time without, with the same
//! bits. All buffers live in
//! [`EdgeScratch`], reused from frame to frame.

use super::background::{Background, FrameGain};
use super::circle::{fit_circle, Circle, CircleFit, FitOptions, FitScratch};
pub use super::types::EdgePoint;
use super::types::SurfaceLine;
use super::{Band, DetectError};

/// Settings of [`edge_points`] and [`measure_circle`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeParams {
    /// Arc length between neighbouring normals (px). 3 px keeps neighbouring
    /// windows on different pixels, so point errors are nearly independent
    /// (the covariance assumes it); 2 px gives ~20 % smaller errors for 50 %
    /// more time.
    pub spacing_px: f64,
    /// At most this many normals around the full circle.
    pub max_normals: usize,
    /// Half-width `w` of the window along each normal (samples each side of
    /// the predicted edge, 1 px apart). It must cover the blurred transition
    /// (±3σ of the blur) plus the prediction error.
    pub half_window: usize,
    /// Windows must stay this far above the surface line (px).
    pub surface_margin_px: f64,
    /// Smallest sphere contrast `1 − τ` (τ the sphere's transmission).
    pub min_contrast: f64,
    /// At most this many edge-and-fit passes in [`measure_circle`]; each
    /// re-centres the normals on the previous fit.
    pub passes: usize,
    /// A further pass is made only when the last fit moved the centre or the
    /// radius by more than this (px) from where the normals were centred.
    pub recentre_px: f64,
}

impl Default for EdgeParams {
    fn default() -> Self {
        EdgeParams {
            spacing_px: 3.0,
            max_normals: 192,
            half_window: 6,
            surface_margin_px: 2.0,
            min_contrast: 0.3,
            passes: 2,
            recentre_px: 0.5,
        }
    }
}

/// Per-normal sums gathered while sampling.
#[derive(Debug, Clone, Copy)]
struct NormalSums {
    /// Direction (cos, sin).
    c: f64,
    s: f64,
    /// `Σ q_j t_j` with `q = I/(g·B)`.
    qt: f64,
    /// `q` at the window's inner and outer ends.
    q_in: f64,
    q_out: f64,
}

/// A normal ready to be sampled: its window's start and step in 16.16
/// fixed point (column, and row within the band), and `1/g` at its inner
/// end with its change per sample.
#[derive(Debug, Clone, Copy)]
struct Window {
    c: f64,
    s: f64,
    ia: f64,
    di: f64,
    xf: i32,
    zf: i32,
    dxf: i32,
    dzf: i32,
}

impl Window {
    /// The window from column `x` and band row `z` along `(c, s)`, with
    /// `1/g` = `ia` at its start changing by `di` per sample. Positions
    /// in 16.16 fixed point (1.5e-5 px steps): integer and fractional parts
    /// by shifts instead of float conversions.
    fn new(x: f64, z: f64, c: f64, s: f64, ia: f64, di: f64) -> Self {
        Window {
            c,
            s,
            ia,
            di,
            xf: (x * FIX) as i32,
            zf: (z * FIX) as i32,
            dxf: (c * FIX) as i32,
            dzf: (s * FIX) as i32,
        }
    }
}

/// The sample sums of one window: `S_k = Σ j^k r_j` with `r_j = I_j/B_j`,
/// and the first and last `r_j`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Samples {
    s0: f64,
    s1: f64,
    s2: f64,
    first: f64,
    last: f64,
}

/// Reusable buffers: one per thread, reused for every frame.
#[derive(Debug, Default, Clone)]
pub struct EdgeScratch {
    /// The edge points of the last call.
    pub points: Vec<EdgePoint>,
    normals: Vec<NormalSums>,
    windows: Vec<Window>,
    samples: Vec<Samples>,
    /// Directions (cos, sin) of all `table.len()` normals around the circle.
    table: Vec<(f64, f64)>,
    /// Work buffer for the transmission.
    levels: Vec<f64>,
    /// Standard deviation (px) of the error shared by all points of the last
    /// call along their radii, from the uncertainty of τ and of the gain.
    pub radial_sigma_px: f64,
    /// The circle fit's buffers.
    pub fit: FitScratch,
    /// The circle the normals of the last call were centred on.
    pub centre: Circle,
}

/// Sub-pixel edge points around `predicted` in `band` (see the module doc).
/// `frame_gain` is the frame's flicker gain ([`Background::gain`], taken at each
/// window's ends); `surface`, when given, hides everything below its line minus
/// the margin. The points are
/// left in `scratch.points` and returned.
pub fn edge_points<'s>(
    band: &Band,
    bg: &Background,
    frame_gain: FrameGain,
    predicted: &Circle,
    surface: Option<&SurfaceLine>,
    params: &EdgeParams,
    scratch: &'s mut EdgeScratch,
) -> Result<&'s [EdgePoint], DetectError> {
    // The gain at the sphere (the light may drift differently across the
    // frame: [`FrameGain::at`]); each window's ends take their own.
    let (gain, sigma_gain) = frame_gain.at(predicted.x_px);
    if band.width != bg.width || band.row0 + band.nrows > bg.height {
        return Err(DetectError::ShapeMismatch {
            width: band.width,
            height: band.row0 + band.nrows,
            bg_width: bg.width,
            bg_height: bg.height,
        });
    }
    let w = params.half_window;
    let m = 2 * w + 1;
    let (cx, cz, r) = (predicted.x_px, predicted.z_px, predicted.r_px);
    scratch.centre = *predicted;
    scratch.points.clear();
    scratch.normals.clear();
    scratch.levels.clear();
    scratch.radial_sigma_px = 0.0;
    if !(r.is_finite() && r > w as f64 + 1.0 && cx.is_finite() && cz.is_finite() && gain > 0.0) {
        return Ok(&scratch.points);
    }
    let circumference = std::f64::consts::TAU * r;
    let n = ((circumference / params.spacing_px.max(0.5)).round() as usize)
        .clamp(8, params.max_normals.max(8));
    let t0 = r - w as f64;
    let t1 = r + w as f64;
    let tl = r - 2.0 * w as f64;
    // Valid rows for interpolation: the band, one pixel in from the frame's edges.
    let z_lo = (band.row0 as f64).max(1.0);
    let z_hi = ((band.row0 + band.nrows) as f64 - 1.0).min(bg.height as f64 - 2.0);
    // Columns likewise: the band's read columns, one pixel in from the
    // frame's edges.
    let x_lo = (band.cols.0 as f64).max(1.0);
    let x_hi = band.cols.1.min(band.width) as f64 - 2.0;
    let visible = |x: f64, z: f64| -> bool {
        let inside = x >= x_lo && x <= x_hi && z >= z_lo && z < z_hi;
        let above = match surface {
            Some(s) => z < s.row_at(x) - params.surface_margin_px,
            None => true,
        };
        inside && above
    };
    unit_normals(&mut scratch.table, n);
    let row0 = band.row0 as f64;
    let last_j = (m - 1) as f64;
    scratch.windows.clear();
    for &(c, s) in &scratch.table {
        let (xa, za) = (cx + t0 * c, cz + t0 * s);
        let (xb, zb) = (cx + t1 * c, cz + t1 * s);
        if !(visible(xa, za) && visible(xb, zb)) {
            continue;
        }
        let Some(w) = lit_window(bg, &frame_gain, [(xa, za), (xb, zb)], (c, s), row0, last_j)
        else {
            continue;
        };
        // The window is a segment inside the (convex) visible region, so
        // every sample's four neighbours are inside the band; checked
        // here on the fixed-point positions as the samplers will step them.
        if window_inside(&w, m, band) {
            scratch.windows.push(w);
        }
    }
    // The background's rows of the band (checked above: the band lies
    // inside it, with the same width).
    let bg_rows = &bg.levels[band.row0 * band.width..(band.row0 + band.nrows) * band.width];
    sample_windows(band, bg_rows, m, &scratch.windows, &mut scratch.samples);
    normal_sums(
        &scratch.windows,
        &scratch.samples,
        t0,
        last_j,
        &mut scratch.normals,
    );
    if scratch.normals.is_empty() {
        return Ok(&scratch.points);
    }
    let (tau, sigma_tau) = transmission(
        band,
        bg,
        gain,
        predicted,
        tl,
        surface,
        params,
        &mut scratch.levels,
    )
    .unwrap_or_else(|| inner_samples_level(&mut scratch.levels, &scratch.normals));
    let contrast = 1.0 - tau;
    if !(contrast >= params.min_contrast && contrast > 0.0) {
        return Ok(&scratch.points);
    }
    // Errors shared by every point: τ and the gain move all edges along
    // their radii by (w + ½)/(1 − τ) times their relative error.
    let rel_gain = sigma_gain / gain;
    scratch.radial_sigma_px =
        (w as f64 + 0.5) / contrast * (sigma_tau * sigma_tau + rel_gain * rel_gain).sqrt();
    edge_points_on_normals(
        &scratch.normals,
        (cx, cz, r),
        t0,
        m,
        contrast,
        &mut scratch.points,
    );
    Ok(&scratch.points)
}

/// The window from `(xa, za)` to `(xb, zb)` along `(c, s)` (rows from
/// `row0`) where the background is lit at both ends (each sample is divided
/// by its own): 1/g at the ends, linear in between (`last_j` the last
/// sample's index).
fn lit_window(
    bg: &Background,
    frame_gain: &FrameGain,
    [(xa, za), (xb, zb)]: [(f64, f64); 2],
    (c, s): (f64, f64),
    row0: f64,
    last_j: f64,
) -> Option<Window> {
    let (Some(ba), Some(bb)) = (bg.bilinear(xa, za), bg.bilinear(xb, zb)) else {
        return None;
    };
    if !(ba > 0.0 && bb > 0.0) {
        return None;
    }
    let (ia, ib) = (1.0 / frame_gain.at(xa).0, 1.0 / frame_gain.at(xb).0);
    Some(Window::new(xa, za - row0, c, s, ia, (ib - ia) / last_j))
}

/// The unit normals `(cos, sin)` of `n` directions evenly around the
/// circle, in `table` (kept while `n` is unchanged).
fn unit_normals(table: &mut Vec<(f64, f64)>, n: usize) {
    if table.len() != n {
        table.clear();
        table.extend((0..n).map(|k| {
            let (s, c) = (std::f64::consts::TAU * k as f64 / n as f64).sin_cos();
            (c, s)
        }));
    }
}

/// Each window's normal sums from its samples' sums (`t0` the radius of
/// its first sample, `last_j` its last sample's index).
fn normal_sums(
    windows: &[Window],
    samples: &[Samples],
    t0: f64,
    last_j: f64,
    normals: &mut Vec<NormalSums>,
) {
    for (w, sm) in windows.iter().zip(samples) {
        // Σ q_j t_j = Σ r_j (ia + j·di)(t0 + j)
        //           = ia·t0·S0 + (ia + di·t0)·S1 + di·S2,  S_k = Σ j^k r_j:
        // three independent sums of the samples, the weights applied once.
        let (ia, di) = (w.ia, w.di);
        normals.push(NormalSums {
            c: w.c,
            s: w.s,
            qt: ia * t0 * sm.s0 + (ia + di * t0) * sm.s1 + di * sm.s2,
            q_in: sm.first * ia,
            q_out: sm.last * (ia + last_j * di),
        });
    }
}

/// The transmission when too little of the sphere's inside is visible: the
/// windows' innermost samples stand for it (their median, and its error
/// from their mean deviation), through `levels`.
fn inner_samples_level(levels: &mut Vec<f64>, normals: &[NormalSums]) -> (f64, f64) {
    // Too little of the sphere's inside is visible: the windows'
    // innermost samples stand for it.
    levels.clear();
    levels.extend(normals.iter().map(|n| n.q_in));
    let mid = levels.len() / 2;
    let tau = *levels.select_nth_unstable_by(mid, f64::total_cmp).1;
    let spread: f64 = levels.iter().map(|q| (q - tau).abs()).sum::<f64>() / levels.len() as f64;
    (tau, 1.25 * spread / (levels.len() as f64).sqrt())
}

/// The edge point on each normal whose inside and outside ends lie on
/// either side of half the contrast: at the radius `te` where the area
/// method puts the step (`(cx, cz, r)` the predicted circle, `t0` the
/// windows' first radius, `m` their samples).
fn edge_points_on_normals(
    normals: &[NormalSums],
    (cx, cz, r): (f64, f64, f64),
    t0: f64,
    m: usize,
    contrast: f64,
    points: &mut Vec<EdgePoint>,
) {
    let ta = t0 - 0.5;
    // Σ t_j over the window.
    let sum_t = m as f64 * r;
    for nrm in normals {
        let p_in = (1.0 - nrm.q_in) / contrast;
        let p_out = (1.0 - nrm.q_out) / contrast;
        if !(p_in > 0.5 && p_out < 0.5) {
            continue;
        }
        let area = (sum_t - nrm.qt) / contrast;
        let te2 = ta * ta + 2.0 * area;
        if !(te2 > 0.0) {
            continue;
        }
        let te = te2.sqrt();
        points.push(EdgePoint {
            x_px: cx + te * nrm.c,
            z_px: cz + te * nrm.s,
            weight: 1.0,
        });
    }
}

/// Fewest interior pixels for [`transmission`] to be trusted.
const MIN_INTERIOR: usize = 32;
/// Interior pixels aimed at by [`transmission`].
const TARGET_INTERIOR: f64 = 256.0;
/// [`transmission`] samples the inside between this fraction of `r_in` and `r_in`.
const INTERIOR_INNER_FRACTION: f64 = 0.6;

/// The sphere's transmission τ and its standard error: the trimmed mean of `I/(g·B)` over about
/// [`TARGET_INTERIOR`] pixels on a square grid in the upper half of the
/// ring between [`INTERIOR_INNER_FRACTION`]·`r_in` and `r_in` (clear of the
/// blurred edge), above the surface line minus the margin and inside the
/// band. An error `ε` in τ moves every edge by about `ε·w/(1−τ)`, so it is
/// averaged over many pixels (noise 2/200 per pixel → ε ≈ 6e-4 → 0.005
/// px). `None` when fewer than [`MIN_INTERIOR`] pixels qualify (a sphere
/// just entering the frame).
///
/// The upper half only: the same part of the ball in flight and in
/// contact. A polished ball's inside is not uniform (a highlight lights
/// part of it), so τ depends on which part is sampled; over the whole
/// visible inside that part shrank as the ball sank into the band, τ
/// changed, every edge moved with it, and with the radius held on the arc
/// left in contact the centre rose with δ: 0.07–0.09 px at δ = 42 px under
/// a 15 % highlight (the contact law's surface 0.16 px high, its exponent
/// 1.99). The upper half stays in view until δ nears R. The ring, not the
/// disk: the level nearer the edges, and less of the highlight (over the
/// upper half-disk the apparent radii of one set-up's drops spread by up
/// to 0.56 px with the highlight's strength, beyond what
/// [`crate::calibrate::setup_infer::EDGE_SPREAD_PX`] allows; over the ring 0.49,
/// the whole disk's 0.45).
#[allow(clippy::too_many_arguments)]
fn transmission(
    band: &Band,
    bg: &Background,
    gain: f64,
    c: &Circle,
    r_in: f64,
    surface: Option<&SurfaceLine>,
    params: &EdgeParams,
    values: &mut Vec<f64>,
) -> Option<(f64, f64)> {
    values.clear();
    if r_in <= 1.0 {
        return None;
    }
    let inner = INTERIOR_INNER_FRACTION * r_in;
    let half_annulus = 0.5 * std::f64::consts::PI * (r_in * r_in - inner * inner);
    let step = ((half_annulus / TARGET_INTERIOR).sqrt()).max(1.0);
    let n = (r_in / step).floor() as i64;
    let (z_lo, z_end) = (band.row0 as f64, (band.row0 + band.nrows) as f64);
    for a in -n..=0 {
        let z = c.z_px + a as f64 * step;
        // Nearest row (z + ½ truncated; the range check keeps it ≥ 0).
        let zr = z + 0.5;
        if zr < z_lo || zr >= z_end {
            continue;
        }
        let i = zr as usize;
        let dz2 = (z - c.z_px) * (z - c.z_px);
        for b in -n..=n {
            let x = c.x_px + b as f64 * step;
            let d2 = (x - c.x_px) * (x - c.x_px) + dz2;
            if d2 > r_in * r_in || d2 < inner * inner {
                continue;
            }
            let xr = x + 0.5;
            if xr < band.cols.0 as f64 || xr >= band.cols.1.min(band.width) as f64 {
                continue;
            }
            let j = xr as usize;
            if let Some(s) = surface {
                if (i as f64) >= s.row_at(j as f64) - params.surface_margin_px {
                    continue;
                }
            }
            let b_val = bg.at(i, j) as f64;
            if b_val > 0.0 {
                let v = band.data[(i - band.row0) * band.width + j] as f64;
                values.push(v / (gain * b_val));
            }
        }
    }
    if values.len() < MIN_INTERIOR {
        return None;
    }
    // Trimmed mean: drop the lowest and highest eighth (dust, glints); two
    // selections instead of a sort.
    let len = values.len();
    let cut = len / 8;
    values.select_nth_unstable_by(len - 1 - cut, f64::total_cmp);
    values[..len - cut].select_nth_unstable_by(cut, f64::total_cmp);
    let kept = &values[cut..len - cut];
    let k = kept.len() as f64;
    let mean = kept.iter().sum::<f64>() / k;
    // Standard error; the trimmed spread understates σ of a Gaussian by
    // ~1.5× for a 25 % trim, hence the factor.
    let var = kept.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (k - 1.0).max(1.0);
    Some((mean, 1.5 * (var / k).sqrt()))
}

/// Fixed-point scale of sample positions: 16 fractional bits.
const FIX: f64 = 65536.0;

/// Whether every sample of window `w` (`m` samples) has its four
/// neighbours inside the band: the rows and columns of the samples are
/// monotone along the window, so its ends bound them. Bands of 2¹⁵ columns
/// or rows or more (beyond 16.16 fixed point in 32 bits) have no windows.
fn window_inside(w: &Window, m: usize, band: &Band) -> bool {
    let steps = (m as i64 - 1).max(0);
    let (x0, z0) = (w.xf as i64, w.zf as i64);
    let (x1, z1) = (x0 + steps * w.dxf as i64, z0 + steps * w.dzf as i64);
    let (jmin, jmax) = (x0.min(x1) >> 16, x0.max(x1) >> 16);
    let (imin, imax) = (z0.min(z1) >> 16, z0.max(z1) >> 16);
    let width = band.width as i64;
    jmin >= band.cols.0 as i64
        && imin >= 0
        && jmax + 1 < width
        && jmax + 1 < band.cols.1 as i64
        && (imax + 1) * width + jmax + 1 < band.data.len() as i64
        && band.data.len() < (1 << 30)
        && band.width < (1 << 15)
        && band.nrows < (1 << 15)
}

/// The sums of every window's `m` samples `r_j = I_j/B_j` — the frame and
/// the background (`bg_rows`: its rows of the band) each interpolated
/// bilinearly in `f32`, divided in `f32` — summed in `f64`, into `out`:
/// eight windows at a time with AVX2
/// (gathers), one at a time without; the same operations in the same order
/// per window, so the same bits (tested).
fn sample_windows(
    band: &Band,
    bg_rows: &[f32],
    m: usize,
    windows: &[Window],
    out: &mut Vec<Samples>,
) {
    assert_eq!(
        bg_rows.len(),
        band.data.len(),
        "the background of the band's rows"
    );
    out.clear();
    out.resize(windows.len(), Samples::default());
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2, checked just above; every window
        // passed `window_inside`, and `bg_rows` has the band's shape.
        unsafe { sample_windows_avx2(band, bg_rows, m, windows, out) };
        return;
    }
    sample_windows_portable(band, bg_rows, m, windows, out);
}

fn sample_windows_portable(
    band: &Band,
    bg_rows: &[f32],
    m: usize,
    windows: &[Window],
    out: &mut [Samples],
) {
    for (w, o) in windows.iter().zip(out.iter_mut()) {
        let (mut xf, mut zf) = (w.xf, w.zf);
        let mut sm = Samples::default();
        for j in 0..m {
            let jf = j as f64;
            let v = (lerp_fixed(band.data, band.width, xf, zf)
                / lerp_fixed(bg_rows, band.width, xf, zf)) as f64;
            xf += w.dxf;
            zf += w.dzf;
            sm.s0 += v;
            sm.s1 += v * jf;
            sm.s2 += v * jf * jf;
            if j == 0 {
                sm.first = v;
            }
            sm.last = v;
        }
        *o = sm;
    }
}

/// [`sample_windows_portable`] on eight windows at a time: each sample's
/// four neighbours by two 32-bit gathers (a pixel and its right neighbour
/// are one 32-bit word), the interpolation in eight `f32` lanes, the sums
/// in two sets of four `f64` lanes.
///
/// # Safety
/// AVX2 must be present, and every window must pass [`window_inside`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn sample_windows_avx2(
    band: &Band,
    bg_rows: &[f32],
    m: usize,
    windows: &[Window],
    out: &mut [Samples],
) {
    use std::arch::x86_64::*;
    const L: usize = 8;
    let base = band.data.as_ptr() as *const i32;
    let below = band.data.as_ptr().wrapping_add(band.width) as *const i32;
    let bg_base = bg_rows.as_ptr();
    let bg_below = bg_rows.as_ptr().wrapping_add(band.width);
    let width = _mm256_set1_epi32(band.width as i32);
    let low = _mm256_set1_epi32(0xffff);
    let inv = _mm256_set1_ps(1.0 / 65536.0);
    let mut k = 0;
    while k < windows.len() {
        let n = (windows.len() - k).min(L);
        // Lanes past the last window repeat it; their sums are dropped.
        let lane = |f: fn(&Window) -> i32| {
            let mut v = [0i32; L];
            for (l, x) in v.iter_mut().enumerate() {
                *x = f(&windows[k + l.min(n - 1)]);
            }
            _mm256_loadu_si256(v.as_ptr() as *const __m256i)
        };
        let (mut x, mut z) = (lane(|w| w.xf), lane(|w| w.zf));
        let (dx, dz) = (lane(|w| w.dxf), lane(|w| w.dzf));
        let zero = _mm256_setzero_pd();
        let (mut s0, mut s1, mut s2) = ([zero; 2], [zero; 2], [zero; 2]);
        let (mut first, mut last) = ([zero; 2], [zero; 2]);
        for j in 0..m {
            let jf = _mm256_set1_pd(j as f64);
            let col = _mm256_srai_epi32::<16>(x);
            let row = _mm256_srai_epi32::<16>(z);
            let fx = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_and_si256(x, low)), inv);
            let fz = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_and_si256(z, low)), inv);
            let at = _mm256_add_epi32(_mm256_mullo_epi32(row, width), col);
            let top = _mm256_i32gather_epi32::<2>(base, at);
            let bot = _mm256_i32gather_epi32::<2>(below, at);
            let a = _mm256_cvtepi32_ps(_mm256_and_si256(top, low));
            let b = _mm256_cvtepi32_ps(_mm256_srli_epi32::<16>(top));
            let c = _mm256_cvtepi32_ps(_mm256_and_si256(bot, low));
            let d = _mm256_cvtepi32_ps(_mm256_srli_epi32::<16>(bot));
            let t = _mm256_add_ps(a, _mm256_mul_ps(fx, _mm256_sub_ps(b, a)));
            let u = _mm256_add_ps(c, _mm256_mul_ps(fx, _mm256_sub_ps(d, c)));
            let frame = _mm256_add_ps(t, _mm256_mul_ps(fz, _mm256_sub_ps(u, t)));
            // The background's four neighbours, the same interpolation.
            let next = _mm256_add_epi32(at, _mm256_set1_epi32(1));
            let a = _mm256_i32gather_ps::<4>(bg_base, at);
            let b = _mm256_i32gather_ps::<4>(bg_base, next);
            let c = _mm256_i32gather_ps::<4>(bg_below, at);
            let d = _mm256_i32gather_ps::<4>(bg_below, next);
            let t = _mm256_add_ps(a, _mm256_mul_ps(fx, _mm256_sub_ps(b, a)));
            let u = _mm256_add_ps(c, _mm256_mul_ps(fx, _mm256_sub_ps(d, c)));
            let back = _mm256_add_ps(t, _mm256_mul_ps(fz, _mm256_sub_ps(u, t)));
            let v = _mm256_div_ps(frame, back);
            let halves = [
                _mm256_cvtps_pd(_mm256_castps256_ps128(v)),
                _mm256_cvtps_pd(_mm256_extractf128_ps::<1>(v)),
            ];
            for h in 0..2 {
                let vj = _mm256_mul_pd(halves[h], jf);
                s0[h] = _mm256_add_pd(s0[h], halves[h]);
                s1[h] = _mm256_add_pd(s1[h], vj);
                s2[h] = _mm256_add_pd(s2[h], _mm256_mul_pd(vj, jf));
                if j == 0 {
                    first[h] = halves[h];
                }
                last[h] = halves[h];
            }
            x = _mm256_add_epi32(x, dx);
            z = _mm256_add_epi32(z, dz);
        }
        let lanes =
            |v: [__m256d; 2]| -> [f64; L] { std::mem::transmute::<[__m256d; 2], [f64; L]>(v) };
        let (s0, s1, s2) = (lanes(s0), lanes(s1), lanes(s2));
        let (first, last) = (lanes(first), lanes(last));
        for l in 0..n {
            out[k + l] = Samples {
                s0: s0[l],
                s1: s1[l],
                s2: s2[l],
                first: first[l],
                last: last[l],
            };
        }
        k += L;
    }
}

/// Bilinear interpolation of row-major `data` (`width` columns) at the
/// 16.16 fixed-point column `x` and local row `z`, both ≥ 0 with their right
/// and lower neighbours inside (the caller checks the window first).
#[inline(always)]
fn lerp_fixed<T: Copy + Into<f32>>(data: &[T], width: usize, x: i32, z: i32) -> f32 {
    let (j, i) = ((x >> 16) as usize, (z >> 16) as usize);
    const INV: f32 = 1.0 / 65536.0;
    let (fx, fz) = ((x & 0xffff) as f32 * INV, (z & 0xffff) as f32 * INV);
    let k = i * width + j;
    let quad = &data[k..k + width + 2];
    let (a, b): (f32, f32) = (quad[0].into(), quad[1].into());
    let (c, d): (f32, f32) = (quad[width].into(), quad[width + 1].into());
    let t = a + fx * (b - a);
    let u = c + fx * (d - c);
    t + fz * (u - t)
}

/// Edge points and a robust circle fit, up to `params.passes` times, each
/// pass re-centring the normals on the previous fit, until a fit lands
/// within `params.recentre_px` of the circle its normals were centred on. With `hold_radius` the radius
/// is held at that value (after calibration) and only the centre is fitted.
pub fn measure_circle(
    band: &Band,
    bg: &Background,
    predicted: &Circle,
    surface: Option<&SurfaceLine>,
    hold_radius: Option<f64>,
    params: &EdgeParams,
    scratch: &mut EdgeScratch,
) -> Result<CircleFit, DetectError> {
    let gain = bg.gain(band)?;
    let mut opts = FitOptions {
        hold_radius,
        ..FitOptions::default()
    };
    let mut circle = *predicted;
    if let Some(r) = hold_radius {
        circle.r_px = r;
    }
    let mut fit = None;
    for _ in 0..params.passes.max(1) {
        edge_points(band, bg, gain, &circle, surface, params, scratch)?;
        opts.radial_sigma_px = scratch.radial_sigma_px;
        let f = fit_circle(&scratch.points, Some(circle), &opts, &mut scratch.fit)?;
        let moved = (f.x_px - circle.x_px)
            .abs()
            .max((f.z_px - circle.z_px).abs())
            .max((f.r_px - circle.r_px).abs());
        circle = f.circle();
        fit = Some(f);
        if moved <= params.recentre_px {
            break;
        }
    }
    fit.ok_or(DetectError::TooFewPoints {
        what: "circle measurement",
        found: 0,
        needed: 1,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn the_avx2_and_portable_samplers_give_the_same_bits() {
        crate::test_support::require_avx2("the edge sampler");
        // A 12-bit band of noise over a background of noise, 1 to 40
        // windows in every direction (so that the last group of eight is
        // partial), 13 samples each.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let (width, nrows) = (97, 61);
        let data: Vec<u16> = (0..width * nrows).map(|_| rng.gen_range(0..4096)).collect();
        let bg_rows: Vec<f32> = (0..width * nrows)
            .map(|_| rng.gen_range(512.0..4096.0))
            .collect();
        let band = Band {
            data: &data,
            row0: 100,
            nrows,
            width,
            cols: (0, width),
        };
        let m = 13;
        for count in 1..=40 {
            let mut windows = Vec::new();
            while windows.len() < count {
                let a: f64 = rng.gen_range(0.0..std::f64::consts::TAU);
                let (x, z) = (
                    rng.gen_range(0.0..width as f64),
                    rng.gen_range(0.0..nrows as f64),
                );
                let w = Window::new(x, z, a.cos(), a.sin(), 1.0, 0.0);
                if window_inside(&w, m, &band) {
                    windows.push(w);
                }
            }
            let mut portable = vec![Samples::default(); count];
            sample_windows_portable(&band, &bg_rows, m, &windows, &mut portable);
            let mut chosen = Vec::new();
            sample_windows(&band, &bg_rows, m, &windows, &mut chosen);
            assert_eq!(portable, chosen, "{count} windows");
            // The sums are those of the samples I_j/B_j, each one divided
            // by its own background: recomputed in f64 from the
            // interpolated values they agree to f32's precision.
            for (p, w) in portable.iter().zip(&windows) {
                let (mut s0, mut s1, mut s2) = (0.0, 0.0, 0.0);
                let (mut xf, mut zf) = (w.xf, w.zf);
                for j in 0..m {
                    let r = lerp_fixed(&data, width, xf, zf) as f64
                        / lerp_fixed(&bg_rows, width, xf, zf) as f64;
                    let jf = j as f64;
                    (s0, s1, s2) = (s0 + r, s1 + r * jf, s2 + r * jf * jf);
                    xf += w.dxf;
                    zf += w.dzf;
                }
                for (got, want) in [(p.s0, s0), (p.s1, s1), (p.s2, s2)] {
                    assert!(
                        (got - want).abs() <= 1e-6 * want.abs().max(1.0),
                        "{got} {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn windows_reaching_out_of_the_band_are_refused() {
        let data = vec![0u16; 20 * 10];
        let band = Band {
            data: &data,
            row0: 0,
            nrows: 10,
            width: 20,
            cols: (0, 20),
        };
        let at = |x: f64, z: f64, c: f64, s: f64| Window::new(x, z, c, s, 1.0, 0.0);
        // 13 samples from column 2 to the right end at 14, row 4: inside.
        assert!(window_inside(&at(2.0, 4.0, 1.0, 0.0), 13, &band));
        // One column more and the last sample's right neighbour is column 20.
        assert!(!window_inside(&at(7.0, 4.0, 1.0, 0.0), 13, &band));
        // Down from row 0: the last sample at row 12 is below the band.
        assert!(!window_inside(&at(5.0, 0.0, 0.0, 1.0), 13, &band));
        // Up and left of the origin.
        assert!(!window_inside(&at(5.0, 5.0, -1.0, 0.0), 13, &band));
        assert!(!window_inside(&at(5.0, 5.0, 0.0, -1.0), 13, &band));
    }
}
