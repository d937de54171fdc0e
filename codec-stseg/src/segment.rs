//! The spatio-temporal segmentation of §4.1–4.3 (its vertex clustering, §4.2, in [`crate::clustering`]) and the sequential driver of §4.5.
//!
//! Frames are handled as frame-major `f32` slices (`frames × vertices × 3`) whose frame 0 is
//! the first frame of the current (not yet coded) block.

use codec_core::{Animation, Result, Topology};
use faer::Mat;
use rayon::prelude::*;

use crate::clustering::cluster_vertices;
use crate::linalg::{double_center, gram, pcs_for_persistence, sym_eigvals_desc};
use crate::mesh::{frame_diagonal, MeshGraph, NEGLIGIBLE_AMPLITUDE};
use crate::params::{Centering, Detector, StsegParams};

/// How a block was cut, following the four cases of §4.5 / Fig. 2.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BlockKind {
    /// (I) The initial cut found no distinct behaviour in `gamma_init` frames: one group.
    NoCut = 1,
    /// (II) New vertex clustering; a temporal boundary was detected before `gamma_max`.
    Detected = 2,
    /// (III) New vertex clustering; no boundary within `gamma_max` frames.
    MaxLength = 3,
    /// (IV) The previous block's grouping was reused (the previous block was (III) or (IV)).
    Reused = 4,
}

impl BlockKind {
    /// The case number of §4.5 (1..=4).
    pub fn case(self) -> u8 {
        self as u8
    }
    pub(crate) fn from_case(c: u8) -> Option<Self> {
        Some(match c {
            1 => Self::NoCut,
            2 => Self::Detected,
            3 => Self::MaxLength,
            4 => Self::Reused,
            _ => return None,
        })
    }
}

/// One temporal segment (one packet) and its vertex grouping.
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    /// First frame of the segment.
    pub first_frame: usize,
    /// Number of frames.
    pub frame_count: usize,
    /// Which case of §4.5 produced it.
    pub kind: BlockKind,
    /// True when the segment ends at a boundary detected by a change in a group's number of
    /// principal components (Alg. 2); false when it ends at `gamma_init`, `gamma_max` or the
    /// end of the animation.
    pub detected_boundary: bool,
    /// Window length used by Alg. 2 (the initial-cut length `|τ_init|`), if a grouping was used.
    pub window: Option<usize>,
    /// Number of vertex groups.
    pub group_count: usize,
    /// Group label of every vertex (`0 .. group_count`).
    pub labels: Vec<u8>,
}

/// The segmentation of a whole animation, as the encoder makes it.
#[derive(Debug, Clone, PartialEq)]
pub struct Segmentation {
    /// Segments in frame order; they tile the animation.
    pub segments: Vec<Segment>,
}

impl Segmentation {
    /// First frames of every segment but the first (all temporal boundaries).
    pub fn boundaries(&self) -> Vec<usize> {
        self.segments.iter().skip(1).map(|s| s.first_frame).collect()
    }

    /// Boundaries detected by Alg. 2 (the frame after each segment with `detected_boundary`).
    pub fn detected_boundaries(&self) -> Vec<usize> {
        self.segments.iter().filter(|s| s.detected_boundary).map(|s| s.first_frame + s.frame_count).collect()
    }

    /// The segmentation as JSON: `{"segments": [{"first_frame", "frame_count", "case",
    /// "detected_boundary", "window", "group_count", "labels": [...]}, ...],
    /// "boundaries": [...], "detected_boundaries": [...]}`.
    pub fn to_json(&self) -> String {
        let list = |v: &[usize]| v.iter().map(|b| b.to_string()).collect::<Vec<_>>().join(",");
        let segs: Vec<String> = self
            .segments
            .iter()
            .map(|s| {
                format!(
                    "{{\"first_frame\":{},\"frame_count\":{},\"case\":{},\"detected_boundary\":{},\"window\":{},\
                     \"group_count\":{},\"labels\":[{}]}}",
                    s.first_frame,
                    s.frame_count,
                    s.kind.case(),
                    s.detected_boundary,
                    s.window.map_or("null".to_string(), |w| w.to_string()),
                    s.group_count,
                    s.labels.iter().map(|l| l.to_string()).collect::<Vec<_>>().join(",")
                )
            })
            .collect();
        format!(
            "{{\"segments\":[{}],\"boundaries\":[{}],\"detected_boundaries\":[{}]}}",
            segs.join(","),
            list(&self.boundaries()),
            list(&self.detected_boundaries())
        )
    }
}

