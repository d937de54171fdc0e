//! Errors per part: the KG error of every connected part of the mesh against its
//! own extent and motion.
//!
//! The global KG error is normalised by the spread of the whole scene, so a large or far part
//! (a static 1000 × 1000 floor, a triangle at x = 1e5, a second copy 1e4 away) hides a part
//! that is destroyed: a deforming 1 × 1 plane beside such a floor decoded at KG 18–5200 % of
//! its own spread while the scene's KG read 0.003–0.49 %. Every part a user sees must hold the
//! quality on its own, so [`part_errors`] measures each part as if it were the whole
//! animation.
//!
//! * **Parts** are the connected components of the surface a user sees: two vertices are
//!   connected when a triangle holds both, or when they are the same point of the surface —
//!   equal positions in every frame ([`visible_parts`]). Exporters split a vertex wherever its
//!   normal or texture coordinate changes (a hard edge, a UV seam), so in the triangle graph
//!   alone a flat-shaded robot is 1 990 facets of 4–6 vertices and a low-poly horse 38 strips;
//!   each facet is not something a user sees on its own, and measured against its own tiny
//!   spread it would set the quality bound of the whole character. Copies of one point that
//!   move together in every frame are therefore welded (the robot is 63 parts, the horse one).
//!   The loaded [`Animation`] carries no grouping of its own (glTF meshes, USD prims and
//!   Alembic objects are merged into one vertex list when read), so these components are the
//!   parts; two objects touching at a welded point are one part. Parts are numbered by their
//!   smallest vertex index.
//! * **Isolated vertices** (in no triangle) belong to no part: they are points, not a
//!   surface, and stay in the global figures only. A mesh without triangles has no parts.
//! * **Part KG** is [`kg_error`](crate::kg_error) on the part's vertices alone: `100 ·
//!   ‖A_p − Â_p‖ / ‖A_p − E(A_p)‖` with `E(A_p)` the per-frame centroid of the part in the
//!   reference. A static part is normalised by its spatial spread, so it has a well-defined
//!   KG.
//! * **Floor.** A part's spread is measured in the coordinates it sits at, which `f32` resolves
//!   only to about `2⁻²⁴ · |x|`; a part far smaller than that resolution cannot be held to a
//!   relative error at all. The RMS spread of a part is therefore floored at
//!   [`PART_SPREAD_FLOOR`] times the largest coordinate magnitude of the part (a 1-unit
//!   triangle at x = 1e5 is measured at its own size; a 1e-4-unit one there against 0.1).
//!   A part whose every vertex sits at the origin in every frame has no defined KG (`None`),
//!   as for the whole animation.
//!
//! One pass over the frames, `O(V · F)`, in blocks of frames summed in frame order, so the
//! result does not depend on the thread count.

use codec_core::{Animation, Result};
use rayon::prelude::*;
use serde::Serialize;

use crate::common::{check_compatible, point, vertex_dist2};

/// Label of a vertex in no triangle (in no part).
pub const NO_PART: u32 = u32::MAX;

/// A part's RMS spread is floored at this fraction of its largest coordinate magnitude
/// (2⁻¹⁶, 256 `f32` units in the last place): 0.5 % of the floored spread is still about one
/// unit in the last place of the coordinates, the finest error a decoded `f32` part can show.
pub const PART_SPREAD_FLOOR: f64 = 1.0 / 65536.0;

/// The connected parts of a triangle list.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Parts {
    /// Part of every vertex ([`NO_PART`] for a vertex in no triangle).
    pub label: Vec<u32>,
    /// Vertex count of every part.
    pub sizes: Vec<usize>,
    /// Smallest vertex index of every part (parts are numbered in this order).
    pub first_vertex: Vec<usize>,
}

impl Parts {
    /// Number of parts.
    pub fn count(&self) -> usize {
        self.sizes.len()
    }

    /// Vertices in no triangle.
    pub fn isolated(&self) -> usize {
        self.label.iter().filter(|&&l| l == NO_PART).count()
    }
}

