//! The codec interface: an object-safe [`AnimationCodec`] that makes streaming
//! [`FrameEncoder`]s and [`FrameDecoder`]s.
//!
//! Frames reach an encoder in blocks as they arrive ([`FrameEncoder::push_frames`]); the
//! encoder emits [`Packet`]s whenever it has enough to code, and the rest at
//! [`FrameEncoder::finish`]. A codec that needs the whole sequence may buffer everything
//! until `finish`, but the interface never forces it to. Decoders turn packets back into
//! frames, one packet at a time.

use std::fmt;

use crate::animation::{Animation, Topology};
use crate::error::Error;
use crate::error::Result;
use crate::limits::Limits;
use crate::params::{
    DeclaredParams, DistortionKind, ParamSet, ParamSpec, ParamValue, RateLadder, SearchSpace, Setting,
};

/// Four-character code identifying a codec inside a stream (never a list index).
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct FourCc(pub [u8; 4]);

impl FourCc {
    /// Builds a FourCC from four ASCII bytes.
    pub const fn new(code: &[u8; 4]) -> Self {
        Self(*code)
    }
}

impl fmt::Display for FourCc {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for &b in &self.0 {
            if b.is_ascii_graphic() || b == b' ' {
                write!(f, "{}", b as char)?;
            } else {
                write!(f, "\\x{b:02x}")?;
            }
        }
        Ok(())
    }
}

impl fmt::Debug for FourCc {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "FourCc({self})")
    }
}

/// One unit of coded data: the frames `first_frame .. first_frame + frame_count`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Packet {
    /// Index of the first frame this packet decodes to.
    pub first_frame: u32,
    /// Number of frames it decodes to (at least one).
    pub frame_count: u32,
    /// True when the packet decodes without any earlier packet (a random-access point).
    pub keyframe: bool,
    /// Codec payload.
    pub data: Vec<u8>,
}

/// A packet plus, when asked for, the encoder's own reconstruction of its frames
/// (`frame_count × vertices × 3`), which must equal the decoder's output bit for bit.
#[derive(Debug, Clone, PartialEq)]
pub struct EncodedPacket {
    /// The packet.
    pub packet: Packet,
    /// The frames a decoder will produce from it, if requested in [`EncoderSetup`].
    pub reconstruction: Option<Vec<f32>>,
}

/// What an encoder knows before the first frame arrives.
#[derive(Debug, Clone, Copy)]
pub struct EncoderSetup<'a> {
    /// Connectivity shared by every frame.
    pub topology: &'a Topology,
    /// Total number of frames that will be pushed.
    pub frame_count: usize,
    /// Frames per second.
    pub frame_rate: f32,
    /// Whether the encoder should attach its reconstruction to every packet.
    pub want_reconstruction: bool,
}

/// What a decoder is told about the stream, all read from the container header.
#[derive(Debug, Clone)]
pub struct StreamInfo {
    /// Codec identity.
    pub fourcc: FourCc,
    /// Version of the codec's own bitstream.
    pub codec_version: u16,
    /// Connectivity (decoded from the topology section).
    pub topology: Topology,
    /// Number of frames in the stream.
    pub frame_count: usize,
    /// Frames per second.
    pub frame_rate: f32,
}

impl StreamInfo {
    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.topology.vertex_count()
    }
}

/// The error a codec promises on a given input, checked by the conformance suite.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ErrorBound {
    /// Every coordinate of every vertex in every frame is within this absolute distance.
    pub max_coordinate_error: Option<f64>,
    /// Root mean square of the per-coordinate error, relative to the bounding-box diagonal.
    pub relative_rms_error: Option<f64>,
}

/// A streaming encoder made by [`AnimationCodec::new_encoder`].
pub trait FrameEncoder: Send {
    /// Stream-level configuration written once into the container header and handed to
    /// the decoder (for example bit depths). Fixed at construction.
    fn config(&self) -> Vec<u8>;

    /// Accepts the next `frames` (a whole number of frames, frame-major `n × vertices × 3`,
    /// already checked finite) and returns the packets it completes, in order.
    fn push_frames(&mut self, frames: &[f32]) -> Result<Vec<EncodedPacket>>;

