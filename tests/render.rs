//! `dropscope render`: the physics against the paper's closed forms, the
//! raster against exact coverage, the PCC side file against the real ones,
//! and byte-for-byte determinism.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use clap::Parser;
use dropscope::cli::render::RenderArgs;
use dropscope::config::Surface;
use dropscope::render::physics::{
    damping_for_restitution, ContactLaw, DropParams, Trajectory, BETA_THIRD_HALF,
    STANDARD_GRAVITY_M_S2,
};
use dropscope::render::raster::{Look, Raster, Scene};
use dropscope::render::truth::Truth;
use dropscope::render::{render, rng_for, Preset, RenderOptions};

#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    args: RenderArgs,
}

pub(crate) fn args(list: &[&str]) -> RenderOptions {
    let mut v = vec!["render"];
    v.extend_from_slice(list);
    Cli::try_parse_from(v)
        .expect("valid render arguments")
        .args
        .options()
}

fn params(radius_mm: f64, v_m_s: f64, g: f64) -> DropParams {
    DropParams {
        sphere_radius_m: radius_mm * 1e-3,
        sphere_density_kg_m3: 7800.0,
        surface: Surface::paper_pdms(),
        gravity_m_s2: g,
        impact_speed_m_s: v_m_s,
        damping_n_s_m: 0.0,
        law: ContactLaw::MODEL,
    }
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

// ------------------------------------------------------------------ physics

/// Without gravity and damping the integrator must reproduce Eq. (4) for
/// δmax and Eq. (5) for τc (Maruoka 2019) to 1e-6 relative: RK4 at τc/2000
/// has a global error near (π/2000)⁴ ≈ 6e-12 and the events are located on
/// the continuous RK4 solution, so 1e-6 leaves a wide margin while still
/// catching any event rounded to a grid step (an error of ~5e-4).
#[test]
fn without_gravity_and_damping_delta_max_and_tau_c_follow_eq4_and_eq5() {
    for (r_mm, v) in [(3.0, 3.13), (4.5, 1.53), (7.0, 0.54), (5.0, 0.77)] {
        let p = params(r_mm, v, 0.0);
        let step = p.default_step_s(1e-6);
        let tr = Trajectory::simulate(&p, 0.0, 1.0, step).unwrap();
        assert_eq!(tr.bounces().len(), 1);
        let b = tr.bounces()[0];
        assert!(
            rel(b.delta_max_m, p.delta_max_eq4_m()) < 1e-6,
            "R {r_mm}: δmax {} vs Eq. 4 {}",
            b.delta_max_m,
            p.delta_max_eq4_m()
        );
        let tau_theory = 2.0 / 3.0 * BETA_THIRD_HALF * b.delta_max_m / v;
        assert!(
            rel(b.tau_c_s(), tau_theory) < 1e-6,
            "R {r_mm}: τc {} vs {}",
            b.tau_c_s(),
            tau_theory
        );
        // symmetric contact: maximum at half time, rebound at the impact speed
        assert!(rel(b.t_max_s, 0.5 * b.tau_c_s()) < 1e-6);
        assert!(rel(b.v_rebound_m_s, v) < 1e-9);
    }
}

/// With gravity and no damping the mechanical energy
/// ½ m ḋ² − m g d + K d³/3 is conserved; sampled on and between grid steps
/// across contact and flight, it must stay within 1e-9 of its value at
/// impact (RK4's energy drift at this step is ~1e-12).
#[test]
fn energy_is_conserved_to_1e_9_without_damping() {
    for (r_mm, h_cm) in [(3.0, 50.0), (7.0, 1.5), (4.5, 12.0)] {
        let v = (2.0 * STANDARD_GRAVITY_M_S2 * h_cm * 1e-2).sqrt();
        let p = params(r_mm, v, STANDARD_GRAVITY_M_S2);
        let step = p.default_step_s(1e-6);
        let tr = Trajectory::simulate(&p, 1e-4, 0.02, step).unwrap();
        let b = tr.bounces()[0];
        let e0 = p.energy_j(0.0, v);
        let mut worst: f64 = 0.0;
        let n = 5000;
        for k in 0..=n {
            // from 1 ms before contact to 1 ms after rebound, off-grid times
            let t = b.t_contact_s - 1e-3 + (b.tau_c_s() + 2e-3) * (k as f64 + 0.37) / n as f64;
            let (d, w) = tr.state(t);
            worst = worst.max(rel(p.energy_j(d, w), e0));
        }
        assert!(
            worst < 1e-9,
            "R {r_mm} H {h_cm}: relative energy error {worst:e}"
        );
        assert!(rel(b.restitution(), 1.0) < 1e-9);
    }
}

/// The damping solved for a requested restitution gives it to 1e-6.
#[test]
fn damping_gives_the_requested_restitution() {
    for (r_mm, h_cm, e) in [
        (3.0, 50.0, 0.9),
        (4.5, 6.0, 0.7),
        (7.0, 1.5, 0.5),
        (5.0, 25.0, 0.95),
    ] {
        let v = (2.0 * STANDARD_GRAVITY_M_S2 * h_cm * 1e-2).sqrt();
        let mut p = params(r_mm, v, STANDARD_GRAVITY_M_S2);
        let step = p.default_step_s(1e-6);
        p.damping_n_s_m = damping_for_restitution(&p, e, step).unwrap();
        assert!(p.damping_n_s_m > 0.0);
        let tr = Trajectory::simulate(&p, 0.0, 0.0, step).unwrap();
        let b = tr.bounces()[0];
        assert!(
            (b.restitution() - e).abs() < 1e-6,
            "asked {e}, got {}",
            b.restitution()
        );
        // damping lowers δmax below the elastic value
        assert!(b.delta_max_m < params(r_mm, v, STANDARD_GRAVITY_M_S2).delta_max_eq4_m() * 1.01);
    }
}

/// A rebound lands again after 2 v_out / g at the speed it left with; a
/// slow later contact that damping holds ends at the static equilibrium
/// K δ² = m g.
#[test]
fn later_contacts_follow_the_free_flight_parabola_or_settle() {
    let v = (2.0 * STANDARD_GRAVITY_M_S2 * 0.015).sqrt();
    let mut p = params(4.0, v, STANDARD_GRAVITY_M_S2);
    let step = p.default_step_s(1e-6);
    p.damping_n_s_m = damping_for_restitution(&p, 0.9, step).unwrap();
    let tr = Trajectory::simulate(&p, 0.0, 0.15, step).unwrap();
    assert!(tr.bounces().len() >= 2);
    let (b1, b2) = (tr.bounces()[0], tr.bounces()[1]);
    let flight = 2.0 * b1.v_rebound_m_s / STANDARD_GRAVITY_M_S2;
    assert!((b2.t_contact_s - b1.t_rebound_s - flight).abs() < 1e-15);
    assert!(rel(b2.v_impact_m_s, b1.v_rebound_m_s) < 1e-15);
    // at the top of that flight the sphere is v²/2g above the surface
    let (d, w) = tr.state(b1.t_rebound_s + 0.5 * flight);
    assert!(
        (d + b1.v_rebound_m_s.powi(2) / (2.0 * STANDARD_GRAVITY_M_S2)).abs() < 1e-15
            && w.abs() < 1e-12
    );

    p.damping_n_s_m = damping_for_restitution(&p, 0.3, step).unwrap();
    let tr = Trajectory::simulate(&p, 0.0, 0.1, step).unwrap();
    let t_rest = tr.resting_contact_s().expect("the second contact settles");
    assert_eq!(tr.bounces().len(), 1);
    let d_eq = (p.mass_kg() * STANDARD_GRAVITY_M_S2 / p.stiffness_n_m2()).sqrt();
    let (d, _) = tr.state(t_rest + 10.0);
    assert!(rel(d, d_eq) < 1e-6, "{d} vs {d_eq}");
}

// ------------------------------------------------------------------ raster

pub(crate) fn clean_scene(w: usize, h: usize, r: f64, row: f64, slope: f64) -> Scene {
    Scene {
        width_px: w,
        height_px: h,
        radius_px: r,
        surface_row_px: row,
        surface_slope: slope,
        pillar_height_px: 40.0,
        pillar_width_px: 25.0,
        channel_width_px: 15.0,
        pillar_phase_px: 3.3,
    }
}

fn raster(scene: Scene, look: Look) -> Raster {
    Raster::new(scene, look, &mut rng_for(1, "", "dust", 0)).unwrap()
}

/// ∫_{x0}^{x1} 2√(r² − (x − cx)²) dx, the exact column integral of a disk
/// (closed form with the well-conditioned atan2 antiderivative).
fn chord_integral(x0: f64, x1: f64, cx: f64, r: f64) -> f64 {
    let prim = |x: f64| {
        let t = (x - cx).clamp(-r, r);
        let h = ((r - t) * (r + t)).max(0.0).sqrt();
        t * h + r * r * t.atan2(h)
    };
    prim(x1) - prim(x0)
}

/// Clean look, sphere in free flight: the darkness of every pixel divided by
/// the local contrast is the coverage. Its total must be π r², and every
/// column's (row's) sum the exact chord integral, which pins the edge
/// positions. Tolerances come from f32 storage of the image: ≤ 2⁻²⁴
/// relative per pixel, so ≤ 1e-5 px per column of ≤ 120 pixels and
/// ≤ 2e-3 px² over the ~20 000 pixels of the disk.
#[test]
fn clean_silhouette_area_and_edges_match_exact_coverage() {
    let look = Preset::Clean.look();
    let (cx, cz, r) = (160.37, 110.81, 62.4);
    let ras = raster(clean_scene(320, 300, r, 250.5, 0.0), look.clone());
    let empty = ras.signal(&[]);
    let with = ras.signal(&[(cx, cz)]);
    let contrast = look.background_level * (1.0 - look.sphere_transmission);
    let cov = |i: usize, j: usize| f64::from(empty[[i, j]] - with[[i, j]]) / contrast;
    let mut total = 0.0;
    let mut worst_col: f64 = 0.0;
    for j in 0..320 {
        let col: f64 = (0..300).map(|i| cov(i, j)).sum();
        total += col;
        let exact = chord_integral(j as f64 - 0.5, j as f64 + 0.5, cx, r);
        worst_col = worst_col.max((col - exact).abs());
    }
    let mut worst_row: f64 = 0.0;
    for i in 0..300 {
        let row: f64 = (0..320).map(|j| cov(i, j)).sum();
        let exact = chord_integral(i as f64 - 0.5, i as f64 + 0.5, cz, r);
        worst_row = worst_row.max((row - exact).abs());
    }
    let area = std::f64::consts::PI * r * r;
    assert!((total - area).abs() < 2e-3, "area {total} vs {area}");
    assert!(worst_col < 1e-5, "column sums off by {worst_col}");
    assert!(worst_row < 1e-5, "row sums off by {worst_row}");
    // and the 12-bit frame is that signal, rounded
    let frame = ras.frame(&[(cx, cz)], &mut rng_for(1, "t", "frame", 0));
    for ((i, j), &v) in frame.indexed_iter() {
        assert_eq!(
            v,
            (f64::from(with[[i, j]]) * 4095.0).round() as u16,
            "pixel {i},{j}"
        );
    }
}

/// Motion blur is the time average of the silhouettes: two samples give
/// the mean of the two single-instant images.
#[test]
fn motion_blur_averages_the_silhouettes_over_the_exposure() {
    let ras = raster(
        clean_scene(200, 200, 40.0, 180.2, 0.0),
        Preset::Clean.look(),
    );
    let a = ras.signal(&[(100.3, 80.1)]);
    let b = ras.signal(&[(100.3, 83.7)]);
    let ab = ras.signal(&[(100.3, 80.1), (100.3, 83.7)]);
    let worst = ab
        .indexed_iter()
        .map(|((i, j), &v)| (v - 0.5 * (a[[i, j]] + b[[i, j]])).abs())
        .fold(0.0_f32, f32::max);
    assert!(worst < 1e-6, "{worst}");
}

/// Pixels wholly below the surface line never show the sphere: with the
/// sphere 25 px into the surface they equal the frame without it, exactly
/// (no blur), or beyond the blur kernel's reach (blur σ: ⌈4σ⌉ rows), or
/// beyond the reflection strip plus that reach (harsh).
#[test]
fn the_band_below_the_surface_line_hides_the_sphere() {
    let (row, slope) = (150.3, 0.01);
    let r = 50.0;
    let cx = 120.0;
    let line_at = |x: f64| row + slope * x;
    let cz = line_at(cx) - r + 25.0;
    let cases = [
        (Preset::Clean.look(), 0.0),
        (
            Look {
                blur_sigma_px: 1.2,
                gradient: 0.3,
                ..Preset::Clean.look()
            },
            // kernel radius ⌈4σ⌉ = 5, plus one row for the line's slope
            // across the kernel's width (the horizontal pass brings in
            // darkness from columns where the line is lower)
            6.0,
        ),
        (
            Look {
                blur_sigma_px: 1.2,
                reflection: 0.3,
                reflection_depth_px: 6.0,
                ..Preset::Clean.look()
            },
            6.0 + 6.0,
        ),
    ];
    for (look, reach) in cases {
        let ras = raster(clean_scene(240, 220, r, row, slope), look.clone());
        let empty = ras.signal(&[]);
        let with = ras.signal(&[(cx, cz)]);
        let mut dark_above = 0;
        for ((i, j), &v) in with.indexed_iter() {
            let top_of_pixel = i as f64 - 0.5;
            // the line's lowest point over this pixel's width
            let line_low = line_at(j as f64 + 0.5).max(line_at(j as f64 - 0.5));
            if top_of_pixel >= line_low + reach {
                assert_eq!(
                    v,
                    empty[[i, j]],
                    "pixel {i},{j} below the line sees the sphere ({look:?})"
                );
            } else if empty[[i, j]] - v > 0.3 {
                dark_above += 1;
            }
        }
        // the visible cap (the sphere above the line) is there
        assert!(dark_above > 3000, "{dark_above}");
    }
}

// -------------------------------------------------------- end to end, files

/// A rayon pool of `n` threads.
pub(crate) fn pool(n: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .unwrap()
}

pub(crate) fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

const SMALL: [&str; 10] = [
    "--width-px",
    "160",
    "--height-px",
    "120",
    "--mm-per-px",
    "0.2",
    "--frames-before",
    "6",
    "--frames-after",
    "4",
];

fn small_render(out: &Path, extra: &[&str]) -> dropscope::render::RenderReport {
    let mut a: Vec<&str> = vec!["--out", out.to_str().unwrap()];
    a.extend_from_slice(&SMALL);
    a.extend_from_slice(extra);
    render(&args(&a)).unwrap()
}

/// Same seed ⇒ identical bytes, on one thread or several; another seed
/// changes the noise.
#[test]
fn rendering_is_byte_identical_across_thread_counts() {
    let d1 = tempfile::tempdir().unwrap();
    let d2 = tempfile::tempdir().unwrap();
    let d3 = tempfile::tempdir().unwrap();
    let extra = [
        "--drop",
        "3:25",
        "--drop",
        "7:3",
        "--restitution",
        "0.8",
        "--seed",
        "7",
    ];
    pool(1).install(|| small_render(d1.path(), &extra));
    pool(3).install(|| small_render(d2.path(), &extra));
    let f1 = files(d1.path());
    let f2 = files(d2.path());
    assert!(f1.len() > 40, "{}", f1.len());
    assert_eq!(
        f1.iter()
            .map(|p| p.strip_prefix(d1.path()).unwrap())
            .collect::<Vec<_>>(),
        f2.iter()
            .map(|p| p.strip_prefix(d2.path()).unwrap())
            .collect::<Vec<_>>()
    );
    for (a, b) in f1.iter().zip(&f2) {
        assert!(
            std::fs::read(a).unwrap() == std::fs::read(b).unwrap(),
            "{} differs",
            a.display()
        );
    }
    let other = [
        "--drop",
        "3:25",
        "--drop",
        "7:3",
        "--restitution",
        "0.8",
        "--seed",
        "8",
    ];
    small_render(d3.path(), &other);
    let frame = "R3mm_H25cm_01/R3mm_H25cm_01_000000.tif";
    assert!(
        std::fs::read(d1.path().join(frame)).unwrap()
            != std::fs::read(d3.path().join(frame)).unwrap()
    );
}

fn text_of<'a>(doc: &'a roxmltree::Document, path: &[&str]) -> &'a str {
    let mut node = doc.root_element();
    assert_eq!(node.tag_name().name(), "chd");
    for name in path {
        node = node
            .children()
            .find(|n| n.has_tag_name(*name))
            .unwrap_or_else(|| panic!("no <{name}> in {path:?}"));
    }
    node.text().unwrap_or("")
}

