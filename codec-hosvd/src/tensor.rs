//! The numerical core: the animation tensor, rigid/affine motion removal (§2.3), HO-SVD
//! (Alg. 1) through Gram matrices, truncation energies, optional HOOI refinement, and the
//! deterministic reconstruction shared by encoder and decoder.
//!
//! Layout conventions. Positions arrive frame-major, `P[t][k][j]` (`F × K × 3`). The tensor
//! of the paper is `T ∈ R^{K×3×F}` (§2.1). Its unfoldings are kept as faer matrices:
//! - mode 1, `X1 = K × 3F`, column `t·3 + j`;
//! - mode 3, `X3 = F × 3K`, column `k·3 + j` — exactly the positions array read row-major.
//!
//! All decompositions run with `Par::Seq` so the encoder's bytes do not depend on how many
//! threads exist (faer's global parallelism would otherwise split reductions by thread count).

use codec_core::linalg::{self, mul};
use codec_core::{Error, Result};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::svd::{self, ComputeSvdVectors};
use faer::{Mat, MatRef, Par};

const CTX: &str = "hosvd";

/// Per-frame inverse affine transform as stored in the stream: original = `x · M + c`
/// (row-vector convention, `M` row-major 3×3), both rounded to `f32`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Affine {
    /// Linear part, row-major.
    pub m: [f32; 9],
    /// Translation.
    pub c: [f32; 3],
}

impl Affine {
    /// The identity transform.
    pub const IDENTITY: Affine = Affine { m: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], c: [0.0; 3] };

    /// Upper bound of the spectral norm of the linear part, `√(‖M‖₁‖M‖∞)`: how much it can
    /// stretch an error vector.
    pub fn gain(&self) -> f64 {
        norm2_bound(&self.m.map(|x| x as f64))
    }
}

pub(crate) fn mat3_inverse(a: &[f64; 9]) -> Option<[f64; 9]> {
    let det =
        a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) + a[2] * (a[3] * a[7] - a[4] * a[6]);
    let norm = a.iter().map(|x| x * x).sum::<f64>().sqrt();
    if !det.is_finite() || det.abs() <= 1e-12 * norm * norm * norm || norm == 0.0 {
        return None;
    }
    let inv = [
        (a[4] * a[8] - a[5] * a[7]) / det,
        (a[2] * a[7] - a[1] * a[8]) / det,
        (a[1] * a[5] - a[2] * a[4]) / det,
        (a[5] * a[6] - a[3] * a[8]) / det,
        (a[0] * a[8] - a[2] * a[6]) / det,
        (a[2] * a[3] - a[0] * a[5]) / det,
        (a[3] * a[7] - a[4] * a[6]) / det,
        (a[1] * a[6] - a[0] * a[7]) / det,
        (a[0] * a[4] - a[1] * a[3]) / det,
    ];
    inv.iter().all(|x| x.is_finite()).then_some(inv)
}

fn mat3_mul(a: &[f64; 9], b: &[f64; 9]) -> [f64; 9] {
    let mut r = [0.0; 9];
    for i in 0..3 {
        for j in 0..3 {
            r[i * 3 + j] = (0..3).map(|l| a[i * 3 + l] * b[l * 3 + j]).sum();
        }
    }
    r
}

/// Upper bound of the spectral norm of a 3×3 matrix, `√(‖A‖₁‖A‖∞)`.
fn norm2_bound(a: &[f64; 9]) -> f64 {
    let n1 = (0..3).map(|j| (0..3).map(|i| a[i * 3 + j].abs()).sum::<f64>()).fold(0.0, f64::max);
    let ninf = (0..3).map(|i| (0..3).map(|j| a[i * 3 + j].abs()).sum::<f64>()).fold(0.0, f64::max);
    (n1 * ninf).sqrt()
}

/// Largest condition number (spectral-norm bound) accepted for a per-frame affine map. The
/// decoder maps the decomposition error back through the inverse map, so a badly conditioned
/// fit (near-planar meshes, where the least-squares affine fit is nearly singular) would
/// amplify it; such frames use the best rigid rotation (orthogonal Procrustes) instead, whose
/// inverse has gain 1.
pub const MAX_AFFINE_CONDITION: f64 = 3.0;

