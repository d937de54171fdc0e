//! The encoder: per block of frames, motion removal (§2.3), HO-SVD (§2.4, Alg. 1), the choice
//! of `(v, f)` (§2.6, Alg. 3–4), truncation, optional HOOI, then the coding of the operator
//! (the toolkit's, [`crate::coding`], or the paper's, [`crate::paper`]) and the block's error
//! bound, checked against the encoder's own reconstruction.

use std::time::Instant;

use codec_core::bytes::ByteWriter;
use codec_core::toolkit::order::CausalGraph;
use codec_core::{entropy, Animation, EncodedPacket, Error, ErrorBound, FrameEncoder, Packet, Result, Topology};
use faer::Mat;

use crate::decoder::add_centre;
use crate::params::{Coding, HosvdParams};
use crate::strategy::{self, Dims, Strategy};
use crate::tensor::{self, Affine, Model, Spectrum, Tensor, Tucker};
use crate::{coding, motion, paper, spectra};
use crate::{FLAG_CENTRE, FLAG_DENOISE, FLAG_MOTION, FLAG_REGRESS, FLAG_RELSTEP, FLAG_TOOLKIT, NAME};

/// What the encoder measured and decided for one packet.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlockStats {
    /// Frames in the block.
    pub frames: usize,
    /// Mode-1 rank kept.
    pub v: usize,
    /// Mode-3 rank kept.
    pub f: usize,
    /// Rank-search error evaluations.
    pub evaluations: usize,
    /// No `(v, f)` met the `ss` budget and `(1, 1)` was used.
    pub over_budget: bool,
    /// Numbers in the paper's size model (`S^(hosvd)/d_s` + `12F`); `× 4` bytes with `d_s = 4`.
    pub paper_numbers: usize,
    /// `‖X‖²` of the normalised tensor.
    pub norm2: f64,
    /// Squared truncation error in the normalised space, `‖X‖² − ‖C̃‖²` (before quantization).
    pub truncation_error2: f64,
    /// Upper bound of `‖T − T̂‖_F` for this block in original coordinates, derived from the
    /// truncation error, the quantizers' half steps and the transforms' gains.
    pub error_bound: f64,
    /// Packet payload bytes.
    pub payload_bytes: usize,
    /// Where the payload goes (toolkit coding; zeros with the paper coding).
    pub sections: Sections,
    /// Mode-1 columns the search put in regression mode whose closed loop failed on the
    /// decoded leads and were re-coded with the mesh predictor (0 normally).
    pub regression_fallbacks: usize,
    /// Seconds in motion removal + Gram factorizations (+ full core when searching).
    pub decompose_seconds: f64,
    /// Seconds in the rank search.
    pub search_seconds: f64,
    /// Seconds in HOOI sweeps.
    pub hooi_seconds: f64,
    /// Seconds quantizing, entropy coding and reconstructing.
    pub code_seconds: f64,
}

/// Bytes of a toolkit packet's parts: the coded operator by group (estimated from the
/// adaptive coder's cost model; their sum is within a few bytes of the coded length), the
/// coded transforms and the side block.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Sections {
    /// `U1` columns (fields over the vertices: the rest shape and its modes of deformation).
    pub u1: f64,
    /// Of `u1`, the first three columns: the rest shape (with the leading `U3` columns, the
    /// shape every frame shares).
    pub u1_lead: f64,
    /// `U3` columns (signals over the frames).
    pub u3: f64,
    /// Core slices.
    pub core: f64,
    /// Coded per-frame transforms (motion removal), with their length prefix.
    pub motion: usize,
    /// zstd side block (`U2`, steps, raw transforms) with its length prefix, the packet's
    /// header bytes, smoothing levels, column modes and centre.
    pub other: usize,
}

/// One encoded block: payload, the decoder's reconstruction (if asked), statistics.
#[derive(Debug, Clone)]
pub struct EncodedBlock {
    /// Packet payload.
    pub payload: Vec<u8>,
    /// `frames × K × 3`, bit-identical to what the decoder produces (when requested).
    pub reconstruction: Option<Vec<f32>>,
    /// Statistics.
    pub stats: BlockStats,
}

/// Unquantized truncated HO-SVD (+ optional HOOI) of frames `F × K × 3`, reconstructed in
/// original coordinates: the reference the quantized stream is measured against, and what
/// `tools/compare_tensorly.py` checks against an independent implementation.
pub fn truncated_reconstruction(
    positions: &[f32],
    k: usize,
    v: usize,
    f: usize,
    rigid: bool,
    hooi_iters: usize,
) -> Result<(Vec<f32>, f64)> {
    truncated_reconstruction_with(positions, k, v, f, rigid, true, hooi_iters)
}

