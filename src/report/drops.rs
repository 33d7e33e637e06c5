//! The drops table: one row per record of drops.csv, its numbers with
//! their one-sigma uncertainties in the units of SPEC §4, its status and
//! reason, the overlay at maximum penetration (`plots/overlays/<run>.png`)
//! and, folded under the row, the per-drop diagnostic figure that the
//! collapse draws (`plots/drops/<run>.svg`: z(t), δ(t), F(δ)).

use std::fmt::Write;
use std::path::Path;

use super::html::{data_uri, escape, num, pm};
use crate::dataset::{DropRecord, DropStatus};

/// Columns of a row, for the failed rows' reason cell and the diagnostics row.
const N_COLUMNS: usize = 11;

/// A figure file of the output folder, when the run name is a plain file
/// name (the writers use it as one; any other name could point outside
/// `plots/`) and the run was measured (a failed run's files, if any, are
/// from an earlier job).
fn figure(out_dir: &Path, rec: &DropRecord, sub: &str, ext: &str) -> Option<Vec<u8>> {
    if rec.status == DropStatus::Failed || crate::plot::file_stem(&rec.run) != rec.run {
        return None;
    }
    std::fs::read(
        out_dir
            .join("plots")
            .join(sub)
            .join(format!("{}.{ext}", rec.run)),
    )
    .ok()
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
    }
}

/// The table of every drop, in the records' order.
pub fn drops_table(out_dir: &Path, records: &[DropRecord]) -> String {
    let mut out = String::from(
        "<table class=\"drops\"><thead><tr><th>#</th><th>run</th><th>R (mm)</th>\
         <th>status</th><th>v<sub>impact</sub> (m/s)</th><th>δ<sub>max</sub> (mm)</th>\
         <th>a<sub>max</sub> (mm)</th><th>τ<sub>c</sub> (ms)</th><th>e</th>\
         <th>v<sub>rebound</sub> (m/s)</th><th>overlay at δ<sub>max</sub></th></tr></thead>",
    );
    for (i, rec) in records.iter().enumerate() {
        let (class, label) = status(rec);
        let run = escape(&rec.run);
        let _ = write!(
            out,
            "<tbody class=\"{class}\" id=\"drop-{n}\"><tr><td class=\"num\">{n}</td>\
             <th class=\"run\">{run}</th><td class=\"num\">{}</td><td class=\"status\">\
             <span class=\"badge {class}\">{label}</span>",
            num(rec.sphere_radius_mm),
            n = i + 1
        );
        if rec.status == DropStatus::Warning && !rec.reason.is_empty() {
            let _ = write!(out, "<div class=\"reason\">{}</div>", escape(&rec.reason));
        }
        out.push_str("</td>");
        if rec.status == DropStatus::Failed {
            let _ = write!(
                out,
                "<td colspan=\"{}\" class=\"reason\">{}</td>",
                N_COLUMNS - 4,
                if rec.reason.is_empty() {
                    "no reason recorded".into()
                } else {
                    escape(&rec.reason)
                }
            );
        } else {
            out.push_str(&cell(rec.v_impact_m_s, rec.v_impact_m_s_err));
            out.push_str(&cell(rec.delta_max_mm, rec.delta_max_mm_err));
            out.push_str(&cell(rec.a_max_mm, rec.a_max_mm_err));
            out.push_str(&cell(rec.tau_c_ms, rec.tau_c_ms_err));
            out.push_str(&cell(rec.restitution, rec.restitution_err));
            out.push_str(&cell(rec.v_rebound_m_s, rec.v_rebound_m_s_err));
            match figure(out_dir, rec, "overlays", "png") {
                Some(png) => {
                    let _ = write!(
                        out,
                        "<td><img class=\"thumb\" src=\"{}\" alt=\"overlay of {run}\" \
                         title=\"click to enlarge\" loading=\"lazy\"></td>",
                        data_uri("image/png", &png)
                    );
                }
                None => out.push_str("<td class=\"missing\">no overlay</td>"),
            }
        }
        out.push_str("</tr>");
        if let Some(svg) = figure(out_dir, rec, "drops", "svg") {
            let _ = write!(
                out,
                "<tr class=\"diag\"><td></td><td colspan=\"{}\"><details><summary>diagnostics of \
                 {run}: z(t) with the flight parabolas and events, δ(t), F(δ)</summary>\
                 <img class=\"diagram\" src=\"{}\" alt=\"diagnostics of {run}\" loading=\"lazy\">\
                 </details></td></tr>",
                N_COLUMNS - 1,
                data_uri("image/svg+xml", &svg)
            );
        }
        out.push_str("</tbody>");
    }
    out.push_str("</table>");
    out
}
