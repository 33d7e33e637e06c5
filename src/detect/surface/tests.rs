use super::columns::*;
use super::step::*;
use super::*;
use crate::detect::background::Background;

/// Pixel-averaged values of a Gaussian-blurred profile made of levels
/// `levels[k]` on `[bounds[k], bounds[k + 1])` (rows grow down).
#[test]
fn two_clean_blurred_steps_are_found_exactly_at_any_phase_width_and_blur() {
    // A strip of its own level (brighter or darker) under the band's
    // top: the model is exact, so the fit must end on both edges to
    // rounding from a start up to half a pixel off, whatever the strip's
    // width (1.5–4 px, at least twice the blur's σ: a narrower one is
    // a valley the fit need not resolve) and level, or its Jacobian is
    // wrong.
    let (mut cases, mut swapped) = (0, 0);
    for &sigma in &[0.5, 0.75, 1.4] {
        for &(width, strip) in &[(1.5, 0.45), (2.5, 0.2), (4.0, 0.6)] {
            if width < 2.0 * sigma {
                continue;
            }
            cases += 5;
            for k in 0..5 {
                let e1 = 20.0 + k as f64 / 5.0;
                let e2 = e1 + width;
                let v = blurred(&[-1e3, e1, e2, 1e3], &[0.75, strip, 0.3], sigma, 40);
                let first = 14usize;
                let window = &v[first..(e2 as usize + 4)];
                let start = [e1.floor() + 0.5, e2.floor() + 0.5];
                // (`None`: the fit ended with its steps swapped.)
                let Some(row) = two_step_edge_row(window, first as f64, start) else {
                    swapped += 1;
                    continue;
                };
                assert!(
                    (row - e1).abs() < 1e-6,
                    "σ {sigma} w {width} e₁ {e1}: {row}"
                );
            }
        }
    }
    assert!(swapped * 10 <= cases, "{swapped} of {cases} swapped");
}

/// A glossy strip under the band's top, 8-bit-like levels, with
/// Gaussian noise of `noise` DN (seeded): the fits' real case, where the
/// residual at the minimum is not zero.
fn noisy_two_steps(e1: f64, width: f64, sigma: f64, noise: f64, seed: u64) -> Vec<f64> {
    use rand::SeedableRng;
    use rand_distr::Distribution;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let normal = rand_distr::Normal::new(0.0, noise).unwrap();
    blurred(
        &[-1e3, e1, e1 + width, 1e3],
        &[190.0, 120.0, 60.0],
        sigma,
        40,
    )
    .into_iter()
    .map(|x| x + normal.sample(&mut rng))
    .collect()
}

/// The two-step model of `window` (rows from `first`) at `θ = (e₁, e₂,
/// σ)`: its steps, the levels' Cholesky, the levels and the residuals.
fn two_steps_at(
    window: &[f64],
    first: usize,
    th: [f64; 3],
) -> (
    UnitStep,
    UnitStep,
    nalgebra::Cholesky<f64, nalgebra::U3>,
    nalgebra::Vector3<f64>,
    Vec<f64>,
) {
    let n = window.len();
    let (mut s1, mut s2) = (UnitStep::default(), UnitStep::default());
    s1.set(n, first as f64, th[0], th[2]);
    s2.set(n, first as f64, th[1], th[2]);
    let mut r = Vec::new();
    let (chol, levels) = two_step_levels(&s1.a, &s2.a, window, &mut r).unwrap();
    (s1, s2, chol, levels, r)
}

#[test]
fn the_two_step_jacobian_is_the_derivative_of_the_projected_residual() {
    // Central differences of r(θ) = A c(θ) − v against the analytic
    // rows, off the minimum on a noisy profile (at a noiseless one's
    // minimum r = 0 and the second-order term W vanishes: the clean
    // tests cannot see its sign).
    let first = 14usize;
    let v = noisy_two_steps(20.3, 2.5, 0.8, 3.0, 7);
    let window = &v[first..28];
    let n = window.len();
    let residual = |th: [f64; 3]| two_steps_at(window, first, th);
    let th = [20.6, 22.5, 1.1];
    let (s1, s2, chol, levels, r) = residual(th);
    let mut jac = Vec::new();
    two_step_jacobian([&s1, &s2], &levels, &chol, &r, &mut jac);
    let h = 1e-5;
    let mut largest: f64 = 0.0;
    let mut worst: f64 = 0.0;
    for j in 0..3 {
        let (mut up, mut down) = (th, th);
        up[j] += h;
        down[j] -= h;
        let (ru, rd) = (residual(up).4, residual(down).4);
        for k in 0..n {
            let fd = (ru[k] - rd[k]) / (2.0 * h);
            largest = largest.max(fd.abs());
            worst = worst.max((jac[k][j] - fd).abs());
        }
    }
    assert!(largest > 1.0, "a Jacobian to compare: {largest}");
    assert!(worst < 1e-6 * largest, "off by {worst} of {largest}");
}

