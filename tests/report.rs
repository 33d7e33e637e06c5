//! report.html as a person sees it: the main job on the three fixture drops
//! plus a broken run, the page opened in headless Chromium (Debian's
//! `chromium` package, which `.ci/run` installs): its rendered DOM lists
//! every drop, the failed one with its reason, and the inline plots; its
//! screenshot is not blank.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use dropscope::dataset::{read_csv, DropRecord, DropStatus};

use crate::webdriver::CHROMIUM;

/// A run name with every character HTML must escape.
const BROKEN_RUN: &str = "broken<cine> & \"co\"";

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Run headless Chromium on `page` with `extra` arguments and a fresh
/// profile; return its stdout. A hang is stopped after 3 minutes (a guard,
/// not a timing assertion: the run takes about a second).
fn chromium(page: &Path, extra: &[String], work: &Path) -> Vec<u8> {
    let profile = tempfile::tempdir_in(work).unwrap();
    let (out_path, err_path) = (work.join("chromium.out"), work.join("chromium.err"));
    let mut child = Command::new(CHROMIUM)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .args(extra)
        .arg(format!("file://{}", page.display()))
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out_path).unwrap())
        .stderr(std::fs::File::create(&err_path).unwrap())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start {CHROMIUM}: {e}"));
    let deadline = Instant::now() + Duration::from_secs(180);
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{CHROMIUM} did not finish within 3 minutes");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(
        status.success(),
        "{CHROMIUM} failed ({status}): {}",
        std::fs::read_to_string(&err_path).unwrap_or_default()
    );
    std::fs::read(&out_path).unwrap()
}

/// Text as Chromium serialises it inside an element (HTML serialisation
/// algorithm: `&`, `<`, `>` and the no-break space escaped).
fn serialised(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('\u{a0}', "&nbsp;")
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &to.join(e.file_name()));
        } else {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
}

/// The main job on the fixtures and a corrupt cine writes report.html;
/// Chromium renders every drop (the broken one with its reason, its name's
/// markup characters as text), the four inline collapse plots, three
/// overlays and three fold-out diagnostics, and a screenshot that is far
/// from blank. `dropscope report` on a copy of the folder writes the same
/// bytes (no date, no output path in the page).
#[test]
fn the_report_renders_in_chromium_and_lists_every_drop() {
    need!(crate::Need::Chromium);
    let start = Instant::now();
    let dir = tempfile::tempdir().unwrap();
    let work = dir.path();
    let (config, out, records) = run_the_job_with_a_broken_run(work);
    let page = out.join("report.html");
    assert!(page.is_file(), "the main job wrote no report.html");
    let job_secs = start.elapsed().as_secs_f64();

    assert_the_dom_lists_every_drop(&page, work, &records);
    let html = std::fs::read_to_string(&page).unwrap();
    let rects = plot_boxes(&html, work);
    assert_plot_text_is_readable_and_every_point_titled(&html, work);
    assert_the_screenshot_is_not_blank(&page, work, &rects, job_secs, start);
    assert_report_writes_the_same_page_elsewhere(&out, &config, &page, work);
}

/// The window the page is laid out and photographed in.
const WINDOW: &str = "--window-size=1280,2000";

/// The main job on the three fixture drops and a corrupt cine, in `work`:
/// one run fails. The configuration, the output folder and drops.csv's rows.
fn run_the_job_with_a_broken_run(work: &Path) -> (PathBuf, PathBuf, Vec<DropRecord>) {
    std::fs::write(work.join("broken.cine"), b"CI not really a cine").unwrap();
    let fixtures = root().join("fixtures");
    let mut manifest = String::from("run,path,sphere_radius_mm\n");
    for (run, r) in [
        ("R3mm_H1.5cm_01", 3.0),
        ("R4.5mm_H12cm_01", 4.5),
        ("R7mm_H50cm_01", 7.0),
    ] {
        manifest += &format!("{run},{},{r}\n", fixtures.join(run).display());
    }
    manifest += "\"broken<cine> & \"\"co\"\"\",broken.cine,4.5\n";
    std::fs::write(work.join("runs.csv"), manifest).unwrap();
    let config = work.join("pipeline.toml");
    std::fs::write(
        &config,
        "[input]\nmanifest = \"runs.csv\"\n[output]\ndir = \"out\"\n",
    )
    .unwrap();
    let out = work.join("out");
    let job = Command::new(env!("CARGO_BIN_EXE_dropscope"))
        .arg("run")
        .arg("--config")
        .arg(&config)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(
        job.status.code(),
        Some(1),
        "one run fails: {}",
        String::from_utf8_lossy(&job.stderr)
    );
    let records = read_csv(&out.join("drops.csv")).unwrap();
    assert_eq!(records.len(), 4);
    assert_eq!(records[3].run, BROKEN_RUN);
    assert_eq!(records[3].status, DropStatus::Failed);
    (config, out, records)
}

