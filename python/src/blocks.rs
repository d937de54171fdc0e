//! Distributed encode: independent temporal blocks (`animcodec::core::blocks`) coded on Dask
//! workers from arrays or from their own frames of a PC2/MDD cache, and assembled on the
//! client into the bytes the local encode writes.

use std::path::PathBuf;

use animcodec::core::Topology;
use animcodec::formats::{self, ReadOptions};
use animcodec::params::params_json;
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList, PyTuple};

use crate::convert::{params_from, value_to_py};
use crate::{registry, to_py, BoxError};

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
pub(crate) fn block_plan<'py>(
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
pub(crate) fn encode_block<'py>(
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
pub(crate) fn cache_header<'py>(
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
pub(crate) fn encode_block_file<'py>(
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
pub(crate) fn assemble_blocks<'py>(
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
