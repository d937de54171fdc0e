//! Tests of quality-targeted rate control over each codec's declared parameter space:
//! `harness::search_space_target`, the envelope sweep, and the default quality of
//! `animcodec encode` without `-p`.

use animcodec::harness::{self, search_space_target, search_target, Target, TargetMetric, DEFAULT_TARGET};
use animcodec::metrics::EvalOptions;
use animcodec::synth;
use codec_core::{
    Animation, AnimationCodec, CodecRegistry, EncodedPacket, EncoderSetup, ErrorBound, FourCc, FrameDecoder,
    FrameEncoder, Limits, Packet, ParamSet, ParamSpec, ParamValue, RateLadder, SearchAxis, SearchSpace, StreamInfo,
};
use codec_quant_delta::QuantDelta;

mod common;
use common::*;

fn small() -> Animation {
    synth::waving_flag(12, 9, 12)
}

fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(f)
}

/// The chosen stream depends on neither the thread count nor the scheduling: 1 and 2 threads
/// give the same bytes, and the search measures the same candidates.
#[test]
fn space_search_chooses_the_same_stream_with_one_and_two_threads() {
    let registry = animcodec::registry();
    let codec = registry.by_name("hosvd").unwrap();
    let animation = small();
    let eval = EvalOptions::default();
    for target in [Target::new(TargetMetric::Kg, 0.5), Target::new(TargetMetric::Sted, 0.05)] {
        let run = |threads| {
            in_pool(threads, || {
                search_space_target(
                    &request(&registry, &animation, target, &eval, 2),
                    codec,
                    &codec.default_params(),
                    &[],
                )
                .unwrap()
            })
        };
        let (one, two) = (run(1), run(2));
        assert_eq!(one.stream, two.stream, "{target}");
        assert_eq!(one.point.params, two.point.params);
        let measured =
            |h: &harness::TargetHit| h.tried.iter().map(|p| (p.params.to_string(), p.bytes)).collect::<Vec<_>>();
        assert_eq!(measured(&one), measured(&two));
        assert!(target.meets(&one.point.report), "{target}: reached {}", target.reached_text(&one.point.report, 6));
        // The answer is the smallest passing stream measured.
        let smallest = one.tried.iter().filter(|p| target.meets(&p.report)).map(|p| p.bytes).min().unwrap();
        assert_eq!(one.point.bytes, smallest);
        // More than one configuration was tried.
        let configs: std::collections::BTreeSet<String> =
            one.tried.iter().map(|p| format!("{:?}{:?}", p.params.get("rigid"), p.params.get("edge_noise"))).collect();
        assert!(configs.len() > 1, "{configs:?}");
    }
}

/// The space holds the single ladder's configuration, so (on a monotone ladder, without
/// refinement) its answer is never larger than the ladder search's.
#[test]
fn space_search_is_never_worse_than_the_ladder_alone() {
    let registry = animcodec::registry();
    let animation = small();
    let eval = EvalOptions::default();
    let target = Target::new(TargetMetric::Kg, 0.5);
    for name in ["hosvd", "pca-aoi"] {
        let codec = registry.by_name(name).unwrap();
        let base = codec.default_params();
        let ladder = search_target(&request(&registry, &animation, target, &eval, 0), codec, &base).unwrap();
        let space = search_space_target(&request(&registry, &animation, target, &eval, 0), codec, &base, &[]).unwrap();
        if !ladder.linear_fallback {
            assert!(space.point.bytes <= ladder.point.bytes, "{name}: {} > {}", space.point.bytes, ladder.point.bytes);
        }
    }
}

/// Parameters the user fixed are not searched.
#[test]
fn fixed_parameters_are_not_searched() {
    let registry = animcodec::registry();
    let codec = registry.by_name("hosvd").unwrap();
    let base = codec.default_params().with(&codec.param_specs(), "rigid", ParamValue::Bool(false)).unwrap();
    let target = Target::new(TargetMetric::Kg, 1.0);
    let hit = search_space_target(
        &request(&registry, &small(), target, &EvalOptions::default(), 0),
        codec,
        &base,
        &["rigid"],
    )
    .unwrap();
    assert!(hit.tried.iter().all(|p| !p.params.bool("rigid").unwrap()));
}

// ---------------------------------------------------------------------------------------------
// A codec whose smaller configuration is garbage: quant-delta that, at `level = 1`, writes a
// stream that decodes to NaN. The search must reject it, whatever its size.

struct Garbling;

struct GarbleEncoder(Box<dyn FrameEncoder>, bool);
impl FrameEncoder for GarbleEncoder {
    fn config(&self) -> Vec<u8> {
        let mut c = vec![u8::from(self.1)];
        c.extend(self.0.config());
        c
    }
    fn push_frames(&mut self, frames: &[f32]) -> codec_core::Result<Vec<EncodedPacket>> {
        self.0.push_frames(frames)
    }
    fn finish(&mut self) -> codec_core::Result<Vec<EncodedPacket>> {
        self.0.finish()
    }
}

