//! The binary buffer of a glTF file [`super::gltf_out`] writes: 4-byte aligned buffer views and
//! their accessors, plain or `EXT_meshopt_compression`/`KHR_meshopt_compression`-encoded. Kept apart from the JSON document
//! and the geometry because it only lays bytes out: what goes in is decided by the caller.

use codec_core::{Error, Result};
use serde_json::{json, Value};

use super::gltf_out_rd::{self, encode_vertex_records};

/// How a glTF file stores its geometry: what the importer it is meant for can read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GltfCompression {
    /// `KHR_mesh_quantization` (16-bit positions and targets) + `EXT_meshopt_compression`
    /// (meshoptimizer's vertex and index codecs on the quantized data, the weights and the key
    /// times; vertex codec format version 0): engines and web viewers read it (three.js,
    /// Babylon.js, Unity's glTFast, Godot 4), Blender 5.0's importer does not.
    Meshopt,
    /// As [`GltfCompression::Meshopt`] through `KHR_meshopt_compression`, the extension's
    /// ratified form, whose vertex codec format version 1 codes 16-bit values as 16-bit deltas
    /// and picks per-channel bit widths (smaller); read by loaders with meshoptimizer 0.23+'s
    /// decoder (three.js r17x+'s `GLTFLoader` + `MeshoptDecoder`, gltfpack's `-ce khr`).
    MeshoptKhr,
    /// `KHR_mesh_quantization` alone: the same quantized geometry stored plainly, for DCC tools
    /// (Blender 5.0 imports it).
    Quantized,
    /// Plain `f32` positions and targets: no extension at all.
    None,
}

impl GltfCompression {
    /// Positions and targets are 16-bit integers (`KHR_mesh_quantization`).
    pub fn quantized(self) -> bool {
        self != GltfCompression::None
    }

    /// Views are meshoptimizer-coded (`EXT_meshopt_compression` or `KHR_meshopt_compression`).
    pub fn meshopt(self) -> bool {
        self.meshopt_extension().is_some()
    }

    /// The meshopt extension's name, when views are meshoptimizer-coded.
    pub fn meshopt_extension(self) -> Option<&'static str> {
        match self {
            GltfCompression::Meshopt => Some("EXT_meshopt_compression"),
            GltfCompression::MeshoptKhr => Some("KHR_meshopt_compression"),
            GltfCompression::Quantized | GltfCompression::None => None,
        }
    }

    /// The format version meshoptimizer's vertex codec writes (and the export's step choice
    /// counts the bytes of): 1 under `KHR_meshopt_compression`, else 0, the only one
    /// `EXT_meshopt_compression` defines.
    pub(super) fn vertex_codec_version(self) -> i32 {
        i32::from(self == GltfCompression::MeshoptKhr)
    }

    /// The extensions a file of this form uses and requires.
    pub fn extensions(self) -> &'static [&'static str] {
        match self {
            GltfCompression::Meshopt => &["KHR_mesh_quantization", "EXT_meshopt_compression"],
            GltfCompression::MeshoptKhr => &["KHR_mesh_quantization", "KHR_meshopt_compression"],
            GltfCompression::Quantized => &["KHR_mesh_quantization"],
            GltfCompression::None => &[],
        }
    }
}

/// Little-endian binary buffer with 4-byte aligned views. With `meshopt`, view data is
/// meshoptimizer-encoded into buffer 0 and the view itself points into buffer 1, the
/// `EXT_meshopt_compression` fallback buffer that holds no data (`fallback` = its length).
pub(super) struct Buffer {
    pub(super) bin: Vec<u8>,
    pub(super) views: Vec<Value>,
    pub(super) accessors: Vec<Value>,
    pub(super) meshopt: bool,
    /// The meshopt extension's name (`EXT_…` or `KHR_meshopt_compression`).
    extension: &'static str,
    /// The vertex codec's format version (0 under `EXT_…`, 1 under `KHR_…`).
    version: i32,
    pub(super) fallback: usize,
    /// Triangles may come back with their corners rotated (the vertices were welded and
    /// renumbered anyway): meshopt's triangle codec (mode `TRIANGLES`), else the exact index
    /// sequence codec.
    pub(super) rotate: bool,
}

/// How a view is meshopt-encoded: records of `stride` bytes (`vertex_stride`: a vertex
/// attribute view, which declares its `byteStride`).
#[derive(Clone, Copy)]
pub(super) enum Stream {
    Attributes { stride: usize, vertex_stride: bool },
}

