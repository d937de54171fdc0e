//! The decoder: every packet alone (each carries its dictionaries), stream versions 1 and 2.
//! Sizes and work are checked against the caller's [`Limits`] before anything is allocated.

use codec_core::bytes::ByteReader;
use codec_core::toolkit::order::{self, CausalGraph};
use codec_core::toolkit::predict::Predictor;
use codec_core::{Error, FrameDecoder, Limits, Packet, ParsedPacket, Result, StreamInfo, Topology};
use faer::Mat;

use crate::params::{Coding, PcaAoiParams};
use crate::payload::{
    check_matrices, layouts, matrix_dims, read_domain, read_means, spend_cluster, DecodedCluster, Resolved,
    RECONSTRUCT_VERTICES,
};
use crate::{cluster, coding, linalg, paper};
use crate::{CODING_PAPER, CODING_TOOLKIT, MAX_BLOCK, MAX_CLUSTERS, NAME};

/// Decoder memory per cluster beyond its mesh coding order (graph headers and vectors).
const PER_CLUSTER_BYTES: u64 = 256;

/// The clusters' mesh coding orders in the decoder: built on the first toolkit packet, after
/// their size passed the limits.
enum MeshOrders {
    Pending(Vec<[u32; 3]>),
    Built(Vec<CausalGraph>),
}

/// How the stream's packets are coded (from the config).
enum DecoderCoding {
    Paper { dict_bits: u8, feat_bits: u8 },
    Toolkit { mesh: Predictor, time: Predictor, meshes: MeshOrders },
}

/// The decoder: every packet is decoded alone.
pub struct PcaAoiDecoder {
    coding: DecoderCoding,
    vertex_count: usize,
    clusters: Vec<Vec<u32>>,
    limits: Limits,
    /// The packets asked a frame of, parsed.
    parsed: ParsedPacket<Vec<DecodedCluster>>,
}

impl PcaAoiDecoder {
    /// Reads the stream configuration (untrusted) and recomputes the clusters from the topology.
    /// Version 1 configs are `dict_bits, feat_bits, clusters`; version 2 configs start with
    /// the coding (0 = paper: then version 1's config; 1 = toolkit: mesh and time predictor
    /// codes, clusters).
    pub fn new(info: &StreamInfo, config: &[u8], limits: &Limits) -> Result<Self> {
        if !(1..=2).contains(&info.codec_version) {
            return Err(Error::Unsupported {
                context: NAME.into(),
                detail: format!("stream version {} (this build decodes 1 and 2)", info.codec_version),
            });
        }
        let mut r = ByteReader::new(config, NAME);
        let coding_code = if info.codec_version == 1 { CODING_PAPER } else { r.u8("config.coding")? };
        let coding = match coding_code {
            CODING_PAPER => {
                let dict_bits = r.u8("config.dict_bits")?;
                let feat_bits = r.u8("config.feat_bits")?;
                for (field, bits) in [("config.dict_bits", dict_bits), ("config.feat_bits", feat_bits)] {
                    if !(4..=24).contains(&bits) {
                        return Err(r.malformed(field, format!("{bits} is outside 4..=24")));
                    }
                }
                DecoderCoding::Paper { dict_bits, feat_bits }
            }
            CODING_TOOLKIT => {
                let mut predictor = |field| {
                    let code = r.u8(field)?;
                    Predictor::from_code(code)
                        .ok_or_else(|| Error::malformed(NAME, field, format!("predictor code {code} is outside 0..=3")))
                };
                let mesh = predictor("config.mesh_predictor")?;
                let time = predictor("config.time_predictor")?;
                DecoderCoding::Toolkit { mesh, time, meshes: MeshOrders::Pending(info.topology.triangles().to_vec()) }
            }
            x => return Err(r.malformed("config.coding", format!("{x} is neither 0 (paper) nor 1 (toolkit)"))),
        };
        let v = info.vertex_count();
        let clusters = r.varint("config.clusters")?;
        r.expect_end("config")?;
        // The encoder writes at most MAX_CLUSTERS; more would only cost decoder memory (one
        // cluster and, for toolkit packets, one coding order each) for a tiny config.
        let most = (v as u64).min(MAX_CLUSTERS as u64);
        if clusters == 0 || clusters > most {
            return Err(r.malformed("config.clusters", format!("{clusters} is outside 1..={most}")));
        }
        Ok(Self {
            coding,
            vertex_count: v,
            clusters: cluster::partition(&info.topology, clusters as usize),
            limits: *limits,
            parsed: ParsedPacket::default(),
        })
    }

