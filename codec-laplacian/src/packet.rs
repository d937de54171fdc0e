//! One packet: its layout, the encoder's analysis and coding, and the decoder.
//!
//! Layout (all little-endian):
//! - `u8` mode: 0 coded, 1 raw (`frames × V × 3` `f32`, written when the coded reconstruction
//!   would break the declared bound, see [`encode`]);
//! - coded: `u8` flags (bit 0: Laplacian domain), `u16` rank N, `u32` anchor spacing, `f32`
//!   coefficient step, `f32` average-mesh/centroid step, `f32` anchor step, N × `f32` basis
//!   steps, then the adaptive arithmetic-coded integers to the end of the packet, in this order:
//!   1. the average mesh, axis by axis along the coding order, parallelogram-predicted;
//!   2. the centroid trajectory (the mean row of the trajectory matrix), axis by axis along
//!      time, predicted by the previous frame;
//!   3. the N temporal basis vectors, column by column and axis by axis along time,
//!      predicted by the previous frame, column j at its own step;
//!   4. the N coefficient fields, column by column: with the Laplacian, the anchors' values
//!      (in coding order, predicted by the previous anchor) and then the quantized δ of every
//!      free vertex in coding order; without it, the field along the coding order,
//!      parallelogram-predicted.
//!
//! The decoder reconstructs `x[t][v][k] = avg[v][k] + m[3t+k] + Σ_j C[v][j]·B[3t+k][j]` in that
//! order in `f64` and rounds to `f32`; the encoder's reconstruction is the same code.

use codec_core::bytes::{ByteReader, ByteWriter};
use codec_core::limits::{WORK_PER_CODED_VALUE, WORK_PER_COORDINATE};
use codec_core::linalg;
use codec_core::toolkit::adaptive::{AdaptiveDecoder, AdaptiveEncoder};
use codec_core::toolkit::order::CausalGraph;
use codec_core::toolkit::predict::{self, Predictor};
use codec_core::toolkit::rdq;
use codec_core::{Error, Limits, Result};
use faer::Mat;

use crate::operator::{self, Operator};
use crate::params::{LaplacianParams, MAX_RANK};
use crate::NAME;

const MODE_CODED: u8 = 0;
const MODE_RAW: u8 = 1;
const FLAG_LAPLACIAN: u8 = 1;

/// Arithmetic-coder classes: average mesh (+ axis), centroid (+ axis), basis (+ axis), anchors,
/// coefficient field j (+ min(j, 15)).
const CLASS_MEAN: usize = 0;
const CLASS_CENTROID: usize = 3;
const CLASS_BASIS: usize = 6;
const CLASS_ANCHOR: usize = 9;
const CLASS_FIELD: usize = 10;
const FIELD_CLASSES: usize = 16;
const CLASSES: usize = CLASS_FIELD + FIELD_CLASSES;

/// How often the encoder quarters its steps before it falls back to a raw packet.
const RETRIES: usize = 12;

fn field_class(j: usize) -> usize {
    CLASS_FIELD + j.min(FIELD_CLASSES - 1)
}

/// Bounding-box diagonal and largest coordinate magnitude of frame-major positions.
pub(crate) fn extent(positions: &[f32]) -> (f64, f64) {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in positions.chunks_exact(3) {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a] as f64);
            hi[a] = hi[a].max(p[a] as f64);
        }
    }
    if positions.len() < 3 {
        return (0.0, 0.0);
    }
    let diagonal = (0..3).map(|a| (hi[a] - lo[a]).powi(2)).sum::<f64>().sqrt();
    let magnitude = (0..3).map(|a| lo[a].abs().max(hi[a].abs())).fold(0.0, f64::max);
    (diagonal, magnitude)
}

