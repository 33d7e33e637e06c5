//! What the main job and `process` show while they run: on a terminal, an overall bar and
//! a spinner per run in flight (indicatif); otherwise (a log file, CI) one
//! plain line per finished run. Either way a failed run's reason is printed
//! when it fails, not only at the end.

use crate::dataset::{DropRecord, DropStatus};
use crate::job::batch::RunEvent;
use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Duration;

/// Progress of one job, fed by [`RunEvent`]s from any thread.
pub struct JobProgress {
    bars: Option<Bars>,
    total: AtomicUsize,
    done: AtomicUsize,
}

struct Bars {
    multi: MultiProgress,
    overall: ProgressBar,
    running: Mutex<BTreeMap<String, ProgressBar>>,
    failed: AtomicUsize,
    cached: AtomicUsize,
}

/// The line printed for a finished run: its status, and for a run this job
/// measured its frames and speed (`seconds` is its own time, not the job's),
/// else "(cached)".
pub fn run_line(record: &DropRecord, frames: usize, seconds: Option<f64>) -> String {
    let from = match seconds {
        None => " (cached)".to_string(),
        Some(_) if record.status == DropStatus::Failed => String::new(),
        Some(s) => format!(
            " ({frames} frames in {s:.2} s, {:.0} frames/s)",
            frames as f64 / s.max(1e-9)
        ),
    };
    match record.status {
        DropStatus::Failed => format!("{}: failed{from}: {}", record.run, record.reason),
        DropStatus::Warning => format!(
            "{}: measured{from}, with warnings: {}",
            record.run, record.reason
        ),
        DropStatus::Ok => format!("{}: measured{from}", record.run),
        DropStatus::Tracked => format!(
            "{}: tracked{from}, no impact measured: {}",
            record.run, record.reason
        ),
        DropStatus::Rejected | DropStatus::Accepted => {
            format!("{}: measured{from}, {}", record.run, record.reason)
        }
    }
}

/// What the job says once at its end, whatever the terminal, of its runs'
/// rows (cached ones too): the runs measured at a frame rate nobody gave
/// (`fps_assumed`), by where it came from, and the runs whose frame rate
/// given disagrees with their recording's (`fps_mismatch` from the manifest or
/// `--fps`), and the runs whose apparent size per mm disagrees with their
/// set-up's (`radius_disagreement`).
pub fn closing_warnings(records: &[DropRecord]) -> Vec<String> {
    fn flagged<'a>(
        records: &'a [DropRecord],
        word: &'a str,
    ) -> impl Iterator<Item = &'a DropRecord> + 'a {
        records
            .iter()
            .filter(move |r| r.flags.split(' ').any(|w| w == word))
    }
    let mut out = Vec::new();
    for (source, from) in [
        (
            "default",
            "dropscope's default, a guess: nothing gave one (pass --fps, or the manifest's \
             fps column, or set camera.fps)",
        ),
        (
            "config",
            "camera.fps of the configuration (pass --fps, or the manifest's fps column, if \
             that is not theirs)",
        ),
    ] {
        let runs: Vec<&DropRecord> = flagged(records, crate::measure::quality::FPS_ASSUMED)
            .filter(|r| r.fps_source == source)
            .collect();
        if let Some(first) = runs.first() {
            out.push(format!(
                "frame rate assumed for {} holding none: {} frames/s (fps_source {source}), \
                 {from}: {}",
                crate::util::text::plural(runs.len(), "recording"),
                first.fps.unwrap_or(f64::NAN),
                names(&runs)
            ));
        }
    }
    for r in flagged(records, crate::measure::quality::RADIUS_DISAGREEMENT) {
        if let Some(s) = r
            .reason
            .split("; ")
            .find(|s| s.contains("px per mm of sphere radius"))
        {
            out.push(format!("{} (set-up {}): {s}", r.run, r.setup));
        }
    }
    for r in flagged(records, crate::measure::quality::FPS_MISMATCH) {
        if let Some(s) = r
            .reason
            .split("; ")
            .find(|s| s.contains("disagrees with the recording's own frame rate"))
        {
            out.push(format!("{}: {s}", r.run));
        }
    }
    out
}

/// Run names for a message: the first five, then how many more.
fn names(runs: &[&DropRecord]) -> String {
    let mut text: Vec<&str> = runs.iter().take(5).map(|r| r.run.as_str()).collect();
    let more = runs.len().saturating_sub(5);
    let more = format!("and {more} more");
    if runs.len() > 5 {
        text.push(&more);
    }
    text.join(", ")
}

impl JobProgress {
    /// Bars when stderr is a terminal, plain lines otherwise.
    pub fn new() -> Self {
        Self::with_bars(std::io::stderr().is_terminal())
    }

