//! Why the collapse could not run.

use std::path::PathBuf;

use crate::dataset::DatasetError;

/// Why the collapse could not run.
#[derive(Debug, thiserror::Error)]
pub enum CollapseError {
    #[error(transparent)]
    Dataset(#[from] DatasetError),
    /// A row names a surface that the configuration does not define; the
    /// message names the file, row, run, surface, configuration and known names.
    #[error("{0}")]
    UnknownSurface(String),
    #[error("{path}: no drops in the file")]
    Empty { path: PathBuf },
    #[error("{path}: cannot write: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
}
