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

use std::error::Error as StdError;
use std::io::Cursor;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use animcodec::core::{Animation, AnimationCodec, CodecRegistry, Limits, ParamSet, StreamDecoder, Topology};
use animcodec::describe;
use animcodec::formats::{self, ReadOptions, WriteOptions};
use animcodec::front::{self, MetricOptions, ParamInput, Streams};
use animcodec::harness::{
    self, FailureRow, SearchRequest, Sweep, SweepDocument, SweepOptions, SweepRow, SweepSeries, Target,
};
use animcodec::metrics::EvalOptions;
use animcodec::output::OutputPolicy;
use animcodec::params::params_json;
use numpy::{PyArray1, PyArray2, PyArray3, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyBytes, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use pyo3::IntoPyObjectExt;
use serde_json::{Map, Number, Value};

create_exception!(
    _native,
    AnimcodecError,
    PyException,
    "An error of the animcodec library (bad input, invalid parameters, corrupt stream, I/O); the message is the \
     Rust library's."
);

type BoxError = Box<dyn StdError + Send + Sync>;

/// The error's message followed by each source not already part of it, on one line — the
/// command line's `error:` line without the prefix.
fn message(e: &(dyn StdError + 'static)) -> String {
    animcodec::core::error::message_with_sources(e)
}

fn to_py<E: Into<BoxError>>(e: E) -> PyErr {
    let e: BoxError = e.into();
    AnimcodecError::new_err(message(e.as_ref()))
}

fn registry() -> &'static CodecRegistry {
    static REGISTRY: std::sync::OnceLock<CodecRegistry> = std::sync::OnceLock::new();
    REGISTRY.get_or_init(animcodec::registry)
}

// ---------------------------------------------------------------------------------------------
// numpy ↔ Animation

/// An animation from `positions[F, V, 3]` (float32) and `faces[T, 3]` (uint32), any memory
/// layout. The positions are copied once: [`Animation`] owns its coordinates.
fn animation_from(
    positions: &PyReadonlyArray3<'_, f32>,
    faces: &PyReadonlyArray2<'_, u32>,
    fps: f32,
) -> PyResult<Animation> {
    let shape = positions.shape();
    if shape[2] != 3 {
        return Err(to_py(format!("positions must have shape (frames, vertices, 3); got {shape:?}")));
    }
    let fshape = faces.shape();
    if fshape[1] != 3 {
        return Err(to_py(format!("faces must have shape (triangles, 3); got {fshape:?}")));
    }
    // The fast path copies the contiguous buffer; any other layout (Fortran order, strides,
    // unaligned buffers as Dask's deserialization can give) is copied element by element in
    // logical (frame, vertex, axis) order. `as_slice` alone would also accept Fortran order.
    if !positions.is_aligned() || !faces.is_aligned() {
        // ndarray cannot read unaligned memory; the Python layer copies such arrays first.
        return Err(to_py("positions and faces must be aligned arrays (np.require(a, requirements='A'))"));
    }
    let coords: Vec<f32> = match positions.as_slice() {
        Ok(slice) if positions.is_c_contiguous() => slice.to_vec(),
        _ => positions.as_array().iter().copied().collect(),
    };
    let tris: Vec<u32> = match faces.as_slice() {
        Ok(slice) if faces.is_c_contiguous() => slice.to_vec(),
        _ => faces.as_array().iter().copied().collect(),
    };
    let triangles: Vec<[u32; 3]> = tris.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    let topology = Topology::new(shape[1], triangles).map_err(to_py)?;
    Animation::new(topology, coords, fps).map_err(to_py)
}

/// `(positions[F, V, 3] float32, faces[T, 3] uint32, fps)`, moving the coordinates into numpy
/// without a copy.
fn animation_to_py<'py>(py: Python<'py>, animation: Animation) -> PyResult<Bound<'py, PyTuple>> {
    let (f, v) = (animation.frame_count(), animation.vertex_count());
    let (topology, positions, fps) = animation.into_parts();
    let positions: Bound<'py, PyArray3<f32>> = PyArray1::from_vec(py, positions).reshape([f, v, 3])?;
    let faces: Vec<u32> = topology.triangles().iter().flatten().copied().collect();
    let t = topology.triangle_count();
    let faces: Bound<'py, PyArray2<u32>> = PyArray1::from_vec(py, faces).reshape([t, 3])?;
    PyTuple::new(py, [positions.into_any(), faces.into_any(), PyFloat::new(py, f64::from(fps)).into_any()])
}

// ---------------------------------------------------------------------------------------------
// JSON ↔ Python (numbers convert exactly: f64 ↔ float, integers ↔ int)

fn value_to_py(py: Python<'_>, value: &Value) -> PyResult<Py<PyAny>> {
    Ok(match value {
        Value::Null => py.None(),
        Value::Bool(b) => b.into_py_any(py)?,
        Value::Number(n) => {
            if let Some(i) = n.as_i64() {
                i.into_py_any(py)?
            } else if let Some(u) = n.as_u64() {
                u.into_py_any(py)?
            } else {
                n.as_f64().unwrap_or(f64::NAN).into_py_any(py)?
            }
        }
        Value::String(s) => s.into_py_any(py)?,
        Value::Array(items) => {
            let list = PyList::empty(py);
            for item in items {
                list.append(value_to_py(py, item)?)?;
            }
            list.into_any().unbind()
        }
        Value::Object(map) => {
            let dict = PyDict::new(py);
            for (k, v) in map {
                dict.set_item(k, value_to_py(py, v)?)?;
            }
            dict.into_any().unbind()
        }
    })
}

