//! `report.html` written into the output folder (`dropscope report`, and
//! the main job's last step): the page [`crate::report`] makes, written
//! whole through the folder's ledger.

use crate::dataset::DropRecord;
use crate::report::ReportError;
use crate::util::out_folder::Ledger;
use std::path::{Path, PathBuf};

/// Write `out_dir/report.html` (atomically) and return its path.
pub fn write_report(
    out_dir: &Path,
    config_name: &str,
    records: &[DropRecord],
) -> Result<PathBuf, ReportError> {
    let mut ledger = Ledger::open(out_dir);
    crate::report::check_one_dataset(out_dir)?;
    let path = out_dir.join("report.html");
    let bytes = crate::report::render_report(out_dir, config_name, records);
    ledger
        .write_as("report.html", &bytes, crate::util::io::Durable::Now)
        .and_then(|_| ledger.save())
        .map_err(|source| ReportError::Write {
            path: path.clone(),
            source,
        })?;
    Ok(path)
}
