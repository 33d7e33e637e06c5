//! An earlier job's leftovers in the output folder: when a job
//! into a folder has fewer runs than the one before it (or a run now writes
//! fewer files: it failed, or no `--overlay-frames`), the earlier job's
//! tracks, overlays and animations of those runs would stay beside the new
//! ones and mix two jobs.
//!
//! `provenance.json` lists, for every run, the files the job wrote and the
//! SHA-256 of their bytes. Before a job writes its own, the files the
//! previous one listed that this job did not write are removed — only
//! those, and only while they still hold the bytes dropscope wrote (a file
//! the user changed, or any file no provenance lists, is never touched),
//! with the cache entries (`runs/<run>.json`) of the runs no longer in the
//! job. A provenance written before it listed files (or without one) names
//! its runs only: their files are then those their cache entries list.
//!
//! A `process` job writes a new drops.csv but no collapse: the collapse
//! files (and report) an earlier job left, computed from another drops.csv,
//! are removed by [`remove_other_dataset`] — the files that carry another
//! dataset id ([`crate::dataset::id`]), which only dropscope writes.

use std::collections::BTreeSet;
use std::path::Path;

use serde::Deserialize;

use crate::job::cache::{self, Entry, OutputFile};
use crate::util::out_folder::Ledger;

/// The part of an earlier `provenance.json` read here.
#[derive(Deserialize)]
struct Previous {
    runs: Vec<PreviousRun>,
}

#[derive(Deserialize)]
struct PreviousRun {
    run: String,
    /// Absent in provenance written before the files were listed.
    outputs: Option<Vec<OutputFile>>,
}

/// A provenance larger than this is not read (1 000 runs take ~1 MB).
const PROVENANCE_MAX_BYTES: u64 = 256 << 20;

/// What [`remove`] removed.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub struct Removed {
    /// Runs of the previous job that are not in this one.
    pub runs: usize,
    /// Output files removed (cache entries not counted).
    pub files: usize,
}

impl Removed {
    /// A line for the user, or `None` when nothing was removed.
    pub fn message(&self) -> Option<String> {
        (self.files > 0 || self.runs > 0).then(|| {
            format!(
                "removed {} that the previous job in this folder wrote (its provenance.json \
                 lists them) and this one did not; {} of that job no longer in this one",
                crate::util::text::plural(self.files, "file"),
                crate::util::text::plural(self.runs, "run")
            )
        })
    }
}

/// Remove from `out` what the previous job's `provenance.json` lists and
/// `current` (this job's runs) did not write; call it before this job's
/// provenance replaces the previous one. No previous provenance, or one that
/// cannot be read, removes nothing.
pub fn remove(out: &Path, current: &[Entry]) -> std::io::Result<Removed> {
    let previous: Previous =
        match crate::util::out_folder::read(out, "provenance.json", PROVENANCE_MAX_BYTES) {
            Ok(Some(bytes)) => match serde_json::from_slice(&bytes) {
                Ok(p) => p,
                Err(_) => return Ok(Removed::default()),
            },
            _ => return Ok(Removed::default()),
        };
    let runs_now: BTreeSet<&str> = current.iter().map(|e| e.record.run.as_str()).collect();
    let written: BTreeSet<&str> = current
        .iter()
        .flat_map(|e| e.outputs.iter().map(|f| f.path.as_str()))
        .collect();
    let mut removed = Removed::default();
    for p in &previous.runs {
        let gone = !runs_now.contains(p.run.as_str());
        let entry = cache::entry_path(out, &p.run).ok();
        let listed = match &p.outputs {
            Some(files) => files.clone(),
            None if gone => cache::listed_outputs(out, &p.run),
            None => Vec::new(),
        };
        for f in listed.iter().filter(|f| !written.contains(f.path.as_str())) {
            // Only a plain path inside `out`, reached through no link,
            // holding the bytes listed.
            if crate::util::out_folder::remove_if_holds(out, &f.path, &f.sha256).unwrap_or(false) {
                removed.files += 1;
            }
        }
        if gone {
            removed.runs += 1;
            if entry.is_some() {
                let rel = format!("runs/{}.json", p.run);
                if let Ok(hash) = crate::util::out_folder::sha256(out, &rel) {
                    crate::util::out_folder::remove_if_holds(out, &rel, &hash)?;
                }
            }
        }
    }
    Ok(removed)
}

