//! The page in headless Chromium on a rendered campaign: a drop rejected,
//! the frames of a planted defect excluded, a surface row set by hand, and
//! `dropscope run` honouring each.

use super::*;
use dropscope::dataset::decisions::{Decisions, Frames, Kind};
use dropscope::dataset::DropStatus;

fn by<'a>(rows: &'a [DropRecord], run: &str) -> &'a DropRecord {
    rows.iter().find(|r| r.run == run).unwrap()
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

/// The four drops of the round trip, by what the page does to each.
struct Runs {
    rejected: &'static str,
    defect: &'static str,
    surfaced: &'static str,
    untouched: &'static str,
}

const RUNS: Runs = Runs {
    rejected: "R3mm_H3cm_01",
    defect: "R4.5mm_H12cm_01",
    surfaced: "R5mm_H25cm_01",
    untouched: "R4mm_H6cm_01",
};

/// A rendered campaign of four drops in `d/camp`, its configuration
/// writing to `d/out`.
struct Campaign<'a> {
    d: &'a Path,
    out: PathBuf,
    cfg: PathBuf,
}

impl Campaign<'_> {
    fn render(d: &Path) -> Campaign<'_> {
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
        Campaign { d, out, cfg }
    }

    /// `dropscope run --config CFG`.
    fn run(&self) -> Output {
        dropscope(self.d, &["run", "--config", self.cfg.to_str().unwrap()])
    }

    /// The rows of drops.csv.
    fn drops(&self) -> Vec<DropRecord> {
        read_csv(&self.out.join("drops.csv")).unwrap()
    }
}

/// The whole round trip on a rendered campaign of four drops: one rejected
/// in the page, one with a planted defect whose frames are excluded in the
/// page, one whose surface row is set in the page (typed), one untouched.
/// The next `dropscope run` honours each and measures again only those
/// three; the one after measures nothing.
#[test]
fn the_page_in_chromium_rejects_excludes_and_sets_a_surface_and_the_job_honours_them() {
    need!(crate::Need::Chromium, crate::Need::ChromeDriver);
    let dir = tempfile::tempdir().unwrap();
    let camp = Campaign::render(dir.path());

    // The clean campaign.
    let first = camp.run();
    assert!(first.status.success(), "{}", text(&first.stderr));
    let clean = camp.drops();
    assert!(clean.iter().all(|r| r.status == DropStatus::Ok));

    let bad_frame = tear_a_frame(&camp, &clean);
    let typed = decide_in_the_page(&camp, bad_frame);
    assert_review_csv_holds_the_decisions(&camp, bad_frame, &typed);

    // The job honours them, measuring again only the three runs they touch.
    let rerun = camp.run();
    assert!(rerun.status.success(), "{}", text(&rerun.stderr));
    assert_eq!(reused(&rerun), 1, "{}", text(&rerun.stderr));
    let after = camp.drops();
    assert_the_rejected_drop_is_kept_out_of_the_collapse(&camp, &clean, &after);
    assert_the_defect_is_back_within_its_errors(&camp, &clean, &after, bad_frame);
    assert_the_hand_surface_is_used_and_shown(&camp, &after, &typed);
    // The untouched drop is the same row.
    assert_eq!(by(&after, RUNS.untouched), by(&clean, RUNS.untouched));
    assert_the_report_shows_every_decision(&camp, bad_frame, &typed);

    // Nothing changed since: every run from the cache.
    let again = camp.run();
    assert_eq!(reused(&again), 4, "{}", text(&again.stderr));
}

/// A torn frame at the peak of the defect's drop: its numbers move beyond
/// their errors. The torn frame's number.
fn tear_a_frame(camp: &Campaign, clean: &[DropRecord]) -> i64 {
    let (d, out, defect) = (camp.d, &camp.out, RUNS.defect);
    let c = by(clean, defect);
    let rows = track(out, defect);
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
    let spoilt_run = camp.run();
    assert_eq!(reused(&spoilt_run), 3, "{}", text(&spoilt_run.stderr));
    let spoilt = camp.drops();
    let moved = off_by(by(&spoilt, defect), c, c, 3.0);
    eprintln!("with the torn frame {bad_frame}: {moved:?}");
    assert!(
        moved.iter().any(|m| m.starts_with("delta_max_mm")),
        "the torn frame moved δmax by less than 3 σ: the test would prove nothing ({moved:?})"
    );
    bad_frame
}

/// Open `run`'s drop from the list: the number of the frame shown first.
fn open(b: &Driver, run: &str) -> serde_json::Value {
    b.click(&format!("tr[data-run=\"{run}\"]"));
    b.wait_for(
        &format!(
            "const i = document.getElementById('frame'); return !document.getElementById('drop').hidden \
             && document.getElementById('drop-title').textContent === '{run}' && i.complete \
             && i.naturalWidth > 0 && i.dataset.frame"
        ),
        &format!("{run}'s first frame"),
    )
}

/// Wait for the page to say `what` was saved.
fn saved(b: &Driver, what: &str) {
    b.wait_for(
        &format!("const s = document.getElementById('said').textContent; return s.includes('{what}') && s.includes('saved')"),
        what,
    );
}

/// Back from a drop to the list.
fn back(b: &Driver) {
    b.click("#back");
    b.wait_for("return !document.getElementById('list').hidden", "the list");
}

