//! Pass 1's state between frames ([`Pass1State`]): the prediction from the
//! last fits, the misses, the rise and the time away above the frame.

use super::frame::{Flag, FrameFlags, FrameTrack};
use super::look::{Look, Seen};
use crate::detect::Circle;

/// Predictions are rounded to multiples of this (px) before a frame is
/// measured around them. A frame's measurement is then the same bits
/// whether its prediction came from this thread's fits or from another
/// thread's fits of the same frames, which differ by ~1e-8 px once both
/// have a few frames behind them (see [`speculate`]); the rounding moves a
/// fit by `O(e σ²/R²)` with `e` ≤ 1/2048 px, below 1e-7 px.
pub(super) const PREDICTION_GRID_PX: f64 = 1.0 / 1024.0;

/// Pass 1's state between frames: the last three fits (for the
/// prediction), how many fits so far, misses in a row, searching or not,
/// the heights of the sphere's rise and, when it left through the top of
/// the frame, until when it is away.
#[derive(Debug, Clone, Default)]
pub(super) struct Pass1State {
    pub(super) history: Vec<(f64, Circle)>,
    pub(super) fits: usize,
    pub(super) misses: usize,
    pub(super) following: bool,
    /// `(t, z + r)` (px) of the fits since the sphere's lowest point last
    /// moved down (its rise from the bottom of the contact), the newest
    /// [`RISE_KEPT`].
    pub(super) rise: std::collections::VecDeque<(f64, f64)>,
    /// Frames before this time are not looked at ([`Look::Away`]).
    pub(super) away_until_s: Option<f64>,
}

/// The return of a sphere that left rising through the top of the frame
/// ([`Pass1State::return_s`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct Return {
    /// The time of its last fit.
    pub(super) t_last_s: f64,
    /// The time from there until its lowest point is back in the frame.
    pub(super) away_s: f64,
    /// The standard error of `away_s`.
    pub(super) away_err_s: f64,
    /// The rise's heights the parabola was fitted to.
    pub(super) heights: usize,
}

/// The row where a sphere coming back down through the top of the frame
/// comes into view: the top edge of row 0 (pixel centres at whole rows).
pub(super) const ENTRY_ROW_PX: f64 = -0.5;

/// A systematic error of the rise's heights (the lowest points of caps
/// leaving through the top of the frame), px, as a bend over the fitted
/// span ([`Pass1State::return_s`]). Measured on the bench's movies (the
/// first fit after each time away against the predicted return): on the
/// 60 000 frames/s `.cine`, whose 128 kept heights span 2.1 ms, 8–11 % of
/// the time away off, 1.3–2.0 times the scatter's standard error alone,
/// and within 0.9 σ with this bend (σ 13–15 % of the time away); on the
/// 10 000 frames/s one within 0.3 % (σ 1.3 %).
pub(super) const RISE_SYSTEMATIC_PX: f64 = 0.005;

/// Heights of the rise kept for [`Pass1State::back_in_view_s`].
pub(super) const RISE_KEPT: usize = 128;

/// Least fits of the rise that [`Pass1State::back_in_view_s`] takes.
pub(super) const RISE_FITS_MIN: usize = 8;

/// Standard errors of the predicted return ([`Pass1State::return_s`])
/// searched before it.
pub(super) const AWAY_SEARCHED_SIGMAS: f64 = 4.0;

/// Least share of the time away, at its end, searched again whatever the
/// parabola's scatter: what its error leaves out. A barrel lens bends the
/// rise's heights towards the centre harder near the top, so the apparent
/// curvature is larger and the return predicted early (searched longer);
/// air drag on a steel sphere of R ≥ 3 mm is below 1 % of its weight at
/// up to 3 m/s.
pub(super) const AWAY_SEARCHED_MIN_SHARE: f64 = 0.05;

/// Least heights of the rise whose scatter is trusted for the margin
/// (the standard deviation of 21 degrees of freedom is under 0.65 of the
/// true one in 1 % of rises); a shorter rise searches the last
/// [`AWAY_SEARCHED_SHORT_SHARE`] of the time away, or more.
pub(super) const AWAY_SCATTER_FITS_MIN: usize = 24;

/// Share of the time away searched after a rise of fewer than
/// [`AWAY_SCATTER_FITS_MIN`] heights: a quarter covers an error of a
/// quarter in its curvature.
pub(super) const AWAY_SEARCHED_SHORT_SHARE: f64 = 0.25;