/// Runs the encoder's segmentation (§4.1–4.3, §4.5) over a whole animation: per-vertex
/// group labels and temporal boundaries, exactly as [`crate::Stseg`] codes them.
pub fn segment_animation(animation: &Animation, params: &StsegParams) -> Result<Segmentation> {
    params.validate()?;
    let mut seg = Segmenter::new(*params, animation.topology());
    let n3 = animation.vertex_count() * 3;
    let total = animation.frame_count();
    let mut start = 0;
    let mut segments = Vec::new();
    while start < total {
        let rest = &animation.positions()[start * n3..];
        let s = seg.next(rest, total - start, start)?.expect("all frames are available");
        start += s.frame_count;
        segments.push(s);
    }
    Ok(Segmentation { segments })
}

/// A reusable vertex grouping (kept across blocks in cases III/IV).
#[derive(Debug, Clone)]
struct Grouping {
    labels: Vec<u8>,
    group_count: usize,
    window: usize,
}

/// The sequential segmentation state machine of §4.5.
pub(crate) struct Segmenter {
    params: StsegParams,
    graph: MeshGraph,
    grouping: Option<Grouping>,
}

impl Segmenter {
    pub fn new(params: StsegParams, topology: &Topology) -> Self {
        Self { params, graph: MeshGraph::new(topology), grouping: None }
    }

    /// Decides the next segment from the buffered frames (`buf`, starting at the first
    /// uncoded frame, absolute index `first_frame`) when `remaining` frames are still to come
    /// in total. Returns `None` when more frames are needed: the decision always looks at
    /// exactly `min(gamma_max, remaining)` frames, so it never depends on how frames arrive.
    pub fn next(&mut self, buf: &[f32], remaining: usize, first_frame: usize) -> Result<Option<Segment>> {
        let v = self.graph.vertex_count();
        let n3 = v * 3;
        let buffered = buf.len() / n3;
        let p = self.params;
        let need = (p.gamma_max as usize).min(remaining);
        if buffered < need || need == 0 {
            return Ok(None);
        }
        let frames = &buf[..need * n3];
        let scale = frame_diagonal(&frames[..n3]).max(f64::MIN_POSITIVE);
        // Beyond the paper: a cut anywhere in the block ends the segment (`Detector::Scan`).
        let cut = match p.detector {
            Detector::Scan => scan_cuts(frames, v, &p),
            Detector::Paper => None,
        };
        let (grouping, fresh) = match self.grouping.take() {
            Some(g) => (g, false),
            None if p.detector == Detector::Scan => {
                // Group on the segment's first γ_init frames (or up to the cut).
                let len = cut.unwrap_or(need).min(p.gamma_init as usize).max(1);
                let (labels, group_count) = cluster_vertices(&self.graph, &frames[..len * n3], &p)?;
                (Grouping { labels, group_count, window: len }, true)
            }
            None => {
                let n_cut = (p.gamma_init as usize).min(need);
                match initial_cut(&frames[..n_cut * n3], v, p.w as usize, p.lambda, p.cut_threshold) {
                    None => {
                        // Case (I): the whole initial range goes to the compressor as one group.
                        return Ok(Some(Segment {
                            first_frame,
                            frame_count: n_cut,
                            kind: BlockKind::NoCut,
                            detected_boundary: false,
                            window: None,
                            group_count: 1,
                            labels: vec![0; v],
                        }));
                    }
                    Some(window) => {
                        let (labels, group_count) = cluster_vertices(&self.graph, &frames[..window * n3], &p)?;
                        (Grouping { labels, group_count, window }, true)
                    }
                }
            }
        };
        let change = temporal_segmentation(frames, &grouping, p.omega_seg, p.seg_centering, scale)?;
        let (frame_count, detected) = match (cut, change) {
            (Some(a), Some(b)) => (a.min(b), true),
            (Some(b), None) | (None, Some(b)) => (b, true),
            (None, None) => (need, false),
        };
        let kind = match (fresh, detected) {
            (false, _) => BlockKind::Reused,
            (true, true) => BlockKind::Detected,
            (true, false) => BlockKind::MaxLength,
        };
        let seg = Segment {
            first_frame,
            frame_count,
            kind,
            detected_boundary: detected,
            window: Some(grouping.window),
            group_count: grouping.group_count,
            labels: grouping.labels.clone(),
        };
        // §4.5: after a detected boundary everything is recomputed; otherwise the grouping is
        // reused for the next block (case IV).
        if !detected {
            self.grouping = Some(grouping);
        }
        Ok(Some(seg))
    }
}

