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

pub mod cluster;
mod coding;
pub mod dictionary;
mod linalg;

use std::time::Duration;

use codec_core::bytes::{zigzag_decode, zigzag_encode, ByteReader, ByteWriter};
use codec_core::toolkit::order::{self, CausalGraph};
use codec_core::toolkit::predict::Predictor;
use codec_core::{
    entropy, Animation, AnimationCodec, EncodedPacket, EncoderSetup, Error, ErrorBound, FourCc, FrameDecoder,
    FrameEncoder, Limits, Packet, ParamSet, ParamSpec, ParamValue, Quantizer, RateLadder, Result, SearchAxis,
    SearchSpace, StreamInfo, Topology,
};
use faer::Mat;
use rayon::prelude::*;

use coding::Layout;
use dictionary::{EstimatorSettings, Tracker};
pub use dictionary::{Method, Mode};

/// Most spatial clusters a stream may declare (the upper end of `clusters`' range).
pub(crate) const MAX_CLUSTERS: usize = 65536;
/// Most frames per block (the upper end of `block`'s range); toolkit-coded packets longer
/// than this are refused.
pub(crate) const MAX_BLOCK: usize = 4096;
/// Decoder memory per cluster beyond its mesh coding order (graph headers and vectors).
const PER_CLUSTER_BYTES: u64 = 256;

/// Codec name on the command line and in error messages.
pub const NAME: &str = "pca-aoi";

/// Which autocorrelation matrix the dictionary diagonalizes (Eq. 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Domain {
    /// The smaller of the two (per cluster, from the nominal block size).
    Auto,
    /// `A = D Dᵀ` (`3d × 3d`): EigenTrajectories; dictionary rows are frame coordinates.
    Temporal,
    /// `A = Dᵀ D` (`n × n`): EigenShapes; dictionary rows are vertices.
    Spatial,
}

/// How dictionaries and features are coded (`coding` parameter).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Coding {
    /// Stream version 2's coding (issue 15): prediction along the cluster's mesh and along
    /// time, per-component steps by the equal-slope rule, adaptive arithmetic coding
    /// (`coding.rs`).
    Toolkit,
    /// The paper's coding (§4.1): uniform quantization at `dict_bits` / `feat_bits`, byte
    /// planes + zstd. Its packets are byte for byte version 1's.
    Paper,
}

// Parameter names in stream-code order (`paper` = 0, `toolkit` = 1).
codec_core::param_choice!(Coding { Paper = "paper", Toolkit = "toolkit" });
codec_core::param_choice!(Domain { Auto = "auto", Temporal = "temporal", Spatial = "spatial" });
codec_core::param_choice!(Mode { Svd = "svd", Baoi = "baoi", Qaoi = "qaoi" });

