//! Progress display of the long commands (`export`, `decode`, `view`, `sweep`, `encode
//! --target`): drawn on a terminal, absent from piped output.

mod common;

use std::path::Path;
use std::process::Command;

use animcodec::formats::write_animation;
use animcodec::synth::{self, SynthSize};
use codec_core::testing::skip;
use common::{animcodec, stderr, stdout, Scratch};

/// Markers only a progress display prints: the stage counter, the ETA, a carriage return or a
/// cursor/line escape sequence.
fn has_progress_text(text: &str) -> bool {
    text.contains("[1/") || text.contains("ETA") || text.contains('\r') || text.contains('\u{1b}')
}

/// The long commands on a small animation, each as an argument list with the text its progress
/// display shows (the terminal itself turns newlines into `\r\n`, so that text, not `\r`,
/// tells a drawn display).
fn commands(dir: &Scratch) -> Vec<(Vec<String>, &'static str)> {
    let flag = synth::by_name("flag", SynthSize::Small).unwrap();
    let input = dir.path("flag.pc2");
    write_animation(Path::new(&input), &flag).unwrap();
    let anim = dir.path("flag.anim");
    common::ok(&["encode", &input, "-c", "quant-delta", "-p", "bits=10", "-o", &anim]);
    let list = |args: &[&str]| args.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    vec![
        (list(&["export", &input, "-o", &dir.path("x.glb"), "-f"]), "export [1/4] reading"),
        (list(&["decode", &anim, "-o", &dir.path("x2.glb"), "-f"]), "decode [2/2] writing"),
        (list(&["view", &input, &anim, "-o", &dir.path("v.html"), "-f"]), "view [2/4] candidate"),
        (list(&["sweep", &input, "-c", "quant-delta", "--ladder", "--points", "2"]), "ladder step"),
        (
            list(&["encode", &input, "-c", "quant-delta", "--target", "kg=5", "-o", &dir.path("t.anim"), "-f"]),
            "points; last:",
        ),
    ]
}

#[test]
fn no_progress_text_off_a_terminal() {
    let dir = Scratch::new("progress-off");
    for (args, _) in commands(&dir) {
        let argv: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = animcodec(&argv);
        assert!(o.status.success(), "{argv:?}: {}", stderr(&o));
        let (out, err) = (stdout(&o), stderr(&o));
        assert!(!has_progress_text(&err), "{argv:?} printed progress to a pipe: {err:?}");
        assert!(!has_progress_text(&out), "{argv:?} printed progress to stdout: {out:?}");
    }
    // `--json` output stays a bare document.
    let input = dir.path("flag.pc2");
    let o = animcodec(&["export", &input, "-o", &dir.path("j.glb"), "--json"]);
    assert!(o.status.success() && stdout(&o).trim_start().starts_with('{') && !has_progress_text(&stdout(&o)));
}

#[test]
fn progress_is_drawn_on_a_terminal() {
    // util-linux `script` runs the command on a pseudo-terminal and records what it draws.
    if Command::new("script").arg("--version").output().is_err() {
        return skip("progress_is_drawn_on_a_terminal", "util-linux `script` not found");
    }
    let dir = Scratch::new("progress-on");
    let bin = env!("CARGO_BIN_EXE_animcodec");
    for (args, marker) in commands(&dir) {
        let line = std::iter::once(bin.to_owned())
            .chain(args.iter().map(|a| format!("'{}'", a.replace('\'', "'\\''"))))
            .collect::<Vec<_>>()
            .join(" ");
        let typescript = dir.path("typescript");
        let o = Command::new("script").args(["-qec", &line, &typescript]).output().unwrap();
        let drawn = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(o.status.success(), "{line}: {drawn}");
        assert!(drawn.contains(marker), "{line}: no progress ({marker:?}) on a terminal: {drawn:?}");
    }
}
