//! The `dropscope` binary: parse the command line, load the configuration,
//! call the library, map errors to exit codes (docs/outputs.md): 0 all good, 1 some
//! runs failed, 2 the command itself could not run.

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

use dropscope::config::PipelineConfig;

/// Sphere-impact high-speed recordings into physics.
#[derive(Debug, Parser)]
#[command(
    name = "dropscope",
    version,
    about,
    long_about = None,
    args_conflicts_with_subcommands = true
)]
struct Cli {
    /// Without a subcommand: the main job (`run`) on ./pipeline.toml, with
    /// `run`'s options (`dropscope --force` is `dropscope run --force`).
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    run: dropscope::cli::run::RunArgs,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// The main job: every run of the configured manifest → process → collapse
    /// → report.html (what `dropscope` with no argument does).
    ///
    /// Each finished run is kept in OUT/runs/<run>.json and reused by later
    /// jobs while its input (size, time, sampled content), the configuration
    /// and dropscope (its version and the SHA-256 of the sources it was built
    /// from) are unchanged; `--force` reprocesses all. A job interrupted at
    /// any moment, even by kill -9, is finished by running it again.
    /// OUT/provenance.json records version, source hash, configuration and
    /// input fingerprints.
    Run(dropscope::cli::run::RunArgs),
    /// Validate a pipeline.toml and print the resolved configuration.
    CheckConfig {
        /// The configuration file (default: ./pipeline.toml, else the embedded default).
        #[arg(long, conflicts_with = "default")]
        config: Option<PathBuf>,
        /// Print the built-in default configuration as written, every key
        /// commented: a pipeline.toml to start from
        /// (`dropscope check-config --default > pipeline.toml`).
        #[arg(long)]
        default: bool,
    },
    /// What a folder of frames or a .cine holds (frames, size, fps, bit depth, gaps…).
    Inspect(dropscope::cli::inspect::InspectArgs),
    /// Write frames exactly as read, as 16-bit PNG `<input>_<index>.png`.
    ///
    /// The index counts from 0, zero-padded to the movie's last;
    /// `<input>_frames.csv` gives each file's camera number and time.
    Export(dropscope::cli::inspect::ExportArgs),
    /// Render synthetic drops with exact truth, as PCC-style frame folders.
    Render(Box<dropscope::cli::render::RenderArgs>),
    /// Dimensionless groups, Ψ(Ξ) and Ω(Ξ) fits, exponents and plots from a drops.csv.
    Collapse {
        #[command(flatten)]
        args: dropscope::cli::collapse::CollapseArgs,
        /// When another job holds the output folder, wait for it to end.
        #[arg(long)]
        wait: bool,
    },
    /// Measure drops: per-drop dataset (drops.csv), tracks and overlays.
    ///
    /// Each row's status: ok; warning (measured, with flags); tracked (the
    /// sphere was followed but never reached the surface: its track,
    /// overlay and free flight, v_last_m_s and g_fit_m_s2, no impact);
    /// failed. Each row's fps_source says where its frame rate came from
    /// (xml, cine, manifest, flag, config, default). Exit status 0 when no
    /// run failed, 1 when some did, 2 when the command could not run.
    Process {
        #[command(flatten)]
        args: dropscope::cli::process::ProcessArgs,
        /// When another job holds the output folder, wait for it to end.
        #[arg(long)]
        wait: bool,
    },
    /// Look at every frame of the drops of an output folder in a web page on
    /// this machine, and decide: reject a drop, exclude frames from every
    /// fit, set a run's surface row by hand, accept a flagged drop.
    ///
    /// Serves http://127.0.0.1:PORT/?token=… (printed; only this machine,
    /// only with the token) until Ctrl-C. Each decision is saved at once in
    /// OUT/review.csv (or the configuration's input.review); the next
    /// `dropscope run` or `process` into OUT applies them, measuring again
    /// only the runs they touch.
    Review {
        /// The output folder (default: the configuration's output.dir).
        #[arg(value_name = "OUT")]
        dir: Option<PathBuf>,
        /// The configuration file (default: ./pipeline.toml, else the embedded default).
        #[arg(long)]
        config: Option<PathBuf>,
        /// The port to listen on, on 127.0.0.1 (default: a free one).
        #[arg(long, default_value_t = 0)]
        port: u16,
    },
    /// The main job on a Slurm cluster: an sbatch array whose tasks each run a
    /// shard (`run --shard slurm`), and a finishing job (`run`) that starts
    /// once every task succeeded and assembles drops.csv, the collapse and
    /// the report. Writes both scripts; --submit also submits them.
    Slurm(dropscope::cli::slurm::SlurmArgs),
    /// Write DIR/report.html from the drops.csv, collapse files and plots in DIR.
    ///
    /// Refuses a folder whose collapse files were computed from another
    /// drops.csv than the one in it (each carries its dataset's id).
    Report {
        /// The output folder to read and write the report into (default:
        /// the configuration's output.dir).
        #[arg(value_name = "DIR")]
        dir: Option<PathBuf>,
        /// The same as DIR (kept for scripts written before DIR).
        #[arg(long, hide = true, conflicts_with = "dir")]
        out: Option<PathBuf>,
        /// The configuration file (default: ./pipeline.toml, else the embedded default).
        #[arg(long)]
        config: Option<PathBuf>,
        /// When another job holds the output folder, wait for it to end.
        #[arg(long)]
        wait: bool,
    },
}

