//! The one assembly of a USD layer's `Mesh` prims into an [`Animation`], for text and crate
//! layers alike (see [`super::usd`]'s module documentation for the rules): points at every
//! frame time, polygons fanned, transforms of each mesh and its ancestors applied.

use codec_core::{Animation, Error, Result, SceneMetadata, UpAxis};

use super::gltf_buffers::Budget;
use super::usd_layer::{shown, unsupported, Layer, Prim, Value, USD_DEFAULT_TIME_CODES_PER_SECOND};
use super::{check_finite_in, in_file, reader_limits, usd_skel, usd_xform};

// ---------------------------------------------------------------------------------------------
// From the layer to an animation.

/// One mesh's topology and point samples, converted.
struct MeshData<'a> {
    vertices: usize,
    triangles: Vec<[u32; 3]>,
    /// Sorted by time: (time code, points); empty when only the default value exists.
    samples: Vec<(f64, Vec<f32>)>,
    default: Option<Vec<f32>>,
    /// Prims (indexes in the layer) whose transforms apply, the mesh's own first.
    transforms: Vec<usize>,
    /// Time codes at which those transforms (and the skeleton animation) are sampled.
    transform_times: Vec<f64>,
    /// The skeleton and blend shapes deforming the points (`usd_skel`), if any.
    deformer: Option<usd_skel::Deformer<'a>>,
    /// Index of the mesh prim in the layer.
    prim: usize,
}

