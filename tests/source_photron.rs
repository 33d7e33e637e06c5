//! The Photron MRAW + CIH(X) reader: the real recording in
//! `../shared/data/real-footage/photron-ball-30kfps/` (SOURCE.md there:
//! Photron Nova S16, 30 000 frames/s, 20 µs, 12-bit packed, 384 × 384,
//! frames 52–66) against the CIHX's values and the 16-bit PNGs of its raw
//! counts beside it; MRAWs of every layout written here by the format's
//! rules and read back; truncated and corrupt files; the commands.

use std::path::{Path, PathBuf};
use std::process::Command;

use dropscope::source::photron::PhotronSource;
use dropscope::source::{open, Frame, FrameSource, OpenOptions};
use ndarray::s;

fn ball_dir() -> PathBuf {
    crate::real_footage("photron-ball-30kfps")
}

fn read_all(src: &mut dyn FrameSource, index: usize) -> Frame {
    let m = src.meta();
    let mut f = Frame::zeros((m.height, m.width));
    src.read_into(index, &mut f).unwrap();
    f
}

/// Frame `number` of the recording as the PNG beside it holds it (raw 12-bit counts).
fn ball_png(number: i64) -> Frame {
    let p = ball_dir().join(format!("frames16/ball_12bit_{number:04}.png"));
    let img = image::open(&p).unwrap().into_luma16();
    Frame::from_shape_fn((img.height() as usize, img.width() as usize), |(r, c)| {
        img.get_pixel(c as u32, r as u32).0[0]
    })
}

#[test]
fn the_real_recording_reads_as_its_cihx_says_and_equals_its_png_frames() {
    let mraw = ball_dir().join("ball_12bit.mraw");
    let mut src = open(&mraw, &OpenOptions::default()).unwrap();
    let m = src.meta().clone();
    assert_eq!(m.format, "mraw");
    assert_eq!((m.width, m.height, m.frame_count), (384, 384, 15));
    // <recordRate>30000</recordRate>, <shutterSpeedNsec>20000</shutterSpeedNsec>.
    assert_eq!(m.fps, 30_000.0);
    assert!(
        (m.exposure_s.unwrap() - 20e-6).abs() < 1e-15,
        "{:?}",
        m.exposure_s
    );
    // <colorInfo><bit>12</bit>, <effectiveBit><depth>12</depth><side>Lower</side>.
    assert_eq!(m.bit_depth, 12);
    // <startFrame>52</startFrame>, <totalFrame>15</totalFrame>.
    assert_eq!(m.first_frame, 52);
    assert_eq!(
        m.frame_numbers.iter().collect::<Vec<_>>(),
        (52..=66).collect::<Vec<i64>>()
    );
    assert!((m.time_s(0).unwrap() - 52.0 / 30_000.0).abs() < 1e-15);
    assert!(m.details.camera.as_deref().unwrap().contains("Nova S16"));
    assert_eq!(
        m.details.side_file,
        Some(ball_dir().join("ball_12bit.cihx"))
    );
    for i in 0..15 {
        let f = read_all(src.as_mut(), i);
        let png = ball_png(52 + i as i64);
        let differ = f.iter().zip(png.iter()).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "frame {i} (number {}): pixels differ", 52 + i);
        // A band of rows, and a copy of the source, read the same rows.
        let mut band = Frame::zeros((7, 384));
        src.read_rows_into(i, 171, &mut band.view_mut()).unwrap();
        assert_eq!(band, f.slice(s![171..178, ..]));
        let mut copy = src.try_clone().unwrap();
        assert_eq!(read_all(copy.as_mut(), i), f);
    }
    // The same recording through its header's path and through its folder.
    for p in [ball_dir().join("ball_12bit.cihx"), ball_dir()] {
        let other = open(&p, &OpenOptions::default()).unwrap();
        assert_eq!(other.meta().path, mraw, "{}", p.display());
        assert_eq!(other.meta().frame_count, 15);
    }
}

// ------------------------------------------------------------ written here

