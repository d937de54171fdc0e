//! Alembic's geometry schemas (`lib/Alembic/AbcGeom`): which objects are meshes, their
//! topology and points, the transform hierarchy, and how they become one [`Animation`].
//!
//! - **PolyMesh** (`schema=AbcGeom_PolyMesh_v1`) and **SubD** (`AbcGeom_SubD_v1`, read as its
//!   control mesh): the compound `.geom` holds `P` (`f32`×3 points), `.faceCounts` and
//!   `.faceIndices` (`i32`). Alembic faces wind clockwise; they are fanned from their first
//!   corner as OBJ polygons are and each triangle is flipped, so the triangles wind
//!   counter-clockwise like every other reader's.
//! - **Xform** (`AbcGeom_Xform_v3`): the compound `.xform` holds `.ops` (one `u8` per operation,
//!   `type << 4 | hint`), `.vals` (the operations' channels, `f64`) and `.inherits` (`bool`,
//!   default true). Operations compose as `AbcGeom::XformSample::getMatrix` does, with Imath's
//!   row vectors (`p' = p·M`): `M = op·M` for each op in order; an object's world matrix is
//!   `local·parentWorld` unless it does not inherit.
//! - At each frame time every sampled property is read at its floor sample (the last sample at
//!   or before that time; the first before it), as `ISampleSelector(t, kFloorIndex)` reads it.

use std::collections::HashSet;

use codec_core::{Animation, Error, Result, SceneMetadata};

use super::core::{meta_get, Archive, Compound, Pod, PropHeader, PropKind, TimeSampling};
use super::ogawa::Group;
use super::{Meter, MAX_DEPTH};
use crate::formats::{check_finite_in, in_file, reader_limits};

/// A 4×4 matrix, row-major, for row vectors.
type M44 = [[f64; 4]; 4];

const IDENTITY: M44 = [[1., 0., 0., 0.], [0., 1., 0., 0.], [0., 0., 1., 0.], [0., 0., 0., 1.]];

/// One mesh object found in the archive.
#[derive(Debug, Clone, PartialEq)]
pub struct AbcMesh {
    /// Full object path, e.g. `/cube/cubeShape`: what `--object` selects.
    pub path: String,
    /// `PolyMesh` or `SubD`.
    pub schema: &'static str,
    /// Points per sample.
    pub vertices: usize,
    /// Polygons.
    pub faces: usize,
    /// Triangles after fanning the polygons.
    pub triangles: usize,
    /// Samples of `P`.
    pub samples: u32,
    /// Time of the first and last sample of `P` (seconds).
    pub start: f64,
    /// See [`AbcMesh::start`].
    pub end: f64,
}

/// A transform operation's type (`XformOperationType`).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Op {
    Scale,
    Translate,
    Rotate,
    Matrix,
    RotateX,
    RotateY,
    RotateZ,
}

impl Op {
    fn channels(self) -> usize {
        match self {
            Op::Scale | Op::Translate => 3,
            Op::Rotate => 4,
            Op::Matrix => 16,
            Op::RotateX | Op::RotateY | Op::RotateZ => 1,
        }
    }

    /// The value a channel has when `.vals` does not give it (`XformOp::getDefaultChannelValue`).
    fn default_channel(self, k: usize) -> f64 {
        match self {
            Op::Scale => 1.0,
            Op::Matrix if k.is_multiple_of(5) => 1.0,
            _ => 0.0,
        }
    }
}

/// An Xform object's `.xform` schema.
struct Xform {
    path: String,
    compound: Compound,
    ops: Vec<Op>,
    /// `.vals` (index in the compound) and whether it is an array property.
    vals: Option<u64>,
    inherits: Option<u64>,
}

/// A mesh object: where its schema's properties are, and its ancestors' transforms.
struct MeshRef {
    path: String,
    schema: &'static str,
    geom: Compound,
    p: u64,
    counts: u64,
    indices: u64,
    /// Indices into the Xform list, from the root down.
    chain: Vec<usize>,
}

/// Everything the traversal found.
struct Scene {
    xforms: Vec<Xform>,
    meshes: Vec<MeshRef>,
}

fn child_path(parent: &str, name: &str) -> String {
    if parent == "/" {
        format!("/{name}")
    } else {
        format!("{parent}/{name}")
    }
}

