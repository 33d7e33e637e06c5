//! Fuzz the cine header parser and, when it accepts the input, the frame
//! reader on the same bytes: any input must give Ok or Err, never a panic.
#![no_main]

use dropscope::source::{cine, FrameSource, OpenOptions, P10Mode};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if cine::parse_layout(data, data.len() as u64).is_err() {
        return;
    }
    // Accepted: read frames through the file reader too.
    let path = std::env::temp_dir().join(format!("fuzz-cine-{}.cine", std::process::id()));
    if std::fs::write(&path, data).is_err() {
        return;
    }
    for p10 in [P10Mode::Raw, P10Mode::Linear] {
        let opts = OpenOptions {
            apply_flips: true,
            p10,
            ..OpenOptions::default()
        };
        if let Ok(mut src) = cine::CineSource::open(&path, &opts) {
            let (h, w, n) = (src.meta().height, src.meta().width, src.meta().frame_count);
            if h * w > 1 << 22 {
                continue;
            }
            let mut frame = ndarray::Array2::<u16>::zeros((h, w));
            for i in 0..n.min(4) {
                let _ = src.read_into(i, &mut frame);
                let mut band = frame.slice_mut(ndarray::s![h / 3..h / 2, ..]);
                let _ = src.read_rows_into(i, h / 3, &mut band);
            }
        }
    }
});
