//! One movie on several threads: chunks of a long movie are
//! tracked ahead by other threads and stitched to the track that one thread
//! makes, so the track and every output file are the same bytes whatever
//! the number of threads.

use crate::render::{args, files, pool};
use dropscope::config::{DetectConfig, PipelineConfig, EMBEDDED_DEFAULT};
use dropscope::dataset::manifest::read_manifest;
use dropscope::dataset::DropStatus;
use dropscope::job::run_outputs::process_all;
use dropscope::source::{open, OpenOptions};
use dropscope::track::{track, TrackSettings};
use std::path::Path;

/// A 3 mm sphere from 1.5 cm at 60 000 frames/s, 256 × 192: ~860 frames,
/// the sphere in every one; its manifest's runs.
fn long_movie(data: &Path) -> Vec<dropscope::dataset::manifest::RunSpec> {
    let dir = data.to_str().unwrap();
    pool(2)
        .install(|| {
            dropscope::render::render(&args(&[
                "--out",
                dir,
                "--drop",
                "3:1.5",
                "--fps",
                "60000",
                "--exposure-us",
                "10",
                "--frames-before",
                "400",
                "--frames-after",
                "300",
                "--width-px",
                "256",
                "--height-px",
                "192",
                "--mm-per-px",
                "0.08",
            ]))
        })
        .unwrap();
    read_manifest(&data.join("runs.csv")).unwrap()
}

#[test]
fn a_long_movie_gives_the_same_bytes_on_one_thread_and_two() {
    // Three chunks of pass 1 on two threads.
    let data = tempfile::tempdir().unwrap();
    let runs = long_movie(data.path());
    let st = TrackSettings::from_config(&DetectConfig::default());
    let tracked = |threads: usize| {
        pool(threads).install(|| {
            let mut src = open(&runs[0].path, &OpenOptions::default()).unwrap();
            track(src.as_mut(), &st).unwrap()
        })
    };
    let (one, two) = (tracked(1), tracked(2));
    let n = one.frames.len();
    assert!(n > 800, "{n} frames");
    // Two threads did measure ahead (most frames of the later chunks are
    // taken from them), one did not.
    assert_eq!(one.measured_ahead, 0);
    assert!(
        two.measured_ahead > n / 3,
        "{} of {n} frames measured ahead",
        two.measured_ahead
    );
    // The same track, bit for bit (Debug prints each f64's shortest
    // round-trip form, so equal text is equal bits).
    assert_eq!(format!("{:?}", one.frames), format!("{:?}", two.frames));
    assert_eq!(one.radius_px.to_bits(), two.radius_px.to_bits());

    // Every output of `process`: the same bytes.
    let cfg = PipelineConfig::from_toml_str(
        EMBEDDED_DEFAULT,
        Path::new("pipeline.toml"),
        Path::new(env!("CARGO_MANIFEST_DIR")),
    )
    .unwrap();
    let outs: Vec<_> = [1, 2]
        .into_iter()
        .map(|threads| {
            let out = tempfile::tempdir().unwrap();
            let recs = pool(threads).install(|| process_all(&runs, &cfg, out.path(), &|_| {}));
            let recs = recs.unwrap();
            assert_eq!(recs[0].status, DropStatus::Ok, "{}", recs[0].reason);
            out
        })
        .collect();
    let (a, b) = (files(outs[0].path()), files(outs[1].path()));
    let rel = |v: &[std::path::PathBuf], root: &Path| -> Vec<std::path::PathBuf> {
        v.iter()
            .map(|p| p.strip_prefix(root).unwrap().to_path_buf())
            .collect()
    };
    assert_eq!(rel(&a, outs[0].path()), rel(&b, outs[1].path()));
    assert!(a.len() >= 3, "{a:?}");
    for (p, q) in a.iter().zip(&b) {
        assert!(
            std::fs::read(p).unwrap() == std::fs::read(q).unwrap(),
            "{} differs between 1 and 2 threads",
            p.display()
        );
    }

    // A late frame file of another bit depth, then of another size: the
    // folder still opens (only its first header is read then), and tracking
    // fails where that frame is read, naming its file, its frame and the
    // first frame's file, with the same error on one thread and two (the
    // thread measuring ahead stops there; the walk in order reads it).
    let index = n - 60;
    let folder =
        dropscope::source::folder::FolderSource::open(&runs[0].path, &OpenOptions::default())
            .unwrap();
    let (first, bad) = (&folder.file(0), &folder.file(index));
    let (w, h) = (256u32, 192u32);
    for (bits, size, says) in [
        (16, (w, h), "256×192 16-bit, but the sequence's first frame"),
        (
            8,
            (w, h - 1),
            "256×191 8-bit, but the sequence's first frame",
        ),
    ] {
        let mut bytes = std::io::Cursor::new(Vec::new());
        let mut enc = tiff::encoder::TiffEncoder::new(&mut bytes).unwrap();
        let pixels = (size.0 * size.1) as usize;
        if bits == 16 {
            enc.write_image::<tiff::encoder::colortype::Gray16>(size.0, size.1, &vec![900; pixels])
        } else {
            enc.write_image::<tiff::encoder::colortype::Gray8>(size.0, size.1, &vec![90; pixels])
        }
        .unwrap();
        std::fs::write(bad, bytes.into_inner()).unwrap();
        let failed = |threads: usize| {
            pool(threads).install(|| {
                let mut src = open(&runs[0].path, &OpenOptions::default()).unwrap();
                track(src.as_mut(), &st).unwrap_err().to_string()
            })
        };
        let (one, two) = (failed(1), failed(2));
        assert_eq!(one, two, "the error on 1 and 2 threads");
        let file = bad.display().to_string();
        assert!(
            one.contains(&format!("{file}: frame {index}: {says}"))
                && one.contains(&format!("{} is 256×192 8-bit", first.display())),
            "{one}"
        );
    }
}

