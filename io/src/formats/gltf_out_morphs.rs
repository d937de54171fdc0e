//! The morph targets [`super::gltf_out`] writes, computed from the frames: the principal
//! component basis or one target per frame, the rigid motion split off beforehand, and the
//! `KHR_mesh_quantization` form. Pure geometry: no JSON and no buffer layout, so the numbers a
//! file holds can be read here apart from how they are stored.

use codec_core::{Animation, Error, Result};
use faer::Mat;

use super::gltf_out_rd;

/// Base mesh, morph targets (each `3V` values) and per-frame weights (`F × k`, frame-major).
pub(super) struct Morphs {
    pub(super) base: Vec<f32>,
    pub(super) targets: Vec<Vec<f32>>,
    pub(super) weights: Vec<f32>,
    pub(super) basis_kg: f64,
}

/// Mean + the leading principal components of the frames, from the eigen-decomposition of the
/// `F × F` Gram matrix of the centred frames (cheaper than the `3V × 3V` covariance): `targets`
/// of them, or (`None`) the fewest whose KG is at most `target_kg`.
pub(super) fn basis_morphs(a: &Animation, targets: Option<usize>, target_kg: f64) -> Result<Morphs> {
    let (frames, n) = (a.frame_count(), a.vertex_count() * 3);
    let gltf_out_rd::FrameEigen { mean, centred, values: lambda, vectors } = gltf_out_rd::frame_eigen(a)?;
    let energy = gltf_out_rd::kg_energy(a);
    let kg_with = |k: usize| {
        let rest: f64 = lambda[k.min(frames)..].iter().sum();
        if energy > 0.0 {
            100.0 * (rest / energy).sqrt()
        } else {
            0.0
        }
    };
    let rank = lambda.iter().filter(|&&l| l > 1e-12 * lambda[0].max(f64::MIN_POSITIVE)).count();
    let k = match targets {
        Some(k) => k.min(rank),
        None => (0..=rank).find(|&k| kg_with(k) <= target_kg).unwrap_or(rank),
    };
    let mut base = mean;
    let mut targets = Vec::with_capacity(k);
    let mut weights = vec![0.0f32; frames * k];
    for j in 0..k {
        let u = vectors.col(j);
        let sigma = lambda[j].sqrt();
        // Component j: direction d = Xᵀu/σ (unit length), coordinate c(f) = σ·u(f). Written as
        // target (hi − lo)·d with weight (c − lo)/(hi − lo) ∈ [0, 1] and lo·d moved into the base:
        // the same frames, and the weights stay inside the [0, 1] slider range that DCC importers
        // clamp shape keys to.
        let coordinate = |f: usize| sigma * u[f];
        let lo = (0..frames).map(coordinate).fold(f64::INFINITY, f64::min);
        let hi = (0..frames).map(coordinate).fold(f64::NEG_INFINITY, f64::max);
        let span = (hi - lo).max(f64::MIN_POSITIVE);
        let mut dir = vec![0.0f64; n];
        for f in 0..frames {
            let w = u[f] / sigma;
            for (d, &x) in dir.iter_mut().zip(centred.row(f).iter()) {
                *d += w * x;
            }
        }
        for (b, &d) in base.iter_mut().zip(&dir) {
            *b += lo * d;
        }
        targets.push(dir.iter().map(|&d| (d * span) as f32).collect());
        for f in 0..frames {
            weights[f * k + j] = ((coordinate(f) - lo) / span).clamp(0.0, 1.0) as f32;
        }
    }
    Ok(Morphs { base: base.iter().map(|&m| m as f32).collect(), targets, weights, basis_kg: kg_with(k) })
}

/// Frame 0 + one target per later frame.
pub(super) fn frame_morphs(a: &Animation) -> Morphs {
    let frames = a.frame_count();
    let base = a.frame(0).to_vec();
    let targets: Vec<Vec<f32>> =
        (1..frames).map(|f| a.frame(f).iter().zip(&base).map(|(x, b)| x - b).collect()).collect();
    let k = targets.len();
    let mut weights = vec![0.0f32; frames * k];
    for f in 1..frames {
        weights[f * k + f - 1] = 1.0;
    }
    Morphs { base, targets, weights, basis_kg: 0.0 }
}

