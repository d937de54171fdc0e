//! `animcodec encode`: animation file → `.anim` container, streamed to disk.

use std::io::Write;
use std::time::Instant;

use animcodec::core::{Animation, AnimationCodec, Limits, ParamSet, StreamDecoder, StreamEncoder, Topology};
use animcodec::formats::stream::{self as cache_stream, CacheReader};
use animcodec::front::{self, EvaluationFields, Streams, TargetSummary};
use animcodec::harness::{
    self, CacheSource, FrameRead, InputSource, SearchRequest, StreamedInput, Target, TargetMetric,
};
use animcodec::metrics::{EvalOptions, MetricReport};
use animcodec::output::{OutputPolicy, PendingFile};
use animcodec::params::params_json;
use animcodec::synth;
use serde::Serialize;
use serde_json::Value;

use super::args::{ReadArgs, StedArgs};
use super::{emit, emit_document, load, raw_bytes, CmdResult, WithContext};
use crate::progress::{self, Progress};
use clap::Args;
use std::path::PathBuf;

/// Arguments of `animcodec encode`.
#[derive(Debug, Args)]
pub struct EncodeArgs {
    /// Input animation: .pc2, .mdd, .gltf/.glb, an OBJ directory or pattern,
    /// `synth:NAME[:small|medium|large]`, or `synth:flag:COLSxROWSxFRAMES` (a flag of any
    /// length: its frames are generated one at a time while encoding, never all held; its mesh
    /// is held, about 420 bytes a vertex, and refused when that exceeds --memory).
    #[arg(value_name = "INPUT")]
    pub input: String,

    /// Codec name (see `animcodec list`), or `auto` (every codec searched for the smallest
    /// stream meeting the target or the default quality).
    #[arg(short, long, value_name = "CODEC")]
    pub codec: String,

    /// Codec parameter as key=value (repeatable; see `animcodec list` for keys and ranges).
    #[arg(short = 'p', long = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,

    /// Output `.anim` file, written under a temporary name and renamed into place when
    /// complete (an interrupted or failed encode leaves no file and changes nothing).
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,

    /// Replace existing output files (without it, an existing output is an error). An output
    /// that is also an input is refused even with it.
    #[arg(short, long)]
    pub force: bool,

    /// Frame rate to use when the input stores none (or to override a synthetic one).
    #[arg(long, value_name = "F", value_parser = super::parse_fps, allow_negative_numbers = true)]
    pub fps: Option<f32>,

    /// Frames handed to the encoder per call (the output does not depend on it).
    #[arg(long, value_name = "N", default_value_t = 32, value_parser = clap::value_parser!(u32).range(1..))]
    pub feed: u32,

    /// Memory budget (bytes; K, M, G suffixes are powers of 1024), e.g. 4G. A .pc2/.mdd input,
    /// an OBJ sequence (or synth:flag:CxRxF) is read frame by frame, so an encode with -p holds
    /// the mesh and what the codec buffers; a codec whose analysis holds a whole block of frames
    /// (hosvd with block=0) chooses temporal blocks that fit the budget. The stream depends on
    /// the budget, never on the machine. The searches (no -p, --target, -c auto) hold the whole
    /// input while that fits the budget; beyond it they stream: each candidate is encoded from
    /// the input as it is read and measured against a second read (a quarter of the budget is
    /// kept for candidate streams, the codec's blocks are fitted to the rest). A codec whose
    /// encoder holds the whole input (sac, stseg) is refused beyond it. Default: none for -p
    /// (hosvd decomposes the whole sequence at once); for the searches, half the machine's RAM.
    #[arg(long, value_name = "BYTES", value_parser = super::parse_bytes)]
    pub memory: Option<u64>,

    /// Search the codec's declared parameter space (its rate ladder on the configurations of
    /// its secondary parameters meant for the target's kind of error: positional, STED or
    /// both; `animcodec list` shows each codec's parameters and ladder) for the smallest stream
    /// whose decoded error meets METRIC=VALUE, or every bound of METRIC=VALUE,METRIC=VALUE…
    /// (metrics: kg [%], sted, hausdorff, max_error, rmse; absolute values in model units
    /// except kg). Parameters given with `-p` stay fixed. With `-c auto`, every codec is
    /// searched and the smallest stream kept. Fails, stating the best errors reached, when no
    /// point meets the target. Without -p and without --target, encode aims at the default
    /// quality, kg=0.5,sted=0.05.
    #[arg(long, value_name = "METRIC=VALUE[,…]", value_parser = super::args::parse_target)]
    pub target: Option<animcodec::harness::Target>,

    /// With --target: extra points bisecting the ladder parameter between the last step that
    /// misses and the first that meets the target (ladders are coarse; integers stop when the
    /// bracket closes). 0 keeps to the ladder's own steps.
    #[arg(long, value_name = "N", default_value_t = 4, value_parser = clap::value_parser!(u32).range(0..=32))]
    pub refine: u32,

    /// With a target: search the codec's single rate ladder only (on the -p parameters), as
    /// before the parameter-space search.
    #[arg(long)]
    pub ladder: bool,

    /// After encoding, decode the written stream and measure it against the input: KG, STED,
    /// Hausdorff, RMSE and max error are printed (and added to --json as `kg`, `sted` and the
    /// full report under `metrics`). With -p, an input read frame by frame (.pc2, .mdd, an OBJ
    /// sequence, synth:flag:CxRxF) is measured frame by frame too: the input is read (or
    /// generated) again beside the stream decoded packet by packet, within --memory.
    #[arg(long)]
    pub eval: bool,

    /// STED options for `--eval` and `--target sted=…`.
    #[command(flatten)]
    pub sted: StedArgs,

    /// Print JSON: {codec, params, bytes, bpvf, frames, vertices, triangles, encode_seconds, …}.
    #[arg(long)]
    pub json: bool,

    /// How the input is read.
    #[command(flatten)]
    pub read: ReadArgs,
}

