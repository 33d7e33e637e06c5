//! TIFF folders: the reader's own path for uncompressed grey strips
//! (`folder.rs`, "fast path") against exact pixel values and against the
//! `image` crate's decoder (the path every other TIFF takes), on the real
//! PCC exports and on hand-made files of both byte orders, one or many
//! strips; and truncated or corrupted TIFFs give errors naming the file,
//! never a panic.

use std::path::{Path, PathBuf};

use dropscope::source::{open, Frame, OpenOptions};
use ndarray::s;

fn sample(rel: &str) -> PathBuf {
    crate::phantom_sample(rel)
}

fn options() -> OpenOptions {
    OpenOptions {
        fps_fallback: Some(1000.0),
        ..OpenOptions::default()
    }
}

/// Frame 0 of the one-file folder `dir`.
fn read_folder(dir: &Path) -> Frame {
    let mut src = open(dir, &options()).unwrap();
    let m = src.meta();
    let mut f = Frame::zeros((m.height, m.width));
    src.read_into(0, &mut f).unwrap();
    f
}

/// A one-file folder holding `bytes` as `f_1.tif`; returns the file's path.
fn one_file_folder(root: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let dir = root.join(name);
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("f_1.tif");
    std::fs::write(&file, bytes).unwrap();
    file
}