/// Walks the object hierarchy from the top object (depth-first, in stored order).
fn traverse(ar: &Archive, meter: &mut Meter) -> Result<Scene> {
    let mut scene = Scene { xforms: Vec::new(), meshes: Vec::new() };
    let mut groups = vec![ar.top.offset];
    let mut chain = Vec::new();
    walk(ar, ar.top, "/", "", &mut groups, &mut chain, &mut scene, meter)?;
    Ok(scene)
}

#[allow(clippy::too_many_arguments)]
fn walk(
    ar: &Archive,
    group: Group,
    path: &str,
    metadata: &str,
    groups: &mut Vec<u64>,
    chain: &mut Vec<usize>,
    scene: &mut Scene,
    meter: &mut Meter,
) -> Result<()> {
    let object = ar.object(group, path, meter)?;
    let schema = meta_get(metadata, "schema").unwrap_or("");
    let mut pushed = false;
    if path != "/" {
        match schema {
            "AbcGeom_Xform_v3" | "AbcGeom_Xform_v2" | "AbcGeom_Xform_v1" => {
                let props = ar.properties(&object, path, meter)?;
                if let Some((i, h)) = props.find(".xform") {
                    if h.kind == PropKind::Compound {
                        let compound = ar.sub_compound(&props, i, path, meter)?;
                        let x = xform(ar, path, compound)?;
                        scene.xforms.push(x);
                        chain.push(scene.xforms.len() - 1);
                        pushed = true;
                    }
                }
            }
            "AbcGeom_PolyMesh_v1" | "AbcGeom_SubD_v1" => {
                let props = ar.properties(&object, path, meter)?;
                if let Some((i, h)) = props.find(".geom") {
                    if h.kind == PropKind::Compound {
                        let geom = ar.sub_compound(&props, i, path, meter)?;
                        let kind = if schema == "AbcGeom_SubD_v1" { "SubD" } else { "PolyMesh" };
                        let m = mesh_ref(ar, path, kind, geom, chain.clone())?;
                        meter.take("mesh paths", path.len() as u64 + 64)?;
                        scene.meshes.push(m);
                    }
                }
            }
            _ => {}
        }
    }
    for (i, child) in object.children.iter().enumerate() {
        let sub = child_path(path, &child.name);
        let g = ar.child_object_group(&object, i, &sub)?;
        if g.offset != 0 && groups.contains(&g.offset) {
            return Err(ar.og.bad("objects", format!("{sub}: the object contains itself (a cycle of groups)")));
        }
        if groups.len() >= MAX_DEPTH {
            return Err(ar.og.bad("objects", format!("{sub}: objects nested deeper than {MAX_DEPTH} levels")));
        }
        groups.push(g.offset);
        walk(ar, g, &sub, &child.metadata, groups, chain, scene, meter)?;
        groups.pop();
    }
    if pushed {
        chain.pop();
    }
    Ok(())
}

fn xform(ar: &Archive, path: &str, compound: Compound) -> Result<Xform> {
    let bad = |detail: String| ar.og.bad(".xform", format!("{path}: {detail}"));
    let mut ops = Vec::new();
    if let Some((i, h)) = compound.find(".ops") {
        if h.kind != PropKind::Scalar || h.pod != Pod::U8 {
            return Err(bad("`.ops` is not a scalar of bytes".into()));
        }
        if h.count > 0 {
            let (_, bytes) = ar.sample(&compound, i, 0, &format!("{path}/.xform/.ops"))?;
            for &b in bytes {
                ops.push(match b >> 4 {
                    0 => Op::Scale,
                    1 => Op::Translate,
                    2 => Op::Rotate,
                    3 => Op::Matrix,
                    4 => Op::RotateX,
                    5 => Op::RotateY,
                    6 => Op::RotateZ,
                    t => return Err(bad(format!("unknown transform operation type {t}"))),
                });
            }
        }
    }
    let vals = match compound.find(".vals") {
        Some((i, h)) if h.pod == Pod::F64 && h.kind != PropKind::Compound => Some(i),
        Some(_) => return Err(bad("`.vals` is not of doubles".into())),
        None => None,
    };
    let inherits = match compound.find(".inherits") {
        Some((i, h)) if h.pod == Pod::Bool && h.kind == PropKind::Scalar => Some(i),
        Some(_) => return Err(bad("`.inherits` is not a scalar bool".into())),
        None => None,
    };
    Ok(Xform { path: path.to_owned(), compound, ops, vals, inherits })
}

