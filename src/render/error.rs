//! Why rendering failed.

use std::path::PathBuf;

use super::{export, physics, raster};

/// Why rendering failed.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// A render option's value is out of range or inconsistent with another.
    #[error("render option `--{name}` = {value}: {allowed}")]
    Invalid {
        /// The option's name, without the leading `--`.
        name: &'static str,
        /// The value as given.
        value: String,
        /// What is allowed instead.
        allowed: String,
    },
    /// The impact could not be simulated.
    #[error("run {run}: {source}")]
    Physics {
        /// The run being rendered.
        run: String,
        /// Why the simulation failed.
        #[source]
        source: physics::PhysicsError,
    },
    /// A frame could not be drawn.
    #[error("run {run}: {source}")]
    Raster {
        /// The run being rendered.
        run: String,
        /// Why the frame could not be drawn.
        #[source]
        source: raster::RasterError,
    },
    /// The drop would press deeper than the pillars are high, outside the contact model.
    #[error(
        "run {run}: δmax = {delta_max_mm:.3} mm reaches the pillar height h = {pillar_height_mm} mm, \
         where the elastic-foundation model F = πEφRδ²/h no longer holds: lower the drop height"
    )]
    OutsideModel {
        /// The run being rendered.
        run: String,
        /// Its maximum penetration δmax, mm.
        delta_max_mm: f64,
        /// The pillar height h, mm.
        pillar_height_mm: f64,
    },
    /// A file could not be written.
    #[error(transparent)]
    Export(#[from] export::ExportError),
    /// An output folder could not be created.
    #[error("{path}: cannot create folder: {source}")]
    CreateDir {
        /// The folder.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
}
