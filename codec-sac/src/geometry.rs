//! Deformation gradients (Sumner & Popović 2004), polar decomposition and rotation log/exp maps
//! (paper §3.2, §3.3); the Poisson reconstruction from gradients is in [`crate::poisson`].

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::svd::{svd, svd_scratch, ComputeSvdVectors};
use faer::{Mat, Par};

/// A 3-vector.
pub type V3 = [f64; 3];
/// A 3 × 3 matrix, row major: `m[row][col]`.
pub type M3 = [[f64; 3]; 3];

/// The identity matrix.
pub const IDENTITY: M3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

pub(crate) fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
pub(crate) fn cross(a: V3, b: V3) -> V3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
pub(crate) fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
pub(crate) fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}

/// `a · b`.
pub fn mul(a: &M3, b: &M3) -> M3 {
    let mut out = [[0.0; 3]; 3];
    for (r, row) in out.iter_mut().enumerate() {
        for (c, x) in row.iter_mut().enumerate() {
            *x = a[r][0] * b[0][c] + a[r][1] * b[1][c] + a[r][2] * b[2][c];
        }
    }
    out
}

fn transpose(a: &M3) -> M3 {
    let mut t = [[0.0; 3]; 3];
    for (r, row) in a.iter().enumerate() {
        for (c, &x) in row.iter().enumerate() {
            t[c][r] = x;
        }
    }
    t
}

fn det(a: &M3) -> f64 {
    dot(a[0], cross(a[1], a[2]))
}

/// Inverse by the adjugate; `None` when the determinant is zero or not finite.
pub(crate) fn inverse(a: &M3) -> Option<M3> {
    let d = det(a);
    if d == 0.0 || !d.is_finite() {
        return None;
    }
    // Rows of the inverse's transpose are the cross products of the columns' complements.
    let c0 = cross(a[1], a[2]);
    let c1 = cross(a[2], a[0]);
    let c2 = cross(a[0], a[1]);
    let inv_t = [c0, c1, c2];
    let mut inv = transpose(&inv_t);
    for row in inv.iter_mut() {
        for x in row.iter_mut() {
            *x /= d;
        }
    }
    Some(inv)
}

/// The tetrahedron frame of a triangle (Sumner & Popović 2004, Eq. 1): columns `v1 − v0`,
/// `v2 − v0` and the fourth vertex offset `n / sqrt(|n|)`, `n = (v1 − v0) × (v2 − v0)`, which
/// has the length of a typical edge. `None` for a zero-area triangle.
pub fn tet_frame(p: [V3; 3]) -> Option<M3> {
    let e1 = sub(p[1], p[0]);
    let e2 = sub(p[2], p[0]);
    let n = cross(e1, e2);
    let len = norm(n);
    if len == 0.0 || !len.is_finite() {
        return None;
    }
    let s = 1.0 / len.sqrt();
    let e3 = [n[0] * s, n[1] * s, n[2] * s];
    Some([[e1[0], e2[0], e3[0]], [e1[1], e2[1], e3[1]], [e1[2], e2[2], e3[2]]])
}

/// The tet frame of `p` with a zero fourth edge when the triangle is degenerate (its normal is
/// zero) — what the deformation gradient `G = V_P V_R⁻¹` uses for a target triangle, where a
/// degenerate target is still a valid (flat) deformation.
pub(crate) fn tet_frame_or_flat(p: [V3; 3]) -> M3 {
    let e1 = sub(p[1], p[0]);
    let e2 = sub(p[2], p[0]);
    let n = cross(e1, e2);
    let len = norm(n);
    let e3 = if len > 0.0 {
        let s = 1.0 / len.sqrt();
        [n[0] * s, n[1] * s, n[2] * s]
    } else {
        [0.0; 3]
    };
    [[e1[0], e2[0], e3[0]], [e1[1], e2[1], e3[1]], [e1[2], e2[2], e3[2]]]
}

/// Triangle corner positions.
pub(crate) fn corners(pos: &[V3], t: [usize; 3]) -> [V3; 3] {
    [pos[t[0]], pos[t[1]], pos[t[2]]]
}

/// Area of every triangle.
pub fn triangle_areas(pos: &[V3], tris: &[[usize; 3]]) -> Vec<f64> {
    tris.iter()
        .map(|&t| {
            let p = corners(pos, t);
            0.5 * norm(cross(sub(p[1], p[0]), sub(p[2], p[0])))
        })
        .collect()
}

