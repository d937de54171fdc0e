//! Traversal coding of the triangle list: topology method 2 (container version 3).
//!
//! Method 1 ([`crate::connectivity`]) codes the canonical order triangle by triangle, naming
//! the first corner of each by its index delta: 5.5–6.9 bits per triangle on the dev meshes.
//! This method walks the mesh instead, as Edgebreaker and the cut-border machine do
//! (Rossignac 1999; Gumhold & Straßer 1998): the triangle across an open edge of the region
//! coded so far shares two known corners, so only its third corner is coded — and a third
//! corner that is already in the region is almost always the next vertex along the region's
//! border. What is left is the vertex numbering, which a stream must keep (positions are
//! indexed by it). Modellers number vertices locally (on horse-gallop every vertex but 3 %
//! has a mesh neighbour whose index differs by one), so a vertex entering the region is coded
//! as a rank among a short list of unvisited indices next to the indices around the gate,
//! with an escape to its index delta. Measured (`cargo run --release -p codec-core --example
//! topology_bench`): see `codec-core/FORMAT.md`.
//!
//! The walk, identical in encoder and decoder:
//!
//! * The region's *open half-edges* are the directed edges `x → y` of coded triangles whose
//!   reverse `y → x` is in no coded triangle (each vertex remembers at most [`MAX_OPEN`] in
//!   each direction; an edge that does not fit is not opened). A new open half-edge is pushed
//!   on a stack of *gates*.
//! * While triangles remain: pop a gate `u → v`; skip it if no longer open. Else code an op:
//!   `0` — no uncoded triangle holds `v → u` (a border, or the other side came first): the
//!   gate is closed; `1` — the triangle `(v, u, w)` brings a vertex `w` seen for the first
//!   time, coded as 1 + its rank among the new-vertex candidates or 0 and its index delta
//!   from the last vertex seen; `2` — `w` was seen but is not a candidate: `w − u` follows;
//!   `3 + k` — `w` is the `k`-th of the seen candidates (vertices with an open half-edge
//!   into `u` or out of `v`: the corners that would close the region's border on either
//!   side). The triangle `(v, u, w)` then closes every open half-edge it reverses and opens
//!   the others.
//! * When the stack is empty and triangles remain, the first uncoded triangle of the
//!   (canonical) list starts a new component: its three corners as index deltas (the first
//!   from the last vertex seen, the others from the corner before).
//!
//! Degenerate triangles (a repeated corner) are never across a gate, so they are coded as
//! component starts. The decoder returns [`canonical_order`] of what it rebuilt: the same
//! oriented triangles, in the order the stream encoder gave them. The container writer uses
//! this method only when a round trip gives back exactly its input (any other order keeps
//! method 1, which keeps any order).

use crate::animation::Topology;
use crate::connectivity::{
    bad_triangle as bad, canonical_order, check_density, index_at, max_triangles, Neighbours, CTX, FIELD,
};
use crate::error::{Error, Result};
use crate::toolkit::adaptive::{AdaptiveDecoder, AdaptiveEncoder, CostModel, MAX_MAGNITUDE};
use numbering::{Predictor, KINDS};

mod numbering;

/// Model classes of the arithmetic coder.
#[derive(Clone, Copy)]
enum Class {
    /// The op of a gate (context: the previous op's kind × whether seen candidates exist).
    Op = 0,
    /// 1 + rank of a new vertex among the new-vertex candidates, 0 = escape (context: the
    /// candidate count, capped at 7).
    NewRank = 1,
    /// A new vertex's index minus the last vertex seen, after an escape.
    NewDelta = 2,
    /// `w − u` of a seen vertex that is not a candidate.
    SeenDelta = 3,
    /// A component start's corners (context: the corner).
    Start = 4,
}
const CLASSES: usize = 5;

const OP_BORDER: i32 = 0;
const OP_NEW: i32 = 1;
const OP_SEEN: i32 = 2;
const OP_CANDIDATE: i32 = 3;

/// Kinds of the previous op, the op's context.
const AFTER_BORDER: usize = 0;
const AFTER_NEW: usize = 1;
const AFTER_SEEN: usize = 2;
const AFTER_CANDIDATE: usize = 3;

/// Most open half-edges remembered per vertex and direction. A manifold region's border
/// passes a vertex a few times at most; the cap bounds every op's work (a hostile stream
/// costs the decoder linear time). Encoder and decoder apply the same rule.
pub const MAX_OPEN: usize = 32;

