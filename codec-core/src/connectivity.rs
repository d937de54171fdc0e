//! Compact coding of the triangle list in canonical order (topology method 1, container versions 2 and 3;
//! method 2, usually smaller, is [`crate::traversal`]).
//!
//! Version 1 coded each triangle as three zigzag varint deltas and zstd: 14–28 bits per
//! triangle on the dev meshes (horse-gallop 14.2, samba 28.1), which for a short animation is
//! more than the coded motion (horse-gallop's 16 843 triangles took 29 857 bytes = 0.59 bits
//! per vertex per frame). This coder spends 5.5–6.9 bits per triangle on the same meshes and keeps
//! the vertex numbering (positions are indexed by it):
//!
//! 1. [`canonical_order`] (done by the stream encoder, not here): every triangle rotated so its
//!    smallest index comes first (orientation kept), triangles grouped by that index in
//!    ascending order, and each group ordered as fans — the next triangle starts with the
//!    previous one's last vertex when one does, new fans start where a fan begins — so
//!    consecutive triangles share edges.
//! 2. Per triangle `(a, b, c)`, context-adaptive arithmetic codes
//!    ([`crate::toolkit::adaptive`]) of: `a − a_prev`; whether `b` continues the fan
//!    (`b = c_prev`, only asked when `a = a_prev`); else `b` as an index into the already known
//!    neighbours of `a` above `a`, those with an open half-edge into `a` first (0 = not there,
//!    then `b − a`); then `c` as an index into the known neighbours of `a` or `b` above `a`,
//!    ranked by how many of the triangle's open half-edges they would close, then whether
//!    they neighbour both (0 = not there, then `c − b`). Known neighbours and the directions of
//!    their half-edges come from earlier triangles, so the decoder rebuilds the same lists. In
//!    a consistently oriented manifold the triangle across an edge holds its reverse, which
//!    is what "open" means: on the dev meshes the ranking saves ~1 bit per triangle
//!    (horse-gallop 8.22 → 7.12, samba 8.27 → 7.33).
//!
//! Any triangle list is coded exactly (order, rotation, degenerate and repeated triangles);
//! the canonical order only makes it small. [`encode`] returns `None` when an index delta
//! does not fit the arithmetic coder's range (meshes beyond 2^31 vertices); the container
//! then keeps version 1's coding.

use std::collections::HashMap;

use crate::animation::Topology;
use crate::error::{Error, Result};
use crate::toolkit::adaptive::{AdaptiveDecoder, AdaptiveEncoder, MAX_MAGNITUDE};

pub(crate) const CTX: &str = "container";
pub(crate) const FIELD: &str = "topology";

/// Model classes of the arithmetic coder.
#[derive(Clone, Copy)]
enum Class {
    /// `a − a_prev`.
    FirstDelta = 0,
    /// 1 when `b = c_prev` in the same fan.
    Fan = 1,
    /// Index + 1 of `b` among the candidates, 0 = escape.
    SecondIndex = 2,
    /// `b − a` after an escape.
    SecondDelta = 3,
    /// Index + 1 of `c` among the candidates, 0 = escape.
    ThirdIndex = 4,
    /// `c − b` after an escape (neighbouring indices are close; `b` is the nearer base).
    ThirdDelta = 5,
}
const CLASSES: usize = 6;

/// The same triangles (each with its orientation) in canonical order: see the module docs.
/// Deterministic, so encoder and decoder see one list; idempotent.
pub fn canonical_order(topology: &Topology) -> Topology {
    let mut rotated: Vec<[u32; 3]> = topology
        .triangles()
        .iter()
        .map(|t| {
            // Rotations keep the orientation; ties (degenerate triangles) take the
            // lexicographically smallest rotation.
            let r = [[t[0], t[1], t[2]], [t[1], t[2], t[0]], [t[2], t[0], t[1]]];
            *r.iter().min().expect("three rotations")
        })
        .collect();
    rotated.sort_unstable();
    let mut out = Vec::with_capacity(rotated.len());
    let mut start = 0;
    while start < rotated.len() {
        let a = rotated[start][0];
        let end = start + rotated[start..].partition_point(|t| t[0] == a);
        fan_order(&rotated[start..end], &mut out);
        start = end;
    }
    Topology::new(topology.vertex_count(), out).expect("same indices as a valid topology")
}

