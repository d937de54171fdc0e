//! The checks of the conformance suite, each a function of a registry that returns the
//! [`Failures`] it found, named by codec. `tests/*.rs` run them on `animcodec::registry()`;
//! `tests/mutants.rs` runs them on deliberately broken codecs to show that each check can fail.
//!
//! Decodes of untrusted bytes run under `catch_unwind` (a panic is reported with the codec
//! and the corruption instead of aborting) and under `allocation_counter::measure`, with tight
//! [`Limits`]; the peak bytes held on the calling thread must stay within [`peak_budget`].
//! Allocations made on other threads (rayon inside a decoder) are not seen.

use std::io::Cursor;
use std::time::{Duration, Instant};

use codec_core::container::IndexEntry;
use codec_core::{
    decode_animation, decode_frame, encode_animation, encode_animation_fed, Animation, AnimationCodec, CodecRegistry,
    Limits, Packet, ParamKind, ParamSet, ParamValue, StreamEncoder, Topology,
};

use crate::*;

/// A check: runs on every codec of a registry and returns what failed.
pub type Check = fn(&CodecRegistry) -> Failures;

/// Every check of the suite, by name.
pub const ALL: &[(&str, Check)] = &[
    ("round_trip_matches_reconstruction_and_bound", round_trip_matches_reconstruction_and_bound),
    ("edge_case_animations_round_trip_or_error", edge_case_animations_round_trip_or_error),
    ("feeding_pattern_does_not_change_bytes", feeding_pattern_does_not_change_bytes),
    ("bytes_do_not_depend_on_thread_count", bytes_do_not_depend_on_thread_count),
    ("random_access_matches_full_decode", random_access_matches_full_decode),
    ("out_of_range_parameters_are_rejected_with_the_range", out_of_range_parameters_are_rejected_with_the_range),
    ("defaults_and_ladder_steps_validate", defaults_and_ladder_steps_validate),
    ("rate_ladder_sizes_are_non_decreasing", rate_ladder_sizes_are_non_decreasing),
    ("registry_names_and_fourccs_are_unique", registry_names_and_fourccs_are_unique),
    ("unknown_fourcc_and_default_limits", unknown_fourcc_and_default_limits),
    ("every_truncation_is_an_error", every_truncation_is_an_error),
    ("byte_flips_are_detected", byte_flips_are_detected),
    ("payload_flips_with_valid_crc_never_panic", payload_flips_with_valid_crc_never_panic),
    ("corrupt_config_and_version_never_panic", corrupt_config_and_version_never_panic),
    ("structural_mutations_never_panic", structural_mutations_never_panic),
    ("encoder_rejects_bad_input", encoder_rejects_bad_input),
    ("empty_pushes_are_harmless", empty_pushes_are_harmless),
    ("forged_vertex_count_is_refused", forged_vertex_count_is_refused),
    ("work_budget_is_honoured", work_budget_is_honoured),
    ("forged_frame_rates_are_refused", forged_frame_rates_are_refused),
];

fn encode_with_reconstruction(
    codec: &dyn AnimationCodec,
    params: &ParamSet,
    anim: &Animation,
    feed: usize,
) -> Result<(Vec<u8>, Animation), String> {
    let enc = encode_animation_fed(codec, params, anim, true, feed).map_err(|e| format!("encode failed: {e}"))?;
    let rec = enc.reconstruction.ok_or("encoder returned no reconstruction though asked for one")?;
    Ok((enc.bytes, rec))
}

/// Suite item 1: at default params and both ends of the rate ladder, on several animations,
/// the decoded frames equal the encoder's reconstruction bit for bit and the error is within
/// the declared bound.
pub fn round_trip_matches_reconstruction_and_bound(registry: &CodecRegistry) -> Failures {
    let anims = animations();
    let mut failures = Failures::new();
    for codec in registry.iter() {
        failures.run(codec.name(), |f| {
            let settings = match test_settings(codec) {
                Ok(s) => s,
                Err(e) => return f.push(codec.name(), e),
            };
            for (anim_name, anim) in &anims {
                for (label, params) in &settings {
                    let ctx = format!("{anim_name}, {label}");
                    f.count(1);
                    let (bytes, rec) = match encode_with_reconstruction(codec, params, anim, anim.frame_count()) {
                        Ok(x) => x,
                        Err(e) => {
                            f.push(codec.name(), format!("{ctx}: {e}"));
                            continue;
                        }
                    };
                    let limits = tight_limits(anim);
                    let dec = match decode_animation(&bytes, registry, limits) {
                        Ok(d) => d,
                        Err(e) => {
                            f.push(codec.name(), format!("{ctx}: decode (limits {limits:?}) failed: {e}"));
                            continue;
                        }
                    };
                    if dec.positions() != rec.positions() {
                        let first = dec.positions().iter().zip(rec.positions()).position(|(a, b)| a.to_bits() != b.to_bits());
                        f.push(
                            codec.name(),
                            format!("{ctx}: decoded frames differ from the encoder's reconstruction (first at coordinate {first:?})"),
                        );
                    }
                    if !codec_core::connectivity::same_triangles(dec.topology(), anim.topology()) || dec.frame_rate() != anim.frame_rate() {
                        f.push(codec.name(), format!("{ctx}: topology or frame rate not preserved"));
                    }
                    let bound = match codec.error_bound(params, anim) {
                        Ok(b) => b,
                        Err(e) => {
                            f.push(codec.name(), format!("{ctx}: error_bound failed: {e}"));
                            continue;
                        }
                    };
                    match measure_error(anim, &dec).and_then(|m| check_bound(&bound, &m)) {
                        Ok(()) => {}
                        Err(e) => f.push(codec.name(), format!("{ctx}: {e}")),
                    }
                }
            }
        });
    }
    failures
}

/// The unusual inputs each codec refuses at default parameters, by codec and case (the case
/// names of [`edge_animations`] and of [`short_animations_meet_the_long_animations_bound`]),
/// with a fragment its message must contain. Every other (codec, case) must encode and round
/// trip: a refusal not listed here fails the suite, and so does a listed refusal that no longer
/// happens (update the table when a codec learns to handle a case). A codec absent from the
/// table (a new one, the mutants of `tests/mutants.rs`) must handle every case.
pub const EXPECTED_REFUSALS: &[(&str, &str, &str)] = &[
    // hosvd reduces the frame mode of a Tucker decomposition: with one or two frames there is
    // nothing to reduce, and even the smallest core exceeds the size its default `ss` asks for
    // (the paper's size model). It says so and names the parameters and codec that do fit.
    ("hosvd", "single-frame", HOSVD_FEW_FRAMES),
    ("hosvd", "1-frame flag", HOSVD_FEW_FRAMES),
    ("hosvd", "2-frame flag", HOSVD_FEW_FRAMES),
    ("hosvd", "1-frame triangle", HOSVD_FEW_FRAMES),
    ("hosvd", "2-frame triangle", HOSVD_FEW_FRAMES),
];

/// hosvd's refusal of an input too short for its frame mode.
const HOSVD_FEW_FRAMES: &str = "with so few frames the frame mode cannot be reduced";

/// The fragment [`EXPECTED_REFUSALS`] expects in `codec`'s refusal of `case`, if any.
fn expected_refusal(codec: &str, case: &str) -> Option<&'static str> {
    EXPECTED_REFUSALS.iter().find(|(c, k, _)| *c == codec && *k == case).map(|(_, _, m)| *m)
}

/// Checks `codec`'s refusal of `case` (message `e`) against [`EXPECTED_REFUSALS`].
fn check_refusal(f: &mut Failures, codec: &str, case: &str, e: &str) {
    if e.trim().is_empty() {
        f.push(codec, format!("{case}: refused with an empty message"));
    }
    match expected_refusal(codec, case) {
        Some(fragment) if e.contains(fragment) => {}
        Some(fragment) => {
            f.push(codec, format!("{case}: refused with '{e}', expected a message containing '{fragment}'"))
        }
        None => f.push(codec, format!("{case}: refused ({e}), but suite::EXPECTED_REFUSALS expects a round trip")),
    }
}

/// Checks that `codec` was expected to encode `case` (it did).
fn check_accepted(f: &mut Failures, codec: &str, case: &str) {
    if let Some(fragment) = expected_refusal(codec, case) {
        f.push(
            codec,
            format!("{case}: encoded, but suite::EXPECTED_REFUSALS expects a refusal ('{fragment}'): update the table"),
        );
    }
}

