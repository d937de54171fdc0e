//! `KHR_draco_mesh_compression` on input: a primitive whose geometry is a Draco-compressed
//! mesh (Blender's glTF exporter writes them with its "Compression" option, and so do many web
//! pipelines), decoded with the `draco-core` crate (a pure-Rust Draco decoder: sequential and
//! EdgeBreaker connectivity, every prediction scheme, Draco's own dequantization).
//!
//! What is read, following the extension's specification (the Khronos
//! `KHR_draco_mesh_compression` README, "Conformance"):
//! - the extension's `bufferView` is decoded as one Draco mesh; its faces are the primitive's
//!   triangles, whatever the primitive's `indices` accessor holds (that accessor's `count`
//!   must be three per decoded face);
//! - an attribute named in the extension's `attributes` (`NAME: unique id`) is taken from the
//!   decoded attribute with that unique id: `POSITION`, and the skin's `JOINTS_n` /
//!   `WEIGHTS_n`. Its accessor gives only the `type`, `componentType`, `normalized` and a
//!   `count` that must equal the decoded point count; its `bufferView` (absent when only
//!   compressed data is stored) is never read. Attributes the extension does not name are
//!   read from their accessors as usual;
//! - morph targets are not covered by the extension and stay uncompressed accessors; each
//!   must hold one displacement per decoded point.
//!
//! **Vertex order**: the primitive's vertices are the decoded points in Draco's order, which
//! may differ from the order of the mesh before compression (EdgeBreaker renumbers points in
//! traversal order, and Draco splits or merges points at attribute seams). This is what
//! three.js's `DRACOLoader` does too. Comparing a Draco file with its uncompressed original
//! therefore needs vertex matching (`animcodec eval --match-vertices`). Encoders that write
//! morph targets next to a Draco primitive keep the point order (Blender's exporter switches
//! to Draco's order-preserving sequential method when a mesh has shape keys).
//!
//! **Values**: the decoder's own output: quantized attributes are dequantized as Draco defines
//! it (`q · range / (2ᵇ − 1) + min`, in `f32`); integer attributes are converted with the
//! accessor's `normalized` flag as the glTF spec says (`c / (2ᵇ − 1)` for unsigned, clamped
//! `c / (2ᵇ⁻¹ − 1)` for signed).
//!
//! **Untrusted data**: the Draco bytes are decoded under [`DecodeLimits`] taken from what is
//! left of the read's memory budget (`--max-memory`), so a crafted stream claiming millions of
//! faces is refused before they are built; every decoded face index and attribute value index
//! is checked before it is used, and every decoder error becomes an error naming the mesh, the
//! primitive and the buffer view.

use codec_core::{Error, Limits, Result};
use draco_core::{DataType as DracoType, DecodeLimits, DecoderBuffer, ErrorKind, Mesh, MeshDecoder, PointAttribute};
use serde_json::Value;

use super::gltf_buffers::{bad, printable, Budget, BufferData};

/// The extension's name.
pub const EXTENSION: &str = "KHR_draco_mesh_compression";

/// Bytes `draco-core` holds per decoded face while decoding a mesh, beyond the attribute
/// values [`DecodeLimits::max_decoded_bytes`] counts: the face list (12 bytes), the corner
/// table (opposite corner, vertex per corner and their reverse maps: about 6 × 4 bytes per
/// corner) and the traversal's scratch. Measured peak (see `docs/notes/issue-46.md`) is below
/// this bound; it turns the memory budget into a face ceiling.
const DECODER_BYTES_PER_FACE: u64 = 160;

/// A primitive's `KHR_draco_mesh_compression` object.
pub(super) struct Extension {
    /// The buffer view holding the Draco bytes.
    pub view: usize,
    /// `attributes`: glTF attribute name → Draco unique id.
    pub attributes: Vec<(String, u32)>,
}

impl Extension {
    /// The Draco unique id of glTF attribute `name`, if the extension covers it.
    pub fn id(&self, name: &str) -> Option<u32> {
        self.attributes.iter().find(|(n, _)| n == name).map(|(_, id)| *id)
    }
}

