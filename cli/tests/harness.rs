//! Tests of the evaluation harness: `animcodec eval`, `animcodec sweep` and
//! `animcodec encode --target`, through the binary and through `animcodec::harness`.
//! Everything runs on small synthetic animations so the suite stays fast.

use animcodec::harness::{
    self, csv_columns, ladder_params, measure_point, search_target, search_target_auto, EvalError, SearchRequest,
    SweepRow, Target, TargetMetric,
};
use animcodec::metrics::EvalOptions;
use animcodec::synth;
use codec_core::{
    Animation, AnimationCodec, CodecRegistry, EncodedPacket, EncoderSetup, ErrorBound, FourCc, FrameDecoder,
    FrameEncoder, Limits, Packet, ParamSet, ParamSpec, ParamValue, RateLadder, StreamInfo,
};
use codec_quant_delta::QuantDelta;
use serde_json::Value;

mod common;
use common::*;

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("{v} is not a number"))
}

/// A small animation: a few hundred vertices × 12 frames.
fn small() -> Animation {
    synth::waving_flag(12, 9, 12)
}

#[test]
fn eval_identical_files_gives_zeros_and_anim_candidates_are_decoded() {
    let s = Scratch::new("eval");
    let pc2 = s.path("flag.pc2");
    ok(&["synth", "flag", "-o", &pc2]);
    let v = ok_json(&["eval", &pc2, &pc2, "--json"]);
    for key in ["kg", "sted", "sted_spatial", "sted_temporal", "hausdorff", "mse", "rmse", "max_error"] {
        assert_eq!(f(&v[key]), 0.0, "{key} of identical files: {v}");
    }
    assert!(v["sted_params"]["ring_radius"].is_u64(), "{v}");
    let text = ok(&["eval", &pc2, &pc2]);
    assert!(text.contains("kg") && text.contains("hausdorff"), "{text}");

    // A .anim candidate is decoded; its metrics match the library on the same pair.
    let anim = s.path("flag.anim");
    ok(&["encode", &pc2, "-c", "quant-delta", "-p", "bits=6", "-o", &anim]);
    let v = ok_json(&["eval", &pc2, &anim, "--json", "--sted-radius", "2", "--sted-window", "3", "--sted-absolute"]);
    assert_eq!(v["sted_params"]["ring_radius"], 2);
    assert_eq!(v["sted_params"]["speed_window"], 3);
    assert_eq!(v["sted_params"]["spatial_difference"], "absolute");
    let registry = animcodec::registry();
    let reference = animcodec::formats::read_animation(pc2.as_ref(), &Default::default()).unwrap();
    let decoded = codec_core::decode_animation(&std::fs::read(&anim).unwrap(), &registry, Limits::default()).unwrap();
    let sted = animcodec::metrics::StedParams {
        ring_radius: 2,
        speed_window: 3,
        spatial_difference: animcodec::metrics::EdgeDifference::Absolute,
        ..Default::default()
    };
    let opts = EvalOptions { sted, ..Default::default() };
    let expected = animcodec::metrics::evaluate(&reference, &decoded, &opts).unwrap();
    assert!(expected.kg.unwrap() > 0.0);
    assert_eq!(f(&v["kg"]), expected.kg.unwrap());
    assert_eq!(f(&v["sted"]), expected.sted.unwrap());
    assert_eq!(f(&v["max_error"]), expected.max_error);

    // Mismatched animations and bad STED options are clear errors.
    let other = s.path("tumble.pc2");
    ok(&["synth", "tumble", "-o", &other]);
    fails(&["eval", &pc2, &other], &["triangles"]);
    fails(&["eval", &pc2, &pc2, "--sted-dt", "0"], &["dt"]);
    fails(&["eval", &pc2, &pc2, "--sted-window", "0"], &["speed_window"]);
}

