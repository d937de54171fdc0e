//! Tests of the Alembic reader and writer against each other, a file written by the reference
//! library, and hostile archives.

use super::*;
use crate::formats::{assert_same_geometry, test_animation};

/// A 3-frame, 24 fps triangle written by alembic3d 1.8.12 (PyAlembic): an Xform `/animcodec`
/// (identity) holding a PolyMesh `/animcodec/mesh` whose face is `[0, 2, 1]` (clockwise) and
/// whose points move by +1 in x each frame.
const REFERENCE: &[u8] = include_bytes!("testdata_tri.abc");

fn reference_animation() -> Animation {
    let p0 = [0., 0., 0., 1., 0., 0., 0., 1., 0.];
    let mut positions = Vec::new();
    for t in 0..3 {
        positions.extend(p0.chunks(3).flat_map(|p| [p[0] + t as f32, p[1], p[2]]));
    }
    Animation::from_parts(3, vec![[0, 1, 2]], positions, 24.0).unwrap()
}

#[test]
fn a_reference_archive_reads_with_its_frames_rate_and_winding() {
    let a = parse_abc(REFERENCE, "tri.abc", None, None, None).unwrap();
    assert_same_geometry(&reference_animation(), &a);
    assert_eq!(a.frame_rate(), 24.0);
    let meshes = parse_meshes(REFERENCE, "tri.abc").unwrap();
    assert_eq!(meshes.len(), 1);
    let m = &meshes[0];
    assert_eq!(
        (m.path.as_str(), m.schema, m.vertices, m.faces, m.triangles, m.samples),
        ("/animcodec/mesh", "PolyMesh", 3, 1, 1, 3)
    );
    assert!((m.end - 2.0 / 24.0).abs() < 1e-12);
    // Selection by path (and by an ancestor); an unknown path lists the meshes.
    assert!(parse_abc(REFERENCE, "t", Some("/animcodec/mesh"), None, None).is_ok());
    assert!(parse_abc(REFERENCE, "t", Some("/animcodec"), None, None).is_ok());
    let e = parse_abc(REFERENCE, "t", Some("/nothing"), None, None).unwrap_err().to_string();
    assert!(e.contains("/animcodec/mesh") && e.contains("/nothing"), "{e}");
    assert_eq!(parse_abc(REFERENCE, "t", None, Some(30.0), None).unwrap().frame_rate(), 30.0);
}

/// The writer lays the archive out as the reference library does: for the same content, every
/// byte before the archive metadata (which names the application) is the same — data, sample
/// keys, property flags, indexed metadata order and the SpookyHash trailers.
#[test]
fn the_writer_matches_the_reference_layout_byte_for_byte() {
    let ours = encode_abc(&reference_animation()).unwrap();
    // The reference's archive metadata block starts at byte 1157 (its length word).
    let cut = 1157;
    // Bytes 8..16 hold the root group's offset, which follows the metadata.
    let first_diff = ours[16..].iter().zip(&REFERENCE[16..]).position(|(a, b)| a != b).map(|d| d + 16);
    assert!(first_diff.is_none_or(|d| d >= cut), "first difference at byte {first_diff:?}");
    assert_eq!(ours[..8], REFERENCE[..8]);
}

#[test]
fn written_archives_read_back_bit_exact() {
    for (v, f, fps) in [(7, 5, 25.0), (3, 1, 30.0), (40, 3, 29.97), (300, 4, 24.0)] {
        let anim = test_animation(v, f, fps);
        let bytes = encode_abc(&anim).unwrap();
        let back = parse_abc(&bytes, "rt.abc", None, None, None).unwrap();
        assert_same_geometry(&anim, &back);
        if f > 1 {
            assert_eq!(back.frame_rate(), fps, "{v} {f} {fps}");
        }
        assert_eq!(encode_abc(&anim).unwrap(), bytes, "same input, same bytes");
    }
    // Repeated frames are stored once and still read back.
    let a = test_animation(5, 2, 24.0);
    let mut positions = a.frame(0).to_vec();
    positions.extend_from_slice(a.frame(0));
    positions.extend_from_slice(a.frame(1));
    positions.extend_from_slice(a.frame(1));
    let anim = Animation::from_parts(5, a.triangles().to_vec(), positions, 24.0).unwrap();
    let back = parse_abc(&encode_abc(&anim).unwrap(), "rep.abc", None, None, None).unwrap();
    assert_same_geometry(&anim, &back);
}

