//! The encoder's rate-distortion search: each component of the operator (a `U1` or `U3`
//! column, a core slice) with its coding order, predictor, gain and distortion measure, and the
//! equal-slope choice of every component's step ([`rdq::allocate`]) over a grid of measured
//! operating points, the rate from the adaptive coder's own cost model.

use codec_core::toolkit::adaptive::CostModel;
use codec_core::toolkit::order::CausalGraph;
use codec_core::toolkit::predict::{self, Predictor};
use codec_core::toolkit::rdq::{self, RdPoint};
use codec_core::toolkit::regress::{Fit, Neighbourhoods, Regression};
use rayon::prelude::*;
use std::sync::Arc;

use super::smoothing::{Smoother, SMOOTHING_ITERATIONS};
use super::{closed_loop_holds, make_fit, ColumnMode, Operator, Settings, CLASSES_PER_GROUP};

#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Group {
    U1,
    U3,
    Core,
}

pub(super) struct Component<'g> {
    pub(super) group: Group,
    pub(super) index: usize,
    pub(super) graph: &'g CausalGraph,
    pub(super) predictor: Predictor,
    pub(super) shaping: f64,
    /// Edge-error weight (U1 only).
    pub(super) edge_weight: f64,
    /// Values in coding order.
    pub(super) values: Vec<f64>,
    pub(super) gain2: f64,
    /// Version 1's step for this component (the grid's centre).
    pub(super) reference_step: f64,
    /// Decoder-side smoothing (U1 with `denoise` only).
    pub(super) smoother: Option<&'g Smoother>,
    /// Try the other column modes (U1 with `regress` only).
    pub(super) modes: bool,
    /// Test hook: regression is the only mode (see [`Settings::force_unguarded_regression`]).
    pub(super) forced: bool,
    /// Regression on the leading columns, unquantized (U1 columns after the first, with
    /// `regress` only): the rate search's stand-in for the decoded ones.
    pub(super) regression: Option<Regression<'g>>,
    /// Per-position step scales ([`super::relstep`]; `U1` columns from
    /// [`super::relstep::SCALED_FROM`] on, with `relstep` only).
    pub(super) scales: Option<Arc<[f64]>>,
}

/// One measured grid point of a component.
#[derive(Clone, Copy)]
struct Evaluated {
    point: RdPoint,
    /// Smoothing level that gave the distortion.
    level: u8,
    /// The column mode it was measured in.
    mode: ColumnMode,
}

