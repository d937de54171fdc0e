//! Searches on an input read frame by frame: what a search measures its candidates against
//! ([`SearchInput`]: the whole animation in memory, or a [`InputSource`] reopened for every
//! pass), the memory plan of a streamed search ([`StreamedInput`]) and one streamed
//! measurement ([`measure_point_streamed`]: encode from one read of the source, decode the
//! stream packet by packet against a second read).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

use animcodec_io::formats::stream::CacheReader;
use animcodec_io::formats::ReadOptions;
use codec_core::limits::DEFAULT_MAX_MEMORY;
use codec_core::memory::{MIB, PROCESS_BYTES};
use codec_core::{Animation, AnimationCodec, CodecRegistry, Limits, ParamSet, SceneMetadata, Topology};
use metrics::EvalOptions;

use super::measured::Point;
use super::streamed::{measure_bytes_held, measure_stream, FrameSource};
use crate::error::{EvalError, Result};

/// Frames read in order: [`FrameRead::read_frames`] clears `out`, fills it with the next
/// `frames` frames (fewer at the end; frame-major, `n × vertices × 3`) and returns how many, 0
/// at the end.
pub trait FrameRead {
    /// Reads the next frames (see the trait).
    fn read_frames(&mut self, frames: usize, out: &mut Vec<f32>) -> codec_core::Result<usize>;

    /// Passes over the next `frames` frames (fewer at the end) and returns how many. Default:
    /// reads them one at a time and drops them; a reader that can seek moves instead.
    fn skip_frames(&mut self, frames: usize) -> codec_core::Result<usize> {
        let mut scratch = Vec::new();
        let mut skipped = 0;
        while skipped < frames {
            match self.read_frames(1, &mut scratch)? {
                0 => break,
                n => skipped += n,
            }
        }
        Ok(skipped)
    }
}

impl FrameRead for CacheReader {
    fn read_frames(&mut self, frames: usize, out: &mut Vec<f32>) -> codec_core::Result<usize> {
        CacheReader::read_frames(self, frames, out)
    }

    fn skip_frames(&mut self, frames: usize) -> codec_core::Result<usize> {
        let from = self.frames_read();
        let to = from.saturating_add(frames).min(self.frame_count());
        self.seek_frame(to)?;
        Ok(to - from)
    }
}

/// An input that can be read from its first frame as often as a search needs (two reads per
/// candidate: one to encode, one to measure against), holding one reader's buffers at a time.
pub trait InputSource: Sync {
    /// The mesh.
    fn topology(&self) -> &Topology;
    /// Frames.
    fn frame_count(&self) -> usize;
    /// Frames per second.
    fn frame_rate(&self) -> f32;
    /// What the input says about its scene (the stream keeps it).
    fn metadata(&self) -> SceneMetadata {
        SceneMetadata::default()
    }
    /// A reader at frame 0.
    fn open(&self) -> Result<Box<dyn FrameRead + '_>>;
    /// A name for messages (the file, or the synthetic input's spec).
    fn name(&self) -> String;
    /// The frame count a codec's parameters are fitted to ([`AnimationCodec::fit_memory`]):
    /// the input's own, except for a sample of a longer input
    /// ([`SampledSource`](super::SampledSource)), which is coded in the blocks the whole is.
    fn fit_frame_count(&self) -> usize {
        self.frame_count()
    }
}

/// A PC2/MDD cache or an OBJ sequence ([`CacheReader`]), reopened for every read.
#[derive(Debug)]
pub struct CacheSource {
    path: PathBuf,
    options: ReadOptions,
    topology: Topology,
    frame_count: usize,
    frame_rate: f32,
}

impl CacheSource {
    /// Opens `path` once (header and topology checked, as [`CacheReader::open`] does) and keeps
    /// what every later read needs.
    pub fn open(path: &Path, options: &ReadOptions) -> Result<Self> {
        let reader = CacheReader::open(path, options)?;
        Ok(Self {
            path: path.to_path_buf(),
            options: options.clone(),
            topology: reader.topology().clone(),
            frame_count: reader.frame_count(),
            frame_rate: reader.frame_rate(),
        })
    }
}

