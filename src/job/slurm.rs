//! `dropscope slurm`: the main job on a Slurm cluster — an
//! array job whose tasks are the shards (`run --shard slurm`, see
//! [`crate::job::shard`]), and a finishing job (`run`) that Slurm starts only
//! after every task succeeded (`--dependency=afterok`), which finds every
//! run in the cache and assembles drops.csv, the collapse and the report.
//!
//! Slurm is the scheduler: this module only writes the two sbatch scripts
//! and, with `--submit`, hands them to `sbatch`.

use std::path::{Path, PathBuf};
use std::process::Command;

/// What `dropscope slurm` is asked for (the command line's
/// `crate::cli::slurm::SlurmOptions`, checked).
#[derive(Debug, Clone)]
pub struct SlurmOptions {
    /// Tasks of the array: the runs are split into this many frame-balanced shares.
    pub array: u32,
    /// Slurm partition (default: the cluster's default partition).
    pub partition: Option<String>,
    /// Time limit of each task and of the finishing job, as sbatch takes it (e.g. 2:00:00).
    pub time: Option<String>,
    /// Memory of each task and of the finishing job, as sbatch takes it (e.g. 4G).
    pub mem: Option<String>,
    /// CPUs of each task; the task runs that many worker threads.
    pub cpus_per_task: u16,
    /// The configuration file (default: ./pipeline.toml, else the embedded default).
    pub config: Option<PathBuf>,
    /// Output folder (default: the configuration's output.dir); it must be
    /// on a file system every node sees.
    pub out: Option<PathBuf>,
    /// Folder for the two scripts and the jobs' logs (default: OUT.slurm beside OUT).
    pub scripts: Option<PathBuf>,
    /// Submit both jobs with sbatch and print their ids.
    pub submit: bool,
}

/// Why the scripts could not be written or submitted.
#[derive(Debug, thiserror::Error)]
pub enum SlurmError {
    /// A script or folder could not be written.
    #[error("{path}: {source}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// `sbatch` could not be started (not a Slurm node); the scripts are written.
    #[error(
        "cannot run sbatch ({0}): is this a Slurm login node? The scripts are written; \
         submit them by hand (see the command printed without --submit)"
    )]
    NoSbatch(std::io::Error),
    /// `sbatch` failed on a script, or printed no job id.
    #[error("sbatch {script} failed: {message}")]
    Sbatch {
        /// The script handed to it.
        script: PathBuf,
        /// What it printed, on its output and its error stream.
        message: String,
    },
    /// A value that would reach the scripts is outside its field's set.
    #[error("{0}")]
    Value(String),
}

/// A value of a field that reaches a script: refused unless every
/// character is in `allowed` (a sentence for the message), as `ok` says.
fn check_field(
    field: &str,
    value: &str,
    allowed: &str,
    ok: impl Fn(char) -> bool,
) -> Result<(), SlurmError> {
    match value.chars().find(|&c| !ok(c)) {
        None if !value.is_empty() => Ok(()),
        found => Err(SlurmError::Value(format!(
            "{field} {:?}: {} (a value written into the Slurm scripts may hold only {allowed})",
            crate::util::text::one_line(value),
            match found {
                Some(c) => format!(
                    "the character {:?} is not allowed",
                    crate::util::text::one_line(&c.to_string())
                ),
                None => "is empty".to_string(),
            }
        ))),
    }
}

/// The characters a path in an `#SBATCH` line may hold (sbatch splits
/// those lines at spaces and reads `%` as a pattern; a newline would end
/// the comment and start a command): letters, digits and `_ . / - + , @ : = ~`.
const SBATCH_PATH: &str =
    "letters, digits and _ . / - + , @ : = ~ (no space, quote, $, %, \\ or control character)";

fn sbatch_path_char(c: char) -> bool {
    c.is_alphanumeric() && !crate::util::text::is_format(c) || "_./-+,@:=~".contains(c)
}

