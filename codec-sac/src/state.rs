//! What encoder and decoder share: the stream config ([`Settings`]), the connectivity's state
//! ([`Shared`]: components and the Poisson system of the stream version), the basis state of
//! a rest pose ([`BasisState`], one [`Bases`] variant per stream version), the keyframe
//! interval ([`Gop`]), and the reconstruction of a P-frame from its codes, which the encoder
//! runs through the decoder's own code path (closed loop, paper §3.1, §3.7 e–f).

use std::sync::Arc;

use codec_core::bytes::ByteWriter;
use codec_core::{Error, Limits, Result, Topology};
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, Par};

use crate::coding::{self, Contexts};
use crate::geometry::{self, M3, V3};
use crate::harmonics::{self, Transfer};
use crate::poisson::{PoissonFactor, PoissonScratch, PoissonSystem, ReducedPoisson};
use crate::NAME;

/// What the decoder must know (stored in the stream config).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Settings {
    pub(crate) bits: u8,
    pub(crate) bases: u32,
    pub(crate) polar: bool,
    pub(crate) iframe_bits: u8,
    /// Stream version: selects how the basis is computed (not stored in the config; the
    /// container header carries it).
    pub(crate) version: u16,
    /// Version 3 config: the basis is recomputed at every keyframe (versions 1–2: always).
    pub(crate) basis_per_keyframe: bool,
    /// Version 3 config: Poisson factorization every `refactor` P-frames, 0 = the rest pose's
    /// factor only (versions 1–2: every frame, with the fourth vertices as unknowns).
    pub(crate) refactor: u8,
}

impl Settings {
    pub(crate) fn config(&self) -> Vec<u8> {
        let mut w = ByteWriter::new();
        w.u8(self.bits);
        w.u32(self.bases);
        w.u8(self.polar as u8);
        w.u8(self.iframe_bits);
        if self.version >= 3 {
            w.u8(self.basis_per_keyframe as u8);
            w.u8(self.refactor);
        }
        w.into_vec()
    }
    /// Channels per group: rotation (3) and stretch (6), or the nine entries of `J − I`.
    pub(crate) fn groups(&self) -> &'static [usize] {
        if self.polar {
            &[3, 6]
        } else {
            &[9]
        }
    }
}

pub(crate) const KIND_I: u8 = 0;
pub(crate) const KIND_P: u8 = 1;
pub(crate) const KIND_REFRESH: u8 = 2;

/// The Poisson system (paper §3.6, Eq. 12) of the stream version.
pub(crate) enum Poisson {
    /// Stream versions 1–2: every triangle's fourth vertex is an unknown; the reference is the
    /// previous reconstruction, factored numerically every frame.
    Full(PoissonSystem),
    /// Stream version 3: the vertex-only system (fourth vertices eliminated), factored at the
    /// previous reconstruction every `refactor` P-frames or once at the rest pose.
    Reduced(ReducedPoisson),
}

/// State that depends only on the connectivity, shared by encoder and decoder.
pub(crate) struct Shared {
    pub(crate) settings: Settings,
    pub(crate) n: usize,
    /// Triangles with three distinct vertices (a repeated index has no area and is ignored).
    pub(crate) tris: Vec<[usize; 3]>,
    pub(crate) component: Vec<usize>,
    pub(crate) component_sizes: Vec<usize>,
    /// `None` for a mesh without triangles (no P-frame can be coded).
    poisson: Option<Poisson>,
    /// Bounds on the basis computation's allocations (the decoder's; none on the encoder).
    pub(crate) limits: Limits,
}

/// The vertex basis `H` (`n × l`) of versions 2–3: the residual layer's spectral part and, in
/// version 3, the synthesis.
pub(crate) struct VertexBasis {
    pub(crate) h: Mat<f64>,
    /// Encoder only: the rest pose's lumped mass, for the projection `Hᵀ M r`.
    pub(crate) mass: Option<Vec<f64>>,
}

/// The manifold harmonic basis of one rest pose in the form its stream version uses: one
/// variant per version, so no field is present in one version and absent in another.
pub(crate) enum Bases {
    /// Version 1: the harmonics of the whole mesh at once; the per-triangle synthesis `C H`.
    V1 { transfer: Transfer },
    /// Version 2: harmonics per connected component; `C H` synthesizes, `H` carries the
    /// residual layer's spectral part.
    V2 { transfer: Transfer, basis: VertexBasis },
    /// Version 3: `H` synthesizes and carries the spectral part; with `refactor = 0` the
    /// Poisson factor of the rest pose, reused by every P-frame.
    V3 { basis: VertexBasis, rest_factor: Option<PoissonFactor> },
}

