//! The front door: what every front end (the command line, the Python package) does with what a
//! user gives it, done once here so the two cannot drift apart.
//!
//! - [`limits`]: the decoding [`Limits`] from `max_memory` / `max_work`;
//! - [`resolve_input`]: an input named by text (`synth:NAME[:SIZE]`,
//!   `synth:flag:COLSxROWSxFRAMES`, an animation file read with [`ReadOptions`], an `.anim`
//!   stream decoded under the limits) as an [`Animation`], and where it came from;
//! - [`params`], [`params_from_text`]: a codec's parameters from `key=value` text or typed values
//!   ([`ParamInput`]) as a validated [`ParamSet`];
//! - [`MetricOptions`]: which metrics to compute and STED's parameters, checked;
//! - [`evaluation_of`]: `encode --target --eval`'s measurement, taken from the search's own
//!   measured point rather than from a second decode.
//!
//! The front ends keep only their outermost conversion: clap arguments or a Python dict into
//! these types, and the results into text, JSON or Python objects.

use std::error::Error as StdError;
use std::path::Path;
use std::time::Instant;

use animcodec_eval::harness::{Target, TargetHit};
use animcodec_eval::params::params_json;
pub use animcodec_eval::params::ParamInput;
use animcodec_io::formats::{self, ReadOptions};
use codec_core::{Animation, AnimationCodec, CodecRegistry, Limits, ParamSet, StreamDecoder};
use metrics::{EdgeDifference, EvalOptions, MetricReport, StedParams};
use serde::Serialize;
use serde_json::Value;

/// What the front door fails with: a library error or a plain message, with its sources.
pub type FrontError = Box<dyn StdError + Send + Sync>;

/// A front-door result.
pub type FrontResult<T> = Result<T, FrontError>;

/// The decoding limits from a memory bound (bytes a decode may hold) and a work bound
/// (operations it may spend); `None` keeps [`Limits::default`]'s. Zero is refused: nothing
/// decodes in zero bytes, and a zero bound is a typo, not a wish.
pub fn limits(max_memory: Option<u64>, max_work: Option<u64>) -> FrontResult<Limits> {
    let mut limits = Limits::default();
    if let Some(m) = max_memory {
        if m == 0 {
            return Err("max_memory must be at least 1 byte".into());
        }
        limits.max_alloc_bytes = usize::try_from(m).unwrap_or(usize::MAX);
    }
    if let Some(w) = max_work {
        if w == 0 {
            return Err("max_work must be at least 1 operation".into());
        }
        limits.max_work = w;
    }
    Ok(limits)
}

/// The share of the machine's RAM a command may hold when no `--memory` is given, as
/// (numerator, denominator) of `MemTotal`: a half. Half, because the machine runs other
/// programs too (the other half is theirs and the system's), and a search that would need more
/// than half the RAM over the whole input is better streamed than swapped. `MemTotal`, not
/// `MemAvailable`: the budget chooses between the whole-array and the streamed search and may
/// fit a codec's blocks ([`AnimationCodec::fit_memory`]), so it must not change from one run
/// to the next with what else happens to be running.
pub const DEFAULT_MEMORY_SHARE: (u64, u64) = (1, 2);

/// The memory budget of a command given no `--memory`: [`DEFAULT_MEMORY_SHARE`] of the
/// machine's RAM (`MemTotal` in `/proc/meminfo`); `None` where that cannot be read (no
/// `/proc`, or a line that does not parse), when no budget applies.
pub fn default_memory_budget() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    mem_total(&text).map(|total| total / DEFAULT_MEMORY_SHARE.1 * DEFAULT_MEMORY_SHARE.0)
}

/// Raw size (f32 coordinates) above which a search streams its input even when the
/// whole-array search fits the memory budget. The whole-array search holds three times the raw
/// input at least (the input, a decoded candidate, the metrics' working copies) plus the
/// encoder's analysis (hosvd's whole-sequence decomposition: ~16× raw): gigabytes once the
/// input is this large, for a search ~1.35× faster than the streamed one (a 40 MB cache: 21.8 s
/// whole, 29.4 s streamed). Below it the whole-array search stays (a few hundred MiB at most).
pub const WHOLE_SEARCH_MAX_RAW: u64 = 256 << 20;

