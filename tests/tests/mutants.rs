//! The suite's checks can fail: each runs on a registry holding a deliberately broken copy of
//! `quant-delta` (a "mutant") and must report that codec, for the right reason. The unbroken
//! wrapper passes every check, so the failures come from the injected faults alone.

use std::sync::Once;

use codec_core::{
    Animation, AnimationCodec, CodecRegistry, EncodedPacket, EncoderSetup, ErrorBound, FourCc, FrameDecoder,
    FrameEncoder, Limits, Packet, ParamSet, ParamSpec, ParamValue, RateLadder, Result, StreamInfo,
};
use codec_quant_delta::{QuantDelta, QuantDeltaParams};
use conformance_tests::suite::{self, Check};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Fault {
    None,
    LyingBound,
    ReconstructionMismatch,
    FeedDependent,
    ThreadDependent,
    SeekBroken,
    ShrinkingLadder,
    DefaultOutOfRange,
    PanicOnShortPayload,
    GreedyDecoder,
    PanicOnEmptyConfig,
    PanicOnSingleFrame,
    GreedyEncoder,
    RefusesShortInput,
}

const FAULTS: [(Fault, &str); 14] = [
    (Fault::None, "mutant-none"),
    (Fault::LyingBound, "mutant-lying-bound"),
    (Fault::ReconstructionMismatch, "mutant-reconstruction"),
    (Fault::FeedDependent, "mutant-feed"),
    (Fault::ThreadDependent, "mutant-threads"),
    (Fault::SeekBroken, "mutant-seek"),
    (Fault::ShrinkingLadder, "mutant-ladder"),
    (Fault::DefaultOutOfRange, "mutant-default"),
    (Fault::PanicOnShortPayload, "mutant-short-payload"),
    (Fault::GreedyDecoder, "mutant-greedy-decoder"),
    (Fault::PanicOnEmptyConfig, "mutant-empty-config"),
    (Fault::PanicOnSingleFrame, "mutant-single-frame"),
    (Fault::GreedyEncoder, "mutant-greedy-encoder"),
    (Fault::RefusesShortInput, "mutant-refuses-short"),
];

/// `quant-delta` with one fault injected.
struct Mutant(Fault);

impl Mutant {
    fn index(&self) -> usize {
        FAULTS.iter().position(|(f, _)| *f == self.0).expect("listed")
    }

    /// The same values as a `quant-delta` parameter set.
    fn inner_params(&self, p: &ParamSet) -> Result<ParamSet> {
        if p.codec() != self.name() {
            return Err(codec_core::Error::parameter(self.name(), "params", "parameters of another codec"));
        }
        let typed = QuantDeltaParams {
            bits: p.int("bits")? as u8,
            block: p.int("block")? as u32,
            level: p.int("level")? as i32,
        };
        typed.to_param_set()
    }
}

