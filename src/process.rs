//! `dropscope process`: every run → track → events → kinematics → one row
//! of `drops.csv`, `tracks/<run>.csv`, an overlay at maximum penetration
//! (`plots/overlays/<run>.png`) and the animated impact
//! (`plots/impacts/<run>.png`). Runs are processed in parallel; a run that
//! cannot be measured gets a `failed` row with its reason and never stops
//! the others. Every file is written whole or not at all.

use crate::cache::OutputFile;
use crate::config::PipelineConfig;
use crate::dataset::{DropRecord, TrackRow};
use crate::events::{EventConfig, Geometry, TrackPoint};
use crate::io_util::{Durable, Spool};
use crate::lens::{undistort_track, Lens};
use crate::manifest::RunSpec;
use crate::measure::{annotate_track, measure_drop, measure_drop_with, DropInfo};
use crate::quality;
use crate::scale::{free_fall_curvature, Curvature, ScaleInputs};
use crate::setup_infer::SceneSignature;
use crate::shelf::{Shelf, ShelvedTrack};
use crate::source::open;
use crate::stage_settings::open_options;
use crate::track::{track, FrameTrack, Track, TrackSettings};
use rayon::prelude::*;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The command line of `dropscope process`.
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("runs").required(true).args(["inputs", "manifest"])))]
pub struct ProcessArgs {
    /// Run folders (PCC exports) or `.cine` files, one drop each, or
    /// folders holding them (searched at any depth; each run found is a drop).
    pub inputs: Vec<PathBuf>,
    /// A runs.csv manifest (columns: docs/outputs.md) instead of INPUTs.
    #[arg(long)]
    pub manifest: Option<PathBuf>,
    /// Output folder (default: the configuration's output.dir).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// The configuration file (default: ./pipeline.toml, else the embedded default).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Sphere radius for INPUTs (default: the configuration's sphere.radius_mm).
    #[arg(long, value_parser = crate::cli_values::positive, allow_negative_numbers = true)]
    pub radius_mm: Option<f64>,
    #[command(flatten)]
    pub recording: crate::cli_values::RecordingArgs,
    /// Also draw the overlay of these camera image numbers (comma-separated,
    /// e.g. `-5,0,12`) for every run: `plots/overlays/<run>_<number>.png`.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub overlay_frames: Vec<i64>,
    /// Reprocess every run, even those whose result from an earlier job
    /// into this folder (OUT/runs/<run>.json) is still valid.
    #[arg(long)]
    pub force: bool,
    /// Worker threads (default: one per core).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,
    /// Draw no animated impact (`plots/impacts/<run>.png`, about 0.5 MB a
    /// drop): the configuration's `output.animation = false`.
    #[arg(long)]
    pub no_animation: bool,
    /// Measure the frames in storage orientation, without the viewer flips
    /// a .cine or Photron header records: the configuration's
    /// `camera.apply_flips = false`.
    #[arg(long)]
    pub no_flips: bool,
    /// Measure P10 cines on their log-encoded 10-bit codes, not linearised:
    /// the configuration's `camera.p10_linear = false`.
    #[arg(long)]
    pub p10_codes: bool,
    /// After the job, print on stderr where its time went: wall and CPU
    /// seconds per stage (reading, tracking passes, force fits, pictures,
    /// writes, …) summed over runs, each stage's share and its mean per
    /// drop. Changes no output.
    #[arg(long)]
    pub timings: bool,
}

/// The outcome of one run.
#[derive(Debug)]
pub struct RunOutcome {
    pub record: DropRecord,
    /// The track CSV's bytes (none for a run that failed): past
    /// [`TRACK_CSV_IN_MEMORY_MAX`], in a temporary file.
    pub track_csv: Spool,
    /// Its rows (one a frame of the movie).
    pub track_rows: usize,
    /// PNG bytes of the overlay at maximum penetration.
    pub overlay: Option<Vec<u8>>,
    /// Overlays of the frames asked for: (image number, PNG bytes).
    pub frame_overlays: Vec<(i64, Vec<u8>)>,
    /// The animated overlay of the impact (animated PNG bytes).
    pub impact: Option<Vec<u8>>,
    /// What the run's images say of its camera set-up (kept in the cache
    /// for [`prepare`]).
    pub scene: Option<SceneSignature>,
    /// Seconds spent on this run (tracking and measuring), for the speed
    /// shown to the user; no output depends on it.
    pub seconds: f64,
    /// What reading its input should say once as a warning (a colour input
    /// read as grey, frame names read one of two ways:
    /// [`crate::source::SourceMeta::reading_notes`]).
    pub notes: Vec<String>,
}

/// The most bytes of a run's track CSV held in memory (~11 000 frames'
/// rows); a longer track goes to a temporary file as it is made, and from
/// there to its output file (a 124 166-frame movie's is 11 MB).
pub const TRACK_CSV_IN_MEMORY_MAX: usize = 1 << 20;

/// Why the command could not run at all (a bad run is a row, not this).
#[derive(Debug, thiserror::Error)]
pub enum ProcessError {
    #[error("{path}: cannot write: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{0}")]
    Usage(String),
    /// An INPUT named on the command line cannot be a run: it is not
    /// there, or is neither a folder nor a `.cine` file. Found before the
    /// output folder is created or touched, so a mistyped path never
    /// replaces the results already in it.
    #[error("{path}: {why}; nothing was written")]
    Input { path: PathBuf, why: String },
}

/// The runs named on the command line: each INPUT one run named after its
/// folder or `.cine` file ([`crate::run_name::from_input`]), with the radius
/// from `--radius-mm` or the configuration. An INPUT that is not there, or
/// is neither a folder nor a cine ([`crate::source::input_kind`]), is an
/// error ([`ProcessError::Input`]), not a run: what is inside an input is
/// the run's to find (a bad one gets a `failed` row), but a path on the
/// command line that names nothing is a mistake in the command.
pub fn runs_from_inputs(
    inputs: &[PathBuf],
    radius_mm: Option<f64>,
    cfg: &PipelineConfig,
) -> Result<Vec<RunSpec>, ProcessError> {
    let r = radius_mm
        .or(cfg.sphere.radius_m.map(|r| r * 1e3))
        .ok_or_else(|| {
            ProcessError::Usage(
                "no sphere radius: give --radius-mm, set sphere.radius_mm in pipeline.toml, or use a --manifest"
                    .into(),
            )
        })?;
    if !(r.is_finite() && r > 0.0) {
        return Err(ProcessError::Usage(format!(
            "--radius-mm {r}: must be a number greater than 0"
        )));
    }
    // Names must be unique (they name the output files): a repeated folder
    // name from another parent gets `_2`, `_3`, ….
    let mut runs: Vec<RunSpec> = Vec::with_capacity(inputs.len());
    for p in inputs {
        check_input(p)?;
        let base = crate::run_name::from_input(p);
        let mut run = base.clone();
        let mut k = 1;
        while runs.iter().any(|r| r.run == run) {
            k += 1;
            run = format!("{base}_{k}");
        }
        runs.push(RunSpec {
            run,
            path: p.clone(),
            sphere_radius_mm: r,
            drop_height_cm: None,
            fps: None,
            mm_per_px: None,
            surface: None,
            sphere_density_kg_m3: None,
            setup: None,
            review: Default::default(),
            number_digits: None,
        });
    }
    Ok(runs)
}

