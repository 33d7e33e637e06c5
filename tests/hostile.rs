//! Hostile and damaged input: each case is made here from a
//! fixture drop or written from scratch, and must give a clear error, a
//! warning with its flag, or a failed row — never a panic, a hang, a
//! write outside the output folder, or a wrong number marked ok.

use dropscope::config::{PipelineConfig, EMBEDDED_DEFAULT};
use dropscope::dataset::manifest::{read_manifest, RunSpec};
use dropscope::dataset::{read_csv, DropRecord, DropStatus};
use dropscope::job::run_outputs::process_all;
use dropscope::source::cine_write::{CinePacking, CineSpec, CineWriter};
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn config() -> PipelineConfig {
    PipelineConfig::from_toml_str(EMBEDDED_DEFAULT, Path::new("pipeline.toml"), &root()).unwrap()
}

const DROP: &str = "R4.5mm_H12cm_01";

/// A copy of the fixture drop R4.5mm_H12cm_01 in `dir/name`, its XML
/// passed through `edit`, without the frames numbered in `drop_frames`.
fn variant(
    dir: &Path,
    name: &str,
    edit: impl Fn(String) -> String,
    drop_frames: &[i64],
) -> PathBuf {
    let from = root().join("fixtures").join(DROP);
    let to = dir.join(name);
    std::fs::create_dir_all(&to).unwrap();
    for e in std::fs::read_dir(&from).unwrap() {
        let p = e.unwrap().path();
        let file = p.file_name().unwrap().to_str().unwrap().to_string();
        if file.ends_with(".xml") {
            let text = std::fs::read_to_string(&p).unwrap();
            std::fs::write(to.join(&file), edit(text)).unwrap();
        } else if !drop_frames
            .iter()
            .any(|n| file == format!("{DROP}_{}.png", frame_number(*n)))
        {
            std::fs::copy(&p, to.join(&file)).unwrap();
        }
    }
    to
}

fn frame_number(n: i64) -> String {
    if n < 0 {
        format!("-{:06}", -n)
    } else {
        format!("{n:06}")
    }
}

/// The text of every `<Time frame="N">` of the TIMEBLOCK, in file order.
fn times(xml: &str) -> Vec<(i64, String)> {
    let block = &xml[xml.find("<TIMEBLOCK>").unwrap()..];
    block
        .split("<Time frame=\"")
        .skip(1)
        .map(|s| {
            let (n, rest) = s.split_once("\">").unwrap();
            (
                n.parse().unwrap(),
                rest.split('<').next().unwrap().to_string(),
            )
        })
        .collect()
}

/// `xml` with the TIMEBLOCK times replaced by `new` (frame, text).
fn with_times(xml: &str, new: &[(i64, String)]) -> String {
    let mut out = xml.to_string();
    for ((n, old), (_, t)) in times(xml).iter().zip(new) {
        let from = format!("<Time frame=\"{n}\">{old}</Time>");
        let to = format!("<Time frame=\"{n}\">{t}</Time>");
        out = out.replacen(&from, &to, 1);
    }
    out
}

/// A PCC time `HH:MM:SS.mmm uuu.uu` moved by `ds` seconds.
fn shift(time: &str, ds: f64) -> String {
    let (hms, micro) = time.split_once(' ').unwrap();
    let mut p = hms.split(':');
    let h: f64 = p.next().unwrap().parse().unwrap();
    let m: f64 = p.next().unwrap().parse().unwrap();
    let s: f64 = p.next().unwrap().parse().unwrap();
    let us: f64 = micro.parse().unwrap();
    let total_us = ((h * 3600.0 + m * 60.0 + s) * 1e6 + us + ds * 1e6).round() as i64;
    let (ms_total, us) = (total_us / 1000, total_us % 1000);
    let (s_total, ms) = (ms_total / 1000, ms_total % 1000);
    format!(
        "{:02}:{:02}:{:02}.{ms:03} {us:03}.00",
        s_total / 3600,
        s_total / 60 % 60,
        s_total % 60
    )
}

fn spec(run: &str, path: &Path) -> RunSpec {
    RunSpec {
        run: run.into(),
        path: path.to_path_buf(),
        sphere_radius_mm: 4.5,
        drop_height_cm: None,
        fps: None,
        mm_per_px: None,
        surface: None,
        sphere_density_kg_m3: None,
        setup: None,
        review: Default::default(),
        number_digits: None,
    }
}

