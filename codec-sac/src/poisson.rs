//! The least-squares Poisson reconstruction of vertex positions from per-triangle deformation
//! gradients (paper §3.6, Eq. 12; Sumner & Popović 2004, §4): the full system and the reduced,
//! once-factored system the decoder re-solves every frame.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{Argsort, Pair, SparseColMat, SymbolicSparseColMat};
use faer::{Conj, Mat, Par, Side};

use codec_core::{Error, Result};

use crate::geometry::{
    corners, cross, degenerate_area, inverse, mul, norm, reference_frames, sub, tet_frame, tet_frame_or_flat, M3, V3,
};
use crate::NAME;

const NONE: usize = usize::MAX;

/// The least-squares Poisson system of paper §3.6 / Eq. 12 (Sumner & Popović 2004, §4):
/// unknowns are the vertex coordinates and every triangle's fourth vertex, one vertex per
/// connected component is pinned. The energy is `Σⱼ areaⱼ ‖Sⱼ − J̃ⱼ‖²_F` (area weights, so
/// tiny triangles do not dominate; exact gradients are still reproduced exactly). The sparsity
/// pattern, its ordering and symbolic Cholesky factorization are computed once; every frame
/// only assembles values and runs the numeric factorization.
pub struct PoissonSystem {
    tris: Vec<[usize; 3]>,
    pins: Vec<usize>,
    /// Unknown index of each vertex, `NONE` when pinned.
    unknown: Vec<usize>,
    unknowns: usize,
    symbolic: SymbolicSparseColMat<usize>,
    argsort: Argsort<usize>,
    cholesky: SymbolicCholesky<usize>,
}

impl PoissonSystem {
    /// Builds the pattern and its symbolic factorization.
    pub fn new(n: usize, tris: &[[usize; 3]], pins: &[usize]) -> Result<Self> {
        let mut unknown = vec![0usize; n];
        for &p in pins {
            unknown[p] = NONE;
        }
        let mut next = 0;
        for u in unknown.iter_mut() {
            if *u != NONE {
                *u = next;
                next += 1;
            }
        }
        let unknowns = next + tris.len();
        let mut pairs = Vec::with_capacity(tris.len() * 10 + unknowns);
        for (j, t) in tris.iter().enumerate() {
            let loc = Self::local(&unknown, next, j, t);
            for p in 0..4 {
                for q in p..4 {
                    if loc[p] != NONE && loc[q] != NONE {
                        let (r, c) = (loc[p].min(loc[q]), loc[p].max(loc[q]));
                        pairs.push(Pair::new(r, c));
                    }
                }
            }
        }
        let (symbolic, argsort) =
            SymbolicSparseColMat::try_new_from_indices(unknowns, unknowns, &pairs).map_err(|e| Error::Numerical {
                context: NAME.into(),
                step: "poisson pattern".into(),
                detail: codec_core::error::debug_in_words(&e),
            })?;
        let cholesky =
            factorize_symbolic_cholesky(symbolic.as_ref(), Side::Upper, SymmetricOrdering::Amd, Default::default())
                .map_err(|e| Error::Numerical {
                    context: NAME.into(),
                    step: "poisson symbolic factorization".into(),
                    detail: codec_core::error::debug_in_words(&e),
                })?;
        Ok(Self { tris: tris.to_vec(), pins: pins.to_vec(), unknown, unknowns, symbolic, argsort, cholesky })
    }

    fn local(unknown: &[usize], first_fourth: usize, j: usize, t: &[usize; 3]) -> [usize; 4] {
        [unknown[t[0]], unknown[t[1]], unknown[t[2]], first_fourth + j]
    }

