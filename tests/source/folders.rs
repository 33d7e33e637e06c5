//! Folders of frames: every image format, numbering, gaps and stray files,
//! errors naming the file, TIFF strips, PCC exports and name patterns.

use super::*;
use dropscope::source::folder::FolderSource;
use dropscope::source::frame_decode::{FrameDecoder, ImageKind};

// ---------------------------------------------------------------- folders

/// An 8-bit grey image in the format of the path's extension (image crate).
fn write_gray8(path: &Path, f: &Frame) {
    let img = image::GrayImage::from_fn(f.ncols() as u32, f.nrows() as u32, |x, y| {
        image::Luma([f[[y as usize, x as usize]] as u8])
    });
    img.save(path).unwrap();
}

fn write_tiff16(path: &Path, f: &Frame) {
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(
        f.ncols() as u32,
        f.nrows() as u32,
        |x, y| image::Luma([f[[y as usize, x as usize]]]),
    );
    img.save(path).unwrap();
}

/// A PackBits-compressed 16-bit TIFF (not the uncompressed fast path).
fn write_tiff16_packbits(path: &Path, f: &Frame) {
    use tiff::encoder::{colortype, Compression, TiffEncoder};
    let file = std::fs::File::create(path).unwrap();
    let mut enc = TiffEncoder::new(file)
        .unwrap()
        .with_compression(Compression::Packbits);
    let data: Vec<u16> = f.iter().copied().collect();
    enc.write_image::<colortype::Gray16>(f.ncols() as u32, f.nrows() as u32, &data)
        .unwrap();
}

fn write_png16(path: &Path, f: &Frame) {
    std::fs::write(path, dropscope::cli::inspect::png16(f).unwrap()).unwrap();
}

/// An 8-bit paletted grey BMP, bottom-up, rows padded to 4 bytes.
fn write_bmp8(path: &Path, f: &Frame) {
    let (h, w) = f.dim();
    let stride = w.div_ceil(4) * 4;
    let data_off = 14 + 40 + 1024;
    let size = data_off + stride * h;
    let mut b = Vec::with_capacity(size);
    b.extend_from_slice(b"BM");
    b.extend_from_slice(&(size as u32).to_le_bytes());
    b.extend_from_slice(&[0; 4]);
    b.extend_from_slice(&(data_off as u32).to_le_bytes());
    b.extend_from_slice(&40u32.to_le_bytes());
    b.extend_from_slice(&(w as i32).to_le_bytes());
    b.extend_from_slice(&(h as i32).to_le_bytes());
    b.extend_from_slice(&1u16.to_le_bytes());
    b.extend_from_slice(&8u16.to_le_bytes());
    b.extend_from_slice(&[0; 4]);
    b.extend_from_slice(&((stride * h) as u32).to_le_bytes());
    b.extend_from_slice(&[0; 8]);
    b.extend_from_slice(&256u32.to_le_bytes());
    b.extend_from_slice(&[0; 4]);
    for g in 0..=255u8 {
        b.extend_from_slice(&[g, g, g, 0]);
    }
    for r in (0..h).rev() {
        for c in 0..w {
            b.push(f[[r, c]] as u8);
        }
        b.resize(b.len() + stride - w, 0);
    }
    std::fs::write(path, b).unwrap();
}

