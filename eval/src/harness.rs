//! The evaluation harness behind `animcodec eval`, `animcodec sweep` and
//! `animcodec encode --target`: rate-ladder sweeps, rate-distortion tables and plots, and
//! target-error search. Everything here works on in-memory [`Animation`]s so it can be tested
//! without the binary.
//!
//! * [`measure_point`] encodes one animation at one parameter set, decodes the stream (the
//!   decoder sees nothing but the bytes) and measures it with [`metrics::evaluate`].
//! * [`sweep`] walks the [`RateLadder`] of every chosen codec ([`ladder_indices`] picks the
//!   points), in parallel with rayon or sequentially (`jobs = 1`, for timing), and returns
//!   the rows sorted by codec then ladder position, whatever the scheduling.
//! * [`write_json`], [`write_csv`] and [`plot_svg`] write the rows; [`monotone_report`] checks
//!   that bpvf rises and the errors fall along each ladder.
//! * [`search_target`] finds the smallest stream of one codec that meets a [`Target`], and
//!   [`search_target_auto`] does it for several codecs and keeps the smallest.

use std::fmt;
use std::path::Path;
use std::str::FromStr;
use std::time::Instant;

use codec_core::{
    encode_animation_fed, Animation, AnimationCodec, CodecRegistry, Limits, ParamSet, ParamValue, RateLadder,
    StreamDecoder,
};
use metrics::{EvalOptions, MetricReport};
use rayon::prelude::*;
use serde_json::{json, Map, Value};

/// Errors of the harness: codec-core errors, I/O errors or plain messages.
pub type HarnessError = Box<dyn std::error::Error + Send + Sync>;

/// Result alias of the harness.
pub type HResult<T> = Result<T, HarnessError>;

/// Indices of `points` ladder steps spread evenly over a ladder of `len` steps, always
/// including both ends (`None`, or `points ≥ len`: every step). Sorted, without repeats.
pub fn ladder_indices(len: usize, points: Option<usize>) -> Vec<usize> {
    match points {
        _ if len == 0 => Vec::new(),
        None => (0..len).collect(),
        Some(n) if n >= len => (0..len).collect(),
        Some(0) => Vec::new(),
        Some(1) => vec![len - 1],
        Some(n) => {
            // Rounded positions i·(len−1)/(n−1); distinct because n < len.
            let mut v: Vec<usize> = (0..n).map(|i| (i * (len - 1) + (n - 1) / 2) / (n - 1)).collect();
            v.dedup();
            v
        }
    }
}

/// `base` with the ladder's parameter set to `step`, validated by the codec (so a step that
/// conflicts with a fixed parameter is an error naming both).
pub fn ladder_params(
    codec: &dyn AnimationCodec,
    base: &ParamSet,
    ladder: &RateLadder,
    step: usize,
) -> HResult<ParamSet> {
    let value = ladder.steps.get(step).ok_or_else(|| {
        format!(
            "{}: rate ladder step {step} does not exist (the ladder has {} steps)",
            codec.name(),
            ladder.steps.len()
        )
    })?;
    let params = base.clone().with(&codec.param_specs(), ladder.param, value.clone())?;
    codec.validate(&params)?;
    Ok(params)
}

/// One measured (codec, parameters) point.
#[derive(Debug, Clone)]
pub struct Point {
    /// Codec name.
    pub codec: &'static str,
    /// The curve this point belongs to: the codec name, or for a [`SweepSeries`] with
    /// non-default base parameters `codec[key=value,…]`.
    pub series: String,
    /// Parameters used.
    pub params: ParamSet,
    /// The ladder's parameter.
    pub ladder_param: &'static str,
    /// Position on the codec's rate ladder (0 = smallest stream).
    pub ladder_index: usize,
    /// Container size in bytes (header and topology included).
    pub bytes: u64,
    /// Bits per vertex per frame of the whole container.
    pub bpvf: f64,
    /// Every metric of the decoded animation against the input.
    pub report: MetricReport,
    /// Wall-clock encoding time.
    pub encode_seconds: f64,
    /// Wall-clock decoding time (from the container bytes alone).
    pub decode_seconds: f64,
}

impl Point {
    /// The ladder parameter's value.
    pub fn ladder_value(&self) -> Option<&ParamValue> {
        self.params.get(self.ladder_param)
    }
}

/// Encodes `animation` with `codec` at `params`, decodes it through the container and
/// measures it. Also returns the container bytes.
pub fn measure_point(
    registry: &CodecRegistry,
    codec: &dyn AnimationCodec,
    params: &ParamSet,
    (ladder_param, ladder_index): (&'static str, usize),
    animation: &Animation,
    eval: &EvalOptions,
    limits: Limits,
) -> HResult<(Point, Vec<u8>)> {
    let start = Instant::now();
    let encoded = encode_animation_fed(codec, params, animation, false, animation.frame_count())?;
    let bytes = encoded.bytes;
    let encode_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let decoded = StreamDecoder::new(bytes.as_slice(), registry, limits)?.decode_all()?;
    let decode_seconds = start.elapsed().as_secs_f64();
    // A stream that decodes to non-finite coordinates is garbage whatever its metrics say
    // (issue 26): never a measured point, so never chosen by a search.
    if decoded.positions().iter().any(|x| !x.is_finite()) {
        return Err(format!("{}: the stream decodes to non-finite coordinates", codec.name()).into());
    }
    let mut report = metrics::evaluate(animation, &decoded, eval)?;
    // The encoder's warnings (a fallback it took to stay within its bound, issue 26) travel with
    // the point, so a search's answer reports them as a plain encode does.
    report.notes.extend(encoded.notes.into_iter().map(|n| format!("encoder: {n}")));
    let size = bytes.len() as u64;
    let point = Point {
        codec: codec.name(),
        series: codec.name().to_string(),
        params: params.clone(),
        ladder_param,
        ladder_index,
        bytes: size,
        bpvf: metrics::bpvf(size, animation.vertex_count(), animation.frame_count())?,
        report,
        encode_seconds,
        decode_seconds,
    };
    Ok((point, bytes))
}

/// How [`sweep`] runs.
#[derive(Debug, Clone, Default)]
pub struct SweepOptions {
    /// Ladder points per codec, spread evenly (`None`: every step).
    pub points: Option<usize>,
    /// Points measured at once: `None` uses rayon's pool, `Some(1)` runs sequentially (for
    /// timing: parallel encodes compete for the cores), `Some(n)` a pool of `n` threads.
    pub jobs: Option<usize>,
    /// Metrics to compute.
    pub eval: EvalOptions,
    /// Decoder limits.
    pub limits: Limits,
}

/// A sweep point that failed, with the reason.
#[derive(Debug, Clone)]
pub struct Failure {
    /// Codec name.
    pub codec: &'static str,
    /// Curve name (see [`Point::series`]).
    pub series: String,
    /// Position on the ladder.
    pub ladder_index: usize,
    /// What went wrong.
    pub message: String,
}

/// Result of [`sweep`]: measured points sorted by codec (in the order given) then ladder
/// position, and the points that failed.
#[derive(Debug, Clone, Default)]
pub struct Sweep {
    /// Measured points.
    pub points: Vec<Point>,
    /// Points that could not be measured.
    pub failures: Vec<Failure>,
}

/// One curve of a sweep: a codec and the parameters its rate ladder is walked on.
#[derive(Clone)]
pub struct SweepSeries<'a> {
    /// The codec.
    pub codec: &'a dyn AnimationCodec,
    /// Parameters every ladder step starts from (the step then sets the ladder parameter).
    pub base: ParamSet,
    /// Curve name in tables, JSON and plots.
    pub label: String,
    /// Ladder positions to measure on this curve (`None`: the sweep's `points`, spread evenly).
    pub steps: Option<Vec<usize>>,
}

impl<'a> SweepSeries<'a> {
    /// The codec at its defaults, labelled with its name.
    pub fn defaults(codec: &'a dyn AnimationCodec) -> Self {
        Self { codec, base: codec.default_params(), label: codec.name().to_string(), steps: None }
    }

    /// The codec on `base`, labelled `codec[key=value,…]` with the parameters that differ from
    /// the defaults (just the codec name when none do). Fails if `base` does not validate.
    pub fn with_base(codec: &'a dyn AnimationCodec, base: ParamSet) -> HResult<Self> {
        codec.validate(&base)?;
        let defaults = codec.default_params();
        let changed: Vec<String> =
            base.iter().filter(|(n, v)| defaults.get(n) != Some(*v)).map(|(n, v)| format!("{n}={v}")).collect();
        let label = if changed.is_empty() {
            codec.name().to_string()
        } else {
            format!("{}[{}]", codec.name(), changed.join(","))
        };
        Ok(Self { codec, base, label, steps: None })
    }

    fn ladder(&self) -> RateLadder {
        self.codec.rate_ladder(&self.base)
    }
}