/// Sum over frames and vertices of the squared distance to the frame's centroid.
pub(crate) fn centered_energy(frames: &[f32], v: usize) -> f64 {
    let mut total = 0.0;
    if v == 0 {
        return 0.0;
    }
    for frame in frames.chunks_exact(v * 3) {
        let mut c = [0.0f64; 3];
        for q in frame.chunks_exact(3) {
            for a in 0..3 {
                c[a] += q[a] as f64;
            }
        }
        for x in &mut c {
            *x /= v as f64;
        }
        for q in frame.chunks_exact(3) {
            for a in 0..3 {
                total += (q[a] as f64 - c[a]).powi(2);
            }
        }
    }
    total
}

/// Writes `codes` (position order of `graph`) with `class`, each with the bucket of its earlier
/// neighbours' codes; positions marked in `skip` are not written (they hold 0).
fn emit(enc: &mut AdaptiveEncoder, class: usize, graph: &CausalGraph, codes: &[i32], skip: Option<&[bool]>) {
    for (p, &c) in codes.iter().enumerate() {
        if skip.is_some_and(|s| s[p]) {
            continue;
        }
        enc.encode(c, class, predict::neighbour_bucket(graph, codes, p));
    }
}

/// The decoder's side of [`emit`].
fn read(dec: &mut AdaptiveDecoder, class: usize, graph: &CausalGraph, skip: Option<&[bool]>) -> Result<Vec<i32>> {
    let mut codes = vec![0i32; graph.len()];
    for p in 0..graph.len() {
        if skip.is_some_and(|s| s[p]) {
            continue;
        }
        codes[p] = dec.decode(class, predict::neighbour_bucket(graph, &codes, p))?;
    }
    Ok(codes)
}

/// Steps and sizes of a coded packet, as in its header.
#[derive(Debug, Clone)]
struct Header {
    laplacian: bool,
    spacing: usize,
    step: f64,
    mean_step: f64,
    anchor_step: f64,
    basis_steps: Vec<f64>,
}

impl Header {
    fn write(&self, w: &mut ByteWriter) {
        w.u8(if self.laplacian { FLAG_LAPLACIAN } else { 0 });
        w.u16(self.basis_steps.len() as u16);
        w.u32(self.spacing as u32);
        for s in [self.step, self.mean_step, self.anchor_step].into_iter().chain(self.basis_steps.iter().copied()) {
            w.f32(s as f32);
        }
    }

    fn read(r: &mut ByteReader<'_>, v: usize, frames: usize) -> Result<Self> {
        let flags = r.u8("flags")?;
        if flags & !FLAG_LAPLACIAN != 0 {
            return Err(r.malformed("flags", format!("unknown flag bits {flags:#04x}")));
        }
        let rank = r.u16("rank")? as usize;
        let most = (MAX_RANK as usize).min(v).min(3 * frames);
        if rank > most {
            return Err(r.malformed("rank", format!("{rank} basis vectors, more than min(1024, V, 3F) = {most}")));
        }
        let spacing = r.u32("anchor spacing")? as usize;
        if spacing == 0 {
            return Err(r.malformed("anchor spacing", "0 (at least 1)".to_owned()));
        }
        let step = |r: &mut ByteReader<'_>, field: &'static str| -> Result<f64> {
            let s = r.finite_f32(field)?;
            if s < f32::MIN_POSITIVE {
                return Err(r.malformed(field, format!("{s} is not a positive normal number")));
            }
            Ok(s as f64)
        };
        let (s, mean_step, anchor_step) = (step(r, "step")?, step(r, "mean step")?, step(r, "anchor step")?);
        let basis_steps = (0..rank).map(|_| step(r, "basis step")).collect::<Result<Vec<_>>>()?;
        Ok(Self { laplacian: flags & FLAG_LAPLACIAN != 0, spacing, step: s, mean_step, anchor_step, basis_steps })
    }
}

/// What both sides hold after the codes: the decoded average mesh (vertex order, `V × 3`), the
/// centroid trajectory (`3F`), the basis (`3F × N`, column-major) and the coefficients
/// (`V × N`, column-major).
pub(crate) struct Decoded {
    avg: Vec<f64>,
    centroid: Vec<f64>,
    basis: Vec<f64>,
    coeffs: Vec<f64>,
}