/// The document of `encode --json` with fixed parameters.
#[derive(Debug, Serialize)]
pub struct EncodeDocument<'a> {
    /// The codec.
    pub codec: &'static str,
    /// Its parameters.
    pub params: Value,
    /// The input as given.
    pub input: &'a str,
    /// The stream written.
    pub output: String,
    /// The stream's size.
    pub bytes: u64,
    /// Its bits per vertex per frame.
    pub bpvf: f64,
    /// Raw f32 size over the stream's.
    pub ratio: f64,
    /// Frames.
    pub frames: usize,
    /// Vertices per frame.
    pub vertices: usize,
    /// Triangles.
    pub triangles: usize,
    /// Frames per second.
    pub frame_rate: f32,
    /// Seconds reading the input.
    pub read_seconds: f64,
    /// Seconds encoding.
    pub encode_seconds: f64,
    /// The encoder's warnings.
    pub notes: Vec<String>,
    /// `--eval`'s figures.
    #[serde(flatten)]
    pub evaluation: Option<EvaluationFields>,
}

/// The document of `encode --json` with a target (or the default quality).
#[derive(Debug, Serialize)]
pub struct TargetEncodeDocument<'a> {
    /// What the search found.
    #[serde(flatten)]
    pub summary: TargetSummary,
    /// The input as given.
    pub input: &'a str,
    /// The stream written.
    pub output: String,
    /// Whether the target is the default quality (no -p, no --target).
    pub default_target: bool,
    /// `space` or `ladder`.
    pub search: &'static str,
    /// The chosen encode's warnings and remarks.
    pub notes: Vec<String>,
    /// How the search read the input: `whole` (the animation in memory) or `streamed` (each
    /// candidate encoded from the input as it is read and measured against a second read).
    pub search_input: &'static str,
    /// The memory budget the search kept to (bytes): `--memory`, or the default share of the
    /// machine's RAM; `null` when none applies.
    pub memory_budget: Option<u64>,
    /// Whether `memory_budget` is the default (no `--memory`).
    pub memory_budget_default: bool,
    /// Raw f32 size over the stream's.
    pub ratio: f64,
    /// Frames.
    pub frames: usize,
    /// Vertices per frame.
    pub vertices: usize,
    /// Triangles.
    pub triangles: usize,
    /// Frames per second.
    pub frame_rate: f32,
    /// Seconds reading the input.
    pub read_seconds: f64,
    /// Seconds searching.
    pub search_seconds: f64,
    /// Seconds encoding the chosen point.
    pub encode_seconds: f64,
    /// `--eval`'s figures.
    #[serde(flatten)]
    pub evaluation: Option<EvaluationFields>,
}

/// Runs `encode`.
pub fn run(args: &EncodeArgs, limits: Limits) -> CmdResult {
    // Mistyped arguments first, then the output, all before anything long happens.
    let streamed = front::streamed_flag(&args.input)?.is_some();
    if args.eval {
        args.sted.metric_options().sted_params()?;
    }
    let policy = output_policy(args);
    if let Some(target) = args.target {
        return run_target(args, target, false, limits, &policy);
    }
    // Quality by default: no parameters and no target aims at the documented default quality
    // and picks the parameters for this input. A streamed flag is never held in memory, so it
    // cannot be searched: it keeps the codec's fixed defaults.
    if args.params.is_empty() && !streamed {
        return run_target(args, harness::DEFAULT_TARGET, true, limits, &policy);
    }
    if args.codec == "auto" {
        return Err("-c auto searches every codec for the smallest stream meeting an error target \
                    (--target METRIC=VALUE, or the default quality without -p); it takes no -p and cannot \
                    encode a streamed synth:flag:COLSxROWSxFRAMES: name a codec (see `animcodec list`)"
            .into());
    }
    let registry = animcodec::registry();
    let codec = registry.by_name(&args.codec)?;
    let params = front::params_from_text(codec, &args.params)?;
    policy.check(&args.output)?;
    animcodec::output::folder_exists(&args.output)?;

    let read_start = Instant::now();
    let mut source = match front::streamed_flag(&args.input)? {
        Some((cols, rows, frames)) => {
            check_flag_memory(&args.input, cols, rows, args.memory)?;
            Source::Flag { cols, rows, frames }
        }
        None => {
            let options = args.read.options(args.fps);
            // A PC2/MDD cache or an OBJ sequence is read frame by frame as the encoder takes it
            // (inputs may be larger than memory); --eval reads it again, frame by frame.
            let path = std::path::Path::new(&args.input);
            if cache_stream::is_streamable(path) {
                Source::Cache(CacheReader::open(path, &options)?)
            } else {
                Source::Whole(load(&args.input, &options, limits, Streams::Refuse)?.animation)
            }
        }
    };
    let topology = source.topology();
    let (frame_count, frame_rate) = source.frames_and_rate(args.fps);
    let read_seconds = read_start.elapsed().as_secs_f64();
    if args.eval && !matches!(source, Source::Whole(_)) {
        // --eval's frame-by-frame measurement must fit --memory: refused before encoding.
        streamed_eval_limits(&args.input, &topology, &args.sted.metric_options().eval_options()?, args.memory, limits)?;
    }
    // A codec with a whole-block analysis chooses its blocks by the memory budget.
    let asked = params.clone();
    let params = match args.memory {
        Some(budget) => codec.fit_memory(&params, topology.vertex_count(), frame_count, budget)?,
        None => params,
    };
    // What the encode does other than the user asked, said before it starts (stderr) and
    // kept with the encoder's warnings (the text's `warning:` lines, `--json` "notes").
    let substitutions = substitutions(args, streamed, codec, &asked, &params);
    for n in &substitutions {
        eprintln!("animcodec: warning: {n}");
    }

    let start = Instant::now();
    // Written to a temporary file renamed into place when complete: a failure or an interruption
    // leaves whatever was at the output path before.
    let file = policy.create(&args.output)?;
    let progress = Progress::counter("encode", frame_count as u64, "frames", args.json);
    let (mut file, bytes, notes) = encode_to_file(
        codec,
        &params,
        &mut source,
        (&topology, frame_count, frame_rate),
        file,
        (args.feed as usize, &progress),
    )?;
    drop(progress);
    let encode_seconds = start.elapsed().as_secs_f64();
    // The encoder's warnings (e.g. a fallback it took to stay within its bound) also go
    // to stderr, whatever the output format; `--json` lists them under "notes".
    for n in &notes {
        eprintln!("animcodec: warning: {n}");
    }
    let notes: Vec<String> = substitutions.into_iter().chain(notes).collect();

    let (v, f, t) = (topology.vertex_count(), frame_count, topology.triangle_count());
    let rate = animcodec::metrics::bpvf(bytes, v, f)?;
    let ratio = raw_bytes(v, f) as f64 / bytes as f64;
    // --eval measures the stream as written, before it replaces anything: a failed measurement
    // leaves the old output untouched and no new file.
    let evaluation = match args.eval {
        false => None,
        true => Some(evaluate_written(args, &source, file.finish()?, limits)?),
    };
    file.commit()?;
    if args.json {
        return emit_document(&EncodeDocument {
            codec: codec.name(),
            params: params_json(&params),
            input: &args.input,
            output: args.output.display().to_string(),
            bytes,
            bpvf: rate,
            ratio,
            frames: f,
            vertices: v,
            triangles: t,
            frame_rate,
            read_seconds,
            encode_seconds,
            notes,
            evaluation: evaluation.as_ref().map(|(r, s)| EvaluationFields::new(r, *s)),
        });
    }
    // A streamed input is read while it is encoded: its read time is in the encode time.
    let read = match source {
        Source::Cache(_) => "read frame by frame while encoding".to_owned(),
        _ => format!("read in {read_seconds:.2} s"),
    };
    let mut text = format!(
        "{input}: {f} frames × {v} vertices, {t} triangles, {fps} fps ({read})\n\
         {codec} [{params}] → {out}\n\
         {bytes} bytes, {rate:.3} bits/vertex/frame, {ratio:.1}:1 vs raw f32, encoded in {encode_seconds:.2} s\n",
        input = args.input,
        fps = frame_rate,
        codec = codec.name(),
        out = args.output.display(),
    );
    for n in &notes {
        text.push_str(&format!("warning: {n}\n"));
    }
    if let Some((r, seconds)) = &evaluation {
        let num = |x: Option<f64>| x.map_or_else(|| "n/a".to_string(), |x| format!("{x:.4e}"));
        text.push_str(&format!(
            "decoded vs input: KG {} %, STED {} (spatial {}, temporal {}), Hausdorff {}, RMSE {:.4e}, \
             max error {:.4e} (measured in {seconds:.2} s)\n",
            num(r.kg),
            num(r.sted),
            num(r.sted_spatial),
            num(r.sted_temporal),
            num(r.hausdorff),
            r.rmse,
            r.max_error,
        ));
        text.push_str(&worst_part_line(r));
        for n in &r.notes {
            text.push_str(&format!("note: {n}\n"));
        }
    }
    emit(&text)
}