/// [`truncated_reconstruction`] with the choice of affine (`true`) or rotation-only motion.
pub fn truncated_reconstruction_with(
    positions: &[f32],
    k: usize,
    v: usize,
    f: usize,
    rigid: bool,
    affine: bool,
    hooi_iters: usize,
) -> Result<(Vec<f32>, f64)> {
    let frames = positions.len() / (3 * k);
    let (transforms, x) = normalise(positions, k, frames, rigid, affine);
    let t = Tensor::new(&x, k, frames);
    let (v, f) = (v.clamp(1, t.max_v()), f.clamp(1, t.max_f()));
    let u2 = t.mode2()?;
    let mut tk = Tucker {
        u1: tensor::leading_left(t.x1.as_ref(), v)?,
        u3: tensor::leading_left(t.x3.as_ref(), f)?,
        core: Vec::new(),
        u2,
    };
    tk.hooi(&t, hooi_iters)?;
    let err2 = (t.norm2 - tk.core_norm2()).max(0.0);
    let m = Model {
        k,
        frames,
        v,
        f,
        u1: row_major(&tk.u1),
        u2: std::array::from_fn(|i| tk.u2[(i / 3, i % 3)]),
        u3: row_major(&tk.u3),
        core: tk.core,
        transforms,
    };
    Ok((tensor::reconstruct(&m), err2))
}

fn row_major(m: &Mat<f64>) -> Vec<f64> {
    let mut out = Vec::with_capacity(m.nrows() * m.ncols());
    for i in 0..m.nrows() {
        for j in 0..m.ncols() {
            out.push(m[(i, j)]);
        }
    }
    out
}

/// RMS distance of frame 0's vertices from their centroid (the translation step's scale).
fn rms_radius(positions: &[f32], k: usize) -> f64 {
    let frame = &positions[..(3 * k).min(positions.len())];
    let n = (frame.len() / 3).max(1) as f64;
    let mean: [f64; 3] = std::array::from_fn(|j| frame.chunks_exact(3).map(|p| p[j] as f64).sum::<f64>() / n);
    let s: f64 = frame.chunks_exact(3).map(|p| (0..3).map(|j| (p[j] as f64 - mean[j]).powi(2)).sum::<f64>()).sum();
    (s / n).sqrt()
}

fn normalise(positions: &[f32], k: usize, frames: usize, rigid: bool, affine: bool) -> (Vec<Affine>, Vec<f64>) {
    normalise_centred(positions, k, frames, rigid, affine, [0.0; 3])
}

/// [`normalise`] of `positions − centre` (f64, exact; [`tensor::remove_affine_motion_centred`]).
fn normalise_centred(
    positions: &[f32],
    k: usize,
    frames: usize,
    rigid: bool,
    affine: bool,
    centre: [f64; 3],
) -> (Vec<Affine>, Vec<f64>) {
    if rigid {
        tensor::remove_affine_motion_centred(positions, k, frames, affine, centre, &mut |proposed, fallback, _| {
            if tensor::mat3_inverse(&proposed.m.map(|v| v as f64)).is_some() {
                proposed
            } else {
                fallback
            }
        })
    } else {
        let x = positions.chunks_exact(3).flat_map(|p| (0..3).map(move |j| p[j] as f64 - centre[j])).collect();
        (vec![Affine::IDENTITY; frames], x)
    }
}

/// Stream version 6: the centre subtracted from a block before its decomposition,
/// rounded to f32 as the packet stores it. The paper decomposes the raw coordinates (§2.1: the
/// first components carry the mean shape); far from the origin the shape and its motion are
/// then tiny next to the offset, and the Gram route (§2.4, `tensor::leading_left`), which
/// squares the singular values, resolves components down to about `1e-8` of the largest only:
/// the same animation translated by 1e5 decoded at KG 20 % where the untranslated one had 3 %.
/// With motion removal every frame is mapped onto frame 0, so frame 0's centroid is the centre
/// of the normalised tensor; without it, the centroid of the whole block.
pub(crate) fn block_centre(positions: &[f32], k: usize, rigid: bool) -> [f32; 3] {
    let used = if rigid { &positions[..(3 * k).min(positions.len())] } else { positions };
    let n = (used.len() / 3).max(1) as f64;
    let mut s = [0.0f64; 3];
    for p in used.chunks_exact(3) {
        for j in 0..3 {
            s[j] += p[j] as f64;
        }
    }
    s.map(|x| {
        let c = (x / n) as f32;
        if c.is_finite() {
            c
        } else {
            0.0
        }
    })
}

/// Mean over frames and mesh edges of the squared edge length of `x` (`F × K × 3`), the
/// edges being the graph's (each once, between a position and an earlier neighbour); 0 when
/// the graph has no edges (e.g. it does not cover the mesh).
fn mean_squared_edge(x: &[f64], k: usize, graph: &CausalGraph) -> f64 {
    if graph.len() != k || k == 0 {
        return 0.0;
    }
    let order = graph.order();
    let frames = x.len() / (3 * k);
    let (mut sum, mut count) = (0.0f64, 0usize);
    for t in 0..frames {
        let xt = &x[t * 3 * k..(t + 1) * 3 * k];
        for p in 0..k {
            let a = order[p] as usize;
            for &q in graph.earlier(p) {
                let b = order[q as usize] as usize;
                sum += (0..3).map(|j| (xt[a * 3 + j] - xt[b * 3 + j]).powi(2)).sum::<f64>();
                count += 1;
            }
        }
    }
    if count == 0 {
        0.0
    } else {
        sum / count as f64
    }
}

