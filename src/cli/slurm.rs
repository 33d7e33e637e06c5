//! The command line of `dropscope slurm` ([`SlurmArgs`]), parsed into
//! [`SlurmOptions`].

use crate::job::slurm::SlurmOptions;
use std::path::PathBuf;

/// The command line of `dropscope slurm`.
#[derive(Debug, Clone, clap::Args)]
pub struct SlurmArgs {
    /// Tasks of the array: the runs are split into this many frame-balanced shares.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub array: u32,
    /// Slurm partition (default: the cluster's default partition).
    #[arg(long)]
    pub partition: Option<String>,
    /// Time limit of each task and of the finishing job, as sbatch takes it (e.g. 2:00:00).
    #[arg(long)]
    pub time: Option<String>,
    /// Memory of each task and of the finishing job, as sbatch takes it (e.g. 4G).
    #[arg(long)]
    pub mem: Option<String>,
    /// CPUs of each task; the task runs that many worker threads.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u16).range(1..))]
    pub cpus_per_task: u16,
    /// The configuration file (default: ./pipeline.toml, else the embedded default).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Output folder (default: the configuration's output.dir); it must be
    /// on a file system every node sees.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Folder for the two scripts and the jobs' logs (default: OUT.slurm beside OUT).
    #[arg(long)]
    pub scripts: Option<PathBuf>,
    /// Submit both jobs with sbatch and print their ids.
    #[arg(long)]
    pub submit: bool,
}

impl SlurmArgs {
    /// What the job level takes.
    pub fn options(&self) -> SlurmOptions {
        SlurmOptions {
            array: self.array,
            partition: self.partition.clone(),
            time: self.time.clone(),
            mem: self.mem.clone(),
            cpus_per_task: self.cpus_per_task,
            config: self.config.clone(),
            out: self.out.clone(),
            scripts: self.scripts.clone(),
            submit: self.submit,
        }
    }
}
