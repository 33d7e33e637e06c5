//! Frame file names (module doc, naming): their prefix, number and kind,
//! and the [`FrameFiles`] of a sequence.

use std::path::{Path, PathBuf};

use crate::source::frame_decode::ImageKind;

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
    pub(super) digits: usize,
    /// `(frame index, file name)` of the files not named by the pattern.
    others: Vec<(usize, String)>,
    /// Image number minus the number in the file's name: not 0 when the
    /// files were renumbered (from 0, as `dropscope export` names them)
    /// and the side file says which images they are ([`super::side_file::align_side_file`]).
    pub(super) renumbered: i64,
}

impl FrameFiles {
    /// The files `(number, name)` of a sequence in `dir`, in index order,
    /// their numbers the last `number_digits` digits of their names (all
    /// the digits: `None`).
    pub(super) fn new(dir: &Path, frames: &[(i64, String)], number_digits: Option<usize>) -> Self {
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
