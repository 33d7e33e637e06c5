//! The main job (`dropscope` or `dropscope run`): every run of the
//! configuration's manifest (or of its input paths) → process → collapse,
//! all into the configuration's output folder.

use crate::collapse::groups::ContactRadius;
use crate::collapse::CollapseArgs;
use crate::config::PipelineConfig;
use crate::dataset::{DropRecord, DropStatus};
use crate::manifest::{read_manifest, RunSpec};
use crate::process::process_all;
use crate::source::folder::ImageKind;
use std::path::{Path, PathBuf};

/// The command line of `dropscope run`.
#[derive(Debug, Default, clap::Args)]
pub struct RunArgs {
    /// The configuration file (default: ./pipeline.toml, else the embedded default).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Output folder (default: the configuration's output.dir).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Why the job could not run (a bad run is a row, not this).
#[derive(Debug, thiserror::Error)]
pub enum BatchError {
    #[error(transparent)]
    Manifest(#[from] crate::manifest::ManifestError),
    #[error(transparent)]
    Process(#[from] crate::process::ProcessError),
    #[error(transparent)]
    Collapse(#[from] crate::collapse::CollapseError),
    #[error(transparent)]
    Report(#[from] crate::report::ReportError),
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(
        "the configuration names no input: set input.manifest or input.paths in pipeline.toml"
    )]
    NoInput,
    #[error("input.paths: no run folder or .cine file found under {0}")]
    NothingFound(String),
}

/// What the job did.
#[derive(Debug, Clone)]
pub struct JobSummary {
    pub records: Vec<DropRecord>,
    pub out: PathBuf,
    /// Whether the collapse stage ran (it needs at least one measured drop).
    pub collapsed: bool,
    pub collapse_warnings: Vec<String>,
}

impl JobSummary {
    pub fn failed(&self) -> usize {
        self.records
            .iter()
            .filter(|r| r.status == DropStatus::Failed)
            .count()
    }
}

fn is_frame_folder(dir: &Path) -> bool {
    std::fs::read_dir(dir).is_ok_and(|entries| {
        entries.flatten().any(|e| {
            e.path()
                .extension()
                .and_then(|x| x.to_str())
                .is_some_and(|x| {
                    ImageKind::from_extension(x).is_some() || x.eq_ignore_ascii_case("xml")
                })
        })
    })
}

fn is_cine(p: &Path) -> bool {
    p.extension()
        .and_then(|x| x.to_str())
        .is_some_and(|x| x.eq_ignore_ascii_case("cine"))
}

/// Runs under the configured paths: a `.cine` or a folder of frames is one
/// run; another folder is searched one level down (sorted by name).
pub fn discover_runs(paths: &[PathBuf]) -> Result<Vec<PathBuf>, BatchError> {
    let mut out = Vec::new();
    for p in paths {
        if is_cine(p) || (p.is_dir() && is_frame_folder(p)) {
            out.push(p.clone());
            continue;
        }
        let mut children: Vec<PathBuf> = std::fs::read_dir(p)
            .map_err(|source| BatchError::Io {
                path: p.clone(),
                source,
            })?
            .flatten()
            .map(|e| e.path())
            .filter(|c| is_cine(c) || (c.is_dir() && is_frame_folder(c)))
            .collect();
        if children.is_empty() {
            return Err(BatchError::NothingFound(p.display().to_string()));
        }
        children.sort();
        out.extend(children);
    }
    Ok(out)
}

/// The runs the configuration names.
pub fn configured_runs(cfg: &PipelineConfig) -> Result<Vec<RunSpec>, BatchError> {
    if let Some(m) = &cfg.input.manifest {
        return Ok(read_manifest(m)?);
    }
    if cfg.input.paths.is_empty() {
        return Err(BatchError::NoInput);
    }
    let found = discover_runs(&cfg.input.paths)?;
    Ok(crate::process::runs_from_inputs(&found, None, cfg)?)
}

/// Process every configured run, then the collapse of the measured ones.
pub fn run_job(
    cfg: &PipelineConfig,
    config_name: &str,
    out: &Path,
    progress: &(dyn Fn(&DropRecord) + Sync),
) -> Result<JobSummary, BatchError> {
    let runs = configured_runs(cfg)?;
    let records = process_all(&runs, cfg, out, progress)?;
    let measured = records
        .iter()
        .filter(|r| r.status != DropStatus::Failed)
        .count();
    let (collapsed, collapse_warnings) = if measured > 0 {
        let args = CollapseArgs {
            drops: out.join("drops.csv"),
            out: Some(out.to_path_buf()),
            config: None,
            contact_radius: ContactRadius::Measured,
            bootstrap: 2000,
            seed: 20190614,
            no_plots: false,
        };
        let s = crate::collapse::run(&args, cfg, config_name)?;
        (true, s.warnings)
    } else {
        (false, Vec::new())
    };
    crate::report::write_report(out, config_name, &records)?;
    Ok(JobSummary {
        records,
        out: out.to_path_buf(),
        collapsed,
        collapse_warnings,
    })
}
