//! Our default GLB export against `gltfpack -cc` (meshoptimizer's packer, npm
//! `gltfpack` 1.3.0, pinned in `tests/gltf/package.json`) on the same frames, at the error
//! three.js plays back. gltfpack packs our exact `--layout frames --no-compress` export; both
//! files are read back with our glTF reader (which agrees with three.js's playback of either to
//! ≤ 1e-5 × the diagonal: `gltf.rs`) and measured with KG against the input; our export aims at
//! gltfpack's KG (`target_kg`) and must meet it in at most 0.7× gltfpack's bytes.
//!
//! Needs `bash cli/tests/gltf/install.sh` (Node.js + npm packages); the real animations come
//! from `../shared/data`; either missing is a visible skip (`codec_core::testing::skip`, a
//! failure under `ANIMCODEC_REQUIRE_ALL=1`). A synthetic animation always runs when the tools do.

mod common;

use std::path::Path;
use std::process::Command;

use animcodec::formats::gltf::{self, GltfSelection};
use animcodec::formats::gltf_out::{encode_gltf, GltfCompression, GltfLayout, GltfOptions};
use animcodec::formats::{read_animation, ReadOptions};
use animcodec::synth::{self, SynthSize};
use codec_core::testing::skip;
use codec_core::Animation;
use common::{node_packages, shared_data, Scratch};

/// The size ratio our export must reach against gltfpack's: 0.7× its bytes at no more KG.
const RATIO: f64 = 0.7;

/// Runs `gltfpack -cc` on `input` (keys at `fps`): at a rate other than its default 30 Hz,
/// with `-af 0` (no resampling), else gltfpack resamples the `STEP` weights at 30 Hz and plays
/// other frames (KG 4–8 % on RobotExpressive's 24-fps animations).
fn gltfpack_cc(tools: &Path, input: &Path, output: &Path, fps: f32) {
    let args: &[&str] = if fps == 30.0 { &["-cc"] } else { &["-cc", "-af", "0"] };
    common::gltfpack(tools, input, output, args);
}

/// Errors of the Khronos glTF Validator on `file`.
fn validator_errors(tools: &Path, file: &Path) -> u64 {
    let o = Command::new("node").arg(tools.join("validate.mjs")).arg(file).output().unwrap();
    assert!(o.status.success(), "gltf-validator failed: {}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    report["errors"].as_u64().unwrap()
}

/// For each of our vertices, the packed file's vertex that plays it: gltfpack reorders vertices
/// (and may merge equal ones), so vertices are matched by their positions on the first, middle
/// and last frames (nearest in those 9 coordinates, among the packed vertices in the 27 grid
/// cells around ours on the first frame; every packed vertex when those cells are empty).
fn vertex_map(ours: &Animation, packed: &Animation) -> Vec<usize> {
    let frames = [0, ours.frame_count() / 2, ours.frame_count() - 1];
    let cell = ours.bounding_box_diagonal() * 2e-3;
    let key = |p: &[f32]| -> [i64; 3] { std::array::from_fn(|k| (p[k] as f64 / cell).floor() as i64) };
    let mut grid: std::collections::HashMap<[i64; 3], Vec<usize>> = std::collections::HashMap::new();
    for v in 0..packed.vertex_count() {
        grid.entry(key(&packed.frame(0)[3 * v..3 * v + 3])).or_default().push(v);
    }
    let distance = |v: usize, w: usize| -> f64 {
        frames
            .iter()
            .map(|&f| {
                let (a, b) = (&ours.frame(f)[3 * v..3 * v + 3], &packed.frame(f)[3 * w..3 * w + 3]);
                (0..3).map(|k| (a[k] as f64 - b[k] as f64).powi(2)).sum::<f64>()
            })
            .sum()
    };
    (0..ours.vertex_count())
        .map(|v| {
            let c = key(&ours.frame(0)[3 * v..3 * v + 3]);
            let mut candidates = Vec::new();
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        if let Some(list) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                            candidates.extend_from_slice(list);
                        }
                    }
                }
            }
            if candidates.is_empty() {
                candidates = (0..packed.vertex_count()).collect();
            }
            candidates.into_iter().min_by(|&a, &b| distance(v, a).total_cmp(&distance(v, b))).unwrap()
        })
        .collect()
}

