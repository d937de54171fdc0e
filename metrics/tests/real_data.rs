//! Checks on a real animation (horse-gallop, first frames) when `../shared/data` is present;
//! otherwise a visible skip (`codec_core::testing::skip`, a failure under CI's
//! `ANIMCODEC_REQUIRE_ALL=1`).

#[path = "../examples/support/readers.rs"]
mod readers;

use std::path::PathBuf;

use codec_core::Animation;
use metrics::{displacement_stats, evaluate, point_triangle_distance, vertex_to_surface_distances, EvalOptions};

const FRAMES: usize = 6;

/// The animation, or `None` after a [`codec_core::testing::skip`] of `test` when it is absent.
fn load(test: &str) -> Option<Animation> {
    let prefix = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/horse-gallop/horse-gallop"));
    let pc2 = prefix.with_extension("pc2");
    if !pc2.exists() {
        codec_core::testing::skip(test, &format!("{} not found", pc2.display()));
        return None;
    }
    let (v, f, p) = readers::read_pc2(&pc2).unwrap();
    let tris = readers::read_obj_triangles(&prefix.with_extension("obj")).unwrap();
    let keep = FRAMES.min(f) * v * 3;
    Some(Animation::from_parts(v, tris, p[..keep].to_vec(), 30.0).unwrap())
}

/// Moves every vertex by a smooth, position-dependent offset of about 0.2 % of the box.
fn perturb(a: &Animation) -> Animation {
    let s = 0.002 * a.bounding_box_diagonal() as f32;
    let p = a
        .positions()
        .chunks(3)
        .flat_map(|c| [c[0] + s * (7.0 * c[1]).sin(), c[1] + s * (5.0 * c[2]).cos(), c[2] - s * (3.0 * c[0]).sin()])
        .collect();
    Animation::from_parts(a.vertex_count(), a.triangles().to_vec(), p, a.frame_rate()).unwrap()
}

#[test]
fn real_mesh_report_is_consistent() {
    let Some(a) = load("real_mesh_report_is_consistent") else { return };
    let b = perturb(&a);
    let r = evaluate(&a, &b, &EvalOptions::default()).unwrap();
    let d = displacement_stats(&a, &b).unwrap();
    assert!(r.notes.is_empty(), "{:?}", r.notes);
    // Every horse vertex is in a triangle, so its distance to the other surface is at most its
    // displacement.
    let h = r.hausdorff.unwrap();
    assert!(h > 0.0 && h <= d.max_error, "{h} vs {}", d.max_error);
    assert!(r.sted.unwrap() > 0.0 && r.kg.unwrap() > 0.0);
}

#[test]
fn real_mesh_surface_distance_matches_brute_force() {
    let Some(a) = load("real_mesh_surface_distance_matches_brute_force") else { return };
    let b = perturb(&a);
    let (from, to) = (b.frame(FRAMES - 1), a.frame(FRAMES - 1));
    let fast = vertex_to_surface_distances(from, to, a.triangles()).unwrap();
    let pt = |f: &[f32], i: usize| [f[3 * i] as f64, f[3 * i + 1] as f64, f[3 * i + 2] as f64];
    // Every 37th vertex against all triangles (the whole mesh would take too long unoptimised).
    for v in (0..a.vertex_count()).step_by(37) {
        let p = pt(from, v);
        let brute = a
            .triangles()
            .iter()
            .map(|t| point_triangle_distance(p, pt(to, t[0] as usize), pt(to, t[1] as usize), pt(to, t[2] as usize)))
            .fold(f64::INFINITY, f64::min);
        assert_eq!(fast[v], brute, "vertex {v}");
    }
}