impl Decoded {
    /// The frames, `f32`, frame-major.
    fn frames(&self, v: usize, frames: usize) -> Vec<f32> {
        let mut out = Vec::with_capacity(frames * v * 3);
        for t in 0..frames {
            self.push_frame(t, v, frames, &mut out);
        }
        out
    }

    /// Appends frame `t` of `frames` to `out`: the mean, the centroid and one row of the
    /// temporal basis against the coefficients (the same sums, in the same order, for one frame
    /// or all).
    fn push_frame(&self, t: usize, v: usize, frames: usize, out: &mut Vec<f32>) {
        let n = self.basis.len() / (3 * frames).max(1);
        for x in 0..v {
            for k in 0..3 {
                let r = 3 * t + k;
                let mut s = self.avg[x * 3 + k] + self.centroid[r];
                for j in 0..n {
                    s += self.coeffs[j * v + x] * self.basis[j * 3 * frames + r];
                }
                out.push(s as f32);
            }
        }
    }
}

/// A decoded packet before its frames are formed: raw frames as stored, or the coded
/// packet's mean, centroid trajectory, basis and coefficients.
pub(crate) enum Parsed {
    Raw { data: Vec<f32>, frames: usize },
    Coded { decoded: Decoded, v: usize, frames: usize },
}

impl Parsed {
    /// Every frame (`F × V × 3`).
    pub(crate) fn all_frames(&self) -> Result<Vec<f32>> {
        let out = match self {
            Parsed::Raw { data, .. } => data.clone(),
            Parsed::Coded { decoded, v, frames } => decoded.frames(*v, *frames),
        };
        finite(out)
    }

    /// Bytes held.
    pub(crate) fn bytes(&self) -> u64 {
        match self {
            Parsed::Raw { data, .. } => data.len() as u64 * 4,
            Parsed::Coded { decoded: d, .. } => {
                (d.avg.len() + d.centroid.len() + d.basis.len() + d.coeffs.len()) as u64 * 8
            }
        }
    }

    /// Frame `t` alone (`t` < the packet's frames, checked by the caller).
    pub(crate) fn frame(&self, t: usize) -> Result<Vec<f32>> {
        let out = match self {
            Parsed::Raw { data, frames } => {
                let per = data.len() / frames.max(&1);
                data[t * per..(t + 1) * per].to_vec()
            }
            Parsed::Coded { decoded, v, frames } => {
                let mut out = Vec::with_capacity(v * 3);
                decoded.push_frame(t, *v, *frames, &mut out);
                out
            }
        };
        finite(out)
    }
}

/// `out`, or the error of its first non-finite coordinate.
fn finite(out: Vec<f32>) -> Result<Vec<f32>> {
    if let Some(x) = out.iter().find(|x: &&f32| !x.is_finite()) {
        return Err(Error::malformed(NAME, "packet", format!("decodes to a non-finite coordinate {x}")));
    }
    Ok(out)
}

/// An encoded packet's bytes and the frames it decodes to.
pub(crate) struct Coded {
    pub bytes: Vec<u8>,
    pub frames: Vec<f32>,
}

/// Encodes `frames` (`F × V × 3`) as one packet. The packet's squared error never exceeds its
/// centred energy (the bound's premise, `bound.rs`): when the coded reconstruction would, the
/// steps are quartered and the packet coded again, and after [`RETRIES`] the frames are
/// written raw.
pub(crate) fn encode(
    p: &LaplacianParams,
    graph: &CausalGraph,
    triangles: &[[u32; 3]],
    frames: &[f32],
) -> Result<Coded> {
    let v = graph.len();
    let f = if v == 0 { 0 } else { frames.len() / (v * 3) };
    let centered = centered_energy(frames, v);
    let mut scale = 1.0;
    if v > 0 && f > 0 {
        for _ in 0..RETRIES {
            if let Some(coded) = encode_coded(p, scale, graph, triangles, frames, f)? {
                let err: f64 = coded.frames.iter().zip(frames).map(|(&a, &b)| (a as f64 - b as f64).powi(2)).sum();
                if err <= centered {
                    return Ok(coded);
                }
            }
            scale *= 0.25;
        }
    }
    let mut w = ByteWriter::new();
    w.u8(MODE_RAW);
    for &x in frames {
        w.f32(x);
    }
    Ok(Coded { bytes: w.into_vec(), frames: frames.to_vec() })
}

