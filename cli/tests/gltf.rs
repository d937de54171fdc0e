//! Independent checks of animcodec's glTF reader and writer against other people's code:
//! three.js (npm `three`, run under Node.js: GLTFLoader, AnimationMixer, CPU skinning) plays the
//! same files, and the Khronos glTF Validator (npm `gltf-validator`) checks what we write.
//! Both need `bash cli/tests/gltf/install.sh` (Node.js + `npm ci`); without it the tests skip
//! through `codec_core::testing::skip` (visible; a failure under `ANIMCODEC_REQUIRE_ALL=1`, as
//! in CI). The real animations come from `../shared/data` (skipped the same way when absent).

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use animcodec::formats::gltf::{self, GltfSelection};
use animcodec::formats::gltf_out::{encode_gltf, GltfCompression, GltfLayout, GltfOptions};
use animcodec::formats::{read_animation, ReadOptions};
use animcodec::synth::{self, SynthSize};
use codec_core::testing::skip;
use codec_core::Animation;
use common::{gltfpack, join_glb, node_packages, shared_data, split_glb, Scratch};
use serde_json::Value;

/// What three.js plays: animation `index` at `t0 + k / fps` for `frames` frames (0: at rest).
struct Sampling {
    index: usize,
    t0: f64,
    fps: f64,
    frames: usize,
}

/// Plays `file` with three.js as `sampling` says, the frames written to `out`.
fn three_play(tools: &Path, file: &Path, sampling: Sampling, out: &Path) -> Vec<f32> {
    three_play_env(tools, file, sampling, out, &[])
}

/// [`three_play`] with environment variables for play.mjs (`NORMALIZE_ROTATIONS=1`).
fn three_play_env(tools: &Path, file: &Path, sampling: Sampling, out: &Path, env: &[(&str, &str)]) -> Vec<f32> {
    let Sampling { index, t0, fps, frames } = sampling;
    let o = Command::new("node")
        .envs(env.iter().copied())
        .arg(tools.join("play.mjs"))
        .arg(file)
        .arg(out)
        .args(["--animation", &index.to_string(), "--t0", &t0.to_string(), "--fps", &fps.to_string()])
        .args(["--frames", &frames.to_string()])
        .output()
        .unwrap();
    assert!(o.status.success(), "three.js failed on {}: {}", file.display(), String::from_utf8_lossy(&o.stderr));
    let bytes = std::fs::read(out).unwrap();
    bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
}

/// Largest coordinate difference between our frames and three.js's, over the bounding-box
/// diagonal; and the number of frames compared.
fn relative_max_error(ours: &Animation, theirs: &[f32]) -> f64 {
    assert_eq!(ours.positions().len(), theirs.len(), "vertex or frame count differs from three.js");
    let worst = ours.positions().iter().zip(theirs).map(|(a, b)| (a - b).abs() as f64).fold(0.0, f64::max);
    worst / ours.bounding_box_diagonal()
}

/// The key range start of animation `index` (three.js and we sample at the same absolute times).
fn start_of(file: &Path, index: usize) -> f64 {
    gltf::list_animations(file).unwrap().get(index).map_or(0.0, |a| a.start)
}

/// An independent check: every RobotExpressive animation (node hierarchy, TRS
/// channels, 2 skins, morph targets) baked by our reader agrees with three.js's playback to
/// 1e-5 × the bounding-box diagonal on every frame; Horse.glb (morph targets) too.
#[test]
fn skinned_and_morph_playback_agrees_with_three_js() {
    let tools = match node_packages(&["three", "gltf-validator"]) {
        Ok(t) => t,
        Err(why) => return skip("skinned_and_morph_playback_agrees_with_three_js", &why),
    };
    let s = Scratch::new("gltf-three");
    let (mut checked, mut missing) = (0, 0);
    for rel in ["robot-expressive/RobotExpressive.glb", "horse-glb/Horse.glb"] {
        let Some(file) = shared_data(rel) else {
            // A visible skip (a failure under ANIMCODEC_REQUIRE_ALL); the other file still runs.
            skip("skinned_and_morph_playback_agrees_with_three_js", &format!("{rel} not found in ../shared/data"));
            missing += 1;
            continue;
        };
        for info in gltf::list_animations(&file).unwrap() {
            let read = ReadOptions { animation: Some(info.index.to_string()), ..Default::default() };
            let ours = read_animation(&file, &read).unwrap();
            let fps = ours.frame_rate() as f64;
            let theirs = three_play(
                &tools,
                &file,
                Sampling { index: info.index, t0: info.start, fps, frames: ours.frame_count() },
                &s.0.join("t.f32"),
            );
            let error = relative_max_error(&ours, &theirs);
            println!(
                "three.js agreement {rel} animation {} {:?}: {} frames × {} vertices at {fps} fps, max error {error:.3e} × diagonal",
                info.index,
                info.name.as_deref().unwrap_or(""),
                ours.frame_count(),
                ours.vertex_count()
            );
            assert!(error <= 1e-5, "{rel} animation {}: max error {error:e} × diagonal", info.index);
            checked += 1;
        }
    }
    println!("{checked} animations checked against three.js");
    // With a file present, zero would mean nothing was compared: not a pass.
    assert!(checked > 0 || missing == 2, "no animation was checked against three.js");
}

