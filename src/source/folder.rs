//! Folders of numbered frames, as Phantom Camera Control exports them
//! (formats/phantom.md §12): `<prefix><number>.<ext>` with TIFF (8/16-bit,
//! any compression), PNG (8/16-bit), BMP (8-bit grey read as is) or JPEG,
//! plus PCC's XML side file for frame rate, exposure, bit depth and times.
//!
//! Naming: the number is the run of digits before the extension, negative
//! when the character before it is a `-` that is itself at the start of the
//! name or preceded by a non-alphanumeric character (`run_-00005.tif` is
//! −5, `run-00005.tif` is 5 with prefix `run-`). Numbers need not be
//! zero-padded and are sorted numerically. One sequence per folder: the
//! largest group of files sharing prefix and extension; files outside it
//! (notes, a stray `background.tif`) are ignored and listed in the warnings.
//! Missing numbers are reported as gaps; frame index `i` is the `i`-th file
//! present, and its time comes from its number, so a gap never shifts time.
//!
//! Opening reads the first frame's header only: its size and bit depth are
//! the sequence's. Every other file's header is read with its rows, and a
//! file of another size or bit depth is an error naming it and its frame
//! when it is read (probing all 6 166 files of a long movie at open took a
//! tenth of its CPU time).
//!
//! A frame file's bytes are decoded by [`super::frame_decode`] (the first
//! one's header when the folder is opened, each one's header and rows on
//! each read), which says what is parsed here and what goes through the
//! `png` and `image` crates.

use std::path::{Path, PathBuf};

use ndarray::ArrayViewMut2;

use super::frame_decode::{format_err, io_err, FrameDecoder, ImageKind, Probe, Shape};
use super::listing::Listing;
use super::pcc_xml::{self, PccXml};
use super::{
    check_band, ColourInput, Frame, FrameNames, FrameNumbers, FrameSource, OpenOptions,
    SourceDetails, SourceError, SourceMeta,
};

/// Split a file name into `(prefix, number, kind)`, or `None` when it is not
/// a numbered image (see the module documentation for the sign rule).
pub fn parse_frame_name(name: &str) -> Option<(String, i64, ImageKind)> {
    parse_frame_name_split(name, None)
}

/// [`parse_frame_name`] reading at most the last `number_digits` digits of
/// the name as its number (the manifest's `number_digits`), the digits
/// before them as part of the prefix; `None`: every digit before the
/// extension.
pub fn parse_frame_name_split(
    name: &str,
    number_digits: Option<usize>,
) -> Option<(String, i64, ImageKind)> {
    let (stem, ext) = name.rsplit_once('.')?;
    let kind = ImageKind::from_extension(ext)?;
    let run = stem.bytes().rev().take_while(u8::is_ascii_digit).count();
    let take = number_digits.map_or(run, |n| run.min(n));
    if take == 0 || take > 18 {
        return None;
    }
    let digits_start = stem.len() - take;
    let digits = &stem[digits_start..];
    let value: i64 = digits.parse().ok()?;
    let before = &stem[..digits_start];
    let negative = before.strip_suffix('-').is_some_and(|rest| {
        rest.chars()
            .last()
            .is_none_or(|c| !c.is_ascii_alphanumeric())
    });
    if negative {
        Some((before[..before.len() - 1].to_string(), -value, kind))
    } else {
        Some((before.to_string(), value, kind))
    }
}

