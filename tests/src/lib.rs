//! Conformance suite crate: the tests live in `tests/`.