/// A small grey cine of `n` frames that the reader accepts, with `edit`
/// applied to its spec, then `patch` to its bytes.
fn cine(path: &Path, edit: impl Fn(&mut CineSpec), patch: impl Fn(&mut Vec<u8>)) {
    let mut s = CineSpec {
        width: 32,
        height: 24,
        frame_count: 20,
        packing: CinePacking::Gray8,
        bit_depth: 8,
        fps: 10_000.0,
        exposure_s: 50e-6,
        first_image_no: -5,
        trigger_unix_s: 1_560_420_000,
        timestamps_s: None,
        flip_v: false,
        camera_version: 7,
    };
    edit(&mut s);
    let mut w = CineWriter::create(path, &s).unwrap();
    let frame = dropscope::source::Frame::from_elem((24, 32), 200);
    for _ in 0..s.frame_count {
        w.write_frame(&frame).unwrap();
    }
    w.finish().unwrap();
    let mut bytes = std::fs::read(path).unwrap();
    patch(&mut bytes);
    std::fs::write(path, bytes).unwrap();
}

/// Offset of the SETUP block of a cine (CINEFILEHEADER.OffSetup).
fn setup(bytes: &[u8]) -> usize {
    u32::from_le_bytes(bytes[28..32].try_into().unwrap()) as usize
}

fn by<'a>(rows: &'a [DropRecord], run: &str) -> &'a DropRecord {
    rows.iter().find(|r| r.run == run).unwrap()
}

/// Corrupt frame times, frame rates and exposures, in PCC folders and in
/// cines: each run fails with the file and the problem named, beside a
/// good run that is measured. Unchecked, the reversed times panic
/// (`f64::clamp`, exit 101, no drops.csv) and the exposures give
/// δmax = 1.7e6 mm with status ok.
#[test]
fn corrupt_times_rates_and_exposures_fail_their_run_only() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let [reversed, garbled, jittered, long_exposure, nan_rate, zero_rate, deep] =
        corrupt_side_files(d);
    let [cine_reversed, cine_exposure, cine_rate, cine_decimation] = corrupt_cines(d);
    let runs = vec![
        spec("good", &root().join("fixtures").join(DROP)),
        spec("reversed", &reversed),
        spec("garbled", &garbled),
        spec("jittered", &jittered),
        spec("long_exposure", &long_exposure),
        spec("nan_rate", &nan_rate),
        spec("zero_rate", &zero_rate),
        spec("deep_xml", &deep),
        spec("cine_reversed", &cine_reversed),
        spec("cine_exposure", &cine_exposure),
        spec("cine_rate", &cine_rate),
        spec("cine_decimation", &cine_decimation),
    ];
    let out = d.join("out");
    let rows = process_all(&runs, &config(), &out, &|_| {}).unwrap();
    assert_eq!(by(&rows, "good").status, DropStatus::Ok);
    assert_each_corrupt_run_failed_naming_its_file(&rows);
    // drops.csv is written, with every row.
    assert_eq!(read_csv(&out.join("drops.csv")).unwrap().len(), runs.len());
}

/// Copies of the fixture drop whose PCC side file holds corrupt frame times,
/// an exposure longer than a frame, a frame rate of NaN or 0, or elements
/// nested 100 000 deep: their folders, in that order.
fn corrupt_side_files(d: &Path) -> [PathBuf; 7] {
    let reversed = variant(
        d,
        "reversed",
        |x| {
            let mut t = times(&x);
            let vals: Vec<String> = t.iter().rev().map(|p| p.1.clone()).collect();
            for (p, v) in t.iter_mut().zip(vals) {
                p.1 = v;
            }
            with_times(&x, &t)
        },
        &[],
    );
    let garbled = variant(
        d,
        "garbled",
        |x| {
            let mut t = times(&x);
            t[40].1 = "10:00:61.000 000.00".into();
            with_times(&x, &t)
        },
        &[],
    );
    // Three frame times jittered by 0.1–1 ms (the 260 s fit with n = 106).
    let jittered = variant(
        d,
        "jittered",
        |x| {
            let mut t = times(&x);
            for (k, ds) in [(32, 0.1e-3), (36, -0.6e-3), (41, 1e-3)] {
                t[k].1 = shift(&t[k].1, ds);
            }
            with_times(&x, &t)
        },
        &[],
    );
    let long_exposure = variant(
        d,
        "long_exposure",
        |x| x.replace("<ShutterNs>50000<", "<ShutterNs>1000000000000<"),
        &[],
    );
    let nan_rate = variant(
        d,
        "nan_rate",
        |x| x.replace("<FrameRateDouble>10000<", "<FrameRateDouble>NaN<"),
        &[],
    );
    let zero_rate = variant(
        d,
        "zero_rate",
        |x| x.replace("<FrameRateDouble>10000<", "<FrameRateDouble>0<"),
        &[],
    );
    // 100 000 nested elements overflowed the XML parser's stack.
    let deep = variant(
        d,
        "deep_xml",
        |x| {
            x.replace(
                "</chd>",
                &format!("{}{}</chd>", "<a>".repeat(100_000), "</a>".repeat(100_000)),
            )
        },
        &[],
    );
    [
        reversed,
        garbled,
        jittered,
        long_exposure,
        nan_rate,
        zero_rate,
        deep,
    ]
}

