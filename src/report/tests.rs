//! The page from collapse outputs of synthetic drops (no movies): what it
//! shows, that input cannot inject markup, and that it names no URL.

use std::path::Path;

use super::html::{escape, pm};
use super::render_report;
use crate::collapse::groups::ContactRadius;
use crate::collapse::synthetic::{eq8_dataset, SyntheticSpec};
use crate::config::{PipelineConfig, EMBEDDED_DEFAULT};
use crate::dataset::{self, DropRecord, DropStatus};
use crate::job::collapse_job::CollapseOptions;

const EVIL_RUN: &str = "<script>alert(\"run\")</script>";
const EVIL_REASON: &str = "cannot open /data/a&b/<img src=x onerror=alert(1)>.cine: 'bad'";

/// 20 drops obeying Eq. (8) (4 per radius), one measured with a warning and
/// one failed run with markup in its name and reason.
fn records() -> Vec<DropRecord> {
    let mut recs = eq8_dataset(
        &SyntheticSpec::paper(4, 3),
        [1.26, -0.3, 0.05],
        [3.53, -0.5, 0.1],
        [0.6, 1.8],
    );
    recs[1].status = DropStatus::Warning;
    recs[1].reason = "g_fit 9.2 m/s² is 6 % off 9.81 <check fps>".into();
    recs.push(DropRecord::failed(EVIL_RUN, 4.5, EVIL_REASON));
    recs
}

/// drops.csv and the collapse outputs of `recs` in `out` (as the main job leaves them).
fn collapse_into(out: &Path, recs: &[DropRecord]) {
    let drops = out.join("drops.csv");
    dataset::write_csv(&drops, recs).unwrap();
    let cfg =
        PipelineConfig::from_toml_str(EMBEDDED_DEFAULT, Path::new("pipeline.toml"), Path::new("."))
            .unwrap();
    let args = CollapseOptions {
        drops,
        out: Some(out.to_path_buf()),
        config: None,
        contact_radius: ContactRadius::Measured,
        bootstrap: 200,
        seed: 5,
        no_plots: false,
    };
    crate::job::collapse_job::run(&args, &cfg, "pipeline.toml").unwrap();
}

/// Every value of a `src="…"`, `data-src="…"`, `data-full="…"` or `href="…"` attribute
/// and every CSS `url(…)`.
fn references(page: &str) -> Vec<&str> {
    let mut refs = Vec::new();
    for key in [" src=\"", "data-src=\"", "data-full=\"", "href=\"", "url("] {
        let mut rest = page;
        while let Some(i) = rest.find(key) {
            rest = &rest[i + key.len()..];
            let end = rest.find(['"', ')']).unwrap_or(rest.len());
            refs.push(&rest[..end]);
        }
    }
    refs
}

#[test]
fn the_page_shows_the_collapse_files_and_every_drop() {
    let dir = tempfile::tempdir().unwrap();
    let recs = records();
    collapse_into(dir.path(), &recs);
    let page = String::from_utf8(render_report(dir.path(), "my config.toml", &recs)).unwrap();

    // Header: version, configuration, counts (19 ok, 1 with a warning, 1 failed).
    assert!(page.contains(concat!("dropscope ", env!("CARGO_PKG_VERSION"))));
    assert!(page.contains("<code>my config.toml</code>"));
    for count in [
        "21 runs",
        "19 measured",
        "1 measured with warnings",
        "1 failed",
    ] {
        assert!(page.contains(&format!(">{count}</span>")), "{count}");
    }
    // The four collapse plots inline, in reading order.
    let at = |s: &str| page.find(s).unwrap_or_else(|| panic!("{s} missing"));
    let order = [
        "plot-psi_vs_xi",
        "plot-omega_vs_xi",
        "plot-pi_vs_eta",
        "plot-tau_vs_v",
    ];
    assert!(order.windows(2).all(|w| at(w[0]) < at(w[1])));
    assert_eq!(page.matches("<svg").count(), 4);
    // The fits table holds fits.json's numbers, as written there.
    let fits: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("fits.json")).unwrap()).unwrap();
    for (series, coef) in [
        ("psi_series", "A1"),
        ("psi_series", "A3"),
        ("omega_series", "B2"),
    ] {
        let e = &fits[series][coef];
        let cell = format!(
            "{coef} = {}",
            pm(e["value"].as_f64().unwrap(), e["stderr"].as_f64())
        );
        assert!(page.contains(&cell), "{cell}");
    }
    let nu = &fits["exponents"][0];
    assert!(page.contains(&pm(nu["nu"].as_f64().unwrap(), nu["nu_stderr"].as_f64())));
    // One row per drop, with its numbers; the warning shown; the failed one marked.
    assert_eq!(page.matches("<tbody class=").count(), recs.len());
    for r in &recs[..20] {
        assert!(page.contains(&format!("<th class=\"run\">{}</th>", r.run)));
        assert!(
            page.contains(&pm(r.tau_c_ms.unwrap(), r.tau_c_ms_err)),
            "{}",
            r.run
        );
    }
    assert!(page.contains("&lt;check fps&gt;"));
    assert!(page.contains(&format!(
        "<span class=\"badge failed\">FAILED</span></td><td colspan=\"7\" class=\"reason\">{}</td>",
        escape(EVIL_REASON)
    )));
    // No collapse alarm: collapse.csv lists exactly these drops.
    assert!(!page.contains("class=\"alarm\">The collapse files"));
}

