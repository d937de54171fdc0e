//! Stream version 2's coding of one cluster's dictionary and features with
//! `codec_core::toolkit`; the paper's uniform bit depths + zstd are in `paper.rs`.
//!
//! A block (of one cluster) is `X̂ = Ê F̂` (Eq. 4–5). Its components are the `k` dictionary
//! columns `E[:, j]` and the `k` feature rows `F[i, :]`. Each is a vector either over the
//! cluster's vertices or over the block's `3d` frame coordinates:
//! - temporal domain (`e = 3d`): dictionary columns are trajectories (time), feature rows are
//!   fields over the vertices (mesh);
//! - spatial domain (`e = n`): dictionary columns are fields over the vertices (mesh), feature
//!   rows are trajectories (time).
//!
//! Vertex fields are quantized in closed loop along the cluster's connectivity-driven order
//! ([`CausalGraph::mesh`] of the cluster's own triangles), each vertex predicted from its
//! reconstructed earlier neighbours (Coddyac's idea for PCA coefficients); trajectories are
//! quantized along time, per axis (`x`, `y`, `z` chains of `d` frames), predicted from the
//! previous frame(s). One step per component comes from the equal-slope rule
//! (`rdq::allocate`'s λ search, run by `equal_slope` over lazily evaluated grids) over a grid
//! of steps plus "dropped", with rates from the adaptive coder's
//! cost model and distortions in the block's units: a feature row's error reaches `X̂` through
//! an orthonormal column (gain 1), a dictionary column's error through its feature row (gain
//! `‖F[j, :]‖`). All codes go through one context-adaptive binary arithmetic coder: class =
//! (dictionary | features, component index), context = magnitude of the neighbours' codes.

use codec_core::toolkit::adaptive::{AdaptiveDecoder, AdaptiveEncoder, CostModel};
use codec_core::toolkit::order::CausalGraph;
use codec_core::toolkit::predict::{self, Predictor};
use codec_core::toolkit::rdq::{self, RdPoint};
use codec_core::{Error, Result};

use faer::{Mat, MatRef};
use rayon::prelude::*;

use crate::{linalg, NAME};

/// Adaptive-model classes per group (dictionary, features); later components share the last.
pub const CLASSES_PER_GROUP: usize = 32;
/// Classes of the arithmetic coder.
pub const CLASSES: usize = 2 * CLASSES_PER_GROUP;

/// Steps per octave and octaves below / above the reference step searched by the RD rule.
const PER_OCTAVE: usize = 2;
const OCTAVES_FINER: usize = 4;
const OCTAVES_COARSER: usize = 6;

/// How a vector's entries are ordered and predicted.
#[derive(Clone, Copy)]
pub enum Layout<'g> {
    /// One value per cluster vertex, along the cluster's mesh order (natural index = local
    /// vertex index).
    Mesh(&'g CausalGraph),
    /// `3d` frame coordinates (natural index `3t + a`), coded as three chains (`a = 0, 1, 2`)
    /// of `d` frames each.
    Time(&'g CausalGraph),
}

impl Layout<'_> {
    fn graph(&self) -> &CausalGraph {
        match self {
            Layout::Mesh(g) | Layout::Time(g) => g,
        }
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        match self {
            Layout::Mesh(g) => g.len(),
            Layout::Time(g) => 3 * g.len(),
        }
    }

    /// Natural index of coding position `p`.
    #[inline]
    fn natural(&self, p: usize) -> usize {
        match self {
            Layout::Mesh(g) => g.order()[p] as usize,
            Layout::Time(g) => {
                let d = g.len();
                3 * (p % d) + p / d
            }
        }
    }

    /// Chains of the layout (1 for a mesh, 3 for time).
    fn chains(&self) -> usize {
        match self {
            Layout::Mesh(_) => 1,
            Layout::Time(_) => 3,
        }
    }
}

/// Settings of the toolkit coding.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// Predictor of vertex fields along the mesh.
    pub mesh: Predictor,
    /// Predictor of trajectories along time.
    pub time: Predictor,
    /// Steps by the equal-slope rule (true) or one step per group from equal distortion per
    /// entry (false; for ablations).
    pub rdq: bool,
}

