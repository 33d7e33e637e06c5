//! The fits section: `fits.json` as the collapse wrote it, laid out as
//! tables (nothing is recomputed here). The document is read as untyped
//! JSON so that a field missing from an older or hand-edited file shows as
//! "—" instead of hiding the whole section.

use serde_json::Value;
use std::fmt::Write;

use super::html::{at_precision_of, escape, num, pm, sig};

const NONE: &str = "—";

fn f(v: &Value, key: &str) -> Option<f64> {
    v.get(key).and_then(Value::as_f64)
}

fn s<'a>(v: &'a Value, key: &str) -> &'a str {
    v.get(key).and_then(Value::as_str).unwrap_or("")
}

/// A count (non-negative integer) as text, or the missing-value mark.
fn count(v: &Value, key: &str) -> String {
    v.get(key)
        .and_then(Value::as_u64)
        .map_or(NONE.into(), |n| n.to_string())
}

/// A 95 % interval, its bounds written to the estimate's precision.
fn interval(ci: Option<&Value>, stderr: Option<f64>) -> String {
    match ci.and_then(Value::as_array).map(|a| a.as_slice()) {
        Some([lo, hi]) => match (lo.as_f64(), hi.as_f64()) {
            (Some(lo), Some(hi)) => {
                format!(
                    " <span class=\"ci\">95 % [{}, {}]</span>",
                    at_precision_of(lo, stderr),
                    at_precision_of(hi, stderr)
                )
            }
            _ => String::new(),
        },
        _ => String::new(),
    }
}

/// An `Estimate` {value, stderr, ci95} as one cell's content.
fn estimate(e: Option<&Value>) -> String {
    let Some(e) = e.filter(|e| !e.is_null()) else {
        return NONE.into();
    };
    match f(e, "value") {
        Some(v) => format!(
            "{}{}",
            pm(v, f(e, "stderr")),
            interval(e.get("ci95"), f(e, "stderr"))
        ),
        None => NONE.into(),
    }
}

fn opt_num(x: Option<f64>) -> String {
    x.map_or_else(|| NONE.into(), num)
}

/// A statistic (χ², residual, range, z) to 3 significant digits.
fn opt_short(x: Option<f64>) -> String {
    x.map_or_else(|| NONE.into(), |x| sig(x, 3))
}

fn yes_no(v: &Value, key: &str) -> &'static str {
    match v.get(key).and_then(Value::as_bool) {
        Some(true) => "yes",
        Some(false) => "no",
        None => NONE,
    }
}

/// One series (Ψ or Ω) as a table row.
fn series_row(
    out: &mut String,
    doc: &Value,
    key: &str,
    names: [&str; 3],
    symbol: &str,
    theory: (&str, Option<f64>, Option<f64>),
) {
    let (theory_name, theory_value, z) = theory;
    let s_ = &doc[key];
    let extrapolated = f(s_, "extrapolated_from_xi");
    let theory_cell = format!(
        "{theory_name} = {}{}",
        opt_num(theory_value),
        z.map_or_else(String::new, |z| format!(
            "; {names0} − theory = {} σ{}",
            sig(z, 2),
            if extrapolated.is_some() {
                " <span class=\"alarm\">(extrapolated)</span>"
            } else {
                ""
            },
            names0 = names[0]
        ))
    );
    if s_.is_null() {
        let _ = write!(
            out,
            "<tr><th>{symbol}</th><td colspan=\"7\" class=\"missing\">not fitted \
             (see the warnings below)</td><td>{theory_cell}</td></tr>"
        );
        return;
    }
    let range = match s_
        .get("xi_range")
        .and_then(Value::as_array)
        .map(|a| a.as_slice())
    {
        Some([lo, hi]) => format!("{} – {}", opt_short(lo.as_f64()), opt_short(hi.as_f64())),
        _ => NONE.into(),
    };
    let _ = write!(
        out,
        "<tr><th>{symbol}<div class=\"law\">{}</div></th>",
        escape(s(s_, "law"))
    );
    for (k, n) in names.iter().enumerate() {
        let mark = match extrapolated {
            Some(lo) if k == 0 => format!(
                "<div class=\"alarm\">extrapolated to Ξ = 0 from Ξ ≥ {}</div>",
                sig(lo, 3)
            ),
            _ => String::new(),
        };
        let _ = write!(out, "<td>{n} = {}{mark}</td>", estimate(s_.get(*n)));
    }
    let _ = write!(
        out,
        "<td>{}</td><td>{}</td><td>{range}</td><td>{}</td><td>{theory_cell}</td></tr>",
        count(s_, "n_drops"),
        opt_short(f(s_, "chi2_red")),
        opt_short(f(s_, "condition_number")),
    );
}

