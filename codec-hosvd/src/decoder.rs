//! The decoder: one packet at a time, every stream version from 1 to [`crate::STREAM_VERSION`].
//! Sizes and work are checked against the caller's [`Limits`] before anything is allocated.

use codec_core::bytes::ByteReader;
use codec_core::toolkit::order::{self, CausalGraph};
use codec_core::toolkit::predict::Predictor;
use codec_core::toolkit::regress::Neighbourhoods;
use codec_core::{entropy, Error, FrameDecoder, Limits, Packet, ParsedPacket, Result, StreamInfo};

use crate::memory::decode_work;
use crate::tensor::{Affine, Model, Prepared};
use crate::{coding, motion, paper};
use crate::{
    CENTRE_BYTES, FLAG_CENTRE, FLAG_DENOISE, FLAG_MOTION, FLAG_REGRESS, FLAG_RELSTEP, FLAG_TOOLKIT, NAME,
    STREAM_VERSION,
};

/// The decoder's mesh coding order: none in version 1 streams, built lazily in version 2.
enum MeshOrder {
    Unavailable,
    Pending(Vec<[u32; 3]>),
    Built(CausalGraph),
}

struct HosvdDecoder {
    k: usize,
    limits: Limits,
    /// Mesh coding order (stream version 2 only).
    graph: MeshOrder,
    /// Stream version (3 allows [`FLAG_MOTION`]).
    version: u16,
    /// The last packet parsed, for further frames of it.
    parsed: ParsedPacket<Parsed>,
}

/// [`AnimationCodec::new_decoder`](codec_core::AnimationCodec::new_decoder): reads the stream
/// configuration (the frames per block, untrusted) and accepts stream versions 1 to
/// [`STREAM_VERSION`].
pub(crate) fn new_decoder(info: &StreamInfo, config: &[u8], limits: &Limits) -> Result<Box<dyn FrameDecoder>> {
    let mut r = ByteReader::new(config, NAME);
    let block = r.u32("config.block")?;
    r.expect_end("config")?;
    if block == 0 {
        return Err(r.malformed("config.block", "0 frames per block"));
    }
    if !(1..=STREAM_VERSION).contains(&info.codec_version) {
        return Err(Error::Unsupported {
            context: NAME.into(),
            detail: format!("stream version {} (this build decodes 1 to {STREAM_VERSION})", info.codec_version),
        });
    }
    // Version 2 packets may use the toolkit coding, which needs the mesh's coding order:
    // built on the first packet that uses it, after checking its size against the limits.
    let graph = if info.codec_version >= 2 {
        MeshOrder::Pending(info.topology.triangles().to_vec())
    } else {
        MeshOrder::Unavailable
    };
    Ok(Box::new(HosvdDecoder {
        k: info.vertex_count(),
        limits: *limits,
        graph,
        version: info.codec_version,
        parsed: ParsedPacket::default(),
    }))
}

impl HosvdDecoder {
    /// The mesh coding order, built on first use once its size passed the limits.
    fn mesh_order(&mut self) -> Result<&CausalGraph> {
        if let MeshOrder::Pending(triangles) = &self.graph {
            let bytes = order::mesh_bytes(self.k, triangles.len());
            self.limits.check_alloc(NAME, "mesh coding order", bytes)?;
            self.graph = MeshOrder::Built(CausalGraph::mesh(self.k, triangles));
        }
        match &self.graph {
            MeshOrder::Built(graph) => Ok(graph),
            _ => Err(Error::malformed(NAME, "flags", "toolkit coding in a version 1 stream")),
        }
    }
}

/// What a packet's flags byte says: bit 0 motion removed (`rigid`), then the `FLAG_*` bits.
#[derive(Debug, Clone, Copy)]
struct Flags {
    rigid: bool,
    toolkit: bool,
    coded_motion: bool,
    denoise: bool,
    regress: bool,
    relstep: bool,
}

/// A packet's header: its flags, frame count and ranks.
#[derive(Debug, Clone, Copy)]
struct Header {
    flags: Flags,
    frames: usize,
    v: usize,
    f: usize,
}

impl HosvdDecoder {
    /// The flag bits the stream's version defines: bit 0 in every version, [`FLAG_TOOLKIT`]
    /// from version 2, [`FLAG_MOTION`] and [`FLAG_DENOISE`] from 3, [`FLAG_REGRESS`] from 4,
    /// [`FLAG_RELSTEP`] from 7
    /// ([`FLAG_CENTRE`] is taken off before, by [`FrameDecoder::decode_packet`]).
    fn known_flags(&self) -> u8 {
        match (&self.graph, self.version) {
            (MeshOrder::Unavailable, _) => 1,
            (_, v) if v >= 7 => 1 | FLAG_TOOLKIT | FLAG_MOTION | FLAG_DENOISE | FLAG_REGRESS | FLAG_RELSTEP,
            (_, v) if v >= 4 => 1 | FLAG_TOOLKIT | FLAG_MOTION | FLAG_DENOISE | FLAG_REGRESS,
            (_, 3) => 1 | FLAG_TOOLKIT | FLAG_MOTION | FLAG_DENOISE,
            _ => 1 | FLAG_TOOLKIT,
        }
    }

