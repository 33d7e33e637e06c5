//! [`FolderSource`]: a folder of numbered frames opened for random access.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use ndarray::ArrayViewMut2;

use super::names::{number_split, parse_frame_name, parse_frame_name_split, FrameFiles};
use super::side_file::{
    align_side_file, gaps_of, lone_export, per_frame, pick_xml, times_per_frame,
};
use crate::source::frame_decode::{format_err, io_err, FrameDecoder, ImageKind, Probe, Shape};
use crate::source::listing::Listing;
use crate::source::pcc_xml::PccXml;
use crate::source::{
    check_band, ColourInput, Frame, FrameNames, FrameNumbers, FrameSource, OpenOptions,
    SourceDetails, SourceError, SourceMeta,
};

/// A folder of numbered frames opened for random access.
pub struct FolderSource {
    meta: SourceMeta,
    /// Shared by the copies of [`FrameSource::try_clone`].
    files: std::sync::Arc<FrameFiles>,
    kind: ImageKind,
    /// Bits per sample of the files (8 or 16).
    container_bits: u8,
    decoder: FrameDecoder,
}

impl std::fmt::Debug for FolderSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FolderSource")
            .field("meta", &self.meta)
            .field("files", &self.files)
            .finish()
    }
}

impl FolderSource {
    /// List `dir`, pick its frame sequence, read its first file's header and
    /// the PCC XML side file if there is one.
    pub fn open(dir: &Path, options: &OpenOptions) -> Result<Self, SourceError> {
        Self::open_listed(Listing::of(dir)?, options)
    }

    /// [`FolderSource::open`] on a folder already listed. Frame files and
    /// XMLs named like a recording beside them (its PCC export) are left
    /// out; recordings beside the sequence are named in a warning.
    pub fn open_listed(listing: Listing, options: &OpenOptions) -> Result<Self, SourceError> {
        let recordings = listing.recordings_text();
        let has_dirs = !listing.dirs.is_empty();
        let (names, dir, not_files) = candidates(listing);
        let dir = dir.as_path();
        let xmls: Vec<String> = names
            .iter()
            .filter(|n| n.to_ascii_lowercase().ends_with(".xml"))
            .cloned()
            .collect();
        let lone = lone_export(&names, &xmls);
        let given_digits = options.number_digits;
        let (mut groups, others) = group_frames(names, given_digits, &lone);
        let (prefix, kind) = pick_sequence(&groups, dir, &recordings, has_dirs)?;
        let mut warnings =
            ignored_warnings(&groups, (&prefix, kind), &others, &recordings, &not_files);
        let mut frames = groups.remove(&(prefix.clone(), kind)).unwrap_or_default();
        let (prefix, number_digits, names_note) =
            split_numbers(&mut frames, prefix, given_digits, &lone);
        frames.sort();
        if let Some(w) = frames.windows(2).find(|w| w[0].0 == w[1].0) {
            return Err(format_err(
                &dir.join(&w[1].1),
                format!("frame number {} also belongs to {}", w[0].0, w[0].1),
            ));
        }
        let mut files = FrameFiles::new(dir, &frames, number_digits);
        if let Some(note) = &names_note {
            warnings.push(note.clone());
        }
        let mut frame_numbers: FrameNumbers = frames.iter().map(|(n, _)| *n).collect();
        let gaps = gaps_of(&frame_numbers);
        let file = |i: usize| files.path(i, frames[i].0);
        if let ([(n, name)], None) = (frames.as_slice(), &lone) {
            warnings.push(format!(
                "one frame file only, {name}: its image number {n} is read from its name \
                 (no PCC side file named like it to say which image it is)"
            ));
        }

        // The first frame's header gives the sequence's size and depth; the
        // others are checked against it as each is read (the decoder reads
        // the header anyway), not here: opening must not touch every file.
        let first = open_and_probe(&file(0), kind, &mut FrameDecoder::for_headers())?;
        let side = read_side_file(dir, &prefix, &xmls, first.bits, options, &mut warnings)?;
        let (xml_path, mut xml, fps, bit_depth) = (side.path, side.xml, side.fps, side.bit_depth);
        if let Some((name, stem, _)) = &lone {
            frame_numbers = lone_numbers(name, stem, xml.as_ref(), &mut warnings);
        }
        if let (Some(x), Some(path), None) = (&xml, &xml_path, &lone) {
            files.renumbered = align_side_file(x, path, &mut frame_numbers, &mut warnings)?;
        }
        let (timestamps_s, exposures_s) =
            values_per_frame(&mut xml, &frame_numbers, fps, &mut warnings);
        let meta = SourceMeta {
            path: dir.to_path_buf(),
            format: kind.name().into(),
            frame_count: frames.len(),
            width: first.width,
            height: first.height,
            bit_depth,
            fps,
            exposure_s: xml.as_ref().and_then(|x| x.exposure_s),
            first_frame: frame_numbers.first().unwrap_or_default(),
            frame_numbers,
            gaps,
            timestamps_s: timestamps_s.map(Into::into),
            details: SourceDetails {
                container: format!("{} {}-bit", kind.name(), first.bits),
                black_level: xml.as_ref().and_then(|x| x.black_level),
                white_level: xml.as_ref().and_then(|x| x.white_level),
                flip_h: xml.as_ref().and_then(|x| x.flip_h).unwrap_or(false),
                flip_v: xml.as_ref().and_then(|x| x.flip_v).unwrap_or(false),
                rotate_deg: 0,
                flips_applied: false,
                exposures_s: exposures_s.map(Into::into),
                acquisition_fps: None,
                decimation: 1.0,
                camera: None,
                software_version: None,
                setup_length: None,
                side_file: xml_path,
                warnings,
                colour: first.colour.then_some(ColourInput::Rgb),
                frame_names: Some(FrameNames {
                    prefix: prefix.clone(),
                    number_digits: files.digits,
                    note: names_note,
                }),
                p10: None,
            },
        };
        drop(frames);
        let mut src = FolderSource {
            meta,
            files: files.into(),
            kind,
            container_bits: first.bits,
            decoder: FrameDecoder::for_frames(),
        };
        crate::source::validate::check_meta(&mut src.meta)?;
        src.check_real_bpp()?;
        Ok(src)
    }

