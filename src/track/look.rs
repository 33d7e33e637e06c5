//! How pass 1 looks at one frame ([`Look`]): a search of the whole frame or a
//! measurement around a predicted circle, and what it saw ([`Seen`]).

use super::band::measure_in_band;
use super::error::{detect_err, TrackError};
use super::settings::TrackSettings;
use crate::detect::coarse::{detect_coarse, BinnedBackground, CoarseScratch};
use crate::detect::{Background, Band, Circle, CircleFit, EdgeScratch, SurfaceLine};
use crate::source::{Frame, FrameSource};
use crate::util::timings::{self, Stage};

/// How pass 1 looks for the sphere in one frame.
#[derive(Debug, Clone, Copy)]
pub(super) enum Look {
    /// The coarse detector over the whole frame.
    Search,
    /// Measured around this circle, predicted from the last fits (on the
    /// [`PREDICTION_GRID_PX`] grid).
    At(Circle),
    /// Not looked at: the sphere left through the top of the frame and is
    /// on its way back ([`Pass1State::back_in_view_s`]).
    Away,
}

impl Look {
    /// The same look, bit for bit.
    pub(super) fn same(&self, other: &Look) -> bool {
        let bits = |c: &Circle| [c.x_px.to_bits(), c.z_px.to_bits(), c.r_px.to_bits()];
        match (self, other) {
            (Look::Search, Look::Search) => true,
            (Look::At(a), Look::At(b)) => bits(a) == bits(b),
            (Look::Away, Look::Away) => true,
            _ => false,
        }
    }
}

/// What pass 1 saw in one frame with one look: a pure function of the
/// frame and the look.
#[derive(Debug, Clone)]
pub(super) struct Seen {
    pub(super) look: Look,
    /// A search found a sphere (and measured around it).
    pub(super) found: bool,
    pub(super) fit: Option<CircleFit>,
    /// With a fit: the circle its normals were centred on, the radial σ and
    /// the edge points' offsets from that centre.
    pub(super) points: Option<(Circle, f64, Vec<[f32; 2]>)>,
}

/// What pass 1 measures with, the same for every frame.
pub(super) struct Pass1<'a> {
    pub(super) bg: &'a Background,
    pub(super) surface: &'a SurfaceLine,
    pub(super) st: &'a TrackSettings,
    pub(super) binned: Option<BinnedBackground>,
    /// The quick look's grid points, for the frames searched whole.
    pub(super) dark_grid: DarkGrid,
}

/// One thread's buffers for [`Pass1::look_at`].
pub(super) struct LookScratch {
    pub(super) buf: Frame,
    pub(super) es: EdgeScratch,
    pub(super) cs: CoarseScratch,
}

impl LookScratch {
    pub(super) fn new(h: usize, w: usize) -> Self {
        LookScratch {
            buf: Frame::zeros((h, w)),
            es: EdgeScratch::default(),
            cs: CoarseScratch::default(),
        }
    }
}

/// Buffers for [`Pass1::look_at`] handed from chunk to chunk: a chunk takes
/// one (or makes one) and gives it back, so that a thread first-touches a
/// whole frame and the search's buffers once, not once a chunk (at
/// 1280 × 800 about 4 MB each time).
#[derive(Default)]
pub(super) struct ScratchPool(std::sync::Mutex<Vec<LookScratch>>);

impl ScratchPool {
    pub(super) fn take(&self, h: usize, w: usize) -> LookScratch {
        let mut pool = self.0.lock().unwrap_or_else(|e| e.into_inner());
        pool.pop().unwrap_or_else(|| LookScratch::new(h, w))
    }

    pub(super) fn give(&self, sc: LookScratch) {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).push(sc);
    }
}

impl<'a> Pass1<'a> {
    pub(super) fn new(bg: &'a Background, surface: &'a SurfaceLine, st: &'a TrackSettings) -> Self {
        let (h, w) = (bg.height, bg.width);
        Pass1 {
            bg,
            surface,
            st,
            // The coarse search runs on frames binned 2×2 (a quarter of the
            // pixels); the measurement's re-centring absorbs its ~1 px error.
            binned: (w >= 128 && h >= 128).then(|| BinnedBackground::new(bg)),
            dark_grid: DarkGrid::new(bg, surface),
        }
    }

