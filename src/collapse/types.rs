//! One input row of the collapse and what became of it ([`DropOutcome`]).

use super::groups::{DropGroups, SkipReason};

/// One input row and what became of it.
#[derive(Debug, Clone)]
pub struct DropOutcome {
    /// Line number in drops.csv (the header is line 1).
    pub row: u64,
    /// The run's name.
    pub run: String,
    /// Sphere radius R, mm.
    pub sphere_radius_mm: f64,
    /// The surface's name, as the row gives it or the configuration's default.
    pub surface: String,
    /// The drop's groups, or why it is skipped.
    pub groups: Result<DropGroups, SkipReason>,
    /// False for a `tracked` run (no contact): not a drop, left out of the
    /// collapse without being counted or listed as skipped.
    pub candidate: bool,
}

impl DropOutcome {
    /// A drop the collapse could have used and did not.
    pub fn skipped(&self) -> bool {
        self.candidate && self.groups.is_err()
    }
}