/// Most new-vertex candidates listed per gate.
const MAX_NEW_CANDIDATES: usize = 48;

/// The walk's state, advanced identically by [`encode`] and [`decode`].
pub(crate) struct Walk {
    pub(crate) vertex_count: u64,
    /// Seen vertices, grown up to the largest index met.
    pub(crate) seen: Vec<bool>,
    /// Per vertex `x`: the `y` of its open half-edges `x → y`, ascending.
    pub(crate) open_out: Vec<Vec<u32>>,
    /// Per vertex `y`: the `x` of its open half-edges `x → y`, ascending.
    pub(crate) open_in: Vec<Vec<u32>>,
    pub(crate) gates: Vec<(u32, u32)>,
    /// Mesh neighbours in coded triangles (new-vertex candidates come from their indices).
    pub(crate) known: Neighbours,
    pub(crate) last_seen: u32,
    after: usize,
}

impl Walk {
    pub(crate) fn new(vertex_count: usize) -> Self {
        Self {
            vertex_count: vertex_count as u64,
            seen: Vec::new(),
            open_out: Vec::new(),
            open_in: Vec::new(),
            gates: Vec::new(),
            known: Neighbours::new(),
            last_seen: 0,
            after: AFTER_NEW,
        }
    }

    pub(crate) fn is_seen(&self, x: u32) -> bool {
        self.seen.get(x as usize).copied().unwrap_or(false)
    }

    pub(crate) fn see(&mut self, x: u32) {
        if x as usize >= self.seen.len() {
            self.seen.resize(x as usize + 1, false);
        }
        self.seen[x as usize] = true;
        self.last_seen = x;
    }

    pub(crate) fn is_open(&self, x: u32, y: u32) -> bool {
        self.open_out.get(x as usize).is_some_and(|l| l.binary_search(&y).is_ok())
    }

    pub(crate) fn open(&mut self, x: u32, y: u32) {
        let top = x.max(y) as usize + 1;
        if top > self.open_out.len() {
            self.open_out.resize(top, Vec::new());
            self.open_in.resize(top, Vec::new());
        }
        let (out, inn) = (&self.open_out[x as usize], &self.open_in[y as usize]);
        if out.len() >= MAX_OPEN || inn.len() >= MAX_OPEN {
            return;
        }
        if let Err(i) = out.binary_search(&y) {
            self.open_out[x as usize].insert(i, y);
            let j = self.open_in[y as usize].binary_search(&x).unwrap_or_else(|j| j);
            self.open_in[y as usize].insert(j, x);
            self.gates.push((x, y));
        }
    }

    pub(crate) fn close(&mut self, x: u32, y: u32) {
        if let Some(out) = self.open_out.get_mut(x as usize) {
            if let Ok(i) = out.binary_search(&y) {
                out.remove(i);
                let inn = &mut self.open_in[y as usize];
                if let Ok(j) = inn.binary_search(&x) {
                    inn.remove(j);
                }
            }
        }
    }

    /// Adds the coded triangle `t` (oriented): each half-edge closes its open reverse or
    /// opens, last to first — so after a gate's triangle `(v, u, w)` the walk goes on from
    /// `u → w` (1.5 % smaller than first to first on the dev meshes).
    pub(crate) fn add(&mut self, t: [u32; 3]) {
        for (x, y) in [(t[2], t[0]), (t[1], t[2]), (t[0], t[1])] {
            if x == y {
                continue;
            }
            if self.is_open(y, x) {
                self.close(y, x);
            } else {
                self.open(x, y);
            }
        }
        self.known.add(t);
    }

    /// Seen vertices that would close the border next to the gate `u → v`: those with an
    /// open half-edge into `u` and one out of `v` first, then into `u` only, then out of `v`
    /// only; each tier ascending.
    pub(crate) fn seen_candidates(&self, u: u32, v: u32, out: &mut Vec<u32>) {
        out.clear();
        let empty = Vec::new();
        let into_u = self.open_in.get(u as usize).unwrap_or(&empty);
        let from_v = self.open_out.get(v as usize).unwrap_or(&empty);
        let both = |x: &u32| into_u.binary_search(x).is_ok() && from_v.binary_search(x).is_ok();
        let usable = |x: &u32| *x != u && *x != v;
        out.extend(into_u.iter().filter(|x| usable(x) && both(x)));
        out.extend(into_u.iter().filter(|x| usable(x) && !both(x)));
        out.extend(from_v.iter().filter(|x| usable(x) && !both(x)));
    }