/// A minimal uncompressed grey TIFF written by hand: `bits` 8 or 16,
/// strips of `rows_per_strip` rows stored in order after the IFD.
fn tiff_bytes(big_endian: bool, frame: &Frame, bits: u16, rows_per_strip: usize) -> Vec<u8> {
    let (h, w) = frame.dim();
    let u16b = |v: u16| {
        if big_endian {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    };
    let u32b = |v: u32| {
        if big_endian {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    };
    let strips = h.div_ceil(rows_per_strip);
    let row_bytes = w * usize::from(bits / 8);
    let n_entries = 10u16;
    let ifd_end = 8 + 2 + 12 * usize::from(n_entries) + 4;
    let offsets_at = ifd_end;
    let counts_at = offsets_at + 4 * strips;
    let data_at = counts_at + 4 * strips;
    let mut b = Vec::new();
    b.extend_from_slice(if big_endian { b"MM\0*" } else { b"II*\0" });
    b.extend_from_slice(&u32b(8));
    b.extend_from_slice(&u16b(n_entries));
    let short = |tag: u16, v: u16| {
        let mut e = Vec::new();
        e.extend_from_slice(&u16b(tag));
        e.extend_from_slice(&u16b(3));
        e.extend_from_slice(&u32b(1));
        e.extend_from_slice(&u16b(v)); // left-justified in the 4-byte field
        e.extend_from_slice(&[0, 0]);
        e
    };
    let long = |tag: u16, count: u32, v: u32| {
        let mut e = Vec::new();
        e.extend_from_slice(&u16b(tag));
        e.extend_from_slice(&u16b(4));
        e.extend_from_slice(&u32b(count));
        e.extend_from_slice(&u32b(v));
        e
    };
    let strip_rows = |i: usize| rows_per_strip.min(h - i * rows_per_strip);
    let one = strips == 1;
    for e in [
        long(256, 1, w as u32),
        long(257, 1, h as u32),
        short(258, bits),
        short(259, 1),
        short(262, 1),
        long(
            273,
            strips as u32,
            if one {
                data_at as u32
            } else {
                offsets_at as u32
            },
        ),
        short(277, 1),
        long(278, 1, rows_per_strip as u32),
        long(
            279,
            strips as u32,
            if one {
                (h * row_bytes) as u32
            } else {
                counts_at as u32
            },
        ),
        short(284, 1),
    ] {
        b.extend_from_slice(&e);
    }
    b.extend_from_slice(&u32b(0));
    let mut at = data_at;
    for i in 0..strips {
        b.extend_from_slice(&u32b(at as u32));
        at += strip_rows(i) * row_bytes;
    }
    for i in 0..strips {
        b.extend_from_slice(&u32b((strip_rows(i) * row_bytes) as u32));
    }
    assert_eq!(b.len(), data_at);
    for &v in frame.iter() {
        if bits == 8 {
            b.push(v as u8);
        } else {
            b.extend_from_slice(&u16b(v));
        }
    }
    b
}

/// The same pixels PackBits-compressed by the `tiff` crate: a file the
/// reader hands to the `image` crate.
fn packbits_bytes(frame: &Frame, bits: u16) -> Vec<u8> {
    use tiff::encoder::{colortype, Compression, TiffEncoder};
    let mut out = std::io::Cursor::new(Vec::new());
    let mut enc = TiffEncoder::new(&mut out)
        .unwrap()
        .with_compression(Compression::Packbits);
    let (w, h) = (frame.ncols() as u32, frame.nrows() as u32);
    if bits == 8 {
        let data: Vec<u8> = frame.iter().map(|&v| v as u8).collect();
        enc.write_image::<colortype::Gray8>(w, h, &data).unwrap();
    } else {
        let data: Vec<u16> = frame.iter().copied().collect();
        enc.write_image::<colortype::Gray16>(w, h, &data).unwrap();
    }
    out.into_inner()
}

/// The image crate's decode of a TIFF, widened to u16.
fn image_crate(path: &Path) -> Frame {
    let img = image::open(path).unwrap();
    let (w, h) = (img.width() as usize, img.height() as usize);
    let v: Vec<u16> = if img.color().bytes_per_pixel() >= 2 {
        img.into_luma16().into_raw()
    } else {
        img.into_luma8()
            .into_raw()
            .into_iter()
            .map(u16::from)
            .collect()
    };
    Frame::from_shape_vec((h, w), v).unwrap()
}

/// Every PCC export in the samples (16-bit, uncompressed, one strip: the
/// reader's own path) reads exactly as the image crate decodes it.
#[test]
fn real_pcc_tiffs_read_exactly_as_the_image_crate_decodes_them() {
    need!(crate::Need::PhantomSamples);
    let root = tempfile::tempdir().unwrap();
    for name in ["8bpp", "12bpp", "cam_1", "packed_10"] {
        let bytes = std::fs::read(sample(&format!("cinefiles-jl/{name}.tif"))).unwrap();
        let file = one_file_folder(root.path(), name, &bytes);
        let ours = read_folder(file.parent().unwrap());
        let theirs = image_crate(&file);
        assert_eq!(ours.dim(), theirs.dim(), "{name}");
        assert!(ours == theirs, "{name}: pixels differ from the image crate");
        // Not a trivial picture: the comparison could have failed.
        let distinct: std::collections::BTreeSet<u16> = ours.iter().copied().collect();
        assert!(
            distinct.len() > 10,
            "{name}: {} distinct values",
            distinct.len()
        );
    }
}

/// The real cam_1 pixels (1280×800) stored every way: hand-made
/// uncompressed files of both byte orders with one strip and with 7-row
/// strips (800 = 114·7 + 2, so the last strip is short), and PackBits files
/// (the image-crate path); 16-bit and 8-bit (the top byte). Every file reads
/// back the exact pixels, whole and as bands crossing strip boundaries.
#[test]
fn own_path_and_image_crate_path_agree_bit_for_bit() {
    need!(crate::Need::PhantomSamples);
    let root = tempfile::tempdir().unwrap();
    let real = image_crate(&sample("cinefiles-jl/cam_1.tif"));
    let eight = real.mapv(|v| v >> 8);
    for (bits, truth) in [(16u16, &real), (8, &eight)] {
        let mut files = Vec::new();
        for big_endian in [false, true] {
            for rps in [truth.nrows(), 7] {
                let name = format!("b{bits}_be{big_endian}_rps{rps}");
                let bytes = tiff_bytes(big_endian, truth, bits, rps);
                files.push(one_file_folder(root.path(), &name, &bytes));
            }
        }
        let name = format!("b{bits}_packbits");
        files.push(one_file_folder(
            root.path(),
            &name,
            &packbits_bytes(truth, bits),
        ));
        for file in &files {
            let dir = file.parent().unwrap();
            assert!(read_folder(dir) == *truth, "{}", dir.display());
            // The image crate reads the hand-made files the same way.
            assert!(
                image_crate(file) == *truth,
                "image crate: {}",
                dir.display()
            );
            let mut src = open(dir, &options()).unwrap();
            for (r0, n) in [(0, 1), (5, 9), (6, 8), (790, 10), (399, 1)] {
                let mut band = Frame::zeros((n, truth.ncols()));
                src.read_rows_into(0, r0, &mut band.view_mut()).unwrap();
                assert!(
                    band == truth.slice(s![r0..r0 + n, ..]),
                    "{} rows {r0}+{n}",
                    dir.display()
                );
            }
        }
    }
}

/// Open the one-file folder of `file` and read its frame and a band; every
/// error must name the file. Returns whether everything succeeded.
fn open_and_read_naming(file: &Path, what: &str) -> bool {
    let name = file.file_name().unwrap().to_string_lossy().into_owned();
    let check = |e: String| assert!(e.contains(&name), "{what}: message lacks {name}: {e}");
    let mut src = match open(file.parent().unwrap(), &options()) {
        Ok(s) => s,
        Err(e) => {
            check(e.to_string());
            return false;
        }
    };
    let m = src.meta().clone();
    let mut f = Frame::zeros((m.height, m.width));
    if let Err(e) = src.read_into(0, &mut f) {
        check(e.to_string());
        return false;
    }
    let mut band = Frame::zeros((1, m.width));
    if let Err(e) = src.read_rows_into(0, m.height - 1, &mut band.view_mut()) {
        check(e.to_string());
        return false;
    }
    true
}

/// Cut at every length, a TIFF whose pixels end the file cannot be opened
/// and read: the error names the file. Hand-made big-endian and
/// little-endian files of several strips and a real PCC export (the
/// reader's own path), and a PackBits file whose IFD comes last (the
/// image-crate path): no cut of it reads either.
#[test]
fn truncated_tiffs_are_errors_naming_the_file() {
    need!(crate::Need::PhantomSamples);
    let root = tempfile::tempdir().unwrap();
    let frame = Frame::from_shape_fn((20, 6), |(r, c)| (r * 1000 + c * 7) as u16);
    let cases = [
        ("hand_be16", tiff_bytes(true, &frame, 16, 7), true),
        (
            "hand_le8",
            tiff_bytes(false, &frame.mapv(|v| v % 251), 8, 3),
            true,
        ),
        (
            "pcc_12bpp",
            std::fs::read(sample("cinefiles-jl/12bpp.tif")).unwrap(),
            true,
        ),
        ("packbits16", packbits_bytes(&frame, 16), false),
    ];
    for (name, bytes, pixels_last) in cases {
        let mut opened = 0;
        for cut in 0..bytes.len() {
            let file = one_file_folder(root.path(), name, &bytes[..cut]);
            let ok = open_and_read_naming(&file, &format!("{name} cut at {cut}"));
            assert!(
                !(ok && pixels_last),
                "{name} cut at {cut} of {} read",
                bytes.len()
            );
            opened += usize::from(ok);
        }
        if !pixels_last {
            // The tiff crate puts the IFD last: only the full file may read.
            assert_eq!(opened, 0, "{name}");
        }
        let file = one_file_folder(root.path(), name, &bytes);
        assert!(open_and_read_naming(&file, name), "{name} whole");
    }
}

/// Every IFD field (type, count, value) of every entry and every header
/// byte set to values that break it: open and read either work or fail
/// with a message naming the file — never a panic.
#[test]
fn corrupted_tiff_fields_are_errors_naming_the_file() {
    need!(crate::Need::PhantomSamples);
    let root = tempfile::tempdir().unwrap();
    let frame = Frame::from_shape_fn((9, 5), |(r, c)| (r * 300 + c) as u16);
    let cases = [
        ("be16", tiff_bytes(true, &frame, 16, 4)),
        ("le8", tiff_bytes(false, &frame.mapv(|v| v % 256), 8, 9)),
        (
            "pcc_8bpp",
            std::fs::read(sample("cinefiles-jl/8bpp.tif")).unwrap(),
        ),
    ];
    let mut failures = 0;
    for (name, bytes) in cases {
        let big = &bytes[0..2] == b"MM";
        let put = |b: &mut Vec<u8>, at: usize, v: u32, width: usize| {
            let all = if big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            };
            let src = if big {
                &all[4 - width..]
            } else {
                &all[..width]
            };
            b[at..at + width].copy_from_slice(src);
        };
        let read16 = |at: usize| {
            let a = [bytes[at], bytes[at + 1]];
            if big {
                u16::from_be_bytes(a)
            } else {
                u16::from_le_bytes(a)
            }
        };
        let ifd = {
            let a = [bytes[4], bytes[5], bytes[6], bytes[7]];
            (if big {
                u32::from_be_bytes(a)
            } else {
                u32::from_le_bytes(a)
            }) as usize
        };
        let n = usize::from(read16(ifd));
        let len = bytes.len() as u32;
        let values = [
            0u32,
            1,
            2,
            3,
            7,
            0xFFFF,
            0x7FFF_FFFF,
            0xFFFF_FFFF,
            len,
            len - 1,
        ];
        let mut variants: Vec<(String, Vec<u8>)> = Vec::new();
        for e in 0..n {
            let at = ifd + 2 + 12 * e;
            for (field, off, width) in [("type", 2, 2), ("count", 4, 4), ("value", 8, 4)] {
                for &v in &values {
                    let mut b = bytes.clone();
                    put(&mut b, at + off, v, width);
                    variants.push((format!("entry {e} {field} = {v}"), b));
                }
            }
        }
        for at in 0..8 {
            for v in [0u8, 0xFF] {
                let mut b = bytes.clone();
                b[at] = v;
                variants.push((format!("header byte {at} = {v}"), b));
            }
        }
        let mut b = bytes.clone();
        put(&mut b, ifd, 0xFFFF, 2);
        variants.push(("entry count 65535".into(), b));
        for (what, b) in variants {
            let file = one_file_folder(root.path(), name, &b);
            if !open_and_read_naming(&file, &format!("{name}: {what}")) {
                failures += 1;
            }
        }
    }
    // The corruptions do break files: many must have been refused.
    assert!(failures > 100, "only {failures} corrupted files refused");
}