fn series(out: &mut String, doc: &Value) {
    let th = &doc["theory"];
    out.push_str("<h3>Series in Ξ (Eq. 8)</h3>");
    for (key, constant) in [("psi_series", "A1"), ("omega_series", "B1")] {
        if let Some(lo) = f(&doc[key], "extrapolated_from_xi") {
            let _ = write!(
                out,
                "<p class=\"alarm\">EXTRAPOLATED: {constant} is read at Ξ = 0 from drops at \
                 Ξ ≥ {} (condition number {}): it is no measurement of the small-Ξ constant, \
                 and its distance from the theory says nothing about the theory. The \
                 fixed-exponent constants and the exponents above are what these drops \
                 support.</p>",
                sig(lo, 3),
                opt_short(f(&doc[key], "condition_number")),
            );
        }
    }
    out.push_str(
        "<table class=\"fits\"><thead><tr><th>fit</th>\
         <th>constant</th><th>linear</th><th>quadratic</th><th>drops</th><th>χ²<sub>red</sub></th>\
         <th>Ξ range</th><th>condition number</th><th>theory at small Ξ</th></tr></thead><tbody>",
    );
    series_row(
        out,
        doc,
        "psi_series",
        ["A1", "A2", "A3"],
        "Ψ(Ξ)",
        (
            "2<sup>1/3</sup>",
            f(th, "psi_small_xi"),
            f(th, "a1_minus_theory_in_stderr"),
        ),
    );
    series_row(
        out,
        doc,
        "omega_series",
        ["B1", "B2", "B3"],
        "Ω(Ξ)",
        (
            "C<sub>0</sub>",
            f(th, "omega_small_xi_c0"),
            f(th, "b1_minus_theory_in_stderr"),
        ),
    );
    out.push_str("</tbody></table>");
    let c = &doc["crossover_xi"];
    let _ = write!(
        out,
        "<p>Crossover Ξ<sub>c</sub> = A1/A2: {}{}</p>",
        if c.is_null() {
            "none (no series fit, or A1 and A2 of opposite sign)".to_string()
        } else {
            estimate(Some(c))
        },
        if s(c, "definition").is_empty() {
            String::new()
        } else {
            format!(
                " <span class=\"law\">({})</span>",
                escape(s(c, "definition"))
            )
        }
    );
    if !s(th, "source").is_empty() {
        let _ = write!(
            out,
            "<p class=\"note\">Theory: {} (B(1/3, 1/2) = {}).</p>",
            escape(s(th, "source")),
            opt_num(f(th, "beta_1_3_1_2"))
        );
    }
}

