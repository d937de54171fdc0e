//! The arithmetic of glTF animation playback, apart from any file: keyframe tracks sampled with
//! `STEP`, `LINEAR` (quaternion slerp for rotations) and `CUBICSPLINE` (glTF 2.0 spec,
//! Appendix C "Animation sampler interpolation modes"), TRS → matrix, and 4 × 4 matrix products.
//! Everything is computed in `f64`; the file's `f32` values are widened once.

use ::gltf::animation::Interpolation;

/// A 4 × 4 matrix in glTF's column-major order: element (row r, column c) is at `4c + r`.
pub type Mat4 = [f64; 16];

/// The identity matrix.
pub const IDENTITY: Mat4 = [1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1.];

/// `a × b`.
pub fn mul(a: &Mat4, b: &Mat4) -> Mat4 {
    let mut out = [0.0; 16];
    for c in 0..4 {
        for r in 0..4 {
            out[4 * c + r] = (0..4).map(|k| a[4 * k + r] * b[4 * c + k]).sum();
        }
    }
    out
}

/// `m × (p, 1)`, the affine part (glTF node and joint matrices are affine).
pub fn transform_point(m: &Mat4, p: [f64; 3]) -> [f64; 3] {
    let mut out = [0.0; 3];
    for (r, o) in out.iter_mut().enumerate() {
        *o = m[r] * p[0] + m[4 + r] * p[1] + m[8 + r] * p[2] + m[12 + r];
    }
    out
}

/// `T × R × S` (spec §3.5.3 "Transformations"); the quaternion `[x, y, z, w]` is used as
/// given (keys and node rotations are unit quaternions; sampled ones are normalized).
pub fn from_trs(t: [f64; 3], q: [f64; 4], s: [f64; 3]) -> Mat4 {
    let [x, y, z, w] = q;
    let (x2, y2, z2) = (x + x, y + y, z + z);
    let (xx, xy, xz) = (x * x2, x * y2, x * z2);
    let (yy, yz, zz) = (y * y2, y * z2, z * z2);
    let (wx, wy, wz) = (w * x2, w * y2, w * z2);
    [
        (1. - (yy + zz)) * s[0],
        (xy + wz) * s[0],
        (xz - wy) * s[0],
        0.,
        (xy - wz) * s[1],
        (1. - (xx + zz)) * s[1],
        (yz + wx) * s[1],
        0.,
        (xz + wy) * s[2],
        (yz - wx) * s[2],
        (1. - (xx + yy)) * s[2],
        0.,
        t[0],
        t[1],
        t[2],
        1.,
    ]
}

/// Spherical linear interpolation from `a` to `b` along the shorter arc (the spec's reference
/// slerp; three.js's `Quaternion.slerpFlat`), normalized. Nearly equal quaternions fall back to
/// a normalized linear blend, where slerp's `sin θ` denominator loses precision.
pub fn slerp(a: [f64; 4], b: [f64; 4], s: f64) -> [f64; 4] {
    let mut cos = a.iter().zip(&b).map(|(x, y)| x * y).sum::<f64>();
    let sign = if cos < 0.0 { -1.0 } else { 1.0 };
    cos *= sign;
    let sin_sq = 1.0 - cos * cos;
    let (wa, wb) = if sin_sq > f64::EPSILON {
        let sin = sin_sq.sqrt();
        let angle = sin.atan2(cos);
        (((1.0 - s) * angle).sin() / sin, (s * angle).sin() / sin)
    } else {
        (1.0 - s, s)
    };
    normalize([
        wa * a[0] + sign * wb * b[0],
        wa * a[1] + sign * wb * b[1],
        wa * a[2] + sign * wb * b[2],
        wa * a[3] + sign * wb * b[3],
    ])
}

/// `q / |q|`; the zero quaternion becomes the identity rotation.
pub fn normalize(q: [f64; 4]) -> [f64; 4] {
    let len = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    if len > 0.0 && len.is_finite() {
        q.map(|x| x / len)
    } else {
        [0., 0., 0., 1.]
    }
}