fn assert_fails(bytes: &[u8], needles: &[&str]) {
    let start = std::time::Instant::now();
    let e = match std::panic::catch_unwind(|| parse_abc(bytes, "h.abc", None, None, Some(64 << 20))) {
        Ok(r) => r.map(|_| ()).err(),
        Err(_) => panic!("the reader panicked"),
    };
    let e = e.map(|e| e.to_string()).unwrap_or_else(|| "no error".into());
    for n in needles {
        assert!(e.contains(n), "{n:?} not in {e:?}");
    }
    assert!(start.elapsed().as_secs_f64() < 1.0, "took {:?}", start.elapsed());
}

#[test]
fn hdf5_and_foreign_files_are_refused_by_name() {
    assert_fails(b"\x89HDF\r\n\x1a\n0000000000000000", &["HDF5", "Ogawa"]);
    assert_fails(b"hello world, not an archive", &["h.abc", "Ogawa"]);
    assert_fails(b"", &["h.abc"]);
}

#[test]
fn truncated_and_bit_flipped_archives_fail_cleanly() {
    let good = encode_abc(&test_animation(20, 6, 24.0)).unwrap();
    for len in (0..good.len()).step_by(7) {
        let r = std::panic::catch_unwind(|| parse_abc(&good[..len], "t.abc", None, None, Some(64 << 20)));
        assert!(r.is_ok(), "panic at length {len}");
    }
    for i in 0..good.len() {
        for bit in [0, 3, 7] {
            let mut b = good.clone();
            b[i] ^= 1 << bit;
            let r = std::panic::catch_unwind(|| parse_abc(&b, "t.abc", None, None, Some(64 << 20)));
            assert!(r.is_ok(), "panic with byte {i} bit {bit} flipped");
        }
    }
}

/// Rewrites the u64 at `at` in `bytes`.
fn poke(bytes: &mut [u8], at: usize, v: u64) {
    bytes[at..at + 8].copy_from_slice(&v.to_le_bytes());
}

/// The offset of the group `path` (child indices from the root) in an archive.
fn group_at(bytes: &[u8], path: &[u64]) -> u64 {
    let (og, root) = ogawa::Ogawa::open(bytes, "t").unwrap();
    let mut g = root;
    for &i in path {
        g = og.child_group(g, i, "t").unwrap();
    }
    g.offset
}

#[test]
fn hostile_structures_fail_fast_with_clear_errors() {
    let good = encode_abc(&test_animation(8, 4, 24.0)).unwrap();
    // The top object's child (the Xform) made to point at the top object itself: a cycle.
    let top = group_at(&good, &[2]);
    let mut cyc = good.clone();
    poke(&mut cyc, top as usize + 8 + 8, top);
    assert_fails(&cyc, &["contains itself"]);
    // The Xform's child (the mesh) pointing back at the Xform: a cycle through two objects.
    let x = group_at(&good, &[2, 1]);
    let mut cyc2 = good.clone();
    poke(&mut cyc2, x as usize + 8 + 8, x);
    assert_fails(&cyc2, &["contains itself"]);
    // An array sample claiming 2^31 bytes, and one claiming 2^63-1.
    let p = group_at(&good, &[2, 1, 1, 0, 0, 1]);
    let (og, _) = ogawa::Ogawa::open(&good, "t").unwrap();
    let g = og.group(p).unwrap();
    let ogawa::Child::Data(d0) = og.child(g, 0, "t").unwrap() else { panic!() };
    for claim in [1u64 << 31, u64::MAX >> 1] {
        let mut big = good.clone();
        poke(&mut big, d0 as usize, claim);
        assert_fails(&big, &["past the end of the file"]);
    }
    // The indexed metadata and the time samplings pointing past the file.
    let root = group_at(&good, &[]);
    for child in [3u64, 4, 5] {
        let mut past = good.clone();
        poke(&mut past, root as usize + 8 + 8 * child as usize, (good.len() as u64 + 100) | ogawa::DATA_BIT);
        assert_fails(&past, &["past the end of the file"]);
    }
    // A group with 2^31 children.
    let mut many = good.clone();
    poke(&mut many, p as usize, 1 << 31);
    assert_fails(&many, &["more than the file"]);
}

