//! One animation encoded by independent temporal blocks — on many machines (the
//! Python package's Dask encode), in any order — and assembled into the very container the
//! local encode writes, byte for byte.
//!
//! A codec opts in with [`AnimationCodec::independent_blocks`]: each of its packets is coded
//! from its own block of frames alone (quant-delta's packets, hosvd's temporal blocks,
//! pca-aoi's blocks with `mode=svd`; baoi/qaoi start each block's dictionary from the previous
//! one). The split is then fixed by the parameters alone ([`block_plan`]), block `i` is coded by
//! [`encode_block`] with the encoder the whole encode would make (same setup: topology in
//! canonical order, total frame count, frame rate), and [`assemble_blocks`] writes the header
//! (the encoder's configuration) and the packets in frame order, then the index.
//!
//! **The self-check runs per block** (as in [`crate::StreamEncoder`]): every
//! packet is decoded by the codec's own decoder, must be finite, and the block's error must be
//! within the bound the encoder declares for the frames it was given (that block alone; the
//! same arithmetic as [`AnimationCodec::error_bound`] on the block). A block that fails never
//! returns a packet, so an assembled stream holds only checked packets.

use std::io::Write;
use std::ops::Range;

use crate::animation::{check_finite, whole_frames, Topology};
use crate::codec::{AnimationCodec, EncoderSetup, Packet, StreamInfo};
use crate::container::ContainerWriter;
use crate::error::{Error, Result};
use crate::limits::Limits;
use crate::params::ParamSet;
use crate::stream::SelfCheck;

/// How an animation splits into independently coded temporal blocks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BlockPlan {
    /// Frames per block (the last block may be shorter).
    pub block_frames: usize,
    /// Number of blocks.
    pub blocks: usize,
    /// Frames in the whole animation.
    pub frame_count: usize,
}

impl BlockPlan {
    /// The frames of block `index`.
    pub fn frames(&self, index: usize) -> Range<usize> {
        let first = (index * self.block_frames).min(self.frame_count);
        first..(first + self.block_frames).min(self.frame_count)
    }
}

/// The parameters the blocks are coded with and their split, for an animation of `vertices`
/// × `frame_count`. With `memory`, the parameters are first fitted to that budget exactly as
/// `animcodec encode --memory` does ([`AnimationCodec::fit_memory`]), so the distributed encode
/// equals the local one with the same budget. Fails for a codec (or parameters) whose packets
/// are not independent, and for an empty animation.
pub fn block_plan(
    codec: &dyn AnimationCodec,
    params: &ParamSet,
    vertices: usize,
    frame_count: usize,
    memory: Option<u64>,
) -> Result<(ParamSet, BlockPlan)> {
    check_params(codec, params)?;
    if frame_count == 0 {
        return Err(Error::InvalidAnimation("the animation has no frames".into()));
    }
    let params = match memory {
        Some(budget) => codec.fit_memory(params, vertices, frame_count, budget)?,
        None => params.clone(),
    };
    codec.validate(&params)?;
    let block_frames = codec.independent_blocks(&params, frame_count)?.clamp(1, frame_count);
    Ok((params, BlockPlan { block_frames, blocks: frame_count.div_ceil(block_frames), frame_count }))
}

fn check_params(codec: &dyn AnimationCodec, params: &ParamSet) -> Result<()> {
    if params.codec() != codec.name() {
        return Err(Error::parameter(
            codec.name(),
            "params",
            format!("parameters belong to codec '{}'", params.codec()),
        ));
    }
    Ok(())
}

fn check_rate(frame_rate: f32) -> Result<()> {
    if !(frame_rate.is_finite() && frame_rate > 0.0) {
        return Err(Error::InvalidAnimation(format!("frame rate {frame_rate} is not a finite positive number")));
    }
    Ok(())
}

