//! One drop, from its track to its numbers: pure, per drop, no I/O.
//!
//! | file | what |
//! | --- | --- |
//! | [`events`] | the surface's frame, contact onset, peak and loss of contact from the track |
//! | [`kinematics`] | v, δ, a, τc, e with jointly propagated errors |
//! | [`force`] | the F(δ) table; the contact models, their integration and least squares |
//! | [`force_fit`] | the contact law fitted to the trajectory, with its errors |
//! | [`flight`] | a run without a contact: its free flight (v at the last frame, g) |
//! | [`quality`] | the quality flags of a measured drop (`flags` in drops.csv) |
//! | `drop` | events → kinematics → force law → the drop's record ([`measure_drop`]) |

mod drop;
pub mod events;
pub mod flight;
pub mod force;
pub mod force_fit;
pub mod kinematics;
pub mod quality;

pub use drop::*;