impl AnimationCodec for Mutant {
    fn name(&self) -> &'static str {
        FAULTS[self.index()].1
    }
    fn fourcc(&self) -> FourCc {
        FourCc([b'M', b'U', b'T', b'a' + self.index() as u8])
    }
    fn stream_version(&self) -> u16 {
        1
    }
    fn summary(&self) -> &'static str {
        "quant-delta with an injected fault"
    }
    fn param_specs(&self) -> Vec<ParamSpec> {
        let mut specs = QuantDelta.param_specs();
        if self.0 == Fault::DefaultOutOfRange {
            specs[0].default = ParamValue::Int(30);
        }
        specs
    }
    fn rate_ladder(&self, _base: &ParamSet) -> RateLadder {
        let mut l = QuantDelta.rate_ladder(_base);
        if self.0 == Fault::ShrinkingLadder {
            l.steps.reverse();
        }
        l
    }
    fn validate(&self, params: &ParamSet) -> Result<()> {
        QuantDelta.validate(&self.inner_params(params)?)
    }
    fn error_bound(&self, params: &ParamSet, animation: &Animation) -> Result<ErrorBound> {
        let mut b = QuantDelta.error_bound(&self.inner_params(params)?, animation)?;
        if self.0 == Fault::LyingBound {
            b.max_coordinate_error = b.max_coordinate_error.map(|e| e / 10.0);
        }
        Ok(b)
    }
    fn new_encoder(&self, params: &ParamSet, setup: &EncoderSetup<'_>) -> Result<Box<dyn FrameEncoder>> {
        let mut inner = self.inner_params(params)?;
        if self.0 == Fault::ThreadDependent && rayon::current_num_threads() == 1 {
            inner = inner.with(&QuantDelta.param_specs(), "block", ParamValue::Int(8))?;
        }
        if self.0 == Fault::RefusesShortInput && setup.frame_count < 3 {
            // A plausible, worded refusal of a valid input: only the refusal table can tell.
            return Err(codec_core::Error::InvalidAnimation("mutant: fewer than 3 frames".into()));
        }
        if self.0 == Fault::GreedyEncoder {
            // Sized from the declared frame count, capped so the test cannot exhaust memory.
            let v: Vec<u8> = Vec::with_capacity(setup.frame_count.min(1 << 26) * 16);
            std::hint::black_box(&v);
        }
        Ok(Box::new(MutantEncoder {
            fault: self.0,
            inner: QuantDelta.new_encoder(&inner, setup)?,
            single_frame: setup.frame_count == 1,
        }))
    }
    fn new_decoder(&self, info: &StreamInfo, config: &[u8], limits: &Limits) -> Result<Box<dyn FrameDecoder>> {
        if self.0 == Fault::PanicOnEmptyConfig {
            assert!(!config.is_empty(), "mutant: indexing an empty config");
        }
        Ok(Box::new(MutantDecoder { fault: self.0, inner: QuantDelta.new_decoder(info, config, limits)?, decoded: 0 }))
    }
}

struct MutantEncoder {
    fault: Fault,
    inner: Box<dyn FrameEncoder>,
    single_frame: bool,
}

impl FrameEncoder for MutantEncoder {
    fn config(&self) -> Vec<u8> {
        self.inner.config()
    }
    fn push_frames(&mut self, frames: &[f32]) -> Result<Vec<EncodedPacket>> {
        assert!(!(self.fault == Fault::PanicOnSingleFrame && self.single_frame), "mutant: cannot code one frame");
        let mut out = self.inner.push_frames(frames)?;
        if self.fault == Fault::FeedDependent {
            // Cuts a packet at every push: valid stream, but the bytes follow the feeding.
            out.extend(self.inner.finish()?);
        }
        if self.fault == Fault::ReconstructionMismatch {
            for p in &mut out {
                if let Some(r) = p.reconstruction.as_mut() {
                    r[0] += 1e-3;
                }
            }
        }
        Ok(out)
    }
    fn finish(&mut self) -> Result<Vec<EncodedPacket>> {
        self.inner.finish()
    }
}

struct MutantDecoder {
    fault: Fault,
    inner: Box<dyn FrameDecoder>,
    decoded: usize,
}

impl FrameDecoder for MutantDecoder {
    fn decode_packet(&mut self, packet: &Packet) -> Result<Vec<f32>> {
        if self.fault == Fault::PanicOnShortPayload {
            assert!(packet.data.len() > 27, "mutant: payload shorter than the three quantizers");
        }
        if self.fault == Fault::GreedyDecoder {
            // Trusts the first payload byte (the bit depth): 12 bits → 48 MiB, a flipped byte → up to 1 GiB.
            let v: Vec<u8> = Vec::with_capacity((packet.data.first().copied().unwrap_or(0) as usize) << 22);
            std::hint::black_box(&v);
        }
        let mut out = self.inner.decode_packet(packet)?;
        if self.fault == Fault::SeekBroken && self.decoded == 0 && packet.first_frame != 0 {
            out.iter_mut().for_each(|x| *x += 1e-3);
        }
        self.decoded += 1;
        Ok(out)
    }
    fn reset(&mut self) {
        self.inner.reset();
    }
}

fn registry_of(fault: Fault) -> CodecRegistry {
    CodecRegistry::new(vec![Box::new(Mutant(fault))]).expect("one codec")
}

