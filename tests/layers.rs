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
use std::sync::OnceLock;

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

// --- Reading the sources.

/// `text` with comments, string and character literals blanked (newlines
/// kept), so that only code is searched.
fn strip(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    let ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    while i < b.len() {
        let c = b[i];
        if b[i..].starts_with(b"//") {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if b[i..].starts_with(b"/*") {
            let mut depth = 0;
            while i < b.len() {
                if b[i..].starts_with(b"/*") {
                    depth += 1;
                    i += 2;
                } else if b[i..].starts_with(b"*/") {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
            out.push(' ');
        } else if (c == b'r' || (c == b'b' && b.get(i + 1) == Some(&b'r')))
            && (i == 0 || !ident(b[i - 1]))
            && {
                let mut j = i + if c == b'b' { 2 } else { 1 };
                while b.get(j) == Some(&b'#') {
                    j += 1;
                }
                b.get(j) == Some(&b'"')
            }
        {
            // A raw string: r"…", r#"…"#, br"…".
            let mut j = i + if c == b'b' { 2 } else { 1 };
            let mut hashes = 0;
            while b[j] == b'#' {
                hashes += 1;
                j += 1;
            }
            j += 1;
            let close: Vec<u8> = std::iter::once(b'"')
                .chain(std::iter::repeat_n(b'#', hashes))
                .collect();
            while j < b.len() && !b[j..].starts_with(&close) {
                j += 1;
            }
            i = (j + close.len()).min(b.len());
            out.push_str("\"\"");
        } else if c == b'"' {
            let mut j = i + 1;
            while j < b.len() && b[j] != b'"' {
                j += if b[j] == b'\\' { 2 } else { 1 };
            }
            i = j + 1;
            out.push_str("\"\"");
        } else if c == b'\'' && char_literal_len(&text[i..]).is_some() {
            i += char_literal_len(&text[i..]).unwrap_or(1);
            out.push_str("' '");
        } else {
            // Whole characters (the sources hold non-ASCII text).
            let ch = text[i..].chars().next().unwrap_or(' ');
            out.push(ch);
            i += ch.len_utf8();
        }
    }
    out
}

/// The length of the character literal `s` starts with, if it starts with
/// one (not a lifetime): `'a'`, `'\n'`, `'\u{1F600}'`, `'é'`.
fn char_literal_len(s: &str) -> Option<usize> {
    let mut chars = s.char_indices().skip(1);
    let (_, first) = chars.next()?;
    if first == '\\' {
        let end = s[1..].find('\'')?;
        // An escape is at most '\u{10FFFF}'.
        (end <= 10 && !s[1..1 + end].contains('\n')).then_some(end + 2)
    } else {
        let (k, close) = chars.next()?;
        (close == '\'').then_some(k + 1)
    }
}

/// The index after the brace block that opens at `open`.
fn block_end(code: &str, open: usize) -> usize {
    let mut depth = 0;
    for (k, c) in code[open..].char_indices() {
        match c {
            '{' => depth += 1,
            '}' => {
                depth -= 1;
                if depth == 0 {
                    return open + k + 1;
                }
            }
            _ => {}
        }
    }
    code.len()
}

/// `code` without the items under `#[cfg(test)]`.
fn without_tests(code: &str) -> String {
    let mark = "#[cfg(test)]";
    let mut out = String::with_capacity(code.len());
    let mut rest = 0;
    while let Some(k) = code[rest..].find(mark) {
        let at = rest + k;
        out.push_str(&code[rest..at]);
        // The item: to its `;`, or to the end of its first brace block.
        let item = at + mark.len();
        let semi = code[item..].find(';').map(|k| item + k);
        let brace = code[item..].find('{').map(|k| item + k);
        rest = match (semi, brace) {
            (Some(s), Some(b)) if s < b => s + 1,
            (_, Some(b)) => block_end(code, b),
            (Some(s), None) => s + 1,
            (None, None) => code.len(),
        };
    }
    out.push_str(&code[rest..]);
    out
}

/// `code` with every brace block's inside blanked: the file's own items.
fn top_level(code: &str) -> String {
    let mut depth = 0usize;
    code.chars()
        .map(|c| {
            let keep = depth == 0 || c == '\n';
            match c {
                '{' => depth += 1,
                '}' => depth = depth.saturating_sub(1),
                _ => {}
            }
            if keep || (c == '}' && depth == 0) {
                c
            } else {
                ' '
            }
        })
        .collect()
}

fn is_ident(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// The identifier after keyword `kw` at each of its places in `code`.
fn names_after(code: &str, kw: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(k) = code[from..].find(kw) {
        let at = from + k;
        from = at + kw.len();
        let before_ok = code[..at].chars().next_back().is_none_or(|c| !is_ident(c));
        let rest = &code[at + kw.len()..];
        if !before_ok || !rest.starts_with(|c: char| c.is_whitespace()) {
            continue;
        }
        let name: String = rest
            .trim_start()
            .chars()
            .take_while(|&c| is_ident(c))
            .collect();
        if !name.is_empty() {
            out.push((at, name));
        }
    }
    out
}

/// Every `use` item of `code`: (its start, the tree after `use`).
fn use_items(code: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    for (at, _) in names_after(code, "use") {
        let tree_start = at + 3;
        if let Some(end) = code[tree_start..].find(';') {
            out.push((at, code[tree_start..tree_start + end].to_string()));
        }
    }
    out
}

/// A use tree (`a::b::{c, d as e, f::{g, self}}`) as (path, name bound).
fn use_paths(tree: &str) -> Vec<(Vec<String>, String)> {
    let tree: String = tree.split_whitespace().collect::<Vec<_>>().join(" ");
    let mut out = Vec::new();
    walk_tree(&tree, &[], &mut out);
    out
}

fn walk_tree(tree: &str, prefix: &[String], out: &mut Vec<(Vec<String>, String)>) {
    for part in split_top(tree) {
        let part = part.trim();
        if part.is_empty() {
            continue;
        }
        if let Some(open) = part.find('{') {
            let head: Vec<String> = part[..open]
                .split("::")
                .map(str::trim)
                .filter(|s| !s.is_empty())
                .map(String::from)
                .collect();
            let inner = &part[open + 1..part.rfind('}').unwrap_or(part.len())];
            let mut p = prefix.to_vec();
            p.extend(head);
            walk_tree(inner, &p, out);
            continue;
        }
        let (path, alias) = match part.split_once(" as ") {
            Some((p, a)) => (p.trim(), Some(a.trim().to_string())),
            None => (part, None),
        };
        let mut segs = prefix.to_vec();
        segs.extend(path.split("::").map(|s| s.trim().to_string()));
        if segs.last().is_some_and(|s| s == "self") {
            segs.pop();
        }
        let Some(last) = segs.last().cloned() else {
            continue;
        };
        out.push((segs, alias.unwrap_or(last)));
    }
}

/// `s` split at its commas outside braces.
fn split_top(s: &str) -> Vec<&str> {
    let (mut parts, mut depth, mut from) = (Vec::new(), 0, 0);
    for (k, c) in s.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                parts.push(&s[from..k]);
                from = k + 1;
            }
            _ => {}
        }
    }
    parts.push(&s[from..]);
    parts
}

/// The paths of `code` (`a::b…`) that start at `crate`, `super`, `self` or
/// `extra` (main.rs's `dropscope`); every path when `extra` is empty.
fn inline_paths(code: &str, extra: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let chars: Vec<(usize, char)> = code.char_indices().collect();
    let mut k = 0;
    while k < chars.len() {
        let (at, c) = chars[k];
        let starts = is_ident(c)
            && (k == 0 || {
                let p = chars[k - 1].1;
                !is_ident(p) && p != ':'
            });
        if !starts {
            k += 1;
            continue;
        }
        let path: String = code[at..]
            .chars()
            .take_while(|&c| is_ident(c) || c == ':')
            .collect();
        k += path.chars().count();
        let segs: Vec<String> = path
            .split("::")
            .filter(|s| !s.is_empty())
            .map(String::from)
            .collect();
        let wanted = if extra.is_empty() {
            true
        } else {
            ["crate", "super", "self", extra].contains(&segs[0].as_str())
        };
        if segs.len() >= 2 && wanted {
            out.push(segs);
        }
    }
    out
}

#[derive(Debug, Default)]
struct Module {
    /// The file, relative to src/.
    file: String,
    children: BTreeMap<String, Vec<String>>,
    /// Names the file defines (items, inline modules, macros).
    defs: BTreeSet<String>,
    /// Names its top-level `use` items bind, with their paths.
    aliases: BTreeMap<String, Vec<String>>,
    /// Every path it names: its `use` items anywhere, and its inline
    /// `crate::`, `super::`, `self::` paths.
    refs: Vec<Vec<String>>,
}

struct Crate {
    modules: BTreeMap<Vec<String>, Module>,
    /// `#[macro_export]` macros (at the crate's root) and their module.
    macros: BTreeMap<String, Vec<String>>,
}

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn read(file: &Path) -> String {
    std::fs::read_to_string(file).unwrap_or_else(|e| panic!("{}: {e}", file.display()))
}

impl Crate {
    fn load() -> Crate {
        let mut c = Crate {
            modules: BTreeMap::new(),
            macros: BTreeMap::new(),
        };
        c.visit(Vec::new(), "lib.rs".into(), "crate");
        c.visit(vec!["<main>".into()], "main.rs".into(), "dropscope");
        c
    }

    fn visit(&mut self, path: Vec<String>, file: String, root_name: &str) {
        let code = without_tests(&strip(&read(&src().join(&file))));
        // Inside an inline module, `super` is this file's module.
        let code = self_in_inline_modules(&code);
        let top = top_level(&code);
        let mut m = Module {
            file: file.clone(),
            ..Module::default()
        };
        let dir = match Path::new(&file).file_name().and_then(|n| n.to_str()) {
            Some("mod.rs" | "lib.rs" | "main.rs") => Path::new(&file)
                .parent()
                .map(|p| p.to_path_buf())
                .unwrap_or_default(),
            _ => PathBuf::from(file.trim_end_matches(".rs")),
        };
        let mut children = Vec::new();
        for (at, name) in names_after(&top, "mod") {
            let after = top[at + 3..].trim_start()[name.len()..].trim_start();
            if after.starts_with(';') {
                let a = dir.join(format!("{name}.rs"));
                let b = dir.join(&name).join("mod.rs");
                let child = if src().join(&a).is_file() { a } else { b };
                let mut p = path.clone();
                p.push(name.clone());
                m.children.insert(name, p.clone());
                children.push((p, child.to_string_lossy().replace('\\', "/")));
            } else {
                m.defs.insert(name);
            }
        }
        for kw in [
            "fn", "struct", "enum", "const", "static", "trait", "type", "union",
        ] {
            for (_, name) in names_after(&top, kw) {
                m.defs.insert(name);
            }
        }
        for (_, name) in names_after(&code, "macro_rules!") {
            m.defs.insert(name);
        }
        let raw = read(&src().join(&file));
        for (k, _) in raw.match_indices("#[macro_export]") {
            if let Some((_, name)) = names_after(&raw[k..], "macro_rules!").first() {
                self.macros.insert(name.clone(), path.clone());
            }
        }
        for (at, tree) in use_items(&code) {
            let at_top = top[at..].starts_with("use");
            for (segs, name) in use_paths(&tree) {
                let mut segs = segs;
                if segs.last().is_some_and(|s| s == "*") {
                    segs.pop();
                }
                if segs.first().is_some_and(|s| s == root_name) && root_name != "crate" {
                    segs[0] = "crate".into();
                }
                if at_top && name != "*" && name != "_" {
                    m.aliases.insert(name, segs.clone());
                }
                m.refs.push(segs);
            }
        }
        let mut outside_use = code.clone();
        for (at, tree) in use_items(&code) {
            let end = at + 3 + tree.len();
            outside_use.replace_range(at..end, &" ".repeat(end - at));
        }
        for mut segs in inline_paths(&outside_use, root_name) {
            if segs[0] == root_name && root_name != "crate" {
                segs[0] = "crate".into();
            }
            m.refs.push(segs);
        }
        // A path from a child module of this file (`cine::open(…)` in a
        // mod.rs), written without `self::`.
        for segs in inline_paths(&outside_use, "") {
            if m.children.contains_key(&segs[0]) {
                m.refs.push(segs);
            }
        }
        self.modules.insert(path, m);
        for (p, f) in children {
            self.visit(p, f, root_name);
        }
    }

    /// The module that `segs`, named in module `here`, leads to: the one
    /// that defines its name (through re-exports), `None` outside the crate.
    fn resolve(&self, here: &[String], segs: &[String], depth: usize) -> Option<Vec<String>> {
        if depth > 16 || segs.is_empty() {
            return None;
        }
        let mut segs: &[String] = segs;
        let mut cur: Vec<String> = match segs[0].as_str() {
            "crate" => {
                segs = &segs[1..];
                Vec::new()
            }
            "self" => {
                segs = &segs[1..];
                here.to_vec()
            }
            "super" => {
                let mut cur = here.to_vec();
                while segs.first().is_some_and(|s| s == "super") {
                    cur.pop();
                    segs = &segs[1..];
                }
                cur
            }
            first => {
                let m = self.modules.get(here)?;
                if m.children.contains_key(first) || m.aliases.contains_key(first) {
                    here.to_vec()
                } else {
                    return None;
                }
            }
        };
        while let Some(s) = segs.first() {
            let m = self.modules.get(&cur)?;
            if let Some(child) = m.children.get(s) {
                cur = child.clone();
                segs = &segs[1..];
                continue;
            }
            if m.defs.contains(s) {
                return Some(cur);
            }
            if cur.is_empty() {
                if let Some(at) = self.macros.get(s) {
                    return Some(at.clone());
                }
            }
            if let Some(target) = m.aliases.get(s) {
                let mut path = target.clone();
                path.extend(segs[1..].iter().cloned());
                return self.resolve(&cur, &path, depth + 1).or(Some(cur));
            }
            return Some(cur);
        }
        Some(cur)
    }
}

/// `code` with `super::` inside inline (non-test) modules read as `self::`:
/// their `super` is the file's own module.
fn self_in_inline_modules(code: &str) -> String {
    let top = top_level(code);
    let mut out = code.to_string();
    // From the last, so that the places found stay where they were.
    for (at, name) in names_after(&top, "mod").into_iter().rev() {
        let after = top[at + 3..].trim_start()[name.len()..].trim_start();
        if !after.starts_with('{') {
            continue;
        }
        let open = at + top[at..].find('{').unwrap_or(0);
        let end = block_end(code, open);
        let inner = code[open..end].replace("super::", "self::");
        out.replace_range(open..end, &inner);
    }
    out
}

/// One import: file `from` takes `path` from file `to` (files relative to src/).
#[derive(Debug, Clone)]
struct Import {
    from: String,
    to: String,
    path: String,
}

/// Every import between two files of the crate.
fn imports() -> &'static [Import] {
    static IMPORTS: OnceLock<Vec<Import>> = OnceLock::new();
    IMPORTS.get_or_init(|| {
        let c = Crate::load();
        let mut out = Vec::new();
        for (here, m) in &c.modules {
            let lib_here: Vec<String> = if here.first().is_some_and(|s| s == "<main>") {
                Vec::new()
            } else {
                here.clone()
            };
            let mut seen = BTreeSet::new();
            for segs in &m.refs {
                // main.rs names the library only through `dropscope::`.
                let in_main = here.first().is_some_and(|s| s == "<main>");
                if in_main && segs.first().is_none_or(|s| s != "crate") {
                    continue;
                }
                let Some(to) = c.resolve(&lib_here, segs, 0) else {
                    continue;
                };
                let Some(target) = c.modules.get(&to) else {
                    continue;
                };
                let path = segs.join("::");
                if target.file != m.file && seen.insert((target.file.clone(), path.clone())) {
                    out.push(Import {
                        from: m.file.clone(),
                        to: target.file.clone(),
                        path,
                    });
                }
            }
        }
        out
    })
}

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
