//! The one error type of the core and of every codec.
//!
//! Messages name the codec (or the container) and the field involved, so a user reading
//! `quant-delta: packet 3: field 'residual_bytes' is truncated` knows where to look.

use std::borrow::Cow;

/// Result alias used throughout animcodec.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong while building, encoding or decoding an animation.
///
/// `context` fields name the codec (`quant-delta`, `pca-aoi`, …) or `container`;
/// `field` names the value in the stream or the parameter concerned.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The animation handed to a constructor or an encoder is not valid.
    #[error("invalid animation: {0}")]
    InvalidAnimation(String),

    /// A codec parameter is unknown, of the wrong kind or out of range.
    #[error("{codec}: parameter '{name}': {message}")]
    InvalidParameter {
        /// Codec name.
        codec: Cow<'static, str>,
        /// Parameter name.
        name: Cow<'static, str>,
        /// What is wrong, including the allowed range or values.
        message: String,
    },

    /// The stream ended before a field could be read.
    #[error("{context}: field '{field}' is truncated (stream ended early)")]
    Truncated {
        /// Codec name or `container`.
        context: Cow<'static, str>,
        /// Field being read.
        field: Cow<'static, str>,
    },

    /// A field read from the stream has an impossible value.
    #[error("{context}: field '{field}' is malformed: {detail}")]
    Malformed {
        /// Codec name or `container`.
        context: Cow<'static, str>,
        /// Field being read.
        field: Cow<'static, str>,
        /// Why the value is rejected.
        detail: String,
    },

    /// A size read from the stream exceeds the decoding [`Limits`](crate::Limits).
    #[error("{context}: field '{field}' = {value} exceeds the limit of {limit}")]
    LimitExceeded {
        /// Codec name or `container`.
        context: Cow<'static, str>,
        /// Field being read.
        field: Cow<'static, str>,
        /// Value found in the stream.
        value: u64,
        /// Limit in force.
        limit: u64,
    },

    /// What a decode would hold at once (sizes read from the stream) exceeds
    /// [`Limits::max_alloc_bytes`](crate::Limits::max_alloc_bytes).
    #[error(
        "{context}: {what} would need {bytes} bytes, more than the {limit} bytes left of the memory limit \
         for the whole decode (Limits::max_alloc_bytes; --max-memory on the command line)"
    )]
    AllocLimit {
        /// Codec name or `container`.
        context: Cow<'static, str>,
        /// What would be allocated (a field or a decoded block), in words.
        what: Cow<'static, str>,
        /// Bytes needed.
        bytes: u64,
        /// Limit in force.
        limit: u64,
    },

    /// The work a stream asks for (counted from sizes before it starts) exceeds
    /// [`Limits::max_work`](crate::Limits::max_work).
    #[error(
        "{context}: {what} would take about {ops} operations, more than the work limit of {limit} \
         for one decode (Limits::max_work; --max-work on the command line)"
    )]
    WorkLimit {
        /// Codec name or `container`.
        context: Cow<'static, str>,
        /// What would be computed, in words.
        what: Cow<'static, str>,
        /// Operations estimated.
        ops: u64,
        /// Limit in force.
        limit: u64,
    },

    /// A checksum does not match: the stream is corrupt.
    #[error("{context}: checksum mismatch in {field} (stored {stored:#010x}, computed {computed:#010x})")]
    Checksum {
        /// Codec name or `container`.
        context: Cow<'static, str>,
        /// Section whose checksum failed.
        field: Cow<'static, str>,
        /// Checksum stored in the stream.
        stored: u32,
        /// Checksum computed over the bytes read.
        computed: u32,
    },

    /// No registered codec has this name or FourCC.
    #[error("unknown codec '{requested}'; available codecs: {available}")]
    UnknownCodec {
        /// Name or FourCC requested.
        requested: String,
        /// Comma-separated list of registered codecs.
        available: String,
    },

    /// The codec or container cannot do what was asked (e.g. a newer stream version).
    #[error("{context}: unsupported: {detail}")]
    Unsupported {
        /// Codec name or `container`.
        context: Cow<'static, str>,
        /// What is unsupported.
        detail: String,
    },

    /// A numerical step failed (a decomposition did not converge, a solve was singular).
    #[error("{context}: numerical failure in {step}: {detail}")]
    Numerical {
        /// Codec name.
        context: Cow<'static, str>,
        /// Algorithm step, e.g. `eigensolver` or `polar decomposition`.
        step: Cow<'static, str>,
        /// Details.
        detail: String,
    },

    /// An I/O error, with the path or stream concerned.
    #[error("{context}: {}", io_reason(source))]
    Io {
        /// Path or description of the stream.
        context: String,
        /// Underlying error.
        #[source]
        source: std::io::Error,
    },
}

/// The error's message followed by each `source()` not already part of it, on one line (an
/// error wrapping an I/O error, for example, already prints its source; I/O sources are shown
/// in plain words by [`io_reason`]). The command line's `error:` line and the Python
/// package's exception text.
pub fn message_with_sources(e: &(dyn std::error::Error + 'static)) -> String {
    let mut line = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        let text = match s.downcast_ref::<std::io::Error>() {
            Some(io) => io_reason(io),
            None => s.to_string(),
        };
        if !line.contains(&text) {
            line.push_str(": ");
            line.push_str(&text);
        }
        source = s.source();
    }
    // A single line even if some message contains a newline.
    line.replace('\n', " ")
}