/// Largest group whose fan starts are searched (see [`fan_order`]).
const FAN_SEARCH: usize = 64;

/// Appends one group (triangles sharing their first, smallest index; sorted) in fan order:
/// the next triangle is the first unused one whose second index is the previous third
/// index, else (a new fan) the first unused one that no unused triangle precedes around the
/// shared vertex (its second index is no unused triangle's third), else the first unused one.
/// Starting fans at their beginning instead of their smallest index saved 1.06 bits per
/// triangle on horse-gallop (7.12 → 6.06). Per-second-index cursors; the start search is
/// linear per fan and only done for groups of at most [`FAN_SEARCH`] triangles.
fn fan_order(group: &[[u32; 3]], out: &mut Vec<[u32; 3]>) {
    let mut used = vec![false; group.len()];
    // First position of each second index in the (sorted) group, advanced past used entries.
    let mut cursor: HashMap<u32, usize> = HashMap::new();
    for (i, t) in group.iter().enumerate().rev() {
        cursor.insert(t[1], i);
    }
    // Unused triangles per third index (for the fan-start search).
    let mut unused_third: HashMap<u32, usize> = HashMap::new();
    if group.len() <= FAN_SEARCH {
        for t in group {
            *unused_third.entry(t[2]).or_insert(0) += 1;
        }
    }
    let mut lowest = 0;
    let mut prev_third: Option<u32> = None;
    for _ in 0..group.len() {
        let mut pick = None;
        if let Some(c) = prev_third {
            if let Some(pos) = cursor.get_mut(&c) {
                while *pos < group.len() && group[*pos][1] == c && used[*pos] {
                    *pos += 1;
                }
                if *pos < group.len() && group[*pos][1] == c {
                    pick = Some(*pos);
                }
            }
        }
        let i = pick.unwrap_or_else(|| {
            while used[lowest] {
                lowest += 1;
            }
            // Start a new fan where an open fan begins: the first unused triangle whose
            // second index is no unused triangle's third (nothing precedes it around `a`), so
            // fans are not cut in the middle. Small groups only (the scan is quadratic).
            if group.len() <= FAN_SEARCH {
                (lowest..group.len())
                    .find(|&j| {
                        let own = usize::from(group[j][2] == group[j][1]);
                        !used[j] && unused_third.get(&group[j][1]).map_or(0, |&n| n - own) == 0
                    })
                    .unwrap_or(lowest)
            } else {
                lowest
            }
        });
        used[i] = true;
        if let Some(n) = unused_third.get_mut(&group[i][2]) {
            *n -= 1;
        }
        out.push(group[i]);
        prev_third = Some(group[i][2]);
    }
}

/// Most neighbours remembered per vertex. Meshes have degree 4–12; the cap keeps every
/// triangle's work bounded (a hostile stream with one vertex in millions of triangles costs
/// the decoder linear time, not quadratic). Encoder and decoder apply the same rule.
const MAX_KNOWN: usize = 32;

/// Most bytes [`decode`] allocates besides the triangles: the neighbour lists (8 bytes per
/// entry, at most 6 entries per triangle and `MAX_KNOWN` per vertex, doubled for growth)
/// and their headers (24 bytes per vertex up to the largest index).
pub fn decoder_bytes(vertex_count: usize, triangle_count: usize) -> u64 {
    let entries = (6 * triangle_count as u64).min(MAX_KNOWN as u64 * vertex_count as u64);
    16 * entries + 24 * vertex_count as u64
}

/// True when `a` and `b` hold the same oriented triangles (as a multiset) over the same
/// vertices, whatever their order and starting corners: what a decoded stream keeps of its
/// input's topology.
pub fn same_triangles(a: &Topology, b: &Topology) -> bool {
    a.vertex_count() == b.vertex_count()
        && a.triangle_count() == b.triangle_count()
        && (a == b || canonical_order(a) == canonical_order(b))
}

