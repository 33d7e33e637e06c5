//! Colour recordings read as grey: the luminance of each pixel.
//!
//! dropscope measures a backlit silhouette; colour carries nothing it uses,
//! so a colour input becomes one grey value a pixel,
//! `Y = 0.2126 R + 0.7152 G + 0.0722 B` (ITU-R BT.709, the weights the
//! `image` crate's grey conversion of colour frame files uses too), rounded
//! to the nearest count. A raw Bayer mosaic is first demosaicked
//! bilinearly: at each pixel, a channel the pixel did not sample is the
//! mean of that channel's samples among its 3 × 3 neighbours inside the
//! picture (its own channel is its own sample).

use std::ops::Range;

use ndarray::ArrayView2;

/// The BT.709 luminance weights of R, G and B.
pub const LUMA_WEIGHTS: [f32; 3] = [0.2126, 0.7152, 0.0722];

/// What a colour input held, read as grey luminance ([`super::SourceDetails::colour`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ColourInput {
    /// A raw Bayer mosaic (a colour camera's unprocessed samples).
    Bayer(Bayer),
    /// Three samples a pixel: an interpolated colour cine (BGR) or colour
    /// frame files (RGB, RGBA, paletted).
    Rgb,
}

impl ColourInput {
    /// A one-word name for tables: `bayer` or `rgb`.
    pub fn name(&self) -> &'static str {
        match self {
            ColourInput::Bayer(_) => "bayer",
            ColourInput::Rgb => "rgb",
        }
    }

    /// What was done, for `inspect` and warnings.
    pub fn describe(&self) -> String {
        match self {
            ColourInput::Bayer(b) => format!(
                "raw Bayer {} colour, read as grey luminance (bilinear demosaic, then \
                 Y = 0.2126 R + 0.7152 G + 0.0722 B)",
                b.name()
            ),
            ColourInput::Rgb => "colour (RGB), read as grey luminance \
                 Y = 0.2126 R + 0.7152 G + 0.0722 B"
                .to_string(),
        }
    }
}

/// A Bayer mosaic's 2 × 2 pattern, named by its top row then its second
/// (`GBRG`: G B on the picture's first row, R G on the second), in the
/// picture top-down.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Bayer {
    /// G B on the first row, R G on the second.
    Gbrg,
    /// R G on the first row, G B on the second.
    Rggb,
    /// G R on the first row, B G on the second.
    Grbg,
    /// B G on the first row, G R on the second.
    Bggr,
}

impl Bayer {
    /// The pattern's name in capitals (`GBRG`, …), as in messages and `reading`.
    pub fn name(self) -> &'static str {
        match self {
            Bayer::Gbrg => "GBRG",
            Bayer::Rggb => "RGGB",
            Bayer::Grbg => "GRBG",
            Bayer::Bggr => "BGGR",
        }
    }

    /// The channel (0 = R, 1 = G, 2 = B) sampled at row `r`, column `c`.
    #[inline]
    pub fn channel(self, r: usize, c: usize) -> usize {
        let k = 2 * (r & 1) + (c & 1);
        const R: usize = 0;
        const G: usize = 1;
        const B: usize = 2;
        let cells = match self {
            Bayer::Gbrg => [G, B, R, G],
            Bayer::Rggb => [R, G, G, B],
            Bayer::Grbg => [G, R, B, G],
            Bayer::Bggr => [B, G, G, R],
        };
        cells[k]
    }
}

/// `Y` of one pixel, rounded and clipped to `0..=max`.
#[inline]
pub fn luma(rgb: [f32; 3], max: u16) -> u16 {
    let y = LUMA_WEIGHTS[0] * rgb[0] + LUMA_WEIGHTS[1] * rgb[1] + LUMA_WEIGHTS[2] * rgb[2];
    (y + 0.5).clamp(0.0, f32::from(max)) as u16
}

