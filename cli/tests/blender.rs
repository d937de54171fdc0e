//! Blender as a tested client of what animcodec writes: Debian's Blender (`apt-get install
//! blender`, 3.4 on Debian 12) runs headless (`blender -b --factory-startup --python
//! cli/tests/blender/evaluate.py`) on
//!
//! - our decoded PC2 (`decode -o X.pc2 --topology-obj`), played by the Mesh Cache modifier on a
//!   mesh built from the topology OBJ, and
//! - our exported GLB (`export -o X.glb --no-compress`: morph targets + weights; Blender 3.4's
//!   importer cannot read EXT_meshopt_compression, which the default export uses), imported
//!   with Blender's glTF importer (shape keys),
//!
//! evaluates the mesh through the depsgraph (modifiers, shape keys, object transforms applied)
//! at several frames and compares the world-space positions with our own decode of the same
//! file (the PC2 as we read it; the GLB as our glTF reader plays it). Tolerances are relative to
//! the bounding-box diagonal and stated at each assertion; the measured maxima are printed.
//! Without Blender the tests skip through `codec_core::testing::skip` (a failure under
//! `ANIMCODEC_REQUIRE_ALL=1`, as in CI, whose `.ci/run` installs it).

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use animcodec::formats::{read_animation, write_animation, ReadOptions};
use codec_core::synth::{self, SynthSize};
use codec_core::testing::skip;
use codec_core::Animation;
use common::{ok, Scratch};
use serde_json::Value;

fn script() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/blender/evaluate.py"))
}

fn blender() -> Result<(), String> {
    match Command::new("blender").args(["-b", "--factory-startup", "--version"]).output() {
        Ok(o) if o.status.success() => Ok(()),
        Ok(o) => Err(format!("blender -b --version failed: {}", String::from_utf8_lossy(&o.stderr))),
        Err(e) => Err(format!("blender not found ({e}); apt-get install blender")),
    }
}

/// Runs evaluate.py; returns its report and the evaluated positions (frames × vertices × 3).
fn evaluate(mode: &str, file: &str, obj: &str, fps: f32, frames: &[usize], out: &str) -> (Value, Vec<f32>) {
    let mut cmd = Command::new("blender");
    cmd.args(["-b", "--factory-startup", "--python-exit-code", "1", "--python"]).arg(script()).args([
        "--",
        mode,
        file,
        obj,
        &fps.to_string(),
        out,
    ]);
    cmd.args(frames.iter().map(|f| f.to_string()));
    let o = cmd.output().expect("blender runs");
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "blender failed: {text}\n{}", String::from_utf8_lossy(&o.stderr));
    let line =
        text.lines().find_map(|l| l.strip_prefix("BLENDER_RESULT ")).unwrap_or_else(|| panic!("no result: {text}"));
    let report: Value = serde_json::from_str(line).unwrap();
    let bytes = std::fs::read(out).unwrap();
    (report, bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect())
}

/// Largest coordinate difference between `ours` at `frames` and Blender's, over the diagonal.
fn worst(ours: &Animation, frames: &[usize], theirs: &[f32]) -> f64 {
    let per = ours.vertex_count() * 3;
    assert_eq!(theirs.len(), per * frames.len(), "Blender evaluated another number of vertices");
    let mut w = 0.0f64;
    for (k, &f) in frames.iter().enumerate() {
        for (a, b) in ours.frame(f).iter().zip(&theirs[k * per..(k + 1) * per]) {
            w = w.max((a - b).abs() as f64);
        }
    }
    w / ours.bounding_box_diagonal()
}

/// The animation these tests write: a synthetic waving flag and a bending cylinder.
fn inputs(dir: &Scratch) -> Vec<(String, String)> {
    let mut out = Vec::new();
    for name in ["flag", "cylinder"] {
        let a = synth::by_name(name, SynthSize::Small).unwrap();
        let pc2 = dir.path(&format!("{name}.pc2"));
        write_animation(Path::new(&pc2), &a).unwrap();
        out.push((name.to_owned(), pc2));
    }
    out
}