/// Unusual animations (one frame, static, no triangles, degenerate triangles, one vertex,
/// a flat axis, far from the origin, exact repeats): encode within the bound and decode to
/// the reconstruction, or refuse as [`EXPECTED_REFUSALS`] says. Never panic.
pub fn edge_case_animations_round_trip_or_error(registry: &CodecRegistry) -> Failures {
    let mut failures = Failures::new();
    for codec in registry.iter() {
        failures.run(codec.name(), |f| {
            for (name, anim) in edge_animations() {
                let params = codec.default_params();
                f.count(1);
                let enc = match catch(|| encode_with_reconstruction(codec, &params, &anim, 3)) {
                    Err(p) => {
                        f.push(codec.name(), format!("{name}: encoder {p}"));
                        continue;
                    }
                    Ok(Err(e)) => {
                        check_refusal(f, codec.name(), name, &e);
                        continue;
                    }
                    Ok(Ok(x)) => x,
                };
                check_accepted(f, codec.name(), name);
                let (bytes, rec) = enc;
                match catch(|| decode_animation(&bytes, registry, tight_limits(&anim))) {
                    Err(p) => f.push(codec.name(), format!("{name}: decoder {p}")),
                    Ok(Err(e)) => f.push(codec.name(), format!("{name}: encoded, but decoding failed: {e}")),
                    Ok(Ok(dec)) => {
                        if dec.positions() != rec.positions() {
                            f.push(codec.name(), format!("{name}: decoded frames differ from the reconstruction"));
                        }
                        match codec.error_bound(&params, &anim) {
                            Err(e) => f.push(codec.name(), format!("{name}: error_bound failed: {e}")),
                            Ok(b) => {
                                if let Err(e) = measure_error(&anim, &dec).and_then(|m| check_bound(&b, &m)) {
                                    f.push(codec.name(), format!("{name}: {e}"));
                                }
                            }
                        }
                    }
                }
            }
        });
    }
    failures
}

/// Very short inputs (1 and 2 frames cut from [`small_animation`], and a single triangle over
/// 1 and 2 frames). At default parameters each codec either refuses as [`EXPECTED_REFUSALS`]
/// says, or decodes to its reconstruction within the bound it declares for the short input
/// *and* within the error it allows itself on the long animation the input was cut from
/// (absolute RMS: the declared relative RMS times the long animation's diagonal; the max
/// coordinate error as declared). So a codec cannot pass by declaring a useless bound for
/// inputs it does not really handle.
pub fn short_animations_meet_the_long_animations_bound(registry: &CodecRegistry) -> Failures {
    let flag = small_animation();
    let triangle = |frames: usize| {
        let positions: Vec<f32> = (0..frames)
            .flat_map(|t| {
                let s = (t as f32 * 0.4).sin();
                [0.0, 0.0, 0.0, 1.0, 0.2 * s, 0.1, -0.3 * s, 1.0, 0.05 * t as f32]
            })
            .collect();
        Animation::from_parts(3, vec![[0, 1, 2]], positions, 30.0).expect("valid")
    };
    let cut = |a: &Animation, frames: usize| {
        Animation::new(a.topology().clone(), a.positions()[..frames * a.vertex_count() * 3].to_vec(), 30.0)
            .expect("valid")
    };
    let long_triangle = triangle(24);
    let cases = [
        ("1-frame flag", &flag, cut(&flag, 1)),
        ("2-frame flag", &flag, cut(&flag, 2)),
        ("1-frame triangle", &long_triangle, cut(&long_triangle, 1)),
        ("2-frame triangle", &long_triangle, cut(&long_triangle, 2)),
    ];
    let mut failures = Failures::new();
    for codec in registry.iter() {
        failures.run(codec.name(), |f| {
            let params = codec.default_params();
            for (name, long, short) in &cases {
                f.count(1);
                let enc = match catch(|| encode_with_reconstruction(codec, &params, short, 1)) {
                    Err(p) => {
                        f.push(codec.name(), format!("{name}: encoder {p}"));
                        continue;
                    }
                    Ok(Err(e)) => {
                        check_refusal(f, codec.name(), name, &e);
                        continue;
                    }
                    Ok(Ok(x)) => x,
                };
                check_accepted(f, codec.name(), name);
                let (bytes, rec) = enc;
                let dec = match catch(|| decode_animation(&bytes, registry, tight_limits(short))) {
                    Ok(Ok(d)) => d,
                    Ok(Err(e)) => {
                        f.push(codec.name(), format!("{name}: encoded, but decoding failed: {e}"));
                        continue;
                    }
                    Err(p) => {
                        f.push(codec.name(), format!("{name}: decoder {p}"));
                        continue;
                    }
                };
                if dec.positions() != rec.positions() {
                    f.push(codec.name(), format!("{name}: decoded frames differ from the reconstruction"));
                }
                let measured = match measure_error(short, &dec) {
                    Ok(m) => m,
                    Err(e) => {
                        f.push(codec.name(), format!("{name}: {e}"));
                        continue;
                    }
                };
                match codec.error_bound(&params, short) {
                    Ok(b) => {
                        if let Err(e) = check_bound(&b, &measured) {
                            f.push(codec.name(), format!("{name}: {e}"));
                        }
                    }
                    Err(e) => f.push(codec.name(), format!("{name}: encoded, but error_bound failed: {e}")),
                }
                let Ok(long_bound) = codec.error_bound(&params, long) else {
                    f.push(codec.name(), format!("{name}: error_bound failed on the long animation"));
                    continue;
                };
                let rms = measured.relative_rms_error * short.bounding_box_diagonal();
                let slack = 1.0 + 1e-9;
                if let Some(b) = long_bound.max_coordinate_error.filter(|b| b.is_finite()) {
                    if measured.max_coordinate_error > b * slack {
                        f.push(
                            codec.name(),
                            format!(
                                "{name}: max coordinate error {:.3e} > {b:.3e}, the bound declared on the long \
                                 animation it was cut from",
                                measured.max_coordinate_error
                            ),
                        );
                    }
                }
                if let Some(b) = long_bound.relative_rms_error.filter(|b| b.is_finite()) {
                    let allowed = b * long.bounding_box_diagonal();
                    if rms > allowed * slack {
                        f.push(
                            codec.name(),
                            format!(
                                "{name}: RMS error {rms:.3e} > {allowed:.3e}, what the bound declared on the long \
                                 animation allows"
                            ),
                        );
                    }
                }
            }
        });
    }
    failures
}

/// Suite item 2: the bytes do not depend on how frames are fed (1 at a time, odd blocks, all
/// at once) nor on whether the reconstruction was requested.
pub fn feeding_pattern_does_not_change_bytes(registry: &CodecRegistry) -> Failures {
    let anim = small_animation();
    let mut failures = Failures::new();
    for codec in registry.iter() {
        failures.run(codec.name(), |f| {
            let params = codec.default_params();
            let reference = match encode_animation(codec, &params, &anim) {
                Ok(b) => b,
                Err(e) => return f.push(codec.name(), format!("encode failed: {e}")),
            };
            let n = anim.frame_count();
            for (feed, want_rec) in [(1, false), (3, true), (7, false), (13, true), (n - 1, false), (n, true), (1000, false)]
            {
                f.count(1);
                match encode_animation_fed(codec, &params, &anim, want_rec, feed) {
                    Err(e) => f.push(codec.name(), format!("feed {feed}: encode failed: {e}")),
                    Ok(enc) if enc.bytes != reference => f.push(
                        codec.name(),
                        format!(
                            "feeding {feed} frame(s) at a time (reconstruction {want_rec}) gives {} bytes differing from all-at-once ({} bytes)",
                            enc.bytes.len(),
                            reference.len()
                        ),
                    ),
                    Ok(_) => {}
                }
            }
        });
    }
    failures
}

/// Suite item 3: identical bytes whether encoding runs in a 1-thread or a 4-thread rayon
/// pool, and identical frames when decoding in either.
pub fn bytes_do_not_depend_on_thread_count(registry: &CodecRegistry) -> Failures {
    let anims = [small_animation(), synth::bending_cylinder(8, 10, 30)];
    let pool = |n| rayon::ThreadPoolBuilder::new().num_threads(n).build().expect("thread pool");
    let (one, four) = (pool(1), pool(4));
    let mut failures = Failures::new();
    for codec in registry.iter() {
        failures.run(codec.name(), |f| {
            let settings = match test_settings(codec) {
                Ok(s) => s,
                Err(e) => return f.push(codec.name(), e),
            };
            for (i, anim) in anims.iter().enumerate() {
                for (label, params) in &settings {
                    f.count(1);
                    let a = one.install(|| encode_animation(codec, params, anim));
                    let b = four.install(|| encode_animation(codec, params, anim));
                    match (a, b) {
                        (Ok(a), Ok(b)) if a == b => {
                            let d1 = one.install(|| decode_animation(&a, registry, Limits::default()));
                            let d4 = four.install(|| decode_animation(&a, registry, Limits::default()));
                            match (d1, d4) {
                                (Ok(x), Ok(y)) if x.positions() == y.positions() => {}
                                (Ok(_), Ok(_)) => f.push(
                                    codec.name(),
                                    format!(
                                        "animation {i}, {label}: decoding with 1 and 4 threads gives different frames"
                                    ),
                                ),
                                (x, y) => f.push(
                                    codec.name(),
                                    format!("animation {i}, {label}: decode failed: {:?} / {:?}", x.err(), y.err()),
                                ),
                            }
                        }
                        (Ok(a), Ok(b)) => f.push(
                            codec.name(),
                            format!(
                                "animation {i}, {label}: 1 thread gives {} bytes, 4 threads {} bytes, not identical",
                                a.len(),
                                b.len()
                            ),
                        ),
                        (a, b) => f.push(
                            codec.name(),
                            format!("animation {i}, {label}: encode failed: {:?} / {:?}", a.err(), b.err()),
                        ),
                    }
                }
            }
        });
    }
    failures
}