/// Area below which a triangle of a frame counts as degenerate: relative to the frame's
/// bounding-box diagonal, so the test does not depend on the model's units.
pub(crate) fn degenerate_area(pos: &[V3]) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in pos {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let d = norm(sub(hi, lo));
    1e-14 * d * d
}

/// Inverse of the reference tetrahedron frame of every triangle and its area weight
/// (`None`/0 for degenerate triangles).
pub(crate) fn reference_frames(tris: &[[usize; 3]], reference: &[V3]) -> Vec<Option<(M3, f64)>> {
    let tiny = degenerate_area(reference);
    tris.iter()
        .map(|&t| {
            let p = corners(reference, t);
            let area = 0.5 * norm(cross(sub(p[1], p[0]), sub(p[2], p[0])));
            if area.is_nan() || area <= tiny {
                return None;
            }
            tet_frame(p).and_then(|v| inverse(&v)).map(|vi| (vi, area))
        })
        .collect()
}

/// Deformation gradient `J = Ṽ V⁻¹` of every triangle from `reference` to `target`
/// (Sumner & Popović 2004, Eq. 2). Triangles degenerate in the reference get the identity;
/// a triangle degenerate in the target only gets a singular gradient (its fourth vertex
/// collapses), which the polar decomposition handles.
pub fn deformation_gradients(tris: &[[usize; 3]], reference: &[V3], target: &[V3]) -> Vec<M3> {
    let frames = reference_frames(tris, reference);
    tris.iter()
        .zip(frames)
        .map(|(&t, f)| match f {
            None => IDENTITY,
            Some((vi, _)) => mul(&tet_frame_or_flat(corners(target, t)), &vi),
        })
        .collect()
}

/// Reusable workspace for many 3 × 3 SVDs (faer, sequential so results never depend on the
/// thread count).
pub struct Svd3 {
    buf: MemBuffer,
}

impl Default for Svd3 {
    fn default() -> Self {
        Self::new()
    }
}

impl Svd3 {
    /// A workspace.
    pub fn new() -> Self {
        let req =
            svd_scratch::<f64>(3, 3, ComputeSvdVectors::Full, ComputeSvdVectors::Full, Par::Seq, Default::default());
        Self { buf: MemBuffer::new(req) }
    }

    /// `a = W diag(s) Vᵀ`, singular values descending.
    fn svd(&mut self, a: &M3) -> Option<(M3, V3, M3)> {
        let m = Mat::<f64>::from_fn(3, 3, |i, j| a[i][j]);
        let mut u = Mat::<f64>::zeros(3, 3);
        let mut v = Mat::<f64>::zeros(3, 3);
        let mut s = faer::Col::<f64>::zeros(3);
        svd(
            m.as_ref(),
            s.as_mut().as_diagonal_mut(),
            Some(u.as_mut()),
            Some(v.as_mut()),
            Par::Seq,
            MemStack::new(&mut self.buf),
            Default::default(),
        )
        .ok()?;
        let uu = std::array::from_fn(|i| std::array::from_fn(|j| u[(i, j)]));
        let vv = std::array::from_fn(|i| std::array::from_fn(|j| v[(i, j)]));
        Some((uu, [s[0], s[1], s[2]], vv))
    }

    /// Polar decomposition `J = U P` with `U` a proper rotation and `P` symmetric (paper Eq. 3).
    ///
    /// From the SVD `J = W Σ Vᵀ`: `U = W Vᵀ`, `P = V Σ Vᵀ`. When `det(W Vᵀ) < 0` (an inverted
    /// triangle, or a reflection produced by the SVD's sign choices), the column of the
    /// smallest singular value is negated in `W` and its singular value in `Σ`, so `U` stays
    /// in SO(3) and `U P = J` still holds exactly; `P` is then symmetric but indefinite.
    pub fn polar(&mut self, j: &M3) -> Option<(M3, M3)> {
        let (mut w, mut s, v) = self.svd(j)?;
        let vt = transpose(&v);
        let mut u = mul(&w, &vt);
        if det(&u) < 0.0 {
            for row in w.iter_mut() {
                row[2] = -row[2];
            }
            s[2] = -s[2];
            u = mul(&w, &vt);
        }
        let mut p = [[0.0; 3]; 3];
        for (r, row) in p.iter_mut().enumerate() {
            for (c, x) in row.iter_mut().enumerate() {
                *x = (0..3).map(|k| v[r][k] * s[k] * v[c][k]).sum();
            }
        }
        Some((u, p))
    }
}

