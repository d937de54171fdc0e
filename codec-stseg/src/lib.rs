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

mod coding;
mod linalg;
mod segment;

use codec_core::bytes::{zigzag_decode, zigzag_encode, ByteReader, ByteWriter};
use codec_core::toolkit::predict::Predictor;
use codec_core::{
    entropy, Animation, AnimationCodec, EncodedPacket, EncoderSetup, Error, ErrorBound, FourCc, FrameDecoder,
    FrameEncoder, Limits, Packet, ParamSet, ParamSpec, ParamValue, Quantizer, RateLadder, Result, StreamInfo,
};
use faer::Mat;
use rayon::prelude::*;

pub use segment::{segment_animation, BlockKind, Segment, Segmentation};

use linalg::{gram, mul, pcs_for_persistence, sym_eig_desc};
use segment::{frame_diagonal, MeshGraph, Segmenter, NEGLIGIBLE_AMPLITUDE};

pub(crate) const NAME: &str = "stseg";
/// Most vertex groups a stream may declare (labels are stored as bytes).
pub const MAX_GROUPS: usize = 16;

/// What the PCA of a vertex group subtracts before its decomposition, and so what the
/// persistence rate ω is a share of (§4.4, Eq. 5 and Eq. 8).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Centering {
    /// The paper's reading: `X` (3|V| coordinate rows × |τ| frame columns) is centred by its
    /// per-frame mean `X̄` (one value per frame, the `+|τ_i|` term of Eq. 8), as a PCA whose
    /// observations are the coordinate rows does. The energy is then dominated by the shape
    /// itself, so ω = 0.99 keeps very few components (Table 1's KG ≈ 5 %).
    Frame,
    /// Per-coordinate temporal mean (the mean shape, 3|V| values per group) subtracted: ω is a
    /// share of the motion energy only, and ω = 0.99 keeps many more components.
    Vertex,
    /// Nothing subtracted (an SVD of `X`); the first component carries the shape.
    None,
    /// Per-frame mean of each axis subtracted (the centroid trajectory, `3|τ_i|` values per
    /// group): like `Frame`, but a translation is removed exactly instead of entering the PCs.
    FrameAxis,
}

impl Centering {
    /// Parameter names, in stream-code order (code = index).
    pub const NAMES: &'static [&'static str] = &["none", "vertex", "frame", "frame-axis"];

    /// The parameter / stream name.
    pub fn name(self) -> &'static str {
        Self::NAMES[self.code() as usize]
    }
    /// Stream code (config byte).
    pub fn code(self) -> u8 {
        match self {
            Self::None => 0,
            Self::Vertex => 1,
            Self::Frame => 2,
            Self::FrameAxis => 3,
        }
    }
    /// From a stream code.
    pub fn from_code(c: u8) -> Option<Self> {
        Some(match c {
            0 => Self::None,
            1 => Self::Vertex,
            2 => Self::Frame,
            3 => Self::FrameAxis,
            _ => return None,
        })
    }
    /// From a parameter name.
    pub fn from_name(n: &str) -> Option<Self> {
        Self::NAMES.iter().position(|&x| x == n).and_then(|i| Self::from_code(i as u8))
    }
}

codec_core::param_choice!(Centering, inherent);

/// Which change detector ends a segment besides Alg. 2's PC counts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Detector {
    /// The paper's: the initial cut (§4.1) runs only at the start of a block with no reused
    /// grouping, on its first γ_init frames, and sets the reference of Alg. 2; no cut → case (I).
    Paper,
    /// Beyond the paper: the §4.1 cut scans the whole block (ranges of γ_init frames, half
    /// overlapping, one kernel scale per block, central splits only) and the first cut ends the
    /// segment; with no cut the block is grouped on its first γ_init frames and runs to γ_max
    /// unless Alg. 2's counts change.
    Scan,
}

codec_core::param_choice!(Detector { Paper = "paper", Scan = "scan" });

/// How a segment's PCA is coded (`coding` parameter).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Coding {
    /// Stream version 3's coding (issue 15, `coding.rs`): per-vertex basis fields predicted
    /// along each group's mesh order, mean and coefficient trajectories predicted in time,
    /// one step per component by the equal-slope RD rule, context-adaptive arithmetic coding.
    Toolkit,
    /// The paper's coding (§4.4, §5.1): uniform `bits` / `coef_bits` quantizers, zigzag run
    /// deltas, zstd — stream version 2's packets, bit for bit.
    Paper,
}

impl Coding {
    /// Parameter names, in stream-code order (code = index).
    pub const NAMES: &'static [&'static str] = &["paper", "toolkit"];
    /// The parameter name.
    pub fn name(self) -> &'static str {
        Self::NAMES[self.code() as usize]
    }
    /// Stream code (config byte of version 3).
    pub fn code(self) -> u8 {
        match self {
            Self::Paper => 0,
            Self::Toolkit => 1,
        }
    }
    /// From a stream code.
    pub fn from_code(c: u8) -> Option<Self> {
        match c {
            0 => Some(Self::Paper),
            1 => Some(Self::Toolkit),
            _ => None,
        }
    }
    /// From a parameter name.
    pub fn from_name(n: &str) -> Option<Self> {
        Self::NAMES.iter().position(|&x| x == n).and_then(|i| Self::from_code(i as u8))
    }
}