    /// Codes whatever is buffered and returns the last packets.
    fn finish(&mut self) -> Result<Vec<EncodedPacket>>;

    /// Warnings about the stream just coded that its user should see (for example that an
    /// error guard had to replace many frames), one sentence each, naming the codec. Read
    /// after [`FrameEncoder::finish`]; the CLI prints them and `--json` lists them. Most
    /// encoders have none (the default).
    fn notes(&self) -> Vec<String> {
        Vec::new()
    }

    /// The bound of what this encoder coded, when it knows it without extra work (read after
    /// [`FrameEncoder::finish`]; must equal [`AnimationCodec::error_bound`] on the same input).
    /// The stream driver's self-check uses it; `None` (the default) makes the driver keep the
    /// input and ask [`AnimationCodec::error_bound`].
    fn declared_bound(&self) -> Option<ErrorBound> {
        None
    }
}

/// A decoder made by [`AnimationCodec::new_decoder`]. Packets arrive in stream order; after a
/// seek the caller calls [`FrameDecoder::reset`] and resumes at a keyframe packet.
pub trait FrameDecoder: Send {
    /// Decodes one packet to its frames (`frame_count × vertices × 3`). Every byte is
    /// untrusted: any inconsistency is an error, never a panic.
    fn decode_packet(&mut self, packet: &Packet) -> Result<Vec<f32>>;

    /// Forgets state carried between packets (called before decoding from a keyframe after a seek).
    fn reset(&mut self) {}

    /// Frame `local` (`< packet.frame_count`) of `packet`, `vertices × 3` values, equal bit for
    /// bit to that frame of [`decode_packet`](Self::decode_packet) on the same packet in the
    /// same decoder state. Random access calls it for one frame of a packet.
    ///
    /// Default: decodes the whole packet and copies the frame out (so the state carried between
    /// packets advances as `decode_packet`'s does). A codec whose packets decode alone overrides
    /// it to parse the packet once (kept in a [`ParsedPacket`]) and form only the frame asked
    /// for, and then reports [`decodes_single_frames`](Self::decodes_single_frames).
    fn decode_frame_of_packet(&mut self, packet: &Packet, local: usize) -> Result<Vec<f32>> {
        let frames = self.decode_packet(packet)?;
        let count = packet.frame_count as usize;
        let per_frame = frames.len().checked_div(count).unwrap_or(0);
        if local >= count || per_frame * count != frames.len() {
            return Err(frame_outside_packet(packet, local));
        }
        Ok(frames[local * per_frame..(local + 1) * per_frame].to_vec())
    }

    /// True when [`decode_frame_of_packet`](Self::decode_frame_of_packet) costs about one
    /// frame once the packet is parsed (the parse kept for the next frame of the same packet)
    /// and leaves the state carried between packets as it was. Default: false (it decodes the
    /// whole packet).
    fn decodes_single_frames(&self) -> bool {
        false
    }

    /// Lets a decoder that [decodes single frames](Self::decodes_single_frames) keep the parses
    /// of several packets, up to `bytes` bytes in all, instead of the last one only (random
    /// access over a whole stream then parses each packet once). Default: nothing kept.
    fn keep_parsed_packets(&mut self, bytes: u64) {
        let _ = bytes;
    }
}

/// The refusal of a frame index outside its packet.
pub fn frame_outside_packet(packet: &Packet, local: usize) -> Error {
    Error::InvalidAnimation(format!(
        "frame {local} of a packet of {} frames (frames {}..{}) is outside it",
        packet.frame_count,
        packet.first_frame,
        u64::from(packet.first_frame) + u64::from(packet.frame_count)
    ))
}

