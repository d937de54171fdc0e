//! `animcodec sweep`: walk every codec's rate ladder on one input, measure every point, print
//! a table and write JSON, CSV and an SVG rate-distortion plot.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use crate::progress::Progress;
use crate::viewer;
use animcodec::core::{AnimationCodec, CodecRegistry, Limits};
use animcodec::front;
use animcodec::harness::{self, monotone_report, Point, Sweep, SweepDocument, SweepOptions, SweepSeries, TargetMetric};
use animcodec::output::{commit_all, OutputPolicy};
use animcodec::params::params_json;

use super::args::{MetricArgs, ReadArgs};
use super::{emit, emit_json, load, source, CmdResult};
use clap::Args;
use std::path::PathBuf;

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

    /// Envelope sweep: rounds of refinement toward the standard targets after the grid (KG ≤ 2,
    /// 0.5, 0.1 and KG & STED ≤ 2 & 0.1, 0.5 & 0.05, 0.1 & 0.02): each measures, per codec and
    /// target, up to two points where the target search would (between ladder steps too),
    /// planned from every point measured so far. 0 skips it.
    #[arg(long, value_name = "N", default_value_t = harness::REFINE_ROUNDS as u32,
          value_parser = clap::value_parser!(u32).range(0..=16))]
    pub refine_rounds: u32,

    /// Ladder points per codec, spread evenly over its rate ladder, ends included (default:
    /// every step).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub points: Option<u32>,

    /// Points measured at once (default: all cores via rayon; at most 4 × the cores, at least
    /// 8). Use `--jobs 1` when the encode and decode times matter: parallel points compete for
    /// the cores.
    #[arg(long, value_name = "N", value_parser = super::parse_workers)]
    pub jobs: Option<u32>,

    /// Write JSON to F (`-`: print it instead of the table): {input, vertices, frames,
    /// eval_options, rows: [{codec, params, ladder_param, ladder_index, bytes, bpvf, kg, sted,
    /// sted_spatial, sted_temporal, hausdorff, hausdorff_relative, mse, rmse, max_error,
    /// encode_seconds, decode_seconds, refined (on refinement points only)}], failures,
    /// monotone, total_seconds, jobs}.
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

    /// Memory budget (bytes; K, M, G suffixes are powers of 1024), e.g. 4G. A sweep holds the
    /// whole input, and each parallel job a decoded candidate and the metrics' working copies.
    /// A sweep that would need more streams a .pc2/.mdd cache, an OBJ sequence or
    /// synth:flag:CxRxF (sized before it is read): each point is encoded from a read of the
    /// input and measured against a second read, one at a time, within the budget (a codec
    /// whose encoder holds the whole input is left out, saying so); any other input is refused.
    /// Default: half the machine's RAM, against which the input and one job are counted.
    #[arg(long, value_name = "BYTES", value_parser = super::parse_bytes)]
    pub memory: Option<u64>,

    /// How the input is read.
    #[command(flatten)]
    pub read: ReadArgs,
}

/// Input swept when none is given.
pub const DEFAULT_INPUT: &str = "synth:flag";

