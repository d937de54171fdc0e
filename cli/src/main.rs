//! `animcodec`: compress, decompress, inspect and compare mesh-animation codecs.
//!
//! Every subcommand lives in its own module under `commands/`. Errors are printed as one
//! line `error: <message>: <cause>…` on stderr with exit code 1; usage errors are clap's
//! (exit code 2).

mod commands;
mod progress;
mod signals;
mod viewer;

use std::path::PathBuf;
use std::process::ExitCode;

use animcodec::synth::SynthSize;
use clap::{Args, Parser, Subcommand, ValueEnum};

/// Compress 3D mesh animations (fixed connectivity, moving vertices) with research codecs,
/// and measure them.
///
/// Inputs are read by file extension: a `.pc2` or `.mdd` point cache (triangles from the OBJ
/// with the same stem, or `--topology`), a `.gltf`/`.glb` morph-target animation, a USD layer
/// (`.usda`, `.usdc`, `.usd`, `.usdz`: time-sampled mesh points), an `.abc` Alembic archive
/// (PolyMesh/SubD objects, transforms baked in; `--object` picks one), or a directory / pattern of OBJ files. `synth:NAME[:SIZE]` names a built-in synthetic animation
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
    /// Most memory a decode, or a glTF read, may hold in total (bytes; K, M, G suffixes are
    /// powers of 1024). Inputs needing more are rejected before allocating. Default 1G.
    #[arg(long, global = true, value_name = "BYTES", value_parser = commands::parse_bytes)]
    max_memory: Option<u64>,

    /// Most arithmetic operations a decode may spend, counted from the stream's sizes before
    /// the work starts (the same count on every machine). Streams needing more are rejected
    /// before computing. Default 200 000 000 000 (about 186G; K, M, G suffixes are powers of
    /// 1024).
    #[arg(long, global = true, value_name = "OPS", value_parser = commands::parse_bytes)]
    max_work: Option<u64>,

    /// Worker threads for codecs that parallelize (default: all cores; at most 4 × the cores,
    /// at least 8). Output bytes do not depend on it.
    #[arg(long, global = true, value_name = "N", value_parser = commands::parse_workers)]
    threads: Option<u32>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// List every codec with its FourCC, parameters (kind, range, default) and rate ladder.
    List(ListArgs),
    /// Encode an animation file into an `.anim` container.
    Encode(EncodeArgs),
    /// Decode an `.anim` container and write the animation to a file.
    Decode(DecodeArgs),
    /// Show the header and packets of an `.anim` container and its bits per vertex per frame,
    /// after verifying every checksum (header, index, each packet).
    Info(InfoArgs),
    /// Write a built-in synthetic animation to a file.
    Synth(SynthArgs),
    /// Encode and decode every synthetic animation with every codec and print a comparison.
    Demo(DemoArgs),
    /// Every error metric (KG, STED, Hausdorff, MSE, …) between a reference and a candidate.
    Eval(EvalArgs),
    /// Walk every codec's rate ladder on one input: table, JSON, CSV and rate-distortion plot.
    Sweep(SweepArgs),
    /// Show the stseg segmentation of an animation: temporal segments and per-vertex group
    /// labels as JSON, and the groups as vertex colours in a PLY or OBJ mesh.
    Inspect(InspectArgs),
    /// Write one self-contained HTML page that plays the reference and candidates side by side
    /// with a shared camera and per-vertex error heat maps.
    View(ViewArgs),
    /// Write any input (or a decoded `.anim` stream) as a glTF/GLB morph-target animation that
    /// every glTF engine plays, and report its error as played back.
    Export(ExportArgs),
    /// List the animations of a glTF/GLB file (index, name, channels, key times and rate):
    /// what `--animation NAME|INDEX` chooses from; or the mesh objects of an Alembic `.abc`
    /// file (path, points, faces, samples): what `--object PATH` chooses from. `info FILE`
    /// prints the same.
    ListAnimations(ListAnimationsArgs),
}

/// Arguments of `animcodec list-animations`.
#[derive(Debug, Args)]
pub struct ListAnimationsArgs {
    /// A `.gltf`, `.glb` or `.abc` file.
    #[arg(value_name = "FILE.glb")]
    pub input: PathBuf,

    /// Print JSON: {file, animations: [{index, name, channels, start, end, key_rate, properties}]}.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `animcodec export`.
#[derive(Debug, Args)]
pub struct ExportArgs {
    /// Input animation (any input format, or an `.anim` container, which is decoded).
    #[arg(value_name = "INPUT")]
    pub input: String,

