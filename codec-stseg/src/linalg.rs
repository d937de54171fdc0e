//! Small dense helpers on top of faer: Gram matrices, and the shared symmetric
//! eigen-decomposition ([`codec_core::linalg`]) with this codec's error context.

pub use codec_core::linalg::mul;
use codec_core::{linalg, Result};
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};

use crate::NAME;

/// `Aᵀ·A`.
pub fn gram(a: MatRef<'_, f64>) -> Mat<f64> {
    let mut c = Mat::<f64>::zeros(a.ncols(), a.ncols());
    matmul(c.as_mut(), Accum::Replace, a.transpose(), a, 1.0, Par::Seq);
    c
}

/// Eigenvalues (clamped at zero, descending) and matching eigenvectors (columns) of a
/// symmetric positive semi-definite matrix; a failure names the PCA `step`.
pub fn sym_eig_desc(g: MatRef<'_, f64>, step: &'static str) -> Result<(Vec<f64>, Mat<f64>)> {
    linalg::sym_eig_desc(g).map_err(|e| e.numerical(NAME, step))
}

/// Eigenvalues only (descending, clamped at zero) of a symmetric PSD matrix.
pub fn sym_eigvals_desc(g: MatRef<'_, f64>, step: &'static str) -> Result<Vec<f64>> {
    linalg::sym_eigvals_desc(g).map_err(|e| e.numerical(NAME, step))
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
