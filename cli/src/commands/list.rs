//! `animcodec list`: every registered codec with its parameters and rate ladder.

use std::fmt::Write as _;

use animcodec::core::AnimationCodec;
use animcodec::describe::codec_json;
use serde_json::Value;

use super::{emit, emit_json, CmdResult};
use clap::Args;

/// Arguments of `animcodec list`.
#[derive(Debug, Args)]
pub struct ListArgs {
    /// Print JSON: an array of {name, fourcc, summary, params, rate_ladder}.
    #[arg(long, conflicts_with = "markdown")]
    pub json: bool,
    /// Print the codec table of README.md and python/README.md (Markdown), made from the registry.
    #[arg(long)]
    pub markdown: bool,
}

/// Runs `list`.
pub fn run(args: &ListArgs) -> CmdResult {
    let registry = animcodec::registry();
    if args.json {
        return emit_json(&Value::Array(registry.iter().map(codec_json).collect()));
    }
    if args.markdown {
        return emit(&animcodec::tables::codec_table_markdown(&registry));
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
    for axis in codec.search_space(&codec.default_params()).secondary {
        let values: Vec<String> = axis.values.iter().map(|v| v.to_string()).collect();
        let _ = writeln!(out, "  searched with: {} = {}", axis.param, values.join(", "));
    }
}
