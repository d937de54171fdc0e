//! `capi/examples/play.c` built with the system's C compiler against the library as installed
//! by `capi/install.sh` (through its pkg-config file), run on every golden stream: its PC2 must
//! equal, byte for byte, the PC2 of the Rust library's decode — and of `animcodec decode` when
//! the command-line binary is built (`cargo test --workspace` builds it). The same example built
//! with AddressSanitizer and UndefinedBehaviorSanitizer must run clean on every golden stream.
//!
//! Without a C compiler or pkg-config the tests skip (`codec_core::testing::skip`).

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use animcodec::core::{decode_animation, Limits};
use codec_core::testing::skip;

/// Installs the built library into a fresh prefix; `None` (after a skip) without cc/pkg-config.
fn install(test: &str) -> Option<(tempdir::Dir, PathBuf)> {
    for tool in ["cc", "pkg-config"] {
        if Command::new(tool).arg("--version").output().is_err() {
            skip(test, &format!("no `{tool}` on PATH (apt-get install gcc pkg-config)"));
            return None;
        }
    }
    // `cargo test` builds the crate as a Rust library for the tests only: the C libraries
    // (`cdylib`, `staticlib`) come from a `cargo build` of the package into the same target
    // directory and profile (cargo holds no lock while tests run).
    let library = common::library_dir();
    let mut build = Command::new(env!("CARGO"));
    build.current_dir(common::workspace()).args(["build", "-q", "-p", "animcodec-capi", "--lib"]);
    if let Some(target) = library.parent() {
        build.env("CARGO_TARGET_DIR", target);
    }
    if library.file_name().is_some_and(|p| p == "release") {
        build.arg("--release");
    }
    let built = build.status().expect("cargo");
    assert!(built.success(), "cargo build -p animcodec-capi failed");
    let dir = tempdir::Dir::new(test);
    let prefix = dir.path().join("prefix");
    let status = Command::new("sh")
        .arg(common::workspace().join("capi").join("install.sh"))
        .arg(common::library_dir())
        .arg(&prefix)
        .status()
        .expect("sh");
    assert!(status.success(), "capi/install.sh failed");
    Some((dir, prefix))
}

/// `cc play.c $(pkg-config --cflags --libs animcodec) extra…` → the executable.
fn build_play(dir: &Path, prefix: &Path, name: &str, extra: &[&str]) -> Result<PathBuf, String> {
    build_example("play.c", dir, prefix, name, extra)
}

/// `cc capi/examples/SOURCE $(pkg-config --cflags --libs animcodec) extra…` → the executable.
fn build_example(source: &str, dir: &Path, prefix: &Path, name: &str, extra: &[&str]) -> Result<PathBuf, String> {
    let pc = Command::new("pkg-config")
        .args(["--cflags", "--libs", "animcodec"])
        .env("PKG_CONFIG_PATH", prefix.join("lib").join("pkgconfig"))
        .output()
        .expect("pkg-config");
    assert!(pc.status.success(), "pkg-config: {}", String::from_utf8_lossy(&pc.stderr));
    let flags = String::from_utf8(pc.stdout).expect("utf-8");
    let exe = dir.join(name);
    let out = Command::new("cc")
        .args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-g"])
        .arg(common::workspace().join("capi").join("examples").join(source))
        .args(flags.split_whitespace())
        .arg("-lm")
        .arg(format!("-Wl,-rpath,{}", prefix.join("lib").display()))
        .args(extra)
        .arg("-o")
        .arg(&exe)
        .output()
        .expect("cc");
    if !out.status.success() {
        return Err(String::from_utf8_lossy(&out.stderr).into_owned());
    }
    Ok(exe)
}

/// The PC2 of the Rust library's decode of `stream`.
fn reference_pc2(stream: &Path) -> Vec<u8> {
    let bytes = std::fs::read(stream).expect("golden");
    let animation = decode_animation(&bytes, &animcodec::registry(), Limits::default()).expect("golden decodes");
    animcodec::formats::pc2::encode_pc2(&animation).expect("pc2")
}

/// The `animcodec` binary when it has been built next to this test.
fn cli() -> Option<PathBuf> {
    let exe = common::library_dir().join(format!("animcodec{}", std::env::consts::EXE_SUFFIX));
    exe.is_file().then_some(exe)
}