/// The vertex cache of every `Mesh` prim of `layer`, one after another (see
/// [`super::usd`]'s module documentation for the rules).
pub(super) fn assemble(file: &str, layer: Layer, frame_rate: Option<f32>, budget: &mut Budget) -> Result<Animation> {
    let mut meshes = Vec::new();
    let mut paths = None;
    for (i, prim) in layer.prims.iter().enumerate() {
        if prim.type_name != "Mesh" {
            continue;
        }
        let path = layer.path(i);
        budget.take("prim paths", path.len() as u64)?;
        let mut mesh = mesh_data(file, &path, prim, budget)?;
        mesh.prim = i;
        let deformer = usd_skel::deformer(file, &layer, &mut paths, i, mesh.vertices, budget)?;
        if let Some(d) = &deformer {
            d.sample_times(&layer, &mut mesh.transform_times);
        }
        // The prims whose transforms place the points: the mesh (or, when it is skinned, its
        // Skeleton) and its ancestors, up to one that resets the transform stack.
        let mut at = Some(deformer.as_ref().map_or(i, |d| d.placed_by()));
        while let Some(p) = at {
            let local = usd_xform::local_transform(&layer.prims[p], 0.0)
                .map_err(|e| Error::malformed(file.to_owned(), format!("{} xformOpOrder", shown(&layer.path(p))), e))?;
            if let Some((_, reset)) = local {
                mesh.transforms.push(p);
                usd_xform::sample_times(&layer.prims[p], &mut mesh.transform_times);
                if reset {
                    break;
                }
            }
            at = layer.prims[p].parent;
        }
        mesh.deformer = deformer;
        meshes.push(mesh);
    }
    if meshes.is_empty() {
        return Err(Error::malformed(file.to_owned(), "meshes", "the layer defines no Mesh prim"));
    }
    // The frame times: every sample time of every mesh.
    let mut times: Vec<f64> =
        meshes.iter().flat_map(|m| m.samples.iter().map(|s| s.0).chain(m.transform_times.iter().copied())).collect();
    times.sort_by(f64::total_cmp);
    times.dedup();
    let step = match times.len() {
        0 | 1 => 1.0,
        _ => (times[times.len() - 1] - times[0]) / (times.len() - 1) as f64,
    };
    for w in times.windows(2) {
        if ((w[1] - w[0]) - step).abs() > step * 1e-6 {
            return Err(unsupported(
                file,
                format!(
                    "the time samples are not evenly spaced (codes {} and {} against a mean step of {step}): a \
                     vertex cache has one frame rate; resample the points first",
                    w[0], w[1]
                ),
            ));
        }
    }
    if times.is_empty() {
        times.push(0.0);
    }
    let vertices: usize = meshes.iter().map(|m| m.vertices).sum();
    let limits = reader_limits();
    if vertices as u64 > limits.max_vertices as u64 {
        return Err(Error::LimitExceeded {
            context: file.to_owned().into(),
            field: "vertex_count".into(),
            value: vertices as u64,
            limit: limits.max_vertices as u64,
        });
    }
    if times.len() as u64 > limits.max_frames as u64 {
        return Err(Error::LimitExceeded {
            context: file.to_owned().into(),
            field: "frame_count".into(),
            value: times.len() as u64,
            limit: limits.max_frames as u64,
        });
    }
    // Skeleton and blend shape playback costs work every frame beyond the output's size.
    let per_frame =
        meshes.iter().filter_map(|m| m.deformer.as_ref()).fold(0u64, |sum, d| sum.saturating_add(d.work_per_frame()));
    let work = per_frame.saturating_mul(times.len() as u64);
    if work > usd_skel::MAX_SKEL_WORK {
        return Err(Error::LimitExceeded {
            context: file.to_owned().into(),
            field: "UsdSkel playback work (frames × (joints + points × influences + blend shape offsets))".into(),
            value: work,
            limit: usd_skel::MAX_SKEL_WORK,
        });
    }
    let floats = (vertices as u64).saturating_mul(3).saturating_mul(times.len() as u64);
    limits.check_alloc("formats", "positions", floats.saturating_mul(4))?;
    budget.take("positions", floats.saturating_mul(4))?;
    // The world transform of every transformed prim at every frame, each computed once (a
    // prim's world is its local transform times the world of the next transformed prim up its
    // chain: world = local(mesh) · local(parent) · …, row vectors).
    let mut worlds: std::collections::HashMap<usize, Vec<usd_xform::Matrix>> = std::collections::HashMap::new();
    for m in &meshes {
        for (k, &p) in m.transforms.iter().enumerate().rev() {
            if worlds.contains_key(&p) {
                continue;
            }
            budget.take("transforms", (times.len() as u64).saturating_mul(128))?;
            let above = m.transforms.get(k + 1).and_then(|q| worlds.get(q));
            let mut per_frame = Vec::with_capacity(times.len());
            for (f, &t) in times.iter().enumerate() {
                let local = usd_xform::local_transform(&layer.prims[p], t)
                    .map_err(|e| {
                        Error::malformed(file.to_owned(), format!("{} xformOpOrder", shown(&layer.path(p))), e)
                    })?
                    .map_or(usd_xform::IDENTITY, |l| l.0);
                per_frame.push(match above {
                    Some(w) => usd_xform::multiply(&local, &w[f]),
                    None => local,
                });
            }
            worlds.insert(p, per_frame);
        }
    }
    let mut positions = Vec::with_capacity(floats as usize);
    for (f, &t) in times.iter().enumerate() {
        for m in &meshes {
            let start = positions.len();
            push_points_at(m, t, &mut positions);
            if let Some(d) = &m.deformer {
                d.deform(t, &mut positions[start..]).map_err(|e| {
                    Error::malformed(file.to_owned(), format!("{} UsdSkel", shown(&layer.path(m.prim))), e)
                })?;
            }
            if let Some(world) = m.transforms.first().and_then(|p| worlds.get(p)) {
                usd_xform::transform_points(&world[f], &mut positions[start..]);
            }
        }
    }
    let mut triangles = Vec::with_capacity(meshes.iter().map(|m| m.triangles.len()).sum());
    let mut offset = 0u32;
    for m in &meshes {
        triangles.extend(m.triangles.iter().map(|t| t.map(|i| i + offset)));
        offset += m.vertices as u32;
    }
    check_finite_in(file, &positions, vertices)?;
    let meta = &layer.metadata;
    let tcps = meta.time_codes_per_second.or(meta.frames_per_second).unwrap_or(USD_DEFAULT_TIME_CODES_PER_SECOND);
    let fps = match frame_rate {
        Some(f) => f,
        None => {
            let fps = (tcps / step) as f32;
            super::check_frame_rate(fps).map_err(|e| in_file(file, e))?
        }
    };
    // What the layer said about its scene goes with the animation to every writer. An up axis
    // other than USD's two is not a scene USD can describe; it is dropped, as Pixar's stage
    // does (`UsdGeomGetStageUpAxis` falls back to the default). A layer that states no unit is
    // in centimetres by USD's rule (`UsdGeomGetStageMetersPerUnit`'s fallback, 0.01), which
    // the writers then state.
    let metadata = SceneMetadata {
        up_axis: meta.up_axis.as_deref().and_then(UpAxis::from_name),
        meters_per_unit: Some(
            meta.meters_per_unit.filter(|m| m.is_finite() && *m > 0.0).unwrap_or(USD_FALLBACK_METERS_PER_UNIT),
        ),
        time_codes_per_second: (meta.time_codes_per_second.is_some() || meta.frames_per_second.is_some())
            .then_some(tcps)
            .filter(|t| t.is_finite() && *t > 0.0),
        start_time_code: times.first().copied(),
    };
    Animation::from_parts(vertices, triangles, positions, fps)
        .and_then(|a| a.with_metadata(metadata))
        .map_err(|e| in_file(file, e))
}