/// Runs `sweep`.
pub fn run(args: &SweepArgs, limits: Limits) -> CmdResult {
    let input = args.input.as_deref().unwrap_or(DEFAULT_INPUT);
    // Outputs are checked before the sweep (minutes), and written only once complete.
    let mut policy = OutputPolicy::new(args.force);
    if !input.starts_with("synth:") {
        policy = policy.with_input(input);
    }
    if let Some(t) = &args.read.topology {
        policy = policy.with_input(t);
    }
    let json_file = args.json.as_deref().filter(|p| p.as_os_str() != "-");
    let to_stdout = args.json.as_deref().is_some_and(|p| p.as_os_str() == "-");
    let outputs: Vec<&Path> =
        [json_file, args.csv.as_deref(), args.plot.as_deref(), args.html.as_deref()].into_iter().flatten().collect();
    policy.check_all(&outputs)?;
    let registry = animcodec::registry();
    let series = sweep_series(&registry, args)?;
    // The default: each codec's lower envelope over its search space; `--ladder` and
    // `--series` give the single-axis curves.
    let envelope_mode = !args.ladder && args.series.is_empty();
    // Checked before the (long) sweep: a typo should not cost it.
    let view_points = args.view_points.iter().map(|t| parse_view_point(t, &series)).collect::<CmdResult<Vec<_>>>()?;
    let eval = args.metrics.metric_options().eval_options()?;
    let read = args.read.options(None);
    // An input read frame by frame (a cache sized from its header, an OBJ sequence, a generated
    // flag) that the sweep could not hold whole is streamed; any other is loaded and refused
    // beyond the budget.
    let streamable = source::streamable(input, &read, None)?;
    let streamed = match &streamable {
        Some(source) => {
            let (v, f) = (source.topology().vertex_count(), source.frame_count());
            check_sweep_memory(args, &series, input, v, f).is_err()
        }
        None => false,
    };
    let (animation, source) = match streamable {
        Some(source) if streamed => {
            if !view_points.is_empty() {
                return Err(format!(
                    "{input}: --view-points shows decoded animations, which a sweep of an input this large does not \
                     keep (it streams the input within the memory budget); leave out --view-points, or give a larger \
                     --memory"
                )
                .into());
            }
            (None, Some(source))
        }
        _ => {
            let animation = load(input, &read, limits, animcodec::front::Streams::Decode)?.animation;
            check_sweep_memory(args, &series, input, animation.vertex_count(), animation.frame_count())?;
            (Some(animation), None)
        }
    };
    // The files the read opened (a .gltf's buffers, …) are inputs too: refused before the work.
    policy.check_all(&outputs)?;
    let (series, streamed_input) = match &source {
        Some(source) => {
            let budget = sweep_budget(args).map_or(u64::MAX, |(b, _)| b);
            let (series, streamed) = streamed_sweep(input, source.as_ref(), series, budget, &eval)?;
            (series, Some(streamed))
        }
        None => (series, None),
    };
    let swept: harness::SearchInput<'_> = match (&animation, &streamed_input) {
        (Some(animation), _) => animation.into(),
        (None, Some(streamed)) => streamed.into(),
        (None, None) => unreachable!("an input is loaded or streamed"),
    };
    let dims = (swept.vertex_count(), swept.frame_count());
    let options = SweepOptions {
        points: args.points.map(|n| n as usize),
        jobs: args.jobs.map(|n| n as usize),
        eval,
        limits,
        // The --view-points' decoded animations are kept as the sweep measures them.
        keep_decoded: view_points.clone(),
        refine_rounds: args.refine_rounds as usize,
    };
    // Every phase's points are counted before the first starts (the later phases at their
    // most, falling to their exact count as they are planned), so the ETA — indicatif's
    // estimate from the points done so far, firming up as the sweep goes — never runs short
    // because the total grew; the message names the phase and the point that started last.
    let bar = Progress::counter("sweep", 0, "points", to_stdout);
    let start = Instant::now();
    let result = if envelope_mode {
        let fixed: Vec<&'static str> = {
            let mut names = Vec::new();
            for s in &series {
                let specs = s.codec.param_specs();
                for pair in &args.params {
                    if let Some(spec) =
                        pair.split_once('=').and_then(|(k, _)| specs.iter().find(|p| p.name == k.trim()))
                    {
                        names.push(spec.name);
                    }
                }
            }
            names
        };
        let codecs: Vec<_> = series.iter().map(|s| (s.codec, s.base.clone(), fixed.clone())).collect();
        let per_config = args.config_points as usize;
        harness::envelope_sweep(&registry, &codecs, swept, &options, per_config, &|event| show_progress(&bar, event))?
    } else {
        harness::sweep(&registry, &series, swept, &options, &|event| show_progress(&bar, event))?
    };
    let seconds = start.elapsed().as_secs_f64();
    bar.finish();
    drop(bar);

    // Every output is built and staged under its temporary name first, then all are renamed
    // together: a failure on the way leaves every old file untouched.
    let mut staged = Vec::new();
    let mut stage = |path: &Path, text: &str| -> CmdResult {
        staged.push(policy.stage(path, text.as_bytes())?);
        Ok(())
    };
    let document = SweepDocument {
        total_seconds: Some(seconds),
        // A streamed sweep measures one point at a time.
        jobs: Some(match (&streamed_input, options.jobs) {
            (Some(_), _) => 1.into(),
            (None, Some(j)) => j.into(),
            (None, None) => "rayon".into(),
        }),
        search_input: if streamed_input.is_some() { "streamed" } else { "whole" },
        ..SweepDocument::new(input, dims, &eval, &result)
    };
    if let Some(path) = args.json.as_ref().filter(|_| !to_stdout) {
        stage(path, &document.to_json_text()?)?;
    }
    if let Some(path) = &args.csv {
        stage(path, &harness::csv_text(&result.points)?)?;
    }
    if let Some(path) = &args.plot {
        let title = format!("{input}: {} frames × {} vertices", dims.1, dims.0);
        stage(path, &animcodec::plot::rd_svg(&title, &result.points))?;
    }
    if let Some(path) = &args.html {
        let page = html_report(input, (animation.as_ref(), dims), &eval, &result, &view_points)?;
        stage(path, &page)?;
    }
    commit_all(staged, &[])?;
    if to_stdout {
        emit_json(&document.to_json()?)?;
    } else {
        emit(&table(input, dims, &result, seconds, envelope_mode))?;
    }
    if result.failures.is_empty() {
        Ok(())
    } else {
        let list: Vec<String> =
            result.failures.iter().map(|f| format!("{} step {}: {}", f.series, f.ladder_index, f.message)).collect();
        Err(format!("{} sweep points failed: {}", list.len(), list.join("; ")).into())
    }
}

