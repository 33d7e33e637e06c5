//! The crate's layers (the project's ARCHITECTURE.md, "What must never be"): what
//! each part of `src/` may import, read from the `use` paths and the
//! `crate::…` / `super::…` / `self::…` paths of every file (main.rs's
//! `dropscope::…`). A path is followed to the file that defines its name,
//! through the `pub use` re-exports of the files on its way; code under
//! `#[cfg(test)]` is left out (tests may reach anywhere).
//!
//! Asserted (the groups below name the folders):
//!
//! - no circle among files, and none among the rooms (each folder under
//!   `src/` taken as one room): an import that runs back up to a room above
//!   is such a circle;
//! - `util/` imports nothing else of the crate;
//! - `config/` imports no stage;
//! - `source/` imports only itself and util; its readers (`.cine`, folders
//!   of frames, Photron) never import each other;
//! - `detect/` never imports source, config or track;
//! - `plot/` imports no domain module: only itself and util;
//! - `track/` never imports config, measure or calibrate;
//! - `measure/` never imports track, detect, source or config;
//! - `render/` never imports detect, track, measure or calibrate (the truth
//!   is made without the measurement), nor one run or many;
//! - `dataset/`, `collapse/`, `figures/` and `report/` never import one run
//!   (`pipeline/`) or many (`job/`); `figures/` never touches `std::fs`;
//!   `collapse/` never imports figures;
//! - `pipeline/` (one run) never imports `job/` (many runs): it writes
//!   nothing into the output folder;
//! - nothing imports `cli/` but `main.rs`, and nothing imports `review/`
//!   (a command of its own) but `main.rs`;
//! - a `mod.rs` defines no name that a file below it imports: shared types
//!   live in a file of their own;
//! - lib.rs's table lists every folder, leaves first, each importing only
//!   those before it (the README's layout table is the same list);
//! - `clap` only in `cli/` and `main.rs` ([`CLAP_FILES`]): below them,
//!   plain settings.
//!
//! Waiting for code to move first: `dataset/`, `collapse/` and `report/` without
//! `std::fs` (`dataset/record.rs` reads its CSV, `collapse/diagnostics.rs`
//! the tracks, `report/` reads the files of the output folder it shows).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

// Standalone (`rustc --test tests/layers.rs`) this file is the crate root: the
// path names the same file either way.
#[path = "layers/reader.rs"]
mod reader;

use reader::{imports, read, src, strip, without_tests};

// --- The groups of today's files that stand for ARCHITECTURE.md's folders.
// A name ending in '/' is a folder of src/, any other a file of src/.

const UTIL: &[&str] = &["util/"];
const CONFIG: &[&str] = &["config/"];
const DATASET: &[&str] = &["dataset/"];
const SOURCE: &[&str] = &["source/"];
const DETECT: &[&str] = &["detect/"];
const PLOT: &[&str] = &["plot/"];
const TRACK: &[&str] = &["track/"];
const MEASURE: &[&str] = &["measure/"];
const CALIBRATE: &[&str] = &["calibrate/"];
const RENDER: &[&str] = &["render/"];
const FIGURES: &[&str] = &["figures/"];
const COLLAPSE: &[&str] = &["collapse/"];
const REPORT: &[&str] = &["report/"];
/// One run: open, track, calibrate, measure.
const PIPELINE: &[&str] = &["pipeline/"];
/// Many runs: the output folder and what a job keeps there.
const JOB: &[&str] = &["job/"];
const REVIEW: &[&str] = &["review/"];
const CLI: &[&str] = &["cli/"];
/// Every part below `review/`, `cli/` and `main.rs`, the commands at the top.
const BELOW_COMMANDS: &[&str] = &[
    "util/",
    "config/",
    "source/",
    "plot/",
    "detect/",
    "track/",
    "dataset/",
    "measure/",
    "collapse/",
    "calibrate/",
    "figures/",
    "report/",
    "render/",
    "pipeline/",
    "job/",
];
/// The files that hold command-line arguments (clap's derives): `cli/` and
/// `main.rs` alone.
const CLAP_FILES: &[&str] = &["main.rs", "cli/"];

