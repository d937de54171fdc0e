//! What both codings of a cluster's payload share: the block's data matrix (its domain and
//! dimensions), the payload's header (domain byte, per-frame means) and the work a cluster's
//! decoding is charged before it starts.

use codec_core::bytes::ByteReader;
use codec_core::toolkit::order::CausalGraph;
use codec_core::{Limits, Result};
use faer::Mat;

use crate::coding::Layout;
use crate::NAME;

/// A cluster's [`Domain`](crate::Domain) as coded: `auto` resolved to the smaller matrix.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Resolved {
    /// `e = 3d` rows (frame coordinates), `m = n` columns (vertices).
    Temporal,
    /// `e = n` rows (vertices), `m = 3d` columns (frame coordinates).
    Spatial,
}

/// The two layouts of a block: (dictionary columns, feature rows).
pub(crate) fn layouts<'g>(domain: Resolved, mesh: &'g CausalGraph, time: &'g CausalGraph) -> (Layout<'g>, Layout<'g>) {
    match domain {
        Resolved::Temporal => (Layout::Time(time), Layout::Mesh(mesh)),
        Resolved::Spatial => (Layout::Mesh(mesh), Layout::Time(time)),
    }
}

/// The two dimensions of the data matrix of a cluster of `n` vertices over `d` frames in
/// `domain`; the rank `k` is at most the smaller.
pub(crate) fn matrix_dims(domain: Resolved, n: usize, d: usize) -> (usize, usize) {
    match domain {
        Resolved::Temporal => (3 * d, n),
        Resolved::Spatial => (n, 3 * d),
    }
}

/// The domain byte of a cluster payload.
pub(crate) fn read_domain(r: &mut ByteReader<'_>) -> Result<Resolved> {
    match r.u8("cluster.domain")? {
        0 => Ok(Resolved::Temporal),
        1 => Ok(Resolved::Spatial),
        x => Err(r.malformed("cluster.domain", format!("{x} is neither 0 (temporal) nor 1 (spatial)"))),
    }
}

/// The `3d` per-frame means of a cluster payload.
pub(crate) fn read_means(r: &mut ByteReader<'_>, d: usize) -> Result<Vec<f64>> {
    let means_bytes = r.take(3 * d * 4, "cluster.means")?;
    let mut means = Vec::with_capacity(3 * d);
    for b in means_bytes.chunks_exact(4) {
        let m = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        if !m.is_finite() {
            return Err(r.malformed("cluster.means", format!("{m} is not finite")));
        }
        means.push(m as f64);
    }
    Ok(means)
}

/// Charges one cluster's work to `limits` (`--max-work`) before it is done: its
/// `(e + m)·k` coded values (`per_value` each), the product `Ê F̂` (`3d·n·k` multiply-adds)
/// and its `3d·n` output coordinates.
pub(crate) fn spend_cluster(
    limits: &mut Limits,
    values: u64,
    per_value: u64,
    d: usize,
    n: usize,
    k: usize,
) -> Result<()> {
    use codec_core::limits::WORK_PER_COORDINATE;
    let coords = Limits::product(&[3, d as u64, n as u64]);
    let work = values
        .saturating_mul(per_value)
        .saturating_add(coords.saturating_mul(k as u64))
        .saturating_add(coords.saturating_mul(WORK_PER_COORDINATE));
    *limits = limits.spend(NAME, "cluster reconstruction", work)?;
    Ok(())
}

/// Vertices of a cluster whose reconstruction the decoder forms at once: `3d × 4096` f64 is at
/// most 384 MiB at the longest block (4096 frames), 3.75 MiB at the default 40. Clusters up to
/// this size are reconstructed in one product.
pub(crate) const RECONSTRUCT_VERTICES: usize = 4096;

/// Checks the decoded dictionary (`e × k`), features (`k × m`) and one chunk of the
/// reconstruction (`3d × min(n, RECONSTRUCT_VERTICES)`), all f64, against `limits`.
pub(crate) fn check_matrices(limits: &Limits, e_dim: usize, m_dim: usize, k: usize, d: usize, n: usize) -> Result<()> {
    limits.check_alloc(
        NAME,
        "cluster.matrices",
        ((e_dim * k + k * m_dim + 3 * d * n.min(RECONSTRUCT_VERTICES)) * 8) as u64,
    )
}

/// One decoded cluster: its domain, the `3d` per-frame means, the dictionary `Ê` and the
/// features `F̂`.
pub(crate) struct DecodedCluster {
    pub domain: Resolved,
    pub means: Vec<f64>,
    pub e_hat: Mat<f64>,
    pub f_hat: Mat<f64>,
}