/// The extension object of mesh `m`'s primitive `p`, checked: `bufferView` an index below
/// `views`, `attributes` an object of unique ids (non-negative integers below 2³²). `None` when
/// the primitive has no such extension.
pub(super) fn extension(file: &str, raw: &Value, m: usize, p: usize, views: usize) -> Result<Option<Extension>> {
    let Some(ext) = raw.pointer(&format!("/meshes/{m}/primitives/{p}/extensions/{EXTENSION}")) else {
        return Ok(None);
    };
    let at = format!("mesh {m} primitive {p}: {EXTENSION}");
    let view = ext
        .get("bufferView")
        .and_then(Value::as_u64)
        .ok_or_else(|| bad(file, "extensions", format!("{at} has no bufferView index")))?;
    if view >= views as u64 {
        return Err(bad(file, "extensions", format!("{at} refers to bufferView {view}, but there are {views}")));
    }
    let map = ext
        .get("attributes")
        .and_then(Value::as_object)
        .ok_or_else(|| bad(file, "extensions", format!("{at} has no attributes object")))?;
    let mut attributes = Vec::with_capacity(map.len());
    for (name, id) in map {
        let id = id.as_u64().and_then(|id| u32::try_from(id).ok()).ok_or_else(|| {
            bad(
                file,
                "extensions",
                format!("{at}: attribute {} has unique id {id}, not a 32-bit index", printable(name)),
            )
        })?;
        attributes.push((name.clone(), id));
    }
    Ok(Some(Extension { view: view as usize, attributes }))
}

/// Every buffer view a Draco primitive of the document reads (to be loaded with the buffers).
pub(super) fn views(raw: &Value) -> Vec<usize> {
    let meshes = raw.get("meshes").and_then(Value::as_array).map(Vec::as_slice).unwrap_or(&[]);
    meshes
        .iter()
        .filter_map(|m| m.get("primitives").and_then(Value::as_array))
        .flatten()
        .filter_map(|p| p.pointer(&format!("/extensions/{EXTENSION}/bufferView")).and_then(Value::as_u64))
        .map(|v| v as usize)
        .collect()
}

/// True when the primitive's attribute `name` is read from the Draco data rather than its
/// accessor (its accessor's bufferView need not be loaded).
pub(super) fn covers(raw: &Value, m: usize, p: usize, name: &str) -> bool {
    raw.pointer(&format!("/meshes/{m}/primitives/{p}/extensions/{EXTENSION}/attributes/{name}")).is_some()
}

/// One decoded Draco primitive.
pub(super) struct Decoded {
    mesh: Mesh,
    /// The triangles, three point indices each, every index below [`Decoded::points`].
    pub triangles: Vec<u32>,
    at: String,
}

impl Decoded {
    /// The decoded point count: the primitive's vertex count.
    pub fn points(&self) -> usize {
        self.mesh.num_points()
    }

    /// The values of the attribute with Draco unique id `id`, `components` per point in point
    /// order, converted to `f64` (integers with the glTF `normalized` rule when `normalized`).
    /// `name` names the glTF attribute in errors. Fails when the attribute is missing, has
    /// fewer components, or a point maps to no stored value.
    pub fn values(&self, file: &str, name: &str, id: u32, components: usize, normalized: bool) -> Result<Vec<f64>> {
        let field = "extensions";
        let attribute = self.mesh.attribute_by_unique_id(id).ok_or_else(|| {
            bad(
                file,
                field,
                format!("{}: {} names Draco attribute {id}, which the data lacks", self.at, printable(name)),
            )
        })?;
        let have = attribute.num_components() as usize;
        if have < components {
            return Err(bad(
                file,
                field,
                format!(
                    "{}: {}'s Draco attribute has {have} components, {components} needed",
                    self.at,
                    printable(name)
                ),
            ));
        }
        read_values(attribute, self.points(), components, normalized).ok_or_else(|| {
            bad(
                file,
                field,
                format!(
                    "{}: {}'s Draco attribute {id} ({:?}) maps a point to no stored value",
                    self.at,
                    printable(name),
                    attribute.data_type()
                ),
            )
        })
    }
}

