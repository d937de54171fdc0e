//! `laplacian`: trajectory PCA whose coefficient fields are coded in the domain of the
//! cotangent Laplacian of the decoded average mesh, after Váša, Marras, Hormann & Brunnett,
//! *Compressing dynamic meshes with geometric Laplacians* (Eurographics 2014). No source of the
//! paper's coder is public; `README.md` says where this reconstruction had to choose.
//!
//! Per packet (the whole sequence by default, or temporal blocks of `block` frames; every
//! packet decodes alone), `packet.rs`:
//! 1. the average mesh (the frame mean of the positions), coded once along the mesh's coding
//!    order with parallelogram prediction;
//! 2. the trajectory matrix (V × 3F, a row per vertex) minus the decoded average mesh, minus
//!    its mean row (the centroid's motion, coded along time);
//! 3. its N leading right singular vectors (the temporal basis), quantized column by column;
//! 4. the V × N coefficient fields (least squares on the decoded basis), each coded as the
//!    quantized `δ = L·c` of the free vertices, `L` the cotangent Laplacian of the decoded
//!    average mesh (`operator.rs`), with one anchor every `spacing` vertices held at a finely
//!    quantized value: the decoder solves the Dirichlet problem `L_ff c_f = δ̂ + W_fa ĉ_a`, so the
//!    quantization error is smooth over the surface and cannot drift beyond the anchors.
//!
//! Declared error bound ([`AnimationCodec::error_bound`](codec_core::AnimationCodec::error_bound), `bound.rs`): the RMS error is at most
//! the RMS distance of the vertices to their frame's centroid (plus `f32` rounding), relative
//! to the bounding-box diagonal: every packet's squared error is kept within its centred
//! energy, by finer steps or, failing that, a raw packet.
//!
//! Modules: `params` (the parameters), `packet` (layout, encoder, decoder of one packet),
//! `operator` (Laplacian, anchors, the envelope Cholesky), `bound` (the declared bound),
//! `memory` (the encoder's memory and the packet's work).

mod bound;
mod memory;
mod operator;
mod packet;
mod params;

use codec_core::codec::{
    EncodedPacket, EncoderSetup, ErrorBound, FourCc, FrameDecoder, FrameEncoder, Packet, ParsedPacket, StreamInfo,
    TypedCodec,
};
use codec_core::params::{RateLadder, SearchAxis, SearchSpace, Setting};
use codec_core::toolkit::order::{mesh_bytes, CausalGraph};
use codec_core::{Animation, Error, Limits, Result};

pub use memory::block_memory;
pub use params::{LaplacianParams, MAX_RANK};

/// Name on the command line and in parameter sets.
const NAME: &str = "laplacian";

/// Version of the bitstream this encoder writes.
const STREAM_VERSION: u16 = 1;

/// Coordinates beyond ±2^100 are refused: steps and reconstructions then stay far inside the
/// `f32` range.
const MAX_MAGNITUDE: f64 = 1.2676506002282294e30;

/// The `laplacian` codec.
#[derive(Debug, Clone, Copy, Default)]
pub struct Laplacian;

impl TypedCodec for Laplacian {
    type Params = LaplacianParams;
    const NAME: &'static str = NAME;
    const FOURCC: FourCc = FourCc::new(b"LAPL");
    const STREAM_VERSION: u16 = STREAM_VERSION;
    const SUMMARY: &'static str =
        "trajectory PCA, coefficient fields coded as cotangent-Laplacian deltas with anchors (Vasa et al. 2014)";

    fn ladder(&self, _base: &LaplacianParams) -> RateLadder {
        // From small streams to large: the coefficient step (and with it the rank, the basis
        // and mean steps) shrinks by about half an octave per rung.
        let steps = [0.05, 0.03, 0.02, 0.012, 8e-3, 5e-3, 3e-3, 2e-3, 1.2e-3, 8e-4, 5e-4, 3e-4, 2e-4, 1e-4, 5e-5, 2e-5];
        RateLadder::over(LaplacianParams::step, steps)
    }
    /// The ladder over `step`, with and without the Laplacian domain (so a sweep measures the
    /// Laplacian lever against direct coding at equal bits, and a target search keeps the
    /// smaller).
    fn space(&self, base: &LaplacianParams) -> SearchSpace {
        SearchSpace {
            primary: self.ladder(base),
            secondary: vec![SearchAxis::over(LaplacianParams::laplacian, [true, false])],
        }
    }
    fn blocks(&self, p: &LaplacianParams, frame_count: usize) -> Result<usize> {
        Ok(if p.block == 0 { frame_count.max(1) } else { p.block as usize })
    }
    /// With `block=0`, the frames per block that fit `budget` by [`block_memory`]; an explicit
    /// `block` is kept.
    fn fit(&self, p: &LaplacianParams, vertices: usize, frames: usize, budget: u64) -> Result<Vec<Setting>> {
        if p.block != 0 || frames == 0 {
            return Ok(Vec::new());
        }
        let Some(block) = memory::block_for_budget(vertices, frames, budget)? else {
            return Ok(Vec::new());
        };
        Ok(vec![LaplacianParams::block.to(u32::try_from(block).unwrap_or(u32::MAX))])
    }
    fn bound(&self, _params: &LaplacianParams, animation: &Animation) -> Result<ErrorBound> {
        let mut stats = bound::BoundStats::new(animation.vertex_count());
        stats.push(animation.positions());
        Ok(stats.bound())
    }
    fn encoder(&self, params: LaplacianParams, setup: &EncoderSetup<'_>) -> Result<Box<dyn FrameEncoder>> {
        let topology = setup.topology;
        let graph = CausalGraph::mesh(topology.vertex_count(), topology.triangles());
        let block = if params.block == 0 { setup.frame_count.max(1) } else { params.block as usize };
        Ok(Box::new(LaplacianEncoder {
            params,
            graph,
            triangles: topology.triangles().to_vec(),
            block,
            want_reconstruction: setup.want_reconstruction,
            pending: Vec::new(),
            next_frame: 0,
            stats: bound::BoundStats::new(topology.vertex_count()),
        }))
    }
    fn decoder(&self, info: &StreamInfo, config: &[u8], limits: &Limits) -> Result<Box<dyn FrameDecoder>> {
        if info.codec_version != STREAM_VERSION {
            return Err(Error::malformed(
                NAME,
                "stream version",
                format!("{} (this build decodes {STREAM_VERSION})", info.codec_version),
            ));
        }
        ByteReader::new(config, NAME).expect_end("config")?;
        let topology = &info.topology;
        limits.check_alloc(NAME, "vertex order", mesh_bytes(topology.vertex_count(), topology.triangles().len()))?;
        let graph = CausalGraph::mesh(topology.vertex_count(), topology.triangles());
        Ok(Box::new(LaplacianDecoder {
            graph,
            triangles: topology.triangles().to_vec(),
            limits: *limits,
            parsed: ParsedPacket::default(),
        }))
    }
}

