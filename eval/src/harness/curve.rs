//! What a sweep's curves show: whether each one is monotone along its ladder
//! ([`monotone_report`]), and which points lie on each codec's lower envelope ([`envelope`]).

use serde::Serialize;

use super::measured::Point;
use super::target::{sted_degenerate, usable, TargetMetric};

/// Monotonicity of one codec's curve along its ladder.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Monotonicity {
    /// Curve name (see [`Point::series`]).
    pub series: String,
    /// bpvf never falls from one ladder point to the next.
    pub bpvf_increasing: bool,
    /// KG never rises (beyond a relative 1e-9) from one ladder point to the next.
    pub kg_decreasing: bool,
    /// STED never rises (same tolerance).
    pub sted_decreasing: bool,
    /// Ladder indices where one of the above fails (the later point of each bad pair).
    pub violations: Vec<usize>,
}

/// Checks every series' curve in sorted `points` (as [`sweep`](super::sweep::sweep) returns them). Metric values
/// that are missing are skipped. The tolerance absorbs float noise only.
pub fn monotone_report(points: &[Point]) -> Vec<Monotonicity> {
    let mut out: Vec<Monotonicity> = Vec::new();
    for pair in points.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        if a.series != b.series {
            continue;
        }
        let not_above = |x: Option<f64>, y: Option<f64>| match (x, y) {
            (Some(x), Some(y)) => y <= x + 1e-9 * x.abs().max(y.abs()),
            _ => true,
        };
        let bpvf_ok = b.bpvf >= a.bpvf;
        let kg_ok = not_above(a.report.kg, b.report.kg);
        let sted_ok = not_above(a.report.sted, b.report.sted);
        let m = match out.iter_mut().find(|m| m.series == a.series) {
            Some(m) => m,
            None => {
                out.push(Monotonicity {
                    series: a.series.clone(),
                    bpvf_increasing: true,
                    kg_decreasing: true,
                    sted_decreasing: true,
                    violations: Vec::new(),
                });
                out.last_mut().expect("just pushed")
            }
        };
        m.bpvf_increasing &= bpvf_ok;
        m.kg_decreasing &= kg_ok;
        m.sted_decreasing &= sted_ok;
        if !(bpvf_ok && kg_ok && sted_ok) {
            m.violations.push(b.ladder_index);
        }
    }
    out
}

/// Positions in `points` of each codec's lower envelope by `metric`: sorted by bytes, the
/// points whose error is below that of every smaller stream of the same codec (points that are
/// not [`usable`] left out, and for STED the [`sted_degenerate`] ones too). In input order.
pub fn envelope(points: &[Point], metric: TargetMetric) -> Vec<usize> {
    let mut order: Vec<usize> = (0..points.len())
        .filter(|&i| {
            let r = &points[i].report;
            metric.value(r).is_some() && usable(&points[i]) && !(metric == TargetMetric::Sted && sted_degenerate(r))
        })
        .collect();
    order.sort_by_key(|&i| (points[i].codec, points[i].bytes, i));
    let mut keep = Vec::new();
    let mut last: Option<(&str, f64)> = None;
    for i in order {
        let v = metric.value(&points[i].report).unwrap_or(f64::INFINITY);
        let better = match last {
            Some((codec, best)) if codec == points[i].codec => v < best,
            _ => v.is_finite(),
        };
        if better {
            last = Some((points[i].codec, v));
            keep.push(i);
        }
    }
    keep.sort_unstable();
    keep
}

/// Positions in `points` of each codec's joint envelope by KG and STED: the points no other
/// point of the same codec beats on all three of bytes, KG (whole or worst part) and STED
/// (fewer or equal everywhere, fewer somewhere) — the streams among which a joint target
/// (`kg=0.5,sted=0.05`) finds its answer. Points not [`usable`], [`sted_degenerate`] or
/// without both metrics are left out. In input order.
pub fn joint_envelope(points: &[Point]) -> Vec<usize> {
    let measured = |i: usize| {
        let r = &points[i].report;
        let (kg, sted) = (r.kg_bound()?, r.sted?);
        (usable(&points[i]) && !sted_degenerate(r) && sted.is_finite()).then_some((points[i].bytes, kg, sted))
    };
    let candidates: Vec<(usize, (u64, f64, f64))> =
        (0..points.len()).filter_map(|i| measured(i).map(|m| (i, m))).collect();
    candidates
        .iter()
        .filter(|(i, (b, k, s))| {
            !candidates.iter().any(|(j, (b2, k2, s2))| {
                points[*j].codec == points[*i].codec && b2 <= b && k2 <= k && s2 <= s && (b2 < b || k2 < k || s2 < s)
            })
        })
        .map(|(i, _)| *i)
        .collect()
}
