//! The `sac` encoder: per frame an I-frame (keyframe interval start), a P-frame (deformation
//! gradients from the previous *reconstructed* frame → polar decomposition → spectral
//! descriptors → quantization and arithmetic coding, paper §3.1–3.5, plus the residual layer
//! beyond the paper) or, when the P-frame misses the error guard, a repair or a refresh frame.
//! Every P-frame is reconstructed through the decoder's own code path
//! ([`Shared::reconstruct`]), so encoder and decoder agree bit for bit.

use std::sync::Arc;

use codec_core::bytes::ByteWriter;
use codec_core::toolkit::planes::{planes_needed, to_byte_planes};
use codec_core::{entropy, EncodedPacket, EncoderSetup, Error, FrameEncoder, Packet, Quantizer, Result};
use faer::Mat;

use crate::coding::{self, Contexts};
use crate::geometry::{self, Svd3};
use crate::harmonics;
use crate::params::{BasisSource, SacParams};
use crate::state::{
    apply_spectral, set_v3, to_v3, BasisState, Gop, Settings, Shared, VertexBasis, KIND_I, KIND_P, KIND_REFRESH,
};
use crate::{NAME, STREAM_VERSION, UNLIMITED};

pub(crate) fn new_encoder(p: SacParams, setup: &EncoderSetup<'_>) -> Result<Box<dyn FrameEncoder>> {
    let shared = Shared::new(
        setup.topology,
        &UNLIMITED,
        Settings {
            bits: p.bits,
            bases: p.bases,
            polar: p.polar,
            iframe_bits: p.iframe_bits,
            version: STREAM_VERSION,
            basis_per_keyframe: p.basis == BasisSource::Keyframe,
            refactor: p.refactor,
        },
    )?;
    Ok(Box::new(SacEncoder::new(p, shared, setup.want_reconstruction)))
}

/// Near-lossless positions: each axis quantized over the frame's range, codes as byte planes
/// through zstd (the paper leaves the I-frame coder open, §3.1 step 1).
pub(crate) fn encode_positions(w: &mut ByteWriter, frame: &[f32], bits: u8, level: i32) -> Result<Vec<f32>> {
    let mut qs = Vec::with_capacity(3);
    for a in 0..3 {
        let axis: Vec<f32> = frame.iter().skip(a).step_by(3).copied().collect();
        qs.push(Quantizer::covering(&axis, bits)?);
    }
    let codes: Vec<u32> = frame.iter().enumerate().map(|(i, &x)| qs[i % 3].quantize(x)).collect();
    let rec = codes.iter().enumerate().map(|(i, &q)| qs[i % 3].dequantize(q)).collect();
    for q in &qs {
        q.write(w);
    }
    w.bytes(&entropy::compress(&to_byte_planes(&codes, (bits as usize).div_ceil(8)), level));
    Ok(rec)
}

/// Residual layer (stream version ≥ 2, not in the paper): codes `frame − rec` per
/// coordinate with step `step`, corrects `rec` in place exactly as [`decode_residual`] will,
/// and returns `(planes, zstd block)`; `None` if a code does not fit in 31 bits (the caller
/// then sends a refresh frame). Codes are zigzag-mapped and split into `planes` byte planes.
fn encode_residual(frame: &[f32], rec: &mut [f32], step: f32, level: i32) -> Option<(u8, Vec<u8>)> {
    let step64 = step as f64;
    let mut codes = Vec::with_capacity(frame.len());
    for (x, r) in frame.iter().zip(rec.iter_mut()) {
        let q = ((*x as f64 - *r as f64) / step64).round();
        if q.is_nan() || q.abs() >= (1u64 << 30) as f64 {
            return None;
        }
        let q = q as i64;
        *r = (*r as f64 + q as f64 * step64) as f32;
        codes.push(codec_core::bytes::zigzag_encode(q) as u32);
    }
    let planes = planes_needed(&codes);
    Some((planes as u8, entropy::compress(&to_byte_planes(&codes, planes), level)))
}

/// How much finer the spectral step is than the per-vertex step (measured on horse-gallop,
/// pcow and chicken-crossing; README).
const SPECTRAL_FINER: f64 = 16.0;