/// Every P sample pointing at one shared block must not amplify the work past the
/// budget; the memory budget bounds the frames × points.
#[test]
fn the_budget_bounds_the_read() {
    let anim = test_animation(200, 50, 24.0);
    let bytes = encode_abc(&anim).unwrap();
    let e = parse_abc(&bytes, "b.abc", None, None, Some(20_000)).unwrap_err().to_string();
    assert!(e.contains("--max-memory"), "{e}");
    assert!(parse_abc(&bytes, "b.abc", None, None, Some(1 << 20)).is_ok());
}

/// A scene Blender 5.0.1 exported (`bpy.ops.wm.alembic_export`, 24 fps, frames 1–12): a cube
/// whose transform is animated (location and rotation keys) and a UV sphere parented to it
/// with animated scale; each object is an Xform with one matrix op holding its mesh. The
/// `.f32` holds Blender's evaluated world positions (`matrix_world @ co`, turned to Y-up as
/// the exporter does), cube then sphere, frame by frame. Blender composes in `f32`, we in
/// `f64`: the points agree to far below 1e-6 of the bounding-box diagonal.
#[test]
fn a_blender_scene_reads_as_blender_plays_it() {
    let bytes = include_bytes!("testdata_blender_scene.abc");
    let expected: Vec<f32> = include_bytes!("testdata_blender_scene.f32")
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    let a = parse_abc(bytes, "scene.abc", None, None, None).unwrap();
    assert_eq!((a.frame_count(), a.vertex_count(), a.frame_rate()), (12, 42, 24.0));
    assert_eq!(a.positions().len(), expected.len());
    let diagonal = a.bounding_box_diagonal();
    let worst = a.positions().iter().zip(&expected).map(|(x, y)| (x - y).abs() as f64).fold(0.0, f64::max);
    assert!(worst <= 1e-6 * diagonal, "worst {worst} against diagonal {diagonal}");
    let meshes = parse_meshes(bytes, "scene.abc").unwrap();
    let paths: Vec<&str> = meshes.iter().map(|m| m.path.as_str()).collect();
    assert_eq!(paths, ["/Cube/Cube", "/Cube/Sphere/Sphere"]);
    // Only the sphere: it still follows its animated parent.
    let s = parse_abc(bytes, "scene.abc", Some("/Cube/Sphere"), None, None).unwrap();
    assert_eq!((s.frame_count(), s.vertex_count()), (12, 34));
    assert_eq!(s.frame(11), &a.frame(11)[8 * 3..]);
}

/// Objects shared between parents (a DAG of groups, every level listing the level below
/// twice: 2^40 paths through 40 levels) are refused after a bounded number of visits, quickly.
#[test]
fn shared_object_groups_do_not_amplify_the_work() {
    use ogawa::{Child, OgawaWriter};
    let mut w = OgawaWriter::new();
    let version = w.data(&[&0i32.to_le_bytes()]);
    let library = w.data(&[&10812i32.to_le_bytes()]);
    let mut headers = Vec::new();
    for name in [b"a", b"b"] {
        headers.extend_from_slice(&1u32.to_le_bytes());
        headers.extend_from_slice(name);
        headers.push(0);
    }
    headers.extend_from_slice(&[0u8; 32]);
    let mut level = w.group(&[Child::Group(0)]);
    for _ in 0..40 {
        let h = w.data(&[&headers]);
        level = w.group(&[Child::Group(0), level, level, h]);
    }
    let md = w.data(&[b""]);
    let mut ts = Vec::new();
    ts.extend_from_slice(&1u32.to_le_bytes());
    ts.extend_from_slice(&1f64.to_le_bytes());
    ts.extend_from_slice(&1u32.to_le_bytes());
    ts.extend_from_slice(&0f64.to_le_bytes());
    let ts = w.data(&[&ts]);
    let imd = w.data(&[b""]);
    let root = w.group(&[version, library, level, md, ts, imd]);
    let bytes = w.finish(root);
    assert_fails(&bytes, &["belongs to two objects"]);
}
