//! The encoder's memory model: peak bytes per block of frames, what
//! [`AnimationCodec::fit_memory`](codec_core::AnimationCodec::fit_memory) sizes blocks with.
//! The decoder's memory and work are checked per packet in `packet::parse` and
//! `operator::Operator::new`, before they are spent.

use codec_core::Result;

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
    codec_core::memory::block_for_budget(
        NAME,
        crate::params::LaplacianParams::block.name(),
        MIN_MEMORY_BLOCK,
        (vertices, frames),
        budget,
        block_memory,
    )
}
