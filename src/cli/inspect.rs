//! `dropscope inspect` and `dropscope export` (SPEC §6): what a folder or
//! `.cine` holds, and frames exactly as read written out as 16-bit PNG.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use serde_json::json;

use crate::config::PipelineConfig;
use crate::source::{open, Frame, FrameSource, OpenOptions, P10Mode, SourceError, SourceMeta};

/// Options shared by the commands that open a source.
#[derive(Debug, Clone, clap::Args)]
pub struct SourceArgs {
    /// Frame rate to assume when the input carries none (a folder without a
    /// PCC XML), a number > 0. Default: camera.fps of the configuration.
    #[arg(long, value_parser = crate::util::flag_values::positive, allow_negative_numbers = true)]
    pub fps: Option<f64>,
    /// The configuration whose camera.fps is the fallback frame rate
    /// (default: ./pipeline.toml, else the embedded default).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Apply the recorded viewer flips (bFlipV/bFlipH): the picture as PCC shows it.
    /// By default frames are returned in storage orientation.
    #[arg(long)]
    pub apply_flips: bool,
    /// P10 packed cines: return linearised 12-bit values instead of the raw 10-bit codes.
    #[arg(long)]
    pub p10_linear: bool,
    /// Folders of frames: read the last N digits of a file's name as its
    /// number, the digits before them as part of the name (as the
    /// manifest's number_digits column).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(1..=18))]
    pub number_digits: Option<u8>,
}

impl SourceArgs {
    /// Open `input`; when it holds no frame rate, use the fallback resolved
    /// as `process` does: `--fps`, else camera.fps of the configuration
    /// (`--config`, else ./pipeline.toml, else the embedded default). The
    /// configuration is read only then. Returns the source and, when the
    /// fallback was used, where its frame rate came from. An input left
    /// without a frame rate is an error saying where to set one.
    pub fn open_source(
        &self,
        input: &Path,
    ) -> anyhow::Result<(Box<dyn FrameSource>, Option<String>)> {
        let has_fps = |m: &SourceMeta| m.fps.is_finite() && m.fps > 0.0;
        let mut options = self.options();
        options.fps_fallback = None;
        match open(input, &options) {
            Ok(src) if has_fps(src.meta()) => return Ok((src, None)),
            Ok(_) | Err(SourceError::NoFrameRate { .. }) => {}
            Err(e) => return Err(e.into()),
        }
        let (fallback, origin, problem) = match self.fps {
            Some(f) => (Some(f), "--fps".to_string(), None),
            None => match PipelineConfig::load_resolved(self.config.as_deref()) {
                Ok((cfg, name)) => (cfg.camera.fps, format!("camera.fps in {name}"), None),
                Err(e) => (None, String::new(), Some(e.to_string())),
            },
        };
        if fallback.is_some() {
            options.fps_fallback = fallback;
            let src = open(input, &options)?;
            if has_fps(src.meta()) {
                return Ok((src, Some(origin)));
            }
        }
        let config = match &self.config {
            Some(p) => p.display().to_string(),
            None if Path::new("pipeline.toml").exists() => "./pipeline.toml".into(),
            None => "pipeline.toml (none here; or pass --config FILE)".into(),
        };
        let mut msg = format!(
            "{}: no frame rate: the input holds none (a folder without its PCC XML side \
             file, or a cine header without one); give --fps, or set camera.fps in {config}",
            input.display()
        );
        if let Some(p) = problem {
            msg.push_str(&format!("; the configuration could not be read: {p}"));
        }
        bail!(msg)
    }

    /// The corresponding [`OpenOptions`] (frame-rate fallback from `--fps` only).
    pub fn options(&self) -> OpenOptions {
        OpenOptions {
            fps_fallback: self.fps,
            apply_flips: self.apply_flips,
            p10: if self.p10_linear {
                P10Mode::Linear
            } else {
                P10Mode::Raw
            },
            number_digits: self.number_digits.map(usize::from),
        }
    }
}

/// `dropscope inspect INPUT [--json]`.
#[derive(Debug, Clone, clap::Args)]
pub struct InspectArgs {
    /// A folder of frames or a `.cine` file.
    pub input: PathBuf,
    /// Print JSON (keys: frames, width, height, fps, first_frame, bit_depth,
    /// exposure_s, gaps, and more).
    #[arg(long)]
    pub json: bool,
    /// How to open the input.
    #[command(flatten)]
    pub source: SourceArgs,
}

