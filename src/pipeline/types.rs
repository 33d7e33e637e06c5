//! What one run gives ([`RunOutcome`]) and why runs cannot be processed
//! ([`ProcessError`]).

use crate::calibrate::setup_infer::SceneSignature;
use crate::dataset::DropRecord;
use crate::util::io::Spool;
use std::path::PathBuf;

/// The outcome of one run.
#[derive(Debug)]
pub struct RunOutcome {
    /// The run's row of drops.csv.
    pub record: DropRecord,
    /// The track CSV's bytes (none for a run that failed): past
    /// [`TRACK_CSV_IN_MEMORY_MAX`], in a temporary file.
    pub track_csv: Spool,
    /// Its rows (one a frame of the movie).
    pub track_rows: usize,
    /// PNG bytes of the overlay at maximum penetration.
    pub overlay: Option<Vec<u8>>,
    /// Overlays of the frames asked for: (image number, PNG bytes).
    pub frame_overlays: Vec<(i64, Vec<u8>)>,
    /// The animated overlay of the impact (animated PNG bytes).
    pub impact: Option<Vec<u8>>,
    /// What the run's images say of its camera set-up (kept in the cache
    /// for `prepare`).
    pub scene: Option<SceneSignature>,
    /// Seconds spent on this run (tracking and measuring), for the speed
    /// shown to the user; no output depends on it.
    pub seconds: f64,
    /// What reading its input should say once as a warning (a colour input
    /// read as grey, frame names read one of two ways:
    /// [`crate::source::SourceMeta::reading_notes`]).
    pub notes: Vec<String>,
}

/// The most bytes of a run's track CSV held in memory (~11 000 frames'
/// rows); a longer track goes to a temporary file as it is made, and from
/// there to its output file (a 124 166-frame movie's is 11 MB).
pub const TRACK_CSV_IN_MEMORY_MAX: usize = 1 << 20;

/// Why the command could not run at all (a bad run is a row, not this).
#[derive(Debug, thiserror::Error)]
pub enum ProcessError {
    /// An output file could not be written.
    #[error("{path}: cannot write: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The command line asks for something that cannot be done; says what.
    #[error("{0}")]
    Usage(String),
    /// An INPUT named on the command line cannot be a run: it is not
    /// there, or is neither a folder nor a `.cine` file. Found before the
    /// output folder is created or touched, so a mistyped path never
    /// replaces the results already in it.
    #[error("{path}: {why}; nothing was written")]
    Input {
        /// The INPUT as given.
        path: PathBuf,
        /// Why it cannot be a run.
        why: String,
    },
}
