//! `--timings`: where a job's time goes, stage by stage. Each
//! stage's work is wrapped in [`time`]; with timings on ([`enable`]), its
//! wall time and its thread's CPU time are summed over every run and
//! thread, and [`table`] prints them after the job. With timings off,
//! [`time`] only calls its work. No output file depends on them.
//!
//! A stage's time is its own: a stage started inside another (a frame read
//! in pass 1, a force fit in the events stage, another run's work a thread
//! takes up while it waits in a stage) is taken out of the outer one, so
//! the stages add up without counting anything twice. Work outside every
//! stage (thread start-up, waiting for other threads outside a stage) is in
//! no row: the table's sum is at most the job's wall time × its threads.

use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Instant;

/// A stage of a job, in the order the work meets them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// The input's fingerprint for the result cache, and the cache lookup.
    Fingerprint,
    /// Opening a run: its folder's listing and headers, or the `.cine` header.
    Open,
    /// Frames read and decoded (whole frames and bands of rows).
    Read,
    /// The background from frames spread over the movie.
    Background,
    /// The surface line fitted to the background.
    Surface,
    /// Tracking pass 1 (radius free) and the radius calibration.
    Pass1,
    /// Tracking pass 2 (radius held).
    Pass2,
    /// Tracks put in the job's temporary file when the runs' set-ups are
    /// read, and read back for their processing ([`crate::pipeline::shelf`]).
    Shelf,
    /// Events, kinematics, scale and the force table: the measurement but
    /// for the force fits.
    Events,
    /// The force law's fits with n free, one per contact model.
    ForceFree,
    /// Under the best model, n held at 2.
    ForceN2,
    /// Under the best model, n and the surface free (the line's cross-check).
    ForceSurface,
    /// The overlay at the maximum penetration, and any asked for.
    Overlays,
    /// The animated impact (drawing and APNG encoding).
    Animation,
    /// Files written: tracks, overlays, animations, cache entries,
    /// drops.csv, provenance.json.
    Writes,
    /// The per-drop figures (`plots/drops/`).
    Figures,
    /// The collapse (the main job).
    Collapse,
    /// report.html (the main job).
    Report,
}

impl Stage {
    /// Every stage, in the table's order.
    pub const ALL: [Stage; 18] = [
        Stage::Fingerprint,
        Stage::Open,
        Stage::Read,
        Stage::Background,
        Stage::Surface,
        Stage::Pass1,
        Stage::Pass2,
        Stage::Shelf,
        Stage::Events,
        Stage::ForceFree,
        Stage::ForceN2,
        Stage::ForceSurface,
        Stage::Overlays,
        Stage::Animation,
        Stage::Writes,
        Stage::Figures,
        Stage::Collapse,
        Stage::Report,
    ];

    /// Its name in the table.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Fingerprint => "input fingerprint (cache)",
            Stage::Open => "open (listing, headers)",
            Stage::Read => "read frames (decode)",
            Stage::Background => "background",
            Stage::Surface => "surface line",
            Stage::Pass1 => "tracking pass 1",
            Stage::Pass2 => "tracking pass 2",
            Stage::Shelf => "tracks kept (temporary file)",
            Stage::Events => "events, kinematics, scale",
            Stage::ForceFree => "force fits (n free, 4 contact models)",
            Stage::ForceN2 => "force fit (n = 2)",
            Stage::ForceSurface => "force fit (n and surface free)",
            Stage::Overlays => "overlay stills",
            Stage::Animation => "animated impact (APNG)",
            Stage::Writes => "file writes (tracks, images, cache)",
            Stage::Figures => "per-drop figures",
            Stage::Collapse => "collapse",
            Stage::Report => "report.html",
        }
    }

    fn index(self) -> usize {
        self as usize
    }
}

const N: usize = Stage::ALL.len();

static ENABLED: AtomicBool = AtomicBool::new(false);
static WALL_NS: [AtomicU64; N] = [const { AtomicU64::new(0) }; N];
static CPU_NS: [AtomicU64; N] = [const { AtomicU64::new(0) }; N];

/// Time the stages from now on (the sums so far are kept).
pub fn enable() {
    ENABLED.store(true, Ordering::Relaxed);
}

