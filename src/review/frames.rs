//! One frame of a run as the review page shows it: read from the run's
//! source when asked for, drawn with what the pipeline used there — the
//! edge points the circle fit kept (green) and those it rejected (orange),
//! the fitted circle (red), the surface line used (blue; the image's own
//! line dashed cyan where another was used), and the window of rows and
//! columns pass 1 reads around its prediction from the three frames
//! before (dashed yellow) — with the caption band of the overlays (frame,
//! time, δ, scale bar). An excluded frame has a magenta border.
//!
//! The edge points are measured again on the frame as the overlays of
//! `process` are ([`crate::track::edge_points_in`]): around the track's
//! circle with its radius held, against the run's background, the fit's
//! final weights telling the used from the rejected.

use image::RgbImage;

use crate::config::PipelineConfig;
use crate::dataset::TrackRow;
use crate::detect::{
    measure_circle, Background, Band, Circle, EdgePoint, EdgeScratch, SurfaceLine,
};
use crate::figures::overlay::{OverlayView, Scene};
use crate::source::{Frame, FrameSource, OpenOptions, SourceMeta};
use crate::track::TrackSettings;

/// Rejected edge points.
pub const REJECTED_RGB: [u8; 3] = [255, 150, 0];
/// The predicted window of pass 1.
pub const WINDOW_RGB: [u8; 3] = [255, 230, 0];
/// The image's own surface line, where another is used.
pub const IMAGE_SURFACE_RGB: [u8; 3] = [0, 220, 220];
/// The border of an excluded frame.
pub const EXCLUDED_RGB: [u8; 3] = [230, 0, 230];

/// Rows read beyond the predicted circle on each side besides the edge
/// window, as the tracker does ([`TrackSettings::band_margin_px`]).
fn band_margin_px(st: &TrackSettings) -> f64 {
    st.band_margin_px
}

/// How much of the frame to show.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum View {
    /// The sphere and a margin, enlarged 2×.
    Sphere,
    /// The contact: where the outline meets the surface line, both
    /// corners, enlarged up to 8×.
    Contact,
    /// The whole frame at 1×.
    Frame,
}

impl View {
    /// The view a word names (`sphere`, `contact`, `frame`).
    pub fn from_word(w: &str) -> Option<View> {
        match w {
            "sphere" => Some(View::Sphere),
            "contact" => Some(View::Contact),
            "frame" => Some(View::Frame),
            _ => None,
        }
    }
}

/// A run opened for drawing its frames.
pub struct RunView {
    source: Box<dyn FrameSource>,
    /// What the run's recording holds: size, frames, rate.
    pub meta: SourceMeta,
    settings: TrackSettings,
    /// The background and the image's surface line, or why there are none.
    found: Result<(Background, SurfaceLine), String>,
    /// The surface line the measurement used (drops.csv's row at the
    /// impact column, with the image's tilt).
    pub used_surface: Option<SurfaceLine>,
    /// Every camera image number, in order.
    pub frames: Vec<i64>,
    mm_per_px: Option<f64>,
}

impl RunView {
    /// Open `path` (a run's input) under `cfg` read as `options` say (as
    /// the job read it: [`crate::pipeline::settings::open_options`]), and find its
    /// background and surface line as the tracker does;
    /// `used_row_at_impact` and `impact_column_px` place the line the
    /// measurement used.
    pub fn open(
        path: &std::path::Path,
        cfg: &PipelineConfig,
        options: &OpenOptions,
        used_row_at_impact: Option<f64>,
        impact_column_px: Option<f64>,
        mm_per_px: Option<f64>,
    ) -> Result<RunView, String> {
        let mut source = crate::source::open(path, options).map_err(|e| e.to_string())?;
        let meta = source.meta().clone();
        let settings = TrackSettings::from_config(&cfg.detect_settings());
        let found = crate::track::background_and_surface(source.as_mut(), &settings)
            .map(|(bg, line, _)| (bg, line))
            .map_err(|e| format!("{}: {e}", path.display()));
        let used_surface = match (&found, used_row_at_impact) {
            (Ok((_, line)), Some(row)) => {
                let x = impact_column_px.unwrap_or(0.5 * meta.width as f64);
                Some(SurfaceLine::given(row - line.slope * x, line.slope))
            }
            (Err(_), Some(row)) => Some(SurfaceLine::given(row, 0.0)),
            _ => None,
        };
        let frames = meta.frame_numbers.iter().collect();
        Ok(RunView {
            source,
            meta,
            settings,
            found,
            used_surface,
            frames,
            mm_per_px,
        })
    }

