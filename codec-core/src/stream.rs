//! Driving codecs through the container: streaming encode and decode, whole-animation
//! helpers, and random access by frame.

use std::io::{Read, Seek, Write};

use crate::animation::{check_finite, Animation, Topology};
use crate::codec::{
    AnimationCodec, EncodedPacket, EncoderSetup, ErrorBound, FrameDecoder, FrameEncoder, Packet, StreamInfo,
};
use crate::container::{self, ContainerReader, ContainerWriter, Header, IndexEntry, Section};
use crate::error::{Error, Result};
use crate::limits::Limits;
use crate::metadata::SceneMetadata;
use crate::params::ParamSet;
use crate::registry::CodecRegistry;

/// Encodes frames as they arrive into a container written to `W`.
///
/// **The encoder checks its own output**: every packet is decoded by the codec's own
/// decoder before it is written; the decoded frames must be finite and equal the encoder's
/// reconstruction when it gave one, and at [`StreamEncoder::finish`] the error against the
/// input must be within the codec's declared [`ErrorBound`] ([`FrameEncoder::declared_bound`],
/// else [`AnimationCodec::error_bound`]). Otherwise `finish` fails with an error naming the
/// codec and the cause, and no index is written (the CLI then leaves no file): a stream that
/// exceeds its bound never leaves the encoder. Cost: one decode of every packet, and a copy of
/// the input frames until the packet holding them is checked (each packet is compared
/// with its input as it is written, the error accumulated and those frames dropped, so memory
/// is bounded by the encoder's own buffering). Only when the encoder declares no bound of its
/// own ([`FrameEncoder::declared_bound`] is `None` before the first frame) is the whole input
/// kept, for [`AnimationCodec::error_bound`] at the end.
pub struct StreamEncoder<'c, W: Write> {
    codec: &'static str,
    codec_ref: &'c dyn AnimationCodec,
    params: ParamSet,
    check: SelfCheck,
    encoder: Box<dyn FrameEncoder>,
    writer: ContainerWriter<W>,
    /// The triangles as the stream stores them (canonical order).
    topology: Topology,
    vertex_count: usize,
    frames_pushed: usize,
    frame_count: usize,
}

impl<'c, W: Write> StreamEncoder<'c, W> {
    /// Validates `params`, makes the codec's encoder and writes the container header.
    /// `frame_count` frames must then be pushed before [`StreamEncoder::finish`].
    pub fn new(
        codec: &'c dyn AnimationCodec,
        params: &ParamSet,
        topology: &Topology,
        frame_count: usize,
        frame_rate: f32,
        want_reconstruction: bool,
        sink: W,
    ) -> Result<Self> {
        let metadata = SceneMetadata::default();
        Self::with_metadata(codec, params, topology, frame_count, frame_rate, want_reconstruction, &metadata, sink)
    }

