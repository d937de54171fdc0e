//! One measured point: encode an animation at one parameter set, decode the stream from its
//! bytes alone, measure the decoded animation. Everything else in the harness is built on
//! [`measure_point`].

use std::time::Instant;

use codec_core::{
    encode_animation_fed, Animation, AnimationCodec, CodecRegistry, Limits, ParamSet, ParamValue, RateLadder,
    StreamDecoder,
};
use metrics::EvalOptions;

use super::measured::Point;
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

/// Encodes `animation` with `codec` at `params`, decodes it through the container and
/// measures it. Also returns the container bytes.
pub fn measure_point(
    registry: &CodecRegistry,
    codec: &dyn AnimationCodec,
    params: &ParamSet,
    ladder: (&'static str, usize),
    animation: &Animation,
    eval: &EvalOptions,
    limits: Limits,
) -> Result<(Point, Vec<u8>)> {
    measure_point_keeping(registry, codec, params, ladder, animation, eval, limits)
        .map(|(point, bytes, _)| (point, bytes))
}

/// [`measure_point`], also returning the decoded animation it measured (for a caller that shows
/// it, so the stream need not be encoded or decoded again).
pub fn measure_point_keeping(
    registry: &CodecRegistry,
    codec: &dyn AnimationCodec,
    params: &ParamSet,
    (ladder_param, ladder_index): (&'static str, usize),
    animation: &Animation,
    eval: &EvalOptions,
    limits: Limits,
) -> Result<(Point, Vec<u8>, Animation)> {
    let start = Instant::now();
    let encoded = encode_animation_fed(codec, params, animation, false, animation.frame_count())?;
    let bytes = encoded.bytes;
    let encode_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let decoded = StreamDecoder::new(bytes.as_slice(), registry, limits)?.decode_all()?;
    let decode_seconds = start.elapsed().as_secs_f64();
    // A stream that decodes to non-finite coordinates is garbage whatever its metrics say:
    // never a measured point, so never chosen by a search.
    if decoded.positions().iter().any(|x| !x.is_finite()) {
        return Err(EvalError::NonFiniteDecode { codec: codec.name() });
    }
    let mut report = metrics::evaluate(animation, &decoded, eval)?;
    // The encoder's warnings (e.g. a fallback it took to stay within its bound) travel with
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
        refined: false,
    };
    Ok((point, bytes, decoded))
}

/// The ladder value at `position` and the position that value actually has: a step at an
/// integral position (or when `fractional` is false, the nearest step); between two numeric
/// steps, the interpolated value rounded to two digits below the steps' difference (floats:
/// 0.9168, not 0.916812…), integers rounded. Choices and booleans have only their steps.
pub(crate) fn value_at(ladder: &RateLadder, position: f64, fractional: bool) -> Option<(f64, ParamValue)> {
    let n = ladder.steps.len();
    if n == 0 || !position.is_finite() {
        return None;
    }
    let position = position.clamp(0.0, (n - 1) as f64);
    let step = |i: usize| Some((i as f64, ladder.steps[i].clone()));
    let lower = position.floor() as usize;
    let t = position - lower as f64;
    if !fractional || t < 1e-9 || lower + 1 >= n {
        return step(position.round() as usize);
    }
    let interpolated = match (&ladder.steps[lower], &ladder.steps[lower + 1]) {
        (ParamValue::Float(a), ParamValue::Float(b)) => {
            round_between(*a, *b, t).map(|x| (lower as f64 + (x - a) / (b - a), ParamValue::Float(x)))
        }
        (ParamValue::Int(a), ParamValue::Int(b)) if a.abs_diff(*b) > 1 => {
            // Rounded, but kept strictly between the steps: a position between two steps asks
            // for a value between them (bits 9 between 8 and 10, even when aimed near 8).
            let x = (*a as f64 + t * (*b - *a) as f64).round() as i64;
            let (low, high) = (a.min(b) + 1, a.max(b) - 1);
            let x = x.clamp(low, high);
            Some((lower as f64 + (x - a) as f64 / (b - a) as f64, ParamValue::Int(x)))
        }
        _ => None,
    };
    interpolated.or_else(|| step(position.round() as usize))
}

/// Whether the ladder's values can be interpolated (numbers), so that positions between
/// steps exist.
pub(crate) fn numeric(ladder: &RateLadder) -> bool {
    ladder.steps.iter().all(|v| matches!(v, ParamValue::Float(_) | ParamValue::Int(_)))
}

/// `a + t·(b − a)` rounded to two digits below the bracket's width, so values read like
/// 0.8969 rather than 0.8968750000000001; `None` once rounding reaches an end (nothing
/// between them) or `a = b`.
pub(crate) fn round_between(a: f64, b: f64, t: f64) -> Option<f64> {
    if a == b {
        return None;
    }
    let x = round_to(a + t * (b - a), 10f64.powf(((b - a).abs().log10() - 2.0).floor()));
    (x.is_finite() && x != a && x != b).then_some(x)
}

/// `x` rounded to a multiple of `unit` (a power of ten), printed digits and all: 0.031, not
/// 0.031000000000000003.
pub(crate) fn round_to(x: f64, unit: f64) -> f64 {
    let x = (x / unit).round() * unit;
    format!("{x:.12}").parse::<f64>().unwrap_or(x)
}