/// One coded attempt at `scale` × the parameters' steps; `None` when it cannot be coded (a
/// non-finite reconstruction or a failed factorization).
fn encode_coded(
    p: &LaplacianParams,
    scale: f64,
    graph: &CausalGraph,
    triangles: &[[u32; 3]],
    frames: &[f32],
    f: usize,
) -> Result<Option<Coded>> {
    let v = graph.len();
    let order = graph.order();
    let (diag, magnitude) = extent(frames);
    let floor = rdq::step_floor(magnitude).max(f32::MIN_POSITIVE as f64);
    let s = rdq::stored_step(scale * p.step * diag, floor);
    let mean_step = rdq::stored_step(p.mean_scale * s, floor);
    let anchor_step = rdq::stored_step(p.anchor_scale * s, floor);
    let mut enc = AdaptiveEncoder::new(CLASSES);
    let (mut codes, mut recon) = (Vec::new(), Vec::new());

    // 1. Average mesh (frame mean), along the coding order.
    let mut avg = vec![0.0; v * 3];
    for k in 0..3 {
        let values: Vec<f64> = order
            .iter()
            .map(|&x| (0..f).map(|t| frames[(t * v + x as usize) * 3 + k] as f64).sum::<f64>() / f as f64)
            .collect();
        predict::quantize(graph, Predictor::Parallelogram, &values, mean_step, 0.0, &mut codes, &mut recon);
        emit(&mut enc, CLASS_MEAN + k, graph, &codes, None);
        for (pos, &x) in order.iter().enumerate() {
            avg[x as usize * 3 + k] = recon[pos];
        }
    }

    // 2. Trajectories minus the average mesh; their mean row (the centroid's motion).
    let chain = CausalGraph::chain(f, false);
    let mut centroid = vec![0.0; 3 * f];
    let mut x = Mat::<f64>::zeros(v, 3 * f);
    for t in 0..f {
        for i in 0..v {
            for k in 0..3 {
                x[(i, 3 * t + k)] = frames[(t * v + i) * 3 + k] as f64 - avg[i * 3 + k];
            }
        }
    }
    for k in 0..3 {
        let values: Vec<f64> = (0..f).map(|t| (0..v).map(|i| x[(i, 3 * t + k)]).sum::<f64>() / v as f64).collect();
        predict::quantize(&chain, Predictor::Previous, &values, mean_step, 0.0, &mut codes, &mut recon);
        emit(&mut enc, CLASS_CENTROID + k, &chain, &codes, None);
        for t in 0..f {
            centroid[3 * t + k] = recon[t];
        }
    }
    for r in 0..3 * f {
        for i in 0..v {
            x[(i, r)] -= centroid[r];
        }
    }

    // 3. Temporal basis: leading eigenvectors of the 3F × 3F Gram matrix.
    let gram = linalg::mul(x.transpose(), x.as_ref());
    let (eig, vecs) = linalg::sym_eig_desc(gram.as_ref()).map_err(|e| e.numerical(NAME, "basis"))?;
    let most = (MAX_RANK as usize).min(v).min(3 * f);
    let rank = if p.rank > 0 {
        (p.rank as usize).min(most)
    } else {
        let threshold = p.keep * v as f64 * s * s;
        eig.iter().take(most).take_while(|&&l| l > threshold).count()
    };
    let mut basis = vec![0.0; 3 * f * rank];
    let mut basis_steps = Vec::with_capacity(rank);
    for j in 0..rank {
        let sigma = eig[j].sqrt();
        let step = rdq::stored_step((p.basis_scale * s / sigma).min(1.0), rdq::step_floor(1.0));
        basis_steps.push(step);
        for k in 0..3 {
            let values: Vec<f64> = (0..f).map(|t| vecs[(3 * t + k, j)]).collect();
            predict::quantize(&chain, Predictor::Previous, &values, step, 0.0, &mut codes, &mut recon);
            emit(&mut enc, CLASS_BASIS + k, &chain, &codes, None);
            for t in 0..f {
                basis[j * 3 * f + 3 * t + k] = recon[t];
            }
        }
    }

    // 4. Coefficients: least squares on the decoded basis, C = X·B̂·(B̂ᵀB̂)⁻¹.
    let b = Mat::<f64>::from_fn(3 * f, rank, |r, j| basis[j * 3 * f + r]);
    let xb = linalg::mul(x.as_ref(), b.as_ref());
    let btb = linalg::mul(b.transpose(), b.as_ref());
    let Some(coeffs) = solve_normal(&btb, &xb) else {
        return Ok(None);
    };
    drop(x);
    let op = if p.laplacian && rank > 0 {
        match Operator::new(graph, triangles, &avg, p.spacing as usize, &Limits::UNLIMITED) {
            Ok(op) => Some(op),
            Err(_) => return Ok(None),
        }
    } else {
        None
    };
    let decoded_coeffs =
        code_coefficients(&mut enc, graph, op.as_ref(), p.spacing as usize, &coeffs, rank, (s, anchor_step));
    let decoded = Decoded { avg, centroid, basis, coeffs: decoded_coeffs };
    let out = decoded.frames(v, f);
    if out.iter().any(|x| !x.is_finite()) {
        return Ok(None);
    }
    let header =
        Header { laplacian: op.is_some(), spacing: p.spacing as usize, step: s, mean_step, anchor_step, basis_steps };
    let mut w = ByteWriter::new();
    w.u8(MODE_CODED);
    header.write(&mut w);
    w.bytes(&enc.finish());
    Ok(Some(Coded { bytes: w.into_vec(), frames: out }))
}

