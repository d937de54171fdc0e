//! Stream version 3's toolkit coding of a segment: the PCA of every group (§4.4,
//! Eq. 5: `X ≈ mean + A·B`) coded with `codec_core::toolkit` instead of the paper's uniform
//! bit depths + zstd (which stays available, `coding=paper`).
//!
//! Components of one segment, every group together:
//! - the mean (per [`Centering`]): per axis a trajectory over the frames, predicted in time
//!   (`frame`, `frame-axis`), or per axis a field over the group's vertices, predicted along
//!   the group's mesh order (`vertex`);
//! - every coefficient row `B_j` (a trajectory over the frames), predicted in time;
//! - every basis column `A_j` (three fields over the group's vertices, one per axis), predicted
//!   along the group's connectivity-driven order ([`CausalGraph::mesh`] of the triangles whose
//!   corners all lie in the group).
//!
//! Each component has its own step, chosen by the equal-slope rule ([`rdq::allocate`]) over
//! measured operating points for a total quantization distortion `D = quant² · E_trunc` (the
//! truncation energy the PCA left, floored at `10⁻⁴·(1 − ω)·E`). Distortion of a component =
//! its gain × its squared error: a mean value of a `frame-axis` group is added to all `n` of
//! its vertices (gain `n`), a `B_j` error reaches the output through `A_j` (gain `‖A_j‖²`),
//! an `A_j` error through `B̂_j` (gain `‖B̂_j‖²`). As in the paper coding the coefficients are
//! quantized first and the basis is fitted to them by least squares; the `A` steps of the joint
//! allocation are kept if the fitted basis meets what the mean and `B` left of `D`, otherwise
//! they are allocated again for it. All codes (group labels
//! first, predicted from the breadth-first parent) go through one context-adaptive arithmetic
//! coder; the class is the component kind and index, the bucket the magnitude of already coded
//! neighbours' codes.

use codec_core::bytes::{ByteReader, ByteWriter};
use codec_core::toolkit::adaptive::{AdaptiveDecoder, AdaptiveEncoder, CostModel};
use codec_core::toolkit::order::{self, CausalGraph};
use codec_core::toolkit::predict::{self, Predictor};
use codec_core::toolkit::rdq::{self, RdPoint};
use codec_core::{entropy, Error, Limits, Result};
use faer::Mat;
use rayon::prelude::*;

use crate::linalg::{mul, sym_eig_desc};
use crate::mesh::MeshGraph;
use crate::params::{Centering, StsegParams, MAX_SEGMENT_FRAMES};
use crate::pca::{centred_block, group_pca_energy, mean_layout, reconstruct_group};
use crate::segment::Segment;
use crate::NAME;

const CLASS_LABEL: usize = 0;
const CLASS_MEAN: usize = 1;
const PER_KIND: usize = 16;
const CLASS_B: usize = CLASS_MEAN + 3;
const CLASS_A: usize = CLASS_B + PER_KIND;
/// Adaptive-model classes: labels, 3 mean axes, 16 coefficient rows, 16 basis columns (later
/// rows / columns share the last class).
pub(crate) const CLASSES: usize = CLASS_A + PER_KIND;

/// Steps per octave, octaves above the rule-of-thumb step and most octaves below it searched
/// by the RD rule (the search stops once a component's distortion is negligible).
const PER_OCTAVE: usize = 2;
const OCTAVES_COARSER: usize = 3;
const OCTAVES_FINER: usize = 24;

/// Predictors of the toolkit coding (stream config).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Predictors {
    pub mesh: Predictor,
    pub time: Predictor,
}

/// Coding orders of the mesh and of the vertex groups of the last segment, built on demand
/// after their sizes passed the limits, and kept while the labels do not change.
pub(crate) struct Graphs {
    vertex_count: usize,
    triangles: Vec<[u32; 3]>,
    full: Option<CausalGraph>,
    labels: Vec<u8>,
    groups: Vec<CausalGraph>,
}

impl Graphs {
    pub fn new(vertex_count: usize, triangles: &[[u32; 3]]) -> Self {
        Self { vertex_count, triangles: triangles.to_vec(), full: None, labels: Vec::new(), groups: Vec::new() }
    }

