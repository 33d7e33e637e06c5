//! The runs of a job from the input paths ([`runs_from_inputs`]), and the runs
//! of one set-up ([`setups`]).

use super::types::ProcessError;
use crate::config::PipelineConfig;
use crate::dataset::manifest::RunSpec;
use std::path::{Path, PathBuf};

/// The runs named on the command line: each INPUT one run named after its
/// folder or `.cine` file ([`crate::dataset::run_name::from_input`]), with the radius
/// from `--radius-mm` or the configuration. An INPUT that is not there, or
/// is neither a folder nor a cine ([`crate::source::input_kind`]), is an
/// error ([`ProcessError::Input`]), not a run: what is inside an input is
/// the run's to find (a bad one gets a `failed` row), but a path on the
/// command line that names nothing is a mistake in the command.
pub fn runs_from_inputs(
    inputs: &[PathBuf],
    radius_mm: Option<f64>,
    cfg: &PipelineConfig,
) -> Result<Vec<RunSpec>, ProcessError> {
    let r = radius_mm
        .or(cfg.sphere.radius_m.map(|r| r * 1e3))
        .ok_or_else(|| {
            ProcessError::Usage(
                "no sphere radius: give --radius-mm, set sphere.radius_mm in pipeline.toml, or use a --manifest"
                    .into(),
            )
        })?;
    if !(r.is_finite() && r > 0.0) {
        return Err(ProcessError::Usage(format!(
            "--radius-mm {r}: must be a number greater than 0"
        )));
    }
    // Names must be unique (they name the output files): a repeated folder
    // name from another parent gets `_2`, `_3`, ….
    let mut runs: Vec<RunSpec> = Vec::with_capacity(inputs.len());
    for p in inputs {
        check_input(p)?;
        let base = crate::dataset::run_name::from_input(p);
        let mut run = base.clone();
        let mut k = 1;
        while runs.iter().any(|r| r.run == run) {
            k += 1;
            run = format!("{base}_{k}");
        }
        runs.push(RunSpec {
            run,
            path: p.clone(),
            sphere_radius_mm: r,
            drop_height_cm: None,
            fps: None,
            mm_per_px: None,
            surface: None,
            sphere_density_kg_m3: None,
            setup: None,
            review: Default::default(),
            number_digits: None,
        });
    }
    Ok(runs)
}

/// `Ok` when `path` can be a run by its kind ([`crate::source::input_kind`]),
/// else why not ([`ProcessError::Input`]).
pub(super) fn check_input(path: &Path) -> Result<(), ProcessError> {
    use crate::source::SourceError;
    let why = match crate::source::input_kind(path) {
        Ok(_) => return Ok(()),
        Err(SourceError::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => {
            "does not exist (each INPUT is a run folder, a .cine file or a folder of runs)"
                .to_string()
        }
        Err(SourceError::Io { source, .. }) => source.to_string(),
        Err(SourceError::Unsupported { reason, .. }) => reason,
        Err(e) => e.to_string(),
    };
    Err(ProcessError::Input {
        path: path.to_path_buf(),
        why,
    })
}

/// Group runs into camera set-ups: runs sharing a `setup` value, in the
/// order of their first run; a run without one alone. Returns indices.
pub fn setups(runs: &[RunSpec]) -> Vec<Vec<usize>> {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut named: Vec<(&str, usize)> = Vec::new();
    for (i, r) in runs.iter().enumerate() {
        match r.setup.as_deref() {
            Some(s) => match named.iter().find(|(n, _)| *n == s) {
                Some(&(_, g)) => groups[g].push(i),
                None => {
                    named.push((s, groups.len()));
                    groups.push(vec![i]);
                }
            },
            None => groups.push(vec![i]),
        }
    }
    groups
}
