//! glTF 2.0 / GLB morph-target animations, read with the `gltf` crate.
//!
//! Choices (all documented here so callers know what they get):
//! - **Mesh**: the first mesh that has morph targets, else the first mesh. All its primitives are
//!   concatenated in order into one vertex list (primitive `k`'s indices are offset by the vertex
//!   counts of primitives `0..k`). Only `TRIANGLES` primitives are accepted; a primitive without
//!   indices is a plain triangle list.
//! - **Space**: positions stay in mesh space: no node or scene transform is applied (the
//!   compression codecs do not care, and skinning/node animation are out of scope).
//! - **Animation**: the first animation (in file order) with a `weights` channel targeting a node
//!   that uses the chosen mesh. It is sampled at the frame rate (default 30 fps) from its first
//!   to its last key time: `floor(duration × fps) + 1` frames at `t₀ + k / fps`. Interpolation:
//!   `STEP`, `LINEAR`, and `CUBICSPLINE` evaluated with the glTF Hermite formula (spec §3.11,
//!   "Interpolation"), not just its value component.
//! - **Frame** = base + Σᵢ wᵢ(t) · targetᵢ (morph target `POSITION` displacements; a target
//!   without positions displaces nothing), summed in target order in `f32`.
//! - **No such animation**: a single frame with the node's `weights`, else the mesh's default
//!   `weights`, else the base mesh.
//! - Images are never loaded (only buffers), so textures in unsupported formats do not matter.
//! - **Buffers** are loaded here, not by `gltf::import_buffers`: the crate's `import` feature
//!   also compiles an image decoder this reader never uses, and its loader panics on a
//!   malformed percent-encoded URI. Supported: the GLB `BIN` chunk, `data:` URIs in base64, and
//!   relative or `file:` paths (only with a `base` directory). Each buffer must hold at least its
//!   declared `byteLength`; the declared length is checked against [`Limits`] before reading.
//!
//! Every accessor is checked (type, component type, count, range) before the `gltf` reader is
//! used, because the reader panics on some invalid combinations; as a last line of defence the
//! whole parse runs under `catch_unwind` and a panic inside the crate becomes an error.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::animation::{Interpolation, Property};
use ::gltf::mesh::Mode;
use ::gltf::{Accessor, Semantic};
use base64::Engine as _;
use codec_core::{Animation, Error, Limits, Result};

use super::{in_file, name, read_file};

/// Reads the morph-target animation of a `.gltf` or `.glb` file, sampled at `frame_rate`.
/// External buffers of a `.gltf` are resolved relative to the file's directory.
pub fn read_gltf(path: &Path, frame_rate: f32) -> Result<Animation> {
    let bytes = read_file(path)?;
    let base = path.parent().map(|p| if p.as_os_str().is_empty() { Path::new(".") } else { p });
    parse_gltf(&bytes, base, &name(path), frame_rate)
}

/// Parses glTF JSON or GLB bytes. `base` resolves external buffer URIs (`None`: only embedded
/// and data-URI buffers work); `file` names the source in errors.
pub fn parse_gltf(bytes: &[u8], base: Option<&Path>, file: &str, frame_rate: f32) -> Result<Animation> {
    if !(frame_rate.is_finite() && frame_rate > 0.0) {
        return Err(Error::InvalidAnimation(format!("frame rate {frame_rate} is not a finite positive number")));
    }
    match catch_unwind(AssertUnwindSafe(|| parse_checked(bytes, base, file, frame_rate))) {
        Ok(result) => result,
        Err(_) => Err(Error::malformed(file.to_owned(), "gltf", "the glTF reader failed on malformed data")),
    }
}

fn bad(file: &str, field: &'static str, detail: impl Into<String>) -> Error {
    Error::malformed(file.to_owned(), field, detail)
}

/// Checks an accessor before handing it to the `gltf` reader: dimensions, component type,
/// non-zero counts (the reader computes `count - 1`), and the vertex limit. Returns the count.
fn check_accessor(
    file: &str,
    field: &'static str,
    accessor: &Accessor,
    dims: Dimensions,
    types: &[DataType],
) -> Result<usize> {
    let what = format!("accessor {}", accessor.index());
    if accessor.dimensions() != dims {
        return Err(bad(file, field, format!("{what} is {:?}, expected {dims:?}", accessor.dimensions())));
    }
    if !types.contains(&accessor.data_type()) {
        return Err(bad(
            file,
            field,
            format!("{what} has component type {:?}, expected {types:?}", accessor.data_type()),
        ));
    }
    if accessor.count() == 0 {
        return Err(bad(file, field, format!("{what} is empty")));
    }
    if accessor.sparse().is_some_and(|s| s.count() == 0) {
        return Err(bad(file, field, format!("{what} has an empty sparse block")));
    }
    let limits = Limits::default();
    if accessor.count() > limits.max_triangles * 3 {
        return Err(Error::LimitExceeded {
            context: file.to_owned().into(),
            field: field.into(),
            value: accessor.count() as u64,
            limit: (limits.max_triangles * 3) as u64,
        });
    }
    Ok(accessor.count())
}

/// Collects exactly `count` items from a reader, or fails (the reader yields fewer items when the
/// buffer view is too short for the accessor).
fn collect_exact<T>(
    file: &str,
    field: &'static str,
    iter: Option<impl Iterator<Item = T>>,
    count: usize,
) -> Result<Vec<T>> {
    let items: Vec<T> = iter.ok_or_else(|| bad(file, field, "buffer data is missing"))?.take(count).collect();
    if items.len() != count {
        return Err(bad(file, field, format!("accessor holds {} items, {count} declared", items.len())));
    }
    Ok(items)
}

/// The chosen mesh, flattened: base positions, per-target displacements, triangles.
struct MorphMesh {
    base: Vec<f32>,
    targets: Vec<Vec<f32>>,
    triangles: Vec<[u32; 3]>,
}

/// The bytes of one glTF buffer.
struct BufferData(Vec<u8>);

