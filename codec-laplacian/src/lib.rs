//! `laplacian`: closed-loop predictive quantization of vertex positions, coded with the coding
//! toolkit's adaptive arithmetic coder.
//!
//! Made by `cargo xtask new-codec` as the starting point of a new codec: small, but a real codec
//! that passes the whole conformance suite, so every change can be checked against it. Replace
//! the method, keep the structure (README "Adding a codec").
//!
//! Per packet of `block` frames (every packet is a keyframe, so any packet decodes alone):
//! 1. One uniform step for the packet: `step` × the diagonal of the packet's bounding box
//!    (stored as `f32` in the packet).
//! 2. The packet's first frame, axis by axis, in the breadth-first vertex order of
//!    [`CausalGraph::mesh`], each vertex predicted from already *reconstructed* neighbours by
//!    the parallelogram rule ([`Predictor::Parallelogram`]); every later frame predicted from
//!    the reconstructed frames before it (the previous frame, then linear extrapolation
//!    `2·x̂[t−1] − x̂[t−2]`). Only the residual is quantized (`predict::quantize_one`), so the
//!    decoder, running the same prediction on the same reconstructions, agrees bit for bit and
//!    every coordinate is within half a step.
//! 3. The integer codes go through [`AdaptiveEncoder`], with the axis and the frame kind
//!    (spatial or temporal prediction) as class and the magnitude of the vertex's already coded
//!    neighbours' codes as context bucket ([`predict::neighbour_bucket`]).
//!
//! Declared error bound ([`AnimationCodec::error_bound`]): every coordinate within half the
//! largest step any packet can get (a packet's box lies inside the whole animation's), plus the
//! rounding of the reconstruction to `f32`.

use codec_core::bytes::{ByteReader, ByteWriter};
use codec_core::codec::{
    AnimationCodec, EncodedPacket, EncoderSetup, ErrorBound, FourCc, FrameDecoder, FrameEncoder, Packet, StreamInfo,
};

use codec_core::params::{ParamSet, ParamSpec, ParamValue, RateLadder};
use codec_core::toolkit::adaptive::{AdaptiveDecoder, AdaptiveEncoder};
use codec_core::toolkit::order::{mesh_bytes, CausalGraph};
use codec_core::toolkit::predict::{self, Predictor};
use codec_core::toolkit::rdq;
use codec_core::{Animation, Error, Limits, Result};

mod params;
pub use params::LaplacianParams;

/// Name on the command line and in parameter sets.
const NAME: &str = "laplacian";

/// Version of the bitstream this encoder writes (bump it when the bytes change; the decoder
/// keeps decoding every version with a golden stream in `tests/golden/`).
const STREAM_VERSION: u16 = 1;

/// Coordinates beyond ±2^100 are refused: steps and reconstructions then stay far inside the
/// `f32` range, so no decoded value can overflow.
const MAX_MAGNITUDE: f64 = 1.2676506002282294e30;

/// Arithmetic-coder classes: `axis` for the spatially predicted first frame of a packet,
/// `3 + axis` for temporally predicted frames (their residuals have different statistics).
const CLASSES: usize = 6;

/// Arithmetic-coder class of a code on `axis`.
fn class(axis: usize, temporal: bool) -> usize {
    axis + if temporal { 3 } else { 0 }
}

/// Upper bound on the coder's binary decisions per coded integer (zero, sign, 30 exponent
/// decisions and 30 mantissa bits), for the decoder's work check.
const DECISIONS_PER_VALUE: u64 = 64;

/// The `laplacian` codec.
#[derive(Debug, Clone, Copy, Default)]
pub struct Laplacian;

/// The step a packet with bounding-box diagonal `diagonal` and largest coordinate magnitude
/// `magnitude` is coded with, as stored (`f32`). The floor keeps codes inside the toolkit's
/// code range (`rdq::step_floor`) and the step a normal, nonzero `f32`.
fn packet_step(relative: f64, diagonal: f64, magnitude: f64) -> f64 {
    rdq::stored_step(relative * diagonal, rdq::step_floor(magnitude).max(f32::MIN_POSITIVE as f64))
}