    /// The image's surface line (row at column 0, tilt), when found.
    pub fn image_surface(&self) -> Option<(f64, f64)> {
        self.found.as_ref().ok().map(|(_, l)| (l.row0_px, l.slope))
    }

    /// Why frames show no edge points, when they cannot.
    pub fn problem(&self) -> Option<String> {
        self.found.as_ref().err().cloned()
    }

    /// The index of camera image `frame`.
    pub fn index_of(&self, frame: i64) -> Option<usize> {
        self.frames.binary_search(&frame).ok()
    }

    /// Frame `frame` drawn in `view` (see the module doc) as PNG bytes, with
    /// the part of the frame shown (`x0`, `z0`, enlargement): `row` is its
    /// row of the track CSV, `before` the rows of the frames before it
    /// (for the prediction), `excluded` whether a person excluded it.
    pub fn draw(
        &mut self,
        frame: i64,
        row: Option<&TrackRow>,
        before: &[&TrackRow],
        excluded: bool,
        view: View,
    ) -> Result<(Vec<u8>, OverlayView), String> {
        let index = self
            .index_of(frame)
            .ok_or_else(|| format!("frame {frame} is not in this run"))?;
        let mut pixels = Frame::zeros((self.meta.height, self.meta.width));
        self.source
            .read_into(index, &mut pixels)
            .map_err(|e| e.to_string())?;
        let band = Band::frame(&pixels).map_err(|e| e.to_string())?;
        let circle = row.and_then(circle_of);
        let (used, rejected) = match (&self.found, circle) {
            (Ok((bg, line)), Some(c)) => edge_points(&band, bg, line, &c, &self.settings),
            _ => (Vec::new(), Vec::new()),
        };
        let image_line = self.found.as_ref().ok().map(|(_, l)| *l);
        let shown_line = self.used_surface.or(image_line);
        let overlay_view = self.view(&band, circle.as_ref(), shown_line.as_ref(), view);
        let scene = Scene {
            band: &band,
            bit_depth: self.meta.bit_depth,
            view: &overlay_view,
            points: &used,
            circle: circle.as_ref(),
            surface: shown_line.as_ref(),
        };
        let mut img = scene.rgb();
        let marks = Marks {
            view: &overlay_view,
        };
        for p in &rejected {
            marks.cross(&mut img, p.x_px, p.z_px, REJECTED_RGB);
        }
        if let (Some(a), Some(b)) = (image_line, self.used_surface) {
            if (a.row_at(band.width as f64 / 2.0) - b.row_at(band.width as f64 / 2.0)).abs() > 0.05
            {
                marks.dashed_line(&mut img, &a, IMAGE_SURFACE_RGB);
            }
        }
        if let Some((rows, cols)) = predicted_window(before, row, &self.settings) {
            marks.dashed_rect(&mut img, rows, cols, WINDOW_RGB);
        }
        if excluded {
            border(&mut img, EXCLUDED_RGB, 3);
        }
        let img = match (row, self.mm_per_px) {
            (Some(r), Some(s)) => crate::plot::with_caption(
                &img,
                &crate::plot::Caption {
                    frame,
                    t_s: r.t_s,
                    delta_mm: r.delta_mm,
                    mm_per_px: s,
                    zoom: overlay_view.zoom,
                },
            )
            .unwrap_or(img),
            _ => img,
        };
        let png = crate::figures::overlay::encode_png(&img).map_err(|e| e.to_string())?;
        Ok((png, overlay_view))
    }

