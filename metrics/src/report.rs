//! [`evaluate`]: every metric at once, as one serializable [`MetricReport`].

use codec_core::{Animation, Result};
use serde::Serialize;

use crate::common::check_compatible;
use crate::displacement::{displacement_stats, kg_error, DisplacementStats};
use crate::hausdorff::{hausdorff, isolated_vertex_count, HausdorffMode, HausdorffStats};
use crate::parts::{part_errors, worst_part, PartError};
use crate::sted::{sted, StedParams, StedResult};

/// What [`evaluate`] computes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct EvalOptions {
    /// STED parameters.
    pub sted: StedParams,
    /// Compute STED (default true).
    pub compute_sted: bool,
    /// Compute the Hausdorff distance, the slowest metric (default true).
    pub compute_hausdorff: bool,
}

impl MetricReport {
    /// The KG a quality bound applies to: the larger of the whole animation's and the worst
    /// part's (a large static part must not hide a destroyed small one). `None` when
    /// the global KG is undefined.
    pub fn kg_bound(&self) -> Option<f64> {
        let part = self.worst_part.as_ref().and_then(|w| w.kg);
        self.kg.map(|kg| part.map_or(kg, |p| kg.max(p)))
    }

    /// The worst part's KG, percent (`None` without parts).
    pub fn worst_part_kg(&self) -> Option<f64> {
        self.worst_part.as_ref().and_then(|w| w.kg)
    }
}

impl Default for EvalOptions {
    fn default() -> Self {
        Self { sted: StedParams::default(), compute_sted: true, compute_hausdorff: true }
    }
}

/// All metrics of a `(reference, candidate)` pair. A metric that is undefined for the input
/// (KG of a reference collapsed to a point, STED of a point cloud, relative values of a
/// zero-size box) or was not requested is `None` (JSON `null`), with the reason in `notes`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MetricReport {
    /// KG error in percent.
    pub kg: Option<f64>,
    /// `sqrt(sted_spatial² + c²·sted_temporal²)`.
    pub sted: Option<f64>,
    /// STED spatial part.
    pub sted_spatial: Option<f64>,
    /// STED temporal part (`None` with a note when undefined: one frame, or a point-sized frame 0).
    pub sted_temporal: Option<f64>,
    /// Largest per-frame symmetric Hausdorff distance.
    pub hausdorff: Option<f64>,
    /// Mean over frames of the per-frame Hausdorff distance.
    pub hausdorff_mean: Option<f64>,
    /// `hausdorff` over the reference bounding-box diagonal.
    pub hausdorff_relative: Option<f64>,
    /// `hausdorff_mean` over the reference bounding-box diagonal.
    pub hausdorff_mean_relative: Option<f64>,
    /// Point-to-triangle, or point-to-point for meshes without triangles.
    pub hausdorff_mode: Option<HausdorffMode>,
    /// Mean squared vertex displacement.
    pub mse: f64,
    /// Root of `mse`.
    pub rmse: f64,
    /// `mse / diag²`.
    pub mse_relative: Option<f64>,
    /// `rmse / diag`.
    pub rmse_relative: Option<f64>,
    /// Largest vertex displacement.
    pub max_error: f64,
    /// Number of parts: connected components of the triangles, seams welded (isolated vertices
    /// are in none; see [`crate::parts::visible_parts`]).
    pub parts: usize,
    /// The part of largest KG against its own spread (`None` without triangles): the
    /// default quality and a `kg=` target hold for it as for the whole.
    pub worst_part: Option<PartError>,
    /// STED parameters used (reported even when STED was skipped).
    pub sted_params: StedParams,
    /// Reference bounding-box diagonal over all frames (`diag` above).
    pub bbox_diagonal: f64,
    /// Vertices per frame (JSON `vertices`, the spelling of every animcodec document: docs/json.md).
    #[serde(rename = "vertices")]
    pub vertex_count: usize,
    /// Frames (JSON `frames`).
    #[serde(rename = "frames")]
    pub frame_count: usize,
    /// Why a metric is missing, and other remarks.
    pub notes: Vec<String>,
}

