//! Quantization and arithmetic coding of spectral descriptors (paper §3.5).
//!
//! Each group of channels (rotation, stretch; or the nine gradient entries without polar
//! decomposition) of a frame has one amplitude `A` (the largest descriptor magnitude, stored
//! as `f32`) and a symmetric uniform quantizer `q = round(c / Δ)`, `Δ = A / (2^(bits−1) − 1)`,
//! so zero is exact and codes lie in `±(2^(bits−1) − 1)`.
//!
//! A code is arithmetic coded (constriction's range coder) as its magnitude class
//! `⌊log2 |q|⌋ + 1` (0 for zero) under an adaptive categorical model, then a sign bit and the
//! bits below the leading one with uniform models. The class models are indexed by group and
//! by the octave of the basis index (low frequencies have larger descriptors) and their counts
//! carry from frame to frame within a keyframe interval, so no histogram is stored: this is
//! the paper's "appearance numbers" (§3.5), learnt by encoder and decoder alike.

use codec_core::toolkit::adaptive::{check_consumed, checked_range_decoder, range_error};
use constriction::stream::model::{DefaultContiguousCategoricalEntropyModel, DefaultUniformModel};
use constriction::stream::queue::DefaultRangeEncoder;
use constriction::stream::{Decode, Encode};

use codec_core::{Error, Result};

use crate::NAME;

/// Octave bands of the basis index used as contexts.
const BANDS: usize = 10;
/// Counts are halved when a context's total exceeds this, so the model keeps adapting.
const MAX_TOTAL: u32 = 1 << 13;
/// Fixed-point precision of constriction's default models.
const PRECISION: u32 = 24;

fn band(k: usize) -> usize {
    ((usize::BITS - k.leading_zeros()) as usize).min(BANDS - 1)
}

/// Largest code magnitude at `bits` bits.
pub fn max_code(bits: u8) -> i64 {
    (1i64 << (bits - 1)) - 1
}

/// Quantization step of a group with amplitude `amp`.
pub fn step(amp: f32, bits: u8) -> f64 {
    amp as f64 / max_code(bits) as f64
}

/// The stored amplitude: the smallest `f32` not below `amp`.
pub fn amplitude(amp: f64) -> f32 {
    let a = amp as f32;
    if (a as f64) < amp && a.is_finite() {
        // The next f32 up (a positive finite value's successor is its bit pattern + 1;
        // `f32::next_up` needs Rust 1.86, above the MSRV).
        if a == 0.0 {
            f32::from_bits(1)
        } else if a > 0.0 {
            f32::from_bits(a.to_bits() + 1)
        } else {
            f32::from_bits(a.to_bits() - 1)
        }
    } else {
        a
    }
}

/// Code of `c` at step `step`.
pub fn quantize(c: f64, step: f64, bits: u8) -> i64 {
    if step == 0.0 {
        return 0;
    }
    let m = max_code(bits);
    ((c / step).round() as i64).clamp(-m, m)
}

/// Adaptive class statistics, one table per (group, band).
#[derive(Clone)]
pub struct Contexts {
    classes: usize,
    counts: Vec<Vec<u32>>,
}

impl Contexts {
    /// Flat statistics for `groups` groups at `bits` bits.
    pub fn new(groups: usize, bits: u8) -> Self {
        let classes = bits as usize; // 0 ..= bits − 1
        Self { classes, counts: vec![vec![1; classes]; groups * BANDS] }
    }

    fn model(&self, ctx: usize) -> DefaultContiguousCategoricalEntropyModel {
        let counts = &self.counts[ctx];
        let total: u64 = counts.iter().map(|&c| c as u64).sum();
        let k = counts.len() as u64;
        let budget = (1u64 << PRECISION) - k;
        let mut probs: Vec<u32> = counts.iter().map(|&c| 1 + (c as u64 * budget / total) as u32).collect();
        let sum: u64 = probs.iter().map(|&p| p as u64).sum();
        let (imax, _) = counts.iter().enumerate().fold((0, 0), |b, (i, &c)| if c > b.1 { (i, c) } else { b });
        probs[imax] += ((1u64 << PRECISION) - sum) as u32;
        DefaultContiguousCategoricalEntropyModel::from_nonzero_fixed_point_probabilities(&probs, false)
            .expect("probabilities are non-zero and sum to 2^24")
    }

    fn update(&mut self, ctx: usize, class: usize) {
        let c = &mut self.counts[ctx];
        c[class] += 16;
        if c.iter().sum::<u32>() > MAX_TOTAL {
            for x in c.iter_mut() {
                *x = x.div_ceil(2);
            }
        }
    }
}

fn class_of(q: i64) -> usize {
    (u64::BITS - q.unsigned_abs().leading_zeros()) as usize
}

/// Encodes the codes of one frame: `codes[g]` holds group `g`'s channels back to back, each
/// `bases` long. Updates `ctx`.
pub fn encode(codes: &[Vec<i64>], bases: usize, ctx: &mut Contexts) -> Vec<u8> {
    let mut enc = DefaultRangeEncoder::new();
    for (g, group) in codes.iter().enumerate() {
        // Models are fixed for the whole frame and updated afterwards (cheaper than per symbol).
        let models: Vec<_> = (0..BANDS).map(|b| ctx.model(g * BANDS + b)).collect();
        for (i, &q) in group.iter().enumerate() {
            let b = band(i % bases);
            let class = class_of(q);
            enc.encode_symbol(class, &models[b]).expect("class inside the model");
            if class > 0 {
                enc.encode_symbol((q < 0) as usize, DefaultUniformModel::new(2)).expect("sign");
                encode_bits(&mut enc, q.unsigned_abs() - (1 << (class - 1)), class - 1);
            }
        }
        for (i, &q) in group.iter().enumerate() {
            ctx.update(g * BANDS + band(i % bases), class_of(q));
        }
    }
    let words = enc.into_compressed().expect("in-memory range encoder");
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}