/// Flag of a known neighbour `y` of `x`: the half-edge `x → y` is in an earlier triangle.
const OUT: u8 = 1;
/// Flag of a known neighbour `y` of `x`: the half-edge `y → x` is in an earlier triangle.
const IN: u8 = 2;

/// Known neighbours per vertex (sorted, deduplicated, at most [`MAX_KNOWN`]) with the
/// directions of the half-edges seen, grown triangle by triangle.
pub(crate) struct Neighbours {
    lists: Vec<Vec<(u32, u8)>>,
}

impl Neighbours {
    /// Empty; lists are allocated up to the largest index met (so a huge declared vertex
    /// count with few triangles costs nothing).
    pub(crate) fn new() -> Self {
        Self { lists: Vec::new() }
    }

    pub(crate) fn list(&self, x: u32) -> &[(u32, u8)] {
        self.lists.get(x as usize).map_or(&[], |l| l.as_slice())
    }

    fn mark(&mut self, x: u32, y: u32, flag: u8) {
        if x as usize >= self.lists.len() {
            self.lists.resize(x as usize + 1, Vec::new());
        }
        let list = &mut self.lists[x as usize];
        match list.binary_search_by_key(&y, |e| e.0) {
            Ok(i) => list[i].1 |= flag,
            Err(i) if list.len() < MAX_KNOWN => list.insert(i, (y, flag)),
            Err(_) => {}
        }
    }

    /// Records the half-edge `p → q`.
    fn link(&mut self, p: u32, q: u32) {
        if p == q {
            return;
        }
        self.mark(p, q, OUT);
        self.mark(q, p, IN);
    }

    pub(crate) fn add(&mut self, t: [u32; 3]) {
        self.link(t[0], t[1]);
        self.link(t[1], t[2]);
        self.link(t[2], t[0]);
    }

    fn flags(&self, x: u32, y: u32) -> u8 {
        let list = self.list(x);
        list.binary_search_by_key(&y, |e| e.0).map_or(0, |i| list[i].1)
    }

    /// Candidates for the second index: known neighbours of `a` above `a`, first those whose
    /// half-edge into `a` is open (the triangle across `a → b` is known, this one is not:
    /// `b → a` seen, `a → b` not), each tier ascending. Returns the first tier's length.
    fn second(&self, a: u32, out: &mut Vec<u32>) -> usize {
        out.clear();
        let list = self.list(a);
        out.extend(list.iter().filter(|e| e.0 > a && e.1 == IN).map(|e| e.0));
        let strong = out.len();
        out.extend(list.iter().filter(|e| e.0 > a && e.1 != IN).map(|e| e.0));
        strong
    }

    /// Candidates for the third index, in tiers (each ascending): vertices closing both open
    /// half-edges (`c → b` seen and `b → c` not; `a → c` seen and `c → a` not), then one of
    /// them, then the other known neighbours common to `a` and `b`, then the rest of either
    /// (all above `a`, not `b`). Returns the count of the first two tiers.
    fn third(&self, a: u32, b: u32, out: &mut Vec<u32>) -> usize {
        out.clear();
        let (la, lb) = (self.list(a), self.list(b));
        let mut all: Vec<u32> = la.iter().chain(lb.iter()).map(|e| e.0).filter(|&x| x > a && x != b).collect();
        all.sort_unstable();
        all.dedup();
        let tier = |x: u32| {
            let (fa, fb) = (self.flags(a, x), self.flags(b, x));
            match (fa == OUT, fb == IN) {
                (true, true) => 0u8,
                (true, false) | (false, true) => 1,
                _ if fa != 0 && fb != 0 => 2,
                _ => 3,
            }
        };
        // (tier, index) pairs sorted: tiers in order, each ascending.
        let mut tiered: Vec<(u8, u32)> = all.iter().map(|&x| (tier(x), x)).collect();
        tiered.sort_unstable();
        out.extend(tiered.iter().map(|e| e.1));
        tiered.iter().filter(|e| e.0 < 2).count()
    }
}

