//! The command line of `dropscope process` ([`ProcessArgs`]).

use std::path::PathBuf;

/// The command line of `dropscope process`.
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("runs").required(true).args(["inputs", "manifest"])))]
pub struct ProcessArgs {
    /// Run folders (PCC exports) or `.cine` files, one drop each, or
    /// folders holding them (searched at any depth; each run found is a drop).
    pub inputs: Vec<PathBuf>,
    /// A runs.csv manifest (columns: docs/outputs.md) instead of INPUTs.
    #[arg(long)]
    pub manifest: Option<PathBuf>,
    /// Output folder (default: the configuration's output.dir).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// The configuration file (default: ./pipeline.toml, else the embedded default).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Sphere radius for INPUTs (default: the configuration's sphere.radius_mm).
    #[arg(long, value_parser = crate::util::flag_values::positive, allow_negative_numbers = true)]
    pub radius_mm: Option<f64>,
    /// Values for recordings that lack them (`--fps`, `--mm-per-px`, `--surface-row-px`).
    #[command(flatten)]
    pub recording: crate::cli::values::RecordingArgs,
    /// Also draw the overlay of these camera image numbers (comma-separated,
    /// e.g. `-5,0,12`) for every run: `plots/overlays/<run>_<number>.png`.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub overlay_frames: Vec<i64>,
    /// Reprocess every run, even those whose result from an earlier job
    /// into this folder (`OUT/runs/<run>.json`) is still valid.
    #[arg(long)]
    pub force: bool,
    /// Worker threads (default: one per core).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,
    /// Draw no animated impact (`plots/impacts/<run>.png`, about 0.5 MB a
    /// drop): the configuration's `output.animation = false`.
    #[arg(long)]
    pub no_animation: bool,
    /// Measure the frames in storage orientation, without the viewer flips
    /// a .cine or Photron header records: the configuration's
    /// `camera.apply_flips = false`.
    #[arg(long)]
    pub no_flips: bool,
    /// Measure P10 cines on their log-encoded 10-bit codes, not linearised:
    /// the configuration's `camera.p10_linear = false`.
    #[arg(long)]
    pub p10_codes: bool,
    /// After the job, print on stderr where its time went: wall and CPU
    /// seconds per stage (reading, tracking passes, force fits, pictures,
    /// writes, …) summed over runs, each stage's share and its mean per
    /// drop. Changes no output.
    #[arg(long)]
    pub timings: bool,
}
