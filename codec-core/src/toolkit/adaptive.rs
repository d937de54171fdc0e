//! Context-adaptive arithmetic coding of signed integers on `constriction`'s range coder.
//!
//! An integer `r` is binarized as (CABAC-style, adaptive exponential-Golomb):
//! 1. a *zero* decision (`r == 0`);
//! 2. a *sign* decision;
//! 3. the exponent `e = ⌊log2 |r|⌋` in unary (`e` ones then a zero, at most [`MAX_EXPONENT`]);
//! 4. the `e` bits of `|r|` below its leading one: the top [`MODELLED_MANTISSA_BITS`] with
//!    adaptive models (per exponent), the rest with a fixed probability of one half.
//!
//! Every adaptive decision has a probability estimate that learns as symbols pass (two
//! exponentially decaying estimates at different speeds, averaged: fast start, stable
//! finish), so no statistics are stored in the stream. The models of steps 1–3 are chosen by a
//! *context*: the caller's `class` (e.g. a component index bucket) times a bucket of the
//! *neighbourhood magnitude* (e.g. the mean magnitude of already coded neighbouring codes, see
//! [`magnitude_bucket`]), so a smooth region and a busy region learn separate statistics.
//!
//! [`CostModel`] runs the same models without coding and returns the ideal code length in bits:
//! what a rate-distortion search ([`super::rdq`]) needs, within a fraction of a percent of the
//! real coder.
//!
//! The decoder treats its input as untrusted: the word count is checked by the caller against
//! its own bounds, the unary exponent stops at [`MAX_EXPONENT`] (the encoder writes no
//! terminating zero there, so longer runs of ones cannot be expressed), and nothing panics on
//! garbage (a corrupted stream decodes to wrong integers or an error, which the caller's range
//! checks catch).
//!
//! Forged symbol counts: constriction's range decoder reads zeros once its
//! words run out, so a stream whose header claims more symbols than were coded (e.g. twice the
//! vertices) used to decode to garbage. [`CheckedWords`] counts the reads past the end: the
//! encoder's seal leaves the decoder at most one word short (it writes the point word, and a
//! zero word only when the range needs it), so a second read past the end means the data ran
//! out before the symbols did, and decoding fails. [`AdaptiveDecoder::finish`] checks the
//! other direction: every word was read (no trailing data the decoder never looked at).

use std::borrow::Borrow;
use std::num::NonZeroU32;

use constriction::backends::ReadWords;
use constriction::stream::model::{DecoderModel, EncoderModel, EntropyModel};
use constriction::stream::queue::{DefaultRangeEncoder, RangeDecoder};
use constriction::stream::{Decode, Encode};
use constriction::CoderError;

use crate::error::{Error, Result};

/// Fixed-point precision of the binary models.
const PRECISION: usize = 16;
const ONE: u32 = 1 << PRECISION;
/// Probabilities are kept inside `[MIN_P, ONE − MIN_P]` so no decision ever costs more than
/// ~11 bits and both symbols stay codable.
const MIN_P: u32 = 32;
/// Adaptation speeds (shifts) of the fast and slow estimates.
const FAST: u32 = 4;
const SLOW: u32 = 7;

/// Largest exponent `⌊log2 |r|⌋` of a coded integer: magnitudes below `2^31`.
pub const MAX_EXPONENT: usize = 30;
/// Mantissa bits (below the leading one) coded with adaptive models; the rest are coded at
/// one half (they are close to uniform).
pub const MODELLED_MANTISSA_BITS: usize = 2;
/// Number of neighbourhood-magnitude buckets ([`magnitude_bucket`]).
pub const MAGNITUDE_BUCKETS: usize = 8;
/// Unary exponent positions with their own models; later positions share the last one.
const EXP_MODELS: usize = 12;

/// An adaptive estimate of the probability that a binary decision is `false` (0).
#[derive(Debug, Clone, Copy)]
struct Bit {
    fast: u16,
    slow: u16,
}

