//! The figures of the domain, as bytes: each drawn with the kit of
//! [`crate::plot`] from the numbers of the stage it shows. Nothing here
//! reads or writes a file: the job level writes what these return.
//!
//! | file | figures |
//! | --- | --- |
//! | [`collapse`](self::collapse_figures) | Π vs η, τc vs v (log–log), Ψ vs Ξ, Ω vs Ξ |
//! | [`drop`](self::drop_figures) | per drop: z(t), δ(t), F(δ) |
//! | [`overlay`] | one frame's detection drawn over it (edge points, circle, surface line), as PNG or one frame of an animation |
//! | [`pictures`] | a run's overlays with their captions, and its animated impact, from its track and recording |

mod collapse;
mod drop;
pub mod overlay;
pub mod pictures;

pub use collapse::{collapse_figures, FIGURE_STEMS};
pub use drop::drop_figures;