/// One vector to code.
struct Component<'g> {
    layout: Layout<'g>,
    predictor: Predictor,
    /// Values in coding order.
    values: Vec<f64>,
    gain2: f64,
    reference_step: f64,
}

impl Component<'_> {
    fn floor(&self) -> f64 {
        floor_of(&self.values)
    }

    fn evaluate(&self, step: f64, codes: &mut Vec<i32>, recon: &mut Vec<f64>) -> RdPoint {
        if step == 0.0 {
            let d: f64 = self.values.iter().map(|x| x * x).sum();
            return RdPoint { rate: 0.0, distortion: self.gain2 * d };
        }
        quantize(self.layout, self.predictor, &self.values, step, codes, recon);
        let mut cost = CostModel::new(1);
        let g = self.layout.graph();
        for chain in codes.chunks(g.len().max(1)) {
            for p in 0..chain.len() {
                cost.add(chain[p], 0, predict::neighbour_bucket(g, chain, p));
            }
        }
        let d: f64 = self.values.iter().zip(recon.iter()).map(|(x, r)| (x - r) * (x - r)).sum();
        RdPoint { rate: cost.bits(), distortion: self.gain2 * d }
    }
}

/// Closed-loop quantization of `values` (coding order) along `layout`.
fn quantize(
    layout: Layout<'_>,
    predictor: Predictor,
    values: &[f64],
    step: f64,
    codes: &mut Vec<i32>,
    recon: &mut Vec<f64>,
) {
    let g = layout.graph();
    if layout.chains() == 1 {
        predict::quantize(g, predictor, values, step, 0.0, codes, recon);
        return;
    }
    codes.clear();
    recon.clear();
    let (mut c, mut r) = (Vec::new(), Vec::new());
    for chain in values.chunks(g.len().max(1)) {
        predict::quantize(g, predictor, chain, step, 0.0, &mut c, &mut r);
        codes.extend_from_slice(&c);
        recon.extend_from_slice(&r);
    }
}

fn encode_codes(enc: &mut AdaptiveEncoder, layout: Layout<'_>, codes: &[i32], class: usize) {
    let g = layout.graph();
    for chain in codes.chunks(g.len().max(1)) {
        for p in 0..chain.len() {
            enc.encode(chain[p], class, predict::neighbour_bucket(g, chain, p));
        }
    }
}

/// The finest step used for `values`: 2^-28 of their range (codes stay far inside 2^30).
fn floor_of(values: &[f64]) -> f64 {
    rdq::step_floor(values.iter().fold(0.0f64, |m, x| m.max(x.abs())))
}

/// Grid steps searched per component (the grid runs from `reference_step · 2^OCTAVES_COARSER`
/// down to `reference_step · 2^-OCTAVES_FINER`).
const GRID: usize = (OCTAVES_COARSER + OCTAVES_FINER) * PER_OCTAVE + 1;

/// One component's RD points over "dropped" (index 0) and the step grid (indices `1..=GRID`,
/// coarse to fine), evaluated lazily: the equal-slope search visits only the grid points near
/// each component's choice (encode speed: evaluating every point cost more than the rest of the coding).
struct StepSearch<'c, 'g> {
    comp: &'c Component<'g>,
    floor: f64,
    largest: f64,
    points: Vec<Option<RdPoint>>,
    /// Finest index that can be chosen: a point whose distortion is below 1e-4 of the budget
    /// ends the search toward finer steps, and a component whose whole energy is below it is
    /// dropped without trying steps (at most `2k·1e-4` of the budget in all).
    limit: usize,
    negligible: f64,
    /// Current choice (warm start of the next walk).
    at: usize,
}

impl<'c, 'g> StepSearch<'c, 'g> {
    fn new(comp: &'c Component<'g>, target: f64) -> Self {
        Self {
            comp,
            floor: comp.floor(),
            largest: comp.reference_step * 2f64.powi(OCTAVES_COARSER as i32),
            points: vec![None; GRID + 1],
            limit: GRID,
            negligible: 1e-4 * target,
            // Start at the reference step (equal distortion per entry).
            at: OCTAVES_COARSER * PER_OCTAVE + 1,
        }
    }

