//! Output safety (temporary file + rename, `--force`, inputs never overwritten,
//! OBJ-sequence folders, placeholders), error messages (no panic text, no Debug values, the
//! right words), and `info` verifying checksums. An OBJ sequence touches only its own name pattern, outputs
//! are validated before they replace anything and committed together, two outputs on one path
//! and `-` as a file are refused, a cache is never paired with another mesh's OBJ, and metric
//! parameters giving NaN or infinity are refused.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::*;

/// Every file name in a directory, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

/// True when a temporary output file (`.NAME.PID-N.tmp`) is in `dir`.
fn has_temporary(dir: &Path) -> bool {
    names(dir).iter().any(|n| n.starts_with('.') && n.ends_with(".tmp"))
}

#[test]
fn interrupted_encode_leaves_the_old_stream_and_no_partial_file() {
    let s = Scratch::new("sigint");
    let out = s.path("k.anim");
    std::fs::write(&out, b"the previous stream").unwrap();
    // A flag big enough that encoding takes several seconds, streamed to disk.
    let mut child = Command::new(env!("CARGO_BIN_EXE_animcodec"))
        .args(["encode", "-c", "quant-delta", "-p", "bits=12", "-f", "-o", &out, "synth:flag:100x100x3000"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Interrupt once the temporary file exists (the encoder is writing).
    let start = Instant::now();
    while !has_temporary(&s.0) && start.elapsed() < Duration::from_secs(60) {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(has_temporary(&s.0), "the encoder never started writing");
    std::thread::sleep(Duration::from_millis(200));
    let killed = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(killed.success());
    let output = child.wait_with_output().unwrap();
    assert_eq!(output.status.code(), Some(130), "stderr: {}", stderr(&output));
    assert_eq!(std::fs::read(&out).unwrap(), b"the previous stream", "the old file must be untouched");
    assert_eq!(names(&s.0), ["k.anim"], "no partial or temporary file is left");
    assert!(!stderr(&output).contains("panicked"));
}

#[test]
fn decode_failing_part_way_keeps_the_old_file_and_leaves_nothing_partial() {
    let s = Scratch::new("ulimit");
    let anim = s.path("s.anim");
    ok(&["encode", "synth:flag", "-c", "quant-delta", "-o", &anim]);
    let out = s.path("e.pc2");
    std::fs::write(&out, b"old content").unwrap();
    // A small file-size limit: the PC2 (about 115 kB) cannot be written completely.
    let o = Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -f 50 && exec '{}' decode '{anim}' -f -o '{out}'", env!("CARGO_BIN_EXE_animcodec")))
        .output()
        .unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.starts_with("error: ") && err.contains("e.pc2") && err.contains("too large"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(std::fs::read(&out).unwrap(), b"old content");
    assert_eq!(names(&s.0), ["e.pc2", "s.anim"]);
}

#[test]
fn an_input_is_never_an_output_even_with_force() {
    let s = Scratch::new("same-file");
    let src = s.path("flag.pc2");
    ok(&["synth", "flag", "-o", &src]);
    let before = std::fs::read(&src).unwrap();
    for force in [false, true] {
        let mut args = vec!["encode", "-c", "quant-delta", "-o", &src, &src];
        if force {
            args.push("--force");
        }
        fails(&args, &["refusing to write", "flag.pc2", "also an input"]);
    }
    // The same file under another spelling, and the topology OBJ read with the cache.
    let other = format!("{}/./flag.pc2", s.0.display());
    fails(&["encode", "-c", "quant-delta", "-f", "-o", &other, &src], &["also an input"]);
    let obj = s.path("flag.obj");
    fails(&["encode", "-c", "quant-delta", "-f", "-o", &obj, &src], &["also an input"]);
    let anim = s.path("flag.anim");
    ok(&["encode", "-c", "quant-delta", "-o", &anim, &src]);
    fails(&["decode", &anim, "-f", "-o", &anim], &["also an input"]);
    assert_eq!(std::fs::read(&src).unwrap(), before);
    assert!(Path::new(&anim).is_file());
}

#[test]
fn existing_outputs_need_force() {
    let s = Scratch::new("force");
    let anim = s.path("a.anim");
    ok(&["encode", "synth:tumble", "-c", "quant-delta", "-o", &anim]);
    let first = std::fs::read(&anim).unwrap();
    fails(&["encode", "synth:tumble", "-c", "quant-delta", "-p", "bits=6", "-o", &anim], &["a.anim", "--force"]);
    assert_eq!(std::fs::read(&anim).unwrap(), first);
    ok(&["encode", "synth:tumble", "-c", "quant-delta", "-p", "bits=6", "-o", &anim, "--force"]);
    assert_ne!(std::fs::read(&anim).unwrap(), first);

    let pc2 = s.path("t.pc2");
    ok(&["decode", &anim, "-o", &pc2]);
    fails(&["decode", &anim, "-o", &pc2], &["t.pc2", "already exists", "--force"]);
    ok(&["decode", &anim, "-o", &pc2, "-f"]);
    ok(&["synth", "cylinder", "-o", &s.path("c.mdd")]);
    fails(&["synth", "cylinder", "-o", &s.path("c.mdd")], &["c.mdd", "--force"]);
    let csv = s.path("r.csv");
    std::fs::write(&csv, "keep").unwrap();
    fails(&["sweep", "synth:tumble", "-c", "quant-delta", "--points", "1", "--csv", &csv], &["r.csv", "--force"]);
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), "keep");
    let json = s.path("seg.json");
    std::fs::write(&json, "keep").unwrap();
    fails(&["inspect", "synth:tumble", "--json", &json], &["seg.json", "--force"]);
    assert_eq!(std::fs::read_to_string(&json).unwrap(), "keep");
    assert!(!has_temporary(&s.0));
}

#[test]
fn decode_writes_the_topology_obj_only_when_asked() {
    let s = Scratch::new("companion");
    let anim = s.path("s.anim");
    ok(&["encode", "synth:flag", "-c", "quant-delta", "-o", &anim]);
    let obj = s.path("e.obj");
    std::fs::write(&obj, "v 0 0 0\n").unwrap();
    // e.obj is not the decoded mesh, and a later read of e.pc2 would pair it: refused.
    fails(&["decode", &anim, "-o", &s.path("e.pc2"), "-f"], &["e.pc2", "e.obj", "--topology-obj"]);
    assert!(!Path::new(&s.path("e.pc2")).exists());
    assert_eq!(std::fs::read_to_string(&obj).unwrap(), "v 0 0 0\n", "e.obj was never named: untouched");
    // Asked for, an existing companion is still not clobbered without --force.
    fails(&["decode", &anim, "-o", &s.path("e.mdd"), "--topology-obj"], &["e.obj", "--force"]);
    assert!(!Path::new(&s.path("e.mdd")).exists(), "nothing is written when one output is refused");
    ok(&["decode", &anim, "-o", &s.path("f.pc2"), "--topology-obj"]);
    let back = animcodec::formats::read_animation(Path::new(&s.path("f.pc2")), &Default::default()).unwrap();
    assert_eq!(back.frame_count(), animcodec::synth::SynthSize::Small.frames());
}

#[test]
fn obj_sequence_folders_with_other_frames_need_force_which_removes_stale_frames() {
    let s = Scratch::new("stale");
    let anim = s.path("s.anim");
    ok(&["encode", "synth:flag", "-c", "quant-delta", "-o", &anim]);
    let frames = animcodec::synth::SynthSize::Small.frames();
    let dir = s.0.join("st");
    std::fs::create_dir(&dir).unwrap();
    for t in 0..60 {
        std::fs::write(dir.join(format!("frame_{t:04}.obj")), "v 0 0 0\n").unwrap();
    }
    let st = format!("{}/", dir.display());
    fails(&["decode", &anim, "-o", &st], &["st", "60 frame files", "--force"]);
    assert_eq!(names(&dir).len(), 60);
    ok(&["decode", &anim, "-o", &st, "--force"]);
    assert_eq!(names(&dir).len(), frames, "stale frames removed");
    let e = ok_json(&["encode", dir.to_str().unwrap(), "-c", "quant-delta", "-o", &s.path("b.anim"), "--json"]);
    assert_eq!(e["frames"], frames);
    // The same for a NAME.obj target: older NAME_NNNN.obj beyond the new sequence are stale.
    for t in 0..45 {
        std::fs::write(s.0.join(format!("walk_{t:04}.obj")), "v 0 0 0\n").unwrap();
    }
    fails(&["decode", &anim, "-o", &s.path("walk.obj")], &["45 frame files"]);
    ok(&["decode", &anim, "-o", &s.path("walk.obj"), "-f"]);
    assert_eq!(names(&s.0).iter().filter(|n| n.starts_with("walk_")).count(), frames);
    assert!(!has_temporary(&s.0) && !has_temporary(&dir));
}

#[test]
fn frame_number_placeholders_work() {
    let s = Scratch::new("placeholders");
    let anim = s.path("s.anim");
    ok(&["encode", "synth:tumble", "-c", "quant-delta", "-o", &anim]);
    let frames = animcodec::synth::SynthSize::Small.frames();
    ok(&["decode", &anim, "-o", &s.path("seq/f_{}.obj")]);
    let seq = names(&s.0.join("seq"));
    assert_eq!(seq.len(), frames);
    assert_eq!(seq[0], "f_0000.obj");
    assert_eq!(seq[frames - 1], format!("f_{:04}.obj", frames - 1));
    ok(&["decode", &anim, "-o", &s.path("h/g_###.obj")]);
    let h = names(&s.0.join("h"));
    assert_eq!((h.len(), h[0].as_str()), (frames, "g_000.obj"));
    // The same pattern reads the sequence back.
    let e = ok_json(&["encode", &s.path("seq/f_{}.obj"), "-c", "quant-delta", "-o", &s.path("b.anim"), "--json"]);
    assert_eq!(e["frames"], frames);
}

#[test]
fn info_verifies_every_packet_checksum() {
    let s = Scratch::new("info-crc");
    let out = s.path("t.anim");
    ok(&["encode", "synth:tumble", "-c", "quant-delta", "-p", "block=8", "-o", &out]);
    let text = ok(&["info", &out]);
    assert!(text.contains("verified") && text.contains("checksums OK"), "{text}");
    let v = ok_json(&["info", &out, "--json"]);
    let packets = v["packets"].as_array().unwrap();
    assert_eq!(v["verified"]["packet_checksums"], packets.len());
    // Flip one payload byte of the third packet (17 bytes of framing precede the payload).
    let offset = packets[2]["offset"].as_u64().unwrap() as usize + 17 + 1;
    let mut bytes = std::fs::read(&out).unwrap();
    bytes[offset] ^= 0x40;
    let bad = s.path("bad.anim");
    std::fs::write(&bad, &bytes).unwrap();
    fails(&["info", &bad], &["bad.anim", "packet 2", "checksum"]);
    fails(&["info", &bad, "--json"], &["packet 2", "checksum"]);
}

#[test]
fn repeated_parameters_and_auto_with_parameters_are_explained() {
    let s = Scratch::new("params");
    let out = s.path("x.anim");
    fails(
        &["encode", "synth:flag", "-c", "quant-delta", "-p", "bits=8", "-p", "bits=12", "-o", &out],
        &["'bits'", "more than once"],
    );
    fails(&["inspect", "synth:flag", "-p", "w=3", "-p", "w=4"], &["'w'", "more than once"]);
    // Without a target, -c auto aims at the default quality; it takes no -p.
    fails(&["encode", "synth:flag", "-c", "auto", "-p", "bits=8", "-o", &out], &["auto", "-p"]);
    assert!(!Path::new(&out).exists());
}

#[test]
fn limit_errors_name_bytes_not_frames() {
    let s = Scratch::new("limits");
    let out = s.path("t.anim");
    ok(&["encode", "synth:flag", "-c", "quant-delta", "-o", &out]);
    // A whole-animation decode (to OBJ) is charged the whole animation; a streamed one (to PC2)
    // one packet at a time, so it needs a smaller budget to fail.
    let e = fails(&["--max-memory", "100K", "decode", &out, "-o", &s.path("t.obj")], &["bytes", "102400", "limit"]);
    assert!(!e.contains("frame_count"), "{e}");
    let e = fails(&["--max-memory", "4K", "decode", &out, "-o", &s.path("t.pc2")], &["bytes", "4096", "limit"]);
    assert!(!e.contains("frame_count"), "{e}");
    assert!(!s.0.join("t.pc2").exists(), "a refused decode leaves no file");
}

#[test]
fn permission_errors_say_permission_denied() {
    use std::os::unix::fs::PermissionsExt;
    let s = Scratch::new("perm");
    let dir = s.0.join("locked");
    std::fs::create_dir(&dir).unwrap();
    let src = dir.join("a.pc2");
    ok(&["synth", "flag", "-o", src.to_str().unwrap()]);
    std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o000)).unwrap();
    let readable = std::fs::metadata(&src).is_ok();
    if readable {
        eprintln!("note: running as root, permissions are not enforced: checking the wording only");
    } else {
        fails(&["encode", src.to_str().unwrap(), "-c", "quant-delta", "-o", &s.path("x.anim")], &["permission denied"]);
        fails(&["info", src.to_str().unwrap()], &["permission denied"]);
    }
    std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o755)).unwrap();
    let e = std::io::Error::from(std::io::ErrorKind::PermissionDenied);
    let text = codec_core::Error::io("cannot open x.pc2", e).to_string();
    assert_eq!(text, "cannot open x.pc2: permission denied");
}