/// How the digits at the end of a sequence's names divide into the end of
/// the name and the frame number, when they can be read two ways: every
/// name has the same number of digits, they begin alike with a digit other
/// than 0 followed by zeros (`E_0094_2` + `0000000169` or `E_0094_` +
/// `20000000169`), and the names differ further on. Returns (the digits
/// read as the number, the other reading's), or `None` when the names
/// allow one reading only. The shorter number is chosen when the common
/// zeros are 3 or more, the zero padding of a counter after a name
/// ending in a digit; else all the digits.
pub fn number_split(digit_runs: &[&str]) -> Option<(usize, usize)> {
    let first = *digit_runs.first()?;
    let len = first.len();
    if digit_runs.len() < 2 || digit_runs.iter().any(|d| d.len() != len) {
        return None;
    }
    let common = digit_runs.iter().fold(len, |n, d| {
        first
            .bytes()
            .zip(d.bytes())
            .take(n)
            .take_while(|(a, b)| a == b)
            .count()
    });
    let c = &first.as_bytes()[..common];
    if common == len || c.first().is_none_or(|&b| b == b'0') {
        return None;
    }
    let z = c.iter().position(|&b| b == b'0')?;
    let zeros = c[z..].iter().take_while(|&&b| b == b'0').count();
    if zeros < 2 {
        return None;
    }
    let short = len - z;
    Some(if zeros >= 3 {
        (short, len)
    } else {
        (len, short)
    })
}

/// The files of a sequence: `<prefix><number>.<ext>` with the number
/// zero-padded to one width (as PCC names them), and the names that are
/// not so (by frame index): what is held does not grow with the number of
/// frames when they follow the pattern.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameFiles {
    dir: PathBuf,
    prefix: String,
    ext: String,
    /// Digits of a number (zero-padded to this), its sign apart.
    digits: usize,
    /// `(frame index, file name)` of the files not named by the pattern.
    others: Vec<(usize, String)>,
    /// Image number minus the number in the file's name: not 0 when the
    /// files were renumbered (from 0, as `dropscope export` names them)
    /// and the side file says which images they are ([`align_side_file`]).
    renumbered: i64,
}

impl FrameFiles {
    /// The files `(number, name)` of a sequence in `dir`, in index order,
    /// their numbers the last `number_digits` digits of their names (all
    /// the digits: `None`).
    fn new(dir: &Path, frames: &[(i64, String)], number_digits: Option<usize>) -> Self {
        let (prefix, ext, digits) = frames
            .first()
            .and_then(|(_, name)| {
                let (prefix, _, _) = parse_frame_name_split(name, number_digits)?;
                let (stem, ext) = name.rsplit_once('.')?;
                let run = stem.bytes().rev().take_while(u8::is_ascii_digit).count();
                let digits = number_digits.map_or(run, |n| run.min(n));
                Some((prefix, ext.to_string(), digits))
            })
            .unwrap_or_default();
        let mut files = FrameFiles {
            dir: dir.to_path_buf(),
            prefix,
            ext,
            digits,
            others: Vec::new(),
            renumbered: 0,
        };
        for (i, (number, name)) in frames.iter().enumerate() {
            if files.named(*number) != *name {
                files.others.push((i, name.clone()));
            }
        }
        files
    }

    /// The name the pattern gives number `n`.
    fn named(&self, n: i64) -> String {
        let sign = if n < 0 { "-" } else { "" };
        let (p, e, w) = (&self.prefix, &self.ext, self.digits);
        format!("{p}{sign}{:0w$}.{e}", n.unsigned_abs())
    }

    /// The file of frame `index`, whose number is `number`.
    pub fn path(&self, index: usize, number: i64) -> PathBuf {
        match self.others.binary_search_by_key(&index, |o| o.0) {
            Ok(k) => self.dir.join(&self.others[k].1),
            Err(_) => self.dir.join(self.named(number - self.renumbered)),
        }
    }