/// Connected components of `triangles` over `vertex_count` vertices (union–find, `O(V + T)`).
/// Indices out of range are ignored (the animation checks them on construction).
pub fn connected_parts(vertex_count: usize, triangles: &[[u32; 3]]) -> Parts {
    joined_parts(vertex_count, triangles.iter())
}

/// [`connected_parts`] of `triangles`, an iterator (so seams can join it without a copy of the
/// triangle list).
pub(crate) fn joined_parts<'a>(vertex_count: usize, triangles: impl Iterator<Item = &'a [u32; 3]>) -> Parts {
    let mut parent: Vec<u32> = (0..vertex_count as u32).collect();
    let mut used = vec![false; vertex_count];
    fn find(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            let up = parent[parent[x as usize] as usize];
            parent[x as usize] = up;
            x = up;
        }
        x
    }
    for t in triangles {
        if t.iter().any(|&i| i as usize >= vertex_count) {
            continue;
        }
        for &i in t {
            used[i as usize] = true;
        }
        for k in 1..3 {
            let (a, b) = (find(&mut parent, t[0]), find(&mut parent, t[k]));
            if a != b {
                // The smaller index is the root, so a root is its part's smallest vertex.
                let (lo, hi) = (a.min(b), a.max(b));
                parent[hi as usize] = lo;
            }
        }
    }
    let mut label = vec![NO_PART; vertex_count];
    let mut sizes = Vec::new();
    let mut first_vertex = Vec::new();
    for v in 0..vertex_count {
        if !used[v] {
            continue;
        }
        let root = find(&mut parent, v as u32) as usize;
        // Roots are the smallest vertex of their part, so a root is met before its members.
        if root == v {
            label[v] = sizes.len() as u32;
            sizes.push(0);
            first_vertex.push(v);
        } else {
            label[v] = label[root];
        }
        sizes[label[v] as usize] += 1;
    }
    Parts { label, sizes, first_vertex }
}

/// The parts a user sees ([`connected_parts`] joined across seams): vertices in triangles whose
/// positions are equal in every frame of `animation` are one point of the surface and join
/// their components. `-0.0` equals `0.0`. Vertices in no triangle stay in no part.
///
/// `O(V · F)` time and `O(V)` memory: a 64-bit hash of each vertex's trajectory, then each
/// vertex is compared in full with the first vertex of its hash (a collision can only miss a
/// weld, never make a false one).
pub fn visible_parts(animation: &Animation) -> Parts {
    let n = animation.vertex_count();
    let triangles = animation.triangles();
    let mut used = vec![false; n];
    for t in triangles {
        for &i in t {
            if let Some(u) = used.get_mut(i as usize) {
                *u = true;
            }
        }
    }
    let mut hash = vec![0x9E37_79B9_7F4A_7C15u64; n];
    for t in 0..animation.frame_count() {
        let frame = animation.frame(t);
        for (v, h) in hash.iter_mut().enumerate().filter(|(v, _)| used[*v]) {
            for &x in &frame[3 * v..3 * v + 3] {
                *h = mix(*h ^ u64::from((x + 0.0).to_bits()));
            }
        }
    }
    let mut order: Vec<u32> = (0..n as u32).filter(|&v| used[v as usize]).collect();
    order.sort_unstable_by_key(|&v| (hash[v as usize], v));
    let same_trajectory = |a: usize, b: usize| {
        (0..animation.frame_count()).all(|t| {
            let f = animation.frame(t);
            (0..3).all(|k| f[3 * a + k] == f[3 * b + k])
        })
    };
    let mut seams = Vec::new();
    for run in order.chunk_by(|&a, &b| hash[a as usize] == hash[b as usize]) {
        let first = run[0];
        for &v in &run[1..] {
            if same_trajectory(first as usize, v as usize) {
                seams.push([first, v, v]);
            }
        }
    }
    joined_parts(n, triangles.iter().chain(&seams))
}

