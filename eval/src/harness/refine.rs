//! The envelope sweep's refinement toward the standard targets ([`STANDARD_TARGETS`]): which
//! points to measure next, from the points measured so far, so that the sweep's envelope holds
//! the streams a target search (`encode --target`) finds. The bracket rules are the space
//! search's (`space::search_space_target`): secant steps in log(error) along the ladder taken
//! as a continuous axis, the ladder's own steps first while the bracket is wider than one step.

use codec_core::{ParamValue, RateLadder};

use super::measured::Point;
use super::point::{numeric, value_at};
use super::target::{usable, Target, TargetMetric};

/// The targets the field compares codecs at, where the envelope sweep refines: KG ≤ 2, 0.5 and
/// 0.1 % (the peers' `rdsummary.py`), and KG and STED together, ≤ 2 & 0.1, ≤ 0.5 & 0.05 and
/// ≤ 0.1 & 0.02 (`rd_joint.py`; a user wants the motion and the surface right together). A
/// sweep reports the smallest measured stream meeting each; without points placed for them it
/// reports a ladder step's stream, up to 19 % larger than what `encode --target` finds
/// (horse-gallop at KG ≤ 0.1 & STED ≤ 0.02: 2.241 against 1.884 bpvf).
pub const STANDARD_TARGETS: [Target; 6] = [
    Target::new(TargetMetric::Kg, 2.0),
    Target::new(TargetMetric::Kg, 0.5),
    Target::new(TargetMetric::Kg, 0.1),
    Target::new(TargetMetric::Kg, 2.0).and_bound(TargetMetric::Sted, 0.1),
    Target::new(TargetMetric::Kg, 0.5).and_bound(TargetMetric::Sted, 0.05),
    Target::new(TargetMetric::Kg, 0.1).and_bound(TargetMetric::Sted, 0.02),
];

/// Refinement rounds of the default sweep (`sweep --refine-rounds`): each measures at most
/// [`CONFIGS_PER_TARGET`] points per codec and target, planned from every point measured
/// before it.
pub const REFINE_ROUNDS: usize = 5;

/// Configurations of a codec refined per target and round: those whose stream at the target
/// is predicted smallest. A configuration predicted larger than the codec's smallest passing
/// stream is not refined at all.
pub const CONFIGS_PER_TARGET: usize = 2;

/// A passing point within this fraction of the target (its error at least this share of the
/// target's level) ends the refinement of its bracket.
pub(crate) const REFINE_CLOSE: f64 = 0.97;
/// Secant steps aim at this fraction of the target (just under it, so the point likely passes).
pub(crate) const REFINE_AIM: f64 = 0.985;
/// A passing point that is not this much smaller than a larger passing point of its curve
/// ends the refinement of its bracket (as it ends a configuration's target search: samba at
/// STED ≤ 0.1 spent 5 more points on one rank for 1.4%).
pub(crate) const PLATEAU: f64 = 0.99;
/// A bracket narrower than this (in ladder positions) is not refined further: the error is a
/// step function of some ladders (hosvd's ranks), and the stream hardly changes inside it.
/// Not wider: on horse-gallop at KG ≤ 0.1 a bracket of 0.1 position (hosvd `ss` 0.664 → 0.654)
/// still spans 7% of stream size.
pub(crate) const MIN_WIDTH: f64 = 0.05;

/// One curve of the sweep as the refinement sees it: its codec, label and ladder, and for each
/// target planned for (by position) whether the curve's configuration is in the part of the
/// codec's space a target search for that kind of error walks
/// ([`AnimationCodec::search_space_for`](codec_core::AnimationCodec::search_space_for)): only
/// those are refined for it, as only those are searched.
pub(crate) struct Curve<'a> {
    pub codec: &'static str,
    pub label: &'a str,
    pub ladder: RateLadder,
    pub searched_for: Vec<bool>,
}

/// A point the refinement measures: the curve (its position in the slice planned over), the
/// ladder position and the ladder value there.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Job {
    pub curve: usize,
    pub position: f64,
    pub value: ParamValue,
}

/// The position of `value` on `ladder`: a step's index, or between two numeric steps the
/// fraction of the way from one to the next; `None` for a value the ladder does not span.
pub(crate) fn position_on(ladder: &RateLadder, value: &ParamValue) -> Option<f64> {
    if let Some(i) = ladder.steps.iter().position(|s| s == value) {
        return Some(i as f64);
    }
    let number = |v: &ParamValue| match v {
        ParamValue::Float(x) => Some(*x),
        ParamValue::Int(x) => Some(*x as f64),
        _ => None,
    };
    let x = number(value)?;
    ladder.steps.windows(2).enumerate().find_map(|(i, w)| {
        let (a, b) = (number(&w[0])?, number(&w[1])?);
        let inside = (a.min(b)..=a.max(b)).contains(&x) && a != b;
        inside.then(|| i as f64 + (x - a) / (b - a))
    })
}