codec_core::param_choice!(Coding, inherent);

codec_core::declare_params! {
    codec: NAME;
    /// Typed parameters of `stseg` (names follow the paper's notation).
    #[derive(Debug, Clone, Copy, PartialEq)]
    pub struct StsegParams {
        /// Information persistence rate ω of the PCA that codes each group and segment (§4.4):
        /// the rate knob. Default 0.99.
        pub omega: f64 = 0.99 => float(0.5, 0.999999, "PCA information persistence rate ω (rate knob)"),
        /// Persistence rate used by the segmentation (Alg. 1 group models, Alg. 2 PC counts). The
        /// paper uses one ω for both; keeping them apart makes the segmentation, and so the packet
        /// structure, the same at every rung of the rate ladder. Default 0.9 (the paper's is ω =
        /// 0.99): with frame-axis counts it rarely ends a segment early, which measured best on
        /// samba and horse-gallop (README, issue 13).
        pub omega_seg: f64 = 0.9 => float(0.5, 0.999999, "persistence rate of the segmentation (Alg. 1, 2)"),
        /// What each group's PCA (coding and Alg. 2 counts) subtracts first, i.e. what ω is a
        /// share of. Default [`Centering::FrameAxis`], the reading of §4.4 / Eq. 8 that lands
        /// nearest Table 1's KG at ω = 0.99 (measured, see README).
        pub centering: Centering = Centering::FrameAxis
            => choice("what the PCA subtracts: frame (paper: per-frame mean), vertex (mean shape) or none"),
        /// What the PCA of Alg. 2's PC counts subtracts. The paper uses one PCA for both (set it
        /// equal to `centering`). Default [`Centering::FrameAxis`]: with `omega_seg = 0.9` the
        /// counts rarely change, segments run to γ_max, and that measured best on real data
        /// (README); [`Centering::Vertex`] with `omega_seg = 0.99` reacts to motion changes.
        pub seg_centering: Centering = Centering::FrameAxis
            => choice("what the PCA of Alg. 2's PC counts subtracts (same choices as centering)"),
        /// Change detector: [`Detector::Paper`] (default) or [`Detector::Scan`].
        pub detector: Detector = Detector::Paper
            => choice("paper (initial cut at block starts) or scan (the cut scans the whole block)"),
        /// Smoothing window `w` of the initial cut (§4.1). Default 5.
        pub w: u32 = 5 => int(2, 32, "initial-cut smoothing window w (frames)"),
        /// Range γ_init of the initial cut. Default 20.
        pub gamma_init: u32 = 20 => int(8, 128, "initial-cut range γ_init (frames), ≥ w + 4"),
        /// Maximal segment length γ_max (§4.3). Default 50.
        pub gamma_max: u32 = 50
            => int(8, MAX_SEGMENT_FRAMES as i64, "maximal segment length γ_max (frames), ≥ gamma_init"),
        /// Kernel parameter λ of Eq. 3, relative to the median squared window distance. Default 1.
        pub lambda: f64 = 1.0
            => float(0.01, 100.0, "kernel parameter λ (Eq. 3), in units of the median distance"),
        /// Smallest maximum-mean discrepancy that counts as an initial cut. Default 0.1.
        pub cut_threshold: f64 = 0.1 => float(0.0, 2.0, "smallest MMD that counts as an initial cut"),
        /// Maximal number of vertex groups N_g (§4.2). Default 4.
        pub groups: u32 = 4 => int(1, MAX_GROUPS as i64, "maximal number of vertex groups N_g"),
        /// Share ρ of the edges taken as rigid (§4.2.1). Default 0.2.
        pub rho: f64 = 0.2 => float(0.01, 0.99, "share ρ of edges taken as rigid"),
        /// Rings η of neighbours added to each group before its PCA (§4.4). Default 2.
        pub eta: u32 = 2 => int(0, 8, "η-ring overlap of vertex groups for boundary consistency"),
        /// Bits of the mean shapes and PCA bases. Default 12.
        pub bits: u8 = 12 => int(6, 20, "bits of mean shapes and PCA bases"),
        /// Bits of the PCA coefficients (orthonormal rows, values in [−1, 1]). Default 12.
        pub coef_bits: u8 = 12 => int(6, 20, "bits of PCA coefficients"),
        /// zstd level (paper coding: everything; toolkit coding: the step table). Default 19.
        pub level: i32 = 19 => int(1, 22, "zstd compression level"),
        /// How the PCA is coded: [`Coding::Toolkit`] (default, stream version 3) or
        /// [`Coding::Paper`] (version 2's bytes; what the paper-reproduction tables use).
        pub coding: Coding = Coding::Toolkit => choice(
            "toolkit (prediction, RD steps, adaptive arithmetic coding; stream v3) or paper (bit depths + zstd)"
        ),
        /// Toolkit coding: RMS quantization error relative to the truncation error the PCA left
        /// (budget `D = quant²·E_trunc` per segment). Default 0.25.
        pub quant: f64 = 0.25
            => float(0.01, 4.0, "toolkit: quantization RMS error target relative to the truncation error"),
        /// Toolkit coding: predictor of the per-vertex fields (basis columns, `vertex` mean)
        /// along each group's mesh order. Default [`Predictor::Average`].
        pub mesh_predictor: Predictor = Predictor::Average
            => choice("toolkit: predictor of basis fields along the group's mesh order"),
        /// Toolkit coding: predictor of the trajectories (coefficient rows, per-frame means) in
        /// time. Default [`Predictor::Previous`].
        pub time_predictor: Predictor = Predictor::Previous
            => choice("toolkit: predictor of coefficient and mean trajectories in time"),
        /// Toolkit coding: noise shaping `α` of the basis columns along the group's mesh order
        /// (`toolkit::predict`: neighbouring vertices err alike, which STED rewards; encoder only,
        /// the stream is unchanged). Default 0.
        pub shaping: f64 = 0.0
            => float(0.0, 0.95, "toolkit: noise shaping α of the basis along the mesh (encoder only)"),
    }
    after_read: |s: StsegParams| s.check_cross().map(|()| s);
    after_write: StsegParams::check_cross;
}

