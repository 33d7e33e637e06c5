//! The main job (`dropscope` or `dropscope run`): every run of the
//! configuration's manifest (or of its input paths) → process → collapse,
//! all into the configuration's output folder.
//!
//! Runs are processed in parallel, each streaming its frames; each run's
//! files are written as soon as it is done, and its cache entry
//! (`runs/<run>.json`, see [`crate::job::cache`]) last, so a job killed at any
//! moment and started again redoes only the runs it had not committed, and
//! ends with the outputs of an uninterrupted job. `drops.csv` is assembled
//! from the entries in the manifest's order; `provenance.json` records the
//! version, the resolved configuration and every input's fingerprint.

use crate::collapse::groups::ContactRadius;
use crate::config::PipelineConfig;
use crate::dataset::manifest::{read_job_manifest, RunSpec};
use crate::dataset::{DropRecord, DropStatus};
use crate::job::cache::{self, Entry};
use crate::job::collapse_job::CollapseOptions;
use crate::job::run_outputs::{write_file, write_run_outputs};
use crate::pipeline::process_setup;
use crate::source::listing::{recording_kind, Listing};
use crate::source::SourceError;
use crate::util::timings::{self, Stage};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Why the job could not run (a bad run is a row, not this).
#[derive(Debug, thiserror::Error)]
pub enum BatchError {
    /// The configuration could not be used.
    #[error(transparent)]
    Config(#[from] crate::config::ConfigError),
    /// The run manifest could not be read.
    #[error(transparent)]
    Manifest(#[from] crate::dataset::manifest::ManifestError),
    /// The processing stage could not run (an output not written, an input that is no run).
    #[error(transparent)]
    Process(#[from] crate::pipeline::ProcessError),
    /// The collapse could not run.
    #[error(transparent)]
    Collapse(#[from] crate::collapse::CollapseError),
    /// The report could not be written.
    #[error(transparent)]
    Report(#[from] crate::report::ReportError),
    /// A file or folder could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The configuration names no input (neither `input.manifest` nor `input.paths`).
    #[error(
        "the configuration names no input: set input.manifest or input.paths in pipeline.toml"
    )]
    NoInput,
    /// `input.paths` holds no run folder or `.cine` file (the path searched).
    #[error("input.paths: no run folder or .cine file found under {0}")]
    NothingFound(String),
    /// The output folder could not be taken.
    #[error(transparent)]
    Lock(#[from] crate::job::lock::LockError),
    /// The review's decisions could not be read.
    #[error(transparent)]
    Review(#[from] crate::dataset::decisions::ReviewError),
    /// `--threads` asks for more than [`max_threads`].
    #[error(
        "--threads {asked}: at most {max} on this machine (4 × its {cores} cores): more threads \
         only share the cores, and each holds frames in memory"
    )]
    TooManyThreads {
        /// The threads asked for.
        asked: usize,
        /// The most allowed.
        max: usize,
        /// The machine's cores.
        cores: usize,
    },
}

/// `threads` refused when above [`max_threads`].
pub fn check_threads(threads: Option<usize>) -> Result<(), BatchError> {
    let (max, cores) = max_threads();
    match threads.filter(|&n| n > max) {
        Some(asked) => Err(BatchError::TooManyThreads { asked, max, cores }),
        None => Ok(()),
    }
}

/// Most worker threads a job takes: 4 × the machine's cores (at least 4),
/// never more than 1024.
pub fn max_threads() -> (usize, usize) {
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    (cores.saturating_mul(4).clamp(4, 1024), cores)
}

/// How the job runs (not what it computes: outputs do not depend on these).
#[derive(Debug, Clone, Copy, Default)]
pub struct JobOptions {
    /// Ignore cached results.
    pub force: bool,
    /// Worker threads; `None` is rayon's default (one per core).
    pub threads: Option<usize>,
    /// Only this share of the runs, and no drops.csv, collapse or report.
    pub shard: Option<crate::job::shard::Shard>,
    /// Wait for another job holding the output folder instead of stopping.
    pub wait: bool,
}

/// What the job reports while it runs, from the worker threads.
#[derive(Debug, Clone, Copy)]
pub enum RunEvent<'a> {
    /// The job knows how many runs it has.
    Planned {
        /// How many.
        runs: usize,
    },
    /// A worker starts on a run.
    Started {
        /// The run's name.
        run: &'a str,
    },
    /// A run is done: measured, failed, or taken from the cache.
    Finished {
        /// The run's row of drops.csv.
        record: &'a DropRecord,
        /// Whether it was taken from the cache.
        cached: bool,
        /// Frames the run held.
        frames: usize,
        /// Seconds this job spent on the run (`None`: taken from the cache).
        seconds: Option<f64>,
    },
    /// Every run is done; the collapse (and report) starts.
    Collapsing,
    /// Something the user should know (a stale lock taken over, a wait).
    Notice(&'a str),
}

/// What the job did.
#[derive(Debug, Clone)]
pub struct JobSummary {
    /// The rows of drops.csv, one per run of this job.
    pub records: Vec<DropRecord>,
    /// The output folder.
    pub out: PathBuf,
    /// Runs whose cached result was reused.
    pub cached: usize,
    /// Frames read by this job (cached runs read none).
    pub frames: usize,
    /// Wall time of processing the runs (not the collapse or report), seconds.
    pub process_s: f64,
    /// Worker threads the runs were processed on.
    pub threads: usize,
    /// Whether the collapse stage ran (it needs at least one measured drop).
    pub collapsed: bool,
    /// The share of the runs this job took (`None`: all, and it assembled them).
    pub shard: Option<crate::job::shard::Shard>,
    /// Warnings of the collapse (also in fits.json).
    pub collapse_warnings: Vec<String>,
    /// Too few drops for the collapse's exponents and series: what they can
    /// and cannot show (`fits.json`'s `few_drops`; not among the warnings).
    pub collapse_note: Option<String>,
}

impl JobSummary {
    /// Runs that failed.
    pub fn failed(&self) -> usize {
        self.count(DropStatus::Failed)
    }

    /// Runs with status `status`.
    pub fn count(&self, status: DropStatus) -> usize {
        self.records.iter().filter(|r| r.status == status).count()
    }
}

/// Whether `dir` is an output folder dropscope wrote (it holds its
/// `provenance.json` or the ledger of its files).
fn is_output_folder(dir: &Path) -> bool {
    [crate::util::out_folder::LEDGER_FILE, "provenance.json"]
        .iter()
        .any(|f| dir.join(f).is_file())
}

/// Whether `path`, inside an output folder, is one of the folders
/// dropscope writes there (never searched for runs: `process DIR --out
/// DIR` again would take `plots/overlays/` for a run).
fn is_output_part(path: &Path) -> bool {
    path.file_name()
        .and_then(|n| n.to_str())
        .is_some_and(|n| matches!(n, "plots" | "tracks" | "runs" | crate::job::lock::LOCK_DIR))
}

/// Deepest folder level searched under an input path (guards symlink loops).
const MAX_SEARCH_DEPTH: usize = 16;

/// Runs under the configured paths: a recording file (`.cine`, `.mraw`) or
/// a folder of frames is one run; any other folder is searched, at any
/// depth, for both. A folder of frames is not searched further, but the
/// recordings beside its frames are runs too (children in name order, so
/// the runs' order does not depend on the file system).
pub fn discover_runs(paths: &[PathBuf]) -> Result<Vec<PathBuf>, BatchError> {
    fn search(dir: &Path, depth: usize, out: &mut Vec<PathBuf>) -> Result<(), BatchError> {
        let listing = Listing::of(dir).map_err(|e| match e {
            SourceError::Io { path, source } => BatchError::Io { path, source },
            other => BatchError::Io {
                path: dir.to_path_buf(),
                source: std::io::Error::other(other.to_string()),
            },
        })?;
        let mut children: Vec<(PathBuf, bool)> = listing
            .recordings()
            .map(|r| (dir.join(r), false))
            .chain(listing.dirs.iter().map(|d| (dir.join(d), true)))
            .collect();
        children.sort();
        let output_folder = is_output_folder(dir);
        for (c, is_dir) in children {
            if output_folder && is_output_part(&c) {
                // dropscope's own figures, tracks and cache, not runs.
                continue;
            }
            if !is_dir {
                out.push(c);
            } else if let Ok(sub) = Listing::of(&c) {
                if sub.has_frames() {
                    out.extend(sub.runs_here());
                } else if depth < MAX_SEARCH_DEPTH {
                    search(&c, depth + 1, out)?;
                }
            }
        }
        Ok(())
    }
    let mut out = Vec::new();
    for p in paths {
        if recording_kind(p).is_some() && !p.is_dir() {
            out.push(p.clone());
            continue;
        }
        if let Some(l) = Listing::of(p).ok().filter(|l| l.has_frames()) {
            out.extend(l.runs_here());
            continue;
        }
        let before = out.len();
        search(p, 1, &mut out)?;
        if out.len() == before {
            return Err(BatchError::NothingFound(p.display().to_string()));
        }
    }
    Ok(out)
}

/// `dropscope process`'s inputs with every folder replaced by the runs
/// found in it ([`discover_runs`]: itself when it holds frames, the
/// recordings beside them, or the runs under it); any other input (a
/// recording, a folder with nothing found in it) is kept, so
/// that it gets its own row and reason, and a path that is not there is
/// kept for [`crate::pipeline::runs_from_inputs`] to refuse.
pub fn expand_inputs(inputs: &[PathBuf]) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for p in inputs {
        if p.is_dir() {
            if let Ok(found) = discover_runs(std::slice::from_ref(p)) {
                out.extend(found);
                continue;
            }
        }
        out.push(p.clone());
    }
    out
}

/// The runs the configuration names; `config_name` names the configuration
/// in messages (a manifest that is not there is its `input.manifest`).
pub fn configured_runs(
    cfg: &PipelineConfig,
    config_name: &str,
) -> Result<Vec<RunSpec>, BatchError> {
    if let Some(m) = &cfg.input.manifest {
        cfg.check_manifest(config_name)?;
        return Ok(read_job_manifest(m)?);
    }
    if cfg.input.paths.is_empty() {
        return Err(BatchError::NoInput);
    }
    let found = discover_runs(&cfg.input.paths)?;
    Ok(crate::pipeline::runs_from_inputs(&found, None, cfg)?)
}

/// The runs of one camera set-up (see [`crate::pipeline::setups`]): their
/// cached results when all are still valid, else all processed together
/// (their scale is pooled) and committed. A run's key in a set-up of
/// several also covers the other runs' keys, since its numbers depend on them.
/// `kept`: the members' tracks [`crate::pipeline::prepare`] kept, if any.
fn run_setup(
    members: &[&RunSpec],
    cfg: &PipelineConfig,
    out: &Path,
    force: bool,
    overlay_frames: &[i64],
    kept: Vec<Option<crate::pipeline::KeptRun>>,
    events: &(dyn Fn(RunEvent) + Sync),
) -> Result<Vec<(Entry, bool)>, BatchError> {
    // The inputs' fingerprints and the runs' keys. An input that cannot be
    // fingerprinted (missing, unreadable) is processed each time;
    // processing then says what is wrong with it.
    let keyed = || {
        let _fingerprint = timings::start(Stage::Fingerprint);
        let fps: Vec<Option<cache::Fingerprint>> = members
            .iter()
            .map(|r| cache::fingerprint(&r.path).ok())
            .collect();
        let keys = keys_of(members, &fps, cfg, overlay_frames);
        (fps, keys)
    };
    // With a cache entry for every run, the keys decide whether anything is
    // processed. Without (a first job, or --force), processing does not
    // wait for them: they are needed only for the entries written after,
    // and are computed beside it.
    let could_hit = !force
        && members
            .iter()
            .all(|r| cache::entry_path(out, &r.run).is_ok_and(|p| p.is_file()));
    let started = || {
        for r in members {
            events(RunEvent::Started { run: &r.run });
        }
    };
    let (fps, keys, outcomes) = if could_hit {
        let (fps, keys) = keyed();
        if keys.iter().all(Option::is_some) {
            let hits: Vec<Entry> = members
                .iter()
                .zip(&keys)
                .filter_map(|(r, k)| match cache::check(out, &r.run, k.as_ref()?) {
                    Ok(e) => Some(e),
                    Err(cache::Miss::Altered(path)) => {
                        events(RunEvent::Notice(&format!(
                            "{}: changed since dropscope wrote it (its content no longer \
                             matches its entry_sha256): run {} is measured again",
                            path.display(),
                            crate::util::text::terminal(&r.run)
                        )));
                        None
                    }
                    Err(_) => None,
                })
                .collect();
            if hits.len() == members.len() {
                for e in &hits {
                    events(RunEvent::Finished {
                        record: &e.record,
                        cached: true,
                        frames: e.frames,
                        seconds: None,
                    });
                }
                return Ok(hits.into_iter().map(|e| (e, true)).collect());
            }
        }
        started();
        (fps, keys, process_setup(members, cfg, overlay_frames, kept))
    } else {
        started();
        let ((fps, keys), outcomes) =
            rayon::join(keyed, || process_setup(members, cfg, overlay_frames, kept));
        (fps, keys, outcomes)
    };
    let mut done = Vec::with_capacity(members.len());
    for ((o, fp), (key, r)) in outcomes
        .into_iter()
        .zip(fps)
        .zip(keys.into_iter().zip(members))
    {
        for note in &o.notes {
            events(RunEvent::Notice(&format!("warning: {}: {note}", r.run)));
        }
        let writes = timings::start(Stage::Writes);
        let outputs = write_run_outputs(out, &o)?;
        let seconds = o.seconds;
        let entry = Entry {
            schema: cache::CACHE_SCHEMA,
            dropscope_version: env!("CARGO_PKG_VERSION").to_string(),
            key: key.clone().unwrap_or_default(),
            input: fp
                .clone()
                .unwrap_or_else(|| cache::Fingerprint::unreadable(&r.path)),
            outputs,
            frames: o.track_rows,
            record: o.record,
            scene: o.scene,
            scene_key: fp.as_ref().map(|fp| cache::scene_key(cfg, r, fp)),
            entry_sha256: String::new(),
        };
        if key.is_some() && crate::dataset::run_name::check(&r.run).is_ok() {
            cache::store(out, &entry).map_err(|source| BatchError::Io {
                path: out.join("runs").join(&r.run),
                source,
            })?;
        }
        drop(writes);
        events(RunEvent::Finished {
            record: &entry.record,
            cached: false,
            frames: entry.frames,
            seconds: Some(seconds),
        });
        done.push((entry, false));
    }
    Ok(done)
}

/// The runs' cache keys from their inputs' fingerprints (`None` where an
/// input has none): each run's own, and in a set-up of several, each
/// covering the others' too.
fn keys_of(
    members: &[&RunSpec],
    fps: &[Option<cache::Fingerprint>],
    cfg: &PipelineConfig,
    overlay_frames: &[i64],
) -> Vec<Option<String>> {
    // Extra overlays asked for are outputs of the run: another list, another key.
    let extra = format!("overlay_frames {overlay_frames:?}");
    let own: Vec<Option<String>> = members
        .iter()
        .zip(fps)
        .map(|(r, fp)| {
            let k = cache::key(cfg, r, fp.as_ref()?);
            Some(if overlay_frames.is_empty() {
                k
            } else {
                cache::combine_keys(&k, &[&extra])
            })
        })
        .collect();
    if members.len() > 1 && own.iter().all(Option::is_some) {
        let all: Vec<&str> = own.iter().flatten().map(String::as_str).collect();
        own.iter()
            .flatten()
            .map(|k| Some(cache::combine_keys(k, &all)))
            .collect()
    } else if members.len() > 1 {
        vec![None; members.len()]
    } else {
        own
    }
}

/// `provenance.json`: what produced the outputs, without timestamps, so the
/// same inputs and configuration give the same bytes.
pub(crate) fn provenance_json(
    cfg: &PipelineConfig,
    config_name: &str,
    entries: &[Entry],
    review: &Review,
) -> Vec<u8> {
    #[derive(serde::Serialize)]
    struct RunProvenance<'a> {
        run: &'a str,
        key: &'a str,
        input: &'a cache::Fingerprint,
        /// The files the run wrote (what [`crate::job::leftovers`] removes when
        /// a later job into the folder does not write them again).
        outputs: &'a [cache::OutputFile],
    }
    #[derive(serde::Serialize)]
    struct Provenance<'a> {
        dropscope_version: &'a str,
        dropscope_source_sha256: &'a str,
        configuration_file: &'a str,
        /// With the keys of pipeline.toml (`radius_mm`, `[surface.<name>]`),
        /// as check-config prints it.
        configuration: toml::Value,
        /// `--fps`, `--mm-per-px`, `--surface-row-px` when given.
        #[serde(skip_serializing_if = "crate::config::CommandLineValues::is_empty")]
        command_line: crate::config::CommandLineValues,
        runs: Vec<RunProvenance<'a>>,
        /// The decisions of `dropscope review` the job applied, when any.
        #[serde(skip_serializing_if = "Option::is_none")]
        review: Option<ReviewProvenance<'a>>,
    }
    #[derive(serde::Serialize)]
    struct ReviewProvenance<'a> {
        file: String,
        decisions: &'a [crate::dataset::decisions::Decision],
    }
    let p = Provenance {
        dropscope_version: env!("CARGO_PKG_VERSION"),
        dropscope_source_sha256: cache::SOURCE_SHA256,
        configuration_file: config_name,
        configuration: cfg.to_file_value(),
        command_line: cfg.command_line,
        runs: entries
            .iter()
            .map(|e| RunProvenance {
                run: &e.record.run,
                key: &e.key,
                input: &e.input,
                outputs: &e.outputs,
            })
            .collect(),
        review: (!review.decisions.rows.is_empty()).then(|| ReviewProvenance {
            file: review.path.display().to_string(),
            decisions: &review.decisions.rows,
        }),
    };
    let mut bytes = serde_json::to_vec_pretty(&p).unwrap_or_default();
    bytes.push(b'\n');
    bytes
}