/// Every CLI failure path that a user can reach with bad arguments or bad files: exit 1, one
/// `error:` line, never the text of a panic.
#[test]
fn no_failure_path_prints_panic_text() {
    let s = Scratch::new("failures");
    let anim = s.path("ok.anim");
    ok(&["encode", "synth:flag", "-c", "sac", "-o", &anim]);
    let junk = s.path("junk.anim");
    std::fs::write(&junk, b"not a stream").unwrap();
    let mut truncated = std::fs::read(&anim).unwrap();
    truncated.truncate(truncated.len() / 2);
    let cut = s.path("cut.anim");
    std::fs::write(&cut, &truncated).unwrap();
    let bad_glb = s.path("bad.glb");
    std::fs::write(&bad_glb, b"glTF\x02\0\0\0\x10\0\0\0garbage!").unwrap();
    let bad_gltf = s.path("bad.gltf");
    std::fs::write(
        &bad_gltf,
        br#"{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":99999}}]}]}"#,
    )
    .unwrap();
    let bad_node = s.path("node.gltf");
    std::fs::write(
        &bad_node,
        br#"{"asset":{"version":"2.0"},"animations":[{"channels":[{"sampler":0,"target":{"node":5000,"path":"weights"}}],"samplers":[{"input":0,"output":0}]}]}"#,
    )
    .unwrap();
    let bad_pc2 = s.path("bad.pc2");
    std::fs::write(&bad_pc2, b"POINTCACHE2\0garbage").unwrap();
    let bad_mdd = s.path("bad.mdd");
    std::fs::write(&bad_mdd, [0xFFu8; 16]).unwrap();
    let bad_obj = s.path("bad.obj");
    std::fs::write(&bad_obj, "v 1 2\nf 1 2 3\n").unwrap();
    let out = s.path("out.anim");
    let missing = s.path("missing.pc2");
    let (x_pc2, x_xyz, m_xyz, t_pc2, y_pc2) =
        (s.path("x.pc2"), s.path("x.xyz"), s.path("m.xyz"), s.path("t.pc2"), s.path("y.pc2"));
    let cases: Vec<Vec<&str>> = vec![
        vec!["encode", "synth:flag", "-c", "nope", "-o", &out],
        vec!["encode", "synth:flag", "-c", "auto", "-p", "bits=8", "-o", &out],
        vec!["encode", "synth:flag", "-c", "hosvd", "-p", "ss=7", "-o", &out],
        vec!["encode", &missing, "-c", "quant-delta", "-o", &out],
        vec!["encode", &bad_glb, "-c", "quant-delta", "-o", &out],
        vec!["encode", &bad_gltf, "-c", "quant-delta", "-o", &out],
        vec!["encode", &bad_node, "-c", "quant-delta", "-o", &out],
        vec!["encode", &bad_pc2, "-c", "quant-delta", "-o", &out],
        vec!["encode", &bad_mdd, "-c", "quant-delta", "-o", &out],
        vec!["encode", &bad_obj, "-c", "quant-delta", "-o", &out],
        vec!["encode", "synth:flag:1x1x1", "-c", "quant-delta", "-o", &out],
        vec!["encode", "synth:flag", "-c", "quant-delta", "--target", "kg=0.000001", "--refine", "0", "-o", &out],
        vec!["decode", &junk, "-o", &x_pc2],
        vec!["decode", &cut, "-o", &x_pc2],
        vec!["decode", &anim, "-o", &x_xyz],
        vec!["decode", &anim, "-o", &anim],
        vec!["info", &junk],
        vec!["info", &cut],
        vec!["eval", &anim, &junk],
        vec!["eval", &anim, "synth:tumble"],
        vec!["sweep", &bad_gltf],
        vec!["sweep", "synth:flag", "-c", "nope"],
        vec!["inspect", &bad_glb],
        vec!["inspect", "synth:flag", "--frame", "999"],
        vec!["inspect", "synth:flag", "--mesh", &m_xyz],
        vec!["synth", "teapot", "-o", &t_pc2],
        vec!["--max-memory", "1K", "decode", &anim, "-o", &y_pc2],
        vec!["--max-memory", "1K", "info", &anim],
    ];
    for args in &cases {
        let o = animcodec(args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "animcodec {args:?}: expected exit 1, stderr: {err}");
        assert!(!err.contains("panicked") && !err.contains("RUST_BACKTRACE"), "animcodec {args:?}: {err}");
        assert!(err.starts_with("error: ") && err.lines().count() == 1, "animcodec {args:?}: {err}");
        assert!(!has_debug_value(&err), "animcodec {args:?}: Debug value in {err}");
    }
    assert!(!Path::new(&out).exists());
}