/// The parsed forms of the packets a decoder was last asked frames of (a codec's dictionaries,
/// factors or coefficients before the frames are formed), so that each further frame of a kept
/// packet costs one frame. A packet is recognised by its first frame, frame count, keyframe flag
/// and bytes (a copy is kept: packets are small next to what they decode to).
///
/// By default only the last packet is kept. [`ParsedPacket::set_budget`] keeps more, the most
/// recently used first, while their sizes (as the codec reports them to
/// [`ParsedPacket::keep`]) add up to at most the budget: random access over a whole stream then
/// parses every packet once.
#[derive(Debug)]
pub struct ParsedPacket<T> {
    /// Most recently used last: (packet, parse, its bytes).
    kept: Vec<(Packet, T, u64)>,
    budget: u64,
}

impl<T> Default for ParsedPacket<T> {
    fn default() -> Self {
        Self { kept: Vec::new(), budget: 0 }
    }
}

impl<T> ParsedPacket<T> {
    /// Keeps parses while their bytes (and their packets') add up to at most `bytes` (the last
    /// one is kept whatever its size).
    pub fn set_budget(&mut self, bytes: u64) {
        self.budget = bytes;
        if let Some(last) = self.kept.pop() {
            self.evict(last.2);
            self.kept.push(last);
        }
    }

    fn position(&self, packet: &Packet) -> Option<usize> {
        self.kept.iter().rposition(|(p, _, _)| {
            p.first_frame == packet.first_frame
                && p.frame_count == packet.frame_count
                && p.keyframe == packet.keyframe
                && p.data == packet.data
        })
    }

    /// Whether the parse of `packet` is kept.
    pub fn holds(&self, packet: &Packet) -> bool {
        self.position(packet).is_some()
    }

    /// The kept parse of `packet`, if it is kept (it becomes the most recently used).
    pub fn get(&mut self, packet: &Packet) -> Option<&T> {
        let i = self.position(packet)?;
        let entry = self.kept.remove(i);
        self.kept.push(entry);
        self.kept.last().map(|(_, parsed, _)| parsed)
    }

    /// Keeps `parsed`, of `bytes` bytes, as the parse of `packet`, dropping the least recently
    /// used parses beyond the budget.
    pub fn keep(&mut self, packet: &Packet, parsed: T, bytes: u64) -> &T {
        if let Some(i) = self.position(packet) {
            self.kept.remove(i);
        }
        let bytes = bytes.saturating_add(packet.data.len() as u64);
        self.evict(bytes);
        self.kept.push((Packet { data: packet.data.clone(), ..*packet }, parsed, bytes));
        &self.kept[self.kept.len() - 1].1
    }

    /// Drops the least recently used parses until `more` bytes fit the budget with the rest.
    fn evict(&mut self, more: u64) {
        let mut total = self.kept.iter().map(|k| k.2).fold(more, u64::saturating_add);
        while total > self.budget && !self.kept.is_empty() {
            total -= self.kept.remove(0).2;
        }
    }

    /// Drops every kept parse.
    pub fn clear(&mut self) {
        self.kept.clear();
    }
}

/// A codec: identity, parameters, rate knob, and factories for encoders and decoders.
///
/// Object safe, so one [`CodecRegistry`](crate::CodecRegistry) holds every codec. A codec crate
/// implements [`TypedCodec`] instead, on its typed parameters, and gets this trait from the
/// adapter; implementing it directly (a test double wrapping another codec, say) still works.
pub trait AnimationCodec: Send + Sync {
    /// Stable name used on the command line (`quant-delta`, `pca-aoi`, …).
    fn name(&self) -> &'static str;

    /// FourCC written into the stream.
    fn fourcc(&self) -> FourCc;

    /// Version of this codec's bitstream that the encoder writes.
    fn stream_version(&self) -> u16;

    /// One-line description.
    fn summary(&self) -> &'static str;

    /// Parameters with kinds, ranges, defaults and docs.
    fn param_specs(&self) -> Vec<ParamSpec>;

    /// Parameter values, all at their defaults.
    fn default_params(&self) -> ParamSet {
        ParamSet::defaults(self.name(), &self.param_specs())
    }

    /// The one rate knob walked on top of `base`, from small streams to large. The ladder may
    /// depend on `base` (pca-aoi walks `k` in its fixed-rank modes but the error band in
    /// `qaoi`); every step applied to `base` must validate.
    fn rate_ladder(&self, base: &ParamSet) -> RateLadder;