/// KG (%) of `packed` against `ours` through `vertex_map`.
fn kg_matched(ours: &Animation, packed: &Animation) -> f64 {
    assert_eq!(ours.frame_count(), packed.frame_count(), "gltfpack changed the frame count");
    let map = vertex_map(ours, packed);
    let mut positions = Vec::with_capacity(ours.positions().len());
    for f in 0..ours.frame_count() {
        let frame = packed.frame(f);
        for &w in &map {
            positions.extend_from_slice(&frame[3 * w..3 * w + 3]);
        }
    }
    let played =
        Animation::from_parts(ours.vertex_count(), ours.triangles().to_vec(), positions, ours.frame_rate()).unwrap();
    animcodec::metrics::kg_error(ours, &played).unwrap()
}

struct Row {
    name: String,
    gltfpack_bytes: usize,
    gltfpack_kg: f64,
    ours_bytes: usize,
    ours_kg: f64,
    targets: usize,
    rigid: bool,
}

/// gltfpack -cc on our frames export, then our export in `compression` (the default:
/// [`GltfCompression::Meshopt`]) aimed at gltfpack's KG.
fn compare(tools: &Path, s: &Scratch, name: &str, a: &Animation, compression: GltfCompression) -> Row {
    let fps = a.frame_rate();
    let frames = s.0.join(format!("{name}-frames.glb"));
    let options = GltfOptions {
        layout: GltfLayout::Frames,
        compression: GltfCompression::None,
        name: name.into(),
        ..Default::default()
    };
    std::fs::write(&frames, encode_gltf(a, &options, true).unwrap().0).unwrap();
    let packed_path = s.0.join(format!("{name}-gltfpack.glb"));
    gltfpack_cc(tools, &frames, &packed_path, fps);
    let selection = GltfSelection { frame_rate: Some(fps), ..Default::default() };
    let packed = gltf::read_gltf(&packed_path, &selection).unwrap();
    let gltfpack_kg = kg_matched(a, &packed);
    // What `animcodec export X -o Y.glb --target kg=T` writes (vertices welded and reordered).
    let options =
        GltfOptions { target_kg: gltfpack_kg, name: name.into(), reorder: true, compression, ..Default::default() };
    let (bytes, summary) = encode_gltf(a, &options, true).unwrap();
    let ours_path = s.0.join(format!("{name}-ours-{compression:?}.glb"));
    std::fs::write(&ours_path, &bytes).unwrap();
    let mut played = gltf::read_gltf(&ours_path, &selection).unwrap();
    if let Some(map) = &summary.vertex_map {
        played = animcodec::formats::gltf_out::restore_vertices(&played, map, a.triangles()).unwrap();
    }
    let ours_kg = animcodec::metrics::kg_error(a, &played).unwrap();
    assert_eq!(validator_errors(tools, &ours_path), 0, "{name}: our GLB fails the Khronos validator");
    let row = Row {
        name: name.into(),
        gltfpack_bytes: std::fs::metadata(&packed_path).unwrap().len() as usize,
        gltfpack_kg,
        ours_bytes: bytes.len(),
        ours_kg,
        targets: summary.targets,
        rigid: summary.rigid,
    };
    println!(
        "| {} | {compression:?} | {} × {} | {} | {:.4} | {} | {:.4} | {:.3} | {}{} |",
        row.name,
        a.frame_count(),
        a.vertex_count(),
        row.gltfpack_bytes,
        row.gltfpack_kg,
        row.ours_bytes,
        row.ours_kg,
        row.ours_bytes as f64 / row.gltfpack_bytes as f64,
        row.targets,
        if row.rigid { " + rigid" } else { "" }
    );
    row
}

