//! Frames off the sphere's flight: each frame in free flight checked
//! against its neighbours, and flagged [`super::Flag::Outlier`] when it is
//! far off them beyond its own error and theirs.
//!
//! In free flight the centre follows a parabola in time (gravity; air drag
//! changes the acceleration by ~1 % over a whole fall, nothing over a few
//! frames) and the apparent radius stays the same or drifts slowly (a ball
//! moving along the optical axis). A frame whose circle is off that path
//! by many times its reported σ was mismeasured (its edge points pulled by
//! something the model of the frame missed), and a fit through it would
//! take the error for motion.
//!
//! A frame is in flight when it has a held fit, is not `partial`, and its
//! circle's bottom is above the surface line by the margin. For each, the
//! `2 WINDOW` nearest frames in flight ([`WINDOW`] on each side where
//! there are, more on one side at the flight's ends), within the same
//! flight (no frame near or in contact between), give a weighted
//! least-squares quadratic in time of the held centre's `x` and `z` and of
//! the free radius `r`, without the frame itself; a neighbour that the
//! others put far off their own fit is dropped from it first (at most
//! two), so that one mismeasured frame does not make its neighbours look
//! off. The frame's normalised residual from that quadratic is
//!
//! `u = (y − ŷ) / √(σ_y² + σ_ŷ²)`,
//!
//! `σ_y` the frame's reported error, `σ_ŷ` the prediction's (from the
//! neighbours' reported errors). The frame is an outlier when, in any of
//! the three,
//!
//! `u² > THRESHOLD² · s²`,   `s² = max(1, median u² / 0.455)`
//!
//! the median over the [`SCATTER_WINDOW`] frames on each side (0.455 is the
//! median of u² for honest Gaussian errors): where the errors are reported
//! too small on some footage, or the neighbours scatter about a quadratic
//! beyond them, `s` widens the test with them, so only a frame far off
//! its neighbours compared with how far they are off each other is
//! flagged; where the errors are honest, `s = 1`.
//!
//! Contact frames are not checked: there the motion is not a parabola
//! (the force may jump at the onset), and a frame's residual from its
//! neighbours says nothing about its measurement.
//!
//! The frames are taken in order and at most `2 WINDOW + 2 SCATTER_WINDOW + 1`
//! are held at a time: the cost and the memory do not grow with the movie.

use std::collections::VecDeque;

/// Frames in flight on each side of a frame that predict it (twice as
/// many on one side at the ends of a flight).
pub const WINDOW: usize = 4;

/// Frames on each side whose residuals give the scatter `s` a frame's is
/// compared with.
pub const SCATTER_WINDOW: usize = 16;

/// How far off (in units of the combined σ, see the module doc) a frame
/// must be to be flagged. Five: an honest Gaussian error passes it once
/// in ~1.7 million frames, while a frame mismeasured by many times its
/// error (a real camera's frame 1.2 px off at σ = 0.08 px, from a
/// background that held part of the sphere) is far beyond it.
pub const THRESHOLD: f64 = 5.0;

/// Neighbours farther than this many frames (in index) are not used.
const REACH: usize = 3 * WINDOW;

/// Fewest neighbours for a quadratic's prediction with one degree of
/// freedom left to judge their scatter.
const MIN_NEIGHBOURS: usize = 4;

/// Neighbours far off the others dropped at most.
const MAX_DROPPED: usize = 2;

/// The median of a χ² variable of one degree of freedom: the median of
/// the squared normalised residuals when the errors are honest.
const CHI2_1_MEDIAN: f64 = 0.454_936;

/// One frame as the check sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// The frame's index (its record's position in the track).
    pub index: usize,
    /// Time of the frame, s.
    pub t_s: f64,
    /// Held centre column, row and free radius (px), each with its
    /// reported σ (px); a σ that is not finite and positive leaves that
    /// coordinate out of the check (no free radius with its error).
    pub values: [(f64, f64); 3],
}

/// A frame of the movie, in order, for [`Outliers::push`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Seen {
    /// In free flight: checked, and a neighbour of the frames around.
    Flight(Sample),
    /// No usable fit (missing, or the circle leaves the frame): skipped,
    /// the flight goes on across it.
    Skip,
    /// Near or in contact: the flight ends here.
    Break,
}

/// A frame of the current flight and, once its neighbours are in, its
/// squared normalised residuals (NaN for a coordinate not checked).
#[derive(Debug, Clone, Copy)]
struct Held {
    sample: Sample,
    u2: Option<[f64; 3]>,
}