/// The notes of an encode with fixed parameters that does other than the user asked: a
/// streamed `synth:flag:COLSxROWSxFRAMES` without `-p` keeps the codec's defaults instead of
/// the default-quality search (which needs the whole animation), and `--memory` changes the
/// parameters `fit_memory` adapts to the budget (the blocks of hosvd and pca-aoi).
fn substitutions(
    args: &EncodeArgs,
    streamed: bool,
    codec: &dyn AnimationCodec,
    asked: &ParamSet,
    used: &ParamSet,
) -> Vec<String> {
    let mut notes = Vec::new();
    let ladder = codec.rate_ladder(used);
    if streamed && args.params.is_empty() && args.target.is_none() {
        notes.push(format!(
            "{input} is generated frame by frame and never held, so the default-quality search \
             ({target}: it decodes and compares whole animations) does not run: {codec} encodes at its default \
             parameters ({knob}), whose error is not measured; choose them with -p KEY=VALUE, or write the flag \
             to a file (animcodec synth) to search it",
            input = args.input,
            target = harness::DEFAULT_TARGET,
            codec = codec.name(),
            knob = used.get(ladder.param).map_or_else(|| ladder.param.to_owned(), |v| format!("{}={v}", ladder.param)),
        ));
    }
    let given = |name: &str| args.params.iter().any(|p| p.split_once('=').is_some_and(|(k, _)| k.trim() == name));
    for (name, value) in used.iter() {
        let before = asked.get(name);
        if before != Some(value) {
            let before = before.map_or_else(|| "unset".to_owned(), |v| format!("{name}={v}"));
            notes.push(format!(
                "--memory {budget}: {codec} encodes with {name}={value} instead of {before} ({whose}) to stay within \
                 the budget",
                budget = args.memory.map_or_else(String::new, |b| format!("{} MiB", b >> 20)),
                codec = codec.name(),
                whose = if given(name) { "given with -p" } else { "its default" },
            ));
        }
    }
    notes
}

