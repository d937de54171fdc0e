//! `quant-delta`: the baseline codec and the reference implementation of [`TypedCodec`].
//!
//! Per packet of `block` frames: each axis is quantized uniformly at `bits` over the packet's
//! range (what meshopt / gltfpack-style quantized morph targets give today), the first frame
//! of the packet is stored as codes and every later frame as the difference from the
//! previous frame's codes, zigzag-mapped, split into byte planes and compressed with zstd.
//! Every packet is a keyframe, so any block can be decoded alone.
//!
//! Modules: `params` (the parameters, re-exported here), `encoder` and `decoder`.

mod decoder;
mod encoder;
mod params;

use codec_core::{
    Animation, EncoderSetup, ErrorBound, FourCc, FrameDecoder, FrameEncoder, Limits, Quantizer, RateLadder, Result,
    Setting, StreamInfo, TypedCodec,
};

pub use params::QuantDeltaParams;

/// Codec name.
pub(crate) const NAME: &str = "quant-delta";

/// The `quant-delta` codec.
#[derive(Debug, Clone, Copy, Default)]
pub struct QuantDelta;

impl TypedCodec for QuantDelta {
    type Params = QuantDeltaParams;
    const NAME: &'static str = NAME;
    const FOURCC: FourCc = FourCc::new(b"QDLT");
    const STREAM_VERSION: u16 = 1;
    const SUMMARY: &'static str = "baseline: per-block uniform quantization, temporal delta of codes, zstd";

    fn ladder(&self, _base: &QuantDeltaParams) -> RateLadder {
        RateLadder::over(QuantDeltaParams::bits, (4..=20).step_by(2))
    }
    /// Every packet quantizes its own `block` frames (its own box) and deltas within itself.
    fn blocks(&self, p: &QuantDeltaParams, _frame_count: usize) -> Result<usize> {
        Ok(p.block as usize)
    }
    /// The encode holds one packet of `block` frames at a time (several copies: pending
    /// frames, codes, byte planes, zstd's tables, the self-check's frames), so its peak is
    /// [`encode_memory`]. A budget below that shortens the packets to the fewest equal ones
    /// that fit (at least [`MIN_MEMORY_BLOCK`] frames; `encode` says so when the user set
    /// `block`), as pca-aoi's blocks are; below even that it is refused, naming the need.
    fn fit(&self, p: &QuantDeltaParams, vertices: usize, frames: usize, budget: u64) -> Result<Vec<Setting>> {
        let block = (p.block as usize).min(frames.max(1));
        if encode_memory(vertices, block) <= budget {
            return Ok(Vec::new());
        }
        let least = MIN_MEMORY_BLOCK.min(block);
        match (least..block).rev().find(|&b| encode_memory(vertices, b) <= budget) {
            Some(fits) => {
                let equal = frames.div_ceil(frames.div_ceil(fits));
                Ok(vec![QuantDeltaParams::block.to(u32::try_from(equal).unwrap_or(u32::MAX))])
            }
            None => {
                let what = format!("packets of {least} frames of {vertices} vertices");
                codec_core::memory::check_budget(NAME, budget, encode_memory(vertices, least), &what, "")?;
                Ok(Vec::new())
            }
        }
    }
    fn bound(&self, p: &QuantDeltaParams, animation: &Animation) -> Result<ErrorBound> {
        let (lo, hi) = animation.bounding_box();
        bound_of_box(p, lo, hi)
    }
    fn encoder(&self, p: QuantDeltaParams, setup: &EncoderSetup<'_>) -> Result<Box<dyn FrameEncoder>> {
        Ok(Box::new(encoder::QuantDeltaEncoder::new(p, setup)))
    }
    /// The whole decode's work is known from the header: it is refused before any packet.
    fn decoder(&self, info: &StreamInfo, config: &[u8], limits: &Limits) -> Result<Box<dyn FrameDecoder>> {
        Ok(Box::new(decoder::QuantDeltaDecoder::new(info, config, limits)?))
    }
}

/// The shortest packet [`AnimationCodec::fit_memory`](codec_core::AnimationCodec::fit_memory)
/// chooses to fit a budget: 8 frames (every packet restarts its deltas, so shorter ones cost
/// bits; quant-delta's own packets of 8 frames, below which its rate climbs steeply).
pub const MIN_MEMORY_BLOCK: usize = 8;

/// Peak bytes of a quant-delta encode with packets of `block` frames of `vertices` vertices,
/// the whole process ([`codec_core::memory`]). Measured on the synthetic flag (release build,
/// `-p bits=12`, peak RSS): 10 000 vertices, blocks of 8, 32 and 60 frames: 34, 65 and 114
/// MiB; 2 500 vertices: 16, 24 and 36 MiB; 1 000 000 vertices: 1 574, 1 806 and 2 267 MiB at 8,
/// 16 and 32 frames. A coordinate of the packet costs about 10 bytes at 1M vertices but about
/// 54 at 10 000: zstd's tables grow with the packet up to a size fixed by its level, then stop.
/// So: 14 bytes a coordinate, zstd's 42 more up to 256 MiB in all, 1 400 bytes a vertex
/// besides; 8–28 % above every measurement, and above samba's (9 971 vertices × 32 frames: 67
/// MiB).
pub fn encode_memory(vertices: usize, block: usize) -> u64 {
    let k = vertices as u64;
    let coordinates = 3 * k * block as u64;
    let zstd = (42 * coordinates).min(256 << 20);
    codec_core::memory::PROCESS_BYTES + 1400 * k + 14 * coordinates + zstd
}

/// The bound of an animation whose bounding box is `lo..hi`: each packet's range lies inside
/// the whole animation's, so its step is no larger.
pub(crate) fn bound_of_box(p: &QuantDeltaParams, lo: [f32; 3], hi: [f32; 3]) -> Result<ErrorBound> {
    let bound = (0..3)
        .map(|a| Quantizer::new(lo[a], hi[a], p.bits).map(|q| q.max_error()))
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .fold(0.0, f64::max);
    Ok(ErrorBound { max_coordinate_error: Some(bound), relative_rms_error: None })
}

#[cfg(test)]
mod tests;
