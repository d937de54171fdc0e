//! Target search along one rate ladder ([`search_target`]) and over several codecs
//! ([`search_target_auto`]), the request every search takes ([`SearchRequest`]), and the
//! helpers the other searches share (the bracket midpoint, the smallest stream over codecs).

use codec_core::{Animation, AnimationCodec, CodecRegistry, Limits, ParamSet, ParamValue};
use metrics::EvalOptions;

use super::input::{measure_point_streamed, SearchInput, StreamedInput};
use super::measured::Point;
use super::point::{ladder_params, measure_point, round_between};
use super::target::{meets, usable, Target, TargetHit, TargetMiss};
use crate::error::{EvalError, Result};

/// What every target search takes besides the codec: the codecs a stream may name, the input,
/// the target, how to measure, how far to refine, and who hears about each measured point.
#[derive(Clone, Copy)]
pub struct SearchRequest<'a> {
    /// Decoders for the streams measured.
    pub registry: &'a CodecRegistry,
    /// The input every candidate is encoded from and measured against: the whole animation,
    /// or a source read frame by frame within a memory budget. The searches are the same;
    /// only what measuring a candidate does differs (`SearchRequest::measure`).
    pub input: SearchInput<'a>,
    /// The error to meet.
    pub target: Target,
    /// Metric options; a search computes only its target's metric (see
    /// [`Target::eval_options`]), with these STED
    /// parameters.
    pub eval: EvalOptions,
    /// Decoder limits.
    pub limits: Limits,
    /// Extra points measured between the last failing and the first passing ladder step.
    pub refine: usize,
    /// Called with every point as soon as it is measured (a search on real data runs for
    /// minutes; the command line shows the latest point). Searches over a space call it from
    /// several threads.
    pub progress: &'a (dyn Fn(&Point) + Sync),
    /// Measure every point with all of `eval`'s metrics, not only the target's: the chosen
    /// point's report is then a full evaluation of its stream (`encode --target --eval`), at
    /// the cost of those metrics on every candidate.
    pub measure_every_metric: bool,
}

impl<'a> SearchRequest<'a> {
    /// A search for `target` on `animation`: default metric options and limits, no
    /// refinement, no progress reports.
    pub fn new(registry: &'a CodecRegistry, animation: &'a Animation, target: Target) -> Self {
        Self::on(registry, SearchInput::Whole(animation), target)
    }

    /// A search for `target` on a streamed input: each candidate is encoded from one read of
    /// the source and measured against another, within its memory budget.
    pub fn streamed(registry: &'a CodecRegistry, input: &'a StreamedInput<'a>, target: Target) -> Self {
        Self::on(registry, SearchInput::Streamed(input), target)
    }

    /// A search for `target` on `input`: default metric options and limits, no refinement, no
    /// progress reports.
    pub fn on(registry: &'a CodecRegistry, input: SearchInput<'a>, target: Target) -> Self {
        Self {
            registry,
            input,
            target,
            eval: EvalOptions::default(),
            limits: Limits::default(),
            refine: 0,
            progress: &|_| {},
            measure_every_metric: false,
        }
    }

