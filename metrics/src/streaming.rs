//! [`StreamingEvaluator`]: every metric of [`evaluate`](crate::evaluate) computed over frames as
//! they arrive, holding a window bounded by the vertex count instead of the whole animation.
//!
//! Each metric keeps what its formula sums over frames and runs the same per-frame code as the
//! whole-array functions, adding the per-frame terms in frame order:
//!
//! * **KG, MSE/RMSE, max error**: the per-frame sums of [`kg_error`](crate::kg_error) and
//!   [`displacement_stats`](crate::displacement_stats); the relative values divide by the
//!   reference's bounding-box diagonal over all frames, grown frame by frame, at
//!   [`StreamingEvaluator::finish`]. Bit-identical to [`evaluate`](crate::evaluate).
//! * **Hausdorff**: the per-frame distance of [`hausdorff()`](crate::hausdorff()) (its tree shaped
//!   on reference frame 0), the largest and the sum kept. Bit-identical.
//! * **STED**: the spatial part frame by frame; the temporal part through its speed window
//!   (`2k` reference edge-length arrays and `k + 1` candidate ones, `k` = `speed_window`), and
//!   the previous reference and candidate frames. Bit-identical.
//! * **Parts** ([`part_errors`](crate::part_errors)): which vertices are one point of the
//!   surface (seams) depends on every frame, so the classes of equal positions are refined
//!   frame by frame (`O(V)`) and the sums accumulate over the parts known after frame 0. When
//!   no later frame separates those parts (every mesh without coincident points, and seams that
//!   stay welded) the result is bit-identical. When a later frame does separate two parts
//!   (points that coincide for a while, then part), the separated parts are recombined at
//!   `finish` from per-component sums and the per-frame centroids of the components that frame 0
//!   joined (24 bytes per such component and frame, within [`history_limit`] bytes); such a
//!   part's spread then differs from the whole-array one by rounding only (1e-12 relative
//!   at most), and `finish` fails, saying so, when that history went over its limit.

use codec_core::animation::{check_finite, extend_bounding_box, whole_frames};
use codec_core::{Error, Result, Topology};
use rayon::prelude::*;

use crate::displacement::{displacement_frame, kg_frame, kg_from_sums, summarize_displacement};
use crate::hausdorff::{isolated_vertex_count, summarize_hausdorff, FrameSurface};
use crate::parts::{
    accumulate_part_frame, connected_parts, joined_parts, merge_part_sums, part_block_frames, part_error, worst_part,
    PartAcc, PartError, Parts, WeldClasses, NO_PART,
};
use crate::report::{assemble, EvalOptions, MetricReport, ReportCounts};
use crate::sted::{diameter, local_deviations, mesh_neighbourhoods, summarize_sted, Neighbourhoods, TemporalWindow};

const CTX: &str = "streaming metrics";

/// Bytes of per-frame component centroids kept to recombine parts that separate after frame 0
/// (module docs): 16 MiB plus two raw frames' worth (24 bytes per vertex).
pub fn history_limit(vertex_count: usize) -> u64 {
    (16u64 << 20) + 24 * vertex_count as u64
}

/// Every metric of [`evaluate`](crate::evaluate), computed over frames as they arrive (bounded
/// window; see the module docs for what is held and which results are bit-identical).
pub struct StreamingEvaluator {
    topology: Topology,
    frame_count: usize,
    options: EvalOptions,
    pushed: usize,
    kg_num: f64,
    kg_den: f64,
    disp_sum: f64,
    disp_max2: f64,
    disp_at: (usize, usize),
    lo: [f32; 3],
    hi: [f32; 3],
    /// Built on reference frame 0 when Hausdorff is requested.
    surface: Option<FrameSurface>,
    hausdorff_max: f64,
    hausdorff_sum: f64,
    /// Edges and neighbourhoods, or why STED is undefined (`None` when not requested).
    sted: Option<std::result::Result<StedMesh, String>>,
    sted_sum: f64,
    sted_empty: usize,
    diameter: f64,
    temporal: Option<TemporalWindow>,
    /// The last reference and candidate frame, for the next temporal edge.
    previous: Option<(Vec<f32>, Vec<f32>)>,
    parts: PartState,
}