    /// The decoder of the stream the encoder writes with `params` (for its reconstruction):
    /// the encoder's clusters and, for the toolkit coding, their coding orders.
    pub(crate) fn for_params(
        params: &PcaAoiParams,
        vertex_count: usize,
        clusters: Vec<Vec<u32>>,
        graphs: Vec<CausalGraph>,
    ) -> Self {
        let coding = match params.coding {
            Coding::Paper => DecoderCoding::Paper { dict_bits: params.dict_bits, feat_bits: params.feat_bits },
            Coding::Toolkit => DecoderCoding::Toolkit {
                mesh: params.mesh_predictor,
                time: params.time_predictor,
                meshes: MeshOrders::Built(graphs),
            },
        };
        Self { coding, vertex_count, clusters, limits: Limits::default(), parsed: ParsedPacket::default() }
    }

    /// Builds the clusters' mesh coding orders on first use, once their size passed the limits.
    fn build_meshes(&mut self) -> Result<()> {
        if let DecoderCoding::Toolkit { meshes, .. } = &mut self.coding {
            if let MeshOrders::Pending(triangles) = meshes {
                let local = cluster::local_meshes(triangles, self.vertex_count, &self.clusters);
                let bytes = local
                    .iter()
                    .zip(&self.clusters)
                    // Plus a fixed per-cluster cost (graph headers and their vectors).
                    .map(|(t, c)| order::mesh_bytes(c.len(), t.len()).saturating_add(PER_CLUSTER_BYTES))
                    .fold(0u64, u64::saturating_add);
                self.limits.check_alloc(NAME, "mesh coding order", bytes)?;
                *meshes = MeshOrders::Built(
                    local.iter().zip(&self.clusters).map(|(t, c)| CausalGraph::mesh(c.len(), t)).collect(),
                );
            }
        }
        Ok(())
    }

    /// The partition recomputed from a topology (exposed for tests).
    pub fn partition(topology: &Topology, clusters: usize) -> Vec<Vec<u32>> {
        cluster::partition(topology, clusters)
    }

    /// Decodes cluster `c`'s payload of a packet of `d` frames up to its matrices, charging its
    /// work to `limits`.
    fn decode_cluster(&self, limits: &mut Limits, payload: &[u8], d: usize, c: usize) -> Result<DecodedCluster> {
        let verts = &self.clusters[c];
        let (dict_bits, feat_bits) = match &self.coding {
            DecoderCoding::Paper { dict_bits, feat_bits } => (*dict_bits, *feat_bits),
            DecoderCoding::Toolkit { mesh, time, meshes } => {
                let MeshOrders::Built(graphs) = meshes else {
                    return Err(Error::malformed(NAME, "cluster", "mesh coding order not built"));
                };
                return self.decode_toolkit_cluster(limits, payload, d, verts, &graphs[c], *mesh, *time);
            }
        };
        paper::decode_cluster(payload, d, verts.len(), (dict_bits, feat_bits), &self.limits, limits)
    }

