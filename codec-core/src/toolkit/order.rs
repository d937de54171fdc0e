//! Deterministic, connectivity-driven coding orders and the causal neighbourhoods predictors
//! use along them.
//!
//! [`CausalGraph::mesh`] visits the vertices of a triangle list breadth first: components are
//! seeded at their lowest vertex index, and each vertex's neighbours are queued in ascending
//! index order. Nothing but the triangle list is used, so a decoder rebuilds the same order from
//! the stream's topology. For every position it records the already visited neighbours (for the
//! neighbour-average predictor) and, when one exists, a *parallelogram* triple `(a, b, c)`:
//! a triangle `(x, a, b)` whose other two corners are visited, and the far corner `c` of a
//! visited triangle across the edge `(a, b)`, so `x ≈ a + b − c` (Touma & Gotsman's rule,
//! which Coddyac applies to PCA coefficients).
//!
//! [`CausalGraph::chain`] is the same structure for a sequence (frames): the neighbour of
//! position `t` is `t − 1`, and with `linear` the triple `(t−1, t−1, t−2)` gives the linear
//! extrapolation `2·x[t−1] − x[t−2]`.

/// A coding order plus, per position, the earlier positions a predictor may use.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CausalGraph {
    /// `order[p]` = the item (vertex / frame) coded at position `p`.
    order: Vec<u32>,
    /// CSR offsets into `earlier`, one per position plus one.
    start: Vec<u32>,
    /// Earlier *positions* adjacent to each position, ascending.
    earlier: Vec<u32>,
    /// Parallelogram triple of positions `(a, b, c)` (prediction `a + b − c`), or `u32::MAX`s.
    parallelogram: Vec<[u32; 3]>,
}

const NONE: u32 = u32::MAX;

impl CausalGraph {
    /// Breadth-first order of `vertex_count` vertices over `triangles` (indices must be below
    /// `vertex_count`; triangles with an out-of-range index are ignored, so no input panics).
    pub fn mesh(vertex_count: usize, triangles: &[[u32; 3]]) -> Self {
        let n = vertex_count;
        let valid = |t: &[u32; 3]| t.iter().all(|&i| (i as usize) < n);
        // Vertex → neighbour CSR (sorted, deduplicated) and vertex → triangle CSR.
        let mut degree = vec![0u32; n + 1];
        for t in triangles.iter().filter(|t| valid(t)) {
            for &i in t {
                degree[i as usize + 1] += 2;
            }
        }
        for i in 0..n {
            degree[i + 1] += degree[i];
        }
        let mut fill = degree.clone();
        let mut adj = vec![0u32; degree[n] as usize];
        let mut tri_start = vec![0u32; n + 1];
        for t in triangles.iter().filter(|t| valid(t)) {
            for (j, &i) in t.iter().enumerate() {
                let i = i as usize;
                adj[fill[i] as usize] = t[(j + 1) % 3];
                adj[fill[i] as usize + 1] = t[(j + 2) % 3];
                fill[i] += 2;
                tri_start[i + 1] += 1;
            }
        }
        for i in 0..n {
            tri_start[i + 1] += tri_start[i];
        }
        let mut tri_fill = tri_start.clone();
        let mut incident = vec![0u32; tri_start[n] as usize];
        for (ti, t) in triangles.iter().enumerate().filter(|(_, t)| valid(t)) {
            for &i in t {
                incident[tri_fill[i as usize] as usize] = ti as u32;
                tri_fill[i as usize] += 1;
            }
        }
        let mut neighbours: Vec<Vec<u32>> = (0..n)
            .map(|i| {
                let mut v = adj[degree[i] as usize..degree[i + 1] as usize].to_vec();
                v.sort_unstable();
                v.dedup();
                v.retain(|&j| j as usize != i);
                v
            })
            .collect();

        // Breadth-first traversal.
        let mut rank = vec![NONE; n];
        let mut order = Vec::with_capacity(n);
        let mut queue = std::collections::VecDeque::new();
        for seed in 0..n {
            if rank[seed] != NONE {
                continue;
            }
            rank[seed] = order.len() as u32;
            order.push(seed as u32);
            queue.push_back(seed as u32);
            while let Some(x) = queue.pop_front() {
                for &y in &neighbours[x as usize] {
                    if rank[y as usize] == NONE {
                        rank[y as usize] = order.len() as u32;
                        order.push(y);
                        queue.push_back(y);
                    }
                }
            }
        }

        // Earlier neighbours as positions, and parallelogram triples.
        let mut start = Vec::with_capacity(n + 1);
        let mut earlier = Vec::new();
        let mut parallelogram = Vec::with_capacity(n);
        start.push(0u32);
        for (p, &x) in order.iter().enumerate() {
            let p = p as u32;
            let list = &mut neighbours[x as usize];
            let mut before: Vec<u32> = list.iter().map(|&y| rank[y as usize]).filter(|&r| r < p).collect();
            before.sort_unstable();
            earlier.extend_from_slice(&before);
            start.push(earlier.len() as u32);
            list.clear();
            parallelogram.push(find_parallelogram(x, p, triangles, &incident, &tri_start, &rank));
        }
        Self { order, start, earlier, parallelogram }
    }

    /// A sequence of `n` items in order; `linear` adds the triple for `2·x[t−1] − x[t−2]`.
    pub fn chain(n: usize, linear: bool) -> Self {
        let order = (0..n as u32).collect();
        let mut start = vec![0u32];
        let mut earlier = Vec::with_capacity(n);
        let mut parallelogram = Vec::with_capacity(n);
        for t in 0..n as u32 {
            if t > 0 {
                earlier.push(t - 1);
            }
            start.push(earlier.len() as u32);
            parallelogram.push(if linear && t > 1 { [t - 1, t - 1, t - 2] } else { [NONE; 3] });
        }
        Self { order, start, earlier, parallelogram }
    }