/// The reason of an I/O error in plain words: "no such file or directory", "permission denied",
/// or the error's own text without the OS error number.
pub fn io_reason(e: &std::io::Error) -> String {
    if e.get_ref().is_some() {
        return e.to_string();
    }
    match e.kind() {
        std::io::ErrorKind::NotFound => "no such file or directory".into(),
        std::io::ErrorKind::PermissionDenied => "permission denied".into(),
        _ => {
            let text = e.to_string();
            match text.find(" (os error") {
                Some(at) => text[..at].to_owned(),
                None => text,
            }
        }
    }
}

/// A `Debug` rendering of a third-party error (a linear-algebra solver's enum, say) turned into
/// words for a message: `NonPositivePivot { index: 42 }` → `non positive pivot (index 42)`,
/// `NoConvergence` → `no convergence`. Messages never show raw `Debug` values.
pub fn debug_in_words(value: &dyn std::fmt::Debug) -> String {
    let debug = format!("{value:?}");
    let mut out = String::with_capacity(debug.len() + 8);
    let mut prev_lower = false;
    for c in debug.chars() {
        match c {
            '{' | '(' => {
                let trimmed = out.trim_end().len();
                out.truncate(trimmed);
                out.push_str(" (");
                prev_lower = false;
            }
            '}' | ')' => {
                let trimmed = out.trim_end().len();
                out.truncate(trimmed);
                out.push(')');
                prev_lower = false;
            }
            ':' => prev_lower = false,
            c if c.is_ascii_uppercase() => {
                if prev_lower {
                    out.push(' ');
                }
                out.push(c.to_ascii_lowercase());
                prev_lower = false;
            }
            c => {
                if !(c == ' ' && out.ends_with(['(', ' '])) {
                    out.push(c);
                }
                prev_lower = c.is_ascii_lowercase() || c.is_ascii_digit();
            }
        }
    }
    out.replace("( ", "(")
}

/// True when `text` holds what looks like a Rust `Debug` value — `Name(Name…` (no space
/// before the parenthesis) or `Name { field: …` — which a user-facing message must not: the
/// tests of the conformance suite and of the CLI assert it on every error they provoke.
pub fn looks_like_debug(text: &str) -> bool {
    let camel = |w: &str| {
        w.len() > 1 && w.starts_with(|c: char| c.is_ascii_uppercase()) && w.chars().any(|c| c.is_ascii_lowercase())
    };
    let word_before = |end: usize| {
        let start = text[..end].rfind(|c: char| !c.is_ascii_alphanumeric()).map_or(0, |p| p + 1);
        &text[start..end]
    };
    let word_after = |start: usize| {
        let end =
            text[start..].find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).map_or(text.len(), |p| start + p);
        (&text[start..end], &text[end..])
    };
    for (i, c) in text.char_indices() {
        if c == '(' && camel(word_before(i)) && camel(word_after(i + 1).0) {
            return true;
        }
        if c == '{' && i > 0 && text[..i].ends_with(' ') && camel(word_before(i - 1)) {
            let (field, rest) = word_after((i + 2).min(text.len()));
            if text[i + 1..].starts_with(' ') && !field.is_empty() && rest.starts_with(':') {
                return true;
            }
        }
    }
    false
}

impl Error {
    /// Shorthand for [`Error::Malformed`].
    pub fn malformed(
        context: impl Into<Cow<'static, str>>,
        field: impl Into<Cow<'static, str>>,
        detail: impl Into<String>,
    ) -> Self {
        Error::Malformed { context: context.into(), field: field.into(), detail: detail.into() }
    }

    /// Shorthand for [`Error::InvalidParameter`].
    pub fn parameter(
        codec: impl Into<Cow<'static, str>>,
        name: impl Into<Cow<'static, str>>,
        message: impl Into<String>,
    ) -> Self {
        Error::InvalidParameter { codec: codec.into(), name: name.into(), message: message.into() }
    }

    /// Shorthand for [`Error::Io`].
    pub fn io(context: impl Into<String>, source: std::io::Error) -> Self {
        Error::Io { context: context.into(), source }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug)]
    #[allow(dead_code)]
    enum Solver {
        NoConvergence,
        NonPositivePivot { index: usize },
        Frontend(Inner),
    }

    #[derive(Debug)]
    enum Inner {
        InvalidData,
    }

    #[test]
    fn debug_values_become_words() {
        assert_eq!(debug_in_words(&Solver::NoConvergence), "no convergence");
        assert_eq!(debug_in_words(&Solver::NonPositivePivot { index: 42 }), "non positive pivot (index 42)");
        assert_eq!(debug_in_words(&Solver::Frontend(Inner::InvalidData)), "frontend (invalid data)");
    }

    #[test]
    fn io_errors_read_as_words() {
        let e = Error::io("x.pc2", std::io::Error::from(std::io::ErrorKind::PermissionDenied));
        assert_eq!(e.to_string(), "x.pc2: permission denied");
        let e = Error::io("x.pc2", std::io::Error::from(std::io::ErrorKind::NotFound));
        assert_eq!(e.to_string(), "x.pc2: no such file or directory");
        let e = Error::io("x", std::io::Error::other("disk on fire"));
        assert_eq!(e.to_string(), "x: disk on fire");
    }

    #[test]
    fn debug_value_detector_works() {
        assert!(looks_like_debug("field 'descriptors' is malformed: Frontend(InvalidData)"));
        assert!(looks_like_debug("x: Io { kind: NotFound }"));
        assert!(!looks_like_debug("quant-delta (FourCC QDLT) 12 bits (see --help)"));
        assert!(!looks_like_debug("frames (Small) are fine"));
        // What debug_in_words makes of a Debug value no longer looks like one.
        assert!(!looks_like_debug(&debug_in_words(&Some(std::io::ErrorKind::NotFound))));
    }
}
