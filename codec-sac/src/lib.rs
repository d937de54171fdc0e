//! `sac`: spectral animation compression of deformation gradients with manifold harmonics
//! (*Spectral animation compression*, J. Comput. Sci. Technol.,
//! `../shared/papers/001_7516895ab061b963.txt`; see `README.md`).
//!
//! Per keyframe interval: the I-frame's positions are quantized near-losslessly; encoder and
//! decoder compute the manifold harmonic bases of the *decoded* I-frame. Every later frame is
//! coded as the deformation from the previous *reconstructed* frame (closed loop, §3.1):
//! per-triangle deformation gradients (§3.2) → polar decomposition and rotation logarithm
//! (§3.3) → least-squares spectral descriptors on the first `bases` harmonics (§3.4) →
//! quantization and arithmetic coding (§3.5) → decoded gradients → least-squares Poisson
//! reconstruction (§3.6) plus one stored translation per connected component.
//!
//! Beyond the paper (stream version 2): the harmonics of a disconnected mesh are
//! computed per connected component, and an optional residual layer (`residual > 0`; spectral
//! projection on the same harmonics, then per-vertex residuals) codes what the Poisson
//! reconstruction missed, inside the closed loop. `residual = 0` is the paper's method.
//!
//! Stream version 3: the basis is computed once per stream from the first
//! frame, which later keyframes name (`basis = keyframe` for the paper's per-keyframe basis);
//! the Poisson system is solved over the vertices only and re-factored every `refactor`
//! P-frames (1 = every frame, the paper's solve); the error guard refreshes up to a cap and
//! repairs with a residual beyond it, and reports both through `FrameEncoder::notes`.
//!
//! Modules: `params` (the parameters, re-exported here), `encoder` and `decoder`, `state`
//! (what both share: the stream config, the connectivity's Poisson system and one basis state
//! per stream version, the P-frame reconstruction), [`harmonics`] (§3.4), [`geometry`]
//! (§3.2–3.3, §3.6) and [`coding`] (§3.5).

pub mod coding;
mod decoder;
mod encoder;
pub mod geometry;
pub mod harmonics;
mod params;
pub mod poisson;
mod state;

use codec_core::{
    Animation, EncoderSetup, ErrorBound, FourCc, FrameDecoder, FrameEncoder, Limits, Quantizer, RateLadder, Result,
    Setting, StreamInfo, TypedCodec,
};

pub use params::{BasisSource, SacParams, PRESET_GUARD_AT_100, RATE_PRESETS};

/// Codec name.
pub const NAME: &str = "sac";

/// The encoder's limits: it reads no untrusted stream, so its allocations are bounded only by
/// the input it was given (the decoder uses the caller's [`Limits`]).
pub(crate) const UNLIMITED: Limits = Limits::UNLIMITED;

/// Stream version the encoder writes. Version 2 computes the manifold harmonics of
/// a disconnected mesh one connected component at a time
/// ([`harmonics::harmonics_by_component`]) and adds the residual layer to P-frames; version 1
/// solved the whole mesh at once. Version 3 computes the basis once per
/// stream from a rest pose every keyframe names (`basis = stream`), solves the Poisson system
/// over the vertices only, re-factored every `refactor` P-frames ([`poisson::ReducedPoisson`]),
/// synthesizes through the vertex basis, and lets the error guard repair a P-frame with a
/// coarse residual before falling back to a refresh frame. The decoder still decodes versions
/// 1 and 2 exactly as they were.
pub const STREAM_VERSION: u16 = 3;

/// Peak bytes of a sac encode of `frames` frames of a mesh of `vertices` vertices with `bases`
/// harmonic bases, the whole process ([`codec_core::memory`]): the stream driver's self-check
/// keeps the whole input (sac declares no bound of its own, so `AnimationCodec::error_bound`
/// runs on it at the end: 12 bytes a vertex a frame), and the encoder's per-mesh state. Measured
/// 21.7 MiB (900 vertices × 40 frames, 32 bases), 37.3 / 49.9 MiB (2 500 × 60, 32 / 64 bases)
/// and 115.7 MiB (10 000 × 60, 32 bases): besides the input, about 4–5 KiB a vertex and 160
/// bytes a vertex per basis; this model is 13–17 % above each. Fitted up to 10 000 vertices (the
/// factorizations' fill may grow faster on much larger meshes).
pub fn encode_memory(vertices: usize, frames: usize, bases: usize) -> u64 {
    let k = vertices as u64;
    codec_core::memory::PROCESS_BYTES + 12 * k * frames as u64 + k * (5632 + 192 * bases as u64)
}