/// Spectral part of the residual layer (version ≥ 2): the M-orthogonal projection
/// `c = Hᵀ M r` of the residual `r = frame − rec` (per axis) on the manifold harmonics `H`,
/// quantized with step `vertex_step · √(Σ M)` (an error `δ` in `c` moves the frame by `‖δ‖` in
/// the M-norm, i.e. by about `‖δ‖/√area` RMS, so this step matches the per-vertex step), and
/// added to `rec` exactly as [`decode_spectral`] will. The Poisson reconstruction of
/// truncated gradient fields misses mostly smooth, low-frequency shape (README, "Where the
/// error comes from"), which these `3 l` numbers carry more cheaply than per-vertex
/// residuals. Returns the step (0 = nothing sent) and the zstd block of signed varint codes;
/// `None` if a code does not fit in 30 bits.
fn encode_spectral(
    frame: &[f32],
    rec: &mut [f32],
    basis: &Mat<f64>,
    mass: &[f64],
    vertex_step: f32,
    level: i32,
) -> Option<(f32, Vec<u8>)> {
    let (n, l) = basis.shape();
    let mut c = vec![0.0f64; 3 * l];
    for k in 0..l {
        let col = basis.col(k);
        for i in 0..n {
            let w = col[i] * mass[i];
            for a in 0..3 {
                c[a * l + k] += w * (frame[3 * i + a] as f64 - rec[3 * i + a] as f64);
            }
        }
    }
    let step = (vertex_step as f64 * mass.iter().sum::<f64>().sqrt() / SPECTRAL_FINER) as f32;
    if !(step.is_finite() && step > 0.0) {
        return Some((0.0, Vec::new()));
    }
    let mut codes = Vec::with_capacity(3 * l);
    for &x in &c {
        let q = (x / step as f64).round();
        if q.is_nan() || q.abs() >= (1u64 << 30) as f64 {
            return None;
        }
        codes.push(q as i64);
    }
    apply_spectral(rec, basis, &codes, step as f64);
    let mut w = ByteWriter::new();
    for &q in &codes {
        w.varint_signed(q);
    }
    Some((step, entropy::compress(w.as_slice(), level)))
}

/// A coded P-frame: payload, reconstruction, and the entropy statistics after it.
type CodedP = (Vec<u8>, Vec<f32>, Contexts);

pub(crate) struct SacEncoder {
    params: SacParams,
    shared: Shared,
    want_reconstruction: bool,
    next_frame: u32,
    gop: Option<Gop>,
    /// Version 3, `basis = stream`: the basis of the first frame, reused by every keyframe.
    stream_state: Option<Arc<BasisState>>,
    /// P-frames attempted, repaired by the guard's residual, and replaced by refresh frames.
    p_frames: u32,
    repaired: u32,
    refreshed: u32,
}

/// RMS coordinate error of `rec` against `orig`, and `orig`'s bounding-box diagonal.
fn frame_error(orig: &[f32], rec: &[f32]) -> (f64, f64) {
    let mse =
        orig.iter().zip(rec).map(|(&a, &b)| (a as f64 - b as f64).powi(2)).sum::<f64>() / orig.len().max(1) as f64;
    (mse.sqrt(), frame_diagonal(orig))
}

fn frame_diagonal(frame: &[f32]) -> f64 {
    let (lo, hi) = codec_core::animation::bounding_box(frame);
    (0..3).map(|a| (hi[a] as f64 - lo[a] as f64).powi(2)).sum::<f64>().sqrt()
}

/// The guard's refresh-frame cap (version 3): at most one P-frame in this many becomes a
/// refresh frame; later guard misses are repaired with a residual correction.
const REFRESH_CAP: u64 = 8;

/// How far inside the error guard a repaired P-frame lands (its vertex step is
/// `2 × max_error × diagonal / GUARD_REPAIR_FINER`).
const GUARD_REPAIR_FINER: f64 = 16.0;

/// The residual layer of one P-frame: `((spectral step, spectral block), vertex step, (planes, block))`.
type ResidualLayer = ((f32, Vec<u8>), f32, (u8, Vec<u8>));

