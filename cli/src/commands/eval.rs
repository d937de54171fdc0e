//! `animcodec eval`: every metric between a reference animation and a candidate.

use std::time::Instant;

use animcodec::core::Limits;
use animcodec::formats::gltf_out::as_shown;
use animcodec::formats::stream::{self as cache_stream, CacheReader};
use animcodec::formats::ReadOptions;
use animcodec::front::{self, Origin, Streams};
use animcodec::harness;
use animcodec::metrics::{EdgeDifference, EvalOptions, MetricReport};
use serde::Serialize;
use std::path::Path;

use super::args::MetricArgs;
use super::{emit, emit_document, load, CmdResult, WithContext};
use clap::Args;
use std::path::PathBuf;

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

/// Runs `eval`.
pub fn run(args: &EvalArgs, limits: Limits) -> CmdResult {
    let options = args.metrics.metric_options().eval_options()?;
    let read = ReadOptions {
        topology: args.topology.clone(),
        frame_rate: None,
        animation: args.animation.clone(),
        object: args.object.clone(),
    };
    if let Some((report, seconds)) = measure_streamed(args, &options, &read, limits)? {
        return emit_report(args, &report, seconds, None);
    }
    // Stages: the two reads and the measurement (Hausdorff and STED on a large mesh: minutes).
    let stages = crate::progress::Progress::stages("eval", 3, args.json);
    stages.stage(format!("reading {}", args.reference));
    let reference = load(&args.reference, &read, limits, Streams::Decode)?;
    stages.stage(format!("reading {}", args.candidate));
    // --animation chooses the reference's animation; a glTF candidate plays its first.
    let mut candidate =
        load(&args.candidate, &ReadOptions { animation: None, ..read }, limits, Streams::Decode)?.animation;
    // A stream as the reference is decoded and measured against as it decodes: said, since the
    // figures are then the candidate's distance from that decode, not from the original.
    let reference_note = match reference.origin {
        Origin::Stream { codec } => Some(format!(
            "the reference {} is an .anim stream ({codec}): it was decoded, and the candidate is compared with \
             the decoded animation (not with the animation that was encoded)",
            args.reference
        )),
        _ => None,
    };
    let mut reference = reference.animation;
    // A glTF shows a +Z-up or non-metre source turned +Y up in metres (the root node our
    // writers add): the other side is compared where the glTF shows it.
    let is_gltf = |p: &str| {
        std::path::Path::new(p)
            .extension()
            .is_some_and(|x| x.eq_ignore_ascii_case("glb") || x.eq_ignore_ascii_case("gltf"))
    };
    if is_gltf(&args.candidate) && !is_gltf(&args.reference) {
        reference = as_shown(&reference)?.unwrap_or(reference);
    } else if is_gltf(&args.reference) && !is_gltf(&args.candidate) {
        candidate = as_shown(&candidate)?.unwrap_or(candidate);
    }
    let mut matched = None;
    if args.match_vertices {
        let context = || format!("matching the vertices of {} to {}", args.candidate, args.reference);
        let m = animcodec::metrics::match_vertices(&reference, &candidate).context(context)?;
        candidate = m.apply(&reference, &candidate).context(context)?;
        matched = Some(m);
    }
    if let Err(e) = animcodec::metrics::check_compatible(&reference, &candidate) {
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
    stages.stage("measuring (KG, STED, Hausdorff, RMSE, max error)");
    let mut report = animcodec::metrics::evaluate(&reference, &candidate, &options)
        .context(|| format!("comparing {} with {}", args.reference, args.candidate))?;
    drop(stages);
    report.notes.extend(reference_note);
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
    emit_report(args, &report, seconds, matched.as_ref())
}

/// `eval` of a reference read frame by frame (a .pc2/.mdd cache or an OBJ sequence) against a
/// candidate read so too, or an `.anim` stream decoded packet by packet: the report of the
/// in-memory comparison ([`harness::measure_sources`], [`harness::measure_stream`]) without
/// holding either animation. `None` for any other pair (and with --match-vertices, which
/// matches whole trajectories), measured in memory.
fn measure_streamed(
    args: &EvalArgs,
    options: &EvalOptions,
    read: &ReadOptions,
    limits: Limits,
) -> CmdResult<Option<(MetricReport, f64)>> {
    let (reference, candidate) = (Path::new(&args.reference), Path::new(&args.candidate));
    let stream = front::names_stream(&args.candidate);
    if args.match_vertices
        || !cache_stream::is_streamable(reference)
        || !(stream || cache_stream::is_streamable(candidate))
    {
        return Ok(None);
    }
    let start = Instant::now();
    let comparing = || format!("comparing {} with {}", args.reference, args.candidate);
    let mut ref_reader = CacheReader::open(reference, read)?;
    let (topology, frame_count, frame_rate) =
        (ref_reader.topology().clone(), ref_reader.frame_count(), ref_reader.frame_rate());
    let mut read_ref = |n: usize, out: &mut Vec<f32>| ref_reader.read_frames(n, out);
    let reference_source = harness::FrameSource { topology: &topology, frame_count, frame_rate, read: &mut read_ref };
    let report = if stream {
        let registry = animcodec::registry();
        let file = front::open_stream(candidate).in_file(&args.candidate)?;
        harness::measure_stream(&registry, file, reference_source, options, limits).context(comparing)?
    } else {
        let mut cand_reader = CacheReader::open(candidate, read)?;
        let (ctop, cframes, crate_) =
            (cand_reader.topology().clone(), cand_reader.frame_count(), cand_reader.frame_rate());
        let mut read_cand = |n: usize, out: &mut Vec<f32>| cand_reader.read_frames(n, out);
        let candidate_source =
            harness::FrameSource { topology: &ctop, frame_count: cframes, frame_rate: crate_, read: &mut read_cand };
        harness::measure_sources(reference_source, candidate_source, options).context(comparing)?
    };
    Ok(Some((report, start.elapsed().as_secs_f64())))
}

/// Prints the report (`--json`: the document).
fn emit_report(
    args: &EvalArgs,
    report: &MetricReport,
    seconds: f64,
    matched: Option<&animcodec::metrics::VertexMatch>,
) -> CmdResult {
    if args.json {
        return emit_document(&EvalDocument {
            report,
            reference: &args.reference,
            candidate: &args.candidate,
            eval_seconds: seconds,
            vertex_match: matched.map(|m| VertexMatch {
                worst_distance: m.worst_distance,
                shared: m.shared,
                unused: m.unused,
            }),
        });
    }
    emit(&text(args, report, seconds))
}

/// The document of `eval --json`: every metric (the report's keys), the two inputs, the
/// seconds, and the vertex match when `--match-vertices` made one.
#[derive(Debug, Serialize)]
pub struct EvalDocument<'a> {
    /// Every metric.
    #[serde(flatten)]
    pub report: &'a MetricReport,
    /// The reference as given.
    pub reference: &'a str,
    /// The candidate as given.
    pub candidate: &'a str,
    /// Seconds measuring.
    pub eval_seconds: f64,
    /// The match `--match-vertices` made.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vertex_match: Option<VertexMatch>,
}

/// How the candidate's vertices were matched to the reference's.
#[derive(Debug, Serialize)]
pub struct VertexMatch {
    /// The worst RMS distance of a matched pair.
    pub worst_distance: f64,
    /// Candidate vertices shared by several reference vertices.
    pub shared: usize,
    /// Candidate vertices no reference vertex follows.
    pub unused: usize,
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
