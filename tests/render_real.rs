//! `dropscope render --preset real`: each real-camera effect alone at its
//! strongest has the stated size, the realised values in `truth.json` are
//! what was drawn, set-ups are shared, and the files are deterministic.

use std::path::Path;

use dropscope::render::camera::CameraRaster;
use dropscope::render::optics::{draw, FrameGeometry, OpticsSpec, Strength};
use dropscope::render::raster::{Look, Scene};
use dropscope::render::truth::Truth;
use dropscope::render::{default_mm_per_px, render, rng_for, Preset};

use crate::render::{args, clean_scene, files, pool};
use dropscope::render::export::{frame_file_name, FrameFormat};

/// A clean 12-bit look (uniform backlight 0.75, transmission 0.06, no blur,
/// no noise) seen through the camera `spec`.
pub(crate) fn camera(spec: &OpticsSpec, scene: Scene) -> CameraRaster {
    camera_with(Preset::Clean.look(), spec, scene)
}

pub(crate) fn camera_with(look: Look, spec: &OpticsSpec, scene: Scene) -> CameraRaster {
    let frame = FrameGeometry {
        width_px: scene.width_px,
        height_px: scene.height_px,
        radius_px: scene.radius_px,
    };
    let optics = draw(spec, 1, "setup", "run", frame, &look);
    CameraRaster::new(scene, look, optics, &mut rng_for(1, "", "dust", 0)).unwrap()
}

fn fade(u: f64, w: f64) -> f64 {
    if u < w {
        0.5 * (1.0 + (std::f64::consts::PI * u / w).cos())
    } else {
        0.0
    }
}

const B: f64 = 0.75;
const TAU_S: f64 = 0.06;

/// Rim 20 % over 4 px, halo 8 % over 4 px, highlight 15 %, no blur: a row
/// through the centre shows, pixel by pixel, `B·(τs + rim·g(R − ρ) +
/// highlight·H)` inside and `B·(1 + halo·g(ρ − R))` outside (pixels wholly
/// on one side of the outline, where the formula is exact; f32 storage:
/// 1e-6). The true outline stays the geometric circle: the coverage-weighted
/// edge pixels carry the rest.
#[test]
fn the_steel_ball_look_has_its_stated_levels() {
    let spec = OpticsSpec {
        rim: Strength::Fixed(0.2),
        rim_width_px: Strength::Fixed(4.0),
        halo: Strength::Fixed(0.08),
        halo_width_px: Strength::Fixed(4.0),
        highlight: Strength::Fixed(0.15),
        ..OpticsSpec::off()
    };
    let (cx, cz, r) = (100.0, 60.0, 40.0);
    let cam = camera(&spec, clean_scene(200, 160, r, 130.0, 0.0));
    let t = &cam.optics().truth;
    assert_eq!(
        (t.rim, t.rim_width_px, t.halo, t.highlight),
        (0.2, 4.0, 0.08, 0.15)
    );
    let sig = cam.signal(&[(cx, cz)]);
    let hl = |x: f64, z: f64| {
        let (hx, hz) = (cx + t.highlight_offset_px[0], cz + t.highlight_offset_px[1]);
        let s = t.highlight_sigma_px;
        t.highlight * (-((x - hx).powi(2) + (z - hz).powi(2)) / (2.0 * s * s)).exp()
    };
    let mut checked = 0;
    for j in 40..100 {
        let rho = cx - j as f64;
        let v = f64::from(sig[[60, j]]);
        let expected = if rho <= r - 0.75 {
            B * (TAU_S + 0.2 * fade(r - rho, 4.0) + hl(j as f64, cz))
        } else if rho >= r + 0.75 {
            B * (1.0 + 0.08 * fade(rho - r, 4.0))
        } else {
            continue;
        };
        assert!((v - expected).abs() < 1e-6, "column {j}: {v} vs {expected}");
        checked += 1;
    }
    assert!(checked > 50);
    // the rim is at its full 20 % just inside the outline, the halo at 8 % just outside
    let just_in = f64::from(sig[[60, 61]]) / B - TAU_S - hl(61.0, cz);
    assert!((just_in - 0.2 * fade(1.0, 4.0)).abs() < 1e-6, "{just_in}");
    let just_out = f64::from(sig[[60, 59]]) / B - 1.0;
    assert!(
        (just_out - 0.08 * fade(1.0, 4.0)).abs() < 1e-6,
        "{just_out}"
    );
}