/// Encodes one block of frames (`F × K × 3`). This is exactly what a packet holds.
/// `graph` is the mesh's coding order ([`CausalGraph::mesh`] of the topology), used by the
/// toolkit coding.
pub fn encode_block(
    positions: &[f32],
    k: usize,
    p: &HosvdParams,
    graph: &CausalGraph,
    want_reconstruction: bool,
) -> Result<EncodedBlock> {
    let frames = positions.len() / (3 * k);
    let start = Instant::now();
    let (centre32, motion_coder, transforms, x) = normalise_block(positions, k, frames, p, graph);
    let t = Tensor::new(&x, k, frames);
    let edge2 = mean_squared_edge(&x, k, graph);
    let dims = Dims { k, f: frames, rigid: p.rigid };
    // Mode 2 is kept whole; rounding U2 to f32 *before* the core is computed makes the stored
    // U2 the one the core was projected on.
    let u2 = t.mode2()?.as_ref().to_owned();
    let u2r = Mat::from_fn(3, 3, |i, j| u2[(i, j)] as f32 as f64);
    let explicit = p.v != 0;
    let list = match p.strategy {
        Strategy::Iterative | Strategy::Exhaustive if !explicit => strategy::candidates(dims, p.ss),
        _ => Vec::new(),
    };
    // The full-rank spectrum (most of an encode's time) only when there are candidates to
    // compare: with one or none (the top of the ladder, where a STED search probes the smallest
    // model) the choice is made without it.
    let needs_errors = !explicit && p.strategy != Strategy::Diagonal && list.len() > 1;
    let spectrum = if needs_errors { Some(spectra::spectrum(&t, &x, k, frames)?) } else { None };
    drop(x);
    let decompose_a = start.elapsed().as_secs_f64();

    let search_start = Instant::now();
    let choice = choose_ranks(p, dims, &list, spectrum.as_deref());
    let search_seconds = search_start.elapsed().as_secs_f64();
    let (v, f) = final_ranks(p, dims, &choice, spectrum.as_deref(), t.norm2);

    let trunc_start = Instant::now();
    let mut tk = match &spectrum {
        Some(s) => Tucker::truncate(&t, s, v, f, u2r.clone()),
        None => {
            let u1 = tensor::leading_left(t.x1.as_ref(), v)?;
            let u3 = tensor::leading_left(t.x3.as_ref(), f)?;
            let core = t.core(u1.as_ref(), u2r.as_ref(), u3.as_ref());
            Tucker { u1, u2: u2r.clone(), u3, core }
        }
    };
    let decompose_seconds = decompose_a + trunc_start.elapsed().as_secs_f64();
    let hooi_start = Instant::now();
    if p.hooi_iters > 0 {
        tk.hooi(&t, p.hooi_iters as usize)?;
    }
    let hooi_seconds = hooi_start.elapsed().as_secs_f64();

    let code_start = Instant::now();
    let norm2 = t.norm2;
    let trunc2 = (norm2 - tk.captured_norm2()).max(0.0);
    drop(t);
    let factors = Factors::new(tk, v, f);

    let budget = noise_budget(p, trunc2, norm2, edge2, 3 * k * frames);
    let mut side = ByteWriter::new();
    for i in 0..9 {
        side.f32(u2r[(i / 3, i % 3)] as f32);
    }
    if p.rigid && motion_coder.is_none() {
        for a in &transforms {
            a.m.iter().chain(&a.c).for_each(|&x| side.f32(x));
        }
    }
    let mut m = Model {
        k,
        frames,
        v,
        f,
        u1: Vec::new(),
        u2: std::array::from_fn(|i| u2r[(i / 3, i % 3)]),
        u3: Vec::new(),
        core: Vec::new(),
        transforms: if p.rigid { transforms.clone() } else { vec![Affine::IDENTITY; frames] },
    };
    let (mut payload, terms, regression_fallbacks, mut sections) =
        code_operator(p, graph, &factors, side, motion_coder, &mut m, budget)?;
    // Stream version 6: the flag, and the centre at the end of the packet.
    payload[0] |= FLAG_CENTRE;
    for c in centre32 {
        payload.extend_from_slice(&c.to_le_bytes());
    }
    if p.coding == Coding::Toolkit {
        let coded = (sections.u1 + sections.u3 + sections.core).round() as usize;
        sections.other = payload.len().saturating_sub(coded + sections.motion);
    }
    let centre = centre32.map(|c| c as f64);
    let error_bound = block_error_bound(positions, centre, &m, &u2r, &factors, &terms, norm2, trunc2);

    // The encoder measures its reconstruction against the input: the error the
    // chosen ranks and steps promise is `error_bound` (truncation, quantization of every factor
    // and of the transforms, the factors' loss of orthogonality, the f32 roundings), proved
    // above; far beyond it (numerical precision lost on an input far from its centre, e.g. a
    // block travelling a long way) no stream is written.
    let mut rec = tensor::reconstruct(&m);
    add_centre(&mut rec, centre32)?;
    check_precision(positions, &rec, error_bound, 0.0, v, f)?;
    let reconstruction = want_reconstruction.then_some(rec);
    let code_seconds = code_start.elapsed().as_secs_f64();
    let stats = BlockStats {
        frames,
        v,
        f,
        evaluations: choice.evaluations,
        over_budget: choice.over_budget,
        paper_numbers: dims.paper_numbers(v, f),
        norm2,
        truncation_error2: trunc2,
        error_bound,
        payload_bytes: payload.len(),
        sections,
        regression_fallbacks,
        decompose_seconds,
        search_seconds,
        hooi_seconds,
        code_seconds,
    };
    Ok(EncodedBlock { payload, reconstruction, stats })
}

