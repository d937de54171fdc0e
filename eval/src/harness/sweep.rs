//! Sweeps: every chosen series walked along its rate ladder ([`sweep`]), one job of it
//! ([`sweep_point`], for other schedulers), and the default envelope sweep over each codec's
//! declared search space ([`envelope_sweep`]).

use codec_core::{Animation, AnimationCodec, CodecRegistry, Limits, ParamSet, RateLadder};
use metrics::EvalOptions;
use rayon::prelude::*;
use serde::Serialize;

use super::curve::envelope;
use super::input::{measure_point_streamed, SearchInput};
use super::measured::Point;
use super::point::{ladder_indices, ladder_params, measure_point_keeping};
use super::refine::{self, Curve, STANDARD_TARGETS};
use super::target::TargetMetric;
use crate::error::{EvalError, Result};

/// How [`sweep`] runs.
#[derive(Debug, Clone, Default)]
pub struct SweepOptions {
    /// Ladder points per codec, spread evenly (`None`: every step).
    pub points: Option<usize>,
    /// Points measured at once: `None` uses rayon's pool, `Some(1)` runs sequentially (for
    /// timing: parallel encodes compete for the cores), `Some(n)` a pool of `n` threads.
    pub jobs: Option<usize>,
    /// Metrics to compute.
    pub eval: EvalOptions,
    /// Decoder limits.
    pub limits: Limits,
    /// Points (curve label, ladder position) whose decoded animation the sweep keeps
    /// ([`Sweep::decoded`]), for a caller that shows them: they are neither encoded nor decoded
    /// again.
    pub keep_decoded: Vec<(String, usize)>,
    /// Rounds of the envelope sweep's refinement toward the [`STANDARD_TARGETS`] after its
    /// grid (0: none; `sweep` runs [`REFINE_ROUNDS`](super::REFINE_ROUNDS)). Plain sweeps
    /// ignore it.
    pub refine_rounds: usize,
}

/// A sweep point that failed, with the reason (in the sweep document as
/// `{codec, series, ladder_index, error}`).
#[derive(Debug, Clone, Serialize)]
pub struct Failure {
    /// Codec name.
    pub codec: &'static str,
    /// Curve name (see [`Point::series`]).
    pub series: String,
    /// Position on the ladder.
    pub ladder_index: usize,
    /// What went wrong.
    #[serde(rename = "error")]
    pub message: String,
}

/// Result of [`sweep`]: measured points sorted by codec (in the order given) then ladder
/// position, and the points that failed.
#[derive(Debug, Clone, Default)]
pub struct Sweep {
    /// Measured points.
    pub points: Vec<Point>,
    /// Points that could not be measured.
    pub failures: Vec<Failure>,
    /// The decoded animations of the points [`SweepOptions::keep_decoded`] asked for, as
    /// (curve label, ladder position, decoded animation), in the order of `points`.
    pub decoded: Vec<(String, usize, Animation)>,
}

/// What [`sweep`] and [`envelope_sweep`] report while they run (from worker threads), for a
/// progress display with an honest total: every phase is counted before the first point
/// starts, a phase not yet planned at its most, so the total only ever falls to the exact
/// count as the later phases are planned (never grows as they start).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SweepEvent<'a> {
    /// Phase `phase` of `phases` (from 1) starts, measuring `points` points; `total` counts the
    /// points of the whole sweep as now known: those of the phases planned so far, exactly,
    /// and at most those of the phases still to plan.
    Phase {
        /// This phase, from 1.
        phase: usize,
        /// The phases of the sweep.
        phases: usize,
        /// What the phase measures, in a word: `ladder steps` (a plain sweep), `ladders`
        /// (every codec's first configuration), `configurations` (the others), `neighbours`
        /// (the ladder neighbours of their points on the envelope), `refinement` (a round of
        /// points toward the standard targets, between ladder steps too).
        name: &'static str,
        /// Its points.
        points: usize,
        /// The whole sweep's points (see above).
        total: usize,
    },
    /// A point started: its curve's label and ladder position.
    Started {
        /// Curve name (see [`Point::series`]).
        series: &'a str,
        /// Position on the ladder.
        step: usize,
    },
    /// A point finished (measured or failed).
    Finished {
        /// Curve name.
        series: &'a str,
        /// Position on the ladder.
        step: usize,
    },
}

