//! Opening an input: its name, its kind, and the reader that [`open`] picks.

use std::path::Path;

use super::error::{SourceError, SUPPORTED_INPUTS};
use super::frame::{FrameSource, InputKind, OpenOptions};
use super::{cine, folder, frame_decode, listing, photron};

/// The name of an input, for run names and file names: its whole name
/// (run folders such as `R4.5mm_H12cm_01` hold dots that are no extension),
/// less the extension of a recording file (`drop_07.cine` → `drop_07`,
/// `ball.mraw` or `ball.cihx` → `ball`), the one extension a file that is a
/// run has. A path that is not there is named the same way, as a folder
/// unless it ends in one of those extensions.
pub fn input_name(path: &Path) -> String {
    let name = if listing::recording_kind(path).is_some() && !path.is_dir() {
        path.file_stem()
    } else {
        path.file_name()
    };
    name.map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string())
}

/// What kind of input `path` is, from its metadata and, for a file with no
/// recording's extension, its first bytes; no frame is read. An error when it is
/// not there (the `Io` error of `NotFound`), cannot be looked at, or is
/// none of [`SUPPORTED_INPUTS`]: what [`open`] refuses before reading.
pub fn input_kind(path: &Path) -> Result<InputKind, SourceError> {
    let md = std::fs::metadata(path).map_err(|source| SourceError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    if md.is_dir() {
        return Ok(InputKind::Folder);
    }
    if !md.is_file() {
        return Err(SourceError::Unsupported {
            path: path.to_path_buf(),
            reason: format!(
                "not a regular file (a named pipe, socket or device); dropscope reads {SUPPORTED_INPUTS}"
            ),
        });
    }
    if let Some(kind) = listing::recording_kind(path) {
        return Ok(kind);
    }
    if cine::has_cine_magic(path) {
        return Ok(InputKind::Cine);
    }
    let what = match path.extension().and_then(|e| e.to_str()) {
        Some(e) if frame_decode::ImageKind::from_extension(e).is_some() => format!(
            "one frame file, give the folder that holds its sequence ({})",
            path.parent()
                .filter(|p| !p.as_os_str().is_empty())
                .map_or_else(|| ".".into(), |p| p.display().to_string())
        ),
        Some(e) => format!("a .{e} file"),
        None => "a file without extension or cine header".to_string(),
    };
    Err(SourceError::Unsupported {
        path: path.to_path_buf(),
        reason: format!(
            "not a folder of frames nor a recording ({what}); dropscope reads {SUPPORTED_INPUTS}"
        ),
    })
}

/// Open a folder of frames, a `.cine`, or a Photron `.mraw` (or its header).
///
/// A directory is read as one PCC-style image sequence
/// ([`folder::FolderSource`]), unless it holds no frames of its own and one
/// recording file, which is then opened ([`listing::Listing`]); a
/// file whose name ends in `.cine` (any case) or that starts with the cine
/// magic `"CI"` is read by [`cine::CineSource`]; a `.mraw`, `.cihx` or
/// `.cih` by [`photron::PhotronSource`] ([`input_kind`]).
pub fn open(path: &Path, options: &OpenOptions) -> Result<Box<dyn FrameSource>, SourceError> {
    Ok(match input_kind(path)? {
        InputKind::Folder => {
            let listing = listing::Listing::of(path)?;
            match listing.lone_recording() {
                Some(file) => open(&file, options)?,
                None => Box::new(folder::FolderSource::open_listed(listing, options)?),
            }
        }
        InputKind::Cine => Box::new(cine::CineSource::open(path, options)?),
        InputKind::Photron => Box::new(photron::PhotronSource::open(path, options)?),
    })
}

#[cfg(test)]
mod tests {
    use super::input_name;

    #[test]
    fn folder_names_keep_their_dots_and_files_lose_their_extension() {
        let dir = tempfile::tempdir().unwrap();
        let run = dir.path().join("R4.5mm_H12cm_01");
        std::fs::create_dir(&run).unwrap();
        assert_eq!(input_name(&run), "R4.5mm_H12cm_01");
        assert_eq!(
            input_name(&dir.path().join("R4.5mm_H12cm_01.cine")),
            "R4.5mm_H12cm_01"
        );
    }
}
