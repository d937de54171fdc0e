//! Support for tests: tests that depend on something outside the repository (the real
//! animations in `../shared/data`, Node.js, a browser, Blender, usd-core), and the check every
//! codec's parameter declaration passes ([`check_declared_params`]), and a deterministic vertex
//! renumbering ([`shuffled_permutation`]) for tests of numbering-dependent coding.
//!
//! A test that depends on something outside calls [`skip`] when what it needs is absent. By default the skip is announced on
//! the process's real standard error — written past libtest's output capture, so it shows even
//! though the test then reports `ok` — and the test returns. With the environment variable
//! [`REQUIRE_ALL_VAR`] set (CI sets it), a skip is a failure instead: a test that cannot run
//! where it matters must not pass silently.

use std::io::Write;

use crate::params::{DeclaredParams, ParamKind, ParamSet, ParamSpec, ParamValue};

/// Environment variable that turns every [`skip`] into a test failure (`.ci/run` sets it).
pub const REQUIRE_ALL_VAR: &str = "ANIMCODEC_REQUIRE_ALL";

/// Whether skips are failures in this run ([`REQUIRE_ALL_VAR`] is set to anything but `0`).
pub fn skips_fail() -> bool {
    std::env::var_os(REQUIRE_ALL_VAR).is_some_and(|v| v != "0")
}

/// Announces that test `test` cannot run because of `reason`, or panics (failing the test)
/// when [`skips_fail`]. The caller returns right after.
///
/// # Panics
/// When [`REQUIRE_ALL_VAR`] is set: that is its purpose.
pub fn skip(test: &str, reason: &str) {
    if skips_fail() {
        panic!("{test}: would skip ({reason}), and {REQUIRE_ALL_VAR} is set: every test must run");
    }
    // io::stderr() directly, not eprintln!: libtest captures the print macros only, and a skip
    // must be visible in a plain `cargo test` run.
    let _ = writeln!(std::io::stderr(), "SKIPPED {test}: {reason} (set {REQUIRE_ALL_VAR}=1 to make this a failure)");
}

/// Values of `spec` that it must accept: the default, both ends of a range and its middle,
/// every choice, both booleans.
pub fn legal_values(spec: &ParamSpec) -> Vec<ParamValue> {
    let mut out = vec![spec.default.clone()];
    match &spec.kind {
        ParamKind::Int { min, max } => out.extend([*min, *max, min / 2 + max / 2].map(ParamValue::Int)),
        ParamKind::Float { min, max } => out.extend([*min, *max, min / 2.0 + max / 2.0].map(ParamValue::Float)),
        ParamKind::Bool => out.extend([false, true].map(ParamValue::Bool)),
        ParamKind::Choice(options) => out.extend(options.iter().map(|o| ParamValue::Choice(o))),
    }
    out
}

/// Values of `spec`'s kind that it must refuse: just outside each end of a range (the
/// neighbouring integer, the neighbouring `f64`), non-finite numbers, a name that is not a
/// choice. Booleans have none.
pub fn illegal_values(spec: &ParamSpec) -> Vec<ParamValue> {
    match &spec.kind {
        ParamKind::Int { min, max } => {
            min.checked_sub(1).into_iter().chain(max.checked_add(1)).map(ParamValue::Int).collect()
        }
        ParamKind::Float { min, max } => {
            [next_f64(*min, false), next_f64(*max, true), f64::NAN, f64::INFINITY].map(ParamValue::Float).to_vec()
        }
        ParamKind::Bool => Vec::new(),
        ParamKind::Choice(_) => vec![ParamValue::Choice("no-such-choice")],
    }
}

/// The `f64` next to `x` upwards (`up`) or downwards.
fn next_f64(x: f64, up: bool) -> f64 {
    if x == 0.0 {
        return if up { f64::from_bits(1) } else { -f64::from_bits(1) };
    }
    let bits = x.to_bits();
    f64::from_bits(if (x > 0.0) == up { bits + 1 } else { bits - 1 })
}

/// A value of another kind than `spec`'s (which the spec must refuse).
fn other_kind(spec: &ParamSpec) -> ParamValue {
    match spec.kind {
        ParamKind::Bool => ParamValue::Int(1),
        _ => ParamValue::Bool(true),
    }
}