/// Parse `HH:MM:SS.mmm uuu.uu` into 10 ns ticks within the day.
fn ticks(time: &str) -> i64 {
    let (hms, us) = time.split_once(' ').unwrap();
    let mut it = hms.split(':');
    let h: i64 = it.next().unwrap().parse().unwrap();
    let m: i64 = it.next().unwrap().parse().unwrap();
    let (s, ms) = it.next().unwrap().split_once('.').unwrap();
    let (s, ms): (i64, i64) = (s.parse().unwrap(), ms.parse().unwrap());
    let (u, c) = us.split_once('.').unwrap();
    let (u, c): (i64, i64) = (u.parse().unwrap(), c.parse().unwrap());
    (((h * 60 + m) * 60 + s) * 1000 + ms) * 100_000 + u * 100 + c
}

/// Every element path of a PCC XML, attributes dropped.
fn element_paths(xml: &str) -> BTreeSet<String> {
    let doc = roxmltree::Document::parse(xml).unwrap();
    let mut out = BTreeSet::new();
    for n in doc.descendants().filter(|n| n.is_element()) {
        let path: Vec<&str> = n
            .ancestors()
            .filter(|a| a.is_element())
            .map(|a| a.tag_name().name())
            .collect();
        out.insert(path.into_iter().rev().collect::<Vec<_>>().join("/"));
    }
    out
}