/// Remove what the previous job in `out` wrote and this one did not
/// ([`crate::job::leftovers`]), saying so, then write this job's `provenance.json`.
pub(crate) fn replace_provenance(
    out: &Path,
    cfg: &PipelineConfig,
    config_name: &str,
    entries: &[Entry],
    review: &Review,
    events: &(dyn Fn(RunEvent) + Sync),
) -> Result<(), BatchError> {
    let removed = crate::job::leftovers::remove(out, entries).map_err(|source| BatchError::Io {
        path: out.to_path_buf(),
        source,
    })?;
    if let Some(m) = removed.message() {
        events(RunEvent::Notice(&m));
    }
    write_file(
        out,
        "provenance.json",
        &provenance_json(cfg, config_name, entries, review),
    )?;
    Ok(())
}

/// What [`process_runs`] did.
#[derive(Debug)]
pub struct Processed {
    /// One cache entry per run, in the runs' order, and whether it was
    /// reused from the cache.
    pub done: Vec<(Entry, bool)>,
    /// Wall time, seconds.
    pub seconds: f64,
    /// Worker threads the runs were processed on.
    pub threads: usize,
    /// The review decisions applied.
    pub review: Review,
}

/// The decisions of `dropscope review` a job applies, and where they are.
#[derive(Debug, Clone, Default)]
pub struct Review {
    /// The configuration's `input.review`, else `review.csv` in the output
    /// folder (which need not exist).
    pub path: PathBuf,
    /// The decisions read from `path` (none when it does not exist).
    pub decisions: crate::dataset::decisions::Decisions,
}

