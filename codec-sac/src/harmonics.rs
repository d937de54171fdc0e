//! Manifold harmonics (paper §3.4, Vallet & Lévy 2008): the smallest eigenpairs of the
//! cotangent Laplacian `L x = λ M x` with the lumped mass matrix, computed by shift-invert
//! Krylov–Schur (faer's matrix-free `partial_self_adjoint_eigen`) over faer's sparse Cholesky,
//! and the per-triangle transfer of paper Eq. 5.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::evd::{self_adjoint_evd, self_adjoint_evd_scratch, ComputeEigenvectors};
use faer::linalg::matmul::matmul;
use faer::linalg::svd::{svd, svd_scratch, ComputeSvdVectors};
use faer::matrix_free::eigen::{partial_self_adjoint_eigen, partial_self_adjoint_eigen_scratch, PartialEigenParams};
use faer::matrix_free::LinOp;
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Accum, Col, Conj, Mat, MatMut, MatRef, Par, Side};

use codec_core::{Error, Limits, Result};

use crate::geometry::{corners, cross, dot, norm, sub, V3};
use crate::poisson::cholesky_work;
use crate::NAME;

fn numerical(step: &'static str, detail: impl Into<String>) -> Error {
    Error::Numerical { context: NAME.into(), step: step.into(), detail: detail.into() }
}

/// Cotangent stiffness matrix (upper triangle, as triplets) and lumped (barycentric) mass.
///
/// Cotangents are clamped to ±1e6 so a degenerate triangle cannot inject infinities; a vertex
/// with no area (only in degenerate triangles, or in none) gets a floor mass of 1e-12 of the
/// average, which keeps `M` invertible (such vertices then carry their own high-frequency
/// eigenvectors and are otherwise harmless).
pub fn laplacian(pos: &[V3], tris: &[[usize; 3]]) -> (Vec<Triplet<usize, usize, f64>>, Vec<f64>, f64) {
    let n = pos.len();
    let mut diag = vec![0.0f64; n];
    let mut mass = vec![0.0f64; n];
    let mut off: Vec<Triplet<usize, usize, f64>> = Vec::with_capacity(tris.len() * 3 + n);
    let mut total_area = 0.0;
    for &t in tris {
        let p = corners(pos, t);
        let area = 0.5 * norm(cross(sub(p[1], p[0]), sub(p[2], p[0])));
        total_area += area;
        for k in 0..3 {
            mass[t[k]] += area / 3.0;
            // Angle at corner k is opposite the edge (k+1, k+2).
            let a = sub(p[(k + 1) % 3], p[k]);
            let b = sub(p[(k + 2) % 3], p[k]);
            let c = norm(cross(a, b));
            let cot = if c > 0.0 { (dot(a, b) / c).clamp(-1e6, 1e6) } else { 0.0 };
            let w = 0.5 * cot;
            let (i, j) = (t[(k + 1) % 3], t[(k + 2) % 3]);
            off.push(Triplet::new(i.min(j), i.max(j), -w));
            diag[i] += w;
            diag[j] += w;
        }
    }
    let floor = 1e-12 * total_area.max(f64::MIN_POSITIVE) / n.max(1) as f64;
    for m in mass.iter_mut() {
        if m.is_nan() || *m <= floor {
            *m = floor;
        }
    }
    for (i, d) in diag.into_iter().enumerate() {
        off.push(Triplet::new(i, i, d));
    }
    (off, mass, total_area)
}

/// `M^{1/2} (L + σM)⁻¹ M^{1/2}`: symmetric, its largest eigenvalues `1/(λ + σ)` belong to
/// the smallest generalized eigenvalues `λ` of `L x = λ M x`.
#[derive(Debug)]
struct ShiftInvert {
    cholesky: SymbolicCholesky<usize>,
    values: Vec<f64>,
    sqrt_mass: Vec<f64>,
}

impl LinOp<f64> for ShiftInvert {
    fn apply_scratch(&self, rhs_ncols: usize, par: Par) -> StackReq {
        self.cholesky.solve_in_place_scratch::<f64>(rhs_ncols, par)
    }
    fn nrows(&self) -> usize {
        self.sqrt_mass.len()
    }
    fn ncols(&self) -> usize {
        self.sqrt_mass.len()
    }
    fn apply(&self, mut out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, _par: Par, stack: &mut MemStack) {
        for j in 0..rhs.ncols() {
            for i in 0..rhs.nrows() {
                out[(i, j)] = rhs[(i, j)] * self.sqrt_mass[i];
            }
        }
        // Always sequential: the eigenvectors must not depend on the thread count.
        LltRef::new(&self.cholesky, &self.values).solve_in_place_with_conj(Conj::No, out.as_mut(), Par::Seq, stack);
        for j in 0..rhs.ncols() {
            for i in 0..rhs.nrows() {
                out[(i, j)] *= self.sqrt_mass[i];
            }
        }
    }
    fn conj_apply(&self, out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, par: Par, stack: &mut MemStack) {
        self.apply(out, rhs, par, stack)
    }
}

