//! One measured point: encode an animation at one parameter set, decode the stream from its
//! bytes alone, measure the decoded animation. Everything else in the harness is built on
//! [`measure_point`].

use std::time::Instant;

use codec_core::{
    encode_animation_fed, Animation, AnimationCodec, CodecRegistry, Limits, ParamSet, ParamValue, RateLadder,
    StreamDecoder,
};
use metrics::{EvalOptions, MetricReport};

use crate::error::{EvalError, Result};

/// Indices of `points` ladder steps spread evenly over a ladder of `len` steps, always
/// including both ends (`None`, or `points ≥ len`: every step). Sorted, without repeats.
pub fn ladder_indices(len: usize, points: Option<usize>) -> Vec<usize> {
    match points {
        _ if len == 0 => Vec::new(),
        None => (0..len).collect(),
        Some(n) if n >= len => (0..len).collect(),
        Some(0) => Vec::new(),
        Some(1) => vec![len - 1],
        Some(n) => {
            // Rounded positions i·(len−1)/(n−1); distinct because n < len.
            let mut v: Vec<usize> = (0..n).map(|i| (i * (len - 1) + (n - 1) / 2) / (n - 1)).collect();
            v.dedup();
            v
        }
    }
}

/// `base` with the ladder's parameter set to `step`, validated by the codec (so a step that
/// conflicts with a fixed parameter is an error naming both).
pub fn ladder_params(
    codec: &dyn AnimationCodec,
    base: &ParamSet,
    ladder: &RateLadder,
    step: usize,
) -> Result<ParamSet> {
    let value = ladder.steps.get(step).ok_or(EvalError::NoSuchLadderStep {
        codec: codec.name(),
        step,
        steps: ladder.steps.len(),
    })?;
    let params = base.clone().with(&codec.param_specs(), ladder.param, value.clone())?;
    codec.validate(&params)?;
    Ok(params)
}

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
}

impl Point {
    /// The ladder parameter's value.
    pub fn ladder_value(&self) -> Option<&ParamValue> {
        self.params.get(self.ladder_param)
    }
}

/// Encodes `animation` with `codec` at `params`, decodes it through the container and
/// measures it. Also returns the container bytes.
pub fn measure_point(
    registry: &CodecRegistry,
    codec: &dyn AnimationCodec,
    params: &ParamSet,
    (ladder_param, ladder_index): (&'static str, usize),
    animation: &Animation,
    eval: &EvalOptions,
    limits: Limits,
) -> Result<(Point, Vec<u8>)> {
    let start = Instant::now();
    let encoded = encode_animation_fed(codec, params, animation, false, animation.frame_count())?;
    let bytes = encoded.bytes;
    let encode_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let decoded = StreamDecoder::new(bytes.as_slice(), registry, limits)?.decode_all()?;
    let decode_seconds = start.elapsed().as_secs_f64();
    // A stream that decodes to non-finite coordinates is garbage whatever its metrics say
    // (issue 26): never a measured point, so never chosen by a search.
    if decoded.positions().iter().any(|x| !x.is_finite()) {
        return Err(EvalError::NonFiniteDecode { codec: codec.name() });
    }
    let mut report = metrics::evaluate(animation, &decoded, eval)?;
    // The encoder's warnings (a fallback it took to stay within its bound, issue 26) travel with
    // the point, so a search's answer reports them as a plain encode does.
    report.notes.extend(encoded.notes.into_iter().map(|n| format!("encoder: {n}")));
    let size = bytes.len() as u64;
    let point = Point {
        codec: codec.name(),
        series: codec.name().to_string(),
        params: params.clone(),
        ladder_param,
        ladder_index,
        bytes: size,
        bpvf: metrics::bpvf(size, animation.vertex_count(), animation.frame_count())?,
        report,
        encode_seconds,
        decode_seconds,
    };
    Ok((point, bytes))
}