fn py_to_value(obj: &Bound<'_, PyAny>) -> PyResult<Value> {
    if obj.is_none() {
        Ok(Value::Null)
    } else if obj.is_instance_of::<PyBool>() {
        Ok(Value::Bool(obj.extract()?))
    } else if obj.is_instance_of::<PyInt>() {
        match obj.extract::<i64>() {
            Ok(i) => Ok(Value::from(i)),
            Err(_) => Ok(Value::from(obj.extract::<u64>()?)),
        }
    } else if obj.is_instance_of::<PyFloat>() {
        let x: f64 = obj.extract()?;
        Ok(Number::from_f64(x).map_or(Value::Null, Value::Number))
    } else if obj.is_instance_of::<PyString>() {
        Ok(Value::String(obj.extract()?))
    } else if let Ok(dict) = obj.cast::<PyDict>() {
        let mut map = Map::new();
        for (k, v) in dict.iter() {
            map.insert(k.extract::<String>()?, py_to_value(&v)?);
        }
        Ok(Value::Object(map))
    } else if let Ok(list) = obj.cast::<PyList>() {
        list.iter().map(|v| py_to_value(&v)).collect::<PyResult<Vec<_>>>().map(Value::Array)
    } else if let Ok(tuple) = obj.cast::<PyTuple>() {
        tuple.iter().map(|v| py_to_value(&v)).collect::<PyResult<Vec<_>>>().map(Value::Array)
    } else {
        Err(to_py(format!("cannot convert {} to JSON", obj.get_type().name()?)))
    }
}

// ---------------------------------------------------------------------------------------------
// parameters and options

/// `codec`'s parameters from a dict through the front door ([`front::params`]): each value
/// converted to a [`ParamInput`] by its Python type (the only step of its own), then typed by
/// the parameter's kind and validated as `-p key=value` is. Errors name the codec and the
/// parameter, with the allowed range.
fn params_from(codec: &dyn AnimationCodec, params: Option<&Bound<'_, PyDict>>) -> PyResult<ParamSet> {
    let mut entries: Vec<(String, ParamInput)> = Vec::new();
    for (key, value) in params.into_iter().flat_map(|d| d.iter()) {
        entries.push((key.extract()?, param_input(&value)));
    }
    front::params(codec, entries.iter().map(|(k, v)| (k.as_str(), v.clone()))).map_err(to_py)
}

/// A Python value as a parameter value: `bool`, `int`, `str` as themselves, anything else that
/// converts to a float (numpy scalars included) as a number, the rest as its `repr`.
fn param_input(value: &Bound<'_, PyAny>) -> ParamInput {
    let shown = || value.repr().map(|r| r.to_string()).unwrap_or_else(|_| "?".into());
    if value.is_instance_of::<PyBool>() {
        value.extract().map_or_else(|_| ParamInput::Other(shown()), ParamInput::Bool)
    } else if value.is_instance_of::<PyInt>() {
        value.extract().map_or_else(|_| ParamInput::Other(shown()), ParamInput::Int)
    } else if value.is_instance_of::<PyString>() {
        value.extract().map_or_else(|_| ParamInput::Other(shown()), ParamInput::Str)
    } else {
        value.extract::<f64>().map_or_else(|_| ParamInput::Other(shown()), ParamInput::Float)
    }
}

fn dict_get<'py, T: FromPyObjectOwned<'py>>(d: Option<&Bound<'py, PyDict>>, key: &str) -> PyResult<Option<T>> {
    match d.map(|d| d.get_item(key)).transpose()?.flatten() {
        Some(v) if !v.is_none() => Ok(Some(v.extract::<T>().map_err(|e| {
            let e: PyErr = e.into();
            to_py(format!("eval option '{key}': {e}"))
        })?)),
        _ => Ok(None),
    }
}

/// Metric options from a dict with the command line's `eval`/`sweep` flags: `sted` and
/// `hausdorff` (compute them; default true), `sted_radius`, `sted_dt`, `sted_window`, `sted_c`,
/// `sted_absolute`; checked by the front door ([`MetricOptions::eval_options`]). Unknown keys
/// are refused.
fn eval_options(options: Option<&Bound<'_, PyDict>>) -> PyResult<EvalOptions> {
    const KEYS: [&str; 7] = ["sted", "hausdorff", "sted_radius", "sted_dt", "sted_window", "sted_c", "sted_absolute"];
    if let Some(d) = options {
        for k in d.keys() {
            let k: String = k.extract()?;
            if !KEYS.contains(&k.as_str()) {
                return Err(to_py(format!("unknown eval option '{k}' (options: {})", KEYS.join(", "))));
            }
        }
    }
    let metric = MetricOptions {
        sted_radius: dict_get(options, "sted_radius")?,
        sted_dt: dict_get(options, "sted_dt")?,
        sted_window: dict_get(options, "sted_window")?,
        sted_c: dict_get(options, "sted_c")?,
        sted_absolute: dict_get(options, "sted_absolute")?.unwrap_or(false),
        skip_sted: !dict_get(options, "sted")?.unwrap_or(true),
        skip_hausdorff: !dict_get(options, "hausdorff")?.unwrap_or(true),
    };
    metric.eval_options().map_err(to_py)
}

// ---------------------------------------------------------------------------------------------
// limits and streams: a path is read through the decoder as it needs the bytes, so the limits
// hold before reading (`decode('/dev/zero')` is refused at its first bytes)

/// The decoding limits of the command line's `--max-memory` and `--max-work` (`None`: their
/// defaults, [`animcodec::core::limits::DEFAULT_MAX_MEMORY`] and `DEFAULT_MAX_WORK`), through
/// the front door ([`front::limits`]: zero refused).
fn limits_from(max_memory: Option<u64>, max_work: Option<u64>) -> PyResult<Limits> {
    front::limits(max_memory, max_work).map_err(to_py)
}

/// A container given as bytes (already in memory) or as a path, which is read through the
/// decoder as it needs the bytes — never read whole first, so the limits hold before reading
/// (a device such as `/dev/zero` is refused at its first bytes, as on the command line).
enum Source<'a> {
    Bytes(&'a [u8]),
    Path(PathBuf),
}

