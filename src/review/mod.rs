//! `dropscope review`: look at every frame of a drop with what the
//! pipeline used there, and record what a person decides about it.
//!
//! | file | what |
//! | --- | --- |
//! | [`decisions`] | `review.csv`: rejected drops, excluded frames, surfaces set by hand, accepted flags — read by `process` and `run` |

pub mod decisions;
