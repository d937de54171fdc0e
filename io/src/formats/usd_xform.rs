//! `UsdGeomXformable` transforms: the `xformOp`s a prim lists in `xformOpOrder`, evaluated at a
//! time code, composed as `UsdGeomXformCache` composes them (see `pxr/usd/usdGeom/xformOp.cpp`
//! and `xformable.cpp`).
//!
//! USD uses row vectors (`p' = p · M`, the translation in the last row). With ops
//! `[op_1, …, op_n]` in `xformOpOrder`, the local transform is `M_n · … · M_1`, so the last op
//! acts on the points first (`[translate, rotateXYZ, scale]` scales, rotates, then
//! translates); a prim's world transform is its local one times its parent's world transform,
//! unless `!resetXformStack!` (first in the order) drops the parent's. `!invert!xformOp:…`
//! uses the inverse of that op. Rotations are in degrees; `rotateXYZ` rotates about X first,
//! then Y, then Z (the other five orders likewise); `orient` is a unit quaternion (real
//! first); `transform` a `matrix4d`. Ops may be `half`, `float` or `double` and time-sampled:
//! a value between samples is interpolated linearly (quaternions by slerp) and held outside
//! them, as `UsdAttribute::Get` does.

use super::usd_layer::{Attribute, Prim, Value};

/// A 4×4 matrix, row-major, for row vectors.
pub(super) type Matrix = [[f64; 4]; 4];

pub(super) const IDENTITY: Matrix = [[1., 0., 0., 0.], [0., 1., 0., 0.], [0., 0., 1., 0.], [0., 0., 0., 1.]];

