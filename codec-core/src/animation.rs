//! The animation data model: one triangle list, positions changing every frame.

use crate::error::{Error, Result};
use crate::metadata::SceneMetadata;

/// Frame rates a stream may carry, and the ones the file readers accept (`io` re-exports this
/// constant as `formats::FRAME_RATE_RANGE`): one frame per 1000 s to 10 000 frames per second.
/// Outside it, key times `frame / fps` stop being representable or distinguishable as `f32`
/// seconds (at 1e-45 fps frame 1 is at +inf s; at 1e5 fps over a minute the key spacing nears
/// the f32 rounding step), and no capture or playback device works there. A
/// stream whose header said 1e30 fps used to decode to a `.usda` that no reader would take
/// back; the container now refuses such a rate when it is written ([`check_stream_frame_rate`])
/// and when it is read.
pub const FRAME_RATE_RANGE: std::ops::RangeInclusive<f32> = 1e-3..=1e4;

/// `fps` when a stream may carry it ([`FRAME_RATE_RANGE`]), else an error saying so.
pub fn check_stream_frame_rate(fps: f32) -> Result<f32> {
    if FRAME_RATE_RANGE.contains(&fps) {
        Ok(fps)
    } else {
        Err(Error::InvalidAnimation(format!(
            "frame rate {fps:e} is outside the range a stream may carry, {:e}..={:e} frames per second",
            FRAME_RATE_RANGE.start(),
            FRAME_RATE_RANGE.end()
        )))
    }
}

/// Fixed connectivity: the vertex count and the triangle list shared by every frame.
///
/// A topology may have no triangles (a point cloud cache) but always has at least one vertex.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Topology {
    vertex_count: usize,
    triangles: Vec<[u32; 3]>,
}

impl Topology {
    /// Builds a topology, checking that every index is below `vertex_count` and that
    /// `vertex_count` is at least one and fits in `u32`.
    ///
    /// Degenerate triangles (a repeated index) are kept: they are valid connectivity for
    /// storage, and codecs that cannot use them say so themselves.
    pub fn new(vertex_count: usize, triangles: Vec<[u32; 3]>) -> Result<Self> {
        if vertex_count == 0 {
            return Err(Error::InvalidAnimation("the animation has no vertices".into()));
        }
        if vertex_count > u32::MAX as usize {
            return Err(Error::InvalidAnimation(format!("{vertex_count} vertices do not fit in 32-bit indices")));
        }
        if let Some((t, tri)) =
            triangles.iter().enumerate().find(|(_, tri)| tri.iter().any(|&i| i as usize >= vertex_count))
        {
            return Err(Error::InvalidAnimation(format!(
                "triangle {t} has index {:?} out of range for {vertex_count} vertices",
                tri
            )));
        }
        Ok(Self { vertex_count, triangles })
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.vertex_count
    }

    /// The triangle list.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// A regular grid of `cols × rows` vertices (row-major: vertex `r * cols + c` at column
    /// `c`, row `r`), two triangles per quad with consistent winding. Fails when the grid has
    /// fewer than 2 × 2 vertices or more than `u32` indices hold.
    pub fn grid(cols: usize, rows: usize) -> Result<Self> {
        let vertex_count = cols.checked_mul(rows).filter(|&n| n <= u32::MAX as usize && cols >= 2 && rows >= 2);
        let Some(vertex_count) = vertex_count else {
            return Err(Error::InvalidAnimation(format!("a {cols} × {rows} grid is not a mesh of 32-bit indices")));
        };
        let index = |r: usize, c: usize| (r * cols + c) as u32;
        let mut triangles = Vec::with_capacity(2 * (cols - 1) * (rows - 1));
        for r in 0..rows - 1 {
            for c in 0..cols - 1 {
                let (a, b, d, e) = (index(r, c), index(r, c + 1), index(r + 1, c), index(r + 1, c + 1));
                triangles.push([a, b, e]);
                triangles.push([a, e, d]);
            }
        }
        Ok(Self { vertex_count, triangles })
    }
}