    /// A packet up to its clusters' matrices (every check and the work charged as for its
    /// frames).
    fn parse(&mut self, packet: &Packet) -> Result<Vec<DecodedCluster>> {
        let d = packet.frame_count as usize;
        if d == 0 {
            return Err(Error::malformed(NAME, "packet.frame_count", "a packet holds at least one frame"));
        }
        // Packets never hold more frames than `block`'s range allows; refusing longer ones
        // bounds the rank, and with it the reconstruction work per decoded value.
        if d > MAX_BLOCK && matches!(self.coding, DecoderCoding::Toolkit { .. }) {
            return Err(Error::malformed(
                NAME,
                "packet.frame_count",
                format!("{d} exceeds the longest block the encoder writes ({MAX_BLOCK})"),
            ));
        }
        let len = d as u64 * self.vertex_count as u64 * 3;
        self.limits.check_alloc(NAME, "packet.frames", len * 4)?;
        self.build_meshes()?;
        let mut r = ByteReader::new(&packet.data, NAME);
        // Each cluster's work is charged (`--max-work`) before it is decoded.
        let mut limits = self.limits;
        let mut clusters = Vec::with_capacity(self.clusters.len());
        for c in 0..self.clusters.len() {
            let payload = r.length_prefixed("cluster.payload")?;
            clusters.push(self.decode_cluster(&mut limits, payload, d, c)?);
        }
        r.expect_end("packet")?;
        self.limits = limits;
        Ok(clusters)
    }

    /// Every frame of a parsed packet of `d` frames.
    fn frames(&self, parsed: &[DecodedCluster], d: usize) -> Vec<f32> {
        let mut out = vec![0f32; d * self.vertex_count * 3];
        for (c, verts) in parsed.iter().zip(&self.clusters) {
            self.write_cluster(c.e_hat.as_ref(), c.f_hat.as_ref(), &c.means, c.domain, verts, &mut out);
        }
        out
    }

    /// Frame `t` of a parsed packet alone: per cluster, the three rows (temporal) or columns
    /// (spatial) of `Ê F̂` that hold frame `t`, plus its means.
    fn frame(&self, parsed: &[DecodedCluster], t: usize) -> Vec<f32> {
        let mut out = vec![0f32; self.vertex_count * 3];
        for (c, verts) in parsed.iter().zip(&self.clusters) {
            let (e_hat, f_hat) = match c.domain {
                Resolved::Temporal => (c.e_hat.as_ref().subrows(3 * t, 3), c.f_hat.as_ref()),
                Resolved::Spatial => (c.e_hat.as_ref(), c.f_hat.as_ref().subcols(3 * t, 3)),
            };
            self.write_cluster(e_hat, f_hat, &c.means[3 * t..3 * t + 3], c.domain, verts, &mut out);
        }
        out
    }

    /// Eq. 5: `D̂ = Ê F̂`, plus the stored means, into the packet's frames. The product is
    /// formed [`RECONSTRUCT_VERTICES`] vertices at a time (whole, it is `3d × n` f64
    /// per cluster — 960 MB for a 40-frame block of 1M vertices, more than the decoded f32
    /// frames themselves); each entry is the same dot product over the `k` components either
    /// way (`reconstruction_in_vertex_chunks_is_bit_exact`).
    fn write_cluster(
        &self,
        e_hat: faer::MatRef<'_, f64>,
        f_hat: faer::MatRef<'_, f64>,
        means: &[f64],
        domain: Resolved,
        verts: &[u32],
        out: &mut [f32],
    ) {
        let v = self.vertex_count;
        for start in (0..verts.len()).step_by(RECONSTRUCT_VERTICES) {
            let chunk = &verts[start..(start + RECONSTRUCT_VERTICES).min(verts.len())];
            let x_hat = reconstruct_vertices(e_hat, f_hat, domain, start, chunk.len());
            for (j, &vert) in chunk.iter().enumerate() {
                for (row, &mean) in means.iter().enumerate() {
                    let value = match domain {
                        Resolved::Temporal => x_hat[(row, j)],
                        Resolved::Spatial => x_hat[(j, row)],
                    };
                    out[((row / 3) * v + vert as usize) * 3 + row % 3] = (value + mean) as f32;
                }
            }
        }
    }

