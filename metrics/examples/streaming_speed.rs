//! Speed of the streaming metrics against the whole-array ones on a large synthetic flag, in
//! one run (same machine, same load): `evaluate` on the whole animation, then
//! `StreamingEvaluator` fed `--chunk` frames at a time; the reports must be equal, and the
//! ratio whole/streaming time is printed (≥ 0.5 is the goal: streaming at least half as fast).
//!
//! ```text
//! cargo run -p metrics --example streaming_speed -- [COLS ROWS FRAMES] [--chunk N] [--no-sted] [--no-hausdorff]
//!     [--streaming-only]
//! ```
//!
//! `--streaming-only` skips `evaluate` (for the peak memory of the streaming path under
//! `/usr/bin/time -v`: the two animations this program builds are 2 × 12 bytes per
//! vertex-frame of it).
//!
//! Default: a 1000 × 1000 flag (1M vertices), 6 frames, chunks of one frame per worker
//! thread. The candidate is the flag quantized to 12 bits over its bounding box.

use std::time::Instant;

use codec_core::Animation;
use metrics::{evaluate, EvalOptions, StreamingEvaluator};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let numbers: Vec<usize> = args.iter().take_while(|a| !a.starts_with("--")).map(|a| a.parse().unwrap()).collect();
    let (cols, rows, frames) = match numbers[..] {
        [c, r, f] => (c, r, f),
        _ => (1000, 1000, 6),
    };
    let flag = |name: &str| args.iter().any(|a| a == name);
    let chunk = args
        .iter()
        .position(|a| a == "--chunk")
        .and_then(|i| args.get(i + 1))
        .map_or(rayon::current_num_threads(), |n| n.parse().unwrap());
    let options = EvalOptions {
        compute_sted: !flag("--no-sted"),
        compute_hausdorff: !flag("--no-hausdorff"),
        ..Default::default()
    };

    let reference = animcodec_synth::waving_flag(cols, rows, frames);
    let candidate = quantized(&reference, 12);
    println!(
        "flag {cols} × {rows} ({} vertices), {frames} frames ({} MB of frames), {} threads, chunks of {chunk} frames",
        reference.vertex_count(),
        reference.positions().len() * 4 / 1_000_000,
        rayon::current_num_threads()
    );

    let t = Instant::now();
    let whole = (!flag("--streaming-only")).then(|| evaluate(&reference, &candidate, &options).unwrap());
    let whole_s = t.elapsed().as_secs_f64();

    let t = Instant::now();
    let mut s = StreamingEvaluator::new(reference.topology(), frames, reference.frame_rate(), &options).unwrap();
    let per = 3 * reference.vertex_count() * chunk.max(1);
    for (a, b) in reference.positions().chunks(per).zip(candidate.positions().chunks(per)) {
        s.push(a, b).unwrap();
    }
    let streamed = s.finish().unwrap();
    let streamed_s = t.elapsed().as_secs_f64();

    let held = StreamingEvaluator::bytes_held(reference.topology(), &options);
    let Some(whole) = whole else {
        println!("streaming {streamed_s:.2} s, KG {:.4} %; window bound {} MB", streamed.kg.unwrap(), held / 1_000_000);
        return;
    };
    assert_eq!(streamed, whole, "the streaming report differs from evaluate's");
    println!("KG {:.4} %, Hausdorff {:?}, STED {:?}: reports equal", whole.kg.unwrap(), whole.hausdorff, whole.sted);
    println!(
        "evaluate {whole_s:.2} s, streaming {streamed_s:.2} s: speed ratio (whole time / streaming time) {:.2}; \
         streaming window bound {} MB",
        whole_s / streamed_s,
        held / 1_000_000
    );
}

/// Every coordinate rounded to `bits` over the animation's bounding box.
fn quantized(a: &Animation, bits: u32) -> Animation {
    let (lo, hi) = a.bounding_box();
    let steps = ((1u64 << bits) - 1) as f32;
    let p = a
        .positions()
        .chunks(3)
        .flat_map(|c| {
            [0, 1, 2].map(|k| {
                let span = (hi[k] - lo[k]).max(f32::MIN_POSITIVE);
                lo[k] + ((c[k] - lo[k]) / span * steps).round() / steps * span
            })
        })
        .collect();
    Animation::new(a.topology().clone(), p, a.frame_rate()).unwrap()
}
