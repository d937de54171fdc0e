//! `animcodec demo`: every synthetic animation × every codec at default parameters:
//! encode, decode, check, measure, and print a table.

use std::fmt::Write as _;
use std::time::Instant;

use animcodec::core::{encode_animation_fed, Animation, AnimationCodec, CodecRegistry, Limits, StreamDecoder};
use animcodec::synth::{self, SynthSize};
use serde_json::{json, Value};

use super::args::SizeArg;
use super::{emit, emit_json, CmdResult};
use clap::Args;

/// Arguments of `animcodec demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Size of the synthetic animations (large takes minutes).
    #[arg(long, value_enum, default_value_t = SizeArg::Medium)]
    pub size: SizeArg,

    /// Comma-separated codecs to run (default: every registered codec).
    #[arg(long, value_name = "A,B", value_delimiter = ',')]
    pub codecs: Vec<String>,

    /// Comma-separated synthetic animations to run (default: all).
    #[arg(long, value_name = "A,B", value_delimiter = ',')]
    pub animations: Vec<String>,

    /// Print JSON: an array of per-run results instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// Frames handed to the encoder per call, small enough that multi-packet streaming is exercised.
const FEED_FRAMES: usize = 16;

/// Error of a decoded animation against the original.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ErrorStats {
    /// Largest Euclidean distance of a vertex from its original position, over all frames.
    pub max_vertex_error: f64,
    /// Largest absolute error of a single coordinate.
    pub max_coordinate_error: f64,
    /// Root mean square of the per-vertex Euclidean error over all vertices and frames.
    pub rmse: f64,
    /// Root mean square of the per-coordinate error.
    pub rms_coordinate_error: f64,
}

/// Compares `decoded` with `original` (same sizes). Sums are taken in a fixed order in `f64`.
pub fn error_stats(original: &[f32], decoded: &[f32]) -> ErrorStats {
    debug_assert_eq!(original.len(), decoded.len());
    let mut s = ErrorStats::default();
    let mut sum_sq = 0.0;
    for (a, b) in original.chunks_exact(3).zip(decoded.chunks_exact(3)) {
        let d = [(a[0] - b[0]) as f64, (a[1] - b[1]) as f64, (a[2] - b[2]) as f64];
        let sq = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        sum_sq += sq;
        s.max_vertex_error = s.max_vertex_error.max(sq.sqrt());
        s.max_coordinate_error = d.iter().fold(s.max_coordinate_error, |m, x| m.max(x.abs()));
    }
    let n = (original.len() / 3).max(1) as f64;
    s.rmse = (sum_sq / n).sqrt();
    s.rms_coordinate_error = (sum_sq / (3.0 * n)).sqrt();
    s
}

/// One (animation, codec) run.
struct Run {
    animation: &'static str,
    codec: &'static str,
    vertices: usize,
    frames: usize,
    diagonal: f64,
    bytes: u64,
    stats: ErrorStats,
    /// KG error in percent (None when undefined, e.g. every frame a single point).
    kg: Option<f64>,
    /// STED with the metric author's defaults (None for a mesh without triangles).
    sted: Option<f64>,
    encode_seconds: f64,
    decode_seconds: f64,
    failure: Option<String>,
}

