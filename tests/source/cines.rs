//! The cine writer's round trip, cines cut short or corrupted (errors, not
//! panics), rows padded as in a DIB, and a long movie's index.

use super::*;
use dropscope::source::cine_write::{CinePacking, CineSpec, CineWriter};

/// Image `i`'s offset in the offset table of a cine's `bytes`.
fn image_offset(bytes: &[u8], layout: &cine::CineLayout, i: usize) -> usize {
    let at = layout.header.off_image_offsets as usize + 8 * i;
    u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize
}

// ---------------------------------------------------------------- writer

fn write_cine(path: &Path, spec: &CineSpec, frames: &[Frame]) {
    let mut w = CineWriter::create(path, spec).unwrap();
    for f in frames {
        w.write_frame(f).unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn writer_round_trip_is_bit_identical_in_every_format() {
    let dir = tempfile::tempdir().unwrap();
    // Width 6 makes P10/P12L rows start mid-byte.
    for (packing, depth, (w, h)) in [
        (CinePacking::Gray8, 8u8, (12, 5)),
        (CinePacking::Gray16, 12, (16, 7)),
        (CinePacking::Gray16, 14, (8, 3)),
        (CinePacking::Gray16, 16, (4, 4)),
        (CinePacking::P10, 10, (6, 6)),
        (CinePacking::P12L, 12, (6, 5)),
    ] {
        let n = 4;
        let spec = CineSpec {
            width: w,
            height: h,
            frame_count: n,
            packing,
            bit_depth: depth,
            fps: 12_345.0,
            exposure_s: 20e-6,
            first_image_no: -2,
            ..CineSpec::default()
        };
        let max = ((1u32 << depth) - 1) as u16;
        let frames: Vec<Frame> = (0..n)
            .map(|i| Frame::from_shape_vec((h, w), lcg_values(w * h, max, 7 + i as u64)).unwrap())
            .collect();
        let path = dir.path().join(format!("{packing:?}{depth}.cine"));
        write_cine(&path, &spec, &frames);
        let mut src = open_default(&path).unwrap();
        let m = src.meta().clone();
        assert_eq!((m.width, m.height, m.frame_count), (w, h, n));
        assert_eq!((m.bit_depth, m.fps, m.first_frame), (depth, 12_345.0, -2));
        assert!((m.exposure_s.unwrap() - 20e-6).abs() < 1e-12);
        // Time stamps: (first + i)/fps within 1 ns (TIME64 is 2^-32 s and
        // the two flag bits are masked).
        for (i, t) in times(&m).iter().enumerate() {
            assert!((t - (i as f64 - 2.0) / 12_345.0).abs() < 1e-9);
        }
        let exposures = m.details.exposures_s.as_ref().unwrap().to_vec().unwrap();
        for (i, e) in exposures.iter().enumerate() {
            assert!((e - 20e-6).abs() < 1e-9, "frame {i}");
        }
        for (i, f) in frames.iter().enumerate() {
            assert_eq!(&read_all(src.as_mut(), i), f, "{packing:?} frame {i}");
        }
        // Random access backwards, then a band.
        assert_eq!(read_all(src.as_mut(), 0), frames[0]);
        let mut band = Frame::zeros((2, w));
        src.read_rows_into(2, 1, &mut band.view_mut()).unwrap();
        assert_eq!(band, frames[2].slice(s![1..3, ..]));
    }
}

#[test]
fn writer_rejects_what_it_cannot_store() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("x.cine");
    let spec = CineSpec {
        width: 4,
        height: 2,
        frame_count: 1,
        ..CineSpec::default()
    };
    let bad = CineSpec {
        bit_depth: 12,
        ..spec.clone()
    };
    assert!(CineWriter::create(&p, &bad).is_err());
    let mut w = CineWriter::create(&p, &spec).unwrap();
    assert!(w.write_frame(&Frame::from_elem((2, 4), 256)).is_err()); // > 8 bit
    assert!(w.write_frame(&Frame::zeros((2, 5))).is_err());
    drop(w);
    assert!(!p.exists(), "an unfinished writer leaves no file");
    let w = CineWriter::create(&p, &spec).unwrap();
    assert!(w.finish().is_err(), "0 of 1 frames written");
}

#[test]
fn a_cine_past_4_gb_reads_through_64_bit_offsets() {
    use std::io::{Seek, SeekFrom, Write};
    let dir = tempfile::tempdir().unwrap();
    let small = dir.path().join("small.cine");
    let spec = CineSpec {
        width: 8,
        height: 4,
        frame_count: 2,
        packing: CinePacking::Gray16,
        bit_depth: 12,
        ..CineSpec::default()
    };
    let frames: Vec<Frame> = (0..2)
        .map(|i| Frame::from_shape_vec((4, 8), lcg_values(32, 4095, i)).unwrap())
        .collect();
    write_cine(&small, &spec, &frames);
    let bytes = std::fs::read(&small).unwrap();
    let layout = cine::parse_layout(&bytes, bytes.len() as u64).unwrap();
    let table = layout.header.off_image_offsets as usize;
    let record = 8 + 8 * 4 * 2;
    // Sparse file: the header, then frame 1's record moved past 5 GB.
    let far: u64 = 5 << 30;
    let big = dir.path().join("big.cine");
    let mut f = std::fs::File::create(&big).unwrap();
    let mut head = bytes.clone();
    head[table + 8..table + 16].copy_from_slice(&far.to_le_bytes());
    f.write_all(&head).unwrap();
    f.seek(SeekFrom::Start(far)).unwrap();
    let first1 = image_offset(&bytes, &layout, 1);
    f.write_all(&bytes[first1..first1 + record]).unwrap();
    drop(f);
    assert!(std::fs::metadata(&big).unwrap().len() > 4 << 30);
    let mut src = open_default(&big).unwrap();
    assert_eq!(read_all(src.as_mut(), 1), frames[1]);
    assert_eq!(read_all(src.as_mut(), 0), frames[0]);
}

// ---------------------------------------------------------------- robustness

/// Lengths at which to cut a file: the first bytes one by one around the
/// header structures, then ~60 points spread over the rest.
fn cut_points(len: usize) -> Vec<usize> {
    let mut v: Vec<usize> = (0..50).collect();
    v.extend([84, 85, 84 + 141, 84 + 143, 84 + 900, 84 + 5700, 84 + 10400]);
    v.extend((1..60).map(|k| k * len / 60));
    v.extend([len - 1, len - 2]);
    v.retain(|&c| c < len);
    v.sort();
    v.dedup();
    v
}

#[test]
fn every_sample_truncated_anywhere_is_an_error_not_a_panic() {
    need!(crate::Need::PhantomSamples);
    let dir = tempfile::tempdir().unwrap();
    let files = [
        "pims/cine_legacy.cine",
        "pims/cine_781.cine",
        "pycine/chart1.cine",
        "cinefiles-jl/8bpp.cine",
        "cinefiles-jl/12bpp.cine",
        "cinefiles-jl/cam_1.cine",
        "cinefiles-jl/packed_10.cine",
        "cinefiles-jl/dt_test.cine",
    ];
    for file in files {
        let bytes = std::fs::read(sample(file)).unwrap();
        for cut in cut_points(bytes.len()) {
            let p = dir.path().join("cut.cine");
            std::fs::write(&p, &bytes[..cut]).unwrap();
            // Every image lies wholly before the end of the real files, so
            // any cut loses at least part of the last image: open must fail.
            let r = open_default(&p);
            assert!(r.is_err(), "{file} cut at {cut} opened");
            let msg = r.err().unwrap().to_string();
            assert!(
                msg.contains("cut.cine"),
                "message must name the file: {msg}"
            );
        }
    }
}

#[test]
fn corrupted_header_fields_give_errors_not_panics() {
    need!(crate::Need::PhantomSamples);
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(sample("cinefiles-jl/packed_10.cine")).unwrap();
    let legacy = std::fs::read(sample("pims/cine_legacy.cine")).unwrap();
    let table = u32::from_le_bytes(bytes[32..36].try_into().unwrap()) as usize;
    let first_image = u64::from_le_bytes(bytes[table..table + 8].try_into().unwrap()) as usize;
    // (offset, width in bytes, must the result be an error?)
    let fields: &[(usize, usize, bool)] = &[
        (0, 2, true),            // magic
        (2, 2, false),           // Headersize
        (6, 2, true),            // Version
        (20, 4, true),           // ImageCount
        (24, 4, true),           // OffImageHeader
        (28, 4, true),           // OffSetup
        (32, 4, true),           // OffImageOffsets
        (44 + 4, 4, true),       // biWidth
        (44 + 8, 4, true),       // biHeight
        (44 + 14, 2, false),     // biBitCount
        (44 + 16, 4, true),      // biCompression
        (84 + 142, 2, false),    // SETUP.Length
        (84 + 808, 4, false),    // CFA (0x80000000 = a grey head: valid)
        (84 + 896, 4, false),    // RealBPP
        (84 + 10416, 4, false),  // first tagged block size
        (table, 8, true),        // image offset 0
        (first_image, 4, false), // AnnotationSize of image 0
    ];
    let p = dir.path().join("bad.cine");
    for &(off, width, must_fail) in fields {
        for value in [
            0u64,
            1,
            0x7F,
            0xFFFF_FFFF_FFFF_FFFF,
            0x8000_0000,
            0x7FFF_FFFF,
        ] {
            let mut b = bytes.clone();
            b[off..off + width].copy_from_slice(&value.to_le_bytes()[..width]);
            if b == bytes {
                continue;
            }
            std::fs::write(&p, &b).unwrap();
            match open_default(&p) {
                Err(e) => assert!(e.to_string().contains("bad.cine"), "{e}"),
                Ok(mut src) => {
                    let extreme = value != 1 && value != 0x7F;
                    assert!(
                        !(must_fail && extreme),
                        "field at {off} = {value:#x} accepted"
                    );
                    let m = src.meta().clone();
                    let mut f = Frame::zeros((m.height, m.width));
                    for i in 0..m.frame_count {
                        let _ = src.read_into(i, &mut f);
                    }
                }
            }
        }
    }
    // The old SETUP: a Length that claims more than the header region holds.
    let mut b = legacy.clone();
    b[84 + 142..84 + 144].copy_from_slice(&60000u16.to_le_bytes());
    std::fs::write(&p, &b).unwrap();
    assert!(open_default(&p).is_err());
}

#[test]
fn eight_bit_rows_padded_to_4_bytes_are_read() {
    // A 6-pixel-wide 8-bit cine whose rows are padded to 8 bytes (DIB rule),
    // announced by biSizeImage = 8 × height.
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("plain.cine");
    let (w, h) = (6usize, 3usize);
    let spec = CineSpec {
        width: w,
        height: h,
        frame_count: 1,
        ..CineSpec::default()
    };
    let frame = test_frame(h, w, 255, 5);
    write_cine(&plain, &spec, std::slice::from_ref(&frame));
    let bytes = std::fs::read(&plain).unwrap();
    let layout = cine::parse_layout(&bytes, bytes.len() as u64).unwrap();
    let start = image_offset(&bytes, &layout, 0);
    let mut b = bytes[..start].to_vec();
    b[44 + 20..44 + 24].copy_from_slice(&((8 * h) as u32).to_le_bytes());
    b.extend_from_slice(&8u32.to_le_bytes());
    b.extend_from_slice(&((8 * h) as u32).to_le_bytes());
    for r in (0..h).rev() {
        b.extend(frame.row(r).iter().map(|&v| v as u8));
        b.extend_from_slice(&[0xEE, 0xEE]);
    }
    let padded = dir.path().join("padded.cine");
    std::fs::write(&padded, &b).unwrap();
    let mut src = open_default(&padded).unwrap();
    assert_eq!(read_all(src.as_mut(), 0), frame);
}

// ---------------------------------------------- a long movie's index

/// The tag-1002 time (s after the trigger) and tag-1003 exposure (s) of
/// every frame of a cine, decoded from its bytes as the tables were.
fn cine_tables(bytes: &[u8], layout: &cine::CineLayout) -> (Vec<f64>, Vec<f64>) {
    let n = layout.header.image_count as usize;
    let u32_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
    let (t, e) = (
        layout.times_at.unwrap() as usize,
        layout.exposures_at.unwrap() as usize,
    );
    let times = (0..n)
        .map(|i| {
            dropscope::source::index::Time64 {
                fractions: u32_at(t + 8 * i),
                seconds: u32_at(t + 8 * i + 4),
            }
            .seconds_since(layout.header.trigger_time)
        })
        .collect();
    let exposures = (0..n)
        .map(|i| f64::from(u32_at(e + 4 * i)) / 4_294_967_296.0)
        .collect();
    (times, exposures)
}

/// A cine of 300 000 frames holds an index of a few bytes, not 36 a frame:
/// its numbers are one run, its times and exposures are read from the file
/// when looked up (the same bits as the tables were), its image offsets a
/// block at a time.
#[test]
fn a_long_cines_index_is_a_few_bytes_and_looks_up_as_its_tables() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("long.cine");
    let n = 300_000;
    let spec = CineSpec {
        width: 4,
        height: 4,
        frame_count: n,
        fps: 60_000.0,
        exposure_s: 10e-6,
        first_image_no: -1000,
        ..CineSpec::default()
    };
    let mut w = CineWriter::create(&path, &spec).unwrap();
    for i in 0..n {
        w.write_frame(&Frame::from_elem((4, 4), (i % 251) as u16))
            .unwrap();
    }
    w.finish().unwrap();
    let mut src = open_default(&path).unwrap();
    let m = src.meta().clone();
    assert_eq!(m.frame_count, n);
    // 36 bytes a frame before (10.8 MB here).
    assert!(
        m.index_heap_bytes() <= 256,
        "{} bytes",
        m.index_heap_bytes()
    );
    let bytes = std::fs::read(&path).unwrap();
    let layout = cine::parse_layout(&bytes, bytes.len() as u64).unwrap();
    let (want_t, exposures) = cine_tables(&bytes, &layout);
    for (i, t) in want_t.iter().enumerate() {
        assert_eq!(m.time_s(i).unwrap().to_bits(), t.to_bits(), "frame {i}");
        assert_eq!(m.frame_number(i), i as i64 - 1000);
    }
    assert_eq!(times(&m), want_t);
    let e = m.details.exposures_s.as_ref().unwrap();
    assert_eq!(e.to_vec().unwrap(), exposures);
    assert_eq!(e.get(n - 1).unwrap(), Some(exposures[n - 1]));
    // Frames anywhere, in any order, on clones too.
    let mut clone = src.try_clone().unwrap();
    for i in [n - 1, 0, 4095, 4096, 4097, 150_001, 8191] {
        let want = Frame::from_elem((4, 4), (i % 251) as u16);
        assert_eq!(read_all(src.as_mut(), i), want, "frame {i}");
        assert_eq!(read_all(clone.as_mut(), i), want, "frame {i}");
    }
}

