//! The encoder's memory model: peak bytes per block of frames, what
//! [`AnimationCodec::fit_memory`](codec_core::AnimationCodec::fit_memory) sizes blocks with.
//! The decoder's memory and work are checked per packet in `packet::decode` and
//! `operator::Operator::new`, before they are spent.

use codec_core::{Error, Result};

use crate::NAME;

/// Fewest frames per block `fit_memory` chooses.
pub const MIN_MEMORY_BLOCK: usize = 8;

/// Peak bytes an encode of blocks of `frames` frames of `vertices` vertices holds: per
/// coordinate the pending `f32` frames, the `f64` trajectory matrix, the reconstruction and the
/// driver's copies; the `3F × 3F` Gram matrix and its eigenvectors; per vertex the topology,
/// coding order, Laplacian and a factor envelope of up to a few hundred entries; the program.
pub fn block_memory(vertices: usize, frames: usize) -> u64 {
    let coords = vertices as u64 * 3 * frames as u64;
    let r = 3 * frames as u64;
    64 * coords + 3 * 8 * r * r + 4096 * vertices as u64 + (64 << 20)
}

/// The frames per block that keep an encode within `budget` by [`block_memory`]: `None` when
/// the whole sequence fits; else equal blocks. Fails, naming the budget, when
/// [`MIN_MEMORY_BLOCK`] frames do not fit.
pub(crate) fn block_for_budget(vertices: usize, frames: usize, budget: u64) -> Result<Option<usize>> {
    let fits = (1..=frames).rev().find(|&b| block_memory(vertices, b) <= budget);
    match fits {
        Some(b) if b >= frames => Ok(None),
        Some(b) if b >= MIN_MEMORY_BLOCK.min(frames) => Ok(Some(frames.div_ceil(frames.div_ceil(b)))),
        _ => {
            let need = block_memory(vertices, MIN_MEMORY_BLOCK.min(frames));
            Err(Error::parameter(
                NAME,
                "block",
                format!(
                    "a memory budget of {budget} bytes does not hold a block of {} frames of {vertices} vertices \
                     (about {need} bytes); give a larger budget",
                    MIN_MEMORY_BLOCK.min(frames)
                ),
            ))
        }
    }
}
