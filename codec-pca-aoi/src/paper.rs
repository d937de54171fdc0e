//! The paper's coding of a cluster (§4.1; stream version 1's packets, still written with
//! `coding=paper`): per-column (dictionary) and per-row (features) uniform quantizers at
//! `dict_bits` / `feat_bits`, codes predicted from the code `stride` places earlier, byte
//! planes + zstd.

use codec_core::bytes::{zigzag_decode, ByteReader, ByteWriter};
use codec_core::toolkit::planes::{delta_plane_count, plane_value, push_byte_planes, push_zigzag_deltas};
use codec_core::{entropy, Error, Limits, Quantizer, Result};
use faer::Mat;

use crate::dictionary::BlockDictionary;
use crate::params::PcaAoiParams;
use crate::payload::{check_matrices, matrix_dims, read_domain, read_means, spend_cluster, DecodedCluster, Resolved};
use crate::{linalg, NAME};

/// The paper coding's payload of one cluster (§4.1): the domain byte, `k`, the stored means,
/// the quantizers and the zstd-compressed byte planes of the stride-predicted codes. The
/// features are computed from the *quantized* dictionary (closed loop). Returns the payload and
/// `k`.
pub(crate) fn encode_cluster(
    x: faer::MatRef<'_, f64>,
    means: &[f32],
    dict: &BlockDictionary,
    domain: Resolved,
    params: &PcaAoiParams,
) -> Result<(Vec<u8>, usize)> {
    let (e_dim, m_dim) = x.shape();
    let k = dict.e.ncols();
    // Dictionary: per-column uniform quantizers (§4.1, q_d bits).
    let mut dict_q = Vec::with_capacity(k);
    let mut dict_codes = Vec::with_capacity(e_dim * k);
    let mut e_hat = Mat::<f64>::zeros(e_dim, k);
    for j in 0..k {
        let col: Vec<f32> = (0..e_dim).map(|i| dict.e[(i, j)] as f32).collect();
        let q = Quantizer::covering(&col, params.dict_bits)?;
        for (i, &c) in col.iter().enumerate() {
            let code = q.quantize(c);
            dict_codes.push(code);
            e_hat[(i, j)] = q.dequantize(code) as f64;
        }
        dict_q.push(q);
    }
    // Features from the quantized dictionary (closed loop), per-row quantizers (q_f bits).
    let f = linalg::mul(e_hat.transpose(), x);
    let mut feat_q = Vec::with_capacity(k);
    let mut feat_codes = Vec::with_capacity(k * m_dim);
    for i in 0..k {
        let row: Vec<f32> = (0..m_dim).map(|j| f[(i, j)] as f32).collect();
        let q = Quantizer::covering(&row, params.feat_bits)?;
        feat_codes.extend(row.iter().map(|&c| q.quantize(c)));
        feat_q.push(q);
    }
    let (dict_stride, feat_stride) = match domain {
        Resolved::Temporal => (3, 1),
        Resolved::Spatial => (1, 3),
    };
    let mut dict_res = Vec::with_capacity(dict_codes.len());
    for col in dict_codes.chunks(e_dim.max(1)) {
        push_zigzag_deltas(col, dict_stride, &mut dict_res);
    }
    let mut feat_res = Vec::with_capacity(feat_codes.len());
    for row in feat_codes.chunks(m_dim.max(1)) {
        push_zigzag_deltas(row, feat_stride, &mut feat_res);
    }
    let mut raw = Vec::new();
    push_byte_planes(&dict_res, delta_plane_count(params.dict_bits), &mut raw);
    push_byte_planes(&feat_res, delta_plane_count(params.feat_bits), &mut raw);

    let mut w = ByteWriter::new();
    w.u8(match domain {
        Resolved::Temporal => 0,
        Resolved::Spatial => 1,
    });
    w.varint(k as u64);
    for &m in means {
        w.f32(m);
    }
    for q in dict_q.iter().chain(&feat_q) {
        q.write(&mut w);
    }
    w.bytes(&entropy::compress(&raw, params.level));
    Ok((w.into_vec(), k))
}