    /// PCC's 16-bit TIFF exports hold values scaled to 0‥65535 while their
    /// XML still says RealBPP 12 (it describes the camera data): when frame
    /// 0 holds a value above `2^RealBPP − 1`, the bit depth is the
    /// container's and a warning says why.
    fn check_real_bpp(&mut self) -> Result<(), SourceError> {
        let bits = self.meta.bit_depth;
        let container = self.container_bits;
        if bits >= container {
            return Ok(());
        }
        let mut f = Frame::zeros((self.meta.height, self.meta.width));
        self.read_into(0, &mut f)?;
        let max = f.iter().copied().max().unwrap_or(0);
        if u32::from(max) >= 1 << bits {
            self.meta.bit_depth = container;
            self.meta.details.warnings.push(format!(
                "frame 0 holds {max}, above the XML's RealBPP {bits} range: \
                 the frames are scaled to {container} bits (a PCC 16-bit export), \
                 bit_depth set to {container}"
            ));
        }
        Ok(())
    }

    /// The file of frame `index`.
    pub fn file(&self, index: usize) -> PathBuf {
        self.files.path(index, self.meta.frame_number(index))
    }

    /// The frame files.
    pub fn files(&self) -> &FrameFiles {
        &self.files
    }
}

/// Open a frame file and read its header.
fn open_and_probe(
    path: &Path,
    kind: ImageKind,
    decoder: &mut FrameDecoder,
) -> Result<Probe, SourceError> {
    let (mut file, len) = crate::util::io::open_regular_len(path).map_err(io_err(path))?;
    decoder.probe(path, &mut file, len, kind)
}

impl FrameSource for FolderSource {
    fn meta(&self) -> &SourceMeta {
        &self.meta
    }