/// Initial temporal cut (§4.1, Eq. 2–3) over `frames` (n frames). Returns `|τ_init| = b + w`,
/// or `None` when no distinct behaviour is found (case I).
///
/// Window `i` is the trajectory of every vertex over frames `i .. i + w`, taken relative to
/// its first frame (so windows compare motion, not where the mesh happens to be). The kernel
/// of Eq. 3 is `exp(−λ·d²/s)` with `s` the median pairwise squared distance (so `λ` does not
/// depend on the mesh scale). The score is the maximum-mean-discrepancy estimate
/// `H1 − 2·H2 + H3` with within-side averages over distinct pairs; the best split must exceed
/// `threshold` to count as a cut.
pub(crate) fn initial_cut(frames: &[f32], v: usize, w: usize, lambda: f64, threshold: f64) -> Option<usize> {
    let n = frames.len() / (v * 3);
    if n < w + 4 {
        return None;
    }
    let (nw, d2) = window_distances(frames, v, w);
    let s = median_scale(&d2, nw, 0, nw)?;
    let (b, mmd) = best_split(&d2, nw, 0, nw, s, lambda, 2, nw - 2)?;
    (mmd > threshold).then_some(b + w)
}

/// Squared distances between the motion windows (Eq. 2's `v^{b_i → b_i+w}`, relative to
/// their first frame) of every window start in `frames`: `(nw, d2)` with `d2` row-major `nw×nw`.
fn window_distances(frames: &[f32], v: usize, w: usize) -> (usize, Vec<f64>) {
    let n3 = v * 3;
    let n = frames.len() / n3;
    let nw = (n + 1).saturating_sub(w);
    let x = |t: usize, i: usize| frames[t * n3 + i] as f64;
    let mut d2 = vec![0.0f64; nw * nw];
    for i in 0..nw {
        for j in i + 1..nw {
            let mut s = 0.0;
            for k in 1..w {
                for c in 0..n3 {
                    let a = x(i + k, c) - x(i, c);
                    let b = x(j + k, c) - x(j, c);
                    s += (a - b) * (a - b);
                }
            }
            d2[i * nw + j] = s;
            d2[j * nw + i] = s;
        }
    }
    (nw, d2)
}

/// Median pairwise squared distance of windows `lo..hi` (the kernel scale `s`); the mean of the
/// positive ones when the median is 0; `None` when all are 0 (no motion change at all).
fn median_scale(d2: &[f64], nw: usize, lo: usize, hi: usize) -> Option<f64> {
    let mut off: Vec<f64> = (lo..hi).flat_map(|i| (i + 1..hi).map(move |j| d2[i * nw + j])).collect();
    off.sort_by(f64::total_cmp);
    if *off.last()? <= 0.0 {
        return None;
    }
    let s = off[off.len() / 2];
    if s > 0.0 {
        return Some(s);
    }
    let pos: Vec<f64> = off.iter().copied().filter(|&d| d > 0.0).collect();
    Some(pos.iter().sum::<f64>() / pos.len() as f64)
}

/// The split of windows `lo..hi` into `lo..lo+b` and `lo+b..hi` with the largest MMD
/// `H1 − 2·H2 + H3` (kernel `exp(−λ·d²/s)`), `b` within `b_min..=b_max`: `(b, mmd)`.
#[allow(clippy::too_many_arguments)]
fn best_split(
    d2: &[f64],
    nw: usize,
    lo: usize,
    hi: usize,
    s: f64,
    lambda: f64,
    b_min: usize,
    b_max: usize,
) -> Option<(usize, f64)> {
    let m = hi - lo;
    let k = |i: usize, j: usize| (-lambda * d2[(lo + i) * nw + lo + j] / s).exp();
    let mut best: Option<(usize, f64)> = None;
    for b in b_min.max(2)..=b_max.min(m.saturating_sub(2)) {
        let (n1, n2) = (b as f64, (m - b) as f64);
        let (mut h1, mut h2, mut h3) = (0.0, 0.0, 0.0);
        for i in 0..m {
            for j in 0..m {
                if i == j {
                    continue;
                }
                match (i < b, j < b) {
                    (true, true) => h1 += k(i, j),
                    (false, false) => h3 += k(i, j),
                    (true, false) => h2 += k(i, j),
                    (false, true) => {}
                }
            }
        }
        let mmd = h1 / (n1 * (n1 - 1.0)) - 2.0 * h2 / (n1 * n2) + h3 / (n2 * (n2 - 1.0));
        if best.is_none_or(|(_, bm)| mmd > bm) {
            best = Some((b, mmd));
        }
    }
    best
}

/// Beyond the paper ([`crate::Detector::Scan`]): the bi-directional cut of §4.1 run over the
/// whole block, in ranges of `gamma_init` frames stepping by half that, with one kernel scale
/// for the whole block (the median window distance of all `frames`, so a range in the middle
/// of steady motion does not look distinct just because its own distances are small). A cut
/// counts only with its split in the middle half of its range (an edge maximum is a trend,
/// and a change near an edge is central in the next range) and an MMD above `threshold`.
/// Returns the first cut's frame — the first window of the second side plus `w/2`, the middle
/// of the windows that straddle the change — if it is at least `w` frames in.
pub(crate) fn scan_cuts(frames: &[f32], v: usize, p: &StsegParams) -> Option<usize> {
    let n = frames.len() / (v * 3);
    let (w, gi) = (p.w as usize, p.gamma_init as usize);
    if n < w + 4 {
        return None;
    }
    let (nw, d2) = window_distances(frames, v, w);
    let s = median_scale(&d2, nw, 0, nw)?;
    let range = (gi + 1).saturating_sub(w).min(nw);
    let step = (gi / 2).max(1);
    let mut lo = 0;
    while lo + range <= nw {
        if let Some((b, mmd)) = best_split(&d2, nw, lo, lo + range, s, p.lambda, range / 4, range - range / 4) {
            let at = lo + b + w / 2;
            if mmd > p.cut_threshold && at >= w && at < n {
                return Some(at);
            }
        }
        if lo + range == nw {
            break;
        }
        lo = (lo + step).min(nw - range);
    }
    None
}

