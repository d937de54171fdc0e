//! USD in and out: time-sampled `UsdGeomMesh` prims of text layers (`.usda`), crate files
//! (`.usdc`, [`super::usdc`]) and usdz packages (read only; their root layer). A `.usd` file
//! may hold either a text layer or a crate file: the reader goes by the first bytes (`#usda`,
//! `PXR-USDC`, a zip's `PK`), never by the extension.
//!
//! **Read** ([`parse_usd`]): both the text parser (`usd_text`) and the crate reader fill one layer
//! model (`usd_layer`), and one assembly (`usd_assemble`) makes the animation. Every `def Mesh` of the layer (depth-first, in authored order, as
//! `UsdStage::Traverse` visits them; prims under `class`/`over` specs and `active = false` prims
//! are not part of the played-back scene and are skipped) becomes part of one vertex cache, its
//! vertices after those of the meshes before it. From each mesh: `points` (the default value
//! and/or `points.timeSamples`), `faceVertexCounts` / `faceVertexIndices` (polygons fanned into
//! triangles from their first corner) and `orientation` (`leftHanded` faces are flipped, so the
//! triangles keep the right-handed winding the other formats use).
//!
//! Frames are the union of every mesh's time codes, sorted; they must be evenly spaced (the
//! [`Animation`] has one frame rate). A mesh without a sample at a frame's time code is evaluated
//! as USD does (`UsdAttribute::Get(time)`, linear interpolation of equal-length arrays between
//! the samples around it, held before the first and after the last). The frame rate is the
//! layer's `timeCodesPerSecond` (else `framesPerSecond`, else USD's 24) divided by the time-code
//! step, unless [`ReadOptions::frame_rate`](super::ReadOptions::frame_rate) overrides it.
//!
//! The `xformOp`s of each mesh and of its ancestors (`xformOpOrder`, `usd_xform`) are applied
//! to its points at every frame; ops sampled at other times than the points add those frames.
//! Meshes bound to a `UsdSkel` skeleton or blend shapes are evaluated as UsdSkel plays them
//! (`usd_skel`: blend shapes, then linear blend skinning into the Skeleton's space, placed by
//! the Skeleton's transforms); the animation's samples add frames too.
//!
//! What is refused by name rather than read wrongly: composition arcs (`subLayers`,
//! `references`, `payload`, `inherits`, `specializes`, variant sets: flatten the stage first,
//! with usd-core's `Usd.Stage.Open(IN).Export(OUT)`), the UsdSkel features not evaluated
//! (inbetween shapes, dual-quaternion skinning, indexed skinning primvars, bindings without
//! `SkelBindingAPI` or outside a `SkelRoot`), a time-sampled topology, points whose count
//! changes over time, value clips, spline-valued points and ops.
//!
//! The input is untrusted: nesting is bounded ([`MAX_DEPTH`]), every array is counted against
//! the read's memory budget before it is kept, the cache's size is checked against
//! [`reader_limits`](super::reader_limits) and the budget before it is allocated, and every
//! coordinate must be finite.
//!
//! **Write** ([`encode_usda`]; [`super::usdc::encode_usdc`] writes the same scene as a crate
//! file): one `Mesh` prim `/animcodec/mesh` under an `Xform`, triangles as
//! `faceVertexCounts` of 3, `points.timeSamples`, per-frame `extent` and `defaultPrim`, so
//! Pixar's compliance checker passes it. The stage metadata is the source's when the animation
//! carries it ([`codec_core::SceneMetadata`]: `upAxis`, `metersPerUnit`, `timeCodesPerSecond`,
//! the time code of frame 0), else a vertex cache's conventions: `upAxis = "Y"`,
//! `metersPerUnit = 1`, time codes 0, 1, … at `timeCodesPerSecond` = the frame rate;
//! `framesPerSecond` is always the frame rate. The reader fills the same metadata, so a layer
//! read and written again keeps it. Coordinates are written in the shortest decimal form that reads back as the same `f32`,
//! so a round trip is exact.

use std::fmt::Write as _;
use std::path::Path;

use codec_core::{Animation, Error, Result};

