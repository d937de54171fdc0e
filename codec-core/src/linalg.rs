//! Dense symmetric decompositions shared by the codecs, on faer, always sequential.
//!
//! hosvd's HO-SVD (the Gram matrices of the unfoldings, Romaszewski et al. Alg. 1), stseg's
//! per-group and per-segment PCA (Luo et al. §4.2–4.4) and pca-aoi's dictionary SVD (Lalos et
//! al. Eq. 3) each wrapped faer the same way; this is the one copy. Every call runs with
//! `Par::Seq`: the codecs encode clusters and groups in parallel with rayon themselves, and a
//! fixed sequential schedule keeps every floating-point reduction in the same order at any
//! thread count, so the bitstreams are deterministic. The results are bit for bit those of the
//! former per-crate wrappers (the same faer calls with the same arguments).

use std::borrow::Cow;
use std::fmt;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::evd::{self, ComputeEigenvectors, EvdError};
use faer::linalg::matmul::matmul;
use faer::linalg::svd::{self, ComputeSvdVectors, SvdError};
use faer::{Accum, Mat, MatRef, Par};

use crate::error::{debug_in_words, Error};

/// A decomposition that failed (faer's iterations did not converge).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum DecompositionError {
    /// The symmetric (self-adjoint) eigensolver reached its iteration limit.
    EigenNoConvergence,
    /// The singular value decomposition reached its iteration limit.
    SvdNoConvergence,
}

impl DecompositionError {
    /// The codec error for this failure in `codec`'s step `step`: [`Error::Numerical`] with
    /// faer's own words as the detail (what the codecs reported before this helper existed).
    pub fn numerical(self, codec: impl Into<Cow<'static, str>>, step: impl Into<Cow<'static, str>>) -> Error {
        let detail = match self {
            Self::EigenNoConvergence => debug_in_words(&EvdError::NoConvergence),
            Self::SvdNoConvergence => debug_in_words(&SvdError::NoConvergence),
        };
        Error::Numerical { context: codec.into(), step: step.into(), detail }
    }
}

impl fmt::Display for DecompositionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::EigenNoConvergence => "symmetric eigendecomposition did not converge",
            Self::SvdNoConvergence => "singular value decomposition did not converge",
        })
    }
}

impl std::error::Error for DecompositionError {}

impl From<EvdError> for DecompositionError {
    fn from(e: EvdError) -> Self {
        match e {
            EvdError::NoConvergence => Self::EigenNoConvergence,
        }
    }
}

impl From<SvdError> for DecompositionError {
    fn from(e: SvdError) -> Self {
        match e {
            SvdError::NoConvergence => Self::SvdNoConvergence,
        }
    }
}

/// `A·B`, sequential.
pub fn mul(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let mut c = Mat::<f64>::zeros(a.nrows(), b.ncols());
    matmul(c.as_mut(), Accum::Replace, a, b, 1.0, Par::Seq);
    c
}

/// Eigenvalues (clamped at zero, descending) and matching eigenvectors (columns, same order)
/// of the symmetric positive semi-definite matrix `g` (only its lower triangle is read).
///
/// faer sorts ascending; the callers (HO-SVD factors, PCA) want the leading components first.
/// Clamping removes the tiny negative values rounding gives a PSD Gram matrix, which would
/// otherwise turn into NaN square roots and negative energies.
pub fn sym_eig_desc(g: MatRef<'_, f64>) -> Result<(Vec<f64>, Mat<f64>), DecompositionError> {
    let n = g.nrows();
    if n == 0 {
        return Ok((Vec::new(), Mat::zeros(0, 0)));
    }
    let par = Par::Seq;
    let mut s = faer::diag::Diag::<f64>::zeros(n);
    let mut u = Mat::<f64>::zeros(n, n);
    let mut mem =
        MemBuffer::new(evd::self_adjoint_evd_scratch::<f64>(n, ComputeEigenvectors::Yes, par, Default::default()));
    evd::self_adjoint_evd(g, s.as_mut(), Some(u.as_mut()), par, MemStack::new(&mut mem), Default::default())?;
    let vals: Vec<f64> = (0..n).rev().map(|i| s.column_vector()[i].max(0.0)).collect();
    let vecs = Mat::from_fn(n, n, |i, j| u[(i, n - 1 - j)]);
    Ok((vals, vecs))
}