    /// The part of the frame `view` shows.
    fn view(
        &self,
        band: &Band,
        circle: Option<&Circle>,
        line: Option<&SurfaceLine>,
        view: View,
    ) -> OverlayView {
        let whole = OverlayView::whole(band);
        match (view, circle) {
            (View::Frame, _) | (_, None) => whole,
            (View::Sphere, Some(c)) => {
                // Room for the predicted window around the circle.
                let margin =
                    self.settings.edge.half_window as f64 + band_margin_px(&self.settings) + 4.0;
                OverlayView::around(band, c, margin, 2)
            }
            (View::Contact, Some(c)) => {
                // Where the outline meets the surface line: both corners of
                // the contact (±a about the centre), the line, and the arc
                // just above it, where the edge points end.
                let (w, h) = (band.width as f64, band.nrows as f64);
                let line_row = line.map_or(c.z_px + c.r_px, |l| l.row_at(c.x_px));
                let d = line_row - c.z_px;
                let a = if d.abs() < c.r_px {
                    (c.r_px * c.r_px - d * d).sqrt()
                } else {
                    0.0
                };
                let half_w = (1.15 * a).max(0.4 * c.r_px).max(12.0);
                let (above, below) = ((0.35 * c.r_px).max(10.0), (0.08 * c.r_px).max(4.0));
                let x0 = (c.x_px - half_w).clamp(0.0, (w - 1.0).max(0.0)) as usize;
                let z0 = (line_row - above).clamp(0.0, (h - 1.0).max(0.0)) as usize;
                let width = ((2.0 * half_w).ceil() as usize).clamp(1, band.width - x0);
                let height = ((above + below).ceil() as usize).clamp(1, band.nrows - z0);
                let zoom = (640 / width.max(1)).clamp(2, 8) as u32;
                OverlayView {
                    x0,
                    z0,
                    width,
                    height,
                    zoom,
                }
            }
        }
    }
}

/// A row's circle (held fit, else free), when it has one.
fn circle_of(r: &TrackRow) -> Option<Circle> {
    match (r.x_px, r.z_px, r.r_px) {
        (Some(x_px), Some(z_px), Some(r_px)) if r_px > 0.0 => Some(Circle { x_px, z_px, r_px }),
        _ => None,
    }
}

/// The edge points around `c` (radius held), split into those the fit
/// used and those it rejected (final weight 0).
fn edge_points(
    band: &Band,
    bg: &Background,
    line: &SurfaceLine,
    c: &Circle,
    st: &TrackSettings,
) -> (Vec<EdgePoint>, Vec<EdgePoint>) {
    let mut es = EdgeScratch::default();
    if measure_circle(band, bg, c, Some(line), Some(c.r_px), &st.edge, &mut es).is_err() {
        return (Vec::new(), Vec::new());
    }
    let weights = &es.fit.weights;
    let (mut used, mut rejected) = (Vec::new(), Vec::new());
    for (i, p) in es.points.iter().enumerate() {
        if weights.get(i).is_some_and(|&w| w > 0.0) {
            used.push(*p);
        } else {
            rejected.push(*p);
        }
    }
    (used, rejected)
}

/// The rows and columns pass 1 reads around its prediction from the three
/// fits before `row` ([`crate::track::predict`]): the predicted circle
/// plus the edge window and the band margin each side. `None` without three
/// fitted frames right before.
fn predicted_window(
    before: &[&TrackRow],
    row: Option<&TrackRow>,
    st: &TrackSettings,
) -> Option<((f64, f64), (f64, f64))> {
    let row = row?;
    if before.len() < 3 {
        return None;
    }
    let history: Vec<(f64, Circle)> = before[before.len() - 3..]
        .iter()
        .map(|r| circle_of(r).map(|c| (r.t_s, c)))
        .collect::<Option<_>>()?;
    let p = crate::track::predict(&history, row.t_s);
    let reach = p.r_px + st.edge.half_window as f64 + band_margin_px(st);
    Some((
        (p.z_px - reach, p.z_px + reach),
        (p.x_px - reach, p.x_px + reach),
    ))
}

/// Drawing over an overlay in frame coordinates (the overlay's mapping:
/// frame point `(x, z)` at `((x − x0 + ½)·zoom, (z − z0 + ½)·zoom)`).
struct Marks<'a> {
    view: &'a OverlayView,
}

