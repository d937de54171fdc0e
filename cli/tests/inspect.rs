//! End-to-end tests of `animcodec inspect` (issue #7): the segmentation JSON, the coloured
//! PLY/OBJ meshes and the error messages. All on the small `synth:phases` (242 vertices ×
//! 40 frames), so they run in well under a second each.

use serde_json::Value;

mod common;
use common::*;

const INPUT: &str = "synth:phases";

fn as_usize(v: &Value) -> usize {
    v.as_u64().unwrap_or_else(|| panic!("not a count: {v}")) as usize
}

#[test]
fn json_describes_a_tiling_segmentation() {
    // The scanning detector finds synth:phases' changes at this size (the default detector,
    // tuned on real data, merges them: codec-stseg/README.md, "Scanning detector").
    let text = ok(&["inspect", INPUT, "-p", "detector=scan", "--json", "-"]);
    let j: Value = serde_json::from_str(&text).unwrap_or_else(|e| panic!("invalid JSON ({e}): {text}"));
    let (v, f) = (as_usize(&j["vertices"]), as_usize(&j["frames"]));
    assert!(v > 0 && f > 0);
    assert!(j["triangles"].as_u64().unwrap() > 0);
    assert_eq!(j["codec"], "stseg");
    assert_eq!(j["params"]["groups"], 4, "default params are reported");

    let boundaries: Vec<usize> = j["boundaries"].as_array().unwrap().iter().map(as_usize).collect();
    let detected: Vec<usize> = j["detected_boundaries"].as_array().unwrap().iter().map(as_usize).collect();
    assert!(!boundaries.is_empty(), "phases changes motion three times; no boundary found");
    assert!(detected.iter().all(|d| boundaries.contains(d)), "{detected:?} ⊄ {boundaries:?}");

    let sets = j["label_sets"].as_array().unwrap();
    let segments = j["segments"].as_array().unwrap();
    assert_eq!(segments.len(), boundaries.len() + 1);
    let mut next = 0;
    for (i, s) in segments.iter().enumerate() {
        assert_eq!(as_usize(&s["index"]), i);
        let (first, count) = (as_usize(&s["first_frame"]), as_usize(&s["frames"]));
        assert_eq!(first, next, "segments tile the frames");
        assert_eq!(as_usize(&s["last_frame"]), first + count - 1);
        if i > 0 {
            assert_eq!(first, boundaries[i - 1]);
        }
        next = first + count;
        let case = as_usize(&s["case"]);
        assert!((1..=4).contains(&case));
        assert_eq!(s["detected_boundary"].as_bool().unwrap(), detected.contains(&next));
        let ends = s["ends_at"].as_str().unwrap();
        assert_eq!(ends == "detected_boundary", s["detected_boundary"] == true, "{s}");
        assert_eq!(ends == "end_of_animation", next == f, "{s}");
        assert!(["detected_boundary", "end_of_animation", "gamma_init", "gamma_max"].contains(&ends), "{s}");

        let groups = as_usize(&s["group_count"]);
        let labels = sets[as_usize(&s["label_set"])].as_array().unwrap();
        assert_eq!(labels.len(), v, "one label per vertex");
        assert!(labels.iter().all(|l| as_usize(l) < groups));
        let sizes: Vec<usize> = s["group_sizes"].as_array().unwrap().iter().map(as_usize).collect();
        assert_eq!(sizes.len(), groups);
        assert_eq!(sizes.iter().sum::<usize>(), v);
        for (g, &n) in sizes.iter().enumerate() {
            assert_eq!(labels.iter().filter(|l| as_usize(l) == g).count(), n, "size of group {g}");
        }
    }
    assert_eq!(next, f, "segments cover every frame");
    // Label sets are distinct: shared groupings are stored once.
    for a in 0..sets.len() {
        for b in a + 1..sets.len() {
            assert_ne!(sets[a], sets[b], "label sets {a} and {b} are equal");
        }
    }
}

#[test]
fn summary_and_json_file_agree() {
    let dir = Scratch::new("summary");
    let json_path = dir.path("seg.json");
    let out = ok(&["inspect", INPUT, "-p", "groups=3", "--json", &json_path]);
    let j: Value = serde_json::from_str(&std::fs::read_to_string(&json_path).unwrap()).unwrap();
    assert_eq!(j["params"]["groups"], 3);
    let segments = j["segments"].as_array().unwrap();
    assert!(segments.iter().all(|s| as_usize(&s["group_count"]) <= 3), "groups=3 respected");
    assert!(out.contains(&format!("{} segments", segments.len())), "{out}");
    for s in segments {
        let range = format!("frames {}..{}", s["first_frame"], s["last_frame"]);
        assert!(out.contains(&range), "summary lacks '{range}': {out}");
    }
    assert!(out.contains(&json_path), "summary names the JSON file: {out}");
}