/// hosvd on a 1-frame input (a single OBJ, a PC2 of one frame, a GLB without animation) used to
/// exit 0 with KG above 60 %: now it is refused with what would work.
#[test]
fn hosvd_refuses_a_one_frame_animation_with_advice() {
    let s = Scratch::new("hosvd-one-frame");
    let anim = s.path("f.anim");
    ok(&["encode", "synth:flag", "-c", "quant-delta", "-p", "bits=20", "-o", &anim]);
    ok(&["decode", &anim, "-o", &s.path("seq/")]);
    let one = s.0.join("seq").join("frame_0000.obj");
    let out = s.path("h.anim");
    fails(
        &["encode", one.to_str().unwrap(), "-c", "hosvd", "-o", &out],
        &["hosvd", "1 frame", "ss=0.9", "quant-delta"],
    );
    assert!(!Path::new(&out).exists());
    // Every other codec codes it.
    for codec in ["quant-delta", "pca-aoi", "sac", "stseg"] {
        ok(&["encode", one.to_str().unwrap(), "-c", codec, "-f", "-o", &out]);
    }
}

/// Runs the binary in `dir` (for relative spellings such as `./o.txt` and `-`).
fn animcodec_in(dir: &Path, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_animcodec")).current_dir(dir).args(args).output().unwrap()
}

