//! The decoder: every packet (segment) alone, stream versions 2 and 3. Sizes and work are
//! checked against the caller's [`Limits`] before anything is allocated.

use codec_core::bytes::ByteReader;
use codec_core::toolkit::predict::Predictor;
use codec_core::{Error, FrameDecoder, Limits, Packet, Result, StreamInfo};

use crate::params::{Centering, Coding, StsegParams};
use crate::segment::BlockKind;
use crate::{coding, paper, MAX_GROUPS, NAME};

/// [`AnimationCodec::new_decoder`](codec_core::AnimationCodec::new_decoder): reads the stream
/// configuration (untrusted) of stream versions 2 and 3.
pub(crate) fn new_decoder(info: &StreamInfo, config: &[u8], limits: &Limits) -> Result<Box<dyn FrameDecoder>> {
    if !(2..=3).contains(&info.codec_version) {
        return Err(Error::Unsupported {
            context: NAME.into(),
            detail: format!("stream version {} (this build decodes 2 and 3)", info.codec_version),
        });
    }
    let mut r = ByteReader::new(config, NAME);
    let bits = r.u8("config.bits")?;
    let coef_bits = r.u8("config.coef_bits")?;
    let centering_code = r.u8("config.centering")?;
    let (coding, predictors) = if info.codec_version >= 3 {
        let c = r.u8("config.coding")?;
        let coding = Coding::from_code(c).ok_or_else(|| r.malformed("config.coding", format!("{c} is not 0..=1")))?;
        let mut pred = |field| -> Result<Predictor> {
            let c = r.u8(field)?;
            Predictor::from_code(c).ok_or_else(|| r.malformed(field, format!("{c} is not 0..=3")))
        };
        let mesh = pred("config.mesh_predictor")?;
        let time = pred("config.time_predictor")?;
        (coding, coding::Predictors { mesh, time })
    } else {
        (Coding::Paper, coding::Predictors { mesh: Predictor::Zero, time: Predictor::Zero })
    };
    r.expect_end("config")?;
    let centering = Centering::from_code(centering_code)
        .ok_or_else(|| r.malformed("config.centering", format!("{centering_code} is not 0..=3")))?;
    for (field, b) in [("config.bits", bits), ("config.coef_bits", coef_bits)] {
        if !(6..=20).contains(&b) {
            return Err(r.malformed(field, format!("{b} is outside 6..=20")));
        }
    }
    Ok(Box::new(StsegDecoder {
        bits,
        coef_bits,
        centering,
        coding,
        predictors,
        vertex_count: info.vertex_count(),
        limits: *limits,
        graphs: coding::Graphs::new(info.vertex_count(), info.topology.triangles()),
    }))
}

pub(crate) struct StsegDecoder {
    bits: u8,
    coef_bits: u8,
    centering: Centering,
    coding: Coding,
    predictors: coding::Predictors,
    vertex_count: usize,
    limits: Limits,
    /// Coding orders of the toolkit coding (built on first use, after the limits check).
    pub(crate) graphs: coding::Graphs,
}

impl StsegDecoder {
    /// The decoder of the stream the encoder writes with `p` (for its reconstruction).
    pub(crate) fn for_params(p: &StsegParams, topology: &codec_core::Topology) -> Self {
        Self {
            bits: p.bits,
            coef_bits: p.coef_bits,
            centering: p.centering,
            coding: p.coding,
            predictors: coding::Predictors { mesh: p.mesh_predictor, time: p.time_predictor },
            vertex_count: topology.vertex_count(),
            // The encoder's own reconstruction: memory checked as a decoder's, work unbounded
            // (a long input's packets would add up past a decode's budget).
            limits: Limits { max_work: u64::MAX, ..Limits::default() },
            graphs: coding::Graphs::new(topology.vertex_count(), topology.triangles()),
        }
    }

    pub(crate) fn decode(&mut self, data: &[u8], frames: usize) -> Result<Vec<f32>> {
        let v = self.vertex_count;
        let mut r = ByteReader::new(data, NAME);
        let case = r.u8("case")?;
        if BlockKind::from_case(case).is_none() {
            return Err(r.malformed("case", format!("{case} is not a block case 1..=4")));
        }
        let group_count = r.varint("group_count")? as usize;
        if group_count == 0 || group_count > MAX_GROUPS.min(v.max(1)) {
            return Err(
                r.malformed("group_count", format!("{group_count} is outside 1..={}", MAX_GROUPS.min(v.max(1))))
            );
        }
        let out = match self.coding {
            Coding::Paper => paper::decode_segment(
                &mut r,
                frames,
                group_count,
                v,
                (self.bits, self.coef_bits),
                self.centering,
                &mut self.limits,
            )?,
            Coding::Toolkit => coding::decode_segment(
                &mut r,
                frames,
                v,
                self.centering,
                self.predictors,
                &mut self.graphs,
                &mut self.limits,
                group_count,
            )?,
        };
        // Corrupt quantizer ranges or steps can overflow f32; say so here rather than emit infinities.
        if out.iter().any(|x| !x.is_finite()) {
            return Err(Error::malformed(NAME, "values", "decoded coordinates are not finite"));
        }
        Ok(out)
    }
}

impl FrameDecoder for StsegDecoder {
    fn decode_packet(&mut self, packet: &Packet) -> Result<Vec<f32>> {
        let frames = packet.frame_count as usize;
        self.limits.check_alloc(NAME, "the decoded packet", (frames as u64) * self.vertex_count as u64 * 12)?;
        self.decode(&packet.data, frames)
    }
}
