//! Symmetric Hausdorff distance between the surfaces of two frames, vertices to surface.
//!
//! For each frame `t`, `h_t = max( max_{v} d(a_tv, S(B_t)), max_{v} d(b_tv, S(A_t)) )` where
//! `S(X)` is the union of the triangles of frame `X` and `d` the Euclidean point-to-triangle
//! distance. Only vertices are sampled on the source side (the usual vertex-based Hausdorff of
//! the codec papers, not Metro's dense surface sampling), so this is a lower bound of the
//! surface-to-surface Hausdorff distance, exact when the maximum sits at a vertex.
//!
//! A bounding-volume hierarchy over triangle bounding boxes (median split on the longest
//! centroid axis) is built once on the reference's first frame and refitted to every frame of
//! both animations (same connectivity); every query runs a branch-and-bound search whose bound
//! starts at the distance to the triangles incident to the *corresponding* vertex in the other
//! frame (same index, same connectivity), which is usually already the answer, so most of the
//! tree is pruned at once. For the per-frame maximum most searches are not even needed: see
//! `directed_max2`.
//!
//! Meshes without triangles fall back to point-to-point distances (each point is a
//! degenerate triangle); [`HausdorffMode`] records which was used.

use codec_core::{Animation, Result};
use rayon::prelude::*;
use serde::Serialize;

use crate::common::{check_compatible, dot, norm2, point, sub};

/// Which distance the Hausdorff computation used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum HausdorffMode {
    /// Vertices to the triangles of the other surface.
    PointToTriangle,
    /// The mesh has no triangles: vertices to the vertices of the other frame.
    PointToPoint,
}

/// Per-frame symmetric Hausdorff distances and their summaries.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HausdorffStats {
    /// Largest per-frame distance.
    pub max: f64,
    /// Mean over frames of the per-frame distance.
    pub mean: f64,
    /// `max / diag` (reference bounding-box diagonal over all frames); `None` if it is zero.
    pub max_relative: Option<f64>,
    /// `mean / diag`; `None` if the diagonal is zero.
    pub mean_relative: Option<f64>,
    /// The symmetric distance of every frame.
    pub per_frame: Vec<f64>,
    /// Distance used.
    pub mode: HausdorffMode,
}

/// Computes [`HausdorffStats`]; fails if the animations do not match.
pub fn hausdorff(reference: &Animation, candidate: &Animation) -> Result<HausdorffStats> {
    check_compatible(reference, candidate)?;
    let surface = FrameSurface::new(reference.triangles(), reference.frame(0));
    let per_frame: Vec<f64> = (0..reference.frame_count())
        .into_par_iter()
        .map(|t| surface.distance(reference.frame(t), candidate.frame(t)))
        .collect();
    let max = per_frame.iter().copied().fold(0.0, f64::max);
    let mean = per_frame.iter().sum::<f64>() / per_frame.len() as f64;
    Ok(summarize_hausdorff(max, mean, reference.bounding_box_diagonal(), surface.mode, per_frame))
}

/// [`HausdorffStats`] from the largest and the mean per-frame distance and the reference's
/// bounding-box diagonal `diag`.
pub(crate) fn summarize_hausdorff(
    max: f64,
    mean: f64,
    diag: f64,
    mode: HausdorffMode,
    per_frame: Vec<f64>,
) -> HausdorffStats {
    let rel = |x: f64| (diag > 0.0).then(|| x / diag);
    HausdorffStats { max, mean, max_relative: rel(max), mean_relative: rel(mean), per_frame, mode }
}

/// What the per-frame distance needs of the shared connectivity: the searched triangles, the
/// triangles incident to every vertex and the tree shape (built on the reference's first
/// frame). `O(T + V)` memory, the same for every frame.
pub(crate) struct FrameSurface {
    triangles: Vec<[u32; 3]>,
    incidence: Incidence,
    shape: BvhShape,
    /// Distance used.
    pub(crate) mode: HausdorffMode,
}

