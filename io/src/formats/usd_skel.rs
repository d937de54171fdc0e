//! `UsdSkel` evaluation: meshes deformed by blend shapes and skeletons, played as
//! `UsdSkelCache` / `UsdSkelSkinningQuery` / `UsdSkelBlendShapeQuery` play them (OpenUSD
//! `pxr/usd/usdSkel/cacheImpl.cpp`, `skinningQuery.cpp`, `skeletonQuery.cpp`,
//! `blendShapeQuery.cpp`, `animMapper.cpp`, `topology.cpp`, `utils.cpp`, and the schema
//! documentation "UsdSkel Schemas In-Depth").
//!
//! The rules applied, in order:
//!
//! 1. **Binding** (`UsdSkel_CacheImpl::Populate`): only prims under a `SkelRoot` are deformed.
//!    From the `SkelRoot` down to the mesh, every prim with `SkelBindingAPI` applied may author
//!    `skel:skeleton`, `primvars:skel:jointIndices`, `primvars:skel:jointWeights`,
//!    `primvars:skel:geomBindTransform`, `skel:skinningMethod` and `skel:joints`; the nearest
//!    one wins (they are inherited). `skel:blendShapes` and `skel:blendShapeTargets` count only
//!    on the mesh itself.
//! 2. **Joint transforms** (`UsdSkelSkeletonQuery::ComputeSkinningTransforms`): the
//!    `SkelAnimation` named by the Skeleton's `skel:animationSource` holds `translations`,
//!    `rotations` (quaternions) and `scales` in its own `joints` order; each joint's local
//!    transform is `scale · rotate · translate` (row vectors, `UsdSkelMakeTransform`), mapped
//!    by joint name onto the Skeleton's `joints` (`UsdSkelAnimMapper`). Joints the animation
//!    does not drive, and every joint when it has no transforms, take `restTransforms`. A
//!    joint's parent is its nearest ancestor path in `joints` (`UsdSkelTopology`); parents come
//!    first. Skeleton-space transform = local · parent's; skinning transform =
//!    `bindTransforms⁻¹` · skeleton-space transform.
//! 3. **Blend shapes** (`UsdSkelBlendShapeQuery`, `UsdSkelApplyBlendShape`), before skinning,
//!    on the mesh's points: the animation's `blendShapeWeights` (in its `blendShapes` order)
//!    are mapped by name onto the mesh's `skel:blendShapes`, whose `skel:blendShapeTargets` are
//!    `BlendShape` prims; each adds `weight × offsets` at its `pointIndices` (or at every point
//!    when it has none). Weights within 1e-6 of zero add nothing.
//! 4. **Linear blend skinning** (`UsdSkelSkinPointsLBS`): each point is moved by
//!    `geomBindTransform`, then becomes `Σ wᵢ · (p · skinningᵢ)` over its `elementSize`
//!    influences (weights as authored, not normalised). Joint indices address the mesh's
//!    `skel:joints` order when it has one (mapped by name onto the Skeleton's), else the
//!    Skeleton's. `constant` interpolation binds every point to the same influences (rigid).
//! 5. **Placement** (`UsdSkelBakeSkinning`): skinned points are in the Skeleton's space, so the
//!    Skeleton's local-to-world transform places them (the mesh's own is not applied); a mesh
//!    with blend shapes and no joint influences keeps its own transform.
//!
//! What is refused by name rather than played wrongly: inbetween shapes, dual-quaternion
//! skinning, indexed skinning primvars, a binding without `SkelBindingAPI` or outside a
//! `SkelRoot`, and every malformed binding (missing arrays, sizes that disagree, indices out
//! of range, unknown joint names).

use std::collections::HashMap;

use codec_core::{Error, Result};

use super::gltf_anim::{self, Mat4};
use super::gltf_buffers::Budget;
use super::usd_layer::{shown, unsupported, Attribute, Layer, Prim, Value};
use super::usd_xform;

mod load;
use load::{load_shape, load_skeleton, load_skin};

/// Most units of playback work a read may cost (one per joint transform and per point per
/// influence or shape offset, per frame): far above real characters (10⁴ frames of a
/// 10⁵-point mesh with 8 influences is 9·10⁹), far below what a crafted file can ask for.
pub(super) const MAX_SKEL_WORK: u64 = 20_000_000_000;