/// Walks the rate ladder of every series on `animation`. `progress` is called once per
/// finished point (from worker threads). Output order (series, then ladder step) does not
/// depend on scheduling.
pub fn sweep(
    registry: &CodecRegistry,
    series: &[SweepSeries<'_>],
    animation: &Animation,
    options: &SweepOptions,
    progress: &(dyn Fn() + Sync),
) -> HResult<Sweep> {
    let jobs = sweep_jobs(series, options.points);
    let run = |&(c, step): &(usize, usize)| -> (usize, usize, HResult<Point>) {
        let result = sweep_point(registry, &series[c], step, animation, options);
        progress();
        (c, step, result)
    };
    let mut results: Vec<(usize, usize, HResult<Point>)> = match options.jobs {
        Some(1) => jobs.iter().map(run).collect(),
        None => jobs.par_iter().map(run).collect(),
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map_err(|e| format!("cannot set up {n} sweep threads: {e}"))?
            .install(|| jobs.par_iter().map(run).collect()),
    };
    // `collect` keeps input order already; sorting states the contract explicitly.
    results.sort_by_key(|(c, step, _)| (*c, *step));
    let mut out = Sweep::default();
    for (c, step, r) in results {
        match r {
            Ok(p) => out.points.push(p),
            Err(e) => out.failures.push(Failure {
                codec: series[c].codec.name(),
                series: series[c].label.clone(),
                ladder_index: step,
                message: e.to_string(),
            }),
        }
    }
    Ok(out)
}

/// One sweep job: `entry` at step `step` of its rate ladder on `animation`, measured as
/// [`sweep`] measures each of its points (it calls this). Exposed so that other schedulers
/// (the Python package's Dask sweep runs one job per (input, series, step)) produce rows
/// identical to the command line's.
pub fn sweep_point(
    registry: &CodecRegistry,
    entry: &SweepSeries<'_>,
    step: usize,
    animation: &Animation,
    options: &SweepOptions,
) -> HResult<Point> {
    let ladder = entry.ladder();
    let params = ladder_params(entry.codec, &entry.base, &ladder, step)?;
    let (mut point, _) =
        measure_point(registry, entry.codec, &params, (ladder.param, step), animation, &options.eval, options.limits)?;
    point.series.clone_from(&entry.label);
    Ok(point)
}

/// A sweep row ([`point_json`]) back as a [`Point`], for writing rows gathered from elsewhere
/// (another process or machine) with [`sweep_json`], [`csv_text`] and [`plot_svg`]. The report
/// holds the row's metrics; what a row does not carry is filled from the arguments
/// (`sted_params` from `eval`, the counts) or left empty (`hausdorff_mean`, the relative MSE and
/// RMSE, `bbox_diagonal` = NaN, no notes), so [`point_json`] of the result equals `row`.
pub fn point_from_row(
    registry: &CodecRegistry,
    row: &Value,
    eval: &EvalOptions,
    (vertex_count, frame_count): (usize, usize),
) -> HResult<Point> {
    let field = |name: &str| row.get(name).ok_or_else(|| format!("sweep row: field '{name}' is missing"));
    let text = |name: &str| -> HResult<&str> {
        Ok(field(name)?.as_str().ok_or_else(|| format!("sweep row: '{name}' is not a string"))?)
    };
    let count = |name: &str| -> HResult<u64> {
        Ok(field(name)?.as_u64().ok_or_else(|| format!("sweep row: '{name}' is not a non-negative integer"))?)
    };
    let number = |name: &str| -> HResult<f64> {
        Ok(field(name)?.as_f64().ok_or_else(|| format!("sweep row: '{name}' is not a number"))?)
    };
    let metric = |name: &str| -> HResult<Option<f64>> {
        match field(name)? {
            Value::Null => Ok(None),
            v => Ok(Some(v.as_f64().ok_or_else(|| format!("sweep row: '{name}' is not a number or null"))?)),
        }
    };
    let codec = registry.by_name(text("codec")?)?;
    let specs = codec.param_specs();
    let mut params = codec.default_params();
    let Some(Value::Object(given)) = row.get("params") else {
        return Err("sweep row: 'params' is not an object".into());
    };
    for (name, value) in given {
        let spec = codec_core::params::find_spec(codec.name(), &specs, name)?;
        let value = match (&spec.kind, value) {
            (codec_core::ParamKind::Int { .. }, Value::Number(n)) if n.is_i64() => {
                ParamValue::Int(n.as_i64().unwrap_or(0))
            }
            (codec_core::ParamKind::Float { .. }, Value::Number(n)) => {
                ParamValue::Float(n.as_f64().unwrap_or(f64::NAN))
            }
            (codec_core::ParamKind::Bool, Value::Bool(b)) => ParamValue::Bool(*b),
            (codec_core::ParamKind::Choice(_), Value::String(s)) => spec.parse(codec.name(), s)?,
            _ => return Err(format!("sweep row: parameter '{name}' = {value} does not fit {}", spec.kind).into()),
        };
        params.set(&specs, spec.name, value)?;
    }
    let ladder_name = text("ladder_param")?;
    let ladder_param = codec_core::params::find_spec(codec.name(), &specs, ladder_name)?.name;
    let report = MetricReport {
        kg: metric("kg")?,
        sted: metric("sted")?,
        sted_spatial: metric("sted_spatial")?,
        sted_temporal: metric("sted_temporal")?,
        hausdorff: metric("hausdorff")?,
        hausdorff_mean: None,
        hausdorff_relative: metric("hausdorff_relative")?,
        hausdorff_mean_relative: None,
        hausdorff_mode: None,
        mse: number("mse")?,
        rmse: number("rmse")?,
        mse_relative: None,
        rmse_relative: None,
        max_error: number("max_error")?,
        sted_params: eval.sted,
        bbox_diagonal: f64::NAN,
        vertex_count,
        frame_count,
        notes: Vec::new(),
    };
    Ok(Point {
        codec: codec.name(),
        series: text("series")?.to_string(),
        params,
        ladder_param,
        ladder_index: usize::try_from(count("ladder_index")?)?,
        bytes: count("bytes")?,
        bpvf: number("bpvf")?,
        report,
        encode_seconds: number("encode_seconds")?,
        decode_seconds: number("decode_seconds")?,
    })
}

/// The (series position, ladder step) pairs a sweep measures.
pub fn sweep_jobs(series: &[SweepSeries<'_>], points: Option<usize>) -> Vec<(usize, usize)> {
    series
        .iter()
        .enumerate()
        .flat_map(|(c, entry)| {
            let steps = entry.steps.clone().unwrap_or_else(|| ladder_indices(entry.ladder().steps.len(), points));
            steps.into_iter().map(move |s| (c, s))
        })
        .collect()
}

/// The parameters as a JSON object.
pub fn params_json(params: &ParamSet) -> Value {
    let mut p = Map::new();
    for (name, value) in params.iter() {
        p.insert(
            name.into(),
            match value {
                ParamValue::Int(v) => Value::from(*v),
                ParamValue::Float(v) => Value::from(*v),
                ParamValue::Bool(v) => Value::from(*v),
                ParamValue::Choice(v) => Value::from(*v),
            },
        );
    }
    Value::Object(p)
}

/// Every metric of a report as JSON, keys named after the metrics (`kg`, `sted`, …,
/// `sted_params`, `notes`). Undefined metrics are `null`.
pub fn report_json(report: &MetricReport) -> Value {
    serde_json::to_value(report).unwrap_or(Value::Null)
}

/// One sweep row as JSON: `codec`, `series`, `params`, `ladder_param`, `ladder_index`, `bytes`, `bpvf`,
/// `kg`, `sted`, `sted_spatial`, `sted_temporal`, `hausdorff`, `hausdorff_relative`, `mse`,
/// `rmse`, `max_error`, `encode_seconds`, `decode_seconds`.
pub fn point_json(p: &Point) -> Value {
    let r = &p.report;
    json!({
        "codec": p.codec,
        "series": p.series,
        "params": params_json(&p.params),
        "ladder_param": p.ladder_param,
        "ladder_index": p.ladder_index,
        "bytes": p.bytes,
        "bpvf": p.bpvf,
        "kg": r.kg,
        "sted": r.sted,
        "sted_spatial": r.sted_spatial,
        "sted_temporal": r.sted_temporal,
        "hausdorff": r.hausdorff,
        "hausdorff_relative": r.hausdorff_relative,
        "mse": r.mse,
        "rmse": r.rmse,
        "max_error": r.max_error,
        "encode_seconds": p.encode_seconds,
        "decode_seconds": p.decode_seconds,
    })
}

/// Columns of [`write_csv`], in order (the same keys as [`point_json`]).
pub const CSV_COLUMNS: &[&str] = &[
    "codec",
    "series",
    "params",
    "ladder_index",
    "bytes",
    "bpvf",
    "kg",
    "sted",
    "sted_spatial",
    "sted_temporal",
    "hausdorff",
    "hausdorff_relative",
    "mse",
    "rmse",
    "max_error",
    "encode_seconds",
    "decode_seconds",
];

/// A series label holds commas (`pca-aoi[mode=baoi,tmax=2]`): quote it as RFC 4180 says.
fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

fn opt(v: Option<f64>) -> String {
    v.map(|x| format!("{x}")).unwrap_or_default()
}

/// The rows as CSV: a header line of [`CSV_COLUMNS`], then one line per point. `params` is
/// `key=value` pairs separated by `;` (so the field needs no quoting); a missing metric is an
/// empty field.
pub fn csv_text(points: &[Point]) -> String {
    let mut out = CSV_COLUMNS.join(",");
    out.push('\n');
    for p in points {
        let r = &p.report;
        let params: Vec<String> = p.params.iter().map(|(n, v)| format!("{n}={v}")).collect();
        let fields = [
            p.codec.to_string(),
            csv_field(&p.series),
            params.join(";"),
            p.ladder_index.to_string(),
            p.bytes.to_string(),
            format!("{}", p.bpvf),
            opt(r.kg),
            opt(r.sted),
            opt(r.sted_spatial),
            opt(r.sted_temporal),
            opt(r.hausdorff),
            opt(r.hausdorff_relative),
            format!("{}", r.mse),
            format!("{}", r.rmse),
            format!("{}", r.max_error),
            format!("{}", p.encode_seconds),
            format!("{}", p.decode_seconds),
        ];
        out.push_str(&fields.join(","));
        out.push('\n');
    }
    out
}

/// Monotonicity of one codec's curve along its ladder.
#[derive(Debug, Clone, PartialEq)]
pub struct Monotonicity {
    /// Curve name (see [`Point::series`]).
    pub series: String,
    /// bpvf never falls from one ladder point to the next.
    pub bpvf_increasing: bool,
    /// KG never rises (beyond a relative 1e-9) from one ladder point to the next.
    pub kg_decreasing: bool,
    /// STED never rises (same tolerance).
    pub sted_decreasing: bool,
    /// Ladder indices where one of the above fails (the later point of each bad pair).
    pub violations: Vec<usize>,
}

/// Checks every series' curve in sorted `points` (as [`sweep`] returns them). Metric values
/// that are missing are skipped. The tolerance absorbs float noise only.
pub fn monotone_report(points: &[Point]) -> Vec<Monotonicity> {
    let mut out: Vec<Monotonicity> = Vec::new();
    for pair in points.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        if a.series != b.series {
            continue;
        }
        let not_above = |x: Option<f64>, y: Option<f64>| match (x, y) {
            (Some(x), Some(y)) => y <= x + 1e-9 * x.abs().max(y.abs()),
            _ => true,
        };
        let bpvf_ok = b.bpvf >= a.bpvf;
        let kg_ok = not_above(a.report.kg, b.report.kg);
        let sted_ok = not_above(a.report.sted, b.report.sted);
        let m = match out.iter_mut().find(|m| m.series == a.series) {
            Some(m) => m,
            None => {
                out.push(Monotonicity {
                    series: a.series.clone(),
                    bpvf_increasing: true,
                    kg_decreasing: true,
                    sted_decreasing: true,
                    violations: Vec::new(),
                });
                out.last_mut().expect("just pushed")
            }
        };
        m.bpvf_increasing &= bpvf_ok;
        m.kg_decreasing &= kg_ok;
        m.sted_decreasing &= sted_ok;
        if !(bpvf_ok && kg_ok && sted_ok) {
            m.violations.push(b.ladder_index);
        }
    }
    out
}

/// Writes `text` to `path` (replacing it) through a temporary file renamed into place when
/// complete, naming the file in the error. Callers check first whether `path` may be replaced
/// ([`OutputPolicy::check`](animcodec_io::output::OutputPolicy::check)).
pub fn write_text(path: &Path, text: &str) -> HResult<()> {
    Ok(animcodec_io::output::OutputPolicy::new(true).write(path, text.as_bytes())?)
}

/// Writes the sweep as JSON: `{input, vertices, frames, eval_options, rows: [point_json…],
/// failures: [{codec, ladder_index, error}], monotone: [{codec, bpvf_increasing, kg_decreasing,
/// sted_decreasing, violations}]}`.
pub fn sweep_json(input: &str, animation: &Animation, eval: &EvalOptions, sweep: &Sweep) -> Value {
    sweep_json_sized(input, (animation.vertex_count(), animation.frame_count()), eval, sweep)
}

/// [`sweep_json`] given the input's `(vertices, frames)` instead of the animation (for rows
/// gathered from other processes, see [`point_from_row`]).
pub fn sweep_json_sized(input: &str, (vertices, frames): (usize, usize), eval: &EvalOptions, sweep: &Sweep) -> Value {
    json!({
        "input": input,
        "vertices": vertices,
        "frames": frames,
        "eval_options": serde_json::to_value(eval).unwrap_or(Value::Null),
        "rows": sweep.points.iter().map(point_json).collect::<Vec<_>>(),
        "failures": sweep.failures.iter().map(|f| json!({
            "codec": f.codec, "series": f.series, "ladder_index": f.ladder_index, "error": f.message,
        })).collect::<Vec<_>>(),
        "monotone": monotone_report(&sweep.points).iter().map(|m| json!({
            "series": m.series,
            "bpvf_increasing": m.bpvf_increasing,
            "kg_decreasing": m.kg_decreasing,
            "sted_decreasing": m.sted_decreasing,
            "violations": m.violations,
        })).collect::<Vec<_>>(),
        // Row positions on each codec's lower envelope (sorted by bytes, error below every
        // smaller stream of the codec), by KG and by STED.
        "envelope": {
            "kg": envelope(&sweep.points, TargetMetric::Kg),
            "sted": envelope(&sweep.points, TargetMetric::Sted),
        },
    })
}

/// Writes the rate-distortion plot of `points` ([`crate::plot::rd_svg`]) to `path`.
pub fn plot_svg(path: &Path, title: &str, points: &[Point]) -> HResult<()> {
    write_text(path, &crate::plot::rd_svg(title, points))
}

/// The metric a [`Target`] bounds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TargetMetric {
    /// KG error in percent.
    Kg,
    /// STED (combined).
    Sted,
    /// Largest per-frame Hausdorff distance (absolute, model units).
    Hausdorff,
    /// Largest vertex displacement (absolute).
    MaxError,
    /// Root mean square vertex displacement (absolute).
    Rmse,
}

