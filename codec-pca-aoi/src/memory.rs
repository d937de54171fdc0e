//! Memory model of `pca-aoi`'s encoder: peak bytes per block, what
//! [`AnimationCodec::fit_memory`](codec_core::AnimationCodec::fit_memory) sizes blocks with.

use codec_core::{Error, Result};

use crate::NAME;

/// Fewest frames per block `fit_memory` chooses.
pub const MIN_MEMORY_BLOCK: usize = 8;

/// Peak bytes of an encode with blocks of `frames` frames of `vertices` vertices, the whole
/// process (stream driver and self-check included): fitted on peak RSS of streamed PC2 encodes
/// (107 MiB at 10 000 vertices × 120-frame blocks, 356 MiB at 40 000 × 120; ≈ 23 bytes a
/// coordinate of the block) and at 1 000 000 vertices, where a coordinate of the block costs
/// ≈ 35 bytes and a vertex ≈ 980 besides (blocks of 27, 33 and 40 frames: 3.55, 4.13 and
/// 4.82 GiB; 32 bytes a coordinate let a 4 GiB budget choose 33 frames), rounded up for
/// headroom.
pub fn block_memory(vertices: usize, frames: usize) -> u64 {
    36 * vertices as u64 * 3 * frames as u64 + 1152 * vertices as u64 + (64 << 20)
}

/// The frames per block that keep an encode with blocks of `block` frames (of `frames` frames
/// of `vertices` vertices) within `budget` bytes by [`block_memory`]: `None` when `block`
/// already fits; else the fewest equal blocks that fit. Fails, naming the budget, when
/// [`MIN_MEMORY_BLOCK`] frames do not fit.
pub(crate) fn block_for_budget(block: usize, vertices: usize, frames: usize, budget: u64) -> Result<Option<usize>> {
    let block = block.min(frames.max(1));
    if block_memory(vertices, block) <= budget {
        return Ok(None);
    }
    let least = MIN_MEMORY_BLOCK.min(block);
    let Some(fits) = (least..block).rev().find(|&b| block_memory(vertices, b) <= budget) else {
        return Err(Error::parameter(
            NAME,
            crate::params::PcaAoiParams::block.name(),
            format!(
                "a memory budget of {budget} bytes does not hold a block of {least} frames of {vertices} vertices \
                 (about {} bytes); give a larger budget",
                block_memory(vertices, least)
            ),
        ));
    };
    Ok(Some(frames.div_ceil(frames.div_ceil(fits))))
}