/// The quantization plan: total noise budget D = (quant · ε)², ε = truncation error (floored at
/// 1e-6‖X‖ so a lossless truncation still gets finite steps), split evenly between U1, U3 and
/// the core; within a factor, evenly between columns, each column's step scaled by 1/s_i so its
/// contribution (entries × step²/12 × s_i²) is the same. `edge2` is the mean squared edge
/// length of the normalised block of `coordinates` coordinates.
fn noise_budget(p: &HosvdParams, trunc2: f64, norm2: f64, edge2: f64, coordinates: usize) -> f64 {
    let eps2 = trunc2.max(1e-12 * norm2);
    let budget = p.quant * p.quant * eps2;
    // STED cap (`edge_noise`): at most (η·L̄)² per coordinate, L̄ the RMS edge length, so at
    // low rates (large ε) the noise stays a small fraction of an edge. Not in the paper.
    if p.edge_noise > 0.0 && edge2 > 0.0 {
        return budget.min(p.edge_noise * p.edge_noise * edge2 * coordinates as f64);
    }
    budget
}

/// The block's centre (stream version 6: see [`block_centre`]), the motion coder when the
/// transforms are coded (stream version 3: toolkit coding with `rigid`), and the normalised
/// block (§2.3): the per-frame transforms and the `F × K × 3` positions less the centre, with
/// the motion removed.
#[allow(clippy::type_complexity)]
fn normalise_block(
    positions: &[f32],
    k: usize,
    frames: usize,
    p: &HosvdParams,
    graph: &CausalGraph,
) -> ([f32; 3], Option<motion::MotionEncoder>, Vec<Affine>, Vec<f64>) {
    let centre32 = block_centre(positions, k, p.rigid);
    let centre = centre32.map(|c| c as f64);
    // With the toolkit coding the transforms are quantized in closed loop while the frames are
    // normalised (`motion.rs`).
    let mut motion_coder = (p.rigid && p.coding == Coding::Toolkit).then(|| {
        let radius = rms_radius(positions, k);
        let bits = match p.motion_bits {
            0 if p.edge_noise > 0.0 => {
                let first: Vec<f64> = positions[..(3 * k).min(positions.len())].iter().map(|&x| x as f64).collect();
                motion::auto_bits(p.edge_noise, radius, mean_squared_edge(&first, k, graph).sqrt())
            }
            0 => motion::DEFAULT_BITS,
            bits => bits,
        };
        motion::MotionEncoder::new(radius, bits)
    });
    let (transforms, x) = match motion_coder.as_mut() {
        Some(mc) => tensor::remove_affine_motion_centred(positions, k, frames, p.affine, centre, &mut |a, fb, mu| {
            mc.store(a, fb, mu)
        }),
        None => normalise_centred(positions, k, frames, p.rigid, p.affine, centre),
    };
    (centre32, motion_coder, transforms, x)
}

/// The ranks `(v, f)` for `ss` by the parameters' strategy (§2.6, Alg. 3–4) over the candidate
/// `list`, reading the truncation errors from the full-rank `spectrum` (present when there is
/// more than one candidate), or the explicit ranks clamped to the tensor's.
fn choose_ranks(p: &HosvdParams, dims: Dims, list: &[(usize, usize)], spectrum: Option<&Spectrum>) -> strategy::Choice {
    if p.v != 0 {
        return strategy::Choice {
            v: (p.v as usize).clamp(1, dims.max_v()),
            f: (p.f as usize).clamp(1, dims.max_f()),
            evaluations: 0,
            over_budget: false,
        };
    }
    match (p.strategy, spectrum, list) {
        (Strategy::Diagonal, _, _) => strategy::diagonal(dims, p.ss),
        (_, _, []) => strategy::Choice { v: 1, f: 1, evaluations: 0, over_budget: true },
        (_, None, &[(v, f), ..]) => strategy::Choice { v, f, evaluations: 0, over_budget: false },
        (Strategy::Iterative, Some(s), _) => {
            strategy::iterative(list, p.samples as usize, p.depth as usize, |v, f| s.truncation_error2(v, f))
        }
        (Strategy::Exhaustive, Some(s), _) => strategy::exhaustive(list, |v, f| s.truncation_error2(v, f)),
    }
}

