//! animcodec's USD reader and writer against Pixar's own library, `usd-core` (PyPI), run by
//! `cli/tests/usd/usd_check.py`: layers usd-core writes (usda, usdc, a `.usd` holding a crate
//! file and a usdz package; two meshes with mixed polygons and a left-handed one, a time-code
//! step of 2, meshes sampled at every frame, every other frame or not at all, topology arrays
//! large enough that usd-core integer-codes them) read back exactly, and layers we write
//! (in-process and through `decode -o X.usda` / `-o X.usdc`) open in usd-core with the same
//! points, bit for bit, at every time sample, a correct extent, the layer's metadata, and no
//! error, failed check or warning from its compliance checker (`UsdUtils.ComplianceChecker` or
//! the `UsdValidation` validators, what `usdchecker` runs). Damaged and hostile crate files and
//! packages fail with a clear error, quickly.
//! Without `python3 -c 'import pxr'` (`pip install usd-core`) the tests skip through
//! `codec_core::testing::skip` (a failure under `ANIMCODEC_REQUIRE_ALL=1`, as in CI).

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
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/usd/usd_check.py"))
}

/// `python3` when it imports usd-core, else why not.
fn usd_core() -> Result<(), String> {
    match Command::new("python3").args(["-c", "import pxr.Usd"]).output() {
        Ok(o) if o.status.success() => Ok(()),
        Ok(o) => Err(format!(
            "usd-core not installed (pip install usd-core): {}",
            String::from_utf8_lossy(&o.stderr).lines().last().unwrap_or("")
        )),
        Err(e) => Err(format!("python3 not found: {e}")),
    }
}

