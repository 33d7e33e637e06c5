//! Reading the sources of `src/`: comments and literals blanked, test code
//! left out, `use` trees and inline paths collected, and each path followed
//! through the re-exports to the file that defines its name.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

// --- Reading the sources.

/// `text` with comments, string and character literals blanked (newlines
/// kept), so that only code is searched.
pub(super) fn strip(text: &str) -> String {
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
pub(super) fn without_tests(code: &str) -> String {
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

pub(super) fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

pub(super) fn read(file: &Path) -> String {
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
pub(super) struct Import {
    pub(super) from: String,
    pub(super) to: String,
    pub(super) path: String,
}

/// Every import between two files of the crate.
pub(super) fn imports() -> &'static [Import] {
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