/// A PCC-style XML like the real ones: FrameRateDouble, ShutterNs, RealBPP,
/// TIMEBLOCK with one Date/Time pair per frame number.
fn write_pcc_xml(path: &Path, numbers: &[i64], fps: f64, real_bpp: u8) {
    let mut t = String::new();
    for n in numbers {
        // Trigger at 12:00:00.000 000.00; frame n at n/fps seconds.
        let rel_us = (*n as f64 / fps * 1e6).round() as i64;
        let total_us = 12 * 3600 * 1_000_000i64 + rel_us;
        let (s, us) = (
            total_us.div_euclid(1_000_000),
            total_us.rem_euclid(1_000_000),
        );
        t.push_str(&format!(
            "<Date frame=\"{n}\">Mon Jan 06 2020</Date><Time frame=\"{n}\">{:02}:{:02}:{:02}.{:03} {:03}.00</Time>",
            s / 3600,
            s / 60 % 60,
            s % 60,
            us / 1000,
            us % 1000
        ));
    }
    let xml = format!(
        "<?xml version=\"1.0\"?>\n<!-- xml cine header file - Copyright VisionResearch Inc. --><chd>\
         <CineFileHeader><FirstImageNo>{}</FirstImageNo><ImageCount>{}</ImageCount>\
         <TriggerTime><Date>Mon Jan 06 2020</Date><Time>12:00:00.000 000.00</Time></TriggerTime></CineFileHeader>\
         <CameraSetup><FrameRateDouble>{fps}</FrameRateDouble><ShutterNs>20000</ShutterNs>\
         <RealBPP>{real_bpp}</RealBPP><BlackLevel>0</BlackLevel><WhiteLevel>{}</WhiteLevel></CameraSetup>\
         <TIMEBLOCK>{t}</TIMEBLOCK></chd>",
        numbers[0],
        // PCC counts the images exported, first to last: files removed
        // since are gaps, not fewer images.
        numbers[numbers.len() - 1] - numbers[0] + 1,
        (1u32 << real_bpp) - 1
    );
    std::fs::write(path, xml).unwrap();
}

#[test]
fn folders_of_every_format_read_back_their_values() {
    type Writer = fn(&Path, &Frame);
    let formats: &[(&str, u16, Writer)] = &[
        ("tif", 255, write_gray8),
        ("tif", 4095, write_tiff16),
        ("tif", 65535, write_tiff16_packbits),
        ("png", 255, write_gray8),
        ("png", 4095, write_png16),
        ("bmp", 255, write_bmp8),
    ];
    for (k, (ext, max, write)) in formats.iter().enumerate() {
        let dir = tempfile::tempdir().unwrap();
        let (h, w) = (9, 14);
        let frames: Vec<Frame> = (0..3)
            .map(|i| test_frame(h, w, *max, i + 10 * k as u64))
            .collect();
        for (i, f) in frames.iter().enumerate() {
            write(&dir.path().join(format!("run_{:06}.{ext}", i + 1)), f);
        }
        let opts = OpenOptions {
            fps_fallback: Some(5000.0),
            ..OpenOptions::default()
        };
        let mut src = open(dir.path(), &opts).unwrap();
        let m = src.meta().clone();
        assert_eq!(
            (m.frame_count, m.width, m.height, m.first_frame),
            (3, w, h, 1)
        );
        assert_eq!(m.bit_depth, if *max > 255 { 16 } else { 8 }, "{ext} {max}");
        assert_eq!(m.fps, 5000.0);
        for (i, f) in frames.iter().enumerate() {
            assert_eq!(&read_all(src.as_mut(), i), f, "{ext} max {max} frame {i}");
            let mut band = Frame::zeros((4, w));
            src.read_rows_into(i, 3, &mut band.view_mut()).unwrap();
            assert_eq!(band, f.slice(s![3..7, ..]), "{ext} band");
            // A window: its columns read; uncompressed TIFF and BMP rows
            // leave the others as they were (not converted).
            let cols = [0..2, 5..9, 12..14];
            let mut window = Frame::from_elem((4, w), 0xBEEF);
            src.read_window_into(i, 3, &cols, &mut window.view_mut())
                .unwrap();
            let raw = (*ext == "tif" && *max != 65535) || *ext == "bmp";
            for c in 0..w {
                let want = if cols.iter().any(|r| r.contains(&c)) || !raw {
                    f.slice(s![3..7, c]).to_owned()
                } else {
                    ndarray::Array1::from_elem(4, 0xBEEF)
                };
                assert_eq!(window.column(c), want, "{ext} {max} window column {c}");
            }
        }
        // The same bytes decoded from memory (the `folder_frame` fuzz
        // target's path) give the same header, frame and band; cut short,
        // an error naming them.
        let bytes = std::fs::read(dir.path().join(format!("run_000002.{ext}"))).unwrap();
        let kind = ImageKind::from_extension(ext).unwrap();
        let name = Path::new("in-memory.frame");
        let bits = if *max > 255 { 16 } else { 8 };
        let header = FrameDecoder::for_headers().probe_bytes(name, kind, &bytes);
        assert_eq!(header.unwrap(), (w, h, bits), "{ext} {max} from memory");
        let mut dec = FrameDecoder::for_frames();
        let mut got = Frame::zeros((h, w));
        dec.read_rows_from_bytes(name, kind, &bytes, (w, h, bits), 0, &mut got.view_mut())
            .unwrap();
        assert_eq!(got, frames[1], "{ext} {max} frame from memory");
        let mut band = Frame::zeros((4, w));
        dec.read_rows_from_bytes(name, kind, &bytes, (w, h, bits), 3, &mut band.view_mut())
            .unwrap();
        assert_eq!(
            band,
            frames[1].slice(s![3..7, ..]),
            "{ext} band from memory"
        );
        let cut = &bytes[..bytes.len() / 2];
        let e = FrameDecoder::for_headers()
            .probe_bytes(name, kind, cut)
            .and_then(|_| {
                dec.read_rows_from_bytes(name, kind, cut, (w, h, bits), 0, &mut got.view_mut())
            })
            .expect_err(&format!("{ext} {max} cut short was read"))
            .to_string();
        assert!(e.contains("in-memory.frame"), "{ext} {max} cut short: {e}");
    }
}

