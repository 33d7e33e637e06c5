//! The drops table: one row per record of drops.csv, its numbers with
//! their one-sigma uncertainties in the units of SPEC §4, its status and
//! reason, a thumbnail of the overlay at maximum penetration (the full
//! picture `plots/overlays/<run>.png` and the animated impact
//! `plots/impacts/<run>.png` open from it) and, folded under the row, the
//! per-drop diagnostic figure (`plots/drops/<run>.svg`: z(t), δ(t), F(δ)),
//! loaded when unfolded.
//!
//! Built for archives of thousands of drops: only the thumbnails are
//! inline (a small JPEG each); the full-size pictures are the files beside
//! the page, loaded when asked for. Every row carries its sort keys, and
//! the page's script sorts the table by any column and filters it by name,
//! reason and status.

use std::fmt::Write;
use std::path::Path;

use super::html::{data_uri, escape, num, pm};
use crate::dataset::{DropRecord, DropStatus};

/// Columns of a row, for the failed rows' reason cell and the diagnostics row.
const N_COLUMNS: usize = 11;

/// Width of an inline overlay thumbnail, pixels (shown at 100 CSS px).
pub const THUMB_PX: u32 = 100;
/// JPEG quality of the thumbnails.
const THUMB_QUALITY: u8 = 75;

/// The path of a figure file of the output folder relative to it, when the
/// run name is a plain file name (the writers use it as one; any other name
/// could point outside `plots/`), the run was measured (a failed run's
/// files, if any, are from an earlier job) and the file is there.
fn figure(out_dir: &Path, rec: &DropRecord, sub: &str, ext: &str) -> Option<String> {
    if rec.status == DropStatus::Failed || crate::dataset::run_name::check(&rec.run).is_err() {
        return None;
    }
    let rel = format!("plots/{sub}/{}.{ext}", rec.run);
    crate::util::out_folder::path(out_dir, &rel)
        .is_ok_and(|p| p.is_file())
        .then_some(rel)
}

/// An overlay larger than this is not made into a thumbnail (dropscope's
/// are ~100 kB).
const OVERLAY_MAX_BYTES: u64 = 64 << 20;

/// A relative path as a URL path: every byte but the unreserved characters
/// and `/` percent-encoded (run names may hold `#`, `?`, `%` or spaces).
pub fn url_path(rel: &str) -> String {
    let mut out = String::with_capacity(rel.len());
    for b in rel.bytes() {
        if b.is_ascii_alphanumeric() || b"-._~/".contains(&b) {
            out.push(b as char);
        } else {
            let _ = write!(out, "%{b:02X}");
        }
    }
    out
}

/// The overlay at `rel` shrunk to [`THUMB_PX`] wide, as JPEG bytes.
fn thumbnail(out_dir: &Path, rel: &str) -> Option<Vec<u8>> {
    // Read through no link, decoded within the frame readers' pixel cap.
    let bytes = crate::util::out_folder::read(out_dir, rel, OVERLAY_MAX_BYTES).ok()??;
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .ok()?;
    reader.limits(crate::source::decode_limits());
    let img = reader.decode().ok()?.to_rgb8();
    let (w, h) = img.dimensions();
    let tw = THUMB_PX.min(w).max(1);
    let th = ((u64::from(h) * u64::from(tw)) / u64::from(w.max(1))).max(1) as u32;
    let small = image::imageops::thumbnail(&img, tw, th);
    let mut out = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, THUMB_QUALITY)
        .encode_image(&small)
        .ok()?;
    Some(out)
}

fn cell(value: Option<f64>, err: Option<f64>) -> String {
    value.map_or_else(
        || "<td class=\"num\">—</td>".into(),
        |v| format!("<td class=\"num\">{}</td>", pm(v, err)),
    )
}

fn status(rec: &DropRecord) -> (&'static str, &'static str) {
    match rec.status {
        DropStatus::Ok => ("ok", "ok"),
        DropStatus::Warning => ("warning", "warning"),
        DropStatus::Failed => ("failed", "FAILED"),
        DropStatus::Tracked => ("tracked", "tracked"),
        DropStatus::Rejected => ("rejected", "rejected"),
        DropStatus::Accepted => ("accepted", "accepted"),
    }
}

