use super::*;
use super::{ahead::*, kept::*, look::*, pass1::*, walk::*};
use crate::config::DetectConfig;
use crate::detect::synth::{self, PillarBand, Scene};
use crate::detect::{Background, Circle, CircleFit, EdgeParams, SurfaceLine};
use crate::source::memory::MemorySource;
use crate::source::SourceMeta;
use crate::source::{Frame, FrameSource, SourceError};
use crate::util::records::Record;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A frame whose dark shape gives no circle fails in words a user
/// reads (no circle, what dropscope measures), the fit's own after
/// them, not the fit's words alone.
#[test]
fn a_fit_without_a_circle_is_said_in_a_users_words() {
    let p = crate::detect::EdgePoint {
        x_px: 10.0,
        z_px: 20.0,
        weight: 1.0,
    };
    let source = crate::detect::circle::hyper_fit(&[p, p, p]).unwrap_err();
    let text = TrackError::Detect { frame: 12, source }.to_string();
    assert!(
        text.starts_with("frame 12: the dark shape there does not outline a circle (hyper circle fit: degenerate fit (all points coincide)); dropscope measures a sphere seen dark against a bright background"),
        "{text}"
    );
}

/// 20 frames of 256×192 px, 8-bit: a sphere of R = 40 px falling at
/// 3.1 px a frame (centre row 50 → 109, clear of the pillar band at
/// row ~170), blur 1 px, noise σ 2 levels, ±3 % flicker; with the
/// true centres.
fn movie() -> (MemorySource, Vec<(f64, f64)>) {
    let truth: Vec<(f64, f64)> = (0..20)
        .map(|k| (128.3 + 0.2 * k as f64, 50.17 + 3.1 * k as f64))
        .collect();
    let disks: Vec<_> = truth.iter().map(|&(x, z)| (x, z, 40.0)).collect();
    (rendered(&disks, 41), truth)
}

/// One 256×192 px 8-bit frame a disc `(x, z, r)`, frame numbers from
/// 0 at 10 000 frames/s: above the pillar band at row ~170, blur 1 px,
/// noise σ 2 levels, ±3 % flicker drawn from `seed`.
fn rendered(disks: &[(f64, f64, f64)], seed: u64) -> MemorySource {
    let disks: Vec<_> = disks.iter().copied().map(Some).collect();
    rendered_or_hidden(&disks, seed)
}

/// [`rendered`], with frames where the sphere is hidden (`None`).
fn rendered_or_hidden(disks: &[Option<(f64, f64, f64)>], seed: u64) -> MemorySource {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let frames = disks
        .iter()
        .map(|&disk| {
            let img = Scene {
                width: 256,
                height: 192,
                background: 200.0,
                vignetting: 0.1,
                sphere_transmission: 0.2,
                disk,
                band: Some(PillarBand {
                    row0_px: 170.4,
                    slope: 0.003,
                    pillar_level: 60.0,
                    channel_level: 90.0,
                    period_px: 40.0,
                    solid_fraction: 0.625,
                }),
                blur_px: 1.0,
            }
            .render();
            let gain = 1.0 + 0.03 * (2.0 * rng.gen::<f64>() - 1.0);
            synth::quantize(&img, gain, 255, || {
                // Box–Muller.
                let u1: f64 = rng.gen_range(f64::EPSILON..1.0);
                let u2: f64 = rng.gen();
                2.0 * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
            })
        })
        .collect();
    let meta = SourceMeta {
        width: 256,
        height: 192,
        bit_depth: 8,
        fps: 10_000.0,
        frame_numbers: (0..disks.len() as i64).collect(),
        ..SourceMeta::default()
    };
    MemorySource::new(meta, frames).unwrap()
}

fn settings() -> TrackSettings {
    TrackSettings::from_config(&DetectConfig::default())
}

/// 172 frames (see [`rendered`]): a sphere of R = 20 px rising from
/// row 130 on the parabola z = 130 − 7k + 0.04k² (frame k), out through
/// the top of the frame from frame ~25 to ~150 and back down to row
/// ~103.
fn away_movie() -> MemorySource {
    let disks: Vec<_> = (0..172).map(away_disk).collect();
    rendered(&disks, 7)
}

