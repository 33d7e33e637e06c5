//! `dropscope process` as a job: the runs named on the command line (or a
//! manifest) through the main job's processing ([`crate::job::batch::process_runs`]:
//! the result cache, `--force`, `--threads`, progress events), then
//! `drops.csv`, `provenance.json` and the per-drop figures
//! (`plots/drops/<run>.svg|png`); no collapse and no report.

use std::path::Path;

use crate::config::PipelineConfig;
use crate::dataset::manifest::RunSpec;
use crate::dataset::{DropRecord, DropStatus};
use crate::job::batch::{
    on_threads, process_runs_unsynced, replace_provenance, BatchError, JobOptions, Processed,
    RunEvent,
};
use crate::job::run_outputs::write_file;
use crate::util::out_folder::Ledger;
use crate::util::timings::{time, Stage};

/// What a `process` job did.
#[derive(Debug, Clone)]
pub struct ProcessSummary {
    /// One record per run, in the runs' order (as in drops.csv).
    pub records: Vec<DropRecord>,
    /// Runs whose cached result was reused.
    pub cached: usize,
    /// Frames read by this job (cached runs read none).
    pub frames: usize,
    /// Wall time of processing the runs, seconds.
    pub process_s: f64,
    /// Worker threads the runs were processed on.
    pub threads: usize,
    /// Tracks the per-drop figures could not use.
    pub warnings: Vec<String>,
}

impl ProcessSummary {
    /// Runs with status `status`.
    pub fn count(&self, status: DropStatus) -> usize {
        self.records.iter().filter(|r| r.status == status).count()
    }
}

/// Remove the collapse files and report an earlier job left in `out`,
/// computed from another drops.csv than the one just written (dataset
/// `id`), saying which ([`crate::job::leftovers::remove_other_dataset`]): a
/// process job writes no collapse, and they would no longer match.
fn remove_other_collapse(
    ledger: &mut Ledger,
    id: &str,
    events: &(dyn Fn(RunEvent) + Sync),
) -> Result<(), BatchError> {
    let out = ledger.out().to_path_buf();
    let removed = crate::job::leftovers::remove_other_dataset(ledger, id).map_err(|source| {
        BatchError::Io {
            path: out.clone(),
            source,
        }
    })?;
    if !removed.is_empty() {
        let (figures, files): (Vec<&String>, Vec<&String>) =
            removed.iter().partition(|f| f.starts_with("plots/"));
        let mut named: Vec<String> = files.iter().map(|f| f.to_string()).collect();
        if !figures.is_empty() {
            named.push(crate::util::text::plural(figures.len(), "figure"));
        }
        events(RunEvent::Notice(&format!(
            "removed {} ({}) that an earlier job computed from another drops.csv; `dropscope \
             collapse {}` computes them for this one",
            crate::util::text::plural(removed.len(), "file"),
            named.join(", "),
            out.join("drops.csv").display()
        )));
    }
    Ok(())
}

/// Process `runs` into `out`, which the caller holds ([`crate::job::lock`]), all
/// of it on `options.threads` ([`on_threads`]).
pub fn run(
    runs: &[RunSpec],
    cfg: &PipelineConfig,
    config_name: &str,
    out: &Path,
    options: &JobOptions,
    overlay_frames: &[i64],
    events: &(dyn Fn(RunEvent) + Sync),
) -> Result<ProcessSummary, BatchError> {
    on_threads(options.threads, out, || {
        run_on_pool(runs, cfg, config_name, out, options, overlay_frames, events)
    })
}

/// [`run`] on the job's pool.
fn run_on_pool(
    runs: &[RunSpec],
    cfg: &PipelineConfig,
    config_name: &str,
    out: &Path,
    options: &JobOptions,
    overlay_frames: &[i64],
    events: &(dyn Fn(RunEvent) + Sync),
) -> Result<ProcessSummary, BatchError> {
    crate::util::io::remove_stale_temporaries(out, &crate::job::lock::writer_is_gone).map_err(
        |source| BatchError::Io {
            path: out.to_path_buf(),
            source,
        },
    )?;
    let Processed {
        done,
        seconds,
        threads,
        review,
    } = process_runs_unsynced(runs, cfg, out, options, overlay_frames, events)?;
    let cached = done.iter().filter(|(_, hit)| *hit).count();
    let frames = done
        .iter()
        .filter(|(_, hit)| !*hit)
        .map(|(e, _)| e.frames)
        .sum();
    let entries: Vec<_> = done.into_iter().map(|(e, _)| e).collect();
    let records: Vec<DropRecord> = entries.iter().map(|e| e.record.clone()).collect();
    let drops = crate::dataset::to_csv_bytes(&records);
    let id = crate::dataset::id::of_bytes(&drops);
    // The per-drop figures are drawn from the tracks while the runs' files
    // are synced and drops.csv and provenance.json written; they are
    // written after drops.csv. The syncs wait on the disk on a thread of
    // their own: on one of the pool's they would hold it, and a single
    // drop's figures (their SVG and PNG drawn at once) would have one thread.
    let mut ledger = Ledger::open(out);
    let (written, drawn) = std::thread::scope(|scope| {
        let ledger = &mut ledger;
        let writer = scope.spawn(|| {
            crate::job::run_outputs::sync_outputs(out)?;
            time(Stage::Writes, || -> Result<(), BatchError> {
                write_file(out, "drops.csv", &drops)?;
                remove_other_collapse(ledger, &id, events)?;
                replace_provenance(out, cfg, config_name, &entries, &review, events)
            })
        });
        let drawn = time(Stage::Figures, || {
            crate::job::per_drop::draw(&out.join("drops.csv"), &records, cfg, &id)
        });
        let written = writer
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        (written, drawn)
    });
    let saved = |ledger: &mut Ledger| {
        ledger.save().map_err(|source| BatchError::Io {
            path: out.to_path_buf(),
            source,
        })
    };
    if let Err(e) = written {
        saved(&mut ledger)?;
        return Err(e);
    }
    let (drawn, warnings) = drawn?;
    let replaced = time(Stage::Figures, || {
        crate::job::per_drop::replace(&mut ledger, drawn, &mut Vec::new())
    });
    saved(&mut ledger)?;
    replaced?;
    Ok(ProcessSummary {
        records,
        cached,
        frames,
        process_s: seconds,
        threads,
        warnings,
    })
}
