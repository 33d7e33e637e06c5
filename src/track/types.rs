//! A tracked run ([`Track`]).

use super::frame::FrameTrack;
use crate::detect::{Background, SurfaceLine};
use crate::util::records::Records;

/// A tracked run.
#[derive(Debug)]
pub struct Track {
    /// The undeformed surface line.
    pub surface: SurfaceLine,
    /// True when the surface line came from the configuration.
    pub surface_from_config: bool,
    /// The sphere's calibrated radius R_px, held in pass 2, px.
    pub radius_px: f64,
    /// One-sigma error of `radius_px`, with its systematic floor, px.
    pub radius_err_px: f64,
    /// Frames whose full circle gave the radius.
    pub radius_frames: usize,
    /// A record a frame, in memory or in a temporary file past
    /// `TrackSettings::frames_in_memory_max`: walk them with
    /// [`Records::iter`], then [`Records::check`] that none failed to be
    /// read back.
    pub frames: Records<FrameTrack>,
    /// The background the frames were measured against.
    pub background: Background,
    /// Frames that pass 2 had to read again (see the module doc, step 4).
    pub reread_frames: usize,
    /// Frames of pass 1 measured ahead by other threads and taken as they
    /// were (see `speculate`); 0 on one thread.
    pub measured_ahead: usize,
    /// Edge points pass 1 kept for pass 2 (at most
    /// `TrackSettings::kept_points_max`).
    pub kept_points: usize,
    /// Frames with a fit whose points were past that budget: pass 2
    /// measured them again as pass 1 did (the same points).
    pub remeasured_frames: usize,
    /// Most frames measured ahead and not yet taken at any one time (0 on
    /// one thread).
    pub ahead_frames_max: usize,
    /// Frames pass 1 did not look at: the sphere was away above the frame
    /// (`TrackSettings::skip_away`).
    pub away_frames: usize,
    /// Frames of pass 1 searched whole on every thread at once, ahead of
    /// the walk in order, and taken (see `Walk::search_ahead`); 0 on one
    /// thread.
    pub searched_ahead: usize,
    /// Frames pass 1 did not search: a search further on, within a
    /// `search_stride`, found nothing (`TrackSettings::probe_searches`).
    pub unsearched_frames: usize,
    /// Frames flagged `Flag::Outlier`.
    pub outlier_frames: usize,
}

impl Track {
    /// One-sigma uncertainty of the surface row at column `x_px`: the line
    /// fit's, plus the systematic error of the edge model it was taken with
    /// ([`SurfaceLine::edge_model_sigma_px`]) in quadrature for a detected
    /// line (a line from the configuration is taken as given).
    pub fn surface_row_err_px(&self, x_px: f64) -> f64 {
        let fit = self.surface.sigma_row_at(x_px);
        if self.surface_from_config {
            fit
        } else {
            fit.hypot(self.surface.edge_model_sigma_px())
        }
    }
}
