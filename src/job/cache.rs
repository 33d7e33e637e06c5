//! The main job's per-run result cache.
//!
//! Each finished run leaves `<out>/runs/<run>.json`: its `drops.csv` record,
//! the output files it wrote and the key it was computed under. The key is
//! SHA-256 over the dropscope version, the resolved configuration (less the
//! output folder), the run's manifest row and the input's [`Fingerprint`].
//! A later job whose key for that run is the same, and whose listed files
//! are all still there, reuses the record instead of reading the movie again.
//!
//! The entry is written last and atomically, after the run's track and
//! overlay: it is the run's commit point. A job killed at any moment leaves
//! each run either committed (whole) or not started, so starting it again
//! finishes with the outputs of an uninterrupted job.

use crate::calibrate::setup_infer::SceneSignature;
use crate::config::PipelineConfig;
use crate::dataset::manifest::RunSpec;
use crate::dataset::DropRecord;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::time::UNIX_EPOCH;

/// Bump when the entry layout or anything it depends on changes meaning.
/// 2: each output listed with its SHA-256. 3: rows carry `fps` and
/// `fps_source`. 4: the entry sealed with the SHA-256 of its own content
/// (`entry_sha256`).
pub const CACHE_SCHEMA: u32 = 4;

/// SHA-256 (hex) of the sources this dropscope was built from: every file
/// under `src/`, `Cargo.toml` and `Cargo.lock`, taken by `build.rs`. Any
/// change to the code or to a dependency's version changes it, and with it
/// every cache key.
pub const SOURCE_SHA256: &str = env!("DROPSCOPE_SOURCE_SHA256");

/// Bytes hashed from the start of a `.cine` (headers and the offset table of
/// up to 130 000 frames) and from each sampled place.
const CINE_HEAD_BYTES: u64 = 1 << 20;
const SAMPLE_BYTES: u64 = 64 << 10;
/// Places sampled through a `.cine`, and frame files sampled in a folder.
const SAMPLES: u64 = 8;
// A sampled frame file is hashed by its first and its last `SAMPLE_BYTES`
// (its header and top rows, its bottom rows), whole when smaller: what
// that costs does not grow with the sensor (whole files of 1 MB at
// 1280 × 800 were 4 % of a drop's CPU time there).

/// What identifies an input without reading all of it: its size, its latest
/// modification time and a SHA-256 of its headers and sampled frames.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Fingerprint {
    /// The input as the manifest resolved it.
    pub path: PathBuf,
    /// `"cine"` or `"folder"`.
    pub kind: String,
    /// Total bytes (a folder: of all its files).
    pub size_bytes: u64,
    /// Files in the input (1 for a `.cine`).
    pub files: u64,
    /// Latest modification time, nanoseconds since 1970 (UTC).
    pub modified_ns: u64,
    /// SHA-256 of the file listing, the side files and the sampled bytes.
    pub content_sha256: String,
}

impl Fingerprint {
    /// For an input that could not be read: nothing but its path.
    pub fn unreadable(path: &Path) -> Self {
        Fingerprint {
            path: path.to_path_buf(),
            kind: "unreadable".into(),
            size_bytes: 0,
            files: 0,
            modified_ns: 0,
            content_sha256: String::new(),
        }
    }
}