/// Asserts a one-line clean error (exit 1, `error:` line, no panic text) mentioning `needles`.
fn assert_clean_error(o: &std::process::Output, needles: &[&str]) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(1), "expected exit 1: {err}");
    assert!(!err.contains("panicked") && err.starts_with("error: ") && err.lines().count() == 1, "{err}");
    for n in needles {
        assert!(err.contains(n), "stderr does not mention '{n}': {err}");
    }
}

/// `decode a.anim -o ./ -f` must not delete the folder's other `*.obj` files.
#[test]
fn an_obj_sequence_never_touches_files_outside_its_name_pattern() {
    let s = Scratch::new("obj-pattern");
    let anim = s.path("a.anim");
    ok(&["encode", "synth:tumble", "-c", "quant-delta", "-o", &anim]);
    let frames = animcodec::synth::SynthSize::Small.frames();
    // Another animation (pcow.pc2 + its topology pcow.obj) and unrelated OBJ files.
    ok(&["synth", "flag", "-o", &s.path("pcow.pc2")]);
    let foreign = ["notes.obj", "README.OBJ"];
    for f in foreign {
        std::fs::write(s.0.join(f), format!("# {f}\n")).unwrap();
    }
    let before = |names: &[&str]| names.iter().map(|n| std::fs::read(s.0.join(n)).unwrap()).collect::<Vec<_>>();
    let kept = ["notes.obj", "README.OBJ", "pcow.obj", "pcow.pc2", "a.anim"];
    let snapshot = before(&kept);
    // A folder target reads back every .obj in it: refused, even with --force, naming them.
    for args in [vec!["decode", &anim, "-o", "./", "-f"], vec!["decode", &anim, "-o", "./"]] {
        assert_clean_error(&animcodec_in(&s.0, &args), &["README.OBJ", "never removed", "frame_{}.obj"]);
    }
    assert_eq!(before(&kept), snapshot, "no file of another name was touched");
    assert_eq!(names(&s.0).len(), kept.len(), "and no new file");
    // A pattern in the same folder writes its frames beside them; a rerun with --force replaces
    // its own frames and removes only its stale ones (a longer older run of the same pattern).
    std::fs::write(s.0.join(format!("frame_{:04}.obj", frames + 3)), "stale").unwrap();
    let near_misses = ["frame_12.obj", "Frame_0001.obj", "frame_0001.OBJ", "frame_0001.obj.bak", "frame_x0001.obj"];
    for f in near_misses {
        std::fs::write(s.0.join(f), "not ours").unwrap();
    }
    let pattern = s.path("frame_{}.obj");
    let stale = format!("frame_{:04}.obj", frames + 3);
    fails(&["decode", &anim, "-o", &pattern], &[&stale, "of this sequence", "--force"]);
    ok(&["decode", &anim, "-o", &pattern, "-f"]);
    ok(&["decode", &anim, "-o", &pattern, "-f"]);
    assert!(!s.0.join(&stale).exists(), "the stale frame of this pattern is removed");
    for f in near_misses {
        assert_eq!(std::fs::read_to_string(s.0.join(f)).unwrap(), "not ours", "{f} is not of the pattern");
    }
    assert_eq!(before(&kept), snapshot);
    let ours = names(&s.0).iter().filter(|n| n.starts_with("frame_") && n.ends_with(".obj") && n.len() == 14).count();
    assert_eq!(ours, frames);
    // A plain NAME.obj target (pcow.obj → pcow_0000.obj, …) never touches pcow.obj itself.
    ok(&["decode", &anim, "-o", &s.path("pcow.obj"), "-f"]);
    assert_eq!(before(&kept), snapshot, "the topology OBJ of pcow.pc2 is kept");
    assert_eq!(names(&s.0).iter().filter(|n| n.starts_with("pcow_")).count(), frames);
    // In a folder of its own, a folder target works as before.
    ok(&["decode", &anim, "-o", &s.path("seq/")]);
    assert_eq!(names(&s.0.join("seq")).len(), frames);
    assert!(!has_temporary(&s.0));
}

