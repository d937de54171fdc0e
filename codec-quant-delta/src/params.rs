//! Parameters of `quant-delta`, each declared once ([`codec_core::declare_params!`]).

use codec_core::Result;

use crate::NAME;

codec_core::declare_params! {
    codec: NAME;
    /// Typed parameters of `quant-delta`.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct QuantDeltaParams {
        /// Bits per coordinate, 1..=24. Default 12.
        pub bits: u8 = 12
            => int(1, 24, "bits per coordinate; max error is half a step of the packet's range"),
        /// Frames per packet (random-access granularity), 1..=65536. Default 32.
        pub block: u32 = 32 => int(1, 65536, "frames per packet (random-access granularity)"),
        /// zstd level, 1..=22. Default 15.
        pub level: i32 = 15 => int(1, 22, "zstd compression level"),
    }
}

impl QuantDeltaParams {
    /// Checks every field against the ranges in [`QuantDeltaParams::specs`]; the error
    /// names the field and states the allowed range.
    pub fn validate(&self) -> Result<()> {
        self.to_param_set().map(|_| ())
    }
}