/// What is read of a cine's index when looked up fails, if the file was cut
/// short after it was opened, with an error naming the file and the frame.
#[test]
fn a_cine_cut_after_opening_fails_its_lookups_naming_file_and_frame() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cut.cine");
    let n = 10_000;
    let spec = CineSpec {
        width: 4,
        height: 4,
        frame_count: n,
        ..CineSpec::default()
    };
    let mut w = CineWriter::create(&path, &spec).unwrap();
    for _ in 0..n {
        w.write_frame(&Frame::from_elem((4, 4), 9)).unwrap();
    }
    w.finish().unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let layout = cine::parse_layout(&bytes, bytes.len() as u64).unwrap();
    let mut src = open_default(&path).unwrap();
    // Cut in the middle of the time stamps: later times, the offsets and
    // the pixels are gone.
    let cut = layout.times_at.unwrap() + 8 * 5000;
    std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .unwrap()
        .set_len(cut)
        .unwrap();
    // On a thread that has read none of it yet (each keeps a few blocks).
    let m = src.meta().clone();
    let e = std::thread::spawn(move || m.time_s(9000).unwrap_err().to_string())
        .join()
        .unwrap();
    assert!(
        e.contains("cut.cine") && e.contains("frame 9000") && e.contains("tag 1002"),
        "{e}"
    );
    let mut f = Frame::zeros((4, 4));
    let e = src.read_into(9001, &mut f).unwrap_err().to_string();
    assert!(e.contains("cut.cine") && e.contains("frame 9001"), "{e}");
    // Opened now, the cut table is an error naming the file.
    let e = open_err(&path, &OpenOptions::default());
    assert!(e.contains("cut.cine") && e.contains("truncated"), "{e}");
}
