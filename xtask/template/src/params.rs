//! Parameters of `template`: one typed struct, its descriptions, and the conversions to and
//! from the generic `ParamSet` every codec exchanges with the command line, the harness and the
//! conformance suite. Kept alone in this file so that moving to a declarative form changes
//! nothing else.

use codec_core::params::{ParamSet, ParamSpec, ParamValue};
use codec_core::{Error, Result};

use crate::NAME;

/// Typed parameters of `template`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TemplateParams {
    /// Quantization step relative to the bounding-box diagonal of each packet's frames,
    /// 1e-6..=0.1. Default 0.001. Every coordinate is within half a step.
    pub step: f64,
    /// Frames per packet (random-access granularity), 1..=65536. Default 32.
    pub block: u32,
}

impl Default for TemplateParams {
    fn default() -> Self {
        Self { step: 1e-3, block: 32 }
    }
}

impl TemplateParams {
    /// Parameter descriptions, with the defaults of [`TemplateParams::default`].
    pub fn specs() -> Vec<ParamSpec> {
        let d = Self::default();
        vec![
            ParamSpec::float(
                "step",
                1e-6,
                0.1,
                d.step,
                "quantization step relative to the bounding-box diagonal; max error is half a step",
            ),
            ParamSpec::int("block", 1, 65536, d.block as i64, "frames per packet (random-access granularity)"),
        ]
    }

    /// Checks every field against the ranges in [`TemplateParams::specs`]; the error names
    /// the field and states the allowed range.
    pub fn validate(&self) -> Result<()> {
        self.to_param_set().map(|_| ())
    }

    /// Reads the typed parameters from a [`ParamSet`] made for this codec. A `ParamSet` only
    /// holds values checked against the specs, so the narrowing cast below is in range.
    pub fn from_param_set(p: &ParamSet) -> Result<Self> {
        if p.codec() != NAME {
            return Err(Error::parameter(NAME, "params", format!("parameters belong to codec '{}'", p.codec())));
        }
        Ok(Self { step: p.float("step")?, block: p.int("block")? as u32 })
    }

    /// The generic form of these parameters; fails like [`TemplateParams::validate`].
    pub fn to_param_set(&self) -> Result<ParamSet> {
        let specs = Self::specs();
        ParamSet::defaults(NAME, &specs).with(&specs, "step", ParamValue::Float(self.step))?.with(
            &specs,
            "block",
            ParamValue::Int(self.block as i64),
        )
    }
}