/// A mesh animation: a [`Topology`] plus frame-major `f32` positions
/// (`frames × vertices × 3`, x y z interleaved) and a frame rate.
#[derive(Debug, Clone, PartialEq)]
pub struct Animation {
    topology: Topology,
    positions: Vec<f32>,
    frame_count: usize,
    frame_rate: f32,
    metadata: SceneMetadata,
}

impl Animation {
    /// Builds an animation from its parts, validating everything:
    /// at least one frame, `positions.len()` a multiple of `3 × vertex_count`,
    /// finite coordinates, a finite positive frame rate.
    pub fn new(topology: Topology, positions: Vec<f32>, frame_rate: f32) -> Result<Self> {
        let floats_per_frame = topology.vertex_count * 3;
        if positions.is_empty() {
            return Err(Error::InvalidAnimation("the animation has no frames".into()));
        }
        if !positions.len().is_multiple_of(floats_per_frame) {
            return Err(Error::InvalidAnimation(format!(
                "{} coordinates is not a whole number of frames of {} vertices",
                positions.len(),
                topology.vertex_count
            )));
        }
        if !(frame_rate.is_finite() && frame_rate > 0.0) {
            return Err(Error::InvalidAnimation(format!("frame rate {frame_rate} is not a finite positive number")));
        }
        check_finite(&positions, topology.vertex_count, 0)?;
        let frame_count = positions.len() / floats_per_frame;
        Ok(Self { topology, positions, frame_count, frame_rate, metadata: SceneMetadata::default() })
    }

    /// Convenience constructor from a vertex count and a triangle list.
    pub fn from_parts(
        vertex_count: usize,
        triangles: Vec<[u32; 3]>,
        positions: Vec<f32>,
        frame_rate: f32,
    ) -> Result<Self> {
        Self::new(Topology::new(vertex_count, triangles)?, positions, frame_rate)
    }

    /// The shared connectivity.
    pub fn topology(&self) -> &Topology {
        &self.topology
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.topology.vertex_count
    }

    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        self.frame_count
    }

    /// The triangle list.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.topology.triangles
    }

    /// Frames per second.
    pub fn frame_rate(&self) -> f32 {
        self.frame_rate
    }

    /// What the source said about its scene (up axis, units, time line); see [`SceneMetadata`].
    pub fn metadata(&self) -> &SceneMetadata {
        &self.metadata
    }

    /// The animation with `metadata` attached (checked by [`SceneMetadata::validate`]).
    pub fn with_metadata(mut self, metadata: SceneMetadata) -> Result<Self> {
        metadata.validate()?;
        self.metadata = metadata;
        Ok(self)
    }

    /// All positions, frame-major (`frames × vertices × 3`).
    pub fn positions(&self) -> &[f32] {
        &self.positions
    }

    /// Positions of frame `t` (`vertices × 3`). Panics if `t >= frame_count()`, like slice indexing.
    pub fn frame(&self, t: usize) -> &[f32] {
        let n = self.vertex_count() * 3;
        &self.positions[t * n..(t + 1) * n]
    }

    /// Iterator over frames, each `vertices × 3` floats.
    pub fn frames(&self) -> std::slice::ChunksExact<'_, f32> {
        self.positions.chunks_exact(self.vertex_count() * 3)
    }

    /// Position of vertex `v` in frame `t`.
    pub fn vertex(&self, t: usize, v: usize) -> [f32; 3] {
        let i = (t * self.vertex_count() + v) * 3;
        [self.positions[i], self.positions[i + 1], self.positions[i + 2]]
    }

    /// Takes the animation apart into topology, positions and frame rate.
    pub fn into_parts(self) -> (Topology, Vec<f32>, f32) {
        (self.topology, self.positions, self.frame_rate)
    }

    /// Axis-aligned bounding box over all frames: `(min, max)`.
    pub fn bounding_box(&self) -> ([f32; 3], [f32; 3]) {
        bounding_box(&self.positions)
    }

    /// Length of the bounding-box diagonal over all frames.
    pub fn bounding_box_diagonal(&self) -> f64 {
        let (lo, hi) = self.bounding_box();
        (0..3).map(|a| (hi[a] as f64 - lo[a] as f64).powi(2)).sum::<f64>().sqrt()
    }
}

