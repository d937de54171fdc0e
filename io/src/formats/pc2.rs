//! PC2 point caches (Blender / 3ds Max "POINTCACHE2"), little endian:
//! 12-byte magic `POINTCACHE2\0`, i32 version (1), i32 vertex count, f32 start frame,
//! f32 sample rate, i32 frame count, then frames × vertices × (x, y, z) f32.
//!
//! The "sample rate" is the step between stored samples measured in frames (1.0 = every frame),
//! not frames per second, and PC2 stores no frame rate at all: the animation gets
//! [`ReadOptions::frame_rate`](super::ReadOptions::frame_rate) or 30 fps. The start frame and
//! sample rate are reported by [`parse_pc2`] but not otherwise used. Triangles come from an OBJ
//! (see [`read_pc2`]).

use std::path::Path;

use codec_core::{Animation, Error, Result};

use super::{
    cache_topology, check_cache_sizes, check_finite_in, in_file, name, obj, read_file, write_file, DEFAULT_FRAME_RATE,
};

/// The 12-byte PC2 signature.
pub const MAGIC: &[u8; 12] = b"POINTCACHE2\0";
/// Size of the PC2 header in bytes.
pub const HEADER_BYTES: usize = 32;

/// Header fields of a PC2 file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pc2Header {
    /// Vertices per frame.
    pub vertex_count: usize,
    /// First frame number of the cache (metadata only).
    pub start_frame: f32,
    /// Step between samples in frames (metadata only; 1.0 = every frame).
    pub sample_rate: f32,
    /// Number of stored frames.
    pub frame_count: usize,
}

fn i32_le(b: &[u8], at: usize) -> i32 {
    i32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn f32_le(b: &[u8], at: usize) -> f32 {
    f32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Parses a PC2 file held in memory: header and frame-major positions. `file` names the source in
/// errors. Sizes are checked against the length of `bytes` before anything is allocated, and every
/// coordinate must be finite (the error names file, frame, vertex and axis).
pub fn parse_pc2(bytes: &[u8], file: &str) -> Result<(Pc2Header, Vec<f32>)> {
    let header = parse_header(bytes, file)?;
    let body = &bytes[HEADER_BYTES..];
    let floats = check_cache_sizes(file, header.frame_count as u64, header.vertex_count as u64, body.len() as u64)?;
    let mut positions = Vec::with_capacity(floats);
    positions.extend(body.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])));
    check_finite_in(file, &positions, header.vertex_count)?;
    Ok((header, positions))
}

/// Parses and checks the 32-byte header at the start of `bytes` (magic, version, counts not
/// negative); the counts are not yet checked against the file's size.
pub fn parse_header(bytes: &[u8], file: &str) -> Result<Pc2Header> {
    if bytes.len() < HEADER_BYTES {
        return Err(Error::Truncated { context: file.to_owned().into(), field: "header".into() });
    }
    if &bytes[..12] != MAGIC {
        return Err(Error::malformed(file.to_owned(), "magic", "not a PC2 file (no POINTCACHE2 signature)"));
    }
    let version = i32_le(bytes, 12);
    if version != 1 {
        return Err(Error::Unsupported {
            context: file.to_owned().into(),
            detail: format!("PC2 version {version} (only version 1 is defined)"),
        });
    }
    let vertices = i32_le(bytes, 16);
    let frames = i32_le(bytes, 28);
    if vertices < 0 {
        return Err(Error::malformed(file.to_owned(), "vertex_count", format!("is negative ({vertices})")));
    }
    if frames < 0 {
        return Err(Error::malformed(file.to_owned(), "frame_count", format!("is negative ({frames})")));
    }
    Ok(Pc2Header {
        vertex_count: vertices as usize,
        start_frame: f32_le(bytes, 20),
        sample_rate: f32_le(bytes, 24),
        frame_count: frames as usize,
    })
}

/// Reads a PC2 cache. Triangles come from `topology` when given, else from the OBJ with the same
/// stem beside the cache (an error suggests `--topology` when there is none); the OBJ must have the
/// cache's vertex count. Frame rate: `frame_rate`, else 30 fps (PC2 stores none).
pub fn read_pc2(path: &Path, topology: Option<&Path>, frame_rate: Option<f32>) -> Result<Animation> {
    let file = name(path);
    let (header, positions) = parse_pc2(&read_file(path)?, &file)?;
    let topology = cache_topology(path, topology, header.vertex_count)?;
    Animation::new(topology, positions, frame_rate.unwrap_or(DEFAULT_FRAME_RATE)).map_err(|e| in_file(&file, e))
}