    /// [`StreamEncoder::new`] for a source with scene metadata, which the header keeps.
    #[allow(clippy::too_many_arguments)]
    pub fn with_metadata(
        codec: &'c dyn AnimationCodec,
        params: &ParamSet,
        topology: &Topology,
        frame_count: usize,
        frame_rate: f32,
        want_reconstruction: bool,
        metadata: &SceneMetadata,
        sink: W,
    ) -> Result<Self> {
        if params.codec() != codec.name() {
            return Err(Error::parameter(
                codec.name(),
                "params",
                format!("parameters belong to codec '{}'", params.codec()),
            ));
        }
        if frame_count == 0 {
            return Err(Error::InvalidAnimation("the animation has no frames".into()));
        }
        crate::animation::check_stream_frame_rate(frame_rate)?;
        codec.validate(params)?;
        let topology_in = topology;
        // The stream stores the triangles in canonical order (each triangle with its
        // orientation, `connectivity::canonical_order`), where the container codes them in a
        // few bits each; the codec sees that same list, as its decoder will.
        let canonical = crate::connectivity::canonical_order(topology);
        let topology = &canonical;
        let setup = EncoderSetup { topology, frame_count, frame_rate, want_reconstruction };
        let encoder = codec.new_encoder(params, &setup)?;
        let info = StreamInfo {
            fourcc: codec.fourcc(),
            codec_version: codec.stream_version(),
            topology: topology.clone(),
            frame_count,
            frame_rate,
        };
        // The encoder's own stream: limits that never refuse it for its size.
        let check = SelfCheck::new(
            codec.new_decoder(&info, &encoder.config(), &Limits::UNLIMITED)?,
            topology_in.clone(),
            frame_rate,
            encoder.declared_bound().is_none(),
            0,
        );
        let writer = ContainerWriter::with_metadata(sink, &info, &encoder.config(), metadata)?;
        Ok(Self {
            codec: codec.name(),
            codec_ref: codec,
            params: params.clone(),
            check,
            encoder,
            writer,
            vertex_count: topology.vertex_count(),
            topology: canonical.clone(),
            frames_pushed: 0,
            frame_count,
        })
    }

    /// The triangle list the stream stores and its decoder returns: the input's triangles,
    /// each with its orientation, in [`crate::connectivity::canonical_order`].
    pub fn topology(&self) -> &Topology {
        &self.topology
    }

    /// Pushes the next frames (frame-major, a whole number of frames), writes the packets
    /// they complete and returns them with their reconstructions if those were asked for.
    pub fn push_frames(&mut self, frames: &[f32]) -> Result<Vec<EncodedPacket>> {
        let n = crate::animation::whole_frames(frames.len(), self.vertex_count)?;
        if self.frames_pushed + n > self.frame_count {
            return Err(Error::InvalidAnimation(format!(
                "{} frames pushed, but the stream was declared with {}",
                self.frames_pushed + n,
                self.frame_count
            )));
        }
        check_finite(frames, self.vertex_count, self.frames_pushed)?;
        self.frames_pushed += n;
        self.check.push(frames);
        let packets = self.encoder.push_frames(frames)?;
        self.write(packets)
    }

    fn write(&mut self, packets: Vec<EncodedPacket>) -> Result<Vec<EncodedPacket>> {
        for p in &packets {
            if let Some(rec) = &p.reconstruction {
                if rec.len() != p.packet.frame_count as usize * self.vertex_count * 3 {
                    return Err(Error::Unsupported {
                        context: self.codec.into(),
                        detail: "encoder reconstruction has the wrong size".into(),
                    });
                }
            }
            self.check.packet(self.codec, self.vertex_count, p)?;
            self.writer.write_packet(&p.packet)?;
        }
        Ok(packets)
    }

    /// Flushes the encoder, writes the index and returns the last packets and the sink.
    pub fn finish(self) -> Result<(Vec<EncodedPacket>, W)> {
        self.finish_with_notes().map(|(packets, sink, _)| (packets, sink))
    }

    /// [`StreamEncoder::finish`], plus the encoder's warnings about the stream
    /// ([`FrameEncoder::notes`]).
    pub fn finish_with_notes(mut self) -> Result<(Vec<EncodedPacket>, W, Vec<String>)> {
        if self.frames_pushed != self.frame_count {
            return Err(Error::InvalidAnimation(format!(
                "{} frames pushed, but the stream was declared with {}",
                self.frames_pushed, self.frame_count
            )));
        }
        let packets = self.encoder.finish()?;
        let packets = self.write(packets)?;
        let notes = self.encoder.notes();
        self.check_bound()?;
        Ok((packets, self.writer.finish()?, notes))
    }