/// Validates files with the Khronos glTF Validator; one JSON report per file.
fn validate(tools: &Path, files: &[PathBuf]) -> Vec<Value> {
    let o = Command::new("node").arg(tools.join("validate.mjs")).args(files).output().unwrap();
    assert!(o.status.success(), "gltf-validator failed: {}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).lines().map(|l| serde_json::from_str(l).unwrap()).collect()
}

/// The animations our writer is checked on: a synthetic one, and Horse.glb and a
/// RobotExpressive animation as our reader bakes them (each absent one a visible skip of
/// `test`'s part on it).
fn writer_inputs(test: &str) -> Vec<(String, Animation)> {
    let mut out = vec![("flag".to_string(), synth::by_name("flag", SynthSize::Small).unwrap())];
    match shared_data("horse-glb/Horse.glb") {
        Some(horse) => out.push(("horse".into(), read_animation(&horse, &ReadOptions::default()).unwrap())),
        None => skip(&format!("{test} (Horse.glb)"), "not found in ../shared/data"),
    }
    match shared_data("robot-expressive/RobotExpressive.glb") {
        Some(robot) => {
            let read = ReadOptions { animation: Some("Wave".into()), ..Default::default() };
            out.push(("robot-wave".into(), read_animation(&robot, &read).unwrap()));
        }
        None => skip(&format!("{test} (RobotExpressive)"), "not found in ../shared/data"),
    }
    out
}

/// Every glTF variant we write: basis and frames layouts, .glb and .gltf, compressed
/// (KHR_mesh_quantization + EXT_meshopt_compression, the default, or KHR_meshopt_compression
/// with the vertex codec's version 1), quantized only, or plain; and the compressed basis with
/// the vertices welded and reordered, as `export` writes it.
fn variants() -> Vec<(String, GltfOptions, bool)> {
    let mut out = Vec::new();
    let all =
        [GltfCompression::Meshopt, GltfCompression::MeshoptKhr, GltfCompression::Quantized, GltfCompression::None];
    for compression in all {
        for layout in [GltfLayout::Basis, GltfLayout::Frames] {
            for glb in [true, false] {
                let options = GltfOptions { layout, target_kg: 0.5, compression, ..Default::default() };
                let name = format!(
                    "{}{}.{}",
                    if layout == GltfLayout::Basis { "basis" } else { "frames" },
                    match compression {
                        GltfCompression::Meshopt => "-meshopt",
                        GltfCompression::MeshoptKhr => "-meshopt-khr",
                        GltfCompression::Quantized => "-quantized",
                        GltfCompression::None => "",
                    },
                    if glb { "glb" } else { "gltf" }
                );
                out.push((name, options, glb));
            }
        }
    }
    // The rigid motion as node animation (parent node translation + rotation, LINEAR/slerp).
    let rigid = GltfOptions { target_kg: 0.5, rigid: Some(true), ..Default::default() };
    out.push(("basis-rigid-meshopt.glb".into(), rigid.clone(), true));
    out.push(("basis-rigid.gltf".into(), GltfOptions { compression: GltfCompression::None, ..rigid }, false));
    for (suffix, compression) in [("meshopt", GltfCompression::Meshopt), ("meshopt-khr", GltfCompression::MeshoptKhr)] {
        let options = GltfOptions { target_kg: 0.5, compression, reorder: true, ..Default::default() };
        out.push((format!("basis-reordered-{suffix}.glb"), options, true));
    }
    out
}

/// Everything we write passes the Khronos glTF Validator with 0 errors, and three.js plays it
/// as our own reader does (1e-5 × diagonal).
#[test]
fn written_gltf_is_valid_and_three_js_plays_it_like_our_reader() {
    let tools = match node_packages(&["three", "gltf-validator"]) {
        Ok(t) => t,
        Err(why) => return skip("written_gltf_is_valid_and_three_js_plays_it_like_our_reader", &why),
    };
    let s = Scratch::new("gltf-valid");
    let mut files = Vec::new();
    for (name, animation) in writer_inputs("written_gltf_is_valid_and_three_js_plays_it_like_our_reader") {
        for (suffix, options, glb) in variants() {
            let path = s.0.join(format!("{name}-{suffix}"));
            let (bytes, _) = encode_gltf(&animation, &options, glb).unwrap();
            std::fs::write(&path, bytes).unwrap();
            files.push((path, animation.frame_rate()));
        }
    }
    let paths: Vec<PathBuf> = files.iter().map(|(p, _)| p.clone()).collect();
    for report in validate(&tools, &paths) {
        println!("validator: {report}");
        assert_eq!(report["errors"], 0, "{report}");
    }
    for (path, fps) in &files {
        let ours = gltf::read_gltf(path, &GltfSelection::default()).unwrap();
        assert_eq!(ours.frame_rate(), *fps, "{}: the frame rate travels in extras", path.display());
        let theirs = three_play(
            &tools,
            path,
            Sampling { index: 0, t0: start_of(path, 0), fps: *fps as f64, frames: ours.frame_count() },
            &s.0.join("t.f32"),
        );
        let error = relative_max_error(&ours, &theirs);
        println!("three.js plays {}: max error {error:.3e} × diagonal against our reader", path.display());
        assert!(error <= 1e-5, "{}: {error:e}", path.display());
    }
}

/// The whole chain on RobotExpressive: list its animations, encode one by name
/// with hosvd, decode to a GLB; the GLB passes the validator and three.js plays it as our
/// reader does. The CLI parts run without Node.js; the checks needing it skip.
#[test]
fn robot_dance_encodes_decodes_to_a_valid_glb() {
    use common::{fails, ok, ok_json};
    let Some(robot) = shared_data("robot-expressive/RobotExpressive.glb") else {
        return skip("robot_dance_encodes_decodes_to_a_valid_glb", "RobotExpressive.glb not in ../shared/data");
    };
    let robot = robot.to_string_lossy().into_owned();
    let list = ok_json(&["list-animations", &robot, "--json"]);
    let names: Vec<&str> = list["animations"].as_array().unwrap().iter().map(|a| a["name"].as_str().unwrap()).collect();
    assert_eq!(names.len(), 14);
    assert!(names.contains(&"Dance") && names.contains(&"Wave"), "{names:?}");
    assert!(ok(&["info", &robot]).contains("Dance"));
    let s = Scratch::new("gltf-robot");
    let anim = s.path("d.anim");
    ok(&["encode", &robot, "--animation", "Dance", "-c", "hosvd", "-o", &anim]);
    let glb = s.path("d.glb");
    ok(&["decode", &anim, "-o", &glb]);
    // The decoded GLB against the baked input: `encode` without -p aims at the default
    // quality, measured on the stream; the GLB adds nothing beyond it.
    let e = ok_json(&["eval", &robot, &glb, "--animation", "Dance", "--json", "--no-hausdorff"]);
    let default_kg = animcodec::harness::DEFAULT_TARGET.bound(animcodec::harness::TargetMetric::Kg).unwrap();
    assert!(e["kg"].as_f64().unwrap() <= default_kg, "{e}");
    fails(&["encode", &robot, "--animation", "Moonwalk", "-c", "hosvd", "-o", &anim, "-f"], &["Moonwalk", "0 'Dance'"]);
    let tools = match node_packages(&["three", "gltf-validator"]) {
        Ok(t) => t,
        Err(why) => return skip("robot_dance_encodes_decodes_to_a_valid_glb (validator/three.js part)", &why),
    };
    let report = &validate(&tools, &[PathBuf::from(&glb)])[0];
    assert_eq!(report["errors"], 0, "{report}");
    let ours = gltf::read_gltf(Path::new(&glb), &GltfSelection::default()).unwrap();
    let theirs = three_play(
        &tools,
        Path::new(&glb),
        Sampling { index: 0, t0: 0.0, fps: ours.frame_rate() as f64, frames: ours.frame_count() },
        &s.0.join("t.f32"),
    );
    assert!(relative_max_error(&ours, &theirs) <= 1e-5);
}

// ---- Hostile glTF input (the reproducers of ../shared/probe-round3, built here from
// a synthetic export the way its glb.py builds them, so they run without ../shared) ----------

/// The synthetic flag (240 vertices, 40 frames) exported uncompressed (plain f32 accessors,
/// so a mutation hits the geometry itself), split for mutation.
fn exported_flag() -> (Animation, Value, Vec<u8>) {
    let a = synth::by_name("flag", SynthSize::Small).unwrap();
    let options = GltfOptions { compression: GltfCompression::None, ..Default::default() };
    let (glb, _) = encode_gltf(&a, &options, true).unwrap();
    let (json, bin) = split_glb(&glb);
    (a, json, bin)
}

/// The index of the first primitive's POSITION accessor.
fn position_accessor(j: &Value) -> usize {
    j["meshes"][0]["primitives"][0]["attributes"]["POSITION"].as_u64().unwrap() as usize
}

fn parse(glb: &[u8]) -> codec_core::Result<Animation> {
    gltf::parse_gltf_with(glb, None, "probe.glb", &GltfSelection::default())
}

/// The error of `result`, which must mention the file once and every one of `needles`.
fn refused(result: codec_core::Result<Animation>, needles: &[&str]) -> String {
    let e = match result {
        Ok(_) => panic!("accepted; expected an error naming {needles:?}"),
        Err(e) => e.to_string(),
    };
    for n in needles {
        assert!(e.contains(n), "'{e}' does not mention '{n}'");
    }
    e
}

/// stride.glb: a byteStride smaller than the element. The library refuses it naming the
/// accessor (before the gltf crate's reader, which asserts); the binary prints one clean line.
#[test]
fn a_stride_smaller_than_the_element_is_refused_by_name_without_panic_text() {
    let (_, mut j, bin) = exported_flag();
    let position = position_accessor(&j);
    let view = j["accessors"][position]["bufferView"].as_u64().unwrap() as usize;
    j["bufferViews"][view]["byteStride"] = 4.into();
    let glb = join_glb(&j, &bin);
    let accessor = format!("accessor {position}");
    refused(parse(&glb), &["probe.glb", "POSITION", &accessor, "byteStride 4", "smaller than the 12-byte element"]);
    let s = Scratch::new("gltf-stride");
    let path = s.path("stride.glb");
    std::fs::write(&path, &glb).unwrap();
    let e = common::fails(&["encode", &path, "-c", "quant-delta", "-o", &s.path("x.anim")], &["byteStride 4"]);
    assert_eq!(e.matches("stride.glb").count(), 1, "the file is named once: {e}");
}

/// Sparse indices out of range, UNSIGNED_BYTE positions without KHR_mesh_quantization,
/// asset.version 3.0: each refused naming the field (they were accepted silently).
#[test]
fn invalid_accessors_and_versions_are_refused_by_name() {
    let (a, j, bin) = exported_flag();
    assert_eq!(parse(&join_glb(&j, &bin)).unwrap().vertex_count(), a.vertex_count());
    // A sparse block on the positions replacing element 1 000 000 of 240.
    let (mut sparse, mut b) = (j.clone(), bin.clone());
    let at = b.len().next_multiple_of(4);
    b.resize(at, 0);
    b.extend(1_000_000u32.to_le_bytes());
    b.extend([0u8; 12]);
    let views = sparse["bufferViews"].as_array_mut().unwrap();
    views.push(serde_json::json!({"buffer": 0, "byteOffset": at, "byteLength": 4}));
    views.push(serde_json::json!({"buffer": 0, "byteOffset": at + 4, "byteLength": 12}));
    let n = views.len();
    sparse["buffers"][0]["byteLength"] = b.len().into();
    let position = position_accessor(&j);
    sparse["accessors"][position]["sparse"] = serde_json::json!({"count": 1,
        "indices": {"bufferView": n - 2, "componentType": 5125}, "values": {"bufferView": n - 1}});
    refused(parse(&join_glb(&sparse, &b)), &["probe.glb", "POSITION", "sparse indices", "1000000", "out of range"]);
    // The same block at a valid index is read: it moves vertex 7 (and only it) in every frame.
    b[at..at + 4].copy_from_slice(&7u32.to_le_bytes());
    let read = parse(&join_glb(&sparse, &b)).unwrap();
    let plain = parse(&join_glb(&j, &bin)).unwrap();
    for f in 0..plain.frame_count() {
        for v in 0..plain.vertex_count() {
            assert_eq!(read.vertex(f, v) == plain.vertex(f, v), v != 7, "frame {f} vertex {v}");
        }
    }
    // Integer positions need KHR_mesh_quantization.
    let mut bytes = j.clone();
    bytes["accessors"][position]["componentType"] = 5121.into();
    refused(parse(&join_glb(&bytes, &bin)), &["probe.glb", "POSITION", "KHR_mesh_quantization"]);
    bytes["extensionsUsed"] = serde_json::json!(["KHR_mesh_quantization"]);
    assert!(parse(&join_glb(&bytes, &bin)).is_ok(), "with the extension 8-bit positions are read");
    // Versions.
    for (version, field) in [("3.0", "asset.version"), ("2", "asset.version"), ("1.0", "asset.version")] {
        let mut v = j.clone();
        v["asset"]["version"] = version.into();
        refused(parse(&join_glb(&v, &bin)), &["probe.glb", field]);
    }
    let mut min = j.clone();
    min["asset"]["minVersion"] = "2.1".into();
    refused(parse(&join_glb(&min, &bin)), &["asset.minVersion"]);
    let mut minor = j.clone();
    minor["asset"]["version"] = "2.1".into();
    assert!(parse(&join_glb(&minor, &bin)).is_ok(), "2.x is read");
}

/// Geometry is read whatever texture and material extensions say (KHR_texture_basisu required,
/// a texture without `source`, images at paths that are never opened); extensions that change
/// the geometry and are not implemented are refused by name.
#[test]
fn geometry_is_read_whatever_appearance_extensions_are_required() {
    let (_, j, bin) = exported_flag();
    let plain = parse(&join_glb(&j, &bin)).unwrap();
    let mut textured = j.clone();
    textured["extensionsUsed"] = serde_json::json!(["KHR_texture_basisu", "KHR_materials_emissive_strength"]);
    textured["extensionsRequired"] = textured["extensionsUsed"].clone();
    textured["images"] = serde_json::json!([{"uri": "/dev/zero", "mimeType": "image/ktx2"}]);
    textured["textures"] = serde_json::json!([{"extensions": {"KHR_texture_basisu": {"source": 0}}}]);
    textured["materials"] = serde_json::json!([{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}},
        "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 2}}}]);
    textured["meshes"][0]["primitives"][0]["material"] = 0.into();
    let read = parse(&join_glb(&textured, &bin)).unwrap();
    assert_eq!(read.positions(), plain.positions());
    for extension in ["EXT_mesh_gpu_instancing", "KHR_animation_pointer", "VENDOR_new"] {
        let mut d = j.clone();
        d["extensionsUsed"] = serde_json::json!([extension]);
        d["extensionsRequired"] = serde_json::json!([extension]);
        refused(parse(&join_glb(&d, &bin)), &["probe.glb", extension, "may change the geometry"]);
    }
    // Draco is read (cli/tests/gltf_draco.rs); required by a file without Draco primitives, it
    // changes nothing.
    let mut d = j.clone();
    d["extensionsUsed"] = serde_json::json!(["KHR_draco_mesh_compression"]);
    d["extensionsRequired"] = serde_json::json!(["KHR_draco_mesh_compression"]);
    assert_eq!(parse(&join_glb(&d, &bin)).unwrap().positions(), plain.positions());
}

/// zero.glb and its variants: a buffer URI is followed only as a relative path inside the
/// glTF file's folder, to a regular file, when an accessor used for geometry reads it, and
/// only after its size is checked. Each case ends in well under a second.
#[cfg(unix)]
#[test]
fn external_buffers_are_read_only_inside_the_folder_and_only_when_used() {
    let (a, j, bin) = exported_flag();
    let s = Scratch::new("gltf-folder");
    let folder = s.0.join("model");
    std::fs::create_dir_all(folder.join("sub")).unwrap();
    std::fs::write(folder.join("buf.bin"), &bin).unwrap();
    std::fs::write(folder.join("sub/buf.bin"), &bin).unwrap();
    std::fs::write(s.0.join("outside.bin"), &bin).unwrap();
    std::os::unix::fs::symlink(s.0.join("outside.bin"), folder.join("escape.bin")).unwrap();
    std::os::unix::fs::symlink(folder.join("buf.bin"), folder.join("alias.bin")).unwrap();
    let fifo = std::process::Command::new("mkfifo").arg(folder.join("fifo")).status().is_ok_and(|s| s.success());
    let read = |doc: &Value| {
        let path = folder.join("m.gltf");
        std::fs::write(&path, serde_json::to_vec(doc).unwrap()).unwrap();
        let start = std::time::Instant::now();
        let result = gltf::read_gltf(&path, &GltfSelection::default());
        assert!(start.elapsed().as_secs_f64() < 5.0, "{:?}", start.elapsed());
        result
    };
    let with_uri = |uri: &str| {
        let mut d = j.clone();
        d["buffers"][0]["uri"] = uri.into();
        d
    };
    let expected = read(&with_uri("buf.bin")).unwrap();
    assert_eq!(expected.vertex_count(), a.vertex_count());
    for ok in ["sub/buf.bin", "./buf.bin", "alias.bin", "sub%2Fbuf.bin"] {
        assert_eq!(read(&with_uri(ok)).unwrap().positions(), expected.positions(), "{ok}");
    }
    // data: URIs still work.
    use base64::Engine as _;
    let inline =
        format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bin));
    assert_eq!(read(&with_uri(&inline)).unwrap().positions(), expected.positions());
    let mut refusals = vec![
        ("/dev/zero", "not a relative path"),
        ("../outside.bin", "not a relative path"),
        ("../../../../etc/hostname", "not a relative path"),
        ("sub/../../outside.bin", "not a relative path"),
        ("%2E%2E/outside.bin", "not a relative path"),
        ("file:///dev/zero", "unsupported URI scheme"),
        ("escape.bin", "outside the glTF file's folder"),
        ("sub", "not a regular file"),
        ("missing.bin", "cannot open"),
    ];
    if fifo {
        refusals.push(("fifo", "not a regular file"));
    } else {
        codec_core::testing::skip(
            "external_buffers_are_read_only_inside_the_folder_and_only_when_used (FIFO part)",
            "mkfifo failed",
        );
    }
    for (uri, why) in refusals {
        let e = refused(read(&with_uri(uri)), &["m.gltf", "buffer 0", why]);
        assert_eq!(e.matches("m.gltf").count(), 1, "{e}");
    }
    // A buffer shorter than its byteLength is refused before reading.
    let mut short = with_uri("buf.bin");
    short["buffers"][0]["byteLength"] = (bin.len() + 1).into();
    refused(read(&short), &["holds", "byteLength"]);
    // Buffers no geometry accessor reads are never opened: /dev/zero (2 GiB declared), the FIFO,
    // a path outside the folder.
    let mut unused = with_uri("buf.bin");
    for uri in ["/dev/zero", "fifo", "../../../../etc/hostname"] {
        unused["buffers"].as_array_mut().unwrap().push(serde_json::json!({"uri": uri, "byteLength": 1u64 << 31}));
    }
    assert_eq!(read(&unused).unwrap().positions(), expected.positions());
}

