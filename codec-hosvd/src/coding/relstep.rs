//! Per-vertex step scales of the `U1` columns (stream version 7, beyond the paper): steps
//! proportional to the local edge length, derived from what the decoder already has.
//!
//! STED measures *relative* edge-length changes in each vertex's one-ring, so a uniform
//! quantization step hurts most where the edges are short. With the scale `w_p` of mesh
//! position `p`, the `U1` columns from [`SCALED_FROM`] on are quantized with the step
//! `step·w_p` at `p` (the prediction is unchanged: [`predict::quantize_scaled`]): their noise
//! follows the local edge length. The scales have RMS 1, so white noise keeps its energy and
//! `quant` / `edge_noise` keep their meaning.
//!
//! The scales come from the *decoded* leading columns `0 … LEADS−1` (after their smoothing) and
//! the gains `g_i` the stream stores (`‖C_i‖`, the core slice norms, as f32): vertex `p`'s
//! embedding is `e_p = (g_i·u1[p, i])_{i < LEADS}`. With orthonormal `U2`, `U3` and an
//! all-orthogonal core (HO-SVD, HOOI), the squared length of an edge averaged over the frames is
//! `Σ_i ‖C_i‖²·(u1[p, i] − u1[q, i])²` over *all* columns; the leading ones carry the rest shape,
//! so `|e_p − e_q|` approximates the edge's RMS length over time.
//!
//! [`predict::quantize_scaled`]: codec_core::toolkit::predict::quantize_scaled

use codec_core::toolkit::order::CausalGraph;

/// Leading `U1` columns that form the embedding (coded with uniform steps).
pub const LEADS: usize = 3;

/// First `U1` column coded with per-vertex scales.
pub const SCALED_FROM: usize = LEADS;

/// Largest ratio of a scale to the RMS scale, either way (before the RMS normalisation).
pub const MAX_SCALE: f64 = 4.0;

/// Largest strength byte: the exponent is `byte / 4`, so `x^γ` is made of square roots,
/// correctly rounded on every platform (a `powf` is not).
pub const MAX_STRENGTH: u8 = 4;

/// Smallest estimated saving, in bits per coded coordinate, for which the encoder turns the
/// scales on ([`jensen_gain`]); below it they cost more than they save (samba: 0.04).
pub const MIN_GAIN: f64 = 0.1;

/// The strength byte of a `relstep` parameter value in `0..=1` (0 = off), to the nearest
/// quarter.
pub fn strength_byte(relstep: f64) -> u8 {
    (relstep.clamp(0.0, 1.0) * MAX_STRENGTH as f64).round() as u8
}

/// `x^(byte/4)` for `x ≥ 0` by square roots.
fn power(x: f64, byte: u8) -> f64 {
    let (r2, r4) = (x.sqrt(), x.sqrt().sqrt());
    match byte {
        0 => 1.0,
        1 => r4,
        2 => r2,
        3 => r2 * r4,
        _ => x,
    }
}

/// Per mesh position, the mean embedding length of its edges (`None` for a position without
/// edges), and their mean; `None` when the embedding is degenerate (no edges, every length
/// zero, or the mean not finite).
fn edge_lengths(graph: &CausalGraph, leads: &[Vec<f64>], gains: &[f64]) -> Option<(Vec<Option<f64>>, f64)> {
    let k = graph.len();
    let n = leads.len().min(gains.len()).min(LEADS);
    if n == 0 || leads[..n].iter().any(|c| c.len() < k) {
        return None;
    }
    let embed: Vec<[f64; LEADS]> = (0..k)
        .map(|p| {
            let mut e = [0.0; LEADS];
            for i in 0..n {
                e[i] = gains[i] * leads[i][p];
            }
            e
        })
        .collect();
    let (start, adjacent) = graph.adjacency();
    let mut lengths = vec![None; k];
    let (mut sum, mut counted) = (0.0, 0usize);
    for p in 0..k {
        let nb = &adjacent[start[p] as usize..start[p + 1] as usize];
        if nb.is_empty() {
            continue;
        }
        let mut l = 0.0;
        for &q in nb {
            let d2: f64 = (0..n).map(|i| (embed[p][i] - embed[q as usize][i]).powi(2)).sum();
            l += d2.sqrt();
        }
        let l = l / nb.len() as f64;
        lengths[p] = Some(l);
        sum += l;
        counted += 1;
    }
    let mean = if counted > 0 { sum / counted as f64 } else { 0.0 };
    (mean.is_finite() && mean > 0.0).then_some((lengths, mean))
}

