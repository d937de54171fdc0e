//! MDD point caches (LightWave / Blender), big endian: i32 frame count, i32 point count,
//! f32 time of each frame in seconds, then frames × points × (x, y, z) f32.
//!
//! Frame rate: [`ReadOptions::frame_rate`](super::ReadOptions::frame_rate) when given; else
//! derived from the stored times when they are finite and strictly increasing and give a rate
//! between [`MIN_DERIVED_FPS`] and [`MAX_DERIVED_FPS`] (the mean rate `(frames-1)/(t_last-t_0)`,
//! snapped to the nearest integer when within 1e-4 relative, which undoes f32 rounding of `t/fps`);
//! else 30 fps (one-frame caches, zero or garbage times).

use std::path::Path;

use codec_core::{Animation, Error, Result};

use super::{
    cache_topology, check_cache_sizes, check_finite_in, in_file, name, pc2, read_file, write_file, DEFAULT_FRAME_RATE,
};

/// Lowest frame rate accepted from MDD times.
pub const MIN_DERIVED_FPS: f64 = 0.01;
/// Highest frame rate accepted from MDD times.
pub const MAX_DERIVED_FPS: f64 = 10_000.0;

fn i32_be(b: &[u8], at: usize) -> i32 {
    i32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// A parsed MDD file.
#[derive(Debug, Clone, PartialEq)]
pub struct MddData {
    /// Points per frame.
    pub vertex_count: usize,
    /// Time of each frame in seconds, as stored.
    pub times: Vec<f32>,
    /// Frame-major positions.
    pub positions: Vec<f32>,
}

/// Parses an MDD file held in memory. `file` names the source in errors. Sizes are checked against
/// the length of `bytes` before anything is allocated, and every coordinate must be finite.
pub fn parse_mdd(bytes: &[u8], file: &str) -> Result<MddData> {
    let (frames, vertices) = parse_counts(bytes, file)?;
    let times_bytes = frames * 4;
    if times_bytes > (bytes.len() - 8) as u64 {
        return Err(Error::malformed(
            file.to_owned(),
            "times",
            format!(
                "file is truncated: {frames} frame times need {times_bytes} bytes, only {} present",
                bytes.len() - 8
            ),
        ));
    }
    let body = &bytes[8 + times_bytes as usize..];
    let floats = check_cache_sizes(file, frames, vertices, body.len() as u64)?;
    let times = bytes[8..8 + times_bytes as usize]
        .chunks_exact(4)
        .map(|c| f32::from_be_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    let mut positions = Vec::with_capacity(floats);
    positions.extend(body.chunks_exact(4).map(|c| f32::from_be_bytes([c[0], c[1], c[2], c[3]])));
    check_finite_in(file, &positions, vertices as usize)?;
    Ok(MddData { vertex_count: vertices as usize, times, positions })
}

/// Parses the 8-byte header at the start of `bytes`: `(frame count, vertex count)`, neither
/// negative; not yet checked against the file's size.
pub fn parse_counts(bytes: &[u8], file: &str) -> Result<(u64, u64)> {
    if bytes.len() < 8 {
        return Err(Error::Truncated { context: file.to_owned().into(), field: "header".into() });
    }
    let frames = i32_be(bytes, 0);
    let vertices = i32_be(bytes, 4);
    if frames < 0 {
        return Err(Error::malformed(file.to_owned(), "frame_count", format!("is negative ({frames})")));
    }
    if vertices < 0 {
        return Err(Error::malformed(file.to_owned(), "vertex_count", format!("is negative ({vertices})")));
    }
    Ok((frames as u64, vertices as u64))
}

/// The frame rate implied by MDD times, if they are sane (see the module docs).
pub fn frame_rate_from_times(times: &[f32]) -> Option<f32> {
    if times.len() < 2 || times.iter().any(|t| !t.is_finite()) || times.windows(2).any(|w| w[1] <= w[0]) {
        return None;
    }
    let span = times[times.len() - 1] as f64 - times[0] as f64;
    let fps = (times.len() - 1) as f64 / span;
    if !(MIN_DERIVED_FPS..=MAX_DERIVED_FPS).contains(&fps) {
        return None;
    }
    let rounded = fps.round();
    Some(if (fps - rounded).abs() <= 1e-4 * fps { rounded as f32 } else { fps as f32 })
}

/// Reads an MDD cache. Triangles as for PC2 ([`pc2::read_pc2`]): `topology`, else `STEM.obj`
/// beside the cache. Frame rate: `frame_rate`, else from the times when sane, else 30 fps.
pub fn read_mdd(path: &Path, topology: Option<&Path>, frame_rate: Option<f32>) -> Result<Animation> {
    let file = name(path);
    let data = parse_mdd(&read_file(path)?, &file)?;
    let topology = cache_topology(path, topology, data.vertex_count)?;
    let fps = frame_rate.or_else(|| frame_rate_from_times(&data.times)).unwrap_or(DEFAULT_FRAME_RATE);
    Animation::new(topology, data.positions, fps).map_err(|e| in_file(&file, e))
}

/// Encodes an animation as MDD bytes with times `t / fps`. Fails if a count does not fit the
/// format's signed 32-bit fields.
pub fn encode_mdd(animation: &Animation) -> Result<Vec<u8>> {
    let vertices = i32::try_from(animation.vertex_count())
        .map_err(|_| Error::Unsupported { context: "mdd".into(), detail: "more than 2^31-1 vertices".into() })?;
    let frames = i32::try_from(animation.frame_count())
        .map_err(|_| Error::Unsupported { context: "mdd".into(), detail: "more than 2^31-1 frames".into() })?;
    let mut out = Vec::with_capacity(8 + animation.frame_count() * 4 + animation.positions().len() * 4);
    out.extend_from_slice(&frames.to_be_bytes());
    out.extend_from_slice(&vertices.to_be_bytes());
    let fps = animation.frame_rate() as f64;
    for t in 0..animation.frame_count() {
        out.extend_from_slice(&((t as f64 / fps) as f32).to_be_bytes());
    }
    for x in animation.positions() {
        out.extend_from_slice(&x.to_be_bytes());
    }
    Ok(out)
}

/// Writes `path` as MDD and, beside it, `STEM.obj` with frame 0 and the triangles, so that the
/// cache can be read back on its own. An existing `STEM.obj` is overwritten.
pub fn write_mdd(path: &Path, animation: &Animation) -> Result<()> {
    write_file(path, &encode_mdd(animation)?)?;
    pc2::write_topology_obj(path, animation)
}

#[cfg(test)]
mod tests {
    use super::super::{assert_same_geometry, read_animation, test_animation, ReadOptions, TempDir};
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn layout_is_big_endian_with_times() {
        let anim = test_animation(2, 3, 20.0);
        let bytes = encode_mdd(&anim).unwrap();
        assert_eq!(bytes.len(), 8 + 3 * 4 + 3 * 2 * 12);
        assert_eq!(&bytes[..8], &[0, 0, 0, 3, 0, 0, 0, 2]);
        assert_eq!(f32::from_be_bytes(bytes[12..16].try_into().unwrap()), 0.05);
        let data = parse_mdd(&bytes, "x.mdd").unwrap();
        assert_eq!(data.times, vec![0.0, 0.05, 0.1]);
        assert_eq!(frame_rate_from_times(&data.times), Some(20.0));
        assert!(data.positions.iter().zip(anim.positions()).all(|(a, b)| a.to_bits() == b.to_bits()));
    }

    #[test]
    fn frame_rate_comes_from_sane_times_only() {
        assert_eq!(frame_rate_from_times(&[0.0]), None);
        assert_eq!(frame_rate_from_times(&[0.0, 0.0, 0.0]), None);
        assert_eq!(frame_rate_from_times(&[0.0, 2.0, 1.0]), None);
        assert_eq!(frame_rate_from_times(&[0.0, f32::NAN]), None);
        assert_eq!(frame_rate_from_times(&[0.0, 1e-9]), None, "1e9 fps is not sane");
        // 24000/1001 is not snapped to 24.
        let ntsc = 24000.0 / 1001.0;
        let times: Vec<f32> = (0..100).map(|t| (t as f64 / ntsc) as f32).collect();
        let fps = frame_rate_from_times(&times).unwrap();
        assert!((fps as f64 - ntsc).abs() < 1e-3 && fps != 24.0, "{fps}");
        // Times need not start at 0.
        assert_eq!(frame_rate_from_times(&[10.0, 10.5, 11.0]), Some(2.0));
        let one_frame = encode_mdd(&test_animation(2, 1, 60.0)).unwrap();
        assert_eq!(frame_rate_from_times(&parse_mdd(&one_frame, "x").unwrap().times), None);
    }

    #[test]
    fn every_truncation_is_an_error_never_a_panic() {
        let bytes = encode_mdd(&test_animation(3, 2, 30.0)).unwrap();
        for len in 0..bytes.len() {
            let e = parse_mdd(&bytes[..len], "cut.mdd").unwrap_err().to_string();
            assert!(e.contains("cut.mdd"), "length {len}: {e}");
        }
        let mut longer = bytes.clone();
        longer.extend_from_slice(&[0; 4]);
        assert!(parse_mdd(&longer, "long.mdd").is_err());
    }

    #[test]
    fn absurd_or_invalid_header_counts_are_rejected_before_allocating() {
        for (f, v) in [(i32::MAX, i32::MAX), (1 << 23, 1 << 20), (1, i32::MAX), (-1, 1), (1, -1), (0, 1), (1, 0)] {
            let mut b = f.to_be_bytes().to_vec();
            b.extend_from_slice(&v.to_be_bytes());
            b.extend_from_slice(&[0; 16]);
            let e = parse_mdd(&b, "big.mdd").unwrap_err().to_string();
            assert!(e.contains("big.mdd"), "{f}×{v}: {e}");
        }
    }

    #[test]
    fn nan_is_an_error_naming_file_frame_and_vertex() {
        let mut bytes = encode_mdd(&test_animation(3, 2, 30.0)).unwrap();
        let at = 8 + 2 * 4 + 10 * 4; // frame 1, vertex 0, axis y
        bytes[at..at + 4].copy_from_slice(&f32::INFINITY.to_be_bytes());
        let e = parse_mdd(&bytes, "nan.mdd").unwrap_err().to_string();
        assert!(e.contains("nan.mdd") && e.contains("frame 1, vertex 0, axis y"), "{e}");
    }

    #[test]
    fn writes_a_readable_topology_beside_the_cache() {
        let dir = TempDir::new("mdd-topo");
        let anim = test_animation(4, 2, 30.0);
        let path = dir.path("x.mdd");
        write_mdd(&path, &anim).unwrap();
        assert!(dir.path("x.obj").is_file());
        let back = read_animation(&path, &ReadOptions::default()).unwrap();
        assert_same_geometry(&anim, &back);
        assert_eq!(back.frame_rate(), 30.0);
        let forced = read_animation(&path, &ReadOptions { frame_rate: Some(12.5), ..Default::default() }).unwrap();
        assert_eq!(forced.frame_rate(), 12.5, "an explicit frame rate overrides the stored times");
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        #[test]
        fn mdd_round_trips_random_animations(
            vertices in 1usize..6,
            frames in 1usize..5,
            fps in 1u32..240,
            seed in proptest::collection::vec(any::<u32>(), 90),
        ) {
            let positions: Vec<f32> = (0..vertices * frames * 3)
                .map(|i| {
                    let x = f32::from_bits(seed[i % seed.len()].rotate_left(i as u32));
                    if x.is_finite() { x } else { -(i as f32) }
                })
                .collect();
            let tris: Vec<[u32; 3]> = (0..vertices as u32).map(|v| [0, v, (v + 1) % vertices as u32]).collect();
            let anim = Animation::from_parts(vertices, tris, positions, fps as f32).unwrap();
            let dir = TempDir::new("mdd-prop");
            let path = dir.path("p.mdd");
            write_mdd(&path, &anim).unwrap();
            let back = read_mdd(&path, None, None).unwrap();
            prop_assert_eq!(back.triangles(), anim.triangles());
            let same = back.positions().iter().zip(anim.positions()).all(|(a, b)| a.to_bits() == b.to_bits());
            prop_assert!(same && back.positions().len() == anim.positions().len());
            // Integer rates survive the times round trip exactly; one frame has no times to use.
            let expected = if frames > 1 { fps as f32 } else { DEFAULT_FRAME_RATE };
            prop_assert_eq!(back.frame_rate(), expected);
        }
    }
}