    /// Reads the flags byte: bits the stream's version does not define, and combinations the
    /// encoder never writes, are errors.
    fn read_flags(&self, r: &mut ByteReader<'_>) -> Result<Flags> {
        let flags = r.u8("flags")?;
        if flags & !self.known_flags() != 0 {
            return Err(r.malformed("flags", format!("{flags:#04x} has unknown bits")));
        }
        let rigid = flags & 1 == 1;
        let toolkit = flags & FLAG_TOOLKIT != 0;
        let coded_motion = flags & FLAG_MOTION != 0;
        if coded_motion && !(rigid && toolkit) {
            return Err(r.malformed("flags", format!("{flags:#04x}: coded motion without rigid toolkit coding")));
        }
        let denoise = flags & FLAG_DENOISE != 0;
        if denoise && !toolkit {
            return Err(r.malformed("flags", format!("{flags:#04x}: denoising without toolkit coding")));
        }
        let regress = flags & FLAG_REGRESS != 0;
        if regress && !toolkit {
            return Err(r.malformed("flags", format!("{flags:#04x}: regression without toolkit coding")));
        }
        let relstep = flags & FLAG_RELSTEP != 0;
        if relstep && !toolkit {
            return Err(r.malformed("flags", format!("{flags:#04x}: step scales without toolkit coding")));
        }
        Ok(Flags { rigid, toolkit, coded_motion, denoise, regress, relstep })
    }

    /// A packet without `FLAG_CENTRE` (every packet of versions 1 to 5; a version 6 packet
    /// after [`HosvdDecoder::parse`] took its centre off), up to the last step of its
    /// reconstruction.
    fn parse_uncentred(&mut self, packet: &Packet) -> Result<Prepared> {
        let (k, frames) = (self.k, packet.frame_count as usize);
        if k == 0 || frames == 0 {
            return Err(Error::malformed(NAME, "packet", "no vertices or no frames"));
        }
        let mut r = ByteReader::new(&packet.data, NAME);
        let flags = self.read_flags(&mut r)?;
        let (v, f) = read_ranks(&mut r, k, frames)?;
        let h = Header { flags, frames, v, f };
        // Every f64 array below, checked before allocating.
        // (U1, U3, core, plus the reconstruction's two intermediates: C·U2 and D = v × 3 × F).
        let doubles = (k as u64 * v as u64)
            .saturating_add(frames as u64 * f as u64)
            .saturating_add(6 * v as u64 * f as u64)
            .saturating_add(3 * frames as u64 * v as u64);
        self.limits.check_alloc(NAME, "factors", doubles.saturating_mul(8))?;
        // The work is known from `K`, the frames and the ranks before anything is inflated or
        // decoded: a stream of a few hundred bytes asking for ~10^11 multiply-adds is refused
        // here when they exceed `--max-work`.
        self.limits = self.limits.spend(NAME, "reconstruction", decode_work(k, frames, v, f, flags.toolkit))?;
        let predictors = if flags.toolkit {
            let mut predictor = |field| {
                let c = r.u8(field)?;
                Predictor::from_code(c).ok_or_else(|| r.malformed(field, format!("unknown predictor {c}")))
            };
            (predictor("mesh_predictor")?, predictor("time_predictor")?)
        } else {
            (Predictor::Zero, Predictor::Zero)
        };
        let side_len = 36
            + if flags.rigid && !flags.coded_motion { 48 * frames } else { 0 }
            + if flags.toolkit { 4 * (2 * v + f) } else { 9 * (v + f + 1) };
        self.limits.check_alloc(NAME, "side", side_len as u64)?;
        let side_block = r.length_prefixed("side")?;
        let side = entropy::decompress(side_block, NAME, "side", side_len)?;
        if side.len() != side_len {
            return Err(Error::malformed(NAME, "side", format!("{} bytes, expected {side_len}", side.len())));
        }
        let mut s = ByteReader::new(&side, NAME);
        let mut u2 = [0.0f64; 9];
        for x in &mut u2 {
            *x = s.finite_f32("u2")? as f64;
        }
        let transforms = if flags.rigid && !flags.coded_motion {
            let mut out = Vec::with_capacity(frames);
            for _ in 0..frames {
                let mut a = Affine::IDENTITY;
                for x in a.m.iter_mut().chain(a.c.iter_mut()) {
                    *x = s.finite_f32("transform")?;
                }
                out.push(a);
            }
            out
        } else if flags.coded_motion {
            // Decoded from the motion block after the codes, once its size is checked.
            Vec::new()
        } else {
            vec![Affine::IDENTITY; frames]
        };
        let (u1, u3, core, transforms) = if flags.toolkit {
            self.decode_toolkit(&mut r, &mut s, &h, predictors, transforms)?
        } else {
            let (u1, u3, core) = paper::decode(&mut r, &mut s, k, frames, v, f, &self.limits)?;
            (u1, u3, core, transforms)
        };
        let model = Model { k, frames, v, f, u1, u2, u3, core, transforms };
        Ok(Prepared::new(&model))
    }

