//! Little-endian byte writing and bounds-checked reading of untrusted streams.
//!
//! Every read names its field, so a truncated stream yields an error such as
//! `pca-aoi: field 'dictionary_rows' is truncated`. Readers never allocate from a size
//! they have not checked against the bytes that remain (see [`ByteReader::take`]).

use std::borrow::Cow;

use crate::error::{Error, Result};

/// Appends little-endian values to a `Vec<u8>`.
#[derive(Debug, Default, Clone)]
pub struct ByteWriter {
    buf: Vec<u8>,
}

impl ByteWriter {
    /// An empty writer.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends one byte.
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }
    /// Appends a little-endian `u16`.
    pub fn u16(&mut self, v: u16) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// Appends a little-endian `u32`.
    pub fn u32(&mut self, v: u32) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// Appends a little-endian `u64`.
    pub fn u64(&mut self, v: u64) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// Appends a little-endian IEEE-754 `f32`.
    pub fn f32(&mut self, v: f32) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// Appends a little-endian IEEE-754 `f64`.
    pub fn f64(&mut self, v: f64) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// Appends an unsigned LEB128 varint.
    pub fn varint(&mut self, mut v: u64) {
        loop {
            let byte = (v & 0x7f) as u8;
            v >>= 7;
            if v == 0 {
                self.buf.push(byte);
                return;
            }
            self.buf.push(byte | 0x80);
        }
    }
    /// Appends a signed value as a zigzag LEB128 varint.
    pub fn varint_signed(&mut self, v: i64) {
        self.varint(zigzag_encode(v));
    }
    /// Appends raw bytes.
    pub fn bytes(&mut self, b: &[u8]) {
        self.buf.extend_from_slice(b);
    }
    /// Appends a varint length followed by the bytes.
    pub fn length_prefixed(&mut self, b: &[u8]) {
        self.varint(b.len() as u64);
        self.bytes(b);
    }
    /// Bytes written so far.
    pub fn len(&self) -> usize {
        self.buf.len()
    }
    /// True when nothing has been written.
    pub fn is_empty(&self) -> bool {
        self.buf.is_empty()
    }
    /// The bytes written.
    pub fn as_slice(&self) -> &[u8] {
        &self.buf
    }
    /// Consumes the writer, returning its bytes.
    pub fn into_vec(self) -> Vec<u8> {
        self.buf
    }
}

/// Bounds-checked little-endian reader over an untrusted byte slice.
#[derive(Debug, Clone)]
pub struct ByteReader<'a> {
    data: &'a [u8],
    pos: usize,
    context: Cow<'static, str>,
}

impl<'a> ByteReader<'a> {
    /// A reader whose errors are attributed to `context` (a codec name or `container`).
    pub fn new(data: &'a [u8], context: impl Into<Cow<'static, str>>) -> Self {
        Self { data, pos: 0, context: context.into() }
    }

    /// The context errors are attributed to.
    pub fn context(&self) -> &str {
        &self.context
    }

