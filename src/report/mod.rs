//! `report.html`: one self-contained page for a person checking a
//! campaign — the counts, the collapse plots, the fits and one row per drop
//! with its numbers, status, overlay and diagnostics.
//!
//! | file | does |
//! | --- | --- |
//! | [`html`] | escaping, base64 data URIs, `value ± error` formatting |
//! | [`fits`] | the fits tables from `fits.json` |
//! | [`drops`] | the drops table from the records, with the overlay and diagnostic figures |
//!
//! The page reads what the other stages wrote into the output folder
//! (`collapse.csv`, `fits.json`, `plots/*.svg`, `plots/overlays/<run>.png`,
//! `plots/impacts/<run>.png`, `plots/drops/<run>.svg`), recomputes nothing
//! and writes nothing: [`render_report`] returns its bytes, the job level
//! writes them (`crate::job::report_job`). It stays small for thousands of drops: the collapse plots are
//! inline SVG and each overlay an inline thumbnail (a JPEG `data:` URI);
//! the full-size overlay, the animated impact and the per-drop figure are
//! the files beside the page, named by relative paths inside `plots/` and
//! loaded only when opened. The style sheet and the script (enlarging,
//! sorting and filtering the drops table) are inline; no URL anywhere. It
//! holds no date and no output path, so the same inputs give the same bytes
//! wherever the output folder is.

pub mod drops;
pub mod fits;
pub mod html;
#[cfg(test)]
mod tests;

use std::fmt::Write;
use std::path::{Path, PathBuf};

use crate::dataset::{DropRecord, DropStatus};
use crate::util::out_folder::Ledger;
use html::escape;