codec_core::declare_params! {
    codec: NAME;
    /// Typed parameters of `pca-aoi`.
    #[derive(Debug, Clone, Copy, PartialEq)]
    pub struct PcaAoiParams {
        /// Dictionary estimation method. Default `baoi`.
        pub mode: Mode = Mode::Baoi
            => choice("dictionary estimation: svd (direct, per block), baoi (Alg. 1), qaoi (Alg. 2)"),
        /// Subspace size (svd, baoi), 1..=512. Default 8. Not used by qaoi, whose first block takes
        /// its size from the SVD spectrum (see the README).
        pub k: u32 = 8
            => int(1, 512, "subspace size (svd, baoi); qaoi sizes its first block from the SVD spectrum"),
        /// Frames per block (= per packet), 1..=4096. Default 40.
        pub block: u32 = 40 => int(1, MAX_BLOCK as i64, "frames per block; one self-contained packet per block"),
        /// Power of `A_i` per orthogonal iteration, 1..=16. Default 1.
        pub z: u32 = 1 => int(1, 16, "power of A_i applied per orthogonal iteration"),
        /// Orthogonal iterations per block (baoi), 1..=64. Default 1.
        pub tmax: u32 = 1 => int(1, 64, "orthogonal iterations per block (baoi)"),
        /// QAOI band, lower edge (relative residual), 1e-6..=1. Default 0.002.
        pub eps_low: f64 = 0.002
            => float(1e-6, 1.0, "qaoi: drop components while the relative residual is below this"),
        /// QAOI band, upper edge (relative residual), 1e-6..=1. Default 0.01.
        pub eps_high: f64 = 0.01
            => float(1e-6, 1.0, "qaoi: add components while the relative residual is above this"),
        /// Domain. Default `auto`.
        pub domain: Domain = Domain::Auto
            => choice("temporal (3d x 3d autocorrelation), spatial (n x n), or auto: the smaller (Eq. 2)"),
        /// Spatial clusters, 1..=65536 (capped at the vertex count). Default 1.
        pub clusters: u32 = 1
            => int(1, MAX_CLUSTERS as i64, "spatial clusters along connectivity, coded independently"),
        /// Bits per dictionary coefficient, 4..=24. Default 14 (§4.1).
        pub dict_bits: u8 = 14 => int(4, 24, "bits per dictionary coefficient"),
        /// Bits per feature coefficient, 4..=24. Default 12 (§4.1).
        pub feat_bits: u8 = 12 => int(4, 24, "bits per feature-vector coefficient"),
        /// Drift guard factor: 0 disables it, otherwise ≥ 1. Default 2.
        pub drift: f64 = 2.0 => float(
            0.0,
            1e6,
            "re-run SVD when an AOI block's residual exceeds drift x the last SVD block's (0 = off)"
        ),
        /// zstd level, 1..=22 (paper coding). Default 15.
        pub level: i32 = 15 => int(1, 22, "zstd compression level (paper coding)"),
        /// Coding of dictionaries and features: `toolkit` (stream version 2's, default) or
        /// `paper` (§4.1's uniform bit depths + zstd, version 1's packets).
        pub coding: Coding = Coding::Toolkit => choice(
            "toolkit (prediction, RD steps, adaptive arithmetic coding) or paper (uniform bits + zstd)"
        ),
        /// Toolkit: target error of every block (and cluster) as the KG measure does it, in
        /// percent of the block's spread about the per-frame centroids, 0.001..=100. The RD rule
        /// chooses which of the `max_k` components to keep and their steps. Default 1.
        pub kg: f64 = 1.0 => float(
            0.001,
            100.0,
            "toolkit: target error per block, KG in percent (RD rule picks components and steps)"
        ),
        /// Toolkit (svd, baoi): subspace size estimated per block, 1..=512 (capped per block at
        /// `min(e, m)`); the RD rule keeps the components that pay for themselves. Default 120
        /// (= `3·block` at the default block: full rank, so any `kg` target is reachable).
        pub max_k: u32 = 120 => int(
            1,
            512,
            "toolkit (svd, baoi): subspace size estimated per block; the RD rule keeps what pays"
        ),
        /// Toolkit: predictor of vertex fields (features or spatial dictionaries) along the
        /// cluster's mesh. Default average.
        pub mesh_predictor: Predictor = Predictor::Average
            => choice("toolkit: predictor of vertex fields along the mesh"),
        /// Toolkit: predictor of trajectories (temporal dictionaries or spatial features) along
        /// time. Default previous.
        pub time_predictor: Predictor = Predictor::Previous
            => choice("toolkit: predictor of trajectories along time (parallelogram = linear extrapolation)"),
        /// Toolkit: steps by the equal-slope rule (true) or equal distortion per entry (false,
        /// for ablations). Default true.
        pub rdq: bool = true => boolean("toolkit: per-component steps by the equal-slope rule"),
    }
    after_read: |s: PcaAoiParams| s.check_cross().map(|()| s);
    after_write: PcaAoiParams::check_cross;
}

impl PcaAoiParams {
    fn check_cross(&self) -> Result<()> {
        if self.eps_low >= self.eps_high {
            return Err(Error::parameter(
                NAME,
                "eps_low",
                format!("{} must be below eps_high = {}", self.eps_low, self.eps_high),
            ));
        }
        if self.drift != 0.0 && self.drift < 1.0 {
            return Err(Error::parameter(NAME, "drift", format!("{} must be 0 (off) or in 1..=1e6", self.drift)));
        }
        Ok(())
    }

    /// Checks every field against the ranges in [`PcaAoiParams::specs`] and the constraints
    /// between fields (`eps_low < eps_high`; `drift` is 0 or at least 1).
    pub fn validate(&self) -> Result<()> {
        self.to_param_set().map(|_| ())
    }

