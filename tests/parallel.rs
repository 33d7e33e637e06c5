//! One movie on several threads (issue 16): chunks of a long movie are
//! tracked ahead by other threads and stitched to the track that one thread
//! makes, so the track and every output file are the same bytes whatever
//! the number of threads.

use crate::render::{args, files, pool};
use dropscope::config::{DetectConfig, PipelineConfig, EMBEDDED_DEFAULT};
use dropscope::dataset::DropStatus;
use dropscope::manifest::read_manifest;
use dropscope::process::process_all;
use dropscope::source::{open, OpenOptions};
use dropscope::track::{track, TrackSettings};
use std::path::Path;

#[test]
fn a_long_movie_gives_the_same_bytes_on_one_thread_and_two() {
    // A 3 mm sphere from 1.5 cm at 60 000 frames/s: ~860 frames, the
    // sphere in every one, three chunks of pass 1 on two threads.
    let data = tempfile::tempdir().unwrap();
    let dir = data.path().to_str().unwrap();
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
    let runs = read_manifest(&data.path().join("runs.csv")).unwrap();
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
}
