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
    /// Dimensionless groups, Ψ(Ξ) and Ω(Ξ) fits, exponents and plots from a drops.csv.
    Collapse(dropscope::collapse::CollapseArgs),
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

/// `dropscope collapse`: exit 0 when every row was used, 1 when some were skipped.
fn run_collapse(args: &dropscope::collapse::CollapseArgs) -> anyhow::Result<ExitCode> {
    let cfg = load_config(args.config.as_deref())?;
    let config_name = match &args.config {
        Some(p) => p.display().to_string(),
        None if std::path::Path::new("pipeline.toml").exists() => "./pipeline.toml".to_string(),
        None => "(embedded pipeline.toml)".to_string(),
    };
    let s = dropscope::collapse::run(args, &cfg, &config_name)?;
    for w in &s.warnings {
        eprintln!("warning: {w}");
    }
    println!(
        "collapse: {} drops used, {} skipped; {} files in {}",
        s.n_used,
        s.n_skipped,
        s.files.len(),
        s.out_dir.display()
    );
    Ok(if s.n_skipped > 0 {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result: anyhow::Result<ExitCode> = match cli.command {
        Command::CheckConfig { config } => load_config(config.as_deref()).map(|c| {
            println!("{c:#?}");
            ExitCode::SUCCESS
        }),
        Command::Collapse(args) => run_collapse(&args),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}
