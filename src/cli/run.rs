//! The command line of `dropscope run` ([`RunArgs`]), the main job.

use std::path::PathBuf;

/// The command line of `dropscope run`.
#[derive(Debug, Default, clap::Args)]
pub struct RunArgs {
    /// The configuration file (default: ./pipeline.toml, else the embedded default).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Output folder (default: the configuration's output.dir).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Reprocess every run, even those whose cached result is still valid.
    #[arg(long)]
    pub force: bool,
    /// Worker threads (default: SLURM_CPUS_PER_TASK inside a Slurm job, else one per core).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,
    /// Process only the K-th of N frame-balanced shares of the runs (0 <= K < N),
    /// committing each into the output folder's cache, with no drops.csv,
    /// collapse or report; `slurm` takes K and N from the Slurm array task.
    /// A plain `run` on the folder afterwards assembles everything.
    #[arg(long, value_name = "K/N|slurm")]
    pub shard: Option<String>,
    /// When another job holds the output folder, wait for it to end
    /// instead of stopping.
    #[arg(long)]
    pub wait: bool,
    /// Draw no animated impact (`plots/impacts/<run>.png`, about 0.5 MB a
    /// drop): the configuration's `output.animation = false`.
    #[arg(long)]
    pub no_animation: bool,
    /// After the job, print on stderr where its time went: wall and CPU
    /// seconds per stage (reading, tracking passes, force fits, pictures,
    /// writes, …) summed over runs, each stage's share and its mean per
    /// drop. Changes no output.
    #[arg(long)]
    pub timings: bool,
    /// Values for recordings that lack them (`--fps`, `--mm-per-px`, `--surface-row-px`).
    #[command(flatten)]
    pub recording: crate::cli::values::RecordingArgs,
}