/// Reads `components` values per point of `attribute` (following its point → value map) as
/// `f64`; `None` when a point's value lies outside the stored data or the type is not numeric.
fn read_values(attribute: &PointAttribute, points: usize, components: usize, normalized: bool) -> Option<Vec<f64>> {
    let kind = attribute.data_type();
    let width = kind.byte_length();
    let stride = usize::try_from(attribute.byte_stride()).ok()?;
    let data = attribute.buffer().data();
    if width == 0 || stride < width.checked_mul(components)? {
        return None;
    }
    let mut out = Vec::with_capacity(points.checked_mul(components)?);
    for point in 0..points {
        let value = attribute.mapped_index(draco_core::PointIndex(u32::try_from(point).ok()?)).0 as usize;
        if value >= attribute.size() {
            return None;
        }
        let start = value.checked_mul(stride)?;
        let bytes = data.get(start..start.checked_add(width * components)?)?;
        for b in bytes.chunks_exact(width) {
            out.push(convert(kind, b, normalized)?);
        }
    }
    Some(out)
}

/// One little-endian component of type `kind` as `f64`: floats as they are, integers with the
/// glTF `normalized` rule when `normalized` (spec §3.11 "Animations"/accessors: unsigned
/// `c / (2ᵇ − 1)`, signed `max(c / (2ᵇ⁻¹ − 1), −1)`), else their integer value.
fn convert(kind: DracoType, b: &[u8], normalized: bool) -> Option<f64> {
    let (x, scale) = match kind {
        DracoType::Float32 => return Some(f32::from_le_bytes(b.try_into().ok()?) as f64),
        DracoType::Float64 => return Some(f64::from_le_bytes(b.try_into().ok()?)),
        DracoType::Int8 => (i8::from_le_bytes(b.try_into().ok()?) as f64, 127.0),
        DracoType::Uint8 | DracoType::Bool => (b[0] as f64, 255.0),
        DracoType::Int16 => (i16::from_le_bytes(b.try_into().ok()?) as f64, 32767.0),
        DracoType::Uint16 => (u16::from_le_bytes(b.try_into().ok()?) as f64, 65535.0),
        DracoType::Int32 => (i32::from_le_bytes(b.try_into().ok()?) as f64, 2147483647.0),
        DracoType::Uint32 => (u32::from_le_bytes(b.try_into().ok()?) as f64, 4294967295.0),
        DracoType::Int64 | DracoType::Uint64 | DracoType::Invalid => return None,
    };
    Some(if normalized { (x / scale).max(-1.0) } else { x })
}

/// The decoder's ceilings for one primitive: faces and decoded attribute bytes within what is
/// left of the read's memory budget (`budget`) and the reader's limits, points within the
/// vertex limit.
fn decode_limits(budget: &Budget, limits: &Limits) -> DecodeLimits {
    let memory = budget.remaining().min(limits.max_alloc_bytes as u64);
    DecodeLimits::default()
        .with_max_points(limits.max_vertices as u64)
        .with_max_faces((limits.max_triangles as u64).min(memory / DECODER_BYTES_PER_FACE))
        .with_max_decoded_bytes(memory)
}

/// Decodes mesh `m`'s primitive `p` ([`Extension::view`]'s bytes) under limits taken from
/// `budget`, and checks its faces: every index below the point count.
pub(super) fn decode(
    file: &str,
    m: usize,
    p: usize,
    ext: &Extension,
    document: &::gltf::Document,
    buffers: &[BufferData],
    budget: &Budget,
) -> Result<Decoded> {
    let at = format!("mesh {m} primitive {p} ({EXTENSION}, bufferView {})", ext.view);
    let view =
        document.views().nth(ext.view).ok_or_else(|| bad(file, "extensions", format!("{at}: no such bufferView")))?;
    let held = buffers.get(view.buffer().index()).map_or(&[][..], |b| &b.0[..]);
    let bytes =
        view.offset().checked_add(view.length()).and_then(|end| held.get(view.offset()..end)).ok_or_else(|| {
            bad(
                file,
                "extensions",
                format!(
                    "{at}: byteOffset {}, byteLength {} lie outside buffer {} ({} bytes)",
                    view.offset(),
                    view.length(),
                    view.buffer().index(),
                    held.len()
                ),
            )
        })?;
    let limits = super::reader_limits();
    let mut input = DecoderBuffer::new(bytes).with_limits(decode_limits(budget, &limits));
    let mut mesh = Mesh::new();
    MeshDecoder::new().decode(&mut input, &mut mesh).map_err(|e| decode_error(file, &at, &e))?;
    let points = mesh.num_points();
    if mesh.num_faces() == 0 || points == 0 {
        return Err(bad(file, "extensions", format!("{at}: the Draco data holds no triangles (a point cloud?)")));
    }
    let mut triangles = Vec::with_capacity(mesh.num_faces() * 3);
    for face in mesh.faces() {
        for corner in face {
            if corner.0 as usize >= points {
                return Err(bad(
                    file,
                    "extensions",
                    format!("{at}: a Draco face uses point {}, out of range for {points} points", corner.0),
                ));
            }
            triangles.push(corner.0);
        }
    }
    Ok(Decoded { mesh, triangles, at })
}

