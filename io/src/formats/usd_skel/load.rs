//! Reading a binding's parts from the layer (rules 1–3 of the parent module): the Skeleton
//! with its animation, the mesh's skinning influences and its blend shapes, each checked
//! against the layer and the budget before it is used.

use super::*;

pub(super) fn load_skeleton<'a>(
    file: &str,
    layer: &'a Layer,
    paths: &Paths,
    prim: usize,
    needs_bind: bool,
    budget: &mut Budget,
) -> Result<Skeleton<'a>> {
    let skel = &layer.prims[prim];
    let path = shown(&layer.path(prim));
    let joints = tokens(skel.attribute("joints")).unwrap_or_default();
    let n = joints.len();
    // Parents, inverse binds, rest transforms and three scratch arrays per frame.
    budget.take("skeleton joints", (n as u64).saturating_mul(6 * 128 + 64))?;
    let index: HashMap<&str, usize> = joints.iter().enumerate().map(|(i, j)| (j.as_str(), i)).collect();
    let mut parents = Vec::with_capacity(n);
    for (i, joint) in joints.iter().enumerate() {
        // The nearest ancestor path that is a joint (`UsdSkelTopology`).
        let mut parent = None;
        let mut at = joint.as_str();
        while let Some((up, _)) = at.rsplit_once('/') {
            if let Some(&p) = index.get(up) {
                parent = Some(p);
                break;
            }
            at = up;
        }
        if let Some(p) = parent {
            if p >= i {
                return Err(malformed(
                    file,
                    &path,
                    "joints",
                    format!("joint {i} ({}) comes before its parent joint {p}", shown(joint)),
                ));
            }
        }
        parents.push(parent);
    }
    let mut inverse_bind = Vec::new();
    if needs_bind {
        let bind = matrices(skel.attribute("bindTransforms"))
            .ok_or_else(|| malformed(file, &path, "bindTransforms", "is missing or not a matrix4d array"))?;
        if bind.len() != n {
            return Err(malformed(
                file,
                &path,
                "bindTransforms",
                format!("has {} matrices for {n} joints", bind.len()),
            ));
        }
        for (i, m) in bind.iter().enumerate() {
            let inv = usd_xform::inverse(&nested(m))
                .ok_or_else(|| malformed(file, &path, "bindTransforms", format!("matrix {i} is singular")))?;
            inverse_bind.push(flat(&inv));
        }
    }
    let rest = matrices(skel.attribute("restTransforms")).filter(|r| r.len() == n);
    let anim = match skel.relationship("skel:animationSource").and_then(|r| r.targets.first()) {
        None => None,
        Some(target) => {
            let a = paths.get(target).filter(|&a| layer.prims[a].type_name == "SkelAnimation").ok_or_else(|| {
                malformed(
                    file,
                    &path,
                    "skel:animationSource",
                    format!("targets {}, which is not a SkelAnimation of this layer", shown(target)),
                )
            })?;
            let anim = &layer.prims[a];
            let anim_joints = tokens(anim.attribute("joints")).unwrap_or_default();
            budget.take("animation joints", (anim_joints.len() as u64).saturating_mul(16))?;
            let joint_map = anim_joints.iter().map(|j| index.get(j.as_str()).copied()).collect();
            let blend_shapes = tokens(anim.attribute("blendShapes")).unwrap_or_default();
            budget.take("animation blend shapes", (blend_shapes.len() as u64).saturating_mul(16))?;
            Some(Animation {
                prim: a,
                joint_map,
                translations: anim.attribute("translations"),
                rotations: anim.attribute("rotations"),
                scales: anim.attribute("scales"),
                blend_shapes: blend_shapes.iter().map(String::as_str).collect(),
                weights: anim.attribute("blendShapeWeights"),
            })
        }
    };
    Ok(Skeleton { prim, parents, inverse_bind, rest, anim })
}

