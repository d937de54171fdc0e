//! The paper's coding of a segment (§4.4, §5.1; stream version 2's packets, still written with
//! `coding=paper`): uniform quantizers at `bits` / `coef_bits`, zigzag run deltas, byte planes +
//! zstd.

use codec_core::bytes::{ByteReader, ByteWriter};
use codec_core::toolkit::planes::{delta_plane_count, plane_value, push_byte_planes, push_zigzag_run, zigzag_run_sums};
use codec_core::{entropy, Error, Limits, Quantizer, Result};
use faer::Mat;
use rayon::prelude::*;

use crate::linalg::{mul, sym_eig_desc};
use crate::mesh::MeshGraph;
use crate::params::{Centering, StsegParams};
use crate::pca::{centred_block, group_pca, mean_layout, reconstruct_group};
use crate::segment::Segment;
use crate::{coding, NAME};

/// One group's coded PCA (§4.4, Eq. 5): `X ≈ mean + A·B`, the mean as [`Centering`] says.
struct GroupCode {
    /// Quantizers of the mean: 3 (per axis, [`Centering::Vertex`]), 1 (over frames,
    /// [`Centering::Frame`]) or none.
    mean_q: Vec<Quantizer>,
    a_q: Vec<Quantizer>,
    b_q: Vec<Quantizer>,
    /// mean codes, A codes (column, axis, vertex), B codes (row, frame).
    values: Vec<u32>,
}

/// PCA of one group in one segment with η-ring overlap, quantized.
fn code_group(p: &StsegParams, graph: &MeshGraph, own: &[u32], block: &[f32], frames: usize) -> Result<GroupCode> {
    let n3 = graph.vertex_count() * 3;
    let (k, vecs) = group_pca(p, graph, own, block, frames)?;

    // Coefficients B = W_kᵀ (orthonormal rows), quantized first; the basis is then fitted to
    // the quantized coefficients (and the quantized mean) by least squares so it absorbs
    // their error.
    let mut b_q = Vec::with_capacity(k);
    let mut b_codes = Vec::with_capacity(k * frames);
    let mut bh = Mat::<f64>::zeros(k, frames);
    for j in 0..k {
        let row: Vec<f32> = (0..frames).map(|t| vecs[(t, j)] as f32).collect();
        let q = Quantizer::covering(&row, p.coef_bits)?;
        for (t, &x) in row.iter().enumerate() {
            let c = q.quantize(x);
            b_codes.push(c);
            bh[(j, t)] = q.dequantize(c) as f64;
        }
        b_q.push(q);
    }
    let n = own.len();
    let x_at = |r: usize, t: usize| block[t * n3 + own[r / 3] as usize * 3 + r % 3] as f64;
    let mut values = Vec::new();
    let mut mean_q = Vec::new();
    // The mean of the own rows (Vertex) or of the extended rows' PCA (Frame), quantized.
    let mean_hat: Vec<f64> = match p.centering {
        Centering::Vertex => {
            let (_, mean) = centred_block(Centering::Vertex, own, block, n3, frames);
            let mut hat = vec![0.0; 3 * n];
            for c in 0..3 {
                let axis: Vec<f32> = (0..n).map(|i| mean[i * 3 + c] as f32).collect();
                let q = Quantizer::covering(&axis, p.bits)?;
                push_zigzag_run(axis.iter().map(|&x| q.quantize(x)), 0, &mut values);
                for i in 0..n {
                    hat[i * 3 + c] = q.dequantize(q.quantize(axis[i])) as f64;
                }
                mean_q.push(q);
            }
            hat
        }
        Centering::Frame => {
            let ext = graph.grow_rings(own, p.eta as usize);
            let (_, mean) = centred_block(Centering::Frame, &ext, block, n3, frames);
            let m: Vec<f32> = mean.iter().map(|&x| x as f32).collect();
            let q = Quantizer::covering(&m, p.bits)?;
            push_zigzag_run(m.iter().map(|&x| q.quantize(x)), 0, &mut values);
            mean_q.push(q);
            m.iter().map(|&x| q.dequantize(q.quantize(x)) as f64).collect()
        }
        Centering::FrameAxis => {
            let ext = graph.grow_rings(own, p.eta as usize);
            let (_, mean) = centred_block(Centering::FrameAxis, &ext, block, n3, frames);
            let mut hat = vec![0.0; 3 * frames];
            for c in 0..3 {
                let axis: Vec<f32> = (0..frames).map(|t| mean[t * 3 + c] as f32).collect();
                let q = Quantizer::covering(&axis, p.bits)?;
                push_zigzag_run(axis.iter().map(|&x| q.quantize(x)), 0, &mut values);
                for t in 0..frames {
                    hat[t * 3 + c] = q.dequantize(q.quantize(axis[t])) as f64;
                }
                mean_q.push(q);
            }
            hat
        }
        Centering::None => Vec::new(),
    };
    let centred = |r: usize, t: usize| -> f64 {
        match p.centering {
            Centering::Vertex => x_at(r, t) - mean_hat[r],
            Centering::Frame => x_at(r, t) - mean_hat[t],
            Centering::FrameAxis => x_at(r, t) - mean_hat[t * 3 + r % 3],
            Centering::None => x_at(r, t),
        }
    };
    let mut a = Mat::<f64>::zeros(n * 3, k);
    if k > 0 {
        let xo = Mat::from_fn(n * 3, frames, centred);
        // A = X̂·B̂ᵀ·(B̂·B̂ᵀ)⁻¹, the inverse through the eigen-decomposition of the small SPD matrix.
        let m = mul(bh.as_ref(), bh.transpose());
        let (mv, mu) = sym_eig_desc(m.as_ref(), "coefficient Gram")?;
        let inv = Mat::from_fn(k, k, |i, j| {
            (0..k).filter(|&l| mv[l] > 1e-12 * mv[0]).map(|l| mu[(i, l)] * mu[(j, l)] / mv[l]).sum::<f64>()
        });
        a = mul(mul(xo.as_ref(), bh.transpose()).as_ref(), inv.as_ref());
    }
    let mut a_q = Vec::with_capacity(k);
    for j in 0..k {
        let col: Vec<f32> = (0..n * 3).map(|r| a[(r, j)] as f32).collect();
        let q = Quantizer::covering(&col, p.bits)?;
        for c in 0..3 {
            push_zigzag_run((0..n).map(|i| q.quantize(col[i * 3 + c])), 0, &mut values);
        }
        a_q.push(q);
    }
    for j in 0..k {
        push_zigzag_run(b_codes[j * frames..(j + 1) * frames].iter().copied(), 0, &mut values);
    }
    Ok(GroupCode { mean_q, a_q, b_q, values })
}

