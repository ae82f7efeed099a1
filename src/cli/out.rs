//! The CLI's text output: stdout and stderr written without ever panicking (a closed pipe —
//! `rtprobe run --list | head -2` — is a normal end: the command finishes and returns its own exit
//! code, its further output dropped), and plain text where a terminal's decorations do not belong
//! (stdout or stderr not a terminal, or `NO_COLOR` set: the status marks are left out).
//!
//! `println!` panics when stdout is gone (`failed printing to stdout: Broken pipe`); every line the
//! CLI prints goes through [`outln!`], [`out!`] or [`errln!`] instead.
use std::io::{IsTerminal, Write};
use std::sync::atomic::{AtomicBool, Ordering};

/// Stdout could not be written (closed pipe, full disk): nothing more is tried.
static STDOUT_GONE: AtomicBool = AtomicBool::new(false);
static STDERR_GONE: AtomicBool = AtomicBool::new(false);

/// The emoji rtprobe's renderers put before outcomes and verdicts (each is followed by words that
/// say the same). The caps report's ✗ is text, and says what no word beside it does: it stays.
const MARKS: &[char] = &['✅', '❌', '💥', '⏱', '➖', '🚧', '⚠', '❔'];

/// Whether `NO_COLOR` asks for plain text (set and not empty, <https://no-color.org>).
fn no_color() -> bool {
    std::env::var_os("NO_COLOR").is_some_and(|v| !v.is_empty())
}

/// Whether stdout gets plain text: not a terminal, or `NO_COLOR`.
pub fn plain_stdout() -> bool {
    no_color() || !std::io::stdout().is_terminal()
}

/// Whether stderr gets plain text (and progress lines instead of a bar): not a terminal, `CI` set
/// (CI systems that fake a terminal still keep a log), or `NO_COLOR`.
pub fn plain_stderr() -> bool {
    no_color()
        || std::env::var_os("CI").is_some_and(|v| !v.is_empty() && v != "false" && v != "0")
        || !std::io::stderr().is_terminal()
}

/// `text` without status marks (each with the variation selector and the space after it) and
/// without ANSI escape sequences.
pub fn strip_marks(text: &str) -> String {
    let mut s = String::with_capacity(text.len());
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        if MARKS.contains(&c) {
            if chars.peek() == Some(&'\u{fe0f}') {
                chars.next();
            }
            if chars.peek() == Some(&' ') {
                chars.next();
            }
        } else if c == '\u{1b}' {
            // CSI: ESC [ parameters final-byte (0x40..=0x7e).
            if chars.peek() == Some(&'[') {
                chars.next();
                for d in chars.by_ref() {
                    if ('\u{40}'..='\u{7e}').contains(&d) {
                        break;
                    }
                }
            }
        } else {
            s.push(c);
        }
    }
    s
}

fn write_to(gone: &AtomicBool, mut w: impl Write, plain: bool, text: &str) {
    if gone.load(Ordering::Relaxed) {
        return;
    }
    let text = if plain { strip_marks(text) } else { text.to_string() };
    if w.write_all(text.as_bytes()).and_then(|_| w.flush()).is_err() {
        gone.store(true, Ordering::Relaxed);
    }
}

/// Write `text` to stdout (see the module doc); after a failed write, nothing more is written.
pub fn stdout(text: &str) {
    write_to(&STDOUT_GONE, std::io::stdout().lock(), plain_stdout(), text);
}

/// Write `text` to stderr, the same way.
pub fn stderr(text: &str) {
    write_to(&STDERR_GONE, std::io::stderr().lock(), plain_stderr(), text);
}

/// `println!` to stdout that never panics.
macro_rules! outln {
    () => { $crate::cli::out::stdout("\n") };
    ($($arg:tt)*) => { $crate::cli::out::stdout(&(format!($($arg)*) + "\n")) };
}

/// `print!` to stdout that never panics.
macro_rules! out {
    ($($arg:tt)*) => { $crate::cli::out::stdout(&format!($($arg)*)) };
}

/// `eprintln!` that never panics.
macro_rules! errln {
    ($($arg:tt)*) => { $crate::cli::out::stderr(&(format!($($arg)*) + "\n")) };
}

pub(crate) use {errln, out, outln};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn marks_and_escapes_are_left_out_of_plain_text() {
        assert_eq!(
            strip_marks(
                "outcomes:  ✅ pass 12  ❌ mismatch 0  💥 crash 15  ⏱ timeout 0  ⚠\u{fe0f} error 6"
            ),
            "outcomes:  pass 12  mismatch 0  crash 15  timeout 0  error 6"
        );
        assert_eq!(strip_marks("\u{1b}[1m\u{1b}[31merror:\u{1b}[0m x"), "error: x");
        // Other text, arrows and bounds included, is kept.
        let kept = "nonuniform → crash, p ≥ 0.61, miss ≤ 0.94% — ok; ✗ VK_EXT_descriptor_heap";
        assert_eq!(strip_marks(kept), kept);
    }

    #[test]
    fn a_closed_stdout_is_remembered_and_never_panics() {
        struct Closed;
        impl Write for Closed {
            fn write(&mut self, _: &[u8]) -> std::io::Result<usize> {
                Err(std::io::ErrorKind::BrokenPipe.into())
            }
            fn flush(&mut self) -> std::io::Result<()> {
                Ok(())
            }
        }
        let gone = AtomicBool::new(false);
        write_to(&gone, Closed, true, "a line\n");
        assert!(gone.load(Ordering::Relaxed));
        // Nothing more is tried.
        write_to(&gone, Closed, true, "another\n");
    }
}