#[test]
fn ply_mesh_has_header_vertices_and_colours() {
    let dir = Scratch::new("ply");
    let (ply, json_path) = (dir.path("seg.ply"), dir.path("seg.json"));
    let frame = 25;
    ok(&["inspect", INPUT, "--mesh", &ply, "--frame", &frame.to_string(), "--json", &json_path]);
    let j: Value = serde_json::from_str(&std::fs::read_to_string(&json_path).unwrap()).unwrap();
    let (v, t) = (as_usize(&j["vertices"]), as_usize(&j["triangles"]));
    let seg = j["segments"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| (as_usize(&s["first_frame"])..=as_usize(&s["last_frame"])).contains(&frame))
        .expect("a segment contains the frame");
    let labels: Vec<usize> =
        j["label_sets"][as_usize(&seg["label_set"])].as_array().unwrap().iter().map(as_usize).collect();

    let text = std::fs::read_to_string(&ply).unwrap();
    let (header, body) = text.split_once("end_header\n").expect("PLY header ends");
    let header: Vec<&str> = header.lines().collect();
    assert_eq!(&header[..2], &["ply", "format ascii 1.0"]);
    for needed in [
        format!("element vertex {v}"),
        "property uchar red".into(),
        "property uchar green".into(),
        "property uchar blue".into(),
        format!("element face {t}"),
        "property list uchar uint vertex_indices".into(),
    ] {
        assert!(header.contains(&needed.as_str()), "header lacks '{needed}': {header:?}");
    }
    let lines: Vec<&str> = body.lines().collect();
    assert_eq!(lines.len(), v + t);
    // Vertices with the same label have the same colour, different labels different colours.
    let mut colour_of: Vec<Option<[u8; 3]>> = vec![None; labels.iter().max().unwrap() + 1];
    for (line, &l) in lines[..v].iter().zip(&labels) {
        let f: Vec<&str> = line.split(' ').collect();
        assert_eq!(f.len(), 6, "{line}");
        assert!(f[..3].iter().all(|x| x.parse::<f32>().is_ok_and(f32::is_finite)), "{line}");
        let rgb = [f[3].parse::<u8>().unwrap(), f[4].parse::<u8>().unwrap(), f[5].parse::<u8>().unwrap()];
        assert_eq!(*colour_of[l].get_or_insert(rgb), rgb, "label {l} has two colours");
    }
    let used: Vec<[u8; 3]> = colour_of.into_iter().flatten().collect();
    for a in 0..used.len() {
        for b in a + 1..used.len() {
            assert_ne!(used[a], used[b]);
        }
    }
    for line in &lines[v..] {
        let f: Vec<usize> = line.split(' ').map(|x| x.parse().unwrap()).collect();
        assert_eq!(f.len(), 4);
        assert_eq!(f[0], 3);
        assert!(f[1..].iter().all(|&i| i < v), "{line}");
    }
}

#[test]
fn obj_mesh_has_coloured_vertices() {
    let dir = Scratch::new("obj");
    let obj = dir.path("seg.obj");
    ok(&["inspect", INPUT, "--mesh", &obj]);
    let text = std::fs::read_to_string(&obj).unwrap();
    let vs: Vec<&str> = text.lines().filter(|l| l.starts_with("v ")).collect();
    let fs = text.lines().filter(|l| l.starts_with("f ")).count();
    assert!(!vs.is_empty() && fs > 0);
    for l in &vs {
        let f: Vec<f32> = l[2..].split(' ').map(|x| x.parse().unwrap()).collect();
        assert_eq!(f.len(), 6, "{l}");
        assert!(f[3..].iter().all(|c| (0.0..=1.0).contains(c)), "colour out of 0..1: {l}");
    }
    // The same vertex count as the PLY of the same frame.
    let ply = dir.path("seg.ply");
    ok(&["inspect", INPUT, "--mesh", &ply]);
    let ply_text = std::fs::read_to_string(&ply).unwrap();
    assert!(ply_text.contains(&format!("element vertex {}\n", vs.len())));
}

#[test]
fn bad_inputs_fail_with_clear_messages() {
    let dir = Scratch::new("errors");
    let stl = dir.path("seg.stl");
    fails(&["inspect", INPUT, "--mesh", &stl], &[".ply", ".obj", "seg.stl"]);
    assert!(!std::path::Path::new(&stl).exists(), "nothing written for a bad extension");
    fails(&["inspect", INPUT, "-p", "nonsense=1"], &["stseg", "nonsense", "gamma_max"]);
    fails(&["inspect", INPUT, "-p", "groups=99"], &["stseg", "groups"]);
    fails(&["inspect", INPUT, "-p", "gamma_max=8"], &["gamma_max", "gamma_init"]);
    let frames = animcodec::synth::SynthSize::Small.frames().to_string();
    let frames_text = format!("{frames} frames");
    fails(&["inspect", INPUT, "--frame", &frames, "--mesh", &dir.path("x.ply")], &["out of range", &frames_text]);
    // A point cache without triangles: no OBJ beside it and no --topology.
    let pc2 = dir.path("lonely.pc2");
    ok(&["synth", "tumble", "-o", &pc2]);
    let _ = std::fs::remove_file(dir.path("lonely.obj"));
    fails(&["inspect", &pc2], &["lonely"]);
}