/// The paper coding's packet payload of one segment (stream version 2's layout).
pub(crate) fn encode_segment(p: &StsegParams, graph: &MeshGraph, seg: &Segment, block: &[f32]) -> Result<Vec<u8>> {
    let v = graph.vertex_count();
    let frames = seg.frame_count;
    let groups: Vec<Vec<u32>> = (0..seg.group_count)
        .map(|g| (0..v as u32).filter(|&i| seg.labels[i as usize] as usize == g).collect())
        .collect();
    // Groups are independent (§4.3 "parallel computing"); collect keeps their order.
    let codes: Vec<GroupCode> =
        groups.par_iter().map(|own| code_group(p, graph, own, block, frames)).collect::<Result<_>>()?;
    let mut w = ByteWriter::new();
    w.u8(seg.kind.case());
    w.varint(seg.group_count as u64);
    for c in &codes {
        w.varint(c.a_q.len() as u64);
        for q in c.mean_q.iter().chain(&c.a_q).chain(&c.b_q) {
            q.write(&mut w);
        }
    }
    let values: Vec<u32> = codes.iter().flat_map(|c| c.values.iter().copied()).collect();
    let planes = delta_plane_count(p.bits.max(p.coef_bits));
    let mut raw = Vec::with_capacity(v + values.len() * planes);
    raw.extend_from_slice(&seg.labels);
    push_byte_planes(&values, planes, &mut raw);
    w.bytes(&entropy::compress(&raw, p.level));
    Ok(w.into_vec())
}

