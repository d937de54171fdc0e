//! The meshes of a glTF file as [`super::gltf_scene`] instances them: each mesh's primitives
//! concatenated into base positions, morph target displacements, triangles and skin influences,
//! every accessor checked against the declared counts and the budget before it is read. Kept
//! apart from the scene because a mesh is read once whichever nodes and animation use it.

use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::mesh::Mode;
use ::gltf::Semantic;
use codec_core::{Error, Result};

use super::gltf_buffers::{
    bad, check_accessor, check_accessor_kind, collect_exact, Budget, BufferData, KHR_MESH_QUANTIZATION,
};
use super::gltf_draco;

/// One mesh, its primitives concatenated: base positions, per-target displacements, triangles
/// (indices local to the mesh) and, when the primitives carry `JOINTS_n`/`WEIGHTS_n`, the skin
/// influences.
pub(super) struct MeshData {
    pub(super) base: Vec<f32>,
    pub(super) targets: Vec<Vec<f32>>,
    pub(super) triangles: Vec<[u32; 3]>,
    /// `influences` joint/weight pairs per vertex (4 per `JOINTS_n` set), weights normalized to
    /// sum 1 (a vertex whose weights are all zero keeps zero weights).
    pub(super) joints: Vec<u16>,
    pub(super) weights: Vec<f32>,
    pub(super) influences: usize,
}

impl MeshData {
    pub(super) fn vertex_count(&self) -> usize {
        self.base.len() / 3
    }
}

pub(super) fn unsupported(file: &str, detail: String) -> Error {
    Error::Unsupported { context: file.to_owned().into(), detail }
}

pub(super) fn limit(file: &str, field: &'static str, value: usize, limit: usize) -> Error {
    Error::LimitExceeded {
        context: file.to_owned().into(),
        field: field.into(),
        value: value as u64,
        limit: limit as u64,
    }
}

/// Position-like VEC3 data: `f32`, or (`KHR_mesh_quantization`) 8/16-bit integers, normalized
/// or not (`max(c / (2ᵇ⁻¹ − 1), −1)` / `c / (2ᵇ − 1)` when normalized, `c` otherwise).
/// Integer accessors are read here with their view's stride, bounds checked (the crate's
/// reader reads only `f32` positions); sparse integer accessors are refused.
pub(super) fn read_vec3(
    file: &str,
    field: &'static str,
    accessor: &::gltf::Accessor,
    buffers: &[BufferData],
) -> Result<Vec<f32>> {
    let n = accessor.count();
    let what = format!("accessor {}", accessor.index());
    // The view's and the accessor's offsets come from the file: their sum may overflow.
    let start = match accessor.view() {
        Some(view) => view.offset().checked_add(accessor.offset()).ok_or_else(|| {
            bad(
                file,
                field,
                format!("{what}: byteOffset {} overflows past bufferView {}", accessor.offset(), view.index()),
            )
        })?,
        None => 0,
    };
    let get = |b: ::gltf::Buffer| buffers.get(b.index()).map(|d| &d.0[..]);
    if accessor.data_type() == DataType::F32 {
        let items = collect_exact(file, field, ::gltf::accessor::Iter::<[f32; 3]>::new(accessor.clone(), get), n)?;
        return Ok(items.concat());
    }
    if accessor.sparse().is_some() {
        return Err(bad(file, field, format!("{what}: sparse quantized positions are not supported")));
    }
    let view = accessor.view().ok_or_else(|| bad(file, field, format!("{what} has no bufferView")))?;
    let size = accessor.data_type().size();
    let stride = view.stride().unwrap_or(3 * size);
    let data = buffers.get(view.buffer().index()).map(|d| &d.0[..]).unwrap_or(&[]);
    let view_end = view.offset().saturating_add(view.length()).min(data.len());
    let needed = start.saturating_add(stride.saturating_mul(n - 1)).saturating_add(3 * size);
    if needed > view_end || stride < 3 * size {
        return Err(bad(
            file,
            field,
            format!("{what}: {n} items of stride {stride} do not fit in bufferView {}", view.index()),
        ));
    }
    let normalized = accessor.normalized();
    let mut out = Vec::with_capacity(3 * n);
    for v in 0..n {
        for c in 0..3 {
            let at = start + v * stride + c * size;
            let b = &data[at..at + size];
            let x = match accessor.data_type() {
                DataType::I8 => (b[0] as i8) as f32 / if normalized { 127.0 } else { 1.0 },
                DataType::U8 => b[0] as f32 / if normalized { 255.0 } else { 1.0 },
                DataType::I16 => i16::from_le_bytes([b[0], b[1]]) as f32 / if normalized { 32767.0 } else { 1.0 },
                DataType::U16 => u16::from_le_bytes([b[0], b[1]]) as f32 / if normalized { 65535.0 } else { 1.0 },
                other => return Err(bad(file, field, format!("{what} has component type {other:?}"))),
            };
            out.push(if normalized { x.max(-1.0) } else { x });
        }
    }
    Ok(out)
}