/// A decoder error as ours: a ceiling of [`decode_limits`] (the decoder says "stream decodes
/// N what, over the caller's ceiling of C") as [`Error::LimitExceeded`], anything else as
/// malformed data.
fn decode_error(file: &str, at: &str, e: &draco_core::DracoError) -> Error {
    let message = printable(e.message());
    let numbers: Vec<u64> = message.split(|c: char| !c.is_ascii_digit()).filter_map(|n| n.parse().ok()).collect();
    match (e.kind(), numbers.first(), numbers.last()) {
        (ErrorKind::LimitExceeded, Some(&value), Some(&limit)) if numbers.len() >= 2 => Error::LimitExceeded {
            context: file.to_owned().into(),
            field: format!("{at}: the decoded Draco mesh ({message}; --max-memory raises the ceiling)").into(),
            value,
            limit,
        },
        _ => bad(file, "extensions", format!("{at}: the Draco data does not decode ({})", printable(&e.to_string()))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn doc(ext: Value) -> Value {
        json!({"meshes": [{"primitives": [{"attributes": {}, "extensions": {EXTENSION: ext}}]}]})
    }

    #[test]
    fn the_extension_object_is_checked() {
        let ok = extension("f.glb", &doc(json!({"bufferView": 1, "attributes": {"POSITION": 7}})), 0, 0, 2).unwrap();
        let ok = ok.expect("present");
        assert_eq!((ok.view, ok.id("POSITION"), ok.id("NORMAL")), (1, Some(7), None));
        assert!(extension("f.glb", &json!({"meshes": [{"primitives": [{}]}]}), 0, 0, 2).unwrap().is_none());
        for (bad, needle) in [
            (json!({"bufferView": 2, "attributes": {}}), "refers to bufferView 2, but there are 2"),
            (json!({"attributes": {}}), "no bufferView"),
            (json!({"bufferView": 0}), "no attributes"),
            (json!({"bufferView": 0, "attributes": {"POSITION": -1}}), "not a 32-bit index"),
            (json!({"bufferView": 0, "attributes": {"POSITION": 4294967296u64}}), "not a 32-bit index"),
        ] {
            let e = extension("f.glb", &doc(bad), 0, 0, 2).err().expect("refused").to_string();
            assert!(e.contains(needle) && e.contains("f.glb"), "{e}");
        }
        assert_eq!(views(&doc(json!({"bufferView": 3, "attributes": {}}))), vec![3]);
        assert!(covers(&doc(json!({"bufferView": 0, "attributes": {"JOINTS_0": 2}})), 0, 0, "JOINTS_0"));
        assert!(!covers(&doc(json!({"bufferView": 0, "attributes": {"JOINTS_0": 2}})), 0, 0, "WEIGHTS_0"));
    }

    #[test]
    fn integer_components_follow_the_gltf_normalized_rule() {
        assert_eq!(convert(DracoType::Uint8, &[255], true), Some(1.0));
        assert_eq!(convert(DracoType::Uint8, &[7], false), Some(7.0));
        assert_eq!(convert(DracoType::Int8, &[0x80], true), Some(-1.0));
        assert_eq!(convert(DracoType::Uint16, &65535u16.to_le_bytes(), true), Some(1.0));
        assert_eq!(convert(DracoType::Int16, &(-32767i16).to_le_bytes(), true), Some(-1.0));
        assert_eq!(convert(DracoType::Float32, &0.25f32.to_le_bytes(), true), Some(0.25));
        assert_eq!(convert(DracoType::Int64, &[0; 8], false), None);
    }
}
