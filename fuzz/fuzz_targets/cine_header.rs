//! Fuzz the cine header parser and, when it accepts the input, the frame
//! reader on the same bytes: any input must give Ok or Err, never a panic.
//!
//! Cost per execution (a campaign is 10 million of them): the file lives in
//! memory (`/dev/shm`, one name per fuzzing process, overwritten), and a
//! frame is read whole only when it fits the input's own bytes (a header
//! claiming 2 000 × 2 000 pixels in a 10 kB file would otherwise zero 8 MB
//! per execution); larger frames are read as a one-row band, which goes
//! through the same offset and size checks.
#![no_main]

use std::path::PathBuf;
use std::sync::OnceLock;

use dropscope::source::{cine, Frame, FrameSource, OpenOptions, P10Mode};
use libfuzzer_sys::fuzz_target;

fn scratch_file() -> &'static PathBuf {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        let base = if std::path::Path::new("/dev/shm").is_dir() {
            PathBuf::from("/dev/shm")
        } else {
            std::env::temp_dir()
        };
        base.join(format!("dropscope-fuzz-{}.cine", std::process::id()))
    })
}

fuzz_target!(|data: &[u8]| {
    if cine::parse_layout(data, data.len() as u64).is_err() {
        return;
    }
    // Accepted: read frames through the file reader too.
    let path = scratch_file();
    if std::fs::write(path, data).is_err() {
        return;
    }
    for p10 in [P10Mode::Raw, P10Mode::Linear] {
        let opts = OpenOptions {
            apply_flips: true,
            p10,
            ..OpenOptions::default()
        };
        let Ok(mut src) = cine::CineSource::open(path, &opts) else {
            continue;
        };
        let (h, w, n) = (src.meta().height, src.meta().width, src.meta().frame_count);
        if h == 0 || w == 0 {
            continue;
        }
        let whole = h.saturating_mul(w) <= data.len().max(1 << 12);
        let mut frame = Frame::zeros(if whole { (h, w) } else { (1, w.min(1 << 16)) });
        for i in 0..n.min(4) {
            if whole {
                let _ = src.read_into(i, &mut frame);
                let mut band = frame.slice_mut(ndarray::s![h / 3..h / 2, ..]);
                let _ = src.read_rows_into(i, h / 3, &mut band);
            } else if frame.ncols() == w {
                let _ = src.read_rows_into(i, h / 2, &mut frame.view_mut());
            }
        }
    }
});
