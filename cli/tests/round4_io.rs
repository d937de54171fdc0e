//! Input and output safety, one test per reproducer of ../shared/probe-round4 (its inputs
//! built here):
//! - gltf-buffer-overwrite: every file a command reads (a `.gltf`'s external buffer, in any
//!   spelling) is one of its inputs, which no output replaces, even with `--force`;
//! - misc (synth): `synth -o a.mdd -f` does not replace an `a.obj` that is not its own;
//! - misc (USD depth): the nesting error states the levels and prims it counted;
//! - usd-deepnames, gltf-memory: long prim paths, inline data: URIs and instanced scenes are
//!   counted against `--max-memory` and refused by it, by name.

use std::path::Path;

use animcodec::formats::gltf_out::{encode_gltf, GltfCompression, GltfOptions};
use animcodec::synth::{self, SynthSize};
use base64::Engine as _;
use serde_json::Value;

mod common;
use common::*;

/// The synthetic flag exported as a GLB (uncompressed), split.
fn exported_flag() -> (Value, Vec<u8>) {
    let a = synth::by_name("flag", SynthSize::Small).unwrap();
    let options = GltfOptions { compression: GltfCompression::None, ..Default::default() };
    let (glb, _) = encode_gltf(&a, &options, true).unwrap();
    split_glb(&glb)
}

/// Writes `dir/NAME.gltf` whose buffer 0 is the external file `dir/BUFFER` (as the probe's
/// glb2gltf.py splits Horse.glb); returns the two paths.
fn split_gltf(s: &Scratch, name: &str, buffer: &str) -> (String, String) {
    let (mut json, bin) = exported_flag();
    json["buffers"][0]["uri"] = Value::from(buffer);
    std::fs::write(s.path(buffer), &bin).unwrap();
    std::fs::write(s.path(name), serde_json::to_vec(&json).unwrap()).unwrap();
    (s.path(name), s.path(buffer))
}

/// gltf-buffer-overwrite: `encode horse.gltf … -o horse.bin -f` replaced the model's geometry
/// with an `.anim`; so did `inspect --json`, `sweep --csv`, `view -o` and `export` (to a
/// buffer named `*.glb`). Every one is refused now, in every spelling of the buffer's path, and
/// the buffer is untouched.
#[test]
fn a_gltf_buffer_is_an_input_no_command_overwrites() {
    let s = Scratch::new("r4-buffer");
    let (gltf, bin) = split_gltf(&s, "horse.gltf", "horse.bin");
    let original = std::fs::read(&bin).unwrap();
    std::fs::create_dir(s.path("sub")).unwrap();
    std::os::unix::fs::symlink(&bin, s.path("link.bin")).unwrap();
    std::fs::hard_link(&bin, s.path("hard.bin")).unwrap();
    let spellings = [bin.clone(), s.path("sub/../horse.bin"), s.0.join(".").join("horse.bin").display().to_string()];
    let others = [s.path("link.bin"), s.path("hard.bin")];
    for out in spellings.iter().chain(&others) {
        fails(&["encode", &gltf, "-c", "quant-delta", "-p", "bits=8", "-o", out, "-f"], &["input", "horse.bin"]);
        assert_eq!(std::fs::read(&bin).unwrap(), original, "encode -o {out} -f changed the buffer");
    }
    let out = bin.as_str();
    let commands: [Vec<&str>; 3] = [
        vec!["inspect", &gltf, "--json", out, "-f"],
        vec!["sweep", &gltf, "-c", "quant-delta", "--points", "2", "--csv", out, "-f"],
        vec!["view", &gltf, "-o", out, "-f"],
    ];
    for args in &commands {
        fails(args, &["input", "horse.bin", "even with --force"]);
        assert_eq!(std::fs::read(&bin).unwrap(), original, "{args:?} changed the buffer");
    }
    // export: a buffer named *.glb.
    let (gltf2, glb_buffer) = split_gltf(&s, "horse2.gltf", "horse2.glb");
    let original2 = std::fs::read(&glb_buffer).unwrap();
    fails(&["export", &gltf2, "-o", &glb_buffer, "-f"], &["input", "horse2.glb"]);
    assert_eq!(std::fs::read(&glb_buffer).unwrap(), original2);
    // The model still reads, and an output elsewhere is still written.
    ok(&["encode", &gltf, "-c", "quant-delta", "-p", "bits=8", "-o", &s.path("ok.anim")]);
    ok(&["encode", &gltf2, "-c", "quant-delta", "-p", "bits=8", "-o", &s.path("ok2.anim")]);
}

