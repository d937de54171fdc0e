//! `hosvd`: HO-SVD / Tucker compression of mesh animations with rigid-motion removal, after
//! Romaszewski, Gawron & Opozda, *Compression of animated 3D models using HO-SVD*
//! (`../shared/papers/004_6114345d2e52f0e6.txt`).
//!
//! Per packet (the whole sequence by default, or temporal blocks of `block` frames):
//! 1. §2.3 — per frame, the least-squares affine map to frame 0 is removed (`rigid=true`);
//!    its inverse (12 numbers per frame) is stored.
//! 2. §2.4, Alg. 1 — HO-SVD of the `K × 3 × F` tensor, each factor from the smaller Gram matrix
//!    of its unfolding ([`tensor::leading_left`]).
//! 3. §2.6, Alg. 3–4 — `(v, f)` chosen for the space saving `ss` (Eq. 12–13) by the `diagonal`,
//!    `iterative` or `exhaustive` strategy, or given explicitly; truncation to `(v, 3, f)`.
//! 4. Beyond the paper: optional HOOI sweeps; quantization of factors and core with steps
//!    balanced against the truncation error; zstd entropy stage.
//!
//! See `README.md` for the stream layout and every choice the paper leaves open.

pub mod coding;
pub mod motion;
mod spectra;
pub mod strategy;
pub mod tensor;

use std::time::Instant;

use codec_core::bytes::{zigzag_decode, zigzag_encode, ByteReader, ByteWriter};
use codec_core::toolkit::order::{self, CausalGraph};
use codec_core::toolkit::predict::Predictor;
use codec_core::toolkit::regress::Neighbourhoods;
use codec_core::{
    entropy, Animation, AnimationCodec, DistortionKind, EncodedPacket, EncoderSetup, Error, ErrorBound, FourCc,
    FrameDecoder, FrameEncoder, Limits, Packet, ParamSet, ParamSpec, ParamValue, Quantizer, RateLadder, Result,
    SearchAxis, SearchSpace, StreamInfo, Topology,
};
use faer::Mat;

use strategy::Dims;
pub use strategy::Strategy;
use tensor::{Affine, Model, Tensor, Tucker};

const NAME: &str = "hosvd";

/// Largest bit depth given to one quantized column: keeps zigzag deltas of codes inside 32 bits.
const MAX_BITS: u8 = 30;

/// Packet flag bit 1 (stream version 2): the operator is coded with the toolkit (`coding.rs`).
const FLAG_TOOLKIT: u8 = 2;

/// Packet flag bit 2 (stream version 3): the per-frame transforms are quantized and
/// arithmetic coded (`motion.rs`) in a block after the codes, instead of raw `f32` in the side
/// block. Written with the toolkit coding and `rigid`.
const FLAG_MOTION: u8 = 4;

/// Packet flag bit 3 (stream version 3): `v` smoothing levels of the `U1` columns follow the
/// codes (and motion) block (`coding::Smoother`). Written with the toolkit coding and `denoise`.
const FLAG_DENOISE: u8 = 8;

/// Packet flag bit 4 (stream version 4): `v` bytes follow the smoothing levels (or the codes /
/// motion block), each `U1` column's predictor (`coding::ColumnMode`: 0 the stream's mesh
/// predictor, 1 local regression on the leading columns (`codec_core::toolkit::regress`),
/// 2 parallelogram). Written with the toolkit coding and `regress`.
const FLAG_REGRESS: u8 = 16;

/// Packet flag bit 5 (stream version 6, issue 41): the packet ends with the `3 × f32` centre
/// the encoder subtracted from every position before the decomposition; the decoder adds it
/// to every decoded vertex ([`HosvdDecoder::decode_packet`]). Written by every version 6
/// encoder, whatever the coding.
const FLAG_CENTRE: u8 = 32;

/// Bytes of the centre at the end of a `FLAG_CENTRE` packet.
const CENTRE_BYTES: usize = 12;

/// Stream version the encoder writes (6: `FLAG_CENTRE`); versions 1 to 5 keep decoding.
pub const STREAM_VERSION: u16 = 6;

codec_core::declare_params! {
    codec: NAME;
    /// Typed parameters of `hosvd`.
    #[derive(Debug, Clone, Copy, PartialEq)]
    pub struct HosvdParams {
        /// Requested space saving `SS = 1 − CR` (Eq. 13) as a fraction, 0..=0.9999. Default 0.9.
        pub ss: f64 = 0.9 => float(
            0.0,
            0.9999,
            "space saving 1 - CR of the paper's size model (Eq. 12-13), e.g. 0.95 keeps 5%"
        ),
        /// How `(v, f)` is chosen for `ss`. Default iterative.
        pub strategy: Strategy = Strategy::Iterative
            => choice("choice of (v, f) for ss: diagonal (v = f), iterative (Alg. 4), exhaustive"),
        /// Explicit mode-1 rank (0 = from `ss`); must be given together with `f`.
        pub v: u32 = 0 => int(0, MAX_RANK, "explicit mode-1 (vertex) rank, 0 = from ss; clamped to min(K, 3F)"),
        /// Explicit mode-3 rank (0 = from `ss`); must be given together with `v`.
        pub f: u32 = 0 => int(0, MAX_RANK, "explicit mode-3 (frame) rank, 0 = from ss; clamped to min(F, 3K)"),
        /// Remove per-frame motion (rotation or affine, `affine`) before the decomposition (§2.3).
        /// Default true.
        pub rigid: bool = true => boolean(
            "remove the per-frame motion to frame 0 first (rotation + translation, or affine: 12 numbers/frame)"
        ),
        /// With `rigid`: fit an affine map (true, the paper's §2.3) or only a rotation +
        /// translation (false; orthogonal Procrustes). Default false since the seventh session
        /// of issue 26: on the four dev animations at `ss` 0.97 and 0.9 the rotation gave the
        /// smaller stream in 7 of 8 cases and the lower KG in 7 of 8 (`docs/notes/`), a
        /// rotation keeps every edge length (an affine map stretches them: STED), and it
        /// does not amplify the decomposition error (the affine maps' gains reach 2.6, README).
        pub affine: bool = false => boolean(
            "with rigid: least-squares affine map (true, the paper) or rotation + translation only (false)"
        ),
        /// With `rigid` and the toolkit coding: bits of the transforms' quantization steps (the
        /// linear part's step is `2^-bits`), 0 = automatic: 12 without an edge-noise cap, else
        /// the coarsest step whose error stays within that cap (`motion::auto_bits`). Written in
        /// the stream's motion block, so any choice decodes with every version 3+ decoder.
        pub motion_bits: u32 = 0 => int(
            0,
            motion::MAX_BITS as i64,
            "with rigid: bits of the transforms' steps (linear step 2^-bits; 0 = auto: 12, or within the edge_noise cap; else 6..=24)"
        ),
        /// HOOI refinement sweeps after the truncated HO-SVD (0 = plain HO-SVD). Default 0.
        pub hooi_iters: u32 = 0 => int(0, 50, "HOOI refinement sweeps after the HO-SVD (beyond the paper)"),
        /// Target quantization RMS error relative to the truncation error, 0.01..=10. Default 0.25.
        pub quant: f64 = 0.25
            => float(0.01, 10.0, "quantization RMS error target relative to the truncation error"),
        /// Frames per independently decomposed packet (0 = the whole sequence). Default 0.
        pub block: u32 = 0 => int(
            0,
            1 << 20,
            "frames per independently decomposed packet, 0 = whole sequence (bounds memory)"
        ),
        /// Alg. 4 samples per level `s`, 3..=64. Default 5.
        pub samples: u32 = 5 => int(3, 64, "iterative strategy: samples per level (s in Alg. 4)"),
        /// Alg. 4 recursion limit `I`, 1..=32. Default 4.
        pub depth: u32 = 4 => int(1, 32, "iterative strategy: recursion limit (I in Alg. 4)"),
        /// zstd level, 1..=22. Default 19.
        pub level: i32 = entropy::DEFAULT_LEVEL => int(1, 22, "zstd compression level"),
        /// How factors and core are coded: the toolkit (stream version 2's coding, default) or
        /// the paper's (version 1: one rule-of-thumb step per column, byte planes + zstd).
        pub coding: Coding = Coding::Toolkit => choice(
            "toolkit (mesh/time prediction, RD steps, adaptive arithmetic coding) or paper (v1 coding)"
        ),
        /// Toolkit: predictor of mode-1 factor entries along the mesh. Default average.
        pub mesh_predictor: Predictor = Predictor::Average
            => choice("toolkit: predictor of mode-1 factor entries along the mesh traversal"),
        /// Toolkit: predictor of mode-3 factor entries along time. Default previous.
        pub time_predictor: Predictor = Predictor::Previous => choice(
            "toolkit: predictor of mode-3 factor entries along time (parallelogram = linear extrapolation)"
        ),
        /// Toolkit: noise shaping of the mode-1 factor along the mesh, 0..=0.95. Default 0.
        pub shaping: f64 = 0.0 => float(
            0.0,
            0.95,
            "toolkit: noise shaping of the mode-1 factor (neighbouring vertices err alike; 0 = off)"
        ),
        /// Toolkit: per-component steps by the equal-slope rule (true) or the paper coding's rule
        /// of thumb (false). Default true.
        pub rdq: bool = true
            => boolean("toolkit: per-component steps by the equal-slope rule (false: rule of thumb)"),
        /// Toolkit: weight of the edge error (STED-like) in the mode-1 factor's RD distortion,
        /// 0..=1. Default 0.
        pub edge_weight: f64 = 0.0 => float(
            0.0,
            1.0,
            "toolkit: weight of edge (STED-like) error in the mode-1 factor's RD distortion"
        ),
        /// Toolkit: cap on the quantization noise, as an RMS per coordinate relative to the RMS
        /// edge length of the mesh, 0..=1 (0 = no cap). Default 0. STED (relative edge-length
        /// changes) is dominated by per-vertex quantization noise, which `quant` sizes relative to
        /// the truncation error, so at low rates the noise reaches a large fraction of an edge.
        pub edge_noise: f64 = 0.0 => float(
            0.0,
            1.0,
            "cap on the quantization noise (RMS per coordinate) relative to the RMS edge length (0 = no cap)"
        ),
        /// Toolkit (stream version 3): the decoder smooths each mode-1 factor column over the mesh
        /// after dequantizing it, with a strength the encoder picks per column (`coding::Smoother`);
        /// the RD rule sees the smoothed error, so it can choose coarser steps. Default true.
        pub denoise: bool = true => boolean(
            "toolkit: decoder smooths each mode-1 factor column over the mesh, strength chosen per column (v3)"
        ),
        /// Toolkit (stream version 4): each mode-1 factor column gets the predictor of fewest bits
        /// among the mesh predictor, the parallelogram and (after the first column) a local linear
        /// regression on the leading columns (up to 4) over its already coded two-ring neighbours.
        /// Beyond the paper. Default true.
        pub regress: bool = true => boolean(
            "toolkit: per mode-1 factor column the cheapest of mesh predictor, parallelogram, local regression on the leading columns (v4)"
        ),
        /// Test hook, not a codec parameter (always false from a [`ParamSet`]): regression on every
        /// mode-1 column with stream version 4's unguarded fit, to drive the encoder into the
        /// divergence of issue 26 and prove its closed-loop check falls back
        /// (`coding::Settings::force_unguarded_regression`).
        #[doc(hidden)]
        pub force_unguarded_regression: bool = false => hidden,
    }
    after_read: |s: HosvdParams| s.check_cross().map(|()| s);
    before_write: HosvdParams::check_cross;
}