/// The seams of [`visible_parts`] found frame by frame: classes of vertices in triangles whose
/// positions have been equal in every frame seen so far (`-0.0` equals `0.0`). The first frame
/// sorts the used vertices by position; each later frame only splits the classes, so the work
/// after the first frame is proportional to the vertices still in a class, and the memory is
/// `O(V)` whatever the frame count. Exact: where [`visible_parts`] could miss a weld on a
/// 64-bit hash collision, this cannot.
#[derive(Debug, Default)]
pub(crate) struct WeldClasses {
    /// Classes of two or more vertices, each in increasing vertex order.
    classes: Vec<Vec<u32>>,
    frames: usize,
}

impl WeldClasses {
    /// Refines the classes by one frame (interleaved xyz of every vertex); `used[v]` says whether
    /// vertex `v` is in a triangle. Returns true when a class split or lost a vertex.
    pub(crate) fn push_frame(&mut self, frame: &[f32], used: &[bool]) -> bool {
        let key = |v: u32| {
            let i = 3 * v as usize;
            [frame[i], frame[i + 1], frame[i + 2]].map(|x| (x + 0.0).to_bits())
        };
        let groups = if self.frames == 0 {
            vec![(0..used.len() as u32).filter(|&v| used[v as usize]).collect::<Vec<u32>>()]
        } else {
            std::mem::take(&mut self.classes)
        };
        let mut changed = false;
        for mut g in groups {
            g.sort_unstable_by_key(|&v| (key(v), v));
            let runs: Vec<&[u32]> = g.chunk_by(|&a, &b| key(a) == key(b)).collect();
            if self.frames > 0 && runs.len() > 1 {
                changed = true;
            }
            self.classes.extend(runs.into_iter().filter(|r| r.len() > 1).map(<[u32]>::to_vec));
        }
        self.frames += 1;
        changed
    }

    /// The seams as degenerate triangles `[first, v, v]` joining each vertex of a class with its
    /// class's first, for [`joined_parts`].
    pub(crate) fn seams(&self) -> Vec<[u32; 3]> {
        self.classes.iter().flat_map(|c| c[1..].iter().map(move |&v| [c[0], v, v])).collect()
    }
}

/// A 64-bit finalizer (SplitMix64's): every input bit changes about half the output bits.
fn mix(mut x: u64) -> u64 {
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// The error of one part.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PartError {
    /// Part number (parts are numbered by their smallest vertex index).
    pub part: usize,
    /// Its smallest vertex index.
    pub first_vertex: usize,
    /// Its vertex count.
    pub vertices: usize,
    /// KG error of the part alone, percent, against its own spread (floored, see the module
    /// notes); `None` when the part is a single point at the origin in every frame.
    pub kg: Option<f64>,
    /// RMS vertex displacement over the part.
    pub rmse: f64,
    /// Largest vertex displacement in the part.
    pub max_error: f64,
    /// RMS distance of the part's vertices from their per-frame centroid (the KG's unit).
    pub spread: f64,
    /// True when `spread` was below the floor and the floor was used instead.
    pub floored: bool,
}

/// Every part's error, by part number. Fails if the animations do not match.
pub fn part_errors(reference: &Animation, candidate: &Animation) -> Result<(Parts, Vec<PartError>)> {
    check_compatible(reference, candidate)?;
    let parts = visible_parts(reference);
    let count = parts.count();
    let frames = reference.frame_count();
    if count == 0 || frames == 0 {
        return Ok((parts, Vec::new()));
    }
    let per_block = part_block_frames(frames);
    let (label, sizes) = (&parts.label, &parts.sizes);
    let blocks: Vec<Vec<PartAcc>> = (0..frames.div_ceil(per_block))
        .into_par_iter()
        .map(|b| {
            let mut acc = vec![PartAcc::default(); count];
            let mut centre = vec![[0.0f64; 3]; count];
            for t in b * per_block..((b + 1) * per_block).min(frames) {
                accumulate_part_frame(reference.frame(t), candidate.frame(t), label, sizes, &mut centre, &mut acc);
            }
            acc
        })
        .collect();
    let mut total = vec![PartAcc::default(); count];
    for block in &blocks {
        merge_part_sums(&mut total, block);
    }
    let errors =
        total.iter().enumerate().map(|(i, a)| part_error(i, parts.first_vertex[i], sizes[i], frames, a)).collect();
    Ok((parts, errors))
}