/// STED's mesh edges and every vertex's neighbourhood.
type StedMesh = (Vec<[u32; 2]>, Neighbourhoods);

/// The per-part sums (module docs).
struct PartState {
    /// Whether each vertex is in a triangle.
    used: Vec<bool>,
    /// Components of the triangle graph alone.
    components: Parts,
    welds: WeldClasses,
    /// The parts after frame 0, whose sums accumulate.
    initial: Option<Parts>,
    per_block: usize,
    block: Vec<PartAcc>,
    total: Vec<PartAcc>,
    centre: Vec<[f64; 3]>,
    /// Per-component sums when frame 0 joined components (else `None`).
    tracking: Option<Tracking>,
    /// A later frame separated parts joined after frame 0.
    separated: bool,
}

struct Tracking {
    acc: Vec<PartAcc>,
    centre: Vec<[f64; 3]>,
    /// Components in a part of two or more components after frame 0.
    tracked: Vec<u32>,
    /// Position of every component in `tracked` (`u32::MAX` if not tracked).
    slot: Vec<u32>,
    /// Frame-major centroids of the tracked components; `None` once over [`history_limit`].
    history: Option<Vec<[f64; 3]>>,
}

/// What one frame contributes, computed in parallel over the frames of a push.
struct FrameTerms {
    kg: (f64, f64),
    displacement: (f64, f64, usize),
    hausdorff: f64,
    sted: (f64, usize),
}

impl StreamingEvaluator {
    /// `topology`: the connectivity both sides share; `frame_count`, `frame_rate` of the
    /// reference; the same options [`evaluate`](crate::evaluate) takes. Fails as `evaluate`
    /// would on invalid options, and on no frames or a frame rate that is not finite and positive.
    pub fn new(topology: &Topology, frame_count: usize, frame_rate: f32, options: &EvalOptions) -> Result<Self> {
        options.sted.validate()?;
        if frame_count == 0 {
            return Err(Error::InvalidAnimation(format!("{CTX}: the reference has no frames")));
        }
        if !(frame_rate.is_finite() && frame_rate > 0.0) {
            return Err(Error::InvalidAnimation(format!(
                "{CTX}: frame rate {frame_rate} is not a finite positive number"
            )));
        }
        let n = topology.vertex_count();
        let sted = options
            .compute_sted
            .then(|| mesh_neighbourhoods(topology.triangles(), n, &options.sted).map_err(|e| e.to_string()));
        let mut used = vec![false; n];
        for t in topology.triangles() {
            for &i in t {
                used[i as usize] = true;
            }
        }
        Ok(Self {
            topology: topology.clone(),
            frame_count,
            options: *options,
            pushed: 0,
            kg_num: 0.0,
            kg_den: 0.0,
            disp_sum: 0.0,
            disp_max2: -1.0,
            disp_at: (0, 0),
            lo: [f32::INFINITY; 3],
            hi: [f32::NEG_INFINITY; 3],
            surface: None,
            hausdorff_max: 0.0,
            hausdorff_sum: 0.0,
            sted,
            sted_sum: 0.0,
            sted_empty: 0,
            diameter: 0.0,
            temporal: None,
            previous: None,
            parts: PartState {
                used,
                components: connected_parts(n, topology.triangles()),
                welds: WeldClasses::default(),
                initial: None,
                per_block: part_block_frames(frame_count),
                block: Vec::new(),
                total: Vec::new(),
                centre: Vec::new(),
                tracking: None,
                separated: false,
            },
        })
    }

    /// Frames pushed so far.
    pub fn frames_pushed(&self) -> usize {
        self.pushed
    }