/// Runs `demo`.
pub fn run(args: &DemoArgs, limits: Limits) -> CmdResult {
    let registry = animcodec::registry();
    let codecs: Vec<&dyn AnimationCodec> = if args.codecs.is_empty() {
        registry.iter().collect()
    } else {
        args.codecs.iter().map(|n| registry.by_name(n.trim())).collect::<Result<_, _>>()?
    };
    let names: Vec<&'static str> = if args.animations.is_empty() {
        synth::NAMES.to_vec()
    } else {
        args.animations
            .iter()
            .map(|n| {
                synth::NAMES.iter().copied().find(|k| *k == n.trim()).ok_or_else(|| {
                    format!("unknown synthetic animation '{n}'; valid names: {}", synth::NAMES.join(", "))
                })
            })
            .collect::<Result<_, _>>()?
    };
    let size: SynthSize = args.size.into();

    let bar = crate::progress::Progress::counter("demo", (names.len() * codecs.len()) as u64, "runs", args.json);

    let mut runs = Vec::new();
    let mut animations = Vec::new();
    for &name in &names {
        bar.message(format!("synthesizing {name}"));
        let start = Instant::now();
        let animation = synth::by_name(name, size)?;
        animations.push((name, animation.vertex_count(), animation.frame_count(), start.elapsed().as_secs_f64()));
        for &codec in &codecs {
            bar.message(format!("{name} / {}", codec.name()));
            runs.push(run_one(&registry, codec, name, &animation, limits));
            bar.inc(1);
        }
    }
    bar.finish();
    drop(bar);

    let failures: Vec<String> =
        runs.iter().filter_map(|r| r.failure.as_ref().map(|f| format!("{} / {}: {f}", r.animation, r.codec))).collect();
    if args.json {
        emit_json(&Value::Array(runs.iter().map(run_json).collect()))?;
    } else {
        emit(&table(size, &animations, &runs))?;
    }
    if failures.is_empty() {
        Ok(())
    } else {
        Err(format!("{} of {} demo runs failed: {}", failures.len(), runs.len(), failures.join("; ")).into())
    }
}

fn run_one(
    registry: &CodecRegistry,
    codec: &dyn AnimationCodec,
    name: &'static str,
    animation: &Animation,
    limits: Limits,
) -> Run {
    let mut run = Run {
        animation: name,
        codec: codec.name(),
        vertices: animation.vertex_count(),
        frames: animation.frame_count(),
        diagonal: animation.bounding_box_diagonal(),
        bytes: 0,
        stats: ErrorStats::default(),
        kg: None,
        sted: None,
        encode_seconds: f64::NAN,
        decode_seconds: f64::NAN,
        failure: None,
    };
    if let Err(e) = measure(registry, codec, animation, limits, &mut run) {
        run.failure = Some(e);
    }
    run
}

/// Encodes, decodes and checks one run, filling `run`; the error says what failed.
fn measure(
    registry: &CodecRegistry,
    codec: &dyn AnimationCodec,
    animation: &Animation,
    limits: Limits,
    run: &mut Run,
) -> Result<(), String> {
    let params = codec.default_params();
    let start = Instant::now();
    let encoded = encode_animation_fed(codec, &params, animation, true, FEED_FRAMES)
        .map_err(|e| format!("encoding failed: {e}"))?;
    run.encode_seconds = start.elapsed().as_secs_f64();
    run.bytes = encoded.bytes.len() as u64;

    let start = Instant::now();
    let decoded = StreamDecoder::new(encoded.bytes.as_slice(), registry, limits)
        .and_then(|d| d.decode_all())
        .map_err(|e| format!("decoding failed: {e}"))?;
    run.decode_seconds = start.elapsed().as_secs_f64();
    run.stats = error_stats(animation.positions(), decoded.positions());
    run.kg = animcodec::metrics::kg_error(animation, &decoded).ok();
    run.sted =
        animcodec::metrics::sted(animation, &decoded, &animcodec::metrics::StedParams::default()).ok().map(|s| s.sted);

    let reconstruction = encoded.reconstruction.ok_or("the encoder returned no reconstruction")?;
    if !animcodec::core::connectivity::same_triangles(decoded.topology(), animation.topology())
        || decoded.frame_count() != animation.frame_count()
    {
        return Err("decoded topology or frame count differs from the input".into());
    }
    // Bit-exact: the encoder's closed loop must match what any decoder produces.
    if let Some(i) =
        reconstruction.positions().iter().zip(decoded.positions()).position(|(a, b)| a.to_bits() != b.to_bits())
    {
        let per_frame = animation.vertex_count() * 3;
        return Err(format!(
            "decoded frame {} vertex {} differs from the encoder's reconstruction",
            i / per_frame,
            (i % per_frame) / 3
        ));
    }
    let bound = codec.error_bound(&params, animation).map_err(|e| format!("error bound: {e}"))?;
    if let Some(max) = bound.max_coordinate_error {
        if run.stats.max_coordinate_error > max {
            return Err(format!(
                "max coordinate error {:.3e} exceeds the promised {max:.3e}",
                run.stats.max_coordinate_error
            ));
        }
    }
    if let Some(rel) = bound.relative_rms_error {
        let got = run.stats.rms_coordinate_error / run.diagonal.max(f64::MIN_POSITIVE);
        if got > rel {
            return Err(format!("relative RMS error {got:.3e} exceeds the promised {rel:.3e}"));
        }
    }
    Ok(())
}