/// Smallest eigenpairs of `M^{-1/2} (L + σM) M^{-1/2}` by a dense faer eigendecomposition
/// (small meshes only). Returns the symmetric-form vectors `y` and `λ` ascending.
fn dense_eigen(
    trip: &[Triplet<usize, usize, f64>],
    sqrt_mass: &[f64],
    count: usize,
    sigma: f64,
    limits: &Limits,
) -> Result<(Mat<f64>, Vec<f64>)> {
    let n = sqrt_mass.len();
    // Two n × n matrices and the decomposition's scratch, before allocating.
    let evd = self_adjoint_evd_scratch::<f64>(n, ComputeEigenvectors::Yes, Par::Seq, Default::default());
    // The matrix and its eigenvectors are held together with the scratch (`Limits` bounds the
    // total a decode holds).
    let matrices = (n as u64).saturating_mul(n as u64).saturating_mul(16);
    limits.check_alloc(
        NAME,
        "dense eigensolver (n × n)",
        matrices.saturating_add(evd.unaligned_bytes_required() as u64),
    )?;
    let mut a = Mat::<f64>::zeros(n, n);
    for t in trip {
        let v = t.val / (sqrt_mass[t.row] * sqrt_mass[t.col]);
        a[(t.row, t.col)] += v;
        if t.row != t.col {
            a[(t.col, t.row)] += v;
        }
    }
    let mut u = Mat::<f64>::zeros(n, n);
    let mut s = Col::<f64>::zeros(n);
    let mut buf = MemBuffer::new(evd);
    self_adjoint_evd(
        a.as_ref(),
        s.as_mut().as_diagonal_mut(),
        Some(u.as_mut()),
        Par::Seq,
        MemStack::new(&mut buf),
        Default::default(),
    )
    .map_err(|e| numerical("manifold harmonics (dense)", codec_core::error::debug_in_words(&e)))?;
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| s[i].total_cmp(&s[j]));
    let vecs = Mat::<f64>::from_fn(n, count, |i, k| u[(i, order[k])]);
    Ok((vecs, order[..count].iter().map(|&i| s[i] - sigma).collect()))
}