/// inst.glb: 20 000 instances of one mesh (4.8 M vertices × 40 frames = 2.3 GB of positions,
/// under every count limit) is refused by the read's memory budget before anything is baked
/// (the triangles included); the budget follows --max-memory.
#[test]
fn a_scene_of_many_instances_is_refused_by_the_memory_budget() {
    let (_, mut j, bin) = exported_flag();
    let nodes: Vec<Value> = (0..20_000).map(|i| serde_json::json!({"mesh": 0, "translation": [i, 0, 0]})).collect();
    j["nodes"] = nodes.into();
    j["scenes"] = serde_json::json!([{"nodes": (0..20_000).collect::<Vec<_>>()}]);
    let glb = join_glb(&j, &bin);
    let start = std::time::Instant::now();
    refused(parse(&glb), &["probe.glb", "memory", "baked positions", "--max-memory"]);
    println!("inst-like scene refused in {:?}", start.elapsed());
    // A caller's budget applies as well: the plain flag (460 KB of positions) within 1 MB, not 100 KB.
    let (_, plain, bin) = exported_flag();
    let plain = join_glb(&plain, &bin);
    let budget = |bytes| GltfSelection { memory_budget: Some(bytes), ..Default::default() };
    assert!(gltf::parse_gltf_with(&plain, None, "f.glb", &budget(1 << 20)).is_ok());
    refused(gltf::parse_gltf_with(&plain, None, "f.glb", &budget(100_000)), &["f.glb", "memory"]);
    // The binary: refused with the default budget; --max-memory sets it.
    let s = Scratch::new("gltf-inst");
    let path = s.path("inst.glb");
    std::fs::write(&path, &glb).unwrap();
    let start = std::time::Instant::now();
    common::fails(&["encode", &path, "-c", "quant-delta", "-o", &s.path("x.anim")], &["inst.glb", "memory"]);
    println!("animcodec encode inst.glb refused in {:?}", start.elapsed());
    let small = s.path("flag.glb");
    std::fs::write(&small, &plain).unwrap();
    let x = s.path("y.anim");
    common::fails(
        &["--max-memory", "100K", "encode", &small, "-c", "quant-delta", "-o", &x],
        &["flag.glb", "memory", "102400"],
    );
}

