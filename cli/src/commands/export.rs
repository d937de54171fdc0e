//! `animcodec export`: any input (or a decoded `.anim` stream) as a glTF/GLB morph-target
//! animation, with the error of the file as played back.

use std::path::Path;
use std::time::Instant;

use animcodec::core::Limits;
use animcodec::formats::gltf;
use animcodec::formats::gltf_out::{as_shown, encode_gltf, restore_vertices, GltfCompression, GltfLayout, GltfOptions};
use animcodec::harness::{self, TargetMetric};
use animcodec::metrics::EvalOptions;
use animcodec::output::OutputPolicy;
use serde::Serialize;

use super::args::{ReadArgs, StedArgs};
use super::{emit, emit_document, load, shown, CmdResult, WithContext};
use clap::Args;
use std::path::PathBuf;

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
    #[arg(long, value_name = "kg=T", value_parser = super::args::parse_target, conflicts_with = "targets")]
    pub target: Option<animcodec::harness::Target>,

    /// basis: auto (default) writes the file both with the per-frame rigid motion (rotation +
    /// translation fitted to the mean shape) as node animation and without, and keeps the
    /// smaller; on / off force it.
    #[arg(long, value_name = "auto|on|off", default_value = "auto")]
    pub rigid: String,

    /// How the file stores its geometry, for the importer it is meant for. meshopt (default):
    /// KHR_mesh_quantization (16-bit positions) + EXT_meshopt_compression (meshoptimizer's
    /// codecs), the smallest, for engines and web viewers (three.js, Babylon.js, glTFast,
    /// Godot 4); Blender 5.0 cannot import it. meshopt-khr: the same through
    /// KHR_meshopt_compression, whose vertex codec version 1 is smaller, for loaders with
    /// meshoptimizer 0.23+'s decoder (three.js r17x+). quantized: KHR_mesh_quantization alone,
    /// for DCC tools (Blender 5.0 imports it). none: plain f32 positions, no extension.
    #[arg(long, value_name = "meshopt|meshopt-khr|quantized|none", default_value = "meshopt")]
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

    /// Frame rate of the input when it stores none (keys are written at frame / fps seconds).
    #[arg(long, value_name = "F", value_parser = super::parse_fps, allow_negative_numbers = true)]
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

    /// How the input is read.
    #[command(flatten)]
    pub read: ReadArgs,
}

/// Runs `export`.
pub fn run(args: &ExportArgs, limits: Limits) -> CmdResult {
    // A missing folder is refused before the (possibly minute-long) export, not after it.
    animcodec::output::folder_exists(&args.output)?;
    let ext = args.output.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
    let glb = match ext.as_deref() {
        Some("glb") => true,
        Some("gltf") => false,
        _ => return Err(format!("{}: export writes .glb or .gltf", shown(&args.output)).into()),
    };
    let mut policy = OutputPolicy::new(args.force).with_input(&args.input);
    if let Some(t) = &args.read.topology {
        policy = policy.with_input(t);
    }
    policy.check(&args.output)?;
    let eval = EvalOptions { compute_hausdorff: false, ..args.sted.metric_options().eval_options()? };
    let read = args.read.options(args.fps);
    let stages = crate::progress::Progress::stages("export", 4, args.json);
    stages.stage(format!("reading {}", shown(&args.input)));
    let animation = load(&args.input, &read, limits, animcodec::front::Streams::Decode)?.animation;
    // The files the read opened (a .gltf's buffers, …) are inputs too: refused before the work.
    policy.check(&args.output)?;
    let layout = match args.layout.as_str() {
        "basis" => GltfLayout::Basis,
        "frames" => GltfLayout::Frames,
        other => return Err(format!("--layout '{other}': expected basis or frames").into()),
    };
    let name =
        Path::new(&args.input).file_stem().map_or_else(|| "animcodec".into(), |s| s.to_string_lossy().into_owned());
    let target_kg = match (&args.target, args.target_kg) {
        (Some(t), _) => match t.single() {
            Some((TargetMetric::Kg, kg)) => kg,
            _ => return Err(format!("--target {t}: export meets KG targets only (--target kg=T)").into()),
        },
        (None, Some(kg)) => kg,
        (None, None) => GltfOptions::default().target_kg,
    };
    let rigid = match args.rigid.as_str() {
        "auto" => None,
        "on" => Some(true),
        "off" => Some(false),
        other => return Err(format!("--rigid '{other}': expected auto, on or off").into()),
    };
    let compression = match (args.no_compress, args.compression.as_str()) {
        (true, _) | (false, "none") => GltfCompression::None,
        (false, "meshopt") => GltfCompression::Meshopt,
        (false, "meshopt-khr") => GltfCompression::MeshoptKhr,
        (false, "quantized") => GltfCompression::Quantized,
        (false, other) => {
            return Err(format!("--compression '{other}': expected meshopt, meshopt-khr, quantized or none").into())
        }
    };
    let options = GltfOptions {
        layout,
        targets: args.targets,
        target_kg,
        name,
        compression,
        rigid,
        reorder: compression.quantized() && !args.keep_vertices,
    };
    let start = Instant::now();
    stages.stage(format!(
        "encoding {} frames × {} vertices as glTF morph targets",
        animation.frame_count(),
        animation.vertex_count()
    ));
    let (bytes, summary) = encode_gltf(&animation, &options, glb)?;
    let seconds = start.elapsed().as_secs_f64();
    // What an engine plays: the file's bytes read back by our own glTF reader and measured,
    // before they replace anything (a file that fails either is never written).
    stages.stage("reading the glTF back and measuring it as played");
    let mut played = gltf::parse_gltf(&bytes, None, &shown(&args.output), animation.frame_rate())
        .context(|| "the glTF written does not read back".to_owned())?;
    if let Some(map) = &summary.vertex_map {
        played = restore_vertices(&played, map, animation.triangles())?;
    }
    // A +Z-up or centimetre source plays through the file's root node: compared where it shows.
    let shown_input = as_shown(&animation)?;
    let report = animcodec::metrics::evaluate(shown_input.as_ref().unwrap_or(&animation), &played, &eval)
        .context(|| format!("comparing {} with {} as played back", shown(&args.input), shown(&args.output)))?;
    stages.stage(format!("writing {}", shown(&args.output)));
    policy.write(&args.output, &bytes)?;
    drop(stages);
    let rate = animcodec::metrics::bpvf(bytes.len() as u64, animation.vertex_count(), animation.frame_count())?;
    if args.json {
        return emit_document(&ExportDocument {
            input: args.input.clone(),
            output: args.output.display().to_string(),
            layout: args.layout.clone(),
            targets: summary.targets,
            rigid: summary.rigid,
            bytes: bytes.len(),
            bpvf: rate,
            kg: report.kg,
            sted: report.sted,
            basis_kg: summary.basis_kg,
            metrics: harness::report_json(&report),
            frames: animation.frame_count(),
            vertices: animation.vertex_count(),
            frame_rate: animation.frame_rate(),
            export_seconds: seconds,
            compression: args_compression_name(compression),
            extensions_required: compression.extensions(),
            importers: importers(compression),
        });
    }
    let num = |x: Option<f64>| x.map_or_else(|| "n/a".to_string(), |x| format!("{x:.4e}"));
    emit(&format!(
        "{input}: {f} frames × {v} vertices at {fps} fps → {out}\n\
         {layout} layout, {k} morph targets{rigid}, {bytes} bytes, {rate:.3} bits/vertex/frame (written in {seconds:.2} s)\n\
         played back (read with animcodec's glTF reader at {fps} fps): KG {kg} %, STED {sted}, max error {max:.4e}\n\
         {importers}\n",
        importers = importers(compression),
        input = shown(&args.input),
        f = animation.frame_count(),
        v = animation.vertex_count(),
        fps = animation.frame_rate(),
        out = shown(&args.output),
        layout = args.layout,
        k = summary.targets,
        rigid = if summary.rigid { " + rigid motion as node animation" } else { "" },
        bytes = bytes.len(),
        kg = num(report.kg),
        sted = num(report.sted),
        max = report.max_error,
    ))
}

