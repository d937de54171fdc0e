//! The measured point itself, as data: what [`measure_point`](super::measure_point) returns
//! and what sweeps, searches, targets and errors hold. Its own module (importing nothing of the
//! harness) so the error type can carry points ([`TargetMiss`](super::TargetMiss)) while every
//! function returning that error sits above it.

use codec_core::{ParamSet, ParamValue};
use metrics::MetricReport;

/// One measured (codec, parameters) point.
#[derive(Debug, Clone)]
pub struct Point {
    /// Codec name.
    pub codec: &'static str,
    /// The curve this point belongs to: the codec name, or for a
    /// [`SweepSeries`](super::SweepSeries) with non-default base parameters `codec[key=value,…]`.
    pub series: String,
    /// Parameters used.
    pub params: ParamSet,
    /// The ladder's parameter.
    pub ladder_param: &'static str,
    /// Position on the codec's rate ladder (0 = smallest stream).
    pub ladder_index: usize,
    /// Container size in bytes (header and topology included).
    pub bytes: u64,
    /// Bits per vertex per frame of the whole container.
    pub bpvf: f64,
    /// Every metric of the decoded animation against the input.
    pub report: MetricReport,
    /// Wall-clock encoding time.
    pub encode_seconds: f64,
    /// Wall-clock decoding time (from the container bytes alone).
    pub decode_seconds: f64,
    /// Measured by the envelope sweep's refinement toward the standard targets
    /// ([`STANDARD_TARGETS`](super::STANDARD_TARGETS)), possibly between two ladder steps
    /// (then `ladder_index` is the step above it): not one of the ladder's own points.
    pub refined: bool,
}

impl Point {
    /// The ladder parameter's value.
    pub fn ladder_value(&self) -> Option<&ParamValue> {
        self.params.get(self.ladder_param)
    }
}
