//! The single-animation functions: the codec list, encode (with parameters, or searching for
//! the default quality or a target), decode, decode one frame, info, evaluate, load and save.

use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;

use animcodec::core::{AnimationCodec, StreamDecoder};
use animcodec::describe;
use animcodec::formats::{self, WriteOptions};
use animcodec::front::{self};
use animcodec::harness::{self, SearchRequest, Target};
use animcodec::output::OutputPolicy;
use animcodec::params::params_json;
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyTuple};
use serde_json::Value;

use crate::convert::{animation_from, animation_to_py, eval_options, params_from, value_to_py};
use crate::input::{limits_from, load_input, Source};
use crate::{registry, to_py, BoxError};

/// Every registered codec: name, FourCC, stream version, summary, parameters (kind, default,
/// range or choices, doc) and rate ladder — `animcodec list --json`.
#[pyfunction]
pub(crate) fn codecs(py: Python<'_>) -> PyResult<Py<PyAny>> {
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
pub(crate) fn encode<'py>(
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
pub(crate) struct Callback {
    pub(crate) callable: Option<Py<PyAny>>,
    raised: Mutex<Option<PyErr>>,
}

/// The unwinding payload of a callback that raised.
struct CallbackRaised;

impl Callback {
    pub(crate) fn new(callable: Option<Py<PyAny>>) -> Self {
        Self { callable, raised: Mutex::new(None) }
    }

    fn raised(&self) -> std::sync::MutexGuard<'_, Option<PyErr>> {
        self.raised.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Calls the callable with `row` as a dict; after an exception, unwinds instead.
    pub(crate) fn call(&self, row: &Value) {
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
    pub(crate) fn run<T: Send>(
        &self,
        py: Python<'_>,
        work: impl FnOnce() -> Result<T, BoxError> + Send,
    ) -> PyResult<T> {
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
pub(crate) struct TargetSearch<'py> {
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
pub(crate) fn encode_to_target<'py>(
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
pub(crate) fn decode<'py>(
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
pub(crate) fn decode_frame<'py>(
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
pub(crate) fn info<'py>(
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
pub(crate) fn evaluate<'py>(
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
pub(crate) fn load<'py>(
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
pub(crate) fn save<'py>(
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