struct GarbleDecoder(Box<dyn FrameDecoder>, bool);
impl FrameDecoder for GarbleDecoder {
    fn decode_packet(&mut self, packet: &Packet) -> codec_core::Result<Vec<f32>> {
        let mut frames = self.0.decode_packet(packet)?;
        if self.1 {
            frames.iter_mut().for_each(|x| *x = f32::NAN);
        }
        Ok(frames)
    }
}

fn as_quant_delta(params: &ParamSet) -> codec_core::Result<ParamSet> {
    let specs = QuantDelta.param_specs();
    let mut p = QuantDelta.default_params();
    for (name, value) in params.iter() {
        p.set(&specs, name, value.clone())?;
    }
    Ok(p)
}

impl AnimationCodec for Garbling {
    fn name(&self) -> &'static str {
        "garbling"
    }
    fn fourcc(&self) -> FourCc {
        FourCc::new(b"TGRB")
    }
    fn stream_version(&self) -> u16 {
        1
    }
    fn summary(&self) -> &'static str {
        "quant-delta decoding to NaN at level 1 (test only)"
    }
    fn param_specs(&self) -> Vec<ParamSpec> {
        QuantDelta.param_specs()
    }
    fn rate_ladder(&self, _base: &ParamSet) -> RateLadder {
        RateLadder { param: "bits", steps: (4..=20).step_by(2).map(ParamValue::Int).collect() }
    }
    fn search_space(&self, base: &ParamSet) -> SearchSpace {
        SearchSpace {
            primary: self.rate_ladder(base),
            secondary: vec![SearchAxis { param: "level", values: vec![ParamValue::Int(19), ParamValue::Int(1)] }],
        }
    }
    fn validate(&self, params: &ParamSet) -> codec_core::Result<()> {
        QuantDelta.validate(&as_quant_delta(params)?)
    }
    fn error_bound(&self, params: &ParamSet, animation: &Animation) -> codec_core::Result<ErrorBound> {
        QuantDelta.error_bound(&as_quant_delta(params)?, animation)
    }
    fn new_encoder(&self, params: &ParamSet, setup: &EncoderSetup<'_>) -> codec_core::Result<Box<dyn FrameEncoder>> {
        let garbage = params.int("level")? == 1;
        Ok(Box::new(GarbleEncoder(QuantDelta.new_encoder(&as_quant_delta(params)?, setup)?, garbage)))
    }
    fn new_decoder(
        &self,
        info: &StreamInfo,
        config: &[u8],
        limits: &Limits,
    ) -> codec_core::Result<Box<dyn FrameDecoder>> {
        let (&flag, rest) = config
            .split_first()
            .ok_or(codec_core::Error::Truncated { context: "garbling".into(), field: "flag".into() })?;
        Ok(Box::new(GarbleDecoder(QuantDelta.new_decoder(info, rest, limits)?, flag == 1)))
    }
}

#[test]
fn candidates_decoding_to_non_finite_coordinates_are_rejected() {
    let registry = CodecRegistry::new(vec![Box::new(Garbling)]).unwrap();
    let codec = registry.by_name("garbling").unwrap();
    for metric in [TargetMetric::Kg, TargetMetric::MaxError] {
        let target = Target::new(metric, 1e-2);
        let hit = search_space_target(
            &request(&registry, &small(), target, &EvalOptions::default(), 0),
            codec,
            &codec.default_params(),
            &[],
        )
        .unwrap();
        assert_eq!(hit.point.params.int("level").unwrap(), 19, "{target}");
        assert!(hit.tried.iter().all(|p| p.params.int("level").unwrap() == 19));
        assert!(!hit.rejected.is_empty() && hit.rejected[0].contains("non-finite"), "{:?}", hit.rejected);
    }
}

// ---------------------------------------------------------------------------------------------
// A codec whose smallest step is a still shape: quant-delta that, at `bits = 4` (its ladder's
// first step), codes frame 0 for every frame (at 14 bits). STED, which sees edge lengths only,
// scores that still shape better than the next steps' quantization noise: a shape error that is
// not monotone at the small end of the ladder (as hosvd's `(v, f) = (3, 1)` is on
// chicken-crossing).

struct Freezing;

struct FreezeEncoder {
    inner: Box<dyn FrameEncoder>,
    freeze: bool,
    first: Vec<f32>,
    coordinates: usize,
}
impl FrameEncoder for FreezeEncoder {
    fn config(&self) -> Vec<u8> {
        self.inner.config()
    }
    fn push_frames(&mut self, frames: &[f32]) -> codec_core::Result<Vec<EncodedPacket>> {
        if !self.freeze {
            return self.inner.push_frames(frames);
        }
        if self.first.is_empty() {
            self.first = frames[..self.coordinates].to_vec();
        }
        let still: Vec<f32> = (0..frames.len() / self.coordinates).flat_map(|_| self.first.iter().copied()).collect();
        self.inner.push_frames(&still)
    }
    fn finish(&mut self) -> codec_core::Result<Vec<EncodedPacket>> {
        self.inner.finish()
    }
}

