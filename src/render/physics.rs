//! The contact mechanics of one drop: free fall, elastic-foundation contact,
//! rebound, free flight, and possibly further bounces — integrated once, then
//! queried at any time for the exact truth the renderer draws and reports.
//!
//! # Model
//!
//! The state is the signed depth `d` (m) of the sphere's lowest point below
//! the undeformed surface (negative in flight) and its rate `w = ḋ` (m/s,
//! positive downward). The penetration is `δ = max(d, 0)`. With sphere mass
//! `m = (4/3) π R³ ρ`, gravity `g` and the elastic-foundation force of
//! Chastel et al. (Maruoka 2019, text above Eq. (2); SPEC §3)
//!
//! ```text
//!     F(δ) = K δ²,   K = π E φ R / h,
//! ```
//!
//! plus an optional linear damping `c ḋ` while in contact, the motion is
//!
//! ```text
//!     m d̈ = m g − [d > 0] (K d² + c ḋ).
//! ```
//!
//! That is the model the measurement is built on, and the renderer's
//! default. A [`ContactLaw`] widens it to contacts the model does not
//! describe:
//!
//! ```text
//!     F = K_n δ^n (1 + α ḋ) + c ḋ
//! ```
//!
//! with any elastic exponent `n` and stiffness `K_n` (N/m^n), linear
//! damping `c` and Hunt–Crossley damping `α` (s/m), and a force that may pull
//! (adhesion: the sphere stays on the surface until `δ = 0`) or not. Without
//! adhesion the force is clamped at 0: the sphere leaves the deformed
//! surface when `F` reaches 0 on the way out (`t_force_zero`, δ still > 0)
//! and flies freely from there; the contact as the renderer reports it
//! still runs from `δ` crossing 0 going down to `δ` returning to 0 (the
//! sphere's bottom back on the undeformed line), and the rebound speed is
//! the speed there.
//!
//! Flight phases are integrated exactly (parabolas). Each contact phase starts
//! exactly at `d = 0` (from the analytic flight) and is integrated with the
//! classical fourth-order Runge–Kutta method at a fixed step. The events
//! (maximum penetration `ḋ = 0`, loss of contact `d = 0`, and without
//! adhesion the force's zero `F = 0`) are located by bisection on the
//! Runge–Kutta step map `h ↦ Φ_h(state)` from the last grid state, i.e. on
//! the continuous extension of the discrete solution, to floating-point
//! resolution — never rounded to a grid step. The state at an arbitrary time
//! in contact is `Φ_{t − t_k}(state_k)` from the grid state just before it,
//! so truth and pictures come from the same dense solution.
//!
//! Without gravity and damping, energy conservation gives Eq. (4) of
//! Maruoka 2019, `δmax/R = (2/φ)^{1/3} (h/R)^{1/3} (ρv²/E)^{1/3}`, and Eq. (5),
//! `τc = (2/3) B(1/3, 1/2) δmax / v`; for any `n`,
//! `δmax = ((n + 1) m v² / (2 K_n))^{1/(n+1)}` and
//! `τc = 2/(n + 1) · B(1/(n + 1), 1/2) · δmax / v`. The tests hold the
//! integrator to these.

use crate::config::Surface;
use std::f64::consts::PI;

/// Standard gravity used by the renderer (SPEC §1), m/s².
pub const STANDARD_GRAVITY_M_S2: f64 = 9.81;

/// The Beta function `B(1/3, 1/2) = Γ(1/3) Γ(1/2) / Γ(5/6)` (SPEC §3, Eq. (5)
/// of Maruoka 2019). Checked by quadrature in the tests.
pub const BETA_THIRD_HALF: f64 = 4.206_546_315_976_364;

