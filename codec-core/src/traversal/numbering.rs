//! Naming the vertex that enters the walk of topology method 3 ([`super`],
//! container version 5).
//!
//! The walk is method 2's: the triangle across a gate `u → v` shares two known corners, so
//! only its third corner `w` is coded (Edgebreaker, Rossignac 1999; the cut-border machine,
//! Gumhold & Straßer 1998). Those coders renumber the vertices in walk order; a stream must
//! keep the input's numbering (positions are indexed by it), so most of the block names each
//! `w` seen for the first time. Method 2 names it by its rank in one fixed list of nearby
//! unseen indices; this module instead lists them by *kind* — which predictor proposed them
//! (the last vertex seen ± 1, `u` ± 1, a mesh neighbour ± 1, …) — and codes, candidate by
//! candidate, a flag "is it this one?" with one adaptive model per kind, so each kind costs
//! what its own hit rate says. The kinds are tried in the order of their hit rates so far
//! (the decoder keeps the same counts), and an index no kind proposed is an *escape*: its
//! distance from the last vertex seen counted in unseen indices only ([`Unseen`]), which is
//! short once the region around it is coded. Measured on the dev meshes
//! (`docs/notes/topology-numbering.md`): escapes counted in unseen indices −0.10 bits per
//! triangle on horse-gallop and −0.35 on samba, the kinds and their order −0.3 on
//! horse-gallop; richer contexts (candidate position, previous hit's kind, whether the gate
//! touches the last vertex) and other predictors (a parallelogram in index space, the stride
//! of the last two new vertices, the smallest unseen index) cost more than they saved.

use super::Walk;

/// Number of candidate kinds (see [`Predictor::candidates`]).
pub(crate) const KINDS: usize = 13;

/// Most candidates listed per new vertex: bounds each one's work.
const MAX_CANDIDATES: usize = 64;

/// Border vertices visited on each side of the gate by the `border ± 1` kind.
const BORDER_STEPS: usize = 3;

/// Unseen indices, counted by a Fenwick tree over the seen flags up to a capacity that
/// doubles as larger indices are seen (every index at or above it is unseen), so a huge
/// declared vertex count costs nothing until its indices are used.
#[derive(Default)]
struct Unseen {
    tree: Vec<u32>,
}

impl Unseen {
    fn cap(&self) -> u64 {
        self.tree.len() as u64
    }

    /// Marks `x` seen (once per index); `seen` holds the flags, `x` included.
    fn mark(&mut self, x: u32, seen: &[bool]) {
        if x as u64 >= self.cap() {
            let cap = (x as usize + 1).next_power_of_two().max(64);
            // The old tree goes first, so the peak stays at the new one (`predictor_bytes`).
            self.tree = Vec::new();
            self.tree = vec![0; cap];
            for (i, _) in seen.iter().enumerate().filter(|&(i, &s)| s && i != x as usize) {
                self.add(i);
            }
        }
        self.add(x as usize);
    }

    fn add(&mut self, i: usize) {
        let mut j = i + 1;
        while j <= self.tree.len() {
            self.tree[j - 1] += 1;
            j += j & j.wrapping_neg();
        }
    }

    /// Unseen indices in `[0, i)`.
    fn before(&self, i: u64) -> u64 {
        let mut seen = 0u64;
        let mut j = i.min(self.cap()) as usize;
        while j > 0 {
            seen += self.tree[j - 1] as u64;
            j &= j - 1;
        }
        i - seen
    }

    /// The `k`-th unseen index, `k` ≥ 1.
    fn nth(&self, k: u64) -> u64 {
        let cap = self.cap();
        let within = self.before(cap);
        if k > within {
            return cap + (k - within) - 1;
        }
        // Fenwick descent on the unseen counts (a node's length minus its seen count).
        let (mut pos, mut rest, mut step) = (0usize, k, self.tree.len());
        while step > 0 {
            let next = pos + step;
            if next <= self.tree.len() {
                let unseen = step as u64 - self.tree[next - 1] as u64;
                if unseen < rest {
                    pos = next;
                    rest -= unseen;
                }
            }
            step >>= 1;
        }
        pos as u64
    }
}

