//! `animcodec decode`: `.anim` container → animation file.

use std::fs::File;
use std::path::Path;
use std::time::Instant;

use animcodec::core::{Limits, StreamDecoder};
use animcodec::formats::stream::{self as cache_stream, CacheWriter};
use animcodec::formats::{self, WriteOptions};
use animcodec::output::OutputPolicy;
use serde::Serialize;

use crate::progress::Progress;

use super::{emit, emit_document, CmdResult, WithContext};
use clap::Args;
use std::path::PathBuf;

/// Arguments of `animcodec decode`.
#[derive(Debug, Args)]
pub struct DecodeArgs {
    /// Input `.anim` container. Any other input (a .glb, .usda, .pc2, … not named .anim and not
    /// starting with a container's magic bytes) is converted: read as
    /// `encode` reads it with default options (the first glTF animation, the file's own frame
    /// rate) and written.
    #[arg(value_name = "IN.anim")]
    pub input: PathBuf,

    /// Output animation: .pc2, .mdd, .glb/.gltf, .usda/.usd (a USD text layer: one Mesh with
    /// time-sampled points, timeCodesPerSecond = the frame rate), .usdc (the same as binary USD),
    /// .abc (Alembic: one PolyMesh under an Xform, uniform time sampling at the frame rate), or an OBJ sequence: a directory (`DIR/frame_0000.obj`, …),
    /// a path ending in .obj with `{}` (frame number, 4+ digits) or `###` (frame number padded
    /// to the run) in the file name, or a plain `NAME.obj` (`NAME_0000.obj`, …). A sequence owns
    /// only the files of its own name pattern: exactly its prefix (`frame_`, the text before
    /// `{}`/`###`, or `NAME_`), a frame number of at least 4 digits (at least the run's length
    /// for `###`) and its suffix (`.obj`), case included. Such files already there are an error
    /// without --force; with it they are replaced, and those beyond the new frames removed. No
    /// other file is touched: a directory holding any other .obj (which reading it back would
    /// take as a frame) is refused. A .pc2/.mdd beside an existing STEM.obj of another mesh is
    /// refused (reading the cache would pair that mesh's triangles): see --topology-obj.
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,

    /// Replace existing output files (without it, an existing output is an error). An output
    /// that is also an input is refused even with it.
    #[arg(short, long)]
    pub force: bool,

    /// With a .pc2/.mdd output: also write `STEM.obj` beside it (frame 0 and the triangles), so
    /// the cache can be read back without --topology (an existing STEM.obj needs --force).
    /// Without it, an existing STEM.obj is left alone and must hold the decoded mesh (same
    /// vertex count and triangles); otherwise the output is refused.
    #[arg(long)]
    pub topology_obj: bool,

    /// Print JSON: {codec, frames, vertices, triangles, decode_seconds, …}.
    #[arg(long)]
    pub json: bool,
}

pub use animcodec::front::open_stream as open;

/// Runs `decode`.
pub fn run(args: &DecodeArgs, limits: Limits) -> CmdResult {
    let options = WriteOptions {
        policy: OutputPolicy::new(args.force).with_input(&args.input).replacing_companions(args.topology_obj),
        topology_obj: args.topology_obj,
    };
    // Refuse a forbidden output before decoding (the sequence checks run when writing).
    if !formats::obj::is_directory_target(&args.output) {
        options.policy.check(&args.output)?;
    }
    // A damaged `.anim` gets the container's error, not the readers' "unknown format".
    let named_stream = args.input.extension().is_some_and(|e| e.eq_ignore_ascii_case("anim"));
    if !named_stream && !is_stream(&args.input) {
        return run_conversion(args, &options);
    }
    let registry = animcodec::registry();
    if cache_stream::is_streamable_output(&args.output) {
        return run_streaming(args, limits, &options);
    }
    let start = Instant::now();
    let name = || args.input.display().to_string();
    let decoder = StreamDecoder::new(open(&args.input)?, &registry, limits).in_file(&name())?;
    let codec = decoder.codec_name();
    // Frames decoded of the header's count, then the write (one stage: the writers take the
    // whole animation).
    let progress = Progress::counter("decode", decoder.header().info.frame_count as u64, "frames", args.json);
    progress.message(format!("decoding {}", args.input.display()));
    let animation = decoder.decode_all_reporting(&mut |frames| progress.set(frames as u64)).in_file(&name())?;
    progress.finish();
    drop(progress);
    let decode_seconds = start.elapsed().as_secs_f64();

    let write_start = Instant::now();
    let stages = Progress::stages("decode", 1, args.json);
    stages.stage(format!("writing {}", args.output.display()));
    let written = formats::write_animation_with(&args.output, &animation, &options)?;
    drop(stages);
    let write_seconds = write_start.elapsed().as_secs_f64();

    let report = Report {
        codec,
        frames: animation.frame_count(),
        vertices: animation.vertex_count(),
        triangles: animation.triangles().len(),
        frame_rate: animation.frame_rate(),
        decode_seconds,
        write_seconds,
        how: "written",
    };
    report.emit(args, &written)
}

/// True when `path` is a file starting with the container's magic bytes (anything else is an
/// animation file to convert).
fn is_stream(path: &Path) -> bool {
    use std::io::Read as _;
    let mut magic = [0u8; 8];
    File::open(path).and_then(|mut f| f.read_exact(&mut magic)).is_ok() && magic == animcodec::core::container::MAGIC
}