/// Encodes an animation as PC2 bytes (start frame 0, sample rate 1). Fails if a count does not
/// fit the format's signed 32-bit fields.
pub fn encode_pc2(animation: &Animation) -> Result<Vec<u8>> {
    let vertices = i32::try_from(animation.vertex_count())
        .map_err(|_| Error::Unsupported { context: "pc2".into(), detail: "more than 2^31-1 vertices".into() })?;
    let frames = i32::try_from(animation.frame_count())
        .map_err(|_| Error::Unsupported { context: "pc2".into(), detail: "more than 2^31-1 frames".into() })?;
    let mut out = Vec::with_capacity(HEADER_BYTES + animation.positions().len() * 4);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&1i32.to_le_bytes());
    out.extend_from_slice(&vertices.to_le_bytes());
    out.extend_from_slice(&0f32.to_le_bytes());
    out.extend_from_slice(&1f32.to_le_bytes());
    out.extend_from_slice(&frames.to_le_bytes());
    for x in animation.positions() {
        out.extend_from_slice(&x.to_le_bytes());
    }
    Ok(out)
}

/// Writes `path` as PC2 and, beside it, `STEM.obj` with frame 0 and the triangles, so that the
/// cache can be read back on its own. An existing `STEM.obj` is overwritten.
pub fn write_pc2(path: &Path, animation: &Animation) -> Result<()> {
    write_file(path, &encode_pc2(animation)?)?;
    write_topology_obj(path, animation)
}

/// Writes the `STEM.obj` companion of a cache: frame 0 plus the triangles.
pub(super) fn write_topology_obj(cache: &Path, animation: &Animation) -> Result<()> {
    let comment = format!(
        "animcodec: topology of {} (frame 0 of {}, {} vertices, {} triangles)",
        cache.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default(),
        animation.frame_count(),
        animation.vertex_count(),
        animation.topology().triangle_count()
    );
    obj::write_obj(&cache.with_extension("obj"), animation.frame(0), animation.triangles(), &comment)
}

#[cfg(test)]
mod tests {
    use super::super::{assert_same_geometry, read_animation, test_animation, ReadOptions, TempDir};
    use super::*;
    use proptest::prelude::*;

    fn header(vertices: i32, frames: i32) -> Vec<u8> {
        let mut b = MAGIC.to_vec();
        for v in [1i32.to_le_bytes(), vertices.to_le_bytes(), 0f32.to_le_bytes(), 1f32.to_le_bytes()] {
            b.extend_from_slice(&v);
        }
        b.extend_from_slice(&frames.to_le_bytes());
        b
    }

    #[test]
    fn header_is_the_documented_layout() {
        let anim = test_animation(3, 2, 30.0);
        let bytes = encode_pc2(&anim).unwrap();
        assert_eq!(bytes.len(), 32 + 2 * 3 * 12);
        assert_eq!(&bytes[..32], &header(3, 2)[..]);
        assert_eq!(f32::from_le_bytes(bytes[32..36].try_into().unwrap()).to_bits(), anim.positions()[0].to_bits());
        let (h, p) = parse_pc2(&bytes, "x.pc2").unwrap();
        assert_eq!((h.vertex_count, h.frame_count, h.start_frame, h.sample_rate), (3, 2, 0.0, 1.0));
        assert_eq!(p.len(), 18);
    }

    #[test]
    fn every_truncation_is_an_error_never_a_panic() {
        let bytes = encode_pc2(&test_animation(3, 2, 30.0)).unwrap();
        for len in 0..bytes.len() {
            let e = parse_pc2(&bytes[..len], "cut.pc2").unwrap_err().to_string();
            assert!(e.contains("cut.pc2"), "length {len}: {e}");
        }
        let e = parse_pc2(&bytes[..bytes.len() - 1], "cut.pc2").unwrap_err().to_string();
        assert!(e.contains("truncated"), "{e}");
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(parse_pc2(&longer, "long.pc2").is_err(), "trailing bytes mean the header is wrong");
    }

    #[test]
    fn absurd_or_invalid_header_counts_are_rejected_before_allocating() {
        // 2^31-1 vertices × 2^31-1 frames would be ~5e19 bytes: rejected by the limits / the file
        // length, without an allocation (which would abort the test process).
        for (v, f) in [(i32::MAX, i32::MAX), (1 << 20, 1 << 23), (1, i32::MAX), (-1, 1), (1, -5), (0, 1), (3, 0)] {
            let e = parse_pc2(&header(v, f), "big.pc2").unwrap_err().to_string();
            assert!(e.contains("big.pc2"), "{v}×{f}: {e}");
        }
        let mut bad = header(1, 1);
        bad[0] = b'X';
        assert!(parse_pc2(&bad, "m.pc2").unwrap_err().to_string().contains("magic"));
        let mut v2 = header(1, 1);
        v2[12] = 2;
        v2.extend_from_slice(&[0; 12]);
        assert!(parse_pc2(&v2, "v.pc2").unwrap_err().to_string().contains("version 2"));
    }