/// `dropscope export INPUT --frames A:B --out DIR`.
#[derive(Debug, Clone, clap::Args)]
#[command(group(clap::ArgGroup::new("range").required(true).args(["frames", "numbers"])))]
pub struct ExportArgs {
    /// A folder of frames or a `.cine` file.
    pub input: PathBuf,
    /// Frame indices A..B−1, counted from 0 (e.g. `0:10`; `A:` = to the
    /// end; `A` alone = that one frame).
    #[arg(long, allow_hyphen_values = true)]
    pub frames: Option<String>,
    /// Camera image numbers A..B−1, as in the file names and `--overlay-frames`
    /// (e.g. `-100:-90`; `A` alone = that one frame).
    #[arg(long, allow_hyphen_values = true)]
    pub numbers: Option<String>,
    /// Shift the values up to fill 16 bits (12-bit data × 16), so that a
    /// viewer shows the picture; by default values are written as stored.
    #[arg(long)]
    pub scale_to_16: bool,
    /// Output folder (created if needed).
    #[arg(long)]
    pub out: PathBuf,
    /// How to open the input.
    #[command(flatten)]
    pub source: SourceArgs,
}

/// Run `inspect`: the report, for stdout.
pub fn run_inspect(args: &InspectArgs) -> anyhow::Result<()> {
    let (src, fps_origin) = args.source.open_source(&args.input)?;
    let mut meta = src.meta().clone();
    if let Some(origin) = fps_origin {
        meta.details.warnings.push(format!(
            "the input holds no frame rate: fps {} from {origin}",
            meta.fps
        ));
    }
    let report = inspect_report(&meta, args.json)?;
    // Text from the file (a cine's camera name, file names) never reaches
    // the terminal as escape sequences; a closed pipe is no panic.
    if args.json {
        crate::util::console::out_raw(&format!("{report}\n"));
    } else {
        crate::outln!("{report}");
    }
    Ok(())
}

/// The inspect report as JSON (`json`) or as aligned text.
pub fn inspect_report(m: &SourceMeta, json: bool) -> Result<String, crate::source::SourceError> {
    let times = m.timestamps_s.as_ref();
    // The first and the last time stamp, when there are any.
    let (first_time, last_time) = match times.filter(|t| !t.is_empty()) {
        Some(t) => (t.get(0)?, t.get(t.len() - 1)?),
        None => (None, None),
    };
    let times = [first_time, last_time];
    Ok(if json {
        inspect_json(m, times)
    } else {
        inspect_text(m, times)
    })
}

/// The inspect report as JSON; `times`: the first and the last time stamp.
fn inspect_json(m: &SourceMeta, [first_time, last_time]: [Option<f64>; 2]) -> String {
    let d = &m.details;
    let value = json!({
        "path": m.path.display().to_string(),
        "format": m.format,
        "frames": m.frame_count,
        "width": m.width,
        "height": m.height,
        "fps": m.fps,
        "first_frame": m.first_frame,
        "last_frame": m.frame_numbers.last(),
        "bit_depth": m.bit_depth,
        "exposure_s": m.exposure_s,
        "gaps": m.gaps.iter().map(|(a, b)| [a, b]).collect::<Vec<_>>(),
        "container": d.container,
        "black_level": d.black_level,
        "white_level": d.white_level,
        "flip_h": d.flip_h,
        "flip_v": d.flip_v,
        "rotate_deg": d.rotate_deg,
        "flips_applied": d.flips_applied,
        "acquisition_fps": d.acquisition_fps,
        "decimation": d.decimation,
        "camera": d.camera,
        "software_version": d.software_version,
        "setup_length": d.setup_length,
        "side_file": d.side_file.as_ref().map(|p| p.display().to_string()),
        "has_timestamps": m.timestamps_s.is_some(),
        "first_time_s": first_time,
        "last_time_s": last_time,
        "name_prefix": d.frame_names.as_ref().map(|n| n.prefix.clone()),
        "number_digits": d.frame_names.as_ref().map(|n| n.number_digits),
        "colour": d.colour.as_ref().map(|c| c.name()),
        "bayer": match &d.colour {
            Some(crate::source::ColourInput::Bayer(b)) => Some(b.name()),
            _ => None,
        },
        "warnings": d.warnings,
    });
    let doc = serde_json::to_string_pretty(&value).unwrap_or_default();
    crate::util::text::json(&doc).into_owned()
}