/// `decode` of an input that is not a stream: read as `encode` reads it (defaults: the first
/// glTF animation, the file's own frame rate) and written, so `decode X.glb -o X.pc2` converts.
fn run_conversion(args: &DecodeArgs, options: &WriteOptions) -> CmdResult {
    let start = Instant::now();
    let input = args.input.display().to_string();
    let stages = Progress::stages("decode", 2, args.json);
    stages.stage(format!("reading {input} (not an animcodec stream: converting it)"));
    let animation =
        super::load(&input, &formats::ReadOptions::default(), Limits::default(), animcodec::front::Streams::Refuse)?
            .animation;
    let decode_seconds = start.elapsed().as_secs_f64();
    let write_start = Instant::now();
    stages.stage(format!("writing {}", args.output.display()));
    let written = formats::write_animation_with(&args.output, &animation, options)?;
    drop(stages);
    let report = Report {
        codec: "none",
        frames: animation.frame_count(),
        vertices: animation.vertex_count(),
        triangles: animation.triangles().len(),
        frame_rate: animation.frame_rate(),
        decode_seconds,
        write_seconds: write_start.elapsed().as_secs_f64(),
        how: "not a stream: converted",
    };
    report.emit(args, &written)
}

/// `decode` to a `.pc2`/`.mdd` file: each packet's frames are written as soon as they
/// are decoded, so memory holds one packet (and the codec decoder's state), never the whole
/// animation; `limits` are charged the same way ([`StreamDecoder::new_streaming`]). The file is
/// pending until the last frame is written: a failure leaves nothing.
fn run_streaming(args: &DecodeArgs, limits: Limits, options: &WriteOptions) -> CmdResult {
    let registry = animcodec::registry();
    let name = || args.input.display().to_string();
    let mut decoder = StreamDecoder::new_streaming(open(&args.input)?, &registry, limits).in_file(&name())?;
    let codec = decoder.codec_name();
    let info = decoder.header().info.clone();
    let mut writer = CacheWriter::create(&args.output, &info.topology, info.frame_count, info.frame_rate, options)?;
    let (mut decode_seconds, mut write_seconds) = (0.0, 0.0);
    let progress = Progress::counter("decode", info.frame_count as u64, "frames", args.json);
    progress.message(format!("decoding {} → {}", args.input.display(), args.output.display()));
    loop {
        let t = Instant::now();
        let Some(packet) = decoder.next_packet() else { break };
        let packet = packet.in_file(&name())?;
        decode_seconds += t.elapsed().as_secs_f64();
        let t = Instant::now();
        writer.write_frames(&packet.positions)?;
        write_seconds += t.elapsed().as_secs_f64();
        progress.inc(packet.frame_count as u64);
    }
    progress.finish();
    drop(progress);
    let t = Instant::now();
    let written = writer.finish()?;
    write_seconds += t.elapsed().as_secs_f64();
    let report = Report {
        codec,
        frames: info.frame_count,
        vertices: info.vertex_count(),
        triangles: info.topology.triangle_count(),
        frame_rate: info.frame_rate,
        decode_seconds,
        write_seconds,
        how: "written frame by frame",
    };
    report.emit(args, &written)
}

/// The document of `decode --json`.
#[derive(Debug, Serialize)]
pub struct DecodeDocument {
    /// The stream's codec.
    pub codec: &'static str,
    /// The input file.
    pub input: String,
    /// The output named on the command line.
    pub output: String,
    /// Every file written.
    pub files: Vec<String>,
    /// Frames.
    pub frames: usize,
    /// Vertices per frame.
    pub vertices: usize,
    /// Triangles.
    pub triangles: usize,
    /// Frames per second.
    pub frame_rate: f32,
    /// Seconds decoding.
    pub decode_seconds: f64,
    /// Seconds writing.
    pub write_seconds: f64,
}

/// What `decode` reports, by either path.
struct Report {
    codec: &'static str,
    frames: usize,
    vertices: usize,
    triangles: usize,
    frame_rate: f32,
    decode_seconds: f64,
    write_seconds: f64,
    /// How the output was written, for the text line.
    how: &'static str,
}

impl Report {
    fn emit(&self, args: &DecodeArgs, written: &[std::path::PathBuf]) -> CmdResult {
        let Report { codec, frames, vertices, triangles, frame_rate, decode_seconds, write_seconds, how } = *self;
        if args.json {
            return emit_document(&DecodeDocument {
                codec,
                input: args.input.display().to_string(),
                output: args.output.display().to_string(),
                files: written.iter().map(|f| f.display().to_string()).collect(),
                frames,
                vertices,
                triangles,
                frame_rate,
                decode_seconds,
                write_seconds,
            });
        }
        emit(&format!(
            "{input}: {codec}, {frames} frames × {vertices} vertices, {triangles} triangles, {frame_rate} fps, \
             decoded in {decode_seconds:.2} s\n→ {out} ({files}, {how} in {write_seconds:.2} s)\n",
            input = args.input.display(),
            out = args.output.display(),
            files = if written.len() == 1 { "1 file".to_owned() } else { format!("{} files", written.len()) },
        ))
    }
}