/// A paper-coded cluster payload of `n` vertices over `d` frames, at the stream's bit depths
/// `(dict_bits, feat_bits)`: sizes are checked against `memory` and the cluster's work charged
/// to `work` before the codes are inflated.
pub(crate) fn decode_cluster(
    payload: &[u8],
    d: usize,
    n: usize,
    (dict_bits, feat_bits): (u8, u8),
    memory: &Limits,
    work: &mut Limits,
) -> Result<DecodedCluster> {
    let mut r = ByteReader::new(payload, NAME);
    let domain = read_domain(&mut r)?;
    let (e_dim, m_dim) = matrix_dims(domain, n, d);
    let k = r.varint_max("cluster.k", e_dim.min(m_dim) as u64)? as usize;
    let means = read_means(&mut r, d)?;
    let mut quantizers = Vec::with_capacity(2 * k);
    for i in 0..2 * k {
        let (field, bits) =
            if i < k { ("cluster.dict_quantizer", dict_bits) } else { ("cluster.feat_quantizer", feat_bits) };
        let q = Quantizer::read(&mut r, field)?;
        if q.bits() != bits {
            return Err(r.malformed(field, format!("{} bits, stream config says {bits}", q.bits())));
        }
        quantizers.push(q);
    }
    let (pd, pf) = (delta_plane_count(dict_bits), delta_plane_count(feat_bits));
    let (nd, nf) = (e_dim * k, k * m_dim);
    let raw_len = nd * pd + nf * pf;
    memory.check_alloc(NAME, "cluster.codes", raw_len as u64)?;
    spend_cluster(work, raw_len as u64, codec_core::limits::WORK_PER_PLANE_BYTE, d, n, k)?;
    check_matrices(memory, e_dim, m_dim, k, d, n)?;
    let block = r.take(r.remaining(), "cluster.codes")?;
    let raw = entropy::decompress(block, NAME, "cluster.codes", raw_len)?;
    if raw.len() != raw_len {
        return Err(Error::malformed(NAME, "cluster.codes", format!("{} bytes, expected {raw_len}", raw.len())));
    }
    let (dict_stride, feat_stride) = match domain {
        Resolved::Temporal => (3, 1),
        Resolved::Spatial => (1, 3),
    };
    // Undoes the stride prediction of one vector of `len` codes starting at `offset`.
    let codes = |plane_base: usize,
                 count: usize,
                 planes: usize,
                 offset: usize,
                 len: usize,
                 stride: usize,
                 max: u32,
                 field: &'static str|
     -> Result<Vec<u32>> {
        let mut v: Vec<u32> = Vec::with_capacity(len);
        for i in 0..len {
            let z = plane_value(&raw[plane_base..], count, planes, offset + i);
            let c = zigzag_decode(u64::from(z)) + if i >= stride { v[i - stride] as i64 } else { 0 };
            if !(0..=max as i64).contains(&c) {
                return Err(Error::malformed(NAME, field, format!("code {c} outside 0..={max}")));
            }
            v.push(c as u32);
        }
        Ok(v)
    };
    let mut e_hat = Mat::<f64>::zeros(e_dim, k);
    for j in 0..k {
        let q = &quantizers[j];
        let col = codes(0, nd, pd, j * e_dim, e_dim, dict_stride, q.max_code(), "cluster.dictionary")?;
        for (i, &c) in col.iter().enumerate() {
            e_hat[(i, j)] = q.dequantize(c) as f64;
        }
    }
    let mut f_hat = Mat::<f64>::zeros(k, m_dim);
    for i in 0..k {
        let q = &quantizers[k + i];
        let row = codes(nd * pd, nf, pf, i * m_dim, m_dim, feat_stride, q.max_code(), "cluster.features")?;
        for (j, &c) in row.iter().enumerate() {
            f_hat[(i, j)] = q.dequantize(c) as f64;
        }
    }
    Ok(DecodedCluster { domain, means, e_hat, f_hat })
}
