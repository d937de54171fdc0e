//! Cross-component prediction: a field's value at a position predicted from its reconstructed
//! values at causal neighbours, *regressed locally* on fields already known at every position.
//!
//! Why: the mode-1 factor of a Tucker (HO-SVD) decomposition of a mesh animation has one row per
//! vertex, and under piecewise-rigid motion a row is locally an affine function of the vertex's
//! rest position. The leading columns carry that geometry, so a later column is, around every
//! vertex, close to an affine function of the leading columns: `u_i(x) ≈ a + Σ_j b_j·u_j(x)`.
//! The neighbour average predicts only the smooth part of a column; the local regression also
//! predicts the geometric detail the column shares with the leading ones. Measured on
//! horse-gallop (`v = 8`) and samba (`v = 14`) before this module was written (Python
//! prototype, closed loop, zero-order entropy): the mode-1 factor's codes took 26% / 39% fewer
//! bits than with the neighbour average (measured with a Python prototype).
//!
//! The fit at position `p` uses the *neighbourhood* `N(p)`: the positions within two mesh rings
//! coded before `p` ([`Neighbourhoods`], at most [`MAX_NEIGHBOURS`], the latest ones). The
//! regressors `r` (at most [`MAX_REGRESSORS`] fields known everywhere, e.g. the factor's
//! columns decoded before) are centred on `N(p)`; least squares of the field `y` on them
//! (intercept included, a small ridge [`RIDGE`]) predicts
//! `ŷ_p = ȳ + (r_p − r̄)ᵀ G⁻¹ Σ_q (r_q − r̄)·y_q` — linear in the neighbours' values, because the
//! centred regressors sum to zero. So [`Fit`] turns each position's fit into one weight per
//! neighbour, `w_q = 1/|N| + (r_p − r̄)ᵀ G⁻¹ (r_q − r̄)`, once (it depends on the regressors
//! only), and a prediction is a dot product, whatever the candidate step of a rate search. Too
//! small a neighbourhood or a singular fit falls back to a [`Predictor`].
//!
//! Everything is plain `f64` arithmetic in a fixed order (no fused operations, no library
//! functions), so the encoder and the decoder compute the same predictions bit for bit.
//!
//! **Guarded fits** ([`Fit::guarded`], hosvd stream version 5). The closed loop
//! regresses on *decoded* regressors, which carry quantization noise of about `step²/12` per
//! entry. Across a small rigid part the decoded leads can be flat up to floating-point rounding
//! (every entry coded with 0): the Gram matrix is ~1e-36, a ridge relative to its trace adds
//! nothing, and one lead code of ±1 (one step) makes the weights grow like step / 1e-18 — the
//! prediction is off by 1e8–1e12 steps and the reconstruction explodes
//! (`../shared/probe-round3/hosvd-divergence/`). The guarded fit therefore (1) adds an
//! *absolute* ridge `|N|·step_j²/12` to `G_jj`, the noise energy the decoded regressor `j`
//! carries over the neighbourhood (ridge regression as the errors-in-variables correction):
//! a neighbourhood whose lead spread is below a few steps carries no information and its
//! weights shrink smoothly to the plain neighbour average `1/|N|`; and (2) clamps every
//! prediction to the neighbours' reconstructed range widened by its own width on both sides
//! (room for a linear extrapolation across two rings), so no fit can put the prediction far
//! outside the values it was made from.

use super::order::CausalGraph;
use super::predict::{self, Predictor};

/// Most regressor fields of one fit.
pub const MAX_REGRESSORS: usize = 4;
/// Most neighbours of one position (the latest coded ones within two rings).
pub const MAX_NEIGHBOURS: usize = 48;
/// Most entries of one position's adjacency read when gathering a neighbourhood (the first, in
/// [`CausalGraph::adjacency`] order): real meshes have far fewer, and a hub vertex of a
/// hostile mesh (a fan of 10⁵ triangles) must not make the gathering quadratic.
pub const RING_CAP: usize = 32;
/// Ridge added to the centred Gram matrix's diagonal, relative to its mean diagonal entry:
/// keeps nearly collinear neighbourhoods from extrapolating wildly.
pub const RIDGE: f64 = 1e-6;
/// Quantization noise energy per entry of a decoded regressor, in squared steps (uniform error
/// over one step): the guarded fit's absolute ridge is `|N| · step² · NOISE_PER_STEP2`.
pub const NOISE_PER_STEP2: f64 = 1.0 / 12.0;

