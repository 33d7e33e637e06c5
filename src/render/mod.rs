//! `dropscope render`: synthetic drops with exact truth, written the way
//! Phantom Camera Control exports a recording (SPEC §4).
//!
//! | file | does |
//! | --- | --- |
//! | [`physics`] | the contact ODE, its events and the exact motion |
//! | [`contact`] | each drop's contact law: the model's, set, or drawn (`--contact wide`) |
//! | [`coverage`] | exact pixel coverage of disk, line and pillars |
//! | [`raster`] | one frame from the sphere centres over the exposure |
//! | [`optics`] | a real camera's effects: strengths per drop and set-up, roll and distortion |
//! | [`camera`] | one frame as a real camera records it (`--preset real`) |
//! | [`export`] | frame files, the PCC XML side file, `truth.json` |
//! | [`truth`] | the `truth.json` schema |
//! | `one_drop` | one drop, from its layout to its frames and `truth.json` ([`render_drop`]) |
//! | `options` | presets, [`RenderOptions`] and [`RenderSettings`] |
//! | [`campaign`] | the paper's grid and the `runs.csv` manifest |
//!
//! # Conventions
//!
//! Image number `n` (the camera's, negative before the trigger) has its
//! mid-exposure at `t = n / fps` after the trigger; motion blur integrates
//! over `[t − exposure/2, t + exposure/2]`. The first contact falls at a
//! random phase within image 0's frame interval, `t_contact ∈ [0, 1/fps)`,
//! as when a PCC user triggers on the impact; the movie starts
//! `frames_before` images earlier and ends `frames_after` images after the
//! loss of contact. The sphere falls straight down column `impact_column_px`;
//! the centre row is `z = y_s(x) − R_px + d / s` with `d` the signed depth of
//! the sphere's lowest point below the surface (physics) and `s` the scale.
//!
//! Randomness: every frame's noise comes from a ChaCha8 generator seeded by
//! `(seed, run, image number)`, the run's layout (contact phase, column,
//! surface row, pillar phase) from `(seed, run)`, the dust from `seed` alone.
//! Frames are rendered in parallel; the bytes do not depend on the number of
//! threads.

pub mod camera;
pub mod campaign;
pub mod contact;
pub mod coverage;
mod error;
pub mod export;
mod one_drop;
pub mod optics;
mod options;
pub mod physics;
pub mod raster;
mod rng;
pub mod truth;

pub use error::RenderError;
pub use one_drop::{default_mm_per_px, render_drop, DropSummary};
pub use options::{Preset, RenderOptions, RenderSettings};
pub use rng::rng_for;

use std::path::{Path, PathBuf};

use crate::dataset::manifest::ManifestRow;

/// What a render produced.
#[derive(Debug, Default)]
pub struct RenderReport {
    /// The drops rendered, in order.
    pub drops: Vec<DropSummary>,
    /// Runs that failed, with the reason; the others were still rendered.
    pub failures: Vec<(String, String)>,
    /// The `runs.csv` written for the drops, ready for `dropscope process --manifest`.
    pub manifest: Option<PathBuf>,
}

impl RenderReport {
    /// Frames written over every drop.
    pub fn frames(&self) -> usize {
        self.drops.iter().map(|d| d.frames).sum()
    }
}

/// Run `dropscope render`: every drop asked for, then the manifest.
/// A drop that fails is reported and the others carry on.
pub fn render(args: &RenderOptions) -> Result<RenderReport, RenderError> {
    render_with_progress(args, &mut |_, _, _| {})
}

/// [`render`], calling `progress(done, total, run)` after each drop.
pub fn render_with_progress(
    args: &RenderOptions,
    progress: &mut dyn FnMut(usize, usize, &str),
) -> Result<RenderReport, RenderError> {
    let settings = args.settings()?;
    let drops = args.drops()?;
    std::fs::create_dir_all(&args.out).map_err(|source| RenderError::CreateDir {
        path: args.out.clone(),
        source,
    })?;
    let mut report = RenderReport::default();
    for (k, spec) in drops.iter().enumerate() {
        progress(k, drops.len(), &spec.run);
        match render_drop(spec, &settings, &args.out) {
            Ok(d) => report.drops.push(d),
            Err(e @ RenderError::Export(_)) | Err(e @ RenderError::CreateDir { .. }) => {
                return Err(e)
            }
            Err(e) => report.failures.push((spec.run.clone(), e.to_string())),
        }
    }
    // The manifest of what was rendered, one drop or many, ready for
    // `dropscope process --manifest`; with --scaled-manifest the same rows
    // with the true scale beside it.
    let path = args.out.join("runs.csv");
    write_manifest(&path, &report, args, &settings, args.manifest_scale)?;
    report.manifest = Some(path);
    if args.scaled_manifest {
        write_manifest(
            &args.out.join("runs_scaled.csv"),
            &report,
            args,
            &settings,
            true,
        )?;
    }
    Ok(report)
}

/// Write the manifest of the rendered drops to `path`, with the true
/// `mm_per_px` when `with_scale`.
fn write_manifest(
    path: &Path,
    report: &RenderReport,
    args: &RenderOptions,
    settings: &RenderSettings,
    with_scale: bool,
) -> Result<(), RenderError> {
    let bytes = if settings.preset.is_real() {
        let rows: Vec<campaign::SetupManifestRow> = report
            .drops
            .iter()
            .map(|d| campaign::SetupManifestRow {
                run: d.run.clone(),
                path: export::run_input_path(&d.run, args.format),
                sphere_radius_mm: d.truth.sphere_radius_mm,
                drop_height_cm: d.truth.drop_height_cm,
                setup: d
                    .truth
                    .camera
                    .as_ref()
                    .map_or_else(String::new, |c| c.setup.clone()),
                mm_per_px: with_scale.then_some(d.truth.mm_per_px),
            })
            .collect();
        crate::dataset::csv_bytes(&rows)
    } else {
        let rows: Vec<ManifestRow> = report
            .drops
            .iter()
            .map(|d| ManifestRow {
                run: d.run.clone(),
                path: export::run_input_path(&d.run, args.format),
                sphere_radius_mm: d.truth.sphere_radius_mm,
                drop_height_cm: Some(d.truth.drop_height_cm),
                fps: Some(d.truth.fps),
                mm_per_px: with_scale.then_some(d.truth.mm_per_px),
                surface: Some(args.surface_name.clone()),
                sphere_density_kg_m3: Some(d.truth.sphere_density_kg_m3),
                setup: None,
                number_digits: None,
            })
            .collect();
        crate::dataset::manifest::to_csv_bytes(&rows)
    };
    crate::util::io::write_atomic(path, &bytes).map_err(|source| {
        RenderError::Export(export::ExportError::Io {
            path: path.to_path_buf(),
            source,
        })
    })
}
