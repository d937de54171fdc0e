//! The declared error bounds of `stseg` (README, "Error bound"): one per coding.

use codec_core::Animation;

use crate::mesh;
use crate::params::{Centering, StsegParams};

/// The declared relative RMS bound (see README "Error bound"). With `D` the animation's
/// bounding-box diagonal, `G` = `groups`, `T` the longest segment, `δ = T/(2^coef_bits − 1)`:
/// - truncation at persistence ω: the discarded energy of each group's η-extended, centred
///   block is ≤ (1−ω) of its energy; a vertex lies in at most `G` extended groups and each
///   centred coordinate is ≤ `D` away, so this term is ≤ `√((1−ω)·G/3)·D` (RMS per coordinate);
/// - coefficient quantization (each entry off by ≤ half a step of [−1, 1]): `‖W − B̂ᵀ‖₂ ≤ δ`,
///   adding ≤ `δ·D`;
/// - basis quantization: `|A| ≤ √T·D/(1−δ)`, half a step per entry, times `‖B̂‖₂ ≤ 1+δ`:
///   ≤ `√T·(1+δ)/((1−δ)(2^bits−1))·D`;
/// - mean quantization: ≤ `D/(2(2^bits−1))`; plus f32 rounding.
///
/// These add (Minkowski). `None` (no promise) when `δ ≥ 1/2`.
pub(crate) fn relative_rms_bound(p: &StsegParams, animation: &Animation) -> Option<f64> {
    let t = p.max_segment() as f64;
    let delta = t / ((1u64 << p.coef_bits) - 1) as f64;
    if delta >= 0.5 {
        return None;
    }
    let qa = ((1u64 << p.bits) - 1) as f64;
    let trunc = ((1.0 - p.omega) * p.groups as f64 / 3.0).sqrt();
    let basis = t.sqrt() * (1.0 + delta) / ((1.0 - delta) * qa);
    let diag = animation.bounding_box_diagonal();
    let (lo, hi) = animation.bounding_box();
    let mag = lo.iter().chain(&hi).fold(0.0f64, |m, &x| m.max((x as f64).abs()));
    if diag <= 0.0 {
        return Some(1e-12);
    }
    // Range of all coordinate values, every axis together: a frame-centred entry is within it.
    let all_range =
        (0..3).map(|c| hi[c] as f64).fold(f64::MIN, f64::max) - (0..3).map(|c| lo[c] as f64).fold(f64::MAX, f64::min);
    // `s`: bound on a vertex's centred 3-vector, relative to D; `mean`: mean quantization.
    let (s, mean) = match p.centering {
        Centering::Vertex => (1.0, 0.5 / qa),
        Centering::Frame => (3f64.sqrt() * all_range / diag, 0.5 * all_range / (qa * diag)),
        // A centroid-centred vertex is within D of the centroid.
        Centering::FrameAxis => (1.0, 0.5 / qa),
        Centering::None => (3f64.sqrt() * mag / diag, 0.0),
    };
    let rounding = 4.0 * mag * f32::EPSILON as f64 / diag;
    Some(s * (trunc + delta + basis) + mean + rounding + 1e-12)
}

/// The declared relative RMS bound of the toolkit coding (README "Error bound"). Per group of a
/// segment the error is at most `√E_tr + Σ_i √d_i` — the LS fit's residual is at most that of
/// the unquantized basis with the quantized mean and coefficients, i.e. truncation + mean
/// error + `Σ_j ‖A_j‖‖δB_j‖`, and the basis error adds `Σ_j ‖δA_j‖‖B̂_j‖` — where the `d_i` are
/// the component distortions the RD rule keeps within `D = quant²·Σ max(E_tr, 10⁻⁴·(1−ω)E)`.
/// With at most `N = 3 + 2T` components per group (Cauchy–Schwarz) and `(a+b)² ≤ 2a² + 2b²`,
/// the squared error is ≤ `2(1 + N·quant²)·(1−ω)·ΣE`, and `ΣE` is bounded as in
/// [`relative_rms_bound`]'s truncation term (a vertex in at most `G` extended groups).
pub(crate) fn toolkit_rms_bound(p: &StsegParams, animation: &Animation) -> Option<f64> {
    let t = p.max_segment() as f64;
    let diag = animation.bounding_box_diagonal();
    if diag <= 0.0 {
        return Some(1e-12);
    }
    let (lo, hi) = animation.bounding_box();
    let mag = lo.iter().chain(&hi).fold(0.0f64, |m, &x| m.max((x as f64).abs()));
    let all_range =
        (0..3).map(|c| hi[c] as f64).fold(f64::MIN, f64::max) - (0..3).map(|c| lo[c] as f64).fold(f64::MAX, f64::min);
    let s = match p.centering {
        Centering::Vertex | Centering::FrameAxis => 1.0,
        Centering::Frame => 3f64.sqrt() * all_range / diag,
        Centering::None => 3f64.sqrt() * mag / diag,
    };
    let n = 3.0 + 2.0 * t;
    let trunc = ((1.0 - p.omega) * p.groups as f64 / 3.0).sqrt();
    // A block below the negligible energy keeps no component: its whole centred energy is error.
    let negligible = mesh::NEGLIGIBLE_AMPLITUDE * (p.groups as f64).sqrt();
    let rounding = 4.0 * mag * f32::EPSILON as f64 / diag;
    Some(s * (trunc + negligible) * (2.0 * (1.0 + n * p.quant * p.quant)).sqrt() + rounding + 1e-12)
}