impl Marks<'_> {
    fn to_img(&self, x: f64, z: f64) -> (f64, f64) {
        let zoom = f64::from(self.view.zoom.max(1));
        (
            (x - self.view.x0 as f64 + 0.5) * zoom,
            (z - self.view.z0 as f64 + 0.5) * zoom,
        )
    }

    fn put(img: &mut RgbImage, u: f64, v: f64, rgb: [u8; 3]) {
        if u >= 0.0 && v >= 0.0 && (u as u32) < img.width() && (v as u32) < img.height() {
            img.put_pixel(u as u32, v as u32, image::Rgb(rgb));
        }
    }

    /// An × over the point, large enough to see at any enlargement.
    fn cross(&self, img: &mut RgbImage, x: f64, z: f64, rgb: [u8; 3]) {
        let (u, v) = self.to_img(x, z);
        let arm = (1.2 * f64::from(self.view.zoom)).max(3.0).round() as i32;
        for k in -arm..=arm {
            let k = f64::from(k);
            Self::put(img, u + k, v + k, rgb);
            Self::put(img, u + k, v - k, rgb);
        }
    }

    fn dashed_line(&self, img: &mut RgbImage, l: &SurfaceLine, rgb: [u8; 3]) {
        let w = img.width();
        let zoom = f64::from(self.view.zoom.max(1));
        for u in 0..w {
            if (u / 6) % 2 == 1 {
                continue;
            }
            let x = self.view.x0 as f64 - 0.5 + (f64::from(u) + 0.5) / zoom;
            let (_, v) = self.to_img(x, l.row_at(x));
            Self::put(img, f64::from(u), v, rgb);
        }
    }

    fn dashed_rect(&self, img: &mut RgbImage, rows: (f64, f64), cols: (f64, f64), rgb: [u8; 3]) {
        let (u0, v0) = self.to_img(cols.0, rows.0);
        let (u1, v1) = self.to_img(cols.1, rows.1);
        let dash = |k: f64| (k as i64 / 5) % 2 == 0;
        let mut u = u0;
        while u <= u1 {
            if dash(u - u0) {
                Self::put(img, u, v0, rgb);
                Self::put(img, u, v1, rgb);
            }
            u += 1.0;
        }
        let mut v = v0;
        while v <= v1 {
            if dash(v - v0) {
                Self::put(img, u0, v, rgb);
                Self::put(img, u1, v, rgb);
            }
            v += 1.0;
        }
    }
}

/// A border `px` wide around `img`.
fn border(img: &mut RgbImage, rgb: [u8; 3], px: u32) {
    let (w, h) = img.dimensions();
    for y in 0..h {
        for x in 0..w {
            if x < px || y < px || x + px >= w || y + px >= h {
                img.put_pixel(x, y, image::Rgb(rgb));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(frame: i64, z: f64) -> TrackRow {
        TrackRow {
            frame,
            t_s: frame as f64 * 1e-4,
            x_px: Some(100.0),
            z_px: Some(z),
            r_px: Some(40.0),
            residual_px: Some(0.05),
            edge_points: 30,
            in_contact: false,
            delta_mm: None,
            sigma_z_px: None,
            sigma_x_px: None,
            r_free_px: None,
            sigma_r_free_px: None,
            force_n: None,
            flags: String::new(),
        }
    }

    #[test]
    fn the_window_is_the_prediction_from_the_three_frames_before_with_the_reach() {
        let st = TrackSettings::from_config(&crate::config::DetectConfig::default());
        // z = 50 + 3k + 0.5k²: the constant-acceleration prediction is exact.
        let z = |k: i64| 50.0 + 3.0 * k as f64 + 0.5 * (k * k) as f64;
        let rows: Vec<TrackRow> = (0..4).map(|k| row(k, z(k))).collect();
        let before: Vec<&TrackRow> = rows[..3].iter().collect();
        let ((z0, z1), (x0, x1)) = predicted_window(&before, Some(&rows[3]), &st).unwrap();
        let reach = 40.0 + st.edge.half_window as f64 + st.band_margin_px;
        assert!((0.5 * (z0 + z1) - z(3)).abs() < 1e-9, "{z0} {z1}");
        assert!(((z1 - z0) - 2.0 * reach).abs() < 1e-9);
        assert!((0.5 * (x0 + x1) - 100.0).abs() < 1e-9 && ((x1 - x0) - 2.0 * reach).abs() < 1e-9);
        // Fewer than three fitted frames before: none.
        assert!(predicted_window(&before[1..], Some(&rows[3]), &st).is_none());
        let mut gap = rows.clone();
        gap[1].x_px = None;
        let before: Vec<&TrackRow> = gap[..3].iter().collect();
        assert!(predicted_window(&before, Some(&gap[3]), &st).is_none());
    }
}