pub(super) fn multiply(a: &Matrix, b: &Matrix) -> Matrix {
    let mut m = [[0.0; 4]; 4];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = (0..4).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

/// The inverse of `m` (Gauss–Jordan with partial pivoting), `None` when it is singular.
pub(super) fn inverse(m: &Matrix) -> Option<Matrix> {
    let mut a = *m;
    let mut inv = IDENTITY;
    for col in 0..4 {
        let pivot = (col..4).max_by(|&x, &y| a[x][col].abs().total_cmp(&a[y][col].abs()))?;
        if a[pivot][col].abs() < 1e-300 {
            return None;
        }
        a.swap(col, pivot);
        inv.swap(col, pivot);
        let p = a[col][col];
        for j in 0..4 {
            a[col][j] /= p;
            inv[col][j] /= p;
        }
        for r in 0..4 {
            if r != col {
                let f = a[r][col];
                for j in 0..4 {
                    a[r][j] -= f * a[col][j];
                    inv[r][j] -= f * inv[col][j];
                }
            }
        }
    }
    Some(inv)
}

/// The rotation by `degrees` about axis 0, 1 or 2 (X, Y, Z), for row vectors.
fn rotation(axis: usize, degrees: f64) -> Matrix {
    let (s, c) = degrees.to_radians().sin_cos();
    let (i, j) = [(1, 2), (2, 0), (0, 1)][axis];
    let mut m = IDENTITY;
    m[i][i] = c;
    m[j][j] = c;
    m[i][j] = s;
    m[j][i] = -s;
    m
}

/// The rotation of the unit quaternion (real, i, j, k), for row vectors.
fn quaternion(q: &[f64]) -> Matrix {
    let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    let (w, x, y, z) = if n > 0.0 { (q[0] / n, q[1] / n, q[2] / n, q[3] / n) } else { (1.0, 0.0, 0.0, 0.0) };
    [
        [1. - 2. * (y * y + z * z), 2. * (x * y + w * z), 2. * (x * z - w * y), 0.],
        [2. * (x * y - w * z), 1. - 2. * (x * x + z * z), 2. * (y * z + w * x), 0.],
        [2. * (x * z + w * y), 2. * (y * z - w * x), 1. - 2. * (x * x + y * y), 0.],
        [0., 0., 0., 1.],
    ]
}

fn numbers(value: &Value) -> Option<Vec<f64>> {
    match value {
        Value::Floats { values, .. } => Some(values.iter().map(|&v| v as f64).collect()),
        Value::Doubles { values, .. } => Some(values.clone()),
        Value::Ints(v) => Some(v.iter().map(|&v| v as f64).collect()),
        _ => None,
    }
}

/// Spherical interpolation of unit quaternions (the shorter way round).
fn slerp(a: &[f64], b: &[f64], alpha: f64) -> Vec<f64> {
    let mut dot: f64 = a.iter().zip(b).map(|(x, y)| x * y).sum();
    let b: Vec<f64> = if dot < 0.0 {
        dot = -dot;
        b.iter().map(|x| -x).collect()
    } else {
        b.to_vec()
    };
    if dot > 0.9995 {
        return a.iter().zip(&b).map(|(x, y)| x + (y - x) * alpha).collect();
    }
    let theta = dot.min(1.0).acos();
    let (wa, wb) = (((1.0 - alpha) * theta).sin() / theta.sin(), (alpha * theta).sin() / theta.sin());
    a.iter().zip(&b).map(|(x, y)| wa * x + wb * y).collect()
}

/// The numbers of an op value of at most 16 components (longer ones are not an op's value and
/// are never copied).
fn small_numbers(value: &Value) -> Option<Vec<f64>> {
    let len = match value {
        Value::Floats { values, .. } => values.len(),
        Value::Doubles { values, .. } => values.len(),
        Value::Ints(v) => v.len(),
        _ => return None,
    };
    if len > 16 {
        return None;
    }
    numbers(value)
}

/// The attribute's value at time code `t` as numbers, as `UsdAttribute::Get(t)` gives it
/// (blocked samples are skipped, as for points). The samples are sorted by time: a binary
/// search finds the two around `t`.
fn numbers_at(attr: &Attribute, t: f64, is_quaternion: bool) -> Option<Vec<f64>> {
    let s = &attr.samples;
    if !s.iter().any(|x| x.1.is_some()) {
        return small_numbers(attr.default.as_ref()?);
    }
    let after = s.partition_point(|x| x.0 < t);
    if let Some((time, Some(v))) = s.get(after) {
        if *time == t {
            return small_numbers(v);
        }
    }
    let before = s[..after].iter().rev().find_map(|(time, v)| Some((*time, v.as_ref()?)));
    let next = s[after..].iter().find_map(|(time, v)| Some((*time, v.as_ref()?)));
    let ((t0, a), (t1, b)) = match (before, next) {
        (Some(a), Some(b)) => (a, b),
        (Some((_, v)), None) | (None, Some((_, v))) => return small_numbers(v),
        (None, None) => return None,
    };
    let (a, b) = (small_numbers(a)?, small_numbers(b)?);
    if a.len() != b.len() {
        return Some(a);
    }
    let alpha = (t - t0) / (t1 - t0);
    Some(if is_quaternion {
        slerp(&a, &b, alpha)
    } else {
        a.iter().zip(&b).map(|(x, y)| x + (y - x) * alpha).collect()
    })
}

/// Types that are not `UsdGeomXformable`: their `xformOp`s, if any, transform nothing.
fn is_xformable(type_name: &str) -> bool {
    !matches!(
        type_name,
        "" | "Scope" | "Material" | "Shader" | "NodeGraph" | "GeomSubset" | "SkelAnimation" | "BlendShape"
    )
}

/// A prim's local transform at time code `t` and whether it resets the transform stack
/// (`None`: it authors no transform). Errors name the op.
pub(super) fn local_transform(prim: &Prim, t: f64) -> Result<Option<(Matrix, bool)>, String> {
    if !is_xformable(&prim.type_name) {
        return Ok(None);
    }
    let Some(order) = prim.attribute("xformOpOrder") else { return Ok(None) };
    let order = match (&order.default, order.samples.first()) {
        (Some(Value::Tokens(t)), _) | (None, Some((_, Some(Value::Tokens(t))))) => t,
        _ => return Ok(None),
    };
    if order.is_empty() {
        return Ok(None);
    }
    let mut local = IDENTITY;
    let mut reset = false;
    for (k, entry) in order.iter().enumerate() {
        if entry == "!resetXformStack!" {
            if k != 0 {
                return Err(format!("`!resetXformStack!` is entry {k} of xformOpOrder, not the first"));
            }
            reset = true;
            continue;
        }
        let (inverted, name) = match entry.strip_prefix("!invert!") {
            Some(n) => (true, n),
            None => (false, entry.as_str()),
        };
        let kind = name
            .strip_prefix("xformOp:")
            .map(|rest| rest.split(':').next().unwrap_or_default())
            .ok_or_else(|| format!("xformOpOrder entry `{entry}` is not an xformOp"))?;
        let attr =
            prim.attribute(name).ok_or_else(|| format!("xformOpOrder lists `{name}`, which the prim does not have"))?;
        let v = numbers_at(attr, t, kind == "orient").ok_or_else(|| format!("`{name}` has no numeric value"))?;
        let want = match kind {
            "rotateX" | "rotateY" | "rotateZ" => 1,
            "orient" => 4,
            "transform" => 16,
            _ => 3,
        };
        if v.len() != want {
            return Err(format!("`{name}` has {} components ({want} expected)", v.len()));
        }
        let m = match kind {
            "translate" => {
                let mut m = IDENTITY;
                m[3][..3].copy_from_slice(&v);
                m
            }
            "scale" => {
                let mut m = IDENTITY;
                for i in 0..3 {
                    m[i][i] = v[i];
                }
                m
            }
            "rotateX" => rotation(0, v[0]),
            "rotateY" => rotation(1, v[0]),
            "rotateZ" => rotation(2, v[0]),
            "orient" => quaternion(&v),
            "transform" => [
                [v[0], v[1], v[2], v[3]],
                [v[4], v[5], v[6], v[7]],
                [v[8], v[9], v[10], v[11]],
                [v[12], v[13], v[14], v[15]],
            ],
            rotate => {
                let axes = rotate
                    .strip_prefix("rotate")
                    .filter(|a| a.len() == 3)
                    .ok_or_else(|| format!("`{name}`: unknown xformOp type `{kind}`"))?;
                let mut m = IDENTITY;
                // The first named axis acts first: for row vectors, it is the leftmost factor.
                for axis in axes.chars() {
                    let a = match axis {
                        'X' => 0,
                        'Y' => 1,
                        'Z' => 2,
                        _ => return Err(format!("`{name}`: unknown xformOp type `{kind}`")),
                    };
                    m = multiply(&m, &rotation(a, v[a]));
                }
                m
            }
        };
        let m =
            if inverted { inverse(&m).ok_or_else(|| format!("`{name}` cannot be inverted (singular)"))? } else { m };
        // Later ops act first: local = M_k · local.
        local = multiply(&m, &local);
    }
    Ok(Some((local, reset)))
}

/// Every time code at which a prim's ops are sampled.
pub(super) fn sample_times(prim: &Prim, out: &mut Vec<f64>) {
    for a in &prim.attributes {
        if a.name.starts_with("xformOp") {
            out.extend(a.samples.iter().filter(|s| s.1.is_some()).map(|s| s.0));
        }
    }
}

/// `points` (xyz triples) transformed by `m` as `GfMatrix4d::Transform` does (w divided out).
pub(super) fn transform_points(m: &Matrix, points: &mut [f32]) {
    for p in points.chunks_exact_mut(3) {
        let (x, y, z) = (p[0] as f64, p[1] as f64, p[2] as f64);
        let mut o = [0.0f64; 4];
        for (j, oj) in o.iter_mut().enumerate() {
            *oj = x * m[0][j] + y * m[1][j] + z * m[2][j] + m[3][j];
        }
        let w = if o[3] != 0.0 { o[3] } else { 1.0 };
        p[0] = (o[0] / w) as f32;
        p[1] = (o[1] / w) as f32;
        p[2] = (o[2] / w) as f32;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn prim(ops: &[(&str, Value)], order: &[&str]) -> Prim {
        let mut attributes: Vec<Attribute> = ops
            .iter()
            .map(|(n, v)| Attribute { name: (*n).to_owned(), default: Some(v.clone()), ..Attribute::default() })
            .collect();
        attributes.push(Attribute {
            name: "xformOpOrder".into(),
            default: Some(Value::Tokens(order.iter().map(|s| (*s).to_owned()).collect())),
            ..Attribute::default()
        });
        Prim { name: "p".into(), type_name: "Xform".into(), attributes, ..Prim::default() }
    }

    fn apply(p: &Prim, point: [f32; 3]) -> [f32; 3] {
        let (m, _) = local_transform(p, 0.0).unwrap().unwrap();
        let mut v = point.to_vec();
        transform_points(&m, &mut v);
        [v[0], v[1], v[2]]
    }

    fn d3(x: f64, y: f64, z: f64) -> Value {
        Value::Doubles { arity: 3, values: vec![x, y, z] }
    }

    #[test]
    fn ops_compose_in_usd_order() {
        // [translate, rotateZ, scale]: scale, then rotate, then translate.
        let p = prim(
            &[
                ("xformOp:translate", d3(10., 0., 0.)),
                ("xformOp:rotateZ", Value::Floats { arity: 1, values: vec![90.] }),
                ("xformOp:scale", Value::Floats { arity: 3, values: vec![2., 2., 2.] }),
            ],
            &["xformOp:translate", "xformOp:rotateZ", "xformOp:scale"],
        );
        let q = apply(&p, [1., 0., 0.]);
        assert!((q[0] - 10.).abs() < 1e-6 && (q[1] - 2.).abs() < 1e-6, "{q:?}");
        // rotateXYZ (90, 90, 0): X first takes +Y to +Z, then Y takes +Z to +X.
        let p = prim(&[("xformOp:rotateXYZ", d3(90., 90., 0.))], &["xformOp:rotateXYZ"]);
        let q = apply(&p, [0., 1., 0.]);
        assert!((q[0] - 1.).abs() < 1e-6 && q[1].abs() < 1e-6 && q[2].abs() < 1e-6, "{q:?}");
        // An inverted translate undoes the translate.
        let p = prim(&[("xformOp:translate", d3(1., 2., 3.))], &["xformOp:translate", "!invert!xformOp:translate"]);
        assert_eq!(apply(&p, [5., 5., 5.]), [5., 5., 5.]);
        // A quaternion of 90° about Z (real first) takes +X to +Y.
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let p =
            prim(&[("xformOp:orient", Value::Floats { arity: 4, values: vec![h, 0., 0., h] })], &["xformOp:orient"]);
        let q = apply(&p, [1., 0., 0.]);
        assert!(q[0].abs() < 1e-6 && (q[1] - 1.).abs() < 1e-6, "{q:?}");
        // Errors name the op.
        let p = prim(&[], &["xformOp:translate"]);
        assert!(local_transform(&p, 0.0).unwrap_err().contains("does not have"));
        let p = prim(&[("xformOp:translate", d3(1., 2., 3.))], &["xformOp:translate", "!resetXformStack!"]);
        assert!(local_transform(&p, 0.0).unwrap_err().contains("not the first"));
        let p = prim(&[("xformOp:scale", d3(0., 1., 1.))], &["!invert!xformOp:scale"]);
        assert!(local_transform(&p, 0.0).unwrap_err().contains("singular"));
    }
}
