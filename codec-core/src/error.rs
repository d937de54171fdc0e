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
    #[error("{context}: {source}")]
    Io {
        /// Path or description of the stream.
        context: String,
        /// Underlying error.
        #[source]
        source: std::io::Error,
    },
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