fn mesh_ref(ar: &Archive, path: &str, schema: &'static str, geom: Compound, chain: Vec<usize>) -> Result<MeshRef> {
    let find = |name: &str, pod: Pod, extent: u8| -> Result<u64> {
        match geom.find(name) {
            Some((i, h)) if h.kind == PropKind::Array && h.pod == pod && h.extent == extent => Ok(i),
            Some((_, h)) => Err(ar.og.bad(
                ".geom",
                format!(
                    "{path}: `{name}` is a {:?} of {:?}×{}, an array of {pod:?}×{extent} was expected",
                    h.kind, h.pod, h.extent
                ),
            )),
            None => Err(ar.og.bad(".geom", format!("{path}: the {schema} has no `{name}`"))),
        }
    };
    let p = find("P", Pod::F32, 3)?;
    let counts = find(".faceCounts", Pod::I32, 1)?;
    let indices = find(".faceIndices", Pod::I32, 1)?;
    Ok(MeshRef { path: path.to_owned(), schema, geom, p, counts, indices, chain })
}

/// The largest sample index at or before time `t` (0 before the first sample).
fn floor_index(ts: &TimeSampling, count: u32, t: f64) -> u32 {
    if count <= 1 {
        return 0;
    }
    let eps = 1e-9 * t.abs().max(1.0);
    let at = |i: u32| ts.time(u64::from(i)).unwrap_or(f64::INFINITY);
    if at(0) > t + eps {
        return 0;
    }
    let (mut lo, mut hi) = (0u32, count - 1);
    while lo < hi {
        let mid = lo + (hi - lo).div_ceil(2);
        if at(mid) <= t + eps {
            lo = mid;
        } else {
            hi = mid - 1;
        }
    }
    lo
}

/// The sampling of a property, and its sample times checked to exist.
fn sampling<'a>(ar: &'a Archive, h: &PropHeader, what: &str) -> Result<&'a TimeSampling> {
    let ts = &ar.time_samplings[h.time_sampling as usize];
    if ts.is_acyclic() && h.count as usize > ts.times.len() {
        return Err(ar.og.bad(
            "time samplings",
            format!("{what}: {} samples but its acyclic time sampling lists {} times", h.count, ts.times.len()),
        ));
    }
    Ok(ts)
}

