//! Small dense helpers on top of faer: Gram matrices and symmetric eigen-decompositions.

use codec_core::{Error, Result};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::evd::{self, ComputeEigenvectors};
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};

use crate::NAME;

/// `Aᵀ·A`.
pub fn gram(a: MatRef<'_, f64>) -> Mat<f64> {
    let mut c = Mat::<f64>::zeros(a.ncols(), a.ncols());
    matmul(c.as_mut(), Accum::Replace, a.transpose(), a, 1.0, Par::Seq);
    c
}

/// `A·B`.
pub fn mul(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let mut c = Mat::<f64>::zeros(a.nrows(), b.ncols());
    matmul(c.as_mut(), Accum::Replace, a, b, 1.0, Par::Seq);
    c
}

/// Eigenvalues (clamped at zero, descending) and matching eigenvectors (columns) of a
/// symmetric positive semi-definite matrix.
pub fn sym_eig_desc(g: MatRef<'_, f64>, step: &'static str) -> Result<(Vec<f64>, Mat<f64>)> {
    let n = g.nrows();
    if n == 0 {
        return Ok((Vec::new(), Mat::zeros(0, 0)));
    }
    let par = Par::Seq;
    let mut s = faer::diag::Diag::<f64>::zeros(n);
    let mut u = Mat::<f64>::zeros(n, n);
    let mut mem =
        MemBuffer::new(evd::self_adjoint_evd_scratch::<f64>(n, ComputeEigenvectors::Yes, par, Default::default()));
    evd::self_adjoint_evd(g, s.as_mut(), Some(u.as_mut()), par, MemStack::new(&mut mem), Default::default()).map_err(
        |e| Error::Numerical { context: NAME.into(), step: step.into(), detail: codec_core::error::debug_in_words(&e) },
    )?;
    // faer sorts ascending; PCA wants the leading components first.
    let vals: Vec<f64> = (0..n).rev().map(|i| s.column_vector()[i].max(0.0)).collect();
    let vecs = Mat::from_fn(n, n, |i, j| u[(i, n - 1 - j)]);
    Ok((vals, vecs))
}

/// Eigenvalues only (descending, clamped at zero) of a symmetric PSD matrix.
pub fn sym_eigvals_desc(g: MatRef<'_, f64>, step: &'static str) -> Result<Vec<f64>> {
    let n = g.nrows();
    if n == 0 {
        return Ok(Vec::new());
    }
    let par = Par::Seq;
    let mut s = faer::diag::Diag::<f64>::zeros(n);
    let mut mem =
        MemBuffer::new(evd::self_adjoint_evd_scratch::<f64>(n, ComputeEigenvectors::No, par, Default::default()));
    evd::self_adjoint_evd(g, s.as_mut(), None, par, MemStack::new(&mut mem), Default::default()).map_err(|e| {
        Error::Numerical { context: NAME.into(), step: step.into(), detail: codec_core::error::debug_in_words(&e) }
    })?;
    Ok((0..n).rev().map(|i| s.column_vector()[i].max(0.0)).collect())
}

/// Number of principal components that keep at least the share `omega` of the energy
/// (the "information persistence rate" of §4.4). Zero when the total energy is at most
/// `negligible` (a still block: the mean alone reconstructs it).
pub fn pcs_for_persistence(vals_desc: &[f64], omega: f64, negligible: f64) -> usize {
    let total: f64 = vals_desc.iter().sum();
    if total <= negligible {
        return 0;
    }
    let mut acc = 0.0;
    for (k, v) in vals_desc.iter().enumerate() {
        acc += v;
        if acc >= omega * total {
            return k + 1;
        }
    }
    vals_desc.len()
}

/// Double-centres a symmetric Gram block in place: the Gram matrix of the same columns after
/// subtracting their mean column (`J·G·J`, `J = I − 11ᵀ/n`).
pub fn double_center(g: &mut Mat<f64>) {
    let n = g.nrows();
    if n == 0 {
        return;
    }
    let nf = n as f64;
    let row: Vec<f64> = (0..n).map(|i| (0..n).map(|j| g[(i, j)]).sum::<f64>() / nf).collect();
    let all = row.iter().sum::<f64>() / nf;
    for i in 0..n {
        for j in 0..n {
            g[(i, j)] = g[(i, j)] - row[i] - row[j] + all;
        }
    }
}