    /// Bytes held on the heap.
    pub fn heap_bytes(&self) -> usize {
        let others: usize = self.others.iter().map(|o| o.1.capacity()).sum();
        self.dir.capacity()
            + self.prefix.capacity()
            + self.ext.capacity()
            + self.others.capacity() * std::mem::size_of::<(usize, String)>()
            + others
    }
}

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
    pub fn open_listed(mut listing: Listing, options: &OpenOptions) -> Result<Self, SourceError> {
        let recordings = listing.recordings_text();
        let has_dirs = !listing.dirs.is_empty();
        // The names are moved, not copied (a long movie's are megabytes).
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
        let dir = dir.as_path();
        // Group numbered images by (prefix, kind); pick the largest group.
        let mut groups: std::collections::BTreeMap<(String, ImageKind), Vec<(i64, String)>> =
            Default::default();
        let xmls: Vec<String> = names
            .iter()
            .filter(|n| n.to_ascii_lowercase().ends_with(".xml"))
            .cloned()
            .collect();
        let lone = lone_export(&names, &xmls);
        let mut others = Vec::new();
        let given_digits = options.number_digits;
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
                    super::SUPPORTED_INPUTS
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
        let (prefix, kind) = (prefix.clone(), *kind);
        let mut warnings = Vec::new();
        for ((p, k), v) in &groups {
            if (p, *k) != (&prefix, kind) {
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
        let mut frames = groups.remove(&(prefix.clone(), kind)).unwrap_or_default();
        // Digits that can be read two ways: the split chosen, said.
        let mut prefix = prefix;
        let mut number_digits = given_digits;
        let mut names_note = None;
        let split = match (given_digits, &lone) {
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
        let mut xml_warnings = Vec::new();
        let xml = pick_xml(dir, &prefix, &xmls, &mut xml_warnings);

        // The PCC XML side file.
        warnings.extend(xml_warnings);
        let xml = xml?;
        let (xml_path, mut xml) = match xml {
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
            Some(b) if (1..=first.bits).contains(&b) => b,
            _ => first.bits,
        };
        if let Some((name, stem, _)) = &lone {
            let from_xml = xml.as_ref().and_then(|x| {
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
            frame_numbers = FrameNumbers::consecutive(number, 1);
            warnings.push(format!(
                "{name} is a single-frame PCC export (named like its side file {stem}.xml, \
                 not numbered): read as image {number}, {why}"
            ));
        }
        if let (Some(x), Some(path), None) = (&xml, &xml_path, &lone) {
            files.renumbered = align_side_file(x, path, &mut frame_numbers, &mut warnings)?;
        }
        let timestamps_s = xml.as_ref().and_then(|x| {
            let (times, note) = times_per_frame(&x.times, &frame_numbers, fps);
            warnings.extend(note);
            times
        });
        let exposures_s = xml
            .as_ref()
            .and_then(|x| per_frame(&x.exposures, &frame_numbers));
        if let Some(x) = &mut xml {
            // Each frame's values are in the two tables now.
            (x.times, x.exposures) = (Vec::new(), Vec::new());
        }
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
        super::validate::check_meta(&mut src.meta)?;
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

/// The folder's only image when an XML side file is named like it
/// (`cam_1.tif` beside `cam_1.xml`, `12bpp.tif` beside `12bpp.xml`): PCC's
/// export of a single image, named after its cine rather than numbered, so
/// that a number at the end of its name (the 1 of `cam_1`) is no image
/// number. Returns (file name, stem, kind).
fn lone_export(names: &[String], xmls: &[String]) -> Option<(String, String, ImageKind)> {
    let split = |n: &str| {
        n.rsplit_once('.')
            .map(|(a, b)| (a.to_string(), b.to_string()))
    };
    let mut images = names.iter().filter_map(|n| {
        let (stem, ext) = split(n)?;
        Some((n.clone(), stem, ImageKind::from_extension(&ext)?))
    });
    let only = images.next()?;
    if images.next().is_some() {
        return None;
    }
    xmls.iter()
        .any(|x| split(x).is_some_and(|(stem, _)| stem == only.1))
        .then_some(only)
}

/// Missing numbers between consecutive present ones, as inclusive ranges.
fn gaps_of(numbers: &FrameNumbers) -> Vec<(i64, i64)> {
    let mut gaps = Vec::new();
    let mut prev: Option<i64> = None;
    for n in numbers.iter() {
        if let Some(p) = prev.filter(|&p| n > p + 1) {
            gaps.push((p + 1, n - 1));
        }
        prev = Some(n);
    }
    gaps
}

/// Values for exactly the present frame numbers, or `None` if any is missing.
fn per_frame(by_number: &[(i64, f64)], numbers: &FrameNumbers) -> Option<Vec<f64>> {
    if by_number.is_empty() {
        return None;
    }
    // PCC lists its frames in order: a copy to sort only when they are not
    // (the stable sort leaves a sorted list as it is: the same lookups).
    let sorted: std::borrow::Cow<[(i64, f64)]> = if by_number.is_sorted_by_key(|t| t.0) {
        by_number.into()
    } else {
        let mut sorted = by_number.to_vec();
        sorted.sort_by_key(|t| t.0);
        sorted.into()
    };
    numbers
        .iter()
        .map(|n| {
            sorted
                .binary_search_by_key(&n, |t| t.0)
                .ok()
                .map(|i| sorted[i].1)
        })
        .collect()
}

/// Check that the side file at `path` describes the frames beside it:
/// the images it names (`FirstImageNo` and `ImageCount`, else its
/// TIMEBLOCK's first and last frame) must hold the files' numbers. Files
/// numbered otherwise but as many and in a row (from 0, as `dropscope
/// export` names them) are those images renumbered: `numbers` become the
/// side file's, with a warning, and the shift from the names is returned.
/// A side file describing other images is refused naming both ranges: its
/// times, rate and exposure would be applied to frames they do not belong to.
fn align_side_file(
    x: &PccXml,
    path: &Path,
    numbers: &mut FrameNumbers,
    warnings: &mut Vec<String>,
) -> Result<i64, SourceError> {
    let (Some(n0), Some(n1)) = (numbers.first(), numbers.last()) else {
        return Ok(0);
    };
    let n = numbers.len() as u64;
    let described = match (x.first_image_no, x.image_count) {
        (Some(f0), Some(c)) if c > 0 => Some((f0, c, "its FirstImageNo and ImageCount")),
        _ => {
            let lo = x.times.iter().map(|t| t.0).min();
            let hi = x.times.iter().map(|t| t.0).max();
            lo.zip(hi)
                .map(|(lo, hi)| (lo, hi.abs_diff(lo) + 1, "its TIMEBLOCK"))
        }
    };
    let Some((f0, c, by)) = described else {
        return Ok(0);
    };
    let f1 = f0.saturating_add(i64::try_from(c - 1).unwrap_or(i64::MAX));
    if n0 >= f0 && n1 <= f1 {
        return Ok(0);
    }
    let in_a_row = n1.abs_diff(n0) + 1 == n;
    if in_a_row && n == c {
        let shift = f0 - n0;
        *numbers = FrameNumbers::consecutive(f0, numbers.len());
        warnings.push(format!(
            "the {n} files are numbered {n0}…{n1}, the side file {} describes images {f0}…{f1} \
             ({by}): the same frames renumbered (as `dropscope export` names them), read as \
             images {f0}…{f1}",
            path.display()
        ));
        return Ok(shift);
    }
    Err(format_err(
        path,
        format!(
            "this side file describes images {f0}…{f1} ({c} frames, {by}) but the frame files \
             beside it are numbered {n0}…{n1} ({n} files): it is not their side file, and its \
             frame rate and times are not applied to them. Put the sequence's own side file \
             there, or remove this one and give the frame rate (--fps, or the manifest's fps)"
        ),
    ))
}

/// The frame times of `numbers` from the side file's TIMEBLOCK (frame,
/// seconds), and a warning when it lists none for some of them: those are
/// placed on the frame rate's grid from the nearest frame it lists, and
/// the warning (starting [`super::validate::TIMES_INCOMPLETE`]) says how
/// many, so that the run is flagged. A block listing none of the frames
/// is not used, with a warning.
fn times_per_frame(
    by_number: &[(i64, f64)],
    numbers: &FrameNumbers,
    fps: f64,
) -> (Option<Vec<f64>>, Option<String>) {
    if by_number.is_empty() {
        return (None, None);
    }
    let mut sorted = by_number.to_vec();
    sorted.sort_by_key(|t| t.0);
    let listed: Vec<Option<f64>> = numbers
        .iter()
        .map(|n| {
            sorted
                .binary_search_by_key(&n, |t| t.0)
                .ok()
                .map(|i| sorted[i].1)
        })
        .collect();
    let missing: Vec<i64> = numbers
        .iter()
        .zip(&listed)
        .filter(|(_, t)| t.is_none())
        .map(|(n, _)| n)
        .collect();
    if missing.is_empty() {
        return (Some(listed.into_iter().flatten().collect()), None);
    }
    let anchors: Vec<(i64, f64)> = numbers
        .iter()
        .zip(&listed)
        .filter_map(|(n, t)| t.map(|t| (n, t)))
        .collect();
    let example = missing
        .iter()
        .take(3)
        .map(|n| n.to_string())
        .collect::<Vec<_>>();
    if anchors.is_empty() {
        return (
            None,
            Some(format!(
                "{}: the side file's TIMEBLOCK lists none of the {} frames (frames {}…): its \
                 times are not used, frame times are frame number / fps",
                super::validate::TIMES_INCOMPLETE,
                numbers.len(),
                example.join(", ")
            )),
        );
    }
    let filled = numbers
        .iter()
        .zip(&listed)
        .map(|(n, t)| {
            t.unwrap_or_else(|| {
                let k = anchors.partition_point(|a| a.0 < n);
                let near = match (k.checked_sub(1).map(|i| anchors[i]), anchors.get(k)) {
                    (Some(a), Some(b)) if n - a.0 <= b.0 - n => a,
                    (Some(a), None) => a,
                    (_, Some(b)) => *b,
                    (None, None) => unreachable!("anchors is not empty"),
                };
                near.1 + (n - near.0) as f64 / fps
            })
        })
        .collect();
    (
        Some(filled),
        Some(format!(
            "{}: the side file's TIMEBLOCK has no time for {} of the {} frames (frame {}{}); \
             theirs are placed on the frame rate's grid from the nearest listed frame",
            super::validate::TIMES_INCOMPLETE,
            missing.len(),
            numbers.len(),
            example.join(", "),
            if missing.len() > 3 { ", …" } else { "" }
        )),
    )
}

/// The folder's PCC XML: the one named like the sequence prefix, else the
/// only `<chd>` XML there. Several candidates without a name match → error.
/// An XML that is not PCC's (no `<chd`, not UTF-8 text) is ignored with a
/// warning, unless it is named like the sequence: that one must be a
/// readable side file. Each is looked through once for those two, then
/// read as a stream (`pcc_xml::read`), never held whole.
fn pick_xml(
    dir: &Path,
    prefix: &str,
    xmls: &[String],
    warnings: &mut Vec<String>,
) -> Result<Option<(PathBuf, PccXml)>, SourceError> {
    let trimmed = prefix.trim_end_matches(['_', '-', ' ', '.']);
    let mut parsed = Vec::new();
    for name in xmls {
        let path = dir.join(name);
        let named_like_sequence = path.file_stem().and_then(|s| s.to_str()) == Some(trimmed);
        let look = look_through(&path).map_err(io_err(&path))?;
        if !look.utf8 {
            if named_like_sequence {
                return Err(format_err(&path, "the PCC side file is not UTF-8 text"));
            }
            warnings.push(format!(
                "ignored {name}: not UTF-8 text, not a PCC side file"
            ));
            continue;
        }
        if !look.chd {
            continue; // some other XML, not PCC's
        }
        let file = crate::util::io::open_regular(&path).map_err(io_err(&path))?;
        let x = pcc_xml::read(std::io::BufReader::with_capacity(1 << 16, file))
            .map_err(|r| format_err(&path, r))?;
        parsed.push((path, x));
    }
    if parsed.len() <= 1 {
        return Ok(parsed.pop());
    }
    let matching: Vec<_> = parsed
        .into_iter()
        .filter(|(p, _)| p.file_stem().and_then(|s| s.to_str()) == Some(trimmed))
        .collect();
    match matching.len() {
        1 => Ok(matching.into_iter().next()),
        _ => Err(format_err(
            dir,
            format!(
                "several PCC XML side files and none named {trimmed}.xml: keep the one of this sequence"
            ),
        )),
    }
}

fn contains(hay: &[u8], needle: &[u8]) -> bool {
    hay.windows(needle.len()).any(|w| w == needle)
}

/// What a look through an XML file found.
#[derive(Debug, PartialEq)]
struct XmlLook {
    /// The whole file is UTF-8.
    utf8: bool,
    /// It holds `<chd` (PCC's root element) somewhere.
    chd: bool,
}

/// Read `path` through in blocks of 64 kB, keeping the last 3 bytes of
/// each (the start of a `<chd` or of a character cut by the block's end).
fn look_through(path: &Path) -> std::io::Result<XmlLook> {
    use std::io::Read;
    const KEPT: usize = 3;
    let mut file = crate::util::io::open_regular(path)?;
    let mut buf = vec![0u8; (1 << 16) + KEPT];
    let mut look = XmlLook {
        utf8: true,
        chd: false,
    };
    // Bytes at buf's start from the block before, and how many of them
    // are an unfinished character.
    let (mut kept, mut unfinished) = (0, 0);
    loop {
        let n = match file.read(&mut buf[kept..]) {
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        let end = kept + n;
        look.chd = look.chd || contains(&buf[..end], b"<chd");
        if look.utf8 {
            match std::str::from_utf8(&buf[kept - unfinished..end]) {
                Ok(_) => unfinished = 0,
                Err(e) if e.error_len().is_none() && n > 0 => {
                    unfinished = end - (kept - unfinished) - e.valid_up_to();
                }
                Err(_) => look.utf8 = false,
            }
        }
        if n == 0 {
            return Ok(look);
        }
        kept = KEPT.min(end);
        buf.copy_within(end - kept..end, 0);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_split_into_prefix_number_and_kind() {
        let p = |n: &str| parse_frame_name(n).map(|(a, b, _)| (a, b));
        assert_eq!(p("run_000012.tif"), Some(("run_".into(), 12)));
        assert_eq!(p("run_-00005.tif"), Some(("run_".into(), -5)));
        assert_eq!(p("-3.png"), Some(("".into(), -3)));
        assert_eq!(p("img-0004.png"), Some(("img-".into(), 4)));
        assert_eq!(p("img--4.png"), Some(("img-".into(), -4)));
        assert_eq!(p("Img7.BMP"), Some(("Img".into(), 7)));
        assert_eq!(p("notes.txt"), None);
        assert_eq!(p("background.tif"), None);
        assert_eq!(p("run.xml"), None);
    }

    #[test]
    fn gaps_are_inclusive_ranges_of_missing_numbers() {
        let numbers = |v: &[i64]| v.iter().copied().collect::<FrameNumbers>();
        assert_eq!(
            gaps_of(&numbers(&[-2, -1, 0, 3, 4, 6])),
            vec![(1, 2), (5, 5)]
        );
        assert!(gaps_of(&numbers(&[5])).is_empty());
    }

    /// The look through a side file finds `<chd` and checks UTF-8 across
    /// its 64 kB blocks: a character or the tag cut by a block's end.
    #[test]
    fn a_look_through_sees_across_its_blocks() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.xml");
        let look = |bytes: &[u8]| {
            std::fs::write(&path, bytes).unwrap();
            let l = look_through(&path).unwrap();
            (l.utf8, l.chd)
        };
        let block = 1 << 16;
        for cut in 1..4 {
            // "<chd" and a 3-byte character ending `cut` bytes into the next block.
            let mut chd = vec![b' '; block - 4 + cut];
            chd.extend_from_slice(b"<chd");
            assert_eq!(look(&chd), (true, true), "<chd cut at {cut}");
            let mut euro = vec![b' '; block - 3 + cut];
            euro.extend_from_slice("\u{20ac}<ch".as_bytes());
            assert_eq!(look(&euro), (true, false), "a character cut at {cut}");
            let mut broken = euro.clone();
            broken[block - 3 + cut + 1] = b'x';
            assert_eq!(look(&broken), (false, false));
            // A character the file ends inside.
            assert_eq!(look(&euro[..block - 3 + cut + 2]), (false, false));
        }
        assert_eq!(look(b""), (true, false));
        assert_eq!(look(b"\xff<chd>"), (false, true));
    }
}
