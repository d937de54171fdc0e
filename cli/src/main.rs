//! `animcodec`: compress, decompress, inspect and compare mesh-animation codecs.
//!
//! Every subcommand lives in its own module under `commands/`. Errors are printed as one
//! line `error: <message>: <cause>…` on stderr with exit code 1; usage errors are clap's
//! (exit code 2).

mod commands;
mod progress;
mod signals;
mod viewer;

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use commands::args::GlobalArgs;
use commands::{animations, decode, demo, encode, eval, export, info, inspect, list, sweep, synth, view};

/// Compress 3D mesh animations (fixed connectivity, moving vertices) with research codecs,
/// and measure them.
///
/// Inputs are read by file extension: a `.pc2` or `.mdd` point cache (triangles from the OBJ
/// with the same stem, or `--topology`), a `.gltf`/`.glb` morph-target animation, a USD layer
/// (`.usda`, `.usdc`, `.usd`, `.usdz`: time-sampled mesh points), an `.abc` Alembic archive
/// (PolyMesh/SubD objects, transforms baked in; `--object` picks one), or a directory / pattern of OBJ files. `synth:NAME[:SIZE]` names a built-in synthetic animation
/// (see `animcodec synth --help`).
///
/// Long commands show their progress on stderr when it is a terminal (frames, points or
/// stages done of their total, and an ETA); never when stderr is piped or with --json.
/// ANIMCODEC_PROGRESS=never turns it off on a terminal too.
#[derive(Debug, Parser)]
#[command(name = "animcodec", version, propagate_version = true, max_term_width = 110)]
struct Cli {
    #[command(flatten)]
    global: GlobalArgs,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// List every codec with its FourCC, parameters (kind, range, default) and rate ladder.
    List(list::ListArgs),
    /// Encode an animation file into an `.anim` container.
    Encode(encode::EncodeArgs),
    /// Decode an `.anim` container and write the animation to a file.
    Decode(decode::DecodeArgs),
    /// Show the header and packets of an `.anim` container and its bits per vertex per frame,
    /// after verifying every checksum (header, index, each packet).
    Info(info::InfoArgs),
    /// Write a built-in synthetic animation to a file.
    Synth(synth::SynthArgs),
    /// Encode and decode every synthetic animation with every codec and print a comparison.
    Demo(demo::DemoArgs),
    /// Every error metric (KG, STED, Hausdorff, MSE, …) between a reference and a candidate.
    Eval(eval::EvalArgs),
    /// Walk every codec's rate ladder on one input: table, JSON, CSV and rate-distortion plot.
    Sweep(sweep::SweepArgs),
    /// Show the stseg segmentation of an animation: temporal segments and per-vertex group
    /// labels as JSON, and the groups as vertex colours in a PLY or OBJ mesh.
    Inspect(inspect::InspectArgs),
    /// Write one self-contained HTML page that plays the reference and candidates side by side
    /// with a shared camera and per-vertex error heat maps.
    View(view::ViewArgs),
    /// Write any input (or a decoded `.anim` stream) as a glTF/GLB morph-target animation that
    /// every glTF engine plays, and report its error as played back.
    Export(export::ExportArgs),
    /// List the animations of a glTF/GLB file (index, name, channels, key times and rate):
    /// what `--animation NAME|INDEX` chooses from; or the mesh objects of an Alembic `.abc`
    /// file (path, points, faces, samples): what `--object PATH` chooses from. `info FILE`
    /// prints the same.
    ListAnimations(animations::ListAnimationsArgs),
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
    let limits = animcodec::front::limits(cli.global.max_memory, cli.global.max_work)?;
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
