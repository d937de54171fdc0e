//! Tiny PC2 / OBJ readers for the example and the real-data test: positions from PC2 and
//! `f` lines from OBJ only. The real readers live in the `animcodec` crate, which `metrics`
//! must not depend on.
#![allow(dead_code)]

use std::path::Path;

/// Boxed-error result.
pub type Res<T> = Result<T, Box<dyn std::error::Error>>;

/// `(vertex count, frame count, positions)` of a POINTCACHE2 file.
pub fn read_pc2(path: &Path) -> Res<(usize, usize, Vec<f32>)> {
    let b = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    if b.len() < 32 || &b[..12] != b"POINTCACHE2\0" {
        return Err(format!("{}: not a POINTCACHE2 file", path.display()).into());
    }
    let i32_at = |o: usize| i32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
    let (v, f) = (i32_at(16), i32_at(28));
    if v <= 0 || f <= 0 || b.len() != 32 + v as usize * f as usize * 12 {
        return Err(format!("{}: header ({v} vertices, {f} frames) does not match the size", path.display()).into());
    }
    let p = b[32..].chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    Ok((v as usize, f as usize, p))
}

/// Triangles of an OBJ file (polygons fanned), 0-based.
pub fn read_obj_triangles(path: &Path) -> Res<Vec<[u32; 3]>> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut tris = Vec::new();
    for (ln, line) in text.lines().enumerate() {
        let mut it = line.split_whitespace();
        if it.next() != Some("f") {
            continue;
        }
        // "a", "a/b", "a/b/c", "a//c": the vertex index comes first; polygons are fanned.
        let idx: Vec<u32> = it
            .map(|tok| tok.split('/').next().unwrap_or("").parse::<u32>().ok().filter(|&i| i > 0).map(|i| i - 1))
            .collect::<Option<_>>()
            .ok_or_else(|| format!("{}:{}: bad face", path.display(), ln + 1))?;
        for k in 1..idx.len().saturating_sub(1) {
            tris.push([idx[0], idx[k], idx[k + 1]]);
        }
    }
    Ok(tris)
}
