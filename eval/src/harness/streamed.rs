//! Measuring without holding either animation whole: an `.anim` stream decoded packet by
//! packet ([`measure_stream`]) or a second animation read frame by frame ([`measure_sources`]),
//! against a reference read frame by frame, through [`metrics::StreamingEvaluator`]. The report
//! is the one [`metrics::evaluate`] gives for the same pair (`metrics::streaming` says which
//! fields are bit-identical). Memory: the evaluator's window, one decoded packet (the codec's
//! decoder state), and [`CHUNK_BYTES`] of reference (and candidate) frames at a time.

use std::io::Read;

use codec_core::{CodecRegistry, Error, Limits, StreamDecoder, Topology};
use metrics::{check_compatible_shapes, EvalOptions, MetricReport, StreamingEvaluator};

use crate::error::Result;

/// One side of a comparison read frame by frame: its shape, and a reader of its next frames.
pub struct FrameSource<'a> {
    /// The connectivity (the reference's is the one the metrics use, as in `evaluate`).
    pub topology: &'a Topology,
    /// Frames in all.
    pub frame_count: usize,
    /// Frames per second.
    pub frame_rate: f32,
    /// Reads the next `n` frames into the vector (cleared first, frame-major `n × vertices × 3`)
    /// and returns how many it read, 0 at the end: `CacheReader::read_frames`
    /// (`animcodec_io::formats::stream`) has this shape.
    pub read: &'a mut dyn FnMut(usize, &mut Vec<f32>) -> codec_core::Result<usize>,
}

/// Bytes of frames read and pushed at a time (but at least one frame per worker thread, which
/// the metrics measure in parallel).
pub const CHUNK_BYTES: u64 = 8 << 20;

/// Frames of `vertex_count` vertices in one chunk: [`CHUNK_BYTES`] of them, at least one per
/// worker thread.
pub fn chunk_frames(vertex_count: usize) -> usize {
    let threads = rayon::current_num_threads().max(1) as u64;
    (CHUNK_BYTES / (12 * vertex_count.max(1) as u64)).max(threads) as usize
}

/// Bytes [`measure_stream`] and [`measure_sources`] hold besides the codec's decoder and one
/// decoded packet: the evaluator's window ([`StreamingEvaluator::bytes_held`]) and two chunks of
/// frames (reference and candidate).
pub fn measure_bytes_held(topology: &Topology, options: &EvalOptions) -> u64 {
    let frame = 12 * topology.vertex_count() as u64;
    StreamingEvaluator::bytes_held(topology, options) + 2 * frame * chunk_frames(topology.vertex_count()) as u64
}

/// Reads exactly `n` frames of `source` into `out`, or fails naming the side and the frame.
fn read_exact_frames(source: &mut FrameSource, side: &str, first: usize, n: usize, out: &mut Vec<f32>) -> Result<()> {
    let got = (source.read)(n, out)?;
    let per_frame = 3 * source.topology.vertex_count();
    if got != n || out.len() != n * per_frame {
        return Err(Error::InvalidAnimation(format!(
            "the {side} ended after {} of its {} frames",
            first + got.min(n),
            source.frame_count
        ))
        .into());
    }
    Ok(())
}

/// Measures the `.anim` stream read from `stream` against `reference`, decoding packet by
/// packet: every metric of [`metrics::evaluate`] on (reference, decoded stream). `limits`
/// bound the decode as `decode` to a cache file does (one packet at a time); what the
/// measurement holds besides is [`measure_bytes_held`], for the caller to budget. Fails on a
/// stream that does not decode, a shape that differs from the reference's (vertices, frames,
/// triangles), or a reference that ends early.
pub fn measure_stream<R: Read>(
    registry: &CodecRegistry,
    stream: R,
    mut reference: FrameSource,
    options: &EvalOptions,
    limits: Limits,
) -> Result<MetricReport> {
    let mut decoder = StreamDecoder::new_streaming(stream, registry, limits)?;
    let info = decoder.header().info.clone();
    check_compatible_shapes((reference.topology, reference.frame_count), (&info.topology, info.frame_count))?;
    let mut evaluator =
        StreamingEvaluator::new(reference.topology, reference.frame_count, reference.frame_rate, options)?;
    let per_frame = 3 * reference.topology.vertex_count();
    let chunk = chunk_frames(reference.topology.vertex_count());
    let mut buffer = Vec::new();
    while let Some(packet) = decoder.next_packet() {
        let packet = packet?;
        for part in packet.positions.chunks(chunk * per_frame) {
            let n = part.len() / per_frame;
            read_exact_frames(&mut reference, "reference", evaluator.frames_pushed(), n, &mut buffer)?;
            evaluator.push(&buffer, part)?;
        }
    }
    Ok(evaluator.finish()?)
}

