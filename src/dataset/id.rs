//! Which `drops.csv` an output folder's derived files were computed from.
//!
//! A dataset's id is the first 16 hex digits of the SHA-256 of its
//! `drops.csv` bytes: the same rows give the same id, any change another.
//! The collapse writes the id of the drops.csv it read into `fits.json`
//! (`provenance.dataset_id`), into every row of `collapse.csv`
//! (`dataset_id`) and into every SVG figure (`<desc>`), and the report
//! refuses a folder whose files carry another id than its drops.csv: files
//! of two jobs, e.g. after `collapse other/drops.csv --out here`, cannot be
//! shown as one.

use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// The id of a drops.csv's bytes.
pub fn of_bytes(bytes: &[u8]) -> String {
    let digest = Sha256::digest(bytes);
    digest[..8].iter().map(|b| format!("{b:02x}")).collect()
}

/// The id of the drops.csv at `path`.
pub fn of_file(path: &Path) -> std::io::Result<String> {
    Ok(of_bytes(&crate::util::io::read_input(
        path,
        crate::util::io::TEXT_INPUT_MAX_BYTES,
    )?))
}

const DESC_PREFIX: &str = "<desc>dropscope dataset_id ";

/// `svg` with its dataset id as the first element inside `<svg …>`.
pub fn tag_svg(mut svg: Vec<u8>, id: &str) -> Vec<u8> {
    let Some(end) = svg.iter().position(|&b| b == b'>') else {
        return svg;
    };
    // In place: a long movie's figure is megabytes.
    let desc = format!("{DESC_PREFIX}{id}</desc>");
    svg.splice(end + 1..end + 1, desc.bytes());
    svg
}

/// The dataset id an SVG written by [`tag_svg`] carries.
pub fn of_svg(svg: &str) -> Option<&str> {
    let start = svg.find(DESC_PREFIX)? + DESC_PREFIX.len();
    let len = svg[start..].find('<')?;
    Some(&svg[start..start + len])
}

/// A derived file that does not belong to the folder's drops.csv.
#[derive(Debug, thiserror::Error)]
#[error(
    "{file} was computed from another drops.csv than {drops} (dataset {found}; {drops} is \
     dataset {expected}): the folder mixes the outputs of two jobs. Run `dropscope collapse \
     {drops}` (it writes beside its input) or the whole job again, or move the other job's \
     files away"
)]
pub struct Mixed {
    /// The derived file (fits.json, collapse.csv, a figure).
    pub file: PathBuf,
    /// The folder's drops.csv.
    pub drops: PathBuf,
    /// What the file says ("none" when it carries no id).
    pub found: String,
    /// The dataset id of the folder's drops.csv.
    pub expected: String,
}

/// Check that `file`, claiming dataset `found`, belongs to `drops` (id `expected`).
pub fn check(file: &Path, found: Option<&str>, drops: &Path, expected: &str) -> Result<(), Mixed> {
    if found == Some(expected) {
        return Ok(());
    }
    Err(Mixed {
        file: file.to_path_buf(),
        drops: drops.to_path_buf(),
        found: found.unwrap_or("none").to_string(),
        expected: expected.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_follow_the_bytes_and_survive_in_svg() {
        let a = of_bytes(b"run,status\na,ok\n");
        assert_eq!(a.len(), 16);
        assert_eq!(a, of_bytes(b"run,status\na,ok\n"));
        assert_ne!(a, of_bytes(b"run,status\nb,ok\n"));
        let svg = tag_svg(b"<svg width=\"3\"><rect/></svg>".to_vec(), &a);
        let text = String::from_utf8(svg).unwrap();
        assert!(text.starts_with("<svg width=\"3\"><desc>"), "{text}");
        assert_eq!(of_svg(&text), Some(a.as_str()));
        assert_eq!(of_svg("<svg></svg>"), None);
        let e = check(
            Path::new("out/fits.json"),
            None,
            Path::new("out/drops.csv"),
            &a,
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("out/fits.json") && e.contains("dataset none") && e.contains(&a),
            "{e}"
        );
    }
}