/// The ranks coded for `choice`: the candidate strategies' fallback when nothing fits the
/// budget, and the smallest ranks at the numerical floor (below).
fn final_ranks(
    p: &HosvdParams,
    dims: Dims,
    choice: &strategy::Choice,
    spectrum: Option<&Spectrum>,
    norm2: f64,
) -> (usize, usize) {
    // The candidate strategies' fallback when nothing fits the budget: the smallest model that
    // is not flat (`Dims::smallest`; the diagonal strategy keeps the paper's `(1, 1)`).
    let (mut v, mut f) = match (choice.over_budget, p.strategy) {
        (true, Strategy::Iterative | Strategy::Exhaustive) => dims.smallest(),
        _ => (choice.v, choice.f),
    };
    // Not in the paper: when the chosen ranks already reproduce the tensor to the numerical
    // floor (the quantization budget's floor, 1e-12‖X‖²; e.g. an exactly low-rank skinned
    // animation), more rank buys nothing but coded near-zero columns: keep the smallest ranks
    // that stay at the floor, so a smaller `ss` never gives a different stream for nothing.
    // The paper coding keeps the paper's choice.
    if let (false, Some(s), Coding::Toolkit) = (p.v != 0, spectrum, p.coding) {
        let floor = 1e-12 * norm2;
        if s.truncation_error2(v, f) <= floor {
            while v > 1 && s.truncation_error2(v - 1, f) <= floor {
                v -= 1;
            }
            while f > 1 && s.truncation_error2(v, f - 1) <= floor {
                f -= 1;
            }
        }
    }
    (v, f)
}

/// The truncated operator, row-major, with the slice norms of the core: how much each factor
/// column is scaled in the reconstruction.
struct Factors {
    u1: Vec<f64>,
    u3: Vec<f64>,
    core: Vec<f64>,
    s1: Vec<f64>,
    s3: Vec<f64>,
}

impl Factors {
    fn new(tk: Tucker, v: usize, f: usize) -> Self {
        let u1 = row_major(&tk.u1);
        let u3 = row_major(&tk.u3);
        let core = tk.core;
        let s1: Vec<f64> =
            (0..v).map(|i| core[i * 3 * f..(i + 1) * 3 * f].iter().map(|c| c * c).sum::<f64>().sqrt()).collect();
        let s3: Vec<f64> = (0..f).map(|l| (0..v * 3).map(|ij| core[ij * f + l].powi(2)).sum::<f64>().sqrt()).collect();
        Self { u1, u3, core, s1, s3 }
    }
}

/// Bounds of the quantization errors: per column of `U1` and `U3` (`‖δu1_i‖`, `‖δu3_l‖`) and of
/// the whole core (`‖δC‖`).
struct ErrorTerms {
    n1: Vec<f64>,
    n3: Vec<f64>,
    dc: f64,
}

/// Quantizes and codes the operator in the parameters' coding within the noise `budget`,
/// writing the packet (without its centre) after the side block `side` (`U2` and, when not
/// coded, the transforms); fills `m`'s factors and core with what the decoder reconstructs.
/// Returns the packet, the bounds of the quantization errors and the number of regression
/// columns re-coded with the mesh predictor.
fn code_operator(
    p: &HosvdParams,
    graph: &CausalGraph,
    factors: &Factors,
    mut side: ByteWriter,
    mut motion_coder: Option<motion::MotionEncoder>,
    m: &mut Model,
    budget: f64,
) -> Result<(Vec<u8>, ErrorTerms, usize, Sections)> {
    let Factors { u1, u3, core, s1, s3 } = factors;
    let mut w = ByteWriter::new();
    if p.coding == Coding::Paper {
        let (n1, n3, dc) = paper::code(&mut w, side, m, p, u1, u3, core, s1, s3, budget)?;
        return Ok((w.into_vec(), ErrorTerms { n1, n3, dc }, 0, Sections::default()));
    }
    let (k, frames, v, f) = (m.k, m.frames, m.v, m.f);
    let op = coding::Operator { k, frames, v, f, u1, u3, core, s1, s3 };
    let settings = coding::Settings {
        mesh: p.mesh_predictor,
        time: p.time_predictor,
        shaping: p.shaping,
        rdq: p.rdq,
        edge_weight: p.edge_weight,
        denoise: p.denoise,
        regress: p.regress,
        relstep: coding::relstep::strength_byte(p.relstep),
        relstep_auto: p.relstep_auto,
        force_unguarded_regression: p.force_unguarded_regression,
    };
    let coded = coding::code(&op, graph, &settings, budget);
    // The encoder checks its own output: a component whose closed loop failed with no safer
    // mode left is never written.
    if let Some(&c) = coded.failed.first() {
        return Err(Error::Unsupported {
            context: NAME.into(),
            detail: format!(
                "component {c} of the coded operator (v = {v}, f = {f}) does not reconstruct within its \
                 quantization step; no stream written"
            ),
        });
    }
    for &step in &coded.steps {
        side.f32(step);
    }
    w.u8(p.rigid as u8
        | FLAG_TOOLKIT
        | if motion_coder.is_some() { FLAG_MOTION } else { 0 }
        | if p.denoise { FLAG_DENOISE } else { 0 }
        | if p.regress { FLAG_REGRESS } else { 0 }
        | if coded.relstep > 0 { FLAG_RELSTEP } else { 0 });
    w.varint(v as u64);
    w.varint(f as u64);
    w.u8(p.mesh_predictor.code());
    w.u8(p.time_predictor.code());
    w.length_prefixed(&entropy::compress(side.as_slice(), p.level));
    w.length_prefixed(&coded.bytes);
    let mut sections = Sections {
        u1: coded.group_bits[0] / 8.0,
        u1_lead: coded.lead_bits / 8.0,
        u3: coded.group_bits[1] / 8.0,
        core: coded.group_bits[2] / 8.0,
        ..Sections::default()
    };
    if let Some(mc) = motion_coder.take() {
        let before = w.as_slice().len();
        w.length_prefixed(&mc.finish());
        sections.motion = w.as_slice().len() - before;
    }
    if p.denoise {
        w.bytes(&coded.smoothing);
    }
    if p.regress {
        w.bytes(&coded.modes);
    }
    if coded.relstep > 0 {
        w.u8(coded.relstep);
        for &g in &coded.gains {
            w.f32(g);
        }
    }
    m.u1 = coded.u1;
    m.u3 = coded.u3;
    m.core = coded.core;
    Ok((w.into_vec(), ErrorTerms { n1: coded.du1, n3: coded.du3, dc: coded.dc }, coded.fallbacks.len(), sections))
}

