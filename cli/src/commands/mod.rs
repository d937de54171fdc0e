//! The subcommands, one module each, and what they share: error reporting, stdout output,
//! input loading. (Parameters as JSON: `animcodec::params`; bpvf: `animcodec::metrics::bpvf`.)

pub mod animations;
pub mod args;
pub mod decode;
pub mod demo;
pub mod encode;
pub mod eval;
pub mod export;
pub mod info;
pub mod inspect;
pub mod list;
pub mod source;
pub mod sweep;
pub mod synth;
pub mod view;

use animcodec::core::Limits;
use animcodec::formats::{self, ReadOptions};
use animcodec::front::{self, Resolved, Streams};
use serde_json::Value;
use std::error::Error as StdError;
use std::io::Write;

/// What every subcommand returns. Errors are codec-core errors, I/O errors, or plain messages.
pub type CmdResult<T = ()> = Result<T, Box<dyn StdError + Send + Sync>>;

/// Prints `error: <message>` followed by each `source()` not already part of the message,
/// on one line ([`animcodec::core::error::message_with_sources`]).
pub fn report_error(e: &(dyn StdError + 'static)) {
    let message = animcodec::core::error::message_with_sources(e);
    let _ = writeln!(std::io::stderr(), "error: {}", terminal_safe(&message));
}

/// A path (or any other name that came from the user or a file) as it is printed: control
/// characters — terminal escape sequences, newlines, carriage returns, … — written as Rust
/// escapes (`\u{1b}`, `\n`), so a crafted file name can neither drive the terminal nor fake a
/// line of output. Every path a command prints goes through it.
pub fn shown(name: impl AsRef<std::ffi::OsStr>) -> String {
    let text = name.as_ref().to_string_lossy();
    if !text.chars().any(char::is_control) {
        return text.into_owned();
    }
    text.chars().map(|c| if c.is_control() { c.escape_default().to_string() } else { c.to_string() }).collect()
}

/// `text` with every control character but newline and tab escaped as [`shown`] does: the
/// last guard of everything written to the terminal ([`emit`], [`report_error`]), for names a
/// library put into a message (its own path, a glTF animation's name, …).
pub fn terminal_safe(text: &str) -> std::borrow::Cow<'_, str> {
    let unsafe_char = |c: char| c.is_control() && c != '\n' && c != '\t';
    if !text.chars().any(unsafe_char) {
        return text.into();
    }
    text.chars().map(|c| if unsafe_char(c) { c.escape_default().to_string() } else { c.to_string() }).collect()
}

/// Most worker threads `--threads` and `sweep --jobs` accept: 4 × the cores this process may
/// use, at least 8. More threads than cores make nothing faster (the output never depends on
/// the count), and thousands of them take minutes to start and hold gigabytes
/// (`--threads 65535` and `sweep --jobs 5000` run past 60 s on trivial inputs).
pub fn max_workers() -> u32 {
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
    u32::try_from(cores.saturating_mul(4)).unwrap_or(u32::MAX).max(8)
}

/// Parses a worker count for `--threads` and `--jobs`: 1 ..= [`max_workers`].
pub fn parse_workers(text: &str) -> Result<u32, String> {
    let n: u32 = text.trim().parse().map_err(|_| format!("'{text}' is not a positive number of threads"))?;
    let max = max_workers();
    match n {
        0 => Err("0 threads: give at least 1".to_owned()),
        n if n > max => Err(format!(
            "{n} threads is more than this machine allows ({max}: 4 × its {} cores, at least 8); more threads than \
             cores make nothing faster (the output is the same at any count) and thousands take minutes to start",
            std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get)
        )),
        n => Ok(n),
    }
}

/// An error with what was being done (usually the file concerned) in front of it.
#[derive(Debug)]
pub struct Context {
    context: String,
    source: Box<dyn StdError + Send + Sync>,
}

impl std::fmt::Display for Context {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.context, self.source)
    }
}

impl StdError for Context {
    fn source(&self) -> Option<&(dyn StdError + 'static)> {
        Some(self.source.as_ref())
    }
}

/// Adds context (such as the file name) to errors.
pub trait WithContext<T> {
    /// Prefixes the error with `context()`.
    fn context(self, context: impl FnOnce() -> String) -> CmdResult<T>;

    /// Prefixes the error with the file name `file`, unless its message already names it (the
    /// readers name their file themselves: printed twice, it reads like two files).
    fn in_file(self, file: &str) -> CmdResult<T>;
}

impl<T, E: Into<Box<dyn StdError + Send + Sync>>> WithContext<T> for Result<T, E> {
    fn context(self, context: impl FnOnce() -> String) -> CmdResult<T> {
        self.map_err(|e| Box::new(Context { context: context(), source: e.into() }) as _)
    }

