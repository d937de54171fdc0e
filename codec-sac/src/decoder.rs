//! The `sac` decoder: reads the stream config (its layout depends on the stream version),
//! then per packet an I-frame (positions and the interval's basis state), a refresh frame
//! (positions) or a P-frame (descriptors → gradients → Poisson solve, paper §3.6, plus the
//! residual layer of versions 2–3). Every byte is untrusted: each field is checked and every
//! allocation and work estimate is charged to the caller's [`Limits`] first.

use std::sync::Arc;

use codec_core::bytes::ByteReader;
use codec_core::toolkit::planes::plane_value;
use codec_core::{entropy, Error, FrameDecoder, Limits, Packet, Quantizer, Result, StreamInfo};
use faer::Mat;

use crate::coding;
use crate::harmonics;
use crate::state::{apply_spectral, set_v3, BasisState, Gop, Settings, Shared, KIND_I, KIND_P, KIND_REFRESH};
use crate::{NAME, STREAM_VERSION};

pub(crate) fn new_decoder(info: &StreamInfo, config: &[u8], limits: &Limits) -> Result<Box<dyn FrameDecoder>> {
    // The config layout depends on the version: check it before reading the config.
    if !(1..=STREAM_VERSION).contains(&info.codec_version) {
        return Err(Error::Unsupported {
            context: NAME.into(),
            detail: format!("stream version {} (this build decodes 1..={STREAM_VERSION})", info.codec_version),
        });
    }
    let mut r = ByteReader::new(config, NAME);
    let bits = r.u8("config.bits")?;
    let bases = r.u32("config.bases")?;
    let polar = r.u8("config.polar")?;
    let iframe_bits = r.u8("config.iframe_bits")?;
    // Version 3 adds the basis source and the Poisson reference.
    let (basis_per_keyframe, refactor) = if info.codec_version >= 3 {
        let basis = r.u8("config.basis")?;
        let refactor = r.u8("config.refactor")?;
        if basis > 1 {
            return Err(r.malformed("config.basis", format!("{basis} is not 0 (stream) or 1 (keyframe)")));
        }
        (basis == 1, refactor)
    } else {
        (true, 1)
    };
    r.expect_end("config")?;
    if !(4..=30).contains(&bits) {
        return Err(r.malformed("config.bits", format!("{bits} is outside 4..=30")));
    }
    if !(1..=1000).contains(&bases) {
        return Err(r.malformed("config.bases", format!("{bases} is outside 1..=1000")));
    }
    if polar > 1 {
        return Err(r.malformed("config.polar", format!("{polar} is not 0 or 1")));
    }
    if !(8..=30).contains(&iframe_bits) {
        return Err(r.malformed("config.iframe_bits", format!("{iframe_bits} is outside 8..=30")));
    }
    // The harmonic basis (n × bases f64) and analysis matrices are the largest allocations;
    // with the connectivity's state they are held for the whole decode, so what is left of
    // the limits after them bounds everything else (the Poisson factor, the eigensolver).
    let n = info.vertex_count() as u64;
    let m = info.topology.triangle_count() as u64;
    let limits = limits
        .reserve(NAME, "bases", (n + m).saturating_mul((bases as u64).min(n)).saturating_mul(8))?
        .reserve(NAME, "topology", (n + m).saturating_mul(200))?;
    // The first keyframe computes the basis: refuse a crafted request (1000 bases on a
    // large mesh) from the header, before the connectivity's factorization.
    limits.check_work(NAME, "manifold harmonics basis", harmonics::work_estimate(n as usize, bases as usize))?;
    let settings = Settings {
        bits,
        bases,
        polar: polar == 1,
        iframe_bits,
        version: info.codec_version,
        basis_per_keyframe,
        refactor,
    };
    let shared = Shared::new(&info.topology, &limits, settings)?;
    let limits = shared.limits;
    Ok(Box::new(SacDecoder { shared, limits, gop: None, state: None, pending: None }))
}

