//! `pca-aoi`: streaming block PCA whose dictionaries are tracked from block to block by
//! adaptive orthogonal iterations (Lalos et al. 2017, "Adaptive compression of animated
//! meshes by exploiting orthogonal iterations").
//!
//! Frames are cut into blocks of `block` frames as they arrive. Each block (and each spatial
//! cluster of it) is centered by its per-frame centroid, its dictionary `E_i` is estimated
//! ([`dictionary`]: direct SVD, BAOI or QAOI with a drift guard), the dictionary and the
//! feature vectors `F_i = E_iᵀ X_i` are quantized uniformly (§4.1) and compressed with zstd.
//! Every packet carries its own dictionary, so every packet is a keyframe. See the crate
//! README for the stream layout and every choice the paper leaves open.
//!
//! Modules: `params` (the parameters, re-exported here), `encoder` and `decoder`, `payload`
//! (what both codings of a cluster share), `paper` (§4.1's coding, stream version 1's) and
//! `coding` (the toolkit coding), `bound` (the declared error bound), `memory` (the encoder's
//! memory model), [`dictionary`] (SVD, BAOI and QAOI, §3) and [`cluster`] (the spatial
//! clusters).

mod bound;
pub mod cluster;
mod coding;
mod decoder;
pub mod dictionary;
mod encoder;
mod linalg;
mod memory;
mod paper;
mod params;
mod payload;

use codec_core::{
    Animation, EncoderSetup, Error, ErrorBound, FourCc, FrameDecoder, FrameEncoder, Limits, RateLadder, Result,
    SearchAxis, SearchSpace, Setting, StreamInfo, TypedCodec,
};

pub use decoder::PcaAoiDecoder;
pub use dictionary::{Method, Mode};
pub use encoder::{BlockStats, PcaAoiEncoder};
pub use memory::{block_memory, MIN_MEMORY_BLOCK};
pub use params::{Coding, Domain, PcaAoiParams};

/// Most spatial clusters a stream may declare (the upper end of `clusters`' range).
pub(crate) const MAX_CLUSTERS: usize = 65536;
/// Most frames per block (the upper end of `block`'s range); toolkit-coded packets longer
/// than this are refused.
pub(crate) const MAX_BLOCK: usize = 4096;

/// Codec name on the command line and in error messages.
pub const NAME: &str = "pca-aoi";

/// Stream version 2 config, first byte: the coding of every packet (the paper's).
pub(crate) const CODING_PAPER: u8 = 0;
/// Stream version 2 config, first byte: the coding of every packet (the toolkit's).
pub(crate) const CODING_TOOLKIT: u8 = 1;

/// The rate ladder of `qaoi` streams: `eps_high` from large to small residuals (`k` is only
/// QAOI's starting rank). Every step stays above the default `eps_low`.
pub fn qaoi_rate_ladder() -> RateLadder {
    RateLadder::over(PcaAoiParams::eps_high, [0.2, 0.1, 0.05, 0.03, 0.02, 0.01, 0.007, 0.005, 0.003])
}

/// The rate ladder of toolkit-coded streams (stream version 2's default): the target KG, from
/// coarse to fine; the RD rule picks ranks and steps for each.
pub fn toolkit_rate_ladder() -> RateLadder {
    RateLadder::over(
        PcaAoiParams::kg,
        [10.0, 6.0, 4.0, 3.0, 2.0, 1.5, 1.0, 0.7, 0.5, 0.35, 0.25, 0.17, 0.12, 0.08, 0.05],
    )
}

/// The `pca-aoi` codec.
#[derive(Debug, Clone, Copy, Default)]
pub struct PcaAoi;

impl TypedCodec for PcaAoi {
    type Params = PcaAoiParams;
    const NAME: &'static str = NAME;
    const FOURCC: FourCc = FourCc::new(b"PAOI");
    const STREAM_VERSION: u16 = 2;
    const SUMMARY: &'static str =
        "streaming block PCA; dictionaries tracked by adaptive orthogonal iterations (Lalos et al. 2017)";

    /// The error band's upper edge for `qaoi`, whose rank follows it; otherwise the target KG
    /// for the toolkit coding (the RD rule picks ranks and steps) and `k` for the paper's.
    fn ladder(&self, base: &PcaAoiParams) -> RateLadder {
        if base.mode == Mode::Qaoi {
            return qaoi_rate_ladder();
        }
        if base.coding == Coding::Toolkit {
            return toolkit_rate_ladder();
        }
        RateLadder::over(PcaAoiParams::k, [1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48])
    }
    /// Toolkit coding in the fixed-rank modes: the ladder over the target KG, on blocks of the
    /// default 40 frames and of 120 (a basis per block: longer blocks share it over more
    /// frames, shorter ones follow changing motion; which wins depends on the input).
    fn space(&self, base: &PcaAoiParams) -> SearchSpace {
        let primary = self.ladder(base);
        if base.coding != Coding::Toolkit || base.mode == Mode::Qaoi {
            return SearchSpace::ladder_only(primary);
        }
        let mut values = vec![base.block];
        if base.block != 120 {
            values.push(120);
        }
        SearchSpace { primary, secondary: vec![SearchAxis::over(PcaAoiParams::block, values)] }
    }
    /// With `mode=svd` every block's dictionary is estimated from that block alone; baoi and
    /// qaoi start from the previous block's dictionary (`dictionary::Tracker`), so their packets
    /// depend on every earlier block.
    fn blocks(&self, p: &PcaAoiParams, _frame_count: usize) -> Result<usize> {
        if p.mode != Mode::Svd {
            return Err(Error::Unsupported {
                context: NAME.into(),
                detail: format!(
                    "mode={} starts each block's dictionary from the previous block's, so its blocks cannot be \
                     encoded independently; use -p mode=svd",
                    codec_core::ParamChoice::name(p.mode)
                ),
            });
        }
        Ok(p.block as usize)
    }
    /// A block (one packet, analysed at once) whose modelled peak ([`block_memory`]) exceeds
    /// `budget` is shortened to the fewest equal blocks that fit; a block that fits is kept.
    /// Fails, naming the budget, when [`MIN_MEMORY_BLOCK`] frames do not fit.
    fn fit(&self, p: &PcaAoiParams, vertices: usize, frames: usize, budget: u64) -> Result<Vec<Setting>> {
        let Some(chosen) = memory::block_for_budget(p.block as usize, vertices, frames, budget)? else {
            return Ok(Vec::new());
        };
        Ok(vec![PcaAoiParams::block.to(u32::try_from(chosen).unwrap_or(u32::MAX))])
    }
    fn bound(&self, p: &PcaAoiParams, animation: &Animation) -> Result<ErrorBound> {
        Ok(bound::error_bound(p, animation))
    }
    fn encoder(&self, p: PcaAoiParams, setup: &EncoderSetup<'_>) -> Result<Box<dyn FrameEncoder>> {
        Ok(Box::new(PcaAoiEncoder::new(&p, setup)?))
    }
    fn decoder(&self, info: &StreamInfo, config: &[u8], limits: &Limits) -> Result<Box<dyn FrameDecoder>> {
        Ok(Box::new(PcaAoiDecoder::new(info, config, limits)?))
    }
}
