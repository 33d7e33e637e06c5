//! `dropscope process`: every run → track → events → kinematics → one row
//! of `drops.csv`, `tracks/<run>.csv`, an overlay at maximum penetration
//! (`plots/overlays/<run>.png`) and the animated impact
//! (`plots/impacts/<run>.png`). Runs are processed in parallel; a run that
//! cannot be measured gets a `failed` row with its reason and never stops
//! the others. Every file is written whole or not at all.
//!
//! | file | what |
//! | --- | --- |
//! | `args.rs` | [`ProcessArgs`], the command line |
//! | `types.rs` | [`RunOutcome`], [`ProcessError`] |
//! | `inputs.rs` | the runs from the input paths, the runs of a set-up |
//! | `run.rs` | one run's flow, a failed run's row; every run of a job |
//! | `failure.rs` | a run's failure (a panic too) caught into its reason |
//! | `tracked.rs` | a run opened and tracked |
//! | `prepare.rs` | runs tracked ahead, kept, restored |
//! | `measure_run.rs` | a tracked run measured into its row |
//! | `checks.rs` | the frame rate's and the saturated background's checks |
//! | `points.rs` | the held fits as the event stage's points |
//! | `corrections.rs` | the speeds at the impact's scale, distortion, a_max's edge error |
//! | `outputs.rs` | a run's files drawn and written |

mod args;
mod checks;
mod corrections;
mod failure;
mod inputs;
mod measure_run;
mod outputs;
mod points;
mod prepare;
mod run;
#[cfg(test)]
mod tests;
mod tracked;
mod types;

pub use args::ProcessArgs;
pub use corrections::A_MAX_EDGE_SYSTEMATIC_PX;
pub use inputs::{runs_from_inputs, setups};
pub use outputs::{sync_outputs, write_file, write_run_outputs};
pub use prepare::{prepare, KeptRun, KeptRuns, Prepared};
pub use run::{process_all, process_all_with_overlays, process_run, process_setup};
pub use types::{ProcessError, RunOutcome, TRACK_CSV_IN_MEMORY_MAX};