    /// The space quality-targeted rate control searches on top of `base`: the rate ladder as
    /// the primary axis, and the secondary parameters worth trying with it (each value of
    /// every configuration applied to `base` must validate). Default: the ladder alone.
    /// A caller that fixes a parameter explicitly removes its axis (see
    /// [`SearchSpace::without`]).
    fn search_space(&self, base: &ParamSet) -> SearchSpace {
        SearchSpace::ladder_only(self.rate_ladder(base))
    }

    /// The part of [`search_space`](Self::search_space) a target search for an error of
    /// `kind` walks: the configurations that can give the smallest stream for such a target.
    /// The full space (what `sweep` measures for its envelopes) must contain every
    /// configuration returned here. Default: the full space.
    fn search_space_for(&self, base: &ParamSet, kind: DistortionKind) -> SearchSpace {
        let _ = kind;
        self.search_space(base)
    }

    /// Where on its rate ladder a target search for an error of `kind` starts (a value of
    /// the ladder's parameter), when the usual answers for that kind lie away from `base`'s
    /// own step. Default: `None`, `base`'s step. A start near the answer saves encodes, not
    /// quality: the search still brackets the target.
    fn search_start(&self, base: &ParamSet, kind: DistortionKind) -> Option<ParamValue> {
        let _ = (base, kind);
        None
    }

    /// Checks a full parameter set, including constraints between parameters; errors state
    /// the allowed range.
    fn validate(&self, params: &ParamSet) -> Result<()>;

    /// The error this codec promises for `animation` at `params`.
    fn error_bound(&self, params: &ParamSet, animation: &Animation) -> Result<ErrorBound>;

    /// `params` adapted so that encoding `vertices × frames` holds at most about
    /// `budget` bytes (the user's `encode --memory`). A codec whose analysis holds a whole
    /// block of frames at once (hosvd's `block=0`, the whole sequence) chooses a temporal
    /// block that fits; parameters the user fixed otherwise are kept. The choice depends only
    /// on the arguments (never on the machine), so the stream does too. Fails when no setting
    /// fits, naming the least budget that would. Default: `params` unchanged (the codec's
    /// memory is already bounded by its packets, or it has no block to choose).
    fn fit_memory(&self, params: &ParamSet, vertices: usize, frames: usize, budget: u64) -> Result<ParamSet> {
        let _ = (vertices, frames, budget);
        Ok(params.clone())
    }

    /// For distributed encoding: the frames per temporal block when every packet of
    /// `params` on an animation of `frame_count` frames is coded from its own block's frames
    /// alone — no state carried from earlier packets into the packet bytes — so that block `i`
    /// encoded on its own (any machine, any order) gives the very packet the whole encode
    /// writes ([`crate::blocks`]). Packets then cover frames `i × block ..` up to the next block
    /// (the last may be shorter). Default: refused (naming the codec), for codecs whose
    /// packets depend on earlier frames or whose analysis spans the whole sequence.
    fn independent_blocks(&self, params: &ParamSet, frame_count: usize) -> Result<usize> {
        let _ = (params, frame_count);
        Err(no_independent_blocks(self.name()))
    }