/// [`away_movie`]'s sphere in frame `k`: (x, z, r) px.
fn away_disk(k: usize) -> (f64, f64, f64) {
    let k = k as f64;
    (128.0 + 0.1 * k, 130.0 - 7.0 * k + 0.04 * k * k, 20.0)
}

/// `m` tracked with the frames while the sphere is away skipped and
/// with every frame looked at: the same track, bit for bit (the frames
/// not looked at hold no sphere, and a search of them finds none).
fn skipped_and_every(m: &mut MemorySource) -> (Track, Track) {
    let st = settings();
    let skipped = track(m, &st).unwrap();
    let every = track(
        m,
        &TrackSettings {
            skip_away: false,
            ..st.clone()
        },
    )
    .unwrap();
    let all = |t: &Track| -> Vec<FrameTrack> { t.frames.iter().collect() };
    assert_eq!(all(&skipped), all(&every));
    (skipped, every)
}

#[test]
fn frames_are_not_looked_at_while_the_sphere_is_away_above_the_frame() {
    let (skipped, every) = skipped_and_every(&mut away_movie());
    let all = |t: &Track| -> Vec<FrameTrack> { t.frames.iter().collect() };
    assert_eq!(every.away_frames, 0);
    // Out of view (its circle wholly above row 0) from frame 25 to 150:
    // the return predicted from the rise's parabola, less its last
    // quarter, is not looked at.
    let fitted: Vec<i64> = all(&skipped)
        .iter()
        .filter(|f| f.free.is_some())
        .map(|f| f.frame)
        .collect();
    let last_before = fitted.iter().copied().filter(|&k| k < 80).max().unwrap();
    let first_after = fitted.iter().copied().find(|&k| k > 80).unwrap();
    assert!((18..=26).contains(&last_before), "{last_before}");
    assert!((146..=156).contains(&first_after), "{first_after}");
    let away = (first_after - last_before - 1) as usize;
    assert!(
        skipped.away_frames >= away * 6 / 10 && skipped.away_frames <= away * 8 / 10,
        "{} of {away}",
        skipped.away_frames
    );
}

#[test]
fn after_a_long_rise_only_the_end_of_the_time_away_is_searched() {
    // A slow rise, z = 130 − 1.5k + 0.003k² (R = 20 px), fitted until
    // frame ~126 (a cap of 9 px); its lowest point leaves at frame 138.9
    // and is back at row −0.5 at frame 361.1. The parabola, from the
    // newer half of ~126 heights, predicts that return to well under
    // 1 %, so only the last 5 % of the time from the last fit is
    // searched (a quarter after `away_movie`'s rise of 12 heights); the
    // track is the same bits as with every frame looked at.
    let disks: Vec<_> = (0..480)
        .map(|k| {
            let k = k as f64;
            (128.0 + 0.05 * k, 130.0 - 1.5 * k + 0.003 * k * k, 20.0)
        })
        .collect();
    let (skipped, _) = skipped_and_every(&mut rendered(&disks, 11));
    let fitted: Vec<i64> = skipped
        .frames
        .iter()
        .filter(|f| f.free.is_some())
        .map(|f| f.frame)
        .collect();
    let last_before = fitted.iter().copied().filter(|&k| k < 250).max().unwrap();
    let first_after = fitted.iter().copied().find(|&k| k > 250).unwrap();
    assert!((115..=135).contains(&last_before), "{last_before}");
    assert!((361..=380).contains(&first_after), "{first_after}");
    let away = (361 - last_before) as usize;
    assert!(
        skipped.away_frames >= away * 90 / 100 && skipped.away_frames <= away,
        "{} of {away}",
        skipped.away_frames
    );
}

#[test]
fn a_cap_that_never_leaves_the_frame_is_looked_for_in_every_frame() {
    // A rise whose lowest point turns at row 4 (z = 130 − 1.5k +
    // 0.00386k², R = 20 px): the sphere is never wholly out of view, so
    // pass 1 skips none of its frames, whatever it finds of the cap.
    // (Before the return was the lowest point's root, the lost cap was
    // taken to be away until back at its last fit's height, and frames
    // where a search finds it were not looked at: another track.)
    let disks: Vec<_> = (0..400)
        .map(|k| {
            let k = k as f64;
            (128.0 + 0.05 * k, 130.0 - 1.5 * k + 0.00386 * k * k, 20.0)
        })
        .collect();
    let (skipped, _) = skipped_and_every(&mut rendered(&disks, 13));
    assert_eq!(skipped.away_frames, 0);
}