/// `metersPerUnit` of a layer that authors none (`UsdGeomLinearUnits::centimeters`).
const USD_FALLBACK_METERS_PER_UNIT: f64 = 0.01;

/// Points of `mesh` at time code `t`, as `UsdAttribute::Get(t)` gives them: the sample at
/// `t`, else linear interpolation between the samples around it, held outside them; the
/// default value when the mesh has no samples.
fn push_points_at(mesh: &MeshData, t: f64, out: &mut Vec<f32>) {
    let s = &mesh.samples;
    if s.is_empty() {
        out.extend_from_slice(mesh.default.as_deref().unwrap_or(&[]));
        return;
    }
    let after = s.partition_point(|x| x.0 < t);
    if after < s.len() && s[after].0 == t {
        out.extend_from_slice(&s[after].1);
    } else if after == 0 {
        out.extend_from_slice(&s[0].1);
    } else if after == s.len() {
        out.extend_from_slice(&s[s.len() - 1].1);
    } else {
        let (t0, a) = (&s[after - 1].0, &s[after - 1].1);
        let (t1, b) = (&s[after].0, &s[after].1);
        let alpha = (t - t0) / (t1 - t0);
        out.extend(a.iter().zip(b).map(|(&x, &y)| (x as f64 + (y as f64 - x as f64) * alpha) as f32));
    }
}