    /// Output `.glb` (binary) or `.gltf` (JSON with the buffer embedded as a data URI).
    #[arg(short, long, value_name = "OUT.glb")]
    pub output: PathBuf,

    /// basis: the mean shape plus the fewest principal components (morph targets, LINEAR
    /// weights) meeting --target-kg, or --targets of them; frames: frame 0 plus one morph target
    /// per frame with STEP weights (exact, large).
    #[arg(long, value_name = "LAYOUT", default_value = "basis")]
    pub layout: String,

    /// basis: the number of morph targets written, K in all (default: the fewest meeting
    /// --target-kg). A compressed export spends one of them on the mean shape's fine residual
    /// when that plays closer than one more principal component.
    #[arg(long, value_name = "K")]
    pub targets: Option<usize>,

    /// basis: the KG error (%) the written animation must meet against the input (> 0);
    /// the same as --target kg=KG. Default 0.05. Not with --targets, which fixes the count.
    #[arg(long, value_name = "KG", conflicts_with_all = ["target", "targets"])]
    pub target_kg: Option<f64>,

    /// basis: the error target, `kg=T` (KG in %, > 0), as `encode --target` spells it; the
    /// fewest morph targets meeting it are written. Only kg is supported here. Not with
    /// --targets.
    #[arg(long, value_name = "kg=T", value_parser = parse_target, conflicts_with = "targets")]
    pub target: Option<animcodec::harness::Target>,

    /// basis: auto (default) writes the file both with the per-frame rigid motion (rotation +
    /// translation fitted to the mean shape) as node animation and without, and keeps the
    /// smaller; on / off force it.
    #[arg(long, value_name = "auto|on|off", default_value = "auto")]
    pub rigid: String,

    /// How the file stores its geometry, for the importer it is meant for. meshopt (default):
    /// KHR_mesh_quantization (16-bit positions) + EXT_meshopt_compression (meshoptimizer's
    /// codecs), the smallest, for engines and web viewers (three.js, Babylon.js, glTFast,
    /// Godot 4); Blender 5.0 cannot import it. quantized: KHR_mesh_quantization alone, for DCC
    /// tools (Blender 5.0 imports it). none: plain f32 positions, no extension.
    #[arg(long, value_name = "meshopt|quantized|none", default_value = "meshopt")]
    pub compression: String,

    /// The same as --compression none.
    #[arg(long, conflicts_with = "compression")]
    pub no_compress: bool,

    /// Keep the input's vertices as they are. By default a compressed export welds vertices
    /// with identical positions on every frame and orders them for locality, as gltfpack does
    /// (smaller files; the file then holds fewer vertices, in another order; the reported error
    /// is measured on the input's vertices).
    #[arg(long)]
    pub keep_vertices: bool,

    /// OBJ file giving the triangles of a .pc2/.mdd input (default: the OBJ beside it).
    #[arg(long, value_name = "OBJ")]
    pub topology: Option<PathBuf>,

    /// glTF input: the animation to play, by name or index (default: the first; `animcodec
    /// list-animations FILE` lists them).
    #[arg(long, value_name = "NAME|INDEX")]
    pub animation: Option<String>,

    /// Alembic input: the mesh object to read, by full path (`/root/char/body`), or an object
    /// whose meshes are read (default: every mesh, merged; `animcodec list-animations FILE.abc`
    /// lists them).
    #[arg(long, value_name = "PATH")]
    pub object: Option<String>,

    /// Frame rate of the input when it stores none (keys are written at frame / fps seconds).
    #[arg(long, value_name = "F", value_parser = commands::parse_fps, allow_negative_numbers = true)]
    pub fps: Option<f32>,

    /// STED options for the played-back report.
    #[command(flatten)]
    pub sted: StedArgs,

    /// Print JSON: {output, layout, targets, bytes, bpvf, kg, sted, metrics, …}.
    #[arg(long)]
    pub json: bool,
    /// Replace existing output files (without it, an existing output is an error). An output
    /// that is also an input is refused even with it.
    #[arg(short, long)]
    pub force: bool,
}

/// Arguments of `animcodec view`.
#[derive(Debug, Args)]
pub struct ViewArgs {
    /// Reference animation (any input format, or an `.anim` container, which is decoded).
    #[arg(value_name = "REFERENCE")]
    pub reference: String,