/// What the tracker holds does not grow with the movie's length: pass 1
/// keeps at most `kept_points_max` edge points for pass 2 (the frames past
/// it are measured again in pass 2, to the same points), what other
/// threads measure ahead is at most `4 × threads − 1` chunks of at most
/// `chunk_frames_max` frames, and past `frames_in_memory_max` frames the
/// per-frame records go to a temporary file. With all three set far below
/// this movie's needs, the track is the same bits as with the defaults, on
/// one thread and two.
#[test]
fn the_points_kept_and_the_frames_measured_ahead_are_bounded() {
    let data = tempfile::tempdir().unwrap();
    let runs = long_movie(data.path());
    let default = TrackSettings::from_config(&DetectConfig::default());
    let bounded = TrackSettings {
        kept_points_max: 10_000,
        chunk_frames_max: 100,
        frames_in_memory_max: 100,
        ..default.clone()
    };
    let tracked = |threads: usize, st: &TrackSettings| {
        pool(threads).install(|| {
            let mut src = open(&runs[0].path, &OpenOptions::default()).unwrap();
            track(src.as_mut(), st).unwrap()
        })
    };
    let full = tracked(2, &default);
    assert!(!full.frames.spilled());
    let n = full.frames.len();
    let fitted = full.frames.iter().filter(|f| f.free.is_some()).count();
    println!(
        "{n} frames, {fitted} fitted, {} points kept, {} ahead at most",
        full.kept_points, full.ahead_frames_max
    );
    assert!(n > 800 && fitted > 800, "{fitted} of {n} frames fitted");
    // With the defaults every fitted frame keeps its points (74 a frame
    // for R = 37.5 px): the points grow with the movie, ...
    assert_eq!(full.remeasured_frames, 0);
    assert!(
        full.kept_points > 50 * fitted,
        "{} points",
        full.kept_points
    );
    // ... and of three chunks of ~290 frames, two are measured ahead at
    // once.
    assert!(full.ahead_frames_max > 400, "{}", full.ahead_frames_max);
    for threads in [1, 2] {
        let b = tracked(threads, &bounded);
        assert!(b.kept_points <= 10_000, "{} points kept", b.kept_points);
        assert!(
            b.remeasured_frames > fitted / 2,
            "{} of {fitted} frames measured again",
            b.remeasured_frames
        );
        assert!(
            b.ahead_frames_max <= (4 * threads - 1) * 100,
            "{threads} threads: {} frames ahead",
            b.ahead_frames_max
        );
        if threads == 2 {
            assert!(b.measured_ahead > n / 3, "{} ahead", b.measured_ahead);
        }
        // The same track, bit for bit, read back from its file.
        assert!(b.frames.spilled());
        assert_eq!(format!("{:?}", b.frames), format!("{:?}", full.frames));
        b.frames.check().unwrap();
        assert_eq!(b.radius_px.to_bits(), full.radius_px.to_bits());
    }
}
