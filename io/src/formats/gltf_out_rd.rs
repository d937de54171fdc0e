//! The compressed basis layout of the glTF export: principal components quantized
//! at steps chosen for a KG target, instead of every component at the full 16-bit range.
//!
//! Transform coding (reverse water-filling, e.g. Cover & Thomas §10.3.3): with orthogonal
//! components, the squared error of the played frames is the sum of each component's error
//! weighted by the energy of its weights over time (`A_j = Σ_f a_j(f)²`), plus the base's
//! error on every frame (`A = F`). Equal weighted error per component (`A_j · s_j²` constant) is
//! the high-rate optimum, so component `j` is quantized at step `s_j = D / √A_j` and the base at
//! `D / √F`; a component whose every coordinate rounds to zero at its step is dropped (the
//! "fewest targets" come out of the rounding). One number, `D`, is then searched for the KG
//! target, and the exact KG of the quantized file (computed from the integers written) is
//! checked before it is returned.
//!
//! glTF form (`KHR_mesh_quantization`): the node's uniform scale `S` is the coarsest step; a
//! target's finer step `s_j` lives in its weights (stored weight `a_j(f) · s_j / S`), so every
//! weight stays in [0, 1] (`a_j` is the component's weight shifted and scaled to [0, 1], its
//! minimum folded into the base): Blender clamps shape-key values to its sliders' [0, 1]. The base, quantized at `S`, gets its finer step back from one more target, the
//! base's residual, at a constant weight `s_b / S`.
//!
//! That allocation serves an explicit target count (`--targets K`). Without one, the export
//! uses [`quantized_basis_coded`]: steps chosen on the bytes meshoptimizer's vertex codec
//! actually spends, the base normalized (no residual target), the weights in the form of the
//! `EXPONENTIAL` filter.

use codec_core::{linalg, Animation, Error, Result};

use faer::Mat;

/// Principal components of the frames about their mean.
pub(super) struct Pca {
    mean: Vec<f64>,
    /// Row j: component j's unit direction (3V values).
    dirs: Mat<f64>,
    /// `F × r`: frame f's coordinate on component j (σ_j u_j(f)).
    coeffs: Mat<f64>,
    /// Eigenvalues (squared singular values), descending.
    lambda: Vec<f64>,
    /// KG's denominator: Σ over frames of the squared distances to the frame's centroid.
    pub(super) energy: f64,
}

/// KG's denominator (Karni & Gotsman): the frames about their own centroids.
pub(super) fn kg_energy(a: &Animation) -> f64 {
    let mut energy = 0.0;
    for f in 0..a.frame_count() {
        let frame = a.frame(f);
        let mut c = [0.0f64; 3];
        for p in frame.chunks_exact(3) {
            (0..3).for_each(|k| c[k] += p[k] as f64);
        }
        c.iter_mut().for_each(|x| *x /= a.vertex_count() as f64);
        energy += frame.chunks_exact(3).map(|p| (0..3).map(|k| (p[k] as f64 - c[k]).powi(2)).sum::<f64>()).sum::<f64>();
    }
    energy
}

/// KG (%) of `played` against `a` (same vertices), in f64.
pub(super) fn kg_between(a: &Animation, played: &Animation) -> f64 {
    let err: f64 = a.positions().iter().zip(played.positions()).map(|(x, y)| (*x as f64 - *y as f64).powi(2)).sum();
    let energy = kg_energy(a);
    if energy > 0.0 {
        100.0 * (err / energy).sqrt()
    } else {
        0.0
    }
}

/// The frames' mean, the centred frames (`F × 3V`) and the eigen-decomposition of their
/// `F × F` Gram matrix (descending eigenvalues, clamped at zero; eigenvectors as columns):
/// what [`pca`] and the uncompressed basis export (`gltf_out_morphs::basis_morphs`) start from.
pub(super) struct FrameEigen {
    pub mean: Vec<f64>,
    pub centred: Mat<f64>,
    pub values: Vec<f64>,
    pub vectors: Mat<f64>,
}

pub(super) fn frame_eigen(a: &Animation) -> Result<FrameEigen> {
    let (frames, n) = (a.frame_count(), a.vertex_count() * 3);
    let mut mean = vec![0.0f64; n];
    for f in 0..frames {
        for (m, &x) in mean.iter_mut().zip(a.frame(f)) {
            *m += x as f64;
        }
    }
    mean.iter_mut().for_each(|m| *m /= frames as f64);
    let centred = Mat::<f64>::from_fn(frames, n, |f, i| a.frame(f)[i] as f64 - mean[i]);
    // Sequential faer calls (`codec_core::linalg`): the same bytes at any thread count.
    let gram = linalg::mul(centred.as_ref(), centred.transpose());
    let (values, vectors) = linalg::sym_eig_desc(gram.as_ref())
        .map_err(|e| e.numerical("glTF export", "eigen-decomposition of the frames' Gram matrix"))?;
    Ok(FrameEigen { mean, centred, values, vectors })
}