impl<'a> Source<'a> {
    fn from_py(data: &'a Bound<'_, PyAny>) -> PyResult<Self> {
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
    fn read<T>(&self, read: impl FnOnce(&mut dyn ReadSeek) -> animcodec::core::Result<T>) -> Result<T, BoxError> {
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
trait ReadSeek: std::io::Read + std::io::Seek {}
impl<T: std::io::Read + std::io::Seek> ReadSeek for T {}

// ---------------------------------------------------------------------------------------------
// inputs

/// Loads an input as the command line does, through the front door
/// ([`front::resolve_input`]): `synth:NAME[:SIZE]` (or `synth:flag:COLSxROWSxFRAMES`), an
/// `.anim` stream (decoded within `limits`), or any animation file the formats module reads.
fn load_input(
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

fn load_cached(
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

// ---------------------------------------------------------------------------------------------
// the functions

/// Every registered codec: name, FourCC, stream version, summary, parameters (kind, default,
/// range or choices, doc) and rate ladder — `animcodec list --json`.
#[pyfunction]
fn codecs(py: Python<'_>) -> PyResult<Py<PyAny>> {
    let list: Vec<Value> = registry().iter().map(describe::codec_json).collect();
    value_to_py(py, &Value::Array(list))
}

/// Encodes an animation into `.anim` container bytes. With parameters: exactly those (the
/// rest at their defaults). Without: a stream meeting the default quality
/// ([`harness::DEFAULT_TARGET`], [`harness::search_default_quality`]; `"auto"`: the smallest
/// over every codec's search space), as `animcodec encode` without `-p` finds it; `progress` is then called with every point
/// measured.
#[pyfunction]
#[pyo3(signature = (positions, faces, codec, fps, params=None, progress=None))]
fn encode<'py>(
    py: Python<'py>,
    positions: PyReadonlyArray3<'py, f32>,
    faces: PyReadonlyArray2<'py, u32>,
    codec: &str,
    fps: f32,
    params: Option<&Bound<'py, PyDict>>,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyBytes>> {
    let registry = registry();
    let animation = animation_from(&positions, &faces, fps)?;
    if params.is_none_or(|p| p.is_empty()) {
        let callback = Callback::new(progress);
        let report = progress_reporter(&callback, harness::DEFAULT_TARGET);
        let request = SearchRequest {
            refine: DEFAULT_REFINE,
            progress: &report,
            ..SearchRequest::default_quality(registry, &animation)
        };
        let hit = callback.run(py, || -> Result<_, BoxError> {
            if codec == "auto" {
                let all: Vec<&dyn AnimationCodec> = registry.iter().collect();
                Ok(harness::search_space_target_auto(&request, &all).map(|(h, _)| h)?)
            } else {
                let c = registry.by_name(codec)?;
                Ok(harness::search_default_quality(&request, c)?)
            }
        })?;
        return Ok(PyBytes::new(py, &hit.stream));
    }
    let codec = registry.by_name(codec).map_err(to_py)?;
    let params = params_from(codec, params)?;
    let bytes = py.detach(|| animcodec::core::encode_animation(codec, &params, &animation)).map_err(to_py)?;
    Ok(PyBytes::new(py, &bytes))
}

/// Bisection steps of the ladder parameter after a search, as `animcodec encode` (its
/// `--refine` default).
const DEFAULT_REFINE: usize = 4;

/// A Python `progress` callable, called from the library's worker threads (each call takes
/// the GIL). The first exception it raises stops the work: the call unwinds out of the library
/// (a [`CallbackRaised`] payload, which no panic hook prints; every later call unwinds at once),
/// and [`Callback::run`] raises that exception in the caller (instead of Python printing it as
/// "unraisable" while the work goes on).
struct Callback {
    callable: Option<Py<PyAny>>,
    raised: Mutex<Option<PyErr>>,
}

/// The unwinding payload of a callback that raised.
struct CallbackRaised;

impl Callback {
    fn new(callable: Option<Py<PyAny>>) -> Self {
        Self { callable, raised: Mutex::new(None) }
    }

    fn raised(&self) -> std::sync::MutexGuard<'_, Option<PyErr>> {
        self.raised.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Calls the callable with `row` as a dict; after an exception, unwinds instead.
    fn call(&self, row: &Value) {
        let Some(callable) = &self.callable else { return };
        if self.raised().is_some() {
            std::panic::resume_unwind(Box::new(CallbackRaised));
        }
        let result = Python::attach(|py| value_to_py(py, row).and_then(|arg| callable.call1(py, (arg,)).map(drop)));
        if let Err(e) = result {
            let mut raised = self.raised();
            if raised.is_none() {
                *raised = Some(e); // the first exception is the one raised
            }
            drop(raised);
            std::panic::resume_unwind(Box::new(CallbackRaised));
        }
    }

    /// Runs `work` with the GIL released; the callback's exception, if it raised, is raised
    /// here instead of the work's result.
    fn run<T: Send>(&self, py: Python<'_>, work: impl FnOnce() -> Result<T, BoxError> + Send) -> PyResult<T> {
        let outcome = py.detach(|| std::panic::catch_unwind(std::panic::AssertUnwindSafe(work)));
        if let Some(e) = self.raised().take() {
            return Err(e);
        }
        match outcome {
            Ok(result) => result.map_err(to_py),
            Err(payload) => std::panic::resume_unwind(payload),
        }
    }
}

/// A search's progress as Python calls: `callback({codec, params, bytes, bpvf, METRIC…})` (each
/// bounded metric's value) for every measured point (see [`Callback`]: an exception stops the search and is raised).
fn progress_reporter(callback: &Callback, target: Target) -> impl Fn(&harness::Point) + Sync + '_ {
    move |p: &harness::Point| {
        let mut point = serde_json::json!({
            "codec": p.codec,
            "params": params_json(&p.params),
            "bytes": p.bytes,
            "bpvf": p.bpvf,
        });
        if let (Value::Object(point), Value::Object(reached)) = (&mut point, front::reached_json(target, &p.report)) {
            point.extend(reached);
        }
        callback.call(&point);
    }
}

/// What `encode_to_target` searches for, as a dict of every key: `target` (`"kg=0.5"`,
/// `"kg=0.5,sted=0.05"`, …),
/// `refine` (extra points between ladder steps), `params` (fixed parameters, or `None`),
/// `ladder` (the rate ladder alone instead of the declared search space), `progress` (a
/// callable or `None`).
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct TargetSearch<'py> {
    target: String,
    refine: usize,
    params: Option<Bound<'py, PyDict>>,
    ladder: bool,
    progress: Option<Py<PyAny>>,
}

/// The smallest stream meeting `search.target` of one codec (on its search space or rate
/// ladder, the other parameters from `search.params`) or of every codec (`codec="auto"`), as
/// `animcodec encode --target` finds it. Returns `(bytes, summary dict)`.
#[pyfunction]
fn encode_to_target<'py>(
    py: Python<'py>,
    positions: PyReadonlyArray3<'py, f32>,
    faces: PyReadonlyArray2<'py, u32>,
    codec: &str,
    fps: f32,
    search: TargetSearch<'py>,
) -> PyResult<(Bound<'py, PyBytes>, Py<PyAny>)> {
    let TargetSearch { target, refine, params, ladder, progress } = search;
    let params = params.as_ref();
    let target: Target = target.parse().map_err(to_py)?;
    let registry = registry();
    let chosen = if codec == "auto" {
        if params.is_some_and(|p| !p.is_empty()) {
            return Err(to_py("parameters cannot be combined with codec='auto': parameters belong to one codec"));
        }
        None
    } else {
        let c = registry.by_name(codec).map_err(to_py)?;
        let base = params_from(c, params)?;
        let walked = c.rate_ladder(&base).param;
        if params.is_some_and(|p| p.contains(walked).unwrap_or(false)) {
            return Err(to_py(format!(
                "{}: '{walked}' is the rate ladder's parameter, which the target {target} chooses; leave it out",
                c.name()
            )));
        }
        Some((c, base))
    };
    let animation = animation_from(&positions, &faces, fps)?;
    let fixed: Vec<String> = match params {
        Some(p) => p.keys().iter().map(|k| k.extract::<String>()).collect::<PyResult<_>>()?,
        None => Vec::new(),
    };
    let callback = Callback::new(progress);
    let report = progress_reporter(&callback, target);
    let request = SearchRequest { refine, progress: &report, ..SearchRequest::new(registry, &animation, target) };
    let (hit, others) = callback.run(py, || -> Result<_, BoxError> {
        let fixed: Vec<&str> = fixed.iter().map(String::as_str).collect();
        let all: Vec<&dyn AnimationCodec> = registry.iter().collect();
        Ok(match (chosen, ladder) {
            (Some((c, base)), true) => harness::search_target(&request, c, &base).map(|h| (h, Vec::new())),
            (Some((c, base)), false) => {
                harness::search_space_target(&request, c, &base, &fixed).map(|h| (h, Vec::new()))
            }
            (None, true) => harness::search_target_auto(&request, &all),
            (None, false) => harness::search_space_target_auto(&request, &all),
        }?)
    })?;
    // The command line's `encode --target --json` summary, the same serde type.
    let summary = serde_json::to_value(front::TargetSummary::new(target, &hit, &others)).map_err(to_py)?;
    Ok((PyBytes::new(py, &hit.stream), value_to_py(py, &summary)?))
}

/// Decodes a container (bytes, or a path read as the decoder goes) within the limits
/// (`max_memory` bytes held, `max_work` operations; `None`: the command line's defaults):
/// `(positions[F, V, 3] float32, faces[T, 3] uint32, fps, codec)`.
#[pyfunction]
#[pyo3(signature = (data, max_memory=None, max_work=None))]
fn decode<'py>(
    py: Python<'py>,
    data: &Bound<'py, PyAny>,
    max_memory: Option<u64>,
    max_work: Option<u64>,
) -> PyResult<(Bound<'py, PyTuple>, &'static str)> {
    let limits = limits_from(max_memory, max_work)?;
    let source = Source::from_py(data)?;
    let (animation, codec) = py
        .detach(|| {
            source.read(|src| {
                let decoder = StreamDecoder::new(src, registry(), limits)?;
                let codec = decoder.codec_name();
                Ok((decoder.decode_all()?, codec))
            })
        })
        .map_err(to_py)?;
    Ok((animation_to_py(py, animation)?, codec))
}