/// The 50 % crossing of the outline's profile (between the background and
/// the sphere's dark level read 20 px inside) on a blurred image: with the
/// rim it lies inside the true outline, so that a silhouette radius comes
/// out small — by 0.1–0.5 px at the strongest rim (20 % over 4 px) under a
/// blur of σ 1.5 px; without the rim it is on the outline within 0.06 px
/// (the blurred 40 px circle's 50 % level lies ~σ²/2R = 0.03 px inside it,
/// plus the linear interpolation between pixels).
#[test]
fn the_rim_makes_a_silhouette_radius_small_by_a_fraction_of_a_pixel() {
    let shrink = |rim: f64| {
        let spec = OpticsSpec {
            rim: Strength::Fixed(rim),
            rim_width_px: Strength::Fixed(4.0),
            blur_sigma0_px: Strength::Fixed(1.5),
            ..OpticsSpec::off()
        };
        let (cx, cz, r) = (100.25, 60.0, 40.0);
        let cam = camera(&spec, clean_scene(200, 160, r, 130.0, 0.0));
        let sig = cam.signal(&[(cx, cz)]);
        let bg = f64::from(sig[[60, 5]]);
        let dark = f64::from(sig[[60, 80]]);
        let half = 0.5 * (bg + dark);
        // walk in from the left until the profile drops below half
        let j = (40..100).find(|&j| f64::from(sig[[60, j]]) < half).unwrap();
        let (a, b) = (f64::from(sig[[60, j - 1]]), f64::from(sig[[60, j]]));
        let x = (j - 1) as f64 + (a - half) / (a - b);
        x - (cx - r)
    };
    let plain = shrink(0.0);
    assert!(plain.abs() < 0.06, "{plain}");
    let with_rim = shrink(0.2);
    assert!(
        (0.1..0.5).contains(&(with_rim - plain)),
        "crossing moved in by {} px",
        with_rim - plain
    );
}

/// Glossy strip 30 % over 3 px and a top row at −25 % over 2 px, against
/// the same scene without them: far from the sphere the strip adds
/// `B·gloss` and the top row scales the band by 0.75; where the sphere's
/// mirror image (the sphere 3 px into the surface) covers the strip, the
/// gloss is gone.
#[test]
fn the_glossy_strip_and_the_top_row_have_their_levels_and_the_mirror_darkens_the_strip() {
    let (r, row) = (40.0, 130.0);
    let scene = clean_scene(200, 200, r, row, 0.0);
    let plain = camera(&OpticsSpec::off(), scene.clone());
    let gloss = camera(
        &OpticsSpec {
            gloss: Strength::Fixed(0.3),
            gloss_width_px: Strength::Fixed(3.0),
            ..OpticsSpec::off()
        },
        scene.clone(),
    );
    let top = camera(
        &OpticsSpec {
            top_row: Strength::Fixed(-0.25),
            top_row_width_px: Strength::Fixed(2.0),
            ..OpticsSpec::off()
        },
        scene,
    );
    // the sphere's bottom 3 px below the line: its mirror covers the strip
    // over the contact chord (±15 px at the line)
    let centre = [(100.0, row + 3.0 - r)];
    let p = plain.signal(&centre);
    let g = gloss.signal(&centre);
    let t = top.signal(&centre);
    for i in [131, 132] {
        // rows 131, 132 lie wholly in the strip (130.5‥132.5 ⊂ 130‥133)
        for j in [10, 190] {
            let added = f64::from(g[[i, j]] - p[[i, j]]);
            assert!((added - B * 0.3).abs() < 1e-6, "row {i} col {j}: {added}");
        }
        for j in 95..106 {
            let added = f64::from(g[[i, j]] - p[[i, j]]);
            assert!(
                added.abs() < 1e-6,
                "row {i} col {j}: {added} under the mirror"
            );
        }
    }
    // rows 130.5‥131.5 wholly in the top row (130‥132), 133 wholly below it
    for j in [10, 60, 190] {
        let ratio = f64::from(t[[131, j]] / p[[131, j]]);
        assert!((ratio - 0.75).abs() < 1e-5, "col {j}: {ratio}");
        assert!((t[[133, j]] - p[[133, j]]).abs() < 1e-6);
    }
}