/// `--eval`: decodes the stream just written (from its file `written`, as any user would) and
/// measures it against the input; returns the report and the seconds it took. An input held
/// whole is compared with the whole decoded animation; one read frame by frame (a cache, an
/// OBJ sequence, a generated flag) is read again frame by frame and compared with the stream
/// as it decodes packet by packet ([`harness::measure_stream`]): the same report, in the
/// memory of the metrics' window, one packet and a chunk of frames, checked against --memory.
fn evaluate_written(
    args: &EncodeArgs,
    source: &Source,
    written: &std::path::Path,
    limits: Limits,
) -> CmdResult<(MetricReport, f64)> {
    let start = Instant::now();
    let registry = animcodec::registry();
    let options = args.sted.metric_options().eval_options()?;
    let comparing = || format!("comparing {} with its decoded stream {}", args.input, args.output.display());
    if let Source::Whole(input) = source {
        let decoded = StreamDecoder::new(super::decode::open(written)?, &registry, limits)
            .and_then(|d| d.decode_all())
            .context(|| format!("decoding {} to measure it", args.output.display()))?;
        let report = animcodec::metrics::evaluate(input, &decoded, &options).context(comparing)?;
        return Ok((report, start.elapsed().as_secs_f64()));
    }
    let topology = source.topology();
    let (frame_count, frame_rate) = source.frames_and_rate(args.fps);
    let limits = streamed_eval_limits(&args.input, &topology, &options, args.memory, limits)?;
    let stream = super::decode::open(written)?;
    let report = match source {
        Source::Cache(_) => {
            let path = std::path::Path::new(&args.input);
            let mut reader = CacheReader::open(path, &args.read.options(args.fps))?;
            let mut read = |n: usize, out: &mut Vec<f32>| reader.read_frames(n, out);
            let reference = harness::FrameSource { topology: &topology, frame_count, frame_rate, read: &mut read };
            harness::measure_stream(&registry, stream, reference, &options, limits)
        }
        Source::Flag { cols, rows, frames } => {
            let (cols, rows, frames) = (*cols, *rows, *frames);
            let (mut next, mut frame) = (0, Vec::new());
            let mut read = |n: usize, out: &mut Vec<f32>| {
                out.clear();
                let n = n.min(frames - next);
                for t in next..next + n {
                    synth::flag_frame(cols, rows, t, frames, &mut frame);
                    out.extend_from_slice(&frame);
                }
                next += n;
                Ok(n)
            };
            let reference = harness::FrameSource { topology: &topology, frame_count, frame_rate, read: &mut read };
            harness::measure_stream(&registry, stream, reference, &options, limits)
        }
        Source::Whole(_) => unreachable!("measured in memory above"),
    };
    Ok((report.context(comparing)?, start.elapsed().as_secs_f64()))
}

/// The limits of `--eval`'s streamed measurement: the decode keeps `limits`; with `--memory`,
/// the metrics' window and frames ([`harness::measure_bytes_held`]) must fit in it, and the
/// decode gets what is left (the encoder has finished and freed its memory by then).
fn streamed_eval_limits(
    input: &str,
    topology: &Topology,
    options: &EvalOptions,
    memory: Option<u64>,
    limits: Limits,
) -> CmdResult<Limits> {
    let Some(budget) = memory else { return Ok(limits) };
    let held = harness::measure_bytes_held(topology, options);
    let Some(left) = budget.checked_sub(held) else {
        return Err(format!(
            "{input}: --eval measures frame by frame holding up to {} MiB for {} vertices (the metrics' window and \
             two chunks of frames), more than --memory {} MiB; raise --memory, or leave out --eval",
            held >> 20,
            topology.vertex_count(),
            budget >> 20
        )
        .into());
    };
    Ok(Limits { max_alloc_bytes: limits.max_alloc_bytes.min(usize::try_from(left).unwrap_or(usize::MAX)), ..limits })
}

/// Where the frames come from: a loaded animation, a PC2/MDD cache or an OBJ sequence read frame
/// by frame, or a synthetic flag generated one frame at a time (so sequences far larger than
/// memory can be encoded).
enum Source {
    Whole(Animation),
    Cache(CacheReader),
    Flag { cols: usize, rows: usize, frames: usize },
}

impl Source {
    /// What the input said about its scene (up axis, units, time line); the stream keeps it.
    /// The streamed caches (PC2, MDD) and synthetic inputs say nothing.
    fn metadata(&self) -> animcodec::core::SceneMetadata {
        match self {
            Source::Whole(a) => *a.metadata(),
            Source::Cache(_) | Source::Flag { .. } => animcodec::core::SceneMetadata::default(),
        }
    }

    fn topology(&self) -> Topology {
        match self {
            Source::Whole(a) => a.topology().clone(),
            Source::Cache(c) => c.topology().clone(),
            Source::Flag { cols, rows, .. } => synth::flag_topology(*cols, *rows),
        }
    }

    fn frames_and_rate(&self, fps: Option<f32>) -> (usize, f32) {
        match self {
            Source::Whole(a) => (a.frame_count(), a.frame_rate()),
            Source::Cache(c) => (c.frame_count(), c.frame_rate()),
            Source::Flag { frames, .. } => (*frames, fps.unwrap_or(synth::FRAME_RATE)),
        }
    }
}

/// Bytes a streamed `synth:flag:COLSxROWSxFRAMES` encode holds per vertex of the flag, whatever
/// its frame count: the mesh (its triangles, and their connectivity coding for the container
/// header) is held while only the frames are generated one at a time. Measured (peak RSS of
/// `encode synth:flag:CxRx2 -c quant-delta -p bits=8`): 126 MB at 500×500, 420 MB at
/// 1000×1000, 3.7 GB at 3000×3000.
const FLAG_MESH_BYTES_PER_VERTEX: u64 = 420;

/// Refuses a streamed flag whose mesh alone needs more than `--memory`: streaming holds the
/// frames one at a time but the mesh whole (`synth:flag:3000x3000x2` needs 3.7 GB).
fn check_flag_memory(input: &str, cols: usize, rows: usize, memory: Option<u64>) -> CmdResult {
    let vertices = cols as u64 * rows as u64;
    let need = vertices.saturating_mul(FLAG_MESH_BYTES_PER_VERTEX);
    match memory {
        Some(budget) if need > budget => Err(format!(
            "{input}: its mesh alone holds about {} MiB ({vertices} vertices × {FLAG_MESH_BYTES_PER_VERTEX} bytes: \
             the triangles and their connectivity coding; only the frames are generated one at a time), more than \
             --memory {} MiB",
            need >> 20,
            budget >> 20
        )
        .into()),
        _ => Ok(()),
    }
}

