//! Uniform scalar quantization with a stored range.
//!
//! A [`Quantizer`] maps `[min, max]` onto the integers `0 ..= 2^bits − 1` with a uniform step
//! and rounds to nearest, so the reconstruction error of any value inside the range is at most
//! half a step ([`Quantizer::max_error`]). Arithmetic is done in `f64` so encoder and decoder
//! agree bit for bit on every platform.

use crate::bytes::{ByteReader, ByteWriter};
use crate::error::{Error, Result};

/// Smallest and largest supported bit depths.
pub const BITS_RANGE: std::ops::RangeInclusive<u8> = 1..=32;

/// A uniform scalar quantizer over a stored range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quantizer {
    min: f32,
    max: f32,
    bits: u8,
}

impl Quantizer {
    /// A quantizer for `[min, max]` at `bits` bits (1..=32).
    pub fn new(min: f32, max: f32, bits: u8) -> Result<Self> {
        if !BITS_RANGE.contains(&bits) {
            return Err(Error::parameter("quantizer", "bits", format!("{bits} is outside the allowed range 1..=32")));
        }
        if !(min.is_finite() && max.is_finite() && min <= max) {
            return Err(Error::parameter(
                "quantizer",
                "range",
                format!("[{min}, {max}] is not a finite, ordered interval"),
            ));
        }
        Ok(Self { min, max, bits })
    }

    /// A quantizer covering every value of `values` (an empty slice gives `[0, 0]`).
    pub fn covering(values: &[f32], bits: u8) -> Result<Self> {
        let (min, max) = min_max(values);
        Self::new(min, max, bits)
    }

    /// Bit depth.
    pub fn bits(&self) -> u8 {
        self.bits
    }
    /// Lower end of the range.
    pub fn min(&self) -> f32 {
        self.min
    }
    /// Upper end of the range.
    pub fn max(&self) -> f32 {
        self.max
    }

    /// Largest code, `2^bits − 1`.
    pub fn max_code(&self) -> u32 {
        ((1u64 << self.bits) - 1) as u32
    }

    /// Quantization step; zero when the range is a single value.
    pub fn step(&self) -> f64 {
        (self.max as f64 - self.min as f64) / self.max_code() as f64
    }

    /// Largest reconstruction error for a value inside the range: half a step, plus the
    /// rounding of the reconstruction to `f32`.
    pub fn max_error(&self) -> f64 {
        let magnitude = (self.min.abs()).max(self.max.abs()) as f64;
        0.5 * self.step() + magnitude * f32::EPSILON as f64
    }

    /// Code of `x`, rounded to nearest and clamped to the range.
    pub fn quantize(&self, x: f32) -> u32 {
        let step = self.step();
        if step == 0.0 {
            return 0;
        }
        let q = ((x as f64 - self.min as f64) / step).round();
        q.clamp(0.0, self.max_code() as f64) as u32
    }

    /// Value of code `q` (codes above [`Quantizer::max_code`] are clamped).
    pub fn dequantize(&self, q: u32) -> f32 {
        let q = q.min(self.max_code());
        (self.min as f64 + q as f64 * self.step()) as f32
    }

    /// Writes bits, min and max (9 bytes).
    pub fn write(&self, w: &mut ByteWriter) {
        w.u8(self.bits);
        w.f32(self.min);
        w.f32(self.max);
    }

    /// Reads a quantizer written by [`Quantizer::write`], validating it.
    pub fn read(r: &mut ByteReader<'_>, field: &'static str) -> Result<Self> {
        let bits = r.u8(field)?;
        let min = r.f32(field)?;
        let max = r.f32(field)?;
        Self::new(min, max, bits).map_err(|e| r.malformed(field, e.to_string()))
    }
}

/// `(min, max)` of a slice; `(0, 0)` when empty.
pub fn min_max(values: &[f32]) -> (f32, f32) {
    if values.is_empty() {
        return (0.0, 0.0);
    }
    values.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn rejects_bad_configuration() {
        assert!(Quantizer::new(0.0, 1.0, 0).is_err());
        assert!(Quantizer::new(0.0, 1.0, 33).is_err());
        assert!(Quantizer::new(1.0, 0.0, 8).is_err());
        assert!(Quantizer::new(f32::NAN, 0.0, 8).is_err());
    }

    #[test]
    fn constant_range_reconstructs_exactly() {
        let q = Quantizer::new(2.5, 2.5, 8).unwrap();
        assert_eq!(q.dequantize(q.quantize(2.5)), 2.5);
    }

    #[test]
    fn serialization_round_trips_and_rejects_garbage() {
        let q = Quantizer::new(-3.0, 7.0, 12).unwrap();
        let mut w = ByteWriter::new();
        q.write(&mut w);
        let bytes = w.into_vec();
        assert_eq!(Quantizer::read(&mut ByteReader::new(&bytes, "t"), "q").unwrap(), q);
        let mut bad = bytes.clone();
        bad[0] = 40;
        assert!(Quantizer::read(&mut ByteReader::new(&bad, "t"), "q").is_err());
    }

    proptest! {
        #[test]
        fn error_within_half_step(
            lo in -1.0e4f32..1.0e4,
            width in 0.0f32..1.0e4,
            bits in 1u8..=32,
            t in 0.0f64..=1.0,
        ) {
            let hi = lo + width;
            let q = Quantizer::new(lo, hi, bits).unwrap();
            let x = (lo as f64 + t * (hi as f64 - lo as f64)) as f32;
            let x = x.clamp(lo, hi);
            let code = q.quantize(x);
            prop_assert!(code <= q.max_code());
            let err = (q.dequantize(code) as f64 - x as f64).abs();
            prop_assert!(err <= q.max_error() * (1.0 + 1e-9), "err {} > bound {}", err, q.max_error());
        }

        #[test]
        fn codes_are_monotone(lo in -100.0f32..100.0, width in 0.001f32..100.0, bits in 1u8..=16,
                              a in 0.0f32..1.0, b in 0.0f32..1.0) {
            let q = Quantizer::new(lo, lo + width, bits).unwrap();
            let (x, y) = (lo + a * width, lo + b * width);
            if x <= y { prop_assert!(q.quantize(x) <= q.quantize(y)); }
        }
    }
}