/// Why a drop cannot be simulated.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PhysicsError {
    /// A drop parameter is out of range.
    #[error("drop parameter `{name}` = {value}: {allowed}")]
    InvalidParameter {
        /// The parameter's name.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What is allowed.
        allowed: &'static str,
    },
    /// The damping is so strong that the sphere does not leave the surface within the time limit.
    #[error(
        "the sphere did not leave the surface within {limit_s:.3e} s of contact at t = {t_contact_s:.6e} s \
         (damping c = {damping_n_s_m:.4e} N·s/m, α = {hunt_crossley_s_m:.4e} s/m too strong): ask for a larger restitution"
    )]
    NoRebound {
        /// Contact onset, s.
        t_contact_s: f64,
        /// The longest contact simulated, s.
        limit_s: f64,
        /// Linear damping c, N·s/m.
        damping_n_s_m: f64,
        /// Hunt–Crossley damping α, s/m.
        hunt_crossley_s_m: f64,
    },
    /// No damping coefficient gives the restitution asked for: the sphere sticks.
    #[error("restitution {requested} cannot be reached with {damping} damping (the sphere sticks); ask for a larger restitution")]
    RestitutionUnreachable {
        /// The restitution asked for.
        requested: f64,
        /// The kind of damping (`linear`, `hunt_crossley`).
        damping: &'static str,
    },
    /// Without adhesion, the sphere leaves the surface too slowly to rise back above the undeformed line.
    #[error(
        "the sphere left the surface at t = {t_s:.6e} s with δ = {delta_m:.3e} m still below the \
         undeformed line and too slow ({speed_m_s:.3e} m/s) to rise back to it: ask for a larger restitution"
    )]
    FallsBackInside {
        /// When the force reached 0, s.
        t_s: f64,
        /// The penetration δ then, m.
        delta_m: f64,
        /// The sphere's upward speed then, m/s.
        speed_m_s: f64,
    },
}

/// How the contact dissipates energy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Damping {
    /// None: the restitution is 1.
    None,
    /// Linear (viscous): `c ḋ`.
    Linear,
    /// Hunt–Crossley: `α K_n δ^n ḋ`, vanishing with δ at the contact's ends.
    HuntCrossley,
}

impl Damping {
    /// The name written to `truth.json`: `none`, `linear` or `hunt_crossley`.
    pub fn name(self) -> &'static str {
        match self {
            Damping::None => "none",
            Damping::Linear => "linear",
            Damping::HuntCrossley => "hunt_crossley",
        }
    }
}

/// The contact force beyond the model's `K δ²`: `F = K_n δ^n (1 + α ḋ) + c ḋ`
/// (the linear coefficient `c` is [`DropParams::damping_n_s_m`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactLaw {
    /// Elastic exponent n.
    pub exponent: f64,
    /// K_n, N/m^n; `None`: the model's `K = π E φ R / h` (with n = 2).
    pub stiffness_n_per_m_n: Option<f64>,
    /// Hunt–Crossley coefficient α, s/m (0 = none).
    pub hunt_crossley_s_m: f64,
    /// The force may pull (true, the model's), or is clamped at F ≥ 0 and
    /// the sphere leaves the surface where it reaches 0.
    pub adhesion: bool,
}

impl ContactLaw {
    /// The measurement's model: `K δ²` with `K = π E φ R / h`, a force that
    /// may pull, no Hunt–Crossley term.
    pub const MODEL: ContactLaw = ContactLaw {
        exponent: 2.0,
        stiffness_n_per_m_n: None,
        hunt_crossley_s_m: 0.0,
        adhesion: true,
    };
}

/// Everything the motion depends on, in SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DropParams {
    /// Sphere radius R.
    pub sphere_radius_m: f64,
    /// Sphere density ρ.
    pub sphere_density_kg_m3: f64,
    /// The pillar surface (E, h, φ used; b and c only drawn).
    pub surface: Surface,
    /// Gravity g (0 switches it off; the tests use that).
    pub gravity_m_s2: f64,
    /// Speed at first contact v (for a drop from height H with gravity: √(2gH)).
    pub impact_speed_m_s: f64,
    /// Linear damping coefficient c of the contact force `c ḋ` (0 = none).
    pub damping_n_s_m: f64,
    /// The elastic law, Hunt–Crossley damping and adhesion
    /// ([`ContactLaw::MODEL`]: the paper's).
    pub law: ContactLaw,
}