/// The budget of a streamed search over an input above [`WHOLE_SEARCH_MAX_RAW`], as
/// (numerator, denominator) of its raw size: twice. A command's memory then grows with its
/// input, not with the machine: `--memory` (or the default budget) only caps it. The budget is
/// kept by the codecs' memory models, which are upper bounds: at twice raw the measured peaks
/// of the default command with `--eval` on a 99 856 × 300 cache (343 MB) were 0.91× raw
/// (quant-delta), 1.36× (pca-aoi) and 1.18× (hosvd), `docs/notes/session-2026-11-29.md`.
/// Raised to the least budget the searched codecs accept ([`harness::least_streamed_budget`]:
/// hosvd's smallest blocks, quant-delta's packets), so no codec is refused for it.
///
/// [`harness::least_streamed_budget`]: animcodec_eval::harness::least_streamed_budget
pub const STREAMED_SEARCH_SHARE_OF_RAW: (u64, u64) = (2, 1);

/// The size (bytes of f32 coordinates) above which a streamed search measures its candidates on
/// a sample of the input's frames ([`harness::SampledSource`]: about an eighth, in windows of
/// the codec's temporal blocks) and then encodes the chosen parameters over the whole input
/// once, measuring that stream: 1 GiB. A streamed candidate is two passes over the input (at
/// 1 000 000 vertices × 1 000 frames, 12 GB, 10–35 minutes each on two cores); below this size
/// a search of four to six such candidates takes minutes and is kept exact.
///
/// [`harness::SampledSource`]: animcodec_eval::harness::SampledSource
pub const SAMPLED_SEARCH_MIN_RAW: u64 = 1 << 30;

/// The budget a search over `raw` bytes of input keeps to, given the command's `budget`
/// (`--memory` or the default) and `least`, the least budget its codecs accept: `None` when
/// the input is small enough for the whole-array search ([`WHOLE_SEARCH_MAX_RAW`]); else
/// [`STREAMED_SEARCH_SHARE_OF_RAW`] of `raw`, raised to `least`, capped by `budget`.
pub fn streamed_search_budget(raw: u64, budget: Option<u64>, least: u64) -> Option<u64> {
    if raw <= WHOLE_SEARCH_MAX_RAW {
        return None;
    }
    let (num, den) = STREAMED_SEARCH_SHARE_OF_RAW;
    let want = (raw / den).saturating_mul(num).max(least);
    Some(budget.map_or(want, |b| b.min(want)))
}

/// `MemTotal` in bytes from the text of `/proc/meminfo` (`MemTotal:   23456789 kB`).
fn mem_total(meminfo: &str) -> Option<u64> {
    let line = meminfo.lines().find(|l| l.starts_with("MemTotal:"))?;
    let mut words = line["MemTotal:".len()..].split_whitespace();
    let kib: u64 = words.next()?.parse().ok()?;
    match words.next() {
        Some("kB") => kib.checked_mul(1024),
        _ => None,
    }
}

/// Whether an `.anim` stream is taken as an input (decoded) or read as any other file (which no
/// reader takes: an `encode` of a stream is refused by the readers as an unknown format).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Streams {
    /// An `.anim` stream is decoded under the limits.
    Decode,
    /// An `.anim` stream is not an animation file: the readers refuse it.
    Refuse,
}

/// Where a resolved input came from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Origin {
    /// A built-in synthetic animation (`synth:…`).
    Synthetic,
    /// An animation file read by [`formats::read_animation`].
    File,
    /// An `.anim` stream, decoded; the codec that wrote it.
    Stream {
        /// The stream's codec.
        codec: &'static str,
    },
}

/// An input resolved into an animation.
#[derive(Debug)]
pub struct Resolved {
    /// The animation.
    pub animation: Animation,
    /// Where it came from.
    pub origin: Origin,
}

