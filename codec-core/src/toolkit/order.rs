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
        let across = EdgeOpposites::new(triangles, &valid, &rank);
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
            parallelogram.push(find_parallelogram(x, p, triangles, &incident, &tri_start, &rank, &across));
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

    /// Every position's neighbours, both ways, as CSR `(start, list)`: for position `p`,
    /// `list[start[p]..start[p + 1]]` holds its earlier neighbours as [`CausalGraph::earlier`]
    /// lists them, then every later position that lists `p` as earlier, ascending. Codecs sum
    /// over these lists in this order (hosvd's smoothing is bit exact in it).
    pub fn adjacency(&self) -> (Vec<u32>, Vec<u32>) {
        let n = self.len();
        let mut degree = vec![0u32; n + 1];
        for p in 0..n {
            for &q in self.earlier(p) {
                degree[p] += 1;
                degree[q as usize] += 1;
            }
        }
        let mut start = vec![0u32; n + 1];
        for p in 0..n {
            start[p + 1] = start[p] + degree[p];
        }
        let mut fill = start.clone();
        let mut list = vec![0u32; start[n] as usize];
        for p in 0..n {
            for &q in self.earlier(p) {
                list[fill[p] as usize] = q;
                fill[p] += 1;
                list[fill[q as usize] as usize] = p as u32;
                fill[q as usize] += 1;
            }
        }
        (start, list)
    }

    /// Share of positions that have a parallelogram triple (a traversal quality figure).
    pub fn parallelogram_share(&self) -> f64 {
        if self.order.is_empty() {
            return 0.0;
        }
        self.parallelogram.iter().filter(|t| t[0] != NONE).count() as f64 / self.order.len() as f64
    }
}

/// Upper bound of the bytes [`CausalGraph::mesh`] allocates for `vertex_count` vertices and
/// `triangle_count` triangles (a decoder checks it against its limits before building).
pub fn mesh_bytes(vertex_count: usize, triangle_count: usize) -> u64 {
    let (n, t) = (vertex_count as u64, triangle_count as u64);
    // Per vertex: degree, tri_start, fill copies, rank, order, start, parallelogram (12) and a
    // `Vec` header (24) for the neighbour lists. Per triangle: adj (6 entries), incident (3),
    // the neighbour lists and `earlier` (6 each), the edge table (3 × 12 bytes) and its
    // min-tree (at most 4 × 3 entries).
    n.saturating_mul(4 * 7 + 12 + 24).saturating_add(t.saturating_mul(4 * (6 + 3 + 6 + 6) + 36 + 4 * 12))
}

/// Every edge of every non-degenerate triangle with the triangle's third corner, sorted by
/// `(edge, triangle index)`, plus a min-tree over the corners' ranks so the first triangle
/// across an edge with a visited third corner is found in `O(log T)` — the candidate the
/// plain scan over the triangles incident to `a` found, without its quadratic cost on many
/// copies of one triangle or a large fan.
struct EdgeOpposites {
    /// `(min corner, max corner, triangle index, third corner)`, sorted.
    entries: Vec<(u32, u32, u32, u32)>,
    /// Min-tree of `rank[third corner]` over `entries`, `size` leaves.
    tree: Vec<u32>,
    size: usize,
}

impl EdgeOpposites {
    fn new(triangles: &[[u32; 3]], valid: &impl Fn(&[u32; 3]) -> bool, rank: &[u32]) -> Self {
        let mut entries = Vec::new();
        for (ti, t) in triangles.iter().enumerate() {
            if !valid(t) || t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                continue;
            }
            for j in 0..3 {
                let (a, b, c) = (t[j], t[(j + 1) % 3], t[(j + 2) % 3]);
                entries.push((a.min(b), a.max(b), ti as u32, c));
            }
        }
        entries.sort_unstable();
        let size = entries.len().next_power_of_two();
        let mut tree = vec![NONE; 2 * size];
        for (i, e) in entries.iter().enumerate() {
            tree[size + i] = rank[e.3 as usize];
        }
        for i in (1..size).rev() {
            tree[i] = tree[2 * i].min(tree[2 * i + 1]);
        }
        Self { entries, tree, size }
    }

    /// Third corner of the first triangle (lowest index) across edge `(a, b)` whose third
    /// corner has a rank below `p`.
    fn first_visited(&self, a: u32, b: u32, p: u32) -> Option<u32> {
        let key = (a.min(b), a.max(b));
        let lo = self.entries.partition_point(|e| (e.0, e.1) < key);
        let hi = lo + self.entries[lo..].partition_point(|e| (e.0, e.1) == key);
        self.first_below(1, 0, self.size, lo, hi, p).map(|i| self.entries[i].3)
    }

    /// First leaf index in `[lo, hi)` below `node` (covering `[l, r)`) with a value below `p`.
    fn first_below(&self, node: usize, l: usize, r: usize, lo: usize, hi: usize, p: u32) -> Option<usize> {
        if r <= lo || hi <= l || self.tree[node] >= p {
            return None;
        }
        if r - l == 1 {
            return Some(l);
        }
        let mid = (l + r) / 2;
        self.first_below(2 * node, l, mid, lo, hi, p).or_else(|| self.first_below(2 * node + 1, mid, r, lo, hi, p))
    }
}

