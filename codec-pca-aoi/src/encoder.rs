//! The streaming encoder: frames are cut into blocks of `block` frames; every cluster of a
//! block is centred by its per-frame centroid, its dictionary estimated ([`crate::dictionary`])
//! and the dictionary and features coded (the toolkit's coding, [`crate::coding`], or the
//! paper's §4.1, [`crate::paper`]). Every packet carries its own dictionaries.

use std::time::Duration;

use codec_core::bytes::ByteWriter;
use codec_core::toolkit::order::CausalGraph;
use codec_core::toolkit::predict::Predictor;
use codec_core::{EncodedPacket, EncoderSetup, ErrorBound, FrameDecoder, FrameEncoder, Packet, Result};
use faer::Mat;
use rayon::prelude::*;

use crate::bound::BoundStats;
use crate::decoder::PcaAoiDecoder;
use crate::dictionary::{self, EstimatorSettings, Method, Tracker};
use crate::params::{Coding, Domain, PcaAoiParams};
use crate::payload::{layouts, Resolved};
use crate::{cluster, coding, linalg, paper};
use crate::{CODING_PAPER, CODING_TOOLKIT};

/// Statistics of one cluster of one block, kept by [`PcaAoiEncoder`] for benchmarks and tests.
#[derive(Debug, Clone)]
pub struct BlockStats {
    /// First frame of the block.
    pub first_frame: u32,
    /// Frames in the block.
    pub frames: u32,
    /// Cluster index.
    pub cluster: usize,
    /// Subspace size `k_i`.
    pub k: usize,
    /// Relative residual `‖X − EEᵀX‖_F / ‖X‖_F` of the unquantized dictionary.
    pub residual: f64,
    /// How the dictionary was obtained.
    pub method: Method,
    /// Orthogonal iterations run.
    pub iterations: usize,
    /// Dictionary-estimation time (SVD, or the orthogonal iterations).
    pub estimate_time: Duration,
    /// Drift-guard time (residual check and any re-initializing SVD).
    pub guard_time: Duration,
    /// Payload bytes of this cluster.
    pub bytes: usize,
}

/// The streaming encoder. Holds at most one incomplete block of frames plus, per cluster,
/// the previous block's dictionary.
pub struct PcaAoiEncoder {
    params: PcaAoiParams,
    settings: EstimatorSettings,
    vertex_count: usize,
    clusters: Vec<Vec<u32>>,
    /// Per cluster, its mesh coding order (toolkit coding; empty chains for the paper's).
    graphs: Vec<CausalGraph>,
    domains: Vec<Resolved>,
    trackers: Vec<Tracker>,
    pending: Vec<f32>,
    next_frame: u32,
    reconstruct: Option<PcaAoiDecoder>,
    stats: Vec<BlockStats>,
    /// What the error bound needs of the frames pushed ([`FrameEncoder::declared_bound`]).
    bound: BoundStats,
}

impl PcaAoiEncoder {
    /// An encoder for `setup` (the parameters must be valid).
    pub fn new(params: &PcaAoiParams, setup: &EncoderSetup<'_>) -> Result<Self> {
        params.validate()?;
        let topology = setup.topology;
        let clusters = cluster::partition(topology, params.clusters as usize);
        let block = params.block as usize;
        let domains = clusters
            .iter()
            .map(|c| match params.domain {
                Domain::Temporal => Resolved::Temporal,
                Domain::Spatial => Resolved::Spatial,
                Domain::Auto if 3 * block <= c.len() => Resolved::Temporal,
                Domain::Auto => Resolved::Spatial,
            })
            .collect();
        let graphs = match params.coding {
            Coding::Toolkit => cluster::local_meshes(topology.triangles(), topology.vertex_count(), &clusters)
                .iter()
                .zip(&clusters)
                .map(|(triangles, verts)| CausalGraph::mesh(verts.len(), triangles))
                .collect(),
            Coding::Paper => clusters.iter().map(|_| CausalGraph::chain(0, false)).collect(),
        };
        let mut enc = Self {
            params: *params,
            settings: params.settings(),
            vertex_count: topology.vertex_count(),
            trackers: vec![Tracker::new(); clusters.len()],
            graphs,
            clusters,
            domains,
            pending: Vec::new(),
            next_frame: 0,
            reconstruct: None,
            stats: Vec::new(),
            bound: BoundStats::new(topology.vertex_count()),
        };
        if setup.want_reconstruction {
            enc.reconstruct =
                Some(PcaAoiDecoder::for_params(params, enc.vertex_count, enc.clusters.clone(), enc.graphs.clone()));
        }
        Ok(enc)
    }