/// Loads every buffer of `document` (see the module docs for the sources accepted).
fn load_buffers(
    file: &str,
    document: &::gltf::Document,
    base: Option<&Path>,
    mut blob: Option<Vec<u8>>,
) -> Result<Vec<BufferData>> {
    let limits = Limits::default();
    let mut buffers = Vec::with_capacity(document.buffers().len());
    for buffer in document.buffers() {
        let index = buffer.index();
        let declared = buffer.length();
        limits.check_alloc("gltf", "buffers", declared as u64)?;
        let data = match buffer.source() {
            ::gltf::buffer::Source::Bin => blob.take().ok_or_else(|| {
                bad(file, "buffers", format!("buffer {index} refers to a GLB BIN chunk the file lacks"))
            })?,
            ::gltf::buffer::Source::Uri(uri) => read_uri(file, index, uri, base, declared, &limits)?,
        };
        if data.len() < declared {
            return Err(bad(
                file,
                "buffers",
                format!("buffer {index} holds {} bytes but declares byteLength {declared}", data.len()),
            ));
        }
        buffers.push(BufferData(data));
    }
    Ok(buffers)
}

/// Reads a buffer URI: `data:[type];base64,...`, `file:PATH`, or a percent-encoded relative path.
fn read_uri(
    file: &str,
    index: usize,
    uri: &str,
    base: Option<&Path>,
    declared: usize,
    limits: &Limits,
) -> Result<Vec<u8>> {
    let fail = |detail: String| bad(file, "buffers", format!("buffer {index}: {detail}"));
    if let Some(rest) = uri.strip_prefix("data:") {
        let payload = rest
            .split_once(";base64,")
            .map(|(_, data)| data)
            .ok_or_else(|| fail("a data URI that is not base64".into()))?;
        // Decoded size is at most 3/4 of the text; refuse before decoding a huge string.
        limits.check_alloc("gltf", "buffers", (payload.len() / 4 * 3) as u64)?;
        return base64::engine::general_purpose::STANDARD
            .decode(payload)
            .map_err(|e| fail(format!("invalid base64 in data URI ({e})")));
    }
    let path = match uri.strip_prefix("file://").or_else(|| uri.strip_prefix("file:")) {
        Some(path) => path.to_owned(),
        None if uri.contains(':') => return Err(fail(format!("unsupported URI scheme in '{uri}'"))),
        None => percent_encoding::percent_decode_str(uri)
            .decode_utf8()
            .map_err(|_| fail(format!("URI '{uri}' is not valid percent-encoded UTF-8")))?
            .into_owned(),
    };
    let base = base.ok_or_else(|| fail(format!("external file '{path}' but no directory to resolve it in")))?;
    let full = base.join(&path);
    // Only the declared length is used (already checked against the limits), so a longer file
    // is read no further than that.
    let opened = std::fs::File::open(&full).map_err(|e| fail(format!("cannot open '{}': {e}", full.display())))?;
    let mut data = Vec::with_capacity(declared);
    std::io::Read::read_to_end(&mut std::io::Read::take(opened, declared as u64), &mut data)
        .map_err(|e| fail(format!("cannot read '{}': {e}", full.display())))?;
    Ok(data)
}

fn load_mesh(file: &str, mesh: &::gltf::Mesh, buffers: &[BufferData]) -> Result<MorphMesh> {
    let limits = Limits::default();
    let target_count = mesh.primitives().next().map(|p| p.morph_targets().len()).unwrap_or(0);
    let mut base: Vec<f32> = Vec::new();
    let mut targets: Vec<Vec<f32>> = vec![Vec::new(); target_count];
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    for primitive in mesh.primitives() {
        let p = primitive.index();
        if primitive.mode() != Mode::Triangles {
            return Err(Error::Unsupported {
                context: file.to_owned().into(),
                detail: format!(
                    "mesh {} primitive {p} has mode {:?}; only TRIANGLES is supported",
                    mesh.index(),
                    primitive.mode()
                ),
            });
        }
        let positions = primitive
            .get(&Semantic::Positions)
            .ok_or_else(|| bad(file, "POSITION", format!("mesh {} primitive {p} has no POSITION", mesh.index())))?;
        let n = check_accessor(file, "POSITION", &positions, Dimensions::Vec3, &[DataType::F32])?;
        let offset = base.len() / 3;
        if offset + n > limits.max_vertices {
            return Err(Error::LimitExceeded {
                context: file.to_owned().into(),
                field: "vertex_count".into(),
                value: (offset + n) as u64,
                limit: limits.max_vertices as u64,
            });
        }
        if primitive.morph_targets().len() != target_count {
            return Err(bad(
                file,
                "targets",
                format!(
                    "mesh {} primitive {p} has {} morph targets, primitive 0 has {target_count}",
                    mesh.index(),
                    primitive.morph_targets().len()
                ),
            ));
        }
        for target in primitive.morph_targets() {
            if let Some(acc) = target.positions() {
                let count = check_accessor(file, "targets.POSITION", &acc, Dimensions::Vec3, &[DataType::F32])?;
                if count != n {
                    return Err(bad(
                        file,
                        "targets.POSITION",
                        format!("primitive {p}: {count} displacements for {n} vertices"),
                    ));
                }
            }
        }
        let indices = match primitive.indices() {
            Some(acc) => {
                check_accessor(
                    file,
                    "indices",
                    &acc,
                    Dimensions::Scalar,
                    &[DataType::U8, DataType::U16, DataType::U32],
                )?;
                Some(acc.count())
            }
            None => None,
        };
        let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
        for [x, y, z] in collect_exact(file, "POSITION", reader.read_positions(), n)? {
            base.extend_from_slice(&[x, y, z]);
        }
        for (t, (pos, _, _)) in reader.read_morph_targets().enumerate() {
            match pos {
                Some(iter) => {
                    for [x, y, z] in collect_exact(file, "targets.POSITION", Some(iter), n)? {
                        targets[t].extend_from_slice(&[x, y, z]);
                    }
                }
                None => targets[t].resize((offset + n) * 3, 0.0),
            }
        }
        let flat: Vec<u32> = match indices {
            Some(count) => collect_exact(file, "indices", reader.read_indices().map(|i| i.into_u32()), count)?,
            None => (0..n as u32).collect(),
        };
        if flat.len() % 3 != 0 {
            return Err(bad(
                file,
                "indices",
                format!("primitive {p}: {} indices is not a whole number of triangles", flat.len()),
            ));
        }
        if let Some(&i) = flat.iter().find(|&&i| i as usize >= n) {
            return Err(bad(file, "indices", format!("primitive {p}: index {i} out of range for {n} vertices")));
        }
        let o = offset as u32;
        triangles.extend(flat.chunks_exact(3).map(|c| [c[0] + o, c[1] + o, c[2] + o]));
        if triangles.len() > limits.max_triangles {
            return Err(Error::LimitExceeded {
                context: file.to_owned().into(),
                field: "triangle_count".into(),
                value: triangles.len() as u64,
                limit: limits.max_triangles as u64,
            });
        }
    }
    if base.is_empty() {
        return Err(bad(file, "meshes", format!("mesh {} has no primitives", mesh.index())));
    }
    Ok(MorphMesh { base, targets, triangles })
}