    /// The rest of a toolkit-coded packet after its side block's `U2` and transforms: the
    /// steps (end of `s`), the arithmetic-coded operator ([`coding::decode`]), the coded motion,
    /// smoothing levels and column modes its flags announce. Returns `U1` (smoothed when
    /// `FLAG_DENOISE` is set), `U3`, the core and the per-frame transforms.
    #[allow(clippy::type_complexity)]
    fn decode_toolkit(
        &mut self,
        r: &mut ByteReader<'_>,
        s: &mut ByteReader<'_>,
        h: &Header,
        (mesh_predictor, time_predictor): (Predictor, Predictor),
        transforms: Vec<Affine>,
    ) -> Result<(Vec<f64>, Vec<f64>, Vec<f64>, Vec<Affine>)> {
        let Header { flags, frames, v, f } = *h;
        let steps = (0..2 * v + f).map(|_| s.finite_f32("steps")).collect::<Result<Vec<f32>>>()?;
        s.expect_end("side")?;
        if let Some(bad) = steps.iter().find(|x| **x < 0.0) {
            return Err(Error::malformed(NAME, "steps", format!("negative step {bad}")));
        }
        let bytes = r.length_prefixed("codes")?;
        let transforms = if flags.coded_motion {
            self.limits.check_alloc(NAME, "motion", 48 * frames as u64)?;
            motion::decode(r.length_prefixed("motion")?, frames)?
        } else {
            transforms
        };
        let smoothing = if flags.denoise { Some(r.take(v, "smoothing")?.to_vec()) } else { None };
        let modes = if flags.regress { Some(r.take(v, "column modes")?.to_vec()) } else { None };
        let relstep = if flags.relstep {
            let strength = r.u8("relstep")?;
            let max = coding::relstep::MAX_STRENGTH;
            if strength == 0 || strength > max {
                return Err(r.malformed("relstep", format!("strength {strength} is outside 1..={max}")));
            }
            if v <= coding::relstep::SCALED_FROM {
                let n = coding::relstep::SCALED_FROM;
                return Err(r.malformed("relstep", format!("step scales with v = {v} (no column after the first {n})")));
            }
            let mut gains = [0.0f32; coding::relstep::LEADS];
            for g in &mut gains {
                *g = r.finite_f32("relstep gains")?;
            }
            Some((strength, gains))
        } else {
            None
        };
        r.expect_end("packet")?;
        if modes.as_ref().is_some_and(|x| x.contains(&(coding::ColumnMode::Regression as u8))) {
            self.limits.check_alloc(NAME, "regression neighbourhoods", Neighbourhoods::bytes(self.k))?;
        }
        if relstep.is_some() {
            // Per-vertex scales: embedding, lengths and scales (40 bytes a vertex) and the
            // mesh adjacency (the smoother's size), within 64 bytes a vertex plus the adjacency.
            self.limits.check_alloc(NAME, "step scales", 64 * self.k as u64)?;
        }
        // Version 5's guarded regression; version 4 streams keep their arithmetic.
        let guarded = self.version >= 5;
        let graph = self.mesh_order()?;
        let (mut u1, u3, core) = coding::decode(
            bytes,
            graph,
            mesh_predictor,
            time_predictor,
            frames,
            v,
            f,
            &steps,
            modes.as_deref(),
            guarded,
            relstep.map(|(strength, gains)| coding::StepScales { strength, gains, levels: smoothing.as_deref() }),
        )?;
        if let Some(levels) = smoothing {
            coding::Smoother::new(graph).apply_columns(graph, &mut u1, v, &levels)?;
        }
        Ok((u1, u3, core, transforms))
    }
}