    fn settings(&self) -> EstimatorSettings {
        EstimatorSettings {
            mode: self.mode,
            k: match self.coding {
                Coding::Paper => self.k as usize,
                Coding::Toolkit => self.max_k as usize,
            },
            z: self.z as usize,
            tmax: self.tmax as usize,
            eps_low: self.eps_low,
            eps_high: self.eps_high,
            drift: self.drift,
        }
    }
}

/// The rate ladder of `qaoi` streams: `eps_high` from large to small residuals (`k` is only
/// QAOI's starting rank). Every step stays above the default `eps_low`.
pub fn qaoi_rate_ladder() -> RateLadder {
    RateLadder {
        param: "eps_high",
        steps: [0.2, 0.1, 0.05, 0.03, 0.02, 0.01, 0.007, 0.005, 0.003].into_iter().map(ParamValue::Float).collect(),
    }
}

/// The rate ladder of toolkit-coded streams (stream version 2's default): the target KG, from
/// coarse to fine; the RD rule picks ranks and steps for each.
pub fn toolkit_rate_ladder() -> RateLadder {
    RateLadder {
        param: "kg",
        steps: [10.0, 6.0, 4.0, 3.0, 2.0, 1.5, 1.0, 0.7, 0.5, 0.35, 0.25, 0.17, 0.12, 0.08, 0.05]
            .into_iter()
            .map(ParamValue::Float)
            .collect(),
    }
}

/// The `pca-aoi` codec.
#[derive(Debug, Clone, Copy, Default)]
pub struct PcaAoi;

impl AnimationCodec for PcaAoi {
    fn name(&self) -> &'static str {
        NAME
    }
    fn fourcc(&self) -> FourCc {
        FourCc::new(b"PAOI")
    }
    fn stream_version(&self) -> u16 {
        2
    }
    fn summary(&self) -> &'static str {
        "streaming block PCA; dictionaries tracked by adaptive orthogonal iterations (Lalos et al. 2017)"
    }
    fn param_specs(&self) -> Vec<ParamSpec> {
        PcaAoiParams::specs()
    }
    /// The error band's upper edge for `qaoi`, whose rank follows it; otherwise the target KG
    /// for the toolkit coding (the RD rule picks ranks and steps) and `k` for the paper's.
    fn rate_ladder(&self, base: &ParamSet) -> RateLadder {
        if base.choice("mode").is_ok_and(|m| m == "qaoi") {
            return qaoi_rate_ladder();
        }
        if base.choice("coding").is_ok_and(|c| c == "toolkit") {
            return toolkit_rate_ladder();
        }
        RateLadder {
            param: "k",
            steps: [1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48].into_iter().map(ParamValue::Int).collect(),
        }
    }
    /// Toolkit coding in the fixed-rank modes: the ladder over the target KG, on blocks of the
    /// default 40 frames and of 120 (a basis per block: longer blocks share it over more
    /// frames, shorter ones follow changing motion; which wins depends on the input).
    fn search_space(&self, base: &ParamSet) -> SearchSpace {
        let primary = self.rate_ladder(base);
        let toolkit = base.choice("coding").is_ok_and(|c| c == "toolkit");
        let qaoi = base.choice("mode").is_ok_and(|m| m == "qaoi");
        if !toolkit || qaoi {
            return SearchSpace::ladder_only(primary);
        }
        let block = base.int("block").unwrap_or(40);
        let mut values = vec![ParamValue::Int(block)];
        if block != 120 {
            values.push(ParamValue::Int(120));
        }
        SearchSpace { primary, secondary: vec![SearchAxis { param: "block", values }] }
    }
    fn validate(&self, params: &ParamSet) -> Result<()> {
        PcaAoiParams::from_param_set(params).map(|_| ())
    }
    /// With `mode=svd` every block's dictionary is estimated from that block alone; baoi and
    /// qaoi start from the previous block's dictionary (`dictionary::Tracker`), so their packets
    /// depend on every earlier block.
    fn independent_blocks(&self, params: &ParamSet, _frame_count: usize) -> Result<usize> {
        let p = PcaAoiParams::from_param_set(params)?;
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
    /// Issue 30: a block (one packet, analysed at once) whose modelled peak
    /// ([`block_memory`]) exceeds `budget` is shortened to the fewest equal blocks that fit;
    /// a block that fits is kept. Fails, naming the budget, when 8 frames do not fit.
    fn fit_memory(&self, params: &ParamSet, vertices: usize, frames: usize, budget: u64) -> Result<ParamSet> {
        let p = PcaAoiParams::from_param_set(params)?;
        let block = (p.block as usize).min(frames.max(1));
        if block_memory(vertices, block) <= budget {
            return Ok(params.clone());
        }
        let least = MIN_MEMORY_BLOCK.min(block);
        let Some(fits) = (least..block).rev().find(|&b| block_memory(vertices, b) <= budget) else {
            return Err(Error::parameter(
                NAME,
                "block",
                format!(
                    "a memory budget of {budget} bytes does not hold a block of {least} frames of {vertices} vertices \
                     (about {} bytes); give a larger budget",
                    block_memory(vertices, least)
                ),
            ));
        };
        let chosen = frames.div_ceil(frames.div_ceil(fits));
        let mut out = params.clone();
        out.set(&PcaAoiParams::specs(), "block", ParamValue::Int(chosen as i64))?;
        Ok(out)
    }
    fn error_bound(&self, params: &ParamSet, animation: &Animation) -> Result<ErrorBound> {
        let p = PcaAoiParams::from_param_set(params)?;
        Ok(error_bound(&p, animation))
    }
    fn new_encoder(&self, params: &ParamSet, setup: &EncoderSetup<'_>) -> Result<Box<dyn FrameEncoder>> {
        let p = PcaAoiParams::from_param_set(params)?;
        Ok(Box::new(PcaAoiEncoder::new(&p, setup)?))
    }
    fn new_decoder(&self, info: &StreamInfo, config: &[u8], limits: &Limits) -> Result<Box<dyn FrameDecoder>> {
        Ok(Box::new(PcaAoiDecoder::new(info, config, limits)?))
    }
}