impl Default for Bit {
    fn default() -> Self {
        Self { fast: (ONE / 2) as u16, slow: (ONE / 2) as u16 }
    }
}

impl Bit {
    /// Probability of 0, in `[MIN_P, ONE − MIN_P]`, as a fixed-point number.
    #[inline]
    fn p0(&self) -> u32 {
        ((self.fast as u32 + self.slow as u32 + 1) >> 1).clamp(MIN_P, ONE - MIN_P)
    }

    #[inline]
    fn update(&mut self, bit: bool) {
        // Estimates live in u16 (ONE = 2^16 does not fit, so the top is ONE − 1).
        let (f, s) = (self.fast as u32, self.slow as u32);
        if bit {
            self.fast = (f - (f >> FAST)) as u16;
            self.slow = (s - (s >> SLOW)) as u16;
        } else {
            self.fast = (f + ((ONE - 1 - f) >> FAST)) as u16;
            self.slow = (s + ((ONE - 1 - s) >> SLOW)) as u16;
        }
    }
}

/// A two-symbol entropy model with probability `p0` of `false`, for constriction's coders.
struct BinaryModel {
    p0: u32,
}

impl EntropyModel<PRECISION> for BinaryModel {
    type Symbol = bool;
    type Probability = u32;
}

impl EncoderModel<PRECISION> for BinaryModel {
    #[inline]
    fn left_cumulative_and_probability(&self, symbol: impl Borrow<bool>) -> Option<(u32, NonZeroU32)> {
        // p0 ∈ [MIN_P, ONE − MIN_P], so both probabilities are nonzero.
        if *symbol.borrow() {
            Some((self.p0, NonZeroU32::new(ONE - self.p0)?))
        } else {
            Some((0, NonZeroU32::new(self.p0)?))
        }
    }
}

impl DecoderModel<PRECISION> for BinaryModel {
    #[inline]
    fn quantile_function(&self, quantile: u32) -> (bool, u32, NonZeroU32) {
        if quantile < self.p0 {
            (false, 0, NonZeroU32::new(self.p0).unwrap_or(NonZeroU32::MIN))
        } else {
            (true, self.p0, NonZeroU32::new(ONE - self.p0).unwrap_or(NonZeroU32::MIN))
        }
    }
}

/// Bucket of a neighbourhood magnitude: 0 for 0, then `⌊log2⌋ + 1` of `2·magnitude`,
/// capped at [`MAGNITUDE_BUCKETS`] − 1. Pass e.g. the mean `|code|` of coded neighbours
/// (`sum_abs / count`, as `sum_abs · 2 / count` keeps half steps apart).
#[inline]
pub fn magnitude_bucket(sum_abs: u64, count: u32) -> usize {
    if count == 0 || sum_abs == 0 {
        return 0;
    }
    let twice_mean = (2 * sum_abs) / count as u64;
    ((64 - twice_mean.leading_zeros()) as usize).min(MAGNITUDE_BUCKETS - 1)
}

/// The adaptive models for `classes` classes × [`MAGNITUDE_BUCKETS`] contexts.
#[derive(Debug, Clone)]
struct Models {
    contexts: usize,
    zero: Vec<Bit>,
    sign: Vec<Bit>,
    exponent: Vec<Bit>,
    mantissa: Vec<Bit>,
}

impl Models {
    fn new(classes: usize) -> Self {
        let contexts = classes.max(1) * MAGNITUDE_BUCKETS;
        Self {
            contexts,
            zero: vec![Bit::default(); contexts],
            sign: vec![Bit::default(); contexts],
            exponent: vec![Bit::default(); contexts * EXP_MODELS],
            mantissa: vec![Bit::default(); (MAX_EXPONENT + 1) * (1 << MODELLED_MANTISSA_BITS)],
        }
    }

