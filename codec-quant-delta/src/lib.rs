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
    /// [`encode_memory`]. A budget below that is refused, naming the need and the largest
    /// `block` that would fit; the parameters are never changed behind the user's back.
    fn fit(&self, p: &QuantDeltaParams, vertices: usize, frames: usize, budget: u64) -> Result<Vec<Setting>> {
        let block = (p.block as usize).min(frames.max(1));
        let need = encode_memory(vertices, block);
        let fits = (1..block).rev().find(|&b| encode_memory(vertices, b) <= budget);
        let advice = fits.map_or_else(String::new, |b| format!(", or a shorter packet: -p block={b} fits"));
        let what = format!("packets of {block} frames of {vertices} vertices");
        codec_core::memory::check_budget(NAME, budget, need, &what, &advice)?;
        Ok(Vec::new())
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

/// Peak bytes of a quant-delta encode with packets of `block` frames of `vertices` vertices,
/// the whole process ([`codec_core::memory`]): measured 17–109 MiB (2 500 and 10 000 vertices,
/// blocks of 8, 32 and 60 frames; samba, 9 971 vertices × 32 frames: 67 MiB), about 50 bytes a
/// coordinate of the packet and 1.2 KiB a vertex besides; this model is 13–27 % above each.
pub fn encode_memory(vertices: usize, block: usize) -> u64 {
    let k = vertices as u64;
    codec_core::memory::PROCESS_BYTES + 1400 * k + 56 * 3 * k * block as u64
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
