//! Vertex matching by trajectory: which candidate vertex plays each reference vertex, when
//! the candidate stores the same animation with its vertices reordered, welded (gltfpack and
//! `animcodec export` merge vertices with identical trajectories) or split (Draco splits a
//! point where an attribute seam runs through it).
//!
//! Each reference vertex is matched to the candidate vertex whose trajectory is nearest: the
//! smallest sum over every frame of the squared distance between the two positions. Several
//! reference vertices may share one candidate vertex (a weld). The match is refused when it
//! would not say which vertex is which:
//! - **ambiguous**: a reference vertex farther than [`MATCH_TOLERANCE`] from its nearest
//!   candidate trajectory, whose second-nearest candidate trajectory (one that differs from the
//!   nearest) is less than [`AMBIGUITY_RATIO`] times as far. Closer matches are accepted
//!   whatever lies near them: two vertices closer together than a file's quantization step
//!   (Draco's, gltfpack's) cannot be told apart, and either choice is within that step;
//! - **unmatched**: a candidate vertex no reference vertex is matched to, whose trajectory is
//!   farther from every reference vertex than the worst accepted match and than
//!   [`MATCH_TOLERANCE`] (the candidate has geometry the reference lacks; a split copy of a
//!   matched vertex passes);
//!
//! Candidate vertices with identical trajectories (split copies) are handed out in turn to the
//! reference vertices that match them, so duplicates on both sides pair up one to one.
//! - different frame counts.
//!
//! Cost: candidates are looked up in a grid over their first-frame positions (the 27 cells
//! around the reference vertex, cells of 1/500 of the bounding-box diagonal), falling back to
//! every candidate when those cells are empty.

use std::collections::HashMap;

use codec_core::{Animation, Error, Result};

/// A reference vertex's match is ambiguous when another candidate trajectory lies less than
/// this many times as far (RMS over the frames) as the nearest one.
pub const AMBIGUITY_RATIO: f64 = 2.0;

/// Matches within this RMS distance (a fraction of the reference's bounding-box diagonal) are
/// never ambiguous: 10⁻³, eight times Draco's 14-bit quantization step and far above
/// gltfpack's.
pub const MATCH_TOLERANCE: f64 = 1e-3;

/// The result of [`match_vertices`].
#[derive(Debug, Clone, PartialEq)]
pub struct VertexMatch {
    /// For each reference vertex, the candidate vertex that plays it.
    pub map: Vec<usize>,
    /// Largest RMS (over the frames) distance between a reference vertex and its match.
    pub worst_distance: f64,
    /// Candidate vertices matched by more than one reference vertex (welds).
    pub shared: usize,
    /// Candidate vertices no reference vertex is matched to (split copies).
    pub unused: usize,
}

impl VertexMatch {
    /// The candidate's positions in the reference's vertex order, with the reference's
    /// triangles and the candidate's frame rate.
    pub fn apply(&self, reference: &Animation, candidate: &Animation) -> Result<Animation> {
        let mut positions = Vec::with_capacity(reference.positions().len());
        for f in 0..candidate.frame_count() {
            let frame = candidate.frame(f);
            for &c in &self.map {
                positions.extend_from_slice(&frame[3 * c..3 * c + 3]);
            }
        }
        Animation::from_parts(
            reference.vertex_count(),
            reference.triangles().to_vec(),
            positions,
            candidate.frame_rate(),
        )
    }
}

const CTX: &str = "vertex matching";

/// Squared distance between the trajectories of vertex `a` of `x` and vertex `b` of `y`,
/// summed over the frames.
fn distance(x: &Animation, a: usize, y: &Animation, b: usize) -> f64 {
    (0..x.frame_count())
        .map(|f| {
            let (p, q) = (&x.frame(f)[3 * a..3 * a + 3], &y.frame(f)[3 * b..3 * b + 3]);
            (0..3).map(|k| (p[k] as f64 - q[k] as f64).powi(2)).sum::<f64>()
        })
        .sum()
}

