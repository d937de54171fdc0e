//! Vertex clustering of §4.2: rigid clusters from the maximal edge-length change, grown over
//! the deformed vertices, then grouped by clustered PCA (Alg. 1).

use codec_core::Result;
use faer::Mat;

use crate::linalg::{gram, pcs_for_persistence, sym_eig_desc};
use crate::mesh::{frame_diagonal, MeshGraph, NEGLIGIBLE_AMPLITUDE};
use crate::params::StsegParams;

/// Most principal components a vertex group keeps while grouping rigid clusters (Alg. 1).
/// The paper does not say; a small cap keeps Eq. 4 a subspace fit rather than a copy.
const MAX_GROUP_PCS: usize = 8;
/// Most iterations of Alg. 1 (it stops earlier when the labels stop changing).
const MAX_GROUPING_ITERATIONS: usize = 30;

/// Per-vertex trajectories over `frames`, each minus its temporal mean (`V × 3n`, row-major).
fn centered_trajectories(frames: &[f32], v: usize) -> (Vec<f64>, usize) {
    let n3 = v * 3;
    let n = frames.len() / n3;
    let d = 3 * n;
    let mut y = vec![0.0f64; v * d];
    for vi in 0..v {
        for c in 0..3 {
            let mean = (0..n).map(|t| frames[t * n3 + vi * 3 + c] as f64).sum::<f64>() / n as f64;
            for t in 0..n {
                y[vi * d + t * 3 + c] = frames[t * n3 + vi * 3 + c] as f64 - mean;
            }
        }
    }
    (y, d)
}