/// Suite item 6: `decode_frame` on a seekable stream returns the same frame as the full
/// decode, for every frame (first, middle and last included), bit for bit.
pub fn random_access_matches_full_decode(registry: &CodecRegistry) -> Failures {
    let anims = [small_animation(), synth::phased_motion_sized(8, 10, 36).0];
    let mut failures = Failures::new();
    for codec in registry.iter() {
        failures.run(codec.name(), |f| {
            for (i, anim) in anims.iter().enumerate() {
                let bytes = match encode_animation(codec, &codec.default_params(), anim) {
                    Ok(b) => b,
                    Err(e) => return f.push(codec.name(), format!("animation {i}: encode failed: {e}")),
                };
                let limits = tight_limits(anim);
                let full = match decode_animation(&bytes, registry, limits) {
                    Ok(a) => a,
                    Err(e) => return f.push(codec.name(), format!("animation {i}: decode failed: {e}")),
                };
                let mut cursor = Cursor::new(&bytes);
                for t in 0..anim.frame_count() {
                    f.count(1);
                    match decode_frame(&mut cursor, registry, limits, t) {
                        Ok(frame) if frame == full.frame(t) => {}
                        Ok(_) => f.push(
                            codec.name(),
                            format!("animation {i}: decode_frame({t}) differs from the full decode"),
                        ),
                        Err(e) => f.push(codec.name(), format!("animation {i}: decode_frame({t}) failed: {e}")),
                    }
                }
                if decode_frame(&mut cursor, registry, limits, anim.frame_count()).is_ok() {
                    f.push(codec.name(), format!("animation {i}: decode_frame past the end succeeded"));
                }
                f.count(1);
                if let Err(e) = frames_of_packets_match_full_decode(&bytes, registry, limits, &full) {
                    f.push(codec.name(), format!("animation {i}: {e}"));
                }
            }
        });
    }
    failures
}

/// Every frame of the stream `bytes` through [`codec_core::FrameDecoder::decode_frame_of_packet`] on one
/// decoder kept across requests (what the C library's playhead does) equals frame `t` of `full`,
/// the stream's full decode, bit for bit.
///
/// A codec that [decodes single frames](codec_core::FrameDecoder::decodes_single_frames) is asked every frame
/// in a scrambled order that jumps between packets and comes back to them (a kept parse and a
/// new one), and after each packet's first frame the whole packet by `decode_packet` (which may
/// use the kept parse); once keeping the last packet's parse only, once keeping every packet's
/// ([`codec_core::FrameDecoder::keep_parsed_packets`]). Any other codec is asked, packet by packet in stream order from a
/// reset, one frame each: its default hook decodes the packet and so advances the decoder as
/// `decode_packet` does. A frame past the end of a packet is refused.
pub fn frames_of_packets_match_full_decode(
    bytes: &[u8],
    registry: &CodecRegistry,
    limits: Limits,
    full: &Animation,
) -> Result<(), String> {
    use codec_core::container;
    use codec_core::stream::{decode_frame_checked, decode_packet_checked, random_access_limits};
    let mut src = Cursor::new(bytes);
    let (header, index) = container::read_index(&mut src, limits).map_err(|e| format!("index: {e}"))?;
    let codec = registry.by_fourcc(header.info.fourcc).map_err(|e| e.to_string())?;
    let decoder_limits = random_access_limits(codec.name(), &header, &index, limits).map_err(|e| e.to_string())?;
    let mut decoder =
        codec.new_decoder(&header.info, &header.config, &decoder_limits).map_err(|e| format!("decoder: {e}"))?;
    let name = codec.name();
    let mut read = |pos: usize| -> Result<Packet, String> {
        container::read_packet_at(&mut src, &index[pos], &header, limits).map_err(|e| format!("packet {pos}: {e}"))
    };
    let frames = full.frame_count();
    let packet_of = |t: usize| index.partition_point(|e| e.first_frame as usize <= t).saturating_sub(1);
    let expect = |t: usize, got: &[f32], how: &str| -> Result<(), String> {
        let want = full.frame(t);
        if got.len() != want.len() || got.iter().zip(want).any(|(a, b)| a.to_bits() != b.to_bits()) {
            return Err(format!("frame {t} by {how} differs from the full decode"));
        }
        Ok(())
    };
    // Twice: keeping the last packet's parse only, then every packet's (a budget that holds them).
    for budget in [0, 1 << 30] {
        if !decoder.decodes_single_frames() {
            break;
        }
        decoder =
            codec.new_decoder(&header.info, &header.config, &decoder_limits).map_err(|e| format!("decoder: {e}"))?;
        decoder.keep_parsed_packets(budget);
        // A stride coprime with the frame count visits every frame once, out of order.
        let stride = (1..=frames).rev().find(|s| s * 8 <= frames * 5 && gcd(*s, frames) == 1).unwrap_or(1);
        let mut seen = vec![false; index.len()];
        for i in 0..frames {
            let t = (i * stride) % frames;
            let pos = packet_of(t);
            let packet = read(pos)?;
            let local = t - index[pos].first_frame as usize;
            let frame = decode_frame_checked(decoder.as_mut(), name, &header, &packet, local, &limits)
                .map_err(|e| format!("frame {t}: {e}"))?;
            expect(t, &frame, "decode_frame_of_packet")?;
            if !std::mem::replace(&mut seen[pos], true) {
                let all = decode_packet_checked(decoder.as_mut(), name, &header, &packet, &limits)
                    .map_err(|e| format!("packet {pos}: {e}"))?;
                let v3 = full.vertex_count() * 3;
                for (j, frame) in all.chunks_exact(v3.max(1)).enumerate() {
                    expect(index[pos].first_frame as usize + j, frame, "decode_packet after a frame of it")?;
                }
            }
        }
    }
    if !decoder.decodes_single_frames() {
        decoder.reset();
        for (pos, entry) in index.iter().enumerate() {
            let local = pos % entry.frame_count as usize;
            let frame = decode_frame_checked(decoder.as_mut(), name, &header, &read(pos)?, local, &limits)
                .map_err(|e| format!("packet {pos}: {e}"))?;
            expect(entry.first_frame as usize + local, &frame, "the default decode_frame_of_packet")?;
        }
    }
    if let Some(pos) = index.len().checked_sub(1) {
        let packet = read(pos)?;
        let past = packet.frame_count as usize;
        if decode_frame_checked(decoder.as_mut(), name, &header, &packet, past, &limits).is_ok() {
            return Err(format!("frame {past} of a packet of {past} frames was decoded"));
        }
    }
    Ok(())
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

// ---------------------------------------------------------------------------------------
// Parameters (suite item 7) and registry (suite item 10)
// ---------------------------------------------------------------------------------------

/// The next `f64` below/above `x` (towards −∞ / +∞), for "just outside the range".
fn next_f64(x: f64, up: bool) -> f64 {
    if x == 0.0 {
        return if up { f64::from_bits(1) } else { -f64::from_bits(1) };
    }
    let bits = x.to_bits();
    let bigger_magnitude = (x > 0.0) == up;
    f64::from_bits(if bigger_magnitude { bits + 1 } else { bits - 1 })
}

/// Suite item 7: for every `ParamSpec`, values just outside its range are rejected by
/// `ParamSet::set` with a message naming the codec, the parameter and the range; values of
/// the wrong kind and unknown names are rejected too.
pub fn out_of_range_parameters_are_rejected_with_the_range(registry: &CodecRegistry) -> Failures {
    let mut failures = Failures::new();
    for codec in registry.iter() {
        failures.run(codec.name(), |f| {
            let specs = codec.param_specs();
            let mut names: Vec<&str> = specs.iter().map(|s| s.name).collect();
            names.sort_unstable();
            if names.windows(2).any(|w| w[0] == w[1]) {
                f.push(codec.name(), format!("duplicate parameter names: {names:?}"));
            }
            for spec in &specs {
                if let Err(e) = spec.check(codec.name(), &spec.default) {
                    f.push(codec.name(), format!("default of '{}' is outside its own spec: {e}", spec.name));
                }
                if spec.doc.trim().is_empty() {
                    f.push(codec.name(), format!("parameter '{}' has no doc", spec.name));
                }
                let (bad, range_text): (Vec<ParamValue>, Vec<String>) = match &spec.kind {
                    ParamKind::Int { min, max } => {
                        let mut v = Vec::new();
                        if let Some(x) = min.checked_sub(1) {
                            v.push(ParamValue::Int(x));
                        }
                        if let Some(x) = max.checked_add(1) {
                            v.push(ParamValue::Int(x));
                        }
                        v.push(ParamValue::Float(*min as f64));
                        (v, vec![format!("{min}..={max}")])
                    }
                    ParamKind::Float { min, max } => (
                        vec![
                            ParamValue::Float(next_f64(*min, false)),
                            ParamValue::Float(next_f64(*max, true)),
                            ParamValue::Float(f64::NAN),
                            ParamValue::Float(f64::INFINITY),
                        ],
                        vec![format!("{min}..={max}")],
                    ),
                    ParamKind::Bool => (vec![ParamValue::Int(1), ParamValue::Choice("true")], vec![]),
                    ParamKind::Choice(options) => (
                        vec![ParamValue::Choice("no-such-option"), ParamValue::Int(0)],
                        options.iter().map(|o| o.to_string()).collect(),
                    ),
                };
                for value in bad {
                    f.count(1);
                    let mut p = codec.default_params();
                    match p.set(&specs, spec.name, value.clone()) {
                        Ok(()) => f.push(codec.name(), format!("'{}' = {value} was accepted", spec.name)),
                        Err(e) => {
                            let msg = e.to_string();
                            // A wrong-kind value is reported by kind; an out-of-range one must state the range.
                            let wrong_kind = !matches!(
                                (&spec.kind, &value),
                                (ParamKind::Int { .. }, ParamValue::Int(_))
                                    | (ParamKind::Float { .. }, ParamValue::Float(_))
                                    | (ParamKind::Choice(_), ParamValue::Choice(_))
                            );
                            let states_range = wrong_kind || range_text.iter().all(|r| msg.contains(r.as_str()));
                            if !msg.contains(codec.name()) || !msg.contains(spec.name) || !states_range {
                                f.push(
                                    codec.name(),
                                    format!("rejecting '{}' = {value}: message does not name codec, parameter and range {range_text:?}: {msg}", spec.name),
                                );
                            }
                            if p != codec.default_params() {
                                f.push(codec.name(), format!("a rejected set of '{}' changed the parameter set", spec.name));
                            }
                        }
                    }
                }
            }
            match codec.default_params().set(&specs, "no-such-parameter", ParamValue::Int(1)) {
                Ok(()) => f.push(codec.name(), "unknown parameter name accepted"),
                Err(e) => {
                    let msg = e.to_string();
                    if !specs.iter().all(|s| msg.contains(s.name)) {
                        f.push(codec.name(), format!("unknown-parameter error does not list the valid names: {msg}"));
                    }
                }
            }
        });
    }
    failures
}

/// Suite item 7: defaults validate; every rate-ladder step is settable and validates; a
/// parameter set made for another codec is refused.
pub fn defaults_and_ladder_steps_validate(registry: &CodecRegistry) -> Failures {
    let mut failures = Failures::new();
    for codec in registry.iter() {
        failures.run(codec.name(), |f| {
            let defaults = codec.default_params();
            if defaults.codec() != codec.name() {
                f.push(codec.name(), format!("default_params() belongs to '{}'", defaults.codec()));
            }
            if let Err(e) = codec.validate(&defaults) {
                f.push(codec.name(), format!("defaults do not validate: {e}"));
            }
            let ladder = codec.rate_ladder(&codec.default_params());
            if !codec.param_specs().iter().any(|s| s.name == ladder.param) {
                f.push(codec.name(), format!("rate ladder walks '{}', which is not a parameter", ladder.param));
            }
            if ladder.steps.len() < 2 {
                f.push(codec.name(), format!("rate ladder has {} step(s); at least 2 needed", ladder.steps.len()));
            }
            for step in &ladder.steps {
                f.count(1);
                match params_with(codec, ladder.param, step.clone()) {
                    Err(e) => f.push(codec.name(), format!("ladder step {}={step} rejected by set: {e}", ladder.param)),
                    Ok(p) => {
                        if let Err(e) = codec.validate(&p) {
                            f.push(codec.name(), format!("ladder step {}={step} does not validate: {e}", ladder.param));
                        }
                    }
                }
            }
            let foreign = ParamSet::defaults("some-other-codec", &codec.param_specs());
            if codec.validate(&foreign).is_ok() {
                f.push(codec.name(), "validate() accepts a parameter set made for another codec");
            }
        });
    }
    failures
}

/// Suite item 7: the rate ladder's streams do not shrink from one step to the next (small →
/// large), on two synthetic animations. No tolerance: a smaller stream at a higher step is
/// reported.
pub fn rate_ladder_sizes_are_non_decreasing(registry: &CodecRegistry) -> Failures {
    let anims =
        [("waving-flag", synth::waving_flag(10, 8, 24)), ("bending-cylinder", synth::bending_cylinder(8, 10, 30))];
    let mut failures = Failures::new();
    for codec in registry.iter() {
        failures.run(codec.name(), |f| {
            let ladder = codec.rate_ladder(&codec.default_params());
            for (name, anim) in &anims {
                let mut sizes = Vec::new();
                for step in &ladder.steps {
                    f.count(1);
                    let r = params_with(codec, ladder.param, step.clone())
                        .and_then(|p| encode_animation(codec, &p, anim))
                        .map(|b| b.len());
                    match r {
                        Ok(n) => sizes.push((step.clone(), n)),
                        Err(e) => {
                            f.push(codec.name(), format!("{name}: {}={step}: encode failed: {e}", ladder.param));
                            return;
                        }
                    }
                }
                let listing = sizes.iter().map(|(s, n)| format!("{s}:{n}")).collect::<Vec<_>>().join(" ");
                if sizes.windows(2).any(|w| w[1].1 < w[0].1) {
                    f.push(
                        codec.name(),
                        format!("{name}: stream sizes along the '{}' ladder shrink: {listing}", ladder.param),
                    );
                }
                if sizes.first().map(|x| x.1) == sizes.last().map(|x| x.1) {
                    f.push(codec.name(), format!("{name}: the ladder does not change the stream size: {listing}"));
                }
            }
        });
    }
    failures
}

/// Suite item 10: names and FourCCs unique and well formed; `by_name` of an unknown name
/// lists the valid ones; every codec is found by its own name and FourCC.
pub fn registry_names_and_fourccs_are_unique(registry: &CodecRegistry) -> Failures {
    let codecs: Vec<&dyn AnimationCodec> = registry.iter().collect();
    let mut failures = Failures::new();
    if codecs.is_empty() {
        failures.push("registry", "the registry is empty");
    }
    for (i, a) in codecs.iter().enumerate() {
        for b in &codecs[..i] {
            if a.name() == b.name() {
                failures.push(a.name(), "name registered twice");
            }
            if a.fourcc() == b.fourcc() {
                failures.push(a.name(), format!("FourCC {} also used by {}", a.fourcc(), b.name()));
            }
        }
        let name = a.name();
        failures.count(1);
        if name.is_empty() || !name.bytes().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == b'-') {
            failures.push(name, "name is not lower-case kebab (used on the command line)");
        }
        if !a.fourcc().0.iter().all(|c| c.is_ascii_graphic()) {
            failures.push(name, format!("FourCC {} is not printable ASCII", a.fourcc()));
        }
        if a.stream_version() == 0 {
            failures.push(name, "stream_version 0 (decoders reject it)");
        }
        if a.summary().trim().is_empty() {
            failures.push(name, "empty summary");
        }
        match registry.by_name(name) {
            Ok(c) if c.fourcc() == a.fourcc() => {}
            _ => failures.push(name, "by_name does not find it"),
        }
        match registry.by_fourcc(a.fourcc()) {
            Ok(c) if c.name() == name => {}
            _ => failures.push(name, "by_fourcc does not find it"),
        }
    }
    match registry.by_name("no-such-codec") {
        Ok(_) => failures.push("registry", "by_name found a codec called no-such-codec"),
        Err(e) => {
            let msg = e.to_string();
            for c in &codecs {
                if !msg.contains(c.name()) || !msg.contains("no-such-codec") {
                    failures.push(c.name(), format!("unknown-codec error does not name it or the request: {msg}"));
                }
            }
        }
    }
    if registry.by_fourcc(codec_core::FourCc::new(b"\0\0\0\0")).is_ok() {
        failures.push("registry", "by_fourcc found a codec for FourCC 0");
    }
    failures
}

