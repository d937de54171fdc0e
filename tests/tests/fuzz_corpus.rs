//! Runs every committed fuzz corpus file (`fuzz/corpus/<target>/*`) through the same function
//! its cargo-fuzz target calls (`conformance_tests::fuzz`), so CI checks every input the fuzzers
//! found interesting, and every past finding, without running a fuzzer. Also checks that the
//! committed seeds are what the generator makes now, and that every registered codec has its
//! fuzz target, `[[bin]]` and corpus.
//!
//! `ANIMCODEC_WRITE_FUZZ_SEEDS=1 cargo test --workspace --test fuzz_corpus` writes the
//! seed inputs made from the synthetic animations (`seed-*` files) into the corpora, and deletes
//! `seed-*` files the generator no longer makes; on an up-to-date tree it changes nothing.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use conformance_tests::fuzz::{self, corpus_dir};

/// With `ANIMCODEC_WRITE_FUZZ_SEEDS` set, writes the seeds once per test binary, before any
/// test here reads the corpus (the tests run in parallel threads; without this one could read
/// a file while another writes it).
fn corpus_written() {
    static WRITTEN: OnceLock<()> = OnceLock::new();
    WRITTEN.get_or_init(|| {
        if std::env::var_os("ANIMCODEC_WRITE_FUZZ_SEEDS").is_some() {
            let touched = fuzz::write_seeds().expect("writing the fuzz seeds");
            let mut report = String::new();
            for path in &touched {
                report.push_str(&format!("wrote or deleted {}\n", path.display()));
            }
            report.push_str(&format!("ANIMCODEC_WRITE_FUZZ_SEEDS: {} seed files changed\n", touched.len()));
            // Past libtest's output capture: what was written must show in a plain run.
            let _ = std::io::Write::write_all(&mut std::io::stderr(), report.as_bytes());
        }
    });
}