/// The `UsdSkel` binding properties of a prim (rule 1).
const BINDING_PROPERTIES: &[&str] = &[
    "primvars:skel:jointIndices",
    "primvars:skel:jointWeights",
    "primvars:skel:geomBindTransform",
    "primvars:skel:skinningMethod",
    "skel:skinningMethod",
    "skel:joints",
    "skel:blendShapes",
];

/// Prim paths → indexes in the layer, built once when a mesh is bound.
pub(super) struct Paths(HashMap<String, usize>);

impl Paths {
    pub(super) fn new(layer: &Layer, budget: &mut Budget) -> Result<Self> {
        let mut map = HashMap::with_capacity(layer.prims.len());
        let mut paths: Vec<String> = Vec::with_capacity(layer.prims.len());
        for (i, prim) in layer.prims.iter().enumerate() {
            // Parents come before their children: extend the parent's path (its length
            // budgeted first: deep prims with long names make long paths).
            let parent: &str = prim.parent.map_or("", |p| paths[p].as_str());
            let len = (parent.len() as u64).saturating_add(1).saturating_add(prim.name.len() as u64);
            budget.take("prim paths", len.saturating_mul(2).saturating_add(64))?;
            let mut path = String::with_capacity(len as usize);
            path.push_str(parent);
            path.push('/');
            path.push_str(&prim.name);
            map.insert(path.clone(), i);
            paths.push(path);
        }
        Ok(Self(map))
    }

    fn get(&self, path: &str) -> Option<usize> {
        self.0.get(path).copied()
    }
}

/// The skeleton a mesh is bound to, loaded.
struct Skeleton<'a> {
    prim: usize,
    /// Each joint's parent (an earlier joint), `None` for a root.
    parents: Vec<Option<usize>>,
    /// `bindTransforms⁻¹`, per joint (empty when no skinning needs them).
    inverse_bind: Vec<Mat4>,
    /// `restTransforms`, per joint, when authored with one per joint.
    rest: Option<Vec<Mat4>>,
    anim: Option<Animation<'a>>,
}

/// The `SkelAnimation` driving a skeleton.
struct Animation<'a> {
    prim: usize,
    /// Each animation joint's skeleton joint (`None`: not in the skeleton).
    joint_map: Vec<Option<usize>>,
    translations: Option<&'a Attribute>,
    rotations: Option<&'a Attribute>,
    scales: Option<&'a Attribute>,
    blend_shapes: Vec<&'a str>,
    weights: Option<&'a Attribute>,
}

/// One blend shape of a mesh.
struct Shape<'a> {
    /// `pointIndices` (every point, in order, when `None`).
    indices: Option<Vec<u32>>,
    /// `offsets`, xyz triples.
    offsets: &'a [f32],
    /// The index of its weight in the animation's `blendShapeWeights`, if it drives it.
    weight: Option<usize>,
}

/// A mesh's joint influences (rule 4).
struct Skin {
    /// Influences per point (`elementSize`).
    per_point: usize,
    /// `constant` interpolation: one set of influences for every point.
    rigid: bool,
    /// Skeleton joint of each influence.
    joints: Vec<u32>,
    weights: Vec<f32>,
    geom_bind: usd_xform::Matrix,
}

/// What deforms one mesh.
pub(super) struct Deformer<'a> {
    mesh: usize,
    points: usize,
    skeleton: Skeleton<'a>,
    shapes: Vec<Shape<'a>>,
    skin: Option<Skin>,
}

fn flat(m: &usd_xform::Matrix) -> Mat4 {
    let mut f = [0.0; 16];
    for (i, row) in m.iter().enumerate() {
        f[4 * i..4 * i + 4].copy_from_slice(row);
    }
    f
}

fn nested(f: &Mat4) -> usd_xform::Matrix {
    let mut m = [[0.0; 4]; 4];
    for (i, row) in m.iter_mut().enumerate() {
        row.copy_from_slice(&f[4 * i..4 * i + 4]);
    }
    m
}

/// The authored value of a uniform attribute: its default, else its only time sample.
fn uniform(attr: &Attribute) -> Option<&Value> {
    attr.default.as_ref().or_else(|| attr.samples.iter().find_map(|s| s.1.as_ref()))
}