/// Codes block `index` of an animation of `frame_count` frames over `topology` (as given; the
/// stream stores it in canonical order) from that block's `frames` alone (frame-major, exactly
/// [`BlockPlan::frames`]`(index)`), with the encoder the whole encode would make, and checks it
/// (module docs). Returns its packets (one for the codecs in this repository), frame numbers
/// counted from the start of the animation.
pub fn encode_block(
    codec: &dyn AnimationCodec,
    params: &ParamSet,
    topology: &Topology,
    frame_count: usize,
    frame_rate: f32,
    index: usize,
    frames: &[f32],
) -> Result<Vec<Packet>> {
    check_rate(frame_rate)?;
    let vertices = topology.vertex_count();
    let (_, plan) = block_plan(codec, params, vertices, frame_count, None)?;
    if index >= plan.blocks {
        return Err(Error::InvalidAnimation(format!(
            "block {index} does not exist: {frame_count} frames make {} blocks of {} frames",
            plan.blocks, plan.block_frames
        )));
    }
    let range = plan.frames(index);
    let n = whole_frames(frames.len(), vertices)?;
    if n != range.len() {
        return Err(Error::InvalidAnimation(format!(
            "block {index} holds frames {}..{} ({} frames); {n} were given",
            range.start,
            range.end,
            range.len()
        )));
    }
    check_finite(frames, vertices, range.start)?;
    let canonical = crate::connectivity::canonical_order(topology);
    let setup = EncoderSetup { topology: &canonical, frame_count, frame_rate, want_reconstruction: false };
    let mut encoder = codec.new_encoder(params, &setup)?;
    let refuse = |cause: String| Error::Unsupported {
        context: codec.name().into(),
        detail: format!("self-check of block {index}: {cause}; the block was not coded"),
    };
    if encoder.declared_bound().is_none() {
        return Err(refuse("the encoder declares no error bound of its own".into()));
    }
    let info = StreamInfo {
        fourcc: codec.fourcc(),
        codec_version: codec.stream_version(),
        topology: canonical.clone(),
        frame_count,
        frame_rate,
    };
    let decoder = codec.new_decoder(&info, &encoder.config(), &Limits::UNLIMITED)?;
    let mut check = SelfCheck::new(decoder, topology.clone(), frame_rate, false, range.start);
    check.push(frames);
    let mut packets = encoder.push_frames(frames)?;
    packets.extend(encoder.finish()?);
    let mut out = Vec::with_capacity(packets.len());
    for mut p in packets {
        // The encoder saw this block as the start of its input: its frame numbers are the
        // block's own. The payload does not depend on them (`independent_blocks`' promise;
        // the byte equality with the whole encode is tested).
        p.packet.first_frame = u32::try_from(range.start + p.packet.first_frame as usize)
            .map_err(|_| Error::InvalidAnimation("frame number does not fit 32 bits".into()))?;
        check.packet(codec.name(), vertices, &p)?;
        out.push(p.packet);
    }
    if check.checked_frames != range.end {
        return Err(refuse(format!(
            "the packets cover frames {}..{} of {}..{}",
            range.start, check.checked_frames, range.start, range.end
        )));
    }
    let bound = encoder
        .declared_bound()
        .ok_or_else(|| refuse("the encoder declared a bound before the first frame but none at the end".into()))?;
    check.within(&bound, check.coordinates(), check.diagonal()).map_err(refuse)?;
    Ok(out)
}

/// Writes the container of the whole animation to `sink` from the packets of every block
/// ([`encode_block`]), given in frame order: the header the whole encode writes (codec,
/// versions, counts, frame rate, the encoder's configuration, the topology in canonical order),
/// the packets, the index. Fails (before the index is written) when the packets do not cover
/// the plan's blocks exactly.
pub fn assemble_blocks<W: Write, I: IntoIterator<Item = Packet>>(
    codec: &dyn AnimationCodec,
    params: &ParamSet,
    topology: &Topology,
    frame_count: usize,
    frame_rate: f32,
    packets: I,
    sink: W,
) -> Result<W> {
    check_rate(frame_rate)?;
    let (_, plan) = block_plan(codec, params, topology.vertex_count(), frame_count, None)?;
    let canonical = crate::connectivity::canonical_order(topology);
    let setup = EncoderSetup { topology: &canonical, frame_count, frame_rate, want_reconstruction: false };
    let config = codec.new_encoder(params, &setup)?.config();
    let mut writer = ContainerWriter::new(
        sink,
        codec.fourcc(),
        codec.stream_version(),
        &canonical,
        frame_count,
        frame_rate,
        &config,
    )?;
    let mut next = 0usize;
    for p in packets {
        // Each packet lies inside one block of the plan (the container checks continuity).
        let block = plan.frames(p.first_frame as usize / plan.block_frames);
        let end = p.first_frame as usize + p.frame_count as usize;
        if p.first_frame as usize != next || end > block.end {
            return Err(Error::InvalidAnimation(format!(
                "packet for frames {}..{end} is out of place: expected one starting at frame {next} within its block \
                 of {} frames",
                p.first_frame, plan.block_frames
            )));
        }
        writer.write_packet(&p)?;
        next = end;
    }
    writer.finish()
}
