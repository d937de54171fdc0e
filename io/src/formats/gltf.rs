//! glTF 2.0 / GLB input: the scene of a glTF file played back into one fixed-topology vertex
//! cache, read with the `gltf` crate. Morph-target animations (Horse.glb), node (TRS)
//! animation and skinned characters (RobotExpressive.glb) all come out as per-frame vertex
//! positions.
//!
//! Choices (all documented here so callers know what they get):
//! - **Vertices** (the vertex order): every node with a mesh in the default scene (else scene 0,
//!   else every root node), visited depth first from the scene's root nodes in order, a node's
//!   own mesh before its children. Each such mesh instance contributes all its primitives'
//!   vertices in primitive order, each in its `POSITION` accessor's order (a mesh used by two
//!   nodes appears twice); a Draco-compressed primitive's in its decoded point order, which
//!   may differ from the mesh before compression (`gltf_draco.rs`). Triangles are
//!   re-indexed accordingly. Only `TRIANGLES` primitives are accepted; a primitive without
//!   indices is a plain triangle list.
//! - **Space**: world space of the scene (the node hierarchy's transforms applied). A skinned
//!   mesh follows the spec (§3.7.3 "Skins"): Σⱼ wⱼ · world(jointⱼ) · inverseBindⱼ · p, the
//!   skinned node's own transform ignored; weights from every `JOINTS_n`/`WEIGHTS_n` set (4 per
//!   set) normalized to sum 1; a joint with zero weight is ignored even when out of range, and
//!   a vertex with no weight at all stays where its node puts it.
//! - **Morph targets** before skinning: p = base + Σᵢ wᵢ(t) · targetᵢ (`POSITION` displacements;
//!   a target without positions displaces nothing). Weights: the node's `weights` channel, else
//!   the node's default `weights`, else the mesh's, else zeros.
//! - **Animation**: `--animation NAME|INDEX` (an exact name first, then an index), default the
//!   first in file order; every one of its channels (translation, rotation, scale, weights) is
//!   applied; nodes it does not animate stay at rest. No animation in the file: one frame at rest.
//! - **Sampling**: from the first to the last key time over all channels,
//!   `floor(duration × fps) + 1` frames at `t₀ + k / fps`. `fps`: the caller's, else the rate
//!   animcodec's writer stores in the animation's `extras`, else the rate of the key grid when
//!   every key lies on one (RobotExpressive: 24, Horse: 10), else 30. Every rate lies in
//!   [`super::FRAME_RATE_RANGE`]; keys on a grid faster than its top (10⁴ fps), or an animation
//!   that spans less than one frame at the file's own rate, are refused by name rather than
//!   collapsed to one frame. Interpolation: `STEP`,
//!   `LINEAR` (rotations: slerp along the short arc), and `CUBICSPLINE` evaluated with the
//!   Hermite formula (spec Appendix C), rotations normalized (`gltf_anim`). Before
//!   its first key a channel holds its first value, after its last key its last value.
//! - Arithmetic in `f64`, positions rounded to `f32` once at the end.
//!
//! What is read, and what is refused (a reader that reads geometry and stays in its folder):
//! - **Only geometry.** Materials, textures, images and samplers are dropped from the JSON
//!   before the `gltf` crate sees it, so texture formats and their extensions never matter.
//!   `asset.version` must be 2.x. A required extension is accepted when it is implemented here
//!   (`KHR_mesh_quantization`, `EXT_meshopt_compression` and `KHR_meshopt_compression` with
//!   every mode and geometry filter,
//!   `KHR_draco_mesh_compression`: see `gltf_draco.rs`, whose decoded vertex order is
//!   kept), or when it only describes appearance ([`APPEARANCE_PREFIXES`]: materials,
//!   textures, lights, metadata); any other (GPU instancing, animation pointers, unknown names)
//!   is refused by name, since it may change the geometry.
//! - **Buffers** are loaded here, not by `gltf::import_buffers` (whose loader follows any
//!   path and panics on a malformed percent-encoded URI), and only those an accessor used for
//!   geometry (positions, morph targets, joints and weights, indices, inverse bind matrices,
//!   animation samplers) reads. Sources: the GLB `BIN` chunk, base64 `data:` URIs, and relative
//!   paths inside the glTF file's own folder (or below it): no absolute path, no `..`, no
//!   symbolic link leading out, regular files only (no FIFO or device), each file's size
//!   checked against its `byteLength` and the memory budget before a byte is read, and only
//!   `byteLength` bytes read.
//! - **Memory**: everything the read holds (buffers, mesh data, the baked positions and
//!   triangles) is counted against one budget ([`GltfSelection::memory_budget`], else the
//!   process default [`set_default_memory_budget`] — the binary's `--max-memory` — else
//!   [`DEFAULT_MEMORY_BUDGET`]) before it is allocated, so a scene of 20 000 instances of one
//!   mesh is refused in milliseconds instead of baking gigabytes.
//! - **Accessors**: every accessor is checked before the `gltf` crate's readers see it: type,
//!   component type (8/16-bit positions only with `KHR_mesh_quantization`), count, byteStride
//!   at least the element size, byte ranges inside the view and the view inside its buffer,
//!   sparse indices increasing and in range; joint indices, inverse bind matrix counts and the
//!   node hierarchy (one parent per node, no cycles) are checked too. As a last line of
//!   defence the whole parse runs under `catch_unwind` and a panic inside the crate becomes an
//!   error (the binary installs a silent panic hook, so no panic text reaches the terminal).

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Component, Path};

use base64::Engine as _;
use codec_core::{Animation, Error, Limits, Result};
use serde_json::Value;

use super::gltf_buffers::{bad, Budget, BufferData, KHR_MESH_QUANTIZATION};
pub use super::gltf_buffers::{printable, set_default_memory_budget, DEFAULT_MEMORY_BUDGET};
use super::gltf_draco;
use super::gltf_meshopt;
use super::gltf_scene::{self, Selection};
use super::{check_frame_rate, name, read_file};

pub use super::gltf_scene::AnimationInfo;

/// What to read from a glTF file.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GltfSelection {
    /// The animation: a name, else an index. `None`: the first.
    pub animation: Option<String>,
    /// Sampling rate. `None`: the file's own (see the module docs).
    pub frame_rate: Option<f32>,
    /// Most bytes the read may hold in total (buffers, mesh data, baked positions). `None`:
    /// the process default ([`set_default_memory_budget`], else [`DEFAULT_MEMORY_BUDGET`]).
    pub memory_budget: Option<u64>,
    /// Copies of the baked positions the caller will hold after the read (an encoder's working
    /// copy, the decoded positions, the metrics' copies), counted against the budget with the
    /// read, before anything is baked: a small file that instancing multiplies is refused
    /// before the command it feeds holds gigabytes. [`read_animation`](super::read_animation)
    /// asks for [`COMMAND_WORKING_COPIES`]; 0 counts the read alone.
    pub working_copies: u64,
}

/// The copies of an animation a command holds beyond the one read, as
/// [`GltfSelection::working_copies`] counts them: 6, measured on a default encode (probe
/// gltf-memory: 2 000 instances of Horse.glb, a 276 KB file, baked 305 MB, within the 1 GiB read
/// budget, and the default quant-delta encode then peaked at 2.04 GB, 6.7 times as much).
pub const COMMAND_WORKING_COPIES: u64 = 6;

/// Reads a `.gltf` or `.glb` file's scene played back as `selection` says. External buffers of
/// a `.gltf` are resolved relative to the file's directory (and must lie inside it).
pub fn read_gltf(path: &Path, selection: &GltfSelection) -> Result<Animation> {
    let bytes = read_file(path)?;
    let base = path.parent().map(|p| if p.as_os_str().is_empty() { Path::new(".") } else { p });
    parse_gltf_with(&bytes, base, &name(path), selection)
}