/// The codecs of `curves`, each once, in the order they first appear.
fn codecs_of(curves: &[Curve<'_>]) -> Vec<&'static str> {
    let mut codecs: Vec<&'static str> = Vec::new();
    for c in curves {
        if !codecs.contains(&c.codec) {
            codecs.push(c.codec);
        }
    }
    codecs
}

/// The most points one round measures: per codec and target, [`CONFIGS_PER_TARGET`] of its
/// curves (fewer when it has fewer).
pub(crate) fn round_most(curves: &[Curve<'_>], targets: &[Target]) -> usize {
    let codecs = codecs_of(curves);
    codecs
        .into_iter()
        .map(|codec| targets.len() * CONFIGS_PER_TARGET.min(curves.iter().filter(|c| c.codec == codec).count()))
        .sum()
}

/// The next round's points, from every point measured so far (`points`, of any curve): for
/// each codec and target, each curve searched for that target's kind of error
/// ([`Curve::searched_for`]) plans its next point toward the target, by its own measured
/// points —
/// - between its last failing point and its first passing one (by ladder position): the
///   secant in log(error), on a ladder step while the bracket spans more than one, else
///   between two steps (numeric ladders; not once narrower than [`MIN_WIDTH`] nor once the
///   passing point is within [`REFINE_CLOSE`] of the target);
/// - one step below its smallest passing point when nothing below it was measured;
/// - one step above its largest failing point when nothing passed;
///
/// predicted (log-linear bytes between the bracket's points, else the nearest point's bytes)
/// no larger than the codec's smallest passing stream so far, and a failing point below it
/// smaller than that stream (streams grow along a ladder). The [`CONFIGS_PER_TARGET`] curves
/// whose passing stream could be smallest (the failing point's bytes; then the prediction)
/// are kept; a point already measured or planned is not planned again.
/// Sorted by curve and position; depends on the points alone, so on no thread count.
pub(crate) fn plan(curves: &[Curve<'_>], points: &[Point], targets: &[Target]) -> Vec<Job> {
    let mut jobs: Vec<Job> = Vec::new();
    let codecs = codecs_of(curves);
    for codec in codecs {
        for (ti, target) in targets.iter().enumerate() {
            let passes = |p: &Point| usable(p) && target.meets(&p.report);
            let error = |p: &Point| target.error(&p.report).filter(|e| usable(p) && e.is_finite() && *e > 0.0);
            let best = points.iter().filter(|p| p.codec == codec && passes(p)).map(|p| p.bytes).min();
            let mut candidates: Vec<(u64, f64, Job)> = Vec::new();
            let searched = |c: &Curve<'_>| c.codec == codec && c.searched_for.get(ti).copied().unwrap_or(false);
            for (k, curve) in curves.iter().enumerate().filter(|(_, c)| searched(c)) {
                let n = curve.ladder.steps.len();
                if n == 0 {
                    continue;
                }
                let own: Vec<(f64, &Point)> = points
                    .iter()
                    .filter(|p| p.series == curve.label)
                    .filter_map(|p| Some((position_on(&curve.ladder, p.ladder_value()?)?, p)))
                    .collect();
                let pass = own.iter().filter(|(_, p)| passes(p)).min_by(|a, b| a.0.total_cmp(&b.0));
                let fail = own
                    .iter()
                    .filter(|(x, p)| !passes(p) && pass.is_none_or(|(at, _)| x < at))
                    .max_by(|a, b| a.0.total_cmp(&b.0));
                // (position, between steps, predicted bytes at the target, the fewest bytes a
                // passing stream there can have: the failing point's, streams growing along
                // the ladder).
                let (x, fractional, predicted, floor) = match (fail, pass) {
                    (Some(&(f, fp)), Some(&(p, pp))) => {
                        let close = error(pp).is_some_and(|e| e >= REFINE_CLOSE * target.level());
                        // A passing point not 1% smaller than a larger passing one of the curve:
                        // the bracket sits on one step of the error (hosvd's ranks), where
                        // moving shifts the quantization a little and nothing more.
                        let plateau =
                            own.iter().any(|(x, q)| *x > p && passes(q) && pp.bytes as f64 >= PLATEAU * q.bytes as f64);
                        let width = p - f;
                        if close || plateau || width < MIN_WIDTH || best.is_some_and(|b| fp.bytes >= b) {
                            continue;
                        }
                        let aim = REFINE_AIM * target.level();
                        let t = match (error(fp), error(pp)) {
                            (Some(ef), Some(ep)) if ef > ep => {
                                ((aim.ln() - ef.ln()) / (ep.ln() - ef.ln())).clamp(0.15, 0.85)
                            }
                            _ => 0.5,
                        };
                        let predicted =
                            ((fp.bytes.max(1) as f64).ln() * (1.0 - t) + (pp.bytes.max(1) as f64).ln() * t).exp();
                        if width > 1.0 + 1e-9 {
                            // The ladder's own steps first: the one nearest the secant strictly
                            // inside the bracket.
                            let (lo, hi) = (f.floor() + 1.0, p.ceil() - 1.0);
                            if lo > hi {
                                continue;
                            }
                            ((f + t * width).round().clamp(lo, hi), false, predicted, fp.bytes)
                        } else if numeric(&curve.ladder) {
                            // Between two steps; where the error falls more than tenfold
                            // across the bracket, no closer than a quarter of it to either end:
                            // the error is then a step function of the ladder (hosvd's ranks),
                            // and a secant through two far-apart steps of it creeps toward one
                            // end (rounds a target search would spend bisecting).
                            let jump = matches!((error(fp), error(pp)), (Some(ef), Some(ep)) if ef > 10.0 * ep);
                            let t = if jump { t.clamp(0.25, 0.75) } else { t };
                            (f + t * width, true, predicted, fp.bytes)
                        } else {
                            continue;
                        }
                    }
                    (None, Some(&(p, pp))) => {
                        if p <= 0.0 {
                            continue;
                        }
                        ((p - 1e-9).ceil() - 1.0, false, pp.bytes as f64, 0)
                    }
                    (Some(&(f, fp)), None) => {
                        if f >= (n - 1) as f64 || best.is_some_and(|b| fp.bytes >= b) {
                            continue;
                        }
                        (f.floor() + 1.0, false, fp.bytes as f64, fp.bytes)
                    }
                    (None, None) => continue,
                };
                if best.is_some_and(|b| predicted > b as f64) {
                    continue;
                }
                let Some((position, value)) = value_at(&curve.ladder, x, fractional) else { continue };
                if own.iter().any(|(_, p)| p.ladder_value() == Some(&value)) {
                    continue;
                }
                candidates.push((floor, predicted, Job { curve: k, position, value }));
            }
            // Fewest possible bytes first (best-first, as a branch and bound): a prediction
            // across a wide bracket is poor where the error is a step function of the ladder
            // (hosvd's ranks), the floor is sound.
            candidates.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)).then(a.2.curve.cmp(&b.2.curve)));
            // Configurations that measured the same streams so far (an option that changes
            // nothing here: hosvd's `edge_noise` where the noise is below its cap) plan the
            // same point: one of them is refined.
            candidates.dedup_by(|b, a| a.0 == b.0 && a.1 == b.1 && a.2.value == b.2.value);
            for (_, _, job) in candidates.into_iter().take(CONFIGS_PER_TARGET) {
                if !jobs.iter().any(|j| j.curve == job.curve && j.value == job.value) {
                    jobs.push(job);
                }
            }
        }
    }
    jobs.sort_by(|a, b| a.curve.cmp(&b.curve).then(a.position.total_cmp(&b.position)));
    jobs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_of_values_between_steps_are_fractions_of_the_way() {
        let ladder =
            RateLadder { param: "ss", steps: [0.99, 0.9, 0.8].iter().map(|&s| ParamValue::Float(s)).collect() };
        assert_eq!(position_on(&ladder, &ParamValue::Float(0.9)), Some(1.0));
        let x = position_on(&ladder, &ParamValue::Float(0.85)).unwrap();
        assert!((x - 1.5).abs() < 1e-9, "{x}");
        assert_eq!(position_on(&ladder, &ParamValue::Float(0.5)), None);
        let ints = RateLadder { param: "bits", steps: vec![ParamValue::Int(4), ParamValue::Int(8)] };
        assert_eq!(position_on(&ints, &ParamValue::Int(5)), Some(0.25));
        let choices = RateLadder { param: "mode", steps: vec![ParamValue::Choice("a"), ParamValue::Choice("b")] };
        assert_eq!(position_on(&choices, &ParamValue::Choice("b")), Some(1.0));
    }
}
