//! STED, the spatio-temporal edge difference of Váša & Skala, "A perception correlated
//! comparison method for dynamic meshes", IEEE TVCG 17(2), 2011.
//!
//! Reading used here (see `metrics/README.md` for the discussion and what could not be
//! checked against the paper's text):
//!
//! * **Spatial part.** For every mesh edge `e = (i, j)` and frame `t`, the reference length
//!   `l = ‖a_ti − a_tj‖`, the candidate length `l' = ‖â_ti − â_tj‖` and the relative edge
//!   difference `ed = |l' − l| / l` (or `(l' − l) / l` with [`EdgeDifference::Signed`]).
//!   For every vertex `v`, its neighbourhood `N_r(v)` is the set of edges whose two ends lie
//!   within `r` edge hops of `v` (`r = ring_radius`). The local deviation is the standard
//!   deviation of `ed` over `N_r(v)` weighted by the reference edge lengths:
//!   `μ = Σ l·ed / Σ l`, `σ_v,t = sqrt(Σ l·(ed − μ)² / Σ l)`. `STED_s` is the mean of
//!   `σ_v,t` over vertices and frames.
//! * **Temporal part.** The temporal edge of vertex `v` between frames `t` and `t+1` has the
//!   space-time length `m = sqrt(‖a_{t+1,v} − a_tv‖² + (dt·D)²)` where `D` is the reference's
//!   bounding-box diagonal over all frames (so `dt` is a fraction of the model size and the
//!   metric is scale invariant), likewise `m'` for the candidate with the same `dt·D`.
//!   `STED_t` is the mean over vertices and frame pairs of `|m' − m| / m`.
//! * **Combination.** `STED = sqrt(STED_s² + c²·STED_t²)`.
//!
//! Zero-length reference edges have zero weight and are skipped (their relative difference is
//! undefined); a vertex-frame whose neighbourhood has no edge of positive length is left out of
//! the mean and counted in [`StedResult::skipped_vertex_frames`].

use codec_core::{Animation, Error, Result};
use rayon::prelude::*;
use serde::Serialize;

use crate::common::{check_compatible, point, sub, unique_edges, vertex_dist2, CTX};

/// How a relative edge difference is formed in the spatial part.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum EdgeDifference {
    /// `|l' − l| / l` (default).
    Absolute,
    /// `(l' − l) / l`: a neighbourhood that is uniformly stretched scores 0 either way, but a
    /// neighbourhood with mixed stretching and shrinking scores higher than with `Absolute`.
    Signed,
}

/// Parameters of [`sted`]; all are reported with the result.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StedParams {
    /// Radius of the topological neighbourhood in edge hops (1 = the one-ring), 1..=16.
    /// Default 3.
    pub ring_radius: u32,
    /// Time step of the space-time edges as a fraction of the reference bounding-box
    /// diagonal, finite and > 0. Default 0.3.
    pub dt: f64,
    /// Weight of the temporal part, finite and ≥ 0. Default 0.5.
    pub c: f64,
    /// Signed or absolute relative edge differences in the spatial part. Default absolute.
    pub spatial_difference: EdgeDifference,
}

impl Default for StedParams {
    fn default() -> Self {
        Self { ring_radius: 3, dt: 0.3, c: 0.5, spatial_difference: EdgeDifference::Absolute }
    }
}

impl StedParams {
    /// Largest accepted `ring_radius` (the neighbourhood cost grows with its square).
    pub const MAX_RING_RADIUS: u32 = 16;

    /// Checks every field, naming the offending one.
    pub fn validate(&self) -> Result<()> {
        if !(1..=Self::MAX_RING_RADIUS).contains(&self.ring_radius) {
            return Err(Error::parameter(
                "sted",
                "ring_radius",
                format!("{} is outside 1..={}", self.ring_radius, Self::MAX_RING_RADIUS),
            ));
        }
        if !(self.dt.is_finite() && self.dt > 0.0) {
            return Err(Error::parameter("sted", "dt", format!("{} is not a finite positive number", self.dt)));
        }
        if !(self.c.is_finite() && self.c >= 0.0) {
            return Err(Error::parameter("sted", "c", format!("{} is not a finite non-negative number", self.c)));
        }
        Ok(())
    }
}

/// Result of [`sted`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StedResult {
    /// `sqrt(spatial² + c²·temporal²)`.
    pub sted: f64,
    /// `STED_s`, mean local deviation of relative edge differences.
    pub spatial: f64,
    /// `STED_t`, mean relative difference of space-time edge lengths (0 for one frame).
    pub temporal: f64,
    /// Parameters used.
    pub params: StedParams,
    /// Number of mesh edges.
    pub edge_count: usize,
    /// Vertex-frames left out of the spatial mean (no edge of positive length around them,
    /// e.g. vertices in no triangle).
    pub skipped_vertex_frames: usize,
    /// Per vertex: mean over frames of its local deviation `σ_v,t` (0 where it was never
    /// defined). Empty unless requested with [`sted_with_fields`].
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