/// `encode --eval` decodes what it wrote and reports the same metrics `eval` gives on the
/// written file; without --json the text names KG and STED.
#[test]
fn encode_eval_reports_the_metrics_of_the_written_stream() {
    let s = Scratch::new("encode-eval");
    let (pc2, anim) = (s.path("flag.pc2"), s.path("flag.anim"));
    ok(&["synth", "flag", "-o", &pc2]);
    let v = ok_json(&["encode", &pc2, "-c", "quant-delta", "-p", "bits=7", "-o", &anim, "--eval", "--json"]);
    let e = ok_json(&["eval", &pc2, &anim, "--json"]);
    for key in ["kg", "sted"] {
        assert!(f(&v[key]) > 0.0, "{key}: {v}");
        assert_eq!(f(&v[key]), f(&e[key]), "{key}");
        assert_eq!(f(&v["metrics"][key]), f(&e[key]), "{key}");
    }
    assert_eq!(f(&v["metrics"]["hausdorff"]), f(&e["hausdorff"]));
    let text = ok(&["encode", &pc2, "-c", "quant-delta", "-p", "bits=7", "-o", &anim, "-f", "--eval"]);
    assert!(text.contains("KG") && text.contains("STED"), "{text}");
    // Without --eval nothing is measured.
    let v = ok_json(&["encode", &pc2, "-c", "quant-delta", "-o", &anim, "-f", "--json"]);
    assert!(v.get("kg").is_none() && v.get("metrics").is_none(), "{v}");
    // A streamed synthetic flag is never held in memory: --eval generates it again, frame by frame.
    let v = ok_json(&["encode", "synth:flag:8x8x10", "-c", "quant-delta", "-o", &anim, "-f", "--eval", "--json"]);
    assert!(f(&v["kg"]) > 0.0, "{v}");
}

/// `animcodec eval` prints the STED of the metric author's tool within 5e-4 (relative; the
/// worst pair measured 3.06e-4, see `metrics/tests/sted_oracle.rs`) on every pair of
/// `../shared/sted-oracle` (a visible skip when it is absent, a failure under CI's
/// `ANIMCODEC_REQUIRE_ALL=1`).
#[test]
fn eval_reproduces_the_sted_oracle() {
    let root = std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared"));
    let oracle = root.join("sted-oracle/sted-oracle.json");
    if !oracle.exists() {
        return codec_core::testing::skip(
            "eval_reproduces_the_sted_oracle",
            &format!("{} not found", oracle.display()),
        );
    }
    let pairs: serde_json::Value = serde_json::from_slice(&std::fs::read(&oracle).unwrap()).unwrap();
    let pairs = pairs.as_array().expect("the oracle is a JSON array");
    // An empty or truncated oracle would pass the loop below without checking anything.
    assert!(pairs.len() >= 8, "expected the eight oracle pairs, found {}", pairs.len());
    for pair in pairs {
        let path = |key: &str| root.join(pair[key].as_str().unwrap()).to_string_lossy().into_owned();
        let (reference, candidate, topology) = (path("reference"), path("candidate"), path("topology"));
        let v = ok_json(&["eval", &reference, &candidate, "--topology", &topology, "--json", "--no-hausdorff"]);
        let (ours, tool) = (f(&v["sted"]), pair["sted"].as_f64().unwrap());
        assert!((ours / tool - 1.0).abs() <= 5e-4, "{candidate}: tool {tool}, animcodec eval {ours}");
    }
}

#[test]
fn sweep_writes_json_csv_and_svg_with_monotone_ladders() {
    let s = Scratch::new("sweep");
    let (json_path, csv_path, svg_path) = (s.path("rd.json"), s.path("rd.csv"), s.path("rd.svg"));
    let text = ok(&[
        "sweep",
        "synth:flag",
        "--ladder",
        "-c",
        "quant-delta",
        "--points",
        "4",
        "--json",
        &json_path,
        "--csv",
        &csv_path,
        "--plot",
        &svg_path,
    ]);
    assert!(text.contains("quant-delta") && text.contains("monotone"), "{text}");
    let v: Value = serde_json::from_str(&std::fs::read_to_string(&json_path).unwrap()).unwrap();
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 4, "{v}");
    let keys =
        ["codec", "params", "bytes", "bpvf", "kg", "sted", "hausdorff", "mse", "encode_seconds", "decode_seconds"];
    for r in rows {
        for k in keys {
            assert!(!r[k].is_null(), "row lacks {k}: {r}");
        }
        assert_eq!(r["codec"], "quant-delta");
    }
    // Evenly spread over the ladder, ends included, in ladder order.
    let ladder = QuantDelta.rate_ladder(&QuantDelta.default_params());
    let idx: Vec<u64> = rows.iter().map(|r| r["ladder_index"].as_u64().unwrap()).collect();
    assert_eq!(idx.first(), Some(&0));
    assert_eq!(idx.last(), Some(&(ladder.steps.len() as u64 - 1)));
    assert!(rows.windows(2).all(|w| f(&w[1]["bpvf"]) > f(&w[0]["bpvf"])), "bpvf must rise along the ladder");
    assert!(rows.windows(2).all(|w| f(&w[1]["kg"]) < f(&w[0]["kg"])), "kg must fall along the ladder");
    assert_eq!(v["monotone"][0]["bpvf_increasing"], true);

    let csv = std::fs::read_to_string(&csv_path).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], csv_columns().join(","));
    assert_eq!(lines.len(), 5);
    assert!(lines[1..].iter().all(|l| l.split(',').count() == csv_columns().len()), "{csv}");

    // The SVG is complete and carries its text as SVG text (no font files involved).
    let svg = std::fs::read_to_string(&svg_path).unwrap();
    assert!(svg.trim_start().starts_with("<svg") && svg.trim_end().ends_with("</svg>"), "{svg}");
    assert!(svg.contains("<text") && svg.contains("bpvf vs KG") && svg.contains("bpvf vs STED"));
    assert!(svg.contains("quant-delta") && svg.contains("<polyline"), "legend and curves");
    assert_eq!(svg.matches("<text").count(), svg.matches("</text>").count(), "text elements are closed");
    assert_eq!(svg.matches("<svg").count(), 1);
}