/// The side file parses back to the run's metadata, its TIMEBLOCK gives
/// every frame's time as n / fps after the trigger (to the file's 10 ns),
/// and its element tree is the real PCC files' tree.
#[test]
fn the_pcc_xml_parses_back_to_the_same_metadata() {
    need!(crate::Need::PhantomSamples);
    let dir = tempfile::tempdir().unwrap();
    let report = small_render(
        dir.path(),
        &[
            "--radius-mm",
            "4",
            "--height-cm",
            "6",
            "--bit-depth",
            "12",
            "--exposure-us",
            "37.5",
            "--fps",
            "12000",
        ],
    );
    let drop = &report.drops[0];
    let run = &drop.run;
    let xml = std::fs::read_to_string(drop.dir.join(format!("{run}.xml"))).unwrap();
    assert!(xml.starts_with("<?xml version=\"1.0\"?>\n<!-- xml cine header file - Copyright VisionResearch Inc. --><chd>"));
    let doc = roxmltree::Document::parse(&xml).unwrap();
    let t: Truth =
        serde_json::from_str(&std::fs::read_to_string(drop.dir.join("truth.json")).unwrap())
            .unwrap();
    let num = |p: &[&str]| text_of(&doc, p).parse::<f64>().unwrap();
    assert_eq!(
        num(&["CineFileHeader", "FirstImageNo"]) as i64,
        t.first_image_no
    );
    assert_eq!(
        num(&["CineFileHeader", "ImageCount"]) as usize,
        t.frames.len()
    );
    assert_eq!(num(&["CameraSetup", "FrameRateDouble"]), 12000.0);
    assert_eq!(num(&["CameraSetup", "ShutterNs"]), 37500.0);
    assert_eq!(num(&["CameraSetup", "RealBPP"]), 12.0);
    assert_eq!(num(&["CameraSetup", "WhiteLevel"]), 4095.0);
    assert_eq!(num(&["CameraSetup", "BlackLevel"]), 0.0);
    assert_eq!(num(&["CameraSetup", "ImWidth"]), 160.0);
    assert_eq!(num(&["CameraSetup", "ImHeight"]), 120.0);
    assert_eq!(num(&["BitmapInfoHeader", "biBitCount"]), 16.0);
    let trigger = ticks(text_of(&doc, &["CineFileHeader", "TriggerTime", "Time"]));
    let block = doc
        .descendants()
        .find(|n| n.has_tag_name("TIMEBLOCK"))
        .unwrap();
    let times: Vec<(i64, i64)> = block
        .children()
        .filter(|n| n.has_tag_name("Time"))
        .map(|n| {
            (
                n.attribute("frame").unwrap().parse().unwrap(),
                ticks(n.text().unwrap()),
            )
        })
        .collect();
    assert_eq!(times.len(), t.frames.len());
    for ((n, tk), f) in times.iter().zip(&t.frames) {
        assert_eq!(*n, f.frame);
        let expect = (f.t_s * 1e8).round() as i64;
        assert!(
            (tk - trigger - expect).abs() <= 1,
            "frame {n}: {} vs {expect}",
            tk - trigger
        );
    }
    let dates = block.children().filter(|n| n.has_tag_name("Date")).count();
    assert_eq!(dates, t.frames.len());
    let exps: Vec<&str> = doc
        .descendants()
        .filter(|n| n.has_tag_name("Exp"))
        .map(|n| n.text().unwrap())
        .collect();
    assert_eq!(exps.len(), t.frames.len());
    assert!(exps.iter().all(|e| *e == "37.500"));
    // same element tree as real PCC exports
    let ours = element_paths(&xml);
    let root = crate::phantom_sample("cinefiles-jl");
    for real in ["cam_1.xml", "12bpp.xml"] {
        let theirs = element_paths(&std::fs::read_to_string(root.join(real)).unwrap());
        assert_eq!(ours, theirs, "element tree differs from {real}");
    }
    // frames are 16-bit files holding 12-bit values
    let first = drop.dir.join(format!("{run}_-000006.tif"));
    let img = image::open(&first).unwrap();
    assert_eq!(img.color(), image::ColorType::L16);
    assert!(img.to_luma16().pixels().all(|p| p.0[0] <= 4095));
}