#[test]
fn play_c_writes_the_pc2_of_the_library_and_of_the_cli_for_every_golden_stream() {
    let test = "play_c_writes_the_pc2_of_the_library_and_of_the_cli_for_every_golden_stream";
    let Some((dir, prefix)) = install(test) else { return };
    let play = build_play(dir.path(), &prefix, "play", &[]).unwrap_or_else(|e| panic!("cc play.c: {e}"));
    let cli = cli();
    if cli.is_none() {
        skip(test, "the animcodec binary is not built (cargo build -p animcodec-cli): compared with the library only");
    }
    let mut codecs = std::collections::BTreeSet::new();
    for (i, stream) in common::goldens().iter().enumerate() {
        let out = dir.path().join(format!("{i}.pc2"));
        let run = Command::new(&play).arg(stream).arg(&out).output().expect("play");
        let stdout = String::from_utf8_lossy(&run.stdout);
        assert!(run.status.success(), "{}: {}{}", stream.display(), stdout, String::from_utf8_lossy(&run.stderr));
        codecs.insert(stdout.split("codec ").nth(1).and_then(|s| s.split(' ').next()).unwrap_or("").to_owned());
        let played = std::fs::read(&out).expect("play's output");
        assert!(played == reference_pc2(stream), "{}: play.c's PC2 differs from the library's", stream.display());
        if let Some(cli) = &cli {
            let cli_out = dir.path().join(format!("{i}-cli.pc2"));
            let run = Command::new(cli).arg("decode").arg(stream).arg("-o").arg(&cli_out).output().expect("cli");
            assert!(run.status.success(), "animcodec decode: {}", String::from_utf8_lossy(&run.stderr));
            assert!(played == std::fs::read(&cli_out).unwrap(), "{}: differs from animcodec decode", stream.display());
        }
    }
    let names: Vec<_> = animcodec::registry().iter().map(|c| c.name().to_owned()).collect();
    assert_eq!(
        codecs.into_iter().collect::<Vec<_>>(),
        {
            let mut n = names;
            n.sort();
            n
        },
        "every codec played"
    );
}

#[test]
fn play_c_under_address_and_undefined_behavior_sanitizers_runs_clean_on_every_golden_stream() {
    let test = "play_c_under_address_and_undefined_behavior_sanitizers_runs_clean_on_every_golden_stream";
    let Some((dir, prefix)) = install(test) else { return };
    let flags = ["-fsanitize=address,undefined", "-fno-omit-frame-pointer", "-fno-sanitize-recover=all"];
    let play = match build_play(dir.path(), &prefix, "play-asan", &flags) {
        Ok(exe) => exe,
        Err(e) => return skip(test, &format!("cc cannot build with sanitizers (libasan/libubsan missing?): {e}")),
    };
    for (i, stream) in common::goldens().iter().enumerate() {
        let out = dir.path().join(format!("asan-{i}.pc2"));
        let run = Command::new(&play)
            .arg(stream)
            .arg(&out)
            .env("ASAN_OPTIONS", "detect_leaks=1:halt_on_error=1")
            .env("UBSAN_OPTIONS", "halt_on_error=1:print_stacktrace=1")
            .output()
            .expect("play");
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(run.status.success() && stderr.is_empty(), "{}: {stderr}", stream.display());
        assert!(std::fs::read(&out).unwrap() == reference_pc2(stream), "{}", stream.display());
    }
    // A stream that fails: reported, nothing written, still clean.
    let missing = dir.path().join("missing.anim");
    let run = Command::new(&play).arg(&missing).arg(dir.path().join("x.pc2")).output().expect("play");
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("cannot open") && !stderr.contains("Sanitizer"), "{stderr}");
}

/// A scratch directory in the system temp dir, removed on drop.
mod tempdir {
    use std::path::{Path, PathBuf};

    pub struct Dir(PathBuf);

    impl Dir {
        pub fn new(name: &str) -> Self {
            let path = std::env::temp_dir().join(format!("animcodec-capi-{name}-{}", std::process::id()));
            let _ = std::fs::remove_dir_all(&path);
            std::fs::create_dir_all(&path).expect("temp dir");
            Self(path)
        }

        pub fn path(&self) -> &Path {
            &self.0
        }
    }

    impl Drop for Dir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// `capi/examples/encode.c`: `ac_encode` from C with a KG target and with fixed parameters;
/// each stream decodes back (through the C API) within its bound, the targeted stream is a
/// valid stream for the Rust library too, and an unknown parameter fails with its name in
/// `ac_last_error`.
#[test]
fn encode_c_writes_streams_that_decode_within_the_target() {
    let test = "encode_c_writes_streams_that_decode_within_the_target";
    let Some((dir, prefix)) = install(test) else { return };
    let exe =
        build_example("encode.c", dir.path(), &prefix, "encode", &[]).unwrap_or_else(|e| panic!("cc encode.c: {e}"));
    let out = dir.path().join("wave.anim");
    let run = Command::new(&exe).arg(&out).output().expect("encode");
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "{stdout}{}", String::from_utf8_lossy(&run.stderr));
    assert!(stdout.contains("target kg=0.5") && stdout.contains("nonsense=3: AC_ERR_INVALID_ARGUMENT"), "{stdout}");
    let bytes = std::fs::read(&out).expect("the stream encode.c wrote");
    let decoded = decode_animation(&bytes, &animcodec::registry(), Limits::default()).expect("decodes");
    assert_eq!((decoded.frame_count(), decoded.vertex_count()), (30, 24 * 16));
}
