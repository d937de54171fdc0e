//! STED, the spatio-temporal edge difference of Váša & Skala, "A perception correlated
//! comparison method for dynamic meshes", IEEE TVCG 17(2), 2011 — computed as the STED tool
//! published by the metric's first author computes it (`../shared/sted-oracle/ALGORITHM.md`),
//! with the tool's defaults. `metrics/README.md` states the equations and the evidence; the
//! oracle test (`tests/sted_oracle.rs`) reproduces every reference value of the tool within 5e-4 (relative).
//!
//! * **Spatial part `S`.** For frame `f` and mesh edge `e = {a, b}`: `L = ‖P_a − P_b‖`
//!   (reference), `L' = ‖Q_a − Q_b‖` (candidate), `d_e = (L − L')/L` (0 when `L = 0`). `R(v)` is
//!   `v` and every vertex within `w` edge hops; `N(v)` every edge with *at least one* endpoint
//!   in `R(v)` (w = 1: spokes, rim edges and the edges leaving the rim). The local deviation
//!   is the length-weighted population standard deviation of `d` over `N(v)`:
//!   `W = Σ L`, `μ = Σ L·d / W`, `σ_v = sqrt(Σ L·(d − μ)² / W)`; a vertex with `W = 0`
//!   contributes 0 but still counts. `S = Σ_f Σ_v σ_v^f / (V·F)`.
//! * **Temporal part `T`.** Positions divided by `D`, the diameter of reference frame 0.
//!   The temporal edge of vertex `i` ending at frame `g` has length
//!   `ℓ_i^g = sqrt(‖P̂_i^g − P̂_i^{g−1}‖² + dt²)` (`ℓ'` likewise from the candidate, same `D`).
//!   The reference speed `s̄_i^f` is the mean of `ℓ_i^g` over `g = max(1, f−k+1) … min(F−1, f+k)`.
//!   `T = Σ_{f=1}^{F−1} Σ_i |ℓ'_i^f − ℓ_i^f| / s̄_i^f / (V·(F−1))`.
//! * **Combination.** `STED = sqrt(S² + c²·T²)`. One frame has no temporal edges: the tool
//!   prints NaN, we report `T = 0` (so `STED = S`) and [`StedResult::temporal_defined`] false.

use codec_core::{Animation, Error, Result};
use rayon::prelude::*;
use serde::Serialize;

use crate::common::{check_compatible, norm2, point, sub, unique_edges, vertex_dist2, CTX};

/// How a relative edge difference is formed in the spatial part.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum EdgeDifference {
    /// `(L − L')/L`, the tool's (default). A uniformly stretched neighbourhood scores 0.
    Signed,
    /// `|L − L'|/L`: not the tool's; a neighbourhood with mixed stretching and shrinking scores
    /// lower than with `Signed`. Kept for comparison with results computed that way.
    Absolute,
}

/// Parameters of [`sted`]; all are reported with the result. The defaults are the author's
/// tool's, read from its compiled code and confirmed by reproducing its output on eight
/// reference pairs (`../shared/sted-oracle/`) to better than 1e-6 relative.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StedParams {
    /// Width `w` of the spatial neighbourhood in topological rings, 1..=16: `R(v)` is every
    /// vertex within `w` edge hops of `v`, the neighbourhood every edge touching `R(v)`.
    /// Default 1 (the tool's).
    pub ring_radius: u32,
    /// Time extent `dt` of one frame step in the temporal edges, in units of the diameter `D`
    /// of reference frame 0; within [`DT_RANGE`](Self::DT_RANGE). Default 0.0003 (the tool's).
    pub dt: f64,
    /// Half-width `k` of the window over which the reference speed is averaged (temporal edges
    /// `f−k+1 … f+k`), 1..=1000. Default 5 (the tool's).
    pub speed_window: u32,
    /// Weight `c` of the temporal part; 0..=[`MAX_C`](Self::MAX_C). Default 9.144e-5 (the tool's): the
    /// temporal term then matters only when the spatial error is tiny.
    pub c: f64,
    /// Signed (the tool's, default) or absolute relative edge differences.
    pub spatial_difference: EdgeDifference,
}

impl Default for StedParams {
    fn default() -> Self {
        Self { ring_radius: 1, dt: 0.0003, speed_window: 5, c: 9.144e-5, spatial_difference: EdgeDifference::Signed }
    }
}

impl StedParams {
    /// Largest accepted `ring_radius` (the neighbourhood size grows with its square).
    pub const MAX_RING_RADIUS: u32 = 16;
    /// Largest accepted `speed_window`.
    pub const MAX_SPEED_WINDOW: u32 = 1000;
    /// Accepted range of `dt` (units of the diameter `D`). Its square must stay a normal number:
    /// every temporal edge is at least `dt` long, which keeps the reference speeds that divide
    /// `T` above zero (at `dt = 1e-300`, `dt²` underflows to 0 and a still vertex gives 0/0).
    pub const DT_RANGE: std::ops::RangeInclusive<f64> = 1e-9..=1e9;
    /// Largest accepted `c`: `c²·T²` must stay finite (at `c = 1e300`, `c²` is infinite).
    pub const MAX_C: f64 = 1e9;