    /// Look at frame `i` as `look` says.
    pub(super) fn look_at(
        &self,
        source: &mut dyn FrameSource,
        i: usize,
        look: Look,
        sc: &mut LookScratch,
    ) -> Result<Seen, TrackError> {
        let (bg, surface, st) = (self.bg, self.surface, self.st);
        let number = source_number(source, i);
        let predicted = match look {
            Look::Away => {
                return Ok(Seen {
                    look,
                    found: false,
                    fit: None,
                    points: None,
                })
            }
            Look::At(p) => Some(p),
            Look::Search => {
                timings::time(Stage::Read, || source.read_into(i, &mut sc.buf))?;
                let band = Band::frame(&sc.buf).map_err(|e| detect_err(number, e))?;
                let gain = bg.gain(&band).map_err(|e| detect_err(number, e))?.gain;
                if self.dark_grid.any_dark(&sc.buf, bg, gain, surface) {
                    match self.binned.as_ref() {
                        Some(b) => b.detect(&band, gain, Some(surface), &st.coarse, &mut sc.cs),
                        None => {
                            detect_coarse(&band, bg, gain, Some(surface), &st.coarse, &mut sc.cs)
                        }
                    }
                    .map_err(|e| detect_err(number, e))?
                    .map(|c| c.circle)
                } else {
                    None
                }
            }
        };
        let fit = match predicted {
            Some(p) => measure_in_band(
                source,
                i,
                &mut sc.buf,
                bg,
                &p,
                surface,
                None,
                st,
                &mut sc.es,
            )?,
            None => None,
        };
        let points = fit.map(|_| {
            let c = sc.es.centre;
            let pts = sc
                .es
                .points
                .iter()
                .map(|p| [(p.x_px - c.x_px) as f32, (p.z_px - c.z_px) as f32])
                .collect();
            (c, sc.es.radial_sigma_px, pts)
        });
        Ok(Seen {
            look,
            found: predicted.is_some(),
            fit,
            points,
        })
    }
}

pub(super) fn source_number(source: &dyn FrameSource, i: usize) -> i64 {
    source.meta().frame_number(i)
}

/// Grid step (px) of the quick look for a dark object before the coarse search.
pub(super) const QUICK_STEP_PX: usize = 6;

/// Whether at least three points of a sparse grid above the surface line are
/// darker than half their background: a sphere of radius ≥ 10 px always
/// covers several. Saves the full coarse search on frames without a sphere.
pub(super) fn anything_dark(
    frame: &Frame,
    bg: &Background,
    gain: f64,
    surface: &SurfaceLine,
) -> bool {
    let (h, w) = frame.dim();
    let mut dark = 0;
    for i in (QUICK_STEP_PX / 2..h).step_by(QUICK_STEP_PX) {
        for j in (QUICK_STEP_PX / 2..w).step_by(QUICK_STEP_PX) {
            if i as f64 > surface.row_at(j as f64) - 2.0 {
                continue;
            }
            if (frame[[i, j]] as f64) < 0.5 * gain * bg.at(i, j) as f64 {
                dark += 1;
                if dark >= 3 {
                    return true;
                }
            }
        }
    }
    false
}

/// The points of [`anything_dark`]'s grid above the surface line, found
/// once for a movie with their background levels, so that a frame searched
/// whole (most of a long movie's, where the sphere is out of view) is
/// checked by one pass over its grid: the same comparisons, the same
/// answer.
pub(super) struct DarkGrid {
    /// Frame size the points were taken for (rows, columns).
    pub(super) dim: (usize, usize),
    /// Row-major index of each point in the frame, and its background level.
    pub(super) points: Vec<(u32, f32)>,
}

impl DarkGrid {
    pub(super) fn new(bg: &Background, surface: &SurfaceLine) -> DarkGrid {
        let (h, w) = (bg.height, bg.width);
        let mut points = Vec::new();
        // A frame of 2^32 pixels or more is checked by `anything_dark`.
        let fits = u32::try_from(h * w).is_ok();
        if fits {
            for i in (QUICK_STEP_PX / 2..h).step_by(QUICK_STEP_PX) {
                for j in (QUICK_STEP_PX / 2..w).step_by(QUICK_STEP_PX) {
                    if i as f64 > surface.row_at(j as f64) - 2.0 {
                        continue;
                    }
                    points.push(((i * w + j) as u32, bg.at(i, j)));
                }
            }
        }
        DarkGrid {
            dim: if fits { (h, w) } else { (0, 0) },
            points,
        }
    }

    /// [`anything_dark`] of `frame`, from the points when the frame is the
    /// size they were taken for and contiguous.
    pub(super) fn any_dark(
        &self,
        frame: &Frame,
        bg: &Background,
        gain: f64,
        surface: &SurfaceLine,
    ) -> bool {
        let data = match frame.as_slice() {
            Some(d) if frame.dim() == self.dim && !d.is_empty() => d,
            _ => return anything_dark(frame, bg, gain, surface),
        };
        let mut dark = 0;
        for &(k, level) in &self.points {
            // As `anything_dark` computes it: (0.5 · gain) · level.
            if (data[k as usize] as f64) < 0.5 * gain * level as f64 {
                dark += 1;
                if dark >= 3 {
                    return true;
                }
            }
        }
        false
    }
}
