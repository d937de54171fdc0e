//! glTF 2.0 / GLB output: the animation as one mesh with position morph targets and a
//! `weights` animation, which every glTF engine plays (three.js, Babylon, Blender, Unity's and
//! Unreal's importers) and which [`super::gltf::read_gltf`] reads back.
//!
//! Layouts:
//! - [`GltfLayout::Basis`] (default): the mean shape as the base mesh plus principal components
//!   of the frames (centred on that mean) as morph targets; weights keyed at every frame,
//!   `LINEAR`. Compressed (the default): every component quantized at its own step for the KG
//!   target, the ones that round to nothing dropped, weights in [0, 1] (`gltf_out_rd`).
//!   Uncompressed: the `k` leading components in f32, each shifted and scaled so its weights
//!   lie in [0, 1] (the slider range DCC importers clamp shape keys to), `k` the smallest meeting the KG target (computed exactly from the PCA's discarded
//!   energy), or given.
//! - [`GltfLayout::Frames`]: frame 0 as the base mesh and one morph target per later frame
//!   (its difference from frame 0), `STEP` weights selecting one target per frame: exact, large.
//!
//! A source that is not +Y up in metres (its [`SceneMetadata`]: a +Z-up USD layer in
//! centimetres) gets a root node above everything whose `matrix` turns it +Y up and scales it
//! to metres, as glTF's coordinate system requires (glTF 2.0 §3.4 "Coordinate System and
//! Units"): the coded positions stay as the source stored them and a viewer shows the model
//! upright and at its size ([`scene_root`], [`as_shown`]).
//!
//! The frame rate travels in the animation's `extras` (`{"animcodec": {"fps": …}}`, glTF has no
//! field for it), keys sit at `frame / fps` seconds. A `.glb` holds the JSON and one binary
//! chunk; a `.gltf` embeds its buffer as a base64 `data:` URI, so either is one self-contained
//! file.

use base64::Engine as _;
use codec_core::{Animation, Error, Result, SceneMetadata, UpAxis};

pub use super::gltf_out_buffer::GltfCompression;
use super::gltf_out_buffer::{align4, drop_zero_offsets, shortest, Buffer, WeightForm};
use super::gltf_out_morphs::{basis_morphs, frame_morphs, quantize, rigid_split, Morphs, RigidMotion};
use super::gltf_out_rd::{self, QBasis};
use serde_json::{json, Value};

/// How the frames become morph targets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GltfLayout {
    /// Mean shape + principal components (few targets, smooth `LINEAR` weights).
    Basis,
    /// Frame 0 + one target per frame with `STEP` weights (exact).
    Frames,
}

/// Options of [`encode_gltf`].
#[derive(Debug, Clone, PartialEq)]
pub struct GltfOptions {
    /// Layout. Default [`GltfLayout::Basis`].
    pub layout: GltfLayout,
    /// `Basis`: number of morph targets; `None` = the smallest meeting `target_kg`.
    pub targets: Option<usize>,
    /// `Basis` without `targets`: the KG error (percent) the written frames must meet, > 0.
    /// Default 0.05.
    pub target_kg: f64,
    /// Mesh, node and animation name.
    pub name: String,
    /// How the geometry and the keys are stored. Default [`GltfCompression::Meshopt`]; the
    /// frames layout is exact up to the 16-bit quantization when quantized.
    pub compression: GltfCompression,
    /// `Basis`: move the per-frame rigid motion (Kabsch fit of each frame to the mean shape:
    /// rotation + translation) to a parent node's `rotation`/`translation` animation and
    /// decompose only what is left. `Some(true)`/`Some(false)` force it; `None` (default) writes
    /// both and keeps the smaller file (with `targets` given: the smaller KG).
    pub rigid: Option<bool>,
    /// Welds vertices with identical positions on every frame and writes them in the order
    /// the triangles first use them after meshoptimizer's vertex-cache ordering (as gltfpack
    /// does), so neighbours sit next to each other and the vertex codec's deltas are small; the
    /// triangle list keeps its order (renumbered). The file then plays the input's vertices
    /// through [`GltfSummary::vertex_map`]. Default false: the file keeps the input's vertices.
    pub reorder: bool,
}

impl Default for GltfOptions {
    fn default() -> Self {
        Self {
            layout: GltfLayout::Basis,
            targets: None,
            target_kg: 0.05,
            name: "animcodec".into(),
            compression: GltfCompression::Meshopt,
            rigid: None,
            reorder: false,
        }
    }
}

/// What [`encode_gltf`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct GltfSummary {
    /// Morph targets written.
    pub targets: usize,
    /// Of those, principal components (`Basis`; the compressed basis may add one target, the
    /// base's residual) or frames (`Frames`).
    pub components: usize,
    /// `Basis`: KG (%) of the basis against the input, computed in f64 (compressed: from the
    /// quantized integers and weights written; else the truncation, before f32 rounding); 0
    /// for `Frames`.
    pub basis_kg: f64,
    /// The rigid motion went to node animation.
    pub rigid: bool,
    /// With [`GltfOptions::reorder`]: input vertex `i` is played by the file's vertex
    /// `vertex_map[i]` ([`restore_vertices`]).
    pub vertex_map: Option<Vec<u32>>,
}

/// The vertex map of [`GltfOptions::reorder`]: `map[i]` = the file vertex playing input vertex
/// `i`, and the number of file vertices. Vertices with bit-identical positions on every frame
/// are welded into one (a flat-shaded or multi-part mesh repeats each corner per face:
/// RobotExpressive's 7 214 vertices are 1 820 trajectories); the welded vertices are then
/// numbered in the order meshoptimizer's vertex-cache-ordered triangles first use them
/// (`optimizeVertexFetchRemap`), unused ones last.
fn weld_map(a: &Animation) -> (Vec<u32>, usize, Vec<[u32; 3]>) {
    let v = a.vertex_count();
    let mut first_of: std::collections::HashMap<Vec<u32>, u32> = std::collections::HashMap::new();
    let mut welded = Vec::with_capacity(v);
    for i in 0..v {
        let key: Vec<u32> =
            (0..a.frame_count()).flat_map(|f| a.frame(f)[3 * i..3 * i + 3].iter().map(|x| x.to_bits())).collect();
        let next = first_of.len() as u32;
        welded.push(*first_of.entry(key).or_insert(next));
    }
    let unique = first_of.len();
    let tri: Vec<u32> = a.triangles().iter().flatten().map(|&i| welded[i as usize]).collect();
    let cached = meshopt::optimize_vertex_cache(&tri, unique);
    let remap = meshopt::optimize_vertex_fetch_remap(&cached, unique);
    let mut order = vec![u32::MAX; unique];
    let mut next = remap.iter().filter(|&&r| (r as usize) < unique).count() as u32;
    for (old, &new) in remap.iter().enumerate() {
        if (new as usize) < unique {
            order[old] = new;
        } else {
            order[old] = next;
            next += 1;
        }
    }
    // The triangles in the cache order (each keeps its corners), renumbered: the index
    // sequence then codes small deltas.
    let triangles = cached.chunks_exact(3).map(|t| [order[t[0] as usize], order[t[1] as usize], order[t[2] as usize]]);
    (welded.iter().map(|&w| order[w as usize]).collect(), unique, triangles.collect())
}