/// Per position, the positions within two mesh rings coded before it (ascending, at most
/// [`MAX_NEIGHBOURS`]: the latest). Each ring is read up to its first [`RING_CAP`] entries.
#[derive(Debug, Clone)]
pub struct Neighbourhoods {
    start: Vec<u32>,
    list: Vec<u32>,
}

impl Neighbourhoods {
    /// Built from `graph`'s earlier-neighbour lists (each edge seen both ways).
    pub fn new(graph: &CausalGraph) -> Self {
        let n = graph.len();
        let (adj_start, adj) = graph.adjacency();
        let ring = |p: usize| {
            let (a, b) = (adj_start[p] as usize, adj_start[p + 1] as usize);
            &adj[a..b.min(a + RING_CAP)]
        };
        let mut mark = vec![u32::MAX; n];
        let mut start = Vec::with_capacity(n + 1);
        start.push(0u32);
        let mut list = Vec::new();
        let mut found = Vec::new();
        for p in 0..n {
            found.clear();
            for &q in ring(p) {
                for &r in std::iter::once(&q).chain(ring(q as usize)) {
                    if (r as usize) < p && mark[r as usize] != p as u32 {
                        mark[r as usize] = p as u32;
                        found.push(r);
                    }
                }
            }
            found.sort_unstable();
            let keep = found.len().saturating_sub(MAX_NEIGHBOURS);
            list.extend_from_slice(&found[keep..]);
            start.push(list.len() as u32);
        }
        Self { start, list }
    }

    /// Bytes [`Neighbourhoods::new`] and one [`Fit`] allocate for `positions` positions, at
    /// most, besides the adjacency (twice the graph's earlier lists, which
    /// [`super::order::mesh_bytes`] bounds): for a decoder's limit check before building them.
    pub fn bytes(positions: usize) -> u64 {
        let hoods = MAX_NEIGHBOURS * 4 + 3 * 4; // lists; offsets, marks, adjacency offsets
        let fit = MAX_NEIGHBOURS * 8 + 1; // weights, usable flag
        (positions as u64).saturating_mul((hoods + fit) as u64)
    }

    /// Number of positions.
    pub fn len(&self) -> usize {
        self.start.len() - 1
    }

    /// True when there are no positions.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The neighbourhood of position `p`.
    pub fn of(&self, p: usize) -> &[u32] {
        &self.list[self.start[p] as usize..self.start[p + 1] as usize]
    }
}

/// Every position's prediction weights over its neighbourhood (see the module docs). Depends
/// on the regressors only.
#[derive(Debug, Clone)]
pub struct Fit {
    k: usize,
    /// Guarded ([`Fit::guarded`]): predictions are clamped to the neighbourhood's range.
    clamped: bool,
    usable: Vec<bool>,
    /// One weight per neighbourhood entry (same layout as [`Neighbourhoods`]' lists).
    weights: Vec<f64>,
}

impl Fit {
    /// Weights for `regressors` (1..=[`MAX_REGRESSORS`] fields in position order, each at
    /// least `hoods.len()` long). A position is usable when its neighbourhood has at least
    /// `k + 2` entries, the Gram matrix's trace is finite and positive, the factorization has
    /// positive pivots and every weight is finite.
    /// This is hosvd stream version 4's fit (unguarded: see the module docs).
    pub fn new(hoods: &Neighbourhoods, regressors: &[&[f64]]) -> Self {
        Self::build(hoods, regressors, None)
    }

    /// The guarded fit (hosvd stream version 5; module docs): as [`Fit::new`], plus an
    /// absolute ridge `|N|·steps[j]²/12` on `G_jj` (`steps[j]` the quantization step regressor
    /// `j` was decoded with; 0 adds nothing) and predictions clamped to the neighbourhood's
    /// reconstructed range widened by its width. `steps` must hold one step per regressor
    /// (else no position is usable).
    pub fn guarded(hoods: &Neighbourhoods, regressors: &[&[f64]], steps: &[f64]) -> Self {
        Self::build(hoods, regressors, Some(steps))
    }

