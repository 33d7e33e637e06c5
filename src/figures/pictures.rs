//! The pictures `process` draws of a run from its track: the overlay of one
//! frame (the frame nearest δmax, and any asked for) with a caption band
//! (frame, time, δ, scale bar), and the animated overlay of the whole
//! impact (an animated PNG: every frame from before contact to after the
//! rebound, with the circle, the edge points and the surface line).

use crate::detect::Band;
use crate::figures::overlay::{encode_indexed_apng, IndexedFrame, OverlayView, Scene};
use crate::plot::{caption_band, with_caption, Caption};
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
    /// The run's recording, to read the frames drawn.
    pub source: &'a mut dyn FrameSource,
    /// What the recording holds.
    pub meta: &'a SourceMeta,
    /// The run's track.
    pub track: &'a Track,
    /// The tracking settings the run was measured with.
    pub settings: &'a TrackSettings,
    /// A frame's δ as its row of the track CSV gives it.
    pub delta_mm: &'a (dyn Fn(&FrameTrack) -> Option<f64> + Sync),
    /// The run's scale, mm per px.
    pub mm_per_px: f64,
}

impl Pictures<'_> {
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
        let _timed = crate::util::timings::start(crate::util::timings::Stage::Overlays);
        let mut frame = Frame::zeros((self.meta.height, self.meta.width));
        let (source, on) = self.split();
        let img = on.draw(
            source,
            &mut frame,
            ft,
            None,
            STILL_ZOOM,
            |scene, caption| with_caption(&scene.rgb(), caption).ok(),
        )?;
        crate::figures::overlay::encode_png(&img).ok()
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
        use crate::util::timings::{start, Stage};
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
        // The frames drawn in the palette on every thread, each
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
                            on.draw(&mut **src, &mut frame, f, Some(view), MOVIE_ZOOM, indexed)
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

/// A frame of the animation: the overlay in the palette with its caption
/// band under it.
fn indexed(scene: &Scene, caption: &Caption) -> Option<IndexedFrame> {
    let band = caption_band(scene.view.size_px().0 as u32, caption).ok()?;
    Some(scene.indexed(&band.grey))
}

