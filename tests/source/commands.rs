//! The `inspect` and `export` commands on cines and folders, and their exit
//! status on bad input.

use super::*;
use std::process::Command;

// ---------------------------------------------------------------- commands

fn dropscope() -> Command {
    Command::new(env!("CARGO_BIN_EXE_dropscope"))
}

#[test]
fn inspect_json_has_the_contract_keys() {
    need!(crate::Need::PhantomSamples);
    let out = dropscope()
        .args(["inspect", "--json"])
        .arg(sample("pims/cine_781.cine"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["frames"], 15);
    assert_eq!(v["width"], 256);
    assert_eq!(v["height"], 256);
    assert_eq!(v["fps"], 9000.0);
    assert_eq!(v["first_frame"], -5417);
    assert_eq!(v["bit_depth"], 12);
    assert_eq!(v["exposure_s"], 10e-6);
    assert_eq!(v["gaps"], serde_json::json!([]));
    let text = dropscope()
        .arg("inspect")
        .arg(sample("pims/cine_781.cine"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(
        text.contains("decimation 10") && text.contains("flip_v true"),
        "{text}"
    );
}

/// `dropscope export --frames FRAMES --out OUT INPUT`, which must succeed.
fn export_frames(input: &Path, frames: &str, out: &Path) {
    let o = dropscope()
        .args(["export", "--frames", frames, "--out"])
        .arg(out)
        .arg(input)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The side file `<name>_frames.csv` an export writes beside its PNGs.
fn exported_frames(csv: &Path) -> Vec<dropscope::cli::inspect::ExportedFrame> {
    csv::Reader::from_path(csv)
        .unwrap()
        .deserialize()
        .map(Result::unwrap)
        .collect()
}

#[test]
fn export_writes_stored_values_as_16_bit_png_named_by_frame_index() {
    need!(crate::Need::PhantomSamples);
    let dir = tempfile::tempdir().unwrap();
    let input = sample("pims/cine_781.cine");
    export_frames(&input, "2:4", dir.path());
    let mut src = open_default(&input).unwrap();
    // 15 frames: indices padded to 2 digits; camera numbers in the side file.
    assert_eq!(src.meta().frame_count, 15);
    for (i, name) in [(2usize, "cine_781_02.png"), (3, "cine_781_03.png")] {
        let img = image::open(dir.path().join(name)).unwrap().into_luma16();
        let f = read_all(src.as_mut(), i);
        for ((r, c), v) in f.indexed_iter() {
            assert_eq!(img.get_pixel(c as u32, r as u32).0[0], *v);
        }
    }
    let rows = exported_frames(&dir.path().join("cine_781_frames.csv"));
    let expect: Vec<(String, usize, i64, f64)> = [2usize, 3]
        .iter()
        .map(|&i| {
            (
                format!("cine_781_0{i}.png"),
                i,
                src.meta().frame_number(i),
                src.meta().time_s(i).unwrap(),
            )
        })
        .collect();
    let got: Vec<_> = rows
        .iter()
        .map(|r| (r.file.clone(), r.index, r.camera_number, r.time_s))
        .collect();
    assert_eq!(got, expect);
    assert_eq!(expect[0].2, -5415);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 3);
    // The exported folder reads back as a sequence numbered by index.
    let opts = OpenOptions {
        fps_fallback: Some(9000.0),
        ..OpenOptions::default()
    };
    let back = open(dir.path(), &opts).unwrap();
    assert_eq!(back.meta().frame_numbers, (2..4).collect());
}

/// Names sort in frame order in a plain listing. 12bpp.cine's camera
/// numbers run -100 … 101: named by them, `12bpp_-098.png` comes before
/// `12bpp_-100.png` by name, after it in frame order. A second export into the
/// folder adds its rows to the side file.
#[test]
fn exported_names_sort_in_frame_order_with_negative_camera_numbers() {
    need!(crate::Need::PhantomSamples);
    let input = sample("cinefiles-jl/12bpp.cine");
    let meta = open_default(&input).unwrap().meta().clone();
    assert_eq!((meta.frame_number(0), meta.frame_count), (-100, 202));
    let dir = tempfile::tempdir().unwrap();
    for frames in ["0:12", "195:"] {
        export_frames(&input, frames, dir.path());
    }
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.ends_with(".png"))
        .collect();
    names.sort();
    assert_eq!(names.len(), 12 + 7);
    assert_eq!(names[0], "12bpp_000.png");
    assert_eq!(names[18], "12bpp_201.png");
    let rows = exported_frames(&dir.path().join("12bpp_frames.csv"));
    let listed: Vec<&str> = rows.iter().map(|r| r.file.as_str()).collect();
    assert_eq!(
        listed, names,
        "the side file lists every file, in name order"
    );
    // Name order is frame order: camera numbers and times increase.
    let indices: Vec<usize> = (0..12).chain(195..202).collect();
    for (r, &i) in rows.iter().zip(&indices) {
        assert_eq!(
            (r.index, r.camera_number, r.time_s),
            (i, meta.frame_number(i), meta.time_s(i).unwrap())
        );
    }
    assert!(rows
        .windows(2)
        .all(|w| w[0].camera_number < w[1].camera_number));
    assert!(rows.windows(2).all(|w| w[0].time_s < w[1].time_s));
}

/// Camera-number ranges as in the file names, a single
/// frame, and 12-bit data scaled to fill 16 bits on request.
#[test]
fn export_takes_camera_numbers_single_frames_and_scales_to_16_bits() {
    need!(crate::Need::PhantomSamples);
    let input = sample("cinefiles-jl/12bpp.cine");
    let src = open_default(&input).unwrap();
    let numbers = src.meta().frame_numbers.clone();
    assert_eq!(src.meta().bit_depth, 12);
    let export = |args: &[&str]| {
        let dir = tempfile::tempdir().unwrap();
        let out = dropscope()
            .arg("export")
            .args(args)
            .arg("--out")
            .arg(dir.path())
            .arg(&input)
            .output()
            .unwrap();
        let mut names: Vec<String> = std::fs::read_dir(dir.path())
            .map(|d| {
                d.flatten()
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .filter(|n| n.ends_with(".png"))
                    .collect()
            })
            .unwrap_or_default();
        names.sort();
        (out, names, dir)
    };
    let first = numbers.first().unwrap();
    let (out, names, _) = export(&["--numbers", &format!("{first}:{}", first + 2)]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(names.len(), 2.min(numbers.len()), "{names:?}");
    let (out, names, dir) = export(&["--numbers", &first.to_string(), "--scale-to-16"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(names.len(), 1, "{names:?}");
    let img = image::open(dir.path().join(&names[0]))
        .unwrap()
        .into_luma16();
    let mut src = open_default(&input).unwrap();
    let f = read_all(src.as_mut(), 0);
    for ((r, c), v) in f.indexed_iter() {
        assert_eq!(img.get_pixel(c as u32, r as u32).0[0], *v << 4);
    }
    let (out, names, _) = export(&["--frames", "0"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(names.len(), 1);
    let (out, _, _) = export(&["--numbers", "99999:100000"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("camera numbers"));
    // Camera numbers given to --frames: pointed to --numbers (clap said
    // "unexpected argument '-1'", or "start "-100" is not an index").
    for arg in [&["--frames", "-100:-90"][..], &["--frames=-100:-90"]] {
        let (out, names, _) = export(arg);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(err.contains("go to --numbers"), "{err}");
        assert!(names.is_empty());
    }
}

#[test]
fn commands_exit_2_naming_the_file_on_bad_input() {
    need!(crate::Need::PhantomSamples);
    // chart1.cine with a colour pattern dropscope does not read (CFA 1,
    // VRI): refused naming the file and the patterns it reads.
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = std::fs::read(sample("pycine/chart1.cine")).unwrap();
    bytes[84 + 808..84 + 812].copy_from_slice(&1u32.to_le_bytes());
    let vri = dir.path().join("vri.cine");
    std::fs::write(&vri, bytes).unwrap();
    let out = dropscope().arg("inspect").arg(&vri).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("vri.cine: unsupported: raw colour cine with CFA 1")
            && err.contains("Bayer patterns CFA 3–6"),
        "{err}"
    );
    let out = dropscope()
        .args(["export", "--frames", "10:20", "--out"])
        .arg(dir.path())
        .arg(sample("cinefiles-jl/cam_1.cine"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("10:20") && err.contains("2 frames"), "{err}");
}