/// Cines with times running backwards, a 4 s exposure, a frame rate of
/// 1e300 and a save decimation of 1e-30: their paths, in that order.
fn corrupt_cines(d: &Path) -> [PathBuf; 4] {
    let cine_reversed = d.join("reversed.cine");
    cine(
        &cine_reversed,
        |s| s.timestamps_s = Some((0..20).map(|i| -(i as f64) * 1e-4).collect()),
        |_| {},
    );
    let cine_exposure = d.join("exposure.cine");
    cine(
        &cine_exposure,
        |_| {},
        |b| {
            // SETUP.ShutterNs: 4 s (the writer refuses it).
            let o = setup(b) + 1568;
            b[o..o + 4].copy_from_slice(&4_000_000_000u32.to_le_bytes());
        },
    );
    let cine_rate = d.join("rate.cine");
    cine(
        &cine_rate,
        |_| {},
        |b| {
            let o = setup(b) + 10400;
            b[o..o + 8].copy_from_slice(&1e300f64.to_le_bytes());
        },
    );
    let cine_decimation = d.join("decimation.cine");
    cine(
        &cine_decimation,
        |_| {},
        |b| {
            let o = setup(b) + 10388;
            b[o..o + 4].copy_from_slice(&1e-30f32.to_le_bytes());
        },
    );
    [cine_reversed, cine_exposure, cine_rate, cine_decimation]
}

/// Every corrupt run failed, naming its file and what is wrong in it, with
/// no numbers.
fn assert_each_corrupt_run_failed_naming_its_file(rows: &[DropRecord]) {
    let xml = format!("{DROP}.xml");
    for (run, file, says) in [
        ("reversed", "reversed", "frame -29: time stamp"),
        ("reversed", "reversed", "the frame times must increase"),
        ("garbled", &xml, "TIMEBLOCK frame=10"),
        ("jittered", "jittered", "corrupt time block"),
        (
            "long_exposure",
            "long_exposure",
            "exposure 1000.0000000000001 s is not within 0 and the frame interval 0.0001 s",
        ),
        ("nan_rate", &xml, "<FrameRateDouble> holds NaN"),
        ("zero_rate", &xml, "<FrameRateDouble> holds 0"),
        ("deep_xml", &xml, "nested more than 64 deep"),
        ("cine_reversed", "reversed.cine", "frame -4: time stamp"),
        ("cine_exposure", "exposure.cine", "exposure 4 s"),
        ("cine_rate", "rate.cine", "frame rate 1e300 frames/s"),
        (
            "cine_decimation",
            "decimation.cine",
            "save decimation 1.0000000031710769e-30",
        ),
    ] {
        let r = by(rows, run);
        assert_eq!(r.status, DropStatus::Failed, "{run}: {}", r.reason);
        assert!(
            r.reason.contains(file) && r.reason.contains(says),
            "{run}: {}",
            r.reason
        );
        assert!(r.delta_max_mm.is_none());
    }
}