    /// The self-check's last step: every frame was decoded and the error is within the bound.
    fn check_bound(&mut self) -> Result<()> {
        let refuse = |cause: String| Error::Unsupported {
            context: self.codec.into(),
            detail: format!("self-check: {cause}; the stream was not written"),
        };
        if self.check.checked_frames != self.frame_count {
            return Err(refuse(format!(
                "the packets cover {} of {} frames",
                self.check.checked_frames, self.frame_count
            )));
        }
        let diagonal = self.check.diagonal();
        let coordinates = self.check.coordinates;
        let bound = match self.encoder.declared_bound() {
            Some(b) => b,
            None if !self.check.keep_input => {
                return Err(refuse("the encoder declared a bound before the first frame but none at the end".into()))
            }
            None => {
                // The bound of the input as the user gave it (as the conformance suite asks).
                let input = std::mem::take(&mut self.check.input);
                let animation = Animation::new(self.check.topology.clone(), input, self.check.frame_rate)?;
                self.codec_ref.error_bound(&self.params, &animation)?
            }
        };
        self.check.within(&bound, coordinates, diagonal).map_err(refuse)
    }
}

/// State of [`StreamEncoder`]'s self-check (and of [`crate::blocks::encode_block`]'s, per block).
pub(crate) struct SelfCheck {
    /// The codec's decoder, fed every packet in order.
    decoder: Box<dyn FrameDecoder>,
    /// Whether every input frame is kept to the end (the encoder declares no bound, so
    /// [`AnimationCodec::error_bound`] needs the whole animation); else frames are dropped once
    /// their packet is checked.
    keep_input: bool,
    /// The input frames pushed and kept (frame-major) from frame `input_first` on, and their
    /// topology and rate as given.
    input: Vec<f32>,
    input_first: usize,
    /// Bounding box and coordinate count of every frame pushed (for the relative RMS bound).
    lo: [f32; 3],
    hi: [f32; 3],
    coordinates: usize,
    topology: Topology,
    frame_rate: f32,
    /// Frames decoded and compared so far (counted from frame 0 of the stream).
    pub(crate) checked_frames: usize,
    /// Largest coordinate error so far.
    max_error: f64,
    /// Sum of squared coordinate errors so far.
    sum_squared: f64,
}

impl SelfCheck {
    /// A check whose first packet starts at frame `first` (0 for a whole stream).
    pub(crate) fn new(
        decoder: Box<dyn FrameDecoder>,
        topology: Topology,
        frame_rate: f32,
        keep_input: bool,
        first: usize,
    ) -> Self {
        Self {
            decoder,
            topology,
            frame_rate,
            keep_input,
            input: Vec::new(),
            input_first: first,
            lo: [f32::INFINITY; 3],
            hi: [f32::NEG_INFINITY; 3],
            coordinates: 0,
            checked_frames: first,
            max_error: 0.0,
            sum_squared: 0.0,
        }
    }

    /// Coordinates pushed so far.
    pub(crate) fn coordinates(&self) -> usize {
        self.coordinates
    }

    /// Diagonal of the bounding box of every frame pushed (0 when none was).
    pub(crate) fn diagonal(&self) -> f64 {
        let (lo, hi) = if self.coordinates < 3 { ([0.0; 3], [0.0; 3]) } else { (self.lo, self.hi) };
        (0..3).map(|a| (hi[a] as f64 - lo[a] as f64).powi(2)).sum::<f64>().sqrt()
    }

    /// Keeps `frames` until their packet is checked, and extends the bounding box.
    pub(crate) fn push(&mut self, frames: &[f32]) {
        crate::animation::extend_bounding_box(&mut self.lo, &mut self.hi, frames);
        self.coordinates += frames.len();
        self.input.extend_from_slice(frames);
    }