impl FrameSurface {
    /// The search structures for `triangles` (indices checked by the topology), the tree shaped
    /// on `first_frame` (interleaved xyz of every vertex).
    pub(crate) fn new(triangles: &[[u32; 3]], first_frame: &[f32]) -> Self {
        let n = first_frame.len() / 3;
        let (triangles, mode) = surface_triangles(triangles, n);
        let incidence = Incidence::new(&triangles, n);
        let shape = BvhShape::build(first_frame, &triangles);
        Self { triangles, incidence, shape, mode }
    }

    /// The symmetric distance between reference frame `a` and candidate frame `b`.
    pub(crate) fn distance(&self, a: &[f32], b: &[f32]) -> f64 {
        let ab = directed_max2(a, b, &self.triangles, &self.incidence, &self.shape, 0.0);
        directed_max2(b, a, &self.triangles, &self.incidence, &self.shape, ab).sqrt()
    }

    /// Bytes held for `n` vertices and `t` triangles (an upper bound: the searched list adds
    /// at most one point per vertex, and median splits down to leaves of 2 to 4 triangles make
    /// at most one node per triangle), and the transient bytes of one [`Self::distance`] call.
    pub(crate) fn bytes(n: usize, t: usize) -> (u64, u64) {
        let (n, tris) = (n as u64, (t + n) as u64);
        // Triangles 12 B, incidence 4 B per corner + 4 B per vertex, tree shape 8 B per node
        // + 4 B per triangle.
        let held = tris * 12 + (3 * tris + n + 1) * 4 + tris * (8 + 4);
        // A refitted tree (72 B of corners per triangle, 56 B per node) and the visit order
        // (16 B per vertex), for one direction at a time.
        let transient = tris * (72 + 56) + n * 16;
        (held, transient)
    }
}

/// Distance from every vertex of `from` to the surface `(to, triangles)` (one frame each,
/// interleaved xyz, same vertex count). With no triangles, distances to the nearest point of
/// `to`. Useful for heatmaps of one frame and for checking against brute force.
pub fn vertex_to_surface_distances(from: &[f32], to: &[f32], triangles: &[[u32; 3]]) -> Result<Vec<f64>> {
    let n = to.len() / 3;
    if from.len() != to.len() || !to.len().is_multiple_of(3) || n == 0 {
        return Err(codec_core::Error::InvalidAnimation(format!(
            "{}: frames of {} and {} coordinates cannot be compared vertex to surface",
            crate::common::CTX,
            from.len(),
            to.len()
        )));
    }
    if let Some(t) = triangles.iter().position(|t| t.iter().any(|&i| i as usize >= n)) {
        return Err(codec_core::Error::InvalidAnimation(format!(
            "{}: triangle {t} has an index out of range for {n} vertices",
            crate::common::CTX
        )));
    }
    let (tris, _) = surface_triangles(triangles, n);
    let inc = Incidence::new(&tris, n);
    let bvh = Bvh::refit(&BvhShape::build(to, &tris), to, &tris);
    Ok((0..n).map(|v| nearest2(&bvh, to, &tris, &inc, point(from, v), v).sqrt()).collect())
}

/// The triangle list to search: the mesh's triangles plus one degenerate triangle `[v, v, v]`
/// per vertex in no triangle, so an isolated vertex is measured as the point it is (without
/// it, an isolated vertex of one frame is compared with the other frame's *surface* alone, and
/// an animation measured against itself reports 40 % of its bounding box). For a
/// point cloud (no triangles at all) every vertex is such a point.
pub(crate) fn surface_triangles(triangles: &[[u32; 3]], n: usize) -> (Vec<[u32; 3]>, HausdorffMode) {
    let mut used = vec![false; n];
    for t in triangles {
        for &i in t {
            if let Some(u) = used.get_mut(i as usize) {
                *u = true;
            }
        }
    }
    let mut all = triangles.to_vec();
    all.extend((0..n as u32).filter(|&v| !used[v as usize]).map(|v| [v, v, v]));
    let mode = if triangles.is_empty() { HausdorffMode::PointToPoint } else { HausdorffMode::PointToTriangle };
    (all, mode)
}