impl DropParams {
    /// The sphere's mass `m = (4/3) π R³ ρ`, kg.
    pub fn mass_kg(&self) -> f64 {
        4.0 / 3.0 * PI * self.sphere_radius_m.powi(3) * self.sphere_density_kg_m3
    }

    /// The foundation stiffness `K = π E φ R / h` of `F = K δ²`, N/m².
    pub fn stiffness_n_m2(&self) -> f64 {
        PI * self.surface.modulus_pa * self.surface.solid_fraction * self.sphere_radius_m
            / self.surface.pillar_height_m
    }

    /// The elastic stiffness of the contact: `K_n` (N/m^n) of the law, or
    /// the model's `K` (N/m²).
    pub fn elastic_stiffness(&self) -> f64 {
        self.law
            .stiffness_n_per_m_n
            .unwrap_or_else(|| self.stiffness_n_m2())
    }

    /// `K_n = K · δ_ref^{2 − n}` with `δ_ref` the model's δmax (Eq. 4) for
    /// this drop: the stiffness of an exponent-`n` law whose force equals
    /// the model's at `δ_ref`, so that δmax stays near the model's
    /// (`δmax/δ_ref = ((n + 1)/3)^{1/(n+1)}` without gravity and damping:
    /// 0.91 at n = 1.4, 1.05 at n = 2.6), N/m^n.
    pub fn stiffness_for_exponent(&self, n: f64) -> f64 {
        self.stiffness_n_m2() * self.delta_max_eq4_m().powf(2.0 - n)
    }

    /// δmax without gravity and damping under the law, from energy
    /// conservation: `((n + 1) m v² / (2 K_n))^{1/(n+1)}`, m.
    pub fn delta_max_energy_m(&self) -> f64 {
        let n = self.law.exponent;
        ((n + 1.0) * self.mass_kg() * self.impact_speed_m_s.powi(2)
            / (2.0 * self.elastic_stiffness()))
        .powf(1.0 / (n + 1.0))
    }

    /// Eq. (4) of Maruoka 2019 (no gravity, no damping):
    /// `δmax = R (2/φ)^{1/3} (h/R)^{1/3} (ρ v² / E)^{1/3}`, m.
    pub fn delta_max_eq4_m(&self) -> f64 {
        let r = self.sphere_radius_m;
        let s = &self.surface;
        let eta = self.sphere_density_kg_m3 * self.impact_speed_m_s.powi(2) / s.modulus_pa;
        r * (2.0 / s.solid_fraction * s.pillar_height_m / r * eta).cbrt()
    }

    /// Eq. (5) of Maruoka 2019 with Eq. (4): `τc = (2/3) B(1/3, 1/2) δmax / v`, s.
    pub fn tau_c_eq5_s(&self) -> f64 {
        2.0 / 3.0 * BETA_THIRD_HALF * self.delta_max_eq4_m() / self.impact_speed_m_s
    }

    /// Mechanical energy `½ m ḋ² − m g d + [d > 0] K_n d^{n+1} / (n + 1)`
    /// (J), conserved when there is no damping.
    pub fn energy_j(&self, d_m: f64, w_m_s: f64) -> f64 {
        let m = self.mass_kg();
        let n = self.law.exponent;
        let elastic = if d_m > 0.0 {
            self.elastic_stiffness() * d_m.powf(n + 1.0) / (n + 1.0)
        } else {
            0.0
        };
        0.5 * m * w_m_s * w_m_s - m * self.gravity_m_s2 * d_m + elastic
    }