/// The outputs `encode` may write: not the input (nor its topology), existing ones only with
/// `--force`.
fn output_policy(args: &EncodeArgs) -> OutputPolicy {
    let mut policy = OutputPolicy::new(args.force);
    if !args.input.starts_with("synth:") {
        policy = policy.with_input(&args.input);
    }
    if let Some(t) = &args.read.topology {
        policy = policy.with_input(t);
    }
    policy
}

/// Encodes `source` into `file`, feeding `feed` frames per call and counting them on
/// `progress` (with the bytes written so far); returns the file (complete, not yet
/// committed), the container size in bytes and the encoder's warnings
/// ([`animcodec::core::FrameEncoder::notes`]).
fn encode_to_file(
    codec: &dyn AnimationCodec,
    params: &ParamSet,
    source: &mut Source,
    (topology, frame_count, frame_rate): (&Topology, usize, f32),
    file: PendingFile,
    (feed, progress): (usize, &Progress),
) -> CmdResult<(PendingFile, u64, Vec<String>)> {
    let written = std::sync::Arc::new(std::sync::atomic::AtomicU64::new(0));
    let mut encoder = StreamEncoder::with_metadata(
        codec,
        params,
        topology,
        frame_count,
        frame_rate,
        false,
        &source.metadata(),
        CountingWriter { inner: file, count: 0, shared: written.clone() },
    )?;
    let per_frame = topology.vertex_count() * 3;
    let pushed = |encoder: &mut StreamEncoder<_>, block: &[f32]| -> CmdResult {
        encoder.push_frames(block)?;
        progress.inc((block.len() / per_frame.max(1)) as u64);
        progress
            .message(format!("{} written", progress::bytes_text(written.load(std::sync::atomic::Ordering::Relaxed))));
        Ok(())
    };
    match source {
        Source::Whole(animation) => {
            for block in animation.positions().chunks(feed.max(1) * per_frame) {
                pushed(&mut encoder, block)?;
            }
        }
        Source::Cache(reader) => {
            let mut block = Vec::new();
            while reader.read_frames(feed.max(1), &mut block)? > 0 {
                pushed(&mut encoder, &block)?;
            }
        }
        Source::Flag { cols, rows, frames } => {
            let mut block = Vec::with_capacity(feed.max(1) * per_frame);
            let mut frame = Vec::with_capacity(per_frame);
            for t in 0..*frames {
                synth::flag_frame(*cols, *rows, t, *frames, &mut frame);
                block.extend_from_slice(&frame);
                if block.len() == feed.max(1) * per_frame || t + 1 == *frames {
                    pushed(&mut encoder, &block)?;
                    block.clear();
                }
            }
        }
    }
    progress.message("finishing the stream");
    let (_, sink, notes) = encoder.finish_with_notes()?;
    progress.message(format!("{} written", progress::bytes_text(sink.count)));
    progress.finish();
    Ok((sink.inner, sink.count, notes))
}

/// Counts the bytes written through it (also in `shared`, for the progress display while the
/// encoder owns the writer).
struct CountingWriter<W: Write> {
    inner: W,
    count: u64,
    shared: std::sync::Arc<std::sync::atomic::AtomicU64>,
}

impl<W: Write> Write for CountingWriter<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.count += n as u64;
        self.shared.store(self.count, std::sync::atomic::Ordering::Relaxed);
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

/// What a search reads: the whole animation, or a source read frame by frame.
enum SearchSource {
    Whole(Animation),
    Streamed(Box<dyn InputSource>),
}

/// A search's input and its memory budget, and the note saying why it streams.
struct PreparedInput {
    input: SearchSource,
    budget: Option<u64>,
    note: Option<String>,
}

/// Reads (or opens) a search's input under the memory budget: `--memory`, else
/// [`front::default_memory_budget`]. An input that can be read frame by frame (PC2, MDD, an
/// OBJ sequence, `synth:flag:COLSxROWSxFRAMES`) is searched whole while the whole-array search
/// fits the budget by [`harness::whole_search_need`] (the largest over `codecs`), and streamed
/// beyond it, with a note saying so. Any other input is read whole; beyond an explicit
/// `--memory` it is refused.
fn prepare_search_input(args: &EncodeArgs, codecs: &[&dyn AnimationCodec], limits: Limits) -> CmdResult<PreparedInput> {
    let (budget, given) = match args.memory {
        Some(m) => (Some(m), true),
        None => (front::default_memory_budget(), false),
    };
    let options = args.read.options(args.fps);
    let need = |v: usize, f: usize| codecs.iter().map(|c| harness::whole_search_need(*c, v, f)).max().unwrap_or(0);
    let path = std::path::Path::new(&args.input);
    let source: Option<Box<dyn InputSource>> = match front::streamed_flag(&args.input)? {
        Some((cols, rows, frames)) => {
            check_flag_memory(&args.input, cols, rows, args.memory)?;
            Some(Box::new(FlagSource::new(&args.input, cols, rows, frames, args.fps)))
        }
        None if cache_stream::is_streamable(path) => Some(Box::new(CacheSource::open(path, &options)?)),
        None => None,
    };
    let Some(source) = source else {
        let animation = load(&args.input, &options, limits, Streams::Refuse)?.animation;
        let whole = need(animation.vertex_count(), animation.frame_count());
        if let (Some(b), true) = (budget, given) {
            if whole > b {
                return Err(format!(
                    "{}: a search over this input holds it whole (only .pc2/.mdd caches, OBJ sequences and \
                     synth:flag:COLSxROWSxFRAMES are read frame by frame), about {} MiB, more than --memory {} MiB; \
                     convert it to a PC2 cache (animcodec export) or give a larger --memory",
                    args.input,
                    whole >> 20,
                    b >> 20
                )
                .into());
            }
        }
        return Ok(PreparedInput { input: SearchSource::Whole(animation), budget, note: None });
    };
    let (v, f) = (source.topology().vertex_count(), source.frame_count());
    let whole = need(v, f);
    match budget {
        Some(b) if whole > b => {
            let whose = if given {
                format!("--memory {} MiB", b >> 20)
            } else {
                format!(
                    "the default memory budget, {} MiB ({} of this machine's RAM; --memory sets it, and the \
                     codec's blocks may depend on it)",
                    b >> 20,
                    if front::DEFAULT_MEMORY_SHARE == (1, 2) {
                        "half".to_owned()
                    } else {
                        format!("{:?}", front::DEFAULT_MEMORY_SHARE)
                    }
                )
            };
            let note = format!(
                "a search over the whole of {} would hold about {} MiB, more than {whose}: it streams instead \
                 (each candidate is encoded from the input as it is read and measured against a second read)",
                args.input,
                whole >> 20
            );
            Ok(PreparedInput { input: SearchSource::Streamed(source), budget, note: Some(note) })
        }
        _ => {
            drop(source);
            let animation = load(&args.input, &options, limits, Streams::Refuse)?.animation;
            Ok(PreparedInput { input: SearchSource::Whole(animation), budget, note: None })
        }
    }
}

