//! Why a figure could not be drawn.

/// A figure that could not be drawn: its name and what went wrong.
#[derive(Debug, thiserror::Error)]
#[error("plot {name}: {message}")]
pub struct PlotError {
    pub name: String,
    pub message: String,
}