/// `SERIES:INDEX` of `--view-points`, checked against the series being swept.
fn parse_view_point(text: &str, series: &[SweepSeries<'_>]) -> CmdResult<(String, usize)> {
    let bad = || format!("--view-points '{text}' is not SERIES:LADDER_INDEX (e.g. hosvd:3)");
    let (name, index) = text.trim().rsplit_once(':').ok_or_else(bad)?;
    let index: usize = index.trim().parse().map_err(|_| bad())?;
    if !series.iter().any(|s| s.label == name) {
        let names: Vec<&str> = series.iter().map(|s| s.label.as_str()).collect();
        return Err(format!("--view-points '{text}': '{name}' is not a swept series ({})", names.join(", ")).into());
    }
    Ok((name.to_string(), index))
}

/// The `--html` report: every row, the interactive plot, and a viewer per chosen point (the
/// decoded animation the sweep measured and kept: no point is encoded or decoded again).
fn html_report(
    input: &str,
    (animation, dims): (Option<&animcodec::core::Animation>, (usize, usize)),
    eval: &animcodec::metrics::EvalOptions,
    sweep: &Sweep,
    view_points: &[(String, usize)],
) -> CmdResult<String> {
    let mut viewers = Vec::new();
    for (name, index) in view_points {
        let point = sweep.points.iter().find(|p| &p.series == name && p.ladder_index == *index).ok_or_else(|| {
            let measured: Vec<String> =
                sweep.points.iter().filter(|p| &p.series == name).map(|p| p.ladder_index.to_string()).collect();
            format!(
                "--view-points '{name}:{index}': the sweep measured no such point; ladder indices measured for \
                 {name}: {}",
                measured.join(", ")
            )
        })?;
        let decoded = sweep
            .decoded
            .iter()
            .find(|(series, step, _)| series == name && step == index)
            .map(|(_, _, decoded)| decoded)
            .ok_or_else(|| format!("--view-points '{name}:{index}': the sweep kept no decoded animation of it"))?;
        let candidate = viewer::Candidate {
            label: format!("{name}:{index}"),
            animation: decoded,
            info: serde_json::json!({
                "codec": point.codec,
                "params": params_json(&point.params),
                "bytes": point.bytes,
                "bpvf": point.bpvf,
            }),
            report: Some(point.report.clone()),
        };
        let options = viewer::ViewerOptions {
            sted: eval.sted,
            title: format!("{name}:{index} against {input}"),
            ..Default::default()
        };
        let animation = animation.ok_or("--view-points: a streamed sweep keeps no animation to view")?;
        viewers.push(viewer::viewer_data(animation, &[candidate], &options)?);
    }
    let mut value = SweepDocument::new(input, dims, eval, sweep).to_json()?;
    value["title"] = format!("Rate-distortion report: {input}").into();
    value["viewers"] = viewers.into();
    Ok(viewer::report_page(&format!("animcodec sweep: {input}"), &value))
}

fn num(v: Option<f64>) -> String {
    v.map_or_else(|| "n/a".to_string(), |x| format!("{x:.4e}"))
}

fn table(input: &str, (vertices, frames): (usize, usize), sweep: &Sweep, seconds: f64, envelope_only: bool) -> String {
    let mut out = String::new();
    let kg = harness::envelope(&sweep.points, TargetMetric::Kg);
    let sted = harness::envelope(&sweep.points, TargetMetric::Sted);
    let joint = harness::joint_envelope(&sweep.points);
    let shown: Vec<&Point> = sweep
        .points
        .iter()
        .enumerate()
        .filter(|(i, _)| !envelope_only || kg.contains(i) || sted.contains(i) || joint.contains(i))
        .map(|(_, p)| p)
        .collect();
    let width = sweep.points.iter().map(|p| p.series.chars().count()).max().unwrap_or(0).max(14);
    let _ = writeln!(
        out,
        "{input}: {frames} frames × {vertices} vertices; {} points in {seconds:.2} s",
        sweep.points.len()
    );
    // With several parts, the worst part's KG (against its own spread) beside the whole
    // animation's: a large static part must not hide a destroyed small one.
    let parts = sweep.points.iter().map(|p| p.report.parts).max().unwrap_or(0);
    let part_column = |v: Option<f64>| if parts > 1 { format!(" {:>11}", num(v)) } else { String::new() };
    if parts > 1 {
        let _ = writeln!(
            out,
            "{parts} parts (connected components): 'part kg' is the worst part's KG against its own spread, \
             which the default quality and --target kg= bound too"
        );
    }
    let _ = writeln!(
        out,
        "{:<w$} {:<16} {:>10} {:>8} {:>11}{} {:>11} {:>11} {:>11} {:>8} {:>8}",
        "codec",
        "knob",
        "bytes",
        "bpvf",
        "kg (%)",
        if parts > 1 { format!(" {:>11}", "part kg (%)") } else { String::new() },
        "sted",
        "hausdorff",
        "mse",
        "enc s",
        "dec s",
        w = width
    );
    if envelope_only {
        let _ = writeln!(
            out,
            "lower envelope of each codec over its parameter space (by KG, STED or both): {} of {} points shown, every \
             point in --json; --ladder for the single-axis ladders",
            shown.len(),
            sweep.points.len()
        );
    }
    let degenerate = shown.iter().any(|p| harness::sted_degenerate(&p.report));
    for p in shown {
        let knob = format!("{}={}", p.ladder_param, p.ladder_value().map(|v| v.to_string()).unwrap_or_default());
        let r = &p.report;
        let _ = writeln!(
            out,
            "{:<w$} {:<16} {:>10} {:>8.4} {:>11}{} {:>11} {:>11} {:>11} {:>8.3} {:>8.3}",
            p.series,
            knob,
            p.bytes,
            p.bpvf,
            num(r.kg),
            part_column(r.worst_part_kg()),
            if harness::sted_degenerate(r) { format!("({})", num(r.sted)) } else { num(r.sted) },
            num(r.hausdorff),
            num(Some(r.mse)),
            p.encode_seconds,
            p.decode_seconds,
            w = width
        );
    }
    if degenerate {
        let _ = writeln!(
            out,
            "(sted): KG above {} %, too far from any target for its STED to be a result (off the STED envelope)",
            harness::STED_DEGENERATE_KG
        );
    }
    for m in monotone_report(&sweep.points).into_iter().filter(|_| !envelope_only) {
        let ok = m.bpvf_increasing && m.kg_decreasing && m.sted_decreasing;
        let _ = writeln!(
            out,
            "{}: {}",
            m.series,
            if ok {
                "monotone (bpvf rises, KG and STED fall along the ladder)".to_string()
            } else {
                format!(
                    "NOT monotone (bpvf rising {}, KG falling {}, STED falling {}; at ladder steps {:?})",
                    m.bpvf_increasing, m.kg_decreasing, m.sted_decreasing, m.violations
                )
            }
        );
    }
    for f in &sweep.failures {
        let _ = writeln!(out, "{} step {}: FAILED: {}", f.series, f.ladder_index, f.message);
    }
    out
}

/// The curves to sweep: every codec of `-c` (default: all registered) on the `-p` parameters,
/// then each `--series CODEC:KEY=VALUE,…`.
fn sweep_series<'r>(registry: &'r CodecRegistry, args: &SweepArgs) -> CmdResult<Vec<SweepSeries<'r>>> {
    let mut out = Vec::new();
    let plain: Vec<&dyn AnimationCodec> = if !args.codecs.is_empty() {
        args.codecs.iter().map(|n| registry.by_name(n.trim())).collect::<Result<_, _>>()?
    } else if args.series.is_empty() {
        registry.iter().collect()
    } else {
        Vec::new()
    };
    if plain.is_empty() && !args.params.is_empty() {
        return Err("-p applies to the codecs of -c; with only --series, put the parameters in each series".into());
    }
    for codec in plain {
        out.push(series_on(codec, &args.params)?);
    }
    for text in &args.series {
        let (name, pairs) = text.split_once(':').unwrap_or((text.as_str(), ""));
        let codec = registry.by_name(name.trim())?;
        let pairs: Vec<String> =
            pairs.split(',').map(str::trim).filter(|p| !p.is_empty()).map(str::to_string).collect();
        out.push(series_on(codec, &pairs)?);
    }
    if let Some(dup) =
        out.iter().enumerate().find_map(|(i, a)| out[..i].iter().any(|b| b.label == a.label).then_some(a))
    {
        return Err(format!("series '{}' is given twice", dup.label).into());
    }
    Ok(out)
}