/// A manifest run named `../../x` is refused naming the row, and nothing is
/// written (or deleted) outside the output folder; a run name that reaches
/// the library anyway fails its row and writes nothing.
#[test]
fn a_run_name_with_dot_dot_writes_nothing_outside_the_output_folder() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let work = d.join("a/b");
    std::fs::create_dir_all(&work).unwrap();
    // What a failing run named ../../x must not delete: <out>/tracks/../../x.csv.
    let victim = work.join("x.csv");
    std::fs::write(&victim, b"keep me").unwrap();
    let manifest = work.join("runs.csv");
    std::fs::write(
        &manifest,
        format!(
            "run,path,sphere_radius_mm\n../../x,{},4.5\n",
            root().join("fixtures").join(DROP).display()
        ),
    )
    .unwrap();
    let e = read_manifest(&manifest).unwrap_err().to_string();
    assert!(
        e.contains("runs.csv: row 2: column `run`") && e.contains("path separator"),
        "{e}"
    );
    let before = listing(d);
    let out = work.join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_dropscope"))
        .args(["process", "--manifest"])
        .arg(&manifest)
        .arg("--out")
        .arg(&out)
        .current_dir(&work)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("path separator"));
    assert_eq!(listing(d), before, "the refused job wrote or deleted files");

    // Through the library: the run fails and writes nothing, the other runs go on.
    let failing = d.join("empty");
    std::fs::create_dir(&failing).unwrap();
    let runs = [
        spec("../../x", &failing),
        spec("..", &failing),
        spec("good", &root().join("fixtures").join(DROP)),
    ];
    let rows = process_all(&runs, &config(), &out, &|_| {}).unwrap();
    assert_eq!(std::fs::read(&victim).unwrap(), b"keep me");
    for r in &rows[..2] {
        assert_eq!(r.status, DropStatus::Failed);
        assert!(r.reason.contains("run name"), "{}", r.reason);
    }
    assert_eq!(rows[2].status, DropStatus::Ok);
    let outside: Vec<String> = listing(d)
        .into_iter()
        .filter(|p| !p.starts_with("a/b/out") && !p.starts_with("empty"))
        .collect();
    assert_eq!(outside, before, "files appeared outside the output folder");
}

fn listing(dir: &Path) -> Vec<String> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(p) = stack.pop() {
        for e in std::fs::read_dir(&p).unwrap() {
            let e = e.unwrap().path();
            if e.is_dir() {
                stack.push(e.clone());
            }
            out.push(e.strip_prefix(dir).unwrap().display().to_string());
        }
    }
    out.sort();
    out
}

/// A named pipe given as a `.cine` or named like a frame never blocks: the
/// cine is refused as not a regular file, the pipe in a folder is passed over.
#[cfg(unix)]
#[test]
fn named_pipes_are_not_opened() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fifo = |p: &Path| {
        let c = std::ffi::CString::new(p.to_str().unwrap()).unwrap();
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o644) }, 0);
    };
    fifo(&d.join("pipe.cine"));
    let folder = variant(d, "with_pipe", |x| x, &[40]);
    fifo(&folder.join(format!("{DROP}_000040.png")));
    let runs = [
        spec("pipe", &d.join("pipe.cine")),
        spec("with_pipe", &folder),
    ];
    let rows = process_all(&runs, &config(), &d.join("out"), &|_| {}).unwrap();
    let r = by(&rows, "pipe");
    assert_eq!(r.status, DropStatus::Failed);
    assert!(r.reason.contains("pipe.cine") && r.reason.contains("not a regular file"));
    // Frame 40 is in flight after the rebound: measured without it.
    let r = by(&rows, "with_pipe");
    assert_ne!(r.status, DropStatus::Failed, "{}", r.reason);
    let o = Command::new(env!("CARGO_BIN_EXE_dropscope"))
        .arg("inspect")
        .arg(&folder)
        .arg("--json")
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("not regular files") && text.contains("_000040.png"),
        "{text}"
    );
}