impl AnimationCodec for Freezing {
    fn name(&self) -> &'static str {
        "freezing"
    }
    fn fourcc(&self) -> FourCc {
        FourCc::new(b"TFRZ")
    }
    fn stream_version(&self) -> u16 {
        1
    }
    fn summary(&self) -> &'static str {
        "quant-delta coding frame 0 for every frame at its smallest step (test only)"
    }
    fn param_specs(&self) -> Vec<ParamSpec> {
        QuantDelta.param_specs()
    }
    fn rate_ladder(&self, base: &ParamSet) -> RateLadder {
        QuantDelta.rate_ladder(base)
    }
    fn validate(&self, params: &ParamSet) -> codec_core::Result<()> {
        QuantDelta.validate(&as_quant_delta(params)?)
    }
    fn error_bound(&self, params: &ParamSet, animation: &Animation) -> codec_core::Result<ErrorBound> {
        if params.int("bits")? == 4 {
            // The still shape promises nothing.
            return Ok(ErrorBound { max_coordinate_error: None, relative_rms_error: None });
        }
        QuantDelta.error_bound(&as_quant_delta(params)?, animation)
    }
    fn new_encoder(&self, params: &ParamSet, setup: &EncoderSetup<'_>) -> codec_core::Result<Box<dyn FrameEncoder>> {
        let freeze = params.int("bits")? == 4;
        let mut inner = as_quant_delta(params)?;
        if freeze {
            inner.set(&QuantDelta.param_specs(), "bits", ParamValue::Int(14))?;
        }
        let coordinates = 3 * setup.topology.vertex_count();
        Ok(Box::new(FreezeEncoder {
            inner: QuantDelta.new_encoder(&inner, setup)?,
            freeze,
            first: Vec::new(),
            coordinates,
        }))
    }
    fn new_decoder(
        &self,
        info: &StreamInfo,
        config: &[u8],
        limits: &Limits,
    ) -> codec_core::Result<Box<dyn FrameDecoder>> {
        QuantDelta.new_decoder(info, config, limits)
    }
}

/// quant-delta with its ladder cut at `bits` = the field (steps 4, 6, … up to it): a ladder
/// that ends before the input's target (test only).
struct ShortLadder(i64);

impl AnimationCodec for ShortLadder {
    fn name(&self) -> &'static str {
        "short-ladder"
    }
    fn fourcc(&self) -> FourCc {
        FourCc::new(b"TSLD")
    }
    fn stream_version(&self) -> u16 {
        1
    }
    fn summary(&self) -> &'static str {
        "quant-delta with a ladder that ends early (test only)"
    }
    fn param_specs(&self) -> Vec<ParamSpec> {
        QuantDelta.param_specs()
    }
    fn rate_ladder(&self, _base: &ParamSet) -> RateLadder {
        RateLadder { param: "bits", steps: (4..=self.0).step_by(2).map(ParamValue::Int).collect() }
    }
    fn validate(&self, params: &ParamSet) -> codec_core::Result<()> {
        QuantDelta.validate(&as_quant_delta(params)?)
    }
    fn error_bound(&self, params: &ParamSet, animation: &Animation) -> codec_core::Result<ErrorBound> {
        QuantDelta.error_bound(&as_quant_delta(params)?, animation)
    }
    fn new_encoder(&self, params: &ParamSet, setup: &EncoderSetup<'_>) -> codec_core::Result<Box<dyn FrameEncoder>> {
        QuantDelta.new_encoder(&as_quant_delta(params)?, setup)
    }
    fn new_decoder(
        &self,
        info: &StreamInfo,
        config: &[u8],
        limits: &Limits,
    ) -> codec_core::Result<Box<dyn FrameDecoder>> {
        QuantDelta.new_decoder(info, config, limits)
    }
}

/// A default-quality search whose every ladder step misses its target continues the ladder's
/// progression (`harness::BEYOND_LADDER_STEPS` steps) and lands where the full ladder does;
/// past those steps it reports the miss.
#[test]
fn the_default_search_continues_past_a_ladder_that_ends_too_soon() {
    let eval = EvalOptions::default();
    let anim = small();
    let registry = animcodec::registry();
    // Fine enough that the answer lies a few steps up quant-delta's ladder.
    let fine = Target::new(TargetMetric::Kg, 0.02);
    let full = harness::search_default_quality(
        &request(&registry, &anim, fine, &eval, 0),
        registry.by_name("quant-delta").unwrap(),
    )
    .unwrap();
    let bits = full.point.params.int("bits").unwrap();
    assert!(bits >= 10, "the input must need a ladder of at least two steps below the answer: bits={bits}");
    // Cut two steps below the answer: the last step and the first past it miss, the second passes.
    let short = CodecRegistry::new(vec![Box::new(ShortLadder(bits - 4))]).unwrap();
    let codec = short.by_name("short-ladder").unwrap();
    let hit = harness::search_default_quality(&request(&short, &anim, fine, &eval, 0), codec).unwrap();
    assert_eq!(hit.point.params.int("bits").unwrap(), bits);
    assert_eq!(hit.point.report.kg, full.point.report.kg);
    assert!(hit.tried.iter().any(|p| p.params.int("bits").unwrap() == bits - 2 && !fine.meets(&p.report)));
    // Cut further below than the continuation reaches: the miss is reported, having measured
    // the ladder's last step and every continued one.
    let far = CodecRegistry::new(vec![Box::new(ShortLadder(6))]).unwrap();
    let codec = far.by_name("short-ladder").unwrap();
    let hard = Target::new(TargetMetric::Kg, 1e-9);
    let e = harness::search_default_quality(&request(&far, &anim, hard, &eval, 0), codec).unwrap_err();
    let harness::EvalError::TargetMiss(miss) = e else { panic!("expected a miss, got {e}") };
    let reached = 6 + 2 * harness::BEYOND_LADDER_STEPS as i64;
    assert_eq!(miss.best.as_ref().unwrap().params.int("bits").unwrap(), reached, "{miss}");
}

