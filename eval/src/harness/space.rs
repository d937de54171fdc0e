//! Target search over a codec's declared search space ([`search_space_target`]): every
//! configuration of its secondary parameters, each walked along the rate ladder, then refined
//! between ladder steps by secant steps.

use codec_core::{AnimationCodec, ParamSet, ParamValue, RateLadder};
use metrics::EvalOptions;
use rayon::prelude::*;

use super::measured::Point;
use super::point::{ladder_params, measure_point};
use super::search::{midpoint, smallest_over_codecs, SearchRequest};
use super::target::{meets, usable, Target, TargetHit, TargetMiss};
use crate::error::{EvalError, Result};

/// One candidate of a space search: its ladder position and what measuring it gave (the
/// point and stream, or why it was rejected).
struct Candidate {
    index: usize,
    outcome: Result<(Point, Vec<u8>), String>,
}

/// One configuration of the secondary axes as searched: its parameters, ladder and
/// candidates in measuring order, the lowest passing ladder position and the highest failing
/// one below it.
struct ConfigRun {
    params: ParamSet,
    ladder: RateLadder,
    candidates: Vec<Candidate>,
    pass: Option<usize>,
    fail_below: Option<usize>,
}

/// What a space search needs for every measurement: the request, the codec searched, and the
/// metric options its candidates are measured with.
struct SpaceSearcher<'a> {
    request: &'a SearchRequest<'a>,
    codec: &'a dyn AnimationCodec,
    target: Target,
    eval: EvalOptions,
}