/// A failed command leaves its output as it was (nothing is replaced before the work succeeds).
#[test]
fn a_failed_command_leaves_the_old_output_and_no_new_file() {
    let s = Scratch::new("validated");
    let input = s.path("flag.pc2");
    ok(&["synth", "flag", "-o", &input]);
    let (anim, glb) = (s.path("out.anim"), s.path("out.glb"));
    for (out, args) in [
        (&anim, vec!["encode", &input, "-c", "quant-delta", "--eval", "--sted-radius", "0", "-o", &anim]),
        (&glb, vec!["export", &input, "-o", &glb, "--sted-radius", "0"]),
        (&anim, vec!["encode", &input, "-c", "quant-delta", "--eval", "--sted-dt", "1e-300", "-o", &anim]),
    ] {
        for force in [true, false] {
            let mut args = args.clone();
            if force {
                std::fs::write(out, "old").unwrap();
                args.push("-f");
            } else {
                std::fs::remove_file(out).unwrap();
            }
            let o = animcodec(&args);
            assert_clean_error(&o, &["sted"]);
            if force {
                assert_eq!(std::fs::read_to_string(out).unwrap(), "old", "{args:?}");
            } else {
                assert!(!Path::new(out).exists(), "{args:?} left a new file");
            }
        }
    }
    // An export whose read-back fails (a stream at 1e-45 fps: key times overflow) replaces
    // nothing. If a frame-rate range check refuses such a stream up front, that is fine too.
    let tiny = s.path("tiny.anim");
    if animcodec(&["encode", &input, "-c", "quant-delta", "--fps", "1e-45", "-o", &tiny]).status.success() {
        std::fs::write(&glb, "old").unwrap();
        let o = animcodec(&["export", &tiny, "-o", &glb, "-f"]);
        assert_clean_error(&o, &["out.glb", "does not read back"]);
        assert_eq!(std::fs::read_to_string(&glb).unwrap(), "old");
        // decode to a glTF reads it back too before writing it.
        let o = animcodec(&["decode", &tiny, "-o", &glb, "-f"]);
        assert_clean_error(&o, &["out.glb", "does not read back"]);
        assert_eq!(std::fs::read_to_string(&glb).unwrap(), "old");
        assert_eq!(stderr(&o).matches("out.glb").count(), 1, "the file is named once");
    }
    assert!(!has_temporary(&s.0));
}

