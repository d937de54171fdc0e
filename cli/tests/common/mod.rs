//! Helpers shared by the end-to-end tests of the `animcodec` binary (`cli.rs`, `harness.rs`,
//! `inspect.rs`, `rate_search.rs`, …): run it, expect success or a one-line error, scratch
//! directories, and the harness search request the library-level tests share.

// Each test binary compiles this module and uses a different subset of it.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use animcodec::core::{Animation, CodecRegistry};
use animcodec::harness::{SearchRequest, Target};
use animcodec::metrics::EvalOptions;
use serde_json::Value;

/// Runs the `animcodec` binary built for these tests.
pub fn animcodec(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_animcodec")).args(args).output().expect("the animcodec binary runs")
}

/// The captured standard output, lossily decoded.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The captured standard error, lossily decoded.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs a command expected to succeed and returns its stdout.
pub fn ok(args: &[&str]) -> String {
    let o = animcodec(args);
    assert!(o.status.success(), "animcodec {args:?} failed: {}", stderr(&o));
    stdout(&o)
}

/// Runs a command expected to succeed and print JSON, and parses it.
pub fn ok_json(args: &[&str]) -> Value {
    let text = ok(args);
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("animcodec {args:?} printed invalid JSON ({e}): {text}"))
}

/// Runs a command expected to fail with exit code 1 and a single `error:` line containing
/// every one of `needles`; returns that line.
pub fn fails(args: &[&str], needles: &[&str]) -> String {
    let o = animcodec(args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "animcodec {args:?}: expected exit 1, stderr: {err}");
    assert!(!err.contains("panicked"), "animcodec {args:?} panicked: {err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "animcodec {args:?}: expected one line of stderr, got: {err}");
    assert!(lines[0].starts_with("error: "), "{err}");
    for n in needles {
        assert!(err.contains(n), "animcodec {args:?}: stderr does not mention '{n}': {err}");
    }
    err
}

/// A scratch directory unique to this test process and test, removed on drop.
pub struct Scratch(pub PathBuf);

impl Scratch {
    /// Creates (emptied) `$TMP/animcodec-test-<pid>-<test>`.
    pub fn new(test: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("animcodec-test-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Self(dir)
    }

    /// A file path inside the directory, as a string for command lines.
    pub fn path(&self, name: &str) -> String {
        self.0.join(name).to_string_lossy().into_owned()
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[allow(unused_imports)]
pub use codec_core::error::looks_like_debug as has_debug_value;

/// The search request of these tests: `eval`'s metric options, default limits, `refine` extra
/// points, no progress reports.
pub fn request<'a>(
    registry: &'a CodecRegistry,
    animation: &'a Animation,
    target: Target,
    eval: &EvalOptions,
    refine: usize,
) -> SearchRequest<'a> {
    SearchRequest { eval: *eval, refine, ..SearchRequest::new(registry, animation, target) }
}

/// The `cli/tests/gltf` folder when Node.js and the npm `packages` are installed there
/// (`bash cli/tests/gltf/install.sh`), else why not (for `codec_core::testing::skip`).
pub fn node_packages(packages: &[&str]) -> Result<PathBuf, String> {
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/gltf"));
    for package in packages {
        if !dir.join("node_modules").join(package).exists() {
            return Err(format!("npm package {package} not installed (bash cli/tests/gltf/install.sh)"));
        }
    }
    if Command::new("node").arg("--version").output().is_err() {
        return Err("node not found".into());
    }
    Ok(dir)
}

/// A file of `../shared/data` (the real animations), or `None` when it is absent.
pub fn shared_data(rel: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data").join(rel);
    p.is_file().then_some(p)
}

/// Runs gltfpack (npm `gltfpack` in `tools`, from [`node_packages`]) with `args` on `input`.
pub fn gltfpack(tools: &Path, input: &Path, output: &Path, args: &[&str]) {
    let o = Command::new("node")
        .arg(tools.join("node_modules/gltfpack/cli.js"))
        .args(args)
        .arg("-i")
        .arg(input)
        .arg("-o")
        .arg(output)
        .output()
        .unwrap();
    assert!(o.status.success(), "gltfpack failed on {}: {}", input.display(), String::from_utf8_lossy(&o.stderr));
}

/// A GLB's JSON and BIN chunk.
pub fn split_glb(glb: &[u8]) -> (serde_json::Value, Vec<u8>) {
    let u32_at = |at: usize| u32::from_le_bytes(glb[at..at + 4].try_into().unwrap()) as usize;
    let json_len = u32_at(12);
    let json = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let bin_len = u32_at(20 + json_len);
    (json, glb[28 + json_len..28 + json_len + bin_len].to_vec())
}

/// A GLB from JSON and a BIN chunk (both padded to 4 bytes), as the probes' glb.py writes it.
pub fn join_glb(json: &serde_json::Value, bin: &[u8]) -> Vec<u8> {
    let mut js = serde_json::to_vec(json).unwrap();
    js.resize(js.len().next_multiple_of(4), b' ');
    let mut bin = bin.to_vec();
    bin.resize(bin.len().next_multiple_of(4), 0);
    let total = 12 + 8 + js.len() + 8 + bin.len();
    let mut out = b"glTF".to_vec();
    for x in [2, total as u32, js.len() as u32] {
        out.extend(x.to_le_bytes());
    }
    out.extend(b"JSON");
    out.extend(&js);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(&bin);
    out
}

/// `Ok` when `python3` imports usd-core (`pip install usd-core`), else why not.
pub fn usd_core() -> Result<(), String> {
    match Command::new("python3").args(["-c", "import pxr.Usd, pxr.UsdSkel"]).output() {
        Ok(o) if o.status.success() => Ok(()),
        Ok(o) => Err(format!(
            "usd-core not installed (pip install usd-core): {}",
            String::from_utf8_lossy(&o.stderr).lines().last().unwrap_or("")
        )),
        Err(e) => Err(format!("python3 not found: {e}")),
    }
}

/// usd-core's own UsdSkel evaluation of `file` (`cli/tests/usd/skel_check.py reference`):
/// world-space points at every integer time code from startTimeCode to endTimeCode, meshes in
/// traversal order, as an animation without triangles.
pub fn usd_core_skel_reference(file: &Path, scratch: &Path) -> Animation {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/usd/skel_check.py");
    let out = scratch.join(format!("{}.ref.f32", file.file_name().unwrap().to_string_lossy()));
    let o = Command::new("python3").arg(script).arg("reference").arg(file).arg(&out).output().expect("python3 runs");
    assert!(o.status.success(), "skel_check.py reference {file:?} failed: {}", String::from_utf8_lossy(&o.stderr));
    let info: Value = serde_json::from_slice(o.stdout.trim_ascii()).expect("one JSON line");
    let positions: Vec<f32> =
        std::fs::read(&out).unwrap().chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    let vertices = info["vertices"].as_u64().unwrap() as usize;
    assert_eq!(positions.len(), vertices * 3 * info["frames"].as_u64().unwrap() as usize, "{info}");
    Animation::from_parts(vertices, Vec::new(), positions, 24.0).unwrap()
}

/// The largest coordinate difference between two animations of the same vertices in the same
/// order, over the bounding-box diagonal of `reference`.
pub fn worst_over_diagonal(reference: &Animation, ours: &Animation) -> f64 {
    assert_eq!(reference.vertex_count(), ours.vertex_count(), "vertex count");
    assert_eq!(reference.frame_count(), ours.frame_count(), "frame count");
    reference.positions().iter().zip(ours.positions()).map(|(a, b)| (a - b).abs() as f64).fold(0.0, f64::max)
        / reference.bounding_box_diagonal()
}

/// `Ok` when `python3` imports Blender 5 as the `bpy` module (`pip install bpy==5.0.1`), else
/// why not: the condition of the Blender client tests.
pub fn blender5() -> Result<(), String> {
    let probe = "import bpy; print(bpy.app.version_string)";
    match Command::new("python3").args(["-c", probe]).output() {
        Ok(o) if o.status.success() && String::from_utf8_lossy(&o.stdout).trim_start().starts_with("5.") => Ok(()),
        Ok(o) if o.status.success() => {
            Err(format!("bpy {} is not Blender 5 (pip install bpy==5.0.1)", String::from_utf8_lossy(&o.stdout).trim()))
        }
        Ok(o) => {
            Err(format!("bpy not installed (pip install bpy==5.0.1): {}", String::from_utf8_lossy(&o.stderr).trim()))
        }
        Err(e) => Err(format!("python3 not found: {e}")),
    }
}

/// 9 vertices × 6 frames at 29.97 fps whose coordinates have awkward binary and decimal
/// expansions (negative zero, 1e30, subnormal-adjacent values): what a writer must carry exactly.
pub fn awkward_animation() -> Animation {
    let positions: Vec<f32> = (0..6 * 9 * 3)
        .map(|i| match i % 6 {
            0 => -0.0,
            1 => (i as f32 * 0.1).sin() * 1e-3,
            2 => 1.0 / 3.0 + i as f32,
            3 => -(i as f32).sqrt() * 12345.678,
            4 => 1e30 / (i as f32 + 1.0),
            _ => f32::MIN_POSITIVE * (i + 1) as f32,
        })
        .collect();
    let tris: Vec<[u32; 3]> = (0..7).map(|v| [v, v + 1, v + 2]).collect();
    Animation::from_parts(9, tris, positions, 29.97).unwrap()
}

/// A usd-core-written layer as pipelines author it (`cli/tests/usd/usd_check.py write`:
/// `case-xforms-usdc.usdc`, +Z up, `metersPerUnit` 0.01, animated xformOps; needs
/// [`usd_core`]) and usd-core's world-space points of every frame turned into what glTF shows
/// (+Y up in metres: `(x, y, z) → (x, z, −y) × 0.01`, in `f64`, rounded once), as an animation
/// without triangles.
pub fn z_up_centimetre_layer(dir: &Scratch) -> (String, Animation) {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/usd/usd_check.py");
    let o = Command::new("python3").arg(script).arg("write").arg(&dir.0).output().expect("python3 runs");
    assert!(o.status.success(), "usd_check.py write failed: {}", String::from_utf8_lossy(&o.stderr));
    let source = dir.path("case-xforms-usdc.usdc");
    let info: Value = serde_json::from_slice(&std::fs::read(dir.path("case-xforms-usdc.json")).unwrap()).unwrap();
    let points: Vec<f32> = std::fs::read(dir.path("case-xforms-usdc.f32"))
        .unwrap()
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    let shown = points
        .chunks_exact(3)
        .flat_map(|p| [p[0] as f64 * 0.01, p[2] as f64 * 0.01, -(p[1] as f64) * 0.01].map(|x| x as f32))
        .collect();
    let vertices = info["vertices"].as_u64().unwrap() as usize;
    (source, Animation::from_parts(vertices, Vec::new(), shown, info["fps"].as_f64().unwrap() as f32).unwrap())
}
