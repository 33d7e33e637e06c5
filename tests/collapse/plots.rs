//! The collapse's figures: valid SVG and PNG showing every point, guide
//! slopes straight and clear of the legend, the legend clear of the error
//! bars, byte-identical reruns, and figures without data saying so.

use super::*;
use std::path::PathBuf;

fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push(p.strip_prefix(dir).unwrap().to_path_buf());
            }
        }
    }
    out.sort();
    out
}

/// A dataset for the plot tests: R = 3 mm (blue circles) and 7 mm (red
/// squares) on distinct power laws, small errors, with one track.
fn plot_dataset(dir: &Path) -> PathBuf {
    let mut spec = SyntheticSpec::paper(12, 4);
    spec.rel_noise = [0.001, 0.003, 0.003, 0.003];
    let mut recs = power_law_dataset(&spec, &[(3.0, 1.0 / 6.0, -2.0 / 3.0)]);
    spec.per_radius = 9;
    recs.extend(power_law_dataset(&spec, &[(7.0, 1.0 / 3.0, -1.0 / 3.0)]));
    let first = &mut recs[0];
    let (rows, t_in, t_out) = contact_track(
        3.0,
        7800.0,
        first.v_impact_m_s.unwrap(),
        &spec.surface,
        10_000.0,
        0.05,
    );
    first.t_contact_s = Some(t_in);
    first.t_rebound_s = Some(t_out);
    std::fs::create_dir_all(dir.join("tracks")).unwrap();
    let mut w =
        csv::Writer::from_path(dir.join("tracks").join(format!("{}.csv", first.run))).unwrap();
    for r in rows {
        w.serialize(r).unwrap();
    }
    w.flush().unwrap();
    let drops = dir.join("drops.csv");
    dataset::write_csv(&drops, &recs).unwrap();
    drops
}

#[test]
fn plots_are_valid_svg_and_png_showing_every_point() {
    let dir = tempfile::tempdir().unwrap();
    let drops = plot_dataset(dir.path());
    let out = dir.path().join("out");
    let s = collapse_job::run(&args(&drops, &out, true), &config(), "pipeline.toml").unwrap();
    // DROPSCOPE_KEEP=DIR keeps the figures for a look by eye.
    if let Ok(keep) = std::env::var("DROPSCOPE_KEEP") {
        for p in files(dir.path()) {
            let to = Path::new(&keep).join(&p);
            std::fs::create_dir_all(to.parent().unwrap()).unwrap();
            std::fs::copy(dir.path().join(&p), to).unwrap();
        }
    }
    assert_eq!(s.n_used, 21);
    let plots = ["pi_vs_eta", "tau_vs_v", "psi_vs_xi", "omega_vs_xi"];
    for name in plots {
        // SVG: well-formed XML; each point is one marker of its radius's
        // colour, plus one in the legend, plus one in the residual panel
        // under the fit (every radius has its power law, Ψ and Ω their
        // series): 12 + 1 + 12 blue circles, 9 + 1 + 9 red squares.
        let text = std::fs::read_to_string(out.join(format!("plots/{name}.svg"))).unwrap();
        let doc = roxmltree::Document::parse(&text).unwrap_or_else(|e| panic!("{name}.svg: {e}"));
        let count = |tag: &str, fill: &str| {
            doc.descendants()
                .filter(|n| n.has_tag_name(tag) && n.attribute("fill") == Some(fill))
                .count()
        };
        assert_eq!(count("circle", "#0000E6"), 25, "{name}: blue circles");
        assert_eq!(count("polygon", "#DC0000"), 19, "{name}: red squares");
        assert!(text.contains("fit"), "{name}: the residual panel's axis");
        assert!(
            text.contains("R = 3 mm") && text.contains("R = 7 mm"),
            "{name}: legend"
        );

        // PNG: decodes, right size, not blank.
        let img = image::open(out.join(format!("plots/{name}.png")))
            .unwrap_or_else(|e| panic!("{name}.png: {e}"))
            .to_rgb8();
        assert_eq!(img.dimensions(), (1100, 1040));
        let mut colours = std::collections::BTreeSet::new();
        for p in img.pixels() {
            colours.insert(p.0);
        }
        assert!(
            colours.len() > 20,
            "{name}.png looks blank ({} colours)",
            colours.len()
        );
        // In the log–log figures the points are spread out, and the blue and
        // red marker pixels form 13 and 10 separate blobs (fitted lines are
        // drawn in lighter shades, so only markers and their error bars
        // count). In Ψ(Ξ) and Ω(Ξ) this data set's R = 7 mm points overlap.
        if !name.ends_with("_xi") {
            // The fit's panel ends above row 740 (in the residual panel
            // under it, points of both radii overlap).
            count_blobs(&img, name, 0..740, [13, 10]);
        }
    }
    // The per-drop figure exists for the one drop with a track, and its
    // force law recovers the model it was integrated with (F = πEφR/h δ²).
    let run = "R3_00";
    for ext in ["svg", "png"] {
        assert!(out.join(format!("plots/drops/{run}.{ext}")).is_file());
    }
    let fits: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("fits.json")).unwrap()).unwrap();
    let law = &fits["force_laws"][0];
    assert_eq!(law["run"], run);
    assert!((f(&law["n"]["value"]) - 2.0).abs() < 1e-9);
    let k = f(&law["k_n_per_mm_pow_n"]["value"]);
    assert!((k / f(&law["model_k_n_per_mm2"]) - 1.0).abs() < 1e-9);
    assert_eq!(fits["force_laws"].as_array().unwrap().len(), 1);
}