/// Recognises `synth:flag:COLSxROWSxFRAMES`, the flag of any size: `(cols, rows, frames)`, or
/// `None` for any other input (a size preset such as `synth:flag:small` included).
pub fn streamed_flag(input: &str) -> FrontResult<Option<(usize, usize, usize)>> {
    let Some(dims) = input.strip_prefix("synth:flag:") else { return Ok(None) };
    if !dims.contains('x') {
        return Ok(None);
    }
    let parts: Vec<usize> = dims
        .split('x')
        .map(|p| p.trim().parse::<usize>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("'{input}': expected synth:flag:COLSxROWSxFRAMES with three positive integers"))?;
    match parts[..] {
        [c, r, f] if c >= 2 && r >= 2 && f >= 1 && c.checked_mul(r).is_some_and(|n| n <= u32::MAX as usize) => {
            Ok(Some((c, r, f)))
        }
        _ => Err(format!(
            "'{input}': expected synth:flag:COLSxROWSxFRAMES with COLS, ROWS ≥ 2, FRAMES ≥ 1 and COLS×ROWS < 2^32"
        )
        .into()),
    }
}

/// Whether `input` names an `.anim` stream by its extension.
pub fn names_stream(input: &str) -> bool {
    Path::new(input).extension().is_some_and(|e| e.eq_ignore_ascii_case("anim"))
}

/// Resolves an input named by text into an animation, under `limits`:
///
/// - `synth:NAME[:SIZE]`: a built-in synthetic animation (size `small` by default);
/// - `synth:flag:COLSxROWSxFRAMES`: the flag of that size, built in memory (refused before
///   building when its coordinates exceed the memory limit);
/// - a name ending in `.anim` (with [`Streams::Decode`]): the stream, decoded under `limits`;
/// - anything else: a file (or OBJ directory / pattern) read by [`formats::read_animation`] with
///   `read` (topology, frame rate, glTF animation, Alembic object).
///
/// `read.frame_rate` also replaces a synthetic animation's rate. Errors name the input.
pub fn resolve_input(
    registry: &CodecRegistry,
    input: &str,
    read: &ReadOptions,
    limits: Limits,
    streams: Streams,
) -> FrontResult<Resolved> {
    if let Some(spec) = input.strip_prefix("synth:") {
        let animation = match streamed_flag(input)? {
            Some((cols, rows, frames)) => {
                // Coordinates held: frames × vertices × 3 f32, checked before any is made.
                let need = (cols as u64).checked_mul(rows as u64).and_then(|v| v.checked_mul(frames as u64 * 12));
                if need.is_none_or(|n| n > limits.max_alloc_bytes as u64) {
                    return Err(format!(
                        "{input}: its frames hold {} MiB in memory, more than the memory limit ({} MiB); encode \
                         streams it frame by frame, or raise --max-memory",
                        need.map_or(u64::MAX, |n| n >> 20),
                        limits.max_alloc_bytes >> 20
                    )
                    .into());
                }
                animcodec_synth::waving_flag(cols, rows, frames)
            }
            None => {
                let (name, size) = match spec.split_once(':') {
                    Some((name, size)) => (name, animcodec_synth::SynthSize::from_name(size)?),
                    None => (spec, animcodec_synth::SynthSize::Small),
                };
                animcodec_synth::by_name(name, size)?
            }
        };
        let animation = match read.frame_rate {
            Some(fps) => {
                let (topology, positions, _) = animation.into_parts();
                Animation::new(topology, positions, fps)?
            }
            None => animation,
        };
        return Ok(Resolved { animation, origin: Origin::Synthetic });
    }
    let path = Path::new(input);
    if streams == Streams::Decode && names_stream(input) {
        let decoder = StreamDecoder::new(open_stream(path)?, registry, limits).map_err(|e| in_file(e.into(), input))?;
        let codec = decoder.codec_name();
        let animation = decoder.decode_all().map_err(|e| in_file(e.into(), input))?;
        return Ok(Resolved { animation, origin: Origin::Stream { codec } });
    }
    if !input.contains(['*', '?', '{', '#']) {
        if let Err(e) = std::fs::metadata(path) {
            return Err(io_message(&format!("cannot read '{input}'"), &e).into());
        }
    }
    Ok(Resolved { animation: formats::read_animation(path, read)?, origin: Origin::File })
}