    fn step(&self, i: usize) -> f64 {
        if i == 0 {
            0.0
        } else {
            rdq::stored_step(self.largest * (-((i - 1) as f64) / PER_OCTAVE as f64).exp2(), self.floor)
        }
    }

    fn point(&mut self, i: usize, codes: &mut Vec<i32>, recon: &mut Vec<f64>) -> RdPoint {
        if let Some(p) = self.points[i] {
            return p;
        }
        let p = self.comp.evaluate(self.step(i), codes, recon);
        self.points[i] = Some(p);
        if p.distortion < self.negligible {
            self.limit = self.limit.min(i);
        }
        p
    }

    /// Walks from the current choice to the local minimum of `D + λR` (the RD curves over the
    /// grid are near-convex, so the local minimum is the grid's minimum but for small bumps).
    /// Ties go to the smaller rate (the coarser step), like `rdq::allocate`.
    fn walk(&mut self, lambda: f64, codes: &mut Vec<i32>, recon: &mut Vec<f64>) -> RdPoint {
        let p0 = self.point(0, codes, recon);
        if p0.distortion < self.negligible {
            self.limit = 0;
        }
        self.at = self.at.min(self.limit);
        let cost = |p: RdPoint| p.distortion + lambda * p.rate;
        loop {
            let here = self.point(self.at, codes, recon);
            if self.at > 0 && cost(self.point(self.at - 1, codes, recon)) <= cost(here) {
                self.at -= 1;
            } else if self.at < self.limit && cost(self.point(self.at + 1, codes, recon)) < cost(here) {
                self.at += 1;
            } else {
                return here;
            }
        }
    }
}

/// The equal-slope rule (`rdq::allocate`'s: the largest slope λ whose choices meet `target`)
/// over lazily evaluated grids: λ is bracketed by factors of 4 from the high-rate estimate at
/// the reference steps, then bisected in log space; every component walks from its previous
/// choice. Returns the chosen grid index per component.
fn equal_slope(searches: &mut [StepSearch<'_, '_>], target: f64) -> Vec<usize> {
    // The components' walks are independent: done in parallel (each task with its own
    // scratch), distortions summed in component order, so the result does not depend on the
    // thread count.
    let at = |lambda: f64, searches: &mut [StepSearch<'_, '_>]| -> (f64, Vec<usize>) {
        let distortions: Vec<f64> = searches
            .par_iter_mut()
            .map_init(|| (Vec::new(), Vec::new()), |(codes, recon), s| s.walk(lambda, codes, recon).distortion)
            .collect();
        (distortions.iter().sum(), searches.iter().map(|s| s.at).collect())
    };
    // High-rate slope at the reference steps: D = n·g²Δ²/12 per component, dD/dR = −g²Δ²·ln2/6,
    // with n·g²Δ²/12 = target / (number of components).
    let n = searches.iter().map(|s| s.comp.values.len()).max().unwrap_or(1).max(1);
    let guess = (2.0 * std::f64::consts::LN_2 * target / (n * searches.len().max(1)) as f64).max(1e-300);
    let (d, c) = at(guess, searches);
    let (mut lo, mut hi, mut best);
    if d <= target {
        // Feasible: raise λ until it is not (or everything is dropped).
        lo = guess;
        best = c;
        hi = guess;
        loop {
            hi *= 4.0;
            let (d, c) = at(hi, searches);
            if d > target {
                break;
            }
            lo = hi;
            best = c;
            if best.iter().all(|&i| i == 0) || hi > 1e300 {
                return best;
            }
        }
    } else {
        lo = guess;
        loop {
            hi = lo;
            lo /= 4.0;
            let (d, c) = at(lo, searches);
            best = c;
            if d <= target {
                break;
            }
            if lo < 1e-300 {
                // The finest steps miss the target: least distortion, like `rdq::allocate`.
                return best;
            }
        }
    }
    // Bisection in log space: 40 halvings of a factor-4 bracket reach f64 resolution.
    for _ in 0..40 {
        let mid = (lo * hi).sqrt();
        if !(mid > lo && mid < hi) {
            break;
        }
        let (d, c) = at(mid, searches);
        if d <= target {
            lo = mid;
            best = c;
        } else {
            hi = mid;
        }
    }
    best
}