/// The 9 per-triangle fields of the deformation gradients `grads` (§3.7 a)–c)): with `polar`,
/// the rotation's log map and the stretch's 6 entries minus the identity; otherwise the
/// gradient minus the identity. `None` when a polar decomposition fails or a value is not
/// finite.
fn gradient_fields(grads: &[geometry::M3], polar: bool) -> Option<Vec<Vec<f64>>> {
    let mut fields = vec![vec![0.0f64; grads.len()]; 9];
    let mut svd = Svd3::new();
    for (j, g) in grads.iter().enumerate() {
        if polar {
            let (u, p) = svd.polar(g)?;
            let w = geometry::log_rotation(&u);
            let vals = [w[0], w[1], w[2], p[0][0] - 1.0, p[1][1] - 1.0, p[2][2] - 1.0, p[0][1], p[0][2], p[1][2]];
            for (ch, v) in vals.into_iter().enumerate() {
                fields[ch][j] = v;
            }
        } else {
            for ch in 0..9 {
                fields[ch][j] = g[ch / 3][ch % 3] - geometry::IDENTITY[ch / 3][ch % 3];
            }
        }
    }
    fields.iter().all(|f| f.iter().all(|x| x.is_finite())).then_some(fields)
}

/// §3.5: the coefficients `coeffs`, channel groups of `groups` channels each quantized at
/// `bits` over the group's amplitude. Returns the codes and amplitudes per group; `None` when
/// an amplitude is not finite.
fn quantize_groups(coeffs: &[Vec<f64>], groups: &[usize], bits: u8) -> Option<(Vec<Vec<i64>>, Vec<f32>)> {
    let mut codes = Vec::new();
    let mut amps = Vec::new();
    let mut ch = 0;
    for &count in groups {
        let group = &coeffs[ch..ch + count];
        ch += count;
        let amax = group.iter().flatten().fold(0.0f64, |a, &c| a.max(c.abs()));
        let amp = coding::amplitude(amax);
        if !amp.is_finite() {
            return None;
        }
        let step = coding::step(amp, bits);
        codes.push(group.iter().flatten().map(|&c| coding::quantize(c, step, bits)).collect::<Vec<_>>());
        amps.push(amp);
    }
    Some((codes, amps))
}

/// A P-frame's bytes: kind, group amplitudes, per-component shifts, then (`residual` is
/// `Some` from stream version 2 on) the residual layer or its two zero steps, then the coded
/// descriptors.
fn p_frame_bytes(amps: &[f32], shifts: &[[f32; 3]], residual: Option<Option<&ResidualLayer>>, coded: &[u8]) -> Vec<u8> {
    let mut w = ByteWriter::new();
    w.u8(KIND_P);
    for a in amps {
        w.f32(*a);
    }
    for sh in shifts {
        for &x in sh {
            w.f32(x);
        }
    }
    match residual {
        Some(Some(((amp, spectral), step, (planes, block)))) => {
            w.f32(*amp);
            if *amp > 0.0 {
                w.length_prefixed(spectral);
            }
            w.f32(*step);
            w.u8(*planes);
            w.length_prefixed(block);
        }
        Some(None) => {
            w.f32(0.0);
            w.f32(0.0);
        }
        None => {}
    }
    w.bytes(coded);
    w.into_vec()
}

impl SacEncoder {
    pub(crate) fn new(params: SacParams, shared: Shared, want_reconstruction: bool) -> Self {
        Self {
            params,
            shared,
            want_reconstruction,
            next_frame: 0,
            gop: None,
            stream_state: None,
            p_frames: 0,
            repaired: 0,
            refreshed: 0,
        }
    }

    fn encode_frame(&mut self, frame: &[f32]) -> Result<EncodedPacket> {
        let t = self.next_frame;
        self.next_frame += 1;
        let k = self.params.keyframe_interval;
        let key = self.gop.is_none() || (k > 0 && t.is_multiple_of(k));
        let (data, rec) = if key { self.encode_key(frame)? } else { self.encode_p(frame)? };
        let packet = Packet { first_frame: t, frame_count: 1, keyframe: key, data };
        Ok(EncodedPacket { packet, reconstruction: self.want_reconstruction.then_some(rec) })
    }

