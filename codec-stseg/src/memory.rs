//! Memory model of `stseg`'s encoder: what
//! [`AnimationCodec::fit_memory`](codec_core::AnimationCodec::fit_memory) checks a budget against.

/// Peak bytes of an stseg encode of `frames` frames of `vertices` vertices whose segmenter holds
/// up to `window` frames (`gamma_max + gamma_init`), the whole process
/// ([`codec_core::memory`]): the stream driver's self-check keeps the whole input (stseg
/// declares no bound of its own: 12 bytes a vertex a frame), the mesh graphs and groups (per
/// vertex) and the pending frames with their centred copies and Gram work (per coordinate of
/// the window). Measured 16.7 MiB (900 vertices × 40 frames), 24.3 MiB (2 500 × 60), 63.9 /
/// 67.5 MiB (10 000 × 60, `gamma_max` 50 / 100) and 72.9 MiB (samba, 9 971 × 175); this model
/// is 12–30 % above each.
pub fn encode_memory(vertices: usize, frames: usize, window: usize) -> u64 {
    let k = vertices as u64;
    codec_core::memory::PROCESS_BYTES + 12 * k * frames as u64 + 3072 * k + 16 * 3 * k * window as u64
}