    /// Candidates: animation files or `.anim` streams (decoded), or CODEC[:key=value,…] to
    /// encode the reference with that codec on the spot (e.g. `hosvd:ss=0.9`).
    #[arg(value_name = "CANDIDATE")]
    pub candidates: Vec<String>,

    /// Output HTML page (self-contained: opens without a network).
    #[arg(short, long, value_name = "OUT.html")]
    pub output: PathBuf,

    /// Per-vertex error shown as the heat map: euclidean (distance in model units) or sted
    /// (STED's local deviation of relative edge lengths).
    #[arg(long, value_name = "METRIC", default_value = "euclidean", value_parser = commands::view::parse_heat)]
    pub heat: crate::viewer::HeatMetric,

    /// Top of the colour bar (default: the 99.5th percentile of every candidate's per-vertex,
    /// per-frame errors; larger errors get the top colour).
    #[arg(long, value_name = "X")]
    pub heat_max: Option<f64>,

    /// Page title (default: the reference's name and size).
    #[arg(long)]
    pub title: Option<String>,

    /// OBJ file giving the triangles of .pc2/.mdd inputs (default: the OBJ beside each).
    #[arg(long, value_name = "OBJ")]
    pub topology: Option<PathBuf>,

    /// glTF input: the animation to play, by name or index (default: the first; `animcodec
    /// list-animations FILE` lists them). Applies to the reference; a glTF candidate plays its first.
    #[arg(long, value_name = "NAME|INDEX")]
    pub animation: Option<String>,

    /// Alembic input: the mesh object to read, by full path (`/root/char/body`), or an object
    /// whose meshes are read (default: every mesh, merged; `animcodec list-animations FILE.abc`
    /// lists them). Applies to the reference.
    #[arg(long, value_name = "PATH")]
    pub object: Option<String>,

    /// STED options (header values and `--heat sted`).
    #[command(flatten)]
    pub sted: StedArgs,
    /// Replace existing output files (without it, an existing output is an error). An output
    /// that is also an input is refused even with it.
    #[arg(short, long)]
    pub force: bool,
}

/// Arguments of `animcodec inspect`.
#[derive(Debug, Args)]
pub struct InspectArgs {
    /// Input animation: .pc2, .mdd, .gltf/.glb, an OBJ directory or pattern, or
    /// `synth:NAME[:small|medium|large]`.
    #[arg(value_name = "INPUT")]
    pub input: String,

    /// stseg parameter as key=value (repeatable; see `animcodec list`). Only the segmentation
    /// parameters (omega_seg, w, gamma_init, gamma_max, lambda, cut_threshold, groups, rho)
    /// change the result.
    #[arg(short = 'p', long = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,

    /// Write JSON to F (`-`: print it instead of the summary): {input, vertices, frames,
    /// triangles, params, boundaries, detected_boundaries, segments: [{index, first_frame,
    /// last_frame, frame_count, case, kind, detected_boundary, ends_at, window, group_count,
    /// group_sizes, label_set}], label_sets: [[label per vertex], …]}. Segments sharing a
    /// grouping share one label set.
    #[arg(long, value_name = "F")]
    pub json: Option<PathBuf>,

    /// Write the mesh at `--frame` with each vertex coloured by its group label in the segment
    /// containing that frame: `.ply` (ASCII, `red green blue` uchar vertex properties) or
    /// `.obj` (`v x y z r g b`, colours 0..1). Colours: hue k·0.618… (golden-ratio steps) for
    /// label k, so they are the same in every run.
    #[arg(long, value_name = "F.ply|F.obj")]
    pub mesh: Option<PathBuf>,

    /// Replace existing output files (without it, an existing output is an error). An output
    /// that is also an input is refused even with it.
    #[arg(short, long)]
    pub force: bool,

    /// Frame shown by `--mesh` (0-based).
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub frame: usize,

    /// OBJ file giving the triangles of a .pc2/.mdd cache (default: the OBJ beside it with the
    /// same stem).
    #[arg(long, value_name = "OBJ")]
    pub topology: Option<PathBuf>,

    /// glTF input: the animation to play, by name or index (default: the first; `animcodec
    /// list-animations FILE` lists them).
    #[arg(long, value_name = "NAME|INDEX")]
    pub animation: Option<String>,