/// Orthogonal Procrustes (Kabsch): the rotation `R` minimising `‖P'·R − P0'‖` given the 3×3
/// cross-covariance `H = P'ᵀP0'`, `R = U·diag(1, 1, det(UVᵀ))·Vᵀ` from `H = U·S·Vᵀ`.
fn procrustes(h: &[f64; 9]) -> Option<[f64; 9]> {
    let hm = Mat::from_fn(3, 3, |i, j| h[i * 3 + j]);
    let par = Par::Seq;
    let mut s = faer::diag::Diag::<f64>::zeros(3);
    let mut u = Mat::<f64>::zeros(3, 3);
    let mut v = Mat::<f64>::zeros(3, 3);
    let mut mem = MemBuffer::new(svd::svd_scratch::<f64>(
        3,
        3,
        ComputeSvdVectors::Full,
        ComputeSvdVectors::Full,
        par,
        Default::default(),
    ));
    svd::svd(
        hm.as_ref(),
        s.as_mut(),
        Some(u.as_mut()),
        Some(v.as_mut()),
        par,
        MemStack::new(&mut mem),
        Default::default(),
    )
    .ok()?;
    let um: [f64; 9] = std::array::from_fn(|i| u[(i / 3, i % 3)]);
    let vt: [f64; 9] = std::array::from_fn(|i| v[(i % 3, i / 3)]);
    let det = |a: &[f64; 9]| {
        a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) + a[2] * (a[3] * a[7] - a[4] * a[6])
    };
    let sign = if det(&mat3_mul(&um, &vt)) < 0.0 { -1.0 } else { 1.0 };
    let d = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, sign];
    let r = mat3_mul(&mat3_mul(&um, &d), &vt);
    r.iter().all(|x| x.is_finite()).then_some(r)
}

/// §2.3: per frame, the affine map to frame 0 by least squares, `x = p·L + b` minimising
/// `Σ_k ‖p_k L + b − p⁰_k‖²`. Returns the stored inverses (f32) and the normalised tensor
/// (`F × K × 3`, f64) computed from the *rounded* inverse so the decoder's inverse is exact.
///
/// With `affine = false` every frame uses the rotation (rigid motion proper).
///
/// Choices left open by the paper: the fit is done on centred coordinates (normal equations of a
/// 3×3 covariance); frames whose affine fit is singular or worse conditioned than
/// [`MAX_AFFINE_CONDITION`] use the best rotation instead, and translation only if even that
/// fails.
pub fn remove_affine_motion(p: &[f32], k: usize, frames: usize, affine: bool) -> (Vec<Affine>, Vec<f64>) {
    remove_affine_motion_with(p, k, frames, affine, &mut |proposed, fallback, _| {
        if mat3_inverse(&proposed.m.map(|v| v as f64)).is_some() {
            proposed
        } else {
            fallback
        }
    })
}

/// Centroids of frame 0 and of the current frame, for a `store` that re-derives the
/// translation from its own rounding of the linear part.
#[derive(Debug, Clone, Copy)]
pub struct Centroids {
    /// `μ_0`.
    pub first: [f64; 3],
    /// `μ_t`.
    pub this: [f64; 3],
}

/// [`remove_affine_motion`] with the stored transforms chosen by `store(proposed, fallback, centroids)`,
/// called once per frame in order: e.g. a quantizer in closed loop over the frames
/// ([`crate::motion`]). It returns the transform the decoder will use, whose linear part must
/// be invertible; `fallback` (identity linear part, centroid shift) is for when `proposed`'s
/// stored form is not.
pub fn remove_affine_motion_with(
    p: &[f32],
    k: usize,
    frames: usize,
    affine: bool,
    store: &mut dyn FnMut(Affine, Affine, Centroids) -> Affine,
) -> (Vec<Affine>, Vec<f64>) {
    remove_affine_motion_centred(p, k, frames, affine, [0.0; 3], store)
}

