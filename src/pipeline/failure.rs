//! A run that fails: its reason caught (a panic too) into its row.

use crate::dataset::manifest::RunSpec;
use std::path::Path;

/// Run `work` for `run`: its panic becomes an error naming the input.
pub(super) fn caught<T, E: From<String>>(
    run: &RunSpec,
    work: impl FnOnce() -> Result<T, E>,
) -> Result<T, E> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(work))
        .unwrap_or_else(|payload| Err(panic_reason(&run.path, payload.as_ref()).into()))
}

/// Why a run could not be tracked, with what is known of its recording
/// once it was opened.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct RunFailure {
    pub(super) reason: String,
    pub(super) recording: Option<Recording>,
}

impl From<String> for RunFailure {
    fn from(reason: String) -> Self {
        RunFailure {
            reason,
            recording: None,
        }
    }
}

/// What a run's row says of its recording, failed or not.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Recording {
    /// Its frames (the track's rows; the summary's frames read).
    pub(super) frames: usize,
    pub(super) fps: f64,
    /// The `fps_source` word ([`open_run`]).
    pub(super) fps_source: String,
}

/// The reason of a run that panicked: the panic's message, which names the
/// place in dropscope; the input is named too.
pub(super) fn panic_reason(input: &Path, payload: &(dyn std::any::Any + Send)) -> String {
    let msg = payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into());
    format!(
        "{}: internal error (a bug in dropscope, please report it with this input): {msg}",
        input.display()
    )
}
