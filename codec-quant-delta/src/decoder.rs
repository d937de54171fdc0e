//! The decoder: every byte untrusted, every allocation and the whole decode's work checked
//! against the caller's [`Limits`] before it happens.

use codec_core::bytes::{zigzag_decode, ByteReader};
use codec_core::toolkit::planes::{delta_plane_count, plane_value};
use codec_core::{entropy, Error, FrameDecoder, Limits, Packet, Quantizer, Result, StreamInfo};

use crate::NAME;

pub(crate) struct QuantDeltaDecoder {
    bits: u8,
    vertex_count: usize,
    limits: Limits,
}

/// Work of one decoded coordinate: its byte planes inflated and the coordinate rebuilt.
fn work_per_value(bits: u8) -> u64 {
    delta_plane_count(bits) as u64 * codec_core::limits::WORK_PER_PLANE_BYTE + codec_core::limits::WORK_PER_COORDINATE
}

impl QuantDeltaDecoder {
    /// The decoder of a stream whose header is `info` and whose config is `config`, after
    /// checking the whole decode's work (known from the header) against `limits`.
    pub(crate) fn new(info: &StreamInfo, config: &[u8], limits: &Limits) -> Result<Self> {
        let mut r = ByteReader::new(config, NAME);
        let bits = r.u8("config.bits")?;
        r.expect_end("config")?;
        if !(1..=24).contains(&bits) {
            return Err(r.malformed("config.bits", format!("{bits} is outside 1..=24")));
        }
        let values = Limits::product(&[info.vertex_count() as u64, info.frame_count as u64, 3]);
        limits.check_work(
            NAME,
            "residual decoding of the whole stream",
            values.saturating_mul(work_per_value(bits)),
        )?;
        Ok(Self { bits, vertex_count: info.vertex_count(), limits: *limits })
    }
}

impl FrameDecoder for QuantDeltaDecoder {
    fn decode_packet(&mut self, packet: &Packet) -> Result<Vec<f32>> {
        let mut r = ByteReader::new(&packet.data, NAME);
        let mut quantizers = Vec::with_capacity(3);
        for _ in 0..3 {
            let q = Quantizer::read(&mut r, "quantizer")?;
            if q.bits() != self.bits {
                return Err(r.malformed("quantizer", format!("{} bits, stream config says {}", q.bits(), self.bits)));
            }
            quantizers.push(q);
        }
        let n3 = self.vertex_count * 3;
        let values = packet.frame_count as usize * n3;
        let planes = delta_plane_count(self.bits);
        let max_len = values.saturating_mul(planes);
        self.limits.check_alloc(NAME, "residuals", max_len as u64)?;
        // Charged before the residuals are inflated (`--max-work`).
        self.limits =
            self.limits.spend(NAME, "residual decoding", (values as u64).saturating_mul(work_per_value(self.bits)))?;
        let block = r.take(r.remaining(), "residuals")?;
        let raw = entropy::decompress(block, NAME, "residuals", max_len)?;
        if raw.len() != max_len {
            return Err(Error::malformed(NAME, "residuals", format!("{} bytes, expected {max_len}", raw.len())));
        }
        let max_code = quantizers[0].max_code() as i64;
        let mut codes = vec![0i64; n3];
        let mut out = Vec::with_capacity(values);
        let mut k = 0usize;
        for t in 0..packet.frame_count as usize {
            for axis in 0..3 {
                for v in 0..self.vertex_count {
                    let d = zigzag_decode(u64::from(plane_value(&raw, values, planes, k)));
                    k += 1;
                    let i = v * 3 + axis;
                    let c = if t == 0 { d } else { codes[i] + d };
                    if !(0..=max_code).contains(&c) {
                        return Err(Error::malformed(
                            NAME,
                            "residuals",
                            format!("frame {}: code {c} outside 0..={max_code}", packet.first_frame as usize + t),
                        ));
                    }
                    codes[i] = c;
                }
            }
            out.extend(codes.iter().enumerate().map(|(i, &c)| quantizers[i % 3].dequantize(c as u32)));
        }
        Ok(out)
    }
}