/// The guide fan of an SVG log–log figure: each guide's dashes (black,
/// 2 px), its label's box (x0, y0, x1, y1) and the legend's frame.
struct Fan {
    guides: Vec<Vec<Vec<(f64, f64)>>>,
    labels: Vec<[f64; 4]>,
    legend: [f64; 4],
}

fn fan(svg: &str) -> Fan {
    let doc = roxmltree::Document::parse(svg).unwrap();
    let num = |n: roxmltree::Node, a: &str| n.attribute(a).unwrap().parse::<f64>().unwrap();
    let dashes: Vec<Vec<(f64, f64)>> = doc
        .descendants()
        .filter(|n| {
            n.has_tag_name("polyline")
                && n.attribute("stroke") == Some("#000000")
                && n.attribute("stroke-width") == Some("2")
        })
        .map(|n| {
            n.attribute("points")
                .unwrap()
                .split_whitespace()
                .map(|p| {
                    let (x, y) = p.split_once(',').unwrap();
                    (x.parse().unwrap(), y.parse().unwrap())
                })
                .collect()
        })
        .collect();
    // Both guides run right from one start: a dash belongs to the guide in
    // its direction from there (the two differ by degrees; the dashes split
    // at the widest gap between directions). Within 40 px of the start the
    // direction is not sure: those dashes form a third group, checked for
    // kinks and the legend only.
    let start = *dashes
        .iter()
        .flatten()
        .min_by(|p, q| p.0.total_cmp(&q.0))
        .unwrap();
    let angle = |d: &Vec<(f64, f64)>| {
        let p = d[d.len() - 1];
        (p.1 - start.1).atan2(p.0 - start.0)
    };
    let (mut far, near): (Vec<_>, Vec<_>) = dashes.into_iter().partition(|d| {
        let p = d[d.len() - 1];
        (p.0 - start.0).hypot(p.1 - start.1) >= 40.0
    });
    far.sort_by(|a, b| angle(a).total_cmp(&angle(b)));
    let gap = (1..far.len())
        .max_by(|&i, &j| {
            (angle(&far[i]) - angle(&far[i - 1])).total_cmp(&(angle(&far[j]) - angle(&far[j - 1])))
        })
        .unwrap();
    let second = far.split_off(gap);
    let guides = vec![far, second, near];
    let labels = doc
        .descendants()
        .filter(|n| n.has_tag_name("text"))
        .filter(|n| {
            let t = n.text().unwrap_or_default().trim();
            ["1/3", "2/3", "1/6"].iter().any(|g| t.ends_with(g)) && t.chars().count() <= 4
        })
        .map(|n| {
            let (x, y, size) = (num(n, "x"), num(n, "y"), num(n, "font-size"));
            let chars = n.text().unwrap().trim().chars().count() as f64;
            [x, y, x + 0.55 * size * chars, y + size]
        })
        .collect();
    let frame = doc
        .descendants()
        .find(|n| n.has_tag_name("rect") && n.attribute("stroke") == Some("#787878"))
        .unwrap();
    let (x, y) = (num(frame, "x"), num(frame, "y"));
    Fan {
        guides,
        labels,
        legend: [x, y, x + num(frame, "width"), y + num(frame, "height")],
    }
}