/// Context of a candidate index: the length of the candidates' first tiers (capped at 3) and
/// whether other candidates follow.
fn candidate_bucket(strong: usize, total: usize) -> usize {
    strong.min(3) * 2 + usize::from(total > strong)
}

/// Codes `topology` exactly (see the module docs); `None` when a delta exceeds the coder's
/// range.
pub fn encode(topology: &Topology) -> Option<Vec<u8>> {
    let fits = |d: i64| d.unsigned_abs() <= MAX_MAGNITUDE as u64;
    let mut enc = AdaptiveEncoder::new(CLASSES);
    let mut known = Neighbours::new();
    let mut cand = Vec::new();
    let (mut prev_a, mut prev_c, mut prev_same) = (0u32, None::<u32>, false);
    for &[a, b, c] in topology.triangles() {
        let da = a as i64 - prev_a as i64;
        if !fits(da) {
            return None;
        }
        enc.encode(da as i32, Class::FirstDelta as usize, usize::from(prev_same));
        let same = da == 0 && prev_c.is_some();
        let fan = same && prev_c == Some(b);
        if same {
            enc.encode(i32::from(fan), Class::Fan as usize, 0);
        }
        if !fan {
            let strong = known.second(a, &mut cand);
            let hit = cand.iter().position(|&x| x == b);
            if !cand.is_empty() {
                enc.encode(
                    hit.map_or(0, |i| i as i32 + 1),
                    Class::SecondIndex as usize,
                    candidate_bucket(strong, cand.len()),
                );
            }
            if hit.is_none() {
                let db = b as i64 - a as i64;
                if !fits(db) {
                    return None;
                }
                enc.encode(db as i32, Class::SecondDelta as usize, usize::from(same));
            }
        }
        let common = known.third(a, b, &mut cand);
        let hit = cand.iter().position(|&x| x == c);
        if !cand.is_empty() {
            enc.encode(
                hit.map_or(0, |i| i as i32 + 1),
                Class::ThirdIndex as usize,
                candidate_bucket(common, cand.len()),
            );
        }
        if hit.is_none() {
            let dc = c as i64 - b as i64;
            if !fits(dc) {
                return None;
            }
            enc.encode(dc as i32, Class::ThirdDelta as usize, usize::from(fan));
        }
        known.add([a, b, c]);
        prev_same = da == 0;
        prev_a = a;
        prev_c = Some(c);
    }
    let bytes = enc.finish();
    // The decoder refuses blocks claiming more triangles than this per byte (a few bytes
    // must not expand into millions of triangles); a mesh this regular keeps the list coding.
    (topology.triangle_count() <= max_triangles(bytes.len())).then_some(bytes)
}

/// Most triangles a connectivity block of `bytes` bytes may hold: 4096 per byte (0.002 bits
/// per triangle; real meshes take 5–8 bits), plus 4096.
pub fn max_triangles(bytes: usize) -> usize {
    bytes.saturating_mul(4096).saturating_add(4096)
}

/// Refuses a block of `bytes` claiming more than [`max_triangles`] (both topology codings:
/// past its data the range decoder reads zeros).
pub(crate) fn check_density(bytes: &[u8], triangle_count: usize) -> Result<()> {
    if triangle_count > max_triangles(bytes.len()) {
        return Err(Error::malformed(
            CTX,
            FIELD,
            format!("{triangle_count} triangles from {} bytes (at most 4096 per byte)", bytes.len()),
        ));
    }
    Ok(())
}

/// The error for triangle `t` of a corrupt topology block.
pub(crate) fn bad_triangle(t: usize, what: String) -> Error {
    Error::malformed(CTX, FIELD, format!("triangle {t}: {what}"))
}

/// `base + delta` as a vertex index of triangle `t`, checked against `vertex_count`.
pub(crate) fn index_at(t: usize, base: u32, delta: i32, vertex_count: usize) -> Result<u32> {
    let i = base as i64 + delta as i64;
    if i < 0 || i >= vertex_count as i64 {
        return Err(bad_triangle(t, format!("index {i} out of range for {vertex_count} vertices")));
    }
    Ok(i as u32)
}

