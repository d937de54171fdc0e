//! The speed check for `stseg`, all in one run: per ω, encode and decode times of the
//! paper coding (`coding=paper`) and the toolkit coding (stream version 3's default) at equal
//! settings, and a memcpy of the decoded frames as the in-run baseline (best of 3 timings each).
//!
//! `cargo build --release -p codec-stseg --example stseg_speed && target/release/examples/stseg_speed [NAME...]`
//! (default samba; data from `../shared/data`, skipped with a message when absent).

use std::path::Path;
use std::time::Instant;

use codec_core::{decode_animation, encode_animation_fed, Animation, CodecRegistry, Limits, Topology};
use codec_stseg::{Coding, Stseg, StsegParams};

#[path = "support/data.rs"]
mod data;

use data::{kg_error, read_obj_triangles, read_pc2};

/// Best of `reps` timings of `f`.
fn best_of(reps: usize, mut f: impl FnMut()) -> f64 {
    (0..reps)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data");
    if !root.exists() {
        println!("SKIP: {} not found", root.display());
        return;
    }
    let mut names: Vec<String> = std::env::args().skip(1).collect();
    if names.is_empty() {
        names = vec!["samba".into()];
    }
    let reg = CodecRegistry::new(vec![Box::new(Stseg)]).unwrap();
    for name in &names {
        let dir = root.join(name);
        let (v, _f, pos) = match read_pc2(&dir.join(format!("{name}.pc2"))) {
            Ok(x) => x,
            Err(e) => {
                println!("SKIP {name}: {e}");
                continue;
            }
        };
        let tris = read_obj_triangles(&dir.join(format!("{name}.obj"))).unwrap();
        let a = Animation::new(Topology::new(v, tris).unwrap(), pos, 30.0).unwrap();
        let out_bytes = a.positions().len() * 4;
        println!("\n## {name}: speed (best of 3; decoded output {:.1} MB)\n", out_bytes as f64 / 1e6);
        println!(
            "| ω | coding | bpvf | KG | encode s | decode s | memcpy s | decode speed / memcpy speed | encode / paper encode |"
        );
        println!("|---|---|---|---|---|---|---|---|---|");
        for omega in [0.99, 0.999, 0.9999] {
            let mut paper_enc = 0.0;
            for coding in [Coding::Paper, Coding::Toolkit] {
                let ps = StsegParams { omega, coding, ..Default::default() }.to_param_set().unwrap();
                let mut bytes = Vec::new();
                let enc_s =
                    best_of(3, || bytes = encode_animation_fed(&Stseg, &ps, &a, false, a.frame_count()).unwrap().bytes);
                let mut dec = None;
                let dec_s = best_of(3, || dec = Some(decode_animation(&bytes, &reg, Limits::default()).unwrap()));
                let dec = dec.unwrap();
                let mut copy = vec![0.0f32; dec.positions().len()];
                let memcpy_s = best_of(5, || {
                    copy.copy_from_slice(std::hint::black_box(dec.positions()));
                    std::hint::black_box(&copy);
                });
                if coding == Coding::Paper {
                    paper_enc = enc_s;
                }
                println!(
                    "| {omega} | {} | {:.3} | {:.3} | {enc_s:.3} | {dec_s:.4} | {memcpy_s:.5} | {:.2}% | {:.2} |",
                    coding.name(),
                    bytes.len() as f64 * 8.0 / (a.vertex_count() * a.frame_count()) as f64,
                    kg_error(&a, dec.positions()),
                    100.0 * memcpy_s / dec_s,
                    enc_s / paper_enc,
                );
            }
        }
    }
}