/// A profile, the two-step fit's start and the end of its window.
type ProfileCase = (Vec<f64>, [f64; 2], usize);

/// Case `seed` of the strip tests: the top's true row, and two profiles
/// with 1.5 DN of noise, each with the two-step fit's start and the end
/// of its window (rows from 14): one blurred step started as if a strip
/// ended two rows below it (what the strip search finds in noise), and
/// a strip 3 px deep.
fn step_and_strip(seed: u64) -> (f64, [ProfileCase; 2]) {
    use rand::SeedableRng;
    use rand_distr::Distribution;
    let e1 = 20.0 + (seed % 5) as f64 / 5.0;
    let sigma = 0.6 + 0.1 * (seed % 4) as f64;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let normal = rand_distr::Normal::new(0.0, 1.5).unwrap();
    let one = blurred(&[-1e3, e1, 1e3], &[190.0, 60.0], sigma, 40)
        .into_iter()
        .map(|x| x + normal.sample(&mut rng))
        .collect();
    let strip = noisy_two_steps(e1, 3.0, sigma, 1.5, seed);
    (
        e1,
        [
            (one, [e1.floor() + 0.5, e1.floor() + 2.5], e1 as usize + 6),
            (
                strip,
                [e1.floor() + 0.5, (e1 + 3.0).floor() + 0.5],
                e1 as usize + 7,
            ),
        ],
    )
}

#[test]
fn a_single_noisy_step_is_not_taken_for_a_strip() {
    // The two-step model splits a single noisy step in two, and its
    // upper row is up to 0.4 px off; the F-test sends it to the
    // caller's one-step fit (`None`). A real strip under the same
    // noise is kept, its top row within the noise's reach.
    let first = 14usize;
    let (mut single, mut strips) = (0, 0);
    for seed in 0..40u64 {
        let (e1, [(one, start, end), (strip, strip_start, strip_end)]) = step_and_strip(seed);
        if two_step_edge_row(&one[first..end], first as f64, start).is_none() {
            single += 1;
        }
        let window = &strip[first..strip_end];
        if let Some(row) = two_step_edge_row(window, first as f64, strip_start) {
            assert!((row - e1).abs() < 0.25, "seed {seed}: {row} for {e1}");
            strips += 1;
        }
    }
    // At the test's 1 % level, about 0.4 of 40 single steps pass.
    assert!(
        single >= 38,
        "{} of 40 single steps taken for strips",
        40 - single
    );
    assert_eq!(strips, 40, "strips kept");
}

#[test]
fn a_two_step_fit_is_given_up_only_where_the_f_test_rejects_it() {
    // The strip tests' profiles, each fitted to its minimum and with the
    // give-up: a fit given up is one the F-test rejects at its minimum
    // (the noisy single steps), a fit not given up ends on the same
    // bits, and no strip is given up. The single steps' fits are given
    // up, in fewer iterations.
    let first = 14usize;
    let (mut given_up, mut strips_given_up) = (0, 0);
    let (mut iterations_full, mut iterations_given_up) = (0, 0);
    for seed in 0..40u64 {
        let (_, cases) = step_and_strip(seed);
        for (k, (v, start, end)) in cases.into_iter().enumerate() {
            let window = &v[first..end];
            let n = window.len();
            let full = fit_two_steps(window, first as f64, start, &mut || f64::INFINITY).unwrap();
            assert!(!full.gave_up);
            let cost_one = fit_one_step(window, first as f64, start[0]).unwrap().1;
            let limit = strip_cost_limit(cost_one, n);
            let early = fit_two_steps(window, first as f64, start, &mut || limit).unwrap();
            if early.gave_up {
                given_up += 1;
                strips_given_up += k;
                iterations_full += full.iterations;
                iterations_given_up += early.iterations;
                assert!(
                    !strip_is_resolved(cost_one, full.cost, n),
                    "seed {seed}: a fit the F-test keeps was given up"
                );
                assert!(early.cost > limit && early.cost >= full.cost);
            } else {
                let bits = |f: &TwoStepFit| (f.th.map(f64::to_bits), f.cost.to_bits());
                assert_eq!(bits(&early), bits(&full), "seed {seed}");
            }
        }
    }
    assert_eq!(strips_given_up, 0, "strips given up");
    assert!(given_up >= 35, "{given_up} of 40 single steps given up");
    assert!(
        2 * iterations_given_up < iterations_full,
        "{iterations_given_up} iterations given up against {iterations_full} to the minimum"
    );
}

