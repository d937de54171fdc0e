//! Release benchmark for `pca-aoi` (in the spirit of the paper's Table 1).
//!
//! ```text
//! cargo build --release -p codec-pca-aoi --example pca_bench
//! target/release/examples/pca_bench table [DATA_DIR] [REPEATS]      # chicken-crossing + samba
//! target/release/examples/pca_bench stream [FRAMES] [VERTICES] [BLOCK]  # peak RSS of a long stream
//! target/release/examples/pca_bench speed [DATA_DIR] [NAME]    # decode vs memcpy, encode vs paper
//! ```
//!
//! `table`: for each dataset and each configuration (svd, baoi, baoi tmax=2, baoi z=2, qaoi,
//! and more iterations), encodes the sequence as a stream (7 frames per push), decodes it,
//! and reports bpvf (packet payload + per-packet container overhead; connectivity excluded),
//! KG computed here in f64, the dictionary-estimation time summed over blocks, and the
//! speed-up over svd measured in the same run. Times are the median of REPEATS runs.
//!
//! `speed`: the speed check on one animation (default samba), all in one run: per
//! subspace size `K`, the paper coding (`k = K`) and the toolkit coding (`max_k = K`, `kg`
//! 0.05 so that the RD rule keeps nearly every component) — bpvf, KG, encode time (best of 2),
//! decode time of all packets (best of 3) and a memcpy of the decoded frames (best of 5), as
//! "decode speed / memcpy speed" and "encode / paper encode":
//! `target/release/examples/pca_bench speed ../shared/data samba`.
//!
//! `stream`: pushes a synthetic animation of FRAMES × VERTICES frame by frame (10 frames per
//! push, generated on the fly, never held whole) and reports the peak resident set size.

use std::time::{Duration, Instant};

use codec_core::container::PACKET_OVERHEAD_BYTES;
use codec_core::{AnimationCodec, EncoderSetup, FrameEncoder, Limits, StreamInfo, Topology};
use codec_pca_aoi::{Coding, Method, Mode, PcaAoi, PcaAoiEncoder, PcaAoiParams};

struct Data {
    name: String,
    topology: Topology,
    frames: usize,
    positions: Vec<f32>,
}

fn read_pc2(path: &str) -> std::io::Result<(usize, usize, Vec<f32>)> {
    let b = std::fs::read(path)?;
    let bad = |m: &str| std::io::Error::new(std::io::ErrorKind::InvalidData, format!("{path}: {m}"));
    if b.len() < 32 || &b[..11] != b"POINTCACHE2" {
        return Err(bad("not a PC2 file"));
    }
    let i32_at = |o: usize| i32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
    let (v, f) = (i32_at(16) as usize, i32_at(28) as usize);
    let need = 32 + v * f * 12;
    if b.len() < need {
        return Err(bad("truncated"));
    }
    let pos = b[32..need].chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    Ok((v, f, pos))
}

fn read_obj_faces(path: &str, v: usize) -> std::io::Result<Vec<[u32; 3]>> {
    let text = std::fs::read_to_string(path)?;
    let mut tris = Vec::new();
    for line in text.lines() {
        let mut it = line.split_whitespace();
        if it.next() != Some("f") {
            continue;
        }
        let idx: Vec<u32> = it
            .filter_map(|t| t.split('/').next()?.parse::<i64>().ok())
            .map(|i| if i < 0 { v as i64 + i } else { i - 1 } as u32)
            .collect();
        for j in 1..idx.len().saturating_sub(1) {
            tris.push([idx[0], idx[j], idx[j + 1]]);
        }
    }
    Ok(tris)
}

fn load(root: &str, name: &str) -> Option<Data> {
    let pc2 = format!("{root}/{name}/{name}.pc2");
    let obj = format!("{root}/{name}/{name}.obj");
    let (v, f, positions) = match read_pc2(&pc2) {
        Ok(x) => x,
        Err(e) => {
            println!("SKIP {name}: {e}");
            return None;
        }
    };
    let tris = read_obj_faces(&obj, v).ok()?;
    Some(Data { name: name.into(), topology: Topology::new(v, tris).ok()?, frames: f, positions })
}

