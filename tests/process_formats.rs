//! `process` sees a recording as Phantom Camera Control shows it: the
//! viewer flips a cine records are applied, P10 codes are linearised, a
//! colour cine is read as its luminance, and the run's row says which
//! (`reading`). Rendered drops written as cines the way a camera stores
//! them are measured as the plain rendering is.

use std::path::{Path, PathBuf};

use crate::render::args;
use dropscope::config::{PipelineConfig, EMBEDDED_DEFAULT};
use dropscope::dataset::manifest::{read_manifest, RunSpec};
use dropscope::dataset::{DropRecord, DropStatus};
use dropscope::job::run_outputs::process_all;
use dropscope::source::cine_write::{CinePacking, CineSpec, CineWriter};
use dropscope::source::{open, Frame, OpenOptions};

fn config() -> PipelineConfig {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    PipelineConfig::from_toml_str(EMBEDDED_DEFAULT, Path::new("pipeline.toml"), &root).unwrap()
}

/// One drop (R 4.5 mm from 12 cm, seed 1, 12-bit) rendered as a cine into
/// `dir`, `extra` arguments added; its run.
fn render_cine(dir: &Path, extra: &[&str]) -> RunSpec {
    let mut a = vec![
        "--out",
        dir.to_str().unwrap(),
        "--drop",
        "4.5:12",
        "--bit-depth",
        "12",
        "--format",
        "cine",
    ];
    a.extend_from_slice(extra);
    dropscope::render::render(&args(&a)).unwrap();
    read_manifest(&dir.join("runs.csv")).unwrap().remove(0)
}

/// A run of a real recording: a 3 mm sphere, nothing else given but `fps`.
fn run_of(name: &str, path: PathBuf, fps: Option<f64>) -> RunSpec {
    RunSpec {
        run: name.into(),
        path,
        sphere_radius_mm: 3.0,
        drop_height_cm: None,
        fps,
        mm_per_px: None,
        surface: None,
        sphere_density_kg_m3: None,
        setup: None,
        review: Default::default(),
        number_digits: None,
    }
}

fn measure(run: &RunSpec, cfg: &PipelineConfig) -> DropRecord {
    let out = tempfile::tempdir().unwrap();
    process_all(std::slice::from_ref(run), cfg, out.path(), &|_| {})
        .unwrap()
        .remove(0)
}