/// Fewest frames per block [`AnimationCodec::fit_memory`] chooses.
pub const MIN_MEMORY_BLOCK: usize = 8;

/// Peak bytes of an encode with blocks of `frames` frames of `vertices` vertices, the whole
/// process (stream driver and self-check included): fitted on peak RSS of streamed PC2 encodes
/// (`docs/notes/issue-30.md`: 107 MiB at 10 000 vertices × 120-frame blocks, 356 MiB at
/// 40 000 × 120; ≈ 23 bytes a coordinate of the block) and at 1 000 000 vertices, where a
/// coordinate of the block costs ≈ 35 bytes and a vertex ≈ 980 besides (blocks of 27, 33 and
/// 40 frames: 3.55, 4.13 and 4.82 GiB; `docs/notes/session-2026-11-27.md` — the former 32 bytes
/// let a 4 GiB budget choose 33 frames), rounded up for headroom.
pub fn block_memory(vertices: usize, frames: usize) -> u64 {
    36 * vertices as u64 * 3 * frames as u64 + 1152 * vertices as u64 + (64 << 20)
}

/// The relative RMS bound (see the README, "Error bound"): the projection never removes more
/// than the data's spread around each frame's centroid, scaled by how far the quantized
/// dictionary is from orthonormal, plus the feature quantization error and `f32` rounding.
fn error_bound(p: &PcaAoiParams, animation: &Animation) -> ErrorBound {
    let mut stats = BoundStats::new(animation.vertex_count());
    stats.push(animation.positions());
    stats.bound(p)
}

/// What [`error_bound`] needs of the input, accumulated frame by frame (issue 30: the encoder
/// declares its bound from the frames it was pushed, so the stream driver's self-check keeps
/// no copy of the whole input). The same arithmetic in the same order as on the whole
/// animation, so both give the same bound bit for bit.
#[derive(Debug, Clone)]
struct BoundStats {
    v: usize,
    lo: [f32; 3],
    hi: [f32; 3],
    max_abs: f64,
    centered: f64,
    coords: usize,
}

impl BoundStats {
    fn new(v: usize) -> Self {
        Self { v, lo: [f32::INFINITY; 3], hi: [f32::NEG_INFINITY; 3], max_abs: 0.0, centered: 0.0, coords: 0 }
    }

