//! A glTF scene played back into one fixed-topology vertex cache: every mesh instance of the
//! scene (node hierarchy, node TRS animation, skins, morph targets) sampled at a frame rate.
//! The choices are listed in [`super::gltf`]'s module docs; the arithmetic is in
//! [`super::gltf_anim`].

use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::animation::Property;
use codec_core::{Animation, Result};

use super::gltf_anim::{self, Mat4, IDENTITY};
use super::gltf_buffers::{bad, check_accessor, collect_exact, Budget, BufferData, KHR_MESH_QUANTIZATION};
pub(super) use super::gltf_scene_channels::list;
pub use super::gltf_scene_channels::AnimationInfo;
use super::gltf_scene_channels::{choose, extras_fps, key_grid, key_range, load_channels, node_targets, MIN_KEY_RATE};
use super::gltf_scene_mesh::{limit, load_mesh, MeshData, MAX_BAKE_WORK};
use super::{in_file, FRAME_RATE_RANGE};

/// Frame rate when neither the caller, the file's `extras` nor a regular key grid gives one.
const FALLBACK_FPS: f64 = 30.0;

/// The node hierarchy: each node's parent, and every node in an order where parents come
/// before their children.
struct Hierarchy {
    parent: Vec<Option<usize>>,
    order: Vec<usize>,
}

/// Builds the hierarchy of every node of the document; a node with two parents or a cycle is
/// an error (glTF requires the nodes to form disjoint trees).
fn hierarchy(file: &str, document: &::gltf::Document) -> Result<Hierarchy> {
    let count = document.nodes().len();
    let mut parent = vec![None; count];
    for node in document.nodes() {
        for child in node.children() {
            if let Some(other) = parent[child.index()] {
                return Err(bad(
                    file,
                    "nodes",
                    format!("node {} is a child of both node {other} and node {}", child.index(), node.index()),
                ));
            }
            parent[child.index()] = Some(node.index());
        }
    }
    let children: Vec<Vec<usize>> = document.nodes().map(|n| n.children().map(|c| c.index()).collect()).collect();
    let mut order = Vec::with_capacity(count);
    let mut reached = vec![false; count];
    let mut stack: Vec<usize> = (0..count).rev().filter(|&n| parent[n].is_none()).collect();
    while let Some(n) = stack.pop() {
        order.push(n);
        reached[n] = true;
        stack.extend(children[n].iter().rev());
    }
    // Every node has at most one parent, so a node not reached from a root lies on a cycle.
    if let Some(stuck) = reached.iter().position(|r| !r) {
        return Err(bad(file, "nodes", format!("node {stuck} is part of a cycle in the node hierarchy")));
    }
    Ok(Hierarchy { parent, order })
}

/// The mesh instances of the scene, in the documented vertex order: the default scene (else
/// scene 0, else every root node), its root nodes in order, each subtree depth first with a
/// node's own mesh before its children.
fn scene_mesh_nodes(document: &::gltf::Document, hierarchy: &Hierarchy) -> Vec<usize> {
    let roots: Vec<usize> = match document.default_scene().or_else(|| document.scenes().next()) {
        Some(scene) => scene.nodes().map(|n| n.index()).collect(),
        None => (0..hierarchy.parent.len()).filter(|&n| hierarchy.parent[n].is_none()).collect(),
    };
    let nodes: Vec<::gltf::Node> = document.nodes().collect();
    let mut out = Vec::new();
    // A node reached twice (invalid: a root listed twice, or a root that is also a descendant of
    // another root) is played once, at its first visit; this keeps the walk linear in the node
    // count (a chain listing every node as a root would otherwise visit ~N²/2 nodes).
    let mut seen = vec![false; nodes.len()];
    let mut stack: Vec<usize> = roots.into_iter().rev().collect();
    while let Some(n) = stack.pop() {
        if std::mem::replace(&mut seen[n], true) {
            continue;
        }
        if nodes[n].mesh().is_some() {
            out.push(n);
        }
        stack.extend(nodes[n].children().map(|c| c.index()).collect::<Vec<_>>().into_iter().rev());
    }
    out
}

