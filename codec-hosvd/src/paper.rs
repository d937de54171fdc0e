//! The paper's coding of the operator (stream version 1's, still written with `coding=paper`):
//! one uniform quantizer per factor column with the rule-of-thumb step, zigzag deltas down the
//! columns, byte planes + zstd.

use codec_core::bytes::{zigzag_decode, zigzag_encode, ByteReader, ByteWriter};
use codec_core::toolkit::planes::{from_byte_planes, planes_needed, to_byte_planes};
use codec_core::{entropy, Error, Limits, Quantizer, Result};

use crate::params::HosvdParams;
use crate::tensor::Model;
use crate::NAME;

/// Largest bit depth given to one quantized column: keeps zigzag deltas of codes inside 32 bits.
const MAX_BITS: u8 = 30;

/// Bits so that a uniform quantizer over `range` has a step no larger than `step`.
fn bits_for(range: f64, step: f64) -> u8 {
    if range <= 0.0 {
        return 1;
    }
    if !(step > 0.0 && step.is_finite()) {
        return MAX_BITS;
    }
    let levels = (range / step).ceil() + 1.0;
    (levels.log2().ceil() as i64).clamp(1, MAX_BITS as i64) as u8
}

fn column_quantizer(values: impl Iterator<Item = f64> + Clone, step: f64) -> Result<Quantizer> {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(x), b.max(x)));
    // Round the range outwards to f32 so every value (rounded to f32) stays inside it.
    let (mut lo32, mut hi32) = (lo as f32, hi as f32);
    if (lo32 as f64) > lo {
        lo32 = lo32 - lo32.abs() * f32::EPSILON - f32::MIN_POSITIVE;
    }
    if (hi32 as f64) < hi {
        hi32 = hi32 + hi32.abs() * f32::EPSILON + f32::MIN_POSITIVE;
    }
    Quantizer::new(lo32, hi32, bits_for(hi32 as f64 - lo32 as f64, step))
}

fn write_codes(w: &mut ByteWriter, values: &[u32], level: i32) {
    let planes = planes_needed(values);
    w.u8(planes as u8);
    w.length_prefixed(&entropy::compress(&to_byte_planes(values, planes), level));
}

fn read_codes(r: &mut ByteReader<'_>, count: usize, limits: &Limits, field: &'static str) -> Result<Vec<u32>> {
    let planes = r.u8(field)? as usize;
    if !(1..=4).contains(&planes) {
        return Err(r.malformed(field, format!("{planes} byte planes, expected 1..=4")));
    }
    let len = count.checked_mul(planes).ok_or_else(|| r.malformed(field, "size overflows"))?;
    limits.check_alloc(NAME, field, len as u64)?;
    let block = r.length_prefixed(field)?;
    let raw = entropy::decompress(block, NAME, field, len)?;
    if raw.len() != len {
        return Err(Error::malformed(NAME, field, format!("{} bytes, expected {len}", raw.len())));
    }
    Ok(from_byte_planes(&raw, count, planes))
}

/// Column `c` of a row-major `rows × cols` matrix.
fn column(m: &[f64], rows: usize, cols: usize, c: usize) -> impl Iterator<Item = f64> + Clone + '_ {
    (0..rows).map(move |r| m[r * cols + c])
}

/// Version 1 codes of a row-major `rows × quantizers.len()` factor, column by column (one
/// quantizer per column) as zigzag deltas down the column, starting from the code of 0;
/// `reconstructed` receives the dequantized factor.
fn delta_code_columns(quantizers: &[Quantizer], values: &[f64], rows: usize, reconstructed: &mut [f64]) -> Vec<u32> {
    let cols = quantizers.len();
    let mut codes = Vec::with_capacity(rows * cols);
    for (i, q) in quantizers.iter().enumerate() {
        let mut prev = q.quantize(0.0) as i64;
        for r in 0..rows {
            let c = q.quantize(values[r * cols + i] as f32);
            codes.push(zigzag_encode(c as i64 - prev) as u32);
            prev = c as i64;
            reconstructed[r * cols + i] = q.dequantize(c) as f64;
        }
    }
    codes
}

