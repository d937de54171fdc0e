//! Runs every committed fuzz corpus file (`fuzz/corpus/<target>/*`) through the same function
//! its cargo-fuzz target calls (`conformance_tests::fuzz`), so CI checks every input the fuzzers
//! found interesting, and every past finding, without running a fuzzer.
//!
//! `ANIMCODEC_WRITE_FUZZ_SEEDS=1 cargo test -p conformance-tests --test fuzz_corpus` writes the
//! seed inputs made from the synthetic animations (`seed-*` files) into the corpora.

use std::path::{Path, PathBuf};

use conformance_tests::fuzz;

fn corpus_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join("fuzz").join("corpus")
}

#[test]
fn every_corpus_file_passes_its_target() {
    let root = corpus_dir();
    if std::env::var_os("ANIMCODEC_WRITE_FUZZ_SEEDS").is_some() {
        for (target, name, bytes) in fuzz::seeds() {
            let dir = root.join(&target);
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(dir.join(format!("seed-{name}")), bytes).unwrap();
        }
    }
    let mut total = 0;
    for target in fuzz::targets() {
        let dir = root.join(&target);
        let mut files: Vec<PathBuf> = match std::fs::read_dir(&dir) {
            Ok(entries) => entries.map(|e| e.unwrap().path()).filter(|p| p.is_file()).collect(),
            Err(e) => panic!("{}: {e}: every fuzz target has a committed corpus", dir.display()),
        };
        files.sort();
        assert!(!files.is_empty(), "{}: empty corpus", dir.display());
        for file in &files {
            let data = std::fs::read(file).unwrap();
            let outcome = std::panic::catch_unwind(|| fuzz::run(&target, &data));
            assert!(outcome.is_ok(), "{target}: {} fails its target (see the panic above)", file.display());
        }
        eprintln!("{target}: {} corpus files", files.len());
        total += files.len();
    }
    eprintln!("{total} corpus files replayed");
}

/// The record format round-trips, so seeds reach the codec exactly as encoded.
#[test]
fn records_round_trip() {
    let registry = animcodec::registry();
    let codec = registry.by_name("quant-delta").unwrap();
    let bytes = codec_core::encode_animation(codec, &codec.default_params(), &fuzz::fuzz_animation(12)).unwrap();
    let parts = conformance_tests::split(&bytes).unwrap();
    let (config, packets) = fuzz::parse_records(&fuzz::to_records(&parts.header.config, &parts.packets)).unwrap();
    assert_eq!(config, parts.header.config);
    assert_eq!(packets, parts.packets);
}

/// The corpus file that failed a fresh clone's `cargo test` on a machine reporting 300 MiB of
/// L3 (issue 27: "held 629183233 bytes at peak"), replayed on a new thread where no faer cache
/// exists yet: the peak must count what the decode allocates, not `private-gemm-x86`'s
/// per-thread packing buffer (2 × the L3 size; see `conformance_tests::warm_up_numeric_caches`).
#[test]
fn a_first_decode_on_a_fresh_thread_is_within_budget() {
    let file = corpus_dir().join("container").join("0abaecc0e542aecbbce36584045e9cc043597c34");
    let data = std::fs::read(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    let outcome = std::thread::spawn(move || fuzz::run("container", &data)).join();
    assert!(outcome.is_ok(), "{} fails its target on a fresh thread (see the panic above)", file.display());
}