/// Codes the `rank` coefficient fields (`coeffs`, column-major `V × rank`) at step `s`: as
/// cotangent-Laplacian deltas with anchors coded apart at `anchor_step` when `op` is given
/// (anchors every `spacing` positions along the coding order), else directly along the coding
/// order with the parallelogram predictor. Returns the fields as the decoder reconstructs them.
fn code_coefficients(
    enc: &mut AdaptiveEncoder,
    graph: &CausalGraph,
    op: Option<&Operator>,
    spacing: usize,
    coeffs: &[f64],
    rank: usize,
    (s, anchor_step): (f64, f64),
) -> Vec<f64> {
    let v = graph.len();
    let order = graph.order();
    let (mut codes, mut recon) = (Vec::new(), Vec::new());
    let skip = op.map(|_| operator::anchor_positions(graph, spacing));
    let anchor_chain = op.map(|op| CausalGraph::chain(op.anchors().len(), false));
    let mut decoded_coeffs = vec![0.0; v * rank];
    let inv = 1.0 / s;
    for j in 0..rank {
        let field = &coeffs[j * v..(j + 1) * v];
        let out = &mut decoded_coeffs[j * v..(j + 1) * v];
        match (op, &skip, &anchor_chain) {
            (Some(op), Some(skip), Some(anchor_chain)) => {
                let values: Vec<f64> = op.anchors().iter().map(|&a| field[a as usize]).collect();
                predict::quantize(anchor_chain, Predictor::Previous, &values, anchor_step, 0.0, &mut codes, &mut recon);
                emit(enc, CLASS_ANCHOR, anchor_chain, &codes, None);
                let anchors = recon.clone();
                let delta = op.delta(field, &anchors);
                let mut pos_codes = vec![0i32; v];
                let mut delta_hat = Vec::with_capacity(delta.len());
                let mut free = delta.iter();
                for (pos, c) in pos_codes.iter_mut().enumerate() {
                    if !skip[pos] {
                        let d = free.next().copied().unwrap_or(0.0);
                        let (code, r) = predict::quantize_one(d, 0.0, s, inv);
                        *c = code;
                        delta_hat.push(r);
                    }
                }
                emit(enc, field_class(j), graph, &pos_codes, Some(skip));
                out.copy_from_slice(&op.solve(&delta_hat, &anchors));
            }
            _ => {
                let values: Vec<f64> = order.iter().map(|&i| field[i as usize]).collect();
                predict::quantize(graph, Predictor::Parallelogram, &values, s, 0.0, &mut codes, &mut recon);
                emit(enc, field_class(j), graph, &codes, None);
                for (pos, &i) in order.iter().enumerate() {
                    out[i as usize] = recon[pos];
                }
            }
        }
    }
    decoded_coeffs
}

