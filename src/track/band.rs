//! A circle measured in the band of rows around a prediction, and the edge
//! points of a frame's held fit (for overlays).

use super::error::TrackError;
use super::frame::FrameTrack;
use super::settings::TrackSettings;
use super::types::Track;
use crate::detect::columns::window_columns;
use crate::detect::{
    measure_circle, Background, Band, Circle, CircleFit, EdgePoint, EdgeScratch, SurfaceLine,
};
use crate::source::{Frame, FrameSource};
use crate::util::timings::{self, Stage};
use ndarray::s;

/// Read the band of rows around `p` and measure the circle there.
#[allow(clippy::too_many_arguments)]
pub(super) fn measure_in_band(
    source: &mut dyn FrameSource,
    index: usize,
    buf: &mut Frame,
    bg: &Background,
    p: &Circle,
    surface: &SurfaceLine,
    hold: Option<f64>,
    st: &TrackSettings,
    es: &mut EdgeScratch,
) -> Result<Option<CircleFit>, TrackError> {
    let (h, w) = buf.dim();
    let reach = p.r_px + st.edge.half_window as f64 + st.band_margin_px;
    let span = |c: f64, n: usize| {
        let lo = (c - reach).floor().max(0.0) as usize;
        (lo, ((c + reach).ceil().max(0.0) as usize + 1).min(n))
    };
    let (lo, hi) = span(p.z_px, h);
    let (left, right) = span(p.x_px, w);
    if lo >= hi || left >= right {
        return Ok(None);
    }
    // The same reach in columns, and the flicker reference strips at the
    // frame's edges: only these columns are converted.
    let strip = bg.region.strip_px.min(w);
    let cols = window_columns(left..right, strip, w);
    let mut view = buf.slice_mut(s![0..hi - lo, ..]);
    timings::time(Stage::Read, || {
        source.read_window_into(index, lo, &cols, &mut view)
    })?;
    let band = match Band::window(buf.slice(s![0..hi - lo, ..]), lo, left..right) {
        Ok(b) => b,
        Err(_) => return Ok(None),
    };
    Ok(measure_circle(&band, bg, p, Some(surface), hold, &st.edge, es).ok())
}

/// The edge points of the held-radius fit of one frame (for overlays), from
/// `band`: that frame's rows, already read by the caller (whole, or the
/// columns around the circle and the flicker strips: see [`Band::window`]).
pub fn edge_points_in(
    band: &Band,
    track: &Track,
    ft: &FrameTrack,
    st: &TrackSettings,
) -> Vec<EdgePoint> {
    let Some(f) = ft.held.or(ft.free) else {
        return Vec::new();
    };
    let mut es = EdgeScratch::default();
    let fit = measure_circle(
        band,
        &track.background,
        &f.circle(),
        Some(&track.surface),
        Some(track.radius_px),
        &st.edge,
        &mut es,
    );
    if fit.is_ok() {
        es.points
    } else {
        Vec::new()
    }
}
