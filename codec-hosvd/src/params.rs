//! Parameters of `hosvd`, each declared once ([`codec_core::declare_params!`]): the paper's
//! (`ss`, `strategy`, `v`, `f`, `rigid`, `samples`, `depth`; §2.3–2.6) and the coding's, with the
//! cross-field checks.

use codec_core::toolkit::predict::Predictor;
use codec_core::{entropy, Error, Result};

use crate::motion;
use crate::strategy::Strategy;
use crate::NAME;

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
        /// translation (false; orthogonal Procrustes). Default false: on the four dev animations
        /// at `ss` 0.97 and 0.9 the rotation gave the smaller stream in 7 of 8 cases and the
        /// lower KG in 7 of 8 (README, "Parameters"), a rotation keeps every edge length (an
        /// affine map stretches them: STED), and it does not amplify the decomposition error
        /// (the affine maps' gains reach 2.6, README).
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
        /// Target quantization RMS error relative to the truncation error, 0.01..=10. Default 2:
        /// with the toolkit coding's equal-slope steps and decoder-side smoothing, coarser steps
        /// on more components give fewer bits at equal KG than fine steps on fewer (horse-gallop,
        /// samba, pcow: README "Choosing `quant`"); the `edge_noise` cap keeps the noise
        /// small where STED binds.
        pub quant: f64 = 2.0
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
        /// Toolkit (stream version 7): per-vertex step scales of the mode-1 factor columns after
        /// the third, proportional to the local edge length raised to this strength (0 = off,
        /// 1 = proportional; to the nearest quarter), derived by the decoder from the decoded
        /// leading columns (`coding::relstep`). STED measures relative edge-length changes, so
        /// uniform noise hurts most where edges are short. Default 0.25: at equal bits STED −1 to
        /// −7 % with KG within about 1 % on horse-gallop and pcow, where 0.5 costs KG 1–6 % and
        /// 1 more (README, "Stream version 7"; `docs/notes/issue-45-relstep.md`).
        pub relstep: f64 = 0.25 => float(
            0.0,
            1.0,
            "toolkit: mode-1 factor steps proportional to the local edge length^relstep (0 = off, 1 = proportional; quarters; v7)"
        ),
        /// Toolkit: with `relstep`, leave the scales off when the mesh's edge lengths promise
        /// less than 0.1 bit per coded coordinate (`coding::relstep::jensen_gain`); false = always
        /// on. Default true.
        pub relstep_auto: bool = true => boolean(
            "toolkit: with relstep, only where the edge lengths vary enough to promise 0.1 bit per coordinate"
        ),
        /// Test hook, not a codec parameter (always false from a [`ParamSet`](codec_core::ParamSet)): regression on every
        /// mode-1 column with stream version 4's unguarded fit, to drive the encoder into a
        /// diverging regression and prove its closed-loop check falls back
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