impl Component<'_> {
    pub(super) fn class(&self) -> usize {
        let g = match self.group {
            Group::U1 => 0,
            Group::U3 => 1,
            Group::Core => 2,
        };
        g * CLASSES_PER_GROUP + self.index.min(CLASSES_PER_GROUP - 1)
    }

    /// The largest step scale (1 without scales).
    pub(super) fn max_scale(&self) -> f64 {
        self.scales.as_deref().map_or(1.0, |w| w.iter().fold(1.0f64, |m, &x| m.max(x)))
    }

    /// The smallest step scale (1 without scales).
    fn min_scale(&self) -> f64 {
        self.scales.as_deref().map_or(1.0, |w| w.iter().fold(1.0f64, |m, &x| m.min(x)))
    }

    /// The finest step the search may choose: 2^-28 of the component's range at the smallest
    /// step scale (codes stay far inside 2^30).
    fn step_floor(&self) -> f64 {
        rdq::step_floor(self.max_abs()) / self.min_scale()
    }

    fn max_abs(&self) -> f64 {
        self.values.iter().fold(0.0f64, |m, x| m.max(x.abs()))
    }

    /// Squared error of `recon`, blended with the edge error by `edge_weight`.
    fn distortion(&self, recon: &[f64]) -> f64 {
        let err = |p: usize| recon[p] - self.values[p];
        let plain: f64 = (0..recon.len()).map(|p| err(p) * err(p)).sum();
        if self.edge_weight == 0.0 {
            return plain;
        }
        let (mut edge, mut edges) = (0.0, 0usize);
        for p in 0..recon.len() {
            let e = err(p);
            for &q in self.graph.earlier(p) {
                edge += (e - err(q as usize)).powi(2);
                edges += 1;
            }
        }
        // White noise of variance σ² scores 2σ² per edge: normalise to σ² per item.
        let norm = if edges > 0 { recon.len() as f64 / (2.0 * edges as f64) } else { 0.0 };
        (1.0 - self.edge_weight) * plain + self.edge_weight * edge * norm
    }

    /// Codes and reconstruction of this component at `step > 0` in `mode`.
    fn quantize(&self, mode: ColumnMode, step: f64, codes: &mut Vec<i32>, recon: &mut Vec<f64>) {
        let scales = self.scales.as_deref();
        match (mode, &self.regression) {
            (ColumnMode::Regression, Some(reg)) => reg.quantize_scaled(&self.values, step, scales, codes, recon),
            (ColumnMode::Parallelogram, _) => {
                let pred = Predictor::Parallelogram;
                predict::quantize_scaled(self.graph, pred, &self.values, step, scales, self.shaping, codes, recon)
            }
            _ => predict::quantize_scaled(
                self.graph,
                self.predictor,
                &self.values,
                step,
                scales,
                self.shaping,
                codes,
                recon,
            ),
        }
    }

    /// The column mode of fewest bits at `step` (ties to the earlier in [`ColumnMode`] order);
    /// [`ColumnMode::Mesh`] without `modes`. Chosen once per component, at its reference step:
    /// the modes' ranking hardly changes along the grid. Measuring every mode at every
    /// candidate step instead made the samba encode 1.2–1.35× slower for no fewer bits (0.286
    /// / 0.562 / 1.406 vs 0.284 / 0.562 / 1.406 bpvf at ss 0.95 / 0.9 / 0.8).
    fn best_mode(&self, step: f64) -> ColumnMode {
        if !self.modes || step <= 0.0 {
            return ColumnMode::Mesh;
        }
        if self.forced && self.regression.is_some() {
            return ColumnMode::Regression;
        }
        let (mut codes, mut recon) = (Vec::new(), Vec::new());
        let mut best = (f64::INFINITY, ColumnMode::Mesh);
        for mode in [ColumnMode::Mesh, ColumnMode::Regression, ColumnMode::Parallelogram] {
            let available = match mode {
                ColumnMode::Mesh => true,
                ColumnMode::Regression => self.regression.is_some(),
                ColumnMode::Parallelogram => self.predictor != Predictor::Parallelogram,
            };
            if available {
                self.quantize(mode, step, &mut codes, &mut recon);
                let rate = self.rate(&codes);
                if rate < best.0 {
                    best = (rate, mode);
                }
            }
        }
        best.1
    }

    /// Rate (bits) and distortion (output units) at `step` (0 = dropped) in `mode`, and the
    /// smoothing level that gave that distortion.
    fn evaluate(&self, mode: ColumnMode, step: f64, codes: &mut Vec<i32>, recon: &mut Vec<f64>) -> Evaluated {
        if step == 0.0 {
            recon.clear();
            recon.resize(self.values.len(), 0.0);
            let point = RdPoint { rate: 0.0, distortion: self.gain2 * self.distortion(recon) };
            return Evaluated { point, level: 0, mode };
        }
        self.quantize(mode, step, codes, recon);
        let rate = self.rate(codes);
        let (distortion, level) = self.best_smoothing(recon);
        Evaluated { point: RdPoint { rate, distortion: self.gain2 * distortion }, level, mode }
    }

    /// Bits of `codes` by the adaptive coder's cost model (one class, neighbour buckets).
    /// Quantizes this column by `reg` into `codes` / `recon`. The search chose the mode on the
    /// unquantized leads; on the decoded ones the regression may lose to the mesh predictor
    /// (or, unguarded, diverge): then the column is coded with the mesh predictor instead
    /// (through `scratch`) and the answer says whether the regression was sound; `None` when
    /// the regression is kept.
    pub(super) fn quantize_regressed(
        &self,
        reg: &Regression<'_>,
        step: f64,
        codes: &mut Vec<i32>,
        recon: &mut Vec<f64>,
        (alt_codes, alt_recon): (&mut Vec<i32>, &mut Vec<f64>),
    ) -> Option<bool> {
        let scales = self.scales.as_deref();
        reg.quantize_scaled(&self.values, step, scales, codes, recon);
        let sound = closed_loop_holds(&self.values, recon, step * self.max_scale(), 0.0);
        if !sound || !self.forced {
            let (graph, pred, shaping) = (self.graph, self.predictor, self.shaping);
            predict::quantize_scaled(graph, pred, &self.values, step, scales, shaping, alt_codes, alt_recon);
            if !sound || self.rate(alt_codes) < self.rate(codes) {
                std::mem::swap(codes, alt_codes);
                std::mem::swap(recon, alt_recon);
                return Some(sound);
            }
        }
        None
    }

    fn rate(&self, codes: &[i32]) -> f64 {
        let mut cost = CostModel::new(1);
        for p in 0..codes.len() {
            cost.add(codes[p], 0, predict::neighbour_bucket(self.graph, codes, p));
        }
        cost.bits()
    }

    /// The smallest distortion over the smoothing levels (none without a smoother) and its
    /// level; stops once two levels in a row got worse.
    fn best_smoothing(&self, recon: &[f64]) -> (f64, u8) {
        let mut best = (self.distortion(recon), 0u8);
        let Some(sm) = self.smoother else { return best };
        let (mut x, mut tmp) = (recon.to_vec(), Vec::new());
        let (mut done, mut worse) = (0usize, 0);
        for (level, &it) in SMOOTHING_ITERATIONS.iter().enumerate().skip(1) {
            sm.smooth(&mut x, it as usize - done, &mut tmp);
            done = it as usize;
            let d = self.distortion(&x);
            if d < best.0 {
                best = (d, level as u8);
                worse = 0;
            } else {
                worse += 1;
                if worse == 2 {
                    break;
                }
            }
        }
        best
    }

    /// Applies `level` to `recon` in place (U1 with a smoother).
    pub(super) fn apply_smoothing(&self, level: u8, recon: &mut Vec<f64>) {
        if let (Some(sm), Some(&it)) = (self.smoother, SMOOTHING_ITERATIONS.get(level as usize)) {
            sm.smooth(recon, it as usize, &mut Vec::new());
        }
    }
}