use codec_core::bytes::ByteReader;

struct LaplacianEncoder {
    params: LaplacianParams,
    graph: CausalGraph,
    triangles: Vec<[u32; 3]>,
    block: usize,
    want_reconstruction: bool,
    pending: Vec<f32>,
    next_frame: u32,
    stats: bound::BoundStats,
}

impl LaplacianEncoder {
    fn frames_pending(&self) -> usize {
        self.pending.len() / (self.graph.len() * 3).max(1)
    }

    fn encode_block(&mut self, frames: usize) -> Result<EncodedPacket> {
        let n = self.graph.len();
        let block: Vec<f32> = self.pending.drain(..frames * n * 3).collect();
        let coded = packet::encode(&self.params, &self.graph, &self.triangles, &block)?;
        let packet =
            Packet { first_frame: self.next_frame, frame_count: frames as u32, keyframe: true, data: coded.bytes };
        self.next_frame += frames as u32;
        Ok(EncodedPacket { packet, reconstruction: self.want_reconstruction.then_some(coded.frames) })
    }
}

impl FrameEncoder for LaplacianEncoder {
    fn config(&self) -> Vec<u8> {
        Vec::new()
    }

    fn push_frames(&mut self, frames: &[f32]) -> Result<Vec<EncodedPacket>> {
        if let Some(x) = frames.iter().find(|x| (x.abs() as f64) > MAX_MAGNITUDE) {
            return Err(Error::parameter(NAME, "input", format!("coordinate {x} is beyond this codec's ±2^100")));
        }
        self.stats.push(frames);
        self.pending.extend_from_slice(frames);
        let mut out = Vec::new();
        while !self.graph.is_empty() && self.frames_pending() >= self.block {
            out.push(self.encode_block(self.block)?);
        }
        Ok(out)
    }

    fn finish(&mut self) -> Result<Vec<EncodedPacket>> {
        let n = self.frames_pending();
        Ok(if n > 0 { vec![self.encode_block(n)?] } else { Vec::new() })
    }

    fn declared_bound(&self) -> Option<ErrorBound> {
        Some(self.stats.bound())
    }
}

struct LaplacianDecoder {
    graph: CausalGraph,
    triangles: Vec<[u32; 3]>,
    limits: Limits,
    /// The last packet parsed, for further frames of it.
    parsed: ParsedPacket<packet::Parsed>,
}

impl LaplacianDecoder {
    /// `packet` up to its frames.
    fn parse(&self, packet: &Packet) -> Result<packet::Parsed> {
        if !packet.keyframe {
            return Err(Error::malformed(NAME, "packet", "every packet of this codec is a keyframe".to_owned()));
        }
        packet::parse(&packet.data, &self.graph, &self.triangles, packet.frame_count as usize, &self.limits)
    }

    /// `packet` up to its frames: kept from an earlier call when it is a kept packet.
    fn parsed(&mut self, packet: &Packet) -> Result<&packet::Parsed> {
        if !self.parsed.holds(packet) {
            let parsed = self.parse(packet)?;
            let bytes = parsed.bytes();
            return Ok(self.parsed.keep(packet, parsed, bytes));
        }
        self.parsed.get(packet).ok_or_else(|| Error::malformed(NAME, "packet", "not parsed"))
    }
}

impl FrameDecoder for LaplacianDecoder {
    /// Uses the kept parse when `packet` is a packet asked a frame of; otherwise parses without
    /// keeping it (sequential decoding holds no more than one packet's planes).
    fn decode_packet(&mut self, packet: &Packet) -> Result<Vec<f32>> {
        if let Some(parsed) = self.parsed.get(packet) {
            return parsed.all_frames();
        }
        self.parse(packet)?.all_frames()
    }

    /// Every packet decodes alone; a frame is one row of the temporal basis (and of the
    /// centroid trajectory) against the coefficients, once the packet is parsed.
    fn decode_frame_of_packet(&mut self, packet: &Packet, local: usize) -> Result<Vec<f32>> {
        if local >= packet.frame_count as usize {
            return Err(codec_core::codec::frame_outside_packet(packet, local));
        }
        self.parsed(packet)?.frame(local)
    }

    fn decodes_single_frames(&self) -> bool {
        true
    }

    fn keep_parsed_packets(&mut self, bytes: u64) {
        self.parsed.set_budget(bytes);
    }
}

#[cfg(test)]
mod tests;