/// The guide slopes must not look bent (drawn through 21 points rounded
/// to pixels, each dash kinks where it crosses one: up to 1.0 px off a
/// straight line), nor the legend, in a band above the data when no corner
/// is free, cover the guides' start. On a campaign-like dataset (five
/// radii whose points fill both lower corners): every guide is a straight
/// dashed line (each dash two points, all within 0.71 px of one line), and
/// no dash nor label is under the legend.
#[test]
fn guide_slopes_are_straight_and_clear_of_the_legend() {
    let spec = SyntheticSpec::paper(6, 3);
    let laws: Vec<(f64, f64, f64)> = spec
        .radii_mm
        .iter()
        .map(|&r| (r, 1.0 / 3.0, -1.0 / 3.0))
        .collect();
    let mut recs = power_law_dataset(&spec, &laws);
    for r in &mut recs {
        let k = r.sphere_radius_mm / 3.0;
        r.tau_c_ms = r.tau_c_ms.map(|t| t * k);
        r.tau_c_ms_err = r.tau_c_ms_err.map(|e| e * k);
    }
    let dir = tempfile::tempdir().unwrap();
    let drops = dir.path().join("drops.csv");
    dataset::write_csv(&drops, &recs).unwrap();
    let out = dir.path().join("out");
    collapse_job::run(&args(&drops, &out, true), &config(), "pipeline.toml").unwrap();
    for name in ["tau_vs_v", "pi_vs_eta"] {
        let svg = std::fs::read_to_string(out.join(format!("plots/{name}.svg"))).unwrap();
        let Fan {
            guides,
            labels,
            legend,
        } = fan(&svg);
        assert_eq!(labels.len(), 2, "{name}: guide labels");
        let inside =
            |(x, y): (f64, f64)| x > legend[0] && x < legend[2] && y > legend[1] && y < legend[3];
        for (i, g) in guides.iter().enumerate() {
            for dash in g {
                assert_eq!(dash.len(), 2, "{name}: a kinked dash {dash:?}");
                for &p in dash {
                    assert!(
                        !inside(p),
                        "{name}: guide at {p:?} under the legend {legend:?}"
                    );
                }
            }
            if i == 2 {
                continue;
            }
            // Distance from the line fitted through all its dash ends (total
            // least squares): pixel rounding alone keeps it under √2/2.
            let pts: Vec<(f64, f64)> = g.iter().flatten().copied().collect();
            let n = pts.len() as f64;
            let (mx, my) = (
                pts.iter().map(|p| p.0).sum::<f64>() / n,
                pts.iter().map(|p| p.1).sum::<f64>() / n,
            );
            let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
            for p in &pts {
                sxx += (p.0 - mx).powi(2);
                syy += (p.1 - my).powi(2);
                sxy += (p.0 - mx) * (p.1 - my);
            }
            let th = 0.5 * (2.0 * sxy).atan2(sxx - syy);
            let reach = pts.iter().map(|p| (p.0 - mx).hypot(p.1 - my));
            assert!(reach.fold(0.0, f64::max) > 50.0, "{name}: a short guide");
            for &p in &pts {
                let off = (-(p.0 - mx) * th.sin() + (p.1 - my) * th.cos()).abs();
                assert!(off <= 0.71, "{name}: {p:?} is {off:.2} px off the guide");
            }
        }
        for l in labels {
            for corner in [(l[0], l[1]), (l[2], l[1]), (l[0], l[3]), (l[2], l[3])] {
                assert!(
                    !inside(corner),
                    "{name}: label {l:?} under the legend {legend:?}"
                );
            }
        }
    }
}