/// `synth:flag:COLSxROWSxFRAMES` as a [`InputSource`]: its frames generated one at a time for
/// every read, its mesh held.
struct FlagSource {
    name: String,
    cols: usize,
    rows: usize,
    frames: usize,
    frame_rate: f32,
    topology: Topology,
}

impl FlagSource {
    fn new(name: &str, cols: usize, rows: usize, frames: usize, fps: Option<f32>) -> Self {
        let topology = synth::flag_topology(cols, rows);
        Self { name: name.to_owned(), cols, rows, frames, frame_rate: fps.unwrap_or(synth::FRAME_RATE), topology }
    }
}

/// A read of a [`FlagSource`]: the next frame to generate.
struct FlagReader<'a> {
    flag: &'a FlagSource,
    next: usize,
    frame: Vec<f32>,
}

impl FrameRead for FlagReader<'_> {
    fn read_frames(&mut self, frames: usize, out: &mut Vec<f32>) -> animcodec::core::Result<usize> {
        out.clear();
        let n = frames.min(self.flag.frames - self.next);
        for t in self.next..self.next + n {
            synth::flag_frame(self.flag.cols, self.flag.rows, t, self.flag.frames, &mut self.frame);
            out.extend_from_slice(&self.frame);
        }
        self.next += n;
        Ok(n)
    }
}

impl InputSource for FlagSource {
    fn topology(&self) -> &Topology {
        &self.topology
    }
    fn frame_count(&self) -> usize {
        self.frames
    }
    fn frame_rate(&self) -> f32 {
        self.frame_rate
    }
    fn open(&self) -> harness::Result<Box<dyn FrameRead + '_>> {
        Ok(Box::new(FlagReader { flag: self, next: 0, frame: Vec::new() }))
    }
    fn name(&self) -> String {
        self.name.clone()
    }
}