    /// Stream version 2's toolkit-coded cluster payload (see the README, "Stream layout").
    #[allow(clippy::too_many_arguments)]
    fn decode_toolkit_cluster(
        &self,
        limits: &mut Limits,
        payload: &[u8],
        d: usize,
        verts: &[u32],
        mesh: &CausalGraph,
        mesh_predictor: Predictor,
        time_predictor: Predictor,
    ) -> Result<DecodedCluster> {
        let mut r = ByteReader::new(payload, NAME);
        let domain = read_domain(&mut r)?;
        let frames = r.varint("cluster.frames")?;
        if frames != d as u64 {
            return Err(r.malformed("cluster.frames", format!("{frames} frames, the packet holds {d}")));
        }
        let n = verts.len();
        let (e_dim, m_dim) = matrix_dims(domain, n, d);
        let k = r.varint_max("cluster.k", e_dim.min(m_dim) as u64)? as usize;
        let means = read_means(&mut r, d)?;
        let mut steps = Vec::with_capacity(2 * k);
        for i in 0..2 * k {
            let field = if i < k { "cluster.dict_step" } else { "cluster.feat_step" };
            let s = r.f32(field)?;
            if !(s.is_finite() && s >= 0.0) {
                return Err(r.malformed(field, format!("{s} is not a finite step ≥ 0")));
            }
            steps.push(s);
        }
        check_matrices(&self.limits, e_dim, m_dim, k, d, n)?;
        self.limits.check_alloc(NAME, "frame chains", (d as u64).saturating_mul(64))?;
        let values = ((e_dim + m_dim) as u64).saturating_mul(k as u64);
        spend_cluster(limits, values, codec_core::limits::WORK_PER_CODED_VALUE, d, n, k)?;
        let time = CausalGraph::chain(d, time_predictor == Predictor::Parallelogram);
        let (dict_layout, feat_layout) = layouts(domain, mesh, &time);
        let settings = coding::Settings { mesh: mesh_predictor, time: time_predictor, rdq: true };
        let bytes = r.take(r.remaining(), "cluster.codes")?;
        let (e_hat, f_hat) = coding::decode(bytes, &steps, dict_layout, feat_layout, &settings)?;
        Ok(DecodedCluster { domain, means, e_hat, f_hat })
    }
}

/// The columns (temporal) or rows (spatial) `start .. start + len` of `Ê F̂`: the vertices'
/// part of the cluster's reconstruction.
fn reconstruct_vertices(
    e_hat: faer::MatRef<'_, f64>,
    f_hat: faer::MatRef<'_, f64>,
    domain: Resolved,
    start: usize,
    len: usize,
) -> Mat<f64> {
    match domain {
        Resolved::Temporal => linalg::mul(e_hat, f_hat.subcols(start, len)),
        Resolved::Spatial => linalg::mul(e_hat.subrows(start, len), f_hat),
    }
}

impl FrameDecoder for PcaAoiDecoder {
    /// Uses the kept parse when `packet` is a packet asked a frame of; otherwise parses without
    /// keeping it (sequential decoding holds no more than one packet's matrices).
    fn decode_packet(&mut self, packet: &Packet) -> Result<Vec<f32>> {
        let d = packet.frame_count as usize;
        let mut kept = std::mem::take(&mut self.parsed);
        let frames = match kept.get(packet) {
            Some(parsed) => Ok(self.frames(parsed, d)),
            None => self.parse(packet).map(|parsed| self.frames(&parsed, d)),
        };
        self.parsed = kept;
        frames
    }

    /// Every packet decodes alone (its clusters' dictionaries and features, kept once parsed);
    /// frame `t` is then three rows (or columns) of each cluster's `Ê F̂` plus its means.
    fn decode_frame_of_packet(&mut self, packet: &Packet, local: usize) -> Result<Vec<f32>> {
        if local >= packet.frame_count as usize {
            return Err(codec_core::codec::frame_outside_packet(packet, local));
        }
        let mut kept = std::mem::take(&mut self.parsed);
        let frame = match kept.get(packet) {
            Some(parsed) => Ok(self.frame(parsed, local)),
            None => self.parse(packet).map(|parsed| {
                let bytes = parsed
                    .iter()
                    .map(|c| {
                        (c.e_hat.nrows() * c.e_hat.ncols() + c.f_hat.nrows() * c.f_hat.ncols() + c.means.len()) as u64
                            * 8
                    })
                    .sum();
                let parsed = kept.keep(packet, parsed, bytes);
                self.frame(parsed, local)
            }),
        };
        self.parsed = kept;
        frame
    }

