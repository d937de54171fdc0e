#!/usr/bin/env python3
"""Independent numpy re-computation of the metrics crate's results (a dev aid, not a test).

Usage:
    target/release/examples/metric_timing PREFIX --dump DIR
    python3 metrics/tools/check_metrics.py DIR [--hausdorff-frames N]

Reads DIR/reference.f32, DIR/candidate.f32, DIR/triangles.u32 and DIR/results.json (written
by the example), recomputes every metric here with numpy in float64, written from the formulas
in metrics/README.md rather than from the Rust code (different loop structure: STED per vertex
vectorised over frames and the reference speed window from cumulative sums, point-triangle distance by plane projection + barycentric test +
edge fallback instead of Voronoi regions), and prints the differences.
"""
import argparse
import json
import sys
from collections import deque

import numpy as np


def load(d):
    res = json.load(open(f"{d}/results.json"))
    V, F, T = res["vertex_count"], res["frame_count"], res["triangle_count"]
    A = np.fromfile(f"{d}/reference.f32", dtype="<f4").astype(np.float64).reshape(F, V, 3)
    B = np.fromfile(f"{d}/candidate.f32", dtype="<f4").astype(np.float64).reshape(F, V, 3)
    tris = np.fromfile(f"{d}/triangles.u32", dtype="<u4").astype(np.int64).reshape(T, 3)
    return res, A, B, tris


def rel_diff(a, b):
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    scale = np.maximum(np.abs(b), 1e-300)
    return float(np.max(np.abs(a - b) / scale))


