//! animcodec's Alembic reader and writer against the reference library, PyAlembic (the
//! `alembic3d` wheel: `pip install alembic3d numpy`), run by `cli/tests/alembic/abc_check.py`:
//! archives alembic3d writes (uniform, cyclic and acyclic time sampling, quads and mixed
//! polygons, an Xform chain with every operation type and a non-inheriting transform, two
//! meshes merged or chosen with `--object`, a SubD beside a static mesh) read back with exactly
//! the world-space points alembic3d reads, the same frame count and rate; and archives we
//! write (`decode -o X.abc`, `export`-style writes) open in alembic3d with the decoded
//! points bit for bit at every sample, uniform time sampling at the frame rate and Alembic's
//! clockwise faces. The Python is `python3`, or `$ANIMCODEC_PYTHON` when set (a venv with
//! alembic3d); without `import alembic3d` the tests skip through `codec_core::testing::skip`
//! (a failure under `ANIMCODEC_REQUIRE_ALL=1`, as in CI).

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use animcodec::formats::{read_animation, write_animation, ReadOptions};
use animcodec::synth::{self, SynthSize};
use codec_core::testing::skip;
use codec_core::Animation;
use common::{fails, ok, ok_json, Scratch};
use serde_json::Value;

fn script() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/alembic/abc_check.py"))
}

fn python_exe() -> String {
    std::env::var("ANIMCODEC_PYTHON").unwrap_or_else(|_| "python3".into())
}

/// Ok when the Python imports alembic3d, else why not.
fn alembic3d() -> Result<(), String> {
    match Command::new(python_exe()).args(["-c", "import alembic3d, imath"]).output() {
        Ok(o) if o.status.success() => Ok(()),
        Ok(o) => Err(format!(
            "alembic3d not installed (pip install alembic3d numpy): {}",
            String::from_utf8_lossy(&o.stderr).lines().last().unwrap_or("")
        )),
        Err(e) => Err(format!("{} not found: {e}", python_exe())),
    }
}

fn python(args: &[&str]) -> String {
    let o = Command::new(python_exe()).arg(script()).args(args).output().expect("python runs");
    assert!(o.status.success(), "abc_check.py {args:?} failed: {}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout).unwrap()
}

fn f32s(path: &Path) -> Vec<f32> {
    std::fs::read(path).unwrap().chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
}

/// Coordinates whose bits differ.
fn differing(a: &[f32], b: &[f32]) -> usize {
    a.iter().zip(b).filter(|(x, y)| x.to_bits() != y.to_bits()).count() + a.len().abs_diff(b.len())
}

#[test]
fn archives_alembic3d_writes_read_back_exactly() {
    if let Err(why) = alembic3d() {
        return skip("archives_alembic3d_writes_read_back_exactly", &why);
    }
    let dir = Scratch::new("abc-alembic3d-writes");
    let cases: Vec<String> = serde_json::from_str(python(&["write", &dir.path("")]).trim()).unwrap();
    assert_eq!(cases.len(), 6, "{cases:?}");
    for case in &cases {
        let meta: Value =
            serde_json::from_str(&std::fs::read_to_string(dir.path(&format!("{case}.json"))).unwrap()).unwrap();
        let abc = meta["abc"].as_str().unwrap();
        let object = meta["object"].as_str().map(str::to_owned);
        let options = ReadOptions { object: object.clone(), ..Default::default() };
        let a = read_animation(Path::new(abc), &options).unwrap_or_else(|e| panic!("{case}: {e}"));
        assert_eq!(a.vertex_count() as u64, meta["vertices"].as_u64().unwrap(), "{case}");
        assert_eq!(a.frame_count() as u64, meta["frames"].as_u64().unwrap(), "{case}");
        assert_eq!(a.triangles().len() as u64, meta["triangles"].as_u64().unwrap(), "{case}");
        assert_eq!(a.frame_rate() as f64, meta["fps"].as_f64().unwrap(), "{case}");
        let expected = f32s(Path::new(&dir.path(&format!("{case}.f32"))));
        assert_eq!(differing(a.positions(), &expected), 0, "{case}: points differ from what alembic3d reads");
        // Through the binary too: encode (with --object when the case selects one).
        let anim = dir.path(&format!("{case}.anim"));
        let mut args = vec!["encode", abc, "-c", "quant-delta", "-p", "bits=16", "-o", &anim];
        if let Some(o) = &object {
            args.extend(["--object", o]);
        }
        ok(&args);
    }
    // Faces wind counter-clockwise after reading: the quad [0, 3, 4, 1] (clockwise in the file)
    // becomes [0, 4, 3], [0, 1, 4].
    let quads = read_animation(Path::new(&dir.path("quads-uniform.abc")), &ReadOptions::default()).unwrap();
    assert_eq!(&quads.triangles()[..2], &[[0, 4, 3], [0, 1, 4]]);
    // list-animations / info list the meshes with their sizes.
    let listed = ok_json(&["list-animations", &dir.path("xform-chain.abc"), "--json"]);
    let meshes = listed["meshes"].as_array().unwrap();
    assert_eq!(meshes.len(), 2, "{listed}");
    assert_eq!(meshes[0]["path"], "/rig/arm/quads");
    assert_eq!((meshes[0]["vertices"].as_u64(), meshes[0]["faces"].as_u64()), (Some(6), Some(2)));
    assert_eq!(meshes[1]["path"], "/rig/free/tri");
    assert_eq!(meshes[1]["frames"], 5);
    let text = ok(&["info", &dir.path("subd.abc")]);
    assert!(text.contains("/x/cage  SubD  6 vertices, 2 faces") && text.contains("/still  PolyMesh"), "{text}");
    // Refusals name the problem: uneven samples, an unknown object.
    fails(&["encode", &dir.path("uneven.abc"), "-c", "quant-delta", "-o", &dir.path("u.anim")], &["evenly spaced"]);
    fails(
        &["encode", &dir.path("subd.abc"), "--object", "/nope", "-c", "quant-delta", "-o", &dir.path("n.anim")],
        &["/nope", "/x/cage", "/still"],
    );
}

/// Checks an archive we wrote with alembic3d: one mesh, its samples bit for bit, uniform time
/// sampling at the frame rate, triangles (wound clockwise) and FramesPerTimeUnit.
fn check_in_alembic3d(abc: &str, expected: &Animation, dir: &Scratch, tag: &str) {
    let bin = dir.path(&format!("{tag}.f32"));
    let bytes: Vec<u8> = expected.positions().iter().flat_map(|x| x.to_le_bytes()).collect();
    std::fs::write(&bin, bytes).unwrap();
    let out = python(&["check", abc, &bin]);
    let r: Value = serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("{tag}: {e}: {out}"));
    assert_eq!(r["meshes"], serde_json::json!(["/animcodec/mesh"]), "{tag}: {r}");
    assert_eq!(r["samples"].as_u64().unwrap(), expected.frame_count() as u64, "{tag}");
    assert_eq!(r["uniform"], true, "{tag}");
    assert_eq!(r["topology"], "kHomogenousTopology", "{tag}: {r}");
    let step = r["time_per_sample"].as_f64().unwrap();
    assert_eq!((1.0 / step) as f32, expected.frame_rate(), "{tag}");
    let n = expected.positions().len() as u64;
    assert_eq!(r["coordinates_checked"].as_u64().unwrap(), n, "{tag}");
    assert_eq!(r["coordinates_differing"], 0, "{tag}: alembic3d reads other points than we wrote");
    assert_eq!(r["face_counts"], serde_json::json!([3]), "{tag}");
    let faces: Vec<[u32; 3]> = serde_json::from_value(r["faces"].clone()).unwrap();
    let ccw: Vec<[u32; 3]> = faces.iter().map(|f| [f[0], f[2], f[1]]).collect();
    assert_eq!(ccw.as_slice(), expected.triangles(), "{tag}");
    let md = r["archive_metadata"].as_str().unwrap();
    assert!(md.contains(&format!("FramesPerTimeUnit={:.6}", expected.frame_rate())), "{tag}: {md}");
    eprintln!("{tag}: alembic3d checked {n} coordinates at {} samples", r["samples"]);
}

