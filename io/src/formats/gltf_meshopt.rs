//! `EXT_meshopt_compression` and `KHR_meshopt_compression` on input: buffer views whose data
//! is meshoptimizer-encoded are decoded into their fallback buffer, after which every accessor
//! reads them like plain data. The two extensions have the same JSON; the `KHR` one also
//! allows version 1 of the vertex codec (which the decoder reads from the stream's first byte)
//! and the `COLOR` filter (not read: geometry never uses it).
//! Every mode of the extension is read: `ATTRIBUTES` (vertex codec, the `meshopt` crate's
//! decoder, safe on untrusted input), `TRIANGLES` (index codec, the same crate) and `INDICES`
//! (the index-sequence codec, decoded here: the crate has no safe binding for it). Every filter
//! is applied after decoding: `NONE`, `OCTAHEDRAL` (unit vectors), `QUATERNION` (rotations) and
//! `EXPONENTIAL` (floats as mantissa and exponent), ported from the extension's specification
//! (the `KHR`/`EXT_meshopt_compression` README, "Filters"; meshoptimizer's `vertexfilter.cpp`
//! scalar reference), because the crate exposes them only as `unsafe` foreign functions and
//! this workspace forbids `unsafe`. `gltfpack -cc` writes all three filters (normals,
//! animation rotations, animation translations and scales).
//!
//! The declared output size is checked before decoding: it must fit the view, the target
//! buffer, and be plausible for the encoded bytes (see [`MAX_ATTRIBUTE_RATIO`]), so a small
//! file cannot make the decoder allocate gigabytes. Only the views geometry reading uses are
//! decoded.

use codec_core::{Limits, Result};
use serde_json::Value;

use super::gltf_buffers::{bad, BufferData};

/// The extension's name.
pub const EXTENSION: &str = "EXT_meshopt_compression";

/// The extension's ratified name (vertex codec version 1 allowed).
pub const KHR_EXTENSION: &str = "KHR_meshopt_compression";

/// Both names, as `extensionsRequired` lists them.
pub const EXTENSIONS: [&str; 2] = [EXTENSION, KHR_EXTENSION];

/// The meshopt object of a buffer view or buffer (`extensions.KHR_…` or `extensions.EXT_…`)
/// and the extension's name.
pub fn object(item: &Value) -> Option<(&'static str, &Value)> {
    EXTENSIONS.iter().find_map(|&name| item.get("extensions")?.get(name).map(|o| (name, o)))
}