/// Refuses a sweep of `vertices × frames` whose whole-array measurement would exceed the
/// budget (`--memory`, else [`front::default_memory_budget`]): the input once, and per parallel
/// job what a whole-array search holds beyond it ([`harness::whole_search_need`] less the input:
/// a decoded candidate, the metrics' working copies, the encoder's analysis), the largest over
/// the series' codecs.
fn check_sweep_memory(
    args: &SweepArgs,
    series: &[SweepSeries<'_>],
    input: &str,
    vertices: usize,
    frames: usize,
) -> CmdResult<()> {
    let Some((budget, given)) = sweep_budget(args) else { return Ok(()) };
    let raw = (vertices as u64).saturating_mul(frames as u64).saturating_mul(12);
    let per_job = series
        .iter()
        .map(|s| harness::whole_search_need(s.codec, vertices, frames).saturating_sub(raw))
        .max()
        .unwrap_or(0);
    // With --memory every parallel job counts; under the default budget only what the sweep
    // needs at all (the input and one job), so that the memory models (upper bounds) never
    // refuse on a many-core machine a sweep that ran before.
    let jobs = if given {
        args.jobs.map_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()), |j| j as usize)
    } else {
        1
    };
    let need = raw.saturating_add(per_job.saturating_mul(jobs as u64));
    if need <= budget {
        return Ok(());
    }
    let whose = if given {
        "--memory".to_owned()
    } else {
        "the default memory budget (half the RAM; --memory sets it)".to_owned()
    };
    Err(format!(
        "{input}: a sweep holds the whole input and, per parallel job ({jobs}), a decoded candidate and the \
         metrics' working copies: about {} MiB, more than {whose}, {} MiB. Give fewer --jobs or a larger --memory, \
         or find the smallest stream at a target with `animcodec encode {input} -c CODEC --target kg=…`, which streams \
         an input of any size within --memory",
        need >> 20,
        budget >> 20
    )
    .into())
}