/// Computes every metric. Fails on mismatched animations or invalid [`StedParams`]; metrics
/// that are undefined for valid input are `None` with a note instead.
pub fn evaluate(reference: &Animation, candidate: &Animation, options: &EvalOptions) -> Result<MetricReport> {
    check_compatible(reference, candidate)?;
    options.sted.validate()?;
    let mut notes = Vec::new();
    let disp = displacement_stats(reference, candidate)?;
    if disp.mse_relative.is_none() {
        notes.push("relative values undefined: the reference bounding box has zero diagonal".to_string());
    }
    let kg = kg_error(reference, candidate).map_err(|e| notes.push(e.to_string())).ok();
    let (parts, errors) = part_errors(reference, candidate)?;
    let mut worst = worst_part(&errors).cloned();
    // One part holding every vertex is the whole animation: its KG is the global KG (the same
    // ratio summed in another order), taken as is so that a single-component input meets a
    // bound exactly as before (a target set to a measured KG stays met).
    if let Some(w) = worst.as_mut().filter(|_| parts.count() == 1 && parts.isolated() == 0 && kg.is_some()) {
        w.kg = kg;
    }
    let st = if options.compute_sted {
        sted(reference, candidate, &options.sted).map_err(|e| notes.push(e.to_string())).ok()
    } else {
        notes.push("sted not requested".to_string());
        None
    };
    let h = if options.compute_hausdorff { Some(hausdorff(reference, candidate)?) } else { None };
    let counts = ReportCounts {
        parts: parts.count(),
        vertices: reference.vertex_count(),
        frames: reference.frame_count(),
        isolated: isolated_vertex_count(reference.triangles(), reference.vertex_count()),
    };
    Ok(assemble(kg, st, h, disp, worst, counts, options, notes))
}

/// Sizes a [`MetricReport`] states beside the metrics.
pub(crate) struct ReportCounts {
    /// Visible parts.
    pub parts: usize,
    /// Vertices per frame.
    pub vertices: usize,
    /// Frames.
    pub frames: usize,
    /// Vertices in no triangle (measured as points by Hausdorff).
    pub isolated: usize,
}

/// The report of [`evaluate`] and of [`StreamingEvaluator::finish`](crate::StreamingEvaluator::finish)
/// from their metrics: the notes on STED and Hausdorff added after those already in `notes`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn assemble(
    kg: Option<f64>,
    st: Option<StedResult>,
    h: Option<HausdorffStats>,
    disp: DisplacementStats,
    worst: Option<PartError>,
    counts: ReportCounts,
    options: &EvalOptions,
    mut notes: Vec<String>,
) -> MetricReport {
    if let Some(s) = &st {
        if !s.temporal_defined {
            notes.push(if counts.frames < 2 {
                "sted is the spatial part alone: a single frame has no temporal edges (the author's tool prints NaN)"
                    .to_string()
            } else {
                "sted is the spatial part alone: reference frame 0 is a single point (diameter 0), the temporal \
                 part's unit"
                    .to_string()
            });
        }
        if s.empty_vertex_frames > 0 {
            notes.push(format!(
                "sted_spatial: {} vertex-frames without a positive-length edge in their neighbourhood count as 0",
                s.empty_vertex_frames
            ));
        }
    }
    match &h {
        Some(h) if h.mode == HausdorffMode::PointToPoint => {
            notes.push("hausdorff: the mesh has no triangles, distances are point-to-point".to_string())
        }
        Some(_) if counts.isolated > 0 => {
            notes.push(format!("hausdorff: {} vertices in no triangle are measured as points", counts.isolated))
        }
        Some(_) => {}
        None => notes.push("hausdorff not requested".to_string()),
    }
    MetricReport {
        kg,
        sted: st.as_ref().map(|s| s.sted),
        sted_spatial: st.as_ref().map(|s| s.spatial),
        sted_temporal: st.as_ref().filter(|s| s.temporal_defined).map(|s| s.temporal),
        hausdorff: h.as_ref().map(|h| h.max),
        hausdorff_mean: h.as_ref().map(|h| h.mean),
        hausdorff_relative: h.as_ref().and_then(|h| h.max_relative),
        hausdorff_mean_relative: h.as_ref().and_then(|h| h.mean_relative),
        hausdorff_mode: h.as_ref().map(|h| h.mode),
        mse: disp.mse,
        rmse: disp.rmse,
        mse_relative: disp.mse_relative,
        rmse_relative: disp.rmse_relative,
        max_error: disp.max_error,
        parts: counts.parts,
        worst_part: worst,
        sted_params: options.sted,
        bbox_diagonal: disp.bbox_diagonal,
        vertex_count: counts.vertices,
        frame_count: counts.frames,
        notes,
    }
}