#[test]
fn input_cannot_inject_markup_and_the_page_names_no_url() {
    let dir = tempfile::tempdir().unwrap();
    let recs = records();
    collapse_into(dir.path(), &recs);
    // An overlay, an animation and a diagnostic figure for the first drop.
    let plots = dir.path().join("plots");
    std::fs::create_dir_all(plots.join("overlays")).unwrap();
    std::fs::create_dir_all(plots.join("impacts")).unwrap();
    std::fs::create_dir_all(plots.join("drops")).unwrap();
    let overlay = image::RgbImage::from_pixel(400, 300, image::Rgb([9, 9, 9]));
    overlay
        .save(plots.join(format!("overlays/{}.png", recs[0].run)))
        .unwrap();
    overlay
        .save(plots.join(format!("impacts/{}.png", recs[0].run)))
        .unwrap();
    std::fs::write(
        plots.join(format!("drops/{}.svg", recs[0].run)),
        "<svg width=\"4\" height=\"4\" xmlns=\"http://www.w3.org/2000/svg\"></svg>",
    )
    .unwrap();
    let page = String::from_utf8(render_report(dir.path(), "<b>cfg</b>", &recs)).unwrap();
    // The only script is the page's own; names and reasons arrive as text.
    assert_eq!(page.matches("<script").count(), 1);
    assert!(!page.contains("<img src=x"));
    assert!(!page.contains("<b>cfg"));
    assert!(page.contains(&escape(EVIL_RUN)));
    // The thumbnail inline (a JPEG 120 px wide, not the 400 px picture),
    // the full-size files beside the page by relative paths; no URL at all.
    let run = &recs[0].run;
    let refs = references(&page);
    assert_eq!(refs.len(), 5, "{refs:.80?}");
    assert!(
        refs[0].starts_with("data:image/jpeg;base64,/9j/"),
        "{:.40}",
        refs[0]
    );
    let jpeg = base64_decode(&refs[0]["data:image/jpeg;base64,".len()..]);
    let thumb = image::load_from_memory(&jpeg).unwrap();
    assert_eq!((thumb.width(), thumb.height()), (100, 75));
    assert_eq!(refs[1], format!("plots/drops/{run}.svg"));
    assert_eq!(refs[2], format!("plots/overlays/{run}.png"));
    assert_eq!(refs[3], format!("plots/impacts/{run}.png"));
    assert_eq!(refs[4], format!("plots/drops/{run}.svg"));
    for r in refs {
        assert!(
            r.starts_with("data:") || (r.starts_with("plots/") && !r.contains("..")),
            "reference {r:.80}"
        );
    }
    assert!(!page.contains("://"));
}

#[test]
fn without_collapse_outputs_the_page_says_so() {
    let dir = tempfile::tempdir().unwrap();
    // A plot left by an earlier job is not shown without its fits.json.
    std::fs::create_dir(dir.path().join("plots")).unwrap();
    std::fs::write(dir.path().join("plots/psi_vs_xi.svg"), "<svg></svg>").unwrap();
    let recs = vec![DropRecord::failed(
        "only",
        3.0,
        "no sphere found in any of the 40 frames",
    )];
    let page = String::from_utf8(render_report(dir.path(), "p.toml", &recs)).unwrap();
    assert!(page.contains(
        "The collapse did not run: no fits.json in the output folder (no drop was measured)"
    ));
    assert!(page.contains("No fits (the collapse did not run)."));
    assert!(page.contains("no sphere found in any of the 40 frames"));
    assert!(!page.contains("<svg"));
}