/// One sampler's keyframes: `times` (strictly increasing, finite) and `values` holding `width`
/// numbers per key (3 × `width` for cubic splines: in-tangent, value, out-tangent).
#[derive(Debug, Clone)]
pub struct Track {
    pub times: Vec<f32>,
    pub values: Vec<f32>,
    pub width: usize,
    pub interpolation: Interpolation,
    /// A rotation track: `LINEAR` is slerp, `CUBICSPLINE` is normalized.
    pub rotation: bool,
}

impl Track {
    /// Value `i` of key `k` (the middle element of the triple for cubic splines).
    fn value(&self, k: usize, i: usize) -> f64 {
        let n = self.width;
        let at = if self.interpolation == Interpolation::CubicSpline { (3 * k + 1) * n + i } else { k * n + i };
        self.values[at] as f64
    }

    /// The track at time `t` (seconds) into `out` (`width` values), clamped to the key range.
    pub fn sample(&self, t: f64, out: &mut [f64]) {
        let n = self.width;
        let keys = self.times.len();
        // Last key with time <= t (the first key if t precedes it). Key times are f32: a key
        // written at frame k's time (k / fps rounded to f32) may lie a rounding error after
        // the f64 sample time, and must still count as reached (else STEP shows frame k − 1).
        let reached = t + 1e-6 * t.abs().max(1.0);
        let k = self.times.partition_point(|&x| x as f64 <= reached).saturating_sub(1);
        if k + 1 >= keys || t <= self.times[0] as f64 || self.interpolation == Interpolation::Step {
            for (i, o) in out.iter_mut().enumerate().take(n) {
                *o = self.value(k, i);
            }
            if self.rotation {
                let q = normalize([out[0], out[1], out[2], out[3]]);
                out[..4].copy_from_slice(&q);
            }
            return;
        }
        let (t0, t1) = (self.times[k] as f64, self.times[k + 1] as f64);
        let dt = t1 - t0;
        let s = ((t - t0) / dt).clamp(0.0, 1.0);
        match self.interpolation {
            Interpolation::Linear if self.rotation => {
                let q = |k| [self.value(k, 0), self.value(k, 1), self.value(k, 2), self.value(k, 3)];
                out[..4].copy_from_slice(&slerp(q(k), q(k + 1), s));
            }
            Interpolation::Linear => {
                for (i, o) in out.iter_mut().enumerate().take(n) {
                    let (v0, v1) = (self.value(k, i), self.value(k + 1, i));
                    *o = v0 + s * (v1 - v0);
                }
            }
            Interpolation::CubicSpline => {
                // Appendix C: Hermite with the out-tangent b_k of key k and the in-tangent
                // a_{k+1} of key k+1, both scaled by the interval.
                let (s2, s3) = (s * s, s * s * s);
                for (i, o) in out.iter_mut().enumerate().take(n) {
                    let (v0, v1) = (self.value(k, i), self.value(k + 1, i));
                    let b0 = self.values[(3 * k + 2) * n + i] as f64;
                    let a1 = self.values[(3 * (k + 1)) * n + i] as f64;
                    *o = (2.0 * s3 - 3.0 * s2 + 1.0) * v0
                        + (s3 - 2.0 * s2 + s) * dt * b0
                        + (-2.0 * s3 + 3.0 * s2) * v1
                        + (s3 - s2) * dt * a1;
                }
                if self.rotation {
                    let q = normalize([out[0], out[1], out[2], out[3]]);
                    out[..4].copy_from_slice(&q);
                }
            }
            Interpolation::Step => unreachable!("handled above"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol)
    }

    /// A rotation by `angle` about z.
    fn about_z(angle: f64) -> [f64; 4] {
        [0.0, 0.0, (angle / 2.0).sin(), (angle / 2.0).cos()]
    }

    #[test]
    fn slerp_moves_at_constant_angular_speed_along_the_short_arc() {
        // 0° → 90° about z: a quarter of the way is 22.5° (a linear blend would give ≈ 20.6°
        // after normalization).
        let q = slerp(about_z(0.0), about_z(std::f64::consts::FRAC_PI_2), 0.25);
        assert!(close(&q, &about_z(std::f64::consts::FRAC_PI_8), 1e-12), "{q:?}");
        // -q is the same rotation: slerp takes the short way round, not a 340° turn.
        let b = about_z(40f64.to_radians()).map(|x| -x);
        let half = slerp(about_z(0.0), b, 0.5);
        let expected = about_z(20f64.to_radians());
        assert!(close(&half, &expected, 1e-12) || close(&half, &expected.map(|x| -x), 1e-12), "{half:?}");
        // Equal quaternions do not divide by sin 0.
        assert!(close(&slerp(about_z(1.0), about_z(1.0), 0.3), &about_z(1.0), 1e-12));
    }

    #[test]
    fn trs_matrix_rotates_scales_and_translates() {
        // Scale x by 2, rotate 90° about z, then translate: (1, 0, 0) → (0, 2, 0) + t.
        let m = from_trs([1.0, 2.0, 3.0], about_z(std::f64::consts::FRAC_PI_2), [2.0, 1.0, 1.0]);
        assert!(close(&transform_point(&m, [1.0, 0.0, 0.0]), &[1.0, 4.0, 3.0], 1e-12));
        assert!(close(&transform_point(&mul(&IDENTITY, &m), [0.0, 1.0, 0.0]), &[0.0, 2.0, 3.0], 1e-12));
        // Composition order: (A × B) p = A (B p).
        let a = from_trs([0.0, 0.0, 5.0], about_z(0.3), [1.0, 3.0, 1.0]);
        let p = [0.5, -1.0, 2.0];
        assert!(close(&transform_point(&mul(&a, &m), p), &transform_point(&a, transform_point(&m, p)), 1e-12));
    }

    #[test]
    fn step_linear_and_cubic_tracks() {
        let track = |interpolation, values: Vec<f32>| Track {
            times: vec![0.0, 1.0, 3.0],
            values,
            width: 1,
            interpolation,
            rotation: false,
        };
        let at = |t: &Track, time: f64| {
            let mut out = [0.0];
            t.sample(time, &mut out);
            out[0]
        };
        let step = track(Interpolation::Step, vec![1.0, 5.0, -2.0]);
        assert_eq!(
            [at(&step, -1.0), at(&step, 0.5), at(&step, 1.0), at(&step, 2.9), at(&step, 9.0)],
            [1.0, 1.0, 5.0, 5.0, -2.0]
        );
        let linear = track(Interpolation::Linear, vec![1.0, 5.0, -2.0]);
        assert_eq!([at(&linear, 0.25), at(&linear, 2.0)], [2.0, 1.5]);
        // Cubic: key values 0, 1, 0; out-tangent of key 1 = 2, every other tangent 0. On [1, 3]
        // (dt = 2) at s = 0.5: h00·1 + h10·dt·2 + h01·0 = 0.5 + 0.125·2·2 = 1.0.
        let cubic = track(Interpolation::CubicSpline, vec![0., 0., 0., 0., 1., 2., 0., 0., 0.]);
        assert!((at(&cubic, 2.0) - 1.0).abs() < 1e-12);
        assert!((at(&cubic, 0.5) - 0.5).abs() < 1e-12, "zero tangents: the mean at the midpoint");
        assert_eq!(at(&cubic, 1.0), 1.0, "keys are hit exactly");
        // A rotation track with cubic tangents comes out normalized.
        let q0 = about_z(0.0).map(|x| x as f32);
        let q1 = about_z(1.0).map(|x| x as f32);
        let z = [0f32; 4];
        let rot = Track {
            times: vec![0.0, 1.0],
            values: [z, q0, z, z, q1, z].concat(),
            width: 4,
            interpolation: Interpolation::CubicSpline,
            rotation: true,
        };
        let mut q = [0.0; 4];
        rot.sample(0.5, &mut q);
        assert!((q.iter().map(|x| x * x).sum::<f64>() - 1.0).abs() < 1e-12);
        assert!(close(&q, &about_z(0.5), 1e-3), "{q:?}");
    }
}