/// Bounding-box diagonal and largest coordinate magnitude of frame-major positions.
fn extent(positions: &[f32]) -> (f64, f64) {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in positions.chunks_exact(3) {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a] as f64);
            hi[a] = hi[a].max(p[a] as f64);
        }
    }
    if positions.is_empty() {
        return (0.0, 0.0);
    }
    let diagonal = (0..3).map(|a| (hi[a] - lo[a]).powi(2)).sum::<f64>().sqrt();
    let magnitude = (0..3).map(|a| lo[a].abs().max(hi[a].abs())).fold(0.0, f64::max);
    (diagonal, magnitude)
}

impl AnimationCodec for Laplacian {
    fn name(&self) -> &'static str {
        NAME
    }
    fn fourcc(&self) -> FourCc {
        FourCc::new(b"LAPL")
    }
    fn stream_version(&self) -> u16 {
        STREAM_VERSION
    }
    fn summary(&self) -> &'static str {
        "closed-loop predictive quantizer (parallelogram keyframes, temporal extrapolation), adaptive arithmetic coding"
    }
    fn param_specs(&self) -> Vec<ParamSpec> {
        LaplacianParams::specs()
    }
    fn rate_ladder(&self, _base: &ParamSet) -> RateLadder {
        // From small streams to large: the step shrinks by about half an octave per rung.
        let steps = [0.05, 0.02, 0.01, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5];
        RateLadder { param: "step", steps: steps.into_iter().map(ParamValue::Float).collect() }
    }
    fn validate(&self, params: &ParamSet) -> Result<()> {
        LaplacianParams::from_param_set(params)?.validate()
    }
    fn error_bound(&self, params: &ParamSet, animation: &Animation) -> Result<ErrorBound> {
        let p = LaplacianParams::from_param_set(params)?;
        let (diagonal, magnitude) = extent(animation.positions());
        // No packet's diagonal or magnitude exceeds the animation's, so no packet's step exceeds
        // this one, up to the f32 rounding of the stored step (relative 2^-24, doubled here).
        let largest_step = packet_step(p.step, diagonal, magnitude) * (1.0 + f32::EPSILON as f64);
        // Half a step from quantization; then the f64 reconstruction (at most magnitude + step)
        // rounded to f32, relative 2^-24 (f32::EPSILON = 2^-23 leaves room).
        let bound = 0.5 * largest_step + (magnitude + largest_step) * f32::EPSILON as f64;
        Ok(ErrorBound { max_coordinate_error: Some(bound), relative_rms_error: None })
    }
    fn new_encoder(&self, params: &ParamSet, setup: &EncoderSetup<'_>) -> Result<Box<dyn FrameEncoder>> {
        let params = LaplacianParams::from_param_set(params)?;
        let topology = setup.topology;
        let graph = CausalGraph::mesh(topology.vertex_count(), topology.triangles());
        Ok(Box::new(LaplacianEncoder {
            params,
            graph,
            want_reconstruction: setup.want_reconstruction,
            pending: Vec::new(),
            next_frame: 0,
        }))
    }
    fn new_decoder(&self, info: &StreamInfo, config: &[u8], limits: &Limits) -> Result<Box<dyn FrameDecoder>> {
        if info.codec_version != STREAM_VERSION {
            return Err(Error::malformed(
                NAME,
                "stream version",
                format!("{} (this build decodes {STREAM_VERSION})", info.codec_version),
            ));
        }
        // This version has no stream configuration: any bytes there are not ours.
        ByteReader::new(config, NAME).expect_end("config")?;
        let topology = &info.topology;
        limits.check_alloc(NAME, "vertex order", mesh_bytes(topology.vertex_count(), topology.triangles().len()))?;
        let graph = CausalGraph::mesh(topology.vertex_count(), topology.triangles());
        Ok(Box::new(LaplacianDecoder { graph, limits: *limits }))
    }
}

struct LaplacianEncoder {
    params: LaplacianParams,
    graph: CausalGraph,
    want_reconstruction: bool,
    pending: Vec<f32>,
    next_frame: u32,
}

impl LaplacianEncoder {
    fn vertex_count(&self) -> usize {
        self.graph.len()
    }

    fn frames_pending(&self) -> usize {
        self.pending.len() / (self.vertex_count() * 3).max(1)
    }