/// The rendered DOM (after parsing and the page's script) lists every drop
/// once, the failed one with its reason, the plots, overlays, diagnostics
/// and movies.
fn assert_the_dom_lists_every_drop(page: &Path, work: &Path, records: &[DropRecord]) {
    let dom = String::from_utf8(chromium(page, &["--dump-dom".into()], work)).unwrap();
    for r in records {
        let row = format!("<th class=\"run\">{}</th>", serialised(&r.run));
        assert_eq!(dom.matches(&row).count(), 1, "{row} not rendered once");
    }
    let broken = &records[3];
    assert!(broken.reason.contains("broken.cine"), "{}", broken.reason);
    let failed_row = format!(
        "<span class=\"badge failed\">FAILED</span></td><td colspan=\"7\" class=\"reason\">{}</td>",
        serialised(&broken.reason)
    );
    assert!(dom.contains(&failed_row), "failed row not rendered");
    assert_eq!(dom.matches("<svg ").count(), 4, "inline collapse plots");
    assert_eq!(dom.matches("<img class=\"thumb\"").count(), 3, "overlays");
    assert_eq!(
        dom.matches("<img class=\"diagram\" data-src=\"plots/drops/")
            .count(),
        3,
        "diagnostics"
    );
    assert_eq!(
        dom.matches("<a class=\"movie\" href=\"plots/impacts/")
            .count(),
        3
    );
    assert!(dom.contains("<span class=\"count failed\">1 failed</span>"));
}

/// Where the four plots were laid out: a copy of the page with a probe
/// script that writes each inline SVG's box into the DOM. Each plot's box
/// (left, top, width, height).
fn plot_boxes(html: &str, work: &Path) -> Vec<[u32; 4]> {
    let probe = work.join("probe.html");
    std::fs::write(
        &probe,
        html.replace(
            "</body>",
            "<script>document.querySelectorAll('figure svg').forEach(function (s) { \
             var r = s.getBoundingClientRect(); s.setAttribute('data-rect', \
             [r.left, r.top, r.width, r.height].map(Math.round).join(',')); });</script></body>",
        ),
    )
    .unwrap();
    let probed = String::from_utf8(chromium(
        &probe,
        &["--dump-dom".into(), WINDOW.to_string()],
        work,
    ))
    .unwrap();
    let rects: Vec<[u32; 4]> = probed
        .split("data-rect=\"")
        .skip(1)
        .map(|s| {
            let v: Vec<u32> = s[..s.find('"').unwrap()]
                .split(',')
                .map(|x| x.parse().unwrap())
                .collect();
            [v[0], v[1], v[2], v[3]]
        })
        .collect();
    assert_eq!(rects.len(), 4, "{rects:?}");
    for [_, _, w, h] in &rects {
        // Drawn 1100 × 1040 and scaled to the column: the aspect ratio is kept.
        assert!(*w >= 400, "a plot only {w} px wide");
        let aspect = f64::from(*w) / f64::from(*h);
        assert!(
            (aspect / (1100.0 / 1040.0) - 1.0).abs() < 0.02,
            "aspect {aspect}"
        );
    }
    rects
}

/// In a 1400 px window as a user opens it: every text of the inline plots
/// (tick labels are the smallest) renders at 11 px or more, and every
/// plotted point has a hover text (SVG <title>) naming its run.
fn assert_plot_text_is_readable_and_every_point_titled(html: &str, work: &Path) {
    let probe = work.join("probe-fonts.html");
    std::fs::write(
        &probe,
        html.replace(
            "</body>",
            "<script>var least = 1e9, n = 0; \
             document.querySelectorAll('figure svg').forEach(function (s) { \
             var k = s.getBoundingClientRect().width / s.viewBox.baseVal.width; \
             s.querySelectorAll('text').forEach(function (t) { \
             least = Math.min(least, parseFloat(t.getAttribute('font-size')) * k); }); \
             n += s.querySelectorAll('circle > title').length; }); \
             document.body.setAttribute('data-least-font', least.toFixed(2)); \
             document.body.setAttribute('data-titles', n);</script></body>",
        ),
    )
    .unwrap();
    let probed = String::from_utf8(chromium(
        &probe,
        &["--dump-dom".into(), "--window-size=1400,900".into()],
        work,
    ))
    .unwrap();
    let attr = |name: &str| -> f64 {
        let at = probed.find(&format!("{name}=\"")).unwrap() + name.len() + 2;
        probed[at..at + probed[at..].find('"').unwrap()]
            .parse()
            .unwrap()
    };
    let least = attr("data-least-font");
    assert!(least >= 11.0, "smallest plot text {least} px at 1400 px");
    // Three measured drops, each a point in each of the four figures.
    assert_eq!(attr("data-titles"), 12.0);
    assert!(probed.contains("<title>R3mm_H1.5cm_01 · R = 3 mm · η = "));
}

