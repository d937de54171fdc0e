//! The command line on the reproducers of `../shared/probe-round4` (`docs/notes/issue-41-cli.md`): worker
//! counts bounded (`jobs-threads`), the interrupt message true after an OBJ sequence's commit
//! (`sigint-seq`), and the smaller findings of `misc`: export/view refuse a missing folder
//! before the work, `export --targets K` writes K targets and refuses `--target-kg` beside it,
//! the help names only commands that exist, printed paths never carry raw control characters,
//! and `synth:flag:CxRxF` is bounded as its help says.

use std::path::Path;
use std::process::{Command, Stdio};

mod common;
use common::*;

/// A usage error (exit 2) naming every one of `needles`, without panic text.
fn usage_error(args: &[&str], needles: &[&str]) -> String {
    let o = animcodec(args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "animcodec {args:?}: expected a usage error, stderr: {err}");
    assert!(!err.contains("panicked"), "{err}");
    for n in needles {
        assert!(err.contains(n), "animcodec {args:?}: stderr does not mention '{n}': {err}");
    }
    err
}

/// `--threads` and `sweep --jobs` took any count (65535, 4294967295): thousands of threads ran
/// past 60 s on trivial inputs. Counts above 4 × the cores (at least 8) are refused at once,
/// with the reason; counts within the bound still work.
#[test]
fn worker_counts_are_bounded_with_a_reason() {
    for args in [
        &["--threads", "65535", "list"][..],
        &["--threads", "1000", "decode", "x.anim", "-o", "x.pc2"][..],
        &["sweep", "synth:flag", "-c", "quant-delta", "--points", "3", "--jobs", "5000"][..],
        &["sweep", "--jobs", "4294967295"][..],
    ] {
        let err = usage_error(args, &["threads", "cores", "more than this machine allows"]);
        assert!(err.contains("the output is the same at any count"), "{err}");
    }
    usage_error(&["--threads", "0", "list"], &["at least 1"]);
    // Within the bound: 8 is always allowed, and the output does not depend on the count.
    let one = ok(&["--threads", "1", "list", "--json"]);
    assert_eq!(ok(&["--threads", "8", "list", "--json"]), one);
    let s = Scratch::new("r4-jobs");
    let json = s.path("s.json");
    ok(&[
        "sweep",
        "synth:flag",
        "-c",
        "quant-delta",
        "--points",
        "2",
        "--jobs",
        "8",
        // The grid's two points alone (the refinement rounds add points of their own).
        "--refine-rounds",
        "0",
        "--no-hausdorff",
        "--json",
        &json,
    ]);
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(doc["rows"].as_array().map(Vec::len), Some(2), "{doc}");
}

/// Every file name in a directory, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