/// Check every value `args` and `plan` put into the scripts: `--partition`
/// (letters, digits, `_ . , -`), `--time` (digits, `:` and `-`, or
/// UNLIMITED), `--mem` (digits with an optional K, M, G or T), the working
/// folder and the logs' folder (written into `#SBATCH` lines:
/// `SBATCH_PATH`), and the binary, configuration and output folder
/// (quoted in the command line: any character but a control or format one).
pub fn check_values(args: &SlurmOptions, plan: &Plan) -> Result<(), SlurmError> {
    if let Some(p) = &args.partition {
        check_field("--partition", p, "letters, digits and _ . , -", |c| {
            c.is_ascii_alphanumeric() || "_.,-".contains(c)
        })?;
    }
    if let Some(t) = &args.time {
        if !matches!(t.as_str(), "UNLIMITED" | "INFINITE") {
            check_field(
                "--time",
                t,
                "digits, : and - (minutes, H:MM:SS, D-HH:MM:SS) or UNLIMITED",
                |c| c.is_ascii_digit() || ":-".contains(c),
            )?;
        }
    }
    if let Some(m) = &args.mem {
        let digits = m.trim_end_matches(['K', 'M', 'G', 'T']);
        let one_unit = m.len() - digits.len() <= 1;
        check_field(
            "--mem",
            m,
            "digits and one unit K, M, G or T (e.g. 4G)",
            |c| c.is_ascii_digit() || "KMGT".contains(c),
        )?;
        if digits.is_empty() || !one_unit || !digits.bytes().all(|b| b.is_ascii_digit()) {
            return Err(SlurmError::Value(format!(
                "--mem {m:?}: not a size (a value written into the Slurm scripts may hold only \
                 digits and one unit K, M, G or T, e.g. 4G)"
            )));
        }
    }
    let logs = plan.scripts.join("logs");
    for (field, path) in [
        ("the working folder", &plan.workdir),
        ("the scripts' folder (--scripts)", &logs),
    ] {
        check_field(
            field,
            &path.to_string_lossy(),
            SBATCH_PATH,
            sbatch_path_char,
        )?;
    }
    let quoted = |c: char| !c.is_control() && !crate::util::text::is_format(c);
    let allowed = "any character but a control or format character";
    check_field(
        "the output folder",
        &plan.out.to_string_lossy(),
        allowed,
        quoted,
    )?;
    check_field(
        "the dropscope binary's path",
        &plan.exe.to_string_lossy(),
        allowed,
        quoted,
    )?;
    if let Some(c) = &plan.config {
        check_field(
            "the configuration's path",
            &c.to_string_lossy(),
            allowed,
            quoted,
        )?;
    }
    Ok(())
}

/// What to run where: absolute paths, so that the jobs do not depend on the
/// directory they start in.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// The dropscope binary the jobs run (it must be on a shared file system).
    pub exe: PathBuf,
    /// `--config` for the jobs (`None`: the embedded default).
    pub config: Option<PathBuf>,
    /// The output folder (on a file system every node sees).
    pub out: PathBuf,
    /// Where the scripts and the logs go.
    pub scripts: PathBuf,
    /// The folder the jobs start in.
    pub workdir: PathBuf,
}

/// The two scripts written.
#[derive(Debug, Clone, PartialEq)]
pub struct Scripts {
    /// The array job's script: one shard per task.
    pub array: PathBuf,
    /// The finishing job's script, started after every task succeeded.
    pub finish: PathBuf,
}

/// Job ids Slurm gave.
#[derive(Debug, Clone, PartialEq)]
pub struct Submitted {
    /// The array job's id.
    pub array_job: String,
    /// The finishing job's id.
    pub finish_job: String,
}

impl Plan {
    /// The plan for `args` from the directory `workdir`, with `out` the
    /// output folder the configuration names and `local_config` the
    /// configuration file found there when `--config` is not given.
    pub fn new(
        args: &SlurmOptions,
        workdir: &Path,
        out: &Path,
        local_config: Option<&Path>,
    ) -> std::io::Result<Plan> {
        let out = workdir.join(args.out.as_deref().unwrap_or(out));
        let scripts = match &args.scripts {
            Some(s) => workdir.join(s),
            None => {
                let mut name = out.file_name().unwrap_or_default().to_os_string();
                name.push(".slurm");
                out.with_file_name(name)
            }
        };
        Ok(Plan {
            exe: std::env::current_exe()?,
            config: args
                .config
                .as_deref()
                .or(local_config)
                .map(|c| workdir.join(c)),
            out,
            scripts,
            workdir: workdir.to_path_buf(),
        })
    }
}

/// `s` quoted for a POSIX shell (safe to paste: no character of it is
/// special inside single quotes, and [`check_values`] refused control
/// characters).
pub fn quote(s: &Path) -> String {
    format!("'{}'", s.to_string_lossy().replace('\'', r"'\''"))
}

/// The `#SBATCH` lines both jobs share.
fn resources(args: &SlurmOptions) -> String {
    let mut s = format!("#SBATCH --cpus-per-task={}\n", args.cpus_per_task);
    for (flag, value) in [
        ("partition", &args.partition),
        ("time", &args.time),
        ("mem", &args.mem),
    ] {
        if let Some(v) = value {
            s += &format!("#SBATCH --{flag}={v}\n");
        }
    }
    s
}