/// Clips up to this many frames also try [`motion_order`]'s vertex order (an export is then
/// coded once more; longer clips keep the fetch order).
const MOTION_ORDER_FRAMES: usize = 64;

/// How many edge rings around the last placed vertices [`motion_order`] looks for the next.
const MOTION_ORDER_RINGS: usize = 3;

/// How many of the last placed vertices [`motion_order`] looks around, newest first, until
/// one has an unplaced vertex within [`MOTION_ORDER_RINGS`] rings.
const MOTION_ORDER_RECENT: usize = 8;

/// A vertex order for the compressed basis of `a` (`order[old] = new`): meshoptimizer's
/// vertex codec codes each vertex as the byte-wise difference from the previous one, so the
/// file's streams (base and targets, each at its own step) code smaller when consecutive
/// vertices have close values in every stream at once, not only close positions. Greedy
/// path: from vertex 0, the next vertex is the unplaced one, within a few edge rings of the
/// last placed ones, whose stream coordinates ([`gltf_out_rd::stream_coordinates`]) differ
/// least in `Σ log2(1 + |Δ| / step)` (about the bits a delta costs); with none nearby, the
/// first unplaced vertex. Sequential and tie-broken by index: the same order on every run.
fn motion_order(a: &Animation, target_kg: f64) -> Result<Vec<u32>> {
    let v = a.vertex_count();
    let (coordinates, width) = gltf_out_rd::stream_coordinates(a, target_kg)?;
    let mut adjacent: Vec<Vec<u32>> = vec![Vec::new(); v];
    for t in a.triangles() {
        for (x, y) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            adjacent[x as usize].push(y);
            adjacent[y as usize].push(x);
        }
    }
    for list in &mut adjacent {
        list.sort_unstable();
        list.dedup();
    }
    let row = |i: usize| &coordinates[i * width..(i + 1) * width];
    let cost =
        |x: usize, y: usize| -> f64 { row(x).iter().zip(row(y)).map(|(p, q)| (1.0 + (p - q).abs()).log2()).sum() };
    let mut order = vec![u32::MAX; v];
    let mut path: Vec<usize> = Vec::with_capacity(v);
    // `seen[i] == stamp`: vertex i was reached in the current ring search.
    let (mut seen, mut stamp) = (vec![0u32; v], 0u32);
    let mut cursor = 0;
    let mut candidates = Vec::new();
    let mut frontier = Vec::new();
    let mut next_frontier = Vec::new();
    while path.len() < v {
        candidates.clear();
        for &source in path.iter().rev().take(MOTION_ORDER_RECENT) {
            stamp += 1;
            seen[source] = stamp;
            frontier.clear();
            frontier.push(source);
            for _ in 0..MOTION_ORDER_RINGS {
                next_frontier.clear();
                for &x in &frontier {
                    for &y in &adjacent[x] {
                        let y = y as usize;
                        if seen[y] != stamp {
                            seen[y] = stamp;
                            next_frontier.push(y);
                            if order[y] == u32::MAX {
                                candidates.push(y);
                            }
                        }
                    }
                }
                std::mem::swap(&mut frontier, &mut next_frontier);
            }
            if !candidates.is_empty() {
                break;
            }
        }
        let next = match path.last() {
            Some(&last) if !candidates.is_empty() => {
                candidates.sort_unstable();
                *candidates.iter().min_by(|&&x, &&y| cost(last, x).total_cmp(&cost(last, y))).expect("not empty")
            }
            _ => {
                while order[cursor] != u32::MAX {
                    cursor += 1;
                }
                cursor
            }
        };
        order[next] = path.len() as u32;
        path.push(next);
    }
    Ok(order)
}

/// `a` as the file holds it under `map` (see [`weld_map`]), with `triangles`.
fn welded(a: &Animation, map: &[u32], count: usize, triangles: Vec<[u32; 3]>) -> Result<Animation> {
    let mut source = vec![0usize; count];
    for (i, &m) in map.iter().enumerate() {
        source[m as usize] = i;
    }
    let mut positions = Vec::with_capacity(count * 3 * a.frame_count());
    for f in 0..a.frame_count() {
        let frame = a.frame(f);
        for &i in &source {
            positions.extend_from_slice(&frame[3 * i..3 * i + 3]);
        }
    }
    Animation::from_parts(count, triangles, positions, a.frame_rate())
}

/// Undoes [`GltfOptions::reorder`] on a played-back file: the input's vertices (each from the
/// file vertex `map` names) and triangles.
pub fn restore_vertices(played: &Animation, map: &[u32], triangles: &[[u32; 3]]) -> Result<Animation> {
    let mut positions = Vec::with_capacity(map.len() * 3 * played.frame_count());
    for f in 0..played.frame_count() {
        let frame = played.frame(f);
        for &m in map {
            let m = m as usize;
            let p = frame
                .get(3 * m..3 * m + 3)
                .ok_or_else(|| Error::InvalidAnimation("the vertex map names a vertex the file lacks".into()))?;
            positions.extend_from_slice(p);
        }
    }
    Animation::from_parts(map.len(), triangles.to_vec(), positions, played.frame_rate())
}