/// How many vertices are in no triangle (measured as points by [`hausdorff`]).
pub fn isolated_vertex_count(triangles: &[[u32; 3]], n: usize) -> usize {
    let mut used = vec![false; n];
    for t in triangles {
        for &i in t {
            if let Some(u) = used.get_mut(i as usize) {
                *u = true;
            }
        }
    }
    used.iter().filter(|u| !**u).count()
}

/// `max(floor, max_v d²(from_v, surface of to))`, exactly, with most searches skipped.
///
/// Two upper bounds of a vertex's distance to the other surface are cheap: `w_v`, its
/// distance to the corresponding vertex, and the tighter `u_v ≤ w_v`, its distance to the
/// triangles incident to that vertex (both lie on the surface when the vertex is in a
/// triangle). Visiting vertices by decreasing `w_v`, the loop stops once `w_v` is no larger
/// than the maximum found so far (no later vertex can raise it), skips the search when `u_v`
/// is no larger, and only searches the tree (fitted to the frame on first use) otherwise.
/// The result is the value an exhaustive search returns.
fn directed_max2(from: &[f32], to: &[f32], tris: &[[u32; 3]], inc: &Incidence, shape: &BvhShape, floor: f64) -> f64 {
    let n = from.len() / 3;
    let mut order: Vec<(f64, u32)> = (0..n)
        .map(|v| {
            // A vertex in no triangle is not on the surface: no cheap bound.
            let w = if inc.of(v).is_empty() { f64::INFINITY } else { norm2(sub(point(from, v), point(to, v))) };
            (w, v as u32)
        })
        .collect();
    order.sort_unstable_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
    let mut max = floor;
    let mut bvh = None;
    for &(w, v) in &order {
        if w <= max {
            break;
        }
        let p = point(from, v as usize);
        let u = incident2(to, tris, inc, p, v as usize);
        if u <= max {
            continue;
        }
        let bvh = bvh.get_or_insert_with(|| Bvh::refit(shape, to, tris));
        max = max.max(bvh.nearest2(p, u));
    }
    max
}

/// Squared distance from `p` to the triangles of `frame` incident to vertex `v`; infinite for
/// a vertex in no triangle.
fn incident2(frame: &[f32], tris: &[[u32; 3]], inc: &Incidence, p: [f64; 3], v: usize) -> f64 {
    let mut best = f64::INFINITY;
    for &t in inc.of(v) {
        let [i, j, k] = tris[t as usize];
        best = best.min(point_triangle_dist2(
            p,
            point(frame, i as usize),
            point(frame, j as usize),
            point(frame, k as usize),
        ));
    }
    best
}

/// Squared distance from `p` to the surface, starting the bound from the triangles incident
/// to vertex `v` (the vertex corresponding to `p`).
fn nearest2(bvh: &Bvh, frame: &[f32], tris: &[[u32; 3]], inc: &Incidence, p: [f64; 3], v: usize) -> f64 {
    bvh.nearest2(p, incident2(frame, tris, inc, p, v))
}

/// Triangles incident to each vertex (CSR).
struct Incidence {
    start: Vec<u32>,
    tris: Vec<u32>,
}

impl Incidence {
    fn new(triangles: &[[u32; 3]], n: usize) -> Self {
        let mut start = vec![0u32; n + 1];
        for t in triangles {
            for &i in t {
                start[i as usize + 1] += 1;
            }
        }
        for v in 0..n {
            start[v + 1] += start[v];
        }
        let mut fill = start.clone();
        let mut tris = vec![0u32; start[n] as usize];
        for (ti, t) in triangles.iter().enumerate() {
            for &i in t {
                tris[fill[i as usize] as usize] = ti as u32;
                fill[i as usize] += 1;
            }
        }
        Self { start, tris }
    }

