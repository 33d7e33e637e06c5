//! `dropscope review` as a person uses it: the page in headless Chromium
//! (through chromedriver) on a rendered campaign, rejecting a drop,
//! excluding the frames of a planted defect and setting a surface row by
//! hand, then `dropscope run` honouring review.csv; and the server's
//! refusals of bad requests, its one-review-per-folder lock and its stop
//! on Ctrl-C.

use crate::webdriver::{http, Driver};
use dropscope::dataset::decisions::{Decisions, Frames, Kind};
use dropscope::dataset::{read_csv, DropRecord, DropStatus, TrackRow};
use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

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

fn by<'a>(rows: &'a [DropRecord], run: &str) -> &'a DropRecord {
    rows.iter().find(|r| r.run == run).unwrap()
}

fn track(out: &Path, run: &str) -> Vec<TrackRow> {
    csv::Reader::from_path(out.join(format!("tracks/{run}.csv")))
        .unwrap()
        .deserialize()
        .map(Result::unwrap)
        .collect()
}

/// The summary line's "N reused from the cache".
fn reused(o: &Output) -> usize {
    let e = text(&o.stderr);
    let at = e
        .find(" reused from the cache")
        .unwrap_or_else(|| panic!("no summary: {e}"));
    e[..at]
        .rsplit(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap_or_else(|_| panic!("{e}"))
}

/// A torn frame: the picture above the surface line, in the columns of
/// the sphere and a margin, moved `px` rows down (as a read-out that
/// slipped would), so that the sphere sits `px` below its track in that
/// frame alone. Written back as an 8-bit TIFF.
fn displace_frame(frame_file: &Path, x_c: f64, r: f64, surface_row: f64, px: u32) {
    let img = image::open(frame_file).unwrap().to_luma8();
    let mut out = img.clone();
    let (w, _) = img.dimensions();
    let x0 = (x_c - r - 12.0).max(0.0) as u32;
    let x1 = ((x_c + r + 12.0) as u32).min(w - 1);
    let z_end = (surface_row - 2.0) as u32;
    for z in px..z_end {
        for x in x0..=x1 {
            out.put_pixel(x, z, *img.get_pixel(x, z - px));
        }
    }
    assert_ne!(out, img);
    out.save_with_format(frame_file, image::ImageFormat::Tiff)
        .unwrap();
}

/// The frame file of camera image `n` in a rendered run folder.
fn frame_file(run_dir: &Path, run: &str, n: i64) -> PathBuf {
    let name = if n < 0 {
        format!("{run}_-{:06}.tif", -n)
    } else {
        format!("{run}_{n:06}.tif")
    };
    let p = run_dir.join(name);
    assert!(p.is_file(), "{}", p.display());
    p
}

/// The quantities of `a` further than `k` errors from `b`'s, the errors
/// `sigma`'s.
fn off_by(a: &DropRecord, b: &DropRecord, sigma: &DropRecord, k: f64) -> Vec<String> {
    let q = |r: &DropRecord| {
        [
            ("v_impact_m_s", r.v_impact_m_s, r.v_impact_m_s_err),
            ("delta_max_mm", r.delta_max_mm, r.delta_max_mm_err),
            ("tau_c_ms", r.tau_c_ms, r.tau_c_ms_err),
            ("a_max_mm", r.a_max_mm, r.a_max_mm_err),
            ("restitution", r.restitution, r.restitution_err),
        ]
    };
    let mut off = Vec::new();
    for (((name, x, _), (_, y, _)), (_, _, e)) in q(a).into_iter().zip(q(b)).zip(q(sigma)) {
        let (x, y, e) = (x.unwrap(), y.unwrap(), e.unwrap());
        if (x - y).abs() > k * e {
            off.push(format!(
                "{name} {x} against {y}: {:.2} σ (σ = {e})",
                (x - y) / e
            ));
        }
    }
    off
}

/// A decision as review.csv holds it: run, kind, frames, value, reason.
type Said = (String, Kind, Option<Frames>, Option<f64>, String);

/// The whole round trip on a rendered campaign of four drops: one rejected
/// in the page, one with a planted defect whose frames are excluded in the
/// page, one whose surface row is set in the page (typed), one untouched.
/// The next `dropscope run` honours each and measures again only those
/// three; the one after measures nothing.
#[test]
fn the_page_in_chromium_rejects_excludes_and_sets_a_surface_and_the_job_honours_them() {
    need!(crate::Need::Chromium, crate::Need::ChromeDriver);
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let render = dropscope(
        d,
        &[
            "render", "--drop", "3:3", "--drop", "4:6", "--drop", "4.5:12", "--drop", "5:25",
            "--seed", "5", "--out", "camp",
        ],
    );
    assert!(render.status.success(), "{}", text(&render.stderr));
    let out = d.join("out");
    let cfg = write_config(d, &d.join("camp/runs.csv"), &out);
    let cfg_s = cfg.to_str().unwrap();
    let (rejected, defect, surfaced, untouched) = (
        "R3mm_H3cm_01",
        "R4.5mm_H12cm_01",
        "R5mm_H25cm_01",
        "R4mm_H6cm_01",
    );

    // The clean campaign.
    let first = dropscope(d, &["run", "--config", cfg_s]);
    assert!(first.status.success(), "{}", text(&first.stderr));
    let clean = read_csv(&out.join("drops.csv")).unwrap();
    assert!(clean.iter().all(|r| r.status == DropStatus::Ok));

    // A torn frame at the peak of one drop: its numbers move beyond their
    // errors.
    let c = by(&clean, defect);
    let rows = track(&out, defect);
    let peak = rows
        .iter()
        .min_by(|a, b| {
            (a.t_s - c.t_max_s.unwrap())
                .abs()
                .total_cmp(&(b.t_s - c.t_max_s.unwrap()).abs())
        })
        .unwrap();
    let bad_frame = peak.frame;
    displace_frame(
        &frame_file(&d.join("camp").join(defect), defect, bad_frame),
        peak.x_px.unwrap(),
        peak.r_px.unwrap(),
        c.surface_row_px.unwrap(),
        4,
    );
    let spoilt_run = dropscope(d, &["run", "--config", cfg_s]);
    assert_eq!(reused(&spoilt_run), 3, "{}", text(&spoilt_run.stderr));
    let spoilt = read_csv(&out.join("drops.csv")).unwrap();
    let moved = off_by(by(&spoilt, defect), c, c, 3.0);
    eprintln!("with the torn frame {bad_frame}: {moved:?}");
    assert!(
        moved.iter().any(|m| m.starts_with("delta_max_mm")),
        "the torn frame moved δmax by less than 3 σ: the test would prove nothing ({moved:?})"
    );

    // The page, in Chromium.
    let review = Review::start(d, &out, &cfg);
    let profile = tempfile::tempdir_in(d).unwrap();
    let b = Driver::start(profile.path());
    b.goto(&review.url);
    b.wait_for(
        "return document.querySelectorAll('#drops tbody tr').length === 4",
        "the drop list",
    );
    let open = |run: &str| {
        b.click(&format!("tr[data-run=\"{run}\"]"));
        b.wait_for(
            &format!(
                "const i = document.getElementById('frame'); return !document.getElementById('drop').hidden \
                 && document.getElementById('drop-title').textContent === '{run}' && i.complete \
                 && i.naturalWidth > 0 && i.dataset.frame"
            ),
            &format!("{run}'s first frame"),
        )
    };
    let saved = |what: &str| {
        b.wait_for(
            &format!("const s = document.getElementById('said').textContent; return s.includes('{what}') && s.includes('saved')"),
            what,
        );
    };
    let back = || {
        b.click("#back");
        b.wait_for("return !document.getElementById('list').hidden", "the list");
    };

    // Reject one drop.
    open(rejected);
    b.type_into("#verdict-reason", "two spheres in view");
    b.click("#reject");
    saved("rejected");
    back();

    // Step through the torn frame's drop, and exclude it with its
    // neighbours.
    let shown = open(defect);
    assert_eq!(
        shown.as_str().unwrap(),
        bad_frame.to_string(),
        "opens at δmax"
    );
    let frame_no = || -> i64 {
        b.script("return document.getElementById('frame-no').value")
            .as_str()
            .unwrap()
            .parse()
            .unwrap()
    };
    b.click("#frame"); // the focus on the page, off any field
    for _ in 0..2 {
        b.press("\u{E014}"); // →
    }
    assert_eq!(frame_no(), bad_frame + 2, "→ steps a frame");
    b.wait_for(
        &format!(
            "return document.getElementById('frame').dataset.frame === '{}'",
            bad_frame + 2
        ),
        "the frame drawn",
    );
    for _ in 0..3 {
        b.press("\u{E012}"); // ←
    }
    assert_eq!(frame_no(), bad_frame - 1, "← steps back");
    b.click("#ex-from-here");
    b.press("\u{E014}");
    b.press("\u{E014}");
    b.click("#ex-to-here");
    b.type_into("#ex-reason", "the frame tore: the ball 4 px low");
    b.click("#ex-save");
    saved("excluded");
    // The excluded frames are marked in the plots.
    b.wait_for(
        "return document.querySelectorAll('#plot-z circle[fill=\"#e600e6\"]').length === 3",
        "three excluded frames in z(t)",
    );
    if let Some(shot) = std::env::var_os("DROPSCOPE_SCREENSHOT") {
        // The README's picture of the page: two frames after the torn one.
        b.script(&format!(
            "const f = document.getElementById('frame-no'); f.value = {}; \
             f.dispatchEvent(new Event('change'));",
            bad_frame + 2
        ));
        b.wait_for(
            &format!(
                "const i = document.getElementById('frame'); return i.complete \
                 && i.dataset.frame === '{}'",
                bad_frame + 2
            ),
            "the frame for the screenshot",
        );
        std::fs::write(&shot, b.screenshot()).unwrap();
    }
    b.click("#go-onset");
    b.wait_for(
        "return document.getElementById('frame').dataset.frame === String(document.getElementById('frame-no').value)",
        "the onset",
    );
    back();

    // Set a surface row by hand: the rendered line's truth.
    let truth: serde_json::Value = serde_json::from_slice(
        &std::fs::read(d.join("camp").join(surfaced).join("truth.json")).unwrap(),
    )
    .unwrap();
    let true_row = truth["surface_row_px"].as_f64().unwrap()
        + truth["surface_slope"].as_f64().unwrap() * truth["impact_column_px"].as_f64().unwrap();
    let typed = format!("{true_row:.2}");
    open(surfaced);
    b.type_into("#surf-row", &typed);
    b.type_into("#surf-reason", "the band's top by eye");
    b.click("#surf-save");
    saved("surface row set");
    back();
    // The list says which drops have decisions.
    b.wait_for(
        "return document.querySelectorAll('#drops .decided').length === 3",
        "three drops marked as decided on",
    );
    drop(b);
    let (status, said) = review.interrupt();
    assert!(status.success(), "{status}: {said}");

    // review.csv holds the three decisions, as made.
    let decisions = Decisions::read(&out.join("review.csv")).unwrap();
    let rows: Vec<Said> = decisions
        .rows
        .iter()
        .map(|r| {
            (
                r.run.clone(),
                r.decision,
                r.frames,
                r.value,
                r.reason.clone(),
            )
        })
        .collect();
    assert_eq!(
        rows,
        vec![
            (
                rejected.to_string(),
                Kind::Reject,
                None,
                None,
                "two spheres in view".to_string()
            ),
            (
                defect.to_string(),
                Kind::Exclude,
                Some(Frames {
                    first: bad_frame - 1,
                    last: bad_frame + 1
                }),
                None,
                "the frame tore: the ball 4 px low".to_string()
            ),
            (
                surfaced.to_string(),
                Kind::Surface,
                None,
                Some(typed.parse().unwrap()),
                "the band's top by eye".to_string()
            ),
        ]
    );

    // The job honours them, measuring again only the three runs they touch.
    let rerun = dropscope(d, &["run", "--config", cfg_s]);
    assert!(rerun.status.success(), "{}", text(&rerun.stderr));
    assert_eq!(reused(&rerun), 1, "{}", text(&rerun.stderr));
    let after = read_csv(&out.join("drops.csv")).unwrap();
    // The rejected drop: its numbers kept, status rejected, out of the collapse.
    let r = by(&after, rejected);
    assert_eq!(r.status, DropStatus::Rejected);
    assert!(r
        .reason
        .starts_with("rejected in review: two spheres in view"));
    assert_eq!(r.delta_max_mm, by(&clean, rejected).delta_max_mm);
    let collapse = std::fs::read_to_string(out.join("collapse.csv")).unwrap();
    let used = |run: &str| {
        let mut rdr = csv::Reader::from_reader(collapse.as_bytes());
        let h = rdr.headers().unwrap().clone();
        let (ri, ui) = (
            h.iter().position(|c| c == "run").unwrap(),
            h.iter().position(|c| c == "used").unwrap(),
        );
        rdr.records()
            .map(Result::unwrap)
            .find(|row| &row[ri] == run)
            .map(|row| row[ui].to_string())
            .unwrap()
    };
    assert_eq!(used(rejected), "false");
    assert_eq!(used(untouched), "true");
    let fits = std::fs::read_to_string(out.join("fits.json")).unwrap();
    assert!(
        fits.contains("status rejected (rejected in review: two spheres in view"),
        "{fits}"
    );
    // The torn frame and its neighbours left out: its numbers back within
    // their errors of the clean render's. The gap they leave at the peak
    // is said (a warning).
    let fixed = by(&after, defect);
    assert_eq!(fixed.status, DropStatus::Warning, "{}", fixed.reason);
    assert_eq!(fixed.flags, "gap_in_contact gap_at_peak");
    let off = off_by(fixed, c, fixed, 1.0);
    eprintln!(
        "the defect's frames excluded: δmax {} against {} clean (σ {})",
        fixed.delta_max_mm.unwrap(),
        c.delta_max_mm.unwrap(),
        fixed.delta_max_mm_err.unwrap()
    );
    assert!(
        off.is_empty(),
        "not back within 1 σ of the clean render: {off:?}"
    );
    let flagged: Vec<i64> = track(&out, defect)
        .iter()
        .filter(|r| r.flags.split(' ').any(|w| w == "excluded"))
        .map(|r| r.frame)
        .collect();
    assert_eq!(flagged, vec![bad_frame - 1, bad_frame, bad_frame + 1]);
    // The surface set by hand is used, and said.
    let s = by(&after, surfaced);
    assert_eq!(s.surface_source, "review");
    let row = s.surface_row_px.unwrap();
    assert!((row - typed.parse::<f64>().unwrap()).abs() < 1e-6, "{row}");
    assert_eq!(
        s.surface_row_px_err,
        Some(dropscope::dataset::decisions::HAND_SURFACE_ERR_PX)
    );
    // …and shown: the page draws the row the job used, and says where it
    // came from.
    let shown = Review::start(d, &out, &cfg);
    let (status, body) = shown.get(&format!("/api/run?token={}&run={surfaced}", shown.token));
    assert_eq!(status, 200, "{}", text(&body));
    let j: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(j["surface"]["source"], "review");
    assert_eq!(j["surface"]["row_at_impact_px"].as_f64(), Some(row));
    let (status, said) = shown.interrupt();
    assert!(status.success(), "{status}: {said}");
    // The untouched drop is the same row.
    assert_eq!(by(&after, untouched), by(&clean, untouched));
    // The report and provenance.json show every decision.
    let report = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(report.contains("<h2>Review decisions</h2>"));
    for said in [
        "rejected: two spheres in view".to_string(),
        format!(
            "excluded frames {}:{} (the frame tore: the ball 4 px low)",
            bad_frame - 1,
            bad_frame + 1
        ),
        format!(
            "surface row {} px set by hand (the band&#39;s top by eye)",
            typed.parse::<f64>().unwrap()
        ),
    ] {
        assert!(report.contains(&said), "report.html lacks {said:?}");
    }
    let prov: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("provenance.json")).unwrap()).unwrap();
    assert_eq!(prov["review"]["decisions"].as_array().unwrap().len(), 3);
    assert_eq!(prov["review"]["decisions"][1]["decision"], "exclude");

    // Nothing changed since: every run from the cache.
    let again = dropscope(d, &["run", "--config", cfg_s]);
    assert_eq!(reused(&again), 4, "{}", text(&again.stderr));
}

