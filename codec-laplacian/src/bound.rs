//! The declared error bound: the RMS error is at most the RMS distance of the vertices to
//! their frame's centroid, relative to the bounding-box diagonal, plus `f32` rounding. The
//! encoder holds every packet's squared error within that packet's centred energy
//! (`packet::encode`), and the packets' energies sum to the animation's.

use codec_core::ErrorBound;

/// What the bound needs of the input, accumulated frame by frame (the encoder declares its
/// bound from the frames it was pushed, with the same arithmetic in the same order as on the
/// whole animation, so both give the same bound bit for bit).
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
            for q in frame.chunks_exact(3) {
                for (a, &x) in q.iter().enumerate() {
                    self.lo[a] = self.lo[a].min(x);
                    self.hi[a] = self.hi[a].max(x);
                    self.max_abs = self.max_abs.max(x.abs() as f64);
                }
            }
            self.centered += crate::packet::centered_energy(frame, v);
            self.coords += frame.len();
        }
    }

    pub(crate) fn bound(&self) -> ErrorBound {
        let diag = if self.coords < 3 {
            0.0
        } else {
            (0..3).map(|a| (self.hi[a] as f64 - self.lo[a] as f64).powi(2)).sum::<f64>().sqrt()
        };
        let rounding = 3.0 * (self.max_abs + diag) * f32::EPSILON as f64;
        if diag == 0.0 {
            // Every vertex of every frame at one point: the packets are raw (zero centred
            // energy admits no error), so only rounding remains.
            return ErrorBound { max_coordinate_error: Some(rounding), relative_rms_error: None };
        }
        let rms = (self.centered / self.coords as f64).sqrt();
        ErrorBound { max_coordinate_error: None, relative_rms_error: Some((rms + rounding) / diag) }
    }
}
