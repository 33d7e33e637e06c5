//! `dropscope collapse DROPS.csv`: reads drops.csv, computes the collapse
//! ([`crate::collapse`]) and writes `collapse.csv`, `fits.json` and the
//! figures ([`crate::figures`]) into the output folder, every file through
//! its ledger ([`crate::util::out_folder`]).

use std::path::{Path, PathBuf};

use crate::collapse::groups::{ContactRadius, DropGroups};
use crate::collapse::{compute_groups, fit, output, CollapseError, DropOutcome};
use crate::config::PipelineConfig;
use crate::dataset::{self, DatasetError};
use crate::job::per_drop;
use crate::util::out_folder::Ledger;

/// What `dropscope collapse` is asked for (the command line's
/// `crate::cli::collapse::CollapseOptions`).
#[derive(Debug, Clone)]
pub struct CollapseOptions {
    /// The per-drop dataset (drops.csv from `process`, or any CSV with its columns).
    pub drops: PathBuf,
    /// Output folder (default: the folder holding DROPS, so that the
    /// collapse sits beside the dataset it was computed from).
    pub out: Option<PathBuf>,
    /// The configuration holding the `[surface.<name>]` materials
    /// (default: ./pipeline.toml, else the embedded default).
    pub config: Option<PathBuf>,
    /// Which contact radius enters ξ and Ξ. `geometric` makes Ψ(Ξ) hold by
    /// construction (Ξ² = Ψ(2 − Π)); use it only to compare.
    pub contact_radius: ContactRadius,
    /// Bootstrap resamples for the 95 % intervals.
    pub bootstrap: usize,
    /// Seed of the bootstrap (same seed, same intervals).
    pub seed: u64,
    /// Do not draw plots (collapse.csv and fits.json only).
    pub no_plots: bool,
}

/// What a run of the collapse produced (also written to disk).
#[derive(Debug, Clone)]
pub struct CollapseSummary {
    /// The folder the collapse wrote into.
    pub out_dir: PathBuf,
    /// Drops that entered the collapse.
    pub n_used: usize,
    /// Rows skipped for a problem (failed, or lacking a quantity).
    pub n_skipped: usize,
    /// Rows a person rejected (`dropscope review`): left out, no problem.
    pub n_rejected: usize,
    /// Everything fitted.
    pub fits: fit::Fits,
    /// Every warning, also in fits.json.
    pub warnings: Vec<String>,
    /// Files written, relative to `out_dir`, sorted.
    pub files: Vec<PathBuf>,
}

fn write(
    ledger: &mut Ledger,
    rel: &Path,
    bytes: &[u8],
    files: &mut Vec<PathBuf>,
) -> Result<(), CollapseError> {
    per_drop::write_as(ledger, rel, bytes, files, crate::util::io::Durable::Now)
}

/// The tables [`run`] writes into the output folder: `collapse.csv`, `fits.json`.
pub const TABLES: [&str; 2] = ["collapse.csv", "fits.json"];

/// Remove what an earlier [`run`] wrote into the ledger's folder (its tables
/// and the figures in `plots/`), so that a collapse redone, or not done,
/// leaves nothing of an earlier one: only files the ledger lists with the
/// bytes dropscope wrote ([`Ledger::remove`]); a file of yours of the same
/// name stays. The per-drop figures in `plots/drops/` are replaced file by
/// file ([`per_drop::replace`]).
pub fn remove_outputs(ledger: &mut Ledger) -> std::io::Result<()> {
    let figures = crate::figures::FIGURE_STEMS
        .iter()
        .flat_map(|stem| ["svg", "png"].map(|ext| format!("plots/{stem}.{ext}")));
    for rel in TABLES.iter().map(|s| s.to_string()).chain(figures) {
        ledger.remove(&rel)?;
    }
    Ok(())
}

