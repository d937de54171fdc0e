//! The streaming metrics (`metrics::StreamingEvaluator`) against the whole-array `evaluate` on
//! every dev animation in `../shared/data` (a visible skip when absent) and on synthetic inputs,
//! the candidate a real codec's decode (quant-delta at 8 bits, so every error is non-zero),
//! pushing frames in chunks of 1, 7 and all.
//!
//! Every report field is compared bit for bit, except the worst part's `kg`, `spread` and
//! `rmse` when parts that coincide in frame 0 part later (then recombined from per-component
//! sums): those within 1e-12 relative. The test says which comparison each input took.

use std::path::PathBuf;

use animcodec::formats::{read_animation, ReadOptions};
use animcodec::metrics::{evaluate, EvalOptions, MetricReport, StreamingEvaluator};
use animcodec::synth;
use codec_core::testing::skip;
use codec_core::{decode_animation, encode_animation_fed, Animation, Limits, ParamValue};
use conformance_tests::*;

fn data_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data")
}

/// quant-delta at 8 bits: a decoded candidate with errors everywhere.
fn decoded(anim: &Animation) -> Animation {
    let registry = registry();
    let codec = registry.by_name("quant-delta").expect("quant-delta is registered");
    let params = params_with(codec, "bits", ParamValue::Int(8)).expect("bits=8 is valid");
    let enc = encode_animation_fed(codec, &params, anim, false, 16).expect("encode");
    decode_animation(&enc.bytes, &registry, Limits::default()).expect("decode")
}

fn streamed(r: &Animation, c: &Animation, options: &EvalOptions, chunk: usize) -> MetricReport {
    let mut s = StreamingEvaluator::new(r.topology(), r.frame_count(), r.frame_rate(), options).expect("new");
    let per = 3 * r.vertex_count() * chunk;
    for (a, b) in r.positions().chunks(per).zip(c.positions().chunks(per)) {
        s.push(a, b).expect("push");
    }
    s.finish().expect("finish")
}

/// Checks every chunking; returns "bit-identical" or "parts within 1e-12".
fn check(name: &str, r: &Animation, c: &Animation) -> &'static str {
    let options = EvalOptions::default();
    let whole = evaluate(r, c, &options).expect("evaluate");
    assert!(whole.kg.unwrap() > 0.0 && whole.max_error > 0.0, "{name}: the candidate has errors");
    let mut how = "bit-identical";
    for chunk in [1, 7, r.frame_count()] {
        let s = streamed(r, c, &options, chunk);
        if s == whole {
            continue;
        }
        let (w, x) = (whole.worst_part.as_ref().unwrap(), s.worst_part.as_ref().unwrap());
        assert_eq!(
            (w.part, w.first_vertex, w.vertices, w.floored, w.max_error),
            (x.part, x.first_vertex, x.vertices, x.floored, x.max_error),
            "{name}, chunks of {chunk}"
        );
        for (field, a, b) in
            [("kg", w.kg.unwrap(), x.kg.unwrap()), ("spread", w.spread, x.spread), ("rmse", w.rmse, x.rmse)]
        {
            assert!((a - b).abs() <= 1e-12 * a.abs(), "{name}, chunks of {chunk}: worst part {field} {a} vs {b}");
        }
        let strip = |m: &MetricReport| MetricReport { worst_part: None, ..m.clone() };
        assert_eq!(strip(&s), strip(&whole), "{name}, chunks of {chunk}");
        how = "parts within 1e-12";
    }
    eprintln!("{name}: {} × {} frames, KG {:.4}: {how}", r.vertex_count(), r.frame_count(), whole.kg.unwrap());
    how
}

#[test]
fn streaming_equals_whole_array_on_every_dev_animation() {
    let dir = data_dir();
    let inputs = [
        "horse-gallop/horse-gallop.pc2",
        "samba/samba.pc2",
        "chicken-crossing/chicken-crossing.pc2",
        "pcow/pcow.pc2",
        "horse-glb/Horse.glb",
        "robot-expressive/RobotExpressive.glb",
    ];
    for input in inputs {
        let path = dir.join(input);
        if !path.exists() {
            skip("streaming_equals_whole_array_on_every_dev_animation", &format!("{} is absent", path.display()));
            continue;
        }
        let anim = read_animation(&path, &ReadOptions::default()).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        check(input, &anim, &decoded(&anim));
    }
}

#[test]
fn streaming_equals_whole_array_on_synthetic_inputs() {
    for name in synth::NAMES {
        let anim = synth::by_name(name, synth::SynthSize::Small).unwrap();
        check(name, &anim, &decoded(&anim));
    }
    // Disconnected parts and duplicated seam vertices.
    let spec = synth::CharacterSpec { frames: 12, ..synth::CharacterSpec::spheres_like(5) };
    let anim = synth::skinned_character(&spec);
    check("skinned character", &anim, &decoded(&anim));
}