/// A STED search also measures each configuration's smallest step, which a search that
/// brackets the target (assuming the error grows toward small streams) never reaches; a KG
/// search does not.
#[test]
fn sted_search_finds_a_passing_smallest_step_past_failing_ones() {
    let registry = CodecRegistry::new(vec![Box::new(Freezing)]).unwrap();
    let codec = registry.by_name("freezing").unwrap();
    // A flag drifting sideways (a tenth of its width over the clip) while it waves at a tenth
    // of the synthetic wave: a still frame 0 keeps its edge lengths nearly (low STED) at a
    // usable KG, while 6-bit quantization noise moves them more.
    let wave = synth::waving_flag(12, 9, 12);
    let n = 3 * wave.vertex_count();
    let (lo, hi) = wave.bounding_box();
    let width = hi[0] - lo[0];
    let positions: Vec<f32> = wave
        .positions()
        .chunks_exact(n)
        .enumerate()
        .flat_map(|(t, frame)| {
            let first = &wave.positions()[..n];
            let drift = 0.1 * width * t as f32 / 12.0;
            frame
                .iter()
                .zip(first)
                .enumerate()
                .map(move |(i, (&x, &x0))| x0 + 0.1 * (x - x0) + if i % 3 == 0 { drift } else { 0.0 })
        })
        .collect();
    let animation = Animation::new(wave.topology().clone(), positions, wave.frame_rate()).unwrap();
    let frame0 = animation.positions()[..n].to_vec();
    let still_positions: Vec<f32> = (0..animation.frame_count()).flat_map(|_| frame0.iter().copied()).collect();
    let still = Animation::new(animation.topology().clone(), still_positions, animation.frame_rate()).unwrap();
    let report = animcodec::metrics::evaluate(&animation, &still, &EvalOptions::default()).unwrap();
    let (still_sted, still_kg) = (report.sted.unwrap(), report.kg.unwrap());
    assert!(still_kg <= harness::DEGENERATE_KG, "test data: the still flag is degenerate (KG {still_kg})");
    let target = Target::new(TargetMetric::Sted, 1.05 * still_sted);
    let hit = search_space_target(
        &request(&registry, &animation, target, &EvalOptions::default(), 0),
        codec,
        &codec.default_params(),
        &[],
    )
    .unwrap();
    assert_eq!(
        hit.point.params.int("bits").unwrap(),
        4,
        "still STED {still_sted}; rejected {:?}; tried {:?}",
        hit.rejected,
        hit.tried.iter().map(|p| (p.params.int("bits"), p.report.sted)).collect::<Vec<_>>()
    );
    // Non-monotone: a larger step failed the target the still shape meets.
    assert!(
        hit.tried.iter().any(|p| p.params.int("bits").unwrap() > 4 && p.report.sted.unwrap() > target.level()),
        "the test lost its point: no failing larger step"
    );
    // A KG target brackets as before: the still shape (KG {still_kg}) is no answer there.
    let kg = Target::new(TargetMetric::Kg, 0.5 * still_kg);
    let hit = search_space_target(
        &request(&registry, &animation, kg, &EvalOptions::default(), 0),
        codec,
        &codec.default_params(),
        &[],
    )
    .unwrap();
    assert!(hit.tried.iter().all(|p| p.params.int("bits").unwrap() != 4 || p.report.kg.unwrap() > kg.level()));
}