    fn validate(&self) -> Result<(), PhysicsError> {
        let law = &self.law;
        let checks: [(&'static str, f64, bool, &'static str); 11] = [
            (
                "force_exponent",
                law.exponent,
                law.exponent >= 1.0 && law.exponent <= 4.0,
                "must lie in [1, 4]",
            ),
            (
                "stiffness_n_per_m_n",
                law.stiffness_n_per_m_n.unwrap_or(1.0),
                law.stiffness_n_per_m_n.unwrap_or(1.0) > 0.0
                    && (law.stiffness_n_per_m_n.is_some() || law.exponent == 2.0),
                "must be > 0 (and given whenever n ≠ 2)",
            ),
            (
                "hunt_crossley_s_m",
                law.hunt_crossley_s_m,
                law.hunt_crossley_s_m >= 0.0,
                "must be ≥ 0",
            ),
            (
                "sphere_radius_m",
                self.sphere_radius_m,
                self.sphere_radius_m > 0.0,
                "must be > 0",
            ),
            (
                "sphere_density_kg_m3",
                self.sphere_density_kg_m3,
                self.sphere_density_kg_m3 > 0.0,
                "must be > 0",
            ),
            (
                "modulus_pa",
                self.surface.modulus_pa,
                self.surface.modulus_pa > 0.0,
                "must be > 0",
            ),
            (
                "pillar_height_m",
                self.surface.pillar_height_m,
                self.surface.pillar_height_m > 0.0,
                "must be > 0",
            ),
            (
                "solid_fraction",
                self.surface.solid_fraction,
                self.surface.solid_fraction > 0.0 && self.surface.solid_fraction <= 1.0,
                "must lie in (0, 1]",
            ),
            (
                "gravity_m_s2",
                self.gravity_m_s2,
                self.gravity_m_s2 >= 0.0,
                "must be ≥ 0",
            ),
            (
                "impact_speed_m_s",
                self.impact_speed_m_s,
                self.impact_speed_m_s > 0.0,
                "must be > 0",
            ),
            (
                "damping_n_s_m",
                self.damping_n_s_m,
                self.damping_n_s_m >= 0.0,
                "must be ≥ 0",
            ),
        ];
        for (name, value, ok, allowed) in checks {
            if !(value.is_finite() && ok) {
                return Err(PhysicsError::InvalidParameter {
                    name,
                    value,
                    allowed,
                });
            }
        }
        Ok(())
    }

    /// The contact force `K_n |d|^n (1 + α ḋ) + c ḋ` (N) at depth `d` and
    /// rate `w`, unclamped (`k` = [`DropParams::elastic_stiffness`]). For
    /// the model's n = 2 the elastic part is `k·d·d`, as it always was.
    fn contact_force(&self, d: f64, w: f64, k: f64) -> f64 {
        let law = &self.law;
        let elastic = if law.exponent == 2.0 {
            k * d * d
        } else {
            k * d.abs().powf(law.exponent)
        };
        let f = elastic + self.damping_n_s_m * w;
        if law.hunt_crossley_s_m != 0.0 {
            f + law.hunt_crossley_s_m * elastic * w
        } else {
            f
        }
    }

    /// `(ḋ, d̈)` of the contact equation, valid for `d ≥ 0`. Used unchanged a
    /// hair beyond `d = 0` (with `|d|^n`) or beyond the force's zero inside
    /// the step that crosses it: that is the continuation of the contact
    /// solution, exact up to the crossing.
    fn contact_rhs(&self, s: [f64; 2], m: f64, k: f64) -> [f64; 2] {
        let [d, w] = s;
        [w, self.gravity_m_s2 - self.contact_force(d, w, k) / m]
    }

    /// One classical RK4 step of length `h` of the contact equation.
    fn rk4(&self, s: [f64; 2], h: f64, m: f64, k: f64) -> [f64; 2] {
        let f = |s| self.contact_rhs(s, m, k);
        let k1 = f(s);
        let k2 = f([s[0] + 0.5 * h * k1[0], s[1] + 0.5 * h * k1[1]]);
        let k3 = f([s[0] + 0.5 * h * k2[0], s[1] + 0.5 * h * k2[1]]);
        let k4 = f([s[0] + h * k3[0], s[1] + h * k3[1]]);
        [
            s[0] + h / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
            s[1] + h / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]),
        ]
    }

    /// A step that resolves the contact: `max_step_s` (the renderer passes
    /// 1/100 of the frame interval) halved until it is at most
    /// `τc(Eq. 5) / 2000`. Powers of two of the caller's step keep the result
    /// independent of the last bits of `cbrt` (which libms may round
    /// differently), so the same inputs give the same truth everywhere.
    pub fn default_step_s(&self, max_step_s: f64) -> f64 {
        let limit = self.tau_c_eq5_s() / 2000.0;
        let mut step = max_step_s;
        while step > limit {
            step *= 0.5;
        }
        step
    }
}