/// Keyframes of a weights channel: times and the raw output values (`keys × targets`, or
/// `keys × 3 × targets` for cubic splines: in-tangent, value, out-tangent).
struct WeightTrack {
    times: Vec<f32>,
    values: Vec<f32>,
    interpolation: Interpolation,
    targets: usize,
}

impl WeightTrack {
    /// Weights at time `t` (seconds), clamped to the key range.
    fn sample(&self, t: f64, out: &mut [f32]) {
        let n = self.targets;
        let keys = self.times.len();
        let cubic = self.interpolation == Interpolation::CubicSpline;
        // Value of target i at key k (the middle element of the triple for cubic splines).
        let value = |k: usize, i: usize| if cubic { self.values[(3 * k + 1) * n + i] } else { self.values[k * n + i] };
        // Last key with time <= t (the first key if t precedes it). Key times are f32: a key
        // written at frame k's time (k / fps rounded to f32) may lie a rounding error after
        // the f64 sample time, and must still count as reached (else STEP shows frame k − 1).
        let reached = t + 1e-6 * t.abs().max(1.0);
        let k = self.times.partition_point(|&x| x as f64 <= reached).saturating_sub(1);
        if k + 1 >= keys || t <= self.times[0] as f64 {
            for (i, w) in out.iter_mut().enumerate() {
                *w = value(k, i);
            }
            return;
        }
        let (t0, t1) = (self.times[k] as f64, self.times[k + 1] as f64);
        let dt = t1 - t0;
        let s = ((t - t0) / dt).clamp(0.0, 1.0);
        for (i, w) in out.iter_mut().enumerate() {
            let (v0, v1) = (value(k, i) as f64, value(k + 1, i) as f64);
            *w = match self.interpolation {
                Interpolation::Step => v0 as f32,
                Interpolation::Linear => (v0 + s * (v1 - v0)) as f32,
                Interpolation::CubicSpline => {
                    // glTF 2.0 spec, Appendix C "Interpolation": Hermite with the out-tangent b_k
                    // of key k and the in-tangent a_{k+1} of key k+1, both scaled by the interval.
                    let b0 = self.values[(3 * k + 2) * n + i] as f64;
                    let a1 = self.values[(3 * (k + 1)) * n + i] as f64;
                    let (s2, s3) = (s * s, s * s * s);
                    ((2.0 * s3 - 3.0 * s2 + 1.0) * v0
                        + (s3 - 2.0 * s2 + s) * dt * b0
                        + (-2.0 * s3 + 3.0 * s2) * v1
                        + (s3 - s2) * dt * a1) as f32
                }
            };
        }
    }
}

fn load_track(
    file: &str,
    channel: &::gltf::animation::Channel,
    buffers: &[BufferData],
    targets: usize,
) -> Result<WeightTrack> {
    let sampler = channel.sampler();
    let keys = check_accessor(file, "animation.input", &sampler.input(), Dimensions::Scalar, &[DataType::F32])?;
    let all_types = [DataType::F32, DataType::I8, DataType::U8, DataType::I16, DataType::U16];
    let outputs = check_accessor(file, "animation.output", &sampler.output(), Dimensions::Scalar, &all_types)?;
    let interpolation = sampler.interpolation();
    let per_key = if interpolation == Interpolation::CubicSpline { 3 * targets } else { targets };
    if targets == 0 {
        return Err(bad(file, "animation.output", "a weights animation on a mesh without morph targets"));
    }
    if outputs != keys * per_key {
        return Err(bad(
            file,
            "animation.output",
            format!(
                "{outputs} weights for {keys} keys × {targets} targets ({interpolation:?}); expected {}",
                keys * per_key
            ),
        ));
    }
    let reader = channel.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
    let times = collect_exact(file, "animation.input", reader.read_inputs(), keys)?;
    if let Some(k) = times.iter().position(|t| !t.is_finite()) {
        return Err(bad(file, "animation.input", format!("key {k} has time {}", times[k])));
    }
    if let Some(k) = times.windows(2).position(|w| w[1] <= w[0]) {
        return Err(bad(file, "animation.input", format!("key times are not increasing at key {}", k + 1)));
    }
    let values = match reader.read_outputs() {
        Some(::gltf::animation::util::ReadOutputs::MorphTargetWeights(w)) => {
            collect_exact(file, "animation.output", Some(w.into_f32()), outputs)?
        }
        _ => return Err(bad(file, "animation.output", "weights buffer data is missing")),
    };
    if let Some(k) = values.iter().position(|v| !v.is_finite()) {
        return Err(bad(file, "animation.output", format!("weight {k} is {}", values[k])));
    }
    Ok(WeightTrack { times, values, interpolation, targets })
}

