//! Stream version 2's coding of the Tucker operator with `codec_core::toolkit`.
//!
//! Components: every mode-1 factor column `U1[:, i]` (a field over the vertices), every mode-3
//! column `U3[:, l]` (a signal over the frames) and every core slice `C[i, :, :]`. Each is
//! quantized in closed loop along its own order with its own step:
//! - `U1` columns along the mesh's breadth-first order ([`CausalGraph::mesh`]), predicted from
//!   reconstructed neighbours (default: parallelogram), optionally noise shaped;
//! - `U3` columns along time ([`CausalGraph::chain`]), predicted from the previous frame(s);
//! - core slices without prediction (entries are nearly uncorrelated), in `(j, l)` order.
//!
//! A column's error is multiplied by its core slice norm in the reconstruction (`s1_i`,
//! `s3_l`; the factors are orthonormal), so its distortion is counted as `s² · ‖δu‖²`. The
//! steps come from the equal-slope rule ([`rdq::allocate`]) over measured operating points
//! (a grid of steps per component, rate from the adaptive coder's own cost model), for a total
//! quantization distortion `D`; or, with `rdq=false`, from version 1's rule of thumb (equal
//! distortion per entry). All codes go through one context-adaptive arithmetic coder; the
//! class is the component (its own adaptive models, up to [`CLASSES_PER_GROUP`] per group), the
//! magnitude bucket comes from the codes of already coded neighbours.
//!
//! Stream version 4 (`regress`, beyond the paper): each `U1` column takes the predictor of
//! fewest bits ([`ColumnMode`]): the stream's mesh predictor, the parallelogram, or (after the
//! first column) a local linear regression on the leading columns over its coded two-ring
//! neighbours ([`codec_core::toolkit::regress`]). The leading columns carry the rest geometry
//! and, under piecewise-rigid motion, a later column is locally an affine function of them, so
//! the regression predicts the geometric detail the neighbour average cannot. The rate search
//! regresses on the unquantized leading columns (the decoded ones depend on steps not yet
//! chosen); the final coding and the decoder on the decoded ones, before smoothing.
//!
//! Stream version 5: the same layout, with the *guarded* regression
//! ([`Fit::guarded`]: an absolute ridge from the leads' steps, predictions clamped to the
//! neighbourhood's range). Version 4's unguarded fit could diverge on decoded leads that are
//! flat up to rounding across a small rigid part (`../shared/probe-round3/hosvd-divergence/`:
//! weights 6e12, codes clamped at `MAX_CODE`, coordinates 5e13). The rate search fits on the
//! unquantized leads with their reference steps; the final pass re-decides each regression
//! column on the *decoded* leads (regression or the mesh predictor, fewer bits), and checks
//! every component's closed loop (each entry within a step of its value before smoothing): a
//! regression column that fails is re-coded with the mesh predictor and counted in
//! [`Coded::fallbacks`]. Version 4 streams still decode with the unguarded fit.

use codec_core::toolkit::adaptive::{AdaptiveDecoder, AdaptiveEncoder, CostModel};
use codec_core::toolkit::order::CausalGraph;
use codec_core::toolkit::predict::{self, Predictor};
use codec_core::toolkit::rdq::{self, RdPoint};
use codec_core::toolkit::regress::{Fit, Neighbourhoods, Regression, MAX_REGRESSORS};
use codec_core::{Error, Result};
use rayon::prelude::*;

use crate::NAME;

/// Adaptive-model classes per component group (U1, U3, core); later components share the last.
pub const CLASSES_PER_GROUP: usize = 32;
const GROUPS: usize = 3;