/// The sortable columns: the key a row carries (`data-<key>`) and its head.
const SORT_KEYS: [(&str, &str); 10] = [
    ("n", "#"),
    ("run", "run"),
    ("r", "R (mm)"),
    ("status", "status"),
    ("v", "v<sub>impact</sub> (m/s)"),
    ("delta", "δ<sub>max</sub> (mm)"),
    ("a", "a<sub>max</sub> (mm)"),
    ("tau", "τ<sub>c</sub> (ms)"),
    ("e", "e"),
    ("vr", "v<sub>rebound</sub> (m/s)"),
];

/// A sort key's attribute: a number in full precision, or nothing.
fn key(name: &str, v: Option<f64>) -> String {
    v.filter(|v| v.is_finite())
        .map_or_else(String::new, |v| format!(" data-{name}=\"{v}\""))
}

/// What the filter box searches in a row: its run, reason and review, in
/// lower case.
fn search_text(rec: &DropRecord) -> String {
    [rec.run.as_str(), &rec.reason, &rec.review]
        .iter()
        .filter(|t| !t.is_empty())
        .copied()
        .collect::<Vec<_>>()
        .join(" ")
        .to_lowercase()
}

/// The filter controls above the table.
fn controls(n: usize) -> String {
    format!(
        "<div class=\"filter\"><label>filter <input id=\"drop-filter\" type=\"search\" \
         placeholder=\"run name or reason\"></label> <label>status <select id=\"drop-status\">\
         <option value=\"\">all</option><option>ok</option><option>warning</option>\
         <option>tracked</option><option>failed</option><option>accepted</option><option>rejected</option></select></label> <span id=\"drop-count\">{n} of {n} drops\
         </span> · click a column head to sort</div>"
    )
}

/// An overlay's path and its thumbnail's JPEG bytes.
type Thumb = (String, Vec<u8>);

/// The table of every drop, in the records' order, with its filter controls.
pub fn drops_table(out_dir: &Path, records: &[DropRecord]) -> String {
    let mut out = controls(records.len());
    out.push_str("<table class=\"drops\"><thead><tr>");
    for (k, head) in SORT_KEYS {
        let _ = write!(
            out,
            "<th data-sort=\"{k}\" title=\"click to sort\">{head}</th>"
        );
    }
    out.push_str("<th>overlay at δ<sub>max</sub></th></tr></thead>");
    let thumbs = thumbnails(out_dir, records);
    for ((i, rec), thumb) in records.iter().enumerate().zip(thumbs) {
        drop_rows(&mut out, out_dir, i + 1, rec, thumb);
    }
    out.push_str("</table>");
    out
}

/// Each record's overlay and its thumbnail, where there is one.
fn thumbnails(out_dir: &Path, records: &[DropRecord]) -> Vec<Option<Thumb>> {
    // The thumbnails on every core: a thousand overlays to decode and shrink.
    use rayon::prelude::*;
    records
        .par_iter()
        .map(|rec| {
            let rel = figure(out_dir, rec, "overlays", "png")?;
            let jpeg = thumbnail(out_dir, &rel)?;
            Some((rel, jpeg))
        })
        .collect()
}

/// Drop number `n`'s rows: its numbers (or why there are none) and its
/// overlay, then its folded diagnostics.
fn drop_rows(out: &mut String, out_dir: &Path, n: usize, rec: &DropRecord, thumb: Option<Thumb>) {
    let run = escape(&rec.run);
    row_start(out, n, rec, &run);
    let reason = if rec.reason.is_empty() {
        "no reason recorded".into()
    } else {
        escape(&rec.reason)
    };
    if rec.status == DropStatus::Failed {
        let _ = write!(
            out,
            "<td colspan=\"{}\" class=\"reason\">{reason}</td>",
            N_COLUMNS - 4,
        );
    } else {
        if rec.status == DropStatus::Tracked {
            tracked_cell(out, rec, &reason);
        } else {
            out.push_str(&cell(rec.v_impact_m_s, rec.v_impact_m_s_err));
            out.push_str(&cell(rec.delta_max_mm, rec.delta_max_mm_err));
            out.push_str(&cell(rec.a_max_mm, rec.a_max_mm_err));
            out.push_str(&cell(rec.tau_c_ms, rec.tau_c_ms_err));
            out.push_str(&cell(rec.restitution, rec.restitution_err));
            out.push_str(&cell(rec.v_rebound_m_s, rec.v_rebound_m_s_err));
        }
        overlay_cell(out, out_dir, rec, &run, thumb);
    }
    out.push_str("</tr>");
    if let Some(svg) = figure(out_dir, rec, "drops", "svg") {
        let _ = write!(
            out,
            "<tr class=\"diag\"><td></td><td colspan=\"{}\"><details><summary>diagnostics of \
             {run}: z(t) with the flight parabolas and events, δ(t), F(δ)</summary>\
             <img class=\"diagram\" data-src=\"{url}\" alt=\"diagnostics of {run}\">\
             <a href=\"{url}\">the figure alone</a></details></td></tr>",
            N_COLUMNS - 1,
            url = url_path(&svg)
        );
    }
    out.push_str("</tbody>");
}

