//! Sweep results as documents: a measured point as a [`SweepRow`] (the JSON row and the CSV
//! line are both this type, serialized), the whole sweep as a [`SweepDocument`], rows gathered
//! from another process read back ([`SweepRow::from_json`], [`points_from_rows`]), and the
//! metric report as JSON.

use std::path::Path;

use codec_core::CodecRegistry;
use metrics::{EvalOptions, MetricReport};
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

use super::csv;
use super::curve::{envelope, joint_envelope, monotone_report, Monotonicity};
use super::measured::Point;
use super::sweep::{Failure, Sweep};
use super::target::TargetMetric;
use crate::error::{EvalError, Result};
use crate::params::{param_value_from_json, ParamsObject};

/// One sweep row: a measured point as `sweep --json` writes it in `rows` and `sweep --csv`
/// writes it as a line (every field but `ladder_param`, in this order). Metrics not defined or
/// not computed are `null` (an empty CSV cell). Keys: `docs/json.md`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepRow {
    /// Codec name.
    pub codec: String,
    /// Curve name (see [`Point::series`]).
    pub series: String,
    /// Parameters used, in the codec's order.
    pub params: ParamsObject,
    /// The parameter the ladder walks.
    pub ladder_param: String,
    /// Position on the rate ladder.
    pub ladder_index: usize,
    /// Container size in bytes.
    pub bytes: u64,
    /// Bits per vertex per frame.
    pub bpvf: f64,
    /// KG error, percent.
    pub kg: Option<f64>,
    /// STED.
    pub sted: Option<f64>,
    /// STED's spatial part.
    pub sted_spatial: Option<f64>,
    /// STED's temporal part.
    pub sted_temporal: Option<f64>,
    /// Largest per-frame Hausdorff distance.
    pub hausdorff: Option<f64>,
    /// `hausdorff` over the bounding-box diagonal.
    pub hausdorff_relative: Option<f64>,
    /// Mean squared vertex displacement.
    pub mse: f64,
    /// Its root.
    pub rmse: f64,
    /// Largest vertex displacement.
    pub max_error: f64,
    /// Number of parts (connected components of the triangles); absent in rows written by
    /// versions without parts (read as 0).
    #[serde(default)]
    pub parts: usize,
    /// KG of the worst part against its own spread, percent (`null` without parts): a large
    /// static part must not hide a destroyed small one.
    #[serde(default)]
    pub worst_part_kg: Option<f64>,
    /// Encoding time.
    pub encode_seconds: f64,
    /// Decoding time.
    pub decode_seconds: f64,
    /// Measured by the envelope sweep's refinement toward the standard targets, possibly
    /// between two ladder steps ([`Point::refined`]); written only when true.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub refined: bool,
}

/// Fields of [`SweepRow`] the CSV leaves out: the ladder's parameter is in `params` already;
/// `refined` is written only when true, so it is no column (a refined point's parameters
/// show its ladder value between two steps).
const NOT_IN_CSV: &[&str] = &["ladder_param", "refined"];

/// Fields a row read back may lack (rows written by versions without parts have neither;
/// `refined` is written only when true).
const MAY_BE_MISSING: &[&str] = &["parts", "worst_part_kg", "refined"];

impl From<&Point> for SweepRow {
    fn from(p: &Point) -> Self {
        let r = &p.report;
        Self {
            codec: p.codec.to_owned(),
            series: p.series.clone(),
            params: ParamsObject::from(&p.params),
            ladder_param: p.ladder_param.to_owned(),
            ladder_index: p.ladder_index,
            bytes: p.bytes,
            bpvf: p.bpvf,
            kg: r.kg,
            sted: r.sted,
            sted_spatial: r.sted_spatial,
            sted_temporal: r.sted_temporal,
            hausdorff: r.hausdorff,
            hausdorff_relative: r.hausdorff_relative,
            mse: r.mse,
            rmse: r.rmse,
            max_error: r.max_error,
            parts: r.parts,
            worst_part_kg: r.worst_part_kg(),
            encode_seconds: p.encode_seconds,
            decode_seconds: p.decode_seconds,
            refined: p.refined,
        }
    }
}