#[test]
fn sweep_series_walk_ladders_on_their_own_base_parameters() {
    let v = ok_json(&[
        "sweep",
        "synth:flag",
        "-c",
        "quant-delta",
        "-p",
        "block=8",
        "--series",
        "pca-aoi:mode=qaoi",
        "--series",
        "pca-aoi:mode=svd,block=10,coding=paper",
        "--points",
        "2",
        "--no-sted",
        "--no-hausdorff",
        "--json",
        "-",
    ]);
    let rows = v["rows"].as_array().unwrap();
    let series: Vec<&str> = rows.iter().map(|r| r["series"].as_str().unwrap()).collect();
    assert_eq!(
        series,
        [
            "quant-delta[block=8]",
            "quant-delta[block=8]",
            "pca-aoi[mode=qaoi]",
            "pca-aoi[mode=qaoi]",
            "pca-aoi[mode=svd,block=10,coding=paper]",
            "pca-aoi[mode=svd,block=10,coding=paper]"
        ]
    );
    // Each curve keeps its base and walks its own ladder: qaoi walks the error band, svd with
    // the paper's coding walks k.
    assert!(rows[..2].iter().all(|r| r["params"]["block"] == 8), "{v}");
    assert!(rows[2..4].iter().all(|r| r["params"]["mode"] == "qaoi" && r["ladder_param"] == "eps_high"), "{v}");
    assert!(rows[4..].iter().all(|r| r["params"]["block"] == 10 && r["ladder_param"] == "k"), "{v}");
    let labels: Vec<&str> = v["monotone"].as_array().unwrap().iter().map(|m| m["series"].as_str().unwrap()).collect();
    assert_eq!(labels.len(), 3, "one monotonicity verdict per curve: {labels:?}");

    fails(&["sweep", "synth:flag", "-c", "quant-delta", "-p", "bits=8"], &["quant-delta", "bits", "walks"]);
    fails(&["sweep", "synth:flag", "--series", "pca-aoi:mode=nope"], &["pca-aoi", "mode"]);
    fails(&["sweep", "synth:flag", "--series", "pca-aoi", "--series", "pca-aoi"], &["pca-aoi", "twice"]);
    fails(&["sweep", "synth:flag", "-p", "k=3", "--series", "pca-aoi"], &["-p", "--series"]);
}

#[test]
fn sweep_without_input_uses_synthetic_data_and_is_deterministic() {
    let a = ok_json(&["sweep", "--points", "2", "--json", "-", "--no-hausdorff"]);
    let b = ok_json(&["sweep", "--points", "2", "--json", "-", "--no-hausdorff", "--jobs", "1"]);
    assert_eq!(a["input"], "synth:flag");
    let (ra, rb) = (a["rows"].as_array().unwrap(), b["rows"].as_array().unwrap());
    // The default sweep is the envelope one: two ladder points of each codec's first
    // configuration, then points of its other configurations.
    assert!(ra.len() > 2 * animcodec::registry().iter().count(), "{}", ra.len());
    assert!(a["envelope"]["kg"].as_array().is_some_and(|e| !e.is_empty()), "{a}");
    assert_eq!(ra.len(), rb.len());
    for (x, y) in ra.iter().zip(rb) {
        for k in ["codec", "params", "bytes", "kg", "sted", "mse"] {
            assert_eq!(x[k], y[k], "{k} differs between parallel and sequential sweeps");
        }
        assert!(x["hausdorff"].is_null());
    }
    fails(&["sweep", "-c", "nope"], &["nope"]);
}