/// A header's values for the writers below.
#[derive(Clone)]
struct Header {
    width: usize,
    height: usize,
    frames: usize,
    start: i64,
    bits: u32,
    effective: u32,
    higher: bool,
    fps: f64,
    shutter_den: u32,
}

fn text_cih(h: &Header) -> String {
    format!(
        "#Camera Information Header\r\nDate : 2016/5/4\r\nCamera Type : FASTCAM SA5 model 7\r\n\
         Record Rate(fps) : {}\r\nShutter Speed(s) : 1/{}\r\nTotal Frame : {}\r\n\
         Start Frame : {}\r\nImage Width : {}\r\nImage Height : {}\r\nColor Type : Mono\r\n\
         Color Bit : {}\r\nFile Format : MRaw\r\nEffectiveBit Depth : {}\r\n\
         EffectiveBit Side : {}\r\nEND\r\n",
        h.fps,
        h.shutter_den,
        h.frames,
        h.start,
        h.width,
        h.height,
        h.bits,
        h.effective,
        if h.higher { "Higher" } else { "Lower" }
    )
}

/// A `.cihx` as Photron writes one: a binary preamble, the XML, binary after it.
fn xml_cihx(h: &Header) -> Vec<u8> {
    let mut b = b"!!! This file can not be edited. !!!".to_vec();
    b.resize(0x100, 0);
    b.extend_from_slice(b"CIHX\x01\x00\x00\x00\x02\x00\x00\x00");
    b.resize(0x13c, 0);
    b.extend_from_slice(
        format!(
            "<?xml version=\"1.0\" encoding=\"utf-8\"?>\r\n<cih>\r\n\
             <imageFileInfo><fileFormat>Mraw</fileFormat></imageFileInfo>\r\n\
             <imageDataInfo><resolution><width>{}</width><height>{}</height></resolution>\
             <colorInfo><type>Mono</type><bit>{}</bit></colorInfo>\
             <effectiveBit><depth>{}</depth><side>{}</side></effectiveBit></imageDataInfo>\r\n\
             <frameInfo><recordedFrame>2000</recordedFrame><totalFrame>{}</totalFrame>\
             <startFrame>{}</startFrame><skipFrame>1</skipFrame></frameInfo>\r\n\
             <recordInfo><recordRate>{}</recordRate><shutterSpeed>{}</shutterSpeed></recordInfo>\r\n\
             <deviceInfo><deviceName>FASTCAM test</deviceName></deviceInfo>\r\n</cih>",
            h.width,
            h.height,
            h.bits,
            h.effective,
            if h.higher { "Higher" } else { "Lower" },
            h.frames,
            h.start,
            h.fps,
            h.shutter_den
        )
        .as_bytes(),
    );
    b.extend_from_slice(b"<3\x1a<3\x1a\x00\xff");
    b
}

/// The frames as an MRAW stores them: rows top-down, frames back to back;
/// 8-bit, 16-bit little-endian (shifted up by `16 − effective` when
/// high-aligned) or 12-bit packed high nibble first across rows.
fn mraw_bytes(h: &Header, frames: &[Frame]) -> Vec<u8> {
    let mut out = Vec::new();
    for f in frames {
        match h.bits {
            8 => out.extend(f.iter().map(|&v| v as u8)),
            16 => {
                let shift = if h.higher { 16 - h.effective } else { 0 };
                for &v in f.iter() {
                    out.extend_from_slice(&(v << shift).to_le_bytes());
                }
            }
            12 => {
                let mut nibbles: Vec<u8> = f
                    .iter()
                    .flat_map(|&v| [(v >> 8) as u8 & 15, (v >> 4) as u8 & 15, v as u8 & 15])
                    .collect();
                if nibbles.len() % 2 == 1 {
                    nibbles.push(0);
                }
                out.extend(nibbles.chunks(2).map(|c| (c[0] << 4) | c[1]));
            }
            _ => unreachable!(),
        }
    }
    out
}

