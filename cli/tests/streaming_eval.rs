//! `--eval` and `eval` measured frame by frame: `encode IN.pc2 -p … --eval`, `encode
//! synth:flag:CxRxF -p … --eval` and `eval A.pc2 B.pc2` / `eval A.pc2 B.anim` read the input
//! again (or generate it again) frame by frame and decode the stream packet by packet
//! (`harness::measure_stream`); the report must equal the in-memory one field for field, and
//! the memory stay well under the animation's size.

mod common;

use std::path::Path;

use animcodec::core::{decode_animation, Animation, Limits};
use animcodec::metrics::{evaluate, EvalOptions};
use common::{fails, ok, ok_json, Scratch};
use serde_json::Value;

/// The in-memory report of `reference` against the decoded `stream`, as JSON text parsed back
/// (as the command's output is: the parser may round a number's last bit, the same way for both).
fn in_memory(reference: &Animation, stream: &str) -> Value {
    let decoded = decode_animation(&std::fs::read(stream).unwrap(), &animcodec::registry(), Limits::default()).unwrap();
    let report = evaluate(reference, &decoded, &EvalOptions::default()).unwrap();
    serde_json::from_str(&serde_json::to_string(&report).unwrap()).unwrap()
}

fn read(path: &str) -> Animation {
    animcodec::formats::read_animation(Path::new(path), &Default::default()).unwrap()
}

/// Every key of `expected` has the same value in `got`.
fn same_fields(got: &Value, expected: &Value, what: &str) {
    let fields = expected.as_object().unwrap();
    assert!(fields.len() > 15, "{expected}");
    let differ: Vec<String> =
        fields.iter().filter(|(k, v)| &got[k.as_str()] != *v).map(|(k, v)| format!("{k}: {} vs {v}", got[k])).collect();
    assert!(differ.is_empty(), "{what}: {differ:?}");
}

#[test]
fn streamed_eval_of_a_cache_equals_the_in_memory_report() {
    let s = Scratch::new("stream-eval-pc2");
    let (pc2, anim) = (s.path("f.pc2"), s.path("f.anim"));
    ok(&["synth", "flag:14x9x33", "-o", &pc2]);
    let v =
        ok_json(&["encode", &pc2, "-c", "quant-delta", "-p", "bits=9", "--feed", "5", "--eval", "--json", "-o", &anim]);
    let expected = in_memory(&read(&pc2), &anim);
    assert!(expected["kg"].as_f64().unwrap() > 0.0);
    same_fields(&v["metrics"], &expected, "encode --eval");
    assert_eq!(v["kg"], expected["kg"]);
    // The eval command on a cache and its stream, and on two caches.
    let e = ok_json(&["eval", &pc2, &anim, "--json"]);
    same_fields(&e, &expected, "eval PC2 .anim");
    let decoded = s.path("d.pc2");
    ok(&["decode", &anim, "-o", &decoded, "--topology-obj"]);
    let e = ok_json(&["eval", &pc2, &decoded, "--json"]);
    same_fields(&e, &expected, "eval PC2 PC2");
    // With --memory: within it, or refused before encoding when the window cannot fit.
    let v = ok_json(&[
        "encode",
        &pc2,
        "-c",
        "quant-delta",
        "-p",
        "bits=9",
        "--eval",
        "--json",
        "--memory",
        "1G",
        "-o",
        &anim,
        "-f",
    ]);
    same_fields(&v["metrics"], &expected, "encode --eval --memory 1G");
    fails(
        &["encode", &pc2, "-c", "quant-delta", "-p", "bits=9", "--eval", "--memory", "20M", "-o", &anim, "-f"],
        &["--eval", "--memory"],
    );
}

#[test]
fn streamed_eval_of_a_generated_flag_equals_the_in_memory_report() {
    let s = Scratch::new("stream-eval-flag");
    let anim = s.path("f.anim");
    let v = ok_json(&["encode", "synth:flag:11x8x20", "-c", "pca-aoi", "-p", "kg=1", "--eval", "--json", "-o", &anim]);
    let expected = in_memory(&animcodec::synth::waving_flag(11, 8, 20), &anim);
    same_fields(&v["metrics"], &expected, "encode synth:flag --eval");
}

/// Peak RSS of `eval CACHE STREAM` (both read frame by frame, the stream decoded packet by
/// packet) against the size of the animation's frames: well under it.
#[test]
fn streamed_eval_holds_far_less_than_the_animation() {
    let time = Path::new("/usr/bin/time");
    if !time.exists() {
        return codec_core::testing::skip("streamed_eval_holds_far_less_than_the_animation", "/usr/bin/time is absent");
    }
    let s = Scratch::new("stream-eval-rss");
    let (pc2, anim, log) = (s.path("f.pc2"), s.path("f.anim"), s.path("time.txt"));
    let (cols, rows, frames) = (100u64, 100u64, 1000u64);
    ok(&["synth", &format!("flag:{cols}x{rows}x{frames}"), "-o", &pc2]);
    ok(&["encode", &pc2, "-c", "quant-delta", "-p", "bits=10", "-o", &anim]);
    let o = std::process::Command::new(time)
        .args(["-f", "%M", "-o", &log, env!("CARGO_BIN_EXE_animcodec"), "eval", &pc2, &anim, "--json"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["kg"].as_f64().unwrap() > 0.0, "{v}");
    let peak_kib: u64 = std::fs::read_to_string(&log).unwrap().trim().lines().last().unwrap().parse().unwrap();
    let raw = cols * rows * frames * 12;
    eprintln!("eval: peak RSS {} MiB, frames {} MiB", peak_kib >> 10, raw >> 20);
    assert!(peak_kib * 1024 < raw / 3, "peak RSS {peak_kib} KiB against {raw} bytes of frames");
}