    /// The next frames of the reference and of the candidate (frame-major `n × vertices × 3`
    /// each, equal lengths, whole frames). Fails on mismatched lengths, partial frames, more
    /// frames than announced, or a non-finite coordinate (named by frame, vertex and axis).
    pub fn push(&mut self, reference: &[f32], candidate: &[f32]) -> Result<()> {
        let n = self.topology.vertex_count();
        if reference.len() != candidate.len() {
            return Err(Error::InvalidAnimation(format!(
                "{CTX}: {} reference coordinates but {} candidate coordinates pushed",
                reference.len(),
                candidate.len()
            )));
        }
        let m = whole_frames(reference.len(), n)?;
        if m == 0 {
            return Ok(());
        }
        if self.pushed + m > self.frame_count {
            return Err(Error::InvalidAnimation(format!(
                "{CTX}: {} frames pushed, more than the reference's {}",
                self.pushed + m,
                self.frame_count
            )));
        }
        check_finite(reference, n, self.pushed).map_err(|e| Error::InvalidAnimation(format!("reference: {e}")))?;
        check_finite(candidate, n, self.pushed).map_err(|e| Error::InvalidAnimation(format!("candidate: {e}")))?;
        let stride = 3 * n;
        if self.pushed == 0 {
            self.start(&reference[..stride]);
        }
        let first = self.pushed;
        let params = self.options.sted;
        let (surface, sted) = (&self.surface, &self.sted);
        let parallel = || -> Vec<FrameTerms> {
            reference
                .par_chunks(stride)
                .zip(candidate.par_chunks(stride))
                .map(|(a, b)| FrameTerms {
                    kg: kg_frame(a, b),
                    displacement: displacement_frame(a, b),
                    hausdorff: surface.as_ref().map_or(0.0, |s| s.distance(a, b)),
                    sted: match sted {
                        Some(Ok((edges, hood))) => {
                            let (sigma, empty) = local_deviations(a, b, edges, hood, &params);
                            (sigma.iter().sum::<f64>(), empty)
                        }
                        _ => (0.0, 0),
                    },
                })
                .collect()
        };
        let (parts, topology, frame_count) = (&mut self.parts, &self.topology, self.frame_count);
        let (temporal, previous, lo, hi) = (&mut self.temporal, &mut self.previous, &mut self.lo, &mut self.hi);
        let sequential = || {
            for (i, (a, b)) in reference.chunks_exact(stride).zip(candidate.chunks_exact(stride)).enumerate() {
                extend_bounding_box(lo, hi, a);
                parts.push_frame(topology, first + i, frame_count, a, b);
                if let Some(t) = temporal.as_mut() {
                    if let Some((pa, pb)) = previous.as_mut() {
                        t.push_edge(t.edge_lengths(a, pa), t.edge_lengths(b, pb));
                        pa.copy_from_slice(a);
                        pb.copy_from_slice(b);
                    } else {
                        *previous = Some((a.to_vec(), b.to_vec()));
                    }
                }
            }
        };
        let (terms, ()) = rayon::join(parallel, sequential);
        for (i, f) in terms.iter().enumerate() {
            self.kg_num += f.kg.0;
            self.kg_den += f.kg.1;
            let (s, m2, v) = f.displacement;
            self.disp_sum += s;
            if m2 > self.disp_max2 {
                self.disp_max2 = m2;
                self.disp_at = (first + i, v);
            }
            self.hausdorff_max = self.hausdorff_max.max(f.hausdorff);
            self.hausdorff_sum += f.hausdorff;
            self.sted_sum += f.sted.0;
            self.sted_empty += f.sted.1;
        }
        self.pushed += m;
        Ok(())
    }

    /// What depends on reference frame 0: the Hausdorff tree's shape and STED's unit `D`.
    fn start(&mut self, frame0: &[f32]) {
        if self.options.compute_hausdorff {
            self.surface = Some(FrameSurface::new(self.topology.triangles(), frame0));
        }
        if let Some(Ok(_)) = &self.sted {
            self.diameter = diameter(frame0);
            let n = self.topology.vertex_count();
            self.temporal = TemporalWindow::new(n, self.frame_count, self.diameter, &self.options.sted);
        }
    }