/// Smallest eigenpairs by shift-invert Krylov–Schur (faer `partial_self_adjoint_eigen`) over a
/// sparse Cholesky factorization of `L + σM` (`a`, upper triangle).
fn krylov_eigen(
    a: &SparseColMat<usize, f64>,
    sqrt_mass: &[f64],
    count: usize,
    sigma: f64,
    max_dim: usize,
    limits: &Limits,
) -> Result<(Mat<f64>, Vec<f64>)> {
    let n = sqrt_mass.len();
    let cholesky = factorize_symbolic_cholesky(a.symbolic(), Side::Upper, SymmetricOrdering::Amd, Default::default())
        .map_err(|e| numerical("laplacian symbolic factorization", codec_core::error::debug_in_words(&e)))?;
    // The fill is known now: refuse a topology whose factor exceeds the limits before any
    // numeric allocation (a crafted, expander-like connectivity fills in almost densely).
    limits.check_work(NAME, "laplacian factorization (sparse Cholesky)", cholesky_work(cholesky.len_val(), n))?;
    let numeric_scratch = cholesky.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default());
    let factor_bytes = (cholesky.len_val() as u64).saturating_mul(8);
    limits.check_alloc(
        NAME,
        "laplacian factor (sparse Cholesky fill)",
        factor_bytes.saturating_add(numeric_scratch.unaligned_bytes_required() as u64),
    )?;
    // The factor stays held (with a copy of the mass) while the eigensolver runs.
    let limits = limits.reserve(NAME, "laplacian factor (sparse Cholesky fill)", factor_bytes + n as u64 * 8)?;
    let mut values = vec![0.0; cholesky.len_val()];
    {
        let mut buf = MemBuffer::new(numeric_scratch);
        cholesky
            .factorize_numeric_llt(
                &mut values,
                a.as_ref(),
                Side::Upper,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut buf),
                Default::default(),
            )
            .map_err(|e| numerical("laplacian factorization", codec_core::error::debug_in_words(&e)))?;
    }
    let op = ShiftInvert { cholesky, values, sqrt_mass: sqrt_mass.to_vec() };
    // A few more pairs than needed: Krylov–Schur can return a "ghost" copy of a converged
    // vector in place of the last wanted one; the Rayleigh–Ritz step below removes it.
    let want = (count + (count / 10).max(8)).min(n);
    let params = PartialEigenParams { max_dim: max_dim.max(2 * want + 20).min(n - 1), ..Default::default() };
    // Krylov–Schur's projection space (`max_dim` vectors of n) lives in its scratch; the
    // returned vectors and the Rayleigh–Ritz step allocate n × want blocks and an SVD scratch;
    // all are held at once (the Rayleigh–Ritz step holds about three n × want blocks).
    let krylov = partial_self_adjoint_eigen_scratch::<f64>(&op, want, Par::Seq, params);
    let ritz_svd =
        svd_scratch::<f64>(n, want, ComputeSvdVectors::Thin, ComputeSvdVectors::No, Par::Seq, Default::default());
    let blocks = (n as u64).saturating_mul(want as u64).saturating_mul(8 * 3);
    limits.check_alloc(
        NAME,
        "eigensolver workspace (Krylov vectors, eigenvectors, Rayleigh-Ritz)",
        (krylov.unaligned_bytes_required() as u64)
            .saturating_add(ritz_svd.unaligned_bytes_required() as u64)
            .saturating_add(blocks),
    )?;
    let mut vecs = Mat::<f64>::zeros(n, want);
    let mut vals = vec![0.0f64; want];
    // xorshift start vector: fixed, and not an eigenvector (a constant would be one).
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let v0 = Col::<f64>::from_fn(n, |_| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 + 0.5
    });
    let mut buf = MemBuffer::new(krylov);
    let info = partial_self_adjoint_eigen(
        vecs.as_mut(),
        &mut vals,
        &op,
        v0.as_ref(),
        TOLERANCE,
        Par::Seq,
        MemStack::new(&mut buf),
        params,
    );
    let got = info.n_converged_eigen.min(want);
    rayleigh_ritz(&op, vecs.as_ref().subcols(0, got), count, sigma)
}

/// Relative residual tolerance of the Krylov–Schur iteration (the Rayleigh–Ritz step then
/// makes the vectors exactly orthonormal).
const TOLERANCE: f64 = 1e-9;

/// Rayleigh–Ritz on the span of `y`: an orthonormal basis of the span (faer thin SVD, rank
/// revealed at 10⁻⁸), the projected operator, its dense eigendecomposition, and the `count`
/// Ritz pairs of largest `μ` (smallest `λ = 1/μ − σ`).
fn rayleigh_ritz(op: &ShiftInvert, y: MatRef<'_, f64>, count: usize, sigma: f64) -> Result<(Mat<f64>, Vec<f64>)> {
    let (n, k) = y.shape();
    let mut u = Mat::<f64>::zeros(n, k);
    let mut s = Col::<f64>::zeros(k);
    let mut buf = MemBuffer::new(svd_scratch::<f64>(
        n,
        k,
        ComputeSvdVectors::Thin,
        ComputeSvdVectors::No,
        Par::Seq,
        Default::default(),
    ));
    svd(y, s.as_mut().as_diagonal_mut(), Some(u.as_mut()), None, Par::Seq, MemStack::new(&mut buf), Default::default())
        .map_err(|e| numerical("rayleigh-ritz svd", codec_core::error::debug_in_words(&e)))?;
    let smax = (0..k).map(|i| s[i]).fold(0.0, f64::max);
    let r = (0..k).filter(|&i| s[i] > 1e-8 * smax).count();
    if r < count {
        return Err(numerical(
            "manifold harmonics",
            format!("eigensolver found {r} independent eigenvectors of {count}"),
        ));
    }
    let q = u.as_ref().subcols(0, r);
    let mut aq = Mat::<f64>::zeros(n, r);
    let mut buf = MemBuffer::new(op.apply_scratch(r, Par::Seq));
    op.apply(aq.as_mut(), q, Par::Seq, MemStack::new(&mut buf));
    // Explicitly sequential products: the operator `*` would use faer's global parallelism.
    let mut t = Mat::<f64>::zeros(r, r);
    matmul(t.as_mut(), Accum::Replace, q.transpose(), aq.as_ref(), 1.0, Par::Seq);
    let t = Mat::<f64>::from_fn(r, r, |i, j| 0.5 * (t[(i, j)] + t[(j, i)]));
    let mut z = Mat::<f64>::zeros(r, r);
    let mut mu = Col::<f64>::zeros(r);
    let mut buf =
        MemBuffer::new(self_adjoint_evd_scratch::<f64>(r, ComputeEigenvectors::Yes, Par::Seq, Default::default()));
    self_adjoint_evd(
        t.as_ref(),
        mu.as_mut().as_diagonal_mut(),
        Some(z.as_mut()),
        Par::Seq,
        MemStack::new(&mut buf),
        Default::default(),
    )
    .map_err(|e| numerical("rayleigh-ritz eigen", codec_core::error::debug_in_words(&e)))?;
    // μ = 1/(λ + σ): λ ascending is μ descending; the sort is stable.
    let mut order: Vec<usize> = (0..r).collect();
    order.sort_by(|&i, &j| mu[j].total_cmp(&mu[i]));
    let mut ritz = Mat::<f64>::zeros(n, r);
    matmul(ritz.as_mut(), Accum::Replace, q, z.as_ref(), 1.0, Par::Seq);
    let out = Mat::<f64>::from_fn(n, count, |i, c| ritz[(i, order[c])]);
    let lambdas =
        order[..count].iter().map(|&i| if mu[i] > 0.0 { 1.0 / mu[i] - sigma } else { f64::INFINITY }).collect();
    Ok((out, lambdas))
}