    fn build(hoods: &Neighbourhoods, regressors: &[&[f64]], steps: Option<&[f64]>) -> Self {
        let k = regressors.len().clamp(1, MAX_REGRESSORS);
        let n = hoods.len();
        let clamped = steps.is_some();
        let mut fit = Self { k, clamped, usable: vec![false; n], weights: vec![0.0; hoods.list.len()] };
        if regressors.len() != k || regressors.iter().any(|r| r.len() < n) {
            return fit;
        }
        if steps.is_some_and(|s| s.len() != k || s.iter().any(|x| !(x.is_finite() && *x >= 0.0))) {
            return fit;
        }
        let mut gram = [0.0f64; MAX_REGRESSORS * MAX_REGRESSORS];
        let mut l = [0.0f64; MAX_REGRESSORS * MAX_REGRESSORS];
        let mut mean = [0.0f64; MAX_REGRESSORS];
        let mut z = [0.0f64; MAX_REGRESSORS];
        for p in 0..n {
            let list = hoods.of(p);
            if list.len() < k + 2 {
                continue;
            }
            let count = list.len() as f64;
            for (j, r) in regressors.iter().enumerate() {
                mean[j] = list.iter().map(|&q| r[q as usize]).sum::<f64>() / count;
            }
            for j in 0..k {
                for c in 0..=j {
                    let (rj, rc) = (regressors[j], regressors[c]);
                    gram[j * k + c] =
                        list.iter().map(|&q| (rj[q as usize] - mean[j]) * (rc[q as usize] - mean[c])).sum::<f64>();
                }
            }
            let trace: f64 = (0..k).map(|j| gram[j * k + j]).sum();
            if !(trace > 0.0 && trace.is_finite()) {
                continue;
            }
            let ridge = RIDGE * trace / k as f64;
            for j in 0..k {
                gram[j * k + j] += ridge;
            }
            if let Some(steps) = steps {
                for j in 0..k {
                    gram[j * k + j] += count * (steps[j] * steps[j] * NOISE_PER_STEP2);
                }
            }
            // Cholesky factor L (lower, row major) of the ridged Gram matrix.
            let mut ok = true;
            'factor: for j in 0..k {
                for c in 0..=j {
                    let mut s = gram[j * k + c];
                    for m in 0..c {
                        s -= l[j * k + m] * l[c * k + m];
                    }
                    if c == j {
                        if s.is_nan() || s <= 0.0 {
                            ok = false;
                            break 'factor;
                        }
                        l[j * k + j] = s.sqrt();
                    } else {
                        l[j * k + c] = s / l[c * k + c];
                    }
                }
            }
            if !ok {
                continue;
            }
            // w_q = 1/|N| + Σ_j (r_p − r̄)_j · z_j, with L·Lᵀ·z = r_q − r̄.
            let start = hoods.start[p] as usize;
            for (e, &q) in list.iter().enumerate() {
                for j in 0..k {
                    let mut s = regressors[j][q as usize] - mean[j];
                    for m in 0..j {
                        s -= l[j * k + m] * z[m];
                    }
                    z[j] = s / l[j * k + j];
                }
                for j in (0..k).rev() {
                    let mut s = z[j];
                    for m in j + 1..k {
                        s -= l[m * k + j] * z[m];
                    }
                    z[j] = s / l[j * k + j];
                }
                let mut w = 1.0 / count;
                for j in 0..k {
                    w += (regressors[j][p] - mean[j]) * z[j];
                }
                fit.weights[start + e] = w;
            }
            fit.usable[p] = fit.weights[start..start + list.len()].iter().all(|w| w.is_finite());
        }
        fit
    }

    /// Number of regressors.
    pub fn regressors(&self) -> usize {
        self.k
    }

    /// True for a guarded fit ([`Fit::guarded`]).
    pub fn is_guarded(&self) -> bool {
        self.clamped
    }

    /// Share of positions with a usable fit.
    pub fn usable_share(&self) -> f64 {
        if self.usable.is_empty() {
            return 0.0;
        }
        self.usable.iter().filter(|&&u| u).count() as f64 / self.usable.len() as f64
    }
}

/// The predictor of one field: fallback [`Predictor`] along `graph`, the neighbourhoods and the
/// fit's weights.
#[derive(Clone, Copy)]
pub struct Regression<'a> {
    /// Order and neighbours of the fallback predictor.
    pub graph: &'a CausalGraph,
    /// Where a position has no usable fit (or the weighted sum is not finite).
    pub fallback: Predictor,
    /// Neighbourhoods the fit was built on.
    pub hoods: &'a Neighbourhoods,
    /// The weights.
    pub fit: &'a Fit,
}