/// Encodes `animation` as glTF: GLB bytes when `glb`, else glTF JSON with an embedded buffer.
pub fn encode_gltf(animation: &Animation, options: &GltfOptions, glb: bool) -> Result<(Vec<u8>, GltfSummary)> {
    if !(options.target_kg.is_finite() && options.target_kg > 0.0) {
        return Err(Error::parameter(
            "glTF export",
            "target_kg",
            format!("{} is not a finite positive KG (%)", options.target_kg),
        ));
    }
    // Keys sit at frame / fps seconds: outside the range they overflow or collapse in f32
    // (1e-45 fps put frame 1 at +inf s, an invalid file).
    super::check_frame_rate(animation.frame_rate()).map_err(|e| match e {
        Error::InvalidAnimation(msg) => Error::parameter(
            "glTF export",
            "frame rate",
            format!("{msg}: its keys (frame / fps seconds) would not be valid glTF times"),
        ),
        other => other,
    })?;
    let root = scene_root(animation.metadata())?;
    if options.reorder && animation.frame_count() > 0 && !animation.triangles().is_empty() {
        // Played back through the root node, the file shows the input as `as_shown` places it.
        let shown = as_shown(animation)?;
        let reference = shown.as_ref().unwrap_or(animation);
        let (mut map, count, triangles) = weld_map(animation);
        let mut moved = welded(animation, &map, count, triangles)?;
        // A second vertex order for the compressed basis of a short clip, kept when its first
        // file is smaller.
        let mut other = None;
        if options.layout == GltfLayout::Basis
            && options.compression.meshopt()
            && animation.frame_count() > 1
            && animation.frame_count() <= MOTION_ORDER_FRAMES
        {
            let order = motion_order(&moved, options.target_kg)?;
            let map2: Vec<u32> = map.iter().map(|&m| order[m as usize]).collect();
            let triangles2 = moved.triangles().iter().map(|t| t.map(|i| order[i as usize])).collect();
            other = Some((welded(animation, &map2, count, triangles2)?, map2));
        }
        // KG on the welded vertices counts each trajectory once, on the input's as often as it
        // repeats: the target is checked on the input's vertices as played back, and aimed
        // lower by the overshoot when missed (a few rounds).
        // The inner aim is bisected between the last that met the target and the last that
        // missed; the smallest file that meets it is kept.
        let mut inner = GltfOptions { reorder: false, ..options.clone() };
        let mut best: Option<(Vec<u8>, GltfSummary, f64)> = None;
        let (mut met_aim, mut missed_aim) = (None::<f64>, None::<f64>);
        for _ in 0..5 {
            let (mut bytes, mut summary) = encode_inner(&moved, &inner, glb, true, root)?;
            if let Some((moved2, map2)) = other.take() {
                let (bytes2, summary2) = encode_inner(&moved2, &inner, glb, true, root)?;
                if bytes2.len() < bytes.len() {
                    (bytes, summary, moved, map) = (bytes2, summary2, moved2, map2);
                }
            }
            let played = super::gltf::parse_gltf(&bytes, None, "glTF export", animation.frame_rate())?;
            let played = restore_vertices(&played, &map, animation.triangles())?;
            let kg = gltf_out_rd::kg_between(reference, &played);
            summary.basis_kg = kg;
            let fixed = options.layout == GltfLayout::Frames || options.targets.is_some();
            let met = kg <= options.target_kg || fixed;
            let better = match &best {
                None => true,
                Some((held, _, held_kg)) => match (met, *held_kg <= options.target_kg || fixed) {
                    (true, true) => bytes.len() < held.len(),
                    (true, false) => true,
                    (false, true) => false,
                    (false, false) => kg < *held_kg,
                },
            };
            if better {
                best = Some((bytes, summary, kg));
            }
            if fixed {
                break;
            }
            let aim = inner.target_kg;
            if met {
                met_aim = Some(met_aim.map_or(aim, |m: f64| m.max(aim)));
            } else {
                missed_aim = Some(missed_aim.map_or(aim, |m: f64| m.min(aim)));
            }
            inner.target_kg = match (met_aim, missed_aim) {
                // Met with room to spare: aim higher.
                (Some(_), None) if kg < 0.98 * options.target_kg => aim * options.target_kg / kg * 0.995,
                (Some(_), None) => break,
                (Some(lo), Some(hi)) if hi / lo < 1.02 => break,
                (Some(lo), Some(hi)) => (lo * hi).sqrt(),
                _ => aim * options.target_kg / kg * 0.995,
            };
        }
        let (bytes, mut summary, _) = best.expect("one round");
        summary.vertex_map = Some(map);
        return Ok((bytes, summary));
    }
    encode_inner(animation, options, glb, false, root)
}

/// The `matrix` (column-major) of the root node a source with `metadata` needs in glTF, which
/// is +Y up in metres (glTF 2.0 §3.4): a +Z-up source turned by −90° about X, `(x, y, z) →
/// (x, z, −y)` (exact; a rotation keeps the triangles' winding), then scaled by its metres per
/// unit. `None` when the source is +Y up in metres or said nothing (glTF's own convention is
/// assumed); an error when the scale has no `f32` form.
pub fn scene_root(metadata: &SceneMetadata) -> Result<Option<[f32; 16]>> {
    let z_up = metadata.up_axis == Some(UpAxis::Z);
    let meters = metadata.meters_per_unit.unwrap_or(1.0);
    if !z_up && meters == 1.0 {
        return Ok(None);
    }
    let s = meters as f32;
    if !(s.is_normal() && s > 0.0) {
        return Err(Error::parameter(
            "glTF export",
            "metersPerUnit",
            format!("{meters} has no single-precision scale for the glTF root node"),
        ));
    }
    Ok(Some(if z_up {
        // Columns: the images of x, y, z: x → x, y → −z, z → y.
        [s, 0., 0., 0., 0., 0., -s, 0., 0., s, 0., 0., 0., 0., 0., 1.]
    } else {
        [s, 0., 0., 0., 0., s, 0., 0., 0., 0., s, 0., 0., 0., 0., 1.]
    }))
}

/// `animation` where a glTF viewer shows it once written: through [`scene_root`]'s matrix, in
/// `f64` and rounded to `f32` as a glTF reader places a vertex, with its metadata then saying
/// +Y up in metres; `None` when no root node is written (the positions are shown as they are).
/// What the written file is measured against.
pub fn as_shown(animation: &Animation) -> Result<Option<Animation>> {
    let Some(m) = scene_root(animation.metadata())? else {
        return Ok(None);
    };
    let m = m.map(f64::from);
    let positions = animation
        .positions()
        .chunks_exact(3)
        .flat_map(|p| super::gltf_anim::transform_point(&m, [p[0] as f64, p[1] as f64, p[2] as f64]).map(|x| x as f32))
        .collect();
    let metadata = SceneMetadata { up_axis: Some(UpAxis::Y), meters_per_unit: Some(1.0), ..*animation.metadata() };
    Animation::new(animation.topology().clone(), positions, animation.frame_rate())?.with_metadata(metadata).map(Some)
}

/// [`encode_gltf`] after the checks and the welding; `rotate`: see [`Buffer::rotate`]; `root`:
/// the [`scene_root`] matrix.
fn encode_inner(
    full: &Animation,
    options: &GltfOptions,
    glb: bool,
    rotate: bool,
    root: Option<[f32; 16]>,
) -> Result<(Vec<u8>, GltfSummary)> {
    if options.layout == GltfLayout::Frames {
        return finish(full, Geometry::Float(frame_morphs(full)), None, options, (glb, rotate), root);
    }
    // Basis: the rigid motion split off or not (`rigid`; both when `None`), and each space's
    // candidate geometries; the smallest file is kept (with `targets` given: the smallest KG).
    let mut spaces: Vec<(Animation, Option<RigidMotion>)> = Vec::new();
    if full.frame_count() >= 2 && options.rigid != Some(false) {
        let (local, motion) = rigid_split(full)?;
        spaces.push((local, Some(motion)));
    }
    if full.frame_count() < 2 || options.rigid != Some(true) {
        spaces.push((full.clone(), None));
    }
    let mut best: Option<((Vec<u8>, GltfSummary), f64)> = None;
    for (space, motion) in spaces {
        let candidates = basis_geometry(&space, options)?;
        for geometry in candidates {
            let kg = geometry.basis_kg();
            let written = finish(&space, geometry, motion.clone(), options, (glb, rotate), root)?;
            let better = best.as_ref().is_none_or(|(b, b_kg)| match options.targets {
                None => written.0.len() < b.0.len(),
                Some(_) => kg < *b_kg,
            });
            if better {
                best = Some((written, kg));
            }
        }
    }
    Ok(best.expect("at least one candidate").0)
}