/// The frames' principal components (eigen-decomposition of the `F × F` Gram matrix).
pub(super) fn pca(a: &Animation) -> Result<Pca> {
    let (frames, n) = (a.frame_count(), a.vertex_count() * 3);
    let FrameEigen { mean, centred, values: all, vectors } = frame_eigen(a)?;
    let top = all.first().copied().unwrap_or(0.0).max(f64::MIN_POSITIVE);
    let rank = all.iter().filter(|&&l| l > 1e-12 * top).count();
    let lambda = all[..rank].to_vec();
    let u = Mat::<f64>::from_fn(frames, rank, |f, j| vectors[(f, j)]);
    // Xᵀu_j = σ_j · dir_j.
    let mut dirs = linalg::mul(u.transpose(), centred.as_ref());
    for j in 0..rank {
        let sigma = lambda[j].sqrt();
        for i in 0..n {
            dirs[(j, i)] /= sigma;
        }
    }
    let coeffs = Mat::<f64>::from_fn(frames, rank, |f, j| u[(f, j)] * lambda[j].sqrt());
    Ok(Pca { mean, dirs, coeffs, lambda, energy: kg_energy(a) })
}

/// The frames as differences from frame 0, in the same form as [`pca`]: "component" j is
/// frame j + 1 minus frame 0, its weight 1 on that frame and 0 elsewhere. Short clips of
/// articulated characters (24 frames of a walk) have no low-rank structure for the principal
/// components to use, and their quantized differences code smaller.
pub(super) fn differences(a: &Animation) -> Pca {
    let (frames, n) = (a.frame_count(), a.vertex_count() * 3);
    let first: Vec<f64> = a.frame(0).iter().map(|&x| x as f64).collect();
    let k = frames.saturating_sub(1);
    let dirs = Mat::<f64>::from_fn(k, n, |j, i| a.frame(j + 1)[i] as f64 - first[i]);
    let coeffs = Mat::<f64>::from_fn(frames, k, |f, j| if f == j + 1 { 1.0 } else { 0.0 });
    let lambda = (0..k).map(|j| (0..n).map(|i| dirs[(j, i)].powi(2)).sum()).collect();
    Pca { mean: first, dirs, coeffs, lambda, energy: kg_energy(a) }
}

/// The frames as successive differences, in the same form as [`pca`]: "component" j is frame
/// j + 1 minus frame j, its weight 1 on frames j + 1 … F − 1 and 0 before (frame f is frame 0
/// plus the first f differences). A frame-to-frame step is smaller than the whole way from
/// frame 0, so it quantizes into fewer bits; each difference's error is carried by every later
/// frame, which the weights' energy (`F − 1 − j`) charges it in the step allocation.
pub(super) fn successive_differences(a: &Animation) -> Pca {
    let (frames, n) = (a.frame_count(), a.vertex_count() * 3);
    let first: Vec<f64> = a.frame(0).iter().map(|&x| x as f64).collect();
    let k = frames.saturating_sub(1);
    let dirs = Mat::<f64>::from_fn(k, n, |j, i| a.frame(j + 1)[i] as f64 - a.frame(j)[i] as f64);
    let coeffs = Mat::<f64>::from_fn(frames, k, |f, j| if f > j { 1.0 } else { 0.0 });
    let lambda = (0..k).map(|j| (0..n).map(|i| dirs[(j, i)].powi(2)).sum()).collect();
    Pca { mean: first, dirs, coeffs, lambda, energy: kg_energy(a) }
}

/// A quantized morph target: integers in units of `S · weight`.
pub(super) struct QTarget {
    pub(super) values: Vec<[i16; 3]>,
    /// Every value fits a signed byte (written as BYTE, 4-byte records, when
    /// [`narrow_targets`] says so for the form's vertex codec version).
    pub(super) bytes: bool,
}

/// The quantized basis as written.
pub(super) struct QBasis {
    pub(super) translation: [f64; 3],
    pub(super) scale: f64,
    pub(super) base: Vec<[i16; 3]>,
    /// The base is written as normalized SHORT (`KHR_mesh_quantization`): it plays
    /// `scale · base / 32767`, a step 32767× finer than the node scale, so the targets' steps
    /// (`scale · weight`) can all be coarser than the base's with weights in [0, 1].
    pub(super) base_normalized: bool,
    /// Every column of weights is `m · 2^e` with one exponent per column and a
    /// 16-bit mantissa ([`exponential_words`]), written through `EXT_meshopt_compression`'s
    /// `EXPONENTIAL` filter.
    pub(super) weights_exponential: bool,
    pub(super) targets: Vec<QTarget>,
    /// `F × K`, frame-major, each in [0, 1].
    pub(super) weights: Vec<f32>,
    /// Principal components kept (the residual target, when written, is the last target).
    pub(super) components: usize,
    /// KG (%) of the frames these integers and weights play, computed in f64.
    pub(super) kg: f64,
    /// KG (%) the search estimated (before the exact check).
    estimate: f64,
}

