//! The `dropscope` binary: parse the command line, load the configuration,
//! call the library, map errors to exit codes (SPEC §6): 0 all good, 1 some
//! runs failed, 2 the command itself could not run.

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

use dropscope::config::{PipelineConfig, EMBEDDED_DEFAULT};

/// Sphere-impact high-speed recordings into physics.
#[derive(Debug, Parser)]
#[command(name = "dropscope", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Validate a pipeline.toml and print the resolved configuration.
    CheckConfig {
        /// The configuration file (default: ./pipeline.toml, else the embedded default).
        #[arg(long)]
        config: Option<PathBuf>,
    },
    /// Render synthetic drops with exact truth, as PCC-style frame folders.
    Render(Box<dropscope::render::RenderArgs>),
}

/// Load `--config FILE`, else `./pipeline.toml`, else the embedded default.
fn load_config(path: Option<&std::path::Path>) -> anyhow::Result<PipelineConfig> {
    let local = PathBuf::from("pipeline.toml");
    Ok(match path {
        Some(p) => PipelineConfig::load(p)?,
        None if local.exists() => PipelineConfig::load(&local)?,
        None => PipelineConfig::from_toml_str(
            EMBEDDED_DEFAULT,
            std::path::Path::new("(embedded pipeline.toml)"),
            std::path::Path::new(""),
        )?,
    })
}

/// `dropscope render`: render, then one summary line (with the speed) on stderr.
fn run_render(args: &dropscope::render::RenderArgs) -> anyhow::Result<ExitCode> {
    let start = std::time::Instant::now();
    let report = dropscope::render::render(args)?;
    let secs = start.elapsed().as_secs_f64();
    for (run, reason) in &report.failures {
        eprintln!("error: {reason}");
        eprintln!("  (run {run} was not rendered)");
    }
    let frames = report.frames();
    eprintln!(
        "rendered {} drops, {frames} frames into {} in {secs:.2} s ({:.0} frames/s){}",
        report.drops.len(),
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

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result: anyhow::Result<ExitCode> = match cli.command {
        Command::CheckConfig { config } => load_config(config.as_deref()).map(|c| {
            println!("{c:#?}");
            ExitCode::SUCCESS
        }),
        Command::Render(args) => run_render(&args),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}