/// Deterministic frames of values below `2^bits` (a 64-bit LCG).
fn test_frames(h: &Header, seed: u64) -> Vec<Frame> {
    let mut x = seed;
    (0..h.frames)
        .map(|_| {
            Frame::from_shape_fn((h.height, h.width), |_| {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((x >> 33) % (1 << h.effective)) as u16
            })
        })
        .collect()
}

#[test]
fn mraws_of_every_layout_and_both_header_forms_read_back_their_values() {
    let dir = tempfile::tempdir().unwrap();
    let base = Header {
        width: 16,
        height: 6,
        frames: 3,
        start: -1,
        bits: 8,
        effective: 8,
        higher: false,
        fps: 5000.0,
        shutter_den: 10000,
    };
    let layouts = [
        base.clone(),
        Header {
            bits: 16,
            effective: 12,
            width: 10,
            height: 4,
            ..base.clone()
        },
        Header {
            bits: 16,
            effective: 12,
            higher: true,
            width: 10,
            height: 4,
            ..base.clone()
        },
        // An odd width: rows of the packed layout start mid-byte.
        Header {
            bits: 12,
            effective: 12,
            width: 7,
            height: 5,
            ..base.clone()
        },
    ];
    for (k, h) in layouts.iter().enumerate() {
        let frames = test_frames(h, 11 + k as u64);
        for xml in [false, true] {
            let stem = format!("rec{k}_{}", if xml { "x" } else { "t" });
            let mraw = dir.path().join(format!("{stem}.mraw"));
            std::fs::write(&mraw, mraw_bytes(h, &frames)).unwrap();
            if xml {
                std::fs::write(dir.path().join(format!("{stem}.cihx")), xml_cihx(h)).unwrap();
            } else {
                std::fs::write(dir.path().join(format!("{stem}.cih")), text_cih(h)).unwrap();
            }
            let what = format!("{stem}: {} bits, {} significant", h.bits, h.effective);
            let mut src = PhotronSource::open(&mraw, &OpenOptions::default()).unwrap();
            let m = src.meta().clone();
            assert_eq!(
                (m.width, m.height, m.frame_count),
                (h.width, h.height, 3),
                "{what}"
            );
            assert_eq!(m.bit_depth as u32, h.effective, "{what}");
            assert_eq!((m.fps, m.first_frame), (5000.0, -1), "{what}");
            assert!((m.exposure_s.unwrap() - 1e-4).abs() < 1e-15, "{what}");
            for (i, want) in frames.iter().enumerate() {
                assert_eq!(&read_all(&mut src, i), want, "{what}: frame {i}");
                for row0 in 0..h.height {
                    for n in 0..=h.height - row0 {
                        let mut band = Frame::zeros((n, h.width));
                        src.read_rows_into(i, row0, &mut band.view_mut()).unwrap();
                        assert_eq!(band, want.slice(s![row0..row0 + n, ..]), "{what}");
                    }
                }
            }
        }
    }
}

#[test]
fn the_real_recording_with_an_old_text_cih_reads_the_same() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(
        ball_dir().join("ball_12bit.mraw"),
        dir.path().join("ball.mraw"),
    )
    .unwrap();
    let h = Header {
        width: 384,
        height: 384,
        frames: 15,
        start: 52,
        bits: 12,
        effective: 12,
        higher: false,
        fps: 30000.0,
        shutter_den: 50000,
    };
    std::fs::write(dir.path().join("ball.cih"), text_cih(&h)).unwrap();
    let mut src = open(&dir.path().join("ball.cih"), &OpenOptions::default()).unwrap();
    let m = src.meta().clone();
    assert_eq!((m.fps, m.first_frame, m.bit_depth), (30000.0, 52, 12));
    assert!((m.exposure_s.unwrap() - 20e-6).abs() < 1e-15);
    assert_eq!(read_all(src.as_mut(), 14), ball_png(66));
}

// ------------------------------------------------------------ damaged files

