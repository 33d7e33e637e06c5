//! Small I/O helpers shared by every writer: files are written whole or not at all.

use std::fs;
use std::io::{self, Write};
use std::path::Path;

/// Write `bytes` to `path` atomically: a temporary file in the same folder,
/// flushed and synced, then renamed over the target. A reader never sees a
/// half-written file, and a crash leaves either the old file or the new one.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let name = path
        .file_name()
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "path has no file name"))?;
    let tmp = dir.join(format!(
        ".{}.tmp{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    {
        let mut f = fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
    }
    fs::rename(&tmp, path).inspect_err(|_| {
        let _ = fs::remove_file(&tmp);
    })
}

/// Remove `path`; a file that is not there is not an error.
pub fn remove_if_present(path: &Path) -> io::Result<()> {
    absent_is_fine(fs::remove_file(path))
}

/// Remove the folder `path` and everything in it; a folder that is not
/// there is not an error.
pub fn remove_dir_if_present(path: &Path) -> io::Result<()> {
    absent_is_fine(fs::remove_dir_all(path))
}

fn absent_is_fine(r: io::Result<()>) -> io::Result<()> {
    match r {
        Err(e) if e.kind() != io::ErrorKind::NotFound => Err(e),
        _ => Ok(()),
    }
}

/// Whether `name` is a temporary of [`write_atomic`]: `.<name>.tmp<pid>`.
fn is_temporary(name: &str) -> bool {
    name.starts_with('.')
        && name.rfind(".tmp").is_some_and(|i| {
            i > 1 && name[i + 4..].chars().all(|c| c.is_ascii_digit()) && name.len() > i + 4
        })
}

/// Remove the temporaries that a killed [`write_atomic`] left under `dir`
/// (searched recursively). Returns how many were removed; a missing `dir`
/// has none.
pub fn remove_stale_temporaries(dir: &Path) -> io::Result<usize> {
    let entries = match fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(e),
    };
    let mut removed = 0;
    for e in entries {
        let e = e?;
        let ty = e.file_type()?;
        if ty.is_dir() {
            removed += remove_stale_temporaries(&e.path())?;
        } else if ty.is_file() && is_temporary(&e.file_name().to_string_lossy()) {
            fs::remove_file(e.path())?;
            removed += 1;
        }
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atomic_write_replaces_whole_file_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.csv");
        write_atomic(&p, b"first version, long").unwrap();
        write_atomic(&p, b"second").unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"second");
        let names: Vec<_> = fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1, "a temporary file was left behind");
    }

    #[test]
    fn stale_temporaries_are_found_and_only_they() {
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("tracks");
        fs::create_dir(&sub).unwrap();
        for name in [".a.csv.tmp123", "keep.csv", ".hidden", "x.tmp1", ".b.tmp"] {
            fs::write(sub.join(name), b"x").unwrap();
        }
        assert_eq!(remove_stale_temporaries(dir.path()).unwrap(), 1);
        let mut left: Vec<String> = fs::read_dir(&sub)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(left, [".b.tmp", ".hidden", "keep.csv", "x.tmp1"]);
        assert_eq!(
            remove_stale_temporaries(&dir.path().join("none")).unwrap(),
            0
        );
    }
}