/// KG = 100·‖A−Â‖_F / ‖A−E(A)‖_F with E(A) the per-frame centroid of the original, in f64.
fn kg(v: usize, a: &[f32], b: &[f32]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (fa, fb) in a.chunks_exact(v * 3).zip(b.chunks_exact(v * 3)) {
        let mut c = [0.0f64; 3];
        for p in fa.chunks_exact(3) {
            for k in 0..3 {
                c[k] += p[k] as f64;
            }
        }
        for x in &mut c {
            *x /= v as f64;
        }
        for (i, (x, y)) in fa.iter().zip(fb).enumerate() {
            num += (*x as f64 - *y as f64).powi(2);
            den += (*x as f64 - c[i % 3]).powi(2);
        }
    }
    100.0 * (num / den).sqrt()
}

struct Run {
    bytes: usize,
    kg: f64,
    /// Estimation time, all blocks.
    est_all: Duration,
    /// Estimation time excluding the first block's SVD (the paper's measure).
    est_tail: Duration,
    guard: Duration,
    encode: Duration,
    mean_residual: f64,
    max_residual: f64,
    mean_k: f64,
    mean_iterations: f64,
    reinits: usize,
}

fn run(data: &Data, p: &PcaAoiParams) -> Run {
    let v = data.topology.vertex_count();
    let setup = EncoderSetup {
        topology: &data.topology,
        frame_count: data.frames,
        frame_rate: 30.0,
        want_reconstruction: false,
    };
    let start = Instant::now();
    let mut enc = PcaAoiEncoder::new(p, &setup).expect("encoder");
    let mut packets = Vec::new();
    for chunk in data.positions.chunks(7 * v * 3) {
        packets.extend(enc.push_frames(chunk).expect("encode"));
    }
    packets.extend(enc.finish().expect("encode"));
    let encode = start.elapsed();
    let info = StreamInfo {
        fourcc: PcaAoi.fourcc(),
        codec_version: PcaAoi.stream_version(),
        topology: data.topology.clone(),
        frame_count: data.frames,
        frame_rate: 30.0,
    };
    let mut dec = PcaAoi.new_decoder(&info, &enc.config(), &Limits::default()).expect("decoder");
    let mut out = Vec::with_capacity(data.positions.len());
    for p in &packets {
        out.extend(dec.decode_packet(&p.packet).expect("decode"));
    }
    let stats = enc.stats();
    let est_all = stats.iter().map(|s| s.estimate_time).sum();
    let est_tail = stats.iter().filter(|s| s.first_frame > 0).map(|s| s.estimate_time).sum();
    Run {
        bytes: packets.iter().map(|p| p.packet.data.len() + PACKET_OVERHEAD_BYTES).sum::<usize>() + enc.config().len(),
        kg: kg(v, &data.positions, &out),
        est_all,
        est_tail,
        guard: stats.iter().map(|s| s.guard_time).sum(),
        encode,
        mean_residual: stats.iter().map(|s| s.residual).sum::<f64>() / stats.len() as f64,
        max_residual: stats.iter().map(|s| s.residual).fold(0.0, f64::max),
        mean_k: stats.iter().map(|s| s.k as f64).sum::<f64>() / stats.len() as f64,
        mean_iterations: stats.iter().map(|s| s.iterations as f64).sum::<f64>() / stats.len() as f64,
        reinits: stats.iter().filter(|s| s.method == Method::Reinit).count(),
    }
}

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