    /// Measures one candidate (`codec` at `params`, at `ladder` = (parameter, index)) with
    /// `eval`: [`measure_point`] on a whole input, [`measure_point_streamed`] on a streamed one.
    /// On a streamed input the stream is kept only when it can still be chosen (it meets the
    /// target and no passing stream measured before is smaller): the others are returned
    /// empty, so the search holds at most two streams.
    pub(crate) fn measure(
        &self,
        codec: &dyn AnimationCodec,
        params: &ParamSet,
        ladder: (&'static str, usize),
        eval: &EvalOptions,
    ) -> Result<(Point, Vec<u8>)> {
        match self.input {
            SearchInput::Whole(animation) => {
                measure_point(self.registry, codec, params, ladder, animation, eval, self.limits)
            }
            SearchInput::Streamed(input) => {
                let (point, stream) =
                    measure_point_streamed(self.registry, codec, params, ladder, input, eval, self.limits)?;
                let passes = usable(&point) && meets(self.target, &point);
                let stream = if input.keep(point.bytes, passes) { stream } else { Vec::new() };
                Ok((point, stream))
            }
        }
    }

    /// The metric options a candidate is measured with: the target's metrics only, or with
    /// [`Self::measure_every_metric`] those of `eval` as well.
    pub(crate) fn metric_options(&self) -> EvalOptions {
        let target = self.target.eval_options(&self.eval);
        if self.measure_every_metric {
            EvalOptions {
                compute_sted: target.compute_sted || self.eval.compute_sted,
                compute_hausdorff: target.compute_hausdorff || self.eval.compute_hausdorff,
                ..target
            }
        } else {
            target
        }
    }
}

/// Finds the smallest stream `codec` makes of `animation` whose decoded error meets `target`,
/// walking the codec's rate ladder with the other parameters fixed at `base`.
///
/// Search: errors are assumed to fall along the ladder (small streams first). The top step is
/// measured first (if it misses, nothing can meet the target); then a binary search finds the
/// first passing step `k`, which leaves `k` measured as passing and `k − 1` (if any) as
/// failing. As a check near the answer, `k − 2` is measured as well (one extra point). If the
/// points measured are *not* monotone (a later step has a larger error than an earlier one,
/// beyond float noise; e.g. `k − 2` passes although `k − 1` fails), the assumption is broken,
/// so every step below `k` is measured too (a linear scan; ladders are short). Among all
/// passing points measured, the one with the fewest bytes wins (ties: lower ladder position).
/// A non-monotone stretch far below the answer that the binary search never touches can go
/// unnoticed: only a full scan would find it, and a full scan costs the whole ladder.
///
/// Ladders are coarse (hosvd's `ss` 0.9 → 0.85 can be the difference between just missing
/// and meeting the target with room to spare), so with `refine > 0` and a monotone ladder the
/// search then bisects the ladder parameter between the failing step `k − 1` and the passing
/// step `k` for up to `refine` more points (integers stop when the bracket closes; choices
/// cannot be refined). Refined points carry ladder index `k` and their exact value in
/// `params`. Only measured points are ever chosen, so the answer always meets the target.
///
/// Every point is passed to `request.progress` as soon as it is measured.
///
/// Errors: invalid parameters or codec failures as errors; no passing point as
/// [`EvalError::TargetMiss`].
pub fn search_target(request: &SearchRequest<'_>, codec: &dyn AnimationCodec, base: &ParamSet) -> Result<TargetHit> {
    let SearchRequest { target, refine, progress, .. } = *request;
    let ladder = codec.rate_ladder(base);
    let n = ladder.steps.len();
    let eval = request.metric_options();
    let mut measured: Vec<Option<(Point, Vec<u8>)>> = vec![None; n];
    let measure = |i: usize, measured: &mut Vec<Option<(Point, Vec<u8>)>>| -> Result<bool> {
        if measured[i].is_none() {
            let params = ladder_params(codec, base, &ladder, i)?;
            let (point, bytes) = request.measure(codec, &params, (ladder.param, i), &eval)?;
            progress(&point);
            measured[i] = Some((point, bytes));
        }
        let p = &measured[i].as_ref().expect("measured above").0;
        Ok(usable(p) && meets(target, p))
    };
    let miss = |measured: &[Option<(Point, Vec<u8>)>]| -> EvalError {
        let best = measured
            .iter()
            .flatten()
            .filter_map(|(p, _)| target.error(&p.report).map(|v| (v, p)))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, p)| p.clone());
        TargetMiss { codec: codec.name(), target, best, refused: Vec::new() }.into()
    };
    if n == 0 {
        return Err(EvalError::EmptyLadder { codec: codec.name() });
    }
    if !measure(n - 1, &mut measured)? {
        return Err(miss(&measured));
    }
    let (mut lo, mut hi) = (0, n - 1);
    while lo < hi {
        let mid = (lo + hi) / 2;
        if measure(mid, &mut measured)? {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    let k = hi;
    // Check one more point near the answer: `k − 1` failed, so with a monotone ladder `k − 2`
    // fails too. If it passes, the ladder is not monotone here.
    if k >= 2 {
        measure(k - 2, &mut measured)?;
    }
    let values: Vec<f64> =
        measured.iter().flatten().map(|(p, _)| target.error(&p.report).unwrap_or(f64::INFINITY)).collect();
    let monotone = values.windows(2).all(|w| w[1] <= w[0] + 1e-9 * w[0].abs().max(w[1].abs()) || w[0].is_infinite());
    if !monotone {
        for i in 0..k {
            measure(i, &mut measured)?;
        }
    }
    // Degenerate reconstructions (KG > 50 %) never meet a target, whatever the metric says.
    let passes = |p: &Point| usable(p) && meets(target, p);
    let mut tried: Vec<(Point, Vec<u8>)> = measured.into_iter().flatten().collect();
    if monotone && k >= 1 {
        let (mut fail, mut pass) = (ladder.steps[k - 1].clone(), ladder.steps[k].clone());
        let specs = codec.param_specs();
        for _ in 0..refine {
            let Some(mid) = midpoint(&fail, &pass) else { break };
            let Ok(params) = base.clone().with(&specs, ladder.param, mid.clone()) else { break };
            if codec.validate(&params).is_err() {
                break;
            }
            let (point, bytes) = request.measure(codec, &params, (ladder.param, k), &eval)?;
            progress(&point);
            if passes(&point) {
                pass = mid;
            } else {
                fail = mid;
            }
            tried.push((point, bytes));
        }
    }
    let best = tried
        .iter()
        .filter(|(p, _)| passes(p))
        .min_by_key(|(p, _)| (p.bytes, p.ladder_index))
        .cloned()
        .expect("the top step passed");
    Ok(TargetHit {
        point: best.0,
        stream: best.1,
        tried: tried.into_iter().map(|(p, _)| p).collect(),
        linear_fallback: !monotone,
        rejected: Vec::new(),
    })
}

/// The value halfway between two ladder values, or `None` when there is nothing in between
/// (adjacent integers, equal values, choices, booleans).
pub(crate) fn midpoint(a: &ParamValue, b: &ParamValue) -> Option<ParamValue> {
    match (a, b) {
        (ParamValue::Int(a), ParamValue::Int(b)) if a.abs_diff(*b) > 1 => Some(ParamValue::Int(a + (b - a) / 2)),
        (ParamValue::Float(a), ParamValue::Float(b)) => round_between(*a, *b, 0.5).map(ParamValue::Float),
        _ => None,
    }
}

/// [`search_target`] for every codec in `codecs` (each at its default parameters), keeping
/// the smallest stream (ties: the earlier codec). Codecs that cannot meet the target are
/// skipped; if none can, [`EvalError::NoCodecMeetsTarget`] lists each codec's miss. Other codec
/// failures are errors.
pub fn search_target_auto(
    request: &SearchRequest<'_>,
    codecs: &[&dyn AnimationCodec],
) -> Result<(TargetHit, Vec<TargetHit>)> {
    smallest_over_codecs(codecs, request.target, |codec| search_target(request, codec, &codec.default_params()))
}

/// Runs `search` for every codec in order and keeps the smallest stream (ties: the earlier
/// codec); codecs that miss the target are skipped, and if all do, the error lists each one's
/// miss. Other failures are errors.
pub(crate) fn smallest_over_codecs(
    codecs: &[&dyn AnimationCodec],
    target: Target,
    mut search: impl FnMut(&dyn AnimationCodec) -> Result<TargetHit>,
) -> Result<(TargetHit, Vec<TargetHit>)> {
    let mut hits = Vec::new();
    let mut misses = Vec::new();
    for &codec in codecs {
        match search(codec) {
            Ok(hit) => hits.push(hit),
            Err(EvalError::TargetMiss(miss)) => misses.push(*miss),
            Err(e) => return Err(EvalError::InCodec { codec: codec.name(), source: Box::new(e) }),
        }
    }
    let best = hits
        .iter()
        .enumerate()
        .min_by_key(|(i, h)| (h.point.bytes, *i))
        .map(|(i, _)| i)
        .ok_or(EvalError::NoCodecMeetsTarget { target, misses })?;
    let chosen = hits.remove(best);
    Ok((chosen, hits))
}
