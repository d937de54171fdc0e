//! Coding toolkit shared by the codecs: what the classical mesh-animation coders get
//! their edge from, beyond one uniform step and zstd.
//!
//! - [`order`]: a deterministic connectivity-driven vertex order (breadth first over the
//!   triangle list) with causal neighbourhoods and parallelogram triples; the same structure for
//!   sequences (frames).
//! - [`predict`]: closed-loop predictive quantization along such an order (previous,
//!   neighbour average, parallelogram / linear extrapolation), with encoder-side noise shaping
//!   so neighbouring items err alike (what STED rewards).
//! - [`adaptive`]: context-adaptive binary arithmetic coding of the resulting integers on
//!   `constriction`'s range coder, and a cost model for rate estimates.
//! - [`rdq`]: per-component steps by the equal-slope (Lagrangian) rule for a target error.
//! - [`planes`]: the plain coding the simpler streams share: zigzag differences and runs of
//!   integer codes in byte planes (for zstd).
//! - [`regress`]: cross-component prediction — a field regressed locally (over causal two-ring
//!   neighbourhoods) on fields already known everywhere, e.g. later mode-1 factor columns on
//!   the leading ones.
//!
//! `codec-core/examples/toolkit_bench.rs` measures each piece's throughput.

pub mod adaptive;
pub mod order;
pub mod planes;
pub mod predict;
pub mod rdq;
pub mod regress;
