//! The per-drop figures (`plots/drops/<run>.svg` and `.png`: z(t), δ(t),
//! F(δ)) of every measured drop whose track lies beside its drops.csv
//! (`tracks/<run>.csv`). `process` draws them while it writes drops.csv
//! ([`draw`]) and writes them after it ([`replace`]); `collapse` draws them
//! again with its own figures, from the same files, to the same bytes.

use std::path::{Path, PathBuf};

use crate::collapse::diagnostics::{self, DropDiagnostics};
use crate::collapse::CollapseError;
use crate::config::{PipelineConfig, Surface};
use crate::dataset::DropRecord;
use crate::util::io::Durable;
use crate::util::out_folder::Ledger;

/// The diagnostics of the drops of `records` (the rows of `drops_csv`)
/// that were measured and have a track beside it; `surface_of(i, record)`
/// gives row i's surface (a row without one is skipped). A track that
/// cannot be used is a warning naming it.
pub fn diagnose_all<'a>(
    drops_csv: &Path,
    records: &[DropRecord],
    surface_of: impl Fn(usize, &DropRecord) -> Option<&'a Surface>,
) -> (Vec<DropDiagnostics>, Vec<String>) {
    let tracks_dir = drops_csv.parent().unwrap_or(Path::new("")).join("tracks");
    let (mut diags, mut warnings) = (Vec::new(), Vec::new());
    let mut todo = Vec::new();
    for (i, rec) in records.iter().enumerate() {
        // A run name that is not a file name never reaches outside tracks/.
        if crate::dataset::run_name::check(&rec.run).is_err() || !rec.status.measured() {
            continue;
        }
        let Some(p) = crate::util::out_folder::path(&tracks_dir, &format!("{}.csv", rec.run))
            .ok()
            .filter(|p| p.is_file())
        else {
            continue;
        };
        let Some(surface) = surface_of(i, rec) else {
            continue;
        };
        todo.push((rec, surface, p));
    }
    // Each drop on its own (on every thread), kept in the records' order.
    use rayon::prelude::*;
    let done: Vec<_> = todo
        .par_iter()
        .map(|(rec, surface, p)| diagnostics::diagnose(rec, surface, p))
        .collect();
    for d in done {
        match d {
            Ok(d) => diags.push(d),
            Err(e) => warnings.push(format!("track not used: {e}")),
        }
    }
    (diags, warnings)
}

/// The figures of `diags`, as (path relative to the output folder, bytes),
/// each SVG tagged with the dataset id of the drops.csv they come from.
/// Each drop's track is let go once its figures are drawn.
pub fn figures(
    diags: Vec<DropDiagnostics>,
    dataset_id: &str,
) -> Result<Vec<(PathBuf, Vec<u8>)>, CollapseError> {
    // Each drop's figures on their own (on every thread), in order.
    use rayon::prelude::*;
    let drawn: Vec<_> = diags
        .into_par_iter()
        .map(|d| {
            crate::util::timings::time(crate::util::timings::Stage::Figures, || {
                // Named after the run, as its track and overlay are (spaces
                // and non-ASCII letters included): its name passed
                // `run_name::check` in `diagnose_all`.
                let named = crate::figures::drop_figures(&d)?;
                Ok::<_, CollapseError>(
                    named
                        .into_iter()
                        .map(|(name, bytes)| {
                            let ext = name.rsplit('.').next().unwrap_or_default();
                            (format!("{}.{ext}", d.run), bytes)
                        })
                        .collect::<Vec<_>>(),
                )
            })
        })
        .collect();
    let mut out = Vec::new();
    for d in drawn {
        for (name, bytes) in d? {
            let rel = Path::new("plots").join("drops").join(name);
            let bytes = if rel.extension().is_some_and(|e| e == "svg") {
                crate::dataset::id::tag_svg(bytes, dataset_id)
            } else {
                bytes
            };
            out.push((rel, bytes));
        }
    }
    Ok(out)
}

/// The figures of the drops in `drops_csv` (whose rows are `records`; it
/// need not be written yet), drawn from the tracks beside it, each row's
/// surface taken from `cfg` by name, and tagged with `dataset_id`, the id
/// of its bytes: (path relative to the output folder, bytes) for
/// [`replace`], and the warnings about tracks that could not be used.
#[allow(clippy::type_complexity)]
pub fn draw(
    drops_csv: &Path,
    records: &[DropRecord],
    cfg: &PipelineConfig,
    dataset_id: &str,
) -> Result<(Vec<(PathBuf, Vec<u8>)>, Vec<String>), CollapseError> {
    let (diags, warnings) = diagnose_all(drops_csv, records, |_, r| {
        let name = if r.surface.is_empty() {
            &cfg.input.surface
        } else {
            &r.surface
        };
        cfg.surfaces.get(name)
    });
    Ok((figures(diags, dataset_id)?, warnings))
}

/// Write `figures` (paths under `plots/drops/`) through the output
/// folder's `ledger`, each atomically (and all synced at once,
/// [`crate::util::io::sync_file_system`]), adding them to `files`, then
/// remove the other per-drop figures an earlier job wrote (those the ledger
/// lists, unchanged): those of drops no longer measured or no longer in
/// the job. A reader sees the old figure or the new one, never none; any
/// other file in the folder (a figure of yours) stays.
pub fn replace(
    ledger: &mut Ledger,
    figures: Vec<(PathBuf, Vec<u8>)>,
    files: &mut Vec<PathBuf>,
) -> Result<(), CollapseError> {
    let mut kept = std::collections::BTreeSet::new();
    // Unsynced, then all synced at once (one journal commit, not two a
    // drop), before the old ones go.
    let any = !figures.is_empty();
    for (rel, bytes) in figures {
        write_as(ledger, &rel, &bytes, files, Durable::WithTheJob)?;
        kept.insert(rel.to_string_lossy().into_owned());
    }
    let out_dir = ledger.out().to_path_buf();
    let gone = |source| CollapseError::Write {
        path: out_dir.join("plots").join("drops"),
        source,
    };
    if any {
        crate::util::io::sync_file_system(&out_dir).map_err(gone)?;
    }
    let earlier: Vec<String> = ledger
        .listed()
        .filter(|rel| rel.starts_with("plots/drops/") && !kept.contains(*rel))
        .map(str::to_string)
        .collect();
    for rel in earlier {
        ledger.remove(&rel).map_err(gone)?;
    }
    Ok(())
}

/// `rel` written through `ledger` and added to `files`, synced now or left for one [`crate::util::io::sync_file_system`]
/// of them all ([`Durable`]): through the output folder's ledger
/// ([`crate::util::out_folder`]), which lists it as dropscope's.
pub(crate) fn write_as(
    ledger: &mut Ledger,
    rel: &Path,
    bytes: &[u8],
    files: &mut Vec<PathBuf>,
    durable: Durable,
) -> Result<(), CollapseError> {
    ledger
        .write_as(&rel.to_string_lossy(), bytes, durable)
        .map_err(|source| CollapseError::Write {
            path: ledger.out().join(rel),
            source,
        })?;
    files.push(rel.to_path_buf());
    Ok(())
}
