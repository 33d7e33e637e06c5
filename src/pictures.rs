//! The pictures `process` draws of a run from its track: the overlay of one
//! frame (the frame nearest δmax, and any asked for) with a caption band
//! (frame, time, δ, scale bar), and the animated overlay of the whole
//! impact (an animated PNG: every frame from before contact to after the
//! rebound, with the circle, the edge points and the surface line).

use image::RgbImage;

use crate::detect::overlay::{encode_indexed_apng, overlay, to_indexed, IndexedFrame, OverlayView};
use crate::detect::Band;
use crate::plot::{with_caption, Caption};
use crate::source::{Frame, FrameSource, SourceMeta};
use crate::track::{edge_points_in, window_columns, FrameTrack, Track, TrackSettings};

/// Enlargement of the still overlays.
pub const STILL_ZOOM: u32 = 3;
/// Enlargement of the animation's frames.
pub const MOVIE_ZOOM: u32 = 1;
/// Frames shown before contact and after the rebound: this share of the
/// contact time, and at least 3 frames.
const MOVIE_MARGIN_SHARE: f64 = 0.3;
/// Most frames in an animation (a longer impact is sampled evenly).
pub const MAX_MOVIE_FRAMES: usize = 100;
/// How long each animation frame shows, ms.
pub const MOVIE_FRAME_MS: u16 = 80;
/// Frame pixels around the sphere in a crop.
const MARGIN_PX: f64 = 12.0;

/// What the pictures of one run are drawn from.
pub struct Pictures<'a> {
    pub source: &'a mut dyn FrameSource,
    pub meta: &'a SourceMeta,
    pub track: &'a Track,
    pub settings: &'a TrackSettings,
    /// A frame's δ as its row of the track CSV gives it.
    pub delta_mm: &'a (dyn Fn(&FrameTrack) -> Option<f64> + Sync),
    pub mm_per_px: f64,
}

impl Pictures<'_> {
    /// Frame `ft` drawn in `view` (default: a crop around its circle at
    /// `zoom`), with its caption; `None` when it cannot be read or has no fit.
    fn draw(&mut self, ft: &FrameTrack, view: Option<OverlayView>, zoom: u32) -> Option<RgbImage> {
        let mut frame = Frame::zeros((self.meta.height, self.meta.width));
        let (source, on) = self.split();
        on.draw(source, &mut frame, ft, view, zoom)
    }

    /// The source, and the rest to draw from.
    fn split(&mut self) -> (&mut dyn FrameSource, Drawn<'_>) {
        let on = Drawn {
            meta: self.meta,
            track: self.track,
            settings: self.settings,
            delta_mm: self.delta_mm,
            mm_per_px: self.mm_per_px,
        };
        (&mut *self.source, on)
    }

    /// The overlay of `ft` as PNG bytes.
    pub fn still(&mut self, ft: &FrameTrack) -> Option<Vec<u8>> {
        let _timed = crate::timings::start(crate::timings::Stage::Overlays);
        crate::detect::overlay::encode_png(&self.draw(ft, None, STILL_ZOOM)?).ok()
    }

    /// The frames of the impact: fitted frames from `t_contact_s` less a
    /// margin to `t_rebound_s` (else the last frame) plus the margin, at
    /// most [`MAX_MOVIE_FRAMES`], evenly sampled.
    pub fn impact_frames(&self, t_contact_s: f64, t_rebound_s: Option<f64>) -> Vec<FrameTrack> {
        let dt = 1.0 / self.meta.fps;
        let end = t_rebound_s.unwrap_or(f64::INFINITY);
        let margin = (MOVIE_MARGIN_SHARE * (end - t_contact_s)).clamp(3.0 * dt, 50.0 * dt);
        let margin = if margin.is_finite() { margin } else { 3.0 * dt };
        let chosen: Vec<FrameTrack> = self
            .track
            .frames
            .iter()
            .filter(|f| f.held.is_some() && f.t_s >= t_contact_s - margin && f.t_s <= end + margin)
            .collect();
        let step = chosen.len().div_ceil(MAX_MOVIE_FRAMES).max(1);
        chosen.into_iter().step_by(step).collect()
    }

    /// The animated overlay of the impact (see [`Self::impact_frames`]) as
    /// animated-PNG bytes: one fixed crop holding every frame's circle, at
    /// [`MOVIE_ZOOM`], [`MOVIE_FRAME_MS`] per frame, looping. `None` with
    /// fewer than 2 frames drawn.
    pub fn impact(&mut self, t_contact_s: f64, t_rebound_s: Option<f64>) -> Option<Vec<u8>> {
        use crate::timings::{start, Stage};
        let _timed = start(Stage::Animation);
        let frames = self.impact_frames(t_contact_s, t_rebound_s);
        let circles: Vec<_> = frames
            .iter()
            .filter_map(|f| f.held.map(|c| c.circle()))
            .collect();
        let (w, h) = (self.meta.width as f64, self.meta.height as f64);
        let lo = |v: f64, hi: f64| v.clamp(0.0, hi - 1.0).floor() as usize;
        let x0 = lo(
            circles
                .iter()
                .map(|c| c.x_px - c.r_px)
                .fold(f64::INFINITY, f64::min)
                - MARGIN_PX,
            w,
        );
        let z0 = lo(
            circles
                .iter()
                .map(|c| c.z_px - c.r_px)
                .fold(f64::INFINITY, f64::min)
                - MARGIN_PX,
            h,
        );
        let x1 = lo(
            circles
                .iter()
                .map(|c| c.x_px + c.r_px)
                .fold(f64::NEG_INFINITY, f64::max)
                + MARGIN_PX,
            w,
        ) + 1;
        let z1 = lo(
            circles
                .iter()
                .map(|c| c.z_px + c.r_px)
                .fold(f64::NEG_INFINITY, f64::max)
                + MARGIN_PX,
            h,
        ) + 1;
        if circles.len() < 2 || x1 <= x0 || z1 <= z0 {
            return None;
        }
        let view = OverlayView {
            x0,
            z0,
            width: x1 - x0,
            height: z1 - z0,
            zoom: MOVIE_ZOOM,
        };
        // The frames drawn and put in the palette on every thread, each
        // with its own copy of the source, a frame buffer and a run of
        // consecutive frames, kept in order.
        let (height, width) = (self.meta.height, self.meta.width);
        let threads = rayon::current_num_threads().min(frames.len()).max(1);
        let mut copies: Vec<Box<dyn FrameSource>> = (1..threads)
            .map_while(|_| self.source.try_clone())
            .collect();
        let (source, on) = self.split();
        let mut sources: Vec<&mut dyn FrameSource> = std::iter::once(source)
            .chain(copies.iter_mut().map(|c| c.as_mut()))
            .collect();
        let (n, groups) = (frames.len(), sources.len());
        let images: Vec<IndexedFrame> = {
            use rayon::prelude::*;
            sources
                .par_iter_mut()
                .enumerate()
                .map(|(g, src)| {
                    let _timed = start(Stage::Animation);
                    let mut frame = Frame::zeros((height, width));
                    frames[g * n / groups..(g + 1) * n / groups]
                        .iter()
                        .map(|f| {
                            on.draw(&mut **src, &mut frame, f, Some(view), MOVIE_ZOOM)
                                .map(|img| to_indexed(&img))
                        })
                        .collect::<Vec<_>>()
                })
                .collect::<Vec<_>>()
                .into_iter()
                .flatten()
                .flatten()
                .collect()
        };
        (images.len() >= 2)
            .then(|| encode_indexed_apng(&images, MOVIE_FRAME_MS).ok())
            .flatten()
    }
}

