//! Photron FASTCAM recordings: a raw `.mraw` movie and its header, the
//! `.cihx` (XML after a binary preamble) or the older `.cih` (text lines
//! `Key : Value`).
//!
//! | file | what |
//! | --- | --- |
//! | [`cih`] | the header, either kind: frame size, bits, frame rate, exposure, frame numbers |
//! | [`mraw`] | [`PhotronSource`]: the frames, read on demand into the caller's buffer |
//!
//! An MRAW is the frames back to back from byte 0, rows top-down, no
//! header of its own: 8-bit samples, 16-bit little-endian samples, or 12-bit
//! samples packed two in three bytes, most significant nibble first
//! (`p0 = b0<<4 | b1>>4`, `p1 = (b1&0xF)<<8 | b2`). The header says which,
//! and how many of the bits are significant and at which end ("effective
//! bit depth" and "side"). Frame `i` of the file is Photron's frame number
//! `startFrame + i` (numbers count from the trigger, negative before it).

pub mod cih;
pub mod mraw;

pub use mraw::PhotronSource;