/// `Σ_edges (x_p − x_q)² / (2·edges/items) / Σ x²` over the graph's earlier-neighbour edges:
/// 1 for white noise, small for a field smooth over the surface.
pub(super) fn edge_ratio(graph: &CausalGraph, x: &[f64]) -> f64 {
    let (mut edge, mut edges, mut plain) = (0.0, 0usize, 0.0);
    for p in 0..x.len() {
        plain += x[p] * x[p];
        for &q in graph.earlier(p) {
            edge += (x[p] - x[q as usize]).powi(2);
            edges += 1;
        }
    }
    if edges == 0 || plain == 0.0 {
        return 1.0;
    }
    edge * x.len() as f64 / (2.0 * edges as f64) / plain
}

/// Edge ratio of the spatial pattern a `U3` column's error takes: the `U1` columns' ratios
/// weighted by the energy the core gives them with that column.
fn mixed_ratio(op: &Operator<'_>, rho: &[f64], l: usize) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (i, r) in rho.iter().enumerate() {
        let e: f64 = (0..3).map(|j| op.core[(i * 3 + j) * op.f + l].powi(2)).sum();
        num += e * r;
        den += e;
    }
    if den > 0.0 {
        num / den
    } else {
        1.0
    }
}

/// Steps per octave and octaves below / above the reference step searched by the RD rule.
const PER_OCTAVE: usize = 2;
const OCTAVES_FINER: usize = 3;
const OCTAVES_COARSER: usize = 6;

/// The components of the mode-3 factor `U3` (one per column, along `time`) and of the core
/// (one per `U1` column's slice, along `core_chain`), after the `U1` columns in `comps`.
pub(super) fn push_factor_components<'g>(
    op: &Operator<'_>,
    rho: &[f64],
    time: &'g CausalGraph,
    core_chain: &'g CausalGraph,
    settings: &Settings,
    target: f64,
    comps: &mut Vec<Component<'g>>,
) {
    let (frames, f) = (op.frames, op.f);
    let beta = settings.edge_weight;
    for l in 0..f {
        let values: Vec<f64> = (0..frames).map(|t| op.u3[t * f + l]).collect();
        let reference_step = (4.0 * target / (f * frames) as f64).sqrt() / op.s3[l].max(1e-300);
        comps.push(Component {
            group: Group::U3,
            index: l,
            graph: time,
            predictor: settings.time,
            shaping: 0.0,
            edge_weight: 0.0,
            values,
            gain2: op.s3[l] * op.s3[l] * (1.0 - beta + beta * mixed_ratio(op, rho, l)),
            reference_step,
            smoother: None,
            modes: false,
            forced: false,
            regression: None,
            scales: None,
        });
    }
    for (i, r) in rho.iter().enumerate() {
        let values = op.core[i * 3 * f..(i + 1) * 3 * f].to_vec();
        let reference_step = (4.0 * target / op.core.len() as f64).sqrt();
        comps.push(Component {
            group: Group::Core,
            index: i,
            graph: core_chain,
            predictor: Predictor::Zero,
            shaping: 0.0,
            edge_weight: 0.0,
            values,
            gain2: 1.0 - beta + beta * r,
            reference_step,
            smoother: None,
            modes: false,
            forced: false,
            regression: None,
            scales: None,
        });
    }
}

/// The reference step of `U1` column `i`: version 1's rule of thumb (the budget `target`
/// split evenly between U1, U3 and the core, and between a group's entries after the gains).
pub(super) fn u1_reference_step(op: &Operator<'_>, target: f64, i: usize) -> f64 {
    (4.0 * target / (op.v * op.k) as f64).sqrt() / op.s1[i].max(1e-300)
}