/// Decoding needs nothing but the bitstream: a stream whose FourCC no codec has is refused by
/// name, and the default limits decode a valid stream like the tight ones do.
pub fn unknown_fourcc_and_default_limits(registry: &CodecRegistry) -> Failures {
    let anim = small_animation();
    let mut failures = Failures::new();
    for codec in registry.iter() {
        failures.run(codec.name(), |f| {
            let bytes = match encode_animation(codec, &codec.default_params(), &anim) {
                Ok(b) => b,
                Err(e) => return f.push(codec.name(), format!("encode failed: {e}")),
            };
            f.count(1);
            let a = decode_animation(&bytes, registry, Limits::default());
            let b = decode_animation(&bytes, registry, tight_limits(&anim));
            match (a, b) {
                (Ok(a), Ok(b)) if a == b => {}
                (a, b) => {
                    f.push(codec.name(), format!("default vs tight limits differ: {:?} / {:?}", a.err(), b.err()))
                }
            }
            let mut other = bytes.clone();
            other[10..14].copy_from_slice(b"\x01ZZ\x02");
            let parts = split(&bytes).expect("valid stream");
            patch_header_crc(&mut other, &parts.header);
            match decode_animation(&other, registry, Limits::default()) {
                Err(codec_core::Error::UnknownCodec { .. }) => {}
                r => f.push(codec.name(), format!("unknown FourCC gave {:?}", r.map(|_| ()))),
            }
        });
    }
    failures
}

/// Which part of the stream byte `pos` belongs to (for failure messages).
fn region(parts: &Parts, total: usize, pos: usize) -> String {
    if pos < parts.header.header_bytes {
        let cfg = config_range(&parts.header);
        return if cfg.contains(&pos) {
            format!("header config byte {}", pos - cfg.start)
        } else {
            format!("header byte {pos}")
        };
    }
    for (i, e) in parts.index.iter().enumerate() {
        let start = e.offset as usize;
        let end = start + e.stored_bytes() as usize;
        if (start..end).contains(&pos) {
            let p = payload_range(e);
            let what = if pos < start + 4 {
                "tag".to_string()
            } else if pos < p.start {
                "fields".to_string()
            } else if pos < p.end {
                format!("payload byte {}", pos - p.start)
            } else {
                "crc".to_string()
            };
            return format!("packet {i} {what}");
        }
    }
    if pos >= total - 12 {
        "trailer".into()
    } else {
        "index".into()
    }
}