fn asymptotes(out: &mut String, doc: &Value) {
    out.push_str(
        "<h3>Asymptotic constants (fixed exponents)</h3><table class=\"fits\"><thead><tr>\
         <th>law</th><th>constant</th><th>drops</th><th>selection</th>\
         <th>rms ln residual</th><th>weighted</th></tr></thead><tbody>",
    );
    for (key, label) in [
        ("eq5_c1", "Ψ = c1 (Eq. 5)"),
        ("eq7_c2", "Ψ/Ξ = c2 (Eq. 7)"),
        ("eq1e_d1", "Ω = d1 (Eq. 1e)"),
        ("eq11_d2", "Ω/Ξ = d2 (Eq. 11)"),
    ] {
        let a = &doc["asymptotes"][key];
        if a.is_null() {
            let _ = write!(
                out,
                "<tr><th>{label}</th><td colspan=\"5\" class=\"missing\">not fitted</td></tr>"
            );
            continue;
        }
        let _ = write!(
            out,
            "<tr><th class=\"law\">{}</th><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            escape(s(a, "law")),
            estimate(a.get("constant")),
            count(a, "n_drops"),
            escape(s(a, "selection")),
            opt_short(f(a, "rms_log_residual")),
            yes_no(a, "weighted"),
        );
    }
    out.push_str("</tbody></table>");
}

fn exponent_cell(e: &Value, name: &str) -> String {
    match f(e, name) {
        Some(v) => format!(
            "{}{}",
            pm(v, f(e, &format!("{name}_stderr"))),
            interval(e.get(format!("{name}_ci")), f(e, &format!("{name}_stderr")))
        ),
        None => NONE.into(),
    }
}

fn exponents(out: &mut String, doc: &Value) {
    out.push_str(
        "<h3>Local exponents per sphere radius</h3><p class=\"note\">Π ∝ η<sup>ν</sup> \
         (the paper finds ν between 1/6 and 1/3) and τ<sub>c</sub> ∝ v<sup>μ</sup> \
         (between −2/3 and −1/3).</p><table class=\"fits\"><thead><tr><th>R (mm)</th>\
         <th>drops</th><th>ν</th><th>drops with τ<sub>c</sub></th><th>μ</th><th>weighted</th>\
         </tr></thead><tbody>",
    );
    let list = doc["exponents"]
        .as_array()
        .map_or(&[][..], |a| a.as_slice());
    if list.is_empty() {
        out.push_str("<tr><td colspan=\"6\" class=\"missing\">none</td></tr>");
    }
    for e in list {
        let _ = write!(
            out,
            "<tr><th>{}</th><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            opt_num(f(e, "radius_mm")),
            count(e, "n_drops"),
            exponent_cell(e, "nu"),
            count(e, "n_tau"),
            exponent_cell(e, "mu"),
            yes_no(e, "weighted"),
        );
    }
    out.push_str("</tbody></table>");
}

fn force_laws(out: &mut String, doc: &Value) {
    let list = doc["force_laws"]
        .as_array()
        .map_or(&[][..], |a| a.as_slice());
    if list.is_empty() {
        return;
    }
    // A campaign's worth of rows is folded away; a handful is shown.
    let _ = write!(
        out,
        "<details class=\"section\"{}><summary><h3>Contact law F = K δ<sup>n</sup> per drop \
         ({})</h3></summary>",
        if list.len() <= 10 { " open" } else { "" },
        crate::util::text::plural(list.len(), "drop")
    );
    out.push_str(
        "<table class=\"fits\"><thead><tr><th>run</th><th>points</th><th>n (model: 2)</th><th>K (N/mm<sup>n</sup>)</th>\
         <th>model πEφR/h (N/mm²)</th><th>from</th></tr></thead><tbody>",
    );
    for l in list {
        let _ = write!(
            out,
            "<tr><th>{}</th><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            escape(s(l, "run")),
            count(l, "n_points"),
            estimate(l.get("n")),
            estimate(l.get("k_n_per_mm_pow_n")),
            opt_num(f(l, "model_k_n_per_mm2")),
            escape(s(l, "source")),
        );
    }
    out.push_str("</tbody></table></details>");
}

