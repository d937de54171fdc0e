//! The two compressions of USD crate files: the LZ4 wrapper (`TfFastCompression`, in
//! `pxr/base/tf/fastCompression.cpp`) and the integer coding of the structural sections and of
//! integer arrays (`Usd_IntegerCompression`, `pxr/usd/usd/integerCoding.cpp`).
//!
//! **LZ4 wrapper.** Byte 0 is a chunk count. 0: one raw LZ4 block follows (the whole rest of
//! the buffer). k > 0: k chunks, each an `i32` compressed length and an LZ4 block that decodes
//! to at most [`LZ4_MAX_CHUNK`] bytes. Every decoded size here is known from a count in the file
//! and checked by the caller against the read's budget, so decoding never allocates beyond it.
//!
//! **Integer coding.** Integers are replaced by their differences from the previous one (the
//! first from 0). The most common difference is written first (as the integer type), then 2-bit
//! codes, four to a byte, the first integer in the low bits: `00` the common value, `01` a small
//! integer, `10` a medium one, `11` a full-width one; then the small/medium/full values, packed
//! little-endian. 32-bit integers use i8/i16/i32, 64-bit ones i16/i32/i64. The encoded bytes go
//! through the LZ4 wrapper, and in a file the result is preceded by its `u64` size.
//!
//! Nothing here panics on any input: every read is bounds-checked and sums wrap as upstream's
//! do (two's-complement).

/// Largest decoded size of one LZ4 chunk (`LZ4_MAX_INPUT_SIZE`).
pub const LZ4_MAX_CHUNK: usize = 0x7E00_0000;

/// Decodes one LZ4 block (the LZ4 block format: sequences of a token, literals, a 2-byte
/// offset and a match) onto the end of `out`, producing at most `max_out` bytes. Matches may
/// only refer to bytes this block produced.
fn lz4_block(src: &[u8], out: &mut Vec<u8>, max_out: usize) -> Result<(), String> {
    let start = out.len();
    let limit = start.checked_add(max_out).ok_or("LZ4 output size overflows")?;
    let mut i = 0usize;
    let byte = |i: &mut usize| -> Result<u8, String> {
        let b = *src.get(*i).ok_or("LZ4 block ends in the middle of a sequence")?;
        *i += 1;
        Ok(b)
    };
    loop {
        let token = byte(&mut i)?;
        let mut literals = (token >> 4) as usize;
        if literals == 15 {
            loop {
                let b = byte(&mut i)?;
                literals = literals.checked_add(b as usize).ok_or("LZ4 literal length overflows")?;
                if b != 255 {
                    break;
                }
            }
        }
        let end = i.checked_add(literals).filter(|&e| e <= src.len()).ok_or("LZ4 literals run past the block")?;
        if out.len() + literals > limit {
            return Err(format!("LZ4 block decodes to more than the {max_out} bytes expected"));
        }
        out.extend_from_slice(&src[i..end]);
        i = end;
        if i == src.len() {
            return Ok(()); // the last sequence has literals only
        }
        let lo = byte(&mut i)?;
        let hi = byte(&mut i)?;
        let offset = u16::from_le_bytes([lo, hi]) as usize;
        if offset == 0 || offset > out.len() - start {
            return Err(format!("LZ4 match offset {offset} points before the block's output"));
        }
        let mut length = (token & 15) as usize;
        if length == 15 {
            loop {
                let b = byte(&mut i)?;
                length = length.checked_add(b as usize).ok_or("LZ4 match length overflows")?;
                if b != 255 {
                    break;
                }
            }
        }
        length += 4;
        if out.len().checked_add(length).is_none_or(|e| e > limit) {
            return Err(format!("LZ4 block decodes to more than the {max_out} bytes expected"));
        }
        let from = out.len() - offset;
        if offset >= length {
            out.extend_from_within(from..from + length);
        } else {
            // An overlapping match repeats the last `offset` bytes.
            for k in 0..length {
                let b = out[from + k];
                out.push(b);
            }
        }
    }
}