/// Per-frame rigid motion: frame f ≈ R_f · local_f + t_f.
#[derive(Clone)]
pub(super) struct RigidMotion {
    pub(super) translations: Vec<f32>,
    pub(super) rotations: Vec<f32>,
}

/// Splits the rigid motion off every frame: Kabsch fit (SVD of the 3 × 3 cross-covariance,
/// reflection excluded) of the mean shape onto each frame; returns the frames brought back by
/// the inverse motion (`local_f = R_fᵀ (frame_f − t_f)`, an isometry per frame, so KG and the
/// PCA's discarded energy measure the same error in either space) and the motion, rotations as
/// unit quaternions `[x, y, z, w]` kept on one hemisphere from frame to frame.
pub(super) fn rigid_split(a: &Animation) -> Result<(Animation, RigidMotion)> {
    let (frames, v) = (a.frame_count(), a.vertex_count());
    let mut mean = vec![0.0f64; 3 * v];
    for f in 0..frames {
        for (m, &x) in mean.iter_mut().zip(a.frame(f)) {
            *m += x as f64 / frames as f64;
        }
    }
    let centroid = |p: &dyn Fn(usize) -> f64| -> [f64; 3] {
        std::array::from_fn(|k| (0..v).map(|i| p(3 * i + k)).sum::<f64>() / v as f64)
    };
    let cm = centroid(&|i| mean[i]);
    let mut local = Vec::with_capacity(frames * 3 * v);
    let (mut translations, mut rotations) = (Vec::new(), Vec::new());
    let mut previous = [0.0, 0.0, 0.0, 1.0];
    for f in 0..frames {
        let frame = a.frame(f);
        let cf = centroid(&|i| frame[i] as f64);
        // H = Σ (p − c_p)(q − c_q)ᵀ, p the mean shape, q the frame.
        let h = Mat::<f64>::from_fn(3, 3, |r, c| {
            (0..v).map(|i| (mean[3 * i + r] - cm[r]) * (frame[3 * i + c] as f64 - cf[c])).sum::<f64>()
        });
        let svd = h.thin_svd().map_err(|e| Error::Numerical {
            context: "glTF export".into(),
            step: "rigid fit (SVD of the 3 × 3 cross-covariance)".into(),
            detail: codec_core::error::debug_in_words(&e),
        })?;
        let (u, w) = (svd.U(), svd.V());
        let vu = w * u.transpose();
        let det = vu[(0, 0)] * (vu[(1, 1)] * vu[(2, 2)] - vu[(1, 2)] * vu[(2, 1)])
            - vu[(0, 1)] * (vu[(1, 0)] * vu[(2, 2)] - vu[(1, 2)] * vu[(2, 0)])
            + vu[(0, 2)] * (vu[(1, 0)] * vu[(2, 1)] - vu[(1, 1)] * vu[(2, 0)]);
        let d = Mat::<f64>::from_fn(3, 3, |r, c| {
            if r != c {
                0.0
            } else if r == 2 {
                det.signum()
            } else {
                1.0
            }
        });
        let r = w * d * u.transpose();
        let rot: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| r[(i, j)]));
        let t: [f64; 3] = std::array::from_fn(|k| cf[k] - (0..3).map(|j| rot[k][j] * cm[j]).sum::<f64>());
        for p in frame.chunks_exact(3) {
            let q: [f64; 3] = std::array::from_fn(|k| p[k] as f64 - t[k]);
            // Rᵀ q
            local.extend((0..3).map(|j| (0..3).map(|k| rot[k][j] * q[k]).sum::<f64>() as f32));
        }
        let mut quat = quaternion(&rot);
        if quat.iter().zip(&previous).map(|(a, b)| a * b).sum::<f64>() < 0.0 {
            quat = quat.map(|x| -x);
        }
        previous = quat;
        translations.extend(t.map(|x| x as f32));
        rotations.extend(quat.map(|x| x as f32));
    }
    let local = Animation::from_parts(v, a.triangles().to_vec(), local, a.frame_rate())?;
    Ok((local, RigidMotion { translations, rotations }))
}