/// The morph targets to write: float (or quantized as a whole by [`quantize`] when
/// compressed), or the basis quantized for a KG target ([`gltf_out_rd`]).
enum Geometry {
    Float(Morphs),
    Quantized(QBasis),
}

impl Geometry {
    fn basis_kg(&self) -> f64 {
        match self {
            Geometry::Float(m) => m.basis_kg,
            Geometry::Quantized(q) => q.kg,
        }
    }
}

/// Clips up to this many frames also try successive differences as targets.
const SUCCESSIVE_DIFFERENCES_FRAMES: usize = 64;

/// The basis layout's candidate morphs: compressed, the principal components and (without
/// `targets`) the differences from frame 0, each quantized for the KG target; else float.
fn basis_geometry(a: &Animation, options: &GltfOptions) -> Result<Vec<Geometry>> {
    // One frame is a plain mesh: 16-bit positions, as the frames layout writes it.
    if options.compression.quantized() && a.frame_count() > 1 {
        let limit = options.targets.unwrap_or(usize::MAX);
        let pca = gltf_out_rd::pca(a)?;
        let kg = options.target_kg;
        let mut out = Vec::new();
        // Without a target count: steps chosen on the coded bytes; with one, the high-rate
        // allocation that can hold the count exactly.
        let mut add = |basis: &gltf_out_rd::Pca| -> Result<()> {
            out.push(Geometry::Quantized(match options.targets {
                None => gltf_out_rd::quantized_basis_coded(a, basis, kg, options.compression.vertex_codec_version())?,
                Some(_) => gltf_out_rd::quantized_basis(a, basis, kg, (limit, limit))?,
            }));
            Ok(())
        };
        add(&pca)?;
        match options.targets {
            None => {
                let differences = gltf_out_rd::differences(a);
                add(&differences)?;
                // Short clips, where one target per frame is what a KG target needs: frame-to-
                // frame steps. (On long clips the principal components win and this candidate's
                // F − 1 targets would only cost time.)
                if a.frame_count() <= SUCCESSIVE_DIFFERENCES_FRAMES {
                    let steps = gltf_out_rd::successive_differences(a);
                    add(&steps)?;
                }
            }
            // `targets` counts every target written (K components plus the base's residual
            // would be K + 1): K components, or K − 1 and the residual, whichever plays closer.
            Some(k) if k > 0 => {
                out.push(Geometry::Quantized(gltf_out_rd::quantized_basis(a, &pca, kg, (k - 1, k))?));
            }
            Some(_) => {}
        }
        Ok(out)
    } else {
        Ok(vec![Geometry::Float(basis_morphs(a, options.targets, options.target_kg)?)])
    }
}

