//! The shared entropy stage: zstd with a stored, limit-checked uncompressed length.
//!
//! Layout of a block: varint `raw_len`, then one zstd frame. The decoder checks `raw_len`
//! against the caller's bound *before* allocating, and checks that the frame decodes to
//! exactly `raw_len` bytes.

use std::borrow::Cow;

use crate::bytes::{ByteReader, ByteWriter};
use crate::error::{Error, Result};

/// Default zstd level: a good ratio at interactive speed.
pub const DEFAULT_LEVEL: i32 = 19;

/// Compresses `raw` into a self-describing block (deterministic for a given level).
pub fn compress(raw: &[u8], level: i32) -> Vec<u8> {
    let mut w = ByteWriter::new();
    w.varint(raw.len() as u64);
    // zstd::bulk::compress only fails on invalid parameters or allocation failure.
    let compressed = zstd::bulk::compress(raw, level).expect("zstd compression of an in-memory buffer");
    w.bytes(&compressed);
    w.into_vec()
}

/// Decompresses a block made by [`compress`]; `max_len` bounds the allocation.
pub fn decompress(
    block: &[u8],
    context: impl Into<Cow<'static, str>>,
    field: &'static str,
    max_len: usize,
) -> Result<Vec<u8>> {
    let context = context.into();
    let mut r = ByteReader::new(block, context.clone());
    let raw_len = r.varint(field)?;
    if raw_len > max_len as u64 {
        return Err(Error::AllocLimit { context, what: field.into(), bytes: raw_len, limit: max_len as u64 });
    }
    let frame = r.take(r.remaining(), field)?;
    // A zstd block decodes to at most 128 KiB and takes at least 4 bytes (an RLE block), so
    // a frame cannot expand more than 32768-fold: a tiny frame claiming a huge size is
    // malformed, and rejecting it here avoids a large useless allocation.
    if raw_len > (frame.len() as u64 + 1) * 32768 {
        return Err(Error::malformed(
            context,
            field,
            format!("{} compressed bytes cannot hold {raw_len} bytes", frame.len()),
        ));
    }
    // zstd writes into the vector's spare capacity and sets its length to what it produced.
    let mut out = Vec::with_capacity(raw_len as usize);
    let mut decoder =
        zstd::bulk::Decompressor::new().map_err(|e| Error::malformed(context.clone(), field, format!("zstd: {e}")))?;
    let n = decoder
        .decompress_to_buffer(frame, &mut out)
        .map_err(|e| Error::malformed(context.clone(), field, format!("zstd: {e}")))?;
    if n as u64 != raw_len || out.len() as u64 != raw_len {
        return Err(Error::malformed(context, field, format!("decompressed to {n} bytes, header says {raw_len}")));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_corruption() {
        let raw: Vec<u8> = (0..10_000u32).map(|i| (i % 17) as u8).collect();
        let block = compress(&raw, 5);
        assert!(block.len() < raw.len() / 10);
        assert_eq!(decompress(&block, "t", "b", raw.len()).unwrap(), raw);
        assert!(matches!(decompress(&block, "t", "b", 100), Err(Error::AllocLimit { .. })));
        for cut in 0..block.len() {
            assert!(decompress(&block[..cut], "t", "b", raw.len()).is_err(), "cut {cut} of {}", block.len());
        }
        let mut flipped = block.clone();
        let last = flipped.len() - 3;
        flipped[last] ^= 0x55;
        // A flipped byte either fails or decodes to the stated length; never panics.
        let _ = decompress(&flipped, "t", "b", raw.len());
    }
}