/// Frame rates outside 1e-3..=1e4 fps are refused where they enter; a file whose keys lie on
/// a 1e5 fps grid is refused by name instead of read back as one frame.
#[test]
fn frame_rates_are_bounded_at_every_entry_point() {
    let a = synth::by_name("flag", SynthSize::Small).unwrap();
    let (topology, positions, _) = a.clone().into_parts();
    for fps in [1e-45f32, 1e-4, 1e5] {
        let odd = Animation::new(topology.clone(), positions.clone(), fps).unwrap();
        let e = encode_gltf(&odd, &GltfOptions::default(), true).unwrap_err().to_string();
        assert!(e.contains("frame rate") && e.contains("outside"), "{fps}: {e}");
    }
    let plain = GltfOptions { compression: GltfCompression::None, rigid: Some(false), ..Default::default() };
    let (glb, _) = encode_gltf(&a, &plain, true).unwrap();
    for fps in [0.0, 1e-45, 2e4, f32::NAN] {
        let selection = GltfSelection { frame_rate: Some(fps), ..Default::default() };
        assert!(gltf::parse_gltf_with(&glb, None, "f.glb", &selection).is_err(), "{fps}");
    }
    // Keys 1e-5 s apart (the writer stores frame / fps): refused naming the rate; with a rate
    // given, sampled.
    let (mut j, mut bin) = split_glb(&glb);
    let input = j["animations"][0]["samplers"][0]["input"].as_u64().unwrap() as usize;
    let view = &j["bufferViews"][j["accessors"][input]["bufferView"].as_u64().unwrap() as usize];
    let offset = view["byteOffset"].as_u64().unwrap_or(0) as usize
        + j["accessors"][input]["byteOffset"].as_u64().unwrap_or(0) as usize;
    let keys = j["accessors"][input]["count"].as_u64().unwrap() as usize;
    for k in 0..keys {
        bin[offset + 4 * k..offset + 4 * k + 4].copy_from_slice(&(k as f32 * 1e-5).to_le_bytes());
    }
    j["accessors"][input]["max"] = serde_json::json!([(keys - 1) as f32 * 1e-5]);
    j["animations"][0]["extras"]["animcodec"]["fps"] = 1e5.into();
    let fast = join_glb(&j, &bin);
    refused(parse(&fast), &["probe.glb", "frames per second, above the highest supported rate 10000", "--fps"]);
    let selection = GltfSelection { frame_rate: Some(1e4), ..Default::default() };
    let sampled = gltf::parse_gltf_with(&fast, None, "f.glb", &selection).unwrap();
    assert!(sampled.frame_count() > 1);
    // The command line refuses such rates before reading anything.
    for fps in ["1e-45", "1e5"] {
        let o = common::animcodec(&["export", "synth:flag", "-o", "/nonexistent/x.glb", "--fps", fps]);
        let err = common::stderr(&o);
        assert!(!o.status.success() && err.contains("not a frame rate in"), "{fps}: {err}");
    }
}