    /// Positions whose deformation gradients from `reference` best match `targets`, with every
    /// pinned vertex kept at its reference position.
    pub fn solve(&self, reference: &[V3], targets: &[M3]) -> Result<Vec<V3>> {
        let first_fourth = self.unknowns - self.tris.len();
        let frames = reference_frames(&self.tris, reference);
        let mut values = Vec::with_capacity(self.argsort_len_hint());
        let mut rhs = Mat::<f64>::zeros(self.unknowns, 3);
        for (j, t) in self.tris.iter().enumerate() {
            let loc = Self::local(&self.unknown, first_fourth, j, t);
            let mut k = [[0.0f64; 4]; 4];
            match frames[j] {
                Some((vi, area)) => {
                    // Row c of S = D V⁻¹ for coordinate r: Σ_p g_c[p] x_p[r] with these
                    // coefficients on (v0, v1, v2, fourth vertex).
                    for c in 0..3 {
                        let g = [-(vi[0][c] + vi[1][c] + vi[2][c]), vi[0][c], vi[1][c], vi[2][c]];
                        for p in 0..4 {
                            for q in 0..4 {
                                k[p][q] += area * g[p] * g[q];
                            }
                        }
                        for r in 0..3 {
                            let target = area * targets[j][r][c];
                            for p in 0..4 {
                                if loc[p] != NONE {
                                    rhs[(loc[p], r)] += g[p] * target;
                                }
                            }
                        }
                    }
                    // Pinned vertices move to the right-hand side.
                    for p in 0..3 {
                        if loc[p] == NONE {
                            let x = reference[t[p]];
                            for q in 0..4 {
                                if loc[q] != NONE {
                                    for r in 0..3 {
                                        rhs[(loc[q], r)] -= k[q][p] * x[r];
                                    }
                                }
                            }
                        }
                    }
                }
                None => {
                    // A degenerate reference triangle carries no information: it drops out of
                    // the energy, and its free fourth vertex is held at 0 so the system stays
                    // definite.
                    k[3][3] = 1.0;
                }
            }
            for p in 0..4 {
                for q in p..4 {
                    if loc[p] != NONE && loc[q] != NONE {
                        values.push(k[p][q]);
                    }
                }
            }
        }
        if values.iter().any(|v| !v.is_finite()) || (0..self.unknowns).any(|i| (0..3).any(|r| !rhs[(i, r)].is_finite()))
        {
            return Err(Error::Numerical {
                context: NAME.into(),
                step: "poisson assembly".into(),
                detail: "non-finite system (extreme coordinates or gradients)".into(),
            });
        }
        let a = SparseColMat::new_from_argsort(self.symbolic.clone(), &self.argsort, &values).map_err(|e| {
            Error::Numerical {
                context: NAME.into(),
                step: "poisson assembly".into(),
                detail: codec_core::error::debug_in_words(&e),
            }
        })?;
        let mut l_values = vec![0.0f64; self.cholesky.len_val()];
        let req = self
            .cholesky
            .factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default())
            .or(self.cholesky.solve_in_place_scratch::<f64>(3, Par::Seq));
        let mut buf = MemBuffer::new(req);
        self.cholesky
            .factorize_numeric_llt(
                &mut l_values,
                a.as_ref(),
                Side::Upper,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut buf),
                Default::default(),
            )
            .map_err(|e| Error::Numerical {
                context: NAME.into(),
                step: "poisson numeric factorization".into(),
                detail: format!(
                    "{} (a vertex is only in degenerate triangles?)",
                    codec_core::error::debug_in_words(&e)
                ),
            })?;
        let llt = LltRef::new(&self.cholesky, &l_values);
        llt.solve_in_place_with_conj(Conj::No, rhs.as_mut(), Par::Seq, MemStack::new(&mut buf));
        let mut out = reference.to_vec();
        for (v, o) in out.iter_mut().enumerate() {
            let u = self.unknown[v];
            if u != NONE {
                *o = [rhs[(u, 0)], rhs[(u, 1)], rhs[(u, 2)]];
            }
        }
        if out.iter().any(|p| !p.iter().all(|x| x.is_finite())) {
            return Err(Error::Numerical {
                context: NAME.into(),
                step: "poisson solve".into(),
                detail: "non-finite vertex positions".into(),
            });
        }
        Ok(out)
    }

    fn argsort_len_hint(&self) -> usize {
        self.tris.len() * 10
    }

    /// Bytes one [`PoissonSystem::solve`] allocates: the numeric Cholesky factor (the fill of
    /// the symbolic factorization), its scratch, the right-hand side and the assembled values.
    /// Known right after [`PoissonSystem::new`], before any numeric work, so a decoder can
    /// refuse a topology whose fill exceeds its [`codec_core::Limits`].
    pub fn solve_bytes(&self) -> u64 {
        let req = self
            .cholesky
            .factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default())
            .or(self.cholesky.solve_in_place_scratch::<f64>(3, Par::Seq));
        let words = self.cholesky.len_val() as u64 + 3 * self.unknowns as u64 + self.argsort_len_hint() as u64;
        words.saturating_mul(8).saturating_add(req.unaligned_bytes_required() as u64)
    }

    /// Operations of one [`PoissonSystem::solve`]: the numeric factorization
    /// ([`cholesky_work`]) and three triangular solve pairs.
    pub fn solve_work(&self) -> u64 {
        let fill = self.cholesky.len_val();
        cholesky_work(fill, self.unknowns).saturating_add(12 * fill as u64)
    }

    /// The pinned vertex of every component.
    pub fn pins(&self) -> &[usize] {
        &self.pins
    }
}

