//! Fuzz the folder reader on one frame file (TIFF, BMP, PNG or JPEG by the
//! first byte): opening the folder (every header, the frame-name rules) and,
//! when it opens, reading the frame whole and as a band. Any bytes must give
//! Ok or Err, never a panic, a hang or an allocation beyond the limits.
//!
//! Cost per execution (issue 14 asks for 10 million): the folder lives in
//! memory (`/dev/shm`), only the previous execution's file is removed, and
//! frames are read only when they have at most 2^18 pixels (a 512 × 384
//! camera frame has 196 608): a larger one fits in a 64 kB input only
//! compressed (PNG, JPEG, compressed TIFF), and decoding millions of pixels
//! in the `image` crate took 10–100 ms an execution; its header is still
//! read and checked when the folder is opened.
#![no_main]

use dropscope::source::{folder::FolderSource, Frame, FrameSource, OpenOptions};
use libfuzzer_sys::fuzz_target;

const EXTS: [&str; 4] = ["tif", "bmp", "png", "jpg"];

fuzz_target!(|data: &[u8]| {
    let Some((&kind, bytes)) = data.split_first() else {
        return;
    };
    // One folder per fuzzing process, in memory when /dev/shm is there.
    let base = if std::path::Path::new("/dev/shm").is_dir() {
        std::path::PathBuf::from("/dev/shm")
    } else {
        std::env::temp_dir()
    };
    let dir = base.join(format!("dropscope-fuzz-folder-{}", std::process::id()));
    let ext = EXTS[usize::from(kind) % EXTS.len()];
    // The previous execution's file, if it had another extension.
    static LAST: std::sync::Mutex<Option<&str>> = std::sync::Mutex::new(None);
    let mut last = LAST.lock().unwrap_or_else(|e| e.into_inner());
    match *last {
        None => {
            let _ = std::fs::create_dir_all(&dir);
        }
        Some(prev) if prev != ext => {
            let _ = std::fs::remove_file(dir.join(format!("f_000003.{prev}")));
        }
        Some(_) => {}
    }
    *last = Some(ext);
    drop(last);
    if std::fs::write(dir.join(format!("f_000003.{ext}")), bytes).is_err() {
        return;
    }
    let opts = OpenOptions {
        fps_fallback: Some(1000.0),
        ..OpenOptions::default()
    };
    let Ok(mut src) = FolderSource::open(&dir, &opts) else {
        return;
    };
    let (h, w) = (src.meta().height, src.meta().width);
    if h.saturating_mul(w) > 1 << 18 {
        return;
    }
    let mut frame = Frame::zeros((h, w));
    let _ = src.read_into(0, &mut frame);
    let mut band = frame.slice_mut(ndarray::s![h / 3..h / 2, ..]);
    let _ = src.read_rows_into(0, h / 3, &mut band);
});
