//! The declared error bound of `pca-aoi` (README, "Error bound"), accumulated frame by frame
//! so the encoder can declare it from the frames it was pushed.

use codec_core::{Animation, ErrorBound};

use crate::dictionary::Mode;
use crate::params::{Coding, PcaAoiParams};

/// The relative RMS bound (see the README, "Error bound"): the projection never removes more
/// than the data's spread around each frame's centroid, scaled by how far the quantized
/// dictionary is from orthonormal, plus the feature quantization error and `f32` rounding.
pub(crate) fn error_bound(p: &PcaAoiParams, animation: &Animation) -> ErrorBound {
    let mut stats = BoundStats::new(animation.vertex_count());
    stats.push(animation.positions());
    stats.bound(p)
}

/// What [`error_bound`] needs of the input, accumulated frame by frame (the encoder
/// declares its bound from the frames it was pushed, so the stream driver's self-check keeps
/// no copy of the whole input). The same arithmetic in the same order as on the whole
/// animation, so both give the same bound bit for bit.
#[derive(Debug, Clone)]
pub(crate) struct BoundStats {
    v: usize,
    lo: [f32; 3],
    hi: [f32; 3],
    max_abs: f64,
    centered: f64,
    coords: usize,
}

impl BoundStats {
    pub(crate) fn new(v: usize) -> Self {
        Self { v, lo: [f32::INFINITY; 3], hi: [f32::NEG_INFINITY; 3], max_abs: 0.0, centered: 0.0, coords: 0 }
    }

    /// Adds whole frames (frame-major).
    pub(crate) fn push(&mut self, frames: &[f32]) {
        let v = self.v;
        if v == 0 {
            return;
        }
        for frame in frames.chunks_exact(v * 3) {
            let mut c = [0.0f64; 3];
            for q in frame.chunks_exact(3) {
                for a in 0..3 {
                    self.lo[a] = self.lo[a].min(q[a]);
                    self.hi[a] = self.hi[a].max(q[a]);
                    self.max_abs = self.max_abs.max(q[a].abs() as f64);
                    c[a] += q[a] as f64;
                }
            }
            for x in &mut c {
                *x /= v as f64;
            }
            for q in frame.chunks_exact(3) {
                for a in 0..3 {
                    self.centered += (q[a] as f64 - c[a]).powi(2);
                }
            }
            self.coords += frame.len();
        }
    }

    pub(crate) fn bound(&self, p: &PcaAoiParams) -> ErrorBound {
        let v = self.v;
        // As `Animation::bounding_box_diagonal` (zero for an empty animation).
        let diag = if self.coords < 3 {
            0.0
        } else {
            (0..3).map(|a| (self.hi[a] as f64 - self.lo[a] as f64).powi(2)).sum::<f64>().sqrt()
        };
        bound_from(p, v, diag, self.max_abs, self.centered, self.coords)
    }
}

fn bound_from(p: &PcaAoiParams, v: usize, diag: f64, max_abs: f64, centered: f64, coords: usize) -> ErrorBound {
    if diag == 0.0 {
        // Every vertex of every frame at one point: centered blocks are zero and the stored
        // f32 means are exact.
        return ErrorBound {
            max_coordinate_error: Some(2.0 * max_abs * f32::EPSILON as f64),
            relative_rms_error: None,
        };
    }
    let coords = coords as f64;
    let rounding = 3.0 * (max_abs + diag) * f32::EPSILON as f64;
    if p.coding == Coding::Toolkit {
        // The toolkit encoder keeps every cluster's block error below its spread about the
        // stored means (it codes nothing rather than more, see `toolkit_cluster`); the spreads
        // sum to at most the spread about each frame's centroid.
        return ErrorBound {
            max_coordinate_error: None,
            relative_rms_error: Some(((centered / coords).sqrt() + rounding) / diag),
        };
    }
    let block = p.block as usize;
    let e_max = (3 * block).max(v) as f64;
    let k_max = match p.mode {
        Mode::Qaoi => (3 * block).min(v),
        _ => (p.k as usize).min(3 * block).min(v),
    } as f64;
    let eps32 = f32::EPSILON as f64;
    let levels = |bits: u8| ((1u64 << bits) - 1) as f64;
    let eps_d = (e_max * k_max).sqrt() * (1.0 / levels(p.dict_bits) + eps32);
    let grow = (1.0 + eps_d).powi(2);
    let projection = 1.0f64.max(grow - 1.0) * (centered / coords).sqrt();
    let features = grow * k_max.sqrt() * diag * (1.0 / levels(p.feat_bits) + 2.0 * eps32);
    ErrorBound { max_coordinate_error: None, relative_rms_error: Some((projection + features + rounding) / diag) }
}