    /// Context index; out-of-range classes share the last class (never panics).
    #[inline]
    fn context(&self, class: usize, bucket: usize) -> usize {
        let classes = self.contexts / MAGNITUDE_BUCKETS;
        class.min(classes - 1) * MAGNITUDE_BUCKETS + bucket.min(MAGNITUDE_BUCKETS - 1)
    }
}

/// Walks the binarization of `value`, calling `emit(model, bit)` for adaptive decisions and
/// `emit(None, bit)` for the fixed one-half decisions. Shared by encoder and cost model so
/// they cannot disagree.
#[inline]
fn binarize(models: &mut Models, value: i32, ctx: usize, mut emit: impl FnMut(Option<&mut Bit>, bool)) {
    let zero = value == 0;
    emit(Some(&mut models.zero[ctx]), !zero);
    if zero {
        return;
    }
    emit(Some(&mut models.sign[ctx]), value < 0);
    let magnitude = value.unsigned_abs();
    let e = (31 - magnitude.leading_zeros()) as usize;
    for j in 0..e {
        emit(Some(&mut models.exponent[ctx * EXP_MODELS + j.min(EXP_MODELS - 1)]), true);
    }
    if e < MAX_EXPONENT {
        emit(Some(&mut models.exponent[ctx * EXP_MODELS + e.min(EXP_MODELS - 1)]), false);
    }
    // Bits below the leading one, most significant first; the first few adaptive, keyed by
    // exponent and the bits already sent.
    let mut prefix = 1usize;
    for b in (0..e).rev() {
        let bit = (magnitude >> b) & 1 == 1;
        let depth = e - 1 - b;
        if depth < MODELLED_MANTISSA_BITS {
            emit(Some(&mut models.mantissa[e * (1 << MODELLED_MANTISSA_BITS) + prefix]), bit);
            prefix = (prefix << 1 | bit as usize) & ((1 << MODELLED_MANTISSA_BITS) - 1);
        } else {
            emit(None, bit);
        }
    }
}

/// Largest magnitude codable: `2^(MAX_EXPONENT + 1) − 1`.
pub const MAX_MAGNITUDE: u32 = (1u32 << (MAX_EXPONENT + 1)) - 1;

/// Arithmetic encoder of signed integers with adaptive contexts.
pub struct AdaptiveEncoder {
    coder: DefaultRangeEncoder,
    models: Models,
}

impl AdaptiveEncoder {
    /// An encoder with `classes` classes (each × [`MAGNITUDE_BUCKETS`] contexts).
    pub fn new(classes: usize) -> Self {
        Self { coder: DefaultRangeEncoder::new(), models: Models::new(classes) }
    }

    /// Codes `value` (|value| ≤ [`MAX_MAGNITUDE`], larger magnitudes are clamped — callers
    /// keep their codes inside it) in context (`class`, `bucket`).
    pub fn encode(&mut self, value: i32, class: usize, bucket: usize) {
        let value = value.clamp(-(MAX_MAGNITUDE as i32), MAX_MAGNITUDE as i32);
        let ctx = self.models.context(class, bucket);
        let coder = &mut self.coder;
        binarize(&mut self.models, value, ctx, |bit_model, bit| {
            let p0 = bit_model.as_ref().map_or(ONE / 2, |m| m.p0());
            // Encoding with a nonzero-probability symbol into an in-memory Vec cannot fail.
            coder.encode_symbol(bit, BinaryModel { p0 }).expect("in-memory range coding of a codable symbol");
            if let Some(m) = bit_model {
                m.update(bit);
            }
        });
    }

    /// The coded bytes (little-endian 32-bit words).
    pub fn finish(self) -> Vec<u8> {
        let words = self.coder.into_compressed().expect("in-memory range encoder");
        words.iter().flat_map(|w| w.to_le_bytes()).collect()
    }
}