    fn in_file(self, file: &str) -> CmdResult<T> {
        self.map_err(|e| {
            let e: Box<dyn StdError + Send + Sync> = e.into();
            if animcodec::core::error::message_with_sources(e.as_ref()).contains(file) {
                e
            } else {
                Box::new(Context { context: file.to_owned(), source: e }) as _
            }
        })
    }
}

/// Parses a frame rate for `--fps`: a number in [`formats::FRAME_RATE_RANGE`].
pub fn parse_fps(text: &str) -> Result<f32, String> {
    match text.trim().parse::<f32>() {
        Ok(f) if formats::FRAME_RATE_RANGE.contains(&f) => Ok(f),
        _ => Err(format!(
            "'{text}' is not a frame rate in {}..={} frames per second",
            formats::FRAME_RATE_RANGE.start(),
            formats::FRAME_RATE_RANGE.end()
        )),
    }
}

/// Writes `text` to stdout. A closed pipe (`animcodec list | head`) ends output quietly
/// instead of panicking as `println!` would.
pub fn emit(text: &str) -> CmdResult {
    let text = terminal_safe(text);
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(Box::new(e)),
        _ => Ok(()),
    }
}

/// Writes pretty JSON and a newline to stdout.
pub fn emit_json(value: &Value) -> CmdResult {
    let mut text = serde_json::to_string_pretty(value)?;
    text.push('\n');
    emit(&text)
}

/// Writes a document (a serde type) as pretty JSON: its keys sorted, as every document prints.
pub fn emit_document<T: serde::Serialize>(document: &T) -> CmdResult {
    emit_json(&serde_json::to_value(document)?)
}

/// Parses a byte count: a plain number or one with a K, M, G or T suffix (powers of 1024;
/// `KB`/`KiB` spellings and lower case accepted).
pub fn parse_bytes(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let split = t.find(|c: char| !c.is_ascii_digit()).unwrap_or(t.len());
    let (digits, suffix) = t.split_at(split);
    let number: u64 = digits.parse().map_err(|_| format!("'{text}' is not a byte count like 512M or 4G"))?;
    let shift = match suffix.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 0,
        "k" | "kb" | "kib" => 10,
        "m" | "mb" | "mib" => 20,
        "g" | "gb" | "gib" => 30,
        "t" | "tb" | "tib" => 40,
        _ => return Err(format!("'{text}' has an unknown unit (use K, M, G or T)")),
    };
    number.checked_mul(1u64 << shift).filter(|&n| n > 0).ok_or_else(|| format!("'{text}' is out of range"))
}

/// An input through the library's front door ([`front::resolve_input`]) with this program's
/// codecs: `synth:…`, an animation file, or (with [`Streams::Decode`]) an `.anim` stream.
pub fn load(input: &str, read: &ReadOptions, limits: Limits, streams: Streams) -> CmdResult<Resolved> {
    front::resolve_input(&animcodec::registry(), input, read, limits, streams)
}

/// Bytes of the animation stored as raw `f32` coordinates.
pub fn raw_bytes(vertices: usize, frames: usize) -> u64 {
    vertices as u64 * frames as u64 * 12
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn byte_counts_parse_with_units() {
        assert_eq!(parse_bytes("1000"), Ok(1000));
        assert_eq!(parse_bytes("4K"), Ok(4096));
        assert_eq!(parse_bytes("512MiB"), Ok(512 << 20));
        assert_eq!(parse_bytes("2g"), Ok(2 << 30));
        assert!(parse_bytes("").is_err());
        assert!(parse_bytes("0").is_err());
        assert!(parse_bytes("12Q").unwrap_err().contains("unknown unit"));
        assert!(parse_bytes("99999999999999999999T").is_err());
        assert!(parse_bytes("16777216T").is_err());
        assert_eq!(parse_fps("24"), Ok(24.0));
        assert_eq!(parse_fps("1e4"), Ok(1e4));
        for bad in ["0", "-3", "nan", "inf", "x", "1e-45", "1e5", "0.0009"] {
            assert!(parse_fps(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn printed_names_escape_control_characters() {
        assert_eq!(shown("plain/dir/a.pc2"), "plain/dir/a.pc2");
        assert_eq!(shown("x\x1b[31mRED\x1b[0m.pc2"), "x\\u{1b}[31mRED\\u{1b}[0m.pc2");
        assert_eq!(shown("two\nlines\r.obj"), "two\\nlines\\r.obj");
        assert_eq!(terminal_safe("a\tb\nc\x07d\x1b"), "a\tb\nc\\u{7}d\\u{1b}");
        assert!(parse_workers("0").is_err() && parse_workers("x").is_err());
        assert_eq!(parse_workers("1"), Ok(1));
        assert_eq!(parse_workers(&max_workers().to_string()), Ok(max_workers()));
        let e = parse_workers("65535").unwrap_err();
        assert!(e.contains("65535 threads") && e.contains("cores"), "{e}");
    }
}
