//! Thin wrappers over faer 0.24 that always run sequentially (`Par::Seq`).
//!
//! Clusters are already encoded in parallel with rayon, and a fixed sequential schedule keeps
//! every floating-point reduction in the same order whatever the thread count, so the
//! bitstream is deterministic.

pub(crate) use codec_core::linalg::mul;
use codec_core::{linalg, Result};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::householder::{
    apply_block_householder_sequence_on_the_left_in_place_scratch,
    apply_block_householder_sequence_on_the_left_in_place_with_conj,
};
use faer::linalg::matmul::matmul;
use faer::linalg::qr::no_pivoting::factor::{qr_in_place, qr_in_place_scratch, recommended_block_size};
use faer::{Accum, Conj, Mat, MatRef, Par};

use crate::NAME;

/// `c ← c + alpha · a · b`.
pub(crate) fn mul_add(c: &mut Mat<f64>, a: MatRef<'_, f64>, b: MatRef<'_, f64>, alpha: f64) {
    matmul(c.as_mut(), Accum::Add, a, b, alpha, Par::Seq);
}

/// Orthonormal basis of the columns of `m` (`rows ≥ cols`) by Householder QR, the
/// orthonormalization the paper uses (§3.3.3, "HR"). Column signs are chosen so that
/// `R` has a nonnegative diagonal, which makes the factor unique and keeps every column
/// pointing the way its input column did.
pub(crate) fn orthonormalize(m: Mat<f64>) -> Mat<f64> {
    let (rows, cols) = m.shape();
    debug_assert!(rows >= cols);
    if cols == 0 {
        return m;
    }
    let bs = recommended_block_size::<f64>(rows, cols);
    let mut qr = m;
    let mut coeff = Mat::zeros(bs, cols);
    let mut buf = MemBuffer::new(qr_in_place_scratch::<f64>(rows, cols, bs, Par::Seq, Default::default()));
    qr_in_place(qr.as_mut(), coeff.as_mut(), Par::Seq, MemStack::new(&mut buf), Default::default());
    let negative: Vec<bool> = (0..cols).map(|j| qr[(j, j)] < 0.0).collect();
    // The Householder basis is the unit lower trapezoid of the factored matrix.
    for j in 0..cols {
        for i in 0..j {
            qr[(i, j)] = 0.0;
        }
        qr[(j, j)] = 1.0;
    }
    let mut q = Mat::<f64>::identity(rows, cols);
    let mut buf = MemBuffer::new(apply_block_householder_sequence_on_the_left_in_place_scratch::<f64>(rows, bs, cols));
    apply_block_householder_sequence_on_the_left_in_place_with_conj(
        qr.as_ref(),
        coeff.as_ref(),
        Conj::No,
        q.as_mut(),
        Par::Seq,
        MemStack::new(&mut buf),
    );
    for (j, &neg) in negative.iter().enumerate() {
        if neg {
            for i in 0..rows {
                q[(i, j)] = -q[(i, j)];
            }
        }
    }
    q
}

/// SVD of the square symmetric matrix `a` (Eq. 3, `A = U Σ Uᵀ`): left singular vectors and
/// singular values in nonincreasing order.
pub(crate) fn svd_symmetric(a: MatRef<'_, f64>) -> Result<(Mat<f64>, Vec<f64>)> {
    linalg::sym_svd(a).map_err(|e| e.numerical(NAME, "svd"))
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

    #[test]
    fn orthonormalize_gives_orthonormal_same_span() {
        let m = Mat::from_fn(9, 3, |i, j| ((i * 7 + j * 3) % 5) as f64 - 1.5 + (i == j) as u8 as f64);
        let q = orthonormalize(m.clone());
        let qtq = mul(q.transpose(), q.as_ref());
        let id = Mat::<f64>::identity(3, 3);
        assert!(max_abs((&qtq - &id).as_ref()) < 1e-12);
        // m lies in span(q): m - q qᵀ m = 0.
        let proj = mul(q.as_ref(), mul(q.transpose(), m.as_ref()).as_ref());
        assert!(max_abs((&m - &proj).as_ref()) < 1e-10 * max_abs(m.as_ref()));
        // Signs follow the input: diagonal of qᵀ m is nonnegative.
        let r = mul(q.transpose(), m.as_ref());
        assert!((0..3).all(|j| r[(j, j)] >= 0.0));
    }

    #[test]
    fn svd_of_symmetric_reconstructs() {
        let x = Mat::from_fn(6, 10, |i, j| ((i * 3 + j * 5) % 7) as f64 - 3.0);
        let a = mul(x.as_ref(), x.transpose());
        let (u, s) = svd_symmetric(a.as_ref()).unwrap();
        assert!(s.windows(2).all(|w| w[0] >= w[1]));
        let mut rec = Mat::<f64>::zeros(6, 6);
        for k in 0..6 {
            for i in 0..6 {
                for j in 0..6 {
                    rec[(i, j)] += s[k] * u[(i, k)] * u[(j, k)];
                }
            }
        }
        assert!(max_abs((&rec - &a).as_ref()) < 1e-10 * max_abs(a.as_ref()));
    }
}