/// A component in [0, 1]-weight form: `frame ≈ … + a(f) · t + min · dir`.
struct Unit {
    /// `(max − min)` of its coordinates over the frames; the target is `range · dir`.
    range: f64,
    min: f64,
    /// `a(f) = (w(f) − min) / range`.
    a: Vec<f64>,
    /// Σ_f a(f)².
    weight_energy: f64,
    /// max |range · dir|.
    reach: f64,
}

fn units(p: &Pca, limit: usize) -> Vec<Unit> {
    let frames = p.coeffs.nrows();
    (0..p.lambda.len().min(limit))
        .map(|j| {
            let w: Vec<f64> = (0..frames).map(|f| p.coeffs[(f, j)]).collect();
            let min = w.iter().copied().fold(f64::INFINITY, f64::min);
            let max = w.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let range = (max - min).max(f64::MIN_POSITIVE);
            let a: Vec<f64> = w.iter().map(|x| (x - min) / range).collect();
            let reach = (0..p.dirs.ncols()).map(|i| p.dirs[(j, i)].abs()).fold(0.0, f64::max) * range;
            Unit { range, min, weight_energy: a.iter().map(|x| x * x).sum(), a, reach }
        })
        .collect()
}

fn round_i16(x: f64) -> i16 {
    x.round().clamp(-32767.0, 32767.0) as i16
}

