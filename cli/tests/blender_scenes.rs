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
//! (shape keys as UsdSkel blend shapes, armatures as a Skeleton and SkelAnimation, skinned
//! meshes bound to it, bone-parented parts under animated Xforms) must read the same way, and
//! also match usd-core's own UsdSkel evaluation of the same file (skipped without usd-core).
//! Without bpy 5 the test skips through `codec_core::testing::skip` (a failure in CI).

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use animcodec::formats::{read_animation, ReadOptions};
use codec_core::testing::skip;
use codec_core::Animation;
use common::{shared_data, usd_core, usd_core_skel_reference, worst_over_diagonal, Scratch};
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
        let skel = format!("{name}-skel.usdc");
        let skel = Some(skel.as_str()).filter(|f| dir.0.join(f).exists());
        let files = [("abc", alembic_axes), ("usdc", usd_axes), ("usdz", usd_axes)]
            .map(|(ext, axes)| (format!("{name}.{ext}"), axes));
        for (file_name, axes) in files.iter().map(|(f, a)| (f.as_str(), *a)).chain(skel.map(|f| (f, usd_axes))) {
            let file = dir.0.join(file_name);
            let ours = read_animation(&file, &ReadOptions::default())
                .unwrap_or_else(|e| panic!("{file_name} (written by Blender 5) does not read: {e}"));
            let expected = converted(&theirs, axes);
            assert_eq!(ours.frame_count(), expected.frame_count(), "{file_name}: frame count");
            assert_eq!(ours.vertex_count(), expected.vertex_count(), "{file_name}: vertex count");
            assert!((ours.frame_rate() - 24.0).abs() < 1e-4, "{file_name}: {} fps", ours.frame_rate());
            let matched = animcodec::metrics::match_vertices(&expected, &ours)
                .unwrap_or_else(|e| panic!("{file_name}: vertices do not match Blender's: {e}"));
            let played = matched.apply(&expected, &ours).unwrap();
            let worst = expected
                .positions()
                .iter()
                .zip(played.positions())
                .map(|(a, b)| (a - b).abs() as f64)
                .fold(0.0, f64::max)
                / expected.bounding_box_diagonal();
            eprintln!(
                "{file_name}: {} frames × {} vertices, max |ours − Blender| = {worst:.3e} × diagonal",
                ours.frame_count(),
                ours.vertex_count()
            );
            assert!(worst <= 1e-6, "{file_name}: {worst:e} × diagonal from Blender's evaluated mesh");
        }
        // The UsdSkel export (the exporter's defaults) evaluated by usd-core too: the same
        // meshes in the same order, so no matching.
        if let Some(skel) = skel {
            let file = dir.0.join(skel);
            match usd_core() {
                Err(why) => skip(&format!("{test} ({skel} against usd-core)"), &why),
                Ok(()) => {
                    let ours = read_animation(&file, &ReadOptions::default()).unwrap();
                    let reference = usd_core_skel_reference(&file, &dir.0);
                    let worst = worst_over_diagonal(&reference, &ours);
                    eprintln!("{skel}: max |ours − usd-core UsdSkel| = {worst:.3e} × diagonal");
                    assert!(worst <= 1e-6, "{skel}: {worst:e} × diagonal from usd-core's UsdSkel evaluation");
                    // The same layer as text (usd-core's export) reads the same.
                    let text = dir.0.join(format!("{name}-skel.usda"));
                    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/usd/skel_check.py");
                    let o = Command::new("python3").arg(script).arg("export").arg(&file).arg(&text).output().unwrap();
                    assert!(o.status.success(), "export to usda: {}", String::from_utf8_lossy(&o.stderr));
                    let from_text = read_animation(&text, &ReadOptions::default()).unwrap();
                    let worst = worst_over_diagonal(&reference, &from_text);
                    eprintln!("{name}-skel.usda: max |ours − usd-core UsdSkel| = {worst:.3e} × diagonal");
                    assert!(worst <= 1e-6, "{name}-skel.usda: {worst:e} × diagonal from usd-core");
                }
            }
        }
    }
}