fn table(root: &str, repeats: usize) {
    println!("pca-aoi benchmark; {} rayon threads; median of {repeats} interleaved runs", rayon::current_num_threads());
    for (name, blocks, k) in [("chicken-crossing", &[40u32, 100, 200][..], 12u32), ("samba", &[25, 35][..], 12)] {
        let Some(data) = load(root, name) else { continue };
        let v = data.topology.vertex_count();
        for (bi, &block) in blocks.iter().enumerate() {
            println!("\n## {} — {v} vertices, {} frames, block d = {block}, k = {k}", data.name, data.frames);
            // The paper's coding (§4.1): this table reproduces the paper.
            let base = PcaAoiParams { block, k, drift: 0.0, coding: Coding::Paper, ..Default::default() };
            let mut configs: Vec<(&str, PcaAoiParams)> = vec![
                ("svd", PcaAoiParams { mode: Mode::Svd, ..base }),
                ("baoi", base),
                ("baoi tmax=2", PcaAoiParams { tmax: 2, ..base }),
                ("baoi z=2", PcaAoiParams { z: 2, ..base }),
                ("qaoi [0.005,0.02]", PcaAoiParams { mode: Mode::Qaoi, eps_low: 0.005, eps_high: 0.02, ..base }),
            ];
            if bi == 0 {
                configs.extend([
                    ("baoi tmax=4", PcaAoiParams { tmax: 4, ..base }),
                    ("baoi tmax=8", PcaAoiParams { tmax: 8, ..base }),
                    ("baoi +guard(2)", PcaAoiParams { drift: 2.0, ..base }),
                    ("qaoi [0.002,0.01]", PcaAoiParams { mode: Mode::Qaoi, eps_low: 0.002, eps_high: 0.01, ..base }),
                ]);
            }
            // Interleave the repeats over the configurations so that load changes on a shared
            // machine hit every configuration alike.
            let mut runs: Vec<Vec<Run>> = configs.iter().map(|_| Vec::new()).collect();
            for _ in 0..repeats {
                for (i, (_, p)) in configs.iter().enumerate() {
                    runs[i].push(run(&data, p));
                }
            }
            println!(
                "| config | bpvf | KG | mean resid | max resid | mean k | OI/block | reinit | dict ms (blocks>0) | dict ms (all) | resid+guard ms | encode ms | dict speed-up vs svd |"
            );
            println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
            let mut svd_tail = None;
            for ((label, _), runs) in configs.iter().zip(&runs) {
                let r = &runs[0];
                for o in &runs[1..] {
                    assert_eq!(o.bytes, r.bytes, "non-deterministic stream size");
                }
                let tail = median(runs.iter().map(|r| r.est_tail).collect());
                let all = median(runs.iter().map(|r| r.est_all).collect());
                let guard = median(runs.iter().map(|r| r.guard).collect());
                let encode = median(runs.iter().map(|r| r.encode).collect());
                let base_tail = *svd_tail.get_or_insert(tail);
                println!(
                    "| {label} | {:.3} | {:.4} | {:.5} | {:.5} | {:.1} | {:.1} | {} | {:.2} | {:.2} | {:.2} | {:.1} | {:.1}× |",
                    r.bytes as f64 * 8.0 / (v * data.frames) as f64,
                    r.kg,
                    r.mean_residual,
                    r.max_residual,
                    r.mean_k,
                    r.mean_iterations,
                    r.reinits,
                    ms(tail),
                    ms(all),
                    ms(guard),
                    ms(encode),
                    ms(base_tail) / ms(tail),
                );
            }
        }
    }
}

fn peak_rss_kib() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    s.lines().find(|l| l.starts_with("VmHWM:"))?.split_whitespace().nth(1)?.parse().ok()
}

fn stream(frames: usize, vertices: usize, block: u32) {
    // A waving strip: cols × rows grid with vertices ≈ cols·rows.
    let cols = (vertices as f64).sqrt().ceil() as usize;
    let rows = vertices.div_ceil(cols);
    let v = cols * rows;
    let mut tris = Vec::new();
    for y in 0..rows - 1 {
        for x in 0..cols - 1 {
            let i = (y * cols + x) as u32;
            tris.push([i, i + 1, i + cols as u32]);
            tris.push([i + 1, i + cols as u32 + 1, i + cols as u32]);
        }
    }
    let topology = Topology::new(v, tris).unwrap();
    let p = PcaAoiParams { block, k: 8, ..Default::default() };
    let setup = EncoderSetup { topology: &topology, frame_count: frames, frame_rate: 30.0, want_reconstruction: false };
    let rss_before = peak_rss_kib();
    let start = Instant::now();
    let mut enc = PcaAoiEncoder::new(&p, &setup).unwrap();
    let mut bytes = 0usize;
    let mut chunk = Vec::with_capacity(10 * v * 3);
    let mut t = 0;
    while t < frames {
        chunk.clear();
        for f in t..(t + 10).min(frames) {
            let tt = f as f32 * 0.05;
            for y in 0..rows {
                for x in 0..cols {
                    let (u, w) = (x as f32 / cols as f32, y as f32 / rows as f32);
                    let z = 0.2 * u * (6.0 * u - 2.0 * tt).sin() + 0.05 * (4.0 * w + 1.3 * tt).cos() * u;
                    chunk.extend_from_slice(&[u + 0.001 * tt, w, z]);
                }
            }
        }
        t = (t + 10).min(frames);
        for p in enc.push_frames(&chunk).unwrap() {
            bytes += p.packet.data.len() + PACKET_OVERHEAD_BYTES;
        }
    }
    for p in enc.finish().unwrap() {
        bytes += p.packet.data.len() + PACKET_OVERHEAD_BYTES;
    }
    let elapsed = start.elapsed();
    let raw_mib = (frames * v * 12) as f64 / (1 << 20) as f64;
    let block_mib = (block as usize * v * 12) as f64 / (1 << 20) as f64;
    println!(
        "stream: {frames} frames × {v} vertices (raw {raw_mib:.0} MiB, one block of {block} frames {block_mib:.1} MiB as f32)"
    );
    println!(
        "encoded {:.1} MiB ({:.3} bpvf) in {:.1} s; peak RSS before encoder {} KiB, after {} KiB ({:.1} MiB)",
        bytes as f64 / (1 << 20) as f64,
        bytes as f64 * 8.0 / (frames * v) as f64,
        elapsed.as_secs_f64(),
        rss_before.unwrap_or(0),
        peak_rss_kib().unwrap_or(0),
        peak_rss_kib().unwrap_or(0) as f64 / 1024.0,
    );
}

