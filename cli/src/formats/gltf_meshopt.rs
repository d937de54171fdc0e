//! `EXT_meshopt_compression` on input: buffer views whose data is meshoptimizer-encoded are
//! decoded (with the `meshopt` crate's decoders, which are safe on untrusted input) into their
//! fallback buffer, after which every accessor reads them like plain data. Modes `ATTRIBUTES`,
//! `TRIANGLES` and `INDICES`; filter `NONE` only (the octahedral, quaternion and exponential
//! filters have no safe binding in the crate; such files are refused by name).

use codec_core::{Limits, Result};
use serde_json::Value;

use super::gltf::{bad, BufferData};

/// The extension's name.
pub const EXTENSION: &str = "EXT_meshopt_compression";

/// True when buffer `index` is a fallback buffer (no data of its own: meshopt views fill it).
pub fn is_fallback(raw: &Value, index: usize) -> bool {
    raw.pointer(&format!("/buffers/{index}/extensions/{EXTENSION}/fallback")).and_then(Value::as_bool) == Some(true)
}

/// A byte record of `N` bytes, the element type the vertex decoder fills.
#[derive(Clone, Copy)]
struct Record<const N: usize>([u8; N]);

impl<const N: usize> Default for Record<N> {
    fn default() -> Self {
        Self([0; N])
    }
}

/// Decodes a meshopt vertex stream of `count` records of `stride` bytes.
fn decode_attributes(data: &[u8], count: usize, stride: usize) -> Option<Vec<u8>> {
    fn go<const N: usize>(data: &[u8], count: usize) -> Option<Vec<u8>> {
        let records: Vec<Record<N>> = meshopt::decode_vertex_buffer(data, count).ok()?;
        Some(records.iter().flat_map(|r| r.0).collect())
    }
    macro_rules! strides {
        ($($n:literal)*) => {
            match stride {
                $($n => go::<$n>(data, count),)*
                _ => None,
            }
        };
    }
    strides!(4 8 12 16 20 24 28 32 36 40 44 48 52 56 60 64 68 72 76 80 84 88 92 96 100 104 108 112 116 120
        124 128 132 136 140 144 148 152 156 160 164 168 172 176 180 184 188 192 196 200 204 208 212 216 220
        224 228 232 236 240 244 248 252 256)
}

/// Decodes every compressed buffer view of `raw` into its (fallback) target buffer.
pub fn decode_views(file: &str, raw: &Value, buffers: &mut [BufferData]) -> Result<()> {
    let Some(views) = raw.get("bufferViews").and_then(Value::as_array) else { return Ok(()) };
    let limits = Limits::default();
    for (i, view) in views.iter().enumerate() {
        let Some(ext) = view.pointer(&format!("/extensions/{EXTENSION}")) else { continue };
        let fail = |detail: String| bad(file, "EXT_meshopt_compression", format!("bufferView {i}: {detail}"));
        let int = |v: &Value, key: &str, default: Option<u64>| -> Result<usize> {
            match v.get(key) {
                None => default.map(|d| d as usize).ok_or_else(|| fail(format!("missing {key}"))),
                Some(x) => x.as_u64().map(|x| x as usize).ok_or_else(|| fail(format!("{key} is not a count"))),
            }
        };
        let source = int(ext, "buffer", None)?;
        let (offset, length) = (int(ext, "byteOffset", Some(0))?, int(ext, "byteLength", None)?);
        let (stride, count) = (int(ext, "byteStride", None)?, int(ext, "count", None)?);
        let mode = ext.get("mode").and_then(Value::as_str).ok_or_else(|| fail("missing mode".into()))?;
        let filter = ext.get("filter").and_then(Value::as_str).unwrap_or("NONE");
        if filter != "NONE" {
            return Err(fail(format!("filter {filter} is not supported (only NONE)")));
        }
        let data = buffers
            .get(source)
            .ok_or_else(|| fail(format!("refers to buffer {source}, but there are {}", buffers.len())))?;
        let end = offset.checked_add(length).filter(|&e| e <= data.0.len());
        let Some(end) = end else {
            return Err(fail(format!("compressed bytes {offset}+{length} lie outside buffer {source}")));
        };
        let size = count.checked_mul(stride).ok_or_else(|| fail("count × byteStride overflows".into()))?;
        let view_length = int(view, "byteLength", None)?;
        if size > view_length {
            return Err(fail(format!("count × byteStride = {size} bytes exceeds the view's byteLength {view_length}")));
        }
        limits.check_alloc("gltf", "EXT_meshopt_compression", size as u64)?;
        let encoded = &data.0[offset..end];
        let decoded = match mode {
            "ATTRIBUTES" => decode_attributes(encoded, count, stride).ok_or_else(|| {
                fail(format!("ATTRIBUTES data malformed or byteStride {stride} not a multiple of 4 in 4..=256"))
            })?,
            "TRIANGLES" | "INDICES" => {
                if mode == "TRIANGLES" && count % 3 != 0 {
                    return Err(fail(format!("TRIANGLES with {count} indices")));
                }
                let bytes: Option<Vec<u8>> = match (mode, stride) {
                    ("TRIANGLES", 2) => meshopt::decode_index_buffer::<u16>(encoded, count)
                        .ok()
                        .map(|v| v.iter().flat_map(|x| x.to_le_bytes()).collect()),
                    ("TRIANGLES", 4) => meshopt::decode_index_buffer::<u32>(encoded, count)
                        .ok()
                        .map(|v| v.iter().flat_map(|x| x.to_le_bytes()).collect()),
                    _ => None,
                };
                bytes.ok_or_else(|| fail(format!("{mode} data malformed or unsupported (byteStride {stride})")))?
            }
            other => return Err(fail(format!("unknown mode {other}"))),
        };
        let target = int(view, "buffer", None)?;
        let target_offset = int(view, "byteOffset", Some(0))?;
        let out = buffers
            .get_mut(target)
            .ok_or_else(|| fail(format!("the view refers to buffer {target}, which does not exist")))?;
        let Some(slot) = target_offset.checked_add(decoded.len()).and_then(|e| out.0.get_mut(target_offset..e)) else {
            return Err(fail(format!(
                "{} decoded bytes do not fit at {target_offset} in buffer {target}",
                decoded.len()
            )));
        };
        slot.copy_from_slice(&decoded);
    }
    Ok(())
}
