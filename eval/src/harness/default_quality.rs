//! The default encode's search (no parameters, no target): one encode at the codec's defaults
//! when it lands near [`DEFAULT_TARGET`], otherwise a short gallop and bisection along the rate
//! ladder.

use codec_core::{Animation, AnimationCodec, CodecRegistry, ParamSet, ParamValue};

use super::measured::Point;
use super::point::{ladder_params, round_to};
use super::search::{midpoint, SearchRequest};
use super::target::{meets, usable, Target, TargetHit, TargetMetric, TargetMiss};
use crate::error::{EvalError, Result};

/// The quality every command aims at when given neither parameters nor a target: KG ≤ 0.5 %
/// (the whole animation's and its worst part's) and STED ≤ 0.05, the middle joint target
/// the peers are compared at. KG alone passes streams whose surface crawls (horse-gallop's
/// default stream at KG 0.49 has STED 0.14); STED alone passes a mesh frozen in frame 0
/// (STED 0.04–0.1 on the dev animations at KG 35–761). See the README's "Quality by default".
pub const DEFAULT_TARGET: Target = Target::new(TargetMetric::Kg, 0.5).and_bound(TargetMetric::Sted, 0.05);

/// How far below [`DEFAULT_TARGET`] a codec's own defaults may land and still be the default
/// encode's answer: a first encode whose error lies in `[target / band, target]` is kept as it
/// is. A factor of 3 keeps the default quality within 3× across inputs (the largest
/// KG at most 3× the smallest over one character's clips) while most inputs cost one encode.
pub const DEFAULT_QUALITY_BAND: f64 = 3.0;

/// Once the default encode has searched, it refines between two ladder steps while its answer
/// is more than this factor below [`DEFAULT_TARGET`] (a stream at a third of the target error
/// can be half again too large; within 1.25× the next encode buys little).
pub const DEFAULT_REFINE_BAND: f64 = 1.25;

/// How many steps past its last the default encode continues a rate ladder whose every step
/// misses the target (continuing its last two steps' progression), before it reports the miss.
pub const BEYOND_LADDER_STEPS: usize = 4;

