//! Helpers shared by the sac examples: tiny PC2/OBJ readers (the real ones live in the
//! `animcodec` crate, which a codec crate must not depend on), KG as `metrics` computes it, and
//! point conversion.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use codec_core::{Animation, Topology};
use codec_sac::geometry::V3;

/// `(vertex count, frame count, positions)` of a POINTCACHE2 file.
pub fn read_pc2(path: &Path) -> std::io::Result<(usize, usize, Vec<f32>)> {
    let b = std::fs::read(path)?;
    let bad = || std::io::Error::new(std::io::ErrorKind::InvalidData, "bad pc2");
    if b.len() < 32 || &b[..12] != b"POINTCACHE2\0" {
        return Err(bad());
    }
    let i32_at = |o: usize| i32::from_le_bytes(b[o..o + 4].try_into().unwrap());
    let (n, f) = (i32_at(16) as usize, i32_at(28) as usize);
    if b.len() < 32 + n * f * 12 {
        return Err(bad());
    }
    let pos = b[32..32 + n * f * 12].chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect();
    Ok((n, f, pos))
}

/// Triangles of the `f` lines of an OBJ file (fans for polygons).
pub fn read_obj_faces(path: &Path) -> std::io::Result<Vec<[u32; 3]>> {
    let text = std::fs::read_to_string(path)?;
    let mut tris = Vec::new();
    for line in text.lines() {
        let mut it = line.split_whitespace();
        if it.next() != Some("f") {
            continue;
        }
        let idx: Vec<u32> = it.filter_map(|t| t.split('/').next()?.parse::<u32>().ok()).map(|i| i - 1).collect();
        for k in 1..idx.len().saturating_sub(1) {
            tris.push([idx[0], idx[k], idx[k + 1]]);
        }
    }
    Ok(tris)
}

/// KG error (%) as `metrics` computes it (reference centroid per frame).
pub fn kg(a: &Animation, b: &[f32]) -> f64 {
    let n = a.vertex_count();
    let (mut num, mut den) = (0.0, 0.0);
    for (t, f) in a.frames().enumerate() {
        let mut c = [0.0f64; 3];
        for p in f.chunks_exact(3) {
            for k in 0..3 {
                c[k] += p[k] as f64 / n as f64;
            }
        }
        for (i, &x) in f.iter().enumerate() {
            num += (x as f64 - b[t * n * 3 + i] as f64).powi(2);
            den += (x as f64 - c[i % 3]).powi(2);
        }
    }
    100.0 * (num / den).sqrt()
}

/// Interleaved xyz `f32` as `f64` points.
pub fn to_v3(f: &[f32]) -> Vec<V3> {
    f.chunks_exact(3).map(|p| [p[0] as f64, p[1] as f64, p[2] as f64]).collect()
}

/// `../shared/data`, or `None` (after a SKIP message) when it is absent.
pub fn data_root() -> Option<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data");
    if root.exists() {
        Some(root)
    } else {
        println!("SKIP: {} is absent", root.display());
        None
    }
}

/// `root/NAME/NAME.pc2` with the triangles of `NAME.obj`, its first `max_frames` frames at
/// 30 fps; `None` (after a SKIP message) when the cache cannot be read.
pub fn load_named(root: &Path, name: &str, max_frames: usize) -> Option<Animation> {
    let dir = root.join(name);
    let (n, frames, pos) = match read_pc2(&dir.join(format!("{name}.pc2"))) {
        Ok(x) => x,
        Err(e) => {
            println!("SKIP {name}: {e}");
            return None;
        }
    };
    let tris = read_obj_faces(&dir.join(format!("{name}.obj"))).expect("obj");
    let f = frames.min(max_frames);
    Some(Animation::new(Topology::new(n, tris).expect("topology"), pos[..f * n * 3].to_vec(), 30.0).expect("animation"))
}