    /// Adds whole frames (frame-major).
    fn push(&mut self, frames: &[f32]) {
        let v = self.v;
        if v == 0 {
            return;
        }
        for frame in frames.chunks_exact(v * 3) {
            let mut c = [0.0f64; 3];
            for q in frame.chunks_exact(3) {
                for a in 0..3 {
                    self.lo[a] = self.lo[a].min(q[a]);
                    self.hi[a] = self.hi[a].max(q[a]);
                    self.max_abs = self.max_abs.max(q[a].abs() as f64);
                    c[a] += q[a] as f64;
                }
            }
            for x in &mut c {
                *x /= v as f64;
            }
            for q in frame.chunks_exact(3) {
                for a in 0..3 {
                    self.centered += (q[a] as f64 - c[a]).powi(2);
                }
            }
            self.coords += frame.len();
        }
    }

    fn bound(&self, p: &PcaAoiParams) -> ErrorBound {
        let v = self.v;
        // As `Animation::bounding_box_diagonal` (zero for an empty animation).
        let diag = if self.coords < 3 {
            0.0
        } else {
            (0..3).map(|a| (self.hi[a] as f64 - self.lo[a] as f64).powi(2)).sum::<f64>().sqrt()
        };
        bound_from(p, v, diag, self.max_abs, self.centered, self.coords)
    }
}