impl TargetMetric {
    /// Every metric with its command-line name.
    pub const ALL: [(TargetMetric, &'static str); 5] = [
        (TargetMetric::Kg, "kg"),
        (TargetMetric::Sted, "sted"),
        (TargetMetric::Hausdorff, "hausdorff"),
        (TargetMetric::MaxError, "max_error"),
        (TargetMetric::Rmse, "rmse"),
    ];

    /// Command-line name (also the JSON key of the metric).
    pub fn name(self) -> &'static str {
        Self::ALL.iter().find(|(m, _)| *m == self).map(|(_, n)| *n).unwrap_or("?")
    }

    /// The metric's value in `report` (`None` when undefined or not computed).
    pub fn value(self, report: &MetricReport) -> Option<f64> {
        match self {
            TargetMetric::Kg => report.kg,
            TargetMetric::Sted => report.sted,
            TargetMetric::Hausdorff => report.hausdorff,
            TargetMetric::MaxError => Some(report.max_error),
            TargetMetric::Rmse => Some(report.rmse),
        }
    }

    /// Evaluation options computing this metric and skipping the expensive ones it does not
    /// need (STED parameters from `base`).
    pub fn eval_options(self, base: &EvalOptions) -> EvalOptions {
        EvalOptions {
            sted: base.sted,
            compute_sted: self == TargetMetric::Sted,
            compute_hausdorff: self == TargetMetric::Hausdorff,
        }
    }
}

/// An error target such as `kg=0.5`: the decoded animation must have `metric ≤ value`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Target {
    /// Metric bounded.
    pub metric: TargetMetric,
    /// Largest acceptable value.
    pub value: f64,
}

impl fmt::Display for Target {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}={}", self.metric.name(), self.value)
    }
}

impl FromStr for Target {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        let names: Vec<&str> = TargetMetric::ALL.iter().map(|(_, n)| *n).collect();
        let (key, value) = text.split_once('=').ok_or_else(|| {
            format!("target '{text}' is not of the form METRIC=VALUE (metrics: {})", names.join(", "))
        })?;
        let key = key.trim().to_ascii_lowercase().replace('-', "_");
        let metric = TargetMetric::ALL
            .iter()
            .find(|(_, n)| *n == key)
            .map(|(m, _)| *m)
            .ok_or_else(|| format!("target '{text}': unknown metric '{key}' (metrics: {})", names.join(", ")))?;
        let value: f64 = value.trim().parse().map_err(|_| format!("target '{text}': '{value}' is not a number"))?;
        if !(value.is_finite() && value >= 0.0) {
            return Err(format!("target '{text}': the value must be finite and ≥ 0"));
        }
        Ok(Target { metric, value })
    }
}