impl SweepRow {
    /// The row as a JSON value (keys in alphabetical order, as in every document).
    pub fn to_json(&self) -> Value {
        serde_json::to_value(self).unwrap_or(Value::Null)
    }

    /// Reads a row as [`SweepRow::to_json`] wrote it. Every field must be present (`null` for
    /// an undefined metric); the error names the field.
    pub fn from_json(row: &Value) -> Result<Self> {
        let bad = |field: &str, reason: String| EvalError::Row { row: None, field: field.to_owned(), reason };
        let Value::Object(given) = row else {
            return Err(bad("row", format!("is not an object: {row}")));
        };
        // A template row says which fields there are and what a valid value of each looks like:
        // serde's own error on a `Value` does not name the field, so the culprit is found by
        // replacing one field at a time with the template's value.
        let Value::Object(template) = Self::template().to_json() else { unreachable!("a row is an object") };
        if let Some(missing) =
            template.keys().find(|k| !given.contains_key(*k) && !MAY_BE_MISSING.contains(&k.as_str()))
        {
            return Err(bad(missing, "is missing".into()));
        }
        match serde_json::from_value::<Self>(row.clone()) {
            Ok(parsed) => Ok(parsed),
            Err(e) => {
                let culprit = template.iter().find(|(name, good)| {
                    let mut fixed: Map<String, Value> = given.clone();
                    fixed.insert((*name).clone(), (*good).clone());
                    serde_json::from_value::<Self>(Value::Object(fixed)).is_ok()
                });
                Err(match culprit {
                    Some((name, _)) => bad(name, format!("= {} is invalid: {e}", given[name])),
                    None => bad("row", e.to_string()),
                })
            }
        }
    }

    /// A row whose every field holds a valid value (for [`SweepRow::from_json`]).
    fn template() -> Self {
        Self {
            codec: String::new(),
            series: String::new(),
            params: ParamsObject::default(),
            ladder_param: String::new(),
            ladder_index: 0,
            bytes: 0,
            bpvf: 0.0,
            kg: None,
            sted: None,
            sted_spatial: None,
            sted_temporal: None,
            hausdorff: None,
            hausdorff_relative: None,
            mse: 0.0,
            rmse: 0.0,
            max_error: 0.0,
            parts: 0,
            worst_part_kg: None,
            encode_seconds: 0.0,
            decode_seconds: 0.0,
            refined: false,
        }
    }