/// `Ok` when `path` can be a run by its kind ([`crate::source::input_kind`]),
/// else why not ([`ProcessError::Input`]).
fn check_input(path: &Path) -> Result<(), ProcessError> {
    use crate::source::SourceError;
    let why = match crate::source::input_kind(path) {
        Ok(_) => return Ok(()),
        Err(SourceError::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => {
            "does not exist (each INPUT is a run folder, a .cine file or a folder of runs)"
                .to_string()
        }
        Err(SourceError::Io { source, .. }) => source.to_string(),
        Err(SourceError::Unsupported { reason, .. }) => reason,
        Err(e) => e.to_string(),
    };
    Err(ProcessError::Input {
        path: path.to_path_buf(),
        why,
    })
}

/// Process one run; never fails: problems become a `failed` record, and so
/// does a panic in any stage (caught here, at the run's boundary, so that
/// one bad input never ends the job).
pub fn process_run(run: &RunSpec, cfg: &PipelineConfig, overlay_frames: &[i64]) -> RunOutcome {
    process_setup(&[run], cfg, overlay_frames, Vec::new())
        .pop()
        .expect("one outcome per run")
}

/// Process runs that share one camera set-up (the manifest's `setup`
/// column; a run without one is a set-up of its own): each is tracked, the
/// curvatures of their free flights are pooled into one scale (see
/// [`crate::scale`]), and each is measured with it. Never fails: a run that
/// cannot be measured, or panics, gets a `failed` record; the outcomes come in `runs`'
/// order.
///
/// `kept` holds, member by member, the track [`prepare`] made of it, if
/// any: taken off its shelf rather than made again (the same track).
pub fn process_setup(
    runs: &[&RunSpec],
    cfg: &PipelineConfig,
    overlay_frames: &[i64],
    mut kept: Vec<Option<KeptRun>>,
) -> Vec<RunOutcome> {
    kept.resize_with(runs.len(), || None);
    let (tracked, track_s): (Vec<Result<Tracked, RunFailure>>, Vec<f64>) = runs
        .par_iter()
        .zip(kept)
        .map(|(r, kept)| {
            let start = std::time::Instant::now();
            let t = kept
                .and_then(|k| k.restore(r, cfg))
                .unwrap_or_else(|| caught(r, || track_run(r, cfg)));
            (t, start.elapsed().as_secs_f64())
        })
        .unzip();
    // A drop a person rejected is left out of its set-up's scale and of
    // the comparison of its apparent sizes.
    let pooled_in = |r: &&RunSpec| r.review.rejected.is_none();
    let curvatures: Vec<Curvature> = tracked
        .iter()
        .zip(runs)
        .filter(|(_, r)| pooled_in(r))
        .filter_map(|(t, _)| t.as_ref().ok()?.curvature)
        .collect();
    let pool = |curvatures: Vec<Curvature>| {
        (curvatures.len() >= 2)
            .then(|| crate::scale::pool(&curvatures))
            .flatten()
    };
    let pooled_at_bound = pool(
        tracked
            .iter()
            .zip(runs)
            .filter(|(_, r)| pooled_in(r))
            .filter_map(|(t, _)| t.as_ref().ok()?.bounded.as_ref()?.curvature)
            .collect(),
    );
    let pooled = pool(curvatures);
    // The members' apparent sizes per mm, compared once all are measured.
    let sizes: Vec<Option<crate::scale::ApparentSize>> = tracked
        .iter()
        .zip(runs)
        .map(|(t, r)| {
            let t = t.as_ref().ok().filter(|_| pooled_in(r))?;
            Some(crate::scale::ApparentSize {
                r_app_px: t.tr.radius_px,
                r_app_err_px: t.tr.radius_err_px,
                radius_mm: r.sphere_radius_mm,
            })
        })
        .collect();
    let mut outcomes: Vec<RunOutcome> = runs
        .par_iter()
        .zip(tracked)
        .zip(track_s)
        .map(|((run, t), track_s)| {
            let start = std::time::Instant::now();
            let recording = match &t {
                Ok(t) => Some(t.recording()),
                Err(f) => f.recording.clone(),
            };
            let mut o = caught(run, || {
                let _timed = crate::timings::start(crate::timings::Stage::Events);
                measure_run(
                    t.map_err(|f| f.reason)?,
                    run,
                    cfg,
                    [pooled, pooled_at_bound],
                    overlay_frames,
                )
            })
            .unwrap_or_else(|reason| failed_outcome(run, cfg, reason, recording.as_ref()));
            if let Some(reason) = non_finite(&o.record) {
                o = failed_outcome(run, cfg, reason, recording.as_ref());
            }
            o.seconds = track_s + start.elapsed().as_secs_f64();
            o
        })
        .collect();
    if runs.len() >= 2 {
        let found = crate::scale::size_disagreements(
            &sizes,
            crate::scale::EdgeOffset::from_config(&cfg.camera),
        );
        for ((o, run), d) in outcomes.iter_mut().zip(runs).zip(found) {
            if let Some(d) = d {
                let setup = run.setup.as_deref().unwrap_or("-");
                quality::flag(
                    &mut o.record,
                    quality::RADIUS_DISAGREEMENT,
                    d.sentence(setup),
                );
            }
        }
    }
    // The review's decisions last, on the row with every flag.
    for (o, run) in outcomes.iter_mut().zip(runs) {
        run.review.apply(&mut o.record);
    }
    outcomes
}

/// Why a measured record cannot stand: a number in it that is not finite
/// (an input value far out of range overflowed). `None` when all are.
fn non_finite(record: &DropRecord) -> Option<String> {
    if record.status == crate::dataset::DropStatus::Failed {
        return None;
    }
    let columns = record.non_finite_columns();
    (!columns.is_empty()).then(|| {
        format!(
            "the measurement gave a number that is not finite in {}: an input value (density, \
             radius, frame rate, scale) is out of any physical range",
            columns.join(", ")
        )
    })
}

/// Run `work` for `run`: its panic becomes an error naming the input.
fn caught<T, E: From<String>>(run: &RunSpec, work: impl FnOnce() -> Result<T, E>) -> Result<T, E> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(work))
        .unwrap_or_else(|payload| Err(panic_reason(&run.path, payload.as_ref()).into()))
}

/// Why a run could not be tracked, with what is known of its recording
/// once it was opened.
#[derive(Debug, Clone, PartialEq)]
struct RunFailure {
    reason: String,
    recording: Option<Recording>,
}

impl From<String> for RunFailure {
    fn from(reason: String) -> Self {
        RunFailure {
            reason,
            recording: None,
        }
    }
}

/// What a run's row says of its recording, failed or not.
#[derive(Debug, Clone, PartialEq)]
struct Recording {
    /// Its frames (the track's rows; the summary's frames read).
    frames: usize,
    fps: f64,
    /// The `fps_source` word ([`open_run`]).
    fps_source: String,
}

/// The `failed` outcome of `run`, with its reason and what is known of its
/// recording.
fn failed_outcome(
    run: &RunSpec,
    cfg: &PipelineConfig,
    reason: String,
    recording: Option<&Recording>,
) -> RunOutcome {
    let mut record = DropRecord::failed(&run.run, run.sphere_radius_mm, reason);
    record.surface = run
        .surface
        .clone()
        .unwrap_or_else(|| cfg.input.surface.clone());
    record.sphere_density_kg_m3 = run.sphere_density_kg_m3.unwrap_or(cfg.sphere.density_kg_m3);
    record.setup = run.setup.clone().unwrap_or_default();
    record.drop_height_cm = run.drop_height_cm;
    record.path = run.path.display().to_string();
    record.fps = recording.map(|r| r.fps);
    record.fps_source = recording.map(|r| r.fps_source.clone()).unwrap_or_default();
    // What its input says of itself (colour, flips, frame names) helps read
    // why it failed: opened again for that (its header only).
    let meta = open_run(run, cfg).ok().map(|(s, _)| s.meta().clone());
    record.reading = meta.as_ref().map(|m| m.reading()).unwrap_or_default();
    RunOutcome {
        record,
        track_csv: Spool::new(0),
        track_rows: recording.map_or(0, |r| r.frames),
        overlay: None,
        frame_overlays: Vec::new(),
        impact: None,
        scene: None,
        seconds: 0.0,
        notes: meta.map(|m| m.reading_notes()).unwrap_or_default(),
    }
}

/// Group runs into camera set-ups: runs sharing a `setup` value, in the
/// order of their first run; a run without one alone. Returns indices.
pub fn setups(runs: &[RunSpec]) -> Vec<Vec<usize>> {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut named: Vec<(&str, usize)> = Vec::new();
    for (i, r) in runs.iter().enumerate() {
        match r.setup.as_deref() {
            Some(s) => match named.iter().find(|(n, _)| *n == s) {
                Some(&(_, g)) => groups[g].push(i),
                None => {
                    named.push((s, groups.len()));
                    groups.push(vec![i]);
                }
            },
            None => groups.push(vec![i]),
        }
    }
    groups
}

/// A job's runs and configuration as they are processed.
pub struct Prepared {
    /// The runs, with the camera set-ups their images show filled in where
    /// the manifest names none ([`crate::setup_infer`], `camera.infer_setups`).
    pub runs: Vec<RunSpec>,
    /// The configuration, with the edge offset the runs measured
    /// ([`crate::scale::EdgeOffset::measure`]) where it gives none.
    pub cfg: PipelineConfig,
    /// The runs tracked to read their scenes, kept for [`process_setup`].
    pub kept: KeptRuns,
}

/// The runs [`prepare`] tracked, by their index in its runs: each track on
/// a [`Shelf`] (its background and records in the job's temporary file),
/// or the reason it could not be made, for [`process_setup`] to take
/// instead of tracking the run again. A run whose track could not be
/// shelved (no temporary file) is not kept: it is tracked again.
#[derive(Default)]
pub struct KeptRuns {
    runs: Vec<std::sync::Mutex<Option<KeptRun>>>,
}

impl KeptRuns {
    /// Run `i`'s, once.
    pub fn take(&self, i: usize) -> Option<KeptRun> {
        self.runs.get(i)?.lock().ok()?.take()
    }
}

/// A run [`prepare`] tracked (see [`KeptRuns`]).
pub struct KeptRun(Result<ShelvedRun, RunFailure>);

