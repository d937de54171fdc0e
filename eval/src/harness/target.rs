//! Error targets (`kg=0.5`, or joint: `kg=0.5,sted=0.05`): the metrics bounded, what a search found ([`TargetHit`]) or why
//! it found nothing ([`TargetMiss`]), and which measured points count as meeting one.

use std::fmt;
use std::str::FromStr;

use codec_core::DistortionKind;
use metrics::{EvalOptions, MetricReport};

use super::measured::Point;

/// A metric a [`Target`] bounds. The discriminants are the positions in [`Self::ALL`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TargetMetric {
    /// KG error in percent.
    Kg,
    /// STED (combined).
    Sted,
    /// Largest per-frame Hausdorff distance (absolute, model units).
    Hausdorff,
    /// Largest vertex displacement (absolute).
    MaxError,
    /// Root mean square vertex displacement (absolute).
    Rmse,
}

impl TargetMetric {
    /// Every metric with its command-line name, in declaration order.
    pub const ALL: [(TargetMetric, &'static str); 5] = [
        (TargetMetric::Kg, "kg"),
        (TargetMetric::Sted, "sted"),
        (TargetMetric::Hausdorff, "hausdorff"),
        (TargetMetric::MaxError, "max_error"),
        (TargetMetric::Rmse, "rmse"),
    ];

    /// Command-line name (also the JSON key of the metric).
    pub fn name(self) -> &'static str {
        Self::ALL.iter().find(|(m, _)| *m == self).map(|(_, n)| *n).unwrap_or("?")
    }

    /// The metric's value in `report` (`None` when undefined or not computed). For KG this is
    /// [`MetricReport::kg_bound`]: the larger of the global and the worst part's KG.
    pub fn value(self, report: &MetricReport) -> Option<f64> {
        match self {
            // The larger of the whole's and the worst part's: a large static part must not
            // hide a destroyed small one.
            TargetMetric::Kg => report.kg_bound(),
            TargetMetric::Sted => report.sted,
            TargetMetric::Hausdorff => report.hausdorff,
            TargetMetric::MaxError => Some(report.max_error),
            TargetMetric::Rmse => Some(report.rmse),
        }
    }

    /// The kind of error the metric measures, which selects the part of a codec's search
    /// space a target search walks ([`AnimationCodec::search_space_for`](codec_core::AnimationCodec::search_space_for)).
    pub fn distortion_kind(self) -> DistortionKind {
        match self {
            TargetMetric::Sted => DistortionKind::Shape,
            TargetMetric::Kg | TargetMetric::Hausdorff | TargetMetric::MaxError | TargetMetric::Rmse => {
                DistortionKind::Position
            }
        }
    }
}

/// An error target: one bound (`kg=0.5`) or several at once (`kg=0.5,sted=0.05`, a *joint*
/// target: the decoded animation must have every bounded metric at most its value). Motion
/// (KG) and local shape (STED) are judged together because each alone can be fooled: KG by a
/// large static part, STED by a mesh that keeps its edge lengths and does not move.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Target {
    /// The bound of each metric, indexed as [`TargetMetric::ALL`] (`None`: not bounded).
    bounds: [Option<f64>; TargetMetric::ALL.len()],
}

impl Target {
    /// A target bounding `metric` alone.
    pub const fn new(metric: TargetMetric, value: f64) -> Self {
        Self { bounds: [None; TargetMetric::ALL.len()] }.and_bound(metric, value)
    }

    /// This target with `metric` bounded by `value` as well (replacing a bound it had).
    pub const fn and_bound(mut self, metric: TargetMetric, value: f64) -> Self {
        self.bounds[metric as usize] = Some(value);
        self
    }

    /// Both targets' bounds together (repeated `--target` options); a metric bounded by both
    /// is an error naming it.
    pub fn and(self, other: Target) -> Result<Self, String> {
        let mut joint = self;
        for (metric, value) in other.bounds() {
            if let Some(first) = self.bound(metric) {
                return Err(format!("{} is bounded twice ({first} and {value})", metric.name()));
            }
            joint = joint.and_bound(metric, value);
        }
        Ok(joint)
    }

