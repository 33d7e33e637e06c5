//! Fuzz the decoding of one frame file of a folder (TIFF, BMP, PNG or JPEG
//! by the first byte), from memory, through the code `FolderSource` runs on
//! a file's bytes (`source::frame_decode`): the header as opening the
//! folder reads it, then the frame whole and as a band as a frame read
//! decodes it. Any bytes must give Ok or Err, never a panic, a hang or an
//! allocation beyond the limits.
//!
//! Not driven here: the folder listing, the frame-name rules, the XML side
//! file (its parser has `pcc_xml`) and the file checks (regular file,
//! bounded reads), which `tests/hostile.rs` and `tests/source.rs` cover.
//!
//! Cost per execution (a campaign is 10 million of them): frames are decoded
//! only when they have at most 2^18 pixels (a 512 × 384 camera frame has
//! 196 608): a larger one fits in a 64 kB input only compressed (PNG, JPEG,
//! compressed TIFF), and decoding millions of pixels in the `image` crate
//! took 10–100 ms an execution; its header is still read and checked.
#![no_main]

use std::path::Path;

use dropscope::source::frame_decode::ImageKind;
use dropscope::source::frame_decode::FrameDecoder;
use dropscope::source::Frame;
use libfuzzer_sys::fuzz_target;

const KINDS: [(ImageKind, &str); 4] = [
    (ImageKind::Tiff, "f_000003.tif"),
    (ImageKind::Bmp, "f_000003.bmp"),
    (ImageKind::Png, "f_000003.png"),
    (ImageKind::Jpeg, "f_000003.jpg"),
];

fuzz_target!(|data: &[u8]| {
    let Some((&kind, bytes)) = data.split_first() else {
        return;
    };
    let (kind, name) = KINDS[usize::from(kind) % KINDS.len()];
    let name = Path::new(name);
    let Ok((w, h, bits)) = FrameDecoder::for_headers().probe_bytes(name, kind, bytes) else {
        return;
    };
    if h.saturating_mul(w) > 1 << 18 {
        return;
    }
    let mut decoder = FrameDecoder::for_frames();
    let mut frame = Frame::zeros((h, w));
    let _ = decoder.read_rows_from_bytes(name, kind, bytes, (w, h, bits), 0, &mut frame.view_mut());
    let mut band = frame.slice_mut(ndarray::s![h / 3..h / 2, ..]);
    let _ = decoder.read_rows_from_bytes(name, kind, bytes, (w, h, bits), h / 3, &mut band);
});
