//! Many runs: the jobs that write an output folder. Everything written,
//! kept or removed in the output folder is decided here (through
//! [`crate::util::out_folder`]); one run's measurement is
//! [`crate::pipeline`]'s, and writes nothing.
//!
//! | file | what |
//! | --- | --- |
//! | [`batch`] | the main job (`dropscope run`): every run → process → collapse → report, with progress |
//! | [`process_job`] | `dropscope process`: the runs through the main job's cache → drops.csv, per-drop figures |
//! | [`collapse_job`] | `dropscope collapse`: drops.csv → the collapse's tables and figures |
//! | [`report_job`] | `report.html` written into the output folder |
//! | [`per_drop`] | the per-drop figures drawn from the tracks beside a drops.csv |
//! | [`cache`] | the per-run result cache: input fingerprints, keys, entries |
//! | [`leftovers`] | an earlier job's files that this job did not write again |
//! | [`lock`] | one job at a time per output folder; shards of one job together |
//! | [`shard`] | `run --shard K/N`: the K-th of N frame-balanced shares of the runs |
//! | [`slurm`] | `dropscope slurm`: the shards as a Slurm array, then a finishing job |
//! | [`run_outputs`] | each run's files written as it is done, made durable before drops.csv; a list of runs processed and written |
//! | [`progress`] | progress bars on a terminal, plain lines elsewhere |

pub mod batch;
pub mod cache;
pub mod collapse_job;
pub mod leftovers;
pub mod lock;
pub mod per_drop;
pub mod process_job;
pub mod progress;
pub mod report_job;
pub mod run_outputs;
pub mod shard;
pub mod slurm;