    fn of(&self, v: usize) -> &[u32] {
        &self.tris[self.start[v] as usize..self.start[v + 1] as usize]
    }
}

#[derive(Clone, Copy)]
struct Node {
    lo: [f64; 3],
    hi: [f64; 3],
    /// Leaf: first primitive; inner: index of the right child (the left child follows the node).
    index: u32,
    /// Number of primitives of a leaf; 0 for inner nodes.
    count: u32,
}

/// Shape of a bounding-volume hierarchy over triangles: built once from one frame, then
/// refitted to every frame ([`Bvh::refit`]). The connectivity is shared by all frames, so a
/// tree that groups nearby triangles in one pose still groups connected patches in another;
/// deformation only loosens the boxes, which costs search time, never correctness.
struct BvhShape {
    /// `(index, count)` of every node in pre-order (children after their parent).
    nodes: Vec<(u32, u32)>,
    /// Triangle ids in leaf order.
    order: Vec<u32>,
}

/// Greatest nesting of a [`BvhShape`]: median splits halve the count down to `LEAF_SIZE`, so
/// the depth is at most log2 of the triangle count (< 32 for `u32` counts).
const MAX_DEPTH: usize = 64;
const LEAF_SIZE: usize = 4;

impl BvhShape {
    fn build(frame: &[f32], triangles: &[[u32; 3]]) -> Self {
        // (triangle id, centroid of its bounding box)
        let mut items: Vec<(u32, [f64; 3])> = triangles
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let (lo, hi) =
                    tri_box(&[point(frame, t[0] as usize), point(frame, t[1] as usize), point(frame, t[2] as usize)]);
                (i as u32, [(lo[0] + hi[0]) * 0.5, (lo[1] + hi[1]) * 0.5, (lo[2] + hi[2]) * 0.5])
            })
            .collect();
        let mut nodes = Vec::with_capacity(2 * items.len() / LEAF_SIZE + 1);

        fn recurse(items: &mut [(u32, [f64; 3])], offset: usize, nodes: &mut Vec<(u32, u32)>) {
            let me = nodes.len();
            nodes.push((offset as u32, items.len() as u32));
            if items.len() <= LEAF_SIZE {
                return;
            }
            let mut lo = [f64::INFINITY; 3];
            let mut hi = [f64::NEG_INFINITY; 3];
            for (_, c) in items.iter() {
                for k in 0..3 {
                    lo[k] = lo[k].min(c[k]);
                    hi[k] = hi[k].max(c[k]);
                }
            }
            let ext = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
            let axis = if ext[0] >= ext[1] && ext[0] >= ext[2] {
                0
            } else if ext[1] >= ext[2] {
                1
            } else {
                2
            };
            let mid = items.len() / 2;
            // Median split (ties broken by triangle id, so the shape is deterministic); with all
            // centroids equal the halves are arbitrary but still valid.
            items.select_nth_unstable_by(mid, |a, b| a.1[axis].total_cmp(&b.1[axis]).then(a.0.cmp(&b.0)));
            let (left, right) = items.split_at_mut(mid);
            recurse(left, offset, nodes);
            let r = nodes.len();
            recurse(right, offset + mid, nodes);
            nodes[me] = (r as u32, 0);
        }

        if !items.is_empty() {
            recurse(&mut items, 0, &mut nodes);
        }
        Self { nodes, order: items.iter().map(|it| it.0).collect() }
    }
}

fn tri_box(t: &[[f64; 3]; 3]) -> ([f64; 3], [f64; 3]) {
    let [p, q, r] = t;
    (
        [p[0].min(q[0]).min(r[0]), p[1].min(q[1]).min(r[1]), p[2].min(q[2]).min(r[2])],
        [p[0].max(q[0]).max(r[0]), p[1].max(q[1]).max(r[1]), p[2].max(q[2]).max(r[2])],
    )
}