/// The `sac` codec.
#[derive(Debug, Clone, Copy, Default)]
pub struct Sac;

impl TypedCodec for Sac {
    type Params = SacParams;
    const NAME: &'static str = NAME;
    const FOURCC: FourCc = FourCc::new(b"SAC1");
    const STREAM_VERSION: u16 = STREAM_VERSION;
    const SUMMARY: &'static str =
        "spectral compression of deformation gradients (polar decomposition + manifold harmonics)";

    /// Walks the rate presets ([`RATE_PRESETS`]): 16…100 bases with the paper's method, then
    /// 100 bases with the residual layer at decreasing steps, which continues the curve below
    /// the paper's error floor. It starts at 16 bases: below that the error guard replaces
    /// many P-frames with refresh frames on real data, and the stream grows again while the
    /// error stays high (measured with `animcodec sweep`: horse-gallop 2 bases 11.8 bpvf at KG
    /// 19.3 against 16 bases 2.0 bpvf at KG 7.0; samba 4 bases 1.07 bpvf against 8 bases 0.82),
    /// so those points are dominated and only break the ladder's order.
    fn ladder(&self, _base: &SacParams) -> RateLadder {
        RateLadder::over(SacParams::rate, 1..=RATE_PRESETS.len() as u8)
    }
    /// The error guard makes the bound provable: every P-frame that is kept has RMS error at
    /// most `max_error × (its frame's bounding-box diagonal) ≤ max_error × (the animation's
    /// diagonal)`; I-frames and refresh frames err by at most half a quantization step of the
    /// frame's range per coordinate, no more than the same step over the animation's range.
    /// The overall RMS is the root of the mean of per-frame mean squares, so it is below the
    /// larger of the two.
    fn bound(&self, p: &SacParams, animation: &Animation) -> Result<ErrorBound> {
        let (lo, hi) = animation.bounding_box();
        let diag = animation.bounding_box_diagonal();
        let mut q = 0.0f64;
        for a in 0..3 {
            q = q.max(Quantizer::new(lo[a], hi[a], p.iframe_bits)?.max_error());
        }
        let rel = if diag > 0.0 { (q / diag).max(p.max_error) } else { 0.0 };
        // Relative headroom for the f32 rounding of the stored frames.
        Ok(ErrorBound { max_coordinate_error: None, relative_rms_error: Some(rel * (1.0 + 1e-6)) })
    }
    /// sac's encoder holds per-mesh state (the manifold harmonic basis and its eigensolver's
    /// work, the Poisson factorization, a few frames), never a block of frames it could
    /// shorten: a budget below [`encode_memory`] is refused up front, naming the need.
    fn fit(&self, p: &SacParams, vertices: usize, frames: usize, budget: u64) -> Result<Vec<Setting>> {
        let bases = (p.bases as usize).min(vertices);
        let what = format!("{frames} frames of {vertices} vertices, {bases} harmonic bases");
        let advice = if bases > 16 { ", or fewer bases (-p bases=N)" } else { "" };
        codec_core::memory::check_budget(NAME, budget, encode_memory(vertices, frames, bases), &what, advice)?;
        Ok(Vec::new())
    }
    fn encoder(&self, p: SacParams, setup: &EncoderSetup<'_>) -> Result<Box<dyn FrameEncoder>> {
        encoder::new_encoder(p, setup)
    }
    fn decoder(&self, info: &StreamInfo, config: &[u8], limits: &Limits) -> Result<Box<dyn FrameDecoder>> {
        decoder::new_decoder(info, config, limits)
    }
}

// The unit tests (`tests.rs`, `use super::*`) drive the internals directly: encoders of the
// old stream versions, the error guard's frame kinds.
#[cfg(test)]
use {
    codec_core::{AnimationCodec, EncodedPacket, Error, ParamSet, ParamValue, Topology},
    encoder::SacEncoder,
    geometry::V3,
    state::{to_v3, Settings, Shared, KIND_I, KIND_P, KIND_REFRESH},
};

#[cfg(test)]
mod tests;
