//! Frame-reading speed: a 2 000-frame 512×384 8-bit TIFF folder,
//! the same frames as PNG, and a 16-bit `.cine`, in frames/s on 1 and 2
//! threads, beside a plain memory copy of the same bytes in the same run
//! and, for PNG, the `image` crate's own decoder. Every rate is given by
//! the wall clock and per CPU second of the threads that did the work (the
//! machine is shared: the CPU figure is what an unshared core delivers).
//! Sources are opened before the clock starts, like the copy's buffer; the
//! time to open each input (a folder lists its files and reads the first
//! frame's header) is printed on its own.
//!
//!     cargo bench --bench read            (DROPSCOPE_BENCH_FRAMES=N to change 2000)
//!
//! Data are generated in a temporary folder (≈1.4 GB, removed at the end),
//! written back and dropped from the page cache (`fsync`, then
//! `POSIX_FADV_DONTNEED`), then read once before timing: every figure is
//! from the page cache, holding the files as it holds a movie read from
//! disk rather than in whatever state the writer left it (for the cine the
//! writer's state measured 1.4× slower to read: 30.5 against 21.9 µs of CPU
//! per frame). Each figure is the best of `REPEATS` runs (the machine is
//! shared).

#[path = "common/mod.rs"]
mod common;
use common::thread_cpu_s;
use std::path::{Path, PathBuf};
use std::time::Instant;

use dropscope::source::cine_write::{CinePacking, CineSpec, CineWriter};
use dropscope::source::{open, Frame, OpenOptions};

const W: usize = 512;
const H: usize = 384;
const REPEATS: usize = 3;

/// A rate in frames per wall-clock second and per CPU second of one
/// thread (the CPU figure is what a core delivers when it is not shared
/// with other processes; with two threads it is per core).
#[derive(Debug, Clone, Copy, Default)]
struct Rate {
    wall: f64,
    cpu: f64,
}

/// Best (highest) wall and CPU rates of `REPEATS` runs of `f`, each taken
/// separately.
fn best(mut f: impl FnMut() -> Rate) -> Rate {
    (0..REPEATS)
        .map(|_| f())
        .fold(Rate::default(), |a, b| Rate {
            wall: a.wall.max(b.wall),
            cpu: a.cpu.max(b.cpu),
        })
}

/// Rate of `frames` frames shared by `threads` threads: thread `t` first
/// runs `prepare(t)` (untimed: opening a source, allocating a buffer), then
/// all start together and run `work(t, state)`. Each thread reads the clock
/// itself (the spawning thread may not be scheduled while the workers
/// run): wall time is from the first start to the last end.
fn run<S>(
    frames: usize,
    threads: usize,
    prepare: impl Fn(usize) -> S + Sync,
    work: impl Fn(usize, &mut S) + Sync,
) -> Rate {
    let barrier = std::sync::Barrier::new(threads);
    let spans: Vec<(Instant, Instant, f64)> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                let (barrier, prepare, work) = (&barrier, &prepare, &work);
                scope.spawn(move || {
                    let mut state = prepare(t);
                    barrier.wait();
                    let start = Instant::now();
                    let cpu0 = thread_cpu_s();
                    work(t, &mut state);
                    let cpu = match (cpu0, thread_cpu_s()) {
                        (Some(a), Some(b)) => b - a,
                        _ => f64::NAN,
                    };
                    (start, Instant::now(), cpu)
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("bench thread"))
            .collect()
    });
    let start = spans.iter().map(|s| s.0).min().expect("a thread");
    let end = spans.iter().map(|s| s.1).max().expect("a thread");
    let cpu: f64 = spans.iter().map(|s| s.2).sum();
    Rate {
        wall: frames as f64 / (end - start).as_secs_f64(),
        cpu: frames as f64 / cpu,
    }
}

/// A drop-like frame: bright background with a gradient, a dark disk that
/// moves with `i`, mild deterministic noise. Values 0‥max.
fn synthetic(i: usize, max: u16) -> Frame {
    let cx = 256.0;
    let cz = 40.0 + (i % 300) as f64;
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15 ^ i as u64;
    Frame::from_shape_fn((H, W), |(r, c)| {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let noise = ((x >> 60) as f64) - 7.5;
        let d = ((r as f64 - cz).powi(2) + (c as f64 - cx).powi(2)).sqrt();
        let base = if d < 60.0 {
            0.15
        } else {
            0.8 - 0.1 * r as f64 / H as f64
        };
        ((base * f64::from(max) + noise * f64::from(max) / 255.0).clamp(0.0, f64::from(max))) as u16
    })
}

