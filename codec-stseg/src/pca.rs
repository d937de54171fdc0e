//! The PCA of one vertex group over one segment (§4.4, Eq. 5): the centred data matrix, the
//! number of components at persistence ω, and the reconstruction `mean + A·B` both codings
//! decode to.

use codec_core::Result;
use faer::Mat;

use crate::linalg::{gram, pcs_for_persistence, sym_eig_desc};
use crate::mesh::{frame_diagonal, MeshGraph, NEGLIGIBLE_AMPLITUDE};
use crate::params::{Centering, StsegParams};

/// Number of mean quantizers and mean values of one group of `n` vertices over `frames`.
pub(crate) fn mean_layout(centering: Centering, n: usize, frames: usize) -> (usize, usize) {
    match centering {
        Centering::Vertex => (3, 3 * n),
        Centering::Frame => (1, frames),
        Centering::FrameAxis => (3, 3 * frames),
        Centering::None => (0, 0),
    }
}

/// The centred data matrix of a group (rows: vertex-major coordinates of `rows`, columns:
/// frames) and the mean that was subtracted (per row for [`Centering::Vertex`], per frame for
/// [`Centering::Frame`], empty for [`Centering::None`]).
pub(crate) fn centred_block(
    centering: Centering,
    rows: &[u32],
    block: &[f32],
    n3: usize,
    frames: usize,
) -> (Mat<f64>, Vec<f64>) {
    let x_at = |r: usize, t: usize| block[t * n3 + rows[r / 3] as usize * 3 + r % 3] as f64;
    let nr = rows.len() * 3;
    match centering {
        Centering::Vertex => {
            let mean: Vec<f64> =
                (0..nr).map(|r| (0..frames).map(|t| x_at(r, t)).sum::<f64>() / frames as f64).collect();
            (Mat::from_fn(nr, frames, |r, t| x_at(r, t) - mean[r]), mean)
        }
        Centering::Frame => {
            let mean: Vec<f64> =
                (0..frames).map(|t| (0..nr).map(|r| x_at(r, t)).sum::<f64>() / nr.max(1) as f64).collect();
            (Mat::from_fn(nr, frames, |r, t| x_at(r, t) - mean[t]), mean)
        }
        Centering::FrameAxis => {
            // mean[t·3 + c]
            let n = rows.len().max(1) as f64;
            let mean: Vec<f64> = (0..frames * 3)
                .map(|tc| (0..rows.len()).map(|i| x_at(i * 3 + tc % 3, tc / 3)).sum::<f64>() / n)
                .collect();
            (Mat::from_fn(nr, frames, |r, t| x_at(r, t) - mean[t * 3 + r % 3]), mean)
        }
        Centering::None => (Mat::from_fn(nr, frames, x_at), Vec::new()),
    }
}

/// The ω-persistence PCA of one group of one segment (§4.4): the number of components `k`
/// and the leading eigenvectors of the Gram matrix of the η-extended, centred block.
pub(crate) fn group_pca(
    p: &StsegParams,
    graph: &MeshGraph,
    own: &[u32],
    block: &[f32],
    frames: usize,
) -> Result<(usize, Mat<f64>)> {
    group_pca_energy(p, graph, own, block, frames).map(|(k, vecs, _, _)| (k, vecs))
}

/// [`group_pca`] plus the truncation energy it leaves and the total energy of the η-extended,
/// centred block (sums of the discarded and of all eigenvalues).
pub(crate) fn group_pca_energy(
    p: &StsegParams,
    graph: &MeshGraph,
    own: &[u32],
    block: &[f32],
    frames: usize,
) -> Result<(usize, Mat<f64>, f64, f64)> {
    let n3 = graph.vertex_count() * 3;
    let ext = graph.grow_rings(own, p.eta as usize);
    let (xe, _) = centred_block(p.centering, &ext, block, n3, frames);
    let scale = frame_diagonal(&block[..n3]);
    let negligible = (NEGLIGIBLE_AMPLITUDE * scale).powi(2) * (ext.len() * 3 * frames) as f64;
    let (vals, vecs) = sym_eig_desc(gram(xe.as_ref()).as_ref(), "segment PCA")?;
    let k = pcs_for_persistence(&vals, p.omega, negligible).min(frames);
    let total: f64 = vals.iter().map(|x| x.max(0.0)).sum();
    let trunc: f64 = vals[k.min(vals.len())..].iter().map(|x| x.max(0.0)).sum();
    Ok((k, vecs, trunc, total))
}

/// Writes one group's `mean + Σ_j A_j·B_j` into `out` (frames × 3V), in f64 rounded to f32:
/// `mean` per centering (vertex `[c][i]`, frame `[0][t]`, frame-axis `[c][t]`, none empty),
/// `a[j][c][i]` over the group's vertices `own` (ascending), `b[j][t]`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn reconstruct_group(
    centering: Centering,
    own: &[u32],
    mean: &[Vec<f64>],
    a: &[Vec<Vec<f64>>],
    b: &[Vec<f64>],
    frames: usize,
    n3: usize,
    out: &mut [f32],
) {
    let k = b.len();
    for t in 0..frames {
        for c in 0..3 {
            for (i, &vi) in own.iter().enumerate() {
                let mut x = match centering {
                    Centering::Vertex => mean[c][i],
                    Centering::Frame => mean[0][t],
                    Centering::FrameAxis => mean[c][t],
                    Centering::None => 0.0,
                };
                for j in 0..k {
                    x += a[j][c][i] * b[j][t];
                }
                out[t * n3 + vi as usize * 3 + c] = x as f32;
            }
        }
    }
}