pub(super) fn align4(bytes: &mut Vec<u8>) {
    while !bytes.len().is_multiple_of(4) {
        bytes.push(0);
    }
}

/// Leaves out `byteOffset` where it is 0, its default (glTF 2.0 `bufferView.byteOffset`,
/// the meshopt extensions' `byteOffset`), in `view` and its meshopt extension object.
pub(super) fn drop_zero_offsets(view: &mut Value) {
    let zero = |v: &mut Value| {
        if let Some(map) = v.as_object_mut() {
            if map.get("byteOffset").and_then(Value::as_u64) == Some(0) {
                map.remove("byteOffset");
            }
        }
    };
    if let Some(extensions) = view.get_mut("extensions").and_then(Value::as_object_mut) {
        extensions.values_mut().for_each(zero);
    }
    zero(view);
}

/// Encodes `raw` (records of `N` bytes) with meshopt's vertex codec.
fn encode_records<const N: usize>(raw: &[u8], version: i32) -> Result<Vec<u8>> {
    let records: Vec<[u8; N]> = raw.chunks_exact(N).map(|c| c.try_into().expect("chunks of N")).collect();
    encode_vertex_records(&records, version)
}

/// [`encode_records`] for any stride the extension allows (a multiple of 4, at most 256).
pub(super) fn encode_stride(raw: &[u8], stride: usize, version: i32) -> Result<Vec<u8>> {
    macro_rules! strides {
        ($($n:literal)*) => {
            match stride {
                $($n => encode_records::<$n>(raw, version),)*
                other => Err(Error::InvalidAnimation(format!("meshopt stride {other} is not written"))),
            }
        };
    }
    strides!(4 8 12 16 20 24 28 32 36 40 44 48 52 56 60 64 68 72 76 80 84 88 92 96 100 104 108 112 116 120 124
        128 132 136 140 144 148 152 156 160 164 168 172 176 180 184 188 192 196 200 204 208 212 216 220 224 228
        232 236 240 244 248 252 256)
}

/// How a weights sampler output is stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum WeightForm {
    /// Plain `f32`.
    F32,
    /// `f32` through the `EXPONENTIAL` filter ([`gltf_out_rd::exponential_words`]); plain
    /// `f32` without meshopt.
    Exponential,
}

impl Buffer {
    pub(super) fn new(compression: GltfCompression) -> Self {
        Self {
            bin: Vec::new(),
            views: Vec::new(),
            accessors: Vec::new(),
            meshopt: compression.meshopt(),
            extension: compression.meshopt_extension().unwrap_or_default(),
            version: compression.vertex_codec_version(),
            fallback: 0,
            rotate: false,
        }
    }

    /// Appends a view holding `raw`; returns its index.
    pub(super) fn view(&mut self, raw: &[u8], stream: Stream, target: Option<u32>) -> Result<usize> {
        align4(&mut self.bin);
        let mut view = json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": raw.len()});
        let Stream::Attributes { stride, vertex_stride } = stream;
        if vertex_stride {
            view["byteStride"] = stride.into();
        }
        if let Some(t) = target {
            view["target"] = t.into();
        }
        if self.meshopt {
            let (encoded, count, mode) = (encode_stride(raw, stride, self.version)?, raw.len() / stride, "ATTRIBUTES");
            if encoded.len() >= raw.len() {
                // The codec gains nothing on this view (f32 weights of a short clip): plain.
                self.bin.extend_from_slice(raw);
                self.views.push(view);
                return Ok(self.views.len() - 1);
            }
            view["buffer"] = 1.into();
            view["byteOffset"] = self.fallback.into();
            self.fallback += raw.len().div_ceil(4) * 4;
            view["extensions"] = json!({self.extension: {
                "buffer": 0, "byteOffset": self.bin.len(), "byteLength": encoded.len(),
                "byteStride": stride, "count": count, "mode": mode}});
            self.bin.extend_from_slice(&encoded);
        } else {
            self.bin.extend_from_slice(raw);
        }
        self.views.push(view);
        Ok(self.views.len() - 1)
    }

