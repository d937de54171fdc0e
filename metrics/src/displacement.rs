//! Metrics on vertex displacements: the KG error, MSE / RMSE, the maximum displacement, and
//! per-vertex error fields for plots.
//!
//! All sums are accumulated in `f64`. Per-frame work runs in parallel with rayon; the
//! per-frame partial sums are collected into a vector and added in frame order, so the
//! result does not depend on the thread count.

use codec_core::{Animation, Error, Result};
use rayon::prelude::*;
use serde::Serialize;

use crate::common::{check_compatible, point, vertex_dist2, CTX};

/// KG error (Karni & Gotsman 2004), in the consensus form used by the codec papers
/// (e.g. SAC eq. 14, Luo et al. eq. 11):
///
/// `KG = 100 · ‖A − Â‖_F / ‖A − E(A)‖_F`
///
/// where `A` is the reference (`3V × F`), `Â` the candidate and `E(A)` holds, in every
/// column (frame), the centroid of the *reference* frame per coordinate. The candidate is
/// never centred. Fails if the animations do not match or if `‖A − E(A)‖_F = 0` (every
/// reference frame collapses to a single point, so the ratio is undefined).
pub fn kg_error(reference: &Animation, candidate: &Animation) -> Result<f64> {
    check_compatible(reference, candidate)?;
    let per_frame: Vec<(f64, f64)> = (0..reference.frame_count())
        .into_par_iter()
        .map(|t| kg_frame(reference.frame(t), candidate.frame(t)))
        .collect();
    let (num, den) = per_frame.iter().fold((0.0, 0.0), |(n, d), &(a, b)| (n + a, d + b));
    kg_from_sums(num, den)
}

/// One frame's KG sums `(‖a − b‖², ‖a − E(a)‖²)` (reference `a`, candidate `b`, interleaved xyz):
/// the terms [`kg_error`] and the streaming evaluator add in frame order.
pub(crate) fn kg_frame(a: &[f32], b: &[f32]) -> (f64, f64) {
    let n = a.len() / 3;
    let mut c = [0.0f64; 3];
    for v in 0..n {
        let p = point(a, v);
        for k in 0..3 {
            c[k] += p[k];
        }
    }
    for ck in &mut c {
        *ck /= n as f64;
    }
    let (mut num, mut den) = (0.0, 0.0);
    for v in 0..n {
        num += vertex_dist2(a, b, v);
        let p = point(a, v);
        den += (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2);
    }
    (num, den)
}

/// The KG error from the sums of every frame, or the error saying it is undefined.
pub(crate) fn kg_from_sums(num: f64, den: f64) -> Result<f64> {
    if den <= 0.0 {
        return Err(Error::InvalidAnimation(format!(
            "{CTX}: KG error is undefined: every reference frame is a single point (‖A − E(A)‖ = 0)"
        )));
    }
    Ok(100.0 * (num / den).sqrt())
}

/// MSE-family statistics of the vertex displacement `‖a_tv − â_tv‖`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DisplacementStats {
    /// Mean over all vertex-frames of the squared Euclidean displacement.
    pub mse: f64,
    /// `sqrt(mse)`.
    pub rmse: f64,
    /// `mse / diag²` with `diag` the reference's bounding-box diagonal over all frames
    /// (dimensionless); `None` when the diagonal is zero.
    pub mse_relative: Option<f64>,
    /// `rmse / diag`; `None` when the diagonal is zero.
    pub rmse_relative: Option<f64>,
    /// Largest displacement of any vertex in any frame.
    pub max_error: f64,
    /// `(frame, vertex)` where `max_error` occurs (the first one in frame-major order).
    pub max_error_at: (usize, usize),
    /// RMSE of each frame (mean over that frame's vertices), for plots.
    pub frame_rmse: Vec<f64>,
    /// Bounding-box diagonal of the reference over all frames.
    pub bbox_diagonal: f64,
}

/// Computes [`DisplacementStats`]. Fails if the animations do not match.
pub fn displacement_stats(reference: &Animation, candidate: &Animation) -> Result<DisplacementStats> {
    check_compatible(reference, candidate)?;
    let n = reference.vertex_count();
    // Per frame: (sum of squared displacements, largest squared displacement, its vertex).
    let per_frame: Vec<(f64, f64, usize)> = (0..reference.frame_count())
        .into_par_iter()
        .map(|t| displacement_frame(reference.frame(t), candidate.frame(t)))
        .collect();
    let mut sum = 0.0;
    let (mut max, mut at) = (-1.0, (0, 0));
    for (t, &(s, m, v)) in per_frame.iter().enumerate() {
        sum += s;
        if m > max {
            max = m;
            at = (t, v);
        }
    }
    let frame_rmse = per_frame.iter().map(|&(s, _, _)| (s / n as f64).sqrt()).collect();
    Ok(summarize_displacement(sum, max, at, n * reference.frame_count(), reference.bounding_box_diagonal(), frame_rmse))
}