impl InputSource for CacheSource {
    fn topology(&self) -> &Topology {
        &self.topology
    }
    fn frame_count(&self) -> usize {
        self.frame_count
    }
    fn frame_rate(&self) -> f32 {
        self.frame_rate
    }
    fn open(&self) -> Result<Box<dyn FrameRead + '_>> {
        let reader = CacheReader::open(&self.path, &self.options)?;
        // The file may have been replaced between two reads: a search must not measure one
        // file against another.
        if reader.frame_count() != self.frame_count || reader.vertex_count() != self.topology.vertex_count() {
            return Err(EvalError::Message(format!(
                "{}: changed while it was searched ({} frames × {} vertices, now {} × {})",
                self.path.display(),
                self.frame_count,
                self.topology.vertex_count(),
                reader.frame_count(),
                reader.vertex_count()
            )));
        }
        Ok(Box::new(reader))
    }
    fn name(&self) -> String {
        self.path.display().to_string()
    }
}

/// What a search's candidates are encoded from and measured against.
#[derive(Clone, Copy)]
pub enum SearchInput<'a> {
    /// The whole animation, in memory.
    Whole(&'a Animation),
    /// An input read frame by frame, within a memory budget.
    Streamed(&'a StreamedInput<'a>),
}

impl<'a> From<&'a Animation> for SearchInput<'a> {
    fn from(animation: &'a Animation) -> Self {
        SearchInput::Whole(animation)
    }
}

impl<'a> From<&'a StreamedInput<'a>> for SearchInput<'a> {
    fn from(streamed: &'a StreamedInput<'a>) -> Self {
        SearchInput::Streamed(streamed)
    }
}

impl SearchInput<'_> {
    /// Vertices per frame.
    pub fn vertex_count(&self) -> usize {
        match self {
            SearchInput::Whole(a) => a.vertex_count(),
            SearchInput::Streamed(s) => s.source.topology().vertex_count(),
        }
    }

    /// Frames.
    pub fn frame_count(&self) -> usize {
        match self {
            SearchInput::Whole(a) => a.frame_count(),
            SearchInput::Streamed(s) => s.source.frame_count(),
        }
    }

    /// Whether candidates are measured one at a time (a streamed input: each holds its share of
    /// the memory budget, so searches that measure in parallel take them in turn).
    pub fn sequential(&self) -> bool {
        matches!(self, SearchInput::Streamed(_))
    }
}

/// The share of a streamed search's memory budget kept for candidate streams, as a divisor:
/// a quarter. The search holds two streams at most (the smallest passing one so far and the
/// one being measured; a failing or larger stream is dropped as soon as it is measured), so
/// each may take half of it. The rest is the work share: the encoder's (its parameters are
/// fitted to it, [`AnimationCodec::fit_memory`]), then in turn the decoder's and the metrics'.
pub const STREAM_SHARE_DIVISOR: u64 = 4;

/// The least share of a streamed search's budget [`StreamedInput::giving_the_codec`] leaves
/// for candidate streams: 64 MiB (two streams of 32 MiB).
pub const MIN_STREAM_SHARE: u64 = 64 * MIB;

/// Frames of one decoded packet [`StreamedInput::least_budget`] leaves room for (the
/// codecs' packets are 8 frames or longer when their blocks are fitted to a budget).
const MIN_PACKET_FRAMES: u64 = 8;

/// A streamed search's input: the source, the memory budget and how it is shared, and the
/// smallest passing stream measured so far (streams larger than it are never chosen, so they
/// are not kept).
pub struct StreamedInput<'a> {
    source: &'a dyn InputSource,
    budget: u64,
    /// The bytes kept for candidate streams: a quarter of the budget, or less when the codec
    /// needs more ([`Self::giving_the_codec`]).
    stream_share: u64,
    feed: usize,
    smallest_passing: Mutex<Option<u64>>,
}