    /// A streaming encoder.
    fn new_encoder(&self, params: &ParamSet, setup: &EncoderSetup<'_>) -> Result<Box<dyn FrameEncoder>>;

    /// A decoder for a stream with this codec's FourCC. `config` is the encoder's
    /// [`FrameEncoder::config`], read back from the header and untrusted.
    fn new_decoder(&self, info: &StreamInfo, config: &[u8], limits: &Limits) -> Result<Box<dyn FrameDecoder>>;
}

/// The refusal of [`AnimationCodec::independent_blocks`] for a codec whose packets depend on
/// earlier frames.
fn no_independent_blocks(codec: &'static str) -> Error {
    Error::Unsupported {
        context: codec.into(),
        detail: "its packets are not coded from independent temporal blocks, so it cannot be encoded block by block \
                 (quant-delta, hosvd and pca-aoi with mode=svd can)"
            .into(),
    }
}

/// A codec written against its typed parameters: what a codec crate implements. One blanket
/// adapter makes every `TypedCodec` an [`AnimationCodec`], the object-safe form the registry
/// holds: it converts the generic [`ParamSet`] to [`TypedCodec::Params`] once per call
/// ([`DeclaredParams::from_set`], with the codec's own checks) and back, so no codec reads a
/// parameter by its name.
///
/// The hooks mirror [`AnimationCodec`]'s under shorter names (so that a type implementing both
/// through the adapter never has two methods of one name in scope): see each for its contract.
/// The rate-control hooks ([`ladder`](Self::ladder), [`space`](Self::space),
/// [`space_for`](Self::space_for), [`start`](Self::start)) get the fields of `base` as read,
/// without the cross-field checks (the search's own encodes run them), or the defaults when
/// `base` belongs to another codec.
pub trait TypedCodec: Send + Sync {
    /// The codec's parameters, declared with [`declare_params!`](crate::declare_params).
    type Params: DeclaredParams;
    /// Stable name used on the command line ([`AnimationCodec::name`]).
    const NAME: &'static str;
    /// FourCC written into the stream.
    const FOURCC: FourCc;
    /// Version of this codec's bitstream that the encoder writes.
    const STREAM_VERSION: u16;
    /// One-line description.
    const SUMMARY: &'static str;

    /// The rate ladder on top of `base` ([`AnimationCodec::rate_ladder`]).
    fn ladder(&self, base: &Self::Params) -> RateLadder;

    /// The space a quality-targeted search walks ([`AnimationCodec::search_space`]). Default:
    /// the ladder alone.
    fn space(&self, base: &Self::Params) -> SearchSpace {
        SearchSpace::ladder_only(self.ladder(base))
    }

    /// The part of the space a search for an error of `kind` walks
    /// ([`AnimationCodec::search_space_for`]). Default: the whole space.
    fn space_for(&self, base: &Self::Params, kind: DistortionKind) -> SearchSpace {
        let _ = kind;
        self.space(base)
    }

    /// Where a search for an error of `kind` starts on the ladder
    /// ([`AnimationCodec::search_start`]). Default: `base`'s own step.
    fn start(&self, base: &Self::Params, kind: DistortionKind) -> Option<ParamValue> {
        let _ = (base, kind);
        None
    }

    /// Checks beyond the declaration's own (run by [`AnimationCodec::validate`] after the
    /// parameters were read and their cross-field checks passed). Default: none.
    fn check(&self, params: &Self::Params) -> Result<()> {
        let _ = params;
        Ok(())
    }

    /// The error promised for `animation` ([`AnimationCodec::error_bound`]).
    fn bound(&self, params: &Self::Params, animation: &Animation) -> Result<ErrorBound>;

    /// The parameter changes that make an encode of `vertices × frames` fit `budget` bytes
    /// ([`AnimationCodec::fit_memory`]; build them with [`Param::to`](crate::params::Param::to)).
    /// Default: none.
    fn fit(&self, params: &Self::Params, vertices: usize, frames: usize, budget: u64) -> Result<Vec<Setting>> {
        let _ = (params, vertices, frames, budget);
        Ok(Vec::new())
    }

    /// Frames per independently coded temporal block ([`AnimationCodec::independent_blocks`]).
    /// Default: refused.
    fn blocks(&self, params: &Self::Params, frame_count: usize) -> Result<usize> {
        let _ = (params, frame_count);
        Err(no_independent_blocks(Self::NAME))
    }