    fn decodes_single_frames(&self) -> bool {
        true
    }

    fn keep_parsed_packets(&mut self, bytes: u64) {
        self.parsed.set_budget(bytes);
    }
}

#[cfg(test)]
mod chunk_tests {
    use super::*;

    /// One frame's rows (temporal) or columns (spatial) of `Ê F̂`, formed alone as
    /// `decode_frame_of_packet` forms them, equal those of the whole product bit for bit, at
    /// ranks, frame counts and cluster sizes from tiny to beyond the product's chunk.
    #[test]
    fn one_frame_of_the_product_is_bit_exact() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for (d, k, n) in [(40, 8, 2562), (1, 1, 5), (3, 3, 40), (16, 24, 700), (40, 60, RECONSTRUCT_VERTICES + 3)] {
            for domain in [Resolved::Temporal, Resolved::Spatial] {
                let (e_dim, m_dim) = matrix_dims(domain, n, d);
                let k = k.min(e_dim).min(m_dim);
                let e = Mat::from_fn(e_dim, k, |_, _| next());
                let f = Mat::from_fn(k, m_dim, |_, _| next());
                for start in (0..n).step_by(RECONSTRUCT_VERTICES) {
                    let len = RECONSTRUCT_VERTICES.min(n - start);
                    let whole = reconstruct_vertices(e.as_ref(), f.as_ref(), domain, start, len);
                    for t in [0, d / 2, d - 1] {
                        let (e1, f1) = match domain {
                            Resolved::Temporal => (e.as_ref().subrows(3 * t, 3), f.as_ref()),
                            Resolved::Spatial => (e.as_ref(), f.as_ref().subcols(3 * t, 3)),
                        };
                        let part = reconstruct_vertices(e1, f1, domain, start, len);
                        for j in 0..len {
                            for c in 0..3 {
                                let (a, b) = match domain {
                                    Resolved::Temporal => (part[(c, j)], whole[(3 * t + c, j)]),
                                    Resolved::Spatial => (part[(j, c)], whole[(j, 3 * t + c)]),
                                };
                                assert_eq!(a.to_bits(), b.to_bits(), "d {d} k {k} n {n} {domain:?} t {t} vertex {j}");
                            }
                        }
                    }
                }
            }
        }
    }

    /// The decoder's reconstruction in chunks of vertices equals the whole product bit for bit
    /// (old streams decode to the same frames), for ranks and cluster sizes on both sides of
    /// the chunk, remainders included.
    #[test]
    fn reconstruction_in_vertex_chunks_is_bit_exact() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for (d, k, n) in [(40, 8, RECONSTRUCT_VERTICES * 2 + 17), (3, 1, RECONSTRUCT_VERTICES + 1), (12, 30, 9000)] {
            for domain in [Resolved::Temporal, Resolved::Spatial] {
                let (e_dim, m_dim) = matrix_dims(domain, n, d);
                let e = Mat::from_fn(e_dim, k, |_, _| next());
                let f = Mat::from_fn(k, m_dim, |_, _| next());
                let whole = linalg::mul(e.as_ref(), f.as_ref());
                for start in (0..n).step_by(RECONSTRUCT_VERTICES) {
                    let len = RECONSTRUCT_VERTICES.min(n - start);
                    let part = reconstruct_vertices(e.as_ref(), f.as_ref(), domain, start, len);
                    for j in 0..len {
                        for row in 0..3 * d {
                            let (a, b) = match domain {
                                Resolved::Temporal => (part[(row, j)], whole[(row, start + j)]),
                                Resolved::Spatial => (part[(j, row)], whole[(start + j, row)]),
                            };
                            assert_eq!(a.to_bits(), b.to_bits(), "d {d} k {k} n {n} {domain:?} vertex {}", start + j);
                        }
                    }
                }
            }
        }
    }
}