/// `dropscope run` with the plan's paths and `extra` arguments.
fn run_line(plan: &Plan, extra: &str) -> String {
    let config = plan
        .config
        .as_ref()
        .map(|c| format!(" --config {}", quote(c)))
        .unwrap_or_default();
    format!(
        "exec {} run{extra} --out {}{config}\n",
        quote(&plan.exe),
        quote(&plan.out)
    )
}

/// The array job's script: task K of N runs shard K/N.
pub fn array_script(args: &SlurmOptions, plan: &Plan) -> String {
    format!(
        "#!/bin/bash\n\
         # dropscope {version}: the main job's runs in {n} frame-balanced shards, one per task;\n\
         # each task commits its runs to the output folder (written by `dropscope slurm`).\n\
         #SBATCH --job-name=dropscope-shards\n\
         #SBATCH --array=0-{last}\n\
         {resources}\
         #SBATCH --chdir={workdir}\n\
         #SBATCH --output={logs}/shard-%A_%a.out\n\
         {run}",
        version = env!("CARGO_PKG_VERSION"),
        n = args.array,
        last = args.array - 1,
        resources = resources(args),
        workdir = plan.workdir.display(),
        logs = plan.scripts.join("logs").display(),
        run = run_line(plan, " --shard slurm"),
    )
}

/// The finishing job's script: the whole job, which finds every run in the
/// cache and assembles drops.csv, the collapse and the report.
pub fn finish_script(args: &SlurmOptions, plan: &Plan) -> String {
    format!(
        "#!/bin/bash\n\
         # dropscope {version}: after every task of the array succeeded, assemble drops.csv,\n\
         # the collapse and report.html (runs a shard left undone are processed here).\n\
         #SBATCH --job-name=dropscope-finish\n\
         {resources}\
         #SBATCH --chdir={workdir}\n\
         #SBATCH --output={logs}/finish-%j.out\n\
         {run}",
        version = env!("CARGO_PKG_VERSION"),
        resources = resources(args),
        workdir = plan.workdir.display(),
        logs = plan.scripts.join("logs").display(),
        run = run_line(plan, ""),
    )
}

/// Write both scripts (and the logs folder) into `plan.scripts`, once
/// every value they hold is checked ([`check_values`]).
pub fn write_scripts(args: &SlurmOptions, plan: &Plan) -> Result<Scripts, SlurmError> {
    check_values(args, plan)?;
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| SlurmError::Io { path, source }
    };
    let logs = plan.scripts.join("logs");
    std::fs::create_dir_all(&logs).map_err(io(&logs))?;
    let scripts = Scripts {
        array: plan.scripts.join("shards.sbatch"),
        finish: plan.scripts.join("finish.sbatch"),
    };
    for (path, text) in [
        (&scripts.array, array_script(args, plan)),
        (&scripts.finish, finish_script(args, plan)),
    ] {
        crate::util::io::write_atomic(path, text.as_bytes()).map_err(io(path))?;
    }
    Ok(scripts)
}

/// `sbatch --parsable [extra] script`: the job id.
fn sbatch(script: &Path, extra: &[String]) -> Result<String, SlurmError> {
    let o = Command::new("sbatch")
        .arg("--parsable")
        .args(extra)
        .arg(script)
        .output()
        .map_err(SlurmError::NoSbatch)?;
    let stdout = String::from_utf8_lossy(&o.stdout);
    // --parsable prints "id" or "id;cluster".
    let id = stdout
        .trim()
        .split(';')
        .next()
        .unwrap_or_default()
        .to_string();
    if !o.status.success() || id.is_empty() || !id.bytes().all(|b| b.is_ascii_digit()) {
        return Err(SlurmError::Sbatch {
            script: script.to_path_buf(),
            message: format!(
                "{} {}",
                stdout.trim(),
                String::from_utf8_lossy(&o.stderr).trim()
            ),
        });
    }
    Ok(id)
}