    /// Appends `f32` data as a view + accessor of `kind` ("SCALAR", "VEC3"); returns the accessor
    /// index. `bounds` adds the min/max glTF requires for positions and animation inputs.
    pub(super) fn floats(&mut self, data: &[f32], kind: &str, target: Option<u32>, bounds: bool) -> Result<usize> {
        let width = match kind {
            "VEC3" => 3,
            "VEC4" => 4,
            _ => 1,
        };
        let raw: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        // VEC3 floats are 12-byte records: written plain (only quantized data is compressed).
        let stream = Stream::Attributes { stride: 4, vertex_stride: false };
        let view = if width == 1 { self.view(&raw, stream, target)? } else { self.plain_view(&raw, target) };
        let mut accessor =
            json!({"bufferView": view, "componentType": 5126, "count": data.len() / width, "type": kind});
        if bounds && !data.is_empty() {
            let (mut lo, mut hi) = (vec![f32::INFINITY; width], vec![f32::NEG_INFINITY; width]);
            for c in data.chunks_exact(width) {
                for k in 0..width {
                    lo[k] = lo[k].min(c[k]);
                    hi[k] = hi[k].max(c[k]);
                }
            }
            accessor["min"] = shortest(&lo);
            accessor["max"] = shortest(&hi);
        }
        self.accessors.push(accessor);
        Ok(self.accessors.len() - 1)
    }

    /// A meshopt-coded view of `raw` in records of `stride` bytes whose decoded data goes
    /// through `filter` (`EXT_meshopt_compression` "Filters").
    pub(super) fn filtered_view(&mut self, raw: &[u8], stride: usize, filter: &str) -> Result<usize> {
        align4(&mut self.bin);
        let encoded = encode_stride(raw, stride, self.version)?;
        let view = json!({"buffer": 1, "byteOffset": self.fallback, "byteLength": raw.len(),
            "extensions": {self.extension: {"buffer": 0, "byteOffset": self.bin.len(),
                "byteLength": encoded.len(), "byteStride": stride, "count": raw.len() / stride,
                "mode": "ATTRIBUTES", "filter": filter}}});
        self.fallback += raw.len().div_ceil(4) * 4;
        self.bin.extend_from_slice(&encoded);
        self.views.push(view);
        Ok(self.views.len() - 1)
    }

    /// A view that is never compressed.
    pub(super) fn plain_view(&mut self, raw: &[u8], target: Option<u32>) -> usize {
        align4(&mut self.bin);
        let mut view = json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": raw.len()});
        if let Some(t) = target {
            view["target"] = t.into();
        }
        self.bin.extend_from_slice(raw);
        self.views.push(view);
        self.views.len() - 1
    }

    /// Appends `KHR_mesh_quantization` positions (the base, then every morph target): one view
    /// of signed 16-bit integers (not normalized) in 8-byte records for the arrays with
    /// `bytes[i]` false, one of signed bytes in 4-byte records for the others, each array an
    /// accessor at its offset in its view, with the min/max glTF requires. Few views keep the
    /// JSON small (a view and its meshopt entry cost about 150 bytes; a 16-frame clip has 16
    /// arrays). Returns the accessor of every array, in order.
    pub(super) fn positions(
        &mut self,
        arrays: &[&[[i16; 3]]],
        bytes: &[bool],
        base_normalized: bool,
    ) -> Result<Vec<usize>> {
        let mut accessors = vec![0; arrays.len()];
        for narrow in [false, true] {
            let members: Vec<usize> = (0..arrays.len()).filter(|&i| bytes[i] == narrow).collect();
            if members.is_empty() {
                continue;
            }
            let stride = if narrow { 4 } else { 8 };
            let mut raw = Vec::new();
            let mut offsets = Vec::with_capacity(members.len());
            for &i in &members {
                offsets.push(raw.len());
                for p in arrays[i] {
                    if narrow {
                        raw.extend_from_slice(&[p[0] as i8 as u8, p[1] as i8 as u8, p[2] as i8 as u8, 0]);
                    } else {
                        raw.extend([p[0], p[1], p[2], 0].iter().flat_map(|x| x.to_le_bytes()));
                    }
                }
            }
            let view = self.view(&raw, Stream::Attributes { stride, vertex_stride: true }, Some(34962))?;
            for (&i, offset) in members.iter().zip(offsets) {
                let data = arrays[i];
                let lo: Vec<i16> = (0..3).map(|k| data.iter().map(|p| p[k]).min().unwrap_or(0)).collect();
                let hi: Vec<i16> = (0..3).map(|k| data.iter().map(|p| p[k]).max().unwrap_or(0)).collect();
                let mut accessor = json!({"bufferView": view, "componentType": if narrow { 5120 } else { 5122 },
                    "count": data.len(), "type": "VEC3", "min": lo, "max": hi});
                if offset > 0 {
                    accessor["byteOffset"] = offset.into();
                }
                if i == 0 && base_normalized {
                    accessor["normalized"] = true.into();
                }
                self.accessors.push(accessor);
                accessors[i] = self.accessors.len() - 1;
            }
        }
        Ok(accessors)
    }