impl Review {
    /// The decisions for a job into `out` ([`crate::dataset::decisions::review_path`]).
    pub fn load(cfg: &PipelineConfig, out: &Path) -> Result<Review, BatchError> {
        use crate::dataset::decisions::{review_path, Decisions, REVIEW_FILE};
        let path = review_path(cfg.input.review.as_deref(), out);
        // The output folder's own file is read through no link below it;
        // a file the configuration names, as any input.
        let decisions = match &cfg.input.review {
            None => Decisions::read_in(out, REVIEW_FILE)?,
            Some(named) => Decisions::read(named)?,
        };
        Ok(Review { path, decisions })
    }

    /// `runs`, each with its decisions; a notice names the runs decided on
    /// that are not among them (their decisions wait, unused).
    pub fn apply(&self, runs: &[RunSpec], notice: &dyn Fn(&str)) -> Vec<RunSpec> {
        let others: Vec<&str> = self
            .decisions
            .runs()
            .into_iter()
            .filter(|d| !runs.iter().any(|r| r.run == *d))
            .collect();
        if !others.is_empty() {
            notice(&format!(
                "{}: decisions about {} not in this job ({}) are not used",
                self.path.display(),
                crate::util::text::plural(others.len(), "run"),
                others.join(", ")
            ));
        }
        runs.iter()
            .map(|r| RunSpec {
                review: self.decisions.for_run(&r.run),
                ..r.clone()
            })
            .collect()
    }
}