/// Upper bound of `‖T − T̂‖_F` for the block in original coordinates ([`BlockStats::error_bound`]).
/// With Û = U + δU, Ĉ = C + δC: Ĉ×₁Û1×₂U2×₃Û3 − C×₁U1×₂U2×₃U3 = δC×Û1×Û3 + C×δU1×Û3 + C×U1×δU3
/// (all ×₂U2), and ‖C ×₁ δU1‖ ≤ Σ_i ‖δu_i‖·s1_i; ‖Û‖₂ ≤ 1 + ‖δU‖_F. Then the stored transforms'
/// largest gain and the f32 roundings.
#[allow(clippy::too_many_arguments)]
fn block_error_bound(
    positions: &[f32],
    centre: [f64; 3],
    m: &Model,
    u2r: &Mat<f64>,
    factors: &Factors,
    terms: &ErrorTerms,
    norm2: f64,
    trunc2: f64,
) -> f64 {
    let ErrorTerms { n1, n3, dc } = terms;
    let (s1, s3) = (&factors.s1, &factors.s3);
    let du1: f64 = n1.iter().map(|x| x * x).sum::<f64>().sqrt();
    let du3: f64 = n3.iter().map(|x| x * x).sum::<f64>().sqrt();
    let g2 = {
        let mut dev = 0.0f64;
        for i in 0..3 {
            for j in 0..3 {
                let dot: f64 = (0..3).map(|l| u2r[(i, l)] * u2r[(j, l)]).sum();
                dev += (dot - if i == j { 1.0 } else { 0.0 }).powi(2);
            }
        }
        dev.sqrt()
    };
    let t1: f64 = n1.iter().zip(s1).map(|(n, s)| n * s).sum();
    let t3: f64 = n3.iter().zip(s3).map(|(n, s)| n * s).sum();
    let norm = norm2.sqrt();
    let ex =
        trunc2.sqrt() + 1e-7 * norm + g2 * norm + (1.0 + g2) * (dc * (1.0 + du1) * (1.0 + du3) + t1 * (1.0 + du3) + t3);
    let gain = m.transforms.iter().map(Affine::gain).fold(0.0, f64::max);
    let pos_norm = positions.iter().map(|&x| (x as f64).powi(2)).sum::<f64>().sqrt();
    // Version 6 rounds twice: the centred reconstruction to f32, then its sum with the centre.
    let centred_norm = positions
        .chunks_exact(3)
        .map(|q| (0..3).map(|j| (q[j] as f64 - centre[j]).powi(2)).sum::<f64>())
        .sum::<f64>()
        .sqrt();
    (gain * ex + (pos_norm + centred_norm + 2.0 * gain * ex) * 2.0f64.powi(-23) + 1e-30) * (1.0 + 1e-9)
}

/// How far the measured error may exceed the bound the chosen ranks and steps promise
/// (`BlockStats::error_bound`, which every sound encode meets) before the encoder refuses: a
/// margin against the bound's own rounding, far below the failures this check is for (KG 20 %
/// instead of 3 %).
const PRECISION_MARGIN: f64 = 2.0;

