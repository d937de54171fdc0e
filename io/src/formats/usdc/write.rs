//! The crate-file writer: one `Mesh` prim `/animcodec/mesh` under an `Xform`, the same scene
//! the text writer ([`super::super::usd::encode_usda`]) writes, as a version 0.8.0 crate file
//! laid out as usd-core lays out its own: the bootstrap header, the values, the six structural
//! sections, the table of contents.
//!
//! One encoding is chosen for everything: arrays are stored raw (readers branch on each
//! representation's compressed bit), doubles are inlined when a `float` holds them exactly
//! (as upstream does), the structural sections are integer-coded and wrapped in literal-only
//! LZ4 blocks (valid LZ4 that every decoder reads), and the sample times are written once and
//! shared by `points` and `extent`.

use codec_core::{Animation, Result};

use super::compression::{compress, encode_ints};
use super::container::{SPEC_ATTRIBUTE, SPEC_PRIM, SPEC_PSEUDO_ROOT};
use super::values::ty;
use crate::formats::usd_layer::StageTimeLine;

/// The crate version written: what usd-core 26.11 and Blender 5 write.
const VERSION: [u8; 3] = [0, 8, 0];

const ARRAY: u64 = 1 << 63;
const INLINED: u64 = 1 << 62;

fn rep(ty: u8, flags: u64, payload: u64) -> u64 {
    flags | ((ty as u64) << 48) | (payload & ((1 << 48) - 1))
}

/// One path of the tree, in depth-first order: its parent's position and its name.
struct PathItem {
    parent: Option<usize>,
    token: u32,
    property: bool,
}

#[derive(Default)]
struct Builder {
    out: Vec<u8>,
    tokens: Vec<String>,
    strings: Vec<u32>,
    fields: Vec<(u32, u64)>,
    field_sets: Vec<u32>,
    paths: Vec<PathItem>,
    /// (path index, field set start, spec type).
    specs: Vec<(u32, u32, u32)>,
}

impl Builder {
    fn token(&mut self, t: &str) -> u32 {
        if let Some(i) = self.tokens.iter().position(|x| x == t) {
            return i as u32;
        }
        self.tokens.push(t.to_owned());
        (self.tokens.len() - 1) as u32
    }

    fn align(&mut self) -> u64 {
        while !self.out.len().is_multiple_of(8) {
            self.out.push(0);
        }
        self.out.len() as u64
    }

    fn token_rep(&mut self, t: &str) -> u64 {
        let i = self.token(t);
        rep(ty::TOKEN, INLINED, i as u64)
    }

    fn string_rep(&mut self, s: &str) -> u64 {
        let t = self.token(s);
        let i = match self.strings.iter().position(|&x| x == t) {
            Some(i) => i,
            None => {
                self.strings.push(t);
                self.strings.len() - 1
            }
        };
        rep(ty::STRING, INLINED, i as u64)
    }

    fn double_rep(&mut self, x: f64) -> u64 {
        if (x as f32) as f64 == x {
            return rep(ty::DOUBLE, INLINED, (x as f32).to_bits() as u64);
        }
        let at = self.align();
        self.out.extend_from_slice(&x.to_le_bytes());
        rep(ty::DOUBLE, 0, at)
    }

    fn token_vector_rep(&mut self, items: &[&str]) -> u64 {
        let indexes: Vec<u32> = items.iter().map(|t| self.token(t)).collect();
        let at = self.align();
        self.out.extend_from_slice(&(indexes.len() as u64).to_le_bytes());
        for i in indexes {
            self.out.extend_from_slice(&i.to_le_bytes());
        }
        rep(ty::TOKEN_VECTOR, 0, at)
    }

    fn int_array_rep(&mut self, values: impl ExactSizeIterator<Item = u32>) -> u64 {
        if values.len() == 0 {
            return rep(ty::INT, ARRAY, 0);
        }
        let at = self.align();
        self.out.extend_from_slice(&(values.len() as u64).to_le_bytes());
        for v in values {
            self.out.extend_from_slice(&v.to_le_bytes());
        }
        rep(ty::INT, ARRAY, at)
    }

