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
    /// What a folder of frames or a .cine holds (frames, size, fps, bit depth, gaps…).
    Inspect(dropscope::source::cli::InspectArgs),
    /// Write frames A..B−1 exactly as read, as 16-bit PNG named by frame number.
    Export(dropscope::source::cli::ExportArgs),
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

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result: anyhow::Result<ExitCode> = match cli.command {
        Command::CheckConfig { config } => load_config(config.as_deref()).map(|c| {
            println!("{c:#?}");
            ExitCode::SUCCESS
        }),
        Command::Inspect(args) => {
            dropscope::source::cli::run_inspect(&args).map(|()| ExitCode::SUCCESS)
        }
        Command::Export(args) => dropscope::source::cli::run_export(&args).map(|files| {
            eprintln!("wrote {} frame(s) to {}", files.len(), args.out.display());
            ExitCode::SUCCESS
        }),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}