impl StsegParams {
    /// Checks every field against the ranges in [`StsegParams::specs`] and the constraints
    /// between them (`gamma_init ≥ w + 4`, `gamma_max ≥ gamma_init`).
    pub fn validate(&self) -> Result<()> {
        self.to_param_set().map(|_| ())
    }

    fn check_cross(&self) -> Result<()> {
        if self.gamma_init < self.w + 4 {
            return Err(Error::parameter(
                NAME,
                "gamma_init",
                format!(
                    "{} must be at least w + 4 = {} (the cut needs two windows each side)",
                    self.gamma_init,
                    self.w + 4
                ),
            ));
        }
        if self.gamma_max < self.gamma_init {
            return Err(Error::parameter(
                NAME,
                "gamma_max",
                format!("{} must be at least gamma_init = {}", self.gamma_max, self.gamma_init),
            ));
        }
        Ok(())
    }

    /// Largest number of frames in one packet.
    fn max_segment(&self) -> usize {
        self.gamma_max.max(self.gamma_init) as usize
    }
}

/// Longest segment (packet) in frames: the upper end of `gamma_max`'s range. Decoders of
/// toolkit-coded packets refuse longer ones (it bounds the reconstruction work per value).
pub(crate) const MAX_SEGMENT_FRAMES: usize = 1024;

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

/// The `stseg` codec.
#[derive(Debug, Clone, Copy, Default)]
pub struct Stseg;

impl AnimationCodec for Stseg {
    fn name(&self) -> &'static str {
        NAME
    }
    fn fourcc(&self) -> FourCc {
        FourCc::new(b"STSG")
    }
    fn stream_version(&self) -> u16 {
        // 2: config carries the centering; the mean is per frame for `centering = frame`.
        // 3: config adds the coding (paper = version 2's packets, toolkit = `coding.rs`) and
        // the toolkit's predictors.
        3
    }
    fn summary(&self) -> &'static str {
        "spatio-temporal segmentation (initial cut, vertex groups, PC-count boundaries) + per-segment PCA"
    }
    fn param_specs(&self) -> Vec<ParamSpec> {
        StsegParams::specs()
    }
    fn rate_ladder(&self, _base: &ParamSet) -> RateLadder {
        RateLadder {
            param: "omega",
            steps: [0.9, 0.95, 0.98, 0.99, 0.995, 0.998, 0.999, 0.9995, 0.9998, 0.9999, 0.99995, 0.99999, 0.999999]
                .into_iter()
                .map(ParamValue::Float)
                .collect(),
        }
    }
    fn validate(&self, params: &ParamSet) -> Result<()> {
        StsegParams::from_param_set(params).map(|_| ())
    }
    fn error_bound(&self, params: &ParamSet, animation: &Animation) -> Result<ErrorBound> {
        let p = StsegParams::from_param_set(params)?;
        let bound = match p.coding {
            Coding::Paper => relative_rms_bound(&p, animation),
            Coding::Toolkit => toolkit_rms_bound(&p, animation),
        };
        Ok(ErrorBound { max_coordinate_error: None, relative_rms_error: bound })
    }
    /// Issue 41 (10c): stseg's segments are chosen by the data (up to `gamma_max` frames, cut
    /// by the detector), so there is no block to shorten: a budget below [`encode_memory`] is
    /// refused up front, naming the need.
    fn fit_memory(&self, params: &ParamSet, vertices: usize, frames: usize, budget: u64) -> Result<ParamSet> {
        let p = StsegParams::from_param_set(params)?;
        let window = frames.min((p.gamma_max + p.gamma_init) as usize);
        let need = encode_memory(vertices, frames, window);
        let what = format!("{frames} frames of {vertices} vertices, segments of up to {} frames", p.gamma_max);
        codec_core::memory::check_budget(NAME, budget, need, &what, "")?;
        Ok(params.clone())
    }
    fn new_encoder(&self, params: &ParamSet, setup: &EncoderSetup<'_>) -> Result<Box<dyn FrameEncoder>> {
        let p = StsegParams::from_param_set(params)?;
        Ok(Box::new(StsegEncoder {
            params: p,
            segmenter: Segmenter::new(p, setup.topology),
            graph: MeshGraph::new(setup.topology),
            decoder: StsegDecoder::for_params(&p, setup.topology),
            vertex_count: setup.topology.vertex_count(),
            total: setup.frame_count,
            want_reconstruction: setup.want_reconstruction,
            pending: Vec::new(),
            next_frame: 0,
        }))
    }
    fn new_decoder(&self, info: &StreamInfo, config: &[u8], limits: &Limits) -> Result<Box<dyn FrameDecoder>> {
        if !(2..=3).contains(&info.codec_version) {
            return Err(Error::Unsupported {
                context: NAME.into(),
                detail: format!("stream version {} (this build decodes 2 and 3)", info.codec_version),
            });
        }
        let mut r = ByteReader::new(config, NAME);
        let bits = r.u8("config.bits")?;
        let coef_bits = r.u8("config.coef_bits")?;
        let centering_code = r.u8("config.centering")?;
        let (coding, predictors) = if info.codec_version >= 3 {
            let c = r.u8("config.coding")?;
            let coding =
                Coding::from_code(c).ok_or_else(|| r.malformed("config.coding", format!("{c} is not 0..=1")))?;
            let mut pred = |field| -> Result<Predictor> {
                let c = r.u8(field)?;
                Predictor::from_code(c).ok_or_else(|| r.malformed(field, format!("{c} is not 0..=3")))
            };
            let mesh = pred("config.mesh_predictor")?;
            let time = pred("config.time_predictor")?;
            (coding, coding::Predictors { mesh, time })
        } else {
            (Coding::Paper, coding::Predictors { mesh: Predictor::Zero, time: Predictor::Zero })
        };
        r.expect_end("config")?;
        let centering = Centering::from_code(centering_code)
            .ok_or_else(|| r.malformed("config.centering", format!("{centering_code} is not 0..=3")))?;
        for (field, b) in [("config.bits", bits), ("config.coef_bits", coef_bits)] {
            if !(6..=20).contains(&b) {
                return Err(r.malformed(field, format!("{b} is outside 6..=20")));
            }
        }
        Ok(Box::new(StsegDecoder {
            bits,
            coef_bits,
            centering,
            coding,
            predictors,
            vertex_count: info.vertex_count(),
            limits: *limits,
            graphs: coding::Graphs::new(info.vertex_count(), info.topology.triangles()),
        }))
    }
}