#[test]
fn a_rise_lost_and_found_on_its_way_out_still_predicts_the_return() {
    // `away_movie` with the sphere hidden in frames 12–13 and 17–18 of
    // its rise (each loss ends the following, each return is a search):
    // the heights before and after each loss are one rise, and the
    // frames while it is out of view are still not looked at.
    let disks: Vec<_> = (0..172)
        .map(|k| (!matches!(k, 12 | 13 | 17 | 18)).then(|| away_disk(k)))
        .collect();
    let (skipped, _) = skipped_and_every(&mut rendered_or_hidden(&disks, 7));
    let all = |t: &Track| -> Vec<FrameTrack> { t.frames.iter().collect() };
    let recovered = all(&skipped)
        .iter()
        .filter(|f| f.frame < 25 && f.flags.contains(Flag::Recovered))
        .count();
    assert_eq!(recovered, 2, "the two returns are searches");
    // Out of view from ~frame 25 to ~150, as in `away_movie`.
    assert!(
        (75..=100).contains(&skipped.away_frames),
        "{} frames away",
        skipped.away_frames
    );
}

/// `n` frames (see [`rendered`]) of a sphere of R = 20 px bouncing at
/// row 130 on [`away_movie`]'s parabola, 175 frames a bounce: out
/// through the top of the frame from ~25 to ~150 frames after each
/// bounce. It starts out of view, 60 frames into a rise (in view from
/// frame ~90).
fn bouncing_movie(n: usize) -> MemorySource {
    let disks: Vec<_> = (0..n)
        .map(|k| {
            let u = ((k + 60) % 175) as f64;
            (
                128.0 + 0.02 * k as f64,
                130.0 - 7.0 * u + 0.04 * u * u,
                20.0,
            )
        })
        .collect();
    rendered(&disks, 11)
}

/// A movie in memory that gives copies of itself as a file does, so
/// that pass 1 measures it ahead on other threads.
struct Shared(std::sync::Arc<MemorySource>);

impl FrameSource for Shared {
    fn meta(&self) -> &SourceMeta {
        self.0.meta()
    }

    fn read_rows_into(
        &mut self,
        index: usize,
        row0: usize,
        out: &mut ndarray::ArrayViewMut2<u16>,
    ) -> Result<(), SourceError> {
        let mut m: &MemorySource = &self.0;
        m.read_rows_into(index, row0, out)
    }