    /// Alembic input: the mesh object to read, by full path (`/root/char/body`), or an object
    /// whose meshes are read (default: every mesh, merged; `animcodec list-animations FILE.abc`
    /// lists them).
    #[arg(long, value_name = "PATH")]
    pub object: Option<String>,
}

/// Arguments of `animcodec list`.
#[derive(Debug, Args)]
pub struct ListArgs {
    /// Print JSON: an array of {name, fourcc, summary, params, rate_ladder}.
    #[arg(long, conflicts_with = "markdown")]
    pub json: bool,
    /// Print the codec table of README.md and python/README.md (Markdown), made from the registry.
    #[arg(long)]
    pub markdown: bool,
}

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

    /// OBJ file giving the triangles of a .pc2/.mdd cache (default: the OBJ beside it with the
    /// same stem).
    #[arg(long, value_name = "OBJ")]
    pub topology: Option<PathBuf>,

    /// glTF input: the animation to play, by name or index (default: the first; `animcodec
    /// list-animations FILE` lists them).
    #[arg(long, value_name = "NAME|INDEX")]
    pub animation: Option<String>,

    /// Alembic input: the mesh object to read, by full path (`/root/char/body`), or an object
    /// whose meshes are read (default: every mesh, merged; `animcodec list-animations FILE.abc`
    /// lists them).
    #[arg(long, value_name = "PATH")]
    pub object: Option<String>,

    /// Frame rate to use when the input stores none (or to override a synthetic one).
    #[arg(long, value_name = "F", value_parser = commands::parse_fps, allow_negative_numbers = true)]
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
    #[arg(long, value_name = "BYTES", value_parser = commands::parse_bytes)]
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
    #[arg(long, value_name = "METRIC=VALUE[,…]", value_parser = parse_target)]
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
}

fn parse_target(text: &str) -> Result<animcodec::harness::Target, String> {
    text.parse()
}

/// STED parameters (defaults: the metrics crate's `StedParams::default()`, which are the
/// metric author's tool's).
#[derive(Debug, Args)]
pub struct StedArgs {
    /// STED neighbourhood width in rings: the edges touching every vertex within R edge hops
    /// (1..=16; default 1).
    #[arg(long, value_name = "R")]
    pub sted_radius: Option<u32>,
    /// STED time extent of one frame step, in units of the diameter of reference frame 0
    /// (1e-9 to 1e9; default 0.0003).
    #[arg(long, value_name = "DT")]
    pub sted_dt: Option<f64>,
    /// STED speed-averaging window: the reference speed at frame f is the mean over temporal
    /// edges f−K+1 … f+K (1..=1000; default 5).
    #[arg(long, value_name = "K")]
    pub sted_window: Option<u32>,
    /// STED weight of the temporal part (0 to 1e9; default 9.144e-5).
    #[arg(long, value_name = "C")]
    pub sted_c: Option<f64>,
    /// Use absolute relative edge differences in STED's spatial part (default signed, as the
    /// metric author's tool).
    #[arg(long)]
    pub sted_absolute: bool,
}

/// The metric switches `eval` and `sweep` share.
#[derive(Debug, Args)]
pub struct MetricArgs {
    /// STED options.
    #[command(flatten)]
    pub sted: StedArgs,

    /// Skip STED.
    #[arg(long)]
    pub no_sted: bool,

    /// Skip the Hausdorff distance.
    #[arg(long)]
    pub no_hausdorff: bool,
}

/// Arguments of `animcodec eval`.
#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Reference animation (any input format, or an `.anim` container, which is decoded).
    #[arg(value_name = "REFERENCE")]
    pub reference: String,

    /// Candidate animation (any input format, or an `.anim` container). Same vertex count,
    /// frame count and triangles as the reference.
    #[arg(value_name = "CANDIDATE")]
    pub candidate: String,

    /// OBJ file giving the triangles of .pc2/.mdd inputs (default: the OBJ beside each).
    #[arg(long, value_name = "OBJ")]
    pub topology: Option<PathBuf>,

    /// glTF input: the animation to play, by name or index (default: the first; `animcodec
    /// list-animations FILE` lists them). Applies to the reference; a glTF candidate plays its first.
    #[arg(long, value_name = "NAME|INDEX")]
    pub animation: Option<String>,

    /// Match the candidate's vertices to the reference's by trajectory (nearest over all
    /// frames) before comparing: for a candidate that reorders, welds or splits vertices
    /// (gltfpack, `animcodec export`, Draco-compressed glTF). The reference's triangles are used
    /// for both; an ambiguous match, or a candidate vertex that follows no reference vertex, is
    /// an error.
    #[arg(long)]
    pub match_vertices: bool,

    /// Alembic input: the mesh object to read, by full path (`/root/char/body`), or an object
    /// whose meshes are read (default: every mesh, merged; `animcodec list-animations FILE.abc`
    /// lists them). Applies to the reference.
    #[arg(long, value_name = "PATH")]
    pub object: Option<String>,

    /// Which metrics, and STED's options.
    #[command(flatten)]
    pub metrics: MetricArgs,

    /// Print JSON with keys named after the metrics: kg, sted, sted_spatial, sted_temporal,
    /// hausdorff, hausdorff_mean, hausdorff_relative, mse, rmse, rmse_relative, max_error,
    /// sted_params, notes, ….
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `animcodec sweep`.
#[derive(Debug, Args)]
pub struct SweepArgs {
    /// Input animation (any `encode` input, or an `.anim` container, decoded first). Default:
    /// the built-in synthetic `synth:flag` (small); any `synth:NAME[:SIZE]` works.
    #[arg(value_name = "INPUT")]
    pub input: Option<String>,