/// Writes the file: `animation` (already without the rigid motion when `motion` is given) as
/// `geometry`, the motion as a parent node's animation, everything under a node with the
/// `root` matrix when given ([`scene_root`]); `form`: `(glb, rotate)`.
fn finish(
    animation: &Animation,
    geometry: Geometry,
    motion: Option<RigidMotion>,
    options: &GltfOptions,
    form: (bool, bool),
    root_matrix: Option<[f32; 16]>,
) -> Result<(Vec<u8>, GltfSummary)> {
    let (glb, rotate) = form;
    // The meshopt forms are for engines and web viewers: no field they do not need.
    let compact = options.compression.meshopt();
    let frames = animation.frame_count();
    // With rigid motion: node 0 carries it, its child node 1 the mesh.
    let mesh_node = if motion.is_some() { 1 } else { 0 };
    let mut buf = Buffer::new(options.compression);
    buf.rotate = rotate;
    let tri: Vec<u32> = animation.triangles().iter().flatten().copied().collect();
    let indices = buf.indices(&tri, animation.vertex_count());
    let mut node = json!({"mesh": 0, "name": options.name});
    let mut weight_form = WeightForm::F32;
    let (position, targets, weights, basis_kg, components, names) = match geometry {
        Geometry::Float(mut morphs) => {
            let k = morphs.targets.len();
            let names: Vec<String> = (0..k)
                .map(|j| match options.layout {
                    GltfLayout::Basis => format!("component {j}"),
                    GltfLayout::Frames => format!("frame {}", j + 1),
                })
                .collect();
            let (position, targets) = if options.compression.quantized() {
                let q = quantize(animation, &mut morphs);
                node["translation"] = shortest(&q.translation);
                node["scale"] = shortest(&q.scale);
                let arrays: Vec<&[[i16; 3]]> =
                    std::iter::once(q.base.as_slice()).chain(q.targets.iter().map(Vec::as_slice)).collect();
                let accessors = buf.positions(&arrays, &vec![false; arrays.len()], false)?;
                let targets = accessors[1..].iter().map(|&a| json!({"POSITION": a})).collect();
                (accessors[0], targets)
            } else {
                let position = buf.floats(&morphs.base, "VEC3", Some(34962), true)?;
                let targets: Vec<Value> = morphs
                    .targets
                    .iter()
                    .map(|t| Ok(json!({"POSITION": buf.floats(t, "VEC3", Some(34962), true)?})))
                    .collect::<Result<_>>()?;
                (position, targets)
            };
            (position, targets, morphs.weights, morphs.basis_kg, k, names)
        }
        Geometry::Quantized(q) => {
            node["translation"] = shortest(&q.translation.map(|x| x as f32));
            let scale = q.scale as f32;
            node["scale"] = shortest(&[scale, scale, scale]);
            weight_form = if q.weights_exponential { WeightForm::Exponential } else { WeightForm::F32 };
            let arrays: Vec<&[[i16; 3]]> =
                std::iter::once(q.base.as_slice()).chain(q.targets.iter().map(|t| t.values.as_slice())).collect();
            let narrow = gltf_out_rd::narrow_targets(options.compression.vertex_codec_version());
            let bytes: Vec<bool> = std::iter::once(false).chain(q.targets.iter().map(|t| t.bytes && narrow)).collect();
            let accessors = buf.positions(&arrays, &bytes, q.base_normalized)?;
            let position = accessors[0];
            let targets: Vec<Value> = accessors[1..].iter().map(|&a| json!({"POSITION": a})).collect();
            let names = (0..q.targets.len())
                .map(|j| if j < q.components { format!("component {j}") } else { "base residual".into() })
                .collect();
            (position, targets, q.weights, q.kg, q.components, names)
        }
    };
    let k = targets.len();
    let fps = animation.frame_rate();
    let mut primitive = json!({"attributes": {"POSITION": position}, "indices": indices});
    // Triangles (4) is the default mode (glTF 2.0 `mesh.primitive.mode`): written out only
    // outside the compact form.
    if !compact {
        primitive["mode"] = 4.into();
    }
    // A sampler's interpolation defaults to `LINEAR` (`animation.sampler.interpolation`).
    let sampler = |input: usize, output: usize, interpolation: &str| {
        let mut s = json!({"input": input, "output": output});
        if !(compact && interpolation == "LINEAR") {
            s["interpolation"] = interpolation.into();
        }
        s
    };
    let mut mesh = json!({"name": options.name, "primitives": []});
    // Shape-key names for DCC importers; the compressed basis's targets are numbered
    // components, which importers name the same way by default, so the bytes are saved.
    if !names.is_empty() && !options.compression.meshopt() {
        mesh["extras"] = json!({"targetNames": names});
    }
    let mut root = json!({
        "asset": {"version": "2.0", "generator": concat!("animcodec ", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [node],
    });
    if let Some(m) = &motion {
        // The rigid part's node starts at frame 0's pose.
        let parent = json!({"name": format!("{} motion", options.name), "children": [1],
            "translation": shortest(&m.translations[..3]), "rotation": shortest(&m.rotations[..4])});
        root["nodes"] = json!([parent, root["nodes"][0].clone()]);
    }
    if let Some(matrix) = root_matrix {
        // Last, so the animation channels keep their node indices.
        if let Some(nodes) = root["nodes"].as_array_mut() {
            let last = nodes.len();
            // Whole numbers as integers (`0`, not `0.0`).
            let matrix: Vec<Value> = matrix
                .iter()
                .zip(shortest(&matrix).as_array().into_iter().flatten())
                .map(|(&x, short)| if x.fract() == 0.0 { json!(x as i32) } else { short.clone() })
                .collect();
            nodes.push(json!({"name": format!("{} +Y up, metres", options.name), "matrix": matrix,
                "children": [0]}));
            root["scenes"] = json!([{"nodes": [last]}]);
        }
    }
    let (mut channels, mut samplers) = (Vec::new(), Vec::new());
    let times: Vec<f32> = (0..frames).map(|f| f as f32 / fps).collect();
    let mut input = None;
    if k > 0 {
        primitive["targets"] = targets.into();
        // The node starts at frame 0's weights so a viewer without animation shows frame 0
        // (the compact form to 3 significant digits: a still pose, not the played frames).
        mesh["weights"] = if compact { significant(&weights[..k], 3) } else { shortest(&weights[..k]) };
        if frames > 1 {
            let keys = buf.floats(&times, "SCALAR", None, true)?;
            input = Some(keys);
            let output = buf.weights(&weights, k, weight_form)?;
            let interpolation = if options.layout == GltfLayout::Frames { "STEP" } else { "LINEAR" };
            channels.push(json!({"sampler": samplers.len(), "target": {"node": mesh_node, "path": "weights"}}));
            samplers.push(sampler(keys, output, interpolation));
        }
    }
    if let (Some(m), true) = (&motion, frames > 1) {
        let keys = match input {
            Some(keys) => keys,
            None => buf.floats(&times, "SCALAR", None, true)?,
        };
        for (path, data, kind) in [("translation", &m.translations, "VEC3"), ("rotation", &m.rotations, "VEC4")] {
            let output = buf.floats(data, kind, None, false)?;
            channels.push(json!({"sampler": samplers.len(), "target": {"node": 0, "path": path}}));
            samplers.push(sampler(keys, output, "LINEAR"));
        }
    }
    if !channels.is_empty() {
        let mut clip = json!({"name": options.name, "channels": channels, "samplers": samplers});
        // The compact form leaves the rate out when a reader recovers it from the key grid.
        if !(compact && key_grid_gives(&times, fps)) {
            clip["extras"] = json!({"animcodec": {"fps": fps}});
        }
        root["animations"] = json!([clip]);
    }
    mesh["primitives"] = json!([primitive]);
    root["meshes"] = json!([mesh]);
    let mut views = buf.views;
    if compact {
        views.iter_mut().for_each(drop_zero_offsets);
    }
    root["bufferViews"] = views.into();
    root["accessors"] = buf.accessors.into();
    let mut bin = buf.bin;
    align4(&mut bin);
    let summary = GltfSummary { targets: k, components, basis_kg, rigid: motion.is_some(), vertex_map: None };
    let mut buffers = vec![json!({"byteLength": bin.len()})];
    let extensions = options.compression.extensions();
    if !extensions.is_empty() {
        root["extensionsUsed"] = json!(extensions);
        root["extensionsRequired"] = json!(extensions);
    }
    if let Some(name) = options.compression.meshopt_extension() {
        buffers.push(json!({"byteLength": buf.fallback, "extensions": {name: {"fallback": true}}}));
    }
    if glb {
        root["buffers"] = buffers.into();
        Ok((glb_bytes(&root, &bin)?, summary))
    } else {
        let uri =
            format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bin));
        buffers[0]["uri"] = uri.into();
        root["buffers"] = buffers.into();
        let text = serde_json::to_vec(&root).map_err(|e| Error::InvalidAnimation(format!("glTF JSON: {e}")))?;
        Ok((text, summary))
    }
}

/// `values` as a JSON array of decimals with `digits` significant digits (the shortest that
/// reads back as the same `f32` when that is shorter).
fn significant(values: &[f32], digits: usize) -> Value {
    let exact = shortest(values);
    Value::Array(
        values
            .iter()
            .zip(exact.as_array().into_iter().flatten())
            .map(|(&x, exact)| {
                let rounded: f64 = format!("{:.*e}", digits.saturating_sub(1), x).parse().unwrap_or(x as f64);
                match serde_json::Number::from_f64(rounded) {
                    Some(n) if n.to_string().len() < exact.to_string().len() => Value::Number(n),
                    _ => exact.clone(),
                }
            })
            .collect(),
    )
}

/// Whether a reader without the rate in `extras` samples keys at `times` (`frame / fps`) at
/// `fps`: the key grid it finds (`gltf_scene_channels::key_rate`, the rule the reader applies)
/// is `fps` itself.
fn key_grid_gives(times: &[f32], fps: f32) -> bool {
    let track = super::gltf_anim::Track {
        times: times.to_vec(),
        values: Vec::new(),
        width: 1,
        interpolation: ::gltf::animation::Interpolation::Linear,
        rotation: false,
    };
    let channel = super::gltf_scene_channels::Channel {
        node: 0,
        property: ::gltf::animation::Property::MorphTargetWeights,
        track,
    };
    times.len() >= 2 && super::gltf_scene_channels::key_rate(&[channel]) == Some(f64::from(fps))
}