#[test]
fn a_truncated_mraw_is_an_error_naming_the_file_and_the_frame() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(ball_dir().join("ball_12bit.mraw")).unwrap();
    std::fs::copy(
        ball_dir().join("ball_12bit.cihx"),
        dir.path().join("cut.cihx"),
    )
    .unwrap();
    let frame_bytes = 384 * 384 * 3 / 2;
    let mut cuts: Vec<usize> = (0..40).collect();
    cuts.extend((1..45).map(|k| k * bytes.len() / 45));
    cuts.extend([
        frame_bytes - 1,
        frame_bytes,
        14 * frame_bytes + 1,
        bytes.len() - 1,
    ]);
    for cut in cuts {
        let p = dir.path().join("cut.mraw");
        std::fs::write(&p, &bytes[..cut]).unwrap();
        let msg = match open(&p, &OpenOptions::default()) {
            Ok(_) => panic!("cut at {cut} opened"),
            Err(e) => e.to_string(),
        };
        let frame = cut / frame_bytes;
        assert!(
            msg.contains("cut.mraw")
                && msg.contains(&format!("frame {frame}:"))
                && msg.contains(&format!("image number {}", 52 + frame))
                && msg.contains("truncated"),
            "cut at {cut}: {msg}"
        );
    }
    // A file cut after opening: the read fails naming the file and frame.
    let p = dir.path().join("cut.mraw");
    std::fs::write(&p, &bytes).unwrap();
    let mut src = open(&p, &OpenOptions::default()).unwrap();
    std::fs::write(&p, &bytes[..3 * frame_bytes]).unwrap();
    let mut f = Frame::zeros((384, 384));
    let e = src.read_into(9, &mut f).unwrap_err().to_string();
    assert!(e.contains("cut.mraw") && e.contains("frame 9"), "{e}");
}

#[test]
fn damaged_or_foreign_headers_are_errors_naming_the_header() {
    let dir = tempfile::tempdir().unwrap();
    let cihx = std::fs::read(ball_dir().join("ball_12bit.cihx")).unwrap();
    let mraw = std::fs::read(ball_dir().join("ball_12bit.mraw")).unwrap();
    std::fs::write(dir.path().join("b.mraw"), &mraw).unwrap();
    let p = dir.path().join("b.mraw");
    let err = |header: &[u8]| -> String {
        std::fs::write(dir.path().join("b.cihx"), header).unwrap();
        match open(&p, &OpenOptions::default()) {
            Ok(_) => "opened".into(),
            Err(e) => e.to_string(),
        }
    };
    // Cut anywhere before the end of its XML: an error, never a panic.
    let end = cihx.windows(6).position(|w| w == b"</cih>").unwrap();
    for cut in (0..end).step_by(97).chain([end, end + 1]) {
        let e = err(&cihx[..cut]);
        assert!(e.contains("b.cihx"), "cut at {cut}: {e}");
    }
    // Every occurrence (`<width>` is in imageFileInfo and imageDataInfo).
    let replace = |from: &str, to: &str| {
        let text = String::from_utf8_lossy(&cihx).replace(from, to);
        text.into_bytes()
    };
    let e = err(&replace("<totalFrame>15<", "<totalFrame>16<"));
    assert!(e.contains("b.mraw") && e.contains("frame 15:"), "{e}");
    let e = err(&replace("<width>384</width>", "<width>0</width>"));
    assert!(e.contains("b.cihx") && e.contains("0×384"), "{e}");
    let e = err(&replace("<recordRate>30000<", "<recordRate>abc<"));
    assert!(e.contains("<recordRate> \"abc\" is not a number"), "{e}");
    let e = err(&replace("<recordRate>30000<", "<recordRate>0<"));
    assert!(e.contains("frame rate 0"), "{e}");
    let e = err(&replace("<type>Raw</type>", "<type>Color</type>"));
    assert!(e.contains("unsupported: a colour Photron recording"), "{e}");
    let e = err(&replace("<bit>12</bit>", "<bit>10</bit>"));
    assert!(
        e.contains("unsupported") && e.contains("12-bit packed"),
        "{e}"
    );
    // No header beside the MRAW, no MRAW beside the header.
    std::fs::remove_file(dir.path().join("b.cihx")).unwrap();
    let e = open(&p, &OpenOptions::default()).err().unwrap().to_string();
    assert!(
        e.contains("b.mraw") && e.contains("no .cihx or .cih"),
        "{e}"
    );
    std::fs::write(dir.path().join("lone.cihx"), &cihx).unwrap();
    let e = open(&dir.path().join("lone.cihx"), &OpenOptions::default())
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("lone.cihx") && e.contains("no .mraw"), "{e}");
}