/// The paper coding's packet of `frames` frames of `v` vertices after its case and group count
/// (stream version 2's layout), at the stream's bit depths `(bits, coef_bits)`. Sizes are
/// checked and the work charged to `limits` before anything is inflated or reconstructed.
pub(crate) fn decode_segment(
    r: &mut ByteReader<'_>,
    frames: usize,
    group_count: usize,
    v: usize,
    (bits, coef_bits): (u8, u8),
    centering: Centering,
    limits: &mut Limits,
) -> Result<Vec<f32>> {
    let max_k = frames.min(3 * v) as u64;
    let n_mean = mean_layout(centering, 0, 0).0;
    let mut ks = Vec::with_capacity(group_count);
    let mut quants = Vec::with_capacity(group_count);
    for _ in 0..group_count {
        let k = r.varint("components")?;
        if k > max_k {
            return Err(r.malformed("components", format!("{k} exceeds min(frames, 3·vertices) = {max_k}")));
        }
        let k = k as usize;
        // Each quantizer takes 9 bytes: a k beyond the remaining bytes is caught before allocating.
        if r.remaining() < (n_mean + 2 * k) * 9 {
            return Err(r.truncated("quantizers"));
        }
        let mut qs = Vec::with_capacity(n_mean + 2 * k);
        for i in 0..n_mean + 2 * k {
            let q = Quantizer::read(r, "quantizer")?;
            let want = if i < n_mean + k { bits } else { coef_bits };
            if q.bits() != want {
                return Err(r.malformed("quantizer", format!("{} bits, stream config says {want}", q.bits())));
            }
            qs.push(q);
        }
        ks.push(k);
        quants.push(qs);
    }
    let planes = delta_plane_count(bits.max(coef_bits));
    let sum_k: usize = ks.iter().sum();
    let max_k_used = ks.iter().copied().max().unwrap_or(0);
    let bound = (v as u64)
        + planes as u64 * (3 * v as u64 * (1 + max_k_used as u64) + (sum_k + 3 * group_count) as u64 * frames as u64);
    limits.check_alloc(NAME, "values", bound.saturating_mul(8))?;
    // The inflated bytes are charged before inflating (`--max-work`).
    *limits = limits.spend(NAME, "values", bound.saturating_mul(codec_core::limits::WORK_PER_PLANE_BYTE))?;
    let raw = entropy::decompress(r.take(r.remaining(), "values")?, NAME, "values", bound as usize)?;
    if raw.len() < v {
        return Err(Error::malformed(NAME, "labels", format!("{} bytes for {v} vertex labels", raw.len())));
    }
    let labels = &raw[..v];
    let mut members: Vec<Vec<u32>> = vec![Vec::new(); group_count];
    for (i, &l) in labels.iter().enumerate() {
        if l as usize >= group_count {
            return Err(Error::malformed(NAME, "labels", format!("vertex {i}: group {l} of {group_count}")));
        }
        members[l as usize].push(i as u32);
    }
    let count: usize = members
        .iter()
        .zip(&ks)
        .map(|(m, &k)| mean_layout(centering, m.len(), frames).1 + 3 * m.len() * k + k * frames)
        .sum();
    if raw.len() != v + planes * count {
        return Err(Error::malformed(NAME, "values", format!("{} bytes, expected {}", raw.len() - v, planes * count)));
    }
    // ... and the reconstruction (`frames·3·n·k` per group, plus the output) before it starts.
    let work = members
        .iter()
        .zip(&ks)
        .map(|(m, &k)| coding::reconstruction_work(frames, m.len(), k))
        .fold(0u64, u64::saturating_add);
    *limits = limits.spend(NAME, "reconstruction", work)?;
    let planes_raw = &raw[v..];
    let mut idx = 0usize;
    let mut next_run = |len: usize| -> Vec<u32> {
        let next = || {
            idx += 1;
            plane_value(planes_raw, count, planes, idx - 1)
        };
        zigzag_run_sums(len, 0, next).map(|c| c.clamp(0, u32::MAX as i64) as u32).collect()
    };
    let n3 = v * 3;
    let mut out = vec![0f32; frames * n3];
    for ((own, &k), qs) in members.iter().zip(&ks).zip(&quants) {
        let n = own.len();
        // Vertex: mean[c][i]; Frame: mean[0][t]; None: no mean.
        let mean: Vec<Vec<f64>> = match centering {
            Centering::Vertex => {
                (0..3).map(|c| next_run(n).into_iter().map(|q| qs[c].dequantize(q) as f64).collect()).collect()
            }
            Centering::Frame => vec![next_run(frames).into_iter().map(|q| qs[0].dequantize(q) as f64).collect()],
            Centering::FrameAxis => {
                (0..3).map(|c| next_run(frames).into_iter().map(|q| qs[c].dequantize(q) as f64).collect()).collect()
            }
            Centering::None => Vec::new(),
        };
        // a[j][c][i]
        let a: Vec<Vec<Vec<f64>>> = (0..k)
            .map(|j| {
                (0..3).map(|_| next_run(n).into_iter().map(|q| qs[n_mean + j].dequantize(q) as f64).collect()).collect()
            })
            .collect();
        let b: Vec<Vec<f64>> = (0..k)
            .map(|j| next_run(frames).into_iter().map(|q| qs[n_mean + k + j].dequantize(q) as f64).collect())
            .collect();
        reconstruct_group(centering, own, &mean, &a, &b, frames, n3, &mut out);
    }
    Ok(out)
}