/// The sweep's memory budget and whether it was given: `--memory`, else
/// [`front::default_memory_budget`]; `None` when neither is known.
fn sweep_budget(args: &SweepArgs) -> Option<(u64, bool)> {
    match args.memory {
        Some(m) => Some((m, true)),
        None => front::default_memory_budget().map(|b| (b, false)),
    }
}

/// A streamed sweep of `source` within `budget`: the series whose codec's encoder streams
/// within the work share (the others left out, each with a line on stderr; none left is an
/// error naming the budget), and the streamed input, its work share raised to the largest
/// least need among them ([`harness::StreamedInput::giving_the_codec`]). Said on stderr.
fn streamed_sweep<'r, 's>(
    input: &str,
    source: &'s dyn harness::InputSource,
    series: Vec<SweepSeries<'r>>,
    budget: u64,
    eval: &animcodec::metrics::EvalOptions,
) -> CmdResult<(Vec<SweepSeries<'r>>, harness::StreamedInput<'s>)> {
    let (v, f) = (source.topology().vertex_count(), source.frame_count());
    let need = series
        .iter()
        .filter_map(|s| harness::least_work_budget(s.codec, &s.base, v, f))
        .filter(|&n| n <= budget.saturating_sub(harness::MIN_STREAM_SHARE))
        .max()
        .unwrap_or(0);
    let streamed = harness::StreamedInput::new(source, budget, harness::chunk_frames(v), eval)?.giving_the_codec(need);
    let mut kept = Vec::new();
    for s in series {
        match s.codec.fit_memory(&s.base, v, f, streamed.work_budget()) {
            Ok(_) => kept.push(s),
            Err(e) => eprintln!(
                "animcodec: left out of the sweep: {}: its encoder cannot stream {input} within {} MiB (the sweep's \
                 budget less {} MiB for a candidate's stream): {e}",
                s.label,
                streamed.work_budget() >> 20,
                (budget - streamed.work_budget()) >> 20
            ),
        }
    }
    if kept.is_empty() {
        return Err(format!(
            "{input}: no codec of the sweep streams it within {} MiB: give a larger --memory",
            budget >> 20
        )
        .into());
    }
    eprintln!(
        "animcodec: {input} ({v} vertices × {f} frames) is more than the sweep can hold whole within {} MiB: it \
         streams, each point encoded from the input as it is read and measured against a second read, one at a time",
        budget >> 20
    );
    Ok((kept, streamed))
}