#[test]
fn every_corpus_file_passes_its_target() {
    corpus_written();
    let root = corpus_dir();
    let mut total = 0;
    for target in fuzz::targets() {
        let dir = root.join(&target);
        let mut files: Vec<PathBuf> = match std::fs::read_dir(&dir) {
            Ok(entries) => entries.map(|e| e.unwrap().path()).filter(|p| p.is_file()).collect(),
            Err(e) => panic!(
                "{}: {e}: every fuzz target has a committed corpus; make its seeds with \
                 ANIMCODEC_WRITE_FUZZ_SEEDS=1 cargo test --workspace --test fuzz_corpus",
                dir.display()
            ),
        };
        files.sort();
        assert!(!files.is_empty(), "{}: empty corpus (make its seeds as above)", dir.display());
        for file in &files {
            let data = std::fs::read(file).unwrap();
            let outcome = std::panic::catch_unwind(|| fuzz::run(&target, &data));
            assert!(outcome.is_ok(), "{target}: {} fails its target (see the panic above)", file.display());
        }
        eprintln!("{target}: {} corpus files", files.len());
        total += files.len();
    }
    assert!(total > 0, "no fuzz target found under {}", root.display());
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
/// L3 ("held 629183233 bytes at peak"), replayed on a new thread where no faer cache
/// exists yet: the peak must count what the decode allocates, not `private-gemm-x86`'s
/// per-thread packing buffer (2 × the L3 size; see `conformance_tests::warm_up_numeric_caches`).
#[test]
fn a_first_decode_on_a_fresh_thread_is_within_budget() {
    let file = corpus_dir().join("container").join("0abaecc0e542aecbbce36584045e9cc043597c34");
    let data = std::fs::read(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    let outcome = std::thread::spawn(move || fuzz::run("container", &data)).join();
    assert!(outcome.is_ok(), "{} fails its target on a fresh thread (see the panic above)", file.display());
}

/// The committed `seed-*` files are exactly what `fuzz::seeds` makes now (compared in memory),
/// so `ANIMCODEC_WRITE_FUZZ_SEEDS=1` on a clean tree changes nothing and a codec change that
/// alters its seeds shows up here, not in someone else's commit. Byte for byte on CPUs with
/// AVX2 + FMA (where seeds are written); without, a seed that differs must still decode
/// (`fuzz::seeds_are_exact_here` says why).
#[test]
fn committed_seeds_are_current() {
    corpus_written();
    let (differences, tolerated): (Vec<_>, Vec<_>) =
        fuzz::seed_differences().into_iter().partition(|(_, _, d)| d.is_stale());
    if !tolerated.is_empty() {
        let names: Vec<String> = tolerated.iter().map(|(t, f, _)| format!("{t}/{f}")).collect();
        let _ = std::io::Write::write_all(
            &mut std::io::stderr(),
            format!(
                "NOTE committed_seeds_are_current: this CPU lacks AVX2/FMA and encodes {} differently; they still \
                 decode, so they are not stale (conformance_tests::fuzz::seeds_are_exact_here)\n",
                names.join(", ")
            )
            .as_bytes(),
        );
    }
    let listing: Vec<String> = differences.iter().map(|(t, f, d)| format!("  {t}/{f}: {d:?}")).collect();
    assert!(
        differences.is_empty(),
        "{} committed fuzz seeds differ from what the generator makes now (tests/src/fuzz.rs, `seeds`):\n{}\n\
         rewrite them with ANIMCODEC_WRITE_FUZZ_SEEDS=1 cargo test --workspace --test fuzz_corpus \
         and commit the result",
        differences.len(),
        listing.join("\n")
    );
}

/// `(name, path)` of every `[[bin]]` in `fuzz/Cargo.toml`. A line-based reading of the few
/// keys cargo-fuzz writes there: enough for this check, and no TOML parser to depend on.
fn fuzz_bins(manifest: &str) -> Vec<(String, String)> {
    let value = |line: &str, key: &str| {
        let (k, v) = line.split_once('=')?;
        (k.trim() == key).then(|| v.trim().trim_matches('"').to_owned())
    };
    let mut bins = Vec::new();
    for section in manifest.split("[[bin]]").skip(1) {
        let section = section.split("\n[").next().unwrap_or(section);
        let name = section.lines().find_map(|l| value(l, "name"));
        let path = section.lines().find_map(|l| value(l, "path"));
        if let (Some(name), Some(path)) = (name, path) {
            bins.push((name, path));
        }
    }
    bins
}

/// Every registered codec (and every other target) has its cargo-fuzz target file calling
/// `conformance_tests::fuzz::run` with its own name, a `[[bin]]` in `fuzz/Cargo.toml` pointing
/// at that file, and a non-empty corpus; and no target file or `[[bin]]` is left over from a
/// codec that is no longer registered.
#[test]
fn every_target_has_a_fuzz_binary_and_a_corpus() {
    corpus_written();
    let fuzz_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join("fuzz");
    let manifest = std::fs::read_to_string(fuzz_dir.join("Cargo.toml")).expect("fuzz/Cargo.toml");
    let bins = fuzz_bins(&manifest);
    let targets = fuzz::targets();
    let mut problems = Vec::new();
    for target in &targets {
        let file = format!("fuzz_targets/{target}.rs");
        match std::fs::read_to_string(fuzz_dir.join(&file)) {
            Ok(text) if text.contains(&format!("fuzz::run(\"{target}\"")) => {}
            Ok(_) => problems.push(format!("fuzz/{file} does not call conformance_tests::fuzz::run(\"{target}\", …)")),
            Err(e) => problems.push(format!("fuzz/{file}: {e}")),
        }
        if !bins.iter().any(|(name, path)| name == target && path == &file) {
            problems.push(format!("fuzz/Cargo.toml has no [[bin]] name = \"{target}\", path = \"{file}\""));
        }
        let corpus = fuzz_dir.join("corpus").join(target);
        let files = std::fs::read_dir(&corpus).map(|d| d.flatten().filter(|e| e.path().is_file()).count()).unwrap_or(0);
        if files == 0 {
            problems.push(format!("fuzz/corpus/{target}/ is missing or empty"));
        }
    }
    for (name, path) in &bins {
        if !targets.contains(name) {
            problems.push(format!("fuzz/Cargo.toml: [[bin]] {name} ({path}) is not a target of a registered codec"));
        }
    }
    for entry in std::fs::read_dir(fuzz_dir.join("fuzz_targets")).expect("fuzz/fuzz_targets").flatten() {
        let name = entry.file_name().to_string_lossy().trim_end_matches(".rs").to_owned();
        if !targets.contains(&name) {
            problems.push(format!("fuzz/fuzz_targets/{name}.rs is not a target of a registered codec"));
        }
    }
    assert!(
        problems.is_empty(),
        "fuzz targets out of step with the registry (`cargo xtask new-codec` writes all three for a new \
         codec; README \"Adding a codec\"):\n  {}",
        problems.join("\n  ")
    );
}

#[test]
fn fuzz_bins_reads_the_manifest_layout() {
    let manifest = "[package]\nname = \"x\"\n\n[[bin]]\nname = \"a\"\npath = \"fuzz_targets/a.rs\"\ntest = false\n\n[profile.release]\nname = \"no\"\n";
    assert_eq!(fuzz_bins(manifest), vec![("a".to_owned(), "fuzz_targets/a.rs".to_owned())]);
}