/// Measures `candidate` against `reference`, both read frame by frame ([`CHUNK_BYTES`] at a
/// time): every metric of [`metrics::evaluate`]. Fails on different shapes or a side that ends
/// early.
pub fn measure_sources(
    mut reference: FrameSource,
    mut candidate: FrameSource,
    options: &EvalOptions,
) -> Result<MetricReport> {
    check_compatible_shapes((reference.topology, reference.frame_count), (candidate.topology, candidate.frame_count))?;
    let mut evaluator =
        StreamingEvaluator::new(reference.topology, reference.frame_count, reference.frame_rate, options)?;
    let chunk = chunk_frames(reference.topology.vertex_count());
    let (mut a, mut b) = (Vec::new(), Vec::new());
    while evaluator.frames_pushed() < reference.frame_count {
        let first = evaluator.frames_pushed();
        let n = chunk.min(reference.frame_count - first);
        read_exact_frames(&mut reference, "reference", first, n, &mut a)?;
        read_exact_frames(&mut candidate, "candidate", first, n, &mut b)?;
        evaluator.push(&a, &b)?;
    }
    Ok(evaluator.finish()?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use codec_core::{encode_animation_fed, Animation, ParamSet, ParamValue};

    fn registry() -> CodecRegistry {
        CodecRegistry::new(vec![Box::new(codec_quant_delta::QuantDelta), Box::new(codec_pca_aoi::PcaAoi)]).unwrap()
    }

    /// A reader over an in-memory animation, `n` frames at a time.
    fn reader(a: &Animation) -> impl FnMut(usize, &mut Vec<f32>) -> codec_core::Result<usize> + '_ {
        let mut next = 0;
        move |n, out| {
            out.clear();
            let n = n.min(a.frame_count() - next);
            out.extend_from_slice(&a.positions()[next * a.vertex_count() * 3..(next + n) * a.vertex_count() * 3]);
            next += n;
            Ok(n)
        }
    }

    fn source<'a>(
        a: &'a Animation,
        read: &'a mut dyn FnMut(usize, &mut Vec<f32>) -> codec_core::Result<usize>,
    ) -> FrameSource<'a> {
        FrameSource { topology: a.topology(), frame_count: a.frame_count(), frame_rate: a.frame_rate(), read }
    }

    #[test]
    fn a_stream_measured_packet_by_packet_equals_evaluate() {
        let registry = registry();
        let anim = animcodec_synth::by_name("flag", animcodec_synth::SynthSize::Small).unwrap();
        for (codec, param, value) in
            [("quant-delta", "bits", ParamValue::Int(9)), ("pca-aoi", "kg", ParamValue::Float(1.0))]
        {
            let codec = registry.by_name(codec).unwrap();
            let params = ParamSet::defaults(codec.name(), &codec.param_specs())
                .with(&codec.param_specs(), param, value)
                .unwrap();
            let enc = encode_animation_fed(codec, &params, &anim, false, 7).unwrap();
            let decoded = codec_core::decode_animation(&enc.bytes, &registry, Limits::default()).unwrap();
            let options = EvalOptions::default();
            let whole = metrics::evaluate(&anim, &decoded, &options).unwrap();
            let mut read = reader(&anim);
            let streamed =
                measure_stream(&registry, &enc.bytes[..], source(&anim, &mut read), &options, Limits::default())
                    .unwrap();
            assert_eq!(streamed, whole, "{}", codec.name());
            let (mut ra, mut rb) = (reader(&anim), reader(&decoded));
            let both = measure_sources(source(&anim, &mut ra), source(&decoded, &mut rb), &options).unwrap();
            assert_eq!(both, whole);
        }
    }

    #[test]
    fn mismatches_and_short_references_are_errors() {
        let registry = registry();
        let anim = animcodec_synth::by_name("flag", animcodec_synth::SynthSize::Small).unwrap();
        let codec = registry.by_name("quant-delta").unwrap();
        let enc = encode_animation_fed(codec, &ParamSet::defaults(codec.name(), &codec.param_specs()), &anim, false, 7)
            .unwrap();
        let options = EvalOptions::default();
        // A reference that stops early.
        let mut short = |n: usize, out: &mut Vec<f32>| {
            out.clear();
            out.extend_from_slice(&anim.positions()[..n.min(3) * anim.vertex_count() * 3]);
            Ok(n.min(3))
        };
        let e = measure_stream(&registry, &enc.bytes[..], source(&anim, &mut short), &options, Limits::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("reference ended after"), "{e}");
        // A reference of another shape.
        let other = animcodec_synth::by_name("cylinder", animcodec_synth::SynthSize::Small).unwrap();
        let mut read = reader(&other);
        let e = measure_stream(&registry, &enc.bytes[..], source(&other, &mut read), &options, Limits::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("vertices") || e.contains("triangle"), "{e}");
        // A truncated stream.
        let mut read = reader(&anim);
        let cut = &enc.bytes[..enc.bytes.len() / 2];
        assert!(measure_stream(&registry, cut, source(&anim, &mut read), &options, Limits::default()).is_err());
        // A decode budget too small for the stream: the decoder's error.
        let mut read = reader(&anim);
        let tiny = Limits { max_alloc_bytes: 1 << 10, ..Limits::default() };
        let e = measure_stream(&registry, &enc.bytes[..], source(&anim, &mut read), &options, tiny)
            .unwrap_err()
            .to_string();
        assert!(e.contains("memory limit"), "{e}");
    }
}