fn run_json(r: &Run) -> Value {
    let finite = |x: f64| if x.is_finite() { Value::from(x) } else { Value::Null };
    json!({
        "animation": r.animation,
        "codec": r.codec,
        "vertices": r.vertices,
        "frames": r.frames,
        "bytes": r.bytes,
        "bpvf": animcodec::metrics::bpvf(r.bytes, r.vertices, r.frames).ok(),
        "kg": r.kg,
        "sted": r.sted,
        "max_error": r.stats.max_vertex_error,
        "max_error_relative": r.stats.max_vertex_error / r.diagonal,
        "rmse": r.stats.rmse,
        "encode_seconds": finite(r.encode_seconds),
        "decode_seconds": finite(r.decode_seconds),
        "ok": r.failure.is_none(),
        "error": r.failure,
    })
}

fn table(size: SynthSize, animations: &[(&str, usize, usize, f64)], runs: &[Run]) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "synthetic animations ({}):", size.name());
    for (name, v, f, secs) in animations {
        let _ = writeln!(out, "  {name:<9} {v:>6} vertices × {f:>4} frames (generated in {secs:.2} s)");
    }
    let _ = writeln!(
        out,
        "\n{:<9} {:<12} {:>10} {:>8} {:>9} {:>9} {:>10} {:>9} {:>10} {:>7} {:>7}  status",
        "animation", "codec", "bytes", "bpvf", "KG %", "STED", "max err", "max/diag", "rmse", "enc s", "dec s"
    );
    for r in runs {
        let status = match &r.failure {
            None => "ok".to_string(),
            Some(f) => format!("FAILED: {f}"),
        };
        let secs = |x: f64| if x.is_finite() { format!("{x:.3}") } else { "-".into() };
        let metric = |x: Option<f64>| x.map_or_else(|| "-".to_string(), |x| format!("{x:.3e}"));
        let _ = writeln!(
            out,
            "{:<9} {:<12} {:>10} {:>8.3} {:>9} {:>9} {:>10.3e} {:>9.2e} {:>10.3e} {:>7} {:>7}  {status}",
            r.animation,
            r.codec,
            r.bytes,
            animcodec::metrics::bpvf(r.bytes, r.vertices, r.frames).unwrap_or(f64::NAN),
            r.kg.map_or_else(|| "-".to_string(), |x| if x >= 0.01 { format!("{x:.4}") } else { format!("{x:.2e}") }),
            metric(r.sted),
            r.stats.max_vertex_error,
            r.stats.max_vertex_error / r.diagonal,
            r.stats.rmse,
            secs(r.encode_seconds),
            secs(r.decode_seconds),
        );
    }
    let _ = writeln!(
        out,
        "\nbpvf = container bits / (vertices × frames); raw f32 is 96. KG is Karni & Gotsman's error (%),\n\
         STED Váša & Skala's as the metric author's tool computes it (its defaults). Other errors are\n\
         Euclidean per vertex; max/diag is relative to the animation's bounding-box diagonal; rmse is\n\
         over all vertices and frames."
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_stats_measure_euclidean_and_coordinate_errors() {
        let a = [0.0, 0.0, 0.0, 1.0, 1.0, 1.0];
        let b = [3.0, 4.0, 0.0, 1.0, 1.0, 1.0];
        let s = error_stats(&a, &b);
        assert_eq!(s.max_vertex_error, 5.0);
        assert_eq!(s.max_coordinate_error, 4.0);
        assert!((s.rmse - (25.0f64 / 2.0).sqrt()).abs() < 1e-12);
        assert!((s.rms_coordinate_error - (25.0f64 / 6.0).sqrt()).abs() < 1e-12);
        assert_eq!(error_stats(&a, &a), ErrorStats::default());
    }
}
