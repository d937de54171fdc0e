//! The cotangent Laplacian of the decoded average mesh, its anchors, and the sparse Cholesky
//! factorization the decoder solves with.
//!
//! Both sides build [`Operator`] from the same inputs (the triangle list and the decoded average
//! mesh, both in the stream) with the same scalar `f64` arithmetic in the same order: no SIMD,
//! no fused multiply-add, no threads, no library kernels. So the factor, and every field solved
//! with it, is the same bit for bit on every CPU, and the encoder's reconstruction is the
//! decoder's.
//!
//! - Weights: `w_uv = ½(cot α + cot β)` over the (one or two) triangles on edge `uv` (Meyer et al.,
//!   the linear finite-element stiffness matrix), clamped to `[W_MIN, W_MAX]`: a clamped weight
//!   is positive, so `L = D − W` is a weighted graph Laplacian, positive semi-definite whatever
//!   the geometry (obtuse or degenerate triangles included), and its restriction to the free
//!   vertices of a component with an anchor is positive definite. The clamp also bounds the
//!   condition number a hostile stream can give the decoder's solve.
//! - Anchors: every `spacing`-th vertex of the breadth-first coding order
//!   ([`CausalGraph::mesh`]), and the seed of every connected component (an isolated vertex is
//!   its own component), so every component has one.
//! - Solve: the anchors are held at their decoded values (Dirichlet conditions), so the free
//!   vertices' system `L_ff c_f = δ + W_fa c_a` is symmetric positive definite; it is factored by
//!   an envelope (profile) Cholesky in reverse breadth-first order (reverse Cuthill–McKee-like,
//!   whose envelope the factor's fill never leaves), so the memory and the work are known from
//!   the topology alone before anything is allocated.

use codec_core::toolkit::order::CausalGraph;
use codec_core::{Error, Limits, Result};

use crate::NAME;

/// Smallest and largest edge weight (cotangent weights of well-shaped triangles lie near
/// 0.3–1.5; a weight outside comes from a needle or a nearly flat triangle).
pub const W_MIN: f64 = 1e-2;
/// See [`W_MIN`].
pub const W_MAX: f64 = 1e2;

/// The Laplacian restricted to the free vertices, factored, plus what is needed to form the
/// right-hand side from anchor values.
#[derive(Debug, Clone)]
pub struct Operator {
    /// Vertex count.
    n: usize,
    /// Anchor vertices, in coding (breadth-first) order.
    anchors: Vec<u32>,
    /// Free vertices in coding order (the order their δ codes are written).
    free_coding: Vec<u32>,
    /// Elimination index of each vertex (`u32::MAX` for anchors).
    elim: Vec<u32>,
    /// Vertex of each elimination index.
    elim_vertex: Vec<u32>,
    /// Adjacency (CSR over vertices): neighbours and edge weights, and each vertex's degree
    /// (sum of its weights).
    adj_start: Vec<usize>,
    adj: Vec<u32>,
    weight: Vec<f64>,
    degree: Vec<f64>,
    /// Envelope Cholesky factor: row `i` holds columns `first[i] ..= i` at `start[i]..`.
    first: Vec<usize>,
    start: Vec<usize>,
    factor: Vec<f64>,
}

/// Sizes of an operator, known from the topology alone (checked against [`Limits`] before any
/// of it is built).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OperatorSize {
    /// Free vertices.
    pub free: u64,
    /// Entries of the envelope factor.
    pub envelope: u64,
    /// Multiply-adds of the factorization (an upper bound: `Σ width²`).
    pub factor_work: u64,
}

impl OperatorSize {
    /// Bytes the operator holds (factor, adjacency, orders), an upper bound.
    pub fn bytes(&self, n: usize, edges: usize) -> u64 {
        let n = n as u64;
        let e = 2 * edges as u64;
        self.envelope * 8 + e * 12 + n * (8 + 8 + 8 + 4 * 4 + 8)
    }
}

