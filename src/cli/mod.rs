//! The command line: clap's flags, checked as they are parsed, for the
//! commands that `main.rs` dispatches; and the commands that only print
//! what an input holds.
//!
//! | file | what |
//! | --- | --- |
//! | [`run`] | [`run::RunArgs`], `dropscope run` (the main job) |
//! | [`collapse`] | [`collapse::CollapseArgs`], `dropscope collapse`, and its `--contact-radius` values |
//! | [`process`] | [`process::ProcessArgs`], `dropscope process` |
//! | [`render`] | [`render::RenderArgs`], `dropscope render`, and the values of its choices |
//! | [`slurm`] | [`slurm::SlurmArgs`], `dropscope slurm` |
//! | [`values`] | [`values::RecordingArgs`]: `--fps`, `--mm-per-px`, `--surface-row-px` for recordings that lack them |
//! | [`inspect`] | `dropscope inspect` and `dropscope export`: what an input holds, its frames as 16-bit PNG |

pub mod collapse;
pub mod inspect;
pub mod process;
pub mod render;
pub mod run;
pub mod slurm;
pub mod values;