    /// Decodes `p`, checks it against the encoder's reconstruction and accumulates its error.
    pub(crate) fn packet(&mut self, codec: &'static str, vertices: usize, p: &EncodedPacket) -> Result<()> {
        let refuse = |cause: String| Error::Unsupported {
            context: codec.into(),
            detail: format!("self-check: {cause}; the stream was not written"),
        };
        let first = p.packet.first_frame as usize;
        let frames = p.packet.frame_count as usize;
        if first != self.checked_frames {
            return Err(refuse(format!("packet starts at frame {first}, expected {}", self.checked_frames)));
        }
        let per_frame = vertices * 3;
        let local = first - self.input_first;
        let input = self
            .input
            .get(local * per_frame..(local + frames) * per_frame)
            .ok_or_else(|| refuse(format!("packet covers frames {first}..{} not pushed yet", first + frames)))?;
        let decoded =
            self.decoder.decode_packet(&p.packet).map_err(|e| refuse(format!("decoding a packet failed: {e}")))?;
        if decoded.len() != input.len() {
            return Err(refuse(format!("decoded {} coordinates, expected {}", decoded.len(), input.len())));
        }
        check_finite(&decoded, vertices, first).map_err(|e| refuse(format!("decoded frames are not finite: {e}")))?;
        if let Some(rec) = &p.reconstruction {
            if let Some(i) = rec.iter().zip(&decoded).position(|(a, b)| a.to_bits() != b.to_bits()) {
                return Err(refuse(format!(
                    "decoded frames differ from the encoder's reconstruction (first at coordinate {} of frame {first})",
                    i
                )));
            }
        }
        for (&x, &y) in input.iter().zip(&decoded) {
            let d = (x as f64 - y as f64).abs();
            self.max_error = self.max_error.max(d);
            self.sum_squared += d * d;
        }
        self.checked_frames += frames;
        if !self.keep_input {
            // Checked: these frames are no longer needed (bounded memory for long inputs).
            self.input.drain(..(local + frames) * per_frame);
            self.input_first = self.checked_frames;
        }
        Ok(())
    }

    /// The accumulated error against `bound`, like the conformance suite's check: a relative
    /// 1e-9 for the rounding of these f64 sums, nothing else loosened. A bound that is not
    /// finite (e.g. a relative one on a zero-extent animation) checks nothing.
    pub(crate) fn within(
        &self,
        bound: &ErrorBound,
        coordinates: usize,
        diagonal: f64,
    ) -> std::result::Result<(), String> {
        let slack = 1.0 + 1e-9;
        if let Some(b) = bound.max_coordinate_error.filter(|b| b.is_finite()) {
            if self.max_error > b * slack {
                return Err(format!("max coordinate error {:.6e} > bound {b:.6e}", self.max_error));
            }
        }
        if let Some(b) = bound.relative_rms_error.filter(|b| b.is_finite()) {
            let rms = (self.sum_squared / coordinates.max(1) as f64).sqrt();
            let rel = if diagonal > 0.0 {
                rms / diagonal
            } else if rms == 0.0 {
                0.0
            } else {
                f64::INFINITY
            };
            if rel > b * slack {
                return Err(format!("relative RMS error {rel:.6e} > bound {b:.6e}"));
            }
        }
        Ok(())
    }
}

/// Result of [`encode_animation`].
#[derive(Debug, Clone)]
pub struct Encoded {
    /// The container bytes.
    pub bytes: Vec<u8>,
    /// The encoder's reconstruction, when requested.
    pub reconstruction: Option<Animation>,
    /// The encoder's warnings ([`FrameEncoder::notes`]), e.g. a fallback it took to keep the
    /// stream within its bound.
    pub notes: Vec<String>,
}