/// Parses glTF JSON or GLB bytes, its first animation sampled at `frame_rate`. `base` resolves
/// external buffer URIs (`None`: only embedded and data-URI buffers work); `file` names the
/// source in errors.
pub fn parse_gltf(bytes: &[u8], base: Option<&Path>, file: &str, frame_rate: f32) -> Result<Animation> {
    parse_gltf_with(bytes, base, file, &GltfSelection { frame_rate: Some(frame_rate), ..Default::default() })
}

/// Parses glTF JSON or GLB bytes as `selection` says (see [`parse_gltf`]).
pub fn parse_gltf_with(bytes: &[u8], base: Option<&Path>, file: &str, selection: &GltfSelection) -> Result<Animation> {
    if let Some(fps) = selection.frame_rate {
        check_frame_rate(fps)?;
    }
    guarded(file, || {
        let mut budget = Budget::new(file, selection.memory_budget);
        let (document, blob, raw) = parse_document(bytes, file, &mut budget)?;
        let buffers = load_buffers(file, &document, base, blob, &raw, &mut budget)?;
        let wanted = Selection {
            animation: selection.animation.as_deref(),
            frame_rate: selection.frame_rate.map(f64::from),
            working_copies: selection.working_copies,
        };
        gltf_scene::bake(file, &document, &buffers, &raw, &wanted, &mut budget)
    })
}

/// Every animation of a `.gltf` or `.glb` file: index, name, channels, key range and rate.
pub fn list_animations(path: &Path) -> Result<Vec<AnimationInfo>> {
    let bytes = read_file(path)?;
    let base = path.parent().map(|p| if p.as_os_str().is_empty() { Path::new(".") } else { p });
    let file = name(path);
    guarded(&file, || {
        let mut budget = Budget::new(&file, None);
        let (document, blob, raw) = parse_document(&bytes, &file, &mut budget)?;
        let buffers = load_buffers(&file, &document, base, blob, &raw, &mut budget)?;
        gltf_scene::list(&file, &document, &buffers)
    })
}

/// Extensions read here rather than by the `gltf` crate.
const SUPPORTED_EXTENSIONS: [&str; 4] =
    [KHR_MESH_QUANTIZATION, gltf_meshopt::EXTENSION, gltf_meshopt::KHR_EXTENSION, gltf_draco::EXTENSION];

/// Prefixes of the extension families that describe appearance or metadata only (materials,
/// textures and their formats, lights, XMP): never a reason to refuse a file for its geometry,
/// even when required (`gltfpack -tc` requires `KHR_texture_basisu`).
pub const APPEARANCE_PREFIXES: [&str; 11] = [
    "KHR_materials_",
    "KHR_texture_",
    "EXT_texture_",
    "MSFT_texture_",
    "KHR_lights_",
    "EXT_lights_",
    "KHR_xmp",
    "EXT_materials_",
    "ADOBE_materials_",
    "MSFT_packing_",
    "KHR_techniques_webgl",
];

/// Runs `parse` with a panic inside the `gltf` crate turned into an error.
fn guarded<T>(file: &str, parse: impl FnOnce() -> Result<T>) -> Result<T> {
    match catch_unwind(AssertUnwindSafe(parse)) {
        Ok(result) => result,
        Err(_) => Err(Error::malformed(file.to_owned(), "gltf", "the glTF reader failed on malformed data")),
    }
}

/// Which buffer views and buffers reading geometry may touch: the views of every accessor a
/// mesh primitive uses for `POSITION`, `JOINTS_n`, `WEIGHTS_n`, its indices or a morph target's
/// `POSITION`, a skin's inverse bind matrices, or an animation sampler (sparse index and value
/// views included), their buffers, and for a meshopt-compressed view its compressed source.
/// For a `KHR_draco_mesh_compression` primitive: its Draco view instead of the accessors the
/// extension covers (and of its indices).
fn geometry_views(root: &::gltf::json::Root, raw: &Value) -> (Vec<bool>, Vec<bool>) {
    use ::gltf::json::mesh::Semantic;
    use ::gltf::json::validation::Checked;
    let mut accessors = vec![false; root.accessors.len()];
    let mut mark = |a: usize| {
        if let Some(x) = accessors.get_mut(a) {
            *x = true;
        }
    };
    let primitives = root
        .meshes
        .iter()
        .enumerate()
        .flat_map(|(m, mesh)| mesh.primitives.iter().enumerate().map(move |(p, x)| (m, p, x)));
    for (m, p, primitive) in primitives {
        // A Draco primitive's covered attributes and triangles come from its Draco data.
        let draco = |name: &str| gltf_draco::covers(raw, m, p, name);
        for (semantic, accessor) in &primitive.attributes {
            if matches!(semantic, Checked::Valid(Semantic::Positions | Semantic::Joints(_) | Semantic::Weights(_)))
                && !draco(&semantic.to_string())
            {
                mark(accessor.value());
            }
        }
        if raw.pointer(&format!("/meshes/{m}/primitives/{p}/extensions/{}", gltf_draco::EXTENSION)).is_none() {
            primitive.indices.iter().for_each(|a| mark(a.value()));
        }
        for target in primitive.targets.iter().flatten() {
            target.positions.iter().for_each(|a| mark(a.value()));
        }
    }
    root.skins.iter().filter_map(|s| s.inverse_bind_matrices).for_each(|a| mark(a.value()));
    for sampler in root.animations.iter().flat_map(|a| &a.samplers) {
        mark(sampler.input.value());
        mark(sampler.output.value());
    }
    let mut views = vec![false; root.buffer_views.len()];
    for accessor in root.accessors.iter().zip(&accessors).filter(|(_, used)| **used).map(|(a, _)| a) {
        let sparse = accessor.sparse.iter().flat_map(|s| [s.indices.buffer_view, s.values.buffer_view]);
        for v in accessor.buffer_view.into_iter().chain(sparse) {
            if let Some(x) = views.get_mut(v.value()) {
                *x = true;
            }
        }
    }
    for v in gltf_draco::views(raw) {
        if let Some(x) = views.get_mut(v) {
            *x = true;
        }
    }
    let mut buffers = vec![false; root.buffers.len()];
    for (v, view) in root.buffer_views.iter().enumerate().filter(|(v, _)| views[*v]) {
        let compressed = raw
            .pointer(&format!("/bufferViews/{v}"))
            .and_then(gltf_meshopt::object)
            .and_then(|(_, o)| o.get("buffer")?.as_u64());
        for b in std::iter::once(view.buffer.value()).chain(compressed.map(|b| b as usize)) {
            if let Some(x) = buffers.get_mut(b) {
                *x = true;
            }
        }
    }
    (views, buffers)
}