/// Why report.html could not be written (missing or unreadable collapse
/// files are said in the page, not here).
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// The report could not be written.
    #[error("{path}: cannot write the report: {source}")]
    Write {
        /// The report file.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The collapse files are another dataset's than the folder's drops.csv.
    #[error(transparent)]
    Mixed(#[from] crate::dataset::id::Mixed),
    /// A file the report shows could not be read.
    #[error("{path}: cannot read: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
}

/// Refuse a folder whose collapse files (`fits.json`, `collapse.csv`, the
/// SVG figures) were computed from another drops.csv than the one in it
/// ([`crate::dataset::id`]). A folder without fits.json has nothing to mix;
/// an SVG that carries no dataset id is not dropscope's (a figure of
/// yours) and not looked at.
pub fn check_one_dataset(out_dir: &Path) -> Result<(), ReportError> {
    use crate::dataset::id::{check, of_svg};
    let fits_path = out_dir.join("fits.json");
    let Ok(fits) = std::fs::read(&fits_path) else {
        return Ok(());
    };
    let drops = out_dir.join("drops.csv");
    let read = |path: &Path| {
        std::fs::read(path).map_err(|source| ReportError::Read {
            path: path.to_path_buf(),
            source,
        })
    };
    let expected = crate::dataset::id::of_bytes(&read(&drops)?);
    let doc: serde_json::Value = serde_json::from_slice(&fits).unwrap_or_default();
    let found = doc["provenance"]["dataset_id"].as_str();
    check(&fits_path, found, &drops, &expected)?;
    let collapse = out_dir.join("collapse.csv");
    if let Ok(mut r) = csv::Reader::from_path(&collapse) {
        let col = r
            .headers()
            .ok()
            .and_then(|h| h.iter().position(|c| c == "dataset_id"));
        for row in r.records() {
            let found = row.ok().and_then(|row| Some(row.get(col?)?.to_string()));
            check(&collapse, found.as_deref(), &drops, &expected)?;
        }
    }
    // Any SVG that says it is one of dropscope's (carries a dataset id): a
    // figure of another job copied in is refused; read through no link.
    for sub in ["plots", "plots/drops"] {
        let Ok(dir) = crate::util::out_folder::path(out_dir, sub) else {
            continue;
        };
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        let mut svgs: Vec<String> = entries
            .flatten()
            .filter(|e| e.file_type().is_ok_and(|t| t.is_file()))
            .filter_map(|e| e.file_name().to_str().map(str::to_string))
            .filter(|n| n.ends_with(".svg"))
            .collect();
        svgs.sort();
        for name in svgs {
            let rel = format!("{sub}/{name}");
            let Ok(Some(bytes)) = crate::util::out_folder::read(out_dir, &rel, SVG_MAX_BYTES)
            else {
                continue;
            };
            let text = String::from_utf8_lossy(&bytes);
            if let Some(found) = of_svg(&text) {
                check(&out_dir.join(&rel), Some(found), &drops, &expected)?;
            }
        }
    }
    Ok(())
}

/// A figure larger than this is not read into the page (a long movie's
/// per-drop figure is ~11 MB).
const SVG_MAX_BYTES: u64 = 256 << 20;

const STYLE: &str = include_str!("style.css");

/// Click a thumbnail (or "▶ impact") to see the full-size picture (or the
/// animation) over the page, click again to close; unfold a drop's
/// diagnostics to load its figure (a thousand figures loaded with the page
/// would take it half a minute to load); click a column head of
/// the drops table to sort by it (again: the other way; rows without the
/// value last); type in the filter box or pick a status to show only the
/// matching drops.
const SCRIPT: &str = r#"
var z = document.getElementById('zoom'), zi = z.querySelector('img');
function show(src, alt) { zi.src = src; zi.alt = alt; z.hidden = false; }
document.querySelectorAll('img.thumb').forEach(function (i) {
  i.addEventListener('click', function () { show(i.getAttribute('data-full') || i.src, i.alt); });
});
document.querySelectorAll('a.movie').forEach(function (a) {
  a.addEventListener('click', function (e) { e.preventDefault(); show(a.getAttribute('href'), a.title); });
});
z.addEventListener('click', function () { z.hidden = true; zi.removeAttribute('src'); });
document.querySelectorAll('details').forEach(function (d) {
  d.addEventListener('toggle', function () {
    var i = d.querySelector('img[data-src]');
    if (d.open && i && !i.getAttribute('src')) { i.src = i.getAttribute('data-src'); }
  });
});
var t = document.querySelector('table.drops');
if (t) {
  var f = document.getElementById('drop-filter'), s = document.getElementById('drop-status'),
    c = document.getElementById('drop-count'), rows = Array.prototype.slice.call(t.tBodies);
  var filter = function () {
    var q = f.value.trim().toLowerCase(), st = s.value, n = 0;
    rows.forEach(function (b) {
      var on = (!st || b.getAttribute('data-status') === st) &&
        (!q || b.getAttribute('data-text').indexOf(q) >= 0);
      b.hidden = !on; n += on ? 1 : 0;
    });
    c.textContent = n + ' of ' + rows.length + ' drops';
  };
  f.addEventListener('input', filter); s.addEventListener('change', filter);
  t.querySelectorAll('th[data-sort]').forEach(function (th) {
    th.addEventListener('click', function () {
      var k = 'data-' + th.getAttribute('data-sort'), text = k === 'data-run' || k === 'data-status',
        dir = th.getAttribute('aria-sort') === 'ascending' ? -1 : 1;
      t.querySelectorAll('th[aria-sort]').forEach(function (h) { h.removeAttribute('aria-sort'); });
      th.setAttribute('aria-sort', dir > 0 ? 'ascending' : 'descending');
      rows.sort(function (a, b) {
        var x = a.getAttribute(k), y = b.getAttribute(k);
        if (x === null || y === null) { return (x === null) - (y === null); }
        return dir * (text ? x.localeCompare(y) : parseFloat(x) - parseFloat(y));
      });
      rows.forEach(function (b) { t.appendChild(b); });
    });
  });
}
"#;

/// The collapse figures in reading order, with their captions; any other
/// SVG the collapse writes into `plots/` follows, sorted by name.
const KNOWN_PLOTS: [(&str, &str); 4] = [
    (
        "psi_vs_xi",
        "Ψ(Ξ): the penetration collapse (Eq. 8, Fig. 3b of Maruoka 2019). All radii should fall \
         on one curve, tending to 2<sup>1/3</sup> at small Ξ.",
    ),
    (
        "omega_vs_xi",
        "Ω(Ξ): the contact-time collapse (Eq. 10). All radii on one curve, tending to \
         C<sub>0</sub> ≈ 3.533 at small Ξ.",
    ),
    (
        "pi_vs_eta",
        "Π = δ/R against η = ρv²/E (log–log, Fig. 3a), with each radius's power law and guide \
         slopes 1/3 and 1/6.",
    ),
    (
        "tau_vs_v",
        "τ<sub>c</sub> against v (log–log, Fig. 4a), with each radius's power law and guide \
         slopes −1/3 and −2/3.",
    ),
];

/// How a collapse figure enters the page.
enum Plot {
    /// Inline: an SVG this folder's ledger lists as dropscope's, unchanged.
    Inline(String),
    /// By reference (`<img>`, where a browser runs no script): an SVG of
    /// the figure's name and this dataset that the ledger does not list
    /// (written by an older dropscope, or by someone else).
    Referenced(String),
}

/// The collapse figures of `plots/`, as (stem, how shown): the figures the
/// collapse draws ([`KNOWN_PLOTS`]), then any other SVG the ledger lists
/// in `plots/`, sorted by name. No other file is inlined: an SVG dropped
/// into `plots/` never brings its script into the page.
fn collapse_plots(out_dir: &Path, ledger: &Ledger, dataset: Option<&str>) -> Vec<(String, Plot)> {
    let mut others: Vec<String> = ledger
        .listed()
        .filter_map(|rel| {
            let stem = rel.strip_prefix("plots/")?.strip_suffix(".svg")?;
            (!stem.contains('/') && !KNOWN_PLOTS.iter().any(|(k, _)| *k == stem))
                .then(|| stem.to_string())
        })
        .collect();
    others.sort();
    let known: Vec<String> = KNOWN_PLOTS.iter().map(|(k, _)| k.to_string()).collect();
    known
        .into_iter()
        .chain(others)
        .filter_map(|stem| {
            let rel = format!("plots/{stem}.svg");
            if let Some(bytes) = ledger.read_owned(&rel, SVG_MAX_BYTES) {
                let text = String::from_utf8(bytes).ok()?;
                // Only an SVG document is inlined; the namespace declaration is
                // implied for <svg> inside HTML, so the page names no URL at all.
                let text = text.trim_start();
                return text.starts_with("<svg").then(|| {
                    let svg = text.replacen(" xmlns=\"http://www.w3.org/2000/svg\"", "", 1);
                    (stem, Plot::Inline(svg))
                });
            }
            let bytes = crate::util::out_folder::read(out_dir, &rel, SVG_MAX_BYTES).ok()??;
            let ours = dataset.is_some()
                && crate::dataset::id::of_svg(&String::from_utf8_lossy(&bytes)) == dataset;
            let known = KNOWN_PLOTS.iter().any(|(k, _)| *k == stem);
            (ours && known).then(|| (stem.clone(), Plot::Referenced(rel)))
        })
        .collect()
}

fn caption(stem: &str) -> String {
    KNOWN_PLOTS
        .iter()
        .find(|(k, _)| *k == stem)
        .map_or_else(|| escape(stem), |(_, c)| c.to_string())
}

/// The `run` and `used` columns of collapse.csv, in its order (None when
/// unreadable).
fn collapse_rows(out_dir: &Path) -> Option<Vec<(String, bool)>> {
    let mut r = csv::Reader::from_path(out_dir.join("collapse.csv")).ok()?;
    let headers = r.headers().ok()?.clone();
    let col = |name: &str| headers.iter().position(|h| h == name);
    let (run, used) = (col("run")?, col("used")?);
    r.records()
        .map(|row| {
            let row = row.ok()?;
            let name = crate::util::text::csv_cell_back(row.get(run)?);
            Some((name.to_string(), row.get(used)? == "true"))
        })
        .collect()
}

/// Whether collapse.csv describes these records: the same runs in the same
/// order, and no run it used that has failed since. (A drop the collapse
/// skipped may be measured: it can lack a, say.)
fn collapse_matches(rows: &[(String, bool)], records: &[DropRecord]) -> bool {
    rows.len() == records.len()
        && rows
            .iter()
            .zip(records)
            .all(|((run, used), r)| *run == r.run && (!*used || r.status.collapses()))
}

fn counts(records: &[DropRecord]) -> [usize; 6] {
    let n = |s: DropStatus| records.iter().filter(|r| r.status == s).count();
    [
        n(DropStatus::Ok),
        n(DropStatus::Warning),
        n(DropStatus::Tracked),
        n(DropStatus::Failed),
        n(DropStatus::Accepted),
        n(DropStatus::Rejected),
    ]
}

/// The counts of the review's outcomes, when a review decided any.
fn review_counts(accepted: usize, rejected: usize) -> String {
    if accepted + rejected == 0 {
        return String::new();
    }
    format!(
        " <span class=\"count accepted\">{accepted} accepted in review</span> \
         <span class=\"count rejected\">{rejected} rejected in review</span>"
    )
}

/// Every decision of `dropscope review` the records carry (drops.csv's
/// `review` column), a line a drop; nothing when there is none.
fn review_section(out: &mut String, records: &[DropRecord]) {
    let reviewed: Vec<&DropRecord> = records.iter().filter(|r| !r.review.is_empty()).collect();
    if reviewed.is_empty() {
        return;
    }
    let _ = write!(
        out,
        "<section id=\"review\"><h2>Review decisions</h2><p>Decided by a person in \
         <code>dropscope review</code> (<code>review.csv</code>) and applied by the job that \
         wrote this folder: {} of {} drops.</p><ul class=\"review\">",
        reviewed.len(),
        records.len()
    );
    for r in reviewed {
        let _ = write!(
            out,
            "<li><b>{}</b> <span class=\"badge {}\">{}</span> {}</li>",
            escape(&r.run),
            r.status.word(),
            r.status.word(),
            escape(&r.review)
        );
    }
    out.push_str("</ul></section>");
}

fn header(out: &mut String, out_dir: &Path, config_name: &str, records: &[DropRecord]) {
    let [ok, warning, tracked, failed, accepted, rejected] = counts(records);
    let tracked = if tracked > 0 {
        format!(" <span class=\"count tracked\">{tracked} tracked without contact</span>")
    } else {
        String::new()
    };
    let dataset = crate::dataset::id::of_file(&out_dir.join("drops.csv"))
        .map(|id| format!(" · dataset <code title=\"SHA-256 of drops.csv\">{id}</code>"))
        .unwrap_or_default();
    let _ = write!(
        out,
        "<header><h1>dropscope report</h1><p class=\"meta\">dropscope {version} · configuration \
         <code>{config}</code>{dataset}</p><p class=\"counts\"><span class=\"count\">{total} runs</span> \
         <span class=\"count ok\">{ok} measured</span> <span class=\"count warning\">{warning} \
         measured with warnings</span>{tracked} <span class=\"count failed\">{failed} failed</span>{review}</p></header>",
        version = env!("CARGO_PKG_VERSION"),
        config = escape(config_name),
        total = records.len(),
        review = review_counts(accepted, rejected),
    );
    out.push_str(
        "<section id=\"how\"><h2>How to read this page</h2><ul>\
         <li><b>Drops</b> (last section): one row per run, in the manifest's order. Numbers are \
         value ± one-sigma uncertainty, the error to two significant digits; units in the column \
         heads. <span class=\"badge ok\">ok</span> all measured; \
         <span class=\"badge warning\">warning</span> measured, but read the note (e.g. the \
         fitted gravity off by more than 2 %: check the frame rate and scale); \
         <span class=\"badge failed\">FAILED</span> nothing measured, the reason says which \
         file or frame and why; <span class=\"badge tracked\">tracked</span> the sphere was \
         followed but never reached the surface (a calibration drop, a clip cut before the \
         impact): its overlay, track and the velocity at its last frame, no impact. Failed and \
         tracked rows are left out of the collapse. After \
         <code>dropscope review</code>: <span class=\"badge accepted\">accepted</span> a \
         warning a person checked and accepted; <span class=\"badge rejected\">rejected</span> \
         measured, but left out of the collapse by a person, who says why; the \
         <i>review</i> line under a status lists every decision about the drop.</li>\
         <li><b>Overlay</b>: the frame nearest the maximum penetration, enlarged, with the edge \
         points, the fitted circle and the surface line. The circle should hug the sphere's \
         edge and the line sit on the pillar tops. Click to enlarge.</li>\
         <li><b>Diagnostics</b> (fold-out under each row): z(t) with the free-flight parabolas, \
         which should follow the points before contact and after rebound, and the contact and \
         rebound times; δ(t); and F(δ) with the fitted F = K δ<sup>n</sup> beside the model \
         (πEφR/h) δ².</li>\
         <li><b>Collapse</b>: in Ψ(Ξ) and Ω(Ξ) every radius should fall on one curve. A red \
         warning on a plot means some drops use the geometric contact radius, for which the \
         Ψ(Ξ) collapse holds by construction. The panel under each fit shows every point's \
         residual from it with its error bar: a trend there is what the fit misses.</li>\
         <li><b>Fits</b>: value ± standard error (covariance scaled by the reduced χ²), then the \
         95 % bootstrap interval. Everything here is read from <code>fits.json</code> and \
         <code>collapse.csv</code>; the CSV and JSON files beside this page hold every digit.</li>\
         </ul></section>",
    );
}

fn collapse_section(out: &mut String, out_dir: &Path, records: &[DropRecord]) {
    out.push_str("<section id=\"collapse\"><h2>Collapse</h2>");
    let fits_path = out_dir.join("fits.json");
    let fits_bytes = std::fs::read(&fits_path).ok();
    if fits_bytes.is_none() {
        let measured = records.iter().filter(|r| r.status.collapses()).count();
        let _ = write!(
            out,
            "<p class=\"missing\">The collapse did not run: no fits.json in the output folder{}.</p>",
            if measured == 0 {
                " (no drop was measured)"
            } else {
                ""
            }
        );
    } else {
        match collapse_rows(out_dir) {
            Some(rows) if collapse_matches(&rows, records) => {}
            Some(rows) => {
                let _ = write!(
                    out,
                    "<p class=\"alarm\">The collapse files in this folder are not from these \
                     drops: collapse.csv lists {} runs, this report {}, or uses runs that have \
                     failed since. They are from an earlier job; run the collapse again.</p>",
                    rows.len(),
                    records.len()
                );
            }
            None => out.push_str(
                "<p class=\"alarm\">collapse.csv is missing or unreadable: the fits below may \
                 be from an earlier job.</p>",
            ),
        }
    }
    // The collapse writes fits.json first: plots without it are an earlier job's.
    let plots = if fits_bytes.is_some() {
        let dataset = crate::dataset::id::of_file(&out_dir.join("drops.csv")).ok();
        collapse_plots(out_dir, &Ledger::open(out_dir), dataset.as_deref())
    } else {
        Vec::new()
    };
    if plots.is_empty() {
        if fits_bytes.is_some() {
            out.push_str("<p class=\"missing\">The collapse wrote no plots.</p>");
        }
    } else {
        out.push_str("<div class=\"plots\">");
        for (stem, plot) in &plots {
            let figure = match plot {
                Plot::Inline(svg) => svg.clone(),
                Plot::Referenced(rel) => format!(
                    "<img src=\"{}\" alt=\"{}\">",
                    drops::url_path(rel),
                    escape(stem)
                ),
            };
            let _ = write!(
                out,
                "<figure id=\"plot-{id}\">{figure}<figcaption>{}</figcaption></figure>",
                caption(stem),
                id = escape(stem)
            );
        }
        out.push_str("</div>");
    }
    out.push_str("</section><section id=\"fits\"><h2>Fits</h2>");
    match fits_bytes.map(|b| serde_json::from_slice::<serde_json::Value>(&b)) {
        None => out.push_str("<p class=\"missing\">No fits (the collapse did not run).</p>"),
        Some(Err(e)) => {
            let _ = write!(
                out,
                "<p class=\"alarm\">fits.json could not be read: {}</p>",
                escape(&e.to_string())
            );
        }
        Some(Ok(doc)) => out.push_str(&fits::fits_section(&doc)),
    }
    out.push_str("</section>");
}

/// The whole page as bytes.
pub fn render_report(out_dir: &Path, config_name: &str, records: &[DropRecord]) -> Vec<u8> {
    let mut out = String::new();
    let _ = write!(
        out,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\
         <title>dropscope report — {}</title><style>{STYLE}</style></head><body>",
        escape(config_name)
    );
    header(&mut out, out_dir, config_name, records);
    collapse_section(&mut out, out_dir, records);
    review_section(&mut out, records);
    out.push_str("<section id=\"drops\"><h2>Drops</h2>");
    if records.is_empty() {
        out.push_str("<p class=\"missing\">No runs.</p>");
    } else {
        out.push_str(&drops::drops_table(out_dir, records));
    }
    let _ = writeln!(
        out,
        "</section><div id=\"zoom\" hidden><img alt=\"\"></div><script>{SCRIPT}</script>\
         </body></html>"
    );
    out.into_bytes()
}