/// Undirected edges of `triangles` with their cotangent weights in `positions` (`n × 3`,
/// `f64`), sorted by `(u, v)` with `u < v`, each summed over its triangles in triangle order
/// (a fixed order: the same sum on both sides). Triangles with a repeated corner add nothing;
/// corners out of range are the caller's to refuse (the container checks them).
fn weighted_edges(n: usize, triangles: &[[u32; 3]], positions: Option<&[f64]>) -> Vec<(u32, u32, f64)> {
    let mut half = Vec::with_capacity(triangles.len() * 3);
    for t in triangles {
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] || t.iter().any(|&x| x as usize >= n) {
            continue;
        }
        for c in 0..3 {
            // The angle at corner `c` weights the opposite edge.
            let (o, a, b) = (t[c] as usize, t[(c + 1) % 3], t[(c + 2) % 3]);
            let cot = positions.map_or(0.0, |p| cotangent(p, o, a as usize, b as usize));
            half.push((a.min(b), a.max(b), 0.5 * cot));
        }
    }
    // Stable: equal keys keep triangle order, so each edge's sum is formed in that order.
    half.sort_by_key(|&(u, v, _)| (u, v));
    let mut edges: Vec<(u32, u32, f64)> = Vec::with_capacity(half.len() / 2 + 1);
    for (u, v, w) in half {
        match edges.last_mut() {
            Some(last) if last.0 == u && last.1 == v => last.2 += w,
            _ => edges.push((u, v, w)),
        }
    }
    for e in &mut edges {
        e.2 = if e.2.is_nan() { W_MIN } else { e.2.clamp(W_MIN, W_MAX) };
    }
    edges
}

/// `cot` of the angle at vertex `o` between the edges to `a` and `b` (`(u·v)/|u×v|`); 0 for a
/// degenerate corner (coincident points), whose weight the clamp then decides.
fn cotangent(p: &[f64], o: usize, a: usize, b: usize) -> f64 {
    let u = [p[a * 3] - p[o * 3], p[a * 3 + 1] - p[o * 3 + 1], p[a * 3 + 2] - p[o * 3 + 2]];
    let v = [p[b * 3] - p[o * 3], p[b * 3 + 1] - p[o * 3 + 1], p[b * 3 + 2] - p[o * 3 + 2]];
    let dot = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    let cx = u[1] * v[2] - u[2] * v[1];
    let cy = u[2] * v[0] - u[0] * v[2];
    let cz = u[0] * v[1] - u[1] * v[0];
    let cross = (cx * cx + cy * cy + cz * cz).sqrt();
    let c = dot / cross;
    if c.is_finite() {
        c
    } else if dot > 0.0 {
        W_MAX
    } else {
        0.0
    }
}

/// Whether each position of `graph`'s order is an anchor: every `spacing`-th position and
/// every component seed (a position with no earlier neighbour).
pub fn anchor_positions(graph: &CausalGraph, spacing: usize) -> Vec<bool> {
    let spacing = spacing.max(1);
    (0..graph.len()).map(|p| p % spacing == 0 || graph.earlier(p).is_empty()).collect()
}

/// The anchors and the free vertices ([`anchor_positions`]), both in coding order.
pub fn split_anchors(graph: &CausalGraph, spacing: usize) -> (Vec<u32>, Vec<u32>) {
    let (mut anchors, mut free) = (Vec::new(), Vec::new());
    for (&v, anchor) in graph.order().iter().zip(anchor_positions(graph, spacing)) {
        if anchor {
            anchors.push(v);
        } else {
            free.push(v);
        }
    }
    (anchors, free)
}

/// The envelope layout of the free vertices' system: elimination order (reverse coding order),
/// each row's first column, and the sizes.
struct Layout {
    elim: Vec<u32>,
    elim_vertex: Vec<u32>,
    first: Vec<usize>,
    size: OperatorSize,
}

fn layout(n: usize, free_coding: &[u32], adj_start: &[usize], adj: &[u32]) -> Layout {
    let mut elim = vec![u32::MAX; n];
    let elim_vertex: Vec<u32> = free_coding.iter().rev().copied().collect();
    for (i, &v) in elim_vertex.iter().enumerate() {
        elim[v as usize] = i as u32;
    }
    let mut first = Vec::with_capacity(elim_vertex.len());
    let (mut envelope, mut work) = (0u64, 0u64);
    for (i, &v) in elim_vertex.iter().enumerate() {
        let v = v as usize;
        let f = adj[adj_start[v]..adj_start[v + 1]]
            .iter()
            .map(|&u| elim[u as usize])
            .filter(|&j| j != u32::MAX)
            .map(|j| j as usize)
            .fold(i, usize::min);
        let width = (i - f + 1) as u64;
        envelope = envelope.saturating_add(width);
        work = work.saturating_add(width.saturating_mul(width));
        first.push(f);
    }
    let size = OperatorSize { free: elim_vertex.len() as u64, envelope, factor_work: work };
    Layout { elim, elim_vertex, first, size }
}