fn gray8(f: &Frame) -> image::GrayImage {
    image::GrayImage::from_fn(W as u32, H as u32, |x, y| {
        image::Luma([f[[y as usize, x as usize]] as u8])
    })
}

/// Write `paths` to disk and drop them from the page cache, so that the
/// next read fills it as reading a movie from disk does (Linux; elsewhere
/// a no-op).
fn evict_from_page_cache(paths: &[PathBuf]) {
    for p in paths {
        let f = std::fs::File::open(p).expect("open for eviction");
        f.sync_all().expect("fsync");
        #[cfg(target_os = "linux")]
        {
            use std::os::fd::AsRawFd;
            // SAFETY: a plain system call on an open descriptor; no memory is passed.
            let r = unsafe { libc::posix_fadvise(f.as_raw_fd(), 0, 0, libc::POSIX_FADV_DONTNEED) };
            assert_eq!(r, 0, "posix_fadvise on {}", p.display());
        }
    }
}

fn bench_options() -> OpenOptions {
    OpenOptions {
        fps_fallback: Some(10_000.0),
        ..OpenOptions::default()
    }
}

/// Reading `n` frames split over `threads` threads, each with its own
/// source (opened before the clock starts: see [`time_open`]).
fn time_source(path: &Path, n: usize, threads: usize) -> Rate {
    run(
        n,
        threads,
        |_| {
            let src = open(path, &bench_options()).expect("open");
            (src, Frame::zeros((H, W)))
        },
        |t, (src, f)| {
            for i in (t..n).step_by(threads) {
                src.read_into(i, f).expect("read");
            }
        },
    )
}

/// Seconds to open `path` (a folder lists its files and reads the first frame's header).
fn time_open(path: &Path) -> f64 {
    let t0 = Instant::now();
    let src = open(path, &bench_options()).expect("open");
    std::hint::black_box(src.meta().frame_count);
    t0.elapsed().as_secs_f64()
}

/// Reading a band of `rows` rows (from row 150) of each frame.
fn time_band(path: &Path, n: usize, threads: usize, rows: usize) -> Rate {
    run(
        n,
        threads,
        |_| {
            let src = open(path, &bench_options()).expect("open");
            (src, Frame::zeros((rows, W)))
        },
        |t, (src, band)| {
            for i in (t..n).step_by(threads) {
                src.read_rows_into(i, 150, &mut band.view_mut())
                    .expect("read");
            }
        },
    )
}

/// Copying each frame's bytes out of one big in-memory buffer (DRAM-bound:
/// the buffer is far larger than the caches) into a reused buffer.
fn time_copy(all: &[u8], frame_bytes: usize, threads: usize) -> Rate {
    let n = all.len() / frame_bytes;
    run(
        n,
        threads,
        |_| vec![0u8; frame_bytes],
        |t, dst| {
            for i in (t..n).step_by(threads) {
                dst.copy_from_slice(&all[i * frame_bytes..(i + 1) * frame_bytes]);
                std::hint::black_box(&dst);
            }
        },
    )
}

/// The image crate decoding each file (`image::open`).
fn time_image_crate(files: &[PathBuf], threads: usize) -> Rate {
    run(
        files.len(),
        threads,
        |_| (),
        |t, _| {
            for f in files.iter().skip(t).step_by(threads) {
                let img = image::open(f).expect("decode");
                std::hint::black_box(img);
            }
        },
    )
}