fn truth(path: &Path) -> Truth {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// A `real` campaign of two radii × two heights: runs.csv holds only run,
/// path, R, H and setup; drops of one radius share their set-up's camera
/// (scale, surface, distortion, roll, focus, column pattern, hot pixels),
/// other radii get another; the per-drop look differs from drop to drop and
/// every realised value lies in the preset's range.
#[test]
fn a_real_campaign_shares_camera_set_ups_per_radius() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    render(&args(&[
        "--out",
        out,
        "--campaign",
        "--preset",
        "real",
        "--radii-mm",
        "3,5",
        "--heights-cm",
        "25,50",
        "--start-at-entry",
        "false",
        "--frames-before",
        "2",
        "--frames-after",
        "1",
        "--seed",
        "4",
    ]))
    .unwrap();
    let csv = std::fs::read_to_string(dir.path().join("runs.csv")).unwrap();
    assert_eq!(
        csv.lines().next().unwrap(),
        "run,path,sphere_radius_mm,drop_height_cm,setup"
    );
    let runs = dropscope::dataset::manifest::read_manifest(&dir.path().join("runs.csv")).unwrap();
    assert_eq!(runs.len(), 4);
    assert_eq!(runs[0].setup.as_deref(), Some("cam_R3mm_01"));
    assert_eq!(runs[1].setup, runs[0].setup);
    assert_eq!(runs[2].setup.as_deref(), Some("cam_R5mm_01"));
    let t: Vec<Truth> = runs
        .iter()
        .map(|r| truth(&r.path.join("truth.json")))
        .collect();
    let c: Vec<_> = t.iter().map(|t| t.camera.clone().unwrap()).collect();
    let shared = |a: usize, b: usize| {
        t[a].mm_per_px == t[b].mm_per_px
            && t[a].surface_row_px == t[b].surface_row_px
            && c[a].k1_per_px2 == c[b].k1_per_px2
            && c[a].roll_deg == c[b].roll_deg
            && c[a].focus_row_px == c[b].focus_row_px
            && c[a].blur_sigma0_px == c[b].blur_sigma0_px
            && c[a].column_gain_rms == c[b].column_gain_rms
            && c[a].hot_pixels == c[b].hot_pixels
    };
    assert!(shared(0, 1) && shared(2, 3));
    let zoom = |k: usize| t[k].mm_per_px / default_mm_per_px(t[k].sphere_radius_mm);
    assert!(c[0].k1_per_px2 != c[2].k1_per_px2 && zoom(0) != zoom(2));
    assert!(c[0].rim != c[1].rim && c[0].gloss != c[1].gloss);
    for (t, c) in t.iter().zip(&c) {
        assert_eq!(t.preset, "real");
        assert!((0.0..=0.2).contains(&c.rim) && (1.0..=4.0).contains(&c.rim_width_px));
        assert!((0.0..=0.08).contains(&c.halo) && (0.0..=0.3).contains(&c.gloss));
        assert!((-0.25..=0.25).contains(&c.top_row) && (0.0..=0.3).contains(&c.dip));
        assert!((0.0..=0.5).contains(&c.corner_displacement_px) && c.roll_deg.abs() <= 0.5);
        assert!(c.blur_sigma_min_px >= 0.6 && c.blur_sigma_max_px <= 2.5 + 1e-12);
        assert!(c.hot_pixels.len() <= 50 && c.column_gain_rms <= 0.015);
        // the scale at R_px 75‥87.5 ± 8 %
        let r_px = t.sphere_radius_mm / t.mm_per_px;
        assert!((68.0..96.0).contains(&r_px), "{r_px}");
        // the mapped centre is the scene centre through roll and distortion
        let f = &t.frames[0];
        let th = c.roll_deg.to_radians();
        let (u, v) = (f.x_px - c.centre_px[0], f.z_px - c.centre_px[1]);
        let (u, v) = (u * th.cos() - v * th.sin(), u * th.sin() + v * th.cos());
        let k = 1.0 + c.k1_per_px2 * (u * u + v * v);
        assert!((f.image_x_px.unwrap() - c.centre_px[0] - u * k).abs() < 1e-9);
        assert!((f.image_z_px.unwrap() - c.centre_px[1] - v * k).abs() < 1e-9);
    }
}