/// The coded block.
pub struct Coded {
    /// Dictionary steps then feature steps (`2k`; 0 = the vector is zero).
    pub steps: Vec<f32>,
    /// The kept components (indices into the input dictionary's columns).
    pub kept: Vec<usize>,
    /// Arithmetic-coded codes.
    pub bytes: Vec<u8>,
    /// `‖X − Ê F̂‖²_F` (before the means are added and the output is rounded to f32).
    pub error2: f64,
    /// `‖X‖²_F`.
    pub energy2: f64,
}

/// Codes a block: `e` is the orthonormal dictionary (`e × k`), `features` = `Eᵀ X` (`k × m`),
/// `x` the centered block (`e × m`) for the closed loop: the coded features are recomputed
/// from the dequantized dictionary. `target` is the total squared quantization error allowed.
pub fn code(
    e: MatRef<'_, f64>,
    features: MatRef<'_, f64>,
    x: MatRef<'_, f64>,
    dict_layout: Layout<'_>,
    feat_layout: Layout<'_>,
    settings: &Settings,
    target: f64,
) -> Coded {
    let (e_dim, k) = e.shape();
    let m_dim = x.ncols();
    let predictor = |l: &Layout<'_>| match l {
        Layout::Mesh(_) => settings.mesh,
        Layout::Time(_) => settings.time,
    };
    let mut comps = Vec::with_capacity(2 * k);
    // Equal distortion per entry, half of the budget per group: uniform noise Δ²/12 per entry.
    let dict_ref = (6.0 * target / (e_dim * k.max(1)) as f64).sqrt();
    let feat_ref = (6.0 * target / (m_dim * k.max(1)) as f64).sqrt();
    for j in 0..k {
        let gain2: f64 = (0..m_dim).map(|c| features[(j, c)].powi(2)).sum();
        comps.push(Component {
            layout: dict_layout,
            predictor: predictor(&dict_layout),
            values: (0..e_dim).map(|p| e[(dict_layout.natural(p), j)]).collect(),
            gain2,
            reference_step: dict_ref / gain2.sqrt().max(1e-300),
        });
    }
    for i in 0..k {
        comps.push(Component {
            layout: feat_layout,
            predictor: predictor(&feat_layout),
            values: (0..m_dim).map(|p| features[(i, feat_layout.natural(p))]).collect(),
            gain2: 1.0,
            reference_step: feat_ref,
        });
    }

    let (mut codes, mut recon) = (Vec::new(), Vec::new());
    let steps: Vec<f64> = if settings.rdq {
        let mut searches: Vec<StepSearch<'_, '_>> = comps.iter().map(|c| StepSearch::new(c, target)).collect();
        let choice = equal_slope(&mut searches, target);
        searches.iter().zip(choice).map(|(s, i)| s.step(i)).collect()
    } else {
        comps.iter().map(|c| rdq::stored_step(c.reference_step, c.floor())).collect()
    };
    // A component pair is kept only when both its column and its row are coded: either alone
    // contributes nothing to `Ê F̂`.
    let kept: Vec<usize> = (0..k).filter(|&j| steps[j] > 0.0 && steps[k + j] > 0.0).collect();
    let kk = kept.len();

    let mut enc = AdaptiveEncoder::new(CLASSES);
    // Dictionary, then the features `EᵀX` of the unquantized dictionary ("open loop"): the
    // error is then `R + ΔE·F + Ê·ΔF`, each column's error weighted by its own feature row,
    // which is what the RD rule assumed. Recomputing the features from `Ê` (`ÊᵀX`, version
    // 1's closed loop) would not be: `Ê` is not orthonormal, and a weak column's error
    // `δE_j` would pick up the strong components' energy through `δE_jᵀ X`.
    let mut e_hat = Mat::<f64>::zeros(e_dim, kk);
    for (slot, &j) in kept.iter().enumerate() {
        let c = &comps[j];
        quantize(c.layout, c.predictor, &c.values, steps[j], &mut codes, &mut recon);
        // The decoder knows the kept components by their slot, not their index in the input
        // dictionary: the class follows the slot (the kept set need not be a prefix).
        encode_codes(&mut enc, c.layout, &codes, slot.min(CLASSES_PER_GROUP - 1));
        for (p, &r) in recon.iter().enumerate() {
            e_hat[(dict_layout.natural(p), slot)] = r;
        }
    }
    let mut f_hat = Mat::<f64>::zeros(kk, m_dim);
    for (slot, &j) in kept.iter().enumerate() {
        let c = &comps[k + j];
        let step = steps[k + j];
        quantize(c.layout, c.predictor, &c.values, step, &mut codes, &mut recon);
        encode_codes(&mut enc, c.layout, &codes, CLASSES_PER_GROUP + slot.min(CLASSES_PER_GROUP - 1));
        for (p, &r) in recon.iter().enumerate() {
            f_hat[(slot, feat_layout.natural(p))] = r;
        }
    }
    // ‖X − Ê F̂‖² = ‖X‖² − 2⟨ÊᵀX, F̂⟩ + ⟨F̂, (ÊᵀÊ) F̂⟩, without forming Ê F̂.
    let f = linalg::mul(e_hat.transpose(), x);
    let gram = linalg::mul(e_hat.transpose(), e_hat.as_ref());
    let gf = linalg::mul(gram.as_ref(), f_hat.as_ref());
    let mut x2 = 0.0;
    for c in 0..m_dim {
        for r in 0..e_dim {
            x2 += x[(r, c)] * x[(r, c)];
        }
    }
    let (mut cross, mut quad) = (0.0, 0.0);
    for c in 0..m_dim {
        for r in 0..kk {
            cross += f[(r, c)] * f_hat[(r, c)];
            quad += gf[(r, c)] * f_hat[(r, c)];
        }
    }
    let mut out_steps: Vec<f32> = kept.iter().map(|&j| steps[j] as f32).collect();
    out_steps.extend(kept.iter().map(|&j| steps[k + j] as f32));
    Coded { steps: out_steps, kept, bytes: enc.finish(), error2: (x2 - 2.0 * cross + quad).max(0.0), energy2: x2 }
}

