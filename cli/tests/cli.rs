//! End-to-end tests of the `animcodec` binary: output formats, round trips through files,
//! and error messages (exit code, one line, no panic).

use std::path::Path;

mod common;
use common::*;

#[test]
fn list_json_describes_quant_delta_and_its_params() {
    let v = ok_json(&["list", "--json"]);
    let codecs = v.as_array().expect("an array of codecs");
    let qd = codecs.iter().find(|c| c["name"] == "quant-delta").expect("quant-delta is listed");
    assert_eq!(qd["fourcc"].as_str().map(str::len), Some(4));
    assert!(!qd["summary"].as_str().unwrap().is_empty());
    let params = qd["params"].as_array().unwrap();
    let bits = params.iter().find(|p| p["name"] == "bits").expect("bits parameter");
    assert_eq!(bits["kind"], "int");
    assert_eq!(bits["min"], 1);
    assert_eq!(bits["max"], 24);
    assert_eq!(bits["default"], 12);
    assert!(!bits["doc"].as_str().unwrap().is_empty());
    for p in params {
        assert!(p["name"].is_string() && p["kind"].is_string() && !p["default"].is_null(), "{p}");
    }
    assert!(qd["rate_ladder"]["param"].is_string());
    assert!(!qd["rate_ladder"]["steps"].as_array().unwrap().is_empty());
    // Every registered codec appears once, with a distinct FourCC.
    let registry = animcodec::registry();
    assert_eq!(codecs.len(), registry.iter().count());
    let mut fourccs: Vec<&str> = codecs.iter().map(|c| c["fourcc"].as_str().unwrap()).collect();
    fourccs.sort();
    fourccs.dedup();
    assert_eq!(fourccs.len(), codecs.len());
}

#[test]
fn list_text_shows_every_codec_and_ladder() {
    let text = ok(&["list"]);
    for codec in animcodec::registry().iter() {
        assert!(text.contains(codec.name()), "{text}");
        assert!(text.contains(&codec.fourcc().to_string()), "{text}");
    }
    assert!(text.contains("rate ladder"), "{text}");
}

/// `list --markdown` prints the table the READMEs carry (`tests/tests/codec_tables.rs` checks them).
#[test]
fn list_markdown_is_the_registry_table() {
    let text = ok(&["list", "--markdown"]);
    assert_eq!(text, animcodec::tables::codec_table_markdown(&animcodec::registry()));
}

#[test]
fn help_documents_every_subcommand_and_flag() {
    let top = ok(&["--help"]);
    for sub in ["list", "encode", "decode", "info", "synth", "demo", "eval", "sweep", "inspect"] {
        assert!(top.contains(sub), "--help lacks {sub}: {top}");
        let help = ok(&[sub, "--help"]);
        assert!(help.contains("Usage: animcodec"), "{sub} --help: {help}");
    }
    let sweep = ok(&["sweep", "--help"]);
    for flag in ["--codecs", "--param", "--series", "--points", "--jobs", "--json", "--csv", "--plot"] {
        assert!(sweep.contains(flag), "sweep --help lacks {flag}: {sweep}");
    }
    let enc = ok(&["encode", "--help"]);
    for flag in ["--codec", "--param", "--output", "--topology", "--fps", "--json", "--max-memory"] {
        assert!(enc.contains(flag), "encode --help lacks {flag}: {enc}");
    }
    // clap usage errors keep their own exit code 2.
    assert_eq!(animcodec(&["encode"]).status.code(), Some(2));
    assert_eq!(animcodec(&["frobnicate"]).status.code(), Some(2));
}

#[test]
fn bad_codec_params_and_files_give_one_line_errors() {
    let s = Scratch::new("errors");
    let out = s.path("x.anim");
    fails(&["encode", "synth:flag", "-c", "nope", "-o", &out], &["unknown codec 'nope'", "quant-delta"]);
    fails(&["encode", "synth:flag", "-c", "quant-delta", "-p", "bitz=3", "-o", &out], &["bitz", "bits"]);
    fails(&["encode", "synth:flag", "-c", "quant-delta", "-p", "bits=99", "-o", &out], &["bits", "1..=24"]);
    fails(&["encode", "synth:flag", "-c", "quant-delta", "-p", "bits=many", "-o", &out], &["bits", "integer"]);
    fails(&["encode", "synth:flag", "-c", "quant-delta", "-p", "bits", "-o", &out], &["key=value"]);
    fails(&["encode", "synth:teapot", "-c", "quant-delta", "-o", &out], &["teapot", "flag"]);
    let missing = s.path("missing.pc2");
    fails(&["encode", &missing, "-c", "quant-delta", "-o", &out], &[&missing]);
    assert!(!Path::new(&out).exists(), "a failed encode left {out} behind");
    fails(&["info", &s.path("missing.anim")], &["missing.anim"]);
    fails(&["decode", &s.path("missing.anim"), "-o", &s.path("y.pc2")], &["missing.anim"]);
    // A file that is not a container.
    let junk = s.path("junk.anim");
    std::fs::write(&junk, b"this is not an animation container at all, just text").unwrap();
    fails(&["info", &junk], &["container"]);
    fails(&["decode", &junk, "-o", &s.path("y.pc2")], &["container"]);
    fails(&["demo", "--size", "small", "--codecs", "nope"], &["unknown codec 'nope'"]);
}