#[test]
fn noisy_two_step_profiles_are_fitted_to_their_minimum() {
    // From half a pixel off, the fit ends before its limit of 60
    // iterations (7–18 here) where no small move of either edge or of
    // σ lowers the cost.
    let first = 14usize;
    let mut most = 0;
    for seed in 0..40u64 {
        let (e1, width, sigma) = (
            20.0 + (seed % 5) as f64 / 5.0,
            2.0 + (seed % 3) as f64,
            0.6 + 0.2 * (seed % 4) as f64,
        );
        let v = noisy_two_steps(e1, width, sigma, 2.0, seed);
        let window = &v[first..(e1 + width) as usize + 4];
        let start = [e1.floor() + 0.5, (e1 + width).floor() + 0.5];
        let TwoStepFit { th, iterations, .. } =
            fit_two_steps(window, first as f64, start, &mut || f64::INFINITY).unwrap();
        most = most.max(iterations);
        let cost = |th: [f64; 3]| {
            two_steps_at(window, first, th)
                .4
                .iter()
                .map(|x| x * x)
                .sum::<f64>()
        };
        let at = [th[0], th[1], th[2]];
        let c = cost(at);
        for j in 0..3 {
            for d in [-1e-4, 1e-4] {
                let mut moved = at;
                moved[j] += d;
                if j == 2 && !(0.2..=6.0).contains(&moved[2]) {
                    continue;
                }
                assert!(
                    cost(moved) >= c * (1.0 - 1e-12),
                    "seed {seed}: θ {at:?} is not a minimum along {j}"
                );
            }
        }
    }
    assert!(most < 60, "{most} iterations");
}

fn blurred(bounds: &[f64], levels: &[f64], sigma: f64, rows: usize) -> Vec<f64> {
    // Mean over the pixel of the blurred indicator of [a, b).
    let piece = |a: f64, b: f64, z: f64| {
        let f = |u: f64| sigma * (int_cdf((u - a) / sigma) - int_cdf((u - b) / sigma));
        f(z + 0.5) - f(z - 0.5)
    };
    (0..rows)
        .map(|i| {
            (0..levels.len())
                .map(|k| levels[k] * piece(bounds[k], bounds[k + 1], i as f64))
                .sum()
        })
        .collect()
}

fn both_rows(v: &[f64]) -> (f64, f64) {
    // The largest step, then the same windows as `column_edges` (w = 5).
    let zs = (0..v.len() - 1)
        .max_by(|&a, &b| (v[a] - v[a + 1]).total_cmp(&(v[b] - v[b + 1])))
        .unwrap();
    let (top, bot) = (zs - 5, zs + 6);
    let hi = 0.5 * (v[top] + v[top + 1]);
    let lo = 0.5 * (v[bot] + v[bot - 1]);
    let area = top as f64 - 0.5 + (top..=bot).map(|i| (v[i] - lo) / (hi - lo)).sum::<f64>();
    let step = step_edge_row(&v[top..=zs + 2], top as f64, zs as f64 + 0.5).unwrap();
    (step, area)
}

#[test]
fn a_clean_blurred_step_is_found_exactly_at_any_phase_and_blur() {
    // The model is exact for this profile, so only rounding remains.
    for &sigma in &[0.3, 0.6, 1.2, 2.5] {
        for k in 0..10 {
            let e = 20.0 + k as f64 / 10.0;
            let v = blurred(&[-1e3, e, 1e3], &[0.75, 0.34], sigma, 40);
            let (step, area) = both_rows(&v);
            assert!((step - e).abs() < 1e-6, "σ {sigma} e {e}: {step}");
            // The area method agrees on a clean step (its window holds ±3σ).
            if sigma <= 1.2 {
                assert!((area - e).abs() < 2e-3, "σ {sigma} e {e}: {area}");
            }
        }
    }
}

/// A background whose every column is `profile` (rows grow down).
fn background_of(profile: &[f64], width: usize) -> Background {
    let levels = profile
        .iter()
        .flat_map(|&v| std::iter::repeat_n(v as f32, width))
        .collect();
    Background {
        width,
        height: profile.len(),
        levels,
        region: Default::default(),
        gains: vec![1.0],
        near_cols: (0, width),
    }
}

