//! The surface line found in the images against the truth of rendered
//! drops: per run, the line's row at the impact column minus the true one
//! (px), for the line the pipeline uses and for each of its two edge
//! models alone (the flank fit and the area row), with the line's error
//! and the models' disagreement.
//!
//!     cargo run --release --example surface_truth -- RUN_DIR [RUN_DIR ...]
//!
//! Each RUN_DIR holds a drop's frames and its `truth.json`: one written by
//! `dropscope render` (`surface_row_px` at column 0, `surface_slope`,
//! `impact_column_px`) or by another renderer (`surface_line` with
//! `row_at_impact_col_px`, `impact_col_px`). Prints one line per run, then
//! the median and 95th percentile of |error| over them.

use dropscope::config::{PipelineConfig, EMBEDDED_DEFAULT};
use dropscope::detect::surface::{column_edges, fit_line};
use dropscope::source::{open, OpenOptions};
use dropscope::track::{background_and_surface, TrackSettings};
use std::path::{Path, PathBuf};

fn truth_row(truth: &serde_json::Value) -> Option<(f64, f64)> {
    if let Some(line) = truth.get("surface_line") {
        let col = truth["impact_col_px"].as_f64()?;
        return Some((line["row_at_impact_col_px"].as_f64()?, col));
    }
    let col = truth["impact_column_px"].as_f64()?;
    let row = truth["surface_row_px"].as_f64()? + truth["surface_slope"].as_f64()? * col;
    Some((row, col))
}

fn pct(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p).round() as usize]
}

fn main() -> anyhow::Result<()> {
    let dirs: Vec<PathBuf> = std::env::args().skip(1).map(PathBuf::from).collect();
    anyhow::ensure!(
        !dirs.is_empty(),
        "usage: surface_truth RUN_DIR [RUN_DIR ...]"
    );
    let cfg = PipelineConfig::from_toml_str(
        EMBEDDED_DEFAULT,
        Path::new("pipeline.toml"),
        Path::new("."),
    )?;
    let st = TrackSettings::from_config(&cfg.detect);
    let options = OpenOptions {
        fps_fallback: Some(10_000.0),
        ..OpenOptions::default()
    };
    let (mut used, mut flank, mut area) = (Vec::new(), Vec::new(), Vec::new());
    println!("run  used(px)  ±err  flank  area  model_err");
    for dir in &dirs {
        let truth: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join("truth.json"))?)?;
        let (row_true, col) = truth_row(&truth)
            .ok_or_else(|| anyhow::anyhow!("{}: no surface truth", dir.display()))?;
        let mut source = open(dir, &options)?;
        let (bg, line, _) = background_and_surface(source.as_mut(), &st)?;
        let edges = column_edges(&bg, &st.surface);
        let flank_line = fit_line(
            &edges.iter().map(|e| (e.x_px, e.row_px)).collect::<Vec<_>>(),
            &st.surface,
        )?;
        let area_line = fit_line(
            &edges
                .iter()
                .map(|e| (e.x_px, e.row_area_px))
                .collect::<Vec<_>>(),
            &st.surface,
        )?;
        let (u, f, a) = (
            line.row_at(col) - row_true,
            flank_line.row_at(col) - row_true,
            area_line.row_at(col) - row_true,
        );
        println!(
            "{}  {u:+.3}  {:.3}  {f:+.3}  {a:+.3}  {:.3}",
            dir.file_name().unwrap_or_default().to_string_lossy(),
            line.sigma_row_at(col).hypot(line.model_err_px),
            line.model_err_px
        );
        used.push(u.abs());
        flank.push(f.abs());
        area.push(a.abs());
    }
    for (what, v) in [
        ("used", &mut used),
        ("flank", &mut flank),
        ("area", &mut area),
    ] {
        println!(
            "{what}: median |error| {:.3} px, p95 {:.3} px, max {:.3} px",
            pct(v, 0.5),
            pct(v, 0.95),
            pct(v, 1.0)
        );
    }
    Ok(())
}