// ------------------------------------------------------------ commands

fn dropscope() -> Command {
    Command::new(env!("CARGO_BIN_EXE_dropscope"))
}

fn ok(out: &std::process::Output) -> String {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn inspect_export_and_process_take_the_mraw_its_header_or_its_folder() {
    let json = ok(&dropscope()
        .args(["inspect", "--json"])
        .arg(ball_dir().join("ball_12bit.cihx"))
        .output()
        .unwrap());
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(v["format"], "mraw");
    assert_eq!(v["fps"], 30000.0);
    assert_eq!(
        (v["frames"].clone(), v["first_frame"].clone()),
        (15.into(), 52.into())
    );
    assert_eq!(
        (v["width"].clone(), v["bit_depth"].clone()),
        (384.into(), 12.into())
    );
    let text = ok(&dropscope().arg("inspect").arg(ball_dir()).output().unwrap());
    assert!(
        text.contains("ball_12bit.mraw") && text.contains("20.000 µs"),
        "{text}"
    );

    let out = tempfile::tempdir().unwrap();
    ok(&dropscope()
        .args(["export", "--numbers", "60:62", "--out"])
        .arg(out.path())
        .arg(ball_dir().join("ball_12bit.mraw"))
        .output()
        .unwrap());
    for (index, number) in [(8, 60), (9, 61)] {
        let p = out.path().join(format!("ball_12bit_{index:02}.png"));
        let img = image::open(&p).unwrap().into_luma16();
        let png = ball_png(number);
        assert!(
            png.indexed_iter()
                .all(|((r, c), &v)| img.get_pixel(c as u32, r as u32).0[0] == v),
            "{}",
            p.display()
        );
    }

    // process reads it (its frame rate from the CIHX) and tracks the ball:
    // it never reaches the substrate in these 15 frames, its bottom ≈ 120 px
    // above the band (SOURCE.md: bottom edge at row ≈ 210 in frame 66, the
    // band's top at row ≈ 330, where the row mean falls from 4095 at 329 to
    // ≈ 1450 at 336); the gap found must lie within 118‥127 px.
    let res = out.path().join("res");
    let o = dropscope()
        .args(["process", "--radius-mm", "1.25", "--no-animation", "--out"])
        .arg(&res)
        .arg(ball_dir().join("ball_12bit.mraw"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_ne!(o.status.code(), Some(2), "{stderr}");
    let rows = std::fs::read_to_string(res.join("drops.csv")).unwrap();
    let row = rows.lines().nth(1).unwrap();
    assert!(
        row.starts_with("ball_12bit,") && row.contains("ball_12bit.mraw"),
        "{row}"
    );
    assert!(
        !row.contains("unsupported") && !row.contains("frame rate"),
        "{row}"
    );
    let gap_px: f64 = row
        .split("closest approach ")
        .nth(1)
        .and_then(|t| t.split(" px").next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("no closest approach in {row}"));
    assert!((118.0..=127.0).contains(&gap_px), "{row}");
}

#[test]
fn a_folder_search_finds_the_mraw_once_and_the_png_sequence() {
    let found = dropscope::job::batch::discover_runs(&[ball_dir()]).unwrap();
    assert_eq!(
        found,
        vec![
            ball_dir().join("ball_12bit.mraw"),
            ball_dir().join("frames16")
        ]
    );
    assert_eq!(
        dropscope::source::input_name(Path::new("x/ball_12bit.cihx")),
        "ball_12bit"
    );
}