/// `C = XB · G⁻¹` for the small symmetric `G = B̂ᵀB̂` (dense Cholesky, plain loops), column-major
/// `V × N`; `None` when `G` is not positive definite.
fn solve_normal(g: &Mat<f64>, xb: &Mat<f64>) -> Option<Vec<f64>> {
    let n = g.nrows();
    let mut l = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let mut s = g[(i, j)];
            for k in 0..j {
                s -= l[i * n + k] * l[j * n + k];
            }
            if i == j {
                if !(s > 0.0 && s.is_finite()) {
                    return None;
                }
                l[i * n + i] = s.sqrt();
            } else {
                l[i * n + j] = s / l[j * n + j];
            }
        }
    }
    let v = xb.nrows();
    let mut out = vec![0.0; v * n];
    let mut y = vec![0.0; n];
    for row in 0..v {
        for i in 0..n {
            let mut s = xb[(row, i)];
            for k in 0..i {
                s -= l[i * n + k] * y[k];
            }
            y[i] = s / l[i * n + i];
        }
        for i in (0..n).rev() {
            let mut s = y[i];
            for k in i + 1..n {
                s -= l[k * n + i] * y[k];
            }
            y[i] = s / l[i * n + i];
        }
        for (j, &c) in y.iter().enumerate() {
            out[j * v + row] = c;
        }
    }
    Some(out)
}

/// Decodes one packet of `frames` frames up to its frames ([`Parsed`]); `limits` bounds its
/// memory and work (checked before either is spent), that of every frame included.
pub(crate) fn parse(
    data: &[u8],
    graph: &CausalGraph,
    triangles: &[[u32; 3]],
    frames: usize,
    limits: &Limits,
) -> Result<Parsed> {
    let v = graph.len();
    let coords = Limits::product(&[frames as u64, v as u64, 3]);
    limits.check_alloc(NAME, "decoded frames", coords.saturating_mul(4))?;
    let mut r = ByteReader::new(data, NAME);
    match r.u8("mode")? {
        MODE_RAW => {
            let len = usize::try_from(coords.saturating_mul(4)).unwrap_or(usize::MAX);
            let bytes = r.take(len, "raw frames")?;
            r.expect_end("raw frames")?;
            let data = bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
            Ok(Parsed::Raw { data, frames })
        }
        MODE_CODED => Ok(Parsed::Coded { decoded: decode_coded(&mut r, graph, triangles, frames, limits)?, v, frames }),
        m => Err(r.malformed("mode", format!("{m} (0 coded, 1 raw)"))),
    }
}