/// One contact: from touching the surface to leaving it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounce {
    /// Time the sphere's lowest point reaches the undeformed surface (δ = 0, going in).
    pub t_contact_s: f64,
    /// Time of maximum penetration (ḋ = 0).
    pub t_max_s: f64,
    /// Time of loss of contact (δ = 0, coming out).
    pub t_rebound_s: f64,
    /// Speed at contact (m/s, positive).
    pub v_impact_m_s: f64,
    /// Speed at loss of contact (m/s, positive).
    pub v_rebound_m_s: f64,
    /// Maximum penetration δmax (m).
    pub delta_max_m: f64,
    /// Without adhesion, when the force reached 0 on the way out and the
    /// sphere left the deformed surface (δ still > 0), and δ then (m);
    /// `None` when it stayed on the surface until δ = 0.
    pub force_zero: Option<(f64, f64)>,
}

impl Bounce {
    /// Contact time τc = t_rebound − t_contact.
    pub fn tau_c_s(&self) -> f64 {
        self.t_rebound_s - self.t_contact_s
    }
    /// Coefficient of restitution v_rebound / v_impact.
    pub fn restitution(&self) -> f64 {
        self.v_rebound_m_s / self.v_impact_m_s
    }
}

/// One piece of the motion.
#[derive(Debug, Clone)]
enum Segment {
    /// Held at rest at depth `d0` (before release).
    Rest { d0: f64 },
    /// Free flight through `(t0, d0, w0)`: `d = d0 + w0 τ + ½ g τ²`.
    Flight { t0: f64, d0: f64, w0: f64 },
    /// RK4 states at `t0 + k·dt`.
    Contact {
        t0: f64,
        dt: f64,
        states: Vec<[f64; 2]>,
    },
}

#[derive(Debug, Clone)]
struct Piece {
    /// The piece applies for `t < t_end` (the last piece: for all later t).
    t_end: f64,
    seg: Segment,
}

/// The integrated motion of one drop, queried with [`Trajectory::state`].
#[derive(Debug, Clone)]
pub struct Trajectory {
    params: DropParams,
    pieces: Vec<Piece>,
    bounces: Vec<Bounce>,
    step_s: f64,
    resting_contact_s: Option<f64>,
}

/// Result of integrating one contact phase: the grid states, the bounce if
/// the sphere left the surface within the time limit, and without adhesion
/// the state `(t, d, ḋ)` where the force reached zero (the flight starts there).
struct ContactRun {
    states: Vec<[f64; 2]>,
    end: Result<Bounce, PhysicsError>,
    leave: Option<(f64, f64, f64)>,
}

/// Bisection for the sign change of `f` on `[0, hi]` (`f(0) > 0 ≥ f(hi)`),
/// run until the bracket cannot shrink in floating point.
fn bisect(f: impl Fn(f64) -> f64, hi: f64) -> f64 {
    let (mut a, mut b) = (0.0_f64, hi);
    for _ in 0..200 {
        let mid = 0.5 * (a + b);
        if mid <= a || mid >= b {
            break;
        }
        if f(mid) > 0.0 {
            a = mid;
        } else {
            b = mid;
        }
    }
    0.5 * (a + b)
}