/// True when buffer `index` is a fallback buffer (no data of its own: meshopt views fill it).
pub fn is_fallback(raw: &Value, index: usize) -> bool {
    raw.pointer(&format!("/buffers/{index}")).and_then(object).and_then(|(_, o)| o.get("fallback")?.as_bool())
        == Some(true)
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
/// `EXT_meshopt_compression` requires version 0; streams of a later version (its first byte,
/// which `KHR_meshopt_compression` allows) get the looser bound of version 1, whose all-zero channel mode spends 2 bits on a channel of
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

/// Decodes every compressed buffer view of `raw` that `used_views` marks into its (fallback)
/// target buffer. `limits` bounds the decoder's temporary output (one view at a time).
pub fn decode_views(
    file: &str,
    raw: &Value,
    buffers: &mut [BufferData],
    used_views: &[bool],
    limits: &Limits,
) -> Result<()> {
    let Some(views) = raw.get("bufferViews").and_then(Value::as_array) else { return Ok(()) };
    for (i, view) in views.iter().enumerate() {
        let Some((name, ext)) = object(view) else { continue };
        if !used_views.get(i).copied().unwrap_or(false) {
            continue;
        }
        let fail = |detail: String| bad(file, name, format!("bufferView {i}: {detail}"));
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
        let filter = match ext.get("filter").map(|f| f.as_str().ok_or_else(|| fail("filter is not a string".into()))) {
            None => Filter::None,
            Some(name) => Filter::parse(name?).ok_or_else(|| fail(format!("unknown filter {}", ext["filter"])))?,
        };
        let mode = match mode {
            "ATTRIBUTES" => Mode::Attributes,
            "TRIANGLES" => Mode::Triangles,
            "INDICES" => Mode::Indices,
            other => return Err(fail(format!("unknown mode {other}"))),
        };
        // The specification allows filters on vertex attributes only, each for its element sizes.
        let filter_fits = match filter {
            Filter::None => true,
            _ if mode != Mode::Attributes => false,
            Filter::Octahedral => stride == 4 || stride == 8,
            Filter::Quaternion => stride == 8,
            Filter::Exponential => stride % 4 == 0,
        };
        if !filter_fits {
            return Err(fail(format!(
                "filter {} does not apply to mode {mode:?} with byteStride {stride}",
                filter.name()
            )));
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
            Mode::Attributes => {
                let version = buffers[source].0.get(offset).map_or(0, |b| usize::from(b & 0x0f));
                let ratio = MAX_ATTRIBUTE_RATIO[version.min(1)];
                encoded_length.saturating_mul(ratio)
            }
            // The triangle codec spends at least one code byte per triangle, the sequence codec
            // at least one byte per index.
            Mode::Triangles => encoded_length.saturating_mul(3).saturating_mul(stride),
            Mode::Indices => encoded_length.saturating_mul(stride),
        };
        if size > plausible {
            return Err(fail(format!(
                "count {count} × byteStride {stride} = {size} bytes is implausibly large for {encoded_length} \
                 encoded bytes (mode {mode:?})"
            )));
        }
        limits.check_alloc("gltf", name, size as u64)?;
        let encoded = buffers[source].0[offset..end].to_vec();
        let slot = &mut buffers[target].0[target_offset..slot_end];
        match mode {
            Mode::Attributes => {
                decode_attributes(&encoded, count, stride, slot).ok_or_else(|| {
                    fail(format!("ATTRIBUTES data malformed or byteStride {stride} not a multiple of 4 in 4..=256"))
                })?;
                filter.apply(slot, stride);
            }
            Mode::Triangles => {
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
            Mode::Indices => {
                if stride != 2 && stride != 4 {
                    return Err(fail(format!("INDICES with byteStride {stride} (2 or 4 expected)")));
                }
                let indices = decode_index_sequence(&encoded, count)
                    .map_err(|why| fail(format!("INDICES data malformed: {why}")))?;
                for (s, x) in slot.chunks_exact_mut(stride).zip(indices) {
                    // A 2-byte sequence keeps the low 16 bits, as the reference decoder does.
                    s.copy_from_slice(&x.to_le_bytes()[..stride]);
                }
            }
        }
    }
    Ok(())
}

/// The extension's compression modes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    Attributes,
    Triangles,
    Indices,
}

/// The extension's filters, applied to decoded vertex attributes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Filter {
    None,
    Octahedral,
    Quaternion,
    Exponential,
}

impl Filter {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "NONE" => Self::None,
            "OCTAHEDRAL" => Self::Octahedral,
            "QUATERNION" => Self::Quaternion,
            "EXPONENTIAL" => Self::Exponential,
            _ => return None,
        })
    }

    fn name(self) -> &'static str {
        match self {
            Self::None => "NONE",
            Self::Octahedral => "OCTAHEDRAL",
            Self::Quaternion => "QUATERNION",
            Self::Exponential => "EXPONENTIAL",
        }
    }

    /// Applies the filter in place to `data`, records of `stride` bytes (checked by the caller:
    /// 4 or 8 for octahedral, 8 for quaternion, a multiple of 4 for exponential).
    fn apply(self, data: &mut [u8], stride: usize) {
        match self {
            Self::None => {}
            Self::Octahedral if stride == 4 => {
                for r in data.chunks_exact_mut(4) {
                    let v = octahedral([r[0] as i8 as f32, r[1] as i8 as f32, r[2] as i8 as f32], 127.0);
                    for (b, x) in r.iter_mut().zip(v) {
                        *b = x as i8 as u8;
                    }
                }
            }
            Self::Octahedral => {
                for r in data.chunks_exact_mut(8) {
                    let c = |k: usize| i16::from_le_bytes([r[2 * k], r[2 * k + 1]]) as f32;
                    let v = octahedral([c(0), c(1), c(2)], 32767.0);
                    for (k, x) in v.into_iter().enumerate() {
                        r[2 * k..2 * k + 2].copy_from_slice(&(x as i16).to_le_bytes());
                    }
                }
            }
            Self::Quaternion => {
                for r in data.chunks_exact_mut(8) {
                    let c: [i16; 4] = std::array::from_fn(|k| i16::from_le_bytes([r[2 * k], r[2 * k + 1]]));
                    for (k, x) in quaternion(c).into_iter().enumerate() {
                        r[2 * k..2 * k + 2].copy_from_slice(&x.to_le_bytes());
                    }
                }
            }
            Self::Exponential => {
                for r in data.chunks_exact_mut(4) {
                    let v = u32::from_le_bytes([r[0], r[1], r[2], r[3]]);
                    r.copy_from_slice(&exponential(v).to_le_bytes());
                }
            }
        }
    }
}

