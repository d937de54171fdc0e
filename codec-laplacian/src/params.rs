//! Parameters of `laplacian`: one declaration per parameter (`codec_core::declare_params!`
//! writes the struct, `Default`, `specs()`, `from_param_set` and `to_param_set` from it).
//! Cross-field rules, if a codec has any, go in the macro's `after_read` / `after_write`
//! hooks (see `codec_core::declare_params!`).

use codec_core::Result;

use crate::NAME;

codec_core::declare_params! {
    codec: NAME;
    /// Typed parameters of `laplacian`.
    #[derive(Debug, Clone, Copy, PartialEq)]
    pub struct LaplacianParams {
        /// Quantization step relative to the bounding-box diagonal of each packet's frames,
        /// 1e-6..=0.1. Default 0.001. Every coordinate is within half a step.
        pub step: f64 = 1e-3
            => float(1e-6, 0.1, "quantization step relative to the bounding-box diagonal; max error is half a step"),
        /// Frames per packet (random-access granularity), 1..=65536. Default 32.
        pub block: u32 = 32 => int(1, 65536, "frames per packet (random-access granularity)"),
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