/// GLB container (glTF spec §4.4): 12-byte header, JSON chunk padded with spaces, BIN chunk
/// padded with zeros, every chunk 4-byte aligned.
fn glb_bytes(root: &Value, bin: &[u8]) -> Result<Vec<u8>> {
    let mut json_chunk = serde_json::to_vec(root).map_err(|e| Error::InvalidAnimation(format!("glTF JSON: {e}")))?;
    while json_chunk.len() % 4 != 0 {
        json_chunk.push(b' ');
    }
    let mut bin_chunk = bin.to_vec();
    while !bin_chunk.len().is_multiple_of(4) {
        bin_chunk.push(0);
    }
    let total = 12 + 8 + json_chunk.len() + 8 + bin_chunk.len();
    let total = u32::try_from(total)
        .map_err(|_| Error::InvalidAnimation(format!("a GLB is at most 4 GiB; this one would be {total} bytes")))?;
    let mut out = Vec::with_capacity(total as usize);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total.to_le_bytes());
    out.extend_from_slice(&(json_chunk.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_chunk);
    out.extend_from_slice(&(bin_chunk.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin_chunk);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use animcodec_synth as synth;

    fn read_back(bytes: &[u8], fps: f32) -> Animation {
        super::super::gltf::parse_gltf(bytes, None, "test.glb", fps).unwrap()
    }

    fn max_diff(a: &Animation, b: &Animation) -> f32 {
        a.positions().iter().zip(b.positions()).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max)
    }

    /// A +Z-up centimetre source is written under a root node that turns it +Y up in metres:
    /// read back, it plays where `as_shown` places it (exactly up to f32 rounding in the frames
    /// layout, within the KG target in the compressed basis, .glb and .gltf alike); a source
    /// without metadata gets no such node.
    #[test]
    fn a_z_up_centimetre_source_plays_upright_in_metres() {
        let plain = synth::by_name("flag", synth::SynthSize::Small).unwrap();
        let meta = SceneMetadata { up_axis: Some(UpAxis::Z), meters_per_unit: Some(0.01), ..Default::default() };
        let a = plain.clone().with_metadata(meta).unwrap();
        let shown = as_shown(&a).unwrap().unwrap();
        let p = a.frame(3)[..3].to_vec();
        let q = &shown.frame(3)[..3];
        assert!((q[0] - p[0] * 0.01).abs() <= 1e-6 && (q[1] - p[2] * 0.01).abs() <= 1e-6, "{p:?} -> {q:?}");
        assert!((q[2] + p[1] * 0.01).abs() <= 1e-6, "{p:?} -> {q:?}");
        let diagonal = shown.bounding_box_diagonal() as f32;
        for (layout, compression, glb) in
            [(GltfLayout::Frames, GltfCompression::None, true), (GltfLayout::Basis, GltfCompression::Meshopt, false)]
        {
            let opts = GltfOptions { layout, compression, target_kg: 0.5, ..Default::default() };
            let (bytes, _) = encode_gltf(&a, &opts, glb).unwrap();
            let played = read_back(&bytes, a.frame_rate());
            if layout == GltfLayout::Frames {
                assert!(max_diff(&shown, &played) <= 1e-6 * diagonal, "{}", max_diff(&shown, &played));
            } else {
                let kg = gltf_out_rd::kg_between(&shown, &played);
                assert!(kg <= 0.5 * 1.001, "KG {kg} against the source shown");
            }
            let (bytes, _) = encode_gltf(&plain, &opts, glb).unwrap();
            let text = String::from_utf8_lossy(&bytes);
            assert!(!text.contains("\"matrix\""), "a source without metadata got a root node");
        }
        let huge = plain.with_metadata(SceneMetadata { meters_per_unit: Some(1e300), ..Default::default() }).unwrap();
        let e = encode_gltf(&huge, &GltfOptions::default(), true).unwrap_err().to_string();
        assert!(e.contains("metersPerUnit"), "{e}");
    }

    /// Frames layout: our reader plays back every frame to f32 rounding of the differences;
    /// compressed, to the 16-bit quantization: at most half a step of the base and of the
    /// (rescaled) target, 3 · half-extent / 65534 per axis, below 2.5e-5 × the diagonal.
    #[test]
    fn frames_layout_plays_back_every_frame() {
        use GltfCompression::*;
        let a = synth::waving_flag(10, 6, 12);
        for glb in [true, false] {
            for compression in [None, Quantized, Meshopt] {
                let opts = GltfOptions { layout: GltfLayout::Frames, compression, ..Default::default() };
                let (bytes, summary) = encode_gltf(&a, &opts, glb).unwrap();
                assert_eq!(summary.targets, 11);
                let b = read_back(&bytes, a.frame_rate());
                assert_eq!((b.frame_count(), b.vertex_count()), (12, a.vertex_count()));
                assert_eq!(b.triangles(), a.triangles());
                let bound = if compression.quantized() { 2.5e-5 * a.bounding_box_diagonal() as f32 } else { 1e-5 };
                assert!(max_diff(&a, &b) < bound, "{compression:?}: {} > {bound}", max_diff(&a, &b));
                let text = String::from_utf8_lossy(&bytes);
                assert_eq!(text.contains("EXT_meshopt_compression"), compression.meshopt());
                assert_eq!(text.contains("KHR_mesh_quantization"), compression.quantized());
            }
        }
        // Quantization makes the file smaller; meshopt's codecs gain nothing on a mesh this small
        // (60 vertices: the extension's JSON outweighs them), so it is only bounded here.
        let size = |compression| {
            let opts = GltfOptions { layout: GltfLayout::Frames, compression, ..Default::default() };
            encode_gltf(&a, &opts, true).unwrap().0.len()
        };
        let (meshopt, quantized, plain) = (size(Meshopt), size(Quantized), size(None));
        assert!(quantized < plain && meshopt < plain, "{meshopt} {quantized} {plain}");
    }

    /// The `weights` sampler output of a GLB whose views are stored plainly (no meshopt).
    fn plain_weights(glb: &[u8]) -> Vec<f32> {
        let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
        let doc: Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
        let bin = &glb[20 + json_len + 8..];
        let animation = &doc["animations"][0];
        let channel =
            animation["channels"].as_array().unwrap().iter().find(|c| c["target"]["path"] == "weights").unwrap();
        let accessor = &doc["accessors"]
            [animation["samplers"][channel["sampler"].as_u64().unwrap() as usize]["output"].as_u64().unwrap() as usize];
        let view = &doc["bufferViews"][accessor["bufferView"].as_u64().unwrap() as usize];
        assert!(view.get("extensions").is_none(), "a plain view: {view}");
        let start =
            view["byteOffset"].as_u64().unwrap() as usize + accessor["byteOffset"].as_u64().unwrap_or(0) as usize;
        let count = accessor["count"].as_u64().unwrap() as usize;
        bin[start..start + 4 * count].chunks_exact(4).map(|b| f32::from_le_bytes(b.try_into().unwrap())).collect()
    }

    /// Every weight written lies in [0, 1], the range DCC importers give a shape key's slider
    /// (Blender 5.0 clamps animated values to it): the basis layout with and without the rigid
    /// motion split off (the meshopt form writes the quantized form's weights, compressed), and
    /// the frames layout of a travelling body.
    #[test]
    fn weights_lie_in_zero_one() {
        let a = synth::waving_flag(16, 10, 30);
        for rigid in [Some(false), Some(true)] {
            let mut kgs = Vec::new();
            for compression in [GltfCompression::None, GltfCompression::Quantized, GltfCompression::Meshopt] {
                let opts = GltfOptions { target_kg: 0.01, compression, rigid, ..Default::default() };
                let (bytes, s) = encode_gltf(&a, &opts, true).unwrap();
                assert!(s.targets > 1, "{s:?}");
                let kg = metrics::kg_error(&a, &read_back(&bytes, a.frame_rate())).unwrap();
                assert!(kg <= 0.01, "{compression:?} {rigid:?}: KG {kg}");
                kgs.push(kg);
                if compression.meshopt() {
                    continue;
                }
                let weights = plain_weights(&bytes);
                assert_eq!(weights.len(), s.targets * a.frame_count());
                let (lo, hi) = weights.iter().fold((f32::MAX, f32::MIN), |(l, h), &w| (l.min(w), h.max(w)));
                assert!(lo >= 0.0 && hi <= 1.0, "{compression:?} {rigid:?}: weights in [{lo}, {hi}]");
            }
            assert_eq!(kgs[1], kgs[2], "meshopt stores the quantized form's values");
        }
        // Frames layout of a body that travels further than half its box (a target then reaches
        // past the base's 16-bit range): the step grows, the weights stay 0 or 1.
        let mut travel = Vec::new();
        for f in 0..a.frame_count() {
            travel.extend(a.frame(f).chunks_exact(3).flat_map(|p| [p[0] + 0.5 * f as f32, p[1], p[2]]));
        }
        let travel = Animation::from_parts(a.vertex_count(), a.triangles().to_vec(), travel, 30.0).unwrap();
        let opts =
            GltfOptions { layout: GltfLayout::Frames, compression: GltfCompression::Quantized, ..Default::default() };
        let (bytes, _) = encode_gltf(&travel, &opts, true).unwrap();
        let weights = plain_weights(&bytes);
        assert!(weights.iter().all(|&w| (0.0..=1.0).contains(&w)), "frames layout weights leave [0, 1]");
        let played = read_back(&bytes, 30.0);
        let bound = 5e-5 * travel.bounding_box_diagonal() as f32;
        assert!(max_diff(&travel, &played) < bound, "{} > {bound}", max_diff(&travel, &played));
    }

    /// Basis layout: the KG target is met on playback, more targets for a tighter target, and
    /// the number of targets given explicitly is honoured.
    #[test]
    fn basis_layout_meets_the_kg_target() {
        let a = synth::waving_flag(16, 10, 30);
        let mut last = 0;
        for t in [1.0, 0.1, 0.01] {
            let (bytes, s) = encode_gltf(&a, &GltfOptions { target_kg: t, ..Default::default() }, true).unwrap();
            let b = read_back(&bytes, a.frame_rate());
            assert_eq!(b.frame_count(), a.frame_count());
            let kg = metrics::kg_error(&a, &b).unwrap();
            assert!(s.basis_kg <= t && kg <= t, "target {t}: basis {} played {kg}", s.basis_kg);
            assert!(s.targets >= last);
            last = s.targets;
        }
        // Exactly 3 targets: compressed, 3 components or 2 and the base's residual (whichever
        // plays closer); uncompressed, 3 components.
        let (_, s) = encode_gltf(&a, &GltfOptions { targets: Some(3), ..Default::default() }, true).unwrap();
        assert!(s.components == 3 || s.components == 2, "{s:?}");
        assert_eq!(s.targets, 3, "--targets K writes K targets in all, the base's residual included: {s:?}");
        let plain = GltfOptions { targets: Some(3), compression: GltfCompression::None, ..Default::default() };
        assert_eq!(encode_gltf(&a, &plain, true).unwrap().1.targets, 3);
        let e = encode_gltf(&a, &GltfOptions { target_kg: 0.0, ..Default::default() }, true).unwrap_err();
        assert!(e.to_string().contains("target_kg"), "{e}");
    }

    /// A tumbling rigid body: its motion goes to the parent node's animation (auto picks it:
    /// fewer targets, smaller file) and plays back within the KG target; forcing it off needs more.
    #[test]
    fn rigid_motion_goes_to_node_animation() {
        let a = synth::by_name("tumble", synth::SynthSize::Small).unwrap();
        let opts = GltfOptions { target_kg: 0.5, ..Default::default() };
        let (bytes, auto) = encode_gltf(&a, &opts, true).unwrap();
        let (plain, off) = encode_gltf(&a, &GltfOptions { rigid: Some(false), ..opts.clone() }, true).unwrap();
        assert!(auto.rigid && auto.targets < off.targets, "auto {auto:?}, off {off:?}");
        assert!(bytes.len() < plain.len());
        let b = read_back(&bytes, a.frame_rate());
        let kg = metrics::kg_error(&a, &b).unwrap();
        assert!(kg <= 0.5, "played back KG {kg}");
        let text = String::from_utf8_lossy(&bytes);
        assert!(text.contains("\"rotation\"") && text.contains("\"translation\""));
    }

    /// `reorder`: vertices repeating another's trajectory are welded (the file holds fewer),
    /// the map brings the played frames back to the input's vertices within the KG target, the
    /// file is smaller, and the triangles come back as the input's through the map.
    #[test]
    fn welded_vertices_play_back_through_the_map() {
        let flag = synth::waving_flag(12, 8, 20);
        let (v, frames) = (flag.vertex_count(), flag.frame_count());
        // Every vertex of the first row written twice (the second copy used by no triangle).
        let extra = 12;
        let mut positions = Vec::new();
        for f in 0..frames {
            positions.extend_from_slice(flag.frame(f));
            positions.extend_from_slice(&flag.frame(f)[..3 * extra]);
        }
        let a = Animation::from_parts(v + extra, flag.triangles().to_vec(), positions, flag.frame_rate()).unwrap();
        let opts = GltfOptions { target_kg: 0.05, ..Default::default() };
        let (plain, _) = encode_gltf(&a, &opts, true).unwrap();
        let (bytes, s) = encode_gltf(&a, &GltfOptions { reorder: true, ..opts }, true).unwrap();
        let map = s.vertex_map.clone().unwrap();
        let b = read_back(&bytes, a.frame_rate());
        assert_eq!(b.vertex_count(), v, "the repeated vertices are welded");
        assert!(map[v..].iter().zip(&map[..extra]).all(|(x, y)| x == y));
        let restored = restore_vertices(&b, &map, a.triangles()).unwrap();
        let kg = metrics::kg_error(&a, &restored).unwrap();
        assert!(kg <= 0.05 && (kg - s.basis_kg).abs() < 1e-9, "KG {kg}, reported {}", s.basis_kg);
        assert!(bytes.len() < plain.len(), "{} vs {}", bytes.len(), plain.len());
        // The file's triangles are the input's, renumbered (corners possibly rotated).
        let mut ours: Vec<[u32; 3]> = a.triangles().iter().map(|t| t.map(|i| map[i as usize])).collect();
        let mut theirs = b.triangles().to_vec();
        let canonical = |t: &mut [u32; 3]| {
            let m = (0..3).min_by_key(|&k| t[k]).unwrap();
            t.rotate_left(m);
        };
        ours.iter_mut().for_each(canonical);
        theirs.iter_mut().for_each(canonical);
        ours.sort();
        theirs.sort();
        assert_eq!(ours, theirs);
    }

    /// The `KHR_meshopt_compression` form: every vertex stream in the vertex codec's format
    /// version 1 (its first byte, `0xa1`; `0xa0` under `EXT_meshopt_compression`), the same
    /// bytes on every run, the KG target met on the input's vertices, and smaller than the
    /// `EXT_…` form; the motion order it is written in is a permutation, the same on every run.
    #[test]
    fn khr_meshopt_form_writes_version_1_and_is_smaller() {
        let a = synth::waving_flag(16, 10, 30);
        let order = motion_order(&a, 0.05).unwrap();
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..a.vertex_count() as u32).collect::<Vec<_>>());
        assert_eq!(order, motion_order(&a, 0.05).unwrap());
        let mut sizes = Vec::new();
        for (compression, version) in [(GltfCompression::Meshopt, 0xa0u8), (GltfCompression::MeshoptKhr, 0xa1)] {
            let opts = GltfOptions { target_kg: 0.05, compression, reorder: true, ..Default::default() };
            let (bytes, s) = encode_gltf(&a, &opts, true).unwrap();
            assert_eq!(bytes, encode_gltf(&a, &opts, true).unwrap().0, "{compression:?}: not deterministic");
            let json_length = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
            let doc: Value = serde_json::from_slice(&bytes[20..20 + json_length]).unwrap();
            let bin = &bytes[20 + json_length + 8..];
            let name = compression.meshopt_extension().unwrap();
            assert_eq!(doc["extensionsRequired"][1], name);
            let mut streams = 0;
            for view in doc["bufferViews"].as_array().unwrap() {
                let Some(ext) = view["extensions"].get(name) else { continue };
                if ext["mode"] == "ATTRIBUTES" {
                    assert_eq!(bin[ext["byteOffset"].as_u64().unwrap() as usize], version, "{compression:?}");
                    streams += 1;
                }
            }
            assert!(streams > 0);
            let played =
                restore_vertices(&read_back(&bytes, a.frame_rate()), s.vertex_map.as_ref().unwrap(), a.triangles());
            let kg = metrics::kg_error(&a, &played.unwrap()).unwrap();
            assert!(kg <= 0.05, "{compression:?}: KG {kg}");
            sizes.push(bytes.len());
        }
        assert!(sizes[1] < sizes[0], "KHR {} bytes, EXT {}", sizes[1], sizes[0]);
    }

    /// The meshopt forms leave out what a reader needs not be told: the frame rate when the
    /// key grid gives it (a reader told nothing samples at the same rate; a rate off the
    /// integers keeps it), the default primitive mode and interpolation, zero byte offsets;
    /// the default weights are short. `KHR_meshopt_compression` writes every target in one
    /// SHORT view. The other forms keep every field.
    #[test]
    fn the_compact_form_leaves_out_defaults() {
        let doc = |bytes: &[u8]| -> Value {
            let json_length = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
            serde_json::from_slice(&bytes[20..20 + json_length]).unwrap()
        };
        let a = synth::waving_flag(16, 10, 30);
        for (fps, compression) in [
            (24.0, GltfCompression::Meshopt),
            (29.97, GltfCompression::Meshopt),
            (30.0, GltfCompression::MeshoptKhr),
            (24.0, GltfCompression::Quantized),
        ] {
            let a =
                Animation::from_parts(a.vertex_count(), a.triangles().to_vec(), a.positions().to_vec(), fps).unwrap();
            let opts = GltfOptions { target_kg: 0.05, compression, ..Default::default() };
            let (bytes, s) = encode_gltf(&a, &opts, true).unwrap();
            assert!(s.targets > 1);
            let j = doc(&bytes);
            let compact = compression.meshopt();
            let integral = fps.fract() == 0.0;
            assert_eq!(j["animations"][0].get("extras").is_none(), compact && integral, "{fps} {compression:?}");
            assert_eq!(j["meshes"][0]["primitives"][0].get("mode").is_none(), compact);
            assert_eq!(j["animations"][0]["samplers"][0].get("interpolation").is_none(), compact);
            let zero_offsets = j["bufferViews"].to_string().contains("\"byteOffset\":0,");
            assert_eq!(zero_offsets, !compact, "{}", j["bufferViews"]);
            let defaults = j["meshes"][0]["weights"].as_array().unwrap();
            assert_eq!(defaults.len(), s.targets);
            // A reader told no rate samples the file at the source's.
            let selection = super::super::gltf::GltfSelection::default();
            let played = super::super::gltf::parse_gltf_with(&bytes, None, "t.glb", &selection).unwrap();
            assert_eq!((played.frame_rate(), played.frame_count()), (fps, a.frame_count()), "{compression:?}");
            let kg = metrics::kg_error(&a, &played).unwrap();
            assert!(kg <= 0.05, "{compression:?}: KG {kg}");
            let views = j["bufferViews"].as_array().unwrap();
            let narrow = views.iter().filter(|v| v.to_string().contains("\"byteStride\":4,")).count();
            if compression == GltfCompression::MeshoptKhr {
                assert_eq!(narrow, 0, "KHR writes no BYTE view: {views:?}");
            }
        }
        assert!(key_grid_gives(&[0.0, 0.1, 0.2], 10.0) && !key_grid_gives(&[0.0], 10.0));
        assert!(!key_grid_gives(&[0.0, 1.0 / 29.97, 2.0 / 29.97], 29.97));
    }

    /// A frame rate other than the reader's default keeps the frame times (keys at f / fps).
    #[test]
    fn keys_sit_at_the_frame_times() {
        let a = synth::waving_flag(6, 4, 7);
        let a = Animation::from_parts(a.vertex_count(), a.triangles().to_vec(), a.positions().to_vec(), 24.0).unwrap();
        let (bytes, _) =
            encode_gltf(&a, &GltfOptions { layout: GltfLayout::Frames, ..Default::default() }, true).unwrap();
        assert_eq!(read_back(&bytes, 24.0).frame_count(), 7);
    }

    #[test]
    fn one_frame_is_a_plain_mesh() {
        let a = synth::waving_flag(6, 4, 1);
        for layout in [GltfLayout::Basis, GltfLayout::Frames] {
            let (bytes, s) = encode_gltf(&a, &GltfOptions { layout, ..Default::default() }, true).unwrap();
            assert_eq!(s.targets, 0);
            let b = read_back(&bytes, 30.0);
            assert_eq!(b.frame_count(), 1);
            // 16-bit positions: half a step of the half-extent.
            assert!(max_diff(&a, &b) < 1e-5 * a.bounding_box_diagonal() as f32);
        }
    }
}