/// The cached outcome of one run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Entry {
    /// The entry's layout, [`CACHE_SCHEMA`] when written; another is a miss.
    pub schema: u32,
    /// The version of dropscope that wrote the entry.
    pub dropscope_version: String,
    /// SHA-256 of everything the result depends on (see the module docs).
    pub key: String,
    /// The run's input as it was measured.
    pub input: Fingerprint,
    /// Output files of this run, relative to the output folder, with the
    /// SHA-256 of the bytes written: a file that is missing, emptied or
    /// altered since makes the entry a miss.
    pub outputs: Vec<OutputFile>,
    /// Frames the run held (rows of its track).
    pub frames: usize,
    /// The run's row of drops.csv.
    pub record: DropRecord,
    /// What the run's images say of its camera set-up, valid while the
    /// run's own key without a set-up is `scene_key` (see [`cached_scene`]).
    #[serde(default)]
    pub scene: Option<SceneSignature>,
    /// The run's own key without a set-up when `scene` was read (see [`cached_scene`]).
    #[serde(default)]
    pub scene_key: Option<String>,
    /// SHA-256 (hex) of the entry's JSON with this field empty, set by
    /// [`store`]: an entry changed by hand (a number in its record) no
    /// longer matches it and is not reused ([`check`]).
    #[serde(default)]
    pub entry_sha256: String,
}

impl Entry {
    /// The SHA-256 of the entry's content: its compact JSON with
    /// `entry_sha256` empty.
    fn content_sha256(&self) -> String {
        let unsealed = Entry {
            entry_sha256: String::new(),
            ..self.clone()
        };
        // Serialising plain structs to JSON cannot fail.
        hex(&Sha256::digest(
            serde_json::to_vec(&unsealed).unwrap_or_default(),
        ))
    }

    /// Whether the entry is as [`store`] wrote it.
    pub fn is_sealed(&self) -> bool {
        !self.entry_sha256.is_empty() && self.entry_sha256 == self.content_sha256()
    }
}

/// One output file of a run and the SHA-256 (hex) of its bytes.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct OutputFile {
    /// Relative to the output folder.
    pub path: String,
    /// SHA-256 of the file (hex).
    pub sha256: String,
}

impl OutputFile {
    /// `path` as holding `bytes`.
    pub fn new(path: String, bytes: &[u8]) -> Self {
        OutputFile {
            path,
            sha256: hex(&Sha256::digest(bytes)),
        }
    }