/// Some rows of a Bayer mosaic: its rows `row0..row0 + rows.nrows()` of
/// `height`, sampled in `pattern`.
#[derive(Debug, Clone, Copy)]
pub struct Mosaic<'a> {
    /// The mosaic's samples, rows top-down.
    pub rows: ArrayView2<'a, u16>,
    /// The picture row of the first of `rows`.
    pub row0: usize,
    /// The whole picture's height, rows.
    pub height: usize,
    /// The colour filter pattern of the whole picture.
    pub pattern: Bayer,
}

/// The luminance of rows `rows` of a mosaic, whose [`Mosaic::rows`] hold
/// the row above and below each asked row where the picture has one: row
/// `rows.start + j` goes to `put(j, values)`, values clipped to `max`.
pub fn bayer_luma(
    m: &Mosaic,
    rows: Range<usize>,
    max: u16,
    row_buf: &mut Vec<u16>,
    mut put: impl FnMut(usize, &[u16]),
) {
    let (raw, raw_row0, pattern) = (m.rows, m.row0, m.pattern);
    let w = raw.ncols();
    row_buf.clear();
    row_buf.resize(w, 0);
    let raw_end = raw_row0 + raw.nrows();
    for (j, r) in rows.enumerate() {
        let r_lo = r.saturating_sub(1).max(raw_row0);
        let r_hi = (r + 2).min(m.height).min(raw_end);
        for (c, out) in row_buf.iter_mut().enumerate() {
            let own = pattern.channel(r, c);
            let mut sum = [0f32; 3];
            let mut count = [0u32; 3];
            for rr in r_lo..r_hi {
                for cc in c.saturating_sub(1)..(c + 2).min(w) {
                    let k = pattern.channel(rr, cc);
                    sum[k] += f32::from(raw[[rr - raw_row0, cc]]);
                    count[k] += 1;
                }
            }
            let mut rgb = [0f32; 3];
            for k in 0..3 {
                rgb[k] = if k == own {
                    f32::from(raw[[r - raw_row0, c]])
                } else if count[k] > 0 {
                    sum[k] / count[k] as f32
                } else {
                    // A 1-pixel-wide picture lacks a channel: its own sample.
                    f32::from(raw[[r - raw_row0, c]])
                };
            }
            *out = luma(rgb, max);
        }
        put(j, row_buf);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;

    #[test]
    fn a_grey_scene_stays_grey_and_a_flat_colour_gives_its_luminance() {
        // Every channel 1000: Y = 1000 everywhere, borders included.
        let raw = Array2::from_elem((6, 8), 1000u16);
        let mut got = Vec::new();
        let mut buf = Vec::new();
        let m = |rows, pattern| Mosaic {
            rows,
            row0: 0,
            height: 6,
            pattern,
        };
        bayer_luma(&m(raw.view(), Bayer::Gbrg), 0..6, 4095, &mut buf, |_, r| {
            got.extend_from_slice(r)
        });
        assert!(got.iter().all(|&v| v == 1000), "{got:?}");
        // R = 2000, G = 1000, B = 400 in every cell of an RGGB mosaic.
        let raw = Array2::from_shape_fn((6, 8), |(r, c)| {
            [2000u16, 1000, 400][Bayer::Rggb.channel(r, c)]
        });
        let want = luma([2000.0, 1000.0, 400.0], 4095);
        assert_eq!(want, 1169); // 425.2 + 715.2 + 28.88
        got.clear();
        bayer_luma(&m(raw.view(), Bayer::Rggb), 1..5, 4095, &mut buf, |_, r| {
            got.extend_from_slice(r)
        });
        assert!(got.iter().all(|&v| v == want), "{got:?}");
    }

    #[test]
    fn patterns_place_their_channels() {
        assert_eq!(
            (0..2)
                .flat_map(|r| (0..2).map(move |c| Bayer::Gbrg.channel(r, c)))
                .collect::<Vec<_>>(),
            vec![1, 2, 0, 1]
        );
        assert_eq!(Bayer::Bggr.channel(3, 3), 0);
    }
}
