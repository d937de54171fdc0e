//! The evaluation side of `animcodec`, shared by the command line and the Python package:
//!
//! - [`harness`]: one measured point (encode, decode from the bytes alone, measure), sweeps
//!   over rate ladders and search spaces, the rate-distortion envelope, target-error search and
//!   the default-quality search, sweep rows as JSON/CSV;
//! - [`plot`]: the rate-distortion plot of a sweep as SVG;
//! - [`describe`]: machine-readable descriptions of codecs and `.anim` containers.
//!
//! Nothing here knows which codecs exist: every entry point takes a
//! [`CodecRegistry`](codec_core::CodecRegistry) (the `animcodec` facade crate owns the list).

pub mod describe;
pub mod harness;
pub mod plot;