    /// Unseen indices next to those around the gate `u → v`: the last vertex seen, `u` and
    /// `v` ± 1, ± 2, then the mesh neighbours of `u` and `v` (ascending) ± 1; first
    /// occurrences, at most [`MAX_NEW_CANDIDATES`].
    fn new_candidates(&self, u: u32, v: u32, out: &mut Vec<u32>) {
        out.clear();
        let push = |x: i64, out: &mut Vec<u32>| {
            if out.len() < MAX_NEW_CANDIDATES
                && (0..self.vertex_count as i64).contains(&x)
                && !self.is_seen(x as u32)
                && !out.contains(&(x as u32))
            {
                out.push(x as u32);
            }
        };
        for base in [self.last_seen, u, v] {
            for d in [1, -1, 2, -2] {
                push(base as i64 + d, out);
            }
        }
        for base in [u, v] {
            for &(y, _) in self.known.list(base) {
                push(y as i64 + 1, out);
                push(y as i64 - 1, out);
            }
        }
    }

    fn op_context(&self, seen_candidates: &[u32]) -> usize {
        self.after * 2 + usize::from(!seen_candidates.is_empty())
    }
}

/// Sorted half-edges `(from, to, triangle)` of the non-degenerate triangles, with a cursor
/// per key range to its first possibly uncoded triangle (so repeated edges cost linear time).
pub(crate) struct HalfEdges {
    edges: Vec<(u32, u32, u32)>,
    cursor: Vec<u32>,
}

impl HalfEdges {
    pub(crate) fn new(triangles: &[[u32; 3]]) -> Self {
        let mut edges = Vec::with_capacity(triangles.len() * 3);
        for (i, t) in triangles.iter().enumerate() {
            if t[0] != t[1] && t[1] != t[2] && t[2] != t[0] {
                for (x, y) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                    edges.push((x, y, i as u32));
                }
            }
        }
        edges.sort_unstable();
        let cursor = (0..edges.len() as u32).collect();
        Self { edges, cursor }
    }

    /// The first uncoded triangle holding the half-edge `x → y`.
    pub(crate) fn across(&mut self, x: u32, y: u32, done: &[bool]) -> Option<usize> {
        let start = self.edges.partition_point(|e| (e.0, e.1) < (x, y));
        let end = start + self.edges[start..].partition_point(|e| (e.0, e.1) == (x, y));
        if start == end {
            return None;
        }
        let mut pos = self.cursor[start] as usize;
        while pos < end && done[self.edges[pos].2 as usize] {
            pos += 1;
        }
        self.cursor[start] = pos as u32;
        (pos < end).then(|| self.edges[pos].2 as usize)
    }
}

/// The corner after `x → y` in `t` (which holds that half-edge).
pub(crate) fn third(t: [u32; 3], x: u32, y: u32) -> u32 {
    (0..3)
        .find(|&i| t[i] == x && t[(i + 1) % 3] == y)
        .map(|i| t[(i + 2) % 3])
        .expect("the triangle holds the half-edge")
}

/// Codes `topology`'s oriented triangles (not their order: see the module docs); `None`
/// when an index delta exceeds the coder's range or the block would be denser than
/// [`max_triangles`] allows.
pub fn encode(topology: &Topology) -> Option<Vec<u8>> {
    encode_with(topology, false)
}

/// Topology method 3 (container version 5): [`encode`]'s walk, each new vertex named by the
/// candidate kinds of `numbering` (adaptive per-kind flags, escapes counted in
/// unseen indices) instead of a rank in one list.
pub fn encode_predicted(topology: &Topology) -> Option<Vec<u8>> {
    encode_with(topology, true)
}

/// Marks `x` seen in the walk and the predictor (method 3).
fn see(walk: &mut Walk, predictor: &mut Option<Predictor>, x: u32) {
    walk.see(x);
    if let Some(p) = predictor {
        p.saw(x, &walk.seen);
    }
}

/// Where the walk's symbols go: the range coder, or a count of their ideal bits per class.
trait Sink {
    fn put(&mut self, value: i32, class: usize, bucket: usize);
}

impl Sink for AdaptiveEncoder {
    fn put(&mut self, value: i32, class: usize, bucket: usize) {
        self.encode(value, class, bucket);
    }
}

/// Ideal code length per class, adapting exactly like [`AdaptiveEncoder`].
struct ClassBits {
    model: CostModel,
    bits: Vec<f64>,
}

