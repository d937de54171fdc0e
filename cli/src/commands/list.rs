//! `animcodec list`: every registered codec with its parameters and rate ladder.

use std::fmt::Write as _;

use codec_core::{AnimationCodec, ParamKind, ParamSpec};
use serde_json::{json, Map, Value};

use super::{emit, emit_json, param_json, CmdResult};
use crate::ListArgs;

/// Runs `list`.
pub fn run(args: &ListArgs) -> CmdResult {
    let registry = animcodec::registry();
    if args.json {
        return emit_json(&Value::Array(registry.iter().map(codec_json).collect()));
    }
    let mut out = String::new();
    for (i, codec) in registry.iter().enumerate() {
        if i > 0 {
            out.push('\n');
        }
        write_codec(&mut out, codec);
    }
    emit(&out)
}

/// One codec as JSON: `{name, fourcc, stream_version, summary, params, rate_ladder}`.
pub fn codec_json(codec: &dyn AnimationCodec) -> Value {
    let ladder = codec.rate_ladder(&codec.default_params());
    json!({
        "name": codec.name(),
        "fourcc": codec.fourcc().to_string(),
        "stream_version": codec.stream_version(),
        "summary": codec.summary(),
        "params": codec.param_specs().iter().map(spec_json).collect::<Vec<_>>(),
        "rate_ladder": {
            "param": ladder.param,
            "steps": ladder.steps.iter().map(param_json).collect::<Vec<_>>(),
        },
    })
}

/// One parameter as JSON: `{name, kind, default, min?, max?, choices?, doc}`.
fn spec_json(spec: &ParamSpec) -> Value {
    let mut m = Map::new();
    m.insert("name".into(), spec.name.into());
    let kind = match &spec.kind {
        ParamKind::Int { min, max } => {
            m.insert("min".into(), (*min).into());
            m.insert("max".into(), (*max).into());
            "int"
        }
        ParamKind::Float { min, max } => {
            m.insert("min".into(), (*min).into());
            m.insert("max".into(), (*max).into());
            "float"
        }
        ParamKind::Bool => "bool",
        ParamKind::Choice(options) => {
            m.insert("choices".into(), options.iter().map(|o| Value::from(*o)).collect());
            "choice"
        }
    };
    m.insert("kind".into(), kind.into());
    m.insert("default".into(), param_json(&spec.default));
    m.insert("doc".into(), spec.doc.into());
    Value::Object(m)
}

fn write_codec(out: &mut String, codec: &dyn AnimationCodec) {
    let _ = writeln!(out, "{} ({}, stream version {})", codec.name(), codec.fourcc(), codec.stream_version());
    let _ = writeln!(out, "  {}", codec.summary());
    let specs = codec.param_specs();
    let name_w = specs.iter().map(|s| s.name.len()).max().unwrap_or(0).max(4);
    let kind_w = specs.iter().map(|s| s.kind.to_string().len()).max().unwrap_or(0).max(4);
    let def_w = specs.iter().map(|s| s.default.to_string().len()).max().unwrap_or(0).max(7);
    if specs.is_empty() {
        let _ = writeln!(out, "  (no parameters)");
    } else {
        let _ = writeln!(out, "  {:name_w$}  {:kind_w$}  {:def_w$}  doc", "name", "kind", "default");
        for s in &specs {
            let _ = writeln!(
                out,
                "  {:name_w$}  {:kind_w$}  {:def_w$}  {}",
                s.name,
                s.kind.to_string(),
                s.default.to_string(),
                s.doc
            );
        }
    }
    let ladder = codec.rate_ladder(&codec.default_params());
    let steps: Vec<String> = ladder.steps.iter().map(|v| v.to_string()).collect();
    let _ = writeln!(out, "  rate ladder: {} = {}", ladder.param, steps.join(", "));
}