    fn vec3f_array_rep(&mut self, values: &[f32]) -> u64 {
        if values.is_empty() {
            return rep(24, ARRAY, 0);
        }
        let at = self.align();
        self.out.extend_from_slice(&((values.len() / 3) as u64).to_le_bytes());
        for v in values {
            self.out.extend_from_slice(&v.to_le_bytes());
        }
        rep(24, ARRAY, at)
    }

    fn times_rep(&mut self, times: &[f64]) -> u64 {
        let at = self.align();
        self.out.extend_from_slice(&(times.len() as u64).to_le_bytes());
        for t in times {
            self.out.extend_from_slice(&t.to_le_bytes());
        }
        rep(ty::DOUBLE_VECTOR, 0, at)
    }

    /// A time-samples value: a jump to the times' representation (just after it), a jump to
    /// the value count (just after that), the count and the value representations.
    fn time_samples_rep(&mut self, times: u64, values: &[u64]) -> u64 {
        let at = self.align();
        self.out.extend_from_slice(&8i64.to_le_bytes());
        self.out.extend_from_slice(&times.to_le_bytes());
        self.out.extend_from_slice(&8i64.to_le_bytes());
        self.out.extend_from_slice(&(values.len() as u64).to_le_bytes());
        for v in values {
            self.out.extend_from_slice(&v.to_le_bytes());
        }
        rep(ty::TIME_SAMPLES, 0, at)
    }

    fn path(&mut self, parent: Option<usize>, name: &str, property: bool) -> usize {
        let token = self.token(name);
        self.paths.push(PathItem { parent, token, property });
        self.paths.len() - 1
    }

    fn spec(&mut self, path: usize, spec_type: u32, fields: &[(&str, u64)]) {
        let start = self.field_sets.len() as u32;
        for &(name, value) in fields {
            let token = self.token(name);
            self.fields.push((token, value));
            self.field_sets.push((self.fields.len() - 1) as u32);
        }
        self.field_sets.push(u32::MAX);
        self.specs.push((path as u32, start, spec_type));
    }
}

/// `u64` size and the LZ4-wrapped integer coding of `values` (32-bit).
fn push_ints(out: &mut Vec<u8>, values: &[i64]) {
    let data = compress(&encode_ints(values, 4));
    out.extend_from_slice(&(data.len() as u64).to_le_bytes());
    out.extend_from_slice(&data);
}

/// The jumps of a depth-first path list (see `container`): −2 leaf, −1 child only, 0 sibling
/// only, else the distance to the next sibling (the child is next).
fn jumps(paths: &[PathItem]) -> Vec<i64> {
    (0..paths.len())
        .map(|i| {
            let child = paths.get(i + 1).is_some_and(|p| p.parent == Some(i));
            let sibling =
                (i + 1..paths.len()).find(|&j| paths[j].parent == paths[i].parent && paths[i].parent.is_some());
            match (child, sibling) {
                (true, Some(j)) => (j - i) as i64,
                (false, Some(_)) => 0,
                (true, None) => -1,
                (false, None) => -2,
            }
        })
        .collect()
}

