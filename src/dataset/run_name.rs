//! Run names are names: they become file names (`tracks/<run>.csv`,
//! `runs/<run>.json`, `plots/overlays/<run>_<n>.png`), so a name from a
//! manifest must be one file name and nothing else, and a name taken from a
//! folder or file is made into one.

use std::path::Path;

/// Longest run name in bytes: file systems allow 255, and the longest file
/// made from a name (a temporary `.<run>_<n>.png.tmp<pid>`) adds ~40.
pub const MAX_RUN_NAME_BYTES: usize = 200;

/// Why `name` cannot be a run name, or `Ok` when it can: not empty, at most
/// [`MAX_RUN_NAME_BYTES`] bytes, no `/` or `\`, no control character, and
/// no Unicode format character (category Cf: zero-width, bidirectional
/// overrides), and not starting with `.` (which also rules out `.` and `..`).
pub fn check(name: &str) -> Result<(), String> {
    let why = if name.is_empty() {
        "is empty"
    } else if name.len() > MAX_RUN_NAME_BYTES {
        "is longer than 200 bytes"
    } else if name.contains(['/', '\\']) {
        "holds a path separator (a run name names files inside the output folder)"
    } else if name.chars().any(char::is_control) {
        "holds a control character"
    } else if let Some(c) = name.chars().find(|&c| crate::util::text::is_format(c)) {
        return Err(format!(
            "run name {:?} holds the invisible format character U+{:04X} (a zero-width or \
             text-direction character: it makes one name look like another); retype the name \
             without it",
            crate::util::text::one_line(name),
            c as u32
        ));
    } else if name.starts_with('.') {
        "starts with `.` (names like `..` or hidden files are not run names)"
    } else {
        return Ok(());
    };
    Err(format!(
        "run name {:?} {why}",
        crate::util::text::one_line(name)
    ))
}

/// The run name of an input given without a manifest: its folder's whole
/// name, dots and all, or its `.cine` file's name without `.cine`
/// ([`crate::source::input_name`]), made into a valid name:
/// separators, control and format characters become `_`, a leading `.` gets a `_`
/// before it, and an over-long name is cut at a character boundary.
pub fn from_input(path: &Path) -> String {
    // `..` or `/` have no name of their own: name them after where they lead.
    let resolved = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
    let raw = crate::source::input_name(&resolved);
    let mut name: String = raw
        .chars()
        .map(|c| {
            if c == '/' || c == '\\' || c.is_control() || crate::util::text::is_format(c) {
                '_'
            } else {
                c
            }
        })
        .collect();
    if name.is_empty() || name.starts_with('.') {
        name.insert(0, '_');
    }
    if name.len() > MAX_RUN_NAME_BYTES {
        let mut end = MAX_RUN_NAME_BYTES;
        while !name.is_char_boundary(end) {
            end -= 1;
        }
        name.truncate(end);
    }
    name
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_with_separators_dots_controls_or_great_length_are_refused() {
        for ok in ["R4.5mm_H12cm_01", "drop 7", "a..b", "Größe_3"] {
            assert_eq!(check(ok), Ok(()), "{ok}");
        }
        for (bad, why) in [
            ("", "empty"),
            ("../../x", "path separator"),
            ("..", "starts with `.`"),
            (".hidden", "starts with `.`"),
            ("a\\b", "path separator"),
            ("a\tb", "control character"),
            ("a\u{7f}", "control character"),
            ("r\u{200b}un", "U+200B"),
            ("evil\u{202e}gnp.exe", "U+202E"),
            ("\u{feff}run", "U+FEFF"),
        ] {
            let e = check(bad).unwrap_err();
            assert!(e.contains(why), "{bad:?}: {e}");
        }
        assert!(check(&"x".repeat(200)).is_ok());
        assert!(check(&"x".repeat(201)).unwrap_err().contains("200 bytes"));
    }

    #[test]
    fn input_names_are_made_valid() {
        let dir = tempfile::tempdir().unwrap();
        let run = dir.path().join("R4.5mm_H12cm_01");
        std::fs::create_dir(&run).unwrap();
        assert_eq!(from_input(&run), "R4.5mm_H12cm_01");
        // `..` is named after the folder it resolves to.
        assert_eq!(from_input(&run.join("..")), from_input(dir.path()));
        let odd = dir.path().join(".a\tb");
        std::fs::create_dir(&odd).unwrap();
        assert_eq!(from_input(&odd), "_.a_b");
        let long = "é".repeat(150);
        let n = from_input(&dir.path().join(format!("{long}.cine")));
        assert!(n.len() <= MAX_RUN_NAME_BYTES && n.starts_with("éé"), "{n}");
        for n in [from_input(Path::new("/")), from_input(&run), n] {
            assert_eq!(check(&n), Ok(()), "{n:?}");
        }
    }

    /// Only a `.cine` file loses its extension: the text after a dot of a
    /// folder's name, of a path that is not there, or of a cine saved
    /// without `.cine`, is part of the name (`R4.5mm_H12cm_01_typo` was
    /// named `R4`).
    #[test]
    fn only_a_cine_loses_its_extension() {
        let dir = tempfile::tempdir().unwrap();
        let at = |name: &str| dir.path().join(name);
        std::fs::create_dir(at("R4.5mm_H12cm_01.v2")).unwrap();
        std::fs::create_dir(at("odd.cine")).unwrap();
        std::fs::write(at("R7mm_H50cm_01.cine"), b"").unwrap();
        std::fs::write(at("R3mm_H1.5cm_01.CINE"), b"").unwrap();
        std::fs::write(at("R4.5mm_H12cm_02"), b"CI").unwrap();
        for (input, name) in [
            ("R4.5mm_H12cm_01.v2", "R4.5mm_H12cm_01.v2"),
            ("odd.cine", "odd.cine"),
            ("R7mm_H50cm_01.cine", "R7mm_H50cm_01"),
            ("R3mm_H1.5cm_01.CINE", "R3mm_H1.5cm_01"),
            ("R4.5mm_H12cm_02", "R4.5mm_H12cm_02"),
            ("R4.5mm_H12cm_01_typo", "R4.5mm_H12cm_01_typo"),
            ("gone/R4.5mm_H12cm_03.cine", "R4.5mm_H12cm_03"),
        ] {
            assert_eq!(from_input(&at(input)), name, "{input}");
        }
        assert_eq!(
            from_input(Path::new("d1/R4.5mm_H12cm_01_typo")),
            "R4.5mm_H12cm_01_typo"
        );
    }
}
