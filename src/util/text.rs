//! One sanitiser for text that came from a file or a name (a run or file
//! name, a cine's camera text, a manifest cell, a failure's reason) on its
//! way to a terminal, a CSV cell or a run name. The report has its own HTML
//! escaping ([`crate::report::html::escape`]).
//!
//! - **Terminal** ([`terminal`]): every control character but a newline and
//!   a tab (escape sequences that set a window title, clear the screen or
//!   write the clipboard start with one) and every Unicode format character
//!   (category Cf: zero-width characters, bidirectional overrides that show
//!   `evil\u{202E}gnp.exe` as `evilexe.png`) is shown as `\u{…}`.
//! - **CSV cell** ([`csv_cell`]): the same characters escaped, newlines and
//!   tabs too, and a text cell that a spreadsheet would take for a formula
//!   (starting with `=`, `+`, `-`, `@`, a tab or a carriage return, as the
//!   OWASP guidance on CSV injection lists) gets a `'` in front, as does one
//!   starting with `'`; [`csv_cell_back`] removes it, so a run name survives
//!   the round trip. Numeric columns are written as numbers and never touched.
//! - **Run names** ([`crate::dataset::run_name::check`]) refuse control and format
//!   characters outright.

use std::borrow::Cow;
use std::fmt::Write;

/// Whether `c` is a Unicode format character (general category Cf,
/// Unicode 15): soft hyphen, Arabic and Syriac marks, zero-width space,
/// joiners and marks, bidirectional embeddings, overrides and isolates,
/// invisible operators, the byte-order mark, interlinear annotation, tags.
pub fn is_format(c: char) -> bool {
    matches!(
        c as u32,
        0x00AD
            | 0x0600..=0x0605
            | 0x061C
            | 0x06DD
            | 0x070F
            | 0x0890..=0x0891
            | 0x08E2
            | 0x180E
            | 0x200B..=0x200F
            | 0x202A..=0x202E
            | 0x2060..=0x2064
            | 0x2066..=0x206F
            | 0xFEFF
            | 0xFFF9..=0xFFFB
            | 0x110BD
            | 0x110CD
            | 0x13430..=0x1343F
            | 0x1BCA0..=0x1BCA3
            | 0x1D173..=0x1D17A
            | 0xE0001
            | 0xE0020..=0xE007F
    )
}

/// Whether `c` is shown escaped: a control character (C0, DEL, C1) or a
/// format character ([`is_format`]); `keep` lists controls let through.
fn hidden(c: char, keep: &[char]) -> bool {
    (c.is_control() || is_format(c)) && !keep.contains(&c)
}

fn escaped<'a>(s: &'a str, keep: &[char]) -> Cow<'a, str> {
    if !s.chars().any(|c| hidden(c, keep)) {
        return Cow::Borrowed(s);
    }
    let mut out = String::with_capacity(s.len() + 8);
    for c in s.chars() {
        if hidden(c, keep) {
            let _ = write!(out, "\\u{{{:x}}}", c as u32);
        } else {
            out.push(c);
        }
    }
    Cow::Owned(out)
}

/// `s` safe to print on a terminal: controls other than newline and tab,
/// and format characters, shown as `\u{…}`.
pub fn terminal(s: &str) -> Cow<'_, str> {
    escaped(s, &['\n', '\t'])
}

/// `s` on one line: every control and format character shown as `\u{…}`.
pub fn one_line(s: &str) -> Cow<'_, str> {
    escaped(s, &[])
}

/// A JSON document with every control character but newline (which
/// serde_json leaves only between tokens) and every format character
/// written as a `\uXXXX` escape: the same document, safe on a terminal.
pub fn json(doc: &str) -> Cow<'_, str> {
    if !doc.chars().any(|c| hidden(c, &['\n'])) {
        return Cow::Borrowed(doc);
    }
    let mut out = String::with_capacity(doc.len() + 16);
    for c in doc.chars() {
        if hidden(c, &['\n']) {
            let mut units = [0u16; 2];
            for u in c.encode_utf16(&mut units) {
                let _ = write!(out, "\\u{u:04x}");
            }
        } else {
            out.push(c);
        }
    }
    Cow::Owned(out)
}

