//! `animcodec eval`: every metric between a reference animation and a candidate.

use std::path::Path;
use std::time::Instant;

use animcodec::formats::gltf_out::as_shown;
use animcodec::formats::ReadOptions;
use animcodec::harness::report_json;
use codec_core::{Animation, Limits, StreamDecoder};
use metrics::{EdgeDifference, EvalOptions, MetricReport, StedParams};
use serde_json::Value;

use super::decode::open;
use super::{emit, emit_json, load_animation, CmdResult, WithContext};
use crate::{EvalArgs, MetricArgs, StedArgs};

/// STED parameters from the command line (defaults from [`StedParams::default`]), checked.
pub fn sted_params(args: &StedArgs) -> CmdResult<StedParams> {
    let d = StedParams::default();
    let p = StedParams {
        ring_radius: args.sted_radius.unwrap_or(d.ring_radius),
        dt: args.sted_dt.unwrap_or(d.dt),
        speed_window: args.sted_window.unwrap_or(d.speed_window),
        c: args.sted_c.unwrap_or(d.c),
        spatial_difference: if args.sted_absolute { EdgeDifference::Absolute } else { d.spatial_difference },
    };
    p.validate()?;
    Ok(p)
}

/// Loads an animation for comparison: an `.anim` container is decoded, anything else is read
/// like an `encode` input.
pub fn load_any(input: &str, options: &ReadOptions, limits: Limits) -> CmdResult<Animation> {
    let path = Path::new(input);
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("anim")) {
        let registry = animcodec::registry();
        let name = || input.to_string();
        let decoder = StreamDecoder::new(open(path)?, &registry, limits).in_file(&name())?;
        return decoder.decode_all().in_file(&name());
    }
    load_animation(input, options)
}

/// The metrics and STED options `eval` and `sweep` were asked for.
pub fn eval_options(args: &MetricArgs) -> CmdResult<EvalOptions> {
    Ok(EvalOptions {
        sted: sted_params(&args.sted)?,
        compute_sted: !args.no_sted,
        compute_hausdorff: !args.no_hausdorff,
    })
}

/// Runs `eval`.
pub fn run(args: &EvalArgs, limits: Limits) -> CmdResult {
    let options = eval_options(&args.metrics)?;
    let read = ReadOptions {
        topology: args.topology.clone(),
        frame_rate: None,
        animation: args.animation.clone(),
        object: args.object.clone(),
    };
    let mut reference = load_any(&args.reference, &read, limits)?;
    // --animation chooses the reference's animation; a glTF candidate plays its first.
    let mut candidate = load_any(&args.candidate, &ReadOptions { animation: None, ..read }, limits)?;
    // A glTF shows a +Z-up or non-metre source turned +Y up in metres (the root node our
    // writers add): the other side is compared where the glTF shows it.
    let is_gltf = |p: &str| {
        Path::new(p).extension().is_some_and(|x| x.eq_ignore_ascii_case("glb") || x.eq_ignore_ascii_case("gltf"))
    };
    if is_gltf(&args.candidate) && !is_gltf(&args.reference) {
        reference = as_shown(&reference)?.unwrap_or(reference);
    } else if is_gltf(&args.reference) && !is_gltf(&args.candidate) {
        candidate = as_shown(&candidate)?.unwrap_or(candidate);
    }
    let mut matched = None;
    if args.match_vertices {
        let context = || format!("matching the vertices of {} to {}", args.candidate, args.reference);
        let m = metrics::match_vertices(&reference, &candidate).context(context)?;
        candidate = m.apply(&reference, &candidate).context(context)?;
        matched = Some(m);
    }
    if let Err(e) = metrics::check_compatible(&reference, &candidate) {
        let gltf = std::path::Path::new(&args.candidate)
            .extension()
            .is_some_and(|x| x.eq_ignore_ascii_case("glb") || x.eq_ignore_ascii_case("gltf"));
        // `export` welds and reorders vertices by default (as gltfpack does): say so rather
        // than leave a bare topology mismatch.
        let hint = if gltf && !args.match_vertices {
            "; `animcodec export` welds vertices with identical trajectories and reorders them for \
             compression, so its files match the input vertex by vertex only when written with \
             --keep-vertices, or compared with --match-vertices (export itself reports KG and STED as played \
             back, on the input's vertices)"
        } else {
            ""
        };
        return Err(format!("comparing {} with {}: {e}{hint}", args.reference, args.candidate).into());
    }
    let start = Instant::now();
    let mut report = metrics::evaluate(&reference, &candidate, &options)
        .context(|| format!("comparing {} with {}", args.reference, args.candidate))?;
    if let Some(m) = &matched {
        report.notes.push(format!(
            "vertices matched by trajectory (--match-vertices): worst RMS distance {:.6e} ({:.3e} of the diagonal), \
             {} candidate vertices shared by several reference vertices, {} unused; the reference's triangles are used",
            m.worst_distance,
            m.worst_distance / report.bbox_diagonal.max(f64::MIN_POSITIVE),
            m.shared,
            m.unused
        ));
    }
    let seconds = start.elapsed().as_secs_f64();
    if args.json {
        let mut value = report_json(&report);
        if let Value::Object(map) = &mut value {
            map.insert("reference".into(), args.reference.clone().into());
            map.insert("candidate".into(), args.candidate.clone().into());
            map.insert("eval_seconds".into(), seconds.into());
            if let Some(m) = &matched {
                map.insert(
                    "vertex_match".into(),
                    serde_json::json!({
                        "worst_distance": m.worst_distance, "shared": m.shared, "unused": m.unused,
                    }),
                );
            }
        }
        return emit_json(&value);
    }
    emit(&text(args, &report, seconds))
}