/// One curve of a sweep: a codec and the parameters its rate ladder is walked on.
#[derive(Clone)]
pub struct SweepSeries<'a> {
    /// The codec.
    pub codec: &'a dyn AnimationCodec,
    /// Parameters every ladder step starts from (the step then sets the ladder parameter).
    pub base: ParamSet,
    /// Curve name in tables, JSON and plots.
    pub label: String,
    /// Ladder positions to measure on this curve (`None`: the sweep's `points`, spread evenly).
    pub steps: Option<Vec<usize>>,
}

impl<'a> SweepSeries<'a> {
    /// The codec at its defaults, labelled with its name.
    pub fn defaults(codec: &'a dyn AnimationCodec) -> Self {
        Self { codec, base: codec.default_params(), label: codec.name().to_string(), steps: None }
    }

    /// The codec on `base`, labelled `codec[key=value,…]` with the parameters that differ from
    /// the defaults (just the codec name when none do). Fails if `base` does not validate.
    pub fn with_base(codec: &'a dyn AnimationCodec, base: ParamSet) -> Result<Self> {
        codec.validate(&base)?;
        let defaults = codec.default_params();
        let changed: Vec<String> =
            base.iter().filter(|(n, v)| defaults.get(n) != Some(*v)).map(|(n, v)| format!("{n}={v}")).collect();
        let label = if changed.is_empty() {
            codec.name().to_string()
        } else {
            format!("{}[{}]", codec.name(), changed.join(","))
        };
        Ok(Self { codec, base, label, steps: None })
    }

    fn ladder(&self) -> RateLadder {
        self.codec.rate_ladder(&self.base)
    }
}

