//! `animcodec view`: one self-contained HTML page playing a reference animation and candidates
//! side by side with per-vertex error heat maps (`crate::viewer`).

use std::path::Path;
use std::time::Instant;

use crate::viewer::{self, Candidate, HeatMetric, ViewerOptions};
use animcodec::core::{Animation, CodecRegistry, Limits, StreamDecoder};
use animcodec::formats::ReadOptions;
use animcodec::metrics::EvalOptions;
use animcodec::output::OutputPolicy;
use animcodec::params::params_json;
use serde_json::{json, Value};

use super::args::StedArgs;
use super::{emit, load, shown, CmdResult, WithContext};
use clap::Args;
use std::path::PathBuf;

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
    #[arg(long, value_name = "METRIC", default_value = "euclidean", value_parser = parse_heat)]
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

/// A candidate as loaded: its label, the decoded animation and what the header shows.
struct Loaded {
    label: String,
    animation: Animation,
    info: Value,
}

/// Runs `view`.
pub fn run(args: &ViewArgs, limits: Limits) -> CmdResult {
    let start = Instant::now();
    // A missing folder is refused before the (possibly long) loading and encoding.
    animcodec::output::folder_exists(&args.output)?;
    // The page is checked before the (possibly long) loading and encoding.
    let mut policy = OutputPolicy::new(args.force).with_input(&args.reference);
    for c in args.candidates.iter().filter(|c| Path::new(c).exists()) {
        policy = policy.with_input(c);
    }
    if let Some(t) = &args.topology {
        policy = policy.with_input(t);
    }
    policy.check(&args.output)?;
    let registry = animcodec::registry();
    let read = ReadOptions {
        topology: args.topology.clone(),
        frame_rate: None,
        animation: args.animation.clone(),
        object: args.object.clone(),
    };
    // Stages: the reference, each candidate, the measurements, the page.
    let stages = crate::progress::Progress::stages("view", 3 + args.candidates.len() as u64, false);
    stages.stage(format!("reading {}", shown(&args.reference)));
    let reference = load(&args.reference, &read, limits, animcodec::front::Streams::Decode)?.animation;
    let sted = args.sted.metric_options().sted_params()?;
    let mut loaded = Vec::new();
    // --animation chooses the reference's animation; a glTF candidate plays its first.
    let read_candidate = ReadOptions { animation: None, ..read };
    for spec in &args.candidates {
        stages.stage(format!("candidate {}", shown(spec)));
        loaded.push(load_candidate(&registry, spec, &reference, &read_candidate, limits)?);
    }
    // The files the read opened (a .gltf's buffers, …) are inputs too: refused before the work.
    policy.check(&args.output)?;
    let eval = EvalOptions { sted, ..EvalOptions::default() };
    stages.stage("measuring the candidates (KG, STED, Hausdorff, per-vertex errors)");
    let mut candidates = Vec::new();
    for c in &loaded {
        let report = animcodec::metrics::evaluate(&reference, &c.animation, &eval)
            .context(|| format!("comparing {} with {}", shown(&args.reference), shown(&c.label)))?;
        candidates.push(Candidate {
            label: c.label.clone(),
            animation: &c.animation,
            info: c.info.clone(),
            report: Some(report),
        });
    }
    let options = ViewerOptions {
        heat: args.heat,
        heat_max: args.heat_max,
        sted,
        title: args.title.clone().unwrap_or_else(|| {
            format!("{}: {} frames × {} vertices", args.reference, reference.frame_count(), reference.vertex_count())
        }),
    };
    stages.stage("building the page");
    let data = viewer::viewer_data(&reference, &candidates, &options)?;
    let page = viewer::viewer_page(&data);
    policy.write(&args.output, page.as_bytes())?;
    drop(stages);
    emit(&format!(
        "{}: reference + {} candidate(s), {} frames × {} vertices, heat {} up to {:.4e}; {} bytes written in {:.2} s\n",
        shown(&args.output),
        candidates.len(),
        reference.frame_count(),
        reference.vertex_count(),
        data["heat_metric"].as_str().unwrap_or(""),
        data["heat_max"].as_f64().unwrap_or(0.0),
        page.len(),
        start.elapsed().as_secs_f64()
    ))
}

/// A candidate: an existing file (any input format, or an `.anim` stream, decoded), or
/// `CODEC[:key=value,…]`, the reference encoded with that codec and decoded on the spot.
fn load_candidate(
    registry: &CodecRegistry,
    spec: &str,
    reference: &Animation,
    read: &ReadOptions,
    limits: Limits,
) -> CmdResult<Loaded> {
    let (name, rest) = spec.split_once(':').unwrap_or((spec, ""));
    if !Path::new(spec).exists() {
        if let Ok(codec) = registry.by_name(name) {
            let pairs: Vec<String> = rest.split(',').filter(|p| !p.trim().is_empty()).map(str::to_string).collect();
            let params = animcodec::front::params_from_text(codec, &pairs)?;
            let bytes = animcodec::core::encode_animation(codec, &params, reference)?;
            let animation = StreamDecoder::new(bytes.as_slice(), registry, limits)?.decode_all()?;
            let size = bytes.len() as u64;
            return Ok(Loaded {
                label: spec.to_string(),
                info: json!({
                    "codec": codec.name(),
                    "params": params_json(&params),
                    "bytes": size,
                    "bpvf": animcodec::metrics::bpvf(size, reference.vertex_count(), reference.frame_count())?,
                }),
                animation,
            });
        }
    }
    let (animation, info) = if spec.to_ascii_lowercase().ends_with(".anim") {
        // One pass over the stream: its codec from the header, then its frames.
        let size = std::fs::metadata(spec).map(|m| m.len()).unwrap_or(0);
        let decoder =
            StreamDecoder::new(super::decode::open(Path::new(spec))?, registry, limits).context(|| shown(spec))?;
        let codec = decoder.codec_name();
        let animation = decoder.decode_all().context(|| shown(spec))?;
        let info = json!({
            "codec": codec,
            "params": "not stored in the stream",
            "bytes": size,
            "bpvf": animcodec::metrics::bpvf(size, animation.vertex_count(), animation.frame_count())?,
        });
        (animation, info)
    } else {
        (load(spec, read, limits, animcodec::front::Streams::Decode)?.animation, json!({}))
    };
    let label = Path::new(spec).file_name().map_or_else(|| spec.to_string(), |f| f.to_string_lossy().into_owned());
    Ok(Loaded { label, animation, info })
}

/// `--heat` values.
pub fn parse_heat(text: &str) -> Result<HeatMetric, String> {
    match text {
        "euclidean" => Ok(HeatMetric::Euclidean),
        "sted" => Ok(HeatMetric::Sted),
        _ => Err(format!("'{text}' is not a heat metric; valid: euclidean, sted")),
    }
}