/// [`remove_affine_motion_with`] of the positions `p − centre` (subtracted in f64, exactly):
/// stream version 6 centres every packet before the decomposition, so the
/// transforms, the centroids and the normalised tensor are those of the centred positions.
/// A zero `centre` gives the same bits as the uncentred function.
pub fn remove_affine_motion_centred(
    p: &[f32],
    k: usize,
    frames: usize,
    affine: bool,
    centre: [f64; 3],
    store: &mut dyn FnMut(Affine, Affine, Centroids) -> Affine,
) -> (Vec<Affine>, Vec<f64>) {
    let centroid = |t: usize| -> [f64; 3] {
        let mut s = [0.0f64; 3];
        for v in p[t * k * 3..(t + 1) * k * 3].chunks_exact(3) {
            for j in 0..3 {
                s[j] += v[j] as f64 - centre[j];
            }
        }
        s.map(|x| x / k as f64)
    };
    let mu0 = centroid(0);
    let mut transforms = Vec::with_capacity(frames);
    let mut x = vec![0.0f64; p.len()];
    for t in 0..frames {
        let mut_t = centroid(t);
        let frame = &p[t * k * 3..(t + 1) * k * 3];
        let first = &p[..k * 3];
        // Covariance of the centred frame (S = P'ᵀP') and cross term (R = P'ᵀP0').
        let mut s = [0.0f64; 9];
        let mut r = [0.0f64; 9];
        for (a, b) in frame.chunks_exact(3).zip(first.chunks_exact(3)) {
            let pa: [f64; 3] = std::array::from_fn(|j| a[j] as f64 - centre[j] - mut_t[j]);
            let pb: [f64; 3] = std::array::from_fn(|j| b[j] as f64 - centre[j] - mu0[j]);
            for i in 0..3 {
                for j in 0..3 {
                    s[i * 3 + j] += pa[i] * pa[j];
                    r[i * 3 + j] += pa[i] * pb[j];
                }
            }
        }
        let fit = mat3_inverse(&s).filter(|_| affine).map(|si| mat3_mul(&si, &r)).and_then(|l| {
            let li = mat3_inverse(&l)?;
            (norm2_bound(&l) * norm2_bound(&li) <= MAX_AFFINE_CONDITION).then_some(li)
        });
        // The inverse of a rotation is its transpose.
        let linear = fit.or_else(|| procrustes(&r).map(|q| std::array::from_fn(|i| q[(i % 3) * 3 + i / 3])));
        // Inverse map: original = x·M + c with M = L⁻¹, c = μ_t − μ_0·M (fallback M = I).
        let m = linear.unwrap_or([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
        let c: [f64; 3] = std::array::from_fn(|j| mut_t[j] - (0..3).map(|i| mu0[i] * m[i * 3 + j]).sum::<f64>());
        let proposed = Affine { m: m.map(|v| v as f32), c: c.map(|v| v as f32) };
        let fallback = Affine { m: Affine::IDENTITY.m, c: std::array::from_fn(|j| (mut_t[j] - mu0[j]) as f32) };
        let aff = store(proposed, fallback, Centroids { first: mu0, this: mut_t });
        // Forward map from the stored (rounded) inverse, so that decode(x) reproduces p up to
        // the decomposition error alone.
        let l = mat3_inverse(&aff.m.map(|v| v as f64)).unwrap_or([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
        let cr: [f64; 3] = aff.c.map(|v| v as f64);
        for (dst, src) in x[t * k * 3..(t + 1) * k * 3].chunks_exact_mut(3).zip(frame.chunks_exact(3)) {
            let q: [f64; 3] = std::array::from_fn(|j| src[j] as f64 - centre[j] - cr[j]);
            for j in 0..3 {
                dst[j] = (0..3).map(|i| q[i] * l[i * 3 + j]).sum();
            }
        }
        transforms.push(aff);
    }
    (transforms, x)
}

/// Eigenvalues (descending, clamped at zero) and eigenvectors of a Gram matrix: Alg. 1's factors
/// are its leading eigenvectors.
fn gram_evd(g: MatRef<'_, f64>) -> Result<(Vec<f64>, Mat<f64>)> {
    linalg::sym_eig_desc(g).map_err(|e| e.numerical(CTX, "Gram eigensolver"))
}

fn thin_left(b: MatRef<'_, f64>) -> Result<Mat<f64>> {
    let (m, n) = b.shape();
    let size = m.min(n);
    let par = Par::Seq;
    let mut s = faer::diag::Diag::<f64>::zeros(size);
    let mut u = Mat::<f64>::zeros(m, size);
    let mut mem = MemBuffer::new(svd::svd_scratch::<f64>(
        m,
        n,
        ComputeSvdVectors::Thin,
        ComputeSvdVectors::No,
        par,
        Default::default(),
    ));
    svd::svd(b, s.as_mut(), Some(u.as_mut()), None, par, MemStack::new(&mut mem), Default::default()).map_err(|e| {
        Error::Numerical { context: CTX.into(), step: "thin SVD".into(), detail: codec_core::error::debug_in_words(&e) }
    })?;
    Ok(u)
}

/// Leading `r` left singular vectors of `a` (`m × n`, `r ≤ min(m, n)`), computed through the
/// smaller Gram matrix (Alg. 1 asks for the left singular vectors of the unfolding):
/// - `m ≤ n`: eigenvectors of `A·Aᵀ` (`m × m`) are the left singular vectors directly;
/// - `m > n`: eigenvectors `W` of `Aᵀ·A` (`n × n`) give `A·W = U·Σ`; a thin SVD of the narrow
///   `m × r` matrix `A·W_r` orthonormalises it (robust when some `σ` vanish, where dividing
///   by `σ` would not be).
///
/// No SVD of the full `m × n` unfolding is ever taken.
pub fn leading_left(a: MatRef<'_, f64>, r: usize) -> Result<Mat<f64>> {
    let (m, n) = a.shape();
    debug_assert!(r >= 1 && r <= m.min(n));
    if m <= n {
        let g = mul(a, a.transpose());
        let (_, vecs) = gram_evd(g.as_ref())?;
        Ok(vecs.subcols(0, r).to_owned())
    } else {
        let g = mul(a.transpose(), a);
        let (_, vecs) = gram_evd(g.as_ref())?;
        let b = mul(a, vecs.subcols(0, r));
        thin_left(b.as_ref())
    }
}

/// The normalised tensor in both unfoldings used by the algorithms.
pub struct Tensor {
    /// Vertices `K`.
    pub k: usize,
    /// Frames `F`.
    pub f: usize,
    /// Mode-1 unfolding, `K × 3F`, column `t·3 + j`.
    pub x1: Mat<f64>,
    /// Mode-3 unfolding, `F × 3K`, column `k·3 + j`.
    pub x3: Mat<f64>,
    /// `‖T‖²`.
    pub norm2: f64,
}

impl Tensor {
    /// Builds both unfoldings from frame-major data `F × K × 3`.
    pub fn new(x: &[f64], k: usize, f: usize) -> Self {
        let x3 = Mat::from_fn(f, 3 * k, |t, c| x[t * 3 * k + c]);
        let x1 = Mat::from_fn(k, 3 * f, |kk, c| x[(c / 3) * 3 * k + kk * 3 + c % 3]);
        let norm2 = x.iter().map(|v| v * v).sum();
        Self { k, f, x1, x3, norm2 }
    }

    /// Rank limit of mode 1 (`min(K, 3F)`).
    pub fn max_v(&self) -> usize {
        self.k.min(3 * self.f)
    }

    /// Rank limit of mode 3 (`min(F, 3K)`).
    pub fn max_f(&self) -> usize {
        self.f.min(3 * self.k)
    }

    /// Mode-2 factor: eigenvectors of the 3×3 Gram matrix `T₍₂₎T₍₂₎ᵀ`, leading first.
    pub fn mode2(&self) -> Result<Mat<f64>> {
        let mut g = Mat::<f64>::zeros(3, 3);
        for t in 0..self.f {
            for kk in 0..self.k {
                let p = [self.x3[(t, kk * 3)], self.x3[(t, kk * 3 + 1)], self.x3[(t, kk * 3 + 2)]];
                for i in 0..3 {
                    for j in 0..3 {
                        g[(i, j)] += p[i] * p[j];
                    }
                }
            }
        }
        Ok(gram_evd(g.as_ref())?.1)
    }

    /// `Z = U1ᵀ·T₍₁₎` (`v × 3F`), the tensor projected on the mode-1 basis.
    pub fn project1(&self, u1: MatRef<'_, f64>) -> Mat<f64> {
        mul(u1.transpose(), self.x1.as_ref())
    }

    /// Core `C = T ×₁ U1ᵀ ×₂ U2ᵀ ×₃ U3ᵀ` as `v × 3 × f` (index `(i·3 + j)·f + l`).
    pub fn core(&self, u1: MatRef<'_, f64>, u2: MatRef<'_, f64>, u3: MatRef<'_, f64>) -> Vec<f64> {
        let z = self.project1(u1);
        core_from_projection(z.as_ref(), u2, u3)
    }
}

/// `C[i, j, l] = Σ_t Σ_j' Z[i, t·3+j'] U2[j', j] U3[t, l]`.
fn core_from_projection(z: MatRef<'_, f64>, u2: MatRef<'_, f64>, u3: MatRef<'_, f64>) -> Vec<f64> {
    let (v, frames, f) = (z.nrows(), u3.nrows(), u3.ncols());
    let mut out = vec![0.0; v * 3 * f];
    for i in 0..v {
        for t in 0..frames {
            let zr = [z[(i, t * 3)], z[(i, t * 3 + 1)], z[(i, t * 3 + 2)]];
            let rot: [f64; 3] = std::array::from_fn(|j| (0..3).map(|jj| zr[jj] * u2[(jj, j)]).sum());
            for (j, r) in rot.iter().enumerate() {
                let base = (i * 3 + j) * f;
                for l in 0..f {
                    out[base + l] += r * u3[(t, l)];
                }
            }
        }
    }
    out
}

/// The full (untruncated) HO-SVD spectrum needed by the rank search: `energy[i][l]`, the energy
/// `Σ_j C[i,j,l]²` of the full core, with its prefix sums so `‖C̃(v,f)‖²` is O(1).
pub struct Spectrum {
    /// Full mode-1 basis, `K × R1`.
    pub u1: Mat<f64>,
    /// Mode-2 basis, 3 × 3.
    pub u2: Mat<f64>,
    /// Full mode-3 basis, `F × R3`.
    pub u3: Mat<f64>,
    r3: usize,
    /// `prefix[(i)(R3+1) + l]` = energy of `C[..i, :, ..l]`.
    prefix: Vec<f64>,
    norm2: f64,
}

impl Spectrum {
    /// Alg. 1 at full rank: factors from the Gram matrices, then the full core's energies.
    pub fn new(t: &Tensor) -> Result<Self> {
        let (r1, r3) = (t.max_v(), t.max_f());
        let u1 = leading_left(t.x1.as_ref(), r1)?;
        let u2 = t.mode2()?;
        let u3 = leading_left(t.x3.as_ref(), r3)?;
        let core = t.core(u1.as_ref(), u2.as_ref(), u3.as_ref());
        let mut prefix = vec![0.0; (r1 + 1) * (r3 + 1)];
        for i in 0..r1 {
            for l in 0..r3 {
                let e: f64 = (0..3).map(|j| core[(i * 3 + j) * r3 + l].powi(2)).sum();
                prefix[(i + 1) * (r3 + 1) + l + 1] =
                    e + prefix[i * (r3 + 1) + l + 1] + prefix[(i + 1) * (r3 + 1) + l] - prefix[i * (r3 + 1) + l];
            }
        }
        Ok(Self { u1, u2, u3, r3, prefix, norm2: t.norm2 })
    }

    /// Squared Frobenius error of truncating to `(v, 3, f)`: `‖T‖² − ‖C̃‖²` (the truncated
    /// reconstruction is an orthogonal projection of `T`, so the energies add).
    pub fn truncation_error2(&self, v: usize, f: usize) -> f64 {
        (self.norm2 - self.prefix[v * (self.r3 + 1) + f]).max(0.0)
    }
}

/// A truncated Tucker operator `[[C; U1, U2, U3]]` with mode 2 kept whole.
#[derive(Debug, Clone)]
pub struct Tucker {
    /// `K × v`.
    pub u1: Mat<f64>,
    /// 3 × 3.
    pub u2: Mat<f64>,
    /// `F × f`.
    pub u3: Mat<f64>,
    /// `v × 3 × f`, index `(i·3 + j)·f + l`.
    pub core: Vec<f64>,
}

impl Tucker {
    /// Truncation of a full spectrum's factors to `(v, 3, f)` and the matching core.
    pub fn truncate(t: &Tensor, s: &Spectrum, v: usize, f: usize, u2: Mat<f64>) -> Self {
        let u1 = s.u1.subcols(0, v).to_owned();
        let u3 = s.u3.subcols(0, f).to_owned();
        let core = t.core(u1.as_ref(), u2.as_ref(), u3.as_ref());
        Self { u1, u2, u3, core }
    }

    /// `‖C‖²`.
    pub fn core_norm2(&self) -> f64 {
        self.core.iter().map(|c| c * c).sum()
    }

    /// `‖T ×₁ U1ᵀ ×₃ U3ᵀ‖²`: the energy the (v, 3, f) subspace captures, as if U2 were exactly
    /// orthonormal. `‖T‖² − ‖C‖²` is not a safe truncation error once U2 has been rounded to
    /// f32: the rounding perturbs `‖C‖²` by about `2·‖U2ᵀU2 − I‖·‖T‖²`, which on a large
    /// tensor exceeds a small truncation error and clamps it to zero. Undoing U2 on the core
    /// (`C[i, :, l] = U2ᵀ·P[i, :, l]`, so `P = U2⁻ᵀ·C`) recovers the projection exactly enough.
    /// Falls back to `‖C‖²` if U2 is singular (it never is: it is a rounded rotation).
    pub fn captured_norm2(&self) -> f64 {
        let u2t: [f64; 9] = std::array::from_fn(|i| self.u2[(i % 3, i / 3)]);
        let Some(inv) = mat3_inverse(&u2t) else { return self.core_norm2() };
        let f = self.u3.ncols();
        let mut sum = 0.0;
        for i in 0..self.u1.ncols() {
            for l in 0..f {
                let c: [f64; 3] = std::array::from_fn(|j| self.core[(i * 3 + j) * f + l]);
                for row in 0..3 {
                    let p: f64 = (0..3).map(|j| inv[row * 3 + j] * c[j]).sum();
                    sum += p * p;
                }
            }
        }
        sum
    }

    /// Beyond the paper: `iters` HOOI sweeps (alternating least squares for the Tucker model,
    /// Kolda & Bader §4.2). Each factor becomes the leading left singular vectors of the tensor
    /// projected on the other factor; mode 2 is kept whole so it never changes. A mode whose
    /// projected unfolding has fewer columns than its rank (e.g. `v > 3f`) is left as is: its
    /// subspace already holds the whole projected range.
    pub fn hooi(&mut self, t: &Tensor, iters: usize) -> Result<()> {
        let (v, f) = (self.u1.ncols(), self.u3.ncols());
        for _ in 0..iters {
            if v <= t.k.min(3 * f) {
                // Y1 = T ×₃ U3ᵀ as K × 3f: from X3ᵀ·U3 (3K × f).
                let q = mul(t.x3.transpose(), self.u3.as_ref());
                let y1 = Mat::from_fn(t.k, 3 * f, |kk, c| q[(kk * 3 + c % 3, c / 3)]);
                self.u1 = leading_left(y1.as_ref(), v)?;
            }
            if f <= t.f.min(3 * v) {
                // Y3 = T ×₁ U1ᵀ as F × 3v: from U1ᵀ·X1 (v × 3F).
                let z = t.project1(self.u1.as_ref());
                let y3 = Mat::from_fn(t.f, 3 * v, |tt, c| z[(c / 3, tt * 3 + c % 3)]);
                self.u3 = leading_left(y3.as_ref(), f)?;
            }
        }
        self.core = t.core(self.u1.as_ref(), self.u2.as_ref(), self.u3.as_ref());
        Ok(())
    }
}

/// Dequantized model as the decoder sees it; [`reconstruct`] turns it into frames.
#[derive(Debug, Clone)]
pub struct Model {
    /// Vertices.
    pub k: usize,
    /// Frames.
    pub frames: usize,
    /// Mode-1 rank.
    pub v: usize,
    /// Mode-3 rank.
    pub f: usize,
    /// `K × v`, row-major.
    pub u1: Vec<f64>,
    /// 3 × 3 row-major.
    pub u2: [f64; 9],
    /// `F × f`, row-major.
    pub u3: Vec<f64>,
    /// `v × 3 × f`.
    pub core: Vec<f64>,
    /// Per-frame inverse transforms (identity when rigid removal is off).
    pub transforms: Vec<Affine>,
}

/// Eq. (10) then step 5 of Alg. 2: `T̃ = C ×₁ U1 ×₂ U2 ×₃ U3`, then each frame mapped back by
/// its stored inverse transform. Encoder and decoder produce identical bits, whatever the
/// thread count: every output coordinate is one fixed-order f64 sum (see [`reconstruct_reference`],
/// the plain loops this reproduces bit for bit).
///
/// Speed: the last step, `X[t][k][j] = Σ_i U1[k][i]·D[t][j][i]`, is
/// `F·K·3·v` multiply-adds and all of the decoder's arithmetic. It runs on blocks of
/// [`LANES`] vertices whose `U1` rows are repacked lane-interleaved (a block is `v·LANES`
/// contiguous values, L1-resident while every frame of a thread's range is reconstructed),
/// with `3·LANES` accumulators updated in the same order `i = 0 … v−1` as the plain loop:
/// vectorization across independent outputs, not a reordering of one output's sum, and
/// separate multiply and add (Rust never contracts them into FMA), so the bits are those of
/// the reference. Frames are split over rayon's threads (disjoint output ranges). On x86-64
/// with AVX2 (runtime-detected by `pulp`) the kernel is compiled for 256-bit vectors.
pub fn reconstruct(m: &Model) -> Vec<f32> {
    Prepared::new(m).frames()
}

/// A model made ready for [`reconstruct`]'s last step: the per-frame loadings `D`, `U1` in
/// lanes and the transforms in f64. Any frame is then formed alone at the cost of one frame,
/// with the bits the whole reconstruction gives it (the kernel's output for frame `t` reads
/// only `D[t]`, the lanes and transform `t`).
pub struct Prepared {
    packed: Vec<f64>,
    d: Vec<f64>,
    transforms: Vec<([f64; 9], [f64; 3])>,
    k: usize,
    v: usize,
    frames: usize,
}

impl Prepared {
    /// `D` and the lanes of `m` (`O(v·f·(3 + F) + K·v)`).
    pub fn new(m: &Model) -> Self {
        let (k, frames, v) = (m.k, m.frames, m.v);
        let d = frame_loadings(m);
        let packed = pack_lanes(&m.u1, k, v);
        let transforms = m.transforms.iter().map(|a| (a.m.map(|x| x as f64), a.c.map(|x| x as f64))).collect();
        Self { packed, d, transforms, k, v, frames }
    }

    /// Bytes held (the loadings, the lanes and the transforms).
    pub fn bytes(&self) -> u64 {
        (self.packed.len() as u64 + self.d.len() as u64 + 12 * self.transforms.len() as u64) * 8
    }

    /// Every frame (`F × K × 3`), split over rayon's threads.
    pub fn frames(&self) -> Vec<f32> {
        let (k, frames) = (self.k, self.frames);
        let mut out = vec![0.0f32; frames * k * 3];
        if k == 0 || frames == 0 {
            return out;
        }
        // Enough chunks to keep every thread busy; the split never changes a value.
        let threads = rayon::current_num_threads().max(1);
        let per_chunk = frames.div_ceil(threads * 2).max(1);
        use rayon::prelude::*;
        out.par_chunks_mut(per_chunk * k * 3).enumerate().for_each(|(c, o)| self.job(c * per_chunk).run(o));
        out
    }

    /// Frame `t` (`< F`) alone (`K × 3`).
    pub fn frame(&self, t: usize) -> Vec<f32> {
        let mut out = vec![0.0f32; self.k * 3];
        if self.k > 0 && t < self.frames {
            self.job(t).run(&mut out);
        }
        out
    }

    fn job(&self, t0: usize) -> KernelJob<'_> {
        KernelJob { packed: &self.packed, d: &self.d, transforms: &self.transforms, k: self.k, v: self.v, t0 }
    }
}

/// Vertices per block of the reconstruction kernel (four 256-bit vectors of f64).
pub const LANES: usize = 16;

/// `D[t][j][i] = Σ_l U3[t][l] Σ_j' U2[j][j'] C[i][j'][l]` (`F × 3 × v`): the per-frame
/// loadings the `U1` rows are combined with. `O(v·f·(3 + F))`, small next to the last step.
fn frame_loadings(m: &Model) -> Vec<f64> {
    let (frames, v, f) = (m.frames, m.v, m.f);
    // C2[i][j][l] = Σ_j' U2[j][j'] C[i][j'][l]
    let mut c2 = vec![0.0f64; v * 3 * f];
    for i in 0..v {
        for j in 0..3 {
            for l in 0..f {
                c2[(i * 3 + j) * f + l] = (0..3).map(|jj| m.u2[j * 3 + jj] * m.core[(i * 3 + jj) * f + l]).sum();
            }
        }
    }
    // D[t][j][i] = Σ_l U3[t][l] C2[i][j][l]
    let mut d = vec![0.0f64; frames * 3 * v];
    for t in 0..frames {
        let u3 = &m.u3[t * f..(t + 1) * f];
        for j in 0..3 {
            for i in 0..v {
                let c = &c2[(i * 3 + j) * f..(i * 3 + j + 1) * f];
                d[(t * 3 + j) * v + i] = u3.iter().zip(c).map(|(a, b)| a * b).sum();
            }
        }
    }
    d
}

/// `U1` (`K × v` row-major) as blocks of [`LANES`] vertices, each `v × LANES` (`[i][lane]`),
/// the last block padded with zeros.
fn pack_lanes(u1: &[f64], k: usize, v: usize) -> Vec<f64> {
    let blocks = k.div_ceil(LANES);
    let mut packed = vec![0.0f64; blocks * v * LANES];
    for kk in 0..k {
        let (b, lane) = (kk / LANES, kk % LANES);
        for i in 0..v {
            packed[(b * v + i) * LANES + lane] = u1[kk * v + i];
        }
    }
    packed
}

/// One thread's share of the last reconstruction step: frames `t0 …` (as many as `out` holds).
struct KernelJob<'a> {
    packed: &'a [f64],
    d: &'a [f64],
    transforms: &'a [([f64; 9], [f64; 3])],
    k: usize,
    v: usize,
    t0: usize,
}

impl KernelJob<'_> {
    fn run(&self, out: &mut [f32]) {
        // pulp compiles the inlined kernel for the best instruction set the CPU has
        // (x86-64-v3 = AVX2 when present) and dispatches at run time, without unsafe here.
        pulp::Arch::new().dispatch(|| self.run_portable(out));
    }

    #[inline(always)]
    fn run_portable(&self, out: &mut [f32]) {
        let (k, v) = (self.k, self.v);
        let frames = out.len() / (3 * k);
        for b in 0..k.div_ceil(LANES) {
            let block = &self.packed[b * v * LANES..(b + 1) * v * LANES];
            let first = b * LANES;
            let n = LANES.min(k - first);
            for tt in 0..frames {
                let t = self.t0 + tt;
                let dt = &self.d[t * 3 * v..(t + 1) * 3 * v];
                // -0.0 is the start value of f64's `Sum` (so `-0.0 + p = p` exactly, as there).
                // Three separate accumulator arrays (one per coordinate) stay in vector registers.
                let (mut a0, mut a1, mut a2) = ([-0.0f64; LANES], [-0.0f64; LANES], [-0.0f64; LANES]);
                let (d0, rest) = dt.split_at(v);
                let (d1, d2) = rest.split_at(v);
                for ((u, (&s0, &s1)), &s2) in block.chunks_exact(LANES).zip(d0.iter().zip(d1)).zip(d2) {
                    for l in 0..LANES {
                        a0[l] += u[l] * s0;
                        a1[l] += u[l] * s1;
                        a2[l] += u[l] * s2;
                    }
                }
                let acc = [a0, a1, a2];
                let (mm, cc) = &self.transforms[t];
                let o = &mut out[(tt * k + first) * 3..(tt * k + first + n) * 3];
                for (l, o) in o.chunks_exact_mut(3).enumerate() {
                    for j in 0..3 {
                        o[j] = (acc[0][l] * mm[j] + acc[1][l] * mm[3 + j] + acc[2][l] * mm[6 + j] + cc[j]) as f32;
                    }
                }
            }
        }
    }
}

/// The plain loops [`reconstruct`] reproduces bit for bit (kept as the reference its tests
/// compare against).
pub fn reconstruct_reference(m: &Model) -> Vec<f32> {
    let (k, frames, v) = (m.k, m.frames, m.v);
    let d = frame_loadings(m);
    let mut out = vec![0.0f32; frames * k * 3];
    for t in 0..frames {
        let a = &m.transforms[t];
        let mm: [f64; 9] = a.m.map(|x| x as f64);
        let cc: [f64; 3] = a.c.map(|x| x as f64);
        let dt = &d[t * 3 * v..(t + 1) * 3 * v];
        for kk in 0..k {
            let row = &m.u1[kk * v..(kk + 1) * v];
            let x: [f64; 3] =
                std::array::from_fn(|j| row.iter().zip(&dt[j * v..(j + 1) * v]).map(|(a, b)| a * b).sum());
            let o = &mut out[(t * k + kk) * 3..(t * k + kk) * 3 + 3];
            for j in 0..3 {
                o[j] = (x[0] * mm[j] + x[1] * mm[3 + j] + x[2] * mm[6 + j] + cc[j]) as f32;
            }
        }
    }
    out
}