fn python(args: &[&str]) -> String {
    let o = Command::new("python3").arg(script()).args(args).output().expect("python3 runs");
    assert!(o.status.success(), "usd_check.py {args:?} failed: {}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout).unwrap()
}

fn f32s(path: &Path) -> Vec<f32> {
    std::fs::read(path).unwrap().chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
}

/// The diagonal of the bounding box of xyz triples.
fn diagonal(p: &[f32]) -> f32 {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for q in p.chunks_exact(3) {
        for k in 0..3 {
            lo[k] = lo[k].min(q[k]);
            hi[k] = hi[k].max(q[k]);
        }
    }
    (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f32>().sqrt()
}

fn same_bits(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

#[test]
fn layers_usd_core_writes_read_back_exactly() {
    if let Err(why) = usd_core() {
        return skip("layers_usd_core_writes_read_back_exactly", &why);
    }
    let dir = Scratch::new("usd-core-writes");
    let cases: Vec<String> = serde_json::from_str(python(&["write", &dir.path("")]).trim()).unwrap();
    assert_eq!(cases.len(), 8);
    for case in &cases {
        let meta: Value =
            serde_json::from_str(&std::fs::read_to_string(dir.path(&format!("{case}.json"))).unwrap()).unwrap();
        let expected = f32s(Path::new(&dir.path(&format!("{case}.f32"))));
        // The case name ends with its file's extension (`.usd` holds a crate file).
        let ext = case.rsplit('-').next().unwrap();
        let layer = dir.path(&format!("{case}.{ext}"));
        let a = read_animation(Path::new(&layer), &ReadOptions::default()).unwrap_or_else(|e| panic!("{case}: {e}"));
        assert_eq!(a.vertex_count() as u64, meta["vertices"].as_u64().unwrap(), "{case}");
        assert_eq!(a.frame_count() as u64, meta["frames"].as_u64().unwrap(), "{case}");
        assert_eq!(a.frame_rate() as f64, meta["fps"].as_f64().unwrap(), "{case}");
        let tris: Vec<[u32; 3]> = serde_json::from_value(meta["triangles"].clone()).unwrap();
        assert_eq!(a.triangles(), tris.as_slice(), "{case}");
        if meta["transformed"] == true {
            // Transformed points: usd-core's XformCache matrices (built through GfRotation and
            // quaternions) and ours (straight from sines and cosines) differ in the last bits;
            // the points must agree to 1e-6 of the bounding-box diagonal at every frame.
            let diag = diagonal(&expected);
            let worst = a.positions().iter().zip(&expected).map(|(x, y)| (x - y).abs()).fold(0.0f32, f32::max);
            assert_eq!(a.positions().len(), expected.len(), "{case}");
            assert!(worst <= 1e-6 * diag, "{case}: off by {worst} (diagonal {diag})");
            eprintln!("{case}: transformed points within {:.2e} of the diagonal", worst / diag);
        } else {
            assert!(same_bits(a.positions(), &expected), "{case}: positions differ from what usd-core wrote");
        }
        // And end to end: the binary encodes the layer losslessly enough to decode it again.
        let anim = dir.path(&format!("{case}.anim"));
        ok(&["encode", &layer, "-c", "quant-delta", "-p", "bits=16", "-o", &anim]);
    }
    // The checker can fail: usd-core's own layer (no metersPerUnit) does not pass it.
    let case = "case-step-two-usda";
    let out = python(&["check", &dir.path(&format!("{case}.usda")), &dir.path(&format!("{case}.f32")), "15"]);
    let r: Value = serde_json::from_str(out.trim()).unwrap();
    assert_eq!(r["coordinates_differing"], 0, "{r}");
    assert!(r["compliance_errors"].to_string().contains("MetersPerUnit"), "{r}");
}

/// Checks one layer we wrote with usd-core: points bit for bit at every time sample, the
/// triangles, the rates, the extent, and the compliance checker's verdict.
fn check_in_usd_core(layer: &str, expected: &Animation, dir: &Scratch, tag: &str) {
    let bin = dir.path(&format!("{tag}.f32"));
    let bytes: Vec<u8> = expected.positions().iter().flat_map(|x| x.to_le_bytes()).collect();
    std::fs::write(&bin, bytes).unwrap();
    let out = python(&["check", layer, &bin, &expected.frame_rate().to_string()]);
    let r: Value = serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("{tag}: {e}: {out}"));
    assert_eq!(r["errors"], Value::Array(vec![]), "{tag}: {r}");
    assert_eq!(r["meshes"], 1, "{tag}");
    assert_eq!(r["time_samples"].as_u64().unwrap(), expected.frame_count() as u64, "{tag}");
    let n = expected.positions().len() as u64;
    assert_eq!(r["coordinates_checked"].as_u64().unwrap(), n, "{tag}");
    assert_eq!(r["coordinates_differing"], 0, "{tag}: usd-core reads other points than we wrote");
    assert_eq!(r["time_codes_per_second"].as_f64().unwrap() as f32, expected.frame_rate(), "{tag}");
    assert_eq!(r["frames_per_second"].as_f64().unwrap() as f32, expected.frame_rate(), "{tag}");
    assert_eq!(r["start_time_code"], 0.0, "{tag}");
    assert_eq!(r["end_time_code"].as_f64().unwrap(), (expected.frame_count() - 1) as f64, "{tag}");
    assert_eq!(r["up_axis"], "Y", "{tag}");
    assert_eq!(r["meters_per_unit"], 1.0, "{tag}");
    assert_eq!(r["default_prim"], "/animcodec", "{tag}");
    let format = if layer.ends_with(".usdc") { "usdc" } else { "usda" };
    assert_eq!(r["format"], format, "{tag}: usd-core reads the layer as another format");
    let tris: Vec<[u32; 3]> = serde_json::from_value(r["triangles"].clone()).unwrap();
    assert_eq!(tris.as_slice(), expected.triangles(), "{tag}");
    eprintln!(
        "{tag}: usd-core checked {n} coordinates at {} time samples, checker: {}",
        r["time_samples"], r["checker"]
    );
    for key in ["compliance_errors", "compliance_failed_checks", "compliance_warnings"] {
        assert_eq!(r[key], Value::Array(vec![]), "{tag}: {key}: {r}");
    }
}

#[test]
fn layers_we_write_open_in_usd_core_and_pass_its_compliance_checker() {
    if let Err(why) = usd_core() {
        return skip("layers_we_write_open_in_usd_core_and_pass_its_compliance_checker", &why);
    }
    let dir = Scratch::new("usd-we-write");
    // In-process, on values with awkward decimal expansions (negative zero, 1e30, tiny normals).
    let awkward = common::awkward_animation();
    for ext in ["usda", "usdc"] {
        let layer = dir.path(&format!("awkward.{ext}"));
        write_animation(Path::new(&layer), &awkward).unwrap();
        check_in_usd_core(&layer, &awkward, &dir, &format!("awkward-{ext}"));
    }

    // Through the binary: a synthetic animation encoded, then `decode -o X.usda`.
    let flag = synth::by_name("flag", SynthSize::Small).unwrap();
    let pc2 = dir.path("flag.pc2");
    write_animation(Path::new(&pc2), &flag).unwrap();
    let anim = dir.path("flag.anim");
    ok(&["encode", &pc2, "-c", "quant-delta", "-p", "bits=12", "-o", &anim]);
    let usda = dir.path("flag.usda");
    let back_pc2 = dir.path("back.pc2");
    ok(&["decode", &anim, "-o", &usda]);
    ok(&["decode", &anim, "-o", &back_pc2, "--topology-obj"]);
    let decoded = read_animation(Path::new(&back_pc2), &ReadOptions::default()).unwrap();
    check_in_usd_core(&usda, &decoded, &dir, "flag");
    // What we wrote reads back through our own reader as the decode, exactly.
    let ours = read_animation(Path::new(&usda), &ReadOptions::default()).unwrap();
    assert!(same_bits(ours.positions(), decoded.positions()));
    assert_eq!(ours.triangles(), decoded.triangles());
    // And as a crate file, through the binary.
    let usdc = dir.path("flag.usdc");
    ok(&["decode", &anim, "-o", &usdc]);
    check_in_usd_core(&usdc, &decoded, &dir, "flag-usdc");
    let ours = read_animation(Path::new(&usdc), &ReadOptions::default()).unwrap();
    assert!(same_bits(ours.positions(), decoded.positions()));
    assert_eq!(ours.triangles(), decoded.triangles());
}

/// usd-core's view of a layer's stage: up axis, units, time codes per second and the first
/// time samples of its first mesh.
fn stage_view(r: &Value) -> Value {
    serde_json::json!([r["up_axis"], r["meters_per_unit"], r["time_codes_per_second"], r["times"]])
}

/// Layers as pipelines author them (+Z up, centimetres, animated xformOps; 30 time codes per
/// second sampled every 2 codes from code 10) keep their stage metadata and time codes through
/// our reader and writers, in-process and through `encode` / `decode`; an Alembic written from
/// a +Z-up stream is turned +Y up, as DCCs read Alembic.
#[test]
fn stage_metadata_survives_read_encode_decode_and_write() {
    if let Err(why) = usd_core() {
        return skip("stage_metadata_survives_read_encode_decode_and_write", &why);
    }
    let dir = Scratch::new("usd-stage-metadata");
    let cases: Vec<String> = serde_json::from_str(python(&["write", &dir.path("")]).trim()).unwrap();
    let mut checked = 0;
    for case in ["case-xforms-usda", "case-xforms-usdc", "case-step-two-usda"] {
        assert!(cases.iter().any(|c| c == case), "usd_check.py no longer writes {case}");
        let ext = case.rsplit('-').next().unwrap();
        let source = dir.path(&format!("{case}.{ext}"));
        let f32_of = |a: &Animation, tag: &str| {
            let bin = dir.path(&format!("{tag}.f32"));
            std::fs::write(&bin, a.positions().iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>()).unwrap();
            bin
        };
        let a = read_animation(Path::new(&source), &ReadOptions::default()).unwrap();
        let fps = a.frame_rate().to_string();
        let src_view =
            stage_view(&serde_json::from_str(python(&["check", &source, &f32_of(&a, case), &fps]).trim()).unwrap());
        // In-process: positions bit for bit, the stage as the source's.
        for out_ext in ["usda", "usdc"] {
            let out = dir.path(&format!("{case}-ours.{out_ext}"));
            write_animation(Path::new(&out), &a).unwrap();
            let r: Value = serde_json::from_str(python(&["check", &out, &f32_of(&a, case), &fps]).trim()).unwrap();
            assert_eq!(r["coordinates_differing"], 0, "{case} -> {out_ext}: {r}");
            assert_eq!(stage_view(&r), src_view, "{case} -> {out_ext}: the stage metadata changed");
            checked += 1;
        }
        // Through a stream: `info` shows the metadata; the decoded layer keeps it.
        let anim = dir.path(&format!("{case}.anim"));
        ok(&["encode", &source, "-c", "quant-delta", "-p", "bits=16", "-o", &anim]);
        let info = common::ok_json(&["info", &anim, "--json"]);
        // 4 carries the metadata; 5 also does, when the topology uses method 3.
        assert!([4, 5].contains(&info["container_version"].as_u64().unwrap_or(0)), "{case}: {info}");
        assert_eq!(info["metadata"]["time_codes_per_second"], src_view[2], "{case}: {info}");
        let pc2 = dir.path(&format!("{case}-decoded.pc2"));
        ok(&["decode", &anim, "-o", &pc2, "--topology-obj"]);
        let decoded = read_animation(Path::new(&pc2), &ReadOptions::default()).unwrap();
        let usdc = dir.path(&format!("{case}-decoded.usdc"));
        ok(&["decode", &anim, "-o", &usdc]);
        let r: Value = serde_json::from_str(python(&["check", &usdc, &f32_of(&decoded, case), &fps]).trim()).unwrap();
        assert_eq!(r["coordinates_differing"], 0, "{case}: decoded usdc: {r}");
        assert_eq!(stage_view(&r), src_view, "{case}: the decoded layer lost the stage metadata");
        // Alembic states no up axis: a +Z-up stream is written +Y up, (x, y, z) -> (x, z, -y).
        let abc = dir.path(&format!("{case}-decoded.abc"));
        ok(&["decode", &anim, "-o", &abc]);
        let back = read_animation(Path::new(&abc), &ReadOptions::default()).unwrap();
        let z_up = src_view[0] == "Z";
        let want: Vec<f32> = if z_up {
            decoded.positions().chunks_exact(3).flat_map(|p| [p[0], p[2], -p[1]]).collect()
        } else {
            decoded.positions().to_vec()
        };
        assert!(same_bits(back.positions(), &want), "{case}: the Alembic is not the decode turned +Y up");
        // Its time line starts where the source's did.
        let start = src_view[3][0].as_f64().unwrap();
        assert_eq!(
            back.metadata().start_time_code.unwrap_or(0.0) / back.frame_rate() as f64,
            start / r["time_codes_per_second"].as_f64().unwrap(),
            "{case}"
        );
        checked += 1;
    }
    assert_eq!(checked, 9);
}

/// Damaged and hostile crate files and packages, through the binary: one clear `error:` line
/// naming the file and what is wrong, quickly, with no panic (no usd-core needed).
#[test]
fn hostile_crate_files_and_packages_fail_cleanly() {
    let dir = Scratch::new("usdc-hostile");
    let anim = synth::by_name("flag", SynthSize::Small).unwrap();
    let good = dir.path("good.usdc");
    write_animation(Path::new(&good), &anim).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    // A `.usd` holding crate content reads as the crate file it is.
    let as_usd = dir.path("crate.usd");
    std::fs::write(&as_usd, &bytes).unwrap();
    let back = read_animation(Path::new(&as_usd), &ReadOptions::default()).unwrap();
    assert!(same_bits(back.positions(), anim.positions()));
    let toc = u64::from_le_bytes(bytes[16..24].try_into().unwrap()) as usize;
    let mut cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("truncated.usdc", bytes[..bytes.len() / 2].to_vec(), "table of contents"),
        ("no-toc.usdc", bytes[..toc + 20].to_vec(), "table of contents"),
    ];
    let mut section_past = bytes.clone();
    section_past[toc + 8 + 16..toc + 8 + 24].copy_from_slice(&(bytes.len() as u64).to_le_bytes());
    cases.push(("section-past.usdc", section_past, "runs past the end"));
    // A usdz whose entry states more bytes than the archive holds, in both its headers.
    let mut z = usdz(&bytes);
    let directory = u32::from_le_bytes(z[z.len() - 6..z.len() - 2].try_into().unwrap()) as usize;
    for at in [18, 22, directory + 20, directory + 24] {
        z[at..at + 4].copy_from_slice(&(1u32 << 31).to_le_bytes());
    }
    cases.push(("size-lie.usdz", z, "past the end of its data"));
    let mut deflated = usdz(&bytes);
    deflated[8] = 8;
    cases.push(("deflated.usdz", deflated, "compressed"));
    for (name, data, needle) in cases {
        let path = dir.path(name);
        std::fs::write(&path, data).unwrap();
        let out = dir.path(&format!("{name}.anim"));
        let t = std::time::Instant::now();
        common::fails(&["encode", &path, "-c", "quant-delta", "-o", &out], &[name, needle]);
        assert!(t.elapsed().as_secs_f64() < 1.0, "{name}: {:?}", t.elapsed());
    }
    // The package of the good file reads.
    let good_z = dir.path("good.usdz");
    std::fs::write(&good_z, usdz(&bytes)).unwrap();
    let back = read_animation(Path::new(&good_z), &ReadOptions::default()).unwrap();
    assert!(same_bits(back.positions(), anim.positions()));
}

/// A one-entry usdz package (a stored zip) holding `layer` as `root.usdc`.
fn usdz(layer: &[u8]) -> Vec<u8> {
    let crc = crc32(layer);
    let name = b"root.usdc";
    let mut z = Vec::new();
    let fixed = |z: &mut Vec<u8>| {
        z.extend_from_slice(&[20, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
        z.extend_from_slice(&crc.to_le_bytes());
        z.extend_from_slice(&(layer.len() as u32).to_le_bytes());
        z.extend_from_slice(&(layer.len() as u32).to_le_bytes());
        z.extend_from_slice(&(name.len() as u16).to_le_bytes());
    };
    z.extend_from_slice(&0x0403_4b50u32.to_le_bytes());
    fixed(&mut z);
    z.extend_from_slice(&0u16.to_le_bytes());
    z.extend_from_slice(name);
    z.extend_from_slice(layer);
    let directory = z.len();
    z.extend_from_slice(&0x0201_4b50u32.to_le_bytes());
    z.extend_from_slice(&20u16.to_le_bytes());
    fixed(&mut z);
    z.extend_from_slice(&[0; 16]);
    z.extend_from_slice(name);
    let size = z.len() - directory;
    z.extend_from_slice(&0x0605_4b50u32.to_le_bytes());
    z.extend_from_slice(&[0, 0, 0, 0, 1, 0, 1, 0]);
    z.extend_from_slice(&(size as u32).to_le_bytes());
    z.extend_from_slice(&(directory as u32).to_le_bytes());
    z.extend_from_slice(&0u16.to_le_bytes());
    z
}

fn crc32(data: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in data {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 != 0 { 0xEDB8_8320 ^ (crc >> 1) } else { crc >> 1 };
        }
    }
    !crc
}