    fn encode_block(&mut self, frames: usize) -> Result<EncodedPacket> {
        let n = self.vertex_count();
        let block: Vec<f32> = self.pending.drain(..frames * n * 3).collect();
        let (diagonal, magnitude) = extent(&block);
        let step = packet_step(self.params.step, diagonal, magnitude);
        let mut coder = AdaptiveEncoder::new(CLASSES);
        let mut frame_codes = PredictionState::new(n, &self.graph, step);
        let mut output = Vec::with_capacity(if self.want_reconstruction { block.len() } else { 0 });
        for (t, frame) in block.chunks_exact(n * 3).enumerate() {
            let order = self.graph.order();
            frame_codes.code_frame(t, |axis, p, prediction, inv| {
                predict::quantize_one(frame[order[p] as usize * 3 + axis] as f64, prediction, step, inv)
            });
            for (class, code, bucket) in frame_codes.coded() {
                coder.encode(code, class, bucket);
            }
            if self.want_reconstruction {
                output.extend(frame_codes.frame_f32());
            }
        }
        let mut w = ByteWriter::new();
        w.f32(step as f32);
        w.bytes(&coder.finish());
        let packet =
            Packet { first_frame: self.next_frame, frame_count: frames as u32, keyframe: true, data: w.into_vec() };
        self.next_frame += frames as u32;
        Ok(EncodedPacket { packet, reconstruction: self.want_reconstruction.then_some(output) })
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
        self.pending.extend_from_slice(frames);
        let block = self.params.block as usize;
        let mut out = Vec::new();
        while self.frames_pending() >= block {
            out.push(self.encode_block(block)?);
        }
        Ok(out)
    }

    fn finish(&mut self) -> Result<Vec<EncodedPacket>> {
        let n = self.frames_pending();
        Ok(if n > 0 { vec![self.encode_block(n)?] } else { Vec::new() })
    }
}

/// The prediction state both sides share: the reconstructions of the last two frames and the
/// codes of the current one, all in coding order (position `p` is vertex `graph.order()[p]`).
/// Encoder and decoder call [`PredictionState::code_frame`] with the same predictions, so they cannot
/// disagree on what is predicted from what.
struct PredictionState<'a> {
    graph: &'a CausalGraph,
    step: f64,
    /// Reconstructions of frames t−1 and t−2 (`[axis][p]`), and of frame t being coded.
    previous: [Vec<f64>; 3],
    before: [Vec<f64>; 3],
    current: [Vec<f64>; 3],
    codes: [Vec<i32>; 3],
    /// Whether the frame just coded was predicted from earlier frames (not the packet's first).
    temporal: bool,
}

impl<'a> PredictionState<'a> {
    fn new(n: usize, graph: &'a CausalGraph, step: f64) -> Self {
        let zeros = || [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
        Self {
            graph,
            step,
            previous: zeros(),
            before: zeros(),
            current: zeros(),
            codes: [vec![0; n], vec![0; n], vec![0; n]],
            temporal: false,
        }
    }

    /// Codes frame `t` of the packet: `quantize(axis, p, prediction, 1/step)` returns the code
    /// and the reconstruction of position `p` (the encoder quantizes, the decoder reads a code).
    fn code_frame(&mut self, t: usize, mut quantize: impl FnMut(usize, usize, f64, f64) -> (i32, f64)) {
        let inv = 1.0 / self.step;
        self.temporal = t > 0;
        for axis in 0..3 {
            for p in 0..self.graph.len() {
                let prediction = match t {
                    0 => predict::predict(self.graph, Predictor::Parallelogram, &self.current[axis], p),
                    1 => self.previous[axis][p],
                    _ => 2.0 * self.previous[axis][p] - self.before[axis][p],
                };
                let (code, recon) = quantize(axis, p, prediction, inv);
                self.codes[axis][p] = code;
                self.current[axis][p] = recon;
            }
        }
        for axis in 0..3 {
            std::mem::swap(&mut self.before[axis], &mut self.previous[axis]);
            self.previous[axis].copy_from_slice(&self.current[axis]);
        }
    }

    /// `(class, code, bucket)` of every code of the frame just coded, in coding order (the
    /// decoder reads them in this order: [`class`], and the bucket from the earlier neighbours'
    /// codes, which precede position `p`).
    fn coded(&self) -> impl Iterator<Item = (usize, i32, usize)> + '_ {
        (0..3).flat_map(move |axis| {
            (0..self.graph.len()).map(move |p| {
                (
                    class(axis, self.temporal),
                    self.codes[axis][p],
                    predict::neighbour_bucket(self.graph, &self.codes[axis], p),
                )
            })
        })
    }