/// Every request that is not the page's own, or names what is not in the
/// folder, gets a 4xx saying what was wrong and changes nothing; a second
/// review of the folder is told it is open; Ctrl-C stops the first and
/// frees the folder.
#[test]
fn bad_requests_are_refused_and_change_nothing_and_ctrl_c_stops_the_review() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    crate::run::fixture_manifest(d);
    let out = d.join("out");
    let cfg = write_config(d, &d.join("runs.csv"), &out);
    let job = dropscope(d, &["run", "--config", cfg.to_str().unwrap()]);
    assert!(job.status.success(), "{}", text(&job.stderr));
    let review = Review::start(d, &out, &cfg);
    let (port, t) = (review.port, review.token.clone());
    let run = "R4.5mm_H12cm_01";

    // What the page asks for, answered.
    let (s, page) = review.get(&format!("/?token={t}"));
    assert_eq!(s, 200);
    assert!(text(&page).contains(&format!("/page.js?token={t}")));
    // Nothing from the network: the page, its script and its style name no
    // other server (the one `http` in the script is SVG's namespace, a
    // name, not a request).
    for part in ["/", "/page.js", "/page.css"] {
        let (s, body) = review.get(&format!("{part}?token={t}"));
        assert_eq!(s, 200);
        let body = text(&body).replace("'http://www.w3.org/2000/svg'", "");
        assert!(
            !body.contains("http:") && !body.contains("https:") && !body.contains("//cdn"),
            "{part} names another server"
        );
    }
    let (s, body) = review.get(&format!(
        "/api/frame?token={t}&run={run}&frame=-30&view=contact"
    ));
    assert_eq!(s, 200);
    assert!(body.starts_with(b"\x89PNG"));
    let origin = format!("http://127.0.0.1:{port}");
    let json_post = |target: &str, body: &str, headers: &[(&str, &str)]| {
        let mut h = vec![("Content-Type", "application/json")];
        h.extend_from_slice(headers);
        let (s, _, b) = http(port, "POST", target, &h, body.as_bytes());
        (s, text(&b))
    };
    let (s, b) = json_post(
        &format!("/api/decide?token={t}"),
        &format!(r#"{{"run":"{run}","decision":"exclude","frames":"-3:-2","reason":"=dust"}}"#),
        &[("Origin", &origin)],
    );
    assert_eq!(s, 200, "{b}");
    let file = out.join("review.csv");
    let before = std::fs::read(&file).unwrap();
    assert!(
        text(&before).ends_with(&format!("{run},exclude,-3:-2,,'=dust,{}\n", {
            let d = Decisions::read(&file).unwrap();
            d.rows[0].time.clone()
        })),
        "{}",
        text(&before)
    );
    let drops_before = std::fs::read(out.join("drops.csv")).unwrap();

    let get = |target: String, headers: &[(&str, &str)]| {
        let (s, _, b) = http(port, "GET", &target, headers, b"");
        (s, text(&b))
    };
    let refusals: Vec<(String, (u16, String), &str)> = vec![
        ("no token".into(), get("/api/drops".into(), &[]), "no token"),
        (
            "a wrong token".into(),
            get(format!("/api/drops?token={}", "0".repeat(32)), &[]),
            "wrong token",
        ),
        (
            "the token twice".into(),
            get(format!("/api/drops?token={t}&token={t}"), &[]),
            "wrong token",
        ),
        (
            "the page without its token".into(),
            get("/".into(), &[]),
            "no token",
        ),
        (
            "another Host (DNS rebinding)".into(),
            get(
                format!("/api/drops?token={t}"),
                &[("Host", &format!("evil.example:{port}"))],
            ),
            "Host `evil.example",
        ),
        (
            "another origin".into(),
            get(
                format!("/api/drops?token={t}"),
                &[("Origin", "http://evil.example")],
            ),
            "another origin",
        ),
        (
            "another site".into(),
            get(
                format!("/api/drops?token={t}"),
                &[("Sec-Fetch-Site", "cross-site")],
            ),
            "another site",
        ),
        (
            "an unknown run".into(),
            get(format!("/api/run?token={t}&run=nope"), &[]),
            "no run `nope` in",
        ),
        (
            "a path for a run".into(),
            get(
                format!("/api/run?token={t}&run=..%2F..%2Fetc%2Fpasswd"),
                &[],
            ),
            "a run name, not a path",
        ),
        (
            "a path in the address".into(),
            get(format!("/..%2F..%2Fetc%2Fpasswd?token={t}"), &[]),
            "no page",
        ),
        (
            "a parameter naming a file".into(),
            get(
                format!("/api/run?token={t}&run={run}&file=%2Fetc%2Fpasswd"),
                &[],
            ),
            "unknown parameter `file`",
        ),
        (
            "a frame out of range".into(),
            get(format!("/api/frame?token={t}&run={run}&frame=99999"), &[]),
            "frame 99999 is not in run `R4.5mm_H12cm_01` (frames -30 to 56)",
        ),
        (
            "a frame that is no number".into(),
            get(format!("/api/frame?token={t}&run={run}&frame=..%2F1"), &[]),
            "not a camera image number",
        ),
        (
            "an unknown view".into(),
            get(
                format!("/api/frame?token={t}&run={run}&frame=0&view=..%2Fx"),
                &[],
            ),
            "sphere, contact or frame",
        ),
        (
            "a GET of a decision".into(),
            get(format!("/api/decide?token={t}"), &[]),
            "takes POST only",
        ),
    ];
    let decide = format!("/api/decide?token={t}");
    let post = |body: &str, headers: &[(&str, &str)]| json_post(&decide, body, headers);
    let o: &[(&str, &str)] = &[("Origin", &origin)];
    let posts: Vec<(&str, (u16, String), &str)> = vec![
        (
            "a decision without Origin",
            post(
                &format!(r#"{{"run":"{run}","decision":"reject","reason":"x"}}"#),
                &[],
            ),
            "no Origin",
        ),
        (
            "a decision from another origin",
            post(
                &format!(r#"{{"run":"{run}","decision":"reject","reason":"x"}}"#),
                &[("Origin", "http://evil.example")],
            ),
            "another origin",
        ),
        (
            "a decision as a form",
            {
                let (s, _, b) = http(
                    port,
                    "POST",
                    &decide,
                    &[
                        ("Origin", &origin),
                        ("Content-Type", "application/x-www-form-urlencoded"),
                    ],
                    b"run=x",
                );
                (s, text(&b))
            },
            "application/json",
        ),
        (
            "a decision about an unknown run",
            post(r#"{"run":"nope","decision":"reject","reason":"x"}"#, o),
            "no run `nope`",
        ),
        (
            "a decision about a path",
            post(
                r#"{"run":"../../etc/passwd","decision":"reject","reason":"x"}"#,
                o,
            ),
            "a run name, not a path",
        ),
        (
            "frames out of range",
            post(
                &format!(r#"{{"run":"{run}","decision":"exclude","frames":"50:99","reason":"x"}}"#),
                o,
            ),
            "frames 50:99 are not all in run",
        ),
        (
            "a surface outside the frame",
            post(
                &format!(r#"{{"run":"{run}","decision":"surface","value":5000,"reason":"x"}}"#),
                o,
            ),
            "outside the frame",
        ),
        (
            "a reject without a reason",
            post(
                &format!(r#"{{"run":"{run}","decision":"reject","reason":" "}}"#),
                o,
            ),
            "needs a reason",
        ),
        (
            "an unknown decision",
            post(
                &format!(r#"{{"run":"{run}","decision":"delete","reason":"x"}}"#),
                o,
            ),
            "reject, exclude, surface or accept",
        ),
        (
            "a field naming a file",
            post(
                &format!(
                    r#"{{"run":"{run}","decision":"reject","reason":"x","path":"/etc/passwd"}}"#
                ),
                o,
            ),
            "unknown field `path`",
        ),
        (
            "a body that is no JSON",
            post("{run", o),
            "not the JSON the page sends",
        ),
        (
            "a withdrawal of nothing",
            json_post(
                &format!("/api/withdraw?token={t}"),
                &format!(r#"{{"run":"{run}","decision":"reject"}}"#),
                o,
            ),
            "no `reject` decision",
        ),
    ];
    for (what, (status, body), says) in refusals
        .iter()
        .map(|(w, r, s)| (w.as_str(), r.clone(), *s))
        .chain(posts)
    {
        assert!(
            (400..500).contains(&status),
            "{what}: status {status}: {body}"
        );
        let message: serde_json::Value =
            serde_json::from_str(&body).unwrap_or_else(|_| panic!("{what}: not JSON: {body}"));
        let message = message["error"].as_str().unwrap_or_default();
        assert!(message.contains(says), "{what}: {status} {message:?}");
    }
    assert!(
        std::fs::read(&file).unwrap() == before,
        "review.csv changed"
    );
    assert!(
        std::fs::read(out.join("drops.csv")).unwrap() == drops_before,
        "drops.csv changed"
    );

    // A second review of the folder is told it is open.
    let second = dropscope(
        d,
        &[
            "review",
            out.to_str().unwrap(),
            "--config",
            cfg.to_str().unwrap(),
        ],
    );
    assert_eq!(second.status.code(), Some(2));
    let e = text(&second.stderr);
    assert!(
        e.contains("is already open for review")
            && e.contains(&format!("pid {}", review.child.id())),
        "{e}"
    );

    // Ctrl-C stops it, frees the folder and says where the decisions are.
    let (status, said) = review.interrupt();
    assert!(status.success(), "{status}: {said}");
    assert!(said.contains("review stopped"), "{said}");
    assert!(!out.join(".dropscope.review.lock").exists());
    assert!(std::net::TcpStream::connect(("127.0.0.1", port)).is_err());
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
