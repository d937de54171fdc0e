//! glTF primitives compressed with `KHR_draco_mesh_compression`, against Google's Draco library
//! and Blender:
//!
//! - `cli/tests/gltf_draco/make_fixture.py` encodes a skinned, morph-targeted grid with DracoPy
//!   (`pip install DracoPy`, Google's Draco wrapped for Python) at levels 0, 7 and 10 and writes
//!   it twice: as Draco data, and uncompressed holding what DracoPy decodes from that data. Our
//!   reader must play both identically, bit for bit, at every frame: the decoded points, faces,
//!   joints and weights equal Google's decoder's, and the attribute map (unique ids 5, 6 and
//!   whatever Draco gave the positions) is followed.
//! - the same Draco data truncated and bit-flipped: a clear error or a valid animation, never a
//!   panic, each in well under a second, within a 100 MB read budget.
//! - `cli/tests/gltf_draco/blender_export.py` re-exports RobotExpressive (three clips) and
//!   Horse.glb with Blender 5's glTF exporter (`pip install bpy`), once plain and once with its
//!   Draco compression; the two play the same positions within Draco's quantization (2⁻¹³ of
//!   the bounding-box diagonal) at every frame of every clip, vertices matched by trajectory
//!   (Draco reorders and splits vertices).
//!
//! Without DracoPy or bpy (or ../shared/data) the tests skip through `codec_core::testing::skip`
//! (a failure under `ANIMCODEC_REQUIRE_ALL=1`, as in CI).

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use animcodec::formats::gltf::{parse_gltf_with, GltfSelection};
use animcodec::formats::{read_animation, ReadOptions};
use codec_core::testing::skip;
use codec_core::Animation;
use common::{fails, join_glb, ok, shared_data, split_glb, Scratch};
use serde_json::Value;

fn script(name: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/gltf_draco")).join(name)
}

/// `python3` when it imports `module`, else why not.
fn python_with(module: &str, install: &str) -> Result<(), String> {
    match Command::new("python3").args(["-c", &format!("import {module}")]).output() {
        Ok(o) if o.status.success() => Ok(()),
        Ok(o) => Err(format!(
            "{module} not importable ({install}): {}",
            String::from_utf8_lossy(&o.stderr).lines().last().unwrap_or("")
        )),
        Err(e) => Err(format!("python3 not found: {e}")),
    }
}

/// Runs a script of `cli/tests/gltf_draco` and returns the JSON after `marker` on its output.
fn run_script(name: &str, args: &[&str], marker: &str) -> Value {
    let o = Command::new("python3").arg(script(name)).args(args).output().expect("python3 runs");
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{name} failed: {out}\n{}", String::from_utf8_lossy(&o.stderr));
    let line = out.lines().find_map(|l| l.strip_prefix(marker)).unwrap_or_else(|| panic!("no {marker}: {out}"));
    serde_json::from_str(line).unwrap()
}