/// The declared relative RMS bound (see README "Error bound"). With `D` the animation's
/// bounding-box diagonal, `G` = `groups`, `T` the longest segment, `δ = T/(2^coef_bits − 1)`:
/// - truncation at persistence ω: the discarded energy of each group's η-extended, centred
///   block is ≤ (1−ω) of its energy; a vertex lies in at most `G` extended groups and each
///   centred coordinate is ≤ `D` away, so this term is ≤ `√((1−ω)·G/3)·D` (RMS per coordinate);
/// - coefficient quantization (each entry off by ≤ half a step of [−1, 1]): `‖W − B̂ᵀ‖₂ ≤ δ`,
///   adding ≤ `δ·D`;
/// - basis quantization: `|A| ≤ √T·D/(1−δ)`, half a step per entry, times `‖B̂‖₂ ≤ 1+δ`:
///   ≤ `√T·(1+δ)/((1−δ)(2^bits−1))·D`;
/// - mean quantization: ≤ `D/(2(2^bits−1))`; plus f32 rounding.
///
/// These add (Minkowski). `None` (no promise) when `δ ≥ 1/2`.
fn relative_rms_bound(p: &StsegParams, animation: &Animation) -> Option<f64> {
    let t = p.max_segment() as f64;
    let delta = t / ((1u64 << p.coef_bits) - 1) as f64;
    if delta >= 0.5 {
        return None;
    }
    let qa = ((1u64 << p.bits) - 1) as f64;
    let trunc = ((1.0 - p.omega) * p.groups as f64 / 3.0).sqrt();
    let basis = t.sqrt() * (1.0 + delta) / ((1.0 - delta) * qa);
    let diag = animation.bounding_box_diagonal();
    let (lo, hi) = animation.bounding_box();
    let mag = lo.iter().chain(&hi).fold(0.0f64, |m, &x| m.max((x as f64).abs()));
    if diag <= 0.0 {
        return Some(1e-12);
    }
    // Range of all coordinate values, every axis together: a frame-centred entry is within it.
    let all_range =
        (0..3).map(|c| hi[c] as f64).fold(f64::MIN, f64::max) - (0..3).map(|c| lo[c] as f64).fold(f64::MAX, f64::min);
    // `s`: bound on a vertex's centred 3-vector, relative to D; `mean`: mean quantization.
    let (s, mean) = match p.centering {
        Centering::Vertex => (1.0, 0.5 / qa),
        Centering::Frame => (3f64.sqrt() * all_range / diag, 0.5 * all_range / (qa * diag)),
        // A centroid-centred vertex is within D of the centroid.
        Centering::FrameAxis => (1.0, 0.5 / qa),
        Centering::None => (3f64.sqrt() * mag / diag, 0.0),
    };
    let rounding = 4.0 * mag * f32::EPSILON as f64 / diag;
    Some(s * (trunc + delta + basis) + mean + rounding + 1e-12)
}

