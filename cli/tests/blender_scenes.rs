//! Blender → animcodec: the caches a studio hands over, made by Blender 5.0 (`bpy` from PyPI,
//! headless) and read by animcodec. `cli/tests/blender/scenes.py` builds four scenes — a grid
//! deformed by animated shape keys, RobotExpressive's armature-skinned character playing
//! `Walking`, a cube under an animated parent transform, two meshes in one file — and exports
//! each as Alembic (`.abc`), binary USD (`.usdc`) and a USD package (`.usdz`), with Blender's
//! own evaluated world-space positions at every frame beside them. Each file must read with
//! the same frame count, the scene's 24 fps and, vertex by vertex (matched by trajectory: the
//! exporters order objects their own way), Blender's positions within 1e-6 of the bounding-box
//! diagonal, in the file's axes (Blender's Alembic exporter turns Z up into Y up; USD keeps
//! Blender's Z up and says so in `upAxis`). USD files written with the exporter's defaults
//! (shape keys and armatures as UsdSkel) must be refused by name, not read as rest poses.
//! Without bpy 5 the test skips through `codec_core::testing::skip` (a failure in CI).

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use animcodec::formats::{read_animation, ReadOptions};
use codec_core::testing::skip;
use codec_core::Animation;
use common::{shared_data, Scratch};
use serde_json::Value;

fn script() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/blender/scenes.py"))
}

/// Blender's evaluated positions of a scene, as an animation without triangles.
fn blender_positions(dir: &Path, scene: &Value) -> Animation {
    let name = scene["name"].as_str().unwrap();
    let bytes = std::fs::read(dir.join(format!("{name}.f32"))).unwrap();
    let positions: Vec<f32> = bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    let vertices: usize =
        scene["objects"].as_array().unwrap().iter().map(|o| o["vertices"].as_u64().unwrap() as usize).sum();
    assert_eq!(positions.len(), vertices * 3 * scene["frames"].as_u64().unwrap() as usize, "{scene}");
    Animation::from_parts(vertices, Vec::new(), positions, scene["fps"].as_f64().unwrap() as f32).unwrap()
}

/// `a` with every position mapped by `axes` (Blender's axes to the file's).
fn converted(a: &Animation, axes: fn([f32; 3]) -> [f32; 3]) -> Animation {
    let positions = a.positions().chunks_exact(3).flat_map(|p| axes([p[0], p[1], p[2]])).collect();
    Animation::from_parts(a.vertex_count(), Vec::new(), positions, a.frame_rate()).unwrap()
}

#[test]
fn animcodec_reads_what_blender_exports() {
    let test = "animcodec_reads_what_blender_exports";
    if let Err(why) = common::blender5() {
        return skip(test, &why);
    }
    let robot = match shared_data("robot-expressive/RobotExpressive.glb") {
        Some(p) => p.display().to_string(),
        None => {
            skip(&format!("{test} (robot scene)"), "RobotExpressive.glb not found in ../shared/data");
            "-".to_owned()
        }
    };
    let dir = Scratch::new("blender-scenes");
    let o = Command::new("python3").arg(script()).arg("--").arg(&dir.0).arg(&robot).output().expect("python3 runs");
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "scenes.py failed: {text}\n{}", String::from_utf8_lossy(&o.stderr));
    let scenes: Vec<Value> =
        text.lines().filter_map(|l| l.strip_prefix("SCENE ")).map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(scenes.len(), if robot == "-" { 3 } else { 4 }, "{text}");
    let alembic_axes: fn([f32; 3]) -> [f32; 3] = |[x, y, z]| [x, z, -y];
    let usd_axes: fn([f32; 3]) -> [f32; 3] = |p| p;
    for scene in &scenes {
        let name = scene["name"].as_str().unwrap();
        let theirs = blender_positions(&dir.0, scene);
        for (ext, axes) in [("abc", alembic_axes), ("usdc", usd_axes), ("usdz", usd_axes)] {
            let file = dir.0.join(format!("{name}.{ext}"));
            let ours = read_animation(&file, &ReadOptions::default())
                .unwrap_or_else(|e| panic!("{name}.{ext} (written by Blender 5) does not read: {e}"));
            let expected = converted(&theirs, axes);
            assert_eq!(ours.frame_count(), expected.frame_count(), "{name}.{ext}: frame count");
            assert_eq!(ours.vertex_count(), expected.vertex_count(), "{name}.{ext}: vertex count");
            assert!((ours.frame_rate() - 24.0).abs() < 1e-4, "{name}.{ext}: {} fps", ours.frame_rate());
            let matched = metrics::match_vertices(&expected, &ours)
                .unwrap_or_else(|e| panic!("{name}.{ext}: vertices do not match Blender's: {e}"));
            let played = matched.apply(&expected, &ours).unwrap();
            let worst = expected
                .positions()
                .iter()
                .zip(played.positions())
                .map(|(a, b)| (a - b).abs() as f64)
                .fold(0.0, f64::max)
                / expected.bounding_box_diagonal();
            eprintln!(
                "{name}.{ext}: {} frames × {} vertices, max |ours − Blender| = {worst:.3e} × diagonal",
                ours.frame_count(),
                ours.vertex_count()
            );
            assert!(worst <= 1e-6, "{name}.{ext}: {worst:e} × diagonal from Blender's evaluated mesh");
        }
        let skel = dir.0.join(format!("{name}-skel.usdc"));
        if skel.exists() {
            let e = read_animation(&skel, &ReadOptions::default()).expect_err("a UsdSkel-deformed mesh read as points");
            assert!(e.to_string().contains("UsdSkel"), "{name}-skel.usdc: {e}");
        }
    }
}