    /// Number of positions.
    pub fn len(&self) -> usize {
        self.order.len()
    }

    /// True when there are no positions.
    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    /// Items in coding order.
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    /// Earlier positions adjacent to position `p`, ascending.
    #[inline]
    pub fn earlier(&self, p: usize) -> &[u32] {
        &self.earlier[self.start[p] as usize..self.start[p + 1] as usize]
    }

    /// Parallelogram triple of positions for `p` (prediction `a + b − c`), if any.
    #[inline]
    pub fn parallelogram(&self, p: usize) -> Option<[u32; 3]> {
        let t = self.parallelogram[p];
        (t[0] != NONE).then_some(t)
    }

    /// Share of positions that have a parallelogram triple (a traversal quality figure).
    pub fn parallelogram_share(&self) -> f64 {
        if self.order.is_empty() {
            return 0.0;
        }
        self.parallelogram.iter().filter(|t| t[0] != NONE).count() as f64 / self.order.len() as f64
    }
}

/// First (by incident-triangle order) triangle `(x, a, b)` with `a`, `b` visited before
/// position `p` and a triangle across `(a, b)` whose third corner `c` is visited too.
fn find_parallelogram(
    x: u32,
    p: u32,
    triangles: &[[u32; 3]],
    incident: &[u32],
    tri_start: &[u32],
    rank: &[u32],
) -> [u32; 3] {
    let visited = |v: u32| rank[v as usize] < p;
    let x = x as usize;
    for &ti in &incident[tri_start[x] as usize..tri_start[x + 1] as usize] {
        let t = triangles[ti as usize];
        let j = t.iter().position(|&i| i as usize == x).unwrap_or(0);
        let (a, b) = (t[(j + 1) % 3], t[(j + 2) % 3]);
        if a == b || !visited(a) || !visited(b) {
            continue;
        }
        // A triangle across edge (a, b): incident to a, containing b, not containing x.
        for &si in &incident[tri_start[a as usize] as usize..tri_start[a as usize + 1] as usize] {
            let s = triangles[si as usize];
            if si == ti || !s.contains(&b) || s.contains(&(x as u32)) {
                continue;
            }
            if let Some(&c) = s.iter().find(|&&c| c != a && c != b) {
                if visited(c) {
                    return [rank[a as usize], rank[b as usize], rank[c as usize]];
                }
            }
        }
    }
    [NONE; 3]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `w × h` grid of vertices split into triangles.
    pub(crate) fn grid(w: usize, h: usize) -> Vec<[u32; 3]> {
        let mut t = Vec::new();
        for y in 0..h - 1 {
            for x in 0..w - 1 {
                let i = (y * w + x) as u32;
                let w = w as u32;
                t.push([i, i + 1, i + w]);
                t.push([i + 1, i + w + 1, i + w]);
            }
        }
        t
    }

    #[test]
    fn mesh_order_is_a_permutation_with_causal_neighbours() {
        let tris = grid(7, 5);
        let g = CausalGraph::mesh(35 + 2, &tris); // two isolated vertices
        let mut seen = g.order().to_vec();
        seen.sort_unstable();
        assert_eq!(seen, (0..37).collect::<Vec<u32>>());
        for p in 0..g.len() {
            assert!(g.earlier(p).iter().all(|&q| (q as usize) < p));
            if let Some([a, b, c]) = g.parallelogram(p) {
                assert!(a < p as u32 && b < p as u32 && c < p as u32);
            }
        }
        // Every grid vertex but the seed has an earlier neighbour (one component).
        assert!((1..35).all(|p| !g.earlier(p).is_empty()));
        assert!(g.parallelogram_share() > 0.7, "{}", g.parallelogram_share());
        // Same input, same order: it is a function of the triangle list alone.
        assert_eq!(g, CausalGraph::mesh(37, &tris));
    }

    #[test]
    fn parallelogram_is_exact_on_a_linear_field() {
        let (w, h) = (9, 6);
        let tris = grid(w, h);
        let g = CausalGraph::mesh(w * h, &tris);
        let field = |v: u32| 3.0 * (v as usize % w) as f64 - 2.0 * (v as usize / w) as f64 + 1.0;
        let mut checked = 0;
        for p in 0..g.len() {
            if let Some([a, b, c]) = g.parallelogram(p) {
                let o = g.order();
                let pred = field(o[a as usize]) + field(o[b as usize]) - field(o[c as usize]);
                assert!((pred - field(o[p])).abs() < 1e-12);
                checked += 1;
            }
        }
        assert!(checked > w * h / 2);
    }

    #[test]
    fn chain_has_previous_and_linear_triples() {
        let g = CausalGraph::chain(4, true);
        assert_eq!(g.earlier(0), &[] as &[u32]);
        assert_eq!(g.earlier(3), &[2]);
        assert_eq!(g.parallelogram(1), None);
        assert_eq!(g.parallelogram(3), Some([2, 2, 1]));
        assert_eq!(CausalGraph::chain(4, false).parallelogram(3), None);
    }

    #[test]
    fn out_of_range_triangles_are_ignored() {
        let g = CausalGraph::mesh(3, &[[0, 1, 2], [0, 1, 99]]);
        assert_eq!(g.len(), 3);
    }
}