impl<'a> StreamedInput<'a> {
    /// A streamed input within `budget` bytes, feeding the encoder `feed` frames per call (the
    /// stream does not depend on it). Fails, naming the budget and the least one that would do,
    /// when the budget cannot hold the measurement of one frame (see [`Self::least_budget`]).
    pub fn new(source: &'a dyn InputSource, budget: u64, feed: usize, eval: &EvalOptions) -> Result<Self> {
        let least = Self::least_budget(source.topology(), eval);
        if budget < least {
            return Err(EvalError::Message(format!(
                "{}: --memory {} MiB is too small for a streamed search: it needs at least {} MiB (a quarter \
                 of the budget for candidate streams; the rest for the program ({} MiB), the metrics' window and \
                 frames of {} vertices, and the codec); give --memory {}M or more",
                source.name(),
                budget / MIB,
                least.div_ceil(MIB),
                PROCESS_BYTES / MIB,
                source.topology().vertex_count(),
                least.div_ceil(MIB)
            )));
        }
        Ok(Self {
            source,
            budget,
            stream_share: budget / STREAM_SHARE_DIVISOR,
            feed: feed.max(1),
            smallest_passing: Mutex::new(None),
        })
    }

    /// This input with at least `need` bytes of the budget for the codec's work (the least its
    /// encoder streams in, [`least_work_budget`]) when three quarters are less: candidate
    /// streams get the rest, down to [`MIN_STREAM_SHARE`] (then unchanged: the codec is refused
    /// later, naming the budget). A low-rate codec on a large input needs the memory for its
    /// blocks, not for its streams (hosvd at 1 000 000 vertices: 3.4 GiB for 8-frame blocks by
    /// its model, streams of a few MiB).
    pub fn giving_the_codec(mut self, need: u64) -> Self {
        self.stream_share = self.budget - work_share(self.budget, Some(need));
        self
    }

    /// The least budget a streamed search can run in: its work share must hold the program,
    /// the measurement's window and frames ([`measure_bytes_held`](super::measure_bytes_held))
    /// and a decoded packet of a few frames; the stream share comes on top.
    pub fn least_budget(topology: &Topology, eval: &EvalOptions) -> u64 {
        let frames = topology.vertex_count() as u64 * 12 * MIN_PACKET_FRAMES;
        let work = PROCESS_BYTES + measure_bytes_held(topology, eval) + frames;
        work.saturating_mul(STREAM_SHARE_DIVISOR).div_ceil(STREAM_SHARE_DIVISOR - 1)
    }

    /// The source.
    pub fn source(&self) -> &'a dyn InputSource {
        self.source
    }

    /// The whole budget.
    pub fn budget(&self) -> u64 {
        self.budget
    }

    /// Bytes one candidate stream may hold (half the stream share).
    pub fn stream_cap(&self) -> u64 {
        self.stream_share / 2
    }

    /// The work share: what the encoder's parameters are fitted to, and what the decoder and
    /// the metrics share afterwards.
    pub fn work_budget(&self) -> u64 {
        self.budget - self.stream_share
    }

    /// Whether a measured stream of `bytes` bytes that meets the target (`passes`) is worth
    /// keeping: only a passing stream no larger than every passing one before can be chosen
    /// (each search chooses the smallest passing stream; ties go to the earlier, which is
    /// kept).
    pub(crate) fn keep(&self, bytes: u64, passes: bool) -> bool {
        if !passes {
            return false;
        }
        let mut smallest = self.smallest_passing.lock().unwrap_or_else(|e| e.into_inner());
        match *smallest {
            Some(s) if bytes > s => false,
            _ => {
                *smallest = Some(bytes);
                true
            }
        }
    }
}