/// Coding of the quantized operator (`coding` parameter).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Coding {
    /// Stream version 2: prediction along mesh and time, RD quantization, adaptive
    /// arithmetic coding (`coding.rs`).
    Toolkit,
    /// Stream version 1's coding (written inside a version 2 stream with flag bit 1 clear).
    Paper,
}

codec_core::param_choice!(Coding { Toolkit = "toolkit", Paper = "paper" });

const MAX_RANK: i64 = 1 << 24;

impl HosvdParams {
    /// Checks every field against the ranges in [`HosvdParams::specs`] and the cross-field
    /// rule (`v` and `f` are given together or not at all); errors name the field and range.
    pub fn validate(&self) -> Result<()> {
        self.to_param_set().map(|_| ())
    }

    fn check_cross(&self) -> Result<()> {
        if (self.v == 0) != (self.f == 0) {
            let (name, set, other) = if self.v == 0 { ("v", "f", self.f) } else { ("f", "v", self.v) };
            return Err(Error::parameter(
                NAME,
                name,
                format!("{set}={other} is set but {name}=0: give both v and f (1..={MAX_RANK}) or neither"),
            ));
        }
        if self.motion_bits != 0 && self.motion_bits < motion::MIN_AUTO_BITS {
            return Err(Error::parameter(
                NAME,
                "motion_bits",
                format!(
                    "{}: 0 (automatic) or {}..={} (coarser steps can make a frame's transform singular)",
                    self.motion_bits,
                    motion::MIN_AUTO_BITS,
                    motion::MAX_BITS
                ),
            ));
        }
        Ok(())
    }
}

/// Fewest frames per block [`AnimationCodec::fit_memory`] chooses: below it the frame mode has
/// too little to reduce (see [`block_params`]) and the per-block side data dominates.
pub const MIN_MEMORY_BLOCK: usize = 8;

/// Peak bytes an encode of blocks of `frames` frames of `vertices` vertices holds, the whole
/// process (the stream driver's copy of the block and its self-check included): a model fitted
/// to measured peak RSS (`docs/notes/issue-30.md`, "hosvd memory model"), rounded up.
pub fn block_memory(vertices: usize, frames: usize) -> u64 {
    let coordinates = vertices as u64 * 3 * frames as u64;
    let k = vertices as u64;
    // Per coordinate of the block: f32 copies (pending, self-check) and f64 working tensors.
    // Per vertex: topology, coding order, mesh graph. Plus the program itself.
    BYTES_PER_COORDINATE * coordinates + BYTES_PER_VERTEX * k + BASE_BYTES
}

// Fitted on `synth flag:200x200x300` (40 000 vertices) encoded with block = 25, 50, 100, 150
// and 300 frames: 290, 441, 799, 1110 and 2049 MiB peak RSS, 56 bytes a coordinate of the block
// and about 130 MiB besides; 10 000 vertices × 300 frames: 552 MiB. Rounded up for headroom.
const BYTES_PER_COORDINATE: u64 = 64;
const BYTES_PER_VERTEX: u64 = 2048;
const BASE_BYTES: u64 = 64 << 20;

/// The `hosvd` codec.
#[derive(Debug, Clone, Copy, Default)]
pub struct Hosvd;

/// FourCC of the stream.
pub const FOURCC: FourCc = FourCc::new(b"HOSV");

