//! Detection on rendered drops, measured against their `truth.json`.
//!
//!     cargo run --release --example detect_rendered -- RUN_DIR [RUN_DIR ...]
//!
//! Each RUN_DIR is a folder written by `dropscope render` (frames
//! `<run>_NNNNNN.{png,tif}` and `truth.json`). Everything is found from the
//! images: the background (the sphere may be in view in every frame), the
//! surface line, the coarse circle in the first frame, then per frame the
//! sub-pixel circle from the previous frame's prediction; R_px is the median
//! radius of the frames whose whole circle is clear of the frame's border
//! and of the surface, and a second pass fits the centre with R_px held.
//! Prints per-run and pooled statistics of the centre-row error in free
//! flight and in contact, the radius and surface errors and the σ coverage.
//! (A stand-in for the tracker in `track.rs`: no FrameSource, no
//! ballistic prediction beyond constant velocity.)

use dropscope::detect::background::{Background, GainRegion};
use dropscope::detect::circle::Circle;
use dropscope::detect::coarse::{detect_coarse, CoarseParams, CoarseScratch};
use dropscope::detect::edges::{measure_circle, EdgeParams, EdgeScratch};
use dropscope::detect::surface::{fit_surface, SurfaceParams};
use dropscope::detect::{calibrate, Band};
use dropscope::figures::overlay;
use dropscope::render::truth::Truth;
use dropscope::source::Frame;
use std::path::{Path, PathBuf};

fn load_frame(path: &Path) -> anyhow::Result<Frame> {
    let img = image::open(path)?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let data: Vec<u16> = match img {
        image::DynamicImage::ImageLuma8(g) => g.into_raw().into_iter().map(u16::from).collect(),
        other => other.to_luma16().into_raw(),
    };
    Ok(Frame::from_shape_vec((h, w), data)?)
}

fn frame_path(dir: &Path, run: &str, n: i64) -> PathBuf {
    let stem = if n < 0 {
        format!("{run}_-{:06}", n.unsigned_abs())
    } else {
        format!("{run}_{n:06}")
    };
    let png = dir.join(format!("{stem}.png"));
    if png.exists() {
        png
    } else {
        dir.join(format!("{stem}.tif"))
    }
}

#[derive(Default)]
struct Pool {
    free_z: Vec<f64>,
    contact_z: Vec<f64>,
    contact_z_free_r: Vec<f64>,
    free_x: Vec<f64>,
    covered: usize,
    total: usize,
    /// Free-flight and contact frames with |e_z| ≤ 2σ_z, and |e_z|/σ_z.
    covered_free: usize,
    covered_contact: usize,
    ratio: Vec<f64>,
    radius: Vec<f64>,
    surface: Vec<f64>,
}

fn pct(v: &[f64], p: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut a: Vec<f64> = v.iter().map(|x| x.abs()).collect();
    a.sort_by(f64::total_cmp);
    a[((a.len() - 1) as f64 * p / 100.0).round() as usize]
}

fn line(name: &str, v: &[f64]) -> String {
    format!(
        "{name}: n {:>3}, median |e| {:.4} px, 95th {:.4} px, max {:.4} px, mean e {:+.4} px",
        v.len(),
        pct(v, 50.0),
        pct(v, 95.0),
        pct(v, 100.0),
        v.iter().sum::<f64>() / v.len().max(1) as f64
    )
}

