//! The collapse stage (SPEC §3): drops.csv → the dimensionless
//! groups of every drop and the scaling fits.
//!
//! | file | does |
//! | --- | --- |
//! | [`groups`] | Π, ξ, η, κ, ω, Ψ, Ξ, Ω (and Π', κ') per drop with first-order errors |
//! | [`fit`] | local exponents per radius, Ψ(Ξ) and Ω(Ξ) series, fixed-exponent asymptotes, crossover, bootstrap |
//! | [`stats`] | weighted least squares, quantiles, Γ and B |
//! | [`diagnostics`] | per-drop flight parabolas and F = K δⁿ from `tracks/<run>.csv` |
//! | [`output`] | `collapse.csv` and `fits.json` as bytes |
//! | [`synthetic`] | drops with known laws (Eq. (8), pure power laws) for tests |
//! | `types` | [`DropOutcome`]: one input row and what became of it |
//! | `error` | [`CollapseError`] |
//!
//! The whole `dropscope collapse` command, which reads drops.csv and writes
//! `collapse.csv`, `fits.json` and the figures into the output folder, is
//! [`crate::job::collapse_job::run`]; the per-drop figures are
//! [`crate::job::per_drop`]'s.

pub mod diagnostics;
mod error;
pub mod fit;
pub mod groups;
pub mod output;
pub mod stats;
pub mod synthetic;
mod types;

pub use error::CollapseError;
pub use types::DropOutcome;

use std::path::Path;

use crate::config::PipelineConfig;
use crate::dataset;
use groups::ContactRadius;

/// Compute the groups of every record (hard error only for an unknown surface).
pub fn compute_groups(
    path: &Path,
    records: &[dataset::DropRecord],
    cfg: &PipelineConfig,
    config_name: &str,
    choice: ContactRadius,
) -> Result<Vec<DropOutcome>, CollapseError> {
    let mut outcomes = Vec::with_capacity(records.len());
    for (i, rec) in records.iter().enumerate() {
        let row = i as u64 + 2;
        let name = if rec.surface.is_empty() {
            cfg.input.surface.clone()
        } else {
            rec.surface.clone()
        };
        let Some(surface) = cfg.surfaces.get(&name) else {
            let known = cfg.surfaces.keys().cloned().collect::<Vec<_>>().join(", ");
            return Err(CollapseError::UnknownSurface(format!(
                "{}: row {row} (run `{}`): surface \"{name}\" is not a [surface.<name>] table \
                 of the configuration {config_name} (known: {known}); add the table or fix the \
                 `surface` column",
                path.display(),
                rec.run
            )));
        };
        outcomes.push(DropOutcome {
            row,
            run: rec.run.clone(),
            sphere_radius_mm: rec.sphere_radius_mm,
            surface: name.clone(),
            groups: groups::compute(rec, &name, surface, choice),
            candidate: rec.status != crate::dataset::DropStatus::Tracked,
        });
    }
    Ok(outcomes)
}
