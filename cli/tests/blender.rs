//! Blender as a tested client of what animcodec writes: Blender 5.0 as a Python module (`pip
//! install bpy==5.0.1`, headless, no display) runs `cli/tests/blender/evaluate.py` on
//!
//! - our decoded PC2 (`decode -o X.pc2 --topology-obj`), played by the Mesh Cache modifier on a
//!   mesh built from the topology OBJ,
//! - our decoded Alembic and binary USD (`decode -o X.abc`, `-o X.usdc`), imported with
//!   Blender's Alembic and USD importers, and
//! - our exported GLB in every form Blender can import (`--compression quantized`: 16-bit
//!   positions, and `none`: f32), both layouts, imported with Blender's glTF importer (shape
//!   keys); the default form (`meshopt`) is refused by Blender 5.0's importer, which the test
//!   checks so that the README's statement fails here the day it changes,
//!
//! evaluates the mesh through the depsgraph (modifiers, shape keys, object transforms applied)
//! at several frames and compares the world-space positions with our own decode of the same
//! file (the PC2 as we read it; the GLB as our glTF reader plays it). Tolerances are relative to
//! the bounding-box diagonal and stated at each assertion; the measured maxima are printed.
//! Without bpy 5 the tests skip through `codec_core::testing::skip` (a failure under
//! `ANIMCODEC_REQUIRE_ALL=1`, as in CI, whose `.ci/run` installs it).

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use animcodec::formats::{read_animation, write_animation, ReadOptions};
use animcodec::synth::{self, SynthSize};
use codec_core::testing::skip;
use codec_core::Animation;
use common::{ok, Scratch};
use serde_json::Value;

fn script() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/blender/evaluate.py"))
}

/// Runs evaluate.py; returns its report and the evaluated positions (frames × vertices × 3),
/// or what Blender printed when the script failed.
fn try_evaluate(
    mode: &str,
    file: &str,
    obj: &str,
    fps: f32,
    frames: &[usize],
    out: &str,
) -> Result<(Value, Vec<f32>), String> {
    let mut cmd = Command::new("python3");
    cmd.arg(script()).args(["--", mode, file, obj, &fps.to_string(), out]);
    cmd.args(frames.iter().map(|f| f.to_string()));
    let o = cmd.output().expect("python3 runs");
    let text = String::from_utf8_lossy(&o.stdout);
    if !o.status.success() {
        return Err(format!("{text}\n{}", String::from_utf8_lossy(&o.stderr)));
    }
    let line =
        text.lines().find_map(|l| l.strip_prefix("BLENDER_RESULT ")).unwrap_or_else(|| panic!("no result: {text}"));
    let report: Value = serde_json::from_str(line).unwrap();
    let bytes = std::fs::read(out).unwrap();
    Ok((report, bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()))
}