/// Refuses a block whose reconstruction `rec` is further from `positions` (Frobenius)
/// than [`PRECISION_MARGIN`] × `promised` plus the unavoidable: `slack` (numerical floors of
/// the analysis) and the `f32` rounding of every output coordinate (half a unit in the last
/// place, twice: the centred value and its sum with the centre).
pub(crate) fn check_precision(
    positions: &[f32],
    rec: &[f32],
    promised: f64,
    slack: f64,
    v: usize,
    f: usize,
) -> Result<()> {
    let (mut err2, mut round2) = (0.0f64, 0.0f64);
    for (&x, &y) in positions.iter().zip(rec) {
        err2 += (x as f64 - y as f64).powi(2);
        // A unit in the last place of |y| (≥ the smallest normal's, for subnormal outputs).
        let ulp = (y.abs().max(f32::MIN_POSITIVE) as f64) * 2.0f64.powi(-23);
        round2 += ulp * ulp;
    }
    let (err, allowed) = (err2.sqrt(), PRECISION_MARGIN * promised + slack + round2.sqrt());
    if err <= allowed {
        return Ok(());
    }
    Err(Error::Unsupported {
        context: NAME.into(),
        detail: format!(
            "the decoded block is {err:.3e} from the input (Frobenius), beyond the {allowed:.3e} that its ranks (v = {v}, f = {f}) and quantization promise: numerical \
             precision was lost (coordinates far from their centre next to the shape's size?); no stream \
             written. Use smaller temporal blocks (-p block=N) or another codec (quant-delta)"
        ),
    })
}

/// Streaming encoder: buffers `block` frames (or all of them), then codes one packet.
/// Public so benchmarks can read [`HosvdEncoder::stats`] after driving it.
pub struct HosvdEncoder {
    params: HosvdParams,
    k: usize,
    graph: CausalGraph,
    block: usize,
    want_reconstruction: bool,
    pending: Vec<f32>,
    next_frame: u32,
    stats: Vec<BlockStats>,
    /// Frames in the whole animation.
    frame_count: usize,
    /// Bounding box and coordinate count of the frames pushed (for [`FrameEncoder::declared_bound`]).
    lo: [f32; 3],
    hi: [f32; 3],
    coordinates: usize,
}

/// The parameters for one block of `frames` frames (`whole`: the block is the whole
/// animation). A block of 1 or 2 frames has no frame mode to reduce: when `ss` cannot be met
/// there (the strategy's smallest model is over budget: `(1, 1)` for the diagonal one, the
/// smallest that is not flat, `(3, 1)`, for the others), the fallback keeps all or nothing: the
/// `(1, 1)` model almost nothing of the shape (KG above 60 % on a 1-frame mesh), `(3, 1)` on one
/// frame everything at more than the raw size. Such a block is coded at full rank when it ends a
/// longer animation (it is small next to the rest), and an animation that short is refused with
/// the `ss` it would need.
fn block_params(p: &HosvdParams, k: usize, frames: usize, whole: bool) -> Result<HosvdParams> {
    let dims = Dims { k, f: frames, rigid: p.rigid };
    let (v0, f0) = match p.strategy {
        Strategy::Diagonal => (1, 1),
        Strategy::Iterative | Strategy::Exhaustive => dims.smallest(),
    };
    if frames >= 3 || p.v != 0 || dims.cr(v0, f0) <= 1.0 - p.ss {
        return Ok(*p);
    }
    if whole {
        let reachable = 1.0 - dims.cr(v0, f0);
        let advice = if reachable > 0.01 {
            format!("use -p ss={:.2} or lower, explicit ranks (-p v=N -p f=N)", reachable - 0.005)
        } else {
            "no ss can be met: use explicit ranks (-p v=N -p f=N)".to_owned()
        };
        return Err(Error::Unsupported {
            context: NAME.into(),
            detail: format!(
                "an animation of {frames} frame{} cannot be coded at ss={}: with so few frames the frame mode \
                 cannot be reduced, and even the smallest Tucker core keeps {:.0}% of the raw size (the paper's \
                 size model); {advice}, or a codec that does not rely on many frames (quant-delta)",
                if frames == 1 { "" } else { "s" },
                p.ss,
                (1.0 - reachable) * 100.0,
            ),
        });
    }
    Ok(HosvdParams { v: dims.max_v() as u32, f: dims.max_f() as u32, ..*p })
}

impl HosvdEncoder {
    /// An encoder for `frame_count` frames over `topology`.
    pub fn new(params: HosvdParams, topology: &Topology, frame_count: usize, want_reconstruction: bool) -> Self {
        let block = if params.block == 0 { frame_count.max(1) } else { params.block as usize };
        Self {
            params,
            k: topology.vertex_count(),
            graph: mesh_graph(&params, topology),
            block,
            want_reconstruction,
            pending: Vec::new(),
            next_frame: 0,
            stats: Vec::new(),
            frame_count,
            lo: [f32::INFINITY; 3],
            hi: [f32::NEG_INFINITY; 3],
            coordinates: 0,
        }
    }