/// Everything derived from the rest pose (the decoded frame the basis is computed from).
/// With `basis = stream` one of these serves every keyframe of the stream.
pub(crate) struct BasisState {
    /// The rest pose's position block (quantizers + zstd codes) as stored in the stream; a
    /// keyframe naming the same bytes reuses this state.
    pub(crate) rest_block: Vec<u8>,
    /// `None`: no basis (the keyframe's `has_bases` flag is clear: only refresh frames follow).
    bases: Option<Bases>,
    /// Encoder only: the analysis operator (least-squares spectral descriptors, §3.4).
    pub(crate) analysis: Option<Mat<f64>>,
}

impl BasisState {
    /// Whether P-frames can be coded (the keyframe's `has_bases` flag).
    pub(crate) fn has_bases(&self) -> bool {
        self.bases.is_some()
    }
    /// Number of basis vectors `l` (0 without a basis).
    pub(crate) fn bases(&self) -> usize {
        match &self.bases {
            Some(Bases::V1 { transfer }) => transfer.bases(),
            Some(Bases::V2 { basis, .. } | Bases::V3 { basis, .. }) => basis.h.ncols(),
            None => 0,
        }
    }
    /// The vertex basis of versions 2–3 (`None` in version 1 or without a basis).
    pub(crate) fn vertex_basis(&self) -> Option<&VertexBasis> {
        match &self.bases {
            Some(Bases::V2 { basis, .. } | Bases::V3 { basis, .. }) => Some(basis),
            _ => None,
        }
    }
}

/// State of the current keyframe interval.
pub(crate) struct Gop {
    pub(crate) state: Arc<BasisState>,
    pub(crate) contexts: Contexts,
    pub(crate) prev: Vec<V3>,
    /// P-frames decoded (accepted, on the encoder) in this interval: the Poisson schedule.
    pub(crate) p_count: u32,
    /// Reused per-frame buffers (version 3).
    pub(crate) work: Work,
}

/// Per-frame buffers, allocated once per interval.
pub(crate) struct Work {
    /// Version 3: the reduced system's scratch.
    poisson: Option<PoissonScratch>,
    /// Version 3, `refactor ≥ 1`: the factor of the last scheduled reference (storage reused).
    previous_factor: Option<PoissonFactor>,
    coeffs: Mat<f64>,
    vertex_fields: Mat<f64>,
    targets: Vec<M3>,
    pub(crate) solved: Vec<V3>,
}

pub(crate) fn to_v3(frame: &[f32]) -> Vec<V3> {
    frame.chunks_exact(3).map(|p| [p[0] as f64, p[1] as f64, p[2] as f64]).collect()
}

pub(crate) fn set_v3(out: &mut [V3], frame: &[f32]) {
    for (o, p) in out.iter_mut().zip(frame.chunks_exact(3)) {
        *o = [p[0] as f64, p[1] as f64, p[2] as f64];
    }
}

impl Shared {
    /// The connectivity's state. The Poisson system's symbolic factorization fixes the size of
    /// its numeric factor; a topology whose factor (plus scratch) exceeds `limits` is refused
    /// here, before any numeric factorization allocates it.
    pub(crate) fn new(topology: &Topology, limits: &Limits, settings: Settings) -> Result<Self> {
        let n = topology.vertex_count();
        let tris: Vec<[usize; 3]> = topology
            .triangles()
            .iter()
            .map(|t| [t[0] as usize, t[1] as usize, t[2] as usize])
            .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
            .collect();
        let (component, pins) = geometry::components(n, &tris);
        let mut component_sizes = vec![0usize; pins.len()];
        for &c in &component {
            component_sizes[c] += 1;
        }
        let poisson = match (tris.is_empty(), settings.version >= 3) {
            (true, _) => None,
            (false, false) => Some(Poisson::Full(PoissonSystem::new(n, &tris, &pins)?)),
            (false, true) => Some(Poisson::Reduced(ReducedPoisson::new(n, &tris, &pins)?)),
        };
        // The factor is held from the first P-frame on; every P-frame factors and solves.
        const WHAT: &str = "poisson factor (sparse Cholesky fill of the topology)";
        const WORK: &str = "poisson factorization per frame (sparse Cholesky of the topology)";
        let mut limits = *limits;
        match &poisson {
            Some(Poisson::Full(p)) => {
                limits = limits.reserve(NAME, WHAT, p.solve_bytes())?;
                limits.check_work(NAME, WORK, p.solve_work())?;
            }
            Some(Poisson::Reduced(r)) => {
                limits = limits.reserve(NAME, WHAT, r.factor_and_scratch_bytes())?;
                limits.check_work(NAME, WORK, r.factor_and_solve_work())?;
            }
            None => {}
        }
        Ok(Self { settings, n, tris, component, component_sizes, poisson, limits })
    }

