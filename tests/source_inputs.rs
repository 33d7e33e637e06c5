//! Finding and naming inputs: every recording and frame sequence of a
//! folder tree, a folder holding one recording, frame names whose digits
//! read two ways (the real `wuppertal-drop-120fps/frames`), inputs that are
//! none of what dropscope reads.

use std::path::PathBuf;
use std::process::Command;

use dropscope::source::{open, OpenOptions};

fn dropscope() -> Command {
    Command::new(env!("CARGO_BIN_EXE_dropscope"))
}

fn samples() -> PathBuf {
    crate::phantom_sample("")
}

/// `phantom-samples/cinefiles-jl` holds five cines and, beside four of
/// them, PCC's single-image export of each (`12bpp.tif` + `12bpp.xml` …):
/// the search finds every cine of the tree, and no frame sequence there.
#[test]
fn a_folder_search_finds_every_cine_beside_loose_exports() {
    let found = dropscope::job::batch::discover_runs(&[samples()]).unwrap();
    let names: Vec<String> = found
        .iter()
        .map(|p| p.strip_prefix(samples()).unwrap().display().to_string())
        .collect();
    assert_eq!(
        names,
        [
            "cinefiles-jl/12bpp.cine",
            "cinefiles-jl/8bpp.cine",
            "cinefiles-jl/cam_1.cine",
            "cinefiles-jl/dt_test.cine",
            "cinefiles-jl/packed_10.cine",
            "pims/cine_781.cine",
            "pims/cine_legacy.cine",
            "pycine/chart1.cine",
        ]
    );
    // `process DIR` takes the same runs.
    assert_eq!(
        dropscope::job::batch::expand_inputs(&[samples().join("cinefiles-jl")]).len(),
        5
    );
    // A folder of frames with a cine beside them: both are runs.
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    std::fs::create_dir(&run).unwrap();
    for i in 0..3 {
        std::fs::write(run.join(format!("run_{i:06}.tif")), b"").unwrap();
    }
    std::fs::copy(samples().join("pims/cine_781.cine"), run.join("other.cine")).unwrap();
    assert_eq!(
        dropscope::job::batch::discover_runs(&[dir.path().to_path_buf()]).unwrap(),
        vec![run.clone(), run.join("other.cine")]
    );
}