/// Opens an `.anim` file for reading through a buffer (a directory is refused by name).
pub fn open_stream(path: &Path) -> FrontResult<std::io::BufReader<std::fs::File>> {
    let file =
        std::fs::File::open(path).map_err(|e| codec_core::Error::io(format!("cannot open {}", path.display()), e))?;
    if file.metadata().is_ok_and(|m| m.is_dir()) {
        return Err(format!("cannot read {}: it is a directory", path.display()).into());
    }
    Ok(std::io::BufReader::new(file))
}

/// `e` with the file name `file` in front, unless its message already names it (the readers
/// name their file themselves: printed twice, it reads like two files).
pub fn in_file(e: FrontError, file: &str) -> FrontError {
    if codec_core::error::message_with_sources(e.as_ref()).contains(file) {
        e
    } else {
        format!("{file}: {}", codec_core::error::message_with_sources(e.as_ref())).into()
    }
}

/// "CONTEXT: REASON" for an I/O error, the reason in plain words ("no such file or directory",
/// "permission denied", …) instead of the OS text with its error number.
pub fn io_message(context: &str, e: &std::io::Error) -> String {
    use std::io::ErrorKind;
    let reason = match e.kind() {
        ErrorKind::NotFound => "no such file or directory".to_owned(),
        ErrorKind::PermissionDenied => "permission denied".to_owned(),
        _ => e.to_string(),
    };
    format!("{context}: {reason}")
}

/// The parameter set of `codec` from (name, value) entries: its defaults with them set, typed
/// by each parameter's kind, validated ([`animcodec_eval::params::param_set`]).
pub fn params<'a>(
    codec: &dyn AnimationCodec,
    entries: impl IntoIterator<Item = (&'a str, ParamInput)>,
) -> FrontResult<ParamSet> {
    Ok(animcodec_eval::params::param_set(codec, entries)?)
}

/// The parameter set of `codec` from `key=value` texts (`-p bits=12`): [`params`] after the
/// split at `=`.
pub fn params_from_text(codec: &dyn AnimationCodec, pairs: &[String]) -> FrontResult<ParamSet> {
    Ok(animcodec_eval::params::param_set_from_text(codec, pairs)?)
}

/// Which metrics to compute and STED's parameters, as a user gives them (`None`: the metric
/// author's defaults, [`StedParams::default`]). [`MetricOptions::eval_options`] checks them.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MetricOptions {
    /// STED neighbourhood width in rings.
    pub sted_radius: Option<u32>,
    /// STED time extent of one frame step.
    pub sted_dt: Option<f64>,
    /// STED speed-averaging window.
    pub sted_window: Option<u32>,
    /// STED weight of the temporal part.
    pub sted_c: Option<f64>,
    /// Absolute (instead of signed) relative edge differences in STED's spatial part.
    pub sted_absolute: bool,
    /// Skip STED.
    pub skip_sted: bool,
    /// Skip the Hausdorff distance.
    pub skip_hausdorff: bool,
}

impl MetricOptions {
    /// STED's parameters, checked ([`StedParams::validate`]).
    pub fn sted_params(&self) -> FrontResult<StedParams> {
        let d = StedParams::default();
        let p = StedParams {
            ring_radius: self.sted_radius.unwrap_or(d.ring_radius),
            dt: self.sted_dt.unwrap_or(d.dt),
            speed_window: self.sted_window.unwrap_or(d.speed_window),
            c: self.sted_c.unwrap_or(d.c),
            spatial_difference: if self.sted_absolute { EdgeDifference::Absolute } else { d.spatial_difference },
        };
        p.validate()?;
        Ok(p)
    }