/// Decodes frame `t` alone (through the index, from the nearest keyframe), within the limits
/// as [`decode`]: `positions[V, 3]`.
#[pyfunction]
#[pyo3(signature = (data, t, max_memory=None, max_work=None))]
fn decode_frame<'py>(
    py: Python<'py>,
    data: &Bound<'py, PyAny>,
    t: usize,
    max_memory: Option<u64>,
    max_work: Option<u64>,
) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let limits = limits_from(max_memory, max_work)?;
    let source = Source::from_py(data)?;
    let frame = py
        .detach(|| source.read(|mut src| animcodec::core::decode_frame(&mut src, registry(), limits, t)))
        .map_err(to_py)?;
    let v = frame.len() / 3;
    PyArray1::from_vec(py, frame).reshape([v, 3])
}

/// What a container holds, every checksum verified — `animcodec info --json` — within the
/// limits as [`decode`].
#[pyfunction]
#[pyo3(signature = (data, max_memory=None, max_work=None))]
fn info<'py>(
    py: Python<'py>,
    data: &Bound<'py, PyAny>,
    max_memory: Option<u64>,
    max_work: Option<u64>,
) -> PyResult<Py<PyAny>> {
    let limits = limits_from(max_memory, max_work)?;
    let source = Source::from_py(data)?;
    let (header, index) = source.read(|mut src| describe::read_verified(&mut src, limits)).map_err(to_py)?;
    value_to_py(py, &describe::info_json(registry(), &header, &index))
}

