//! Rate-distortion quantization: one step per component by the equal-slope (Lagrangian) rule.
//!
//! Each component (a factor column, a core slice, a coefficient stream) offers candidate
//! operating points — typically a geometric grid of steps ([`step_grid`]) plus "drop it" —
//! each with its *measured* rate (bits, e.g. from [`super::adaptive::CostModel`]) and
//! distortion (squared error in the output's units, i.e. already multiplied by the
//! component's gain²). Minimising total rate subject to total distortion `≤ D` is solved by
//! minimising `D_i + λ·R_i` per component for one common `λ` (Everett's theorem; Shoham &
//! Gersho 1988): every component then works at the same slope `−dD/dR = λ`. [`allocate`]
//! bisects `λ` for the largest total distortion within the target; only points on each
//! component's lower convex hull can be chosen, which the per-component minimisation
//! handles by itself.
//!
//! Compared with one rule-of-thumb step per component (equal distortion everywhere), this
//! gives fewer bits to components whose bits buy little (noisy, poorly predicted ones) and
//! drops components whose energy is below the water level (reverse water-filling).

/// One candidate operating point of a component.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RdPoint {
    /// Estimated bits.
    pub rate: f64,
    /// Squared error it leaves, in output units.
    pub distortion: f64,
}

/// Result of [`allocate`].
#[derive(Debug, Clone, PartialEq)]
pub struct Allocation {
    /// Chosen point index per component.
    pub choice: Vec<usize>,
    /// The slope `λ` (distortion per bit) of the choice.
    pub lambda: f64,
    /// Total rate of the choice.
    pub rate: f64,
    /// Total distortion of the choice.
    pub distortion: f64,
}

/// Smallest step a component of largest magnitude `max_abs` is given: `2^-28` of its range
/// (codes stay far inside the coders' 2^30), and never zero.
pub fn step_floor(max_abs: f64) -> f64 {
    max_abs * 2f64.powi(-28) + 1e-300
}

/// A step as streams store it: rounded to `f32`, never below `floor`; `f32::MAX` when the
/// rounding overflows.
pub fn stored_step(step: f64, floor: f64) -> f64 {
    let s = step.max(floor) as f32;
    if s.is_finite() && s > 0.0 {
        s as f64
    } else {
        f32::MAX as f64
    }
}

/// `count` steps from `largest` down by `2^(−1/per_octave)` each.
pub fn step_grid(largest: f64, count: usize, per_octave: usize) -> Vec<f64> {
    (0..count).map(|j| largest * (-(j as f64) / per_octave.max(1) as f64).exp2()).collect()
}

fn choose(components: &[Vec<RdPoint>], lambda: f64) -> (Vec<usize>, f64, f64) {
    let mut choice = Vec::with_capacity(components.len());
    let (mut rate, mut distortion) = (0.0, 0.0);
    for points in components {
        let mut best = 0;
        let mut best_cost = f64::INFINITY;
        for (i, p) in points.iter().enumerate() {
            let cost = p.distortion + lambda * p.rate;
            // Ties go to the smaller rate, so the choice is deterministic.
            if cost < best_cost || (cost == best_cost && p.rate < points[best].rate) {
                best = i;
                best_cost = cost;
            }
        }
        if let Some(p) = points.get(best) {
            rate += p.rate;
            distortion += p.distortion;
        }
        choice.push(best);
    }
    (choice, rate, distortion)
}

/// The equal-slope allocation with total distortion at most `target` (or, when even the
/// finest points exceed it, the finest points). Components without points get index 0.
pub fn allocate(components: &[Vec<RdPoint>], target: f64) -> Allocation {
    // λ = 0 picks the least distortion; a huge λ the least rate.
    let (choice0, rate0, dist0) = choose(components, 0.0);
    if dist0 >= target {
        return Allocation { choice: choice0, lambda: 0.0, rate: rate0, distortion: dist0 };
    }
    let total_rate: f64 = components.iter().flat_map(|c| c.iter().map(|p| p.rate)).fold(0.0, f64::max);
    let total_dist: f64 = components.iter().map(|c| c.iter().map(|p| p.distortion).fold(0.0, f64::max)).sum();
    let mut hi = (total_dist / total_rate.max(1e-12)).max(1e-300) * 4.0;
    let (c, r, d) = choose(components, hi);
    if d <= target {
        return Allocation { choice: c, lambda: hi, rate: r, distortion: d };
    }
    let mut lo = 0.0f64;
    let mut best = Allocation { choice: choice0, lambda: 0.0, rate: rate0, distortion: dist0 };
    // Bisection in log space once lo > 0; 60 halvings reach f64 resolution.
    for _ in 0..60 {
        let mid = if lo > 0.0 { (lo * hi).sqrt() } else { hi * 1e-12 };
        let (c, r, d) = choose(components, mid);
        if d <= target {
            if r <= best.rate {
                best = Allocation { choice: c, lambda: mid, rate: r, distortion: d };
            }
            lo = mid;
        } else {
            hi = mid;
        }
        if lo > 0.0 && hi / lo < 1.0 + 1e-9 {
            break;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    /// High-rate model of a Gaussian-like component: D = g²σ²·2^(−2R/n) style points.
    fn component(scale: f64, n: f64) -> Vec<RdPoint> {
        let mut pts = vec![RdPoint { rate: 0.0, distortion: scale * n }];
        for step in step_grid(1.0, 24, 4) {
            let d = (n * step * step / 12.0).min(scale * n);
            let r = n * ((scale.sqrt() / step).log2() + 2.05).max(0.0);
            pts.push(RdPoint { rate: r, distortion: d });
        }
        pts
    }

    #[test]
    fn meets_the_target_and_beats_equal_distortion() {
        let comps: Vec<_> = [4.0, 1.0, 0.25, 0.01, 1e-4].iter().map(|&s| component(s, 1000.0)).collect();
        let target = 50.0;
        let a = allocate(&comps, target);
        assert!(a.distortion <= target);
        // Equal distortion per component (the rule of thumb): the finest point each component
        // needs to stay under target/5.
        let mut rate_equal = 0.0;
        for c in &comps {
            let p = c.iter().filter(|p| p.distortion <= target / 5.0).map(|p| p.rate).fold(f64::INFINITY, f64::min);
            rate_equal += p;
        }
        assert!(a.rate < rate_equal, "lagrangian {} vs equal-distortion {rate_equal}", a.rate);
        // The weakest component is below the water level: dropped.
        assert_eq!(comps[4][a.choice[4]].rate, 0.0);
        // Tighter targets cost more.
        let b = allocate(&comps, target / 4.0);
        assert!(b.rate > a.rate && b.distortion <= target / 4.0);
    }

    #[test]
    fn unreachable_target_gives_the_finest_points() {
        let comps = vec![component(1.0, 10.0)];
        let a = allocate(&comps, 0.0);
        let finest = comps[0].iter().map(|p| p.distortion).fold(f64::INFINITY, f64::min);
        assert_eq!(a.distortion, finest);
        assert_eq!(allocate(&[], 1.0).choice, Vec::<usize>::new());
    }
}