fn encode_or_report(f: &mut Failures, codec: &dyn AnimationCodec, anim: &Animation, what: &str) -> Option<Vec<u8>> {
    match encode_animation(codec, &codec.default_params(), anim) {
        Ok(b) => Some(b),
        Err(e) => {
            f.push(codec.name(), format!("{what}: encode failed: {e}"));
            None
        }
    }
}

/// Time budgets for the corruption checks, per codec and stream. Each case is one full
/// decode attempt; a codec whose decoder is slow in the dev profile gets an evenly spread
/// subset of the cases (never fewer than the floor), so the suite stays fast for every codec.
const TRUNCATION_BUDGET: Duration = Duration::from_secs(2);
const FLIP_BUDGET: Duration = Duration::from_secs(4);
const PAYLOAD_BUDGET: Duration = Duration::from_millis(1500);

/// Fastest of three decodes of a valid stream.
fn decode_time(bytes: &[u8], registry: &CodecRegistry, limits: Limits) -> Duration {
    (0..3)
        .map(|_| {
            let t = Instant::now();
            let _ = decode_animation(bytes, registry, limits);
            t.elapsed()
        })
        .min()
        .unwrap_or_default()
}

/// Keeps an evenly spread subset of `cases` that fits `budget` at `per_case` each (at least
/// `floor` cases), and says so on stderr when it drops any.
fn thin<T>(cases: Vec<T>, per_case: Duration, budget: Duration, floor: usize, what: &str) -> Vec<T> {
    let total = cases.len();
    let fit = (budget.as_secs_f64() / per_case.as_secs_f64().max(1e-9)) as usize;
    let keep = fit.max(floor).min(total);
    if keep == total {
        return cases;
    }
    eprintln!("note: {what}: {keep} of {total} cases kept (one decode takes {per_case:.1?})");
    let step = total as f64 / keep as f64;
    let picks: std::collections::BTreeSet<usize> = (0..keep).map(|i| (i as f64 * step) as usize).collect();
    cases.into_iter().enumerate().filter(|(i, _)| picks.contains(i)).map(|(_, c)| c).collect()
}

/// The packets the per-packet corruptions visit: first, second, middle and last (all of
/// them when there are at most four), so a codec coding one packet per frame stays fast.
fn sample_packets(n: usize) -> Vec<usize> {
    let mut v: Vec<usize> = [0, 1, n / 2, n.saturating_sub(1)].into_iter().filter(|&i| i < n).collect();
    v.sort_unstable();
    v.dedup();
    v
}

/// Cut positions: every prefix for streams up to `exhaustive` bytes, else every prefix in the
/// first and last 512 bytes and about 1500 evenly spaced ones between.
fn cuts(len: usize, exhaustive: usize) -> Vec<usize> {
    if len <= exhaustive {
        return (0..len).collect();
    }
    let mut v: Vec<usize> = (0..512.min(len)).chain(len.saturating_sub(512)..len).collect();
    let step = (len / 1500).max(1);
    v.extend((512..len.saturating_sub(512)).step_by(step));
    v.sort_unstable();
    v.dedup();
    v
}

/// Suite item 4: every truncation of a valid stream is an error from `decode_animation` and
/// `decode_frame` — never a panic, never a large allocation; so is trailing junk.
pub fn every_truncation_is_an_error(registry: &CodecRegistry) -> Failures {
    let mut failures = Failures::new();
    for codec in registry.iter() {
        failures.run(codec.name(), |f| {
            for (what, anim, exhaustive) in [("tiny", tiny_animation(), 1 << 14), ("small", small_animation(), 3000)] {
                let Some(bytes) = encode_or_report(f, codec, &anim, what) else { continue };
                let limits = tight_limits(&anim);
                let parts = split(&bytes).expect("encoder output is a valid container");
                let per = decode_time(&bytes, registry, limits);
                let label = format!("{} truncations of the {what} stream", codec.name());
                let cuts = thin(cuts(bytes.len(), exhaustive), per, TRUNCATION_BUDGET, 400, &label);
                for (i, cut) in cuts.into_iter().enumerate() {
                    let at = format!(
                        "{what} stream of {} bytes cut at {cut} ({})",
                        bytes.len(),
                        region(&parts, bytes.len(), cut)
                    );
                    f.count(1);
                    match decode_guarded(&bytes[..cut], registry, limits) {
                        Err(p) => f.push(codec.name(), format!("{at}: {p}")),
                        Ok(out) => {
                            if out.result.is_ok() {
                                f.push(codec.name(), format!("{at}: decoded without error"));
                            }
                            if out.peak_bytes > peak_budget(&limits) {
                                f.push(codec.name(), format!("{at}: peak {} bytes", out.peak_bytes));
                            }
                        }
                    }
                    if i % 3 == 0 {
                        let t = anim.frame_count() / 2;
                        match decode_frame_guarded(&bytes[..cut], registry, limits, t) {
                            Err(p) => f.push(codec.name(), format!("{at}: decode_frame {p}")),
                            Ok((Ok(_), _)) => f.push(codec.name(), format!("{at}: decode_frame({t}) succeeded")),
                            Ok((Err(_), peak)) if peak > peak_budget(&limits) => {
                                f.push(codec.name(), format!("{at}: decode_frame peak {peak} bytes"))
                            }
                            Ok(_) => {}
                        }
                    }
                }
                let mut longer = bytes.clone();
                longer.push(0);
                if codec_core::decode_animation(&longer, registry, limits).is_ok() {
                    f.push(codec.name(), format!("{what}: a byte after the trailer was accepted"));
                }
            }
        });
    }
    failures
}

/// Suite item 5, container level: random single- and multi-byte changes anywhere (header,
/// packets, index, trailer) and every byte of header, packet framing and index flipped. All
/// bytes are covered by a checksum or a checked tag, so every one must be an error;
/// `decode_frame` (which reads only the packets it needs) may succeed but must return a
/// frame of the right size.
pub fn byte_flips_are_detected(registry: &CodecRegistry) -> Failures {
    let anim = small_animation();
    let limits = tight_limits(&anim);
    let mut failures = Failures::new();
    for codec in registry.iter() {
        failures.run(codec.name(), |f| {
            let Some(bytes) = encode_or_report(f, codec, &anim, "small") else { return };
            let parts = split(&bytes).expect("valid container");
            let mut rng = Rng::for_codec(codec.name(), 5);
            // (positions, masks) of each corruption.
            let mut cases: Vec<Vec<(usize, u8)>> = Vec::new();
            let framing = |pos: usize| {
                pos < parts.header.header_bytes || parts.index.iter().all(|e| !payload_range(e).contains(&pos))
            };
            for pos in (0..bytes.len()).filter(|&p| framing(p)) {
                cases.push(vec![(pos, 0x01)]);
                cases.push(vec![(pos, 0x80)]);
            }
            for _ in 0..2500 {
                cases.push(vec![(rng.below(bytes.len()), rng.nonzero_byte())]);
            }
            for _ in 0..300 {
                let n = 2 + rng.below(3);
                cases.push((0..n).map(|_| (rng.below(bytes.len()), rng.nonzero_byte())).collect());
            }
            let v3 = anim.vertex_count() * 3;
            let per = decode_time(&bytes, registry, limits);
            let cases = thin(cases, per, FLIP_BUDGET, 600, &format!("{} byte flips", codec.name()));
            for (k, case) in cases.iter().enumerate() {
                let mut b = bytes.clone();
                for &(pos, mask) in case {
                    b[pos] ^= mask;
                }
                if b == bytes {
                    continue; // two flips of one byte cancelled out
                }
                let at = case
                    .iter()
                    .map(|&(p, m)| format!("{p} ({}) ^= {m:#04x}", region(&parts, bytes.len(), p)))
                    .collect::<Vec<_>>()
                    .join(", ");
                f.count(1);
                match decode_guarded(&b, registry, limits) {
                    Err(p) => f.push(codec.name(), format!("flip {at}: {p}")),
                    Ok(out) => {
                        if out.result.is_ok() {
                            f.push(codec.name(), format!("flip {at}: accepted (byte not covered by a checksum)"));
                        }
                        if out.peak_bytes > peak_budget(&limits) {
                            f.push(codec.name(), format!("flip {at}: peak {} bytes", out.peak_bytes));
                        }
                    }
                }
                if k % 8 == 0 {
                    let t = rng.below(anim.frame_count());
                    match decode_frame_guarded(&b, registry, limits, t) {
                        Err(p) => f.push(codec.name(), format!("flip {at}: decode_frame({t}) {p}")),
                        Ok((Ok(frame), _)) if frame.len() != v3 || frame.iter().any(|x| !x.is_finite()) => {
                            f.push(codec.name(), format!("flip {at}: decode_frame({t}) gave a bad frame"))
                        }
                        Ok((_, peak)) if peak > peak_budget(&limits) => {
                            f.push(codec.name(), format!("flip {at}: decode_frame peak {peak} bytes"))
                        }
                        Ok(_) => {}
                    }
                }
            }
        });
    }
    failures
}