impl Drawn<'_> {
    /// Frame `ft` read into `frame` (the source's shape) and drawn in
    /// `view` (default: a crop around its circle at `zoom`) by `picture`
    /// from what it shows and its caption; `None` when it cannot be read
    /// or has no fit.
    fn draw<T>(
        &self,
        source: &mut dyn FrameSource,
        frame: &mut Frame,
        ft: &FrameTrack,
        view: Option<OverlayView>,
        zoom: u32,
        picture: impl FnOnce(&Scene, &Caption) -> Option<T>,
    ) -> Option<T> {
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
        crate::util::timings::time(crate::util::timings::Stage::Read, || {
            source.read_window_into(ft.index, 0, &cols, &mut frame.view_mut())
        })
        .ok()?;
        let band = Band::window(frame.view(), 0, crop).ok()?;
        let pts = edge_points_in(&band, self.track, ft, self.settings);
        let scene = Scene {
            band: &band,
            bit_depth: self.meta.bit_depth,
            view: &view,
            points: &pts,
            circle: Some(&c),
            surface: Some(&self.track.surface),
        };
        let delta_mm = (self.delta_mm)(ft);
        let caption = Caption {
            frame: ft.frame,
            t_s: ft.t_s,
            delta_mm,
            mm_per_px: self.mm_per_px,
            zoom: view.zoom,
        };
        picture(&scene, &caption)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::circle::Circle;
    use crate::detect::edges::EdgePoint;
    use crate::detect::surface::SurfaceLine;
    use crate::figures::overlay::{encode_indexed_apng, to_indexed};
    use rand::{Rng, SeedableRng};

    /// An animation frame as it was made before it was drawn in the
    /// palette: the RGB overlay, its caption in RGB, then every pixel put
    /// in the palette.
    fn indexed_from_rgb(scene: &Scene, caption: &Caption) -> IndexedFrame {
        to_indexed(&with_caption(&scene.rgb(), caption).unwrap())
    }

    #[test]
    fn a_frame_drawn_in_the_palette_is_the_rgb_frame_put_in_it() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(18);
        // Rows 20..80 of a 90-column frame, values over the full range of
        // each bit depth and past it (clipped to white).
        let (row0, nrows, width) = (20, 60, 90);
        let mut compared = 0;
        for bit_depth in [8u8, 12, 16] {
            let top = if bit_depth == 16 {
                u16::MAX
            } else {
                (1u16 << bit_depth) + 300
            };
            let data: Vec<u16> = (0..nrows * width).map(|_| rng.gen_range(0..=top)).collect();
            let band = Band {
                data: &data,
                row0,
                nrows,
                width,
                cols: (0, width),
            };
            for zoom in [1u32, 2, 3] {
                // Inside the band; past its top, bottom and right; one
                // pixel; a strip of the band's full width.
                let views = [
                    (30, 35, 40, 30),
                    (70, 10, 30, 30),
                    (60, 70, 40, 25),
                    (5, 79, 1, 1),
                    (0, 20, 90, 60),
                ];
                for (x0, z0, w, h) in views {
                    let view = OverlayView {
                        x0,
                        z0,
                        width: w,
                        height: h,
                        zoom,
                    };
                    // A circle partly outside the crop, points near and
                    // past its edges and corners, a sloping surface.
                    let circle = Circle {
                        x_px: x0 as f64 + rng.gen_range(-5.0..w as f64 + 5.0),
                        z_px: z0 as f64 + rng.gen_range(-5.0..h as f64 + 5.0),
                        r_px: rng.gen_range(3.0..25.0),
                    };
                    let points: Vec<EdgePoint> = (0..30)
                        .map(|_| EdgePoint {
                            x_px: x0 as f64 + rng.gen_range(-2.0..w as f64 + 2.0),
                            z_px: z0 as f64 + rng.gen_range(-2.0..h as f64 + 2.0),
                            weight: 1.0,
                        })
                        .chain(
                            [(-0.5, -0.5), (-0.6, 0.0), (w as f64 - 0.5, h as f64 - 0.51)].map(
                                |(dx, dz)| EdgePoint {
                                    x_px: x0 as f64 + dx,
                                    z_px: z0 as f64 + dz,
                                    weight: 1.0,
                                },
                            ),
                        )
                        .collect();
                    let surface =
                        SurfaceLine::given(z0 as f64 + 0.6 * h as f64, rng.gen_range(-0.2..0.2));
                    let caption = Caption {
                        frame: rng.gen_range(-50..5000),
                        t_s: rng.gen_range(-0.01..0.5),
                        delta_mm: rng.gen_bool(0.8).then(|| rng.gen_range(-3.0..3.0)),
                        mm_per_px: rng.gen_range(0.01..0.1),
                        zoom,
                    };
                    let scenes = [
                        Scene {
                            band: &band,
                            bit_depth,
                            view: &view,
                            points: &points,
                            circle: Some(&circle),
                            surface: Some(&surface),
                        },
                        Scene {
                            band: &band,
                            bit_depth,
                            view: &view,
                            points: &[],
                            circle: None,
                            surface: None,
                        },
                    ];
                    for scene in &scenes {
                        let want = indexed_from_rgb(scene, &caption);
                        let got = indexed(scene, &caption).unwrap();
                        let at = format!("bit depth {bit_depth}, view {view:?}");
                        assert_eq!((got.width, got.height), (want.width, want.height), "{at}");
                        assert!(got.data == want.data, "{at}");
                        compared += 1;
                    }
                }
            }
        }
        assert_eq!(compared, 3 * 3 * 5 * 2);
    }

    #[test]
    fn an_animation_drawn_in_the_palette_is_the_bytes_of_the_rgb_one() {
        // A moving sphere over a 12-bit frame, as an animation shows it.
        let (nrows, width) = (70, 80);
        let data: Vec<u16> = (0..nrows * width)
            .map(|k| (16 * ((k % width) * 3 + k / width)) as u16)
            .collect();
        let band = Band::new(
            ndarray::ArrayView2::from_shape((nrows, width), &data).unwrap(),
            0,
        )
        .unwrap();
        let view = OverlayView {
            x0: 10,
            z0: 5,
            width: 60,
            height: 60,
            zoom: MOVIE_ZOOM,
        };
        let surface = SurfaceLine::given(50.0, 0.01);
        let frames = |by_rgb: bool| -> Vec<IndexedFrame> {
            (0..8)
                .map(|k| {
                    let circle = Circle {
                        x_px: 40.0,
                        z_px: 20.0 + 3.3 * k as f64,
                        r_px: 12.0,
                    };
                    let points: Vec<EdgePoint> = (0..40)
                        .map(|j| {
                            let t = std::f64::consts::TAU * j as f64 / 40.0;
                            EdgePoint {
                                x_px: circle.x_px + circle.r_px * t.cos(),
                                z_px: circle.z_px + circle.r_px * t.sin(),
                                weight: 1.0,
                            }
                        })
                        .collect();
                    let scene = Scene {
                        band: &band,
                        bit_depth: 12,
                        view: &view,
                        points: &points,
                        circle: Some(&circle),
                        surface: Some(&surface),
                    };
                    let caption = Caption {
                        frame: k,
                        t_s: k as f64 * 1e-4,
                        delta_mm: (k > 3).then_some(0.1 * k as f64),
                        mm_per_px: 0.05,
                        zoom: MOVIE_ZOOM,
                    };
                    if by_rgb {
                        indexed_from_rgb(&scene, &caption)
                    } else {
                        indexed(&scene, &caption).unwrap()
                    }
                })
                .collect()
        };
        let (new, old) = (frames(false), frames(true));
        let bytes = |f: &[IndexedFrame]| encode_indexed_apng(f, MOVIE_FRAME_MS).unwrap();
        assert!(bytes(&new) == bytes(&old));
    }
}