/// One triangle's part of a [`ReducedPoisson`] factor.
#[derive(Debug, Clone, Copy)]
struct Element {
    /// Reference area (the energy weight).
    area: f64,
    /// `g[c][p]`: coefficient of corner `p` (three vertices, then the fourth vertex) in
    /// column `c` of the gradient `S = X V⁻¹` (Sumner & Popović 2004, Eq. 2).
    g: [[f64; 4]; 3],
    /// Reference tetrahedron frame inverse `V⁻¹`.
    vi: M3,
    /// Elimination factors `k[p][3] / k[3][3]` of the triangle's private fourth vertex.
    e: [f64; 3],
    /// Reduced 3 × 3 element matrix `k' = k_vv − k_v3 k_3v / k_33`.
    reduced: [[f64; 3]; 3],
}

/// The Poisson system of paper Eq. 12 over the vertices only (stream version 3): each
/// triangle's fourth vertex is private to it and is eliminated exactly (Schur complement), so
/// the system has the mesh's vertex adjacency pattern (about a third of the unknowns of
/// [`PoissonSystem`] and far less fill). This holds the pattern and its symbolic
/// factorization; a [`PoissonFactor`] holds the numeric factor of one reference geometry.
///
/// Two references (parameter `poisson`):
/// - **rest** (default): the paper measures the gradient misfit against the previous
///   reconstruction `P`, `Σⱼ area_P ‖X V_P⁻¹ − J̃‖²`, whose matrix changes every frame.
///   Since `V_P = G V_R` (`G` the gradient of `P` from the rest pose `R`), the same misfit
///   is `(X V_R⁻¹ − J̃ G) G⁻¹`; dropping the `G⁻¹` weight gives `Σⱼ area_R ‖X V_R⁻¹ − J̃ G‖²`,
///   whose matrix depends only on the rest pose: factored once per basis. Exact gradients are
///   still reproduced exactly; inconsistent (truncated) ones are weighted differently.
/// - **previous** (the paper): the factor of the previous reconstruction, every frame.
pub struct ReducedPoisson {
    tris: Vec<[usize; 3]>,
    /// Unknown index of each vertex, `NONE` when pinned.
    unknown: Vec<usize>,
    unknowns: usize,
    symbolic: SymbolicSparseColMat<usize>,
    argsort: Argsort<usize>,
    /// Per triangle, the value slots `(p, q)` (corner pairs with `unknown[p] <= unknown[q]`,
    /// both free) in pattern order.
    slots: Vec<(usize, usize, usize)>,
    cholesky: SymbolicCholesky<usize>,
}

/// The numeric factor of a [`ReducedPoisson`] system for one reference geometry.
pub struct PoissonFactor {
    elements: Vec<Option<Element>>,
    l_values: Vec<f64>,
}

/// Reusable buffers of [`ReducedPoisson::solve`].
pub struct PoissonScratch {
    rhs: Mat<f64>,
    values: Vec<f64>,
    stack: MemBuffer,
}