/// The measured values and their one-sigma errors compared.
fn values(r: &DropRecord) -> [(&'static str, f64, f64); 4] {
    [
        (
            "v_impact",
            r.v_impact_m_s.unwrap(),
            r.v_impact_m_s_err.unwrap(),
        ),
        (
            "delta_max",
            r.delta_max_mm.unwrap(),
            r.delta_max_mm_err.unwrap(),
        ),
        ("a_max", r.a_max_mm.unwrap(), r.a_max_mm_err.unwrap()),
        ("tau_c", r.tau_c_ms.unwrap(), r.tau_c_ms_err.unwrap()),
    ]
}

/// A P10 cine holds the log-encoded codes of the 12-bit values (each the
/// nearest code of Vision Research's table, whose steps are 1–8 counts
/// below the white level): measured linearised, as `process` does by
/// default, every value lies within a quarter of the 12-bit render's one
/// sigma of it (seen: 1e-3 σ to 2e-3 σ). Measured on the codes
/// (`camera.p10_linear = false`), the edges are distorted by the log curve
/// and v_impact moves by more than half a sigma (seen: 1.2 σ).
#[test]
fn a_p10_render_measures_within_the_12_bit_renders_errors() {
    let d12 = tempfile::tempdir().unwrap();
    let dp10 = tempfile::tempdir().unwrap();
    let run12 = render_cine(d12.path(), &[]);
    let run10 = render_cine(dp10.path(), &["--packing", "p10"]);
    let src = open(&run10.path, &OpenOptions::default()).unwrap();
    assert!(src.meta().details.container.starts_with("P10"));
    let cfg = config();
    let r12 = measure(&run12, &cfg);
    let r10 = measure(&run10, &cfg);
    assert_eq!(r12.status, DropStatus::Ok, "{}", r12.reason);
    assert_eq!(r10.status, DropStatus::Ok, "{}", r10.reason);
    assert_eq!(
        (r12.reading.as_str(), r10.reading.as_str()),
        ("", "p10_linear")
    );
    for ((what, a, sigma), (_, b, _)) in values(&r12).into_iter().zip(values(&r10)) {
        assert!(
            (a - b).abs() <= 0.25 * sigma,
            "{what}: P10 {b} against 12-bit {a} ± {sigma}"
        );
    }
    let mut codes = cfg.clone();
    codes.camera.p10_linear = false;
    let rc = measure(&run10, &codes);
    assert_eq!(rc.reading, "p10_codes");
    let (_, v12, s12) = values(&r12)[0];
    let (_, vc, _) = values(&rc)[0];
    assert!(
        (vc - v12).abs() > 0.5 * s12,
        "measured on its codes the P10 drop gave v {vc} against {v12} ± {s12}"
    );
}

/// The rendered drop rewritten with the project's cine writer the way a
/// camera set to show its picture flipped stores it: rows in the opposite
/// order and `bFlipV = 1`. `process` applies the flip (as PCC shows the
/// picture) and measures exactly what it measures on the upright cine;
/// told not to (`camera.apply_flips = false`) it sees the scene upside down
/// and fails, asking whether the picture is upside down.
#[test]
fn a_cine_stored_upside_down_with_bflipv_measures_as_the_upright_one() {
    let dir = tempfile::tempdir().unwrap();
    let upright = render_cine(dir.path(), &[]);
    let mut src = open(&upright.path, &OpenOptions::default()).unwrap();
    let m = src.meta().clone();
    let flipped_path = dir.path().join("flipped.cine");
    let spec = CineSpec {
        width: m.width,
        height: m.height,
        frame_count: m.frame_count,
        packing: CinePacking::Gray16,
        bit_depth: 12,
        fps: m.fps,
        exposure_s: m.exposure_s.unwrap(),
        first_image_no: m.first_frame as i32,
        timestamps_s: Some((0..m.frame_count).map(|i| m.time_s(i).unwrap()).collect()),
        flip_v: true,
        ..CineSpec::default()
    };
    let mut w = CineWriter::create(&flipped_path, &spec).unwrap();
    let mut f = Frame::zeros((m.height, m.width));
    for i in 0..m.frame_count {
        src.read_into(i, &mut f).unwrap();
        let upside_down = f.slice(ndarray::s![..;-1, ..]).to_owned();
        w.write_frame(&upside_down).unwrap();
    }
    w.finish().unwrap();
    let flipped = RunSpec {
        run: "flipped".into(),
        path: flipped_path,
        ..upright.clone()
    };
    let cfg = config();
    let a = measure(&upright, &cfg);
    let b = measure(&flipped, &cfg);
    assert_eq!(a.status, DropStatus::Ok, "{}", a.reason);
    assert_eq!(b.status, a.status, "{}", b.reason);
    for ((what, x, _), (_, y, _)) in values(&a).into_iter().zip(values(&b)) {
        assert_eq!(x, y, "{what}");
    }
    assert_eq!(a.surface_row_px, b.surface_row_px);
    assert_eq!((a.reading.as_str(), b.reading.as_str()), ("", "flip_v"));
    let mut storage = cfg.clone();
    storage.camera.apply_flips = false;
    let c = measure(&flipped, &storage);
    assert_eq!(c.status, DropStatus::Failed, "{c:?}");
    assert!(
        c.reason.contains("is the picture upside down?")
            || c.reason.contains("no surface line in the background"),
        "the reason asks about orientation or finds no surface: {}",
        c.reason
    );
    assert_eq!(c.reading, "flips_not_applied");
}

/// The real Wuppertal frames show a liquid drop resting on a dark
/// substrate (SOURCE.md there: substrate top at row 183-184, the picture
/// upright). No sphere is measured there, and the failure does not ask
/// whether the picture is upside down: its darkest rows are at the bottom.
#[test]
fn an_upright_drop_on_a_dark_substrate_is_not_called_upside_down() {
    let run = run_of(
        "wuppertal",
        crate::real_footage("wuppertal-drop-120fps/frames"),
        Some(120.0),
    );
    let r = measure(&run, &config());
    assert_eq!(r.status, DropStatus::Failed, "{r:?}");
    assert!(r.reason.contains("no sphere found whole"), "{}", r.reason);
    assert!(!r.reason.contains("upside down"), "{}", r.reason);
    assert_eq!(r.reading, "");
}

/// The real colour cine `pycine/chart1.cine` (raw Bayer GBRG, P10, one
/// frame of a test chart): `process` reads it, as its luminance with its
/// codes linearised, and its row says so; it fails for what it holds (one
/// frame is no drop), not for its format.
#[test]
fn a_colour_cine_is_processed_as_its_luminance_and_its_row_says_so() {
    let run = run_of("chart1", crate::phantom_sample("pycine/chart1.cine"), None);
    let r = measure(&run, &config());
    assert_eq!(r.status, DropStatus::Failed);
    assert_eq!(r.reading, "bayer_gbrg_luminance p10_linear");
    assert!(
        r.reason
            .contains("only 1 frames: too short a movie to find a drop in"),
        "{}",
        r.reason
    );
    let mut codes = config();
    codes.camera.p10_linear = false;
    assert_eq!(
        measure(&run, &codes).reading,
        "bayer_gbrg_luminance p10_codes"
    );
}

/// `--packing` packs a 12-bit cine: asked of anything else, `render`
/// refuses, naming the option and what to add.
#[test]
fn packing_is_refused_for_anything_but_a_12_bit_cine() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let refusal = |extra: &[&str]| {
        let mut a = vec!["--out", out, "--drop", "4.5:12"];
        a.extend_from_slice(extra);
        dropscope::render::render(&args(&a))
            .unwrap_err()
            .to_string()
    };
    assert_eq!(
        refusal(&["--packing", "p10", "--bit-depth", "12"]),
        "render option `--packing` = p10: packs the samples of a .cine: add --format cine"
    );
    assert_eq!(
        refusal(&["--packing", "p12l", "--format", "cine", "--bit-depth", "8"]),
        "render option `--packing` = p12l: packs 12-bit frames: add --bit-depth 12"
    );
    assert!(std::fs::read_dir(dir.path()).unwrap().next().is_none());
}