/// The new-vertex model: candidate kinds with their hit counts, and the unseen indices.
pub(crate) struct Predictor {
    hits: [u32; KINDS],
    tries: [u32; KINDS],
    /// Kinds in the order their candidates are listed.
    order: [usize; KINDS],
    unseen: Unseen,
    /// The current candidates and their kinds.
    pub(crate) candidates: Vec<(u32, usize)>,
}

impl Predictor {
    pub(crate) fn new() -> Self {
        Self {
            hits: [0; KINDS],
            tries: [0; KINDS],
            order: std::array::from_fn(|k| k),
            unseen: Unseen::default(),
            candidates: Vec::new(),
        }
    }

    /// Records that `x` was just marked seen in `seen`.
    pub(crate) fn saw(&mut self, x: u32, seen: &[bool]) {
        self.unseen.mark(x, seen);
    }

    /// The next unseen index above (`up`) or below `b`, or −1.
    fn next_unseen(&self, b: u32, up: bool) -> i64 {
        let k = self.unseen.before(b as u64 + u64::from(up));
        match (up, k) {
            (true, _) => self.unseen.nth(k + 1) as i64,
            (false, 0) => -1,
            (false, _) => self.unseen.nth(k) as i64,
        }
    }

    /// Lists the unseen candidates for the vertex across the gate `u → v`, kind by kind in
    /// the current order; an index proposed twice keeps its first kind. Kinds: 0 the last
    /// vertex seen + 1, 1 − 1; 2 `u` + 1, 3 `u` − 1; 4 `v` + 1, 5 `v` − 1; 6 the last vertex
    /// seen + 2, − 2; 7 `u` + 2, − 2, `v` + 2, − 2; 8 each known neighbour of `u`, then of `v`
    /// (ascending), + 1, − 1; 9 the same ± 2; 10 the last vertex seen + 3, − 3; 11 the border
    /// vertices up to 3 steps before `u` and after `v` (following the first open half-edge
    /// into, resp. out of, each), alternating sides, + 1, − 1; 12 the next unseen index above
    /// `u`, below `u`, above `v`, below `v`. At most [`MAX_CANDIDATES`].
    pub(crate) fn list(&mut self, walk: &Walk, u: u32, v: u32) {
        let mut out = std::mem::take(&mut self.candidates);
        out.clear();
        let n = walk.vertex_count as i64;
        let push = |x: i64, kind: usize, out: &mut Vec<(u32, usize)>| {
            if out.len() < MAX_CANDIDATES
                && (0..n).contains(&x)
                && !walk.is_seen(x as u32)
                && !out.iter().any(|e| e.0 == x as u32)
            {
                out.push((x as u32, kind));
            }
        };
        let last = walk.last_seen as i64;
        let (ui, vi) = (u as i64, v as i64);
        for &kind in &self.order {
            match kind {
                0 => push(last + 1, kind, &mut out),
                1 => push(last - 1, kind, &mut out),
                2 => push(ui + 1, kind, &mut out),
                3 => push(ui - 1, kind, &mut out),
                4 => push(vi + 1, kind, &mut out),
                5 => push(vi - 1, kind, &mut out),
                6 => {
                    push(last + 2, kind, &mut out);
                    push(last - 2, kind, &mut out);
                }
                7 => {
                    for b in [ui, vi] {
                        push(b + 2, kind, &mut out);
                        push(b - 2, kind, &mut out);
                    }
                }
                8 | 9 => {
                    let d = kind as i64 - 7;
                    for b in [u, v] {
                        for &(y, _) in walk.known.list(b) {
                            push(y as i64 + d, kind, &mut out);
                            push(y as i64 - d, kind, &mut out);
                        }
                    }
                }
                10 => {
                    push(last + 3, kind, &mut out);
                    push(last - 3, kind, &mut out);
                }
                11 => {
                    let (mut x, mut y) = (u, v);
                    for _ in 0..BORDER_STEPS {
                        if let Some(&p) = walk.open_in.get(x as usize).and_then(|l| l.first()) {
                            x = p;
                            push(x as i64 + 1, kind, &mut out);
                            push(x as i64 - 1, kind, &mut out);
                        }
                        if let Some(&q) = walk.open_out.get(y as usize).and_then(|l| l.first()) {
                            y = q;
                            push(y as i64 + 1, kind, &mut out);
                            push(y as i64 - 1, kind, &mut out);
                        }
                    }
                }
                _ => {
                    for b in [u, v] {
                        push(self.next_unseen(b, true), kind, &mut out);
                        push(self.next_unseen(b, false), kind, &mut out);
                    }
                }
            }
        }
        self.candidates = out;
    }