/// A [`Tracked`] without its source (opened again: a job's runs are not
/// all held open) and the distortion bound's track (made again from the
/// track), its track on the shelf.
struct ShelvedRun {
    shelf: Arc<Shelf>,
    meta: crate::source::SourceMeta,
    track: ShelvedTrack,
    settings: TrackSettings,
    surface_name: String,
    curvature: Option<Curvature>,
    fps_source: String,
}

impl KeptRun {
    /// What [`track_run`] gave, or `t`'s track put on `shelf`; `None` when
    /// it could not be put there.
    fn new(t: Result<Tracked, RunFailure>, shelf: Option<&Arc<Shelf>>) -> Option<KeptRun> {
        let t = match t {
            Ok(t) => t,
            Err(e) => return Some(KeptRun(Err(e))),
        };
        let shelf = shelf?;
        let track = crate::timings::time(crate::timings::Stage::Shelf, || shelf.put(t.tr)).ok()?;
        Some(KeptRun(Ok(ShelvedRun {
            shelf: Arc::clone(shelf),
            meta: t.meta,
            track,
            settings: t.settings,
            surface_name: t.surface_name,
            curvature: t.curvature,
            fps_source: t.fps_source,
        })))
    }

    /// The run as [`track_run`] gave it; `None` when its track cannot be
    /// read back (the run is then tracked again).
    fn restore(self, run: &RunSpec, cfg: &PipelineConfig) -> Option<Result<Tracked, RunFailure>> {
        let s = match self.0 {
            Ok(s) => s,
            Err(e) => return Some(Err(e)),
        };
        let tr =
            crate::timings::time(crate::timings::Stage::Shelf, || s.shelf.take(s.track)).ok()?;
        Some(caught(run, || {
            // The same recording, opened again: its frame rate is the one
            // it was tracked at.
            let (source, _) = open_run(run, cfg)?;
            let bounded = bounded_of(&tr, &s.meta, cfg);
            tr.frames
                .check()
                .map_err(|e| format!("{}: {e}", run.path.display()))?;
            Ok(Tracked {
                source,
                meta: s.meta,
                tr,
                settings: s.settings,
                surface_name: s.surface_name,
                curvature: s.curvature,
                bounded,
                fps_source: s.fps_source,
            })
        }))
    }
}

/// Prepare a job's runs (see [`Prepared`]). With `camera.infer_setups` and
/// two runs or more without a `setup`, each of those is tracked to read its
/// scene, and its track kept for its processing ([`KeptRuns`]); `scene_of`
/// gives a run's scene when it is already known (a cache). A run that cannot be
/// tracked stays without a set-up (its processing says why). The edge
/// offset is measured on those runs whose own free fall gives their scale
/// within [`crate::scale::EDGE_OFFSET_FREE_FALL_REL_ERR`].
pub fn prepare(
    runs: &[RunSpec],
    cfg: &PipelineConfig,
    scene_of: &(dyn Fn(&RunSpec) -> Option<SceneSignature> + Sync),
    notice: &dyn Fn(&str),
) -> Prepared {
    let mut out = Prepared {
        runs: runs.to_vec(),
        cfg: cfg.clone(),
        kept: KeptRuns::default(),
    };
    let open: Vec<usize> = (0..runs.len())
        .filter(|&i| runs[i].setup.is_none())
        .collect();
    if !cfg.camera.infer_setups || open.len() < 2 {
        return out;
    }
    let known: Vec<Option<SceneSignature>> = open.par_iter().map(|&i| scene_of(&runs[i])).collect();
    let unknown = known.iter().filter(|s| s.is_none()).count();
    if unknown > 0 {
        notice(&format!(
            "camera set-ups: reading the scenes of {unknown} run(s) without a `setup` (camera.infer_setups)"
        ));
    }
    let shelf = (unknown > 0)
        .then(|| Shelf::new().ok().map(Arc::new))
        .flatten();
    let (scenes, kept): (Vec<Option<SceneSignature>>, Vec<Option<KeptRun>>) = open
        .par_iter()
        .zip(known)
        .map(|(&i, known)| {
            let run = &runs[i];
            if known.is_some() {
                return (known, None);
            }
            let t = caught(run, || track_run(run, cfg));
            let scene = t.as_ref().ok().map(|t| t.scene(run.sphere_radius_mm));
            (scene, KeptRun::new(t, shelf.as_ref()))
        })
        .unzip();
    out.kept.runs = (0..runs.len()).map(|_| Default::default()).collect();
    for (&i, k) in open.iter().zip(kept) {
        out.kept.runs[i] = std::sync::Mutex::new(k);
    }
    let taken: Vec<&str> = runs.iter().filter_map(|r| r.setup.as_deref()).collect();
    let groups = crate::setup_infer::infer_groups(&scenes);
    for (k, group) in groups.iter().enumerate() {
        let name = crate::setup_infer::setup_name(k + 1, &taken);
        for &j in group {
            out.runs[open[j]].setup = Some(name.clone());
        }
    }
    let grouped: usize = groups.iter().map(Vec::len).sum();
    if grouped > 0 {
        notice(&format!(
            "camera set-ups from the images: {} run(s) in {} set-up(s) (auto1 …), {} alone",
            grouped,
            groups.len(),
            open.len() - grouped
        ));
    }
    if cfg.camera.edge_offset_px.is_none() {
        let offsets: Vec<f64> = scenes
            .iter()
            .flatten()
            .filter_map(|sc| {
                let (s, err) = sc.free_fall_mm_per_px?;
                (err < crate::scale::EDGE_OFFSET_FREE_FALL_REL_ERR * s)
                    .then(|| sc.r_app_px - sc.radius_mm / s)
            })
            .collect();
        if let Some(e) = crate::scale::EdgeOffset::measure(&offsets) {
            out.cfg.camera.edge_offset_px = Some(e.offset_px);
            out.cfg.camera.edge_offset_spread_px = Some(e.spread_px);
            notice(&format!(
                "edge offset from {} runs' own free falls: {:+.3} ± {:.3} px",
                offsets.len(),
                e.offset_px,
                e.spread_px
            ));
        }
    }
    out
}

/// A run tracked but not yet measured.
struct Tracked {
    source: Box<dyn crate::source::FrameSource>,
    meta: crate::source::SourceMeta,
    tr: Track,
    settings: TrackSettings,
    surface_name: String,
    /// The curvature of the run's own free flights.
    curvature: Option<Curvature>,
    /// The track through a lens at `camera.distortion_bound_px`, when no
    /// k1 is given and the bound is not 0.
    bounded: Option<crate::lens::Bounded>,
    /// Where `meta.fps` came from (the `fps_source` word, [`open_run`]).
    fps_source: String,
}

impl Tracked {
    /// What the run's row says of its recording.
    fn recording(&self) -> Recording {
        Recording {
            frames: self.tr.frames.len(),
            fps: self.meta.fps,
            fps_source: self.fps_source.clone(),
        }
    }

    /// What the run's images say of its camera set-up.
    fn scene(&self, radius_mm: f64) -> SceneSignature {
        let g_m_s2 = EventConfig::default().g_m_s2;
        let scale = |c: &Curvature| c.mm_per_px(g_m_s2);
        let free_fall_mm_per_px = self.curvature.as_ref().map(|c| {
            let s = scale(c);
            // The distortion bound's change of the scale, as in the errors.
            let at_bound = self
                .bounded
                .as_ref()
                .and_then(|b| b.curvature.as_ref())
                .map_or(0.0, |b| (scale(b) - s).abs() / 3f64.sqrt());
            (s, (s * c.rel_err()).hypot(at_bound))
        });
        SceneSignature {
            width_px: self.meta.width,
            height_px: self.meta.height,
            surface_row_px: self.tr.surface.row_at(0.5 * self.meta.width as f64),
            surface_slope: self.tr.surface.slope,
            r_app_px: self.tr.radius_px,
            r_app_err_px: self.tr.radius_err_px,
            radius_mm,
            free_fall_mm_per_px,
        }
    }
}

/// The reason of a run that panicked: the panic's message, which names the
/// place in dropscope; the input is named too.
fn panic_reason(input: &Path, payload: &(dyn std::any::Any + Send)) -> String {
    let msg = payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into());
    format!(
        "{}: internal error (a bug in dropscope, please report it with this input): {msg}",
        input.display()
    )
}

/// `run`'s frames, opened, and where their frame rate came from (the
/// `fps_source` column): the recording's own when it holds one, else the
/// fallback [`PipelineConfig::fps_fallback`] names. A recording without a
/// rate of its own is opened twice, the first time to learn that.
fn open_run(
    run: &RunSpec,
    cfg: &PipelineConfig,
) -> Result<(Box<dyn crate::source::FrameSource>, String), String> {
    use crate::config::FpsSource;
    let open_with = |fps_fallback: Option<f64>| {
        let options = open_options(cfg, run.number_digits, fps_fallback);
        crate::timings::time(crate::timings::Stage::Open, || open(&run.path, &options))
    };
    let has_fps = |m: &crate::source::SourceMeta| m.fps.is_finite() && m.fps > 0.0;
    match open_with(None) {
        Ok(src) if has_fps(src.meta()) => {
            let word = FpsSource::Recording.word(&recording_fps_word(src.meta()));
            return Ok((src, word));
        }
        Ok(_) | Err(crate::source::SourceError::NoFrameRate { .. }) => {}
        Err(e) => return Err(e.to_string()),
    }
    let (fps, from) = cfg.fps_fallback(run.fps);
    let src = open_with(Some(fps)).map_err(|e| e.to_string())?;
    Ok((src, from.word("")))
}

