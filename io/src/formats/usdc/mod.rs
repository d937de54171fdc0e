//! Binary USD crate files (`.usdc`, and `.usd` files whose first bytes are `PXR-USDC`): a
//! focused reader of what a vertex cache uses, and a writer.
//!
//! The format, as `pxr/usd/usd/crateFile.cpp` defines it: a header, values, six structural
//! sections and a table of contents ([`container`]); LZ4-wrapped, integer-coded sections
//! ([`compression`]); value representations and the values they point to ([`values`]). The
//! reader builds the shared layer model ([`layer`]), from which the text reader's assembly
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
}