fn encode_bits(enc: &mut DefaultRangeEncoder, mut value: u64, mut n: usize) {
    while n > 0 {
        let chunk = n.min(16);
        enc.encode_symbol((value & ((1 << chunk) - 1)) as usize, DefaultUniformModel::new(1 << chunk))
            .expect("bits inside the uniform model");
        value >>= chunk;
        n -= chunk;
    }
}

fn malformed(detail: impl Into<String>) -> Error {
    Error::malformed(NAME, "descriptors", detail)
}

/// Decodes what [`encode`] wrote: `sizes[g]` codes per group. Every symbol is checked.
pub fn decode(bytes: &[u8], sizes: &[usize], bases: usize, ctx: &mut Contexts) -> Result<Vec<Vec<i64>>> {
    // A decoder that runs past the coded words (a stream declaring more codes than
    // it holds) fails instead of decoding zeros, and one that leaves words unread fails at the end.
    let mut dec = checked_range_decoder(bytes, NAME, "descriptors")?;
    let bad = |e| range_error(NAME, "descriptors", e);
    let mut out = Vec::with_capacity(sizes.len());
    for (g, &size) in sizes.iter().enumerate() {
        let models: Vec<_> = (0..BANDS).map(|b| ctx.model(g * BANDS + b)).collect();
        let mut group = Vec::with_capacity(size);
        for i in 0..size {
            let class: usize = dec.decode_symbol(&models[band(i % bases)]).map_err(bad)?;
            if class >= ctx.classes {
                return Err(malformed(format!("class {class} exceeds {}", ctx.classes - 1)));
            }
            let q = if class == 0 {
                0
            } else {
                let sign: usize = dec.decode_symbol(DefaultUniformModel::new(2)).map_err(bad)?;
                let mut rest = 0u64;
                let mut n = class - 1;
                let mut shift = 0;
                while n > 0 {
                    let chunk = n.min(16);
                    let bits: usize = dec.decode_symbol(DefaultUniformModel::new(1 << chunk)).map_err(bad)?;
                    rest |= (bits as u64) << shift;
                    shift += chunk;
                    n -= chunk;
                }
                let mag = ((1u64 << (class - 1)) + rest) as i64;
                if sign == 1 {
                    -mag
                } else {
                    mag
                }
            };
            group.push(q);
        }
        for (i, &q) in group.iter().enumerate() {
            ctx.update(g * BANDS + band(i % bases), class_of(q));
        }
        out.push(group);
    }
    if sizes.iter().any(|&s| s > 0) {
        check_consumed(dec, NAME, "descriptors")?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_round_trip_through_the_range_coder_and_adapt() {
        let bits = 18u8;
        let bases = 40;
        let m = max_code(bits);
        let mut state = 12345u64;
        let mut frames = Vec::new();
        for f in 0..4 {
            let mut groups = Vec::new();
            for (g, chans) in [3usize, 6].iter().enumerate() {
                let mut v = Vec::new();
                for i in 0..chans * bases {
                    state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    let k = i % bases;
                    let scale = (m as f64) / (1.0 + k as f64 * k as f64) / (1 + g + f) as f64;
                    let x = ((state >> 33) as f64 / (1u64 << 31) as f64 - 0.5) * 2.0 * scale;
                    v.push((x.round() as i64).clamp(-m, m));
                }
                v[0] = m;
                v[1] = -m;
                groups.push(v);
            }
            frames.push(groups);
        }
        let mut ce = Contexts::new(2, bits);
        let mut cd = Contexts::new(2, bits);
        let mut sizes = Vec::new();
        for groups in &frames {
            let bytes = encode(groups, bases, &mut ce);
            sizes.push(bytes.len());
            let back = decode(&bytes, &[3 * bases, 6 * bases], bases, &mut cd).unwrap();
            assert_eq!(&back, groups);
        }
        // Decaying descriptors cost far fewer than 18 bits each.
        let raw_bits = (9 * bases * 18) as f64;
        assert!(((sizes[3] * 8) as f64) < 0.8 * raw_bits, "{sizes:?}");
        // Garbage never panics.
        for seed in 0..200u32 {
            let junk: Vec<u8> =
                (0..64).map(|i| (i as u32).wrapping_mul(2654435761u32).wrapping_add(seed * 97) as u8).collect();
            let _ = decode(&junk, &[3 * bases, 6 * bases], bases, &mut Contexts::new(2, bits));
        }
    }

    #[test]
    fn quantizer_is_symmetric_with_exact_zero() {
        let a = amplitude(0.3);
        assert!(a as f64 >= 0.3);
        let s = step(a, 18);
        assert_eq!(quantize(0.0, s, 18), 0);
        assert_eq!(quantize(0.3, s, 18), max_code(18));
        assert_eq!(quantize(-0.3, s, 18), -max_code(18));
        let x = 0.123456;
        assert!((quantize(x, s, 18) as f64 * s - x).abs() <= 0.5 * s);
    }
}
