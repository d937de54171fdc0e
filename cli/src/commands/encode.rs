//! `animcodec encode`: animation file → `.anim` container, streamed to disk.

use std::io::Write;
use std::time::Instant;

use animcodec::core::{Animation, AnimationCodec, Limits, ParamSet, StreamDecoder, StreamEncoder, Topology};
use animcodec::formats::stream::{self as cache_stream, CacheReader};
use animcodec::front::{self, EvaluationFields, Streams, TargetSummary};
use animcodec::harness::{self, SearchRequest, Target, TargetMetric};
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

    /// Memory budget of an encode with -p (bytes; K, M, G suffixes are powers of 1024), e.g.
    /// 4G. A .pc2/.mdd input, an OBJ sequence (or synth:flag:CxRxF) is read frame by frame, so the encode holds
    /// the mesh and what the codec buffers; a codec whose analysis holds a whole block of frames (hosvd with
    /// block=0) chooses temporal blocks that fit the budget. The stream depends on the budget,
    /// never on the machine. Default: none (hosvd decomposes the whole sequence at once).
    /// Not with --target or the default-quality search, which hold the whole animation.
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
    /// full report under `metrics`).
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

/// Why `--eval` refuses a streamed flag (checked before encoding starts).
const EVAL_NEEDS_MEMORY: &str = "--eval needs the input in memory, but synth:flag:COLSxROWSxFRAMES is generated \
                                 frame by frame; write it to a file first (animcodec synth) or drop --eval";

/// Runs `encode`.
pub fn run(args: &EncodeArgs, limits: Limits) -> CmdResult {
    // Mistyped arguments first, then the output, all before anything long happens.
    let streamed = front::streamed_flag(&args.input)?.is_some();
    if args.eval {
        args.sted.metric_options().sted_params()?;
        if streamed && args.target.is_none() {
            return Err(EVAL_NEEDS_MEMORY.into());
        }
    }
    let policy = output_policy(args);
    if args.memory.is_some() && (args.target.is_some() || args.params.is_empty()) {
        return Err("--memory bounds an encode with fixed parameters (-p KEY=VALUE): --target and the \
                    default-quality search (no -p) decode and compare whole animations, so they hold the \
                    whole input in memory"
            .into());
    }
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
            // (inputs may be larger than memory), unless --eval needs the whole input in memory
            // to measure it.
            let path = std::path::Path::new(&args.input);
            if !args.eval && cache_stream::is_streamable(path) {
                Source::Cache(CacheReader::open(path, &options)?)
            } else {
                Source::Whole(load(&args.input, &options, limits, Streams::Refuse)?.animation)
            }
        }
    };
    let topology = source.topology();
    let (frame_count, frame_rate) = source.frames_and_rate(args.fps);
    let read_seconds = read_start.elapsed().as_secs_f64();
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
    let evaluation = match (&source, args.eval) {
        (_, false) => None,
        (Source::Whole(input), true) => Some(evaluate_written(args, input, file.finish()?, limits)?),
        (Source::Flag { .. } | Source::Cache(_), true) => return Err(EVAL_NEEDS_MEMORY.into()),
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
/// measures it against the input; returns the report and the seconds it took.
fn evaluate_written(
    args: &EncodeArgs,
    input: &Animation,
    written: &std::path::Path,
    limits: Limits,
) -> CmdResult<(MetricReport, f64)> {
    let start = Instant::now();
    let registry = animcodec::registry();
    let decoded = StreamDecoder::new(super::decode::open(written)?, &registry, limits)
        .and_then(|d| d.decode_all())
        .context(|| format!("decoding {} to measure it", args.output.display()))?;
    let options = args.sted.metric_options().eval_options()?;
    let report = animcodec::metrics::evaluate(input, &decoded, &options)
        .context(|| format!("comparing {} with its decoded stream {}", args.input, args.output.display()))?;
    Ok((report, start.elapsed().as_secs_f64()))
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
    // The search decodes and compares whole animations, so a synth:flag:COLSxROWSxFRAMES is
    // built in memory (within the memory limit).
    let options = args.read.options(args.fps);
    let animation = load(&args.input, &options, limits, Streams::Refuse)?.animation;
    // The files the read opened (a .gltf's buffers, …) are inputs too: refused before the work.
    policy.check(&args.output)?;
    let read_seconds = read_start.elapsed().as_secs_f64();

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
    let request = SearchRequest {
        eval,
        limits,
        refine: args.refine as usize,
        progress: &progress,
        measure_every_metric: args.eval,
        ..SearchRequest::new(&registry, &animation, target)
    };
    let every_codec: Vec<&dyn AnimationCodec> = registry.iter().collect();
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
    let mut notes: Vec<String> =
        hit.point.report.notes.iter().filter_map(|n| n.strip_prefix("encoder: ")).map(str::to_owned).collect();
    notes.extend(sted_motion_note(target, &hit.point));
    for n in &notes {
        eprintln!("animcodec: warning: {n}");
    }
    // Written under a temporary name and measured (--eval) before it replaces anything.
    let mut file = policy.create(&args.output)?;
    file.write_all(&hit.stream).map_err(|e| file.error(e))?;
    let p = &hit.point;
    // --eval: the search measured this very stream; its report is reused (the stream is not
    // decoded again unless the search skipped a metric --eval reports).
    let evaluation = if args.eval {
        file.finish()?;
        Some(front::evaluation_of(&registry, &hit, &animation, &measured, limits)?)
    } else {
        None
    };
    file.commit()?;
    let (v, f) = (animation.vertex_count(), animation.frame_count());
    if args.json {
        return emit_document(&TargetEncodeDocument {
            summary: TargetSummary::new(target, &hit, &others),
            input: &args.input,
            output: args.output.display().to_string(),
            default_target: by_default,
            search: if args.ladder { "ladder" } else { "space" },
            notes,
            ratio: raw_bytes(v, f) as f64 / p.bytes as f64,
            frames: f,
            vertices: v,
            triangles: animation.topology().triangle_count(),
            frame_rate: animation.frame_rate(),
            read_seconds,
            search_seconds,
            encode_seconds: p.encode_seconds,
            evaluation: evaluation.as_ref().map(|(r, s)| EvaluationFields::new(r, *s)),
        });
    }
    let mut out = format!(
        "{input}: {f} frames × {v} vertices (read in {read_seconds:.2} s)\n\
         target {target}{default}: {codec} [{params}] reaches {reached} → {output}\n\
         {parts}{bytes} bytes, {rate:.3} bits/vertex/frame; searched {n} in {search_seconds:.2} s{fallback}\n",
        input = args.input,
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