/// The inspect report as aligned text; `times`: the first and the last
/// time stamp.
fn inspect_text(m: &SourceMeta, [first_time, last_time]: [Option<f64>; 2]) -> String {
    let d = &m.details;
    let opt = |v: Option<String>| v.unwrap_or_else(|| "—".into());
    let mut lines = vec![
        format!("path          {}", m.path.display()),
        format!("format        {} ({})", m.format, d.container),
        format!(
            "frames        {} (numbers {} … {})",
            m.frame_count,
            m.first_frame,
            m.frame_numbers.last().unwrap_or(m.first_frame)
        ),
        format!(
            "size          {} × {} px (width × height)",
            m.width, m.height
        ),
        format!("bit depth     {}", m.bit_depth),
        format!(
            "fps           {}{}",
            m.fps,
            match d.acquisition_fps {
                Some(a) if d.decimation != 1.0 =>
                    format!(" (recorded at {a}, saved with decimation {})", d.decimation),
                _ => String::new(),
            }
        ),
        format!(
            "exposure      {}",
            opt(m.exposure_s.map(|e| format!("{:.3} µs", e * 1e6)))
        ),
        format!("gaps          {}", gaps_text(&m.gaps)),
        format!(
            "black/white   {} / {}",
            opt(d.black_level.map(|v| v.to_string())),
            opt(d.white_level.map(|v| v.to_string()))
        ),
        format!(
            "flips         flip_v {} flip_h {} rotate {}° ({})",
            d.flip_v,
            d.flip_h,
            d.rotate_deg,
            if d.flips_applied {
                "applied"
            } else {
                "not applied: storage orientation"
            }
        ),
        format!(
            "time stamps   {}",
            match (first_time, last_time) {
                (Some(a), Some(b)) => format!("{a:.9} s … {b:.9} s after the trigger"),
                _ => "none (times from frame number / fps)".into(),
            }
        ),
    ];
    if let Some(c) = &d.camera {
        let mut line = format!("camera        {c}");
        if let Some(v) = d.software_version {
            line.push_str(&format!(", software {v}"));
        }
        if let Some(v) = d.setup_length {
            line.push_str(&format!(", SETUP length {v}"));
        }
        lines.push(line);
    }
    if let Some(s) = &d.side_file {
        lines.push(format!("side file     {}", s.display()));
    }
    if let Some(n) = &d.frame_names {
        lines.push(format!(
            "frame names   {:?} + {}-digit number",
            n.prefix, n.number_digits
        ));
    }
    if let Some(c) = &d.colour {
        lines.push(format!("colour        {}", c.describe()));
    }
    for w in &d.warnings {
        lines.push(format!("warning       {w}"));
    }
    lines.join("\n")
}