impl AnimationCodec for Hosvd {
    fn name(&self) -> &'static str {
        NAME
    }
    fn fourcc(&self) -> FourCc {
        FOURCC
    }
    fn stream_version(&self) -> u16 {
        STREAM_VERSION
    }
    fn summary(&self) -> &'static str {
        "HO-SVD / Tucker (v, 3, f) truncation with rigid-motion removal (Romaszewski et al.)"
    }
    fn param_specs(&self) -> Vec<ParamSpec> {
        HosvdParams::specs()
    }
    fn rate_ladder(&self, _base: &ParamSet) -> RateLadder {
        // Larger space saving = smaller stream: the ladder walks ss downwards. 0.998, 0.96 and
        // 0.94 (issue 15, session 3) give very small ranks and a finer walk where STED and KG
        // targets fall. A ladder over (ss, edge_noise) holding both the KG-best and the
        // STED-best series is not size-monotone on every input (conformance), see the README.
        // 0.6 (issue 26, fifth session): between 0.7 and 0.5 a stream grows ~4× (horse-gallop:
        // 1.96 → 8.0 bpvf), and an envelope interpolated across that gap at KG ≤ 0.1 promised
        // 7% fewer bits than any stream measured there.
        let steps = [0.998, 0.995, 0.99, 0.98, 0.97, 0.96, 0.95, 0.94, 0.93, 0.9, 0.85, 0.8, 0.7, 0.6, 0.5];
        RateLadder { param: "ss", steps: steps.iter().map(|&s| ParamValue::Float(s)).collect() }
    }
    /// The ladder over `ss`, on each combination of the three levers that decide between the
    /// KG-efficient and the STED-efficient streams (issue 15, sessions 3 and 5): the edge
    /// (STED-like) distortion in the mode-1 factor's RD rule (`edge_weight` 0 or 1; toolkit
    /// coding), affine motion removal (`rigid`; removing it helps STED on articulated motion)
    /// and the cap on the quantization noise relative to the edge length (`edge_noise` 0,
    /// 0.012 — between the best hand-picked series' 0.009 and 0.015 — or 0.02, which the
    /// looser STED targets want: at STED ≤ 0.1 it needs 4 % fewer bytes on horse-gallop and
    /// 12 % fewer on samba than 0.012; sixth session of 2026-11-27). The default
    /// configuration comes first. (Fixing `edge_weight = 1` halves the search but costs 17%
    /// at KG ≤ 0.5 on samba: issue 26 note.)
    fn search_space(&self, base: &ParamSet) -> SearchSpace {
        let toolkit = base.choice("coding").is_ok_and(|c| c == "toolkit");
        let mut secondary = Vec::new();
        if toolkit {
            secondary.push(SearchAxis {
                param: "edge_weight",
                values: vec![ParamValue::Float(0.0), ParamValue::Float(1.0)],
            });
        }
        secondary.push(SearchAxis { param: "rigid", values: vec![ParamValue::Bool(true), ParamValue::Bool(false)] });
        secondary.push(SearchAxis {
            param: "edge_noise",
            values: vec![ParamValue::Float(0.0), ParamValue::Float(0.012), ParamValue::Float(0.02)],
        });
        SearchSpace { primary: self.rate_ladder(base), secondary }
    }
    /// What a target search walks (issue 26: a `--target` search must cost few encodes). Every
    /// measured target search so far chose within these halves of the space: KG targets
    /// `edge_noise = 0` (14 of 14 RobotExpressive clips at KG ≤ 0.5, samba, horse-gallop),
    /// STED targets `edge_weight = 1` with `edge_noise = 0.012` (samba and horse-gallop at STED
    /// ≤ 0.05 and ≤ 0.1, where the other configurations needed 4–25% more bytes;
    /// `docs/notes/issue-26-search.md`) or 0.02 (better at STED ≤ 0.1: see
    /// [`Self::search_space`]). `rigid` stays searched: it wins either way depending on the
    /// motion. For STED the first configuration is `edge_noise = 0.012, rigid = false`, the
    /// usual winner.
    fn search_space_for(&self, base: &ParamSet, kind: DistortionKind) -> SearchSpace {
        let toolkit = base.choice("coding").is_ok_and(|c| c == "toolkit");
        let rigid = |first: bool| SearchAxis {
            param: "rigid",
            values: vec![ParamValue::Bool(first), ParamValue::Bool(!first)],
        };
        let mut secondary = Vec::new();
        match kind {
            DistortionKind::Position => {
                if toolkit {
                    secondary.push(SearchAxis {
                        param: "edge_weight",
                        values: vec![ParamValue::Float(0.0), ParamValue::Float(1.0)],
                    });
                }
                secondary.push(rigid(true));
            }
            DistortionKind::Shape => {
                if toolkit {
                    secondary.push(SearchAxis { param: "edge_weight", values: vec![ParamValue::Float(1.0)] });
                }
                secondary.push(SearchAxis {
                    param: "edge_noise",
                    values: vec![ParamValue::Float(0.012), ParamValue::Float(0.02)],
                });
                secondary.push(rigid(false));
            }
        }
        SearchSpace { primary: self.rate_ladder(base), secondary }
    }
    /// STED targets start at `ss = 0.97`: the dev animations meet STED ≤ 0.05–0.1 at `ss`
    /// 0.92–0.99 (samba 0.96–0.99, horse-gallop 0.92–0.96, pcow 0.93–0.98, chicken-crossing
    /// 0.96–0.985), three to five ladder steps above the default 0.9 that KG targets start
    /// from. Saves two to three encodes per STED search on samba.
    fn search_start(&self, _base: &ParamSet, kind: DistortionKind) -> Option<ParamValue> {
        (kind == DistortionKind::Shape).then_some(ParamValue::Float(0.97))
    }
    fn validate(&self, params: &ParamSet) -> Result<()> {
        HosvdParams::from_param_set(params).map(|_| ())
    }
    /// Each temporal block is decomposed and coded on its own (`HosvdEncoder::code`: the
    /// block's frames, its length, and whether it is the whole animation); `block=0` is one
    /// block of the whole sequence.
    fn independent_blocks(&self, params: &ParamSet, frame_count: usize) -> Result<usize> {
        let p = HosvdParams::from_param_set(params)?;
        Ok(if p.block == 0 { frame_count.max(1) } else { p.block as usize })
    }
    /// With `block=0` (the whole sequence in one decomposition), the frames per block that fit
    /// `budget` by [`block_memory`]; equal blocks (`⌈F / n⌉` frames for the fewest `n` that fit),
    /// so no short remainder block is decomposed on its own. An explicit `block` is kept.
    fn fit_memory(&self, params: &ParamSet, vertices: usize, frames: usize, budget: u64) -> Result<ParamSet> {
        let p = HosvdParams::from_param_set(params)?;
        if p.block != 0 || frames == 0 {
            return Ok(params.clone());
        }
        let fits = (1..=frames).rev().find(|&b| block_memory(vertices, b) <= budget);
        let block = match fits {
            Some(b) if b >= frames => return Ok(params.clone()),
            Some(b) if b >= MIN_MEMORY_BLOCK.min(frames) => frames.div_ceil(frames.div_ceil(b)),
            _ => {
                let need = block_memory(vertices, MIN_MEMORY_BLOCK.min(frames));
                return Err(Error::parameter(
                    NAME,
                    "block",
                    format!(
                        "a memory budget of {budget} bytes does not hold a block of {} frames of {vertices} vertices \
                         (about {need} bytes); give a larger budget",
                        MIN_MEMORY_BLOCK.min(frames)
                    ),
                ));
            }
        };
        let mut out = params.clone();
        out.set(&HosvdParams::specs(), "block", ParamValue::Int(block as i64))?;
        Ok(out)
    }
    /// Runs the encoder's analysis and returns the bound derived in [`BlockStats::error_bound`]
    /// (truncation error from the core energies plus worst-case quantization terms, mapped
    /// through the stored inverse transforms). Not a measured error: it never looks at the
    /// reconstruction.
    fn error_bound(&self, params: &ParamSet, animation: &Animation) -> Result<ErrorBound> {
        let p = HosvdParams::from_param_set(params)?;
        let k = animation.vertex_count();
        let per_block = if p.block == 0 { animation.frame_count() } else { p.block as usize };
        let mut total2 = 0.0;
        let whole = per_block >= animation.frame_count();
        let graph = mesh_graph(&p, animation.topology());
        for chunk in animation.positions().chunks(per_block * k * 3) {
            let bp = block_params(&p, k, chunk.len() / (3 * k).max(1), whole)?;
            let b = encode_block(chunk, k, &bp, &graph, false)?;
            total2 += b.stats.error_bound.powi(2);
        }
        let frob = total2.sqrt();
        let n = (animation.positions().len()) as f64;
        let diag = animation.bounding_box_diagonal();
        let rel = if diag > 0.0 { frob / n.sqrt() / diag } else { f64::INFINITY };
        Ok(ErrorBound { max_coordinate_error: Some(frob), relative_rms_error: Some(rel) })
    }
    fn new_encoder(&self, params: &ParamSet, setup: &EncoderSetup<'_>) -> Result<Box<dyn FrameEncoder>> {
        let p = HosvdParams::from_param_set(params)?;
        Ok(Box::new(HosvdEncoder::new(p, setup.topology, setup.frame_count, setup.want_reconstruction)))
    }
    fn new_decoder(&self, info: &StreamInfo, config: &[u8], limits: &Limits) -> Result<Box<dyn FrameDecoder>> {
        let mut r = ByteReader::new(config, NAME);
        let block = r.u32("config.block")?;
        r.expect_end("config")?;
        if block == 0 {
            return Err(r.malformed("config.block", "0 frames per block"));
        }
        if !(1..=STREAM_VERSION).contains(&info.codec_version) {
            return Err(Error::Unsupported {
                context: NAME.into(),
                detail: format!("stream version {} (this build decodes 1 to {STREAM_VERSION})", info.codec_version),
            });
        }
        // Version 2 packets may use the toolkit coding, which needs the mesh's coding order:
        // built on the first packet that uses it, after checking its size against the limits.
        let graph = if info.codec_version >= 2 {
            MeshOrder::Pending(info.topology.triangles().to_vec())
        } else {
            MeshOrder::Unavailable
        };
        Ok(Box::new(HosvdDecoder { k: info.vertex_count(), limits: *limits, graph, version: info.codec_version }))
    }
}

/// What the encoder measured and decided for one packet.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlockStats {
    /// Frames in the block.
    pub frames: usize,
    /// Mode-1 rank kept.
    pub v: usize,
    /// Mode-3 rank kept.
    pub f: usize,
    /// Rank-search error evaluations.
    pub evaluations: usize,
    /// No `(v, f)` met the `ss` budget and `(1, 1)` was used.
    pub over_budget: bool,
    /// Numbers in the paper's size model (`S^(hosvd)/d_s` + `12F`); `× 4` bytes with `d_s = 4`.
    pub paper_numbers: usize,
    /// `‖X‖²` of the normalised tensor.
    pub norm2: f64,
    /// Squared truncation error in the normalised space, `‖X‖² − ‖C̃‖²` (before quantization).
    pub truncation_error2: f64,
    /// Upper bound of `‖T − T̂‖_F` for this block in original coordinates, derived from the
    /// truncation error, the quantizers' half steps and the transforms' gains.
    pub error_bound: f64,
    /// Packet payload bytes.
    pub payload_bytes: usize,
    /// Mode-1 columns the search put in regression mode whose closed loop failed on the
    /// decoded leads and were re-coded with the mesh predictor (issue 26; 0 normally).
    pub regression_fallbacks: usize,
    /// Seconds in motion removal + Gram factorizations (+ full core when searching).
    pub decompose_seconds: f64,
    /// Seconds in the rank search.
    pub search_seconds: f64,
    /// Seconds in HOOI sweeps.
    pub hooi_seconds: f64,
    /// Seconds quantizing, entropy coding and reconstructing.
    pub code_seconds: f64,
}

/// One encoded block: payload, the decoder's reconstruction (if asked), statistics.
#[derive(Debug, Clone)]
pub struct EncodedBlock {
    /// Packet payload.
    pub payload: Vec<u8>,
    /// `frames × K × 3`, bit-identical to what the decoder produces (when requested).
    pub reconstruction: Option<Vec<f32>>,
    /// Statistics.
    pub stats: BlockStats,
}

/// Unquantized truncated HO-SVD (+ optional HOOI) of frames `F × K × 3`, reconstructed in
/// original coordinates: the reference the quantized stream is measured against, and what
/// `tools/compare_tensorly.py` checks against an independent implementation.
pub fn truncated_reconstruction(
    positions: &[f32],
    k: usize,
    v: usize,
    f: usize,
    rigid: bool,
    hooi_iters: usize,
) -> Result<(Vec<f32>, f64)> {
    truncated_reconstruction_with(positions, k, v, f, rigid, true, hooi_iters)
}

/// [`truncated_reconstruction`] with the choice of affine (`true`) or rotation-only motion.
pub fn truncated_reconstruction_with(
    positions: &[f32],
    k: usize,
    v: usize,
    f: usize,
    rigid: bool,
    affine: bool,
    hooi_iters: usize,
) -> Result<(Vec<f32>, f64)> {
    let frames = positions.len() / (3 * k);
    let (transforms, x) = normalise(positions, k, frames, rigid, affine);
    let t = Tensor::new(&x, k, frames);
    let (v, f) = (v.clamp(1, t.max_v()), f.clamp(1, t.max_f()));
    let u2 = t.mode2()?;
    let mut tk = Tucker {
        u1: tensor::leading_left(t.x1.as_ref(), v)?,
        u3: tensor::leading_left(t.x3.as_ref(), f)?,
        core: Vec::new(),
        u2,
    };
    tk.hooi(&t, hooi_iters)?;
    let err2 = (t.norm2 - tk.core_norm2()).max(0.0);
    let m = Model {
        k,
        frames,
        v,
        f,
        u1: row_major(&tk.u1),
        u2: std::array::from_fn(|i| tk.u2[(i / 3, i % 3)]),
        u3: row_major(&tk.u3),
        core: tk.core,
        transforms,
    };
    Ok((tensor::reconstruct(&m), err2))
}

