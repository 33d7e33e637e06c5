//! Frame sequences: one trait, [`FrameSource`], that every input implements.
//!
//! Frames are grey, row-major, rows top-down (row 0 is the top of the
//! picture), held as `u16` whatever the file's container: 8-bit data keeps its
//! values 0‥255, 12-bit data its values 0‥4095. [`SourceMeta::bit_depth`] gives
//! the real number of significant bits. Readers fill a caller's buffer, so a
//! loop over a movie allocates nothing per frame, and frames are read on
//! demand in any order.

pub use colour::ColourInput;
pub use error::{SourceError, SUPPORTED_INPUTS};
pub use frame::{
    Frame, FrameNames, FrameSource, InputKind, OpenOptions, P10Mode, SourceDetails, SourceMeta,
};
pub use index::{FrameNumbers, FrameValues};
pub use open::{input_kind, input_name, open};
pub(crate) use rows::{check_band, fill_row, fill_rows, for_cols, grown};
pub use validate::{decode_limits, frame_too_large, MAX_FRAME_PIXELS};

pub mod cine;
pub mod cine_write;
pub mod colour;
mod error;
pub mod folder;
mod frame;
pub mod frame_decode;
pub mod index;
pub mod listing;
pub mod memory;
mod open;
mod p10_lut;
mod packing;
pub mod pcc_xml;
pub mod photron;
mod rows;
pub mod validate;
mod widen;