/// First (by incident-triangle order) triangle `(x, a, b)` with `a`, `b` visited before
/// position `p` and a triangle across `(a, b)` whose third corner `c` is visited too (the
/// lowest-index such triangle; one containing `x` has `c = x`, which is not visited).
fn find_parallelogram(
    x: u32,
    p: u32,
    triangles: &[[u32; 3]],
    incident: &[u32],
    tri_start: &[u32],
    rank: &[u32],
    across: &EdgeOpposites,
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
        if let Some(c) = across.first_visited(a, b, p) {
            return [rank[a as usize], rank[b as usize], rank[c as usize]];
        }
    }
    [NONE; 3]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adjacency_lists_earlier_then_later_neighbours() {
        let g = CausalGraph::mesh(35, &grid(7, 5));
        let (start, list) = g.adjacency();
        assert_eq!(start.len(), g.len() + 1);
        for p in 0..g.len() {
            let nb = &list[start[p] as usize..start[p + 1] as usize];
            let later: Vec<u32> =
                (p + 1..g.len()).filter(|&q| g.earlier(q).contains(&(p as u32))).map(|q| q as u32).collect();
            assert_eq!(nb, [g.earlier(p), &later[..]].concat(), "position {p}");
        }
    }

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

    /// The plain scan `find_parallelogram` used before the edge table (quadratic on many
    /// copies of one triangle), kept as the reference the fast lookup must agree with.
    fn reference_parallelograms(n: usize, triangles: &[[u32; 3]], g: &CausalGraph) -> Vec<[u32; 3]> {
        let mut rank = vec![NONE; n];
        for (p, &v) in g.order().iter().enumerate() {
            rank[v as usize] = p as u32;
        }
        let valid = |t: &[u32; 3]| t.iter().all(|&i| (i as usize) < n);
        let mut incident: Vec<Vec<u32>> = vec![Vec::new(); n];
        for (ti, t) in triangles.iter().enumerate().filter(|(_, t)| valid(t)) {
            for &i in t {
                incident[i as usize].push(ti as u32);
            }
        }
        let mut out = Vec::new();
        for (p, &x) in g.order().iter().enumerate() {
            let p = p as u32;
            let visited = |v: u32| rank[v as usize] < p;
            let mut found = [NONE; 3];
            'outer: for &ti in &incident[x as usize] {
                let t = triangles[ti as usize];
                let j = t.iter().position(|&i| i == x).unwrap_or(0);
                let (a, b) = (t[(j + 1) % 3], t[(j + 2) % 3]);
                if a == b || !visited(a) || !visited(b) {
                    continue;
                }
                for &si in &incident[a as usize] {
                    let s = triangles[si as usize];
                    if si == ti || !s.contains(&b) || s.contains(&x) {
                        continue;
                    }
                    if let Some(&c) = s.iter().find(|&&c| c != a && c != b) {
                        if visited(c) {
                            found = [rank[a as usize], rank[b as usize], rank[c as usize]];
                            break 'outer;
                        }
                    }
                }
            }
            out.push(found);
        }
        out
    }

    fn triples(g: &CausalGraph) -> Vec<[u32; 3]> {
        (0..g.len()).map(|p| g.parallelogram(p).unwrap_or([NONE; 3])).collect()
    }

    #[test]
    fn edge_lookup_picks_the_same_triangle_as_the_plain_scan() {
        // Grids, plus meshes with duplicates, degenerate and reversed triangles and a book of
        // pages listed in descending order (the first candidates across the spine unvisited).
        let mut cases: Vec<(usize, Vec<[u32; 3]>)> = vec![(35, grid(7, 5)), (54, grid(9, 6))];
        let mut seed = 12345u64;
        let mut next = |m: u32| {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 33) % m as u64) as u32
        };
        for n in [6u32, 12, 30] {
            let tris: Vec<[u32; 3]> = (0..3 * n).map(|_| [next(n), next(n), next(n)]).collect();
            cases.push((n as usize, tris));
        }
        let mut dup = grid(6, 6);
        dup.extend(grid(6, 6).iter().rev().map(|t| [t[2], t[1], t[0]]));
        dup.extend([[0, 0, 1], [3, 4, 3], [7, 8, 13]]);
        cases.push((36, dup));
        let book: Vec<[u32; 3]> = (2..40u32).rev().map(|c| [0, 1, c]).collect();
        cases.push((40, book));
        for (n, tris) in cases {
            let g = CausalGraph::mesh(n, &tris);
            assert_eq!(triples(&g), reference_parallelograms(n, &tris, &g), "{tris:?}");
        }
    }

    #[test]
    fn many_copies_of_one_triangle_and_a_large_fan_build_quickly() {
        // The plain scan took copies² + fan² steps here (~10^11); the edge table takes
        // O(T log T). A hang would show as a test timeout; the result is checked too.
        let copies = 200_000;
        let fan = 100_000u32;
        let mut tris = vec![[0u32, 1, 2]; copies];
        tris.extend((0..fan).map(|i| [3, 4 + i, 4 + (i + 1) % fan]));
        let n = 4 + fan as usize;
        let g = CausalGraph::mesh(n, &tris);
        assert_eq!(g.len(), n);
        // No triangle across (0, 1) has a third corner other than 2: no triple for 0..=2.
        assert!((0..3).all(|p| g.parallelogram(p).is_none()));
        // The fan is visited hub first, then the rim in order: every rim vertex from the
        // third on predicts across the spoke to its predecessor from the triangle before.
        assert!(g.parallelogram_share() > 0.99, "{}", g.parallelogram_share());
        assert!(mesh_bytes(n, tris.len()) < 200 * tris.len() as u64 + 100 * n as u64);
    }
}
