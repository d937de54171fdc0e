//! Byte planes and zigzag runs: the plain coding of integer codes that the codecs' simple
//! streams share (uniform codes or their differences, zigzag-mapped, split into byte planes so
//! that zstd sees the slowly varying high bytes together).
//!
//! Layout: `values.len() × planes` bytes, plane-major: plane `p` holds byte `p` (little end
//! first) of every value in order.

use crate::bytes::{zigzag_decode, zigzag_encode};

/// Byte planes of the zigzag differences of `bits`-bit codes (a difference needs `bits + 1`).
pub fn delta_plane_count(bits: u8) -> usize {
    (bits as usize + 1).div_ceil(8)
}

/// Byte planes needed to hold the largest of `values` (at least one).
pub fn planes_needed(values: &[u32]) -> usize {
    let max = values.iter().copied().max().unwrap_or(0);
    ((32 - max.leading_zeros()) as usize).div_ceil(8).max(1)
}

/// Appends the `planes` low byte planes of `values` to `out`.
pub fn push_byte_planes(values: &[u32], planes: usize, out: &mut Vec<u8>) {
    out.reserve(values.len() * planes);
    for p in 0..planes {
        out.extend(values.iter().map(|v| (v >> (8 * p)) as u8));
    }
}

/// The `planes` low byte planes of `values`.
pub fn to_byte_planes(values: &[u32], planes: usize) -> Vec<u8> {
    let mut out = Vec::new();
    push_byte_planes(values, planes, &mut out);
    out
}

/// Value `i` of byte planes `raw` holding `count` values in `planes` planes. The caller has
/// checked `raw.len() >= count × planes` and `i < count`.
pub fn plane_value(raw: &[u8], count: usize, planes: usize, i: usize) -> u32 {
    (0..planes).fold(0u32, |acc, p| acc | (raw[p * count + i] as u32) << (8 * p))
}

/// The `count` values of byte planes `raw` (`planes` planes; the caller has checked
/// `raw.len() >= count × planes`).
pub fn from_byte_planes(raw: &[u8], count: usize, planes: usize) -> Vec<u32> {
    (0..count).map(|i| plane_value(raw, count, planes, i)).collect()
}

/// Appends `codes` as zigzag differences from the code `stride` places earlier (the first
/// `stride` codes from 0).
pub fn push_zigzag_deltas(codes: &[u32], stride: usize, out: &mut Vec<u32>) {
    for (i, &c) in codes.iter().enumerate() {
        let d = if i >= stride { c as i64 - codes[i - stride] as i64 } else { c as i64 };
        out.push(zigzag_encode(d) as u32);
    }
}

/// Appends a run of codes as zigzag differences from the previous code of the run (the first
/// from `start`).
pub fn push_zigzag_run(codes: impl IntoIterator<Item = u32>, start: i64, out: &mut Vec<u32>) {
    let mut prev = start;
    for c in codes {
        out.push(zigzag_encode(c as i64 - prev) as u32);
        prev = c as i64;
    }
}

/// The inverse of [`push_zigzag_run`] on `len` zigzag differences read by `next`: the running
/// sums from `start`, without clamping (the caller checks the range it needs).
pub fn zigzag_run_sums(len: usize, start: i64, mut next: impl FnMut() -> u32) -> impl Iterator<Item = i64> {
    let mut prev = start;
    (0..len).map(move |_| {
        prev += zigzag_decode(u64::from(next()));
        prev
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn planes_round_trip_and_are_plane_major() {
        let values = [0u32, 1, 0x1_02, 0x3_04_05, u32::MAX];
        let raw = to_byte_planes(&values, 4);
        assert_eq!(&raw[..5], &[0, 1, 2, 5, 255]);
        assert_eq!(&raw[5..10], &[0, 0, 1, 4, 255]);
        assert_eq!(from_byte_planes(&raw, 5, 4), values);
        assert_eq!(planes_needed(&values), 4);
        assert_eq!(planes_needed(&[0, 255]), 1);
        assert_eq!(planes_needed(&[]), 1);
        assert_eq!(delta_plane_count(8), 2);
        assert_eq!(delta_plane_count(7), 1);
    }

    #[test]
    fn zigzag_runs_round_trip() {
        let codes = [5u32, 3, 3, 9, 0];
        let mut out = Vec::new();
        push_zigzag_run(codes, 0, &mut out);
        let mut it = out.iter().copied();
        let back: Vec<i64> = zigzag_run_sums(codes.len(), 0, || it.next().unwrap()).collect();
        assert_eq!(back, codes.map(i64::from));
        let mut strided = Vec::new();
        push_zigzag_deltas(&codes, 2, &mut strided);
        assert_eq!(strided, [10, 6, 3, 12, 5]);
    }
}
