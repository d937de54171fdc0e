//! What every stage of the segmentation shares: the mesh graph (adjacency and unique edges)
//! and the scale the amplitude thresholds are relative to.

use codec_core::Topology;

/// Amplitude, relative to the first frame's bounding-box diagonal, below which motion is
/// treated as none (f32 positions carry ~6e-8 relative noise).
pub(crate) const NEGLIGIBLE_AMPLITUDE: f64 = 1e-6;

/// Mesh adjacency (CSR) and unique edges.
#[derive(Debug, Clone)]
pub(crate) struct MeshGraph {
    pub edges: Vec<[u32; 2]>,
    offsets: Vec<usize>,
    neighbours: Vec<u32>,
}

impl MeshGraph {
    pub fn new(topology: &Topology) -> Self {
        let v = topology.vertex_count();
        let mut edges: Vec<[u32; 2]> = Vec::with_capacity(topology.triangle_count() * 3);
        for t in topology.triangles() {
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                if a != b {
                    edges.push([a.min(b), a.max(b)]);
                }
            }
        }
        edges.sort_unstable();
        edges.dedup();
        let mut deg = vec![0usize; v + 1];
        for e in &edges {
            deg[e[0] as usize] += 1;
            deg[e[1] as usize] += 1;
        }
        let mut offsets = vec![0usize; v + 1];
        for i in 0..v {
            offsets[i + 1] = offsets[i] + deg[i];
        }
        let mut fill = offsets.clone();
        let mut neighbours = vec![0u32; offsets[v]];
        for e in &edges {
            neighbours[fill[e[0] as usize]] = e[1];
            fill[e[0] as usize] += 1;
            neighbours[fill[e[1] as usize]] = e[0];
            fill[e[1] as usize] += 1;
        }
        for i in 0..v {
            neighbours[offsets[i]..offsets[i + 1]].sort_unstable();
        }
        Self { edges, offsets, neighbours }
    }

    pub fn vertex_count(&self) -> usize {
        self.offsets.len() - 1
    }

    pub fn neighbours(&self, v: usize) -> &[u32] {
        &self.neighbours[self.offsets[v]..self.offsets[v + 1]]
    }

    /// `members` (sorted) grown by `eta` rings of neighbours, sorted (§4.4 boundary consistency).
    pub fn grow_rings(&self, members: &[u32], eta: usize) -> Vec<u32> {
        let mut inside = vec![false; self.vertex_count()];
        for &m in members {
            inside[m as usize] = true;
        }
        let mut frontier: Vec<u32> = members.to_vec();
        for _ in 0..eta {
            let mut next = Vec::new();
            for &f in &frontier {
                for &n in self.neighbours(f as usize) {
                    if !inside[n as usize] {
                        inside[n as usize] = true;
                        next.push(n);
                    }
                }
            }
            frontier = next;
        }
        (0..self.vertex_count() as u32).filter(|&i| inside[i as usize]).collect()
    }
}

/// Bounding-box diagonal of one frame.
pub(crate) fn frame_diagonal(frame: &[f32]) -> f64 {
    let (lo, hi) = codec_core::animation::bounding_box(frame);
    (0..3).map(|a| (hi[a] as f64 - lo[a] as f64).powi(2)).sum::<f64>().sqrt()
}