    /// The same files, with buffers of its own.
    fn try_clone(&self) -> Option<Box<dyn FrameSource>> {
        Some(Box::new(FolderSource {
            meta: self.meta.clone(),
            files: self.files.clone(),
            kind: self.kind,
            container_bits: self.container_bits,
            decoder: FrameDecoder::for_frames(),
        }))
    }

    fn read_rows_into(
        &mut self,
        index: usize,
        row0: usize,
        out: &mut ArrayViewMut2<u16>,
    ) -> Result<(), SourceError> {
        self.read_cols(index, row0, None, out)
    }

    fn read_window_into(
        &mut self,
        index: usize,
        row0: usize,
        cols: &[std::ops::Range<usize>],
        out: &mut ArrayViewMut2<u16>,
    ) -> Result<(), SourceError> {
        self.read_cols(index, row0, Some(cols), out)
    }
}

impl FolderSource {
    fn read_cols(
        &mut self,
        index: usize,
        row0: usize,
        cols: Option<&[std::ops::Range<usize>]>,
        out: &mut ArrayViewMut2<u16>,
    ) -> Result<(), SourceError> {
        check_band(&self.meta, index, row0, out)?;
        let path = &self.file(index);
        let (mut file, len) = crate::util::io::open_regular_len(path).map_err(io_err(path))?;
        let first = self.file(0);
        let shape = Shape {
            width: self.meta.width,
            height: self.meta.height,
            bits: self.container_bits,
            first: &first,
        };
        self.decoder.read_rows(
            path, index, &mut file, len, self.kind, shape, row0, cols, out,
        )
    }
}

/// The names of a listed folder that may belong to its frame sequence:
/// frame files and XMLs named like a recording beside them (its PCC export)
/// left out; with the folder and its entries that are not regular files.
/// The names are moved, not copied (a long movie's are megabytes).
fn candidates(mut listing: Listing) -> (Vec<String>, PathBuf, Vec<String>) {
    let names: Vec<String> = if listing.recordings.is_empty() {
        listing.files
    } else {
        let (files, l) = (std::mem::take(&mut listing.files), &listing);
        files
            .into_iter()
            .filter(|n| !l.is_export(n) && !l.recordings.contains(n))
            .collect()
    };
    let Listing { dir, not_files, .. } = listing;
    (names, dir, not_files)
}

/// Numbered images grouped by (prefix, kind), the lone export's alone when
/// there is one, and the names that are neither frames nor XMLs.
#[allow(clippy::type_complexity)]
fn group_frames(
    names: Vec<String>,
    given_digits: Option<usize>,
    lone: &Option<(String, String, ImageKind)>,
) -> (
    BTreeMap<(String, ImageKind), Vec<(i64, String)>>,
    Vec<String>,
) {
    let mut groups: BTreeMap<(String, ImageKind), Vec<(i64, String)>> = Default::default();
    let mut others = Vec::new();
    for name in names {
        if let Some((prefix, number, kind)) = parse_frame_name_split(&name, given_digits) {
            groups
                .entry((prefix, kind))
                .or_default()
                .push((number, name));
        } else if !name.to_ascii_lowercase().ends_with(".xml") {
            others.push(name);
        }
    }
    if let Some((name, stem, kind)) = &lone {
        // Its number comes from the XML below; the name is not parsed.
        groups.clear();
        groups.insert((stem.clone(), *kind), vec![(0, name.clone())]);
        others.retain(|o| o != name);
    }
    (groups, others)
}

