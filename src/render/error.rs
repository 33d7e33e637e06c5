//! Why rendering failed.

use std::path::PathBuf;

use super::{export, physics, raster};

/// Why rendering failed.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("render option `--{name}` = {value}: {allowed}")]
    Invalid {
        name: &'static str,
        value: String,
        allowed: String,
    },
    #[error("run {run}: {source}")]
    Physics {
        run: String,
        #[source]
        source: physics::PhysicsError,
    },
    #[error("run {run}: {source}")]
    Raster {
        run: String,
        #[source]
        source: raster::RasterError,
    },
    #[error(
        "run {run}: δmax = {delta_max_mm:.3} mm reaches the pillar height h = {pillar_height_mm} mm, \
         where the elastic-foundation model F = πEφRδ²/h no longer holds: lower the drop height"
    )]
    OutsideModel {
        run: String,
        delta_max_mm: f64,
        pillar_height_mm: f64,
    },
    #[error(transparent)]
    Export(#[from] export::ExportError),
    #[error("{path}: cannot create folder: {source}")]
    CreateDir {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}
