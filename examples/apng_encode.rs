//! The animated impact's PNG encoding, setting by setting: decodes the
//! indexed frames of every animation in a folder (`plots/impacts/` of a
//! `dropscope process` output) and times re-encoding them with each PNG
//! filter and compression level, printing the CPU ms per animation and the
//! bytes.
//!
//!     cargo run --release --example apng_encode -- OUT/plots/impacts [REPEATS]
//!
//! `-- --same DIR1 DIR2` says whether two folders' animations show the
//! same frames (pixels and palette), whatever their encoding.

use std::time::Instant;

struct Movie {
    w: u32,
    h: u32,
    palette: Vec<u8>,
    frames: Vec<Vec<u8>>,
}

fn load(path: &std::path::Path) -> Movie {
    let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut r = dec.read_info().unwrap();
    let info = r.info();
    let (w, h) = (info.width, info.height);
    let palette = info.palette.as_ref().unwrap().to_vec();
    let n = info.animation_control().map_or(1, |a| a.num_frames);
    let mut frames = Vec::new();
    for _ in 0..n {
        let mut buf = vec![0; r.output_buffer_size().unwrap()];
        let f = r.next_frame(&mut buf).unwrap();
        assert_eq!((f.width, f.height), (w, h), "frames of the whole size");
        buf.truncate(f.buffer_size());
        frames.push(buf);
    }
    Movie {
        w,
        h,
        palette,
        frames,
    }
}

fn encode(m: &Movie, deflate: png::DeflateCompression, filter: png::Filter) -> usize {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, m.w, m.h);
    enc.set_color(png::ColorType::Indexed);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_palette(m.palette.clone());
    enc.set_deflate_compression(deflate);
    enc.set_filter(filter);
    enc.set_animated(m.frames.len() as u32, 0).unwrap();
    enc.set_frame_delay(80, 1000).unwrap();
    let mut w = enc.write_header().unwrap();
    for f in &m.frames {
        w.write_image_data(f).unwrap();
    }
    w.finish().unwrap();
    out.len()
}

/// Whether the animations of two folders show the same frames (palette
/// and indices), whatever their PNG encoding.
fn same(a: &std::path::Path, b: &std::path::Path) {
    let mut names: Vec<_> = std::fs::read_dir(a)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    names.sort();
    let mut differ = 0;
    for name in &names {
        let (x, y) = (load(&a.join(name)), load(&b.join(name)));
        if (x.w, x.h, &x.palette, &x.frames) != (y.w, y.h, &y.palette, &y.frames) {
            println!("{}: frames differ", name.to_string_lossy());
            differ += 1;
        }
    }
    println!("{} animations, {differ} with different frames", names.len());
}

fn cpu_s() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: a valid timespec pointer.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

fn main() {
    let mut args = std::env::args().skip(1);
    let dir = args
        .next()
        .expect("usage: apng_encode DIR [REPEATS] | --same DIR DIR");
    if dir == "--same" {
        let (a, b) = (args.next().unwrap(), args.next().unwrap());
        return same(a.as_ref(), b.as_ref());
    }
    let repeats: usize = args.next().map_or(3, |s| s.parse().unwrap());
    let mut paths: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    paths.sort();
    let movies: Vec<Movie> = paths.iter().map(|p| load(p)).collect();
    let frames: usize = movies.iter().map(|m| m.frames.len()).sum();
    println!(
        "{} animations, {} frames, {:.0} pixels a frame on average",
        movies.len(),
        frames,
        movies
            .iter()
            .map(|m| (m.w * m.h) as f64 * m.frames.len() as f64)
            .sum::<f64>()
            / frames as f64
    );
    use png::{DeflateCompression as D, Filter as F};
    let settings = [
        (
            "fdeflate, adaptive (Fast)",
            D::FdeflateUltraFast,
            F::Adaptive,
        ),
        ("fdeflate, up (Fastest)", D::FdeflateUltraFast, F::Up),
        ("fdeflate, sub", D::FdeflateUltraFast, F::Sub),
        ("fdeflate, none", D::FdeflateUltraFast, F::NoFilter),
        ("zlib 1, none", D::Level(1), F::NoFilter),
        ("zlib 1, up", D::Level(1), F::Up),
        ("stored", D::NoCompression, F::NoFilter),
    ];
    println!("setting                      CPU ms/animation (best, worst)   bytes/animation");
    for (name, d, f) in settings {
        let mut times = Vec::new();
        let mut bytes = 0;
        for _ in 0..repeats {
            let t = (cpu_s(), Instant::now());
            bytes = movies.iter().map(|m| encode(m, d, f)).sum::<usize>();
            times.push(cpu_s() - t.0);
        }
        let best = times.iter().cloned().fold(f64::INFINITY, f64::min);
        let worst = times.iter().cloned().fold(0.0, f64::max);
        let per = |s: f64| s * 1e3 / movies.len() as f64;
        println!(
            "{name:<28} {:>8.2} {:>8.2}                  {:>10.0}",
            per(best),
            per(worst),
            bytes as f64 / movies.len() as f64
        );
    }
}