/// Animation names are printed with control characters escaped (a name can carry ANSI escapes
/// and newlines); JSON output keeps them, escaped by JSON itself.
#[test]
fn animation_names_are_printed_escaped() {
    let (_, mut j, bin) = exported_flag();
    let hostile = "\u{1b}[31mred\nline";
    j["animations"][0]["name"] = hostile.into();
    let s = Scratch::new("gltf-names");
    let path = s.path("named.glb");
    std::fs::write(&path, join_glb(&j, &bin)).unwrap();
    let text = common::ok(&["list-animations", &path]);
    assert!(!text.contains('\u{1b}') && text.contains("\\u{1b}[31mred\\nline"), "{text}");
    assert_eq!(text.lines().count(), 2, "{text}");
    let json = common::ok_json(&["list-animations", &path, "--json"]);
    assert_eq!(json["animations"][0]["name"], hostile);
    let out = s.path("x.anim");
    let args = ["encode", path.as_str(), "--animation", "x\u{1b}[2J", "-c", "quant-delta", "-o", out.as_str()];
    let e = common::fails(&args, &["\\u{1b}[31mred\\nline", "x\\u{1b}[2J"]);
    assert!(!e.contains('\u{1b}'), "{e}");
}

/// Counts of EXT_meshopt_compression filters in a GLB's buffer views.
fn meshopt_filters(glb: &Path) -> std::collections::BTreeMap<String, usize> {
    let (json, _) = split_glb(&std::fs::read(glb).unwrap());
    let mut out = std::collections::BTreeMap::new();
    for view in json["bufferViews"].as_array().unwrap() {
        if let Some(filter) = view.pointer("/extensions/EXT_meshopt_compression/filter").and_then(Value::as_str) {
            *out.entry(filter.to_string()).or_insert(0) += 1;
        }
    }
    out
}