use super::gltf_buffers::Budget;
use super::usd_assemble::assemble;
pub use super::usd_layer::USD_DEFAULT_TIME_CODES_PER_SECOND;
use super::usd_layer::{unsupported, Layer, StageTimeLine};
use super::usd_lexer::Lexer;
use super::usd_text::{Parser, USDA_MAGIC};
use super::{name, read_file};

pub use super::usd_layer::MAX_DEPTH;

/// The first bytes of a binary crate file.
pub(super) const USDC_MAGIC: &[u8] = b"PXR-USDC";
/// The first bytes of a zip archive (a `.usdz` package).
const ZIP_MAGIC: &[u8] = b"PK\x03\x04";

/// Reads a USD file — a text layer, a crate file or a `.usdz` package, told apart by their
/// first bytes, whatever the extension (see the module documentation); `frame_rate` overrides
/// the layer's rate.
pub fn read_usd(path: &Path, frame_rate: Option<f32>) -> Result<Animation> {
    let bytes = read_file(path)?;
    let budget = Budget::new(&name(path), None);
    parse_usd_with(&bytes, &name(path), frame_rate, budget)
}

/// Parses a USD layer held in memory: a text layer (`#usda`), a crate file (`PXR-USDC`) or a
/// `.usdz` package (a zip). `file` names the source in errors; `frame_rate` overrides the
/// layer's; `memory_budget` bounds what the read holds beyond the input (default: the
/// process's read budget, 1 GiB unless `--max-memory` set it).
pub fn parse_usd(bytes: &[u8], file: &str, frame_rate: Option<f32>, memory_budget: Option<u64>) -> Result<Animation> {
    parse_usd_with(bytes, file, frame_rate, Budget::new(file, memory_budget))
}

/// Parses a USD layer held in memory; the same as [`parse_usd`] (text layers, crate files and
/// packages are all read), kept under its first name.
pub fn parse_usda(bytes: &[u8], file: &str, frame_rate: Option<f32>, memory_budget: Option<u64>) -> Result<Animation> {
    parse_usd(bytes, file, frame_rate, memory_budget)
}

fn parse_usd_with(bytes: &[u8], file: &str, frame_rate: Option<f32>, mut budget: Budget) -> Result<Animation> {
    let layer = read_layer(bytes, file, &mut budget, true)?;
    assemble(file, layer, frame_rate, &mut budget)
}

/// The layer model of a text layer, a crate file or (when `package` allows it) a package's
/// root layer.
fn read_layer(bytes: &[u8], file: &str, budget: &mut Budget, package: bool) -> Result<Layer> {
    if bytes.starts_with(USDC_MAGIC) {
        return super::usdc::read_layer(bytes, file, budget);
    }
    if bytes.starts_with(ZIP_MAGIC) {
        if !package {
            return Err(unsupported(file, "a USDZ package inside a package (its root layer must be usda or usdc)"));
        }
        let (root, root_name) = super::usdz::root_layer(bytes, file)?;
        let inner = format!("{file}[{}]", super::gltf::printable(&root_name));
        return read_layer(root, &inner, budget, false);
    }
    if !bytes.starts_with(USDA_MAGIC) {
        return Err(Error::malformed(
            file.to_owned(),
            "header",
            "not a USD layer (no `#usda` header, no `PXR-USDC` crate header, not a usdz package)",
        ));
    }
    let text = std::str::from_utf8(bytes)
        .map_err(|e| Error::malformed(file.to_owned(), "text", format!("not UTF-8 (byte {})", e.valid_up_to())))?;
    let mut parser = Parser { lexer: Lexer { text, pos: 0, file }, peeked: None, budget, prim_depth: 0 };
    parser.layer()
}

// ---------------------------------------------------------------------------------------------
// Writer

/// Writes `value` in the shortest decimal form that reads back as the same `f32` (Rust's
/// `Display`/`LowerExp` for `f32` are shortest-round-trip), in exponent form outside
/// [1e-4, 1e7] so huge and tiny values stay short.
fn push_f32(out: &mut String, value: f32) {
    let a = value.abs();
    if a == 0.0 || (1e-4..1e7).contains(&a) {
        let _ = write!(out, "{value}");
    } else {
        let _ = write!(out, "{value:e}");
    }
}