/// How many whole frames of `vertex_count` vertices `coordinates` interleaved xyz values hold;
/// an error when they do not make whole frames (or there are no vertices). Shared by every
/// path that takes frames in chunks (the stream encoder, the streaming cache writer).
pub fn whole_frames(coordinates: usize, vertex_count: usize) -> Result<usize> {
    let per_frame = vertex_count * 3;
    if per_frame == 0 || !coordinates.is_multiple_of(per_frame) {
        return Err(Error::InvalidAnimation(format!(
            "{coordinates} coordinates is not a whole number of frames of {vertex_count} vertices"
        )));
    }
    Ok(coordinates / per_frame)
}

/// Axis-aligned bounding box of interleaved xyz positions: `(min, max)`.
/// Returns `([0; 3], [0; 3])` for an empty slice.
pub fn bounding_box(positions: &[f32]) -> ([f32; 3], [f32; 3]) {
    if positions.len() < 3 {
        return ([0.0; 3], [0.0; 3]);
    }
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    extend_bounding_box(&mut lo, &mut hi, positions);
    (lo, hi)
}

/// Grows the box `(lo, hi)` to hold interleaved xyz `positions` (a box built frame by frame
/// from `[∞; 3]`, `[−∞; 3]` as streaming encoders and the self-check do).
pub fn extend_bounding_box(lo: &mut [f32; 3], hi: &mut [f32; 3], positions: &[f32]) {
    for p in positions.chunks_exact(3) {
        for ((l, h), &x) in lo.iter_mut().zip(hi.iter_mut()).zip(p) {
            *l = l.min(x);
            *h = h.max(x);
        }
    }
}

/// Checks that every coordinate is finite; the error names frame, vertex and axis.
/// `first_frame` offsets the reported frame number (for streaming blocks).
pub fn check_finite(positions: &[f32], vertex_count: usize, first_frame: usize) -> Result<()> {
    // Fast path: a branch-free scan of the exponent bits in blocks vectorizes (several times
    // faster than an early-exit search on a 20 MB cache); the slow search only names the culprit.
    const EXPONENT: u32 = 0x7f80_0000;
    let any_bad = positions
        .chunks(4096)
        .any(|block| block.iter().map(|x| ((x.to_bits() & EXPONENT) == EXPONENT) as u32).sum::<u32>() != 0);
    if !any_bad {
        return Ok(());
    }
    if let Some(i) = positions.iter().position(|x| !x.is_finite()) {
        let per_frame = vertex_count * 3;
        return Err(Error::InvalidAnimation(format!(
            "non-finite coordinate {} at frame {}, vertex {}, axis {}",
            positions[i],
            first_frame + i / per_frame,
            (i % per_frame) / 3,
            ["x", "y", "z"][i % 3]
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> Topology {
        Topology::new(3, vec![[0, 1, 2]]).unwrap()
    }

    #[test]
    fn rejects_bad_input_with_named_problem() {
        assert!(Topology::new(0, vec![]).is_err());
        let e = Topology::new(3, vec![[0, 1, 3]]).unwrap_err().to_string();
        assert!(e.contains("triangle 0"), "{e}");
        assert!(Animation::new(tri(), vec![], 30.0).is_err());
        assert!(Animation::new(tri(), vec![0.0; 8], 30.0).is_err());
        let mut p = vec![0.0; 18];
        p[13] = f32::NAN;
        let e = Animation::new(tri(), p, 30.0).unwrap_err().to_string();
        assert!(e.contains("frame 1, vertex 1, axis y"), "{e}");
        assert!(Animation::new(tri(), vec![0.0; 9], 0.0).is_err());
        assert!(Animation::new(tri(), vec![0.0; 9], f32::NAN).is_err());
    }

    #[test]
    fn accessors_follow_frame_major_layout() {
        let p: Vec<f32> = (0..18).map(|i| i as f32).collect();
        let a = Animation::new(tri(), p, 24.0).unwrap();
        assert_eq!(a.frame_count(), 2);
        assert_eq!(a.frame(1)[0], 9.0);
        assert_eq!(a.vertex(1, 2), [15.0, 16.0, 17.0]);
        assert_eq!(a.frames().count(), 2);
        assert_eq!(a.bounding_box(), ([0.0, 1.0, 2.0], [15.0, 16.0, 17.0]));
    }
}
