//! Build script: the SHA-256 of the sources that decide dropscope's results
//! (every file under `src/`, `Cargo.toml` and `Cargo.lock`), handed to the
//! crate as `DROPSCOPE_SOURCE_SHA256`. The main job's cache keys and
//! `provenance.json` carry it, so outputs computed by other code are never
//! reused (the crate version does not change between releases).

use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// Every file under `dir`, at any depth.
fn files_under(dir: &Path, out: &mut Vec<PathBuf>) {
    let entries = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("build script: cannot list {}: {e}", dir.display()));
    for entry in entries {
        let path = entry
            .unwrap_or_else(|e| panic!("build script: cannot list {}: {e}", dir.display()))
            .path();
        if path.is_dir() {
            files_under(&path, out);
        } else {
            out.push(path);
        }
    }
}

fn main() {
    let root = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let mut files = Vec::new();
    files_under(&root.join("src"), &mut files);
    files.push(root.join("Cargo.toml"));
    files.push(root.join("Cargo.lock"));
    // Relative names with '/' on every system, in one order.
    let mut named: Vec<(String, PathBuf)> = files
        .into_iter()
        .map(|p| {
            let rel = p.strip_prefix(&root).unwrap_or(&p);
            let name = rel
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect::<Vec<_>>()
                .join("/");
            (name, p)
        })
        .collect();
    named.sort();
    let mut h = Sha256::new();
    for (name, path) in &named {
        // A crate built from a registry may have no Cargo.lock: hashed as empty.
        let bytes = std::fs::read(path).unwrap_or_default();
        h.update(name.as_bytes());
        h.update([0]);
        h.update((bytes.len() as u64).to_le_bytes());
        h.update(&bytes);
        println!("cargo:rerun-if-changed={}", path.display());
    }
    // New or removed files under src/.
    println!("cargo:rerun-if-changed={}", root.join("src").display());
    let hex: String = h.finalize().iter().map(|b| format!("{b:02x}")).collect();
    println!("cargo:rustc-env=DROPSCOPE_SOURCE_SHA256={hex}");
}