/// Logarithm of a rotation as an axis-angle 3-vector `θ·a` (paper Eq. 7; the components are
/// those of the skew matrix in a fixed basis, here the usual `vee` order).
///
/// Robust over the whole range: `θ = atan2(|s|, (tr R − 1)/2)` with `s = vee(R − Rᵀ)/2 =
/// sin θ · a`; near 0 the factor `θ / sin θ` uses its series; near π (where `s` vanishes) the
/// axis is read from the symmetric part `(R + Rᵀ)/2 − cos θ·I = (1 − cos θ) a aᵀ`, with its
/// sign taken from `s` when `s` still carries one. The principal branch (θ ≤ π) is always
/// used: P-frames code the rotation between consecutive frames, which is far from π, so the
/// field stays coherent over time and space.
pub fn log_rotation(r: &M3) -> V3 {
    let s = [0.5 * (r[2][1] - r[1][2]), 0.5 * (r[0][2] - r[2][0]), 0.5 * (r[1][0] - r[0][1])];
    let sin = norm(s);
    let cos = (0.5 * (r[0][0] + r[1][1] + r[2][2] - 1.0)).clamp(-1.0, 1.0);
    let theta = sin.atan2(cos);
    if theta < 1e-4 {
        // θ/sin θ = 1 + θ²/6 + 7θ⁴/360 + …
        let f = 1.0 + theta * theta / 6.0;
        return [s[0] * f, s[1] * f, s[2] * f];
    }
    if theta < 3.0 {
        let f = theta / sin;
        return [s[0] * f, s[1] * f, s[2] * f];
    }
    // Near π: axis from the symmetric part, column with the largest diagonal entry.
    let b: M3 =
        std::array::from_fn(|i| std::array::from_fn(|j| 0.5 * (r[i][j] + r[j][i]) - if i == j { cos } else { 0.0 }));
    let k = (0..3).fold(0, |best, i| if b[i][i] > b[best][best] { i } else { best });
    let mut a = [b[0][k], b[1][k], b[2][k]];
    let len = norm(a);
    if len == 0.0 {
        return [0.0; 3];
    }
    if dot(a, s) < 0.0 {
        a = [-a[0], -a[1], -a[2]];
    }
    [a[0] / len * theta, a[1] / len * theta, a[2] / len * theta]
}

/// Rotation of an axis-angle 3-vector (Rodrigues), with series for small angles.
pub fn exp_rotation(w: V3) -> M3 {
    let t2 = dot(w, w);
    let t = t2.sqrt();
    let (a, b) = if t < 1e-4 {
        // sin t / t and (1 − cos t) / t².
        (1.0 - t2 / 6.0, 0.5 - t2 / 24.0)
    } else {
        (t.sin() / t, (1.0 - t.cos()) / t2)
    };
    let k: M3 = [[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]];
    let k2 = mul(&k, &k);
    std::array::from_fn(|i| std::array::from_fn(|j| IDENTITY[i][j] + a * k[i][j] + b * k2[i][j]))
}