/// A [`BvhShape`] fitted to the triangles of one frame.
struct Bvh {
    nodes: Vec<Node>,
    /// Triangle corners in leaf order.
    prims: Vec<[[f64; 3]; 3]>,
}

impl Bvh {
    fn refit(shape: &BvhShape, frame: &[f32], triangles: &[[u32; 3]]) -> Self {
        let prims: Vec<[[f64; 3]; 3]> = shape
            .order
            .iter()
            .map(|&i| {
                let t = triangles[i as usize];
                [point(frame, t[0] as usize), point(frame, t[1] as usize), point(frame, t[2] as usize)]
            })
            .collect();
        let mut nodes: Vec<Node> =
            shape.nodes.iter().map(|&(index, count)| Node { lo: [0.0; 3], hi: [0.0; 3], index, count }).collect();
        // Children follow their parent, so a reverse sweep sees both children before the parent.
        for i in (0..nodes.len()).rev() {
            let n = nodes[i];
            let (lo, hi) = if n.count > 0 {
                let mut lo = [f64::INFINITY; 3];
                let mut hi = [f64::NEG_INFINITY; 3];
                for t in &prims[n.index as usize..(n.index + n.count) as usize] {
                    let (l, h) = tri_box(t);
                    for k in 0..3 {
                        lo[k] = lo[k].min(l[k]);
                        hi[k] = hi[k].max(h[k]);
                    }
                }
                (lo, hi)
            } else {
                let (a, b) = (&nodes[i + 1], &nodes[n.index as usize]);
                ([0, 1, 2].map(|k| a.lo[k].min(b.lo[k])), [0, 1, 2].map(|k| a.hi[k].max(b.hi[k])))
            };
            nodes[i].lo = lo;
            nodes[i].hi = hi;
        }
        Self { nodes, prims }
    }

    /// Smallest squared distance from `p` to any triangle, or `best` if none is closer.
    fn nearest2(&self, p: [f64; 3], mut best: f64) -> f64 {
        if self.nodes.is_empty() {
            return best;
        }
        let mut stack = [(0u32, 0.0f64); MAX_DEPTH];
        let mut top = 1;
        stack[0] = (0, box_dist2(&self.nodes[0], p));
        while top > 0 {
            top -= 1;
            let (i, d) = stack[top];
            if d >= best {
                continue;
            }
            let node = &self.nodes[i as usize];
            if node.count > 0 {
                let first = node.index as usize;
                for tri in &self.prims[first..first + node.count as usize] {
                    best = best.min(point_triangle_dist2(p, tri[0], tri[1], tri[2]));
                }
                continue;
            }
            let (l, r) = (i + 1, node.index);
            let (dl, dr) = (box_dist2(&self.nodes[l as usize], p), box_dist2(&self.nodes[r as usize], p));
            // Push the farther child first so the nearer one is searched first.
            let (near, far) = if dl <= dr { ((l, dl), (r, dr)) } else { ((r, dr), (l, dl)) };
            if far.1 < best {
                stack[top] = far;
                top += 1;
            }
            if near.1 < best {
                stack[top] = near;
                top += 1;
            }
        }
        best
    }
}

fn box_dist2(n: &Node, p: [f64; 3]) -> f64 {
    let mut d = 0.0;
    for ((lo, hi), x) in n.lo.iter().zip(&n.hi).zip(&p) {
        let e = (lo - x).max(x - hi).max(0.0);
        d += e * e;
    }
    d
}