    /// The evaluation options: the metrics asked for, STED's parameters checked.
    pub fn eval_options(&self) -> FrontResult<EvalOptions> {
        Ok(EvalOptions {
            sted: self.sted_params()?,
            compute_sted: !self.skip_sted,
            compute_hausdorff: !self.skip_hausdorff,
        })
    }
}

/// How often the front door decoded a stream to measure it again ([`evaluation_of`]); a test
/// reads it to prove a measured stream is decoded once.
pub static MEASURE_DECODES: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// The measurement of a target search's chosen stream against `input`, with `options`: the
/// search's own report of that point when it already holds every metric asked for (no decode
/// at all), else the stream the search kept decoded once more, in memory, to compute the
/// metrics the search skipped (a search computes only its target's metric). The encoder's notes
/// the search attached to the point (`encoder: …`) are left out: they are the encode's, not
/// the measurement's. Returns the report and the seconds the measurement took.
pub fn evaluation_of(
    registry: &CodecRegistry,
    hit: &TargetHit,
    input: &Animation,
    options: &EvalOptions,
    limits: Limits,
) -> FrontResult<(MetricReport, f64)> {
    if let Some(found) = search_evaluation(hit, options) {
        return Ok(found);
    }
    let start = Instant::now();
    MEASURE_DECODES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let decoded = StreamDecoder::new(hit.stream.as_slice(), registry, limits)?.decode_all()?;
    let report = metrics::evaluate(input, &decoded, options)?;
    Ok((report, start.elapsed().as_secs_f64()))
}

/// The search's own report of its chosen point when it holds every metric `options` asks for
/// (with the same STED parameters), without the encoder's notes, and the seconds it took;
/// `None` when the search skipped one (it computes only its target's metrics).
pub fn search_evaluation(hit: &TargetHit, options: &EvalOptions) -> Option<(MetricReport, f64)> {
    let report = &hit.point.report;
    let complete = (!options.compute_sted || report.sted.is_some())
        && (!options.compute_hausdorff || report.hausdorff.is_some())
        && report.sted_params == options.sted;
    complete.then(|| {
        let mut report = report.clone();
        report.notes.retain(|n| !n.starts_with("encoder: "));
        (report, hit.point.decode_seconds)
    })
}

/// What a target search found, as every front end reports it (`encode --target --json` and
/// the Python package's `encode_to_target` summary): the chosen point, every point tried, and
/// the other codecs' answers (`-c auto`).
#[derive(Debug, Clone, Serialize)]
pub struct TargetSummary {
    /// The chosen codec.
    pub codec: &'static str,
    /// Its parameters.
    pub params: Value,
    /// The target's bounds, one per metric: `{"kg": 0.5, "sted": 0.05}`.
    pub target: Value,
    /// Each bounded metric's value reached (`null`: undefined).
    pub reached: Value,
    /// Connected parts of the mesh.
    pub parts: usize,
    /// KG (%) of the worst part against its own spread.
    pub worst_part_kg: Option<f64>,
    /// The stream's size.
    pub bytes: u64,
    /// Its bits per vertex per frame.
    pub bpvf: f64,
    /// Whether the errors were not monotone along the ladder (a linear scan was used).
    pub linear_fallback: bool,
    /// Candidates the search refused, and why.
    pub rejected: Vec<String>,
    /// Every point tried.
    pub tried: Vec<TriedPoint>,
    /// The other codecs that meet the target (`auto`).
    pub other_codecs: Vec<OtherCodec>,
}

/// One point a target search tried.
#[derive(Debug, Clone, Serialize)]
pub struct TriedPoint {
    /// Position on the ladder.
    pub ladder_index: usize,
    /// Its parameters.
    pub params: Value,
    /// Its stream's size.
    pub bytes: u64,
    /// Its bits per vertex per frame.
    pub bpvf: f64,
    /// Each bounded metric's value.
    pub reached: Value,
}