/// The page, in Chromium: one drop rejected, the torn frame and its
/// neighbours excluded, a surface row typed; the list marks the three, and
/// Ctrl-C stops the review. The row as typed.
fn decide_in_the_page(camp: &Campaign, bad_frame: i64) -> String {
    let review = Review::start(camp.d, &camp.out, &camp.cfg);
    let profile = tempfile::tempdir_in(camp.d).unwrap();
    let b = Driver::start(profile.path());
    b.goto(&review.url);
    b.wait_for(
        "return document.querySelectorAll('#drops tbody tr').length === 4",
        "the drop list",
    );

    // Reject one drop.
    open(&b, RUNS.rejected);
    b.type_into("#verdict-reason", "two spheres in view");
    b.click("#reject");
    saved(&b, "rejected");
    back(&b);

    exclude_the_torn_frames(&b, bad_frame);
    let typed = set_the_surface_row(&b, camp.d);
    // The list says which drops have decisions.
    b.wait_for(
        "return document.querySelectorAll('#drops .decided').length === 3",
        "three drops marked as decided on",
    );
    drop(b);
    let (status, said) = review.interrupt();
    assert!(status.success(), "{status}: {said}");
    typed
}

/// Step through the torn frame's drop, and exclude it with its
/// neighbours.
fn exclude_the_torn_frames(b: &Driver, bad_frame: i64) {
    let shown = open(b, RUNS.defect);
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
    saved(b, "excluded");
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
    back(b);
}

/// Set a surface row by hand: the rendered line's truth. The row as typed.
fn set_the_surface_row(b: &Driver, d: &Path) -> String {
    let surfaced = RUNS.surfaced;
    let truth: serde_json::Value = serde_json::from_slice(
        &std::fs::read(d.join("camp").join(surfaced).join("truth.json")).unwrap(),
    )
    .unwrap();
    let true_row = truth["surface_row_px"].as_f64().unwrap()
        + truth["surface_slope"].as_f64().unwrap() * truth["impact_column_px"].as_f64().unwrap();
    let typed = format!("{true_row:.2}");
    open(b, surfaced);
    b.type_into("#surf-row", &typed);
    b.type_into("#surf-reason", "the band's top by eye");
    b.click("#surf-save");
    saved(b, "surface row set");
    back(b);
    typed
}

/// review.csv holds the three decisions, as made.
fn assert_review_csv_holds_the_decisions(camp: &Campaign, bad_frame: i64, typed: &str) {
    let decisions = Decisions::read(&camp.out.join("review.csv")).unwrap();
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
                RUNS.rejected.to_string(),
                Kind::Reject,
                None,
                None,
                "two spheres in view".to_string()
            ),
            (
                RUNS.defect.to_string(),
                Kind::Exclude,
                Some(Frames {
                    first: bad_frame - 1,
                    last: bad_frame + 1
                }),
                None,
                "the frame tore: the ball 4 px low".to_string()
            ),
            (
                RUNS.surfaced.to_string(),
                Kind::Surface,
                None,
                Some(typed.parse().unwrap()),
                "the band's top by eye".to_string()
            ),
        ]
    );
}

/// The rejected drop: its numbers kept, status rejected, out of the collapse.
fn assert_the_rejected_drop_is_kept_out_of_the_collapse(
    camp: &Campaign,
    clean: &[DropRecord],
    after: &[DropRecord],
) {
    let (out, rejected) = (&camp.out, RUNS.rejected);
    let r = by(after, rejected);
    assert_eq!(r.status, DropStatus::Rejected);
    assert!(r
        .reason
        .starts_with("rejected in review: two spheres in view"));
    assert_eq!(r.delta_max_mm, by(clean, rejected).delta_max_mm);
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
    assert_eq!(used(RUNS.untouched), "true");
    let fits = std::fs::read_to_string(out.join("fits.json")).unwrap();
    assert!(
        fits.contains("status rejected (rejected in review: two spheres in view"),
        "{fits}"
    );
}

/// The torn frame and its neighbours left out: its numbers back within
/// their errors of the clean render's. The gap they leave at the peak is
/// said (a warning).
fn assert_the_defect_is_back_within_its_errors(
    camp: &Campaign,
    clean: &[DropRecord],
    after: &[DropRecord],
    bad_frame: i64,
) {
    let c = by(clean, RUNS.defect);
    let fixed = by(after, RUNS.defect);
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
    let flagged: Vec<i64> = track(&camp.out, RUNS.defect)
        .iter()
        .filter(|r| r.flags.split(' ').any(|w| w == "excluded"))
        .map(|r| r.frame)
        .collect();
    assert_eq!(flagged, vec![bad_frame - 1, bad_frame, bad_frame + 1]);
}

/// The surface set by hand is used, and said; and shown: the page draws
/// the row the job used, and says where it came from.
fn assert_the_hand_surface_is_used_and_shown(camp: &Campaign, after: &[DropRecord], typed: &str) {
    let surfaced = RUNS.surfaced;
    let s = by(after, surfaced);
    assert_eq!(s.surface_source, "review");
    let row = s.surface_row_px.unwrap();
    assert!((row - typed.parse::<f64>().unwrap()).abs() < 1e-6, "{row}");
    assert_eq!(
        s.surface_row_px_err,
        Some(dropscope::dataset::decisions::HAND_SURFACE_ERR_PX)
    );
    let shown = Review::start(camp.d, &camp.out, &camp.cfg);
    let (status, body) = shown.get(&format!("/api/run?token={}&run={surfaced}", shown.token));
    assert_eq!(status, 200, "{}", text(&body));
    let j: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(j["surface"]["source"], "review");
    assert_eq!(j["surface"]["row_at_impact_px"].as_f64(), Some(row));
    let (status, said) = shown.interrupt();
    assert!(status.success(), "{status}: {said}");
}

/// The report and provenance.json show every decision.
fn assert_the_report_shows_every_decision(camp: &Campaign, bad_frame: i64, typed: &str) {
    let out = &camp.out;
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
}