    /// A streaming encoder ([`AnimationCodec::new_encoder`]).
    fn encoder(&self, params: Self::Params, setup: &EncoderSetup<'_>) -> Result<Box<dyn FrameEncoder>>;

    /// A decoder ([`AnimationCodec::new_decoder`]).
    fn decoder(&self, info: &StreamInfo, config: &[u8], limits: &Limits) -> Result<Box<dyn FrameDecoder>>;
}

/// The fields of a rate-control hook's `base`: read without the cross-field checks, the
/// defaults for a set of another codec.
fn base_fields<P: DeclaredParams>(base: &ParamSet) -> P {
    P::read_fields(base).unwrap_or_default()
}

/// The adapter: every [`TypedCodec`] is an [`AnimationCodec`].
impl<C: TypedCodec> AnimationCodec for C {
    fn name(&self) -> &'static str {
        C::NAME
    }
    fn fourcc(&self) -> FourCc {
        C::FOURCC
    }
    fn stream_version(&self) -> u16 {
        C::STREAM_VERSION
    }
    fn summary(&self) -> &'static str {
        C::SUMMARY
    }
    fn param_specs(&self) -> Vec<ParamSpec> {
        C::Params::param_specs()
    }
    fn rate_ladder(&self, base: &ParamSet) -> RateLadder {
        self.ladder(&base_fields(base))
    }
    fn search_space(&self, base: &ParamSet) -> SearchSpace {
        self.space(&base_fields(base))
    }
    fn search_space_for(&self, base: &ParamSet, kind: DistortionKind) -> SearchSpace {
        self.space_for(&base_fields(base), kind)
    }
    fn search_start(&self, base: &ParamSet, kind: DistortionKind) -> Option<ParamValue> {
        self.start(&base_fields(base), kind)
    }
    fn validate(&self, params: &ParamSet) -> Result<()> {
        self.check(&C::Params::from_set(params)?)
    }
    fn error_bound(&self, params: &ParamSet, animation: &Animation) -> Result<ErrorBound> {
        self.bound(&C::Params::from_set(params)?, animation)
    }
    fn fit_memory(&self, params: &ParamSet, vertices: usize, frames: usize, budget: u64) -> Result<ParamSet> {
        let changes = self.fit(&C::Params::from_set(params)?, vertices, frames, budget)?;
        if changes.is_empty() {
            return Ok(params.clone());
        }
        SearchSpace::apply(params, &C::Params::param_specs(), &changes)
    }
    fn independent_blocks(&self, params: &ParamSet, frame_count: usize) -> Result<usize> {
        self.blocks(&C::Params::from_set(params)?, frame_count)
    }
    fn new_encoder(&self, params: &ParamSet, setup: &EncoderSetup<'_>) -> Result<Box<dyn FrameEncoder>> {
        self.encoder(C::Params::from_set(params)?, setup)
    }
    fn new_decoder(&self, info: &StreamInfo, config: &[u8], limits: &Limits) -> Result<Box<dyn FrameDecoder>> {
        self.decoder(info, config, limits)
    }
}

#[cfg(test)]
mod parsed_packet_tests {
    use super::*;

    fn packet(first: u32, byte: u8) -> Packet {
        Packet { first_frame: first, frame_count: 2, keyframe: true, data: vec![byte; 10] }
    }

    /// Without a budget only the last parse is kept; with one, the most recently used parses
    /// that fit it (packet bytes included), the least recently used dropped first; a packet
    /// with other bytes is another packet.
    #[test]
    fn kept_parses_follow_the_budget_least_recently_used_first() {
        let mut kept = ParsedPacket::default();
        kept.keep(&packet(0, 1), "a", 100);
        kept.keep(&packet(2, 1), "b", 100);
        assert!(!kept.holds(&packet(0, 1)) && kept.holds(&packet(2, 1)));
        assert!(!kept.holds(&packet(2, 9)), "same frames, other bytes");
        kept.set_budget(330);
        kept.keep(&packet(0, 1), "a", 100);
        kept.keep(&packet(4, 1), "c", 100);
        assert_eq!(kept.get(&packet(2, 1)), Some(&"b")); // now the most recently used
        kept.keep(&packet(6, 1), "d", 100); // 4 × 110 > 330: the least recently used ("a") goes
        assert!(!kept.holds(&packet(0, 1)));
        assert!(kept.holds(&packet(2, 1)) && kept.holds(&packet(4, 1)) && kept.holds(&packet(6, 1)));
        kept.set_budget(0);
        assert!(kept.holds(&packet(6, 1)) && !kept.holds(&packet(2, 1)), "the last one stays");
        kept.clear();
        assert!(!kept.holds(&packet(6, 1)));
    }
}
