//! The streaming encoder (§4.5): frames are consumed in order, the segmenter ([`crate::segment`])
//! ends each segment, and every segment is coded (the toolkit's coding, [`crate::coding`], or the
//! paper's, [`crate::paper`]) as one packet; the encoder's reconstruction is the decoder's.

use codec_core::{Animation, EncodedPacket, EncoderSetup, Error, FrameEncoder, Packet, Result};

use crate::decoder::StsegDecoder;
use crate::mesh::MeshGraph;
use crate::params::{Coding, StsegParams};
use crate::segment::{BlockKind, Segment, Segmentation, Segmenter};
use crate::{coding, paper, MAX_GROUPS, NAME};

/// Fixed-size temporal blocks with a single vertex group: the segmentation of the paper's
/// "Adapted PCA" baseline (§5.3.1), for comparisons with [`encode_with_segmentation`].
pub fn fixed_block_segmentation(vertex_count: usize, frame_count: usize, block: usize) -> Segmentation {
    let block = block.max(1);
    let segments = (0..frame_count)
        .step_by(block)
        .map(|first_frame| Segment {
            first_frame,
            frame_count: block.min(frame_count - first_frame),
            kind: BlockKind::NoCut,
            detected_boundary: false,
            window: None,
            group_count: 1,
            labels: vec![0; vertex_count],
        })
        .collect();
    Segmentation { segments }
}

/// Codes `animation` with the PCA stage of `stseg` (§4.4) over a given segmentation (for
/// example [`fixed_block_segmentation`]) and returns the packets, in the `stseg` stream
/// format, and the decoded frames. [`Stseg`](crate::Stseg)'s encoder is this with [`segment_animation`](crate::segment_animation).
pub fn encode_with_segmentation(
    animation: &Animation,
    params: &StsegParams,
    segmentation: &Segmentation,
) -> Result<(Vec<Packet>, Vec<f32>)> {
    params.validate()?;
    let graph = MeshGraph::new(animation.topology());
    let v = animation.vertex_count();
    let n3 = v * 3;
    let mut next = 0;
    let mut packets = Vec::new();
    let mut rec = Vec::with_capacity(animation.positions().len());
    let mut dec = StsegDecoder::for_params(params, animation.topology());
    for seg in &segmentation.segments {
        if seg.first_frame != next
            || seg.frame_count == 0
            || next + seg.frame_count > animation.frame_count()
            || seg.labels.len() != v
            || seg.group_count == 0
            || seg.group_count > MAX_GROUPS
            || seg.labels.iter().any(|&l| l as usize >= seg.group_count)
        {
            return Err(Error::parameter(
                NAME,
                "segmentation",
                format!("segment at frame {} is inconsistent", seg.first_frame),
            ));
        }
        let block = &animation.positions()[next * n3..(next + seg.frame_count) * n3];
        let data = encode_segment(params, &graph, &mut dec.graphs, seg, block)?;
        rec.extend_from_slice(&dec.decode(&data, seg.frame_count)?);
        packets.push(Packet { first_frame: next as u32, frame_count: seg.frame_count as u32, keyframe: true, data });
        next += seg.frame_count;
    }
    if next != animation.frame_count() {
        return Err(Error::parameter(
            NAME,
            "segmentation",
            format!("covers {next} of {} frames", animation.frame_count()),
        ));
    }
    Ok((packets, rec))
}

/// [`AnimationCodec::new_encoder`](codec_core::AnimationCodec::new_encoder) for valid
/// parameters `p`.
pub(crate) fn new_encoder(p: &StsegParams, setup: &EncoderSetup<'_>) -> Result<Box<dyn FrameEncoder>> {
    Ok(Box::new(StsegEncoder {
        params: *p,
        segmenter: Segmenter::new(*p, setup.topology),
        graph: MeshGraph::new(setup.topology),
        decoder: StsegDecoder::for_params(p, setup.topology),
        vertex_count: setup.topology.vertex_count(),
        total: setup.frame_count,
        want_reconstruction: setup.want_reconstruction,
        pending: Vec::new(),
        next_frame: 0,
    }))
}

struct StsegEncoder {
    params: StsegParams,
    segmenter: Segmenter,
    graph: MeshGraph,
    /// Rebuilds the reconstruction; its coding orders are shared with the toolkit encoder.
    decoder: StsegDecoder,
    vertex_count: usize,
    total: usize,
    want_reconstruction: bool,
    pending: Vec<f32>,
    next_frame: usize,
}

impl StsegEncoder {
    fn drain(&mut self) -> Result<Vec<EncodedPacket>> {
        let n3 = self.vertex_count * 3;
        let mut out = Vec::new();
        while let Some(seg) = self.segmenter.next(&self.pending, self.total - self.next_frame, self.next_frame)? {
            let block: Vec<f32> = self.pending.drain(..seg.frame_count * n3).collect();
            let data = encode_segment(&self.params, &self.graph, &mut self.decoder.graphs, &seg, &block)?;
            let reconstruction =
                if self.want_reconstruction { Some(self.decoder.decode(&data, seg.frame_count)?) } else { None };
            let packet = Packet {
                first_frame: self.next_frame as u32,
                frame_count: seg.frame_count as u32,
                keyframe: true,
                data,
            };
            self.next_frame += seg.frame_count;
            out.push(EncodedPacket { packet, reconstruction });
        }
        Ok(out)
    }
}

impl FrameEncoder for StsegEncoder {
    fn config(&self) -> Vec<u8> {
        let p = &self.params;
        vec![p.bits, p.coef_bits, p.centering.code(), p.coding.code(), p.mesh_predictor.code(), p.time_predictor.code()]
    }

    fn push_frames(&mut self, frames: &[f32]) -> Result<Vec<EncodedPacket>> {
        self.pending.extend_from_slice(frames);
        self.drain()
    }

    fn finish(&mut self) -> Result<Vec<EncodedPacket>> {
        let out = self.drain()?;
        if !self.pending.is_empty() {
            return Err(Error::Unsupported {
                context: NAME.into(),
                detail: "frames left after the last segment".into(),
            });
        }
        Ok(out)
    }
}

/// Packet payload of one segment in the coding `p.coding` names (layouts in README.md).
fn encode_segment(
    p: &StsegParams,
    graph: &MeshGraph,
    graphs: &mut coding::Graphs,
    seg: &Segment,
    block: &[f32],
) -> Result<Vec<u8>> {
    match p.coding {
        Coding::Paper => paper::encode_segment(p, graph, seg, block),
        Coding::Toolkit => coding::encode_segment(p, graph, graphs, seg, block),
    }
}
