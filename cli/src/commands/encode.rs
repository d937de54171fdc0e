//! `animcodec encode`: animation file → `.anim` container, streamed to disk.

use std::io::Write;
use std::time::Instant;

use animcodec::core::{Animation, AnimationCodec, Limits, ParamSet, StreamDecoder, StreamEncoder, Topology};
use animcodec::formats::stream::{self as cache_stream, CacheReader};
use animcodec::front::{self, EvaluationFields, Streams, TargetSummary};
use animcodec::harness::{self, InputSource, SearchRequest, StreamedInput, Target, TargetMetric};
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

mod target;
use target::run_target;

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
    /// input while it is under 256 MiB of coordinates and that fits the budget; otherwise they
    /// stream: each candidate is encoded from the input as it is read and measured against a
    /// second read (a quarter of the budget is kept for candidate streams, or what the codec's
    /// smallest blocks leave, down to 64 MiB; the codec's blocks are fitted to the rest); a larger input streams within twice its raw size (or the least its
    /// codec's blocks allow; the codecs' memory models are upper bounds), this budget only caps it. A codec whose
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

    /// The streamed searches (no -p, --target, -c auto) on an input over 1 GiB of coordinates
    /// (--sample-above) measure their candidates on a sample of its frames (about an eighth, in
    /// windows of the codec's temporal blocks spread over the input; an input too short for
    /// such a sample, or hosvd decomposing the whole sequence at once, is not sampled), aiming
    /// 10 % below the target, then encode the
    /// chosen parameters over the whole input once and measure that stream: what is reported
    /// (and written) is the whole's. Should the whole miss the target, the search runs again
    /// aiming lower by what it missed, up to twice. With --no-sample every candidate is encoded
    /// and measured over the whole input (two full passes each).
    #[arg(long)]
    pub no_sample: bool,

    /// The size of coordinates (bytes; K, M, G suffixes) above which a streamed search samples
    /// (see --no-sample).
    #[arg(long, value_name = "BYTES", value_parser = super::parse_bytes, default_value = "1G")]
    pub sample_above: u64,

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

/// Runs `encode`.
pub fn run(args: &EncodeArgs, limits: Limits) -> CmdResult {
    // Mistyped arguments first, then the output, all before anything long happens.
    front::streamed_flag(&args.input)?;
    if args.eval {
        args.sted.metric_options().sted_params()?;
    }
    let policy = output_policy(args);
    if let Some(target) = args.target {
        return run_target(args, target, false, limits, &policy);
    }
    // Quality by default: no parameters and no target aims at the documented default quality
    // and picks the parameters for this input (a streamed flag too: a large one is searched
    // streamed, each candidate measured against the flag generated again).
    if args.params.is_empty() {
        return run_target(args, harness::DEFAULT_TARGET, true, limits, &policy);
    }
    if args.codec == "auto" {
        return Err("-c auto searches every codec for the smallest stream meeting an error target \
                    (--target METRIC=VALUE, or the default quality without -p); it takes no -p: name a codec \
                    (see `animcodec list`)"
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
    let substitutions = substitutions(args, codec, &asked, &params);
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

/// The notes of an encode with fixed parameters that does other than the user asked:
/// `--memory` changes the parameters `fit_memory` adapts to the budget (the blocks of hosvd and
/// pca-aoi, the packets of quant-delta).
fn substitutions(args: &EncodeArgs, codec: &dyn AnimationCodec, asked: &ParamSet, used: &ParamSet) -> Vec<String> {
    let mut notes = Vec::new();
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
