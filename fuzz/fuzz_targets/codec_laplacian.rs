#![no_main]
//! Fuzz target `codec_laplacian`: see `conformance_tests::fuzz` (tests/src/fuzz.rs).

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| conformance_tests::fuzz::run("codec_laplacian", data));