/// Mutant panics are expected by the hundreds; keep them off stderr, print everything else.
fn quiet_mutant_panics() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let msg = info
                .payload()
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| info.payload().downcast_ref::<&str>().map(|s| s.to_string()));
            if !msg.is_some_and(|m| m.contains("mutant:")) {
                default(info);
            }
        }));
    });
}

fn expect_caught(fault: Fault, checks: &[(&str, Check)], needle: &str) {
    quiet_mutant_panics();
    let registry = registry_of(fault);
    let name = Mutant(fault).name();
    for (check_name, check) in checks {
        let failures = check(&registry);
        assert!(
            failures.has(name, needle),
            "{check_name} did not report {name} with '{needle}'; it reported: {:#?}",
            failures.messages()
        );
    }
}

#[test]
fn unbroken_wrapper_passes_every_check() {
    quiet_mutant_panics();
    let registry = registry_of(Fault::None);
    for (name, check) in suite::ALL {
        check(&registry).assert_none(name);
    }
}

#[test]
fn lying_bound_is_caught() {
    expect_caught(Fault::LyingBound, &[("round_trip", suite::round_trip_matches_reconstruction_and_bound)], "> bound");
}

#[test]
fn reconstruction_mismatch_is_caught() {
    expect_caught(
        Fault::ReconstructionMismatch,
        &[("round_trip", suite::round_trip_matches_reconstruction_and_bound)],
        "differ from the encoder's reconstruction",
    );
}

#[test]
fn feed_dependent_bytes_are_caught() {
    expect_caught(
        Fault::FeedDependent,
        &[("feeding", suite::feeding_pattern_does_not_change_bytes)],
        "differing from all-at-once",
    );
}

#[test]
fn thread_dependent_bytes_are_caught() {
    expect_caught(Fault::ThreadDependent, &[("threads", suite::bytes_do_not_depend_on_thread_count)], "not identical");
}

#[test]
fn broken_seek_is_caught() {
    expect_caught(
        Fault::SeekBroken,
        &[("random_access", suite::random_access_matches_full_decode)],
        "differs from the full decode",
    );
}

#[test]
fn shrinking_ladder_is_caught() {
    expect_caught(Fault::ShrinkingLadder, &[("ladder", suite::rate_ladder_sizes_are_non_decreasing)], "shrink");
}

#[test]
fn default_out_of_range_is_caught() {
    expect_caught(
        Fault::DefaultOutOfRange,
        &[("out_of_range", suite::out_of_range_parameters_are_rejected_with_the_range)],
        "outside its own spec",
    );
    expect_caught(
        Fault::DefaultOutOfRange,
        &[("defaults", suite::defaults_and_ladder_steps_validate)],
        "do not validate",
    );
}

#[test]
fn decoder_panic_on_short_payload_is_caught() {
    expect_caught(Fault::PanicOnShortPayload, &[("structural", suite::structural_mutations_never_panic)], "panicked");
}

#[test]
fn greedy_decoder_is_caught() {
    expect_caught(Fault::GreedyDecoder, &[("payload_flips", suite::payload_flips_with_valid_crc_never_panic)], "peak");
}

#[test]
fn decoder_panic_on_empty_config_is_caught() {
    expect_caught(Fault::PanicOnEmptyConfig, &[("config", suite::corrupt_config_and_version_never_panic)], "panicked");
}

#[test]
fn encoder_panic_on_edge_case_is_caught() {
    expect_caught(
        Fault::PanicOnSingleFrame,
        &[("edge_cases", suite::edge_case_animations_round_trip_or_error)],
        "panicked",
    );
}

#[test]
fn greedy_encoder_is_caught() {
    expect_caught(Fault::GreedyEncoder, &[("encoder_input", suite::encoder_rejects_bad_input)], "peak");
}

#[test]
fn refusing_valid_short_input_is_caught() {
    expect_caught(
        Fault::RefusesShortInput,
        &[
            ("edge_cases", suite::edge_case_animations_round_trip_or_error),
            ("short", suite::short_animations_meet_the_long_animations_bound),
        ],
        "expects a round trip",
    );
}