/// One command's outputs are replaced together or not at all.
#[test]
fn a_commands_outputs_are_committed_together_or_not_at_all() {
    let s = Scratch::new("together");
    let (json, csv, html) = (s.path("o.json"), s.path("o.csv"), s.path("r.html"));
    for f in [&json, &csv] {
        std::fs::write(f, "old").unwrap();
    }
    // The HTML report fails after the JSON and CSV are built (no such ladder point measured).
    let args = ["sweep", "synth:tumble", "-c", "hosvd", "--points", "2", "--json", &json, "--csv", &csv];
    let mut failing = args.to_vec();
    failing.extend(["--html", &html, "--view-points", "hosvd:9", "-f"]);
    assert_clean_error(&animcodec(&failing), &["hosvd:9"]);
    for f in [&json, &csv] {
        assert_eq!(std::fs::read_to_string(f).unwrap(), "old", "{f} was replaced by a failed run");
    }
    assert!(!Path::new(&html).exists() && !has_temporary(&s.0));
    let mut good = args.to_vec();
    good.push("-f");
    ok(&good);
    assert!(std::fs::read_to_string(&json).unwrap().starts_with('{'));
    assert!(std::fs::read_to_string(&csv).unwrap().starts_with("codec,"));
}

/// Two outputs on one path (`sweep … --json o.txt --csv o.txt`) are refused: one would
/// silently replace the other.
#[test]
fn two_outputs_on_one_path_are_refused_in_any_spelling() {
    let s = Scratch::new("one-path");
    std::fs::write(s.0.join("o.txt"), "old").unwrap();
    std::os::unix::fs::symlink("o.txt", s.0.join("link.txt")).unwrap();
    std::fs::hard_link(s.0.join("o.txt"), s.0.join("hard.txt")).unwrap();
    std::fs::create_dir(s.0.join("sub")).unwrap();
    let sweep = |json: &str, csv: &str| {
        animcodec_in(
            &s.0,
            &["sweep", "synth:tumble", "-c", "quant-delta", "--points", "1", "-f", "--json", json, "--csv", csv],
        )
    };
    for (a, b) in [
        ("o.txt", "o.txt"),
        ("o.txt", "./o.txt"),
        ("o.txt", "sub/../o.txt"),
        ("link.txt", "o.txt"),
        ("o.txt", "hard.txt"),
        ("new.txt", "./new.txt"),
    ] {
        let start = Instant::now();
        assert_clean_error(&sweep(a, b), &["refusing to write", b]);
        assert!(start.elapsed() < Duration::from_secs(5), "refused before any work");
    }
    assert_eq!(std::fs::read_to_string(s.0.join("o.txt")).unwrap(), "old");
    assert!(!s.0.join("new.txt").exists());
    // inspect's two outputs likewise.
    let o = animcodec_in(&s.0, &["inspect", "synth:tumble", "--json", "m.obj", "--mesh", "./m.obj"]);
    assert_clean_error(&o, &["m.obj"]);
    assert_eq!(names(&s.0), ["hard.txt", "link.txt", "o.txt", "sub"]);
}