    /// Bytes not yet read.
    pub fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }

    /// Current offset from the start of the slice.
    pub fn position(&self) -> usize {
        self.pos
    }

    /// Error for a truncated field.
    pub fn truncated(&self, field: impl Into<Cow<'static, str>>) -> Error {
        Error::Truncated { context: self.context.clone(), field: field.into() }
    }

    /// Error for a malformed field.
    pub fn malformed(&self, field: impl Into<Cow<'static, str>>, detail: impl Into<String>) -> Error {
        Error::malformed(self.context.clone(), field, detail)
    }

    /// Takes the next `n` bytes as a sub-slice (no allocation).
    pub fn take(&mut self, n: usize, field: &'static str) -> Result<&'a [u8]> {
        if n > self.remaining() {
            return Err(self.truncated(field));
        }
        let s = &self.data[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    fn array<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N]> {
        let s = self.take(N, field)?;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        Ok(a)
    }

    /// Reads one byte.
    pub fn u8(&mut self, field: &'static str) -> Result<u8> {
        Ok(self.array::<1>(field)?[0])
    }
    /// Reads a little-endian `u16`.
    pub fn u16(&mut self, field: &'static str) -> Result<u16> {
        Ok(u16::from_le_bytes(self.array(field)?))
    }
    /// Reads a little-endian `u32`.
    pub fn u32(&mut self, field: &'static str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.array(field)?))
    }
    /// Reads a little-endian `u64`.
    pub fn u64(&mut self, field: &'static str) -> Result<u64> {
        Ok(u64::from_le_bytes(self.array(field)?))
    }
    /// Reads a little-endian `f32` (any bit pattern, including NaN; callers check).
    pub fn f32(&mut self, field: &'static str) -> Result<f32> {
        Ok(f32::from_le_bytes(self.array(field)?))
    }
    /// Reads a little-endian `f32` and rejects NaN and infinities.
    pub fn finite_f32(&mut self, field: &'static str) -> Result<f32> {
        let v = self.f32(field)?;
        if !v.is_finite() {
            return Err(self.malformed(field, format!("{v} is not finite")));
        }
        Ok(v)
    }
    /// Reads a little-endian `f64`.
    pub fn f64(&mut self, field: &'static str) -> Result<f64> {
        Ok(f64::from_le_bytes(self.array(field)?))
    }
    /// Reads an unsigned LEB128 varint (at most 10 bytes, no overflow).
    pub fn varint(&mut self, field: &'static str) -> Result<u64> {
        let mut value: u64 = 0;
        for shift in (0..64).step_by(7) {
            let byte = self.u8(field)?;
            let bits = (byte & 0x7f) as u64;
            if shift == 63 && bits > 1 {
                return Err(self.malformed(field, "varint overflows 64 bits"));
            }
            value |= bits << shift;
            if byte & 0x80 == 0 {
                return Ok(value);
            }
        }
        Err(self.malformed(field, "varint longer than 10 bytes"))
    }
    /// Reads a zigzag LEB128 varint.
    pub fn varint_signed(&mut self, field: &'static str) -> Result<i64> {
        Ok(zigzag_decode(self.varint(field)?))
    }
    /// Reads a varint that must not exceed `max`; the error states the bound.
    pub fn varint_max(&mut self, field: &'static str, max: u64) -> Result<u64> {
        let v = self.varint(field)?;
        if v > max {
            return Err(self.malformed(field, format!("{v} exceeds the maximum {max}")));
        }
        Ok(v)
    }
    /// Reads a varint length, checks it against the remaining bytes, and returns that many bytes.
    pub fn length_prefixed(&mut self, field: &'static str) -> Result<&'a [u8]> {
        let n = self.varint(field)?;
        if n > self.remaining() as u64 {
            return Err(self.truncated(field));
        }
        self.take(n as usize, field)
    }
    /// Fails unless every byte has been consumed.
    pub fn expect_end(&self, field: &'static str) -> Result<()> {
        if self.remaining() != 0 {
            return Err(self.malformed(field, format!("{} unexpected trailing bytes", self.remaining())));
        }
        Ok(())
    }
}

/// Maps signed to unsigned so small magnitudes give small codes: 0, -1, 1, -2, … → 0, 1, 2, 3, …
pub fn zigzag_encode(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

/// Inverse of [`zigzag_encode`].
pub fn zigzag_decode(v: u64) -> i64 {
    ((v >> 1) as i64) ^ -((v & 1) as i64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_truncation() {
        let mut w = ByteWriter::new();
        w.u8(7);
        w.u16(0xBEEF);
        w.u32(123_456);
        w.u64(u64::MAX);
        w.f32(1.5);
        w.varint(300);
        w.varint(u64::MAX);
        w.varint_signed(-5);
        w.length_prefixed(b"abc");
        let bytes = w.into_vec();
        let mut r = ByteReader::new(&bytes, "test");
        assert_eq!(r.u8("a").unwrap(), 7);
        assert_eq!(r.u16("b").unwrap(), 0xBEEF);
        assert_eq!(r.u32("c").unwrap(), 123_456);
        assert_eq!(r.u64("d").unwrap(), u64::MAX);
        assert_eq!(r.f32("e").unwrap(), 1.5);
        assert_eq!(r.varint("f").unwrap(), 300);
        assert_eq!(r.varint("g").unwrap(), u64::MAX);
        assert_eq!(r.varint_signed("h").unwrap(), -5);
        assert_eq!(r.length_prefixed("i").unwrap(), b"abc");
        r.expect_end("end").unwrap();
        for cut in 0..bytes.len() {
            let mut r = ByteReader::new(&bytes[..cut], "test");
            let res: Result<()> = (|| {
                r.u8("a")?;
                r.u16("b")?;
                r.u32("c")?;
                r.u64("d")?;
                r.f32("e")?;
                r.varint("f")?;
                r.varint("g")?;
                r.varint_signed("h")?;
                r.length_prefixed("i")?;
                Ok(())
            })();
            assert!(res.is_err(), "cut at {cut} should fail");
        }
    }

    #[test]
    fn varint_rejects_overflow() {
        let bytes = [0xff; 11];
        assert!(ByteReader::new(&bytes, "t").varint("v").is_err());
        let bytes = [0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x02];
        assert!(ByteReader::new(&bytes, "t").varint("v").is_err());
    }

    #[test]
    fn zigzag_is_a_bijection_on_edges() {
        for v in [0, 1, -1, 2, -2, i64::MAX, i64::MIN] {
            assert_eq!(zigzag_decode(zigzag_encode(v)), v);
        }
        assert_eq!(zigzag_encode(-1), 1);
        assert_eq!(zigzag_encode(1), 2);
    }
}