    /// Whether the file is in `out` (and inside it) with the bytes it was written with.
    pub(crate) fn is_intact(&self, out: &Path) -> bool {
        crate::util::out_folder::sha256(out, &self.path).is_ok_and(|h| h == self.sha256)
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// SHA-256 (hex) of a whole file's bytes.
pub fn sha256_file(path: &Path) -> std::io::Result<String> {
    let mut h = Sha256::new();
    std::io::copy(&mut crate::util::io::open_regular(path)?, &mut h)?;
    Ok(hex(&h.finalize()))
}

fn modified_ns(md: &std::fs::Metadata) -> u64 {
    md.modified()
        .ok()
        .and_then(|t| t.duration_since(UNIX_EPOCH).ok())
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
}

/// Feed `len` bytes of `file` from `offset` (fewer at the end of the file),
/// through `buf`: a piece at a time, so that hashing a large frame file
/// touches no new memory (the same bytes hashed as reading it whole).
fn hash_range(
    h: &mut Sha256,
    file: &mut File,
    offset: u64,
    len: u64,
    buf: &mut [u8],
) -> std::io::Result<()> {
    file.seek(SeekFrom::Start(offset))?;
    let mut left = len;
    while left > 0 {
        let want = buf.len().min(usize::try_from(left).unwrap_or(usize::MAX));
        let got = match file.read(&mut buf[..want]) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        h.update(&buf[..got]);
        left -= got as u64;
    }
    Ok(())
}

/// Files whose status is read at once, on every thread, for a folder's
/// fingerprint.
const STAT_CHUNK: usize = 4096;

/// The piece [`hash_range`] reads at a time.
const HASH_PIECE_BYTES: usize = 64 << 10;

/// The fingerprint of a `.cine` file or a folder of frames.
pub fn fingerprint(path: &Path) -> std::io::Result<Fingerprint> {
    let md = std::fs::metadata(path)?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; HASH_PIECE_BYTES];
    if !md.is_dir() {
        let size = md.len();
        let mut f = crate::util::io::open_regular(path)?;
        hash_range(&mut h, &mut f, 0, CINE_HEAD_BYTES, &mut buf)?;
        if size > CINE_HEAD_BYTES {
            for k in 0..SAMPLES {
                let offset = CINE_HEAD_BYTES + (size - CINE_HEAD_BYTES) * k / SAMPLES;
                hash_range(&mut h, &mut f, offset, SAMPLE_BYTES, &mut buf)?;
            }
        }
        return Ok(Fingerprint {
            path: path.to_path_buf(),
            kind: "cine".into(),
            size_bytes: size,
            files: 1,
            modified_ns: modified_ns(&md),
            content_sha256: hex(&h.finalize()),
        });
    }
    // The status calls (one per file: thousands for a long movie) on every
    // thread, a chunk of the listing at a time; the first error in the
    // listing's order is the one returned. Of each file only its name, size
    // and modification time are kept (its whole status and directory entry
    // were ~500 bytes a file: 150 MB for a 248 166-frame TIFF folder).
    let names: Vec<std::ffi::OsString> = std::fs::read_dir(path)?
        .map(|e| e.map(|e| e.file_name()))
        .collect::<std::io::Result<_>>()?;
    use rayon::prelude::*;
    let mut files: Vec<(String, u64, u64)> = Vec::new();
    for chunk in names.chunks(STAT_CHUNK) {
        let stats: Vec<std::io::Result<std::fs::Metadata>> = chunk
            .par_iter()
            .map(|n| std::fs::symlink_metadata(path.join(n)))
            .collect();
        for (n, m) in chunk.iter().zip(stats) {
            let m = m?;
            if m.is_file() {
                let name = n.to_string_lossy().into_owned();
                files.push((name, m.len(), modified_ns(&m)));
            }
        }
    }
    drop(names);
    files.sort_by(|a, b| a.0.cmp(&b.0));
    let (mut size, mut latest) = (0u64, 0u64);
    let mut line = String::new();
    for (name, len, modified) in &files {
        use std::fmt::Write;
        size += len;
        latest = latest.max(*modified);
        line.clear();
        let _ = writeln!(line, "{name}\0{len}\0{modified}");
        h.update(line.as_bytes());
    }
    // The side files whole, and frames sampled evenly, first and last included.
    let is_side = |n: &str| n.to_ascii_lowercase().ends_with(".xml");
    let frames: Vec<&String> = files
        .iter()
        .map(|(n, _, _)| n)
        .filter(|n| !is_side(n))
        .collect();
    let mut picked: Vec<&String> = files
        .iter()
        .map(|(n, _, _)| n)
        .filter(|n| is_side(n))
        .collect();
    if let Some(last) = frames.len().checked_sub(1) {
        let n = SAMPLES as usize;
        let mut idx: Vec<usize> = (0..=n).map(|k| last * k / n).collect();
        idx.dedup();
        picked.extend(idx.into_iter().map(|i| frames[i]));
    }
    for name in picked {
        let mut f = crate::util::io::open_regular(&path.join(name))?;
        let size = f.metadata()?.len();
        if size <= 2 * SAMPLE_BYTES || is_side(name) {
            hash_range(&mut h, &mut f, 0, size, &mut buf)?;
        } else {
            hash_range(&mut h, &mut f, 0, SAMPLE_BYTES, &mut buf)?;
            hash_range(&mut h, &mut f, size - SAMPLE_BYTES, SAMPLE_BYTES, &mut buf)?;
        }
    }
    Ok(Fingerprint {
        path: path.to_path_buf(),
        kind: "folder".into(),
        size_bytes: size,
        files: files.len() as u64,
        modified_ns: latest,
        content_sha256: hex(&h.finalize()),
    })
}

/// The configuration a run's result depends on: all of it but the output
/// folder and where the review's decisions are (a run's own decisions are
/// in its key, through its [`RunSpec`]).
fn config_for_key(cfg: &PipelineConfig) -> PipelineConfig {
    let mut c = cfg.clone();
    c.output.dir = PathBuf::new();
    c.input.review = None;
    c
}

/// A path as the file system names the thing it reaches: canonical (from
/// the root, links followed; a missing file by its folder's canonical
/// path), else absolute from the working folder. The
/// manifest and its runs' paths are relative to the working folder when
/// given so (`--config ux/a.toml` from `/tmp` names `ux/runs.csv`, the same
/// file as `runs.csv` from `/tmp/ux`): keyed as given, one job reprocessed
/// every run that another had cached for being started from elsewhere.
fn where_it_is(path: &Path) -> PathBuf {
    let in_its_folder = || {
        let folder = std::fs::canonicalize(path.parent()?).ok()?;
        Some(folder.join(path.file_name()?))
    };
    std::fs::canonicalize(path)
        .ok()
        .or_else(in_its_folder)
        .or_else(|| std::path::absolute(path).ok())
        .unwrap_or_else(|| path.to_path_buf())
}

/// The cache key of `run` under `cfg` with input `fp`, computed by this
/// build of dropscope.
pub fn key(cfg: &PipelineConfig, run: &RunSpec, fp: &Fingerprint) -> String {
    key_for_source(SOURCE_SHA256, cfg, run, fp)
}

/// The key of a run whose numbers also depend on other runs (a camera
/// set-up's pooled scale): its own key with every member's, in order.
pub fn combine_keys(own: &str, members: &[&str]) -> String {
    let mut h = Sha256::new();
    h.update(own.as_bytes());
    for m in members {
        h.update(b"|");
        h.update(m.as_bytes());
    }
    hex(&h.finalize())
}

/// [`key`] as the build whose sources hash to `source` would compute it.
fn key_for_source(source: &str, cfg: &PipelineConfig, run: &RunSpec, fp: &Fingerprint) -> String {
    #[derive(Serialize)]
    struct KeyParts<'a> {
        schema: u32,
        version: &'a str,
        source: &'a str,
        config: PipelineConfig,
        run: &'a RunSpec,
        input: &'a Fingerprint,
    }
    // Its paths as the file system names what they reach.
    let mut config = config_for_key(cfg);
    config.input.manifest = config.input.manifest.as_deref().map(where_it_is);
    config.input.paths = config.input.paths.iter().map(|p| where_it_is(p)).collect();
    let run = RunSpec {
        path: where_it_is(&run.path),
        ..run.clone()
    };
    let input = Fingerprint {
        path: where_it_is(&fp.path),
        ..fp.clone()
    };
    let parts = KeyParts {
        schema: CACHE_SCHEMA,
        version: env!("CARGO_PKG_VERSION"),
        source,
        config,
        run: &run,
        input: &input,
    };
    // Serialising plain structs to JSON cannot fail.
    let json = serde_json::to_vec(&parts).unwrap_or_default();
    hex(&Sha256::digest(&json))
}

