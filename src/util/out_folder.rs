//! The output folder: the one way a job writes, reads back or removes a
//! file inside it.
//!
//! - A path inside the folder is plain names only ([`crate::util::io::inside`]).
//! - No link under the folder is followed: every folder between the output
//!   folder and the file must be a real folder (`symlink_metadata`), folders
//!   are made one at a time, a temporary is created with `O_EXCL |
//!   O_NOFOLLOW`, and a file is read with `O_NOFOLLOW`. A planted link
//!   (`OUT/plots -> ~/photos`) stops the job with a message naming it. A link
//!   where a file is written is replaced (a rename does not follow it: its
//!   target is not touched). The output folder itself may be a link.
//! - A file is removed only when an earlier job listed it as its own with
//!   the SHA-256 of its bytes, and it still holds them: the run files in
//!   `provenance.json` and the run's cache entry ([`crate::job::leftovers`]); the
//!   job-level files (the collapse's tables and figures, the per-drop
//!   figures, `report.html`) in the folder's [`Ledger`],
//!   `.dropscope-files.json`. A file of yours, or one you changed, stays.

use std::collections::BTreeMap;
use std::fs;
use std::io::{self, Read, Write};
use std::path::{Component, Path, PathBuf};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::util::io::Durable;

/// `out/rel` once `rel` is checked to be plain names and no existing
/// component below `out` (the file's own name included) is a link.
pub fn path(out: &Path, rel: &str) -> io::Result<PathBuf> {
    let full = crate::util::io::inside(out, rel)?;
    let mut at = out.to_path_buf();
    for c in Path::new(rel).components() {
        let Component::Normal(name) = c else {
            unreachable!("inside() admits plain names only")
        };
        at.push(name);
        match fs::symlink_metadata(&at) {
            Ok(md) if md.file_type().is_symlink() => return Err(link(out, &at)),
            Ok(_) => {}
            Err(e) if e.kind() == io::ErrorKind::NotFound => break,
            Err(e) => return Err(e),
        }
    }
    Ok(full)
}

fn link(out: &Path, at: &Path) -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidInput,
        format!(
            "{} is a symbolic link: dropscope follows no link inside its output folder {} \
             (a link there could send its files, or its removals, anywhere); remove the link, \
             or give another --out",
            at.display(),
            out.display()
        ),
    )
}

/// Make the folder `out/rel_dir` and every folder between, each a real
/// folder (a link or a file in the way is an error naming it); the output
/// folder itself is made when missing (it may be a link).
pub fn create_dirs(out: &Path, rel_dir: &str) -> io::Result<PathBuf> {
    fs::create_dir_all(out)?;
    if rel_dir.is_empty() {
        return Ok(out.to_path_buf());
    }
    let full = crate::util::io::inside(out, rel_dir)?;
    let mut at = out.to_path_buf();
    for c in Path::new(rel_dir).components() {
        let Component::Normal(name) = c else {
            unreachable!("inside() admits plain names only")
        };
        at.push(name);
        loop {
            match fs::symlink_metadata(&at) {
                Ok(md) if md.file_type().is_symlink() => return Err(link(out, &at)),
                Ok(md) if md.is_dir() => break,
                Ok(_) => {
                    return Err(io::Error::new(
                        io::ErrorKind::AlreadyExists,
                        format!("{} is not a folder", at.display()),
                    ))
                }
                Err(e) if e.kind() == io::ErrorKind::NotFound => match fs::create_dir(&at) {
                    Err(e) if e.kind() != io::ErrorKind::AlreadyExists => return Err(e),
                    // Made, or made by another shard meanwhile: look again.
                    _ => continue,
                },
                Err(e) => return Err(e),
            }
        }
    }
    Ok(full)
}

/// Write what `write` writes to `out/rel` atomically
/// ([`crate::util::io::write_atomic_as`]), making its folders
/// ([`create_dirs`]); returns the full path.
pub fn write_as(
    out: &Path,
    rel: &str,
    durable: Durable,
    write: impl FnOnce(&mut fs::File) -> io::Result<()>,
) -> io::Result<PathBuf> {
    let parent = Path::new(rel).parent().unwrap_or(Path::new(""));
    create_dirs(out, &parent.to_string_lossy())?;
    let full = path(out, rel)?;
    crate::util::io::write_atomic_as(&full, durable, write)?;
    Ok(full)
}

/// [`write_as`] of `bytes`, synced.
pub fn write(out: &Path, rel: &str, bytes: &[u8]) -> io::Result<PathBuf> {
    write_as(out, rel, Durable::Now, |f| f.write_all(bytes))
}

