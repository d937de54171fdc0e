//! `animcodec`: compress, decompress, inspect and compare mesh-animation codecs.
//!
//! Every subcommand lives in its own module under `commands/`. Errors are printed as one
//! line `error: <message>: <cause>…` on stderr with exit code 1; usage errors are clap's
//! (exit code 2).

mod commands;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand, ValueEnum};
use codec_core::synth::SynthSize;

/// Compress 3D mesh animations (fixed connectivity, moving vertices) with research codecs,
/// and measure them.
///
/// Inputs are read by file extension: a `.pc2` or `.mdd` point cache (triangles from the OBJ
/// with the same stem, or `--topology`), a `.gltf`/`.glb` morph-target animation, or a
/// directory / pattern of OBJ files. `synth:NAME[:SIZE]` names a built-in synthetic animation
/// (see `animcodec synth --help`).
#[derive(Debug, Parser)]
#[command(name = "animcodec", version, propagate_version = true, max_term_width = 110)]
struct Cli {
    #[command(flatten)]
    global: GlobalArgs,
    #[command(subcommand)]
    command: Command,
}

/// Options shared by every subcommand.
#[derive(Debug, Args)]
struct GlobalArgs {
    /// Largest single allocation a decoder may make from stream contents (bytes; K, M, G
    /// suffixes are powers of 1024). Streams needing more are rejected before allocating.
    /// Default 4G.
    #[arg(long, global = true, value_name = "BYTES", value_parser = commands::parse_bytes)]
    max_memory: Option<u64>,

    /// Worker threads for codecs that parallelize (default: all cores). Output bytes do not
    /// depend on it.
    #[arg(long, global = true, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// List every codec with its FourCC, parameters (kind, range, default) and rate ladder.
    List(ListArgs),
    /// Encode an animation file into an `.anim` container.
    Encode(EncodeArgs),
    /// Decode an `.anim` container and write the animation to a file.
    Decode(DecodeArgs),
    /// Show the header and packets of an `.anim` container, and its bits per vertex per frame.
    Info(InfoArgs),
    /// Write a built-in synthetic animation to a file.
    Synth(SynthArgs),
    /// Encode and decode every synthetic animation with every codec and print a comparison.
    Demo(DemoArgs),
}

/// Arguments of `animcodec list`.
#[derive(Debug, Args)]
pub struct ListArgs {
    /// Print JSON: an array of {name, fourcc, summary, params, rate_ladder}.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `animcodec encode`.
#[derive(Debug, Args)]
pub struct EncodeArgs {
    /// Input animation: .pc2, .mdd, .gltf/.glb, an OBJ directory or pattern,
    /// `synth:NAME[:small|medium|large]`, or `synth:flag:COLSxROWSxFRAMES` (a flag of any
    /// size, generated frame by frame while encoding, never held in memory).
    #[arg(value_name = "INPUT")]
    pub input: String,

    /// Codec name (see `animcodec list`).
    #[arg(short, long, value_name = "CODEC")]
    pub codec: String,

    /// Codec parameter as key=value (repeatable; see `animcodec list` for keys and ranges).
    #[arg(short = 'p', long = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,

    /// Output `.anim` file (replaced if it exists; removed again if encoding fails).
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,

    /// OBJ file giving the triangles of a .pc2/.mdd cache (default: the OBJ beside it with the
    /// same stem).
    #[arg(long, value_name = "OBJ")]
    pub topology: Option<PathBuf>,

    /// Frame rate to use when the input stores none (or to override a synthetic one).
    #[arg(long, value_name = "F", value_parser = commands::parse_fps, allow_negative_numbers = true)]
    pub fps: Option<f32>,

    /// Frames handed to the encoder per call (the output does not depend on it).
    #[arg(long, value_name = "N", default_value_t = 32, value_parser = clap::value_parser!(u32).range(1..))]
    pub feed: u32,

    /// Print JSON: {codec, params, bytes, bpvf, frames, vertices, triangles, encode_seconds, …}.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `animcodec decode`.
#[derive(Debug, Args)]
pub struct DecodeArgs {
    /// Input `.anim` container.
    #[arg(value_name = "IN.anim")]
    pub input: PathBuf,

    /// Output animation: .pc2, .mdd, or an OBJ sequence (a path ending in .obj containing `{}`
    /// or `#` for the frame number, or a directory).
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,

    /// Print JSON: {codec, frames, vertices, triangles, decode_seconds, …}.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `animcodec info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// Input `.anim` container.
    #[arg(value_name = "IN.anim")]
    pub input: PathBuf,

    /// List every packet even when there are many (the text output otherwise shows the first 32).
    #[arg(long)]
    pub all_packets: bool,

    /// Print JSON: {codec, fourcc, frames, vertices, triangles, bytes, bpvf, geometry_bpvf,
    /// packets: [{first_frame, frame_count, keyframe, bytes}], …}.
    #[arg(long)]
    pub json: bool,
}

/// Size presets of the synthetic animations.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SizeArg {
    /// A few hundred vertices × 40 frames.
    Small,
    /// About 2.5k vertices × 120 frames.
    Medium,
    /// About 10k vertices × 300 frames.
    Large,
}

impl From<SizeArg> for SynthSize {
    fn from(s: SizeArg) -> Self {
        match s {
            SizeArg::Small => SynthSize::Small,
            SizeArg::Medium => SynthSize::Medium,
            SizeArg::Large => SynthSize::Large,
        }
    }
}

/// Arguments of `animcodec synth`.
#[derive(Debug, Args)]
pub struct SynthArgs {
    /// Animation: flag (waving cloth), cylinder (two-bone skinned bend + twist), tumble (rigid
    /// body), phases (motion changing character at frames F/4, F/2, 3F/4).
    #[arg(value_name = "NAME")]
    pub name: String,

    /// Size preset.
    #[arg(long, value_enum, default_value_t = SizeArg::Small)]
    pub size: SizeArg,

    /// Output file: .pc2, .mdd, or an OBJ sequence.
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,
}

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

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            commands::report_error(e.as_ref());
            ExitCode::from(1)
        }
    }
}

fn run(cli: Cli) -> commands::CmdResult {
    if let Some(n) = cli.global.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n as usize)
            .build_global()
            .map_err(|e| format!("cannot set up {n} worker threads: {e}"))?;
    }
    let limits = commands::limits(cli.global.max_memory);
    match cli.command {
        Command::List(a) => commands::list::run(&a),
        Command::Encode(a) => commands::encode::run(&a),
        Command::Decode(a) => commands::decode::run(&a, limits),
        Command::Info(a) => commands::info::run(&a, limits),
        Command::Synth(a) => commands::synth::run(&a),
        Command::Demo(a) => commands::demo::run(&a, limits),
    }
}
