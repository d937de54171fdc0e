//! Memory and work models of `hosvd`: the encoder's peak bytes per block (what
//! [`AnimationCodec::fit_memory`](codec_core::AnimationCodec::fit_memory) sizes blocks with) and
//! the decoder's work per packet (checked against `Limits::max_work` before decoding).

use codec_core::{Limits, Result};

use crate::NAME;

/// Fewest frames per block `fit_memory` chooses: below it the frame mode has
/// too little to reduce (see `encoder::block_params`) and the per-block side data dominates.
pub const MIN_MEMORY_BLOCK: usize = 8;

/// Peak bytes an encode of blocks of `frames` frames of `vertices` vertices holds, the whole
/// process (the stream driver's copy of the block and its self-check included): a model fitted
/// to measured peak RSS (below), rounded up.
pub fn block_memory(vertices: usize, frames: usize) -> u64 {
    let coordinates = vertices as u64 * 3 * frames as u64;
    let k = vertices as u64;
    // Per coordinate of the block: f32 copies (pending, self-check) and f64 working tensors.
    // Per vertex: topology, coding order, mesh graph. Plus the program itself.
    BYTES_PER_COORDINATE * coordinates + BYTES_PER_VERTEX * k + BASE_BYTES
}

// Fitted on `synth flag:200x200x300` (40 000 vertices) encoded with block = 25, 50, 100, 150
// and 300 frames: 290, 441, 799, 1110 and 2049 MiB peak RSS, 56 bytes a coordinate of the block
// and about 130 MiB besides; 10 000 vertices × 300 frames: 552 MiB. Rounded up for headroom.
const BYTES_PER_COORDINATE: u64 = 64;
const BYTES_PER_VERTEX: u64 = 2048;
const BASE_BYTES: u64 = 64 << 20;

/// The frames per block that keep an encode of `frames` frames of `vertices` vertices within
/// `budget` bytes by [`block_memory`]: `None` when the whole sequence fits in one block; else
/// equal blocks (`⌈F / n⌉` frames for the fewest `n` that fit), so no short remainder block is
/// decomposed on its own. Fails, naming the budget, when [`MIN_MEMORY_BLOCK`] frames do not fit.
pub(crate) fn block_for_budget(vertices: usize, frames: usize, budget: u64) -> Result<Option<usize>> {
    codec_core::memory::block_for_budget(
        NAME,
        crate::params::HosvdParams::block.name(),
        MIN_MEMORY_BLOCK,
        (vertices, frames),
        budget,
        block_memory,
    )
}

/// Work of decoding one packet of `frames` frames of `k` vertices with ranks `v` and `f`
/// (`Limits::max_work`, counted before the work starts): the coded values of `U1`, `U3` and
/// the core (arithmetic-coded with `toolkit`, else inflated byte planes), the frame loadings
/// ([`crate::tensor::reconstruct`]: `F·3·v·f + 9·v·f`), the last step's `F·K·3·v` multiply-adds
/// (all but a sliver of the arithmetic) and the output coordinates.
pub fn decode_work(k: usize, frames: usize, v: usize, f: usize, toolkit: bool) -> u64 {
    use codec_core::limits::{WORK_PER_CODED_VALUE, WORK_PER_COORDINATE, WORK_PER_PLANE_BYTE};
    let (k, frames, v, f) = (k as u64, frames as u64, v as u64, f as u64);
    let values = Limits::product(&[k, v])
        .saturating_add(Limits::product(&[frames, f]))
        .saturating_add(Limits::product(&[3, v, f]));
    // Byte planes: at most 4 per value (`read_codes`).
    let per_value = if toolkit { WORK_PER_CODED_VALUE } else { 4 * WORK_PER_PLANE_BYTE };
    let coords = Limits::product(&[frames, k, 3]);
    values
        .saturating_mul(per_value)
        .saturating_add(Limits::product(&[frames, 3, v, f]))
        .saturating_add(Limits::product(&[9, v, f]))
        .saturating_add(coords.saturating_mul(v))
        .saturating_add(coords.saturating_mul(WORK_PER_COORDINATE))
}