    pub(crate) fn components(&self) -> usize {
        self.component_sizes.len()
    }

    /// Operations one P-frame with `bases` vectors takes to reconstruct: the synthesis of every
    /// channel from the basis and the Poisson factorization and solve (`Limits::max_work`).
    pub(crate) fn frame_work(&self, bases: usize) -> u64 {
        let channels = self.settings.groups().iter().sum::<usize>() as u64;
        let synthesis = (self.n as u64).saturating_mul(bases as u64).saturating_mul(channels);
        let poisson = match &self.poisson {
            Some(Poisson::Full(p)) => p.solve_work(),
            Some(Poisson::Reduced(r)) => r.factor_and_solve_work(),
            None => 0,
        };
        synthesis.saturating_add(poisson)
    }

    /// The number of basis vectors `l` the basis of the rest pose `rest` has (what
    /// [`Shared::basis_state`] computes, found without computing it: a P-frame's descriptors
    /// are checked against it before the basis is paid for).
    /// Versions 2–3 solve per connected component: every component with triangles and an
    /// area that is not zero gives `min(bases, its vertices)` vectors, the `bases` smallest of
    /// all are kept (`harmonics::harmonics_by_component_within`); version 1 and a connected
    /// mesh give `min(bases, n)`.
    pub(crate) fn expected_bases(&self, rest: &[f32]) -> usize {
        let bases = self.settings.bases as usize;
        if self.tris.is_empty() {
            return 0;
        }
        if self.settings.version < 2 || self.component_sizes.len() <= 1 {
            return bases.min(self.n);
        }
        let rest = to_v3(rest);
        let components = self.component_sizes.len();
        let mut area = vec![0.0f64; components];
        let mut has_triangles = vec![false; components];
        for t in &self.tris {
            let c = self.component[t[0]];
            has_triangles[c] = true;
            // The same sum, in the same order, as the by-component solver's area.
            let [a, b, d] = [rest[t[0]], rest[t[1]], rest[t[2]]];
            area[c] += 0.5 * geometry::norm(geometry::cross(geometry::sub(b, a), geometry::sub(d, a)));
        }
        let total: usize = (0..components)
            .filter(|&c| has_triangles[c] && !(area[c].is_finite() && area[c] <= 0.0))
            .map(|c| bases.min(self.component_sizes[c]))
            .sum();
        total.min(bases)
    }

    /// Operations a new basis state takes (`Limits::max_work`).
    pub(crate) fn basis_work(&self) -> u64 {
        harmonics::work_estimate(self.n, self.settings.bases as usize)
    }

