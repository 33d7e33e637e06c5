//! Where the loader's time goes: the cost of the system calls alone, with
//! no decoding, beside the memcpy baseline of `benches/read.rs`, by thread
//! CPU time per 512×384 frame (one thread; the machine is shared, so each
//! figure is the best of five passes over 2 000 frames).
//!
//!     cargo run --release --example read_floor
//!
//! The mmap rows answer "would mapping the file beat reading it": once the
//! page tables are filled a forward copy out of the mapping runs at memcpy
//! speed, but filling them (the first touch of each page, or MAP_POPULATE)
//! costs more than `pread`'s own copy, and every movie is read once.
//!
//! Data (≈1.2 GB in a temporary folder, removed at the end) are written,
//! dropped from the page cache and read once, as in the benchmark. Linux.

#[path = "../benches/common/mod.rs"]
mod common;

use std::fs::File;
use std::io::Read;
use std::os::fd::AsRawFd;
use std::os::unix::fs::FileExt;
use std::path::PathBuf;

const W: usize = 512;
const H: usize = 384;
const N: usize = 2000;

/// CPU time of this thread (s); the benches' clock.
fn thread_cpu_s() -> f64 {
    common::thread_cpu_s().expect("a thread CPU clock (Linux)")
}

/// Best µs of CPU per frame over five passes of `pass` (which does N frames).
fn us_per_frame(mut pass: impl FnMut()) -> f64 {
    (0..5)
        .map(|_| {
            let t = thread_cpu_s();
            pass();
            (thread_cpu_s() - t) * 1e6 / N as f64
        })
        .fold(f64::INFINITY, f64::min)
}

fn evict_and_warm(paths: &[PathBuf]) {
    for p in paths {
        let f = File::open(p).unwrap();
        f.sync_all().unwrap();
        // SAFETY: a plain system call on an open descriptor.
        unsafe { libc::posix_fadvise(f.as_raw_fd(), 0, 0, libc::POSIX_FADV_DONTNEED) };
    }
    for p in paths {
        std::hint::black_box(std::fs::read(p).unwrap());
    }
}