    /// Checks every field, naming the offending one and its allowed range.
    pub fn validate(&self) -> Result<()> {
        if !(1..=Self::MAX_RING_RADIUS).contains(&self.ring_radius) {
            return Err(Error::parameter(
                "sted",
                "ring_radius",
                format!("{} is outside 1..={}", self.ring_radius, Self::MAX_RING_RADIUS),
            ));
        }
        if !Self::DT_RANGE.contains(&self.dt) {
            return Err(Error::parameter(
                "sted",
                "dt",
                format!("{:e} is outside {:e}..={:e}", self.dt, Self::DT_RANGE.start(), Self::DT_RANGE.end()),
            ));
        }
        if !(1..=Self::MAX_SPEED_WINDOW).contains(&self.speed_window) {
            return Err(Error::parameter(
                "sted",
                "speed_window",
                format!("{} is outside 1..={}", self.speed_window, Self::MAX_SPEED_WINDOW),
            ));
        }
        if !(0.0..=Self::MAX_C).contains(&self.c) {
            return Err(Error::parameter("sted", "c", format!("{:e} is outside 0..={:e}", self.c, Self::MAX_C)));
        }
        Ok(())
    }
}

/// Result of [`sted`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StedResult {
    /// `sqrt(spatial² + c²·temporal²)`.
    pub sted: f64,
    /// `S`, mean local deviation of relative edge differences.
    pub spatial: f64,
    /// `T`, mean relative change of temporal edge lengths (0 when not defined).
    pub temporal: f64,
    /// False when the temporal part is undefined — one frame, or reference frame 0 collapsed
    /// to a point (`D = 0`) — and `sted` is the spatial part alone.
    pub temporal_defined: bool,
    /// `D`, the diameter of reference frame 0 (the temporal part's unit of length).
    pub diameter: f64,
    /// Parameters used.
    pub params: StedParams,
    /// Number of mesh edges.
    pub edge_count: usize,
    /// Vertex-frames whose neighbourhood has no edge of positive length (e.g. vertices in no
    /// triangle): they contribute 0 to `S` but count in its mean, as in the tool.
    pub empty_vertex_frames: usize,
    /// Per vertex: mean over frames of its local deviation `σ_v^f`. Empty unless requested
    /// with [`sted_with_fields`].
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub spatial_per_vertex: Vec<f64>,
}

/// Computes STED. Fails on mismatched animations, invalid parameters, or a mesh with no
/// edges (a point cloud has no STED).
pub fn sted(reference: &Animation, candidate: &Animation, params: &StedParams) -> Result<StedResult> {
    run(reference, candidate, params, false)
}

/// Like [`sted`], also filling [`StedResult::spatial_per_vertex`].
pub fn sted_with_fields(reference: &Animation, candidate: &Animation, params: &StedParams) -> Result<StedResult> {
    run(reference, candidate, params, true)
}

/// STED's local deviation `σ_v^f` of every vertex in every frame (frame-major, `F × V`, as
/// `f32` to halve the memory of long sequences): the per-vertex, per-frame field whose mean is
/// the spatial part `S`. For heat maps of where and when a candidate distorts the surface.
pub fn sted_local_deviations(reference: &Animation, candidate: &Animation, params: &StedParams) -> Result<Vec<f32>> {
    let (edges, hood) = prepare(reference, candidate, params)?;
    let n = reference.vertex_count();
    let mut out = vec![0.0f32; n * reference.frame_count()];
    out.par_chunks_mut(n.max(1)).enumerate().for_each(|(t, frame)| {
        let (sigma, _) = local_deviations(reference.frame(t), candidate.frame(t), &edges, &hood, params);
        frame.iter_mut().zip(sigma).for_each(|(o, s)| *o = s as f32);
    });
    Ok(out)
}

/// Frames processed per parallel batch (bounds the memory of per-vertex fields).
const FRAME_BATCH: usize = 32;

/// Checks the inputs and builds the mesh edges and every vertex's neighbourhood.
fn prepare(
    reference: &Animation,
    candidate: &Animation,
    params: &StedParams,
) -> Result<(Vec<[u32; 2]>, Neighbourhoods)> {
    check_compatible(reference, candidate)?;
    params.validate()?;
    mesh_neighbourhoods(reference.triangles(), reference.vertex_count(), params)
}