impl ReducedPoisson {
    /// The pattern of the mesh with `pins` (one per connected component) held fixed.
    pub fn new(n: usize, tris: &[[usize; 3]], pins: &[usize]) -> Result<Self> {
        let err =
            |step: &'static str, detail: String| Error::Numerical { context: NAME.into(), step: step.into(), detail };
        let mut unknown = vec![0usize; n];
        for &p in pins {
            unknown[p] = NONE;
        }
        let mut next = 0;
        for u in unknown.iter_mut() {
            if *u != NONE {
                *u = next;
                next += 1;
            }
        }
        let unknowns = next;
        let mut pairs = Vec::with_capacity(tris.len() * 6 + unknowns);
        let mut slots = Vec::with_capacity(tris.len() * 6);
        for (j, t) in tris.iter().enumerate() {
            for p in 0..3 {
                for q in 0..3 {
                    let (a, b) = (unknown[t[p]], unknown[t[q]]);
                    if a != NONE && b != NONE && a <= b {
                        pairs.push(Pair::new(a, b));
                        slots.push((j, p, q));
                    }
                }
            }
        }
        // Every free vertex gets a diagonal entry (a vertex only in degenerate triangles then
        // fails the numeric factorization with a clear message instead of the symbolic one).
        for u in 0..unknowns {
            pairs.push(Pair::new(u, u));
        }
        let (symbolic, argsort) = SymbolicSparseColMat::try_new_from_indices(unknowns, unknowns, &pairs)
            .map_err(|e| err("poisson pattern", codec_core::error::debug_in_words(&e)))?;
        // Supernodal: measured faster than faer's automatic (simplicial) choice on these meshes.
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
            ..Default::default()
        };
        let cholesky = factorize_symbolic_cholesky(symbolic.as_ref(), Side::Upper, SymmetricOrdering::Amd, params)
            .map_err(|e| err("poisson symbolic factorization", codec_core::error::debug_in_words(&e)))?;
        Ok(Self { tris: tris.to_vec(), unknown, unknowns, symbolic, argsort, slots, cholesky })
    }

    fn scratch_req(&self) -> StackReq {
        self.cholesky
            .factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default())
            .or(self.cholesky.solve_in_place_scratch::<f64>(3, Par::Seq))
    }

    /// Bytes of one [`PoissonFactor`] (the fill of the symbolic factorization plus the
    /// per-triangle elements) and one [`PoissonScratch`]. Known right after
    /// [`ReducedPoisson::new`], before any numeric work, so a decoder can refuse a topology
    /// whose fill exceeds its [`codec_core::Limits`] instead of attempting the allocation.
    pub fn factor_and_scratch_bytes(&self) -> u64 {
        let factor = (self.cholesky.len_val() as u64).saturating_mul(8)
            + self.tris.len() as u64 * std::mem::size_of::<Option<Element>>() as u64;
        let scratch = (3 * self.unknowns as u64 + (self.slots.len() + self.unknowns) as u64) * 8;
        factor.saturating_add(scratch).saturating_add(self.scratch_req().unaligned_bytes_required() as u64)
    }

    /// Operations of one [`ReducedPoisson::factor`] and one [`ReducedPoisson::solve`]: the
    /// numeric factorization ([`cholesky_work`]) and three triangular solve
    /// pairs.
    pub fn factor_and_solve_work(&self) -> u64 {
        let fill = self.cholesky.len_val();
        cholesky_work(fill, self.unknowns).saturating_add(12 * fill as u64)
    }

    /// Scratch for [`ReducedPoisson::factor`] and [`ReducedPoisson::solve`] (allocate once).
    pub fn scratch(&self) -> PoissonScratch {
        let req = self.scratch_req();
        PoissonScratch {
            rhs: Mat::zeros(self.unknowns, 3),
            values: Vec::with_capacity(self.slots.len() + self.unknowns),
            stack: MemBuffer::new(req),
        }
    }

    /// The numeric factor of the system whose reference geometry is `reference`, reusing
    /// `into`'s storage when given.
    pub fn factor(
        &self,
        reference: &[V3],
        scratch: &mut PoissonScratch,
        into: Option<PoissonFactor>,
    ) -> Result<PoissonFactor> {
        let err =
            |step: &'static str, detail: String| Error::Numerical { context: NAME.into(), step: step.into(), detail };
        let mut f = into.unwrap_or(PoissonFactor { elements: Vec::new(), l_values: Vec::new() });
        f.elements.clear();
        let tiny = degenerate_area(reference);
        for &t in &self.tris {
            let p = corners(reference, t);
            let area = 0.5 * norm(cross(sub(p[1], p[0]), sub(p[2], p[0])));
            let frame = if area.is_nan() || area <= tiny { None } else { tet_frame(p).and_then(|v| inverse(&v)) };
            let Some(vi) = frame else {
                f.elements.push(None);
                continue;
            };
            let g: [[f64; 4]; 3] =
                std::array::from_fn(|c| [-(vi[0][c] + vi[1][c] + vi[2][c]), vi[0][c], vi[1][c], vi[2][c]]);
            let mut k = [[0.0f64; 4]; 4];
            for gc in &g {
                for p in 0..4 {
                    for q in 0..4 {
                        k[p][q] += area * gc[p] * gc[q];
                    }
                }
            }
            let e: [f64; 3] = std::array::from_fn(|p| k[p][3] / k[3][3]);
            let reduced = std::array::from_fn(|p| std::array::from_fn(|q| k[p][q] - e[p] * k[3][q]));
            f.elements.push(Some(Element { area, g, vi, e, reduced }));
        }
        let values = &mut scratch.values;
        values.clear();
        for &(j, p, q) in &self.slots {
            values.push(f.elements[j].map_or(0.0, |el| el.reduced[p][q]));
        }
        values.extend(std::iter::repeat_n(0.0, self.unknowns));
        if values.iter().any(|v| !v.is_finite()) {
            return Err(err("poisson assembly", "non-finite system (extreme coordinates)".into()));
        }
        let a = SparseColMat::new_from_argsort(self.symbolic.clone(), &self.argsort, values)
            .map_err(|e| err("poisson assembly", codec_core::error::debug_in_words(&e)))?;
        f.l_values.resize(self.cholesky.len_val(), 0.0);
        self.cholesky
            .factorize_numeric_llt(
                &mut f.l_values,
                a.as_ref(),
                Side::Upper,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut scratch.stack),
                Default::default(),
            )
            .map_err(|e| {
                err(
                    "poisson numeric factorization",
                    format!("{} (a vertex only in degenerate triangles?)", codec_core::error::debug_in_words(&e)),
                )
            })?;
        Ok(f)
    }

    /// Positions whose gradients from the factor's reference `R` best match `J̃ⱼ Gⱼ`
    /// (`Gⱼ` the gradient of `previous` from `R`; the identity, not computed, when
    /// `previous_is_reference`), area-weighted with `R`'s areas; pinned vertices stay at
    /// their `previous` positions. Writes `out` (`previous.len()` entries).
    pub fn solve(
        &self,
        factor: &PoissonFactor,
        previous: &[V3],
        previous_is_reference: bool,
        targets: &[M3],
        scratch: &mut PoissonScratch,
        out: &mut Vec<V3>,
    ) -> Result<()> {
        let rhs = &mut scratch.rhs;
        rhs.fill(0.0);
        for (j, t) in self.tris.iter().enumerate() {
            let Some(el) = &factor.elements[j] else { continue };
            let target = if previous_is_reference {
                targets[j]
            } else {
                // G = V_P V_R⁻¹ (fourth vertex of P as in `tet_frame`, zero if P is degenerate).
                mul(&targets[j], &mul(&tet_frame_or_flat(corners(previous, *t)), &el.vi))
            };
            // Element right-hand side r[p][axis] = Σ_c g[c][p] area T[axis][c], then the
            // fourth vertex eliminated: r'[p] = r[p] − e[p] r[3].
            let mut r = [[0.0f64; 3]; 4];
            for (c, gc) in el.g.iter().enumerate() {
                for axis in 0..3 {
                    let w = el.area * target[axis][c];
                    for (rp, &g) in r.iter_mut().zip(gc) {
                        rp[axis] += g * w;
                    }
                }
            }
            for pp in 0..3 {
                let u = self.unknown[t[pp]];
                if u == NONE {
                    continue;
                }
                for axis in 0..3 {
                    let mut v = r[pp][axis] - el.e[pp] * r[3][axis];
                    // Pinned corners move to the right-hand side.
                    for q in 0..3 {
                        if self.unknown[t[q]] == NONE {
                            v -= el.reduced[pp][q] * previous[t[q]][axis];
                        }
                    }
                    rhs[(u, axis)] += v;
                }
            }
        }
        LltRef::new(&self.cholesky, &factor.l_values).solve_in_place_with_conj(
            Conj::No,
            rhs.as_mut(),
            Par::Seq,
            MemStack::new(&mut scratch.stack),
        );
        out.clear();
        out.extend_from_slice(previous);
        for (v, o) in out.iter_mut().enumerate() {
            let u = self.unknown[v];
            if u != NONE {
                *o = [rhs[(u, 0)], rhs[(u, 1)], rhs[(u, 2)]];
            }
        }
        if out.iter().any(|p| !p.iter().all(|x| x.is_finite())) {
            return Err(Error::Numerical {
                context: NAME.into(),
                step: "poisson solve".into(),
                detail: "non-finite vertex positions".into(),
            });
        }
        Ok(())
    }
}

