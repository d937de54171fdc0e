//! Spatial clustering along mesh connectivity (§4.1 uses METIS; see the README for why a
//! breadth-first partition is used here).
//!
//! Vertices are ordered breadth-first over the triangle adjacency (restarting at the lowest
//! unvisited vertex for each connected component) and the order is cut into `clusters`
//! consecutive runs of equal size (±1). Each run is a union of consecutive BFS layers, so
//! clusters are compact bands of the surface. The partition depends only on the topology, so
//! the decoder recomputes it and the stream does not carry it.

use std::collections::VecDeque;

use codec_core::Topology;

/// Vertex lists of the clusters, each in increasing vertex order.
pub fn partition(topology: &Topology, clusters: usize) -> Vec<Vec<u32>> {
    let n = topology.vertex_count();
    let clusters = clusters.clamp(1, n);
    if clusters == 1 {
        return vec![(0..n as u32).collect()];
    }
    // Compressed adjacency lists.
    let mut degree = vec![0usize; n + 1];
    for t in topology.triangles() {
        for a in 0..3 {
            let (u, v) = (t[a] as usize, t[(a + 1) % 3] as usize);
            if u != v {
                degree[u + 1] += 1;
                degree[v + 1] += 1;
            }
        }
    }
    for i in 0..n {
        degree[i + 1] += degree[i];
    }
    let offsets = degree;
    let mut fill = offsets.clone();
    let mut adjacency = vec![0u32; offsets[n]];
    for t in topology.triangles() {
        for a in 0..3 {
            let (u, v) = (t[a] as usize, t[(a + 1) % 3] as usize);
            if u != v {
                adjacency[fill[u]] = v as u32;
                fill[u] += 1;
                adjacency[fill[v]] = u as u32;
                fill[v] += 1;
            }
        }
    }
    let mut order = Vec::with_capacity(n);
    let mut seen = vec![false; n];
    let mut queue = VecDeque::new();
    for root in 0..n {
        if seen[root] {
            continue;
        }
        seen[root] = true;
        queue.push_back(root);
        while let Some(u) = queue.pop_front() {
            order.push(u as u32);
            for &v in &adjacency[offsets[u]..offsets[u + 1]] {
                if !seen[v as usize] {
                    seen[v as usize] = true;
                    queue.push_back(v as usize);
                }
            }
        }
    }
    let mut parts: Vec<Vec<u32>> = (0..clusters)
        .map(|c| {
            let (lo, hi) = (c * n / clusters, (c + 1) * n / clusters);
            order[lo..hi].to_vec()
        })
        .collect();
    for p in &mut parts {
        p.sort_unstable();
    }
    parts
}

/// Per cluster, the triangles with all three corners in it, renumbered to positions in the
/// cluster's vertex list: the cluster's own mesh, from which its coding order is built
/// (stream version 2). `O(V + T)`; corners outside `0..vertex_count` are ignored.
pub fn local_meshes(triangles: &[[u32; 3]], vertex_count: usize, clusters: &[Vec<u32>]) -> Vec<Vec<[u32; 3]>> {
    let mut home = vec![(u32::MAX, 0u32); vertex_count];
    for (c, verts) in clusters.iter().enumerate() {
        for (i, &v) in verts.iter().enumerate() {
            if let Some(h) = home.get_mut(v as usize) {
                *h = (c as u32, i as u32);
            }
        }
    }
    let mut out = vec![Vec::new(); clusters.len()];
    for t in triangles {
        let [a, b, c] = t.map(|v| home.get(v as usize).copied().unwrap_or((u32::MAX, 0)));
        if a.0 != u32::MAX && a.0 == b.0 && b.0 == c.0 {
            out[a.0 as usize].push([a.1, b.1, c.1]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(w: usize, h: usize) -> Topology {
        let mut tris = Vec::new();
        for y in 0..h - 1 {
            for x in 0..w - 1 {
                let i = (y * w + x) as u32;
                tris.push([i, i + 1, i + w as u32]);
                tris.push([i + 1, i + w as u32 + 1, i + w as u32]);
            }
        }
        Topology::new(w * h, tris).unwrap()
    }

    #[test]
    fn covers_every_vertex_once_with_balanced_sizes() {
        let t = grid(13, 9);
        for c in [1, 2, 5, 117, 500] {
            let parts = partition(&t, c);
            assert_eq!(parts.len(), c.min(117));
            let mut all: Vec<u32> = parts.iter().flatten().copied().collect();
            all.sort_unstable();
            assert_eq!(all, (0..117).collect::<Vec<u32>>());
            let (lo, hi) = (parts.iter().map(Vec::len).min().unwrap(), parts.iter().map(Vec::len).max().unwrap());
            assert!(hi - lo <= 1, "sizes {lo}..{hi}");
        }
    }

    #[test]
    fn two_parts_of_a_grid_are_spatially_separated() {
        // BFS from corner 0: the first half holds the vertices nearest that corner.
        let t = grid(10, 10);
        let parts = partition(&t, 2);
        let dist = |v: u32| (v % 10 + v / 10) as f64;
        let mean = |p: &Vec<u32>| p.iter().map(|&v| dist(v)).sum::<f64>() / p.len() as f64;
        assert!(mean(&parts[0]) + 4.0 < mean(&parts[1]));
        // Point clouds (no triangles) still partition.
        let cloud = Topology::new(7, vec![]).unwrap();
        assert_eq!(partition(&cloud, 3).iter().map(Vec::len).sum::<usize>(), 7);
    }
}