/// A drop's group with its sort keys and search text, and its row's first
/// cells: number, run (`run`, escaped), radius, status with the reason and
/// review.
fn row_start(out: &mut String, n: usize, rec: &DropRecord, run: &str) {
    let (class, label) = status(rec);
    let measured = rec.status.measured();
    let keys: String = [
        ("v", rec.v_impact_m_s),
        ("delta", rec.delta_max_mm),
        ("a", rec.a_max_mm),
        ("tau", rec.tau_c_ms),
        ("e", rec.restitution),
        ("vr", rec.v_rebound_m_s),
    ]
    .into_iter()
    .filter(|_| measured)
    .map(|(k, v)| key(k, v))
    .collect();
    let _ = write!(
        out,
        "<tbody class=\"{class}\" id=\"drop-{n}\" data-n=\"{n}\" data-run=\"{run}\" \
         data-status=\"{class}\"{r}{keys} data-text=\"{text}\"><tr><td class=\"num\">{n}</td>\
         <th class=\"run\">{run}</th><td class=\"num\">{}</td><td class=\"status\">\
         <span class=\"badge {class}\">{label}</span>",
        num(rec.sphere_radius_mm),
        r = key("r", Some(rec.sphere_radius_mm)),
        text = escape(&search_text(rec)),
    );
    let noted = matches!(
        rec.status,
        DropStatus::Warning | DropStatus::Accepted | DropStatus::Rejected
    );
    if noted && !rec.reason.is_empty() {
        let _ = write!(out, "<div class=\"reason\">{}</div>", escape(&rec.reason));
    }
    if !rec.review.is_empty() {
        let _ = write!(
            out,
            "<div class=\"review\" title=\"decided in dropscope review (review.csv)\">\
             review: {}</div>",
            escape(&rec.review)
        );
    }
    out.push_str("</td>");
}

/// A tracked drop's one cell over the numbers: no impact, so the free
/// flight's velocity at its last frame, and `reason` (escaped).
fn tracked_cell(out: &mut String, rec: &DropRecord, reason: &str) {
    let v = match (rec.v_last_m_s, rec.t_last_s) {
        (Some(v), Some(t)) => format!(
            "v = {} m/s at the last frame ({} ms): ",
            pm(v, rec.v_last_m_s_err),
            num(t * 1e3)
        ),
        _ => String::new(),
    };
    let _ = write!(
        out,
        "<td colspan=\"{}\" class=\"reason\">{v}{reason}</td>",
        N_COLUMNS - 5,
    );
}

/// The overlay's thumbnail, opening the full picture, and the link to the
/// animated impact; or a note that there is no overlay.
fn overlay_cell(
    out: &mut String,
    out_dir: &Path,
    rec: &DropRecord,
    run: &str,
    thumb: Option<Thumb>,
) {
    let Some((rel, jpeg)) = thumb else {
        out.push_str("<td class=\"missing\">no overlay</td>");
        return;
    };
    let _ = write!(
        out,
        "<td><img class=\"thumb\" src=\"{}\" data-full=\"{}\" \
         alt=\"overlay of {run}\" title=\"click to enlarge\">",
        data_uri("image/jpeg", &jpeg),
        url_path(&rel)
    );
    if let Some(movie) = figure(out_dir, rec, "impacts", "png") {
        let _ = write!(
            out,
            "<a class=\"movie\" href=\"{}\" title=\"the impact, frame by frame\">\
             ▶ impact</a>",
            url_path(&movie)
        );
    }
    out.push_str("</td>");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn run_names_become_url_paths() {
        assert_eq!(
            url_path("plots/overlays/R3 #1?%.png"),
            "plots/overlays/R3%20%231%3F%25.png"
        );
        assert_eq!(url_path("plots/drops/Rä.svg"), "plots/drops/R%C3%A4.svg");
    }
}