/// Frames per block of [`part_errors`]: fixed blocks of frames (independent of the thread
/// count), each summed frame after frame, the blocks then added in order.
pub(crate) fn part_block_frames(frames: usize) -> usize {
    const BLOCKS: usize = 64;
    frames.div_ceil(BLOCKS).max(1)
}

/// One part's sums over vertex-frames.
#[derive(Clone, Copy, Default, Debug, PartialEq)]
pub(crate) struct PartAcc {
    /// Squared displacements.
    pub(crate) num: f64,
    /// Squared distances from the part's per-frame centroid.
    pub(crate) den: f64,
    /// Largest squared displacement.
    pub(crate) max2: f64,
    /// Largest coordinate magnitude.
    pub(crate) magnitude: f64,
}

/// Adds one frame (reference `fa`, candidate `fb`) to every part's sums; `centre` is scratch of
/// one entry per part.
pub(crate) fn accumulate_part_frame(
    fa: &[f32],
    fb: &[f32],
    label: &[u32],
    sizes: &[usize],
    centre: &mut [[f64; 3]],
    acc: &mut [PartAcc],
) {
    centre.fill([0.0; 3]);
    for (v, &l) in label.iter().enumerate() {
        if l == NO_PART {
            continue;
        }
        let p = point(fa, v);
        let c = &mut centre[l as usize];
        for k in 0..3 {
            c[k] += p[k];
        }
    }
    for (c, &s) in centre.iter_mut().zip(sizes) {
        for ck in c.iter_mut() {
            *ck /= s as f64;
        }
    }
    for (v, &l) in label.iter().enumerate() {
        if l == NO_PART {
            continue;
        }
        let (p, c, a) = (point(fa, v), centre[l as usize], &mut acc[l as usize]);
        let d2 = vertex_dist2(fa, fb, v);
        a.num += d2;
        a.max2 = a.max2.max(d2);
        a.den += (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2);
        a.magnitude = a.magnitude.max(p[0].abs()).max(p[1].abs()).max(p[2].abs());
    }
}

/// Adds a block's sums into the totals, part by part.
pub(crate) fn merge_part_sums(total: &mut [PartAcc], block: &[PartAcc]) {
    for (t, a) in total.iter_mut().zip(block) {
        t.num += a.num;
        t.den += a.den;
        t.max2 = t.max2.max(a.max2);
        t.magnitude = t.magnitude.max(a.magnitude);
    }
}

/// The error of part `part` (`size` vertices, smallest `first_vertex`) from its sums over
/// `frames` frames.
pub(crate) fn part_error(part: usize, first_vertex: usize, size: usize, frames: usize, a: &PartAcc) -> PartError {
    let samples = (size * frames) as f64;
    let spread = (a.den / samples).sqrt();
    let floor = PART_SPREAD_FLOOR * a.magnitude;
    let floored = spread < floor;
    let unit = spread.max(floor);
    PartError {
        part,
        first_vertex,
        vertices: size,
        kg: (unit > 0.0).then(|| 100.0 * (a.num / samples).sqrt() / unit),
        rmse: (a.num / samples).sqrt(),
        max_error: a.max2.sqrt(),
        spread,
        floored,
    }
}