/// Walks the rate ladder of every series on `input`: an animation in memory, or a streamed input
/// ([`SearchInput::Streamed`]: each point encoded from a read of it and measured against a
/// second, one at a time within its memory budget). `progress` hears of the one phase
/// (its points) and of every point as it starts and as it finishes (from worker threads;
/// [`SweepEvent`]). Output order (series, then ladder step) does not depend on scheduling.
pub fn sweep<'i>(
    registry: &CodecRegistry,
    series: &[SweepSeries<'_>],
    input: impl Into<SearchInput<'i>>,
    options: &SweepOptions,
    progress: &(dyn Fn(SweepEvent<'_>) + Sync),
) -> Result<Sweep> {
    let points = sweep_jobs(series, options.points).len();
    progress(SweepEvent::Phase { phase: 1, phases: 1, name: "ladder steps", points, total: points });
    sweep_phase(registry, series, input.into(), options, progress)
}

/// [`sweep`] without the phase event: one phase of a sweep whose caller reports the phases.
fn sweep_phase(
    registry: &CodecRegistry,
    series: &[SweepSeries<'_>],
    input: SearchInput<'_>,
    options: &SweepOptions,
    progress: &(dyn Fn(SweepEvent<'_>) + Sync),
) -> Result<Sweep> {
    let jobs = sweep_jobs(series, options.points);
    let run = |&(c, step): &(usize, usize)| -> (usize, usize, Result<KeptPoint>) {
        progress(SweepEvent::Started { series: &series[c].label, step });
        let keep = options.keep_decoded.iter().any(|(label, s)| *label == series[c].label && *s == step);
        let result = sweep_point_keeping(registry, &series[c], step, input, options, keep);
        progress(SweepEvent::Finished { series: &series[c].label, step });
        (c, step, result)
    };
    let mut results: Vec<(usize, usize, Result<KeptPoint>)> = in_pool(pool(input, options), &jobs, run)?;
    // `collect` keeps input order already; sorting states the contract explicitly.
    results.sort_by_key(|(c, step, _)| (*c, *step));
    let mut out = Sweep::default();
    for (c, step, r) in results {
        match r {
            Ok((p, decoded)) => {
                if let Some(decoded) = decoded {
                    out.decoded.push((p.series.clone(), p.ladder_index, decoded));
                }
                out.points.push(p);
            }
            Err(e) => out.failures.push(Failure {
                codec: series[c].codec.name(),
                series: series[c].label.clone(),
                ladder_index: step,
                message: e.to_string(),
            }),
        }
    }
    Ok(out)
}

/// The points measured at once on `input`: one at a time on a streamed input (each holds the
/// memory budget's work share), else as [`SweepOptions::jobs`] says.
fn pool(input: SearchInput<'_>, options: &SweepOptions) -> Option<usize> {
    if input.sequential() {
        Some(1)
    } else {
        options.jobs
    }
}

/// `run` over `jobs` as `jobs` (a thread count) says: `None` rayon's pool, `Some(1)`
/// sequentially, `Some(n)` a pool of `n` threads. Results in the order of `jobs`.
fn in_pool<J: Sync, T: Send>(jobs: Option<usize>, items: &[J], run: impl Fn(&J) -> T + Sync + Send) -> Result<Vec<T>> {
    Ok(match jobs {
        Some(1) => items.iter().map(run).collect(),
        None => items.par_iter().map(run).collect(),
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map_err(|source| EvalError::ThreadPool { threads: n, source })?
            .install(|| items.par_iter().map(run).collect()),
    })
}

/// A measured point and, when it was asked for, its decoded animation.
type KeptPoint = (Point, Option<Animation>);

/// One sweep job: `entry` at step `step` of its rate ladder on `animation`, measured as
/// [`sweep`] measures each of its points (it calls this). Exposed so that other schedulers
/// (the Python package's Dask sweep runs one job per (input, series, step)) produce rows
/// identical to the command line's.
pub fn sweep_point(
    registry: &CodecRegistry,
    entry: &SweepSeries<'_>,
    step: usize,
    animation: &Animation,
    options: &SweepOptions,
) -> Result<Point> {
    sweep_point_keeping(registry, entry, step, SearchInput::Whole(animation), options, false).map(|(point, _)| point)
}

/// [`sweep_point`], also returning the decoded animation when `keep` is set.
fn sweep_point_keeping(
    registry: &CodecRegistry,
    entry: &SweepSeries<'_>,
    step: usize,
    input: SearchInput<'_>,
    options: &SweepOptions,
    keep: bool,
) -> Result<KeptPoint> {
    let ladder = entry.ladder();
    let params = ladder_params(entry.codec, &entry.base, &ladder, step)?;
    let (mut point, decoded) = measure_on(registry, entry.codec, &params, (ladder.param, step), input, options, keep)?;
    point.series.clone_from(&entry.label);
    Ok((point, decoded))
}

/// One sweep point of `codec` at `params`: on a whole input [`measure_point_keeping`] (its
/// decoded animation returned when `keep` is set), on a streamed one [`measure_point_streamed`]
/// (the stream is dropped once measured; a decoded animation cannot be kept: an error).
fn measure_on(
    registry: &CodecRegistry,
    codec: &dyn AnimationCodec,
    params: &ParamSet,
    ladder: (&'static str, usize),
    input: SearchInput<'_>,
    options: &SweepOptions,
    keep: bool,
) -> Result<KeptPoint> {
    match input {
        SearchInput::Whole(animation) => {
            let (point, _, decoded) =
                measure_point_keeping(registry, codec, params, ladder, animation, &options.eval, options.limits)?;
            Ok((point, keep.then_some(decoded)))
        }
        SearchInput::Streamed(_) if keep => Err(EvalError::Message(
            "a streamed sweep keeps no decoded animation to view (the input is read frame by frame): leave out \
             --view-points, or sweep a shorter input"
                .into(),
        )),
        SearchInput::Streamed(streamed) => {
            let (point, _stream) =
                measure_point_streamed(registry, codec, params, ladder, streamed, &options.eval, options.limits)?;
            Ok((point, None))
        }
    }
}

/// The (series position, ladder step) pairs a sweep measures.
pub fn sweep_jobs(series: &[SweepSeries<'_>], points: Option<usize>) -> Vec<(usize, usize)> {
    series
        .iter()
        .enumerate()
        .flat_map(|(c, entry)| {
            let steps = entry.steps.clone().unwrap_or_else(|| ladder_indices(entry.ladder().steps.len(), points));
            steps.into_iter().map(move |s| (c, s))
        })
        .collect()
}

/// Errors that mark the part of a rate-distortion curve the envelope sweep looks at closely:
/// KG 0.05–4 % or STED 0.01–0.2 (the quality targets of the README tables, with room).
const ENVELOPE_KG: (f64, f64) = (0.05, 4.0);
const ENVELOPE_STED: (f64, f64) = (0.01, 0.2);

/// The default sweep: each codec's lower envelope over its declared search space
/// ([`AnimationCodec::search_space`] on `base`, minus the `fixed` parameters). First every
/// codec's first configuration on its whole ladder (the points of today's single-axis sweep,
/// `options.points` applies), then every other configuration at its smallest step and
/// `per_config` ladder positions spread evenly over the positions where the first
/// configuration's KG or STED fell in the range the targets live in (every position if none
/// did), then up to `per_config` more per configuration next to its points on the envelope
/// (`envelope_neighbours`), then `options.refine_rounds` rounds of refinement toward the
/// [`STANDARD_TARGETS`]: per codec and target, the next point of up to
/// [`CONFIGS_PER_TARGET`](super::CONFIGS_PER_TARGET) configurations where a target search
/// would measure it (inside the bracket of passing and failing points, between ladder steps
/// once the bracket is one step wide), planned from every point measured so far; those points
/// are marked [`Point::refined`]. Curves are labelled `codec[key=value,…]`; [`envelope`]
/// picks the points on the lower envelope. Results are in a fixed order (the grid's series,
/// then each round's points by configuration and ladder position) whatever the scheduling.
pub fn envelope_sweep<'a, 'i>(
    registry: &CodecRegistry,
    codecs: &[(&'a dyn AnimationCodec, ParamSet, Vec<&'static str>)],
    input: impl Into<SearchInput<'i>>,
    options: &SweepOptions,
    per_config: usize,
    progress: &(dyn Fn(SweepEvent<'_>) + Sync),
) -> Result<Sweep> {
    let input = input.into();
    let mut first = Vec::new();
    let mut rest: Vec<Vec<SweepSeries<'a>>> = Vec::new();
    for (codec, base, fixed) in codecs {
        let specs = codec.param_specs();
        let space = codec.search_space(base).without(fixed);
        let mut series: Vec<SweepSeries<'a>> = space
            .configurations()
            .iter()
            .filter_map(|config| {
                let params = codec_core::SearchSpace::apply(base, &specs, config).ok()?;
                SweepSeries::with_base(*codec, params).ok()
            })
            .collect();
        if series.is_empty() {
            return Err(EvalError::NoValidConfiguration { codec: codec.name(), on: None });
        }
        first.push(series.remove(0));
        rest.push(series);
    }
    // Every phase counted before the first starts: the first exactly, the second and third
    // at their most (`second_phase_most`, `third_phase_most`), replaced by their exact
    // counts as they are planned.
    let first_points = sweep_jobs(&first, options.points).len();
    let second_most: usize = first
        .iter()
        .zip(&rest)
        .flat_map(|(head, others)| others.iter().map(move |s| second_phase_most(head, s, per_config)))
        .sum();
    let third_most: usize = rest.iter().flatten().map(|s| third_phase_most(s, per_config)).sum();
    let rounds = options.refine_rounds;
    // For each codec and standard target, the configurations its target search walks.
    let searched: Searched = codecs
        .iter()
        .map(|(codec, base, fixed)| {
            let specs = codec.param_specs();
            let per_target = STANDARD_TARGETS
                .iter()
                .map(|t| {
                    let space = codec.search_space_for(base, t.distortion_kind()).without(fixed);
                    space
                        .configurations()
                        .iter()
                        .filter_map(|config| codec_core::SearchSpace::apply(base, &specs, config).ok())
                        .collect()
                })
                .collect();
            (codec.name(), per_target)
        })
        .collect();
    let round_most = {
        let all: Vec<&SweepSeries<'a>> = first.iter().chain(rest.iter().flatten()).collect();
        refine::round_most(&curves_of(&all, &searched), &STANDARD_TARGETS)
    };
    let phase = |phase: usize, name: &'static str, points: usize, total: usize| {
        progress(SweepEvent::Phase { phase, phases: 3 + rounds, name, points, total });
    };
    phase(1, "ladders", first_points, first_points + second_most + third_most + rounds * round_most);
    let mut result = sweep_phase(registry, &first, input, options, progress)?;
    let mut second = Vec::new();
    for (head, others) in first.iter().zip(rest) {
        let curve: Vec<&Point> = result.points.iter().filter(|p| p.series == head.label).collect();
        let within = |v: Option<f64>, (lo, hi): (f64, f64)| v.is_some_and(|v| v >= lo && v <= hi);
        let mut region: Vec<usize> = curve
            .iter()
            .filter(|p| within(p.report.kg, ENVELOPE_KG) || within(p.report.sted, ENVELOPE_STED))
            .map(|p| p.ladder_index)
            .collect();
        region.sort_unstable();
        region.dedup();
        for mut s in others {
            let positions = if region.is_empty() { (0..s.ladder().steps.len()).collect() } else { region.clone() };
            let mut picked: Vec<usize> =
                ladder_indices(positions.len(), Some(per_config)).into_iter().map(|i| positions[i]).collect();
            // And its smallest step: a shape error need not grow toward the small end of a
            // ladder (`space::search_space_target`; chicken-crossing's STED ≤ 0.1 is met
            // there by hosvd's rigid STED configuration, at half the bytes of any larger step).
            if !picked.contains(&0) {
                picked.insert(0, 0);
            }
            s.steps = Some(picked);
            second.push(s);
        }
    }
    let second_points = sweep_jobs(&second, options.points).len();
    phase(2, "configurations", second_points, first_points + second_points + third_most + rounds * round_most);
    let more = sweep_phase(registry, &second, input, options, progress)?;
    result.points.extend(more.points);
    result.failures.extend(more.failures);
    result.decoded.extend(more.decoded);
    let third = envelope_neighbours(&second, &result.points, per_config);
    let third_points = sweep_jobs(&third, options.points).len();
    let mut known = first_points + second_points + third_points;
    phase(3, "neighbours", third_points, known + rounds * round_most);
    if !third.is_empty() {
        let more = sweep_phase(registry, &third, input, options, progress)?;
        result.points.extend(more.points);
        result.failures.extend(more.failures);
        result.decoded.extend(more.decoded);
    }
    // Refinement toward the standard targets, round by round: each round's points are
    // planned from every point measured before it (`refine::plan`), so the rounds close in
    // on each target the way a target search does, from the grid's points.
    let all: Vec<&SweepSeries<'a>> = first.iter().chain(second.iter()).collect();
    let curves = curves_of(&all, &searched);
    let mut failed: Vec<(usize, codec_core::ParamValue)> = Vec::new();
    for round in 0..rounds {
        let jobs: Vec<refine::Job> = refine::plan(&curves, &result.points, &STANDARD_TARGETS)
            .into_iter()
            .filter(|j| !failed.iter().any(|(c, v)| *c == j.curve && *v == j.value))
            .collect();
        known += jobs.len();
        phase(4 + round, "refinement", jobs.len(), known + (rounds - round - 1) * round_most);
        if jobs.is_empty() {
            break;
        }
        let run = |job: &refine::Job| {
            let series = all[job.curve];
            let step = job.position.ceil() as usize;
            progress(SweepEvent::Started { series: &series.label, step });
            let measured = refined_point(registry, series, job, step, input, options);
            progress(SweepEvent::Finished { series: &series.label, step });
            measured
        };
        for (job, measured) in jobs.iter().zip(in_pool(pool(input, options), &jobs, run)?) {
            match measured {
                Ok(point) => result.points.push(point),
                Err(e) => {
                    let series = all[job.curve];
                    failed.push((job.curve, job.value.clone()));
                    result.failures.push(Failure {
                        codec: series.codec.name(),
                        series: series.label.clone(),
                        ladder_index: job.position.ceil() as usize,
                        message: e.to_string(),
                    });
                }
            }
        }
    }
    Ok(result)
}

/// The configurations a target search walks: per codec, per standard target, the parameter
/// sets of its part of the codec's space.
type Searched = Vec<(&'static str, Vec<Vec<ParamSet>>)>;

/// The curves of `all` as the refinement plans over them: each marked for the targets whose
/// search walks its configuration (`searched`).
fn curves_of<'s>(all: &[&'s SweepSeries<'_>], searched: &Searched) -> Vec<Curve<'s>> {
    all.iter()
        .map(|s| {
            let spaces = searched.iter().find(|(name, _)| *name == s.codec.name()).map(|(_, p)| p);
            Curve {
                codec: s.codec.name(),
                label: &s.label,
                ladder: s.ladder(),
                searched_for: spaces.map_or_else(Vec::new, |p| p.iter().map(|c| c.contains(&s.base)).collect()),
            }
        })
        .collect()
}

/// One point of the refinement: `series` with its ladder parameter at `job`'s value (a step,
/// or between two), measured as every sweep point is, marked [`Point::refined`] and carrying
/// `step` (the ladder step at or above it) as its ladder index.
fn refined_point(
    registry: &CodecRegistry,
    series: &SweepSeries<'_>,
    job: &refine::Job,
    step: usize,
    input: SearchInput<'_>,
    options: &SweepOptions,
) -> Result<Point> {
    let ladder = series.ladder();
    let params = series.base.clone().with(&series.codec.param_specs(), ladder.param, job.value.clone())?;
    series.codec.validate(&params)?;
    let (mut point, _) = measure_on(registry, series.codec, &params, (ladder.param, step), input, options, false)?;
    point.series.clone_from(&series.label);
    point.refined = true;
    Ok(point)
}

/// The most points the envelope sweep's second phase measures on configuration `s` (after
/// `head`, its codec's first): `per_config` positions spread over at most the longer of the
/// two ladders, and the smallest step.
fn second_phase_most(head: &SweepSeries<'_>, s: &SweepSeries<'_>, per_config: usize) -> usize {
    let positions = head.ladder().steps.len().max(s.ladder().steps.len());
    per_config.min(positions) + 1
}

/// The most points the envelope sweep's third phase measures on configuration `s`:
/// `per_config` ladder neighbours, of the steps the second phase left (its smallest step is
/// always measured there).
fn third_phase_most(s: &SweepSeries<'_>, per_config: usize) -> usize {
    per_config.min(s.ladder().steps.len().saturating_sub(1))
}

/// The envelope sweep's third phase: for every configuration after the first, the unmeasured
/// ladder neighbours (one step either side) of its points that lie on their codec's lower
/// envelope by KG or STED with that error inside [`ENVELOPE_KG`] / [`ENVELOPE_STED`] — at most
/// `per_config` per configuration, nearest the cheap end first. The second phase spreads a
/// configuration's points by where the *first* configuration's errors fell; a configuration
/// that is better for one metric reaches the same error at other steps (hosvd's STED
/// configuration meets STED 0.1 on horse-gallop two `ss` steps above the first one's), so
/// without this its part of the envelope is a chord across coarse steps (horse-gallop, hosvd,
/// STED ≤ 0.1: the envelope without this phase gives 0.670 bpvf, `--target` finds 0.594).
/// Depends only on the measured points, so it is the same at any thread count.
fn envelope_neighbours<'a>(series: &[SweepSeries<'a>], points: &[Point], per_config: usize) -> Vec<SweepSeries<'a>> {
    let within = |v: Option<f64>, (lo, hi): (f64, f64)| v.is_some_and(|v| v >= lo && v <= hi);
    let mut on_envelope = vec![false; points.len()];
    for (metric, zone) in [(TargetMetric::Kg, ENVELOPE_KG), (TargetMetric::Sted, ENVELOPE_STED)] {
        for i in envelope(points, metric) {
            on_envelope[i] |= within(metric.value(&points[i].report), zone);
        }
    }
    let mut out = Vec::new();
    for s in series {
        let measured: Vec<usize> = points.iter().filter(|p| p.series == s.label).map(|p| p.ladder_index).collect();
        let mut anchors: Vec<usize> = (0..points.len())
            .filter(|&i| on_envelope[i] && points[i].series == s.label)
            .map(|i| points[i].ladder_index)
            .collect();
        anchors.sort_unstable();
        anchors.dedup();
        let steps = s.ladder().steps.len();
        let mut extra = Vec::new();
        for a in anchors {
            for n in [a.checked_sub(1), Some(a + 1)].into_iter().flatten() {
                if n < steps && !measured.contains(&n) && !extra.contains(&n) && extra.len() < per_config {
                    extra.push(n);
                }
            }
        }
        if !extra.is_empty() {
            extra.sort_unstable();
            let mut t = s.clone();
            t.steps = Some(extra);
            out.push(t);
        }
    }
    out
}