    #[test]
    fn nan_is_an_error_naming_file_frame_and_vertex() {
        let mut bytes = encode_pc2(&test_animation(3, 2, 30.0)).unwrap();
        // Frame 1, vertex 2, axis z: float index 9 + 6 + 2 = 17.
        bytes[32 + 17 * 4..32 + 18 * 4].copy_from_slice(&f32::NAN.to_le_bytes());
        let e = parse_pc2(&bytes, "nan.pc2").unwrap_err().to_string();
        assert!(e.contains("nan.pc2") && e.contains("frame 1, vertex 2, axis z"), "{e}");
    }

    #[test]
    fn topology_comes_from_option_or_sibling_and_must_match() {
        let dir = TempDir::new("pc2-topo");
        let anim = test_animation(5, 3, 30.0);
        let cache = dir.path("a.pc2");
        write_file(&cache, &encode_pc2(&anim).unwrap()).unwrap();
        let e = read_animation(&cache, &ReadOptions::default()).unwrap_err().to_string();
        assert!(e.contains("a.obj") && e.contains("--topology"), "{e}");
        let other = dir.path("mesh.obj");
        obj::write_obj(&other, anim.frame(0), anim.triangles(), "").unwrap();
        let opts = ReadOptions { topology: Some(other.clone()), ..Default::default() };
        let back = read_animation(&cache, &opts).unwrap();
        assert_same_geometry(&anim, &back);
        assert_eq!(back.frame_rate(), DEFAULT_FRAME_RATE);
        obj::write_obj(&other, &anim.frame(0)[..12], &anim.triangles()[..2], "").unwrap();
        let e = read_animation(&cache, &opts).unwrap_err().to_string();
        assert!(e.contains("mesh.obj") && e.contains("4 vertices") && e.contains("has 5"), "{e}");
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        #[test]
        fn pc2_round_trips_random_animations(
            vertices in 1usize..6,
            frames in 1usize..5,
            seed in proptest::collection::vec(any::<u32>(), 90),
        ) {
            // Random finite bit patterns (including subnormals and -0.0).
            let positions: Vec<f32> = (0..vertices * frames * 3)
                .map(|i| {
                    let x = f32::from_bits(seed[i % seed.len()].rotate_left(i as u32));
                    if x.is_finite() { x } else { i as f32 }
                })
                .collect();
            let tris: Vec<[u32; 3]> = (0..vertices as u32).map(|v| [v, (v + 1) % vertices as u32, 0]).collect();
            let anim = Animation::from_parts(vertices, tris, positions, 30.0).unwrap();
            let dir = TempDir::new("pc2-prop");
            let path = dir.path("p.pc2");
            write_pc2(&path, &anim).unwrap();
            let back = read_pc2(&path, None, Some(30.0)).unwrap();
            prop_assert_eq!(back.triangles(), anim.triangles());
            let same = back.positions().iter().zip(anim.positions()).all(|(a, b)| a.to_bits() == b.to_bits());
            prop_assert!(same && back.positions().len() == anim.positions().len());
        }
    }

    #[test]
    fn reads_samba_when_present() {
        let cache = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/samba/samba.pc2");
        if !cache.is_file() {
            return codec_core::testing::skip("reads_samba_when_present", &format!("{} not found", cache.display()));
        }
        let anim = read_animation(&cache, &ReadOptions::default()).unwrap();
        assert_eq!((anim.vertex_count(), anim.frame_count(), anim.topology().triangle_count()), (9971, 175, 19938));
        // The OBJ beside the cache is frame 0 printed with ~6 significant digits: the cache's first
        // frame must agree with it to that precision (checks byte order and layout).
        let mesh = obj::read_obj(&cache.with_extension("obj")).unwrap();
        let scale = anim.bounding_box_diagonal() as f32;
        let worst = mesh.positions.iter().zip(anim.frame(0)).map(|(a, b)| (a - b).abs()).fold(0f32, f32::max);
        assert!(worst <= 1e-5 * scale, "frame 0 differs from samba.obj by {worst} (diagonal {scale})");
    }
}