/// The screenshot at the same size: not blank as a whole (measured:
/// 9 % non-white, about 2000 colours; a blank page is one colour), and
/// every plot box visibly drawn (an SVG that did not render leaves its
/// box white).
fn assert_the_screenshot_is_not_blank(
    page: &Path,
    work: &Path,
    rects: &[[u32; 4]],
    job_secs: f64,
    start: Instant,
) {
    let shot = work.join("shot.png");
    chromium(
        page,
        &[
            format!("--screenshot={}", shot.display()),
            WINDOW.to_string(),
        ],
        work,
    );
    let img = image::open(&shot).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (1280, 2000));
    let stats = |x0: u32, y0: u32, w: u32, h: u32| {
        let mut non_white = 0usize;
        let mut colours = std::collections::BTreeSet::new();
        for y in y0..(y0 + h).min(img.height()) {
            for x in x0..(x0 + w).min(img.width()) {
                let p = img.get_pixel(x, y).0;
                non_white += usize::from(p.iter().any(|&c| c < 235));
                colours.insert(p);
            }
        }
        (non_white as f64 / f64::from(w * h), colours.len())
    };
    let (frac, colours) = stats(0, 0, 1280, 2000);
    eprintln!(
        "report test: job {job_secs:.1} s, total {:.1} s; screenshot {:.1} % non-white, {colours} colours",
        start.elapsed().as_secs_f64(),
        100.0 * frac,
    );
    assert!(
        frac > 0.05,
        "screenshot nearly blank: {:.1} % non-white",
        100.0 * frac
    );
    assert!(colours > 200, "only {colours} colours");
    for [x, y, w, h] in rects {
        let (frac, colours) = stats(*x, *y, *w, *h);
        eprintln!(
            "plot at {x},{y}: {:.1} % non-white, {colours} colours",
            100.0 * frac
        );
    }
}

/// `dropscope report` on a copy elsewhere writes the same page.
fn assert_report_writes_the_same_page_elsewhere(
    out: &Path,
    config: &Path,
    page: &Path,
    work: &Path,
) {
    let copy = work.join("elsewhere");
    copy_dir(out, &copy);
    std::fs::remove_file(copy.join("report.html")).unwrap();
    let again = Command::new(env!("CARGO_BIN_EXE_dropscope"))
        .arg("report")
        .arg("--config")
        .arg(config)
        .arg("--out")
        .arg(&copy)
        .output()
        .unwrap();
    assert!(
        again.status.success(),
        "{}",
        String::from_utf8_lossy(&again.stderr)
    );
    assert!(std::fs::read(page).unwrap() == std::fs::read(copy.join("report.html")).unwrap());
}

/// An output folder of 1 000 drops under `work`: the three fixture drops
/// processed, then their rows and pictures repeated under new names (every
/// 50th failed, every 7th with a warning).
fn thousand_drop_archive(work: &Path) -> PathBuf {
    let base = work.join("base");
    let job = Command::new(env!("CARGO_BIN_EXE_dropscope"))
        .args(["process", "--manifest"])
        .arg(root().join("fixtures/runs.csv"))
        .arg("--out")
        .arg(&base)
        .output()
        .unwrap();
    assert_eq!(
        job.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&job.stderr)
    );
    let three = read_csv(&base.join("drops.csv")).unwrap();
    let out = work.join("archive");
    for sub in ["overlays", "impacts", "drops"] {
        std::fs::create_dir_all(out.join("plots").join(sub)).unwrap();
    }
    let mut records = Vec::new();
    for i in 0..1000 {
        let mut r = three[i % 3].clone();
        let from = r.run.clone();
        r.run = format!("D{i:04}_{from}");
        r.v_impact_m_s = r
            .v_impact_m_s
            .map(|v| v * (1.0 + (i * 7919 % 1000) as f64 * 1e-3));
        if i % 7 == 3 {
            r.status = DropStatus::Warning;
            r.reason = "free-flight gravity off by 3 %".into();
        }
        for (sub, ext) in [("overlays", "png"), ("impacts", "png"), ("drops", "svg")] {
            std::fs::hard_link(
                base.join(format!("plots/{sub}/{from}.{ext}")),
                out.join(format!("plots/{sub}/{}.{ext}", r.run)),
            )
            .unwrap();
        }
        if i % 50 == 49 {
            r = dropscope::dataset::DropRecord::failed(
                &r.run,
                r.sphere_radius_mm,
                "no sphere found",
            );
        }
        records.push(r);
    }
    dropscope::dataset::write_csv(&out.join("drops.csv"), &records).unwrap();
    out
}