    /// The bounded metrics and their bounds, in [`TargetMetric::ALL`] order.
    pub fn bounds(&self) -> impl Iterator<Item = (TargetMetric, f64)> + '_ {
        TargetMetric::ALL.iter().zip(self.bounds).filter_map(|((m, _), b)| b.map(|b| (*m, b)))
    }

    /// The bound of `metric`, if this target bounds it.
    pub fn bound(&self, metric: TargetMetric) -> Option<f64> {
        self.bounds[metric as usize]
    }

    /// The metric bounded, when exactly one is.
    pub fn single(&self) -> Option<(TargetMetric, f64)> {
        let mut bounds = self.bounds();
        let first = bounds.next()?;
        bounds.next().is_none().then_some(first)
    }

    /// Whether `report` meets every bound (a metric not computed or undefined does not).
    pub fn meets(&self, report: &MetricReport) -> bool {
        self.bounds().all(|(m, b)| m.value(report).is_some_and(|v| v.is_finite() && v <= b))
    }

    /// The error a search drives toward [`Self::level`]: for one bound, the metric's value;
    /// for a joint target, the largest ratio value / bound over the bounds (≤ 1 exactly when
    /// every bound is met, so one number says how far the binding bound is). `None` when a
    /// bounded metric is undefined.
    pub fn error(&self, report: &MetricReport) -> Option<f64> {
        if let Some((metric, _)) = self.single() {
            return metric.value(report);
        }
        let mut worst: Option<f64> = None;
        for (metric, bound) in self.bounds() {
            let v = metric.value(report)?;
            let ratio = if bound > 0.0 {
                v / bound
            } else if v == 0.0 {
                0.0
            } else {
                f64::INFINITY
            };
            worst = Some(worst.map_or(ratio, |w: f64| w.max(ratio)));
        }
        worst
    }

    /// The value of [`Self::error`] at which the target is just met: the bound for one metric,
    /// 1 for a joint target.
    pub fn level(&self) -> f64 {
        self.single().map_or(1.0, |(_, b)| b)
    }

    /// The kind of error the target bounds ([`DistortionKind::Both`] when it bounds STED and a
    /// positional metric together), which selects the part of a codec's search space a target
    /// search walks.
    pub fn distortion_kind(&self) -> DistortionKind {
        let shape = self.bound(TargetMetric::Sted).is_some();
        let position = self.bounds().any(|(m, _)| m.distortion_kind() == DistortionKind::Position);
        match (shape, position) {
            (true, true) => DistortionKind::Both,
            (true, false) => DistortionKind::Shape,
            _ => DistortionKind::Position,
        }
    }

    /// Evaluation options computing the bounded metrics and skipping the expensive ones the
    /// target does not need (STED parameters from `base`).
    pub fn eval_options(&self, base: &EvalOptions) -> EvalOptions {
        EvalOptions {
            sted: base.sted,
            compute_sted: self.bound(TargetMetric::Sted).is_some(),
            compute_hausdorff: self.bound(TargetMetric::Hausdorff).is_some(),
        }
    }

    /// Each bounded metric's value in `report` (`None`: undefined or not computed), in
    /// [`TargetMetric::ALL`] order.
    pub fn reached(&self, report: &MetricReport) -> Vec<(TargetMetric, Option<f64>)> {
        self.bounds().map(|(m, _)| (m, m.value(report))).collect()
    }

    /// `reached` as text: `kg=0.4312, sted=0.0301` (`n/a` for an undefined metric).
    pub fn reached_text(&self, report: &MetricReport, digits: usize) -> String {
        self.reached(report)
            .iter()
            .map(|(m, v)| match v {
                Some(v) => format!("{}={v:.digits$}", m.name()),
                None => format!("{}=n/a", m.name()),
            })
            .collect::<Vec<_>>()
            .join(", ")
    }
}