/// The decoder's side of [`code`]: `(Ê, F̂)` (column-major `e × k`, row-major `k × m`) from the
/// `2k` steps (checked finite and non-negative by the caller) and the arithmetic-coded bytes.
pub fn decode(
    bytes: &[u8],
    steps: &[f32],
    dict_layout: Layout<'_>,
    feat_layout: Layout<'_>,
    settings: &Settings,
) -> Result<(Mat<f64>, Mat<f64>)> {
    let k = steps.len() / 2;
    let (e_dim, m_dim) = (dict_layout.len(), feat_layout.len());
    let mut dec = AdaptiveDecoder::new(bytes, CLASSES, NAME, "cluster.codes")?;
    let mut codes = Vec::new();
    let mut recon = Vec::new();
    let predictor = |l: &Layout<'_>| match l {
        Layout::Mesh(_) => settings.mesh,
        Layout::Time(_) => settings.time,
    };
    let mut e_hat = Mat::<f64>::zeros(e_dim, k);
    for j in 0..k {
        let class = j.min(CLASSES_PER_GROUP - 1);
        component(&mut dec, &mut codes, &mut recon, dict_layout, predictor(&dict_layout), class, steps[j])?;
        for (p, &r) in recon.iter().enumerate() {
            e_hat[(dict_layout.natural(p), j)] = r;
        }
    }
    let mut f_hat = Mat::<f64>::zeros(k, m_dim);
    for i in 0..k {
        let class = CLASSES_PER_GROUP + i.min(CLASSES_PER_GROUP - 1);
        component(&mut dec, &mut codes, &mut recon, feat_layout, predictor(&feat_layout), class, steps[k + i])?;
        for (p, &r) in recon.iter().enumerate() {
            f_hat[(i, feat_layout.natural(p))] = r;
        }
    }
    // Every coded word was read (a header claiming fewer vertices than were coded is
    // an error, as is one claiming more: the decoder then runs past its data).
    dec.finish()?;
    Ok((e_hat, f_hat))
}