/// The same seed gives the same bytes on one thread or three; the movie
/// starts with the sphere's bottom just inside the top edge and one frame
/// file in flight is missing and listed. (A 25 cm drop: ~130 small frames.)
#[test]
fn real_renders_are_deterministic_and_miss_one_listed_frame_file() {
    let d1 = tempfile::tempdir().unwrap();
    let d2 = tempfile::tempdir().unwrap();
    let run = |dir: &Path| {
        render(&args(&[
            "--out",
            dir.to_str().unwrap(),
            "--preset",
            "real",
            "--drop",
            "3:25",
            "--width-px",
            "160",
            "--height-px",
            "120",
            "--mm-per-px",
            "0.2",
            "--seed",
            "9",
        ]))
        .unwrap()
    };
    let report = pool(1).install(|| run(d1.path()));
    pool(3).install(|| run(d2.path()));
    let (f1, f2) = (files(d1.path()), files(d2.path()));
    assert_eq!(f1.len(), f2.len());
    for (a, b) in f1.iter().zip(&f2) {
        assert!(
            std::fs::read(a).unwrap() == std::fs::read(b).unwrap(),
            "{}",
            a.display()
        );
    }
    let d = &report.drops[0];
    let t = &d.truth;
    let c = t.camera.as_ref().unwrap();
    let frames = files(&d.dir)
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "tif"))
        .count();
    assert_eq!(frames + 1, t.frames.len());
    assert_eq!(c.missing_frames.len(), 1);
    let m = c.missing_frames[0];
    let name = frame_file_name(&d.run, m, FrameFormat::Tiff);
    assert!(!d.dir.join(name).exists());
    assert!(m > t.first_image_no + 1 && m < -2);
    // just inside the top edge: the sphere moves ~1 px per frame there
    assert!(!c.release_in_view);
    let bottom = t.frames[0].image_z_px.unwrap() + t.radius_px;
    assert!((0.0..3.0).contains(&bottom), "{bottom}");
    // the second contact is 4 600 frames away: not rendered
    assert!(t.second_bounce.is_none());
}

/// A 1.5 cm drop: the sphere hangs in view until its release, and the movie
/// goes on through the rebound's flight (1 100 frames) and a second contact.
/// (As a .cine: no frame files to write.)
#[test]
fn a_low_real_drop_starts_at_the_release_and_shows_a_second_contact() {
    let dir = tempfile::tempdir().unwrap();
    let report = render(&args(&[
        "--out",
        dir.path().to_str().unwrap(),
        "--preset",
        "real",
        "--drop",
        "7:1.5",
        "--width-px",
        "160",
        "--height-px",
        "120",
        "--mm-per-px",
        "0.2",
        "--format",
        "cine",
    ]))
    .unwrap();
    let t = &report.drops[0].truth;
    let c = t.camera.as_ref().unwrap();
    assert!(c.release_in_view && c.missing_frames.is_empty());
    let first = &t.frames[0];
    assert!(first.t_s <= c.t_release_s && first.t_s > c.t_release_s - 1e-4);
    let second = t.second_bounce.as_ref().expect("a second contact");
    assert!(second.t_contact_s > t.t_rebound_s + 0.1);
    let last = t.frames.last().unwrap();
    assert!(last.t_s > second.t_rebound_s);
    assert!(t
        .frames
        .iter()
        .any(|f| f.in_contact && f.t_s > second.t_contact_s));
}

/// A clean look whose band has one grey (0.45) across pillars and channels,
/// so that the band's top edge in a column is read exactly from the pixel
/// it crosses.
fn flat_band() -> Look {
    Look {
        channel_grey: 0.45,
        ..Preset::Clean.look()
    }
}

