//! Colour inputs read as grey luminance: the real raw-Bayer sample
//! `pycine/chart1.cine` (a colour chart, P10, CFA 3) against a reference
//! computed here from its mosaic, decoded here from the file's bytes;
//! interpolated-colour and raw-Bayer cines made from the project's cine
//! writer's grey output; colour frame files.

use std::path::Path;
use std::process::Command;

use dropscope::source::cine_write::{CinePacking, CineSpec, CineWriter};
use dropscope::source::colour::Bayer;
use dropscope::source::{open, ColourInput, Frame, FrameSource, OpenOptions};
use ndarray::s;

fn read_all(src: &mut dyn FrameSource, index: usize) -> Frame {
    let m = src.meta();
    let mut f = Frame::zeros((m.height, m.width));
    src.read_into(index, &mut f).unwrap();
    f
}

/// Frame 0 of a P10 cine's stored samples, decoded here: the offset table
/// (u32 at byte 32), the first image's offset (i64), its annotation size
/// (u32), then 4 samples in 5 bytes, most significant bit first, rows
/// top-down (formats/phantom.md §6–§8.4).
fn p10_mosaic(bytes: &[u8], w: usize, h: usize) -> Frame {
    let le32 = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    let table = le32(32);
    let image = i64::from_le_bytes(bytes[table..table + 8].try_into().unwrap()) as usize;
    let pixels = image + le32(image);
    let mut v = Vec::with_capacity(w * h);
    for g in bytes[pixels..pixels + w * h * 5 / 4].chunks_exact(5) {
        let b: Vec<u16> = g.iter().map(|&x| u16::from(x)).collect();
        v.push((b[0] << 2) | (b[1] >> 6));
        v.push(((b[1] & 0x3F) << 4) | (b[2] >> 4));
        v.push(((b[2] & 0x0F) << 6) | (b[3] >> 2));
        v.push(((b[3] & 0x03) << 8) | b[4]);
    }
    Frame::from_shape_vec((h, w), v).unwrap()
}

/// The channel (0 R, 1 G, 2 B) of a pattern at (r, c), from its name.
fn channel(name: &str, r: usize, c: usize) -> usize {
    let letter = name.as_bytes()[2 * (r % 2) + c % 2];
    match letter {
        b'R' => 0,
        b'G' => 1,
        _ => 2,
    }
}

/// The luminance of a Bayer mosaic by normalised convolution: each
/// channel's samples convolved with a 3 × 3 box and divided by the box
/// convolved with that channel's sample mask (bilinear interpolation, the
/// picture's edges included), a pixel's own channel its sample; then
/// Y = 0.2126 R + 0.7152 G + 0.0722 B, rounded.
fn reference_luma(m: &Frame, pattern: &str) -> Frame {
    let (h, w) = m.dim();
    Frame::from_shape_fn((h, w), |(r, c)| {
        let mut rgb = [0f64; 3];
        for (k, v) in rgb.iter_mut().enumerate() {
            if channel(pattern, r, c) == k {
                *v = f64::from(m[[r, c]]);
                continue;
            }
            let (mut sum, mut mask) = (0.0, 0.0);
            for rr in r.saturating_sub(1)..(r + 2).min(h) {
                for cc in c.saturating_sub(1)..(c + 2).min(w) {
                    let on = f64::from(u8::from(channel(pattern, rr, cc) == k));
                    sum += on * f64::from(m[[rr, cc]]);
                    mask += on;
                }
            }
            *v = sum / mask;
        }
        (0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]).round() as u16
    })
}

/// Mean of the samples of channel `k` in a 60 × 60 window about (x, z).
fn patch_mean(m: &Frame, pattern: &str, (x, z): (usize, usize), k: usize) -> f64 {
    let (mut s, mut n) = (0.0, 0.0);
    for r in z - 30..z + 30 {
        for c in x - 30..x + 30 {
            if channel(pattern, r, c) == k {
                s += f64::from(m[[r, c]]);
                n += 1.0;
            }
        }
    }
    s / n
}

