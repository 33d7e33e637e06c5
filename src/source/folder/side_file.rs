//! PCC's XML side file beside the frames: which one, whether it describes
//! them, and the frame times from it; and a lone exported image.

use std::path::{Path, PathBuf};

use crate::source::frame_decode::{format_err, io_err, ImageKind};
use crate::source::pcc_xml::{self, PccXml};
use crate::source::{FrameNumbers, SourceError};

/// The folder's only image when an XML side file is named like it
/// (`cam_1.tif` beside `cam_1.xml`, `12bpp.tif` beside `12bpp.xml`): PCC's
/// export of a single image, named after its cine rather than numbered, so
/// that a number at the end of its name (the 1 of `cam_1`) is no image
/// number. Returns (file name, stem, kind).
pub(super) fn lone_export(
    names: &[String],
    xmls: &[String],
) -> Option<(String, String, ImageKind)> {
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
pub(super) fn gaps_of(numbers: &FrameNumbers) -> Vec<(i64, i64)> {
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
pub(super) fn per_frame(by_number: &[(i64, f64)], numbers: &FrameNumbers) -> Option<Vec<f64>> {
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
pub(super) fn align_side_file(
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
/// the warning (starting [`crate::source::validate::TIMES_INCOMPLETE`]) says how
/// many, so that the run is flagged. A block listing none of the frames
/// is not used, with a warning.
pub(super) fn times_per_frame(
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
                crate::source::validate::TIMES_INCOMPLETE,
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
            crate::source::validate::TIMES_INCOMPLETE,
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
pub(super) fn pick_xml(
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
pub(super) struct XmlLook {
    /// The whole file is UTF-8.
    pub(super) utf8: bool,
    /// It holds `<chd` (PCC's root element) somewhere.
    pub(super) chd: bool,
}

/// Read `path` through in blocks of 64 kB, keeping the last 3 bytes of
/// each (the start of a `<chd` or of a character cut by the block's end).
pub(super) fn look_through(path: &Path) -> std::io::Result<XmlLook> {
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