/// What weakens a measurement is flagged, with status `warning` and a
/// reason, never `ok`: frames 10–19 of a drop deleted (the contact's middle:
/// δmax comes out 0.8 % off, which must not pass as ok), a movie starting
/// 7 frames before contact, a background clipped at white, a manifest
/// scale 5 % off and a manifest fps that contradicts the file. An
/// unrelated non-UTF-8 `notes.xml` beside the frames changes nothing.
#[test]
fn weakened_measurements_are_flagged_warnings() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let gap = variant(d, "gap", |x| x, &(10..=19).collect::<Vec<_>>());
    let late = variant(d, "late", |x| x, &(-30..=-8).collect::<Vec<_>>());
    let notes = variant(d, "notes", |x| x, &[]);
    std::fs::write(notes.join("notes.xml"), b"\xff\xfe<n\x00o\x00t\x00e\x00>").unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_dropscope"))
        .args([
            "render",
            "--radius-mm",
            "4.5",
            "--height-cm",
            "12",
            "--background-level",
            "1",
            "--format",
            "png",
            "--width-px",
            "384",
            "--height-px",
            "288",
            "--out",
        ])
        .arg(d.join("white"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let fixture = root().join("fixtures").join(DROP);
    let mut scale = spec("scale", &fixture);
    scale.mm_per_px = Some(1.05 * 0.055);
    let mut fps = spec("fps", &fixture);
    fps.fps = Some(9000.0);
    let runs = [
        spec("good", &fixture),
        spec("gap", &gap),
        spec("late", &late),
        spec("notes", &notes),
        spec("white", &d.join("white").join(DROP)),
        scale,
        fps,
    ];
    let rows = process_all(&runs, &config(), &d.join("out"), &|_| {}).unwrap();
    let good = by(&rows, "good");
    assert_eq!((good.status, good.flags.as_str()), (DropStatus::Ok, ""));
    assert_eq!(
        by(&rows, "notes"),
        &DropRecord {
            run: "notes".into(),
            path: notes.display().to_string(),
            ..good.clone()
        }
    );
    for (run, flags, says) in [
        (
            "gap",
            "gap_in_contact gap_at_peak",
            "10 frame(s) missing in the contact (10–19)",
        ),
        ("late", "short_flight", "free-flight frames before"),
        (
            "white",
            "saturated",
            "of the background near the sphere's path",
        ),
        // A scale 5–7 % off also puts the contact law's surface 4 px from
        // the image's line: the cross-check sees what a wrong scale does.
        (
            "scale",
            "surface_law_disagreement scale_disagreement",
            "puts the undeformed surface",
        ),
        (
            "fps",
            "fps_mismatch",
            "the manifest's fps 9000 disagrees with the recording's own frame rate 10000 \
             frames/s (xml)",
        ),
    ] {
        let r = by(&rows, run);
        assert_eq!(r.status, DropStatus::Warning, "{run}: {}", r.reason);
        assert_eq!(r.flags, flags, "{run}: {}", r.reason);
        assert!(r.reason.contains(says), "{run}: {}", r.reason);
    }
    // On disk: the flags column between status and reason.
    let text = std::fs::read_to_string(d.join("out/drops.csv")).unwrap();
    assert!(text
        .lines()
        .next()
        .unwrap()
        .ends_with(",status,flags,reason,review"));
    assert!(
        text.contains(",warning,gap_in_contact gap_at_peak,"),
        "{text}"
    );
}

/// The cache reuses a run only when every file it wrote still has the
/// SHA-256 it was written with: an emptied track or an altered overlay is
/// recomputed, back to the same bytes.
#[test]
fn the_cache_recomputes_an_emptied_or_altered_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("runs.csv"),
        format!(
            "run,path,sphere_radius_mm\nr3,{},3\n",
            root().join("fixtures/R3mm_H1.5cm_01").display()
        ),
    )
    .unwrap();
    let cfg = d.join("pipeline.toml");
    std::fs::write(
        &cfg,
        "[input]\nmanifest = \"runs.csv\"\nsurface = \"pdms\"\n\
         [surface.pdms]\nmodulus_pa = 1.6e6\npillar_height_mm = 3.5\n\
         pillar_width_mm = 2.5\nchannel_width_mm = 1.5\n[output]\ndir = \"out\"\n",
    )
    .unwrap();
    // The job's last line: "… N reused from the cache …".
    let reused = || -> String {
        let o = Command::new(env!("CARGO_BIN_EXE_dropscope"))
            .args(["run", "--config"])
            .arg(&cfg)
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&o.stderr).into_owned();
        assert_eq!(o.status.code(), Some(0), "{e}");
        let tail = e.lines().last().unwrap_or_default();
        let k = tail.find(" reused").unwrap_or_else(|| panic!("{tail}"));
        tail[..k].rsplit(' ').next().unwrap().to_string()
    };
    assert_eq!(reused(), "0");
    assert_eq!(reused(), "1");
    let track = d.join("out/tracks/r3.csv");
    let overlay = d.join("out/plots/overlays/r3.png");
    let (t0, o0) = (
        std::fs::read(&track).unwrap(),
        std::fs::read(&overlay).unwrap(),
    );
    std::fs::write(&track, b"").unwrap();
    assert_eq!(reused(), "0");
    assert_eq!(std::fs::read(&track).unwrap(), t0);
    let mut altered = o0.clone();
    let last = altered.len() - 1;
    altered[last] ^= 1;
    std::fs::write(&overlay, &altered).unwrap();
    assert_eq!(reused(), "0");
    assert_eq!(std::fs::read(&overlay).unwrap(), o0);
    assert_eq!(reused(), "1");
}

