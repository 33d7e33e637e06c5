//! The records of a job: the run manifest `runs.csv`, the per-drop record
//! and `drops.csv` (SPEC §4), a person's decisions `review.csv`, the id of a
//! `drops.csv`, and run names.
//!
//! | file | what it holds |
//! | --- | --- |
//! | `record.rs` | [`DropRecord`], [`TrackRow`], [`DropStatus`]; `drops.csv` as bytes, written and read ([`to_csv_bytes`], [`read_csv`]) |
//! | [`manifest`] | the run manifest `runs.csv`: one run a row, read, checked and written |
//! | [`decisions`] | `review.csv`: rejected drops, excluded frames, surfaces set by hand, accepted flags — read by `process` and `run`, written by `review` |
//! | [`id`] | which `drops.csv` an output folder's derived files were computed from |
//! | [`run_name`] | run names that are file names, never paths |

pub mod decisions;
pub mod id;
pub mod manifest;
mod record;
pub mod run_name;

pub use record::{
    csv_bytes, read_csv, to_csv_bytes, write_csv, write_csv_rows, DatasetError, DropRecord,
    DropStatus, TrackRow, NO_TEXT,
};