/// `num / den` clamped to `[0, 1]`, 0 when `den` is not positive (degenerate edge).
#[inline]
fn ratio(num: f64, den: f64) -> f64 {
    if den > 0.0 {
        (num / den).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

fn point_segment_dist2(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let ab = sub(b, a);
    let s = ratio(dot(sub(p, a), ab), norm2(ab));
    norm2(sub(p, [a[0] + s * ab[0], a[1] + s * ab[1], a[2] + s * ab[2]]))
}

/// Euclidean distance from `p` to the (filled) triangle `abc`; degenerate triangles are
/// treated as the union of their edges. Exported for brute-force checks.
pub fn point_triangle_distance(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    point_triangle_dist2(p, a, b, c).sqrt()
}

/// Squared distance from `p` to triangle `abc`: the Voronoi-region walk of Ericson,
/// *Real-Time Collision Detection* §5.1.5, with degenerate triangles (zero area: repeated
/// or collinear corners) handled as the union of their three edges, so no input gives NaN.
pub(crate) fn point_triangle_dist2(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let ab = sub(b, a);
    let ac = sub(c, a);
    let n = [ab[1] * ac[2] - ab[2] * ac[1], ab[2] * ac[0] - ab[0] * ac[2], ab[0] * ac[1] - ab[1] * ac[0]];
    if norm2(n) == 0.0 {
        return point_segment_dist2(p, a, b).min(point_segment_dist2(p, b, c)).min(point_segment_dist2(p, c, a));
    }
    let at = |s: f64, u: [f64; 3], o: [f64; 3]| [o[0] + s * u[0], o[1] + s * u[1], o[2] + s * u[2]];
    let ap = sub(p, a);
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return norm2(ap);
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return norm2(bp);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return norm2(sub(p, at(ratio(d1, d1 - d3), ab, a)));
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return norm2(cp);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return norm2(sub(p, at(ratio(d2, d2 - d6), ac, a)));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return norm2(sub(p, at(ratio(d4 - d3, (d4 - d3) + (d5 - d6)), sub(c, b), b)));
    }
    let sum = va + vb + vc;
    let (v, w) = if sum > 0.0 { (vb / sum, vc / sum) } else { (0.0, 0.0) };
    norm2(sub(p, [a[0] + ab[0] * v + ac[0] * w, a[1] + ab[1] * v + ac[1] * w, a[2] + ab[2] * v + ac[2] * w]))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * (1.0 + b.abs())
    }

    #[test]
    fn point_triangle_regions_by_hand() {
        // Right triangle a=(0,0,0), b=(1,0,0), c=(0,1,0) in the z=0 plane.
        let (a, b, c) = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        // Above the interior: distance is the height, 2 → d² = 4.
        assert!(close(point_triangle_dist2([0.25, 0.25, 2.0], a, b, c), 4.0));
        // Vertex region of a: (-1,-1,0) → d² = 2.
        assert!(close(point_triangle_dist2([-1.0, -1.0, 0.0], a, b, c), 2.0));
        // Vertex region of b: (2,-1,1) → (1,-1,1) → 3.
        assert!(close(point_triangle_dist2([2.0, -1.0, 1.0], a, b, c), 3.0));
        // Edge ab region: (0.5,-2,0) → 4.
        assert!(close(point_triangle_dist2([0.5, -2.0, 0.0], a, b, c), 4.0));
        // Edge bc region: (1,1,0) projects on (0.5,0.5,0) → 0.5.
        assert!(close(point_triangle_dist2([1.0, 1.0, 0.0], a, b, c), 0.5));
        // Edge ca region: (-3,0.5,4) → (0,0.5,0): 9 + 16 = 25.
        assert!(close(point_triangle_dist2([-3.0, 0.5, 4.0], a, b, c), 25.0));
    }

    #[test]
    fn degenerate_triangles_never_nan() {
        let (a, c) = ([0.0, 0.0, 0.0], [2.0, 0.0, 0.0]);
        // a == b: the segment a-c; point (1,1,0) is at distance 1.
        assert!(close(point_triangle_dist2([1.0, 1.0, 0.0], a, a, c), 1.0));
        // Collinear corners: segment from 0 to 2 on x; (3,0,0) is at distance 1.
        assert!(close(point_triangle_dist2([3.0, 0.0, 0.0], a, [1.0, 0.0, 0.0], c), 1.0));
        // All three equal: a point.
        assert!(close(point_triangle_dist2([0.0, 3.0, 4.0], a, a, a), 25.0));
    }

    /// Unit square in z=0 made of two triangles (0,1,2),(0,2,3), two frames.
    /// Candidate: frame 0 lifts vertex 2 (the corner (1,1)) by 0.5 in z; frame 1 is identical.
    /// Frame 0, reference vertices to the candidate surface: only vertex 2 = (1,1,0) is off
    /// the bent surface; its nearest point is on the lifted triangles. Triangle (0,1,2') with
    /// 0=(0,0,0), 1=(1,0,0), 2'=(1,1,0.5) has normal (0,-0.5,1)/|…|; the distance from (1,1,0)
    /// to its plane is |(1,1,0)·(0,-0.5,1)|/sqrt(1.25) = 0.5/sqrt(1.25) = 0.4472136 and the
    /// foot (1, 0.8, 0.4) lies inside the triangle; by symmetry the same for (0,2',3).
    /// Candidate vertices to the reference surface: 2' = (1,1,0.5) is 0.5 above the square.
    /// So h_0 = max(0.4472, 0.5) = 0.5 and h_1 = 0: max 0.5, mean 0.25.
    /// Diagonal of the reference box [0,1]²×[0,0]: sqrt(2).
    #[test]
    fn hausdorff_matches_hand_computation() {
        let sq = [0., 0., 0., 1., 0., 0., 1., 1., 0., 0., 1., 0.];
        let tris = vec![[0, 1, 2], [0, 2, 3]];
        let r = Animation::from_parts(4, tris.clone(), [sq, sq].concat(), 30.0).unwrap();
        let mut lifted = sq;
        lifted[8] = 0.5;
        let c = Animation::from_parts(4, tris.clone(), [lifted, sq].concat(), 30.0).unwrap();
        let h = hausdorff(&r, &c).unwrap();
        assert_eq!(h.mode, HausdorffMode::PointToTriangle);
        assert!(close(h.per_frame[0], 0.5) && h.per_frame[1] == 0.0, "{:?}", h.per_frame);
        assert!(close(h.max, 0.5) && close(h.mean, 0.25));
        assert!(close(h.max_relative.unwrap(), 0.5 / 2f64.sqrt()));
        let d = vertex_to_surface_distances(&sq, &lifted, &tris).unwrap();
        assert!(close(d[2], 0.5 / 1.25f64.sqrt()), "{d:?}");
        assert_eq!(d[0], 0.0);
        // Symmetry: swapping reference and candidate gives the same per-frame distances.
        assert_eq!(hausdorff(&c, &r).unwrap().per_frame, h.per_frame);
    }

    #[test]
    fn point_cloud_falls_back_to_point_to_point() {
        // Points (0,0,0),(3,0,0); candidate moves point 1 to (3,4,0). Reference→candidate:
        // point 1 is 4 from (3,4,0) and 5 from (0,0,0) → 4. Candidate→reference: (3,4,0) is
        // 4 from (3,0,0) → 4. h = 4.
        let r = Animation::from_parts(2, vec![], vec![0., 0., 0., 3., 0., 0.], 30.0).unwrap();
        let c = Animation::from_parts(2, vec![], vec![0., 0., 0., 3., 4., 0.], 30.0).unwrap();
        let h = hausdorff(&r, &c).unwrap();
        assert_eq!(h.mode, HausdorffMode::PointToPoint);
        assert!(close(h.max, 4.0));
        // A point whose nearest neighbour is not its own counterpart: candidate swaps positions
        // → every point has a zero-distance match.
        let s = Animation::from_parts(2, vec![], vec![3., 0., 0., 0., 0., 0.], 30.0).unwrap();
        assert_eq!(hausdorff(&r, &s).unwrap().max, 0.0);
    }

    /// Vertices in no triangle are points (probe hausdorff-isolated). An animation against
    /// itself is at distance 0, and an isolated point moved by 0.25 far from the surface is at
    /// 0.25 (compared with the other frame's surface alone it would be at 40 % of the box).
    #[test]
    fn isolated_vertices_are_points() {
        // A triangle near the origin and two free points at x = 10 and x = 20.
        let f0 = [0., 0., 0., 1., 0., 0., 0., 1., 0., 10., 0., 0., 20., 0., 0.];
        let tris = vec![[0, 1, 2]];
        let r = Animation::from_parts(5, tris.clone(), [f0, f0].concat(), 30.0).unwrap();
        let h = hausdorff(&r, &r).unwrap();
        assert_eq!((h.max, h.mode), (0.0, HausdorffMode::PointToTriangle));
        let mut moved = f0;
        moved[10] = 0.25;
        let c = Animation::from_parts(5, tris.clone(), [f0, moved].concat(), 30.0).unwrap();
        let h = hausdorff(&r, &c).unwrap();
        assert_eq!(h.per_frame[0], 0.0);
        assert!(close(h.per_frame[1], 0.25), "{:?}", h.per_frame);
        assert_eq!(isolated_vertex_count(&tris, 5), 2);
        let d = vertex_to_surface_distances(&f0, &f0, &tris).unwrap();
        assert!(d.iter().all(|&x| x == 0.0), "{d:?}");
    }

    /// BVH search against brute force on a bumpy grid with random-ish query points.
    #[test]
    fn bvh_matches_brute_force() {
        let g = 20usize;
        let mut pts = Vec::new();
        for y in 0..g {
            for x in 0..g {
                let z = ((x as f32) * 0.7).sin() * ((y as f32) * 0.4).cos() * 0.3;
                pts.extend([x as f32 * 0.1, y as f32 * 0.1, z]);
            }
        }
        let mut tris = Vec::new();
        for y in 0..g - 1 {
            for x in 0..g - 1 {
                let i = (y * g + x) as u32;
                tris.push([i, i + 1, i + g as u32 + 1]);
                tris.push([i, i + g as u32 + 1, i + g as u32]);
            }
        }
        // Query frame: the grid pushed around by a deterministic pseudo-random field.
        let mut seed = 12345u64;
        let q: Vec<f32> = pts
            .iter()
            .map(|&p| {
                seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                p + ((seed >> 33) as f32 / (1u64 << 31) as f32 - 0.5) * 0.4
            })
            .collect();
        let fast = vertex_to_surface_distances(&q, &pts, &tris).unwrap();
        for (v, &fast_v) in fast.iter().enumerate() {
            let p = point(&q, v);
            let brute = tris
                .iter()
                .map(|t| {
                    point_triangle_dist2(
                        p,
                        point(&pts, t[0] as usize),
                        point(&pts, t[1] as usize),
                        point(&pts, t[2] as usize),
                    )
                })
                .fold(f64::INFINITY, f64::min)
                .sqrt();
            assert_eq!(fast_v, brute, "vertex {v}");
        }
        // The per-frame maximum, which skips most searches, equals the exhaustive maximum in
        // both directions.
        let back = vertex_to_surface_distances(&pts, &q, &tris).unwrap();
        let exhaustive = fast.iter().chain(&back).copied().fold(0.0, f64::max);
        let r = Animation::from_parts(g * g, tris.clone(), pts.clone(), 30.0).unwrap();
        let c = Animation::from_parts(g * g, tris.clone(), q.clone(), 30.0).unwrap();
        assert_eq!(hausdorff(&r, &c).unwrap().max, exhaustive);
    }

    #[test]
    fn bad_frames_are_errors() {
        assert!(vertex_to_surface_distances(&[0.0; 6], &[0.0; 9], &[]).is_err());
        assert!(vertex_to_surface_distances(&[0.0; 9], &[0.0; 9], &[[0, 1, 3]]).is_err());
        assert!(vertex_to_surface_distances(&[], &[], &[]).is_err());
    }
}
