//! Data helpers shared by the stseg examples: tiny PC2/OBJ readers (the real ones live in the
//! `animcodec` crate, which a codec crate must not depend on) and KG as `metrics` computes it.
#![allow(dead_code)]

use std::path::Path;

use codec_core::Animation;

/// `(vertex count, frame count, positions)` of a POINTCACHE2 file.
pub fn read_pc2(path: &Path) -> Result<(usize, usize, Vec<f32>), String> {
    let b = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    if b.len() < 32 || &b[..11] != b"POINTCACHE2" {
        return Err(format!("{}: not a PC2 file", path.display()));
    }
    let i32_at = |o: usize| i32::from_le_bytes(b[o..o + 4].try_into().unwrap());
    let (v, f) = (i32_at(16) as usize, i32_at(28) as usize);
    let need = 32 + v * f * 12;
    if b.len() < need {
        return Err(format!("{}: truncated", path.display()));
    }
    let pos = b[32..need].chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect();
    Ok((v, f, pos))
}

/// Triangles of the `f` lines of an OBJ file (fans for polygons).
pub fn read_obj_triangles(path: &Path) -> Result<Vec<[u32; 3]>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut tris = Vec::new();
    for line in text.lines() {
        let mut it = line.split_whitespace();
        if it.next() != Some("f") {
            continue;
        }
        let idx: Vec<u32> =
            it.filter_map(|t| t.split('/').next()?.parse::<i64>().ok()).map(|i| (i - 1) as u32).collect();
        for k in 1..idx.len().saturating_sub(1) {
            tris.push([idx[0], idx[k], idx[k + 1]]);
        }
    }
    Ok(tris)
}

/// KG = 100·‖A − Â‖_F / ‖A − E(A)‖_F, E(A) = per-frame centroid of the original (as `metrics`).
pub fn kg_error(a: &Animation, rec: &[f32]) -> f64 {
    let v = a.vertex_count();
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (t, frame) in a.frames().enumerate() {
        let mut c = [0.0f64; 3];
        for p in frame.chunks_exact(3) {
            for k in 0..3 {
                c[k] += p[k] as f64 / v as f64;
            }
        }
        for (i, &x) in frame.iter().enumerate() {
            let y = rec[t * v * 3 + i] as f64;
            num += (x as f64 - y).powi(2);
            den += (x as f64 - c[i % 3]).powi(2);
        }
    }
    100.0 * num.sqrt() / den.sqrt()
}
