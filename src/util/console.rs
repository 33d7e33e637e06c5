//! What dropscope prints on its standard output and error: each text made
//! safe for a terminal ([`crate::util::text::terminal`]: no escape sequence from a
//! file name or a cine's camera text reaches it), and written without ever
//! panicking. `println!` panics when the write fails: a closed pipe
//! (`dropscope run | head -c 600`), a full disk (`2>/dev/full`). Here a
//! failed write is dropped, and the job goes on to write its outputs.
//!
//! [`outln!`](crate::outln) and [`errln!`](crate::errln) are `println!` and
//! `eprintln!` through it; [`out_raw`] prints trusted text as it is (the
//! embedded default configuration, JSON made by dropscope).

use std::io::Write;

/// Write `text` to `w`, ignoring a failure (closed pipe, no space).
fn put(mut w: impl Write, text: &str) {
    let _ = w.write_all(text.as_bytes()).and_then(|()| w.flush());
}

/// `text` on standard output, made safe for a terminal.
pub fn out(text: &str) {
    put(std::io::stdout().lock(), &crate::util::text::terminal(text));
}

/// `text` on standard output as it is (text dropscope made, nothing from a file).
pub fn out_raw(text: &str) {
    put(std::io::stdout().lock(), text);
}

/// `text` on standard error, made safe for a terminal.
pub fn err(text: &str) {
    put(std::io::stderr().lock(), &crate::util::text::terminal(text));
}

/// `println!` through [`out`]: never panics, escapes what a terminal would run.
#[macro_export]
macro_rules! outln {
    ($($arg:tt)*) => {
        $crate::util::console::out(&format!("{}\n", format_args!($($arg)*)))
    };
}

/// `eprintln!` through [`err`]: never panics, escapes what a terminal would run.
#[macro_export]
macro_rules! errln {
    ($($arg:tt)*) => {
        $crate::util::console::err(&format!("{}\n", format_args!($($arg)*)))
    };
}