/// `codec` on the parameters `pairs`, refusing to set the parameter its ladder walks.
fn series_on<'r>(codec: &'r dyn AnimationCodec, pairs: &[String]) -> CmdResult<SweepSeries<'r>> {
    let base = animcodec::front::params_from_text(codec, pairs)?;
    let walked = codec.rate_ladder(&base).param;
    if let Some(p) = pairs.iter().find(|p| p.split_once('=').is_some_and(|(k, _)| k.trim() == walked)) {
        return Err(
            format!("{}: '{p}' sets the parameter the sweep walks ({walked}); leave it out", codec.name()).into()
        );
    }
    Ok(SweepSeries::with_base(codec, base)?)
}

/// Shows a sweep's progress on `bar`: a phase sets the total and names itself in the prefix,
/// a started point's name becomes the message, a finished point advances it.
fn show_progress(bar: &Progress, event: harness::SweepEvent<'_>) {
    match event {
        harness::SweepEvent::Phase { phase, phases, name, points, total } => {
            bar.set_total(total as u64);
            bar.prefix(if phases > 1 {
                format!("sweep {phase}/{phases} {name} ({points})")
            } else {
                "sweep".to_owned()
            });
        }
        harness::SweepEvent::Started { series, step } => bar.message(format!("{series} ladder step {step}")),
        harness::SweepEvent::Finished { .. } => bar.inc(1),
    }
}