impl Pass1State {
    /// Whether a sphere that a search could find is out of view: none
    /// fitted yet, or the last fit was leaving through the top of the
    /// frame (its circle past row 0). It then comes into view and stays
    /// there much longer than a stride of searches ([`SEARCH_STRIDE_S`]);
    /// one lost in view may be hidden or unmeasurable a frame or two at a
    /// time, and every frame is searched.
    pub(super) fn out_of_view(&self) -> bool {
        self.history
            .last()
            .is_none_or(|(_, c)| c.z_px - c.r_px < 0.0)
    }

    /// How to look at the frame of time `t`.
    pub(super) fn look(&self, t: f64) -> Look {
        if !self.following && self.away_until_s.is_some_and(|u| t < u) {
            return Look::Away;
        }
        if self.following {
            let p = predict(&self.history, t);
            let grid = |v: f64| (v / PREDICTION_GRID_PX).round() * PREDICTION_GRID_PX;
            Look::At(Circle {
                x_px: grid(p.x_px),
                z_px: grid(p.z_px),
                r_px: grid(p.r_px),
            })
        } else {
            Look::Search
        }
    }

    /// When the sphere that was just lost is back in view, if it left
    /// through the top of the frame while rising: the return predicted by
    /// [`Pass1State::return_s`] less a margin of [`AWAY_SEARCHED_SIGMAS`]
    /// standard errors, at least [`AWAY_SEARCHED_MIN_SHARE`] of the time
    /// away ([`AWAY_SEARCHED_SHORT_SHARE`] after a rise of fewer than
    /// [`AWAY_SCATTER_FITS_MIN`] heights), at most all of it. `None`
    /// (search every frame) when it left any other way, or the rise is
    /// short or not a parabola that falls back.
    pub(super) fn back_in_view_s(&self) -> Option<f64> {
        let back = self.return_s()?;
        let least = if back.heights < AWAY_SCATTER_FITS_MIN {
            AWAY_SEARCHED_SHORT_SHARE
        } else {
            AWAY_SEARCHED_MIN_SHARE
        };
        let margin_s = (AWAY_SEARCHED_SIGMAS * back.away_err_s)
            .max(least * back.away_s)
            .min(back.away_s);
        let t = back.t_last_s + back.away_s - margin_s;
        t.is_finite().then_some(t)
    }

    /// The parabola of the sphere's rise (least squares over the newer half
    /// of the rise's heights of its lowest point, at least
    /// [`RISE_FITS_MIN`]) brings that point back into the frame (to the top
    /// edge of row 0, [`ENTRY_ROW_PX`]) at its later root, with the
    /// standard error of that time: from the heights' scatter about the
    /// parabola and [`RISE_SYSTEMATIC_PX`] in quadrature. `None` when the last fit is not near the top of the frame
    /// (its top within a radius of row 0), the rise is short or not a
    /// parabola that falls back, or its lowest point never leaves the
    /// frame (a cap stays in view: it is searched for).
    pub(super) fn return_s(&self) -> Option<Return> {
        let &(t_last, last) = self.history.last()?;
        if last.z_px - last.r_px >= last.r_px {
            return None;
        }
        let n = self.rise.len();
        let used = if n == RISE_KEPT { n } else { n / 2 };
        if used < RISE_FITS_MIN {
            return None;
        }
        // h = a + b·u + c·u² (the lowest point's row less the entry row),
        // u = (t − t_last) / span.
        let (t, h): (Vec<f64>, Vec<f64>) = self
            .rise
            .iter()
            .skip(n - used)
            .map(|&(t, bottom)| (t, bottom - ENTRY_ROW_PX))
            .unzip();
        let fit = crate::util::lsq::PolyFit::fit(&t, &h, &vec![1.0; used], 2, t_last)?;
        let (a, b, c, span) = (fit.coef()[0], fit.coef()[1], fit.coef()[2], fit.x_scale);
        // Rising (h falls) at the last fit, and falling back (h″ > 0).
        if b >= 0.0 || c <= 0.0 || b.is_nan() || c.is_nan() {
            return None;
        }
        // Out of the frame only if the parabola's lowest h is below 0.
        let disc = b * b - 4.0 * a * c;
        if disc.is_nan() || disc <= 0.0 {
            return None;
        }
        let root = disc.sqrt();
        let u = (-b + root) / (2.0 * c);
        // The root's gradient in (a, b, c) is −(1, u, u²)/h′(u), h′(u) =
        // √disc; the coefficients' covariance scaled to the heights'
        // scatter (their stated σ of 1 px is no measurement).
        let cov = &fit.fit.cov * fit.fit.chi2_red();
        let g = [1.0 / root, u / root, u * u / root];
        let var_u = crate::util::lsq::quad_form(&g, &cov);
        // A systematic bend of the heights the fit cannot take up in a and
        // b: RISE_SYSTEMATIC_PX times the shifted Legendre P₂(2u + 1) =
        // 6u² + 6u + 1 over the fitted span (u from −1 to 0).
        let sys_u = RISE_SYSTEMATIC_PX * (g[0] + 6.0 * g[1] + 6.0 * g[2]);
        let (away_s, away_err_s) = (u * span, (var_u.max(0.0) + sys_u * sys_u).sqrt() * span);
        (away_s.is_finite() && away_s > 0.0 && away_err_s.is_finite()).then_some(Return {
            t_last_s: t_last,
            away_s,
            away_err_s,
            heights: used,
        })
    }