/// A USD text layer holding `animation` (see the module documentation).
pub fn encode_usda(animation: &Animation) -> Result<Vec<u8>> {
    let (v, f) = (animation.vertex_count(), animation.frame_count());
    let tris = animation.triangles();
    // About 3 × 12 characters per vertex and frame.
    let mut s = String::with_capacity(64 + tris.len() * 16 + v * f * 40);
    let stage = StageTimeLine::of(animation);
    let _ = write!(
        s,
        "#usda 1.0\n(\n    defaultPrim = \"animcodec\"\n    doc = \"animcodec vertex cache: {v} vertices, {f} frames\"\n    \
         endTimeCode = {}\n    framesPerSecond = {}\n    metersPerUnit = {}\n    startTimeCode = {}\n    \
         timeCodesPerSecond = {}\n    upAxis = \"{}\"\n)\n\n",
        stage.time_code(f - 1),
        stage.frames_per_second,
        stage.meters_per_unit,
        stage.time_code(0),
        stage.time_codes_per_second,
        stage.up_axis,
    );
    s.push_str("def Xform \"animcodec\" (\n    kind = \"component\"\n)\n{\n    def Mesh \"mesh\"\n    {\n");
    s.push_str("        float3[] extent.timeSamples = {\n");
    for t in 0..f {
        let frame = animation.frame(t);
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for p in frame.chunks_exact(3) {
            for ((l, h), &x) in lo.iter_mut().zip(hi.iter_mut()).zip(p) {
                *l = l.min(x);
                *h = h.max(x);
            }
        }
        let _ = write!(s, "            {}: [(", stage.time_code(t));
        for (k, x) in lo.iter().enumerate() {
            if k > 0 {
                s.push_str(", ");
            }
            push_f32(&mut s, *x);
        }
        s.push_str("), (");
        for (k, x) in hi.iter().enumerate() {
            if k > 0 {
                s.push_str(", ");
            }
            push_f32(&mut s, *x);
        }
        s.push_str(")],\n");
    }
    s.push_str("        }\n        int[] faceVertexCounts = [");
    for i in 0..tris.len() {
        s.push_str(if i == 0 { "3" } else { ", 3" });
    }
    s.push_str("]\n        int[] faceVertexIndices = [");
    for (i, t) in tris.iter().enumerate() {
        let _ = write!(s, "{}{}, {}, {}", if i == 0 { "" } else { ", " }, t[0], t[1], t[2]);
    }
    s.push_str("]\n        point3f[] points.timeSamples = {\n");
    for t in 0..f {
        let _ = write!(s, "            {}: [", stage.time_code(t));
        for (i, p) in animation.frame(t).chunks_exact(3).enumerate() {
            s.push_str(if i == 0 { "(" } else { ", (" });
            push_f32(&mut s, p[0]);
            s.push_str(", ");
            push_f32(&mut s, p[1]);
            s.push_str(", ");
            push_f32(&mut s, p[2]);
            s.push(')');
        }
        s.push_str("],\n");
    }
    s.push_str("        }\n        uniform token subdivisionScheme = \"none\"\n    }\n}\n");
    Ok(s.into_bytes())
}

/// A layer about to be written must read back (with [`parse_usda`]) as exactly `animation`:
/// the same triangles, every coordinate bit for bit, and the same stage metadata and time
/// codes. A layer that does not is never written.
pub(super) fn check_reads_back(path: &Path, bytes: &[u8], animation: &Animation) -> Result<()> {
    let back = parse_usda(bytes, &name(path), Some(animation.frame_rate()), Some(u64::MAX))
        .map_err(|e| Error::InvalidAnimation(format!("the USD layer written does not read back: {e}")))?;
    let same = back.triangles() == animation.triangles()
        && StageTimeLine::of(&back) == StageTimeLine::of(animation)
        && back.positions().len() == animation.positions().len()
        && back.positions().iter().zip(animation.positions()).all(|(a, b)| a.to_bits() == b.to_bits());
    if !same {
        return Err(Error::InvalidAnimation(format!(
            "{}: the USD layer written does not read back as the same positions, triangles and stage metadata",
            name(path)
        )));
    }
    Ok(())
}

/// Extensions read and written as USD text layers.
pub(super) fn is_usd_extension(ext: &str) -> bool {
    matches!(ext, "usda" | "usd" | "usdc" | "usdz")
}