/// Frames processed per parallel batch (bounds the memory of per-vertex fields).
const FRAME_BATCH: usize = 32;

fn run(reference: &Animation, candidate: &Animation, params: &StedParams, fields: bool) -> Result<StedResult> {
    check_compatible(reference, candidate)?;
    params.validate()?;
    let n = reference.vertex_count();
    let edges = unique_edges(reference.triangles());
    if edges.is_empty() {
        return Err(Error::InvalidAnimation(format!("{CTX}: STED needs mesh edges, but the mesh has no triangles")));
    }
    let hood = Neighbourhoods::new(n, &edges, params.ring_radius)?;
    let frames = reference.frame_count();

    // Spatial part, batches of frames in parallel, reduced in frame order.
    let mut sum = 0.0;
    let mut counted = 0usize;
    let mut pv_sum = vec![0.0; if fields { n } else { 0 }];
    let mut pv_count = vec![0u32; if fields { n } else { 0 }];
    for batch in (0..frames).collect::<Vec<_>>().chunks(FRAME_BATCH) {
        let results: Vec<Vec<f64>> = batch
            .par_iter()
            .map(|&t| local_deviations(reference.frame(t), candidate.frame(t), &edges, &hood, params))
            .collect();
        for sigma in results {
            for (v, &s) in sigma.iter().enumerate() {
                if s >= 0.0 {
                    sum += s;
                    counted += 1;
                    if fields {
                        pv_sum[v] += s;
                        pv_count[v] += 1;
                    }
                }
            }
        }
    }
    let spatial = if counted > 0 { sum / counted as f64 } else { 0.0 };

    // Temporal part.
    let step = params.dt * reference.bounding_box_diagonal();
    let step2 = step * step;
    let temporal = if frames < 2 || step2 == 0.0 {
        0.0
    } else {
        let per_pair: Vec<f64> = (0..frames - 1)
            .into_par_iter()
            .map(|t| {
                let (a0, a1, b0, b1) =
                    (reference.frame(t), reference.frame(t + 1), candidate.frame(t), candidate.frame(t + 1));
                (0..n)
                    .map(|v| {
                        let m = (vertex_dist2(a1, a0, v) + step2).sqrt();
                        let mc = (vertex_dist2(b1, b0, v) + step2).sqrt();
                        (mc - m).abs() / m
                    })
                    .sum::<f64>()
            })
            .collect();
        per_pair.iter().sum::<f64>() / ((frames - 1) * n) as f64
    };

    let spatial_per_vertex =
        pv_sum.iter().zip(&pv_count).map(|(&s, &c)| if c > 0 { s / c as f64 } else { 0.0 }).collect();
    Ok(StedResult {
        sted: (spatial * spatial + params.c * params.c * temporal * temporal).sqrt(),
        spatial,
        temporal,
        params: *params,
        edge_count: edges.len(),
        skipped_vertex_frames: frames * n - counted,
        spatial_per_vertex,
    })
}