    /// Take frame `i`'s result: its track entry, the state moved on.
    pub(super) fn step(
        &mut self,
        meta: &crate::source::SourceMeta,
        i: usize,
        t: f64,
        seen: &Seen,
        w: usize,
        skip_away: bool,
    ) -> FrameTrack {
        let number = meta.frame_number(i);
        let mut flags = FrameFlags::default();
        let looked = match seen.look {
            Look::Search => {
                if seen.found && self.fits > 0 {
                    flags.insert(Flag::Recovered);
                }
                seen.found
            }
            Look::At(_) => true,
            Look::Away => false,
        };
        match seen.fit {
            Some(f) => {
                // The rise in the sphere's lowest point, z + r: on a cap
                // leaving through the top of the frame the free fit's
                // centre and radius wander together (r 72–79 px for a
                // 75 px sphere), its lowest edge does not. Higher than the
                // last fit also after a loss: a cap leaving slowly is lost
                // and found again frame after frame.
                let bottom = f.z_px + f.r_px;
                match self.history.last() {
                    Some(&(_, last)) if bottom < last.z_px + last.r_px => {
                        if self.rise.len() == RISE_KEPT {
                            self.rise.pop_front();
                        }
                        self.rise.push_back((t, bottom));
                    }
                    _ => self.rise.clear(),
                }
                self.away_until_s = None;
                self.misses = 0;
                self.following = true;
                self.fits += 1;
                if self.history.len() == 3 {
                    self.history.remove(0);
                }
                self.history.push((t, f.circle()));
                if f.z_px - f.r_px < 0.0 || f.x_px - f.r_px < 0.0 || f.x_px + f.r_px > w as f64 {
                    flags.insert(Flag::Partial);
                }
            }
            None => {
                if looked {
                    flags.insert(Flag::Missing);
                }
                self.misses += 1;
                if self.misses >= 2 && self.following {
                    self.following = false;
                    if skip_away {
                        self.away_until_s = self.back_in_view_s();
                    }
                }
            }
        }
        FrameTrack {
            index: i,
            frame: number,
            t_s: t,
            free: seen.fit,
            held: None,
            flags,
        }
    }
}

/// The next circle from the last three fits: constant acceleration through
/// them (Newton's divided differences), or constant velocity / position
/// with fewer.
pub fn predict(history: &[(f64, Circle)], t: f64) -> Circle {
    let m = history.len();
    let (t2, c2) = history[m - 1];
    if m < 2 {
        return c2;
    }
    let (t1, c1) = history[m - 2];
    let lin = |a: f64, b: f64| b + (b - a) / (t2 - t1) * (t - t2);
    let mut x = lin(c1.x_px, c2.x_px);
    let mut z = lin(c1.z_px, c2.z_px);
    if m >= 3 {
        let (t0, c0) = history[m - 3];
        let d01 = |a: f64, b: f64| (b - a) / (t1 - t0);
        let d12 = |a: f64, b: f64| (b - a) / (t2 - t1);
        let acc_z = (d12(c1.z_px, c2.z_px) - d01(c0.z_px, c1.z_px)) / (t2 - t0);
        let acc_x = (d12(c1.x_px, c2.x_px) - d01(c0.x_px, c1.x_px)) / (t2 - t0);
        z += acc_z * (t - t2) * (t - t1);
        x += acc_x * (t - t2) * (t - t1);
    }
    Circle {
        x_px: x,
        z_px: z,
        r_px: c2.r_px,
    }
}
