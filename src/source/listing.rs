//! What a folder holds, from its entries' names and types only (no file is
//! opened): recording files (`.cine`, Photron `.mraw`), frame files, and
//! sub-folders. [`super::open`] reads a folder as its frame sequence, or as
//! its one recording when it holds no frames of its own; the job's search
//! for runs ([`Listing::runs_here`]) takes every recording and every folder
//! of frames.
//!
//! A frame file or XML named like a recording beside it (`cam_1.tif` and
//! `cam_1.xml` beside `cam_1.cine`) is that recording's export by Phantom
//! Camera Control, not a sequence of its own.

use std::path::{Path, PathBuf};

use super::frame_decode::ImageKind;
use super::{InputKind, SourceError};

/// The kind of a recording file by its extension: `.cine` → cine; `.mraw`,
/// `.cihx`, `.cih` → Photron (any case). `None` for anything else.
pub fn recording_kind(path: &Path) -> Option<InputKind> {
    let ext = path.extension()?.to_str()?;
    if ext.eq_ignore_ascii_case("cine") {
        Some(InputKind::Cine)
    } else if ["mraw", "cihx", "cih"]
        .iter()
        .any(|e| ext.eq_ignore_ascii_case(e))
    {
        Some(InputKind::Photron)
    } else {
        None
    }
}

/// Whether a folder entry named `name` is a recording that is a run: a
/// `.cine` or a `.mraw` (a Photron header is the MRAW's, not a run of its own).
fn is_recording(name: &str) -> bool {
    let ext = name.rsplit_once('.').map_or("", |(_, e)| e);
    ext.eq_ignore_ascii_case("cine") || ext.eq_ignore_ascii_case("mraw")
}

fn stem(name: &str) -> &str {
    name.rsplit_once('.').map_or(name, |(s, _)| s)
}

/// A folder's entries, sorted by name.
#[derive(Debug, Clone, Default)]
pub struct Listing {
    /// The folder listed.
    pub dir: PathBuf,
    /// Regular files (links followed).
    pub files: Vec<String>,
    /// Sub-folders (links followed).
    pub dirs: Vec<String>,
    /// Entries that are neither: named pipes, sockets, devices, broken links.
    pub not_files: Vec<String>,
    /// The files that are recordings (`.cine`, `.mraw`), also in `files`.
    pub recordings: Vec<String>,
}

impl Listing {
    /// List `dir`: each entry's type from the listing itself, a link
    /// followed to what it names (a named pipe is never opened).
    pub fn of(dir: &Path) -> Result<Listing, SourceError> {
        let io = |source| SourceError::Io {
            path: dir.to_path_buf(),
            source,
        };
        let mut l = Listing {
            dir: dir.to_path_buf(),
            ..Listing::default()
        };
        for e in std::fs::read_dir(dir).map_err(io)? {
            let e = e.map_err(io)?;
            let Some(name) = e.file_name().to_str().map(str::to_string) else {
                continue;
            };
            let (is_dir, is_file) = match e.file_type() {
                Ok(t) if !t.is_symlink() => (t.is_dir(), t.is_file()),
                _ => match std::fs::metadata(e.path()) {
                    Ok(m) => (m.is_dir(), m.is_file()),
                    Err(_) => (false, false),
                },
            };
            if is_file {
                l.files.push(name);
            } else if is_dir {
                l.dirs.push(name);
            } else {
                l.not_files.push(name);
            }
        }
        l.files.sort();
        l.dirs.sort();
        l.not_files.sort();
        l.find_recordings();
        Ok(l)
    }

    /// Fill [`Listing::recordings`] from [`Listing::files`].
    pub fn find_recordings(&mut self) {
        self.recordings = self
            .files
            .iter()
            .filter(|n| is_recording(n))
            .cloned()
            .collect();
    }

    /// The recording files (`.cine`, `.mraw`), by name.
    pub fn recordings(&self) -> impl Iterator<Item = &str> {
        self.recordings.iter().map(String::as_str)
    }

    /// Whether `name` (a frame file or XML) is the export of a recording
    /// beside it: named like it (and not the recording itself).
    pub fn is_export(&self, name: &str) -> bool {
        let s = stem(name);
        !is_recording(name) && self.recordings().any(|r| stem(r) == s)
    }

    /// Whether the folder holds frames of its own: a frame file (TIFF, PNG,
    /// BMP, JPEG) or an XML side file that is not a recording's export.
    pub fn has_frames(&self) -> bool {
        self.files.iter().any(|n| {
            let ext = n.rsplit_once('.').map_or("", |(_, e)| e);
            (ImageKind::from_extension(ext).is_some() || ext.eq_ignore_ascii_case("xml"))
                && !self.is_export(n)
        })
    }

    /// The folder's only recording, when it holds no frames of its own:
    /// what reading the folder reads.
    pub fn lone_recording(&self) -> Option<PathBuf> {
        let mut r = self.recordings();
        let one = r.next()?;
        (r.next().is_none() && !self.has_frames()).then(|| self.dir.join(one))
    }

    /// The runs in this folder itself, in name order: every recording, and
    /// the folder when it holds frames of its own (first).
    pub fn runs_here(&self) -> Vec<PathBuf> {
        let mut out = Vec::new();
        if self.has_frames() {
            out.push(self.dir.clone());
        }
        out.extend(self.recordings().map(|r| self.dir.join(r)));
        out
    }

    /// The recordings said for a message: "3 recordings (a.cine, b.cine, c.mraw)".
    pub fn recordings_text(&self) -> Option<String> {
        let all: Vec<&str> = self.recordings().collect();
        if all.is_empty() {
            return None;
        }
        let shown: Vec<&str> = all.iter().take(5).copied().collect();
        Some(format!(
            "{} recording{} ({}{})",
            all.len(),
            if all.len() == 1 { "" } else { "s" },
            shown.join(", "),
            if all.len() > 5 { ", …" } else { "" }
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn listing(files: &[&str]) -> Listing {
        let mut l = Listing {
            dir: PathBuf::from("d"),
            files: files.iter().map(|s| s.to_string()).collect(),
            ..Listing::default()
        };
        l.find_recordings();
        l
    }

    #[test]
    fn exports_beside_their_cines_are_no_frames_of_the_folder() {
        let l = listing(&[
            "12bpp.cine",
            "12bpp.tif",
            "12bpp.xml",
            "cam_1.cine",
            "cam_1.tif",
        ]);
        assert!(!l.has_frames());
        assert_eq!(l.lone_recording(), None);
        assert_eq!(
            l.runs_here(),
            vec![PathBuf::from("d/12bpp.cine"), PathBuf::from("d/cam_1.cine")]
        );
        let one = listing(&["drop.cine", "drop.xml", "notes.txt"]);
        assert_eq!(one.lone_recording(), Some(PathBuf::from("d/drop.cine")));
        let mixed = listing(&["drop.cine", "run_000001.tif", "run_000002.tif"]);
        assert!(mixed.has_frames());
        assert_eq!(mixed.lone_recording(), None);
        assert_eq!(
            mixed.runs_here(),
            vec![PathBuf::from("d"), PathBuf::from("d/drop.cine")]
        );
        let photron = listing(&["ball.cihx", "ball.mraw"]);
        assert_eq!(photron.lone_recording(), Some(PathBuf::from("d/ball.mraw")));
    }
}