fn num(v: Option<f64>) -> String {
    v.map_or_else(|| "n/a".to_string(), |x| format!("{x:.6e}"))
}

fn text(args: &EvalArgs, r: &MetricReport, seconds: f64) -> String {
    let p = &r.sted_params;
    let mut out = format!(
        "{} vs {}: {} frames × {} vertices, bounding-box diagonal {:.6}\n",
        args.reference, args.candidate, r.frame_count, r.vertex_count, r.bbox_diagonal
    );
    let rows = [
        ("kg (%)", num(r.kg)),
        // The worst connected part against its own spread, beside the global KG.
        ("worst_part_kg (%)", num(r.worst_part_kg())),
        ("sted", num(r.sted)),
        ("sted_spatial", num(r.sted_spatial)),
        ("sted_temporal", num(r.sted_temporal)),
        ("hausdorff", num(r.hausdorff)),
        ("hausdorff_mean", num(r.hausdorff_mean)),
        ("hausdorff_relative", num(r.hausdorff_relative)),
        ("mse", num(Some(r.mse))),
        ("rmse", num(Some(r.rmse))),
        ("rmse_relative", num(r.rmse_relative)),
        ("max_error", num(Some(r.max_error))),
    ];
    for (k, v) in rows {
        out.push_str(&format!("  {k:<20} {v}\n"));
    }
    out.push_str(&format!(
        "  STED: ring radius {}, dt {}, speed window {}, c {}, {} differences; computed in {seconds:.2} s\n",
        p.ring_radius,
        p.dt,
        p.speed_window,
        p.c,
        match p.spatial_difference {
            EdgeDifference::Signed => "signed",
            EdgeDifference::Absolute => "absolute",
        }
    ));
    if let Some(w) = &r.worst_part {
        out.push_str(&format!(
            "  worst part: part {} of {} ({} vertices from vertex {}), RMSE {:.6e}, max error {:.6e}, spread {:.6e}{}\n",
            w.part,
            r.parts,
            w.vertices,
            w.first_vertex,
            w.rmse,
            w.max_error,
            w.spread,
            if w.floored { " (below the floor: KG measured against the floor)" } else { "" }
        ));
    }
    for n in &r.notes {
        out.push_str(&format!("  note: {n}\n"));
    }
    out
}
