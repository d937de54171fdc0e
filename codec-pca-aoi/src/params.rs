//! Parameters of `pca-aoi`, each declared once ([`codec_core::declare_params!`]): the paper's
//! (`mode`, `k`, `block`, `z`, `tmax`, `eps_low`, `eps_high`, `domain`, `clusters`,
//! `dict_bits`, `feat_bits`; §3–4) and the toolkit coding's, with the cross-field checks.

use codec_core::toolkit::predict::Predictor;
use codec_core::{Error, Result};

use crate::dictionary::{EstimatorSettings, Mode};
use crate::{MAX_BLOCK, MAX_CLUSTERS, NAME};

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
    /// Stream version 2's coding: prediction along the cluster's mesh and along
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

    pub(crate) fn settings(&self) -> EstimatorSettings {
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