    /// Comma-separated codecs (default: every registered codec, unless --series is given).
    #[arg(short, long = "codecs", value_name = "A,B", value_delimiter = ',')]
    pub codecs: Vec<String>,

    /// Parameter for the codecs of -c (repeatable), the base each ladder step starts from, e.g.
    /// `-c pca-aoi -p mode=qaoi` (whose ladder then walks the error band). Setting the ladder's
    /// own parameter is an error: the sweep walks it.
    #[arg(short = 'p', long = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,

    /// An extra curve: a codec and its base parameters (repeatable), e.g.
    /// `--series pca-aoi:mode=baoi,tmax=2`. Curves are labelled `codec[key=value,…]` with the
    /// parameters that differ from the defaults, so one codec can be compared with itself.
    #[arg(long = "series", value_name = "CODEC:KEY=VALUE,...")]
    pub series: Vec<String>,

    /// Sweep only the single-axis rate ladders (each codec on its -p parameters) instead of
    /// each codec's lower envelope over its declared parameter space (the default without
    /// --series).
    #[arg(long)]
    pub ladder: bool,

    /// Envelope sweep: ladder points measured on each configuration after the first (spread
    /// over the part of the ladder where the first configuration reached KG 0.05–4 or STED
    /// 0.01–0.2), then up to as many again next to its points on the envelope.
    #[arg(long, value_name = "N", default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub config_points: u32,

    /// Ladder points per codec, spread evenly over its rate ladder, ends included (default:
    /// every step).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub points: Option<u32>,

    /// Points measured at once (default: all cores via rayon; at most 4 × the cores, at least
    /// 8). Use `--jobs 1` when the encode and decode times matter: parallel points compete for
    /// the cores.
    #[arg(long, value_name = "N", value_parser = commands::parse_workers)]
    pub jobs: Option<u32>,

    /// Write JSON to F (`-`: print it instead of the table): {input, vertices, frames,
    /// eval_options, rows: [{codec, params, ladder_param, ladder_index, bytes, bpvf, kg, sted,
    /// sted_spatial, sted_temporal, hausdorff, hausdorff_relative, mse, rmse, max_error,
    /// encode_seconds, decode_seconds}], failures, monotone, total_seconds, jobs}.
    #[arg(long, value_name = "F")]
    pub json: Option<PathBuf>,

    /// Write the rows as CSV to F (same columns; params as key=value;key=value).
    #[arg(long, value_name = "F")]
    pub csv: Option<PathBuf>,

    /// Write an SVG with two panels: bpvf vs KG (left) and bpvf vs STED (right), one curve per
    /// codec, error axes in log scale.
    #[arg(long, value_name = "F.svg")]
    pub plot: Option<PathBuf>,

    /// Replace existing output files (without it, an existing output is an error). An output
    /// that is also an input is refused even with it.
    #[arg(short, long)]
    pub force: bool,

    /// OBJ file giving the triangles of a .pc2/.mdd input.
    #[arg(long, value_name = "OBJ")]
    pub topology: Option<PathBuf>,

    /// glTF input: the animation to play, by name or index (default: the first; `animcodec
    /// list-animations FILE` lists them).
    #[arg(long, value_name = "NAME|INDEX")]
    pub animation: Option<String>,

    /// Alembic input: the mesh object to read, by full path (`/root/char/body`), or an object
    /// whose meshes are read (default: every mesh, merged; `animcodec list-animations FILE.abc`
    /// lists them).
    #[arg(long, value_name = "PATH")]
    pub object: Option<String>,