#[test]
fn collapse_files_of_other_drops_are_flagged() {
    let dir = tempfile::tempdir().unwrap();
    let recs = records();
    collapse_into(dir.path(), &recs[..10]);
    let page = String::from_utf8(render_report(dir.path(), "p.toml", &recs)).unwrap();
    assert!(page.contains("collapse.csv lists 10 runs, this report 21"));
    // The same runs, but one the collapse used has failed since.
    let mut now = recs[..10].to_vec();
    now[4] = DropRecord::failed(&now[4].run, now[4].sphere_radius_mm, "unreadable now");
    let page = String::from_utf8(render_report(dir.path(), "p.toml", &now)).unwrap();
    assert!(page.contains("or uses runs that have failed since"));
    // And as they were: no alarm about them (these 10 drops' series may
    // still be flagged as extrapolated).
    let page = String::from_utf8(render_report(dir.path(), "p.toml", &recs[..10])).unwrap();
    assert!(!page.contains("are not from these drops"));
    assert!(!page.contains("missing or unreadable"));
}

#[test]
fn the_same_outputs_give_the_same_bytes_wherever_the_folder_is() {
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let recs = records();
    collapse_into(a.path(), &recs);
    collapse_into(b.path(), &recs);
    let pa = render_report(a.path(), "p.toml", &recs);
    assert!(pa == render_report(b.path(), "p.toml", &recs));
    let text = String::from_utf8(pa).unwrap();
    assert!(!text.contains(&a.path().display().to_string()));
}

#[test]
fn a_collapse_without_plots_says_so_and_keeps_its_fits() {
    let dir = tempfile::tempdir().unwrap();
    let recs = records();
    collapse_into(dir.path(), &recs);
    std::fs::remove_dir_all(dir.path().join("plots")).unwrap();
    let page = String::from_utf8(render_report(dir.path(), "p.toml", &recs)).unwrap();
    assert!(page.contains("The collapse wrote no plots."));
    assert!(page.contains("<td>A1 = "));
}

/// The captioned plots are exactly the figures the collapse draws, so a
/// figure added to one and not the other is caught here.
#[test]
fn captioned_plots_are_the_collapse_figures() {
    let mut captioned: Vec<&str> = super::KNOWN_PLOTS.iter().map(|(s, _)| *s).collect();
    let mut drawn = crate::figures::FIGURE_STEMS.to_vec();
    captioned.sort_unstable();
    drawn.sort_unstable();
    assert_eq!(captioned, drawn);
}

/// Standard base64 back to bytes (the inverse of [`super::html::base64`]).
fn base64_decode(text: &str) -> Vec<u8> {
    const B64: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let vals: Vec<u32> = text
        .bytes()
        .filter(|&b| b != b'=')
        .map(|b| B64.iter().position(|&c| c == b).unwrap() as u32)
        .collect();
    let mut out = Vec::new();
    for chunk in vals.chunks(4) {
        let n = chunk
            .iter()
            .enumerate()
            .fold(0, |n, (i, v)| n | v << (18 - 6 * i));
        for k in 0..chunk.len() - 1 {
            out.push((n >> (16 - 8 * k)) as u8);
        }
    }
    out
}

#[test]
fn base64_decodes_back() {
    for bytes in [&b""[..], b"a", b"ab", b"abc", b"\xff\x00\x10dropscope"] {
        assert_eq!(base64_decode(&super::html::base64(bytes)), bytes);
    }
}

/// Rows carry their sort keys (full precision; none for a failed row's
/// measurements), their status and their lower-cased name and reason for
/// the filter.
#[test]
fn rows_carry_their_sort_and_filter_keys() {
    let dir = tempfile::tempdir().unwrap();
    let recs = records();
    let page = String::from_utf8(render_report(dir.path(), "p.toml", &recs)).unwrap();
    let r = &recs[0];
    assert!(page.contains(&format!(
        "data-n=\"1\" data-run=\"{}\" data-status=\"ok\" data-r=\"{}\" data-v=\"{}\"",
        r.run,
        r.sphere_radius_mm,
        r.v_impact_m_s.unwrap()
    )));
    let failed = page.split("<tbody").last().unwrap();
    assert!(failed.contains("data-status=\"failed\""));
    assert!(!failed.contains("data-v=") && !failed.contains("data-tau="));
    assert!(failed.contains(&format!(
        "data-text=\"{}\"",
        escape(&format!("{EVIL_RUN} {EVIL_REASON}").to_lowercase())
    )));
    assert_eq!(page.matches("<th data-sort=").count(), 10);
    assert!(page.contains("<span id=\"drop-count\">21 of 21 drops</span>"));
}
