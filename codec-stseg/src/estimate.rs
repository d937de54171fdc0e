//! The paper's rate estimate (§5.1, Eq. 8–9) of a segmentation, for comparison with the
//! measured streams.

use codec_core::{entropy, Animation, Error, Result};
use faer::Mat;

use crate::linalg::mul;
use crate::mesh::MeshGraph;
use crate::params::{Centering, StsegParams};
use crate::pca::{centred_block, group_pca};
use crate::segment::{Segment, Segmentation};
use crate::NAME;

/// The per-group component counts `k_j^i` of one segment (groups in label order), as the
/// encoder chooses them (§4.4): the inputs of the paper's rate estimate (Eq. 8).
pub fn segment_components(animation: &Animation, params: &StsegParams, segment: &Segment) -> Result<Vec<usize>> {
    params.validate()?;
    let graph = MeshGraph::new(animation.topology());
    let v = animation.vertex_count();
    let n3 = v * 3;
    if segment.labels.len() != v || segment.first_frame + segment.frame_count > animation.frame_count() {
        return Err(Error::parameter(NAME, "segment", "does not fit the animation"));
    }
    let block = &animation.positions()[segment.first_frame * n3..(segment.first_frame + segment.frame_count) * n3];
    (0..segment.group_count)
        .map(|g| {
            let own: Vec<u32> = (0..v as u32).filter(|&i| segment.labels[i as usize] as usize == g).collect();
            if own.is_empty() {
                return Ok(0);
            }
            Ok(group_pca(params, &graph, &own, block, segment.frame_count)?.0)
        })
        .collect()
}

/// The paper's rate estimate (§5.1, Eq. 8–9) for a segmentation: every value of the PCA
/// decomposition counted as a 32-bit float, times the ratio of a lossless compressor on those
/// floats.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaperRate {
    /// `Q` of Eq. 8 in bits: `32·Σ_{i,j}(3|V_j|·k_j^i + k_j^i·|τ_i| + m)` with `m` the mean's
    /// size (`|τ_i|` for [`Centering::Frame`], the paper's; `3|V_j|` for `Vertex`; 0 for `None`).
    pub q_bits: f64,
    /// `|XC_bs|`: bytes of the concatenated f32 components.
    pub raw_bytes: usize,
    /// `|X_bs|`: those bytes after the lossless stage (zstd at level 6 here, zlib in the paper).
    pub compressed_bytes: usize,
    /// Eq. 9: `|X_bs|/|XC_bs| · Q/(V·F)`.
    pub bpvf: f64,
    /// Eq. 8 alone: `Q/(V·F)` (no lossless stage).
    pub bpvf_uncompressed: f64,
}

/// Eq. 8–9 for `segmentation` of `animation` at `params`: the unquantized PCA components of
/// every group and segment (own rows only), as f32, compressed per segment.
pub fn paper_rate_estimate(
    animation: &Animation,
    params: &StsegParams,
    segmentation: &Segmentation,
) -> Result<PaperRate> {
    params.validate()?;
    let graph = MeshGraph::new(animation.topology());
    let v = animation.vertex_count();
    let n3 = v * 3;
    let (mut q_bits, mut raw_bytes, mut compressed_bytes) = (0.0, 0usize, 0usize);
    for seg in &segmentation.segments {
        if seg.labels.len() != v || seg.first_frame + seg.frame_count > animation.frame_count() {
            return Err(Error::parameter(NAME, "segmentation", "does not fit the animation"));
        }
        let frames = seg.frame_count;
        let block = &animation.positions()[seg.first_frame * n3..(seg.first_frame + frames) * n3];
        let mut raw: Vec<u8> = Vec::new();
        for g in 0..seg.group_count {
            let own: Vec<u32> = (0..v as u32).filter(|&i| seg.labels[i as usize] as usize == g).collect();
            if own.is_empty() {
                continue;
            }
            let (k, vecs) = group_pca(params, &graph, &own, block, frames)?;
            let (xo, mean) = match params.centering {
                c @ (Centering::Frame | Centering::FrameAxis) => {
                    let ext = graph.grow_rings(&own, params.eta as usize);
                    let (_, m) = centred_block(c, &ext, block, n3, frames);
                    let x = Mat::from_fn(own.len() * 3, frames, |r, t| {
                        let i = if c == Centering::Frame { t } else { t * 3 + r % 3 };
                        block[t * n3 + own[r / 3] as usize * 3 + r % 3] as f64 - m[i]
                    });
                    (x, m)
                }
                c => centred_block(c, &own, block, n3, frames),
            };
            let w = vecs.subcols(0, k);
            let a = mul(xo.as_ref(), w);
            q_bits += 32.0 * (3 * own.len() * k + k * frames + mean.len()) as f64;
            raw.extend(mean.iter().flat_map(|&x| (x as f32).to_le_bytes()));
            for j in 0..k {
                raw.extend((0..own.len() * 3).flat_map(|r| (a[(r, j)] as f32).to_le_bytes()));
                raw.extend((0..frames).flat_map(|t| (w[(t, j)] as f32).to_le_bytes()));
            }
        }
        raw_bytes += raw.len();
        compressed_bytes += zstd_len(&raw);
    }
    let vf = (v * animation.frame_count()).max(1) as f64;
    let ratio = if raw_bytes > 0 { compressed_bytes as f64 / raw_bytes as f64 } else { 0.0 };
    Ok(PaperRate { q_bits, raw_bytes, compressed_bytes, bpvf: ratio * q_bits / vf, bpvf_uncompressed: q_bits / vf })
}

/// Bytes of `raw` after the lossless stage at level 6 (the estimate's stand-in for zlib).
fn zstd_len(raw: &[u8]) -> usize {
    if raw.is_empty() {
        0
    } else {
        entropy::compress(raw, 6).len()
    }
}