/// The mesh edges and every vertex's neighbourhood of `ring_radius` rings; fails for a mesh
/// without edges (a point cloud has no STED).
pub(crate) fn mesh_neighbourhoods(
    triangles: &[[u32; 3]],
    n: usize,
    params: &StedParams,
) -> Result<(Vec<[u32; 2]>, Neighbourhoods)> {
    let edges = unique_edges(triangles);
    if edges.is_empty() {
        return Err(Error::InvalidAnimation(format!("{CTX}: STED needs mesh edges, but the mesh has no triangles")));
    }
    let hood = Neighbourhoods::new(n, &edges, params.ring_radius)?;
    Ok((edges, hood))
}

fn run(reference: &Animation, candidate: &Animation, params: &StedParams, fields: bool) -> Result<StedResult> {
    let (edges, hood) = prepare(reference, candidate, params)?;
    let n = reference.vertex_count();
    let frames = reference.frame_count();

    // Spatial part, batches of frames in parallel, reduced in frame order.
    let mut sum = 0.0;
    let mut empty = 0usize;
    let mut pv_sum = vec![0.0; if fields { n } else { 0 }];
    for batch in (0..frames).collect::<Vec<_>>().chunks(FRAME_BATCH) {
        let results: Vec<(Vec<f64>, usize)> = batch
            .par_iter()
            .map(|&t| local_deviations(reference.frame(t), candidate.frame(t), &edges, &hood, params))
            .collect();
        for (sigma, empty_here) in results {
            sum += sigma.iter().sum::<f64>();
            empty += empty_here;
            if fields {
                pv_sum.iter_mut().zip(&sigma).for_each(|(acc, s)| *acc += s);
            }
        }
    }
    let diameter = diameter(reference.frame(0));
    let mut temporal = TemporalWindow::new(n, frames, diameter, params);
    if let Some(t) = temporal.as_mut() {
        for g in 1..frames {
            t.push_edge(
                t.edge_lengths(reference.frame(g), reference.frame(g - 1)),
                t.edge_lengths(candidate.frame(g), candidate.frame(g - 1)),
            );
        }
    }
    let spatial_per_vertex = pv_sum.iter().map(|&s| s / frames as f64).collect();
    Ok(summarize_sted(
        sum,
        empty,
        n,
        frames,
        temporal.map(|t| t.total()),
        diameter,
        params,
        edges.len(),
        spatial_per_vertex,
    ))
}

/// [`StedResult`] from the sum of every frame's local deviations, the count of empty
/// neighbourhoods and `T` (`None` when undefined).
#[allow(clippy::too_many_arguments)]
pub(crate) fn summarize_sted(
    spatial_sum: f64,
    empty: usize,
    n: usize,
    frames: usize,
    temporal: Option<f64>,
    diameter: f64,
    params: &StedParams,
    edge_count: usize,
    spatial_per_vertex: Vec<f64>,
) -> StedResult {
    let spatial = spatial_sum / (n * frames) as f64;
    let temporal_defined = temporal.is_some();
    let temporal = temporal.unwrap_or(0.0);
    StedResult {
        sted: (spatial * spatial + params.c * params.c * temporal * temporal).sqrt(),
        spatial,
        temporal,
        temporal_defined,
        diameter,
        params: *params,
        edge_count,
        empty_vertex_frames: empty,
        spatial_per_vertex,
    }
}

/// Vertices per parallel chunk of the temporal part; fixed, so that partial sums are added in
/// the same order whatever the thread count.
const TEMPORAL_CHUNK: usize = 4096;

/// The temporal part `T` (module docs), fed one temporal edge at a time in frame order: the
/// reference's edge lengths of the window `max(1, f−k+1) … min(F−1, f+k)` are kept as at most
/// `2k` arrays of `V` lengths, the candidate's of the frames still waiting for their window as
/// at most `k + 1` (memory `O(k·V)`, not `O(F·V)`). Frame `f`'s term is added as soon as the
/// last edge of its window arrives; each frame's vertices run in parallel in fixed chunks.
pub(crate) struct TemporalWindow {
    n: usize,
    frames: usize,
    k: usize,
    inv_d2: f64,
    dt2: f64,
    /// `reference[j]`: the reference lengths of temporal edge `first + j`.
    reference: std::collections::VecDeque<Vec<f64>>,
    first: usize,
    /// `candidate[j]`: the candidate lengths of temporal edge `next + j`.
    candidate: std::collections::VecDeque<Vec<f64>>,
    /// The next frame whose term is due.
    next: usize,
    /// Edges received so far.
    edges: usize,
    total: f64,
}

impl TemporalWindow {
    /// The window for `frames` frames of `n` vertices, or `None` when `T` is undefined (one
    /// frame, or a reference frame 0 of diameter 0).
    pub(crate) fn new(n: usize, frames: usize, diameter: f64, p: &StedParams) -> Option<Self> {
        (frames >= 2 && diameter > 0.0).then(|| Self {
            n,
            frames,
            k: p.speed_window as usize,
            inv_d2: 1.0 / (diameter * diameter),
            dt2: p.dt * p.dt,
            reference: Default::default(),
            first: 1,
            candidate: Default::default(),
            next: 1,
            edges: 0,
            total: 0.0,
        })
    }