/// Decodes a `TfFastCompression` buffer into at most `max_out` bytes (see the module
/// documentation). The caller has counted `max_out` against its budget; the buffer grows with
/// what is decoded (LZ4 expands a byte to at most 255), so a lying size costs no memory.
pub fn decompress(src: &[u8], max_out: usize) -> Result<Vec<u8>, String> {
    let (&chunks, mut rest) = src.split_first().ok_or("empty compressed buffer")?;
    let mut out = Vec::with_capacity(max_out.min(src.len().saturating_mul(255).saturating_add(16)));
    if chunks == 0 {
        lz4_block(rest, &mut out, max_out)?;
        return Ok(out);
    }
    for chunk in 0..chunks {
        if rest.len() < 4 {
            return Err(format!("compressed chunk {chunk} of {chunks} has no size"));
        }
        let size = i32::from_le_bytes([rest[0], rest[1], rest[2], rest[3]]);
        let size = usize::try_from(size)
            .ok()
            .filter(|&s| s <= rest.len() - 4)
            .ok_or_else(|| format!("compressed chunk {chunk} claims {size} bytes, past the end of its buffer"))?;
        let room = (max_out - out.len()).min(LZ4_MAX_CHUNK);
        lz4_block(&rest[4..4 + size], &mut out, room)?;
        rest = &rest[4 + size..];
    }
    Ok(out)
}

/// `data` as a `TfFastCompression` buffer of literal-only LZ4 blocks: valid LZ4 that every
/// decoder reads, a few bytes larger than the input. Inputs above [`LZ4_MAX_CHUNK`] are split
/// into chunks as upstream does.
pub fn compress(data: &[u8]) -> Vec<u8> {
    fn block(data: &[u8], out: &mut Vec<u8>) {
        let n = data.len();
        if n < 15 {
            out.push((n as u8) << 4);
        } else {
            out.push(0xF0);
            let mut rest = n - 15;
            while rest >= 255 {
                out.push(255);
                rest -= 255;
            }
            out.push(rest as u8);
        }
        out.extend_from_slice(data);
    }
    let mut out = Vec::with_capacity(data.len() + data.len() / 255 + 16);
    if data.len() <= LZ4_MAX_CHUNK {
        out.push(0);
        block(data, &mut out);
        return out;
    }
    let chunks = data.chunks(LZ4_MAX_CHUNK);
    out.push(chunks.len() as u8);
    for chunk in chunks {
        let at = out.len();
        out.extend_from_slice(&[0; 4]);
        block(chunk, &mut out);
        let size = (out.len() - at - 4) as i32;
        out[at..at + 4].copy_from_slice(&size.to_le_bytes());
    }
    out
}

/// Bytes the integer coding of `n` integers of `width` bytes may take at most (before LZ4):
/// the common value, the codes and full-width values. `None` on overflow.
pub fn encoded_bound(n: u64, width: u64) -> Option<u64> {
    if n == 0 {
        return Some(0);
    }
    width.checked_add(n.checked_mul(2)?.checked_add(7)? / 8)?.checked_add(n.checked_mul(width)?)
}