/// The id of a job writing into an output folder (see [`crate::job::lock`]):
/// SHA-256 over what it is (`kind`: `"run"`, `"process"`, …), this build's
/// sources, the configuration (less the output folder) and its runs. Every
/// shard of a job computes the same id; another configuration or run list
/// gives another.
pub fn job_id(kind: &str, cfg: &PipelineConfig, runs: &[RunSpec]) -> String {
    #[derive(Serialize)]
    struct JobParts<'a> {
        kind: &'a str,
        schema: u32,
        source: &'a str,
        config: PipelineConfig,
        runs: &'a [RunSpec],
    }
    let parts = JobParts {
        kind,
        schema: CACHE_SCHEMA,
        source: SOURCE_SHA256,
        config: config_for_key(cfg),
        runs,
    };
    // Serialising plain structs to JSON cannot fail.
    let json = serde_json::to_vec(&parts).unwrap_or_default();
    hex(&Sha256::digest(&json))
}

/// The key a run's scene signature is cached under: its own key as if the
/// manifest named no set-up (a scene does not depend on it).
pub fn scene_key(cfg: &PipelineConfig, run: &RunSpec, fp: &Fingerprint) -> String {
    let mut alone = run.clone();
    alone.setup = None;
    // Nor on the edge offset, which a job may measure from the scenes.
    let mut cfg = cfg.clone();
    cfg.camera.edge_offset_px = None;
    cfg.camera.edge_offset_spread_px = None;
    key(&cfg, &alone, fp)
}