#[test]
fn chart1_reads_as_the_luminance_of_its_bayer_mosaic() {
    let path = crate::phantom_sample("pycine/chart1.cine");
    let mut src = open(&path, &OpenOptions::default()).unwrap();
    let m = src.meta().clone();
    assert_eq!((m.width, m.height, m.bit_depth), (2048, 1080, 10));
    assert_eq!(m.details.colour, Some(ColourInput::Bayer(Bayer::Gbrg)));
    let pattern = "GBRG";
    let mosaic = p10_mosaic(&std::fs::read(&path).unwrap(), 2048, 1080);
    // The pattern is the chart's: the colour checker's blue patch (third
    // row, first column) holds more blue than red, its red patch (third
    // column) more red than blue, its green patch more green than either;
    // and the two green sites of a 2 × 2 cell agree (1 %), which the
    // other diagonal's R and B do not.
    let (blue, green, red) = ((264, 704), (586, 704), (914, 704));
    let mean = |at, k| patch_mean(&mosaic, pattern, at, k);
    assert!(mean(blue, 2) > 1.15 * mean(blue, 0), "blue patch");
    assert!(mean(red, 0) > 1.5 * mean(red, 2), "red patch");
    assert!(
        mean(green, 1) > 1.3 * mean(green, 0).max(mean(green, 2)),
        "green patch"
    );
    for at in [blue, green, red] {
        let (mut g1, mut g2) = (0.0, 0.0);
        for r in (at.1 - 30..at.1 + 30).step_by(2) {
            for c in (at.0 - 30..at.0 + 30).step_by(2) {
                g1 += f64::from(mosaic[[r, c]]);
                g2 += f64::from(mosaic[[r + 1, c + 1]]);
            }
        }
        assert!(
            (g1 / g2 - 1.0).abs() < 0.01,
            "green sites {g1} {g2} at {at:?}"
        );
    }
    // Every pixel is the reference luminance (f32 against f64 rounding:
    // at most 1 count, seldom).
    let want = reference_luma(&mosaic, pattern);
    let got = read_all(src.as_mut(), 0);
    let diffs: Vec<i32> = got
        .iter()
        .zip(want.iter())
        .map(|(a, b)| (i32::from(*a) - i32::from(*b)).abs())
        .collect();
    assert!(
        diffs.iter().all(|&d| d <= 1),
        "max {:?}",
        diffs.iter().max()
    );
    let off = diffs.iter().filter(|&&d| d > 0).count();
    assert!(off * 1000 < diffs.len(), "{off} pixels differ by 1");
    // Bands read alone (their neighbour rows fetched) are the same rows.
    for (row0, n) in [(0, 1), (0, 3), (517, 8), (1077, 3)] {
        let mut band = Frame::zeros((n, 2048));
        src.read_rows_into(0, row0, &mut band.view_mut()).unwrap();
        assert_eq!(band, got.slice(s![row0..row0 + n, ..]), "rows {row0}+{n}");
    }
    let out = Command::new(env!("CARGO_BIN_EXE_dropscope"))
        .args(["inspect", "--json"])
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        (v["colour"].as_str(), v["bayer"].as_str()),
        (Some("bayer"), Some("GBRG"))
    );
}

/// A cine written by the project's writer, then its header edited at the
/// given (offset, bytes).
fn edited_cine(path: &Path, spec: &CineSpec, frames: &[Frame], edits: &[(usize, Vec<u8>)]) {
    let mut w = CineWriter::create(path, spec).unwrap();
    for f in frames {
        w.write_frame(f).unwrap();
    }
    w.finish().unwrap();
    let mut b = std::fs::read(path).unwrap();
    for (at, bytes) in edits {
        b[*at..at + bytes.len()].copy_from_slice(bytes);
    }
    std::fs::write(path, b).unwrap();
}

/// Offsets in a cine of the project's writer (CINEFILEHEADER at 0,
/// BITMAPINFOHEADER at 44, SETUP at 84).
const COMPRESSION: usize = 4;
const BI_WIDTH: usize = 44 + 4;
const BI_BIT_COUNT: usize = 44 + 14;
const IM_WIDTH: usize = 84 + 737;
const CFA: usize = 84 + 808;

fn lcg_frame(h: usize, w: usize, max: u32, seed: u64) -> Frame {
    let mut x = seed;
    Frame::from_shape_fn((h, w), |_| {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((x >> 33) % u64::from(max + 1)) as u16
    })
}

/// Interpolated colour: B G R samples a pixel, 8 or 16 bits each. Written
/// as a grey cine three times as wide (its rows are the BGR rows) and
/// relabelled 24/48-bit colour, width w, CFA 3.
#[test]
fn interpolated_colour_cines_read_as_the_luminance_of_each_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (8, 5);
    for (packing, bits, bit_count, max) in [
        (CinePacking::Gray8, 8u8, 24u16, 255u32),
        (CinePacking::Gray16, 12, 48, 4095),
    ] {
        let wide = lcg_frame(h, 3 * w, max, u64::from(bit_count));
        let path = dir.path().join(format!("bgr{bit_count}.cine"));
        let spec = CineSpec {
            width: 3 * w,
            height: h,
            packing,
            bit_depth: bits,
            frame_count: 1,
            ..CineSpec::default()
        };
        edited_cine(
            &path,
            &spec,
            std::slice::from_ref(&wide),
            &[
                (BI_WIDTH, (w as u32).to_le_bytes().to_vec()),
                (BI_BIT_COUNT, bit_count.to_le_bytes().to_vec()),
                (IM_WIDTH, (w as u16).to_le_bytes().to_vec()),
                (CFA, 3u32.to_le_bytes().to_vec()),
            ],
        );
        let mut src = open(&path, &OpenOptions::default()).unwrap();
        assert_eq!(src.meta().details.colour, Some(ColourInput::Rgb));
        assert_eq!((src.meta().width, src.meta().bit_depth), (w, bits));
        let got = read_all(src.as_mut(), 0);
        for ((r, c), &y) in got.indexed_iter() {
            let (b, g, rd) = (
                f64::from(wide[[r, 3 * c]]),
                f64::from(wide[[r, 3 * c + 1]]),
                f64::from(wide[[r, 3 * c + 2]]),
            );
            let want = (0.2126 * rd + 0.7152 * g + 0.0722 * b).round();
            assert!(
                (f64::from(y) - want).abs() <= 1.0,
                "{bit_count}-bit ({r}, {c}): {y} vs {want}"
            );
        }
    }
}

