//! `dropscope review` as a person uses it: the page in headless Chromium
//! (through chromedriver) on a rendered campaign, rejecting a drop,
//! excluding the frames of a planted defect and setting a surface row by
//! hand, then `dropscope run` honouring review.csv ([`page`]); the server's
//! refusals of bad requests, its one-review-per-folder lock and its stop
//! on Ctrl-C ([`refusals`]); a folder of a thousand drops a page at a time.

use crate::webdriver::{http, Driver};
use dropscope::dataset::{read_csv, DropRecord, TrackRow};
use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

mod page;
mod refusals;

fn exe() -> &'static str {
    env!("CARGO_BIN_EXE_dropscope")
}

/// `dropscope ARGS…` in `cwd`.
fn dropscope(cwd: &Path, args: &[&str]) -> Output {
    Command::new(exe())
        .current_dir(cwd)
        .args(args)
        .output()
        .unwrap()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// A `dropscope review` running in the background, with its address.
struct Review {
    child: Child,
    port: u16,
    token: String,
    url: String,
    stderr: PathBuf,
}

impl Review {
    /// Start `dropscope review OUT --config CFG` and read the address it prints.
    fn start(cwd: &Path, out: &Path, cfg: &Path) -> Review {
        let stderr = cwd.join(format!("review-{}.err", std::process::id()));
        let mut child = Command::new(exe())
            .current_dir(cwd)
            .arg("review")
            .arg(out)
            .arg("--config")
            .arg(cfg)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(&stderr).unwrap())
            .spawn()
            .unwrap();
        let mut line = String::new();
        std::io::BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        let url = line
            .split_whitespace()
            .find(|w| w.starts_with("http://"))
            .unwrap_or_else(|| {
                panic!(
                    "no address printed: {line:?}; stderr: {}",
                    std::fs::read_to_string(&stderr).unwrap_or_default()
                )
            })
            .to_string();
        assert!(url.starts_with("http://127.0.0.1:"), "{url}");
        let port: u16 = url["http://127.0.0.1:".len()..]
            .split('/')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        let token = url.split("token=").nth(1).unwrap().to_string();
        assert_eq!(token.len(), 32, "{url}");
        Review {
            child,
            port,
            token,
            url,
            stderr,
        }
    }

    /// Ctrl-C (SIGINT); the exit status and what it said on stderr.
    fn interrupt(mut self) -> (std::process::ExitStatus, String) {
        // SAFETY: a signal to our own child process.
        unsafe {
            libc::kill(self.child.id() as libc::pid_t, libc::SIGINT);
        }
        let deadline = Instant::now() + Duration::from_secs(20);
        let status = loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                break s;
            }
            assert!(
                Instant::now() < deadline,
                "dropscope review did not stop within 20 s of Ctrl-C"
            );
            std::thread::sleep(Duration::from_millis(20));
        };
        (
            status,
            std::fs::read_to_string(&self.stderr).unwrap_or_default(),
        )
    }

    fn get(&self, target: &str) -> (u16, Vec<u8>) {
        let (s, _, b) = http(self.port, "GET", target, &[], b"");
        (s, b)
    }
}