/// The `fps_source` word of a recording's own frame rate: `cine` for a
/// cine header, `xml` for a PCC XML side file, else the reader's format.
fn recording_fps_word(meta: &crate::source::SourceMeta) -> String {
    match meta.format.as_str() {
        "cine" => "cine".into(),
        _ if meta.details.side_file.is_some() => "xml".into(),
        other => other.to_string(),
    }
}

/// The track through a lens at `camera.distortion_bound_px`, when no k1 is
/// given and the bound is not 0.
/// The lens a run's track is seen through (see `lens.rs`).
#[derive(Debug, Clone, Copy, PartialEq)]
enum LensUsed {
    /// `camera.distortion_k1_per_px2`: the track is corrected with it.
    Calibrated(f64),
    /// Measured by the surface line's bow: the track is corrected with
    /// `k1`, and `err` is a systematic term.
    Measured { k1: f64, err: f64 },
    /// Not measured: the distortion bound's lens is a systematic term.
    Bound(Lens),
    /// No distortion considered (`camera.distortion_bound_px = 0`).
    None,
}

impl LensUsed {
    /// The `k1` the track is corrected with, its error, and where it came
    /// from (`drops.csv`'s `distortion_source`).
    fn describe(&self) -> (Option<f64>, Option<f64>, &'static str) {
        match *self {
            LensUsed::Calibrated(k1) => (Some(k1), None, "config"),
            LensUsed::Measured { k1, err } => (Some(k1), Some(err), "surface_bow"),
            LensUsed::Bound(_) => (None, None, "bound"),
            LensUsed::None => (None, None, "none"),
        }
    }
}

/// Which lens a track is seen through: the configuration's calibration;
/// else the one its surface line's bow measures, where that is informative
/// and tighter than the distortion bound; else the bound (or none).
fn lens_of(tr: &Track, meta: &crate::source::SourceMeta, cfg: &PipelineConfig) -> LensUsed {
    let camera = &cfg.camera;
    if let Some(k1) = camera.distortion_k1_per_px2 {
        return LensUsed::Calibrated(k1);
    }
    if camera.distortion_bound_px <= 0.0 {
        return LensUsed::None;
    }
    let bound = Lens::barrel_at_corner(camera.distortion_bound_px, meta.width, meta.height);
    match crate::lens::k1_from_bow(&tr.surface, meta.width, meta.height) {
        Some((k1, err)) if err * 3f64.sqrt() < bound.k1_per_px2.abs() => {
            LensUsed::Measured { k1, err }
        }
        _ => LensUsed::Bound(bound),
    }
}

fn bounded_of(
    tr: &Track,
    meta: &crate::source::SourceMeta,
    cfg: &PipelineConfig,
) -> Option<crate::lens::Bounded> {
    use crate::timings::{time, Stage};
    let lens = match lens_of(tr, meta, cfg) {
        LensUsed::Measured { err, .. } => Lens::new(-err * 3f64.sqrt(), meta.width, meta.height),
        LensUsed::Bound(lens) => lens,
        LensUsed::Calibrated(_) | LensUsed::None => return None,
    };
    Some({
        let (surface, radius_px, curvature) = time(Stage::Events, || {
            let (surface, radius_px) = crate::lens::undistorted_line(tr, &lens);
            let c = free_fall_curvature(
                || bounded_points(tr, &lens, radius_px),
                |x| surface.row_at(x),
                radius_px,
            );
            (surface, radius_px, c)
        });
        crate::lens::Bounded {
            lens,
            surface_row0_px: surface.row0_px,
            surface_slope: surface.slope,
            radius_px,
            curvature,
        }
    })
}

fn track_run(run: &RunSpec, cfg: &PipelineConfig) -> Result<Tracked, RunFailure> {
    crate::run_name::check(&run.run)?;
    let surface_name = run
        .surface
        .clone()
        .unwrap_or_else(|| cfg.input.surface.clone());
    if !cfg.surfaces.contains_key(&surface_name) {
        return Err(format!(
            "surface `{surface_name}` is not defined in pipeline.toml (known: {})",
            cfg.surfaces.keys().cloned().collect::<Vec<_>>().join(", ")
        )
        .into());
    }
    use crate::timings::{time, Stage};
    let (mut source, fps_source) = open_run(run, cfg)?;
    let meta = source.meta().clone();
    // A failure from here on has a recording: its frames and frame rate
    // are in the failed row.
    let failed = |e: &dyn std::fmt::Display| RunFailure {
        reason: format!("{}: {e}", run.path.display()),
        recording: Some(Recording {
            frames: meta.frame_count,
            fps: meta.fps,
            fps_source: fps_source.clone(),
        }),
    };
    let settings = TrackSettings::from_config(&cfg.detect_settings());
    let mut tr = track(source.as_mut(), &settings).map_err(|e| failed(&e))?;
    let lens = lens_of(&tr, &meta, cfg);
    if let LensUsed::Calibrated(k1) | LensUsed::Measured { k1, .. } = lens {
        tr =
            undistort_track(tr, &Lens::new(k1, meta.width, meta.height)).map_err(|e| failed(&e))?;
    }
    exclude_frames(&mut tr, &run.review).map_err(|e| failed(&e))?;
    // The free falls' curvature, and the track through the lens at the
    // distortion bound with its own: each on a thread.
    let (curvature, bounded) = rayon::join(
        || {
            time(Stage::Events, || {
                free_fall_curvature(
                    || held_points(&tr, |_| (None, None)),
                    |x| tr.surface.row_at(x),
                    tr.radius_px,
                )
            })
        },
        || bounded_of(&tr, &meta, cfg),
    );
    tr.frames.check().map_err(|e| failed(&e))?;
    Ok(Tracked {
        source,
        meta,
        tr,
        settings,
        surface_name,
        curvature,
        bounded,
        fps_source,
    })
}