/// The `--compression` name of `c`.
/// The document of `export --json`.
#[derive(Debug, Serialize)]
pub struct ExportDocument {
    /// The input as given.
    pub input: String,
    /// The file written.
    pub output: String,
    /// `basis` or `frames`.
    pub layout: String,
    /// Morph targets written.
    pub targets: usize,
    /// Whether the rigid motion is written as node animation.
    pub rigid: bool,
    /// The file's size.
    pub bytes: usize,
    /// Bits per vertex per frame of the file.
    pub bpvf: f64,
    /// KG (%) of the animation as played back.
    pub kg: Option<f64>,
    /// STED of the animation as played back.
    pub sted: Option<f64>,
    /// KG (%) of the basis before quantization.
    pub basis_kg: f64,
    /// Every metric as played back.
    pub metrics: serde_json::Value,
    /// Frames.
    pub frames: usize,
    /// Vertices per frame.
    pub vertices: usize,
    /// Frames per second.
    pub frame_rate: f32,
    /// Seconds writing the file.
    pub export_seconds: f64,
    /// How the geometry is stored.
    pub compression: &'static str,
    /// The glTF extensions the file requires.
    pub extensions_required: &'static [&'static str],
    /// The importers that read it.
    pub importers: &'static str,
}

fn args_compression_name(c: GltfCompression) -> &'static str {
    match c {
        GltfCompression::Meshopt => "meshopt",
        GltfCompression::MeshoptKhr => "meshopt-khr",
        GltfCompression::Quantized => "quantized",
        GltfCompression::None => "none",
    }
}

/// Which importers open a file of this form (checked: three.js and the Khronos validator for
/// every form, Blender 5.0 for quantized and none; cli/tests/gltf.rs, cli/tests/blender.rs).
fn importers(c: GltfCompression) -> &'static str {
    match c {
        GltfCompression::Meshopt => {
            "requires EXT_meshopt_compression + KHR_mesh_quantization: engines and web viewers read it (three.js, \
             Babylon.js, Unity glTFast, Godot 4); Blender 5.0 does not — use --compression quantized for DCC tools"
        }
        GltfCompression::MeshoptKhr => {
            "requires KHR_meshopt_compression + KHR_mesh_quantization: loaders with meshoptimizer 0.23+'s decoder \
             read it (three.js r17x+); older ones need --compression meshopt; Blender 5.0 does not — use \
             --compression quantized for DCC tools"
        }
        GltfCompression::Quantized => {
            "requires KHR_mesh_quantization: Blender 5.0, three.js, Babylon.js and most engines read it"
        }
        GltfCompression::None => "no extensions: every glTF 2.0 importer reads it",
    }
}