/// Proves that a [`declare_params!`](crate::declare_params) struct's specs, parsing and
/// printing agree, for every parameter: the defaults of the specs are the struct's `Default`;
/// for every legal value of every spec ([`legal_values`]) the printed value parses back to
/// itself and `ParamSet → typed → ParamSet` gives the same set (so each value lands in the
/// field that writes it back, at any point of the range); every illegal value
/// ([`illegal_values`], another kind, an unknown name) is refused, both as a value and as text,
/// by an error naming the codec and the parameter.
///
/// # Panics
/// On the first disagreement, with what disagreed: this is a test.
pub fn check_declared_params<P: DeclaredParams>() {
    let codec = P::CODEC;
    let specs = P::param_specs();
    assert!(!specs.is_empty(), "{codec}: no parameters");
    for (i, s) in specs.iter().enumerate() {
        assert!(specs[..i].iter().all(|t| t.name != s.name), "{codec}: parameter {} declared twice", s.name);
        assert!(!s.doc.is_empty(), "{codec}.{}: no help text", s.name);
        s.check(codec, &s.default).unwrap_or_else(|e| panic!("{codec}.{}: default refused: {e}", s.name));
    }
    let defaults = ParamSet::defaults(codec, &specs);
    let written = P::default().write_fields().unwrap_or_else(|e| panic!("{codec}: Default does not write: {e}"));
    assert_eq!(written, defaults, "{codec}: Default and the specs' defaults disagree");
    let read = P::read_fields(&defaults).unwrap_or_else(|e| panic!("{codec}: defaults do not read: {e}"));
    assert_eq!(read, P::default(), "{codec}: the specs' defaults read back to another struct");

    for spec in &specs {
        let name = spec.name;
        for value in legal_values(spec) {
            let text = value.to_string();
            let parsed = spec.parse(codec, &text).unwrap_or_else(|e| panic!("{codec}.{name}: '{text}' refused: {e}"));
            assert_eq!(parsed, value, "{codec}.{name}: '{text}' parses to another value");
            let set = defaults
                .clone()
                .with(&specs, name, value.clone())
                .unwrap_or_else(|e| panic!("{codec}.{name}={text}: {e}"));
            let typed = P::read_fields(&set).unwrap_or_else(|e| panic!("{codec}.{name}={text}: does not read: {e}"));
            let back = typed.write_fields().unwrap_or_else(|e| panic!("{codec}.{name}={text}: does not write: {e}"));
            assert_eq!(back, set, "{codec}.{name}={text}: ParamSet -> typed -> ParamSet changed the values");
            assert_eq!(back.get(name), Some(&value), "{codec}.{name}={text}: written back as another value");
        }
        let mut bad_values = illegal_values(spec);
        let mut bad_texts: Vec<String> = bad_values.iter().map(ToString::to_string).collect();
        bad_values.push(other_kind(spec));
        bad_texts.push(if spec.kind == ParamKind::Bool { "maybe" } else { "twelve" }.to_string());
        for value in bad_values {
            let e = defaults
                .clone()
                .with(&specs, name, value.clone())
                .expect_err(&format!("{codec}.{name}: illegal value {value:?} accepted"))
                .to_string();
            assert!(e.contains(codec) && e.contains(name), "{codec}.{name}: error does not name both: {e}");
        }
        for text in bad_texts {
            let e = spec.parse(codec, &text).expect_err(&format!("{codec}.{name}: illegal text '{text}' accepted"));
            let e = e.to_string();
            assert!(e.contains(codec) && e.contains(name), "{codec}.{name}: error does not name both: {e}");
        }
    }
    let foreign = ParamSet::defaults("no-such-codec", &specs);
    assert!(P::read_fields(&foreign).is_err(), "{codec}: read a parameter set of another codec");
}

/// A permutation of `0..n` in which each run of `window` consecutive indices is shuffled among
/// itself by a xorshift generator started at `seed` (`window` ≥ `n`: the whole range): a local,
/// irregular numbering like a real mesh's. The same arguments give the same permutation on
/// every platform; golden streams depend on it, so its arithmetic must not change.
///
/// # Panics
/// If `window` is 0 (when `n` > 0).
pub fn shuffled_permutation(n: usize, window: usize, seed: u64) -> Vec<usize> {
    let mut perm: Vec<usize> = (0..n).collect();
    let mut s = seed;
    for chunk in perm.chunks_mut(window) {
        for i in (1..chunk.len()).rev() {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            chunk.swap(i, (s % (i as u64 + 1)) as usize);
        }
    }
    perm
}
