//! Suite item 8: bad input to every registered encoder gives `Err`, never a panic.
//!
//! Kept in its own test binary: an encoder that sizes a buffer from an absurd declared frame
//! count can abort the process on allocation failure, and that should not take the other
//! suites' reports with it.

use conformance_tests::{codecs_under_test, suite};

#[test]
fn encoder_rejects_bad_input() {
    suite::encoder_rejects_bad_input(&codecs_under_test()).assert_none("encoder_rejects_bad_input");
}

/// Pushing empty blocks between frames changes nothing (a zero-frame push is legal).
#[test]
fn empty_pushes_are_harmless() {
    suite::empty_pushes_are_harmless(&codecs_under_test()).assert_none("empty_pushes_are_harmless");
}