/// Settings of the toolkit coding.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// Predictor of `U1` entries along the mesh.
    pub mesh: Predictor,
    /// Predictor of `U3` entries along time.
    pub time: Predictor,
    /// Noise shaping of `U1` along the mesh, `α ∈ [0, 0.95]` (encoder only).
    pub shaping: f64,
    /// Steps by the equal-slope rule (true) or version 1's rule of thumb (false).
    pub rdq: bool,
    /// Weight `β ∈ [0, 1]` of the *edge* error in the distortion the RD rule balances:
    /// `(1 − β)·Σ e² + β·Σ_edges (e_p − e_q)² / (2·edges per vertex)` (normalised so white
    /// noise over the vertices scores the same). A `U1` column's quantization error is close
    /// to white over the surface, while the error of a core slice or a `U3` column reaches
    /// the vertices through the (smooth) `U1` columns, whose normalised edge energy `ρ_i` is
    /// far below 1: with `β > 0`, bits move to `U1`, errors get smoother over the surface —
    /// what STED measures — and noise shaping pays off.
    pub edge_weight: f64,
    /// Decoder-side smoothing of the `U1` columns ([`Smoother`], stream version 3).
    pub denoise: bool,
    /// Per `U1` column, the predictor with the fewest bits among the mesh predictor, the
    /// parallelogram and (after the first column) local regression on the leading columns
    /// ([`codec_core::toolkit::regress`]); stream version 4, [`ColumnMode`].
    pub regress: bool,
    /// Test hook (never set by the codec's parameters): regression on every `U1` column after
    /// the first, with version 4's *unguarded* fit and no final-pass choice, so tests can drive
    /// the encoder into the divergence and see its closed-loop check fall back.
    pub force_unguarded_regression: bool,
}

/// How a `U1` column is predicted (stream version 4: one byte per column).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColumnMode {
    /// The stream's mesh predictor.
    Mesh = 0,
    /// Local regression on the leading columns (not for column 0).
    Regression = 1,
    /// The parallelogram predictor.
    Parallelogram = 2,
}

impl ColumnMode {
    /// The mode of a stored byte for column `i`, if valid there.
    pub fn from_byte(byte: u8, column: usize) -> Option<Self> {
        match byte {
            0 => Some(Self::Mesh),
            1 if column > 0 => Some(Self::Regression),
            2 => Some(Self::Parallelogram),
            _ => None,
        }
    }
}

/// Smoothing strengths a column may get: iterations of `x ← (x + mean of its mesh
/// neighbours) / 2` (Jacobi), indexed by the level byte in the stream.
pub const SMOOTHING_ITERATIONS: [u8; 8] = [0, 1, 2, 3, 5, 8, 12, 20];

/// Decoder-side denoising of the mode-1 factor columns (stream version 3, beyond the paper).
///
/// A column's quantization error is nearly white over the vertices while the column itself is
/// smooth (the leading left singular vectors of the motion): a few steps of neighbour
/// averaging remove much more noise than signal. The encoder measures, for every candidate
/// step, the error after each strength in [`SMOOTHING_ITERATIONS`] and keeps the best (0 =
/// none), so the equal-slope rule sees the smoothed error and chooses coarser steps; the
/// decoder applies the chosen strength. White noise loses most of its edge differences —
/// what STED measures — under averaging. Neighbours are the mesh's ([`CausalGraph::mesh`]
/// edges, in coding positions); the arithmetic is the same in encoder and decoder, in a fixed
/// order, so both get the same bits.
pub struct Smoother {
    start: Vec<u32>,
    adjacent: Vec<u32>,
}

impl Smoother {
    /// Adjacency of `graph`'s positions (each earlier-neighbour edge both ways, in
    /// [`CausalGraph::adjacency`]'s order, which the smoothing sums in).
    pub fn new(graph: &CausalGraph) -> Self {
        let (start, adjacent) = graph.adjacency();
        Self { start, adjacent }
    }

    /// One averaging step of `x` (position order) into `out`.
    fn step(&self, x: &[f64], out: &mut [f64]) {
        for p in 0..x.len() {
            let nb = &self.adjacent[self.start[p] as usize..self.start[p + 1] as usize];
            out[p] = if nb.is_empty() {
                x[p]
            } else {
                let sum: f64 = nb.iter().map(|&q| x[q as usize]).sum();
                0.5 * (x[p] + sum / nb.len() as f64)
            };
        }
    }