/// The band's top edge in column `j` of a sharp image: the row where the
/// value crosses from `above` to the band's `B·0.45`, read from the one
/// pixel that straddles it (value = mix of the two by area).
fn edge_row(sig: &ndarray::Array2<f32>, j: usize, above: f64) -> f64 {
    let band = B * 0.45;
    let i = (1..sig.nrows() - 1)
        .find(|&i| {
            (f64::from(sig[[i + 1, j]]) - band).abs() < 1e-6
                && (f64::from(sig[[i, j]]) - band).abs() > 1e-7
        })
        .unwrap();
    let f = (above - f64::from(sig[[i, j]])) / (above - band);
    i as f64 + 0.5 - f
}

/// Barrel distortion at its strongest (0.5 px at the corners): the band's
/// straight top edge, 10 rows from the top, bends into the distorted image
/// of the line — read column by column within 0.01 px of `Geometry::forward`
/// of the scene line (the pixel-square approximation's error is ~1e-3 px) —
/// so that it bends by 0.19 px between the middle and the ends at this row.
#[test]
fn barrel_distortion_bends_a_straight_line_by_the_stated_corner_displacement() {
    let spec = OpticsSpec {
        corner_displacement_px: Strength::Fixed(0.5),
        ..OpticsSpec::off()
    };
    let line = 10.0;
    let cam = camera_with(flat_band(), &spec, clean_scene(512, 384, 40.0, line, 0.0));
    let t = &cam.optics().truth;
    assert_eq!(t.corner_displacement_px, 0.5);
    let r_c = (255.5_f64).hypot(191.5);
    assert!((t.k1_per_px2 + 0.5 / r_c.powi(3)).abs() < 1e-18);
    let g = cam.optics().geometry;
    // corner (0, 0) moves 0.5 px towards the centre
    let (xd, zd) = g.forward(0.0, 0.0);
    assert!((xd.hypot(zd) - 0.5).abs() < 1e-12);
    let sig = cam.signal(&[]);
    let expected = |j: usize| {
        // the scene point (x, line) landing on column j
        let mut x = j as f64;
        for _ in 0..30 {
            x += j as f64 - g.forward(x, line).0;
        }
        g.forward(x, line).1
    };
    let mut worst: f64 = 0.0;
    for j in (0..512).step_by(7) {
        worst = worst.max((edge_row(&sig, j, B) - expected(j)).abs());
    }
    assert!(worst < 0.01, "worst {worst} px");
    let bend = edge_row(&sig, 0, B) - edge_row(&sig, 256, B);
    assert!(
        (bend - (expected(0) - expected(256))).abs() < 0.01 && bend > 0.15,
        "{bend}"
    );
}

/// Roll at its strongest (0.5°): the band's top edge through the image
/// centre tilts by tan 0.5° = 0.00873 rows per column (least-squares slope
/// of the edge rows, within 1e-5), and the truth's mapping makes the fall
/// direction tilt with it.
#[test]
fn camera_roll_tilts_the_band_top_by_the_roll_angle() {
    let spec = OpticsSpec {
        roll_deg: Strength::Fixed(0.5),
        ..OpticsSpec::off()
    };
    let cam = camera_with(flat_band(), &spec, clean_scene(512, 384, 40.0, 191.5, 0.0));
    let sig = cam.signal(&[]);
    let pts: Vec<(f64, f64)> = (20..492)
        .map(|j| (j as f64, edge_row(&sig, j, B)))
        .collect();
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let slope = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum::<f64>()
        / pts.iter().map(|p| (p.0 - mx).powi(2)).sum::<f64>();
    let want = 0.5_f64.to_radians().tan();
    assert!((slope - want).abs() < 1e-5, "{slope} vs {want}");
    assert!((my - 191.5).abs() < 0.01, "{my}");
    // a fall of 100 px down the scene's columns moves the image point left by 100 sin θ
    let g = cam.optics().geometry;
    let (a, b) = (g.forward(255.5, 100.0), g.forward(255.5, 200.0));
    assert!(((b.0 - a.0) + 100.0 * 0.5_f64.to_radians().sin()).abs() < 1e-9);
}