#[test]
fn encode_info_agree_and_corruption_is_caught() {
    let s = Scratch::new("encode-info");
    let out = s.path("t.anim");
    let wall = std::time::Instant::now();
    let e = ok_json(&[
        "encode",
        "synth:tumble",
        "-c",
        "quant-delta",
        "-p",
        "bits=14",
        "-p",
        "block=8",
        "-o",
        &out,
        "--json",
    ]);
    let size = std::fs::metadata(&out).unwrap().len();
    assert_eq!(e["codec"], "quant-delta");
    assert_eq!(e["params"]["bits"], 14);
    assert_eq!(e["params"]["block"], 8);
    assert_eq!(e["bytes"], size);
    let (v, f) = (e["vertices"].as_u64().unwrap(), e["frames"].as_u64().unwrap());
    assert!((e["bpvf"].as_f64().unwrap() - size as f64 * 8.0 / (v * f) as f64).abs() < 1e-9);
    assert!(e["triangles"].as_u64().unwrap() > 0);
    // A time that can be wrong: positive, and within the wall time of the whole command (a
    // unit slip such as milliseconds, or a timer started before the process, fails here).
    let wall = wall.elapsed().as_secs_f64();
    for key in ["read_seconds", "encode_seconds"] {
        let t = e[key].as_f64().unwrap();
        assert!(t > 0.0 && t < wall, "{key} = {t} s, the command took {wall} s");
    }

    let i = ok_json(&["info", &out, "--json"]);
    assert_eq!(i["codec"], "quant-delta");
    assert_eq!(i["bytes"], size);
    assert_eq!(i["frames"], f);
    assert_eq!(i["vertices"], v);
    assert_eq!(i["triangles"], e["triangles"]);
    let packets = i["packets"].as_array().unwrap();
    // block=8 over 40 frames: 5 packets tiling the frames in order.
    assert_eq!(packets.len() as u64, f.div_ceil(8));
    let mut next = 0;
    for p in packets {
        assert_eq!(p["first_frame"], next);
        next += p["frames"].as_u64().unwrap();
        assert!(p["bytes"].as_u64().unwrap() > 0);
    }
    assert_eq!(next, f);
    let geometry = i["geometry_bpvf"].as_f64().unwrap();
    assert!(geometry > 0.0 && geometry < i["bpvf"].as_f64().unwrap());
    let text = ok(&["info", &out]);
    assert!(text.contains("quant-delta") && text.contains(&size.to_string()), "{text}");

    // Flip a byte in the middle of the packets: decoding must fail cleanly.
    let mut bytes = std::fs::read(&out).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x5a;
    let bad = s.path("bad.anim");
    std::fs::write(&bad, &bytes).unwrap();
    fails(&["decode", &bad, "-o", &s.path("bad.pc2")], &[]);
    // Truncation is caught by info too.
    std::fs::write(&bad, &bytes[..bytes.len() - 5]).unwrap();
    fails(&["info", &bad], &[]);
    // A memory limit below one decoded packet is refused before decoding.
    fails(&["--max-memory", "1K", "decode", &out, "-o", &s.path("small.pc2")], &["limit"]);
}

