//! The promise of README "Adding a codec", checked on every `cargo test --workspace`: in a copy
//! of this workspace, `cargo xtask new-codec` followed by the documented steps
//! (`xtask::GENERATED`, what `cargo xtask write-generated` runs) gives a codec that passes the
//! conformance suite, the golden-stream, fuzz-corpus and codec-table tests, its own tests and
//! the format check — with no other edit. It also runs the template codec (`xtask/template/`)
//! through the whole suite, so the template cannot rot unnoticed.
//!
//! Cost: the copy is a different workspace (its path-dependency crates get new build hashes), so
//! its workspace crates are compiled again, but registry crates are not: the copy builds into this
//! workspace's own target folder, where they are already compiled with the same settings. The
//! conformance run is restricted to the new codec (`ANIMCODEC_CODECS`); the other codecs are
//! tested by this workspace's own run.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use codec_core::testing::skip;

/// The codec the test scaffolds: a hyphen, so every spelling (crate, module, type, fuzz
/// target) differs from the name.
const NAME: &str = "scaffold-probe";

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("xtask/ has a parent").to_path_buf()
}

/// This workspace's target folder, which the copy builds into.
fn target_dir(root: &Path) -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR").map(PathBuf::from).unwrap_or_else(|| root.join("target"))
}

/// Files of the working tree that git tracks or would track (tracked files and new files not
/// ignored, as they are on disk now, so uncommitted work is what gets tested). `None` outside a
/// git checkout.
fn workspace_files(root: &Path) -> Option<Vec<PathBuf>> {
    let out = Command::new("git")
        .args(["ls-files", "-z", "--cached", "--others", "--exclude-standard"])
        .current_dir(root)
        .output()
        .ok()?;
    if !out.status.success() {
        return None;
    }
    let mut files: Vec<PathBuf> = out
        .stdout
        .split(|&b| b == 0)
        .filter(|f| !f.is_empty())
        .map(|f| PathBuf::from(String::from_utf8_lossy(f).into_owned()))
        .collect();
    files.sort();
    files.dedup();
    Some(files)
}

fn copy_workspace(root: &Path, files: &[PathBuf], to: &Path) {
    if to.exists() {
        std::fs::remove_dir_all(to).unwrap_or_else(|e| panic!("{}: {e}", to.display()));
    }
    for f in files {
        let from = root.join(f);
        // A tracked file deleted in the working tree is absent from the copy too.
        if !from.is_file() {
            continue;
        }
        let dest = to.join(f);
        std::fs::create_dir_all(dest.parent().expect("a file has a parent")).unwrap();
        std::fs::copy(&from, &dest).unwrap_or_else(|e| panic!("{} → {}: {e}", from.display(), dest.display()));
        // Same modification times as the originals: cargo's fingerprints then see the copy of
        // an unchanged file as unchanged on the next run, so a local rerun rebuilds only what
        // changed (CI builds the copy once either way).
        if let Ok(modified) = std::fs::metadata(&from).and_then(|m| m.modified()) {
            let _ = std::fs::File::options().write(true).open(&dest).and_then(|f| f.set_modified(modified));
        }
    }
}

/// Runs cargo in the copy with `args` and `env` set (and every variable of this repository's
/// that changes what tests do removed, so the outer run's settings cannot leak in), panicking
/// with its output on failure.
fn cargo(ws: &Path, target: &Path, args: &[&str], env: &[(&str, &str)]) {
    let start = Instant::now();
    let mut cmd = Command::new(std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into()));
    // The copy's own crates at opt-level 0: they are compiled anew (a different workspace), and
    // what runs on them here is small. Registry crates keep the opt-level 3 of
    // `[profile.dev.package."*"]`, so their builds in the shared target folder are reused.
    cmd.args(args).current_dir(ws).env("CARGO_TARGET_DIR", target).env("CARGO_PROFILE_DEV_OPT_LEVEL", "0");
    for (key, _) in std::env::vars_os() {
        let key = key.to_string_lossy();
        if key.starts_with("ANIMCODEC_WRITE_") || key == "ANIMCODEC_CODECS" {
            cmd.env_remove(&*key);
        }
    }
    for (k, v) in env {
        cmd.env(k, v);
    }
    let out = cmd.output().unwrap_or_else(|e| panic!("running cargo: {e}"));
    let shown =
        format!("{} cargo {}", env.iter().map(|(k, v)| format!("{k}={v} ")).collect::<String>(), args.join(" "));
    assert!(
        out.status.success(),
        "in the scaffolded copy {}: `{shown}` failed ({})\n--- stdout\n{}\n--- stderr\n{}",
        ws.display(),
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let passed: usize = String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| l.strip_prefix("test result: ok. ")?.split(' ').next()?.parse::<usize>().ok())
        .sum();
    eprintln!("{shown}: {passed} tests passed, {:.0} s", start.elapsed().as_secs_f64());
}

