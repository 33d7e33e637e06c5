//! A job's runs written into its output folder: each run's files
//! (track CSV, overlays, animated impact) as soon as the run is done, each
//! whole or not at all, and made durable at once before the drops.csv that
//! lists them ([`write_run_outputs`], [`sync_outputs`]); [`process_all`]
//! processes and writes a list of runs.

use crate::config::PipelineConfig;
use crate::dataset::manifest::RunSpec;
use crate::dataset::DropRecord;
use crate::job::cache::OutputFile;
use crate::pipeline::{prepare, process_setup, setups, Prepared, ProcessError, RunOutcome};
use crate::util::io::Durable;
use rayon::prelude::*;
use std::io::Write;
use std::path::Path;

/// Write `bytes` to `out/rel` atomically, creating folders.
pub fn write_file(out: &Path, rel: &str, bytes: &[u8]) -> Result<(), ProcessError> {
    write_file_as(out, rel, Durable::Now, |f| f.write_all(bytes))
}

/// Write what `write` writes to `out/rel` atomically, creating folders,
/// durable as `durable` says.
fn write_file_as(
    out: &Path,
    rel: &str,
    durable: Durable,
    write: impl FnOnce(&mut std::fs::File) -> std::io::Result<()>,
) -> Result<(), ProcessError> {
    crate::util::out_folder::write_as(out, rel, durable, write)
        .map(drop)
        .map_err(|source| ProcessError::Write {
            path: out.join(rel),
            source,
        })
}

/// Make the files written by [`write_run_outputs`] (and the cache entries)
/// into `out` durable, all at once: called before the drops.csv that lists
/// them. Until then an operating-system crash may leave a run's file short;
/// the cache finds it by its SHA-256 and processes the run again.
pub fn sync_outputs(out: &Path) -> Result<(), ProcessError> {
    crate::util::io::sync_file_system(out).map_err(|source| ProcessError::Write {
        path: out.to_path_buf(),
        source,
    })
}

/// Write one run's track (`tracks/<run>.csv`), overlays
/// (`plots/overlays/<run>[_<number>].png`) and animated impact
/// (`plots/impacts/<run>.png`) into `out`, each atomically but unsynced:
/// the job makes them durable at once ([`sync_outputs`]) before its
/// drops.csv. A track, main overlay or animation that this run's previous
/// cache entry lists, and that this outcome does not have (the run now
/// fails), is removed while it holds the bytes written then
/// ([`crate::util::out_folder::remove_if_holds`]). A run whose name
/// is no file name writes and removes nothing. Returns the files written,
/// relative to `out`, with the SHA-256 of their bytes.
pub fn write_run_outputs(out: &Path, o: &RunOutcome) -> Result<Vec<OutputFile>, ProcessError> {
    let run = &o.record.run;
    if crate::dataset::run_name::check(run).is_err() {
        // Its row says why it failed; it has no files and removes none.
        return Ok(Vec::new());
    }
    let track = format!("tracks/{run}.csv");
    let main_overlay = format!("plots/overlays/{run}.png");
    let before = crate::job::cache::listed_outputs(out, run);
    let remove_if_present = |out: &Path, rel: &str| remove_if_listed(out, rel, &before);
    let mut written = Vec::new();
    if o.track_csv.is_empty() {
        remove_if_present(out, &track)?;
    } else {
        // From its spool to the file, never whole in memory.
        write_file_as(out, &track, Durable::WithTheJob, |f| o.track_csv.copy_to(f))?;
        written.push(OutputFile {
            sha256: o.track_csv.sha256_hex(),
            path: track,
        });
    }
    let mut write = |rel: String, bytes: &[u8]| -> Result<(), ProcessError> {
        write_file_as(out, &rel, Durable::WithTheJob, |f| f.write_all(bytes))?;
        written.push(OutputFile::new(rel, bytes));
        Ok(())
    };
    match &o.overlay {
        Some(png) => write(main_overlay, png)?,
        None => remove_if_present(out, &main_overlay)?,
    }
    let impact = format!("plots/impacts/{run}.png");
    match &o.impact {
        Some(apng) => write(impact, apng)?,
        None => remove_if_present(out, &impact)?,
    }
    for (n, png) in &o.frame_overlays {
        write(format!("plots/overlays/{run}_{n}.png"), png)?;
    }
    Ok(written)
}

/// Remove `out/rel` if `listed` (what an earlier job wrote for the run)
/// names it and it still holds the bytes listed there.
fn remove_if_listed(out: &Path, rel: &str, listed: &[OutputFile]) -> Result<(), ProcessError> {
    let Some(f) = listed.iter().find(|f| f.path == rel) else {
        return Ok(());
    };
    crate::util::out_folder::remove_if_holds(out, rel, &f.sha256)
        .map(drop)
        .map_err(|source| ProcessError::Write {
            path: out.join(rel),
            source,
        })
}

/// Process `runs` in parallel and write `drops.csv`, `tracks/` and
/// `plots/overlays/` into `out`. Returns the records in the runs' order.
pub fn process_all(
    runs: &[RunSpec],
    cfg: &PipelineConfig,
    out: &Path,
    progress: &(dyn Fn(&DropRecord) + Sync),
) -> Result<Vec<DropRecord>, ProcessError> {
    process_all_with_overlays(runs, cfg, out, &[], progress)
}

/// [`process_all`], also drawing the overlays of the image numbers
/// `overlay_frames` of every run (`plots/overlays/<run>_<number>.png`).
/// Each run's files are written as soon as it is done, so memory holds only
/// the runs in flight.
pub fn process_all_with_overlays(
    runs: &[RunSpec],
    cfg: &PipelineConfig,
    out: &Path,
    overlay_frames: &[i64],
    progress: &(dyn Fn(&DropRecord) + Sync),
) -> Result<Vec<DropRecord>, ProcessError> {
    let Prepared { runs, cfg, kept } = prepare(runs, cfg, &|_| None, &|_| {});
    let (runs, cfg, kept) = (&runs, &cfg, &kept);
    let groups = setups(runs);
    let done = groups
        .par_iter()
        .map(|g| {
            let members: Vec<&RunSpec> = g.iter().map(|&i| &runs[i]).collect();
            let kept = g.iter().map(|&i| kept.take(i)).collect();
            let outcomes = process_setup(&members, cfg, overlay_frames, kept);
            let mut recs = Vec::with_capacity(g.len());
            for (&i, o) in g.iter().zip(outcomes) {
                write_run_outputs(out, &o)?;
                progress(&o.record);
                recs.push((i, o.record));
            }
            Ok(recs)
        })
        .collect::<Result<Vec<_>, ProcessError>>()?;
    // Back in the runs' order.
    let mut done: Vec<(usize, DropRecord)> = done.into_iter().flatten().collect();
    done.sort_by_key(|(i, _)| *i);
    let records: Vec<DropRecord> = done.into_iter().map(|(_, r)| r).collect();
    sync_outputs(out)?;
    write_file(out, "drops.csv", &crate::dataset::to_csv_bytes(&records))?;
    Ok(records)
}