    /// The row back as a [`Point`], for writing rows gathered from elsewhere (another process
    /// or machine) with [`SweepDocument`], [`csv_text`] and the plot. The report holds the
    /// row's metrics; what a row does not carry is filled from the arguments (`sted_params`
    /// from `eval`, the counts) or left empty (`hausdorff_mean`, the relative MSE and RMSE,
    /// `bbox_diagonal` = NaN, no notes), so the row of the result equals this row.
    pub fn to_point(
        &self,
        registry: &CodecRegistry,
        eval: &EvalOptions,
        (vertices, frames): (usize, usize),
    ) -> Result<Point> {
        let codec = registry.by_name(&self.codec)?;
        let specs = codec.param_specs();
        let mut params = codec.default_params();
        for (name, value) in &self.params.0 {
            let spec = codec_core::params::find_spec(codec.name(), &specs, name)?;
            let typed = param_value_from_json(codec.name(), spec, value).ok_or_else(|| EvalError::Row {
                row: None,
                field: format!("params.{name}"),
                reason: format!("= {value} does not fit {}", spec.kind),
            })??;
            params.set(&specs, spec.name, typed)?;
        }
        let ladder_param = codec_core::params::find_spec(codec.name(), &specs, &self.ladder_param)?.name;
        let report = MetricReport {
            kg: self.kg,
            sted: self.sted,
            sted_spatial: self.sted_spatial,
            sted_temporal: self.sted_temporal,
            hausdorff: self.hausdorff,
            hausdorff_mean: None,
            hausdorff_relative: self.hausdorff_relative,
            hausdorff_mean_relative: None,
            hausdorff_mode: None,
            mse: self.mse,
            rmse: self.rmse,
            mse_relative: None,
            rmse_relative: None,
            max_error: self.max_error,
            parts: self.parts,
            // A row carries the worst part's KG alone; the rest of the part is unknown here.
            worst_part: self.worst_part_kg.map(|kg| metrics::PartError {
                part: 0,
                first_vertex: 0,
                vertices: 0,
                kg: Some(kg),
                rmse: f64::NAN,
                max_error: f64::NAN,
                spread: f64::NAN,
                floored: false,
            }),
            sted_params: eval.sted,
            bbox_diagonal: f64::NAN,
            vertex_count: vertices,
            frame_count: frames,
            notes: Vec::new(),
        };
        Ok(Point {
            codec: codec.name(),
            series: self.series.clone(),
            params,
            ladder_param,
            ladder_index: self.ladder_index,
            bytes: self.bytes,
            bpvf: self.bpvf,
            report,
            encode_seconds: self.encode_seconds,
            decode_seconds: self.decode_seconds,
            refined: self.refined,
        })
    }
}

/// Rows gathered from elsewhere (JSON values as [`SweepRow::to_json`] wrote them) back as
/// points of an input of `(vertices, frames)`; an error names the row (its position) and the
/// field.
pub fn points_from_rows(
    registry: &CodecRegistry,
    rows: &[Value],
    eval: &EvalOptions,
    dims: (usize, usize),
) -> Result<Vec<Point>> {
    rows.iter()
        .enumerate()
        .map(|(i, row)| {
            SweepRow::from_json(row).and_then(|r| r.to_point(registry, eval, dims)).map_err(|e| match e {
                EvalError::Row { field, reason, .. } => EvalError::Row { row: Some(i), field, reason },
                other => other,
            })
        })
        .collect()
}

/// A failed sweep point as a document carries it (`{codec, series, ladder_index, error}`),
/// read back from another process.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FailureRow {
    /// Codec name.
    pub codec: String,
    /// Curve name.
    pub series: String,
    /// Position on the ladder.
    pub ladder_index: usize,
    /// What went wrong.
    pub error: String,
}

impl FailureRow {
    /// The failure, its codec looked up in `registry`.
    pub fn to_failure(&self, registry: &CodecRegistry) -> Result<Failure> {
        Ok(Failure {
            codec: registry.by_name(&self.codec)?.name(),
            series: self.series.clone(),
            ladder_index: self.ladder_index,
            message: self.error.clone(),
        })
    }
}

/// Row positions on each codec's lower envelope (sorted by bytes, error below every smaller
/// stream of the codec), by KG and by STED, and on its joint envelope by both.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Envelopes {
    /// By KG.
    pub kg: Vec<usize>,
    /// By STED (rows whose KG exceeds [`STED_DEGENERATE_KG`](super::STED_DEGENERATE_KG) left out).
    pub sted: Vec<usize>,
    /// By KG and STED together ([`joint_envelope`](super::joint_envelope)).
    pub joint: Vec<usize>,
}