/// truth.json is self-consistent: δ from the centre row and the surface
/// line, contact flags from the event times, a_max from δmax, and the
/// frames are exactly the files on disk.
#[test]
fn truth_is_self_consistent_and_matches_the_files() {
    let dir = tempfile::tempdir().unwrap();
    let report = small_render(
        dir.path(),
        &[
            "--campaign",
            "--radii-mm",
            "3,7",
            "--heights-cm",
            "1.5,50",
            "--preset",
            "harsh",
            "--format",
            "png",
            "--restitution",
            "0.85",
        ],
    );
    assert_eq!(report.drops.len(), 4);
    assert!(report.failures.is_empty());
    let manifest = std::fs::read_to_string(dir.path().join("runs.csv")).unwrap();
    let mut lines = manifest.lines();
    // The scale column stays empty unless --manifest-scale: the pipeline
    // must measure it from the sphere, as for real data.
    assert_eq!(
        lines.next().unwrap(),
        "run,path,sphere_radius_mm,drop_height_cm,fps,mm_per_px,surface,sphere_density_kg_m3"
    );
    let runs = dropscope::dataset::manifest::read_manifest(&dir.path().join("runs.csv")).unwrap();
    assert_eq!(runs.len(), 4);
    assert!(runs
        .iter()
        .all(|r| r.mm_per_px.is_none() && r.path.is_dir()));
    for d in &report.drops {
        let t: Truth =
            serde_json::from_str(&std::fs::read_to_string(d.dir.join("truth.json")).unwrap())
                .unwrap();
        let line = lines.next().unwrap();
        assert!(line.starts_with(&format!("{},{},", t.run, t.run)), "{line}");
        assert!(t.t_contact_s >= 0.0 && t.t_contact_s < 1.0 / t.fps);
        assert!((t.restitution - 0.85).abs() < 1e-6);
        assert!((t.tau_c_s - (t.t_rebound_s - t.t_contact_s)).abs() < 1e-15);
        let r = t.sphere_radius_mm;
        assert!((t.a_max_mm - (r * r - (r - t.delta_max_mm).powi(2)).sqrt()).abs() < 1e-12);
        assert!((t.radius_px * t.mm_per_px - r).abs() < 1e-12);
        let mut peak: f64 = 0.0;
        for f in &t.frames {
            let y_s = t.surface_row_px + t.surface_slope * f.x_px;
            let delta = ((f.z_px + t.radius_px - y_s) * t.mm_per_px).max(0.0);
            assert!(
                (delta - f.delta_mm).abs() < 1e-9,
                "frame {}: {delta} vs {}",
                f.frame,
                f.delta_mm
            );
            assert_eq!(
                f.in_contact,
                f.t_s > t.t_contact_s && f.t_s < t.t_rebound_s,
                "frame {}",
                f.frame
            );
            assert_eq!(f.t_s, f.frame as f64 / t.fps);
            peak = peak.max(f.delta_mm);
            let file = d.dir.join(dropscope::render::export::frame_file_name(
                &t.run,
                f.frame,
                dropscope::render::export::FrameFormat::Png,
            ));
            assert!(file.exists(), "{}", file.display());
        }
        // the sampled peak is below the true maximum but within a frame's motion
        assert!(peak <= t.delta_max_mm && peak > 0.9 * t.delta_max_mm);
        let n_files = std::fs::read_dir(&d.dir).unwrap().count();
        assert_eq!(n_files, t.frames.len() + 2);
        assert_eq!(t.frames.first().unwrap().frame, -6);
        assert_eq!(
            t.frames.last().unwrap().frame,
            (t.t_rebound_s * t.fps).ceil() as i64 + 4
        );
    }
}