    fn try_clone(&self) -> Option<Box<dyn FrameSource>> {
        Some(Box::new(Shared(self.0.clone())))
    }
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

/// Out of view (before the sphere enters, and while it is away above
/// the frame) one frame in a stride is searched, and the track is the
/// same bits as with every frame searched: the frames left would have
/// found nothing, and each first find is still the first frame where a
/// search finds the sphere.
#[test]
fn out_of_view_one_frame_a_stride_is_searched_and_the_track_is_the_same() {
    for (mut m, least) in [(away_movie(), 20), (bouncing_movie(1100), 150)] {
        let st = settings();
        let probed = track(&mut m, &st).unwrap();
        let every = track(
            &mut m,
            &TrackSettings {
                probe_searches: false,
                ..st.clone()
            },
        )
        .unwrap();
        let all = |t: &Track| -> Vec<FrameTrack> { t.frames.iter().collect() };
        assert_eq!(format!("{:?}", all(&probed)), format!("{:?}", all(&every)));
        assert_eq!(every.unsearched_frames, 0);
        println!(
            "{} of {} frames not searched",
            probed.unsearched_frames,
            all(&probed).len()
        );
        assert!(
            probed.unsearched_frames >= least,
            "{}",
            probed.unsearched_frames
        );
    }
}

/// The sphere away six times (the first before it enters): on 1, 2 and
/// 3 threads, in rounds of chunks measured ahead that start while it is
/// away (and probe) or in view, the same track, bit for bit; on more
/// than one, frames are measured ahead and searched ahead on every
/// thread, and the frames not looked at are the same.
#[test]
fn a_sphere_away_again_and_again_is_tracked_the_same_on_any_threads() {
    let m = std::sync::Arc::new(bouncing_movie(1100));
    let st = TrackSettings {
        chunk_frames_max: 100,
        ..settings()
    };
    let tracked =
        |threads: usize| pool(threads).install(|| track(&mut Shared(m.clone()), &st).unwrap());
    let one = tracked(1);
    let frames = |t: &Track| -> Vec<FrameTrack> { t.frames.iter().collect() };
    let fitted = frames(&one).iter().filter(|f| f.free.is_some()).count();
    println!(
        "1 thread: {fitted} of 1 100 frames fitted, {} away",
        one.away_frames
    );
    // In view ~50 frames of each bounce's 175 and the first 90 out.
    assert!((250..=400).contains(&fitted), "{fitted} fitted");
    assert!(one.away_frames > 300, "{} away", one.away_frames);
    assert_eq!((one.measured_ahead, one.searched_ahead), (0, 0));
    // Out of view, one frame in a stride is searched.
    let stride = search_stride(m.meta().fps);
    println!(
        "stride {stride}: {} frames not searched",
        one.unsearched_frames
    );
    assert!(
        stride > 1 && one.unsearched_frames > 100,
        "{}",
        one.unsearched_frames
    );
    for threads in [2, 3] {
        let more = tracked(threads);
        println!(
            "{threads} threads: {} measured ahead, {} searched ahead",
            more.measured_ahead, more.searched_ahead
        );
        assert_eq!(
            format!("{:?}", frames(&more)),
            format!("{:?}", frames(&one))
        );
        assert_eq!(more.radius_px.to_bits(), one.radius_px.to_bits());
        assert_eq!(more.away_frames, one.away_frames);
        // Most frames in view are taken from the chunks; the frames
        // searched at the end of each time away, and before the
        // sphere enters, mostly from the searches on every thread.
        assert!(more.measured_ahead > fitted / 2, "{}", more.measured_ahead);
        assert!(more.searched_ahead > 60 / stride, "{}", more.searched_ahead);
        assert_eq!(more.unsearched_frames, one.unsearched_frames);
    }
}

/// A chunk measured ahead that starts with the sphere out of view
/// probes until it finds it, then sees in every frame from there what
/// a chunk searching every frame sees; of the frames before, it holds
/// a few searches, each what that chunk saw there.
#[test]
fn a_chunk_probes_until_it_finds_the_sphere_then_sees_every_frame() {
    let m = std::sync::Arc::new(bouncing_movie(300));
    let st = settings();
    let mut src = Shared(m.clone());
    let (bg, surface, _) = background_and_surface(&mut src, &st).unwrap();
    let ctx = Pass1::new(&bg, &surface, &st);
    let meta = m.meta().clone();
    // Chunks from frame 0 (out of view until ~90), 140 (away, back
    // at ~265) and 100 (in view).
    let bounds = [0, 0, 300, 140, 300, 100, 300];
    for k in [0, 2, 4] {
        let seen = |stride_max: usize| {
            let copies = std::sync::Mutex::new(vec![src.try_clone().unwrap()]);
            let pool = ScratchPool::default();
            speculate(&copies, &bounds[k..k + 3], &ctx, &meta, &pool, stride_max).remove(0)
        };
        let (every, probed) = (seen(1), seen(PROBE_STRIDE_MAX));
        let first = bounds[k + 1];
        assert_eq!(every.len(), 300 - first);
        assert!(every.iter().all(Option::is_some));
        let found = every
            .iter()
            .position(|s| s.as_ref().is_some_and(|s| s.found))
            .unwrap();
        let held = probed.iter().filter(|s| s.is_some()).count();
        println!(
            "chunk from {first}: found at {}, {held} held",
            first + found
        );
        assert_eq!(probed.len(), every.len());
        for (i, (p, e)) in probed.iter().zip(&every).enumerate() {
            match p {
                Some(p) => assert_eq!(
                    format!("{p:?}"),
                    format!("{:?}", e.as_ref().unwrap()),
                    "frame {i}"
                ),
                None => assert!(i < found, "frame {} left out", first + i),
            }
        }
        let before = probed[..found].iter().filter(|s| s.is_some()).count();
        if found > 64 {
            // A probe at most every PROBE_STRIDE_MAX frames, and the
            // frames searched again after the last empty one.
            let most = 6 + found / PROBE_STRIDE_MAX + PROBE_STRIDE_MAX;
            assert!(before <= most, "{before} of {found} held");
        } else {
            assert!(found < 8, "found at {found}");
        }
    }
}

#[test]
fn the_return_is_where_the_rise_s_parabola_comes_back() {
    // Lowest points of an exact parabola h = 70 − 3k + 0.01k² (frames k
    // of 0.1 ms, R = 20 px), the last fit at frame 20 (h = 14): it
    // leaves the frame at k = 25.7 and is back at row −0.5 (the top
    // edge of row 0) at k = 274.3; after a rise of 21 heights (10
    // fitted) the last quarter of that time is searched.
    let state_of = |h: &dyn Fn(f64) -> f64| {
        let mut state = Pass1State {
            following: true,
            ..Pass1State::default()
        };
        for k in 0..=20 {
            let t = k as f64 * 1e-4;
            let bottom = h(k as f64);
            state.rise.push_back((t, bottom));
            let circle = Circle {
                x_px: 100.0,
                z_px: bottom - 20.0,
                r_px: 20.0,
            };
            state.history = vec![(t, circle)];
        }
        state
    };
    let mut state = state_of(&|k| 70.0 - 3.0 * k + 0.01 * k * k);
    let entry = (3.0 + (9.0f64 - 4.0 * 0.01 * 70.5).sqrt()) / (2.0 * 0.01);
    assert!((entry - 274.3).abs() < 0.01, "{entry}");
    let back = state.back_in_view_s().unwrap();
    let expected = (20.0 + 0.75 * (entry - 20.0)) * 1e-4;
    assert!((back - expected).abs() < 1e-9, "{back} vs {expected}");
    // A rise whose lowest point stays in the frame (h = 70 − 3k +
    // 0.04k² turns at h = 13.75): a cap stays in view, none.
    assert_eq!(
        state_of(&|k| 70.0 - 3.0 * k + 0.04 * k * k).back_in_view_s(),
        None
    );
    // Lost in mid-frame (its top a radius or more below row 0): none.
    let last = state.history[0];
    state.history = vec![(
        last.0,
        Circle {
            z_px: 45.0,
            ..last.1
        },
    )];
    assert_eq!(state.back_in_view_s(), None);
    // Too short a rise: none.
    state.history = vec![last];
    state.rise.drain(..state.rise.len() - 15);
    assert_eq!(state.back_in_view_s(), None);
}

/// A state that has followed a rise of `n` lowest-edge heights
/// `h(k) = 326.5 − 3k + 0.004k²` (px, frame k of 0.1 ms) plus Gaussian
/// noise of `noise_px`, the last of them near the top of the frame
/// (h = 10.5 at k = 127), and the true time from the last one until
/// that point is back at row −0.5 (k = 617.6).
fn noisy_rise(n: usize, noise_px: f64, seed: u64) -> (Pass1State, f64) {
    use rand_distr::{Distribution, Normal};
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let normal = Normal::new(0.0, noise_px).unwrap();
    let h = |k: f64| 326.5 - 3.0 * k + 0.004 * k * k;
    let k0 = 128 - n;
    let mut state = Pass1State {
        following: true,
        ..Pass1State::default()
    };
    for k in k0..128 {
        let t = k as f64 * 1e-4;
        let z = h(k as f64) + normal.sample(&mut rng);
        state.rise.push_back((t, z));
        state.history = vec![(
            t,
            Circle {
                x_px: 100.0,
                z_px: z - 20.0,
                r_px: 20.0,
            },
        )];
    }
    // Back at row −0.5: the later root of h(k) + 0.5 = 0.
    let entry = (3.0 + (9.0f64 - 4.0 * 0.004 * 327.0).sqrt()) / (2.0 * 0.004);
    (state, (entry - 127.0) * 1e-4)
}

#[test]
fn the_return_s_standard_error_is_the_spread_of_noisy_rises() {
    // 400 rises of 128 heights with 0.3 px of noise (the newest 128
    // are fitted; the standard error is ~0.6 % of the time away): the
    // stated standard error of the time away against the spread of its
    // values (a standard error for heights of the fit's nominal 1 px
    // would be 3.3 times too large), and the truth within 5 of them.
    let (mut within_1, mut sum_err, mut sum_sq) = (0, 0.0, 0.0);
    let trials = 400;
    for seed in 0..trials {
        let (state, truth_s) = noisy_rise(128, 0.3, seed);
        let back = state.return_s().unwrap();
        assert_eq!(back.heights, 128);
        let off = back.away_s - truth_s;
        assert!(
            off.abs() < 5.0 * back.away_err_s,
            "seed {seed}: {off} vs {back:?}"
        );
        within_1 += usize::from(off.abs() < back.away_err_s);
        sum_err += back.away_err_s;
        sum_sq += off * off;
    }
    let stated = sum_err / trials as f64;
    let spread = (sum_sq / trials as f64).sqrt();
    assert!(
        (0.85..1.15).contains(&(stated / spread)),
        "stated {stated:.3e} s, spread {spread:.3e} s"
    );
    // 68 % within one standard error (±4.7 % at 2σ for 400 trials).
    assert!((240..306).contains(&within_1), "{within_1} of {trials}");
}

#[test]
fn a_bend_of_the_heights_by_their_systematic_error_moves_the_return_one_sigma() {
    // A 60 000 frames/s rise (frames of 1/60 ms): 128 exact heights h =
    // 10 + 0.5j + 0.00002j² (j = 127 − k) of the lowest point over 2.1
    // ms, bent by 0.3 px there and away for 0.4 s. Its stated
    // error is the systematic bend's alone; bending the heights by
    // RISE_SYSTEMATIC_PX·P₂ over the span moves the return by that.
    let state_of = |bend_px: f64| {
        let mut state = Pass1State {
            following: true,
            ..Pass1State::default()
        };
        for k in 0..128 {
            let (t, j) = (k as f64 / 60_000.0, 127.0 - k as f64);
            let u = -j / 127.0;
            let h = 10.0 + 0.5 * j + 0.00002 * j * j + bend_px * (6.0 * u * u + 6.0 * u + 1.0);
            state.rise.push_back((t, h));
            let circle = Circle {
                x_px: 100.0,
                z_px: h - 20.0,
                r_px: 20.0,
            };
            state.history = vec![(t, circle)];
        }
        state.return_s().unwrap()
    };
    let (exact, bent) = (state_of(0.0), state_of(RISE_SYSTEMATIC_PX));
    let moved = (bent.away_s - exact.away_s).abs();
    assert!(
        (0.9..1.1).contains(&(moved / exact.away_err_s)),
        "moved {moved:.3e} s, stated {:.3e} s",
        exact.away_err_s
    );
    // Here the bend is 5 % of the time away and more.
    assert!(exact.away_err_s > 0.05 * exact.away_s, "{exact:?}");
}

#[test]
fn the_search_starts_four_standard_errors_before_the_return_or_a_twentieth() {
    // Noisy enough that four standard errors are more than a twentieth
    // of the time away: the search starts 4σ early, before the truth
    // in every rise; exact heights: a twentieth early; a rise of fewer
    // than 24 heights (the newer half of 40): a quarter early.
    for seed in 0..100 {
        let (state, truth_s) = noisy_rise(128, 2.0, seed);
        let back = state.return_s().unwrap();
        assert!(AWAY_SEARCHED_SIGMAS * back.away_err_s > 0.05 * back.away_s);
        let start = state.back_in_view_s().unwrap();
        let expected = back.t_last_s + back.away_s - 4.0 * back.away_err_s;
        assert!((start - expected).abs() < 1e-12, "{start} vs {expected}");
        assert!(start < back.t_last_s + truth_s, "seed {seed}");
    }
    let (exact, truth_s) = noisy_rise(128, 1e-9, 0);
    let t_last = exact.return_s().unwrap().t_last_s;
    let start = exact.back_in_view_s().unwrap();
    assert!((start - (t_last + 0.95 * truth_s)).abs() < 1e-9, "{start}");
    let (short, truth_s) = noisy_rise(40, 1e-9, 0);
    assert_eq!(short.return_s().unwrap().heights, 20);
    let start = short.back_in_view_s().unwrap();
    assert!((start - (t_last + 0.75 * truth_s)).abs() < 1e-9, "{start}");
}

#[test]
fn pass_2_on_kept_points_matches_a_fresh_measurement_of_the_frame() {
    let (mut m, truth) = movie();
    let st = settings();
    let kept = track(&mut m, &st).unwrap();
    // Every frame's held circle lies within recentre_px of its normals'
    // centre here: no frame is read twice.
    assert_eq!(kept.reread_frames, 0);
    // recentre_px = 0 sends every frame of pass 2 back to the frame
    // (measured afresh around its free circle with the radius held),
    // as without kept points.
    let fresh_st = TrackSettings {
        edge: EdgeParams {
            recentre_px: 0.0,
            ..st.edge
        },
        ..st.clone()
    };
    let fresh = track(&mut m, &fresh_st).unwrap();
    let held = |t: &Track| -> Vec<CircleFit> {
        t.frames.iter().map(|f| f.held.expect("held fit")).collect()
    };
    let (a, b) = (held(&kept), held(&fresh));
    assert_eq!(fresh.reread_frames, b.len());
    let mut worst: (f64, f64, f64, f64) = (0.0, 0.0, 0.0, 0.0);
    let mut sigma_z = (f64::INFINITY, 0.0_f64);
    for (k, ((p, q), &(x, z))) in a.iter().zip(&b).zip(&truth).enumerate() {
        worst.0 = worst.0.max((p.z_px - z).abs()).max((p.x_px - x).abs());
        worst.1 = worst.1.max((q.z_px - z).abs()).max((q.x_px - x).abs());
        let dz = (p.z_px - q.z_px).abs();
        if k == 0 {
            worst.3 = dz;
        } else {
            worst.2 = worst.2.max(dz);
        }
        // σ_z: from the same kind of points, so close (within 30 %).
        let (sp, sq) = (p.cov.sigma_z_px(), q.cov.sigma_z_px());
        assert!((sp / sq - 1.0).abs() < 0.3, "σ_z {sp} vs {sq}");
        sigma_z = (sigma_z.0.min(sp), sigma_z.1.max(sp));
    }
    println!(
        "max |error| kept {:.4}, fresh {:.4}; max |Δz| {:.5} px, in the first frame {:.5} px; \
     σ_z {:.5}..{:.5} px",
        worst.0, worst.1, worst.2, worst.3, sigma_z.0, sigma_z.1
    );
    // Both well within the free-flight 95th-percentile target (0.06
    // px; measured max 0.015 px for either, x or z), and alike: the
    // schemes sample the same frame, with windows placed up to ~0.5 px
    // apart along the normals, which the estimator does not see, so
    // they differ by far less than the frame's noise moves a centre
    // (σ_z 0.005–0.009 px here; measured max |Δz| 0.0009 px). The
    // first frame's free circle, from the coarse start, is the farthest
    // from the held one, and its fresh windows the farthest from the
    // kept: there they differ by up to the frame's σ_z (measured |Δz|
    // 0.0050 px).
    assert!(worst.0 < 0.03 && worst.1 < 0.03, "{worst:?}");
    assert!(worst.2 < 0.002 && worst.3 < 0.0075, "{worst:?}");
}

#[test]
fn the_kept_points_never_hold_more_room_than_their_budget() {
    // Frames of 37 to 59 points into a budget that is no power of two:
    // plain doubling would end at 2 048 or 4 096 points.
    let max = 3_000;
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let (mut buf, mut grown) = (Vec::<[f32; 2]>::new(), 0);
    loop {
        let end = buf.len() + rng.gen_range(37..60);
        if end > max {
            break;
        }
        let cap = buf.capacity();
        reserve_within(&mut buf, end, max);
        grown += usize::from(buf.capacity() != cap);
        buf.resize(end, [0.0; 2]);
        assert!(buf.capacity() <= max, "{} > {max}", buf.capacity());
    }
    assert!(buf.len() > max - 60);
    // Still grown by doubling: a handful of reallocations, not one a frame.
    assert!(grown <= 10, "{grown} reallocations");
}

/// The quick look's grid found once gives `anything_dark`'s answer:
/// random levels and frames darkened at random, gains about 1, surface
/// lines flat, tilted, above and below the frame.
#[test]
fn the_dark_grid_answers_as_anything_dark() {
    let mut rng = ChaCha8Rng::seed_from_u64(16);
    let (h, w) = (61, 97);
    let bg = Background {
        width: w,
        height: h,
        levels: (0..h * w).map(|_| rng.gen_range(20.0..250.0f32)).collect(),
        region: Default::default(),
        gains: Vec::new(),
        near_cols: (0, w),
    };
    let (mut yes, mut no) = (0, 0);
    for (row0_px, slope) in [
        (45.3, 0.0),
        (30.0, 0.2),
        (70.0, -0.3),
        (-5.0, 0.0),
        (200.0, 0.0),
    ] {
        let surface = SurfaceLine::given(row0_px, slope);
        let grid = DarkGrid::new(&bg, &surface);
        for _ in 0..200 {
            let dark_share = [0.0, 0.0005, 0.002, 0.01, 0.3][rng.gen_range(0..5)];
            let frame = Frame::from_shape_fn((h, w), |(i, j)| {
                let level = bg.at(i, j);
                let f = if rng.gen::<f64>() < dark_share {
                    0.3
                } else {
                    0.9
                };
                (level * f) as u16
            });
            let gain = rng.gen_range(0.95..1.05);
            let want = anything_dark(&frame, &bg, gain, &surface);
            assert_eq!(grid.any_dark(&frame, &bg, gain, &surface), want);
            if want {
                yes += 1;
            } else {
                no += 1;
            }
        }
    }
    assert!(yes > 100 && no > 100, "{yes} dark, {no} not");
    // A frame of another size is looked at the plain way.
    let surface = SurfaceLine::given(50.0, 0.0);
    let other = Frame::zeros((h - 1, w));
    let grid = DarkGrid::new(&bg, &surface);
    assert!(grid.any_dark(&other, &bg, 1.0, &surface));
}

#[test]
fn a_frames_flags_are_written_in_one_order_whatever_the_order_set() {
    let mut f = FrameFlags::default();
    assert_eq!(f.text(), "");
    f.insert(Flag::Missing);
    f.insert(Flag::Recovered);
    assert!(f.contains(Flag::Missing) && !f.contains(Flag::Partial));
    assert_eq!(f.text(), "recovered missing");
    f.insert(Flag::Partial);
    f.insert(Flag::Missing);
    assert_eq!(f.text(), "recovered partial missing");
    assert_eq!(std::mem::size_of::<FrameFlags>(), 1);
}

#[test]
fn what_pass_1_keeps_of_a_frame_reads_back_from_its_bytes() {
    let c = Circle {
        x_px: 1.5,
        z_px: -0.0,
        r_px: 1e-300,
    };
    let all = [
        None,
        Some(Kept::Points {
            start: usize::MAX >> 1,
            len: 17,
            centre: c,
            radial_sigma_px: 0.25,
        }),
        Some(Kept::Again(Look::Search)),
        Some(Kept::Again(Look::At(c))),
        Some(Kept::Again(Look::Away)),
    ];
    for k in all {
        let mut bytes = Vec::new();
        k.put(&mut bytes);
        assert_eq!(bytes.len(), <Option<Kept> as Record>::BYTES);
        let back = <Option<Kept> as Record>::get(&bytes);
        assert_eq!(format!("{back:?}"), format!("{k:?}"));
    }
}

#[test]
fn a_frames_record_stays_within_its_bytes() {
    // A long movie's track holds one record a frame, pass 1 one `Kept`:
    // most of what its memory grows by (docs/performance.md: 256 + 56
    // bytes a frame).
    let (record, kept) = (
        std::mem::size_of::<FrameTrack>(),
        std::mem::size_of::<Option<Kept>>(),
    );
    assert!(record <= 256, "FrameTrack is {record} bytes");
    assert!(kept <= 56, "Option<Kept> is {kept} bytes");
}
