//! The contact law of each drop: the measurement's model (the default), one
//! law set by options, or a law drawn per drop (`--contact wide`) so that
//! accuracy is tested on contacts the model does not describe.
//!
//! `--contact wide` draws, per drop from `(seed, run)`:
//!
//! | what | range |
//! | --- | --- |
//! | elastic exponent n of `K_n δ^n` | uniform in [1.4, 2.6] |
//! | damping | none, linear `c ḋ` or Hunt–Crossley `α K_n δ^n ḋ`, one third each |
//! | adhesion | the force may pull, or not (clamped at F ≥ 0), one half each |
//! | restitution | uniform in [0.3, 0.98] (1 without damping) |
//!
//! The stiffness is `K_n = K · δ_ref^{2 − n}` with `K = π E φ R / h` and
//! `δ_ref` the drop's δmax under the model (Eq. (4) of Maruoka 2019): the
//! force equals the model's at `δ_ref`, so δmax stays within −9 %…+5 % of the
//! model's over the range of n, inside the paper's range. The damping
//! coefficient is solved for the drawn restitution. Every value is drawn
//! whether or not an option fixes it, so fixing one leaves the others'
//! draws unchanged.

use rand::Rng;

use super::physics::{self, ContactLaw, Damping, DropParams};
use super::rng_for;

/// The exponents `--contact wide` draws n from.
pub const WIDE_EXPONENT: (f64, f64) = (1.4, 2.6);
/// The restitutions `--contact wide` draws from (damped drops).
pub const WIDE_RESTITUTION: (f64, f64) = (0.3, 0.98);

/// How each drop's contact law is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ContactMode {
    /// The measurement's model, `π E φ R δ² / h`, with linear damping solved
    /// for `--restitution`; or the law the options below set.
    #[default]
    Model,
    /// Per drop: n in 1.4–2.6, damping none / linear / Hunt–Crossley,
    /// adhesion or not, restitution 0.3–0.98; the options below fix any one.
    Wide,
}

/// The damping named on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DampingArg {
    /// No damping: restitution 1.
    None,
    /// Linear damping `c ḋ`.
    Linear,
    /// Hunt–Crossley damping `α K_n δ^n ḋ`.
    HuntCrossley,
}

impl From<DampingArg> for Damping {
    fn from(d: DampingArg) -> Self {
        match d {
            DampingArg::None => Damping::None,
            DampingArg::Linear => Damping::Linear,
            DampingArg::HuntCrossley => Damping::HuntCrossley,
        }
    }
}

/// The validated contact options of a render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactSpec {
    /// The model's law, or drawn per drop (`--contact`).
    pub mode: ContactMode,
    /// `--force-exponent`.
    pub exponent: Option<f64>,
    /// `--damping`.
    pub damping: Option<Damping>,
    /// `--no-adhesion`.
    pub no_adhesion: bool,
    /// `--restitution` (the target; 1 by default outside `wide`).
    pub restitution: Option<f64>,
}

impl ContactSpec {
    /// True when no option asks for anything but the model: the renderer
    /// then draws the drop exactly as it always has, and `truth.json` has
    /// no contact section.
    pub fn is_model(&self) -> bool {
        self.mode == ContactMode::Model
            && self.exponent.is_none()
            && self.damping.is_none()
            && !self.no_adhesion
    }
}

/// One drop's contact, before its damping coefficient is solved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactDraw {
    /// Elastic exponent n of `K_n δ^n`.
    pub exponent: f64,
    /// The kind of damping.
    pub damping: Damping,
    /// The force may pull (true), or is clamped at F ≥ 0.
    pub adhesion: bool,
    /// The restitution the damping is solved for (1 without damping).
    pub restitution: f64,
}

/// The contact of drop `run`: drawn from `(seed, run)` under `wide` (each
/// value replaced by its option when given), else the options' law.
pub fn draw(spec: &ContactSpec, seed: u64, run: &str) -> ContactDraw {
    let mut rng = rng_for(seed, run, "contact", 0);
    let u: [f64; 4] = std::array::from_fn(|_| rng.gen_range(0.0..1.0));
    let wide = spec.mode == ContactMode::Wide;
    let exponent = spec.exponent.unwrap_or(if wide {
        WIDE_EXPONENT.0 + (WIDE_EXPONENT.1 - WIDE_EXPONENT.0) * u[0]
    } else {
        2.0
    });
    let requested = spec.restitution;
    let damping = spec.damping.unwrap_or(if wide {
        [Damping::None, Damping::Linear, Damping::HuntCrossley][((3.0 * u[1]) as usize).min(2)]
    } else if requested.is_some_and(|e| e < 1.0) {
        Damping::Linear
    } else {
        Damping::None
    });
    let adhesion = !spec.no_adhesion && (!wide || u[2] < 0.5);
    let restitution = if damping == Damping::None {
        1.0
    } else {
        requested.unwrap_or(if wide {
            WIDE_RESTITUTION.0 + (WIDE_RESTITUTION.1 - WIDE_RESTITUTION.0) * u[3]
        } else {
            1.0
        })
    };
    ContactDraw {
        exponent,
        damping,
        adhesion,
        restitution,
    }
}