/// `encode --target` (or the default quality target, `by_default`): searches the codec's
/// declared parameter space (see [`harness::search_space_target`]; with `--ladder` its rate
/// ladder alone, [`harness::search_target`]) and writes the smallest stream that meets the
/// target. Parameters given with `-p` stay fixed and are not searched.
fn run_target(args: &EncodeArgs, target: Target, by_default: bool, limits: Limits, policy: &OutputPolicy) -> CmdResult {
    let registry = animcodec::registry();
    let auto = args.codec == "auto";
    let chosen: Option<(&dyn AnimationCodec, ParamSet)> = if auto {
        if !args.params.is_empty() {
            return Err("-p cannot be combined with -c auto: parameters belong to one codec".into());
        }
        None
    } else {
        let codec = registry.by_name(&args.codec)?;
        let params = front::params_from_text(codec, &args.params)?;
        let ladder = codec.rate_ladder(&params);
        if let Some(p) = args.params.iter().find(|p| p.split_once('=').is_some_and(|(k, _)| k.trim() == ladder.param)) {
            return Err(format!(
                "{}: '-p {p}' sets the rate ladder's parameter, which --target {target} chooses; leave it out",
                codec.name()
            )
            .into());
        }
        Some((codec, params))
    };
    // --eval's metrics: every one, with the STED options given. With --eval the search measures
    // every candidate with them, so the chosen stream's report is its evaluation (encoded and
    // decoded once); without, only the target's metrics.
    let measured = args.sted.metric_options().eval_options()?;
    let eval = if args.eval { measured } else { EvalOptions { sted: measured.sted, ..EvalOptions::default() } };
    policy.check(&args.output)?;
    animcodec::output::folder_exists(&args.output)?;

    let read_start = Instant::now();
    let registry_codecs: Vec<&dyn AnimationCodec> = registry.iter().collect();
    let searched: Vec<&dyn AnimationCodec> = match &chosen {
        Some((codec, _)) => vec![*codec],
        None => registry_codecs.clone(),
    };
    // The whole animation in memory while the search fits the memory budget; beyond it (and
    // for an input read frame by frame) the streamed search.
    let prepared = prepare_search_input(args, &searched, limits)?;
    // The files the read opened (a .gltf's buffers, …) are inputs too: refused before the work.
    policy.check(&args.output)?;
    let read_seconds = read_start.elapsed().as_secs_f64();
    let streamed_input = match &prepared.input {
        SearchSource::Streamed(source) => Some(StreamedInput::new(
            source.as_ref(),
            prepared.budget.expect("a streamed search has a budget"),
            args.feed as usize,
            &eval,
        )?),
        SearchSource::Whole(_) => None,
    };
    let mut notes: Vec<String> = prepared.note.iter().cloned().collect();
    // On a streamed input, a codec whose encoder holds the whole input cannot stream: refused
    // (a named codec) or left out (-c auto), naming the budget.
    let mut every_codec: Vec<&dyn AnimationCodec> = registry_codecs.clone();
    if let Some(streamed) = &streamed_input {
        let (v, f) = (streamed.source().topology().vertex_count(), streamed.source().frame_count());
        let refusal = |codec: &dyn AnimationCodec, params: &ParamSet| -> Option<String> {
            codec.fit_memory(params, v, f, streamed.work_budget()).err().map(|e| {
                format!(
                    "{}: its encoder cannot stream {} within --memory {} MiB (the streamed search gives the codec \
                     {} MiB, three quarters of the budget; a quarter is kept for candidate streams): {e}",
                    codec.name(),
                    args.input,
                    streamed.budget() >> 20,
                    streamed.work_budget() >> 20,
                )
            })
        };
        match &chosen {
            Some((codec, params)) => {
                if let Some(why) = refusal(*codec, params) {
                    return Err(why.into());
                }
            }
            None => every_codec.retain(|codec| match refusal(*codec, &codec.default_params()) {
                Some(why) => {
                    eprintln!("animcodec: left out of -c auto: {why}");
                    notes.push(format!("left out of -c auto: {why}"));
                    false
                }
                None => true,
            }),
        }
    }
    // Said once the search is sure to run (a refusal above is the one message).
    for n in prepared.note.iter() {
        eprintln!("animcodec: {n}");
    }

    let start = Instant::now();
    let fixed: Vec<&str> = args.params.iter().filter_map(|p| p.split_once('=').map(|(k, _)| k.trim())).collect();
    // Each point is a full encode + decode + evaluation (minutes in all on real data): on a
    // terminal, the points measured of those expected, and the latest point.
    let bar = search_progress(&registry, &chosen, &fixed, target, (by_default, args.ladder), args.refine, args.json);
    let progress = |p: &harness::Point| {
        bar.inc(1);
        let knob = p.ladder_value().map_or_else(String::new, |v| format!("{}={v} ", p.ladder_param));
        bar.message(format!("last: {} {knob}→ {} at {:.3} bpvf", p.codec, target.reached_text(&p.report, 4), p.bpvf));
    };
    let input = match (&prepared.input, &streamed_input) {
        (_, Some(streamed)) => harness::SearchInput::Streamed(streamed),
        (SearchSource::Whole(animation), None) => harness::SearchInput::Whole(animation),
        (SearchSource::Streamed(_), None) => unreachable!("a streamed source has its streamed input"),
    };
    let request = SearchRequest {
        eval,
        limits,
        refine: args.refine as usize,
        progress: &progress,
        measure_every_metric: args.eval,
        ..SearchRequest::on(&registry, input, target)
    };
    let found = match (chosen, args.ladder) {
        (Some((codec, _)), false) if by_default => {
            harness::search_default_quality(&request, codec).map(|hit| (hit, Vec::new()))
        }
        (Some((codec, params)), true) => harness::search_target(&request, codec, &params).map(|hit| (hit, Vec::new())),
        (Some((codec, params)), false) => {
            harness::search_space_target(&request, codec, &params, &fixed).map(|hit| (hit, Vec::new()))
        }
        (None, true) => harness::search_target_auto(&request, &every_codec),
        (None, false) => harness::search_space_target_auto(&request, &every_codec),
    };
    bar.finish();
    // Every point measured, over every codec searched (the chosen codec's are `hit.tried`).
    let measured_points = bar.done();
    drop(bar);
    let (hit, others) = found?;
    let search_seconds = start.elapsed().as_secs_f64();
    // The chosen encode's warnings, as a plain encode prints them (stderr, `--json` "notes").
    let mut warnings: Vec<String> =
        hit.point.report.notes.iter().filter_map(|n| n.strip_prefix("encoder: ")).map(str::to_owned).collect();
    warnings.extend(sted_motion_note(target, &hit.point));
    for n in &warnings {
        eprintln!("animcodec: warning: {n}");
    }
    notes.extend(warnings);
    if hit.stream.is_empty() {
        return Err("internal error: the search chose a stream it did not keep".into());
    }
    // Written under a temporary name and measured (--eval) before it replaces anything.
    let mut file = policy.create(&args.output)?;
    file.write_all(&hit.stream).map_err(|e| file.error(e))?;
    let p = &hit.point;
    // --eval: the search measured this very stream; its report is reused (the stream is not
    // decoded again unless the search skipped a metric --eval reports).
    let evaluation = if args.eval {
        file.finish()?;
        Some(match &input {
            harness::SearchInput::Whole(animation) => {
                front::evaluation_of(&registry, &hit, animation, &measured, limits)?
            }
            harness::SearchInput::Streamed(streamed) => match front::search_evaluation(&hit, &measured) {
                Some(found) => found,
                None => {
                    let start = Instant::now();
                    let (report, _) =
                        harness::measure_stream_against(&registry, &hit.stream, streamed.source(), &measured, limits)?;
                    (report, start.elapsed().as_secs_f64())
                }
            },
        })
    } else {
        None
    };
    file.commit()?;
    let (v, f) = (input.vertex_count(), input.frame_count());
    let (triangles, frame_rate) = match &prepared.input {
        SearchSource::Whole(a) => (a.topology().triangle_count(), a.frame_rate()),
        SearchSource::Streamed(source) => (source.topology().triangle_count(), source.frame_rate()),
    };
    if args.json {
        return emit_document(&TargetEncodeDocument {
            summary: TargetSummary::new(target, &hit, &others),
            input: &args.input,
            output: args.output.display().to_string(),
            default_target: by_default,
            search: if args.ladder { "ladder" } else { "space" },
            notes,
            search_input: if streamed_input.is_some() { "streamed" } else { "whole" },
            memory_budget: prepared.budget,
            memory_budget_default: args.memory.is_none() && prepared.budget.is_some(),
            ratio: raw_bytes(v, f) as f64 / p.bytes as f64,
            frames: f,
            vertices: v,
            triangles,
            frame_rate,
            read_seconds,
            search_seconds,
            encode_seconds: p.encode_seconds,
            evaluation: evaluation.as_ref().map(|(r, s)| EvaluationFields::new(r, *s)),
        });
    }
    let mut out = format!(
        "{input}: {f} frames × {v} vertices ({read})\n\
         target {target}{default}: {codec} [{params}] reaches {reached} → {output}\n\
         {parts}{bytes} bytes, {rate:.3} bits/vertex/frame; searched {n} in {search_seconds:.2} s{fallback}\n",
        input = args.input,
        read = if streamed_input.is_some() {
            "streamed: read twice per candidate".to_owned()
        } else {
            format!("read in {read_seconds:.2} s")
        },
        default = if by_default { " (the default quality; -p or --target for other choices)" } else { "" },
        codec = p.codec,
        params = p.params,
        reached = target.reached_text(&p.report, 6),
        output = args.output.display(),
        bytes = p.bytes,
        rate = p.bpvf,
        n = match measured_points as usize {
            n if n > hit.tried.len() => format!("{n} points ({} for {})", hit.tried.len(), p.codec),
            _ => format!("{} points", hit.tried.len()),
        },
        // A KG bound holds for every part; say which figure it was.
        parts = match (&p.report.worst_part, target.bound(TargetMetric::Kg)) {
            (Some(w), Some(_)) if p.report.parts > 1 => format!(
                "kg is the larger of the whole animation's ({}) and the worst of its {} parts' (part {}, {} vertices: {})\n",
                p.report.kg.map_or_else(|| "n/a".to_string(), |x| format!("{x:.6}")),
                p.report.parts,
                w.part,
                w.vertices,
                w.kg.map_or_else(|| "n/a".to_string(), |x| format!("{x:.6}")),
            ),
            _ => String::new(),
        },
        fallback = if hit.linear_fallback { " (errors not monotone along the ladder: linear scan used)" } else { "" },
    );
    for r in &hit.rejected {
        out.push_str(&format!("  rejected candidate: {r}\n"));
    }
    if let Some((r, seconds)) = &evaluation {
        let num = |x: Option<f64>| x.map_or_else(|| "n/a".to_string(), |x| format!("{x:.4e}"));
        out.push_str(&format!(
            "decoded vs input: KG {} %, STED {}, Hausdorff {}, RMSE {:.4e}, max error {:.4e} (measured in {seconds:.2} s)\n",
            num(r.kg),
            num(r.sted),
            num(r.hausdorff),
            r.rmse,
            r.max_error,
        ));
        out.push_str(&worst_part_line(r));
    }
    for o in &others {
        out.push_str(&format!(
            "  also meets it: {} [{}] {} bytes, {:.3} bpvf\n",
            o.point.codec, o.point.params, o.point.bytes, o.point.bpvf
        ));
    }
    emit(&out)
}