/// The pillars dipping under the sphere at their strongest (30 % of δ): with
/// the sphere 10 px into the surface, the band's top edge (sphere above it,
/// band below) lies 3 px lower at the sphere's column and on the line far
/// from it (within 0.01 px).
#[test]
fn the_band_top_dips_under_the_sphere_by_the_stated_fraction_of_delta() {
    let spec = OpticsSpec {
        dip: Strength::Fixed(0.3),
        ..OpticsSpec::off()
    };
    let (r, line, delta) = (40.0, 130.0, 10.0);
    let cam = camera_with(flat_band(), &spec, clean_scene(200, 200, r, line, 0.0));
    let sig = cam.signal(&[(100.0, line - r + delta)]);
    let at_sphere = edge_row(&sig, 100, B * TAU_S);
    assert!(
        (at_sphere - (line + 0.3 * delta)).abs() < 0.01,
        "{at_sphere}"
    );
    for j in [10, 190] {
        assert!((edge_row(&sig, j, B) - line).abs() < 1e-6);
    }
    // no dip out of contact
    let free = cam.signal(&[(100.0, line - r - 5.0)]);
    assert!((edge_row(&free, 100, B) - line).abs() < 1e-6);
}

/// Defocus: σ(row) = 0.6 + g·|row − 40| with g set for σ = 2.5 at row 240.
/// The blurred step of the band's top edge (on a pixel boundary, so that the
/// pixels add no spread) has across it the spread of the Gaussian kernel
/// sampled at σ of its row: within 3 % at row 40 and at row 240.
#[test]
fn defocus_grows_the_blur_away_from_the_focal_row() {
    let kernel_sd = |sigma: f64| {
        let k: Vec<f64> = (-12..=12)
            .map(|k| (-0.5 * (f64::from(k) / sigma).powi(2)).exp())
            .collect();
        let sum: f64 = k.iter().sum();
        let var: f64 = k
            .iter()
            .zip(-12..=12)
            .map(|(w, q)| w * f64::from(q * q))
            .sum::<f64>()
            / sum;
        var.sqrt()
    };
    let spread = |line: f64| {
        let spec = OpticsSpec {
            blur_sigma0_px: Strength::Fixed(0.6),
            defocus_px_per_row: Strength::Fixed(1.9 / 200.0),
            focus_row_px: Strength::Fixed(40.5),
            ..OpticsSpec::off()
        };
        let cam = camera_with(flat_band(), &spec, clean_scene(160, 300, 20.0, line, 0.0));
        let sig = cam.signal(&[]);
        let col: Vec<f64> = (0..300).map(|i| f64::from(sig[[i, 80]])).collect();
        let d: Vec<(f64, f64)> = (1..299)
            .map(|i| (i as f64 + 0.5, col[i] - col[i + 1]))
            .filter(|&(z, _)| (z - line).abs() < 15.0)
            .collect();
        let w: f64 = d.iter().map(|p| p.1).sum();
        let m = d.iter().map(|p| p.0 * p.1).sum::<f64>() / w;
        (d.iter().map(|p| (p.0 - m).powi(2) * p.1).sum::<f64>() / w).sqrt()
    };
    let near = spread(40.5);
    let far = spread(240.5);
    assert!((near / kernel_sd(0.6) - 1.0).abs() < 0.03, "{near}");
    assert!((far / kernel_sd(2.5) - 1.0).abs() < 0.03, "{far}");
}