/// `params` (with the model's law and no damping) given the drawn contact:
/// the law with `K_n = K · δ_ref^{2 − n}`, and the damping coefficient
/// solved for the restitution with `step_s`.
pub fn apply(
    params: &DropParams,
    c: &ContactDraw,
    step_s: f64,
) -> Result<DropParams, physics::PhysicsError> {
    let mut p = *params;
    p.law = ContactLaw {
        exponent: c.exponent,
        stiffness_n_per_m_n: Some(params.stiffness_for_exponent(c.exponent)),
        hunt_crossley_s_m: 0.0,
        adhesion: c.adhesion,
    };
    p.damping_n_s_m = 0.0;
    let x = physics::damping_coefficient_for_restitution(&p, c.damping, c.restitution, step_s)?;
    match c.damping {
        Damping::Linear => p.damping_n_s_m = x,
        Damping::HuntCrossley => p.law.hunt_crossley_s_m = x,
        Damping::None => {}
    }
    Ok(p)
}

/// The law in words, for `truth.json`.
pub fn describe(c: &ContactDraw) -> String {
    let damping = match c.damping {
        Damping::None => "",
        Damping::Linear => " + c·dδ/dt",
        Damping::HuntCrossley => "·(1 + α·dδ/dt)",
    };
    let clamp = if c.adhesion {
        "the force may pull (adhesion)"
    } else {
        "clamped to F ≥ 0 (no adhesion)"
    };
    format!("K_n·δ^n{damping}, {clamp}, plus gravity")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(mode: ContactMode) -> ContactSpec {
        ContactSpec {
            mode,
            exponent: None,
            damping: None,
            no_adhesion: false,
            restitution: None,
        }
    }

    #[test]
    fn wide_draws_cover_every_kind_and_stay_in_their_ranges() {
        let s = spec(ContactMode::Wide);
        let draws: Vec<ContactDraw> = (0..300).map(|k| draw(&s, 7, &format!("r{k}"))).collect();
        for d in &draws {
            assert!((1.4..=2.6).contains(&d.exponent), "{d:?}");
            match d.damping {
                Damping::None => assert_eq!(d.restitution, 1.0),
                _ => assert!((0.3..=0.98).contains(&d.restitution), "{d:?}"),
            }
        }
        for kind in [Damping::None, Damping::Linear, Damping::HuntCrossley] {
            let n = draws.iter().filter(|d| d.damping == kind).count();
            assert!((70..130).contains(&n), "{kind:?}: {n} of 300");
        }
        let sticky = draws.iter().filter(|d| d.adhesion).count();
        assert!(
            (110..190).contains(&sticky),
            "{sticky} of 300 with adhesion"
        );
    }

    #[test]
    fn fixing_one_value_leaves_the_other_draws_unchanged() {
        let wide = spec(ContactMode::Wide);
        let fixed = ContactSpec {
            exponent: Some(1.7),
            ..wide
        };
        for k in 0..20 {
            let run = format!("r{k}");
            let (a, b) = (draw(&wide, 3, &run), draw(&fixed, 3, &run));
            assert_eq!(b.exponent, 1.7);
            assert_eq!(
                (a.damping, a.adhesion, a.restitution),
                (b.damping, b.adhesion, b.restitution)
            );
        }
    }

    #[test]
    fn without_options_the_model_is_drawn() {
        let s = spec(ContactMode::Model);
        assert!(s.is_model());
        let d = draw(&s, 1, "r");
        assert_eq!(
            d,
            ContactDraw {
                exponent: 2.0,
                damping: Damping::None,
                adhesion: true,
                restitution: 1.0
            }
        );
        let damped = ContactSpec {
            restitution: Some(0.8),
            ..s
        };
        assert!(damped.is_model());
        assert_eq!(draw(&damped, 1, "r").damping, Damping::Linear);
    }
}
