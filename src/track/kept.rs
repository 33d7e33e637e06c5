//! What pass 1 keeps of a frame for pass 2 ([`Kept`]), and its record's bytes.

use super::look::Look;
use crate::detect::Circle;
use crate::util::records::{Put, Record, Take};

/// What pass 1 keeps of a frame with a fit for pass 2.
#[derive(Debug, Clone, Copy)]
pub(super) enum Kept {
    /// Where its edge points sit in the kept buffer, and the circle their
    /// normals were centred on (the origin of their offsets).
    Points {
        start: usize,
        len: usize,
        centre: Circle,
        radial_sigma_px: f64,
    },
    /// Past [`TrackSettings::kept_points_max`]: how pass 1 looked at it,
    /// to measure it again in pass 2.
    Again(Look),
}

/// A tag (0 nothing kept, 1 points, 2 and 3 a look to measure again: a
/// search, a circle), the points' place, a circle and the radial σ.
impl Record for Option<Kept> {
    const BYTES: usize = 1 + 8 * 2 + 8 * 4;

    fn put(&self, out: &mut Vec<u8>) {
        let none = Circle {
            x_px: 0.0,
            z_px: 0.0,
            r_px: 0.0,
        };
        let (tag, start, len, c, sigma) = match *self {
            None => (0, 0, 0, none, 0.0),
            Some(Kept::Points {
                start,
                len,
                centre,
                radial_sigma_px,
            }) => (1, start, len, centre, radial_sigma_px),
            Some(Kept::Again(Look::Search)) => (2, 0, 0, none, 0.0),
            Some(Kept::Again(Look::At(c))) => (3, 0, 0, c, 0.0),
            Some(Kept::Again(Look::Away)) => (4, 0, 0, none, 0.0),
        };
        let mut p = Put(out);
        p.u8(tag);
        p.u64(start as u64);
        p.u64(len as u64);
        for v in [c.x_px, c.z_px, c.r_px, sigma] {
            p.f64(v);
        }
    }

    fn get(b: &[u8]) -> Self {
        let mut t = Take(b);
        let (tag, start, len) = (t.u8(), t.u64() as usize, t.u64() as usize);
        let c = Circle {
            x_px: t.f64(),
            z_px: t.f64(),
            r_px: t.f64(),
        };
        let radial_sigma_px = t.f64();
        match tag {
            0 => None,
            1 => Some(Kept::Points {
                start,
                len,
                centre: c,
                radial_sigma_px,
            }),
            2 => Some(Kept::Again(Look::Search)),
            4 => Some(Kept::Again(Look::Away)),
            _ => Some(Kept::Again(Look::At(c))),
        }
    }
}

/// One frame's kept points as [`hold`] takes them.
#[derive(Debug, Clone, Copy)]
pub(super) struct KeptRef<'a> {
    /// Offsets from `centre`.
    pub(super) points: &'a [[f32; 2]],
    pub(super) centre: Circle,
    pub(super) radial_sigma_px: f64,
}
