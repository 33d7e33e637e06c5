//! Scatter markers as one plotters element type, so that a series can mix
//! them and a legend can show them. Drawn in backend pixels: a circle becomes
//! one SVG `<circle>`, a triangle, diamond or square one `<polygon>`, a cross
//! two `<line>`s.

use plotters::element::{Drawable, PointCollection};
use plotters::prelude::*;
use plotters_backend::{BackendCoord, DrawingErrorKind};

/// The marker shapes of Figs. 3–4 of Maruoka 2019, plus a few for other radii.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MarkerKind {
    /// A circle (R = 3 mm in the paper's figures).
    Circle,
    /// A triangle pointing up (R = 4 mm).
    Triangle,
    /// A diagonal cross (R = 4.5 mm).
    Cross,
    /// A diamond (R = 5 mm).
    Diamond,
    /// A square (R = 7 mm).
    Square,
    /// A triangle pointing down (another radius).
    InvertedTriangle,
}

/// Colour and marker of a sphere radius (paper's Figs. 3–4 for the five
/// radii it used; others, in order of the `index`-th unknown radius,
/// cycle through purple, teal, brown, magenta).
pub fn radius_style(radius_mm: f64, other_index: usize) -> (RGBColor, MarkerKind) {
    let known = [
        (3.0, RGBColor(0, 0, 230), MarkerKind::Circle),
        (4.0, RGBColor(0, 150, 0), MarkerKind::Triangle),
        (4.5, RGBColor(0, 0, 0), MarkerKind::Cross),
        (5.0, RGBColor(240, 130, 0), MarkerKind::Diamond),
        (7.0, RGBColor(220, 0, 0), MarkerKind::Square),
    ];
    for (r, c, m) in known {
        if (radius_mm - r).abs() < 1e-3 {
            return (c, m);
        }
    }
    let others = [
        (RGBColor(130, 0, 170), MarkerKind::InvertedTriangle),
        (RGBColor(0, 140, 140), MarkerKind::Circle),
        (RGBColor(140, 80, 20), MarkerKind::Square),
        (RGBColor(200, 0, 150), MarkerKind::Diamond),
    ];
    let (c, m) = others[other_index % others.len()];
    (c, m)
}

/// One marker at a data coordinate.
#[derive(Debug, Clone, Copy)]
pub struct Marker<C> {
    /// Where the marker stands, in data coordinates.
    pub at: C,
    /// Its shape.
    pub kind: MarkerKind,
    /// Its colour.
    pub color: RGBColor,
    /// Half-size in pixels.
    pub size: i32,
}

impl<C> Marker<C> {
    /// A marker of `kind` and `color` at `at`, `size` pixels from its centre to its edge.
    pub fn new(at: C, kind: MarkerKind, color: RGBColor, size: i32) -> Self {
        Marker {
            at,
            kind,
            color,
            size,
        }
    }
}

impl<'a, C: 'a> PointCollection<'a, C> for &'a Marker<C> {
    type Point = &'a C;
    type IntoIter = std::iter::Once<&'a C>;
    fn point_iter(self) -> Self::IntoIter {
        std::iter::once(&self.at)
    }
}

impl<C, DB: DrawingBackend> Drawable<DB> for Marker<C> {
    fn draw<I: Iterator<Item = BackendCoord>>(
        &self,
        mut pos: I,
        backend: &mut DB,
        _: (u32, u32),
    ) -> Result<(), DrawingErrorKind<DB::ErrorType>> {
        let Some((x, y)) = pos.next() else {
            return Ok(());
        };
        let s = self.size;
        let fill = self.color.filled();
        match self.kind {
            MarkerKind::Circle => backend.draw_circle((x, y), s as u32, &fill, true),
            MarkerKind::Triangle => backend.fill_polygon(
                [(x, y - s - 1), (x - s - 1, y + s), (x + s + 1, y + s)],
                &fill,
            ),
            MarkerKind::InvertedTriangle => backend.fill_polygon(
                [(x, y + s + 1), (x - s - 1, y - s), (x + s + 1, y - s)],
                &fill,
            ),
            MarkerKind::Diamond => {
                let d = s + 2;
                backend.fill_polygon([(x, y - d), (x + d, y), (x, y + d), (x - d, y)], &fill)
            }
            MarkerKind::Square => backend.fill_polygon(
                [
                    (x - s, y - s),
                    (x + s, y - s),
                    (x + s, y + s),
                    (x - s, y + s),
                ],
                &fill,
            ),
            MarkerKind::Cross => {
                let st = self.color.stroke_width(2);
                backend.draw_line((x - s, y - s), (x + s, y + s), &st)?;
                backend.draw_line((x - s, y + s), (x + s, y - s), &st)
            }
        }
    }
}