/// Reads the ranks `v` and `f` of a packet of `frames` frames of `k` vertices: each at least 1
/// and at most what the tensor's unfoldings allow (`min(K, 3F)`, `min(F, 3K)`).
fn read_ranks(r: &mut ByteReader<'_>, k: usize, frames: usize) -> Result<(usize, usize)> {
    let vmax = k.min(3 * frames);
    let fmax = frames.min(3 * k);
    let v = r.varint("v")?;
    if v == 0 || v > vmax as u64 {
        return Err(r.malformed("v", format!("{v} is outside 1..={vmax}")));
    }
    let f = r.varint("f")?;
    if f == 0 || f > fmax as u64 {
        return Err(r.malformed("f", format!("{f} is outside 1..={fmax}")));
    }
    Ok((v as usize, f as usize))
}

/// A packet parsed up to the last step of its reconstruction, and the centre its frames get
/// (stream version 6).
struct Parsed {
    prepared: Prepared,
    centre: Option<[f32; 3]>,
}

impl Parsed {
    /// Frames `t` for `t` in `frames` (all of them, or one), with the centre added.
    fn finish(&self, mut out: Vec<f32>) -> Result<Vec<f32>> {
        if let Some(centre) = self.centre {
            add_centre(&mut out, centre)?;
        }
        Ok(out)
    }
}

impl HosvdDecoder {
    /// Stream version 6: a packet with `FLAG_CENTRE` ends with the centre the encoder
    /// subtracted; the rest, with that flag cleared, is a version 5 packet. The centre is added
    /// to every decoded coordinate ([`add_centre`]).
    fn parse(&mut self, packet: &Packet) -> Result<Parsed> {
        let centred = packet.data.first().is_some_and(|&flags| flags & FLAG_CENTRE != 0);
        if !centred {
            return Ok(Parsed { prepared: self.parse_uncentred(packet)?, centre: None });
        }
        if self.version < 6 {
            return Err(Error::malformed(
                NAME,
                "flags",
                format!("{:#04x}: a centre in a version {} stream", packet.data[0], self.version),
            ));
        }
        let Some(split) = packet.data.len().checked_sub(CENTRE_BYTES).filter(|&n| n >= 1) else {
            return Err(Error::malformed(NAME, "centre", "the packet is too short to hold its centre"));
        };
        let mut r = ByteReader::new(&packet.data[split..], NAME);
        let mut centre = [0.0f32; 3];
        for c in &mut centre {
            *c = r.finite_f32("centre")?;
        }
        let mut data = packet.data[..split].to_vec();
        data[0] &= !FLAG_CENTRE;
        let inner = Packet { data, ..*packet };
        Ok(Parsed { prepared: self.parse_uncentred(&inner)?, centre: Some(centre) })
    }

    /// `packet` parsed: kept from an earlier call when it is a kept packet.
    fn parsed(&mut self, packet: &Packet) -> Result<&Parsed> {
        if !self.parsed.holds(packet) {
            let parsed = self.parse(packet)?;
            let bytes = parsed.prepared.bytes();
            return Ok(self.parsed.keep(packet, parsed, bytes));
        }
        self.parsed.get(packet).ok_or_else(|| Error::malformed(NAME, "packet", "not parsed"))
    }
}

impl FrameDecoder for HosvdDecoder {
    /// Uses the kept parse when `packet` is a packet asked a frame of; otherwise parses without
    /// keeping it (sequential decoding holds no more than one packet's model).
    fn decode_packet(&mut self, packet: &Packet) -> Result<Vec<f32>> {
        if let Some(parsed) = self.parsed.get(packet) {
            return parsed.finish(parsed.prepared.frames());
        }
        let parsed = self.parse(packet)?;
        parsed.finish(parsed.prepared.frames())
    }

    /// Every packet decodes alone; frame `t` is `U1` against that frame's loadings
    /// (`U2 · core · row t of U3`) and mapped by its transform, once the packet is parsed.
    fn decode_frame_of_packet(&mut self, packet: &Packet, local: usize) -> Result<Vec<f32>> {
        if local >= packet.frame_count as usize {
            return Err(codec_core::codec::frame_outside_packet(packet, local));
        }
        let parsed = self.parsed(packet)?;
        parsed.finish(parsed.prepared.frame(local))
    }

    fn decodes_single_frames(&self) -> bool {
        true
    }

    fn keep_parsed_packets(&mut self, bytes: u64) {
        self.parsed.set_budget(bytes);
    }
}

/// Adds the packet's centre to every decoded vertex (`F × K × 3`), in f64 then rounded to f32,
/// as the encoder's reconstruction does; a sum that is not finite is an error.
pub(crate) fn add_centre(out: &mut [f32], centre: [f32; 3]) -> Result<()> {
    for p in out.chunks_exact_mut(3) {
        for j in 0..3 {
            p[j] = (p[j] as f64 + centre[j] as f64) as f32;
        }
    }
    match out.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(Error::malformed(NAME, "centre", format!("decoded coordinate {i} is not finite"))),
        None => Ok(()),
    }
}