/// Most units of playback work (see [`super::gltf_scene::bake`]): far above any real animation (10⁴ frames of a
/// 10⁵-vertex mesh with 4 influences and 4 targets is 9·10⁹), far below a crafted file's
/// 10⁷ frames × 10⁵ nodes.
pub(super) const MAX_BAKE_WORK: usize = 20_000_000_000;

/// Most morph targets a mesh may have (each costs 12 bytes per vertex and work per frame).
pub(super) const MAX_MORPH_TARGETS: usize = 4096;
/// Most `JOINTS_n`/`WEIGHTS_n` sets a primitive may have (4 influences each).
pub(super) const MAX_JOINT_SETS: usize = 8;

/// Checks an accessor whose data a `KHR_draco_mesh_compression` primitive holds instead:
/// dimensions, component type and a count equal to the decoded one (`count`); its bufferView,
/// if any, is not read.
pub(super) fn check_declared(
    file: &str,
    field: &'static str,
    accessor: &::gltf::Accessor,
    dims: Dimensions,
    types: &[DataType],
    count: usize,
) -> Result<()> {
    check_accessor_kind(file, field, accessor, dims, types)?;
    let what = format!("accessor {}", accessor.index());
    if accessor.count() != count {
        return Err(bad(
            file,
            field,
            format!("{what} declares {} items but the Draco data decodes to {count}", accessor.count()),
        ));
    }
    Ok(())
}