/// The streams the codec-level corruption tests start from: defaults and both ladder ends.
fn base_streams(f: &mut Failures, codec: &dyn AnimationCodec, anim: &Animation) -> Vec<(String, Vec<u8>)> {
    let settings = match test_settings(codec) {
        Ok(s) => s,
        Err(e) => {
            f.push(codec.name(), e);
            return Vec::new();
        }
    };
    let mut out = Vec::new();
    for (label, params) in settings {
        match encode_animation(codec, &params, anim) {
            Ok(b) => out.push((label, b)),
            Err(e) => f.push(codec.name(), format!("{label}: encode failed: {e}")),
        }
    }
    out
}

/// The small animation's decode limits and shape, against which suite item 5 judges the decode
/// of a corrupted stream (see [`judge_corrupt_decode`]).
struct CorruptionJudge<'a> {
    registry: &'a CodecRegistry,
    limits: Limits,
    frames: usize,
    verts: usize,
}

impl CorruptionJudge<'_> {
    /// A failure message for decoding `bytes` (described by `at`), or `None` if it behaved.
    fn judge(&self, at: &str, bytes: &[u8]) -> Option<String> {
        judge_corrupt_decode(at, bytes, self.registry, self.limits, self.frames, self.verts)
    }
}

/// Runs `body` on every base stream (see [`base_streams`]) of every registered codec, with a
/// per-codec random source seeded by `seed`; failures are collected per codec.
fn for_each_base_stream(
    registry: &CodecRegistry,
    seed: u64,
    mut body: impl FnMut(&mut Failures, &dyn AnimationCodec, &mut Rng, &CorruptionJudge, &str, &[u8], &Parts),
) -> Failures {
    let anim = small_animation();
    let judge = CorruptionJudge {
        registry,
        limits: tight_limits(&anim),
        frames: anim.frame_count(),
        verts: anim.vertex_count(),
    };
    let mut failures = Failures::new();
    for codec in registry.iter() {
        failures.run(codec.name(), |f| {
            let mut rng = Rng::for_codec(codec.name(), seed);
            for (label, bytes) in base_streams(f, codec, &anim) {
                let parts = split(&bytes).expect("valid container");
                body(f, codec, &mut rng, &judge, &label, &bytes, &parts);
            }
        });
    }
    failures
}

/// Suite item 5, codec level: bytes flipped inside packet payloads with the packet CRC
/// recomputed, so the codec's parser sees them. Err or a finite animation of the right size;
/// never a panic or a large allocation.
pub fn payload_flips_with_valid_crc_never_panic(registry: &CodecRegistry) -> Failures {
    for_each_base_stream(registry, 17, |f, codec, rng, judge, label, bytes, parts| {
        // Streams with many packets: the first, second, middle and last packets.
        let payloads: Vec<(usize, IndexEntry)> =
            sample_packets(parts.index.len()).into_iter().map(|i| (i, parts.index[i])).collect();
        let mut cases: Vec<(usize, Vec<(usize, u8)>)> = Vec::new();
        for &(i, e) in &payloads {
            let len = e.payload_bytes as usize;
            // Codec payload headers (sizes, ranges, counts) sit at the start: flip
            // each of the first 48 bytes three ways.
            for off in 0..len.min(48) {
                for mask in [0x01, 0x80, 0xFF] {
                    cases.push((i, vec![(off, mask)]));
                }
            }
            if len > 0 {
                for _ in 0..120 {
                    cases.push((i, vec![(rng.below(len), rng.nonzero_byte())]));
                }
                for _ in 0..30 {
                    cases.push((i, (0..3).map(|_| (rng.below(len), rng.nonzero_byte())).collect()));
                }
            }
        }
        let per = decode_time(bytes, registry, judge.limits);
        let cases = thin(cases, per, PAYLOAD_BUDGET, 200, &format!("{} payload flips, {label}", codec.name()));
        for (i, flips) in cases {
            let e = parts.index[i];
            let mut b = bytes.to_vec();
            let start = payload_range(&e).start;
            for &(off, mask) in &flips {
                b[start + off] ^= mask;
            }
            patch_packet_crc(&mut b, &e);
            let at = format!("{label}: packet {i} payload {flips:?} (offset, xor)");
            f.count(1);
            if let Some(msg) = judge.judge(&at, &b) {
                f.push(codec.name(), msg);
            }
        }
    })
}

/// Suite item 5, codec level: the codec configuration in the header corrupted (each byte
/// flipped, truncated, extended, emptied) with the header CRC valid, and unsupported stream
/// versions. The configuration reaches `new_decoder` as untrusted bytes.
pub fn corrupt_config_and_version_never_panic(registry: &CodecRegistry) -> Failures {
    for_each_base_stream(registry, 23, |f, codec, rng, judge, label, bytes, parts| {
        let h = &parts.header;
        let cfg = config_range(h);
        for pos in cfg.clone() {
            for mask in [0x01, 0x80, 0xFF, rng.nonzero_byte()] {
                let mut b = bytes.to_vec();
                b[pos] ^= mask;
                patch_header_crc(&mut b, h);
                let at = format!("{label}: config byte {} ^= {mask:#04x}", pos - cfg.start);
                f.count(1);
                if let Some(m) = judge.judge(&at, &b) {
                    f.push(codec.name(), m);
                }
            }
        }
        let mut configs: Vec<(String, Vec<u8>)> =
            (0..h.config.len()).map(|n| (format!("config truncated to {n} bytes"), h.config[..n].to_vec())).collect();
        for extra in [vec![0u8], vec![0xFF; 8], (0..64).map(|_| rng.nonzero_byte()).collect()] {
            configs.push((format!("config + {} junk bytes", extra.len()), [h.config.clone(), extra].concat()));
        }
        configs.push(("config of 4096 0xFF bytes".into(), vec![0xFF; 4096]));
        let version = h.info.codec_version;
        for (what, config) in configs {
            f.count(1);
            match rebuild(h, &config, version, None, None, &parts.packets) {
                Err(e) => f.push(codec.name(), format!("{label}: {what}: rebuild failed: {e}")),
                Ok(b) => {
                    if let Some(m) = judge.judge(&format!("{label}: {what}"), &b) {
                        f.push(codec.name(), m);
                    }
                }
            }
        }
        for v in [0, codec.stream_version() + 1, u16::MAX] {
            f.count(1);
            let b = rebuild(h, &h.config, v, None, None, &parts.packets).expect("rebuild");
            match decode_guarded(&b, registry, judge.limits) {
                Ok(out) if out.result.is_err() => {}
                Ok(_) => f.push(codec.name(), format!("{label}: stream version {v} accepted")),
                Err(p) => f.push(codec.name(), format!("{label}: stream version {v}: {p}")),
            }
        }
        for v in 1..codec.stream_version() {
            f.count(1);
            let b = rebuild(h, &h.config, v, None, None, &parts.packets).expect("rebuild");
            if let Some(m) = judge.judge(&format!("{label}: older version {v}"), &b) {
                f.push(codec.name(), m);
            }
        }
    })
}

/// One structural mutation of a stream: a name, the rebuilt bytes, and the shape a decoder
/// must produce if it accepts them.
struct Mutation {
    what: String,
    bytes: Vec<u8>,
    frames: usize,
    vertices: usize,
}