/// The numbers of an array value (integers, floats or doubles), as `f64`; `None` for any
/// other value.
fn numbers(value: &Value) -> Option<Vec<f64>> {
    match value {
        Value::Floats { values, .. } => Some(values.iter().map(|&v| v as f64).collect()),
        Value::Doubles { values, .. } => Some(values.clone()),
        Value::Ints(v) => Some(v.iter().map(|&v| v as f64).collect()),
        _ => None,
    }
}

/// An array attribute at time code `t`, as `UsdAttribute::Get(t)` gives it: the sample at
/// `t`, else linear interpolation between the samples around it when both hold as many
/// values (quaternions, real first, by slerp), else the earlier one; held outside them; the
/// default when there are no samples. Blocked samples are skipped.
///
/// `expected` is the number of values the caller needs: a value of another length is an
/// error (its length), found before anything is copied.
fn array_at(
    attr: &Attribute,
    t: f64,
    quaternions: bool,
    expected: usize,
) -> std::result::Result<Option<Vec<f64>>, usize> {
    let checked = |v: &Value| -> std::result::Result<Option<Vec<f64>>, usize> {
        let len = match v {
            Value::Floats { values, .. } => values.len(),
            Value::Doubles { values, .. } => values.len(),
            Value::Ints(values) => values.len(),
            _ => return Ok(None),
        };
        if len != expected {
            return Err(len);
        }
        Ok(numbers(v))
    };
    let s = &attr.samples;
    if !s.iter().any(|x| x.1.is_some()) {
        return attr.default.as_ref().map_or(Ok(None), checked);
    }
    let after = s.partition_point(|x| x.0 < t);
    if let Some((time, Some(v))) = s.get(after) {
        if *time == t {
            return checked(v);
        }
    }
    let before = s[..after].iter().rev().find_map(|(time, v)| Some((*time, v.as_ref()?)));
    let next = s[after..].iter().find_map(|(time, v)| Some((*time, v.as_ref()?)));
    let ((t0, a), (t1, b)) = match (before, next) {
        (Some(a), Some(b)) => (a, b),
        (Some((_, v)), None) | (None, Some((_, v))) => return checked(v),
        (None, None) => return Ok(None),
    };
    // Samples of other lengths than each other are not interpolated: the earlier one holds.
    let Some(a) = checked(a)? else { return Ok(None) };
    let b = match checked(b) {
        Ok(Some(b)) => b,
        _ => return Ok(Some(a)),
    };
    let alpha = (t - t0) / (t1 - t0);
    if quaternions && a.len() % 4 == 0 {
        let mut out = Vec::with_capacity(a.len());
        for (qa, qb) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
            // `gltf_anim::slerp` takes (x, y, z, w); the order does not change the result.
            let q = gltf_anim::slerp([qa[0], qa[1], qa[2], qa[3]], [qb[0], qb[1], qb[2], qb[3]], alpha);
            out.extend_from_slice(&q);
        }
        return Ok(Some(out));
    }
    Ok(Some(a.iter().zip(&b).map(|(x, y)| x + (y - x) * alpha).collect()))
}

fn tokens(attr: Option<&Attribute>) -> Option<&[String]> {
    match attr.and_then(uniform) {
        Some(Value::Tokens(t)) => Some(t),
        _ => None,
    }
}

/// A `matrix4d[]` attribute: one row-major matrix per 16 doubles.
fn matrices(attr: Option<&Attribute>) -> Option<Vec<Mat4>> {
    match attr.and_then(uniform)? {
        Value::Doubles { arity: 16, values } => {
            Some(values.chunks_exact(16).map(|m| std::array::from_fn(|i| m[i])).collect())
        }
        Value::Doubles { values, .. } if values.is_empty() => Some(Vec::new()),
        _ => None,
    }
}

