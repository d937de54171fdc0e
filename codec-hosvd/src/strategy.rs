//! Choosing the truncation `(v, f)` for a requested space saving (§2.5–2.6, Eq. 12–13,
//! Alg. 3–4).

/// How `(v, f)` is chosen for a requested space saving.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Strategy {
    /// §2.6 diagonal: as many mode-1 as mode-3 components (`v = f`), no error evaluation.
    Diagonal,
    /// Alg. 4: sampled, shrinking search over the Alg. 3 list, assuming a unimodal error.
    Iterative,
    /// Every pair of the Alg. 3 list (the reference the other two are judged against).
    Exhaustive,
}

codec_core::param_choice!(Strategy { Diagonal = "diagonal", Iterative = "iterative", Exhaustive = "exhaustive" });

/// Dimensions of one tensor block and whether transforms are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dims {
    /// Vertices `K`.
    pub k: usize,
    /// Frames `F`.
    pub f: usize,
    /// Rigid/affine motion removal on (adds `12F` numbers, §2.5).
    pub rigid: bool,
}

impl Dims {
    /// Largest useful mode-1 rank, `min(K, 3F)`.
    pub fn max_v(&self) -> usize {
        self.k.min(3 * self.f)
    }
    /// Smallest mode-1 rank the rank searches consider, `min(3, max_v)`: below 3 every
    /// reconstructed frame is flat ([`candidates`]).
    pub fn min_v(&self) -> usize {
        3.min(self.max_v())
    }
    /// The model used when no candidate fits the budget: the smallest one that is not flat,
    /// `(min_v, 1)`.
    pub fn smallest(&self) -> (usize, usize) {
        (self.min_v().max(1), 1)
    }
    /// Largest useful mode-3 rank, `min(F, 3K)`.
    pub fn max_f(&self) -> usize {
        self.f.min(3 * self.k)
    }

    /// Numbers stored by the paper's size model, `S^(hosvd)/d_s` of §2.5 plus the `12F`
    /// transform numbers (§2.5: "it will be included in our results"):
    /// `v·K + J² + f·F + v·J·f (+ 12F)`.
    ///
    /// Eq. (12) as printed counts `f·F` twice; the `S^(hosvd)` formula just above it counts it
    /// once, which is what the stored operator needs, so that is what is used here.
    pub fn paper_numbers(&self, v: usize, f: usize) -> usize {
        v * self.k + 9 + f * self.f + 3 * v * f + if self.rigid { 12 * self.f } else { 0 }
    }

    /// Eq. (12): compression rate `CR = S^(hosvd) / S`.
    pub fn cr(&self, v: usize, f: usize) -> f64 {
        self.paper_numbers(v, f) as f64 / (3 * self.k * self.f) as f64
    }
}

/// Alg. 3: for every value of the mode with more candidates (`v` when `K > F`, else `f`), the
/// largest partner with `Ψ(v, f) ≤ λ` (λ = `1 − ss`), sorted along that mode. Pairs dominated by
/// a neighbour (same partner, smaller own rank — they occur once the partner hits its rank
/// limit) are dropped, so the list is the Pareto front of the size budget.
///
/// Choice left open by the paper: it keeps the pair with `|Ψ − λ|` minimal within a margin δ,
/// which may overshoot the budget; here the budget is never exceeded (δ = 0, one-sided).
///
/// Not in the paper: `v` starts at [`Dims::min_v`] (3), because with fewer mode-1 components
/// every frame of the reconstruction is flat (its `K × 3` coordinates have rank `v`: a plane
/// through the origin, or a line). Such a model is never worth its bytes — on
/// chicken-crossing `ss = 0.998` chose one at KG 63 / STED 0.21 where `(3, 1)`, a single
/// shape moved by the per-frame transforms, gives KG 34 / STED 0.089 for 40% more bytes.
pub fn candidates(d: Dims, ss: f64) -> Vec<(usize, usize)> {
    let lambda = 1.0 - ss;
    let (vmax, fmax) = (d.max_v(), d.max_f());
    let vmin = d.min_v();
    let mut list = Vec::new();
    if d.k > d.f {
        for v in vmin..=vmax {
            // Ψ grows with f: the largest feasible f by scanning down is O(F) per v; fine at
            // these sizes and exact.
            if let Some(f) = (1..=fmax).rev().find(|&f| d.cr(v, f) <= lambda) {
                list.push((v, f));
            }
        }
        list.dedup_by(|next, prev| {
            next.1 == prev.1 && {
                *prev = *next;
                true
            }
        });
    } else {
        for f in 1..=fmax {
            if let Some(v) = (vmin..=vmax).rev().find(|&v| d.cr(v, f) <= lambda) {
                list.push((v, f));
            }
        }
        list.dedup_by(|next, prev| {
            next.0 == prev.0 && {
                *prev = *next;
                true
            }
        });
    }
    list
}