/// Another codec's answer to the same target.
#[derive(Debug, Clone, Serialize)]
pub struct OtherCodec {
    /// The codec.
    pub codec: &'static str,
    /// Its parameters.
    pub params: Value,
    /// Its stream's size.
    pub bytes: u64,
    /// Its bits per vertex per frame.
    pub bpvf: f64,
    /// Each bounded metric's value.
    pub reached: Value,
}

impl TargetSummary {
    /// The summary of `hit` (and `others`) for `target`.
    pub fn new(target: Target, hit: &TargetHit, others: &[TargetHit]) -> Self {
        let value_of = |p: &animcodec_eval::harness::Point| reached_json(target, &p.report);
        let p = &hit.point;
        Self {
            codec: p.codec,
            params: params_json(&p.params),
            target: bounds_json(target),
            reached: value_of(p),
            parts: p.report.parts,
            worst_part_kg: p.report.worst_part_kg(),
            bytes: p.bytes,
            bpvf: p.bpvf,
            linear_fallback: hit.linear_fallback,
            rejected: hit.rejected.clone(),
            tried: hit
                .tried
                .iter()
                .map(|t| TriedPoint {
                    ladder_index: t.ladder_index,
                    params: params_json(&t.params),
                    bytes: t.bytes,
                    bpvf: t.bpvf,
                    reached: value_of(t),
                })
                .collect(),
            other_codecs: others
                .iter()
                .map(|h| OtherCodec {
                    codec: h.point.codec,
                    params: params_json(&h.point.params),
                    bytes: h.point.bytes,
                    bpvf: h.point.bpvf,
                    reached: value_of(&h.point),
                })
                .collect(),
        }
    }
}

/// A target's bounds as JSON: `{"kg": 0.5, "sted": 0.05}`.
pub fn bounds_json(target: Target) -> Value {
    Value::Object(target.bounds().map(|(m, v)| (m.name().to_owned(), serde_json::json!(v))).collect())
}

/// Each bounded metric's value in `report` as JSON (`null`: undefined): `{"kg": 0.43, "sted": 0.031}`.
pub fn reached_json(target: Target, report: &MetricReport) -> Value {
    Value::Object(
        target.reached(report).into_iter().map(|(m, v)| (m.name().to_owned(), serde_json::json!(v))).collect(),
    )
}

/// `--eval`'s figures in an `encode --json` document (and the Python summary's).
#[derive(Debug, Clone, Serialize)]
pub struct EvaluationFields {
    /// KG (%).
    pub kg: Option<f64>,
    /// KG (%) of the worst part against its own spread.
    pub worst_part_kg: Option<f64>,
    /// STED.
    pub sted: Option<f64>,
    /// Every metric.
    pub metrics: Value,
    /// Seconds measuring.
    pub eval_seconds: f64,
}