/// Process `runs` into `out` (which the caller holds), a camera set-up at a
/// time and set-ups in parallel on `options.threads` workers: each set-up's
/// cached results when still valid (unless `options.force`), else processed
/// and committed to the cache. `overlay_frames` are extra overlays drawn for
/// every run (part of the cache key). Writes no drops.csv; the runs' files
/// are on the disk when it returns ([`crate::job::run_outputs::sync_outputs`]).
pub fn process_runs(
    runs: &[RunSpec],
    cfg: &PipelineConfig,
    out: &Path,
    options: &JobOptions,
    overlay_frames: &[i64],
    events: &(dyn Fn(RunEvent) + Sync),
) -> Result<Processed, BatchError> {
    let processed = process_runs_unsynced(runs, cfg, out, options, overlay_frames, events)?;
    // The runs' files and cache entries, written unsynced, made durable at
    // once before the caller's drops.csv.
    crate::job::run_outputs::sync_outputs(out)?;
    Ok(processed)
}

/// [`process_runs`] but for its end: the runs' files and cache entries are
/// written and renamed into place, not yet synced. The caller makes them
/// durable ([`crate::job::run_outputs::sync_outputs`]) before it writes drops.csv;
/// meanwhile it may read them (`process` draws the per-drop figures from
/// the tracks while the disk syncs).
pub fn process_runs_unsynced(
    runs: &[RunSpec],
    cfg: &PipelineConfig,
    out: &Path,
    options: &JobOptions,
    overlay_frames: &[i64],
    events: &(dyn Fn(RunEvent) + Sync),
) -> Result<Processed, BatchError> {
    let start = std::time::Instant::now();
    let review = Review::load(cfg, out)?;
    let runs = &review.apply(runs, &|m| events(RunEvent::Notice(m)));
    events(RunEvent::Planned { runs: runs.len() });
    let scene_of = |r: &RunSpec| {
        (!options.force)
            .then(|| cache::cached_scene(out, cfg, r))
            .flatten()
    };
    let notice = |m: &str| events(RunEvent::Notice(m));
    // On the job's threads, finding the set-ups too.
    let work = || {
        let threads = rayon::current_num_threads();
        let crate::pipeline::Prepared { runs, cfg, kept } =
            crate::pipeline::prepare(runs, cfg, &scene_of, &notice);
        let (runs, cfg, kept) = (&runs, &cfg, &kept);
        let groups = crate::pipeline::setups(runs);
        groups
            .par_iter()
            .map(|g| {
                let members: Vec<&RunSpec> = g.iter().map(|&i| &runs[i]).collect();
                let kept = g.iter().map(|&i| kept.take(i)).collect();
                run_setup(
                    &members,
                    cfg,
                    out,
                    options.force,
                    overlay_frames,
                    kept,
                    events,
                )
                .map(|d| g.iter().copied().zip(d).collect::<Vec<_>>())
            })
            .collect::<Result<Vec<_>, BatchError>>()
            .map(|v| {
                // Back in the manifest's order.
                let mut all: Vec<(usize, (Entry, bool))> = v.into_iter().flatten().collect();
                all.sort_by_key(|(i, _)| *i);
                let done = all.into_iter().map(|(_, d)| d).collect();
                (done, threads)
            })
    };
    let (done, threads) = on_threads(options.threads, out, work)?;
    Ok(Processed {
        done,
        seconds: start.elapsed().as_secs_f64(),
        threads,
        review,
    })
}

