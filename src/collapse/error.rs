//! Why the collapse could not run.

use std::path::PathBuf;

use crate::dataset::DatasetError;

/// Why the collapse could not run.
#[derive(Debug, thiserror::Error)]
pub enum CollapseError {
    /// drops.csv could not be read.
    #[error(transparent)]
    Dataset(#[from] DatasetError),
    /// A row names a surface that the configuration does not define; the
    /// message names the file, row, run, surface, configuration and known names.
    #[error("{0}")]
    UnknownSurface(String),
    /// drops.csv holds no row.
    #[error("{path}: no drops in the file")]
    Empty {
        /// The drops.csv read.
        path: PathBuf,
    },
    /// An output file could not be written.
    #[error("{path}: cannot write: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A figure could not be drawn.
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
}