    /// The whole mesh's order (labels are coded along it).
    fn full(&mut self, limits: &Limits) -> Result<&CausalGraph> {
        if self.full.is_none() {
            limits.check_alloc(
                NAME,
                "mesh coding order",
                order::mesh_bytes(self.vertex_count, self.triangles.len()),
            )?;
            self.full = Some(CausalGraph::mesh(self.vertex_count, &self.triangles));
        }
        Ok(self.full.as_ref().expect("built above"))
    }

    /// One order per group (`labels` < `group_count`, checked by the caller): the group's
    /// vertices ascending are its local items, its triangles those with all corners inside.
    fn groups(&mut self, labels: &[u8], group_count: usize, limits: &Limits) -> Result<&[CausalGraph]> {
        if self.groups.len() == group_count && self.labels == labels {
            return Ok(&self.groups);
        }
        let mut local = vec![0u32; labels.len()];
        let mut counts = vec![0usize; group_count];
        for (i, &l) in labels.iter().enumerate() {
            local[i] = counts[l as usize] as u32;
            counts[l as usize] += 1;
        }
        let mut tris: Vec<Vec<[u32; 3]>> = vec![Vec::new(); group_count];
        for t in &self.triangles {
            if t.iter().any(|&i| i as usize >= labels.len()) {
                continue;
            }
            let l = labels[t[0] as usize];
            if labels[t[1] as usize] == l && labels[t[2] as usize] == l {
                tris[l as usize].push([local[t[0] as usize], local[t[1] as usize], local[t[2] as usize]]);
            }
        }
        let bytes: u64 = (0..group_count).map(|g| order::mesh_bytes(counts[g], tris[g].len())).sum();
        limits.check_alloc(NAME, "group coding orders", bytes)?;
        self.groups = (0..group_count).map(|g| CausalGraph::mesh(counts[g], &tris[g])).collect();
        self.labels = labels.to_vec();
        Ok(&self.groups)
    }
}

/// One quantized component: one or three fields (position order of `graph`) sharing a step.
struct Component<'g> {
    class: usize,
    graph: &'g CausalGraph,
    predictor: Predictor,
    fields: Vec<Vec<f64>>,
    gain2: f64,
    reference_step: f64,
    /// Noise shaping α along `graph` (encoder only; basis columns).
    shaping: f64,
}

impl Component<'_> {
    fn max_abs(&self) -> f64 {
        self.fields.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()))
    }

    fn energy(&self) -> f64 {
        self.fields.iter().flatten().map(|x| x * x).sum()
    }

    /// Rate (bits, the adaptive coder's cost model) and distortion at `step` (0 = dropped).
    fn evaluate(&self, step: f64, codes: &mut Vec<i32>, recon: &mut Vec<f64>) -> RdPoint {
        if step == 0.0 {
            return RdPoint { rate: 0.0, distortion: self.gain2 * self.energy() };
        }
        let mut cost = CostModel::new(1);
        let mut err2 = 0.0;
        for field in &self.fields {
            predict::quantize(self.graph, self.predictor, field, step, self.shaping, codes, recon);
            for p in 0..codes.len() {
                cost.add(codes[p], 0, predict::neighbour_bucket(self.graph, codes, p));
            }
            err2 += field.iter().zip(recon.iter()).map(|(x, r)| (x - r) * (x - r)).sum::<f64>();
        }
        RdPoint { rate: cost.bits(), distortion: self.gain2 * err2 }
    }
}