/// Operations of a sparse Cholesky factorization whose factor has `fill` entries in `n`
/// columns: `Σ_j c_j²` over the column counts `c_j`, bounded below by `fill² / n`
/// (Cauchy–Schwarz), which is what is returned — an expander-like crafted connectivity, whose
/// factor is nearly dense, gives about n³/4. It lives with the Poisson systems here because the
/// harmonics (`harmonics.rs`, built on this module) factor sparse systems too.
pub fn cholesky_work(fill: usize, n: usize) -> u64 {
    let fill = fill as u64;
    fill.saturating_mul(fill) / (n as u64).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::tests::{blob, rot};
    use crate::geometry::{components, deformation_gradients, exp_rotation, log_rotation, Svd3};

    #[test]
    fn gradients_to_positions_round_trip_to_machine_precision() {
        let (a, tris) = blob(3);
        let n = a.len();
        // A non-rigid, non-affine target: twist + bulge + translation.
        let b: Vec<V3> = a
            .iter()
            .map(|p| {
                let ang = 0.6 * p[2];
                let (s, c) = ang.sin_cos();
                let g = 1.0 + 0.2 * p[0] * p[0];
                [g * (c * p[0] - s * p[1]) + 3.0, g * (s * p[0] + c * p[1]) - 1.0, p[2] * 1.1 + 0.5]
            })
            .collect();
        let j = deformation_gradients(&tris, &a, &b);
        let (_, pins) = components(n, &tris);
        let sys = PoissonSystem::new(n, &tris, &pins).unwrap();
        let x = sys.solve(&a, &j).unwrap();
        // The solution is b up to the translation fixed by the pinned vertex.
        let shift = sub(b[pins[0]], a[pins[0]]);
        let err = x
            .iter()
            .zip(&b)
            .map(|(x, b)| (0..3).map(|k| (x[k] + shift[k] - b[k]).abs()).fold(0.0, f64::max))
            .fold(0.0, f64::max);
        assert!(err < 1e-10 * n as f64, "round-trip error {err}");
        // Through polar decomposition and log/exp as the codec does it.
        let mut svd = Svd3::new();
        let j2: Vec<M3> = j
            .iter()
            .map(|j| {
                let (u, p) = svd.polar(j).unwrap();
                mul(&exp_rotation(log_rotation(&u)), &p)
            })
            .collect();
        let x2 = sys.solve(&a, &j2).unwrap();
        let err2 = x2.iter().zip(&x).map(|(p, q)| norm(sub(*p, *q))).fold(0.0, f64::max);
        assert!(err2 < 1e-10 * n as f64, "polar/log/exp round-trip error {err2}");
    }

    #[test]
    fn disconnected_meshes_pin_one_vertex_per_component() {
        let tris = vec![[0, 1, 2], [3, 4, 5]];
        let (comp, pins) = components(7, &tris);
        assert_eq!(comp, vec![0, 0, 0, 1, 1, 1, 2]);
        assert_eq!(pins, vec![0, 3, 6]);
        let a: Vec<V3> =
            vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [5., 0., 0.], [6., 0., 0.], [5., 1., 1.], [9., 9., 9.]];
        let r = rot([0.0, 0.3, 1.0], 0.4);
        let b: Vec<V3> = a
            .iter()
            .map(|p| {
                (0..3).fold([0.0; 3], |mut o, i| {
                    for k in 0..3 {
                        o[i] += r[i][k] * p[k];
                    }
                    o
                })
            })
            .collect();
        let sys = PoissonSystem::new(7, &tris, &pins).unwrap();
        let x = sys.solve(&a, &deformation_gradients(&tris, &a, &b)).unwrap();
        for c in [[0usize, 1, 2], [3, 4, 5]] {
            let s = sub(b[c[0]], x[c[0]]);
            for &v in &c {
                assert!(norm(sub(sub(b[v], x[v]), s)) < 1e-12);
            }
        }
        assert_eq!(x[6], a[6]);
    }
}