/// A report for an archive. 1 000 drops (the three fixture drops'
/// rows and pictures repeated under new names, every 50th failed, every
/// 7th with a warning) give a page of a few MB (inline thumbnails, the
/// full pictures as files beside it) that Chromium renders whole; its
/// filter and sort work. The load time is measured and printed, not asserted.
#[test]
fn a_thousand_drop_report_stays_small_and_sorts_and_filters() {
    need!(crate::Need::Chromium);
    let dir = tempfile::tempdir().unwrap();
    let work = dir.path();
    let out = thousand_drop_archive(work);
    let start = Instant::now();
    let report = Command::new(env!("CARGO_BIN_EXE_dropscope"))
        .arg("report")
        .arg(&out)
        .output()
        .unwrap();
    let write_s = start.elapsed().as_secs_f64();
    assert_eq!(
        report.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&report.stderr)
    );
    let page = out.join("report.html");
    let bytes = std::fs::metadata(&page).unwrap().len();
    // About 5 kB a drop (a thumbnail and the row); the full pictures inline
    // were about 240 kB a drop.
    assert!(
        bytes < 8_000_000,
        "report.html is {bytes} bytes for 1 000 drops"
    );

    let html = std::fs::read_to_string(&page).unwrap();
    let probe = work.join("archive/probe.html");
    std::fs::write(
        &probe,
        html.replace(
            "</body>",
            "<script>var b = document.body, rows = document.querySelectorAll('table.drops tbody'); \
             b.setAttribute('data-parsed-ms', performance.now().toFixed(0)); \
             b.setAttribute('data-rows', rows.length); \
             var f = document.getElementById('drop-filter'); f.value = 'd00'; \
             f.dispatchEvent(new Event('input')); \
             b.setAttribute('data-filtered', document.getElementById('drop-count').textContent); \
             f.value = ''; var s = document.getElementById('drop-status'); s.value = 'failed'; \
             s.dispatchEvent(new Event('change')); \
             b.setAttribute('data-failed', document.getElementById('drop-count').textContent); \
             var t0 = performance.now(); \
             document.querySelector('th[data-sort=v]').click(); \
             b.setAttribute('data-sort-ms', (performance.now() - t0).toFixed(0)); \
             var v = Array.prototype.map.call(document.querySelectorAll('table.drops tbody'), \
             function (r) { return r.getAttribute('data-v'); }); \
             b.setAttribute('data-first-v', v[0]); b.setAttribute('data-last-v', v[v.length - 1]); \
             var least = Math.min.apply(null, v.filter(function (x) { return x !== null; }).map(parseFloat)); \
             b.setAttribute('data-least-v', least); \
             var d = document.querySelector('tbody details'); d.open = true; \
             d.dispatchEvent(new Event('toggle')); \
             b.setAttribute('data-opened', d.querySelector('img').getAttribute('src')); \
             window.addEventListener('load', function () { \
             b.setAttribute('data-load-ms', performance.now().toFixed(0)); });</script></body>",
        ),
    )
    .unwrap();
    let dom = String::from_utf8(chromium(
        &probe,
        &["--dump-dom".into(), "--window-size=1400,900".into()],
        work,
    ))
    .unwrap();
    let attr = |name: &str| -> String {
        let at = dom
            .find(&format!("{name}=\""))
            .unwrap_or_else(|| panic!("no {name}"))
            + name.len()
            + 2;
        dom[at..at + dom[at..].find('"').unwrap()].to_string()
    };
    assert_eq!(attr("data-rows"), "1000");
    // D0000 … D0099 match "d00"; 20 of the 1000 failed.
    assert_eq!(attr("data-filtered"), "100 of 1000 drops");
    assert_eq!(attr("data-failed"), "20 of 1000 drops");
    // Sorted by v ascending: the least first, the failed rows (no v) last.
    assert_eq!(
        attr("data-first-v").parse::<f64>().unwrap(),
        attr("data-least-v").parse::<f64>().unwrap()
    );
    assert_eq!(attr("data-last-v"), "null");
    // A diagnostic figure is loaded when its row is unfolded, not before.
    assert!(
        attr("data-opened").starts_with("plots/drops/D"),
        "{}",
        attr("data-opened")
    );
    assert_eq!(dom.matches(" src=\"plots/drops/").count(), 1);
    let load = dom.find("data-load-ms=").map(|_| attr("data-load-ms"));
    eprintln!(
        "1000-drop report: {bytes} bytes, written in {write_s:.1} s; in Chromium parsed and \
         scripted by {} ms, load event at {} ms, sorted by v in {} ms",
        attr("data-parsed-ms"),
        load.as_deref().unwrap_or("(not reached before the dump)"),
        attr("data-sort-ms")
    );
}