pub(crate) fn decode_positions(r: &mut ByteReader<'_>, n: usize, bits: u8, limits: &Limits) -> Result<Vec<f32>> {
    let mut qs = Vec::with_capacity(3);
    for _ in 0..3 {
        let q = Quantizer::read(r, "positions.quantizer")?;
        if q.bits() != bits {
            return Err(r.malformed("positions.quantizer", format!("{} bits, stream config says {bits}", q.bits())));
        }
        qs.push(q);
    }
    let planes = (bits as usize).div_ceil(8);
    let count = n * 3;
    let len = count * planes;
    limits.check_alloc(NAME, "positions", len as u64)?;
    let raw = entropy::decompress(r.take(r.remaining(), "positions")?, NAME, "positions", len)?;
    if raw.len() != len {
        return Err(Error::malformed(NAME, "positions", format!("{} bytes, expected {len}", raw.len())));
    }
    Ok((0..count).map(|i| qs[i % 3].dequantize(plane_value(&raw, count, planes, i))).collect())
}

/// Reads and applies the spectral part (step 0: none).
fn decode_spectral(r: &mut ByteReader<'_>, rec: &mut [f32], basis: &Mat<f64>) -> Result<()> {
    let step = r.f32("residual.spectral_step")?;
    if !(step.is_finite() && step >= 0.0) {
        return Err(r.malformed("residual.spectral_step", format!("{step} is not a finite non-negative number")));
    }
    if step == 0.0 {
        return Ok(());
    }
    let l = basis.ncols();
    let block = r.length_prefixed("residual.spectral")?;
    let raw = entropy::decompress(block, NAME, "residual.spectral", 3 * l * 10)?;
    let mut cr = ByteReader::new(&raw, NAME);
    let max = (1i64 << 30) - 1;
    let mut codes = Vec::with_capacity(3 * l);
    for _ in 0..3 * l {
        let q = cr.varint_signed("residual.spectral")?;
        if q.abs() > max {
            return Err(cr.malformed("residual.spectral", format!("code {q} exceeds {max}")));
        }
        codes.push(q);
    }
    cr.expect_end("residual.spectral")?;
    apply_spectral(rec, basis, &codes, step as f64);
    Ok(())
}

/// Reads the residual layer of a version-2 P-frame and applies it to `rec`; every field is
/// checked and the only allocation is bounded by the vertex count.
fn decode_residual(r: &mut ByteReader<'_>, rec: &mut [f32], limits: &Limits) -> Result<()> {
    let step = r.f32("residual.step")?;
    if !(step.is_finite() && step >= 0.0) {
        return Err(r.malformed("residual.step", format!("{step} is not a finite non-negative number")));
    }
    if step == 0.0 {
        return Ok(());
    }
    let planes = r.u8("residual.planes")? as usize;
    if !(1..=4).contains(&planes) {
        return Err(r.malformed("residual.planes", format!("{planes} is outside 1..=4")));
    }
    let count = rec.len();
    let len = count * planes;
    limits.check_alloc(NAME, "residual", len as u64)?;
    let block = r.length_prefixed("residual")?;
    let raw = entropy::decompress(block, NAME, "residual", len)?;
    if raw.len() != len {
        return Err(Error::malformed(NAME, "residual", format!("{} bytes, expected {len}", raw.len())));
    }
    let step64 = step as f64;
    for (i, x) in rec.iter_mut().enumerate() {
        let q = codec_core::bytes::zigzag_decode(u64::from(plane_value(&raw, count, planes, i)));
        *x = (*x as f64 + q as f64 * step64) as f32;
    }
    Ok(())
}

pub(crate) struct SacDecoder {
    shared: Shared,
    limits: Limits,
    gop: Option<Gop>,
    /// Version 3: the last basis state, reused by keyframes that name the same rest pose.
    state: Option<Arc<BasisState>>,
    /// The basis the current interval's keyframe asked for, not computed yet: the first
    /// P-frame computes it once its descriptors decoded at the size the basis will have
    /// (a config asking for more bases than the stream codes
    /// used to cost the whole basis before the descriptors were found malformed).
    pending: Option<PendingBasis>,
}