/// Result of a rank search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Choice {
    /// Mode-1 rank.
    pub v: usize,
    /// Mode-3 rank.
    pub f: usize,
    /// Error evaluations spent.
    pub evaluations: usize,
    /// True when no pair meets the budget and the smallest model `(1, 1)` was used.
    pub over_budget: bool,
}

/// §2.6 diagonal strategy: the largest `n` with `(v, f) = (n, n)` inside the budget (each capped
/// at its rank limit); if one mode hits its limit first, the other takes the remaining budget.
pub fn diagonal(d: Dims, ss: f64) -> Choice {
    let lambda = 1.0 - ss;
    let (vmax, fmax) = (d.max_v(), d.max_f());
    let fits = |v: usize, f: usize| d.cr(v, f) <= lambda;
    if !fits(1, 1) {
        return Choice { v: 1, f: 1, evaluations: 0, over_budget: true };
    }
    let mut n = 1;
    while n < vmax.max(fmax) && fits((n + 1).min(vmax), (n + 1).min(fmax)) {
        n += 1;
    }
    let (mut v, mut f) = (n.min(vmax), n.min(fmax));
    while v < vmax && fits(v + 1, f) {
        v += 1;
    }
    while f < fmax && fits(v, f + 1) {
        f += 1;
    }
    Choice { v, f, evaluations: 0, over_budget: false }
}

/// Alg. 4 (FindMinimum): evaluate `samples` uniformly spaced entries of the list, then recurse
/// on the span between the neighbours of the best one, `depth` times at most (or until the span
/// holds no more than `samples` entries, which are then all evaluated). `error` is called at
/// most once per entry.
pub fn iterative(
    list: &[(usize, usize)],
    samples: usize,
    depth: usize,
    mut error: impl FnMut(usize, usize) -> f64,
) -> Choice {
    if list.is_empty() {
        return Choice { v: 1, f: 1, evaluations: 0, over_budget: true };
    }
    let samples = samples.max(3);
    let mut cache: Vec<Option<f64>> = vec![None; list.len()];
    let mut evaluations = 0;
    let mut eval = |i: usize, cache: &mut Vec<Option<f64>>| -> f64 {
        *cache[i].get_or_insert_with(|| {
            evaluations += 1;
            error(list[i].0, list[i].1)
        })
    };
    let (mut lo, mut hi) = (0usize, list.len() - 1);
    let mut best = 0usize;
    for level in 0..depth.max(1) {
        let indices: Vec<usize> = if hi - lo < samples {
            (lo..=hi).collect()
        } else {
            let mut ix: Vec<usize> = (0..samples)
                .map(|s| lo + ((hi - lo) as f64 * s as f64 / (samples - 1) as f64).round() as usize)
                .collect();
            ix.dedup();
            ix
        };
        let errors: Vec<f64> = indices.iter().map(|&i| eval(i, &mut cache)).collect();
        // Ties go to the first (smaller own rank) entry, deterministically.
        let imin = (0..errors.len()).fold(0, |b, i| if errors[i] < errors[b] { i } else { b });
        best = indices[imin];
        if indices.len() == hi - lo + 1 || level + 1 == depth {
            break;
        }
        lo = indices[imin.saturating_sub(1)];
        hi = indices[(imin + 1).min(indices.len() - 1)];
    }
    Choice { v: list[best].0, f: list[best].1, evaluations, over_budget: false }
}