    /// Per-block, per-cluster statistics of everything encoded so far.
    pub fn stats(&self) -> &[BlockStats] {
        &self.stats
    }

    /// The spatial clusters (vertex lists).
    pub fn clusters(&self) -> &[Vec<u32>] {
        &self.clusters
    }

    fn encode_block(&mut self, frames: &[f32]) -> Result<EncodedPacket> {
        let per_frame = self.vertex_count * 3;
        let d = frames.len() / per_frame;
        let settings = self.settings;
        let params = self.params;
        let v = self.vertex_count;
        let results: Vec<Result<(Vec<u8>, dictionary::BlockDictionary, usize)>> = self
            .clusters
            .par_iter()
            .zip(self.domains.par_iter())
            .zip(self.trackers.par_iter_mut())
            .zip(self.graphs.par_iter())
            .map(|(((verts, &domain), tracker), graph)| {
                encode_cluster(frames, d, v, verts, domain, tracker, graph, &settings, &params)
            })
            .collect();
        let mut w = ByteWriter::new();
        for (c, r) in results.into_iter().enumerate() {
            let (payload, dict, k) = r?;
            w.length_prefixed(&payload);
            self.stats.push(BlockStats {
                first_frame: self.next_frame,
                frames: d as u32,
                cluster: c,
                k,
                residual: dict.residual,
                method: dict.method,
                iterations: dict.iterations,
                estimate_time: dict.estimate_time,
                guard_time: dict.guard_time,
                bytes: payload.len(),
            });
        }
        let packet = Packet { first_frame: self.next_frame, frame_count: d as u32, keyframe: true, data: w.into_vec() };
        self.next_frame += d as u32;
        // The reconstruction goes through the decoder itself, so it matches bit for bit.
        let reconstruction = match self.reconstruct.as_mut() {
            Some(dec) => Some(dec.decode_packet(&packet)?),
            None => None,
        };
        Ok(EncodedPacket { packet, reconstruction })
    }
}

impl FrameEncoder for PcaAoiEncoder {
    /// [`AnimationCodec::error_bound`](codec_core::AnimationCodec::error_bound) of the frames pushed, accumulated as they arrive.
    fn declared_bound(&self) -> Option<ErrorBound> {
        Some(self.bound.bound(&self.params))
    }

    fn config(&self) -> Vec<u8> {
        let mut w = ByteWriter::new();
        match self.params.coding {
            Coding::Paper => {
                w.u8(CODING_PAPER);
                w.u8(self.params.dict_bits);
                w.u8(self.params.feat_bits);
            }
            Coding::Toolkit => {
                w.u8(CODING_TOOLKIT);
                w.u8(self.params.mesh_predictor.code());
                w.u8(self.params.time_predictor.code());
            }
        }
        w.varint(self.clusters.len() as u64);
        w.into_vec()
    }

    fn push_frames(&mut self, frames: &[f32]) -> Result<Vec<EncodedPacket>> {
        self.bound.push(frames);
        let per_block = self.params.block as usize * self.vertex_count * 3;
        let mut out = Vec::new();
        let mut rest = frames;
        if !self.pending.is_empty() {
            let need = per_block - self.pending.len();
            let take = need.min(rest.len());
            self.pending.extend_from_slice(&rest[..take]);
            rest = &rest[take..];
            if self.pending.len() == per_block {
                let block = std::mem::take(&mut self.pending);
                out.push(self.encode_block(&block)?);
            }
        }
        // Whole blocks straight from the caller's slice: no copy, no quadratic draining.
        while rest.len() >= per_block {
            out.push(self.encode_block(&rest[..per_block])?);
            rest = &rest[per_block..];
        }
        self.pending.extend_from_slice(rest);
        Ok(out)
    }

    fn finish(&mut self) -> Result<Vec<EncodedPacket>> {
        if self.pending.is_empty() {
            return Ok(Vec::new());
        }
        let block = std::mem::take(&mut self.pending);
        Ok(vec![self.encode_block(&block)?])
    }
}