/// Equal-slope steps of `comps` for a total distortion `target`; returns the steps and the
/// distortion each leaves.
fn allocate(comps: &[Component<'_>], target: f64) -> (Vec<f64>, Vec<f64>) {
    let evaluated: Vec<(Vec<f64>, Vec<RdPoint>)> = comps
        .par_iter()
        .map(|c| {
            let (mut codes, mut recon) = (Vec::new(), Vec::new());
            let floor = rdq::step_floor(c.max_abs());
            let largest = c.reference_step * 2f64.powi(OCTAVES_COARSER as i32);
            let mut grid = vec![0.0];
            let mut pts = vec![c.evaluate(0.0, &mut codes, &mut recon)];
            if pts[0].distortion > 0.0 {
                for s in rdq::step_grid(largest, (OCTAVES_COARSER + OCTAVES_FINER) * PER_OCTAVE + 1, PER_OCTAVE) {
                    let s = rdq::stored_step(s, floor);
                    let p = c.evaluate(s, &mut codes, &mut recon);
                    grid.push(s);
                    pts.push(p);
                    // Stop once this component's error is a negligible share of the budget:
                    // divided by the component count so that the finest points of all
                    // components together stay below the target (else the allocation's
                    // premise Σd ≤ D, which the error bound rests on, could fail).
                    if p.distortion < 1e-3 * target / comps.len() as f64 {
                        break;
                    }
                }
            }
            (grid, pts)
        })
        .collect();
    let points: Vec<Vec<RdPoint>> = evaluated.iter().map(|(_, p)| p.clone()).collect();
    let a = rdq::allocate(&points, target);
    let steps = a.choice.iter().zip(&evaluated).map(|(&i, (g, _))| g[i]).collect();
    let dist = a.choice.iter().zip(&points).map(|(&i, p)| p[i].distortion).collect();
    (steps, dist)
}

/// Codes `comp` at `step` into `enc`; returns the reconstructed fields.
fn code_component(comp: &Component<'_>, step: f64, enc: &mut AdaptiveEncoder) -> Vec<Vec<f64>> {
    let (mut codes, mut recon) = (Vec::new(), Vec::new());
    comp.fields
        .iter()
        .map(|field| {
            if step == 0.0 {
                return vec![0.0; field.len()];
            }
            predict::quantize(comp.graph, comp.predictor, field, step, comp.shaping, &mut codes, &mut recon);
            for p in 0..codes.len() {
                enc.encode(codes[p], comp.class, predict::neighbour_bucket(comp.graph, &codes, p));
            }
            recon.clone()
        })
        .collect()
}

/// Encoder-side model of one group: the PCA and the true mean.
struct GroupModel {
    own: Vec<u32>,
    k: usize,
    /// Mean per centering: vertex `[c][i]`, frame `[0][t]`, frame-axis `[c][t]`, none: empty.
    mean: Vec<Vec<f64>>,
    /// `B_j(t)` (orthonormal rows).
    b: Vec<Vec<f64>>,
    /// `‖A_j‖²` of the unquantized basis `A = (X − mean)·Bᵀ` (own rows).
    a_norm2: Vec<f64>,
    /// Unquantized basis `A_j`, per axis over the group's vertices in ascending order.
    a: Vec<[Vec<f64>; 3]>,
    /// Quantization budget share: `max(E_trunc, 10⁻⁴·(1 − ω)·E)` of the η-extended block.
    budget: f64,
}

/// A centred entry `(row, frame)` of a group's own rows.
type Centred<'a> = dyn Fn(usize, usize) -> f64 + Sync + 'a;

fn group_model(p: &StsegParams, graph: &MeshGraph, own: &[u32], block: &[f32], frames: usize) -> Result<GroupModel> {
    let n3 = graph.vertex_count() * 3;
    let n = own.len();
    let (k, vecs, trunc, total) = group_pca_energy(p, graph, own, block, frames)?;
    let ext = graph.grow_rings(own, p.eta as usize);
    let x_at = |r: usize, t: usize| block[t * n3 + own[r / 3] as usize * 3 + r % 3] as f64;
    let (mean, centred): (Vec<Vec<f64>>, Box<Centred<'_>>) = match p.centering {
        Centering::Vertex => {
            let (_, m) = centred_block(Centering::Vertex, own, block, n3, frames);
            let per_axis = (0..3).map(|c| (0..n).map(|i| m[i * 3 + c]).collect()).collect();
            (per_axis, Box::new(move |r, t| x_at(r, t) - m[r]))
        }
        Centering::Frame => {
            let (_, m) = centred_block(Centering::Frame, &ext, block, n3, frames);
            (vec![m.clone()], Box::new(move |r, t| x_at(r, t) - m[t]))
        }
        Centering::FrameAxis => {
            let (_, m) = centred_block(Centering::FrameAxis, &ext, block, n3, frames);
            let per_axis = (0..3).map(|c| (0..frames).map(|t| m[t * 3 + c]).collect()).collect();
            (per_axis, Box::new(move |r, t| x_at(r, t) - m[t * 3 + r % 3]))
        }
        Centering::None => (Vec::new(), Box::new(x_at)),
    };
    let b: Vec<Vec<f64>> = (0..k).map(|j| (0..frames).map(|t| vecs[(t, j)]).collect()).collect();
    let mut a = Vec::with_capacity(k);
    let mut a_norm2 = Vec::with_capacity(k);
    for bj in &b {
        let col: [Vec<f64>; 3] =
            std::array::from_fn(|c| (0..n).map(|i| (0..frames).map(|t| centred(i * 3 + c, t) * bj[t]).sum()).collect());
        a_norm2.push(col.iter().flatten().map(|x| x * x).sum());
        a.push(col);
    }
    let budget = trunc.max((1.0 - p.omega) * total * 1e-4);
    Ok(GroupModel { own: own.to_vec(), k, mean, b, a_norm2, a, budget })
}

/// `values` (ascending vertex order of a group) in `graph`'s position order.
fn in_order(graph: &CausalGraph, values: &[f64]) -> Vec<f64> {
    graph.order().iter().map(|&x| values[x as usize]).collect()
}

/// `recon` (position order) back to ascending vertex order.
fn from_order(graph: &CausalGraph, recon: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; recon.len()];
    for (p, &x) in graph.order().iter().enumerate() {
        out[x as usize] = recon[p];
    }
    out
}