fn measure_run(
    t: Tracked,
    run: &RunSpec,
    cfg: &PipelineConfig,
    [setup, setup_at_bound]: [Option<Curvature>; 2],
    overlay_frames: &[i64],
) -> Result<RunOutcome, String> {
    let scene = t.scene(run.sphere_radius_mm);
    let Tracked {
        mut source,
        meta,
        tr,
        settings,
        surface_name,
        curvature,
        bounded,
        fps_source,
    } = t;
    let event_cfg = EventConfig {
        exposure_s: meta.exposure_s.unwrap_or(0.0),
        ..EventConfig::default()
    };
    // Scale: given (manifest, then configuration), else free fall (the
    // set-up's, else the run's own), else the sphere's apparent radius.
    let inputs = ScaleInputs {
        radius_mm: run.sphere_radius_mm,
        g_m_s2: event_cfg.g_m_s2,
        given_mm_per_px: cfg.given_mm_per_px(run.mm_per_px),
        setup,
        own: curvature,
        r_app_px: tr.radius_px,
        r_app_err_px: tr.radius_err_px,
        edge_offset: crate::scale::EdgeOffset::from_config(&cfg.camera),
        setup_at_bound,
        own_at_bound: bounded.as_ref().and_then(|b| b.curvature),
    };
    let sc = crate::scale::resolve(&inputs);
    let (radius_px, radius_err_px) = sc.radius_px(&inputs);
    let edge_offset = sc.edge_offset_px(&inputs);
    let mut held = 0usize;
    let x_sum: f64 = tr
        .frames
        .iter()
        .filter_map(|f| f.held.map(|h| h.x_px))
        .inspect(|_| held += 1)
        .sum();
    let x_mid = x_sum / held.max(1) as f64;
    // The scale and the true radius in pixels are tied (R_px = R_mm / s)
    // whatever the source, so the kinematics carries them as one.
    let geom = Geometry {
        surface_row_px: tr.surface.row0_px,
        surface_slope: tr.surface.slope,
        surface_row_err_px: tr.surface_row_err_px(x_mid),
        radius_px,
        radius_err_px,
        mm_per_px: sc.mm_per_px,
        mm_per_px_err: sc.mm_per_px * sc.rel_err,
        scale_from_radius: true,
    };
    // The free-radius circle measures the silhouette: its radius, less the
    // edge offset, is the sphere's.
    let offset_px_edge = edge_offset.map_or(0.0, |(o, _)| o);
    // The points of the first bounce that the events under a geometry use,
    // with the contact half-widths of another: made again from the track
    // when needed, never every frame's.
    let window = |half_widths: &Geometry, geom: &Geometry| {
        let held = held_points(&tr, |f| half_width(f, offset_px_edge, half_widths));
        crate::events::first_contact_window(held, geom, &event_cfg)
    };
    let first_geom = geom;
    let info = DropInfo {
        run: run.run.clone(),
        sphere_radius_mm: run.sphere_radius_mm,
        sphere_density_kg_m3: run.sphere_density_kg_m3.unwrap_or(cfg.sphere.density_kg_m3),
        surface: surface_name,
    };
    let failed = |e: crate::events::EventError| format!("{}: {e}", run.path.display());
    let points = match window(&geom, &geom) {
        Err(e @ crate::events::EventError::NeverLands { .. }) => {
            // Tracked, never landing: its free flight and files, no impact.
            let row_of = |f: &FrameTrack| {
                let mut row = track_row(f);
                row.delta_mm = row
                    .x_px
                    .zip(row.z_px)
                    .map(|(x, z)| geom.penetration_px(x, z) * geom.mm_per_px);
                row
            };
            let files = Files {
                recording: RecordingRow {
                    run,
                    cfg,
                    meta: &meta,
                    tr: &tr,
                    sc: &sc,
                    edge_offset,
                    fps_source: &fps_source,
                },
                source: source.as_mut(),
                settings: &settings,
                row_of: &row_of,
                still_at_s: None,
                impact: None,
                overlay_frames,
                scene,
            };
            return tracked_only(failed(e), &info, &geom, event_cfg.g_m_s2, files);
        }
        points => points.map_err(failed)?,
    };
    let mut m = measure_drop(&info, &points, &geom, &event_cfg).map_err(failed)?;
    drop(points);
    // The surface is the image's line (or the configuration's), never the
    // contact law's: the law is what the experiment measures. The law's
    // surface only cross-checks the line: where they disagree beyond 3σ the
    // drop is flagged, and the line's error takes in their disagreement
    // (which of the two is off, the image cannot tell), so that every error
    // resting on the line says so; the values stay the line's.
    let mut surface_source = if tr.surface_from_config {
        "config"
    } else {
        "image"
    };
    let mut geom = geom;
    // A surface row set by hand in `dropscope review` replaces the line
    // found, wherever it came from: through the row given at the impact
    // column, with the image's tilt. Like the configuration's, it is given,
    // not cross-checked.
    let by_hand = run.review.surface_row_px.as_ref().map(|(row, _)| *row);
    let mut hand_offset_px = 0.0;
    if let Some(row_px) = by_hand {
        let at_impact = m.record.surface_row_px.unwrap_or(geom.surface_row_px);
        hand_offset_px = row_px - at_impact;
        geom.surface_row_px += hand_offset_px;
        geom.surface_row_err_px = crate::review::decisions::HAND_SURFACE_ERR_PX;
        surface_source = "review";
        let points = window(&geom, &geom).map_err(failed)?;
        m = measure_drop(&info, &points, &geom, &event_cfg).map_err(failed)?;
    }
    let disagreement = match &m.law {
        Ok(law) if surface_source == "image" => {
            crate::measure::surface_law_check(law, geom.surface_row_err_px)
                .map(|flag| (flag, law.surface_offset_px.map_or(0.0, |d| d.value)))
        }
        _ => None,
    };
    if let Some((_, offset_px)) = disagreement {
        geom.surface_row_err_px = geom.surface_row_err_px.hypot(offset_px);
        let points = window(&geom, &geom).map_err(failed)?;
        m = measure_drop_with(&info, &points, &geom, &event_cfg, Some(&m.law)).map_err(failed)?;
    }
    let geom = geom;
    // A frame's row of the track CSV, with contact, δ and force: made
    // when written, one at a time (a long movie's rows, 168 bytes a frame,
    // were held beside its track).
    let row_of = |f: &FrameTrack| {
        let mut row = track_row(f);
        annotate_track(std::slice::from_mut(&mut row), &m, &geom);
        row
    };
    let law_offset = m.law.as_ref().ok().and_then(|l| l.surface_offset_px);
    let mut record = m.record.clone();
    if let (Some(((word, message), offset_px)), Ok(law)) = (disagreement, &m.law) {
        quality::flag(&mut record, word, message);
        // n and K were fitted on the line: its widened error reaches them
        // through their response to the surface.
        let widen = |err: &mut Option<f64>, per_px: f64| {
            *err = err.map(|e| e.hypot(per_px * offset_px));
        };
        widen(&mut record.force_exponent_err, law.n_per_surface_px);
        widen(&mut record.force_k_si_err, law.k_per_surface_px);
    }
    record.surface_source = surface_source.to_string();
    record.surface_law_offset_px = law_offset.map(|d| d.value);
    record.surface_law_offset_px_err = law_offset.map(|d| d.err);
    widen_a_max_err(&mut record, &geom, edge_offset.map_or(0.0, |(_, e)| e));
    let lens = lens_of(&tr, &meta, cfg);
    let corrected = matches!(lens, LensUsed::Calibrated(_) | LensUsed::Measured { .. });
    speeds_at_the_impact_scale(&mut record, &sc, corrected);
    let (k1, k1_err, lens_source) = lens.describe();
    record.distortion_k1_per_px2 = k1;
    record.distortion_k1_per_px2_err = k1_err;
    record.distortion_source = lens_source.to_string();
    if let Some(b) = &bounded {
        // The first look's points (their half-widths on the image's line)
        // and the lens's, each under the geometry measured on them.
        let shift = crate::lens::shift_at_bound(
            |g| window(&first_geom, g).ok(),
            |g| {
                let held = bounded_points(&tr, &b.lens, b.radius_px);
                crate::events::first_contact_window(held, g, &event_cfg).ok()
            },
            &geom,
            &sc,
            &inputs,
            b,
            setup_at_bound,
            geom.surface_row_px - tr.surface.row0_px,
            &info.sphere(),
            &event_cfg,
            |sc| if corrected { 1.0 } else { speed_factor(sc).0 },
        );
        if let Some(shift) = shift {
            distortion_systematic(&mut record, &shift);
        }
    }
    crate::measure::flag_restitution_above_one(&mut record);
    // The overlays draw the line used.
    let mut tr = tr;
    tr.surface.row0_px += hand_offset_px;
    let recording = RecordingRow {
        run,
        cfg,
        meta: &meta,
        tr: &tr,
        sc: &sc,
        edge_offset,
        fps_source: &fps_source,
    };
    recording.describe(&mut record);
    let impact = record
        .t_contact_s
        .filter(|_| cfg.output.animation)
        .map(|t| (t, record.t_rebound_s));
    // The overlay at the frame nearest the maximum penetration.
    let still_at_s = record.t_max_s;
    with_files(
        record,
        Files {
            recording,
            source: source.as_mut(),
            settings: &settings,
            row_of: &row_of,
            still_at_s,
            impact,
            overlay_frames,
            scene,
        },
    )
}

/// What a run's row says of its recording, its scale and its checks,
/// whatever became of its impact.
struct RecordingRow<'a> {
    run: &'a RunSpec,
    cfg: &'a PipelineConfig,
    meta: &'a crate::source::SourceMeta,
    tr: &'a Track,
    sc: &'a crate::scale::Scale,
    /// Apparent minus true radius and its error, px.
    edge_offset: Option<(f64, f64)>,
    fps_source: &'a str,
}

impl RecordingRow<'_> {
    /// Fill `record`'s manifest, scale and frame-rate columns and flag what
    /// weakens them (scale disagreement, saturation, frame times, an
    /// assumed or disagreeing frame rate).
    fn describe(&self, record: &mut DropRecord) {
        let (run, sc, meta, tr) = (self.run, self.sc, self.meta, self.tr);
        record.setup = run.setup.clone().unwrap_or_default();
        record.drop_height_cm = run.drop_height_cm;
        record.path = run.path.display().to_string();
        record.reading = meta.reading();
        record.scale_source = sc.source.name().to_string();
        record.free_fall_mm_per_px = sc.free_fall_mm_per_px.map(|(s, _)| s);
        record.free_fall_mm_per_px_err = sc.free_fall_mm_per_px.map(|(_, e)| e);
        record.edge_offset_px = self.edge_offset.map(|(o, _)| o);
        record.edge_offset_px_err = self.edge_offset.map(|(_, e)| e);
        record.surface_model_err_px = Some(tr.surface.model_err_px);
        if let Some(w) = &sc.warning {
            quality::flag(record, quality::SCALE_DISAGREEMENT, w.clone());
        }
        if let Some(share) = saturated_share(tr, meta.bit_depth) {
            quality::flag(
                record,
                quality::SATURATED,
                format!(
                    "{:.1} % of the background near the sphere's path is clipped at the white level",
                    share * 100.0
                ),
            );
        }
        for w in &meta.details.warnings {
            if w.starts_with(crate::source::validate::IRREGULAR_TIMES)
                || w.starts_with(crate::source::validate::TIMES_INCOMPLETE)
            {
                quality::flag(record, quality::TIME_IRREGULAR, w.clone());
            } else if w.starts_with(crate::source::validate::TIMES_AND_RATE_DISAGREE) {
                quality::flag(record, quality::FPS_MISMATCH, w.clone());
            }
        }
        frame_rate_checks(record, run, self.cfg, meta.fps, self.fps_source);
    }
}