fn mesh_data<'a>(file: &str, path: &str, prim: &Prim, budget: &mut Budget) -> Result<MeshData<'a>> {
    let at = |what: &str| format!("{} {what}", shown(path));
    let bad = |field: String, detail: String| Error::malformed(file.to_owned(), field, detail);
    let floats = |value: &Value, field: &str, budget: &mut Budget| -> Result<Vec<f32>> {
        match value {
            Value::Floats { values, .. } if values.is_empty() => Ok(Vec::new()),
            Value::Doubles { values, .. } if values.is_empty() => Ok(Vec::new()),
            Value::Ints(values) if values.is_empty() => Ok(Vec::new()),
            Value::Floats { arity: 3, values } => {
                budget.take("points", values.len() as u64 * 4)?;
                Ok(values.clone())
            }
            Value::Doubles { arity: 3, values } => {
                budget.take("points", values.len() as u64 * 4)?;
                Ok(values.iter().map(|&v| v as f32).collect())
            }
            _ => Err(bad(at(field), "is not a list of 3-component points".into())),
        }
    };
    // A topology attribute: its default, or its one time sample (a changing topology is refused).
    let topology = |name: &str| -> Result<Vec<u32>> {
        let attr = prim.attribute(name).ok_or_else(|| bad(at(name), "is missing".into()))?;
        if attr.samples.len() > 1 {
            return Err(unsupported(
                file,
                format!("{}.{name} is time-sampled: a changing topology is not a vertex cache", shown(path)),
            ));
        }
        let value = attr.samples.first().map(|s| s.1.as_ref()).unwrap_or(attr.default.as_ref());
        match value {
            Some(Value::Ints(v)) => v
                .iter()
                .map(|&i| u32::try_from(i).ok())
                .collect::<Option<Vec<u32>>>()
                .ok_or_else(|| bad(at(name), "holds a value that is not a non-negative integer".into())),
            Some(Value::Floats { values, .. }) if values.is_empty() => Ok(Vec::new()),
            Some(_) => Err(bad(at(name), "is not a list of integers".into())),
            None => Err(bad(at(name), "is missing".into())),
        }
    };
    let points = prim.attribute("points");
    let default = points.and_then(|a| a.default.as_ref()).map(|v| floats(v, "points", budget)).transpose()?;
    let mut samples = Vec::with_capacity(points.map_or(0, |a| a.samples.len()));
    for (time, value) in points.map_or(&[][..], |a| &a.samples[..]) {
        // A blocked sample has no points: USD reports no value there; the frame is filled
        // from the samples around it, as for a time the mesh does not sample.
        if let Some(v) = value {
            samples.push((*time, floats(v, "points.timeSamples", budget)?));
        }
    }
    let first = samples.first().map(|s| &s.1).or(default.as_ref());
    let Some(first) = first else {
        return Err(bad(at("points"), "has no value (neither a default nor a time sample)".into()));
    };
    let vertices = first.len() / 3;
    if vertices == 0 {
        return Err(bad(at("points"), "is empty".into()));
    }
    for (time, s) in &samples {
        if s.len() != first.len() {
            return Err(unsupported(
                file,
                format!(
                    "{} has {} points at time code {time} but {vertices} at the first sample: a changing point count \
                     is not a vertex cache",
                    at("points"),
                    s.len() / 3
                ),
            ));
        }
    }
    let counts = topology("faceVertexCounts")?;
    let indices = topology("faceVertexIndices")?;
    let left_handed =
        prim.attribute("orientation").is_some_and(|a| matches!(&a.default, Some(Value::Token(t)) if t == "leftHanded"));
    let corners: u64 = counts.iter().map(|&c| c as u64).sum();
    if corners != indices.len() as u64 {
        return Err(bad(
            at("faceVertexCounts"),
            format!("sums to {corners} corners but faceVertexIndices holds {}", indices.len()),
        ));
    }
    if let Some(&i) = indices.iter().find(|&&i| i as usize >= vertices) {
        return Err(bad(at("faceVertexIndices"), format!("index {i} is out of range ({vertices} points)")));
    }
    let fan: u64 = counts.iter().map(|&c| (c as u64).saturating_sub(2)).sum();
    budget.take("triangles", fan * 12)?;
    let mut triangles = Vec::with_capacity(fan as usize);
    let mut at_corner = 0usize;
    for (face, &n) in counts.iter().enumerate() {
        let n = n as usize;
        if n < 3 {
            return Err(bad(at("faceVertexCounts"), format!("face {face} has {n} corners (at least 3 are needed)")));
        }
        let f = &indices[at_corner..at_corner + n];
        for k in 1..n - 1 {
            let tri = if left_handed { [f[0], f[k + 1], f[k]] } else { [f[0], f[k], f[k + 1]] };
            triangles.push(tri);
        }
        at_corner += n;
    }
    Ok(MeshData {
        vertices,
        triangles,
        samples,
        default,
        transforms: Vec::new(),
        transform_times: Vec::new(),
        deformer: None,
        prim: 0,
    })
}