/// `sweep --memory`: a sweep holds the input whole and a candidate per parallel job. One that
/// would need more than the budget streams an input read frame by frame (each point encoded
/// from one read and measured against a second, one at a time): the same rows as the sweep held
/// whole. Any other input is refused before the sweep, naming the budget.
#[test]
fn sweep_beyond_its_memory_budget_streams_or_is_refused_naming_the_budget() {
    let s = Scratch::new("sweep-memory");
    let args = |input: &str, memory: &str, jobs: &str| -> Vec<String> {
        ["sweep", input, "-c", "quant-delta", "--points", "2", "--memory", memory, "--jobs", jobs, "--json", "-"]
            .map(str::to_owned)
            .to_vec()
    };
    let run = |a: Vec<String>| common::animcodec(&a.iter().map(String::as_str).collect::<Vec<_>>());
    // The built-in flag is generated whole: refused.
    let refused = |memory, jobs| {
        let o = run(args("synth:flag", memory, jobs));
        assert!(!o.status.success(), "--memory {memory} --jobs {jobs} ran");
        let e = common::stderr(&o);
        assert!(e.contains("more than --memory") && e.contains("--target") && !e.contains("panicked"), "{e}");
        // "about N MiB": what the sweep would hold.
        e.split("about ").nth(1).and_then(|t| t.split(' ').next()).and_then(|n| n.parse::<u64>().ok()).unwrap()
    };
    let (one, four) = (refused("1M", "1"), refused("1M", "4"));
    assert!(four > one, "four jobs hold more than one: {four} vs {one} MiB");
    // A 48 MB cache: held whole within 4G; streamed within 180M (its whole sweep needs ~216 MiB).
    let pc2 = s.path("flag.pc2");
    ok(&["synth", "flag:100x100x400", "-o", &pc2]);
    let whole = ok_json(&args(&pc2, "4G", "2").iter().map(String::as_str).collect::<Vec<_>>());
    let o = run(args(&pc2, "180M", "2"));
    assert!(o.status.success(), "{}", common::stderr(&o));
    assert!(common::stderr(&o).contains("one at a time"), "{}", common::stderr(&o));
    let streamed: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!((whole["search_input"].as_str(), streamed["search_input"].as_str()), (Some("whole"), Some("streamed")));
    assert_eq!(streamed["jobs"], 1, "a streamed sweep measures one point at a time");
    let view = |v: &serde_json::Value| -> Vec<serde_json::Value> {
        v["rows"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| serde_json::json!([r["series"], r["params"], r["bytes"], r["kg"], r["sted"], r["hausdorff"]]))
            .collect()
    };
    assert!(!view(&whole).is_empty());
    assert_eq!(view(&streamed), view(&whole));
    // A streamed sweep keeps no decoded animation to view.
    let html = s.path("r.html");
    let mut a = args(&pc2, "180M", "1");
    a.extend(["--html".into(), html.clone(), "--view-points".into(), "quant-delta:0".into()]);
    let o = run(a);
    assert!(!o.status.success() && common::stderr(&o).contains("--view-points"), "{}", common::stderr(&o));
    assert!(!std::path::Path::new(&html).exists());
}

#[test]
fn target_search_meets_the_target_and_the_next_smaller_point_does_not() {
    let registry = animcodec::registry();
    let codec = registry.by_name("quant-delta").unwrap();
    let animation = small();
    let ladder = codec.rate_ladder(&codec.default_params());
    let eval = EvalOptions { compute_sted: false, compute_hausdorff: false, ..Default::default() };
    let kg: Vec<f64> = (0..ladder.steps.len())
        .map(|i| {
            let p = ladder_params(codec, &codec.default_params(), &ladder, i).unwrap();
            let (pt, _) =
                measure_point(&registry, codec, &p, (ladder.param, i), &animation, &eval, Limits::default()).unwrap();
            pt.report.kg.unwrap()
        })
        .collect();
    assert!(kg.windows(2).all(|w| w[1] < w[0]), "quant-delta's KG falls along its ladder: {kg:?}");
    for want in [1, kg.len() / 2, kg.len() - 1] {
        let target = Target::new(TargetMetric::Kg, (kg[want] + kg[want - 1]) / 2.0);
        let hit =
            search_target(&request(&registry, &animation, target, &eval, 0), codec, &codec.default_params()).unwrap();
        assert_eq!(hit.point.ladder_index, want, "target {target}");
        assert!(hit.point.report.kg.unwrap() <= target.level());
        assert!(kg[want - 1] > target.level(), "the next-smaller ladder point misses");
        assert!(!hit.linear_fallback);
        // Top step + binary search + the check below the answer: fewer than the whole ladder.
        assert!(hit.tried.len() <= 2 + (ladder.steps.len() as f64).log2().ceil() as usize);
        // The stream is the chosen point's and decodes to what was measured.
        assert_eq!(hit.stream.len() as u64, hit.point.bytes);
    }
    // Exactly on a ladder point's value counts as meeting it.
    let target = Target::new(TargetMetric::Kg, kg[0]);
    let hit = search_target(&request(&registry, &animation, target, &eval, 0), codec, &codec.default_params()).unwrap();
    assert_eq!(hit.point.ladder_index, 0);
}

