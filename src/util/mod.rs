//! The crate's leaves: small tools that every stage may use and that import
//! nothing else of the crate.
//!
//! | file | what it holds |
//! | --- | --- |
//! | [`io`] | atomic writes, `read_at`/`write_at`, paths kept inside the output folder, only regular files opened as inputs |
//! | [`records`] | a run's per-frame records of fixed size, in memory up to a budget and in a temporary file past it |
//! | [`lsq`] | weighted linear least squares with covariance, polynomial fits |
//! | [`out_folder`] | every write, read-back and removal inside the output folder: no link followed, only dropscope's own files removed |
//! | [`timings`] | `--timings`: wall and CPU time per stage of a job |
//! | [`text`] | one sanitiser for text bound for a terminal, a CSV cell or a run name; [`text::plural`] |
//! | [`console`] | printing that never panics ([`outln!`](crate::outln), [`errln!`](crate::errln)) |
//! | [`flag_values`] | command-line flag values checked as clap parses them (`--fps`, `--radius-mm`, …) |
//! | [`ranges`] | the physical range of every number where it enters |

pub mod console;
pub mod flag_values;
pub mod io;
pub mod lsq;
pub mod out_folder;
pub mod ranges;
pub mod records;
pub mod text;
pub mod timings;