/// A keyframe's basis request ([`SacDecoder::pending`]).
struct PendingBasis {
    /// The decoded rest pose and its stored block (version 3's cache key; empty before).
    rest: Vec<f32>,
    rest_block: Vec<u8>,
    /// The number of vectors the basis will have ([`Shared::expected_bases`]).
    bases: usize,
}

impl SacDecoder {
    /// Parses a keyframe's basis fields after `has_bases` and its positions, and returns the
    /// decoded frame and the interval's basis state.
    fn keyframe(&mut self, r: &mut ByteReader<'_>, with_basis: bool) -> Result<(Vec<f32>, Arc<BasisState>)> {
        let s = &self.shared;
        let bits = s.settings.iframe_bits;
        if s.settings.version < 3 {
            let block = r.take(r.remaining(), "positions")?;
            let rec = decode_positions(&mut ByteReader::new(block, NAME), s.n, bits, &self.limits)?;
            // The basis waits for the interval's first P-frame (`pending`).
            let state = s.basis_state(&rec, Vec::new(), Some(false), false)?;
            self.pending = (with_basis && !s.tris.is_empty()).then(|| PendingBasis {
                bases: s.expected_bases(&rec),
                rest: rec.clone(),
                rest_block: Vec::new(),
            });
            return Ok((rec, Arc::new(state)));
        }
        let named = match r.u8("rest_source")? {
            0 => None,
            1 if s.settings.basis_per_keyframe => {
                return Err(r.malformed("rest_source", "a keyframe-basis stream names no rest pose"))
            }
            1 if !with_basis => return Err(r.malformed("rest_source", "a rest pose for a keyframe without bases")),
            1 => Some(r.length_prefixed("rest")?),
            b => return Err(r.malformed("rest_source", format!("{b} is not 0 (this frame) or 1 (named)"))),
        };
        let own = r.take(r.remaining(), "positions")?;
        let rec = decode_positions(&mut ByteReader::new(own, NAME), s.n, bits, &self.limits)?;
        let rest_block = named.unwrap_or(own);
        if let Some(cached) = &self.state {
            if with_basis && cached.has_bases() && cached.rest_block == rest_block {
                return Ok((rec, cached.clone()));
            }
        }
        // Without a basis the state is final; with one, the basis waits for the interval's
        // first P-frame (`pending`), which caches it in `self.state`.
        let state = Arc::new(s.basis_state(&rec, Vec::new(), Some(false), false)?);
        if with_basis && !s.tris.is_empty() {
            let rest = match named {
                Some(_) => decode_positions(&mut ByteReader::new(rest_block, NAME), s.n, bits, &self.limits)?,
                None => rec.clone(),
            };
            self.pending = Some(PendingBasis { bases: s.expected_bases(&rest), rest, rest_block: rest_block.to_vec() });
        } else {
            self.state = Some(state.clone());
        }
        Ok((rec, state))
    }
}