/// The streaming check (see the module doc): push every frame in order,
/// then [`Outliers::finish`] for the indices of the outliers.
#[derive(Debug, Default)]
pub struct Outliers {
    /// The current flight's frames still needed: up to `2 WINDOW` before
    /// the next whose residual is computed, and up to `SCATTER_WINDOW`
    /// before the next decided.
    held: VecDeque<Held>,
    /// Position in `held` of the next frame whose residual is computed.
    next_residual: usize,
    /// Position in `held` of the next frame decided.
    next_decided: usize,
    flagged: Vec<usize>,
}

impl Outliers {
    /// Take the next frame of the movie, in order.
    pub fn push(&mut self, seen: Seen) {
        match seen {
            Seen::Flight(sample) => {
                self.held.push_back(Held { sample, u2: None });
                while self.held.len() - self.next_residual > 2 * WINDOW {
                    self.residual();
                }
                while self.next_residual - self.next_decided > SCATTER_WINDOW {
                    self.decide();
                }
                while self.next_decided > SCATTER_WINDOW && self.next_residual > 2 * WINDOW {
                    self.held.pop_front();
                    self.next_residual -= 1;
                    self.next_decided -= 1;
                }
            }
            Seen::Skip => {}
            Seen::Break => self.end_flight(),
        }
    }

    /// The indices of the outlier frames, in order.
    pub fn finish(mut self) -> Vec<usize> {
        self.end_flight();
        self.flagged
    }

    fn end_flight(&mut self) {
        while self.next_residual < self.held.len() {
            self.residual();
        }
        while self.next_decided < self.held.len() {
            self.decide();
        }
        self.held.clear();
        self.next_residual = 0;
        self.next_decided = 0;
    }

    /// The squared normalised residuals of the frame at `next_residual`
    /// from its `2 WINDOW` nearest neighbours (the earlier of two as near).
    fn residual(&mut self) {
        let c = self.next_residual;
        let me = self.held[c].sample;
        let mut near: Vec<&Sample> = self
            .held
            .iter()
            .enumerate()
            .filter(|&(k, h)| k != c && h.sample.index.abs_diff(me.index) <= REACH)
            .map(|(_, h)| &h.sample)
            .collect();
        near.sort_by_key(|s| (s.index.abs_diff(me.index), s.index));
        near.truncate(2 * WINDOW);
        let u2 = std::array::from_fn(|q| {
            let (y, sigma) = me.values[q];
            if !usable(sigma) {
                return f64::NAN;
            }
            let points: Vec<(f64, f64, f64)> = near
                .iter()
                .filter(|s| usable(s.values[q].1))
                .map(|s| (s.t_s - me.t_s, s.values[q].0, s.values[q].1))
                .collect();
            match predict(&points) {
                Some((y_hat, var_hat)) => (y - y_hat).powi(2) / (sigma * sigma + var_hat),
                None => f64::NAN,
            }
        });
        self.held[c].u2 = Some(u2);
        self.next_residual += 1;
    }

    /// Flag the frame at `next_decided` when a residual of it is beyond
    /// [`THRESHOLD`] times the scatter `s` of the residuals around it:
    /// `s² = max(1, median u² / median χ²₁)` over the `SCATTER_WINDOW`
    /// frames on each side with one (the frame's own left out).
    fn decide(&mut self) {
        let c = self.next_decided;
        let Some(u2) = self.held[c].u2 else {
            self.next_decided += 1;
            return;
        };
        let lo = c.saturating_sub(SCATTER_WINDOW);
        let hi = (c + SCATTER_WINDOW + 1).min(self.held.len());
        let off = (0..3).any(|q| {
            if !u2[q].is_finite() {
                return false;
            }
            let mut around: Vec<f64> = (lo..hi)
                .filter(|&k| k != c)
                .filter_map(|k| self.held[k].u2.map(|u| u[q]))
                .filter(|v| v.is_finite())
                .collect();
            let s2 = if around.is_empty() {
                1.0
            } else {
                (median(&mut around) / CHI2_1_MEDIAN).max(1.0)
            };
            u2[q] > THRESHOLD * THRESHOLD * s2
        });
        if off {
            self.flagged.push(self.held[c].sample.index);
        }
        self.next_decided += 1;
    }
}

fn usable(sigma: f64) -> bool {
    sigma.is_finite() && sigma > 0.0
}

/// The median of a non-empty slice (reorders it).
fn median(v: &mut [f64]) -> f64 {
    let n = v.len();
    let upper = *v.select_nth_unstable_by(n / 2, f64::total_cmp).1;
    if n % 2 == 1 {
        upper
    } else {
        let lower = v[..n / 2].iter().copied().fold(f64::NEG_INFINITY, f64::max);
        0.5 * (lower + upper)
    }
}