/// [`DisplacementStats`] from the sums over every vertex-frame: `sum` of squared
/// displacements over `count` vertex-frames, the largest squared one `max2` at `at`, and the
/// reference's bounding-box diagonal `diag`.
pub(crate) fn summarize_displacement(
    sum: f64,
    max2: f64,
    at: (usize, usize),
    count: usize,
    diag: f64,
    frame_rmse: Vec<f64>,
) -> DisplacementStats {
    let mse = sum / count as f64;
    let rmse = mse.sqrt();
    let rel = |x: f64, p: i32| (diag > 0.0).then(|| x / diag.powi(p));
    DisplacementStats {
        mse,
        rmse,
        mse_relative: rel(mse, 2),
        rmse_relative: rel(rmse, 1),
        max_error: max2.max(0.0).sqrt(),
        max_error_at: at,
        frame_rmse,
        bbox_diagonal: diag,
    }
}

/// One frame's displacement terms: (sum of squared displacements, largest squared
/// displacement or −1 for an empty frame, its first vertex).
pub(crate) fn displacement_frame(a: &[f32], b: &[f32]) -> (f64, f64, usize) {
    let (mut sum, mut max, mut at) = (0.0, -1.0, 0);
    for v in 0..a.len() / 3 {
        let d2 = vertex_dist2(a, b, v);
        sum += d2;
        if d2 > max {
            max = d2;
            at = v;
        }
    }
    (sum, max, at)
}

/// Per-vertex displacement fields over the whole animation, for heatmaps.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VertexDisplacement {
    /// Per vertex: RMS over frames of the displacement, `sqrt(mean_t ‖a_tv − â_tv‖²)`.
    pub rms: Vec<f64>,
    /// Per vertex: the largest displacement over frames.
    pub max: Vec<f64>,
}