impl EvaluationFields {
    /// The fields of a measurement and its seconds.
    pub fn new(report: &MetricReport, seconds: f64) -> Self {
        Self {
            kg: report.kg,
            worst_part_kg: report.worst_part_kg(),
            sted: report.sted,
            metrics: serde_json::to_value(report).unwrap_or(Value::Null),
            eval_seconds: seconds,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_limits_are_refused_and_others_kept() {
        assert!(limits(Some(0), None).unwrap_err().to_string().contains("max_memory"));
        assert!(limits(None, Some(0)).unwrap_err().to_string().contains("max_work"));
        let l = limits(Some(4096), Some(77)).unwrap();
        assert_eq!((l.max_alloc_bytes, l.max_work), (4096, 77));
        assert_eq!(limits(None, None).unwrap(), Limits::default());
    }

    #[test]
    fn synthetic_inputs_resolve_every_spelling() {
        let registry = crate::registry();
        let read = ReadOptions::default();
        let r = resolve_input(&registry, "synth:tumble", &read, Limits::default(), Streams::Decode).unwrap();
        assert_eq!(r.origin, Origin::Synthetic);
        let r = resolve_input(&registry, "synth:flag:6x5x7", &read, Limits::default(), Streams::Decode).unwrap();
        assert_eq!((r.animation.vertex_count(), r.animation.frame_count()), (30, 7));
        let small = Limits { max_alloc_bytes: 1000, ..Limits::default() };
        let e = resolve_input(&registry, "synth:flag:60x50x70", &read, small, Streams::Decode).unwrap_err();
        assert!(e.to_string().contains("memory limit"), "{e}");
        let e = resolve_input(&registry, "synth:flag:huge", &read, Limits::default(), Streams::Decode).unwrap_err();
        assert!(e.to_string().contains("small, medium, large"), "{e}");
        let e = resolve_input(&registry, "/nonexistent/x.pc2", &read, Limits::default(), Streams::Decode).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/x.pc2") && e.to_string().contains("no such file"), "{e}");
    }

    #[test]
    fn text_and_typed_parameters_take_one_path() {
        let registry = crate::registry();
        let codec = registry.by_name("quant-delta").unwrap();
        let from_text = params_from_text(codec, &["bits=9".to_owned()]).unwrap();
        let typed = params(codec, [("bits", ParamInput::Int(9))]).unwrap();
        assert_eq!(from_text, typed);
        let e = params(codec, [("bits", ParamInput::Str("9".into()))]).unwrap_err().to_string();
        assert!(e.contains("parameter 'bits' = '9' is not a"), "{e}");
        let e = params_from_text(codec, &["bits=9".to_owned(), "bits=10".to_owned()]).unwrap_err().to_string();
        assert!(e.contains("more than once"), "{e}");
        let e = params_from_text(codec, &["bits".to_owned()]).unwrap_err().to_string();
        assert!(e.contains("not of the form key=value"), "{e}");
    }

    #[test]
    fn metric_options_are_checked() {
        assert!(MetricOptions { sted_radius: Some(0), ..Default::default() }.eval_options().is_err());
        let o =
            MetricOptions { skip_hausdorff: true, sted_absolute: true, ..Default::default() }.eval_options().unwrap();
        assert!(o.compute_sted && !o.compute_hausdorff);
        assert_eq!(o.sted.spatial_difference, EdgeDifference::Absolute);
    }
}

#[cfg(test)]
mod memory_tests {
    use super::*;

    #[test]
    fn mem_total_reads_kib_and_refuses_what_it_does_not_know() {
        let text = "MemFree:  10 kB\nMemTotal:       23456 kB\nMemAvailable: 5 kB\n";
        assert_eq!(mem_total(text), Some(23456 * 1024));
        assert_eq!(mem_total("MemTotal: 12 MB\n"), None);
        assert_eq!(mem_total("MemTotal: x kB\n"), None);
        assert_eq!(mem_total("MemFree: 1 kB\n"), None);
        assert_eq!(mem_total("MemTotal: 99999999999999999999 kB\n"), None);
    }

    /// Small inputs keep the whole-array search; a large one streams within its share of raw,
    /// raised to what its codecs need, never above the budget.
    #[test]
    fn a_large_input_streams_within_its_share_of_raw_capped_by_the_budget() {
        const MIB: u64 = 1 << 20;
        assert_eq!(streamed_search_budget(WHOLE_SEARCH_MAX_RAW, Some(64 * 1024 * MIB), 0), None);
        let raw = 343 * MIB;
        let (num, den) = STREAMED_SEARCH_SHARE_OF_RAW;
        let share = raw / den * num;
        assert_eq!(streamed_search_budget(raw, Some(4096 * MIB), 0), Some(share));
        assert_eq!(streamed_search_budget(raw, None, 0), Some(share));
        assert_eq!(streamed_search_budget(raw, Some(4096 * MIB), 900 * MIB), Some(share.max(900 * MIB)));
        assert_eq!(streamed_search_budget(raw, Some(300 * MIB), 0), Some(300 * MIB));
        assert_eq!(streamed_search_budget(raw, Some(300 * MIB), 900 * MIB), Some(300 * MIB));
        assert_eq!(streamed_search_budget(u64::MAX, None, 0), Some((u64::MAX / den).saturating_mul(num)));
    }
}