#[test]
fn jpeg_frames_read_as_the_image_crate_decodes_them() {
    let dir = tempfile::tempdir().unwrap();
    let f = test_frame(16, 16, 255, 3);
    let p = dir.path().join("a_1.jpg");
    write_gray8(&p, &f); // JPEG by extension
    let opts = OpenOptions {
        fps_fallback: Some(100.0),
        ..OpenOptions::default()
    };
    let mut src = FolderSource::open(dir.path(), &opts).unwrap();
    assert_eq!(src.meta().format, "jpeg");
    let got = read_all(&mut src, 0);
    let want = image::open(&p).unwrap().into_luma8();
    for ((r, c), v) in got.indexed_iter() {
        assert_eq!(*v, u16::from(want.get_pixel(c as u32, r as u32).0[0]));
    }
}

#[test]
fn a_folder_with_negative_numbers_a_gap_a_stray_file_and_an_xml() {
    let dir = tempfile::tempdir().unwrap();
    let numbers = [-3i64, -2, -1, 0, 1, 3, 10];
    let frames: Vec<Frame> = numbers
        .iter()
        .map(|&n| test_frame(6, 8, 4095, n as u64))
        .collect();
    for (n, f) in numbers.iter().zip(&frames) {
        // Unpadded numbers, written out of order: must sort numerically.
        write_tiff16(&dir.path().join(format!("drop_{n}.tif")), f);
    }
    std::fs::write(dir.path().join("notes.txt"), "stray").unwrap();
    write_tiff16(&dir.path().join("background.tif"), &frames[0]);
    write_pcc_xml(&dir.path().join("drop.xml"), &numbers, 8000.0, 12);
    let mut src = open_default(dir.path()).unwrap();
    let m = src.meta().clone();
    assert_eq!(m.frame_numbers.iter().collect::<Vec<_>>(), numbers);
    assert_eq!(m.first_frame, -3);
    assert_eq!(m.gaps, vec![(2, 2), (4, 9)]);
    assert_eq!((m.fps, m.bit_depth), (8000.0, 12));
    assert_eq!(m.exposure_s, Some(20e-6));
    assert!(m.details.warnings.iter().any(|w| w.contains("notes.txt")));
    assert!(m
        .details
        .warnings
        .iter()
        .any(|w| w.contains("background.tif")));
    // Times come from the XML by frame number: a gap does not shift time.
    let t = times(&m);
    for (i, n) in numbers.iter().enumerate() {
        assert!(
            (t[i] - *n as f64 / 8000.0).abs() < 1e-6,
            "frame {n}: {}",
            t[i]
        );
        assert!((m.time_s(i).unwrap() - *n as f64 / 8000.0).abs() < 1e-6);
    }
    for (i, f) in frames.iter().enumerate() {
        assert_eq!(&read_all(src.as_mut(), i), f);
    }
}