/// The declared relative RMS bound of the toolkit coding (README "Error bound"). Per group of a
/// segment the error is at most `√E_tr + Σ_i √d_i` — the LS fit's residual is at most that of
/// the unquantized basis with the quantized mean and coefficients, i.e. truncation + mean
/// error + `Σ_j ‖A_j‖‖δB_j‖`, and the basis error adds `Σ_j ‖δA_j‖‖B̂_j‖` — where the `d_i` are
/// the component distortions the RD rule keeps within `D = quant²·Σ max(E_tr, 10⁻⁴·(1−ω)E)`.
/// With at most `N = 3 + 2T` components per group (Cauchy–Schwarz) and `(a+b)² ≤ 2a² + 2b²`,
/// the squared error is ≤ `2(1 + N·quant²)·(1−ω)·ΣE`, and `ΣE` is bounded as in
/// [`relative_rms_bound`]'s truncation term (a vertex in at most `G` extended groups).
fn toolkit_rms_bound(p: &StsegParams, animation: &Animation) -> Option<f64> {
    let t = p.max_segment() as f64;
    let diag = animation.bounding_box_diagonal();
    if diag <= 0.0 {
        return Some(1e-12);
    }
    let (lo, hi) = animation.bounding_box();
    let mag = lo.iter().chain(&hi).fold(0.0f64, |m, &x| m.max((x as f64).abs()));
    let all_range =
        (0..3).map(|c| hi[c] as f64).fold(f64::MIN, f64::max) - (0..3).map(|c| lo[c] as f64).fold(f64::MAX, f64::min);
    let s = match p.centering {
        Centering::Vertex | Centering::FrameAxis => 1.0,
        Centering::Frame => 3f64.sqrt() * all_range / diag,
        Centering::None => 3f64.sqrt() * mag / diag,
    };
    let n = 3.0 + 2.0 * t;
    let trunc = ((1.0 - p.omega) * p.groups as f64 / 3.0).sqrt();
    // A block below the negligible energy keeps no component: its whole centred energy is error.
    let negligible = segment::NEGLIGIBLE_AMPLITUDE * (p.groups as f64).sqrt();
    let rounding = 4.0 * mag * f32::EPSILON as f64 / diag;
    Some(s * (trunc + negligible) * (2.0 * (1.0 + n * p.quant * p.quant)).sqrt() + rounding + 1e-12)
}

/// Fixed-size temporal blocks with a single vertex group: the segmentation of the paper's
/// "Adapted PCA" baseline (§5.3.1), for comparisons with [`encode_with_segmentation`].
pub fn fixed_block_segmentation(vertex_count: usize, frame_count: usize, block: usize) -> Segmentation {
    let block = block.max(1);
    let segments = (0..frame_count)
        .step_by(block)
        .map(|first_frame| Segment {
            first_frame,
            frame_count: block.min(frame_count - first_frame),
            kind: BlockKind::NoCut,
            detected_boundary: false,
            window: None,
            group_count: 1,
            labels: vec![0; vertex_count],
        })
        .collect();
    Segmentation { segments }
}

/// Codes `animation` with the PCA stage of `stseg` (§4.4) over a given segmentation (for
/// example [`fixed_block_segmentation`]) and returns the packets, in the `stseg` stream
/// format, and the decoded frames. [`Stseg`]'s encoder is this with [`segment_animation`].
pub fn encode_with_segmentation(
    animation: &Animation,
    params: &StsegParams,
    segmentation: &Segmentation,
) -> Result<(Vec<Packet>, Vec<f32>)> {
    params.validate()?;
    let graph = MeshGraph::new(animation.topology());
    let v = animation.vertex_count();
    let n3 = v * 3;
    let mut next = 0;
    let mut packets = Vec::new();
    let mut rec = Vec::with_capacity(animation.positions().len());
    let mut dec = StsegDecoder::for_params(params, animation.topology());
    for seg in &segmentation.segments {
        if seg.first_frame != next
            || seg.frame_count == 0
            || next + seg.frame_count > animation.frame_count()
            || seg.labels.len() != v
            || seg.group_count == 0
            || seg.group_count > MAX_GROUPS
            || seg.labels.iter().any(|&l| l as usize >= seg.group_count)
        {
            return Err(Error::parameter(
                NAME,
                "segmentation",
                format!("segment at frame {} is inconsistent", seg.first_frame),
            ));
        }
        let block = &animation.positions()[next * n3..(next + seg.frame_count) * n3];
        let data = encode_segment(params, &graph, &mut dec.graphs, seg, block)?;
        rec.extend_from_slice(&dec.decode(&data, seg.frame_count)?);
        packets.push(Packet { first_frame: next as u32, frame_count: seg.frame_count as u32, keyframe: true, data });
        next += seg.frame_count;
    }
    if next != animation.frame_count() {
        return Err(Error::parameter(
            NAME,
            "segmentation",
            format!("covers {next} of {} frames", animation.frame_count()),
        ));
    }
    Ok((packets, rec))
}

