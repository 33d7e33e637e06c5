//! The background when the sphere is in every frame (plain, glinting,
//! pale) and under a light drifting differently on the two sides.

use super::*;

/// A slow drop for the background tests: the sphere (R 75 px) at column
/// `x_px` moves 40 px down over 24 frames of 512 × 384, so its path's core
/// is covered in every frame; each frame's pixel at column `j` is scaled by
/// `light(k, j)` (frame `k`). The sphere-free light and the background
/// built from the frames.
fn background_of_a_slow_drop(
    x_px: f64,
    seed: u64,
    light: impl Fn(usize, usize) -> f64,
) -> (ndarray::Array2<f64>, Background) {
    background_of_a_slow_glinting_drop(x_px, seed, (0.2, 0.0), 24, light)
}

/// [`background_of_a_slow_drop`] over `frames` frames, the sphere of
/// transmission `look.0` showing the full light (a polished ball's
/// specular reflection of the backlight) within `0.6 look.1` of its centre
/// and in three pixels of ten, speckled, out to `look.1`.
fn background_of_a_slow_glinting_drop(
    x_px: f64,
    seed: u64,
    (transmission, glint_px): (f64, f64),
    frames: usize,
    light: impl Fn(usize, usize) -> f64,
) -> (ndarray::Array2<f64>, Background) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let band = pillar_band(300.4, 0.002);
    let truth = scene(512, 384, REALISTIC, None, Some(band)).render();
    let n = frames;
    let frames: Vec<Frame> = (0..n)
        .map(|k| {
            let centre = (x_px, 150.0 + 40.0 * k as f64 / (n - 1) as f64, 75.0);
            let s = Scene {
                sphere_transmission: transmission,
                ..scene(512, 384, REALISTIC, Some(centre), Some(band))
            };
            let mut img = s.render();
            for ((i, j), v) in img.indexed_iter_mut() {
                let d = (j as f64 - centre.0).hypot(i as f64 - centre.1);
                let speckle = (i * 7919 + j * 104_729 + k * 31) % 10 < 3;
                if d < 0.6 * glint_px || (d < glint_px && speckle) {
                    *v = truth[[i, j]];
                }
            }
            let gain = 1.0 + REALISTIC.flicker * (2.0 * rng.gen::<f64>() - 1.0);
            let noise = REALISTIC.noise;
            let mut f =
                synth::quantize(&img, gain, max_level(REALISTIC), || noise * gauss(&mut rng));
            for ((_, j), v) in f.indexed_iter_mut() {
                *v = (*v as f64 * light(k, j)).round().min(u16::MAX as f64) as u16;
            }
            f
        })
        .collect();
    let views: Vec<_> = frames.iter().map(|f| f.view()).collect();
    let bg = Background::from_frames_with_sphere(
        &views,
        GainRegion::default(),
        &CoarseParams::default(),
        6.0,
    )
    .unwrap();
    (truth, bg)
}

