//! dropscope — high-speed recordings of sphere impacts into physics.
//!
//! Data flows one way (SPEC §2), and the modules follow it, from the leaves
//! up: each imports only modules before it in this table (a test,
//! `tests/layers.rs`, holds the rules).
//!
//! | module | what |
//! | --- | --- |
//! | [`util`] | the leaves: atomic writes and paths inside the output folder, spilled per-frame records, least squares, `--timings`, text sanitising and printing, flag values, the physical ranges of numbers |
//! | [`config`] | `pipeline.toml` → validated [`config::PipelineConfig`] in SI units |
//! | [`source`] | frame sequences: the [`source::FrameSource`] trait and its readers |
//! | [`plot`] | the drawing kit: SVG + PNG bytes from plain data, embedded font |
//! | [`detect`] | per frame: background, surface line, coarse and sub-pixel sphere circle |
//! | [`track`] | per run: two-pass tracking through row bands, R_px calibration |
//! | [`dataset`] | the records: the run manifest `runs.csv`, the per-drop record ([`dataset::DropRecord`]) and `drops.csv`, the decisions `review.csv`, the id of a `drops.csv`, run names that are file names |
//! | [`measure`] | one drop from track to record: the surface's frame and the events, kinematics, force law, free flight alone, quality flags |
//! | [`collapse`] | drops.csv → dimensionless groups, Ψ(Ξ), Ω(Ξ), exponent fits |
//! | [`calibrate`] | mm/px (given, from free fall pooled per camera set-up, or from the radius), lens distortion, camera set-ups inferred from the images |
//! | [`figures`] | the domain's figures as bytes: the collapse's, each drop's, a frame's detection overlay, a run's overlays and animated impact |
//! | [`report`] | `report.html`: counts, collapse plots, fits and every drop on one self-contained page |
//! | [`render`] | synthetic drops with exact truth (`dropscope render`) |
//! | [`pipeline`] | one run (or camera set-up): open → track → calibrate → measure → its record, track rows and pictures; writes nothing into the output folder |
//! | [`job`] | many runs into an output folder: `run`, `process`, `collapse`, the cache, the lock, shards, Slurm, progress |
//! | [`review`] | `dropscope review`: every frame of a drop in a local web page; a person's decisions written to `review.csv` ([`dataset::decisions`]) |
//! | [`cli`] | the command line, clap's only home: every command's flags, parsed into the plain options of the modules above; `inspect` and `export` |
//!
//! Conventions, kept everywhere: the centre of pixel (0, 0) is at (0.0, 0.0),
//! column `x` grows to the right and row `z` grows downward. Quantities carry
//! their unit in their name (`_px`, `_mm`, `_s`, `_m_s`, `_pa`); inside the
//! library everything is SI unless the name says otherwise.

#![deny(missing_docs)]

pub mod calibrate;
pub mod cli;
pub mod collapse;
pub mod config;
pub mod dataset;
pub mod detect;
pub mod figures;
pub mod job;
pub mod measure;
pub mod pipeline;
pub mod plot;
pub mod render;
pub mod report;
pub mod review;
pub mod source;
#[cfg(test)]
mod test_support;
pub mod track;
pub mod util;
