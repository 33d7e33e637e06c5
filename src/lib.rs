//! dropscope — high-speed recordings of sphere impacts into physics.
//!
//! Data flows one way (SPEC §2), and the modules follow it:
//!
//! | module | stage |
//! | --- | --- |
//! | [`util`] | the leaves: atomic writes and paths inside the output folder, spilled per-frame records, least squares, `--timings`, text sanitising and printing, the physical ranges of numbers |
//! | [`config`] | `pipeline.toml` → validated [`config::PipelineConfig`] in SI units |
//! | [`cli_values`] | `--fps`, `--mm-per-px`, `--surface-row-px` for recordings that lack them |
//! | [`source`] | frame sequences: the [`source::FrameSource`] trait and its readers |
//! | [`inspect`] | `dropscope inspect` and `dropscope export`: what an input holds, its frames as 16-bit PNG |
//! | [`stage_settings`] | the stages' own settings from the configuration: how a recording is opened, detected and tracked |
//! | [`detect`] | per frame: background, surface line, coarse and sub-pixel sphere circle |
//! | [`track`] | per run: two-pass tracking through row bands, R_px calibration |
//! | [`calibrate`] | mm/px (given, from free fall pooled per camera set-up, or from the radius), lens distortion, camera set-ups inferred from the images |
//! | [`measure`] | one drop from track to record: the surface's frame and the events, kinematics, force law, free flight alone, quality flags |
//! | [`dataset`] | the run manifest `runs.csv`, the per-drop record ([`dataset::DropRecord`]) and `drops.csv`, the decisions `review.csv`, the id of a `drops.csv`, run names that are file names |
//! | [`process`] | one run (or camera set-up) → record, track, overlays; runs in parallel |
//! | [`process_job`] | `dropscope process`: the runs through the main job's cache → drops.csv, per-drop figures |
//! | [`progress`] | the main job's progress bars, or plain lines off a terminal |
//! | [`collapse`] | drops.csv → dimensionless groups, Ψ(Ξ), Ω(Ξ), exponent fits |
//! | [`figures`] | the domain's figures as bytes: the collapse's, each drop's, a frame's detection overlay, a run's overlays and animated impact |
//! | [`collapse_job`] | `dropscope collapse`: drops.csv → the collapse's tables and figures in the output folder |
//! | [`per_drop`] | the per-drop figures drawn from the tracks beside a drops.csv, written into the output folder |
//! | [`batch`] | the main job (`dropscope run`): process then collapse, with progress |
//! | [`cache`] | the main job's per-run result cache: input fingerprints and keys |
//! | [`leftovers`] | an earlier job's files in the output folder that this job did not write again |
//! | [`lock`] | one job at a time per output folder; shards of one job together |
//! | [`shelf`] | tracks kept in a temporary file between reading the runs' set-ups and processing them |
//! | [`shard`] | `run --shard K/N`: the K-th of N frame-balanced shares of the runs |
//! | [`slurm`] | `dropscope slurm`: the shards as a Slurm array, then a finishing job |
//! | [`report`] | `report.html`: counts, collapse plots, fits and every drop on one self-contained page |
//! | [`review`] | `dropscope review`: every frame of a drop in a local web page; a person's decisions written to `review.csv` ([`dataset::decisions`]) |
//! | [`render`] | synthetic drops with exact truth (`dropscope render`) |
//! | [`plot`] | the drawing kit: SVG + PNG bytes from plain data, embedded font |
//!
//! Conventions, kept everywhere: the centre of pixel (0, 0) is at (0.0, 0.0),
//! column `x` grows to the right and row `z` grows downward. Quantities carry
//! their unit in their name (`_px`, `_mm`, `_s`, `_m_s`, `_pa`); inside the
//! library everything is SI unless the name says otherwise.

#![deny(missing_docs)]

pub mod batch;
pub mod cache;
pub mod calibrate;
pub mod cli_values;
pub mod collapse;
pub mod collapse_job;
pub mod config;
pub mod dataset;
pub mod detect;
pub mod figures;
pub mod inspect;
pub mod leftovers;
pub mod lock;
pub mod measure;
pub mod per_drop;
pub mod plot;
pub mod process;
pub mod process_job;
pub mod progress;
pub mod render;
pub mod report;
pub mod review;
pub mod shard;
pub mod shelf;
pub mod slurm;
pub mod source;
pub mod stage_settings;
#[cfg(test)]
mod test_support;
pub mod track;
pub mod util;