impl Sink for ClassBits {
    fn put(&mut self, value: i32, class: usize, bucket: usize) {
        let before = self.model.bits();
        self.model.add(value, class, bucket);
        self.bits[class] += self.model.bits() - before;
    }
}

/// Method 2, or method 3 with `predicted`.
fn encode_with(topology: &Topology, predicted: bool) -> Option<Vec<u8>> {
    let mut enc = AdaptiveEncoder::new(CLASSES + if predicted { KINDS } else { 0 });
    walk_symbols(topology, predicted, &mut enc)?;
    let bytes = enc.finish();
    (topology.triangle_count() <= max_triangles(bytes.len())).then_some(bytes)
}

/// Where the bits of method 2 (`predicted` false) or method 3 go, for benchmarks: the ideal
/// code length (bits, before the range coder's few bytes of overhead) of the ops (class 0),
/// the new-vertex ranks (1, method 2 only), the escapes (2), the seen vertices' deltas (3), the
/// component starts (4) and, for method 3, the candidate flags summed over the kinds (5).
/// `None` where [`encode`] / [`encode_predicted`] would give up.
#[doc(hidden)]
pub fn bits_by_class(topology: &Topology, predicted: bool) -> Option<[f64; 6]> {
    let classes = CLASSES + if predicted { KINDS } else { 0 };
    let mut sink = ClassBits { model: CostModel::new(classes), bits: vec![0.0; classes] };
    walk_symbols(topology, predicted, &mut sink)?;
    let mut out = [0.0; 6];
    out[..CLASSES].copy_from_slice(&sink.bits[..CLASSES]);
    out[5] = sink.bits[CLASSES..].iter().fold(0.0, |a, b| a + b);
    Some(out)
}

/// The walk of [`encode_with`], its symbols into `enc`; `None` when an index delta exceeds the
/// coder's range.
fn walk_symbols(topology: &Topology, predicted: bool, enc: &mut impl Sink) -> Option<()> {
    let triangles = topology.triangles();
    if triangles.len() > u32::MAX as usize / 3 {
        return None;
    }
    let fits = |d: i64| d.unsigned_abs() <= MAX_MAGNITUDE as u64;
    let mut half_edges = HalfEdges::new(triangles);
    let mut done = vec![false; triangles.len()];
    let mut walk = Walk::new(topology.vertex_count());
    let mut predictor = predicted.then(Predictor::new);
    let (mut seen_cand, mut new_cand) = (Vec::new(), Vec::new());
    let (mut coded, mut next_start) = (0usize, 0usize);
    while coded < triangles.len() {
        if let Some((u, v)) = walk.gates.pop() {
            if !walk.is_open(u, v) {
                continue;
            }
            walk.seen_candidates(u, v, &mut seen_cand);
            let context = walk.op_context(&seen_cand);
            let Some(t) = half_edges.across(v, u, &done) else {
                enc.put(OP_BORDER, Class::Op as usize, context);
                walk.close(u, v);
                walk.after = AFTER_BORDER;
                continue;
            };
            done[t] = true;
            coded += 1;
            let w = third(triangles[t], v, u);
            if !walk.is_seen(w) {
                enc.put(OP_NEW, Class::Op as usize, context);
                match predictor.as_mut() {
                    None => {
                        walk.new_candidates(u, v, &mut new_cand);
                        match new_cand.iter().position(|&x| x == w) {
                            Some(k) => enc.put(k as i32 + 1, Class::NewRank as usize, new_cand.len().min(7)),
                            None => {
                                enc.put(0, Class::NewRank as usize, new_cand.len().min(7));
                                let d = w as i64 - walk.last_seen as i64;
                                if !fits(d) {
                                    return None;
                                }
                                enc.put(d as i32, Class::NewDelta as usize, 0);
                            }
                        }
                    }
                    Some(p) => {
                        p.list(&walk, u, v);
                        let hit = p.candidates.iter().position(|e| e.0 == w);
                        for (i, &(_, kind)) in p.candidates.iter().enumerate() {
                            enc.put(i32::from(hit == Some(i)), CLASSES + kind, 0);
                            if hit == Some(i) {
                                break;
                            }
                        }
                        if hit.is_none() {
                            let d = p.escape_code(walk.last_seen, w);
                            if !fits(d) {
                                return None;
                            }
                            enc.put(d as i32, Class::NewDelta as usize, 0);
                        }
                        p.learn(hit);
                    }
                }
                see(&mut walk, &mut predictor, w);
                walk.after = AFTER_NEW;
            } else if let Some(k) = seen_cand.iter().position(|&x| x == w) {
                enc.put(OP_CANDIDATE + k as i32, Class::Op as usize, context);
                walk.after = AFTER_CANDIDATE;
            } else {
                enc.put(OP_SEEN, Class::Op as usize, context);
                let d = w as i64 - u as i64;
                if !fits(d) {
                    return None;
                }
                enc.put(d as i32, Class::SeenDelta as usize, 0);
                walk.after = AFTER_SEEN;
            }
            walk.add([v, u, w]);
            continue;
        }
        while done[next_start] {
            next_start += 1;
        }
        let t = triangles[next_start];
        done[next_start] = true;
        coded += 1;
        let mut base = walk.last_seen;
        for (corner, &x) in t.iter().enumerate() {
            let d = x as i64 - base as i64;
            if !fits(d) {
                return None;
            }
            enc.put(d as i32, Class::Start as usize, corner);
            base = x;
        }
        for x in t {
            if !walk.is_seen(x) {
                see(&mut walk, &mut predictor, x);
            }
        }
        walk.after = AFTER_NEW;
        walk.add(t);
    }
    Some(())
}