/// Encodes a whole animation, pushing it in blocks of `feed_frames` frames (the bytes do
/// not depend on `feed_frames`; it exists so tests can prove that).
pub fn encode_animation_fed(
    codec: &dyn AnimationCodec,
    params: &ParamSet,
    animation: &Animation,
    want_reconstruction: bool,
    feed_frames: usize,
) -> Result<Encoded> {
    let mut enc = StreamEncoder::with_metadata(
        codec,
        params,
        animation.topology(),
        animation.frame_count(),
        animation.frame_rate(),
        want_reconstruction,
        animation.metadata(),
        Vec::new(),
    )?;
    let per_frame = animation.vertex_count() * 3;
    let mut rec = Vec::new();
    let mut keep = |packets: Vec<EncodedPacket>| {
        for p in packets {
            if let Some(r) = p.reconstruction {
                rec.extend_from_slice(&r);
            }
        }
    };
    for chunk in animation.positions().chunks(feed_frames.max(1) * per_frame) {
        keep(enc.push_frames(chunk)?);
    }
    let topology = enc.topology().clone();
    let (last, bytes, notes) = enc.finish_with_notes()?;
    keep(last);
    let reconstruction = if want_reconstruction {
        Some(Animation::new(topology, rec, animation.frame_rate())?.with_metadata(*animation.metadata())?)
    } else {
        None
    };
    Ok(Encoded { bytes, reconstruction, notes })
}

/// Encodes a whole animation into container bytes.
pub fn encode_animation(codec: &dyn AnimationCodec, params: &ParamSet, animation: &Animation) -> Result<Vec<u8>> {
    Ok(encode_animation_fed(codec, params, animation, false, animation.frame_count())?.bytes)
}

/// Frames decoded from one packet.
#[derive(Debug, Clone, PartialEq)]
pub struct DecodedPacket {
    /// First frame.
    pub first_frame: usize,
    /// Number of frames.
    pub frame_count: usize,
    /// Positions, `frame_count × vertices × 3`.
    pub positions: Vec<f32>,
}

/// Decodes a container from any `Read`, packet by packet.
pub struct StreamDecoder<R: Read> {
    reader: ContainerReader<R>,
    decoder: Box<dyn FrameDecoder>,
    codec: &'static str,
    index: Option<Vec<IndexEntry>>,
}

fn check_decoded(codec: &'static str, header: &Header, packet: &Packet, positions: &[f32]) -> Result<()> {
    let v = header.info.vertex_count();
    if positions.len() != packet.frame_count as usize * v * 3 {
        return Err(Error::malformed(
            codec,
            "packet",
            format!("decoded {} coordinates for {} frames of {v} vertices", positions.len(), packet.frame_count),
        ));
    }
    check_finite(positions, v, packet.first_frame as usize)
        .map_err(|e| Error::malformed(codec, "packet", format!("decoded frames are not finite: {e}")))
}

fn packet_alloc(header: &Header, frames: u64) -> u64 {
    frames * header.info.vertex_count() as u64 * 12
}

/// Decodes one packet the way every decode path does: its frames are charged to `limits`
/// before the codec runs, and the result must have the packet's shape
/// (`frame_count × vertices × 3`) and be finite. For callers that drive a [`FrameDecoder`]
/// themselves over [`container::read_packet_at`] (random access with a decoder kept between
/// calls, as the C library's player does); the caller resets `decoder` before a keyframe it
/// seeks to.
pub fn decode_packet_checked(
    decoder: &mut dyn FrameDecoder,
    codec: &'static str,
    header: &Header,
    packet: &Packet,
    limits: &Limits,
) -> Result<Vec<f32>> {
    limits.check_alloc(codec, "the decoded packet", packet_alloc(header, packet.frame_count as u64))?;
    let positions = decoder.decode_packet(packet)?;
    check_decoded(codec, header, packet, &positions)?;
    Ok(positions)
}