/// Connected components of the mesh (vertices joined by triangle edges); isolated vertices
/// are components of their own. Returns the component of every vertex and, per component,
/// its lowest vertex index (the pinned vertex of the Poisson solve, paper Eq. 2).
pub fn components(n: usize, tris: &[[usize; 3]]) -> (Vec<usize>, Vec<usize>) {
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    for t in tris {
        for k in 1..3 {
            let (a, b) = (find(&mut parent, t[0]), find(&mut parent, t[k]));
            if a != b {
                // The smaller index becomes the root, so the root is the lowest vertex.
                let (lo, hi) = if a < b { (a, b) } else { (b, a) };
                parent[hi] = lo;
            }
        }
    }
    let mut comp = vec![usize::MAX; n];
    let mut pins = Vec::new();
    let mut id_of_root = vec![usize::MAX; n];
    for (v, c) in comp.iter_mut().enumerate() {
        let r = find(&mut parent, v);
        if id_of_root[r] == usize::MAX {
            id_of_root[r] = pins.len();
            pins.push(r);
        }
        *c = id_of_root[r];
    }
    (comp, pins)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn rot(axis: V3, angle: f64) -> M3 {
        let l = norm(axis);
        exp_rotation([axis[0] / l * angle, axis[1] / l * angle, axis[2] / l * angle])
    }

    fn max_diff(a: &M3, b: &M3) -> f64 {
        (0..9).map(|i| (a[i / 3][i % 3] - b[i / 3][i % 3]).abs()).fold(0.0, f64::max)
    }

    #[test]
    fn log_exp_round_trip_over_the_whole_angle_range() {
        let axes = [[1.0, 0.0, 0.0], [0.3, -0.5, 0.8], [-0.2, 0.9, 0.1], [0.0, 0.0, -1.0]];
        for axis in axes {
            for angle in [0.0, 1e-9, 1e-5, 1e-3, 0.5, 2.0, 2.99, 3.01, 3.1, std::f64::consts::PI - 1e-7] {
                let r = rot(axis, angle);
                let w = log_rotation(&r);
                assert!((norm(w) - angle).abs() < 1e-9, "angle {angle}: |log| = {}", norm(w));
                let back = exp_rotation(w);
                assert!(max_diff(&back, &r) < 1e-9, "axis {axis:?} angle {angle}");
            }
        }
        // Exactly π: either axis sign is a valid logarithm.
        let r = rot([0.0, 1.0, 0.0], std::f64::consts::PI);
        assert!(max_diff(&exp_rotation(log_rotation(&r)), &r) < 1e-12);
    }

    #[test]
    fn polar_gives_a_proper_rotation_even_for_reflections() {
        let mut svd = Svd3::new();
        let r = rot([0.2, 0.7, -0.4], 1.3);
        let p: M3 = [[1.2, 0.1, -0.05], [0.1, 0.9, 0.2], [-0.05, 0.2, 1.1]];
        let j = mul(&r, &p);
        let (u, pp) = svd.polar(&j).unwrap();
        assert!(max_diff(&u, &r) < 1e-12 && max_diff(&pp, &p) < 1e-12);
        // A reflection (inverted triangle): U must stay in SO(3) and U P must equal J.
        let flip: M3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -0.5]];
        let j = mul(&r, &flip);
        let (u, pp) = svd.polar(&j).unwrap();
        assert!((det(&u) - 1.0).abs() < 1e-12, "det {}", det(&u));
        assert!(max_diff(&mul(&u, &pp), &j) < 1e-12);
        assert!(max_diff(&pp, &transpose(&pp)) < 1e-12);
        // A singular gradient (collapsed triangle) still decomposes.
        let (u, pp) = svd.polar(&[[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]).unwrap();
        assert!((det(&u) - 1.0).abs() < 1e-12);
        assert!(max_diff(&mul(&u, &pp), &[[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]) < 1e-12);
    }

    /// A closed, bumpy sphere-like mesh (octahedron subdivided and pushed out), `n` vertices.
    pub(crate) fn blob(level: usize) -> (Vec<V3>, Vec<[usize; 3]>) {
        let mut pos: Vec<V3> =
            vec![[1., 0., 0.], [-1., 0., 0.], [0., 1., 0.], [0., -1., 0.], [0., 0., 1.], [0., 0., -1.]];
        let mut tris: Vec<[usize; 3]> =
            vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
        for _ in 0..level {
            let mut mid = std::collections::HashMap::new();
            let mut next = Vec::new();
            for t in &tris {
                let mut m = [0usize; 3];
                for k in 0..3 {
                    let (a, b) = (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]));
                    m[k] = *mid.entry((a, b)).or_insert_with(|| {
                        let p =
                            [(pos[a][0] + pos[b][0]) / 2., (pos[a][1] + pos[b][1]) / 2., (pos[a][2] + pos[b][2]) / 2.];
                        pos.push(p);
                        pos.len() - 1
                    });
                }
                next.push([t[0], m[0], m[2]]);
                next.push([t[1], m[1], m[0]]);
                next.push([t[2], m[2], m[1]]);
                next.push([m[0], m[1], m[2]]);
            }
            tris = next;
        }
        for (i, p) in pos.iter_mut().enumerate() {
            let l = norm(*p);
            let bump = 1.0 + 0.1 * ((i as f64) * 0.7).sin();
            *p = [p[0] / l * bump * 1.5, p[1] / l * bump, p[2] / l * bump * 0.8];
        }
        (pos, tris)
    }
}