    /// Bars (`true`) or plain lines (`false`).
    pub fn with_bars(bars: bool) -> Self {
        let bars = bars.then(|| {
            let multi = MultiProgress::with_draw_target(ProgressDrawTarget::stderr());
            let overall = multi.add(ProgressBar::new(0));
            overall.set_style(
                ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {pos}/{len} runs {msg}")
                    .unwrap_or_else(|_| ProgressStyle::default_bar())
                    .progress_chars("=> "),
            );
            Bars {
                multi,
                overall,
                running: Mutex::new(BTreeMap::new()),
                failed: AtomicUsize::new(0),
                cached: AtomicUsize::new(0),
            }
        });
        JobProgress {
            bars,
            total: AtomicUsize::new(0),
            done: AtomicUsize::new(0),
        }
    }

    /// Take one event.
    pub fn event(&self, e: RunEvent) {
        match e {
            RunEvent::Planned { runs } => {
                self.total.store(runs, Ordering::Relaxed);
                if let Some(b) = &self.bars {
                    b.overall.set_length(runs as u64);
                }
            }
            RunEvent::Started { run } => {
                if let Some(b) = &self.bars {
                    let s = b.multi.add(ProgressBar::new_spinner());
                    s.set_style(
                        ProgressStyle::with_template("  {spinner} {msg} {elapsed}")
                            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
                    );
                    s.set_message(crate::util::text::terminal(run).into_owned());
                    s.enable_steady_tick(Duration::from_millis(120));
                    if let Ok(mut m) = b.running.lock() {
                        m.insert(run.to_string(), s);
                    }
                }
            }
            RunEvent::Notice(message) => match &self.bars {
                None => crate::errln!("{message}"),
                Some(b) => {
                    let _ = b.multi.println(crate::util::text::terminal(message));
                }
            },
            RunEvent::Collapsing => match &self.bars {
                None => crate::errln!("collapse …"),
                Some(b) => b.overall.set_message("collapse …"),
            },
            RunEvent::Finished {
                record,
                cached,
                frames,
                seconds,
            } => {
                let k = self.done.fetch_add(1, Ordering::Relaxed) + 1;
                let n = self.total.load(Ordering::Relaxed);
                match &self.bars {
                    None => crate::errln!("[{k}/{n}] {}", run_line(record, frames, seconds)),
                    Some(b) => {
                        if let Some(s) = b
                            .running
                            .lock()
                            .ok()
                            .and_then(|mut m| m.remove(&record.run))
                        {
                            s.finish_and_clear();
                            b.multi.remove(&s);
                        }
                        if cached {
                            b.cached.fetch_add(1, Ordering::Relaxed);
                        }
                        if record.status == DropStatus::Failed {
                            b.failed.fetch_add(1, Ordering::Relaxed);
                        }
                        if !record.status.measured() {
                            let _ = b.multi.println(crate::util::text::terminal(&run_line(
                                record, frames, seconds,
                            )));
                        }
                        b.overall.set_message(format!(
                            "({} failed, {} cached)",
                            b.failed.load(Ordering::Relaxed),
                            b.cached.load(Ordering::Relaxed)
                        ));
                        b.overall.inc(1);
                    }
                }
            }
        }
    }

    /// Remove the bars (before the summary is printed).
    pub fn finish(&self) {
        if let Some(b) = &self.bars {
            b.overall.finish_and_clear();
            let _ = b.multi.clear();
        }
    }
}

impl Default for JobProgress {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_say_status_reason_and_cache() {
        let mut r = DropRecord::failed("R3_01", 3.0, "no sphere found in 97 frames");
        assert_eq!(
            run_line(&r, 97, Some(0.5)),
            "R3_01: failed: no sphere found in 97 frames"
        );
        r.status = DropStatus::Ok;
        assert_eq!(run_line(&r, 97, None), "R3_01: measured (cached)");
        // The run's own speed, not the job's.
        assert_eq!(
            run_line(&r, 400, Some(0.25)),
            "R3_01: measured (400 frames in 0.25 s, 1600 frames/s)"
        );
        // Bars off the terminal take every event without drawing.
        let p = JobProgress::with_bars(true);
        p.event(RunEvent::Planned { runs: 1 });
        p.event(RunEvent::Started { run: "R3_01" });
        p.event(RunEvent::Finished {
            record: &r,
            cached: false,
            frames: 10,
            seconds: Some(0.1),
        });
        assert_eq!(p.done.load(Ordering::Relaxed), 1);
        assert!(p.bars.as_ref().unwrap().running.lock().unwrap().is_empty());
        p.finish();
    }
}
