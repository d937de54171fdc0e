//! Parameters of `laplacian`: one declaration per parameter (`codec_core::declare_params!`
//! writes the struct, `Default`, `specs()`, `from_param_set` and `to_param_set` from it).

use codec_core::Result;

use crate::NAME;

/// Largest number of temporal basis vectors a packet may carry (the decoder's bound too).
pub const MAX_RANK: u32 = 1024;

codec_core::declare_params! {
    codec: NAME;
    /// Typed parameters of `laplacian`.
    #[derive(Debug, Clone, Copy, PartialEq)]
    pub struct LaplacianParams {
        /// Quantization step of the coefficient fields (of their Laplacian δ, or of the fields
        /// themselves without `laplacian`), relative to the packet's bounding-box diagonal,
        /// 1e-7..=0.5. Default 0.002. The rate knob: the other steps and the rank follow it.
        pub step: f64 = 2e-3 => float(
            1e-7,
            0.5,
            "quantization step of the coefficient fields relative to the bounding-box diagonal (the rate knob)"
        ),
        /// Temporal basis vectors N (0 = automatic: every PCA component whose energy exceeds
        /// `keep` × V × step², the components worth more than their quantization noise).
        pub rank: u32 = 0 => int(0, MAX_RANK as i64, "temporal basis vectors N, 0 = automatic from step and keep"),
        /// Automatic rank threshold (see `rank`), 0.01..=100. Default 4 (horse-gallop, step
        /// 0.004: keep 1 coded 31 components at 1.3× the bytes for the same STED; 16 lost KG).
        pub keep: f64 = 4.0 => float(
            0.01,
            100.0,
            "automatic rank: keep components with energy above keep x vertices x step^2"
        ),
        /// Basis precision: column j's step is `basis_scale × step / σ_j` (equal error per
        /// coded value with the coefficients), 0.01..=100. Default 1.
        pub basis_scale: f64 = 1.0 => float(0.01, 100.0, "basis step relative to step / singular value"),
        /// Step of the average mesh and the centroid motion relative to `step`, 0.001..=100.
        /// Default 0.05: the average mesh is in every frame and its cotangent weights shape
        /// every field's δ, so its noise costs STED and field bits (horse-gallop, step 0.004:
        /// 1 gave STED 0.25 at 1.85 bpvf, 0.05 STED 0.039 at 0.91).
        pub mean_scale: f64 = 0.05 => float(0.001, 100.0, "average mesh and centroid step relative to step"),
        /// Step of the anchors' coefficients relative to `step`, 0.001..=10. Default 0.25.
        pub anchor_scale: f64 = 0.25 => float(0.001, 10.0, "anchor coefficient step relative to step"),
        /// One anchor every `spacing` vertices of the coding order (plus one per connected
        /// component), 2..=65536. Default 40.
        pub spacing: u32 = 40 => int(2, 65536, "one anchor every spacing vertices (plus one per component)"),
        /// Code the coefficient fields in the domain of the average mesh's cotangent Laplacian
        /// (true, the method) or directly by parallelogram prediction (false, for comparison).
        pub laplacian: bool = true => boolean(
            "code the coefficient fields as cotangent-Laplacian deltas with anchors (false: parallelogram prediction)"
        ),
        /// Frames per independently coded packet (0 = the whole sequence). Default 0.
        pub block: u32 = 0 => int(0, 1 << 20, "frames per independently coded packet, 0 = whole sequence (bounds memory)"),
    }
}

impl LaplacianParams {
    /// Checks every field against its range; the error names the field and states the
    /// allowed range.
    pub fn validate(&self) -> Result<()> {
        self.to_param_set().map(|_| ())
    }
}

#[cfg(test)]
mod tests {
    /// The declaration's specs, parsing and printing agree for every value of every parameter.
    #[test]
    fn declared_params_are_consistent() {
        codec_core::testing::check_declared_params::<super::LaplacianParams>();
    }
}