    /// Appends a weights sampler output (`F × k` f32, frame-major). Compressed, a meshopt record
    /// is one frame's weights (or as many whole weights as fit 256 bytes), so the codec's deltas
    /// run from a weight to the same weight one record earlier; returns the accessor index.
    pub(super) fn weights(&mut self, data: &[f32], k: usize, form: WeightForm) -> Result<usize> {
        if form == WeightForm::Exponential && self.meshopt && k > 0 {
            // One frame's weights per record; the exponent bytes are constant down a column.
            let words = gltf_out_rd::exponential_words(data, k);
            let raw: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
            let per_record = (1..=k.min(64)).rev().find(|d| k.is_multiple_of(*d)).unwrap_or(1);
            let view = self.filtered_view(&raw, 4 * per_record, "EXPONENTIAL")?;
            self.accessors
                .push(json!({"bufferView": view, "componentType": 5126, "count": data.len(), "type": "SCALAR"}));
            return Ok(self.accessors.len() - 1);
        }
        let raw: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        let per_record = (1..=k.min(64)).rev().find(|d| k.is_multiple_of(*d)).unwrap_or(1);
        let view = self.view(&raw, Stream::Attributes { stride: 4 * per_record, vertex_stride: false }, None)?;
        self.accessors.push(json!({"bufferView": view, "componentType": 5126, "count": data.len(), "type": "SCALAR"}));
        Ok(self.accessors.len() - 1)
    }

    /// Appends triangle indices (u16 when every index fits, else u32); compressed, with
    /// meshoptimizer's index sequence codec (mode `INDICES`), which returns the list exactly,
    /// not its triangle codec (mode `TRIANGLES`), which rotates the corners of triangles: the
    /// triangle list must come back exactly as it was (same topology for `eval` and the
    /// codecs); returns the accessor index.
    pub(super) fn indices(&mut self, data: &[u32], vertex_count: usize) -> usize {
        let (raw, component, stride): (Vec<u8>, u32, usize) = if vertex_count <= u16::MAX as usize {
            (data.iter().flat_map(|&x| (x as u16).to_le_bytes()).collect(), 5123, 2)
        } else {
            (data.iter().flat_map(|x| x.to_le_bytes()).collect(), 5125, 4)
        };
        let view = if self.meshopt && !data.is_empty() {
            align4(&mut self.bin);
            let (encoded, mode) = match self.rotate {
                true => (meshopt::encode_index_buffer(data, vertex_count).ok(), "TRIANGLES"),
                false => (None, "INDICES"),
            };
            let (encoded, mode) = match encoded {
                Some(e) => (e, mode),
                None => (super::gltf_meshopt::encode_index_sequence(data), "INDICES"),
            };
            let view = json!({"buffer": 1, "byteOffset": self.fallback, "byteLength": raw.len(), "target": 34963,
                "extensions": {self.extension: {"buffer": 0, "byteOffset": self.bin.len(),
                    "byteLength": encoded.len(), "byteStride": stride, "count": data.len(), "mode": mode}}});
            self.fallback += raw.len().div_ceil(4) * 4;
            self.bin.extend_from_slice(&encoded);
            self.views.push(view);
            self.views.len() - 1
        } else {
            self.plain_view(&raw, Some(34963))
        };
        self.accessors
            .push(json!({"bufferView": view, "componentType": component, "count": data.len(), "type": "SCALAR"}));
        self.accessors.len() - 1
    }
}

/// `values` as a JSON array of the shortest decimals that read back as the same `f32`
/// (serde_json would print the `f64` widening: 0.036700748 as 0.03670074790716171).
pub(super) fn shortest(values: &[f32]) -> Value {
    Value::Array(
        values
            .iter()
            .map(|x| {
                let short: f64 = format!("{x}").parse().unwrap_or(*x as f64);
                serde_json::Number::from_f64(short).map_or(Value::Null, Value::Number)
            })
            .collect(),
    )
}