/// The words of a range-coded block for constriction's decoder, refusing to run past them.
///
/// The first read past the last word returns "no more data" (the decoder then shifts in a zero
/// word, which a legitimately sealed stream may need: see the module docs); any further read
/// fails with [`RanPastEnd`], which the decoder reports as an error instead of decoding
/// symbols from zeros that were never written.
#[derive(Debug, Clone)]
pub struct CheckedWords {
    words: Vec<u32>,
    pos: usize,
    past_end: u32,
}

/// The error of a read past [`CheckedWords`]' allowance.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RanPastEnd;

impl CheckedWords {
    /// The words of `bytes` (little-endian 32-bit words; a whole number of them).
    pub fn from_le_bytes(bytes: &[u8], context: &'static str, field: &'static str) -> Result<Self> {
        if !bytes.len().is_multiple_of(4) {
            return Err(corrupt(context, field, "arithmetic-coded block is not a whole number of 32-bit words"));
        }
        let words = bytes.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
        Ok(Self::new(words))
    }

    /// The words themselves.
    pub fn new(words: Vec<u32>) -> Self {
        Self { words, pos: 0, past_end: 0 }
    }

    /// Whether every word was read (what a decoder that decoded exactly the encoder's symbols
    /// has done: see the module docs).
    pub fn consumed(&self) -> bool {
        self.pos == self.words.len()
    }

    /// Whether the block holds no word at all (an encoder that coded no symbol).
    pub fn is_empty(&self) -> bool {
        self.words.is_empty()
    }
}

impl ReadWords<u32, constriction::Queue> for CheckedWords {
    type ReadError = RanPastEnd;

    #[inline]
    fn read(&mut self) -> std::result::Result<Option<u32>, RanPastEnd> {
        if let Some(&w) = self.words.get(self.pos) {
            self.pos += 1;
            return Ok(Some(w));
        }
        self.past_end += 1;
        if self.past_end > 1 {
            Err(RanPastEnd)
        } else {
            Ok(None)
        }
    }

    #[inline]
    fn maybe_exhausted(&self) -> bool {
        self.pos >= self.words.len()
    }
}

/// constriction's default range decoder (32-bit words, 64-bit state) over [`CheckedWords`].
pub type CheckedRangeDecoder = RangeDecoder<u32, u64, CheckedWords>;

/// A [`CheckedRangeDecoder`] over `bytes` (a whole number of little-endian 32-bit words).
pub fn checked_range_decoder(bytes: &[u8], context: &'static str, field: &'static str) -> Result<CheckedRangeDecoder> {
    let words = CheckedWords::from_le_bytes(bytes, context, field)?;
    CheckedRangeDecoder::with_backend(words).map_err(|_| corrupt(context, field, "range coder header"))
}

/// The error of a symbol that could not be decoded: the data ran out or is invalid.
pub fn range_error<F>(context: &'static str, field: &'static str, e: CoderError<F, RanPastEnd>) -> Error {
    match e {
        CoderError::Backend(RanPastEnd) => corrupt(
            context,
            field,
            "the arithmetic-coded data ends before its symbols do (the stream declares more values than it codes)",
        ),
        CoderError::Frontend(_) => corrupt(context, field, "invalid range code"),
    }
}

/// Checks that a range decoder that decoded its last symbol read every word of its block:
/// trailing words mean the stream declares fewer values than it codes.
pub fn check_consumed(dec: CheckedRangeDecoder, context: &'static str, field: &'static str) -> Result<()> {
    let (words, _, _) = dec.into_raw_parts();
    if words.consumed() {
        Ok(())
    } else {
        Err(corrupt(
            context,
            field,
            &format!(
                "{} of its {} arithmetic-coded words were never read (the stream declares fewer values than it codes)",
                words.words.len() - words.pos,
                words.words.len()
            ),
        ))
    }
}

/// Decoder for [`AdaptiveEncoder`]'s output.
pub struct AdaptiveDecoder {
    coder: CheckedRangeDecoder,
    models: Models,
    /// The block holds no word: its encoder coded no symbol, so decoding any is an error.
    empty: bool,
    /// Whether any symbol was decoded (a block from which none is decoded must be empty).
    used: bool,
    context: &'static str,
    field: &'static str,
}