/// The folder holding `drops` (`.` for a bare file name).
fn beside(drops: &Path) -> PathBuf {
    match drops.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

impl CollapseOptions {
    /// The folder [`run`] writes into: `--out`, else beside DROPS.
    pub fn out_dir(&self) -> PathBuf {
        self.out.clone().unwrap_or_else(|| beside(&self.drops))
    }
}

/// Run the collapse stage: read `args.drops`, write everything into the
/// output folder. `config_name` names the configuration in messages.
pub fn run(
    args: &CollapseOptions,
    cfg: &PipelineConfig,
    config_name: &str,
) -> Result<CollapseSummary, CollapseError> {
    let records = dataset::read_csv(&args.drops)?;
    let dataset_id =
        crate::dataset::id::of_file(&args.drops).map_err(|source| DatasetError::Io {
            path: args.drops.clone(),
            source,
        })?;
    if records.is_empty() {
        return Err(CollapseError::Empty {
            path: args.drops.clone(),
        });
    }
    let outcomes = compute_groups(&args.drops, &records, cfg, config_name, args.contact_radius)?;
    let used: Vec<DropGroups> = outcomes
        .iter()
        .filter_map(|o| o.groups.as_ref().ok().cloned())
        .collect();
    let settings = fit::FitSettings {
        resamples: args.bootstrap,
        seed: args.seed,
    };
    let fits = fit::fit_all(&used, settings);

    let (mut warnings, n_skipped, n_rejected) = warnings_of(&used, &records, &outcomes, &fits);

    // Per-drop diagnostics where tracks/<run>.csv exists beside drops.csv.
    let (diags, track_warnings) = per_drop::diagnose_all(&args.drops, &records, |i, _| {
        cfg.surfaces.get(&outcomes[i].surface)
    });
    warnings.extend(track_warnings);
    let force_laws: Vec<_> = diags.iter().filter_map(|d| d.force_law.clone()).collect();

    let prov = provenance(args, cfg, &used, &dataset_id);

    let out_dir = args.out_dir();
    let ledger = &mut Ledger::open(&out_dir);
    let failed = |source| CollapseError::Write {
        path: out_dir.clone(),
        source,
    };
    // Nothing of an earlier collapse in this folder (another dataset's, or
    // figures a --no-plots run would not replace) survives this one.
    remove_outputs(ledger).map_err(failed)?;
    let mut files = Vec::new();
    let written = (|| {
        write(
            ledger,
            Path::new(TABLES[0]),
            &output::collapse_csv(&outcomes, &dataset_id),
            &mut files,
        )?;
        write(
            ledger,
            Path::new(TABLES[1]),
            &output::fits_json(&prov, &outcomes, &fits, &force_laws, &warnings),
            &mut files,
        )?;
        if !args.no_plots {
            for (name, bytes) in crate::figures::collapse_figures(&used, &fits)? {
                let rel = Path::new("plots").join(&name);
                let bytes = if rel.extension().is_some_and(|e| e == "svg") {
                    crate::dataset::id::tag_svg(bytes, &dataset_id)
                } else {
                    bytes
                };
                write(ledger, &rel, &bytes, &mut files)?;
            }
            per_drop::replace(ledger, per_drop::figures(diags, &dataset_id)?, &mut files)
        } else {
            per_drop::replace(ledger, Vec::new(), &mut files)
        }
    })();
    // What was written is listed, whether or not all of it was.
    let saved = ledger.save().map_err(failed);
    written?;
    saved?;
    files.sort();
    Ok(CollapseSummary {
        out_dir,
        n_used: used.len(),
        n_skipped,
        n_rejected,
        fits,
        warnings,
        files,
    })
}

/// The collapse's warnings (drops on the geometric contact radius, rows
/// skipped, drops rejected in review, the fits'), with the counts of rows
/// skipped and of drops rejected.
fn warnings_of(
    used: &[DropGroups],
    records: &[dataset::DropRecord],
    outcomes: &[DropOutcome],
    fits: &fit::Fits,
) -> (Vec<String>, usize, usize) {
    let mut warnings = Vec::new();
    let n_geo = used.iter().filter(|g| g.a_source.is_geometric()).count();
    if n_geo > 0 {
        let runs: Vec<&str> = used
            .iter()
            .filter(|g| g.a_source.is_geometric())
            .map(|g| g.run.as_str())
            .take(5)
            .collect();
        warnings.push(format!(
            "GEOMETRIC CONTACT RADIUS: {n_geo} of {} drops use a = sqrt(R^2 - (R - delta)^2) \
             (requested, a_max_mm missing, or a_max_mm equal to it; e.g. {}). For them \
             Xi^2 = Psi (2 - Pi) holds by construction, so their collapse of Psi(Xi) is not an \
             experimental result (docs/physics.md)",
            used.len(),
            runs.join(", ")
        ));
    }
    let n_rejected = records
        .iter()
        .filter(|r| r.status == dataset::DropStatus::Rejected)
        .count();
    // A rejected drop is listed under `skipped` with its reason, and said
    // apart: a person's decision, not a problem of the row.
    let n_skipped = outcomes
        .iter()
        .filter(|o| o.skipped())
        .count()
        .saturating_sub(n_rejected);
    if n_skipped > 0 {
        warnings.push(format!(
            "{n_skipped} of {} rows skipped (listed under `skipped`)",
            outcomes.len()
        ));
    }
    if n_rejected > 0 {
        warnings.push(format!(
            "{} rejected in review left out (listed under `skipped`)",
            crate::util::text::plural(n_rejected, "drop")
        ));
    }
    warnings.extend(fits.warnings.iter().cloned());
    (warnings, n_skipped, n_rejected)
}

/// What `fits.json` records of how the collapse was made.
fn provenance(
    args: &CollapseOptions,
    cfg: &PipelineConfig,
    used: &[DropGroups],
    dataset_id: &str,
) -> output::Provenance {
    let names: std::collections::BTreeSet<&str> = used.iter().map(|g| g.surface.as_str()).collect();
    let surfaces = names
        .into_iter()
        .map(|n| {
            let s = &cfg.surfaces[n];
            output::SurfaceUsed {
                name: n.to_string(),
                modulus_pa: s.modulus_pa,
                pillar_height_m: s.pillar_height_m,
                solid_fraction: s.solid_fraction,
            }
        })
        .collect();
    output::Provenance {
        dropscope_version: env!("CARGO_PKG_VERSION"),
        drops_csv: args
            .drops
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
        dataset_id: dataset_id.to_string(),
        contact_radius: match args.contact_radius {
            ContactRadius::Measured => "measured",
            ContactRadius::Geometric => "geometric",
        },
        bootstrap_resamples: args.bootstrap,
        seed: args.seed,
        surfaces,
    }
}
