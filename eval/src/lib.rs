//! The evaluation side of `animcodec`, shared by the command line and the Python package:
//!
//! - [`harness`]: one measured point (encode, decode from the bytes alone, measure), sweeps
//!   over rate ladders and search spaces, the rate-distortion envelope, target-error search and
//!   the default-quality search, sweep rows and documents (serde types) as JSON and CSV;
//! - [`plot`]: the rate-distortion plot of a sweep as SVG;
//! - [`describe`]: machine-readable descriptions of codecs and `.anim` containers;
//! - [`params`]: codec parameters as JSON, the one conversion every document uses;
//! - [`error`]: [`EvalError`], what all of it fails with.
//!
//! Nothing here knows which codecs exist: every entry point takes a
//! [`CodecRegistry`](codec_core::CodecRegistry) (the `animcodec` facade crate owns the list).
//! The JSON keys every document uses are listed once, in `docs/json.md`.

pub mod describe;
pub mod error;
pub mod harness;
pub mod params;
pub mod plot;

pub use error::EvalError;