/// A SIGINT landing after an OBJ sequence's commit said "interrupted: no output file was
/// changed" although the folder had been replaced. Here the signal lands exactly there,
/// deterministically: the command's stdout is a pipe kept full, so after the commit it blocks
/// writing its summary until the signal comes.
#[cfg(target_os = "linux")]
#[test]
fn interrupt_after_a_sequence_commit_says_what_was_written() {
    use std::io::Write;
    use std::os::unix::fs::OpenOptionsExt;
    let s = Scratch::new("r4-sigint-seq");
    let (old, new) = (s.path("old.anim"), s.path("new.anim"));
    ok(&["encode", "synth:flag:12x12x60", "-c", "quant-delta", "-p", "bits=8", "-o", &old]);
    ok(&["encode", "synth:flag:10x10x40", "-c", "quant-delta", "-p", "bits=8", "-o", &new]);
    let seq = s.0.join("seq");
    ok(&["decode", &old, "-o", &format!("{}/", seq.display())]);
    assert_eq!(names(&seq).len(), 60);

    // A FIFO held open for reading and writing by this test (so the command's open never
    // waits), filled until a write would block.
    let fifo = s.path("stdout.fifo");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    const O_NONBLOCK: i32 = 0o4000; // Linux, every architecture Rust supports there
    let mut ours = std::fs::OpenOptions::new().read(true).write(true).custom_flags(O_NONBLOCK).open(&fifo).unwrap();
    let chunk = [b'#'; 4096];
    loop {
        match ours.write(&chunk) {
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break,
            Err(e) => panic!("filling the FIFO: {e}"),
        }
    }
    let stdout = std::fs::OpenOptions::new().write(true).open(&fifo).unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_animcodec"))
        .args(["decode", &new, "-f", "-o", &format!("{}/", seq.display())])
        .stdout(Stdio::from(stdout))
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The commit is done when the folder holds exactly the 40 new frames and no temporary file.
    let committed = || {
        let n = names(&seq);
        n.len() == 40 && !n.iter().any(|f| f.ends_with(".tmp"))
    };
    let mut polls = 0;
    while !committed() {
        polls += 1;
        assert!(polls < 6000, "the decode never committed: {:?}", names(&seq));
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    let frame0 = std::fs::read_to_string(seq.join("frame_0000.obj")).unwrap();
    assert_eq!(frame0.lines().filter(|l| l.starts_with("v ")).count(), 100, "frame 0 is the new mesh");
    assert!(Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap().success());
    let output = child.wait_with_output().unwrap();
    drop(ours);
    let err = stderr(&output);
    assert_eq!(output.status.code(), Some(130), "{err}");
    assert!(!err.contains("no output file was changed"), "the message must say what was written: {err}");
    for needle in ["interrupted after changing output files", "40 files were written (complete)", "frame_0000.obj"] {
        assert!(err.contains(needle), "'{needle}' missing: {err}");
    }
    assert!(err.contains("20 stale file(s)"), "the old frames 40..59 were removed: {err}");
    assert!(!err.contains("panicked"), "{err}");
}

/// `export` and `view` wrote nothing into a missing folder, but found out only after the work
/// (6–9.5 s on the sample data). The folder is now checked first: even an input that cannot be
/// read is reported after the folder, so no work can come before the check.
#[test]
fn export_and_view_refuse_a_missing_folder_before_any_work() {
    let s = Scratch::new("r4-folder");
    let out = s.path("missing/x.glb");
    let err = fails(&["export", "/nonexistent/in.pc2", "-o", &out], &["does not exist", "missing"]);
    assert!(!err.contains("in.pc2"), "the folder is checked before the input is read: {err}");
    let page = s.path("missing/v.html");
    let err = fails(&["view", "/nonexistent/in.pc2", "quant-delta", "-o", &page], &["does not exist", "missing"]);
    assert!(!err.contains("in.pc2"), "the folder is checked before the input is read: {err}");
}

/// `export --targets K` wrote K + 1 targets (K components and the base's residual); now K in
/// all, with or without the rigid motion split off.
#[test]
fn export_targets_k_writes_k_targets() {
    let s = Scratch::new("r4-targets");
    for (input, rigid) in
        [("synth:flag", "on"), ("synth:flag", "off"), ("synth:cylinder", "auto"), ("synth:phases", "on")]
    {
        for k in [1usize, 3, 5] {
            let out = s.path(&format!("t{k}.glb"));
            let j =
                ok_json(&["export", input, "-o", &out, "-f", "--targets", &k.to_string(), "--rigid", rigid, "--json"]);
            assert_eq!(j["targets"].as_u64(), Some(k as u64), "{input} --rigid {rigid} --targets {k}: {j}");
            // The file holds exactly that many morph targets.
            let bytes = std::fs::read(&out).unwrap();
            let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
            let doc: serde_json::Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
            let written = doc["meshes"][0]["primitives"][0]["targets"].as_array().map_or(0, Vec::len);
            assert_eq!(written, k, "{input} --rigid {rigid} --targets {k}");
        }
    }
}

/// `--target-kg` (and `--target`) beside `--targets` was silently ignored: now a usage error.
#[test]
fn export_refuses_a_kg_target_beside_a_target_count() {
    for extra in [&["--target-kg", "0.1"][..], &["--target", "kg=0.1"][..]] {
        let mut args = vec!["export", "synth:flag", "-o", "/tmp/never-written.glb", "--targets", "5"];
        args.extend_from_slice(extra);
        usage_error(&args, &["cannot be used with", "--targets"]);
    }
}

/// The subcommands of `animcodec` (from `--help`).
fn subcommands() -> Vec<String> {
    let help = ok(&["--help"]);
    let commands = help.split("Commands:").nth(1).expect("a Commands section");
    commands
        .lines()
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .filter(|l| l.starts_with("  ") && !l.starts_with("   "))
        .filter_map(|l| l.split_whitespace().next())
        .map(str::to_owned)
        .collect()
}

/// `encode --help` pointed to `animcodec describe`, which does not exist. Every `animcodec
/// WORD` any help text names is now a subcommand.
#[test]
fn help_texts_name_only_commands_that_exist() {
    let commands = subcommands();
    assert!(commands.contains(&"encode".to_owned()) && commands.contains(&"list".to_owned()), "{commands:?}");
    for command in &commands {
        if command == "help" {
            continue;
        }
        let help = ok(&[command, "--help"]);
        let flat = help.split_whitespace().collect::<Vec<_>>().join(" ");
        for (i, _) in flat.match_indices("animcodec ") {
            let word: String = flat[i + 10..].chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '-').collect();
            if word.is_empty() || word.starts_with('-') {
                continue;
            }
            assert!(commands.contains(&word), "`{command} --help` names `animcodec {word}`, which is no command");
        }
    }
}

