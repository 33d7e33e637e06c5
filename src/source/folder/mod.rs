//! Folders of numbered frames, as Phantom Camera Control exports them
//! (formats/phantom.md §12): `<prefix><number>.<ext>` with TIFF (8/16-bit,
//! any compression), PNG (8/16-bit), BMP (8-bit grey read as is) or JPEG,
//! plus PCC's XML side file for frame rate, exposure, bit depth and times.
//!
//! Naming: the number is the run of digits before the extension, negative
//! when the character before it is a `-` that is itself at the start of the
//! name or preceded by a non-alphanumeric character (`run_-00005.tif` is
//! −5, `run-00005.tif` is 5 with prefix `run-`). Numbers need not be
//! zero-padded and are sorted numerically. One sequence per folder: the
//! largest group of files sharing prefix and extension; files outside it
//! (notes, a stray `background.tif`) are ignored and listed in the warnings.
//! Missing numbers are reported as gaps; frame index `i` is the `i`-th file
//! present, and its time comes from its number, so a gap never shifts time.
//!
//! Opening reads the first frame's header only: its size and bit depth are
//! the sequence's. Every other file's header is read with its rows, and a
//! file of another size or bit depth is an error naming it and its frame
//! when it is read (probing all 6 166 files of a long movie at open took a
//! tenth of its CPU time).
//!
//! A frame file's bytes are decoded by [`crate::source::frame_decode`] (the first
//! one's header when the folder is opened, each one's header and rows on
//! each read), which says what is parsed here and what goes through the
//! `png` and `image` crates.
//!
//! | file | what |
//! | --- | --- |
//! | `names` | frame file names and the [`FrameFiles`] of a sequence |
//! | `source` | [`FolderSource`]: opening the folder, reading a frame |
//! | `side_file` | the PCC XML side file and the frame times from it |

mod names;
mod side_file;
mod source;

pub use names::{number_split, parse_frame_name, parse_frame_name_split, FrameFiles};
pub use source::FolderSource;

#[cfg(test)]
mod tests;