fn provenance(out: &mut String, doc: &Value) {
    let p = &doc["provenance"];
    let mut surfaces = Vec::new();
    for m in p["surfaces"].as_array().map_or(&[][..], |a| a.as_slice()) {
        surfaces.push(format!(
            "{} (E = {} Pa, h = {} mm, φ = {})",
            escape(s(m, "name")),
            opt_num(f(m, "modulus_pa")),
            opt_num(f(m, "pillar_height_m").map(|h| h * 1e3)),
            opt_num(f(m, "solid_fraction")),
        ));
    }
    let _ = write!(
        out,
        "<p>{} in the fits, {} skipped, {} with the geometric contact radius. \
         Contact radius: {}; bootstrap: {} resamples, seed {}. Surfaces: {}.</p>",
        doc.get("n_used")
            .and_then(Value::as_u64)
            .map_or(NONE.into(), |n| crate::util::text::plural(
                n as usize, "drop"
            )),
        count(doc, "n_skipped"),
        count(doc, "n_geometric_contact_radius"),
        escape(s(p, "contact_radius")),
        count(p, "bootstrap_resamples"),
        count(p, "seed"),
        if surfaces.is_empty() {
            NONE.into()
        } else {
            surfaces.join("; ")
        },
    );
}

fn notes(out: &mut String, doc: &Value) {
    let skipped = doc["skipped"].as_array().map_or(&[][..], |a| a.as_slice());
    if !skipped.is_empty() {
        out.push_str("<h3>Rows left out of the fits</h3><ul class=\"skipped\">");
        for k in skipped {
            let _ = write!(
                out,
                "<li><b>{}</b> (drops.csv line {}): {}</li>",
                escape(s(k, "run")),
                count(k, "row"),
                escape(s(k, "reason"))
            );
        }
        out.push_str("</ul>");
    }
    // The few-drops note is shown at the top, not among the warnings.
    let few = doc.get("few_drops").and_then(Value::as_str);
    let warnings: Vec<&Value> = doc["warnings"]
        .as_array()
        .map_or(&[][..], |a| a.as_slice())
        .iter()
        .filter(|w| few.is_none() || w.as_str() != few)
        .collect();
    if !warnings.is_empty() {
        out.push_str("<h3>Warnings of the collapse</h3><ul class=\"warnings\">");
        for w in warnings {
            let w = w.as_str().unwrap_or("");
            let class = if w.starts_with("GEOMETRIC") || w.starts_with("EXTRAPOLATED") {
                " class=\"alarm\""
            } else {
                ""
            };
            let _ = write!(out, "<li{class}>{}</li>", escape(w));
        }
        out.push_str("</ul>");
    }
}

/// The fits section's body from the parsed `fits.json`.
pub fn fits_section(doc: &Value) -> String {
    let mut out = String::new();
    // What the data support first, the extrapolations last.
    provenance(&mut out, doc);
    match doc.get("few_drops").and_then(Value::as_str) {
        // Too few drops for any exponent or series: that said once, in
        // place of their empty tables.
        Some(few) => {
            // `commands` as code.
            let text: String = escape(few)
                .split('`')
                .enumerate()
                .map(|(i, part)| {
                    if i % 2 == 1 {
                        format!("<code>{part}</code>")
                    } else {
                        part.to_string()
                    }
                })
                .collect();
            let _ = write!(out, "<p class=\"few-drops\">{text}</p>");
            asymptotes(&mut out, doc);
        }
        None => {
            exponents(&mut out, doc);
            asymptotes(&mut out, doc);
            series(&mut out, doc);
        }
    }
    force_laws(&mut out, doc);
    notes(&mut out, doc);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_drop_is_counted_in_the_singular() {
        let one = serde_json::json!({
            "n_used": 1, "n_skipped": 0, "n_geometric_contact_radius": 0,
            "force_laws": [{"run": "R3mm_H6cm_01"}],
        });
        let html = fits_section(&one);
        assert!(html.contains("<p>1 drop in the fits,"), "{html}");
        assert!(html.contains("per drop (1 drop)</h3>"), "{html}");
        assert!(!html.contains("1 drops"), "{html}");
        let two = serde_json::json!({"n_used": 2, "force_laws": [{}, {}]});
        let html = fits_section(&two);
        assert!(html.contains("<p>2 drops in the fits,") && html.contains("(2 drops)</h3>"));
    }
}