    /// Statistics of every packet coded so far.
    pub fn stats(&self) -> &[BlockStats] {
        &self.stats
    }

    fn code(&mut self, frames: usize) -> Result<EncodedPacket> {
        let n = frames * self.k * 3;
        let whole = self.next_frame == 0 && frames >= self.frame_count;
        let params = block_params(&self.params, self.k, frames, whole)?;
        let block: Vec<f32> = self.pending.drain(..n).collect();
        let b = encode_block(&block, self.k, &params, &self.graph, self.want_reconstruction)?;
        self.stats.push(b.stats);
        let packet =
            Packet { first_frame: self.next_frame, frame_count: frames as u32, keyframe: true, data: b.payload };
        self.next_frame += frames as u32;
        Ok(EncodedPacket { packet, reconstruction: b.reconstruction })
    }
}

impl FrameEncoder for HosvdEncoder {
    fn config(&self) -> Vec<u8> {
        (self.block.min(u32::MAX as usize) as u32).to_le_bytes().to_vec()
    }

    fn push_frames(&mut self, frames: &[f32]) -> Result<Vec<EncodedPacket>> {
        if frames.len() >= 3 {
            let (lo, hi) = codec_core::animation::bounding_box(frames);
            for a in 0..3 {
                self.lo[a] = self.lo[a].min(lo[a]);
                self.hi[a] = self.hi[a].max(hi[a]);
            }
        }
        self.coordinates += frames.len();
        self.pending.extend_from_slice(frames);
        let mut out = Vec::new();
        while self.pending.len() >= self.block * self.k * 3 && self.k > 0 {
            out.push(self.code(self.block)?);
        }
        Ok(out)
    }

    /// [`AnimationCodec::error_bound`](codec_core::AnimationCodec::error_bound) from the packets' own bounds (the same arithmetic), so
    /// the stream driver's self-check needs no second analysis.
    fn declared_bound(&self) -> Option<ErrorBound> {
        let frob = self.stats.iter().map(|s| s.error_bound.powi(2)).sum::<f64>().sqrt();
        let diag = if self.coordinates >= 3 {
            (0..3).map(|a| (self.hi[a] as f64 - self.lo[a] as f64).powi(2)).sum::<f64>().sqrt()
        } else {
            0.0
        };
        let rel = if diag > 0.0 { frob / (self.coordinates as f64).sqrt() / diag } else { f64::INFINITY };
        Some(ErrorBound { max_coordinate_error: Some(frob), relative_rms_error: Some(rel) })
    }

    fn notes(&self) -> Vec<String> {
        let fallbacks: usize = self.stats.iter().map(|s| s.regression_fallbacks).sum();
        if fallbacks == 0 {
            return Vec::new();
        }
        vec![format!(
            "{NAME}: fallback: {fallbacks} mode-1 column{} in regression mode did not reconstruct within its \
             step on the decoded leading columns and {} re-coded with the mesh predictor",
            if fallbacks == 1 { "" } else { "s" },
            if fallbacks == 1 { "was" } else { "were" },
        )]
    }

    fn finish(&mut self) -> Result<Vec<EncodedPacket>> {
        if self.k == 0 {
            return Err(Error::Unsupported { context: NAME.into(), detail: "an animation without vertices".into() });
        }
        let n = self.pending.len() / (self.k * 3);
        Ok(if n > 0 { vec![self.code(n)?] } else { Vec::new() })
    }
}

/// [`AnimationCodec::error_bound`](codec_core::AnimationCodec::error_bound): runs the encoder's
/// analysis on every block of `animation` and combines the blocks' bounds
/// ([`BlockStats::error_bound`]) in the Frobenius norm.
pub(crate) fn error_bound(p: &HosvdParams, animation: &Animation) -> Result<ErrorBound> {
    let k = animation.vertex_count();
    let per_block = if p.block == 0 { animation.frame_count() } else { p.block as usize };
    let mut total2 = 0.0;
    let whole = per_block >= animation.frame_count();
    let graph = mesh_graph(p, animation.topology());
    for chunk in animation.positions().chunks(per_block * k * 3) {
        let bp = block_params(p, k, chunk.len() / (3 * k).max(1), whole)?;
        let b = encode_block(chunk, k, &bp, &graph, false)?;
        total2 += b.stats.error_bound.powi(2);
    }
    let frob = total2.sqrt();
    let n = (animation.positions().len()) as f64;
    let diag = animation.bounding_box_diagonal();
    let rel = if diag > 0.0 { frob / n.sqrt() / diag } else { f64::INFINITY };
    Ok(ErrorBound { max_coordinate_error: Some(frob), relative_rms_error: Some(rel) })
}

/// The mesh's coding order when the toolkit coding needs it (an empty order otherwise).
pub fn mesh_graph(p: &HosvdParams, topology: &Topology) -> CausalGraph {
    match p.coding {
        Coding::Toolkit => CausalGraph::mesh(topology.vertex_count(), topology.triangles()),
        Coding::Paper => CausalGraph::chain(0, false),
    }
}