/// Bad options are refused with the option's name.
#[test]
fn bad_options_name_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    for (bad, name) in [
        (vec!["--out", out, "--bit-depth", "10"], "bit-depth"),
        (vec!["--out", out, "--restitution", "1.5"], "restitution"),
        (vec!["--out", out, "--exposure-us", "500"], "exposure-us"),
        (vec!["--out", out, "--drop", "3"], "drop"),
    ] {
        let err = render(&args(&bad)).unwrap_err().to_string();
        assert!(err.contains(name), "{err}");
    }
    // A frame rate ≤ 0 is refused as the command line is parsed
    // (tests/cli.rs); one set in code is refused by `render`.
    let mut bad = args(&["--out", out]);
    bad.fps = -3.0;
    let err = render(&bad).unwrap_err().to_string();
    assert!(err.contains("fps"), "{err}");
    // a drop beyond the model's range fails alone; the others are rendered
    let mut a = vec![
        "--out",
        out,
        "--drop",
        "3:1.5",
        "--pillar-height-mm",
        "0.6",
        "--drop",
        "3:50",
    ];
    a.extend_from_slice(&SMALL);
    let report = render(&args(&a)).unwrap();
    assert_eq!(report.drops.len(), 1);
    assert_eq!(report.failures.len(), 1);
    assert!(
        report.failures[0].1.contains("pillar height"),
        "{:?}",
        report.failures
    );
    let manifest = std::fs::read_to_string(dir.path().join("runs.csv")).unwrap();
    assert_eq!(manifest.lines().count(), 2, "{manifest}");
}