/// synth → PC2 → encode → info → decode → PC2, checking the decoded file against the
/// original within quant-delta's bound. Needs `formats` (PC2 read/write).
#[test]
fn synth_encode_info_decode_round_trip_through_pc2() {
    let s = Scratch::new("round-trip");
    let src = s.path("flag.pc2");
    let text = ok(&["synth", "flag", "--size", "small", "-o", &src]);
    assert!(text.contains("flag"), "{text}");
    let anim = s.path("flag.anim");
    let e = ok_json(&["encode", &src, "-c", "quant-delta", "-p", "bits=16", "-o", &anim, "--json"]);
    let i = ok_json(&["info", &anim, "--json"]);
    assert_eq!(i["bytes"], e["bytes"]);
    assert_eq!(i["frames"], e["frames"]);
    let dst = s.path("decoded.pc2");
    let d = ok_json(&["decode", &anim, "-o", &dst, "--topology-obj", "--json"]);
    assert_eq!(d["frames"], e["frames"]);

    let opts = animcodec::formats::ReadOptions::default();
    let original = animcodec::formats::read_animation(Path::new(&src), &opts).unwrap();
    let decoded = animcodec::formats::read_animation(Path::new(&dst), &opts).unwrap();
    let expected = animcodec::synth::by_name("flag", animcodec::synth::SynthSize::Small).unwrap();
    assert_eq!(original.positions(), expected.positions(), "PC2 stores f32 exactly");
    assert!(codec_core::connectivity::same_triangles(decoded.topology(), original.topology()));
    // The codec's own promise at the parameters used.
    let registry = animcodec::registry();
    let codec = registry.by_name("quant-delta").unwrap();
    let params = codec.default_params().with(&codec.param_specs(), "bits", codec_core::ParamValue::Int(16)).unwrap();
    let bound = codec.error_bound(&params, &original).unwrap().max_coordinate_error.unwrap();
    let max_err =
        original.positions().iter().zip(decoded.positions()).map(|(a, b)| (a - b).abs() as f64).fold(0.0, f64::max);
    assert!(max_err <= bound, "max coordinate error {max_err} > {bound}");
    assert!(max_err > 0.0, "16-bit quantization cannot be lossless on this animation");
}

/// `decode` of an animation file that is not a stream converts it: the positions written are
/// the input's as read (a GLB to PC2 here), and the JSON says no codec was involved.
#[test]
fn decode_converts_an_input_that_is_not_a_stream() {
    let s = Scratch::new("decode-converts");
    let src = s.path("flag.pc2");
    ok(&["synth", "flag", "--size", "small", "-o", &src]);
    let glb = s.path("flag.glb");
    ok(&["export", &src, "-o", &glb, "--layout", "frames", "--compression", "none"]);
    let dst = s.path("from-glb.pc2");
    let d = ok_json(&["decode", &glb, "-o", &dst, "--topology-obj", "--json"]);
    assert_eq!(d["codec"], "none", "{d}");
    let opts = animcodec::formats::ReadOptions::default();
    let read = animcodec::formats::read_animation(Path::new(&glb), &opts).unwrap();
    let converted = animcodec::formats::read_animation(Path::new(&dst), &opts).unwrap();
    assert_eq!(d["frames"], read.frame_count());
    assert_eq!(converted.positions(), read.positions(), "PC2 stores the glTF's played f32 positions exactly");
    assert_eq!(converted.triangles(), read.triangles());
    // A file that is neither a stream nor a readable animation: the reader's error.
    let junk = s.path("junk.bin");
    std::fs::write(&junk, b"not an animation").unwrap();
    fails(&["decode", &junk, "-o", &s.path("x.pc2")], &["junk.bin", "unknown format"]);
}

#[test]
fn streamed_flag_encodes_to_the_same_bytes_as_the_whole_flag() {
    let s = Scratch::new("streamed-flag");
    let (a, b) = (s.path("whole.anim"), s.path("streamed.anim"));
    // Small flag = 20 × 12 vertices × 40 frames; different feed sizes must not matter either.
    // (Parameters given: without them the in-memory flag would be encoded at the default
    // quality, which a streamed flag cannot be searched for.)
    ok(&["encode", "synth:flag:small", "-c", "quant-delta", "-p", "bits=12", "-o", &a, "--feed", "40"]);
    ok(&["encode", "synth:flag:20x12x40", "-c", "quant-delta", "-p", "bits=12", "-o", &b, "--feed", "3"]);
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    fails(&["encode", "synth:flag:20x1x40", "-c", "quant-delta", "-o", &b], &["COLSxROWSxFRAMES"]);
    fails(&["encode", "synth:flag:20xtenx40", "-c", "quant-delta", "-o", &b], &["COLSxROWSxFRAMES"]);
}