fn bound_from(p: &PcaAoiParams, v: usize, diag: f64, max_abs: f64, centered: f64, coords: usize) -> ErrorBound {
    if diag == 0.0 {
        // Every vertex of every frame at one point: centered blocks are zero and the stored
        // f32 means are exact.
        return ErrorBound {
            max_coordinate_error: Some(2.0 * max_abs * f32::EPSILON as f64),
            relative_rms_error: None,
        };
    }
    let coords = coords as f64;
    let rounding = 3.0 * (max_abs + diag) * f32::EPSILON as f64;
    if p.coding == Coding::Toolkit {
        // The toolkit encoder keeps every cluster's block error below its spread about the
        // stored means (it codes nothing rather than more, see `toolkit_cluster`); the spreads
        // sum to at most the spread about each frame's centroid.
        return ErrorBound {
            max_coordinate_error: None,
            relative_rms_error: Some(((centered / coords).sqrt() + rounding) / diag),
        };
    }
    let block = p.block as usize;
    let e_max = (3 * block).max(v) as f64;
    let k_max = match p.mode {
        Mode::Qaoi => (3 * block).min(v),
        _ => (p.k as usize).min(3 * block).min(v),
    } as f64;
    let eps32 = f32::EPSILON as f64;
    let levels = |bits: u8| ((1u64 << bits) - 1) as f64;
    let eps_d = (e_max * k_max).sqrt() * (1.0 / levels(p.dict_bits) + eps32);
    let grow = (1.0 + eps_d).powi(2);
    let projection = 1.0f64.max(grow - 1.0) * (centered / coords).sqrt();
    let features = grow * k_max.sqrt() * diag * (1.0 / levels(p.feat_bits) + 2.0 * eps32);
    ErrorBound { max_coordinate_error: None, relative_rms_error: Some((projection + features + rounding) / diag) }
}

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

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Resolved {
    Temporal,
    Spatial,
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
            let coding = match params.coding {
                Coding::Paper => DecoderCoding::Paper { dict_bits: params.dict_bits, feat_bits: params.feat_bits },
                Coding::Toolkit => DecoderCoding::Toolkit {
                    mesh: params.mesh_predictor,
                    time: params.time_predictor,
                    meshes: MeshOrders::Built(enc.graphs.clone()),
                },
            };
            enc.reconstruct = Some(PcaAoiDecoder {
                coding,
                vertex_count: enc.vertex_count,
                clusters: enc.clusters.clone(),
                limits: Limits::default(),
            });
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
    /// [`AnimationCodec::error_bound`] of the frames pushed, accumulated as they arrive.
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

/// Stream version 2 config, first byte: the coding of every packet.
const CODING_PAPER: u8 = 0;
const CODING_TOOLKIT: u8 = 1;

fn plane_count(bits: u8) -> usize {
    (bits as usize + 1).div_ceil(8)
}

/// Zigzag residuals of `codes` predicted from the code `stride` places earlier.
fn push_residuals(codes: &[u32], stride: usize, out: &mut Vec<u32>) {
    for (i, &c) in codes.iter().enumerate() {
        let d = if i >= stride { c as i64 - codes[i - stride] as i64 } else { c as i64 };
        out.push(zigzag_encode(d) as u32);
    }
}

fn to_planes(values: &[u32], planes: usize, out: &mut Vec<u8>) {
    for p in 0..planes {
        out.extend(values.iter().map(|v| (v >> (8 * p)) as u8));
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
    let f = linalg::mul(e_hat.transpose(), x.as_ref());
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
        push_residuals(col, dict_stride, &mut dict_res);
    }
    let mut feat_res = Vec::with_capacity(feat_codes.len());
    for row in feat_codes.chunks(m_dim.max(1)) {
        push_residuals(row, feat_stride, &mut feat_res);
    }
    let mut raw = Vec::new();
    to_planes(&dict_res, plane_count(params.dict_bits), &mut raw);
    to_planes(&feat_res, plane_count(params.feat_bits), &mut raw);

    let mut w = ByteWriter::new();
    w.u8(match domain {
        Resolved::Temporal => 0,
        Resolved::Spatial => 1,
    });
    w.varint(k as u64);
    for &m in &means {
        w.f32(m);
    }
    for q in dict_q.iter().chain(&feat_q) {
        q.write(&mut w);
    }
    w.bytes(&entropy::compress(&raw, params.level));
    Ok((w.into_vec(), dict, k))
}

/// The two layouts of a block: (dictionary columns, feature rows).
fn layouts<'g>(domain: Resolved, mesh: &'g CausalGraph, time: &'g CausalGraph) -> (Layout<'g>, Layout<'g>) {
    match domain {
        Resolved::Temporal => (Layout::Time(time), Layout::Mesh(mesh)),
        Resolved::Spatial => (Layout::Mesh(mesh), Layout::Time(time)),
    }
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
        })
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

    /// Issue 41: charges one cluster's work to `limits` (`--max-work`) before it is done: its
    /// `(e + m)·k` coded values (`per_value` each), the product `Ê F̂` (`3d·n·k` multiply-adds)
    /// and its `3d·n` output coordinates.
    fn spend_cluster(limits: &mut Limits, values: u64, per_value: u64, d: usize, n: usize, k: usize) -> Result<()> {
        use codec_core::limits::WORK_PER_COORDINATE;
        let coords = Limits::product(&[3, d as u64, n as u64]);
        let work = values
            .saturating_mul(per_value)
            .saturating_add(coords.saturating_mul(k as u64))
            .saturating_add(coords.saturating_mul(WORK_PER_COORDINATE));
        *limits = limits.spend(NAME, "cluster reconstruction", work)?;
        Ok(())
    }

    fn decode_cluster(&self, limits: &mut Limits, payload: &[u8], d: usize, c: usize, out: &mut [f32]) -> Result<()> {
        let verts = &self.clusters[c];
        let (dict_bits, feat_bits) = match &self.coding {
            DecoderCoding::Paper { dict_bits, feat_bits } => (*dict_bits, *feat_bits),
            DecoderCoding::Toolkit { mesh, time, meshes } => {
                let MeshOrders::Built(graphs) = meshes else {
                    return Err(Error::malformed(NAME, "cluster", "mesh coding order not built"));
                };
                return self.decode_toolkit_cluster(limits, payload, d, verts, &graphs[c], *mesh, *time, out);
            }
        };
        let mut r = ByteReader::new(payload, NAME);
        let domain = read_domain(&mut r)?;
        let n = verts.len();
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
        let (pd, pf) = (plane_count(dict_bits), plane_count(feat_bits));
        let (nd, nf) = (e_dim * k, k * m_dim);
        let raw_len = nd * pd + nf * pf;
        self.limits.check_alloc(NAME, "cluster.codes", raw_len as u64)?;
        Self::spend_cluster(limits, raw_len as u64, codec_core::limits::WORK_PER_PLANE_BYTE, d, n, k)?;
        self.limits.check_alloc(
            NAME,
            "cluster.matrices",
            ((nd + nf + 3 * d * n.min(RECONSTRUCT_VERTICES)) * 8) as u64,
        )?;
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
                let mut z = 0u32;
                for p in 0..planes {
                    z |= (raw[plane_base + p * count + offset + i] as u32) << (8 * p);
                }
                let c = zigzag_decode(z as u64) + if i >= stride { v[i - stride] as i64 } else { 0 };
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
        self.write_cluster(e_hat.as_ref(), f_hat.as_ref(), &means, domain, verts, out);
        Ok(())
    }

    /// Eq. 5: `D̂ = Ê F̂`, plus the stored means, into the packet's frames. The product is
    /// formed [`RECONSTRUCT_VERTICES`] vertices at a time (issue 30: whole, it is `3d × n` f64
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
        out: &mut [f32],
    ) -> Result<()> {
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
        self.limits.check_alloc(
            NAME,
            "cluster.matrices",
            ((e_dim * k + k * m_dim + 3 * d * n.min(RECONSTRUCT_VERTICES)) * 8) as u64,
        )?;
        self.limits.check_alloc(NAME, "frame chains", (d as u64).saturating_mul(64))?;
        let values = ((e_dim + m_dim) as u64).saturating_mul(k as u64);
        Self::spend_cluster(limits, values, codec_core::limits::WORK_PER_CODED_VALUE, d, n, k)?;
        let time = CausalGraph::chain(d, time_predictor == Predictor::Parallelogram);
        let (dict_layout, feat_layout) = layouts(domain, mesh, &time);
        let settings = coding::Settings { mesh: mesh_predictor, time: time_predictor, rdq: true };
        let bytes = r.take(r.remaining(), "cluster.codes")?;
        let (e_hat, f_hat) = coding::decode(bytes, &steps, dict_layout, feat_layout, &settings)?;
        self.write_cluster(e_hat.as_ref(), f_hat.as_ref(), &means, domain, verts, out);
        Ok(())
    }
}

