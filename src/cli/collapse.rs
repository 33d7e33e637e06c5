//! The command line of `dropscope collapse` ([`CollapseArgs`]), parsed into
//! [`CollapseOptions`].

use crate::collapse::groups::ContactRadius;
use crate::job::collapse_job::CollapseOptions;
use clap::builder::PossibleValue;
use clap::ValueEnum;
use std::path::PathBuf;

/// `dropscope collapse DROPS.csv [--out DIR] [--config FILE]`.
#[derive(Debug, Clone, clap::Args)]
pub struct CollapseArgs {
    /// The per-drop dataset (drops.csv from `process`, or any CSV with its columns).
    pub drops: PathBuf,
    /// Output folder (default: the folder holding DROPS, so that the
    /// collapse sits beside the dataset it was computed from).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// The configuration holding the `[surface.<name>]` materials
    /// (default: ./pipeline.toml, else the embedded default).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Which contact radius enters ξ and Ξ. `geometric` makes Ψ(Ξ) hold by
    /// construction (Ξ² = Ψ(2 − Π)); use it only to compare.
    #[arg(long, value_enum, default_value_t = ContactRadius::Measured)]
    pub contact_radius: ContactRadius,
    /// Bootstrap resamples for the 95 % intervals.
    #[arg(long, default_value_t = 2000)]
    pub bootstrap: usize,
    /// Seed of the bootstrap (same seed, same intervals).
    #[arg(long, default_value_t = 20190614)]
    pub seed: u64,
    /// Do not draw plots (collapse.csv and fits.json only).
    #[arg(long)]
    pub no_plots: bool,
}

impl CollapseArgs {
    /// What the job level takes.
    pub fn options(self) -> CollapseOptions {
        CollapseOptions {
            drops: self.drops,
            out: self.out,
            config: self.config,
            contact_radius: self.contact_radius,
            bootstrap: self.bootstrap,
            seed: self.seed,
            no_plots: self.no_plots,
        }
    }
}

impl ValueEnum for ContactRadius {
    fn value_variants<'a>() -> &'a [Self] {
        &[ContactRadius::Measured, ContactRadius::Geometric]
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        let (name, help) = match self {
            ContactRadius::Measured => ("measured", "`a_max_mm`, the measured half-width (falls back to geometric, loudly, when missing)"),
            ContactRadius::Geometric => ("geometric", "`a_geom_mm` = √(R² − (R − δ)²): makes Ψ(Ξ) hold by construction"),
        };
        Some(PossibleValue::new(name).help(help))
    }
}