    /// `iterations` averaging steps of `x` in place (`tmp` is scratch).
    fn smooth(&self, x: &mut Vec<f64>, iterations: usize, tmp: &mut Vec<f64>) {
        tmp.resize(x.len(), 0.0);
        for _ in 0..iterations {
            self.step(x, tmp);
            std::mem::swap(x, tmp);
        }
    }

    /// Applies the stream's level per column to `u1` (`K × v` row-major, vertex order) given
    /// the mesh order the smoother was built on. Unknown levels are an error.
    pub fn apply_columns(&self, graph: &CausalGraph, u1: &mut [f64], v: usize, levels: &[u8]) -> Result<()> {
        let (mut col, mut tmp) = (Vec::new(), Vec::new());
        for (i, &level) in levels.iter().enumerate().take(v) {
            let iterations = *SMOOTHING_ITERATIONS
                .get(level as usize)
                .ok_or_else(|| Error::malformed(NAME, "smoothing", format!("level {level} of column {i}, at most 7")))?
                as usize;
            if iterations == 0 {
                continue;
            }
            col.clear();
            col.extend(graph.order().iter().map(|&x| u1[x as usize * v + i]));
            self.smooth(&mut col, iterations, &mut tmp);
            for (p, &x) in graph.order().iter().enumerate() {
                u1[x as usize * v + i] = col[p];
            }
        }
        Ok(())
    }
}

/// The unquantized operator, as the encoder has it.
pub struct Operator<'a> {
    /// Vertices.
    pub k: usize,
    /// Frames.
    pub frames: usize,
    /// Mode-1 rank.
    pub v: usize,
    /// Mode-3 rank.
    pub f: usize,
    /// `K × v` row-major.
    pub u1: &'a [f64],
    /// `F × f` row-major.
    pub u3: &'a [f64],
    /// `v × 3 × f`.
    pub core: &'a [f64],
    /// Core slice norms along mode 1 (gains of the `U1` columns).
    pub s1: &'a [f64],
    /// Core slice norms along mode 3 (gains of the `U3` columns).
    pub s3: &'a [f64],
}