#[test]
fn encode_target_through_the_binary() {
    let s = Scratch::new("target");
    let out = s.path("t.anim");
    let v = ok_json(&["encode", "synth:flag", "-c", "quant-delta", "--target", "kg=0.5", "-o", &out, "--json"]);
    assert!(f(&v["reached"]["kg"]) <= 0.5, "{v}");
    assert_eq!(v["target"], serde_json::json!({"kg": 0.5}));
    assert_eq!(v["bytes"].as_u64().unwrap(), std::fs::metadata(&out).unwrap().len());
    // The file on disk really has the reported error.
    let e = ok_json(&["eval", "synth:flag", &out, "--json", "--no-hausdorff"]);
    assert_eq!(f(&e["kg"]), f(&v["reached"]["kg"]));
    // Every point tried below the chosen one missed (the binary search's neighbour check).
    let chosen = v["tried"].as_array().unwrap().iter().find(|t| t["bytes"] == v["bytes"]).unwrap().clone();
    for t in v["tried"].as_array().unwrap() {
        if t["ladder_index"].as_u64() < chosen["ladder_index"].as_u64() {
            assert!(f(&t["reached"]["kg"]) > 0.5, "{t}");
        }
    }
    let text = ok(&["encode", "synth:flag", "-c", "quant-delta", "--target", "max_error=0.01", "-f", "-o", &out]);
    assert!(text.contains("reaches max_error="), "{text}");

    // Unreachable targets say what was reached; the ladder knob cannot be fixed; -p with auto.
    let missed = s.path("missed.anim");
    fails(&["encode", "synth:flag", "-c", "quant-delta", "--target", "max_error=0", "-o", &missed], &["best reached"]);
    assert!(!std::path::Path::new(&missed).exists(), "no file is written when the target is missed");
    fails(&["encode", "synth:flag", "-c", "quant-delta", "--target", "kg=1", "-p", "bits=8", "-o", &out], &["bits"]);
    fails(&["encode", "synth:flag", "-c", "auto", "--target", "kg=1", "-p", "bits=8", "-o", &out], &["auto"]);
    let o = animcodec(&["encode", "synth:flag", "-c", "quant-delta", "--target", "psnr=1", "-o", &out]);
    assert_eq!(o.status.code(), Some(2), "a malformed --target is a usage error");
}

#[test]
fn encode_target_auto_keeps_the_smallest_stream() {
    let s = Scratch::new("auto");
    let out = s.path("auto.anim");
    let v =
        ok_json(&["encode", "synth:tumble", "-c", "auto", "--target", "max_error=0.05", "-f", "-o", &out, "--json"]);
    assert!(f(&v["reached"]["max_error"]) <= 0.05);
    for o in v["other_codecs"].as_array().unwrap() {
        assert!(o["bytes"].as_u64() >= v["bytes"].as_u64(), "{o} is smaller than the chosen {v}");
        assert!(f(&o["reached"]["max_error"]) <= 0.05);
    }
}

// ---------------------------------------------------------------------------------------------
// A test codec: quant-delta under another name, with `pad` extra bytes per packet and its own
// ladder, so `-c auto` has a choice and the non-monotone fallback can be exercised.

struct Wrapped {
    name: &'static str,
    fourcc: FourCc,
    pad: usize,
    ladder: Vec<i64>,
}

struct PadEncoder(Box<dyn FrameEncoder>, usize);

impl FrameEncoder for PadEncoder {
    fn config(&self) -> Vec<u8> {
        self.0.config()
    }
    fn push_frames(&mut self, frames: &[f32]) -> codec_core::Result<Vec<EncodedPacket>> {
        let p = self.0.push_frames(frames)?;
        Ok(self.pad(p))
    }
    fn finish(&mut self) -> codec_core::Result<Vec<EncodedPacket>> {
        let p = self.0.finish()?;
        Ok(self.pad(p))
    }
}

impl PadEncoder {
    fn pad(&self, mut packets: Vec<EncodedPacket>) -> Vec<EncodedPacket> {
        for p in &mut packets {
            p.packet.data.extend(std::iter::repeat_n(0u8, self.1));
        }
        packets
    }
}

struct PadDecoder(Box<dyn FrameDecoder>, usize);

impl FrameDecoder for PadDecoder {
    fn decode_packet(&mut self, packet: &Packet) -> codec_core::Result<Vec<f32>> {
        let n = packet
            .data
            .len()
            .checked_sub(self.1)
            .ok_or(codec_core::Error::Truncated { context: "wrapped".into(), field: "padding".into() })?;
        let inner = Packet { data: packet.data[..n].to_vec(), ..packet.clone() };
        self.0.decode_packet(&inner)
    }
}