/// CSR adjacency of `edges` over `n` vertices (each edge in both rows, neighbours ascending).
fn adjacency(n: usize, edges: &[(u32, u32, f64)]) -> (Vec<usize>, Vec<u32>, Vec<f64>) {
    let mut count = vec![0usize; n + 1];
    for &(u, v, _) in edges {
        count[u as usize + 1] += 1;
        count[v as usize + 1] += 1;
    }
    for i in 0..n {
        count[i + 1] += count[i];
    }
    let mut fill = count.clone();
    let mut adj = vec![0u32; count[n]];
    let mut weight = vec![0.0; count[n]];
    // Edges are sorted by (u, v): row u receives its larger neighbours ascending, row v its
    // smaller ones ascending, all smaller before any larger.
    for &(u, v, w) in edges {
        for (a, b) in [(v, u), (u, v)] {
            let slot = fill[a as usize];
            adj[slot] = b;
            weight[slot] = w;
            fill[a as usize] += 1;
        }
    }
    (count, adj, weight)
}

/// Sizes of the operator of this topology and anchor spacing, without building it.
pub fn operator_size(graph: &CausalGraph, triangles: &[[u32; 3]], spacing: usize) -> (OperatorSize, usize) {
    let n = graph.len();
    let edges = weighted_edges(n, triangles, None);
    let (adj_start, adj, _) = adjacency(n, &edges);
    let (_, free) = split_anchors(graph, spacing);
    (layout(n, &free, &adj_start, &adj).size, edges.len())
}

impl Operator {
    /// Builds and factors the operator of `triangles` on the average mesh `positions` (`n × 3`,
    /// vertex order) with anchors every `spacing` positions of `graph`. The memory and the work
    /// are checked against `limits` before they are spent. Fails (naming the pivot) when the
    /// factorization meets a non-positive pivot, which exact arithmetic rules out.
    pub fn new(
        graph: &CausalGraph,
        triangles: &[[u32; 3]],
        positions: &[f64],
        spacing: usize,
        limits: &Limits,
    ) -> Result<Self> {
        let n = graph.len();
        let edges = weighted_edges(n, triangles, Some(positions));
        let (adj_start, adj, weight) = adjacency(n, &edges);
        let (anchors, free_coding) = split_anchors(graph, spacing);
        let Layout { elim, elim_vertex, first, size } = layout(n, &free_coding, &adj_start, &adj);
        limits.check_alloc(NAME, "Laplacian factor", size.bytes(n, edges.len()))?;
        limits.check_work(NAME, "Laplacian factorization", size.factor_work)?;
        let degree: Vec<f64> = (0..n).map(|v| weight[adj_start[v]..adj_start[v + 1]].iter().sum()).collect();
        let mut start = Vec::with_capacity(first.len() + 1);
        let mut total = 0usize;
        for (i, &f) in first.iter().enumerate() {
            start.push(total);
            total += i - f + 1;
        }
        start.push(total);
        let mut factor = vec![0.0; total];
        // The matrix entries into the envelope: diagonal = degree, off-diagonal = −w.
        for (i, &v) in elim_vertex.iter().enumerate() {
            let v = v as usize;
            factor[start[i] + (i - first[i])] = degree[v];
            for s in adj_start[v]..adj_start[v + 1] {
                let j = elim[adj[s] as usize];
                if j != u32::MAX && (j as usize) < i {
                    factor[start[i] + (j as usize - first[i])] = -weight[s];
                }
            }
        }
        // Row-oriented (bordering) Cholesky inside the envelope.
        for i in 0..first.len() {
            let (fi, si) = (first[i], start[i]);
            for j in fi..i {
                let (fj, sj) = (first[j], start[j]);
                let k0 = fi.max(fj);
                let mut s = factor[si + (j - fi)];
                for k in k0..j {
                    s -= factor[si + (k - fi)] * factor[sj + (k - fj)];
                }
                factor[si + (j - fi)] = s / factor[sj + (j - fj)];
            }
            let mut d = factor[si + (i - fi)];
            for k in fi..i {
                let x = factor[si + (k - fi)];
                d -= x * x;
            }
            if !(d > 0.0 && d.is_finite()) {
                return Err(Error::malformed(
                    NAME,
                    "Laplacian",
                    format!(
                        "the average mesh's Laplacian factorization met pivot {d} at row {i} (not positive definite)"
                    ),
                ));
            }
            factor[si + (i - fi)] = d.sqrt();
        }
        Ok(Self { n, anchors, free_coding, elim, elim_vertex, adj_start, adj, weight, degree, first, start, factor })
    }

    /// Anchor vertices, in coding order.
    pub fn anchors(&self) -> &[u32] {
        &self.anchors
    }