/// The scene signature of `run` from its entry in `out`, if the entry was
/// written from the same input under the same configuration (its outputs
/// need not be intact: the signature is not one of them).
pub fn cached_scene(out: &Path, cfg: &PipelineConfig, run: &RunSpec) -> Option<SceneSignature> {
    let e = read_entry(out, &run.run).ok()?;
    let wanted = scene_key(cfg, run, &fingerprint(&run.path).ok()?);
    (e.schema == CACHE_SCHEMA && e.scene_key.as_deref() == Some(wanted.as_str()))
        .then_some(e.scene)
        .flatten()
}

/// Where the entry of run `run` lives (`runs/<run>.json`), checked to be
/// inside `out`.
pub fn entry_path(out: &Path, run: &str) -> std::io::Result<PathBuf> {
    crate::util::io::inside(out, &format!("runs/{run}.json"))
}

/// An entry larger than this is not read (its record and a few file names).
const ENTRY_MAX_BYTES: u64 = 16 << 20;

/// Why a run's entry is not used.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Miss {
    /// No entry, a damaged one, or one of another schema, key or run.
    Absent,
    /// The entry parses but its content is not what dropscope sealed: it
    /// was changed since (by hand, or by another program).
    Altered(PathBuf),
    /// A file it lists is missing or no longer holds the bytes written.
    OutputChanged,
}

/// The entry of `run` in `out` as [`store`] wrote it: read through no link
/// ([`crate::util::out_folder::read`]), parsed, and its seal checked.
fn read_entry(out: &Path, run: &str) -> Result<Entry, Miss> {
    let rel = format!("runs/{run}.json");
    let bytes = crate::util::out_folder::read(out, &rel, ENTRY_MAX_BYTES)
        .ok()
        .flatten()
        .ok_or(Miss::Absent)?;
    let e: Entry = serde_json::from_slice(&bytes).map_err(|_| Miss::Absent)?;
    if e.schema != CACHE_SCHEMA || e.record.run != run {
        return Err(Miss::Absent);
    }
    if !e.is_sealed() {
        return Err(Miss::Altered(out.join(rel)));
    }
    Ok(e)
}

/// The files the entry of `run` in `out` lists (none when it has no valid
/// entry): what an earlier job wrote for the run.
pub fn listed_outputs(out: &Path, run: &str) -> Vec<OutputFile> {
    read_entry(out, run).map(|e| e.outputs).unwrap_or_default()
}

/// The entry of `run`, if there is one computed under `key`, sealed as
/// [`store`] wrote it, and every file it lists is still in `out` with the
/// SHA-256 it was written with; else why not.
pub fn check(out: &Path, run: &str, key: &str) -> Result<Entry, Miss> {
    let e = read_entry(out, run)?;
    if e.key != key {
        return Err(Miss::Absent);
    }
    if !e.outputs.iter().all(|f| f.is_intact(out)) {
        return Err(Miss::OutputChanged);
    }
    Ok(e)
}

/// [`check`] as an option: anything but a valid entry (no entry, another
/// key, a damaged or altered entry, a missing, empty or altered output)
/// is a miss.
pub fn lookup(out: &Path, run: &str, key: &str) -> Option<Entry> {
    check(out, run, key).ok()
}