/// The binding of the mesh `mesh` (rule 1), or `None` when nothing deforms it.
pub(super) fn deformer<'a>(
    file: &str,
    layer: &'a Layer,
    paths: &mut Option<Paths>,
    mesh: usize,
    points: usize,
    budget: &mut Budget,
) -> Result<Option<Deformer<'a>>> {
    let prim = &layer.prims[mesh];
    let path = || shown(&layer.path(mesh));
    let authors_binding = |p: &Prim| {
        BINDING_PROPERTIES.iter().any(|a| p.attribute(a).is_some()) || p.relationship("skel:skeleton").is_some()
    };
    let mut chain = Vec::new();
    let mut at = prim.parent;
    let mut root = None;
    while let Some(p) = at {
        chain.push(p);
        if layer.prims[p].type_name == "SkelRoot" {
            root = Some(chain.len());
        }
        at = layer.prims[p].parent;
    }
    let Some(root) = root else {
        if authors_binding(prim) || prim.relationship("skel:blendShapeTargets").is_some() {
            return Err(unsupported(
                file,
                format!(
                    "the mesh {} has a UsdSkel binding but no SkelRoot above it, so UsdSkel does not deform it; \
                     put the mesh and its Skeleton under a SkelRoot",
                    path()
                ),
            ));
        }
        return Ok(None);
    };
    // The prims whose binding applies, the SkelRoot first and the mesh last.
    chain.truncate(root);
    chain.reverse();
    chain.push(mesh);
    let mut found: HashMap<&str, &'a Attribute> = HashMap::new();
    let mut skeleton_target: Option<&'a str> = None;
    for &p in &chain {
        let q = &layer.prims[p];
        if !q.has_api("SkelBindingAPI") {
            if authors_binding(q) {
                return Err(unsupported(
                    file,
                    format!(
                        "{} authors UsdSkel binding properties without applying SkelBindingAPI, which UsdSkel then \
                         ignores; apply the schema (prepend apiSchemas = [\"SkelBindingAPI\"]) or bake the \
                         deformation into the points",
                        shown(&layer.path(p))
                    ),
                ));
            }
            continue;
        }
        for name in BINDING_PROPERTIES {
            if *name == "skel:blendShapes" && p != mesh {
                continue;
            }
            if let Some(a) = q.attribute(name).filter(|a| a.default.is_some() || !a.samples.is_empty()) {
                found.insert(name, a);
            }
        }
        if let Some(r) = q.relationship("skel:skeleton") {
            if let Some(t) = r.targets.first() {
                skeleton_target = Some(t);
            }
        }
    }
    let blend_targets = if prim.has_api("SkelBindingAPI") {
        prim.relationship("skel:blendShapeTargets").filter(|r| !r.targets.is_empty())
    } else {
        None
    };
    let has_influences =
        found.contains_key("primvars:skel:jointIndices") && found.contains_key("primvars:skel:jointWeights");
    let has_shapes = found.contains_key("skel:blendShapes") && blend_targets.is_some();
    if !has_influences && !has_shapes {
        if found.contains_key("primvars:skel:jointIndices") || found.contains_key("primvars:skel:jointWeights") {
            return Err(malformed(
                file,
                &path(),
                "primvars:skel:jointIndices",
                "needs both primvars:skel:jointIndices and primvars:skel:jointWeights",
            ));
        }
        return Ok(None);
    }
    for name in ["primvars:skel:jointIndices:indices", "primvars:skel:jointWeights:indices"] {
        if chain.iter().any(|&p| layer.prims[p].attribute(name).is_some()) {
            return Err(unsupported(
                file,
                format!("the mesh {}: indexed skinning primvars (`{name}`) are not evaluated here", path()),
            ));
        }
    }
    let Some(skeleton_target) = skeleton_target else {
        return Err(unsupported(
            file,
            format!(
                "the mesh {} has UsdSkel joint influences or blend shapes but no `skel:skeleton` binding, so \
                 nothing drives them",
                path()
            ),
        ));
    };
    if paths.is_none() {
        *paths = Some(Paths::new(layer, budget)?);
    }
    let paths = paths.as_ref().expect("built");
    let skel_prim =
        paths.get(skeleton_target).filter(|&s| layer.prims[s].type_name == "Skeleton").ok_or_else(|| {
            malformed(
                file,
                &path(),
                "skel:skeleton",
                format!("targets {}, which is not a Skeleton of this layer", shown(skeleton_target)),
            )
        })?;
    let skeleton = load_skeleton(file, layer, paths, skel_prim, has_influences, budget)?;
    let skin = if has_influences {
        let skel_joints = tokens(layer.prims[skel_prim].attribute("joints")).unwrap_or_default();
        Some(load_skin(file, layer, mesh, points, &found, skel_joints, budget)?)
    } else {
        None
    };
    let shapes = match blend_targets {
        Some(targets) if has_shapes => {
            let names = tokens(found.get("skel:blendShapes").copied())
                .ok_or_else(|| malformed(file, &path(), "skel:blendShapes", "is not a token array"))?;
            if names.len() != targets.targets.len() {
                return Err(malformed(
                    file,
                    &path(),
                    "skel:blendShapes",
                    format!(
                        "names {} blend shapes but skel:blendShapeTargets has {} targets",
                        names.len(),
                        targets.targets.len()
                    ),
                ));
            }
            let mut shapes = Vec::with_capacity(names.len());
            for (name, target) in names.iter().zip(&targets.targets) {
                let weight = skeleton.anim.as_ref().and_then(|a| a.blend_shapes.iter().position(|n| n == name));
                shapes.push(load_shape(file, layer, paths, target, points, weight, budget)?);
            }
            shapes
        }
        _ => Vec::new(),
    };
    Ok(Some(Deformer { mesh, points, skeleton, shapes, skin }))
}