pub(super) fn load_skin(
    file: &str,
    layer: &Layer,
    mesh: usize,
    points: usize,
    found: &HashMap<&str, &Attribute>,
    skel_joints: &[String],
    budget: &mut Budget,
) -> Result<Skin> {
    let path = shown(&layer.path(mesh));
    let method = found
        .get("primvars:skel:skinningMethod")
        .or_else(|| found.get("skel:skinningMethod"))
        .and_then(|a| match uniform(a) {
            Some(Value::Token(t)) => Some(t.as_str()),
            _ => None,
        })
        .unwrap_or("classicLinear");
    if method != "classicLinear" {
        return Err(unsupported(
            file,
            format!(
                "the mesh {path} uses `{}` skinning (skel:skinningMethod); only linear blend skinning \
                 (classicLinear) is evaluated here",
                crate::formats::gltf::printable(method)
            ),
        ));
    }
    let indices = found["primvars:skel:jointIndices"];
    let weights = found["primvars:skel:jointWeights"];
    for a in [indices, weights] {
        if a.samples.len() > 1 {
            return Err(unsupported(file, format!("{path} {} is time-sampled: not evaluated here", a.name)));
        }
    }
    let per_point = indices.element_size.unwrap_or(1);
    if per_point != weights.element_size.unwrap_or(1) || per_point < 1 {
        return Err(malformed(
            file,
            &path,
            "primvars:skel:jointIndices",
            format!(
                "elementSize {per_point} of jointIndices and {} of jointWeights must be equal and at least 1",
                weights.element_size.unwrap_or(1)
            ),
        ));
    }
    let per_point = per_point as usize;
    // A primvar's interpolation is `constant` unless authored.
    let interpolation = indices.interpolation.as_deref().unwrap_or("constant");
    if interpolation != weights.interpolation.as_deref().unwrap_or("constant")
        || !matches!(interpolation, "constant" | "vertex")
    {
        return Err(malformed(
            file,
            &path,
            "primvars:skel:jointIndices",
            "jointIndices and jointWeights must both have `constant` or both `vertex` interpolation",
        ));
    }
    let rigid = interpolation == "constant";
    let expected = if rigid { per_point as u64 } else { (points as u64).saturating_mul(per_point as u64) };
    let (Some(Value::Ints(idx)), Some(w)) = (uniform(indices), uniform(weights)) else {
        return Err(malformed(file, &path, "primvars:skel:jointIndices", "is not an int array"));
    };
    let w: &[f32] = match w {
        Value::Floats { values, .. } => values,
        _ => return Err(malformed(file, &path, "primvars:skel:jointWeights", "is not a float array")),
    };
    if idx.len() as u64 != expected || w.len() as u64 != expected {
        return Err(malformed(
            file,
            &path,
            "primvars:skel:jointIndices",
            format!(
                "{} joint indices and {} weights, but {interpolation} interpolation with elementSize {per_point} \
                 over {points} points needs {expected}",
                idx.len(),
                w.len()
            ),
        ));
    }
    budget.take("joint influences", expected.saturating_mul(8))?;
    // Indices address the mesh's own joint order (`skel:joints`) when it has one, whose names
    // map onto the Skeleton's joints (`UsdSkelSkinningQuery`'s joint mapper); else the
    // Skeleton's order.
    let order: Option<Vec<u32>> = match found.get("skel:joints") {
        None => None,
        Some(a) => {
            let names = tokens(Some(a)).ok_or_else(|| malformed(file, &path, "skel:joints", "is not a token array"))?;
            budget.take("joint order", (names.len() as u64).saturating_mul(4))?;
            budget.take("joint names", (skel_joints.len() as u64).saturating_mul(48))?;
            let index: HashMap<&str, usize> = skel_joints.iter().enumerate().map(|(i, j)| (j.as_str(), i)).collect();
            let mut order = Vec::with_capacity(names.len());
            for name in names {
                let j = index.get(name.as_str()).copied().ok_or_else(|| {
                    malformed(
                        file,
                        &path,
                        "skel:joints",
                        format!("names joint {}, which the Skeleton does not have", shown(name)),
                    )
                })?;
                order.push(j as u32);
            }
            Some(order)
        }
    };
    let addressable = order.as_ref().map_or(skel_joints.len(), Vec::len);
    let mut joints = Vec::with_capacity(idx.len());
    for (k, &i) in idx.iter().enumerate() {
        if i < 0 || i as u64 >= addressable as u64 {
            return Err(malformed(
                file,
                &path,
                "primvars:skel:jointIndices",
                format!("index {i} (influence {k}) is out of range ({addressable} joints)"),
            ));
        }
        joints.push(order.as_ref().map_or(i as u32, |o| o[i as usize]));
    }
    let geom_bind = match found.get("primvars:skel:geomBindTransform").map(|a| uniform(a)) {
        None | Some(None) => usd_xform::IDENTITY,
        Some(Some(Value::Doubles { values, .. })) if values.len() == 16 => nested(&std::array::from_fn(|i| values[i])),
        Some(Some(_)) => {
            return Err(malformed(file, &path, "primvars:skel:geomBindTransform", "is not a matrix4d"));
        }
    };
    Ok(Skin { per_point, rigid, joints, weights: w.to_vec(), geom_bind })
}

pub(super) fn load_shape<'a>(
    file: &str,
    layer: &'a Layer,
    paths: &Paths,
    target: &str,
    points: usize,
    weight: Option<usize>,
    budget: &mut Budget,
) -> Result<Shape<'a>> {
    let at = shown(target);
    let s = paths
        .get(target)
        .filter(|&s| layer.prims[s].type_name == "BlendShape")
        .ok_or_else(|| malformed(file, &at, "", "is a blend shape target but not a BlendShape of this layer"))?;
    let shape = &layer.prims[s];
    if let Some(a) = shape.attributes.iter().find(|a| a.name.starts_with("inbetweens:")) {
        return Err(unsupported(
            file,
            format!(
                "the blend shape {at} has inbetween shapes (`{}`), which are not evaluated here",
                crate::formats::gltf::printable(&a.name)
            ),
        ));
    }
    let offsets: &[f32] = match shape.attribute("offsets").and_then(uniform) {
        Some(Value::Floats { arity: 3, values }) => values,
        Some(Value::Floats { values, .. }) if values.is_empty() => &[],
        _ => return Err(malformed(file, &at, "offsets", "is missing or not a vector3f array")),
    };
    let count = offsets.len() / 3;
    let indices = match shape.attribute("pointIndices").and_then(uniform) {
        None => {
            if count != points && count != 0 {
                return Err(malformed(
                    file,
                    &at,
                    "offsets",
                    format!("has {count} offsets for {points} points (and no pointIndices)"),
                ));
            }
            None
        }
        Some(Value::Ints(v)) => {
            if v.len() != count {
                return Err(malformed(
                    file,
                    &at,
                    "pointIndices",
                    format!("has {} indices for {count} offsets", v.len()),
                ));
            }
            budget.take("blend shape indices", (v.len() as u64).saturating_mul(4))?;
            let mut out = Vec::with_capacity(v.len());
            for &i in v {
                if i < 0 || i as u64 >= points as u64 {
                    return Err(malformed(
                        file,
                        &at,
                        "pointIndices",
                        format!("index {i} is out of range ({points} points)"),
                    ));
                }
                out.push(i as u32);
            }
            Some(out)
        }
        Some(Value::Floats { values, .. }) if values.is_empty() => Some(Vec::new()),
        Some(_) => return Err(malformed(file, &at, "pointIndices", "is not an int array")),
    };
    Ok(Shape { indices, offsets, weight })
}