/// The sweep document `sweep --json` writes (and the Python package returns): the input, its
/// size, the metric options, every row, the failures, each curve's monotonicity and the
/// envelopes. Keys: `docs/json.md`.
#[derive(Debug, Clone, Serialize)]
pub struct SweepDocument {
    /// The input as given.
    pub input: String,
    /// Vertices per frame of the input.
    pub vertices: usize,
    /// Frames of the input.
    pub frames: usize,
    /// Metrics computed, STED's parameters.
    pub eval_options: EvalOptions,
    /// Measured points, by series then ladder position.
    pub rows: Vec<SweepRow>,
    /// Points that could not be measured.
    pub failures: Vec<Failure>,
    /// Per series: bpvf rising and errors falling along the ladder.
    pub monotone: Vec<Monotonicity>,
    /// Row positions on each codec's lower envelope.
    pub envelope: Envelopes,
    /// Wall time of the whole sweep, when the caller timed it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub total_seconds: Option<f64>,
    /// How the points were scheduled: a thread count, `"rayon"` (its pool), `"dask"`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub jobs: Option<Value>,
    /// How the input was read: `"whole"` (in memory; [`SweepDocument::new`]'s) or `"streamed"`
    /// (every point encoded from a read of the input and measured against a second, one at a
    /// time, within the memory budget).
    pub search_input: &'static str,
}

impl SweepDocument {
    /// The document of `sweep` on an input of `(vertices, frames)`.
    pub fn new(input: &str, (vertices, frames): (usize, usize), eval: &EvalOptions, sweep: &Sweep) -> Self {
        let ladder_points: Vec<Point> = sweep.points.iter().filter(|p| !p.refined).cloned().collect();
        Self {
            input: input.to_owned(),
            vertices,
            frames,
            eval_options: *eval,
            rows: sweep.points.iter().map(SweepRow::from).collect(),
            failures: sweep.failures.clone(),
            // Along each ladder's own steps: a refined point lies between two of them.
            monotone: monotone_report(&ladder_points),
            envelope: Envelopes {
                kg: envelope(&sweep.points, TargetMetric::Kg),
                sted: envelope(&sweep.points, TargetMetric::Sted),
                joint: joint_envelope(&sweep.points),
            },
            total_seconds: None,
            jobs: None,
            search_input: "whole",
        }
    }

    /// The document as a JSON value (keys in alphabetical order, as in every document).
    pub fn to_json(&self) -> Result<Value> {
        Ok(serde_json::to_value(self)?)
    }

    /// The document as pretty-printed JSON text ending in a newline.
    pub fn to_json_text(&self) -> Result<String> {
        Ok(serde_json::to_string_pretty(&self.to_json()?)? + "\n")
    }
}

/// The header of [`csv_text`]: the [`SweepRow`] fields a CSV line holds, in order.
pub fn csv_columns() -> Vec<&'static str> {
    csv::header_and_cells(&SweepRow::template(), NOT_IN_CSV).map(|(names, _)| names).unwrap_or_default()
}

/// The rows as CSV: a header line of [`csv_columns`], then one line per point. `params` is
/// `key=value` pairs separated by `;` (so the field needs no quoting); a missing metric is an
/// empty field.
pub fn csv_text(points: &[Point]) -> Result<String> {
    let mut out = csv::line(&csv_columns().iter().map(|c| c.to_string()).collect::<Vec<_>>());
    out.push('\n');
    for p in points {
        let (_, cells) =
            csv::header_and_cells(&SweepRow::from(p), NOT_IN_CSV).map_err(|e| EvalError::Csv(e.to_string()))?;
        out.push_str(&csv::line(&cells));
        out.push('\n');
    }
    Ok(out)
}

/// Every metric of a report as JSON, keys named after the metrics (`kg`, `sted`, …,
/// `sted_params`, `notes`). Undefined metrics are `null`.
pub fn report_json(report: &MetricReport) -> Value {
    serde_json::to_value(report).unwrap_or(Value::Null)
}

/// Writes `text` to `path` (replacing it) through a temporary file renamed into place when
/// complete, naming the file in the error. Callers check first whether `path` may be replaced
/// ([`OutputPolicy::check`](animcodec_io::output::OutputPolicy::check)).
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    Ok(animcodec_io::output::OutputPolicy::new(true).write(path, text.as_bytes())?)
}