/// A raw Bayer cine (Compression 2, CFA 4 = RGGB, 12 bits in 16, rows
/// bottom-up) stored with bFlipV = 1: its luminance is the reference's,
/// flipped rows when the flip is applied, and every band reads as the
/// same rows of the whole frame.
#[test]
fn a_raw_bayer_cine_is_read_in_bands_and_flipped_as_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (9, 7);
    let mosaic = lcg_frame(h, w, 4095, 5);
    let path = dir.path().join("bayer.cine");
    let spec = CineSpec {
        width: w,
        height: h,
        packing: CinePacking::Gray16,
        bit_depth: 12,
        frame_count: 1,
        flip_v: true,
        ..CineSpec::default()
    };
    edited_cine(
        &path,
        &spec,
        std::slice::from_ref(&mosaic),
        &[
            (COMPRESSION, 2u16.to_le_bytes().to_vec()),
            (CFA, 4u32.to_le_bytes().to_vec()),
        ],
    );
    let want = reference_luma(&mosaic, "RGGB");
    for apply_flips in [false, true] {
        let opts = OpenOptions {
            apply_flips,
            ..OpenOptions::default()
        };
        let mut src = open(&path, &opts).unwrap();
        assert_eq!(
            src.meta().details.colour,
            Some(ColourInput::Bayer(Bayer::Rggb))
        );
        let want = if apply_flips {
            want.slice(s![..;-1, ..]).to_owned()
        } else {
            want.clone()
        };
        let got = read_all(src.as_mut(), 0);
        assert!(
            got.iter()
                .zip(want.iter())
                .all(|(a, b)| a.abs_diff(*b) <= 1),
            "flips {apply_flips}:\n{got}\n{want}"
        );
        for row0 in 0..h {
            for n in 1..=h - row0 {
                let mut band = Frame::zeros((n, w));
                src.read_rows_into(0, row0, &mut band.view_mut()).unwrap();
                assert_eq!(band, got.slice(s![row0..row0 + n, ..]), "{row0}+{n}");
            }
        }
    }
}

/// Colour frame files (RGB PNG, 8 and 16 bits) are their luminance as the
/// `image` crate computes it, and say they are colour.
#[test]
fn colour_frame_files_are_read_as_their_luminance_and_say_so() {
    for sixteen in [false, true] {
        let dir = tempfile::tempdir().unwrap();
        let mut want = Vec::new();
        for i in 0..3u32 {
            let img = image::RgbImage::from_fn(12, 6, |x, y| {
                image::Rgb([(x * 20) as u8, (y * 40 + i) as u8, ((x + y) * 9) as u8])
            });
            let dynamic = if sixteen {
                image::DynamicImage::ImageRgb16(image::DynamicImage::ImageRgb8(img).into_rgb16())
            } else {
                image::DynamicImage::ImageRgb8(img)
            };
            dynamic
                .save(dir.path().join(format!("rgb_{i:04}.png")))
                .unwrap();
            want.push(if sixteen {
                dynamic.to_luma16().into_raw()
            } else {
                dynamic
                    .to_luma8()
                    .into_raw()
                    .into_iter()
                    .map(u16::from)
                    .collect()
            });
        }
        let opts = OpenOptions {
            fps_fallback: Some(1000.0),
            ..OpenOptions::default()
        };
        let mut src = open(dir.path(), &opts).unwrap();
        assert_eq!(src.meta().details.colour, Some(ColourInput::Rgb));
        for (i, w) in want.iter().enumerate() {
            assert_eq!(read_all(src.as_mut(), i).into_raw_vec_and_offset().0, *w);
        }
        let out = Command::new(env!("CARGO_BIN_EXE_dropscope"))
            .args(["inspect", "--fps", "1000"])
            .arg(dir.path())
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            text.contains("colour        colour (RGB), read as grey luminance"),
            "{text}"
        );
    }
}