/// The committed fixtures are what the command in fixtures/README.md
/// renders today, byte for byte (a golden-file check: a deliberate change
/// to the pictures must come with regenerated fixtures).
#[test]
fn the_committed_fixtures_regenerate_byte_for_byte() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    render(&args(&[
        "--drop",
        "3:1.5",
        "--drop",
        "4.5:12",
        "--drop",
        "7:50",
        "--preset",
        "realistic",
        "--format",
        "png",
        "--width-px",
        "384",
        "--height-px",
        "288",
        "--restitution",
        "0.9",
        "--seed",
        "2019",
        "--out",
        out,
    ]))
    .unwrap();
    let ours = files(dir.path());
    assert!(ours.len() > 260);
    for p in &ours {
        let committed = root.join(p.strip_prefix(dir.path()).unwrap());
        let same = std::fs::read(&committed).map(|b| b == std::fs::read(p).unwrap());
        assert!(
            same.unwrap_or(false),
            "{} differs from a fresh render: regenerate with the command in fixtures/README.md",
            committed.display()
        );
    }
    let committed_count = files(&root).len() - 1; // README.md
    assert_eq!(
        committed_count,
        ours.len(),
        "fixtures/ holds files the command does not write"
    );
}

/// The command's exit status: 2 when it cannot run (the message names the
/// option), 1 when some drops failed (the others are written), 0 otherwise.
#[test]
fn render_exit_codes_follow_the_spec() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let run = |extra: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_dropscope"))
            .args(["render", "--out", out])
            .args(SMALL)
            .args(extra)
            .output()
            .unwrap()
    };
    let bad = run(&["--tilt", "0.5"]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--tilt"));
    let some_failed = run(&[
        "--drop",
        "3:1.5",
        "--drop",
        "3:50",
        "--pillar-height-mm",
        "0.6",
    ]);
    assert_eq!(some_failed.status.code(), Some(1));
    let err = String::from_utf8_lossy(&some_failed.stderr);
    assert!(
        err.contains("R3mm_H50cm_01") && err.contains("rendered 1 drop,"),
        "{err}"
    );
    assert_eq!(run(&["--drop", "3:1.5"]).status.code(), Some(0));
}