/// What [`search_target`] found: the chosen point, its container bytes, and every point it
/// measured on the way (sorted by ladder position).
#[derive(Debug, Clone)]
pub struct TargetHit {
    /// The smallest stream found that meets the target.
    pub point: Point,
    /// Its container bytes.
    pub stream: Vec<u8>,
    /// Every point measured, by ladder position.
    pub tried: Vec<Point>,
    /// True when the measured errors were not monotone along the ladder and the search fell
    /// back to a linear scan below the binary search's answer.
    pub linear_fallback: bool,
    /// Candidates the search rejected (the codec failed, or the stream decoded to non-finite
    /// coordinates), one message each, in search order.
    pub rejected: Vec<String>,
}

/// Why [`search_target`] found nothing: no ladder point meets the target.
#[derive(Debug, Clone)]
pub struct TargetMiss {
    /// Codec name.
    pub codec: &'static str,
    /// The target.
    pub target: Target,
    /// The measured point with the smallest error (`None` if the metric was undefined at
    /// every point measured).
    pub best: Option<Point>,
    /// Why the candidates the codec refused were refused (its own advice, e.g. hosvd on one
    /// frame), distinct messages in search order.
    pub refused: Vec<String>,
}

impl TargetMiss {
    /// The miss of a search that measured `tried` and saw the codec refuse `rejected`: the
    /// point of smallest finite error, and the distinct refusals (each without the `codec
    /// [params]: ` prefix the space search gives a candidate's message, so one reason given at
    /// every candidate is listed once).
    pub fn new<'a>(
        codec: &'static str,
        target: Target,
        tried: impl Iterator<Item = &'a Point>,
        rejected: Vec<String>,
    ) -> Self {
        let best = tried
            .filter_map(|p| target.metric.value(&p.report).filter(|v| v.is_finite()).map(|v| (v, p)))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, p)| p.clone());
        let mut refused: Vec<String> = Vec::new();
        for message in rejected {
            let reason = message
                .strip_prefix(codec)
                .and_then(|rest| rest.strip_prefix(" ["))
                .and_then(|rest| rest.split_once("]: "))
                .map_or(message.as_str(), |(_, reason)| reason)
                .to_owned();
            if !refused.contains(&reason) {
                refused.push(reason);
            }
        }
        Self { codec, target, best, refused }
    }
}

impl fmt::Display for TargetMiss {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let m = self.target.metric;
        match self.best.as_ref().and_then(|b| m.value(&b.report).map(|v| (b, v))) {
            Some((b, v)) => write!(
                f,
                "{}: no rate-ladder point meets {}: the best reached is {}={v:.6} at [{}] ({} bytes, {:.4} bpvf)",
                self.codec,
                self.target,
                m.name(),
                b.params,
                b.bytes,
                b.bpvf
            ),
            None => write!(
                f,
                "{}: no rate-ladder point meets {}: {} is undefined for this input",
                self.codec,
                self.target,
                m.name()
            ),
        }?;
        // The codec's own reasons come last: they say what would work.
        if let Some(first) = self.refused.first() {
            write!(f, "; where the codec refused: {first}")?;
            if self.refused.len() > 1 {
                write!(f, " (and {} other reasons)", self.refused.len() - 1)?;
            }
        }
        Ok(())
    }
}

impl std::error::Error for TargetMiss {}

/// Finds the smallest stream `codec` makes of `animation` whose decoded error meets `target`,
/// walking the codec's rate ladder with the other parameters fixed at `base`.
///
/// Search: errors are assumed to fall along the ladder (small streams first). The top step is
/// measured first (if it misses, nothing can meet the target); then a binary search finds the
/// first passing step `k`, which leaves `k` measured as passing and `k − 1` (if any) as
/// failing. As a check near the answer, `k − 2` is measured as well (one extra point). If the
/// points measured are *not* monotone (a later step has a larger error than an earlier one,
/// beyond float noise; e.g. `k − 2` passes although `k − 1` fails), the assumption is broken,
/// so every step below `k` is measured too (a linear scan; ladders are short). Among all
/// passing points measured, the one with the fewest bytes wins (ties: lower ladder position).
/// A non-monotone stretch far below the answer that the binary search never touches can go
/// unnoticed: only a full scan would find it, and a full scan costs the whole ladder.
///
/// Ladders are coarse (hosvd's `ss` 0.9 → 0.85 can be the difference between just missing
/// and meeting the target with room to spare), so with `refine > 0` and a monotone ladder the
/// search then bisects the ladder parameter between the failing step `k − 1` and the passing
/// step `k` for up to `refine` more points (integers stop when the bracket closes; choices
/// cannot be refined). Refined points carry ladder index `k` and their exact value in
/// `params`. Only measured points are ever chosen, so the answer always meets the target.
///
/// Errors: invalid parameters or codec failures as errors; no passing point as [`TargetMiss`].
#[allow(clippy::too_many_arguments)]
pub fn search_target(
    registry: &CodecRegistry,
    codec: &dyn AnimationCodec,
    base: &ParamSet,
    animation: &Animation,
    target: Target,
    eval: &EvalOptions,
    limits: Limits,
    refine: usize,
) -> HResult<TargetHit> {
    search_target_with_progress(registry, codec, base, animation, target, eval, limits, refine, &|_| {})
}