struct StsegEncoder {
    params: StsegParams,
    segmenter: Segmenter,
    graph: MeshGraph,
    /// Rebuilds the reconstruction; its coding orders are shared with the toolkit encoder.
    decoder: StsegDecoder,
    vertex_count: usize,
    total: usize,
    want_reconstruction: bool,
    pending: Vec<f32>,
    next_frame: usize,
}

impl StsegEncoder {
    fn drain(&mut self) -> Result<Vec<EncodedPacket>> {
        let n3 = self.vertex_count * 3;
        let mut out = Vec::new();
        while let Some(seg) = self.segmenter.next(&self.pending, self.total - self.next_frame, self.next_frame)? {
            let block: Vec<f32> = self.pending.drain(..seg.frame_count * n3).collect();
            let data = encode_segment(&self.params, &self.graph, &mut self.decoder.graphs, &seg, &block)?;
            let reconstruction =
                if self.want_reconstruction { Some(self.decoder.decode(&data, seg.frame_count)?) } else { None };
            let packet = Packet {
                first_frame: self.next_frame as u32,
                frame_count: seg.frame_count as u32,
                keyframe: true,
                data,
            };
            self.next_frame += seg.frame_count;
            out.push(EncodedPacket { packet, reconstruction });
        }
        Ok(out)
    }
}

impl FrameEncoder for StsegEncoder {
    fn config(&self) -> Vec<u8> {
        let p = &self.params;
        vec![p.bits, p.coef_bits, p.centering.code(), p.coding.code(), p.mesh_predictor.code(), p.time_predictor.code()]
    }

    fn push_frames(&mut self, frames: &[f32]) -> Result<Vec<EncodedPacket>> {
        self.pending.extend_from_slice(frames);
        self.drain()
    }

    fn finish(&mut self) -> Result<Vec<EncodedPacket>> {
        let out = self.drain()?;
        if !self.pending.is_empty() {
            return Err(Error::Unsupported {
                context: NAME.into(),
                detail: "frames left after the last segment".into(),
            });
        }
        Ok(out)
    }
}

/// Byte planes needed for zigzag differences of `bits`-bit codes.
fn plane_count(bits: u8) -> usize {
    (bits as usize + 1).div_ceil(8)
}

/// Appends codes as zigzag differences from the previous code of the same run.
fn push_run(out: &mut Vec<u32>, codes: impl Iterator<Item = u32>) {
    let mut prev = 0i64;
    for c in codes {
        out.push(zigzag_encode(c as i64 - prev) as u32);
        prev = c as i64;
    }
}

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

/// Number of mean quantizers and mean values of one group of `n` vertices over `frames`.
pub(crate) fn mean_layout(centering: Centering, n: usize, frames: usize) -> (usize, usize) {
    match centering {
        Centering::Vertex => (3, 3 * n),
        Centering::Frame => (1, frames),
        Centering::FrameAxis => (3, 3 * frames),
        Centering::None => (0, 0),
    }
}

/// The centred data matrix of a group (rows: vertex-major coordinates of `rows`, columns:
/// frames) and the mean that was subtracted (per row for [`Centering::Vertex`], per frame for
/// [`Centering::Frame`], empty for [`Centering::None`]).
pub(crate) fn centred_block(
    centering: Centering,
    rows: &[u32],
    block: &[f32],
    n3: usize,
    frames: usize,
) -> (Mat<f64>, Vec<f64>) {
    let x_at = |r: usize, t: usize| block[t * n3 + rows[r / 3] as usize * 3 + r % 3] as f64;
    let nr = rows.len() * 3;
    match centering {
        Centering::Vertex => {
            let mean: Vec<f64> =
                (0..nr).map(|r| (0..frames).map(|t| x_at(r, t)).sum::<f64>() / frames as f64).collect();
            (Mat::from_fn(nr, frames, |r, t| x_at(r, t) - mean[r]), mean)
        }
        Centering::Frame => {
            let mean: Vec<f64> =
                (0..frames).map(|t| (0..nr).map(|r| x_at(r, t)).sum::<f64>() / nr.max(1) as f64).collect();
            (Mat::from_fn(nr, frames, |r, t| x_at(r, t) - mean[t]), mean)
        }
        Centering::FrameAxis => {
            // mean[t·3 + c]
            let n = rows.len().max(1) as f64;
            let mean: Vec<f64> = (0..frames * 3)
                .map(|tc| (0..rows.len()).map(|i| x_at(i * 3 + tc % 3, tc / 3)).sum::<f64>() / n)
                .collect();
            (Mat::from_fn(nr, frames, |r, t| x_at(r, t) - mean[t * 3 + r % 3]), mean)
        }
        Centering::None => (Mat::from_fn(nr, frames, x_at), Vec::new()),
    }
}

/// The ω-persistence PCA of one group of one segment (§4.4): the number of components `k`
/// and the leading eigenvectors of the Gram matrix of the η-extended, centred block.
fn group_pca(
    p: &StsegParams,
    graph: &MeshGraph,
    own: &[u32],
    block: &[f32],
    frames: usize,
) -> Result<(usize, Mat<f64>)> {
    group_pca_energy(p, graph, own, block, frames).map(|(k, vecs, _, _)| (k, vecs))
}