fn best_of(n: usize, mut f: impl FnMut()) -> f64 {
    (0..n)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn speed(root: &str, name: &str) {
    let Some(data) = load(root, name) else { return };
    let v = data.topology.vertex_count();
    let setup = EncoderSetup {
        topology: &data.topology,
        frame_count: data.frames,
        frame_rate: 30.0,
        want_reconstruction: false,
    };
    let info = StreamInfo {
        fourcc: PcaAoi.fourcc(),
        codec_version: PcaAoi.stream_version(),
        topology: data.topology.clone(),
        frame_count: data.frames,
        frame_rate: 30.0,
    };
    println!(
        "## {name}: speed ({v} vertices x {} frames; decoded output {:.1} MB; {} rayon threads)\n",
        data.frames,
        data.positions.len() as f64 * 4.0 / 1e6,
        rayon::current_num_threads()
    );
    println!("| K | coding | bpvf | KG | encode s | decode s | memcpy s | decode speed / memcpy speed | encode / paper encode |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for big_k in [8u32, 32, 120] {
        let mut paper_encode = f64::NAN;
        for coding in [Coding::Paper, Coding::Toolkit] {
            let p = PcaAoiParams { k: big_k, max_k: big_k, kg: 0.05, coding, ..Default::default() };
            let mut packets = Vec::new();
            let mut config = Vec::new();
            let encode = best_of(2, || {
                let mut enc = PcaAoiEncoder::new(&p, &setup).expect("encoder");
                packets = enc.push_frames(&data.positions).expect("encode");
                packets.extend(enc.finish().expect("encode"));
                config = enc.config();
            });
            let mut out = Vec::new();
            let decode = best_of(3, || {
                let mut dec = PcaAoi.new_decoder(&info, &config, &Limits::default()).expect("decoder");
                out = Vec::with_capacity(data.positions.len());
                for p in &packets {
                    out.extend(dec.decode_packet(&p.packet).expect("decode"));
                }
            });
            let mut copy = vec![0.0f32; out.len()];
            let memcpy = best_of(5, || {
                copy.copy_from_slice(std::hint::black_box(&out));
                std::hint::black_box(&copy);
            });
            if coding == Coding::Paper {
                paper_encode = encode;
            }
            let bytes: usize = packets.iter().map(|p| p.packet.data.len() + PACKET_OVERHEAD_BYTES).sum();
            println!(
                "| {big_k} | {coding:?} | {:.3} | {:.3} | {encode:.3} | {decode:.4} | {memcpy:.5} | {:.2}% | {:.2} |",
                bytes as f64 * 8.0 / (v * data.frames) as f64,
                kg(v, &data.positions, &out),
                100.0 * memcpy / decode,
                encode / paper_encode,
            );
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    match args.get(1).map(String::as_str) {
        Some("speed") => {
            let root = args.get(2).cloned().unwrap_or_else(|| "../shared/data".into());
            speed(&root, args.get(3).map_or("samba", String::as_str));
        }
        Some("stream") => {
            let frames = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(5000);
            let vertices = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(10_000);
            let block = args.get(4).and_then(|s| s.parse().ok()).unwrap_or(40);
            stream(frames, vertices, block);
        }
        _ => {
            let root = args.get(2).cloned().unwrap_or_else(|| "../shared/data".into());
            let repeats = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(5);
            table(&root, repeats);
        }
    }
}