/// Every metric of `candidate` against `reference` (same faces, same frame rate) — the keys of
/// `animcodec eval --json` except the file names, plus `eval_seconds`.
#[pyfunction]
#[pyo3(signature = (reference, candidate, faces, fps, options=None))]
fn evaluate<'py>(
    py: Python<'py>,
    reference: PyReadonlyArray3<'py, f32>,
    candidate: PyReadonlyArray3<'py, f32>,
    faces: PyReadonlyArray2<'py, u32>,
    fps: f32,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Py<PyAny>> {
    let options = eval_options(options)?;
    if reference.shape() != candidate.shape() {
        return Err(to_py(format!(
            "reference and candidate differ in shape: {:?} vs {:?} (frames, vertices, 3)",
            reference.shape(),
            candidate.shape()
        )));
    }
    let reference = animation_from(&reference, &faces, fps)?;
    let candidate = animation_from(&candidate, &faces, fps)?;
    let (report, seconds) = py
        .detach(|| {
            let start = Instant::now();
            animcodec::metrics::evaluate(&reference, &candidate, &options).map(|r| (r, start.elapsed().as_secs_f64()))
        })
        .map_err(to_py)?;
    let mut value = harness::report_json(&report);
    value["eval_seconds"] = seconds.into();
    value_to_py(py, &value)
}

/// Reads an animation file (or `synth:NAME[:SIZE]`, or an `.anim` stream, decoded within the
/// limits as [`decode`]): `(positions, faces, fps)`.
#[pyfunction]
#[pyo3(signature = (path, topology=None, fps=None, animation=None, max_memory=None, max_work=None))]
fn load<'py>(
    py: Python<'py>,
    path: &str,
    topology: Option<PathBuf>,
    fps: Option<f32>,
    animation: Option<String>,
    max_memory: Option<u64>,
    max_work: Option<u64>,
) -> PyResult<Bound<'py, PyTuple>> {
    let limits = limits_from(max_memory, max_work)?;
    let animation = py.detach(|| load_input(path, topology, fps, animation, limits)).map_err(to_py)?;
    animation_to_py(py, animation)
}

/// Writes an animation (format from the extension, as `animcodec decode -o` does); refuses
/// to replace an existing file unless `force`. Returns the files written.
#[pyfunction]
#[pyo3(signature = (path, positions, faces, fps, force=false, topology_obj=true))]
fn save<'py>(
    py: Python<'py>,
    path: PathBuf,
    positions: PyReadonlyArray3<'py, f32>,
    faces: PyReadonlyArray2<'py, u32>,
    fps: f32,
    force: bool,
    topology_obj: bool,
) -> PyResult<Vec<PathBuf>> {
    let animation = animation_from(&positions, &faces, fps)?;
    let options = WriteOptions { policy: OutputPolicy::new(force), topology_obj };
    if !formats::obj::is_directory_target(&path) {
        options.policy.check(&path).map_err(to_py)?;
    }
    py.detach(|| formats::write_animation_with(&path, &animation, &options)).map_err(to_py)
}

/// The series of a sweep: `[(codec, params dict or None), …]` → each codec on those
/// parameters, labelled as the command line labels it; setting the walked parameter is refused.
fn series_from<'r>(registry: &'r CodecRegistry, series: &Bound<'_, PyList>) -> PyResult<Vec<SweepSeries<'r>>> {
    let mut out: Vec<SweepSeries<'r>> = Vec::new();
    for item in series.iter() {
        let (name, params): (String, Option<Bound<'_, PyDict>>) = item.extract()?;
        let codec = registry.by_name(name.trim()).map_err(to_py)?;
        let base = params_from(codec, params.as_ref())?;
        let walked = codec.rate_ladder(&base).param;
        if params.as_ref().is_some_and(|p| p.contains(walked).unwrap_or(false)) {
            return Err(to_py(format!("{}: '{walked}' is the parameter the sweep walks; leave it out", codec.name())));
        }
        let entry = SweepSeries::with_base(codec, base).map_err(to_py)?;
        if out.iter().any(|s| s.label == entry.label) {
            return Err(to_py(format!("series '{}' is given twice", entry.label)));
        }
        out.push(entry);
    }
    Ok(out)
}

/// The jobs of a sweep, per series: `[{codec, series, params, ladder_param, steps: [ladder
/// index, …]}, …]` — the ladder steps `animcodec sweep --points N` measures.
#[pyfunction]
#[pyo3(signature = (series, points=None))]
fn sweep_plan(py: Python<'_>, series: &Bound<'_, PyList>, points: Option<usize>) -> PyResult<Py<PyAny>> {
    let registry = registry();
    let series = series_from(registry, series)?;
    let plan: Vec<Value> = series
        .iter()
        .map(|s| {
            let ladder = s.codec.rate_ladder(&s.base);
            serde_json::json!({
                "codec": s.codec.name(),
                "series": s.label,
                "params": params_json(&s.base),
                "ladder_param": ladder.param,
                "steps": harness::ladder_indices(ladder.steps.len(), points),
            })
        })
        .collect();
    value_to_py(py, &Value::Array(plan))
}

/// One sweep job, as a dict of every key: series `(codec, params)` at ladder step `step` on
/// `input` (a path or `synth:NAME[:SIZE]`, read with `topology` and `fps`, loaded once per
/// worker process and kept; `animation` picks a glTF file's animation by name or index, or
/// `None`: the first) or on the animation `arrays = (positions, faces, fps)` (or `None`); `eval`
/// the metric options (or `None`).
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct SweepJob<'py> {
    input: String,
    codec: String,
    params: Option<Bound<'py, PyDict>>,
    step: usize,
    eval: Option<Bound<'py, PyDict>>,
    topology: Option<PathBuf>,
    fps: Option<f32>,
    animation: Option<String>,
    arrays: Option<AnimationArrays<'py>>,
}