    /// Bytes the window holds at most for `n` vertices and half-width `k`.
    pub(crate) fn bytes(n: usize, k: u32) -> u64 {
        (3 * k as u64 + 2) * n as u64 * 8
    }

    /// Lengths of the temporal edges of every vertex from frame `prev` to frame `next`, in
    /// units of `D`.
    pub(crate) fn edge_lengths(&self, next: &[f32], prev: &[f32]) -> Vec<f64> {
        let (inv_d2, dt2) = (self.inv_d2, self.dt2);
        let mut out = vec![0.0; self.n];
        out.par_chunks_mut(TEMPORAL_CHUNK).enumerate().for_each(|(c, chunk)| {
            for (i, l) in chunk.iter_mut().enumerate() {
                *l = (vertex_dist2(next, prev, c * TEMPORAL_CHUNK + i) * inv_d2 + dt2).sqrt();
            }
        });
        out
    }

    /// The next temporal edge (ending at frame `1 + edges received`): the reference's and the
    /// candidate's lengths from [`Self::edge_lengths`]. Adds the term of every frame whose
    /// window is now complete.
    pub(crate) fn push_edge(&mut self, reference: Vec<f64>, candidate: Vec<f64>) {
        self.edges += 1;
        self.reference.push_back(reference);
        self.candidate.push_back(candidate);
        let last = self.edges;
        while self.next < self.frames && (self.next + self.k).min(self.frames - 1) <= last {
            let f = self.next;
            let lo = (f + 1).saturating_sub(self.k).max(1);
            while self.first < lo {
                self.reference.pop_front();
                self.first += 1;
            }
            let (window, current) = (&self.reference, &self.reference[f - self.first]);
            let cand = self.candidate.pop_front().unwrap_or_default();
            let count = window.len() as f64;
            let n = self.n;
            let chunk_sums: Vec<f64> = (0..n.div_ceil(TEMPORAL_CHUNK))
                .into_par_iter()
                .map(|c| {
                    (c * TEMPORAL_CHUNK..((c + 1) * TEMPORAL_CHUNK).min(n))
                        .map(|v| {
                            let mean_speed = window.iter().map(|w| w[v]).sum::<f64>() / count;
                            (cand[v] - current[v]).abs() / mean_speed
                        })
                        .sum::<f64>()
                })
                .collect();
            self.total += chunk_sums.iter().sum::<f64>();
            self.next += 1;
        }
    }

    /// `T`, once every edge has been pushed.
    pub(crate) fn total(&self) -> f64 {
        self.total / (self.n * (self.frames - 1)) as f64
    }
}

/// Per vertex of one frame: the length-weighted population standard deviation of relative
/// edge differences over its neighbourhood (0 where no neighbourhood edge has positive
/// reference length), and how many vertices had such an empty neighbourhood.
pub(crate) fn local_deviations(
    a: &[f32],
    b: &[f32],
    edges: &[[u32; 2]],
    hood: &Neighbourhoods,
    p: &StedParams,
) -> (Vec<f64>, usize) {
    // (weight = reference length, relative difference) per edge.
    let per_edge: Vec<(f64, f64)> = edges
        .iter()
        .map(|&[i, j]| {
            let (i, j) = (i as usize, j as usize);
            let l = norm(sub(point(a, i), point(a, j)));
            if l > 0.0 {
                let lc = norm(sub(point(b, i), point(b, j)));
                let d = (l - lc) / l;
                (l, if p.spatial_difference == EdgeDifference::Absolute { d.abs() } else { d })
            } else {
                (0.0, 0.0)
            }
        })
        .collect();
    let mut empty = 0;
    let sigma = (0..hood.len())
        .map(|v| {
            let list = hood.of(v);
            let (mut w, mut wd) = (0.0, 0.0);
            for &e in list {
                let (l, d) = per_edge[e as usize];
                w += l;
                wd += l * d;
            }
            if w <= 0.0 {
                empty += 1;
                return 0.0;
            }
            let mu = wd / w;
            let var = list
                .iter()
                .map(|&e| {
                    let (l, d) = per_edge[e as usize];
                    l * (d - mu) * (d - mu)
                })
                .sum::<f64>()
                / w;
            var.max(0.0).sqrt()
        })
        .collect();
    (sigma, empty)
}

fn norm(x: [f64; 3]) -> f64 {
    norm2(x).sqrt()
}

/// Largest cells-per-axis of the grid in [`diameter`] (at most 1000 cells, 500 500 pairs).
const DIAMETER_GRID_MAX: usize = 10;

