//! The records of a job: the per-drop record and `drops.csv` (SPEC §4), the
//! id of a `drops.csv`, and run names.
//!
//! | file | what it holds |
//! | --- | --- |
//! | `record.rs` | [`DropRecord`], [`TrackRow`], [`DropStatus`]; `drops.csv` as bytes, written and read ([`to_csv_bytes`], [`read_csv`]) |
//! | [`id`] | which `drops.csv` an output folder's derived files were computed from |
//! | [`run_name`] | run names that are file names, never paths |

pub mod id;
mod record;
pub mod run_name;

pub use record::{
    csv_bytes, read_csv, to_csv_bytes, write_csv, write_csv_rows, DatasetError, DropRecord,
    DropStatus, TrackRow, NO_TEXT,
};
