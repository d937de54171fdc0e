//! A glTF scene played back into one fixed-topology vertex cache: every mesh instance of the
//! scene (node hierarchy, node TRS animation, skins, morph targets) sampled at a frame rate.
//! The choices are listed in [`super::gltf`]'s module docs; the arithmetic is in
//! [`super::gltf_anim`].

use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::animation::{Interpolation, Property};
use ::gltf::mesh::Mode;
use ::gltf::Semantic;
use codec_core::{Animation, Error, Result};

use super::gltf_anim::{self, Mat4, Track, IDENTITY};
use super::gltf_buffers::{
    bad, check_accessor, check_accessor_kind, collect_exact, printable, Budget, BufferData, KHR_MESH_QUANTIZATION,
};
use super::gltf_draco;
use super::{in_file, FRAME_RATE_RANGE};

/// Frame rate when neither the caller, the file's `extras` nor a regular key grid gives one.
const FALLBACK_FPS: f64 = 30.0;

/// One mesh, its primitives concatenated: base positions, per-target displacements, triangles
/// (indices local to the mesh) and, when the primitives carry `JOINTS_n`/`WEIGHTS_n`, the skin
/// influences.
struct MeshData {
    base: Vec<f32>,
    targets: Vec<Vec<f32>>,
    triangles: Vec<[u32; 3]>,
    /// `influences` joint/weight pairs per vertex (4 per `JOINTS_n` set), weights normalized to
    /// sum 1 (a vertex whose weights are all zero keeps zero weights).
    joints: Vec<u16>,
    weights: Vec<f32>,
    influences: usize,
}

impl MeshData {
    fn vertex_count(&self) -> usize {
        self.base.len() / 3
    }
}

fn unsupported(file: &str, detail: String) -> Error {
    Error::Unsupported { context: file.to_owned().into(), detail }
}