/// The sequence: the largest group (prefix, kind); an error when there is
/// none or two tie.
fn pick_sequence(
    groups: &BTreeMap<(String, ImageKind), Vec<(i64, String)>>,
    dir: &Path,
    recordings: &Option<String>,
    has_dirs: bool,
) -> Result<(String, ImageKind), SourceError> {
    let Some(best) = groups.values().map(Vec::len).max() else {
        let what = if let Some(r) = &recordings {
            format!(
                "no numbered frames (<prefix><number>.tif|png|bmp|jpg) in this folder, \
                 but {r}: give the one to read as the input (or list them in a runs.csv)"
            )
        } else if has_dirs {
            "no numbered frames (<prefix><number>.tif|png|bmp|jpg) in this folder, \
             only sub-folders: give the run folders themselves, or list them in a \
             runs.csv and use --manifest"
                .to_string()
        } else {
            format!(
                "no numbered frames (<prefix><number>.tif|png|bmp|jpg) in this folder; \
                 dropscope reads {}",
                crate::source::SUPPORTED_INPUTS
            )
        };
        return Err(format_err(dir, what));
    };
    let mut tied = groups.iter().filter(|(_, v)| v.len() == best);
    let ((prefix, kind), _) = tied.next().expect("a largest group exists");
    if let Some(((p2, k2), _)) = tied.next() {
        return Err(format_err(
            dir,
            format!(
                "two frame sequences of {best} files each ({prefix:?}… {} files and \
                 {p2:?}… {} files): keep one sequence per folder",
                kind.name(),
                k2.name()
            ),
        ));
    }
    Ok((prefix.clone(), *kind))
}

/// Warnings naming what the sequence leaves out: other groups of frames,
/// other files, recordings beside it, entries that are not regular files.
fn ignored_warnings(
    groups: &BTreeMap<(String, ImageKind), Vec<(i64, String)>>,
    (prefix, kind): (&String, ImageKind),
    others: &[String],
    recordings: &Option<String>,
    not_files: &[String],
) -> Vec<String> {
    let mut warnings = Vec::new();
    for ((p, k), v) in groups {
        if (p, *k) != (prefix, kind) {
            warnings.push(format!(
                "ignored {} file(s) outside the sequence, e.g. {}",
                v.len(),
                v[0].1
            ));
        }
    }
    if !others.is_empty() {
        let shown: Vec<&str> = others.iter().take(5).map(String::as_str).collect();
        warnings.push(format!(
            "ignored {} non-frame file(s): {}{}",
            others.len(),
            shown.join(", "),
            if others.len() > 5 { ", …" } else { "" }
        ));
    }
    if let Some(r) = &recordings {
        warnings.push(format!(
            "this folder also holds {r}, not read with its frame sequence: give each \
             as an input of its own"
        ));
    }
    if !not_files.is_empty() {
        warnings.push(format!(
            "ignored {} entries that are not regular files (named pipes, sockets, \
             devices or broken links), e.g. {}",
            not_files.len(),
            not_files[0]
        ));
    }
    warnings
}

/// Digits that can be read two ways: the split chosen (the frames'
/// numbers and the prefix read with it), and the note that says so.
/// Returns the prefix, the number's digits and the note.
fn split_numbers(
    frames: &mut [(i64, String)],
    prefix: String,
    given_digits: Option<usize>,
    lone: &Option<(String, String, ImageKind)>,
) -> (String, Option<usize>, Option<String>) {
    let mut prefix = prefix;
    let mut number_digits = given_digits;
    let mut names_note = None;
    let split = match (given_digits, lone) {
        (None, None) if frames.iter().all(|(n, _)| *n >= 0) => {
            let runs: Vec<&str> = frames
                .iter()
                .filter_map(|(_, name)| {
                    let stem = name.rsplit_once('.')?.0;
                    let run = stem.bytes().rev().take_while(u8::is_ascii_digit).count();
                    Some(&stem[stem.len() - run..])
                })
                .collect();
            number_split(&runs)
        }
        _ => None,
    };
    if let Some((chosen, other)) = split {
        let example = frames[0].1.clone();
        let all = example.rsplit_once('.').map_or(0, |(stem, _)| {
            stem.bytes().rev().take_while(u8::is_ascii_digit).count()
        });
        if chosen < all {
            for f in frames.iter_mut() {
                if let Some((p, n, _)) = parse_frame_name_split(&f.1, Some(chosen)) {
                    f.0 = n;
                    prefix = p;
                }
            }
            number_digits = Some(chosen);
        }
        let reading = |d: usize| {
            let a = if matches!(d, 8 | 11 | 18) { "an" } else { "a" };
            match parse_frame_name_split(&example, Some(d)) {
                Some((p, n, _)) => format!("name {p:?} and {a} {d}-digit frame number ({n} …)"),
                None => format!("{a} {d}-digit frame number"),
            }
        };
        names_note = Some(format!(
            "the frame names ({example} …) end in {all} digits that read two ways: taken \
             as {}, not as {}; set number_digits = {other} in the run's manifest row to \
             read them the other way",
            reading(chosen),
            reading(other)
        ));
    }
    (prefix, number_digits, names_note)
}