/// What a part may import: only the groups listed (and itself), or anything
/// but them.
enum Allowed {
    Only(&'static [&'static [&'static str]]),
    Never(&'static [&'static [&'static str]]),
}

struct Rule {
    part: &'static [&'static str],
    name: &'static str,
    allowed: Allowed,
    why: &'static str,
}

const RULES: &[Rule] = &[
    Rule {
        part: UTIL,
        name: "util/",
        allowed: Allowed::Only(&[UTIL]),
        why: "util imports nothing of the crate",
    },
    Rule {
        part: CONFIG,
        name: "config/",
        allowed: Allowed::Only(&[CONFIG, UTIL]),
        why: "config is a leaf: TOML to plain settings, no stage",
    },
    Rule {
        part: SOURCE,
        name: "source/",
        allowed: Allowed::Only(&[SOURCE, UTIL]),
        why: "source never imports config, dataset, detect or anything above",
    },
    Rule {
        part: &["source/cine/", "source/cine_write.rs"],
        name: "source/'s .cine reader",
        allowed: Allowed::Never(&[
            &[
                "source/folder/",
                "source/frame_decode/",
                "source/listing.rs",
            ],
            &["source/photron/"],
        ]),
        why: "readers never import each other",
    },
    Rule {
        part: &[
            "source/folder/",
            "source/frame_decode/",
            "source/listing.rs",
        ],
        name: "source/'s folder reader",
        allowed: Allowed::Never(&[
            &["source/cine/", "source/cine_write.rs"],
            &["source/photron/"],
        ]),
        why: "readers never import each other",
    },
    Rule {
        part: &["source/photron/"],
        name: "source/photron/",
        allowed: Allowed::Never(&[
            &["source/cine/", "source/cine_write.rs"],
            &[
                "source/folder/",
                "source/frame_decode/",
                "source/listing.rs",
            ],
        ]),
        why: "readers never import each other",
    },
    Rule {
        part: DETECT,
        name: "detect/",
        allowed: Allowed::Never(&[SOURCE, CONFIG, TRACK]),
        why: "detect never imports source (it takes an ArrayView2<u16>), config or track",
    },
    Rule {
        part: PLOT,
        name: "plot/",
        allowed: Allowed::Only(&[PLOT, UTIL]),
        why: "plot is the drawing kit: plain data in, bytes out, no domain module",
    },
    Rule {
        part: TRACK,
        name: "track/",
        allowed: Allowed::Never(&[CONFIG, MEASURE, CALIBRATE]),
        why: "track never imports config (it takes TrackSettings), measure or calibrate",
    },
    Rule {
        part: MEASURE,
        name: "measure (events, kinematics, force, flight, quality, measure)",
        allowed: Allowed::Never(&[TRACK, DETECT, SOURCE, CONFIG]),
        why: "measure never imports track, detect, source or config: pure, per drop",
    },
    Rule {
        part: RENDER,
        name: "render/",
        allowed: Allowed::Never(&[DETECT, TRACK, MEASURE, CALIBRATE, PIPELINE, JOB]),
        why: "the truth is made without the measurement",
    },
    Rule {
        part: DATASET,
        name: "dataset/",
        allowed: Allowed::Never(&[PIPELINE, JOB]),
        why: "dataset is the records' schema: one run fills it, the job level writes it",
    },
    Rule {
        part: FIGURES,
        name: "figures/",
        allowed: Allowed::Never(&[PIPELINE, JOB]),
        why: "figures are bytes in, bytes out: the job level writes them",
    },
    Rule {
        part: COLLAPSE,
        name: "collapse/",
        allowed: Allowed::Never(&[PIPELINE, JOB, FIGURES]),
        why: "collapse computes; the job level draws and writes",
    },
    Rule {
        part: REPORT,
        name: "report/",
        allowed: Allowed::Never(&[PIPELINE, JOB]),
        why: "report.html is made from the job's files; the job level calls it",
    },
    Rule {
        part: PIPELINE,
        name: "pipeline/",
        allowed: Allowed::Never(&[JOB]),
        why: "one run writes nothing into the output folder: the job level does",
    },
    Rule {
        part: BELOW_COMMANDS,
        name: "every part but review/, cli/ and main.rs",
        allowed: Allowed::Never(&[CLI, REVIEW]),
        why: "the command line is parsed at the top, and review is a command of its own: below \
              them, plain settings; what the job needs of review (review.csv) is in dataset/",
    },
    Rule {
        part: REVIEW,
        name: "review/",
        allowed: Allowed::Never(&[CLI]),
        why: "the command line is parsed at the top: below it, plain settings",
    },
];

fn in_group(file: &str, group: &[&str]) -> bool {
    group.iter().any(|g| {
        if g.ends_with('/') {
            file.starts_with(g)
        } else {
            file == *g
        }
    })
}

/// The room of a file: its top folder under src/, or the file itself.
fn room(file: &str) -> String {
    match file.split_once('/') {
        Some((dir, _)) => format!("{dir}/"),
        None => file.into(),
    }
}

/// A circle of `graph`, if it has one, as its nodes in order.
fn find_circle(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    #[derive(Clone, Copy, PartialEq)]
    enum Mark {
        New,
        Open,
        Done,
    }
    fn dfs(
        v: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        mark: &mut BTreeMap<String, Mark>,
        stack: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        mark.insert(v.to_string(), Mark::Open);
        stack.push(v.to_string());
        for w in graph.get(v).into_iter().flatten() {
            match mark.get(w.as_str()).copied().unwrap_or(Mark::New) {
                Mark::Open => {
                    let from = stack.iter().position(|s| s == w).unwrap_or(0);
                    let mut circle = stack[from..].to_vec();
                    circle.push(w.clone());
                    return Some(circle);
                }
                Mark::New => {
                    if let Some(c) = dfs(w, graph, mark, stack) {
                        return Some(c);
                    }
                }
                Mark::Done => {}
            }
        }
        stack.pop();
        mark.insert(v.to_string(), Mark::Done);
        None
    }
    let mut mark = BTreeMap::new();
    for v in graph.keys() {
        if mark.get(v.as_str()).copied().unwrap_or(Mark::New) == Mark::New {
            if let Some(c) = dfs(v, graph, &mut mark, &mut Vec::new()) {
                return Some(c);
            }
        }
    }
    None
}

/// The imports that tie `circle` (consecutive nodes), as text.
fn ties(circle: &[String], node: impl Fn(&str) -> String) -> String {
    circle
        .windows(2)
        .map(|w| {
            let names: Vec<String> = imports()
                .iter()
                .filter(|i| node(&i.from) == w[0] && node(&i.to) == w[1])
                .map(|i| format!("src/{} imports {}", i.from, i.path))
                .collect();
            let more = match names.len() {
                n if n > 4 => format!("; and {} more", n - 4),
                _ => String::new(),
            };
            let shown = names.iter().take(4).cloned().collect::<Vec<_>>();
            format!("  {} -> {}: {}{more}", w[0], w[1], shown.join("; "))
        })
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn the_reader_sees_the_imports_it_must() {
    let has = |from: &str, to: &str| imports().iter().any(|i| i.from == from && i.to == to);
    let files: BTreeSet<&str> = imports().iter().map(|i| i.from.as_str()).collect();
    assert!(
        files.len() > 60,
        "only {} files import anything",
        files.len()
    );
    // A `use crate::…` item, a re-export followed to its file, an inline
    // `crate::` path, a `super::` path and main.rs's `dropscope::`.
    assert!(
        has("track/kept.rs", "util/records.rs"),
        "track/kept.rs -> util/records.rs"
    );
    assert!(
        has("track/pass2.rs", "detect/circle/types.rs"),
        "via detect's re-export"
    );
    assert!(
        has("pipeline/tracked.rs", "track/run.rs"),
        "pipeline/tracked.rs -> track/run.rs"
    );
    assert!(
        has("detect/edges.rs", "detect/circle/types.rs"),
        "super::circle"
    );
    assert!(
        has("main.rs", "config/settings.rs"),
        "main.rs -> config/settings.rs, via config's re-export"
    );
    // Test code is left out: test_support.rs is imported by tests only.
    assert!(!imports().iter().any(|i| i.to == "test_support.rs"));
}

#[test]
fn no_file_imports_what_its_layer_must_never_import() {
    let mut broken = Vec::new();
    for i in imports() {
        for rule in RULES {
            if !in_group(&i.from, rule.part) {
                continue;
            }
            let ok = match &rule.allowed {
                Allowed::Only(groups) => {
                    in_group(&i.to, rule.part) || groups.iter().any(|g| in_group(&i.to, g))
                }
                Allowed::Never(groups) => {
                    in_group(&i.to, rule.part) || !groups.iter().any(|g| in_group(&i.to, g))
                }
            };
            if !ok {
                broken.push(format!(
                    "src/{} imports {} (src/{}): {} — {}",
                    i.from, i.path, i.to, rule.name, rule.why
                ));
            }
        }
    }
    assert!(
        broken.is_empty(),
        "imports that the layers forbid (ARCHITECTURE.md, \"What must never be\"):\n{}",
        broken.join("\n")
    );
}

#[test]
fn figures_never_touch_files() {
    for file in walk(&src()) {
        let rel = rel(&file);
        if !in_group(&rel, FIGURES) {
            continue;
        }
        let code = without_tests(&strip(&read(&file)));
        assert!(
            !code.contains("std::fs") && !code.contains("fs::"),
            "src/{rel} uses std::fs: figures/ — figures are bytes in, bytes out: the job level \
             writes them"
        );
    }
}

#[test]
fn no_circle_among_files() {
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for i in imports() {
        graph
            .entry(i.from.clone())
            .or_default()
            .insert(i.to.clone());
    }
    if let Some(circle) = find_circle(&graph) {
        panic!(
            "a circle of files (each imports the next; move the name to the lowest file that \
             uses it):\n{}\n{}",
            circle.join(" -> "),
            ties(&circle, |f| f.to_string())
        );
    }
}

#[test]
fn no_import_runs_back_up_between_rooms() {
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for i in imports() {
        let (a, b) = (room(&i.from), room(&i.to));
        if a != b {
            graph.entry(a).or_default().insert(b);
        }
    }
    if let Some(circle) = find_circle(&graph) {
        panic!(
            "a circle of rooms (each folder of src/ one room): one of these imports runs back \
             up; move the name to the lowest file that uses it:\n{}\n{}",
            circle.join(" -> "),
            ties(&circle, room)
        );
    }
}

#[test]
fn a_mod_rs_defines_nothing_its_children_import() {
    let mut broken = Vec::new();
    for i in imports() {
        // The file of a module above `from`: `dir/mod.rs`, or `dir.rs` for `dir/`.
        let parent_of = |dir: &str| {
            i.to == format!("{dir}/mod.rs") || (i.to == format!("{dir}.rs") && !dir.is_empty())
        };
        let mut dir = Path::new(&i.from).parent();
        while let Some(d) = dir {
            let d_str = d.to_string_lossy().replace('\\', "/");
            if d_str.is_empty() {
                break;
            }
            if parent_of(&d_str) {
                broken.push(format!(
                    "src/{} imports {} (src/{}): a mod.rs (or the file of a folder's module) \
                     documents, declares and re-exports; a type its children import goes in a \
                     types.rs / error.rs of the folder",
                    i.from, i.path, i.to
                ));
            }
            dir = d.parent();
        }
    }
    assert!(broken.is_empty(), "{}", broken.join("\n"));
}

#[test]
fn clap_only_in_the_command_line_files() {
    for file in walk(&src()) {
        let rel = rel(&file);
        let code = without_tests(&strip(&read(&file)));
        if code.contains("clap::") || code.contains("use clap") {
            assert!(
                in_group(&rel, CLAP_FILES),
                "src/{rel} uses clap: anything but the command line (cli/ and main.rs in the \
                 layout to grow into; today the files of CLAP_FILES in tests/layers.rs) must \
                 never import clap: take plain settings"
            );
        }
    }
}

/// Every `.rs` file under `dir`.
fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap_or_else(|e| panic!("{}: {e}", d.display())) {
            let p = e.expect("a folder entry").path();
            if p.is_dir() {
                todo.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

fn rel(file: &Path) -> String {
    file.strip_prefix(src())
        .unwrap_or(file)
        .to_string_lossy()
        .replace('\\', "/")
}

#[test]
fn lib_rs_lists_every_folder_in_the_order_of_the_imports() {
    // The table that opens lib.rs: `//! | [`name`] | what |`, leaves first.
    let lib = read(&src().join("lib.rs"));
    let order: Vec<String> = lib
        .lines()
        .filter_map(|l| l.strip_prefix("//! | [`"))
        .filter_map(|l| l.split_once("`]"))
        .map(|(name, _)| format!("{name}/"))
        .collect();
    let rooms: BTreeSet<String> = walk(&src())
        .iter()
        .map(|f| room(&rel(f)))
        .filter(|r| r.ends_with('/'))
        .collect();
    let listed: BTreeSet<String> = order.iter().cloned().collect();
    assert_eq!(
        listed, rooms,
        "lib.rs's table of modules and the folders of src/ differ"
    );
    let at = |r: &str| order.iter().position(|o| o == r);
    let mut upward = Vec::new();
    for i in imports() {
        let (a, b) = (room(&i.from), room(&i.to));
        if let (Some(ia), Some(ib)) = (at(&a), at(&b)) {
            if ib > ia {
                upward.push(format!(
                    "src/{} ({a}) imports {} ({b}), listed after it",
                    i.from, i.path
                ));
            }
        }
    }
    assert!(
        upward.is_empty(),
        "lib.rs lists its modules leaves first: each imports only those before it\n{}",
        upward.join("\n")
    );
}

#[test]
fn every_folder_below_the_commands_is_held_to_their_rule() {
    // BELOW_COMMANDS is written out (a rule's part is a constant): a new
    // folder of src/ must join it, or review/ and cli/ could be imported
    // from it unseen.
    let rooms: BTreeSet<String> = walk(&src())
        .iter()
        .map(|f| room(&rel(f)))
        .filter(|r| r.ends_with('/') && r != "review/" && r != "cli/")
        .collect();
    let listed: BTreeSet<String> = BELOW_COMMANDS.iter().map(|s| s.to_string()).collect();
    assert_eq!(
        listed, rooms,
        "BELOW_COMMANDS in tests/layers.rs and the folders of src/ below review/ and cli/ differ"
    );
}