#[test]
fn a_scaffolded_codec_passes_every_test_with_no_other_edit() {
    let start = Instant::now();
    let root = root();
    let Some(files) = workspace_files(&root) else {
        return skip(
            "a_scaffolded_codec_passes_every_test_with_no_other_edit",
            "not a git checkout (git ls-files failed)",
        );
    };
    let target = target_dir(&root);
    let ws = target.join("scaffold-test").join("workspace");
    copy_workspace(&root, &files, &ws);
    eprintln!("copied {} files to {} in {:.1} s", files.len(), ws.display(), start.elapsed().as_secs_f64());

    // The scaffold, exactly as `cargo xtask new-codec` runs it.
    let names = xtask::check_names(&ws, &animcodec::registry(), NAME, None).expect("a valid, new codec name");
    let written = xtask::new_codec(&ws, &names).expect("new-codec succeeds");
    for expected in [
        format!("codec-{NAME}/Cargo.toml"),
        format!("codec-{NAME}/src/lib.rs"),
        format!("codec-{NAME}/src/params.rs"),
        format!("codec-{NAME}/README.md"),
        "Cargo.toml".to_owned(),
        "animcodec/Cargo.toml".to_owned(),
        "animcodec/src/lib.rs".to_owned(),
        "fuzz/Cargo.toml".to_owned(),
        format!("fuzz/fuzz_targets/codec_{}.rs", names.snake),
    ] {
        assert!(written.contains(&expected), "new-codec did not write {expected}: {written:?}");
    }
    // No trace of the template's own names is left in the new crate.
    for f in written.iter().filter(|f| f.starts_with(&format!("codec-{NAME}/"))) {
        let text = std::fs::read_to_string(ws.join(f)).unwrap();
        for word in ["template", "Template", "TMPL"] {
            assert!(!text.contains(word), "{f} still says '{word}'");
        }
    }
    // Asking again is refused (the crate exists now), and nothing is written.
    assert!(xtask::check_names(&ws, &animcodec::registry(), NAME, None).unwrap_err().contains("already exists"));

    // The documented steps: README "Adding a codec" states each of these commands.
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    for g in xtask::GENERATED {
        let line = xtask::command_line(g);
        assert!(readme.contains(&line), "README.md does not document `{line}`");
        cargo(&ws, &target, g.1, &[(g.0, "1")]);
    }

    // Every test that concerns a new codec, on it: conformance suite (restricted to it, the
    // other codecs are tested by the real workspace's run), golden streams, fuzz corpora and
    // their wiring, the README tables, parameter declarations, the crate floors (architecture);
    // and the format check. Not its unit tests (`cargo test -p codec-NAME`): they are the
    // template's, which run as `codec-template` in every workspace run, and selecting one
    // package makes cargo resolve dependency features differently from `--workspace`,
    // rebuilding faer, serde and the rest.
    cargo(
        &ws,
        &target,
        &[
            "test",
            "--workspace",
            "--test",
            "conformance",
            "--test",
            "corruption",
            "--test",
            "encoder_input",
            "--test",
            "golden",
            "--test",
            "fuzz_corpus",
            "--test",
            "codec_tables",
            "--test",
            "param_declarations",
            "--test",
            "architecture",
        ],
        &[("ANIMCODEC_CODECS", NAME)],
    );
    cargo(&ws, &target, &["fmt", "--all", "--", "--check"], &[]);

    // What the generated files hold: the golden stream, the seeds, the README row.
    assert!(ws.join(format!("tests/golden/{NAME}-v1.anim")).is_file(), "no golden stream written");
    let corpus = ws.join(format!("fuzz/corpus/codec_{}", names.snake));
    assert!(std::fs::read_dir(&corpus).map(|d| d.count()).unwrap_or(0) > 0, "no fuzz seeds in {}", corpus.display());
    let readme = std::fs::read_to_string(ws.join("README.md")).unwrap();
    assert!(readme.contains(&format!("| `{NAME}` | `{}` |", names.fourcc)), "README.md codec table lacks {NAME}");

    // The copy is kept for inspection (the next run replaces it); it is small, its build output
    // is in the target folder anyway.
    eprintln!(
        "scaffold test: {:.0} s in all; the scaffolded copy is in {}",
        start.elapsed().as_secs_f64(),
        ws.display()
    );
}