    /// The report [`evaluate`](crate::evaluate) gives for the same pair (every field, notes
    /// included). Fails when fewer frames than announced were pushed, or when parts separated
    /// after the history limit (module docs).
    pub fn finish(self) -> Result<MetricReport> {
        if self.pushed != self.frame_count {
            return Err(Error::InvalidAnimation(format!(
                "{CTX}: {} of the reference's {} frames were pushed",
                self.pushed, self.frame_count
            )));
        }
        let n = self.topology.vertex_count();
        let frames = self.frame_count;
        let mut notes = Vec::new();
        let diag = (0..3).map(|a| (self.hi[a] as f64 - self.lo[a] as f64).powi(2)).sum::<f64>().sqrt();
        let disp = summarize_displacement(self.disp_sum, self.disp_max2, self.disp_at, n * frames, diag, Vec::new());
        if disp.mse_relative.is_none() {
            notes.push("relative values undefined: the reference bounding box has zero diagonal".to_string());
        }
        let kg = kg_from_sums(self.kg_num, self.kg_den).map_err(|e| notes.push(e.to_string())).ok();
        let (parts, errors) = self.parts.finish(&self.topology, frames)?;
        let mut worst = worst_part(&errors).cloned();
        // As in `evaluate`: one part holding every vertex is the whole animation.
        if let Some(w) = worst.as_mut().filter(|_| parts.count() == 1 && parts.isolated() == 0 && kg.is_some()) {
            w.kg = kg;
        }
        let st = match self.sted {
            Some(Ok((edges, _))) => Some(summarize_sted(
                self.sted_sum,
                self.sted_empty,
                n,
                frames,
                self.temporal.as_ref().map(|t| t.total()),
                self.diameter,
                &self.options.sted,
                edges.len(),
                Vec::new(),
            )),
            Some(Err(e)) => {
                notes.push(e);
                None
            }
            None => {
                notes.push("sted not requested".to_string());
                None
            }
        };
        let h = self.surface.as_ref().map(|s| {
            let mean = self.hausdorff_sum / frames as f64;
            summarize_hausdorff(self.hausdorff_max, mean, diag, s.mode, Vec::new())
        });
        let counts = ReportCounts {
            parts: parts.count(),
            vertices: n,
            frames,
            isolated: isolated_vertex_count(self.topology.triangles(), n),
        };
        Ok(assemble(kg, st, h, disp, worst, counts, &self.options, notes))
    }

    /// Bytes this evaluator holds for `topology` × `options` (its window), for memory budgets:
    /// a stated upper bound, counting the transient per-frame buffers of every worker thread.
    /// Independent of the frame count; the frames a caller pushes are the caller's.
    pub fn bytes_held(topology: &Topology, options: &EvalOptions) -> u64 {
        let n = topology.vertex_count() as u64;
        let t = topology.triangle_count() as u64;
        let threads = rayon::current_num_threads().max(1) as u64;
        // Parts: used flags, three labelings (components, after frame 0, and the one a later
        // frame's check builds) of at most 20 bytes per vertex, the weld classes and their
        // frame-0 sort (16 bytes per vertex), per-part sums for blocks, totals, components and
        // centroids (at most one part per vertex), and the component centroid history.
        let parts = n + 3 * 20 * n + 16 * n + 24 * n + 4 * 32 * n + 2 * 24 * n + history_limit(n as usize);
        let mut total = parts + 12 * t;
        if options.compute_hausdorff {
            let (held, transient) = FrameSurface::bytes(n as usize, t as usize);
            total += held + threads * transient;
        }
        if options.compute_sted {
            let edges = 3 * t;
            // Neighbourhood lists: 8 bytes per vertex of offsets, 4 per entry; an entry per edge
            // end within the ring (see `neighbourhood_entries`).
            let entries = neighbourhood_entries(topology, options.sted.ring_radius);
            total += 8 * edges + 8 * (n + 1) + 4 * entries;
            // Per frame and thread: (length, difference) per edge and a deviation per vertex.
            total += threads * (16 * edges + 8 * n);
            // The temporal window and the previous frames.
            total += TemporalWindow::bytes(n as usize, options.sted.speed_window) + 2 * 12 * n;
        }
        total
    }
}