/// Vertices of a cluster whose reconstruction [`PcaAoiDecoder::write_cluster`] forms at once:
/// `3d × 4096` f64 is at most 384 MiB at the longest block (4096 frames), 3.75 MiB at the
/// default 40. Clusters up to this size are reconstructed in one product, as before.
const RECONSTRUCT_VERTICES: usize = 4096;

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

/// The two dimensions of the data matrix of a cluster of `n` vertices over `d` frames in
/// `domain`; the rank `k` is at most the smaller.
fn matrix_dims(domain: Resolved, n: usize, d: usize) -> (usize, usize) {
    match domain {
        Resolved::Temporal => (3 * d, n),
        Resolved::Spatial => (n, 3 * d),
    }
}

/// The domain byte of a cluster payload.
fn read_domain(r: &mut ByteReader<'_>) -> Result<Resolved> {
    match r.u8("cluster.domain")? {
        0 => Ok(Resolved::Temporal),
        1 => Ok(Resolved::Spatial),
        x => Err(r.malformed("cluster.domain", format!("{x} is neither 0 (temporal) nor 1 (spatial)"))),
    }
}

/// The `3d` per-frame means of a cluster payload.
fn read_means(r: &mut ByteReader<'_>, d: usize) -> Result<Vec<f64>> {
    let means_bytes = r.take(3 * d * 4, "cluster.means")?;
    let mut means = Vec::with_capacity(3 * d);
    for b in means_bytes.chunks_exact(4) {
        let m = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        if !m.is_finite() {
            return Err(r.malformed("cluster.means", format!("{m} is not finite")));
        }
        means.push(m as f64);
    }
    Ok(means)
}

impl FrameDecoder for PcaAoiDecoder {
    fn decode_packet(&mut self, packet: &Packet) -> Result<Vec<f32>> {
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
        let mut out = vec![0f32; len as usize];
        self.build_meshes()?;
        let mut r = ByteReader::new(&packet.data, NAME);
        // Issue 41: each cluster's work is charged (`--max-work`) before it is decoded.
        let mut limits = self.limits;
        for c in 0..self.clusters.len() {
            let payload = r.length_prefixed("cluster.payload")?;
            self.decode_cluster(&mut limits, payload, d, c, &mut out)?;
        }
        r.expect_end("packet")?;
        self.limits = limits;
        Ok(out)
    }
}

#[cfg(test)]
mod chunk_tests {
    use super::*;

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