/// Computes [`VertexDisplacement`]. Parallel over blocks of vertices, sequential over frames
/// inside a block, so each vertex's sum is always taken in frame order.
pub fn per_vertex_displacement(reference: &Animation, candidate: &Animation) -> Result<VertexDisplacement> {
    check_compatible(reference, candidate)?;
    const BLOCK: usize = 512;
    let n = reference.vertex_count();
    let frames = reference.frame_count();
    let blocks: Vec<(Vec<f64>, Vec<f64>)> = (0..n.div_ceil(BLOCK))
        .into_par_iter()
        .map(|b| {
            let (lo, hi) = (b * BLOCK, ((b + 1) * BLOCK).min(n));
            let mut sum = vec![0.0; hi - lo];
            let mut max = vec![0.0f64; hi - lo];
            for t in 0..frames {
                let (fa, fb) = (reference.frame(t), candidate.frame(t));
                for v in lo..hi {
                    let d2 = vertex_dist2(fa, fb, v);
                    sum[v - lo] += d2;
                    max[v - lo] = max[v - lo].max(d2);
                }
            }
            let rms = sum.iter().map(|s| (s / frames as f64).sqrt()).collect();
            (rms, max.iter().map(|m| m.sqrt()).collect())
        })
        .collect();
    let mut out = VertexDisplacement { rms: Vec::with_capacity(n), max: Vec::with_capacity(n) };
    for (r, m) in blocks {
        out.rms.extend(r);
        out.max.extend(m);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn anim(v: usize, positions: Vec<f32>) -> Animation {
        Animation::from_parts(v, vec![], positions, 30.0).unwrap()
    }

    /// Two vertices, two frames.
    /// Reference frame 0: (0,0,0), (2,0,0)  centroid (1,0,0), spread² = 1 + 1 = 2
    /// Reference frame 1: (0,0,0), (0,4,0)  centroid (0,2,0), spread² = 4 + 4 = 8
    /// ‖A − E(A)‖² = 10.
    /// Candidate: frame 0 vertex 1 moved by (0,1,0) → d² = 1; frame 1 vertex 0 moved by
    /// (0,0,2) → d² = 4. ‖A − Â‖² = 5.  KG = 100·sqrt(5/10) = 70.7106781…
    /// MSE = 5 / 4 vertex-frames = 1.25; RMSE = 1.1180340; max displacement 2 at (1, 0).
    /// Bounding box over all frames: [0,2]×[0,4]×[0,0], diagonal sqrt(20).
    /// mse_relative = 1.25/20 = 0.0625; rmse_relative = sqrt(1.25/20) = 0.25.
    /// frame RMSE: frame 0 sqrt(1/2), frame 1 sqrt(4/2).
    /// Per vertex: v0 d² = [0, 4] → rms sqrt(2), max 2; v1 d² = [1, 0] → rms sqrt(0.5), max 1.
    fn pair() -> (Animation, Animation) {
        let r = anim(2, vec![0., 0., 0., 2., 0., 0., 0., 0., 0., 0., 4., 0.]);
        let c = anim(2, vec![0., 0., 0., 2., 1., 0., 0., 0., 2., 0., 4., 0.]);
        (r, c)
    }

    #[test]
    fn kg_matches_hand_computation() {
        let (r, c) = pair();
        let kg = kg_error(&r, &c).unwrap();
        assert!((kg - 100.0 * 0.5f64.sqrt()).abs() < 1e-12, "{kg}");
        assert_eq!(kg_error(&r, &r).unwrap(), 0.0);
    }

    #[test]
    fn kg_uses_reference_centroid_not_candidate() {
        // Translating the candidate by (0,0,3) everywhere: ‖A − Â‖² = 4 · 9 = 36, so
        // KG = 100·sqrt(36/10); centring the reconstruction would wrongly give 0.
        let (r, _) = pair();
        let shifted: Vec<f32> = r.positions().chunks(3).flat_map(|p| [p[0], p[1], p[2] + 3.0]).collect();
        let kg = kg_error(&r, &anim(2, shifted)).unwrap();
        assert!((kg - 100.0 * 3.6f64.sqrt()).abs() < 1e-12, "{kg}");
    }

    #[test]
    fn kg_undefined_for_collapsed_reference() {
        let r = anim(2, vec![1.0; 6]);
        let e = kg_error(&r, &r).unwrap_err().to_string();
        assert!(e.contains("KG error is undefined"), "{e}");
    }

    #[test]
    fn displacement_matches_hand_computation() {
        let (r, c) = pair();
        let s = displacement_stats(&r, &c).unwrap();
        assert!((s.mse - 1.25).abs() < 1e-15);
        assert!((s.rmse - 1.25f64.sqrt()).abs() < 1e-15);
        assert!((s.mse_relative.unwrap() - 0.0625).abs() < 1e-15);
        assert!((s.rmse_relative.unwrap() - 0.25).abs() < 1e-15);
        assert_eq!(s.max_error, 2.0);
        assert_eq!(s.max_error_at, (1, 0));
        assert!((s.bbox_diagonal - 20f64.sqrt()).abs() < 1e-12);
        assert!((s.frame_rmse[0] - 0.5f64.sqrt()).abs() < 1e-15);
        assert!((s.frame_rmse[1] - 2f64.sqrt()).abs() < 1e-15);

        let pv = per_vertex_displacement(&r, &c).unwrap();
        assert!((pv.rms[0] - 2f64.sqrt()).abs() < 1e-15 && (pv.rms[1] - 0.5f64.sqrt()).abs() < 1e-15);
        assert_eq!(pv.max, vec![2.0, 1.0]);
    }

    #[test]
    fn identical_input_gives_zero_and_degenerate_box_gives_none() {
        let r = anim(2, vec![1.0; 6]);
        let s = displacement_stats(&r, &r).unwrap();
        assert_eq!((s.mse, s.max_error), (0.0, 0.0));
        assert_eq!(s.mse_relative, None);
        assert_eq!(s.rmse_relative, None);
    }

    #[test]
    fn per_vertex_spans_several_blocks() {
        // 1100 vertices (3 blocks of 512); vertex v displaced by v·0.001 along x in frame 0 only,
        // so rms_v = v·0.001/sqrt(2) (two frames), max_v = v·0.001.
        let n = 1100;
        let r = anim(n, vec![0.0; n * 6]);
        let mut p = vec![0.0f32; n * 6];
        for v in 0..n {
            p[3 * v] = v as f32 * 0.001;
        }
        let c = anim(n, p);
        let pv = per_vertex_displacement(&r, &c).unwrap();
        for v in [0, 511, 512, 1099] {
            let d = (v as f32 * 0.001) as f64;
            assert!((pv.max[v] - d).abs() < 1e-12);
            assert!((pv.rms[v] - d / 2f64.sqrt()).abs() < 1e-12);
        }
    }
}