impl Trajectory {
    /// Integrate a drop whose first contact is at `t_contact_s`, until every
    /// contact that starts before `t_end_s` has ended. With gravity, the
    /// sphere was released from rest a height `v²/(2g)` above the surface at
    /// `t_contact − v/g` and is held at rest before that.
    pub fn simulate(
        params: &DropParams,
        t_contact_s: f64,
        t_end_s: f64,
        step_s: f64,
    ) -> Result<Self, PhysicsError> {
        params.validate()?;
        if !(step_s.is_finite() && step_s > 0.0) {
            return Err(PhysicsError::InvalidParameter {
                name: "step_s",
                value: step_s,
                allowed: "must be > 0",
            });
        }
        let g = params.gravity_m_s2;
        let v = params.impact_speed_m_s;
        let mut pieces = Vec::new();
        if g > 0.0 {
            pieces.push(Piece {
                t_end: t_contact_s - v / g,
                seg: Segment::Rest {
                    d0: -v * v / (2.0 * g),
                },
            });
        }
        pieces.push(Piece {
            t_end: t_contact_s,
            seg: Segment::Flight {
                t0: t_contact_s,
                d0: 0.0,
                w0: v,
            },
        });
        let mut bounces = Vec::new();
        let mut t_in = t_contact_s;
        let mut w_in = v;
        // A generous cap on bounces: each one ends far from the last (flight
        // time 2 v_out / g), so this is only reached with absurd inputs.
        let mut resting_contact_s = None;
        for _ in 0..64 {
            let run = integrate_contact(params, t_in, w_in, step_s);
            let b = match run.end {
                Ok(b) => b,
                Err(e) if bounces.is_empty() => return Err(e),
                Err(_) => {
                    // A later, slow contact that damping holds on the
                    // surface: integrated for 100 τc, then at rest.
                    let last = *run.states.last().expect("a contact has states");
                    pieces.push(Piece {
                        t_end: t_in + (run.states.len() - 1) as f64 * step_s,
                        seg: Segment::Contact {
                            t0: t_in,
                            dt: step_s,
                            states: run.states,
                        },
                    });
                    pieces.push(Piece {
                        t_end: f64::INFINITY,
                        seg: Segment::Rest { d0: last[0] },
                    });
                    resting_contact_s = Some(t_in);
                    break;
                }
            };
            // Without adhesion the flight starts where the force reached
            // zero, below the undeformed line (the same parabola).
            let (t_leave, flight) = match run.leave {
                Some((t, d, w)) => (
                    t,
                    Segment::Flight {
                        t0: t,
                        d0: d,
                        w0: w,
                    },
                ),
                None => (
                    b.t_rebound_s,
                    Segment::Flight {
                        t0: b.t_rebound_s,
                        d0: 0.0,
                        w0: -b.v_rebound_m_s,
                    },
                ),
            };
            pieces.push(Piece {
                t_end: t_leave,
                seg: Segment::Contact {
                    t0: t_in,
                    dt: step_s,
                    states: run.states,
                },
            });
            pieces.push(Piece {
                t_end: f64::INFINITY,
                seg: flight,
            });
            bounces.push(b);
            // Back to the surface after 2 v_out / g, at the same speed.
            if g <= 0.0 {
                break;
            }
            let t_next = b.t_rebound_s + 2.0 * b.v_rebound_m_s / g;
            if t_next >= t_end_s {
                break;
            }
            if let Some(last) = pieces.last_mut() {
                last.t_end = t_next;
            }
            t_in = t_next;
            w_in = b.v_rebound_m_s;
        }
        Ok(Trajectory {
            params: *params,
            pieces,
            bounces,
            step_s,
            resting_contact_s,
        })
    }

    /// The parameters this motion was integrated with.
    pub fn params(&self) -> &DropParams {
        &self.params
    }

    /// The fixed integration step (s).
    pub fn step_s(&self) -> f64 {
        self.step_s
    }

    /// Every contact, in time order (at least one).
    pub fn bounces(&self) -> &[Bounce] {
        &self.bounces
    }

    /// `(d, ḋ)` at time `t_s`: signed depth of the sphere's lowest point below
    /// the undeformed surface (m, negative in flight) and its rate (m/s, + down).
    pub fn state(&self, t_s: f64) -> (f64, f64) {
        let piece = self
            .pieces
            .iter()
            .find(|p| t_s < p.t_end)
            .or(self.pieces.last())
            .expect("a trajectory has at least one piece");
        let g = self.params.gravity_m_s2;
        match &piece.seg {
            Segment::Rest { d0 } => (*d0, 0.0),
            Segment::Flight { t0, d0, w0 } => {
                let tau = t_s - t0;
                (d0 + w0 * tau + 0.5 * g * tau * tau, w0 + g * tau)
            }
            Segment::Contact { t0, dt, states } => {
                let m = self.params.mass_kg();
                let k = self.params.elastic_stiffness();
                let pos = ((t_s - t0) / dt).floor().max(0.0) as usize;
                let idx = pos.min(states.len() - 1);
                let h = t_s - (t0 + idx as f64 * dt);
                let s = self.params.rk4(states[idx], h, m, k);
                (s[0], s[1])
            }
        }
    }