/// Encoder notes (`FrameEncoder::notes`) reach the user: `warning:` lines in the text output,
/// a `notes` array with `--json` (empty when there is nothing to say). sac's error guard at a
/// tiny `max_error` refreshes one P-frame (its cap) and repairs the others, and says so.
#[test]
fn encode_prints_the_encoders_warnings() {
    let s = Scratch::new("encode-notes");
    let out = s.path("flag.anim");
    let e = ok_json(&["encode", "synth:flag:8x6x6", "-c", "quant-delta", "-p", "bits=12", "-o", &out, "--json"]);
    assert_eq!(e["notes"], serde_json::json!([]));
    // A streamed flag without -p gets the default-quality search like any input: the search's
    // document (its target, what it reached), not the codec's fixed defaults.
    let o = common::animcodec(&["encode", "synth:flag:8x6x6", "-c", "pca-aoi", "-o", &out, "-f", "--json"]);
    let e: serde_json::Value = serde_json::from_str(&common::stdout(&o)).unwrap();
    assert_eq!(e["default_target"], true, "{e}");
    assert!(e["reached"]["kg"].as_f64().is_some_and(|kg| kg <= 0.5), "{e}");
    assert!(!common::stderr(&o).contains("generated frame by frame"), "{}", common::stderr(&o));
    let args = ["encode", "synth:flag:8x6x6", "-c", "sac", "-p", "bases=1", "-p", "max_error=1e-4", "-o", &out, "-f"];
    let text = ok(&args);
    assert!(text.contains("warning: sac: the error guard") && text.contains("repaired 4 of 5 P-frames"), "{text}");
    let mut with_json = args.to_vec();
    with_json.push("--json");
    let e = ok_json(&with_json);
    let notes = e["notes"].as_array().unwrap();
    assert!(notes.len() == 2 && notes[1].as_str().unwrap().contains("repaired 4 of 5"), "{notes:?}");
}

#[test]
fn demo_runs_quant_delta_on_every_synthetic_animation() {
    let text = ok(&["demo", "--size", "small", "--codecs", "quant-delta"]);
    for name in animcodec::synth::NAMES {
        assert!(
            text.lines().any(|l| l.starts_with(name) && l.contains("quant-delta") && l.ends_with("ok")),
            "{name}: {text}"
        );
    }
    let v = ok_json(&["demo", "--size", "small", "--codecs", "quant-delta", "--animations", "flag,tumble", "--json"]);
    let runs = v.as_array().unwrap();
    assert_eq!(runs.len(), 2);
    for r in runs {
        assert_eq!(r["ok"], true, "{r}");
        assert!(r["bpvf"].as_f64().unwrap() > 0.0 && r["bpvf"].as_f64().unwrap() < 96.0, "{r}");
        let rel = r["max_error_relative"].as_f64().unwrap();
        assert!(rel > 0.0 && rel < 1e-2, "{r}");
        // KG and STED of the decoded animation: positive, and small at quant-delta's defaults.
        for key in ["kg", "sted"] {
            let x = r[key].as_f64().unwrap_or_else(|| panic!("{key} missing: {r}"));
            assert!(x > 0.0 && x < 1.0, "{key}: {r}");
        }
    }
    let header = text.lines().find(|l| l.starts_with("animation")).unwrap();
    assert!(header.contains("KG %") && header.contains("STED"), "{header}");
}

/// `eval` resolves inputs as `encode` does (one front door): the flag of any size is accepted
/// by both.
#[test]
fn eval_takes_every_input_encode_takes() {
    let json = ok_json(&["eval", "synth:flag:12x10x6", "synth:flag:12x10x6", "--json", "--no-sted", "--no-hausdorff"]);
    assert_eq!(json["vertices"], 120, "{json}");
    assert_eq!(json["frames"], 6, "{json}");
    assert_eq!(json["kg"], 0.0, "{json}");
    // Beyond the memory limit, refused before any frame is made.
    fails(&["eval", "synth:flag:3000x3000x300", "synth:flag:12x10x6"], &["synth:flag:3000x3000x300", "memory limit"]);
}

/// An `.anim` stream given as `eval`'s reference is decoded, and the report says so (the
/// figures are then distances from that decode, not from the animation that was encoded).
#[test]
fn eval_says_when_its_reference_is_a_decoded_stream() {
    let dir = Scratch::new("eval_stream_reference");
    let anim = dir.path("flag.anim");
    ok(&["encode", "synth:flag", "-c", "quant-delta", "-p", "bits=10", "-o", &anim]);
    let json = ok_json(&["eval", &anim, "synth:flag", "--json", "--no-sted", "--no-hausdorff"]);
    let notes = json["notes"].as_array().expect("notes").iter().map(|n| n.as_str().unwrap_or("")).collect::<Vec<_>>();
    assert!(notes.iter().any(|n| n.contains("is an .anim stream (quant-delta)") && n.contains("decoded")), "{notes:?}");
    let text = ok(&["eval", &anim, "synth:flag", "--no-sted", "--no-hausdorff"]);
    assert!(text.contains("note: the reference") && text.contains(".anim stream"), "{text}");
    // A stream as the candidate is the usual case: no note.
    let json = ok_json(&["eval", "synth:flag", &anim, "--json", "--no-sted", "--no-hausdorff"]);
    assert!(!json["notes"].to_string().contains(".anim stream"), "{json}");
}