fn i32s(bytes: &[u8]) -> impl Iterator<Item = i32> + '_ {
    bytes.chunks_exact(4).map(|b| i32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// A mesh's topology from sample 0: vertex count, polygon count and fanned triangles.
struct Topo {
    vertices: usize,
    faces: usize,
    triangles: Vec<[u32; 3]>,
}

fn topology(ar: &Archive, m: &MeshRef, meter: &mut Meter) -> Result<Topo> {
    let ph = &m.geom.props[m.p as usize];
    if ph.count == 0 {
        return Err(ar.og.bad("P", format!("{}: `P` has no samples", m.path)));
    }
    let (_, p0) = ar.sample(&m.geom, m.p, 0, &format!("{}/P", m.path))?;
    let vertices = p0.len() / 12;
    let limits = reader_limits();
    if vertices > limits.max_vertices {
        return Err(Error::LimitExceeded {
            context: ar.og.file().to_owned().into(),
            field: format!("{}: vertex count", m.path).into(),
            value: vertices as u64,
            limit: limits.max_vertices as u64,
        });
    }
    if m.geom.props[m.counts as usize].count == 0 || m.geom.props[m.indices as usize].count == 0 {
        return Err(ar.og.bad(".geom", format!("{}: no face samples", m.path)));
    }
    let (_, counts) = ar.sample(&m.geom, m.counts, 0, &format!("{}/.faceCounts", m.path))?;
    let (_, indices) = ar.sample(&m.geom, m.indices, 0, &format!("{}/.faceIndices", m.path))?;
    meter.work("faces", (counts.len() + indices.len()) as u64)?;
    let mut corners_total = 0u64;
    let mut fan = 0u64;
    for (f, c) in i32s(counts).enumerate() {
        if c < 3 {
            return Err(ar
                .og
                .bad(".faceCounts", format!("{}: face {f} has {c} corners (at least 3 are needed)", m.path)));
        }
        corners_total += c as u64;
        fan += c as u64 - 2;
    }
    if corners_total != (indices.len() / 4) as u64 {
        return Err(ar.og.bad(
            ".faceCounts",
            format!(
                "{}: the faces have {corners_total} corners but `.faceIndices` holds {}",
                m.path,
                indices.len() / 4
            ),
        ));
    }
    if fan > limits.max_triangles as u64 {
        return Err(Error::LimitExceeded {
            context: ar.og.file().to_owned().into(),
            field: format!("{}: triangle count", m.path).into(),
            value: fan,
            limit: limits.max_triangles as u64,
        });
    }
    meter.take("triangles", fan * 12)?;
    let mut triangles = Vec::with_capacity(fan as usize);
    let mut corners = Vec::new();
    let mut at = 0usize;
    for c in i32s(counts) {
        corners.clear();
        for i in i32s(&indices[at * 4..(at + c as usize) * 4]) {
            if i < 0 || i as usize >= vertices {
                return Err(ar
                    .og
                    .bad(".faceIndices", format!("{}: index {i} is out of range ({vertices} points)", m.path)));
            }
            corners.push(i as u32);
        }
        at += c as usize;
        let start = triangles.len();
        crate::formats::obj::push_fan(&corners, &mut triangles);
        // Clockwise (Alembic) to counter-clockwise.
        for t in &mut triangles[start..] {
            t.swap(1, 2);
        }
    }
    Ok(Topo { vertices, faces: counts.len() / 4, triangles })
}

/// Checks that the topology and the point count never change: every stored sample of
/// `.faceCounts` / `.faceIndices` equals sample 0's, every sample of `P` holds as many points.
/// `frame_of` names the frame of a sample time in errors.
fn check_constant(
    ar: &Archive,
    m: &MeshRef,
    vertices: usize,
    meter: &mut Meter,
    frame_of: &dyn Fn(f64) -> String,
) -> Result<()> {
    for (prop, name) in [(m.counts, ".faceCounts"), (m.indices, ".faceIndices")] {
        let h = &m.geom.props[prop as usize];
        let what = format!("{}/{name}", m.path);
        let (at0, first) = ar.sample(&m.geom, prop, 0, &what)?;
        if h.is_constant() {
            continue;
        }
        let ts = sampling(ar, h, &what)?;
        let mut seen = HashSet::from([at0]);
        // Stored slots 1..=last-first+1; the first sample stored in slot s is first+s-1.
        let slots = h.last_changed - h.first_changed + 1;
        for s in 1..=slots {
            let i = h.first_changed + s - 1;
            let (at, bytes) = ar.sample(&m.geom, prop, i, &what)?;
            if !seen.insert(at) {
                continue;
            }
            meter.work("topology comparison", bytes.len() as u64)?;
            if bytes != first {
                let t = ts.time(u64::from(i)).unwrap_or(f64::NAN);
                return Err(Error::Unsupported {
                    context: ar.og.file().to_owned().into(),
                    detail: format!(
                        "{}: the topology changes at {} (`{name}` sample {i}): a vertex cache needs one topology",
                        m.path,
                        frame_of(t)
                    ),
                });
            }
        }
    }
    let h = &m.geom.props[m.p as usize];
    let ts = sampling(ar, h, &format!("{}/P", m.path))?;
    let mut seen = HashSet::new();
    let slots = if h.is_constant() { 0 } else { h.last_changed - h.first_changed + 1 };
    for s in 0..=slots {
        let i = if s == 0 { 0 } else { h.first_changed + s - 1 };
        let (at, bytes) = ar.sample(&m.geom, m.p, i, &format!("{}/P", m.path))?;
        if seen.insert(at) && bytes.len() != vertices * 12 {
            let t = ts.time(u64::from(i)).unwrap_or(f64::NAN);
            return Err(Error::Unsupported {
                context: ar.og.file().to_owned().into(),
                detail: format!(
                    "{}: the point count changes at {} ({} points instead of {vertices}): a vertex cache needs one \
                     topology",
                    m.path,
                    frame_of(t),
                    bytes.len() / 12
                ),
            });
        }
    }
    Ok(())
}

fn mul(a: &M44, b: &M44) -> M44 {
    let mut r = [[0.0; 4]; 4];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j] + a[i][3] * b[3][j];
        }
    }
    r
}