/// First-frame grid of one animation's vertices.
struct Grid {
    cell: f64,
    cells: HashMap<[i64; 3], Vec<usize>>,
    count: usize,
}

impl Grid {
    fn new(a: &Animation, cell: f64) -> Self {
        let mut cells: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
        for v in 0..a.vertex_count() {
            cells.entry(Self::key(cell, &a.frame(0)[3 * v..3 * v + 3])).or_default().push(v);
        }
        Self { cell, cells, count: a.vertex_count() }
    }

    fn key(cell: f64, p: &[f32]) -> [i64; 3] {
        std::array::from_fn(|k| (p[k] as f64 / cell).floor() as i64)
    }

    /// The vertices in the 27 cells around `p`, else every vertex.
    fn near(&self, p: &[f32]) -> Vec<usize> {
        let c = Self::key(self.cell, p);
        let mut out = Vec::new();
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(list) = self.cells.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                        out.extend_from_slice(list);
                    }
                }
            }
        }
        if out.is_empty() {
            out = (0..self.count).collect();
        }
        out
    }
}

/// Matches every vertex of `reference` to the candidate vertex with the nearest trajectory
/// (see the module docs for when the match is refused).
pub fn match_vertices(reference: &Animation, candidate: &Animation) -> Result<VertexMatch> {
    if reference.frame_count() != candidate.frame_count() {
        return Err(Error::InvalidAnimation(format!(
            "{CTX}: reference has {} frames but candidate has {}",
            reference.frame_count(),
            candidate.frame_count()
        )));
    }
    let frames = reference.frame_count() as f64;
    let rms = |d: f64| (d / frames).sqrt();
    let diagonal = reference.bounding_box_diagonal().max(f64::MIN_POSITIVE);
    let candidates = Grid::new(candidate, diagonal * 2e-3);
    let mut map = Vec::with_capacity(reference.vertex_count());
    let mut uses = vec![0u32; candidate.vertex_count()];
    let mut worst = 0.0f64;
    for r in 0..reference.vertex_count() {
        let near = candidates.near(&reference.frame(0)[3 * r..3 * r + 3]);
        let scored: Vec<(f64, usize)> = near.iter().map(|&c| (distance(reference, r, candidate, c), c)).collect();
        let d1 = scored.iter().map(|s| s.0).fold(f64::INFINITY, f64::min);
        // Among exact ties (copies of one trajectory), the copy used least so far.
        let c1 = scored.iter().filter(|s| s.0 == d1).map(|s| s.1).min_by_key(|&c| uses[c]).expect("a candidate vertex");
        uses[c1] += 1;
        // The nearest candidate trajectory that differs from the best one (a split copy of
        // the best one is not a rival).
        let rival = scored
            .iter()
            .filter(|&&(_, c)| c != c1 && distance(candidate, c, candidate, c1) > 0.0)
            .map(|&(d, c)| (d, c))
            .min_by(|a, b| a.0.total_cmp(&b.0));
        if let Some((d2, c2)) = rival {
            if rms(d1) > MATCH_TOLERANCE * diagonal && rms(d2) < AMBIGUITY_RATIO * rms(d1) {
                return Err(Error::InvalidAnimation(format!(
                    "{CTX}: ambiguous: reference vertex {r} follows candidate vertex {c1} at an RMS distance of \
                     {:.3e} and candidate vertex {c2} at {:.3e} (less than {AMBIGUITY_RATIO}× as far): the two \
                     files do not play the same vertices closely enough to tell them apart",
                    rms(d1),
                    rms(d2)
                )));
            }
        }
        worst = worst.max(rms(d1));
        map.push(c1);
    }
    let references = Grid::new(reference, diagonal * 2e-3);
    for (c, _) in uses.iter().enumerate().filter(|(_, &n)| n == 0) {
        let near = references.near(&candidate.frame(0)[3 * c..3 * c + 3]);
        let nearest = near.iter().map(|&r| distance(candidate, c, reference, r)).fold(f64::INFINITY, f64::min);
        if rms(nearest) > worst.max(MATCH_TOLERANCE * diagonal) {
            return Err(Error::InvalidAnimation(format!(
                "{CTX}: candidate vertex {c} follows no reference vertex (the nearest is at an RMS distance of \
                 {:.3e}, farther than every match, {worst:.3e}): the candidate has geometry the reference lacks \
                 ({} candidate vertices, {} reference vertices)",
                rms(nearest),
                candidate.vertex_count(),
                reference.vertex_count()
            )));
        }
    }
    Ok(VertexMatch {
        map,
        worst_distance: worst,
        shared: uses.iter().filter(|&&n| n > 1).count(),
        unused: uses.iter().filter(|&&n| n == 0).count(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` vertices on a line moving up over 3 frames; vertex `v` at x = v.
    fn line(xs: &[f32]) -> Animation {
        let mut positions = Vec::new();
        for f in 0..3 {
            for &x in xs {
                positions.extend_from_slice(&[x, f as f32, 0.0]);
            }
        }
        let triangles = if xs.len() >= 3 { vec![[0, 1, 2]] } else { vec![] };
        Animation::from_parts(xs.len(), triangles, positions, 30.0).unwrap()
    }

    #[test]
    fn reordered_vertices_are_matched() {
        let reference = line(&[0.0, 1.0, 2.0, 3.0]);
        let candidate = line(&[3.0, 0.0, 2.001, 1.0]);
        let m = match_vertices(&reference, &candidate).unwrap();
        assert_eq!(m.map, vec![1, 3, 2, 0]);
        assert!((m.worst_distance - 0.001).abs() < 1e-6, "{}", m.worst_distance);
        let played = m.apply(&reference, &candidate).unwrap();
        assert_eq!(played.frame(1)[3..6], [1.0, 1.0, 0.0]);
        assert_eq!(played.triangles(), reference.triangles());
    }

    #[test]
    fn welded_and_split_vertices_are_matched() {
        // Reference vertices 1 and 2 follow one trajectory (welded in the candidate); the
        // candidate's vertex 3 is a split copy of its vertex 0.
        let reference = line(&[0.0, 5.0, 5.0, 9.0]);
        let candidate = line(&[0.0, 5.0, 9.0, 0.0]);
        let m = match_vertices(&reference, &candidate).unwrap();
        assert_eq!(m.map, vec![0, 1, 1, 2]);
        assert_eq!((m.shared, m.unused), (1, 1));
        // Two candidate vertices closer together than the tolerance: the nearest is taken.
        let m = match_vertices(&reference, &line(&[0.0, 4.9999, 5.0002, 9.0])).unwrap();
        assert_eq!(m.map, vec![0, 1, 1, 3]);
    }

    #[test]
    fn ambiguous_and_extra_vertices_are_refused() {
        let reference = line(&[0.0, 1.0, 2.0]);
        // Reference vertex 1 lies halfway between candidate vertices 1 and 2.
        let e = match_vertices(&reference, &line(&[0.0, 0.9, 1.1, 2.0])).unwrap_err().to_string();
        assert!(e.contains("ambiguous: reference vertex 1"), "{e}");
        // The candidate has a vertex far from every reference vertex.
        let e = match_vertices(&reference, &line(&[0.0, 1.0, 2.0, 7.0])).unwrap_err().to_string();
        assert!(e.contains("candidate vertex 3 follows no reference vertex"), "{e}");
        let mut short = line(&[0.0, 1.0, 2.0]).positions().to_vec();
        short.truncate(6 * 3);
        let two = Animation::from_parts(3, vec![[0, 1, 2]], short, 30.0).unwrap();
        assert!(match_vertices(&reference, &two).unwrap_err().to_string().contains("frames"));
    }
}