/// A folder holding one recording (and its PCC export) is read as that
/// recording; a folder holding several names them.
#[test]
fn a_folder_holding_one_cine_reads_as_that_cine() {
    let dir = tempfile::tempdir().unwrap();
    for f in ["cam_1.cine", "cam_1.tif", "cam_1.xml"] {
        std::fs::copy(samples().join("cinefiles-jl").join(f), dir.path().join(f)).unwrap();
    }
    let src = open(dir.path(), &OpenOptions::default()).unwrap();
    let m = src.meta();
    assert_eq!(m.path, dir.path().join("cam_1.cine"));
    assert_eq!(
        (m.format.as_str(), m.frame_count, m.width),
        ("cine", 2, 1280)
    );
    let out = dropscope()
        .args(["inspect", "--json"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        (v["format"].as_str(), v["frames"].as_u64()),
        (Some("cine"), Some(2))
    );
    let out = dropscope()
        .arg("inspect")
        .arg(samples().join("cinefiles-jl"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(
            "5 recordings (12bpp.cine, 8bpp.cine, cam_1.cine, dt_test.cine, packed_10.cine)"
        ),
        "{err}"
    );
}

fn wuppertal() -> PathBuf {
    crate::real_footage("wuppertal-drop-120fps/frames")
}

/// `E_0094_20000000169.bmp`: the lab's run `E_0094_2` and a 10-digit
/// counter (SOURCE.md there: frames 169…, 120 frames/s). Its names end in
/// 11 digits; read whole they made image 20000000169, 1.67·10⁸ s after the
/// trigger. The split is chosen (the 2 and seven zeros are the same in
/// every name), said in a warning and in `inspect`, and the manifest's
/// `number_digits` (or `--number-digits`) takes the other.
#[test]
fn ambiguous_frame_numbers_say_the_split_chosen_and_can_be_set() {
    let opts = |digits| OpenOptions {
        fps_fallback: Some(120.0),
        number_digits: digits,
        ..OpenOptions::default()
    };
    let src = open(&wuppertal(), &opts(None)).unwrap();
    let m = src.meta();
    assert_eq!(m.frame_count, 20);
    assert_eq!((m.first_frame, m.frame_numbers.last()), (169, Some(2999)));
    assert_eq!(m.gaps, vec![(179, 2989)]);
    assert!((m.time_s(0).unwrap() - 169.0 / 120.0).abs() < 1e-12);
    let names = m.details.frame_names.clone().unwrap();
    assert_eq!(
        (names.prefix.as_str(), names.number_digits),
        ("E_0094_2", 10)
    );
    let note = names.note.unwrap();
    assert!(
        note.contains("name \"E_0094_2\" and a 10-digit frame number (169 …)")
            && note.contains("set number_digits = 11"),
        "{note}"
    );
    assert!(m.details.warnings.contains(&note));
    assert!(m.reading_notes().contains(&note));
    // All eleven digits, as asked: no note.
    let whole = open(&wuppertal(), &opts(Some(11))).unwrap();
    assert_eq!(whole.meta().first_frame, 20_000_000_169);
    assert_eq!(
        whole.meta().details.frame_names.as_ref().unwrap().note,
        None
    );
    // The commands.
    let out = dropscope()
        .args(["inspect", "--json", "--fps", "120"])
        .arg(wuppertal())
        .output()
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["name_prefix"], "E_0094_2");
    assert_eq!(v["number_digits"], 10);
    assert_eq!(v["first_frame"], 169);
    let out = dropscope()
        .args(["inspect", "--fps", "120", "--number-digits", "11"])
        .arg(wuppertal())
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("numbers 20000000169 … 20000002999"), "{text}");
    // The manifest column reaches the run: `process` warns about the
    // split once for the row without it, not for the row that sets it.
    let dir = tempfile::tempdir().unwrap();
    let manifest = dir.path().join("runs.csv");
    std::fs::write(
        &manifest,
        format!(
            "run,path,sphere_radius_mm,fps,number_digits\n\
             chosen,{0},3,120,\nset,{0},3,120,11\n",
            wuppertal().display()
        ),
    )
    .unwrap();
    let runs = dropscope::dataset::manifest::read_manifest(&manifest).unwrap();
    assert_eq!(
        runs.iter().map(|r| r.number_digits).collect::<Vec<_>>(),
        vec![None, Some(11)]
    );
    let out = dropscope()
        .args(["process", "--no-animation", "--manifest"])
        .arg(&manifest)
        .arg("--out")
        .arg(dir.path().join("out"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        err.matches("warning: chosen: the frame names").count(),
        1,
        "{err}"
    );
    assert!(!err.contains("warning: set: the frame names"), "{err}");
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "run,path,sphere_radius_mm,number_digits\na,x,3,0\n").unwrap();
    let e = dropscope::dataset::manifest::read_manifest(&bad)
        .unwrap_err()
        .to_string();
    assert!(e.contains("row 2: column `number_digits` = 0"), "{e}");
}

/// What is none of the inputs dropscope reads is refused naming what it
/// reads; a single frame file points to its folder.
#[test]
fn unsupported_inputs_name_what_is_supported() {
    let movie = crate::real_footage("tracker-balltoss/BallTossOut.mov");
    let frame = wuppertal().join("E_0094_20000000169.bmp");
    for (input, says) in [
        (&movie, "(a .mov file)"),
        (
            &frame,
            "(one frame file, give the folder that holds its sequence",
        ),
    ] {
        let out = dropscope().arg("inspect").arg(input).output().unwrap();
        assert_eq!(out.status.code(), Some(2));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(says)
                && err.contains(
                    "dropscope reads a folder of numbered TIFF/PNG/BMP/JPEG frames (as \
                     Phantom Camera Control exports them), a Phantom .cine, or a Photron \
                     .mraw with its .cihx/.cih"
                ),
            "{err}"
        );
    }
}