/// The gaps in the frame numbers, `a…b` each (`none`).
fn gaps_text(gaps: &[(i64, i64)]) -> String {
    if gaps.is_empty() {
        return "none".to_string();
    }
    gaps.iter()
        .map(|(a, b)| {
            if a == b {
                format!("{a}")
            } else {
                format!("{a}…{b}")
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// `--numbers A:B` (or `A`): the indices of camera numbers A..B−1.
fn number_range(
    text: &str,
    numbers: &crate::source::FrameNumbers,
) -> anyhow::Result<std::ops::Range<usize>> {
    let parse = |s: &str| -> anyhow::Result<i64> {
        s.trim()
            .parse()
            .with_context(|| format!("--numbers {text:?}: {s:?} is not a camera number"))
    };
    let (a, b) = match text.split_once(':') {
        Some((a, b)) => (
            parse(a)?,
            if b.trim().is_empty() {
                i64::MAX
            } else {
                parse(b)?
            },
        ),
        None => {
            let a = parse(text)?;
            (a, a + 1)
        }
    };
    let first = numbers.iter().position(|n| n >= a);
    let end = numbers.iter().rposition(|n| n < b).map(|i| i + 1);
    match (first, end, numbers.first(), numbers.last()) {
        (Some(i), Some(j), _, _) if i < j => Ok(i..j),
        (_, _, Some(lo), Some(hi)) => {
            bail!("--numbers {text:?}: no frame in that range (the input holds camera numbers {lo} to {hi})")
        }
        _ => bail!("--numbers {text:?}: the input holds no frame"),
    }
}

/// Parse `--frames A:B` (or `A:`, or `A`) into the index range `A..B` within
/// `count` frames: `A:` runs to the end, `A` is that frame alone.
pub fn parse_frame_range(text: &str, count: usize) -> anyhow::Result<std::ops::Range<usize>> {
    if text.trim_start().starts_with('-') {
        bail!(
            "--frames {text:?}: --frames counts the input's frames from 0 (0 to {}); \
             camera image numbers such as {text} go to --numbers",
            count.saturating_sub(1)
        );
    }
    let Some((a, b)) = text.split_once(':') else {
        let a: usize = text
            .trim()
            .parse()
            .with_context(|| format!("--frames {text:?}: expected A:B or A, e.g. 0:10"))?;
        if a >= count {
            bail!("--frames {text:?}: need A < {count} (the input has {count} frames)");
        }
        return Ok(a..a + 1);
    };
    let a: usize = a
        .trim()
        .parse()
        .with_context(|| format!("--frames {text:?}: start {a:?} is not an index"))?;
    let b: usize = if b.trim().is_empty() {
        count
    } else {
        b.trim()
            .parse()
            .with_context(|| format!("--frames {text:?}: end {b:?} is not an index"))?
    };
    if a >= b || b > count {
        bail!("--frames {text:?}: need 0 ≤ A < B ≤ {count} (the input has {count} frames)");
    }
    Ok(a..b)
}

/// Run `export`: frames A..B as 16-bit grey PNGs `<name>_<index>.png`, the
/// 0-based index of the frame in the input zero-padded to one width (as
/// PCC's image counter), so that a plain listing sorts in frame order
/// (camera numbers do not: `-98` sorts before `-100`). Each file's camera
/// number and time are in the side file `<name>_frames.csv`
/// ([`ExportedFrame`]; rows of earlier exports into the folder kept).
/// Values as read (not rescaled), rows top-down. Returns the files written.
pub fn run_export(args: &ExportArgs) -> anyhow::Result<Vec<PathBuf>> {
    let (mut src, _) = args.source.open_source(&args.input)?;
    let meta = src.meta().clone();
    let range = match (&args.frames, &args.numbers) {
        (Some(f), _) => parse_frame_range(f, meta.frame_count)?,
        (None, Some(n)) => number_range(n, &meta.frame_numbers)?,
        (None, None) => bail!("give --frames A:B (indices) or --numbers A:B (camera numbers)"),
    };
    let width = meta.frame_count.saturating_sub(1).to_string().len();
    let shift = if args.scale_to_16 {
        16u32.saturating_sub(u32::from(meta.bit_depth))
    } else {
        0
    };
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let stem = crate::source::input_name(&args.input);
    let mut frame = Frame::zeros((meta.height, meta.width));
    let mut written = Vec::new();
    let mut rows = Vec::new();
    for i in range {
        src.read_into(i, &mut frame)?;
        let name = format!("{stem}_{i:0width$}.png");
        let path = args.out.join(&name);
        if shift > 0 {
            frame.mapv_inplace(|v| (u32::from(v) << shift).min(65535) as u16);
        }
        let bytes = png16(&frame).with_context(|| format!("encoding {}", path.display()))?;
        crate::util::io::write_atomic(&path, &bytes)
            .with_context(|| format!("writing {}", path.display()))?;
        rows.push(ExportedFrame {
            file: name,
            index: i,
            camera_number: meta.frame_number(i),
            time_s: meta.time_s(i)?,
        });
        written.push(path);
    }
    let side = args.out.join(format!("{stem}_frames.csv"));
    crate::util::io::write_atomic(&side, &frames_csv(&side, rows))
        .with_context(|| format!("writing {}", side.display()))?;
    Ok(written)
}

/// A row of export's side file `<name>_frames.csv`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ExportedFrame {
    /// The PNG's file name.
    pub file: String,
    /// The frame's 0-based index in the input (as in the name and `--frames`).
    pub index: usize,
    /// Its camera image number (as `--numbers` and PCC; negative before the trigger).
    pub camera_number: i64,
    /// Its time after the trigger, seconds.
    pub time_s: f64,
}

/// The side file's bytes: `new` rows, with the rows of the file already at
/// `path` for files not written again, sorted by file name.
fn frames_csv(path: &Path, new: Vec<ExportedFrame>) -> Vec<u8> {
    let old: Vec<ExportedFrame> = csv::Reader::from_path(path)
        .map(|mut r| r.deserialize().flatten().collect())
        .unwrap_or_default();
    let rows: std::collections::BTreeMap<String, ExportedFrame> = old
        .into_iter()
        .chain(new)
        .map(|r| (r.file.clone(), r))
        .collect();
    crate::dataset::csv_bytes(rows.values())
}

/// Encode a frame as a 16-bit grey PNG.
pub fn png16(frame: &Frame) -> Result<Vec<u8>, png::EncodingError> {
    let (h, w) = frame.dim();
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, w as u32, h as u32);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Sixteen);
        let mut writer = enc.write_header()?;
        let data: Vec<u8> = frame.iter().flat_map(|v| v.to_be_bytes()).collect();
        writer.write_image_data(&data)?;
        writer.finish()?;
    }
    Ok(out)
}