/// [`group_pca`] plus the truncation energy it leaves and the total energy of the η-extended,
/// centred block (sums of the discarded and of all eigenvalues).
pub(crate) fn group_pca_energy(
    p: &StsegParams,
    graph: &MeshGraph,
    own: &[u32],
    block: &[f32],
    frames: usize,
) -> Result<(usize, Mat<f64>, f64, f64)> {
    let n3 = graph.vertex_count() * 3;
    let ext = graph.grow_rings(own, p.eta as usize);
    let (xe, _) = centred_block(p.centering, &ext, block, n3, frames);
    let scale = frame_diagonal(&block[..n3]);
    let negligible = (NEGLIGIBLE_AMPLITUDE * scale).powi(2) * (ext.len() * 3 * frames) as f64;
    let (vals, vecs) = sym_eig_desc(gram(xe.as_ref()).as_ref(), "segment PCA")?;
    let k = pcs_for_persistence(&vals, p.omega, negligible).min(frames);
    let total: f64 = vals.iter().map(|x| x.max(0.0)).sum();
    let trunc: f64 = vals[k.min(vals.len())..].iter().map(|x| x.max(0.0)).sum();
    Ok((k, vecs, trunc, total))
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
                push_run(&mut values, axis.iter().map(|&x| q.quantize(x)));
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
            push_run(&mut values, m.iter().map(|&x| q.quantize(x)));
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
                push_run(&mut values, axis.iter().map(|&x| q.quantize(x)));
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
            push_run(&mut values, (0..n).map(|i| q.quantize(col[i * 3 + c])));
        }
        a_q.push(q);
    }
    for j in 0..k {
        push_run(&mut values, b_codes[j * frames..(j + 1) * frames].iter().copied());
    }
    Ok(GroupCode { mean_q, a_q, b_q, values })
}

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

/// Packet payload of one segment in the coding `p.coding` names (layouts in README.md).
fn encode_segment(
    p: &StsegParams,
    graph: &MeshGraph,
    graphs: &mut coding::Graphs,
    seg: &Segment,
    block: &[f32],
) -> Result<Vec<u8>> {
    match p.coding {
        Coding::Paper => encode_segment_paper(p, graph, seg, block),
        Coding::Toolkit => coding::encode_segment(p, graph, graphs, seg, block),
    }
}

/// The paper coding's packet payload (stream version 2's layout).
fn encode_segment_paper(p: &StsegParams, graph: &MeshGraph, seg: &Segment, block: &[f32]) -> Result<Vec<u8>> {
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
    let planes = plane_count(p.bits.max(p.coef_bits));
    let mut raw = Vec::with_capacity(v + values.len() * planes);
    raw.extend_from_slice(&seg.labels);
    for pl in 0..planes {
        raw.extend(values.iter().map(|&x| (x >> (8 * pl)) as u8));
    }
    w.bytes(&entropy::compress(&raw, p.level));
    Ok(w.into_vec())
}

struct StsegDecoder {
    bits: u8,
    coef_bits: u8,
    centering: Centering,
    coding: Coding,
    predictors: coding::Predictors,
    vertex_count: usize,
    limits: Limits,
    /// Coding orders of the toolkit coding (built on first use, after the limits check).
    graphs: coding::Graphs,
}

impl StsegDecoder {
    /// The decoder of the stream the encoder writes with `p` (for its reconstruction).
    fn for_params(p: &StsegParams, topology: &codec_core::Topology) -> Self {
        Self {
            bits: p.bits,
            coef_bits: p.coef_bits,
            centering: p.centering,
            coding: p.coding,
            predictors: coding::Predictors { mesh: p.mesh_predictor, time: p.time_predictor },
            vertex_count: topology.vertex_count(),
            // The encoder's own reconstruction: memory checked as a decoder's, work unbounded
            // (a long input's packets would add up past a decode's budget).
            limits: Limits { max_work: u64::MAX, ..Limits::default() },
            graphs: coding::Graphs::new(topology.vertex_count(), topology.triangles()),
        }
    }

    fn decode(&mut self, data: &[u8], frames: usize) -> Result<Vec<f32>> {
        let v = self.vertex_count;
        let mut r = ByteReader::new(data, NAME);
        let case = r.u8("case")?;
        if BlockKind::from_case(case).is_none() {
            return Err(r.malformed("case", format!("{case} is not a block case 1..=4")));
        }
        let group_count = r.varint("group_count")? as usize;
        if group_count == 0 || group_count > MAX_GROUPS.min(v.max(1)) {
            return Err(
                r.malformed("group_count", format!("{group_count} is outside 1..={}", MAX_GROUPS.min(v.max(1))))
            );
        }
        let out = match self.coding {
            Coding::Paper => self.decode_paper(&mut r, frames, group_count)?,
            Coding::Toolkit => coding::decode_segment(
                &mut r,
                frames,
                v,
                self.centering,
                self.predictors,
                &mut self.graphs,
                &mut self.limits,
                group_count,
            )?,
        };
        // Corrupt quantizer ranges or steps can overflow f32; say so here rather than emit infinities.
        if out.iter().any(|x| !x.is_finite()) {
            return Err(Error::malformed(NAME, "values", "decoded coordinates are not finite"));
        }
        Ok(out)
    }

