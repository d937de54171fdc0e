//! `stseg`: spatio-temporal segmentation + PCA (Luo, Deng, Zhao, Jin, Zeng, Xie, Seo,
//! "Spatio-temporal Segmentation based Adaptive Compression of Dynamic Mesh Sequences",
//! ACM TOMM 2020).
//!
//! The encoder consumes frames in order (§4.5). For each block it runs the initial temporal
//! cut (§4.1), clusters vertices into at most `groups` groups (§4.2, Alg. 1), finds the next
//! temporal boundary from changes in each group's number of principal components (§4.3,
//! Alg. 2), and codes every group of the segment by PCA at persistence `omega` with `eta`-ring
//! overlap (§4.4), quantized and entropy-coded with zstd. One packet per temporal segment;
//! every packet is a keyframe. See `README.md` for the stream layout.
//! [`segment_animation`] exposes the segmentation (group labels and boundaries).
//!
//! Modules: `params` (the parameters, re-exported here), `encoder` and `decoder`, `segment`
//! (§4.1–4.3: the initial cut, the vertex groups, the PC-count boundaries), `pca` (§4.4: one
//! group's PCA and its reconstruction), `paper` (the paper's coding, stream version 2's) and
//! `coding` (the toolkit coding), `bound` (the declared error bounds), `estimate` (the paper's
//! rate estimate, Eq. 8–9), `memory` (the encoder's memory model) and `linalg`.

mod bound;
mod clustering;
mod coding;
mod decoder;
mod encoder;
mod estimate;
mod linalg;
mod memory;
mod mesh;
mod paper;
mod params;
mod pca;
mod segment;

use codec_core::{
    Animation, EncoderSetup, ErrorBound, FourCc, FrameDecoder, FrameEncoder, Limits, RateLadder, Result, Setting,
    StreamInfo, TypedCodec,
};

pub use encoder::{encode_with_segmentation, fixed_block_segmentation};
pub use estimate::{paper_rate_estimate, segment_components, PaperRate};
pub use memory::encode_memory;
pub use params::{Centering, Coding, Detector, StsegParams};
pub use segment::{segment_animation, BlockKind, Segment, Segmentation};

pub(crate) const NAME: &str = "stseg";
/// Most vertex groups a stream may declare (labels are stored as bytes).
pub const MAX_GROUPS: usize = 16;

/// The `stseg` codec.
#[derive(Debug, Clone, Copy, Default)]
pub struct Stseg;

impl TypedCodec for Stseg {
    type Params = StsegParams;
    const NAME: &'static str = NAME;
    const FOURCC: FourCc = FourCc::new(b"STSG");
    /// 2: config carries the centering; the mean is per frame for `centering = frame`.
    /// 3: config adds the coding (paper = version 2's packets, toolkit = `coding.rs`) and the
    /// toolkit's predictors.
    const STREAM_VERSION: u16 = 3;
    const SUMMARY: &'static str =
        "spatio-temporal segmentation (initial cut, vertex groups, PC-count boundaries) + per-segment PCA";

    fn ladder(&self, _base: &StsegParams) -> RateLadder {
        RateLadder::over(
            StsegParams::omega,
            [0.9, 0.95, 0.98, 0.99, 0.995, 0.998, 0.999, 0.9995, 0.9998, 0.9999, 0.99995, 0.99999, 0.999999],
        )
    }
    fn bound(&self, p: &StsegParams, animation: &Animation) -> Result<ErrorBound> {
        let bound = match p.coding {
            Coding::Paper => bound::relative_rms_bound(p, animation),
            Coding::Toolkit => bound::toolkit_rms_bound(p, animation),
        };
        Ok(ErrorBound { max_coordinate_error: None, relative_rms_error: bound })
    }
    /// stseg's segments are chosen by the data (up to `gamma_max` frames, cut
    /// by the detector), so there is no block to shorten: a budget below [`encode_memory`] is
    /// refused up front, naming the need.
    fn fit(&self, p: &StsegParams, vertices: usize, frames: usize, budget: u64) -> Result<Vec<Setting>> {
        let window = frames.min((p.gamma_max + p.gamma_init) as usize);
        let need = encode_memory(vertices, frames, window);
        let what = format!("{frames} frames of {vertices} vertices, segments of up to {} frames", p.gamma_max);
        codec_core::memory::check_budget(NAME, budget, need, &what, "")?;
        Ok(Vec::new())
    }
    fn encoder(&self, p: StsegParams, setup: &EncoderSetup<'_>) -> Result<Box<dyn FrameEncoder>> {
        encoder::new_encoder(&p, setup)
    }
    fn decoder(&self, info: &StreamInfo, config: &[u8], limits: &Limits) -> Result<Box<dyn FrameDecoder>> {
        decoder::new_decoder(info, config, limits)
    }
}

// The unit tests (`tests.rs`, `use super::*`) drive the internals directly: the decoder on
// hand-made packets, the mean layout, the longest segment.
#[cfg(test)]
use {
    codec_core::{AnimationCodec, Packet},
    decoder::StsegDecoder,
    params::MAX_SEGMENT_FRAMES,
    pca::mean_layout,
};

#[cfg(test)]
mod tests;