fn main() {
    let n: usize = std::env::var("DROPSCOPE_BENCH_FRAMES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2000);
    let dir = tempfile::tempdir().expect("temp dir");
    let tiff_dir = dir.path().join("tiff");
    let png_dir = dir.path().join("png");
    std::fs::create_dir_all(&tiff_dir).unwrap();
    std::fs::create_dir_all(&png_dir).unwrap();
    let cine = dir.path().join("movie.cine");
    eprintln!(
        "generating {n} frames of {W}×{H} in {} …",
        dir.path().display()
    );
    let spec = CineSpec {
        width: W,
        height: H,
        frame_count: n,
        packing: CinePacking::Gray16,
        bit_depth: 12,
        ..CineSpec::default()
    };
    let mut writer = CineWriter::create(&cine, &spec).unwrap();
    let mut png_files = Vec::new();
    let mut tiff_files = Vec::new();
    // 16 distinct frames, reused, keep generation quick.
    let pool: Vec<Frame> = (0..16).map(|i| synthetic(i * 37, 255)).collect();
    let pool12: Vec<Frame> = pool.iter().map(|f| f.mapv(|v| v * 16)).collect();
    for i in 0..n {
        let f = &pool[i % pool.len()];
        let img = gray8(f);
        let t = tiff_dir.join(format!("run_{i:06}.tif"));
        img.save(&t).unwrap();
        tiff_files.push(t);
        let p = png_dir.join(format!("run_{i:06}.png"));
        img.save(&p).unwrap();
        png_files.push(p);
        writer.write_frame(&pool12[i % pool.len()]).unwrap();
    }
    writer.finish().unwrap();
    let mut generated = tiff_files.clone();
    generated.extend(png_files.iter().cloned());
    generated.push(cine.clone());
    evict_from_page_cache(&generated);

    let read_all_files = |d: &Path| -> Vec<u8> {
        let mut v = Vec::new();
        let mut names: Vec<_> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        names.sort();
        for p in names {
            v.extend(std::fs::read(p).unwrap());
        }
        v
    };
    // Warm the page cache (and hold the bytes for the copy baseline).
    let tiff_bytes = read_all_files(&tiff_dir);
    let png_bytes = read_all_files(&png_dir);
    let cine_bytes = std::fs::read(&cine).unwrap();
    let tiff_frame = tiff_bytes.len() / n;
    let cine_frame = W * H * 2;
    eprintln!(
        "sizes: tiff {:.0} kB/frame, png {:.0} kB/frame, cine {:.0} kB/frame",
        tiff_frame as f64 / 1e3,
        png_bytes.len() as f64 / n as f64 / 1e3,
        cine_frame as f64 / 1e3
    );
    // One untimed pass each.
    time_source(&tiff_dir, n.min(200), 1);
    time_source(&png_dir, n.min(200), 1);
    time_source(&cine, n.min(200), 1);

    println!(
        "| input | threads | dropscope frames/s wall | dropscope frames/s per CPU-s | baseline | \
         baseline wall | baseline per CPU-s | ratio wall | ratio CPU |"
    );
    println!("|---|---:|---:|---:|---|---:|---:|---:|---:|");
    for threads in [1, 2] {
        let rows = [
            (
                "TIFF 8-bit folder",
                best(|| time_source(&tiff_dir, n, threads)),
                "memcpy of the file bytes",
                best(|| time_copy(&tiff_bytes, tiff_frame, threads)),
            ),
            (
                "TIFF 8-bit folder",
                best(|| time_source(&tiff_dir, n, threads)),
                "image::open (image crate)",
                best(|| time_image_crate(&tiff_files, threads)),
            ),
            (
                "PNG 8-bit folder",
                best(|| time_source(&png_dir, n, threads)),
                "image::open (image crate)",
                best(|| time_image_crate(&png_files, threads)),
            ),
            (
                "16-bit .cine",
                best(|| time_source(&cine, n, threads)),
                "memcpy of the pixel bytes",
                best(|| time_copy(&cine_bytes[..n * cine_frame], cine_frame, threads)),
            ),
        ];
        let band = [
            (
                "16-bit .cine, 64-row band",
                best(|| time_band(&cine, n, threads, 64)),
                "memcpy of the band's bytes",
                best(|| time_copy(&cine_bytes[..n * cine_frame / 6], cine_frame / 6, threads)),
            ),
            (
                "TIFF 8-bit folder, 64-row band",
                best(|| time_band(&tiff_dir, n, threads, 64)),
                "memcpy of the band's bytes",
                best(|| time_copy(&tiff_bytes[..n * (W * H / 6)], W * H / 6, threads)),
            ),
        ];
        for (name, ours, base_name, base) in rows.into_iter().chain(band) {
            println!(
                "| {name} | {threads} | {:.0} | {:.0} | {base_name} | {:.0} | {:.0} | {:.2} | {:.2} |",
                ours.wall,
                ours.cpu,
                base.wall,
                base.cpu,
                base.wall / ours.wall,
                base.cpu / ours.cpu
            );
        }
    }
    for (name, path) in [("TIFF", &tiff_dir), ("PNG", &png_dir), (".cine", &cine)] {
        let s = (0..REPEATS)
            .map(|_| time_open(path))
            .fold(f64::INFINITY, f64::min);
        println!(
            "opening the {name} input (not in the rates above): {:.1} ms, {:.2} µs per frame",
            s * 1e3,
            s * 1e6 / n as f64
        );
    }
}