/// Unit quaternion `[x, y, z, w]` of a rotation matrix (`m[row][column]`; Shepperd's method).
pub(super) fn quaternion(m: &[[f64; 3]; 3]) -> [f64; 4] {
    let trace = m[0][0] + m[1][1] + m[2][2];
    let q = if trace > 0.0 {
        let s = 0.5 / (trace + 1.0).sqrt();
        [(m[2][1] - m[1][2]) * s, (m[0][2] - m[2][0]) * s, (m[1][0] - m[0][1]) * s, 0.25 / s]
    } else if m[0][0] > m[1][1] && m[0][0] > m[2][2] {
        let s = 2.0 * (1.0 + m[0][0] - m[1][1] - m[2][2]).sqrt();
        [0.25 * s, (m[0][1] + m[1][0]) / s, (m[0][2] + m[2][0]) / s, (m[2][1] - m[1][2]) / s]
    } else if m[1][1] > m[2][2] {
        let s = 2.0 * (1.0 + m[1][1] - m[0][0] - m[2][2]).sqrt();
        [(m[0][1] + m[1][0]) / s, 0.25 * s, (m[1][2] + m[2][1]) / s, (m[0][2] - m[2][0]) / s]
    } else {
        let s = 2.0 * (1.0 + m[2][2] - m[0][0] - m[1][1]).sqrt();
        [(m[0][2] + m[2][0]) / s, (m[1][2] + m[2][1]) / s, 0.25 * s, (m[1][0] - m[0][1]) / s]
    };
    let len = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    q.map(|x| x / len)
}

/// `KHR_mesh_quantization` form of the morphs: positions and targets as 16-bit integers, the
/// node's translation and scale undoing the quantization.
pub(super) struct Quantized {
    pub(super) base: Vec<[i16; 3]>,
    pub(super) targets: Vec<Vec<[i16; 3]>>,
    pub(super) translation: [f32; 3],
    pub(super) scale: [f32; 3],
}

/// Quantizes the morphs: the base about the centre of the animation's bounding box (over every
/// frame) in steps of half its extent per axis / 32767 (coarser when a target reaches further);
/// each target rescaled to use the full 16-bit range (its weights multiplied by the same factor,
/// at most 1, so the played frames are unchanged up to rounding and weights stay in [0, 1]).
pub(super) fn quantize(animation: &Animation, morphs: &mut Morphs) -> Quantized {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in animation.positions().chunks_exact(3) {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a] as f64);
            hi[a] = hi[a].max(p[a] as f64);
        }
    }
    let widest = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max).max(1e-30);
    // A flat axis still gets a usable step (targets may move along it).
    let mut half: [f64; 3] = std::array::from_fn(|a| ((hi[a] - lo[a]) / 2.0).max(widest * 1e-3));
    let centre: [f64; 3] = std::array::from_fn(|a| (hi[a] + lo[a]) / 2.0);
    // A target's reach: its largest coordinate in units of the half extent. A target reaching
    // past the half extent (a walk's last frame against its first) would need a weight above 1
    // to fit 16 bits, which DCC importers clamp to their [0, 1] sliders: the step grows instead.
    let reach = |t: &[f32], half: &[f64; 3]| {
        t.chunks_exact(3).flat_map(|d| (0..3).map(move |a| (d[a] as f64).abs() / half[a])).fold(0.0, f64::max)
    };
    let widest_reach = morphs.targets.iter().map(|t| reach(t, &half)).fold(1.0, f64::max);
    half = half.map(|h| h * widest_reach);
    let to_short = |x: f64| x.round().clamp(-32767.0, 32767.0) as i16;
    let base = morphs
        .base
        .chunks_exact(3)
        .map(|p| std::array::from_fn(|a| to_short((p[a] as f64 - centre[a]) / half[a] * 32767.0)))
        .collect();
    let k = morphs.targets.len();
    let mut targets = Vec::with_capacity(k);
    for (j, t) in morphs.targets.iter().enumerate() {
        let r = reach(t, &half);
        let factor = if r > 0.0 { r } else { 1.0 };
        targets.push(
            t.chunks_exact(3)
                .map(|d| std::array::from_fn(|a| to_short(d[a] as f64 / (factor * half[a]) * 32767.0)))
                .collect(),
        );
        // factor ≤ 1: weights in [0, 1] stay there.
        for f in 0..morphs.weights.len() / k.max(1) {
            morphs.weights[f * k + j] = (morphs.weights[f * k + j] as f64 * factor) as f32;
        }
    }
    Quantized { base, targets, translation: centre.map(|c| c as f32), scale: half.map(|h| (h / 32767.0) as f32) }
}
