//! Fuzz the Photron header parser (a `.cihx`: XML after a binary preamble,
//! or a `.cih`: `Key : Value` lines) and, when it accepts the input, the
//! MRAW reader on a movie made for that header: any input must give Ok or
//! Err, never a panic.
//!
//! The movie (at most 64 kB, else the header alone is fuzzed) repeats the
//! input's bytes; every other input has it one byte short, so that the
//! check of a truncated MRAW is driven too. Files live in `/dev/shm`, one
//! pair per fuzzing process, overwritten.
#![no_main]

use std::path::PathBuf;
use std::sync::OnceLock;

use dropscope::source::photron::cih::{self, CihForm};
use dropscope::source::photron::PhotronSource;
use dropscope::source::{Frame, FrameSource, OpenOptions};
use libfuzzer_sys::fuzz_target;

fn scratch_dir() -> &'static PathBuf {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        let base = if std::path::Path::new("/dev/shm").is_dir() {
            PathBuf::from("/dev/shm")
        } else {
            std::env::temp_dir()
        };
        let dir = base.join(format!("dropscope-fuzz-photron-{}", std::process::id()));
        let _ = std::fs::create_dir_all(&dir);
        dir
    })
}

fuzz_target!(|data: &[u8]| {
    let Ok(c) = cih::parse(data) else {
        return;
    };
    let need = c.frame_bytes().saturating_mul(c.total_frames);
    if need > 1 << 16 || data.is_empty() {
        return;
    }
    let dir = scratch_dir();
    let (header, other) = match c.form {
        CihForm::Xml => (dir.join("f.cihx"), dir.join("f.cih")),
        CihForm::Text => (dir.join("f.cih"), dir.join("f.cihx")),
    };
    let _ = std::fs::remove_file(other);
    let len = need as usize - (data.len() % 2).min(need as usize);
    let movie: Vec<u8> = data.iter().copied().cycle().take(len).collect();
    let mraw = dir.join("f.mraw");
    if std::fs::write(&header, data).is_err() || std::fs::write(&mraw, movie).is_err() {
        return;
    }
    let opts = OpenOptions {
        apply_flips: true,
        ..OpenOptions::default()
    };
    let Ok(mut src) = PhotronSource::open(&mraw, &opts) else {
        return;
    };
    let (h, w, n) = (src.meta().height, src.meta().width, src.meta().frame_count);
    let mut frame = Frame::zeros((h, w));
    for i in 0..n.min(4) {
        let _ = src.read_into(i, &mut frame);
        let mut band = frame.slice_mut(ndarray::s![h / 3..h / 2, ..]);
        let _ = src.read_rows_into(i, h / 3, &mut band);
    }
});
