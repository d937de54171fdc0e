//! Micro-benchmark of the coding toolkit (`codec_core::toolkit`): throughput of each piece on a
//! synthetic 300 × 300 grid mesh (90 000 vertices) carrying a smooth field, with a memcpy of the
//! same values as the in-run baseline.
//!
//! ```sh
//! cargo run --release -p codec-core --example toolkit_bench
//! ```

use std::hint::black_box;
use std::time::Instant;

use codec_core::toolkit::adaptive::{AdaptiveDecoder, AdaptiveEncoder, CostModel};
use codec_core::toolkit::order::CausalGraph;
use codec_core::toolkit::predict::{self, Predictor};
use codec_core::toolkit::rdq::{self, RdPoint};

fn grid(w: usize, h: usize) -> Vec<[u32; 3]> {
    let mut t = Vec::new();
    for y in 0..h - 1 {
        for x in 0..w - 1 {
            let i = (y * w + x) as u32;
            let w = w as u32;
            t.push([i, i + 1, i + w]);
            t.push([i + 1, i + w + 1, i + w]);
        }
    }
    t
}

/// Best of `reps` timings of `f`, in seconds.
fn time(reps: usize, mut f: impl FnMut()) -> f64 {
    (0..reps)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let (w, h) = (300, 300);
    let n = w * h;
    let tris = grid(w, h);
    let reps = 5;

    let values: Vec<f64> = (0..n)
        .map(|v| {
            let (x, y) = ((v % w) as f64, (v / w) as f64);
            (0.05 * x).sin() * (0.03 * y).cos() + 0.001 * ((v * 7919) % 13) as f64
        })
        .collect();
    let mut copy = vec![0.0f64; n];
    let memcpy = time(reps * 4, || {
        copy.copy_from_slice(black_box(&values));
        black_box(&copy);
    });
    println!("toolkit micro-benchmark: {w}x{h} grid, {n} vertices, best of {reps}");
    println!("{:<42} {:>10} {:>14} {:>12}", "piece", "ms", "M items/s", "× memcpy");
    let row = |name: &str, secs: f64, items: usize| {
        println!("{name:<42} {:>10.3} {:>14.2} {:>12.1}", secs * 1e3, items as f64 / secs / 1e6, secs / memcpy);
    };
    row("memcpy of the field (f64)", memcpy, n);

    let mut graph = CausalGraph::mesh(n, &tris);
    row("order: CausalGraph::mesh (BFS + parallelogram)", time(reps, || graph = CausalGraph::mesh(n, &tris)), n);
    println!("    parallelogram share {:.3}", graph.parallelogram_share());
    let field: Vec<f64> = graph.order().iter().map(|&v| values[v as usize]).collect();

    let step = 1e-3;
    let (mut codes, mut recon) = (Vec::new(), Vec::new());
    for predictor in [Predictor::Zero, Predictor::Average, Predictor::Parallelogram] {
        let t = time(reps, || predict::quantize(&graph, predictor, &field, step, 0.0, &mut codes, &mut recon));
        let mean = codes.iter().map(|c| c.unsigned_abs() as f64).sum::<f64>() / n as f64;
        row(&format!("predict::quantize {}", predictor.name()), t, n);
        println!("    mean |code| {mean:.2}");
    }
    let t =
        time(reps, || predict::quantize(&graph, Predictor::Parallelogram, &field, step, 0.7, &mut codes, &mut recon));
    row("predict::quantize parallelogram, shaping 0.7", t, n);
    predict::quantize(&graph, Predictor::Parallelogram, &field, step, 0.0, &mut codes, &mut recon);
    let mut dec = Vec::new();
    row(
        "predict::dequantize parallelogram",
        time(reps, || predict::dequantize(&graph, Predictor::Parallelogram, &codes, step, &mut dec)),
        n,
    );
    assert_eq!(dec, recon);

    let buckets: Vec<usize> = (0..n).map(|p| predict::neighbour_bucket(&graph, &codes, p)).collect();
    let mut bytes = Vec::new();
    let t = time(reps, || {
        let mut enc = AdaptiveEncoder::new(1);
        for (c, b) in codes.iter().zip(&buckets) {
            enc.encode(*c, 0, *b);
        }
        bytes = enc.finish();
    });
    row("adaptive: encode", t, n);
    println!("    {:.3} bits per value", bytes.len() as f64 * 8.0 / n as f64);
    let mut out = vec![0i32; n];
    let t = time(reps, || {
        let mut d = AdaptiveDecoder::new(&bytes, 1, "bench", "codes").unwrap();
        for (o, b) in out.iter_mut().zip(&buckets) {
            *o = d.decode(0, *b).unwrap();
        }
    });
    assert_eq!(out, codes);
    row("adaptive: decode", t, n);
    let mut bits = 0.0;
    let t = time(reps, || {
        let mut m = CostModel::new(1);
        for (c, b) in codes.iter().zip(&buckets) {
            m.add(*c, 0, *b);
        }
        bits = m.bits();
    });
    row("adaptive: CostModel", t, n);
    println!("    estimate {:.0} bits vs coded {} bits", bits, bytes.len() * 8);

    // RD allocation: 300 components × 25 points.
    let comps: Vec<Vec<RdPoint>> = (0..300)
        .map(|i| {
            let scale = (-(i as f64) / 40.0).exp();
            rdq::step_grid(1.0, 25, 2)
                .into_iter()
                .map(|s| RdPoint {
                    rate: 1000.0 * ((scale / s).log2() + 2.0).max(0.0),
                    distortion: (1000.0 * s * s / 12.0).min(scale * 1000.0),
                })
                .collect()
        })
        .collect();
    let mut a = rdq::allocate(&comps, 1.0);
    let t = time(reps, || a = rdq::allocate(black_box(&comps), 1.0));
    row("rdq::allocate (300 components × 25 points)", t, 300 * 25);
    println!("    λ {:.3e}, distortion {:.3}, rate {:.0}", a.lambda, a.distortion, a.rate);
}
