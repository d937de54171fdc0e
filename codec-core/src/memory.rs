//! Memory models of the encoders that hold no whole block of
//! frames they could shorten (quant-delta's packets, sac's per-mesh state, stseg's segments),
//! so that `animcodec encode --memory` refuses up front, naming the least budget that would do,
//! instead of overrunning it without a word ([`AnimationCodec::fit_memory`]).
//!
//! Every model is the whole process's peak (program, topology, the stream driver's self-check
//! and the codec's own state), fitted to peak RSS measured with `/usr/bin/time -f %M` on
//! `animcodec encode` of streamed PC2 caches (`synth flag:50x50x60`, `flag:100x100x60`, samba)
//! and rounded up; `docs/notes/issue-41-hosvd.md` has the measurements. Like hosvd's and
//! pca-aoi's, a model depends only on the arguments, never on the machine.
//!
//! [`AnimationCodec::fit_memory`]: crate::AnimationCodec::fit_memory

use crate::error::{Error, Result};

/// Bytes of a mebibyte.
pub const MIB: u64 = 1 << 20;

/// The process before any codec state: program, allocator, reader, container writer and
/// self-check decoder of a tiny input (`animcodec encode` of a 900-vertex cache: 16 MiB,
/// `animcodec list`: 9 MiB).
pub const PROCESS_BYTES: u64 = 14 * MIB;

/// `Ok` when `need` bytes (the codec's model of this encode) fit `budget`, else the refusal:
/// names the codec, the budget, the least budget that would do (whole MiB, rounded up) and
/// `what` the model counted; `advice` (may be empty) says what else would fit.
pub fn check_budget(codec: &'static str, budget: u64, need: u64, what: &str, advice: &str) -> Result<()> {
    if need <= budget {
        return Ok(());
    }
    let need_mib = need.div_ceil(MIB);
    Err(Error::Unsupported {
        context: codec.into(),
        detail: format!(
            "--memory {:.1} MiB is less than this encode needs by the codec's memory model: about {need_mib} MiB \
             ({what}); give --memory {need_mib}M or more{advice}",
            budget as f64 / MIB as f64
        ),
    })
}

/// The frames per temporal block that keep an encode of `frames` frames of `vertices`
/// vertices within `budget` bytes by the codec's model `block_memory(vertices, block)`: `None`
/// when the whole sequence fits in one block; else equal blocks (`⌈F / n⌉` frames for the
/// fewest `n` that fit), so no short remainder block is analysed on its own. Fails, naming the
/// codec's `block` parameter and the budget, when `min_block` frames (or all of them, if fewer)
/// do not fit.
pub fn block_for_budget(
    codec: &'static str,
    block_param: &'static str,
    min_block: usize,
    (vertices, frames): (usize, usize),
    budget: u64,
    block_memory: impl Fn(usize, usize) -> u64,
) -> Result<Option<usize>> {
    let smallest = min_block.min(frames);
    match (1..=frames).rev().find(|&b| block_memory(vertices, b) <= budget) {
        Some(b) if b >= frames => Ok(None),
        Some(b) if b >= smallest => Ok(Some(frames.div_ceil(frames.div_ceil(b)))),
        _ => Err(Error::parameter(
            codec,
            block_param,
            format!(
                "a memory budget of {budget} bytes does not hold a block of {smallest} frames of {vertices} vertices \
                 (about {} bytes); give a larger budget",
                block_memory(vertices, smallest)
            ),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_budget_below_the_need_is_refused_naming_the_need_in_mib() {
        assert!(check_budget("x", 10 * MIB, 10 * MIB, "w", "").is_ok());
        let e = check_budget("x", 16 * MIB, 40 * MIB + 1, "w", "; or y").unwrap_err().to_string();
        assert!(e.contains("--memory 16.0 MiB") && e.contains("about 41 MiB") && e.contains("--memory 41M"), "{e}");
        assert!(e.starts_with("x: ") && e.contains("(w)") && e.ends_with("; or y"), "{e}");
    }
}