/// frame = base + Σ wᵢ · targetᵢ, appended to `out`.
fn blend(mesh: &MorphMesh, weights: &[f32], out: &mut Vec<f32>) {
    let start = out.len();
    out.extend_from_slice(&mesh.base);
    let frame = &mut out[start..];
    for (target, &w) in mesh.targets.iter().zip(weights) {
        if w != 0.0 {
            for (p, d) in frame.iter_mut().zip(target) {
                *p += w * d;
            }
        }
    }
}

/// Splits a GLB (or takes glTF JSON), deserializes the JSON, checks every index in it
/// ([`check_indices`]) and only then lets the `gltf` crate validate it (its validation indexes
/// arrays unchecked in places: a `POSITION` accessor index out of range panics there).
fn parse_document(bytes: &[u8], file: &str) -> Result<(::gltf::Document, Option<Vec<u8>>)> {
    let (json, blob) = if bytes.starts_with(b"glTF") {
        // The crate computes `length - 12` unchecked (an overflow panic, found by fuzzing).
        let declared = bytes.get(8..12).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
        match declared {
            None => return Err(bad(file, "glb", "the 12-byte GLB header is truncated")),
            Some(n) if n < 12 => {
                return Err(bad(
                    file,
                    "glb",
                    format!("the header declares a total length of {n} bytes, less than itself"),
                ))
            }
            Some(_) => {}
        }
        let glb = ::gltf::Glb::from_slice(bytes).map_err(|e| bad(file, "glb", e.to_string()))?;
        (glb.json.into_owned(), glb.bin.map(|b| b.into_owned()))
    } else {
        (bytes.to_vec(), None)
    };
    let root: ::gltf::json::Root =
        ::gltf::json::deserialize::from_slice(&json).map_err(|e| bad(file, "gltf", e.to_string()))?;
    check_indices(file, &root)?;
    let document = ::gltf::Document::from_json(root).map_err(|e| bad(file, "gltf", e.to_string()))?;
    Ok((document, blob))
}

/// Checks that every index into the document's arrays that this reader or the `gltf` crate
/// follows is in range: accessors (buffer views, sparse blocks), buffer views (buffers), meshes
/// (attribute, index and morph-target accessors), nodes (meshes, children, skins, cameras),
/// scenes, skins and animations (channel samplers and target nodes, sampler accessors).
/// Materials, textures and images are checked by the crate's own validation, which does so
/// safely.
fn check_indices(file: &str, root: &::gltf::json::Root) -> Result<()> {
    fn check(file: &str, what: impl Fn() -> String, index: usize, len: usize, array: &str) -> Result<()> {
        if index >= len {
            return Err(bad(file, "gltf", format!("{} refers to {array} {index}, but there are {len}", what())));
        }
        Ok(())
    }
    let accessors = root.accessors.len();
    let views = root.buffer_views.len();
    let nodes = root.nodes.len();
    for (i, a) in root.accessors.iter().enumerate() {
        if let Some(v) = a.buffer_view {
            check(file, || format!("accessor {i}"), v.value(), views, "bufferView")?;
        }
        if let Some(sparse) = &a.sparse {
            check(
                file,
                || format!("accessor {i} sparse indices"),
                sparse.indices.buffer_view.value(),
                views,
                "bufferView",
            )?;
            check(
                file,
                || format!("accessor {i} sparse values"),
                sparse.values.buffer_view.value(),
                views,
                "bufferView",
            )?;
        }
    }
    for (i, v) in root.buffer_views.iter().enumerate() {
        check(file, || format!("bufferView {i}"), v.buffer.value(), root.buffers.len(), "buffer")?;
    }
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let at = || format!("mesh {m} primitive {p}");
            for (semantic, accessor) in &primitive.attributes {
                let what = || format!("{} attribute {}", at(), semantic.to_string());
                check(file, what, accessor.value(), accessors, "accessor")?;
            }
            if let Some(indices) = primitive.indices {
                check(file, || format!("{} indices", at()), indices.value(), accessors, "accessor")?;
            }
            for (t, target) in primitive.targets.iter().flatten().enumerate() {
                for a in [target.positions, target.normals, target.tangents].into_iter().flatten() {
                    check(file, || format!("{} morph target {t}", at()), a.value(), accessors, "accessor")?;
                }
            }
        }
    }
    for (i, node) in root.nodes.iter().enumerate() {
        let at = || format!("node {i}");
        if let Some(mesh) = node.mesh {
            check(file, at, mesh.value(), root.meshes.len(), "mesh")?;
        }
        for child in node.children.iter().flatten() {
            check(file, at, child.value(), nodes, "node")?;
        }
        if let Some(skin) = node.skin {
            check(file, at, skin.value(), root.skins.len(), "skin")?;
        }
        if let Some(camera) = node.camera {
            check(file, at, camera.value(), root.cameras.len(), "camera")?;
        }
    }
    for (i, scene) in root.scenes.iter().enumerate() {
        for n in &scene.nodes {
            check(file, || format!("scene {i}"), n.value(), nodes, "node")?;
        }
    }
    if let Some(scene) = root.scene {
        check(file, || "the default scene".into(), scene.value(), root.scenes.len(), "scene")?;
    }
    for (i, skin) in root.skins.iter().enumerate() {
        let at = || format!("skin {i}");
        for n in skin.joints.iter().chain(&skin.skeleton) {
            check(file, at, n.value(), nodes, "node")?;
        }
        if let Some(a) = skin.inverse_bind_matrices {
            check(file, at, a.value(), accessors, "accessor")?;
        }
    }
    for (i, animation) in root.animations.iter().enumerate() {
        for (c, channel) in animation.channels.iter().enumerate() {
            let at = || format!("animation {i} channel {c}");
            check(file, at, channel.sampler.value(), animation.samplers.len(), "sampler")?;
            check(file, at, channel.target.node.value(), nodes, "node")?;
            // The crate's validation skips channels: an unknown `path` would panic in
            // `Target::property` (found by fuzzing).
            if !matches!(channel.target.path, ::gltf::json::validation::Checked::Valid(_)) {
                return Err(bad(
                    file,
                    "gltf",
                    format!("{}: the target path is not one of translation, rotation, scale, weights", at()),
                ));
            }
        }
        for (k, sampler) in animation.samplers.iter().enumerate() {
            let at = || format!("animation {i} sampler {k}");
            check(file, at, sampler.input.value(), accessors, "accessor")?;
            check(file, at, sampler.output.value(), accessors, "accessor")?;
        }
    }
    Ok(())
}