    /// The basis state of the rest pose `rest` (decoded positions) whose stored block is
    /// `rest_block`. `with_basis` is read from the stream by the decoder; the encoder tries to
    /// compute the basis and reports whether it could (the state then has no basis).
    pub(crate) fn basis_state(
        &self,
        rest: &[f32],
        rest_block: Vec<u8>,
        with_basis: Option<bool>,
        encoder: bool,
    ) -> Result<BasisState> {
        let mut state = BasisState { rest_block, bases: None, analysis: None };
        let want = with_basis.unwrap_or(true) && !self.tris.is_empty();
        if !want {
            return Ok(state);
        }
        let rest = to_v3(rest);
        let v = self.settings.version;
        let bases = self.settings.bases as usize;
        let result = (|| -> Result<(Bases, Option<Mat<f64>>)> {
            // Version 2 on: per connected component; version 1: the whole mesh.
            let h = if v >= 2 {
                harmonics::harmonics_by_component_within(&rest, &self.tris, bases, &self.limits)?
            } else {
                harmonics::harmonics_within(&rest, &self.tris, bases, &self.limits)?
            };
            let mut analysis = None;
            let mut transfer = None;
            if encoder || v < 3 {
                let t = Transfer::new(&h, &self.tris);
                if encoder {
                    analysis = Some(t.analysis(&geometry::triangle_areas(&rest, &self.tris))?);
                }
                // Version 3 synthesizes from `H` directly; `C H` is only kept for versions 1–2.
                if v < 3 {
                    transfer = Some(t);
                }
            }
            // The encoder's projection of the residual layer (versions 2–3) needs the mass.
            let mass = (encoder && v >= 2).then(|| harmonics::laplacian(&rest, &self.tris).1);
            let bases = match (v, transfer) {
                (1, Some(transfer)) => Bases::V1 { transfer },
                (2, Some(transfer)) => Bases::V2 { transfer, basis: VertexBasis { h: h.basis, mass } },
                _ => {
                    let rest_factor = match (&self.poisson, self.settings.refactor) {
                        (Some(Poisson::Reduced(rp)), 0) => Some(rp.factor(&rest, &mut rp.scratch(), None)?),
                        _ => None,
                    };
                    Bases::V3 { basis: VertexBasis { h: h.basis, mass }, rest_factor }
                }
            };
            Ok((bases, analysis))
        })();
        match result {
            Ok((bases, analysis)) => {
                state.bases = Some(bases);
                state.analysis = analysis;
            }
            // The encoder falls back to refresh frames and says so in the stream; the decoder
            // was told a basis exists, so failing here is an error.
            Err(e) if !encoder => return Err(e),
            Err(_) => {}
        }
        Ok(state)
    }

    /// Starts a keyframe interval at the decoded I-frame `frame` with the basis `state`.
    pub(crate) fn start_gop(&self, frame: &[f32], state: Arc<BasisState>) -> Gop {
        let contexts = Contexts::new(self.settings.groups().len(), self.settings.bits);
        let work = Work {
            poisson: match &self.poisson {
                Some(Poisson::Reduced(rp)) => Some(rp.scratch()),
                _ => None,
            },
            previous_factor: None,
            coeffs: Mat::zeros(0, 0),
            vertex_fields: Mat::zeros(0, 0),
            targets: Vec::with_capacity(self.tris.len()),
            solved: Vec::with_capacity(self.n),
        };
        Gop { state, contexts, prev: to_v3(frame), p_count: 0, work }
    }