fn row_major(m: &Mat<f64>) -> Vec<f64> {
    let mut out = Vec::with_capacity(m.nrows() * m.ncols());
    for i in 0..m.nrows() {
        for j in 0..m.ncols() {
            out.push(m[(i, j)]);
        }
    }
    out
}

/// RMS distance of frame 0's vertices from their centroid (the translation step's scale).
fn rms_radius(positions: &[f32], k: usize) -> f64 {
    let frame = &positions[..(3 * k).min(positions.len())];
    let n = (frame.len() / 3).max(1) as f64;
    let mean: [f64; 3] = std::array::from_fn(|j| frame.chunks_exact(3).map(|p| p[j] as f64).sum::<f64>() / n);
    let s: f64 = frame.chunks_exact(3).map(|p| (0..3).map(|j| (p[j] as f64 - mean[j]).powi(2)).sum::<f64>()).sum();
    (s / n).sqrt()
}

fn normalise(positions: &[f32], k: usize, frames: usize, rigid: bool, affine: bool) -> (Vec<Affine>, Vec<f64>) {
    normalise_centred(positions, k, frames, rigid, affine, [0.0; 3])
}

/// [`normalise`] of `positions − centre` (f64, exact; [`tensor::remove_affine_motion_centred`]).
fn normalise_centred(
    positions: &[f32],
    k: usize,
    frames: usize,
    rigid: bool,
    affine: bool,
    centre: [f64; 3],
) -> (Vec<Affine>, Vec<f64>) {
    if rigid {
        tensor::remove_affine_motion_centred(positions, k, frames, affine, centre, &mut |proposed, fallback, _| {
            if tensor::mat3_inverse(&proposed.m.map(|v| v as f64)).is_some() {
                proposed
            } else {
                fallback
            }
        })
    } else {
        let x = positions.chunks_exact(3).flat_map(|p| (0..3).map(move |j| p[j] as f64 - centre[j])).collect();
        (vec![Affine::IDENTITY; frames], x)
    }
}

/// Stream version 6 (issue 41): the centre subtracted from a block before its decomposition,
/// rounded to f32 as the packet stores it. The paper decomposes the raw coordinates (§2.1: the
/// first components carry the mean shape); far from the origin the shape and its motion are
/// then tiny next to the offset, and the Gram route (§2.4, `tensor::leading_left`), which
/// squares the singular values, resolves components down to about `1e-8` of the largest only:
/// the same animation translated by 1e5 decoded at KG 20 % where the untranslated one had 3 %.
/// With motion removal every frame is mapped onto frame 0, so frame 0's centroid is the centre
/// of the normalised tensor; without it, the centroid of the whole block.
fn block_centre(positions: &[f32], k: usize, rigid: bool) -> [f32; 3] {
    let used = if rigid { &positions[..(3 * k).min(positions.len())] } else { positions };
    let n = (used.len() / 3).max(1) as f64;
    let mut s = [0.0f64; 3];
    for p in used.chunks_exact(3) {
        for j in 0..3 {
            s[j] += p[j] as f64;
        }
    }
    s.map(|x| {
        let c = (x / n) as f32;
        if c.is_finite() {
            c
        } else {
            0.0
        }
    })
}

/// Mean over frames and mesh edges of the squared edge length of `x` (`F × K × 3`), the
/// edges being the graph's (each once, between a position and an earlier neighbour); 0 when
/// the graph has no edges (e.g. it does not cover the mesh).
fn mean_squared_edge(x: &[f64], k: usize, graph: &CausalGraph) -> f64 {
    if graph.len() != k || k == 0 {
        return 0.0;
    }
    let order = graph.order();
    let frames = x.len() / (3 * k);
    let (mut sum, mut count) = (0.0f64, 0usize);
    for t in 0..frames {
        let xt = &x[t * 3 * k..(t + 1) * 3 * k];
        for p in 0..k {
            let a = order[p] as usize;
            for &q in graph.earlier(p) {
                let b = order[q as usize] as usize;
                sum += (0..3).map(|j| (xt[a * 3 + j] - xt[b * 3 + j]).powi(2)).sum::<f64>();
                count += 1;
            }
        }
    }
    if count == 0 {
        0.0
    } else {
        sum / count as f64
    }
}

/// Bits so that a uniform quantizer over `range` has a step no larger than `step`.
fn bits_for(range: f64, step: f64) -> u8 {
    if range <= 0.0 {
        return 1;
    }
    if !(step > 0.0 && step.is_finite()) {
        return MAX_BITS;
    }
    let levels = (range / step).ceil() + 1.0;
    (levels.log2().ceil() as i64).clamp(1, MAX_BITS as i64) as u8
}

fn column_quantizer(values: impl Iterator<Item = f64> + Clone, step: f64) -> Result<Quantizer> {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(x), b.max(x)));
    // Round the range outwards to f32 so every value (rounded to f32) stays inside it.
    let (mut lo32, mut hi32) = (lo as f32, hi as f32);
    if (lo32 as f64) > lo {
        lo32 = lo32 - lo32.abs() * f32::EPSILON - f32::MIN_POSITIVE;
    }
    if (hi32 as f64) < hi {
        hi32 = hi32 + hi32.abs() * f32::EPSILON + f32::MIN_POSITIVE;
    }
    Quantizer::new(lo32, hi32, bits_for(hi32 as f64 - lo32 as f64, step))
}

fn planes_needed(values: &[u32]) -> u8 {
    let max = values.iter().copied().max().unwrap_or(0);
    (((32 - max.leading_zeros()) as u8).div_ceil(8)).max(1)
}

fn write_codes(w: &mut ByteWriter, values: &[u32], level: i32) {
    let planes = planes_needed(values) as usize;
    let mut raw = vec![0u8; values.len() * planes];
    for p in 0..planes {
        for (o, v) in raw[p * values.len()..(p + 1) * values.len()].iter_mut().zip(values) {
            *o = (v >> (8 * p)) as u8;
        }
    }
    w.u8(planes as u8);
    w.length_prefixed(&entropy::compress(&raw, level));
}

fn read_codes(r: &mut ByteReader<'_>, count: usize, limits: &Limits, field: &'static str) -> Result<Vec<u32>> {
    let planes = r.u8(field)? as usize;
    if !(1..=4).contains(&planes) {
        return Err(r.malformed(field, format!("{planes} byte planes, expected 1..=4")));
    }
    let len = count.checked_mul(planes).ok_or_else(|| r.malformed(field, "size overflows"))?;
    limits.check_alloc(NAME, field, len as u64)?;
    let block = r.length_prefixed(field)?;
    let raw = entropy::decompress(block, NAME, field, len)?;
    if raw.len() != len {
        return Err(Error::malformed(NAME, field, format!("{} bytes, expected {len}", raw.len())));
    }
    let mut out = vec![0u32; count];
    for p in 0..planes {
        for (o, b) in out.iter_mut().zip(&raw[p * count..(p + 1) * count]) {
            *o |= (*b as u32) << (8 * p);
        }
    }
    Ok(out)
}

/// Column `c` of a row-major `rows × cols` matrix.
fn column(m: &[f64], rows: usize, cols: usize, c: usize) -> impl Iterator<Item = f64> + Clone + '_ {
    (0..rows).map(move |r| m[r * cols + c])
}

/// Version 1 codes of a row-major `rows × quantizers.len()` factor, column by column (one
/// quantizer per column) as zigzag deltas down the column, starting from the code of 0;
/// `reconstructed` receives the dequantized factor.
fn delta_code_columns(quantizers: &[Quantizer], values: &[f64], rows: usize, reconstructed: &mut [f64]) -> Vec<u32> {
    let cols = quantizers.len();
    let mut codes = Vec::with_capacity(rows * cols);
    for (i, q) in quantizers.iter().enumerate() {
        let mut prev = q.quantize(0.0) as i64;
        for r in 0..rows {
            let c = q.quantize(values[r * cols + i] as f32);
            codes.push(zigzag_encode(c as i64 - prev) as u32);
            prev = c as i64;
            reconstructed[r * cols + i] = q.dequantize(c) as f64;
        }
    }
    codes
}