/// What a run's files are drawn and written from.
struct Files<'a> {
    recording: RecordingRow<'a>,
    source: &'a mut dyn crate::source::FrameSource,
    settings: &'a TrackSettings,
    /// A frame's row of the track CSV.
    row_of: &'a (dyn Fn(&FrameTrack) -> TrackRow + Sync),
    /// The main overlay is the held frame nearest this time.
    still_at_s: Option<f64>,
    /// The animated impact's contact and rebound times.
    impact: Option<(f64, Option<f64>)>,
    overlay_frames: &'a [i64],
    scene: SceneSignature,
}

/// The run's outcome: `record`, with its overlays, animated impact and
/// track CSV (drawn and written beside each other).
fn with_files(record: DropRecord, f: Files<'_>) -> Result<RunOutcome, String> {
    let Files {
        recording,
        source,
        settings,
        row_of,
        still_at_s,
        impact,
        overlay_frames,
        scene,
    } = f;
    let RecordingRow {
        run, meta, tr, sc, ..
    } = recording;
    let pictures = || {
        let mut pictures = crate::pictures::Pictures {
            source,
            meta,
            track: tr,
            settings,
            delta_mm: &|f| row_of(f).delta_mm,
            mm_per_px: sc.mm_per_px,
        };
        let overlay = still_at_s.and_then(|at| {
            let ft = tr
                .frames
                .iter()
                .filter(|f| f.held.is_some() && !f.flags.contains(crate::track::Flag::Excluded))
                .min_by(|a, b| (a.t_s - at).abs().total_cmp(&(b.t_s - at).abs()))?;
            pictures.still(&ft)
        });
        let frame_overlays: Vec<(i64, Vec<u8>)> = overlay_frames
            .iter()
            .filter_map(|&n| {
                let ft = tr.frames.iter().find(|f| f.frame == n)?;
                pictures.still(&ft).map(|png| (n, png))
            })
            .collect();
        let impact = impact.and_then(|(t, rebound)| pictures.impact(t, rebound));
        (overlay, frame_overlays, impact)
    };
    let track_csv = || {
        let mut track_csv = Spool::new(TRACK_CSV_IN_MEMORY_MAX);
        crate::dataset::write_csv_rows(&mut track_csv, tr.frames.iter().map(|f| row_of(&f)))
            .map(|()| track_csv)
            .map_err(|e| {
                format!(
                    "{}: cannot hold its track CSV in a temporary file: {e}",
                    run.path.display()
                )
            })
    };
    let ((overlay, frame_overlays, impact), track_csv) = rayon::join(pictures, track_csv);
    let track_csv = track_csv?;
    // Everything above walked the track's records: none failed to be read.
    tr.frames
        .check()
        .map_err(|e| format!("{}: {e}", run.path.display()))?;
    Ok(RunOutcome {
        record,
        track_csv,
        track_rows: tr.frames.len(),
        overlay,
        frame_overlays,
        impact,
        scene: Some(scene),
        seconds: 0.0,
        notes: meta.reading_notes(),
    })
}

/// The outcome of a run whose sphere was tracked but never reached the
/// surface (`why`): status `tracked`, its free flight ([`crate::flight`]:
/// v at the last tracked frame, g) at the run's scale, its scale and frame
/// rate columns, its track (δ negative: the clearance) and the overlay of
/// its last tracked frame, no impact.
fn tracked_only(
    why: String,
    info: &DropInfo,
    geom: &Geometry,
    g_m_s2: f64,
    f: Files<'_>,
) -> Result<RunOutcome, String> {
    let (run, tr, sc) = (f.recording.run, f.recording.tr, f.recording.sc);
    let mut record = DropRecord::failed(&run.run, run.sphere_radius_mm, String::new());
    record.status = crate::dataset::DropStatus::Tracked;
    record.sphere_density_kg_m3 = info.sphere_density_kg_m3;
    record.surface = info.surface.clone();
    record.mm_per_px = Some(sc.mm_per_px);
    record.mm_per_px_err = Some(sc.mm_per_px * sc.rel_err);
    let points: Vec<TrackPoint> = held_points(tr, |_| (None, None)).collect();
    record.surface_row_px = points
        .last()
        .map(|p| geom.surface_row_at(p.x_px))
        .or(Some(geom.surface_row_px));
    record.surface_row_px_err = Some(geom.surface_row_err_px);
    record.surface_source = "image".into();
    record.reason = match crate::flight::free_flight(&points, sc.mm_per_px, sc.rel_err, g_m_s2) {
        Ok(ff) => {
            // To the nanosecond, as the track's times.
            record.t_last_s = Some((ff.t_last_s * 1e9).round() / 1e9);
            record.v_last_m_s = Some(ff.v_last_m_s.value);
            record.v_last_m_s_err = Some(ff.v_last_m_s.err);
            record.g_fit_m_s2 = ff.g_fit_m_s2.map(|g| g.value);
            record.g_fit_m_s2_err = ff.g_fit_m_s2.map(|g| g.err);
            format!(
                "{why}: tracked only, no impact measured: {} frames of free flight, v = \
                 {:.4} ± {:.4} m/s at the last one",
                ff.frames, ff.v_last_m_s.value, ff.v_last_m_s.err
            )
        }
        Err(e) => format!("{why}: tracked only, no impact measured; no free-flight fit: {e}"),
    };
    if let Some(g) = record.g_fit_m_s2.zip(record.g_fit_m_s2_err) {
        // As a drop's flight is checked (crate::measure).
        let off = g.0 / g_m_s2 - 1.0;
        if off.abs() > 0.02 && (g.0 - g_m_s2).abs() > 3.0 * g.1 {
            quality::flag(
                &mut record,
                quality::GRAVITY_OFF,
                format!(
                    "free-flight gravity {:.3} ± {:.3} m/s² is {:+.1} % off {g_m_s2} m/s²: \
                     check the frame rate and the scale",
                    g.0,
                    g.1,
                    off * 100.0
                ),
            );
        }
    }
    f.recording.describe(&mut record);
    let still_at_s = points.last().map(|p| p.t_s);
    with_files(
        record,
        Files {
            still_at_s,
            impact: None,
            ..f
        },
    )
}

/// Fill the row's `fps` and `fps_source` and flag what is doubtful about
/// them: a frame rate assumed (`camera.fps` or [`crate::config::DEFAULT_FPS`]:
/// [`quality::FPS_ASSUMED`]), or one given (manifest, `--fps`) that
/// disagrees with the recording's own, which is used
/// ([`quality::FPS_MISMATCH`]).
fn frame_rate_checks(
    record: &mut DropRecord,
    run: &RunSpec,
    cfg: &PipelineConfig,
    fps: f64,
    fps_source: &str,
) {
    record.fps = Some(fps);
    record.fps_source = fps_source.to_string();
    match fps_source {
        "config" => quality::flag(
            record,
            quality::FPS_ASSUMED,
            format!(
                "the recording holds no frame rate: measured at {fps} frames/s, camera.fps of \
                 the configuration; if that is not this recording's, pass --fps (or the \
                 manifest's fps column)"
            ),
        ),
        "default" => quality::flag(
            record,
            quality::FPS_ASSUMED,
            format!(
                "the recording holds no frame rate and none was given: measured at {fps} \
                 frames/s, dropscope's default, a guess; times and speeds scale with it: pass \
                 --fps (or the manifest's fps column, or camera.fps)"
            ),
        ),
        "manifest" | "flag" => {}
        _ => {
            let given = [
                (run.fps, "the manifest's fps"),
                (cfg.command_line.fps, "--fps"),
            ];
            if let Some((f, by)) = given.iter().find_map(|(f, by)| Some((f.as_ref()?, by))) {
                if (f / fps - 1.0).abs() > crate::source::validate::FPS_AGREEMENT {
                    quality::flag(
                        record,
                        quality::FPS_MISMATCH,
                        format!(
                            "{by} {f} disagrees with the recording's own frame rate {fps} \
                             frames/s ({fps_source}); the recording's is used"
                        ),
                    );
                }
            }
        }
    }
}