/// Most bytes [`decode`] allocates besides the triangles it returns: the walk's state
/// (seen flags and open half-edge lists up to the largest index, the gate stack, the mesh
/// neighbours) and the canonical ordering of the result.
pub fn decoder_bytes(vertex_count: usize, triangle_count: usize) -> u64 {
    let (v, t) = (vertex_count as u64, triangle_count as u64);
    let open_entries = (3 * t).min(MAX_OPEN as u64 * v);
    v + 48 * v
        + 2 * 2 * 4 * open_entries
        + 3 * 8 * t
        + crate::connectivity::decoder_bytes(vertex_count, triangle_count)
        + 48 * t
}

/// Inverse of [`encode`]: `triangle_count` triangles over `vertex_count` vertices in
/// [`canonical_order`], every op, index and candidate checked (a corrupt block is an error
/// naming the triangle, never a panic). The caller has checked both counts and
/// [`decoder_bytes`] against its limits; more than [`max_triangles`] for the block's size is
/// refused up front.
pub fn decode(bytes: &[u8], vertex_count: usize, triangle_count: usize) -> Result<Topology> {
    decode_with(bytes, vertex_count, triangle_count, false)
}

/// Inverse of [`encode_predicted`] (topology method 3), with [`decode`]'s checks; the
/// caller has checked [`decoder_bytes_predicted`] against its limits.
pub fn decode_predicted(bytes: &[u8], vertex_count: usize, triangle_count: usize) -> Result<Topology> {
    decode_with(bytes, vertex_count, triangle_count, true)
}

/// [`decoder_bytes`] plus the new-vertex model of method 3.
pub fn decoder_bytes_predicted(vertex_count: usize, triangle_count: usize) -> u64 {
    decoder_bytes(vertex_count, triangle_count) + numbering::predictor_bytes(vertex_count)
}