/// `work` on a pool of `threads` worker threads, or on the calling one's
/// (rayon's global pool, one thread per core, unless inside another) when
/// `None` or when it has that many already: a job runs all of its work
/// there (its runs, figures, collapse and report), so that `--threads`
/// bounds all of it. `out` is the job's folder, named if the pool cannot
/// be made.
pub fn on_threads<R: Send>(
    threads: Option<usize>,
    out: &Path,
    work: impl FnOnce() -> Result<R, BatchError> + Send,
) -> Result<R, BatchError> {
    let in_pool =
        |n: usize| rayon::current_thread_index().is_some() && rayon::current_num_threads() == n;
    check_threads(threads)?;
    match threads {
        Some(n) if !in_pool(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map_err(|e| BatchError::Io {
                path: out.to_path_buf(),
                source: std::io::Error::other(e),
            })?
            .install(work),
        _ => work(),
    }
}

/// An I/O error on `path` as the job's error.
fn io(path: &Path) -> impl FnOnce(std::io::Error) -> BatchError {
    let path = path.to_path_buf();
    move |source| BatchError::Io { path, source }
}

/// Process every configured run (reusing valid cached results), then the
/// collapse of the measured ones. With `options.shard`, only that share of
/// the runs, and nothing assembled.
///
/// The output folder is held for the job ([`crate::job::lock`]): another job
/// into it is refused (or waited for), shards of this one are let in.
pub fn run_job(
    cfg: &PipelineConfig,
    config_name: &str,
    out: &Path,
    options: &JobOptions,
    events: &(dyn Fn(RunEvent) + Sync),
) -> Result<JobSummary, BatchError> {
    let runs = configured_runs(cfg, config_name)?;
    std::fs::create_dir_all(out).map_err(io(out))?;
    let me = crate::job::lock::Holder::this_process(
        &cache::job_id("run", cfg, &runs),
        options.shard.map(|s| s.to_string()),
    );
    let _held =
        crate::job::lock::acquire(out, &me, options.wait, &|m| events(RunEvent::Notice(m)))?;
    crate::util::io::remove_stale_temporaries(out, &crate::job::lock::writer_is_gone)
        .map_err(io(out))?;
    let runs = match options.shard {
        Some(shard) => crate::job::shard::select(&runs, shard, cfg.camera.infer_setups),
        None => runs,
    };
    on_threads(options.threads, out, || {
        job_on_pool(&runs, cfg, config_name, out, options, events)
    })
}

/// [`run_job`] once the folder is held and the runs chosen, on the job's
/// pool.
fn job_on_pool(
    runs: &[RunSpec],
    cfg: &PipelineConfig,
    config_name: &str,
    out: &Path,
    options: &JobOptions,
    events: &(dyn Fn(RunEvent) + Sync),
) -> Result<JobSummary, BatchError> {
    let Processed {
        done,
        seconds: process_s,
        threads,
        review,
    } = process_runs(runs, cfg, out, options, &[], events)?;
    let cached = done.iter().filter(|(_, hit)| *hit).count();
    let frames = done
        .iter()
        .filter(|(_, hit)| !*hit)
        .map(|(e, _)| e.frames)
        .sum();
    let entries: Vec<Entry> = done.into_iter().map(|(e, _)| e).collect();
    let records: Vec<DropRecord> = entries.iter().map(|e| e.record.clone()).collect();
    if options.shard.is_some() {
        return Ok(JobSummary {
            records,
            out: out.to_path_buf(),
            cached,
            frames,
            process_s,
            threads,
            collapsed: false,
            collapse_warnings: Vec::new(),
            collapse_note: None,
            shard: options.shard,
        });
    }
    timings::time(Stage::Writes, || -> Result<(), BatchError> {
        write_file(out, "drops.csv", &crate::dataset::to_csv_bytes(&records))?;
        replace_provenance(out, cfg, config_name, &entries, &review, events)
    })?;
    let collapse = timings::start(Stage::Collapse);
    let measured = records.iter().filter(|r| r.status.collapses()).count();
    // The collapse is redone from drops.csv every time: first remove what an
    // earlier job's collapse wrote, so that no figure of a run that has
    // since failed or left the manifest survives (nor all of it when no
    // drop is measured now).
    let mut ledger = crate::util::out_folder::Ledger::open(out);
    crate::job::collapse_job::remove_outputs(&mut ledger)
        .and_then(|()| ledger.save())
        .map_err(io(out))?;
    let (collapsed, collapse_warnings, collapse_note) = if measured > 0 {
        events(RunEvent::Collapsing);
        let args = CollapseOptions {
            drops: out.join("drops.csv"),
            out: Some(out.to_path_buf()),
            config: None,
            contact_radius: ContactRadius::Measured,
            bootstrap: 2000,
            seed: 20190614,
            no_plots: false,
        };
        let s = crate::job::collapse_job::run(&args, cfg, config_name)?;
        let note = s.fits.few_drops.clone();
        let warnings = s
            .warnings
            .into_iter()
            .filter(|w| note.as_ref() != Some(w))
            .collect();
        (true, warnings, note)
    } else {
        let replaced = crate::job::per_drop::replace(&mut ledger, Vec::new(), &mut Vec::new());
        ledger.save().map_err(io(out))?;
        replaced?;
        (false, Vec::new(), None)
    };
    drop(collapse);
    timings::time(Stage::Report, || {
        crate::job::report_job::write_report(out, config_name, &records)
    })?;
    Ok(JobSummary {
        records,
        out: out.to_path_buf(),
        cached,
        frames,
        process_s,
        threads,
        collapsed,
        collapse_warnings,
        collapse_note,
        shard: None,
    })
}

#[cfg(test)]
mod tests;
