//! Decoding limits, containers given as bytes or paths (read through the decoder as it needs
//! the bytes, so the limits hold before reading), and inputs loaded as the command line loads
//! them, with the small cache sweep workers reuse.

use std::io::Cursor;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use animcodec::core::{Animation, Limits};
use animcodec::formats::ReadOptions;
use animcodec::front::{self, Streams};
use pyo3::prelude::*;
use pyo3::types::PyBytes;

use crate::{message, registry, to_py, BoxError};

/// The decoding limits of the command line's `--max-memory` and `--max-work` (`None`: their
/// defaults, [`animcodec::core::limits::DEFAULT_MAX_MEMORY`] and `DEFAULT_MAX_WORK`), through
/// the front door ([`front::limits`]: zero refused).
pub(crate) fn limits_from(max_memory: Option<u64>, max_work: Option<u64>) -> PyResult<Limits> {
    front::limits(max_memory, max_work).map_err(to_py)
}

/// A container given as bytes (already in memory) or as a path, which is read through the
/// decoder as it needs the bytes — never read whole first, so the limits hold before reading
/// (a device such as `/dev/zero` is refused at its first bytes, as on the command line).
pub(crate) enum Source<'a> {
    Bytes(&'a [u8]),
    Path(PathBuf),
}

impl<'a> Source<'a> {
    pub(crate) fn from_py(data: &'a Bound<'_, PyAny>) -> PyResult<Self> {
        if let Ok(bytes) = data.cast::<PyBytes>() {
            return Ok(Source::Bytes(bytes.as_bytes()));
        }
        match data.extract::<PathBuf>() {
            Ok(path) => Ok(Source::Path(path)),
            Err(_) => Err(pyo3::exceptions::PyTypeError::new_err(format!(
                "expected .anim bytes or a path; got {}",
                data.get_type().name()?
            ))),
        }
    }

    /// Runs `read` on the bytes or on the opened file (buffered, seekable); errors name the file.
    pub(crate) fn read<T>(
        &self,
        read: impl FnOnce(&mut dyn ReadSeek) -> animcodec::core::Result<T>,
    ) -> Result<T, BoxError> {
        match self {
            Source::Bytes(b) => Ok(read(&mut Cursor::new(*b))?),
            Source::Path(path) => {
                let name = path.display().to_string();
                read(&mut front::open_stream(path)?).map_err(|e| {
                    let text = message(&e);
                    if text.contains(&name) {
                        text.into()
                    } else {
                        format!("{name}: {text}").into()
                    }
                })
            }
        }
    }
}

/// What the container readers need: reading and seeking (bytes in memory or a file).
pub(crate) trait ReadSeek: std::io::Read + std::io::Seek {}
impl<T: std::io::Read + std::io::Seek> ReadSeek for T {}

// ---------------------------------------------------------------------------------------------
// inputs

/// Loads an input as the command line does, through the front door
/// ([`front::resolve_input`]): `synth:NAME[:SIZE]` (or `synth:flag:COLSxROWSxFRAMES`), an
/// `.anim` stream (decoded within `limits`), or any animation file the formats module reads.
pub(crate) fn load_input(
    input: &str,
    topology: Option<PathBuf>,
    fps: Option<f32>,
    animation: Option<String>,
    limits: Limits,
) -> Result<Animation, BoxError> {
    let read = ReadOptions { topology, frame_rate: fps, animation, object: None };
    Ok(front::resolve_input(registry(), input, &read, limits, Streams::Decode)?.animation)
}

/// Sweep jobs on one worker reload the same few inputs over and over: the last ones loaded
/// stay in memory (keyed by input, topology, frame rate and glTF animation).
type CacheKey = (String, Option<PathBuf>, Option<u32>, Option<String>);
static INPUT_CACHE: Mutex<Vec<(CacheKey, Arc<Animation>)>> = Mutex::new(Vec::new());
const INPUT_CACHE_ENTRIES: usize = 2;

pub(crate) fn load_cached(
    input: &str,
    topology: Option<PathBuf>,
    fps: Option<f32>,
    animation: Option<String>,
) -> Result<Arc<Animation>, BoxError> {
    let key = (input.to_string(), topology.clone(), fps.map(f32::to_bits), animation.clone());
    if let Some((_, a)) = INPUT_CACHE.lock().map_err(|_| "input cache poisoned")?.iter().find(|(k, _)| *k == key) {
        return Ok(Arc::clone(a));
    }
    let animation = Arc::new(load_input(input, topology, fps, animation, Limits::default())?);
    let mut cache = INPUT_CACHE.lock().map_err(|_| "input cache poisoned")?;
    cache.retain(|(k, _)| *k != key);
    cache.insert(0, (key, Arc::clone(&animation)));
    cache.truncate(INPUT_CACHE_ENTRIES);
    Ok(animation)
}