/// Manifold harmonic bases: `count` mass-orthonormal eigenvectors (columns of an `n × count`
/// matrix) of the smallest eigenvalues, ascending, with deterministic signs.
pub struct Harmonics {
    /// Basis vectors, `n × count`, `Hᵀ M H = I`.
    pub basis: Mat<f64>,
    /// Generalized eigenvalues, ascending.
    pub eigenvalues: Vec<f64>,
}

/// Operations the harmonics of `n` vertices with `count` vectors take, from the sizes alone
/// (so a decoder refuses a crafted basis request before any work; `Limits::max_work`): on
/// the Krylov path, one pass of Krylov–Schur's full reorthogonalization against its `max_dim`
/// vectors (2 n max_dim²) and the Rayleigh–Ritz thin SVD (4 n want²); on the dense path, the
/// n × n eigendecomposition (4 n³). A lower bound of the real count (restarts, the shift-invert
/// solves and the Laplacian factorization come on top; the factorization is checked once its
/// fill is known, [`cholesky_work`]). Covers the by-component basis too: each component's
/// count is at most the whole mesh's, per vertex.
pub fn work_estimate(n: usize, count: usize) -> u64 {
    let (n64, count) = (n as u64, count.min(n) as u64);
    if n == 0 || count == 0 {
        return 0;
    }
    let want = (count + (count / 10).max(8)).min(n64);
    let max_dim = (2 * count + 20).max(64);
    if max_dim + 1 >= n64 {
        return 4u64.saturating_mul(n64).saturating_mul(n64).saturating_mul(n64);
    }
    let reorthogonalize = 2u64.saturating_mul(n64).saturating_mul(max_dim.saturating_mul(max_dim));
    let ritz = 4u64.saturating_mul(n64).saturating_mul(want.saturating_mul(want));
    reorthogonalize.saturating_add(ritz)
}

/// Computes the first `count` manifold harmonics of the mesh `pos`/`tris`.
///
/// Shift `σ = 10⁻²/area` sits well below the first non-zero eigenvalue (≈ 1/area in these
/// units) so `L + σM` is positive definite and the wanted end of the spectrum is well separated
/// after inversion. The Krylov start vector is a fixed pseudo-random sequence, every step runs
/// sequentially, and each eigenvector's sign is chosen so that its largest-magnitude entry (the
/// first one on exact ties) is positive: the same decoded frame always gives the same basis.
pub fn harmonics(pos: &[V3], tris: &[[usize; 3]], count: usize) -> Result<Harmonics> {
    harmonics_within(pos, tris, count, &crate::UNLIMITED)
}

/// [`harmonics`], refusing with [`Error::AllocLimit`] (before allocating) a factor or an
/// eigensolver workspace larger than `limits` allows: the decoder's entry point.
pub fn harmonics_within(pos: &[V3], tris: &[[usize; 3]], count: usize, limits: &Limits) -> Result<Harmonics> {
    harmonics_with(pos, tris, count, 0, limits)
}