/// The same values as a quant-delta parameter set (quant-delta checks whose set it is given).
fn inner(params: &ParamSet) -> codec_core::Result<ParamSet> {
    let specs = QuantDelta.param_specs();
    let mut p = QuantDelta.default_params();
    for (name, value) in params.iter() {
        p.set(&specs, name, value.clone())?;
    }
    Ok(p)
}

impl AnimationCodec for Wrapped {
    fn name(&self) -> &'static str {
        self.name
    }
    fn fourcc(&self) -> FourCc {
        self.fourcc
    }
    fn stream_version(&self) -> u16 {
        QuantDelta.stream_version()
    }
    fn summary(&self) -> &'static str {
        "quant-delta with padding (test only)"
    }
    fn param_specs(&self) -> Vec<ParamSpec> {
        QuantDelta.param_specs()
    }
    fn rate_ladder(&self, _base: &ParamSet) -> RateLadder {
        RateLadder { param: "bits", steps: self.ladder.iter().map(|&b| ParamValue::Int(b)).collect() }
    }
    fn validate(&self, params: &ParamSet) -> codec_core::Result<()> {
        QuantDelta.validate(&inner(params)?)
    }
    fn error_bound(&self, params: &ParamSet, animation: &Animation) -> codec_core::Result<ErrorBound> {
        QuantDelta.error_bound(&inner(params)?, animation)
    }
    fn new_encoder(&self, params: &ParamSet, setup: &EncoderSetup<'_>) -> codec_core::Result<Box<dyn FrameEncoder>> {
        Ok(Box::new(PadEncoder(QuantDelta.new_encoder(&inner(params)?, setup)?, self.pad)))
    }
    fn new_decoder(
        &self,
        info: &StreamInfo,
        config: &[u8],
        limits: &Limits,
    ) -> codec_core::Result<Box<dyn FrameDecoder>> {
        Ok(Box::new(PadDecoder(QuantDelta.new_decoder(info, config, limits)?, self.pad)))
    }
}

fn wrapped_registry() -> CodecRegistry {
    let ladder: Vec<i64> = (4..=20).step_by(2).collect();
    CodecRegistry::new(vec![
        Box::new(Wrapped { name: "padded", fourcc: FourCc::new(b"TPAD"), pad: 64, ladder: ladder.clone() }),
        Box::new(Wrapped { name: "plain", fourcc: FourCc::new(b"TPLN"), pad: 0, ladder }),
        // Not monotone: bits 12 sits between 8 and 10.
        Box::new(Wrapped { name: "shuffled", fourcc: FourCc::new(b"TSHF"), pad: 0, ladder: vec![4, 6, 8, 12, 10, 14] }),
    ])
    .unwrap()
}

#[test]
fn auto_search_keeps_the_smallest_stream_whatever_the_order() {
    let registry = wrapped_registry();
    let animation = small();
    let eval = EvalOptions::default();
    let target = Target::new(TargetMetric::MaxError, 1e-2);
    let padded = registry.by_name("padded").unwrap();
    let plain = registry.by_name("plain").unwrap();
    for order in [[padded, plain], [plain, padded]] {
        let (best, others) = search_target_auto(&request(&registry, &animation, target, &eval, 0), &order).unwrap();
        assert_eq!(best.point.codec, "plain");
        assert_eq!(others.len(), 1);
        assert!(others[0].point.bytes > best.point.bytes);
    }
    // Nothing reachable: the error lists each codec's best.
    let target = Target::new(TargetMetric::MaxError, 0.0);
    let e = search_target_auto(&request(&registry, &animation, target, &eval, 0), &[padded, plain])
        .unwrap_err()
        .to_string();
    assert!(e.contains("padded") && e.contains("plain") && e.contains("best reached"), "{e}");
}