fn mutations(parts: &Parts, other: &[(String, Parts)], rng: &mut Rng) -> Vec<Result<Mutation, String>> {
    let h = &parts.header;
    let info = &h.info;
    let (frames, verts) = (info.frame_count, info.vertex_count());
    let version = info.codec_version;
    let mut out = Vec::new();
    let mut add =
        |what: String, topology: Option<&Topology>, frame_count: Option<usize>, config: &[u8], packets: &[Packet]| {
            let f = frame_count.unwrap_or(frames);
            let v = topology.map_or(verts, |t| t.vertex_count());
            out.push(
                rebuild(h, config, version, topology, frame_count, packets)
                    .map(|bytes| Mutation { what: what.clone(), bytes, frames: f, vertices: v })
                    .map_err(|e| format!("{what}: rebuild failed: {e}")),
            );
        };
    let n = parts.packets.len();
    for i in sample_packets(n) {
        let len = parts.packets[i].data.len();
        let mut cut_lengths = vec![0, 1, len / 2, len.saturating_sub(1)];
        cut_lengths.dedup();
        for keep in cut_lengths.into_iter().filter(|&k| k < len) {
            let mut p = parts.packets.clone();
            p[i].data.truncate(keep);
            add(format!("packet {i} payload cut to {keep} of {len} bytes"), None, None, &h.config, &p);
        }
        let junk: Vec<Vec<u8>> = vec![vec![0], vec![0xFF; 8], (0..64).map(|_| rng.nonzero_byte()).collect()];
        for extra in junk {
            let mut p = parts.packets.clone();
            p[i].data.extend_from_slice(&extra);
            add(format!("packet {i} payload + {} junk bytes", extra.len()), None, None, &h.config, &p);
        }
        let mut p = parts.packets.clone();
        p[i].keyframe = !p[i].keyframe;
        add(format!("packet {i} keyframe flag toggled"), None, None, &h.config, &p);
        let mut p = parts.packets.clone();
        p[i].data = (0..len).map(|_| rng.next_u64() as u8).collect();
        add(format!("packet {i} payload replaced by {len} random bytes"), None, None, &h.config, &p);
    }
    if n >= 2 {
        let mut p = parts.packets.clone();
        let (a, b) = (p[0].data.clone(), p[n - 1].data.clone());
        p[0].data = b;
        p[n - 1].data = a;
        add("first and last payloads swapped".into(), None, None, &h.config, &p);
        let mut p = parts.packets.clone();
        for q in p.iter_mut().skip(1) {
            q.data = parts.packets[0].data.clone();
        }
        add("every payload replaced by the first".into(), None, None, &h.config, &p);
        // Move one frame from the first packet to the second: payloads now disagree with
        // the frame counts they are decoded for.
        if parts.packets[0].frame_count > 1 {
            let mut p = parts.packets.clone();
            p[0].frame_count -= 1;
            p[1].first_frame -= 1;
            p[1].frame_count += 1;
            add("one frame moved from packet 0 to packet 1".into(), None, None, &h.config, &p);
        }
        let kept = &parts.packets[..n - 1];
        let kept_frames: usize = kept.iter().map(|p| p.frame_count as usize).sum();
        add("last packet dropped (header says fewer frames)".into(), None, Some(kept_frames), &h.config, kept);
    }
    // One packet claiming every frame, holding the first packet's payload.
    if n >= 1 {
        let p = vec![Packet {
            first_frame: 0,
            frame_count: frames as u32,
            keyframe: true,
            data: parts.packets[0].data.clone(),
        }];
        add("a single packet claiming every frame".into(), None, None, &h.config, &p);
    }
    // Header topology with more and with fewer vertices than the packets were coded for.
    let tris = info.topology.triangles().to_vec();
    let more = Topology::new(verts + 3, tris.clone()).expect("valid");
    add(
        format!("header declares {} vertices instead of {verts}", verts + 3),
        Some(&more),
        None,
        &h.config,
        &parts.packets,
    );
    let half = (verts / 2).max(1);
    let fewer_tris: Vec<[u32; 3]> = tris.iter().copied().filter(|t| t.iter().all(|&i| (i as usize) < half)).collect();
    let fewer = Topology::new(half, fewer_tris).expect("valid");
    add(format!("header declares {half} vertices instead of {verts}"), Some(&fewer), None, &h.config, &parts.packets);
    // Packets and configuration from other streams of the same codec.
    for (label, o) in other {
        let same_split = o
            .packets
            .iter()
            .map(|p| (p.first_frame, p.frame_count))
            .eq(parts.packets.iter().map(|p| (p.first_frame, p.frame_count)));
        if same_split && o.header.info.topology == info.topology && o.header.config != h.config {
            add(
                format!("configuration of the {label} stream with these packets"),
                None,
                None,
                &o.header.config,
                &parts.packets,
            );
        }
        if o.header.info.topology != info.topology {
            let f: usize = o.packets.iter().map(|p| p.frame_count as usize).sum();
            add(
                format!("packets of the {label} stream ({} vertices)", o.header.info.vertex_count()),
                None,
                Some(f),
                &o.header.config,
                &o.packets,
            );
        }
    }
    out
}

/// Suite item 5, codec level: rebuilt streams (all checksums and the index consistent) with
/// payloads cut, extended, replaced, swapped, frame ranges moved, keyframe flags toggled,
/// header vertex counts changed, and packets or configuration taken from other streams.
/// `decode_animation` and `decode_frame` must give Err or the right shape; never panic.
pub fn structural_mutations_never_panic(registry: &CodecRegistry) -> Failures {
    let anim = small_animation();
    let tiny = tiny_animation();
    let mut failures = Failures::new();
    for codec in registry.iter() {
        failures.run(codec.name(), |f| {
            let mut rng = Rng::for_codec(codec.name(), 31);
            let streams: Vec<(String, Parts)> = base_streams(f, codec, &anim)
                .into_iter()
                .map(|(l, b)| (l, split(&b).expect("valid container")))
                .collect();
            let mut others = streams.clone();
            if let Some(b) = encode_or_report(f, codec, &tiny, "tiny") {
                others.push(("tiny animation".into(), split(&b).expect("valid container")));
            }
            for (label, parts) in &streams {
                let others: Vec<(String, Parts)> = others.iter().filter(|(l, _)| l != label).cloned().collect();
                for m in mutations(parts, &others, &mut rng) {
                    let m = match m {
                        Ok(m) => m,
                        Err(e) => {
                            f.push(codec.name(), format!("{label}: {e}"));
                            continue;
                        }
                    };
                    let limits = Limits {
                        max_vertices: m.vertices.max(anim.vertex_count()),
                        max_frames: m.frames.max(anim.frame_count()),
                        max_triangles: anim.triangles().len(),
                        ..tight_limits(&anim)
                    };
                    check_mutation(f, codec, registry, label, &m, limits);
                }
            }
        });
    }
    failures
}

fn check_mutation(
    f: &mut Failures,
    codec: &dyn AnimationCodec,
    registry: &CodecRegistry,
    label: &str,
    m: &Mutation,
    limits: Limits,
) {
    let at = format!("{label}: {}", m.what);
    f.count(1);
    if let Some(msg) = judge_corrupt_decode(&at, &m.bytes, registry, limits, m.frames, m.vertices) {
        f.push(codec.name(), msg);
    }
    for t in [0, m.frames / 2, m.frames - 1] {
        match decode_frame_guarded(&m.bytes, registry, limits, t) {
            Err(p) => f.push(codec.name(), format!("{at}: decode_frame({t}) {p}")),
            Ok((Ok(frame), _)) if frame.len() != m.vertices * 3 || frame.iter().any(|x| !x.is_finite()) => {
                f.push(codec.name(), format!("{at}: decode_frame({t}) gave {} values or non-finite ones", frame.len()))
            }
            Ok((_, peak)) if peak > peak_budget(&limits) => {
                f.push(codec.name(), format!("{at}: decode_frame({t}) peak {peak} bytes"))
            }
            Ok(_) => {}
        }
    }
}

fn new_encoder<'c>(
    codec: &'c dyn AnimationCodec,
    params: &ParamSet,
    topology: &Topology,
    frames: usize,
    rate: f32,
) -> codec_core::Result<StreamEncoder<'c, Vec<u8>>> {
    StreamEncoder::new(codec, params, topology, frames, rate, true, Vec::new())
}

/// Pushes `blocks` into a fresh encoder declared for `declared` frames and finishes it;
/// returns the first error.
fn push_all(
    codec: &dyn AnimationCodec,
    anim: &Animation,
    declared: usize,
    blocks: &[Vec<f32>],
) -> codec_core::Result<()> {
    let mut enc = new_encoder(codec, &codec.default_params(), anim.topology(), declared, 30.0)?;
    for b in blocks {
        enc.push_frames(b)?;
    }
    enc.finish().map(|_| ())
}

fn expect_err(f: &mut Failures, codec: &str, what: &str, r: Result<codec_core::Result<()>, String>) {
    f.count(1);
    match r {
        Err(p) => f.push(codec, format!("{what}: {p}")),
        Ok(Ok(())) => f.push(codec, format!("{what}: accepted")),
        Ok(Err(e)) if e.to_string().trim().is_empty() => f.push(codec, format!("{what}: empty error message")),
        Ok(Err(_)) => {}
    }
}

/// Suite item 8: NaN or infinite coordinates, frames of the wrong size, more or fewer frames
/// than declared, zero frames, bad frame rates, another codec's parameters and an absurd frame
/// count all give `Err` from `StreamEncoder` — never a panic or a large allocation.
pub fn encoder_rejects_bad_input(registry: &CodecRegistry) -> Failures {
    let anim = synth::waving_flag(6, 5, 10);
    let n3 = anim.vertex_count() * 3;
    let frames: Vec<Vec<f32>> = anim.frames().map(|f| f.to_vec()).collect();
    let mut failures = Failures::new();
    for codec in registry.iter() {
        let name = codec.name();
        failures.run(name, |f| {
            // Sanity: the unmodified input encodes, so the rejections below are about the input.
            if let Err(e) = push_all(codec, &anim, 10, &frames) {
                return f.push(name, format!("valid input refused: {e}"));
            }
            for (what, bad) in [("NaN", f32::NAN), ("+inf", f32::INFINITY), ("-inf", f32::NEG_INFINITY)] {
                for frame in [0usize, 7] {
                    let mut blocks = frames.clone();
                    blocks[frame][n3 / 2] = bad;
                    expect_err(
                        f,
                        name,
                        &format!("{what} in frame {frame}"),
                        catch(|| push_all(codec, &anim, 10, &blocks)),
                    );
                }
            }
            let mut short = frames.clone();
            short[3].pop();
            expect_err(f, name, "a frame one coordinate short", catch(|| push_all(codec, &anim, 10, &short)));
            let mut long = frames.clone();
            long[3].extend_from_slice(&[0.0; 3]);
            expect_err(f, name, "a frame one vertex too long", catch(|| push_all(codec, &anim, 10, &long)));
            let mut extra = frames.clone();
            extra.push(frames[0].clone());
            expect_err(f, name, "11 frames pushed, 10 declared", catch(|| push_all(codec, &anim, 10, &extra)));
            expect_err(f, name, "9 frames pushed, 10 declared", catch(|| push_all(codec, &anim, 10, &frames[..9])));
            let all: Vec<f32> = frames.concat();
            expect_err(f, name, "10 frames in one block, 4 declared", catch(|| push_all(codec, &anim, 4, &[all])));
            expect_err(f, name, "zero frames declared", catch(|| push_all(codec, &anim, 0, &[])));
            for rate in [0.0, -30.0, f32::NAN, f32::INFINITY] {
                expect_err(
                    f,
                    name,
                    &format!("frame rate {rate}"),
                    catch(|| new_encoder(codec, &codec.default_params(), anim.topology(), 10, rate).map(|_| ())),
                );
            }
            let foreign = ParamSet::defaults("some-other-codec", &codec.param_specs());
            expect_err(
                f,
                name,
                "parameters of another codec",
                catch(|| new_encoder(codec, &foreign, anim.topology(), 10, 30.0).map(|_| ())),
            );
            // More frames than the container's 32-bit field: refused up front. The peak bytes
            // held while refusing must stay small (no buffer sized from the declared count).
            let mut r = None;
            let info = allocation_counter::measure(|| {
                r = Some(catch(|| {
                    new_encoder(codec, &codec.default_params(), anim.topology(), 1 << 33, 30.0).map(|_| ())
                }));
            });
            expect_err(f, name, "2^33 frames declared", r.expect("ran"));
            if info.bytes_max > 64 << 20 {
                f.push(name, format!("declaring 2^33 frames held {} bytes at peak", info.bytes_max));
            }
        });
    }
    failures
}