/// The neighbourhoods and the fits of the regression of `U1` column `i ≥ 1` on the first
/// `min(i, leads)` columns (none when `leads` is 0), here on the unquantized columns.
pub(super) fn lead_fits(
    op: &Operator<'_>,
    mesh: &CausalGraph,
    leads: usize,
    guarded: bool,
    target: f64,
) -> (Option<Neighbourhoods>, Vec<Fit>) {
    let v = op.v;
    let lead_columns: Vec<Vec<f64>> =
        (0..leads).map(|i| mesh.order().iter().map(|&x| op.u1[x as usize * v + i]).collect()).collect();
    let lead_refs: Vec<&[f64]> = lead_columns.iter().map(|c| c.as_slice()).collect();
    // The guarded fit's ridge needs the leads' steps, not chosen yet: their reference steps
    // stand in (the decoded leads' noise is of that order).
    let lead_steps: Vec<f64> = lead_columns
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let max_abs = c.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            rdq::stored_step(u1_reference_step(op, target, i), rdq::step_floor(max_abs))
        })
        .collect();
    let hoods = (leads > 0).then(|| Neighbourhoods::new(mesh));
    let fits: Vec<Fit> = match &hoods {
        Some(h) => (1..=leads).map(|n| make_fit(h, &lead_refs[..n], &lead_steps[..n], guarded)).collect(),
        None => Vec::new(),
    };
    (hoods, fits)
}

/// The step, smoothing level and column mode of every component, and the estimated bits.
pub(super) struct Steps {
    pub(super) steps: Vec<f64>,
    pub(super) levels: Vec<u8>,
    pub(super) modes: Vec<ColumnMode>,
    pub(super) estimated_bits: f64,
}

/// Chooses every component's step: with `rdq`, the equal-slope choice for the total
/// distortion `target` over a grid of steps around each reference; otherwise the reference.
pub(super) fn choose_steps(comps: &[Component<'_>], rdq: bool, target: f64) -> Steps {
    let (mut codes, mut recon) = (Vec::new(), Vec::new());
    if !rdq {
        let steps: Vec<f64> = comps.iter().map(|c| rdq::stored_step(c.reference_step, c.step_floor())).collect();
        let evaluated: Vec<Evaluated> = comps
            .iter()
            .zip(&steps)
            .map(|(c, &s)| {
                if c.smoother.is_some() || c.modes {
                    c.evaluate(c.best_mode(s), s, &mut codes, &mut recon)
                } else {
                    Evaluated { point: RdPoint { rate: 0.0, distortion: 0.0 }, level: 0, mode: ColumnMode::Mesh }
                }
            })
            .collect();
        return Steps {
            steps,
            levels: evaluated.iter().map(|e| e.level).collect(),
            modes: evaluated.iter().map(|e| e.mode).collect(),
            estimated_bits: 0.0,
        };
    }
    // Components are independent: their grids are measured in parallel (each task with its
    // own scratch) and collected in component order, so the choice does not depend on the
    // thread count. This search is most of the toolkit encoder's time.
    let measured: Vec<(Vec<f64>, Vec<Evaluated>)> = comps
        .par_iter()
        .map(|c| {
            let (mut codes, mut recon) = (Vec::new(), Vec::new());
            // Never finer than 2^-28 of the component's range (codes stay far inside 2^30).
            let floor = c.step_floor();
            let largest = c.reference_step * 2f64.powi(OCTAVES_COARSER as i32);
            let mode = c.best_mode(rdq::stored_step(c.reference_step, floor));
            let mut grid = vec![0.0];
            let mut evaluated = vec![c.evaluate(mode, 0.0, &mut codes, &mut recon)];
            for s in rdq::step_grid(largest, (OCTAVES_COARSER + OCTAVES_FINER) * PER_OCTAVE + 1, PER_OCTAVE) {
                let s = rdq::stored_step(s, floor);
                let e = c.evaluate(mode, s, &mut codes, &mut recon);
                grid.push(s);
                evaluated.push(e);
                // Finer steps cannot be chosen once this component's distortion is negligible.
                if e.point.distortion < 1e-4 * target {
                    break;
                }
            }
            (grid, evaluated)
        })
        .collect();
    let points: Vec<Vec<RdPoint>> = measured.iter().map(|(_, e)| e.iter().map(|e| e.point).collect()).collect();
    let a = rdq::allocate(&points, target);
    let chosen: Vec<(f64, Evaluated)> = a.choice.iter().zip(&measured).map(|(&i, (g, e))| (g[i], e[i])).collect();
    Steps {
        steps: chosen.iter().map(|c| c.0).collect(),
        levels: chosen.iter().map(|c| c.1.level).collect(),
        modes: chosen.iter().map(|c| c.1.mode).collect(),
        estimated_bits: a.rate,
    }
}