#[test]
fn archives_we_write_open_in_alembic3d_bit_exact() {
    if let Err(why) = alembic3d() {
        return skip("archives_we_write_open_in_alembic3d_bit_exact", &why);
    }
    let dir = Scratch::new("abc-we-write");
    // In-process, on values with awkward binary expansions (negative zero, 1e30, tiny normals).
    let awkward = common::awkward_animation();
    let abc = dir.path("awkward.abc");
    write_animation(Path::new(&abc), &awkward).unwrap();
    check_in_alembic3d(&abc, &awkward, &dir, "awkward");

    // Through the binary: a synthetic animation encoded, then `decode -o X.abc`.
    let flag = synth::by_name("flag", SynthSize::Small).unwrap();
    let pc2 = dir.path("flag.pc2");
    write_animation(Path::new(&pc2), &flag).unwrap();
    let anim = dir.path("flag.anim");
    ok(&["encode", &pc2, "-c", "quant-delta", "-p", "bits=12", "-o", &anim]);
    let abc = dir.path("flag.abc");
    let back_pc2 = dir.path("back.pc2");
    ok(&["decode", &anim, "-o", &abc]);
    ok(&["decode", &anim, "-o", &back_pc2, "--topology-obj"]);
    let decoded = read_animation(Path::new(&back_pc2), &ReadOptions::default()).unwrap();
    check_in_alembic3d(&abc, &decoded, &dir, "flag");
    // What we wrote reads back through our own reader as the decode, exactly, at its rate.
    let ours = read_animation(Path::new(&abc), &ReadOptions::default()).unwrap();
    assert_eq!(differing(ours.positions(), decoded.positions()), 0);
    assert_eq!(ours.triangles(), decoded.triangles());
    assert_eq!(ours.frame_rate(), decoded.frame_rate());
    // The safe-output policy: an existing .abc is not replaced without --force.
    fails(&["decode", &anim, "-o", &abc], &["flag.abc"]);
    ok(&["decode", &anim, "-o", &abc, "--force"]);
}

/// Hostile archives through the binary: one-line errors, exit 1, no panic, quickly.
#[test]
fn hostile_archives_fail_with_one_line_errors() {
    let dir = Scratch::new("abc-hostile");
    let a = synth::by_name("tumble", SynthSize::Small).unwrap();
    let abc = dir.path("good.abc");
    write_animation(Path::new(&abc), &a).unwrap();
    let good = std::fs::read(&abc).unwrap();
    let out = dir.path("x.anim");
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("truncated.abc", good[..good.len() / 2].to_vec(), "past the end"),
        ("hdf5.abc", b"\x89HDF\r\n\x1a\n and more".to_vec(), "HDF5"),
        ("unfrozen.abc", [&good[..5], &[0u8], &good[6..]].concat(), "not closed"),
        ("empty.abc", Vec::new(), "Ogawa"),
    ];
    for (name, bytes, needle) in cases {
        let p = dir.path(name);
        std::fs::write(&p, bytes).unwrap();
        let start = std::time::Instant::now();
        fails(&["encode", &p, "-c", "quant-delta", "-o", &out], &[name, needle]);
        assert!(start.elapsed().as_secs_f64() < 2.0, "{name}: {:?}", start.elapsed());
    }
}