/// CPU time of the calling thread, seconds.
pub fn thread_cpu_s() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: a valid, writable timespec.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// A stage open on this thread: when it started, and its inner stages' time.
struct Open {
    stage: Stage,
    wall0: Instant,
    cpu0: f64,
    inner_wall_s: f64,
    inner_cpu_s: f64,
}

thread_local! {
    static OPEN: RefCell<Vec<Open>> = const { RefCell::new(Vec::new()) };
    /// Whether this thread is counted in [`WORKERS`] yet.
    static COUNTED: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Worker threads (of any rayon pool) that timed a stage: what `--threads`
/// bounds, shown by [`table`].
static WORKERS: AtomicU64 = AtomicU64::new(0);

/// A stage open on this thread ([`start`]): closed when dropped, also
/// when the work panics.
pub struct Timed(Stage);

impl Drop for Timed {
    fn drop(&mut self) {
        let (wall1, cpu1) = (Instant::now(), thread_cpu_s());
        OPEN.with(|open| {
            let mut open = open.borrow_mut();
            let Some(o) = open.pop() else { return };
            let wall = wall1.duration_since(o.wall0).as_secs_f64();
            let cpu = (cpu1 - o.cpu0).max(0.0);
            let ns = |s: f64| (s.max(0.0) * 1e9) as u64;
            let i = self.0.index();
            WALL_NS[i].fetch_add(ns(wall - o.inner_wall_s), Ordering::Relaxed);
            CPU_NS[i].fetch_add(ns(cpu - o.inner_cpu_s), Ordering::Relaxed);
            if let Some(outer) = open.last_mut() {
                outer.inner_wall_s += wall;
                outer.inner_cpu_s += cpu;
            }
        });
    }
}

/// Open `stage` on this thread until the value returned is dropped (`None`
/// with timings off).
#[must_use = "the stage closes when this is dropped"]
pub fn start(stage: Stage) -> Option<Timed> {
    if !ENABLED.load(Ordering::Relaxed) {
        return None;
    }
    if rayon::current_thread_index().is_some() && !COUNTED.replace(true) {
        WORKERS.fetch_add(1, Ordering::Relaxed);
    }
    OPEN.with(|open| {
        open.borrow_mut().push(Open {
            stage,
            wall0: Instant::now(),
            cpu0: thread_cpu_s(),
            inner_wall_s: 0.0,
            inner_cpu_s: 0.0,
        })
    });
    Some(Timed(stage))
}

/// The innermost stage open on this thread (`None` with timings off): for
/// work this stage hands to another thread ([`rayon::join`]), which is
/// timed as the same stage with [`start`] there.
pub fn current() -> Option<Stage> {
    OPEN.with(|open| open.borrow().last().map(|o| o.stage))
}

/// Run `work` as (part of) `stage`.
pub fn time<T>(stage: Stage, work: impl FnOnce() -> T) -> T {
    let _timed = start(stage);
    work()
}

/// One stage's sums so far: (stage, wall s, CPU s).
pub fn sums() -> Vec<(Stage, f64, f64)> {
    Stage::ALL
        .iter()
        .map(|&s| {
            let get = |a: &[AtomicU64; N]| a[s.index()].load(Ordering::Relaxed) as f64 * 1e-9;
            (s, get(&WALL_NS), get(&CPU_NS))
        })
        .collect()
}

/// The table printed after a job: per stage its wall and CPU seconds summed
/// over runs and threads, its share of the stages' sum, and its mean per
/// drop over the `drops` this job measured (cached runs cost none of this);
/// then the job's own wall time on its `threads`, and how many worker
/// threads did the stages' work (more than `threads` would be work outside
/// the job's pool).
pub fn table(drops: usize, job_wall_s: f64, threads: usize) -> String {
    use std::fmt::Write;
    let rows = sums();
    let (wall_sum, cpu_sum) = rows.iter().fold((0.0, 0.0), |(w, c), r| (w + r.1, c + r.2));
    let share = |v: f64, sum: f64| 100.0 * v / if sum > 0.0 { sum } else { 1.0 };
    let per_drop = |v: f64| {
        if drops == 0 {
            "-".to_string()
        } else {
            format!("{:.2}", v / drops as f64 * 1e3)
        }
    };
    let mut t = format!(
        "timings, summed over runs and threads ({} measured):\n\
         {:<36} {:>9} {:>7} {:>9} {:>7} {:>12} {:>11}\n",
        crate::util::text::plural(drops, "drop"),
        "stage",
        "wall s",
        "share",
        "CPU s",
        "share",
        "wall ms/drop",
        "CPU ms/drop"
    );
    let mut line = |name: &str, w: f64, c: f64| {
        let _ = writeln!(
            t,
            "{name:<36} {w:>9.3} {:>6.1}% {c:>9.3} {:>6.1}% {:>12} {:>11}",
            share(w, wall_sum),
            share(c, cpu_sum),
            per_drop(w),
            per_drop(c)
        );
    };
    for (s, w, c) in &rows {
        line(s.name(), *w, *c);
    }
    line("sum of the stages", wall_sum, cpu_sum);
    let _ = write!(
        t,
        "job: {job_wall_s:.3} s wall on {} ({:.3} thread-seconds); its stages ran on {}",
        crate::util::text::plural(threads, "thread"),
        job_wall_s * threads as f64,
        crate::util::text::plural(WORKERS.load(Ordering::Relaxed) as usize, "worker thread")
    );
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An inner stage's time is taken out of the outer one's, a stage is
    /// closed by a panic too, and the table names every stage.
    #[test]
    fn inner_stages_are_taken_out_of_outer_ones() {
        enable();
        let r = std::panic::catch_unwind(|| time(Stage::Report, || panic!("inside a stage")));
        assert!(r.is_err());
        OPEN.with(|o| assert!(o.borrow().is_empty(), "the panic left a stage open"));
        let before = sums();
        let spin = |s: f64| {
            let t0 = Instant::now();
            while t0.elapsed().as_secs_f64() < s {
                std::hint::black_box(0);
            }
        };
        let t0 = Instant::now();
        time(Stage::Collapse, || {
            spin(0.01);
            time(Stage::Report, || spin(0.05));
        });
        let outside_s = t0.elapsed().as_secs_f64();
        let after = sums();
        let got = |s: Stage| {
            let i = s.index();
            (after[i].1 - before[i].1, after[i].2 - before[i].2)
        };
        let (collapse_wall, collapse_cpu) = got(Stage::Collapse);
        let (report_wall, report_cpu) = got(Stage::Report);
        // No other test of this binary times these two stages (the main
        // job's), so: each has at least the time it spun, and the two add up
        // to no more than the whole block took (counted twice, the inner
        // 50 ms would be in both).
        assert!(collapse_wall >= 0.01 && report_wall >= 0.05);
        assert!(collapse_cpu >= 0.0 && report_cpu >= 0.0);
        assert!(
            collapse_wall + report_wall <= outside_s + 1e-6,
            "collapse {collapse_wall} s + report {report_wall} s > {outside_s} s"
        );
        // Work this stage hands to another thread, timed there as the stage
        // `current` names, is counted in it: 20 ms of the other thread's CPU.
        let before = sums();
        time(Stage::Collapse, || {
            let stage = current();
            assert_eq!(stage, Some(Stage::Collapse));
            std::thread::scope(|s| {
                s.spawn(|| {
                    assert_eq!(current(), None, "a new thread has no stage open");
                    let _timed = stage.and_then(start);
                    let c0 = thread_cpu_s();
                    while thread_cpu_s() - c0 < 0.02 {
                        std::hint::black_box(0);
                    }
                });
            });
        });
        let handed_cpu = sums()[Stage::Collapse.index()].2 - before[Stage::Collapse.index()].2;
        assert!(handed_cpu >= 0.02, "{handed_cpu} s");
        let t = table(3, 0.2, 2);
        for s in Stage::ALL {
            assert!(t.contains(s.name()), "{} missing:\n{t}", s.name());
        }
        assert!(
            t.contains("3 drops measured")
                && t.contains("on 2 threads (0.400 thread-seconds); its stages ran on "),
            "{t}"
        );
    }
}