/// The topology OBJ of a cache and the frames of an OBJ sequence are inputs too, whatever the
/// output's extension or spelling (before, only `.obj` outputs inside a pattern's folder were
/// checked).
#[test]
fn topology_objs_and_sequence_frames_are_inputs() {
    let s = Scratch::new("r4-frames");
    ok(&["synth", "flag", "-o", &s.path("c.pc2")]);
    let obj = std::fs::read(s.path("c.obj")).unwrap();
    std::fs::hard_link(s.path("c.obj"), s.path("c-topology.anim")).unwrap();
    fails(
        &["encode", &s.path("c.pc2"), "-c", "quant-delta", "-p", "bits=8", "-o", &s.path("c-topology.anim"), "-f"],
        &["input", "topology OBJ"],
    );
    assert_eq!(std::fs::read(s.path("c.obj")).unwrap(), obj);
    std::fs::create_dir(s.path("seq")).unwrap();
    ok(&["synth", "flag", "-o", &s.path("seq/f.obj")]);
    let frame = s.path("seq/f_0003.obj");
    let before = std::fs::read(&frame).unwrap();
    std::fs::hard_link(&frame, s.path("frame.anim")).unwrap();
    let pattern = s.path("seq/f_*.obj");
    fails(&["encode", &pattern, "-c", "quant-delta", "-p", "bits=8", "-o", &s.path("frame.anim"), "-f"], &["input"]);
    assert_eq!(std::fs::read(&frame).unwrap(), before);
}