/// `--format cine` writes the same pictures as the TIFF export: every frame
/// read back through the loader is identical, the image numbers and the
/// frame rate agree, and the manifest points at the .cine.
#[test]
fn a_cine_render_reads_back_identical_to_the_tiff_render() {
    use dropscope::source::{open, Frame, OpenOptions};
    for bits in ["8", "12"] {
        let dt = tempfile::tempdir().unwrap();
        let dc = tempfile::tempdir().unwrap();
        let extra = ["--bit-depth", bits, "--drop", "4:6"];
        let rt = small_render(dt.path(), &extra);
        let rc = small_render(dc.path(), &[&extra[..], &["--format", "cine"]].concat());
        let run = &rt.drops[0].run;
        let manifest = std::fs::read_to_string(dc.path().join("runs.csv")).unwrap();
        assert!(
            manifest.contains(&format!("{run}/{run}.cine")),
            "{manifest}"
        );
        let mut a = open(&dt.path().join(run), &OpenOptions::default()).unwrap();
        let mut b = open(
            &rc.drops[0].dir.join(format!("{run}.cine")),
            &OpenOptions::default(),
        )
        .unwrap();
        let (ma, mb) = (a.meta().clone(), b.meta().clone());
        assert_eq!(ma.frame_numbers, mb.frame_numbers);
        assert_eq!(
            (ma.width, ma.height, ma.bit_depth),
            (mb.width, mb.height, mb.bit_depth)
        );
        assert!((ma.fps - mb.fps).abs() < 1e-9);
        let mut fa = Frame::zeros((ma.height, ma.width));
        let mut fb = fa.clone();
        for i in 0..ma.frame_count {
            a.read_into(i, &mut fa).unwrap();
            b.read_into(i, &mut fb).unwrap();
            assert!(
                fa == fb,
                "{bits}-bit frame {i} differs between TIFF and cine"
            );
        }
    }
}