    /// The paper coding's packet after its case and group count (stream version 2's layout).
    fn decode_paper(&mut self, r: &mut ByteReader<'_>, frames: usize, group_count: usize) -> Result<Vec<f32>> {
        let v = self.vertex_count;
        let max_k = frames.min(3 * v) as u64;
        let n_mean = mean_layout(self.centering, 0, 0).0;
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
                let want = if i < n_mean + k { self.bits } else { self.coef_bits };
                if q.bits() != want {
                    return Err(r.malformed("quantizer", format!("{} bits, stream config says {want}", q.bits())));
                }
                qs.push(q);
            }
            ks.push(k);
            quants.push(qs);
        }
        let planes = plane_count(self.bits.max(self.coef_bits));
        let sum_k: usize = ks.iter().sum();
        let max_k_used = ks.iter().copied().max().unwrap_or(0);
        let bound = (v as u64)
            + planes as u64
                * (3 * v as u64 * (1 + max_k_used as u64) + (sum_k + 3 * group_count) as u64 * frames as u64);
        self.limits.check_alloc(NAME, "values", bound.saturating_mul(8))?;
        // Issue 41: the inflated bytes are charged before inflating (`--max-work`).
        self.limits =
            self.limits.spend(NAME, "values", bound.saturating_mul(codec_core::limits::WORK_PER_PLANE_BYTE))?;
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
            .map(|(m, &k)| mean_layout(self.centering, m.len(), frames).1 + 3 * m.len() * k + k * frames)
            .sum();
        if raw.len() != v + planes * count {
            return Err(Error::malformed(
                NAME,
                "values",
                format!("{} bytes, expected {}", raw.len() - v, planes * count),
            ));
        }
        // ... and the reconstruction (`frames·3·n·k` per group, plus the output) before it starts.
        let work = members
            .iter()
            .zip(&ks)
            .map(|(m, &k)| coding::reconstruction_work(frames, m.len(), k))
            .fold(0u64, u64::saturating_add);
        self.limits = self.limits.spend(NAME, "reconstruction", work)?;
        let planes_raw = &raw[v..];
        let mut idx = 0usize;
        let mut next_run = |len: usize| -> Vec<u32> {
            let mut prev = 0i64;
            let mut out = Vec::with_capacity(len);
            for _ in 0..len {
                let mut z = 0u32;
                for pl in 0..planes {
                    z |= (planes_raw[pl * count + idx] as u32) << (8 * pl);
                }
                idx += 1;
                prev += zigzag_decode(z as u64);
                out.push(prev.clamp(0, u32::MAX as i64) as u32);
            }
            out
        };
        let n3 = v * 3;
        let mut out = vec![0f32; frames * n3];
        for ((own, &k), qs) in members.iter().zip(&ks).zip(&quants) {
            let n = own.len();
            // Vertex: mean[c][i]; Frame: mean[0][t]; None: no mean.
            let mean: Vec<Vec<f64>> = match self.centering {
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
                    (0..3)
                        .map(|_| next_run(n).into_iter().map(|q| qs[n_mean + j].dequantize(q) as f64).collect())
                        .collect()
                })
                .collect();
            let b: Vec<Vec<f64>> = (0..k)
                .map(|j| next_run(frames).into_iter().map(|q| qs[n_mean + k + j].dequantize(q) as f64).collect())
                .collect();
            reconstruct_group(self.centering, own, &mean, &a, &b, frames, n3, &mut out);
        }
        Ok(out)
    }
}

/// Writes one group's `mean + Σ_j A_j·B_j` into `out` (frames × 3V), in f64 rounded to f32:
/// `mean` per centering (vertex `[c][i]`, frame `[0][t]`, frame-axis `[c][t]`, none empty),
/// `a[j][c][i]` over the group's vertices `own` (ascending), `b[j][t]`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn reconstruct_group(
    centering: Centering,
    own: &[u32],
    mean: &[Vec<f64>],
    a: &[Vec<Vec<f64>>],
    b: &[Vec<f64>],
    frames: usize,
    n3: usize,
    out: &mut [f32],
) {
    let k = b.len();
    for t in 0..frames {
        for c in 0..3 {
            for (i, &vi) in own.iter().enumerate() {
                let mut x = match centering {
                    Centering::Vertex => mean[c][i],
                    Centering::Frame => mean[0][t],
                    Centering::FrameAxis => mean[c][t],
                    Centering::None => 0.0,
                };
                for j in 0..k {
                    x += a[j][c][i] * b[j][t];
                }
                out[t * n3 + vi as usize * 3 + c] = x as f32;
            }
        }
    }
}

impl FrameDecoder for StsegDecoder {
    fn decode_packet(&mut self, packet: &Packet) -> Result<Vec<f32>> {
        let frames = packet.frame_count as usize;
        self.limits.check_alloc(NAME, "the decoded packet", (frames as u64) * self.vertex_count as u64 * 12)?;
        self.decode(&packet.data, frames)
    }
}

#[cfg(test)]
mod tests;