fn corrupt(context: &'static str, field: &'static str, detail: &str) -> Error {
    Error::malformed(context, field, detail.to_owned())
}

impl AdaptiveDecoder {
    /// A decoder over `bytes` (a whole number of 32-bit words) with the encoder's `classes`.
    /// `context`/`field` name the stream part in errors.
    pub fn new(bytes: &[u8], classes: usize, context: &'static str, field: &'static str) -> Result<Self> {
        let words = CheckedWords::from_le_bytes(bytes, context, field)?;
        let empty = words.is_empty();
        let coder =
            CheckedRangeDecoder::with_backend(words).map_err(|_| corrupt(context, field, "range coder header"))?;
        Ok(Self { coder, models: Models::new(classes), empty, used: false, context, field })
    }

    /// Ends decoding: fails unless every word of the block was read, i.e. the block held no
    /// more than the symbols decoded. Call after the last symbol.
    pub fn finish(self) -> Result<()> {
        if !self.used && !self.empty {
            return Err(corrupt(self.context, self.field, "arithmetic-coded words where no value is coded"));
        }
        check_consumed(self.coder, self.context, self.field)
    }

    #[inline]
    fn bit(&mut self, which: Option<(Which, usize)>) -> Result<bool> {
        let model = match which {
            Some((Which::Zero, i)) => Some(&mut self.models.zero[i]),
            Some((Which::Sign, i)) => Some(&mut self.models.sign[i]),
            Some((Which::Exponent, i)) => Some(&mut self.models.exponent[i]),
            Some((Which::Mantissa, i)) => Some(&mut self.models.mantissa[i]),
            None => None,
        };
        if self.empty {
            return Err(range_error::<()>(self.context, self.field, CoderError::Backend(RanPastEnd)));
        }
        self.used = true;
        let p0 = model.as_ref().map_or(ONE / 2, |m| m.p0());
        let bit = self.coder.decode_symbol(BinaryModel { p0 }).map_err(|e| range_error(self.context, self.field, e))?;
        if let Some(m) = model {
            m.update(bit);
        }
        Ok(bit)
    }

    /// Decodes one integer in context (`class`, `bucket`), mirroring `binarize`.
    pub fn decode(&mut self, class: usize, bucket: usize) -> Result<i32> {
        let ctx = self.models.context(class, bucket);
        if !self.bit(Some((Which::Zero, ctx)))? {
            return Ok(0);
        }
        let negative = self.bit(Some((Which::Sign, ctx)))?;
        let mut e = 0usize;
        while e < MAX_EXPONENT && self.bit(Some((Which::Exponent, ctx * EXP_MODELS + e.min(EXP_MODELS - 1))))? {
            e += 1;
        }
        let mut magnitude = 1u32;
        let mut prefix = 1usize;
        for depth in 0..e {
            let bit = if depth < MODELLED_MANTISSA_BITS {
                let b = self.bit(Some((Which::Mantissa, e * (1 << MODELLED_MANTISSA_BITS) + prefix)))?;
                prefix = (prefix << 1 | b as usize) & ((1 << MODELLED_MANTISSA_BITS) - 1);
                b
            } else {
                self.bit(None)?
            };
            magnitude = magnitude << 1 | bit as u32;
        }
        // magnitude < 2^31 because e ≤ MAX_EXPONENT = 30.
        let m = magnitude as i32;
        Ok(if negative { -m } else { m })
    }
}

#[derive(Clone, Copy)]
enum Which {
    Zero,
    Sign,
    Exponent,
    Mantissa,
}

/// `−log2(p / ONE)` for `p` in steps of `ONE / TABLE`, for fast cost estimates.
const TABLE_BITS: u32 = 12;

