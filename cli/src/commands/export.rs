//! `animcodec export`: any input (or a decoded `.anim` stream) as a glTF/GLB morph-target
//! animation, with the error of the file as played back.

use std::path::Path;
use std::time::Instant;

use animcodec::formats::gltf_out::{as_shown, encode_gltf, restore_vertices, GltfCompression, GltfLayout, GltfOptions};
use animcodec::formats::{gltf, ReadOptions};
use animcodec::harness::{self, TargetMetric};
use animcodec::output::OutputPolicy;
use codec_core::Limits;
use metrics::EvalOptions;
use serde_json::json;

use super::eval::{load_any, sted_params};
use super::{emit, emit_json, shown, CmdResult, WithContext};
use crate::ExportArgs;

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
    if let Some(t) = &args.topology {
        policy = policy.with_input(t);
    }
    policy.check(&args.output)?;
    let eval = EvalOptions { sted: sted_params(&args.sted)?, compute_hausdorff: false, ..EvalOptions::default() };
    let read = ReadOptions {
        topology: args.topology.clone(),
        frame_rate: args.fps,
        animation: args.animation.clone(),
        object: args.object.clone(),
    };
    let stages = crate::progress::Stages::new("export", 4, args.json);
    stages.stage(format!("reading {}", shown(&args.input)));
    let animation = load_any(&args.input, &read, limits)?;
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
        (Some(t), _) if t.metric != TargetMetric::Kg => {
            return Err(format!("--target {t}: export meets KG targets only (--target kg=T)").into())
        }
        (Some(t), _) => t.value,
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
        (false, "quantized") => GltfCompression::Quantized,
        (false, other) => return Err(format!("--compression '{other}': expected meshopt, quantized or none").into()),
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
    let report = metrics::evaluate(shown_input.as_ref().unwrap_or(&animation), &played, &eval)
        .context(|| format!("comparing {} with {} as played back", shown(&args.input), shown(&args.output)))?;
    stages.stage(format!("writing {}", shown(&args.output)));
    policy.write(&args.output, &bytes)?;
    drop(stages);
    let rate = metrics::bpvf(bytes.len() as u64, animation.vertex_count(), animation.frame_count())?;
    if args.json {
        return emit_json(&json!({
            "input": args.input,
            "output": args.output.display().to_string(),
            "layout": args.layout,
            "targets": summary.targets,
            "rigid": summary.rigid,
            "bytes": bytes.len(),
            "bpvf": rate,
            "kg": report.kg,
            "sted": report.sted,
            "basis_kg": summary.basis_kg,
            "metrics": harness::report_json(&report),
            "frames": animation.frame_count(),
            "vertices": animation.vertex_count(),
            "frame_rate": animation.frame_rate(),
            "export_seconds": seconds,
            "compression": args_compression_name(compression),
            "extensions_required": compression.extensions(),
            "importers": importers(compression),
        }));
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
fn args_compression_name(c: GltfCompression) -> &'static str {
    match c {
        GltfCompression::Meshopt => "meshopt",
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
        GltfCompression::Quantized => {
            "requires KHR_mesh_quantization: Blender 5.0, three.js, Babylon.js and most engines read it"
        }
        GltfCompression::None => "no extensions: every glTF 2.0 importer reads it",
    }
}
