//! `dropscope inspect` and `dropscope export` (SPEC §6): what a folder or
//! `.cine` holds, and frames exactly as read written out as 16-bit PNG.

use std::path::PathBuf;

use anyhow::{bail, Context};
use serde_json::json;

use super::{open, Frame, OpenOptions, P10Mode, SourceMeta};

/// Options shared by the commands that open a source.
#[derive(Debug, Clone, clap::Args)]
pub struct SourceArgs {
    /// Frame rate to assume when the input carries none (a folder without a PCC XML).
    #[arg(long)]
    pub fps: Option<f64>,
    /// Apply the recorded viewer flips (bFlipV/bFlipH): the picture as PCC shows it.
    /// By default frames are returned in storage orientation.
    #[arg(long)]
    pub apply_flips: bool,
    /// P10 packed cines: return linearised 12-bit values instead of the raw 10-bit codes.
    #[arg(long)]
    pub p10_linear: bool,
}

impl SourceArgs {
    /// The corresponding [`OpenOptions`].
    pub fn options(&self) -> OpenOptions {
        OpenOptions {
            fps_fallback: self.fps,
            apply_flips: self.apply_flips,
            p10: if self.p10_linear {
                P10Mode::Linear
            } else {
                P10Mode::Raw
            },
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
    #[command(flatten)]
    pub source: SourceArgs,
}

/// `dropscope export INPUT --frames A:B --out DIR`.
#[derive(Debug, Clone, clap::Args)]
pub struct ExportArgs {
    /// A folder of frames or a `.cine` file.
    pub input: PathBuf,
    /// Frame indices A..B−1, counted from 0 (e.g. `0:10`; `A:` = to the end).
    #[arg(long)]
    pub frames: String,
    /// Output folder (created if needed).
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub source: SourceArgs,
}

/// Run `inspect`: print the report on stdout.
pub fn run_inspect(args: &InspectArgs) -> anyhow::Result<()> {
    let src = open(&args.input, &args.source.options())?;
    println!("{}", inspect_report(src.meta(), args.json));
    Ok(())
}

/// The inspect report as JSON (`json`) or as aligned text.
pub fn inspect_report(m: &SourceMeta, json: bool) -> String {
    let d = &m.details;
    let times = m.timestamps_s.as_ref();
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
        "has_timestamps": times.is_some(),
        "first_time_s": times.and_then(|t| t.first()),
        "last_time_s": times.and_then(|t| t.last()),
        "warnings": d.warnings,
    });
    if json {
        return serde_json::to_string_pretty(&value).unwrap_or_default();
    }
    let opt = |v: Option<String>| v.unwrap_or_else(|| "—".into());
    let mut lines = vec![
        format!("path          {}", m.path.display()),
        format!("format        {} ({})", m.format, d.container),
        format!(
            "frames        {} (numbers {} … {})",
            m.frame_count,
            m.first_frame,
            m.frame_numbers.last().copied().unwrap_or(m.first_frame)
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
        format!(
            "gaps          {}",
            if m.gaps.is_empty() {
                "none".to_string()
            } else {
                m.gaps
                    .iter()
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
        ),
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
            match times {
                Some(t) if !t.is_empty() =>
                    format!("{:.9} s … {:.9} s after the trigger", t[0], t[t.len() - 1]),
                _ => "none (times from frame number / fps)".into(),
            }
        ),
    ];
    if let Some(c) = &d.camera {
        lines.push(format!(
            "camera        {c}, software {}, SETUP length {}",
            opt(d.software_version.map(|v| v.to_string())),
            opt(d.setup_length.map(|v| v.to_string()))
        ));
    }
    if let Some(s) = &d.side_file {
        lines.push(format!("side file     {}", s.display()));
    }
    for w in &d.warnings {
        lines.push(format!("warning       {w}"));
    }
    lines.join("\n")
}

/// Parse `A:B` (or `A:`) into the index range `A..B` within `count` frames.
pub fn parse_frame_range(text: &str, count: usize) -> anyhow::Result<std::ops::Range<usize>> {
    let (a, b) = text
        .split_once(':')
        .with_context(|| format!("--frames {text:?}: expected A:B, e.g. 0:10"))?;
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

/// Run `export`: frames A..B as 16-bit grey PNGs `<name>_<number>.png`,
/// values as read (not rescaled), rows top-down. Returns the files written.
pub fn run_export(args: &ExportArgs) -> anyhow::Result<Vec<PathBuf>> {
    let mut src = open(&args.input, &args.source.options())?;
    let meta = src.meta().clone();
    let range = parse_frame_range(&args.frames, meta.frame_count)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let stem = super::input_name(&args.input);
    let mut frame = Frame::zeros((meta.height, meta.width));
    let mut written = Vec::new();
    for i in range {
        src.read_into(i, &mut frame)?;
        let number = meta.frame_numbers[i];
        let path = args.out.join(format!("{stem}_{number}.png"));
        let bytes = png16(&frame).with_context(|| format!("encoding {}", path.display()))?;
        crate::io_util::write_atomic(&path, &bytes)
            .with_context(|| format!("writing {}", path.display()))?;
        written.push(path);
    }
    Ok(written)
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