/// A sorted map, so tests can compare sample sets; used by the tests only.
#[cfg(test)]
fn times_of(animation_text: &str) -> std::collections::BTreeMap<String, usize> {
    let mut m = std::collections::BTreeMap::new();
    for line in animation_text.lines() {
        if let Some((t, _)) = line.trim().split_once(": [") {
            *m.entry(t.to_owned()).or_insert(0) += 1;
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::{assert_same_geometry, test_animation};

    fn parse(text: &str) -> Result<Animation> {
        parse_usda(text.as_bytes(), "t.usda", None, None)
    }

    #[test]
    fn written_layers_read_back_bit_exact() {
        for (v, f, fps) in [(7, 5, 25.0), (3, 1, 30.0), (40, 3, 29.97)] {
            let anim = test_animation(v, f, fps);
            let bytes = encode_usda(&anim).unwrap();
            let back = parse_usda(&bytes, "rt.usda", None, None).unwrap();
            assert_same_geometry(&anim, &back);
            assert_eq!(back.frame_rate(), fps);
            let text = String::from_utf8(bytes).unwrap();
            // One `extent` and one `points` sample per frame.
            assert!(times_of(&text).values().all(|&n| n == 2), "{:?}", times_of(&text));
        }
    }

    const QUAD: &str = r#"#usda 1.0
(
    timeCodesPerSecond = 48
    framesPerSecond = 24
    doc = """a "quoted" doc
over two lines"""
    customLayerData = {
        string note = "{ [ ( ignored"
        dictionary nested = { int x = 3 }
    }
)

class "Proto" { def Mesh "ignored" { point3f[] points = [(1,2,3)] } }

def Scope "world" (
    prepend apiSchemas = ["SomeAPI"]
)
{
    def Mesh "quad" (kind = "component")
    {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        uniform token orientation = "leftHanded"
        point3f[] points.timeSamples = {
            0: [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)],
            4: [(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1e0)],
        }
        color3f[] primvars:displayColor = [(1, 0, 0)] (interpolation = "constant")
        rel material:binding = </world/mat>
    }
    def Mesh "tri" (active = true)
    {
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 2, 1]
        point3f[] points = [(-1.5, 2.25, -0), (3, 4, 5), (6, 7, 8)]
        point3f[] points.timeSamples = {
            0: [(0, 0, 0), (0, 0, 0), (0, 0, 0)],
            8: [(8, 8, 8), (8, 8, 8), (8, 8, 8)],
        }
    }
    def Mesh "off" (active = false) { point3f[] points = [(1,2,3)] }
}
"#;

    #[test]
    fn meshes_samples_polygons_and_rates_are_read_as_usd_plays_them() {
        let a = parse(QUAD).unwrap();
        assert_eq!(a.vertex_count(), 7);
        // Times 0, 4, 8 at 48 codes per second: step 4 → 12 fps.
        assert_eq!(a.frame_count(), 3);
        assert_eq!(a.frame_rate(), 12.0);
        // The quad fanned and flipped (left-handed), the triangle after it, offset by 4.
        assert_eq!(a.triangles(), &[[0, 2, 1], [0, 3, 2], [4, 6, 5]]);
        // The quad holds its last sample at time 8; the triangle is interpolated at time 4.
        assert_eq!(&a.frame(2)[..12], &[0., 0., 1., 1., 0., 1., 1., 1., 1., 0., 1., 1.]);
        assert_eq!(&a.frame(1)[12..15], &[4., 4., 4.]);
        assert_eq!(parse_usda(QUAD.as_bytes(), "t", Some(30.0), None).unwrap().frame_rate(), 30.0);
    }

    #[test]
    fn unsupported_and_malformed_layers_are_named() {
        let cases: &[(&str, &str)] = &[
            ("PXR-USDC\0\0\0\0", "88-byte header"),
            ("PK\x03\x04rest", "end-of-central-directory"),
            ("hello", "#usda"),
            ("#usda 1.0\n(\n subLayers = [@a.usda@]\n)\n", "subLayers"),
            ("#usda 1.0\ndef Xform \"a\" (references = @b.usda@) {}\n", "references"),
            ("#usda 1.0\ndef Xform \"a\" { double3 xformOp:translat = (1, 2, 3)\n uniform token[] xformOpOrder = [\"xformOp:translate\"]\n def Mesh \"m\" { point3f[] points = [(0,0,0),(1,0,0),(0,1,0)]\n int[] faceVertexCounts = [3]\n int[] faceVertexIndices = [0,1,2] } }\n", "/a xformOpOrder"),
            ("#usda 1.0\ndef Xform \"a\" {}\n", "no Mesh"),
            ("#usda 1.0\ndef Mesh \"m\" { point3f[] points = [(0,0,0),(1,0,0),(0,1,0)]\n int[] faceVertexCounts = [3]\n int[] faceVertexIndices = [0,1,2]\n int[] primvars:skel:jointIndices = [0, 0, 0] (elementSize = 1 interpolation = \"vertex\") }\n", "UsdSkel"),
            ("#usda 1.0\ndef Mesh \"m\" { point3f[] points = [(0,0,0),(1,0,0),(0,1,0)]\n int[] faceVertexCounts = [3]\n int[] faceVertexIndices = [0,1,3] }\n", "out of range"),
            ("#usda 1.0\ndef Mesh \"m\" { point3f[] points = [(0,0,0),(1,0,0)]\n int[] faceVertexCounts = [2]\n int[] faceVertexIndices = [0,1] }\n", "at least 3"),
            ("#usda 1.0\ndef Mesh \"m\" { point3f[] points.timeSamples = { 0: [(0,0,0)], 1: [(0,0,0),(1,1,1)] }\n int[] faceVertexCounts = []\n int[] faceVertexIndices = [] }\n", "changing point count"),
            ("#usda 1.0\ndef Mesh \"m\" { point3f[] points.timeSamples = { 0: [(0,0,0)], 1: [(1,0,0)], 3: [(2,0,0)] }\n int[] faceVertexCounts = []\n int[] faceVertexIndices = [] }\n", "evenly spaced"),
            ("#usda 1.0\ndef Mesh \"m\" { point3f[] points = [(0,0,nan)]\n int[] faceVertexCounts = []\n int[] faceVertexIndices = [] }\n", "t.usda"),
            ("#usda 1.0\ndef Mesh \"m\" { point3f[] points = [(0,0,0)\n", "line"),
            ("#usda 2.0\n", "version"),
        ];
        for (text, needle) in cases {
            let e = parse(text).unwrap_err().to_string();
            assert!(e.contains(needle), "{text:?}: {e}");
        }
        let deep =
            format!("#usda 1.0\ndef Mesh \"m\" {{ int[] x = {}{} }}\n", "[".repeat(100_000), "]".repeat(100_000));
        assert!(parse(&deep).unwrap_err().to_string().contains("nested"));
        let deep = format!("#usda 1.0\n{}", "def \"a\" {".repeat(100_000));
        assert!(parse(&deep).unwrap_err().to_string().contains("nested"));
    }

    /// Transforms of the mesh and its ancestors are applied, sampled ones at every frame; a
    /// `Scope` (not xformable) transforms nothing; `!resetXformStack!` drops the parents'.
    #[test]
    fn xform_ops_of_the_mesh_and_its_ancestors_are_applied() {
        let layer = |reset: &str| {
            format!(
                "#usda 1.0\ndef Xform \"a\" {{ double3 xformOp:translate.timeSamples = {{ 0: (1, 2, 3), 2: (3, 2, 3) }}\n \
                 uniform token[] xformOpOrder = [\"xformOp:translate\"]\n def Scope \"s\" {{ float3 xformOp:scale = (9, 9, 9)\n \
                 uniform token[] xformOpOrder = [\"xformOp:scale\"]\n def Mesh \"m\" {{ float xformOp:rotateZ = 90\n \
                 uniform token[] xformOpOrder = [{reset}\"xformOp:rotateZ\"]\n point3f[] points.timeSamples = {{ 0: [(1,0,0),(0,1,0),(0,0,1)], \
                 1: [(1,0,0),(0,1,0),(0,0,1)] }}\n \
                 int[] faceVertexCounts = [3]\n int[] faceVertexIndices = [0,1,2] }} }} }}\n"
            )
        };
        let a = parse(&layer("")).unwrap();
        assert_eq!(a.frame_count(), 3);
        // Frame 1 (time 1): rotated 90° about Z, then translated by the interpolated (2, 2, 3).
        let f = a.frame(1);
        let want = [2., 3., 3., 1., 2., 3., 2., 2., 4.];
        assert!(f.iter().zip(want).all(|(x, y)| (x - y).abs() < 1e-6), "{f:?}");
        let a = parse(&layer("\"!resetXformStack!\", ")).unwrap();
        assert_eq!(a.frame_count(), 2);
        let f = a.frame(0);
        let want = [0., 1., 0., -1., 0., 0., 0., 0., 1.];
        assert!(f.iter().zip(want).all(|(x, y)| (x - y).abs() < 1e-6), "{f:?}");
    }

    /// The nesting error counts levels, not prims, and says so, with both (probe misc).
    #[test]
    fn the_nesting_error_states_the_levels_and_prims_counted() {
        let mesh = "def Mesh \"m\" { point3f[] points.timeSamples = { 0: [(0,0,0),(1,0,0),(0,1,0)] }\n int[] \
                    faceVertexCounts = [3]\n int[] faceVertexIndices = [0,1,2] }\n";
        let nested = |n: usize| format!("#usda 1.0\n{}{mesh}{}", "def Xform \"x\" {\n".repeat(n), "}\n".repeat(n));
        let e = parse(&nested(254)).unwrap_err().to_string();
        assert!(e.contains("nested 257 levels deep, past the limit of 256 levels (255 of them nested prims"), "{e}");
        // A shallower one reads.
        assert_eq!(parse(&nested(250)).unwrap().vertex_count(), 3);
    }

    /// Nested long prim names do not cost the sum of every path prefix (2.5 GB for a 20 MB
    /// layer if every prim kept its whole path): only a kept mesh's path is held, and it is
    /// counted against the budget (probe usd-deepnames).
    #[test]
    fn long_prim_paths_are_counted_once() {
        let name = "n".repeat(10_000);
        let mut text = String::from("#usda 1.0\n");
        for k in 0..50 {
            let _ = writeln!(text, "def Xform \"{name}{k}\" {{");
        }
        text += "def Mesh \"m\" { point3f[] points = [(0,0,0),(1,0,0),(0,1,0)]\n int[] faceVertexCounts = [3]\n int[] \
                 faceVertexIndices = [0,1,2] }\n";
        text += &"}\n".repeat(50);
        // The mesh path is 500 000 characters: a budget below it refuses, naming it...
        let e = parse_usda(text.as_bytes(), "p.usda", None, Some(400_000)).unwrap_err().to_string();
        assert!(e.contains("prim paths") && e.contains("--max-memory"), "{e}");
        // ... one above it reads (the 50 prefixes alone were 12.75 MB).
        assert_eq!(parse_usda(text.as_bytes(), "p.usda", None, Some(2_000_000)).unwrap().vertex_count(), 3);
        // Messages elide the middle of a long path.
        let e = parse(&text.replace("int[] faceVertexIndices = [0,1,2]", "int[] faceVertexIndices = [0,1,7]"))
            .unwrap_err()
            .to_string();
        assert!(e.len() < 1000 && e.contains("characters)"), "{} bytes: {}", e.len(), &e[..e.len().min(300)]);
    }

    #[test]
    fn the_budget_bounds_the_read() {
        let anim = test_animation(50, 20, 24.0);
        let bytes = encode_usda(&anim).unwrap();
        let e = parse_usda(&bytes, "b.usda", None, Some(10_000)).unwrap_err().to_string();
        assert!(e.contains("total memory"), "{e}");
        // A one-point static mesh beside a long animated one: the cache is frames × all points,
        // counted before it is allocated.
        let mut text = String::from("#usda 1.0\ndef Mesh \"big\" { point3f[] points = [");
        text.push_str(&"(1,2,3),".repeat(20_000));
        text.push_str("]\n int[] faceVertexCounts = []\n int[] faceVertexIndices = [] }\ndef Mesh \"long\" { point3f[] points.timeSamples = {");
        for t in 0..20_000 {
            let _ = write!(text, "{t}: [(0,0,0)],");
        }
        text.push_str("}\n int[] faceVertexCounts = []\n int[] faceVertexIndices = [] }\n");
        let e = parse_usda(text.as_bytes(), "b.usda", None, Some(64 * text.len() as u64)).unwrap_err().to_string();
        assert!(e.contains("positions"), "{e}");
    }
}