/// Frame `local` of `packet` by [`FrameDecoder::decode_frame_of_packet`], checked as
/// [`decode_packet_checked`] checks a packet: the packet's frames are charged to `limits` first
/// (what a codec's parse of the packet may hold, and the check every decode path makes, so a
/// stream too large for the limits is refused with the same message), and the frame must have
/// one frame's shape and be finite.
pub fn decode_frame_checked(
    decoder: &mut dyn FrameDecoder,
    codec: &'static str,
    header: &Header,
    packet: &Packet,
    local: usize,
    limits: &Limits,
) -> Result<Vec<f32>> {
    if local >= packet.frame_count as usize {
        return Err(crate::codec::frame_outside_packet(packet, local));
    }
    limits.check_alloc(codec, "the decoded packet", packet_alloc(header, packet.frame_count as u64))?;
    let frame = decoder.decode_frame_of_packet(packet, local)?;
    let one =
        Packet { first_frame: packet.first_frame + local as u32, frame_count: 1, keyframe: false, data: Vec::new() };
    check_decoded(codec, header, &one, &frame)?;
    Ok(frame)
}

/// The limits left for a codec decoder that random access builds: `limits` less the packet
/// `index` and the topology, which are held while it decodes (what [`decode_frame`] charges).
pub fn random_access_limits(
    codec: &'static str,
    header: &Header,
    index: &[IndexEntry],
    limits: Limits,
) -> Result<Limits> {
    limits.reserve(codec, "the index", std::mem::size_of_val(index) as u64)?.reserve(
        codec,
        "the topology",
        header.info.topology.triangle_count() as u64 * 12,
    )
}

impl<R: Read> StreamDecoder<R> {
    /// Reads the header and makes the decoder of the codec named by its FourCC. The decoded
    /// animation is charged to `limits` whole (what [`StreamDecoder::decode_all`] holds).
    pub fn new(src: R, registry: &CodecRegistry, limits: Limits) -> Result<Self> {
        Self::open(src, registry, limits, true)
    }

    /// [`StreamDecoder::new`] for a caller that takes packets one by one with
    /// [`StreamDecoder::next_packet`] and drops each before the next (`decode` to a
    /// PC2/MDD file writes frames as they are decoded): only one decoded packet at a time is
    /// charged to `limits`, so a stream far larger than the budget decodes within it.
    /// [`StreamDecoder::decode_all`] still checks the whole animation against `limits`.
    pub fn new_streaming(src: R, registry: &CodecRegistry, limits: Limits) -> Result<Self> {
        Self::open(src, registry, limits, false)
    }

    fn open(src: R, registry: &CodecRegistry, limits: Limits, whole: bool) -> Result<Self> {
        let reader = ContainerReader::new(src, limits)?;
        let header = reader.header();
        let codec = registry.by_fourcc(header.info.fourcc)?;
        if header.info.codec_version > codec.stream_version() || header.info.codec_version == 0 {
            return Err(Error::Unsupported {
                context: codec.name().into(),
                detail: format!(
                    "stream version {}; this build reads 1..={}",
                    header.info.codec_version,
                    codec.stream_version()
                ),
            });
        }
        // `Limits` bound the total a decode holds: the decoded animation (what `decode_all`
        // keeps; a caller taking packets one by one is charged the same) and the topology are
        // held throughout, so the codec's decoder gets what is left of the memory budget.
        let held = if whole { packet_alloc(header, header.info.frame_count as u64) } else { 0 };
        let decoder_limits = limits.reserve(codec.name(), "the decoded animation", held)?.reserve(
            codec.name(),
            "the topology",
            header.info.topology.triangle_count() as u64 * 12,
        )?;
        // Every decode writes each of its coordinates; a header whose frames alone
        // exceed the work budget is refused before any codec state is built.
        let info = &header.info;
        let coordinates = Limits::product(&[info.vertex_count() as u64, info.frame_count as u64, 3]);
        decoder_limits.check_work(
            codec.name(),
            "the decoded frames",
            coordinates.saturating_mul(crate::limits::WORK_PER_COORDINATE),
        )?;
        let decoder = codec.new_decoder(&header.info, &header.config, &decoder_limits)?;
        Ok(Self { codec: codec.name(), reader, decoder, index: None })
    }

    /// The container header.
    pub fn header(&self) -> &Header {
        self.reader.header()
    }

