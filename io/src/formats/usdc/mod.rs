//! Binary USD crate files (`.usdc`, and `.usd` files whose first bytes are `PXR-USDC`): a
//! focused reader of what a vertex cache uses, and a writer.
//!
//! The format, as `pxr/usd/usd/crateFile.cpp` defines it: a header, values, six structural
//! sections and a table of contents (`container`); LZ4-wrapped, integer-coded sections
//! (`compression`); value representations and the values they point to (`values`). The
//! reader builds the shared layer model (`layer`), from which the text reader's assembly
//! makes the animation; values are decoded only for the fields it uses, and types it does not
//! need are skipped.
//!
//! The input is untrusted: every count, size and offset is checked (checked arithmetic) against
//! the file and against the read's memory budget (`--max-memory`) before anything is
//! allocated; decompression never produces more than the size the file states; the path tree
//! is built iteratively, each item visited once; prims nest at most [`super::usd::MAX_DEPTH`]
//! deep.

mod compression;
mod container;
mod layer;
mod values;
mod write;

use codec_core::Result;

use super::gltf_buffers::Budget;
use super::usd_layer::Layer;

pub use write::encode_usdc;

/// The layer model of the crate file `bytes` (`file` names it in errors).
pub(super) fn read_layer(bytes: &[u8], file: &str, budget: &mut Budget) -> Result<Layer> {
    let krate = container::read_crate(bytes, file, budget)?;
    layer::layer(&krate, budget)
}

#[cfg(test)]
mod tests {
    use super::super::usd::parse_usd;
    use super::*;
    use crate::formats::{assert_same_geometry, test_animation};

    #[test]
    fn written_crate_files_read_back_bit_exact() {
        for (v, f, fps) in [(7, 5, 25.0), (3, 1, 30.0), (40, 3, 29.97)] {
            let anim = test_animation(v, f, fps);
            let bytes = encode_usdc(&anim).unwrap();
            assert_eq!(&bytes[..8], b"PXR-USDC");
            let back = parse_usd(&bytes, "rt.usdc", None, None).unwrap();
            assert_same_geometry(&anim, &back);
            assert_eq!(back.frame_rate(), fps);
            // Same input, same bytes.
            assert_eq!(encode_usdc(&anim).unwrap(), bytes);
            // In a package too.
            let z = super::super::usdz::tests::zip("rt.usdc", &bytes);
            assert_same_geometry(&anim, &parse_usd(&z, "rt.usdz", None, None).unwrap());
        }
        if let Ok(dir) = std::env::var("ANIMCODEC_USDC_SAMPLE") {
            std::fs::write(dir, encode_usdc(&test_animation(20, 4, 24.0)).unwrap()).unwrap();
        }
    }

    /// Every truncation and every single-bit flip of a small crate file is an error or a read,
    /// never a panic, and never a large allocation.
    #[test]
    fn damaged_crate_files_fail_cleanly() {
        let bytes = encode_usdc(&test_animation(5, 3, 24.0)).unwrap();
        for cut in 0..bytes.len() {
            assert!(parse_usd(&bytes[..cut], "cut.usdc", None, Some(1 << 20)).is_err(), "cut at {cut}");
        }
        for at in 0..bytes.len() {
            for bit in 0..8 {
                let mut b = bytes.clone();
                b[at] ^= 1 << bit;
                let _ = parse_usd(&b, "flip.usdc", None, Some(1 << 20));
            }
        }
    }

    /// (start, size) of a section, from the table of contents.
    fn section(bytes: &[u8], name: &str) -> (usize, usize) {
        let toc = u64::from_le_bytes(bytes[16..24].try_into().unwrap()) as usize;
        let n = u64::from_le_bytes(bytes[toc..toc + 8].try_into().unwrap()) as usize;
        (0..n)
            .map(|i| toc + 8 + 32 * i)
            .find(|&e| bytes[e..e + 16].split(|&b| b == 0).next() == Some(name.as_bytes()))
            .map(|e| {
                let word = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
                (word(e + 16), word(e + 24))
            })
            .unwrap()
    }

    /// The offsets of the first `points` sample (its array) and of the `points` time samples.
    fn points_offsets(bytes: &[u8]) -> (usize, usize) {
        let mut budget = Budget::new("t", None);
        let k = container::read_crate(bytes, "t", &mut budget).unwrap();
        for spec in &k.specs {
            if !k.path_text(spec.path).unwrap().ends_with(".points") {
                continue;
            }
            for (t, rep) in k.field_set(spec.field_set) {
                if k.token(t, "t").unwrap() == "timeSamples" {
                    let samples =
                        values::Values { krate: &k }.time_samples(values::Rep(rep), "t", &mut budget).unwrap();
                    return (samples[0].1.payload() as usize, values::Rep(rep).payload() as usize);
                }
            }
        }
        unreachable!("no points samples")
    }

    fn put(bytes: &[u8], at: usize, value: u64) -> Vec<u8> {
        let mut b = bytes.to_vec();
        b[at..at + 8].copy_from_slice(&value.to_le_bytes());
        b
    }

    /// Lies about sizes, counts and offsets: a clear error naming what is wrong, fast, within
    /// a small budget (nothing is allocated from a lying size).
    #[test]
    fn hostile_sizes_and_offsets_are_refused() {
        let bytes = encode_usdc(&test_animation(5, 3, 24.0)).unwrap();
        let (points, samples) = points_offsets(&bytes);
        let (tokens, _) = section(&bytes, "TOKENS");
        let (fields, _) = section(&bytes, "FIELDS");
        let toc = u64::from_le_bytes(bytes[16..24].try_into().unwrap()) as usize;
        let cases: Vec<(Vec<u8>, &str)> = vec![
            // A 2^31-element points array; a 2^31-sample time series.
            (put(&bytes, points, 1 << 31), "past the end of the file"),
            (put(&bytes, samples + 24, 1 << 31), "past the end of the file"),
            // The table of contents and a section past the end of the file.
            (put(&bytes, 16, bytes.len() as u64 + 100), "table of contents"),
            (put(&bytes, toc + 8 + 16, bytes.len() as u64 - 4), "runs past the end"),
            (put(&bytes, toc + 8 + 24, 1 << 62), "runs past the end"),
            (put(&bytes, toc, 1 << 40), "sections"),
            // Compressed and decoded sizes that lie.
            (put(&bytes, tokens + 16, 1 << 40), "TOKENS"),
            (put(&bytes, tokens + 8, 1 << 36), "total memory"),
            (put(&bytes, tokens, 1 << 36), "TOKENS"),
            (put(&bytes, fields, 1 << 40), "total memory"),
            // A jump out of the file.
            (put(&bytes, samples, 1 << 40), "leaves the file"),
        ];
        for (i, (file, needle)) in cases.iter().enumerate() {
            let t = std::time::Instant::now();
            let e = parse_usd(file, "hostile.usdc", None, Some(64 << 20)).unwrap_err().to_string();
            assert!(e.contains(needle) && e.contains("hostile.usdc"), "case {i}: {e}");
            assert!(t.elapsed().as_secs_f64() < 1.0, "case {i} took {:?}", t.elapsed());
        }
        // Crate versions outside 0.4–0.11 are refused by name.
        let mut old = bytes.clone();
        old[9] = 3;
        assert!(parse_usd(&old, "v.usdc", None, None).unwrap_err().to_string().contains("0.3.0"));
    }
}