    /// Counts the tries and the hit of the current list (`hit`: the index of the new vertex
    /// in it, `None` for an escape) and re-sorts the kinds by hit rate `(hits + 1) / (tries
    /// + 2)`, descending, ties by kind.
    pub(crate) fn learn(&mut self, hit: Option<usize>) {
        let tried = hit.map_or(self.candidates.len(), |h| h + 1);
        for &(_, k) in &self.candidates[..tried] {
            self.tries[k] = self.tries[k].saturating_add(1);
        }
        if let Some(h) = hit {
            let k = self.candidates[h].1;
            self.hits[k] = self.hits[k].saturating_add(1);
        }
        let (h, t) = (self.hits, self.tries);
        self.order.sort_by(|&a, &b| {
            let rate_a = (h[a] as u64 + 1) * (t[b] as u64 + 2);
            let rate_b = (h[b] as u64 + 1) * (t[a] as u64 + 2);
            rate_b.cmp(&rate_a).then(a.cmp(&b))
        });
    }

    /// The escape code of the unseen `w` from the seen `base`: `k − 1` when `w` is the `k`-th
    /// unseen index above `base`, `−k` when it is the `k`-th below.
    pub(crate) fn escape_code(&self, base: u32, w: u32) -> i64 {
        let (b, w) = (base as u64, w as u64);
        if w > b {
            (self.unseen.before(w + 1) - self.unseen.before(b + 1)) as i64 - 1
        } else {
            -((self.unseen.before(b) - self.unseen.before(w)) as i64)
        }
    }

    /// Inverse of [`Predictor::escape_code`]; `None` when the code points below the first or
    /// past the last unseen index.
    pub(crate) fn escaped(&self, base: u32, code: i32, vertex_count: usize) -> Option<u32> {
        let b = base as u64;
        let target = if code >= 0 {
            self.unseen.before(b + 1) + code as u64 + 1
        } else {
            let below = self.unseen.before(b);
            below.checked_sub(code.unsigned_abs() as u64)? + 1
        };
        let x = self.unseen.nth(target);
        (x < vertex_count as u64).then_some(x as u32)
    }
}

/// Most bytes a [`Predictor`] holds for `vertex_count` vertices: the Fenwick tree (4 bytes per
/// index, up to twice the vertex count) and the candidate list.
pub(crate) fn predictor_bytes(vertex_count: usize) -> u64 {
    8 * vertex_count as u64 + 16 * MAX_CANDIDATES as u64 + 256
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unseen_counts_and_finds_indices() {
        let mut seen = vec![false; 300];
        let mut u = Unseen::default();
        for x in [5u32, 6, 7, 100, 3, 250, 64, 63] {
            seen[x as usize] = true;
            u.mark(x, &seen);
        }
        let unseen: Vec<u64> = (0..400u64).filter(|&i| !seen.get(i as usize).copied().unwrap_or(false)).collect();
        for i in 0..400u64 {
            assert_eq!(u.before(i), unseen.iter().filter(|&&x| x < i).count() as u64, "before {i}");
        }
        for (k, &x) in unseen.iter().enumerate() {
            assert_eq!(u.nth(k as u64 + 1), x, "nth {}", k + 1);
        }
        let p = Predictor { unseen: u, ..Predictor::new() };
        for base in [5u32, 63, 100, 250] {
            for &w in unseen.iter().filter(|&&x| x < 300) {
                let code = p.escape_code(base, w as u32);
                assert_eq!(p.escaped(base, code as i32, 300), Some(w as u32), "base {base}, w {w}");
            }
        }
        assert_eq!(p.escape_code(5, 4), -1);
        assert_eq!(p.escape_code(5, 8), 0);
        assert_eq!(p.escaped(5, -6, 300), None, "below index 0");
        assert_eq!(p.escaped(250, 48, 300), Some(299));
        assert_eq!(p.escaped(250, 49, 300), None, "past the last vertex");
    }
}