def point_triangle_dist(P, tri):
    """Distances from points P (m,3) to triangles tri (T,3,3): (m,T) array."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    n = np.cross(b - a, c - a)
    nn = np.einsum("ij,ij->i", n, n)
    ok = nn > 0
    nhat = np.where(ok[:, None], n / np.sqrt(np.where(ok, nn, 1.0))[:, None], 0.0)
    ap = P[:, None, :] - a[None]
    h = np.einsum("mtk,tk->mt", ap, nhat)
    proj = P[:, None, :] - h[..., None] * nhat[None]
    # Barycentric coordinates of the projection (Cramer's rule on the edge vectors).
    v0, v1 = b - a, c - a
    v2 = proj - a[None]
    d00 = np.einsum("ij,ij->i", v0, v0)
    d01 = np.einsum("ij,ij->i", v0, v1)
    d11 = np.einsum("ij,ij->i", v1, v1)
    d20 = np.einsum("mtk,tk->mt", v2, v0)
    d21 = np.einsum("mtk,tk->mt", v2, v1)
    den = d00 * d11 - d01 * d01
    den = np.where(den != 0, den, 1.0)
    bv = (d11 * d20 - d01 * d21) / den
    bw = (d00 * d21 - d01 * d20) / den
    inside = ok[None] & (bv >= 0) & (bw >= 0) & (bv + bw <= 1)
    best = np.where(inside, np.abs(h), np.inf)

    def seg(p0, p1):
        u = p1 - p0
        uu = np.einsum("ij,ij->i", u, u)
        t = np.einsum("mtk,tk->mt", P[:, None, :] - p0[None], u) / np.where(uu > 0, uu, 1.0)
        t = np.clip(np.where(uu > 0, t, 0.0), 0.0, 1.0)
        q = p0[None] + t[..., None] * u[None]
        return np.linalg.norm(P[:, None, :] - q, axis=2)

    return np.minimum(best, np.minimum(seg(a, b), np.minimum(seg(b, c), seg(c, a))))


def vertex_to_surface(P, X, tris, chunk=48):
    tri = X[tris]
    out = np.empty(len(P))
    for s in range(0, len(P), chunk):
        out[s : s + chunk] = point_triangle_dist(P[s : s + chunk], tri).min(axis=1)
    return out


def neighbourhood_edges(V, edges, radius):
    adj = [[] for _ in range(V)]
    for e, (i, j) in enumerate(edges):
        adj[i].append((j, e))
        adj[j].append((i, e))
    hoods = []
    for v in range(V):
        dist = {v: 0}
        q = deque([v])
        while q:
            u = q.popleft()
            if dist[u] == radius:
                continue
            for w, _ in adj[u]:
                if w not in dist:
                    dist[w] = dist[u] + 1
                    q.append(w)
        # Every edge with at least one endpoint in the ring set R(v).
        hoods.append(np.array(sorted({e for u in dist for w, e in adj[u]}), dtype=np.int64))
    return hoods


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--hausdorff-frames", type=int, default=1)
    args = ap.parse_args()
    res, A, B, tris = load(args.dir)
    rep = res["report"]
    sp = rep["sted_params"]
    F, V, _ = A.shape
    rows = []

    # KG: centroid of each reference frame, never of the candidate.
    cen = A.mean(axis=1, keepdims=True)
    kg = 100 * np.sqrt(((A - B) ** 2).sum() / ((A - cen) ** 2).sum())
    rows.append(("kg", kg, rep["kg"]))

    d2 = ((A - B) ** 2).sum(axis=2)
    diag = np.linalg.norm(A.reshape(-1, 3).max(0) - A.reshape(-1, 3).min(0))
    mse = d2.mean()
    rows += [
        ("mse", mse, rep["mse"]),
        ("rmse", np.sqrt(mse), rep["rmse"]),
        ("mse_relative", mse / diag**2, rep["mse_relative"]),
        ("rmse_relative", np.sqrt(mse) / diag, rep["rmse_relative"]),
        ("max_error", np.sqrt(d2.max()), rep["max_error"]),
        ("bbox_diagonal", diag, rep["bbox_diagonal"]),
    ]
    vec_rows = [
        ("frame_rmse[]", np.sqrt(d2.mean(axis=1)), res["frame_rmse"]),
        ("per_vertex_rms[]", np.sqrt(d2.mean(axis=0)), res["per_vertex_rms"]),
        ("per_vertex_max[]", np.sqrt(d2.max(axis=0)), res["per_vertex_max"]),
    ]

    # STED.
    e = np.sort(tris[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    e = e[e[:, 0] != e[:, 1]]
    edges = np.unique(e, axis=0)
    hoods = neighbourhood_edges(V, edges, sp["ring_radius"])
    la = np.linalg.norm(A[:, edges[:, 0]] - A[:, edges[:, 1]], axis=2)  # (F, E)
    lb = np.linalg.norm(B[:, edges[:, 0]] - B[:, edges[:, 1]], axis=2)
    with np.errstate(divide="ignore", invalid="ignore"):
        ed = np.where(la > 0, (la - lb) / la, 0.0)
    if sp["spatial_difference"] == "absolute":
        ed = np.abs(ed)
    # Vertices whose neighbourhood has no positive length count as 0.
    sig = np.zeros((F, V))
    for v in range(V):
        h = hoods[v]
        if len(h) == 0:
            continue
        w, d = la[:, h], ed[:, h]
        W = w.sum(axis=1)
        good = W > 0
        mu = (w * d).sum(axis=1) / np.where(good, W, 1)
        var = (w * (d - mu[:, None]) ** 2).sum(axis=1) / np.where(good, W, 1)
        sig[good, v] = np.sqrt(np.maximum(var[good], 0))
    sted_s = sig.mean()
    # Temporal: unit D = diameter of reference frame 0 (brute force over all pairs, chunked).
    P0 = A[0]
    D = 0.0
    for s0 in range(0, V, 1024):
        D = max(D, float(((P0[s0 : s0 + 1024, None, :] - P0[None, :, :]) ** 2).sum(-1).max()))
    D = np.sqrt(D)
    if F > 1 and D > 0:
        k = sp["speed_window"]
        ell = np.sqrt(((A[1:] - A[:-1]) ** 2).sum(axis=2) / D**2 + sp["dt"] ** 2)  # row g-1 = edge g
        ellc = np.sqrt(((B[1:] - B[:-1]) ** 2).sum(axis=2) / D**2 + sp["dt"] ** 2)
        csum = np.vstack([np.zeros((1, V)), np.cumsum(ell, axis=0)])  # csum[g] = sum of edges 1..g
        tot = 0.0
        for f in range(1, F):
            lo, hi = max(1, f - k + 1), min(F - 1, f + k)
            mean_speed = (csum[hi] - csum[lo - 1]) / (hi - lo + 1)
            tot += (np.abs(ellc[f - 1] - ell[f - 1]) / mean_speed).sum()
        sted_t = tot / (V * (F - 1))
    else:
        sted_t = 0.0
    rows += [
        ("sted_spatial", sted_s, rep["sted_spatial"]),
        ("sted_temporal", sted_t, rep["sted_temporal"]),
        ("sted", np.sqrt(sted_s**2 + sp["c"] ** 2 * sted_t**2), rep["sted"]),
    ]
    vec_rows.append(("sted_spatial_per_vertex[]", sig.mean(axis=0), res["sted_spatial_per_vertex"]))

    # Hausdorff: brute force over every triangle for the first N frames.
    ab0 = vertex_to_surface(A[0], B[0], tris)
    ba0 = vertex_to_surface(B[0], A[0], tris)
    vec_rows += [("frame0 ref->cand[]", ab0, res["frame0_ref_to_cand"]), ("frame0 cand->ref[]", ba0, res["frame0_cand_to_ref"])]
    nf = min(args.hausdorff_frames, F)
    hf = [max(ab0.max(), ba0.max())]
    for t in range(1, nf):
        hf.append(max(vertex_to_surface(A[t], B[t], tris).max(), vertex_to_surface(B[t], A[t], tris).max()))
    vec_rows.append((f"hausdorff_per_frame[0:{nf}]", np.array(hf), res["hausdorff_per_frame"][:nf]))
    if nf == F:
        rows += [("hausdorff", max(hf), rep["hausdorff"]), ("hausdorff_mean", np.mean(hf), rep["hausdorff_mean"])]

    print(f"{'metric':<34} {'numpy':>16} {'rust':>16} {'max rel diff':>13}")
    worst = 0.0
    for name, ref, rust in rows:
        r = rel_diff(rust, ref)
        worst = max(worst, r)
        print(f"{name:<34} {ref:>16.9e} {rust:>16.9e} {r:>13.2e}")
    for name, ref, rust in vec_rows:
        rust = np.asarray(rust, dtype=np.float64)
        diff = np.abs(rust - ref)
        r = float(np.max(diff / np.maximum(np.abs(ref), 1e-300))) if np.any(ref != 0) else float(diff.max())
        worst = max(worst, r) if np.isfinite(r) else worst
        print(f"{name:<34} {'n=' + str(len(ref)):>16} {'maxabs ' + format(diff.max(), '.1e'):>16} {r:>13.2e}")
    print(f"worst relative difference: {worst:.2e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