#[test]
fn non_monotone_ladders_fall_back_to_a_linear_scan() {
    let registry = wrapped_registry();
    let codec = registry.by_name("shuffled").unwrap();
    let animation = small();
    let eval = EvalOptions::default();
    let ladder = codec.rate_ladder(&codec.default_params());
    let bytes_and_err: Vec<(u64, f64)> = (0..ladder.steps.len())
        .map(|i| {
            let p = ladder_params(codec, &codec.default_params(), &ladder, i).unwrap();
            let (pt, _) =
                measure_point(&registry, codec, &p, (ladder.param, i), &animation, &eval, Limits::default()).unwrap();
            (pt.bytes, pt.report.max_error)
        })
        .collect();
    // A target met by bits 12 (step 3) but not by bits 10 (step 4): the binary search alone
    // settles on step 5 (bits 14); the check of step 3 reveals the kink and the scan finds it.
    let target = Target::new(TargetMetric::MaxError, (bytes_and_err[3].1 + bytes_and_err[4].1) / 2.0);
    assert!(bytes_and_err[4].1 > target.level() && bytes_and_err[3].1 <= target.level());
    let hit = search_target(&request(&registry, &animation, target, &eval, 0), codec, &codec.default_params()).unwrap();
    // The smallest passing stream among all steps.
    let best = bytes_and_err.iter().filter(|(_, e)| *e <= target.level()).map(|(b, _)| *b).min().unwrap();
    assert_eq!(hit.point.bytes, best);
    assert_eq!(hit.point.ladder_index, 3);
    assert!(hit.linear_fallback);
}

#[test]
fn target_miss_names_the_best_point() {
    let registry = animcodec::registry();
    let codec = registry.by_name("quant-delta").unwrap();
    let target = Target::new(TargetMetric::Kg, 0.0);
    let e = search_target(
        &request(&registry, &small(), target, &EvalOptions::default(), 0),
        codec,
        &codec.default_params(),
    )
    .unwrap_err();
    let EvalError::TargetMiss(miss) = e else { panic!("expected a TargetMiss, got {e}") };
    assert_eq!(miss.best.as_ref().unwrap().ladder_index, codec.rate_ladder(&codec.default_params()).steps.len() - 1);
    let _ = SweepRow::from(miss.best.as_ref().unwrap()).to_json();
}

#[test]
fn refinement_between_ladder_steps_finds_a_smaller_stream_that_meets_the_target() {
    let registry = animcodec::registry();
    let codec = registry.by_name("quant-delta").unwrap();
    let animation = small();
    let eval = EvalOptions { compute_sted: false, compute_hausdorff: false, ..Default::default() };
    let base = codec.default_params();
    // quant-delta's ladder has even bit depths only; aim exactly at the KG of 7 bits.
    let with_bits = base.clone().with(&codec.param_specs(), "bits", ParamValue::Int(7)).unwrap();
    let (at7, _) =
        measure_point(&registry, codec, &with_bits, ("bits", 0), &animation, &eval, Limits::default()).unwrap();
    let target = Target::new(TargetMetric::Kg, at7.report.kg.unwrap());
    let coarse = search_target(&request(&registry, &animation, target, &eval, 0), codec, &base).unwrap();
    assert_eq!(coarse.point.params.int("bits").unwrap(), 8);
    let fine = search_target(&request(&registry, &animation, target, &eval, 3), codec, &base).unwrap();
    assert_eq!(fine.point.params.int("bits").unwrap(), 7, "the bisection between 6 (miss) and 8 finds 7");
    assert!(fine.point.bytes < coarse.point.bytes);
    assert!(fine.point.report.kg.unwrap() <= target.level());
    // Between adjacent integers there is nothing left to try: one extra point, not three.
    assert_eq!(fine.tried.len(), coarse.tried.len() + 1);
    assert_eq!(fine.stream.len() as u64, fine.point.bytes);
}

#[test]
fn progress_sees_every_point_the_target_search_measures() {
    let registry = animcodec::registry();
    let animation = small();
    let eval = EvalOptions { compute_sted: false, compute_hausdorff: false, ..Default::default() };
    let target = Target::new(TargetMetric::Kg, 1.0);
    let seen = std::sync::Mutex::new(Vec::new());
    let record = |p: &harness::Point| seen.lock().unwrap().push((p.codec, p.bytes));

    let codec = registry.by_name("quant-delta").unwrap();
    let base = codec.default_params();
    let hit = harness::search_target(
        &SearchRequest { progress: &record, ..request(&registry, &animation, target, &eval, 2) },
        codec,
        &base,
    )
    .unwrap();
    // `tried` lists ladder steps in ladder order, then refinements; progress sees them as measured.
    let mut tried: Vec<_> = hit.tried.iter().map(|p| (p.codec, p.bytes)).collect();
    let mut calls = seen.lock().unwrap().clone();
    tried.sort();
    calls.sort();
    assert_eq!(calls, tried, "one call per measured point");
    // Without progress reports the search gives the same answer.
    let plain = search_target(&request(&registry, &animation, target, &eval, 2), codec, &base).unwrap();
    assert_eq!((plain.point.bytes, plain.tried.len()), (hit.point.bytes, hit.tried.len()));

    seen.lock().unwrap().clear();
    let codecs = [registry.by_name("quant-delta").unwrap(), registry.by_name("pca-aoi").unwrap()];
    let (best, others) = harness::search_target_auto(
        &SearchRequest { progress: &record, ..request(&registry, &animation, target, &eval, 0) },
        &codecs,
    )
    .unwrap();
    let all: usize = best.tried.len() + others.iter().map(|h| h.tried.len()).sum::<usize>();
    assert_eq!(seen.lock().unwrap().len(), all);
    assert!(
        seen.lock().unwrap().iter().any(|(c, _)| *c == "quant-delta")
            && seen.lock().unwrap().iter().any(|(c, _)| *c == "pca-aoi")
    );
}