fn cost_table() -> &'static [f32] {
    use std::sync::OnceLock;
    static TABLE: OnceLock<Vec<f32>> = OnceLock::new();
    TABLE.get_or_init(|| {
        (0..(1u32 << TABLE_BITS))
            .map(|i| {
                let p = (i as f64 + 0.5) / (1u64 << TABLE_BITS) as f64;
                (-p.log2()) as f32
            })
            .collect()
    })
}

/// The encoder's models without the coder: ideal code length of a sequence, for rate
/// estimates. Adapts exactly like [`AdaptiveEncoder`].
#[derive(Debug, Clone)]
pub struct CostModel {
    models: Models,
    bits: f64,
}

impl CostModel {
    /// A fresh cost model with `classes` classes.
    pub fn new(classes: usize) -> Self {
        Self { models: Models::new(classes), bits: 0.0 }
    }

    /// Adds the cost of coding `value` in context (`class`, `bucket`) and adapts.
    #[inline]
    pub fn add(&mut self, value: i32, class: usize, bucket: usize) {
        let value = value.clamp(-(MAX_MAGNITUDE as i32), MAX_MAGNITUDE as i32);
        let ctx = self.models.context(class, bucket);
        let table = cost_table();
        let mut bits = 0.0f32;
        binarize(&mut self.models, value, ctx, |bit_model, bit| match bit_model {
            Some(m) => {
                let p0 = m.p0();
                let p = if bit { ONE - p0 } else { p0 };
                bits += table[(p >> (PRECISION as u32 - TABLE_BITS)) as usize];
                m.update(bit);
            }
            None => bits += 1.0,
        });
        self.bits += bits as f64;
    }