fn run(dir: &Path, pool: &mut Pool) -> anyhow::Result<()> {
    let truth: Truth = serde_json::from_slice(&std::fs::read(dir.join("truth.json"))?)?;
    let frames: Vec<Frame> = truth
        .frames
        .iter()
        .map(|f| load_frame(&frame_path(dir, &truth.run, f.frame)))
        .collect::<Result<_, _>>()?;
    let views: Vec<_> = frames.iter().map(|f| f.view()).collect();
    let coarse = CoarseParams::default();
    // DETECT_BG_FRAMES=N: the background from the first N frames (they must
    // be free of the sphere); otherwise from all frames, sphere in view.
    let bg = match std::env::var("DETECT_BG_FRAMES")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
    {
        Some(n) => Background::from_frames(&views[..n.min(views.len())], GainRegion::default())?,
        None => Background::from_frames_with_sphere(&views, GainRegion::default(), &coarse, 6.0)?,
    };
    let surface = fit_surface(&bg, &SurfaceParams::default())?;
    let xi = truth.impact_column_px;
    let s_err = surface.row_at(xi) - (truth.surface_row_px + truth.surface_slope * xi);
    println!(
        "{}: R {} mm = {:.3} px, {} frames; surface at the impact column {:+.4} px (σ {:.4}), slope {:+.5} (truth {:+.5})",
        truth.run,
        truth.sphere_radius_mm,
        truth.radius_px,
        frames.len(),
        s_err,
        surface.sigma_row_at(xi),
        surface.slope,
        truth.surface_slope
    );
    pool.surface.push(s_err);

    let mut params = EdgeParams::default();
    if let Some(m) = std::env::var("DETECT_MARGIN_PX")
        .ok()
        .and_then(|v| v.parse().ok())
    {
        params.surface_margin_px = m;
    }
    let mut es = EdgeScratch::default();
    let mut cs = CoarseScratch::default();
    // Pass 1: radius free, prediction = previous centre + previous velocity.
    let mut fits = Vec::with_capacity(frames.len());
    let mut prev: Option<Circle> = None;
    let mut prev2: Option<Circle> = None;
    for (k, f) in frames.iter().enumerate() {
        let band = Band::frame(f)?;
        let predicted = match (prev, prev2) {
            (Some(a), Some(b)) => Some(Circle {
                x_px: 2.0 * a.x_px - b.x_px,
                z_px: 2.0 * a.z_px - b.z_px,
                r_px: a.r_px,
            }),
            (Some(a), None) => Some(a),
            _ => {
                let g = bg.gain(&band)?.gain;
                detect_coarse(&band, &bg, g, Some(&surface), &coarse, &mut cs)?.map(|c| c.circle)
            }
        };
        let fit = predicted.and_then(|p| {
            measure_circle(&band, &bg, &p, Some(&surface), None, &params, &mut es).ok()
        });
        if fit.is_none() {
            println!("  frame {k}: no fit");
        }
        if std::env::var_os("DETECT_VERBOSE").is_some() {
            if let Some(f) = &fit {
                let t = &truth.frames[k];
                println!(
                    "  frame {k:>3} ({:>4}): z {:8.3} ez {:+.4} ex {:+.4} er {:+.4} σz {:.4} pts {}/{} it {} contact {}",
                    t.frame,
                    f.z_px,
                    f.z_px - t.z_px,
                    f.x_px - t.x_px,
                    f.r_px - truth.radius_px,
                    f.cov.sigma_z_px(),
                    f.inliers,
                    f.n_used,
                    f.iterations,
                    t.in_contact
                );
            }
        }
        prev2 = prev;
        prev = fit.map(|f| f.circle());
        fits.push(fit);
    }
    // Calibration: frames whose whole circle (plus the window) is clear.
    let free: Vec<_> = fits.iter().flatten().copied().collect();
    let (h, w) = frames[0].dim();
    let cal = calibrate::calibrate_radius(&free, w, h, Some(&surface), &params, 3);
    let r_px = cal.map_or(truth.radius_px, |c| c.r_px);
    match cal {
        Some(c) => {
            let s = calibrate::scale(truth.sphere_radius_mm, &c, None);
            println!(
                "  R_px {:.4} ± {:.4} from {} full-circle frames: error {:+.4} px; scale {:.6} mm/px (truth {})",
                c.r_px,
                c.sigma_px,
                c.frames,
                c.r_px - truth.radius_px,
                s.mm_per_px,
                truth.mm_per_px
            );
            pool.radius.push(c.r_px - truth.radius_px);
        }
        None => println!("  too few full-circle frames: R_px from truth"),
    }
    // Pass 2: radius held.
    let mut free_z = Vec::new();
    let mut contact_z = Vec::new();
    for ((f, fit1), t) in frames.iter().zip(&fits).zip(&truth.frames) {
        let Some(fit1) = fit1 else { continue };
        let band = Band::frame(f)?;
        let Ok(fit) = measure_circle(
            &band,
            &bg,
            &fit1.circle(),
            Some(&surface),
            Some(r_px),
            &params,
            &mut es,
        ) else {
            continue;
        };
        let ez = fit.z_px - t.z_px;
        let ex = fit.x_px - t.x_px;
        // DETECT_OVERLAY=DIR: a 4× overlay of the deepest frame.
        if let Some(out) = std::env::var_os("DETECT_OVERLAY") {
            if t.delta_mm > 0.0 && t.delta_mm >= truth.delta_max_mm * 0.999 {
                let c = fit.circle();
                let view = overlay::OverlayView::around(&band, &c, 12.0, 4);
                let img = overlay::overlay(
                    &band,
                    truth.bit_depth,
                    &view,
                    &es.points,
                    Some(&c),
                    Some(&surface),
                );
                let path =
                    Path::new(&out).join(format!("{}_frame{}_overlay.png", truth.run, t.frame));
                dropscope::util::io::write_atomic(&path, &overlay::encode_png(&img)?)?;
                println!("  overlay: {}", path.display());
            }
        }
        pool.total += 1;
        let inside = ez.abs() <= 2.0 * fit.cov.sigma_z_px();
        pool.ratio.push(ez / fit.cov.sigma_z_px());
        if inside {
            pool.covered += 1;
            if t.in_contact {
                pool.covered_contact += 1;
            } else {
                pool.covered_free += 1;
            }
        }
        if t.in_contact {
            contact_z.push(ez);
            pool.contact_z_free_r.push(fit1.z_px - t.z_px);
        } else {
            free_z.push(ez);
            pool.free_x.push(ex);
        }
    }
    println!("  {}", line("free flight z (R held)", &free_z));
    println!("  {}", line("in contact z (R held) ", &contact_z));
    pool.free_z.extend(free_z);
    pool.contact_z.extend(contact_z);
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let dirs: Vec<PathBuf> = std::env::args().skip(1).map(PathBuf::from).collect();
    if dirs.is_empty() {
        anyhow::bail!("usage: detect_rendered RUN_DIR [RUN_DIR ...]");
    }
    let mut pool = Pool::default();
    for d in &dirs {
        if let Err(e) = run(d, &mut pool) {
            println!("{}: failed: {e:#}", d.display());
        }
    }
    println!("pooled over {} runs:", dirs.len());
    println!("  {}", line("free flight z (R held)", &pool.free_z));
    println!("  {}", line("free flight x (R held)", &pool.free_x));
    println!("  {}", line("in contact z (R held) ", &pool.contact_z));
    println!(
        "  {}",
        line("in contact z (R free) ", &pool.contact_z_free_r)
    );
    println!("  {}", line("R_px", &pool.radius));
    println!("  {}", line("surface row at impact column", &pool.surface));
    println!(
        "  |e_z| ≤ 2σ_z in {:.1} % of {} frames ({:.1} % in free flight, {:.1} % in contact); rms of e_z/σ_z {:.2}",
        100.0 * pool.covered as f64 / pool.total.max(1) as f64,
        pool.total,
        100.0 * pool.covered_free as f64 / pool.free_z.len().max(1) as f64,
        100.0 * pool.covered_contact as f64 / pool.contact_z.len().max(1) as f64,
        (pool.ratio.iter().map(|r| r * r).sum::<f64>() / pool.ratio.len().max(1) as f64).sqrt()
    );
    Ok(())
}
