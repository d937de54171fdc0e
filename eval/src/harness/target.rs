//! Error targets (`kg=0.5`): the metric bounded, what a search found ([`TargetHit`]) or why
//! it found nothing ([`TargetMiss`]), and which measured points count as meeting one.

use std::fmt;
use std::str::FromStr;

use codec_core::DistortionKind;
use metrics::{EvalOptions, MetricReport};

use super::measured::Point;

/// The metric a [`Target`] bounds.
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
    /// Every metric with its command-line name.
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
            // The larger of the whole's and the worst part's (issue 41): a large static part
            // must not hide a destroyed small one.
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

    /// Evaluation options computing this metric and skipping the expensive ones it does not
    /// need (STED parameters from `base`).
    pub fn eval_options(self, base: &EvalOptions) -> EvalOptions {
        EvalOptions {
            sted: base.sted,
            compute_sted: self == TargetMetric::Sted,
            compute_hausdorff: self == TargetMetric::Hausdorff,
        }
    }
}

/// An error target such as `kg=0.5`: the decoded animation must have `metric ≤ value`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Target {
    /// Metric bounded.
    pub metric: TargetMetric,
    /// Largest acceptable value.
    pub value: f64,
}

impl fmt::Display for Target {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}={}", self.metric.name(), self.value)
    }
}

impl FromStr for Target {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        let names: Vec<&str> = TargetMetric::ALL.iter().map(|(_, n)| *n).collect();
        let (key, value) = text.split_once('=').ok_or_else(|| {
            format!("target '{text}' is not of the form METRIC=VALUE (metrics: {})", names.join(", "))
        })?;
        let key = key.trim().to_ascii_lowercase().replace('-', "_");
        let metric = TargetMetric::ALL
            .iter()
            .find(|(_, n)| *n == key)
            .map(|(m, _)| *m)
            .ok_or_else(|| format!("target '{text}': unknown metric '{key}' (metrics: {})", names.join(", ")))?;
        let value: f64 = value.trim().parse().map_err(|_| format!("target '{text}': '{value}' is not a number"))?;
        if !(value.is_finite() && value >= 0.0) {
            return Err(format!("target '{text}': the value must be finite and ≥ 0"));
        }
        Ok(Target { metric, value })
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
            .filter_map(|p| target.metric.value(&p.report).filter(|v| v.is_finite()).map(|v| (v, p)))
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
        let m = self.target.metric;
        match self.best.as_ref().and_then(|b| m.value(&b.report).map(|v| (b, v))) {
            Some((b, v)) => write!(
                f,
                "{}: no rate-ladder point meets {}: the best reached is {}={v:.6} at [{}] ({} bytes, {:.4} bpvf)",
                self.codec,
                self.target,
                m.name(),
                b.params,
                b.bytes,
                b.bpvf
            ),
            // Nothing measured because the codec refused every candidate: the metric is not
            // undefined, the codec said why (issue 41, 10f).
            None if !self.refused.is_empty() => {
                write!(
                    f,
                    "{}: no rate-ladder point meets {}: the codec refused every candidate",
                    self.codec, self.target
                )
            }
            None => write!(
                f,
                "{}: no rate-ladder point meets {}: {} is undefined for this input",
                self.codec,
                self.target,
                m.name()
            ),
        }?;
        // Issue 41: say when the bound was the worst part's, not the whole animation's.
        if let Some(b) = self.best.as_ref().filter(|b| m == TargetMetric::Kg && b.report.parts > 1) {
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
/// 0.00023 (a nearly rigid reconstruction STED cannot see; issue 15 session 5 met the same on
/// chicken-crossing). Such points never meet a target and are left out of the envelopes.
pub const DEGENERATE_KG: f64 = 50.0;

/// Whether `p` is a usable reconstruction (KG, when measured, at most [`DEGENERATE_KG`], for
/// the whole animation and for its worst part: issue 41).
pub fn usable(p: &Point) -> bool {
    p.report.kg_bound().is_none_or(|kg| kg.is_finite() && kg <= DEGENERATE_KG)
}

pub(crate) fn meets(target: Target, p: &Point) -> bool {
    target.metric.value(&p.report).is_some_and(|v| v.is_finite() && v <= target.value)
}
