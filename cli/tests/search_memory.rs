//! The searches (`encode` without -p, `--target`, `-c auto`) within `--memory`: beyond the
//! whole-array search's need they stream (each candidate encoded from the input as it is read
//! and measured against a second read), choosing the same parameters and writing the same
//! bytes; a budget too small for streaming, or a codec whose encoder holds the whole input, is
//! refused naming the budget; `--json` says which path was taken.

mod common;

use common::{fails, ok, ok_json, Scratch};
use serde_json::Value;

/// A 10 000-vertex × 400-frame flag written as a PC2 (48 MB raw): its whole-array
/// quant-delta search needs about 216 MiB by the model, its streamed search 154 MiB.
fn flag_cache(s: &Scratch) -> String {
    let pc2 = s.path("flag.pc2");
    ok(&["synth", "flag:100x100x400", "-o", &pc2]);
    pc2
}

/// What the two paths must agree on: the chosen parameters and size, and every point tried
/// (parameters, size, errors reached).
fn choice(j: &Value) -> Value {
    let tried: Vec<Value> = j["tried"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| serde_json::json!([t["params"], t["bytes"], t["reached"]]))
        .collect();
    serde_json::json!({"params": j["params"], "bytes": j["bytes"], "reached": j["reached"], "tried": tried})
}

#[test]
fn a_streamed_search_chooses_what_the_whole_array_search_chooses_byte_for_byte() {
    let s = Scratch::new("search-memory-equal");
    let pc2 = flag_cache(&s);
    for extra in [&[][..], &["--target", "kg=0.2", "--refine", "1"][..]] {
        let (whole, streamed) = (s.path("whole.anim"), s.path("streamed.anim"));
        let mut args = vec!["encode", &pc2, "-c", "quant-delta", "-f", "--json"];
        args.extend_from_slice(extra);
        let w = ok_json(&[&args[..], &["-o", &whole]].concat());
        assert_eq!(w["search_input"], "whole", "{w}");
        // Less than the whole-array search needs, more than the streamed one.
        let st = ok_json(&[&args[..], &["-o", &streamed, "--memory", "180M"]].concat());
        assert_eq!(st["search_input"], "streamed", "{st}");
        assert_eq!(st["memory_budget"].as_u64(), Some(180 << 20));
        assert_eq!(st["memory_budget_default"], false);
        assert!(
            st["notes"].as_array().unwrap().iter().any(|n| n.as_str().unwrap().contains("streams instead")),
            "{st}"
        );
        assert_eq!(choice(&st), choice(&w), "{extra:?}");
        assert_eq!(std::fs::read(&whole).unwrap(), std::fs::read(&streamed).unwrap(), "{extra:?}");
    }
}

#[test]
fn a_budget_too_small_or_a_codec_that_holds_the_input_is_refused_naming_the_budget() {
    let s = Scratch::new("search-memory-refused");
    let pc2 = flag_cache(&s);
    let out = s.path("x.anim");
    // Below the streamed search's least budget: the message gives the least one.
    fails(
        &["encode", &pc2, "-c", "quant-delta", "--memory", "40M", "-o", &out],
        &["--memory 40 MiB", "too small", "give --memory"],
    );
    // sac's encoder holds the whole input: refused by name within the budget.
    fails(
        &["encode", &pc2, "-c", "sac", "--memory", "180M", "-o", &out],
        &["sac", "--memory 180 MiB", "cannot stream"],
    );
    assert!(!std::path::Path::new(&out).exists());
}