/// Decodes one component's codes and reconstructs it (coding order) into `recon`.
fn component(
    dec: &mut AdaptiveDecoder,
    codes: &mut Vec<i32>,
    recon: &mut Vec<f64>,
    layout: Layout<'_>,
    predictor: Predictor,
    class: usize,
    step: f32,
) -> Result<()> {
    recon.clear();
    if step == 0.0 {
        recon.resize(layout.len(), 0.0);
        return Ok(());
    }
    let g = layout.graph();
    let mut chain_codes = vec![0i32; g.len()];
    let mut chain_recon = Vec::new();
    codes.clear();
    for _ in 0..layout.chains() {
        for p in 0..g.len() {
            let bucket = predict::neighbour_bucket(g, &chain_codes, p);
            chain_codes[p] = dec.decode(class, bucket)?;
        }
        predict::dequantize(g, predictor, &chain_codes, step as f64, &mut chain_recon);
        recon.extend_from_slice(&chain_recon);
        codes.extend_from_slice(&chain_codes);
    }
    if recon.iter().any(|x| !x.is_finite()) {
        return Err(Error::malformed(NAME, "cluster.codes", "a decoded value is not finite"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A kept set that is not a prefix (a middle component dropped) must decode to what the
    /// encoder measured: the coder class follows the kept slot on both sides. More components
    /// than classes, so the last ones share an adapted class (a class taken from the input index
    /// instead of the slot then decodes garbage).
    #[test]
    fn a_dropped_middle_component_still_decodes_to_the_encoders_reconstruction() {
        let (d1, d2, k) = (24, 10, CLASSES_PER_GROUP + 2);
        let (e_dim, m_dim) = (3 * d1, 3 * d2);
        // Orthonormal dictionary: unit coordinate columns.
        let e = Mat::<f64>::from_fn(e_dim, k, |r, c| if r == 2 * c + 1 { 1.0 } else { 0.0 });
        // Component 1 carries no energy: dropped, while components 0 and 2 are kept.
        let scale: Vec<f64> = (0..k).map(|j| if j == 1 { 0.0 } else { 5.0 / (1.0 + j as f64) }).collect();
        let features = Mat::<f64>::from_fn(k, m_dim, |r, c| scale[r] * ((c * (r + 2)) as f64 * 0.37).sin());
        let x = linalg::mul(e.as_ref(), features.as_ref());
        let dict_graph = CausalGraph::chain(d1, false);
        let feat_graph = CausalGraph::chain(d2, false);
        let settings = Settings { mesh: Predictor::Average, time: Predictor::Previous, rdq: true };
        let (dl, fl) = (Layout::Time(&dict_graph), Layout::Time(&feat_graph));
        let energy: f64 = (0..m_dim).map(|c| (0..e_dim).map(|r| x[(r, c)].powi(2)).sum::<f64>()).sum();
        let coded = code(e.as_ref(), features.as_ref(), x.as_ref(), dl, fl, &settings, 1e-6 * energy);
        assert_eq!(coded.kept.len(), k - 1);
        assert!(!coded.kept.contains(&1));
        let (e_hat, f_hat) = decode(&coded.bytes, &coded.steps, dl, fl, &settings).expect("decodes");
        let y = linalg::mul(e_hat.as_ref(), f_hat.as_ref());
        let err: f64 = (0..m_dim).map(|c| (0..e_dim).map(|r| (x[(r, c)] - y[(r, c)]).powi(2)).sum::<f64>()).sum();
        assert!((err - coded.error2).abs() <= 1e-9 * energy, "decoded error {err}, encoder's {}", coded.error2);
        assert!(err <= 1.05e-6 * energy, "error {err} over the budget");
    }
}