/// Open `out/rel` for reading: a regular file, reached through no link.
pub fn open(out: &Path, rel: &str) -> io::Result<fs::File> {
    let full = path(out, rel)?;
    open_no_follow(&full)
}

/// Open `path` for reading if it is a regular file and not a link (nor
/// blocking on a named pipe).
pub fn open_no_follow(path: &Path) -> io::Result<fs::File> {
    #[cfg(unix)]
    let f = {
        use std::os::unix::fs::OpenOptionsExt;
        fs::OpenOptions::new()
            .read(true)
            .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK)
            .open(path)?
    };
    #[cfg(not(unix))]
    let f = fs::File::open(path)?;
    if !f.metadata()?.is_file() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{} is not a regular file", path.display()),
        ));
    }
    Ok(f)
}

/// The bytes of `out/rel` ([`open`]), at most `limit`: `Ok(None)` when it
/// holds more.
pub fn read(out: &Path, rel: &str, limit: u64) -> io::Result<Option<Vec<u8>>> {
    let mut bytes = Vec::new();
    open(out, rel)?.take(limit + 1).read_to_end(&mut bytes)?;
    Ok((bytes.len() as u64 <= limit).then_some(bytes))
}

/// SHA-256 (hex) of `out/rel` ([`open`]).
pub fn sha256(out: &Path, rel: &str) -> io::Result<String> {
    let mut h = Sha256::new();
    io::copy(&mut open(out, rel)?, &mut h)?;
    Ok(hex(&h.finalize()))
}