/// Temporal segmentation (§4.3, Alg. 2): slides a window of the initial-cut length `L` over
/// `frames`, starting right after the reference window `[0, L)` (Alg. 2 line 5), and returns
/// the first window start `i ≥ L` at which any group's number of principal components (at
/// persistence ω) differs from the reference window's, i.e. the boundary `b = i`.
/// `None` when the count never changes within `frames` (`gamma_max` reached). Groups are
/// independent and run in parallel; the earliest change wins, so the result does not depend
/// on scheduling.
fn temporal_segmentation(
    frames: &[f32],
    g: &Grouping,
    omega: f64,
    centering: Centering,
    scale: f64,
) -> Result<Option<usize>> {
    let v = g.labels.len();
    let n3 = v * 3;
    let n = frames.len() / n3;
    let win = g.window;
    if 2 * win > n {
        return Ok(None);
    }
    let per_group: Vec<Result<Option<usize>>> = (0..g.group_count)
        .into_par_iter()
        .map(|grp| {
            let verts: Vec<usize> = (0..v).filter(|&i| g.labels[i] as usize == grp).collect();
            if verts.is_empty() {
                return Ok(None);
            }
            // Rows: the group's coordinates. Row centring is invariant to a per-row shift and
            // frame centring to a global one: the shifts keep the Gram entries small. One Gram
            // matrix serves every window.
            let nr = verts.len() * 3;
            let c0 = verts.iter().flat_map(|&i| (0..3).map(move |c| frames[i * 3 + c] as f64)).sum::<f64>() / nr as f64;
            let x = Mat::from_fn(nr, n, |r, t| {
                let i = verts[r / 3] * 3 + r % 3;
                let x = frames[t * n3 + i] as f64;
                match centering {
                    Centering::Vertex => x - frames[i] as f64,
                    Centering::Frame => x - c0,
                    Centering::FrameAxis => x - frames[verts[0] * 3 + r % 3] as f64,
                    Centering::None => x,
                }
            });
            let full = gram(x.as_ref());
            let col_sum: Vec<f64> = (0..n).map(|t| (0..nr).map(|r| x[(r, t)]).sum()).collect();
            // Per axis: axis_sum[t·3 + c].
            let axis_sum: Vec<f64> =
                (0..n * 3).map(|tc| (0..verts.len()).map(|i| x[(i * 3 + tc % 3, tc / 3)]).sum()).collect();
            let negligible = (NEGLIGIBLE_AMPLITUDE * scale).powi(2) * (verts.len() * 3 * win) as f64;
            let count = |start: usize| -> Result<usize> {
                let mut w = full.submatrix(start, start, win, win).to_owned();
                match centering {
                    Centering::Vertex => double_center(&mut w),
                    // X̂ᵀX̂ = XᵀX − s·sᵀ/rows with s the column sums (per-frame mean removed).
                    Centering::Frame => {
                        for a in 0..win {
                            for b in 0..win {
                                w[(a, b)] -= col_sum[start + a] * col_sum[start + b] / nr as f64;
                            }
                        }
                    }
                    Centering::FrameAxis => {
                        let nv = verts.len() as f64;
                        for a in 0..win {
                            for b in 0..win {
                                w[(a, b)] -= (0..3)
                                    .map(|c| axis_sum[(start + a) * 3 + c] * axis_sum[(start + b) * 3 + c])
                                    .sum::<f64>()
                                    / nv;
                            }
                        }
                    }
                    Centering::None => {}
                }
                Ok(pcs_for_persistence(&sym_eigvals_desc(w.as_ref(), "window PCA")?, omega, negligible))
            };
            let reference = count(0)?;
            // Alg. 2 line 5: the scan starts right after the reference window.
            for i in win..=n.saturating_sub(win) {
                if count(i)? != reference {
                    return Ok(Some(i));
                }
            }
            Ok(None)
        })
        .collect();
    let mut best: Option<usize> = None;
    for r in per_group {
        if let Some(i) = r? {
            best = Some(best.map_or(i, |b| b.min(i)));
        }
    }
    Ok(best)
}