    fn encode_key(&mut self, frame: &[f32]) -> Result<(Vec<u8>, Vec<f32>)> {
        let mut body = ByteWriter::new();
        let rec = encode_positions(&mut body, frame, self.params.iframe_bits, self.params.level)?;
        let body = body.into_vec();
        let settings = self.shared.settings;
        let v3 = settings.version >= 3;
        let once = v3 && !settings.basis_per_keyframe;
        let (state, named) = match (&self.stream_state, once) {
            (Some(s), true) => (s.clone(), true),
            _ => (Arc::new(self.shared.basis_state(&rec, body.clone(), None, true)?), false),
        };
        if once {
            self.stream_state = Some(state.clone());
        }
        let mut w = ByteWriter::new();
        w.u8(KIND_I);
        w.u8(state.has_bases() as u8);
        if v3 {
            // Rest source: 0 = this keyframe, 1 = the rest pose's position block follows (the
            // first frame's, so a decoder starting here derives the identical basis).
            if named && state.has_bases() {
                w.u8(1);
                w.length_prefixed(&state.rest_block);
            } else {
                w.u8(0);
            }
        }
        w.bytes(&body);
        self.gop = Some(self.shared.start_gop(&rec, state));
        Ok((w.into_vec(), rec))
    }

    fn encode_refresh(&mut self, frame: &[f32]) -> Result<(Vec<u8>, Vec<f32>)> {
        let mut w = ByteWriter::new();
        w.u8(KIND_REFRESH);
        let rec = encode_positions(&mut w, frame, self.params.iframe_bits, self.params.level)?;
        if let Some(g) = self.gop.as_mut() {
            set_v3(&mut g.prev, &rec);
        }
        Ok((w.into_vec(), rec))
    }

    /// The residual layer at vertex step `step` on top of `rec` (corrected in place); `None`
    /// when it cannot be coded.
    fn residual_layer(&self, frame: &[f32], rec: &mut [f32], step: f32) -> Option<ResidualLayer> {
        let gop = self.gop.as_ref()?;
        let Some(VertexBasis { h, mass: Some(mass) }) = gop.state.vertex_basis() else { return None };
        let spectral = encode_spectral(frame, rec, h, mass, step, self.params.level)?;
        let coded = encode_residual(frame, rec, step, self.params.level)?;
        if rec.iter().any(|x| !x.is_finite()) {
            return None;
        }
        Some((spectral, step, coded))
    }

    /// The P-frame pipeline; `None` when it cannot run or misses the error guard. The second
    /// value is true when the guard's repair residual was needed.
    fn try_p(&mut self, frame: &[f32]) -> Result<Option<(CodedP, bool)>> {
        let gop = self.gop.as_ref().expect("a keyframe starts every interval");
        let Some(analysis) = gop.state.analysis.as_ref() else { return Ok(None) };
        let s = &self.shared;
        let settings = s.settings;
        let target = to_v3(frame);
        // §3.7 a)–c): gradients from the previous reconstruction, polar decomposition, log map.
        let grads = geometry::deformation_gradients(&s.tris, &gop.prev, &target);
        let Some(fields) = gradient_fields(&grads, settings.polar) else { return Ok(None) };
        // §3.4 Eq. 8–9 (least-squares form) and §3.5 quantization.
        let coeffs: Vec<Vec<f64>> = fields.iter().map(|f| harmonics::analyze(analysis, f)).collect();
        let Some((codes, amps)) = quantize_groups(&coeffs, settings.groups(), settings.bits) else { return Ok(None) };
        let mut contexts = gop.contexts.clone();
        let coded = coding::encode(&codes, analysis.nrows(), &mut contexts);
        // §3.7 e)–f) through the decoder's own code path.
        let gop = self.gop.as_mut().expect("a keyframe starts every interval");
        match s.reconstruct(gop, &codes, &amps) {
            Ok(()) => {}
            Err(Error::Numerical { .. }) => return Ok(None),
            Err(e) => return Err(e),
        }
        let solved = &gop.work.solved;
        let mut sums = vec![[0.0f64; 3]; s.components()];
        for (v, p) in solved.iter().enumerate() {
            for k in 0..3 {
                sums[s.component[v]][k] += target[v][k] - p[k];
            }
        }
        let shifts: Vec<[f32; 3]> = sums
            .iter()
            .zip(&s.component_sizes)
            .map(|(d, &c)| std::array::from_fn(|k| (d[k] / c as f64) as f32))
            .collect();
        let solved_rec = s.translate(solved, &shifts);
        if solved_rec.iter().any(|x| !x.is_finite()) {
            return Ok(None);
        }
        // Residual layer (version ≥ 2): step relative to this frame's diagonal.
        let diag = frame_diagonal(frame);
        let mut rec = solved_rec.clone();
        let mut residual = None;
        if settings.version >= 2 {
            let step = (self.params.residual * diag) as f32;
            if step > 0.0 && step.is_finite() {
                let Some(layer) = self.residual_layer(frame, &mut rec, step) else { return Ok(None) };
                residual = Some(layer);
            }
        }
        let (rms, _) = frame_error(frame, &rec);
        let mut repaired = false;
        let within = |rms: f64| rms <= self.params.max_error * diag;
        // Version 3 caps the refresh frames: while they are fewer than one P-frame in
        // `REFRESH_CAP`, a guard miss is a refresh frame as before (it resets the closed loop
        // to near-lossless, which pcow's unstable loop at 100 bases needs: repairing every
        // miss measured KG 11.6 there against 4.5); beyond the cap it is repaired.
        let capped = (self.refreshed as u64) * REFRESH_CAP >= self.p_frames as u64;
        if !within(rms) && settings.version >= 3 && capped {
            // The guard's repair (version 3): a residual whose per-coordinate error is at most
            // half its step, here `max_error × diagonal / 16`, far inside the guard: a frame
            // held *at* the guard's bound would be a poor reference for the closed loop (pcow's
            // unstable loop then lost monotonicity: measured with `animcodec sweep`). Still a
            // few bits per coordinate against `iframe_bits` for a refresh frame.
            let step = (2.0 * self.params.max_error * diag / GUARD_REPAIR_FINER) as f32;
            rec.clone_from(&solved_rec);
            let Some(layer) = self.residual_layer(frame, &mut rec, step) else { return Ok(None) };
            residual = Some(layer);
            repaired = true;
        }
        let (rms, _) = frame_error(frame, &rec);
        if !within(rms) {
            return Ok(None);
        }
        let residual = (settings.version >= 2).then_some(residual.as_ref());
        Ok(Some(((p_frame_bytes(&amps, &shifts, residual, &coded), rec, contexts), repaired)))
    }