/// Version 1's coding of the operator: one `Quantizer` per column with the rule-of-thumb step,
/// zigzag deltas, byte planes + zstd. Fills `m`'s factors and core and returns the per-column
/// bounds of `‖δu1_i‖`, `‖δu3_l‖` and the bound of `‖δC‖` (from the quantizers' half steps).
#[allow(clippy::too_many_arguments)]
fn paper_code(
    w: &mut ByteWriter,
    mut side: ByteWriter,
    m: &mut Model,
    p: &HosvdParams,
    u1: &[f64],
    u3: &[f64],
    core: &[f64],
    s1: &[f64],
    s3: &[f64],
    budget: f64,
) -> Result<(Vec<f64>, Vec<f64>, f64)> {
    let (k, frames, v, f) = (m.k, m.frames, m.v, m.f);
    let step_core = (4.0 * budget / core.len() as f64).sqrt();
    let q1: Vec<Quantizer> = (0..v)
        .map(|i| column_quantizer(column(u1, k, v, i), (4.0 * budget / (v * k) as f64).sqrt() / s1[i]))
        .collect::<Result<_>>()?;
    let q3: Vec<Quantizer> = (0..f)
        .map(|l| column_quantizer(column(u3, frames, f, l), (4.0 * budget / (f * frames) as f64).sqrt() / s3[l]))
        .collect::<Result<_>>()?;
    let qc = column_quantizer(core.iter().copied(), step_core)?;
    for q in q1.iter().chain(&q3).chain(std::iter::once(&qc)) {
        q.write(&mut side);
    }

    // Codes: factor columns as zigzag deltas down the column (neighbouring vertices / frames
    // have similar loadings); core as zigzag offsets from the code of 0.
    m.u1 = vec![0.0; k * v];
    m.u3 = vec![0.0; frames * f];
    m.core = vec![0.0; core.len()];
    let codes1 = delta_code_columns(&q1, u1, k, &mut m.u1);
    let codes3 = delta_code_columns(&q3, u3, frames, &mut m.u3);
    let zero = qc.quantize(0.0) as i64;
    let mut codesc = Vec::with_capacity(core.len());
    for (o, &c) in m.core.iter_mut().zip(core) {
        let code = qc.quantize(c as f32);
        codesc.push(zigzag_encode(code as i64 - zero) as u32);
        *o = qc.dequantize(code) as f64;
    }

    w.u8(p.rigid as u8);
    w.varint(v as u64);
    w.varint(f as u64);
    w.length_prefixed(&entropy::compress(side.as_slice(), p.level));
    write_codes(w, &codes1, p.level);
    write_codes(w, &codes3, p.level);
    write_codes(w, &codesc, p.level);
    // The quantizer bounds every entry error by half a step.
    let n1 = q1.iter().map(|q| (k as f64).sqrt() * q.max_error()).collect();
    let n3 = q3.iter().map(|q| (frames as f64).sqrt() * q.max_error()).collect();
    let dc = (core.len() as f64).sqrt() * qc.max_error();
    Ok((n1, n3, dc))
}

/// Encodes one block of frames (`F × K × 3`). This is exactly what a packet holds.
/// `graph` is the mesh's coding order ([`CausalGraph::mesh`] of the topology), used by the
/// toolkit coding.
pub fn encode_block(
    positions: &[f32],
    k: usize,
    p: &HosvdParams,
    graph: &CausalGraph,
    want_reconstruction: bool,
) -> Result<EncodedBlock> {
    let frames = positions.len() / (3 * k);
    let start = Instant::now();
    // Stream version 6: the block is centred first (see `block_centre`).
    let centre32 = block_centre(positions, k, p.rigid);
    let centre = centre32.map(|c| c as f64);
    // Stream version 3: with the toolkit coding the transforms are quantized in closed loop
    // while the frames are normalised (`motion.rs`).
    let mut motion_coder = (p.rigid && p.coding == Coding::Toolkit).then(|| {
        let radius = rms_radius(positions, k);
        let bits = match p.motion_bits {
            0 if p.edge_noise > 0.0 => {
                let first: Vec<f64> = positions[..(3 * k).min(positions.len())].iter().map(|&x| x as f64).collect();
                motion::auto_bits(p.edge_noise, radius, mean_squared_edge(&first, k, graph).sqrt())
            }
            0 => motion::DEFAULT_BITS,
            bits => bits,
        };
        motion::MotionEncoder::new(radius, bits)
    });
    let (transforms, x) = match motion_coder.as_mut() {
        Some(mc) => tensor::remove_affine_motion_centred(positions, k, frames, p.affine, centre, &mut |a, fb, mu| {
            mc.store(a, fb, mu)
        }),
        None => normalise_centred(positions, k, frames, p.rigid, p.affine, centre),
    };
    let t = Tensor::new(&x, k, frames);
    let edge2 = mean_squared_edge(&x, k, graph);
    let dims = Dims { k, f: frames, rigid: p.rigid };
    // Mode 2 is kept whole; rounding U2 to f32 *before* the core is computed makes the stored
    // U2 the one the core was projected on.
    let u2 = t.mode2()?.as_ref().to_owned();
    let u2r = Mat::from_fn(3, 3, |i, j| u2[(i, j)] as f32 as f64);
    let explicit = p.v != 0;
    let list = match p.strategy {
        Strategy::Iterative | Strategy::Exhaustive if !explicit => strategy::candidates(dims, p.ss),
        _ => Vec::new(),
    };
    // The full-rank spectrum (most of an encode's time) only when there are candidates to
    // compare: with one or none (the top of the ladder, where a STED search probes the smallest
    // model) the choice is made without it.
    let needs_errors = !explicit && p.strategy != Strategy::Diagonal && list.len() > 1;
    let spectrum = if needs_errors { Some(spectra::spectrum(&t, &x, k, frames)?) } else { None };
    drop(x);
    let decompose_a = start.elapsed().as_secs_f64();

    let search_start = Instant::now();
    let choice = if explicit {
        strategy::Choice {
            v: (p.v as usize).clamp(1, dims.max_v()),
            f: (p.f as usize).clamp(1, dims.max_f()),
            evaluations: 0,
            over_budget: false,
        }
    } else {
        match (p.strategy, &spectrum, list.as_slice()) {
            (Strategy::Diagonal, _, _) => strategy::diagonal(dims, p.ss),
            (_, _, []) => strategy::Choice { v: 1, f: 1, evaluations: 0, over_budget: true },
            (_, None, &[(v, f), ..]) => strategy::Choice { v, f, evaluations: 0, over_budget: false },
            (Strategy::Iterative, Some(s), _) => {
                strategy::iterative(&list, p.samples as usize, p.depth as usize, |v, f| s.truncation_error2(v, f))
            }
            (Strategy::Exhaustive, Some(s), _) => strategy::exhaustive(&list, |v, f| s.truncation_error2(v, f)),
        }
    };
    let search_seconds = search_start.elapsed().as_secs_f64();
    // The candidate strategies' fallback when nothing fits the budget: the smallest model that
    // is not flat (`Dims::smallest`; the diagonal strategy keeps the paper's `(1, 1)`).
    let (mut v, mut f) = match (choice.over_budget, p.strategy) {
        (true, Strategy::Iterative | Strategy::Exhaustive) => dims.smallest(),
        _ => (choice.v, choice.f),
    };
    // Not in the paper: when the chosen ranks already reproduce the tensor to the numerical
    // floor (the quantization budget's floor, 1e-12‖X‖²; e.g. an exactly low-rank skinned
    // animation), more rank buys nothing but coded near-zero columns: keep the smallest ranks
    // that stay at the floor, so a smaller `ss` never gives a different stream for nothing.
    // The paper coding keeps the paper's choice.
    if let (false, Some(s), Coding::Toolkit) = (explicit, &spectrum, p.coding) {
        let floor = 1e-12 * t.norm2;
        if s.truncation_error2(v, f) <= floor {
            while v > 1 && s.truncation_error2(v - 1, f) <= floor {
                v -= 1;
            }
            while f > 1 && s.truncation_error2(v, f - 1) <= floor {
                f -= 1;
            }
        }
    }

    let trunc_start = Instant::now();
    let mut tk = match &spectrum {
        Some(s) => Tucker::truncate(&t, s, v, f, u2r.clone()),
        None => {
            let u1 = tensor::leading_left(t.x1.as_ref(), v)?;
            let u3 = tensor::leading_left(t.x3.as_ref(), f)?;
            let core = t.core(u1.as_ref(), u2r.as_ref(), u3.as_ref());
            Tucker { u1, u2: u2r.clone(), u3, core }
        }
    };
    let decompose_seconds = decompose_a + trunc_start.elapsed().as_secs_f64();
    let hooi_start = Instant::now();
    if p.hooi_iters > 0 {
        tk.hooi(&t, p.hooi_iters as usize)?;
    }
    let hooi_seconds = hooi_start.elapsed().as_secs_f64();

    let code_start = Instant::now();
    let norm2 = t.norm2;
    let trunc2 = (norm2 - tk.captured_norm2()).max(0.0);
    drop(t);
    let u1 = row_major(&tk.u1);
    let u3 = row_major(&tk.u3);
    let core = tk.core;
    // Slice norms of the core: how much each factor column is scaled in the reconstruction.
    let s1: Vec<f64> =
        (0..v).map(|i| core[i * 3 * f..(i + 1) * 3 * f].iter().map(|c| c * c).sum::<f64>().sqrt()).collect();
    let s3: Vec<f64> = (0..f).map(|l| (0..v * 3).map(|ij| core[ij * f + l].powi(2)).sum::<f64>().sqrt()).collect();

    // Quantization plan: total noise budget D = (quant · ε)², ε = truncation error (floored at
    // 1e-6‖X‖ so a lossless truncation still gets finite steps), split evenly between U1, U3 and
    // the core; within a factor, evenly between columns, each column's step scaled by 1/s_i so
    // its contribution (entries × step²/12 × s_i²) is the same.
    let eps2 = trunc2.max(1e-12 * norm2);
    let mut budget = p.quant * p.quant * eps2;
    // STED cap (`edge_noise`): at most (η·L̄)² per coordinate, L̄ the RMS edge length, so at
    // low rates (large ε) the noise stays a small fraction of an edge. Not in the paper.
    if p.edge_noise > 0.0 && edge2 > 0.0 {
        budget = budget.min(p.edge_noise * p.edge_noise * edge2 * (3 * k * frames) as f64);
    }
    let mut side = ByteWriter::new();
    for i in 0..9 {
        side.f32(u2r[(i / 3, i % 3)] as f32);
    }
    if p.rigid && motion_coder.is_none() {
        for a in &transforms {
            a.m.iter().chain(&a.c).for_each(|&x| side.f32(x));
        }
    }
    let mut m = Model {
        k,
        frames,
        v,
        f,
        u1: Vec::new(),
        u2: std::array::from_fn(|i| u2r[(i / 3, i % 3)]),
        u3: Vec::new(),
        core: Vec::new(),
        transforms: if p.rigid { transforms.clone() } else { vec![Affine::IDENTITY; frames] },
    };
    let mut w = ByteWriter::new();
    let mut regression_fallbacks = 0;
    // Per-column bounds of ‖δu1_i‖, ‖δu3_l‖, and ‖δC‖, for the error bound below.
    let (n1, n3, dc) = match p.coding {
        Coding::Paper => paper_code(&mut w, side, &mut m, p, &u1, &u3, &core, &s1, &s3, budget)?,
        Coding::Toolkit => {
            let op = coding::Operator { k, frames, v, f, u1: &u1, u3: &u3, core: &core, s1: &s1, s3: &s3 };
            let settings = coding::Settings {
                mesh: p.mesh_predictor,
                time: p.time_predictor,
                shaping: p.shaping,
                rdq: p.rdq,
                edge_weight: p.edge_weight,
                denoise: p.denoise,
                regress: p.regress,
                force_unguarded_regression: p.force_unguarded_regression,
            };
            let coded = coding::code(&op, graph, &settings, budget);
            // The encoder checks its own output (issue 26): a component whose closed loop
            // failed with no safer mode left is never written.
            if let Some(&c) = coded.failed.first() {
                return Err(Error::Unsupported {
                    context: NAME.into(),
                    detail: format!(
                        "component {c} of the coded operator (v = {v}, f = {f}) does not reconstruct within its \
                         quantization step; no stream written"
                    ),
                });
            }
            regression_fallbacks = coded.fallbacks.len();
            for &step in &coded.steps {
                side.f32(step);
            }
            w.u8(p.rigid as u8
                | FLAG_TOOLKIT
                | if motion_coder.is_some() { FLAG_MOTION } else { 0 }
                | if p.denoise { FLAG_DENOISE } else { 0 }
                | if p.regress { FLAG_REGRESS } else { 0 });
            w.varint(v as u64);
            w.varint(f as u64);
            w.u8(p.mesh_predictor.code());
            w.u8(p.time_predictor.code());
            w.length_prefixed(&entropy::compress(side.as_slice(), p.level));
            w.length_prefixed(&coded.bytes);
            if let Some(mc) = motion_coder.take() {
                w.length_prefixed(&mc.finish());
            }
            if p.denoise {
                w.bytes(&coded.smoothing);
            }
            if p.regress {
                w.bytes(&coded.modes);
            }
            m.u1 = coded.u1;
            m.u3 = coded.u3;
            m.core = coded.core;
            (coded.du1, coded.du3, coded.dc)
        }
    };
    // Stream version 6: the flag, and the centre at the end of the packet.
    let mut payload = w.into_vec();
    payload[0] |= FLAG_CENTRE;
    for c in centre32 {
        payload.extend_from_slice(&c.to_le_bytes());
    }

    // Error bound (Frobenius, original coordinates). With Û = U + δU, Ĉ = C + δC:
    // Ĉ×₁Û1×₂U2×₃Û3 − C×₁U1×₂U2×₃U3 = δC×Û1×Û3 + C×δU1×Û3 + C×U1×δU3 (all ×₂U2), and
    // ‖C ×₁ δU1‖ ≤ Σ_i ‖δu_i‖·s1_i; ‖Û‖₂ ≤ 1 + ‖δU‖_F.
    let du1: f64 = n1.iter().map(|x| x * x).sum::<f64>().sqrt();
    let du3: f64 = n3.iter().map(|x| x * x).sum::<f64>().sqrt();
    let g2 = {
        let mut dev = 0.0f64;
        for i in 0..3 {
            for j in 0..3 {
                let dot: f64 = (0..3).map(|l| u2r[(i, l)] * u2r[(j, l)]).sum();
                dev += (dot - if i == j { 1.0 } else { 0.0 }).powi(2);
            }
        }
        dev.sqrt()
    };
    let t1: f64 = n1.iter().zip(&s1).map(|(n, s)| n * s).sum();
    let t3: f64 = n3.iter().zip(&s3).map(|(n, s)| n * s).sum();
    let norm = norm2.sqrt();
    let ex =
        trunc2.sqrt() + 1e-7 * norm + g2 * norm + (1.0 + g2) * (dc * (1.0 + du1) * (1.0 + du3) + t1 * (1.0 + du3) + t3);
    let gain = m.transforms.iter().map(Affine::gain).fold(0.0, f64::max);
    let pos_norm = positions.iter().map(|&x| (x as f64).powi(2)).sum::<f64>().sqrt();
    // Version 6 rounds twice: the centred reconstruction to f32, then its sum with the centre.
    let centred_norm = positions
        .chunks_exact(3)
        .map(|q| (0..3).map(|j| (q[j] as f64 - centre[j]).powi(2)).sum::<f64>())
        .sum::<f64>()
        .sqrt();
    let error_bound =
        (gain * ex + (pos_norm + centred_norm + 2.0 * gain * ex) * 2.0f64.powi(-23) + 1e-30) * (1.0 + 1e-9);

    // The encoder measures its reconstruction against the input (issue 41): the error the
    // chosen ranks and steps promise is `error_bound` (truncation, quantization of every factor
    // and of the transforms, the factors' loss of orthogonality, the f32 roundings), proved
    // above; far beyond it (numerical precision lost on an input far from its centre, e.g. a
    // block travelling a long way) no stream is written.
    let mut rec = tensor::reconstruct(&m);
    add_centre(&mut rec, centre32)?;
    check_precision(positions, &rec, error_bound, 0.0, v, f)?;
    let reconstruction = want_reconstruction.then_some(rec);
    let code_seconds = code_start.elapsed().as_secs_f64();
    let stats = BlockStats {
        frames,
        v,
        f,
        evaluations: choice.evaluations,
        over_budget: choice.over_budget,
        paper_numbers: dims.paper_numbers(v, f),
        norm2,
        truncation_error2: trunc2,
        error_bound,
        payload_bytes: payload.len(),
        regression_fallbacks,
        decompose_seconds,
        search_seconds,
        hooi_seconds,
        code_seconds,
    };
    Ok(EncodedBlock { payload, reconstruction, stats })
}