/// `float(x)` rounded half away from zero and truncated to an integer, as the reference's
/// `int(x * s + (x >= 0 ? 0.5 : -0.5))`.
fn round_away(x: f32) -> i32 {
    (x + if x >= 0.0 { 0.5 } else { -0.5 }) as i32
}

/// The octahedral filter on one record: `c` holds the stored x, y and the stored "one"
/// (`max` at the record's bit width, possibly fewer bits); the result is the unit vector at
/// the full width (spec: "Octahedral filter").
fn octahedral(c: [f32; 3], max: f32) -> [i32; 3] {
    let (mut x, mut y) = (c[0], c[1]);
    let z = c[2] - x.abs() - y.abs();
    // Fold back the lower hemisphere.
    let t = if z >= 0.0 { 0.0 } else { z };
    x += if x >= 0.0 { t } else { -t };
    y += if y >= 0.0 { t } else { -t };
    let s = max / (x * x + y * y + z * z).sqrt();
    [round_away(x * s), round_away(y * s), round_away(z * s)]
}

/// The quaternion filter on one record: three components in ±1/√2 at the bit width stored in
/// the fourth (`| 3`), the index of the dropped largest component in its low 2 bits (spec:
/// "Quaternion filter"). Returns the normalized 16-bit quaternion in x, y, z, w order.
fn quaternion(c: [i16; 4]) -> [i16; 4] {
    let scale = 1.0 / 2f32.sqrt();
    let sf = i32::from(c[3]) | 3;
    let ss = scale / sf as f32;
    let x = f32::from(c[0]) * ss;
    let y = f32::from(c[1]) * ss;
    let z = f32::from(c[2]) * ss;
    let ww = 1.0 - x * x - y * y - z * z;
    let w = if ww >= 0.0 { ww } else { 0.0 }.sqrt();
    let qc = (c[3] & 3) as usize;
    let mut out = [0i16; 4];
    out[(qc + 1) & 3] = round_away(x * 32767.0) as i16;
    out[(qc + 2) & 3] = round_away(y * 32767.0) as i16;
    out[(qc + 3) & 3] = round_away(z * 32767.0) as i16;
    out[qc] = (w * 32767.0 + 0.5) as i32 as i16;
    out
}

/// The exponential filter on one 32-bit value: a signed 24-bit mantissa in the low bits, a
/// signed 8-bit exponent in the high byte; the result is the `f32` bits of `m · 2ᵉ` (spec:
/// "Exponential filter"; the reference builds `2ᵉ` from its bits, so e = −128 gives the bits
/// of −∞/NaN patterns as it does there: the caller's finiteness checks refuse them).
fn exponential(v: u32) -> u32 {
    let m = ((v << 8) as i32) >> 8;
    let e = (v as i32) >> 24;
    let power = f32::from_bits(((e + 127) as u32) << 23);
    (power * m as f32).to_bits()
}

/// Decodes an `INDICES` stream (meshoptimizer's index sequence codec, spec "Mode 2:
/// indices"): a header byte `0xd0 | version` (version ≤ 1), then per index a LEB128 varint
/// `v` whose low bit picks one of two baselines and whose rest is a zigzag delta from it, then
/// a 4-byte tail. Errors say what is wrong; never reads outside `data`.
fn decode_index_sequence(data: &[u8], count: usize) -> std::result::Result<Vec<u32>, String> {
    // The smallest valid stream: header, one byte per index, the tail.
    if data.len() < count.saturating_add(5) {
        return Err(format!("{} bytes cannot hold {count} indices", data.len()));
    }
    if data[0] & 0xf0 != 0xd0 || data[0] & 0x0f > 1 {
        return Err(format!("header byte {:#04x} is not an index sequence of version 0 or 1", data[0]));
    }
    let body = &data[1..data.len() - 4];
    let mut at = 0usize;
    let mut last = [0u32; 2];
    let mut out = Vec::with_capacity(count);
    for i in 0..count {
        // A varint: at most 5 bytes (7 bits each, the fifth keeps its low 4 bits).
        let mut v = 0u32;
        let mut shift = 0u32;
        loop {
            let Some(&byte) = body.get(at) else { return Err(format!("index {i} runs past the data")) };
            at += 1;
            v |= u32::from(byte & 127) << shift;
            shift += 7;
            if byte < 128 || shift > 28 {
                break;
            }
        }
        let baseline = (v & 1) as usize;
        let v = v >> 1;
        let delta = (v >> 1) ^ (v & 1).wrapping_neg();
        let index = last[baseline].wrapping_add(delta);
        last[baseline] = index;
        out.push(index);
    }
    if at != body.len() {
        return Err(format!("{} bytes left after {count} indices", body.len() - at));
    }
    Ok(out)
}