/// A node's local transform at rest: TRS (animatable) or a matrix (not animatable).
#[derive(Clone, Copy)]
enum Local {
    Trs { t: [f64; 3], r: [f64; 4], s: [f64; 3] },
    Matrix(Mat4),
}

fn rest_transform(node: &::gltf::Node) -> Local {
    match node.transform() {
        ::gltf::scene::Transform::Matrix { matrix } => {
            let mut m = [0.0; 16];
            for (c, column) in matrix.iter().enumerate() {
                for (r, x) in column.iter().enumerate() {
                    m[4 * c + r] = *x as f64;
                }
            }
            Local::Matrix(m)
        }
        ::gltf::scene::Transform::Decomposed { translation, rotation, scale } => {
            Local::Trs { t: translation.map(f64::from), r: rotation.map(f64::from), s: scale.map(f64::from) }
        }
    }
}

/// A mesh instance in the cache: its node, mesh, skin and first vertex.
struct Instance {
    node: usize,
    mesh: usize,
    skin: Option<usize>,
    offset: usize,
    /// Rest morph weights (node's, else mesh's, else zeros).
    weights: Vec<f64>,
}

/// A skin: joint nodes and inverse bind matrices.
struct Skin {
    joints: Vec<usize>,
    inverse_bind: Vec<Mat4>,
}

fn load_skin(file: &str, skin: &::gltf::Skin, buffers: &[BufferData]) -> Result<Skin> {
    let joints: Vec<usize> = skin.joints().map(|n| n.index()).collect();
    if joints.is_empty() {
        return Err(bad(file, "skins", format!("skin {} has no joints", skin.index())));
    }
    let inverse_bind = match skin.inverse_bind_matrices() {
        None => vec![IDENTITY; joints.len()],
        Some(acc) => {
            let count = check_accessor(file, "inverseBindMatrices", &acc, Dimensions::Mat4, &[DataType::F32], buffers)?;
            if count < joints.len() {
                return Err(bad(
                    file,
                    "inverseBindMatrices",
                    format!("skin {}: {count} inverse bind matrices for {} joints", skin.index(), joints.len()),
                ));
            }
            let reader = skin.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
            let raw = collect_exact(file, "inverseBindMatrices", reader.read_inverse_bind_matrices(), count)?;
            raw.iter()
                .take(joints.len())
                .map(|m| {
                    let mut out = [0.0; 16];
                    for (c, column) in m.iter().enumerate() {
                        for (r, x) in column.iter().enumerate() {
                            out[4 * c + r] = *x as f64;
                        }
                    }
                    out
                })
                .collect()
        }
    };
    Ok(Skin { joints, inverse_bind })
}

/// What to play: the animation (name or index; `None` = the first) and the frame rate
/// (`None` = the file's own: animcodec's `extras`, else the key grid, else 30).
pub(super) struct Selection<'a> {
    pub animation: Option<&'a str>,
    pub frame_rate: Option<f64>,
    /// Copies of the positions the caller holds after the read (`GltfSelection::working_copies`).
    pub working_copies: u64,
}