    /// Decoded gradients from the group codes and amplitudes (paper Eq. 10–11, `J̃ = Ũ P̃`),
    /// then the Poisson solve (Eq. 12). Leaves the positions before the component
    /// translations in `gop.work.solved`.
    pub(crate) fn reconstruct(&self, gop: &mut Gop, codes: &[Vec<i64>], amps: &[f32]) -> Result<()> {
        let state = &*gop.state;
        let m = self.tris.len();
        let l = state.bases();
        if l == 0 || m == 0 {
            return Err(Error::malformed(NAME, "packet", "P-frame without bases"));
        }
        let work = &mut gop.work;
        let channels = self.settings.groups().iter().sum::<usize>();
        match &state.bases {
            Some(Bases::V3 { basis, .. }) => {
                // Synthesis through the vertex basis: (C H c)_j is the mean of `H c` over the
                // triangle's corners, so `H` (n × l) times the coefficients (l × channels) costs
                // half of `C H` (m × l, m ≈ 2n) and is one matrix product.
                if work.coeffs.shape() != (l, channels) {
                    work.coeffs = Mat::zeros(l, channels);
                    work.vertex_fields = Mat::zeros(self.n, channels);
                }
                let mut ch = 0;
                for (g, group) in codes.iter().enumerate() {
                    let step = coding::step(amps[g], self.settings.bits);
                    for chan in group.chunks_exact(l) {
                        for (k, &q) in chan.iter().enumerate() {
                            work.coeffs[(k, ch)] = q as f64 * step;
                        }
                        ch += 1;
                    }
                }
                matmul(
                    work.vertex_fields.as_mut(),
                    Accum::Replace,
                    basis.h.as_ref(),
                    work.coeffs.as_ref(),
                    1.0,
                    Par::Seq,
                );
                let vf = &work.vertex_fields;
                work.targets.clear();
                for t in &self.tris {
                    let f = |c: usize| (vf[(t[0], c)] + vf[(t[1], c)] + vf[(t[2], c)]) / 3.0;
                    work.targets.push(self.target_gradient(f));
                }
            }
            Some(Bases::V1 { transfer } | Bases::V2 { transfer, .. }) => {
                let mut fields: Vec<Vec<f64>> = Vec::with_capacity(9);
                for (g, group) in codes.iter().enumerate() {
                    let step = coding::step(amps[g], self.settings.bits);
                    for chan in group.chunks_exact(l) {
                        let c: Vec<f64> = chan.iter().map(|&q| q as f64 * step).collect();
                        let mut f = vec![0.0; m];
                        transfer.synthesize(&c, &mut f);
                        fields.push(f);
                    }
                }
                work.targets.clear();
                work.targets.extend((0..m).map(|j| self.target_gradient(|ch| fields[ch][j])));
            }
            None => return Err(Error::malformed(NAME, "packet", "P-frame without bases")),
        }
        let missing = || Error::malformed(NAME, "packet", "P-frame without a Poisson system");
        match &self.poisson {
            Some(Poisson::Reduced(rp)) => {
                let scratch = work.poisson.get_or_insert_with(|| rp.scratch());
                let every = self.settings.refactor as u32;
                if every == 0 {
                    let factor = match &state.bases {
                        Some(Bases::V3 { rest_factor: Some(f), .. }) => f,
                        _ => return Err(missing()),
                    };
                    rp.solve(factor, &gop.prev, false, &work.targets, scratch, &mut work.solved)
                } else {
                    // The schedule depends only on the P-frames both sides have accepted, so
                    // an encoder attempt that ends in a refresh frame changes nothing.
                    // (A failed factorization leaves none, and the next attempt is fresh again.)
                    let fresh = gop.p_count.is_multiple_of(every) || work.previous_factor.is_none();
                    if fresh {
                        work.previous_factor = Some(rp.factor(&gop.prev, scratch, work.previous_factor.take())?);
                    }
                    let factor = work.previous_factor.as_ref().ok_or_else(missing)?;
                    rp.solve(factor, &gop.prev, fresh, &work.targets, scratch, &mut work.solved)
                }
            }
            Some(Poisson::Full(p)) => {
                work.solved = p.solve(&gop.prev, &work.targets)?;
                Ok(())
            }
            None => Err(missing()),
        }
    }

    /// `J̃ = exp(ω) (I + S)` from the nine channel values `f(0..9)` (polar), or `I + f`.
    fn target_gradient(&self, f: impl Fn(usize) -> f64) -> M3 {
        if self.settings.polar {
            let u = geometry::exp_rotation([f(0), f(1), f(2)]);
            let (a, b, c, d, e, ff) = (1.0 + f(3), 1.0 + f(4), 1.0 + f(5), f(6), f(7), f(8));
            geometry::mul(&u, &[[a, d, e], [d, b, ff], [e, ff, c]])
        } else {
            std::array::from_fn(|r| std::array::from_fn(|c| geometry::IDENTITY[r][c] + f(3 * r + c)))
        }
    }

    /// Adds each component's stored translation and rounds to `f32`.
    pub(crate) fn translate(&self, solved: &[V3], shifts: &[[f32; 3]]) -> Vec<f32> {
        let mut out = Vec::with_capacity(self.n * 3);
        for (v, p) in solved.iter().enumerate() {
            let s = shifts[self.component[v]];
            for k in 0..3 {
                out.push((p[k] + s[k] as f64) as f32);
            }
        }
        out
    }
}

/// `rec += H q step`, per axis, in a fixed order (shared by encoder and decoder).
pub(crate) fn apply_spectral(rec: &mut [f32], basis: &Mat<f64>, codes: &[i64], step: f64) {
    let (n, l) = basis.shape();
    let mut d = vec![0.0f64; 3 * n];
    for k in 0..l {
        let col = basis.col(k);
        for a in 0..3 {
            let q = codes[a * l + k];
            if q != 0 {
                let x = q as f64 * step;
                for i in 0..n {
                    d[3 * i + a] += col[i] * x;
                }
            }
        }
    }
    for (r, d) in rec.iter_mut().zip(&d) {
        *r = (*r as f64 + d) as f32;
    }
}
