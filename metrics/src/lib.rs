//! Error metrics for mesh animations.
//!
//! Every metric takes a `(reference, candidate)` pair of [`Animation`](codec_core::Animation)s with the same vertex
//! count, frame count and triangle list (checked: a mismatch is an `Err`, never a panic):
//!
//! * [`kg_error`] — Karni & Gotsman's KG error (percent),
//! * [`displacement_stats`] — MSE, RMSE (absolute and relative to the bounding-box
//!   diagonal) and the largest vertex displacement,
//! * [`hausdorff()`] — per-frame symmetric vertex-to-surface Hausdorff distance,
//! * [`sted()`] — Váša & Skala's spatio-temporal edge difference with [`StedParams`],
//! * [`per_vertex_displacement`], [`sted_with_fields`] — per-vertex fields for heatmaps,
//! * [`bpvf()`] / [`geometry_bpvf`] — bits per vertex per frame from byte counts,
//! * [`part_errors`] — the KG error of every connected part against its own spread,
//! * [`evaluate`] — everything at once as a serializable [`MetricReport`],
//! * [`StreamingEvaluator`] — the same report over frames as they arrive, in bounded memory.

pub mod bpvf;
pub mod common;
pub mod displacement;
pub mod hausdorff;
pub mod matching;
pub mod parts;
pub mod report;
pub mod sted;
pub mod streaming;

pub use bpvf::{bpvf, geometry_bpvf};
pub use common::{check_compatible, check_compatible_shapes};
pub use displacement::{displacement_stats, kg_error, per_vertex_displacement, DisplacementStats, VertexDisplacement};
pub use hausdorff::{
    hausdorff, isolated_vertex_count, point_triangle_distance, vertex_to_surface_distances, HausdorffMode,
    HausdorffStats,
};
pub use matching::{match_vertices, VertexMatch};
pub use parts::{
    connected_parts, part_errors, visible_parts, worst_part, PartError, Parts, NO_PART, PART_SPREAD_FLOOR,
};
pub use report::{evaluate, EvalOptions, MetricReport};
pub use sted::{diameter, sted, sted_local_deviations, sted_with_fields, EdgeDifference, StedParams, StedResult};
pub use streaming::StreamingEvaluator;