/// An animation handed over as arrays: `(positions[F, V, 3] float32, faces[T, 3] uint32, fps)`.
type AnimationArrays<'py> = (PyReadonlyArray3<'py, f32>, PyReadonlyArray2<'py, u32>, f32);

/// Runs one sweep job. Returns `{"row": …, "vertices", "frames"}`; the row is what
/// `animcodec sweep --json` writes for that point (the same harness function measures it).
#[pyfunction]
fn sweep_point<'py>(py: Python<'py>, job: SweepJob<'py>) -> PyResult<Py<PyAny>> {
    let SweepJob { input, codec, params, step, eval, topology, fps, animation: gltf_animation, arrays } = job;
    let registry = registry();
    let list = PyList::new(py, [(codec, params)])?;
    let series = series_from(registry, &list)?;
    let options =
        SweepOptions { points: None, jobs: Some(1), eval: eval_options(eval.as_ref())?, ..SweepOptions::default() };
    let animation = match arrays {
        Some((positions, faces, fps)) => Arc::new(animation_from(&positions, &faces, fps)?),
        None => py.detach(|| load_cached(&input, topology, fps, gltf_animation)).map_err(to_py)?,
    };
    let point = py.detach(|| harness::sweep_point(registry, &series[0], step, &animation, &options)).map_err(to_py)?;
    let value = serde_json::json!({
        "row": SweepRow::from(&point).to_json(),
        "vertices": animation.vertex_count(),
        "frames": animation.frame_count(),
    });
    value_to_py(py, &value)
}

/// A single-process sweep of one input, as a dict of every key: `input` (read with `topology`,
/// `fps` and the glTF `animation`; or, when `arrays` is given, the name of that animation),
/// `series` (`[(codec, params or None), …]`), `points` per series (or `None`: every step),
/// `eval` (or `None`), `jobs` (`1`: one point after the other; `None`: rayon's pool).
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct LocalSweep<'py> {
    input: String,
    arrays: Option<AnimationArrays<'py>>,
    animation: Option<String>,
    series: Bound<'py, PyList>,
    points: Option<usize>,
    eval: Option<Bound<'py, PyDict>>,
    jobs: Option<usize>,
    topology: Option<PathBuf>,
    fps: Option<f32>,
    progress: Option<Py<PyAny>>,
}

/// The command line's single-process sweep of one input (`animcodec sweep INPUT --json`, the
/// same harness call): the sweep document as a dict.
#[pyfunction]
fn sweep_local<'py>(py: Python<'py>, sweep: LocalSweep<'py>) -> PyResult<Py<PyAny>> {
    let LocalSweep { input, arrays, animation: gltf_animation, series, points, eval, jobs, topology, fps, progress } =
        sweep;
    let registry = registry();
    let series = series_from(registry, &series)?;
    let options = SweepOptions { points, jobs, eval: eval_options(eval.as_ref())?, ..SweepOptions::default() };
    let total = harness::sweep_jobs(&series, options.points).len();
    let done = std::sync::atomic::AtomicUsize::new(0);
    // Called from the sweep's worker threads (the GIL released around the sweep), each taking
    // the GIL for the call; a callback that raises stops the sweep and is raised ([`Callback`]).
    let callback = Callback::new(progress);
    let report = |event: harness::SweepEvent<'_>| {
        if callback.callable.is_none() {
            return;
        }
        let (kind, series, step) = match event {
            harness::SweepEvent::Started { series, step } => ("started", series, step),
            harness::SweepEvent::Finished { series, step } => {
                done.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                ("finished", series, step)
            }
            harness::SweepEvent::Planned(_) => return,
        };
        callback.call(&serde_json::json!({
            "event": kind,
            "series": series,
            "ladder_index": step,
            "done": done.load(std::sync::atomic::Ordering::Relaxed),
            "total": total,
        }));
    };
    let given = arrays.map(|(positions, faces, fps)| animation_from(&positions, &faces, fps)).transpose()?;
    let (animation, result, seconds) = callback.run(py, || -> Result<_, BoxError> {
        let animation = match given {
            Some(a) => a,
            None => load_input(&input, topology, fps, gltf_animation, Limits::default())?,
        };
        let start = Instant::now();
        let result = harness::sweep(registry, &series, &animation, &options, &report)?;
        Ok((animation, result, start.elapsed().as_secs_f64()))
    })?;
    let document = SweepDocument {
        total_seconds: Some(seconds),
        jobs: Some(jobs.map_or_else(|| "rayon".into(), |j| j.into())),
        ..SweepDocument::new(&input, (animation.vertex_count(), animation.frame_count()), &options.eval, &result)
    };
    value_to_py(py, &document.to_json().map_err(to_py)?)
}

/// Refuses outputs that exist (unless `force`) or are an input, before a long sweep — the
/// command line's checks.
#[pyfunction]
#[pyo3(signature = (outputs, inputs, force=false))]
fn check_outputs(outputs: Vec<PathBuf>, inputs: Vec<PathBuf>, force: bool) -> PyResult<()> {
    let mut policy = OutputPolicy::new(force);
    for input in &inputs {
        policy = policy.with_input(input);
    }
    for path in &outputs {
        policy.check(path).map_err(to_py)?;
    }
    Ok(())
}

/// Gathered rows of one input and where to write them, as a dict of every key: `input`, its
/// `vertices` and `frames`, `rows` (as `sweep_point` returned them), `failures`
/// (`{codec, series, ladder_index, error}`), `eval` (or `None`), `total_seconds` and `jobs` (or
/// `None`: left out of the document), and the files `json`, `csv`, `plot` (or `None`).
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct GatheredSweep<'py> {
    input: String,
    vertices: usize,
    frames: usize,
    rows: Bound<'py, PyList>,
    failures: Bound<'py, PyList>,
    eval: Option<Bound<'py, PyDict>>,
    total_seconds: Option<f64>,
    jobs: Option<Bound<'py, PyAny>>,
    json: Option<PathBuf>,
    csv: Option<PathBuf>,
    plot: Option<PathBuf>,
}

