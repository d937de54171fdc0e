//! The encoder: per packet of `block` frames, one uniform quantizer per axis over the packet's
//! range, the first frame's codes and later frames' code differences, zigzag-mapped, in byte
//! planes compressed with zstd.

use codec_core::bytes::{zigzag_encode, ByteWriter};
use codec_core::toolkit::planes::{delta_plane_count, to_byte_planes};
use codec_core::{entropy, EncodedPacket, EncoderSetup, ErrorBound, FrameEncoder, Packet, Quantizer, Result};

use crate::{bound_of_box, QuantDeltaParams};

pub(crate) struct QuantDeltaEncoder {
    params: QuantDeltaParams,
    vertex_count: usize,
    want_reconstruction: bool,
    pending: Vec<f32>,
    next_frame: u32,
    /// Bounding box of every frame pushed ([`FrameEncoder::declared_bound`]).
    lo: [f32; 3],
    hi: [f32; 3],
}

impl QuantDeltaEncoder {
    pub(crate) fn new(params: QuantDeltaParams, setup: &EncoderSetup<'_>) -> Self {
        Self {
            params,
            vertex_count: setup.topology.vertex_count(),
            want_reconstruction: setup.want_reconstruction,
            pending: Vec::new(),
            next_frame: 0,
            lo: [f32::INFINITY; 3],
            hi: [f32::NEG_INFINITY; 3],
        }
    }

    fn frames_pending(&self) -> usize {
        self.pending.len() / (self.vertex_count * 3)
    }

    fn encode_block(&mut self, frames: usize) -> Result<EncodedPacket> {
        let n3 = self.vertex_count * 3;
        let block: Vec<f32> = self.pending.drain(..frames * n3).collect();
        let mut quantizers = Vec::with_capacity(3);
        for axis in 0..3 {
            let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
            for p in block.chunks_exact(3) {
                lo = lo.min(p[axis]);
                hi = hi.max(p[axis]);
            }
            quantizers.push(Quantizer::new(lo, hi, self.params.bits)?);
        }
        // Residuals in the order frame, axis, vertex: each axis of a frame is one run.
        let mut residuals = Vec::with_capacity(block.len());
        let mut prev = vec![0u32; n3];
        let mut reconstruction = self.want_reconstruction.then(|| Vec::with_capacity(block.len()));
        for (t, frame) in block.chunks_exact(n3).enumerate() {
            let codes: Vec<u32> = frame.iter().enumerate().map(|(i, &x)| quantizers[i % 3].quantize(x)).collect();
            for axis in 0..3 {
                for v in 0..self.vertex_count {
                    let i = v * 3 + axis;
                    let d = if t == 0 { codes[i] as i64 } else { codes[i] as i64 - prev[i] as i64 };
                    residuals.push(zigzag_encode(d) as u32);
                }
            }
            if let Some(rec) = reconstruction.as_mut() {
                rec.extend(codes.iter().enumerate().map(|(i, &q)| quantizers[i % 3].dequantize(q)));
            }
            prev = codes;
        }
        let mut w = ByteWriter::new();
        for q in &quantizers {
            q.write(&mut w);
        }
        let planes = to_byte_planes(&residuals, delta_plane_count(self.params.bits));
        w.bytes(&entropy::compress(&planes, self.params.level));
        let packet =
            Packet { first_frame: self.next_frame, frame_count: frames as u32, keyframe: true, data: w.into_vec() };
        self.next_frame += frames as u32;
        Ok(EncodedPacket { packet, reconstruction })
    }
}

impl FrameEncoder for QuantDeltaEncoder {
    fn config(&self) -> Vec<u8> {
        vec![self.params.bits]
    }

    fn push_frames(&mut self, frames: &[f32]) -> Result<Vec<EncodedPacket>> {
        codec_core::animation::extend_bounding_box(&mut self.lo, &mut self.hi, frames);
        self.pending.extend_from_slice(frames);
        let block = self.params.block as usize;
        let mut out = Vec::new();
        while self.frames_pending() >= block {
            out.push(self.encode_block(block)?);
        }
        Ok(out)
    }

    /// [`codec_core::AnimationCodec::error_bound`] from the bounding box of the frames pushed.
    fn declared_bound(&self) -> Option<ErrorBound> {
        let (lo, hi) = if self.next_frame == 0 && self.pending.is_empty() {
            ([0.0; 3], [0.0; 3]) // as `bounding_box` of no positions
        } else {
            (self.lo, self.hi)
        };
        // An empty or degenerate box still gives a valid quantizer; an error here means the
        // parameters are invalid, which `validate` already refused.
        bound_of_box(&self.params, lo, hi).ok()
    }

    fn finish(&mut self) -> Result<Vec<EncodedPacket>> {
        let n = self.frames_pending();
        Ok(if n > 0 { vec![self.encode_block(n)?] } else { Vec::new() })
    }
}