impl fmt::Display for Target {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, (metric, value)) in self.bounds().enumerate() {
            if i > 0 {
                f.write_str(",")?;
            }
            write!(f, "{}={value}", metric.name())?;
        }
        Ok(())
    }
}

impl FromStr for Target {
    type Err = String;

    /// `METRIC=VALUE[,METRIC=VALUE…]`: one bound, or several for a joint target.
    fn from_str(text: &str) -> Result<Self, String> {
        let names: Vec<&str> = TargetMetric::ALL.iter().map(|(_, n)| *n).collect();
        let mut target: Option<Target> = None;
        for part in text.split(',') {
            let (key, value) = part.split_once('=').ok_or_else(|| {
                format!(
                    "target '{text}' is not of the form METRIC=VALUE[,METRIC=VALUE…] (metrics: {})",
                    names.join(", ")
                )
            })?;
            let key = key.trim().to_ascii_lowercase().replace('-', "_");
            let metric =
                TargetMetric::ALL.iter().find(|(_, n)| *n == key).map(|(m, _)| *m).ok_or_else(|| {
                    format!("target '{text}': unknown metric '{key}' (metrics: {})", names.join(", "))
                })?;
            let value: f64 =
                value.trim().parse().map_err(|_| format!("target '{text}': '{}' is not a number", value.trim()))?;
            if !(value.is_finite() && value >= 0.0) {
                return Err(format!("target '{text}': the value must be finite and ≥ 0"));
            }
            let bound = Target::new(metric, value);
            target = Some(match target {
                None => bound,
                Some(t) => t.and(bound).map_err(|e| format!("target '{text}': {e}"))?,
            });
        }
        target.ok_or_else(|| format!("target '{text}' is empty"))
    }
}

/// What [`search_target`](super::search::search_target) found: the chosen point, its container bytes, and every point it
/// measured on the way (sorted by ladder position).
#[derive(Debug, Clone)]
pub struct TargetHit {
    /// The smallest stream found that meets the target.
    pub point: Point,
    /// Its container bytes.
    pub stream: Vec<u8>,
    /// Every point measured, by ladder position.
    pub tried: Vec<Point>,
    /// True when the measured errors were not monotone along the ladder and the search fell
    /// back to a linear scan below the binary search's answer.
    pub linear_fallback: bool,
    /// Candidates the search rejected (the codec failed, or the stream decoded to non-finite
    /// coordinates), one message each, in search order.
    pub rejected: Vec<String>,
}

/// Why [`search_target`](super::search::search_target) found nothing: no ladder point meets the target.
#[derive(Debug, Clone)]
pub struct TargetMiss {
    /// Codec name.
    pub codec: &'static str,
    /// The target.
    pub target: Target,
    /// The measured point with the smallest error (`None` if the metric was undefined at
    /// every point measured).
    pub best: Option<Point>,
    /// Why the candidates the codec refused were refused (its own advice, e.g. hosvd on one
    /// frame), distinct messages in search order.
    pub refused: Vec<String>,
}

impl TargetMiss {
    /// The miss of a search that measured `tried` and saw the codec refuse `rejected`: the
    /// point of smallest finite error, and the distinct refusals (each without the `codec
    /// [params]: ` prefix the space search gives a candidate's message, so one reason given at
    /// every candidate is listed once).
    pub fn new<'a>(
        codec: &'static str,
        target: Target,
        tried: impl Iterator<Item = &'a Point>,
        rejected: Vec<String>,
    ) -> Self {
        let best = tried
            .filter_map(|p| target.error(&p.report).filter(|v| v.is_finite()).map(|v| (v, p)))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, p)| p.clone());
        let mut refused: Vec<String> = Vec::new();
        for message in rejected {
            let reason = message
                .strip_prefix(codec)
                .and_then(|rest| rest.strip_prefix(" ["))
                .and_then(|rest| rest.split_once("]: "))
                .map_or(message.as_str(), |(_, reason)| reason)
                .to_owned();
            if !refused.contains(&reason) {
                refused.push(reason);
            }
        }
        Self { codec, target, best, refused }
    }
}