/// What `gltfpack -cc` writes (KHR_mesh_quantization, EXT_meshopt_compression with the
/// OCTAHEDRAL, QUATERNION and EXPONENTIAL filters) is read, and agrees with three.js's playback
/// of the same packed file to 1e-5 × the bounding-box diagonal: a synthetic export with normals
/// and rigid node motion, packed with -cc and with -cc -vpf (floating positions: EXPONENTIAL
/// on the geometry itself), and Horse.glb / RobotExpressive.glb when ../shared/data has them.
#[test]
fn what_gltfpack_writes_is_read_like_three_js_plays_it() {
    let test = "what_gltfpack_writes_is_read_like_three_js_plays_it";
    let tools = match node_packages(&["three", "gltf-validator"]) {
        Ok(t) if t.join("node_modules/gltfpack/cli.js").exists() => t,
        Ok(_) => {
            return codec_core::testing::skip(
                test,
                "npm package gltfpack not installed (bash cli/tests/gltf/install.sh)",
            )
        }
        Err(why) => return codec_core::testing::skip(test, &why),
    };
    let s = Scratch::new("gltf-pack");
    // The synthetic input: the tumbling flag's rigid motion as node animation, plus normals
    // (gltfpack encodes them with the octahedral filter; our reader never needs them).
    let a = synth::by_name("flag", SynthSize::Small).unwrap();
    let options =
        GltfOptions { compression: GltfCompression::None, rigid: Some(true), target_kg: 0.5, ..Default::default() };
    let (glb, _) = encode_gltf(&a, &options, true).unwrap();
    let (mut j, mut bin) = split_glb(&glb);
    let at = bin.len().next_multiple_of(4);
    bin.resize(at, 0);
    let v = a.vertex_count();
    for k in 0..v {
        let t = k as f32 * 0.37;
        for c in [t.cos() * 0.6, t.sin() * 0.6, 0.8f32] {
            bin.extend(c.to_le_bytes());
        }
    }
    j["bufferViews"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({"buffer": 0, "byteOffset": at, "byteLength": 12 * v}));
    let view = j["bufferViews"].as_array().unwrap().len() - 1;
    j["accessors"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({"bufferView": view, "componentType": 5126, "count": v, "type": "VEC3"}));
    let normals = j["accessors"].as_array().unwrap().len() - 1;
    let mesh = j["nodes"].as_array().unwrap().iter().find_map(|n| n["mesh"].as_u64()).unwrap() as usize;
    j["meshes"][mesh]["primitives"][0]["attributes"]["NORMAL"] = normals.into();
    j["buffers"][0]["byteLength"] = bin.len().into();
    let input = s.0.join("flag.glb");
    std::fs::write(&input, join_glb(&j, &bin)).unwrap();
    assert!(gltf::read_gltf(&input, &GltfSelection::default()).is_ok());

    let mut packed = Vec::new();
    for (name, args) in [("flag-cc.glb", &["-cc"][..]), ("flag-cc-vpf.glb", &["-cc", "-vpf"][..])] {
        let out = s.0.join(name);
        gltfpack(&tools, &input, &out, args);
        packed.push(out);
    }
    let filters = [meshopt_filters(&packed[0]), meshopt_filters(&packed[1])];
    println!("gltfpack filters: -cc {:?}, -cc -vpf {:?}", filters[0], filters[1]);
    for filter in ["OCTAHEDRAL", "QUATERNION"] {
        assert!(filters[0].contains_key(filter), "gltfpack -cc wrote no {filter} view: {:?}", filters[0]);
    }
    assert!(filters[1].contains_key("EXPONENTIAL"), "gltfpack -cc -vpf wrote no EXPONENTIAL view: {:?}", filters[1]);
    for rel in ["horse-glb/Horse.glb", "robot-expressive/RobotExpressive.glb"] {
        match shared_data(rel) {
            Some(file) => {
                let out = s.0.join(Path::new(rel).file_name().unwrap());
                gltfpack(&tools, &file, &out, &["-cc"]);
                packed.push(out);
            }
            None => codec_core::testing::skip(&format!("{test} ({rel})"), "not found in ../shared/data"),
        }
    }
    let mut checked = 0;
    for file in &packed {
        let animations = gltf::list_animations(file).unwrap();
        for info in animations.iter().take(3) {
            let read = GltfSelection { animation: Some(info.index.to_string()), ..Default::default() };
            let ours = gltf::read_gltf(file, &read).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
            let fps = ours.frame_rate() as f64;
            let frames = ours.frame_count();
            let out = s.0.join("t.f32");
            let theirs = three_play(&tools, file, Sampling { index: info.index, t0: info.start, fps, frames }, &out);
            let raw_error = relative_max_error(&ours, &theirs);
            // Compared with rotation keys normalized in three.js too: gltfpack stores them as
            // 16-bit QUATERNION-filtered values, unit only to ~1e-4, which three.js uses as
            // they are and our reader normalizes (a skinned character then differs by ~1.6e-5
            // × diagonal; see the notes).
            let normalized = [("NORMALIZE_ROTATIONS", "1")];
            let theirs = three_play_env(
                &tools,
                file,
                Sampling { index: info.index, t0: info.start, fps, frames },
                &out,
                &normalized,
            );
            let error = relative_max_error(&ours, &theirs);
            println!(
                "gltfpack {} animation {}: {frames} frames × {} vertices, max error × diagonal against three.js: \
                 {error:.3e} (rotation keys normalized), {raw_error:.3e} (as stored)",
                file.display(),
                info.index,
                ours.vertex_count()
            );
            assert!(error <= 1e-5, "{}: {error:e}", file.display());
            checked += 1;
        }
    }
    assert!(checked >= 2, "{checked} animations compared");
    // Against the unpacked synthetic input: the same frames and vertices (gltfpack may reorder
    // them). Positions are not compared here: gltfpack stores morph weights in 8 bits, whose
    // error on the basis layout's targets (about 1.6e-2 × diagonal in the bounding box) is
    // gltfpack's, not the reader's; the three.js comparison above checks the reading.
    let ours = gltf::read_gltf(&input, &GltfSelection::default()).unwrap();
    let back = gltf::read_gltf(&packed[0], &GltfSelection::default()).unwrap();
    assert_eq!((back.frame_count(), back.vertex_count()), (ours.frame_count(), ours.vertex_count()));
    let bounds = |x: &Animation| {
        let mut lo = [f32::MAX; 3];
        let mut hi = [f32::MIN; 3];
        for p in x.positions().chunks_exact(3) {
            for c in 0..3 {
                lo[c] = lo[c].min(p[c]);
                hi[c] = hi[c].max(p[c]);
            }
        }
        (lo, hi)
    };
    let (b0, b1) = (bounds(&ours), bounds(&back));
    let diagonal = ours.bounding_box_diagonal() as f32;
    let worst = (0..3).map(|c| (b0.0[c] - b1.0[c]).abs().max((b0.1[c] - b1.1[c]).abs())).fold(0f32, f32::max);
    println!("bounding box of the packed synthetic flag against the unpacked one: {:.3e} × diagonal", worst / diagonal);
}