/// Decodes `n` integers coded with `width`-byte integers (4 or 8) from `encoded` (the bytes
/// after LZ4), as i64 (32-bit values sign-extended; the caller reinterprets unsigned ones).
pub fn decode_ints(encoded: &[u8], n: usize, width: usize) -> Result<Vec<i64>, String> {
    if n == 0 {
        return Ok(Vec::new());
    }
    let codes_len = n.checked_mul(2).and_then(|b| b.checked_add(7)).ok_or("integer count overflows")? / 8;
    let header = width.checked_add(codes_len).ok_or("integer count overflows")?;
    if encoded.len() < header {
        return Err(format!("{} bytes of coded integers hold no codes for {n} integers", encoded.len()));
    }
    let read = |bytes: &[u8], at: &mut usize, size: usize| -> Result<i64, String> {
        let b = bytes.get(*at..*at + size).ok_or("coded integers end early")?;
        *at += size;
        Ok(match size {
            1 => b[0] as i8 as i64,
            2 => i16::from_le_bytes([b[0], b[1]]) as i64,
            4 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as i64,
            _ => i64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]),
        })
    };
    let mut at = 0;
    let common = read(encoded, &mut at, width)?;
    let codes = &encoded[width..header];
    let mut at = header;
    let sizes: [usize; 3] = if width == 4 { [1, 2, 4] } else { [2, 4, 8] };
    let mut out = Vec::with_capacity(n);
    let mut prev: i64 = 0;
    for k in 0..n {
        let code = (codes[k / 4] >> (2 * (k % 4))) & 3;
        let delta = if code == 0 { common } else { read(encoded, &mut at, sizes[code as usize - 1])? };
        prev = if width == 4 { (prev as i32).wrapping_add(delta as i32) as i64 } else { prev.wrapping_add(delta) };
        out.push(prev);
    }
    Ok(out)
}