#[test]
fn the_line_is_fitted_in_the_columns_near_the_sphere_whatever_the_others_hold() {
    // A tilted band top (0.01 rows a column), 400 columns; the line
    // taken in columns 100..300.
    let (w, h) = (400, 48);
    let mut bg = background_of(&vec![0.0; h], w);
    for j in 0..w {
        let e = 20.3 + 0.01 * j as f64;
        let v = blurred(&[-1e3, e, 1e3], &[200.0, 80.0], 0.8, h);
        for (i, v) in v.into_iter().enumerate() {
            bg.levels[i * w + j] = v as f32;
        }
    }
    bg.near_cols = (100, 300);
    let bits = |l: SurfaceLine| (l.row0_px.to_bits(), l.slope.to_bits(), l.n_used);
    let near = fit_surface(&bg, &SurfaceParams::default()).unwrap();
    assert!((near.row_at(200.0) - 22.3).abs() < 1e-3, "{near:?}");
    assert!((near.slope - 0.01).abs() < 1e-5, "{near:?}");
    assert_eq!(near.n_used, 200);
    // The other columns: a step 10 rows higher, noise, NaN.
    let mut x = 7u64;
    for i in 0..h {
        for j in (0..100).chain(300..w) {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
            bg.levels[i * w + j] = match (x >> 59, i < 12) {
                (0, _) => f32::NAN,
                (_, true) => 200.0 + (x >> 61) as f32,
                (_, false) => 60.0,
            };
        }
    }
    assert_eq!(
        bits(fit_surface(&bg, &SurfaceParams::default()).unwrap()),
        bits(near)
    );
    // Over every column, they move it (or leave no line).
    bg.near_cols = (0, w);
    let all = fit_surface(&bg, &SurfaceParams::default()).ok();
    assert_ne!(all.map(bits), Some(bits(near)));
}

#[test]
fn a_strip_below_the_band_top_brighter_or_darker_is_fitted_not_followed() {
    // Backlight 200 DN over a band at 0.7 of it, a glossy strip adding
    // 0.22 of the backlight over the band's top 3 px (σ = 0.8 px): the
    // step into the strip (16 DN) is a third of the strip's lower edge
    // (44 DN). The line is the band's top: the largest step would put it
    // at the strip's bottom, 3 px too low. Two blurred steps are this
    // profile's exact model: only f32 rounding remains.
    let e = 30.3;
    let v: Vec<f64> = blurred(&[-1e3, e, e + 3.0, 1e3], &[200.0, 184.0, 140.0], 0.8, 64)
        .into_iter()
        .collect();
    let line = fit_surface(&background_of(&v, 40), &SurfaceParams::default()).unwrap();
    assert!((line.row0_px - e).abs() < 0.001, "{}", line.row0_px);
    assert!(line.slope.abs() < 1e-9);
    // A strip darker than the backlight by more than the band below:
    // the top step is the largest, and the strip's edge is fitted too
    // (a single step's flank, which reaches 2 rows into the strip, was
    // 0.053 px off here).
    let v = blurred(&[-1e3, e, e + 3.0, 1e3], &[200.0, 160.0, 140.0], 0.8, 64);
    let line = fit_surface(&background_of(&v, 40), &SurfaceParams::default()).unwrap();
    assert!((line.row0_px - e).abs() < 0.001, "{}", line.row0_px);
    // A pillar-top row 25 % darker than the band over 1.4 px, σ = 0.65:
    // the step up out of it is found and fitted too (the flank fit of
    // the top step alone was 0.0xx px high here).
    let v = blurred(
        &[-1e3, e, e + 1.4, 1e3],
        &[200.0, 0.75 * 90.0, 90.0],
        0.65,
        64,
    );
    let line = fit_surface(&background_of(&v, 40), &SurfaceParams::default()).unwrap();
    assert!((line.row0_px - e).abs() < 0.001, "{}", line.row0_px);
}