/// The default encode (no parameters, no target): one encode at the codec's defaults, kept
/// when its error lies within [`DEFAULT_QUALITY_BAND`] of [`DEFAULT_TARGET`]. Otherwise (a
/// short clip the codec's size model overshoots, a smooth one it undershoots) the search
/// starts from there: it gallops along the rate ladder towards the target (1, 2, 4 … steps),
/// bisects the bracket it finds, and refines between the two ladder steps up to `refine`
/// times while the answer is more than [`DEFAULT_REFINE_BAND`] below the target. When every
/// step misses, the last included, it continues the ladder [`BEYOND_LADDER_STEPS`] steps past
/// its end, and refines likewise between the last miss and the first pass. Typically
/// one to four encodes; the whole declared parameter space
/// ([`search_space_target`](super::search_space_target)) is for an explicit `--target`, where
/// tens of encodes buy smaller streams.
///
/// The target is `request.target`: [`DEFAULT_TARGET`] for the default encode
/// ([`SearchRequest::default_quality`]); the bands are relative to it.
pub fn search_default_quality(request: &SearchRequest<'_>, codec: &dyn AnimationCodec) -> Result<TargetHit> {
    let SearchRequest { target, refine, progress, .. } = *request;
    let eval = request.metric_options();
    let base = codec.default_params();
    let ladder = codec.rate_ladder(&base);
    let n = ladder.steps.len();
    if n == 0 {
        return Err(EvalError::EmptyLadder { codec: codec.name() });
    }
    let start = ladder.steps.iter().position(|v| base.get(ladder.param) == Some(v));
    let mut tried: Vec<(Point, Vec<u8>)> = Vec::new();
    let mut rejected: Vec<String> = Vec::new();
    // Measures `params` (at ladder position `index`); true when it meets the target. A codec
    // refusal counts as a miss and its reason is kept (hosvd's one-frame advice, say).
    let measure = |params: &ParamSet,
                   index: usize,
                   tried: &mut Vec<(Point, Vec<u8>)>,
                   rejected: &mut Vec<String>|
     -> Result<bool> {
        match request.measure(codec, params, (ladder.param, index), &eval) {
            Ok((point, stream)) => {
                progress(&point);
                let pass = usable(&point) && meets(target, &point);
                tried.push((point, stream));
                Ok(pass)
            }
            Err(e) => {
                rejected.push(e.to_string());
                Ok(false)
            }
        }
    };
    let at = |i: usize| ladder_params(codec, &base, &ladder, i);
    // The codec's defaults first (they are a ladder step for every registered codec; if not,
    // the middle of the ladder).
    let first = start.unwrap_or(n / 2);
    let first_pass = measure(&base, first, &mut tried, &mut rejected)?;
    let in_band = |p: &Point| target.error(&p.report).is_some_and(|v| v >= target.level() / DEFAULT_QUALITY_BAND);
    if first_pass && tried.last().is_some_and(|(p, _)| in_band(p)) {
        let (point, stream) = tried.pop().expect("measured above");
        return Ok(TargetHit { tried: vec![point.clone()], point, stream, linear_fallback: false, rejected });
    }
    // Gallop towards the target: up the ladder (larger streams) after a miss, down after a
    // pass far below the target, until the outcome flips or the ladder ends.
    let (mut fail, mut pass): (Option<usize>, Option<usize>) =
        if first_pass { (None, Some(first)) } else { (Some(first), None) };
    let mut stride = 1;
    loop {
        let next =
            if first_pass { pass.map(|p| p.saturating_sub(stride)) } else { fail.map(|f| (f + stride).min(n - 1)) };
        let Some(i) = next.filter(|&i| Some(i) != fail && Some(i) != pass) else { break };
        if measure(&at(i)?, i, &mut tried, &mut rejected)? {
            pass = Some(i);
            if !first_pass {
                break;
            }
        } else {
            fail = Some(i);
            if first_pass {
                break;
            }
        }
        stride *= 2;
    }
    let specs = codec.param_specs();
    // The parameters with the ladder's parameter at `value` (between or past its steps), if
    // the codec takes them.
    let with_value = |value: &ParamValue| {
        base.clone().with(&specs, ladder.param, value.clone()).ok().filter(|params| codec.validate(params).is_ok())
    };
    // The bracket to refine in: a failing and a passing value, and the passing ladder position.
    let mut bracket = None;
    if let (Some(mut f), Some(mut p)) = (fail, pass) {
        // Bisect the ladder bracket to adjacent steps.
        while f.abs_diff(p) > 1 {
            let mid = (f + p) / 2;
            if measure(&at(mid)?, mid, &mut tried, &mut rejected)? {
                p = mid;
            } else {
                f = mid;
            }
        }
        bracket = Some((ladder.steps[f].clone(), ladder.steps[p].clone(), p));
    } else if pass.is_none() && fail == Some(n - 1) {
        // The last step missed: continue the ladder's own progression a few steps. A ladder
        // is sized on typical meshes, and a finer mesh needs more: pca-aoi's ends at KG
        // 0.05 %, which meets STED ≤ 0.05 on a 100 000-vertex flag, but on the 1 000 000-vertex
        // flag, whose edges are three times shorter, the same positional error is a larger
        // relative one (STED 0.071 at kg=0.05, 0.030 at kg=0.02).
        let mut last_fail = ladder.steps[n - 1].clone();
        for k in 1..=BEYOND_LADDER_STEPS {
            let Some(value) = beyond_ladder(&ladder.steps, k) else { break };
            let Some(params) = with_value(&value) else { break };
            if measure(&params, n - 1, &mut tried, &mut rejected)? {
                bracket = Some((last_fail, value, n - 1));
                break;
            }
            last_fail = value;
        }
    }
    // Between the bracket's values, while the answer is far below the target.
    if let Some((mut fail_value, mut pass_value, p)) = bracket {
        for _ in 0..refine {
            let far_below = tried
                .iter()
                .filter(|(pt, _)| usable(pt) && meets(target, pt))
                .min_by_key(|(pt, _)| pt.bytes)
                .is_some_and(|(pt, _)| {
                    target.error(&pt.report).is_some_and(|v| v < target.level() / DEFAULT_REFINE_BAND)
                });
            let Some(mid) = midpoint(&fail_value, &pass_value).filter(|_| far_below) else { break };
            let Some(params) = with_value(&mid) else { break };
            if measure(&params, p, &mut tried, &mut rejected)? {
                pass_value = mid;
            } else {
                fail_value = mid;
            }
        }
    }
    let mut best = tried.iter().filter(|(p, _)| usable(p) && meets(target, p)).min_by_key(|(p, _)| p.bytes).cloned();
    // When the codec refused candidates and nothing passed (the gallop after a miss only
    // climbs), the refusals may hide steps that work: scan the rest of the ladder (short; a
    // refusal costs no encode).
    if best.is_none() && !rejected.is_empty() {
        let seen: Vec<usize> = tried.iter().map(|(p, _)| p.ladder_index).collect();
        for i in (0..n).filter(|i| !seen.contains(i) && *i != first) {
            let Ok(params) = at(i) else { continue };
            measure(&params, i, &mut tried, &mut rejected)?;
        }
        best = tried.iter().filter(|(p, _)| usable(p) && meets(target, p)).min_by_key(|(p, _)| p.bytes).cloned();
    }
    match best {
        Some((point, stream)) => Ok(TargetHit {
            point,
            stream,
            tried: tried.into_iter().map(|(p, _)| p).collect(),
            linear_fallback: false,
            rejected,
        }),
        None => Err(TargetMiss::new(codec.name(), target, tried.iter().map(|(p, _)| p), rejected).into()),
    }
}