/// The part of largest KG (ties: the lower part number), or `None` when no part has one.
pub fn worst_part(errors: &[PartError]) -> Option<&PartError> {
    errors.iter().filter(|e| e.kg.is_some_and(f64::is_finite)).fold(None, |best: Option<&PartError>, e| match best {
        Some(b) if b.kg >= e.kg => Some(b),
        _ => Some(e),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kg_error;

    #[test]
    fn components_are_numbered_by_smallest_vertex() {
        // Parts {0, 3, 4} and {1, 2}; vertex 5 is isolated.
        let p = connected_parts(6, &[[4, 3, 0], [2, 1, 1]]);
        assert_eq!(p.label, vec![0, 1, 1, 0, 0, NO_PART]);
        assert_eq!(p.sizes, vec![3, 2]);
        assert_eq!(p.first_vertex, vec![0, 1]);
        assert_eq!((p.count(), p.isolated()), (2, 1));
        // A chain joined through a later triangle is one part.
        let p = connected_parts(7, &[[5, 6, 4], [0, 1, 2], [2, 3, 4]]);
        assert_eq!(p.sizes, vec![7]);
        assert_eq!(connected_parts(3, &[]).count(), 0);
    }

    fn tri(offset: f32, scale: f32) -> [f32; 9] {
        [offset, 0., 0., offset + scale, 0., 0., offset, scale, 0.]
    }

    /// A single part without isolated vertices has the global KG.
    #[test]
    fn one_part_is_the_global_kg() {
        let f0 = tri(0.0, 1.0);
        let mut f1 = tri(0.0, 1.0);
        f1[4] = 0.5;
        let r = Animation::from_parts(3, vec![[0, 1, 2]], [f0, f1].concat(), 30.0).unwrap();
        let mut c = r.positions().to_vec();
        c[0] += 0.01;
        c[13] -= 0.02;
        let c = Animation::from_parts(3, vec![[0, 1, 2]], c, 30.0).unwrap();
        let (_, e) = part_errors(&r, &c).unwrap();
        let global = kg_error(&r, &c).unwrap();
        assert_eq!(e.len(), 1);
        assert!((e[0].kg.unwrap() - global).abs() < 1e-9 * global, "{e:?} vs {global}");
        assert!(!e[0].floored);
    }

    /// A small part wrecked beside a large static one: the global KG is tiny, the part's is
    /// its own ratio (hand computation).
    #[test]
    fn a_small_part_is_measured_against_itself() {
        // Part 0: unit triangle at the origin, static, two frames. Its centroid is (1/3, 1/3, 0);
        // squared distances of the corners: 2/9, 5/9, 5/9 → 12/9 per frame, spread² = (12/9)/3.
        // Part 1: a triangle of size 1000 at x = 5000, static.
        let frame: Vec<f32> = [tri(0.0, 1.0), tri(5000.0, 1000.0)].concat();
        let tris = vec![[0, 1, 2], [3, 4, 5]];
        let r = Animation::from_parts(6, tris.clone(), [frame.clone(), frame.clone()].concat(), 30.0).unwrap();
        // Move vertex 0 by 0.1 in frame 1 only: num = 0.01 over 6 part-vertex-frames.
        let mut c = r.positions().to_vec();
        c[18 + 2] = 0.1;
        let c = Animation::from_parts(6, tris, c, 30.0).unwrap();
        let (parts, e) = part_errors(&r, &c).unwrap();
        assert_eq!(parts.count(), 2);
        // (0.1 is stored as an f32: a relative tolerance.)
        let expected = 100.0 * (0.01f64 / 6.0).sqrt() / (12.0f64 / 9.0 / 3.0).sqrt();
        assert!((e[0].kg.unwrap() - expected).abs() < 1e-6 * expected, "{e:?} vs {expected}");
        assert!((e[0].max_error - 0.1).abs() < 1e-7 && e[1].kg == Some(0.0));
        assert!(kg_error(&r, &c).unwrap() < expected / 1000.0);
        assert_eq!(worst_part(&e).unwrap().part, 0);
    }

    /// A part below the floor is measured against the floor; isolated vertices are no part.
    #[test]
    fn tiny_parts_are_floored_and_points_are_no_part() {
        // A triangle of size 1e-3 at x = 1e5: floor 1e5 · 2⁻¹⁶ ≈ 1.53 ≫ its spread.
        let frame: Vec<f32> = [tri(1.0e5, 1.0e-3).as_slice(), &[7.0, 7.0, 7.0]].concat();
        let r = Animation::from_parts(4, vec![[0, 1, 2]], frame.clone(), 30.0).unwrap();
        let mut moved = frame.clone();
        moved[9] = 8.0;
        moved[1] = 0.0153;
        let c = Animation::from_parts(4, vec![[0, 1, 2]], moved, 30.0).unwrap();
        let (parts, e) = part_errors(&r, &c).unwrap();
        assert_eq!((parts.count(), parts.isolated()), (1, 1));
        assert!(e[0].floored);
        // The largest coordinate is 1e5 (1e5 + 1e-3 rounds to it in f32); one displaced vertex
        // of three, one frame.
        let floor = PART_SPREAD_FLOOR * 1.0e5;
        let expected = 100.0 * ((0.0153f32 as f64).powi(2) / 3.0).sqrt() / floor;
        assert!((e[0].kg.unwrap() - expected).abs() < 1e-6 * expected, "{e:?} vs {expected}");
    }

    /// Copies of a point split at a seam are one part while they move together; copies that
    /// part in any frame are not welded, and isolated copies join nothing.
    #[test]
    fn seams_are_welded_but_only_for_equal_trajectories() {
        // Two triangles sharing the edge (1,0)-(0,1) through copies 1≡3 and 2≡4; vertex 6 is an
        // isolated copy of vertex 0, vertex 5 the far corner of the second triangle.
        let f0: Vec<f32> = vec![0., 0., 0., 1., 0., 0., 0., 1., 0., 1., 0., 0., 0., 1., 0., 1., 1., 0., 0., 0., 0.];
        let mut f1 = f0.clone();
        f1[3] = -0.0 + 2.0; // vertex 1 moves, and its copy 3 with it
        f1[9] = 2.0;
        f1[0] = -0.0; // -0.0 welds with 0.0
        let tris = vec![[0, 1, 2], [3, 5, 4]];
        let r = Animation::from_parts(7, tris.clone(), [f0.clone(), f1.clone()].concat(), 30.0).unwrap();
        let p = visible_parts(&r);
        assert_eq!((p.count(), p.isolated()), (1, 1), "{p:?}");
        assert_eq!(connected_parts(7, &tris).count(), 2);
        // A third frame where both copies (3 and 4) leave their originals: two parts again.
        let mut f2 = f1.clone();
        f2[12] = 0.5;
        f2[9] = 2.5;
        let r = Animation::from_parts(7, tris, [f0, f1, f2].concat(), 30.0).unwrap();
        assert_eq!(visible_parts(&r).count(), 2);
    }

    #[test]
    fn result_is_the_same_for_every_block_split() {
        // 130 frames (three blocks of 3 frames … the split depends on the frame count only);
        // compare with the per-part KG computed on the part's own animation.
        let frames = 130;
        let mut pos = Vec::new();
        let mut cand = Vec::new();
        for t in 0..frames {
            let s = (t as f32 * 0.1).sin();
            let f: Vec<f32> = [tri(0.0, 1.0 + s), tri(100.0, 50.0)].concat();
            let mut g = f.clone();
            g[3] += 0.01 * s;
            pos.extend(f);
            cand.extend(g);
        }
        let tris = vec![[0, 1, 2], [3, 4, 5]];
        let r = Animation::from_parts(6, tris.clone(), pos.clone(), 30.0).unwrap();
        let c = Animation::from_parts(6, tris, cand.clone(), 30.0).unwrap();
        let (_, e) = part_errors(&r, &c).unwrap();
        let first = |p: &[f32]| p.chunks(18).flat_map(|f| f[..9].to_vec()).collect::<Vec<f32>>();
        let ra = Animation::from_parts(3, vec![[0, 1, 2]], first(&pos), 30.0).unwrap();
        let ca = Animation::from_parts(3, vec![[0, 1, 2]], first(&cand), 30.0).unwrap();
        let alone = kg_error(&ra, &ca).unwrap();
        assert!((e[0].kg.unwrap() - alone).abs() < 1e-9 * alone, "{} vs {alone}", e[0].kg.unwrap());
    }
}