fn malformed(file: &str, prim: &str, field: &str, detail: impl Into<String>) -> Error {
    Error::malformed(file.to_owned(), format!("{prim} {field}"), detail.into())
}

impl Deformer<'_> {
    /// The prim whose transforms place the deformed points: the Skeleton when the mesh is
    /// skinned (rule 5), else the mesh.
    pub(super) fn placed_by(&self) -> usize {
        if self.skin.is_some() {
            self.skeleton.prim
        } else {
            self.mesh
        }
    }

    /// Every time code at which the animation driving the mesh is sampled.
    pub(super) fn sample_times(&self, layer: &Layer, out: &mut Vec<f64>) {
        if let Some(anim) = &self.skeleton.anim {
            for name in ["translations", "rotations", "scales", "blendShapeWeights"] {
                if let Some(a) = layer.prims[anim.prim].attribute(name) {
                    out.extend(a.samples.iter().filter(|s| s.1.is_some()).map(|s| s.0));
                }
            }
        }
    }

    /// Units of work per frame (see [`MAX_SKEL_WORK`]).
    pub(super) fn work_per_frame(&self) -> u64 {
        let joints = self.skeleton.parents.len() as u64;
        let shapes: u64 = self.shapes.iter().map(|s| s.indices.as_ref().map_or(self.points, Vec::len) as u64).sum();
        let skin = self.skin.as_ref().map_or(0, |s| (self.points as u64).saturating_mul(s.per_point as u64));
        joints.saturating_mul(4).saturating_add(shapes).saturating_add(skin)
    }

    /// The skinning transforms of every skeleton joint at time code `t` (rule 2).
    fn skinning_transforms(&self, t: f64) -> std::result::Result<Vec<Mat4>, String> {
        let skel = &self.skeleton;
        let n = skel.parents.len();
        let mut local: Vec<Option<Mat4>> = match &skel.rest {
            Some(r) => r.iter().copied().map(Some).collect(),
            None => vec![None; n],
        };
        if let Some(anim) = &skel.anim {
            let m = anim.joint_map.len();
            let part = |attr: Option<&Attribute>, name: &str, width: usize| {
                attr.map_or(Ok(None), |a| array_at(a, t, name == "rotations", width.saturating_mul(m))).map_err(|len| {
                    format!("the SkelAnimation has {m} joints but {} {name} at time code {t}", len / width)
                })
            };
            let parts = (
                part(anim.translations, "translations", 3)?,
                part(anim.rotations, "rotations", 4)?,
                part(anim.scales, "scales", 3)?,
            );
            // Without all three arrays the animation drives no joint: the rest pose holds.
            if let (Some(tr), Some(ro), Some(sc)) = parts {
                for (a, j) in anim.joint_map.iter().enumerate() {
                    if let Some(j) = *j {
                        let q = &ro[4 * a..4 * a + 4];
                        // The layer holds quaternions real first; `from_trs` takes (x, y, z, w).
                        local[j] = Some(gltf_anim::from_trs(
                            [tr[3 * a], tr[3 * a + 1], tr[3 * a + 2]],
                            [q[1], q[2], q[3], q[0]],
                            [sc[3 * a], sc[3 * a + 1], sc[3 * a + 2]],
                        ));
                    }
                }
            }
        }
        let mut skel_space: Vec<Mat4> = Vec::with_capacity(n);
        for (j, l) in local.iter().enumerate() {
            let l = l.ok_or_else(|| {
                format!("joint {j} has no animated transform and the Skeleton has no restTransforms for every joint")
            })?;
            // Row vectors: skel = local · parent's skel. `gltf_anim::mul` composes the same
            // row-major numbers read as column-major (transposed) matrices, so the order flips.
            skel_space.push(match skel.parents[j] {
                Some(p) => gltf_anim::mul(&skel_space[p], &l),
                None => l,
            });
        }
        Ok(skel_space.iter().zip(&skel.inverse_bind).map(|(s, ib)| gltf_anim::mul(s, ib)).collect())
    }

    /// Deforms the mesh's points at time code `t` in place (rules 3 and 4): blend shapes,
    /// then skinning into the Skeleton's space.
    pub(super) fn deform(&self, t: f64, points: &mut [f32]) -> std::result::Result<(), String> {
        if !self.shapes.is_empty() {
            let anim = self.skeleton.anim.as_ref();
            let weights = match anim.and_then(|a| a.weights.map(|w| (a, w))) {
                None => None,
                Some((a, w)) => array_at(w, t, false, a.blend_shapes.len()).map_err(|len| {
                    format!(
                        "the SkelAnimation names {} blend shapes but has {len} blendShapeWeights at time code {t}",
                        a.blend_shapes.len()
                    )
                })?,
            };
            if let Some(weights) = weights {
                for shape in &self.shapes {
                    let Some(w) = shape.weight.map(|k| weights[k]) else { continue };
                    if w.abs() <= 1e-6 {
                        continue;
                    }
                    let mut add = |i: usize, o: &[f32]| {
                        for c in 0..3 {
                            points[3 * i + c] = (points[3 * i + c] as f64 + w * o[c] as f64) as f32;
                        }
                    };
                    match &shape.indices {
                        Some(ix) => ix.iter().zip(shape.offsets.chunks_exact(3)).for_each(|(&i, o)| add(i as usize, o)),
                        None => shape.offsets.chunks_exact(3).enumerate().for_each(|(i, o)| add(i, o)),
                    }
                }
            }
        }
        if let Some(skin) = &self.skin {
            let xforms = self.skinning_transforms(t)?;
            for (i, p) in points.chunks_exact_mut(3).enumerate() {
                let mut bound = [p[0], p[1], p[2]];
                usd_xform::transform_points(&skin.geom_bind, &mut bound);
                let p0 = [bound[0] as f64, bound[1] as f64, bound[2] as f64];
                let first = if skin.rigid { 0 } else { i * skin.per_point };
                let mut out = [0.0f64; 3];
                for k in first..first + skin.per_point {
                    let w = skin.weights[k];
                    if w != 0.0 {
                        let q = gltf_anim::transform_point(&xforms[skin.joints[k] as usize], p0);
                        for c in 0..3 {
                            out[c] += q[c] * w as f64;
                        }
                    }
                }
                p.copy_from_slice(&out.map(|x| x as f32));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::usd::parse_usd;

    /// A text layer: a SkelRoot holding a two-joint Skeleton, its animation and a mesh, with
    /// `mesh_extra` added to the mesh, `skel_extra` to the Skeleton and `anim_extra` to the
    /// animation.
    fn layer(mesh_extra: &str, skel_extra: &str, anim_extra: &str) -> String {
        format!(
            r#"#usda 1.0
(
    startTimeCode = 0
    endTimeCode = 1
)
def SkelRoot "root"
{{
    def Skeleton "skel" (prepend apiSchemas = ["SkelBindingAPI"])
    {{
        uniform token[] joints = ["a", "a/b"]
        uniform matrix4d[] bindTransforms = [((1,0,0,0),(0,1,0,0),(0,0,1,0),(0,0,0,1)), ((1,0,0,0),(0,1,0,0),(0,0,1,0),(1,0,0,1))]
        uniform matrix4d[] restTransforms = [((1,0,0,0),(0,1,0,0),(0,0,1,0),(0,0,0,1)), ((1,0,0,0),(0,1,0,0),(0,0,1,0),(1,0,0,1))]
        rel skel:animationSource = <anim>
        {skel_extra}
        def SkelAnimation "anim"
        {{
            uniform token[] joints = ["a/b", "a"]
            float3[] translations.timeSamples = {{ 0: [(1, 0, 0), (0, 0, 0)], 1: [(1, 0, 0), (0, 0, 0)] }}
            quatf[] rotations.timeSamples = {{ 0: [(1, 0, 0, 0), (1, 0, 0, 0)], 1: [(1, 0, 0, 0), (0.70710677, 0, 0, 0.70710677)] }}
            half3[] scales = [(1, 1, 1), (1, 1, 1)]
            {anim_extra}
        }}
    }}
    def Mesh "m" (prepend apiSchemas = ["SkelBindingAPI"])
    {{
        point3f[] points = [(1, 0, 0), (2, 0, 0), (2, 1, 0)]
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
        rel skel:skeleton = </root/skel>
        {mesh_extra}
    }}
}}
"#
        )
    }

    const INFLUENCES: &str = r#"int[] primvars:skel:jointIndices = [0, 0, 1, 1, 1, 0] (elementSize = 2 interpolation = "vertex")
        float[] primvars:skel:jointWeights = [1, 0, 0.5, 0.5, 1, 0] (elementSize = 2 interpolation = "vertex")"#;

    fn read(text: &str) -> codec_core::Result<codec_core::Animation> {
        parse_usd(text.as_bytes(), "t.usda", None, Some(64 << 20))
    }

    fn close(a: &[f32], b: &[f32]) -> bool {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6)
    }

    #[test]
    fn skinning_follows_the_joints() {
        let a = read(&layer(INFLUENCES, "", "")).unwrap();
        assert_eq!(a.frame_count(), 2);
        // Frame 0: the rest pose (the animation repeats it).
        assert!(close(&a.positions()[..9], &[1., 0., 0., 2., 0., 0., 2., 1., 0.]), "{:?}", &a.positions()[..9]);
        // Frame 1: joint a turns 90° about Z, and b with it. Point 0 (on a) → (0, 1, 0);
        // point 2 (on a, by its row) → (-1, 2, 0); point 1 half on each: both give (0, 2, 0).
        assert!(close(&a.positions()[9..], &[0., 1., 0., 0., 2., 0., -1., 2., 0.]), "{:?}", &a.positions()[9..]);
        // Rigid: constant interpolation binds every point to joint b.
        let rigid = r#"int[] primvars:skel:jointIndices = [1] (interpolation = "constant")
            float[] primvars:skel:jointWeights = [1] (interpolation = "constant")"#;
        let a = read(&layer(rigid, "", "")).unwrap();
        assert!(close(&a.positions()[9..], &[0., 1., 0., 0., 2., 0., -1., 2., 0.]));
        // The mesh's own joint order: index 0 names joint a/b.
        let ordered = r#"uniform token[] skel:joints = ["a/b"]
            int[] primvars:skel:jointIndices = [0] (interpolation = "constant")
            float[] primvars:skel:jointWeights = [1] (interpolation = "constant")"#;
        let b = read(&layer(ordered, "", "")).unwrap();
        assert_eq!(a.positions(), b.positions());
    }

    #[test]
    fn sparse_blend_shapes_add_weighted_offsets() {
        let mesh = r#"uniform token[] skel:blendShapes = ["up"]
        rel skel:blendShapeTargets = [<up>]
        def BlendShape "up" { uniform vector3f[] offsets = [(0, 0, 2)]
            uniform int[] pointIndices = [1] }"#;
        let anim = r#"uniform token[] blendShapes = ["other", "up"]
            float[] blendShapeWeights.timeSamples = { 0: [1, 0], 1: [1, 0.25] }"#;
        let a = read(&layer(mesh, "", anim)).unwrap();
        // No joint influences: the points stay in the mesh's space; only the blend shape moves.
        assert!(close(&a.positions()[..9], &[1., 0., 0., 2., 0., 0., 2., 1., 0.]));
        assert!(close(&a.positions()[9..], &[1., 0., 0., 2., 0., 0.5, 2., 1., 0.]), "{:?}", &a.positions()[9..]);
    }

    #[test]
    fn malformed_or_unevaluated_bindings_are_refused_by_name() {
        let shape = |extra: &str| {
            format!(
                r#"uniform token[] skel:blendShapes = ["up"]
            rel skel:blendShapeTargets = [<up>]
            def BlendShape "up" {{ uniform vector3f[] offsets = [(0, 0, 2)]
                {extra} }}"#
            )
        };
        let cases: Vec<(String, String, String, &[&str])> = vec![
            (
                INFLUENCES.replace("[0, 0, 1, 1, 1, 0]", "[0, 0, 1, 7, 1, 0]"),
                String::new(),
                String::new(),
                &["/root/m", "jointIndices", "index 7", "out of range"],
            ),
            (
                INFLUENCES.replace(
                    "elementSize = 2 interpolation = \"vertex\")\n",
                    "elementSize = 3 interpolation = \"vertex\")\n",
                ),
                String::new(),
                String::new(),
                &["/root/m", "elementSize"],
            ),
            (
                INFLUENCES.replace("[1, 0, 0.5, 0.5, 1, 0]", "[1, 0, 0.5]"),
                String::new(),
                String::new(),
                &["/root/m", "needs 6"],
            ),
            (
                format!("uniform token[] skel:joints = [\"nope\"]\n{INFLUENCES}"),
                String::new(),
                String::new(),
                &["/root/m", "skel:joints", "nope"],
            ),
            (
                format!("uniform token primvars:skel:skinningMethod = \"dualQuaternion\"\n{INFLUENCES}"),
                String::new(),
                String::new(),
                &["/root/m", "dualQuaternion"],
            ),
            (
                shape("uniform int[] pointIndices = [5]"),
                String::new(),
                String::new(),
                &["/root/m/up", "pointIndices", "out of range"],
            ),
            (shape(""), String::new(), String::new(), &["/root/m/up", "offsets", "1 offsets for 3 points"]),
            (
                shape(
                    "uniform int[] pointIndices = [1]\nuniform vector3f[] inbetweens:half = [(0, 0, 1)] (weight = 0.5)",
                ),
                String::new(),
                String::new(),
                &["/root/m/up", "inbetween"],
            ),
            (
                INFLUENCES.to_owned(),
                String::new(),
                "float3[] translations.timeSamples = { 0: [(1, 0, 0)] }".to_owned(),
                &["/root/m", "translations"],
            ),
            (
                INFLUENCES.to_owned(),
                "uniform matrix4d[] bindTransforms = [((1,0,0,0),(0,1,0,0),(0,0,1,0),(0,0,0,1))]".to_owned(),
                String::new(),
                &["/root/skel", "bindTransforms", "1 matrices for 2 joints"],
            ),
            (
                INFLUENCES.to_owned(),
                "uniform token[] joints = [\"a/b\", \"a\"]".to_owned(),
                String::new(),
                &["/root/skel", "before its parent"],
            ),
        ];
        for (mesh, skel, anim, needles) in cases {
            let text = layer(&mesh, &skel, &anim);
            let e = read(&text).expect_err(&text).to_string();
            for n in needles {
                assert!(e.contains(n), "`{n}` not in: {e}\n{text}");
            }
        }
        // Without SkelBindingAPI, and outside a SkelRoot.
        let text = layer(INFLUENCES, "", "")
            .replace("def Mesh \"m\" (prepend apiSchemas = [\"SkelBindingAPI\"])", "def Mesh \"m\"");
        let e = read(&text).unwrap_err().to_string();
        assert!(e.contains("/root/m") && e.contains("SkelBindingAPI"), "{e}");
        let text = layer(INFLUENCES, "", "").replace("def SkelRoot", "def Xform");
        let e = read(&text).unwrap_err().to_string();
        assert!(e.contains("/root/m") && e.contains("no SkelRoot"), "{e}");
        // A skeleton binding that names a prim that is not a Skeleton.
        let text = layer(INFLUENCES, "", "").replace("</root/skel>", "</root/m>");
        let e = read(&text).unwrap_err().to_string();
        assert!(e.contains("skel:skeleton") && e.contains("not a Skeleton"), "{e}");
    }

    #[test]
    fn joint_arrays_are_budgeted_before_allocation() {
        // 200,000 joints: the skeleton's per-joint transforms are counted against the budget.
        let joints: Vec<String> = (0..200_000).map(|i| format!("\"j{i}\"")).collect();
        let skel = format!("uniform token[] joints = [{}]", joints.join(","));
        let text = layer(INFLUENCES, &skel, "");
        let t = std::time::Instant::now();
        let e = parse_usd(text.as_bytes(), "t.usda", None, Some(40 << 20)).unwrap_err().to_string();
        assert!(e.contains("memory") && e.contains("skeleton joints"), "{e}");
        assert!(t.elapsed().as_secs_f64() < 5.0);
    }
}
