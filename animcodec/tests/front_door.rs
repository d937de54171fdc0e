//! Each measured stream is encoded once and decoded once: the sweep keeps the decoded
//! animations of the points a report shows (`sweep --html`), and `encode --target --eval`
//! takes its measurement from the search's own point. A codec wrapper counts every encoder and
//! stream decoder the library opens.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use animcodec::core::{
    AnimationCodec, CodecRegistry, DistortionKind, EncoderSetup, ErrorBound, FourCc, FrameDecoder, FrameEncoder,
    Limits, ParamSet, ParamSpec, ParamValue, RateLadder, SearchSpace, StreamInfo,
};
use animcodec::front;
use animcodec::harness::{self, SearchRequest, SweepOptions, SweepSeries, Target};
use animcodec::metrics::EvalOptions;

/// quant-delta, counting the encoders and decoders opened.
struct Counting {
    inner: codec_quant_delta::QuantDelta,
    encodes: Arc<AtomicUsize>,
    decodes: Arc<AtomicUsize>,
}

impl AnimationCodec for Counting {
    fn name(&self) -> &'static str {
        self.inner.name()
    }
    fn fourcc(&self) -> FourCc {
        self.inner.fourcc()
    }
    fn stream_version(&self) -> u16 {
        self.inner.stream_version()
    }
    fn summary(&self) -> &'static str {
        self.inner.summary()
    }
    fn param_specs(&self) -> Vec<ParamSpec> {
        self.inner.param_specs()
    }
    fn default_params(&self) -> ParamSet {
        self.inner.default_params()
    }
    fn rate_ladder(&self, base: &ParamSet) -> RateLadder {
        self.inner.rate_ladder(base)
    }
    fn search_space(&self, base: &ParamSet) -> SearchSpace {
        self.inner.search_space(base)
    }
    fn search_space_for(&self, base: &ParamSet, kind: DistortionKind) -> SearchSpace {
        self.inner.search_space_for(base, kind)
    }
    fn search_start(&self, base: &ParamSet, kind: DistortionKind) -> Option<ParamValue> {
        self.inner.search_start(base, kind)
    }
    fn validate(&self, params: &ParamSet) -> animcodec::core::Result<()> {
        self.inner.validate(params)
    }
    fn error_bound(
        &self,
        params: &ParamSet,
        animation: &animcodec::core::Animation,
    ) -> animcodec::core::Result<ErrorBound> {
        self.inner.error_bound(params, animation)
    }
    fn new_encoder(
        &self,
        params: &ParamSet,
        setup: &EncoderSetup<'_>,
    ) -> animcodec::core::Result<Box<dyn FrameEncoder>> {
        self.encodes.fetch_add(1, Ordering::SeqCst);
        self.inner.new_encoder(params, setup)
    }
    fn new_decoder(
        &self,
        info: &StreamInfo,
        config: &[u8],
        limits: &Limits,
    ) -> animcodec::core::Result<Box<dyn FrameDecoder>> {
        // The encoder checks its own output through a decoder of unlimited limits while it
        // encodes: that one is part of the encode, not a decode of a stream.
        if *limits != Limits::UNLIMITED {
            self.decodes.fetch_add(1, Ordering::SeqCst);
        }
        self.inner.new_decoder(info, config, limits)
    }
}

fn counting_registry() -> (CodecRegistry, Arc<AtomicUsize>, Arc<AtomicUsize>) {
    let (encodes, decodes) = (Arc::new(AtomicUsize::new(0)), Arc::new(AtomicUsize::new(0)));
    let codec =
        Counting { inner: codec_quant_delta::QuantDelta, encodes: Arc::clone(&encodes), decodes: Arc::clone(&decodes) };
    (CodecRegistry::new(vec![Box::new(codec)]).unwrap(), encodes, decodes)
}