/// [`search_target`] that calls `progress` with every point as soon as it is measured (a
/// search on real data runs for minutes; the CLI shows the latest point).
#[allow(clippy::too_many_arguments)]
pub fn search_target_with_progress(
    registry: &CodecRegistry,
    codec: &dyn AnimationCodec,
    base: &ParamSet,
    animation: &Animation,
    target: Target,
    eval: &EvalOptions,
    limits: Limits,
    refine: usize,
    progress: &dyn Fn(&Point),
) -> HResult<TargetHit> {
    let ladder = codec.rate_ladder(base);
    let n = ladder.steps.len();
    let eval = target.metric.eval_options(eval);
    let mut measured: Vec<Option<(Point, Vec<u8>)>> = vec![None; n];
    let measure = |i: usize, measured: &mut Vec<Option<(Point, Vec<u8>)>>| -> HResult<bool> {
        if measured[i].is_none() {
            let params = ladder_params(codec, base, &ladder, i)?;
            let (point, bytes) = measure_point(registry, codec, &params, (ladder.param, i), animation, &eval, limits)?;
            progress(&point);
            measured[i] = Some((point, bytes));
        }
        let p = &measured[i].as_ref().expect("measured above").0;
        Ok(usable(p) && meets(target, p))
    };
    let miss = |measured: &[Option<(Point, Vec<u8>)>]| -> HarnessError {
        let best = measured
            .iter()
            .flatten()
            .filter_map(|(p, _)| target.metric.value(&p.report).map(|v| (v, p)))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, p)| p.clone());
        Box::new(TargetMiss { codec: codec.name(), target, best, refused: Vec::new() })
    };
    if n == 0 {
        return Err(format!("{}: the rate ladder is empty", codec.name()).into());
    }
    if !measure(n - 1, &mut measured)? {
        return Err(miss(&measured));
    }
    let (mut lo, mut hi) = (0, n - 1);
    while lo < hi {
        let mid = (lo + hi) / 2;
        if measure(mid, &mut measured)? {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    let k = hi;
    // Check one more point near the answer: `k − 1` failed, so with a monotone ladder `k − 2`
    // fails too. If it passes, the ladder is not monotone here.
    if k >= 2 {
        measure(k - 2, &mut measured)?;
    }
    let values: Vec<f64> =
        measured.iter().flatten().map(|(p, _)| target.metric.value(&p.report).unwrap_or(f64::INFINITY)).collect();
    let monotone = values.windows(2).all(|w| w[1] <= w[0] + 1e-9 * w[0].abs().max(w[1].abs()) || w[0].is_infinite());
    if !monotone {
        for i in 0..k {
            measure(i, &mut measured)?;
        }
    }
    // Degenerate reconstructions (KG > 50 %) never meet a target, whatever the metric says.
    let passes = |p: &Point| usable(p) && meets(target, p);
    let mut tried: Vec<(Point, Vec<u8>)> = measured.into_iter().flatten().collect();
    if monotone && k >= 1 {
        let (mut fail, mut pass) = (ladder.steps[k - 1].clone(), ladder.steps[k].clone());
        let specs = codec.param_specs();
        for _ in 0..refine {
            let Some(mid) = midpoint(&fail, &pass) else { break };
            let Ok(params) = base.clone().with(&specs, ladder.param, mid.clone()) else { break };
            if codec.validate(&params).is_err() {
                break;
            }
            let (point, bytes) = measure_point(registry, codec, &params, (ladder.param, k), animation, &eval, limits)?;
            progress(&point);
            if passes(&point) {
                pass = mid;
            } else {
                fail = mid;
            }
            tried.push((point, bytes));
        }
    }
    let best = tried
        .iter()
        .filter(|(p, _)| passes(p))
        .min_by_key(|(p, _)| (p.bytes, p.ladder_index))
        .cloned()
        .expect("the top step passed");
    Ok(TargetHit {
        point: best.0,
        stream: best.1,
        tried: tried.into_iter().map(|(p, _)| p).collect(),
        linear_fallback: !monotone,
        rejected: Vec::new(),
    })
}

/// The value halfway between two ladder values, or `None` when there is nothing in between
/// (adjacent integers, equal values, choices, booleans).
fn midpoint(a: &ParamValue, b: &ParamValue) -> Option<ParamValue> {
    match (a, b) {
        (ParamValue::Int(a), ParamValue::Int(b)) if a.abs_diff(*b) > 1 => Some(ParamValue::Int(a + (b - a) / 2)),
        (ParamValue::Float(a), ParamValue::Float(b)) if a != b => {
            // Rounded to two digits below the bracket's width, so values read like 0.8969
            // rather than 0.8968750000000001; stop once rounding reaches an end.
            let unit = 10f64.powf(((b - a).abs().log10() - 2.0).floor());
            let mid = ((a + (b - a) / 2.0) / unit).round() * unit;
            let mid = format!("{mid:.12}").parse::<f64>().unwrap_or(mid);
            (mid.is_finite() && mid != *a && mid != *b).then_some(ParamValue::Float(mid))
        }
        _ => None,
    }
}

/// [`search_target`] for every codec in `codecs` (each at its default parameters), keeping
/// the smallest stream (ties: the earlier codec). Codecs that cannot meet the target are
/// skipped; if none can, the error lists each codec's best. Other codec failures are errors.
pub fn search_target_auto(
    registry: &CodecRegistry,
    codecs: &[&dyn AnimationCodec],
    animation: &Animation,
    target: Target,
    eval: &EvalOptions,
    limits: Limits,
    refine: usize,
) -> HResult<(TargetHit, Vec<TargetHit>)> {
    search_target_auto_with_progress(registry, codecs, animation, target, eval, limits, refine, &|_| {})
}

/// [`search_target_auto`] that calls `progress` with every point as soon as it is measured.
#[allow(clippy::too_many_arguments)]
pub fn search_target_auto_with_progress(
    registry: &CodecRegistry,
    codecs: &[&dyn AnimationCodec],
    animation: &Animation,
    target: Target,
    eval: &EvalOptions,
    limits: Limits,
    refine: usize,
    progress: &dyn Fn(&Point),
) -> HResult<(TargetHit, Vec<TargetHit>)> {
    smallest_over_codecs(codecs, target, |codec| {
        let base = codec.default_params();
        search_target_with_progress(registry, codec, &base, animation, target, eval, limits, refine, progress)
    })
}

/// Runs `search` for every codec in order and keeps the smallest stream (ties: the earlier
/// codec); codecs that miss the target are skipped, and if all do, the error lists each one's
/// miss. Other failures are errors.
fn smallest_over_codecs(
    codecs: &[&dyn AnimationCodec],
    target: Target,
    mut search: impl FnMut(&dyn AnimationCodec) -> HResult<TargetHit>,
) -> HResult<(TargetHit, Vec<TargetHit>)> {
    let mut hits = Vec::new();
    let mut misses = Vec::new();
    for &codec in codecs {
        match search(codec) {
            Ok(hit) => hits.push(hit),
            Err(e) => match e.downcast::<TargetMiss>() {
                Ok(miss) => misses.push(miss.to_string()),
                Err(e) => return Err(format!("{}: {e}", codec.name()).into()),
            },
        }
    }
    let best = hits
        .iter()
        .enumerate()
        .min_by_key(|(i, h)| (h.point.bytes, *i))
        .map(|(i, _)| i)
        .ok_or_else(|| format!("no codec meets {target}: {}", misses.join("; ")))?;
    let chosen = hits.remove(best);
    Ok((chosen, hits))
}

/// Errors that mark the part of a rate-distortion curve the envelope sweep looks at closely:
/// KG 0.05–4 % or STED 0.01–0.2 (the targets of the issues and the README tables, with room).
const ENVELOPE_KG: (f64, f64) = (0.05, 4.0);
const ENVELOPE_STED: (f64, f64) = (0.01, 0.2);

/// The default sweep: each codec's lower envelope over its declared search space
/// ([`AnimationCodec::search_space`] on `base`, minus the `fixed` parameters). First every
/// codec's first configuration on its whole ladder (the points of today's single-axis sweep,
/// `options.points` applies), then every other configuration at `per_config` ladder positions
/// spread evenly over the positions where the first configuration's KG or STED fell in the
/// range the targets live in (every position if none did). Curves are labelled
/// `codec[key=value,…]`; [`envelope`] picks the points on the lower envelope. Results are in
/// a fixed order (the first phase's series, then the others) whatever the scheduling.
pub fn envelope_sweep<'a>(
    registry: &CodecRegistry,
    codecs: &[(&'a dyn AnimationCodec, ParamSet, Vec<&'static str>)],
    animation: &Animation,
    options: &SweepOptions,
    per_config: usize,
    progress: &(dyn Fn(usize) + Sync),
) -> HResult<Sweep> {
    let mut first = Vec::new();
    let mut rest: Vec<Vec<SweepSeries<'a>>> = Vec::new();
    for (codec, base, fixed) in codecs {
        let specs = codec.param_specs();
        let space = codec.search_space(base).without(fixed);
        let mut series: Vec<SweepSeries<'a>> = space
            .configurations()
            .iter()
            .filter_map(|config| {
                let params = codec_core::SearchSpace::apply(base, &specs, config).ok()?;
                SweepSeries::with_base(*codec, params).ok()
            })
            .collect();
        if series.is_empty() {
            return Err(format!("{}: no configuration of the search space validates", codec.name()).into());
        }
        first.push(series.remove(0));
        rest.push(series);
    }
    progress(sweep_jobs(&first, options.points).len());
    let mut result = sweep(registry, &first, animation, options, &|| progress(0))?;
    let mut second = Vec::new();
    for (head, others) in first.iter().zip(rest) {
        let curve: Vec<&Point> = result.points.iter().filter(|p| p.series == head.label).collect();
        let within = |v: Option<f64>, (lo, hi): (f64, f64)| v.is_some_and(|v| v >= lo && v <= hi);
        let mut region: Vec<usize> = curve
            .iter()
            .filter(|p| within(p.report.kg, ENVELOPE_KG) || within(p.report.sted, ENVELOPE_STED))
            .map(|p| p.ladder_index)
            .collect();
        region.sort_unstable();
        region.dedup();
        for mut s in others {
            let positions = if region.is_empty() { (0..s.ladder().steps.len()).collect() } else { region.clone() };
            let picked = ladder_indices(positions.len(), Some(per_config)).into_iter().map(|i| positions[i]).collect();
            s.steps = Some(picked);
            second.push(s);
        }
    }
    progress(sweep_jobs(&second, options.points).len());
    let more = sweep(registry, &second, animation, options, &|| progress(0))?;
    result.points.extend(more.points);
    result.failures.extend(more.failures);
    Ok(result)
}

/// Positions in `points` of each codec's lower envelope by `metric`: sorted by bytes, the
/// points whose error is below that of every smaller stream of the same codec (points that are
/// not [`usable`] left out). In input order.
pub fn envelope(points: &[Point], metric: TargetMetric) -> Vec<usize> {
    let mut order: Vec<usize> =
        (0..points.len()).filter(|&i| metric.value(&points[i].report).is_some() && usable(&points[i])).collect();
    order.sort_by_key(|&i| (points[i].codec, points[i].bytes, i));
    let mut keep = Vec::new();
    let mut last: Option<(&str, f64)> = None;
    for i in order {
        let v = metric.value(&points[i].report).unwrap_or(f64::INFINITY);
        let better = match last {
            Some((codec, best)) if codec == points[i].codec => v < best,
            _ => v.is_finite(),
        };
        if better {
            last = Some((points[i].codec, v));
            keep.push(i);
        }
    }
    keep.sort_unstable();
    keep
}

/// A reconstruction whose KG exceeds this (in %) is not a usable animation, whatever its
/// STED or Hausdorff distance: on samba hosvd at `ss=0.998` decodes to KG 233 % with STED
/// 0.00023 (a nearly rigid reconstruction STED cannot see; issue 15 session 5 met the same on
/// chicken-crossing). Such points never meet a target and are left out of the envelopes.
pub const DEGENERATE_KG: f64 = 50.0;