    /// Start of a later contact from which the sphere did not rebound within
    /// 100 τc (damping holds it; it is then taken as at rest), if any.
    pub fn resting_contact_s(&self) -> Option<f64> {
        self.resting_contact_s
    }

    /// Penetration `δ = max(d, 0)` at `t_s` (m).
    pub fn delta_m(&self, t_s: f64) -> f64 {
        self.state(t_s).0.max(0.0)
    }
}

/// Integrate one contact phase from `d = 0`, `ḋ = w_in > 0` at `t_in`,
/// for at most 100 τc (Eq. 5 at this speed). Without adhesion the phase
/// ends where the force reaches zero; the flight from there back to `d = 0`
/// is a parabola, solved exactly.
fn integrate_contact(p: &DropParams, t_in: f64, w_in: f64, dt: f64) -> ContactRun {
    let m = p.mass_kg();
    let k = p.elastic_stiffness();
    let g = p.gravity_m_s2;
    let tau_est = {
        let mut q = *p;
        q.impact_speed_m_s = w_in;
        q.tau_c_eq5_s()
    };
    let limit_s = 100.0 * tau_est;
    let max_steps = (limit_s / dt).ceil() as usize + 1;
    let mut states = vec![[0.0, w_in]];
    let mut s = [0.0, w_in];
    let mut max_event: Option<(f64, f64)> = None;
    let force = |s: [f64; 2]| p.contact_force(s[0], s[1], k);
    for i in 0..max_steps {
        let t_i = t_in + i as f64 * dt;
        let next = p.rk4(s, dt, m, k);
        if max_event.is_none() && s[1] > 0.0 && next[1] <= 0.0 {
            let h = bisect(|h| p.rk4(s, h, m, k)[1], dt);
            max_event = Some((t_i + h, p.rk4(s, h, m, k)[0]));
        }
        // Without adhesion: the force's zero on the way out, unless δ
        // reaches 0 first within this step.
        let h_leave = (!p.law.adhesion && s[1] < 0.0 && force(s) > 0.0 && force(next) <= 0.0)
            .then(|| bisect(|h| force(p.rk4(s, h, m, k)), dt));
        let h_surface = (next[0] <= 0.0).then(|| bisect(|h| p.rk4(s, h, m, k)[0], dt));
        let leave_first = match (h_leave, h_surface) {
            (Some(hl), Some(hs)) => hl < hs,
            (Some(_), None) => true,
            _ => false,
        };
        if leave_first {
            let h = h_leave.expect("the force's zero was located");
            let [d_f, w_f] = p.rk4(s, h, m, k);
            let t_f = t_i + h;
            let (t_max_s, delta_max_m) = max_event.unwrap_or((t_f, d_f.max(s[0])));
            // d_f + w_f τ + ½ g τ² = 0 on the way up (w_f < 0): the smaller
            // root, written without cancellation.
            let disc = w_f * w_f - 2.0 * g * d_f;
            if !(disc > 0.0 && w_f < 0.0) {
                return ContactRun {
                    states,
                    end: Err(PhysicsError::FallsBackInside {
                        t_s: t_f,
                        delta_m: d_f,
                        speed_m_s: -w_f,
                    }),
                    leave: None,
                };
            }
            let v_out = disc.sqrt();
            let tau = 2.0 * d_f / (-w_f + v_out);
            return ContactRun {
                states,
                end: Ok(Bounce {
                    t_contact_s: t_in,
                    t_max_s,
                    t_rebound_s: t_f + tau,
                    v_impact_m_s: w_in,
                    v_rebound_m_s: v_out,
                    delta_max_m,
                    force_zero: Some((t_f, d_f)),
                }),
                leave: Some((t_f, d_f, w_f)),
            };
        }
        if let Some(h) = h_surface {
            let out = p.rk4(s, h, m, k);
            let (t_max_s, delta_max_m) = max_event.unwrap_or((t_i + h, out[0].max(s[0])));
            return ContactRun {
                states,
                end: Ok(Bounce {
                    t_contact_s: t_in,
                    t_max_s,
                    t_rebound_s: t_i + h,
                    v_impact_m_s: w_in,
                    v_rebound_m_s: -out[1],
                    delta_max_m,
                    force_zero: None,
                }),
                leave: None,
            };
        }
        states.push(next);
        s = next;
    }
    ContactRun {
        states,
        end: Err(PhysicsError::NoRebound {
            t_contact_s: t_in,
            limit_s,
            damping_n_s_m: p.damping_n_s_m,
            hunt_crossley_s_m: p.law.hunt_crossley_s_m,
        }),
        leave: None,
    }
}