#[test]
fn folder_errors_name_the_file() {
    // Empty folder.
    let dir = tempfile::tempdir().unwrap();
    let e = open_err(dir.path(), &OpenOptions::default());
    assert!(e.contains("no numbered frames"), "{e}");
    // No frame rate anywhere.
    write_gray8(&dir.path().join("a_1.tif"), &test_frame(4, 4, 255, 1));
    let e = open_err(dir.path(), &OpenOptions::default());
    assert!(e.contains("no frame rate"), "{e}");
    let opts = OpenOptions {
        fps_fallback: Some(1000.0),
        ..OpenOptions::default()
    };
    // Mixed sizes, then mixed depths, a corrupt file, a truncated one: the
    // folder opens (only the first frame's header is read then), and reading
    // the offending frame is an error naming its file and frame, and the
    // first frame's file for a size or depth; the other frames still read.
    let read_err = |index: usize| {
        let mut src = open(dir.path(), &opts).unwrap();
        let mut f = Frame::zeros((4, 4));
        src.read_into(1, &mut f).unwrap();
        let mut band = Frame::zeros((2, 4));
        let e = src
            .read_rows_into(index, 1, &mut band.view_mut())
            .unwrap_err()
            .to_string();
        let whole = src.read_into(index, &mut f).unwrap_err().to_string();
        assert_eq!(e, whole, "a band and the whole frame: the same error");
        e
    };
    write_gray8(&dir.path().join("a_2.tif"), &test_frame(4, 4, 255, 2));
    write_gray8(&dir.path().join("a_3.tif"), &test_frame(5, 4, 255, 3));
    let e = read_err(2);
    assert!(
        e.contains("a_3.tif: frame 2: 4×5 8-bit, but the sequence's first frame")
            && e.contains("a_1.tif is 4×4 8-bit"),
        "{e}"
    );
    write_tiff16(&dir.path().join("a_3.tif"), &test_frame(4, 4, 999, 3));
    let e = read_err(2);
    assert!(
        e.contains("a_3.tif: frame 2: 4×4 16-bit") && e.contains("a_1.tif is 4×4 8-bit"),
        "{e}"
    );
    // A corrupt file.
    std::fs::write(dir.path().join("a_3.tif"), b"II*\0garbage").unwrap();
    let e = read_err(2);
    assert!(e.contains("a_3.tif") && e.contains("frame 2"), "{e}");
    // A truncated file.
    let good = dir.path().join("a_2.tif");
    let bytes = std::fs::read(&good).unwrap();
    std::fs::write(dir.path().join("a_3.tif"), &bytes[..bytes.len() / 2]).unwrap();
    let e = read_err(2);
    assert!(e.contains("a_3.tif") && e.contains("frame 2"), "{e}");
    // A file that goes bad after opening: the read names file and frame.
    std::fs::copy(&good, dir.path().join("a_3.tif")).unwrap();
    let mut src = open(dir.path(), &opts).unwrap();
    std::fs::write(dir.path().join("a_3.tif"), b"not an image").unwrap();
    let mut f = Frame::zeros((4, 4));
    let e = src.read_into(2, &mut f).unwrap_err().to_string();
    assert!(e.contains("a_3.tif") && e.contains("frame 2"), "{e}");
    // A frame file that disappeared after opening.
    std::fs::remove_file(dir.path().join("a_3.tif")).unwrap();
    let e = src.read_into(2, &mut f).unwrap_err().to_string();
    assert!(e.contains("a_3.tif"), "{e}");
}