/// Whether `p` is a usable reconstruction (KG, when measured, at most [`DEGENERATE_KG`]).
pub fn usable(p: &Point) -> bool {
    p.report.kg.is_none_or(|kg| kg.is_finite() && kg <= DEGENERATE_KG)
}

fn meets(target: Target, p: &Point) -> bool {
    target.metric.value(&p.report).is_some_and(|v| v.is_finite() && v <= target.value)
}

/// The quality every command aims at when given neither parameters nor a target: KG ≤ 0.5 %
/// (see the README's "Quality by default" and `docs/notes/issue-26-rate-control.md` for the
/// measurements behind the choice).
pub const DEFAULT_TARGET: Target = Target { metric: TargetMetric::Kg, value: 0.5 };

/// How far below [`DEFAULT_TARGET`] a codec's own defaults may land and still be the default
/// encode's answer: a first encode whose error lies in `[target / band, target]` is kept as it
/// is. A factor of 3 keeps the default quality within 3× across inputs (issue 26: the largest
/// KG at most 3× the smallest over one character's clips) while most inputs cost one encode.
pub const DEFAULT_QUALITY_BAND: f64 = 3.0;

/// Once the default encode has searched, it refines between two ladder steps while its answer
/// is more than this factor below [`DEFAULT_TARGET`] (a stream at a third of the target error
/// can be half again too large; within 1.25× the next encode buys little).
pub const DEFAULT_REFINE_BAND: f64 = 1.25;

/// The default encode (no parameters, no target): one encode at the codec's defaults, kept
/// when its error lies within [`DEFAULT_QUALITY_BAND`] of [`DEFAULT_TARGET`]. Otherwise (a
/// short clip the codec's size model overshoots, a smooth one it undershoots) the search
/// starts from there: it gallops along the rate ladder towards the target (1, 2, 4 … steps),
/// bisects the bracket it finds, and refines between the two ladder steps up to `refine`
/// times while the answer is more than [`DEFAULT_REFINE_BAND`] below the target. Typically
/// one to four encodes; the whole declared parameter space ([`search_space_target`]) is for an
/// explicit `--target`, where tens of encodes buy smaller streams.
#[allow(clippy::too_many_arguments)]
pub fn search_default_quality(
    registry: &CodecRegistry,
    codec: &dyn AnimationCodec,
    animation: &Animation,
    eval: &EvalOptions,
    limits: Limits,
    refine: usize,
    progress: &dyn Fn(&Point),
) -> HResult<TargetHit> {
    let target = DEFAULT_TARGET;
    let eval = target.metric.eval_options(eval);
    let base = codec.default_params();
    let ladder = codec.rate_ladder(&base);
    let n = ladder.steps.len();
    if n == 0 {
        return Err(format!("{}: the rate ladder is empty", codec.name()).into());
    }
    let start = ladder.steps.iter().position(|v| base.get(ladder.param) == Some(v));
    let mut tried: Vec<(Point, Vec<u8>)> = Vec::new();
    let mut rejected: Vec<String> = Vec::new();
    // Measures `params` (at ladder position `index`); true when it meets the target. A codec
    // refusal counts as a miss and its reason is kept (hosvd's one-frame advice, say).
    let measure = |params: &ParamSet,
                   index: usize,
                   tried: &mut Vec<(Point, Vec<u8>)>,
                   rejected: &mut Vec<String>|
     -> HResult<bool> {
        match measure_point(registry, codec, params, (ladder.param, index), animation, &eval, limits) {
            Ok((point, stream)) => {
                progress(&point);
                let pass = usable(&point) && meets(target, &point);
                tried.push((point, stream));
                Ok(pass)
            }
            Err(e) => {
                rejected.push(e.to_string());
                Ok(false)
            }
        }
    };
    let at = |i: usize| ladder_params(codec, &base, &ladder, i);
    // The codec's defaults first (they are a ladder step for every registered codec; if not,
    // the middle of the ladder).
    let first = start.unwrap_or(n / 2);
    let first_pass = measure(&base, first, &mut tried, &mut rejected)?;
    let in_band = |p: &Point| target.metric.value(&p.report).is_some_and(|v| v >= target.value / DEFAULT_QUALITY_BAND);
    if first_pass && tried.last().is_some_and(|(p, _)| in_band(p)) {
        let (point, stream) = tried.pop().expect("measured above");
        return Ok(TargetHit { tried: vec![point.clone()], point, stream, linear_fallback: false, rejected });
    }
    // Gallop towards the target: up the ladder (larger streams) after a miss, down after a
    // pass far below the target, until the outcome flips or the ladder ends.
    let (mut fail, mut pass): (Option<usize>, Option<usize>) =
        if first_pass { (None, Some(first)) } else { (Some(first), None) };
    let mut stride = 1;
    loop {
        let next =
            if first_pass { pass.map(|p| p.saturating_sub(stride)) } else { fail.map(|f| (f + stride).min(n - 1)) };
        let Some(i) = next.filter(|&i| Some(i) != fail && Some(i) != pass) else { break };
        if measure(&at(i)?, i, &mut tried, &mut rejected)? {
            pass = Some(i);
            if !first_pass {
                break;
            }
        } else {
            fail = Some(i);
            if first_pass {
                break;
            }
        }
        stride *= 2;
    }
    // Bisect the ladder bracket to adjacent steps.
    if let (Some(mut f), Some(mut p)) = (fail, pass) {
        while f.abs_diff(p) > 1 {
            let mid = (f + p) / 2;
            if measure(&at(mid)?, mid, &mut tried, &mut rejected)? {
                p = mid;
            } else {
                f = mid;
            }
        }
        // Between the two steps, while the answer is far below the target.
        let (mut fail_value, mut pass_value) = (ladder.steps[f].clone(), ladder.steps[p].clone());
        let specs = codec.param_specs();
        for _ in 0..refine {
            let far_below = tried
                .iter()
                .filter(|(pt, _)| usable(pt) && meets(target, pt))
                .min_by_key(|(pt, _)| pt.bytes)
                .is_some_and(|(pt, _)| {
                    target.metric.value(&pt.report).is_some_and(|v| v < target.value / DEFAULT_REFINE_BAND)
                });
            let Some(mid) = midpoint(&fail_value, &pass_value).filter(|_| far_below) else { break };
            let Ok(params) = base.clone().with(&specs, ladder.param, mid.clone()) else { break };
            if codec.validate(&params).is_err() {
                break;
            }
            if measure(&params, p, &mut tried, &mut rejected)? {
                pass_value = mid;
            } else {
                fail_value = mid;
            }
        }
    }
    let best = tried.iter().filter(|(p, _)| usable(p) && meets(target, p)).min_by_key(|(p, _)| p.bytes).cloned();
    match best {
        Some((point, stream)) => Ok(TargetHit {
            point,
            stream,
            tried: tried.into_iter().map(|(p, _)| p).collect(),
            linear_fallback: false,
            rejected,
        }),
        None => Err(Box::new(TargetMiss::new(codec.name(), target, tried.iter().map(|(p, _)| p), rejected))),
    }
}

/// One candidate of a space search: its ladder position and what measuring it gave (the
/// point and stream, or why it was rejected).
struct Candidate {
    index: usize,
    outcome: Result<(Point, Vec<u8>), String>,
}

/// One configuration of the secondary axes as searched: its parameters, ladder and
/// candidates in measuring order, the lowest passing ladder position and the highest failing
/// one below it.
struct ConfigRun {
    params: ParamSet,
    ladder: RateLadder,
    candidates: Vec<Candidate>,
    pass: Option<usize>,
    fail_below: Option<usize>,
}

/// What a space search needs for every measurement.
struct SpaceSearcher<'a> {
    registry: &'a CodecRegistry,
    codec: &'a dyn AnimationCodec,
    animation: &'a Animation,
    target: Target,
    eval: EvalOptions,
    limits: Limits,
    progress: &'a (dyn Fn(&Point) + Sync),
}