impl fmt::Display for TargetMiss {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let target = self.target;
        match self.best.as_ref() {
            Some(b) => write!(
                f,
                "{}: no rate-ladder point meets {target}: the best reached is {} at [{}] ({} bytes, {:.4} bpvf)",
                self.codec,
                target.reached_text(&b.report, 6),
                b.params,
                b.bytes,
                b.bpvf
            ),
            // Nothing measured because the codec refused every candidate: the metric is not
            // undefined, the codec said why.
            None if !self.refused.is_empty() => {
                write!(f, "{}: no rate-ladder point meets {target}: the codec refused every candidate", self.codec)
            }
            None => write!(
                f,
                "{}: no rate-ladder point meets {target}: {} is undefined for this input",
                self.codec,
                target.bounds().map(|(m, _)| m.name()).collect::<Vec<_>>().join(" or ")
            ),
        }?;
        // Say when the bound was the worst part's, not the whole animation's.
        if let Some(b) = self.best.as_ref().filter(|b| target.bound(TargetMetric::Kg).is_some() && b.report.parts > 1) {
            if let (Some(w), Some(kg)) = (&b.report.worst_part, b.report.kg) {
                if w.kg.is_some_and(|p| p > kg) {
                    write!(
                        f,
                        " (the worst of {} parts: part {}, {} vertices from vertex {}; the whole animation is at kg={kg:.6})",
                        b.report.parts, w.part, w.vertices, w.first_vertex
                    )?;
                }
            }
        }
        // The codec's own reasons come last: they say what would work.
        if let Some(first) = self.refused.first() {
            write!(f, "; where the codec refused: {first}")?;
            if self.refused.len() > 1 {
                write!(f, " (and {} other reasons)", self.refused.len() - 1)?;
            }
        }
        Ok(())
    }
}

impl std::error::Error for TargetMiss {}

/// A reconstruction whose KG exceeds this (in %) is not a usable animation, whatever its
/// STED or Hausdorff distance: on samba hosvd at `ss=0.998` decodes to KG 233 % with STED
/// 0.00023 (a nearly rigid reconstruction STED cannot see; chicken-crossing shows the
/// same). Such points never meet a target and are left out of the envelopes.
pub const DEGENERATE_KG: f64 = 50.0;

/// Whether `p` is a usable reconstruction (KG, when measured, at most [`DEGENERATE_KG`], for
/// the whole animation and for its worst part, so a large static part cannot hide a destroyed
/// small one).
pub fn usable(p: &Point) -> bool {
    p.report.kg_bound().is_none_or(|kg| kg.is_finite() && kg <= DEGENERATE_KG)
}

/// A stream whose KG exceeds this (in %) is too far from every target a user sets (the joint
/// targets bound KG at 2, 0.5 and 0.1) for its STED to be read as a result: STED is blind to a
/// locally uniform scale and weighs motion by about 1e-4, so such a stream can score a STED
/// below any good stream's (hosvd at KG 125, STED 7.6e-5). The sweep leaves these points off
/// the STED envelope and the plot draws them open, off the line.
pub const STED_DEGENERATE_KG: f64 = 10.0;

/// Whether `p`'s STED says nothing about its quality: its KG (whole or worst part) exceeds
/// [`STED_DEGENERATE_KG`], or is not finite.
pub fn sted_degenerate(report: &MetricReport) -> bool {
    report.kg_bound().is_some_and(|kg| !(kg.is_finite() && kg <= STED_DEGENERATE_KG))
}

pub(crate) fn meets(target: Target, p: &Point) -> bool {
    target.meets(&p.report)
}