#[test]
fn blender_mesh_cache_plays_our_decoded_pc2() {
    if let Err(why) = blender() {
        return skip("blender_mesh_cache_plays_our_decoded_pc2", &why);
    }
    let dir = Scratch::new("blender-pc2");
    for (name, input) in inputs(&dir) {
        let anim = dir.path(&format!("{name}.anim"));
        ok(&["encode", &input, "-c", "hosvd", "-o", &anim]);
        let decoded = dir.path(&format!("{name}-decoded.pc2"));
        ok(&["decode", &anim, "-o", &decoded, "--topology-obj"]);
        let ours = read_animation(Path::new(&decoded), &ReadOptions::default()).unwrap();
        let last = ours.frame_count() - 1;
        let frames = [0, 1, last / 3, last / 2, last];
        let obj = dir.path(&format!("{name}-decoded.obj"));
        let (report, theirs) =
            evaluate("pc2", &decoded, &obj, ours.frame_rate(), &frames, &dir.path(&format!("{name}-pc2.f32")));
        assert_eq!(report["vertices"][0].as_u64().unwrap() as usize, ours.vertex_count(), "{report}");
        let w = worst(&ours, &frames, &theirs);
        eprintln!("blender pc2 {name}: max |Blender − ours| = {w:.3e} × diagonal over frames {frames:?}");
        // The Mesh Cache modifier copies the cache's float32 coordinates at whole frames: equal.
        assert!(w <= 1e-7, "{name}: Blender's Mesh Cache differs from our decode by {w:e} × diagonal");
    }
}

#[test]
fn blender_gltf_importer_plays_our_exported_glb() {
    if let Err(why) = blender() {
        return skip("blender_gltf_importer_plays_our_exported_glb", &why);
    }
    let dir = Scratch::new("blender-glb");
    for (name, input) in inputs(&dir) {
        let source = read_animation(Path::new(&input), &ReadOptions::default()).unwrap();
        let read = ReadOptions { frame_rate: Some(source.frame_rate()), ..Default::default() };
        for layout in ["frames", "basis"] {
            let glb = dir.path(&format!("{name}-{layout}.glb"));
            // Debian 12's Blender 3.4 glTF importer has no EXT_meshopt_compression ("Extension
            // EXT_meshopt_compression is not available on this addon version"), which our
            // default export requires: Blender gets the uncompressed form (`--no-compress`).
            ok(&["export", &input, "-o", &glb, "--layout", layout, "--no-compress"]);
            let ours = read_animation(Path::new(&glb), &read).unwrap();
            let last = ours.frame_count() - 1;
            let frames = [0, 1, last / 3, last / 2, last];
            let out = dir.path(&format!("{name}-{layout}.f32"));
            let (report, theirs) = evaluate("glb", &glb, "", ours.frame_rate(), &frames, &out);
            assert_eq!(report["objects"], 1, "{report}");
            assert!(report["shape_keys"][0].as_u64().unwrap() > 1, "{report}");
            let w = worst(&ours, &frames, &theirs);
            eprintln!("blender glb {name} {layout}: max |Blender − ours| = {w:.3e} × diagonal, frames {frames:?}, {} shape keys", report["shape_keys"][0]);
            // Blender mixes shape keys in float32 (basis + Σ wᵢ·(keyᵢ − basis)) from the
            // dequantized targets, we in float64 then round: a few float32 ulps of the largest
            // coordinate.
            const TOLERANCE: f64 = 1e-5;
            if layout == "frames" {
                // One target per frame, weights 0/1: inside Blender's default slider range.
                assert!(w <= TOLERANCE, "{name}: Blender's glTF playback differs from ours by {w:e} × diagonal");
                continue;
            }
            // The basis layout animates weights in [-1, 1]; Blender 3.4 clamps each shape key to
            // the slider range it derives from the default weights ([0, 1]), so it plays the
            // file wrong — by far more than the tolerance (measured 0.12 × diagonal on the flag)
            // — until the sliders are widened, when it agrees with us.
            assert!(w > 100.0 * TOLERANCE, "{name}: Blender 3.4 no longer clamps shape keys ({w:e}): update the test");
            let (_, unclamped) = evaluate("glb-unclamped", &glb, "", ours.frame_rate(), &frames, &out);
            let w = worst(&ours, &frames, &unclamped);
            eprintln!("blender glb {name} {layout}, sliders widened: max |Blender − ours| = {w:.3e} × diagonal");
            assert!(w <= TOLERANCE, "{name}: Blender's unclamped glTF playback differs from ours by {w:e} × diagonal");
        }
    }
}