/// Submit the array job, then the finishing job depending on its success.
pub fn submit(scripts: &Scripts) -> Result<Submitted, SlurmError> {
    let array_job = sbatch(&scripts.array, &[])?;
    let finish_job = sbatch(
        &scripts.finish,
        &[format!("--dependency=afterok:{array_job}")],
    )
    .map_err(|e| match e {
        SlurmError::Sbatch { script, message } => SlurmError::Sbatch {
            script,
            message: format!(
                "{message} (array job {array_job} is submitted: `scancel {array_job}` to stop it)"
            ),
        },
        e => e,
    })?;
    Ok(Submitted {
        array_job,
        finish_job,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args() -> SlurmOptions {
        SlurmOptions {
            array: 3,
            partition: None,
            time: Some("1:00:00".into()),
            mem: None,
            cpus_per_task: 4,
            config: None,
            out: None,
            scripts: None,
            submit: false,
        }
    }

    fn plan() -> Plan {
        Plan {
            exe: "/opt/bin/dropscope".into(),
            config: Some("/data/it's here/pipeline.toml".into()),
            out: "/scratch/out".into(),
            scripts: "/scratch/out.slurm".into(),
            workdir: "/data".into(),
        }
    }

    #[test]
    fn scripts_run_the_shards_then_the_whole_job() {
        let a = array_script(&args(), &plan());
        for line in [
            "#!/bin/bash\n",
            "\n#SBATCH --array=0-2\n",
            "\n#SBATCH --cpus-per-task=4\n",
            "\n#SBATCH --time=1:00:00\n",
            "\n#SBATCH --output=/scratch/out.slurm/logs/shard-%A_%a.out\n",
            "\nexec '/opt/bin/dropscope' run --shard slurm --out '/scratch/out' \
             --config '/data/it'\\''s here/pipeline.toml'\n",
        ] {
            assert!(a.contains(line), "{line:?} not in\n{a}");
        }
        assert!(!a.contains("--partition") && !a.contains("--mem"), "{a}");
        let f = finish_script(&args(), &plan());
        assert!(
            f.ends_with("\nexec '/opt/bin/dropscope' run --out '/scratch/out' --config '/data/it'\\''s here/pipeline.toml'\n"),
            "{f}"
        );
        assert!(!f.contains("--array") && !f.contains("--shard"), "{f}");
        // The quoted path survives a real shell.
        let o = Command::new("sh")
            .arg("-c")
            .arg(format!("printf %s {}", quote(Path::new("/a/it's b"))))
            .output()
            .unwrap();
        assert_eq!(o.stdout, b"/a/it's b");
    }

    /// A newline in a value would end the `#SBATCH` comment and run the
    /// rest as a command; each field is refused with what it may hold.
    #[test]
    fn values_that_would_run_in_the_scripts_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let mut p = plan();
        p.scripts = dir.path().join("s");
        type Edit = fn(&mut SlurmOptions, &mut Plan);
        let cases: [(&str, Edit); 9] = [
            ("--partition", |a, _| {
                a.partition = Some("debug\ntouch /tmp/x".into())
            }),
            ("--partition", |a, _| a.partition = Some("a;b".into())),
            ("--time", |a, _| a.time = Some("1:00:00\nrm -rf ~".into())),
            ("--time", |a, _| a.time = Some("$(id)".into())),
            ("--mem", |a, _| a.mem = Some("4G\necho".into())),
            ("--mem", |a, _| a.mem = Some("4GG".into())),
            ("working folder", |_, p| p.workdir = "/data/a b".into()),
            ("output folder", |_, p| {
                p.out = "/res\ntouch X; echo ".into()
            }),
            ("scripts' folder", |_, p| p.scripts = "/s/%x".into()),
        ];
        for (field, edit) in cases {
            let (mut a, mut q) = (args(), p.clone());
            edit(&mut a, &mut q);
            let e = write_scripts(&a, &q).unwrap_err().to_string();
            assert!(
                e.contains(field) && e.contains("may hold only"),
                "{field}: {e}"
            );
        }
        assert!(!p.scripts.exists(), "a refused plan wrote its scripts");
        let mut a = args();
        (a.partition, a.mem, a.time) = (
            Some("gpu,cpu".into()),
            Some("512M".into()),
            Some("2-00:00:00".into()),
        );
        write_scripts(&a, &p).unwrap();
    }

    #[test]
    fn sbatch_missing_or_failing_is_a_clear_error() {
        let dir = tempfile::tempdir().unwrap();
        let mut p = plan();
        p.scripts = dir.path().join("s");
        let s = write_scripts(&args(), &p).unwrap();
        assert!(s.array.is_file() && s.finish.is_file() && p.scripts.join("logs").is_dir());
        // A script sbatch refuses (no Slurm reachable, or a bad option) names it.
        let bad = dir.path().join("none.sbatch");
        let e = sbatch(&bad, &["--no-such-option".into()])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("none.sbatch") || e.contains("cannot run sbatch"),
            "{e}"
        );
    }
}