/// Each codec's envelope: sorted by bytes, its errors strictly fall.
#[test]
fn envelope_sweep_points_form_a_falling_curve_per_codec() {
    let registry = animcodec::registry();
    let animation = small();
    let codecs: Vec<(&dyn AnimationCodec, ParamSet, Vec<&'static str>)> = ["quant-delta", "hosvd"]
        .iter()
        .map(|n| {
            let c = registry.by_name(n).unwrap();
            (c, c.default_params(), Vec::new())
        })
        .collect();
    let options = harness::SweepOptions { points: Some(6), jobs: Some(2), ..Default::default() };
    let swept = harness::envelope_sweep(&registry, &codecs, &animation, &options, 2, &|_| {}).unwrap();
    assert!(swept.failures.is_empty(), "{:?}", swept.failures);
    // hosvd's secondary configurations were measured and are labelled with their parameters.
    assert!(swept.points.iter().any(|p| p.series.starts_with("hosvd[")), "no secondary configuration measured");
    // The third phase: some secondary configuration got more than its 2 spread points, and
    // every point of a configuration is next (one ladder step) to another of its points.
    let mut by_series: std::collections::BTreeMap<&str, Vec<usize>> = Default::default();
    for p in swept.points.iter().filter(|p| p.series.starts_with("hosvd[")) {
        by_series.entry(&p.series).or_default().push(p.ladder_index);
    }
    // Every secondary configuration measured its smallest step (a shape error need not grow
    // toward it), beside its 2 spread points and the envelope neighbours.
    for (series, steps) in &by_series {
        assert!(steps.contains(&0), "{series}: smallest step not measured: {steps:?}");
    }
    assert!(by_series.values().any(|steps| steps.len() > 3), "no envelope neighbours measured: {by_series:?}");
    for (series, steps) in &by_series {
        if steps.len() > 3 {
            let near = |s: usize| steps.iter().any(|&t| t != s && t.abs_diff(s) == 1);
            assert!(steps.iter().filter(|&&s| near(s)).count() >= steps.len() - 3, "{series}: {steps:?}");
        }
    }
    for metric in [TargetMetric::Kg, TargetMetric::Sted] {
        let on = harness::envelope(&swept.points, metric);
        for codec in ["quant-delta", "hosvd"] {
            let mut curve: Vec<_> = on.iter().map(|&i| &swept.points[i]).filter(|p| p.codec == codec).collect();
            assert!(!curve.is_empty());
            curve.sort_by_key(|p| p.bytes);
            for w in curve.windows(2) {
                assert!(metric.value(&w[1].report).unwrap() < metric.value(&w[0].report).unwrap());
            }
            // No point of the codec that may be on the envelope (usable; for STED, KG not too
            // far off for its STED to count) is both smaller and better than an envelope point.
            let eligible = |q: &&harness::Point| {
                harness::usable(q) && !(metric == TargetMetric::Sted && harness::sted_degenerate(&q.report))
            };
            for p in &curve {
                let v = metric.value(&p.report).unwrap();
                assert!(!swept
                    .points
                    .iter()
                    .filter(eligible)
                    .any(|q| q.codec == codec && q.bytes < p.bytes && metric.value(&q.report).is_some_and(|w| w <= v)));
            }
        }
    }
}

/// `encode` without `-p` aims at the default quality; with `-p`, exactly those parameters.
#[test]
fn encode_without_parameters_meets_the_default_quality() {
    let s = Scratch::new("default-quality");
    let (pc2, anim) = (s.path("flag.pc2"), s.path("flag.anim"));
    ok(&["synth", "flag", "-o", &pc2]);
    for codec in ["hosvd", "quant-delta"] {
        let v = ok_json(&["encode", &pc2, "-c", codec, "-o", &anim, "-f", "--json", "--eval"]);
        assert_eq!(v["default_target"], true, "{v}");
        assert_eq!(v["target"], serde_json::json!({"kg": 0.5, "sted": 0.05}));
        let kg = v["kg"].as_f64().unwrap();
        assert!(kg <= DEFAULT_TARGET.bound(TargetMetric::Kg).unwrap(), "{codec}: KG {kg}");
        let sted = v["sted"].as_f64().unwrap();
        assert!(sted <= DEFAULT_TARGET.bound(TargetMetric::Sted).unwrap(), "{codec}: STED {sted}");
        assert_eq!(v["reached"]["kg"], v["kg"], "the search's measurement is the --eval one");
        assert_eq!(v["bytes"].as_u64().unwrap(), std::fs::metadata(&anim).unwrap().len());
    }
    let v = ok_json(&["encode", &pc2, "-c", "hosvd", "-p", "ss=0.9", "-o", &anim, "-f", "--json"]);
    assert!(v.get("default_target").is_none(), "{v}");
    assert_eq!(v["params"]["ss"], 0.9);
    let v = ok_json(&["encode", &pc2, "-c", "auto", "-o", &anim, "-f", "--json"]);
    assert_eq!(v["default_target"], true, "{v}");
    fails(&["encode", &pc2, "-c", "auto", "-p", "ss=0.9", "-o", &anim, "-f"], &["-p"]);
}

/// The default encode's search (`harness::search_default_quality`): whatever the codec's
/// defaults give on inputs they overshoot or undershoot, the answer meets the default target
/// and lies within `DEFAULT_QUALITY_BAND` of it (so the default quality varies by at most that
/// factor across inputs) unless the next smaller stream it measured misses the target (a
/// cliff) or the ladder ends; an in-band first encode is kept with no search.
#[test]
fn default_quality_lands_within_its_band_of_the_target() {
    let registry = animcodec::registry();
    let eval = EvalOptions::default();
    // The default target is joint: its error is the binding bound's ratio value / bound.
    let band = DEFAULT_TARGET.level() / harness::DEFAULT_QUALITY_BAND;
    // Few frames (hosvd's size model keeps too little), many, and a rigid tumble.
    let inputs = [
        ("flag-6", synth::waving_flag(12, 9, 6)),
        ("flag-40", synth::waving_flag(16, 12, 40)),
        ("tumble", synth::tumbling_body(30)),
    ];
    for codec in ["hosvd", "pca-aoi", "quant-delta"] {
        let codec = registry.by_name(codec).unwrap();
        for (name, anim) in &inputs {
            let hit = harness::search_default_quality(&request(&registry, anim, DEFAULT_TARGET, &eval, 4), codec)
                .unwrap_or_else(|e| panic!("{} on {name}: {e}", codec.name()));
            let reached = DEFAULT_TARGET.reached_text(&hit.point.report, 6);
            assert!(DEFAULT_TARGET.meets(&hit.point.report), "{} on {name}: {reached}", codec.name());
            let error = DEFAULT_TARGET.error(&hit.point.report).unwrap();
            // Below the band only at a cliff (a measured smaller stream misses the target) or at
            // the ladder's floor: its first step, or a smaller step measured that gives no
            // smaller stream (hosvd's smallest model that is not flat, `(v, f) = (3, 1)`, holds
            // the rigid tumble exactly: KG 0.014 at every `ss` from 0.97 up).
            let cliff = hit.tried.iter().any(|p| p.bytes < hit.point.bytes && !DEFAULT_TARGET.meets(&p.report));
            let floor = hit.point.ladder_index == 0
                || hit.tried.iter().any(|p| p.ladder_index < hit.point.ladder_index && p.bytes >= hit.point.bytes);
            assert!(
                error >= band || cliff || floor,
                "{} on {name}: {reached} (error {error}) is below the band ({band}) with no cliff below it; tried {:?}",
                codec.name(),
                hit.tried.iter().map(|p| (p.ladder_index, p.bytes, p.report.kg, p.report.sted)).collect::<Vec<_>>()
            );
            if hit.tried.len() == 1 {
                assert_eq!(hit.point.params, codec.default_params(), "{} on {name}", codec.name());
            }
        }
    }
}

/// What a target search walks for each kind of error is part of what `sweep` measures (the
/// full space), for every registered codec: an envelope never lacks a configuration a
/// target search could choose.
#[test]
fn each_kind_of_target_searches_within_the_full_space() {
    use codec_core::DistortionKind;
    let registry = animcodec::registry();
    for codec in registry.iter() {
        let base = codec.default_params();
        let full = codec.search_space(&base);
        let specs = codec.param_specs();
        let apply = |config: &[(&'static str, ParamValue)]| SearchSpace::apply(&base, &specs, config).unwrap();
        let full_sets: Vec<ParamSet> = full.configurations().iter().map(|c| apply(c)).collect();
        for kind in [DistortionKind::Position, DistortionKind::Shape, DistortionKind::Both] {
            let part = codec.search_space_for(&base, kind);
            assert_eq!(part.primary, full.primary, "{}: {kind:?}", codec.name());
            for config in part.configurations() {
                let set = apply(&config);
                assert!(full_sets.contains(&set), "{} {kind:?}: {set} is not in the full space", codec.name());
            }
        }
    }
}

/// A STED target searches hosvd's shape-preserving half of its space (edge distortion in the
/// RD rule, the noise cap), a KG target the other half; both find streams that meet them.
#[test]
fn hosvd_target_searches_walk_the_half_of_the_space_for_their_error() {
    let registry = animcodec::registry();
    let codec = registry.by_name("hosvd").unwrap();
    let animation = small();
    let eval = EvalOptions::default();
    let sted = Target::new(TargetMetric::Sted, 0.05);
    let hit = search_space_target(&request(&registry, &animation, sted, &eval, 2), codec, &codec.default_params(), &[])
        .unwrap();
    assert!(hit.tried.iter().all(|p| [0.012, 0.02].contains(&p.params.float("edge_noise").unwrap())
        && p.params.float("edge_weight").unwrap() == 1.0));
    assert!(hit.tried.iter().any(|p| !p.params.bool("rigid").unwrap()));
    // hosvd's start for STED targets (`search_start`), not the default `ss`.
    assert_eq!(hit.tried[0].params.float("ss").unwrap(), 0.97);
    let kg = Target::new(TargetMetric::Kg, 0.5);
    let hit = search_space_target(&request(&registry, &animation, kg, &eval, 2), codec, &codec.default_params(), &[])
        .unwrap();
    assert!(hit.tried.iter().all(|p| p.params.float("edge_noise").unwrap() == 0.0));
    assert_eq!(hit.tried[0].params.float("ss").unwrap(), 0.9, "KG targets start at the default");
    assert!(TargetMetric::Kg.value(&hit.point.report).unwrap() <= 0.5);
    // A joint target walks both edge weights without the noise cap, and meets both bounds.
    let joint: Target = "kg=0.5,sted=0.05".parse().unwrap();
    let hit =
        search_space_target(&request(&registry, &animation, joint, &eval, 2), codec, &codec.default_params(), &[])
            .unwrap();
    assert!(joint.meets(&hit.point.report), "{}", joint.reached_text(&hit.point.report, 6));
    assert!(hit.tried.iter().all(|p| p.params.float("edge_noise").unwrap() == 0.0));
    assert_eq!(hit.tried[0].params.float("ss").unwrap(), 0.9, "joint targets start at the default");
    // Every configuration is measured at least once: both edge weights were tried.
    let weights: std::collections::BTreeSet<String> =
        hit.tried.iter().map(|p| p.params.float("edge_weight").unwrap().to_string()).collect();
    assert_eq!(weights.into_iter().collect::<Vec<_>>(), ["0", "1"]);
}

/// A STED target met by a stream that does not follow the motion says so (stderr and `--json`
/// "notes"): on the flag, hosvd's smallest model — one shape moved rigidly — meets STED ≤ 0.1 at
/// KG 14 %. A KG target gets no such note.
#[test]
fn a_sted_target_met_without_the_motion_says_so() {
    let s = Scratch::new("sted-motion-note");
    let (pc2, anim) = (s.path("flag.pc2"), s.path("flag.anim"));
    ok(&["synth", "flag", "-o", &pc2]);
    let v = ok_json(&["encode", &pc2, "-c", "hosvd", "--target", "sted=0.1", "-o", &anim, "-f", "--json", "--eval"]);
    let kg = v["kg"].as_f64().unwrap();
    let notes: Vec<&str> = v["notes"].as_array().unwrap().iter().filter_map(|n| n.as_str()).collect();
    assert!(kg > 5.0, "test data: KG {kg} — the note's case did not arise");
    assert!(notes.iter().any(|n| n.contains("STED sees edge lengths") && n.contains("--target kg=")), "{notes:?}");
    let v = ok_json(&["encode", &pc2, "-c", "hosvd", "--target", "kg=1", "-o", &anim, "-f", "--json"]);
    assert!(v["notes"].as_array().unwrap().iter().all(|n| !n.as_str().unwrap().contains("STED")), "{v}");
}

/// Joint targets, as a property over synthetic inputs and random bounds: whatever the input,
/// codec and pair of bounds, a search either returns a stream meeting **both** bounds — the
/// smallest such stream it measured — or misses, and then no point it measured met both.
#[test]
fn joint_targets_are_met_on_every_bound_or_missed_honestly() {
    let registry = animcodec::registry();
    let eval = EvalOptions::default();
    let inputs = [
        ("flag", synth::waving_flag(12, 9, 12)),
        ("cylinder", synth::bending_cylinder(8, 10, 16)),
        ("tumble", synth::tumbling_body_sized(10, 6, 12)),
    ];
    // A fixed linear congruential sequence: the same bounds on every run, spread over two
    // decades of KG and of STED (log-uniform).
    let mut state: u64 = 0x2545_f491_4f6c_dd1d;
    let mut uniform = || {
        state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut hits, mut misses) = (0, 0);
    for (name, animation) in &inputs {
        // Three random pairs, and one no codec can meet (a miss must say so, not pass).
        for round in 0..4 {
            let (kg, sted) =
                if round < 3 { (0.03 * 100f64.powf(uniform()), 0.003 * 100f64.powf(uniform())) } else { (1e-9, 1e-9) };
            let target = Target::new(TargetMetric::Kg, kg).and_bound(TargetMetric::Sted, sted);
            for codec in ["quant-delta", "pca-aoi", "hosvd"] {
                let codec = registry.by_name(codec).unwrap();
                let request = request(&registry, animation, target, &eval, 2);
                match search_space_target(&request, codec, &codec.default_params(), &[]) {
                    Ok(hit) => {
                        hits += 1;
                        let r = &hit.point.report;
                        assert!(
                            r.kg_bound().unwrap() <= kg && r.sted.unwrap() <= sted,
                            "{} on {name} at {target}: {}",
                            codec.name(),
                            target.reached_text(r, 6)
                        );
                        let smallest = hit.tried.iter().filter(|p| target.meets(&p.report)).map(|p| p.bytes).min();
                        assert_eq!(smallest, Some(hit.point.bytes), "{} on {name} at {target}", codec.name());
                        // The stream is what was measured: decoded again, the same errors.
                        let decoded =
                            codec_core::StreamDecoder::new(hit.stream.as_slice(), &registry, Limits::default())
                                .unwrap()
                                .decode_all()
                                .unwrap();
                        let again =
                            animcodec::metrics::evaluate(animation, &decoded, &target.eval_options(&eval)).unwrap();
                        assert_eq!((again.kg_bound(), again.sted), (r.kg_bound(), r.sted));
                    }
                    Err(harness::EvalError::TargetMiss(miss)) => {
                        misses += 1;
                        let best = miss.best.as_ref().map(|p| target.meets(&p.report));
                        assert_ne!(best, Some(true), "{} on {name} missed {target} with a passing point", codec.name());
                    }
                    Err(e) => panic!("{} on {name} at {target}: {e}", codec.name()),
                }
            }
        }
    }
    // The property was exercised on both sides.
    eprintln!("joint targets: {hits} hits, {misses} misses");
    assert!(hits >= 10 && misses >= 3, "{hits} hits, {misses} misses");
}

/// `encode --target kg=…,sted=…` through the binary: the written stream meets both bounds as
/// `eval` measures it, and `--json` reports both.
#[test]
fn encode_with_a_joint_target_writes_a_stream_meeting_both_bounds() {
    let s = Scratch::new("joint-target");
    let (pc2, anim) = (s.path("cyl.pc2"), s.path("cyl.anim"));
    ok(&["synth", "cylinder", "-o", &pc2]);
    let v = ok_json(&["encode", &pc2, "-c", "auto", "--target", "kg=0.3,sted=0.02", "-o", &anim, "-f", "--json"]);
    assert_eq!(v["target"], serde_json::json!({"kg": 0.3, "sted": 0.02}));
    let e = ok_json(&["eval", &pc2, &anim, "--json", "--no-hausdorff"]);
    let worst = e["worst_part"]["kg"].as_f64().unwrap_or(e["kg"].as_f64().unwrap()).max(e["kg"].as_f64().unwrap());
    assert!(worst <= 0.3, "{e}");
    assert!(e["sted"].as_f64().unwrap() <= 0.02, "{e}");
    assert_eq!(v["reached"]["sted"], e["sted"]);
    let text = ok(&["encode", &pc2, "-c", "hosvd", "--target", "kg=0.3,sted=0.02", "-o", &anim, "-f"]);
    assert!(text.contains("target kg=0.3,sted=0.02: hosvd") && text.contains("reaches kg="), "{text}");
    let o = animcodec(&["encode", &pc2, "--target", "kg=0.3,kg=0.2", "-o", &anim, "-f"]);
    assert_eq!(o.status.code(), Some(2), "a malformed --target is a usage error");
    assert!(stderr(&o).contains("kg is bounded twice"), "{}", stderr(&o));
}

/// The envelope sweep's refinement places its points where the target search finds its
/// answers: at every standard target the search meets, the smallest swept stream of the codec
/// meeting it is no larger than the stream the space search (`encode -c CODEC --target`, 4
/// refinement points) chooses. Without the refinement the grid alone is larger somewhere (so
/// this can fail), and the refined sweep is the same at 1 and 2 threads.
#[test]
fn refined_sweep_envelope_reaches_what_the_target_search_finds() {
    let registry = animcodec::registry();
    let animation = synth::waving_flag(14, 10, 16);
    let eval = EvalOptions::default();
    let names = ["quant-delta", "pca-aoi", "hosvd"];
    let codecs: Vec<(&dyn AnimationCodec, ParamSet, Vec<&'static str>)> = names
        .iter()
        .map(|n| {
            let c = registry.by_name(n).unwrap();
            (c, c.default_params(), Vec::new())
        })
        .collect();
    let sweep = |rounds: usize, jobs: usize| {
        let options = harness::SweepOptions { jobs: Some(jobs), refine_rounds: rounds, ..Default::default() };
        let swept = harness::envelope_sweep(&registry, &codecs, &animation, &options, 3, &|_| {}).unwrap();
        assert!(swept.failures.is_empty(), "{:?}", swept.failures);
        swept
    };
    let (grid, refined) = (sweep(0, 2), sweep(harness::REFINE_ROUNDS, 2));
    assert!(refined.points.iter().any(|p| p.refined) && !grid.points.iter().any(|p| p.refined));
    let same = |a: &harness::Sweep, b: &harness::Sweep| {
        let key = |s: &harness::Sweep| {
            s.points.iter().map(|p| (p.series.clone(), p.params.to_string(), p.bytes)).collect::<Vec<_>>()
        };
        key(a) == key(b)
    };
    assert!(same(&refined, &sweep(harness::REFINE_ROUNDS, 1)), "the refined sweep depends on the thread count");
    let smallest = |s: &harness::Sweep, codec: &str, target: Target| {
        s.points
            .iter()
            .filter(|p| p.codec == codec && harness::usable(p) && target.meets(&p.report))
            .map(|p| p.bytes)
            .min()
    };
    let (mut compared, mut grid_larger) = (0, 0);
    for target in harness::STANDARD_TARGETS {
        for (codec, base, _) in &codecs {
            let Ok(hit) = search_space_target(&request(&registry, &animation, target, &eval, 4), *codec, base, &[])
            else {
                continue;
            };
            let swept = smallest(&refined, codec.name(), target).expect("the search met it, so a swept point does");
            assert!(
                swept <= hit.point.bytes,
                "{} at {target}: the refined sweep's smallest passing stream is {swept} B, the search found {} B ({})",
                codec.name(),
                hit.point.bytes,
                hit.point.params
            );
            compared += 1;
            grid_larger += usize::from(smallest(&grid, codec.name(), target).is_none_or(|g| g > hit.point.bytes));
        }
    }
    eprintln!("{compared} (codec, target) pairs compared; the grid alone was larger at {grid_larger}");
    assert!(compared >= 6, "only {compared} (codec, target) pairs met by the search");
    assert!(grid_larger > 0, "the grid alone already matched the search everywhere: the test shows nothing");
}