/// Imath's `Matrix44::setAxisAngle` (row vectors): a rotation by `angle` radians about `axis`.
fn axis_angle(axis: [f64; 3], angle: f64) -> M44 {
    let len = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    let [x, y, z] = if len > 0.0 { [axis[0] / len, axis[1] / len, axis[2] / len] } else { [0.0; 3] };
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    [
        [x * x * t + c, x * y * t + z * s, x * z * t - y * s, 0.0],
        [x * y * t - z * s, y * y * t + c, y * z * t + x * s, 0.0],
        [x * z * t + y * s, y * z * t - x * s, z * z * t + c, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// An Xform's local matrix and `inherits` flag at time `t`.
fn local(ar: &Archive, x: &Xform, t: f64, meter: &mut Meter) -> Result<(M44, bool)> {
    let mut inherits = true;
    if let Some(i) = x.inherits {
        let h = &x.compound.props[i as usize];
        if h.count > 0 {
            let what = format!("{}/.xform/.inherits", x.path);
            let ts = sampling(ar, h, &what)?;
            let (_, b) = ar.sample(&x.compound, i, floor_index(ts, h.count, t), &what)?;
            inherits = b.first().is_none_or(|&v| v != 0);
        }
    }
    let channels: usize = x.ops.iter().map(|o| o.channels()).sum();
    let mut vals = Vec::with_capacity(channels);
    if let Some(i) = x.vals {
        let h = &x.compound.props[i as usize];
        if h.count > 0 {
            let what = format!("{}/.xform/.vals", x.path);
            let ts = sampling(ar, h, &what)?;
            let (_, b) = ar.sample(&x.compound, i, floor_index(ts, h.count, t), &what)?;
            meter.work("transforms", b.len() as u64 + 64)?;
            vals.extend(b.chunks_exact(8).take(channels).map(super::core::f64_le));
        }
    }
    let mut m = IDENTITY;
    let mut k = 0usize;
    for &op in &x.ops {
        let n = op.channels();
        let ch = |j: usize| vals.get(k + j).copied().unwrap_or_else(|| op.default_channel(j));
        let deg = |a: f64| a.to_radians();
        let l = match op {
            Op::Matrix => {
                let mut r = [[0.0; 4]; 4];
                for (j, row) in r.iter_mut().enumerate() {
                    for (c, v) in row.iter_mut().enumerate() {
                        *v = ch(4 * j + c);
                    }
                }
                r
            }
            Op::RotateX => axis_angle([1., 0., 0.], deg(ch(0))),
            Op::RotateY => axis_angle([0., 1., 0.], deg(ch(0))),
            Op::RotateZ => axis_angle([0., 0., 1.], deg(ch(0))),
            Op::Scale => {
                let mut r = IDENTITY;
                (r[0][0], r[1][1], r[2][2]) = (ch(0), ch(1), ch(2));
                r
            }
            Op::Translate => {
                let mut r = IDENTITY;
                (r[3][0], r[3][1], r[3][2]) = (ch(0), ch(1), ch(2));
                r
            }
            Op::Rotate => axis_angle([ch(0), ch(1), ch(2)], deg(ch(3))),
        };
        m = mul(&l, &m);
        k += n;
    }
    Ok((m, inherits))
}

/// True when an Xform changes over time.
fn xform_animated(x: &Xform) -> bool {
    [x.vals, x.inherits].into_iter().flatten().any(|i| !x.compound.props[i as usize].is_constant())
}

/// Every mesh of the archive, with sizes and sample counts.
pub(super) fn list(ar: &Archive, meter: &mut Meter) -> Result<Vec<AbcMesh>> {
    let scene = traverse(ar, meter)?;
    let mut out = Vec::new();
    for m in &scene.meshes {
        let topo = topology(ar, m, meter)?;
        let h = &m.geom.props[m.p as usize];
        let ts = sampling(ar, h, &m.path)?;
        out.push(AbcMesh {
            path: m.path.clone(),
            schema: m.schema,
            vertices: topo.vertices,
            faces: topo.faces,
            triangles: topo.triangles.len(),
            samples: h.count,
            start: ts.time(0).unwrap_or(0.0),
            end: ts.time(u64::from(h.count.saturating_sub(1))).unwrap_or(0.0),
        });
    }
    Ok(out)
}

/// Reads the selected meshes (all when `object` is `None`) as one animation.
pub(super) fn assemble(
    ar: &Archive,
    object: Option<&str>,
    frame_rate: Option<f32>,
    meter: &mut Meter,
) -> Result<Animation> {
    let file = ar.og.file();
    let scene = traverse(ar, meter)?;
    if scene.meshes.is_empty() {
        return Err(ar.og.bad("objects", "the archive holds no PolyMesh or SubD object"));
    }
    let selected: Vec<&MeshRef> = match object {
        None => scene.meshes.iter().collect(),
        Some(sel) => {
            let sel = sel.trim_end_matches('/');
            let chosen: Vec<&MeshRef> = scene
                .meshes
                .iter()
                .filter(|m| sel.is_empty() || m.path == sel || m.path.starts_with(&format!("{sel}/")))
                .collect();
            if chosen.is_empty() {
                let names: Vec<&str> = scene.meshes.iter().take(20).map(|m| m.path.as_str()).collect();
                return Err(Error::InvalidAnimation(format!(
                    "{file}: no mesh object at or under {sel:?}; the meshes are: {}{}",
                    names.join(", "),
                    if scene.meshes.len() > 20 { ", …" } else { "" }
                )));
            }
            chosen
        }
    };
    let limits = reader_limits();
    // Frame times: every sample of each mesh's P and of its animated ancestors.
    let mut times: Vec<f64> = Vec::new();
    let mut add = |ts: &TimeSampling, count: u32, what: &str, meter: &mut Meter| -> Result<()> {
        if count as usize > limits.max_frames {
            return Err(Error::LimitExceeded {
                context: file.to_owned().into(),
                field: format!("{what}: sample count").into(),
                value: u64::from(count),
                limit: limits.max_frames as u64,
            });
        }
        meter.take("frame times", u64::from(count) * 8)?;
        times.extend((0..count).map(|i| ts.time(u64::from(i)).unwrap_or(f64::NAN)));
        Ok(())
    };
    let mut animated_xforms = HashSet::new();
    for m in &selected {
        let h = &m.geom.props[m.p as usize];
        let what = format!("{}/P", m.path);
        add(sampling(ar, h, &what)?, h.count, &what, meter)?;
        for &x in &m.chain {
            let xf = &scene.xforms[x];
            if xform_animated(xf) && animated_xforms.insert(x) {
                for i in [xf.vals, xf.inherits].into_iter().flatten() {
                    let h = &xf.compound.props[i as usize];
                    let what = format!("{}/.xform/{}", xf.path, h.name);
                    if !h.is_constant() {
                        add(sampling(ar, h, &what)?, h.count, &what, meter)?;
                    }
                }
            }
        }
    }
    times.sort_by(f64::total_cmp);
    times.dedup_by(|b, a| (*b - *a).abs() <= 1e-9 * a.abs().max(1.0));
    if times.len() > limits.max_frames {
        return Err(Error::LimitExceeded {
            context: file.to_owned().into(),
            field: "frame_count".into(),
            value: times.len() as u64,
            limit: limits.max_frames as u64,
        });
    }
    let step = match times.len() {
        0 | 1 => None,
        n => Some((times[n - 1] - times[0]) / (n - 1) as f64),
    };
    if let Some(step) = step {
        for w in times.windows(2) {
            if ((w[1] - w[0]) - step).abs() > step * 1e-5 {
                return Err(Error::Unsupported {
                    context: file.to_owned().into(),
                    detail: format!(
                        "the samples are not evenly spaced in time ({} s and {} s against a mean step of {step} s): a \
                         vertex cache has one frame rate; resample the archive",
                        w[0], w[1]
                    ),
                });
            }
        }
    }
    let frame_of = |t: f64| match times.iter().position(|&x| (x - t).abs() <= 1e-9 * t.abs().max(1.0)) {
        Some(f) => format!("frame {f} ({t} s)"),
        None => format!("time {t} s"),
    };
    let mut topos = Vec::with_capacity(selected.len());
    let mut vertices = 0usize;
    for m in &selected {
        let topo = topology(ar, m, meter)?;
        check_constant(ar, m, topo.vertices, meter, &frame_of)?;
        vertices += topo.vertices;
        topos.push(topo);
    }
    if vertices == 0 {
        return Err(ar.og.bad("P", "the meshes have no points"));
    }
    if vertices > limits.max_vertices {
        return Err(Error::LimitExceeded {
            context: file.to_owned().into(),
            field: "vertex_count".into(),
            value: vertices as u64,
            limit: limits.max_vertices as u64,
        });
    }
    let frames = times.len().max(1);
    let floats = (vertices as u64) * 3 * frames as u64;
    limits.check_alloc("formats", "positions", floats * 4)?;
    meter.take("positions", floats * 4)?;
    meter.work("positions", floats)?;
    let mut positions: Vec<f32> = Vec::with_capacity(floats as usize);
    for f in 0..frames {
        let t = times.get(f).copied().unwrap_or(0.0);
        for m in &selected {
            let h = &m.geom.props[m.p as usize];
            let what = format!("{}/P", m.path);
            let ts = sampling(ar, h, &what)?;
            let (_, p) = ar.sample(&m.geom, m.p, floor_index(ts, h.count, t), &what)?;
            let points = p.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]));
            let mut world: Option<M44> = None;
            for &x in &m.chain {
                let (l, inherits) = local(ar, &scene.xforms[x], t, meter)?;
                world = Some(match (world, inherits) {
                    (Some(parent), true) => mul(&l, &parent),
                    _ => l,
                });
            }
            match world.filter(|w| *w != IDENTITY) {
                None => positions.extend(points),
                Some(w) => {
                    let mut xyz = [0f64; 3];
                    for (k, v) in points.enumerate() {
                        xyz[k % 3] = f64::from(v);
                        if k % 3 == 2 {
                            let [x, y, z] = xyz;
                            let row = |c: usize| x * w[0][c] + y * w[1][c] + z * w[2][c] + w[3][c];
                            let wh = row(3);
                            let s = if wh != 0.0 && wh != 1.0 { 1.0 / wh } else { 1.0 };
                            positions.extend([(row(0) * s) as f32, (row(1) * s) as f32, (row(2) * s) as f32]);
                        }
                    }
                }
            }
        }
    }
    let mut triangles = Vec::with_capacity(topos.iter().map(|t| t.triangles.len()).sum());
    let mut offset = 0u32;
    for t in &topos {
        triangles.extend(t.triangles.iter().map(|tri| tri.map(|i| i + offset)));
        offset += t.vertices as u32;
    }
    check_finite_in(file, &positions, vertices)?;
    let fps = match (frame_rate, step) {
        (Some(f), _) => f,
        (None, Some(step)) => crate::formats::check_frame_rate((1.0 / step) as f32).map_err(|e| in_file(file, e))?,
        (None, None) => meta_get(&ar.metadata, "FramesPerTimeUnit")
            .and_then(|v| v.parse::<f32>().ok())
            .filter(|f| crate::formats::FRAME_RATE_RANGE.contains(f))
            .unwrap_or(crate::formats::DEFAULT_FRAME_RATE),
    };
    // Alembic states no up axis or unit; its time line starts where the first sample is.
    let start = times.first().copied().filter(|t| *t != 0.0);
    let metadata = SceneMetadata { start_time_code: start.map(|t| t * f64::from(fps)), ..Default::default() };
    Animation::from_parts(vertices, triangles, positions, fps)
        .and_then(|a| a.with_metadata(metadata))
        .map_err(|e| in_file(file, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_indices_hold_before_and_after() {
        let ts = TimeSampling { time_per_cycle: 0.5, times: vec![1.0], max_samples: 0 };
        assert_eq!(floor_index(&ts, 4, 0.0), 0);
        assert_eq!(floor_index(&ts, 4, 1.0), 0);
        assert_eq!(floor_index(&ts, 4, 1.49), 0);
        assert_eq!(floor_index(&ts, 4, 1.5), 1);
        assert_eq!(floor_index(&ts, 4, 2.5), 3);
        assert_eq!(floor_index(&ts, 4, 99.0), 3);
    }

    #[test]
    fn rotations_follow_imath() {
        // 90° about Z takes x to y with row vectors.
        let r = axis_angle([0., 0., 1.], std::f64::consts::FRAC_PI_2);
        let p = [1.0, 0.0, 0.0];
        let out: Vec<f64> = (0..3).map(|c| p[0] * r[0][c] + p[1] * r[1][c] + p[2] * r[2][c]).collect();
        assert!((out[0]).abs() < 1e-12 && (out[1] - 1.0).abs() < 1e-12);
    }
}