/// Assembles gathered rows of one input into the command line's sweep document (rows read back
/// through the same serde types, failures, monotonicity, envelopes) and writes the requested
/// files with the command line's writers (`--json`, `--csv`, `--plot`). Returns the document.
#[pyfunction]
fn sweep_document<'py>(py: Python<'py>, gathered: GatheredSweep<'py>) -> PyResult<Py<PyAny>> {
    let GatheredSweep { input, vertices, frames, rows, failures, eval, total_seconds, jobs, json, csv, plot } =
        gathered;
    let registry = registry();
    let eval = eval_options(eval.as_ref())?;
    let rows: Vec<Value> = rows.iter().map(|row| py_to_value(&row)).collect::<PyResult<_>>()?;
    let mut sweep = Sweep {
        points: harness::points_from_rows(registry, &rows, &eval, (vertices, frames)).map_err(to_py)?,
        ..Sweep::default()
    };
    for f in failures.iter() {
        let row: FailureRow = serde_json::from_value(py_to_value(&f)?)
            .map_err(|e| to_py(format!("sweep failure {}: {e}", sweep.failures.len())))?;
        sweep.failures.push(row.to_failure(registry).map_err(to_py)?);
    }
    let document = SweepDocument {
        total_seconds,
        jobs: jobs.as_ref().map(py_to_value).transpose()?,
        ..SweepDocument::new(&input, (vertices, frames), &eval, &sweep)
    };
    py.detach(|| -> Result<(), BoxError> {
        if let Some(path) = &json {
            harness::write_text(path, &document.to_json_text()?)?;
        }
        if let Some(path) = &csv {
            harness::write_text(path, &harness::csv_text(&sweep.points)?)?;
        }
        if let Some(path) = &plot {
            let title = format!("{input}: {frames} frames × {vertices} vertices");
            animcodec::plot::write_rd_svg(path, &title, &sweep.points)?;
        }
        Ok(())
    })
    .map_err(to_py)?;
    value_to_py(py, &document.to_json().map_err(to_py)?)
}

// ---------------------------------------------------------------------------------------------
// distributed encode: independent temporal blocks coded on Dask workers
// (`animcodec::core::blocks`), assembled on the client into the local encode's bytes

/// Packets as Python tuples `(first_frame, frame_count, keyframe, data)`.
fn packets_to_py<'py>(py: Python<'py>, packets: Vec<animcodec::core::Packet>) -> PyResult<Bound<'py, PyList>> {
    let items: Vec<Bound<'py, PyTuple>> = packets
        .into_iter()
        .map(|p| (p.first_frame, p.frame_count, p.keyframe, PyBytes::new(py, &p.data)).into_pyobject(py))
        .collect::<PyResult<_>>()?;
    PyList::new(py, items)
}

fn topology_from(faces: &PyReadonlyArray2<'_, u32>, vertices: usize) -> PyResult<Topology> {
    if faces.shape()[1] != 3 {
        return Err(to_py(format!("faces must have shape (triangles, 3); got {:?}", faces.shape())));
    }
    if !faces.is_aligned() {
        return Err(to_py("faces must be an aligned array (np.require(a, requirements='A'))"));
    }
    let tris: Vec<u32> = faces.as_array().iter().copied().collect();
    Topology::new(vertices, tris.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()).map_err(to_py)
}

/// How `codec` at `params` (the rest at their defaults; fitted to `memory` bytes as
/// `animcodec encode --memory` does) splits `frames` frames of `vertices` vertices into
/// independently coded blocks: `{"params", "block", "blocks"}` (`params` complete: give them to
/// `encode_block*` and `assemble_blocks`). Refused for codecs whose packets depend on earlier
/// frames.
#[pyfunction]
#[pyo3(signature = (codec, vertices, frames, params=None, memory=None))]
fn block_plan<'py>(
    py: Python<'py>,
    codec: &str,
    vertices: usize,
    frames: usize,
    params: Option<&Bound<'py, PyDict>>,
    memory: Option<u64>,
) -> PyResult<Py<PyAny>> {
    let codec = registry().by_name(codec).map_err(to_py)?;
    let params = params_from(codec, params)?;
    let (params, plan) =
        animcodec::core::blocks::block_plan(codec, &params, vertices, frames, memory).map_err(to_py)?;
    let out = serde_json::json!({
        "params": params_json(&params),
        "block": plan.block_frames,
        "blocks": plan.blocks,
    });
    value_to_py(py, &out)
}

/// Codes block `index` of an animation of `frames` frames from that block's positions
/// (`[n, V, 3]` float32: exactly the block's frames) and checks it; returns its packets.
#[pyfunction]
#[pyo3(signature = (positions, faces, codec, fps, params, frames, index))]
#[allow(clippy::too_many_arguments)]
fn encode_block<'py>(
    py: Python<'py>,
    positions: PyReadonlyArray3<'py, f32>,
    faces: PyReadonlyArray2<'py, u32>,
    codec: &str,
    fps: f32,
    params: &Bound<'py, PyDict>,
    frames: usize,
    index: usize,
) -> PyResult<Bound<'py, PyList>> {
    let shape = positions.shape();
    if shape[2] != 3 {
        return Err(to_py(format!("positions must have shape (frames, vertices, 3); got {shape:?}")));
    }
    if !positions.is_aligned() {
        return Err(to_py("positions must be an aligned array (np.require(a, requirements='A'))"));
    }
    let topology = topology_from(&faces, shape[1])?;
    let coords: Vec<f32> = match positions.as_slice() {
        Ok(slice) if positions.is_c_contiguous() => slice.to_vec(),
        _ => positions.as_array().iter().copied().collect(),
    };
    let codec = registry().by_name(codec).map_err(to_py)?;
    let params = params_from(codec, Some(params))?;
    let packets = py
        .detach(|| animcodec::core::blocks::encode_block(codec, &params, &topology, frames, fps, index, &coords))
        .map_err(to_py)?;
    packets_to_py(py, packets)
}