/// `--csv -` must not write a file named `-`: `-` is stdout where the help says so
/// (`--json -`), and refused as a file name everywhere else.
#[test]
fn a_dash_is_stdout_or_refused_never_a_file() {
    let s = Scratch::new("dash");
    ok(&["encode", "synth:tumble", "-c", "quant-delta", "-o", &s.path("a.anim")]);
    for args in [
        vec!["sweep", "synth:tumble", "-c", "quant-delta", "--points", "1", "--csv", "-"],
        vec!["sweep", "synth:tumble", "-c", "quant-delta", "--points", "1", "--plot", "-"],
        vec!["decode", "a.anim", "-o", "-"],
        vec!["encode", "synth:tumble", "-c", "quant-delta", "-o", "-"],
        vec!["view", "synth:tumble", "a.anim", "-o", "-"],
    ] {
        assert_clean_error(&animcodec_in(&s.0, &args), &["'-'", "./-"]);
    }
    let o = animcodec_in(&s.0, &["sweep", "synth:tumble", "-c", "quant-delta", "--points", "1", "--json", "-"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(serde_json::from_slice::<serde_json::Value>(&o.stdout).is_ok(), "--json - prints the JSON");
    assert_eq!(names(&s.0), ["a.anim"], "no file named '-'");
}

/// `decode -o X.pc2` beside a stale `X.obj` of another mesh with the same vertex count must
/// not let a later read pair the wrong triangles silently.
#[test]
fn a_cache_is_never_paired_with_another_meshs_obj() {
    let s = Scratch::new("pairing");
    let anim = s.path("a.anim");
    ok(&["encode", "synth:flag", "-c", "quant-delta", "-o", &anim]);
    // X.obj: the flag's vertices with other triangles.
    ok(&["synth", "flag", "-o", &s.path("flag.pc2")]);
    let flag_obj = std::fs::read_to_string(s.path("flag.obj")).unwrap();
    let other: String =
        flag_obj.lines().filter(|l| !l.starts_with("f ")).map(|l| format!("{l}\n")).collect::<String>() + "f 1 2 3\n";
    std::fs::write(s.path("X.obj"), &other).unwrap();
    for ext in ["pc2", "mdd"] {
        let out = s.path(&format!("X.{ext}"));
        assert_clean_error(
            &animcodec(&["decode", &anim, "-o", &out, "-f"]),
            &["X.obj", "other triangles", "--topology-obj"],
        );
        assert!(!Path::new(&out).exists());
    }
    assert_eq!(std::fs::read_to_string(s.path("X.obj")).unwrap(), other);
    // Written with its topology, the pair is right; then the OBJ matches and needs no flag.
    ok(&["decode", &anim, "-o", &s.path("X.pc2"), "--topology-obj", "-f"]);
    ok(&["decode", &anim, "-o", &s.path("X.pc2"), "-f"]);
    let back = animcodec::formats::read_animation(Path::new(&s.path("X.pc2")), &Default::default()).unwrap();
    let flag = animcodec::formats::read_animation(Path::new(&s.path("flag.pc2")), &Default::default()).unwrap();
    assert_eq!(back.triangles(), flag.triangles());
}

/// Metric parameters that would give STED NaN (`eval --sted-dt 1e-300`) or infinity
/// (`--sted-c 1e300`) are refused.
#[test]
fn metric_parameters_giving_nan_or_infinity_are_refused_everywhere() {
    let s = Scratch::new("sted-params");
    let input = s.path("t.pc2");
    ok(&["synth", "tumble", "-o", &input]);
    let anim = s.path("t.anim");
    ok(&["encode", &input, "-c", "quant-delta", "-o", &anim]);
    for (flag, value, field) in
        [("--sted-dt", "1e-300", "dt"), ("--sted-c", "1e300", "c"), ("--sted-dt", "1e300", "dt")]
    {
        let needles = ["sted", field, value];
        fails(&["eval", &input, &anim, flag, value], &needles);
        fails(&["sweep", &input, "-c", "quant-delta", "--points", "1", flag, value], &needles);
        fails(&["view", &input, &anim, "-o", &s.path("v.html"), flag, value], &needles);
        fails(&["export", &input, "-o", &s.path("e.glb"), flag, value], &needles);
        fails(&["encode", &input, "-c", "quant-delta", "--eval", "-o", &s.path("e.anim"), flag, value], &needles);
    }
    // The library refuses them too (StedParams::validate, called by every metrics entry point).
    let a = animcodec::formats::read_animation(Path::new(&input), &Default::default()).unwrap();
    for p in [
        animcodec::metrics::StedParams { dt: 1e-300, ..Default::default() },
        animcodec::metrics::StedParams { c: 1e300, ..Default::default() },
    ] {
        let e =
            animcodec::metrics::evaluate(&a, &a, &animcodec::metrics::EvalOptions { sted: p, ..Default::default() })
                .unwrap_err();
        assert!(e.to_string().contains("sted"), "{e}");
        assert!(animcodec::metrics::sted(&a, &a, &p).is_err());
    }
    assert_eq!(names(&s.0), ["t.anim", "t.obj", "t.pc2"], "no output of a refused command");
}