/// Load `--config FILE`, else `./pipeline.toml`, else the embedded default;
/// with its name for messages.
fn load_config(path: Option<&std::path::Path>) -> anyhow::Result<(PipelineConfig, String)> {
    Ok(PipelineConfig::load_resolved(path)?)
}

/// Hold output folder `out` for a `kind` command (see `dropscope::job::lock`),
/// creating it; a stale lock taken over is said on stderr.
fn hold_folder(
    out: &std::path::Path,
    kind: &str,
    cfg: &PipelineConfig,
    runs: &[dropscope::dataset::manifest::RunSpec],
    wait: bool,
) -> anyhow::Result<dropscope::job::lock::FolderLock> {
    std::fs::create_dir_all(out)
        .map_err(|e| anyhow::anyhow!("{}: cannot create the output folder: {e}", out.display()))?;
    let me = dropscope::job::lock::Holder::this_process(
        &dropscope::job::cache::job_id(kind, cfg, runs),
        None,
    );
    Ok(dropscope::job::lock::acquire(out, &me, wait, &|m| {
        dropscope::errln!("{m}")
    })?)
}

/// "N runs: … measured, … reused from the cache; F frames read in T s on N threads (X frames/s)".
fn job_counts(job: &dropscope::job::batch::JobSummary) -> String {
    use dropscope::dataset::DropStatus;
    format!(
        "{}: {} measured, {} with warnings, {}{} failed{}, {} reused from the cache; {}",
        dropscope::util::text::plural(job.records.len(), "run"),
        job.count(DropStatus::Ok),
        job.count(DropStatus::Warning),
        tracked_count(job.count(DropStatus::Tracked)),
        job.failed(),
        reviewed(
            job.count(DropStatus::Accepted),
            job.count(DropStatus::Rejected)
        ),
        job.cached,
        speed(job.frames, job.process_s, job.threads),
    )
}

/// ", A accepted and R rejected in review" when a review decided any, else nothing.
fn reviewed(accepted: usize, rejected: usize) -> String {
    if accepted + rejected == 0 {
        return String::new();
    }
    format!(", {accepted} accepted and {rejected} rejected in review")
}

/// "N tracked without contact (…), " when some runs are, else nothing.
fn tracked_count(n: usize) -> String {
    if n == 0 {
        return String::new();
    }
    format!(
        "{n} tracked without contact (no impact: their tracks, overlays and free flights, \
         status `tracked`), "
    )
}