fn parse_checked(bytes: &[u8], base: Option<&Path>, file: &str, frame_rate: f32) -> Result<Animation> {
    let (document, blob) = parse_document(bytes, file)?;
    let buffers = load_buffers(file, &document, base, blob)?;
    let mesh = document
        .meshes()
        .find(|m| m.primitives().any(|p| p.morph_targets().len() > 0))
        .or_else(|| document.meshes().next())
        .ok_or_else(|| bad(file, "meshes", "the file has no mesh"))?;
    let morph = load_mesh(file, &mesh, &buffers)?;
    let vertex_count = morph.base.len() / 3;
    let target_count = morph.targets.len();
    let uses_mesh = |node: &::gltf::Node| node.mesh().is_some_and(|m| m.index() == mesh.index());
    let channel = document.animations().find_map(|anim| {
        anim.channels().find(|c| c.target().property() == Property::MorphTargetWeights && uses_mesh(&c.target().node()))
    });
    let mut positions = Vec::new();
    match channel {
        None => {
            let node = document.nodes().find(|n| uses_mesh(n));
            let default = node.and_then(|n| n.weights()).or_else(|| mesh.weights()).unwrap_or(&[]);
            if !default.is_empty() && default.len() != target_count {
                return Err(bad(
                    file,
                    "weights",
                    format!("{} default weights for {target_count} targets", default.len()),
                ));
            }
            blend(&morph, default, &mut positions);
        }
        Some(channel) => {
            let track = load_track(file, &channel, &buffers, target_count)?;
            let (t0, t1) = (track.times[0] as f64, track.times[track.times.len() - 1] as f64);
            let fps = frame_rate as f64;
            // The small epsilon keeps a key that falls on a frame boundary (1.5 s × 30 fps) in,
            // also when the f32 key time lies a rounding error short of it (39 / 30 s as f32 is
            // 38.9999986 frames; f32 time errors are ≈ 6e-8 relative, far below 1e-4 frames).
            let frames_f = ((t1 - t0) * fps + 1e-4).floor() + 1.0;
            let limits = Limits::default();
            if frames_f > limits.max_frames as f64 {
                return Err(Error::LimitExceeded {
                    context: file.to_owned().into(),
                    field: "frame_count".into(),
                    value: frames_f as u64,
                    limit: limits.max_frames as u64,
                });
            }
            let frames = frames_f as usize;
            limits.check_alloc("gltf", "positions", (frames * vertex_count * 12) as u64)?;
            positions.reserve_exact(frames * vertex_count * 3);
            let mut weights = vec![0f32; target_count];
            for k in 0..frames {
                track.sample(t0 + k as f64 / fps, &mut weights);
                blend(&morph, &weights, &mut positions);
            }
        }
    }
    Animation::from_parts(vertex_count, morph.triangles, positions, frame_rate).map_err(|e| in_file(file, e))
}

#[cfg(test)]
mod tests {
    use super::super::{read_animation, ReadOptions, TempDir};
    use super::*;
    use serde_json::{json, Value};

    /// A small glTF document builder: one buffer, accessors appended as f32/u16 arrays.
    struct Builder {
        bin: Vec<u8>,
        views: Vec<Value>,
        accessors: Vec<Value>,
    }

    impl Builder {
        fn new() -> Self {
            Self { bin: Vec::new(), views: Vec::new(), accessors: Vec::new() }
        }

