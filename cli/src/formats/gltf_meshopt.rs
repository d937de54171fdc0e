//! `EXT_meshopt_compression` on input: buffer views whose data is meshoptimizer-encoded are
//! decoded (with the `meshopt` crate's decoders, which are safe on untrusted input) into their
//! fallback buffer, after which every accessor reads them like plain data. Modes `ATTRIBUTES`
//! and `TRIANGLES`; mode `INDICES` (the crate has no safe binding for the index-sequence
//! decoder) and filters other than `NONE` (the octahedral, quaternion and exponential filters
//! have no safe binding either) are refused by name.
//!
//! The declared output size is checked before decoding: it must fit the view, the target
//! buffer, and be plausible for the encoded bytes (see [`MAX_ATTRIBUTE_RATIO`]), so a small
//! file cannot make the decoder allocate gigabytes.

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

/// Most bytes a version-0 vertex stream decodes to per encoded byte: the densest block
/// encoding spends 2 header bits on a group of 16 equal bytes (meshoptimizer's vertex codec,
/// `decodeBytesGroup` mode 0), i.e. 64 output bytes per input byte; the tail only adds input.
/// `EXT_meshopt_compression` requires version 0; streams of a later version (its first byte)
/// get the looser bound of version 1, whose all-zero channel mode spends 2 bits on a channel of
/// a 256-vertex block (1024 bytes per byte).
const MAX_ATTRIBUTE_RATIO: [usize; 2] = [64, 1024];

/// Decodes a meshopt vertex stream of `count` records of `stride` bytes into `out`
/// (`count × stride` bytes).
fn decode_attributes(data: &[u8], count: usize, stride: usize, out: &mut [u8]) -> Option<()> {
    fn go<const N: usize>(data: &[u8], count: usize, out: &mut [u8]) -> Option<()> {
        let records: Vec<Record<N>> = meshopt::decode_vertex_buffer(data, count).ok()?;
        for (slot, record) in out.chunks_exact_mut(N).zip(&records) {
            slot.copy_from_slice(&record.0);
        }
        Some(())
    }
    macro_rules! strides {
        ($($n:literal)*) => {
            match stride {
                $($n => go::<$n>(data, count, out),)*
                _ => None,
            }
        };
    }
    strides!(4 8 12 16 20 24 28 32 36 40 44 48 52 56 60 64 68 72 76 80 84 88 92 96 100 104 108 112 116 120
        124 128 132 136 140 144 148 152 156 160 164 168 172 176 180 184 188 192 196 200 204 208 212 216 220
        224 228 232 236 240 244 248 252 256)
}

/// Decodes every compressed buffer view of `raw` into its (fallback) target buffer. `limits`
/// bounds the decoder's temporary output (one view at a time).
pub fn decode_views(file: &str, raw: &Value, buffers: &mut [BufferData], limits: &Limits) -> Result<()> {
    let Some(views) = raw.get("bufferViews").and_then(Value::as_array) else { return Ok(()) };
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
        match mode {
            "ATTRIBUTES" | "TRIANGLES" => {}
            "INDICES" => return Err(fail("mode INDICES is not supported (only ATTRIBUTES and TRIANGLES)".into())),
            other => return Err(fail(format!("unknown mode {other}"))),
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
        // Checked before decoding: the decoded bytes must fit their slot in the target buffer
        // (whose size was checked when it was allocated) and be plausible for the input.
        let target = int(view, "buffer", None)?;
        let target_offset = int(view, "byteOffset", Some(0))?;
        let target_length = buffers
            .get(target)
            .ok_or_else(|| fail(format!("the view refers to buffer {target}, which does not exist")))?
            .0
            .len();
        let slot_end = target_offset.checked_add(size).filter(|&e| e <= target_length);
        let Some(slot_end) = slot_end else {
            return Err(fail(format!(
                "{size} decoded bytes (count × byteStride) do not fit at {target_offset} in buffer {target}"
            )));
        };
        let encoded_length = end - offset;
        let plausible = match mode {
            "ATTRIBUTES" => {
                let version = buffers[source].0.get(offset).map_or(0, |b| usize::from(b & 0x0f));
                let ratio = MAX_ATTRIBUTE_RATIO[version.min(1)];
                encoded_length.saturating_mul(ratio)
            }
            // The triangle codec spends at least one code byte per triangle.
            _ => encoded_length.saturating_mul(3).saturating_mul(stride),
        };
        if size > plausible {
            return Err(fail(format!(
                "count {count} × byteStride {stride} = {size} bytes is implausibly large for {encoded_length} \
                 encoded bytes (mode {mode})"
            )));
        }
        limits.check_alloc("gltf", "EXT_meshopt_compression", size as u64)?;
        let encoded = buffers[source].0[offset..end].to_vec();
        let slot = &mut buffers[target].0[target_offset..slot_end];
        if mode == "ATTRIBUTES" {
            decode_attributes(&encoded, count, stride, slot).ok_or_else(|| {
                fail(format!("ATTRIBUTES data malformed or byteStride {stride} not a multiple of 4 in 4..=256"))
            })?;
            continue;
        }
        if count % 3 != 0 {
            return Err(fail(format!("TRIANGLES with {count} indices")));
        }
        let decoded = match stride {
            2 => meshopt::decode_index_buffer::<u16>(&encoded, count).ok().map(|v| {
                slot.chunks_exact_mut(2).zip(v).for_each(|(s, x)| s.copy_from_slice(&x.to_le_bytes()));
            }),
            4 => meshopt::decode_index_buffer::<u32>(&encoded, count).ok().map(|v| {
                slot.chunks_exact_mut(4).zip(v).for_each(|(s, x)| s.copy_from_slice(&x.to_le_bytes()));
            }),
            _ => None,
        };
        decoded.ok_or_else(|| fail(format!("TRIANGLES data malformed or byteStride {stride} not 2 or 4")))?;
    }
    Ok(())
}