    fn encode_p(&mut self, frame: &[f32]) -> Result<(Vec<u8>, Vec<f32>)> {
        self.p_frames += 1;
        match self.try_p(frame)? {
            Some(((data, rec, contexts), repaired)) => {
                self.repaired += repaired as u32;
                let g = self.gop.as_mut().expect("keyframe first");
                g.contexts = contexts;
                g.p_count += 1;
                set_v3(&mut g.prev, &rec);
                Ok((data, rec))
            }
            None => {
                self.refreshed += 1;
                self.encode_refresh(frame)
            }
        }
    }
}

impl FrameEncoder for SacEncoder {
    fn config(&self) -> Vec<u8> {
        self.shared.settings.config()
    }

    fn push_frames(&mut self, frames: &[f32]) -> Result<Vec<EncodedPacket>> {
        frames.chunks_exact(self.shared.n * 3).map(|f| self.encode_frame(f)).collect()
    }

    fn finish(&mut self) -> Result<Vec<EncodedPacket>> {
        Ok(Vec::new())
    }

    /// Says how often the error guard acted: repairs (coarse residual, version 3) and refresh
    /// frames (positions at `iframe_bits`, each about as large as a keyframe).
    fn notes(&self) -> Vec<String> {
        let mut notes = Vec::new();
        let p = self.p_frames.max(1);
        if self.refreshed > 0 {
            notes.push(format!(
                "{NAME}: the error guard (max_error={}) replaced {} of {} P-frames with refresh frames \
                 (positions at iframe_bits={}, each about the size of a keyframe){}",
                self.params.max_error,
                self.refreshed,
                self.p_frames,
                self.params.iframe_bits,
                if self.refreshed * 4 >= p {
                    "; the stream is mostly keyframe-sized frames: the pipeline fails on this animation"
                } else {
                    ""
                }
            ));
        }
        if self.repaired > 0 {
            notes.push(format!(
                "{NAME}: the error guard (max_error={}) reached its cap of refresh frames (one P-frame in \
                 {REFRESH_CAP}) and repaired {} of {} P-frames with a residual correction instead (a few bits \
                 per coordinate each; more bases or the residual layer avoid it)",
                self.params.max_error, self.repaired, self.p_frames
            ));
        }
        notes
    }
}
