//! Parameters of `stseg`, each declared once ([`codec_core::declare_params!`]), named after the
//! paper's notation (ω, γ_init, γ_max, λ, N_g, ρ, η; §4), with the coding's and the cross-field
//! checks.

use codec_core::toolkit::predict::Predictor;
use codec_core::{Error, Result};

use crate::{MAX_GROUPS, NAME};

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
    /// Stream version 3's coding (`coding.rs`): per-vertex basis fields predicted
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
        /// samba and horse-gallop (README).
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
    pub(crate) fn max_segment(&self) -> usize {
        self.gamma_max.max(self.gamma_init) as usize
    }
}

/// Longest segment (packet) in frames: the upper end of `gamma_max`'s range. Decoders of
/// toolkit-coded packets refuse longer ones (it bounds the reconstruction work per value).
pub(crate) const MAX_SEGMENT_FRAMES: usize = 1024;