/// The exact diameter of a frame: the largest distance between two of its vertices.
///
/// The author's tool uses an octant-based search that equals the exact diameter on real meshes
/// (ALGORITHM.md). Here: vertices are bucketed into a grid of at most 10³ cells; cell pairs
/// are visited by decreasing upper bound (the largest distance between their bounding boxes)
/// and compared point by point until the bound falls below the best distance found, so only
/// the few cell pairs near opposite ends of the shape are searched exhaustively.
pub fn diameter(frame: &[f32]) -> f64 {
    let n = frame.len() / 3;
    if n < 2 {
        return 0.0;
    }
    let pts: Vec<[f64; 3]> = (0..n).map(|v| point(frame, v)).collect();
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for q in &pts {
        for a in 0..3 {
            lo[a] = lo[a].min(q[a]);
            hi[a] = hi[a].max(q[a]);
        }
    }
    // About 32 points per cell, at most DIAMETER_GRID_MAX per axis.
    let g = ((n as f64 / 32.0).cbrt().round() as usize).clamp(1, DIAMETER_GRID_MAX);
    let cell_of = |q: &[f64; 3]| {
        let mut c = 0;
        for a in 0..3 {
            let span = hi[a] - lo[a];
            let i = if span > 0.0 { (((q[a] - lo[a]) / span) * g as f64) as usize } else { 0 };
            c = c * g + i.min(g - 1);
        }
        c
    };
    let mut members: Vec<Vec<u32>> = vec![Vec::new(); g * g * g];
    for (v, q) in pts.iter().enumerate() {
        members[cell_of(q)].push(v as u32);
    }
    // Occupied cells with their tight boxes.
    let cells: Vec<(&[u32], [f64; 3], [f64; 3])> = members
        .iter()
        .filter(|m| !m.is_empty())
        .map(|m| {
            let (mut clo, mut chi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
            for &v in m {
                for a in 0..3 {
                    clo[a] = clo[a].min(pts[v as usize][a]);
                    chi[a] = chi[a].max(pts[v as usize][a]);
                }
            }
            (m.as_slice(), clo, chi)
        })
        .collect();
    let mut pairs: Vec<(f64, u32, u32)> = Vec::with_capacity(cells.len() * (cells.len() + 1) / 2);
    for (i, (_, alo, ahi)) in cells.iter().enumerate() {
        for (j, (_, blo, bhi)) in cells.iter().enumerate().skip(i) {
            let bound2: f64 = (0..3).map(|a| (ahi[a] - blo[a]).abs().max((bhi[a] - alo[a]).abs()).powi(2)).sum();
            pairs.push((bound2, i as u32, j as u32));
        }
    }
    pairs.sort_unstable_by(|x, y| y.0.total_cmp(&x.0));
    let mut best2 = 0.0f64;
    for &(bound2, i, j) in &pairs {
        if bound2 <= best2 {
            break;
        }
        let (a, b) = (cells[i as usize].0, cells[j as usize].0);
        for (ia, &u) in a.iter().enumerate() {
            let rest = if i == j { &b[ia + 1..] } else { b };
            let pu = pts[u as usize];
            for &w in rest {
                best2 = best2.max(norm2(sub(pu, pts[w as usize])));
            }
        }
    }
    best2.sqrt()
}

/// Vertices whose neighbourhoods are gathered per parallel batch.
const HOOD_BLOCK: usize = 1 << 16;
/// Most neighbourhood entries (edge ids, 4 bytes each: 1 GiB) before giving up: a large radius
/// on a large mesh grows as `V · radius²`.
pub(crate) const MAX_HOOD_ENTRIES: usize = 1 << 28;

/// For every vertex `v`, the edges with at least one endpoint within `radius` hops of `v`,
/// each once (CSR).
pub(crate) struct Neighbourhoods {
    start: Vec<usize>,
    edges: Vec<u32>,
}

impl Neighbourhoods {
    pub(crate) fn new(n: usize, edges: &[[u32; 2]], radius: u32) -> Result<Self> {
        // Adjacency with edge ids.
        let mut deg = vec![0usize; n + 1];
        for &[i, j] in edges {
            deg[i as usize + 1] += 1;
            deg[j as usize + 1] += 1;
        }
        for v in 0..n {
            deg[v + 1] += deg[v];
        }
        let mut fill = deg.clone();
        let mut adj = vec![(0u32, 0u32); deg[n]];
        for (e, &[i, j]) in edges.iter().enumerate() {
            adj[fill[i as usize]] = (j, e as u32);
            fill[i as usize] += 1;
            adj[fill[j as usize]] = (i, e as u32);
            fill[j as usize] += 1;
        }
        let adj_of = |v: usize| &adj[deg[v]..deg[v + 1]];
        let mut start = Vec::with_capacity(n + 1);
        start.push(0);
        let mut flat = Vec::new();
        for block in (0..n).step_by(HOOD_BLOCK) {
            let lists: Vec<Vec<u32>> = (block..(block + HOOD_BLOCK).min(n))
                .into_par_iter()
                .map_init(
                    || (vec![u32::MAX; n], Vec::<u32>::new()),
                    |(stamp, queue), v| {
                        // Breadth-first search to `radius` hops; `stamp[w] == v` marks R(v).
                        queue.clear();
                        queue.push(v as u32);
                        stamp[v] = v as u32;
                        let (mut head, mut level_end, mut level) = (0, 1, 0);
                        while head < queue.len() && level < radius {
                            while head < level_end {
                                let u = queue[head] as usize;
                                head += 1;
                                for &(w, _) in adj_of(u) {
                                    if stamp[w as usize] != v as u32 {
                                        stamp[w as usize] = v as u32;
                                        queue.push(w);
                                    }
                                }
                            }
                            level_end = queue.len();
                            level += 1;
                        }
                        // Every edge touching R(v), once: an edge with both ends inside is
                        // taken from its lower end.
                        let mut out = Vec::new();
                        for &u in queue.iter() {
                            for &(w, e) in adj_of(u as usize) {
                                if stamp[w as usize] != v as u32 || u < w {
                                    out.push(e);
                                }
                            }
                        }
                        out
                    },
                )
                .collect();
            for l in lists {
                flat.extend(l);
                start.push(flat.len());
            }
            if flat.len() > MAX_HOOD_ENTRIES {
                return Err(Error::parameter(
                    "sted",
                    "ring_radius",
                    format!(
                        "the neighbourhoods of radius {radius} hold more than {MAX_HOOD_ENTRIES} edge entries \
                         (after {} of {n} vertices); use a smaller radius",
                        start.len() - 1
                    ),
                ));
            }
        }
        Ok(Self { start, edges: flat })
    }

    pub(crate) fn len(&self) -> usize {
        self.start.len() - 1
    }

    pub(crate) fn of(&self, v: usize) -> &[u32] {
        &self.edges[self.start[v]..self.start[v + 1]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    /// A ladder of four triangles (0,2,1), (1,2,3), (2,4,3), (3,4,5) in the plane z = 0:
    /// ```text
    ///  1 ---- 3 ---- 5      0=(0,0) 1=(0,1) 2=(1,0) 3=(1,1) 4=(2,0) 5=(2,1)
    ///  |  \   |  \   |      edges: 0-1 0-2 1-2 1-3 2-3 2-4 3-4 3-5 4-5
    ///  0 ---- 2 ---- 4
    /// ```
    fn ladder(frames: &[[f32; 18]]) -> Animation {
        Animation::from_parts(6, vec![[0, 2, 1], [1, 2, 3], [2, 4, 3], [3, 4, 5]], frames.concat(), 30.0).unwrap()
    }

    const LADDER: [f32; 18] = [0., 0., 0., 0., 1., 0., 1., 0., 0., 1., 1., 0., 2., 0., 0., 2., 1., 0.];

    #[test]
    fn neighbourhoods_by_hand() {
        let edges = unique_edges(&[[0, 2, 1], [1, 2, 3], [2, 4, 3], [3, 4, 5]]);
        assert_eq!(edges, vec![[0, 1], [0, 2], [1, 2], [1, 3], [2, 3], [2, 4], [3, 4], [3, 5], [4, 5]]);
        let sorted = |h: &Neighbourhoods, v: usize| {
            let mut l = h.of(v).to_vec();
            l.sort();
            l
        };
        let one = Neighbourhoods::new(6, &edges, 1).unwrap();
        // R(0) = {0, 1, 2}: every edge touching it — 0-1, 0-2, 1-2, and the edges leaving the
        // ring 1-3, 2-3, 2-4 (ids 0..=5); not 3-4, 3-5, 4-5.
        assert_eq!(sorted(&one, 0), vec![0, 1, 2, 3, 4, 5]);
        // R(5) = {3, 4, 5}: 1-3, 2-3, 2-4, 3-4, 3-5, 4-5.
        assert_eq!(sorted(&one, 5), vec![3, 4, 5, 6, 7, 8]);
        // R(2) = {0, 1, 2, 3, 4} touches every edge.
        assert_eq!(sorted(&one, 2), (0..9).collect::<Vec<_>>());
        // Two rings from 0: R = {0..=4}, every edge.
        assert_eq!(sorted(&Neighbourhoods::new(6, &edges, 2).unwrap(), 0), (0..9).collect::<Vec<_>>());
    }

    /// One frame; the candidate moves vertex 4 from (2,0) to (2.5,0), w = 1. Relative
    /// differences d = (L − L')/L: 2-4: (1 − 1.5)/1 = −0.5; 3-4: (√2 − √3.25)/√2 = −0.2747549;
    /// 4-5: (1 − √1.25)/1 = −0.1180340; every other edge 0.
    /// Vertex 0 pins the neighbourhood rule: N(0) = {0-1, 0-2, 1-2, 1-3, 2-3, 2-4} (edges
    /// touching R(0) = {0,1,2}), W = 5 + √2 = 6.4142136, only 2-4 moved:
    /// μ = −0.5/W = −0.0779519, σ² = ((W − 1)·μ² + (−0.5 − μ)²)/W, σ_0 = 0.1813820. (Had the
    /// neighbourhood been the edges with both ends in R(0), σ_0 would be 0.)
    /// The others, computed the same way: σ_1 = 0.1740124 (N: 8 edges, all but 4-5),
    /// σ_2 = σ_3 = 0.1650062 (all 9), σ_4 = 0.1702597 (all but 0-1), σ_5 = 0.1821112
    /// (1-3, 2-3, 2-4, 3-4, 3-5, 4-5). S = mean = 0.1729629. One frame: T undefined.
    #[test]
    fn spatial_by_hand_one_ring() {
        let mut moved = LADDER;
        moved[12] = 2.5;
        let res = sted_with_fields(&ladder(&[LADDER]), &ladder(&[moved]), &StedParams::default()).unwrap();
        let s2 = 2f64.sqrt();
        let w0 = 5.0 + s2;
        let mu0 = -0.5 / w0;
        let sig0 = (((w0 - 1.0) * mu0 * mu0 + (-0.5 - mu0).powi(2)) / w0).sqrt();
        assert!(close(sig0, 0.1813820, 1e-7), "{sig0}");
        let expect = [sig0, 0.1740124, 0.1650062, 0.1650062, 0.1702597, 0.1821112];
        for (v, (&got, &want)) in res.spatial_per_vertex.iter().zip(&expect).enumerate() {
            assert!(close(got, want, 1e-7), "vertex {v}: {:?}", res.spatial_per_vertex);
        }
        assert!(close(res.spatial, 0.1729629, 1e-7), "{}", res.spatial);
        assert!(!res.temporal_defined && res.temporal == 0.0 && res.sted == res.spatial);
        assert_eq!((res.edge_count, res.empty_vertex_frames), (9, 0));
        // Absolute differences: the same edges moved, all by shrinking, so |d| = −d and σ is
        // unchanged.
        let abs = StedParams { spatial_difference: EdgeDifference::Absolute, ..Default::default() };
        let res_abs = sted(&ladder(&[LADDER]), &ladder(&[moved]), &abs).unwrap();
        assert!(close(res_abs.spatial, res.spatial, 1e-12));
    }

    /// Three frames of the same ladder translated along z: the reference by 0.3 then 0.2, the
    /// candidate by 0.4 then 0.1. D = diameter of reference frame 0 = |(0,0)−(2,1)| = √5;
    /// dt = 0.1. Temporal edge lengths (every vertex alike), ℓ^g = sqrt((Δz/D)² + dt²):
    /// reference ℓ¹ = √0.028 = 0.1673320, ℓ² = √0.018 = 0.1341641; candidate ℓ'¹ = √0.042 =
    /// 0.2049390, ℓ'² = √0.012 = 0.1095445.
    /// k = 1: windows g ∈ {1, 2} for f = 1 and {2} for f = 2:
    ///   T = (|ℓ'¹ − ℓ¹| / ((ℓ¹ + ℓ²)/2) + |ℓ'² − ℓ²| / ℓ²) / 2 = 0.216486365.
    /// k = 5 (default): both windows {1, 2}: T = (|ℓ'¹ − ℓ¹| + |ℓ'² − ℓ²|) / (ℓ¹ + ℓ²) = 0.206392655.
    /// The shapes are exact, so S = 0 and STED = c·T.
    #[test]
    fn temporal_by_hand() {
        let up = |dz: f32| {
            let mut f = LADDER;
            for v in 0..6 {
                f[3 * v + 2] += dz;
            }
            f
        };
        let r = ladder(&[LADDER, up(0.3), up(0.5)]);
        let c = ladder(&[LADDER, up(0.4), up(0.5)]);
        for (k, want) in [(1, 0.216486365), (5, 0.206392655)] {
            let p = StedParams { dt: 0.1, speed_window: k, c: 2.0, ..StedParams::default() };
            let res = sted(&r, &c, &p).unwrap();
            assert!(close(res.diameter, 5f64.sqrt(), 1e-12), "{}", res.diameter);
            // f32 positions: 0.3 and 0.4 are not exact in f32, so allow 1e-6.
            assert!(close(res.temporal, want, 1e-6), "k = {k}: {}", res.temporal);
            assert!(res.temporal_defined && res.spatial.abs() < 1e-7);
            assert!(close(res.sted, 2.0 * res.temporal, 1e-7));
            assert_eq!(res.params, p);
        }
    }

    /// The per-frame field averages to the spatial part, frame by frame and vertex by vertex.
    #[test]
    fn local_deviations_field_averages_to_the_spatial_part() {
        let mut moved = LADDER;
        moved[12] = 2.5;
        let (r, c) = (ladder(&[LADDER, LADDER]), ladder(&[LADDER, moved]));
        let field = sted_local_deviations(&r, &c, &StedParams::default()).unwrap();
        let res = sted_with_fields(&r, &c, &StedParams::default()).unwrap();
        assert_eq!(field.len(), 12);
        assert!(field[..6].iter().all(|&x| x == 0.0), "frame 0 is exact: {field:?}");
        assert!(close(field[6] as f64, 0.1813820, 1e-6), "{field:?}");
        let mean = field.iter().map(|&x| x as f64).sum::<f64>() / 12.0;
        assert!(close(mean, res.spatial, 1e-7));
        for v in 0..6 {
            assert!(close(field[6 + v] as f64 / 2.0, res.spatial_per_vertex[v], 1e-7));
        }
    }

    #[test]
    fn defaults_are_the_tools() {
        let p = StedParams::default();
        assert_eq!((p.ring_radius, p.dt, p.speed_window, p.c), (1, 0.0003, 5, 9.144e-5));
        assert_eq!(p.spatial_difference, EdgeDifference::Signed);
    }

    #[test]
    fn rejects_bad_params_and_point_clouds() {
        let r = ladder(&[LADDER]);
        for (p, field) in [
            (StedParams { ring_radius: 0, ..Default::default() }, "ring_radius"),
            (StedParams { ring_radius: 17, ..Default::default() }, "ring_radius"),
            (StedParams { dt: 0.0, ..Default::default() }, "dt"),
            (StedParams { dt: f64::NAN, ..Default::default() }, "dt"),
            (StedParams { speed_window: 0, ..Default::default() }, "speed_window"),
            (StedParams { speed_window: 1001, ..Default::default() }, "speed_window"),
            (StedParams { c: -1.0, ..Default::default() }, "c"),
            (StedParams { c: f64::INFINITY, ..Default::default() }, "c"),
            // Finite but giving NaN (dt² underflows) or infinity (c² overflows).
            (StedParams { dt: 1e-300, ..Default::default() }, "dt"),
            (StedParams { c: 1e300, ..Default::default() }, "c"),
        ] {
            let e = sted(&r, &r, &p).unwrap_err().to_string();
            assert!(e.contains("sted: parameter") && e.contains(field), "{e}");
        }
        let cloud = Animation::from_parts(6, vec![], LADDER.to_vec(), 30.0).unwrap();
        let e = sted(&cloud, &cloud, &StedParams::default()).unwrap_err().to_string();
        assert!(e.contains("no triangles"), "{e}");
    }

    #[test]
    fn degenerate_edges_count_as_empty_not_nan() {
        // Vertices 4 and 5 coincide with 2 and 3 in the reference: edges 2-4, 3-5 have length
        // 0 and weight 0; no NaN anywhere. A frame collapsed to one point has D = 0: the
        // temporal part is undefined, and every neighbourhood is empty (counted, contributing 0).
        let mut f = LADDER;
        f[12..18].copy_from_slice(&[1., 0., 0., 1., 1., 0.]);
        let mut g = f;
        g[0] = 0.1;
        let res = sted(&ladder(&[f, f]), &ladder(&[g, g]), &StedParams::default()).unwrap();
        assert!(res.spatial.is_finite() && res.spatial > 0.0 && res.temporal.is_finite());
        let point = [0.5f32; 18];
        let res = sted(&ladder(&[point, point]), &ladder(&[LADDER, LADDER]), &StedParams::default()).unwrap();
        assert_eq!((res.spatial, res.diameter, res.temporal_defined, res.empty_vertex_frames), (0.0, 0.0, false, 12));
    }

    /// The grid search returns the brute-force diameter, including on a sphere-like cloud where
    /// many pairs are near the maximum, and on flat and tiny inputs.
    #[test]
    fn diameter_matches_brute_force() {
        let brute = |f: &[f32]| {
            let n = f.len() / 3;
            let mut best = 0.0f64;
            for i in 0..n {
                for j in i + 1..n {
                    best = best.max(norm2(sub(point(f, i), point(f, j))));
                }
            }
            best.sqrt()
        };
        let mut sphere = Vec::new();
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..3000 {
            let (u, t) = (2.0 * rnd() - 1.0, std::f64::consts::TAU * rnd());
            let r = (1.0 - u * u).sqrt();
            sphere.extend([(r * t.cos()) as f32, (r * t.sin()) as f32, u as f32]);
        }
        let flat: Vec<f32> = (0..500).flat_map(|i| [(i % 25) as f32, (i / 25) as f32 * 0.5, 0.0]).collect();
        for (name, f) in [("sphere", &sphere[..]), ("flat", &flat[..]), ("ladder", &LADDER[..]), ("two", &LADDER[..6])]
        {
            assert_eq!(diameter(f), brute(f), "{name}");
        }
        assert_eq!(diameter(&LADDER[..3]), 0.0);
    }
}