/// misc: `synth flag -o a.mdd -f` replaced `a.obj`, the topology of an unrelated `a.pc2`
/// (which no longer read). `-f` names `a.mdd`; an `a.obj` that is not its own is refused.
#[test]
fn synth_force_never_replaces_another_caches_obj() {
    let s = Scratch::new("r4-synth");
    // a.pc2 + a.obj: another mesh (the cylinder), as the probe's off2 pair.
    ok(&["synth", "cylinder", "-o", &s.path("a.pc2")]);
    let a_obj = std::fs::read(s.path("a.obj")).unwrap();
    let e = fails(&["synth", "flag", "-o", &s.path("a.mdd"), "-f"], &["a.obj", "a.mdd", "another"]);
    assert!(e.contains("remove"), "{e}");
    assert_eq!(std::fs::read(s.path("a.obj")).unwrap(), a_obj, "a.obj must be untouched");
    assert!(!Path::new(&s.path("a.mdd")).exists(), "nothing is written when the companion is refused");
    ok(&["encode", &s.path("a.pc2"), "-c", "quant-delta", "-p", "bits=8", "-o", &s.path("z.anim")]);
    // The same with a hand-written OBJ (no animcodec comment), through the streamed writer.
    std::fs::write(s.path("b.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    fails(&["synth", "flag:4x4x3", "-o", &s.path("b.pc2"), "-f"], &["b.obj", "another"]);
    assert_eq!(std::fs::read_to_string(s.path("b.obj")).unwrap(), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    // Its own companion (written for this cache name) or the same mesh: replaced as before.
    ok(&["synth", "flag", "-o", &s.path("c.mdd")]);
    ok(&["synth", "flag", "--size", "medium", "-o", &s.path("c.mdd"), "-f"]);
    // c.obj now holds the medium flag: c.pc2 of the same mesh may replace it, of another not.
    fails(&["synth", "flag", "-o", &s.path("c.pc2"), "-f"], &["c.obj", "another mesh"]);
    ok(&["synth", "flag", "--size", "medium", "-o", &s.path("c.pc2"), "-f"]);
    let back = animcodec::formats::read_animation(Path::new(&s.path("c.pc2")), &Default::default()).unwrap();
    assert_eq!(back.vertex_count(), synth::by_name("flag", SynthSize::Medium).unwrap().vertex_count());
    // decode --topology-obj asks for the companion by name: --force replaces it.
    let anim = s.path("a.anim");
    ok(&["encode", "synth:flag", "-c", "quant-delta", "-o", &anim]);
    ok(&["decode", &anim, "-o", &s.path("b.pc2"), "--topology-obj", "-f"]);
}

/// misc: a layer nested 254 prims deep was refused as "nested more than 256 deep". The message
/// now states what was counted.
#[test]
fn the_usd_nesting_error_states_what_it_counted() {
    let s = Scratch::new("r4-depth");
    let tri = "[(0,0,0),(1,0,0),(0,1,0)]";
    let mesh = format!(
        "def Mesh \"m\"\n{{\n int[] faceVertexCounts=[3]\n int[] faceVertexIndices=[0,1,2]\n point3f[] \
         points.timeSamples = {{ 0: {tri} }}\n}}\n"
    );
    let layer = format!("#usda 1.0\n{}{mesh}{}", "def Xform \"x\"\n{\n".repeat(254), "}\n".repeat(254));
    let path = s.path("deep254.usda");
    std::fs::write(&path, layer).unwrap();
    let e = fails(
        &["encode", &path, "-c", "quant-delta", "-p", "bits=8", "-o", &s.path("d.anim")],
        &["257 levels", "limit of 256", "255 of them nested prims"],
    );
    assert!(!e.contains("more than 256 deep"), "{e}");
}

/// usd-deepnames: 250 nested prims with 80 000-character names (a 20 MB layer) held 2.5 GB
/// under `--max-memory 64M`: each prim cloned its whole path. Built smaller here (100 × 40 000,
/// 4 MB): the kept path is counted and refused by a budget below it, and read within one above.
#[test]
fn long_usd_prim_paths_are_counted_against_max_memory() {
    let s = Scratch::new("r4-deepnames");
    let name = "n".repeat(40_000);
    let tri = "[(0, 0, 0), (1, 0, 0), (0, 1, 0)]";
    let mesh = format!(
        "def Mesh \"m\"\n{{\n int[] faceVertexCounts = [3]\n int[] faceVertexIndices = [0, 1, 2]\n point3f[] \
         points.timeSamples = {{\n 0: {tri},\n 1: {tri},\n }}\n}}\n"
    );
    let mut layer = String::from("#usda 1.0\n(\n timeCodesPerSecond = 24\n)\n");
    for k in 0..100 {
        layer += &format!("def Xform \"{name}{k}\"\n{{\n");
    }
    layer += &mesh;
    layer += &"}\n".repeat(100);
    let path = s.path("deepnames.usda");
    std::fs::write(&path, &layer).unwrap();
    let out = s.path("o.anim");
    let e = fails(
        &["encode", &path, "-c", "quant-delta", "-p", "bits=12", "-o", &out, "--max-memory", "2M"],
        &["prim paths", "--max-memory"],
    );
    assert!(e.len() < 2000, "the message must not print the 4 MB path: {} bytes", e.len());
    ok(&["encode", &path, "-c", "quant-delta", "-p", "bits=12", "-o", &out, "--max-memory", "64M"]);
}

/// gltf-memory (c): a `.gltf` whose data: URI holds far more than its byteLength reached
/// 632 MB under `--max-memory 64M` (only byteLength was counted). The JSON text and the
/// decoded bytes count now, before decoding.
#[test]
fn a_data_uri_is_counted_before_it_is_decoded() {
    let s = Scratch::new("r4-datauri");
    let (mut json, mut bin) = exported_flag();
    bin.resize(bin.len() + 12_000_000, 0);
    let uri =
        format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bin));
    json["buffers"][0]["uri"] = Value::from(uri);
    let path = s.path("bigdata.gltf");
    std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    let out = s.path("o.anim");
    fails(
        &["encode", &path, "-c", "quant-delta", "-p", "bits=12", "-o", &out, "--max-memory", "8M"],
        &["--max-memory"],
    );
    // The decoded excess alone (12 MB beyond byteLength) is over a 40M budget that holds the
    // JSON text twice (2 × 16 MB).
    fails(
        &["encode", &path, "-c", "quant-delta", "-p", "bits=12", "-o", &out, "--max-memory", "40M"],
        &["data: URI", "--max-memory"],
    );
    ok(&["encode", &path, "-c", "quant-delta", "-p", "bits=12", "-o", &out, "--max-memory", "64M"]);
}

/// gltf-memory (a): a 276 KB GLB of 2 000 instances baked 305 MB, within the 1 GiB read
/// budget, and the default encode then held 2.04 GB for a minute. The read now counts what the
/// command will hold of the baked positions too, and the refusal names the size and the flag.
/// Scaled down here: 100 instances of the flag (11.5 MB baked) against --max-memory 64M.
#[test]
fn an_instanced_scene_counts_what_the_command_will_hold() {
    let s = Scratch::new("r4-instances");
    let (mut json, bin) = exported_flag();
    let n = 100;
    json["nodes"] =
        Value::from((0..n).map(|i| serde_json::json!({"mesh": 0, "translation": [i, 0, 0]})).collect::<Vec<_>>());
    json["scenes"] = serde_json::json!([{ "nodes": (0..n).collect::<Vec<_>>() }]);
    let path = s.path("inst.glb");
    std::fs::write(&path, join_glb(&json, &bin)).unwrap();
    let out = s.path("o.anim");
    let e = fails(
        &["encode", &path, "-c", "quant-delta", "-p", "bits=12", "-o", &out, "--max-memory", "64M"],
        &["inst.glb", "copies of the positions", "--max-memory"],
    );
    assert!(!Path::new(&out).exists(), "{e}");
    // Within the default budget it reads and encodes.
    ok(&["encode", &path, "-c", "quant-delta", "-p", "bits=12", "-o", &out]);
}