fn main() {
    let dir = tempfile::tempdir().unwrap();
    let frame8 = W * H + 292; // a PCC-like TIFF: 292-byte header, then pixels
    let frame16 = W * H * 2;
    let files: Vec<PathBuf> = (0..N)
        .map(|i| dir.path().join(format!("f_{i:05}.tif")))
        .collect();
    for (i, f) in files.iter().enumerate() {
        let v: Vec<u8> = (0..frame8).map(|k| (k * 7 + i) as u8).collect();
        std::fs::write(f, v).unwrap();
    }
    let big = dir.path().join("movie.raw");
    std::fs::write(
        &big,
        (0..N * frame16)
            .map(|k| (k * 13) as u8)
            .collect::<Vec<u8>>(),
    )
    .unwrap();
    let mut all = files.clone();
    all.push(big.clone());
    evict_and_warm(&all);
    let bytes8: Vec<u8> = files
        .iter()
        .flat_map(|f| std::fs::read(f).unwrap())
        .collect();
    let bytes16 = std::fs::read(&big).unwrap();

    let mut buf = vec![0u8; 1 << 20];
    let mut out = vec![0u16; W * H];
    let mut rows = vec![0u8; frame16];
    let row = W * 2;
    let movie = File::open(&big).unwrap();
    let results = [
        ("memcpy of a TIFF's bytes (the bench's baseline)", {
            us_per_frame(|| {
                for i in 0..N {
                    buf[..frame8].copy_from_slice(&bytes8[i * frame8..(i + 1) * frame8]);
                    std::hint::black_box(&buf);
                }
            })
        }),
        ("open + read whole file + close (no decoding)", {
            us_per_frame(|| {
                for f in &files {
                    let mut h = File::open(f).unwrap();
                    h.read_exact(&mut buf[..frame8]).unwrap();
                    std::hint::black_box(&buf);
                }
            })
        }),
        ("  … + widen to u16", {
            us_per_frame(|| {
                for f in &files {
                    let mut h = File::open(f).unwrap();
                    h.read_exact(&mut buf[..frame8]).unwrap();
                    for (d, s) in out.iter_mut().zip(&buf[292..frame8]) {
                        *d = u16::from(*s);
                    }
                    std::hint::black_box(&out);
                }
            })
        }),
        ("memcpy of a 16-bit frame (the bench's baseline)", {
            us_per_frame(|| {
                for i in 0..N {
                    rows.copy_from_slice(&bytes16[i * frame16..(i + 1) * frame16]);
                    std::hint::black_box(&rows);
                }
            })
        }),
        ("pread of a 16-bit frame", {
            let f = File::open(&big).unwrap();
            us_per_frame(|| {
                for i in 0..N {
                    f.read_exact_at(&mut rows, (i * frame16) as u64).unwrap();
                    std::hint::black_box(&rows);
                }
            })
        }),
        ("  … + rows reversed in place (bottom-up storage)", {
            let f = File::open(&big).unwrap();
            us_per_frame(|| {
                for i in 0..N {
                    f.read_exact_at(&mut rows, (i * frame16) as u64).unwrap();
                    for r in 0..H / 2 {
                        let (top, bottom) = rows.split_at_mut((H - 1 - r) * row);
                        top[r * row..(r + 1) * row].swap_with_slice(&mut bottom[..row]);
                    }
                    std::hint::black_box(&rows);
                }
            })
        }),
        ("mmap of a 16-bit frame + reversed copy + munmap", {
            let f = File::open(&big).unwrap();
            us_per_frame(|| {
                for i in 0..N {
                    let off = (i * frame16) as u64;
                    let start = off / 4096 * 4096;
                    let lead = (off - start) as usize;
                    // SAFETY: a read-only private mapping of an open file,
                    // read within its length, unmapped before the next one.
                    unsafe {
                        let p = libc::mmap(
                            std::ptr::null_mut(),
                            frame16 + lead,
                            libc::PROT_READ,
                            libc::MAP_PRIVATE,
                            f.as_raw_fd(),
                            start as libc::off_t,
                        );
                        assert_ne!(p, libc::MAP_FAILED);
                        let src = std::slice::from_raw_parts((p as *const u8).add(lead), frame16);
                        for (s, d) in src.chunks_exact(row).zip(rows.rchunks_exact_mut(row)) {
                            d.copy_from_slice(s);
                        }
                        libc::munmap(p, frame16 + lead);
                    }
                    std::hint::black_box(&rows);
                }
            })
        }),
        (
            "mmap of the whole file once, reversed copy per frame (faulting)",
            { whole_file_mmap(&movie, frame16, row, &mut rows, 0, true) },
        ),
        ("  … MAP_POPULATE (faults not timed)", {
            whole_file_mmap(&movie, frame16, row, &mut rows, libc::MAP_POPULATE, true)
        }),
        ("  … MAP_POPULATE, plain memcpy per frame (no reversal)", {
            whole_file_mmap(&movie, frame16, row, &mut rows, libc::MAP_POPULATE, false)
        }),
    ];
    for (name, us) in results {
        println!("{us:6.1} µs/frame  {name}");
    }
}

/// Best µs of CPU per frame over five passes that each map the whole movie
/// once (`extra` flags, e.g. `MAP_POPULATE`, applied before the clock
/// starts) and copy every frame out of the mapping, rows reversed or not.
fn whole_file_mmap(
    f: &File,
    frame: usize,
    row: usize,
    out: &mut [u8],
    extra: libc::c_int,
    reverse: bool,
) -> f64 {
    let len = N * frame;
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        // SAFETY: a read-only private mapping of an open file that nothing
        // truncates, read within its length, unmapped at the end of the pass.
        unsafe {
            let p = libc::mmap(
                std::ptr::null_mut(),
                len,
                libc::PROT_READ,
                libc::MAP_PRIVATE | extra,
                f.as_raw_fd(),
                0,
            );
            assert_ne!(p, libc::MAP_FAILED);
            let all = std::slice::from_raw_parts(p as *const u8, len);
            let t = thread_cpu_s();
            for i in 0..N {
                let src = &all[i * frame..(i + 1) * frame];
                if reverse {
                    for (s, d) in src.chunks_exact(row).zip(out.rchunks_exact_mut(row)) {
                        d.copy_from_slice(s);
                    }
                } else {
                    out.copy_from_slice(src);
                }
                std::hint::black_box(&out);
            }
            best = best.min((thread_cpu_s() - t) * 1e6 / N as f64);
            libc::munmap(p, len);
        }
    }
    best
}