impl SpaceSearcher<'_> {
    fn measure(&self, params: &ParamSet, ladder_param: &'static str, index: usize) -> Candidate {
        let outcome = measure_point(
            self.registry,
            self.codec,
            params,
            (ladder_param, index),
            self.animation,
            &self.eval,
            self.limits,
        )
        .map_err(|e| format!("{} [{params}]: {e}", self.codec.name()));
        if let Ok((p, _)) = &outcome {
            (self.progress)(p);
        }
        Candidate { index, outcome }
    }

    fn passes(&self, c: &Candidate) -> bool {
        c.outcome.as_ref().is_ok_and(|(p, _)| usable(p) && meets(self.target, p))
    }

    fn step(&self, run: &ConfigRun, index: usize) -> HResult<ParamSet> {
        ladder_params(self.codec, &run.params, &run.ladder, index)
    }

    /// Measures ladder position `index` of `run` (once) and says whether it meets the target.
    fn visit(&self, run: &mut ConfigRun, index: usize) -> HResult<bool> {
        if let Some(c) = run.candidates.iter().find(|c| c.index == index) {
            return Ok(self.passes(c));
        }
        let params = self.step(run, index)?;
        let c = self.measure(&params, run.ladder.param, index);
        let pass = self.passes(&c);
        run.candidates.push(c);
        Ok(pass)
    }

    fn bytes_at(run: &ConfigRun, index: usize) -> Option<u64> {
        run.candidates.iter().find(|c| c.index == index).and_then(|c| c.outcome.as_ref().ok()).map(|(p, _)| p.bytes)
    }

    /// The first configuration, searched cold: a binary search for the first passing step.
    /// The top step (the largest, slowest stream) is measured only if nothing below it
    /// passes; if it misses too, nothing on this ladder meets the target.
    fn search_cold(&self, run: &mut ConfigRun) -> HResult<()> {
        let n = run.ladder.steps.len();
        if n == 0 {
            return Ok(());
        }
        let (mut lo, mut hi) = (0, n - 1);
        while lo < hi {
            let mid = (lo + hi) / 2;
            if self.visit(run, mid)? {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        if !self.visit(run, hi)? {
            return Ok(());
        }
        run.pass = Some(hi);
        run.fail_below = hi.checked_sub(1);
        Ok(())
    }

    /// Another configuration, warm-started at `start` (the first configuration's answer;
    /// neighbouring configurations land on nearby steps): down while it passes, or up until it
    /// passes. Early stop: going up, a failing step whose stream already has `bound` bytes or
    /// more (the smallest passing stream found so far) ends the walk, since every larger step
    /// makes a larger stream.
    fn search_warm(&self, run: &mut ConfigRun, start: usize, bound: Option<u64>) -> HResult<()> {
        let n = run.ladder.steps.len();
        if n == 0 {
            return Ok(());
        }
        let mut i = start.min(n - 1);
        if self.visit(run, i)? {
            while i > 0 && self.visit(run, i - 1)? {
                i -= 1;
            }
            run.pass = Some(i);
            run.fail_below = i.checked_sub(1);
            return Ok(());
        }
        loop {
            let over = matches!((bound, Self::bytes_at(run, i)), (Some(b), Some(x)) if x >= b);
            if over || i + 1 >= n {
                return Ok(());
            }
            i += 1;
            if self.visit(run, i)? {
                run.pass = Some(i);
                run.fail_below = Some(i - 1);
                return Ok(());
            }
        }
    }

    /// Refines the ladder parameter between the failing step below the answer and the
    /// answer, up to `refine` points (ladders are coarse): each point by the secant in
    /// log(error) (errors fall about exponentially along a rate axis), aimed just under the
    /// target and kept inside the middle 70% of the bracket so it always shrinks (bisection
    /// when the secant is undefined). Stops early once a passing point is within
    /// [`REFINE_CLOSE`] of the target (the stream cannot get much smaller). Refined points
    /// carry the answer's index.
    fn refine(&self, run: &mut ConfigRun, refine: usize) {
        let (Some(k), Some(f)) = (run.pass, run.fail_below) else { return };
        if f + 1 != k {
            return;
        }
        let value_at = |run: &ConfigRun, index: usize| {
            run.candidates
                .iter()
                .find(|c| c.index == index)
                .and_then(|c| c.outcome.as_ref().ok())
                .and_then(|(p, _)| self.target.metric.value(&p.report))
        };
        let mut fail = (run.ladder.steps[f].clone(), value_at(run, f));
        let mut pass = (run.ladder.steps[k].clone(), value_at(run, k));
        let specs = self.codec.param_specs();
        for _ in 0..refine {
            if pass.1.is_some_and(|v| v >= REFINE_CLOSE * self.target.value) {
                break;
            }
            let Some(next) =
                secant(&fail, &pass, REFINE_AIM * self.target.value).or_else(|| midpoint(&fail.0, &pass.0))
            else {
                break;
            };
            let Ok(params) = run.params.clone().with(&specs, run.ladder.param, next.clone()) else { break };
            if self.codec.validate(&params).is_err() {
                break;
            }
            let c = self.measure(&params, run.ladder.param, k);
            let value = c.outcome.as_ref().ok().and_then(|(p, _)| self.target.metric.value(&p.report));
            if self.passes(&c) {
                pass = (next, value);
            } else {
                fail = (next, value);
            }
            run.candidates.push(c);
        }
    }
}

/// A refined point meeting the target within this fraction of it ends the refinement.
const REFINE_CLOSE: f64 = 0.97;
/// The secant aims at this fraction of the target (just under it, so the point likely passes).
const REFINE_AIM: f64 = 0.985;

/// The parameter value where the error is expected to reach `aim`, by linear interpolation of
/// log(error) between the failing and passing ends of a bracket, kept within the middle 70%
/// of the bracket and rounded as [`midpoint`] rounds; `None` when the errors are missing or
/// not ordered, or the bracket holds nothing in between.
fn secant(fail: &(ParamValue, Option<f64>), pass: &(ParamValue, Option<f64>), aim: f64) -> Option<ParamValue> {
    let (Some(vf), Some(vp)) = (fail.1, pass.1) else { return None };
    if !(vf > vp && vp > 0.0 && aim > 0.0) {
        return None;
    }
    let t = ((aim.ln() - vf.ln()) / (vp.ln() - vf.ln())).clamp(0.15, 0.85);
    match (&fail.0, &pass.0) {
        (ParamValue::Int(a), ParamValue::Int(b)) => {
            let x = (*a as f64 + t * (*b - *a) as f64).round() as i64;
            (x != *a && x != *b && (x - a).signum() == (b - a).signum()).then_some(ParamValue::Int(x))
        }
        (ParamValue::Float(a), ParamValue::Float(b)) if a != b => {
            let unit = 10f64.powf(((b - a).abs().log10() - 2.0).floor());
            let x = ((a + t * (b - a)) / unit).round() * unit;
            let x = format!("{x:.12}").parse::<f64>().unwrap_or(x);
            (x.is_finite() && x != *a && x != *b).then_some(ParamValue::Float(x))
        }
        _ => None,
    }
}

/// Finds the smallest stream `codec` makes of `animation` meeting `target` over the codec's
/// declared [`SearchSpace`](codec_core::SearchSpace) on top of `base`: every configuration of
/// the secondary axes (minus the parameters in `fixed`, which the user set), each walked along
/// the primary rate ladder.
///
/// Search: the first configuration (the codec's usual one) cold, by a binary search over its
/// ladder (its top step measured only when nothing below passes); then every other configuration in parallel (rayon), each warm-started at the first
/// one's answer and walked up or down one step at a time, abandoned once a failing step's
/// stream is as large as the first configuration's answer (an early stop: its passing steps
/// can only be larger). Then the ladder parameter is bisected `refine` times between the last
/// failing and the first passing step (secant steps, see `SpaceSearcher::refine`), for the
/// best configuration and, in parallel, the runner-up when its answer is within 3% of the
/// best's bytes. Each configuration's walk
/// depends only on the first configuration's result, never on another running at the same
/// time, and the results are combined in configuration order: the chosen stream does not
/// depend on the thread count. Only measured points are ever chosen; a candidate that fails
/// to encode or decodes to non-finite coordinates is rejected (listed in
/// [`TargetHit::rejected`]), never chosen. Invalid configurations are skipped.
///
/// Assumes errors fall along each ladder (as [`search_target`] does); the single-axis
/// [`search_target`] remains for `--ladder`.
#[allow(clippy::too_many_arguments)]
pub fn search_space_target(
    registry: &CodecRegistry,
    codec: &dyn AnimationCodec,
    base: &ParamSet,
    fixed: &[&str],
    animation: &Animation,
    target: Target,
    eval: &EvalOptions,
    limits: Limits,
    refine: usize,
    progress: &(dyn Fn(&Point) + Sync),
) -> HResult<TargetHit> {
    let space = codec.search_space(base).without(fixed);
    let specs = codec.param_specs();
    let mut runs: Vec<ConfigRun> = space
        .configurations()
        .iter()
        .filter_map(|config| {
            let params = codec_core::SearchSpace::apply(base, &specs, config).ok()?;
            codec.validate(&params).ok()?;
            let ladder = codec.rate_ladder(&params);
            Some(ConfigRun { params, ladder, candidates: Vec::new(), pass: None, fail_below: None })
        })
        .collect();
    if runs.is_empty() {
        return Err(format!("{}: no configuration of the search space validates on [{base}]", codec.name()).into());
    }
    let searcher =
        SpaceSearcher { registry, codec, animation, target, eval: target.metric.eval_options(eval), limits, progress };
    let (first, others) = runs.split_first_mut().expect("checked non-empty");
    searcher.search_cold(first)?;
    let start = first.pass.unwrap_or(first.ladder.steps.len().saturating_sub(1));
    let bound = first.pass.and_then(|k| SpaceSearcher::bytes_at(first, k));
    others.par_iter_mut().map(|run| searcher.search_warm(run, start, bound)).collect::<HResult<Vec<()>>>()?;

    // Refinement of the best configuration and a close runner-up, chosen in configuration order.
    let mut ranked: Vec<(u64, usize)> = runs
        .iter()
        .enumerate()
        .filter_map(|(i, run)| run.pass.and_then(|k| SpaceSearcher::bytes_at(run, k)).map(|b| (b, i)))
        .collect();
    ranked.sort();
    if let Some(&(best, _)) = ranked.first() {
        let chosen: Vec<usize> =
            ranked.iter().take(2).filter(|(b, _)| (*b as f64) <= best as f64 * 1.03).map(|(_, i)| *i).collect();
        runs.par_iter_mut().enumerate().filter(|(i, _)| chosen.contains(i)).for_each(|(_, run)| {
            searcher.refine(run, refine);
        });
    }

    let mut tried = Vec::new();
    let mut rejected = Vec::new();
    let mut best: Option<(Point, Vec<u8>)> = None;
    for run in runs {
        for c in run.candidates {
            let pass = searcher.passes(&c);
            match c.outcome {
                Ok((point, stream)) => {
                    if pass && best.as_ref().is_none_or(|(b, _)| point.bytes < b.bytes) {
                        best = Some((point.clone(), stream));
                    }
                    tried.push(point);
                }
                Err(message) => rejected.push(message),
            }
        }
    }
    match best {
        Some((point, stream)) => Ok(TargetHit { point, stream, tried, linear_fallback: false, rejected }),
        None => Err(Box::new(TargetMiss::new(codec.name(), target, tried.iter(), rejected))),
    }
}

/// [`search_space_target`] for every codec in `codecs` (each on its defaults, nothing fixed),
/// keeping the smallest stream (ties: the earlier codec). Codecs that cannot meet the target
/// are skipped; if none can, the error lists each codec's best. Other failures are errors.
#[allow(clippy::too_many_arguments)]
pub fn search_space_target_auto(
    registry: &CodecRegistry,
    codecs: &[&dyn AnimationCodec],
    animation: &Animation,
    target: Target,
    eval: &EvalOptions,
    limits: Limits,
    refine: usize,
    progress: &(dyn Fn(&Point) + Sync),
) -> HResult<(TargetHit, Vec<TargetHit>)> {
    smallest_over_codecs(codecs, target, |codec| {
        let base = codec.default_params();
        search_space_target(registry, codec, &base, &[], animation, target, eval, limits, refine, progress)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use codec_core::synth;

    /// The harness takes its codecs from the caller; these tests use the baseline and one
    /// transform codec (the facade crate's `registry()` is above this crate).
    fn test_registry() -> CodecRegistry {
        CodecRegistry::new(vec![Box::new(codec_core::quant_delta::QuantDelta), Box::new(codec_pca_aoi::PcaAoi)])
            .expect("unique codec names")
    }

    #[test]
    fn ladder_indices_spread_evenly_and_keep_ends() {
        assert_eq!(ladder_indices(9, None), (0..9).collect::<Vec<_>>());
        assert_eq!(ladder_indices(9, Some(20)), (0..9).collect::<Vec<_>>());
        assert_eq!(ladder_indices(9, Some(3)), vec![0, 4, 8]);
        assert_eq!(ladder_indices(9, Some(2)), vec![0, 8]);
        assert_eq!(ladder_indices(9, Some(1)), vec![8]);
        assert_eq!(ladder_indices(0, Some(3)), Vec::<usize>::new());
        for len in 2..30 {
            for n in 2..len {
                let v = ladder_indices(len, Some(n));
                assert_eq!(v.len(), n, "len {len} n {n}");
                assert_eq!((v[0], v[n - 1]), (0, len - 1));
                assert!(v.windows(2).all(|w| w[0] < w[1]));
            }
        }
    }

    #[test]
    fn midpoints_are_rounded_and_stop_when_the_bracket_closes() {
        let f = |x| ParamValue::Float(x);
        assert_eq!(midpoint(&f(0.9), &f(0.85)), Some(f(0.875)));
        assert_eq!(midpoint(&f(0.9), &f(0.875)), Some(f(0.8875)));
        assert_eq!(midpoint(&f(0.8968), &f(0.8969)), Some(f(0.89685)));
        assert_eq!(midpoint(&f(1.0), &f(1.0)), None);
        assert_eq!(midpoint(&ParamValue::Int(6), &ParamValue::Int(8)), Some(ParamValue::Int(7)));
        assert_eq!(midpoint(&ParamValue::Int(8), &ParamValue::Int(7)), None);
        assert_eq!(midpoint(&ParamValue::Int(250), &ParamValue::Int(160)), Some(ParamValue::Int(205)));
        assert_eq!(midpoint(&ParamValue::Bool(false), &ParamValue::Bool(true)), None);
    }

    #[test]
    fn targets_parse() {
        assert_eq!("kg=0.5".parse::<Target>().unwrap(), Target { metric: TargetMetric::Kg, value: 0.5 });
        assert_eq!("max-error=1e-3".parse::<Target>().unwrap().metric, TargetMetric::MaxError);
        assert_eq!("STED = 0.01".parse::<Target>().unwrap().metric, TargetMetric::Sted);
        assert!("kg".parse::<Target>().unwrap_err().contains("METRIC=VALUE"));
        assert!("psnr=3".parse::<Target>().unwrap_err().contains("kg, sted, hausdorff"));
        assert!("kg=-1".parse::<Target>().is_err());
        assert!("kg=nan".parse::<Target>().is_err());
        assert!("kg=x".parse::<Target>().is_err());
    }

    #[test]
    fn sweep_points_and_rows_read_back_give_the_sweep_rows() {
        let registry = test_registry();
        let a = synth::tumbling_body_sized(8, 6, 4);
        let series: Vec<SweepSeries<'_>> = registry.iter().take(2).map(SweepSeries::defaults).collect();
        let options = SweepOptions { points: Some(2), jobs: Some(1), ..Default::default() };
        let swept = sweep(&registry, &series, &a, &options, &|| {}).unwrap();
        assert_eq!(swept.points.len(), 4);
        let without_timings = |p: &Point| {
            let mut v = point_json(p);
            v["encode_seconds"] = Value::Null;
            v["decode_seconds"] = Value::Null;
            v
        };
        // One job on its own measures what the sweep measured at that point.
        for (p, &(c, step)) in swept.points.iter().zip(&sweep_jobs(&series, options.points)) {
            let alone = sweep_point(&registry, &series[c], step, &a, &options).unwrap();
            assert_eq!(without_timings(&alone), without_timings(p));
        }
        // Rows gathered elsewhere come back as the same rows, table and document.
        let dims = (a.vertex_count(), a.frame_count());
        let back: Vec<Point> = swept
            .points
            .iter()
            .map(|p| point_from_row(&registry, &point_json(p), &options.eval, dims).unwrap())
            .collect();
        assert_eq!(
            back.iter().map(point_json).collect::<Vec<_>>(),
            swept.points.iter().map(point_json).collect::<Vec<_>>()
        );
        assert_eq!(csv_text(&back), csv_text(&swept.points));
        let rebuilt = Sweep { points: back, failures: Vec::new() };
        assert_eq!(sweep_json_sized("x", dims, &options.eval, &rebuilt), sweep_json("x", &a, &options.eval, &swept));
        let mut broken = point_json(&swept.points[0]);
        broken.as_object_mut().unwrap().remove("bpvf");
        let e = point_from_row(&registry, &broken, &options.eval, dims).unwrap_err().to_string();
        assert!(e.contains("'bpvf' is missing"), "{e}");
    }

    #[test]
    fn miss_reports_the_best_point() {
        let registry = test_registry();
        let codec = registry.by_name("quant-delta").unwrap();
        let a = synth::tumbling_body_sized(8, 6, 4);
        let target = Target { metric: TargetMetric::MaxError, value: 0.0 };
        let e = search_target(
            &registry,
            codec,
            &codec.default_params(),
            &a,
            target,
            &EvalOptions::default(),
            Limits::default(),
            0,
        )
        .unwrap_err();
        let miss = e.downcast_ref::<TargetMiss>().expect("a TargetMiss");
        let top = codec.rate_ladder(&codec.default_params()).steps.len() - 1;
        assert_eq!(miss.best.as_ref().unwrap().ladder_index, top);
        let text = miss.to_string();
        assert!(text.contains("best reached is max_error=") && text.contains("quant-delta"), "{text}");
    }
}