/// Column pattern (1.5 %), 50 hot pixels and a 5 % drift, sensor alone (a
/// clean 12-bit look: no noise): per-column levels scatter by 1.5 %·√2
/// (gain and offset) within 15 % (512 columns); every listed hot pixel reads
/// its value; the ratio of a drifted frame to an undrifted one is the
/// stated drift gain at the first and last columns (within 12-bit rounding).
#[test]
fn column_pattern_hot_pixels_and_drift_have_their_stated_size() {
    let scene = clean_scene(512, 96, 20.0, 90.0, 0.0);
    let spec = OpticsSpec {
        column_noise: Strength::Fixed(0.015),
        hot_pixels: Strength::Fixed(50.0),
        ..OpticsSpec::off()
    };
    let cam = camera(&spec, scene.clone());
    let t = &cam.optics().truth;
    assert_eq!(t.hot_pixels.len(), 50);
    let mut rng = rng_for(1, "r", "frame", 0);
    let f = cam.frame(&[], 0.0, &mut rng);
    for &[i, j] in &t.hot_pixels {
        assert_eq!(f[[i, j]], t.hot_pixel_dn);
    }
    let white = 4095.0;
    let level: Vec<f64> = (0..512)
        .map(|j| {
            let mut v: Vec<f64> = (0..60).map(|i| f64::from(f[[i, j]])).collect();
            v.sort_by(f64::total_cmp);
            v[30] / (B * white) - 1.0
        })
        .collect();
    let rms = (level.iter().map(|x| x * x).sum::<f64>() / 512.0).sqrt();
    let want = 0.015 * 2f64.sqrt();
    assert!((rms / want - 1.0).abs() < 0.15, "{rms} vs {want}");

    let drifting = camera(
        &OpticsSpec {
            drift: Strength::Fixed(0.05),
            ..OpticsSpec::off()
        },
        scene.clone(),
    );
    let steady = camera(&OpticsSpec::off(), scene);
    let o = drifting.optics();
    for s in [0.0, 0.3, 1.0] {
        let a = drifting.frame(&[], s, &mut rng_for(1, "r", "frame", 0));
        let b = steady.frame(&[], s, &mut rng_for(1, "r", "frame", 0));
        for j in [0, 511] {
            let ratio = f64::from(a[[10, j]]) / f64::from(b[[10, j]]);
            assert!(
                (ratio - o.drift_gain(j, s)).abs() < 5e-4,
                "{s} {j}: {ratio}"
            );
        }
    }
    let swing = (0..=10)
        .map(|k| o.drift_gain(0, k as f64 / 10.0))
        .fold((f64::MAX, f64::MIN), |(lo, hi), g| (lo.min(g), hi.max(g)));
    assert!(swing.1 - swing.0 > 0.02 && swing.1 - 1.0 <= 0.05 && 1.0 - swing.0 <= 0.05);
}

/// `--format jpeg`: the same movie as the TIFF render (same frame numbers,
/// the same missing file), each frame within JPEG's loss of it — mean
/// |difference| under 1.5 DN and the worst pixel under 40 DN at quality
/// 85–98, drawn per drop and written to truth — and 12-bit JPEG refused.
#[test]
fn jpeg_frames_hold_the_tiff_frames_within_the_compression_loss() {
    use dropscope::source::{open, Frame, OpenOptions};
    let dt = tempfile::tempdir().unwrap();
    let dj = tempfile::tempdir().unwrap();
    let common = [
        "--preset",
        "real",
        "--drop",
        "3:25",
        "--width-px",
        "160",
        "--height-px",
        "120",
        "--mm-per-px",
        "0.2",
        "--seed",
        "5",
    ];
    let with = |dir: &Path, fmt: &str| {
        let mut a = vec!["--out", dir.to_str().unwrap(), "--format", fmt];
        a.extend_from_slice(&common);
        render(&args(&a)).unwrap()
    };
    let rt = with(dt.path(), "tiff");
    let rj = with(dj.path(), "jpeg");
    let q = rj.drops[0].truth.jpeg_quality.unwrap();
    assert!((85..=98).contains(&q), "{q}");
    assert_eq!(rt.drops[0].truth.jpeg_quality, None);
    let run = &rt.drops[0].run;
    let mut a = open(&dt.path().join(run), &OpenOptions::default()).unwrap();
    let mut b = open(&dj.path().join(run), &OpenOptions::default()).unwrap();
    let (ma, mb) = (a.meta().clone(), b.meta().clone());
    assert_eq!(ma.frame_numbers, mb.frame_numbers);
    let mut fa = Frame::zeros((ma.height, ma.width));
    let mut fb = fa.clone();
    for i in (0..ma.frame_count).step_by(5) {
        a.read_into(i, &mut fa).unwrap();
        b.read_into(i, &mut fb).unwrap();
        let d: Vec<f64> = fa
            .iter()
            .zip(fb.iter())
            .map(|(x, y)| (f64::from(*x) - f64::from(*y)).abs())
            .collect();
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        let worst = d.iter().cloned().fold(0.0, f64::max);
        assert!(
            mean < 1.5 && worst < 40.0,
            "frame {i}: mean {mean}, worst {worst}"
        );
    }
    let e = args(&["--out", "x", "--format", "jpeg", "--bit-depth", "12"])
        .settings()
        .unwrap_err()
        .to_string();
    assert!(e.contains("--format") && e.contains("8 bits"), "{e}");
}