/// Loads every buffer geometry reading uses (see the module docs for the sources accepted);
/// the others stay empty and are never opened.
fn load_buffers(
    file: &str,
    document: &::gltf::Document,
    base: Option<&Path>,
    mut blob: Option<Vec<u8>>,
    raw: &Value,
    budget: &mut Budget,
) -> Result<Vec<BufferData>> {
    let limits = super::reader_limits();
    let (used_views, used_buffers) = geometry_views(document.as_json(), raw);
    let mut buffers = Vec::with_capacity(document.buffers().len());
    for buffer in document.buffers() {
        let index = buffer.index();
        let declared = buffer.length();
        if !used_buffers[index] {
            buffers.push(BufferData(Vec::new()));
            continue;
        }
        // Every buffer is held at once: their declared lengths count as one total.
        budget.take("the buffers' byteLength", declared as u64)?;
        limits.check_alloc("gltf", "buffers", declared as u64)?;
        let data = match buffer.source() {
            // A KHR/EXT_meshopt_compression fallback buffer: filled by decoding the views below.
            ::gltf::buffer::Source::Bin if gltf_meshopt::is_fallback(raw, index) => vec![0; declared],
            ::gltf::buffer::Source::Bin => blob.take().ok_or_else(|| {
                bad(file, "buffers", format!("buffer {index} refers to a GLB BIN chunk the file lacks"))
            })?,
            ::gltf::buffer::Source::Uri(uri) => read_uri(file, index, uri, base, declared, &limits, budget)?,
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
    gltf_meshopt::decode_views(file, raw, &mut buffers, &used_views, &limits)?;
    Ok(buffers)
}

/// Reads a buffer URI: `data:[type];base64,...`, or a percent-encoded relative path inside
/// `base` (see [`read_external`]).
fn read_uri(
    file: &str,
    index: usize,
    uri: &str,
    base: Option<&Path>,
    declared: usize,
    limits: &Limits,
    budget: &mut Budget,
) -> Result<Vec<u8>> {
    let fail = |detail: String| bad(file, "buffers", format!("buffer {index}: {detail}"));
    if let Some(rest) = uri.strip_prefix("data:") {
        let payload = rest
            .split_once(";base64,")
            .map(|(_, data)| data)
            .ok_or_else(|| fail("a data URI that is not base64".into()))?;
        // Decoded size is at most 3/4 of the text; refuse before decoding a huge string.
        let decoded = (payload.len() / 4 * 3) as u64;
        limits.check_alloc("gltf", "buffers", decoded)?;
        // byteLength is already counted; a URI may hold more than it declares.
        budget.take("a data: URI's decoded bytes", decoded.saturating_sub(declared as u64))?;
        return base64::engine::general_purpose::STANDARD
            .decode(payload)
            .map_err(|e| fail(format!("invalid base64 in data URI ({e})")));
    }
    if uri.contains(':') {
        // `file:` URIs name absolute paths; other schemes (http:, …) are not fetched.
        return Err(fail(format!(
            "unsupported URI scheme in '{}' (only relative paths and data: URIs)",
            printable(uri)
        )));
    }
    let path = percent_encoding::percent_decode_str(uri)
        .decode_utf8()
        .map_err(|_| fail(format!("URI '{}' is not valid percent-encoded UTF-8", printable(uri))))?
        .into_owned();
    let base =
        base.ok_or_else(|| fail(format!("external file '{}' but no directory to resolve it in", printable(&path))))?;
    let data =
        read_external(base, &path, declared).map_err(|detail| fail(format!("'{}': {detail}", printable(&path))))?;
    // An input of the command like the file itself: never an output.
    crate::output::note_read(&base.join(&path), Some(format!("the external buffer '{}' of {file}", printable(&path))));
    Ok(data)
}

/// Reads the first `declared` bytes of `relative` inside `folder`: a relative path of plain
/// components (no root, no `..`), which after resolving symbolic links still lies inside the
/// folder, names a regular file (not a FIFO, device or directory: those could block or never
/// end) and holds at least `declared` bytes. The file is checked before it is opened and the
/// opened handle again (same file, still regular), so a swap in between is noticed; only a
/// FIFO swapped in during that instant could still block the open.
fn read_external(folder: &Path, relative: &str, declared: usize) -> std::result::Result<Vec<u8>, String> {
    let path = Path::new(relative);
    let plain = path.components().all(|c| matches!(c, Component::Normal(_) | Component::CurDir));
    if relative.is_empty() || !plain {
        return Err(
            "not a relative path inside the glTF file's folder (absolute paths and '..' are not followed)".into()
        );
    }
    let folder = folder.canonicalize().map_err(|e| format!("cannot resolve the glTF file's folder: {e}"))?;
    let real = folder.join(path).canonicalize().map_err(|e| format!("cannot open: {e}"))?;
    if !real.starts_with(&folder) {
        return Err("leads outside the glTF file's folder (through a symbolic link)".into());
    }
    let meta = std::fs::metadata(&real).map_err(|e| format!("cannot open: {e}"))?;
    if !meta.is_file() {
        return Err("not a regular file".into());
    }
    if meta.len() < declared as u64 {
        return Err(format!("holds {} bytes but the buffer declares byteLength {declared}", meta.len()));
    }
    let opened = std::fs::File::open(&real).map_err(|e| format!("cannot open: {e}"))?;
    let now = opened.metadata().map_err(|e| format!("cannot open: {e}"))?;
    #[cfg(unix)]
    let same = {
        use std::os::unix::fs::MetadataExt;
        now.dev() == meta.dev() && now.ino() == meta.ino()
    };
    #[cfg(not(unix))]
    let same = true;
    if !(now.is_file() && same) {
        return Err("changed while being opened".into());
    }
    let mut data = Vec::with_capacity(declared);
    std::io::Read::read_to_end(&mut std::io::Read::take(opened, declared as u64), &mut data)
        .map_err(|e| format!("cannot read: {e}"))?;
    Ok(data)
}

/// `asset.version` must be 2.x (and `asset.minVersion`, when given, 2.0): a glTF 3 file may
/// mean anything.
fn check_version(file: &str, raw: &Value) -> Result<()> {
    let major =
        |v: &str| v.split_once('.').filter(|(_, minor)| minor.parse::<u32>().is_ok()).map(|(m, _)| m.to_owned());
    let version = raw.pointer("/asset/version").and_then(Value::as_str);
    match version {
        None => return Err(bad(file, "asset.version", "missing (a glTF 2.0 file says \"2.0\")")),
        Some(v) if major(v).as_deref() != Some("2") => {
            return Err(bad(file, "asset.version", format!("'{}' is not 2.x; only glTF 2 is read", printable(v))))
        }
        Some(_) => {}
    }
    if let Some(min) = raw.pointer("/asset/minVersion") {
        if min.as_str() != Some("2.0") {
            return Err(bad(file, "asset.minVersion", format!("{min} is not 2.0; only glTF 2.0 is read")));
        }
    }
    Ok(())
}

/// Every required extension must be implemented here or describe appearance only (see the
/// module docs); the others are refused by name.
fn check_required_extensions(file: &str, raw: &Value) -> Result<()> {
    let Some(required) = raw.get("extensionsRequired") else { return Ok(()) };
    let list = required.as_array().ok_or_else(|| bad(file, "extensionsRequired", "not an array"))?;
    for name in list {
        let name = name.as_str().ok_or_else(|| bad(file, "extensionsRequired", format!("{name} is not a name")))?;
        let appearance = APPEARANCE_PREFIXES.iter().any(|p| name.starts_with(p));
        if !(SUPPORTED_EXTENSIONS.contains(&name) || appearance) {
            return Err(Error::Unsupported {
                context: file.to_owned().into(),
                detail: format!(
                    "the file requires extension {}, which may change the geometry and is not supported \
                     (supported: {}; appearance-only extensions are ignored)",
                    printable(name),
                    SUPPORTED_EXTENSIONS.join(", ")
                ),
            });
        }
    }
    Ok(())
}

/// The document without what this reader never uses and the `gltf` crate would validate:
/// materials, textures, images, samplers (and the primitives' material references). Texture
/// extensions such as `KHR_texture_basisu` move a texture's `source` into the extension, which
/// the crate's own schema would refuse.
fn geometry_only(raw: &Value) -> Value {
    let mut v = raw.clone();
    if let Some(root) = v.as_object_mut() {
        for key in ["materials", "textures", "images", "samplers"] {
            root.remove(key);
        }
        root.remove("extensionsRequired");
    }
    for mesh in v.get_mut("meshes").and_then(Value::as_array_mut).into_iter().flatten() {
        for primitive in mesh.get_mut("primitives").and_then(Value::as_array_mut).into_iter().flatten() {
            if let Some(p) = primitive.as_object_mut() {
                p.remove("material");
            }
        }
    }
    v
}

/// Splits a GLB (or takes glTF JSON), checks its version and required extensions, drops what
/// is not geometry ([`geometry_only`]), deserializes it, checks every index in it
/// ([`check_indices`]) and only then lets the `gltf` crate validate it (its validation indexes
/// arrays unchecked in places: a `POSITION` accessor index out of range panics there).
fn parse_document(bytes: &[u8], file: &str, budget: &mut Budget) -> Result<(::gltf::Document, Option<Vec<u8>>, Value)> {
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
        (glb.json, glb.bin.map(|b| b.into_owned()))
    } else {
        (std::borrow::Cow::Borrowed(bytes), None)
    };
    // The JSON is held parsed twice (the raw value and the document), data: URIs included:
    // counted before parsing, so a huge inline buffer is refused by the budget instead of
    // being copied (uncounted, a 160 MB data: URI holds 632 MB under --max-memory 64M).
    budget.take("the glTF JSON, parsed (twice)", (json.len() as u64).saturating_mul(2))?;
    let raw: Value = serde_json::from_slice(&json).map_err(|e| bad(file, "gltf", e.to_string()))?;
    check_version(file, &raw)?;
    check_required_extensions(file, &raw)?;
    let root: ::gltf::json::Root =
        serde_json::from_value(geometry_only(&raw)).map_err(|e| bad(file, "gltf", e.to_string()))?;
    check_indices(file, &root)?;
    let document = validate(file, root, &raw)?;
    Ok((document, blob, raw))
}

/// The `gltf` crate's validation of the document, except for one rule the Draco extension
/// lifts: an accessor that a `KHR_draco_mesh_compression` primitive fills from its Draco data
/// (an attribute the extension names, or the primitive's indices) has no `bufferView` (the
/// extension's spec: "must not define the bufferView and sparse properties"), which the crate
/// reports as missing data.
fn validate(file: &str, root: ::gltf::json::Root, raw: &Value) -> Result<::gltf::Document> {
    use ::gltf::json::validation::{Error as Invalid, Validate};
    let mut draco_filled = vec![false; root.accessors.len()];
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if raw.pointer(&format!("/meshes/{m}/primitives/{p}/extensions/{}", gltf_draco::EXTENSION)).is_none() {
                continue;
            }
            let covered = primitive
                .attributes
                .iter()
                .filter(|(semantic, _)| gltf_draco::covers(raw, m, p, &semantic.to_string()))
                .map(|(_, a)| a.value());
            for a in covered.chain(primitive.indices.map(|a| a.value())) {
                if let Some(x) = draco_filled.get_mut(a) {
                    *x = true;
                }
            }
        }
    }
    let lifted: Vec<String> = (0..root.accessors.len())
        .filter(|&a| draco_filled[a] && root.accessors[a].buffer_view.is_none())
        .map(|a| format!("accessors[{a}].bufferView"))
        .collect();
    let mut errors = Vec::new();
    root.validate(&root, ::gltf::json::Path::new, &mut |path, error| {
        let path = path();
        if !(matches!(error, Invalid::Missing) && lifted.contains(&path.to_string())) {
            errors.push((path, error));
        }
    });
    if !errors.is_empty() {
        return Err(bad(file, "gltf", ::gltf::Error::Validation(errors).to_string()));
    }
    Ok(::gltf::Document::from_json_without_validation(root))
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
            while !self.bin.len().is_multiple_of(4) {
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
            let per = match ty {
                "VEC3" => 3,
                "VEC4" => 4,
                "MAT4" => 16,
                _ => 1,
            };
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

        /// JOINTS_n data: four u16 joint indices per vertex.
        fn joints(&mut self, v: &[u16]) -> usize {
            let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
            self.push(&bytes, v.len() / 4, "VEC4", 5123)
        }

        /// A whole document with the given nodes, scene roots, meshes, skins and animations.
        fn scene_document(&self, nodes: Value, roots: Value, meshes: Value, skins: Value, animations: Value) -> Value {
            json!({
                "asset": {"version": "2.0"},
                "scene": 0, "scenes": [{"nodes": roots}], "nodes": nodes,
                "meshes": meshes, "skins": skins, "animations": animations,
                "buffers": [{"byteLength": self.bin.len()}], "bufferViews": self.views, "accessors": self.accessors
            })
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
            while !json_bytes.len().is_multiple_of(4) {
                json_bytes.push(b' ');
            }
            let mut bin = self.bin.clone();
            while !bin.len().is_multiple_of(4) {
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
        // Default rate: the key grid's (keys 1 s apart: 1 fps, 3 frames).
        let own = read_animation(&path, &ReadOptions::default()).unwrap();
        assert_eq!((own.frame_count(), own.frame_rate()), (3, 1.0));

        let (b, doc) = morph_triangle("STEP", None);
        let path = write_gltf(&dir, &b, &doc);
        let a = read_animation(&path, &opts).unwrap();
        assert_eq!(offsets(&a), vec![(0., 0.), (0., 0.), (1., 0.), (1., 0.), (0., 1.)]);
    }

    /// A data: URI's text (parsed twice with the JSON) and its decoded bytes beyond its
    /// byteLength both count against the budget, before the parse and before the decoding
    /// (probe gltf-memory).
    #[test]
    fn a_data_uri_counts_its_text_and_decoded_bytes() {
        let (b, doc) = morph_triangle("LINEAR", None);
        let mut inline = doc.clone();
        let mut padded = b.bin.clone();
        padded.resize(b.bin.len() + 300_000, 0);
        let encoded = base64::engine::general_purpose::STANDARD.encode(&padded);
        inline["buffers"][0]["uri"] = json!(format!("data:application/octet-stream;base64,{encoded}"));
        let bytes = serde_json::to_vec(&inline).unwrap();
        let read = |budget: u64| {
            let selection = GltfSelection { frame_rate: Some(2.0), memory_budget: Some(budget), ..Default::default() };
            parse_gltf_with(&bytes, None, "d.gltf", &selection)
        };
        // The text (400 kB) twice is over 600 kB.
        let e = read(600_000).unwrap_err().to_string();
        assert!(e.contains("glTF JSON") && e.contains("--max-memory"), "{e}");
        // Within 1.1 MB for the text, the 300 kB decoded beyond byteLength are not.
        let e = read(1_100_000).unwrap_err().to_string();
        assert!(e.contains("data: URI") && e.contains("--max-memory"), "{e}");
        assert_eq!(read(2_000_000).unwrap().vertex_count(), 3);
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
        // (8/16-bit positions are KHR_mesh_quantization's; 32-bit integers are not allowed.)
        let mut wrong_type = d.clone();
        wrong_type["accessors"][0]["componentType"] = json!(5125);
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

    /// Indices out of range are found before the `gltf` crate follows them (its
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
            // An unknown channel path (found by fuzzing read_gltf) panics in the gltf crate.
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

    /// A GLB header declaring a total length below 12 bytes (found by fuzzing read_gltf) is an
    /// error, not the `gltf` crate's subtraction with overflow.
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

    fn assert_close(got: [f32; 3], expected: [f64; 3], what: &str) {
        let ok = got.iter().zip(expected).all(|(g, e)| (*g as f64 - e).abs() <= 1e-5);
        assert!(ok, "{what}: got {got:?}, expected {expected:?}");
    }

    /// A two-bone skin whose positions can be worked out by hand.
    ///
    /// Nodes: 0 = bone 0 at the origin (child: 1), 1 = bone 1 at (0, 1, 0) carrying a rigid
    /// triangle (mesh 1), 2 = the skinned mesh node, translated by (100, 0, 0), which the spec
    /// says to ignore. Scene roots [0, 2]: vertex order = mesh 1 (node 1, reached through node 0)
    /// then mesh 0 (node 2). Mesh 0: v0 = (1, 0, 0) on bone 0; v1 = (1, 1, 0) half on each bone,
    /// with bone 1 in the second influence set (JOINTS_1/WEIGHTS_1) and unnormalized weights
    /// 1 + 1; v2 = (1, 2, 0) on bone 1; one morph target (+1, 0, 0) at default weight 0.5.
    /// Inverse bind matrices: identity and translate(0, −1, 0). Animation "Bend": bone 0
    /// translates (0,0,0) → (0,0,2) and bone 1 rotates 0° → 90° about z over 1 s (LINEAR).
    fn two_bone_skin() -> (Builder, Value) {
        let mut b = Builder::new();
        let positions = b.f32s(&[1., 0., 0., 1., 1., 0., 1., 2., 0.], "VEC3");
        let morph = b.f32s(&[1., 0., 0., 1., 0., 0., 1., 0., 0.], "VEC3");
        let joints0 = b.joints(&[0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0]);
        let weights0 = b.f32s(&[1., 0., 0., 0., 1., 0., 0., 0., 1., 0., 0., 0.], "VEC4");
        let joints1 = b.joints(&[0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0]);
        let weights1 = b.f32s(&[0., 0., 0., 0., 1., 0., 0., 0., 0., 0., 0., 0.], "VEC4");
        let rigid = b.f32s(&[0., 0., 0., 1., 0., 0., 0., 0., 1.], "VEC3");
        let mut ibm = vec![0f32; 32];
        for k in 0..4 {
            ibm[5 * k] = 1.0;
            ibm[16 + 5 * k] = 1.0;
        }
        ibm[16 + 13] = -1.0;
        let ibm = b.f32s(&ibm, "MAT4");
        let times = b.f32s(&[0., 1.], "SCALAR");
        let moves = b.f32s(&[0., 0., 0., 0., 0., 2.], "VEC3");
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let turns = b.f32s(&[0., 0., 0., 1., 0., 0., h, h], "VEC4");
        let nodes = json!([
            {"name": "bone0", "children": [1]},
            {"name": "bone1", "translation": [0, 1, 0], "mesh": 1},
            {"name": "skinned", "translation": [100, 0, 0], "mesh": 0, "skin": 0}
        ]);
        let meshes = json!([
            {"weights": [0.5], "primitives": [{"attributes": {"POSITION": positions,
                "JOINTS_0": joints0, "WEIGHTS_0": weights0, "JOINTS_1": joints1, "WEIGHTS_1": weights1},
                "targets": [{"POSITION": morph}]}]},
            {"primitives": [{"attributes": {"POSITION": rigid}}]}
        ]);
        let skins = json!([{"joints": [0, 1], "inverseBindMatrices": ibm}]);
        let animations = json!([{"name": "Bend",
            "samplers": [{"input": times, "output": moves}, {"input": times, "output": turns}],
            "channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}},
                         {"sampler": 1, "target": {"node": 1, "path": "rotation"}}]}]);
        let doc = b.scene_document(nodes, json!([0, 2]), meshes, skins, animations);
        (b, doc)
    }

    #[test]
    fn two_bone_skin_matches_the_hand_computed_positions() {
        let (b, doc) = two_bone_skin();
        let glb = b.glb(&doc);
        let read = |fps: f32| {
            let selection =
                GltfSelection { animation: Some("Bend".into()), frame_rate: Some(fps), ..Default::default() };
            parse_gltf_with(&glb, None, "skin.glb", &selection).unwrap()
        };
        let a = read(1.0);
        assert_eq!((a.vertex_count(), a.frame_count()), (6, 2));
        // Mesh 1 (node 1) first, then the skinned mesh 0, re-indexed.
        assert_eq!(a.triangles(), &[[0, 1, 2], [3, 4, 5]]);
        // Rest (t = 0): bone 1 at (0, 1, 0); the skin reproduces the bind pose + morph (0.5, 0, 0).
        assert_close(a.vertex(0, 0), [0., 1., 0.], "rigid vertex 0 at rest");
        assert_close(a.vertex(0, 3), [1.5, 0., 0.], "v0 at rest");
        assert_close(a.vertex(0, 4), [1.5, 1., 0.], "v1 at rest");
        assert_close(a.vertex(0, 5), [1.5, 2., 0.], "v2 at rest");
        // t = 1: bone 0 moved to z = 2, bone 1 turned 90°. v2: (1.5, 2, 0) − (0, 1, 0) = (1.5, 1, 0),
        // turned: (−1, 1.5, 0), + (0, 1, 0) + (0, 0, 2) = (−1, 2.5, 2). v1: the mean of bone 0's
        // (1.5, 1, 2) and bone 1's (0, 2.5, 2). The node's own (100, 0, 0) is ignored.
        assert_close(a.vertex(1, 0), [0., 1., 2.], "rigid vertex 0 at t = 1");
        assert_close(a.vertex(1, 1), [0., 2., 2.], "rigid vertex 1 at t = 1");
        assert_close(a.vertex(1, 3), [1.5, 0., 2.], "v0 at t = 1");
        assert_close(a.vertex(1, 4), [0.75, 1.75, 2.], "v1 at t = 1");
        assert_close(a.vertex(1, 5), [-1., 2.5, 2.], "v2 at t = 1");
        // t = 0.25 (4 fps, frame 1): slerp gives 22.5° (a normalized linear blend ≈ 21.6°).
        let a = read(4.0);
        assert_eq!(a.frame_count(), 5);
        let (c, s) = (22.5f64.to_radians().cos(), 22.5f64.to_radians().sin());
        // v2: (1.5, 1, 0) turned by 22.5°, + (0, 1, 0) + (0, 0, 0.5).
        assert_close(a.vertex(1, 5), [1.5 * c - s, 1.5 * s + c + 1.0, 0.5], "v2 at t = 0.25");
        // The same file picked by index, and by default (the first animation).
        let by_index = GltfSelection { animation: Some("0".into()), frame_rate: Some(1.0), ..Default::default() };
        assert_eq!(parse_gltf_with(&glb, None, "skin.glb", &by_index).unwrap().positions(), read(1.0).positions());
        // Default rate: the keys' own (1 s apart → 1 fps).
        let own = parse_gltf_with(&glb, None, "skin.glb", &GltfSelection::default()).unwrap();
        assert_eq!((own.frame_rate(), own.frame_count()), (1.0, 2));
    }

    #[test]
    fn step_translation_and_cubic_rotation_on_a_node() {
        let mut b = Builder::new();
        let positions = b.f32s(&[1., 0., 0., 0., 1., 0., 0., 0., 1.], "VEC3");
        let steps = b.f32s(&[0., 1., 2.], "SCALAR");
        let moves = b.f32s(&[0., 0., 0., 1., 0., 0., 2., 0., 0.], "VEC3");
        let ends = b.f32s(&[0., 2.], "SCALAR");
        let h = std::f32::consts::FRAC_1_SQRT_2;
        // Cubic keys: (in-tangent, value, out-tangent) per key, zero tangents: 0° → 90° about z.
        let z = [0f32; 4];
        let turns = b.f32s(&[z, [0., 0., 0., 1.], z, z, [0., 0., h, h], z].concat(), "VEC4");
        let nodes = json!([{"mesh": 0}]);
        let meshes = json!([{"primitives": [{"attributes": {"POSITION": positions}}]}]);
        let animations = json!([{"samplers": [
                {"input": steps, "output": moves, "interpolation": "STEP"},
                {"input": ends, "output": turns, "interpolation": "CUBICSPLINE"}],
            "channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}},
                         {"sampler": 1, "target": {"node": 0, "path": "rotation"}}]}]);
        let doc = b.scene_document(nodes, json!([0]), meshes, json!([]), animations);
        let selection = GltfSelection { animation: None, frame_rate: Some(2.0), ..Default::default() };
        let a = parse_gltf_with(&b.glb(&doc), None, "node.glb", &selection).unwrap();
        assert_eq!(a.frame_count(), 5);
        // Hermite with zero tangents at s: h00·q0 + h01·q1, normalized.
        let angle = |s: f64| {
            let (h00, h01) = (2. * s * s * s - 3. * s * s + 1., -2. * s * s * s + 3. * s * s);
            let half = std::f64::consts::FRAC_PI_4;
            2.0 * (h01 * half.sin()).atan2(h00 + h01 * half.cos())
        };
        for (frame, step_x) in [(0, 0.0), (1, 0.0), (2, 1.0), (3, 1.0), (4, 2.0)] {
            let theta = angle(frame as f64 / 4.0);
            assert_close(a.vertex(frame, 0), [step_x + theta.cos(), theta.sin(), 0.], &format!("frame {frame}"));
        }
        assert!((angle(0.5) - std::f64::consts::FRAC_PI_4).abs() < 1e-12, "symmetric at the midpoint");
        assert_close(a.vertex(4, 0), [2., 1., 0.], "last key");
    }

    #[test]
    fn malformed_skins_and_scenes_are_errors_naming_the_problem() {
        let (b, doc) = two_bone_skin();
        let check = |doc: &Value, expected: &str| {
            let e = parse_gltf(&b.glb(doc), None, "bad.glb", 30.0).unwrap_err().to_string();
            assert!(e.contains("bad.glb") && e.contains(expected), "{e} (expected '{expected}')");
            assert!(!e.contains("reader failed"), "the gltf crate panicked: {e}");
        };
        type Mutation = Box<dyn Fn(&mut Value)>;
        let cases: Vec<(Mutation, &str)> = vec![
            (Box::new(|d| d["skins"][0]["joints"] = json!([0])), "uses joint 1 but skin 0 has 1 joints"),
            (Box::new(|d| d["accessors"][7]["count"] = json!(1)), "1 inverse bind matrices for 2 joints"),
            (Box::new(|d| d["accessors"][7]["type"] = json!("MAT3")), "inverseBindMatrices"),
            (Box::new(|d| d["nodes"][2]["children"] = json!([1])), "child of both node 0 and node 2"),
            (Box::new(|d| d["nodes"][1]["children"] = json!([0])), "cycle"),
            (
                Box::new(|d| {
                    let attributes = d["meshes"][0]["primitives"][0]["attributes"].as_object_mut().unwrap();
                    attributes.remove("WEIGHTS_1");
                }),
                "JOINTS_1 but no WEIGHTS_1",
            ),
            (
                Box::new(|d| {
                    let attributes = d["meshes"][0]["primitives"][0]["attributes"].as_object_mut().unwrap();
                    for k in ["JOINTS_0", "WEIGHTS_0", "JOINTS_1", "WEIGHTS_1"] {
                        attributes.remove(k);
                    }
                }),
                "has no JOINTS_0",
            ),
            (Box::new(|d| d["accessors"][2]["type"] = json!("VEC3")), "JOINTS"),
            (Box::new(|d| d["animations"][0]["channels"][1]["target"]["path"] = json!("weights")), "no morph targets"),
            (Box::new(|d| d["animations"][0]["channels"][1]["target"]["path"] = json!("scale")), "expected"),
            (
                Box::new(|d| d["nodes"][0]["matrix"] = json!([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1])),
                "has a matrix",
            ),
            (Box::new(|d| d["scenes"][0]["nodes"] = json!([0])), "bad.glb"),
            (Box::new(|d| d["nodes"][2].as_object_mut().unwrap().remove("mesh").map(|_| ()).unwrap()), "bad.glb"),
        ];
        for (mutate, expected) in cases {
            let mut bad = doc.clone();
            mutate(&mut bad);
            if expected == "bad.glb" {
                // Still valid: fewer vertices (mesh 1 only), no error expected.
                assert!(parse_gltf(&b.glb(&bad), None, "bad.glb", 30.0).is_ok());
                continue;
            }
            check(&bad, expected);
        }
        // A joint out of range with zero weight is ignored (real exporters write joint 0 / weight 0
        // padding, some write garbage indices there).
        let mut padded = doc.clone();
        let mut b2 = Builder { bin: b.bin.clone(), views: b.views.clone(), accessors: b.accessors.clone() };
        let junk = b2.joints(&[0, 77, 0, 0, 0, 77, 0, 0, 1, 77, 0, 0]);
        padded["accessors"] = json!(b2.accessors);
        padded["bufferViews"] = json!(b2.views);
        padded["buffers"][0]["byteLength"] = json!(b2.bin.len());
        padded["meshes"][0]["primitives"][0]["attributes"]["JOINTS_0"] = json!(junk);
        assert_eq!(
            parse_gltf(&b2.glb(&padded), None, "pad.glb", 1.0).unwrap().positions(),
            parse_gltf(&b.glb(&doc), None, "pad.glb", 1.0).unwrap().positions()
        );
        // Animations by name: a missing one lists what the file has.
        let selection = GltfSelection { animation: Some("Jump".into()), ..Default::default() };
        let e = parse_gltf_with(&b.glb(&doc), None, "skin.glb", &selection).unwrap_err().to_string();
        assert!(e.contains("no animation named or numbered 'Jump'") && e.contains("0 'Bend'"), "{e}");
        let selection = GltfSelection { animation: Some("3".into()), ..Default::default() };
        assert!(parse_gltf_with(&b.glb(&doc), None, "skin.glb", &selection).is_err());
    }

    #[test]
    fn corrupted_skinned_files_give_results_not_crashes() {
        let (b, doc) = two_bone_skin();
        let glb = b.glb(&doc);
        let mut accepted = 0;
        for i in (0..glb.len()).step_by(3) {
            for v in [0u8, 0x7f, 0xff] {
                let mut m = glb.clone();
                m[i] = v;
                if let Ok(a) = parse_gltf(&m, None, "m.glb", 3.0) {
                    assert!(a.positions().iter().all(|x| x.is_finite()));
                    accepted += 1;
                }
            }
        }
        assert!(accepted > 0);
    }

    /// EXT_meshopt_compression + KHR_mesh_quantization (as our writer produces them) are read;
    /// malformed extension data is an error naming the view, never a panic.
    #[test]
    fn meshopt_compressed_quantized_files_are_read_and_checked() {
        use super::super::gltf_out::{encode_gltf, GltfLayout, GltfOptions};
        let a = animcodec_synth::waving_flag(8, 5, 6);
        let opts = GltfOptions { layout: GltfLayout::Frames, ..Default::default() };
        let (text, _) = encode_gltf(&a, &opts, false).unwrap();
        let doc: Value = serde_json::from_slice(&text).unwrap();
        let read = |d: &Value| parse_gltf(&serde_json::to_vec(d).unwrap(), None, "m.gltf", a.frame_rate());
        let b = read(&doc).unwrap();
        let worst = a.positions().iter().zip(b.positions()).map(|(x, y)| (x - y).abs()).fold(0f32, f32::max);
        assert!(worst < 2.5e-5 * a.bounding_box_diagonal() as f32, "{worst}");
        let view = (0..doc["bufferViews"].as_array().unwrap().len())
            .find(|&i| doc["bufferViews"][i]["extensions"]["EXT_meshopt_compression"]["mode"] == "ATTRIBUTES")
            .unwrap();
        fn ext(d: &mut Value, view: usize) -> &mut Value {
            &mut d["bufferViews"][view]["extensions"]["EXT_meshopt_compression"]
        }
        type Mutation = Box<dyn Fn(&mut Value)>;
        let cases: Vec<(Mutation, &str)> = vec![
            (Box::new(move |d| ext(d, view)["buffer"] = json!(7)), "buffer 7"),
            (Box::new(move |d| ext(d, view)["byteLength"] = json!(1u64 << 40)), "outside buffer"),
            (Box::new(move |d| ext(d, view)["mode"] = json!("WIGGLE")), "unknown mode"),
            (Box::new(move |d| ext(d, view)["filter"] = json!("SPIRAL")), "unknown filter"),
            (Box::new(move |d| ext(d, view)["filter"] = json!(3)), "filter is not a string"),
            (Box::new(move |d| ext(d, view)["byteStride"] = json!(6)), "byteStride 6"),
            (Box::new(move |d| ext(d, view)["count"] = json!(1u64 << 40)), "EXT_meshopt_compression"),
            (Box::new(move |d| ext(d, view)["byteLength"] = json!(3)), "implausibly large"),
            (Box::new(move |d| d["bufferViews"][view]["byteOffset"] = json!(1u64 << 30)), "do not fit"),
        ];
        for (mutate, expected) in cases {
            let mut bad = doc.clone();
            mutate(&mut bad);
            let e = read(&bad).unwrap_err().to_string();
            assert!(e.contains("m.gltf") && e.contains(expected), "{e} (expected '{expected}')");
        }
        // Corrupted compressed bytes (GLB form): a result, never a crash.
        let (glb, _) = encode_gltf(&a, &opts, true).unwrap();
        let mut accepted = 0;
        for i in (0..glb.len()).step_by(2) {
            for v in [0u8, 0x5a, 0xff] {
                let mut m = glb.clone();
                m[i] = v;
                if let Ok(b) = parse_gltf(&m, None, "m.glb", a.frame_rate()) {
                    assert!(b.positions().iter().all(|x| x.is_finite()));
                    accepted += 1;
                }
            }
        }
        assert!(accepted > 0);
        // Without the extension's data the fallback buffer holds zeros: no crash either way.
        let mut stripped = doc.clone();
        stripped["bufferViews"][view].as_object_mut().unwrap().remove("extensions");
        assert!(read(&stripped).is_ok());
    }

    /// One triangle mesh (accessor 0: positions, 1: indices) in a GLB with the given nodes/roots.
    fn triangle_builder() -> (Builder, Value) {
        let mut b = Builder::new();
        let base = b.f32s(&[0., 0., 0., 1., 0., 0., 0., 1., 0.], "VEC3");
        let idx = b.u16s(&[0, 1, 2]);
        let meshes = json!([{"primitives": [{"attributes": {"POSITION": base}, "indices": idx}]}]);
        (b, meshes)
    }

    fn parse_glb(b: &Builder, doc: &Value) -> Result<Animation> {
        parse_gltf(&b.glb(doc), None, "t.glb", 30.0)
    }

    fn assert_fails(result: Result<Animation>, expected: &[&str]) {
        let Err(e) = result else { panic!("expected an error naming {expected:?}") };
        let e = e.to_string();
        assert!(expected.iter().all(|x| e.contains(x)), "{e} (expected {expected:?})");
    }

    #[test]
    fn scene_roots_that_are_descendants_play_each_mesh_once() {
        // A chain 0 → 1 → … → N−1, each node moved by x + 1 and carrying the mesh, with every
        // node listed as a scene root: each mesh instance is played once, in chain order (before
        // the fix the walk visited N²/2 nodes and played node k k+1 times).
        const N: usize = 1000;
        let (b, meshes) = triangle_builder();
        let nodes: Vec<Value> = (0..N)
            .map(|k| {
                let mut node = json!({"mesh": 0, "translation": [1, 0, 0]});
                if k + 1 < N {
                    node["children"] = json!([k + 1]);
                }
                node
            })
            .collect();
        let roots: Vec<usize> = (0..N).collect();
        let doc = b.scene_document(json!(nodes), json!(roots), meshes, json!([]), json!([]));
        let a = parse_glb(&b, &doc).unwrap();
        assert_eq!(a.vertex_count(), 3 * N);
        for k in 0..N {
            assert_eq!(a.vertex(0, 3 * k), [(k + 1) as f32, 0.0, 0.0], "instance {k}");
        }
    }

    #[test]
    fn absurd_morph_target_and_joint_set_counts_fail_before_reading() {
        let (mut b, _) = triangle_builder();
        let joints = b.joints(&[0; 12]);
        let weights = b.f32s(&[1.0; 12], "VEC4");
        let doc_with = |b: &Builder, attributes: Value, targets: Value| {
            let meshes = json!([{"primitives": [{"attributes": attributes, "indices": 1, "targets": targets}]}]);
            b.scene_document(json!([{"mesh": 0}]), json!([0]), meshes, json!([]), json!([]))
        };
        // Many targets all naming one accessor.
        let targets: Vec<Value> = (0..5000).map(|_| json!({"POSITION": 0})).collect();
        let doc = doc_with(&b, json!({"POSITION": 0}), json!(targets));
        assert_fails(parse_glb(&b, &doc), &["t.glb", "targets", "5000", "4096"]);
        // Nine JOINTS_n/WEIGHTS_n sets.
        let mut attributes = json!({"POSITION": 0});
        for s in 0..9 {
            attributes[format!("JOINTS_{s}")] = json!(joints);
            attributes[format!("WEIGHTS_{s}")] = json!(weights);
        }
        let doc = doc_with(&b, attributes, json!([]));
        assert_fails(parse_glb(&b, &doc), &["t.glb", "JOINTS_n sets", "8"]);
        // A vertex count over the limit is refused before the positions are read.
        let mut doc = doc_with(&b, json!({"POSITION": 0}), json!([]));
        doc["accessors"][0]["count"] = json!(20_000_000);
        assert_fails(parse_glb(&b, &doc), &["t.glb", "vertex_count", "20000000"]);
        // 2M vertices × 200 targets would be 4.8 GB of positions: refused before reading.
        let targets: Vec<Value> = (0..200).map(|_| json!({"POSITION": 0})).collect();
        let mut doc = doc_with(&b, json!({"POSITION": 0}), json!(targets));
        doc["accessors"][0]["count"] = json!(2_000_000);
        assert_fails(parse_glb(&b, &doc), &["t.glb", "mesh vertex data", "targets"]);
    }

    #[test]
    fn overflowing_accessor_offsets_fail_by_name() {
        let (b, meshes) = triangle_builder();
        let mut doc = b.scene_document(json!([{"mesh": 0}]), json!([0]), meshes, json!([]), json!([]));
        doc["bufferViews"][0]["byteOffset"] = json!(u64::MAX - 8);
        doc["accessors"][0]["byteOffset"] = json!(16);
        assert_fails(parse_glb(&b, &doc), &["t.glb", "POSITION", "byteOffset", "overflows"]);
    }

    #[test]
    fn playback_work_is_bounded() {
        // 4000 nodes animated over 300 000 s at 30 fps (9·10⁶ frames of 3 vertices):
        // 3.6·10¹⁰ node transforms, refused before playing.
        const N: usize = 4000;
        let (mut b, meshes) = triangle_builder();
        let input = b.f32s(&[0., 300_000.], "SCALAR");
        let output = b.f32s(&[0., 0., 0., 1., 0., 0.], "VEC3");
        let mut nodes: Vec<Value> = (0..N).map(|_| json!({})).collect();
        nodes[0] = json!({"mesh": 0});
        let animations = json!([{"samplers": [{"input": input, "output": output}],
            "channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}}]}]);
        let doc = b.scene_document(json!(nodes), json!([0]), meshes, json!([]), animations);
        assert_fails(parse_glb(&b, &doc), &["t.glb", "playback work", "20000000000"]);
    }

    /// Mode INDICES (meshoptimizer's index sequence codec): the writer's plain index view
    /// re-encoded as an index sequence into a fallback buffer reads back the same triangles.
    #[test]
    fn meshopt_indices_mode_is_read() {
        use super::super::gltf_out::{encode_gltf, GltfLayout, GltfOptions};
        let a = animcodec_synth::waving_flag(8, 5, 6);
        let opts = GltfOptions { layout: GltfLayout::Frames, ..Default::default() };
        let (text, _) = encode_gltf(&a, &opts, false).unwrap();
        let mut doc: Value = serde_json::from_slice(&text).unwrap();
        let read = |d: &Value| parse_gltf(&serde_json::to_vec(d).unwrap(), None, "m.gltf", a.frame_rate());
        let expected = read(&doc).unwrap();
        let indices = doc["meshes"][0]["primitives"][0]["indices"].as_u64().unwrap() as usize;
        let view = doc["accessors"][indices]["bufferView"].as_u64().unwrap() as usize;
        let stride = if doc["accessors"][indices]["componentType"] == 5125 { 4 } else { 2 };
        let flat: Vec<u32> = expected.triangles().iter().flatten().copied().collect();
        let sequence = gltf_meshopt::encode_index_sequence(&flat);
        let uri = doc["buffers"][0]["uri"].as_str().unwrap().to_owned();
        let (prefix, data) = uri.split_once(";base64,").unwrap();
        let mut bytes = base64::engine::general_purpose::STANDARD.decode(data).unwrap();
        bytes.resize(bytes.len().next_multiple_of(4), 0);
        let offset = bytes.len();
        bytes.extend(&sequence);
        let encoded = base64::engine::general_purpose::STANDARD.encode(&bytes);
        doc["buffers"][0]["uri"] = json!(format!("{prefix};base64,{encoded}"));
        doc["buffers"][0]["byteLength"] = json!(bytes.len());
        let size = flat.len() * stride;
        let fallback = doc["buffers"].as_array().unwrap().len();
        doc["buffers"].as_array_mut().unwrap().push(
            json!({"byteLength": size.next_multiple_of(4), "extensions": {"EXT_meshopt_compression": {"fallback": true}}}),
        );
        doc["bufferViews"][view] = json!({"buffer": fallback, "byteOffset": 0, "byteLength": size,
            "extensions": {"EXT_meshopt_compression": {"buffer": 0, "byteOffset": offset,
                "byteLength": sequence.len(), "byteStride": stride, "count": flat.len(), "mode": "INDICES"}}});
        let back = read(&doc).unwrap();
        assert_eq!(back.triangles(), expected.triangles());
        assert_eq!(back.positions(), expected.positions());
        // A truncated sequence is an error naming the view.
        doc["bufferViews"][view]["extensions"]["EXT_meshopt_compression"]["byteLength"] = json!(sequence.len() - 1);
        assert_fails(read(&doc), &["m.gltf", &format!("bufferView {view}"), "INDICES data malformed"]);
    }

    #[test]
    fn meshopt_sizes_are_checked_before_decoding() {
        use super::super::gltf_out::{encode_gltf, GltfLayout, GltfOptions};
        let a = animcodec_synth::waving_flag(8, 5, 6);
        let opts = GltfOptions { layout: GltfLayout::Frames, ..Default::default() };
        let (text, _) = encode_gltf(&a, &opts, false).unwrap();
        let doc: Value = serde_json::from_slice(&text).unwrap();
        let read = |d: &Value| parse_gltf(&serde_json::to_vec(d).unwrap(), None, "m.gltf", a.frame_rate());
        let view = (0..doc["bufferViews"].as_array().unwrap().len())
            .find(|&i| doc["bufferViews"][i]["extensions"]["EXT_meshopt_compression"]["mode"] == "ATTRIBUTES")
            .unwrap();
        let ext = doc["bufferViews"][view]["extensions"]["EXT_meshopt_compression"].clone();
        let target = doc["bufferViews"][view]["buffer"].as_u64().unwrap() as usize;
        let stride = ext["byteStride"].as_u64().unwrap();
        let encoded = ext["byteLength"].as_u64().unwrap();
        // An output 65× the encoded size (more than the vertex codec can produce), with the view
        // and the target buffer declared large enough to hold it.
        let count = 65 * encoded / stride + 1;
        let mut big = doc.clone();
        big["bufferViews"][view]["extensions"]["EXT_meshopt_compression"]["count"] = json!(count);
        big["bufferViews"][view]["byteLength"] = json!(count * stride);
        big["bufferViews"][view]["byteOffset"] = json!(0);
        let target_length = doc["buffers"][target]["byteLength"].as_u64().unwrap();
        big["buffers"][target]["byteLength"] = json!(target_length.max(count * stride));
        assert_fails(read(&big), &["m.gltf", "EXT_meshopt_compression", "implausibly large"]);
        // An output that does not fit the target buffer is refused before decoding.
        let count = target_length / stride + 1;
        let mut outside = doc.clone();
        outside["bufferViews"][view]["extensions"]["EXT_meshopt_compression"]["count"] = json!(count);
        outside["bufferViews"][view]["byteLength"] = json!(count * stride);
        outside["bufferViews"][view]["byteOffset"] = json!(0);
        assert_fails(read(&outside), &["m.gltf", "EXT_meshopt_compression", "do not fit"]);
        // Fallback buffers no geometry view uses are never allocated; a used one counts
        // against the read's memory budget before it is.
        let mut many = doc.clone();
        let fallback = json!({"byteLength": 3u64 << 30, "extensions": {"EXT_meshopt_compression": {"fallback": true}}});
        many["buffers"].as_array_mut().unwrap().extend([fallback.clone(), fallback]);
        assert!(read(&many).is_ok());
        many["buffers"][target]["byteLength"] = json!(3u64 << 30);
        assert_fails(read(&many), &["m.gltf", "memory", "buffers' byteLength"]);
        // Mode INDICES on a vertex view (its byteStride is not an index size) is refused by name.
        let mut indices = doc.clone();
        indices["bufferViews"][view]["extensions"]["EXT_meshopt_compression"]["mode"] = json!("INDICES");
        assert_fails(read(&indices), &["m.gltf", "INDICES with byteStride"]);
    }

    #[test]
    fn reads_horse_glb_when_present() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/horse-glb/Horse.glb");
        if !path.is_file() {
            return codec_core::testing::skip("reads_horse_glb_when_present", &format!("{} not found", path.display()));
        }
        let a = read_animation(&path, &ReadOptions { frame_rate: Some(30.0), ..Default::default() }).unwrap();
        assert_eq!((a.vertex_count(), a.topology().triangle_count()), (796, 984));
        // 16 keys from 0 to 1.5 s: 46 frames at 30 fps, 16 at the keys' own 10 fps (the default).
        assert_eq!(a.frame_count(), 46);
        let at_keys = read_animation(&path, &ReadOptions::default()).unwrap();
        assert_eq!((at_keys.frame_count(), at_keys.frame_rate()), (16, 10.0));
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