/// [`harmonics`] with a dense solve whenever `n ≤ dense_up_to` (0 keeps stream version 1's
/// rule: dense only when the Krylov space would reach `n`).
fn harmonics_with(
    pos: &[V3],
    tris: &[[usize; 3]],
    count: usize,
    dense_up_to: usize,
    limits: &Limits,
) -> Result<Harmonics> {
    let n = pos.len();
    let count = count.min(n);
    if n == 0 || count == 0 {
        return Ok(Harmonics { basis: Mat::zeros(n, 0), eigenvalues: Vec::new() });
    }
    limits.check_work(NAME, "manifold harmonics", work_estimate(n, count))?;
    let (mut trip, mass, area) = laplacian(pos, tris);
    if !(area > 0.0 && area.is_finite()) {
        return Err(numerical("manifold harmonics", format!("mesh area {area} is not positive")));
    }
    if trip.iter().any(|t| !t.val.is_finite()) || mass.iter().any(|m| !m.is_finite()) {
        return Err(numerical("manifold harmonics", "non-finite Laplacian or mass (extreme coordinates?)"));
    }
    let sigma = 1e-2 / area;
    for (i, &m) in mass.iter().enumerate() {
        trip.push(Triplet::new(i, i, sigma * m));
    }
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &trip)
        .map_err(|e| numerical("laplacian assembly", codec_core::error::debug_in_words(&e)))?;
    let sqrt_mass: Vec<f64> = mass.iter().map(|m| m.sqrt()).collect();
    // Krylov–Schur needs a projection space smaller than n; faer panics otherwise, so small
    // meshes (where a dense problem is cheap anyway) take the dense path.
    let max_dim = (2 * count + 20).max(64);
    let (sym_vecs, eigenvalues) = if max_dim + 1 >= n || n <= dense_up_to {
        dense_eigen(&trip, &sqrt_mass, count, sigma, limits)?
    } else {
        krylov_eigen(&a, &sqrt_mass, count, sigma, max_dim, limits)?
    };
    let mut basis = Mat::<f64>::zeros(n, count);
    for k in 0..count {
        // Back from the symmetric form: x = M^{-1/2} y, which is M-orthonormal.
        let mut best = 0usize;
        for i in 0..n {
            if sym_vecs[(i, k)].abs() > sym_vecs[(best, k)].abs() {
                best = i;
            }
        }
        let sign = if sym_vecs[(best, k)] < 0.0 { -1.0 } else { 1.0 };
        for i in 0..n {
            basis[(i, k)] = sign * sym_vecs[(i, k)] / sqrt_mass[i];
        }
    }
    if basis.col_iter().any(|c| c.iter().any(|x| !x.is_finite())) {
        return Err(numerical("manifold harmonics", "non-finite basis vector"));
    }
    Ok(Harmonics { basis, eigenvalues })
}

/// Manifold harmonics of a possibly disconnected mesh, one connected component at a time
/// (stream version ≥ 2).
///
/// The Laplacian of a disconnected mesh is block diagonal, so its eigenpairs are the union of
/// the components' eigenpairs (each extended by zero), and the `count` smallest of the union
/// are the whole mesh's first `count` harmonics. Solving per component matters because the
/// eigenvalue 0 has one eigenvector per component: on chicken-crossing (41 components) the
/// single-start-vector Krylov–Schur of [`harmonics`] must find a 41-fold eigenvalue, which it
/// cannot (a Krylov space holds one vector per eigenspace), and with 16 bases it ran for more
/// than 12 minutes. Per component, 0 is simple. Components without triangles or
/// without area carry no triangle field and get no basis vector. Components of at most
/// [`DENSE_COMPONENT`] vertices use the dense solver. Ties in `λ` are broken by component
/// (lowest vertex first), then by position within the component; the order is deterministic.
/// A connected mesh gives exactly [`harmonics`]' result.
pub fn harmonics_by_component(pos: &[V3], tris: &[[usize; 3]], count: usize) -> Result<Harmonics> {
    harmonics_by_component_within(pos, tris, count, &crate::UNLIMITED)
}