/// What the PCC XML side file (or the options without one) says of the
/// sequence.
struct SideValues {
    path: Option<PathBuf>,
    xml: Option<PccXml>,
    fps: f64,
    /// The XML's RealBPP when it fits the container, else the container's.
    bit_depth: u8,
}

/// The PCC XML side file, the frame rate and the bit depth; its warnings
/// into `warnings`.
fn read_side_file(
    dir: &Path,
    prefix: &str,
    xmls: &[String],
    container_bits: u8,
    options: &OpenOptions,
    warnings: &mut Vec<String>,
) -> Result<SideValues, SourceError> {
    let mut xml_warnings = Vec::new();
    let xml = pick_xml(dir, prefix, xmls, &mut xml_warnings);
    warnings.extend(xml_warnings);
    let xml = xml?;
    let (path, xml) = match xml {
        Some((p, x)) => (Some(p), Some(x)),
        None => (None, None),
    };
    let fps = match xml.as_ref().and_then(|x| x.fps) {
        Some(f) if f.is_finite() && f > 0.0 => f,
        _ => match options.fps_fallback {
            Some(f) if f.is_finite() && f > 0.0 => f,
            _ => {
                return Err(SourceError::NoFrameRate {
                    path: dir.to_path_buf(),
                })
            }
        },
    };
    // Bit depth: the XML's RealBPP when it fits the container, else the container's.
    let bit_depth = match xml.as_ref().and_then(|x| x.real_bpp) {
        Some(b) if (1..=container_bits).contains(&b) => b,
        _ => container_bits,
    };
    Ok(SideValues {
        path,
        xml,
        fps,
        bit_depth,
    })
}

/// The image number of a single-frame PCC export (`name`, named like its
/// side file `stem.xml`): the XML's, else the one in its name, else 0; a
/// warning says which.
fn lone_numbers(
    name: &str,
    stem: &str,
    xml: Option<&PccXml>,
    warnings: &mut Vec<String>,
) -> FrameNumbers {
    let from_xml = xml.and_then(|x| {
        x.first_image_no
            .map(|n| (n, "FirstImageNo"))
            .or_else(|| x.times.first().map(|t| (t.0, "first time stamp")))
    });
    let in_name = parse_frame_name(name).map(|(_, n, _)| n);
    let (number, why) = match (from_xml, in_name) {
        (Some((n, field)), Some(m)) if m != n => {
            (n, format!("the XML's {field}, not the {m} in its name"))
        }
        (Some((n, field)), _) => (n, format!("the XML's {field}")),
        (None, Some(m)) => (m, "the number in its name: the XML says none".into()),
        (None, None) => (0, "0: neither its name nor the XML says which".into()),
    };
    warnings.push(format!(
        "{name} is a single-frame PCC export (named like its side file {stem}.xml, \
         not numbered): read as image {number}, {why}"
    ));
    FrameNumbers::consecutive(number, 1)
}

/// Each frame's time stamp and exposure from the side file (its warnings
/// into `warnings`), moved out of it.
fn values_per_frame(
    xml: &mut Option<PccXml>,
    frame_numbers: &FrameNumbers,
    fps: f64,
    warnings: &mut Vec<String>,
) -> (Option<Vec<f64>>, Option<Vec<f64>>) {
    let timestamps_s = xml.as_ref().and_then(|x| {
        let (times, note) = times_per_frame(&x.times, frame_numbers, fps);
        warnings.extend(note);
        times
    });
    let exposures_s = xml
        .as_ref()
        .and_then(|x| per_frame(&x.exposures, frame_numbers));
    if let Some(x) = xml.as_mut() {
        // Each frame's values are in the two tables now.
        (x.times, x.exposures) = (Vec::new(), Vec::new());
    }
    (timestamps_s, exposures_s)
}
