//! Detection: from one grey frame to the sphere's circle, at sub-pixel accuracy.
//!
//! Every function here is pure: it takes frames (or views of a band of rows
//! of a frame) that are already in memory and returns numbers; nothing reads
//! files or prints. The stages, in the order a run uses them:
//!
//! | module | does |
//! | --- | --- |
//! | [`background`] | per-pixel background from the frames before the sphere, and a per-frame flicker gain |
//! | [`background_rows`] | the same from sample frames read a band of rows at a time (never all held whole) |
//! | [`background_sphere`] | the first passes of either from frames that may show the sphere: its coarse circles |
//! | [`columns`] | the columns within reach of the sphere's path that the background and the line look at |
//! | [`surface`] | the top of the pillar band as a sub-pixel line `row = row0 + slope · column` |
//! | [`coarse`] | the sphere's first appearance and a coarse circle (also when it enters through the top) |
//! | [`edges`] | sub-pixel edge points along normals to a predicted circle |
//! | [`circle`] | algebraic (hyper) start, robust geometric refinement, covariance, radius-held variant |
//! | [`calibrate`] | R_px from the full-circle frames; the scale and its check against the manifest |
//! | [`synth`] | exact anti-aliased test scenes (disk, tilted pillar band) with known truth |
//! | `types` | what the stages hand each other: [`Band`], [`EdgePoint`], [`SurfaceLine`] |
//! | `error` | [`DetectError`] |
//!
//! # Pixel convention
//!
//! The centre of pixel `(row 0, column 0)` is at `(x, z) = (0.0, 0.0)`; `x`
//! (columns) grows to the right and `z` (rows) grows downward. Pixel `(i, j)`
//! (row `i`, column `j`) covers `[j − ½, j + ½] × [i − ½, i + ½]` and its value
//! is the mean of the scene over that square. Frames are indexed
//! `frame[[row, column]]`. Every `_px` quantity in this module uses this
//! convention; a view of a band of rows carries its first row (`row0`) so
//! that coordinates stay those of the whole frame.

// `!(x > 0.0)` is meant throughout: it rejects NaN as well as non-positive values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod background;
pub mod background_rows;
pub mod background_sphere;
pub mod calibrate;
pub mod circle;
pub mod coarse;
pub mod columns;
pub mod edges;
mod error;
pub mod surface;
pub mod synth;
mod types;

pub use background::Background;
pub use circle::{fit_circle, hyper_fit, Circle, CircleFit, Covariance, FitOptions};
pub use edges::{edge_points, measure_circle, EdgeParams, EdgeScratch};
pub use error::DetectError;
pub use types::{Band, EdgePoint, SurfaceLine};