/// A crate file holding `animation` (see the module documentation).
pub fn encode_usdc(animation: &Animation) -> Result<Vec<u8>> {
    let stage = StageTimeLine::of(animation);
    let (v, f) = (animation.vertex_count(), animation.frame_count());
    let tris = animation.triangles();
    let mut b = Builder::default();
    b.out.reserve(88 + v * f * 12 + tris.len() * 16 + f * 48 + 4096);
    b.out.extend_from_slice(b"PXR-USDC");
    b.out.extend_from_slice(&[VERSION[0], VERSION[1], VERSION[2], 0, 0, 0, 0, 0]);
    b.out.extend_from_slice(&[0u8; 72]); // the table of contents' offset, reserved words
    b.token(""); // the root path's element

    // Values: the topology, every frame's points and extent, then the sample times.
    let counts = b.int_array_rep(std::iter::repeat_n(3u32, tris.len()));
    let indices = b.int_array_rep(tris.iter().flatten().copied().collect::<Vec<u32>>().into_iter());
    let mut points = Vec::with_capacity(f);
    let mut extents = Vec::with_capacity(f);
    for t in 0..f {
        let frame = animation.frame(t);
        points.push(b.vec3f_array_rep(frame));
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for p in frame.chunks_exact(3) {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let extent = [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]];
        extents.push(b.vec3f_array_rep(&extent));
    }
    let times: Vec<f64> = (0..f).map(|t| stage.time_code(t)).collect();
    let times = b.times_rep(&times);
    let points = b.time_samples_rep(times, &points);
    let extent = b.time_samples_rep(times, &extents);

    // The specs, in the text writer's order.
    let root = b.path(None, "", false);
    let xform = b.path(Some(root), "animcodec", false);
    let mesh = b.path(Some(xform), "mesh", false);
    let properties = ["extent", "faceVertexCounts", "faceVertexIndices", "points", "subdivisionScheme"];
    let property_paths: Vec<usize> = properties.iter().map(|p| b.path(Some(mesh), p, true)).collect();

    let fields = [
        ("defaultPrim", b.token_rep("animcodec")),
        ("documentation", b.string_rep(&format!("animcodec vertex cache: {v} vertices, {f} frames"))),
        ("endTimeCode", b.double_rep(stage.time_code(f - 1))),
        ("framesPerSecond", b.double_rep(stage.frames_per_second)),
        ("metersPerUnit", b.double_rep(stage.meters_per_unit)),
        ("startTimeCode", b.double_rep(stage.time_code(0))),
        ("timeCodesPerSecond", b.double_rep(stage.time_codes_per_second)),
        ("upAxis", b.token_rep(stage.up_axis)),
        ("primChildren", b.token_vector_rep(&["animcodec"])),
    ];
    b.spec(root, SPEC_PSEUDO_ROOT, &fields);
    let def = rep(ty::SPECIFIER, INLINED, 0);
    let fields = [
        ("specifier", def),
        ("typeName", b.token_rep("Xform")),
        ("kind", b.token_rep("component")),
        ("primChildren", b.token_vector_rep(&["mesh"])),
    ];
    b.spec(xform, SPEC_PRIM, &fields);
    let fields =
        [("specifier", def), ("typeName", b.token_rep("Mesh")), ("properties", b.token_vector_rep(&properties))];
    b.spec(mesh, SPEC_PRIM, &fields);
    let varying = rep(ty::VARIABILITY, INLINED, 0);
    let uniform = rep(ty::VARIABILITY, INLINED, 1);
    let not_custom = rep(ty::BOOL, INLINED, 0);
    let attributes = [
        ("float3[]", varying, ("timeSamples", extent)),
        ("int[]", varying, ("default", counts)),
        ("int[]", varying, ("default", indices)),
        ("point3f[]", varying, ("timeSamples", points)),
        ("token", uniform, ("default", b.token_rep("none"))),
    ];
    for (&path, (type_name, variability, value)) in property_paths.iter().zip(attributes) {
        let fields =
            [("typeName", b.token_rep(type_name)), ("custom", not_custom), ("variability", variability), value];
        b.spec(path, SPEC_ATTRIBUTE, &fields);
    }

    // The structural sections.
    let mut sections: Vec<(&str, u64, u64)> = Vec::new();
    let begin = |b: &mut Builder| b.align();
    let start = begin(&mut b);
    let mut raw = Vec::new();
    for t in &b.tokens {
        raw.extend_from_slice(t.as_bytes());
        raw.push(0);
    }
    let packed = compress(&raw);
    for x in [b.tokens.len() as u64, raw.len() as u64, packed.len() as u64] {
        b.out.extend_from_slice(&x.to_le_bytes());
    }
    b.out.extend_from_slice(&packed);
    sections.push(("TOKENS", start, b.out.len() as u64 - start));

    let start = begin(&mut b);
    b.out.extend_from_slice(&(b.strings.len() as u64).to_le_bytes());
    for i in b.strings.clone() {
        b.out.extend_from_slice(&i.to_le_bytes());
    }
    sections.push(("STRINGS", start, b.out.len() as u64 - start));

    let start = begin(&mut b);
    b.out.extend_from_slice(&(b.fields.len() as u64).to_le_bytes());
    let names: Vec<i64> = b.fields.iter().map(|f| f.0 as i64).collect();
    push_ints(&mut b.out, &names);
    let reps: Vec<u8> = b.fields.iter().flat_map(|f| f.1.to_le_bytes()).collect();
    let packed = compress(&reps);
    b.out.extend_from_slice(&(packed.len() as u64).to_le_bytes());
    b.out.extend_from_slice(&packed);
    sections.push(("FIELDS", start, b.out.len() as u64 - start));

    let start = begin(&mut b);
    b.out.extend_from_slice(&(b.field_sets.len() as u64).to_le_bytes());
    let sets: Vec<i64> = b.field_sets.iter().map(|&f| f as i32 as i64).collect();
    push_ints(&mut b.out, &sets);
    sections.push(("FIELDSETS", start, b.out.len() as u64 - start));

    let start = begin(&mut b);
    let n = b.paths.len() as u64;
    b.out.extend_from_slice(&n.to_le_bytes());
    b.out.extend_from_slice(&n.to_le_bytes());
    let indexes: Vec<i64> = (0..n as i64).collect();
    let elements: Vec<i64> =
        b.paths.iter().map(|p| if p.property { -(p.token as i64) } else { p.token as i64 }).collect();
    let jumps = jumps(&b.paths);
    push_ints(&mut b.out, &indexes);
    push_ints(&mut b.out, &elements);
    push_ints(&mut b.out, &jumps);
    sections.push(("PATHS", start, b.out.len() as u64 - start));

    let start = begin(&mut b);
    b.out.extend_from_slice(&(b.specs.len() as u64).to_le_bytes());
    let specs = b.specs.clone();
    push_ints(&mut b.out, &specs.iter().map(|s| s.0 as i64).collect::<Vec<_>>());
    push_ints(&mut b.out, &specs.iter().map(|s| s.1 as i64).collect::<Vec<_>>());
    push_ints(&mut b.out, &specs.iter().map(|s| s.2 as i64).collect::<Vec<_>>());
    sections.push(("SPECS", start, b.out.len() as u64 - start));

    let toc = begin(&mut b);
    b.out.extend_from_slice(&(sections.len() as u64).to_le_bytes());
    for (name, start, size) in &sections {
        let mut field = [0u8; 16];
        field[..name.len()].copy_from_slice(name.as_bytes());
        b.out.extend_from_slice(&field);
        b.out.extend_from_slice(&start.to_le_bytes());
        b.out.extend_from_slice(&size.to_le_bytes());
    }
    b.out[16..24].copy_from_slice(&toc.to_le_bytes());
    Ok(b.out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn item(parent: Option<usize>) -> PathItem {
        PathItem { parent, token: 0, property: false }
    }

    /// `/`, `/a`, `/a/x`, `/a/y`, `/b`: the root has a child only; `/a` a child and a sibling
    /// three items on; `/a/x` a sibling only; `/a/y` and `/b` are leaves.
    #[test]
    fn path_jumps_encode_children_and_siblings() {
        let paths = [item(None), item(Some(0)), item(Some(1)), item(Some(1)), item(Some(0))];
        assert_eq!(jumps(&paths), vec![-1, 3, 0, -2, -2]);
    }
}
