//! The figures of the domain, as bytes: each drawn with the kit of
//! [`crate::plot`] from the numbers of the stage it shows. Nothing here
//! reads or writes a file: the job level writes what these return.
//!
//! | file | figures |
//! | --- | --- |
//! | [`collapse`](self::collapse_figures) | Π vs η, τc vs v (log–log), Ψ vs Ξ, Ω vs Ξ |
//! | [`drop`](self::drop_figures) | per drop: z(t), δ(t), F(δ) |

mod collapse;
mod drop;

pub use collapse::{collapse_figures, FIGURE_STEMS};
pub use drop::drop_figures;