/// Remove the collapse files and report in the ledger's folder computed
/// from another drops.csv than the dataset `id` ([`crate::dataset::id`]):
/// `fits.json`, `collapse.csv`, the collapse figures' SVGs and
/// `report.html` that dropscope wrote (the ledger lists them, unchanged)
/// and that carry another id, and the PNG twin of each figure removed (a
/// PNG carries no id; one without its SVG goes when anything else went). A
/// file the ledger does not list is not dropscope's and stays. Returns the
/// paths removed, relative to the folder.
pub fn remove_other_dataset(ledger: &mut Ledger, id: &str) -> std::io::Result<Vec<String>> {
    const MAX: u64 = 1 << 30;
    let id_in = |ledger: &Ledger, rel: &str| -> Option<String> {
        let t = String::from_utf8(ledger.read_owned(rel, MAX)?).ok()?;
        if rel == "fits.json" {
            let doc: serde_json::Value = serde_json::from_str(&t).ok()?;
            return Some(doc["provenance"]["dataset_id"].as_str()?.to_string());
        }
        if rel == "collapse.csv" {
            let mut r = csv::Reader::from_reader(t.as_bytes());
            let col = r.headers().ok()?.iter().position(|c| c == "dataset_id")?;
            return Some(r.records().next()?.ok()?.get(col)?.to_string());
        }
        if rel == "report.html" {
            const MARK: &str = "title=\"SHA-256 of drops.csv\">";
            let start = t.find(MARK)? + MARK.len();
            return Some(t[start..].split('<').next()?.to_string());
        }
        crate::dataset::id::of_svg(&t).map(str::to_string)
    };
    let stems = crate::figures::FIGURE_STEMS;
    let tagged = crate::job::collapse_job::TABLES
        .iter()
        .map(|s| s.to_string())
        .chain(stems.iter().map(|s| format!("plots/{s}.svg")))
        .chain(["report.html".to_string()]);
    let mut removed = Vec::new();
    for rel in tagged {
        if id_in(ledger, &rel).is_some_and(|found| found != id) && ledger.remove(&rel)? {
            removed.push(rel);
        }
    }
    for stem in stems {
        let (svg, png) = (format!("plots/{stem}.svg"), format!("plots/{stem}.png"));
        let orphan = !ledger.owns(&svg) && !removed.is_empty();
        if (removed.contains(&svg) || orphan) && ledger.remove(&png)? {
            removed.push(png);
        }
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{cache_entry, out_with_tracks};

    fn entry(run: &str, outputs: Vec<OutputFile>) -> Entry {
        cache_entry(run, "k", outputs)
    }

    /// A provenance written before it listed files names its runs: the
    /// files of a run no longer in the job are those its cache entry lists,
    /// removed while they hold the listed bytes, with the entry. A listed
    /// path outside the folder, or a file that changed, is left alone.
    #[test]
    fn old_provenance_falls_back_on_the_cache_entries() {
        let (dir, out) = out_with_tracks(&[("a.csv", b"a"), ("b.csv", b"b, edited")]);
        let out = &out;
        std::fs::write(dir.path().join("outside.csv"), b"o").unwrap();
        let a = entry(
            "a",
            vec![
                OutputFile::new("tracks/a.csv".into(), b"a"),
                OutputFile::new("../outside.csv".into(), b"o"),
            ],
        );
        let b = entry("b", vec![OutputFile::new("tracks/b.csv".into(), b"b")]);
        cache::store(out, &a).unwrap();
        cache::store(out, &b).unwrap();
        std::fs::write(
            out.join("provenance.json"),
            br#"{"runs": [{"run": "a", "key": "k"}, {"run": "b", "key": "k"}]}"#,
        )
        .unwrap();
        let removed = remove(out, std::slice::from_ref(&b)).unwrap();
        assert_eq!(removed, Removed { runs: 1, files: 1 });
        assert!(!out.join("tracks/a.csv").exists());
        assert!(!out.join("runs/a.json").exists());
        assert!(out.join("runs/b.json").exists());
        assert_eq!(
            std::fs::read(out.join("tracks/b.csv")).unwrap(),
            b"b, edited"
        );
        assert_eq!(std::fs::read(dir.path().join("outside.csv")).unwrap(), b"o");
        // No provenance, or a damaged one: nothing removed.
        std::fs::write(out.join("provenance.json"), b"{ damaged").unwrap();
        assert_eq!(remove(out, &[]).unwrap(), Removed::default());
    }

    /// The collapse files that carry another dataset id go, with their PNG
    /// twins; a file carrying this id, or none (not dropscope's), stays.
    #[test]
    fn only_files_of_another_dataset_are_removed() {
        let (_dir, out) = out_with_tracks(&[]);
        let tag = |id: &str| crate::dataset::id::tag_svg(b"<svg><g/></svg>".to_vec(), id);
        let mut ledger = Ledger::open(&out);
        for (rel, bytes) in [
            (
                "fits.json",
                br#"{"provenance": {"dataset_id": "old"}}"#.to_vec(),
            ),
            ("collapse.csv", b"run,dataset_id\na,old\n".to_vec()),
            ("plots/tau_vs_v.svg", tag("old")),
            ("plots/tau_vs_v.png", b"png".to_vec()),
            ("plots/pi_vs_eta.svg", tag("new")),
            ("plots/pi_vs_eta.png", b"png".to_vec()),
            ("report.html", b"<p>old page</p>".to_vec()),
        ] {
            ledger
                .write_as(rel, &bytes, crate::util::io::Durable::Now)
                .unwrap();
        }
        ledger.save().unwrap();
        // Files of yours, carrying another id or none: not dropscope's.
        std::fs::write(out.join("plots/mine.svg"), tag("old")).unwrap();
        std::fs::write(out.join("report.html"), b"<p>my own page</p>").unwrap();
        let mut ledger = Ledger::open(&out);
        let removed = remove_other_dataset(&mut ledger, "new").unwrap();
        assert_eq!(
            removed,
            [
                "collapse.csv",
                "fits.json",
                "plots/tau_vs_v.svg",
                "plots/tau_vs_v.png"
            ]
        );
        for kept in [
            "plots/pi_vs_eta.svg",
            "plots/pi_vs_eta.png",
            "report.html",
            "plots/mine.svg",
        ] {
            assert!(out.join(kept).is_file(), "{kept}");
        }
        assert!(remove_other_dataset(&mut ledger, "new").unwrap().is_empty());
    }
}
