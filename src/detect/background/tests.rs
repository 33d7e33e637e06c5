#[test]
fn the_network_sorts_every_column_for_1_to_33_rows_at_any_width() {
    // Pseudo-random columns with ties, and +∞ (covered pixels): after
    // sort_rows each column must equal its sorted copy exactly.
    // Widths below and above the vector lanes (4 with SSE, 8 with AVX2),
    // so that the vector body and its tail both run; the portable loop
    // must give the same result as the one chosen at run time.
    let mut x = 12345u64;
    for (w, n) in [7usize, 37]
        .into_iter()
        .flat_map(|w| (1..=33).map(move |n| (w, n)))
    {
        let mut rows: Vec<f32> = (0..n * w)
            .map(|_| {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                match (x >> 60) as u8 {
                    0 => f32::INFINITY,
                    k => (k % 5) as f32 + 0.5 * (x >> 40 & 7) as f32,
                }
            })
            .collect();
        let mut want: Vec<Vec<f32>> = (0..w)
            .map(|j| (0..n).map(|k| rows[k * w + j]).collect())
            .collect();
        for c in want.iter_mut() {
            c.sort_by(f32::total_cmp);
        }
        let mut portable = rows.clone();
        super::sort_rows(&mut rows, w, &super::batcher_pairs(n));
        super::sort_rows_portable(&mut portable, w, &super::batcher_pairs(n));
        assert_eq!(rows, portable, "n = {n}, w = {w}");
        for (j, c) in want.iter().enumerate() {
            let got: Vec<f32> = (0..n).map(|k| rows[k * w + j]).collect();
            assert_eq!(&got, c, "n = {n}, w = {w}, column {j}");
        }
    }
    assert_eq!(super::batcher_pairs(8).len(), 19);
}

#[test]
fn the_gain_follows_a_light_that_drifts_differently_on_each_side() {
    // Background 1000 everywhere; the frame 4 % brighter on the left
    // strip's columns and 2 % darker on the right's, linear in between.
    let (w, h) = (100usize, 20usize);
    let flat = Array2::from_elem((h, w), 1000u16);
    let bg = Background::from_frames(&[flat.view()], GainRegion::default()).unwrap();
    let region = GainRegion::default();
    let (xl, xr) = (
        (region.strip_px - 2) as f64 / 2.0,
        (w - region.strip_px + w - 2) as f64 / 2.0,
    );
    let light = |j: f64| 1.04 + (j - xl) / (xr - xl) * (0.98 - 1.04);
    let frame = Array2::from_shape_fn((h, w), |(_, j)| (1000.0 * light(j as f64)).round() as u16);
    let g = bg.gain(&Band::frame(&frame).unwrap()).unwrap();
    for x in [xl, 30.0, 50.0, 77.5, xr] {
        let (at, sigma) = g.at(x);
        assert!(
            (at - light(x)).abs() < 1e-3,
            "x {x}: {at} against {}",
            light(x)
        );
        assert!(sigma < 1e-3, "{sigma}");
    }
    // Beyond the strips, the strip's own gain.
    assert!((g.at(-5.0).0 - g.at(xl).0).abs() < 1e-12);
    // Over both strips together, the mean: what a single gain would say.
    assert!((g.gain - 1.01).abs() < 1e-3, "{}", g.gain);
}

#[test]
fn median_of_odd_and_even_counts() {
    assert_eq!(super::median_of(&mut [3.0, 1.0, 2.0]), 2.0);
    assert_eq!(super::median_of(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
    assert_eq!(super::median_of(&mut [7.0]), 7.0);
}

use super::*;
use ndarray::Array2;

#[test]
fn flicker_is_divided_out_and_a_passing_speck_is_ignored() {
    let (h, w) = (40, 64);
    let truth = Array2::from_shape_fn((h, w), |(i, j)| 100.0 + i as f64 + 0.5 * j as f64);
    let gains = [1.0, 1.03, 0.97, 1.01, 0.99];
    let frames: Vec<Array2<u16>> = gains
        .iter()
        .enumerate()
        .map(|(k, g)| {
            let mut f = truth.mapv(|v| (v * g) as u16);
            if k == 2 {
                f[[20, 30]] = 0; // a speck in one frame
            }
            f
        })
        .collect();
    let views: Vec<_> = frames.iter().map(|f| f.view()).collect();
    let bg = Background::from_frames(
        &views,
        GainRegion {
            strip_px: 8,
            step: 1,
        },
    )
    .unwrap();
    for (k, g) in gains.iter().enumerate() {
        // Truncation to integers moves each gain by < 1/100 of a level.
        assert!(
            (bg.gains[k] - g).abs() < 0.01,
            "{k}: {} vs {g}",
            bg.gains[k]
        );
    }
    // Median of 5 gain-corrected values: within 1 level of the truth.
    assert!((bg.at(20, 30) as f64 - truth[[20, 30]]).abs() < 1.5);
    let band = Band::new(frames[1].slice(ndarray::s![10..30, ..]), 10).unwrap();
    let g = bg.gain(&band).unwrap();
    assert!((g.gain - 1.03).abs() < 0.01, "{g:?}");
    // Truncation residuals (≤ 1 level of ~130) give σ_g of order 1e-4.
    assert!(g.sigma > 0.0 && g.sigma < 1e-3, "{g:?}");
}