/// The first characters that make a spreadsheet read a cell as a formula
/// (OWASP, CSV injection), and the quote that marks one neutralised.
const FORMULA_START: [char; 6] = ['=', '+', '-', '@', '\t', '\r'];
const QUOTE: char = '\'';

/// A text cell of a CSV file: [`one_line`], with a `'` in front when it
/// starts like a formula or with a `'` (see the module docs). `-` alone is
/// the word for "none" ([`crate::dataset::NO_TEXT`]) and stays.
pub fn csv_cell(s: &str) -> Cow<'_, str> {
    let flat = one_line(s);
    let quote = flat != "-"
        && flat
            .chars()
            .next()
            .is_some_and(|c| c == QUOTE || FORMULA_START.contains(&c));
    if quote {
        Cow::Owned(format!("{QUOTE}{flat}"))
    } else {
        flat
    }
}

/// A text cell as [`csv_cell`] wrote it, back: the `'` it put in front removed.
pub fn csv_cell_back(s: &str) -> &str {
    match s.strip_prefix(QUOTE) {
        Some(rest)
            if rest
                .chars()
                .next()
                .is_some_and(|c| c == QUOTE || FORMULA_START.contains(&c)) =>
        {
            rest
        }
        _ => s,
    }
}

/// "1 drop", "3 drops": a count with its noun for messages.
pub fn plural(n: usize, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escape_sequences_and_format_characters_are_shown_not_sent() {
        let title = "run\u{1b}]0;owned\u{7}\u{1b}[2J\u{9b}x";
        assert_eq!(
            terminal(title),
            "run\\u{1b}]0;owned\\u{7}\\u{1b}[2J\\u{9b}x"
        );
        assert_eq!(terminal("evil\u{202e}gnp.exe"), "evil\\u{202e}gnp.exe");
        assert_eq!(terminal("r\u{200b}un"), "r\\u{200b}un");
        assert_eq!(terminal("two\nlines\tand a tab"), "two\nlines\tand a tab");
        assert_eq!(one_line("two\nlines"), "two\\u{a}lines");
        assert!(matches!(terminal("Größe 3 µs"), Cow::Borrowed(_)));
        assert!(is_format('\u{feff}') && is_format('\u{e0041}') && !is_format('é'));
        let doc = serde_json::to_string_pretty(&serde_json::json!({
            "camera": "cam\u{1b}]52;c;eA==\u{7}\u{9b}\u{202e}\u{e0041}"
        }))
        .unwrap();
        let safe = json(&doc);
        assert!(!safe.chars().any(|c| hidden(c, &['\n'])), "{safe}");
        let back: serde_json::Value = serde_json::from_str(&safe).unwrap();
        let orig: serde_json::Value = serde_json::from_str(&doc).unwrap();
        assert_eq!(back, orig);
    }

    #[test]
    fn formula_cells_get_a_quote_that_reads_back_off() {
        for (raw, cell) in [
            ("=cmd|' -c calc'!A1", "'=cmd|' -c calc'!A1"),
            ("@SUM(A1:A9)", "'@SUM(A1:A9)"),
            ("+cmd", "'+cmd"),
            ("-2+3", "'-2+3"),
            ("\tx", "\\u{9}x"),
            ("'quoted", "''quoted"),
            ("R4.5mm_H12cm_01", "R4.5mm_H12cm_01"),
            ("-", "-"),
            ("a=b", "a=b"),
        ] {
            assert_eq!(csv_cell(raw), cell, "{raw:?}");
        }
        for raw in ["=cmd", "@SUM(A1)", "+1", "-x", "'q", "''", "plain", "-"] {
            assert_eq!(csv_cell_back(&csv_cell(raw)), raw, "{raw:?}");
        }
        // A user's own quote before a plain word is theirs.
        assert_eq!(csv_cell_back("'plain"), "'plain");
    }
}