impl SpaceSearcher<'_> {
    fn measure(&self, params: &ParamSet, ladder_param: &'static str, index: usize) -> Candidate {
        let request = self.request;
        let outcome = measure_point(
            request.registry,
            self.codec,
            params,
            (ladder_param, index),
            request.animation,
            &self.eval,
            request.limits,
        )
        .map_err(|e| format!("{} [{params}]: {e}", self.codec.name()));
        if let Ok((p, _)) = &outcome {
            (self.request.progress)(p);
        }
        Candidate { index, outcome }
    }

    fn passes(&self, c: &Candidate) -> bool {
        c.outcome.as_ref().is_ok_and(|(p, _)| usable(p) && meets(self.target, p))
    }

    fn step(&self, run: &ConfigRun, index: usize) -> Result<ParamSet> {
        ladder_params(self.codec, &run.params, &run.ladder, index)
    }

    /// Measures ladder position `index` of `run` (once) and says whether it meets the target.
    fn visit(&self, run: &mut ConfigRun, index: usize) -> Result<bool> {
        if let Some(c) = run.candidates.iter().find(|c| c.index == index) {
            return Ok(self.passes(c));
        }
        let params = self.step(run, index)?;
        let c = self.measure(&params, run.ladder.param, index);
        let pass = self.passes(&c);
        run.candidates.push(c);
        Ok(pass)
    }

    fn bytes_at(run: &ConfigRun, index: usize) -> Option<u64> {
        run.candidates.iter().find(|c| c.index == index).and_then(|c| c.outcome.as_ref().ok()).map(|(p, _)| p.bytes)
    }

    /// The first configuration, searched cold: a binary search for the first passing step.
    /// The top step (the largest, slowest stream) is measured only if nothing below it
    /// passes; if it misses too, nothing on this ladder meets the target.
    fn search_cold(&self, run: &mut ConfigRun) -> Result<()> {
        let n = run.ladder.steps.len();
        if n == 0 {
            return Ok(());
        }
        let (mut lo, mut hi) = (0, n - 1);
        while lo < hi {
            let mid = (lo + hi) / 2;
            if self.visit(run, mid)? {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        if !self.visit(run, hi)? {
            return Ok(());
        }
        run.pass = Some(hi);
        run.fail_below = hi.checked_sub(1);
        Ok(())
    }

    /// Another configuration, warm-started at `start` (the first configuration's answer;
    /// neighbouring configurations land on nearby steps): down while it passes, or up until it
    /// passes. Early stop: going up, a failing step whose stream already has `bound` bytes or
    /// more (the smallest passing stream found so far) ends the walk, since every larger step
    /// makes a larger stream.
    fn search_warm(&self, run: &mut ConfigRun, start: usize, bound: Option<u64>) -> Result<()> {
        let n = run.ladder.steps.len();
        if n == 0 {
            return Ok(());
        }
        let mut i = start.min(n - 1);
        if self.visit(run, i)? {
            while i > 0 && self.visit(run, i - 1)? {
                i -= 1;
            }
            run.pass = Some(i);
            run.fail_below = i.checked_sub(1);
            return Ok(());
        }
        loop {
            let over = matches!((bound, Self::bytes_at(run, i)), (Some(b), Some(x)) if x >= b);
            if over || i + 1 >= n {
                return Ok(());
            }
            i += 1;
            if self.visit(run, i)? {
                run.pass = Some(i);
                run.fail_below = Some(i - 1);
                return Ok(());
            }
        }
    }

    /// Refines the ladder parameter between the failing step below the answer and the
    /// answer, up to `refine` points (ladders are coarse): each point by the secant in
    /// log(error) (errors fall about exponentially along a rate axis), aimed just under the
    /// target and kept inside the middle 70% of the bracket so it always shrinks (bisection
    /// when the secant is undefined). Stops early once a passing point is within
    /// [`REFINE_CLOSE`] of the target (the stream cannot get much smaller). Refined points
    /// carry the answer's index.
    fn refine(&self, run: &mut ConfigRun, refine: usize) {
        let (Some(k), Some(f)) = (run.pass, run.fail_below) else { return };
        if f + 1 != k {
            return;
        }
        let value_at = |run: &ConfigRun, index: usize| {
            run.candidates
                .iter()
                .find(|c| c.index == index)
                .and_then(|c| c.outcome.as_ref().ok())
                .and_then(|(p, _)| self.target.metric.value(&p.report))
        };
        let mut fail = (run.ladder.steps[f].clone(), value_at(run, f));
        let mut pass = (run.ladder.steps[k].clone(), value_at(run, k));
        let specs = self.codec.param_specs();
        for _ in 0..refine {
            if pass.1.is_some_and(|v| v >= REFINE_CLOSE * self.target.value) {
                break;
            }
            let Some(next) =
                secant(&fail, &pass, REFINE_AIM * self.target.value).or_else(|| midpoint(&fail.0, &pass.0))
            else {
                break;
            };
            let Ok(params) = run.params.clone().with(&specs, run.ladder.param, next.clone()) else { break };
            if self.codec.validate(&params).is_err() {
                break;
            }
            let c = self.measure(&params, run.ladder.param, k);
            let value = c.outcome.as_ref().ok().and_then(|(p, _)| self.target.metric.value(&p.report));
            if self.passes(&c) {
                pass = (next, value);
            } else {
                fail = (next, value);
            }
            run.candidates.push(c);
        }
    }
}

/// A refined point meeting the target within this fraction of it ends the refinement.
const REFINE_CLOSE: f64 = 0.97;
/// The secant aims at this fraction of the target (just under it, so the point likely passes).
const REFINE_AIM: f64 = 0.985;

/// The parameter value where the error is expected to reach `aim`, by linear interpolation of
/// log(error) between the failing and passing ends of a bracket, kept within the middle 70%
/// of the bracket and rounded as [`midpoint`] rounds; `None` when the errors are missing or
/// not ordered, or the bracket holds nothing in between.
fn secant(fail: &(ParamValue, Option<f64>), pass: &(ParamValue, Option<f64>), aim: f64) -> Option<ParamValue> {
    let (Some(vf), Some(vp)) = (fail.1, pass.1) else { return None };
    if !(vf > vp && vp > 0.0 && aim > 0.0) {
        return None;
    }
    let t = ((aim.ln() - vf.ln()) / (vp.ln() - vf.ln())).clamp(0.15, 0.85);
    match (&fail.0, &pass.0) {
        (ParamValue::Int(a), ParamValue::Int(b)) => {
            let x = (*a as f64 + t * (*b - *a) as f64).round() as i64;
            (x != *a && x != *b && (x - a).signum() == (b - a).signum()).then_some(ParamValue::Int(x))
        }
        (ParamValue::Float(a), ParamValue::Float(b)) if a != b => {
            let unit = 10f64.powf(((b - a).abs().log10() - 2.0).floor());
            let x = ((a + t * (b - a)) / unit).round() * unit;
            let x = format!("{x:.12}").parse::<f64>().unwrap_or(x);
            (x.is_finite() && x != *a && x != *b).then_some(ParamValue::Float(x))
        }
        _ => None,
    }
}

/// Finds the smallest stream `codec` makes of `animation` meeting `target` over the codec's
/// declared [`SearchSpace`](codec_core::SearchSpace) on top of `base`: every configuration of
/// the secondary axes (minus the parameters in `fixed`, which the user set), each walked along
/// the primary rate ladder.
///
/// Search: the first configuration (the codec's usual one) cold, by a binary search over its
/// ladder (its top step measured only when nothing below passes); then every other configuration in parallel (rayon), each warm-started at the first
/// one's answer and walked up or down one step at a time, abandoned once a failing step's
/// stream is as large as the first configuration's answer (an early stop: its passing steps
/// can only be larger). Then the ladder parameter is bisected `refine` times between the last
/// failing and the first passing step (secant steps, see `SpaceSearcher::refine`), for the
/// best configuration and, in parallel, the runner-up when its answer is within 3% of the
/// best's bytes. Each configuration's walk
/// depends only on the first configuration's result, never on another running at the same
/// time, and the results are combined in configuration order: the chosen stream does not
/// depend on the thread count. Only measured points are ever chosen; a candidate that fails
/// to encode or decodes to non-finite coordinates is rejected (listed in
/// [`TargetHit::rejected`]), never chosen. Invalid configurations are skipped.
///
/// Assumes errors fall along each ladder (as [`search_target`] does); the single-axis
/// [`search_target`] remains for `--ladder`.
pub fn search_space_target(
    request: &SearchRequest<'_>,
    codec: &dyn AnimationCodec,
    base: &ParamSet,
    fixed: &[&str],
) -> Result<TargetHit> {
    let space = codec.search_space(base).without(fixed);
    let specs = codec.param_specs();
    let mut runs: Vec<ConfigRun> = space
        .configurations()
        .iter()
        .filter_map(|config| {
            let params = codec_core::SearchSpace::apply(base, &specs, config).ok()?;
            codec.validate(&params).ok()?;
            let ladder = codec.rate_ladder(&params);
            Some(ConfigRun { params, ladder, candidates: Vec::new(), pass: None, fail_below: None })
        })
        .collect();
    if runs.is_empty() {
        return Err(EvalError::NoValidConfiguration { codec: codec.name(), on: Some(base.to_string()) });
    }
    let target = request.target;
    let searcher = SpaceSearcher { request, codec, target, eval: request.metric_options() };
    let (first, others) = runs.split_first_mut().expect("checked non-empty");
    searcher.search_cold(first)?;
    let start = first.pass.unwrap_or(first.ladder.steps.len().saturating_sub(1));
    let bound = first.pass.and_then(|k| SpaceSearcher::bytes_at(first, k));
    others.par_iter_mut().map(|run| searcher.search_warm(run, start, bound)).collect::<Result<Vec<()>>>()?;

    // Refinement of the best configuration and a close runner-up, chosen in configuration order.
    let mut ranked: Vec<(u64, usize)> = runs
        .iter()
        .enumerate()
        .filter_map(|(i, run)| run.pass.and_then(|k| SpaceSearcher::bytes_at(run, k)).map(|b| (b, i)))
        .collect();
    ranked.sort();
    if let Some(&(best, _)) = ranked.first() {
        let chosen: Vec<usize> =
            ranked.iter().take(2).filter(|(b, _)| (*b as f64) <= best as f64 * 1.03).map(|(_, i)| *i).collect();
        runs.par_iter_mut().enumerate().filter(|(i, _)| chosen.contains(i)).for_each(|(_, run)| {
            searcher.refine(run, request.refine);
        });
    }

    let mut tried = Vec::new();
    let mut rejected = Vec::new();
    let mut best: Option<(Point, Vec<u8>)> = None;
    for run in runs {
        for c in run.candidates {
            let pass = searcher.passes(&c);
            match c.outcome {
                Ok((point, stream)) => {
                    if pass && best.as_ref().is_none_or(|(b, _)| point.bytes < b.bytes) {
                        best = Some((point.clone(), stream));
                    }
                    tried.push(point);
                }
                Err(message) => rejected.push(message),
            }
        }
    }
    match best {
        Some((point, stream)) => Ok(TargetHit { point, stream, tried, linear_fallback: false, rejected }),
        None => Err(TargetMiss::new(codec.name(), target, tried.iter(), rejected).into()),
    }
}

/// [`search_space_target`] for every codec in `codecs` (each on its defaults, nothing fixed),
/// keeping the smallest stream (ties: the earlier codec). Codecs that cannot meet the target
/// are skipped; if none can, the error lists each codec's best. Other failures are errors.
pub fn search_space_target_auto(
    request: &SearchRequest<'_>,
    codecs: &[&dyn AnimationCodec],
) -> Result<(TargetHit, Vec<TargetHit>)> {
    smallest_over_codecs(codecs, request.target, |codec| {
        search_space_target(request, codec, &codec.default_params(), &[])
    })
}