/// What a frame's picture is drawn from, but the source: shared by the
/// threads that draw an animation's frames, each from its own source.
struct Drawn<'a> {
    meta: &'a SourceMeta,
    track: &'a Track,
    settings: &'a TrackSettings,
    delta_mm: &'a (dyn Fn(&FrameTrack) -> Option<f64> + Sync),
    mm_per_px: f64,
}

impl Drawn<'_> {
    /// See [`Pictures::draw`]; `frame` (the source's shape) is read into.
    fn draw(
        &self,
        source: &mut dyn FrameSource,
        frame: &mut Frame,
        ft: &FrameTrack,
        view: Option<OverlayView>,
        zoom: u32,
    ) -> Option<RgbImage> {
        let c = ft.held.or(ft.free)?.circle();
        let view = match view {
            Some(v) => v,
            None => OverlayView::around(&Band::frame(frame).ok()?, &c, MARGIN_PX, zoom),
        };
        // Whole rows (the flicker gain is the whole frame's), but only the
        // crop's columns, which hold the circle and MARGIN_PX around it
        // (more than the edge normals reach), and the flicker strips.
        let width = frame.ncols();
        let crop = view.x0..view.x0 + view.width;
        let strip = self.track.background.region.strip_px.min(width);
        let cols = window_columns(crop.clone(), strip, width);
        crate::timings::time(crate::timings::Stage::Read, || {
            source.read_window_into(ft.index, 0, &cols, &mut frame.view_mut())
        })
        .ok()?;
        let band = Band::window(frame.view(), 0, crop).ok()?;
        let pts = edge_points_in(&band, self.track, ft, self.settings);
        let img = overlay(
            &band,
            self.meta.bit_depth,
            &view,
            &pts,
            Some(&c),
            Some(&self.track.surface),
        );
        let delta_mm = (self.delta_mm)(ft);
        let caption = Caption {
            frame: ft.frame,
            t_s: ft.t_s,
            delta_mm,
            mm_per_px: self.mm_per_px,
            zoom: view.zoom,
        };
        with_caption(&img, &caption).ok()
    }
}