/// An upper bound of the neighbourhood entries of every vertex: the edges touching `R(v)`, at
/// most the sum of the degrees over `R(v)`; for one ring `Σ_u deg(u)·(deg(u) + 1)`, for more
/// rings `V · Δ · (1 + Δ + … + Δ^r)` with `Δ` the largest degree, capped at the most the
/// neighbourhoods may hold.
fn neighbourhood_entries(topology: &Topology, radius: u32) -> u64 {
    let n = topology.vertex_count();
    let mut degree = vec![0u64; n];
    for e in crate::common::unique_edges(topology.triangles()) {
        degree[e[0] as usize] += 1;
        degree[e[1] as usize] += 1;
    }
    let cap = crate::sted::MAX_HOOD_ENTRIES as u64;
    if radius <= 1 {
        return degree.iter().map(|d| d * (d + 1)).sum::<u64>().min(cap);
    }
    let max = degree.iter().copied().max().unwrap_or(0);
    let mut ring = 1u64;
    let mut reach = 1u64;
    for _ in 0..radius {
        ring = ring.saturating_mul(max);
        reach = reach.saturating_add(ring);
    }
    (n as u64).saturating_mul(max).saturating_mul(reach).min(cap)
}

impl PartState {
    fn push_frame(&mut self, topology: &Topology, t: usize, frames: usize, a: &[f32], b: &[f32]) {
        let split = self.welds.push_frame(a, &self.used);
        let n = topology.vertex_count();
        if t == 0 {
            let initial = joined_parts(n, topology.triangles().iter().chain(&self.welds.seams()));
            let count = initial.count();
            self.block = vec![PartAcc::default(); count];
            self.total = vec![PartAcc::default(); count];
            self.centre = vec![[0.0; 3]; count];
            if count < self.components.count() {
                // Components joined by frame 0's seams: the ones sharing a part are tracked.
                let mut per_part = vec![0u32; count];
                for &v in &self.components.first_vertex {
                    per_part[initial.label[v] as usize] += 1;
                }
                let tracked: Vec<u32> = (0..self.components.count() as u32)
                    .filter(|&c| per_part[initial.label[self.components.first_vertex[c as usize]] as usize] > 1)
                    .collect();
                let mut slot = vec![u32::MAX; self.components.count()];
                for (i, &c) in tracked.iter().enumerate() {
                    slot[c as usize] = i as u32;
                }
                let bytes = (tracked.len() as u64).saturating_mul(frames as u64).saturating_mul(24);
                let history = (bytes <= history_limit(n)).then(|| Vec::with_capacity(tracked.len() * frames));
                self.tracking = Some(Tracking {
                    acc: vec![PartAcc::default(); self.components.count()],
                    centre: vec![[0.0; 3]; self.components.count()],
                    tracked,
                    slot,
                    history,
                });
            }
            self.initial = Some(initial);
        } else if split && !self.separated {
            if let Some(initial) = &self.initial {
                let now = joined_parts(n, topology.triangles().iter().chain(&self.welds.seams()));
                self.separated = now.label != initial.label;
            }
        }
        let Some(initial) = &self.initial else { return };
        if initial.count() == 0 {
            return;
        }
        accumulate_part_frame(a, b, &initial.label, &initial.sizes, &mut self.centre, &mut self.block);
        if (t + 1).is_multiple_of(self.per_block) || t + 1 == frames {
            merge_part_sums(&mut self.total, &self.block);
            self.block.fill(PartAcc::default());
        }
        if let Some(tr) = self.tracking.as_mut() {
            let c = &self.components;
            accumulate_part_frame(a, b, &c.label, &c.sizes, &mut tr.centre, &mut tr.acc);
            if let Some(h) = tr.history.as_mut() {
                h.extend(tr.tracked.iter().map(|&k| tr.centre[k as usize]));
            }
        }
    }