/// A hand-made 3×4 8-bit TIFF with two strips of two rows stored in reverse
/// order (not contiguous): the fast path must follow StripOffsets.
fn tiff_with_reversed_strips(value: impl Fn(usize, usize) -> u8) -> Vec<u8> {
    let mut b = Vec::new();
    b.extend_from_slice(b"II*\0");
    b.extend_from_slice(&8u32.to_le_bytes());
    let entries: [(u16, u16, u32, u32); 9] = [
        (256, 3, 1, 3),
        (257, 3, 1, 4),
        (258, 3, 1, 8),
        (259, 3, 1, 1),
        (262, 3, 1, 1),
        (273, 4, 2, 122),
        (277, 3, 1, 1),
        (278, 3, 1, 2),
        (279, 4, 2, 130),
    ];
    b.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for (tag, ty, count, v) in entries {
        b.extend_from_slice(&tag.to_le_bytes());
        b.extend_from_slice(&ty.to_le_bytes());
        b.extend_from_slice(&count.to_le_bytes());
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.extend_from_slice(&0u32.to_le_bytes());
    assert_eq!(b.len(), 122);
    for v in [144u32, 138, 6, 6] {
        b.extend_from_slice(&v.to_le_bytes()); // offsets: strip 0 at 144, strip 1 at 138
    }
    for r in [2, 3, 0, 1] {
        for c in 0..3 {
            b.push(value(r, c));
        }
    }
    b
}

#[test]
fn tiff_strips_out_of_order_are_followed() {
    let dir = tempfile::tempdir().unwrap();
    let v = |r: usize, c: usize| (10 * r + c) as u8;
    std::fs::write(dir.path().join("s_1.tif"), tiff_with_reversed_strips(v)).unwrap();
    let opts = OpenOptions {
        fps_fallback: Some(1.0),
        ..OpenOptions::default()
    };
    let mut src = open(dir.path(), &opts).unwrap();
    let f = read_all(src.as_mut(), 0);
    assert_eq!(f, Frame::from_shape_fn((4, 3), |(r, c)| u16::from(v(r, c))));
    // The image crate agrees with the hand-made file.
    let img = image::open(dir.path().join("s_1.tif"))
        .unwrap()
        .into_luma8();
    assert_eq!(img.get_pixel(2, 3).0[0], 32);
    let mut band = Frame::zeros((2, 3));
    src.read_rows_into(0, 1, &mut band.view_mut()).unwrap();
    assert_eq!(band, f.slice(s![1..3, ..]));
}

#[test]
fn a_folder_holding_a_real_pcc_export_reads_its_xml() {
    need!(crate::Need::PhantomSamples);
    // PCC's own first-frame export of 12bpp.cine, named as a sequence file.
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(
        sample("cinefiles-jl/12bpp.tif"),
        dir.path().join("12bpp_-100.tif"),
    )
    .unwrap();
    std::fs::copy(
        sample("cinefiles-jl/12bpp.xml"),
        dir.path().join("12bpp.xml"),
    )
    .unwrap();
    let mut src = open_default(dir.path()).unwrap();
    let m = src.meta().clone();
    assert_eq!((m.frame_count, m.width, m.height), (1, 128, 16));
    assert_eq!((m.first_frame, m.fps), (-100, 10000.0));
    assert!((m.exposure_s.unwrap() - 99e-6).abs() < 1e-12);
    // The XML says RealBPP 12 but the TIFF holds values up to 5440 (scaled
    // to 16 bits by PCC): bit_depth is the container's, with a warning.
    assert_eq!(m.bit_depth, 16);
    assert!(m.details.warnings.iter().any(|w| w.contains("RealBPP 12")));
    // Its time equals the cine's tag-1002 time of image −100 (50 ns).
    let cine = open_default(&sample("cinefiles-jl/12bpp.cine")).unwrap();
    let t_cine = times(cine.meta())[0];
    assert!((times(&m)[0] - t_cine).abs() < 5e-8);
    // Pixels: exactly what the image crate decodes.
    let f = read_all(src.as_mut(), 0);
    let img = image::open(sample("cinefiles-jl/12bpp.tif"))
        .unwrap()
        .into_luma16();
    for ((r, c), v) in f.indexed_iter() {
        assert_eq!(*v, img.get_pixel(c as u32, r as u32).0[0]);
    }
}

/// PCC names a single-image export after its cine, not numbered
/// (`cam_1.tif`, `12bpp.tif`, beside `cam_1.xml`, `12bpp.xml`): `cam_1.tif`
/// is not image 1 by its name, nor is `12bpp.tif` refused for having no
/// number; each is the XML's FirstImageNo, with that
/// image's time (equal to the cine's own time stamp of it) and a warning.
#[test]
fn a_single_image_pcc_export_is_the_image_its_xml_names() {
    need!(crate::Need::PhantomSamples);
    for (name, number) in [("cam_1", 0), ("12bpp", -100), ("packed_10", 0)] {
        let dir = tempfile::tempdir().unwrap();
        for ext in ["tif", "xml"] {
            let file = format!("{name}.{ext}");
            std::fs::copy(
                sample(&format!("cinefiles-jl/{file}")),
                dir.path().join(&file),
            )
            .unwrap();
        }
        let src = open_default(dir.path()).unwrap_or_else(|e| panic!("{name}: {e}"));
        let m = src.meta().clone();
        assert_eq!((m.frame_count, m.first_frame), (1, number), "{name}");
        assert!(
            m.details
                .warnings
                .iter()
                .any(|w| w.contains("single-frame PCC export")
                    && w.contains(&format!("image {number}"))),
            "{name}: {:?}",
            m.details.warnings
        );
        let cine = open_default(&sample(&format!("cinefiles-jl/{name}.cine"))).unwrap();
        let c = cine.meta();
        let at = c.frame_numbers.iter().position(|n| n == number).unwrap();
        let t = m.timestamps_s.as_ref().map(|t| t.get(0).unwrap().unwrap());
        let t_cine = c.timestamps_s.as_ref().map(|t| t.get(at).unwrap().unwrap());
        match (t, t_cine) {
            (Some(t), Some(tc)) => assert!((t - tc).abs() < 5e-8, "{name}: {t} vs {tc}"),
            // packed_10's cine carries no time stamps: its frame number's time.
            (Some(t), None) => assert!((t - number as f64 / m.fps).abs() < 1e-5, "{name}: {t}"),
            other => panic!("{name}: times {other:?}"),
        }
    }
}

/// A folder's files as `<prefix><number>.<ext>` zero-padded to one width:
/// what is held does not grow with the frames; names that are not so
/// (another padding, an extension's case) are kept by index and read.
#[test]
fn a_folders_files_are_a_pattern_and_its_exceptions() {
    let dir = tempfile::tempdir().unwrap();
    let numbers: Vec<i64> = (-3..2000).filter(|n| *n != 7).collect();
    let name = |n: i64| match n {
        -2 => "run_-2.tif".to_string(),
        11 => "run_000011.TIF".to_string(),
        1500 => "run_1500.tif".to_string(),
        n if n < 0 => format!("run_-{:05}.tif", -n),
        n => format!("run_{n:05}.tif"),
    };
    for &n in &numbers {
        let f = Frame::from_elem((2, 4), (n + 3) as u16);
        write_tiff16(&dir.path().join(name(n)), &f);
    }
    let opts = OpenOptions {
        fps_fallback: Some(1000.0),
        ..OpenOptions::default()
    };
    let mut src = FolderSource::open(dir.path(), &opts).unwrap();
    let m = src.meta().clone();
    assert_eq!(m.frame_count, numbers.len());
    assert_eq!(m.frame_numbers.iter().collect::<Vec<_>>(), numbers);
    assert_eq!(m.gaps, vec![(7, 7)]);
    for (i, &n) in numbers.iter().enumerate() {
        assert_eq!(src.file(i), dir.path().join(name(n)), "frame {i}");
    }
    // Three names outside the pattern, two runs of numbers: a few hundred
    // bytes for 2 003 files (a path each before: ~200 kB).
    let held = src.files().heap_bytes() + m.index_heap_bytes();
    assert!(held < 1024, "{held} bytes");
    for i in [0, 1, 10, 14, 1502, numbers.len() - 1] {
        let want = Frame::from_elem((2, 4), (numbers[i] + 3) as u16);
        assert_eq!(read_all(&mut src, i), want, "frame {i}");
    }
}