/// [`harmonics_by_component`] within `limits` (see [`harmonics_within`]).
pub fn harmonics_by_component_within(
    pos: &[V3],
    tris: &[[usize; 3]],
    count: usize,
    limits: &Limits,
) -> Result<Harmonics> {
    let n = pos.len();
    let (component, pins) = crate::geometry::components(n, tris);
    if pins.len() <= 1 {
        return harmonics_within(pos, tris, count, limits);
    }
    let nc = pins.len();
    let mut local = vec![0usize; n];
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); nc];
    for (v, &c) in component.iter().enumerate() {
        local[v] = members[c].len();
        members[c].push(v);
    }
    let mut comp_tris: Vec<Vec<[usize; 3]>> = vec![Vec::new(); nc];
    for t in tris {
        comp_tris[component[t[0]]].push([local[t[0]], local[t[1]], local[t[2]]]);
    }
    // (λ, component, index within the component's result, the component's harmonics)
    let mut parts: Vec<Option<Harmonics>> = Vec::with_capacity(nc);
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for c in 0..nc {
        if comp_tris[c].is_empty() {
            parts.push(None);
            continue;
        }
        let lpos: Vec<V3> = members[c].iter().map(|&v| pos[v]).collect();
        let area: f64 = comp_tris[c]
            .iter()
            .map(|&t| {
                let p = corners(&lpos, t);
                0.5 * norm(cross(sub(p[1], p[0]), sub(p[2], p[0])))
            })
            .sum();
        if area.is_finite() && area <= 0.0 {
            parts.push(None);
            continue;
        }
        let h = harmonics_with(&lpos, &comp_tris[c], count.min(lpos.len()), DENSE_COMPONENT, limits)?;
        for (k, &l) in h.eigenvalues.iter().enumerate() {
            pairs.push((l, c, k));
        }
        parts.push(Some(h));
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    pairs.truncate(count);
    if pairs.is_empty() && count > 0 {
        return Err(numerical("manifold harmonics", "no component has a positive area"));
    }
    let mut basis = Mat::<f64>::zeros(n, pairs.len());
    for (col, &(_, c, k)) in pairs.iter().enumerate() {
        let h = parts[c].as_ref().expect("pairs come from solved components");
        for (i, &v) in members[c].iter().enumerate() {
            basis[(v, col)] = h.basis[(i, k)];
        }
    }
    Ok(Harmonics { basis, eigenvalues: pairs.iter().map(|p| p.0).collect() })
}

/// Components up to this many vertices are solved densely by [`harmonics_by_component`].
pub const DENSE_COMPONENT: usize = 400;

/// The per-triangle spectral transform: synthesis `B = C H` (`m × l`, paper Eq. 5 applied to
/// every basis vector, as Eq. 10–11 use it) and, for the encoder, the analysis operator
/// `B⁺ W^{1/2}`-weighted least squares (`l × m`).
///
/// The paper's analysis (Eq. 6, 8–9) maps a per-triangle field to vertices with
/// `(CᵀC)⁻¹Cᵀ` and then takes inner products with `H`. `CᵀC` is singular on every
/// 3-colourable triangulation (grids, octahedra: a field with values `a, b, c` on the three
/// colour classes, `a + b + c = 0`, averages to zero on every triangle), so instead the
/// descriptors are the area-weighted least-squares fit of the field by `C H`, computed with a
/// pseudo-inverse from faer's SVD. It reproduces any field in the span of `C H` exactly
/// (in particular the constant fields of a rigid motion) and is the best possible
/// per-triangle reconstruction for the given bases.
pub struct Transfer {
    /// `m × l` synthesis matrix, triangle values of each basis vector.
    pub synthesis: Mat<f64>,
}

impl Transfer {
    /// `C H` for the triangles `tris`.
    pub fn new(h: &Harmonics, tris: &[[usize; 3]]) -> Self {
        let l = h.basis.ncols();
        let synthesis = Mat::<f64>::from_fn(tris.len(), l, |j, k| {
            let t = tris[j];
            (h.basis[(t[0], k)] + h.basis[(t[1], k)] + h.basis[(t[2], k)]) / 3.0
        });
        Self { synthesis }
    }

    /// Number of bases.
    pub fn bases(&self) -> usize {
        self.synthesis.ncols()
    }

    /// Triangle field `C H c` from descriptors `c`.
    pub fn synthesize(&self, coeffs: &[f64], out: &mut [f64]) {
        // Column by column: the matrix is column major, so every pass is contiguous.
        out.fill(0.0);
        for (k, &c) in coeffs.iter().enumerate() {
            let col = self.synthesis.col(k);
            for (j, o) in out.iter_mut().enumerate() {
                *o += col[j] * c;
            }
        }
    }