/// Loads a mesh: every primitive, in order (primitive `k`'s vertices follow those of `0..k`).
/// `quantization`: the file uses `KHR_mesh_quantization` (8/16-bit positions and displacements
/// allowed; without it the core spec allows only `f32`). `json` is the file's raw JSON (the
/// primitives' `KHR_draco_mesh_compression` objects); a Draco primitive is decoded under what is
/// left of `budget`.
pub(super) fn load_mesh(
    file: &str,
    mesh: &::gltf::Mesh,
    document: &::gltf::Document,
    buffers: &[BufferData],
    json: &serde_json::Value,
    quantization: bool,
    budget: &Budget,
) -> Result<MeshData> {
    let limits = super::reader_limits();
    let m = mesh.index();
    let first = mesh.primitives().next();
    let target_count = first.as_ref().map(|p| p.morph_targets().len()).unwrap_or(0);
    if target_count > MAX_MORPH_TARGETS {
        return Err(limit(file, "targets", target_count, MAX_MORPH_TARGETS));
    }
    let sets_of = |p: &::gltf::Primitive| {
        (0..).take_while(|&s| p.get(&Semantic::Joints(s)).is_some()).take(MAX_JOINT_SETS + 1).count()
    };
    let sets = first.as_ref().map(sets_of).unwrap_or(0);
    if sets > MAX_JOINT_SETS {
        return Err(limit(file, "JOINTS_n sets", sets, MAX_JOINT_SETS));
    }
    // Bytes held per vertex once read: base and target positions (f32 × 3 each), and per
    // influence a u16 joint and an f32 weight, plus the per-primitive staging of both.
    let bytes_per_vertex = 12 * (1 + target_count) + 4 * sets * 12;
    let mut data = MeshData {
        base: Vec::new(),
        targets: vec![Vec::new(); target_count],
        triangles: Vec::new(),
        joints: Vec::new(),
        weights: Vec::new(),
        influences: 4 * sets,
    };
    for primitive in mesh.primitives() {
        let p = primitive.index();
        if primitive.mode() != Mode::Triangles {
            return Err(unsupported(
                file,
                format!("mesh {m} primitive {p} has mode {:?}; only TRIANGLES is supported", primitive.mode()),
            ));
        }
        let positions = primitive
            .get(&Semantic::Positions)
            .ok_or_else(|| bad(file, "POSITION", format!("mesh {m} primitive {p} has no POSITION")))?;
        let quantized: &[DataType] = if quantization {
            &[DataType::F32, DataType::I8, DataType::U8, DataType::I16, DataType::U16]
        } else {
            &[DataType::F32]
        };
        if !quantized.contains(&positions.data_type()) {
            return Err(bad(
                file,
                "POSITION",
                format!(
                    "mesh {m} primitive {p}: accessor {} has component type {:?}; integer positions need \
                     {KHR_MESH_QUANTIZATION} in extensionsUsed",
                    positions.index(),
                    positions.data_type()
                ),
            ));
        }
        let offset = data.vertex_count();
        // Sizes are checked before anything is read (or its layout checked): every target may
        // name the same accessor.
        let vertices = offset.saturating_add(positions.count());
        if vertices > limits.max_vertices {
            return Err(limit(file, "vertex_count", vertices, limits.max_vertices));
        }
        let bytes = vertices.saturating_mul(bytes_per_vertex);
        if bytes > limits.max_alloc_bytes {
            return Err(limit(
                file,
                "mesh vertex data (POSITION, targets, JOINTS_n, WEIGHTS_n) bytes",
                bytes,
                limits.max_alloc_bytes,
            ));
        }
        // A Draco primitive: its triangles and the attributes its extension names come from the
        // decoded Draco mesh, the declared accessors give only counts and types.
        let draco = match gltf_draco::extension(file, json, m, p, document.views().len())? {
            Some(ext) => {
                let decoded = gltf_draco::decode(file, m, p, &ext, document, buffers, budget)?;
                Some((ext, decoded))
            }
            None => None,
        };
        let from_draco = |name: &str| draco.as_ref().and_then(|(ext, d)| ext.id(name).map(|id| (d, id)));
        let n = match from_draco("POSITION") {
            Some((decoded, _)) => {
                check_declared(file, "POSITION", &positions, Dimensions::Vec3, quantized, decoded.points())?;
                decoded.points()
            }
            None => check_accessor(file, "POSITION", &positions, Dimensions::Vec3, quantized, buffers)?,
        };
        if let Some((_, decoded)) = &draco {
            if decoded.points() != n {
                return Err(bad(
                    file,
                    "POSITION",
                    format!("mesh {m} primitive {p}: {n} positions for {} decoded Draco points", decoded.points()),
                ));
            }
            // What the copies below hold, counted before they are made.
            let held = (n as u64).saturating_mul(bytes_per_vertex as u64);
            budget.check("the decoded Draco primitive", held.saturating_add(4 * decoded.triangles.len() as u64))?;
        }
        if primitive.morph_targets().len() != target_count {
            return Err(bad(
                file,
                "targets",
                format!(
                    "mesh {m} primitive {p} has {} morph targets, primitive 0 has {target_count}",
                    primitive.morph_targets().len()
                ),
            ));
        }
        for target in primitive.morph_targets() {
            if let Some(acc) = target.positions() {
                let count = check_accessor(file, "targets.POSITION", &acc, Dimensions::Vec3, quantized, buffers)?;
                if count != n {
                    return Err(bad(
                        file,
                        "targets.POSITION",
                        format!("mesh {m} primitive {p}: {count} displacements for {n} vertices"),
                    ));
                }
            }
        }
        if sets_of(&primitive) != sets {
            return Err(bad(
                file,
                "JOINTS_0",
                format!("mesh {m} primitive {p} has {} JOINTS sets, primitive 0 has {sets}", sets_of(&primitive)),
            ));
        }
        const JOINT_TYPES: [DataType; 2] = [DataType::U8, DataType::U16];
        const WEIGHT_TYPES: [DataType; 3] = [DataType::F32, DataType::U8, DataType::U16];
        for s in 0..sets as u32 {
            let joints = primitive.get(&Semantic::Joints(s)).expect("counted above");
            let count = match from_draco(&format!("JOINTS_{s}")) {
                Some(_) => check_declared(file, "JOINTS", &joints, Dimensions::Vec4, &JOINT_TYPES, n).map(|_| n)?,
                None => check_accessor(file, "JOINTS", &joints, Dimensions::Vec4, &JOINT_TYPES, buffers)?,
            };
            let weights = primitive.get(&Semantic::Weights(s)).ok_or_else(|| {
                bad(file, "WEIGHTS", format!("mesh {m} primitive {p} has JOINTS_{s} but no WEIGHTS_{s}"))
            })?;
            let wcount = match from_draco(&format!("WEIGHTS_{s}")) {
                Some(_) => check_declared(file, "WEIGHTS", &weights, Dimensions::Vec4, &WEIGHT_TYPES, n).map(|_| n)?,
                None => check_accessor(file, "WEIGHTS", &weights, Dimensions::Vec4, &WEIGHT_TYPES, buffers)?,
            };
            if count != n || wcount != n {
                return Err(bad(
                    file,
                    "JOINTS",
                    format!("mesh {m} primitive {p}: JOINTS_{s} has {count} and WEIGHTS_{s} {wcount} items for {n} vertices"),
                ));
            }
        }
        let index_types = [DataType::U8, DataType::U16, DataType::U32];
        let indices = match (primitive.indices(), &draco) {
            (Some(acc), Some((_, decoded))) => {
                check_declared(file, "indices", &acc, Dimensions::Scalar, &index_types, decoded.triangles.len())?;
                None
            }
            (Some(acc), None) => {
                Some(check_accessor(file, "indices", &acc, Dimensions::Scalar, &index_types, buffers)?)
            }
            (None, _) => None,
        };
        let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
        match from_draco("POSITION") {
            Some((decoded, id)) => {
                let values = decoded.values(file, "POSITION", id, 3, positions.normalized())?;
                data.base.extend(values.iter().map(|&x| x as f32));
            }
            None => data.base.extend(read_vec3(file, "POSITION", &positions, buffers)?),
        }
        for (t, target) in primitive.morph_targets().enumerate() {
            match target.positions() {
                Some(acc) => data.targets[t].extend(read_vec3(file, "targets.POSITION", &acc, buffers)?),
                None => data.targets[t].resize((offset + n) * 3, 0.0),
            }
        }
        if sets > 0 {
            // Per vertex: the 4·sets joints of sets 0, 1, … and their weights, in that order.
            let mut joints = vec![0u16; n * 4 * sets];
            let mut weights = vec![0f32; n * 4 * sets];
            for s in 0..sets {
                let js: Vec<[u16; 4]> = match from_draco(&format!("JOINTS_{s}")) {
                    Some((decoded, id)) => {
                        let values = decoded.values(file, "JOINTS", id, 4, false)?;
                        if let Some(j) = values.iter().find(|j| !(j.fract() == 0.0 && (0.0..=65535.0).contains(*j))) {
                            return Err(bad(
                                file,
                                "JOINTS",
                                format!("mesh {m} primitive {p}: a Draco JOINTS_{s} value is {j}, not a joint index"),
                            ));
                        }
                        values.chunks_exact(4).map(|c| [c[0] as u16, c[1] as u16, c[2] as u16, c[3] as u16]).collect()
                    }
                    None => collect_exact(file, "JOINTS", reader.read_joints(s as u32).map(|j| j.into_u16()), n)?,
                };
                let ws: Vec<[f32; 4]> = match from_draco(&format!("WEIGHTS_{s}")) {
                    Some((decoded, id)) => {
                        let normalized = primitive.get(&Semantic::Weights(s as u32)).is_some_and(|a| a.normalized());
                        let values = decoded.values(file, "WEIGHTS", id, 4, normalized)?;
                        values.chunks_exact(4).map(|c| [c[0] as f32, c[1] as f32, c[2] as f32, c[3] as f32]).collect()
                    }
                    None => collect_exact(file, "WEIGHTS", reader.read_weights(s as u32).map(|w| w.into_f32()), n)?,
                };
                for v in 0..n {
                    let at = v * 4 * sets + 4 * s;
                    joints[at..at + 4].copy_from_slice(&js[v]);
                    weights[at..at + 4].copy_from_slice(&ws[v]);
                }
            }
            for (v, w) in weights.chunks_exact_mut(4 * sets).enumerate() {
                if let Some(x) = w.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
                    return Err(bad(file, "WEIGHTS", format!("mesh {m} primitive {p} vertex {v} has skin weight {x}")));
                }
                let sum: f32 = w.iter().sum();
                if sum > 0.0 {
                    w.iter_mut().for_each(|x| *x /= sum);
                }
            }
            data.joints.extend(joints);
            data.weights.extend(weights);
        }
        let flat: Vec<u32> = match (indices, draco) {
            (_, Some((_, decoded))) => decoded.triangles,
            (Some(count), None) => collect_exact(file, "indices", reader.read_indices().map(|i| i.into_u32()), count)?,
            (None, None) => (0..n as u32).collect(),
        };
        if !flat.len().is_multiple_of(3) {
            return Err(bad(
                file,
                "indices",
                format!("mesh {m} primitive {p}: {} indices is not a whole number of triangles", flat.len()),
            ));
        }
        if let Some(&i) = flat.iter().find(|&&i| i as usize >= n) {
            return Err(bad(
                file,
                "indices",
                format!("mesh {m} primitive {p}: index {i} out of range for {n} vertices"),
            ));
        }
        let o = offset as u32;
        data.triangles.extend(flat.chunks_exact(3).map(|c| [c[0] + o, c[1] + o, c[2] + o]));
        if data.vertex_count() > limits.max_vertices {
            return Err(limit(file, "vertex_count", data.vertex_count(), limits.max_vertices));
        }
        if data.triangles.len() > limits.max_triangles {
            return Err(limit(file, "triangle_count", data.triangles.len(), limits.max_triangles));
        }
    }
    if data.base.is_empty() {
        return Err(bad(file, "meshes", format!("mesh {m} has no primitives")));
    }
    Ok(data)
}