/// Asserts the bar on `row`: KG ≤ gltfpack's and bytes ≤ 0.7× gltfpack's.
fn assert_beats(row: &Row) {
    assert!(row.ours_kg <= row.gltfpack_kg, "{}: our KG {} > gltfpack's {}", row.name, row.ours_kg, row.gltfpack_kg);
    assert!(
        row.ours_bytes as f64 <= RATIO * row.gltfpack_bytes as f64,
        "{}: {} bytes > {RATIO} × gltfpack's {}",
        row.name,
        row.ours_bytes,
        row.gltfpack_bytes
    );
}

/// The synthetic comparison (always runs with the tools): a waving flag.
#[test]
fn our_glb_beats_gltfpack_on_a_synthetic_animation() {
    let test = "our_glb_beats_gltfpack_on_a_synthetic_animation";
    let tools = match node_packages(&["gltfpack", "gltf-validator"]) {
        Ok(t) => t,
        Err(why) => return skip(test, &why),
    };
    let s = Scratch::new("gltfpack-synth");
    println!("| animation | frames × vertices | gltfpack -cc bytes | its KG | ours bytes | our KG | ratio | targets |");
    let a = synth::by_name("flag", SynthSize::Medium).unwrap();
    let row = compare(&tools, &s, "flag", &a, GltfCompression::Meshopt);
    assert_beats(&row);
    // A user checks gltfpack's welded, reordered output with `eval --match-vertices` (vertices
    // matched by trajectory): the KG this test measured. Without it the topology differs.
    let (frames, packed) = (s.path("flag-frames.glb"), s.path("flag-gltfpack.glb"));
    let e = common::ok_json(&["eval", &frames, &packed, "--match-vertices", "--json", "--no-hausdorff"]);
    let kg = e["kg"].as_f64().unwrap();
    println!("eval --match-vertices of gltfpack's output: KG {kg:.5} (this test's matching: {:.5})", row.gltfpack_kg);
    assert!((kg - row.gltfpack_kg).abs() <= 1e-3 * row.gltfpack_kg, "{e}");
    common::fails(&["eval", &frames, &packed, "--no-hausdorff"], &["--match-vertices"]);
}

/// The real animations the comparison is made on: samba, chicken-crossing and three RobotExpressive animations.
#[test]
fn our_glb_beats_gltfpack_on_the_real_animations() {
    let test = "our_glb_beats_gltfpack_on_the_real_animations";
    let tools = match node_packages(&["gltfpack", "gltf-validator"]) {
        Ok(t) => t,
        Err(why) => return skip(test, &why),
    };
    let s = Scratch::new("gltfpack-real");
    let mut inputs: Vec<(String, Animation)> = Vec::new();
    for name in ["samba", "chicken-crossing"] {
        match (shared_data(&format!("{name}/{name}.pc2")), shared_data(&format!("{name}/{name}.obj"))) {
            (Some(pc2), Some(obj)) => {
                let read = ReadOptions { topology: Some(obj), ..Default::default() };
                inputs.push((name.into(), read_animation(&pc2, &read).unwrap()));
            }
            _ => skip(&format!("{test} ({name})"), "not found in ../shared/data"),
        }
    }
    match shared_data("robot-expressive/RobotExpressive.glb") {
        Some(robot) => {
            for name in ["Dance", "Walking", "Wave"] {
                let read = ReadOptions { animation: Some(name.into()), ..Default::default() };
                inputs.push((format!("robot-{name}"), read_animation(&robot, &read).unwrap()));
            }
        }
        None => skip(&format!("{test} (RobotExpressive)"), "not found in ../shared/data"),
    }
    if inputs.is_empty() {
        return;
    }
    println!(
        "| animation | ours as | frames × vertices | gltfpack -cc bytes | its KG | ours bytes | our KG | ratio | targets |"
    );
    let rows: Vec<Row> =
        inputs.iter().map(|(name, a)| compare(&tools, &s, name, a, GltfCompression::Meshopt)).collect();
    for row in &rows {
        assert_beats(row);
    }
}

/// The first `frames` frames of `a`.
fn clip(a: &Animation, frames: usize) -> Animation {
    let per = 3 * a.vertex_count();
    Animation::from_parts(
        a.vertex_count(),
        a.triangles().to_vec(),
        a.positions()[..frames * per].to_vec(),
        a.frame_rate(),
    )
    .unwrap()
}