/// The share of the background at the white level (within 1 % of
/// 2^bits − 1: the background is a median divided by the frames' flicker
/// gains) in the box the sphere swept above the surface line, when above
/// [`quality::SATURATED_SHARE`].
fn saturated_share(tr: &Track, bit_depth: u8) -> Option<f64> {
    let white = 0.99 * ((1u32 << bit_depth.min(16)) - 1) as f32;
    // The box of the held centres, walked once (none held).
    let (mut any, mut x_lo, mut x_hi, mut z_lo) =
        (false, f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY);
    for c in tr.frames.iter().filter_map(|f| f.held) {
        any = true;
        (x_lo, x_hi, z_lo) = (x_lo.min(c.x_px), x_hi.max(c.x_px), z_lo.min(c.z_px));
    }
    let bg = &tr.background;
    let (w, h) = (bg.width as f64, bg.height as f64);
    let r = tr.radius_px;
    let clampf = |v: f64, hi: f64| v.clamp(0.0, (hi - 1.0).max(0.0)) as usize;
    let x0 = clampf(x_lo - 1.2 * r, w);
    let x1 = clampf(x_hi + 1.2 * r, w);
    let z0 = clampf(z_lo - 1.2 * r, h);
    let (mut clipped, mut total) = (0usize, 0usize);
    for col in x0..=x1 {
        let z1 = clampf(tr.surface.row_at(col as f64) - 2.0, h);
        for row in z0..=z1.max(z0) {
            total += 1;
            clipped += usize::from(bg.at(row, col) >= white);
        }
    }
    let share = clipped as f64 / total.max(1) as f64;
    (any && share > quality::SATURATED_SHARE).then_some(share)
}

/// Mark the frames a person excluded (`review.csv`) in `tr`: their fits
/// stay in the track (and its CSV, flagged `excluded`) but no fit uses
/// them ([`points_of`] leaves them out).
fn exclude_frames(
    tr: &mut Track,
    review: &crate::review::decisions::RunReview,
) -> std::io::Result<()> {
    if review.excluded.is_empty() {
        return Ok(());
    }
    tr.frames.update(|_, block: &mut [FrameTrack]| {
        for f in block.iter_mut().filter(|f| review.excludes(f.frame)) {
            f.flags.insert(crate::track::Flag::Excluded);
        }
        Ok::<(), std::io::Error>(())
    })
}

/// The held-radius fits as event-stage points, with the contact
/// half-width that `half_width` gives from the free-radius fit, made as
/// they are walked: none held.
fn held_points<'a>(
    tr: &'a Track,
    half_width: impl Fn(&crate::detect::CircleFit) -> (Option<f64>, Option<f64>) + 'a,
) -> impl Iterator<Item = TrackPoint> + 'a {
    points_of(
        tr.frames.iter().filter_map(|f| f.held.map(|h| (f, h))),
        half_width,
    )
}

/// The held fits through `lens` ([`crate::lens::undistort_held`]) as points
/// without half-widths, as they are walked.
fn bounded_points<'a>(
    tr: &'a Track,
    lens: &'a Lens,
    r_px: f64,
) -> impl Iterator<Item = TrackPoint> + 'a {
    points_of(crate::lens::undistort_held(tr, lens, r_px), |_| {
        (None, None)
    })
}

/// [`held_points`] of frames given with their held fits (the track's, or
/// moved by a lens: [`crate::lens::undistort_held`]); a circle leaving the
/// frame is no point, nor a frame the tracker found off its neighbours'
/// flight ([`crate::track::Flag::Outlier`]), nor one a person excluded
/// ([`crate::track::Flag::Excluded`]).
fn points_of(
    held: impl Iterator<Item = (FrameTrack, crate::detect::CircleFit)>,
    half_width: impl Fn(&crate::detect::CircleFit) -> (Option<f64>, Option<f64>),
) -> impl Iterator<Item = TrackPoint> {
    use crate::track::Flag;
    held.filter(|(f, _)| {
        ![Flag::Partial, Flag::Outlier, Flag::Excluded]
            .into_iter()
            .any(|flag| f.flags.contains(flag))
    })
    .map(move |(f, h)| {
        let (hw, hw_err) = f.free.as_ref().map_or((None, None), &half_width);
        TrackPoint {
            frame: f.frame,
            t_s: f.t_s,
            x_px: h.x_px,
            z_px: h.z_px,
            sigma_z_px: h.cov.sigma_z_px().max(1e-4),
            half_width_px: hw,
            sigma_half_width_px: hw_err,
        }
    })
}

/// With a given scale and a lens that is not corrected (`corrected`:
/// calibrated or measured by the surface's bow, the track then in the
/// scene's pixels, where the given scale holds at the impact as anywhere),
/// the speeds use [`crate::scale::Scale::for_speeds`]:
/// the magnification at the impact that free fall measures, where it is
/// precise and disagrees with the given one. Where free fall is too
/// imprecise to be used (one drop's own flight), its disagreement beyond
/// its error is still added to the speeds' errors, since the given scale
/// need not be the magnification at the impact. On the real preset with
/// the true scale given, v_impact was 0.03 % high (barrel distortion) with
/// the given scale alone.
fn speeds_at_the_impact_scale(record: &mut DropRecord, sc: &crate::scale::Scale, corrected: bool) {
    if corrected {
        return;
    }
    let (factor, rel) = speed_factor(sc);
    for (v, err) in [
        (&mut record.v_impact_m_s, &mut record.v_impact_m_s_err),
        (&mut record.v_rebound_m_s, &mut record.v_rebound_m_s_err),
    ] {
        if let (Some(v), Some(e)) = (v.as_mut(), err.as_mut()) {
            *v *= factor;
            *e = (*e * factor).hypot(v.abs() * rel);
        }
    }
}

/// The factor that takes speeds at `sc` to speeds at the impact's
/// magnification, and the relative error that adds (see
/// [`speeds_at_the_impact_scale`]); (1, 0) unless the scale is given and
/// free fall measured one.
fn speed_factor(sc: &crate::scale::Scale) -> (f64, f64) {
    let (crate::scale::ScaleSource::Given, Some((ff, ff_err))) =
        (sc.source, sc.free_fall_mm_per_px)
    else {
        return (1.0, 0.0);
    };
    match sc.for_speeds() {
        Some((s, rel)) => (s / sc.mm_per_px, rel),
        None => (
            1.0,
            ((ff / sc.mm_per_px - 1.0).abs() - ff_err / ff).max(0.0),
        ),
    }
}

/// Add the distortion bound's [`Shift`](crate::lens::Shift) to the errors
/// as a systematic term: k1 anywhere between minus and plus the bound,
/// uniformly, moves each number by up to the shift, a standard deviation
/// of |shift| / √3. The shifts are written beside them.
fn distortion_systematic(record: &mut DropRecord, shift: &crate::lens::Shift) {
    let sd = |d: f64| d.abs() / 3f64.sqrt();
    let widen = |err: &mut Option<f64>, d: f64| *err = err.map(|e| e.hypot(sd(d)));
    widen(&mut record.mm_per_px_err, shift.mm_per_px);
    widen(&mut record.v_impact_m_s_err, shift.v_impact_m_s);
    widen(&mut record.v_rebound_m_s_err, shift.v_rebound_m_s);
    // The restitution v_out / v_in moves with both speeds' shifts at once
    // (the same k1): by e·(Δv_out/v_out − Δv_in/v_in).
    if let (Some(e), Some(vi), Some(vo)) = (
        record.restitution,
        record.v_impact_m_s,
        record.v_rebound_m_s,
    ) {
        let de = e * (shift.v_rebound_m_s / vo - shift.v_impact_m_s / vi);
        widen(&mut record.restitution_err, de);
    }
    widen(&mut record.delta_max_mm_err, shift.delta_max_mm);
    widen(&mut record.tau_c_ms_err, shift.tau_c_ms);
    record.distortion_mm_per_px = Some(shift.mm_per_px);
    record.distortion_v_impact_m_s = Some(shift.v_impact_m_s);
    record.distortion_delta_max_mm = Some(shift.delta_max_mm);
    record.distortion_tau_c_ms = Some(shift.tau_c_ms);
}

/// The standard deviation of the difference between the silhouette's edge
/// offset in the flight, where it is measured, and at the peak, where a_max
/// uses it (motion smear, the lower outline hidden in contact), px. On the
/// `realistic` renders with contacts beyond the model (120 drops) that
/// difference is 0.003 px at the median and 0.008 px at the 95th
/// percentile: a normal spread of 0.0045 px gives both (0.67σ and 1.96σ).
pub const A_MAX_EDGE_SYSTEMATIC_PX: f64 = 0.0045;

/// Add to a_max's error what is common to every frame of the peak and so
/// not in its fit's: the surface row's error (∂a/∂y_s = (R − δ)/a) and the
/// edge offset's (∂a/∂r = R/a), with [`A_MAX_EDGE_SYSTEMATIC_PX`].
fn widen_a_max_err(record: &mut DropRecord, geom: &Geometry, edge_offset_err_px: f64) {
    let (Some(a_mm), Some(err_mm), Some(d_mm)) =
        (record.a_max_mm, record.a_max_mm_err, record.delta_max_mm)
    else {
        return;
    };
    let s = geom.mm_per_px;
    let (a, r, d) = (a_mm / s, geom.radius_px, d_mm / s);
    if a <= 0.0 {
        return;
    }
    let from_surface = (r - d) / a * geom.surface_row_err_px;
    let from_edge = r / a * edge_offset_err_px.hypot(A_MAX_EDGE_SYSTEMATIC_PX);
    record.a_max_mm_err = Some(err_mm.hypot(from_surface * s).hypot(from_edge * s));
}