/// The least budget at which `codec` encodes `vertices × frames` at `params` unchanged (its
/// whole-input memory model, [`AnimationCodec::fit_memory`] probed by bisection); `None` when
/// even 1 PiB does not.
pub fn encoder_need(codec: &dyn AnimationCodec, params: &ParamSet, vertices: usize, frames: usize) -> Option<u64> {
    least_budget(|b| codec.fit_memory(params, vertices, frames, b).is_ok_and(|p| &p == params))
}

/// The least budget, to a MiB, for which `fits` holds (it must hold from there up), found by
/// bisection; `None` when even 1 PiB does not.
fn least_budget(fits: impl Fn(u64) -> bool) -> Option<u64> {
    let (mut lo, mut hi) = (0u64, 1u64 << 50);
    if !fits(hi) {
        return None;
    }
    while hi - lo > MIB {
        let mid = lo + (hi - lo) / 2;
        if fits(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Some(hi)
}

/// The work share of a streamed search's `budget` (see [`StreamedInput::work_budget`]): three
/// quarters, or the codec's `need` when that is more and leaves [`MIN_STREAM_SHARE`] for
/// candidate streams ([`StreamedInput::giving_the_codec`]).
pub fn work_share(budget: u64, need: Option<u64>) -> u64 {
    let default = budget - budget / STREAM_SHARE_DIVISOR;
    match need {
        Some(need) if need > default && budget.saturating_sub(need) >= MIN_STREAM_SHARE => need,
        _ => default,
    }
}

/// The least work share (to a MiB) in which `codec` encodes `vertices × frames` at `params`,
/// fitting them ([`AnimationCodec::fit_memory`] accepts it); `None` when even 1 PiB does not.
pub fn least_work_budget(codec: &dyn AnimationCodec, params: &ParamSet, vertices: usize, frames: usize) -> Option<u64> {
    least_budget(|b| codec.fit_memory(params, vertices, frames, b).is_ok())
}

/// The least budget a streamed search can give `codec` at `params` on `vertices × frames`:
/// the smallest budget whose work share (all but the 1/[`STREAM_SHARE_DIVISOR`] kept for streams) its
/// [`AnimationCodec::fit_memory`] accepts, found by bisection to a MiB; `None` when even 1 PiB
/// does not (a codec whose encoder holds the whole input). The parameters may still be
/// fitted (hosvd's blocks shrink); this is where fitting stops being possible.
pub fn least_streamed_budget(
    codec: &dyn AnimationCodec,
    params: &ParamSet,
    vertices: usize,
    frames: usize,
) -> Option<u64> {
    let work = |b: u64| b - b / STREAM_SHARE_DIVISOR;
    least_budget(|b| codec.fit_memory(params, vertices, frames, work(b)).is_ok())
}

/// About what a search over the whole animation holds at its peak with `codec`: the input,
/// one decoded candidate and the whole-array metrics' working copies (three times the raw
/// coordinates) plus the encoder's own need at the codec's defaults ([`encoder_need`]).
pub fn whole_search_need(codec: &dyn AnimationCodec, vertices: usize, frames: usize) -> u64 {
    let raw = (vertices as u64).saturating_mul(frames as u64).saturating_mul(12);
    let encoder = encoder_need(codec, &codec.default_params(), vertices, frames).unwrap_or(u64::MAX);
    raw.saturating_mul(3).saturating_add(encoder)
}

/// A `Vec<u8>` sink that refuses to grow past `cap` bytes.
struct CappedSink {
    bytes: Vec<u8>,
    cap: u64,
}

impl Write for CappedSink {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if self.bytes.len() as u64 + buf.len() as u64 > self.cap {
            return Err(std::io::Error::other(format!(
                "the candidate stream passed {} MiB, the most one stream may hold within the memory budget \
                 (half the share of --memory kept for candidate streams)",
                self.cap / MIB
            )));
        }
        self.bytes.extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// [`measure_point`](super::measure_point) on a streamed input: `params` fitted to the work
/// share of the budget ([`AnimationCodec::fit_memory`]; the point carries the fitted set), the
/// stream encoded from one read of the source into memory (at most
/// [`StreamedInput::stream_cap`] bytes), then decoded packet by packet and measured frame by
/// frame against a second read. Returns the point and its stream.
pub fn measure_point_streamed(
    registry: &CodecRegistry,
    codec: &dyn AnimationCodec,
    params: &ParamSet,
    (ladder_param, ladder_index): (&'static str, usize),
    input: &StreamedInput<'_>,
    eval: &EvalOptions,
    limits: Limits,
) -> Result<(Point, Vec<u8>)> {
    let source = input.source;
    let topology = source.topology();
    let (vertices, frames) = (topology.vertex_count(), source.frame_count());
    let params = codec.fit_memory(params, vertices, source.fit_frame_count(), input.work_budget())?;
    let start = Instant::now();
    let sink = CappedSink { bytes: Vec::new(), cap: input.stream_cap() };
    let (sink, notes) = encode_source(codec, &params, source, input.feed, sink, &|_| {})?;
    let bytes = sink.bytes;
    let encode_seconds = start.elapsed().as_secs_f64();
    let limits = measurement_limits(codec.name(), input.work_budget(), limits, topology, eval)?;
    let (mut report, decode_seconds) = measure_stream_against(registry, &bytes[..], source, eval, limits, &|_| {})?;
    report.notes.extend(notes.into_iter().map(|n| format!("encoder: {n}")));
    let size = bytes.len() as u64;
    let point = Point {
        codec: codec.name(),
        series: codec.name().to_string(),
        params,
        ladder_param,
        ladder_index,
        bytes: size,
        bpvf: metrics::bpvf(size, vertices, frames)?,
        report,
        encode_seconds,
        decode_seconds,
        refined: false,
    };
    Ok((point, bytes))
}

/// Encodes a read of `source` with `codec` at `params` (as given: fit them to the budget
/// first) into `sink`, `feed` frames per call, telling `pushed` the frames pushed so far;
/// returns the sink and the encoder's warnings.
pub fn encode_source<W: Write>(
    codec: &dyn AnimationCodec,
    params: &ParamSet,
    source: &dyn InputSource,
    feed: usize,
    sink: W,
    pushed: &dyn Fn(usize),
) -> Result<(W, Vec<String>)> {
    let topology = source.topology();
    let mut encoder = codec_core::StreamEncoder::with_metadata(
        codec,
        params,
        topology,
        source.frame_count(),
        source.frame_rate(),
        false,
        &source.metadata(),
        sink,
    )?;
    let per_frame = 3 * topology.vertex_count().max(1);
    let mut reader = source.open()?;
    let (mut block, mut done) = (Vec::new(), 0);
    while reader.read_frames(feed.max(1), &mut block)? > 0 {
        encoder.push_frames(&block)?;
        done += block.len() / per_frame;
        pushed(done);
    }
    drop(reader);
    let (_, sink, notes) = encoder.finish_with_notes()?;
    Ok((sink, notes))
}

/// The limits of a streamed measurement in `work_budget` bytes once the encoder is gone: the
/// decoder gets what the measurement's window and frames ([`measure_bytes_held`]) leave;
/// an error naming `codec` when they leave nothing.
///
/// The stream measured is one the search has just encoded, within its memory plan: the default
/// decode bound ([`DEFAULT_MAX_MEMORY`], 1 GiB, a guard against hostile streams) gives way to
/// the work share (at 1 000 000 vertices the metrics' window alone is ~0.9 GiB and a
/// quant-delta packet of 32 frames 384 MB); a bound set otherwise (`--max-memory`) still
/// applies.
pub fn measurement_limits(
    codec: &'static str,
    work_budget: u64,
    limits: Limits,
    topology: &Topology,
    eval: &EvalOptions,
) -> Result<Limits> {
    let work = usize::try_from(work_budget).unwrap_or(usize::MAX);
    let max_alloc_bytes =
        if limits.max_alloc_bytes == DEFAULT_MAX_MEMORY { work } else { limits.max_alloc_bytes.min(work) };
    let limits = Limits { max_alloc_bytes, ..limits };
    Ok(limits.reserve(codec, "the streaming metrics' window and frames", measure_bytes_held(topology, eval))?)
}

/// Decodes `stream` packet by packet and measures it against a fresh read of `source`
/// ([`measure_stream`](super::measure_stream)), telling `read` the frames of it read so far;
/// returns the report and the seconds the decode and the measurement took.
pub fn measure_stream_against(
    registry: &CodecRegistry,
    stream: impl std::io::Read,
    source: &dyn InputSource,
    eval: &EvalOptions,
    limits: Limits,
    read: &dyn Fn(usize),
) -> Result<(metrics::MetricReport, f64)> {
    let start = Instant::now();
    let mut reader = source.open()?;
    let mut done = 0;
    let mut read_frames = |n: usize, out: &mut Vec<f32>| {
        let n = reader.read_frames(n, out)?;
        done += n;
        read(done);
        Ok(n)
    };
    let reference = FrameSource {
        topology: source.topology(),
        frame_count: source.frame_count(),
        frame_rate: source.frame_rate(),
        read: &mut read_frames,
    };
    let report = measure_stream(registry, stream, reference, eval, limits)?;
    Ok((report, start.elapsed().as_secs_f64()))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::harness::{search_default_quality, search_space_target, SearchRequest, Target, TargetMetric};

    /// An animation in memory served frame by frame, as a file would be.
    pub(crate) struct InMemory(pub(crate) Animation);

    struct InMemoryReader<'a> {
        animation: &'a Animation,
        next: usize,
    }

    impl FrameRead for InMemoryReader<'_> {
        fn read_frames(&mut self, frames: usize, out: &mut Vec<f32>) -> codec_core::Result<usize> {
            out.clear();
            let n = frames.min(self.animation.frame_count() - self.next);
            let per_frame = self.animation.vertex_count() * 3;
            out.extend_from_slice(&self.animation.positions()[self.next * per_frame..(self.next + n) * per_frame]);
            self.next += n;
            Ok(n)
        }
    }

    impl InputSource for InMemory {
        fn topology(&self) -> &Topology {
            self.0.topology()
        }
        fn frame_count(&self) -> usize {
            self.0.frame_count()
        }
        fn frame_rate(&self) -> f32 {
            self.0.frame_rate()
        }
        fn metadata(&self) -> SceneMetadata {
            *self.0.metadata()
        }
        fn open(&self) -> Result<Box<dyn FrameRead + '_>> {
            Ok(Box::new(InMemoryReader { animation: &self.0, next: 0 }))
        }
        fn name(&self) -> String {
            "in memory".into()
        }
    }

    fn registry() -> CodecRegistry {
        CodecRegistry::new(vec![Box::new(codec_quant_delta::QuantDelta), Box::new(codec_pca_aoi::PcaAoi)]).unwrap()
    }

    /// The same search on the whole animation and on it streamed (a budget that changes no
    /// parameter): same points tried, same metrics, same chosen stream, byte for byte.
    #[test]
    fn streamed_searches_choose_what_whole_ones_do() {
        let registry = registry();
        let animation = animcodec_synth::tumbling_body_sized(10, 8, 24);
        let source = InMemory(animation.clone());
        let eval = EvalOptions::default();
        let kg: Target = Target::new(TargetMetric::Kg, 0.3);
        for codec in registry.iter() {
            for (target, space) in [(crate::harness::DEFAULT_TARGET, false), (kg, true)] {
                let streamed = StreamedInput::new(&source, 1 << 40, 5, &eval).unwrap();
                let whole_request = SearchRequest { refine: 2, ..SearchRequest::new(&registry, &animation, target) };
                let streamed_request =
                    SearchRequest { refine: 2, ..SearchRequest::streamed(&registry, &streamed, target) };
                let run = |request: &SearchRequest<'_>| {
                    if space {
                        search_space_target(request, codec, &codec.default_params(), &[])
                    } else {
                        search_default_quality(request, codec)
                    }
                };
                let (w, s) = (run(&whole_request).unwrap(), run(&streamed_request).unwrap());
                let view = |hit: &crate::harness::TargetHit| {
                    hit.tried
                        .iter()
                        .map(|p| (p.params.to_string(), p.bytes, p.report.kg, p.report.sted))
                        .collect::<Vec<_>>()
                };
                assert_eq!(view(&s), view(&w), "{} {target}", codec.name());
                assert_eq!(s.point.params, w.point.params);
                assert_eq!(s.point.report, w.point.report);
                assert!(!s.stream.is_empty());
                assert_eq!(s.stream, w.stream, "{} {target}", codec.name());
            }
        }
    }

    #[test]
    fn only_a_stream_that_can_still_be_chosen_is_kept() {
        let animation = animcodec_synth::tumbling_body_sized(6, 4, 4);
        let source = InMemory(animation);
        let input = StreamedInput::new(&source, 1 << 30, 1, &EvalOptions::default()).unwrap();
        assert!(!input.keep(100, false), "a failing stream");
        assert!(input.keep(100, true));
        assert!(!input.keep(101, true), "larger than a passing one before");
        assert!(input.keep(100, true), "a tie goes to the earlier, but the later is kept too");
        assert!(input.keep(90, true));
    }

    #[test]
    fn the_codec_gets_its_need_before_the_streams_their_quarter() {
        let g = 1u64 << 30;
        assert_eq!(work_share(4 * g, None), 3 * g);
        assert_eq!(work_share(4 * g, Some(2 * g)), 3 * g, "a need within three quarters changes nothing");
        assert_eq!(work_share(4 * g, Some(3 * g + g / 2)), 3 * g + g / 2);
        assert_eq!(work_share(4 * g, Some(4 * g - MIN_STREAM_SHARE)), 4 * g - MIN_STREAM_SHARE);
        assert_eq!(work_share(4 * g, Some(4 * g - MIN_STREAM_SHARE + 1)), 3 * g, "streams keep their least");
        let source = InMemory(animcodec_synth::tumbling_body_sized(6, 4, 4));
        let input = StreamedInput::new(&source, 4 * g, 1, &EvalOptions::default()).unwrap();
        let input = input.giving_the_codec(3 * g + g / 2);
        assert_eq!((input.work_budget(), input.stream_cap()), (3 * g + g / 2, g / 4));
    }

    #[test]
    fn a_budget_below_the_least_is_refused_naming_both() {
        let source = InMemory(animcodec_synth::tumbling_body_sized(6, 4, 4));
        let eval = EvalOptions::default();
        let least = StreamedInput::least_budget(source.topology(), &eval);
        let e = StreamedInput::new(&source, least - 1, 1, &eval).err().unwrap().to_string();
        assert!(e.contains("too small") && e.contains(&format!("{}M", least.div_ceil(MIB))), "{e}");
        assert!(StreamedInput::new(&source, least, 1, &eval).is_ok());
    }

    #[test]
    fn the_encoder_need_is_where_fit_memory_stops_changing_the_parameters() {
        let codec = codec_pca_aoi::PcaAoi;
        let params = codec.default_params();
        let need = encoder_need(&codec, &params, 50_000, 400).unwrap();
        assert_eq!(codec.fit_memory(&params, 50_000, 400, need).unwrap(), params);
        assert_ne!(codec.fit_memory(&params, 50_000, 400, need - 2 * MIB).ok(), Some(params));
    }
}