/// The progress display of a target search: the points expected of the search `encode` runs
/// (`by_default`: the default quality; `ladder`: `--ladder`), over every codec for `-c auto`
/// (`chosen` is `None`).
fn search_progress(
    registry: &animcodec::core::CodecRegistry,
    chosen: &Option<(&dyn AnimationCodec, ParamSet)>,
    fixed: &[&str],
    target: Target,
    (by_default, ladder): (bool, bool),
    refine: u32,
    json: bool,
) -> Progress {
    let search = match (by_default, ladder) {
        (_, true) => progress::Search::Ladder,
        (true, false) if chosen.is_some() => progress::Search::DefaultQuality,
        _ => progress::Search::Space,
    };
    let expect = |codec: &dyn AnimationCodec, base: &ParamSet, fixed: &[&str]| {
        progress::expected_search_points(codec, base, fixed, target, search, refine as usize)
    };
    let expected = match chosen {
        Some((codec, params)) => expect(*codec, params, fixed),
        None => registry.iter().map(|c| expect(c, &c.default_params(), &[])).sum(),
    };
    let bar = Progress::estimate("encode", expected, "points", json);
    bar.message(format!("searching for {target}"));
    bar
}

/// `--eval`'s line on the worst part: its KG against its own spread, beside the global figures
/// (a large static part must not hide a destroyed small one); empty for a mesh of one part (its
/// KG is the global one) or without triangles.
pub fn worst_part_line(r: &MetricReport) -> String {
    match &r.worst_part {
        Some(w) if r.parts > 1 => format!(
            "worst part: KG {} % of its own spread (part {} of {}: {} vertices from vertex {}), RMSE {:.4e}, max error {:.4e}\n",
            w.kg.map_or_else(|| "n/a".to_string(), |x| format!("{x:.4e}")),
            w.part,
            r.parts,
            w.vertices,
            w.first_vertex,
            w.rmse,
            w.max_error
        ),
        _ => String::new(),
    }
}

/// KG (%) above which a stream chosen for a STED target gets a note: it keeps the shape but
/// visibly not the motion.
const STED_MOTION_NOTE_KG: f64 = 5.0;

/// The note for a STED target met by a stream that does not follow the motion: STED (the
/// metric author's tool) weighs its temporal part by about 1e-4, so a shape moved rigidly — or
/// even frame 0 repeated — can meet it (samba at STED ≤ 0.1 is met by hosvd's
/// `(v, f) = (3, 1)` model at KG 19).
fn sted_motion_note(target: Target, point: &harness::Point) -> Option<String> {
    let kg = point.report.kg?;
    let sted = target.bound(TargetMetric::Sted).filter(|_| target.bound(TargetMetric::Kg).is_none())?;
    (kg > STED_MOTION_NOTE_KG).then(|| {
        format!(
            "the stream meets STED <= {} at KG {kg:.1} %: STED sees edge lengths, hardly motion, so this stream \
             keeps the shape but not all of the motion; use --target kg=... (or both checks, --eval) when the motion \
             matters",
            sted
        )
    })
}