/// How far the measured error may exceed the bound the chosen ranks and steps promise
/// (`BlockStats::error_bound`, which every sound encode meets) before the encoder refuses: a
/// margin against the bound's own rounding, far below the failures this check is for (KG 20 %
/// instead of 3 %).
const PRECISION_MARGIN: f64 = 2.0;

/// Issue 41: refuses a block whose reconstruction `rec` is further from `positions` (Frobenius)
/// than [`PRECISION_MARGIN`] × `promised` plus the unavoidable: `slack` (numerical floors of
/// the analysis) and the `f32` rounding of every output coordinate (half a unit in the last
/// place, twice: the centred value and its sum with the centre).
fn check_precision(positions: &[f32], rec: &[f32], promised: f64, slack: f64, v: usize, f: usize) -> Result<()> {
    let (mut err2, mut round2) = (0.0f64, 0.0f64);
    for (&x, &y) in positions.iter().zip(rec) {
        err2 += (x as f64 - y as f64).powi(2);
        // A unit in the last place of |y| (≥ the smallest normal's, for subnormal outputs).
        let ulp = (y.abs().max(f32::MIN_POSITIVE) as f64) * 2.0f64.powi(-23);
        round2 += ulp * ulp;
    }
    let (err, allowed) = (err2.sqrt(), PRECISION_MARGIN * promised + slack + round2.sqrt());
    if err <= allowed {
        return Ok(());
    }
    Err(Error::Unsupported {
        context: NAME.into(),
        detail: format!(
            "the decoded block is {err:.3e} from the input (Frobenius), beyond the {allowed:.3e} that its ranks (v = {v}, f = {f}) and quantization promise: numerical \
             precision was lost (coordinates far from their centre next to the shape's size?); no stream \
             written. Use smaller temporal blocks (-p block=N) or another codec (quant-delta)"
        ),
    })
}

/// Streaming encoder: buffers `block` frames (or all of them), then codes one packet.
/// Public so benchmarks can read [`HosvdEncoder::stats`] after driving it.
pub struct HosvdEncoder {
    params: HosvdParams,
    k: usize,
    graph: CausalGraph,
    block: usize,
    want_reconstruction: bool,
    pending: Vec<f32>,
    next_frame: u32,
    stats: Vec<BlockStats>,
    /// Frames in the whole animation.
    frame_count: usize,
    /// Bounding box and coordinate count of the frames pushed (for [`FrameEncoder::declared_bound`]).
    lo: [f32; 3],
    hi: [f32; 3],
    coordinates: usize,
}