impl<'a> SearchRequest<'a> {
    /// The default encode's request: [`DEFAULT_TARGET`] on `animation`, default metric options
    /// and limits, no refinement, no progress reports.
    pub fn default_quality(registry: &'a CodecRegistry, animation: &'a Animation) -> Self {
        Self::new(registry, animation, DEFAULT_TARGET)
    }
}

/// The `k`-th value past the end of a numeric ladder, continuing its last two steps'
/// progression: geometric for floats (`last · (last / previous)^k`, to two significant
/// digits), arithmetic for integers (`last + k · (last − previous)`). `None` for a ladder of
/// fewer than two steps, one that does not move at its end, or other kinds of value.
pub(crate) fn beyond_ladder(steps: &[ParamValue], k: usize) -> Option<ParamValue> {
    let [.., previous, last] = steps else { return None };
    match (previous, last) {
        (ParamValue::Float(a), ParamValue::Float(b)) if *a > 0.0 && *b > 0.0 && a != b => {
            let x = b * (b / a).powi(i32::try_from(k).ok()?);
            let x = round_to(x, 10f64.powf(x.log10().floor() - 1.0));
            (x.is_finite() && x > 0.0).then_some(ParamValue::Float(x))
        }
        (ParamValue::Int(a), ParamValue::Int(b)) if a != b => {
            let step = b.checked_sub(*a)?.checked_mul(i64::try_from(k).ok()?)?;
            b.checked_add(step).map(ParamValue::Int)
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ladder_continues_its_own_progression() {
        let f = ParamValue::Float;
        let kg = [f(0.12), f(0.08), f(0.05)];
        let past: Vec<_> = (1..=4).map(|k| beyond_ladder(&kg, k)).collect();
        assert_eq!(past, [Some(f(0.031)), Some(f(0.02)), Some(f(0.012)), Some(f(0.0076))]);
        let bits = [ParamValue::Int(14), ParamValue::Int(16)];
        assert_eq!(beyond_ladder(&bits, 2), Some(ParamValue::Int(20)));
        assert_eq!(beyond_ladder(&[f(1.0), f(1.0)], 1), None);
        assert_eq!(beyond_ladder(&[f(1.0)], 1), None);
        assert_eq!(beyond_ladder(&[ParamValue::Int(i64::MAX - 1), ParamValue::Int(i64::MAX)], 1), None);
    }
}
