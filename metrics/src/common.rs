//! Checks shared by every metric and small geometric helpers.

use codec_core::{Animation, Error, Result, Topology};

/// Context string used in error messages.
pub(crate) const CTX: &str = "metrics";

/// Fails unless `reference` and `candidate` have the same vertex count, frame count and
/// triangle list: every metric here compares vertex `v` of frame `t` with vertex `v` of frame `t`.
pub fn check_compatible(reference: &Animation, candidate: &Animation) -> Result<()> {
    check_compatible_shapes(
        (reference.topology(), reference.frame_count()),
        (candidate.topology(), candidate.frame_count()),
    )
}

/// [`check_compatible`] on what two animations are made of, `(topology, frame count)` each:
/// for sides that are read frame by frame and never held whole.
pub fn check_compatible_shapes(reference: (&Topology, usize), candidate: (&Topology, usize)) -> Result<()> {
    let ((rtop, rframes), (ctop, cframes)) = (reference, candidate);
    if rtop.vertex_count() != ctop.vertex_count() {
        return Err(Error::InvalidAnimation(format!(
            "{CTX}: reference has {} vertices but candidate has {}",
            rtop.vertex_count(),
            ctop.vertex_count()
        )));
    }
    if rframes != cframes {
        return Err(Error::InvalidAnimation(format!(
            "{CTX}: reference has {rframes} frames but candidate has {cframes}"
        )));
    }
    let (rt, ct) = (rtop.triangles(), ctop.triangles());
    if rt.len() != ct.len() {
        return Err(Error::InvalidAnimation(format!(
            "{CTX}: reference has {} triangles but candidate has {}",
            rt.len(),
            ct.len()
        )));
    }
    // A decoded stream keeps every oriented triangle but stores them in canonical order
    // (`codec_core::connectivity`), so the comparison is of the triangle sets.
    if rt != ct && !codec_core::connectivity::same_triangles(rtop, ctop) {
        let (rc, cc) =
            (codec_core::connectivity::canonical_order(rtop), codec_core::connectivity::canonical_order(ctop));
        let i = rc.triangles().iter().zip(cc.triangles()).position(|(a, b)| a != b).unwrap_or(0);
        return Err(Error::InvalidAnimation(format!(
            "{CTX}: topology differs at triangle {i} in canonical order (smallest index first, sorted): \
             reference {:?}, candidate {:?}",
            rc.triangles()[i],
            cc.triangles()[i]
        )));
    }
    Ok(())
}

/// Point `v` of an interleaved xyz `f32` frame, widened to `f64`.
#[inline]
pub(crate) fn point(frame: &[f32], v: usize) -> [f64; 3] {
    [frame[3 * v] as f64, frame[3 * v + 1] as f64, frame[3 * v + 2] as f64]
}

#[inline]
pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline]
pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
pub(crate) fn norm2(a: [f64; 3]) -> f64 {
    dot(a, a)
}

/// Squared distance between vertex `v` of two frames.
#[inline]
pub(crate) fn vertex_dist2(a: &[f32], b: &[f32], v: usize) -> f64 {
    norm2(sub(point(a, v), point(b, v)))
}

/// The unique undirected edges of a triangle list, `(lo, hi)` with `lo < hi`, sorted.
/// Degenerate triangles contribute only their non-degenerate edges.
pub fn unique_edges(triangles: &[[u32; 3]]) -> Vec<[u32; 2]> {
    let mut edges: Vec<[u32; 2]> = Vec::with_capacity(triangles.len() * 3);
    for t in triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            if a != b {
                edges.push([a.min(b), a.max(b)]);
            }
        }
    }
    edges.sort_unstable();
    edges.dedup();
    edges
}

#[cfg(test)]
mod tests {
    use super::*;

    fn anim(v: usize, tris: Vec<[u32; 3]>, frames: usize) -> Animation {
        Animation::from_parts(v, tris, vec![0.5; v * 3 * frames], 30.0).unwrap()
    }

    #[test]
    fn mismatches_are_named() {
        let a = anim(3, vec![[0, 1, 2]], 2);
        let e = check_compatible(&a, &anim(4, vec![[0, 1, 2]], 2)).unwrap_err().to_string();
        assert!(e.contains("3 vertices") && e.contains("candidate has 4"), "{e}");
        let e = check_compatible(&a, &anim(3, vec![[0, 1, 2]], 3)).unwrap_err().to_string();
        assert!(e.contains("frames"), "{e}");
        let e = check_compatible(&a, &anim(3, vec![[0, 2, 1]], 2)).unwrap_err().to_string();
        assert!(e.contains("triangle 0"), "{e}");
        let e = check_compatible(&a, &anim(3, vec![], 2)).unwrap_err().to_string();
        assert!(e.contains("triangles"), "{e}");
        assert!(check_compatible(&a, &a.clone()).is_ok());
    }

    #[test]
    fn unique_edges_dedups_shared_and_degenerate() {
        // Two triangles sharing edge 1-2, plus a degenerate one repeating vertex 3.
        let e = unique_edges(&[[0, 1, 2], [2, 1, 3], [3, 3, 0]]);
        assert_eq!(e, vec![[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]);
    }
}