/// The parameters for one block of `frames` frames (`whole`: the block is the whole
/// animation). A block of 1 or 2 frames has no frame mode to reduce: when `ss` cannot be met
/// there (the strategy's smallest model is over budget: `(1, 1)` for the diagonal one, the
/// smallest that is not flat, `(3, 1)`, for the others), the fallback keeps all or nothing: the
/// `(1, 1)` model almost nothing of the shape (KG above 60 % on a 1-frame mesh), `(3, 1)` on one
/// frame everything at more than the raw size. Such a block is coded at full rank when it ends a
/// longer animation (it is small next to the rest), and an animation that short is refused with
/// the `ss` it would need.
fn block_params(p: &HosvdParams, k: usize, frames: usize, whole: bool) -> Result<HosvdParams> {
    let dims = Dims { k, f: frames, rigid: p.rigid };
    let (v0, f0) = match p.strategy {
        Strategy::Diagonal => (1, 1),
        Strategy::Iterative | Strategy::Exhaustive => dims.smallest(),
    };
    if frames >= 3 || p.v != 0 || dims.cr(v0, f0) <= 1.0 - p.ss {
        return Ok(*p);
    }
    if whole {
        let reachable = 1.0 - dims.cr(v0, f0);
        let advice = if reachable > 0.01 {
            format!("use -p ss={:.2} or lower, explicit ranks (-p v=N -p f=N)", reachable - 0.005)
        } else {
            "no ss can be met: use explicit ranks (-p v=N -p f=N)".to_owned()
        };
        return Err(Error::Unsupported {
            context: NAME.into(),
            detail: format!(
                "an animation of {frames} frame{} cannot be coded at ss={}: with so few frames the frame mode \
                 cannot be reduced, and even the smallest Tucker core keeps {:.0}% of the raw size (the paper's \
                 size model); {advice}, or a codec that does not rely on many frames (quant-delta)",
                if frames == 1 { "" } else { "s" },
                p.ss,
                (1.0 - reachable) * 100.0,
            ),
        });
    }
    Ok(HosvdParams { v: dims.max_v() as u32, f: dims.max_f() as u32, ..*p })
}

impl HosvdEncoder {
    /// An encoder for `frame_count` frames over `topology`.
    pub fn new(params: HosvdParams, topology: &Topology, frame_count: usize, want_reconstruction: bool) -> Self {
        let block = if params.block == 0 { frame_count.max(1) } else { params.block as usize };
        Self {
            params,
            k: topology.vertex_count(),
            graph: mesh_graph(&params, topology),
            block,
            want_reconstruction,
            pending: Vec::new(),
            next_frame: 0,
            stats: Vec::new(),
            frame_count,
            lo: [f32::INFINITY; 3],
            hi: [f32::NEG_INFINITY; 3],
            coordinates: 0,
        }
    }

    /// Statistics of every packet coded so far.
    pub fn stats(&self) -> &[BlockStats] {
        &self.stats
    }

    fn code(&mut self, frames: usize) -> Result<EncodedPacket> {
        let n = frames * self.k * 3;
        let whole = self.next_frame == 0 && frames >= self.frame_count;
        let params = block_params(&self.params, self.k, frames, whole)?;
        let block: Vec<f32> = self.pending.drain(..n).collect();
        let b = encode_block(&block, self.k, &params, &self.graph, self.want_reconstruction)?;
        self.stats.push(b.stats);
        let packet =
            Packet { first_frame: self.next_frame, frame_count: frames as u32, keyframe: true, data: b.payload };
        self.next_frame += frames as u32;
        Ok(EncodedPacket { packet, reconstruction: b.reconstruction })
    }
}

impl FrameEncoder for HosvdEncoder {
    fn config(&self) -> Vec<u8> {
        (self.block.min(u32::MAX as usize) as u32).to_le_bytes().to_vec()
    }

    fn push_frames(&mut self, frames: &[f32]) -> Result<Vec<EncodedPacket>> {
        if frames.len() >= 3 {
            let (lo, hi) = codec_core::animation::bounding_box(frames);
            for a in 0..3 {
                self.lo[a] = self.lo[a].min(lo[a]);
                self.hi[a] = self.hi[a].max(hi[a]);
            }
        }
        self.coordinates += frames.len();
        self.pending.extend_from_slice(frames);
        let mut out = Vec::new();
        while self.pending.len() >= self.block * self.k * 3 && self.k > 0 {
            out.push(self.code(self.block)?);
        }
        Ok(out)
    }

    /// [`AnimationCodec::error_bound`] from the packets' own bounds (the same arithmetic), so
    /// the stream driver's self-check needs no second analysis.
    fn declared_bound(&self) -> Option<ErrorBound> {
        let frob = self.stats.iter().map(|s| s.error_bound.powi(2)).sum::<f64>().sqrt();
        let diag = if self.coordinates >= 3 {
            (0..3).map(|a| (self.hi[a] as f64 - self.lo[a] as f64).powi(2)).sum::<f64>().sqrt()
        } else {
            0.0
        };
        let rel = if diag > 0.0 { frob / (self.coordinates as f64).sqrt() / diag } else { f64::INFINITY };
        Some(ErrorBound { max_coordinate_error: Some(frob), relative_rms_error: Some(rel) })
    }

    fn notes(&self) -> Vec<String> {
        let fallbacks: usize = self.stats.iter().map(|s| s.regression_fallbacks).sum();
        if fallbacks == 0 {
            return Vec::new();
        }
        vec![format!(
            "{NAME}: fallback: {fallbacks} mode-1 column{} in regression mode did not reconstruct within its \
             step on the decoded leading columns and {} re-coded with the mesh predictor",
            if fallbacks == 1 { "" } else { "s" },
            if fallbacks == 1 { "was" } else { "were" },
        )]
    }

    fn finish(&mut self) -> Result<Vec<EncodedPacket>> {
        if self.k == 0 {
            return Err(Error::Unsupported { context: NAME.into(), detail: "an animation without vertices".into() });
        }
        let n = self.pending.len() / (self.k * 3);
        Ok(if n > 0 { vec![self.code(n)?] } else { Vec::new() })
    }
}

/// The mesh's coding order when the toolkit coding needs it (an empty order otherwise).
pub fn mesh_graph(p: &HosvdParams, topology: &Topology) -> CausalGraph {
    match p.coding {
        Coding::Toolkit => CausalGraph::mesh(topology.vertex_count(), topology.triangles()),
        Coding::Paper => CausalGraph::chain(0, false),
    }
}

/// The decoder's mesh coding order: none in version 1 streams, built lazily in version 2.
enum MeshOrder {
    Unavailable,
    Pending(Vec<[u32; 3]>),
    Built(CausalGraph),
}

/// Work of decoding one packet of `frames` frames of `k` vertices with ranks `v` and `f`
/// (`Limits::max_work`, counted before the work starts): the coded values of `U1`, `U3` and
/// the core (arithmetic-coded with `toolkit`, else inflated byte planes), the frame loadings
/// ([`tensor::reconstruct`]: `F·3·v·f + 9·v·f`), the last step's `F·K·3·v` multiply-adds
/// (all but a sliver of the arithmetic) and the output coordinates.
pub fn decode_work(k: usize, frames: usize, v: usize, f: usize, toolkit: bool) -> u64 {
    use codec_core::limits::{WORK_PER_CODED_VALUE, WORK_PER_COORDINATE, WORK_PER_PLANE_BYTE};
    let (k, frames, v, f) = (k as u64, frames as u64, v as u64, f as u64);
    let values = Limits::product(&[k, v])
        .saturating_add(Limits::product(&[frames, f]))
        .saturating_add(Limits::product(&[3, v, f]));
    // Byte planes: at most 4 per value (`read_codes`).
    let per_value = if toolkit { WORK_PER_CODED_VALUE } else { 4 * WORK_PER_PLANE_BYTE };
    let coords = Limits::product(&[frames, k, 3]);
    values
        .saturating_mul(per_value)
        .saturating_add(Limits::product(&[frames, 3, v, f]))
        .saturating_add(Limits::product(&[9, v, f]))
        .saturating_add(coords.saturating_mul(v))
        .saturating_add(coords.saturating_mul(WORK_PER_COORDINATE))
}

struct HosvdDecoder {
    k: usize,
    limits: Limits,
    /// Mesh coding order (stream version 2 only).
    graph: MeshOrder,
    /// Stream version (3 allows [`FLAG_MOTION`]).
    version: u16,
}

impl HosvdDecoder {
    /// The mesh coding order, built on first use once its size passed the limits.
    fn mesh_order(&mut self) -> Result<&CausalGraph> {
        if let MeshOrder::Pending(triangles) = &self.graph {
            let bytes = order::mesh_bytes(self.k, triangles.len());
            self.limits.check_alloc(NAME, "mesh coding order", bytes)?;
            self.graph = MeshOrder::Built(CausalGraph::mesh(self.k, triangles));
        }
        match &self.graph {
            MeshOrder::Built(graph) => Ok(graph),
            _ => Err(Error::malformed(NAME, "flags", "toolkit coding in a version 1 stream")),
        }
    }
}