    /// The encoder's analysis operator `(W^{1/2} C H)⁺ W^{1/2}` (`l × m`), `W` the triangle
    /// areas of the keyframe; singular values below `10⁻¹⁰ σ_max` are dropped.
    pub fn analysis(&self, weights: &[f64]) -> Result<Mat<f64>> {
        let (m, l) = self.synthesis.shape();
        let sw: Vec<f64> = weights.iter().map(|w| w.max(0.0).sqrt()).collect();
        let a = Mat::<f64>::from_fn(m, l, |j, k| sw[j] * self.synthesis[(j, k)]);
        let k = m.min(l);
        let mut u = Mat::<f64>::zeros(m, k);
        let mut v = Mat::<f64>::zeros(l, k);
        let mut s = Col::<f64>::zeros(k);
        let mut buf = MemBuffer::new(svd_scratch::<f64>(
            m,
            l,
            ComputeSvdVectors::Thin,
            ComputeSvdVectors::Thin,
            Par::Seq,
            Default::default(),
        ));
        svd(
            a.as_ref(),
            s.as_mut().as_diagonal_mut(),
            Some(u.as_mut()),
            Some(v.as_mut()),
            Par::Seq,
            MemStack::new(&mut buf),
            Default::default(),
        )
        .map_err(|e| numerical("spectral analysis svd", codec_core::error::debug_in_words(&e)))?;
        let smax = (0..k).map(|i| s[i].abs()).fold(0.0, f64::max);
        let mut out = Mat::<f64>::zeros(l, m);
        for i in 0..k {
            if s[i].abs() > 1e-10 * smax {
                let inv = 1.0 / s[i];
                for j in 0..m {
                    let uj = u[(j, i)] * inv * sw[j];
                    if uj != 0.0 {
                        for r in 0..l {
                            out[(r, j)] += v[(r, i)] * uj;
                        }
                    }
                }
            }
        }
        Ok(out)
    }
}

