//! Decoder-side smoothing of the `U1` columns (stream version 3, beyond the paper): the
//! strengths a column may get and the neighbour averaging both sides run, bit for bit alike.

use codec_core::toolkit::order::CausalGraph;
use codec_core::{Error, Result};

use crate::NAME;

/// Smoothing strengths a column may get: iterations of `x ← (x + mean of its mesh
/// neighbours) / 2` (Jacobi), indexed by the level byte in the stream.
pub const SMOOTHING_ITERATIONS: [u8; 8] = [0, 1, 2, 3, 5, 8, 12, 20];

/// Decoder-side denoising of the mode-1 factor columns (stream version 3, beyond the paper).
///
/// A column's quantization error is nearly white over the vertices while the column itself is
/// smooth (the leading left singular vectors of the motion): a few steps of neighbour
/// averaging remove much more noise than signal. The encoder measures, for every candidate
/// step, the error after each strength in [`SMOOTHING_ITERATIONS`] and keeps the best (0 =
/// none), so the equal-slope rule sees the smoothed error and chooses coarser steps; the
/// decoder applies the chosen strength. White noise loses most of its edge differences —
/// what STED measures — under averaging. Neighbours are the mesh's ([`CausalGraph::mesh`]
/// edges, in coding positions); the arithmetic is the same in encoder and decoder, in a fixed
/// order, so both get the same bits.
pub struct Smoother {
    start: Vec<u32>,
    adjacent: Vec<u32>,
}

impl Smoother {
    /// Adjacency of `graph`'s positions (each earlier-neighbour edge both ways, in
    /// [`CausalGraph::adjacency`]'s order, which the smoothing sums in).
    pub fn new(graph: &CausalGraph) -> Self {
        let (start, adjacent) = graph.adjacency();
        Self { start, adjacent }
    }

    /// One averaging step of `x` (position order) into `out`.
    pub(super) fn step(&self, x: &[f64], out: &mut [f64]) {
        for p in 0..x.len() {
            let nb = &self.adjacent[self.start[p] as usize..self.start[p + 1] as usize];
            out[p] = if nb.is_empty() {
                x[p]
            } else {
                let sum: f64 = nb.iter().map(|&q| x[q as usize]).sum();
                0.5 * (x[p] + sum / nb.len() as f64)
            };
        }
    }

    /// `iterations` averaging steps of `x` in place (`tmp` is scratch).
    pub(super) fn smooth(&self, x: &mut Vec<f64>, iterations: usize, tmp: &mut Vec<f64>) {
        tmp.resize(x.len(), 0.0);
        for _ in 0..iterations {
            self.step(x, tmp);
            std::mem::swap(x, tmp);
        }
    }

    /// Applies the stream's level per column to `u1` (`K × v` row-major, vertex order) given
    /// the mesh order the smoother was built on. Unknown levels are an error.
    pub fn apply_columns(&self, graph: &CausalGraph, u1: &mut [f64], v: usize, levels: &[u8]) -> Result<()> {
        let (mut col, mut tmp) = (Vec::new(), Vec::new());
        for (i, &level) in levels.iter().enumerate().take(v) {
            let iterations = *SMOOTHING_ITERATIONS
                .get(level as usize)
                .ok_or_else(|| Error::malformed(NAME, "smoothing", format!("level {level} of column {i}, at most 7")))?
                as usize;
            if iterations == 0 {
                continue;
            }
            col.clear();
            col.extend(graph.order().iter().map(|&x| u1[x as usize * v + i]));
            self.smooth(&mut col, iterations, &mut tmp);
            for (p, &x) in graph.order().iter().enumerate() {
                u1[x as usize * v + i] = col[p];
            }
        }
        Ok(())
    }
}