/// Encodes an index sequence as meshoptimizer's `encodeIndexSequence` does (version 1):
/// the baseline is the one the previous index used, or the other one when it is closer.
/// (The `meshopt` crate exposes no safe binding for it; the glTF export writes its triangle
/// lists with it, since the index codec proper rotates triangle corners.)
pub(super) fn encode_index_sequence(indices: &[u32]) -> Vec<u8> {
    let mut out = vec![0xd1];
    let mut last = [0u32; 2];
    let mut current = 0usize;
    for &index in indices {
        let d0 = index.wrapping_sub(last[current]) as i32;
        let d1 = index.wrapping_sub(last[current ^ 1]) as i32;
        if d1.unsigned_abs() < d0.unsigned_abs() {
            current ^= 1;
        }
        let d = index.wrapping_sub(last[current]) as i32;
        let zigzag = ((d << 1) ^ (d >> 31)) as u32;
        let mut v = (zigzag << 1) | current as u32;
        while v >= 128 {
            out.push((v as u8 & 127) | 128);
            v >>= 7;
        }
        out.push(v as u8);
        last[current] = index;
    }
    out.extend([0; 4]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_sequences_round_trip_and_malformed_ones_fail() {
        let indices: Vec<u32> = vec![0, 1, 2, 2, 1, 3, 100_000, 7, 100_001, 4_000_000_000, 5, 0];
        let encoded = encode_index_sequence(&indices);
        assert_eq!(decode_index_sequence(&encoded, indices.len()).unwrap(), indices);
        // Too few bytes, a wrong header, a count that leaves bytes over or runs out.
        assert!(decode_index_sequence(&encoded[..encoded.len() - 1], indices.len()).is_err());
        let mut header = encoded.clone();
        header[0] = 0xd2;
        assert!(decode_index_sequence(&header, indices.len()).unwrap_err().contains("header"));
        assert!(decode_index_sequence(&encoded, indices.len() - 1).unwrap_err().contains("left after"));
        assert!(decode_index_sequence(&[0xd1, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0, 0, 0, 0], 2).is_err());
        for cut in 0..encoded.len() {
            let _ = decode_index_sequence(&encoded[..cut], indices.len());
        }
    }

    #[test]
    fn filters_decode_what_the_specification_encodes() {
        // Octahedral, 8 bits: +z (x = y = 0), +x (z = one − |x| = 0), and −z (x = y = one: the
        // lower hemisphere folded back); the fourth byte is kept.
        let mut r8 = vec![0u8, 0, 127, 9, 127, 0, 127, 0, 127, 127, 127, 0];
        Filter::Octahedral.apply(&mut r8, 4);
        assert_eq!(r8, vec![0, 0, 127, 9, 127, 0, 0, 0, 0, 0, 129, 0]);
        let enc =
            |x: i16, y: i16, one: i16| -> Vec<u8> { [x, y, one, 0].iter().flat_map(|v| v.to_le_bytes()).collect() };
        let mut r16 = enc(16384, 0, 32767);
        Filter::Octahedral.apply(&mut r16, 8);
        let c = |r: &[u8], k: usize| i16::from_le_bytes([r[2 * k], r[2 * k + 1]]) as f32 / 32767.0;
        let s = std::f32::consts::FRAC_1_SQRT_2;
        assert!((c(&r16, 0) - s).abs() < 1e-4 && c(&r16, 1) == 0.0 && (c(&r16, 2) - s).abs() < 1e-4);
        // Quaternion: identity (w dropped as the largest: index 3) comes back as (0, 0, 0, 1).
        let mut q: Vec<u8> = [0i16, 0, 0, (0x7ff0 | 3) as i16].iter().flat_map(|v| v.to_le_bytes()).collect();
        Filter::Quaternion.apply(&mut q, 8);
        assert_eq!((c(&q, 0), c(&q, 1), c(&q, 2), c(&q, 3)), (0.0, 0.0, 0.0, 1.0));
        // Exponential: 3 · 2⁻¹ = 1.5, −5 · 2⁴ = −80.
        let e = |m: i32, e: i32| -> u32 { ((e as u32) << 24) | (m as u32 & 0x00ff_ffff) };
        assert_eq!(f32::from_bits(exponential(e(3, -1))), 1.5);
        assert_eq!(f32::from_bits(exponential(e(-5, 4))), -80.0);
    }
}