/// SHA-256 (hex) of `bytes`.
pub fn sha256_of(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Remove `out/rel` if it is a regular file (not a link) holding the bytes
/// whose SHA-256 is `sha256`: a file dropscope wrote and nobody changed
/// since. Returns whether it was removed; a missing file, a link, a folder
/// or another content is left alone.
pub fn remove_if_holds(out: &Path, rel: &str, sha256_hex: &str) -> io::Result<bool> {
    match sha256(out, rel) {
        Ok(h) if h == sha256_hex => {}
        _ => return Ok(false),
    }
    let full = path(out, rel)?;
    match fs::remove_file(&full) {
        Ok(()) => Ok(true),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(false),
        Err(e) => Err(e),
    }
}

/// The ledger's file in the output folder.
pub const LEDGER_FILE: &str = ".dropscope-files.json";

/// A ledger larger than this is not read (a file takes ~100 bytes).
const LEDGER_MAX_BYTES: u64 = 256 << 20;

/// The job-level files dropscope wrote into an output folder (the
/// collapse's tables and figures, the per-drop figures, `report.html`),
/// each with the SHA-256 of its bytes, kept in [`LEDGER_FILE`]. Only a
/// file it lists and that still holds those bytes is removed by a later
/// job, and only such an SVG is inlined into the report. Missing or
/// damaged, it lists nothing: nothing is removed.
#[derive(Debug, Default, Serialize, Deserialize)]
pub struct Ledger {
    #[serde(skip)]
    out: PathBuf,
    /// Path relative to the output folder → SHA-256 (hex) of its bytes.
    files: BTreeMap<String, String>,
}

impl Ledger {
    /// The ledger of `out` as the last job left it.
    pub fn open(out: &Path) -> Ledger {
        let files = read(out, LEDGER_FILE, LEDGER_MAX_BYTES)
            .ok()
            .flatten()
            .and_then(|b| serde_json::from_slice::<Ledger>(&b).ok())
            .map(|l| l.files)
            .unwrap_or_default();
        Ledger {
            out: out.to_path_buf(),
            files,
        }
    }

    /// The output folder.
    pub fn out(&self) -> &Path {
        &self.out
    }

    /// Write `bytes` to `rel` ([`write_as`]) and list it.
    pub fn write_as(&mut self, rel: &str, bytes: &[u8], durable: Durable) -> io::Result<PathBuf> {
        let full = write_as(&self.out, rel, durable, |f| f.write_all(bytes))?;
        self.files.insert(rel.to_string(), sha256_of(bytes));
        Ok(full)
    }

    /// Whether `rel` is listed and still holds the bytes it was written with.
    pub fn owns(&self, rel: &str) -> bool {
        self.files
            .get(rel)
            .is_some_and(|h| sha256(&self.out, rel).is_ok_and(|now| &now == h))
    }

    /// The bytes of `rel` when it is dropscope's ([`Ledger::owns`]): read
    /// once and checked against the listed SHA-256.
    pub fn read_owned(&self, rel: &str, limit: u64) -> Option<Vec<u8>> {
        let want = self.files.get(rel)?;
        let bytes = read(&self.out, rel, limit).ok()??;
        (&sha256_of(&bytes) == want).then_some(bytes)
    }

    /// The listed paths, sorted.
    pub fn listed(&self) -> impl Iterator<Item = &str> {
        self.files.keys().map(String::as_str)
    }

    /// Remove `rel` if it is dropscope's ([`Ledger::owns`]) and unlist it;
    /// a listed file that was changed since is unlisted and left (it is
    /// yours now). Returns whether it was removed.
    pub fn remove(&mut self, rel: &str) -> io::Result<bool> {
        let Some(h) = self.files.remove(rel) else {
            return Ok(false);
        };
        remove_if_holds(&self.out, rel, &h)
    }

    /// Write the ledger (atomically, synced), unlisting what is gone.
    pub fn save(&mut self) -> io::Result<()> {
        let out = self.out.clone();
        self.files
            .retain(|rel, _| path(&out, rel).is_ok_and(|p| p.is_file()));
        let mut bytes = serde_json::to_vec_pretty(&*self).map_err(io::Error::other)?;
        bytes.push(b'\n');
        write(&self.out, LEDGER_FILE, &bytes)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(unix)]
    #[test]
    fn no_link_below_the_output_folder_is_followed() {
        let dir = tempfile::tempdir().unwrap();
        let (out, photos) = (dir.path().join("out"), dir.path().join("photos"));
        fs::create_dir_all(out.join("plots")).unwrap();
        fs::create_dir(&photos).unwrap();
        fs::write(photos.join("cat.png"), b"cat").unwrap();
        std::os::unix::fs::symlink(&photos, out.join("plots/drops")).unwrap();
        let e = write(&out, "plots/drops/a.png", b"x")
            .unwrap_err()
            .to_string();
        assert!(e.contains("plots/drops is a symbolic link"), "{e}");
        let e = create_dirs(&out, "plots/drops/more")
            .unwrap_err()
            .to_string();
        assert!(e.contains("is a symbolic link"), "{e}");
        assert!(open(&out, "plots/drops/cat.png").is_err());
        let h = sha256_of(b"cat");
        assert!(!remove_if_holds(&out, "plots/drops/cat.png", &h).unwrap_or(false));
        assert_eq!(fs::read(photos.join("cat.png")).unwrap(), b"cat");
        assert_eq!(fs::read_dir(&photos).unwrap().count(), 1);
        // A link in a file's place is read by nobody, removed by nobody,
        // and a write replaces the link, not its target.
        std::os::unix::fs::symlink(photos.join("cat.png"), out.join("plots/x.png")).unwrap();
        assert!(open(&out, "plots/x.png").is_err());
        assert!(!remove_if_holds(&out, "plots/x.png", &h).unwrap_or(false));
        assert_eq!(fs::read(photos.join("cat.png")).unwrap(), b"cat");
    }

    #[test]
    fn a_missing_output_folder_is_made() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("new/out");
        write(&out, "collapse.csv", b"a\n").unwrap();
        write(&out, "plots/drops/a.svg", b"<svg/>").unwrap();
        assert_eq!(fs::read(out.join("collapse.csv")).unwrap(), b"a\n");
        assert!(out.join("plots/drops/a.svg").is_file());
    }

    #[test]
    fn the_ledger_removes_only_what_it_listed_unchanged() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path();
        let mut l = Ledger::open(out);
        l.write_as("plots/a.svg", b"<svg/>", Durable::Now).unwrap();
        l.write_as("plots/b.svg", b"<svg/>", Durable::Now).unwrap();
        l.save().unwrap();
        fs::write(out.join("plots/mine.svg"), b"<svg>mine</svg>").unwrap();
        fs::write(out.join("plots/b.svg"), b"<svg>edited</svg>").unwrap();
        let mut l = Ledger::open(out);
        assert!(l.owns("plots/a.svg") && !l.owns("plots/b.svg") && !l.owns("plots/mine.svg"));
        assert!(l.remove("plots/a.svg").unwrap());
        assert!(!l.remove("plots/b.svg").unwrap());
        assert!(!l.remove("plots/mine.svg").unwrap());
        l.save().unwrap();
        assert!(!out.join("plots/a.svg").exists());
        assert!(out.join("plots/b.svg").is_file() && out.join("plots/mine.svg").is_file());
        assert_eq!(Ledger::open(out).listed().count(), 0);
        // A damaged ledger lists nothing.
        fs::write(out.join(LEDGER_FILE), b"{ damaged").unwrap();
        assert_eq!(Ledger::open(out).listed().count(), 0);
    }
}