/// Plays the scene into a vertex cache. `json` is the file's raw JSON (extension data,
/// animcodec's `extras`); everything held is counted against `budget` before it is allocated.
pub(super) fn bake(
    file: &str,
    document: &::gltf::Document,
    buffers: &[BufferData],
    json: &serde_json::Value,
    selection: &Selection,
    budget: &mut Budget,
) -> Result<Animation> {
    let limits = super::reader_limits();
    let hierarchy = hierarchy(file, document)?;
    let mesh_nodes = scene_mesh_nodes(document, &hierarchy);
    if mesh_nodes.is_empty() {
        return Err(bad(file, "meshes", "no node of the scene has a mesh"));
    }
    let quantization = json
        .get("extensionsUsed")
        .and_then(|u| u.as_array())
        .is_some_and(|u| u.iter().any(|e| e.as_str() == Some(KHR_MESH_QUANTIZATION)));
    let nodes: Vec<::gltf::Node> = document.nodes().collect();
    let mut meshes: Vec<Option<MeshData>> = (0..document.meshes().len()).map(|_| None).collect();
    let mut skins: Vec<Option<Skin>> = (0..document.skins().len()).map(|_| None).collect();
    let mut instances = Vec::new();
    let mut vertex_count = 0usize;
    let mut triangle_count = 0usize;
    for &n in &mesh_nodes {
        let mesh = nodes[n].mesh().expect("a mesh node");
        let m = mesh.index();
        if meshes[m].is_none() {
            let data = load_mesh(file, &mesh, document, buffers, json, quantization, budget)?;
            let held = 4 * (data.base.len() + data.targets.iter().map(Vec::len).sum::<usize>() + data.weights.len())
                + 2 * data.joints.len()
                + 12 * data.triangles.len();
            budget.take("mesh data", held as u64)?;
            meshes[m] = Some(data);
        }
        let data = meshes[m].as_ref().expect("loaded");
        let skin = nodes[n].skin().map(|s| s.index());
        if let Some(s) = skin {
            if skins[s].is_none() {
                skins[s] = Some(load_skin(file, &nodes[n].skin().expect("a skin"), buffers)?);
            }
            let joints = skins[s].as_ref().expect("loaded").joints.len();
            if data.influences == 0 {
                return Err(bad(file, "JOINTS_0", format!("node {n} has skin {s} but mesh {m} has no JOINTS_0")));
            }
            // A joint index must name a joint of the skin; one carrying zero weight is ignored.
            let bad_joint = data.joints.iter().zip(&data.weights).position(|(&j, &w)| w > 0.0 && j as usize >= joints);
            if let Some(i) = bad_joint {
                return Err(bad(
                    file,
                    "JOINTS",
                    format!(
                        "mesh {m} vertex {} uses joint {} but skin {s} has {joints} joints",
                        i / data.influences,
                        data.joints[i]
                    ),
                ));
            }
        }
        let targets = data.targets.len();
        let rest = nodes[n].weights().or_else(|| mesh.weights()).unwrap_or(&[]);
        if !rest.is_empty() && rest.len() != targets {
            return Err(bad(
                file,
                "weights",
                format!("node {n}: {} default weights for {targets} targets", rest.len()),
            ));
        }
        let mut weights = vec![0.0; targets];
        for (w, &r) in weights.iter_mut().zip(rest) {
            *w = r as f64;
        }
        let offset = vertex_count;
        vertex_count += data.vertex_count();
        if vertex_count > limits.max_vertices {
            return Err(limit(file, "vertex_count", vertex_count, limits.max_vertices));
        }
        // Counted only here; the triangles are built once the whole read is known to fit.
        triangle_count += data.triangles.len();
        if triangle_count > limits.max_triangles {
            return Err(limit(file, "triangle_count", triangle_count, limits.max_triangles));
        }
        instances.push(Instance { node: n, mesh: m, skin, offset, weights });
    }

    let chosen = choose(file, document, selection.animation)?;
    let targets = node_targets(document);
    let channels = match &chosen {
        Some(a) => load_channels(file, a, buffers, &|n| targets[n])?,
        None => Vec::new(),
    };
    let own_rate = || -> Result<f64> {
        if let Some(fps) = chosen.as_ref().and_then(|a| extras_fps(json, a.index())) {
            return Ok(fps);
        }
        match key_grid(&channels) {
            Some(rate) if rate > f64::from(*FRAME_RATE_RANGE.end()) => Err(bad(
                file,
                "animation.input",
                format!(
                    "the keys lie on a grid of {rate:.6e} frames per second, above the highest supported rate {}; \
                     give a frame rate (--fps) to sample it",
                    FRAME_RATE_RANGE.end()
                ),
            )),
            Some(rate) if (MIN_KEY_RATE..=f64::from(*FRAME_RATE_RANGE.end())).contains(&rate) => Ok(rate),
            _ => Ok(FALLBACK_FPS),
        }
    };
    let fps = match selection.frame_rate {
        Some(fps) => fps,
        None => own_rate()?,
    };
    let (t0, frames) = match key_range(&channels) {
        None => (0.0, 1usize),
        Some((t0, t1)) => {
            // The small epsilon keeps a key that falls on a frame boundary (1.5 s × 30 fps) in,
            // also when the f32 key time lies a rounding error short of it (39 / 30 s as f32 is
            // 38.9999986 frames; f32 time errors are ≈ 6e-8 relative, far below 1e-4 frames).
            let frames_f = ((t1 - t0) * fps + 1e-4).floor() + 1.0;
            if frames_f > limits.max_frames as f64 {
                return Err(limit(file, "frame_count", frames_f as usize, limits.max_frames));
            }
            // An animation whose keys span less than one frame at the file's own rate would
            // play as a still (keys microseconds apart): say so rather than lose the motion.
            if frames_f < 2.0 && t1 > t0 && selection.frame_rate.is_none() {
                return Err(bad(
                    file,
                    "animation.input",
                    format!(
                        "the keys span {:.6e} s, less than one frame at {fps} fps: give a frame rate (--fps) to \
                         sample it",
                        t1 - t0
                    ),
                ));
            }
            (t0, frames_f as usize)
        }
    };
    // Everything the playback holds: the positions, the triangles (twice: ours and the
    // animation's topology), and per vertex the f64 morph scratch.
    let positions_bytes = (frames as u64).saturating_mul(vertex_count as u64).saturating_mul(12);
    budget.take("the baked positions (frames × vertices × 12 bytes)", positions_bytes)?;
    if selection.working_copies > 0 {
        // What the command will hold of them, counted now: a small file with many instances
        // must be refused before the command makes its working copies.
        budget.take(
            &format!(
                "the {} copies of the positions a command works on after the read ({} bytes each)",
                selection.working_copies, positions_bytes
            ),
            positions_bytes.saturating_mul(selection.working_copies),
        )?;
    }
    budget.take("the triangles", (triangle_count as u64) * 24)?;
    budget.take("the playback scratch", (vertex_count as u64) * 24)?;
    limits.check_alloc("gltf", "positions", positions_bytes)?;
    // The CPU work is bounded too (the output size alone does not bound it: many nodes or
    // targets cost work every frame): one unit per node transform, channel sample, joint matrix
    // and per vertex per morph target or skin influence.
    let per_frame = instances.iter().fold(nodes.len().saturating_add(channels.len()), |sum, instance| {
        let data = meshes[instance.mesh].as_ref().expect("loaded");
        let joints = instance.skin.and_then(|s| skins[s].as_ref()).map_or(0, |skin| skin.joints.len());
        let per_vertex = 1 + data.targets.len() + data.influences;
        sum.saturating_add(data.vertex_count().saturating_mul(per_vertex)).saturating_add(joints)
    });
    let work = frames.saturating_mul(per_frame);
    if work > MAX_BAKE_WORK {
        return Err(limit(
            file,
            "playback work (frames × (nodes + channels + joints + vertices × (1 + targets + influences)))",
            work,
            MAX_BAKE_WORK,
        ));
    }
    let mut triangles: Vec<[u32; 3]> = Vec::with_capacity(triangle_count);
    for instance in &instances {
        let o = instance.offset as u32;
        let data = meshes[instance.mesh].as_ref().expect("loaded");
        triangles.extend(data.triangles.iter().map(|t| [t[0] + o, t[1] + o, t[2] + o]));
    }
    let mut positions: Vec<f32> = Vec::with_capacity(frames * vertex_count * 3);
    let rest: Vec<Local> = nodes.iter().map(rest_transform).collect();
    let mut local = rest.clone();
    let mut world = vec![IDENTITY; nodes.len()];
    let mut node_weights: Vec<Option<Vec<f64>>> = vec![None; nodes.len()];
    let mut sample = vec![0.0; channels.iter().map(|c| c.track.width).max().unwrap_or(0)];
    let mut morphed: Vec<f64> = Vec::new();
    for k in 0..frames {
        let t = t0 + k as f64 / fps;
        local.copy_from_slice(&rest);
        for c in &channels {
            c.track.sample(t, &mut sample);
            match (&mut local[c.node], c.property) {
                (Local::Trs { t, .. }, Property::Translation) => t.copy_from_slice(&sample[..3]),
                (Local::Trs { r, .. }, Property::Rotation) => r.copy_from_slice(&sample[..4]),
                (Local::Trs { s, .. }, Property::Scale) => s.copy_from_slice(&sample[..3]),
                (_, Property::MorphTargetWeights) => node_weights[c.node] = Some(sample[..c.track.width].to_vec()),
                (Local::Matrix(_), _) => unreachable!("checked by load_channels"),
            }
        }
        for &n in &hierarchy.order {
            let m = match local[n] {
                Local::Trs { t, r, s } => gltf_anim::from_trs(t, r, s),
                Local::Matrix(m) => m,
            };
            world[n] = match hierarchy.parent[n] {
                Some(p) => gltf_anim::mul(&world[p], &m),
                None => m,
            };
        }
        for instance in &instances {
            let data = meshes[instance.mesh].as_ref().expect("loaded");
            debug_assert_eq!(positions.len(), (k * vertex_count + instance.offset) * 3);
            // Morph first (spec §3.7.2.2 "Morph Targets"), then skin or place the node.
            let weights = node_weights[instance.node].as_deref().unwrap_or(&instance.weights);
            morphed.clear();
            morphed.extend(data.base.iter().map(|&x| x as f64));
            for (target, &w) in data.targets.iter().zip(weights) {
                if w != 0.0 {
                    for (p, &d) in morphed.iter_mut().zip(target) {
                        *p += w * d as f64;
                    }
                }
            }
            match instance.skin {
                None => {
                    for p in morphed.chunks_exact(3) {
                        let q = gltf_anim::transform_point(&world[instance.node], [p[0], p[1], p[2]]);
                        positions.extend(q.map(|x| x as f32));
                    }
                }
                Some(s) => {
                    // Spec §3.7.3 "Skins": joint matrix = world(joint) × inverse bind matrix;
                    // the skinned mesh node's own transform is not applied.
                    let skin = skins[s].as_ref().expect("loaded");
                    let joint_matrices: Vec<Mat4> = skin
                        .joints
                        .iter()
                        .zip(&skin.inverse_bind)
                        .map(|(&j, ibm)| gltf_anim::mul(&world[j], ibm))
                        .collect();
                    let per = data.influences;
                    for (v, p) in morphed.chunks_exact(3).enumerate() {
                        let p = [p[0], p[1], p[2]];
                        let mut q = [0.0f64; 3];
                        let mut total = 0.0;
                        for i in v * per..(v + 1) * per {
                            let w = data.weights[i] as f64;
                            if w > 0.0 {
                                let moved = gltf_anim::transform_point(&joint_matrices[data.joints[i] as usize], p);
                                (0..3).for_each(|a| q[a] += w * moved[a]);
                                total += w;
                            }
                        }
                        // A vertex with no weight stays where its node puts it.
                        let q = if total > 0.0 { q } else { gltf_anim::transform_point(&world[instance.node], p) };
                        positions.extend(q.map(|x| x as f32));
                    }
                }
            }
        }
    }
    Animation::from_parts(vertex_count, triangles, positions, fps as f32).map_err(|e| in_file(file, e))
}