/// Quantizes at distortion level `d` (see the module comment), writing at most `max_targets`
/// targets (the base's residual only when a component left room for it); `exact` also computes
/// the KG the integers play (else only the estimate).
fn quantize_at(a: &Animation, p: &Pca, units: &[Unit], d: f64, max_targets: usize, exact: bool) -> QBasis {
    let (frames, n) = (p.coeffs.nrows(), p.mean.len());
    // Steps; a component whose reach rounds to zero is dropped.
    let mut kept = Vec::new();
    let mut dropped_energy = 0.0;
    for (j, u) in units.iter().enumerate() {
        let step = (d / u.weight_energy.max(f64::MIN_POSITIVE).sqrt()).max(u.reach / 32767.0);
        if u.reach >= step / 2.0 {
            kept.push((j, step));
        } else {
            dropped_energy += p.lambda[j];
        }
    }
    dropped_energy += p.lambda[units.len()..].iter().sum::<f64>();
    let mut base = p.mean.clone();
    for &(j, _) in &kept {
        for (i, b) in base.iter_mut().enumerate() {
            *b += units[j].min * p.dirs[(j, i)];
        }
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for q in base.chunks_exact(3) {
        for k in 0..3 {
            lo[k] = lo[k].min(q[k]);
            hi[k] = hi[k].max(q[k]);
        }
    }
    let centre: [f64; 3] = std::array::from_fn(|k| (lo[k] + hi[k]) / 2.0);
    let half = (0..3).map(|k| (hi[k] - lo[k]) / 2.0).fold(0.0, f64::max);
    let base_step = (d / (frames as f64).sqrt()).max(half / 32767.0).max(f64::MIN_POSITIVE);
    let scale = kept.iter().map(|&(_, s)| s).fold(base_step, f64::max);
    let base_int: Vec<[i16; 3]> =
        base.chunks_exact(3).map(|q| std::array::from_fn(|k| round_i16((q[k] - centre[k]) / scale))).collect();
    let mut estimate = dropped_energy;
    let mut targets = Vec::new();
    let mut columns: Vec<Vec<f32>> = Vec::new();
    // The components, then the base's residual.
    for &(j, step) in &kept {
        let u = &units[j];
        let mut err = 0.0;
        let values: Vec<[i16; 3]> = (0..n / 3)
            .map(|v| {
                std::array::from_fn(|k| {
                    let t = u.range * p.dirs[(j, 3 * v + k)];
                    let q = round_i16(t / step);
                    err += (t - q as f64 * step).powi(2);
                    q
                })
            })
            .collect();
        estimate += u.weight_energy * err;
        let g = step / scale;
        columns.push(u.a.iter().map(|&x| (x * g) as f32).collect());
        targets.push(values);
    }
    let components = targets.len();
    let mut base_err = 0.0;
    if targets.len() < max_targets && scale > base_step * (1.0 + 1e-9) {
        let values: Vec<[i16; 3]> = base
            .chunks_exact(3)
            .zip(&base_int)
            .map(|(q, b)| {
                std::array::from_fn(|k| {
                    let r = q[k] - centre[k] - b[k] as f64 * scale;
                    let i = round_i16(r / base_step);
                    base_err += (r - i as f64 * base_step).powi(2);
                    i
                })
            })
            .collect();
        if values.iter().any(|v| v.iter().any(|&x| x != 0)) {
            targets.push(values);
            columns.push(vec![(base_step / scale) as f32; frames]);
        }
    } else {
        base_err = base
            .chunks_exact(3)
            .zip(&base_int)
            .map(|(q, b)| (0..3).map(|k| (q[k] - centre[k] - b[k] as f64 * scale).powi(2)).sum::<f64>())
            .sum();
    }
    estimate += frames as f64 * base_err;
    let k = targets.len();
    let mut weights = vec![0.0f32; frames * k];
    for (j, c) in columns.iter().enumerate() {
        for f in 0..frames {
            weights[f * k + j] = c[f];
        }
    }
    let kg_of = |e: f64| if p.energy > 0.0 { 100.0 * (e.max(0.0) / p.energy).sqrt() } else { 0.0 };
    let mut out = QBasis {
        translation: centre,
        scale,
        base: base_int,
        base_normalized: false,
        weights_exponential: false,
        targets: targets
            .into_iter()
            .map(|values| {
                let bytes = values.iter().all(|v| v.iter().all(|&x| (-127..=127).contains(&x)));
                QTarget { values, bytes }
            })
            .collect(),
        weights,
        components,
        kg: f64::NAN,
        estimate: kg_of(estimate),
    };
    if exact {
        out.kg = kg_of(played_error(a, &out));
    }
    out
}

/// Σ over frames and coordinates of (played − input)², the played frames computed from the
/// integers and f32 weights as written.
fn played_error(a: &Animation, q: &QBasis) -> f64 {
    let (frames, v, k) = (a.frame_count(), a.vertex_count(), q.targets.len());
    let w = Mat::<f64>::from_fn(frames, k, |f, j| q.weights[f * k + j] as f64);
    let t = Mat::<f64>::from_fn(k, 3 * v, |j, i| q.targets[j].values[i / 3][i % 3] as f64);
    let moved = linalg::mul(w.as_ref(), t.as_ref());
    let mut err = 0.0;
    let unit = if q.base_normalized { 1.0 / 32767.0 } else { 1.0 };
    for f in 0..frames {
        let frame = a.frame(f);
        for i in 0..3 * v {
            let base = q.base[i / 3][i % 3] as f64 * unit;
            let played = q.translation[i % 3] + q.scale * (base + moved[(f, i)]);
            err += (played - frame[i] as f64).powi(2);
        }
    }
    err
}

/// The quantized basis meeting `target_kg` (KG %) with the fewest bytes this scheme finds,
/// using at most `components` components and `targets` targets in all (components and the
/// base's residual): the distortion level is bisected on the estimate, then the exact KG is
/// checked and the aim lowered until it holds (at most a few rounds; the finest quantization is
/// returned when even that misses).
pub(super) fn quantized_basis(
    a: &Animation,
    p: &Pca,
    target_kg: f64,
    (components, targets): (usize, usize),
) -> Result<QBasis> {
    let units = units(p, components);
    let diag = a.bounding_box_diagonal().max(f64::MIN_POSITIVE);
    let mut aim = target_kg;
    let mut best: Option<QBasis> = None;
    for _ in 0..6 {
        // Bisection on log D between a step far below the 16-bit floor and the diagonal.
        let (mut lo, mut hi) = ((diag * 1e-9).ln(), diag.ln());
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if quantize_at(a, p, &units, mid.exp(), targets, false).estimate <= aim {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let q = quantize_at(a, p, &units, lo.exp(), targets, true);
        if !q.kg.is_finite() {
            return Err(Error::InvalidAnimation("glTF export: the quantized basis is not finite".into()));
        }
        let met = q.kg <= target_kg;
        let overshoot = q.kg / target_kg;
        if met || best.as_ref().is_none_or(|b| q.kg < b.kg) {
            best = Some(q);
        }
        if met {
            break;
        }
        // Aim lower by the measured overshoot (and a little more).
        aim /= overshoot * 1.01;
    }
    Ok(best.expect("at least one round"))
}

/// Bytes meshoptimizer's vertex codec (format `version`: 0 under `EXT_meshopt_compression`,
/// 1 under `KHR_meshopt_compression`) spends on `values` in the records the writer stores them
/// in: under version 0, signed bytes in 4-byte records when every value fits, else (and always
/// under version 1, see [`narrow_targets`]) 16-bit integers in 8-byte records.
pub(super) fn coded_bytes(values: &[[i16; 3]], version: i32) -> usize {
    let narrow = narrow_targets(version) && values.iter().all(|v| v.iter().all(|&x| (-127..=127).contains(&x)));
    let encoded = if narrow {
        let records: Vec<[u8; 4]> =
            values.iter().map(|p| [p[0] as i8 as u8, p[1] as i8 as u8, p[2] as i8 as u8, 0]).collect();
        encode_vertex_records(&records, version)
    } else {
        let records: Vec<[u8; 8]> = values
            .iter()
            .map(|p| {
                let mut r = [0u8; 8];
                for k in 0..3 {
                    r[2 * k..2 * k + 2].copy_from_slice(&p[k].to_le_bytes());
                }
                r
            })
            .collect();
        encode_vertex_records(&records, version)
    };
    encoded.map_or(usize::MAX, |e| e.len())
}

/// Whether targets whose values all fit a signed byte are written as BYTE (4-byte records, a
/// view of their own) in vertex codec format `version`. Version 0 codes bytes, so a 16-bit
/// value costs its high byte's deltas too; version 1 codes 16-bit channels as 16-bit deltas at
/// the bit width they need, so small values cost the same in SHORT records and the second view
/// (its JSON, ~200 bytes) is saved.
pub(super) fn narrow_targets(version: i32) -> bool {
    version == 0
}

/// `EXT_meshopt_compression`'s `EXPONENTIAL` filter form of non-negative `weights` (`k` per
/// frame, frame-major): each 32-bit word holds a signed 24-bit mantissa and, in its high byte,
/// a signed exponent (the spec's "Exponential filter"); every column shares the exponent that
/// puts its largest weight in [2^15, 2^16), so a weight keeps 16 bits relative to its column's
/// largest and the codec sees a constant exponent byte. Weights already in this form come back
/// unchanged.
pub(super) fn exponential_words(weights: &[f32], k: usize) -> Vec<u32> {
    let exponents: Vec<i32> = (0..k)
        .map(|j| {
            let top = weights.iter().skip(j).step_by(k.max(1)).fold(0.0f64, |m, &w| m.max(w as f64));
            if top > 0.0 {
                (top.log2().floor() as i32 - 15).clamp(-100, 100)
            } else {
                0
            }
        })
        .collect();
    weights
        .iter()
        .enumerate()
        .map(|(i, &w)| {
            let e = exponents[i % k.max(1)];
            let m = (w as f64 / 2f64.powi(e)).round().clamp(-8_388_607.0, 8_388_607.0) as i32;
            ((e as u32) << 24) | (m as u32 & 0x00ff_ffff)
        })
        .collect()
}

/// The value an `EXPONENTIAL` word decodes to: `m · 2^e`.
pub(super) fn exponential_value(word: u32) -> f32 {
    let m = ((word << 8) as i32) >> 8;
    let e = (word as i32) >> 24;
    (m as f64 * 2f64.powi(e)) as f32
}

/// The distortion level `D` of the high-rate allocation ([`quantize_at`]) whose estimated KG
/// meets `target_kg`: bisected on `log D` between a step far below the 16-bit floor and the
/// diagonal.
fn water_level(a: &Animation, p: &Pca, units: &[Unit], target_kg: f64) -> f64 {
    let diag = a.bounding_box_diagonal().max(f64::MIN_POSITIVE);
    let (mut lo, mut hi) = ((diag * 1e-9).ln(), diag.ln());
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if quantize_at(a, p, units, mid.exp(), usize::MAX, false).estimate <= target_kg {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo.exp()
}

/// Every vertex's coordinates in the streams the compressed basis writes, in units of each
/// stream's water-filling step for `target_kg` (the base at `D/√F`, component `j`'s target
/// at `D/√A_j`; components that round to nothing left out): `V` rows of equal length,
/// flattened. Two vertices close in these coordinates code small deltas when they are
/// neighbours in the file (meshoptimizer's vertex codec codes each vertex against the
/// previous one).
pub(super) fn stream_coordinates(a: &Animation, target_kg: f64) -> Result<(Vec<f64>, usize)> {
    let p = pca(a)?;
    let units = units(&p, usize::MAX);
    let (frames, v) = (p.coeffs.nrows(), a.vertex_count());
    let d = water_level(a, &p, &units, target_kg).max(f64::MIN_POSITIVE);
    let kept: Vec<(usize, f64)> = units
        .iter()
        .enumerate()
        .map(|(j, u)| (j, d / u.weight_energy.max(f64::MIN_POSITIVE).sqrt()))
        .filter(|&(j, step)| units[j].reach >= step / 2.0)
        .collect();
    let width = 3 * (1 + kept.len());
    let base_step = d / (frames.max(1) as f64).sqrt();
    let mut out = vec![0.0; v * width];
    for (i, row) in out.chunks_exact_mut(width).enumerate() {
        for k in 0..3 {
            let c = 3 * i + k;
            let base = p.mean[c] + units.iter().enumerate().map(|(j, u)| u.min * p.dirs[(j, c)]).sum::<f64>();
            row[k] = base / base_step;
            for (slot, &(j, step)) in kept.iter().enumerate() {
                row[3 * (slot + 1) + k] = units[j].range * p.dirs[(j, c)] / step;
            }
        }
    }
    Ok((out, width))
}

/// One way to write a stream (the base or a target): its step (infinite: the target is not
/// written), the bytes it codes to and its squared error (unweighted).
#[derive(Clone, Copy)]
struct Choice {
    step: f64,
    stick: f64,
    bytes: f64,
    err: f64,
}

/// Steps tried per stream: quarter octaves, this many either side of the water-filling step.
const STEP_GRID: i32 = 24;

/// How far past half a step a value may keep the previous vertex's integer ([`round_at`]);
/// tried on clips up to [`STICKY_FRAMES`] frames (on long clips it would triple the
/// allocation's time for the few streams that carry the bytes).
const STICK: [f64; 3] = [0.0, 0.1, 0.25];

/// See [`STICK`].
const STICKY_FRAMES: usize = 64;

/// JSON and weights a written target costs beyond its coded values (an accessor with its
/// min/max, a `targets` entry, a column of weights), in bytes.
const TARGET_OVERHEAD: f64 = 130.0;

/// `values` rounded at `step`: the integers and their squared error. With `stick` > 0 a
/// value keeps the previous vertex's integer (same coordinate) when it lies within
/// `0.5 + stick` steps of it: a zero delta, which meshoptimizer's vertex codec stores in
/// fewer bits (2 or 0 per byte of a group of 16) at a bounded extra error.
fn round_at(values: &[f64], step: f64, stick: f64) -> (Vec<[i16; 3]>, f64) {
    let mut err = 0.0;
    let mut previous = [0i16; 3];
    let q = values
        .chunks_exact(3)
        .map(|c| {
            let v: [i16; 3] = std::array::from_fn(|k| {
                let x = c[k] / step;
                let r = if stick > 0.0 && (x - previous[k] as f64).abs() <= 0.5 + stick {
                    previous[k]
                } else {
                    round_i16(x)
                };
                err += (c[k] - r as f64 * step).powi(2);
                r
            });
            previous = v;
            v
        })
        .collect();
    (q, err)
}

/// The choices for a stream of `values` around the step `reference`: every grid step at
/// which they fit 16 bits (at least the finest that fits), and for a target, not writing it
/// (error `dropped`).
fn choices(values: &[f64], reference: f64, dropped: Option<f64>, sticky: bool, version: i32) -> Vec<Choice> {
    let peak = values.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let mut out = Vec::new();
    if let Some(err) = dropped {
        out.push(Choice { step: f64::INFINITY, stick: 0.0, bytes: 0.0, err });
    }
    let finest = (peak / 32767.0).max(f64::MIN_POSITIVE);
    let mut steps: Vec<f64> =
        (-STEP_GRID..=STEP_GRID).map(|k| reference * 2f64.powf(k as f64 / 8.0)).filter(|&s| s >= finest).collect();
    if steps.is_empty() {
        steps.push(finest);
    }
    for step in steps {
        for stick in if sticky { &STICK[..] } else { &STICK[..1] } {
            let stick = *stick;
            let (q, err) = round_at(values, step, stick);
            if dropped.is_some() && q.iter().all(|v| *v == [0, 0, 0]) {
                continue;
            }
            let overhead = if dropped.is_some() { TARGET_OVERHEAD } else { 0.0 };
            out.push(Choice { step, stick, bytes: coded_bytes(&q, version) as f64 + overhead, err });
        }
    }
    out
}

/// The choice minimizing `bytes + mu · weight · err`.
fn pick(choices: &[Choice], weight: f64, mu: f64) -> Choice {
    *choices
        .iter()
        .min_by(|a, b| (a.bytes + mu * weight * a.err).total_cmp(&(b.bytes + mu * weight * b.err)))
        .expect("a stream has a choice")
}

/// The quantized basis meeting `target_kg` with steps chosen on the bytes meshoptimizer's
/// vertex codec actually spends: each stream (the base and every component's target) is
/// coded at a grid of steps around its water-filling step, and the steps minimizing
/// `bytes + μ · weighted error` (Lagrangian rate-distortion allocation, Shoham & Gersho 1988)
/// are kept for the smallest `μ` whose estimated KG meets the aim; the exact KG of the
/// integers is then checked and the aim lowered until it holds. The codec's cost is a
/// staircase in the step (2, 4 or 8 bits per byte of each group of 16 deltas, signed bytes
/// when a target fits them), which the high-rate model of [`quantized_basis`] cannot see.
///
/// glTF form: the base is normalized SHORT at step `s_b` (node scale `32767 · s_b`), so
/// every target's step `s_j` is a weight `s_j / (32767 · s_b)` in [0, 1] and no residual
/// target is needed. The weights are those the `EXPONENTIAL` filter stores
/// ([`exponential_words`]): 16 bits relative to each column's largest, a constant exponent.
pub(super) fn quantized_basis_coded(a: &Animation, p: &Pca, target_kg: f64, version: i32) -> Result<QBasis> {
    let units = units(p, usize::MAX);
    let (frames, n) = (p.coeffs.nrows(), p.mean.len());
    // The water-filling level for the target: the reference each stream's grid centres on.
    let d = water_level(a, p, &units, target_kg);
    let sticky = frames <= STICKY_FRAMES;
    let targets: Vec<Vec<f64>> =
        units.iter().enumerate().map(|(j, u)| (0..n).map(|i| u.range * p.dirs[(j, i)]).collect()).collect();
    let target_choices: Vec<Vec<Choice>> = units
        .iter()
        .zip(&targets)
        .enumerate()
        .map(|(j, (u, t))| {
            let energy = u.weight_energy.max(f64::MIN_POSITIVE);
            // Not written: the component's own energy (its minimum leaves the base too).
            choices(t, d / energy.sqrt(), Some(p.lambda[j] / energy), sticky, version)
        })
        .collect();
    let tail: f64 = p.lambda[units.len()..].iter().sum();
    let base_of = |kept: &[bool]| -> (Vec<f64>, [f64; 3]) {
        let mut base = p.mean.clone();
        for (j, _) in kept.iter().enumerate().filter(|(_, &k)| k) {
            for (i, b) in base.iter_mut().enumerate() {
                *b += units[j].min * p.dirs[(j, i)];
            }
        }
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for q in base.chunks_exact(3) {
            for k in 0..3 {
                lo[k] = lo[k].min(q[k]);
                hi[k] = hi[k].max(q[k]);
            }
        }
        let centre: [f64; 3] = std::array::from_fn(|k| (lo[k] + hi[k]) / 2.0);
        for (i, b) in base.iter_mut().enumerate() {
            *b -= centre[i % 3];
        }
        (base, centre)
    };
    let kg_of = |e: f64| if p.energy > 0.0 { 100.0 * (e.max(0.0) / p.energy).sqrt() } else { 0.0 };
    let weights_of = |j: usize| units[j].weight_energy;
    let mut kept = vec![true; units.len()];
    let (mut base, mut centre) = base_of(&kept);
    let mut base_choices = choices(&base, d / (frames as f64).sqrt(), None, sticky, version);
    // μ's range: the error is measured as a fraction of KG's denominator.
    let scale_mu = 1.0 / p.energy.max(f64::MIN_POSITIVE);
    let solve = |aim: f64, base_choices: &[Choice]| -> (Choice, Vec<Choice>) {
        let at = |mu: f64| {
            let b = pick(base_choices, frames as f64, mu * scale_mu);
            let t: Vec<Choice> =
                target_choices.iter().enumerate().map(|(j, c)| pick(c, weights_of(j), mu * scale_mu)).collect();
            let err =
                frames as f64 * b.err + t.iter().enumerate().map(|(j, c)| weights_of(j) * c.err).sum::<f64>() + tail;
            (b, t, kg_of(err))
        };
        let (mut lo, mut hi) = (0.0f64, 60.0f64);
        if at(hi.exp()).2 > aim {
            let (b, t, _) = at(hi.exp());
            return (b, t);
        }
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if at(mid.exp()).2 <= aim {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let (b, t, _) = at(hi.exp());
        (b, t)
    };
    // The aim is searched between the last aim that met the target and the last that missed
    // (the estimate assumes independent rounding errors, which sticky rounding is not), and
    // the met basis with the fewest estimated bytes is kept.
    let mut aim = target_kg;
    let (mut met_aim, mut missed_aim) = (None::<f64>, None::<f64>);
    let mut best: Option<(QBasis, f64)> = None;
    for _ in 0..8 {
        let (mut b, mut t) = solve(aim, &base_choices);
        // The base depends on which components are written (their minimum is folded in).
        for _ in 0..3 {
            let now: Vec<bool> = t.iter().map(|c| c.step.is_finite()).collect();
            if now == kept {
                break;
            }
            kept = now;
            (base, centre) = base_of(&kept);
            base_choices = choices(&base, d / (frames as f64).sqrt(), None, sticky, version);
            (b, t) = solve(aim, &base_choices);
        }
        let scale = 32767.0 * b.step;
        let (base_int, _) = round_at(&base, b.step, b.stick);
        let mut written = Vec::new();
        let mut columns: Vec<Vec<f64>> = Vec::new();
        for (j, c) in t.iter().enumerate().filter(|(_, c)| c.step.is_finite()) {
            let step = c.step.min(scale);
            let (values, _) = round_at(&targets[j], step, c.stick);
            written.push(values);
            columns.push(units[j].a.iter().map(|&x| x * step / scale).collect());
        }
        let k = written.len();
        let mut weights = vec![0.0f32; frames * k];
        for (j, c) in columns.iter().enumerate() {
            for f in 0..frames {
                weights[f * k + j] = c[f] as f32;
            }
        }
        let words = exponential_words(&weights, k);
        weights = words.iter().map(|&w| exponential_value(w)).collect();
        let mut q = QBasis {
            translation: centre,
            scale,
            base: base_int,
            base_normalized: true,
            targets: written
                .into_iter()
                .map(|values| {
                    let bytes = values.iter().all(|v| v.iter().all(|&x| (-127..=127).contains(&x)));
                    QTarget { values, bytes }
                })
                .collect(),
            weights,
            weights_exponential: true,
            components: k,
            kg: f64::NAN,
            estimate: f64::NAN,
        };
        q.kg = kg_of(played_error(a, &q));
        if !q.kg.is_finite() {
            return Err(Error::InvalidAnimation("glTF export: the quantized basis is not finite".into()));
        }
        let met = q.kg <= target_kg;
        let overshoot = q.kg / target_kg;
        let bytes: f64 = b.bytes + t.iter().map(|c| c.bytes).sum::<f64>();
        let better = match &best {
            None => true,
            Some((held, held_bytes)) => match (met, held.kg <= target_kg) {
                (true, true) => bytes < *held_bytes,
                (true, false) => true,
                (false, true) => false,
                (false, false) => q.kg < held.kg,
            },
        };
        if better {
            best = Some((q, bytes));
        }
        if met {
            met_aim = Some(met_aim.map_or(aim, |m: f64| m.max(aim)));
        } else {
            missed_aim = Some(missed_aim.map_or(aim, |m: f64| m.min(aim)));
        }
        aim = match (met_aim, missed_aim) {
            // Met with room to spare (the errors partly cancel): aim higher.
            (Some(_), None) if overshoot < 0.98 => aim / overshoot * 0.995,
            (Some(_), None) => break,
            (Some(lo), Some(hi)) if hi / lo < 1.02 => break,
            (Some(lo), Some(hi)) => (lo * hi).sqrt(),
            _ => aim / (overshoot * 1.01),
        };
    }
    Ok(best.expect("at least one round").0)
}

/// The vertex codec's compression level: the slowest and smallest (it only takes effect in
/// format version 1, where it tries more channel modes and bit-width combinations).
const VERTEX_CODEC_LEVEL: i32 = 3;

/// Encodes `records` with meshopt's vertex codec in format `version` (0 or 1).
pub(super) fn encode_vertex_records<T>(records: &[T], version: i32) -> Result<Vec<u8>> {
    meshopt::encode_vertex_buffer_level(records, VERTEX_CODEC_LEVEL, Some(version))
        .map_err(|e| Error::InvalidAnimation(format!("meshopt encoding: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;
    use animcodec_synth as synth;

    /// The coded allocation: the exact KG meets the target, the base is normalized (no
    /// residual target), weights lie in [0, 1] and are in the exponential filter's form (which
    /// gives them back exactly), for principal components and for frame differences.
    #[test]
    fn coded_basis_meets_the_target_with_exact_weights() {
        let a = synth::waving_flag(16, 10, 30);
        for t in [0.1, 0.01] {
            let components = quantized_basis_coded(&a, &pca(&a).unwrap(), t, 0).unwrap();
            let frames = quantized_basis_coded(&a, &differences(&a), t, 0).unwrap();
            for q in [&components, &frames] {
                assert!(q.kg <= t, "target {t}: exact KG {}", q.kg);
                assert!(q.base_normalized && q.components == q.targets.len());
                assert!(q.weights.iter().all(|w| (0.0..=1.0).contains(w)));
            }
            for q in [&components, &frames] {
                assert!(q.weights_exponential);
                let words = exponential_words(&q.weights, q.targets.len());
                assert!(words.iter().zip(&q.weights).all(|(&w, &x)| exponential_value(w) == x));
            }
        }
    }

    /// The exact KG of the written integers meets the target and tightens with it; the
    /// estimate the search uses is close to it; weights stay in [0, 1].
    #[test]
    fn quantized_basis_meets_the_target_exactly() {
        let a = synth::waving_flag(16, 10, 30);
        let mut last = usize::MAX;
        for t in [1.0, 0.1, 0.01] {
            let q = quantized_basis(&a, &pca(&a).unwrap(), t, (usize::MAX, usize::MAX)).unwrap();
            assert!(q.kg <= t, "target {t}: exact KG {}", q.kg);
            assert!((q.estimate - q.kg).abs() <= 0.2 * t, "target {t}: estimate {} exact {}", q.estimate, q.kg);
            assert!(q.weights.iter().all(|w| (0.0..=1.0).contains(w)));
            // Finer target: finer steps (the node scale shrinks).
            let scale = (q.scale * 1e9) as usize;
            assert!(scale <= last, "{scale} > {last}");
            last = scale;
        }
    }
}