/// The value at `Δt = 0` of the weighted least-squares quadratic through
/// `points` (`Δt` s, value, σ) and its variance; `None` with fewer than
/// [`MIN_NEIGHBOURS`] points. Up to [`MAX_DROPPED`] points are dropped
/// first, one at a time: the one farthest off the fit of the others, when
/// beyond [`THRESHOLD`] times their scatter (`max(1, χ²/ν)` of that fit) —
/// so a frame mismeasured among the neighbours is not taken for the path,
/// while errors reported too small everywhere drop nothing. The fit of
/// the others is not made: with the leverage `h` of a point in the fit of
/// all, its residual `e` from that fit and its σ, the others' fit puts it
/// off by `t² = e² / (σ² (1 − h))` of its combined error, and their
/// `χ²` is the fit's less `t²`.
fn predict(points: &[(f64, f64, f64)]) -> Option<(f64, f64)> {
    let mut used: Vec<(f64, f64, f64)> = points.to_vec();
    let mut dropped = 0;
    loop {
        if used.len() < MIN_NEIGHBOURS {
            return None;
        }
        let fit = Quadratic::fit(&used)?;
        if dropped < MAX_DROPPED && used.len() > MIN_NEIGHBOURS {
            let (mut chi2, mut worst, mut worst_t2) = (0.0, 0, 0.0);
            for (k, &(dt, y, s)) in used.iter().enumerate() {
                let (y_hat, var_hat) = fit.at(dt);
                let u2 = ((y - y_hat) / s).powi(2);
                chi2 += u2;
                let leverage = (var_hat / (s * s)).min(1.0 - 1e-9);
                let t2 = u2 / (1.0 - leverage);
                if t2 > worst_t2 {
                    (worst, worst_t2) = (k, t2);
                }
            }
            let others_dof = (used.len() - 4) as f64;
            let s2 = ((chi2 - worst_t2).max(0.0) / others_dof).max(1.0);
            if worst_t2 > THRESHOLD * THRESHOLD * s2 {
                used.remove(worst);
                dropped += 1;
                continue;
            }
        }
        return Some(fit.at(0.0));
    }
}

/// A weighted least-squares quadratic `y = c₀ + c₁u + c₂u²` in the scaled
/// time `u = Δt / span`, with the inverse of its normal matrix.
struct Quadratic {
    span: f64,
    coef: [f64; 3],
    inv: [[f64; 3]; 3],
}

impl Quadratic {
    /// The fit through `points` (`Δt` s, value, σ); `None` when singular
    /// (fewer than three distinct times).
    #[allow(clippy::needless_range_loop)]
    fn fit(points: &[(f64, f64, f64)]) -> Option<Quadratic> {
        let span = points.iter().map(|p| p.0.abs()).fold(0.0, f64::max);
        if span.is_nan() || span <= 0.0 {
            return None;
        }
        let mut ata = [[0.0; 3]; 3];
        let mut atb = [0.0; 3];
        for &(dt, y, s) in points {
            let u = dt / span;
            let b = [1.0, u, u * u];
            let w = 1.0 / (s * s);
            for i in 0..3 {
                atb[i] += w * b[i] * y;
                for j in 0..3 {
                    ata[i][j] += w * b[i] * b[j];
                }
            }
        }
        let inv = invert3(&ata)?;
        let coef = std::array::from_fn(|i| (0..3).map(|j| inv[i][j] * atb[j]).sum());
        Some(Quadratic { span, coef, inv })
    }

    /// The value at `Δt` and its variance.
    fn at(&self, dt: f64) -> (f64, f64) {
        let u = dt / self.span;
        let b = [1.0, u, u * u];
        let value = (0..3).map(|i| self.coef[i] * b[i]).sum();
        let var: f64 = (0..3)
            .flat_map(|i| (0..3).map(move |j| (i, j)))
            .map(|(i, j)| b[i] * self.inv[i][j] * b[j])
            .sum();
        (value, var.max(0.0))
    }
}