fn limit(file: &str, field: &'static str, value: usize, limit: usize) -> Error {
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
fn read_vec3(file: &str, field: &'static str, accessor: &::gltf::Accessor, buffers: &[BufferData]) -> Result<Vec<f32>> {
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

/// Most units of playback work (see [`bake`]): far above any real animation (10⁴ frames of a
/// 10⁵-vertex mesh with 4 influences and 4 targets is 9·10⁹), far below a crafted file's
/// 10⁷ frames × 10⁵ nodes.
const MAX_BAKE_WORK: usize = 20_000_000_000;

/// Most morph targets a mesh may have (each costs 12 bytes per vertex and work per frame).
const MAX_MORPH_TARGETS: usize = 4096;
/// Most `JOINTS_n`/`WEIGHTS_n` sets a primitive may have (4 influences each).
const MAX_JOINT_SETS: usize = 8;

/// Checks an accessor whose data a `KHR_draco_mesh_compression` primitive holds instead:
/// dimensions, component type and a count equal to the decoded one (`count`); its bufferView,
/// if any, is not read.
fn check_declared(
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
fn load_mesh(
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

/// The node hierarchy: each node's parent, and every node in an order where parents come
/// before their children.
struct Hierarchy {
    parent: Vec<Option<usize>>,
    order: Vec<usize>,
}

/// Builds the hierarchy of every node of the document; a node with two parents or a cycle is
/// an error (glTF requires the nodes to form disjoint trees).
fn hierarchy(file: &str, document: &::gltf::Document) -> Result<Hierarchy> {
    let count = document.nodes().len();
    let mut parent = vec![None; count];
    for node in document.nodes() {
        for child in node.children() {
            if let Some(other) = parent[child.index()] {
                return Err(bad(
                    file,
                    "nodes",
                    format!("node {} is a child of both node {other} and node {}", child.index(), node.index()),
                ));
            }
            parent[child.index()] = Some(node.index());
        }
    }
    let children: Vec<Vec<usize>> = document.nodes().map(|n| n.children().map(|c| c.index()).collect()).collect();
    let mut order = Vec::with_capacity(count);
    let mut reached = vec![false; count];
    let mut stack: Vec<usize> = (0..count).rev().filter(|&n| parent[n].is_none()).collect();
    while let Some(n) = stack.pop() {
        order.push(n);
        reached[n] = true;
        stack.extend(children[n].iter().rev());
    }
    // Every node has at most one parent, so a node not reached from a root lies on a cycle.
    if let Some(stuck) = reached.iter().position(|r| !r) {
        return Err(bad(file, "nodes", format!("node {stuck} is part of a cycle in the node hierarchy")));
    }
    Ok(Hierarchy { parent, order })
}

/// The mesh instances of the scene, in the documented vertex order: the default scene (else
/// scene 0, else every root node), its root nodes in order, each subtree depth first with a
/// node's own mesh before its children.
fn scene_mesh_nodes(document: &::gltf::Document, hierarchy: &Hierarchy) -> Vec<usize> {
    let roots: Vec<usize> = match document.default_scene().or_else(|| document.scenes().next()) {
        Some(scene) => scene.nodes().map(|n| n.index()).collect(),
        None => (0..hierarchy.parent.len()).filter(|&n| hierarchy.parent[n].is_none()).collect(),
    };
    let nodes: Vec<::gltf::Node> = document.nodes().collect();
    let mut out = Vec::new();
    // A node reached twice (invalid: a root listed twice, or a root that is also a descendant of
    // another root) is played once, at its first visit; this keeps the walk linear in the node
    // count (a chain listing every node as a root would otherwise visit ~N²/2 nodes).
    let mut seen = vec![false; nodes.len()];
    let mut stack: Vec<usize> = roots.into_iter().rev().collect();
    while let Some(n) = stack.pop() {
        if std::mem::replace(&mut seen[n], true) {
            continue;
        }
        if nodes[n].mesh().is_some() {
            out.push(n);
        }
        stack.extend(nodes[n].children().map(|c| c.index()).collect::<Vec<_>>().into_iter().rev());
    }
    out
}

/// A node's local transform at rest: TRS (animatable) or a matrix (not animatable).
#[derive(Clone, Copy)]
enum Local {
    Trs { t: [f64; 3], r: [f64; 4], s: [f64; 3] },
    Matrix(Mat4),
}

fn rest_transform(node: &::gltf::Node) -> Local {
    match node.transform() {
        ::gltf::scene::Transform::Matrix { matrix } => {
            let mut m = [0.0; 16];
            for (c, column) in matrix.iter().enumerate() {
                for (r, x) in column.iter().enumerate() {
                    m[4 * c + r] = *x as f64;
                }
            }
            Local::Matrix(m)
        }
        ::gltf::scene::Transform::Decomposed { translation, rotation, scale } => {
            Local::Trs { t: translation.map(f64::from), r: rotation.map(f64::from), s: scale.map(f64::from) }
        }
    }
}

/// One animation channel, loaded and checked.
struct Channel {
    node: usize,
    property: Property,
    track: Track,
}

/// Summary of one animation of a file (`list-animations`).
#[derive(Debug, Clone, PartialEq)]
pub struct AnimationInfo {
    /// Index in the file's `animations` array.
    pub index: usize,
    /// Its name, if any.
    pub name: Option<String>,
    /// Channels (node × property).
    pub channels: usize,
    /// First key time over all its samplers (seconds).
    pub start: f64,
    /// Last key time over all its samplers (seconds).
    pub end: f64,
    /// The rate of its key grid when the keys lie on one (what `--fps` defaults to).
    pub key_rate: Option<f64>,
    /// Properties animated: a subset of translation, rotation, scale, weights.
    pub properties: Vec<&'static str>,
}

fn property_name(p: Property) -> &'static str {
    match p {
        Property::Translation => "translation",
        Property::Rotation => "rotation",
        Property::Scale => "scale",
        Property::MorphTargetWeights => "weights",
    }
}

/// Loads and checks every channel of `animation`. `targets(node)` is the morph target count of
/// the node's mesh (for `weights` channels).
fn load_channels(
    file: &str,
    animation: &::gltf::Animation,
    buffers: &[BufferData],
    targets: &dyn Fn(usize) -> usize,
) -> Result<Vec<Channel>> {
    let a = animation.index();
    let mut out = Vec::new();
    for channel in animation.channels() {
        let c = channel.index();
        let at = || format!("animation {a} channel {c}");
        let node = channel.target().node();
        let property = channel.target().property();
        if property != Property::MorphTargetWeights {
            if let ::gltf::scene::Transform::Matrix { .. } = node.transform() {
                return Err(bad(
                    file,
                    "animation.channels",
                    format!(
                        "{} animates node {}, which has a matrix (only TRS nodes can be animated)",
                        at(),
                        node.index()
                    ),
                ));
            }
        }
        let sampler = channel.sampler();
        let keys =
            check_accessor(file, "animation.input", &sampler.input(), Dimensions::Scalar, &[DataType::F32], buffers)?;
        let normalized = [DataType::F32, DataType::I8, DataType::U8, DataType::I16, DataType::U16];
        let (dims, types, width): (Dimensions, &[DataType], usize) = match property {
            Property::Translation | Property::Scale => (Dimensions::Vec3, &[DataType::F32], 3),
            Property::Rotation => (Dimensions::Vec4, &normalized, 4),
            Property::MorphTargetWeights => (Dimensions::Scalar, &normalized, targets(node.index())),
        };
        if width == 0 {
            return Err(bad(
                file,
                "animation.output",
                format!("{}: a weights animation on node {}, whose mesh has no morph targets", at(), node.index()),
            ));
        }
        let outputs = check_accessor(file, "animation.output", &sampler.output(), dims, types, buffers)?;
        let interpolation = sampler.interpolation();
        let per_key = if interpolation == Interpolation::CubicSpline { 3 * width } else { width };
        let expected = keys * per_key;
        let got = if property == Property::MorphTargetWeights { outputs } else { outputs * width };
        if got != expected {
            return Err(bad(
                file,
                "animation.output",
                format!(
                    "{}: {got} values for {keys} keys × {width} ({}, {interpolation:?}); expected {expected}",
                    at(),
                    property_name(property)
                ),
            ));
        }
        let reader = channel.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
        let times = collect_exact(file, "animation.input", reader.read_inputs(), keys)?;
        if let Some(k) = times.iter().position(|t| !t.is_finite()) {
            return Err(bad(file, "animation.input", format!("{}: key {k} has time {}", at(), times[k])));
        }
        if let Some(k) = times.windows(2).position(|w| w[1] <= w[0]) {
            return Err(bad(
                file,
                "animation.input",
                format!("{}: key times are not increasing at key {}", at(), k + 1),
            ));
        }
        use ::gltf::animation::util::ReadOutputs;
        let missing = || bad(file, "animation.output", format!("{}: output buffer data is missing", at()));
        let values: Vec<f32> = match reader.read_outputs().ok_or_else(missing)? {
            ReadOutputs::Translations(it) => collect_exact(file, "animation.output", Some(it), outputs)?.concat(),
            ReadOutputs::Scales(it) => collect_exact(file, "animation.output", Some(it), outputs)?.concat(),
            ReadOutputs::Rotations(r) => collect_exact(file, "animation.output", Some(r.into_f32()), outputs)?.concat(),
            ReadOutputs::MorphTargetWeights(w) => collect_exact(file, "animation.output", Some(w.into_f32()), outputs)?,
        };
        if let Some(k) = values.iter().position(|v| !v.is_finite()) {
            return Err(bad(file, "animation.output", format!("{}: value {k} is {}", at(), values[k])));
        }
        let rotation = property == Property::Rotation;
        out.push(Channel {
            node: node.index(),
            property,
            track: Track { times, values, width, interpolation, rotation },
        });
    }
    Ok(out)
}

/// Lowest key-grid rate used as the sampling rate: keys further apart than a second are
/// sampled at [`FALLBACK_FPS`] instead (a 2-key, 10-second animation is not meant as 0.1 fps).
const MIN_KEY_RATE: f64 = 1.0;

/// The rate of the key grid: `1 / Δ` for the smallest key spacing `Δ` when every key time of
/// every channel is a whole number of `Δ` after the first (within 1 % of `Δ`), rounded to an
/// integer when within 0.1 % of one; `None` otherwise. Any rate: the caller refuses one above
/// [`FRAME_RATE_RANGE`] by name.
fn key_grid(channels: &[Channel]) -> Option<f64> {
    let mut times: Vec<f64> = channels.iter().flat_map(|c| c.track.times.iter().map(|&t| t as f64)).collect();
    times.sort_by(f64::total_cmp);
    times.dedup_by(|a, b| (*a - *b).abs() <= 1e-6 * b.abs().max(1.0));
    let step = times.windows(2).map(|w| w[1] - w[0]).fold(f64::INFINITY, f64::min);
    if !(step.is_finite() && step > 0.0) {
        return None;
    }
    let on_grid = times.iter().all(|t| {
        let k = (t - times[0]) / step;
        (k - k.round()).abs() <= 0.01
    });
    let rate = 1.0 / step;
    let rounded = rate.round();
    let rate = if (rate - rounded).abs() <= 1e-3 * rounded { rounded } else { rate };
    on_grid.then_some(rate)
}

/// The key grid's rate when it is the one sampling uses by default: between [`MIN_KEY_RATE`]
/// and the top of [`FRAME_RATE_RANGE`].
fn key_rate(channels: &[Channel]) -> Option<f64> {
    key_grid(channels).filter(|r| (MIN_KEY_RATE..=f64::from(*FRAME_RATE_RANGE.end())).contains(r))
}

/// Time range of the channels' keys.
fn key_range(channels: &[Channel]) -> Option<(f64, f64)> {
    let first = channels.iter().map(|c| c.track.times[0] as f64).fold(f64::INFINITY, f64::min);
    let last =
        channels.iter().map(|c| *c.track.times.last().expect("non-empty") as f64).fold(f64::NEG_INFINITY, f64::max);
    first.is_finite().then_some((first, last))
}

/// Morph target count of the mesh each node uses (0 without a mesh).
fn node_targets(document: &::gltf::Document) -> Vec<usize> {
    document
        .nodes()
        .map(|n| n.mesh().and_then(|m| m.primitives().next()).map_or(0, |p| p.morph_targets().len()))
        .collect()
}

/// Every animation of the document, summarized.
pub(super) fn list(file: &str, document: &::gltf::Document, buffers: &[BufferData]) -> Result<Vec<AnimationInfo>> {
    let targets = node_targets(document);
    document
        .animations()
        .map(|animation| {
            let channels = load_channels(file, &animation, buffers, &|n| targets[n])?;
            let (start, end) = key_range(&channels).unwrap_or((0.0, 0.0));
            let mut properties: Vec<&'static str> = Vec::new();
            for c in &channels {
                let name = property_name(c.property);
                if !properties.contains(&name) {
                    properties.push(name);
                }
            }
            Ok(AnimationInfo {
                index: animation.index(),
                name: animation.name().map(str::to_owned),
                channels: channels.len(),
                start,
                end,
                key_rate: key_rate(&channels),
                properties,
            })
        })
        .collect()
}

/// Finds the animation `wanted` names: an exact name first, else an index; `None` = the first.
fn choose<'a>(
    file: &str,
    document: &'a ::gltf::Document,
    wanted: Option<&str>,
) -> Result<Option<::gltf::Animation<'a>>> {
    let Some(wanted) = wanted else { return Ok(document.animations().next()) };
    if let Some(a) = document.animations().find(|a| a.name() == Some(wanted)) {
        return Ok(Some(a));
    }
    if let Some(a) = wanted.parse::<usize>().ok().and_then(|i| document.animations().nth(i)) {
        return Ok(Some(a));
    }
    let available: Vec<String> = document
        .animations()
        .map(|a| match a.name() {
            Some(n) => format!("{} '{}'", a.index(), printable(n)),
            None => a.index().to_string(),
        })
        .collect();
    let have = if available.is_empty() { "none".to_string() } else { available.join(", ") };
    Err(bad(file, "animation", format!("no animation named or numbered '{}'; the file has: {have}", printable(wanted))))
}

/// The frame rate stored by animcodec's glTF writer in the animation's `extras`.
fn extras_fps(json: &serde_json::Value, animation: usize) -> Option<f64> {
    let fps = json.get("animations")?.get(animation)?.get("extras")?.get("animcodec")?.get("fps")?.as_f64()?;
    FRAME_RATE_RANGE.contains(&(fps as f32)).then_some(fps)
}

/// A mesh instance in the cache: its node, mesh, skin and first vertex.
struct Instance {
    node: usize,
    mesh: usize,
    skin: Option<usize>,
    offset: usize,
    /// Rest morph weights (node's, else mesh's, else zeros).
    weights: Vec<f64>,
}

/// A skin: joint nodes and inverse bind matrices.
struct Skin {
    joints: Vec<usize>,
    inverse_bind: Vec<Mat4>,
}

fn load_skin(file: &str, skin: &::gltf::Skin, buffers: &[BufferData]) -> Result<Skin> {
    let joints: Vec<usize> = skin.joints().map(|n| n.index()).collect();
    if joints.is_empty() {
        return Err(bad(file, "skins", format!("skin {} has no joints", skin.index())));
    }
    let inverse_bind = match skin.inverse_bind_matrices() {
        None => vec![IDENTITY; joints.len()],
        Some(acc) => {
            let count = check_accessor(file, "inverseBindMatrices", &acc, Dimensions::Mat4, &[DataType::F32], buffers)?;
            if count < joints.len() {
                return Err(bad(
                    file,
                    "inverseBindMatrices",
                    format!("skin {}: {count} inverse bind matrices for {} joints", skin.index(), joints.len()),
                ));
            }
            let reader = skin.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
            let raw = collect_exact(file, "inverseBindMatrices", reader.read_inverse_bind_matrices(), count)?;
            raw.iter()
                .take(joints.len())
                .map(|m| {
                    let mut out = [0.0; 16];
                    for (c, column) in m.iter().enumerate() {
                        for (r, x) in column.iter().enumerate() {
                            out[4 * c + r] = *x as f64;
                        }
                    }
                    out
                })
                .collect()
        }
    };
    Ok(Skin { joints, inverse_bind })
}

/// What to play: the animation (name or index; `None` = the first) and the frame rate
/// (`None` = the file's own: animcodec's `extras`, else the key grid, else 30).
pub(super) struct Selection<'a> {
    pub animation: Option<&'a str>,
    pub frame_rate: Option<f64>,
    /// Copies of the positions the caller holds after the read (`GltfSelection::working_copies`).
    pub working_copies: u64,
}