    /// Name of the codec decoding the stream.
    pub fn codec_name(&self) -> &'static str {
        self.codec
    }

    /// The index, once [`StreamDecoder::next_packet`] has returned `None`.
    pub fn index(&self) -> Option<&[IndexEntry]> {
        self.index.as_deref()
    }

    /// Decodes the next packet; `None` after the last one (the index has then been verified).
    pub fn next_packet(&mut self) -> Option<Result<DecodedPacket>> {
        match self.reader.next_section()? {
            Err(e) => Some(Err(e)),
            Ok(Section::End(index)) => {
                self.index = Some(index);
                None
            }
            Ok(Section::Packet(packet)) => Some(self.decode(&packet)),
        }
    }

    fn decode(&mut self, packet: &Packet) -> Result<DecodedPacket> {
        let limits = *self.reader.limits();
        let positions =
            decode_packet_checked(self.decoder.as_mut(), self.codec, self.reader.header(), packet, &limits)?;
        Ok(DecodedPacket {
            first_frame: packet.first_frame as usize,
            frame_count: packet.frame_count as usize,
            positions,
        })
    }

    /// Decodes every packet into one animation.
    pub fn decode_all(self) -> Result<Animation> {
        self.decode_all_reporting(&mut |_| {})
    }

    /// [`StreamDecoder::decode_all`], calling `frames_done` with the number of frames decoded
    /// so far after every packet (a progress display; the header's frame count is the total).
    pub fn decode_all_reporting(mut self, frames_done: &mut dyn FnMut(usize)) -> Result<Animation> {
        let header = self.reader.header();
        self.reader.limits().check_alloc(
            self.codec,
            "the decoded animation",
            packet_alloc(header, header.info.frame_count as u64),
        )?;
        let mut positions = Vec::new();
        let mut frames = 0;
        while let Some(p) = self.next_packet() {
            let p = p?;
            positions.extend_from_slice(&p.positions);
            frames += p.frame_count;
            frames_done(frames);
        }
        let header = self.reader.header();
        Animation::new(header.info.topology.clone(), positions, header.info.frame_rate)?.with_metadata(header.metadata)
    }
}

/// Decodes container bytes into an animation.
pub fn decode_animation(bytes: &[u8], registry: &CodecRegistry, limits: Limits) -> Result<Animation> {
    StreamDecoder::new(bytes, registry, limits)?.decode_all()
}

/// Decodes frame `t` of a seekable stream using the index: reads only the packets from the
/// nearest keyframe at or before the packet holding `t`.
pub fn decode_frame<R: Read + Seek>(
    src: &mut R,
    registry: &CodecRegistry,
    limits: Limits,
    t: usize,
) -> Result<Vec<f32>> {
    let (header, index) = container::read_index(src, limits)?;
    let codec = registry.by_fourcc(header.info.fourcc)?;
    let (start, target) = container::seek_packets(&index, t).ok_or_else(|| {
        Error::InvalidAnimation(format!("frame {t} is past the end of the stream ({} frames)", header.info.frame_count))
    })?;
    // The index, the topology and the packets from the keyframe on are held while decoding.
    let decoder_limits = random_access_limits(codec.name(), &header, &index, limits)?;
    let mut decoder = codec.new_decoder(&header.info, &header.config, &decoder_limits)?;
    decoder.reset();
    for entry in &index[start..=target] {
        let packet = container::read_packet_at(src, entry, &header, limits)?;
        if entry.first_frame as usize + entry.frame_count as usize > t {
            // The frame's packet: only that frame, where the codec can form it alone.
            let local = t - entry.first_frame as usize;
            return decode_frame_checked(decoder.as_mut(), codec.name(), &header, &packet, local, &limits);
        }
        decode_packet_checked(decoder.as_mut(), codec.name(), &header, &packet, &limits)?;
    }
    Err(Error::malformed(codec.name(), "index", format!("no packet holds frame {t}")))
}