    /// The final parts and every part's error.
    fn finish(self, topology: &Topology, frames: usize) -> Result<(Parts, Vec<PartError>)> {
        let n = topology.vertex_count();
        let Some(initial) = self.initial else {
            return Err(Error::InvalidAnimation(format!("{CTX}: no frame was pushed")));
        };
        if !self.separated {
            let errors = (0..initial.count())
                .map(|i| part_error(i, initial.first_vertex[i], initial.sizes[i], frames, &self.total[i]))
                .collect();
            return Ok((initial, errors));
        }
        let last = joined_parts(n, topology.triangles().iter().chain(&self.welds.seams()));
        let tracking = self.tracking.as_ref();
        let comps = &self.components;
        // Components of every final part, in component order.
        let mut members: Vec<Vec<usize>> = vec![Vec::new(); last.count()];
        for (c, &v) in comps.first_vertex.iter().enumerate() {
            members[last.label[v] as usize].push(c);
        }
        let mut errors = Vec::with_capacity(last.count());
        for (i, member) in members.iter().enumerate() {
            let first = last.first_vertex[i];
            let was = initial.label[first] as usize;
            if initial.sizes[was] == last.sizes[i] {
                errors.push(part_error(i, first, last.sizes[i], frames, &self.total[was]));
                continue;
            }
            // A part separated from others after frame 0: its sums from its components'.
            let (Some(tr), Some(history)) = (tracking, tracking.and_then(|t| t.history.as_ref())) else {
                return Err(Error::InvalidAnimation(format!(
                    "{CTX}: the part of vertex {first} separated from the points it shared in frame 0, and the \
                     per-frame centroids needed to measure it alone were over the {} bytes this evaluator keeps; \
                     measure this pair in memory",
                    history_limit(n)
                )));
            };
            let mut acc = PartAcc::default();
            for &c in member {
                let a = &tr.acc[c];
                acc.num += a.num;
                acc.den += a.den;
                acc.max2 = acc.max2.max(a.max2);
                acc.magnitude = acc.magnitude.max(a.magnitude);
            }
            if member.iter().any(|&m| tr.slot[m] == u32::MAX) {
                return Err(Error::InvalidAnimation(format!(
                    "{CTX}: the part of vertex {first} separated after frame 0 but its components were not tracked"
                )));
            }
            let k = tr.tracked.len();
            let size = last.sizes[i] as f64;
            for f in 0..frames {
                let row = &history[f * k..(f + 1) * k];
                let mut c = [0.0f64; 3];
                for &m in member {
                    let (w, p) = (comps.sizes[m] as f64, row[tr.slot[m] as usize]);
                    for d in 0..3 {
                        c[d] += w * p[d];
                    }
                }
                let c = c.map(|x| x / size);
                for &m in member {
                    let (w, p) = (comps.sizes[m] as f64, row[tr.slot[m] as usize]);
                    acc.den += w * ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2));
                }
            }
            errors.push(part_error(i, first, last.sizes[i], frames, &acc));
        }
        debug_assert!(last.label.iter().all(|&l| l == NO_PART || (l as usize) < errors.len()));
        Ok((last, errors))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::evaluate;
    use codec_core::Animation;

    /// A pseudo-random generator for reproducible inputs.
    fn lcg(seed: &mut u64) -> f32 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((*seed >> 40) as f32 / (1u64 << 24) as f32) - 0.5
    }

    /// A `cols × rows` grid waving over `frames` frames, and a candidate with noise.
    fn grid_pair(cols: usize, rows: usize, frames: usize, noise: f32) -> (Animation, Animation) {
        let topo = Topology::grid(cols, rows).unwrap();
        let mut seed = 7u64;
        let (mut r, mut c) = (Vec::new(), Vec::new());
        for t in 0..frames {
            for y in 0..rows {
                for x in 0..cols {
                    let z = ((x as f32 * 0.5 + t as f32 * 0.3).sin() + (y as f32 * 0.2).cos()) * 0.3;
                    let p = [x as f32 * 0.1, y as f32 * 0.1, z];
                    r.extend(p);
                    c.extend(p.map(|q| q + noise * lcg(&mut seed)));
                }
            }
        }
        (Animation::new(topo.clone(), r, 30.0).unwrap(), Animation::new(topo, c, 30.0).unwrap())
    }

    fn stream(r: &Animation, c: &Animation, options: &EvalOptions, chunk: usize) -> Result<MetricReport> {
        let mut s = StreamingEvaluator::new(r.topology(), r.frame_count(), r.frame_rate(), options)?;
        let per = 3 * r.vertex_count() * chunk;
        for (a, b) in r.positions().chunks(per).zip(c.positions().chunks(per)) {
            s.push(a, b)?;
        }
        s.finish()
    }

    #[test]
    fn equals_evaluate_bit_for_bit_in_every_chunking() {
        for (frames, window) in [(1, 5), (2, 5), (13, 5), (40, 3), (9, 1)] {
            let (r, c) = grid_pair(9, 7, frames, 0.01);
            let options = EvalOptions {
                sted: crate::StedParams { speed_window: window, ..Default::default() },
                ..Default::default()
            };
            let whole = evaluate(&r, &c, &options).unwrap();
            assert!(whole.kg.unwrap() > 0.0 && whole.hausdorff.unwrap() > 0.0);
            for chunk in [1, 7, frames] {
                assert_eq!(stream(&r, &c, &options, chunk).unwrap(), whole, "{frames} frames in chunks of {chunk}");
            }
            for options in
                [EvalOptions { compute_sted: false, ..options }, EvalOptions { compute_hausdorff: false, ..options }]
            {
                assert_eq!(stream(&r, &c, &options, 3).unwrap(), evaluate(&r, &c, &options).unwrap());
            }
        }
    }

    #[test]
    fn point_clouds_collapsed_frames_and_isolated_vertices_match() {
        // A point cloud: no parts, no STED, point-to-point Hausdorff.
        let (r, c) = grid_pair(4, 3, 5, 0.05);
        let cloud = |a: &Animation| Animation::from_parts(12, vec![], a.positions().to_vec(), 30.0).unwrap();
        let (r2, c2) = (cloud(&r), cloud(&c));
        let whole = evaluate(&r2, &c2, &EvalOptions::default()).unwrap();
        assert!(whole.notes.len() >= 2, "{:?}", whole.notes);
        assert_eq!(stream(&r2, &c2, &EvalOptions::default(), 2).unwrap(), whole);
        // Every frame a single point: KG and relative values undefined, temporal part undefined.
        let p = Animation::from_parts(3, vec![[0, 1, 2]], vec![1.0; 9 * 4], 30.0).unwrap();
        let whole = evaluate(&p, &p, &EvalOptions::default()).unwrap();
        assert!(whole.kg.is_none());
        assert_eq!(stream(&p, &p, &EvalOptions::default(), 3).unwrap(), whole);
        // Isolated vertices beside a mesh.
        let tris = vec![[0, 1, 2], [2, 1, 3]];
        let r3 = Animation::from_parts(12, tris.clone(), r.positions().to_vec(), 30.0).unwrap();
        let c3 = Animation::from_parts(12, tris, c.positions().to_vec(), 30.0).unwrap();
        let whole = evaluate(&r3, &c3, &EvalOptions::default()).unwrap();
        assert!(whole.notes.iter().any(|n| n.contains("no triangle")), "{:?}", whole.notes);
        assert_eq!(stream(&r3, &c3, &EvalOptions::default(), 1).unwrap(), whole);
    }

    /// Two triangles split at a seam (copies of two points): welded in every frame, one part,
    /// bit-identical. Then copies that coincide in the first frames and part later: two parts,
    /// recombined from component sums, equal within 1e-12 relative.
    #[test]
    fn seams_welded_for_good_or_parting_later() {
        let tris = vec![[0, 1, 2], [3, 4, 5], [6, 7, 8]];
        let frames = 11;
        let mut seed = 3u64;
        let (mut r, mut c) = (Vec::new(), Vec::new());
        for t in 0..frames {
            let s = t as f32 * 0.1;
            // Triangle A; triangle B shares A's vertices 1 and 2 through copies 3 and 4 in every
            // frame; triangle C touches A's vertex 0 with its vertex 6 until frame 6, then moves away.
            let a = [[0.0, 0.0, s], [1.0, 0.0, 0.0], [0.0, 1.0, 0.5 * s]];
            let b = [a[1], a[2], [1.0 + s, 1.0, 0.2]];
            let away = if t >= 6 { 0.3 * (t - 5) as f32 } else { 0.0 };
            let cc = [[a[0][0] - away, a[0][1], a[0][2]], [-1.0, -0.5, s], [-0.5, -1.0, 0.1]];
            for p in a.iter().chain(&b).chain(&cc) {
                r.extend(p);
                c.extend(p.map(|q| q + 0.01 * lcg(&mut seed)));
            }
        }
        let ra = Animation::from_parts(9, tris.clone(), r, 30.0).unwrap();
        let ca = Animation::from_parts(9, tris, c, 30.0).unwrap();
        let whole = evaluate(&ra, &ca, &EvalOptions::default()).unwrap();
        assert_eq!(whole.parts, 2, "A+B welded, C parted");
        for chunk in [1, 4, frames] {
            let s = stream(&ra, &ca, &EvalOptions::default(), chunk).unwrap();
            let (w, x) = (whole.worst_part.as_ref().unwrap(), s.worst_part.as_ref().unwrap());
            assert_eq!(
                (w.part, w.vertices, w.first_vertex, w.floored),
                (x.part, x.vertices, x.first_vertex, x.floored)
            );
            for (a, b) in [(w.kg.unwrap(), x.kg.unwrap()), (w.spread, x.spread), (w.rmse, x.rmse)] {
                assert!((a - b).abs() <= 1e-12 * a.abs(), "{a} vs {b}");
            }
            assert_eq!(w.max_error, x.max_error);
            let strip = |m: &MetricReport| MetricReport { worst_part: None, ..m.clone() };
            assert_eq!(strip(&s), strip(&whole));
        }
        // Without the parting, the seams hold: one part, bit-identical.
        let r1 = Animation::from_parts(6, vec![[0, 1, 2], [3, 4, 5]], frames_of(&ra, 6), 30.0).unwrap();
        let c1 = Animation::from_parts(6, vec![[0, 1, 2], [3, 4, 5]], frames_of(&ca, 6), 30.0).unwrap();
        let whole = evaluate(&r1, &c1, &EvalOptions::default()).unwrap();
        assert_eq!(whole.parts, 1);
        assert_eq!(stream(&r1, &c1, &EvalOptions::default(), 2).unwrap(), whole);
    }

    /// The first `keep` vertices of every frame.
    fn frames_of(a: &Animation, keep: usize) -> Vec<f32> {
        a.frames().flat_map(|f| f[..3 * keep].to_vec()).collect()
    }

    #[test]
    fn bad_pushes_are_errors() {
        let (r, c) = grid_pair(3, 3, 4, 0.01);
        let o = EvalOptions::default();
        let new = || StreamingEvaluator::new(r.topology(), 4, 30.0, &o).unwrap();
        let mut s = new();
        assert!(s.push(r.frame(0), &c.frame(0)[..9]).unwrap_err().to_string().contains("candidate coordinates"));
        assert!(s.push(&r.frame(0)[..5], &c.frame(0)[..5]).is_err());
        let mut bad = c.frame(1).to_vec();
        bad[4] = f32::NAN;
        let e = s.push(r.frame(1), &bad).unwrap_err().to_string();
        assert!(e.contains("candidate") && e.contains("vertex 1"), "{e}");
        let mut s = new();
        s.push(r.positions(), c.positions()).unwrap();
        assert!(s.push(r.frame(0), c.frame(0)).unwrap_err().to_string().contains("more than"));
        let mut s = new();
        s.push(r.frame(0), c.frame(0)).unwrap();
        assert!(s.finish().unwrap_err().to_string().contains("1 of the reference's 4"));
        let bad_sted = EvalOptions { sted: crate::StedParams { speed_window: 0, ..Default::default() }, ..o };
        assert!(StreamingEvaluator::new(r.topology(), 4, 30.0, &bad_sted).is_err());
        assert!(StreamingEvaluator::new(r.topology(), 0, 30.0, &o).is_err());
        assert!(StreamingEvaluator::new(r.topology(), 4, f32::NAN, &o).is_err());
    }

    #[test]
    fn bytes_held_grows_with_vertices_not_frames() {
        let o = EvalOptions::default();
        let small = StreamingEvaluator::bytes_held(&Topology::grid(10, 10).unwrap(), &o);
        let big = StreamingEvaluator::bytes_held(&Topology::grid(100, 100).unwrap(), &o);
        assert!(big > small && big < 100 * small, "{small} {big}");
        let lean = EvalOptions { compute_sted: false, compute_hausdorff: false, ..o };
        assert!(StreamingEvaluator::bytes_held(&Topology::grid(100, 100).unwrap(), &lean) < big);
    }
}