/// Plays the scene into a vertex cache. `json` is the file's raw JSON (extension data,
/// animcodec's `extras`); everything held is counted against `budget` before it is allocated.
pub(super) fn bake(
    file: &str,
    document: &::gltf::Document,
    buffers: &[BufferData],
    json: &serde_json::Value,
    selection: &Selection,
    budget: &mut Budget,
) -> Result<Animation> {
    let limits = super::reader_limits();
    let hierarchy = hierarchy(file, document)?;
    let mesh_nodes = scene_mesh_nodes(document, &hierarchy);
    if mesh_nodes.is_empty() {
        return Err(bad(file, "meshes", "no node of the scene has a mesh"));
    }
    let quantization = json
        .get("extensionsUsed")
        .and_then(|u| u.as_array())
        .is_some_and(|u| u.iter().any(|e| e.as_str() == Some(KHR_MESH_QUANTIZATION)));
    let nodes: Vec<::gltf::Node> = document.nodes().collect();
    let mut meshes: Vec<Option<MeshData>> = (0..document.meshes().len()).map(|_| None).collect();
    let mut skins: Vec<Option<Skin>> = (0..document.skins().len()).map(|_| None).collect();
    let mut instances = Vec::new();
    let mut vertex_count = 0usize;
    let mut triangle_count = 0usize;
    for &n in &mesh_nodes {
        let mesh = nodes[n].mesh().expect("a mesh node");
        let m = mesh.index();
        if meshes[m].is_none() {
            let data = load_mesh(file, &mesh, document, buffers, json, quantization, budget)?;
            let held = 4 * (data.base.len() + data.targets.iter().map(Vec::len).sum::<usize>() + data.weights.len())
                + 2 * data.joints.len()
                + 12 * data.triangles.len();
            budget.take("mesh data", held as u64)?;
            meshes[m] = Some(data);
        }
        let data = meshes[m].as_ref().expect("loaded");
        let skin = nodes[n].skin().map(|s| s.index());
        if let Some(s) = skin {
            if skins[s].is_none() {
                skins[s] = Some(load_skin(file, &nodes[n].skin().expect("a skin"), buffers)?);
            }
            let joints = skins[s].as_ref().expect("loaded").joints.len();
            if data.influences == 0 {
                return Err(bad(file, "JOINTS_0", format!("node {n} has skin {s} but mesh {m} has no JOINTS_0")));
            }
            // A joint index must name a joint of the skin; one carrying zero weight is ignored.
            let bad_joint = data.joints.iter().zip(&data.weights).position(|(&j, &w)| w > 0.0 && j as usize >= joints);
            if let Some(i) = bad_joint {
                return Err(bad(
                    file,
                    "JOINTS",
                    format!(
                        "mesh {m} vertex {} uses joint {} but skin {s} has {joints} joints",
                        i / data.influences,
                        data.joints[i]
                    ),
                ));
            }
        }
        let targets = data.targets.len();
        let rest = nodes[n].weights().or_else(|| mesh.weights()).unwrap_or(&[]);
        if !rest.is_empty() && rest.len() != targets {
            return Err(bad(
                file,
                "weights",
                format!("node {n}: {} default weights for {targets} targets", rest.len()),
            ));
        }
        let mut weights = vec![0.0; targets];
        for (w, &r) in weights.iter_mut().zip(rest) {
            *w = r as f64;
        }
        let offset = vertex_count;
        vertex_count += data.vertex_count();
        if vertex_count > limits.max_vertices {
            return Err(limit(file, "vertex_count", vertex_count, limits.max_vertices));
        }
        // Counted only here; the triangles are built once the whole read is known to fit.
        triangle_count += data.triangles.len();
        if triangle_count > limits.max_triangles {
            return Err(limit(file, "triangle_count", triangle_count, limits.max_triangles));
        }
        instances.push(Instance { node: n, mesh: m, skin, offset, weights });
    }

    let chosen = choose(file, document, selection.animation)?;
    let targets = node_targets(document);
    let channels = match &chosen {
        Some(a) => load_channels(file, a, buffers, &|n| targets[n])?,
        None => Vec::new(),
    };
    let own_rate = || -> Result<f64> {
        if let Some(fps) = chosen.as_ref().and_then(|a| extras_fps(json, a.index())) {
            return Ok(fps);
        }
        match key_grid(&channels) {
            Some(rate) if rate > f64::from(*FRAME_RATE_RANGE.end()) => Err(bad(
                file,
                "animation.input",
                format!(
                    "the keys lie on a grid of {rate:.6e} frames per second, above the highest supported rate {}; \
                     give a frame rate (--fps) to sample it",
                    FRAME_RATE_RANGE.end()
                ),
            )),
            Some(rate) if (MIN_KEY_RATE..=f64::from(*FRAME_RATE_RANGE.end())).contains(&rate) => Ok(rate),
            _ => Ok(FALLBACK_FPS),
        }
    };
    let fps = match selection.frame_rate {
        Some(fps) => fps,
        None => own_rate()?,
    };
    let (t0, frames) = match key_range(&channels) {
        None => (0.0, 1usize),
        Some((t0, t1)) => {
            // The small epsilon keeps a key that falls on a frame boundary (1.5 s × 30 fps) in,
            // also when the f32 key time lies a rounding error short of it (39 / 30 s as f32 is
            // 38.9999986 frames; f32 time errors are ≈ 6e-8 relative, far below 1e-4 frames).
            let frames_f = ((t1 - t0) * fps + 1e-4).floor() + 1.0;
            if frames_f > limits.max_frames as f64 {
                return Err(limit(file, "frame_count", frames_f as usize, limits.max_frames));
            }
            // An animation whose keys span less than one frame at the file's own rate would
            // play as a still (keys microseconds apart): say so rather than lose the motion.
            if frames_f < 2.0 && t1 > t0 && selection.frame_rate.is_none() {
                return Err(bad(
                    file,
                    "animation.input",
                    format!(
                        "the keys span {:.6e} s, less than one frame at {fps} fps: give a frame rate (--fps) to \
                         sample it",
                        t1 - t0
                    ),
                ));
            }
            (t0, frames_f as usize)
        }
    };
    // Everything the playback holds: the positions, the triangles (twice: ours and the
    // animation's topology), and per vertex the f64 morph scratch.
    let positions_bytes = (frames as u64).saturating_mul(vertex_count as u64).saturating_mul(12);
    budget.take("the baked positions (frames × vertices × 12 bytes)", positions_bytes)?;
    if selection.working_copies > 0 {
        // What the command will hold of them, counted now: a small file with many instances
        // must be refused before the command makes its working copies.
        budget.take(
            &format!(
                "the {} copies of the positions a command works on after the read ({} bytes each)",
                selection.working_copies, positions_bytes
            ),
            positions_bytes.saturating_mul(selection.working_copies),
        )?;
    }
    budget.take("the triangles", (triangle_count as u64) * 24)?;
    budget.take("the playback scratch", (vertex_count as u64) * 24)?;
    limits.check_alloc("gltf", "positions", positions_bytes)?;
    // The CPU work is bounded too (the output size alone does not bound it: many nodes or
    // targets cost work every frame): one unit per node transform, channel sample, joint matrix
    // and per vertex per morph target or skin influence.
    let per_frame = instances.iter().fold(nodes.len().saturating_add(channels.len()), |sum, instance| {
        let data = meshes[instance.mesh].as_ref().expect("loaded");
        let joints = instance.skin.and_then(|s| skins[s].as_ref()).map_or(0, |skin| skin.joints.len());
        let per_vertex = 1 + data.targets.len() + data.influences;
        sum.saturating_add(data.vertex_count().saturating_mul(per_vertex)).saturating_add(joints)
    });
    let work = frames.saturating_mul(per_frame);
    if work > MAX_BAKE_WORK {
        return Err(limit(
            file,
            "playback work (frames × (nodes + channels + joints + vertices × (1 + targets + influences)))",
            work,
            MAX_BAKE_WORK,
        ));
    }
    let mut triangles: Vec<[u32; 3]> = Vec::with_capacity(triangle_count);
    for instance in &instances {
        let o = instance.offset as u32;
        let data = meshes[instance.mesh].as_ref().expect("loaded");
        triangles.extend(data.triangles.iter().map(|t| [t[0] + o, t[1] + o, t[2] + o]));
    }
    let mut positions: Vec<f32> = Vec::with_capacity(frames * vertex_count * 3);
    let rest: Vec<Local> = nodes.iter().map(rest_transform).collect();
    let mut local = rest.clone();
    let mut world = vec![IDENTITY; nodes.len()];
    let mut node_weights: Vec<Option<Vec<f64>>> = vec![None; nodes.len()];
    let mut sample = vec![0.0; channels.iter().map(|c| c.track.width).max().unwrap_or(0)];
    let mut morphed: Vec<f64> = Vec::new();
    for k in 0..frames {
        let t = t0 + k as f64 / fps;
        local.copy_from_slice(&rest);
        for c in &channels {
            c.track.sample(t, &mut sample);
            match (&mut local[c.node], c.property) {
                (Local::Trs { t, .. }, Property::Translation) => t.copy_from_slice(&sample[..3]),
                (Local::Trs { r, .. }, Property::Rotation) => r.copy_from_slice(&sample[..4]),
                (Local::Trs { s, .. }, Property::Scale) => s.copy_from_slice(&sample[..3]),
                (_, Property::MorphTargetWeights) => node_weights[c.node] = Some(sample[..c.track.width].to_vec()),
                (Local::Matrix(_), _) => unreachable!("checked by load_channels"),
            }
        }
        for &n in &hierarchy.order {
            let m = match local[n] {
                Local::Trs { t, r, s } => gltf_anim::from_trs(t, r, s),
                Local::Matrix(m) => m,
            };
            world[n] = match hierarchy.parent[n] {
                Some(p) => gltf_anim::mul(&world[p], &m),
                None => m,
            };
        }
        for instance in &instances {
            let data = meshes[instance.mesh].as_ref().expect("loaded");
            debug_assert_eq!(positions.len(), (k * vertex_count + instance.offset) * 3);
            // Morph first (spec §3.7.2.2 "Morph Targets"), then skin or place the node.
            let weights = node_weights[instance.node].as_deref().unwrap_or(&instance.weights);
            morphed.clear();
            morphed.extend(data.base.iter().map(|&x| x as f64));
            for (target, &w) in data.targets.iter().zip(weights) {
                if w != 0.0 {
                    for (p, &d) in morphed.iter_mut().zip(target) {
                        *p += w * d as f64;
                    }
                }
            }
            match instance.skin {
                None => {
                    for p in morphed.chunks_exact(3) {
                        let q = gltf_anim::transform_point(&world[instance.node], [p[0], p[1], p[2]]);
                        positions.extend(q.map(|x| x as f32));
                    }
                }
                Some(s) => {
                    // Spec §3.7.3 "Skins": joint matrix = world(joint) × inverse bind matrix;
                    // the skinned mesh node's own transform is not applied.
                    let skin = skins[s].as_ref().expect("loaded");
                    let joint_matrices: Vec<Mat4> = skin
                        .joints
                        .iter()
                        .zip(&skin.inverse_bind)
                        .map(|(&j, ibm)| gltf_anim::mul(&world[j], ibm))
                        .collect();
                    let per = data.influences;
                    for (v, p) in morphed.chunks_exact(3).enumerate() {
                        let p = [p[0], p[1], p[2]];
                        let mut q = [0.0f64; 3];
                        let mut total = 0.0;
                        for i in v * per..(v + 1) * per {
                            let w = data.weights[i] as f64;
                            if w > 0.0 {
                                let moved = gltf_anim::transform_point(&joint_matrices[data.joints[i] as usize], p);
                                (0..3).for_each(|a| q[a] += w * moved[a]);
                                total += w;
                            }
                        }
                        // A vertex with no weight stays where its node puts it.
                        let q = if total > 0.0 { q } else { gltf_anim::transform_point(&world[instance.node], p) };
                        positions.extend(q.map(|x| x as f32));
                    }
                }
            }
        }
    }
    Animation::from_parts(vertex_count, triangles, positions, fps as f32).map_err(|e| in_file(file, e))
}
