//! UsdSkel through animcodec's USD readers against usd-core's own evaluation
//! (`cli/tests/usd/skel_check.py`): usd-core writes a layer set at run time — an animated Xform
//! above a SkelRoot; a tube skinned with three influences per point (linear blend skinning), a
//! `geomBindTransform` and its own `skel:joints` order; a rigidly bound box (constant
//! interpolation) whose binding it inherits from the SkelRoot; a SkelAnimation listing its
//! joints and blend shapes in other orders than the Skeleton and the mesh; and a grid with a
//! dense and a sparse (`pointIndices`) blend shape — as a crate file and as its text export.
//! Both must read as usd-core's `UsdSkel.Cache` / `SkinningQuery.ComputeSkinnedPoints` /
//! `BlendShapeQuery` compute them, within 1e-6 of the bounding-box diagonal. Inbetween shapes
//! and dual-quaternion skinning, which are not evaluated, must be refused naming the prim and
//! the feature. Without usd-core the test skips through `codec_core::testing::skip` (a failure
//! under `ANIMCODEC_REQUIRE_ALL=1`, as in CI).

mod common;

use std::process::Command;

use animcodec::formats::{read_animation, ReadOptions};
use codec_core::testing::skip;
use common::{usd_core, usd_core_skel_reference, worst_over_diagonal, Scratch};

#[test]
fn usd_skel_layers_read_as_usd_core_evaluates_them() {
    let test = "usd_skel_layers_read_as_usd_core_evaluates_them";
    if let Err(why) = usd_core() {
        return skip(test, &why);
    }
    let dir = Scratch::new("usd-skel");
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/usd/skel_check.py");
    let o = Command::new("python3").arg(script).arg("write").arg(&dir.0).output().expect("python3 runs");
    assert!(o.status.success(), "skel_check.py write failed: {}", String::from_utf8_lossy(&o.stderr));
    for name in ["skel.usdc", "skel.usda"] {
        let file = dir.0.join(name);
        let ours = read_animation(&file, &ReadOptions::default()).unwrap_or_else(|e| panic!("{name}: {e}"));
        let theirs = usd_core_skel_reference(&file, &dir.0);
        assert_eq!(ours.frame_count(), 11, "{name}");
        assert_eq!(ours.vertex_count(), 13 * 3 + 4 + 6 * 5, "{name}");
        assert!((ours.frame_rate() - 24.0).abs() < 1e-4, "{name}: {} fps", ours.frame_rate());
        let worst = worst_over_diagonal(&theirs, &ours);
        eprintln!("{name}: max |ours − usd-core UsdSkel| = {worst:.3e} × diagonal");
        assert!(worst <= 1e-6, "{name}: {worst:e} × diagonal from usd-core's UsdSkel evaluation");
        // The skeleton moves the points: the rest pose would be far off.
        let first = &ours.positions()[..ours.vertex_count() * 3];
        let last = &ours.positions()[ours.positions().len() - ours.vertex_count() * 3..];
        assert!(first.iter().zip(last).any(|(a, b)| (a - b).abs() > 0.1), "{name}: nothing moves");
    }
    for (name, needles) in [
        ("inbetweens.usda", ["/World/Face/Grid/smile", "inbetween"]),
        ("dq.usda", ["/World/Rig/Tube", "dualQuaternion"]),
    ] {
        let e = read_animation(&dir.0.join(name), &ReadOptions::default()).expect_err(name).to_string();
        for n in needles {
            assert!(e.contains(n), "{name}: `{n}` not in: {e}");
        }
    }
}
