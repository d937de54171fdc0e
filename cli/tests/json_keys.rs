//! Every `--json` document of every command uses only the keys documented in `docs/json.md`:
//! one spelling per quantity (`frames`, never `frame_count`; `frame_rate`, never `fps`). A key
//! added to a command without a line in the document fails here, which keeps the document and
//! the commands in step.

use std::collections::BTreeSet;

use serde_json::Value;

mod common;
use common::*;

/// The documented keys: the backticked first cell of every table row in `docs/json.md`
/// (rows of the form ``| `key` | meaning | documents |``).
fn documented_keys() -> BTreeSet<String> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/json.md");
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let keys: BTreeSet<String> = text
        .lines()
        .filter_map(|line| line.strip_prefix("| `"))
        .filter_map(|rest| rest.split_once('`'))
        .map(|(key, _)| key.to_owned())
        .collect();
    assert!(keys.len() > 50, "docs/json.md lists only {} keys: is the table still there?", keys.len());
    keys
}

/// Every codec parameter name: the keys of a `params` object are parameter names, documented
/// by `animcodec list`, not by the vocabulary.
fn parameter_names() -> BTreeSet<String> {
    animcodec::registry().iter().flat_map(|c| c.param_specs()).map(|s| s.name.to_owned()).collect()
}

/// Collects `path: key` for every key of `value` (at any depth) that is not documented.
fn undocumented(value: &Value, path: &str, keys: &BTreeSet<String>, params: &BTreeSet<String>, out: &mut Vec<String>) {
    match value {
        Value::Object(map) => {
            for (key, inner) in map {
                let here = format!("{path}.{key}");
                if !keys.contains(key) {
                    out.push(here.clone());
                }
                match (key.as_str(), inner) {
                    ("params", Value::Object(named)) => {
                        out.extend(named.keys().filter(|k| !params.contains(*k)).map(|k| format!("{here}.{k}")));
                    }
                    _ => undocumented(inner, &here, keys, params, out),
                }
            }
        }
        Value::Array(items) => {
            items.iter().for_each(|item| undocumented(item, &format!("{path}[]"), keys, params, out))
        }
        _ => {}
    }
}

#[test]
fn every_json_key_of_every_command_is_documented() {
    let s = Scratch::new("json-keys");
    let (pc2, anim, out, glb) = (s.path("flag.pc2"), s.path("flag.anim"), s.path("out.pc2"), s.path("flag.glb"));
    ok(&["synth", "flag", "-o", &pc2]);
    let sweep = s.path("sweep.json");
    let documents: Vec<(&str, Value)> = vec![
        ("list", ok_json(&["list", "--json"])),
        ("encode", ok_json(&["encode", &pc2, "-c", "quant-delta", "-p", "bits=8", "-o", &anim, "--eval", "--json"])),
        (
            "encode --target",
            ok_json(&["encode", &pc2, "-c", "quant-delta", "--target", "kg=1", "-o", &anim, "-f", "--json"]),
        ),
        ("info", ok_json(&["info", &anim, "--json"])),
        ("decode", ok_json(&["decode", &anim, "-o", &out, "--json"])),
        ("eval", ok_json(&["eval", &pc2, &anim, "--json"])),
        ("export", ok_json(&["export", &pc2, "-o", &glb, "--json"])),
        ("info (glTF)", ok_json(&["info", &glb, "--json"])),
        ("list-animations", ok_json(&["list-animations", &glb, "--json"])),
        (
            "sweep",
            ok_json(&["sweep", "synth:flag", "-c", "quant-delta,pca-aoi", "--ladder", "--points", "2", "--json", "-"]),
        ),
        ("inspect", ok_json(&["inspect", "synth:flag", "--json", "-"])),
        ("demo", ok_json(&["demo", "--size", "small", "--codecs", "quant-delta", "--animations", "flag", "--json"])),
    ];
    // The sweep file is the document printed with `--json -` (same writer); checked once more
    // in its envelope form, the default.
    ok(&["sweep", "synth:flag", "-c", "quant-delta", "--points", "2", "--json", &sweep]);
    let file: Value = serde_json::from_str(&std::fs::read_to_string(&sweep).unwrap()).unwrap();

    let (keys, params) = (documented_keys(), parameter_names());
    let mut missing = Vec::new();
    for (command, value) in documents.iter().chain([("sweep --json FILE", file)].iter()) {
        undocumented(value, command, &keys, &params, &mut missing);
    }
    missing.sort();
    missing.dedup();
    assert!(
        missing.is_empty(),
        "keys missing from docs/json.md (add them, or use the documented spelling):\n{}",
        missing.join("\n")
    );
}

/// The renamed spellings stay gone (`docs/json.md`, "Renamed keys").
#[test]
fn retired_spellings_are_not_documented() {
    let keys = documented_keys();
    for retired in ["fps", "frame_count", "vertex_count", "codec_version", "failure", "triangle_count"] {
        assert!(!keys.contains(retired), "docs/json.md lists the retired key '{retired}'");
    }
}