/// Mean components of a group (classes `CLASS_MEAN + axis`).
fn mean_components<'g>(
    centering: Centering,
    mean: &[Vec<f64>],
    n: usize,
    frames: usize,
    group: &'g CausalGraph,
    time: &'g CausalGraph,
    pr: Predictors,
) -> Vec<Component<'g>> {
    mean.iter()
        .enumerate()
        .map(|(c, m)| {
            let (graph, predictor, field, gain2) = match centering {
                Centering::Vertex => (group, pr.mesh, in_order(group, m), frames as f64),
                Centering::Frame => (time, pr.time, m.clone(), 3.0 * n as f64),
                _ => (time, pr.time, m.clone(), n as f64),
            };
            Component {
                class: CLASS_MEAN + c,
                graph,
                predictor,
                fields: vec![field],
                gain2,
                reference_step: 0.0,
                shaping: 0.0,
            }
        })
        .collect()
}

/// Sets each component's rule-of-thumb step (equal distortion per entry, uniform noise
/// `Δ²/12`): the centre of the RD search grid.
fn set_reference_steps(comps: &mut [Component<'_>], target: f64) {
    let count = comps.len().max(1) as f64;
    for c in comps {
        let entries = c.fields.iter().map(Vec::len).sum::<usize>().max(1) as f64;
        c.reference_step = (12.0 * target / (count * entries * c.gain2.max(1e-300))).sqrt();
    }
}

/// What a segment's kind of component is: a mean axis, a coefficient row `B` or a basis
/// column `A` (pass 1's unquantized one).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Part {
    Mean,
    B,
    A,
}

/// Pass 1's components of every group in stream order (mean, `B` rows, unquantized `A`
/// columns), each with its group, [`Part`] and index.
fn pass1_components<'g>(
    p: &StsegParams,
    models: &[GroupModel],
    group_graphs: &'g [CausalGraph],
    time: &'g CausalGraph,
    pr: Predictors,
    frames: usize,
) -> (Vec<Component<'g>>, Vec<(usize, Part, usize)>) {
    let mut comps = Vec::new();
    let mut kinds = Vec::new();
    for (g, m) in models.iter().enumerate() {
        let gg = &group_graphs[g];
        for (c, comp) in
            mean_components(p.centering, &m.mean, m.own.len(), frames, gg, time, pr).into_iter().enumerate()
        {
            comps.push(comp);
            kinds.push((g, Part::Mean, c));
        }
        for j in 0..m.k {
            comps.push(Component {
                class: CLASS_B + j.min(PER_KIND - 1),
                graph: time,
                predictor: pr.time,
                fields: vec![m.b[j].clone()],
                gain2: m.a_norm2[j],
                reference_step: 0.0,
                shaping: 0.0,
            });
            kinds.push((g, Part::B, j));
        }
        for j in 0..m.k {
            comps.push(Component {
                class: CLASS_A + j.min(PER_KIND - 1),
                graph: gg,
                predictor: pr.mesh,
                fields: m.a[j].iter().map(|f| in_order(gg, f)).collect(),
                gain2: 1.0,
                reference_step: 0.0,
                shaping: p.shaping,
            });
            kinds.push((g, Part::A, j));
        }
    }
    (comps, kinds)
}