fn decode_coded(
    r: &mut ByteReader<'_>,
    graph: &CausalGraph,
    triangles: &[[u32; 3]],
    f: usize,
    limits: &Limits,
) -> Result<Decoded> {
    let v = graph.len();
    if v == 0 || f == 0 {
        return Err(r.malformed("mode", "a coded packet with no vertices or no frames".to_owned()));
    }
    let h = Header::read(r, v, f)?;
    let n = h.basis_steps.len();
    let (v64, f64_, n64) = (v as u64, f as u64, n as u64);
    // Codes and the decoded planes (f64), then the operator; work: the codes, the solves, the
    // reconstruction's multiply-adds and the output.
    let values = Limits::product(&[3, v64])
        .saturating_add(Limits::product(&[3, f64_]))
        .saturating_add(Limits::product(&[3, f64_, n64]))
        .saturating_add(Limits::product(&[v64, n64]));
    limits.check_alloc(
        NAME,
        "decoded planes",
        values.saturating_mul(8).saturating_add(Limits::product(&[v64, 4 * 4])),
    )?;
    limits.check_work(NAME, "arithmetic decoding", values.saturating_mul(WORK_PER_CODED_VALUE))?;
    let coords = Limits::product(&[f64_, v64, 3]);
    limits.check_work(
        NAME,
        "reconstruction",
        coords.saturating_mul(n64).saturating_add(coords.saturating_mul(WORK_PER_COORDINATE)),
    )?;
    let order = graph.order();
    let mut dec = AdaptiveDecoder::new(r.take(r.remaining(), "codes")?, CLASSES, NAME, "codes")?;
    let mut recon = Vec::new();
    let mut avg = vec![0.0; v * 3];
    for k in 0..3 {
        let codes = read(&mut dec, CLASS_MEAN + k, graph, None)?;
        predict::dequantize(graph, Predictor::Parallelogram, &codes, h.mean_step, &mut recon);
        for (pos, &x) in order.iter().enumerate() {
            avg[x as usize * 3 + k] = recon[pos];
        }
    }
    let chain = CausalGraph::chain(f, false);
    let mut centroid = vec![0.0; 3 * f];
    for k in 0..3 {
        let codes = read(&mut dec, CLASS_CENTROID + k, &chain, None)?;
        predict::dequantize(&chain, Predictor::Previous, &codes, h.mean_step, &mut recon);
        for t in 0..f {
            centroid[3 * t + k] = recon[t];
        }
    }
    let mut basis = vec![0.0; 3 * f * n];
    for (j, &step) in h.basis_steps.iter().enumerate() {
        for k in 0..3 {
            let codes = read(&mut dec, CLASS_BASIS + k, &chain, None)?;
            predict::dequantize(&chain, Predictor::Previous, &codes, step, &mut recon);
            for t in 0..f {
                basis[j * 3 * f + 3 * t + k] = recon[t];
            }
        }
    }
    let op = if h.laplacian && n > 0 {
        let (size, edges) = operator::operator_size(graph, triangles, h.spacing);
        limits.check_alloc(NAME, "Laplacian factor", size.bytes(v, edges))?;
        limits.check_work(
            NAME,
            "Laplacian solves",
            size.envelope.saturating_mul(2).saturating_add(2 * edges as u64).saturating_mul(n64),
        )?;
        Some(Operator::new(graph, triangles, &avg, h.spacing, limits)?)
    } else {
        None
    };
    let skip = op.as_ref().map(|_| operator::anchor_positions(graph, h.spacing));
    let anchor_chain = op.as_ref().map(|op| CausalGraph::chain(op.anchors().len(), false));
    let mut coeffs = vec![0.0; v * n];
    for j in 0..n {
        let out = &mut coeffs[j * v..(j + 1) * v];
        match (&op, &skip, &anchor_chain) {
            (Some(op), Some(skip), Some(anchor_chain)) => {
                let codes = read(&mut dec, CLASS_ANCHOR, anchor_chain, None)?;
                predict::dequantize(anchor_chain, Predictor::Previous, &codes, h.anchor_step, &mut recon);
                let codes = read(&mut dec, field_class(j), graph, Some(skip))?;
                let delta: Vec<f64> =
                    codes.iter().zip(skip.iter()).filter(|(_, &s)| !s).map(|(&c, _)| c as f64 * h.step).collect();
                out.copy_from_slice(&op.solve(&delta, &recon));
            }
            _ => {
                let codes = read(&mut dec, field_class(j), graph, None)?;
                predict::dequantize(graph, Predictor::Parallelogram, &codes, h.step, &mut recon);
                for (pos, &i) in order.iter().enumerate() {
                    out[i as usize] = recon[pos];
                }
            }
        }
    }
    dec.finish()?;
    Ok(Decoded { avg, centroid, basis, coeffs })
}