/// The coded operator: per-component steps (0 = dropped), the decoder's values and the
/// arithmetic-coded bytes.
pub struct Coded {
    /// `v` steps of `U1`, `f` of `U3`, `v` of the core slices.
    pub steps: Vec<f32>,
    /// Dequantized `U1` (`K × v`), `U3` (`F × f`), core — exactly what the decoder rebuilds.
    pub u1: Vec<f64>,
    /// See `u1`.
    pub u3: Vec<f64>,
    /// See `u1`.
    pub core: Vec<f64>,
    /// Arithmetic-coded codes.
    pub bytes: Vec<u8>,
    /// `‖δu1_i‖` per column, `‖δu3_l‖` per column, `‖δC‖`: for the error bound.
    pub du1: Vec<f64>,
    /// See `du1`.
    pub du3: Vec<f64>,
    /// See `du1`.
    pub dc: f64,
    /// Estimated bits of the chosen allocation (the cost model's).
    pub estimated_bits: f64,
    /// Smoothing level per `U1` column (index into [`SMOOTHING_ITERATIONS`]); all 0 without
    /// `denoise`.
    pub smoothing: Vec<u8>,
    /// Per `U1` column, its [`ColumnMode`] byte (all 0 without `regress`).
    pub modes: Vec<u8>,
    /// `U1` columns coded in regression mode whose closed loop failed (an entry more than a
    /// step from its value, or not finite) and were re-coded with the mesh predictor.
    pub fallbacks: Vec<usize>,
    /// Components (coding order: `U1`, `U3`, core) whose closed loop failed with no safer mode
    /// to fall back to; the caller must not write the stream.
    pub failed: Vec<usize>,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Group {
    U1,
    U3,
    Core,
}

struct Component<'g> {
    group: Group,
    index: usize,
    graph: &'g CausalGraph,
    predictor: Predictor,
    shaping: f64,
    /// Edge-error weight (U1 only).
    edge_weight: f64,
    /// Values in coding order.
    values: Vec<f64>,
    gain2: f64,
    /// Version 1's step for this component (the grid's centre).
    reference_step: f64,
    /// Decoder-side smoothing (U1 with `denoise` only).
    smoother: Option<&'g Smoother>,
    /// Try the other column modes (U1 with `regress` only).
    modes: bool,
    /// Test hook: regression is the only mode (see [`Settings::force_unguarded_regression`]).
    forced: bool,
    /// Regression on the leading columns, unquantized (U1 columns after the first, with
    /// `regress` only): the rate search's stand-in for the decoded ones.
    regression: Option<Regression<'g>>,
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
    fn class(&self) -> usize {
        let g = match self.group {
            Group::U1 => 0,
            Group::U3 => 1,
            Group::Core => 2,
        };
        g * CLASSES_PER_GROUP + self.index.min(CLASSES_PER_GROUP - 1)
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
        match (mode, &self.regression) {
            (ColumnMode::Regression, Some(reg)) => reg.quantize(&self.values, step, codes, recon),
            (ColumnMode::Parallelogram, _) => {
                predict::quantize(self.graph, Predictor::Parallelogram, &self.values, step, self.shaping, codes, recon)
            }
            _ => predict::quantize(self.graph, self.predictor, &self.values, step, self.shaping, codes, recon),
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
    fn quantize_regressed(
        &self,
        reg: &Regression<'_>,
        step: f64,
        codes: &mut Vec<i32>,
        recon: &mut Vec<f64>,
        (alt_codes, alt_recon): (&mut Vec<i32>, &mut Vec<f64>),
    ) -> Option<bool> {
        reg.quantize(&self.values, step, codes, recon);
        let sound = closed_loop_holds(&self.values, recon, step, 0.0);
        if !sound || !self.forced {
            predict::quantize(self.graph, self.predictor, &self.values, step, self.shaping, alt_codes, alt_recon);
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
    fn apply_smoothing(&self, level: u8, recon: &mut Vec<f64>) {
        if let (Some(sm), Some(&it)) = (self.smoother, SMOOTHING_ITERATIONS.get(level as usize)) {
            sm.smooth(recon, it as usize, &mut Vec::new());
        }
    }
}

/// `Σ_edges (x_p − x_q)² / (2·edges/items) / Σ x²` over the graph's earlier-neighbour edges:
/// 1 for white noise, small for a field smooth over the surface.
fn edge_ratio(graph: &CausalGraph, x: &[f64]) -> f64 {
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
fn push_factor_components<'g>(
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
        });
    }
}

/// The reference step of `U1` column `i`: version 1's rule of thumb (the budget `target`
/// split evenly between U1, U3 and the core, and between a group's entries after the gains).
fn u1_reference_step(op: &Operator<'_>, target: f64, i: usize) -> f64 {
    (4.0 * target / (op.v * op.k) as f64).sqrt() / op.s1[i].max(1e-300)
}

/// The neighbourhoods and the fits of the regression of `U1` column `i ≥ 1` on the first
/// `min(i, leads)` columns (none when `leads` is 0), here on the unquantized columns.
fn lead_fits(
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

/// The decoded factors and core as the coder reconstructs them, with their errors.
struct Decoded {
    u1: Vec<f64>,
    u3: Vec<f64>,
    core: Vec<f64>,
    du1: Vec<f64>,
    du3: Vec<f64>,
    dc2: f64,
}

impl Decoded {
    fn new(op: &Operator<'_>) -> Self {
        Self {
            u1: vec![0.0; op.k * op.v],
            u3: vec![0.0; op.frames * op.f],
            core: vec![0.0; op.core.len()],
            du1: vec![0.0; op.v],
            du3: vec![0.0; op.f],
            dc2: 0.0,
        }
    }

    /// Stores component `c`'s reconstruction `recon` (in its graph's order) and its error.
    fn place(&mut self, c: &Component<'_>, recon: &[f64], v: usize, f: usize) {
        let err2: f64 = c.values.iter().zip(recon).map(|(x, r)| (x - r) * (x - r)).sum();
        match c.group {
            Group::U1 => {
                for (p, &x) in c.graph.order().iter().enumerate() {
                    self.u1[x as usize * v + c.index] = recon[p];
                }
                self.du1[c.index] = err2.sqrt();
            }
            Group::U3 => {
                for (t, &r) in recon.iter().enumerate() {
                    self.u3[t * f + c.index] = r;
                }
                self.du3[c.index] = err2.sqrt();
            }
            Group::Core => {
                self.core[c.index * 3 * f..(c.index + 1) * 3 * f].copy_from_slice(recon);
                self.dc2 += err2;
            }
        }
    }
}

/// The step, smoothing level and column mode of every component, and the estimated bits.
struct Steps {
    steps: Vec<f64>,
    levels: Vec<u8>,
    modes: Vec<ColumnMode>,
    estimated_bits: f64,
}

/// Chooses every component's step: with `rdq`, the equal-slope choice for the total
/// distortion `target` over a grid of steps around each reference; otherwise the reference.
fn choose_steps(comps: &[Component<'_>], rdq: bool, target: f64) -> Steps {
    let (mut codes, mut recon) = (Vec::new(), Vec::new());
    if !rdq {
        let steps: Vec<f64> =
            comps.iter().map(|c| rdq::stored_step(c.reference_step, rdq::step_floor(c.max_abs()))).collect();
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
            let floor = rdq::step_floor(c.max_abs());
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

/// Quantizes and codes `op` for a total quantization distortion `target` (squared error in
/// the normalised space).
pub fn code(op: &Operator<'_>, mesh: &CausalGraph, settings: &Settings, target: f64) -> Coded {
    let (frames, v, f) = (op.frames, op.v, op.f);
    let time = CausalGraph::chain(frames, settings.time == Predictor::Parallelogram);
    let core_chain = CausalGraph::chain(3 * f, false);
    // Version 1's rule of thumb: the budget split evenly between U1, U3 and the core, and
    // evenly between a group's entries after the gains (uniform noise Δ²/12 per entry).
    let mut comps = Vec::with_capacity(2 * v + f);
    // Normalised edge energy of each U1 column (1 for white noise, ≪ 1 for smooth fields).
    let smoother = settings.denoise.then(|| Smoother::new(mesh));
    let rho: Vec<f64> = (0..v)
        .map(|i| {
            let values: Vec<f64> = mesh.order().iter().map(|&x| op.u1[x as usize * v + i]).collect();
            edge_ratio(mesh, &values)
        })
        .collect();
    // Regression (stream version 4): column i ≥ 1 on columns 0..min(i, MAX_REGRESSORS), here
    // unquantized (the decoded ones are only known once the steps are chosen).
    let leads = regression_leads(settings, v);
    let guarded = !settings.force_unguarded_regression;
    let (hoods, fits) = lead_fits(op, mesh, leads, guarded, target);
    for i in 0..v {
        let values: Vec<f64> = mesh.order().iter().map(|&x| op.u1[x as usize * v + i]).collect();
        let reference_step = u1_reference_step(op, target, i);
        let regression = match &hoods {
            Some(hoods) if i > 0 => {
                let n = i.min(leads);
                Some(Regression { graph: mesh, fallback: settings.mesh, hoods, fit: &fits[n - 1] })
            }
            _ => None,
        };
        comps.push(Component {
            group: Group::U1,
            index: i,
            graph: mesh,
            predictor: settings.mesh,
            shaping: settings.shaping,
            edge_weight: settings.edge_weight,
            values,
            gain2: op.s1[i] * op.s1[i],
            reference_step,
            smoother: smoother.as_ref(),
            modes: settings.regress,
            forced: settings.force_unguarded_regression,
            regression,
        });
    }
    push_factor_components(op, &rho, &time, &core_chain, settings, target, &mut comps);

    // Steps: the equal-slope choice over a grid around the reference, or the reference.
    let (mut codes, mut recon) = (Vec::new(), Vec::new());
    let Steps { steps, levels, modes, estimated_bits } = choose_steps(&comps, settings.rdq, target);

    // Code every component at its step.
    let mut enc = AdaptiveEncoder::new(GROUPS * CLASSES_PER_GROUP);
    let mut out = Decoded::new(op);
    // The leading U1 columns as the decoder has them before smoothing: the regressors.
    let mut decoded_leads: Vec<Vec<f64>> = Vec::with_capacity(leads);
    let mut decoded_fit: Option<(usize, Fit)> = None;
    let mut modes = modes;
    let (mut fallbacks, mut failed) = (Vec::new(), Vec::new());
    let (mut alt_codes, mut alt_recon) = (Vec::new(), Vec::new());
    for (ci, ((c, &step), &level)) in comps.iter().zip(&steps).zip(&levels).enumerate() {
        if step > 0.0 {
            match (&hoods, modes[ci]) {
                (Some(hoods), ColumnMode::Regression) => {
                    let n = c.index.min(leads);
                    let refs: Vec<&[f64]> = decoded_leads[..n].iter().map(|x| x.as_slice()).collect();
                    // The decoder's steps of the leads (stored as f32).
                    let lead_steps: Vec<f64> = steps[..n].iter().map(|&s| s as f32 as f64).collect();
                    let fit = current_fit(&mut decoded_fit, n, hoods, &refs, &lead_steps, guarded);
                    let reg = Regression { graph: mesh, fallback: c.predictor, hoods, fit };
                    let scratch = (&mut alt_codes, &mut alt_recon);
                    if let Some(sound) = c.quantize_regressed(&reg, step, &mut codes, &mut recon, scratch) {
                        modes[ci] = ColumnMode::Mesh;
                        if !sound {
                            fallbacks.push(c.index);
                        }
                    }
                }
                (_, ColumnMode::Parallelogram) => {
                    let pred = Predictor::Parallelogram;
                    predict::quantize(c.graph, pred, &c.values, step, c.shaping, &mut codes, &mut recon)
                }
                _ => predict::quantize(c.graph, c.predictor, &c.values, step, c.shaping, &mut codes, &mut recon),
            }
            let shaping = if modes[ci] == ColumnMode::Regression { 0.0 } else { c.shaping };
            if !closed_loop_holds(&c.values, &recon, step, shaping) {
                failed.push(ci);
            }
            for p in 0..codes.len() {
                enc.encode(codes[p], c.class(), predict::neighbour_bucket(c.graph, &codes, p));
            }
        } else {
            recon.clear();
            recon.resize(c.values.len(), 0.0);
        }
        if c.group == Group::U1 && c.index < leads {
            decoded_leads.push(recon.clone());
        }
        if step > 0.0 {
            c.apply_smoothing(level, &mut recon);
        }
        out.place(c, &recon, v, f);
    }
    Coded {
        steps: steps.iter().map(|&s| s as f32).collect(),
        u1: out.u1,
        u3: out.u3,
        core: out.core,
        bytes: enc.finish(),
        du1: out.du1,
        du3: out.du3,
        dc: out.dc2.sqrt(),
        estimated_bits,
        smoothing: levels[..v].to_vec(),
        modes: modes[..v].iter().map(|&m| m as u8).collect(),
        fallbacks,
        failed,
    }
}

/// The closed loop's promise: every reconstructed entry finite and within half a step of its
/// value — `step/2/(1 − α)` with noise shaping `α` (the shaped target moves by `α` times the
/// neighbours' mean error) — plus half a step for the rounding of the prediction's
/// arithmetic. Only a clamped code (a prediction more than `MAX_CODE` steps off: a diverging
/// predictor) breaks it.
fn closed_loop_holds(values: &[f64], recon: &[f64], step: f64, shaping: f64) -> bool {
    let tolerance = step * (0.5 / (1.0 - shaping.clamp(0.0, 0.95)) + 0.5);
    values.iter().zip(recon).all(|(x, r)| r.is_finite() && (x - r).abs() <= tolerance)
}

/// The regression fit of a stream's arithmetic: guarded (version 5) or version 4's.
fn make_fit(hoods: &Neighbourhoods, refs: &[&[f64]], steps: &[f64], guarded: bool) -> Fit {
    if guarded {
        Fit::guarded(hoods, refs, steps)
    } else {
        Fit::new(hoods, refs)
    }
}

/// The fit on the first `n` decoded leading columns, built when `n` changes (columns come in
/// order, so `n` never decreases and one fit is alive at a time).
fn current_fit<'f>(
    slot: &'f mut Option<(usize, Fit)>,
    n: usize,
    hoods: &Neighbourhoods,
    refs: &[&[f64]],
    steps: &[f64],
    guarded: bool,
) -> &'f Fit {
    if slot.as_ref().is_some_and(|(m, _)| *m != n) {
        *slot = None; // dropped before the next is built
    }
    &slot.get_or_insert_with(|| (n, make_fit(hoods, refs, steps, guarded))).1
}

/// Number of leading `U1` columns the others may be regressed on (0 without `regress`).
fn regression_leads(settings: &Settings, v: usize) -> usize {
    if settings.regress {
        v.saturating_sub(1).min(MAX_REGRESSORS)
    } else {
        0
    }
}

/// The decoder's side of [`code`]: `(U1, U3, core)` from the steps and the arithmetic-coded
/// bytes. `steps` were checked finite and non-negative by the caller.
#[allow(clippy::too_many_arguments)]
pub fn decode(
    bytes: &[u8],
    mesh: &CausalGraph,
    mesh_predictor: Predictor,
    time_predictor: Predictor,
    frames: usize,
    v: usize,
    f: usize,
    steps: &[f32],
    column_modes: Option<&[u8]>,
    guarded: bool,
) -> Result<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    let k = mesh.len();
    if steps.len() != 2 * v + f {
        return Err(Error::malformed(NAME, "steps", format!("{} steps, expected {}", steps.len(), 2 * v + f)));
    }
    let modes: Vec<ColumnMode> = match column_modes {
        Some(bytes) => {
            if bytes.len() != v {
                return Err(Error::malformed(NAME, "column modes", format!("{} bytes, expected {v}", bytes.len())));
            }
            let mode = |(i, &b): (usize, &u8)| {
                ColumnMode::from_byte(b, i).ok_or_else(|| {
                    Error::malformed(NAME, "column modes", format!("column {i}: mode {b} (0..=2; 1 not for column 0)"))
                })
            };
            bytes.iter().enumerate().map(mode).collect::<Result<_>>()?
        }
        None => vec![ColumnMode::Mesh; v],
    };
    let time = CausalGraph::chain(frames, time_predictor == Predictor::Parallelogram);
    let core_chain = CausalGraph::chain(3 * f, false);
    let mut dec = AdaptiveDecoder::new(bytes, GROUPS * CLASSES_PER_GROUP, NAME, "codes")?;
    let mut codes = Vec::new();
    let mut recon = Vec::new();
    let mut u1 = vec![0.0; k * v];
    // Regression (version 4): the caller checked the neighbourhoods' size against its limits.
    let leads = if modes.contains(&ColumnMode::Regression) { v.saturating_sub(1).min(MAX_REGRESSORS) } else { 0 };
    let hoods = (leads > 0).then(|| Neighbourhoods::new(mesh));
    let mut decoded_leads: Vec<Vec<f64>> = Vec::with_capacity(leads);
    let mut fit: Option<(usize, Fit)> = None;
    for i in 0..v {
        let class = i.min(CLASSES_PER_GROUP - 1);
        let r = match (&hoods, modes[i]) {
            (Some(hoods), ColumnMode::Regression) => {
                let n = i.min(leads);
                let refs: Vec<&[f64]> = decoded_leads[..n].iter().map(|x| x.as_slice()).collect();
                let lead_steps: Vec<f64> = steps[..n].iter().map(|&s| s as f64).collect();
                let fit = current_fit(&mut fit, n, hoods, &refs, &lead_steps, guarded);
                let reg = Regression { graph: mesh, fallback: mesh_predictor, hoods, fit };
                component(&mut dec, &mut codes, &mut recon, mesh, mesh_predictor, Some(&reg), class, steps[i])?
            }
            (_, ColumnMode::Parallelogram) => {
                let pred = Predictor::Parallelogram;
                component(&mut dec, &mut codes, &mut recon, mesh, pred, None, class, steps[i])?
            }
            _ => component(&mut dec, &mut codes, &mut recon, mesh, mesh_predictor, None, class, steps[i])?,
        };
        for (p, &x) in mesh.order().iter().enumerate() {
            u1[x as usize * v + i] = r[p];
        }
        if i < leads {
            decoded_leads.push(r.to_vec());
        }
    }
    let mut u3 = vec![0.0; frames * f];
    for l in 0..f {
        let r = component(
            &mut dec,
            &mut codes,
            &mut recon,
            &time,
            time_predictor,
            None,
            CLASSES_PER_GROUP + l.min(CLASSES_PER_GROUP - 1),
            steps[v + l],
        )?;
        for (t, &x) in r.iter().enumerate() {
            u3[t * f + l] = x;
        }
    }
    let mut core = vec![0.0; 3 * v * f];
    for i in 0..v {
        let r = component(
            &mut dec,
            &mut codes,
            &mut recon,
            &core_chain,
            Predictor::Zero,
            None,
            2 * CLASSES_PER_GROUP + i.min(CLASSES_PER_GROUP - 1),
            steps[v + f + i],
        )?;
        core[i * 3 * f..(i + 1) * 3 * f].copy_from_slice(r);
    }
    // Every coded word was read (a header claiming fewer values than were coded is
    // an error, as is one claiming more: the decoder then runs past its data).
    dec.finish()?;
    Ok((u1, u3, core))
}

/// Decodes one component's codes and reconstructs it (position order) into `recon`.
#[allow(clippy::too_many_arguments)]
fn component<'r>(
    dec: &mut AdaptiveDecoder,
    codes: &mut Vec<i32>,
    recon: &'r mut Vec<f64>,
    graph: &CausalGraph,
    predictor: Predictor,
    regression: Option<&Regression<'_>>,
    class: usize,
    step: f32,
) -> Result<&'r [f64]> {
    recon.clear();
    if step == 0.0 {
        recon.resize(graph.len(), 0.0);
        return Ok(recon);
    }
    codes.clear();
    codes.resize(graph.len(), 0);
    for p in 0..graph.len() {
        let bucket = predict::neighbour_bucket(graph, codes, p);
        codes[p] = dec.decode(class, bucket)?;
    }
    match regression {
        Some(reg) => reg.dequantize(codes, step as f64, recon),
        None => predict::dequantize(graph, predictor, codes, step as f64, recon),
    }
    if recon.iter().any(|x| !x.is_finite()) {
        return Err(Error::malformed(NAME, "codes", "a decoded value is not finite"));
    }
    Ok(recon)
}