impl Regression<'_> {
    /// Prediction for position `p` from the reconstruction `recon` (valid below `p`): the
    /// weighted sum over the neighbourhood, in its order.
    #[inline]
    pub fn predict(&self, recon: &[f64], p: usize) -> f64 {
        if self.fit.usable[p] {
            let (a, b) = (self.hoods.start[p] as usize, self.hoods.start[p + 1] as usize);
            let pred: f64 =
                self.hoods.list[a..b].iter().zip(&self.fit.weights[a..b]).map(|(&q, &w)| w * recon[q as usize]).sum();
            if pred.is_finite() {
                if !self.fit.clamped {
                    return pred;
                }
                // Guarded: within the neighbours' range widened by its width (module docs).
                let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
                for &q in &self.hoods.list[a..b] {
                    let y = recon[q as usize];
                    lo = if y < lo { y } else { lo };
                    hi = if y > hi { y } else { hi };
                }
                let width = hi - lo;
                let (lo, hi) = (lo - width, hi + width);
                return if pred < lo {
                    lo
                } else if pred > hi {
                    hi
                } else {
                    pred
                };
            }
        }
        predict::predict(self.graph, self.fallback, recon, p)
    }

    /// Closed-loop quantization of `values` (position order) at `step > 0`, like
    /// [`predict::quantize`] without noise shaping.
    pub fn quantize(&self, values: &[f64], step: f64, codes: &mut Vec<i32>, recon: &mut Vec<f64>) {
        self.quantize_scaled(values, step, None, codes, recon)
    }

    /// [`Regression::quantize`] with a step per position, `step · scales[p]`, like
    /// [`predict::quantize_scaled`].
    pub fn quantize_scaled(
        &self,
        values: &[f64],
        step: f64,
        scales: Option<&[f64]>,
        codes: &mut Vec<i32>,
        recon: &mut Vec<f64>,
    ) {
        let n = values.len().min(self.hoods.len());
        codes.clear();
        codes.resize(n, 0);
        recon.clear();
        recon.resize(n, 0.0);
        let inv = 1.0 / step;
        for p in 0..n {
            let pred = self.predict(recon, p);
            (codes[p], recon[p]) = match scales {
                Some(w) => {
                    let s = step * w[p];
                    predict::quantize_one(values[p], pred, s, 1.0 / s)
                }
                None => predict::quantize_one(values[p], pred, step, inv),
            };
        }
    }

    /// The decoder's side of [`Regression::quantize`].
    pub fn dequantize(&self, codes: &[i32], step: f64, recon: &mut Vec<f64>) {
        self.dequantize_scaled(codes, step, None, recon)
    }

    /// The decoder's side of [`Regression::quantize_scaled`].
    pub fn dequantize_scaled(&self, codes: &[i32], step: f64, scales: Option<&[f64]>, recon: &mut Vec<f64>) {
        let n = codes.len().min(self.hoods.len());
        recon.clear();
        recon.resize(n, 0.0);
        for p in 0..n {
            let s = match scales {
                Some(w) => step * w[p],
                None => step,
            };
            recon[p] = self.predict(recon, p) + codes[p] as f64 * s;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A grid mesh and three fields: two "coordinates" with per-vertex detail (a hash, so the
    /// neighbour average cannot predict it) and a piecewise-affine function of them, the
    /// situation the module is for.
    fn setup() -> (CausalGraph, Vec<Vec<f64>>) {
        let topo = crate::Topology::grid(20, 16).unwrap();
        let graph = CausalGraph::mesh(topo.vertex_count(), topo.triangles());
        let n = graph.len();
        let detail = |x: u32, salt: u32| {
            let h = (x.wrapping_mul(2_654_435_761) ^ salt).wrapping_mul(2_246_822_519);
            (h >> 8) as f64 / (1u32 << 24) as f64 - 0.5
        };
        let mut fields = vec![vec![0.0; n]; 3];
        for (p, &x) in graph.order().iter().enumerate() {
            let (i, j) = ((x % 20) as f64, (x / 20) as f64);
            let (u, w) = (i + 0.3 * detail(x, 1), j + 0.3 * detail(x, 2));
            fields[0][p] = u;
            fields[1][p] = w;
            fields[2][p] = if i < 10.0 { 2.0 * u - w } else { 0.5 * u + 3.0 * w };
        }
        (graph, fields)
    }

    #[test]
    fn neighbourhoods_are_causal_two_rings() {
        let (graph, _) = setup();
        let hoods = Neighbourhoods::new(&graph);
        assert_eq!(hoods.len(), graph.len());
        for p in 0..graph.len() {
            let list = hoods.of(p);
            assert!(list.len() <= MAX_NEIGHBOURS);
            assert!(list.windows(2).all(|w| w[0] < w[1]), "ascending, no repeats");
            assert!(list.iter().all(|&q| (q as usize) < p), "only earlier positions");
            // Every earlier 1-ring neighbour is in it.
            for &q in graph.earlier(p) {
                assert!(list.contains(&q), "position {p}: 1-ring neighbour {q} missing");
            }
        }
        // Interior vertices of a grid have 2-ring neighbours beyond the 1-ring.
        let wider = (0..graph.len()).filter(|&p| hoods.of(p).len() > graph.earlier(p).len()).count();
        assert!(wider > graph.len() / 2, "{wider} of {}", graph.len());
    }

    #[test]
    fn a_hub_vertex_does_not_make_the_gathering_quadratic() {
        // A fan of 100 000 triangles around vertex 0: every vertex neighbours the hub, whose
        // ring is read up to RING_CAP entries only (uncapped this is ~10¹⁰ steps).
        let n = 100_001u32;
        let triangles: Vec<[u32; 3]> = (1..n - 1).map(|i| [0, i, i + 1]).collect();
        let graph = CausalGraph::mesh(n as usize, &triangles);
        let hoods = Neighbourhoods::new(&graph);
        assert_eq!(hoods.len(), n as usize);
        assert!((0..hoods.len()).all(|p| hoods.of(p).len() <= MAX_NEIGHBOURS));
        // The rim vertices still see the hub and their rim neighbours.
        assert!(hoods.of(hoods.len() - 1).len() >= 2);
    }

    #[test]
    fn regression_beats_the_neighbour_average_on_a_locally_affine_field() {
        let (graph, f) = setup();
        let hoods = Neighbourhoods::new(&graph);
        let regs: Vec<&[f64]> = vec![&f[0], &f[1]];
        let fit = Fit::new(&hoods, &regs);
        assert!(fit.usable_share() > 0.8, "{}", fit.usable_share());
        let reg = Regression { graph: &graph, fallback: Predictor::Average, hoods: &hoods, fit: &fit };
        let step = 0.01;
        let (mut c_reg, mut r_reg, mut c_avg, mut r_avg) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        reg.quantize(&f[2], step, &mut c_reg, &mut r_reg);
        predict::quantize(&graph, Predictor::Average, &f[2], step, 0.0, &mut c_avg, &mut r_avg);
        let mag = |c: &[i32]| c.iter().map(|&x| (x.unsigned_abs() as f64 + 1.0).log2()).sum::<f64>();
        assert!(mag(&c_reg) < 0.7 * mag(&c_avg), "regression {} vs average {}", mag(&c_reg), mag(&c_avg));
        // Closed loop: every entry within half a step.
        for p in 0..f[2].len() {
            assert!((r_reg[p] - f[2][p]).abs() <= 0.5 * step * (1.0 + 1e-9));
        }
    }

    #[test]
    fn decoder_rebuilds_the_encoders_reconstruction_exactly() {
        let (graph, f) = setup();
        let hoods = Neighbourhoods::new(&graph);
        for k in 1..=2 {
            let regs: Vec<&[f64]> = f[..k].iter().map(|v| v.as_slice()).collect();
            let fit = Fit::new(&hoods, &regs);
            let reg = Regression { graph: &graph, fallback: Predictor::Parallelogram, hoods: &hoods, fit: &fit };
            let (mut codes, mut recon, mut back) = (Vec::new(), Vec::new(), Vec::new());
            reg.quantize(&f[2], 0.003, &mut codes, &mut recon);
            reg.dequantize(&codes, 0.003, &mut back);
            assert_eq!(recon, back, "k = {k}");
        }
    }

    #[test]
    fn degenerate_regressors_fall_back_without_panics_or_nans() {
        let (graph, f) = setup();
        let hoods = Neighbourhoods::new(&graph);
        let n = graph.len();
        let constant = vec![1.0; n];
        let huge: Vec<f64> = (0..n).map(|p| if p % 2 == 0 { 1e300 } else { -1e300 }).collect();
        let nan: Vec<f64> = (0..n).map(|p| if p == 5 { f64::NAN } else { p as f64 }).collect();
        for regs in [vec![constant.as_slice()], vec![huge.as_slice(), f[0].as_slice()], vec![nan.as_slice()]] {
            let fit = Fit::new(&hoods, &regs);
            let reg = Regression { graph: &graph, fallback: Predictor::Average, hoods: &hoods, fit: &fit };
            let (mut codes, mut recon, mut back) = (Vec::new(), Vec::new(), Vec::new());
            reg.quantize(&f[2], 0.01, &mut codes, &mut recon);
            reg.dequantize(&codes, 0.01, &mut back);
            assert!(recon.iter().all(|x| x.is_finite()));
            assert_eq!(recon, back);
        }
        // Wrong regressor lengths: nothing usable, plain fallback.
        let short = vec![0.0; 3];
        let fit = Fit::new(&hoods, &[short.as_slice()]);
        assert_eq!(fit.usable_share(), 0.0);
    }

    /// The hosvd divergence (`../shared/probe-round3/hosvd-divergence/`) in miniature: decoded
    /// leads flat up to rounding (1e-18) over a patch, one lead one step off at a few
    /// positions, and a predicted column with a real spread. The unguarded fit's weights grow
    /// like step / 1e-18 and its closed loop clamps codes; the guarded fit stays at the
    /// neighbour average there, within half a step, and the decoder agrees bit for bit.
    #[test]
    fn guarded_fit_survives_leads_flat_up_to_rounding() {
        let (graph, _) = setup();
        let hoods = Neighbourhoods::new(&graph);
        let n = graph.len();
        let step = 6e-4;
        let lead: Vec<f64> =
            (0..n).map(|p| if p % 37 == 36 { 0.01 + step } else { 0.01 + 2e-18 * (p % 3) as f64 }).collect();
        let y: Vec<f64> = (0..n).map(|p| 1e-4 * ((p * 7919) % 13) as f64 / 13.0).collect();
        let regs = [lead.as_slice()];
        let unguarded = Fit::new(&hoods, &regs);
        let largest = unguarded.weights.iter().fold(0.0f64, |m, w| m.max(w.abs()));
        assert!(largest > 1e6, "the reproducer's mechanism: weights {largest}");
        let (mut codes, mut recon, mut back) = (Vec::new(), Vec::new(), Vec::new());
        let reg = Regression { graph: &graph, fallback: Predictor::Average, hoods: &hoods, fit: &unguarded };
        reg.quantize(&y, 1e-6, &mut codes, &mut recon);
        let worst = y.iter().zip(&recon).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(worst > 1e-6, "unguarded closed loop stays in bounds ({worst}): the test lost its point");

        let guarded = Fit::guarded(&hoods, &regs, &[step]);
        assert!(guarded.is_guarded());
        let largest = guarded.weights.iter().fold(0.0f64, |m, w| m.max(w.abs()));
        assert!(largest < 2.0, "guarded weights {largest}");
        let reg = Regression { graph: &graph, fallback: Predictor::Average, hoods: &hoods, fit: &guarded };
        reg.quantize(&y, 1e-6, &mut codes, &mut recon);
        for p in 0..n {
            assert!((recon[p] - y[p]).abs() <= 0.5e-6 * (1.0 + 1e-9), "position {p}");
        }
        reg.dequantize(&codes, 1e-6, &mut back);
        assert_eq!(recon, back);
    }

    #[test]
    fn guarded_fit_keeps_the_regression_gain_on_informative_leads() {
        let (graph, f) = setup();
        let hoods = Neighbourhoods::new(&graph);
        let regs: Vec<&[f64]> = vec![&f[0], &f[1]];
        // Lead steps far below the leads' spread (≈ 1 per ring): the ridge hardly matters.
        let fit = Fit::guarded(&hoods, &regs, &[0.01, 0.01]);
        let reg = Regression { graph: &graph, fallback: Predictor::Average, hoods: &hoods, fit: &fit };
        let (mut c_reg, mut r_reg, mut c_avg, mut r_avg) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        reg.quantize(&f[2], 0.01, &mut c_reg, &mut r_reg);
        predict::quantize(&graph, Predictor::Average, &f[2], 0.01, 0.0, &mut c_avg, &mut r_avg);
        let mag = |c: &[i32]| c.iter().map(|&x| (x.unsigned_abs() as f64 + 1.0).log2()).sum::<f64>();
        assert!(mag(&c_reg) < 0.7 * mag(&c_avg), "guarded {} vs average {}", mag(&c_reg), mag(&c_avg));
        // Wrong number of steps: nothing usable.
        assert_eq!(Fit::guarded(&hoods, &regs, &[0.01]).usable_share(), 0.0);
    }
}
