//! The drawing kit: plain data in, SVG and PNG bytes out. Every figure is
//! drawn twice from one description, as SVG (text left to the viewer's
//! sans-serif) and as PNG (text rasterised from the embedded DejaVu Sans,
//! so no system font is needed). The figures of the domain (the collapse's,
//! a drop's) are in [`crate::figures`].
//!
//! | file | does |
//! | --- | --- |
//! | `draw` | both formats from one description, the font, tick labels, hover targets, PNG bytes |
//! | `layout` | axis ranges, log ticks, guide slopes, legend placement |
//! | [`caption`](self::with_caption) | the band under an overlay: frame, time, δ, scale bar |
//! | `marker` | the per-radius markers of Figs. 3–4 |
//! | `error` | [`PlotError`] |
//!
//! Markers follow Figs. 3–4 of Maruoka 2019: R = 3 mm blue circle, 4 mm
//! green triangle, 4.5 mm black ×, 5 mm orange diamond, 7 mm red square;
//! other radii get further colour/marker pairs in order of size.

mod caption;
mod draw;
mod error;
pub(crate) mod layout;
mod marker;

pub use caption::{caption_band, scale_bar, with_caption, Caption, CaptionBand, BAND_RGB, BAR_RGB};
pub(crate) use draw::{
    axis_tick, hover, render, render_both, tick, Backend, DrawResult, Plane, DESC_FONT,
    LEGEND_FONT, LIGHT_LINES, TICK_FONT,
};
pub use draw::{file_stem, register_fonts, rgb_png};
pub use error::PlotError;
pub use marker::{radius_style, Marker, MarkerKind};