    /// Write an HTML report: the interactive rate-distortion plot (hover a point for its
    /// parameters, bytes and every metric), the table, and a viewer per `--view-points` point.
    #[arg(long, value_name = "F.html")]
    pub html: Option<PathBuf>,

    /// With --html: points whose decoded animation is embedded as a viewer against the input,
    /// as SERIES:LADDER_INDEX (e.g. `hosvd:3`, index 0 = the smallest stream; repeatable or
    /// comma-separated).
    #[arg(long, value_name = "SERIES:INDEX", value_delimiter = ',', requires = "html")]
    pub view_points: Vec<String>,

    /// Which metrics, and STED's options.
    #[command(flatten)]
    pub metrics: MetricArgs,
}

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

/// Arguments of `animcodec info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// Input `.anim` container (or a `.gltf`/`.glb` file: its animations are listed; an `.abc`
    /// file: its mesh objects are listed).
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
    /// body), phases (motion changing character at frames F/4, F/2, 3F/4); or
    /// flag:COLSxROWSxFRAMES, a flag of any length written frame by frame to a .pc2/.mdd (its
    /// frames are never all held in memory, only its mesh; for scale tests).
    #[arg(value_name = "NAME")]
    pub name: String,

    /// Size preset.
    #[arg(long, value_enum, default_value_t = SizeArg::Small)]
    pub size: SizeArg,

    /// Output file: .pc2 or .mdd (with `STEM.obj` beside it holding the triangles), or an OBJ
    /// sequence (as for `decode -o`).
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,

    /// Replace the existing output file (without it, an existing output is an error). It names
    /// the .pc2/.mdd only: an existing STEM.obj beside it is replaced only when it was written
    /// for this cache (by this program) or holds the same mesh; any other (the topology of
    /// another cache of the same stem, a model) is refused by name: remove it or choose another
    /// output name.
    #[arg(short, long)]
    pub force: bool,
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
    signals::install_cleanup();
    // Every file a reader opens (a .gltf's buffers, a cache's OBJ, …) is an input no output
    // may replace, even with --force: overwriting it would lose the user's data.
    animcodec::output::protect_files_read();
    // No panic text ever reaches the terminal: the library turns the panics it can meet (inside
    // the gltf crate) into errors, which are reported below; any other panic is a bug, reported
    // as one short line instead of a backtrace.
    std::panic::set_hook(Box::new(|_| {}));
    let cli = Cli::parse();
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(move || run(cli))) {
        Ok(Ok(())) => ExitCode::SUCCESS,
        Ok(Err(e)) => {
            commands::report_error(e.as_ref());
            ExitCode::from(1)
        }
        Err(_) => {
            let line = b"error: internal error (a bug in animcodec); please report the command that caused it\n";
            let _ = std::io::Write::write_all(&mut std::io::stderr(), line);
            ExitCode::from(101)
        }
    }
}

fn run(cli: Cli) -> commands::CmdResult {
    if let Some(n) = cli.global.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n as usize) // bounded by commands::parse_workers
            .build_global()
            .map_err(|e| format!("cannot set up {n} worker threads: {e}"))?;
    }
    let limits = commands::limits(cli.global.max_memory, cli.global.max_work);
    if let Some(bytes) = cli.global.max_memory {
        // The glTF reader's total budget (its default is 1 GiB).
        animcodec::formats::gltf::set_default_memory_budget(bytes);
    }
    if let Some(ops) = cli.global.max_work {
        // The Alembic reader's parsing work.
        animcodec::formats::abc::set_default_work_budget(ops);
    }
    match cli.command {
        Command::List(a) => commands::list::run(&a),
        Command::Encode(a) => commands::encode::run(&a, limits),
        Command::Decode(a) => commands::decode::run(&a, limits),
        Command::Info(a) => commands::info::run(&a, limits),
        Command::Synth(a) => commands::synth::run(&a),
        Command::Demo(a) => commands::demo::run(&a, limits),
        Command::Eval(a) => commands::eval::run(&a, limits),
        Command::Sweep(a) => commands::sweep::run(&a, limits),
        Command::Inspect(a) => commands::inspect::run(&a),
        Command::View(a) => commands::view::run(&a, limits),
        Command::Export(a) => commands::export::run(&a, limits),
        Command::ListAnimations(a) => commands::animations::run(&a.input, a.json),
    }
}