impl HosvdDecoder {
    /// A packet without `FLAG_CENTRE` (every packet of versions 1 to 5; a version 6 packet
    /// after [`FrameDecoder::decode_packet`] took its centre off).
    fn decode_uncentred(&mut self, packet: &Packet) -> Result<Vec<f32>> {
        let (k, frames) = (self.k, packet.frame_count as usize);
        if k == 0 || frames == 0 {
            return Err(Error::malformed(NAME, "packet", "no vertices or no frames"));
        }
        let mut r = ByteReader::new(&packet.data, NAME);
        let flags = r.u8("flags")?;
        let known = match (&self.graph, self.version) {
            (MeshOrder::Unavailable, _) => 1,
            (_, v) if v >= 4 => 1 | FLAG_TOOLKIT | FLAG_MOTION | FLAG_DENOISE | FLAG_REGRESS,
            (_, 3) => 1 | FLAG_TOOLKIT | FLAG_MOTION | FLAG_DENOISE,
            _ => 1 | FLAG_TOOLKIT,
        };
        if flags & !known != 0 {
            return Err(r.malformed("flags", format!("{flags:#04x} has unknown bits")));
        }
        let rigid = flags & 1 == 1;
        let toolkit = flags & FLAG_TOOLKIT != 0;
        let coded_motion = flags & FLAG_MOTION != 0;
        if coded_motion && !(rigid && toolkit) {
            return Err(r.malformed("flags", format!("{flags:#04x}: coded motion without rigid toolkit coding")));
        }
        let denoise = flags & FLAG_DENOISE != 0;
        if denoise && !toolkit {
            return Err(r.malformed("flags", format!("{flags:#04x}: denoising without toolkit coding")));
        }
        let regress = flags & FLAG_REGRESS != 0;
        if regress && !toolkit {
            return Err(r.malformed("flags", format!("{flags:#04x}: regression without toolkit coding")));
        }
        let vmax = k.min(3 * frames);
        let fmax = frames.min(3 * k);
        let v = r.varint("v")?;
        if v == 0 || v > vmax as u64 {
            return Err(r.malformed("v", format!("{v} is outside 1..={vmax}")));
        }
        let f = r.varint("f")?;
        if f == 0 || f > fmax as u64 {
            return Err(r.malformed("f", format!("{f} is outside 1..={fmax}")));
        }
        let (v, f) = (v as usize, f as usize);
        // Every f64 array below, checked before allocating.
        // (U1, U3, core, plus the reconstruction's two intermediates: C·U2 and D = v × 3 × F).
        let doubles = (k as u64 * v as u64)
            .saturating_add(frames as u64 * f as u64)
            .saturating_add(6 * v as u64 * f as u64)
            .saturating_add(3 * frames as u64 * v as u64);
        self.limits.check_alloc(NAME, "factors", doubles.saturating_mul(8))?;
        // Issue 41 (round 4, `hosvd-work`): the work is known from `K`, the frames and the ranks
        // before anything is inflated or decoded; a 171-byte stream asking for ~10^11
        // multiply-adds is refused here when they exceed `--max-work`.
        self.limits = self.limits.spend(NAME, "reconstruction", decode_work(k, frames, v, f, toolkit))?;
        let (mesh_predictor, time_predictor) = if toolkit {
            let mut predictor = |field| {
                let c = r.u8(field)?;
                Predictor::from_code(c).ok_or_else(|| r.malformed(field, format!("unknown predictor {c}")))
            };
            (predictor("mesh_predictor")?, predictor("time_predictor")?)
        } else {
            (Predictor::Zero, Predictor::Zero)
        };
        let side_len = 36
            + if rigid && !coded_motion { 48 * frames } else { 0 }
            + if toolkit { 4 * (2 * v + f) } else { 9 * (v + f + 1) };
        self.limits.check_alloc(NAME, "side", side_len as u64)?;
        let side_block = r.length_prefixed("side")?;
        let side = entropy::decompress(side_block, NAME, "side", side_len)?;
        if side.len() != side_len {
            return Err(Error::malformed(NAME, "side", format!("{} bytes, expected {side_len}", side.len())));
        }
        let mut s = ByteReader::new(&side, NAME);
        let mut u2 = [0.0f64; 9];
        for x in &mut u2 {
            *x = s.finite_f32("u2")? as f64;
        }
        let transforms = if rigid && !coded_motion {
            let mut out = Vec::with_capacity(frames);
            for _ in 0..frames {
                let mut a = Affine::IDENTITY;
                for x in a.m.iter_mut().chain(a.c.iter_mut()) {
                    *x = s.finite_f32("transform")?;
                }
                out.push(a);
            }
            out
        } else if coded_motion {
            // Decoded from the motion block below, after its size is checked.
            Vec::new()
        } else {
            vec![Affine::IDENTITY; frames]
        };
        if toolkit {
            let steps = (0..2 * v + f).map(|_| s.finite_f32("steps")).collect::<Result<Vec<f32>>>()?;
            s.expect_end("side")?;
            if let Some(bad) = steps.iter().find(|x| **x < 0.0) {
                return Err(Error::malformed(NAME, "steps", format!("negative step {bad}")));
            }
            let bytes = r.length_prefixed("codes")?;
            let transforms = if coded_motion {
                self.limits.check_alloc(NAME, "motion", 48 * frames as u64)?;
                motion::decode(r.length_prefixed("motion")?, frames)?
            } else {
                transforms
            };
            let smoothing = if denoise { Some(r.take(v, "smoothing")?.to_vec()) } else { None };
            let modes = if regress { Some(r.take(v, "column modes")?.to_vec()) } else { None };
            r.expect_end("packet")?;
            if modes.as_ref().is_some_and(|x| x.contains(&(coding::ColumnMode::Regression as u8))) {
                self.limits.check_alloc(NAME, "regression neighbourhoods", Neighbourhoods::bytes(k))?;
            }
            // Version 5's guarded regression; version 4 streams keep their arithmetic.
            let guarded = self.version >= 5;
            let graph = self.mesh_order()?;
            let (mut u1, u3, core) = coding::decode(
                bytes,
                graph,
                mesh_predictor,
                time_predictor,
                frames,
                v,
                f,
                &steps,
                modes.as_deref(),
                guarded,
            )?;
            if let Some(levels) = smoothing {
                coding::Smoother::new(graph).apply_columns(graph, &mut u1, v, &levels)?;
            }
            let model = Model { k, frames, v, f, u1, u2, u3, core, transforms };
            return Ok(tensor::reconstruct(&model));
        }
        let q1: Vec<Quantizer> = (0..v).map(|_| Quantizer::read(&mut s, "u1_quantizer")).collect::<Result<_>>()?;
        let q3: Vec<Quantizer> = (0..f).map(|_| Quantizer::read(&mut s, "u3_quantizer")).collect::<Result<_>>()?;
        let qc = Quantizer::read(&mut s, "core_quantizer")?;
        s.expect_end("side")?;
        if let Some(q) = q1.iter().chain(&q3).chain([&qc]).find(|q| q.bits() > MAX_BITS) {
            return Err(Error::malformed(NAME, "quantizer", format!("{} bits, at most {MAX_BITS}", q.bits())));
        }

        let column_codes = |codes: &[u32], qs: &[Quantizer], rows: usize, cols: usize, field: &'static str| {
            let mut out = vec![0.0f64; rows * cols];
            for (c, q) in qs.iter().enumerate() {
                let mut prev = q.quantize(0.0) as i64;
                let max = q.max_code() as i64;
                for r in 0..rows {
                    let code = prev + zigzag_decode(codes[c * rows + r] as u64);
                    if !(0..=max).contains(&code) {
                        return Err(Error::malformed(NAME, field, format!("code {code} outside 0..={max}")));
                    }
                    out[r * cols + c] = q.dequantize(code as u32) as f64;
                    prev = code;
                }
            }
            Ok(out)
        };
        let c1 = read_codes(&mut r, k * v, &self.limits, "u1_codes")?;
        let u1 = column_codes(&c1, &q1, k, v, "u1_codes")?;
        drop(c1);
        let c3 = read_codes(&mut r, frames * f, &self.limits, "u3_codes")?;
        let u3 = column_codes(&c3, &q3, frames, f, "u3_codes")?;
        let cc = read_codes(&mut r, 3 * v * f, &self.limits, "core_codes")?;
        r.expect_end("packet")?;
        let zero = qc.quantize(0.0) as i64;
        let max = qc.max_code() as i64;
        let core = cc
            .iter()
            .map(|&z| {
                let code = zero + zigzag_decode(z as u64);
                if (0..=max).contains(&code) {
                    Ok(qc.dequantize(code as u32) as f64)
                } else {
                    Err(Error::malformed(NAME, "core_codes", format!("code {code} outside 0..={max}")))
                }
            })
            .collect::<Result<Vec<f64>>>()?;
        let model = Model { k, frames, v, f, u1, u2, u3, core, transforms };
        Ok(tensor::reconstruct(&model))
    }
}

impl FrameDecoder for HosvdDecoder {
    /// Stream version 6 (issue 41): a packet with `FLAG_CENTRE` ends with the centre the
    /// encoder subtracted; the rest, with that flag cleared, is a version 5 packet. The centre
    /// is added to every decoded coordinate ([`add_centre`]).
    fn decode_packet(&mut self, packet: &Packet) -> Result<Vec<f32>> {
        let centred = packet.data.first().is_some_and(|&flags| flags & FLAG_CENTRE != 0);
        if !centred {
            return self.decode_uncentred(packet);
        }
        if self.version < 6 {
            return Err(Error::malformed(
                NAME,
                "flags",
                format!("{:#04x}: a centre in a version {} stream", packet.data[0], self.version),
            ));
        }
        let Some(split) = packet.data.len().checked_sub(CENTRE_BYTES).filter(|&n| n >= 1) else {
            return Err(Error::malformed(NAME, "centre", "the packet is too short to hold its centre"));
        };
        let mut r = ByteReader::new(&packet.data[split..], NAME);
        let mut centre = [0.0f32; 3];
        for c in &mut centre {
            *c = r.finite_f32("centre")?;
        }
        let mut data = packet.data[..split].to_vec();
        data[0] &= !FLAG_CENTRE;
        let inner = Packet { data, ..*packet };
        let mut out = self.decode_uncentred(&inner)?;
        add_centre(&mut out, centre)?;
        Ok(out)
    }
}

/// Adds the packet's centre to every decoded vertex (`F × K × 3`), in f64 then rounded to f32,
/// as the encoder's reconstruction does; a sum that is not finite is an error.
fn add_centre(out: &mut [f32], centre: [f32; 3]) -> Result<()> {
    for p in out.chunks_exact_mut(3) {
        for j in 0..3 {
            p[j] = (p[j] as f64 + centre[j] as f64) as f32;
        }
    }
    match out.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(Error::malformed(NAME, "centre", format!("decoded coordinate {i} is not finite"))),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests;