/// A PC2/MDD cache's `(vertices, frames, fps, faces[T, 3] uint32)`, read from its header and
/// topology only (no positions), as `encode_block_file` reads it.
#[pyfunction]
#[pyo3(signature = (path, topology=None, fps=None))]
fn cache_header<'py>(
    py: Python<'py>,
    path: PathBuf,
    topology: Option<PathBuf>,
    fps: Option<f32>,
) -> PyResult<Bound<'py, PyTuple>> {
    let options = ReadOptions { topology, frame_rate: fps, animation: None, object: None };
    let reader = py.detach(|| formats::stream::CacheReader::open(&path, &options)).map_err(to_py)?;
    let faces: Vec<u32> = reader.topology().triangles().iter().flatten().copied().collect();
    let t = reader.topology().triangle_count();
    let faces: Bound<'py, PyArray2<u32>> = PyArray1::from_vec(py, faces).reshape([t, 3])?;
    (reader.vertex_count(), reader.frame_count(), reader.frame_rate(), faces).into_pyobject(py)
}

/// [`encode_block`] reading only block `index`'s frames from a PC2/MDD cache (a worker reads
/// its own frames: the file must be at `path` on every worker).
#[pyfunction]
#[pyo3(signature = (path, codec, params, index, topology=None, fps=None))]
fn encode_block_file<'py>(
    py: Python<'py>,
    path: PathBuf,
    codec: &str,
    params: &Bound<'py, PyDict>,
    index: usize,
    topology: Option<PathBuf>,
    fps: Option<f32>,
) -> PyResult<Bound<'py, PyList>> {
    let codec = registry().by_name(codec).map_err(to_py)?;
    let params = params_from(codec, Some(params))?;
    let options = ReadOptions { topology, frame_rate: fps, animation: None, object: None };
    let packets = py
        .detach(|| -> Result<_, BoxError> {
            let mut reader = formats::stream::CacheReader::open(&path, &options)?;
            let (v, f) = (reader.vertex_count(), reader.frame_count());
            let (_, plan) = animcodec::core::blocks::block_plan(codec, &params, v, f, None)?;
            if index >= plan.blocks {
                return Err(format!("block {index} does not exist: {f} frames make {} blocks", plan.blocks).into());
            }
            let range = plan.frames(index);
            reader.seek_frame(range.start)?;
            let mut frames = Vec::new();
            reader.read_frames(range.len(), &mut frames)?;
            let topology = reader.topology().clone();
            Ok(animcodec::core::blocks::encode_block(
                codec,
                &params,
                &topology,
                f,
                reader.frame_rate(),
                index,
                &frames,
            )?)
        })
        .map_err(to_py)?;
    packets_to_py(py, packets)
}

/// The `.anim` container of the whole animation from every block's packets (in frame order):
/// the bytes the local encode with the same parameters writes.
#[pyfunction]
#[pyo3(signature = (faces, vertices, codec, fps, params, frames, packets))]
#[allow(clippy::too_many_arguments)]
fn assemble_blocks<'py>(
    py: Python<'py>,
    faces: PyReadonlyArray2<'py, u32>,
    vertices: usize,
    codec: &str,
    fps: f32,
    params: &Bound<'py, PyDict>,
    frames: usize,
    packets: &Bound<'py, PyList>,
) -> PyResult<Bound<'py, PyBytes>> {
    let topology = topology_from(&faces, vertices)?;
    let codec = registry().by_name(codec).map_err(to_py)?;
    let params = params_from(codec, Some(params))?;
    let packets: Vec<animcodec::core::Packet> = packets
        .iter()
        .map(|item| {
            let (first_frame, frame_count, keyframe, data): (u32, u32, bool, Bound<'py, PyBytes>) = item.extract()?;
            Ok(animcodec::core::Packet { first_frame, frame_count, keyframe, data: data.as_bytes().to_vec() })
        })
        .collect::<PyResult<_>>()?;
    let bytes = py
        .detach(|| {
            animcodec::core::blocks::assemble_blocks(codec, &params, &topology, frames, fps, packets, Vec::new())
        })
        .map_err(to_py)?;
    Ok(PyBytes::new(py, &bytes))
}

/// The extension module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("AnimcodecError", m.py().get_type::<AnimcodecError>())?;
    m.add("DEFAULT_MAX_MEMORY", animcodec::core::limits::DEFAULT_MAX_MEMORY)?;
    m.add("DEFAULT_MAX_WORK", animcodec::core::limits::DEFAULT_MAX_WORK)?;
    m.add_function(wrap_pyfunction!(codecs, m)?)?;
    m.add_function(wrap_pyfunction!(encode, m)?)?;
    m.add_function(wrap_pyfunction!(encode_to_target, m)?)?;
    m.add_function(wrap_pyfunction!(decode, m)?)?;
    m.add_function(wrap_pyfunction!(decode_frame, m)?)?;
    m.add_function(wrap_pyfunction!(info, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(save, m)?)?;
    m.add_function(wrap_pyfunction!(sweep_plan, m)?)?;
    m.add_function(wrap_pyfunction!(sweep_point, m)?)?;
    m.add_function(wrap_pyfunction!(sweep_local, m)?)?;
    m.add_function(wrap_pyfunction!(check_outputs, m)?)?;
    m.add_function(wrap_pyfunction!(sweep_document, m)?)?;
    m.add_function(wrap_pyfunction!(block_plan, m)?)?;
    m.add_function(wrap_pyfunction!(encode_block, m)?)?;
    m.add_function(wrap_pyfunction!(encode_block_file, m)?)?;
    m.add_function(wrap_pyfunction!(cache_header, m)?)?;
    m.add_function(wrap_pyfunction!(assemble_blocks, m)?)?;
    Ok(())
}
