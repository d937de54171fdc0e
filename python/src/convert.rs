//! Conversions between Python and the library's types: numpy arrays ↔ [`Animation`], JSON
//! values ↔ Python objects (numbers exactly: f64 ↔ float, integers ↔ int), and parameter and
//! metric-option dicts through the command line's front door.

use animcodec::core::{Animation, AnimationCodec, ParamSet, Topology};
use animcodec::front::{self, MetricOptions, ParamInput};
use animcodec::metrics::EvalOptions;
use numpy::{PyArray1, PyArray2, PyArray3, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use pyo3::IntoPyObjectExt;
use serde_json::{Map, Number, Value};

use crate::to_py;

/// An animation from `positions[F, V, 3]` (float32) and `faces[T, 3]` (uint32), any memory
/// layout. The positions are copied once: [`Animation`] owns its coordinates.
pub(crate) fn animation_from(
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
pub(crate) fn animation_to_py<'py>(py: Python<'py>, animation: Animation) -> PyResult<Bound<'py, PyTuple>> {
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

pub(crate) fn value_to_py(py: Python<'_>, value: &Value) -> PyResult<Py<PyAny>> {
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

pub(crate) fn py_to_value(obj: &Bound<'_, PyAny>) -> PyResult<Value> {
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
pub(crate) fn params_from(codec: &dyn AnimationCodec, params: Option<&Bound<'_, PyDict>>) -> PyResult<ParamSet> {
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
pub(crate) fn eval_options(options: Option<&Bound<'_, PyDict>>) -> PyResult<EvalOptions> {
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
