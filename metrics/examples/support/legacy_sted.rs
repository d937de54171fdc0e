//! An earlier STED definition that differs from the author's tool's (commit 14b2640), kept
//! only as the timing baseline of `metric_timing`: `metrics::sted()` must stay under 2× this
//! one's time, measured in the same run. Not a metric to use: it gives 0.50–1.01× the tool's
//! values. Radius-3 neighbourhoods of the edges with *both* ends within 3 hops, absolute
//! relative differences, temporal edges with `dt = 0.3 ×` the bounding-box diagonal and no
//! speed window, `c = 0.5`.

use codec_core::Animation;
use rayon::prelude::*;

const RADIUS: usize = 3;
const DT: f64 = 0.3;
const C: f64 = 0.5;

fn pt(f: &[f32], v: usize) -> [f64; 3] {
    [f[3 * v] as f64, f[3 * v + 1] as f64, f[3 * v + 2] as f64]
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// `(sted, spatial, temporal)` by the old definition.
pub fn legacy_sted(r: &Animation, c: &Animation) -> (f64, f64, f64) {
    let n = r.vertex_count();
    let mut edges: Vec<[usize; 2]> = r
        .triangles()
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .filter(|(a, b)| a != b)
        .map(|(a, b)| [a.min(b) as usize, a.max(b) as usize])
        .collect();
    edges.sort_unstable();
    edges.dedup();
    let mut adj = vec![Vec::new(); n];
    for (e, &[i, j]) in edges.iter().enumerate() {
        adj[i].push((j, e));
        adj[j].push((i, e));
    }
    // Edges with both ends within RADIUS hops, by breadth-first search per vertex.
    let hoods: Vec<Vec<usize>> = (0..n)
        .into_par_iter()
        .map_init(
            || vec![usize::MAX; n],
            |stamp, v| {
                let mut queue = vec![v];
                stamp[v] = v;
                let (mut head, mut level_end) = (0, 1);
                for _ in 0..RADIUS {
                    while head < level_end {
                        let u = queue[head];
                        head += 1;
                        for &(w, _) in &adj[u] {
                            if stamp[w] != v {
                                stamp[w] = v;
                                queue.push(w);
                            }
                        }
                    }
                    level_end = queue.len();
                }
                let mut out = Vec::new();
                for &u in &queue {
                    out.extend(adj[u].iter().filter(|&&(w, _)| u < w && stamp[w] == v).map(|&(_, e)| e));
                }
                out
            },
        )
        .collect();
    let frames = r.frame_count();
    let spatial_sum: f64 = (0..frames)
        .into_par_iter()
        .map(|t| {
            let (a, b) = (r.frame(t), c.frame(t));
            let per_edge: Vec<(f64, f64)> = edges
                .iter()
                .map(|&[i, j]| {
                    let l = dist(pt(a, i), pt(a, j));
                    if l > 0.0 {
                        (l, ((dist(pt(b, i), pt(b, j)) - l) / l).abs())
                    } else {
                        (0.0, 0.0)
                    }
                })
                .collect();
            hoods
                .iter()
                .map(|h| {
                    let w: f64 = h.iter().map(|&e| per_edge[e].0).sum();
                    if w <= 0.0 {
                        return 0.0;
                    }
                    let mu = h.iter().map(|&e| per_edge[e].0 * per_edge[e].1).sum::<f64>() / w;
                    (h.iter().map(|&e| per_edge[e].0 * (per_edge[e].1 - mu).powi(2)).sum::<f64>() / w).sqrt()
                })
                .sum::<f64>()
        })
        .collect::<Vec<f64>>()
        .iter()
        .sum();
    let spatial = spatial_sum / (n * frames) as f64;
    let step2 = (DT * r.bounding_box_diagonal()).powi(2);
    let temporal = if frames < 2 {
        0.0
    } else {
        (0..frames - 1)
            .into_par_iter()
            .map(|t| {
                (0..n)
                    .map(|v| {
                        let m = (dist(pt(r.frame(t + 1), v), pt(r.frame(t), v)).powi(2) + step2).sqrt();
                        let mc = (dist(pt(c.frame(t + 1), v), pt(c.frame(t), v)).powi(2) + step2).sqrt();
                        (mc - m).abs() / m
                    })
                    .sum::<f64>()
            })
            .collect::<Vec<f64>>()
            .iter()
            .sum::<f64>()
            / ((frames - 1) * n) as f64
    };
    ((spatial * spatial + C * C * temporal * temporal).sqrt(), spatial, temporal)
}