/// The inverse of a 3 × 3 matrix; `None` when (nearly) singular.
fn invert3(m: &[[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let cof =
        |r0: usize, r1: usize, c0: usize, c1: usize| m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0];
    let adj = [
        [cof(1, 2, 1, 2), -cof(0, 2, 1, 2), cof(0, 1, 1, 2)],
        [-cof(1, 2, 0, 2), cof(0, 2, 0, 2), -cof(0, 1, 0, 2)],
        [cof(1, 2, 0, 1), -cof(0, 2, 0, 1), cof(0, 1, 0, 1)],
    ];
    let det = m[0][0] * adj[0][0] + m[0][1] * adj[1][0] + m[0][2] * adj[2][0];
    let scale = m.iter().flatten().map(|v| v.abs()).fold(0.0, f64::max);
    if det.is_nan() || det.abs() <= 1e-12 * scale * scale * scale {
        return None;
    }
    Some(adj.map(|row| row.map(|v| v / det)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A fall at 10 000 frames/s: z = 100 + 2.5 k + 0.01 k² px, x drifting
    /// 0.01 px a frame, r = 60 px, each with Gaussian noise of its σ
    /// (0.02 px for the centre, 0.015 for the radius).
    fn fall(n: usize, seed: u64) -> Vec<Sample> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut gauss = move || {
            // Box–Muller.
            let (u1, u2): (f64, f64) = (rng.gen_range(1e-12..1.0), rng.gen_range(0.0..1.0));
            (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        };
        (0..n)
            .map(|k| {
                let kf = k as f64;
                Sample {
                    index: k,
                    t_s: kf * 1e-4,
                    values: [
                        (175.0 + 0.01 * kf + 0.02 * gauss(), 0.02),
                        (100.0 + 2.5 * kf + 0.01 * kf * kf + 0.02 * gauss(), 0.02),
                        (60.0 + 0.015 * gauss(), 0.015),
                    ],
                }
            })
            .collect()
    }

    fn check(seen: impl IntoIterator<Item = Seen>) -> Vec<usize> {
        let mut o = Outliers::default();
        for s in seen {
            o.push(s);
        }
        o.finish()
    }

    #[test]
    fn an_honest_fall_has_no_outlier() {
        for seed in 0..20 {
            let flagged = check(fall(400, seed).into_iter().map(Seen::Flight));
            assert!(flagged.is_empty(), "seed {seed}: {flagged:?}");
        }
    }

    #[test]
    fn a_frame_off_by_ten_sigma_is_flagged_and_its_neighbours_are_not() {
        // Off in z, in x, in the radius; at the start, inside, at the
        // last frame (predicted from one side only), and two in a row.
        // At the ends, extrapolated from one side, the prediction's own
        // error is about twice the frame's: 20σ off there.
        for (at, q, by) in [
            (0usize, 1usize, 0.4),
            (57, 1, -0.2),
            (58, 0, 0.2),
            (120, 2, -0.15),
            (199, 1, 0.4),
        ] {
            let mut s = fall(200, 3);
            s[at].values[q].0 += by;
            let flagged = check(s.into_iter().map(Seen::Flight));
            assert_eq!(flagged, vec![at], "{at} off by {by} in {q}");
        }
        let mut s = fall(200, 4);
        s[80].values[1].0 += 0.3;
        s[81].values[1].0 -= 0.3;
        assert_eq!(check(s.into_iter().map(Seen::Flight)), vec![80, 81]);
    }

    #[test]
    fn errors_reported_too_small_everywhere_flag_nothing_but_a_frame_off_its_neighbours() {
        // The same fall with σ reported 3× too small: the neighbours'
        // scatter widens the test (s²), so nothing is flagged; a frame off
        // by 0.3 px (5× the true noise of 0.02, 45× the reported σ) still is.
        let shrink = |mut s: Sample| {
            for v in s.values.iter_mut() {
                v.1 /= 3.0;
            }
            s
        };
        let flagged = check(fall(300, 5).into_iter().map(shrink).map(Seen::Flight));
        assert!(flagged.is_empty(), "{flagged:?}");
        let mut s = fall(300, 5);
        s[150].values[1].0 += 0.3;
        let flagged = check(s.into_iter().map(shrink).map(Seen::Flight));
        assert_eq!(flagged, vec![150]);
    }

    #[test]
    fn contact_is_not_checked_and_ends_the_flight() {
        // A jump of 5 px between the two flights (a bounce): each flight is
        // fitted on its own, so neither side's frames are off.
        let s = fall(100, 6);
        let mut seen: Vec<Seen> = s[..40].iter().copied().map(Seen::Flight).collect();
        seen.extend([Seen::Break; 5]);
        seen.extend(s[45..].iter().map(|f| {
            let mut f = *f;
            f.values[1].0 -= 5.0;
            Seen::Flight(f)
        }));
        assert!(check(seen).is_empty());
        // Skipped frames (missing) do not end it: a frame off right after
        // a missing one is still compared with both sides.
        let mut s = fall(100, 7);
        s[51].values[1].0 += 0.2;
        let seen = s.iter().enumerate().map(|(k, f)| {
            if k == 50 {
                Seen::Skip
            } else {
                Seen::Flight(*f)
            }
        });
        assert_eq!(check(seen), vec![51]);
    }

    #[test]
    fn a_frame_without_a_radius_error_is_checked_on_its_centre_only() {
        let mut s = fall(60, 8);
        s[30].values[2] = (40.0, f64::NAN);
        assert!(check(s.iter().copied().map(Seen::Flight)).is_empty());
        s[30].values[1].0 += 0.2;
        assert_eq!(check(s.into_iter().map(Seen::Flight)), vec![30]);
    }
}