/// Output paths were echoed with raw terminal escapes (`\e[31m` turned the terminal red). Every
/// printed path, in summaries and errors, escapes control characters.
#[test]
fn printed_paths_escape_control_characters() {
    let s = Scratch::new("r4-escapes");
    let evil = s.path("x\x1b[31mRED\x1b[0m\r.pc2");
    let out = ok(&["synth", "flag", "-o", &evil]);
    assert!(!out.contains('\x1b') && !out.contains('\r'), "{out:?}");
    assert!(out.contains("\\u{1b}[31mRED"), "{out:?}");
    let anim = s.path("q.anim");
    ok(&["encode", &evil, "-c", "quant-delta", "-p", "bits=8", "-o", &anim]);
    let decoded = s.path("d\x1b]0;title\x07.pc2");
    let out = ok(&["decode", &anim, "-o", &decoded]);
    assert!(!out.chars().any(|c| c.is_control() && c != '\n'), "{out:?}");
    let glb = s.path("e\x1b[2J.glb");
    let out = ok(&["export", &anim, "-o", &glb]);
    assert!(!out.chars().any(|c| c.is_control() && c != '\n'), "{out:?}");
    // Errors too: a file that is not there, a refused output.
    let missing = s.path("gone\x1b[31m.anim");
    let o = animcodec(&["decode", &missing, "-o", &s.path("z.pc2")]);
    assert_eq!(o.status.code(), Some(1));
    assert!(!stderr(&o).trim_end().chars().any(char::is_control), "{:?}", stderr(&o));
    let o = animcodec(&["synth", "flag", "-o", &evil]);
    assert_eq!(o.status.code(), Some(1));
    assert!(!stderr(&o).trim_end().chars().any(char::is_control), "{:?}", stderr(&o));
}

/// `synth:flag:3000x3000x2` took 3.7 GB although the help said the input is never held: its
/// frames are not, its mesh is (about 420 bytes a vertex). The help says so now, and a mesh
/// needing more than `--memory` is refused before anything is built.
#[test]
fn a_streamed_flag_is_bounded_by_memory() {
    let s = Scratch::new("r4-flag");
    let out = s.path("f.anim");
    let err = fails(
        &["encode", "synth:flag:1500x1500x2", "-c", "quant-delta", "-p", "bits=8", "--memory", "64M", "-o", &out],
        &["mesh", "--memory", "2250000 vertices"],
    );
    assert!(err.contains("only the frames are generated one at a time"), "{err}");
    assert!(!Path::new(&out).exists());
    ok(&["encode", "synth:flag:40x30x3", "-c", "quant-delta", "-p", "bits=8", "--memory", "64M", "-o", &out]);
    let help = ok(&["encode", "--help"]).split_whitespace().collect::<Vec<_>>().join(" ");
    assert!(!help.contains("never held in memory"), "the help no longer says the flag is never held");
    assert!(help.contains("its mesh") && help.contains("bytes a vertex"), "{help}");
}