    /// Free vertices, in coding order.
    #[cfg(test)]
    pub fn free(&self) -> &[u32] {
        &self.free_coding
    }

    /// `δ` of `field` (vertex order) at the free vertices, in coding order: the free rows of
    /// `L·c`, with the anchors' values taken from `anchor_values` (the decoded ones, so that
    /// [`Operator::solve`] on the exact `δ` returns `field` at the free vertices).
    pub fn delta(&self, field: &[f64], anchor_values: &[f64]) -> Vec<f64> {
        let mut value = field.to_vec();
        for (&a, &x) in self.anchors.iter().zip(anchor_values) {
            value[a as usize] = x;
        }
        self.free_coding
            .iter()
            .map(|&v| {
                let v = v as usize;
                let mut s = self.degree[v] * value[v];
                for k in self.adj_start[v]..self.adj_start[v + 1] {
                    s -= self.weight[k] * value[self.adj[k] as usize];
                }
                s
            })
            .collect()
    }

    /// The field (vertex order) whose anchors are `anchor_values` (coding order) and whose free
    /// rows of `L·c` are `delta` (coding order of the free vertices).
    pub fn solve(&self, delta: &[f64], anchor_values: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.n];
        for (&a, &x) in self.anchors.iter().zip(anchor_values) {
            out[a as usize] = x;
        }
        // Right-hand side in elimination order: δ plus the anchor neighbours' pull.
        let m = self.elim_vertex.len();
        let mut y = vec![0.0; m];
        for (&v, &d) in self.free_coding.iter().zip(delta) {
            let v = v as usize;
            let mut b = d;
            for k in self.adj_start[v]..self.adj_start[v + 1] {
                let u = self.adj[k] as usize;
                if self.elim[u] == u32::MAX {
                    b += self.weight[k] * out[u];
                }
            }
            y[self.elim[v] as usize] = b;
        }
        // Forward (L y = b) then backward (Lᵀ x = y) substitution, in place.
        for i in 0..m {
            let (fi, si) = (self.first[i], self.start[i]);
            let mut s = y[i];
            for (l, &yk) in self.factor[si..si + (i - fi)].iter().zip(&y[fi..i]) {
                s -= l * yk;
            }
            y[i] = s / self.factor[si + (i - fi)];
        }
        for i in (0..m).rev() {
            let (fi, si) = (self.first[i], self.start[i]);
            y[i] /= self.factor[si + (i - fi)];
            let x = y[i];
            for (yk, l) in y[fi..i].iter_mut().zip(&self.factor[si..si + (i - fi)]) {
                *yk -= l * x;
            }
        }
        for (i, &v) in self.elim_vertex.iter().enumerate() {
            out[v as usize] = y[i];
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use animcodec_synth as synth;

    #[test]
    fn solve_inverts_delta_and_holds_anchors() {
        let anim = synth::waving_flag(9, 7, 3);
        let t = anim.topology().triangles();
        let n = anim.vertex_count();
        let pos: Vec<f64> = anim.positions()[..n * 3].iter().map(|&x| x as f64).collect();
        let graph = CausalGraph::mesh(n, t);
        let op = Operator::new(&graph, t, &pos, 7, &Limits::default()).unwrap();
        assert!(op.anchors().len() >= n / 7 && !op.free().is_empty());
        let field: Vec<f64> = (0..n).map(|v| ((v * 37 % 11) as f64).sin()).collect();
        let anchors: Vec<f64> = op.anchors().iter().map(|&a| field[a as usize] + 0.5).collect();
        let back = op.solve(&op.delta(&field, &anchors), &anchors);
        for (k, &a) in op.anchors().iter().enumerate() {
            assert_eq!(back[a as usize], anchors[k]);
        }
        for &v in op.free() {
            assert!((back[v as usize] - field[v as usize]).abs() < 1e-9, "vertex {v}");
        }
        let (size, _) = operator_size(&graph, t, 7);
        assert_eq!(size.envelope as usize, op.factor.len());
    }

    #[test]
    fn degenerate_geometry_still_factors() {
        // Every vertex at one point: all cotangents degenerate, weights clamped positive.
        let anim = synth::waving_flag(5, 4, 1);
        let t = anim.topology().triangles();
        let n = anim.vertex_count();
        let graph = CausalGraph::mesh(n, t);
        let op = Operator::new(&graph, t, &vec![0.0; n * 3], 40, &Limits::default()).unwrap();
        let zero = op.solve(&vec![0.0; op.free().len()], &vec![1.0; op.anchors().len()]);
        assert!(zero.iter().all(|x| (x - 1.0).abs() < 1e-9));
    }
}