/// Pushing empty blocks between frames changes nothing (a zero-frame push is legal).
pub fn empty_pushes_are_harmless(registry: &CodecRegistry) -> Failures {
    let anim = synth::waving_flag(6, 5, 10);
    let mut failures = Failures::new();
    for codec in registry.iter() {
        failures.run(codec.name(), |f| {
            let params = codec.default_params();
            let reference = match codec_core::encode_animation(codec, &params, &anim) {
                Ok(b) => b,
                Err(e) => return f.push(codec.name(), format!("encode failed: {e}")),
            };
            f.count(1);
            let r = (|| {
                let mut enc = new_encoder(codec, &params, anim.topology(), 10, anim.frame_rate())?;
                enc.push_frames(&[])?;
                for frame in anim.frames() {
                    enc.push_frames(frame)?;
                    enc.push_frames(&[])?;
                }
                enc.finish().map(|(_, bytes)| bytes)
            })();
            match r {
                Ok(b) if b == reference => {}
                Ok(_) => f.push(codec.name(), "empty pushes changed the bytes"),
                Err(e) => f.push(codec.name(), format!("empty pushes: {e}")),
            }
        });
    }
    failures
}

/// The streams the forged-header checks start from: [`base_streams`] of the small animation (defaults and
/// both ladder ends) and every synthetic animation at default parameters.
fn forge_streams(f: &mut Failures, codec: &dyn AnimationCodec) -> Vec<(String, Vec<u8>)> {
    let mut out = base_streams(f, codec, &small_animation());
    for (name, anim) in animations() {
        if let Some(b) = encode_or_report(f, codec, &anim, name) {
            out.push((format!("{name}, default"), b));
        }
    }
    out
}

/// The header's vertex count doubled (the topology
/// keeps its triangles, every checksum is valid), the rest of the stream unchanged. The packets
/// code half the vertices the decoder is told about, so every decoder must refuse: a coder
/// that runs past its payload is an error (a range decoder reading zeros past its data would
/// otherwise decode garbage with success).
pub fn forged_vertex_count_is_refused(registry: &CodecRegistry) -> Failures {
    let mut failures = Failures::new();
    for codec in registry.iter() {
        failures.run(codec.name(), |f| {
            for (label, bytes) in forge_streams(f, codec) {
                let parts = split(&bytes).expect("valid stream");
                let info = &parts.header.info;
                let doubled = Topology::new(2 * info.vertex_count(), info.topology.triangles().to_vec())
                    .expect("the same triangles fit twice the vertices");
                let forged = rebuild(
                    &parts.header,
                    &parts.header.config,
                    info.codec_version,
                    Some(&doubled),
                    None,
                    &parts.packets,
                )
                .expect("rebuild");
                f.count(1);
                match catch(|| decode_animation(&forged, registry, Limits::default())) {
                    Ok(Err(_)) => {}
                    Ok(Ok(_)) => f.push(
                        codec.name(),
                        format!("{label}: twice the vertices ({}) decoded with success", doubled.vertex_count()),
                    ),
                    Err(p) => f.push(codec.name(), format!("{label}: twice the vertices: {p}")),
                }
            }
        });
    }
    failures
}

/// `Limits::max_work` (`--max-work`) binds every codec. Per
/// stream, the smallest budget that decodes it is found by bisection (the count is a function
/// of the stream's sizes, so the same every run): one operation less is refused with
/// [`codec_core::Error::WorkLimit`] naming `--max-work`, a budget of 1 is refused the same way,
/// and the count covers at least five operations per decoded coordinate (the container's
/// charge for writing them is four: each codec counts its own reconstruction on top).
pub fn work_budget_is_honoured(registry: &CodecRegistry) -> Failures {
    let anim = small_animation();
    let coordinates = anim.positions().len() as u64;
    let mut failures = Failures::new();
    for codec in registry.iter() {
        failures.run(codec.name(), |f| {
            let Some(bytes) = encode_or_report(f, codec, &anim, "small animation") else { return };
            let decodes = |work: u64| {
                catch(|| decode_animation(&bytes, registry, Limits { max_work: work, ..Limits::default() }))
                    .unwrap_or_else(|p| Err(codec_core::Error::malformed("conformance", "decode", p)))
            };
            let refused = |work: u64| match decodes(work) {
                Err(e @ codec_core::Error::WorkLimit { .. }) if e.to_string().contains("--max-work") => None,
                Err(e) => Some(format!("budget {work}: refused with another error: {e}")),
                Ok(_) => Some(format!("budget {work}: decoded")),
            };
            f.count(1);
            if let Some(m) = refused(1) {
                return f.push(codec.name(), m);
            }
            let mut ok = codec_core::container::DEFAULT_MAX_WORK;
            if let Err(e) = decodes(ok) {
                return f.push(codec.name(), format!("refused under the default budget: {e}"));
            }
            let mut low = 1u64;
            while ok - low > 1 {
                let mid = low + (ok - low) / 2;
                match decodes(mid) {
                    Ok(_) => ok = mid,
                    Err(_) => low = mid,
                }
            }
            if let Some(m) = refused(ok - 1) {
                f.push(codec.name(), format!("one below the least budget that decodes ({ok}): {m}"));
            }
            if ok < 5 * coordinates {
                f.push(
                    codec.name(),
                    format!(
                        "its decode counts {ok} operations for {coordinates} coordinates: its own work is not counted"
                    ),
                );
            }
        });
    }
    failures
}

/// A header frame rate outside what the file readers accept (not
/// finite, not positive, 1e30, or just outside `io`'s range) is refused by the container with
/// a message naming the field, so no decode writes a file animcodec cannot read back; the ends
/// of the range decode. The range is the readers' own (`animcodec::formats::FRAME_RATE_RANGE`).
pub fn forged_frame_rates_are_refused(registry: &CodecRegistry) -> Failures {
    let anim = synth::waving_flag(6, 5, 10);
    let range = animcodec::formats::FRAME_RATE_RANGE;
    let mut failures = Failures::new();
    if codec_core::animation::FRAME_RATE_RANGE != range {
        failures.push("container", "its frame-rate range differs from the file readers'");
    }
    for codec in registry.iter() {
        failures.run(codec.name(), |f| {
            let Some(bytes) = encode_or_report(f, codec, &anim, "flag") else { return };
            let parts = split(&bytes).expect("valid stream");
            let with_rate = |rate: f32| {
                let mut b = bytes.clone();
                b[28..32].copy_from_slice(&rate.to_le_bytes());
                patch_header_crc(&mut b, &parts.header);
                b
            };
            let below = f32::from_bits(range.start().to_bits() - 1);
            let above = f32::from_bits(range.end().to_bits() + 1);
            for rate in [1e30, f32::INFINITY, f32::NAN, 0.0, -30.0, f32::MIN_POSITIVE, below, above] {
                f.count(1);
                match decode_animation(&with_rate(rate), registry, Limits::default()) {
                    Err(e) if e.to_string().contains("frame_rate") => {}
                    Err(e) => f.push(codec.name(), format!("frame rate {rate:e}: refused without naming it: {e}")),
                    Ok(_) => f.push(codec.name(), format!("frame rate {rate:e} decoded")),
                }
            }
            for rate in [*range.start(), *range.end()] {
                f.count(1);
                match decode_animation(&with_rate(rate), registry, Limits::default()) {
                    Ok(a) if a.frame_rate() == rate => {}
                    Ok(a) => f.push(codec.name(), format!("frame rate {rate:e} decoded as {}", a.frame_rate())),
                    Err(e) => f.push(codec.name(), format!("frame rate {rate:e} refused: {e}")),
                }
            }
        });
    }
    failures
}