/// The saving the scales promise at full strength, in bits per coded coordinate, at high
/// rate: at equal relative noise (what STED sees), steps `∝ L_p` instead of one uniform step
/// save `log2(mean(1/L)) + mean(log2 L) ≥ 0` (Jensen), over the positions with edges and
/// lengths > 0. 0 when the embedding is degenerate. Encoder only.
pub fn jensen_gain(graph: &CausalGraph, leads: &[Vec<f64>], gains: &[f64]) -> f64 {
    let Some((lengths, _)) = edge_lengths(graph, leads, gains) else { return 0.0 };
    let (mut inv, mut log, mut n) = (0.0, 0.0, 0usize);
    for l in lengths.into_iter().flatten().filter(|&l| l > 0.0) {
        inv += 1.0 / l;
        log += l.log2();
        n += 1;
    }
    if n == 0 {
        return 0.0;
    }
    let g = (inv / n as f64).log2() + log / n as f64;
    if g.is_finite() {
        g
    } else {
        0.0
    }
}

/// The scale of every mesh position (`graph`'s order): `w_p = clamp((L_p / L̄)^γ, 1/4, 4)`
/// normalised to RMS 1, `L_p` the mean embedding length of the edges at `p`, `L̄` its mean over
/// the positions with edges, `γ = strength / 4` (by square roots). `leads` are the leading `U1` columns in
/// position order, `gains` their gains (as many). All ones when the embedding is degenerate
/// (every length zero, or one not finite). Bit-exact arithmetic (f64, sums in position /
/// adjacency / column order): shared by encoder and decoder.
pub fn vertex_scales(graph: &CausalGraph, leads: &[Vec<f64>], gains: &[f64], strength: u8) -> Vec<f64> {
    let k = graph.len();
    let ones = vec![1.0; k];
    if strength == 0 {
        return ones;
    }
    let Some((lengths, mean)) = edge_lengths(graph, leads, gains) else { return ones };
    let mut w: Vec<f64> = lengths
        .iter()
        .map(|l| {
            let s = l.map_or(1.0, |l| power(l / mean, strength));
            if s.is_finite() {
                s.clamp(1.0 / MAX_SCALE, MAX_SCALE)
            } else {
                1.0
            }
        })
        .collect();
    let rms = (w.iter().map(|x| x * x).sum::<f64>() / k as f64).sqrt();
    if !(rms.is_finite() && rms > 0.0) {
        return ones;
    }
    for x in &mut w {
        *x /= rms;
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A strip of triangles whose edges double in length along it.
    fn strip(k: usize) -> (CausalGraph, Vec<[f64; 3]>) {
        let tris: Vec<[u32; 3]> = (0..k as u32 - 2).map(|i| [i, i + 1, i + 2]).collect();
        let graph = CausalGraph::mesh(k, &tris);
        let pos =
            (0..k).map(|i| [2f64.powf(i as f64 / 4.0), (i % 2) as f64 * 2f64.powf(i as f64 / 4.0), 0.0]).collect();
        (graph, pos)
    }

    #[test]
    fn scales_follow_edge_length_with_rms_one() {
        let (graph, pos) = strip(12);
        let leads: Vec<Vec<f64>> =
            (0..3).map(|j| graph.order().iter().map(|&x| pos[x as usize][j]).collect()).collect();
        let gains = [1.0; 3];
        let w = vertex_scales(&graph, &leads, &gains, 4);
        let rms = (w.iter().map(|x| x * x).sum::<f64>() / w.len() as f64).sqrt();
        assert!((rms - 1.0).abs() < 1e-12, "rms {rms}");
        // Vertex 11's edges are far longer than vertex 0's.
        let at = |x: usize| w[graph.order().iter().position(|&o| o as usize == x).unwrap()];
        assert!(at(11) > 2.0 * at(0), "{} vs {}", at(11), at(0));
        let max = w.iter().cloned().fold(0.0, f64::max);
        let min = w.iter().cloned().fold(f64::INFINITY, f64::min);
        assert!(max / min <= MAX_SCALE * MAX_SCALE + 1e-9);
        // Strength 0 and degenerate embeddings give ones.
        assert!(vertex_scales(&graph, &leads, &gains, 0).iter().all(|&x| x == 1.0));
        // Half strength: the square root of the full strength's ratios (before the clamp).
        let half = vertex_scales(&graph, &leads, &gains, 2);
        assert!(
            at(11) / at(0)
                > half[graph.order().iter().position(|&o| o == 11).unwrap()]
                    / half[graph.order().iter().position(|&o| o == 0).unwrap()]
        );
        // The promised saving: positive on the strip, 0 on a degenerate embedding.
        assert!(jensen_gain(&graph, &leads, &gains) > 0.1);
        assert_eq!(jensen_gain(&graph, &vec![vec![0.0; 12]; 3], &gains), 0.0);
        assert_eq!(power(16.0, 1), 2.0);
        assert_eq!(power(16.0, 3), 8.0);
        let zero = vec![vec![0.0; 12]; 3];
        assert!(vertex_scales(&graph, &zero, &gains, 4).iter().all(|&x| x == 1.0));
        let nan = vec![vec![f64::NAN; 12]; 3];
        assert!(vertex_scales(&graph, &nan, &gains, 4).iter().all(|&x| x == 1.0));
        assert!(vertex_scales(&graph, &leads, &[f64::INFINITY; 3], 4).iter().all(|&x| x == 1.0));
    }
}