fn decode_with(bytes: &[u8], vertex_count: usize, triangle_count: usize, predicted: bool) -> Result<Topology> {
    check_density(bytes, triangle_count)?;
    let classes = CLASSES + if predicted { KINDS } else { 0 };
    let mut dec = AdaptiveDecoder::new(bytes, classes, CTX, FIELD)?;
    let mut predictor = predicted.then(Predictor::new);
    let index = |t: usize, base: u32, delta: i32| index_at(t, base, delta, vertex_count);
    let mut triangles: Vec<[u32; 3]> = Vec::with_capacity(triangle_count);
    let mut walk = Walk::new(vertex_count);
    let (mut seen_cand, mut new_cand) = (Vec::new(), Vec::new());
    while triangles.len() < triangle_count {
        let t = triangles.len();
        if let Some((u, v)) = walk.gates.pop() {
            if !walk.is_open(u, v) {
                continue;
            }
            walk.seen_candidates(u, v, &mut seen_cand);
            let context = walk.op_context(&seen_cand);
            let op = dec.decode(Class::Op as usize, context)?;
            let w = match op {
                OP_BORDER => {
                    walk.close(u, v);
                    walk.after = AFTER_BORDER;
                    continue;
                }
                OP_NEW => {
                    let w = match predictor.as_mut() {
                        None => {
                            walk.new_candidates(u, v, &mut new_cand);
                            match dec.decode(Class::NewRank as usize, new_cand.len().min(7))? {
                                0 => index(t, walk.last_seen, dec.decode(Class::NewDelta as usize, 0)?)?,
                                k if k > 0 && (k as usize) <= new_cand.len() => new_cand[k as usize - 1],
                                k => return Err(bad(t, format!("new vertex candidate {k} of {}", new_cand.len()))),
                            }
                        }
                        Some(p) => {
                            p.list(&walk, u, v);
                            let mut hit = None;
                            for (i, &(_, kind)) in p.candidates.iter().enumerate() {
                                match dec.decode(CLASSES + kind, 0)? {
                                    0 => {}
                                    1 => {
                                        hit = Some(i);
                                        break;
                                    }
                                    k => return Err(bad(t, format!("candidate flag {k}"))),
                                }
                            }
                            let w = match hit {
                                Some(i) => p.candidates[i].0,
                                None => {
                                    let code = dec.decode(Class::NewDelta as usize, 0)?;
                                    p.escaped(walk.last_seen, code, vertex_count).ok_or_else(|| {
                                        bad(
                                            t,
                                            format!(
                                                "escape {code} from vertex {} leaves the unseen indices",
                                                walk.last_seen
                                            ),
                                        )
                                    })?
                                }
                            };
                            p.learn(hit);
                            w
                        }
                    };
                    if walk.is_seen(w) {
                        return Err(bad(t, format!("new vertex {w} was seen before")));
                    }
                    see(&mut walk, &mut predictor, w);
                    walk.after = AFTER_NEW;
                    w
                }
                OP_SEEN => {
                    let w = index(t, u, dec.decode(Class::SeenDelta as usize, 0)?)?;
                    if !walk.is_seen(w) {
                        return Err(bad(t, format!("vertex {w} coded as seen was not")));
                    }
                    walk.after = AFTER_SEEN;
                    w
                }
                k if k >= OP_CANDIDATE && ((k - OP_CANDIDATE) as usize) < seen_cand.len() => {
                    walk.after = AFTER_CANDIDATE;
                    seen_cand[(k - OP_CANDIDATE) as usize]
                }
                k => return Err(bad(t, format!("op {k} ({} seen candidates)", seen_cand.len()))),
            };
            walk.add([v, u, w]);
            triangles.push([v, u, w]);
            continue;
        }
        let mut corners = [0u32; 3];
        let mut base = walk.last_seen;
        for (corner, c) in corners.iter_mut().enumerate() {
            *c = index(t, base, dec.decode(Class::Start as usize, corner)?)?;
            base = *c;
        }
        for x in corners {
            if !walk.is_seen(x) {
                see(&mut walk, &mut predictor, x);
            }
        }
        walk.after = AFTER_NEW;
        walk.add(corners);
        triangles.push(corners);
    }
    let topology = Topology::new(vertex_count, triangles).map_err(|e| Error::malformed(CTX, FIELD, e.to_string()))?;
    Ok(canonical_order(&topology))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    fn grid(n: usize) -> Topology {
        canonical_order(&crate::Topology::grid(n, n).unwrap())
    }

    /// Round trips `topo` through methods 2 and 3; their block sizes.
    fn roundtrip_both(topo: &Topology) -> (usize, usize) {
        let canonical = canonical_order(topo);
        let bytes = encode(&canonical).expect("fits");
        let back = decode(&bytes, topo.vertex_count(), topo.triangle_count()).unwrap();
        assert_eq!(back, canonical);
        let predicted = encode_predicted(&canonical).expect("fits");
        let back = decode_predicted(&predicted, topo.vertex_count(), topo.triangle_count()).unwrap();
        assert_eq!(back, canonical, "method 3");
        (bytes.len(), predicted.len())
    }

    fn roundtrip(topo: &Topology) -> usize {
        roundtrip_both(topo).0
    }

    /// Vertices renumbered by a deterministic (xorshift) shuffle.
    fn renumbered(topo: &Topology, seed: u64) -> Topology {
        shuffled_within(topo, topo.vertex_count().max(1), seed | 1)
    }

    /// Each run of `window` consecutive vertex indices of `topo` shuffled among themselves by a
    /// deterministic xorshift from `seed` (`window` ≥ the vertex count: the whole numbering).
    pub(crate) fn shuffled_within(topo: &Topology, window: usize, seed: u64) -> Topology {
        let perm = crate::testing::shuffled_permutation(topo.vertex_count(), window, seed);
        let tris = topo.triangles().iter().map(|t| t.map(|x| perm[x as usize] as u32)).collect();
        Topology::new(topo.vertex_count(), tris).unwrap()
    }

    #[test]
    fn every_kind_of_triangle_list_roundtrips() {
        roundtrip(&grid(20));
        roundtrip(&renumbered(&grid(20), 9));
        // Degenerate, repeated and reversed triangles, an edge shared by three triangles,
        // two components, and an empty list.
        let odd = Topology::new(
            8,
            vec![[0, 0, 1], [1, 0, 0], [2, 3, 4], [2, 3, 4], [4, 3, 2], [3, 3, 3], [2, 3, 5], [3, 2, 6], [6, 7, 5]],
        )
        .unwrap();
        roundtrip(&odd);
        roundtrip(&Topology::new(3, vec![[0, 1, 2]]).unwrap());
        roundtrip(&Topology::new(3, Vec::new()).unwrap());
        // A closed surface: an octahedron, and one vertex in 200 triangles (a wide fan).
        let octa = vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
        roundtrip(&Topology::new(6, octa).unwrap());
        let fan: Vec<[u32; 3]> = (1..=200).map(|i| [0, i, i % 200 + 1]).collect();
        roundtrip(&Topology::new(201, fan).unwrap());
    }

    #[test]
    fn random_triangle_soups_roundtrip() {
        // Few vertices, many triangles: repeated and reversed triangles, edges in many
        // triangles, degenerate ones, several components — every case the walk must code.
        let mut s = 0x853c_49e6_748f_ea9bu64;
        let mut next = |n: u64| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s % n) as u32
        };
        for case in 0..300u64 {
            let vertices = 3 + (case % 40) as u32;
            let count = 1 + next(3 * vertices as u64 + 1) as usize;
            let tris =
                (0..count).map(|_| [next(vertices as u64), next(vertices as u64), next(vertices as u64)]).collect();
            roundtrip(&Topology::new(vertices as usize, tris).unwrap());
        }
        // And a mesh cut into strips: a grid with every other row of triangles removed.
        let g = grid(16);
        let strips: Vec<[u32; 3]> = g.triangles().iter().copied().filter(|t| (t[0] / 16) % 2 == 0).collect();
        roundtrip(&Topology::new(g.vertex_count(), strips).unwrap());
    }

    #[test]
    fn local_numberings_code_smaller_than_method_1() {
        // A 40 × 40 grid in its own (row-major) numbering: the new vertex is next to an
        // index around the gate.
        let g = grid(40);
        let traversal = roundtrip(&g);
        let connectivity = crate::connectivity::encode(&g).unwrap().len();
        let bits = traversal as f64 * 8.0 / g.triangle_count() as f64;
        assert!(bits < 1.5, "{bits:.2} bits per triangle");
        assert!(traversal < connectivity, "{traversal} bytes vs method 1's {connectivity}");
    }

    #[test]
    fn method_3_names_local_numberings_in_fewer_bits() {
        // A grid renumbered within windows of 8: local but irregular, like real meshes.
        let (m2, m3) = roundtrip_both(&shuffled_within(&grid(40), 8, 0x9e37_79b9_7f4a_7c15));
        assert!(m3 < m2, "method 3 {m3} bytes vs method 2's {m2}");
        // Vertex counts far above the indices used, and the escape at either end of the range.
        roundtrip_both(&Topology::new(u32::MAX as usize, vec![[7, 3_000_000, 9], [9, 3_000_000, 0]]).unwrap());
        roundtrip_both(&Topology::new(5, vec![[4, 0, 2], [2, 0, 1], [1, 3, 2]]).unwrap());
    }

    #[test]
    fn corrupt_blocks_are_errors_not_panics() {
        let g = renumbered(&grid(12), 3);
        let canonical = canonical_order(&g);
        // Method 3 first: every truncation and three flips per byte.
        let bytes = encode_predicted(&canonical).unwrap();
        for cut in (0..bytes.len()).step_by(4) {
            let _ = decode_predicted(&bytes[..cut], g.vertex_count(), g.triangle_count());
        }
        for i in 0..bytes.len() {
            for flip in [0x01, 0x5a, 0xff] {
                let mut b = bytes.clone();
                b[i] ^= flip;
                if let Ok(t) = decode_predicted(&b, g.vertex_count(), g.triangle_count()) {
                    assert_eq!(t.triangle_count(), g.triangle_count());
                }
            }
        }
        let _ = decode_predicted(&bytes, g.vertex_count(), g.triangle_count() * 3);
        let e = decode_predicted(&[], g.vertex_count(), 5_000_000).unwrap_err().to_string();
        assert!(e.contains("at most 4096 per byte"), "{e}");
        let e = decode_predicted(&bytes, 10, g.triangle_count()).unwrap_err().to_string();
        assert!(e.contains("topology") && (e.contains("out of range") || e.contains("leaves the unseen")), "{e}");
        let bytes = encode(&canonical).unwrap();
        for cut in (0..bytes.len()).step_by(4) {
            let _ = decode(&bytes[..cut], g.vertex_count(), g.triangle_count());
        }
        for i in 0..bytes.len() {
            for flip in [0x01, 0x5a, 0xff] {
                let mut b = bytes.clone();
                b[i] ^= flip;
                let _ = decode(&b, g.vertex_count(), g.triangle_count());
            }
        }
        let _ = decode(&bytes, g.vertex_count(), g.triangle_count() * 3);
        assert!(decode(&bytes[..3], g.vertex_count(), 1).is_err(), "not whole words");
        let e = decode(&[], g.vertex_count(), 5_000_000).unwrap_err().to_string();
        assert!(e.contains("at most 4096 per byte"), "{e}");
        // A declared vertex count far above the indices used allocates nothing for it.
        let huge = Topology::new(u32::MAX as usize, canonical.triangles().to_vec()).unwrap();
        let b = encode(&huge).unwrap();
        assert_eq!(decode(&b, huge.vertex_count(), huge.triangle_count()).unwrap(), huge);
        let e = decode(&bytes, 10, g.triangle_count()).unwrap_err().to_string();
        assert!(e.contains("topology") && e.contains("out of range"), "{e}");
    }

    /// The per-class bit count sees the same symbols as the coder: its total is the block's
    /// size within the range coder's overhead (a few words), for methods 2 and 3.
    #[test]
    fn bits_by_class_add_up_to_the_block() {
        let canonical = canonical_order(&renumbered(&grid(30), 5));
        for predicted in [false, true] {
            let bytes = encode_with(&canonical, predicted).unwrap().len() as f64;
            let classes = bits_by_class(&canonical, predicted).unwrap();
            let total = classes.iter().sum::<f64>() / 8.0;
            assert!((bytes - 12.0..=bytes + 1.0).contains(&total), "{total} bits/8 vs {bytes} bytes");
            assert_eq!(classes[1] == 0.0, predicted, "method 3 codes no ranks");
            assert_eq!(classes[5] == 0.0, !predicted, "method 2 codes no flags");
        }
    }

    /// Method 3 on arbitrary bytes: an error or a triangle list of the declared size with
    /// every index in range, never a panic — also with a declared vertex count of 2^32 − 1,
    /// where the escapes can name any index (the unseen-index tree grows only as far as the
    /// indices met, at most twice the largest).
    #[test]
    fn method_3_on_random_bytes_is_an_error_or_a_valid_list() {
        let mut s = 0x243f_6a88_85a3_08d3u64;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        let mut decoded = 0;
        for round in 0..600 {
            let words = (next() % 24) as usize;
            let bytes: Vec<u8> = (0..4 * words).map(|_| next() as u8).collect();
            let vertex_count = [3usize, 40, 5_000, 1 << 20][round % 4];
            let triangle_count = [1usize, 7, 60][(round / 4) % 3];
            if let Ok(t) = decode_predicted(&bytes, vertex_count, triangle_count) {
                assert_eq!(t.triangle_count(), triangle_count);
                assert!(t.triangles().iter().flatten().all(|&x| (x as usize) < vertex_count));
                decoded += 1;
            }
        }
        assert!(decoded > 0, "no random block decoded: the test would not see a wrong list");
        // Escapes far up a 2^32 − 1 vertex range: the walk allocates up to the index met only.
        for round in 0..40 {
            let bytes: Vec<u8> = (0..16).map(|_| next() as u8).collect();
            let r = decode_predicted(&bytes, u32::MAX as usize, 1 + round % 3);
            if let Ok(t) = r {
                assert!(t.triangles().iter().flatten().all(|&x| x < u32::MAX));
            }
        }
    }
}