fn dist2(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// The cluster of a vertex on no rigid edge (yet).
const NO_CLUSTER: usize = usize::MAX;

/// Maximal edge-length change of every edge of `graph` over the `n` frames, relative to the
/// edge's mean length so that the rigidity test does not depend on local mesh density.
fn max_edge_change(graph: &MeshGraph, frames: &[f32], n: usize) -> Vec<f64> {
    let n3 = graph.vertex_count() * 3;
    graph
        .edges
        .iter()
        .map(|e| {
            let (a, b) = (e[0] as usize * 3, e[1] as usize * 3);
            let (mut lo, mut hi, mut sum) = (f64::INFINITY, f64::NEG_INFINITY, 0.0);
            for t in 0..n {
                let f = &frames[t * n3..];
                let l = (0..3).map(|c| (f[a + c] as f64 - f[b + c] as f64).powi(2)).sum::<f64>().sqrt();
                lo = lo.min(l);
                hi = hi.max(l);
                sum += l;
            }
            let mean = sum / n as f64;
            if mean > 0.0 {
                (hi - lo) / mean
            } else {
                0.0
            }
        })
        .collect()
}

/// Rigid regions: the connected components of the edges whose change `mec` is at most
/// `threshold` (union-find), numbered in order of their lowest vertex. Returns every vertex's
/// cluster ([`NO_CLUSTER`] for a vertex on no rigid edge) and the number of clusters.
fn rigid_clusters(graph: &MeshGraph, mec: &[f64], threshold: f64) -> (Vec<usize>, usize) {
    let v = graph.vertex_count();
    let mut parent: Vec<usize> = (0..v).collect();
    fn find(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut rigid = vec![false; v];
    for (e, &m) in graph.edges.iter().zip(mec) {
        if m <= threshold {
            let (a, b) = (e[0] as usize, e[1] as usize);
            rigid[a] = true;
            rigid[b] = true;
            let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
            if ra != rb {
                parent[ra.max(rb)] = ra.min(rb);
            }
        }
    }
    let mut cluster = vec![NO_CLUSTER; v];
    let mut root_to_cluster = vec![NO_CLUSTER; v];
    let mut count = 0usize;
    for i in 0..v {
        if rigid[i] {
            let r = find(&mut parent, i);
            if root_to_cluster[r] == NO_CLUSTER {
                root_to_cluster[r] = count;
                count += 1;
            }
            cluster[i] = root_to_cluster[r];
        }
    }
    (cluster, count)
}

/// Rigid cluster growing: wave by wave, each vertex in no cluster next to a cluster joins the
/// adjacent cluster whose centre trajectory (`sums / sizes`) is closest; centres are updated
/// after each wave. A part with no rigid edge at all gets a new cluster at its lowest vertex.
fn grow_clusters<'t>(
    graph: &MeshGraph,
    traj: &impl Fn(usize) -> &'t [f64],
    cluster: &mut [usize],
    count: &mut usize,
    sums: &mut Vec<Vec<f64>>,
    sizes: &mut Vec<usize>,
) {
    let v = graph.vertex_count();
    loop {
        let mut wave: Vec<(usize, usize)> = Vec::new();
        for i in 0..v {
            if cluster[i] != NO_CLUSTER {
                continue;
            }
            let mut best: Option<(usize, f64)> = None;
            for &nb in graph.neighbours(i) {
                let c = cluster[nb as usize];
                if c == NO_CLUSTER {
                    continue;
                }
                let centre: Vec<f64> = sums[c].iter().map(|s| s / sizes[c] as f64).collect();
                let dd = dist2(traj(i), &centre);
                if best.is_none_or(|(bc, bd)| dd < bd || (dd == bd && c < bc)) {
                    best = Some((c, dd));
                }
            }
            if let Some((c, _)) = best {
                wave.push((i, c));
            }
        }
        if wave.is_empty() {
            // A part with no rigid edge at all: seed a new cluster at its lowest vertex.
            match (0..v).find(|&i| cluster[i] == NO_CLUSTER) {
                None => break,
                Some(i) => {
                    wave.push((i, *count));
                    sums.push(vec![0.0; traj(i).len()]);
                    sizes.push(0);
                    *count += 1;
                }
            }
        }
        for (i, c) in wave {
            cluster[i] = c;
            sizes[c] += 1;
            sums[c].iter_mut().zip(traj(i)).for_each(|(s, x)| *s += x);
        }
    }
}

/// Two-stage vertex clustering (§4.2) on the initial-cut frames: rigid clusters from the
/// maximal edge-length change, grown over deformed vertices, then grouped by clustered PCA
/// (Alg. 1). Returns per-vertex group labels and the number of groups.
pub(crate) fn cluster_vertices(graph: &MeshGraph, frames: &[f32], p: &StsegParams) -> Result<(Vec<u8>, usize)> {
    let v = graph.vertex_count();
    let n3 = v * 3;
    let n = frames.len() / n3;
    let (y, d) = centered_trajectories(frames, v);
    let traj = |i: usize| &y[i * d..(i + 1) * d];

    let mec = max_edge_change(graph, frames, n);
    // Exponential fit (maximum likelihood: rate = 1/mean); its inverse CDF at ρ gives the
    // rigidity threshold.
    let mean_mec = mec.iter().sum::<f64>() / mec.len().max(1) as f64;
    let threshold = -(1.0 - p.rho).ln() * mean_mec;

    let (mut cluster, mut count) = rigid_clusters(graph, &mec, threshold);
    let mut sums: Vec<Vec<f64>> = vec![vec![0.0; d]; count];
    let mut sizes = vec![0usize; count];
    for i in 0..v {
        if cluster[i] != NO_CLUSTER {
            sizes[cluster[i]] += 1;
            sums[cluster[i]].iter_mut().zip(traj(i)).for_each(|(s, x)| *s += x);
        }
    }
    grow_clusters(graph, &traj, &mut cluster, &mut count, &mut sums, &mut sizes);
    let members: Vec<Vec<usize>> = {
        let mut m = vec![Vec::new(); count];
        for i in 0..v {
            m[cluster[i]].push(i);
        }
        m
    };
    let centres: Vec<Vec<f64>> = (0..count).map(|c| sums[c].iter().map(|s| s / sizes[c] as f64).collect()).collect();

    // Alg. 1, rigid cluster grouping. Seeds: the largest cluster, then farthest-point on the
    // cluster centres (the paper takes "the first N_g clusters"; this makes the seeds distinct).
    let ng = (p.groups as usize).min(count);
    let mut seeds = vec![(0..count).max_by_key(|&c| (sizes[c], std::cmp::Reverse(c))).unwrap_or(0)];
    while seeds.len() < ng {
        let far = (0..count)
            .filter(|c| !seeds.contains(c))
            .map(|c| (c, seeds.iter().map(|&s| dist2(&centres[c], &centres[s])).fold(f64::INFINITY, f64::min)))
            .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)));
        match far {
            Some((c, dd)) if dd > 0.0 => seeds.push(c),
            _ => break,
        }
    }
    let mut label: Vec<usize> = vec![usize::MAX; count];
    for (g, &s) in seeds.iter().enumerate() {
        label[s] = g;
    }
    let negligible = |rows: usize| (NEGLIGIBLE_AMPLITUDE * frame_diagonal(&frames[..n3])).powi(2) * rows as f64;
    let model = |vertices: &mut dyn Iterator<Item = usize>| -> Result<Option<(Vec<f64>, Mat<f64>)>> {
        let list: Vec<usize> = vertices.collect();
        if list.is_empty() {
            return Ok(None);
        }
        let mut centre = vec![0.0; d];
        for &i in &list {
            centre.iter_mut().zip(traj(i)).for_each(|(c, x)| *c += x);
        }
        centre.iter_mut().for_each(|c| *c /= list.len() as f64);
        let ym = Mat::from_fn(list.len(), d, |r, c| traj(list[r])[c] - centre[c]);
        let (vals, vecs) = sym_eig_desc(gram(ym.as_ref()).as_ref(), "group PCA")?;
        let k = pcs_for_persistence(&vals, p.omega_seg, negligible(list.len())).min(MAX_GROUP_PCS);
        Ok(Some((centre, vecs.subcols(0, k).to_owned())))
    };
    let mut models: Vec<Option<(Vec<f64>, Mat<f64>)>> =
        seeds.iter().map(|&s| model(&mut members[s].iter().copied())).collect::<Result<_>>()?;
    for _ in 0..MAX_GROUPING_ITERATIONS {
        let prev = label.clone();
        for c in 0..count {
            let mut best: Option<(usize, f64)> = None;
            for (g, m) in models.iter().enumerate() {
                let Some((centre, basis)) = m else { continue };
                // Eq. 4: squared reconstruction error of the cluster with the group's PCA.
                let mut err = 0.0;
                for &i in &members[c] {
                    let r: Vec<f64> = traj(i).iter().zip(centre).map(|(x, m)| x - m).collect();
                    let mut e = r.iter().map(|x| x * x).sum::<f64>();
                    for j in 0..basis.ncols() {
                        let proj: f64 = (0..d).map(|q| basis[(q, j)] * r[q]).sum();
                        e -= proj * proj;
                    }
                    err += e.max(0.0);
                }
                if best.is_none_or(|(_, be)| err < be) {
                    best = Some((g, err));
                }
            }
            label[c] = best.map_or(0, |b| b.0);
        }
        if label == prev {
            break;
        }
        models = (0..models.len())
            .map(|g| model(&mut (0..count).filter(|&c| label[c] == g).flat_map(|c| members[c].iter().copied())))
            .collect::<Result<_>>()?;
    }
    // Compact the labels (empty groups vanish) in order of each group's lowest vertex.
    let mut remap = vec![usize::MAX; models.len()];
    let mut next = 0;
    let mut out = vec![0u8; v];
    for i in 0..v {
        let g = label[cluster[i]];
        if remap[g] == usize::MAX {
            remap[g] = next;
            next += 1;
        }
        out[i] = remap[g] as u8;
    }
    Ok((out, next.max(1)))
}