impl FrameDecoder for SacDecoder {
    fn decode_packet(&mut self, packet: &Packet) -> Result<Vec<f32>> {
        if packet.frame_count != 1 {
            return Err(Error::malformed(
                NAME,
                "packet",
                format!("{} frames; sac packets hold one", packet.frame_count),
            ));
        }
        let mut r = ByteReader::new(&packet.data, NAME);
        let kind = r.u8("kind")?;
        match kind {
            KIND_I => {
                if !packet.keyframe {
                    return Err(r.malformed("kind", "I-frame in a packet not flagged as keyframe"));
                }
                let with_basis = match r.u8("has_bases")? {
                    0 => false,
                    1 => true,
                    b => return Err(r.malformed("has_bases", format!("{b} is not 0 or 1"))),
                };
                self.pending = None;
                let (rec, state) = self.keyframe(&mut r, with_basis)?;
                self.gop = Some(self.shared.start_gop(&rec, state));
                Ok(rec)
            }
            KIND_REFRESH | KIND_P => {
                let s = &self.shared;
                let Some(gop) = self.gop.as_mut() else {
                    return Err(r.malformed("kind", "a P-frame before any keyframe"));
                };
                if kind == KIND_REFRESH {
                    let rec = decode_positions(&mut r, s.n, s.settings.iframe_bits, &self.limits)?;
                    set_v3(&mut gop.prev, &rec);
                    return Ok(rec);
                }
                let l = match &self.pending {
                    Some(p) => p.bases,
                    None if gop.state.has_bases() => gop.state.bases(),
                    None => return Err(r.malformed("kind", "a P-frame in an interval without bases")),
                };
                let groups = s.settings.groups();
                let mut amps = Vec::with_capacity(groups.len());
                for _ in groups {
                    let a = r.f32("amplitude")?;
                    if !(a.is_finite() && a >= 0.0) {
                        return Err(r.malformed("amplitude", format!("{a} is not a finite non-negative number")));
                    }
                    amps.push(a);
                }
                let comps = s.components();
                if r.remaining() < comps * 12 {
                    return Err(r.truncated("translations"));
                }
                let mut shifts = Vec::with_capacity(comps);
                for _ in 0..comps {
                    let mut sh = [0.0f32; 3];
                    for x in sh.iter_mut() {
                        *x = r.finite_f32("translation")?;
                    }
                    shifts.push(sh);
                }
                // Version 1 streams have no residual layer; version 2 always has its step.
                let mut residual = None;
                if s.settings.version >= 2 {
                    let start = r.position();
                    if r.f32("residual.spectral_step")? != 0.0 {
                        r.length_prefixed("residual.spectral")?;
                    }
                    if r.f32("residual.step")? != 0.0 {
                        r.u8("residual.planes")?;
                        r.length_prefixed("residual")?;
                    }
                    residual = Some(&packet.data[start..r.position()]);
                }
                let sizes: Vec<usize> = groups.iter().map(|&c| c * l).collect();
                let rest = r.take(r.remaining(), "descriptors")?;
                let mut contexts = gop.contexts.clone();
                let codes = coding::decode(rest, &sizes, l, &mut contexts)?;
                if let Some(p) = self.pending.take() {
                    // The descriptors fit a basis of `l` vectors: now compute it.
                    self.limits = self.limits.spend(NAME, "manifold harmonics basis of a keyframe", s.basis_work())?;
                    let state = s.basis_state(&p.rest, p.rest_block, Some(true), false)?;
                    if state.bases() != l {
                        return Err(Error::malformed(
                            NAME,
                            "bases",
                            format!("the rest pose has {} basis vectors, {l} expected", state.bases()),
                        ));
                    }
                    let state = Arc::new(state);
                    if s.settings.version >= 3 {
                        self.state = Some(state.clone());
                    }
                    gop.state = state;
                }
                self.limits = self.limits.spend(NAME, "P-frame reconstruction", s.frame_work(l))?;
                s.reconstruct(gop, &codes, &amps)?;
                let mut rec = s.translate(&gop.work.solved, &shifts);
                if let Some(bytes) = residual {
                    let mut rr = ByteReader::new(bytes, NAME);
                    let basis = gop.state.vertex_basis().ok_or_else(|| rr.malformed("residual", "no basis"))?;
                    decode_spectral(&mut rr, &mut rec, &basis.h)?;
                    decode_residual(&mut rr, &mut rec, &self.limits)?;
                    rr.expect_end("residual")?;
                }
                if rec.iter().any(|x| !x.is_finite()) {
                    return Err(Error::malformed(NAME, "packet", "decoded positions are not finite"));
                }
                gop.contexts = contexts;
                gop.p_count += 1;
                set_v3(&mut gop.prev, &rec);
                Ok(rec)
            }
            k => Err(r.malformed("kind", format!("{k} is not a frame kind (0 = I, 1 = P, 2 = refresh)"))),
        }
    }

    fn reset(&mut self) {
        self.gop = None;
        self.pending = None;
    }
}