    /// The frame just coded as `f32` positions in vertex order.
    fn frame_f32(&self) -> Vec<f32> {
        let n = self.graph.len();
        let mut out = vec![0.0f32; n * 3];
        for (p, &v) in self.graph.order().iter().enumerate() {
            for axis in 0..3 {
                out[v as usize * 3 + axis] = self.previous[axis][p] as f32;
            }
        }
        out
    }
}

struct LaplacianDecoder {
    graph: CausalGraph,
    limits: Limits,
}

impl FrameDecoder for LaplacianDecoder {
    fn decode_packet(&mut self, packet: &Packet) -> Result<Vec<f32>> {
        if !packet.keyframe {
            return Err(Error::malformed(NAME, "packet", "every packet of this codec is a keyframe".to_owned()));
        }
        let n = self.graph.len();
        let values = packet.frame_count as u64 * n as u64 * 3;
        // Output frames, plus four reconstruction and code planes of one frame.
        self.limits.check_alloc(NAME, "decoded frames", values * 4 + n as u64 * 3 * (3 * 8 + 4))?;
        self.limits.check_work(NAME, "arithmetic decoding", values * DECISIONS_PER_VALUE)?;
        let mut r = ByteReader::new(&packet.data, NAME);
        let step = r.finite_f32("step")? as f64;
        if step < f32::MIN_POSITIVE as f64 {
            return Err(r.malformed("step", format!("{step} is not a positive normal number")));
        }
        let mut coder = AdaptiveDecoder::new(r.take(r.remaining(), "codes")?, CLASSES, NAME, "codes")?;
        let mut state = PredictionState::new(n, &self.graph, step);
        let mut out = Vec::with_capacity(values as usize);
        // Codes of the frame being decoded: a code's context bucket is read from the codes of
        // its earlier neighbours, which are decoded before it (positions below p).
        let mut codes: [Vec<i32>; 3] = [vec![0; n], vec![0; n], vec![0; n]];
        let graph = &self.graph;
        for t in 0..packet.frame_count as usize {
            let mut failure = None;
            state.code_frame(t, |axis, p, prediction, _inv| {
                let bucket = predict::neighbour_bucket(graph, &codes[axis], p);
                let code = match coder.decode(class(axis, t > 0), bucket) {
                    Ok(c) => c,
                    Err(e) => {
                        failure.get_or_insert(e);
                        0
                    }
                };
                codes[axis][p] = code;
                (code, prediction + code as f64 * step)
            });
            if let Some(e) = failure {
                return Err(e);
            }
            let frame = state.frame_f32();
            if let Some(x) = frame.iter().find(|x| !x.is_finite()) {
                return Err(Error::malformed(
                    NAME,
                    "codes",
                    format!("frame {} decodes to {x}", packet.first_frame as usize + t),
                ));
            }
            out.extend(frame);
        }
        // Every coded word must have been read, and none past the end: a stream whose header
        // declares more (or fewer) values than its codes hold is malformed, not decoded.
        coder.finish()?;
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use codec_core::{decode_animation, encode_animation_fed, synth, CodecRegistry};

    /// A quick check while developing; the conformance suite (`tests/`) checks much more once
    /// the codec is registered.
    #[test]
    fn round_trip_within_bound_and_matches_encoder_reconstruction() {
        let anim = synth::waving_flag(8, 6, 40);
        let registry = CodecRegistry::new(vec![Box::new(Laplacian)]).unwrap();
        for step in [0.05, 1e-3, 1e-6] {
            let params = LaplacianParams { step, block: 16 }.to_param_set().unwrap();
            let enc = encode_animation_fed(&Laplacian, &params, &anim, true, 7).unwrap();
            let dec = decode_animation(&enc.bytes, &registry, Limits::default()).unwrap();
            assert_eq!(Some(&dec), enc.reconstruction.as_ref(), "step {step}");
            let bound = Laplacian.error_bound(&params, &anim).unwrap().max_coordinate_error.unwrap();
            let err =
                anim.positions().iter().zip(dec.positions()).map(|(a, b)| (a - b).abs() as f64).fold(0.0, f64::max);
            assert!(err <= bound, "step {step}: error {err} > bound {bound}");
            assert!(err > bound / 20.0, "step {step}: error {err} far below bound {bound}: is the bound meaningful?");
        }
    }

    #[test]
    fn typed_validation_states_the_range() {
        let e = LaplacianParams { step: 0.5, ..Default::default() }.validate().unwrap_err().to_string();
        assert!(e.contains(NAME) && e.contains("step") && e.contains("0.1"), "{e}");
    }
}
