//! Why a figure could not be drawn.

/// A figure that could not be drawn: its name and what went wrong.
#[derive(Debug, thiserror::Error)]
#[error("plot {name}: {message}")]
pub struct PlotError {
    /// The figure's name.
    pub name: String,
    /// What went wrong.
    pub message: String,
}