/// Descriptors `A f` of a triangle field `f` for an analysis operator `A` (`l × m`).
pub fn analyze(a: &Mat<f64>, field: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.nrows()];
    for (j, &f) in field.iter().enumerate() {
        if f != 0.0 {
            let col = a.col(j);
            for (r, o) in out.iter_mut().enumerate() {
                *o += col[r] * f;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::tests::blob;

    /// The first `count` columns of `h` solve `L x = λ M x` (residual below 1e-6 of `‖Mx‖(1+λ)`)
    /// and are M-orthonormal to 1e-8; `L x` from the upper-triangle triplets.
    fn assert_mass_orthonormal_eigenpairs(pos: &[V3], tris: &[[usize; 3]], h: &Harmonics, count: usize) {
        let n = pos.len();
        let (trip, mass, _) = laplacian(pos, tris);
        for k in 0..count {
            let x = h.basis.col(k);
            let mut lx = vec![0.0; n];
            for t in &trip {
                lx[t.row] += t.val * x[t.col];
                if t.row != t.col {
                    lx[t.col] += t.val * x[t.row];
                }
            }
            let res = (0..n).map(|i| (lx[i] - h.eigenvalues[k] * mass[i] * x[i]).powi(2)).sum::<f64>().sqrt();
            let scale = (0..n).map(|i| (mass[i] * x[i]).powi(2)).sum::<f64>().sqrt() * (1.0 + h.eigenvalues[k]);
            assert!(res < 1e-6 * scale, "eigenpair {k}: residual {res}");
            for q in 0..=k {
                let ip: f64 = (0..n).map(|i| h.basis[(i, q)] * mass[i] * x[i]).sum();
                let want = if q == k { 1.0 } else { 0.0 };
                assert!((ip - want).abs() < 1e-8, "<h{q}, h{k}>_M = {ip}");
            }
        }
    }

    #[test]
    fn harmonics_are_mass_orthonormal_eigenvectors_and_deterministic() {
        let (pos, tris) = blob(3);
        let n = pos.len();
        let h = harmonics(&pos, &tris, 20).unwrap();
        assert_eq!(h.basis.shape(), (n, 20));
        assert_mass_orthonormal_eigenpairs(&pos, &tris, &h, 20);
        assert!(h.eigenvalues.windows(2).all(|w| w[0] <= w[1] + 1e-9));
        assert!(h.eigenvalues[0].abs() < 1e-8, "first eigenvalue {}", h.eigenvalues[0]);
        // The first basis vector of a connected mesh is constant.
        let c0 = h.basis[(0, 0)];
        assert!((0..n).all(|i| (h.basis[(i, 0)] - c0).abs() < 1e-8 * c0.abs()));
        let again = harmonics(&pos, &tris, 20).unwrap();
        assert_eq!(again.basis, h.basis, "the basis must be bit-for-bit reproducible");
    }

    /// Identical disconnected components make every eigenvalue a multiple one (the
    /// eigenvalue 0 once per component), which the single-vector Krylov iteration of the whole
    /// mesh cannot resolve. Per component, the result is the single component's spectrum
    /// repeated, with exact eigenpairs of the whole mesh.
    #[test]
    fn disconnected_copies_give_each_component_spectrum_repeated() {
        let (one, one_tris) = blob(4);
        let n1 = one.len();
        assert!(n1 > DENSE_COMPONENT, "the copies must take the Krylov path");
        let copies = 4;
        let mut pos = Vec::new();
        let mut tris = Vec::new();
        for c in 0..copies {
            pos.extend(one.iter().map(|p| [p[0] + 3.0 * c as f64, p[1], p[2]]));
            tris.extend(one_tris.iter().map(|t| [t[0] + c * n1, t[1] + c * n1, t[2] + c * n1]));
        }
        let count = 14;
        let h = harmonics_by_component(&pos, &tris, count).unwrap();
        assert_eq!(h.basis.ncols(), count);
        let single = harmonics(&one, &one_tris, count).unwrap();
        let mut want: Vec<f64> = single.eigenvalues.iter().flat_map(|&l| std::iter::repeat_n(l, copies)).collect();
        want.sort_by(f64::total_cmp);
        for (k, &w) in want.iter().enumerate().take(count) {
            let got = h.eigenvalues[k];
            assert!((got - w).abs() < 1e-7 * (1.0 + w.abs()), "eigenvalue {k}: {got} vs {w}");
        }
        assert!(h.eigenvalues[..copies].iter().all(|l| l.abs() < 1e-8), "{:?}", h.eigenvalues);
        // Eigenpairs of the whole mesh, M-orthonormal.
        assert_mass_orthonormal_eigenpairs(&pos, &tris, &h, count);
        // A connected mesh gives exactly the whole-mesh solver's basis.
        let same = harmonics_by_component(&one, &one_tris, count).unwrap();
        assert_eq!(same.basis, single.basis);
    }

    #[test]
    fn shift_invert_krylov_agrees_with_a_dense_solve() {
        let (pos, tris) = blob(3);
        let n = pos.len();
        let (mut trip, mass, area) = laplacian(&pos, &tris);
        let sigma = 1e-2 / area;
        for (i, &m) in mass.iter().enumerate() {
            trip.push(Triplet::new(i, i, sigma * m));
        }
        let a = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &trip).unwrap();
        let sqrt_mass: Vec<f64> = mass.iter().map(|m| m.sqrt()).collect();
        let (vk, lk) = krylov_eigen(&a, &sqrt_mass, 30, sigma, 80, &crate::UNLIMITED).unwrap();
        let (vd, ld) = dense_eigen(&trip, &sqrt_mass, 30, sigma, &crate::UNLIMITED).unwrap();
        for k in 0..30 {
            assert!((lk[k] - ld[k]).abs() < 1e-8 * (1.0 + ld[k].abs()), "eigenvalue {k}: {} vs {}", lk[k], ld[k]);
        }
        // Eigenvectors agree up to sign where the eigenvalue is simple.
        for k in 1..29 {
            if ld[k] - ld[k - 1] > 1e-6 && ld[k + 1] - ld[k] > 1e-6 {
                let dot: f64 = (0..n).map(|i| vk[(i, k)] * vd[(i, k)]).sum();
                assert!((dot.abs() - 1.0).abs() < 1e-6, "vector {k}: |<krylov, dense>| = {}", dot.abs());
            }
        }
    }

    #[test]
    fn full_basis_on_a_tiny_mesh_and_constant_fields_are_exact() {
        let (pos, tris) = blob(0);
        let h = harmonics(&pos, &tris, 100).unwrap();
        assert_eq!(h.basis.ncols(), pos.len());
        let tr = Transfer::new(&h, &tris);
        let weights = vec![1.0; tris.len()];
        let a = tr.analysis(&weights).unwrap();
        let field = vec![0.25; tris.len()];
        let c = analyze(&a, &field);
        let mut back = vec![0.0; tris.len()];
        tr.synthesize(&c, &mut back);
        assert!(back.iter().all(|b| (b - 0.25).abs() < 1e-12), "{back:?}");
        // Also with a single basis vector.
        let h1 = harmonics(&pos, &tris, 1).unwrap();
        let tr1 = Transfer::new(&h1, &tris);
        let c = analyze(&tr1.analysis(&weights).unwrap(), &field);
        tr1.synthesize(&c, &mut back);
        assert!(back.iter().all(|b| (b - 0.25).abs() < 1e-12), "{back:?}");
    }
}
