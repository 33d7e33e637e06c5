//! Raw Phantom `.cine` files (formats/phantom.md, decisions in §0).
//!
//! Layout: `CINEFILEHEADER` (44 B at 0) → `BITMAPINFOHEADER` at
//! `OffImageHeader` → `SETUP` at `OffSetup` (only its first `SETUP.Length`
//! bytes exist; later fields fall back, §4.3) → tagged blocks from
//! `OffSetup + Length` to `OffImageOffsets` (1002 time stamps, 1003
//! exposures) → `ImageCount` × int64 absolute image offsets → per image
//! `u32 AnnotationSize`, annotation, `u32 ImageSize`, pixels.
//!
//! Pixels: 8-bit and 16-bit (LE, LSB-aligned) rows are stored **bottom-up**;
//! packed P10 (biCompression 256) and P12L (1024) rows **top-down**. Frames
//! are returned top-down in storage orientation; the viewer flips `bFlipV` /
//! `bFlipH` are reported in `SourceMeta::details` and applied only with
//! `OpenOptions::apply_flips`. P10 codes are raw unless
//! `OpenOptions::p10` asks for the linearisation table.
//!
//! Every size and count is checked against the file length before anything
//! is allocated; all seeks are 64-bit, so files over 4 GB work.
//!
//! | file | what |
//! | --- | --- |
//! | `header` | [`CineHeader`], [`CineStorage`], [`CineLayout`]: what the header region says |
//! | `layout` | [`parse_layout_at`]: reading and checking the header region |
//! | `read` | [`CineSource`]: frames read on demand |

mod header;
mod layout;
mod read;

pub use header::{has_cine_magic, CineHeader, CineLayout, CineStorage};
pub use layout::{header_region_len, parse_layout, parse_layout_at, ReadAt};
pub use read::CineSource;

#[cfg(test)]
mod tests;