impl Drop for Review {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A pipeline.toml beside `manifest` (camera set-ups not inferred: each
/// run its own, so a decision about one run touches no other), writing to
/// `out`.
fn write_config(dir: &Path, manifest: &Path, out: &Path) -> PathBuf {
    let cfg = dir.join("pipeline.toml");
    std::fs::write(
        &cfg,
        format!(
            "[input]\nmanifest = \"{}\"\nsurface = \"pdms\"\n[camera]\ninfer_setups = false\n\
             [surface.pdms]\nmodulus_pa = 1.6e6\npillar_height_mm = 3.5\n\
             pillar_width_mm = 2.5\nchannel_width_mm = 1.5\n[output]\ndir = \"{}\"\n",
            manifest.display(),
            out.display()
        ),
    )
    .unwrap();
    cfg
}

fn track(out: &Path, run: &str) -> Vec<TrackRow> {
    csv::Reader::from_path(out.join(format!("tracks/{run}.csv")))
        .unwrap()
        .deserialize()
        .map(Result::unwrap)
        .collect()
}

/// A folder of 1 000 drops: the list holds them all, shows them 50 to a
/// page, sorts and filters over all of them, and opens a drop of the last
/// page with its frames drawn as asked.
#[test]
fn a_folder_of_a_thousand_drops_is_listed_a_page_at_a_time_and_any_drop_opens() {
    need!(crate::Need::Chromium, crate::Need::ChromeDriver);
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    crate::run::fixture_manifest(d);
    let out = d.join("out");
    let cfg = write_config(d, &d.join("runs.csv"), &out);
    let job = dropscope(d, &["run", "--config", cfg.to_str().unwrap()]);
    assert!(job.status.success(), "{}", text(&job.stderr));
    // 1 000 drops made of the three measured ones, each δmax its own (a
    // permutation of 1.000…1.999 mm), the tracks of the one to open.
    let three = read_csv(&out.join("drops.csv")).unwrap();
    let delta = |i: usize| 1.0 + ((i * 7919) % 1000) as f64 * 1e-3;
    let many: Vec<DropRecord> = (0..1000)
        .map(|i| {
            let mut r = three[i % 3].clone();
            r.run = format!("D{:04}_{}", i + 1, r.run);
            r.delta_max_mm = Some(delta(i));
            r
        })
        .collect();
    dropscope::dataset::write_csv(&out.join("drops.csv"), &many).unwrap();
    let far = &many[998];
    let base = &three[998 % 3];
    std::fs::copy(
        out.join(format!("tracks/{}.csv", base.run)),
        out.join(format!("tracks/{}.csv", far.run)),
    )
    .unwrap();

    let review = Review::start(d, &out, &cfg);
    let (s, body) = review.get(&format!("/api/drops?token={}", review.token));
    assert_eq!(s, 200);
    let profile = tempfile::tempdir_in(d).unwrap();
    let b = Driver::start(profile.path());
    let t0 = Instant::now();
    b.goto(&review.url);
    b.wait_for(
        "return document.getElementById('count').textContent === '1000 of 1000 drops'",
        "the list of 1 000",
    );
    eprintln!(
        "1 000 drops: the list ({} kB of JSON) shown in {:.2} s",
        body.len() / 1000,
        t0.elapsed().as_secs_f64()
    );
    let rows_shown = "return document.querySelectorAll('#drops tbody tr').length";
    assert_eq!(b.script(rows_shown), 50);
    assert_eq!(
        b.script("return document.getElementById('page-no').textContent"),
        "page 1 of 20"
    );
    let first_run = "return document.querySelector('#drops tbody tr').dataset.run";
    b.click("#next-page");
    assert_eq!(b.script(first_run), many[50].run.as_str());
    // Sorted by δmax over all 1 000: the smallest first, the largest first.
    let smallest = (0..1000)
        .min_by(|&i, &j| delta(i).total_cmp(&delta(j)))
        .unwrap();
    let largest = (0..1000)
        .max_by(|&i, &j| delta(i).total_cmp(&delta(j)))
        .unwrap();
    b.click("th[data-sort=\"delta\"]");
    assert_eq!(
        b.script("return document.getElementById('page-no').textContent"),
        "page 2 of 20",
        "sorting keeps the page"
    );
    b.click("#prev-page");
    assert_eq!(b.script(first_run), many[smallest].run.as_str());
    b.click("th[data-sort=\"delta\"]");
    assert_eq!(b.script(first_run), many[largest].run.as_str());
    // Filtered over all of them, and the drop of the last page opened.
    b.type_into("#filter", &far.run[..5]);
    assert_eq!(b.script(rows_shown), 1);
    assert_eq!(
        b.script("return document.getElementById('count').textContent"),
        "1 of 1000 drops"
    );
    b.click(&format!("tr[data-run=\"{}\"]", far.run));
    let frame = b.wait_for(
        "const i = document.getElementById('frame'); return !document.getElementById('drop').hidden \
         && i.complete && i.naturalWidth > 0 && i.dataset.frame",
        "the drop's frame",
    );
    let rows = track(&out, &far.run);
    let peak = rows
        .iter()
        .min_by(|a, b| {
            (a.t_s - far.t_max_s.unwrap())
                .abs()
                .total_cmp(&(b.t_s - far.t_max_s.unwrap()).abs())
        })
        .unwrap();
    assert_eq!(frame, peak.frame.to_string());
    drop(b);
    let (status, said) = review.interrupt();
    assert!(status.success(), "{status}: {said}");
}
