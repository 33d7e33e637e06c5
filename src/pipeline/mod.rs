//! One run (or the runs of one camera set-up): open the recording → track
//! → calibrate → events → kinematics → force law → one row of `drops.csv`,
//! with the run's track rows, its overlay at maximum penetration and its
//! animated impact as bytes. A run that cannot be measured gets a `failed`
//! row with its reason and never stops the others. Nothing here writes into
//! the output folder: [`crate::job`] writes what these return.
//!
//! | file | what |
//! | --- | --- |
//! | `types.rs` | [`RunOutcome`], [`ProcessError`] |
//! | `inputs.rs` | the runs from the input paths, the runs of a set-up |
//! | `run.rs` | one run's flow, a failed run's row; the runs of one set-up |
//! | `failure.rs` | a run's failure (a panic too) caught into its reason |
//! | `tracked.rs` | a run opened and tracked |
//! | `prepare.rs` | runs tracked ahead, kept, restored |
//! | `measure_run.rs` | a tracked run measured into its row |
//! | `checks.rs` | the frame rate's and the saturated background's checks |
//! | `points.rs` | the held fits as the event stage's points |
//! | `corrections.rs` | the speeds at the impact's scale, distortion, a_max's edge error |
//! | `outputs.rs` | a run's pictures drawn and its track rows spooled |
//! | [`settings`] | the stages' own settings from the configuration: how a recording is opened, detected and tracked |
//! | [`shelf`] | tracks kept in a temporary file between reading the runs' set-ups and processing them |

mod checks;
mod corrections;
mod failure;
mod inputs;
mod measure_run;
mod outputs;
mod points;
mod prepare;
mod run;
pub mod settings;
pub mod shelf;
#[cfg(test)]
mod tests;
mod tracked;
mod types;

pub use corrections::A_MAX_EDGE_SYSTEMATIC_PX;
pub use inputs::{runs_from_inputs, setups};
pub use prepare::{prepare, KeptRun, KeptRuns, Prepared};
pub use run::{process_run, process_setup};
pub use types::{ProcessError, RunOutcome, TRACK_CSV_IN_MEMORY_MAX};