/// The legend keeps clear of the error bars, not only of the markers: on
/// the fixtures' three drops the Ω(Ξ) legend could lie over the 3 mm
/// drop's one-sigma bar (the report's first screen).
#[test]
fn the_legend_keeps_clear_of_the_error_bars() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let o = dropscope()
        .args(["process", "--no-animation", "--manifest"])
        .arg(root.join("fixtures/runs.csv"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let drops = out.join("drops.csv");
    collapse_job::run(&args(&drops, &out, true), &config(), "pipeline.toml").unwrap();
    for name in ["psi_vs_xi", "omega_vs_xi", "pi_vs_eta", "tau_vs_v"] {
        let svg = std::fs::read_to_string(out.join(format!("plots/{name}.svg"))).unwrap();
        let doc = roxmltree::Document::parse(&svg).unwrap();
        let num = |n: roxmltree::Node, a: &str| n.attribute(a).unwrap().parse::<f64>().unwrap();
        let frame = doc
            .descendants()
            .find(|n| n.has_tag_name("rect") && n.attribute("stroke") == Some("#787878"))
            .unwrap();
        let (x0, y0) = (num(frame, "x"), num(frame, "y"));
        let (x1, y1) = (x0 + num(frame, "width"), y0 + num(frame, "height"));
        let mut bars = 0;
        // The 3 mm (blue) and 7 mm (red) drops' bars: two-point lines.
        for n in doc.descendants().filter(|n| {
            n.has_tag_name("polyline")
                && n.attribute("stroke-width") == Some("1")
                && matches!(n.attribute("stroke"), Some("#0000E6" | "#DC0000"))
        }) {
            let p: Vec<(f64, f64)> = n
                .attribute("points")
                .unwrap()
                .split_whitespace()
                .map(|p| {
                    let (x, y) = p.split_once(',').unwrap();
                    (x.parse().unwrap(), y.parse().unwrap())
                })
                .collect();
            let (lx, hx) = (p[0].0.min(p[1].0), p[0].0.max(p[1].0));
            let (ly, hy) = (p[0].1.min(p[1].1), p[0].1.max(p[1].1));
            assert!(
                hx < x0 || lx > x1 || hy < y0 || ly > y1,
                "{name}: the bar {p:?} runs under the legend ({x0}, {y0})-({x1}, {y1})"
            );
            bars += 1;
        }
        assert!(bars >= 4, "{name}: {bars} bars");
    }
}

#[test]
fn two_runs_write_identical_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let drops = plot_dataset(dir.path());
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    collapse_job::run(&args(&drops, &a, true), &config(), "pipeline.toml").unwrap();
    collapse_job::run(&args(&drops, &b, true), &config(), "pipeline.toml").unwrap();
    let (fa, fb) = (files(&a), files(&b));
    assert_eq!(fa, fb);
    assert!(fa.len() >= 12, "{fa:?}");
    for p in fa {
        assert!(
            std::fs::read(a.join(&p)).unwrap() == std::fs::read(b.join(&p)).unwrap(),
            "{} differs",
            p.display()
        );
    }
}

/// Blobs of blue and red marker pixels in the rows `rows` of `img`.
fn count_blobs(img: &image::RgbImage, name: &str, rows: std::ops::Range<u32>, want: [u32; 2]) {
    for (rgb, want) in [([0u8, 0, 230], want[0]), ([220, 0, 0], want[1])] {
        let mask = image::GrayImage::from_fn(img.width(), img.height(), |x, y| {
            let on = rows.contains(&y) && img.get_pixel(x, y).0 == rgb;
            image::Luma([if on { 255 } else { 0 }])
        });
        let labels = imageproc::region_labelling::connected_components(
            &mask,
            imageproc::region_labelling::Connectivity::Eight,
            image::Luma([0u8]),
        );
        let blobs = labels.pixels().map(|p| p.0[0]).max().unwrap_or(0);
        assert_eq!(blobs, want, "{name}.png: blobs of {rgb:?}");
    }
}

/// With no drop to show, a figure says so instead of
/// drawing axes over nothing.
#[test]
fn figures_without_data_say_so() {
    let fits = dropscope::collapse::fit::fit_all(
        &[],
        dropscope::collapse::fit::FitSettings {
            resamples: 10,
            seed: 1,
        },
    );
    let figures = dropscope::figures::collapse_figures(&[], &fits).unwrap();
    let svgs: Vec<String> = figures
        .iter()
        .filter(|(name, _)| name.ends_with(".svg"))
        .map(|(_, b)| String::from_utf8(b.clone()).unwrap())
        .collect();
    assert_eq!(svgs.len(), 4);
    for svg in svgs {
        assert!(svg.contains("No measured drop to show"), "{svg}");
        assert!(!svg.contains("<line"), "axes drawn over nothing: {svg}");
    }
}