        fn push(&mut self, bytes: &[u8], count: usize, ty: &str, component: u32) -> usize {
            while self.bin.len() % 4 != 0 {
                self.bin.push(0);
            }
            self.views.push(json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()}));
            self.bin.extend_from_slice(bytes);
            self.accessors.push(json!({
                "bufferView": self.views.len() - 1, "componentType": component, "count": count, "type": ty
            }));
            self.accessors.len() - 1
        }

        fn f32s(&mut self, v: &[f32], ty: &str) -> usize {
            let per = if ty == "VEC3" { 3 } else { 1 };
            let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
            let a = self.push(&bytes, v.len() / per, ty, 5126);
            if per == 3 {
                // The spec (and the gltf crate's validation) requires min/max on POSITION.
                let lo: Vec<f32> =
                    (0..3).map(|k| v.iter().skip(k).step_by(3).copied().fold(f32::MAX, f32::min)).collect();
                let hi: Vec<f32> =
                    (0..3).map(|k| v.iter().skip(k).step_by(3).copied().fold(f32::MIN, f32::max)).collect();
                self.accessors[a]["min"] = json!(lo);
                self.accessors[a]["max"] = json!(hi);
            }
            a
        }

        fn u16s(&mut self, v: &[u16]) -> usize {
            let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
            self.push(&bytes, v.len(), "SCALAR", 5123)
        }

        /// The document; `buffer_uri` None means a GLB blob.
        fn document(&self, meshes: Value, animations: Value, buffer_uri: Option<&str>) -> Value {
            let mut buffer = json!({"byteLength": self.bin.len()});
            if let Some(uri) = buffer_uri {
                buffer["uri"] = json!(uri);
            }
            json!({
                "asset": {"version": "2.0"},
                "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
                "meshes": meshes, "animations": animations,
                "buffers": [buffer], "bufferViews": self.views, "accessors": self.accessors
            })
        }

        fn glb(&self, doc: &Value) -> Vec<u8> {
            let mut json_bytes = serde_json::to_vec(doc).unwrap();
            while json_bytes.len() % 4 != 0 {
                json_bytes.push(b' ');
            }
            let mut bin = self.bin.clone();
            while bin.len() % 4 != 0 {
                bin.push(0);
            }
            let total = 12 + 8 + json_bytes.len() + 8 + bin.len();
            let mut out = b"glTF".to_vec();
            out.extend_from_slice(&2u32.to_le_bytes());
            out.extend_from_slice(&(total as u32).to_le_bytes());
            out.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
            out.extend_from_slice(b"JSON");
            out.extend_from_slice(&json_bytes);
            out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
            out.extend_from_slice(b"BIN\0");
            out.extend_from_slice(&bin);
            out
        }
    }

    /// One triangle, two targets (x + 2 on every vertex; y + 4 on every vertex), and a weights
    /// track over keys 0, 1, 2 s: [0,0] → [1,0] → [0,1] (cubic: the given tangents).
    fn morph_triangle(interpolation: &str, tangents: Option<(f32, f32)>) -> (Builder, Value) {
        let mut b = Builder::new();
        let base = b.f32s(&[0., 0., 0., 1., 0., 0., 0., 1., 0.], "VEC3");
        let t0 = b.f32s(&[2., 0., 0., 2., 0., 0., 2., 0., 0.], "VEC3");
        let t1 = b.f32s(&[0., 4., 0., 0., 4., 0., 0., 4., 0.], "VEC3");
        let idx = b.u16s(&[0, 1, 2]);
        let input = b.f32s(&[0., 1., 2.], "SCALAR");
        let values: Vec<f32> = match tangents {
            None => vec![0., 0., 1., 0., 0., 1.],
            // Per key: in-tangents, values, out-tangents (all targets share the given pair).
            Some((a, o)) => [[0f32, 0.], [1., 0.], [0., 1.]].iter().flat_map(|v| [a, a, v[0], v[1], o, o]).collect(),
        };
        let output = b.f32s(&values, "SCALAR");
        let meshes = json!([{"primitives": [{"attributes": {"POSITION": base}, "indices": idx,
            "targets": [{"POSITION": t0}, {"POSITION": t1}]}]}]);
        let animations = json!([{"samplers": [{"input": input, "output": output, "interpolation": interpolation}],
            "channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}]}]);
        let doc = b.document(meshes, animations, Some("buf.bin"));
        (b, doc)
    }

    fn write_gltf(dir: &TempDir, b: &Builder, doc: &Value) -> std::path::PathBuf {
        std::fs::write(dir.path("buf.bin"), &b.bin).unwrap();
        let path = dir.path("m.gltf");
        std::fs::write(&path, serde_json::to_vec(doc).unwrap()).unwrap();
        path
    }

    /// x offset (weight of target 0 × 2) and y offset (weight of target 1 × 4) of vertex 0 per frame.
    fn offsets(a: &Animation) -> Vec<(f32, f32)> {
        (0..a.frame_count()).map(|t| (a.vertex(t, 0)[0] / 2.0, a.vertex(t, 0)[1] / 4.0)).collect()
    }

    #[test]
    fn linear_and_step_weights_are_sampled_at_the_frame_rate() {
        let dir = TempDir::new("gltf-linear");
        let (b, doc) = morph_triangle("LINEAR", None);
        let path = write_gltf(&dir, &b, &doc);
        let opts = ReadOptions { frame_rate: Some(2.0), ..Default::default() };
        let a = read_animation(&path, &opts).unwrap();
        assert_eq!((a.vertex_count(), a.triangles()), (3, &[[0, 1, 2]][..]));
        assert_eq!(a.frame_rate(), 2.0);
        assert_eq!(offsets(&a), vec![(0., 0.), (0.5, 0.), (1., 0.), (0.5, 0.5), (0., 1.)]);
        // Every vertex moves by the same blend: vertex 1 = (1, 0, 0) + offsets.
        assert_eq!(a.vertex(3, 1), [2.0, 2.0, 0.0]);
        // Default rate: 2 s at 30 fps = 61 frames.
        assert_eq!(read_animation(&path, &ReadOptions::default()).unwrap().frame_count(), 61);

        let (b, doc) = morph_triangle("STEP", None);
        let path = write_gltf(&dir, &b, &doc);
        let a = read_animation(&path, &opts).unwrap();
        assert_eq!(offsets(&a), vec![(0., 0.), (0., 0.), (1., 0.), (1., 0.), (0., 1.)]);
    }

    #[test]
    fn buffers_load_from_data_uris_and_percent_encoded_paths_or_fail_by_name() {
        let dir = TempDir::new("gltf-buffers");
        let opts = ReadOptions { frame_rate: Some(2.0), ..Default::default() };
        let (b, doc) = morph_triangle("LINEAR", None);
        let expected = offsets(&read_animation(&write_gltf(&dir, &b, &doc), &opts).unwrap());
        let parse =
            |doc: &Value| parse_gltf(&serde_json::to_vec(doc).unwrap(), Some(dir.path("").as_path()), "t.gltf", 2.0);

        // The same buffer as a base64 data URI.
        let mut inline = doc.clone();
        let encoded = base64::engine::general_purpose::STANDARD.encode(&b.bin);
        inline["buffers"][0]["uri"] = json!(format!("data:application/octet-stream;base64,{encoded}"));
        assert_eq!(offsets(&parse(&inline).unwrap()), expected);
        // A percent-encoded relative path.
        std::fs::write(dir.path("my buf.bin"), &b.bin).unwrap();
        let mut spaced = doc.clone();
        spaced["buffers"][0]["uri"] = json!("my%20buf.bin");
        assert_eq!(offsets(&parse(&spaced).unwrap()), expected);

        let fails = |doc: &Value, expected: &str| {
            let e = parse(doc).unwrap_err().to_string();
            assert!(
                e.contains("t.gltf") && e.contains("buffer 0") && e.contains(expected),
                "{e} (expected '{expected}')"
            );
        };
        let mut bad = inline.clone();
        bad["buffers"][0]["uri"] = json!("data:application/octet-stream;base64,@@@@");
        fails(&bad, "invalid base64");
        bad["buffers"][0]["uri"] = json!("data:text/plain,hello");
        fails(&bad, "not base64");
        bad["buffers"][0]["uri"] = json!("https://example.invalid/buf.bin");
        fails(&bad, "unsupported URI scheme");
        bad["buffers"][0]["uri"] = json!("bad%FF%FE.bin");
        fails(&bad, "percent-encoded");
        let mut short = doc.clone();
        short["buffers"][0]["byteLength"] = json!(b.bin.len() + 8);
        fails(&short, "declares byteLength");
        let mut absurd = doc.clone();
        absurd["buffers"][0]["byteLength"] = json!(1u64 << 40);
        let e = parse(&absurd).unwrap_err().to_string();
        assert!(e.contains("buffers"), "{e}");
        // Without a directory an external file cannot be resolved.
        let e = parse_gltf(&serde_json::to_vec(&doc).unwrap(), None, "t.gltf", 2.0).unwrap_err().to_string();
        assert!(e.contains("no directory"), "{e}");
    }

    #[test]
    fn cubic_spline_uses_the_hermite_tangents() {
        let dir = TempDir::new("gltf-cubic");
        let opts = ReadOptions { frame_rate: Some(2.0), ..Default::default() };
        // Zero tangents: at s = 0.5 Hermite gives the mean of the two values.
        let (b, doc) = morph_triangle("CUBICSPLINE", Some((0.0, 0.0)));
        let a = read_animation(&write_gltf(&dir, &b, &doc), &opts).unwrap();
        assert_eq!(offsets(&a), vec![(0., 0.), (0.5, 0.), (1., 0.), (0.5, 0.5), (0., 1.)]);
        // Out-tangent 1, in-tangent 0: at s = 0.5 the tangent term adds (s³ - 2s² + s)·dt·1 = 0.125.
        let (b, doc) = morph_triangle("CUBICSPLINE", Some((0.0, 1.0)));
        let a = read_animation(&write_gltf(&dir, &b, &doc), &opts).unwrap();
        assert_eq!(offsets(&a)[1], (0.625, 0.125));
        assert_eq!(offsets(&a)[2], (1.0, 0.0), "keys are hit exactly");
    }

    #[test]
    fn glb_blob_no_animation_and_multiple_primitives() {
        // Two primitives: an indexed triangle and a non-indexed one; default mesh weights [0.5, 0].
        let mut b = Builder::new();
        let p0 = b.f32s(&[0., 0., 0., 1., 0., 0., 0., 1., 0.], "VEC3");
        let p1 = b.f32s(&[5., 5., 5., 6., 5., 5., 5., 6., 5.], "VEC3");
        let d = b.f32s(&[2., 0., 0., 2., 0., 0., 2., 0., 0.], "VEC3");
        let idx = b.u16s(&[2, 1, 0]);
        let meshes = json!([{"weights": [0.5, 0.0], "primitives": [
            {"attributes": {"POSITION": p0}, "indices": idx, "targets": [{"POSITION": d}, {"POSITION": d}]},
            {"attributes": {"POSITION": p1}, "targets": [{"POSITION": d}, {"NORMAL": d}]}]}]);
        let doc = b.document(meshes, json!([]), None);
        let glb = b.glb(&doc);
        let a = parse_gltf(&glb, None, "m.glb", 30.0).unwrap();
        assert_eq!(a.frame_count(), 1);
        assert_eq!(a.triangles(), &[[2, 1, 0], [3, 4, 5]]);
        assert_eq!(a.vertex(0, 0), [1.0, 0.0, 0.0]);
        assert_eq!(a.vertex(0, 4), [7.0, 5.0, 5.0]);
        // Every truncation of the GLB is an error, never a panic.
        for len in 0..glb.len() {
            let e = parse_gltf(&glb[..len], None, "cut.glb", 30.0).unwrap_err().to_string();
            assert!(e.contains("cut.glb"), "length {len}: {e}");
        }
    }

    #[test]
    fn corrupted_bytes_give_results_not_crashes() {
        // Every byte of a small GLB (header, JSON and buffer) replaced by a few values: the parse
        // must come back with a result (an error, or an animation with finite positions).
        let (b, mut doc) = morph_triangle("CUBICSPLINE", Some((0.5, -0.5)));
        doc["buffers"][0].as_object_mut().unwrap().remove("uri");
        let glb = b.glb(&doc);
        let mut accepted = 0;
        for i in 0..glb.len() {
            for v in [0u8, 0x39, 0xff] {
                let mut m = glb.clone();
                m[i] = v;
                if let Ok(a) = parse_gltf(&m, None, "m.glb", 7.0) {
                    assert!(a.positions().iter().all(|x| x.is_finite()));
                    accepted += 1;
                }
            }
        }
        assert!(accepted > 0, "some corruptions (e.g. in padding) are harmless");
    }

    #[test]
    fn malformed_documents_are_errors_naming_the_problem() {
        let (b, doc) = morph_triangle("LINEAR", None);
        let check = |doc: &Value, expected: &str| {
            let e = parse_gltf(&b.glb(doc), None, "bad.glb", 30.0).unwrap_err().to_string();
            assert!(e.contains("bad.glb") && e.contains(expected), "{e} (expected '{expected}')");
        };
        let mut d = doc.clone();
        d["buffers"][0].as_object_mut().unwrap().remove("uri");
        let mut lines = d.clone();
        lines["meshes"][0]["primitives"][0]["mode"] = json!(1);
        check(&lines, "only TRIANGLES");
        let mut wrong_count = d.clone();
        wrong_count["accessors"][5]["count"] = json!(5);
        check(&wrong_count, "expected 6");
        let mut wrong_type = d.clone();
        wrong_type["accessors"][0]["componentType"] = json!(5121);
        check(&wrong_type, "component type");
        let mut bad_index = d.clone();
        bad_index["accessors"][3]["componentType"] = json!(5126);
        check(&bad_index, "component type");
        let mut too_long = d.clone();
        too_long["accessors"][0]["count"] = json!(1000);
        check(&too_long, "bad.glb");
        let e = parse_gltf(b"{not json", None, "junk.gltf", 30.0).unwrap_err().to_string();
        assert!(e.contains("junk.gltf"), "{e}");
        // An external buffer that does not exist.
        let e = parse_gltf(&serde_json::to_vec(&doc).unwrap(), Some(Path::new("/nonexistent-dir")), "x.gltf", 30.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("x.gltf") && e.contains("buffers"), "{e}");
        // Weights that blow up to infinity.
        let mut huge = Builder::new();
        let p = huge.f32s(&[3e38, 0., 0., 1., 0., 0., 0., 1., 0.], "VEC3");
        let t = huge.f32s(&[3e38, 0., 0., 0., 0., 0., 0., 0., 0.], "VEC3");
        let meshes =
            json!([{"weights": [1.0], "primitives": [{"attributes": {"POSITION": p}, "targets": [{"POSITION": t}]}]}]);
        let hdoc = huge.document(meshes, json!([]), None);
        let e = parse_gltf(&huge.glb(&hdoc), None, "inf.glb", 30.0).unwrap_err().to_string();
        assert!(e.contains("inf.glb") && e.contains("non-finite") && e.contains("vertex 0"), "{e}");
    }

    /// Issue 16: indices out of range are found before the `gltf` crate follows them (its
    /// validation panics on a `POSITION` accessor out of range, and nothing checks a channel's
    /// target node). The message names the index: the catch_unwind fallback's generic message
    /// would mean a panic was printed.
    #[test]
    fn out_of_range_indices_are_errors_before_the_gltf_crate_sees_them() {
        let (b, doc) = morph_triangle("LINEAR", None);
        let mut d = doc.clone();
        d["buffers"][0].as_object_mut().unwrap().remove("uri");
        type Mutation = Box<dyn Fn(&mut Value)>;
        let cases: Vec<(&str, Mutation, &str)> = vec![
            (
                "position",
                Box::new(|d| d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(99999)),
                "accessor 99999",
            ),
            ("node", Box::new(|d| d["animations"][0]["channels"][0]["target"]["node"] = json!(5000)), "node 5000"),
            ("sampler", Box::new(|d| d["animations"][0]["channels"][0]["sampler"] = json!(7)), "sampler 7"),
            ("input", Box::new(|d| d["animations"][0]["samplers"][0]["input"] = json!(70)), "accessor 70"),
            ("indices", Box::new(|d| d["meshes"][0]["primitives"][0]["indices"] = json!(12)), "accessor 12"),
            (
                "target",
                Box::new(|d| d["meshes"][0]["primitives"][0]["targets"][1]["POSITION"] = json!(40)),
                "accessor 40",
            ),
            ("view", Box::new(|d| d["accessors"][0]["bufferView"] = json!(300)), "bufferView 300"),
            ("buffer", Box::new(|d| d["bufferViews"][0]["buffer"] = json!(9)), "buffer 9"),
            ("mesh", Box::new(|d| d["nodes"][0]["mesh"] = json!(3)), "mesh 3"),
            ("child", Box::new(|d| d["nodes"][0]["children"] = json!([0, 77])), "node 77"),
            ("scene", Box::new(|d| d["scene"] = json!(4)), "scene 4"),
            // Fuzzing finding (read_gltf): an unknown channel path panicked in the gltf crate.
            (
                "path",
                Box::new(|d| d["animations"][0]["channels"][0]["target"]["path"] = json!("weyghts")),
                "target path",
            ),
        ];
        for (what, mutate, expected) in cases {
            let mut bad = d.clone();
            mutate(&mut bad);
            for (bytes, file) in [(b.glb(&bad), "bad.glb"), (serde_json::to_vec(&bad).unwrap(), "bad.gltf")] {
                let e = parse_gltf(&bytes, None, file, 30.0).unwrap_err().to_string();
                assert!(e.contains(file) && e.contains(expected), "{what}: {e} (expected '{expected}')");
                assert!(!e.contains("reader failed"), "{what}: the gltf crate panicked: {e}");
            }
        }
    }

    /// Fuzzing finding (read_gltf): a GLB header declaring a total length below 12 bytes made
    /// the `gltf` crate subtract with overflow.
    #[test]
    fn glb_lengths_below_the_header_are_errors() {
        for n in [0u32, 11] {
            let mut b = b"glTF\x02\0\0\0".to_vec();
            b.extend_from_slice(&n.to_le_bytes());
            b.extend_from_slice(b"JSON{}");
            let e = parse_gltf(&b, None, "short.glb", 30.0).unwrap_err().to_string();
            assert!(e.contains("short.glb") && e.contains("less than itself"), "{e}");
        }
        let e = parse_gltf(b"glTF\x02\0", None, "cut.glb", 30.0).unwrap_err().to_string();
        assert!(e.contains("truncated"), "{e}");
    }

    #[test]
    fn reads_horse_glb_when_present() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/horse-glb/Horse.glb");
        if !path.is_file() {
            println!("SKIP reads_horse_glb_when_present: {} not found", path.display());
            return;
        }
        let a = read_animation(&path, &ReadOptions::default()).unwrap();
        assert_eq!((a.vertex_count(), a.topology().triangle_count()), (796, 984));
        // 16 keys from 0 to 1.5 s: 46 frames at 30 fps, 16 at the keys' own 10 fps.
        assert_eq!(a.frame_count(), 46);
        let at_keys = read_animation(&path, &ReadOptions { frame_rate: Some(10.0), ..Default::default() }).unwrap();
        assert_eq!(at_keys.frame_count(), 16);
        // Sampling at 30 fps hits every key: frame 3k equals key frame k (up to f32 key-time rounding).
        let scale = a.bounding_box_diagonal() as f32;
        for k in 0..16 {
            let worst = a.frame(3 * k).iter().zip(at_keys.frame(k)).map(|(x, y)| (x - y).abs()).fold(0f32, f32::max);
            assert!(worst <= 1e-5 * scale, "key {k}: {worst}");
        }
        // The horse actually moves between keys.
        let moved = at_keys.frame(1).iter().zip(at_keys.frame(5)).map(|(x, y)| (x - y).abs()).fold(0f32, f32::max);
        assert!(moved > 1e-3 * scale, "frames 1 and 5 are identical");
    }
}