/// [`try_evaluate`], which must succeed.
fn evaluate(mode: &str, file: &str, obj: &str, fps: f32, frames: &[usize], out: &str) -> (Value, Vec<f32>) {
    try_evaluate(mode, file, obj, fps, frames, out).unwrap_or_else(|e| panic!("Blender failed on {file}: {e}"))
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
    if let Err(why) = common::blender5() {
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

/// Blender's Alembic and USD importers play our `.abc` and `.usdc` at the decoded positions.
#[test]
fn blender_imports_our_alembic_and_usd() {
    if let Err(why) = common::blender5() {
        return skip("blender_imports_our_alembic_and_usd", &why);
    }
    let dir = Scratch::new("blender-abc-usd");
    for (name, input) in inputs(&dir) {
        let anim = dir.path(&format!("{name}.anim"));
        ok(&["encode", &input, "-c", "quant-delta", "-p", "bits=16", "-o", &anim]);
        for (ext, mode) in [("abc", "abc"), ("usdc", "usd")] {
            let file = dir.path(&format!("{name}.{ext}"));
            ok(&["decode", &anim, "-o", &file]);
            let ours = read_animation(Path::new(&file), &ReadOptions::default()).unwrap();
            let last = ours.frame_count() - 1;
            let frames = [0, 1, last / 3, last / 2, last];
            let out = dir.path(&format!("{name}-{ext}.f32"));
            let (report, theirs) = evaluate(mode, &file, "", ours.frame_rate(), &frames, &out);
            assert_eq!(report["objects"], 1, "{report}");
            let w = worst(&ours, &frames, &theirs);
            eprintln!("blender {ext} {name}: max |Blender − ours| = {w:.3e} × diagonal over frames {frames:?}");
            // The importers copy the float32 points (and turn the axes): equal up to the
            // rounding of a matrix product with the axis change.
            assert!(w <= 1e-6, "{name}.{ext}: Blender plays it {w:e} × diagonal from our decode");
        }
    }
}

#[test]
fn blender_gltf_importer_plays_our_exported_glb() {
    if let Err(why) = common::blender5() {
        return skip("blender_gltf_importer_plays_our_exported_glb", &why);
    }
    let dir = Scratch::new("blender-glb");
    for (name, input) in inputs(&dir) {
        let source = read_animation(Path::new(&input), &ReadOptions::default()).unwrap();
        let read = ReadOptions { frame_rate: Some(source.frame_rate()), ..Default::default() };
        for layout in ["frames", "basis"] {
            for compression in ["quantized", "none"] {
                let glb = dir.path(&format!("{name}-{layout}-{compression}.glb"));
                let out = ok(&["export", &input, "-o", &glb, "--layout", layout, "--compression", compression]);
                assert!(out.contains("Blender 5.0") || compression == "none", "{out}");
                let ours = read_animation(Path::new(&glb), &read).unwrap();
                let last = ours.frame_count() - 1;
                let frames = [0, 1, last / 3, last / 2, last];
                let out = dir.path(&format!("{name}-{layout}-{compression}.f32"));
                let (report, theirs) = evaluate("glb", &glb, "", ours.frame_rate(), &frames, &out);
                assert_eq!(report["objects"], 1, "{report}");
                assert!(report["shape_keys"][0].as_u64().unwrap() > 1, "{report}");
                let w = worst(&ours, &frames, &theirs);
                eprintln!(
                    "blender glb {name} {layout} {compression}: max |Blender − ours| = {w:.3e} × diagonal, frames \
                     {frames:?}, {} shape keys, sliders {}",
                    report["shape_keys"][0], report["sliders"]
                );
                // Blender mixes shape keys in float32 (basis + Σ wᵢ·(keyᵢ − basis)) from the
                // dequantized targets, we in float64 then round: a few float32 ulps of the
                // largest coordinate. Every weight lies in [0, 1], inside the slider range
                // Blender clamps shape keys to, so no slider needs widening.
                const TOLERANCE: f64 = 1e-5;
                assert!(
                    w <= TOLERANCE,
                    "{name} {layout} {compression}: Blender's glTF playback differs from ours by {w:e} × diagonal"
                );
            }
        }
        // The default form: Blender 5.0's importer has no EXT_meshopt_compression, as `export`
        // says in its output. When this fails, Blender reads it: update the export's message
        // and the README.
        let glb = dir.path(&format!("{name}-meshopt.glb"));
        let out = ok(&["export", &input, "-o", &glb]);
        assert!(out.contains("Blender 5.0 does not"), "{out}");
        let refused = try_evaluate("glb", &glb, "", source.frame_rate(), &[0], &dir.path("meshopt.f32"));
        let why = refused.expect_err("Blender 5.0 imported EXT_meshopt_compression");
        assert!(why.contains("EXT_meshopt_compression is not available"), "{why}");
    }
}

/// A +Z-up layer in centimetres (usd-core-written) exported to glTF plays in Blender 5 upright
/// and at its size, as our glTF reader plays it: Blender applies the file's root node (its
/// importer then turns glTF's +Y up into its own +Z up, undone by evaluate.py). Exactly
/// exported (frames, f32) it equals usd-core's points turned +Y up in metres within 1e-6 ×
/// diagonal; the DCC form (`--compression quantized`) plays as our reader does.
#[test]
fn blender_plays_a_z_up_centimetre_export_upright_in_metres() {
    const NAME: &str = "blender_plays_a_z_up_centimetre_export_upright_in_metres";
    if let Err(why) = common::blender5() {
        return skip(NAME, &why);
    }
    if let Err(why) = common::usd_core() {
        return skip(NAME, &why);
    }
    let dir = Scratch::new("blender-z-up");
    let (source, want) = common::z_up_centimetre_layer(&dir);
    for (layout, compression) in [("frames", "none"), ("basis", "quantized")] {
        let glb = dir.path(&format!("{layout}-{compression}.glb"));
        ok(&["export", &source, "-o", &glb, "--layout", layout, "--compression", compression]);
        let ours = read_animation(Path::new(&glb), &ReadOptions::default()).unwrap();
        let frames: Vec<usize> = (0..ours.frame_count()).collect();
        let out = dir.path(&format!("{layout}-{compression}.f32"));
        let (report, theirs) = evaluate("glb", &glb, "", ours.frame_rate(), &frames, &out);
        let w_ours = worst(&ours, &frames, &theirs);
        let w_source = worst(&want, &frames, &theirs);
        eprintln!(
            "blender glb z-up cm {layout} {compression}: {w_ours:.3e} × diagonal from our reader, {w_source:.3e} \
             from usd-core's points in +Y-up metres ({report})"
        );
        assert!(w_ours <= 1e-5, "{layout} {compression}: Blender plays it {w_ours:e} × diagonal from our reader");
        if compression == "none" {
            assert!(w_source <= 1e-6, "{layout}: Blender plays it {w_source:e} × diagonal from the source shown");
        }
    }
}