/// Every entry of the list; the best one.
pub fn exhaustive(list: &[(usize, usize)], mut error: impl FnMut(usize, usize) -> f64) -> Choice {
    if list.is_empty() {
        return Choice { v: 1, f: 1, evaluations: 0, over_budget: true };
    }
    let errors: Vec<f64> = list.iter().map(|&(v, f)| error(v, f)).collect();
    let best = (0..errors.len()).fold(0, |b, i| if errors[i] < errors[b] { i } else { b });
    Choice { v: list[best].0, f: list[best].1, evaluations: list.len(), over_budget: false }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn candidates_fit_the_budget_and_are_a_pareto_front() {
        for (k, f, rigid) in [(500, 40, true), (30, 200, false), (100, 100, true)] {
            let d = Dims { k, f, rigid };
            for ss in [0.5, 0.9, 0.97] {
                let list = candidates(d, ss);
                // Empty exactly when even the smallest model that is not flat is over budget.
                let (v0, f0) = d.smallest();
                assert_eq!(list.is_empty(), d.cr(v0, f0) > 1.0 - ss, "{k}x{f} ss {ss}");
                for w in list.windows(2) {
                    assert!(w[0] != w[1]);
                    // Along the list one rank grows and the other shrinks: no pair dominates.
                    assert!((w[0].0 < w[1].0 && w[0].1 > w[1].1) || (w[0].1 < w[1].1 && w[0].0 > w[1].0), "{w:?}");
                }
                for &(v, ff) in &list {
                    assert!(d.cr(v, ff) <= 1.0 - ss);
                    assert!(v >= d.min_v(), "{v}: a flat model");
                    assert!(v <= d.max_v() && ff <= d.max_f());
                    // Maximal: one more of either rank breaks the budget or the rank limit.
                    assert!(
                        v == d.max_v() || d.cr(v + 1, ff) > 1.0 - ss || ff == d.max_f() || d.cr(v, ff + 1) > 1.0 - ss
                    );
                }
            }
        }
    }

    #[test]
    fn diagonal_is_balanced_and_within_budget() {
        let d = Dims { k: 1000, f: 100, rigid: true };
        let c = diagonal(d, 0.95);
        assert!(d.cr(c.v, c.f) <= 0.05);
        assert!(!(d.cr(c.v + 1, c.f) <= 0.05 && c.v < d.max_v()));
        assert!(c.v.abs_diff(c.f) <= 1 || c.f == d.max_f() || c.v == d.max_v(), "{c:?}");
        let tiny = diagonal(Dims { k: 10, f: 10, rigid: true }, 0.999);
        assert!(tiny.over_budget && (tiny.v, tiny.f) == (1, 1));
    }

    #[test]
    fn iterative_finds_the_minimum_of_a_unimodal_error_with_fewer_evaluations() {
        let list: Vec<(usize, usize)> = (1..=300).map(|v| (v, 301 - v)).collect();
        let err = |v: usize, _f: usize| (v as f64 - 187.0).powi(2) + 1.0;
        let ex = exhaustive(&list, err);
        let it = iterative(&list, 5, 12, err);
        assert_eq!((ex.v, it.v), (187, 187));
        assert!(it.evaluations < ex.evaluations / 5, "{} vs {}", it.evaluations, ex.evaluations);
        // Depth 1 only samples: the result is one of the samples, never better than exhaustive.
        let coarse = iterative(&list, 5, 1, err);
        assert!(err(coarse.v, coarse.f) >= err(ex.v, ex.f) && coarse.evaluations == 5);
    }
}