/// Builds the centered block matrix of one cluster: `e × m` with `e = 3d` rows (temporal) or
/// `e = n_c` rows (spatial); returns it with the stored (f32) per-row means.
fn block_matrix(frames: &[f32], d: usize, v: usize, verts: &[u32], domain: Resolved) -> (Mat<f64>, Vec<f32>) {
    let n = verts.len();
    let at = |r: usize, j: usize| frames[((r / 3) * v + verts[j] as usize) * 3 + r % 3] as f64;
    let means: Vec<f32> = (0..3 * d).map(|r| ((0..n).map(|j| at(r, j)).sum::<f64>() / n as f64) as f32).collect();
    let x = match domain {
        Resolved::Temporal => Mat::from_fn(3 * d, n, |r, j| at(r, j) - means[r] as f64),
        Resolved::Spatial => Mat::from_fn(n, 3 * d, |j, r| at(r, j) - means[r] as f64),
    };
    (x, means)
}

/// One cluster of one block: its centred data matrix, the dictionary the tracker estimates
/// for it, and its payload in the stream's coding; returns the payload, the dictionary and the
/// number of components coded.
#[allow(clippy::too_many_arguments)]
fn encode_cluster(
    frames: &[f32],
    d: usize,
    v: usize,
    verts: &[u32],
    domain: Resolved,
    tracker: &mut Tracker,
    graph: &CausalGraph,
    settings: &EstimatorSettings,
    params: &PcaAoiParams,
) -> Result<(Vec<u8>, dictionary::BlockDictionary, usize)> {
    let (x, means) = block_matrix(frames, d, v, verts, domain);
    let dict = tracker.estimate(x.as_ref(), settings)?;
    if params.coding == Coding::Toolkit {
        let (payload, k) = toolkit_cluster(x.as_ref(), &means, &dict, domain, graph, d, params);
        return Ok((payload, dict, k));
    }
    let (payload, k) = paper::encode_cluster(x.as_ref(), &means, &dict, domain, params)?;
    Ok((payload, dict, k))
}

/// Toolkit coding of one cluster's block (stream version 2, `coding.rs`); returns the payload
/// and the number of components kept.
fn toolkit_cluster(
    x: faer::MatRef<'_, f64>,
    means: &[f32],
    dict: &dictionary::BlockDictionary,
    domain: Resolved,
    mesh: &CausalGraph,
    d: usize,
    params: &PcaAoiParams,
) -> (Vec<u8>, usize) {
    let time = CausalGraph::chain(d, params.time_predictor == Predictor::Parallelogram);
    let (dict_layout, feat_layout) = layouts(domain, mesh, &time);
    let settings = coding::Settings { mesh: params.mesh_predictor, time: params.time_predictor, rdq: params.rdq };
    let f = linalg::mul(dict.e.transpose(), x);
    let energy: f64 = (0..x.ncols()).map(|c| (0..x.nrows()).map(|r| x[(r, c)] * x[(r, c)]).sum::<f64>()).sum();
    // Quantization error budget: what the KG target leaves after the truncation; when the
    // estimated subspace alone misses the target, a quarter of the truncation error (relative
    // RMS); never below 1e-6 of the block's spread (f32 output precision).
    let truncation = energy * dict.residual * dict.residual;
    let total = (params.kg / 100.0).powi(2) * energy;
    let target = (total - truncation).max(0.0625 * truncation).max(1e-12 * energy);
    let mut coded = coding::code(dict.e.as_ref(), f.as_ref(), x, dict_layout, feat_layout, &settings, target);
    if coded.error2 > 0.99 * coded.energy2 && !coded.kept.is_empty() {
        // Worse than the means alone (possible only with absurdly coarse steps): code nothing,
        // which keeps the error bound (`error_bound`) honest.
        let k0 = dict.e.as_ref().subcols(0, 0);
        coded = coding::code(k0, f.as_ref().subrows(0, 0), x, dict_layout, feat_layout, &settings, target);
    }
    let mut w = ByteWriter::new();
    w.u8(match domain {
        Resolved::Temporal => 0,
        Resolved::Spatial => 1,
    });
    // The arithmetic-coded part has no length of its own: the frame count makes a packet
    // whose header lost it fail instead of decoding garbage.
    w.varint(d as u64);
    w.varint(coded.kept.len() as u64);
    for &m in means {
        w.f32(m);
    }
    for &s in &coded.steps {
        w.f32(s);
    }
    w.bytes(&coded.bytes);
    (w.into_vec(), coded.kept.len())
}