/// The packet payload of a segment: case, group count, ranks, the zstd-compressed steps, then
/// the arithmetic-coded labels and, per group, mean and `B` at pass 1's steps and the fitted
/// `A` at pass 2's.
fn write_segment(
    seg: &Segment,
    full: &CausalGraph,
    models: &[GroupModel],
    (comps, steps1): (&[Component<'_>], &[f64]),
    (comps2, steps2): (&[Component<'_>], &[f64]),
    level: i32,
) -> Vec<u8> {
    let mut enc = AdaptiveEncoder::new(CLASSES);
    if seg.group_count > 1 {
        let codes = label_codes(full, &seg.labels);
        for p in 0..codes.len() {
            enc.encode(codes[p], CLASS_LABEL, predict::neighbour_bucket(full, &codes, p));
        }
    }
    let mut side = ByteWriter::new();
    let mut a_at = 0;
    let mut idx = 0;
    for m in models {
        for _ in 0..m.mean.len() + m.k {
            let (comp, s) = (&comps[idx], steps1[idx]);
            code_component(comp, s, &mut enc);
            side.f32(s as f32);
            idx += 1;
        }
        idx += m.k; // pass-1 basis components
        for _ in 0..m.k {
            code_component(&comps2[a_at], steps2[a_at], &mut enc);
            side.f32(steps2[a_at] as f32);
            a_at += 1;
        }
    }
    let mut w = ByteWriter::new();
    w.u8(seg.kind.case());
    w.varint(seg.group_count as u64);
    for m in models {
        w.varint(m.k as u64);
    }
    w.length_prefixed(&entropy::compress(side.as_slice(), level));
    w.bytes(&enc.finish());
    w.into_vec()
}

/// Toolkit-coded packet payload of one segment (layout in README "Stream version 3").
pub(crate) fn encode_segment(
    p: &StsegParams,
    graph: &MeshGraph,
    graphs: &mut Graphs,
    seg: &Segment,
    block: &[f32],
) -> Result<Vec<u8>> {
    let v = graph.vertex_count();
    let n3 = v * 3;
    let frames = seg.frame_count;
    let pr = Predictors { mesh: p.mesh_predictor, time: p.time_predictor };
    let owns: Vec<Vec<u32>> = (0..seg.group_count)
        .map(|g| (0..v as u32).filter(|&i| seg.labels[i as usize] as usize == g).collect())
        .collect();
    let models: Vec<GroupModel> =
        owns.par_iter().map(|own| group_model(p, graph, own, block, frames)).collect::<Result<_>>()?;
    let limits = Limits::default();
    graphs.full(&limits)?;
    graphs.groups(&seg.labels, seg.group_count, &limits)?;
    let full = graphs.full.as_ref().expect("built above");
    let group_graphs = &graphs.groups;
    let time = CausalGraph::chain(frames, pr.time == Predictor::Parallelogram);
    let target = p.quant * p.quant * models.iter().map(|m| m.budget).sum::<f64>();

    // Pass 1: mean, coefficient rows and the unquantized basis together; the mean and B steps
    // are kept.
    let (mut comps, kinds) = pass1_components(p, &models, group_graphs, &time, pr, frames);
    set_reference_steps(&mut comps, target);
    // 3% of the budget held back so the fitted basis usually meets it at its pass-1 steps.
    let (steps1, dist1) = allocate(&comps, 0.97 * target);

    // Quantize means and B with their steps (the decoder's values), in stream order later;
    // here only their reconstructions are needed for the basis fit.
    let mut scratch = AdaptiveEncoder::new(CLASSES);
    let mut mean_hat: Vec<Vec<Vec<f64>>> = models.iter().map(|m| vec![Vec::new(); m.mean.len()]).collect();
    let mut b_hat: Vec<Vec<Vec<f64>>> = models.iter().map(|m| vec![Vec::new(); m.k]).collect();
    let mut used = 0.0;
    for ((comp, &(g, kind, i)), (&s, &d)) in comps.iter().zip(&kinds).zip(steps1.iter().zip(&dist1)) {
        match kind {
            Part::Mean => {
                let r = code_component(comp, s, &mut scratch).remove(0);
                mean_hat[g][i] = if p.centering == Centering::Vertex { from_order(&group_graphs[g], &r) } else { r };
                used += d;
            }
            Part::B => {
                b_hat[g][i] = code_component(comp, s, &mut scratch).remove(0);
                used += d;
            }
            Part::A => {}
        }
    }
    drop(scratch);

    // Basis fitted to the quantized mean and coefficients by least squares (own rows),
    // A = (X − m̂)·B̂ᵀ·(B̂·B̂ᵀ)⁺, then pass 2: its steps for what is left of the budget.
    let fitted: Vec<Vec<[Vec<f64>; 3]>> = models
        .par_iter()
        .zip(&mean_hat)
        .zip(&b_hat)
        .map(|((m, mh), bh)| fit_basis(p.centering, &m.own, block, n3, frames, mh, bh))
        .collect::<Result<_>>()?;
    let mut comps2 = Vec::new();
    for (g, m) in models.iter().enumerate() {
        let gg = &group_graphs[g];
        for j in 0..m.k {
            comps2.push(Component {
                class: CLASS_A + j.min(PER_KIND - 1),
                graph: gg,
                predictor: pr.mesh,
                fields: fitted[g][j].iter().map(|f| in_order(gg, f)).collect(),
                gain2: b_hat[g][j].iter().map(|x| x * x).sum(),
                reference_step: 0.0,
                shaping: p.shaping,
            });
        }
    }
    // The fitted basis is close to the unquantized one: its pass-1 steps are kept when they
    // still meet the budget (measured), otherwise its steps are allocated again.
    let target2 = (target - used).max(0.0);
    let pass1_a: Vec<f64> =
        kinds.iter().zip(&steps1).filter(|((_, kind, _), _)| *kind == Part::A).map(|(_, &s)| s).collect();
    let (mut codes, mut recon) = (Vec::new(), Vec::new());
    let kept: f64 = comps2.iter().zip(&pass1_a).map(|(c, &s)| c.evaluate(s, &mut codes, &mut recon).distortion).sum();
    let steps2 = if kept <= target2 || comps2.is_empty() {
        pass1_a
    } else {
        set_reference_steps(&mut comps2, target2.max(1e-300));
        allocate(&comps2, target2).0
    };

    // Stream: labels, then per group mean, B, A.
    Ok(write_segment(seg, full, &models, (&comps, &steps1), (&comps2, &steps2), p.level))
}

/// Label residuals along the mesh order: label minus the breadth-first parent's label.
fn label_codes(full: &CausalGraph, labels: &[u8]) -> Vec<i32> {
    let order = full.order();
    (0..order.len())
        .map(|p| {
            let pred = full.earlier(p).first().map_or(0, |&q| labels[order[q as usize] as usize] as i32);
            labels[order[p] as usize] as i32 - pred
        })
        .collect()
}

/// Least-squares basis for the quantized mean and coefficients (own rows), per column and axis.
fn fit_basis(
    centering: Centering,
    own: &[u32],
    block: &[f32],
    n3: usize,
    frames: usize,
    mean_hat: &[Vec<f64>],
    b_hat: &[Vec<f64>],
) -> Result<Vec<[Vec<f64>; 3]>> {
    let k = b_hat.len();
    let n = own.len();
    if k == 0 {
        return Ok(Vec::new());
    }
    let x_at = |r: usize, t: usize| block[t * n3 + own[r / 3] as usize * 3 + r % 3] as f64;
    let centred = |r: usize, t: usize| -> f64 {
        x_at(r, t)
            - match centering {
                Centering::Vertex => mean_hat[r % 3][r / 3],
                Centering::Frame => mean_hat[0][t],
                Centering::FrameAxis => mean_hat[r % 3][t],
                Centering::None => 0.0,
            }
    };
    let bh = Mat::from_fn(k, frames, |j, t| b_hat[j][t]);
    let xo = Mat::from_fn(n * 3, frames, centred);
    let m = mul(bh.as_ref(), bh.transpose());
    let (mv, mu) = sym_eig_desc(m.as_ref(), "coefficient Gram")?;
    let inv = Mat::from_fn(k, k, |i, j| {
        (0..k).filter(|&l| mv[l] > 1e-12 * mv[0]).map(|l| mu[(i, l)] * mu[(j, l)] / mv[l]).sum::<f64>()
    });
    let a = mul(mul(xo.as_ref(), bh.transpose()).as_ref(), inv.as_ref());
    Ok((0..k).map(|j| std::array::from_fn(|c| (0..n).map(|i| a[(i * 3 + c, j)]).collect())).collect())
}

/// Decodes one component's fields (position order) at `step`.
fn decode_component(
    dec: &mut AdaptiveDecoder,
    graph: &CausalGraph,
    predictor: Predictor,
    class: usize,
    step: f32,
    fields: usize,
) -> Result<Vec<Vec<f64>>> {
    let n = graph.len();
    let mut codes = vec![0i32; n];
    let mut out = Vec::with_capacity(fields);
    for _ in 0..fields {
        let mut recon = Vec::new();
        if step == 0.0 {
            recon.resize(n, 0.0);
        } else {
            for p in 0..n {
                let bucket = predict::neighbour_bucket(graph, &codes, p);
                codes[p] = dec.decode(class, bucket)?;
            }
            predict::dequantize(graph, predictor, &codes, step as f64, &mut recon);
            if recon.iter().any(|x| !x.is_finite()) {
                return Err(Error::malformed(NAME, "codes", "a decoded value is not finite"));
            }
        }
        out.push(recon);
    }
    Ok(out)
}

/// Work of one group's reconstruction ([`crate::pca::reconstruct_group`]: `frames·3·n·k`
/// multiply-adds) and its `frames·3·n` output coordinates (`Limits::max_work`).
pub(crate) fn reconstruction_work(frames: usize, n: usize, k: usize) -> u64 {
    let coords = Limits::product(&[frames as u64, 3, n as u64]);
    coords.saturating_mul(k as u64).saturating_add(coords.saturating_mul(codec_core::limits::WORK_PER_COORDINATE))
}

/// Reads a toolkit packet's per-group component counts (each at most `min(frames, 3·v)`) and
/// the quantization steps of every coded field (the means', then each component's `b` and `a`),
/// each finite and non-negative.
fn read_ranks_and_steps(
    r: &mut ByteReader<'_>,
    frames: usize,
    v: usize,
    centering: Centering,
    group_count: usize,
) -> Result<(Vec<usize>, Vec<f32>)> {
    let max_k = frames.min(3 * v) as u64;
    let mut ks = Vec::with_capacity(group_count);
    for _ in 0..group_count {
        let k = r.varint("components")?;
        if k > max_k {
            return Err(r.malformed("components", format!("{k} exceeds min(frames, 3·vertices) = {max_k}")));
        }
        ks.push(k as usize);
    }
    let n_mean = mean_layout(centering, 0, 0).0;
    let step_count: usize = ks.iter().map(|&k| n_mean + 2 * k).sum();
    let side_raw = r.length_prefixed("steps")?;
    let side = entropy::decompress(side_raw, NAME, "steps", step_count * 4)?;
    if side.len() != step_count * 4 {
        return Err(Error::malformed(NAME, "steps", format!("{} bytes, expected {}", side.len(), step_count * 4)));
    }
    let mut sr = ByteReader::new(&side, NAME);
    let mut steps = Vec::with_capacity(step_count);
    for _ in 0..step_count {
        let s = sr.f32("step")?;
        if !s.is_finite() || s < 0.0 {
            return Err(Error::malformed(NAME, "step", format!("{s} is not a finite non-negative step")));
        }
        steps.push(s);
    }
    Ok((ks, steps))
}

/// Decodes the group label of each of the `v` vertices (mesh order; all zero when there is one
/// group): each label is coded as the difference from its first earlier neighbour's on the
/// full mesh's causal graph, and must name one of the `group_count` groups.
fn decode_labels(
    dec: &mut AdaptiveDecoder,
    graphs: &mut Graphs,
    limits: &mut Limits,
    v: usize,
    group_count: usize,
) -> Result<Vec<u8>> {
    let mut labels = vec![0u8; v];
    if group_count > 1 {
        // Every decoded value is charged before decoding (`--max-work`).
        *limits = limits.spend(NAME, "labels", (v as u64).saturating_mul(codec_core::limits::WORK_PER_CODED_VALUE))?;
        let full = graphs.full(limits)?;
        let order = full.order();
        let mut codes = vec![0i32; v];
        for p in 0..full.len() {
            let bucket = predict::neighbour_bucket(full, &codes, p);
            codes[p] = dec.decode(CLASS_LABEL, bucket)?;
            let pred = full.earlier(p).first().map_or(0, |&q| labels[order[q as usize] as usize] as i64);
            let l = pred + codes[p] as i64;
            if !(0..group_count as i64).contains(&l) {
                return Err(Error::malformed(
                    NAME,
                    "labels",
                    format!("vertex {}: group {l} of {group_count}", order[p]),
                ));
            }
            labels[order[p] as usize] = l as u8;
        }
    }
    Ok(labels)
}

/// Decodes a toolkit-coded packet of `frames` frames (after the case byte was checked).
#[allow(clippy::too_many_arguments)]
pub(crate) fn decode_segment(
    r: &mut ByteReader<'_>,
    frames: usize,
    v: usize,
    centering: Centering,
    pr: Predictors,
    graphs: &mut Graphs,
    limits: &mut Limits,
    group_count: usize,
) -> Result<Vec<f32>> {
    use codec_core::limits::WORK_PER_CODED_VALUE;
    // Work amplification guard: a component whose steps are zero costs the stream almost
    // nothing, yet reconstruction costs frames·3·n·k multiply-adds. Packets never hold more
    // frames than `gamma_max` allows, so refusing longer ones bounds k, and with it the work
    // per decoded value, by `MAX_SEGMENT_FRAMES`.
    if frames > MAX_SEGMENT_FRAMES {
        return Err(Error::malformed(
            NAME,
            "packet frames",
            format!("{frames} exceeds the longest segment the encoder writes ({MAX_SEGMENT_FRAMES})"),
        ));
    }
    let (ks, steps) = read_ranks_and_steps(r, frames, v, centering, group_count)?;
    let n_mean = mean_layout(centering, 0, 0).0;
    let bytes = r.take(r.remaining(), "codes")?;
    let mut dec = AdaptiveDecoder::new(bytes, CLASSES, NAME, "codes")?;
    let labels = decode_labels(&mut dec, graphs, limits, v, group_count)?;
    let members: Vec<Vec<u32>> = {
        let mut m = vec![Vec::new(); group_count];
        for (i, &l) in labels.iter().enumerate() {
            m[l as usize].push(i as u32);
        }
        m
    };
    let values: u64 = members
        .iter()
        .zip(&ks)
        .map(|(m, &k)| (mean_layout(centering, m.len(), frames).1 + 3 * m.len() * k + k * frames) as u64)
        .sum();
    limits.check_alloc(NAME, "values", values.saturating_mul(8))?;
    let work = members
        .iter()
        .zip(&ks)
        .map(|(m, &k)| reconstruction_work(frames, m.len(), k))
        .fold(values.saturating_mul(WORK_PER_CODED_VALUE), u64::saturating_add);
    *limits = limits.spend(NAME, "values and reconstruction", work)?;
    let group_graphs = graphs.groups(&labels, group_count, limits)?;
    let time = CausalGraph::chain(frames, pr.time == Predictor::Parallelogram);
    let n3 = v * 3;
    let mut out = vec![0f32; frames * n3];
    let mut at = 0;
    for ((own, &k), gg) in members.iter().zip(&ks).zip(group_graphs) {
        let mut mean = Vec::with_capacity(n_mean);
        for c in 0..n_mean {
            let field = if centering == Centering::Vertex {
                from_order(gg, &decode_component(&mut dec, gg, pr.mesh, CLASS_MEAN + c, steps[at], 1)?[0])
            } else {
                decode_component(&mut dec, &time, pr.time, CLASS_MEAN + c, steps[at], 1)?.remove(0)
            };
            mean.push(field);
            at += 1;
        }
        let mut b = Vec::with_capacity(k);
        for j in 0..k {
            b.push(decode_component(&mut dec, &time, pr.time, CLASS_B + j.min(PER_KIND - 1), steps[at], 1)?.remove(0));
            at += 1;
        }
        let mut a = Vec::with_capacity(k);
        for j in 0..k {
            let f = decode_component(&mut dec, gg, pr.mesh, CLASS_A + j.min(PER_KIND - 1), steps[at], 3)?;
            a.push(f.iter().map(|x| from_order(gg, x)).collect::<Vec<_>>());
            at += 1;
        }
        // A term with a zero step on either side is all zeros: skip it (same values up to the
        // sign of an exact zero), so zero-step components cost no reconstruction work.
        let (b_steps, a_steps) = steps[at - 2 * k..at].split_at(k);
        let (a, b): (Vec<_>, Vec<_>) = a
            .into_iter()
            .zip(b)
            .zip(a_steps.iter().zip(b_steps))
            .filter(|(_, (&sa, &sb))| sa != 0.0 && sb != 0.0)
            .map(|(term, _)| term)
            .unzip();
        reconstruct_group(centering, own, &mean, &a, &b, frames, n3, &mut out);
    }
    // Every coded word was read (a header claiming fewer vertices than were coded is
    // an error, as is one claiming more: the decoder then runs past its data).
    dec.finish()?;
    Ok(out)
}
