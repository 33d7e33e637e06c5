//! One input row of the collapse and what became of it ([`DropOutcome`]).

use super::groups::{DropGroups, SkipReason};

/// One input row and what became of it.
#[derive(Debug, Clone)]
pub struct DropOutcome {
    /// Line number in drops.csv (the header is line 1).
    pub row: u64,
    pub run: String,
    pub sphere_radius_mm: f64,
    pub surface: String,
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