/// `export` writes glTF/GLB morph-target animations that our reader plays back at the error it
/// reports; `decode -o X.glb` writes the same default layout.
#[test]
fn export_writes_gltf_that_plays_back_at_the_reported_error() {
    let s = Scratch::new("export");
    let pc2 = s.path("flag.pc2");
    ok(&["synth", "flag", "-o", &pc2]);
    let glb = s.path("flag.glb");
    let v = ok_json(&["export", &pc2, "-o", &glb, "--json"]);
    assert_eq!(v["layout"], "basis");
    let k = v["targets"].as_u64().unwrap();
    assert!((1..40).contains(&k), "{v}");
    assert!(f(&v["kg"]) <= 0.05, "{v}");
    // `eval` reads the GLB with the same reader and gets the same KG, on a file that keeps the
    // input's vertices (the default export welds and reorders them as gltfpack does, and
    // measures its KG through the vertex map).
    let kept_glb = s.path("kept.glb");
    let kept = ok_json(&["export", &pc2, "-o", &kept_glb, "--json", "--keep-vertices"]);
    assert!(f(&kept["kg"]) <= 0.05, "{kept}");
    let e = ok_json(&["eval", &pc2, &kept_glb, "--json", "--no-hausdorff"]);
    assert_eq!(f(&e["kg"]), f(&kept["kg"]));
    // The welded, reordered default export is not compared vertex by vertex: `eval` says why.
    fails(&["eval", &pc2, &glb], &["topology differs", "--keep-vertices"]);
    let loose = ok_json(&["export", &pc2, "-o", &glb, "-f", "--json", "--target-kg", "1"]);
    assert!(loose["targets"].as_u64().unwrap() < k && f(&loose["kg"]) <= 1.0, "{loose}");
    let gltf = s.path("flag.gltf");
    let exact = ok_json(&["export", &pc2, "-o", &gltf, "--json", "--layout", "frames", "--no-compress"]);
    assert_eq!(exact["targets"].as_u64(), Some(39));
    assert!(f(&exact["kg"]) < 1e-4, "{exact}");
    // Compressed (the default): 16-bit positions cost a little error and save bytes.
    let packed = ok_json(&["export", &pc2, "-o", &s.path("packed.glb"), "--json", "--layout", "frames"]);
    assert!(f(&packed["kg"]) < 0.01 && f(&packed["kg"]) > f(&exact["kg"]), "{packed}");
    assert!(packed["bytes"].as_u64() < exact["bytes"].as_u64(), "{packed} {exact}");
    let text = std::fs::read_to_string(&gltf).unwrap();
    assert!(text.contains("\"STEP\"") && text.contains("data:application/octet-stream;base64,"));
    // decode writes glTF too.
    let anim = s.path("flag.anim");
    ok(&["encode", &pc2, "-c", "hosvd", "-o", &anim]);
    let out = s.path("decoded.glb");
    ok(&["decode", &anim, "-o", &out]);
    let e = ok_json(&["eval", &anim, &out, "--json", "--no-hausdorff"]);
    assert!(f(&e["kg"]) <= 0.05, "{e}");
    fails(&["export", &pc2, "-o", &glb, "-f", "--layout", "rows"], &["rows", "basis or frames"]);
    fails(&["export", &pc2, "-o", &glb], &["already exists", "--force"]);
    fails(&["export", &glb, "-o", &glb, "-f"], &["also an input"]);
    fails(&["export", &pc2, "-o", &s.path("flag.fbx")], &[".glb or .gltf"]);
    fails(&["export", &pc2, "-o", &glb, "-f", "--target-kg", "0"], &["target_kg"]);
    // The general spelling, --target kg=T, is the same request; other metrics are refused.
    let same = ok_json(&["export", &pc2, "-o", &glb, "-f", "--json", "--target", "kg=1"]);
    assert_eq!((same["targets"].clone(), same["bytes"].clone()), (loose["targets"].clone(), loose["bytes"].clone()));
    fails(&["export", &pc2, "-o", &glb, "-f", "--target", "sted=0.1"], &["kg=T"]);
}