/// Commit `entry`, sealed with the SHA-256 of its content: written
/// atomically, after the files it lists.
pub fn store(out: &Path, entry: &Entry) -> std::io::Result<()> {
    let rel = format!("runs/{}.json", entry.record.run);
    let sealed = Entry {
        entry_sha256: entry.content_sha256(),
        ..entry.clone()
    };
    let mut bytes = serde_json::to_vec_pretty(&sealed).map_err(std::io::Error::other)?;
    bytes.push(b'\n');
    // Unsynced, as the run's outputs: made durable with them before the
    // job's drops.csv (`process::sync_outputs`); an entry a crash left
    // short does not parse and is a miss, one whose outputs a crash left
    // short fails their SHA-256 and is a miss.
    crate::util::out_folder::write_as(out, &rel, crate::util::io::Durable::WithTheJob, |f| {
        std::io::Write::write_all(f, &bytes)
    })
    .map(drop)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> PipelineConfig {
        crate::test_support::default_config()
    }

    fn run(path: &Path) -> RunSpec {
        RunSpec {
            run: "a".into(),
            path: path.to_path_buf(),
            sphere_radius_mm: 4.5,
            drop_height_cm: None,
            fps: None,
            mm_per_px: None,
            surface: None,
            sphere_density_kg_m3: None,
            setup: None,
            review: Default::default(),
            number_digits: None,
        }
    }

    #[test]
    fn fingerprint_sees_content_listing_and_time_changes() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().join("run");
        std::fs::create_dir(&d).unwrap();
        for i in 0..20 {
            std::fs::write(d.join(format!("f_{i:03}.tif")), vec![i as u8; 100]).unwrap();
        }
        std::fs::write(d.join("f.xml"), b"<chd/>").unwrap();
        let a = fingerprint(&d).unwrap();
        assert_eq!(
            (a.files, a.size_bytes, a.kind.as_str()),
            (21, 2006, "folder")
        );
        assert_eq!(a, fingerprint(&d).unwrap(), "not deterministic");
        // Same size, other bytes, in a sampled frame (the last).
        std::fs::write(d.join("f_019.tif"), vec![0u8; 100]).unwrap();
        let b = fingerprint(&d).unwrap();
        assert_ne!(a.content_sha256, b.content_sha256);
        // A frame removed.
        std::fs::remove_file(d.join("f_007.tif")).unwrap();
        let c = fingerprint(&d).unwrap();
        assert_ne!(b.content_sha256, c.content_sha256);
        // In a sampled frame of 1 MB, a byte in its last 64 kB (its bottom
        // rows) is seen, one in its middle is not.
        let mut big = vec![3u8; 1 << 20];
        std::fs::write(d.join("f_019.tif"), &big).unwrap();
        let e = fingerprint(&d).unwrap();
        assert_ne!(c.content_sha256, e.content_sha256);
        // (Each written with the same modification time, which is hashed too.)
        let at = std::time::SystemTime::UNIX_EPOCH + std::time::Duration::from_secs(1 << 30);
        let write = |bytes: &[u8]| {
            std::fs::write(d.join("f_019.tif"), bytes).unwrap();
            let f = std::fs::File::options()
                .write(true)
                .open(d.join("f_019.tif"))
                .unwrap();
            f.set_modified(at).unwrap();
        };
        write(&big);
        let e = fingerprint(&d).unwrap();
        big[(1 << 20) - 1000] = 4;
        write(&big);
        let f = fingerprint(&d).unwrap();
        assert_ne!(e.content_sha256, f.content_sha256);
        big[1 << 19] = 4;
        write(&big);
        let g = fingerprint(&d).unwrap();
        assert_eq!(
            (f.content_sha256, f.size_bytes),
            (g.content_sha256.clone(), g.size_bytes)
        );

        let cine = dir.path().join("m.cine");
        std::fs::write(&cine, vec![7u8; 3 << 20]).unwrap();
        let c = fingerprint(&cine).unwrap();
        assert_eq!((c.files, c.size_bytes), (1, 3 << 20));
        // One byte changed inside a sampled block (the 5th of 8: 1 MiB + 2 MiB·4/8).
        let mut bytes = std::fs::read(&cine).unwrap();
        bytes[(1 << 20) + (1 << 20) + 10] = 8;
        std::fs::write(&cine, &bytes).unwrap();
        assert_ne!(c.content_sha256, fingerprint(&cine).unwrap().content_sha256);
        assert!(fingerprint(&dir.path().join("nowhere")).is_err());
    }

    #[test]
    fn key_changes_with_code_configuration_run_and_input_but_not_output_folder() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.cine");
        std::fs::write(&p, b"CI").unwrap();
        let fp = fingerprint(&p).unwrap();
        let (c, r) = (cfg(), run(&p));
        let k = key(&c, &r, &fp);
        assert_eq!(k.len(), 64);
        let mut c2 = c.clone();
        c2.output.dir = PathBuf::from("elsewhere");
        assert_eq!(k, key(&c2, &r, &fp));
        c2.detect.contact_margin_px = 3.0;
        assert_ne!(k, key(&c2, &r, &fp));
        let mut r2 = r.clone();
        r2.sphere_radius_mm = 4.0;
        assert_ne!(k, key(&c, &r2, &fp));
        let mut fp2 = fp.clone();
        fp2.modified_ns += 1;
        assert_ne!(k, key(&c, &r, &fp2));
        // Other code: a build from other sources computes another key.
        assert!(SOURCE_SHA256.len() == 64 && SOURCE_SHA256.bytes().all(|b| b.is_ascii_hexdigit()));
        assert_eq!(k, key_for_source(SOURCE_SHA256, &c, &r, &fp));
        assert_ne!(k, key_for_source(&"0".repeat(64), &c, &r, &fp));
    }

    #[test]
    fn key_is_the_same_for_one_input_named_from_two_folders() {
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("ux");
        std::fs::create_dir(&sub).unwrap();
        let p = sub.join("m.cine");
        std::fs::write(&p, b"CI").unwrap();
        let fp = fingerprint(&p).unwrap();
        let mut c = cfg();
        c.input.manifest = Some(sub.join("runs.csv"));
        let k = key(&c, &run(&p), &fp);
        // The same file by a path with a detour, and by a link to its folder.
        let detour = sub.join("..").join("ux").join("m.cine");
        let link = dir.path().join("link");
        std::os::unix::fs::symlink(&sub, &link).unwrap();
        for other in [detour, link.join("m.cine")] {
            let mut c2 = c.clone();
            c2.input.manifest = Some(other.with_file_name("runs.csv"));
            let fp2 = Fingerprint {
                path: other.clone(),
                ..fp.clone()
            };
            assert_eq!(k, key(&c2, &run(&other), &fp2), "{}", other.display());
        }
        // Another file is another key.
        let q = sub.join("n.cine");
        std::fs::write(&q, b"CI").unwrap();
        let fq = Fingerprint {
            path: q.clone(),
            ..fp.clone()
        };
        assert_ne!(k, key(&c, &run(&q), &fq));
    }

    #[test]
    fn job_id_follows_kind_configuration_and_runs_but_not_output_folder() {
        let (c, r) = (cfg(), run(Path::new("a.cine")));
        let id = job_id("run", &c, std::slice::from_ref(&r));
        assert_eq!(id.len(), 64);
        let mut c2 = c.clone();
        c2.output.dir = PathBuf::from("elsewhere");
        assert_eq!(id, job_id("run", &c2, std::slice::from_ref(&r)));
        c2.detect.contact_margin_px = 3.0;
        assert_ne!(id, job_id("run", &c2, std::slice::from_ref(&r)));
        assert_ne!(id, job_id("process", &c, std::slice::from_ref(&r)));
        assert_ne!(id, job_id("run", &c, &[r.clone(), r]));
    }

    #[test]
    fn lookup_misses_on_other_key_missing_output_or_damage() {
        let (_dir, out) = crate::test_support::out_with_tracks(&[("a.csv", b"frame\n1\n")]);
        let out = &out;
        let mut entry = crate::test_support::cache_entry(
            "a",
            "k1",
            vec![OutputFile::new("tracks/a.csv".into(), b"frame\n1\n")],
        );
        entry.input = Fingerprint {
            path: "x".into(),
            kind: "cine".into(),
            size_bytes: 1,
            files: 1,
            modified_ns: 2,
            content_sha256: "00".into(),
        };
        store(out, &entry).unwrap();
        let sealed = lookup(out, "a", "k1").unwrap();
        assert!(sealed.is_sealed());
        assert_eq!(
            sealed,
            Entry {
                entry_sha256: sealed.entry_sha256.clone(),
                ..entry.clone()
            }
        );
        assert_eq!(lookup(out, "a", "k2"), None);
        assert_eq!(lookup(out, "b", "k1"), None);
        // Emptied, or one byte altered: a miss.
        std::fs::write(out.join("tracks/a.csv"), b"").unwrap();
        assert_eq!(lookup(out, "a", "k1"), None);
        std::fs::write(out.join("tracks/a.csv"), b"frame\n2\n").unwrap();
        assert_eq!(lookup(out, "a", "k1"), None);
        std::fs::write(out.join("tracks/a.csv"), b"frame\n1\n").unwrap();
        assert!(lookup(out, "a", "k1").is_some());
        // Listed outside the output folder: a miss, whatever is there.
        let mut outside = entry.clone();
        outside.outputs[0].path = "../a.csv".into();
        std::fs::write(out.join("../a.csv"), b"frame\n1\n").unwrap();
        store(out, &outside).unwrap();
        assert_eq!(lookup(out, "a", "k1"), None);
        store(out, &entry).unwrap();
        std::fs::remove_file(out.join("tracks/a.csv")).unwrap();
        assert_eq!(lookup(out, "a", "k1"), None);
        std::fs::write(entry_path(out, "a").unwrap(), b"{ damaged").unwrap();
        assert_eq!(lookup(out, "a", "k1"), None);
    }

    /// A number of the record changed by hand in runs/<run>.json: the seal
    /// no longer matches and the entry is not reused, saying so.
    #[test]
    fn an_entry_changed_by_hand_is_not_reused() {
        let (_dir, out) = crate::test_support::out_with_tracks(&[("a.csv", b"frame\n1\n")]);
        let mut entry = crate::test_support::cache_entry(
            "a",
            "k1",
            vec![OutputFile::new("tracks/a.csv".into(), b"frame\n1\n")],
        );
        entry.record.v_impact_m_s = Some(1.5);
        store(&out, &entry).unwrap();
        assert!(check(&out, "a", "k1").is_ok());
        let path = entry_path(&out, "a").unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("\"v_impact_m_s\": 1.5"), "{text}");
        std::fs::write(
            &path,
            text.replace("\"v_impact_m_s\": 1.5", "\"v_impact_m_s\": 9.99"),
        )
        .unwrap();
        assert_eq!(check(&out, "a", "k1"), Err(Miss::Altered(path.clone())));
        assert!(listed_outputs(&out, "a").is_empty());
        // Its seal blanked too: still not dropscope's.
        let text = std::fs::read_to_string(&path).unwrap();
        let blank = blank_seal(&text);
        std::fs::write(&path, blank).unwrap();
        assert!(matches!(check(&out, "a", "k1"), Err(Miss::Altered(_))));
    }

    /// `text` with the value of `entry_sha256` emptied.
    fn blank_seal(text: &str) -> String {
        let key = "\"entry_sha256\": \"";
        let start = text.find(key).unwrap() + key.len();
        let end = start + text[start..].find('"').unwrap();
        format!("{}{}", &text[..start], &text[end..])
    }
}