/// a = √(r² − d²), d = y_s(x) − z, with r the fit's radius less the
/// silhouette's edge offset, and its σ from the fit's covariance.
fn half_width(
    f: &crate::detect::CircleFit,
    edge_offset_px: f64,
    geom: &Geometry,
) -> (Option<f64>, Option<f64>) {
    let d = geom.surface_row_at(f.x_px) - f.z_px;
    let r = f.r_px - edge_offset_px;
    if d.abs() >= r {
        return (None, None);
    }
    let a = (r * r - d * d).sqrt();
    let err = match f.cov {
        crate::detect::Covariance::Full([_, _, _, zz, zr, rr]) => {
            let (gr, gz) = (r / a, d / a);
            (gr * gr * rr + gz * gz * zz + 2.0 * gr * gz * zr)
                .max(0.0)
                .sqrt()
        }
        crate::detect::Covariance::CentreOnly(_) => return (Some(a), None),
    };
    (Some(a), Some(err.max(1e-4)))
}

/// A frame's row of the track CSV, without the measurement's columns
/// (contact, δ, force: [`annotate_track`]).
fn track_row(f: &FrameTrack) -> TrackRow {
    let fit = f.held.or(f.free);
    TrackRow {
        frame: f.frame,
        // To the nanosecond: a time computed as frame / fps carries
        // float noise (-0.0030000000000001137) no clock has.
        t_s: (f.t_s * 1e9).round() / 1e9,
        x_px: fit.map(|c| c.x_px),
        z_px: fit.map(|c| c.z_px),
        r_px: fit.map(|c| c.r_px),
        residual_px: fit.map(|c| c.residual_px),
        edge_points: fit.map_or(0, |c| c.inliers as usize),
        in_contact: false,
        delta_mm: None,
        sigma_z_px: fit.map(|c| c.cov.sigma_z_px()),
        sigma_x_px: fit.map(|c| c.cov.sigma_x_px()),
        r_free_px: f.free.map(|c| c.r_px),
        sigma_r_free_px: f.free.and_then(|c| c.cov.sigma_r_px()),
        force_n: None,
        flags: f.flags.text(),
    }
}

/// Process `runs` in parallel and write `drops.csv`, `tracks/` and
/// `plots/overlays/` into `out`. Returns the records in the runs' order.
pub fn process_all(
    runs: &[RunSpec],
    cfg: &PipelineConfig,
    out: &Path,
    progress: &(dyn Fn(&DropRecord) + Sync),
) -> Result<Vec<DropRecord>, ProcessError> {
    process_all_with_overlays(runs, cfg, out, &[], progress)
}

/// [`process_all`], also drawing the overlays of the image numbers
/// `overlay_frames` of every run (`plots/overlays/<run>_<number>.png`).
/// Each run's files are written as soon as it is done, so memory holds only
/// the runs in flight.
pub fn process_all_with_overlays(
    runs: &[RunSpec],
    cfg: &PipelineConfig,
    out: &Path,
    overlay_frames: &[i64],
    progress: &(dyn Fn(&DropRecord) + Sync),
) -> Result<Vec<DropRecord>, ProcessError> {
    let Prepared { runs, cfg, kept } = prepare(runs, cfg, &|_| None, &|_| {});
    let (runs, cfg, kept) = (&runs, &cfg, &kept);
    let groups = setups(runs);
    let done = groups
        .par_iter()
        .map(|g| {
            let members: Vec<&RunSpec> = g.iter().map(|&i| &runs[i]).collect();
            let kept = g.iter().map(|&i| kept.take(i)).collect();
            let outcomes = process_setup(&members, cfg, overlay_frames, kept);
            let mut recs = Vec::with_capacity(g.len());
            for (&i, o) in g.iter().zip(outcomes) {
                write_run_outputs(out, &o)?;
                progress(&o.record);
                recs.push((i, o.record));
            }
            Ok(recs)
        })
        .collect::<Result<Vec<_>, ProcessError>>()?;
    // Back in the runs' order.
    let mut done: Vec<(usize, DropRecord)> = done.into_iter().flatten().collect();
    done.sort_by_key(|(i, _)| *i);
    let records: Vec<DropRecord> = done.into_iter().map(|(_, r)| r).collect();
    sync_outputs(out)?;
    write_file(out, "drops.csv", &crate::dataset::to_csv_bytes(&records))?;
    Ok(records)
}

/// Write `bytes` to `out/rel` atomically, creating folders.
pub fn write_file(out: &Path, rel: &str, bytes: &[u8]) -> Result<(), ProcessError> {
    write_file_as(out, rel, Durable::Now, |f| f.write_all(bytes))
}

/// Write what `write` writes to `out/rel` atomically, creating folders,
/// durable as `durable` says.
fn write_file_as(
    out: &Path,
    rel: &str,
    durable: Durable,
    write: impl FnOnce(&mut std::fs::File) -> std::io::Result<()>,
) -> Result<(), ProcessError> {
    crate::out_folder::write_as(out, rel, durable, write)
        .map(drop)
        .map_err(|source| ProcessError::Write {
            path: out.join(rel),
            source,
        })
}

/// Make the files written by [`write_run_outputs`] (and the cache entries)
/// into `out` durable, all at once: called before the drops.csv that lists
/// them. Until then an operating-system crash may leave a run's file short;
/// the cache finds it by its SHA-256 and processes the run again.
pub fn sync_outputs(out: &Path) -> Result<(), ProcessError> {
    crate::io_util::sync_file_system(out).map_err(|source| ProcessError::Write {
        path: out.to_path_buf(),
        source,
    })
}

/// Write one run's track (`tracks/<run>.csv`), overlays
/// (`plots/overlays/<run>[_<number>].png`) and animated impact
/// (`plots/impacts/<run>.png`) into `out`, each atomically but unsynced:
/// the job makes them durable at once ([`sync_outputs`]) before its
/// drops.csv. A track, main overlay or animation that this run's previous
/// cache entry lists, and that this outcome does not have (the run now
/// fails), is removed while it holds the bytes written then
/// ([`crate::out_folder::remove_if_holds`]). A run whose name
/// is no file name writes and removes nothing. Returns the files written,
/// relative to `out`, with the SHA-256 of their bytes.
pub fn write_run_outputs(out: &Path, o: &RunOutcome) -> Result<Vec<OutputFile>, ProcessError> {
    let run = &o.record.run;
    if crate::run_name::check(run).is_err() {
        // Its row says why it failed; it has no files and removes none.
        return Ok(Vec::new());
    }
    let track = format!("tracks/{run}.csv");
    let main_overlay = format!("plots/overlays/{run}.png");
    let before = crate::cache::listed_outputs(out, run);
    let remove_if_present = |out: &Path, rel: &str| remove_if_listed(out, rel, &before);
    let mut written = Vec::new();
    if o.track_csv.is_empty() {
        remove_if_present(out, &track)?;
    } else {
        // From its spool to the file, never whole in memory.
        write_file_as(out, &track, Durable::WithTheJob, |f| o.track_csv.copy_to(f))?;
        written.push(OutputFile {
            sha256: o.track_csv.sha256_hex(),
            path: track,
        });
    }
    let mut write = |rel: String, bytes: &[u8]| -> Result<(), ProcessError> {
        write_file_as(out, &rel, Durable::WithTheJob, |f| f.write_all(bytes))?;
        written.push(OutputFile::new(rel, bytes));
        Ok(())
    };
    match &o.overlay {
        Some(png) => write(main_overlay, png)?,
        None => remove_if_present(out, &main_overlay)?,
    }
    let impact = format!("plots/impacts/{run}.png");
    match &o.impact {
        Some(apng) => write(impact, apng)?,
        None => remove_if_present(out, &impact)?,
    }
    for (n, png) in &o.frame_overlays {
        write(format!("plots/overlays/{run}_{n}.png"), png)?;
    }
    Ok(written)
}

/// Remove `out/rel` if `listed` (what an earlier job wrote for the run)
/// names it and it still holds the bytes listed there.
fn remove_if_listed(out: &Path, rel: &str, listed: &[OutputFile]) -> Result<(), ProcessError> {
    let Some(f) = listed.iter().find(|f| f.path == rel) else {
        return Ok(());
    };
    crate::out_folder::remove_if_holds(out, rel, &f.sha256)
        .map(drop)
        .map_err(|source| ProcessError::Write {
            path: out.join(rel),
            source,
        })
}

#[cfg(test)]
mod tests;