/// Inverse of [`encode`]: `triangle_count` triangles over `vertex_count` vertices, every
/// index and candidate choice checked (a corrupt block is an error naming the triangle,
/// never a panic). The caller has checked both counts and [`decoder_bytes`] against its
/// limits. More than [`max_triangles`] for the block's size is refused up front: past its
/// data the range decoder reads zeros, so a tiny block could otherwise claim any count.
pub fn decode(bytes: &[u8], vertex_count: usize, triangle_count: usize) -> Result<Topology> {
    check_density(bytes, triangle_count)?;
    let mut dec = AdaptiveDecoder::new(bytes, CLASSES, CTX, FIELD)?;
    let bad = bad_triangle;
    let index = |t: usize, base: u32, delta: i32| index_at(t, base, delta, vertex_count);
    let pick = |t: usize, cand: &[u32], code: i32, what: &str| -> Result<Option<u32>> {
        match code {
            0 => Ok(None),
            k if k > 0 && (k as usize) <= cand.len() => Ok(Some(cand[k as usize - 1])),
            k => Err(bad(t, format!("{what} candidate {k} of {}", cand.len()))),
        }
    };
    let mut triangles = Vec::with_capacity(triangle_count);
    let mut known = Neighbours::new();
    let mut cand = Vec::new();
    let (mut prev_a, mut prev_c, mut prev_same) = (0u32, None::<u32>, false);
    for t in 0..triangle_count {
        let da = dec.decode(Class::FirstDelta as usize, usize::from(prev_same))?;
        let a = index(t, prev_a, da)?;
        let same = da == 0 && prev_c.is_some();
        let fan = match (same, prev_c) {
            (true, Some(pc)) => match dec.decode(Class::Fan as usize, 0)? {
                0 => None,
                1 => Some(pc),
                k => return Err(bad(t, format!("fan flag {k}"))),
            },
            _ => None,
        };
        let b = match fan {
            Some(b) => b,
            None => {
                let strong = known.second(a, &mut cand);
                let hit = if cand.is_empty() {
                    None
                } else {
                    let code = dec.decode(Class::SecondIndex as usize, candidate_bucket(strong, cand.len()))?;
                    pick(t, &cand, code, "second index")?
                };
                match hit {
                    Some(b) => b,
                    None => index(t, a, dec.decode(Class::SecondDelta as usize, usize::from(same))?)?,
                }
            }
        };
        let common = known.third(a, b, &mut cand);
        let hit = if cand.is_empty() {
            None
        } else {
            let code = dec.decode(Class::ThirdIndex as usize, candidate_bucket(common, cand.len()))?;
            pick(t, &cand, code, "third index")?
        };
        let c = match hit {
            Some(c) => c,
            None => index(t, b, dec.decode(Class::ThirdDelta as usize, usize::from(fan.is_some()))?)?,
        };
        known.add([a, b, c]);
        triangles.push([a, b, c]);
        prev_same = da == 0;
        prev_a = a;
        prev_c = Some(c);
    }
    Topology::new(vertex_count, triangles).map_err(|e| Error::malformed(CTX, FIELD, e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: u32) -> Topology {
        crate::synth::flag_topology(n as usize, n as usize)
    }

    /// A deterministic shuffle (xorshift) of triangle order and rotation.
    fn scrambled(topo: &Topology, seed: u64) -> Topology {
        let mut s = seed | 1;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        let mut tris = topo.triangles().to_vec();
        for i in (1..tris.len()).rev() {
            let j = (next() % (i as u64 + 1)) as usize;
            tris.swap(i, j);
        }
        for t in &mut tris {
            t.rotate_left((next() % 3) as usize);
        }
        Topology::new(topo.vertex_count(), tris).unwrap()
    }

    fn roundtrip(topo: &Topology) -> usize {
        let bytes = encode(topo).expect("fits");
        let back = decode(&bytes, topo.vertex_count(), topo.triangle_count()).unwrap();
        assert_eq!(&back, topo);
        bytes.len()
    }

    #[test]
    fn any_order_roundtrips_exactly() {
        let g = grid(20);
        roundtrip(&g);
        roundtrip(&scrambled(&g, 7));
        // Degenerate, repeated and reversed triangles, and an empty list.
        let odd = Topology::new(5, vec![[0, 0, 1], [1, 0, 0], [2, 3, 4], [2, 3, 4], [4, 3, 2], [3, 3, 3]]).unwrap();
        roundtrip(&odd);
        roundtrip(&canonical_order(&odd));
        roundtrip(&Topology::new(3, Vec::new()).unwrap());
    }

    #[test]
    fn canonical_order_keeps_each_oriented_triangle_and_is_idempotent() {
        let g = scrambled(&grid(15), 3);
        let c = canonical_order(&g);
        assert_eq!(canonical_order(&c), c);
        assert_eq!(canonical_order(&scrambled(&g, 11)), c, "independent of the input order and rotations");
        let key = |t: &[u32; 3]| *[[t[0], t[1], t[2]], [t[1], t[2], t[0]], [t[2], t[0], t[1]]].iter().min().unwrap();
        let mut a: Vec<_> = g.triangles().iter().map(key).collect();
        let mut b: Vec<_> = c.triangles().iter().map(key).collect();
        a.sort_unstable();
        b.sort_unstable();
        assert_eq!(a, b, "same triangles with the same orientation");
        assert!(c.triangles().iter().all(|t| t[0] <= t[1] && t[0] <= t[2]));
        assert!(same_triangles(&g, &c));
        let mut flipped = c.triangles().to_vec();
        flipped[0].swap(1, 2);
        assert!(!same_triangles(&g, &Topology::new(c.vertex_count(), flipped).unwrap()), "orientation counts");
    }

    #[test]
    fn canonical_order_codes_small() {
        // A 40 × 40 grid: 3042 triangles. Version 1's coding as reference.
        let g = scrambled(&grid(40), 5);
        let v1 = crate::container::encode_topology_list(&g).len();
        let compact = roundtrip(&canonical_order(&g));
        let bits = compact as f64 * 8.0 / g.triangle_count() as f64;
        assert!(bits < 4.0, "{bits:.2} bits per triangle");
        assert!(compact * 3 < v1, "{compact} bytes vs version 1's {v1}");
    }

    #[test]
    fn corrupt_blocks_are_errors_not_panics() {
        let g = canonical_order(&grid(12));
        let bytes = encode(&g).unwrap();
        // Every truncation (whole words) and a few bit flips: an error or a different valid
        // topology, never a panic; declaring more triangles than coded never panics either.
        for cut in (0..bytes.len()).step_by(4) {
            let _ = decode(&bytes[..cut], g.vertex_count(), g.triangle_count());
        }
        for i in 0..bytes.len() {
            let mut b = bytes.clone();
            b[i] ^= 0x5a;
            let _ = decode(&b, g.vertex_count(), g.triangle_count());
        }
        let _ = decode(&bytes, g.vertex_count(), g.triangle_count() * 3);
        assert!(decode(&bytes[..3], g.vertex_count(), 1).is_err(), "not whole words");
        // An empty block cannot claim millions of triangles.
        let e = decode(&[], g.vertex_count(), 5_000_000).unwrap_err().to_string();
        assert!(e.contains("at most 4096 per byte"), "{e}");
        // A declared vertex count far above the indices used allocates nothing for it.
        let huge = Topology::new(u32::MAX as usize, g.triangles().to_vec()).unwrap();
        let b = encode(&huge).unwrap();
        assert_eq!(decode(&b, huge.vertex_count(), huge.triangle_count()).unwrap(), huge);
        // Fewer vertices than the indices need: named error.
        let e = decode(&bytes, 10, g.triangle_count()).unwrap_err().to_string();
        assert!(e.contains("topology") && e.contains("out of range"), "{e}");
    }
}
