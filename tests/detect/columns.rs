//! Column windows: a band read as a window measures what whole rows do,
//! and a column gain pattern cancels in the edge points.

use super::*;

/// A band read as a column window (`Band::window`, as the tracker reads
/// wide frames: the columns within the band's reach of the prediction and
/// the flicker strips) measures the same bits as the same rows read whole,
/// whatever its other columns hold; and when the fit moves far from the
/// prediction (normals leave the window), still the same bits whatever they
/// hold: nothing outside the window is read.
#[test]
fn a_column_window_measures_what_whole_rows_do() {
    let (w, h) = (480, 200);
    let look = REALISTIC;
    let mut rng = ChaCha8Rng::seed_from_u64(77);
    let truth = (231.37, 92.81, 40.0);
    let s = scene(w, h, look, Some(truth), None);
    let bg = background(&s, look, &mut rng);
    let frame = shoot(&s, look, &mut rng);
    let params = EdgeParams::default();
    let strip = GainRegion::default().strip_px;
    let measure = |band: &Band, p: &Circle| {
        let mut es = EdgeScratch::default();
        let fit = measure_circle(band, &bg, p, None, None, &params, &mut es).ok();
        (fit, es.points)
    };
    for (dx, dz, far) in [(0.0, 0.0, false), (1.3, -0.8, false), (-9.0, 2.0, true)] {
        let p = Circle {
            x_px: truth.0 + dx,
            z_px: truth.1 + dz,
            r_px: truth.2 + 0.5,
        };
        let reach = p.r_px + params.half_window as f64 + 6.0;
        let span = |c: f64| {
            (
                (c - reach).floor() as usize,
                (c + reach).ceil() as usize + 1,
            )
        };
        let ((lo, hi), (left, right)) = (span(p.z_px), span(p.x_px));
        let rows = frame.slice(ndarray::s![lo..hi, ..]);
        let whole = measure(&Band::new(rows, lo).unwrap(), &p);
        assert!(whole.0.is_some(), "no fit at offset ({dx}, {dz})");
        let read = |c: usize| c < strip || (left..right).contains(&c) || c >= w - strip;
        let mut seen = Vec::new();
        for fill in [0u16, 255, 9999] {
            let mut band = rows.to_owned();
            for ((_, c), v) in band.indexed_iter_mut() {
                if !read(c) {
                    *v = fill;
                }
            }
            seen.push(measure(
                &Band::window(band.view(), lo, left..right).unwrap(),
                &p,
            ));
        }
        assert!(
            seen.iter().all(|m| *m == seen[0]),
            "offset ({dx}, {dz}): depends on unread columns"
        );
        if far {
            // Normals on the left side run out of the window: fewer points.
            assert!(seen[0].1.len() < whole.1.len(), "offset ({dx}, {dz})");
        } else {
            assert_eq!(seen[0], whole, "offset ({dx}, {dz})");
        }
    }
}

/// A sensor's column fixed pattern — a gain per column, here 3 % rms — is in
/// every frame and in the background alike and cancels pixel by pixel: the
/// edge points divide each sample by its own background: 0.002 px rms, 0.005
/// at worst, the 12-bit rounding of the patterned frames. (With `1/B`
/// interpolated linearly between a window's ends it would stay in every
/// sample of a window crossing columns: the edge points move by 0.17 px rms,
/// 0.37 px at worst, on this disk.) Noise-free frames, blur σ = 1 px.
#[test]
fn a_column_gain_pattern_cancels_in_the_edge_points() {
    let look = Look {
        blur_px: 1.0,
        noise: 0.0,
        flicker: 0.0,
        bits: 12,
    };
    let (w, h) = (160, 160);
    let mut rng = ChaCha8Rng::seed_from_u64(29);
    let column_gain: Vec<f64> = (0..w).map(|_| 1.0 + 0.03 * gauss(&mut rng)).collect();
    let truth = (80.3, 79.6, 50.0);
    // The edge points' radii about the true centre, with and without the
    // pattern.
    let radii = |pattern: bool| -> Vec<(f64, f64)> {
        let shot = |s: &Scene| {
            let mut img = s.render();
            if pattern {
                for ((_, j), v) in img.indexed_iter_mut() {
                    *v *= column_gain[j];
                }
            }
            synth::quantize(&img, 1.0, max_level(look), || 0.0)
        };
        let with_disk = scene(w, h, look, Some(truth), None);
        let empty = scene(w, h, look, None, None);
        let frames: Vec<Frame> = (0..4).map(|_| shot(&empty)).collect();
        let views: Vec<_> = frames.iter().map(|f| f.view()).collect();
        let bg = Background::from_frames(&views, GainRegion::default()).unwrap();
        let frame = shot(&with_disk);
        let band = Band::frame(&frame).unwrap();
        let predicted = Circle {
            x_px: truth.0 + 0.4,
            z_px: truth.1 - 0.3,
            r_px: truth.2 + 0.2,
        };
        let mut scratch = EdgeScratch::default();
        measure_circle(
            &band,
            &bg,
            &predicted,
            None,
            None,
            &EdgeParams::default(),
            &mut scratch,
        )
        .unwrap();
        scratch
            .points
            .iter()
            .map(|p| {
                let (dx, dz) = (p.x_px - truth.0, p.z_px - truth.1);
                (dz.atan2(dx), dx.hypot(dz))
            })
            .collect()
    };
    let (plain, patterned) = (radii(false), radii(true));
    assert_eq!(plain.len(), patterned.len());
    assert!(plain.len() > 90, "{} points", plain.len());
    let (mut worst, mut sum2): (f64, f64) = (0.0, 0.0);
    for (a, b) in plain.iter().zip(&patterned) {
        assert!((a.0 - b.0).abs() < 1e-3, "the same normals");
        worst = worst.max((a.1 - b.1).abs());
        sum2 += (a.1 - b.1).powi(2);
    }
    let rms = (sum2 / plain.len() as f64).sqrt();
    eprintln!("column gain pattern: edge points moved {rms:.4} px rms, {worst:.4} at worst");
    // 12-bit rounding of the patterned frames moves them by up to 0.005.
    assert!(worst < 0.01, "an edge point moved by {worst} px");
}