/// Found by the `folder_frame` fuzz target: a 1.9 kB RLE8 BMP whose header
/// claims 3 072 × 45 319 pixels (its "end of bitmap" code fills the rest)
/// took the decoder 16 s (at nice 19 on the shared machine) and 600 MB per
/// read. That size is beyond every reader's pixel cap (8192 × 4096); a
/// compressed frame within the cap but claiming more than 4 096 pixels per
/// byte of its file (3 072 × 4 000 in 1 080 bytes) is refused when the
/// folder is opened, naming the file; the same frame at a camera's size reads.
#[test]
fn a_compressed_frame_claiming_an_absurd_size_is_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let bmp_rle8 = |w: u32, h: u32| {
        let data_offset = 14 + 40 + 1024u32;
        let rle = [0u8, 1]; // end of bitmap: every pixel left is index 0
        let mut b = Vec::new();
        b.extend_from_slice(b"BM");
        b.extend_from_slice(&(data_offset + rle.len() as u32).to_le_bytes());
        b.extend_from_slice(&[0; 4]);
        b.extend_from_slice(&data_offset.to_le_bytes());
        b.extend_from_slice(&40u32.to_le_bytes());
        b.extend_from_slice(&w.to_le_bytes());
        b.extend_from_slice(&h.to_le_bytes());
        b.extend_from_slice(&1u16.to_le_bytes()); // planes
        b.extend_from_slice(&8u16.to_le_bytes()); // bits per pixel
        b.extend_from_slice(&1u32.to_le_bytes()); // BI_RLE8
        b.extend_from_slice(&(rle.len() as u32).to_le_bytes());
        b.extend_from_slice(&[0; 8]); // resolution
        b.extend_from_slice(&256u32.to_le_bytes()); // colours used
        b.extend_from_slice(&0u32.to_le_bytes());
        for i in 0..=255u8 {
            b.extend_from_slice(&[i, i, i, 0]);
        }
        b.extend_from_slice(&rle);
        b
    };
    let opts = dropscope::source::OpenOptions {
        fps_fallback: Some(1000.0),
        ..Default::default()
    };
    let huge = dir.path().join("huge");
    std::fs::create_dir(&huge).unwrap();
    std::fs::write(huge.join("f_000003.bmp"), bmp_rle8(3072, 45_319)).unwrap();
    let Err(e) = dropscope::source::open(&huge, &opts) else {
        panic!("a 3072×45319 frame in 1 080 bytes was opened");
    };
    let e = e.to_string();
    assert!(
        e.contains("f_000003.bmp") && e.contains("implausible frame size 3072×45319"),
        "{e}"
    );
    std::fs::write(huge.join("f_000003.bmp"), bmp_rle8(3072, 4000)).unwrap();
    let Err(e) = dropscope::source::open(&huge, &opts) else {
        panic!("a 3072×4000 frame in 1 080 bytes was opened");
    };
    let e = e.to_string();
    assert!(
        e.contains("f_000003.bmp") && e.contains("implausible size 3072×4000 for a 1080-byte file"),
        "{e}"
    );
    // The same file at a camera's size is a frame (all black).
    let small = dir.path().join("small");
    std::fs::create_dir(&small).unwrap();
    std::fs::write(small.join("f_000003.bmp"), bmp_rle8(64, 16)).unwrap();
    let mut src = dropscope::source::open(&small, &opts).unwrap();
    let mut frame = dropscope::source::Frame::zeros((16, 64));
    src.read_into(0, &mut frame).unwrap();
    assert!(frame.iter().all(|&v| v == 0));
}