/// The damping coefficient `c` (N·s/m) for which the first bounce has the
/// restitution `v_rebound / v_impact = requested`, found by bisection on `c`
/// (the restitution falls monotonically with `c`) to 1e-12 in restitution.
/// `requested = 1` gives `c = 0`.
pub fn damping_for_restitution(
    params: &DropParams,
    requested: f64,
    step_s: f64,
) -> Result<f64, PhysicsError> {
    damping_coefficient_for_restitution(params, Damping::Linear, requested, step_s)
}

/// The coefficient of `kind` — `c` (N·s/m) for [`Damping::Linear`], `α`
/// (s/m) for [`Damping::HuntCrossley`] — for which the first bounce has the
/// restitution `v_rebound / v_impact = requested` (the speeds where δ
/// crosses 0), by bisection on the coefficient (the restitution falls
/// monotonically with it) to 1e-13 in restitution where floating point
/// allows. `requested = 1` gives 0; [`Damping::None`] accepts only 1. The
/// other coefficient of `params` is left as it is (0 in the renderer).
pub fn damping_coefficient_for_restitution(
    params: &DropParams,
    kind: Damping,
    requested: f64,
    step_s: f64,
) -> Result<f64, PhysicsError> {
    if !(requested.is_finite() && requested > 0.0 && requested <= 1.0) {
        return Err(PhysicsError::InvalidParameter {
            name: "restitution",
            value: requested,
            allowed: "must lie in (0, 1]",
        });
    }
    if requested == 1.0 {
        return Ok(0.0);
    }
    let with = |x: f64| {
        let mut q = *params;
        match kind {
            Damping::Linear => q.damping_n_s_m = x,
            Damping::HuntCrossley => q.law.hunt_crossley_s_m = x,
            Damping::None => {}
        }
        q
    };
    if kind == Damping::None {
        return Err(PhysicsError::InvalidParameter {
            name: "restitution",
            value: requested,
            allowed: "must be 1 without damping",
        });
    }
    let e_of = |x: f64| -> f64 {
        let q = with(x);
        match integrate_contact(&q, 0.0, q.impact_speed_m_s, step_s).end {
            Ok(b) => b.restitution(),
            Err(_) => 0.0, // stuck: below any positive target
        }
    };
    // Start at a damping rate c/m of 1000 /s (about 1/τc), or α v = 0.1,
    // and double: a bracket built from arithmetic only, so the bisection is
    // reproducible.
    let mut hi = match kind {
        Damping::HuntCrossley => 0.1 / params.impact_speed_m_s,
        _ => params.mass_kg() * 1000.0,
    };
    let mut lo = 0.0;
    let mut tries = 0;
    let unreachable = PhysicsError::RestitutionUnreachable {
        requested,
        damping: kind.name(),
    };
    while e_of(hi) > requested {
        lo = hi;
        hi *= 2.0;
        tries += 1;
        if tries > 60 {
            return Err(unreachable);
        }
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        let e = e_of(mid);
        if (e - requested).abs() <= 1e-13 {
            return Ok(mid);
        }
        if e > requested {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let c = 0.5 * (lo + hi);
    if e_of(c) <= 0.0 {
        return Err(unreachable);
    }
    Ok(c)
}

#[cfg(test)]
mod tests;