/// The background's relative error against the light, one value per degree
/// on the circle of radius `r_px` about `(x_px, z_px)`, above the band and
/// inside `columns`. The gains are relative to frame 0: the shapes are
/// compared, not the levels (the ratio of the means over the sphere-free
/// block of rows 0..40 and `block` columns).
fn ring_errors(
    truth: &ndarray::Array2<f64>,
    bg: &Background,
    (x_px, z_px, r_px): (f64, f64, f64),
    block: std::ops::Range<usize>,
    columns: std::ops::Range<usize>,
) -> Vec<f64> {
    let (mut st, mut sb) = (0.0, 0.0);
    for i in 0..40 {
        for j in block.clone() {
            st += truth[[i, j]];
            sb += bg.at(i, j) as f64;
        }
    }
    let k = st / sb;
    (0..360)
        .filter_map(|a| {
            let t = (a as f64).to_radians();
            let (x, z) = (x_px + r_px * t.cos(), z_px + r_px * t.sin());
            let (i, j) = (z.round() as usize, x.round() as usize);
            (z < 296.0 && columns.contains(&j))
                .then(|| (bg.at(i, j) as f64 * k - truth[[i, j]]) / truth[[i, j]])
        })
        .collect()
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

#[test]
fn background_is_recovered_when_the_sphere_is_in_every_frame() {
    // Against the exact sphere-free light, the background must be right to
    // 1 % around the sphere's edges (where edge profiles take their zero) —
    // noise σ 2 on 200 gives ~0.5 % per frame, and the median of the
    // uncovered frames or the quadratic fill does better.
    let (truth, bg) = background_of_a_slow_drop(250.3, 22, |_, _| 1.0);
    for zc in [150.0, 190.0] {
        for dr in [-6.0, 0.0, 6.0] {
            let rel = ring_errors(&truth, &bg, (250.3, zc, 75.0 + dr), 0..40, 0..512);
            let mean = mean(&rel);
            let rms = (rel.iter().map(|v| v * v).sum::<f64>() / rel.len() as f64).sqrt();
            println!("ring centre {zc} radius 75{dr:+}: mean {mean:+.4}, rms {rms:.4}");
            // Systematic part (what biases edges): ≤ 0.3 %. Scatter: one
            // frame's noise is 1 %, a median of several less.
            assert!(
                mean.abs() <= 0.003 && rms <= 0.012,
                "mean {mean}, rms {rms}"
            );
        }
    }
}

/// The background's ring errors around the slow drop's first and last
/// positions within the bounds of
/// [`background_is_recovered_when_the_sphere_is_in_every_frame`].
fn assert_rings_within_bounds(truth: &ndarray::Array2<f64>, bg: &Background) {
    for zc in [150.0, 190.0] {
        for dr in [-6.0, 0.0, 6.0] {
            let rel = ring_errors(truth, bg, (250.3, zc, 75.0 + dr), 0..40, 0..512);
            let mean = mean(&rel);
            let rms = (rel.iter().map(|v| v * v).sum::<f64>() / rel.len() as f64).sqrt();
            println!("ring centre {zc} radius 75{dr:+}: mean {mean:+.4}, rms {rms:.4}");
            assert!(
                mean.abs() <= 0.003 && rms <= 0.012,
                "ring {zc} {dr}: mean {mean}, rms {rms}"
            );
        }
    }
}

#[test]
fn background_is_recovered_when_the_sphere_in_every_frame_has_a_speckled_glint() {
    // A polished ball shows the backlight in its middle, ragged at the
    // rim of the reflection: its dark pixels are a ring around many holes.
    // The holes' outlines are not the sphere's edge and must not pull the
    // circles that mask the sphere out of the background (they came out
    // 49 px in radius instead of 75, and the sphere's own edges stayed in
    // the background: 45 % off on the ring inside the edge). Eight
    // frames, as the tracker samples.
    let (truth, bg) = background_of_a_slow_glinting_drop(250.3, 24, (0.2, 25.0), 8, |_, _| 1.0);
    assert_rings_within_bounds(&truth, &bg);
}

#[test]
fn background_is_recovered_when_a_pale_sphere_is_in_every_frame() {
    // A sphere showing 40 % of the light (a polished ball reflecting its
    // surroundings), in view in every sample frame and moving less than
    // its diameter: the pixels no sample shows bare are bordered by a ring
    // that only the sphere's blurred edge uncovers. Taken for the light,
    // that ring made the coarse background half the light inside the
    // path, the pale sphere was not dark against it, and its mask came out
    // 9 px small in the first frame (28 % off inside the edge).
    let (truth, bg) = background_of_a_slow_glinting_drop(250.3, 24, (0.4, 0.0), 8, |_, _| 1.0);
    assert_rings_within_bounds(&truth, &bg);
}

/// A backlight that drifts differently on the left and on the right of the
/// frame (the real preset's slow drift, here 5 % and −2 % over the movie).
/// The sphere hides each pixel of its path in different frames, so with
/// one gain per frame each pixel's median mixes different frames' lights:
/// a step in the background along the path, which moves the edges (a
/// 2–3e-4 error of v_impact on the real preset). With the gain per column,
/// linear between the two reference strips, the background around the
/// sphere is the light's shape to the same 0.3 % as without drift (it was
/// 0.42 % off on the inner ring at the top).
#[test]
fn a_light_drifting_differently_on_the_two_sides_leaves_no_step_in_the_background() {
    let x = 130.3;
    let (truth, bg) = background_of_a_slow_drop(x, 23, |k, j| {
        let (left, right) = (0.05 * k as f64 / 23.0, -0.02 * k as f64 / 23.0);
        let u = j as f64 / 511.0;
        1.0 + (1.0 - u) * left + u * right
    });
    for zc in [150.0, 190.0] {
        for dr in [-6.0, 0.0, 6.0] {
            // Frame 0 has no drift: its light is the reference.
            let rel = ring_errors(&truth, &bg, (x, zc, 75.0 + dr), 20..60, 20..492);
            let (lower, upper) = rel.split_at(rel.len() / 2);
            let (mean, lower, upper) = (mean(&rel), mean(lower), mean(upper));
            println!("ring centre {zc} radius 75{dr:+}: mean {mean:+.4}, lower half {lower:+.4}, upper half {upper:+.4}");
            assert!(mean.abs() <= 0.003, "ring {zc} {dr}: mean {mean}");
            assert!(
                (lower - upper).abs() <= 0.003,
                "ring {zc} {dr}: halves {lower} {upper}"
            );
        }
    }
}
