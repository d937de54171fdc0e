//! Rate-distortion sweeps: the plan of a sweep's jobs, one job (what a Dask worker runs), the
//! single-process sweep, and the assembly of gathered rows into the command line's document
//! and files.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use animcodec::core::{CodecRegistry, Limits};
use animcodec::harness::{self, FailureRow, Sweep, SweepDocument, SweepOptions, SweepRow, SweepSeries};
use animcodec::output::OutputPolicy;
use animcodec::params::params_json;
use numpy::{PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use serde_json::Value;

use crate::codec::Callback;
use crate::convert::{animation_from, eval_options, params_from, py_to_value, value_to_py};
use crate::input::{load_cached, load_input};
use crate::{registry, to_py, BoxError};

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
pub(crate) fn sweep_plan(py: Python<'_>, series: &Bound<'_, PyList>, points: Option<usize>) -> PyResult<Py<PyAny>> {
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
pub(crate) struct SweepJob<'py> {
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
pub(crate) fn sweep_point<'py>(py: Python<'py>, job: SweepJob<'py>) -> PyResult<Py<PyAny>> {
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
pub(crate) struct LocalSweep<'py> {
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
pub(crate) fn sweep_local<'py>(py: Python<'py>, sweep: LocalSweep<'py>) -> PyResult<Py<PyAny>> {
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
            harness::SweepEvent::Phase { .. } => return,
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
pub(crate) fn check_outputs(outputs: Vec<PathBuf>, inputs: Vec<PathBuf>, force: bool) -> PyResult<()> {
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
pub(crate) struct GatheredSweep<'py> {
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
pub(crate) fn sweep_document<'py>(py: Python<'py>, gathered: GatheredSweep<'py>) -> PyResult<Py<PyAny>> {
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