/// Short clips: Horse.glb (16 frames, a morph animation) and the first 10, 15 and 22 frames of
/// samba and of RobotExpressive's Walking, in the default form and in `KHR_meshopt_compression`.
/// The 0.7× of the long clips holds from 15 frames; below, what was measured is asserted with a
/// small margin, as [`short_clip_bound`] says.
#[test]
fn our_glb_beats_gltfpack_on_short_clips() {
    let test = "our_glb_beats_gltfpack_on_short_clips";
    let tools = match node_packages(&["gltfpack", "gltf-validator"]) {
        Ok(t) => t,
        Err(why) => return skip(test, &why),
    };
    let s = Scratch::new("gltfpack-short");
    let mut inputs: Vec<(String, Animation)> = Vec::new();
    match shared_data("horse-glb/Horse.glb") {
        Some(horse) => inputs.push(("Horse.glb".into(), read_animation(&horse, &ReadOptions::default()).unwrap())),
        None => skip(&format!("{test} (Horse.glb)"), "not found in ../shared/data"),
    }
    let mut long = Vec::new();
    match (shared_data("samba/samba.pc2"), shared_data("samba/samba.obj")) {
        (Some(pc2), Some(obj)) => {
            let read = ReadOptions { topology: Some(obj), ..Default::default() };
            long.push(("samba".to_owned(), read_animation(&pc2, &read).unwrap()));
        }
        _ => skip(&format!("{test} (samba)"), "not found in ../shared/data"),
    }
    match shared_data("robot-expressive/RobotExpressive.glb") {
        Some(robot) => {
            let read = ReadOptions { animation: Some("Walking".into()), ..Default::default() };
            long.push(("robot-Walking".to_owned(), read_animation(&robot, &read).unwrap()));
        }
        None => skip(&format!("{test} (RobotExpressive)"), "not found in ../shared/data"),
    }
    for (name, a) in &long {
        for frames in [10, 15, 22] {
            inputs.push((format!("{name}[..{frames}]"), clip(a, frames)));
        }
    }
    if inputs.is_empty() {
        return;
    }
    println!(
        "| animation | ours as | frames × vertices | gltfpack -cc bytes | its KG | ours bytes | our KG | ratio | targets |"
    );
    for (name, a) in &inputs {
        for compression in [GltfCompression::Meshopt, GltfCompression::MeshoptKhr] {
            let row = compare(&tools, &s, name, a, compression);
            assert_within(&row, short_clip_bound(&row.name, compression));
        }
    }
}

/// The size bar for a short clip (a fraction of gltfpack's bytes) in `compression`: 0.7 from
/// 15 frames; below (10 frames, and Horse.glb's 16 frames of a 494-vertex mesh), the measured
/// ratio plus about 0.01 (`docs/notes/issue-40-short-2.md`: 0.74–0.75 at 10 frames, 0.68–0.74
/// with `KHR_meshopt_compression`; `docs/notes/issue-40-horse.md`: Horse 0.802, 0.744 with
/// `KHR_meshopt_compression`).
fn short_clip_bound(name: &str, compression: GltfCompression) -> f64 {
    let khr = compression == GltfCompression::MeshoptKhr;
    if name == "Horse.glb" {
        if khr {
            0.755
        } else {
            0.81
        }
    } else if name.ends_with("[..10]") {
        if khr {
            0.75
        } else {
            0.76
        }
    } else {
        RATIO
    }
}

/// KG ≤ gltfpack's and bytes ≤ `bound` × gltfpack's.
fn assert_within(row: &Row, bound: f64) {
    assert!(row.ours_kg <= row.gltfpack_kg, "{}: our KG {} > gltfpack's {}", row.name, row.ours_kg, row.gltfpack_kg);
    assert!(
        row.ours_bytes as f64 <= bound * row.gltfpack_bytes as f64,
        "{}: {} bytes > {bound} × gltfpack's {}",
        row.name,
        row.ours_bytes,
        row.gltfpack_bytes
    );
}
