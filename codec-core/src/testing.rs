//! Support for tests that depend on something outside the repository (the real animations in
//! `../shared/data`, Node.js, a browser, Blender, usd-core).
//!
//! Such a test calls [`skip`] when what it needs is absent. By default the skip is announced on
//! the process's real standard error — written past libtest's output capture, so it shows even
//! though the test then reports `ok` — and the test returns. With the environment variable
//! [`REQUIRE_ALL_VAR`] set (CI sets it), a skip is a failure instead: a test that cannot run
//! where it matters must not pass silently.

use std::io::Write;

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
