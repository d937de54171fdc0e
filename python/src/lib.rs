//! `animcodec._native`: the Rust side of the `animcodec` Python package.
//!
//! Thin wrappers over the library crates — the `animcodec` facade (`animcodec/`: registry, and
//! the file formats, sweep harness and descriptions it re-exports), `codec-core` and
//! `metrics` — so Python gets exactly
//! what the command line computes. The pure-Python layer (`python/animcodec/`) checks and
//! converts numpy arrays (dtype, shape, contiguity) before calling in here; these functions
//! still check everything they receive. Long calls (encode, decode, evaluate, sweep jobs)
//! release the GIL. Every library error becomes `animcodec.AnimcodecError` carrying the Rust
//! message (with its sources, as the command line prints it).

mod blocks;
mod codec;
mod convert;
mod input;
mod sweep;

use std::error::Error as StdError;

use animcodec::core::CodecRegistry;
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

create_exception!(
    _native,
    AnimcodecError,
    PyException,
    "An error of the animcodec library (bad input, invalid parameters, corrupt stream, I/O); the message is the \
     Rust library's."
);

pub(crate) type BoxError = Box<dyn StdError + Send + Sync>;

/// The error's message followed by each source not already part of it, on one line — the
/// command line's `error:` line without the prefix.
pub(crate) fn message(e: &(dyn StdError + 'static)) -> String {
    animcodec::core::error::message_with_sources(e)
}

pub(crate) fn to_py<E: Into<BoxError>>(e: E) -> PyErr {
    let e: BoxError = e.into();
    AnimcodecError::new_err(message(e.as_ref()))
}

pub(crate) fn registry() -> &'static CodecRegistry {
    static REGISTRY: std::sync::OnceLock<CodecRegistry> = std::sync::OnceLock::new();
    REGISTRY.get_or_init(animcodec::registry)
}

/// The extension module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("AnimcodecError", m.py().get_type::<AnimcodecError>())?;
    m.add("DEFAULT_MAX_MEMORY", animcodec::core::limits::DEFAULT_MAX_MEMORY)?;
    m.add("DEFAULT_MAX_WORK", animcodec::core::limits::DEFAULT_MAX_WORK)?;
    m.add_function(wrap_pyfunction!(codec::codecs, m)?)?;
    m.add_function(wrap_pyfunction!(codec::encode, m)?)?;
    m.add_function(wrap_pyfunction!(codec::encode_to_target, m)?)?;
    m.add_function(wrap_pyfunction!(codec::decode, m)?)?;
    m.add_function(wrap_pyfunction!(codec::decode_frame, m)?)?;
    m.add_function(wrap_pyfunction!(codec::info, m)?)?;
    m.add_function(wrap_pyfunction!(codec::evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(codec::load, m)?)?;
    m.add_function(wrap_pyfunction!(codec::save, m)?)?;
    m.add_function(wrap_pyfunction!(sweep::sweep_plan, m)?)?;
    m.add_function(wrap_pyfunction!(sweep::sweep_point, m)?)?;
    m.add_function(wrap_pyfunction!(sweep::sweep_local, m)?)?;
    m.add_function(wrap_pyfunction!(sweep::check_outputs, m)?)?;
    m.add_function(wrap_pyfunction!(sweep::sweep_document, m)?)?;
    m.add_function(wrap_pyfunction!(blocks::block_plan, m)?)?;
    m.add_function(wrap_pyfunction!(blocks::encode_block, m)?)?;
    m.add_function(wrap_pyfunction!(blocks::encode_block_file, m)?)?;
    m.add_function(wrap_pyfunction!(blocks::cache_header, m)?)?;
    m.add_function(wrap_pyfunction!(blocks::assemble_blocks, m)?)?;
    Ok(())
}
