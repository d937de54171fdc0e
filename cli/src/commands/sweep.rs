//! `animcodec sweep`: walk every codec's rate ladder on one input, measure every point, print
//! a table and write JSON, CSV and an SVG rate-distortion plot.

use std::fmt::Write as _;
use std::io::IsTerminal;
use std::path::Path;
use std::time::Instant;

use crate::viewer;
use animcodec::formats::ReadOptions;
use animcodec::harness::{self, monotone_report, Point, Sweep, SweepDocument, SweepOptions, SweepSeries, TargetMetric};
use animcodec::output::{commit_all, OutputPolicy};
use animcodec::params::params_json;
use codec_core::{AnimationCodec, CodecRegistry, Limits};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use super::encode::parse_params;
use super::eval::{eval_options, load_any};
use super::{emit, emit_json, CmdResult};
use crate::SweepArgs;

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
    if let Some(t) = &args.topology {
        policy = policy.with_input(t);
    }
    let json_file = args.json.as_deref().filter(|p| p.as_os_str() != "-");
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
    let eval = eval_options(&args.metrics)?;
    let read = ReadOptions {
        topology: args.topology.clone(),
        frame_rate: None,
        animation: args.animation.clone(),
        object: args.object.clone(),
    };
    let animation = load_any(input, &read, limits)?;
    // The files the read opened (a .gltf's buffers, …) are inputs too: refused before the work.
    policy.check_all(&outputs)?;

    let options =
        SweepOptions { points: args.points.map(|n| n as usize), jobs: args.jobs.map(|n| n as usize), eval, limits };
    let total = if envelope_mode { 0 } else { harness::sweep_jobs(&series, options.points).len() as u64 };
    let bar = if std::io::stderr().is_terminal() {
        let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
        // ETA: indicatif's estimate from the points done so far (points differ in cost, so it
        // firms up as the sweep goes); the message names the point that started last.
        if let Ok(style) =
            ProgressStyle::with_template("{bar:30} {pos}/{len} {elapsed} (ETA {eta}) sweeping {prefix}: {msg}")
        {
            bar.set_style(style);
        }
        bar.set_prefix(input.to_string());
        bar.enable_steady_tick(std::time::Duration::from_millis(500));
        bar
    } else {
        ProgressBar::hidden()
    };
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
        harness::envelope_sweep(&registry, &codecs, &animation, &options, per_config, &|event| {
            show_progress(&bar, event)
        })?
    } else {
        harness::sweep(&registry, &series, &animation, &options, &|event| show_progress(&bar, event))?
    };
    let seconds = start.elapsed().as_secs_f64();
    bar.finish_and_clear();

    let to_stdout = args.json.as_deref().is_some_and(|p| p.as_os_str() == "-");
    // Every output is built and staged under its temporary name first, then all are renamed
    // together: a failure on the way leaves every old file untouched.
    let mut staged = Vec::new();
    let mut stage = |path: &Path, text: &str| -> CmdResult {
        staged.push(policy.stage(path, text.as_bytes())?);
        Ok(())
    };
    let dims = (animation.vertex_count(), animation.frame_count());
    let document = SweepDocument {
        total_seconds: Some(seconds),
        jobs: Some(options.jobs.map_or_else(|| "rayon".into(), |j| j.into())),
        ..SweepDocument::new(input, dims, &eval, &result)
    };
    if let Some(path) = args.json.as_ref().filter(|_| !to_stdout) {
        stage(path, &document.to_json_text()?)?;
    }
    if let Some(path) = &args.csv {
        stage(path, &harness::csv_text(&result.points)?)?;
    }
    if let Some(path) = &args.plot {
        let title = format!("{input}: {} frames × {} vertices", animation.frame_count(), animation.vertex_count());
        stage(path, &animcodec::plot::rd_svg(&title, &result.points))?;
    }
    if let Some(path) = &args.html {
        let page = html_report(&registry, input, &animation, &eval, &result, &view_points, limits)?;
        stage(path, &page)?;
    }
    commit_all(staged, &[])?;
    if to_stdout {
        emit_json(&document.to_json()?)?;
    } else {
        emit(&table(input, &animation, &result, seconds, envelope_mode))?;
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

/// The `--html` report: every row, the interactive plot, and a viewer per chosen point (its
/// stream re-encoded from the same parameters, which gives the same bytes, and decoded).
fn html_report(
    registry: &CodecRegistry,
    input: &str,
    animation: &codec_core::Animation,
    eval: &metrics::EvalOptions,
    sweep: &Sweep,
    view_points: &[(String, usize)],
    limits: Limits,
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
        let codec = registry.by_name(point.codec)?;
        let bytes = codec_core::encode_animation(codec, &point.params, animation)?;
        let decoded = codec_core::StreamDecoder::new(bytes.as_slice(), registry, limits)?.decode_all()?;
        let candidate = viewer::Candidate {
            label: format!("{name}:{index}"),
            animation: &decoded,
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
        viewers.push(viewer::viewer_data(animation, &[candidate], &options)?);
    }
    let dims = (animation.vertex_count(), animation.frame_count());
    let mut value = SweepDocument::new(input, dims, eval, sweep).to_json()?;
    value["title"] = format!("Rate-distortion report: {input}").into();
    value["viewers"] = viewers.into();
    Ok(viewer::report_page(&format!("animcodec sweep: {input}"), &value))
}

fn num(v: Option<f64>) -> String {
    v.map_or_else(|| "n/a".to_string(), |x| format!("{x:.4e}"))
}

fn table(input: &str, animation: &codec_core::Animation, sweep: &Sweep, seconds: f64, envelope_only: bool) -> String {
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
        "{input}: {} frames × {} vertices; {} points in {seconds:.2} s",
        animation.frame_count(),
        animation.vertex_count(),
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

/// `codec` on the parameters `pairs`, refusing to set the parameter its ladder walks.
fn series_on<'r>(codec: &'r dyn AnimationCodec, pairs: &[String]) -> CmdResult<SweepSeries<'r>> {
    let base = parse_params(codec, pairs)?;
    let walked = codec.rate_ladder(&base).param;
    if let Some(p) = pairs.iter().find(|p| p.split_once('=').is_some_and(|(k, _)| k.trim() == walked)) {
        return Err(
            format!("{}: '{p}' sets the parameter the sweep walks ({walked}); leave it out", codec.name()).into()
        );
    }
    Ok(SweepSeries::with_base(codec, base)?)
}

/// Shows a sweep's progress on `bar`: planned points extend it, a started point's name becomes
/// the message, a finished point advances it.
fn show_progress(bar: &ProgressBar, event: harness::SweepEvent<'_>) {
    match event {
        harness::SweepEvent::Planned(n) => bar.inc_length(n as u64),
        harness::SweepEvent::Started { series, step } => bar.set_message(format!("{series} ladder step {step}")),
        harness::SweepEvent::Finished { .. } => bar.inc(1),
    }
}