    /// Total estimated bits so far.
    pub fn bits(&self) -> f64 {
        self.bits
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn laplacian(n: usize, scale: f64, seed: u64) -> Vec<i32> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                let u = ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
                let x = -scale * (2.0 * (u - 0.5)).abs().max(1e-300).ln() * if u < 0.5 { -1.0 } else { 1.0 };
                x.round() as i32
            })
            .collect()
    }

    #[test]
    fn round_trips_every_magnitude_and_context() {
        let mut values: Vec<i32> = laplacian(5000, 3.0, 1);
        values.extend([0, 1, -1, 2, -2, MAX_MAGNITUDE as i32, -(MAX_MAGNITUDE as i32), 1 << 20, -(1 << 29) - 7]);
        let mut enc = AdaptiveEncoder::new(3);
        for (i, &v) in values.iter().enumerate() {
            enc.encode(v, i % 4, i % 9);
        }
        let bytes = enc.finish();
        let mut dec = AdaptiveDecoder::new(&bytes, 3, "t", "codes").unwrap();
        for (i, &v) in values.iter().enumerate() {
            assert_eq!(dec.decode(i % 4, i % 9).unwrap(), v, "value {i}");
        }
    }

    #[test]
    fn beats_the_zeroth_order_entropy_of_a_skewed_source_and_cost_model_agrees() {
        // Two interleaved sources of very different scale, told apart by the class: the
        // contexts must separate them (cost below the mixed source's zeroth-order entropy).
        let a = laplacian(20_000, 0.3, 2);
        let b = laplacian(20_000, 40.0, 3);
        let mut enc = AdaptiveEncoder::new(2);
        let mut cost = CostModel::new(2);
        let mut hist = std::collections::HashMap::<i32, usize>::new();
        for i in 0..a.len() {
            enc.encode(a[i], 0, 0);
            enc.encode(b[i], 1, 0);
            cost.add(a[i], 0, 0);
            cost.add(b[i], 1, 0);
            *hist.entry(a[i]).or_default() += 1;
            *hist.entry(b[i]).or_default() += 1;
        }
        let n = 2.0 * a.len() as f64;
        let entropy: f64 = hist.values().map(|&c| -(c as f64) * (c as f64 / n).log2()).sum();
        let real = enc.finish().len() as f64 * 8.0;
        assert!(real < 0.9 * entropy, "coded {real} bits, mixed zeroth-order entropy {entropy}");
        assert!((cost.bits() - real).abs() < 0.01 * real + 64.0, "estimate {} vs real {real}", cost.bits());
    }

    #[test]
    fn garbage_and_truncation_never_panic() {
        let values = laplacian(2000, 10.0, 4);
        let mut enc = AdaptiveEncoder::new(1);
        values.iter().for_each(|&v| enc.encode(v, 0, 0));
        let bytes = enc.finish();
        assert!(AdaptiveDecoder::new(&bytes[..bytes.len() - 1], 1, "t", "c").is_err());
        for cut in (0..bytes.len()).step_by(4) {
            if let Ok(mut dec) = AdaptiveDecoder::new(&bytes[..cut], 1, "t", "c") {
                for _ in 0..values.len() {
                    if dec.decode(0, 0).is_err() {
                        break;
                    }
                }
            }
        }
        let mut s = 7u32;
        let garbage: Vec<u8> = (0..4096)
            .map(|_| {
                s = s.wrapping_mul(1103515245).wrapping_add(12345);
                (s >> 16) as u8
            })
            .collect();
        if let Ok(mut dec) = AdaptiveDecoder::new(&garbage, 1, "t", "c") {
            for _ in 0..10_000 {
                if dec.decode(0, 5).is_err() {
                    break;
                }
            }
        }
    }

    /// Decoding exactly what was coded reads every word and never runs past the
    /// allowance, for every length (the seal's one or two words included); decoding more runs
    /// past the end and fails; a block with a word more than was coded fails `finish`.
    #[test]
    fn running_past_the_data_or_leaving_words_unread_is_an_error() {
        for n in [0usize, 1, 2, 3, 7, 50, 333, 4000] {
            for scale in [0.0, 0.2, 30.0] {
                let values = laplacian(n, scale, n as u64 + 9);
                let mut enc = AdaptiveEncoder::new(2);
                values.iter().enumerate().for_each(|(i, &v)| enc.encode(v, i % 2, 0));
                let bytes = enc.finish();
                let mut dec = AdaptiveDecoder::new(&bytes, 2, "t", "c").unwrap();
                for (i, &v) in values.iter().enumerate() {
                    assert_eq!(dec.decode(i % 2, 0).unwrap(), v, "n {n} value {i}");
                }
                dec.finish().unwrap_or_else(|e| panic!("n {n} scale {scale}: {e}"));
                // Asking for more values than were coded: an error within a few words' worth
                // (zeros cost little, so allow many symbols, but never unbounded).
                let mut dec = AdaptiveDecoder::new(&bytes, 2, "t", "c").unwrap();
                let mut failed = false;
                for i in 0..values.len() + 10_000_000 {
                    if let Err(e) = dec.decode(i % 2, 0) {
                        assert!(e.to_string().contains("ends before its symbols do"), "{e}");
                        failed = true;
                        break;
                    }
                }
                assert!(failed, "n {n} scale {scale}: decoded 10^7 values past the data");
                // Two words more than the encoder wrote are left unread (one may be read in place
                // of the zero word the seal can leave out).
                let mut longer = bytes.clone();
                longer.extend_from_slice(&[0x5a; 8]);
                let mut dec = AdaptiveDecoder::new(&longer, 2, "t", "c").unwrap();
                let ok = values.iter().enumerate().all(|(i, &v)| dec.decode(i % 2, 0).is_ok_and(|d| d == v));
                if ok {
                    assert!(dec.finish().is_err(), "n {n} scale {scale}: trailing word accepted");
                }
            }
        }
    }

    #[test]
    fn magnitude_buckets_are_monotone_and_bounded() {
        let mut last = 0;
        for s in 0..10_000u64 {
            let b = magnitude_bucket(s, 3);
            assert!(b >= last && b < MAGNITUDE_BUCKETS);
            last = b;
        }
        assert_eq!(magnitude_bucket(5, 0), 0);
    }
}