fn read(path: &Path, animation: Option<&str>, fps: Option<f32>) -> Animation {
    let options = ReadOptions { animation: animation.map(String::from), frame_rate: fps, ..Default::default() };
    read_animation(path, &options).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn same_bits(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// The DracoPy fixtures in `dir`, or why not.
fn fixtures(dir: &Scratch) -> Result<Value, String> {
    python_with("DracoPy", "pip install DracoPy")?;
    Ok(run_script("make_fixture.py", &[&dir.path("")], "FIXTURE "))
}

#[test]
fn draco_primitives_read_as_googles_decoder_decodes_them() {
    let dir = Scratch::new("draco-dracopy");
    let report = match fixtures(&dir) {
        Ok(r) => r,
        Err(why) => return skip("draco_primitives_read_as_googles_decoder_decodes_them", &why),
    };
    for level in ["0", "7", "10"] {
        let r = &report[level];
        let draco = read(Path::new(&dir.path(r["draco"].as_str().unwrap())), None, Some(24.0));
        let plain = read(Path::new(&dir.path(r["plain"].as_str().unwrap())), None, Some(24.0));
        assert_eq!(draco.vertex_count() as u64, r["points"].as_u64().unwrap(), "level {level}");
        assert_eq!(draco.triangles().len() as u64, r["faces"].as_u64().unwrap(), "level {level}");
        assert_eq!(draco.triangles(), plain.triangles(), "level {level}: faces differ from Google's decoder");
        assert_eq!(draco.frame_count(), plain.frame_count());
        assert!(draco.frame_count() >= 20, "the animation plays: {} frames", draco.frame_count());
        assert!(
            same_bits(draco.positions(), plain.positions()),
            "level {level}: positions differ from what Google's decoder gives (skinned and morphed alike)"
        );
        // Google's decode is within half a 14-bit quantization step per coordinate of the grid.
        let extent = r["extent"].as_f64().unwrap();
        assert!(r["max_quantization_error"].as_f64().unwrap() <= extent * 2f64.powi(-13), "{r}");
    }
    // The motion is real (the joint rotates, the morph target moves): frames differ.
    let draco = read(Path::new(&dir.path("draco_7.glb")), None, Some(24.0));
    assert!(draco.frame(0) != draco.frame(draco.frame_count() / 2));
    // list-animations and eval read it too; eval matches vertices on request.
    let listed = ok(&["list-animations", &dir.path("draco_7.glb")]);
    assert!(listed.contains("1 animation"), "{listed}");
    let out = ok(&["eval", &dir.path("plain_7.glb"), &dir.path("draco_7.glb"), "--match-vertices", "--no-sted"]);
    assert!(out.contains("max_error            0.000000e0"), "{out}");
    assert!(out.contains("vertices matched by trajectory"), "{out}");
}

/// Reads `glb` in process under a 100 MB budget; returns the error text (empty when it reads)
/// and the time taken.
fn read_hostile(glb: &[u8]) -> (String, Duration) {
    let selection = GltfSelection { memory_budget: Some(100 << 20), ..Default::default() };
    let start = Instant::now();
    let result = parse_gltf_with(glb, None, "hostile.glb", &selection);
    (result.err().map(|e| e.to_string()).unwrap_or_default(), start.elapsed())
}

#[test]
fn truncated_and_bit_flipped_draco_data_fail_cleanly() {
    let dir = Scratch::new("draco-hostile");
    if let Err(why) = fixtures(&dir) {
        return skip("truncated_and_bit_flipped_draco_data_fail_cleanly", &why);
    }
    for level in ["0", "7", "10"] {
        let glb = std::fs::read(dir.path(&format!("draco_{level}.glb"))).unwrap();
        let (json, bin) = split_glb(&glb);
        let v = json["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["bufferView"]
            .as_u64()
            .unwrap() as usize;
        let start = json["bufferViews"][v]["byteOffset"].as_u64().unwrap() as usize;
        let length = json["bufferViews"][v]["byteLength"].as_u64().unwrap() as usize;
        let mut worst = Duration::ZERO;
        let mut failures = 0;
        // Truncated: the view's byteLength cut short.
        for cut in [0, 1, 4, 8, 20, length / 4, length / 2, length - 16, length - 1] {
            let mut j = json.clone();
            j["bufferViews"][v]["byteLength"] = cut.into();
            let (e, t) = read_hostile(&join_glb(&j, &bin));
            worst = worst.max(t);
            assert!(
                e.contains("KHR_draco_mesh_compression") && e.contains("hostile.glb"),
                "level {level}, cut to {cut} bytes: {e:?}"
            );
            assert!(!e.contains("failed on malformed data"), "a panic inside the reader: {e}");
        }
        // Bit-flipped: each byte of the Draco data, one bit (cycling through the 8).
        for k in 0..length {
            let mut b = bin.clone();
            b[start + k] ^= 1 << (k % 8);
            let (e, t) = read_hostile(&join_glb(&json, &b));
            worst = worst.max(t);
            assert!(!e.contains("failed on malformed data"), "level {level}, byte {k}: a panic inside the reader: {e}");
            failures += usize::from(!e.is_empty());
        }
        assert!(failures > 0, "level {level}: no bit flip was noticed");
        assert!(worst < Duration::from_secs(1), "level {level}: a hostile read took {worst:?}");
        eprintln!("level {level}: {length} Draco bytes, {failures} flips refused, slowest read {worst:?}");
    }
    // The command line says what is wrong in plain words.
    let glb = std::fs::read(dir.path("draco_7.glb")).unwrap();
    let (mut json, bin) = split_glb(&glb);
    let v = json["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["bufferView"].clone();
    json["bufferViews"][v.as_u64().unwrap() as usize]["byteLength"] = 20.into();
    let cut = dir.path("cut.glb");
    std::fs::write(&cut, join_glb(&json, &bin)).unwrap();
    fails(&["eval", &cut, &cut], &["cut.glb", "KHR_draco_mesh_compression", "does not decode"]);
}

/// Largest distance between a vertex of `a` and its match in `b` (matched by trajectory) over
/// every frame, over the bounding-box diagonal of `a`.
fn worst_matched(a: &Animation, b: &Animation) -> f64 {
    let m = animcodec::metrics::match_vertices(a, b).unwrap();
    let played = m.apply(a, b).unwrap();
    let worst = a
        .positions()
        .chunks_exact(3)
        .zip(played.positions().chunks_exact(3))
        .map(|(p, q)| (0..3).map(|k| (p[k] as f64 - q[k] as f64).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max);
    worst / a.bounding_box_diagonal()
}

#[test]
fn blender_draco_exports_play_like_the_plain_exports() {
    if let Err(why) = python_with("bpy", "pip install bpy==5.0.1") {
        return skip("blender_draco_exports_play_like_the_plain_exports", &why);
    }
    let cases = [
        ("robot-expressive/RobotExpressive.glb", "robot", &["Dance", "Walking", "Wave"][..]),
        ("horse-glb/Horse.glb", "horse", &[][..]),
    ];
    let dir = Scratch::new("draco-blender");
    for (source, name, clips) in cases {
        let Some(src) = shared_data(source) else {
            return skip(
                "blender_draco_exports_play_like_the_plain_exports",
                &format!("../shared/data/{source} absent"),
            );
        };
        let (plain, draco) = (dir.path(&format!("{name}.glb")), dir.path(&format!("{name}_draco.glb")));
        let mut args = vec![src.to_str().unwrap(), &plain, &draco];
        args.extend(clips);
        let report = run_script("blender_export.py", &args, "EXPORT_RESULT ");
        let actions: Vec<&str> = report["actions"].as_array().unwrap().iter().map(|a| a.as_str().unwrap()).collect();
        if !clips.is_empty() {
            assert_eq!(actions, clips, "{report}");
        }
        let (json, _) = split_glb(&std::fs::read(&draco).unwrap());
        assert!(json["extensionsRequired"].to_string().contains("KHR_draco_mesh_compression"), "not Draco-compressed");
        for action in &actions {
            let a = read(Path::new(&plain), Some(action), None);
            let b = read(Path::new(&draco), Some(action), None);
            assert_eq!(a.frame_count(), b.frame_count());
            assert!(a.frame_count() > 1, "{name} {action}: no animation");
            let worst = worst_matched(&a, &b);
            eprintln!(
                "{name} {action}: {} plain / {} Draco vertices, {} frames, worst matched error {worst:.3e} of the diagonal",
                a.vertex_count(),
                b.vertex_count(),
                a.frame_count()
            );
            assert!(
                worst <= 2f64.powi(-13),
                "{name} {action}: {worst:e} of the diagonal, beyond Draco's 14-bit quantization"
            );
        }
    }
}

/// three.js plays `file`'s first animation (its `DRACOLoader` with the Draco decoder three ships,
/// under Node.js: `cli/tests/gltf/play.mjs`) at `fps` from `t0` for `frames` frames.
fn three_play(tools: &Path, file: &Path, t0: f64, fps: f32, frames: usize, out: &Path) -> Vec<f32> {
    let o = Command::new("node")
        .arg(tools.join("play.mjs"))
        .arg(file)
        .arg(out)
        .args(["--animation", "0", "--t0", &t0.to_string(), "--fps", &fps.to_string()])
        .args(["--frames", &frames.to_string()])
        .output()
        .unwrap();
    assert!(o.status.success(), "three.js failed on {}: {}", file.display(), String::from_utf8_lossy(&o.stderr));
    std::fs::read(out).unwrap().chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
}

#[test]
fn three_js_plays_draco_files_at_our_positions() {
    let tools = match common::node_packages(&["three"]) {
        Ok(t) => t,
        Err(why) => return skip("three_js_plays_draco_files_at_our_positions", &why),
    };
    let dir = Scratch::new("draco-three");
    let mut files = Vec::new();
    match fixtures(&dir) {
        Ok(_) => files.extend(["draco_0.glb", "draco_7.glb", "draco_10.glb"].map(|f| PathBuf::from(dir.path(f)))),
        Err(why) => return skip("three_js_plays_draco_files_at_our_positions", &why),
    }
    // A Blender-written file too, when bpy is there (three.js keeps Draco's vertex order, as we do).
    if let (Ok(()), Some(src)) =
        (python_with("bpy", "pip install bpy==5.0.1"), shared_data("robot-expressive/RobotExpressive.glb"))
    {
        let (plain, draco) = (dir.path("robot.glb"), dir.path("robot_draco.glb"));
        run_script("blender_export.py", &[src.to_str().unwrap(), &plain, &draco, "Wave"], "EXPORT_RESULT ");
        files.push(PathBuf::from(draco));
    }
    for file in files {
        let ours = read(&file, None, None);
        let t0 = animcodec::formats::gltf::list_animations(&file).unwrap()[0].start;
        let theirs =
            three_play(&tools, &file, t0, ours.frame_rate(), ours.frame_count(), Path::new(&dir.path("three.f32")));
        assert_eq!(
            ours.positions().len(),
            theirs.len(),
            "{}: vertex or frame count differs from three.js",
            file.display()
        );
        let worst = ours.positions().iter().zip(&theirs).map(|(a, b)| (a - b).abs() as f64).fold(0.0, f64::max)
            / ours.bounding_box_diagonal();
        eprintln!(
            "{}: {} vertices × {} frames, three.js within {worst:.2e} of the diagonal",
            file.display(),
            ours.vertex_count(),
            ours.frame_count()
        );
        assert!(worst < 1e-5, "{}: three.js plays {worst:e} of the diagonal away", file.display());
    }
}