/// `dropscope run` (and `dropscope` alone): exit 1 when some runs failed.
fn run_main_job(args: &dropscope::cli::run::RunArgs) -> anyhow::Result<ExitCode> {
    dropscope::job::batch::check_threads(args.threads.map(usize::from))?;
    let (mut cfg, name) = load_config(args.config.as_deref())?;
    cfg.output.animation &= !args.no_animation;
    cfg.command_line = args.recording.values();
    if args.config.is_none() && name == dropscope::config::EMBEDDED_NAME {
        if let Some(m) = cfg.input.manifest.as_ref().filter(|m| !m.exists()) {
            anyhow::bail!(
                "no pipeline.toml in this folder and no --config: the built-in default \
                 configuration processes the sample drops of the dropscope repository \
                 ({}), which are not here. Run `dropscope` inside the repository, or save \
                 `dropscope check-config --default > pipeline.toml` here and set [input] \
                 manifest to your runs.csv (or paths to your run folders), or pass --config FILE",
                m.display()
            );
        }
    }
    let out = args.out.clone().unwrap_or_else(|| cfg.output.dir.clone());
    let env = |k: &str| std::env::var(k).ok();
    let shard = args
        .shard
        .as_deref()
        .map(|spec| dropscope::job::shard::Shard::parse(spec, &env))
        .transpose()?;
    let start = std::time::Instant::now();
    if args.timings {
        dropscope::util::timings::enable();
    }
    let progress = dropscope::job::progress::JobProgress::new();
    let options = dropscope::job::batch::JobOptions {
        force: args.force,
        threads: args
            .threads
            .map(usize::from)
            .or_else(|| dropscope::job::shard::slurm_cpus_per_task(&env)),
        shard,
        wait: args.wait,
    };
    let job = dropscope::job::batch::run_job(&cfg, &name, &out, &options, &|e| progress.event(e));
    progress.finish();
    let job = job?;
    let timings = args.timings.then(|| {
        dropscope::util::timings::table(
            job.records.len() - job.cached,
            start.elapsed().as_secs_f64(),
            job.threads,
        )
    });
    if let Some(shard) = job.shard {
        dropscope::errln!(
            "shard {shard}: {}; committed to {}. Once every shard is done, `dropscope run` on \
             that folder assembles drops.csv, the collapse and the report",
            job_counts(&job),
            out.display()
        );
        timings.iter().for_each(|t| dropscope::errln!("{t}"));
        // Failed runs are committed rows too: the shard did its work, and
        // the finishing run (started by Slurm only after every task
        // succeeded) reports them with exit status 1.
        return Ok(ExitCode::SUCCESS);
    }
    for w in dropscope::job::progress::closing_warnings(&job.records)
        .iter()
        .chain(&job.collapse_warnings)
    {
        dropscope::errln!("warning: {w}");
    }
    if let Some(note) = &job.collapse_note {
        dropscope::errln!("note: {note}");
    }
    dropscope::errln!(
        "{}; collapse {}; {:.2} s in all; results in {} (open report.html there)",
        job_counts(&job),
        if job.collapsed {
            "done"
        } else {
            "skipped (no measured drop)"
        },
        start.elapsed().as_secs_f64(),
        out.display()
    );
    timings.iter().for_each(|t| dropscope::errln!("{t}"));
    Ok(if job.failed() > 0 {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

/// `dropscope process`: every run in parallel; exit 1 when some runs failed.
fn run_process(
    args: &dropscope::cli::process::ProcessArgs,
    wait: bool,
) -> anyhow::Result<ExitCode> {
    use dropscope::dataset::DropStatus;
    let start = std::time::Instant::now();
    if args.timings {
        dropscope::util::timings::enable();
    }
    dropscope::job::batch::check_threads(args.threads.map(usize::from))?;
    let (mut cfg, name) = load_config(args.config.as_deref())?;
    cfg.output.animation &= !args.no_animation;
    cfg.camera.apply_flips &= !args.no_flips;
    cfg.camera.p10_linear &= !args.p10_codes;
    cfg.command_line = args.recording.values();
    let runs = match &args.manifest {
        Some(m) => dropscope::dataset::manifest::read_job_manifest(m)?,
        None => dropscope::pipeline::runs_from_inputs(
            &dropscope::job::batch::expand_inputs(&args.inputs),
            args.radius_mm,
            &cfg,
        )?,
    };
    let out = args.out.clone().unwrap_or_else(|| cfg.output.dir.clone());
    let _held = hold_folder(&out, "process", &cfg, &runs, wait)?;
    let options = dropscope::job::batch::JobOptions {
        force: args.force,
        threads: args.threads.map(usize::from),
        shard: None,
        wait,
    };
    let progress = dropscope::job::progress::JobProgress::new();
    let job = dropscope::job::process_job::run(
        &runs,
        &cfg,
        &name,
        &out,
        &options,
        &args.overlay_frames,
        &|e| progress.event(e),
    );
    progress.finish();
    let job = job?;
    for w in dropscope::job::progress::closing_warnings(&job.records)
        .iter()
        .chain(&job.warnings)
    {
        dropscope::errln!("warning: {w}");
    }
    let failed = job.count(DropStatus::Failed);
    dropscope::errln!(
        "{}: {} measured, {} with warnings, {}{} failed{}, {} reused from the cache; {}; \
         results in {}",
        dropscope::util::text::plural(job.records.len(), "run"),
        job.count(DropStatus::Ok),
        job.count(DropStatus::Warning),
        tracked_count(job.count(DropStatus::Tracked)),
        failed,
        reviewed(
            job.count(DropStatus::Accepted),
            job.count(DropStatus::Rejected)
        ),
        job.cached,
        speed(job.frames, job.process_s, job.threads),
        out.display()
    );
    if args.timings {
        dropscope::errln!(
            "{}",
            dropscope::util::timings::table(
                job.records.len() - job.cached,
                start.elapsed().as_secs_f64(),
                job.threads
            )
        );
    }
    Ok(if failed > 0 {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

/// "F frames read in T s on N threads (X frames/s)", T the processing's
/// wall time (not the collapse's or the report's); "no frames read" when
/// every run came from the cache.
fn speed(frames: usize, secs: f64, threads: usize) -> String {
    if frames == 0 {
        return "no frames read".into();
    }
    format!(
        "{frames} frames read in {secs:.2} s on {} ({:.0} frames/s)",
        dropscope::util::text::plural(threads, "thread"),
        frames as f64 / secs.max(1e-9)
    )
}

/// `dropscope collapse`: groups, fits and plots; exit 1 when rows were skipped.
fn run_collapse(
    args: &dropscope::job::collapse_job::CollapseOptions,
    wait: bool,
) -> anyhow::Result<ExitCode> {
    let (cfg, name) = load_config(args.config.as_deref())?;
    let _held = hold_folder(&args.out_dir(), "collapse", &cfg, &[], wait)?;
    let s = dropscope::job::collapse_job::run(args, &cfg, &name)?;
    for w in &s.warnings {
        match &s.fits.few_drops {
            Some(note) if note == w => dropscope::errln!("note: {w}"),
            _ => dropscope::errln!("warning: {w}"),
        }
    }
    say(format_args!(
        "collapse: {} used, {} skipped{}; {} files in {}\n",
        dropscope::util::text::plural(s.n_used, "drop"),
        s.n_skipped,
        if s.n_rejected > 0 {
            format!(", {} rejected in review", s.n_rejected)
        } else {
            String::new()
        },
        s.files.len(),
        s.out_dir.display()
    ))?;
    Ok(if s.n_skipped > 0 {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

/// `dropscope render`: render, then one summary line (with the speed) on stderr.
fn run_render(args: &dropscope::render::RenderOptions) -> anyhow::Result<ExitCode> {
    let start = std::time::Instant::now();
    let report = dropscope::render::render_with_progress(args, &mut |done, total, run| {
        dropscope::errln!("[{}/{total}] {run}", done + 1);
    })?;
    let secs = start.elapsed().as_secs_f64();
    for (run, reason) in &report.failures {
        dropscope::errln!("error: {reason}");
        dropscope::errln!("  (run {run} was not rendered)");
    }
    let frames = report.frames();
    dropscope::errln!(
        "rendered {}, {frames} frames into {} in {secs:.2} s ({:.0} frames/s){}",
        dropscope::util::text::plural(report.drops.len(), "drop"),
        args.out.display(),
        frames as f64 / secs.max(1e-9),
        report
            .manifest
            .as_ref()
            .map(|m| format!("; manifest {}", m.display()))
            .unwrap_or_default()
    );
    Ok(if report.failures.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// `dropscope report`: report.html from what the main job left in a folder.
fn run_report(
    out: Option<PathBuf>,
    config: Option<PathBuf>,
    wait: bool,
) -> anyhow::Result<ExitCode> {
    let (cfg, name) = load_config(config.as_deref())?;
    let out = out.unwrap_or_else(|| cfg.output.dir.clone());
    // A folder that is not there has nothing to hold; the report says what is missing.
    let _held = if out.is_dir() {
        Some(hold_folder(&out, "report", &cfg, &[], wait)?)
    } else {
        None
    };
    let records = dropscope::dataset::read_csv(&out.join("drops.csv"))?;
    let path = dropscope::job::report_job::write_report(&out, &name, &records)?;
    say(format_args!("report: {}\n", path.display()))?;
    Ok(ExitCode::SUCCESS)
}

/// `dropscope export`: the frames, and a warning when their times are at a
/// frame rate the input does not hold and `--fps` did not give (the
/// configuration's camera.fps).
fn run_export(args: &dropscope::cli::inspect::ExportArgs) -> anyhow::Result<ExitCode> {
    let files = dropscope::cli::inspect::run_export(args)?;
    dropscope::errln!("wrote {} frame(s) to {}", files.len(), args.out.display());
    if args.source.fps.is_none() {
        // Opened again (headers only) to learn where its frame rate came from.
        if let (src, Some(origin)) = args.source.open_source(&args.input)? {
            dropscope::errln!(
                "warning: {} holds no frame rate: the time_s of {}_frames.csv are at {} \
                 frames/s, from {origin}, an assumed value; pass --fps if that is not this \
                 recording's",
                args.input.display(),
                dropscope::source::input_name(&args.input),
                src.meta().fps
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// `dropscope review`: serve the review page of an output folder until Ctrl-C.
fn run_review(
    dir: Option<PathBuf>,
    config: Option<&std::path::Path>,
    port: u16,
) -> anyhow::Result<ExitCode> {
    use dropscope::dataset::decisions;
    use dropscope::review::server;
    let (cfg, name) = load_config(config)?;
    let out = dir.unwrap_or_else(|| cfg.output.dir.clone());
    let drops = out.join("drops.csv");
    if !drops.is_file() {
        anyhow::bail!(
            "{}: no drops.csv there: `dropscope review` looks at the output folder of \
             `dropscope run` or `dropscope process`; run one of them first",
            out.display()
        );
    }
    let review_rel = decisions::review_rel(cfg.input.review.as_deref(), &out)?;
    let review_file = out.join(&review_rel);
    // Read now: a decisions file that cannot be read is said before the page opens.
    decisions::Decisions::read_in(&out, &review_rel)?;
    let me = dropscope::job::lock::Holder::this_process("dropscope review", None);
    let _held = match dropscope::job::lock::acquire_in(&out, REVIEW_LOCK, &me, false, &|m| {
        dropscope::errln!("{m}")
    }) {
        Ok(l) => l,
        Err(dropscope::job::lock::LockError::Busy { holder, ticket, .. }) => anyhow::bail!(
            "{} is already open for review (pid {} on host {}: `{}`): use the address it \
             printed, or stop it with Ctrl-C first. If that process is gone (another \
             machine), remove {} and try again",
            out.display(),
            holder.pid,
            holder.host,
            holder.command,
            ticket.display()
        ),
        Err(e) => return Err(e.into()),
    };
    // The manifest's frame numbering, where it gives one (a configuration
    // whose runs cannot be listed now only loses that).
    let number_digits = dropscope::job::batch::configured_runs(&cfg, &name)
        .unwrap_or_default()
        .into_iter()
        .filter_map(|r| Some((r.run, r.number_digits?)))
        .collect();
    let srv = server::Server::bind(server::ServeOptions {
        out: out.clone(),
        review_rel,
        cfg,
        port,
        number_digits,
    })?;
    let stop = server::stop_on_signals();
    say(format_args!(
        "review of {}: open {}\n",
        out.display(),
        srv.url()
    ))?;
    // The rest on stderr: stdout is the address alone, for a script that
    // reads one line and closes the pipe.
    dropscope::errln!(
        "(this machine only; decisions are saved at once in {}; Ctrl-C stops)",
        review_file.display()
    );
    srv.serve(stop)?;
    dropscope::errln!(
        "review stopped; the decisions are in {}: `dropscope run` (or `process`) into {} \
         applies them",
        review_file.display(),
        out.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// The lock `dropscope review` holds in its output folder (see [`dropscope::job::lock::acquire_in`]).
const REVIEW_LOCK: &str = ".dropscope.review.lock";

/// `dropscope check-config`: validate, check that the manifest it names is
/// there, and print the configuration resolved. The built-in default's
/// manifest (the repository's sample drops) is missing wherever dropscope
/// runs outside its checkout, where printing it is still what the command
/// is asked for: for it, a warning on stderr (the main job has its own
/// advice for that case).
fn run_check_config(config: Option<&std::path::Path>) -> anyhow::Result<ExitCode> {
    let (cfg, name) = load_config(config)?;
    if let Err(e) = cfg.check_manifest(&name) {
        if name != dropscope::config::EMBEDDED_NAME {
            return Err(e.into());
        }
        dropscope::errln!(
            "warning: {e}; this built-in default names the sample drops of the dropscope \
             repository: to start your own, `dropscope check-config --default > pipeline.toml` \
             and set [input] manifest to your runs.csv"
        );
    }
    say(format_args!(
        "# {name}: valid; resolved (paths as dropscope will use them):\n{}",
        cfg.to_toml()
    ))?;
    Ok(ExitCode::SUCCESS)
}

/// `dropscope slurm`: write the scripts, and with --submit submit them.
fn run_slurm(args: &dropscope::cli::slurm::SlurmArgs) -> anyhow::Result<ExitCode> {
    use dropscope::job::slurm;
    let args = &args.options();
    let (cfg, name) = load_config(args.config.as_deref())?;
    // The jobs would fail on a configuration naming no runs: say it now.
    let runs = dropscope::job::batch::configured_runs(&cfg, &name)?;
    let local = std::path::Path::new("pipeline.toml");
    let plan = slurm::Plan::new(
        args,
        &std::env::current_dir()?,
        &cfg.output.dir,
        local.exists().then_some(local),
    )?;
    let scripts = slurm::write_scripts(args, &plan)?;
    say(format_args!(
        "{} runs in {} shards into {}; scripts {} and {}, logs in {}\n",
        runs.len(),
        args.array,
        plan.out.display(),
        scripts.array.display(),
        scripts.finish.display(),
        plan.scripts.join("logs").display()
    ))?;
    if !args.submit {
        say(format_args!(
            "submit with: jid=$(sbatch --parsable {}) && sbatch --dependency=afterok:$jid {}\n",
            slurm::quote(&scripts.array),
            slurm::quote(&scripts.finish)
        ))?;
        return Ok(ExitCode::SUCCESS);
    }
    let ids = slurm::submit(&scripts)?;
    say(format_args!(
        "array job {} ({} tasks)\nfinishing job {} (starts when every task of {} has \
         succeeded; then {} holds report.html)\n",
        ids.array_job,
        args.array,
        ids.finish_job,
        ids.array_job,
        plan.out.display()
    ))?;
    Ok(ExitCode::SUCCESS)
}

/// Stdout could not take all that was written (its reader closed it,
/// `dropscope inspect X | head -1`, or `>/dev/full`): no error, the command
/// stops there with exit status 0.
#[derive(Debug, thiserror::Error)]
#[error("stdout was closed by its reader")]
struct StdoutClosed;

/// Write `text` to stdout, made safe for a terminal
/// ([`dropscope::util::text::terminal`]). A closed pipe is [`StdoutClosed`], not
/// the panic of `print!`.
fn say(text: impl std::fmt::Display) -> anyhow::Result<()> {
    use std::io::Write;
    let text = text.to_string();
    let text = dropscope::util::text::terminal(&text);
    let mut out = std::io::stdout().lock();
    match write!(out, "{text}").and_then(|()| out.flush()) {
        // A closed pipe, a full disk: what could be written was; the
        // command stops there (exit 0), as console::out drops the rest.
        Err(_) => Err(StdoutClosed.into()),
        Ok(()) => Ok(()),
    }
}

/// An error and its causes on one line, each cause only when the text so
/// far does not already say it (our errors often print their source
/// themselves: "file: No such file or directory" once, not twice).
fn error_text(e: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let c = cause.to_string();
        if text.is_empty() {
            text = c;
        } else if !text.contains(&c) {
            text = format!("{text}: {c}");
        }
    }
    text
}

/// Blocks of 1 MiB and more (a long movie's track, kept edge points, the
/// figures' pixels) get their own mapping, returned to the system when
/// freed. glibc's default threshold rises as large blocks are freed, after
/// which they come from its heaps and their pages stay resident: a
/// 62 166-frame movie peaks at 56–62 MB instead of 49 without this.
/// Smaller blocks, frames at 512 × 384 among them, stay in the
/// heaps and are reused (at 128 kB the campaign's system time doubled).
fn map_large_blocks() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets a parameter of the allocator; called first
    // thing in main, before any other thread exists.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 1 << 20);
    }
}

fn main() -> ExitCode {
    map_large_blocks();
    let cli = Cli::parse();
    let command = cli.command.unwrap_or(Command::Run(cli.run));
    let result: anyhow::Result<ExitCode> = match command {
        Command::Run(args) => run_main_job(&args),
        Command::CheckConfig {
            default: true,
            config: _,
        } => say(dropscope::config::EMBEDDED_DEFAULT).map(|()| ExitCode::SUCCESS),
        Command::CheckConfig {
            config,
            default: false,
        } => run_check_config(config.as_deref()),
        Command::Inspect(args) => {
            dropscope::cli::inspect::run_inspect(&args).map(|()| ExitCode::SUCCESS)
        }
        Command::Export(args) => run_export(&args),
        Command::Render(args) => run_render(&args.options()),
        Command::Collapse { args, wait } => run_collapse(&args.options(), wait),
        Command::Process { args, wait } => run_process(&args, wait),
        Command::Report {
            dir,
            out,
            config,
            wait,
        } => run_report(dir.or(out), config, wait),
        Command::Slurm(args) => run_slurm(&args),
        Command::Review { dir, config, port } => run_review(dir, config.as_deref(), port),
    };
    match result {
        Ok(code) => code,
        // The reader of stdout has gone (`dropscope inspect X | head -1`):
        // what it wanted was written.
        Err(e) if e.is::<StdoutClosed>() => ExitCode::SUCCESS,
        Err(e) => {
            dropscope::errln!("error: {}", error_text(&e));
            ExitCode::from(2)
        }
    }
}