/// A +Z-up layer in centimetres (usd-core-written, animated xformOps) exported to glTF, which
/// is +Y up in metres, shows upright and at its size: the file's root node turns and scales it.
/// Exported exactly (frames layout, f32), our reader and three.js play usd-core's world points
/// turned +Y up and scaled to metres within 1e-6 × diagonal; the default (compressed) export
/// plays at the KG it reported; a stream decoded to `.glb` keeps the conversion.
#[test]
fn z_up_centimetre_usd_exports_upright_in_metres() {
    use animcodec::formats::gltf_out::as_shown;
    use common::{ok, ok_json, worst_over_diagonal, z_up_centimetre_layer};
    const NAME: &str = "z_up_centimetre_usd_exports_upright_in_metres";
    if let Err(why) = common::usd_core() {
        return skip(NAME, &why);
    }
    let s = Scratch::new("gltf-z-up");
    let (source, want) = z_up_centimetre_layer(&s);
    let input = read_animation(Path::new(&source), &ReadOptions::default()).unwrap();
    let shown = as_shown(&input).unwrap().expect("a +Z-up centimetre source needs a root node");
    // What the writer measures against is usd-core's points converted.
    let w = worst_over_diagonal(&want, &shown);
    assert!(w <= 1e-6, "as_shown differs from usd-core's points turned +Y up in metres by {w:e} × diagonal");
    let exact = s.path("exact.glb");
    ok(&["export", &source, "-o", &exact, "--layout", "frames", "--compression", "none"]);
    let compressed = s.path("default.glb");
    let report = ok_json(&["export", &source, "-o", &compressed, "--json"]);
    let glb = std::fs::read(&exact).unwrap();
    let (json, _) = split_glb(&glb);
    let root = json["scenes"][0]["nodes"][0].as_u64().unwrap() as usize;
    assert_eq!(
        json["nodes"][root]["matrix"],
        serde_json::json!([0.01, 0, 0, 0, 0, 0, -0.01, 0, 0, 0.01, 0, 0, 0, 0, 0, 1])
    );
    let played = read_animation(Path::new(&exact), &ReadOptions::default()).unwrap();
    let w = worst_over_diagonal(&want, &played);
    println!("exact export of a +Z-up cm layer, our reader: {w:.3e} × diagonal from usd-core's points in +Y-up metres");
    assert!(w <= 1e-6, "our reader plays the export {w:e} × diagonal from the source shown +Y up in metres");
    // The compressed export: measured where it shows, the KG it reported.
    let played = read_animation(Path::new(&compressed), &ReadOptions::default()).unwrap();
    let eval = animcodec::metrics::EvalOptions { compute_sted: false, compute_hausdorff: false, ..Default::default() };
    let kg = animcodec::metrics::evaluate(&shown, &played, &eval).unwrap().kg.unwrap();
    let reported = report["kg"].as_f64().unwrap();
    println!("default export: reported KG {reported:.6}, measured against the source shown {kg:.6}");
    assert!((kg - reported).abs() <= 1e-3 * reported.max(1e-6), "reported {reported}, measured {kg}");
    assert!(reported <= GltfOptions::default().target_kg, "{report}");
    // `eval` compares the source with the file where the file shows it.
    let e = ok_json(&["eval", &source, &exact, "--json", "--no-hausdorff"]);
    assert!(e["kg"].as_f64().unwrap() <= 1e-4, "eval of the exact export: {e}");
    // Through a stream: the metadata travels and the decoded GLB is upright in metres too.
    let anim = s.path("x.anim");
    ok(&["encode", &source, "-c", "quant-delta", "-p", "bits=16", "-o", &anim]);
    let (usdc, decoded_glb) = (s.path("decoded.usdc"), s.path("decoded.glb"));
    ok(&["decode", &anim, "-o", &usdc]);
    ok(&["decode", &anim, "-o", &decoded_glb]);
    let decoded = read_animation(Path::new(&usdc), &ReadOptions::default()).unwrap();
    let decoded_shown = as_shown(&decoded).unwrap().expect("the stream kept the metadata");
    let played = read_animation(Path::new(&decoded_glb), &ReadOptions::default()).unwrap();
    let kg = animcodec::metrics::evaluate(&decoded_shown, &played, &eval).unwrap().kg.unwrap();
    assert!(kg <= GltfOptions::default().target_kg * 1.01, "decoded GLB: KG {kg} against the decode shown");
    let tools = match node_packages(&["three", "gltf-validator"]) {
        Ok(t) => t,
        Err(why) => return skip(&format!("{NAME} (three.js part)"), &why),
    };
    let files = [PathBuf::from(&exact), PathBuf::from(&compressed), PathBuf::from(&decoded_glb)];
    for report in validate(&tools, &files) {
        assert_eq!(report["errors"], 0, "{report}");
    }
    for (file, reference, tolerance) in [(&files[0], &want, 1e-6), (&files[1], &shown, 1e-5)] {
        let ours = read_animation(file, &ReadOptions::default()).unwrap();
        let fps = ours.frame_rate() as f64;
        let theirs = three_play(
            &tools,
            file,
            Sampling { index: 0, t0: start_of(file, 0), fps, frames: ours.frame_count() },
            &s.0.join("t.f32"),
        );
        let against_ours = relative_max_error(&ours, &theirs);
        let three =
            Animation::from_parts(reference.vertex_count(), Vec::new(), theirs, reference.frame_rate()).unwrap();
        let against_source = worst_over_diagonal(reference, &three);
        println!(
            "three.js plays {}: {against_ours:.3e} × diagonal from our reader, {against_source:.3e} from the source shown",
            file.display()
        );
        assert!(against_ours <= 1e-5, "{}: {against_ours:e}", file.display());
        // The exact export equals the source shown; the compressed one is within its KG.
        if tolerance <= 1e-6 {
            assert!(against_source <= tolerance, "{}: {against_source:e}", file.display());
        }
    }
}