/// Eigenvalues only (clamped at zero, descending) of the symmetric PSD matrix `g`: what
/// [`sym_eig_desc`] gives without computing the eigenvectors.
pub fn sym_eigvals_desc(g: MatRef<'_, f64>) -> Result<Vec<f64>, DecompositionError> {
    let n = g.nrows();
    if n == 0 {
        return Ok(Vec::new());
    }
    let par = Par::Seq;
    let mut s = faer::diag::Diag::<f64>::zeros(n);
    let mut mem =
        MemBuffer::new(evd::self_adjoint_evd_scratch::<f64>(n, ComputeEigenvectors::No, par, Default::default()));
    evd::self_adjoint_evd(g, s.as_mut(), None, par, MemStack::new(&mut mem), Default::default())?;
    Ok((0..n).rev().map(|i| s.column_vector()[i].max(0.0)).collect())
}

/// `A = U·Σ·Uᵀ` of the square symmetric matrix `a` through the SVD (full `U`, singular values
/// nonincreasing). Unlike [`sym_eig_desc`] it reads the whole matrix and returns `|λ|`; pca-aoi
/// follows Lalos et al. Eq. 3, which writes the dictionary as the SVD of the autocorrelation
/// matrix, and its streams depend on these exact bits.
pub fn sym_svd(a: MatRef<'_, f64>) -> Result<(Mat<f64>, Vec<f64>), DecompositionError> {
    let n = a.nrows();
    let mut u = Mat::zeros(n, n);
    let mut s = faer::diag::Diag::<f64>::zeros(n);
    let mut buf = MemBuffer::new(svd::svd_scratch::<f64>(
        n,
        n,
        ComputeSvdVectors::Full,
        ComputeSvdVectors::No,
        Par::Seq,
        Default::default(),
    ));
    svd::svd(a, s.as_mut(), Some(u.as_mut()), None, Par::Seq, MemStack::new(&mut buf), Default::default())?;
    let values = (0..n).map(|i| s.column_vector()[i]).collect();
    Ok((u, values))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn max_abs(m: MatRef<'_, f64>) -> f64 {
        let mut x: f64 = 0.0;
        for j in 0..m.ncols() {
            for i in 0..m.nrows() {
                x = x.max(m[(i, j)].abs());
            }
        }
        x
    }

    fn gram() -> Mat<f64> {
        let x = Mat::from_fn(6, 10, |i, j| ((i * 3 + j * 5) % 7) as f64 - 3.0);
        mul(x.as_ref(), x.transpose())
    }

    fn reconstruct(u: &Mat<f64>, s: &[f64]) -> Mat<f64> {
        let n = u.nrows();
        Mat::from_fn(n, n, |i, j| (0..s.len()).map(|k| s[k] * u[(i, k)] * u[(j, k)]).sum())
    }

    #[test]
    fn eigen_decomposition_is_descending_and_reconstructs() {
        let a = gram();
        let (vals, vecs) = sym_eig_desc(a.as_ref()).unwrap();
        assert!(vals.windows(2).all(|w| w[0] >= w[1]) && vals.iter().all(|&v| v >= 0.0));
        assert!(max_abs((&reconstruct(&vecs, &vals) - &a).as_ref()) < 1e-10 * max_abs(a.as_ref()));
        assert_eq!(sym_eigvals_desc(a.as_ref()).unwrap(), vals);
        assert_eq!(sym_eig_desc(Mat::<f64>::zeros(0, 0).as_ref()).unwrap().0, Vec::<f64>::new());
    }

    #[test]
    fn svd_of_symmetric_reconstructs() {
        let a = gram();
        let (u, s) = sym_svd(a.as_ref()).unwrap();
        assert!(s.windows(2).all(|w| w[0] >= w[1]));
        assert!(max_abs((&reconstruct(&u, &s) - &a).as_ref()) < 1e-10 * max_abs(a.as_ref()));
    }

    #[test]
    fn errors_keep_faer_words_and_name_codec_and_step() {
        let e = DecompositionError::EigenNoConvergence.numerical("hosvd", "Gram eigensolver");
        let Error::Numerical { context, step, detail } = &e else { panic!("{e:?}") };
        assert_eq!((context.as_ref(), step.as_ref()), ("hosvd", "Gram eigensolver"));
        assert_eq!(detail, &debug_in_words(&EvdError::NoConvergence));
        let e = DecompositionError::SvdNoConvergence.numerical("pca-aoi", "svd").to_string();
        assert!(e.contains("pca-aoi") && e.contains("svd"), "{e}");
    }
}