#[test]
fn a_sweep_keeps_the_points_it_shows_and_measures_each_stream_once() {
    let (registry, encodes, decodes) = counting_registry();
    let codec = registry.by_name("quant-delta").unwrap();
    let animation = animcodec::synth::waving_flag(8, 6, 12);
    let series = vec![SweepSeries::defaults(codec)];
    let options = SweepOptions {
        points: Some(4),
        jobs: Some(1),
        keep_decoded: vec![("quant-delta".to_owned(), 0)],
        ..SweepOptions::default()
    };
    let sweep = harness::sweep(&registry, &series, &animation, &options, &|_| {}).unwrap();
    let measured = sweep.points.len() + sweep.failures.len();
    assert_eq!(sweep.points.len(), 4, "{:?}", sweep.failures);
    assert_eq!(encodes.load(Ordering::SeqCst), measured, "one encode per measured point");
    assert_eq!(decodes.load(Ordering::SeqCst), measured, "one decode per measured point");
    // The kept decode is the one the point was measured on: the report's figures hold for it.
    assert_eq!(sweep.decoded.len(), 1);
    let (series, step, decoded) = &sweep.decoded[0];
    assert_eq!((series.as_str(), *step), ("quant-delta", 0));
    let point = sweep.points.iter().find(|p| p.ladder_index == 0).unwrap();
    let again = animcodec::metrics::evaluate(&animation, decoded, &options.eval).unwrap();
    assert_eq!(again.kg, point.report.kg);
}

#[test]
fn a_target_search_measurement_is_reused_by_eval() {
    let (registry, encodes, decodes) = counting_registry();
    let codec = registry.by_name("quant-delta").unwrap();
    let animation = animcodec::synth::waving_flag(8, 6, 12);
    let target: Target = "kg=1".parse().unwrap();
    let request = SearchRequest { refine: 1, ..SearchRequest::new(&registry, &animation, target) };
    let hit = harness::search_target(&request, codec, &codec.default_params()).unwrap();
    let tried = hit.tried.len();
    assert!(tried > 0);
    assert_eq!(encodes.load(Ordering::SeqCst), tried, "one encode per point tried");
    assert_eq!(decodes.load(Ordering::SeqCst), tried, "one decode per point tried");

    // The metrics the search computed: taken from its report, no decode.
    let kg_only = EvalOptions { compute_sted: false, compute_hausdorff: false, ..EvalOptions::default() };
    let (report, _) = front::evaluation_of(&registry, &hit, &animation, &kg_only, Limits::default()).unwrap();
    assert_eq!(report.kg, hit.point.report.kg);
    assert!(report.notes.iter().all(|n| !n.starts_with("encoder: ")));
    assert_eq!((encodes.load(Ordering::SeqCst), decodes.load(Ordering::SeqCst)), (tried, tried));

    // Metrics the search skipped (it computes only its target's): the kept stream is decoded
    // once more in memory, never encoded again.
    let (report, _) =
        front::evaluation_of(&registry, &hit, &animation, &EvalOptions::default(), Limits::default()).unwrap();
    assert!(report.sted.is_some() && report.hausdorff.is_some());
    assert_eq!(report.kg, hit.point.report.kg);
    assert_eq!((encodes.load(Ordering::SeqCst), decodes.load(Ordering::SeqCst)), (tried, tried + 1));

    // `encode --target --eval`: the search measures every metric, so the chosen stream's report
    // is its evaluation — each stream encoded and decoded once, nothing measured again.
    encodes.store(0, Ordering::SeqCst);
    decodes.store(0, Ordering::SeqCst);
    let request = SearchRequest { measure_every_metric: true, ..request };
    let hit = harness::search_target(&request, codec, &codec.default_params()).unwrap();
    let tried = hit.tried.len();
    let (report, _) =
        front::evaluation_of(&registry, &hit, &animation, &EvalOptions::default(), Limits::default()).unwrap();
    assert!(report.sted.is_some() && report.hausdorff.is_some());
    assert_eq!((encodes.load(Ordering::SeqCst), decodes.load(Ordering::SeqCst)), (tried, tried));
}