/// Per vertex of one frame: the weighted standard deviation of relative edge differences over
/// its neighbourhood, or −1 where no neighbourhood edge has positive reference length.
fn local_deviations(a: &[f32], b: &[f32], edges: &[[u32; 2]], hood: &Neighbourhoods, p: &StedParams) -> Vec<f64> {
    // (weight = reference length, relative difference) per edge.
    let per_edge: Vec<(f64, f64)> = edges
        .iter()
        .map(|&[i, j]| {
            let (i, j) = (i as usize, j as usize);
            let l = norm(sub(point(a, i), point(a, j)));
            if l > 0.0 {
                let lc = norm(sub(point(b, i), point(b, j)));
                let d = (lc - l) / l;
                (l, if p.spatial_difference == EdgeDifference::Absolute { d.abs() } else { d })
            } else {
                (0.0, 0.0)
            }
        })
        .collect();
    (0..hood.len())
        .map(|v| {
            let list = hood.of(v);
            let (mut w, mut wd) = (0.0, 0.0);
            for &e in list {
                let (l, d) = per_edge[e as usize];
                w += l;
                wd += l * d;
            }
            if w <= 0.0 {
                return -1.0;
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
        .collect()
}

fn norm(x: [f64; 3]) -> f64 {
    (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt()
}

/// Vertices whose neighbourhoods are gathered per parallel batch.
const HOOD_BLOCK: usize = 1 << 16;
/// Most neighbourhood entries (edge ids, 4 bytes each: 1 GiB) before giving up: a large radius
/// on a large mesh grows as `V · radius²`.
const MAX_HOOD_ENTRIES: usize = 1 << 28;

/// For every vertex, the edges with both ends within `radius` hops (CSR).
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
                        // Breadth-first search to `radius` hops; `stamp[w] == v` marks visited.
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
                        let mut out = Vec::new();
                        for &u in queue.iter() {
                            for &(w, e) in adj_of(u as usize) {
                                if u < w && stamp[w as usize] == v as u32 {
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

    /// A strip of two triangles (0,1,2),(1,3,2):
    /// ```text
    ///  2 ---- 3        0=(0,0,0) 1=(1,0,0) 2=(0,1,0) 3=(1,1,0)
    ///  | \    |        edges: 0-1, 0-2, 1-2, 1-3, 2-3
    ///  |   \  |
    ///  0 ---- 1
    /// ```
    fn strip(frames: &[[f32; 12]]) -> Animation {
        Animation::from_parts(4, vec![[0, 1, 2], [1, 3, 2]], frames.concat(), 30.0).unwrap()
    }

    const BASE: [f32; 12] = [0., 0., 0., 1., 0., 0., 0., 1., 0., 1., 1., 0.];

    #[test]
    fn neighbourhoods_by_hand() {
        let edges = unique_edges(&[[0, 1, 2], [1, 3, 2]]);
        assert_eq!(edges, vec![[0, 1], [0, 2], [1, 2], [1, 3], [2, 3]]);
        let h = Neighbourhoods::new(4, &edges, 1).unwrap();
        let sorted = |v: usize| {
            let mut l = h.of(v).to_vec();
            l.sort();
            l
        };
        // One-ring of 0 is {0,1,2}: edges 0-1, 0-2, 1-2 → ids 0,1,2.
        assert_eq!(sorted(0), vec![0, 1, 2]);
        // One-ring of 1 is everything: all five edges.
        assert_eq!(sorted(1), vec![0, 1, 2, 3, 4]);
        // One-ring of 3 is {1,2,3}: edges 1-2, 1-3, 2-3 → ids 2,3,4.
        assert_eq!(sorted(3), vec![2, 3, 4]);
        assert_eq!(sorted(0), {
            let mut l = Neighbourhoods::new(4, &edges, 2).unwrap().of(3).to_vec();
            l.retain(|&e| [0, 1, 2].contains(&e));
            l.sort();
            l
        });
    }

    /// One frame; candidate moves vertex 3 from (1,1,0) to (1,1.5,0), ring radius 1.
    /// Reference lengths: 0-1: 1, 0-2: 1, 1-2: √2, 1-3: 1, 2-3: 1.
    /// Candidate: 1-3 becomes 1.5 (ed = 0.5); 2-3 becomes sqrt(1 + 0.25) = 1.1180340 (ed =
    /// 0.1180340); the others are unchanged (ed = 0).
    /// Vertex 0, edges {0-1, 0-2, 1-2}: all ed = 0 → σ = 0.
    /// Vertex 3, edges {1-2, 1-3, 2-3} with weights (√2, 1, 1), ed (0, 0.5, 0.1180340):
    ///   W = 3.4142136, μ = (0.5 + 0.1180340)/W = 0.1810180,
    ///   σ² = (√2·μ² + (0.5 − μ)² + (0.1180340 − μ)²)/W
    ///      = (0.0463402 + 0.1017495 + 0.0039670)/3.4142136 = 0.0445364, σ = 0.2110365.
    /// Vertices 1 and 2, all five edges, weights (1, 1, √2, 1, 1), W = 5.4142136:
    ///   μ = 0.6180340/W = 0.1141503,
    ///   σ² = ((2 + √2)·μ² + (0.5 − μ)² + (0.1180340 − μ)²)/W
    ///      = (0.0444882 + 0.1488800 + 0.0000151)/5.4142136 = 0.0357177, σ = 0.1889913.
    /// STED_s = (0 + 2·0.1889913 + 0.2110365)/4 = 0.1472548. One frame → STED_t = 0.
    #[test]
    fn spatial_by_hand_one_ring() {
        let mut moved = BASE;
        moved[10] = 1.5;
        let r = strip(&[BASE]);
        let c = strip(&[moved]);
        let p = StedParams { ring_radius: 1, ..StedParams::default() };
        let res = sted_with_fields(&r, &c, &p).unwrap();
        let e23 = 1.25f64.sqrt() - 1.0;
        let s2 = 2f64.sqrt();
        // Vertex 3.
        let w3 = s2 + 2.0;
        let mu3 = (0.5 + e23) / w3;
        let sig3 = ((s2 * mu3 * mu3 + (0.5 - mu3).powi(2) + (e23 - mu3).powi(2)) / w3).sqrt();
        assert!(close(sig3, 0.2110365, 1e-6), "{sig3}");
        // Vertices 1 and 2: two unit edges and the diagonal with ed = 0, plus 1-3 and 2-3.
        let w1 = s2 + 4.0;
        let mu1 = (0.5 + e23) / w1;
        let sig1 = (((2.0 + s2) * mu1 * mu1 + (0.5 - mu1).powi(2) + (e23 - mu1).powi(2)) / w1).sqrt();
        assert!(close(sig1, 0.1889913, 1e-6), "{sig1}");
        let expect = [0.0, sig1, sig1, sig3];
        for (v, (&got, &want)) in res.spatial_per_vertex.iter().zip(&expect).enumerate() {
            assert!(close(got, want, 1e-7), "vertex {v}: {:?}", res.spatial_per_vertex);
        }
        let mean = expect.iter().sum::<f64>() / 4.0;
        assert!(close(mean, 0.1472548, 1e-6));
        assert!(close(res.spatial, mean, 1e-7) && res.temporal == 0.0 && close(res.sted, mean, 1e-7));
        assert_eq!(res.edge_count, 5);
        assert_eq!(res.skipped_vertex_frames, 0);
    }

    /// Two frames of the same shape; the reference translates by (0,0,0.3) between them, the
    /// candidate by (0,0,0.4). Bounding box of the reference: [0,1]×[0,1]×[0,0.3], diagonal
    /// D = sqrt(2.09). With dt = 0.5: step = 0.5·D, step² = 0.5225.
    /// Reference temporal length m = sqrt(0.09 + 0.5225) = sqrt(0.6125) = 0.7826238;
    /// candidate m' = sqrt(0.16 + 0.5225) = sqrt(0.6825) = 0.8261356.
    /// Every vertex: |m' − m|/m = 0.0555975. STED_t = 0.0555975; STED_s = 0 (shape is exact);
    /// STED = c·STED_t = 2·0.0555975 with c = 2.
    #[test]
    fn temporal_by_hand() {
        let up = |dz: f32| {
            let mut f = BASE;
            for v in 0..4 {
                f[3 * v + 2] += dz;
            }
            f
        };
        let r = strip(&[BASE, up(0.3)]);
        let c = strip(&[BASE, up(0.4)]);
        let p = StedParams { dt: 0.5, c: 2.0, ..StedParams::default() };
        let res = sted(&r, &c, &p).unwrap();
        let m = (0.09f64 + 0.5225).sqrt();
        let mc = (0.16f64 + 0.5225).sqrt();
        // f32 positions: 0.3 and 0.4 are not exact in f32, so allow 1e-7.
        assert!(close(res.temporal, (mc - m) / m, 1e-7), "{}", res.temporal);
        assert!(close(res.temporal, 0.0555975, 1e-6));
        assert!(res.spatial.abs() < 1e-7);
        assert!(close(res.sted, 2.0 * res.temporal, 1e-7));
        assert_eq!(res.params, p);
    }

    #[test]
    fn rejects_bad_params_and_point_clouds() {
        let r = strip(&[BASE]);
        for p in [
            StedParams { ring_radius: 0, ..Default::default() },
            StedParams { ring_radius: 17, ..Default::default() },
            StedParams { dt: 0.0, ..Default::default() },
            StedParams { dt: f64::NAN, ..Default::default() },
            StedParams { c: -1.0, ..Default::default() },
            StedParams { c: f64::INFINITY, ..Default::default() },
        ] {
            let e = sted(&r, &r, &p).unwrap_err().to_string();
            assert!(e.contains("sted: parameter"), "{e}");
        }
        let cloud = Animation::from_parts(4, vec![], BASE.to_vec(), 30.0).unwrap();
        let e = sted(&cloud, &cloud, &StedParams::default()).unwrap_err().to_string();
        assert!(e.contains("no triangles"), "{e}");
    }

    #[test]
    fn degenerate_edges_are_skipped_not_nan() {
        // Vertices 2 and 3 coincide in the reference: edge 2-3 has length 0 and is skipped;
        // no NaN anywhere.
        let mut f = BASE;
        f[9..12].copy_from_slice(&[0., 1., 0.]);
        let r = strip(&[f]);
        let mut g = f;
        g[0] = 0.1;
        let res = sted(&r, &strip(&[g]), &StedParams { ring_radius: 1, ..Default::default() }).unwrap();
        assert!(res.spatial.is_finite() && res.spatial > 0.0);
    }
}