/// Version 1's coding of the operator: one `Quantizer` per column with the rule-of-thumb step,
/// zigzag deltas, byte planes + zstd. Fills `m`'s factors and core and returns the per-column
/// bounds of `‖δu1_i‖`, `‖δu3_l‖` and the bound of `‖δC‖` (from the quantizers' half steps).
#[allow(clippy::too_many_arguments)]
pub(crate) fn code(
    w: &mut ByteWriter,
    mut side: ByteWriter,
    m: &mut Model,
    p: &HosvdParams,
    u1: &[f64],
    u3: &[f64],
    core: &[f64],
    s1: &[f64],
    s3: &[f64],
    budget: f64,
) -> Result<(Vec<f64>, Vec<f64>, f64)> {
    let (k, frames, v, f) = (m.k, m.frames, m.v, m.f);
    let step_core = (4.0 * budget / core.len() as f64).sqrt();
    let q1: Vec<Quantizer> = (0..v)
        .map(|i| column_quantizer(column(u1, k, v, i), (4.0 * budget / (v * k) as f64).sqrt() / s1[i]))
        .collect::<Result<_>>()?;
    let q3: Vec<Quantizer> = (0..f)
        .map(|l| column_quantizer(column(u3, frames, f, l), (4.0 * budget / (f * frames) as f64).sqrt() / s3[l]))
        .collect::<Result<_>>()?;
    let qc = column_quantizer(core.iter().copied(), step_core)?;
    for q in q1.iter().chain(&q3).chain(std::iter::once(&qc)) {
        q.write(&mut side);
    }

    // Codes: factor columns as zigzag deltas down the column (neighbouring vertices / frames
    // have similar loadings); core as zigzag offsets from the code of 0.
    m.u1 = vec![0.0; k * v];
    m.u3 = vec![0.0; frames * f];
    m.core = vec![0.0; core.len()];
    let codes1 = delta_code_columns(&q1, u1, k, &mut m.u1);
    let codes3 = delta_code_columns(&q3, u3, frames, &mut m.u3);
    let zero = qc.quantize(0.0) as i64;
    let mut codesc = Vec::with_capacity(core.len());
    for (o, &c) in m.core.iter_mut().zip(core) {
        let code = qc.quantize(c as f32);
        codesc.push(zigzag_encode(code as i64 - zero) as u32);
        *o = qc.dequantize(code) as f64;
    }

    w.u8(p.rigid as u8);
    w.varint(v as u64);
    w.varint(f as u64);
    w.length_prefixed(&entropy::compress(side.as_slice(), p.level));
    write_codes(w, &codes1, p.level);
    write_codes(w, &codes3, p.level);
    write_codes(w, &codesc, p.level);
    // The quantizer bounds every entry error by half a step.
    let n1 = q1.iter().map(|q| (k as f64).sqrt() * q.max_error()).collect();
    let n3 = q3.iter().map(|q| (frames as f64).sqrt() * q.max_error()).collect();
    let dc = (core.len() as f64).sqrt() * qc.max_error();
    Ok((n1, n3, dc))
}

/// The operator of a paper-coded packet of `frames` frames of `k` vertices at ranks `v` and
/// `f`: the quantizers that end the side block `s` (one per `U1` column, one per `U3` column,
/// one for the core), then the three code blocks of `r`. Returns `(U1, U3, core)`, row-major.
#[allow(clippy::too_many_arguments)]
pub(crate) fn decode(
    r: &mut ByteReader<'_>,
    s: &mut ByteReader<'_>,
    k: usize,
    frames: usize,
    v: usize,
    f: usize,
    limits: &Limits,
) -> Result<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    let q1: Vec<Quantizer> = (0..v).map(|_| Quantizer::read(s, "u1_quantizer")).collect::<Result<_>>()?;
    let q3: Vec<Quantizer> = (0..f).map(|_| Quantizer::read(s, "u3_quantizer")).collect::<Result<_>>()?;
    let qc = Quantizer::read(s, "core_quantizer")?;
    s.expect_end("side")?;
    if let Some(q) = q1.iter().chain(&q3).chain([&qc]).find(|q| q.bits() > MAX_BITS) {
        return Err(Error::malformed(NAME, "quantizer", format!("{} bits, at most {MAX_BITS}", q.bits())));
    }

    let c1 = read_codes(r, k * v, limits, "u1_codes")?;
    let u1 = column_values(&c1, &q1, k, v, "u1_codes")?;
    drop(c1);
    let c3 = read_codes(r, frames * f, limits, "u3_codes")?;
    let u3 = column_values(&c3, &q3, frames, f, "u3_codes")?;
    let cc = read_codes(r, 3 * v * f, limits, "core_codes")?;
    r.expect_end("packet")?;
    let zero = qc.quantize(0.0) as i64;
    let max = qc.max_code() as i64;
    let core = cc
        .iter()
        .map(|&z| {
            let code = zero + zigzag_decode(z as u64);
            if (0..=max).contains(&code) {
                Ok(qc.dequantize(code as u32) as f64)
            } else {
                Err(Error::malformed(NAME, "core_codes", format!("code {code} outside 0..={max}")))
            }
        })
        .collect::<Result<Vec<f64>>>()?;
    Ok((u1, u3, core))
}

/// Dequantized row-major `rows × qs.len()` factor from the codes of [`delta_code_columns`]
/// (column by column, zigzag deltas from the code of 0); a code outside its quantizer's range
/// is an error naming `field`.
fn column_values(codes: &[u32], qs: &[Quantizer], rows: usize, cols: usize, field: &'static str) -> Result<Vec<f64>> {
    let mut out = vec![0.0f64; rows * cols];
    for (c, q) in qs.iter().enumerate() {
        let mut prev = q.quantize(0.0) as i64;
        let max = q.max_code() as i64;
        for r in 0..rows {
            let code = prev + zigzag_decode(codes[c * rows + r] as u64);
            if !(0..=max).contains(&code) {
                return Err(Error::malformed(NAME, field, format!("code {code} outside 0..={max}")));
            }
            out[r * cols + c] = q.dequantize(code as u32) as f64;
            prev = code;
        }
    }
    Ok(out)
}