#[test]
fn in_a_noisy_background_strips_are_fitted_and_noise_goes_to_the_one_step_fit() {
    // 300 columns of the band top at row 30.3 (σ = 0.8 px) with noise.
    // Plain, 1.5 DN (a background of few frames): the strip search fires
    // on the noise in most columns, and all of them but for the F-test's
    // 1 % take the one-step fit's row. With a glossy strip 3 px deep,
    // 0.5 DN: the columns where the search finds the strip from the
    // band's top keep the two-step fit, its top within 0.3 px and 0.03
    // on average, where the one-step fit is 0.2 px or more low.
    use rand::SeedableRng;
    use rand_distr::Distribution;
    let (e, cols, rows) = (30.3, 300, 64);
    let noisy = |bounds: &[f64], levels: &[f64], noise: f64, seed: u64| {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let normal = rand_distr::Normal::new(0.0, noise).unwrap();
        let mut bg = background_of(&blurred(bounds, levels, 0.8, rows), cols);
        for x in bg.levels.iter_mut() {
            *x += normal.sample(&mut rng) as f32;
        }
        bg
    };
    let params = SurfaceParams::default();
    let w = params.half_window;
    // Per column: the top step's row as `column_edges` finds it, whether
    // the strip search fires, and the one-step fit's row.
    let column = |bg: &Background, j: usize| {
        let step = |i: usize| bg.at(i, j) as f64 - bg.at(i + 1, j) as f64;
        let (best_row, best) = (w..rows - w - 1)
            .map(|i| (i, step(i)))
            .fold((0, f64::NEG_INFINITY), |a, b| if b.1 > a.1 { b } else { a });
        let zs = top_step_row(bg, j, w, best_row, best);
        let flank: Vec<f64> = (zs - w..=zs + 2).map(|i| bg.at(i, j) as f64).collect();
        let one = step_edge_row(&flank, (zs - w) as f64, zs as f64 + 0.5);
        (zs, strip_edge_row(bg, j, zs, best).is_some(), one)
    };
    let plain = noisy(&[-1e3, e, 1e3], &[200.0, 140.0], 1.5, 7);
    let (mut searched, mut one_step) = (0, 0);
    for edge in column_edges(&plain, &params) {
        let (_, strip, one) = column(&plain, edge.x_px as usize);
        searched += strip as usize;
        one_step += (strip && one.map(f64::to_bits) == Some(edge.row_px.to_bits())) as usize;
    }
    assert!(
        searched >= 200,
        "the strip search fired in {searched} columns"
    );
    assert!(
        100 * one_step >= 98 * searched,
        "{one_step} of {searched} columns with noise took the one-step fit"
    );
    let glossy = noisy(&[-1e3, e, e + 3.0, 1e3], &[200.0, 184.0, 140.0], 0.5, 8);
    let (mut fitted, mut sum_px, mut sum_one_px) = (0, 0.0, 0.0);
    for edge in column_edges(&glossy, &params) {
        let (zs, strip, one) = column(&glossy, edge.x_px as usize);
        if strip && (zs as f64 + 0.5 - e).abs() < 1.0 {
            fitted += 1;
            sum_px += edge.row_px - e;
            sum_one_px += one.unwrap_or(f64::NAN) - e;
            assert!((edge.row_px - e).abs() < 0.3, "{edge:?}");
        }
    }
    // The one-step fit's flank reaches into the strip: ~0.3 px low.
    let (mean_px, mean_one_px) = (sum_px / fitted as f64, sum_one_px / fitted as f64);
    assert!(fitted >= 200, "{fitted} columns with the strip fitted");
    assert!(mean_px.abs() < 0.03, "the strip's top {mean_px} px off");
    assert!(mean_one_px > 0.2, "the one-step fit {mean_one_px} px off");
}

#[test]
fn a_structured_band_top_moves_the_flank_fit_far_less_than_the_area_row() {
    // A darker top row (pillar tops edge-on, −25 % over 1.5 px) and a
    // glossy strip (+20 % of the backlight over 2.5 px) under σ = 0.8 px:
    // the area method is pulled by the band's inside, the flank fit much
    // less, and their disagreement is of the size of the area method's bias.
    let e = 20.3;
    let band = 0.34;
    for (levels, bounds) in [
        (vec![0.75, band * 0.75, band], vec![-1e3, e, e + 1.5, 1e3]),
        (vec![0.75, band + 0.15, band], vec![-1e3, e, e + 2.5, 1e3]),
    ] {
        let v = blurred(&bounds, &levels, 0.8, 40);
        let (step, area) = both_rows(&v);
        assert!((area - e).abs() > 0.15, "area {area}");
        assert!(
            (step - e).abs() < 0.5 * (area - e).abs(),
            "step {step} area {area}"
        );
        assert!(
            (step - area).abs() > 0.5 * (area - e).abs(),
            "step {step} area {area}"
        );
    }
}