/// The integer coding of `values` with `width`-byte integers (4 or 8; 32-bit values are given
/// sign-extended or as their unsigned value, both wrap the same), before LZ4.
pub fn encode_ints(values: &[i64], width: usize) -> Vec<u8> {
    if values.is_empty() {
        return Vec::new();
    }
    let wrap = |x: i64| if width == 4 { x as i32 as i64 } else { x };
    let mut prev = 0i64;
    let deltas: Vec<i64> = values
        .iter()
        .map(|&v| {
            let d = if width == 4 { (v as i32).wrapping_sub(prev as i32) as i64 } else { v.wrapping_sub(prev) };
            prev = wrap(v);
            d
        })
        .collect();
    // The most common difference; ties go to the larger value (as upstream chooses).
    let mut sorted = deltas.clone();
    sorted.sort_unstable();
    let (mut common, mut best, mut run) = (sorted[0], 0usize, 0usize);
    for k in 0..sorted.len() {
        run = if k > 0 && sorted[k] == sorted[k - 1] { run + 1 } else { 1 };
        if run >= best {
            best = run;
            common = sorted[k];
        }
    }
    let codes_len = (values.len() * 2).div_ceil(8);
    let mut out = Vec::with_capacity(width + codes_len + values.len() * width);
    out.extend_from_slice(&common.to_le_bytes()[..width]);
    let codes_at = out.len();
    out.resize(codes_at + codes_len, 0);
    let (small, medium) = if width == 4 { (8, 16) } else { (16, 32) };
    for (k, &d) in deltas.iter().enumerate() {
        let fits = |bits: u32| d >= -(1i64 << (bits - 1)) && d < (1i64 << (bits - 1));
        let (code, size) = if d == common {
            (0u8, 0)
        } else if fits(small) {
            (1, small as usize / 8)
        } else if fits(medium) {
            (2, medium as usize / 8)
        } else {
            (3, width)
        };
        out[codes_at + k / 4] |= code << (2 * (k % 4));
        out.extend_from_slice(&d.to_le_bytes()[..size]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The worked example of `integerCoding.cpp`: differences [123, 1, 1, 100000, 0, 1, 0], the
    /// common value 1, codes 01 00 00 11 | 01 00 01, then i8 123, i32 100000, i8 0, i8 0.
    #[test]
    fn integer_coding_matches_the_hand_checked_example() {
        let values = [123i64, 124, 125, 100125, 100125, 100126, 100126];
        let encoded = encode_ints(&values, 4);
        let mut want = vec![1, 0, 0, 0];
        want.push(0b11_00_00_01);
        want.push(0b00_01_00_01);
        want.push(123);
        want.extend_from_slice(&100000i32.to_le_bytes());
        want.extend_from_slice(&[0, 0]);
        assert_eq!(encoded, want);
        assert_eq!(decode_ints(&encoded, values.len(), 4).unwrap(), values);
    }

    #[test]
    fn integer_coding_round_trips_both_widths_and_wraps() {
        let cases: Vec<Vec<i64>> = vec![
            vec![],
            vec![0],
            vec![-2, -1, 0, 5, 5, 5, -1],
            vec![i32::MIN as i64, i32::MAX as i64, 0, i32::MIN as i64, 70000, -70000],
            (0..1000).map(|i| (i * i) % 977 - 400).collect(),
        ];
        for values in &cases {
            for width in [4, 8] {
                let e = encode_ints(values, width);
                assert!(e.len() as u64 <= encoded_bound(values.len() as u64, width as u64).unwrap());
                assert_eq!(&decode_ints(&e, values.len(), width).unwrap(), values, "width {width}");
            }
        }
        let big = [i64::MIN, i64::MAX, 1 << 40, -(1 << 33), 3];
        assert_eq!(decode_ints(&encode_ints(&big, 8), 5, 8).unwrap(), big);
        // u32 values above i32::MAX come back sign-extended; the caller reinterprets them.
        let e = encode_ints(&[0xFFFF_FFFF, 7], 4);
        assert_eq!(decode_ints(&e, 2, 4).unwrap(), vec![-1, 7]);
        // 64-bit codes: 01 = i16, so 300 takes two bytes.
        let e = encode_ints(&[300, 300, 300], 8);
        assert_eq!(e.len(), 8 + 1 + 2);
    }

    #[test]
    fn truncated_coded_integers_are_errors() {
        let e = encode_ints(&[1, 1000, -100000, 5], 4);
        for cut in 0..e.len() {
            assert!(decode_ints(&e[..cut], 4, 4).is_err(), "cut {cut}");
        }
        assert!(decode_ints(&e, usize::MAX, 4).is_err());
    }

    #[test]
    fn lz4_wrapper_round_trips_and_reads_real_matches() {
        for data in [&b""[..], b"a", b"hello, hello, hello, hello!", &[7u8; 1000][..]] {
            let c = compress(data);
            assert_eq!(decompress(&c, data.len()).unwrap(), data);
        }
        // A hand-made block with an overlapping match: literal "ab", then offset 2, length 6
        // ("ababab"), then a final literal "c".
        let block = [0x22, b'a', b'b', 2, 0, 0x10, b'c'];
        let wrapped: Vec<u8> = [0u8].iter().chain(block.iter()).copied().collect();
        assert_eq!(decompress(&wrapped, 9).unwrap(), b"abababab".iter().chain(b"c").copied().collect::<Vec<u8>>());
        // The same block as one chunk of a chunked buffer.
        let mut chunked = vec![1u8];
        chunked.extend_from_slice(&(block.len() as i32).to_le_bytes());
        chunked.extend_from_slice(&block);
        assert_eq!(decompress(&chunked, 9).unwrap().len(), 9);
    }

    #[test]
    fn lz4_lies_are_errors() {
        // More output than expected.
        assert!(decompress(&compress(&[1u8; 100]), 99).unwrap_err().contains("more than"));
        // A match before the start, a zero offset, a literal run past the end.
        assert!(decompress(&[0, 0x10, b'a', 5, 0, 0x10, b'b'], 100).unwrap_err().contains("offset"));
        assert!(decompress(&[0, 0x10, b'a', 0, 0, 0x10, b'b'], 100).unwrap_err().contains("offset"));
        assert!(decompress(&[0, 0x50, b'a'], 100).unwrap_err().contains("past"));
        // A chunk size past the buffer, a negative one, a missing one.
        assert!(decompress(&[1, 100, 0, 0, 0, 0], 100).unwrap_err().contains("past"));
        assert!(decompress(&[1, 255, 255, 255, 255], 100).unwrap_err().contains("past"));
        assert!(decompress(&[2, 1, 0, 0, 0, 0], 100).unwrap_err().contains("no size"));
        assert!(decompress(&[], 100).is_err());
        // A long run of length-extension bytes ends with the input, not with an allocation.
        let mut long = vec![0u8, 0x1F, b'x', 1, 0];
        long.extend(std::iter::repeat_n(255u8, 10_000));
        assert!(decompress(&long, 1 << 20).is_err());
    }
}
