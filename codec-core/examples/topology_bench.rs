//! Topology coding on real meshes: container version 1's list coding, version 2's
//! connectivity coding (method 1), version 3's traversal coding (method 2) and version 5's
//! predicted traversal (method 3): bytes, bits per triangle, encode and decode time, same run;
//! then where methods 2 and 3 spend their bits (ideal code length per symbol class).
//!
//! `cargo run --release -p codec-core --example topology_bench -- ../shared/data/*/*.obj`

use std::time::Instant;

use codec_core::connectivity::{canonical_order, decode, encode};
use codec_core::container::encode_topology_list;
use codec_core::traversal;
use codec_core::Topology;

fn load_obj(path: &str) -> Result<Topology, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    let mut vertices = 0usize;
    let mut triangles = Vec::new();
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => vertices += 1,
            Some("f") => {
                let idx: Vec<u32> = it
                    .map(|w| w.split('/').next().unwrap_or("").parse::<u32>().map(|i| i - 1))
                    .collect::<Result<_, _>>()
                    .map_err(|e| format!("{path}: face '{line}': {e}"))?;
                // Fan-triangulate polygons.
                for k in 1..idx.len().saturating_sub(1) {
                    triangles.push([idx[0], idx[k], idx[k + 1]]);
                }
            }
            _ => {}
        }
    }
    Topology::new(vertices, triangles).map_err(|e| format!("{path}: {e}"))
}

fn best_of<T>(runs: usize, mut f: impl FnMut() -> T) -> (T, f64) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..runs {
        let t = Instant::now();
        out = Some(f());
        best = best.min(t.elapsed().as_secs_f64());
    }
    (out.expect("runs > 0"), best)
}

fn main() {
    let paths: Vec<String> = std::env::args().skip(1).collect();
    if paths.is_empty() {
        eprintln!("usage: topology_bench MESH.obj...");
        std::process::exit(2);
    }
    println!("| mesh | triangles | list bytes | list bits/tri | method 1 bytes | method 1 bits/tri | method 2 bytes | method 2 bits/tri | method 3 bytes | method 3 bits/tri | method 3 / method 2 | canonical order s | method 1 encode s | method 1 decode s | method 2 encode s | method 2 decode s | method 3 encode s | method 3 decode s |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut breakdown = Vec::new();
    for path in &paths {
        let topo = match load_obj(path) {
            Ok(t) => t,
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(1);
            }
        };
        let n = topo.triangle_count().max(1) as f64;
        let (v1, _) = best_of(1, || encode_topology_list(&topo));
        let (canon, t_canon) = best_of(3, || canonical_order(&topo));
        let (v2, t_enc) = best_of(3, || encode(&canon).expect("indices fit"));
        let (back, t_dec) = best_of(3, || decode(&v2, canon.vertex_count(), canon.triangle_count()).expect("decodes"));
        assert_eq!(back, canon, "round trip");
        let (v3, t_enc3) = best_of(3, || traversal::encode(&canon).expect("indices fit"));
        let (back3, t_dec3) =
            best_of(3, || traversal::decode(&v3, canon.vertex_count(), canon.triangle_count()).expect("decodes"));
        assert_eq!(back3, canon, "method 2 round trip");
        let (v4, t_enc4) = best_of(3, || traversal::encode_predicted(&canon).expect("indices fit"));
        let (back4, t_dec4) = best_of(3, || {
            traversal::decode_predicted(&v4, canon.vertex_count(), canon.triangle_count()).expect("decodes")
        });
        assert_eq!(back4, canon, "method 3 round trip");
        let name = std::path::Path::new(path).file_stem().map_or(path.clone(), |s| s.to_string_lossy().into_owned());
        println!(
            "| {name} | {} | {} | {:.2} | {} | {:.2} | {} | {:.2} | {} | {:.2} | {:.3} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} |",
            topo.triangle_count(),
            v1.len(),
            v1.len() as f64 * 8.0 / n,
            v2.len(),
            v2.len() as f64 * 8.0 / n,
            v3.len(),
            v3.len() as f64 * 8.0 / n,
            v4.len(),
            v4.len() as f64 * 8.0 / n,
            v4.len() as f64 / v3.len().max(1) as f64,
            t_canon,
            t_enc,
            t_dec,
            t_enc3,
            t_dec3,
            t_enc4,
            t_dec4
        );
        breakdown.push((name, n, canon));
    }
    // Where methods 2 and 3 spend their bits (ideal code lengths per class, bits per triangle).
    println!();
    println!("| mesh | method | ops | new-vertex ranks | candidate flags | escapes | seen deltas | component starts | total |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for (name, n, canon) in &breakdown {
        for (method, predicted) in [(2, false), (3, true)] {
            let b = traversal::bits_by_class(canon, predicted).expect("indices fit");
            println!(
                "| {name} | {method} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} |",
                b[0] / n,
                b[1] / n,
                b[5] / n,
                b[2] / n,
                b[3] / n,
                b[4] / n,
                b.iter().sum::<f64>() / n
            );
        }
    }
}
