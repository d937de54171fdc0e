#!/usr/bin/env python3
"""How much STED three ideas would buy, measured without a codec (issue 26's STED <= 0.05 rows).

    sted_levers.py PEERS_DIR NAME [--parts K ...]

For NAME (data in PEERS_DIR/../data/NAME/NAME.pc2 + .obj), STED is the metric author's tool's
value (PEERS_DIR/sted_np.py, its defaults) and KG the consensus form (PEERS_DIR/anim.py).
Noise is added to every frame alike, as the quantization of a static basis column would be;
eta is its RMS per coordinate relative to the RMS edge length of frame 0 (hosvd's `edge_noise`).

1. Noise proportional to the local edge length versus uniform noise at the same bits: the
   per-vertex steps keep the same geometric mean, and the bits of a quantized coordinate go
   with -log2(step).
2. High-pass quantization: uniform noise added to the umbrella-Laplacian (delta) coordinates
   and the positions solved back (least squares, weakly anchored), versus the same noise on
   the positions. Its error is low-frequency, which is what should spare edge lengths.
3. Anisotropic noise: the step along each frame's vertex normal k times the tangential steps
   (same geometric mean, same bits), the noise moving with the surface. Edge lengths change to
   first order only with the tangential components.
4. Per-part rigid motion (`--parts K ...`): K parts from k-means on the trajectories, then six
   rounds of reassigning each vertex to the part whose rigid (Kabsch) motion from frame 0 fits
   it best; reconstructed with hard labels and with labels smoothed over 2 and 5 rings (linear
   blend skinning). Frame 0 exact, nothing quantized: the model's own STED.
"""
import os
import sys

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spl
from scipy.cluster.vq import kmeans2


def unique_edges(faces):
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    return np.unique(np.sort(e, 1), axis=0)


def umbrella(vertices, edges):
    """I - D^-1 A: each vertex minus the mean of its neighbours."""
    adj = sp.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(vertices, vertices))
    adj = ((adj + adj.T) > 0).astype(np.float64).tocsr()
    deg = np.asarray(adj.sum(1)).ravel()
    deg[deg == 0] = 1
    return (sp.eye(vertices) - sp.diags(1 / deg) @ adj).tocsr(), sp.diags(1 / deg) @ adj


def normal_frames(p, faces):
    """Per vertex: unit normal (area-weighted) and two tangents."""
    face_normal = np.cross(p[faces[:, 1]] - p[faces[:, 0]], p[faces[:, 2]] - p[faces[:, 0]])
    n = np.zeros_like(p)
    for c in range(3):
        np.add.at(n, faces[:, c], face_normal)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    helper = np.where(np.abs(n[:, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0.0, 1, 0]]))
    t1 = np.cross(n, helper)
    t1 /= np.maximum(np.linalg.norm(t1, axis=1, keepdims=True), 1e-30)
    return n, t1, np.cross(n, t1)


def kabsch(p, q):
    mp, mq = p.mean(0), q.mean(0)
    u, _, vt = np.linalg.svd((p - mp).T @ (q - mq))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1, 1, d]) @ u.T
    return r, mq - r @ mp


def main():
    args = sys.argv[1:]
    if len(args) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    parts = []
    if "--parts" in args:
        i = args.index("--parts")
        parts = [int(k) for k in args[i + 1 :]]
        args = args[:i]
    peers, name = os.path.abspath(args[0]), args[1]
    sys.path.insert(0, peers)
    import anim
    import sted_np

    positions, faces = anim.load(os.path.join(peers, "..", "data", name), name)
    a = positions.astype(np.float64)
    frames, vertices, _ = a.shape
    edges = unique_edges(faces)
    length = np.linalg.norm(a[0, edges[:, 0]] - a[0, edges[:, 1]], axis=1)
    rms_edge = float(np.sqrt((length**2).mean()))
    lap, mean_of_neighbours = umbrella(vertices, edges)
    total, count = np.zeros(vertices), np.zeros(vertices)
    for c in (0, 1):
        np.add.at(total, edges[:, c], length)
        np.add.at(count, edges[:, c], 1)
    local = total / np.maximum(count, 1)
    local[count == 0] = rms_edge
    local = np.maximum(local, 1e-9 * rms_edge)  # zero-length edges: keep the logarithm finite
    rng = np.random.default_rng(0)
    unit = rng.uniform(-0.5, 0.5, size=(vertices, 3))
    solve = spl.factorized((lap.T @ lap + 1e-2 * sp.eye(vertices)).tocsc())

    def sted(candidate):
        return sted_np.sted(a, candidate, faces)

    print(f"{name}: {frames} frames x {vertices} vertices, RMS edge {rms_edge:.4g}")
    frames_of = [normal_frames(a[f], faces) for f in range(frames)]
    print(
        "| eta | uniform STED | ∝ local edge STED (same bits) | Laplacian-domain STED / KG "
        "| normal step 2× / 4× tangential STED (same bits) | uniform KG |"
    )
    print("|---:|---:|---:|---:|---:|---:|")
    for eta in (0.012, 0.02, 0.03):
        step = eta * rms_edge * np.sqrt(12)
        noise = step * unit
        weight = local / np.exp(np.log(local).mean())
        shaped = noise * weight[:, None]
        lowpass = np.stack([solve(lap.T @ noise[:, c]) for c in range(3)], 1)
        uniform = a + noise[None]
        high_pass = a + lowpass[None]
        anisotropic = []
        for ratio in (2, 4):
            tangential = step * ratio ** (-1 / 3)
            normal = tangential * ratio
            moved = np.stack(
                [
                    a[f]
                    + normal * unit[:, :1] * n
                    + tangential * unit[:, 1:2] * t1
                    + tangential * unit[:, 2:3] * t2
                    for f, (n, t1, t2) in enumerate(frames_of)
                ]
            )
            anisotropic.append(f"{sted(moved):.4f}")
        print(
            f"| {eta} | {sted(uniform):.4f} | {sted(a + shaped[None]):.4f} | "
            f"{sted(high_pass):.4f} / {anim.kg(a, high_pass):.3f} | {' / '.join(anisotropic)} | "
            f"{anim.kg(a, uniform):.3f} |",
            flush=True,
        )

    if parts:
        rest = a[0]
        features = (a - a.mean(1, keepdims=True)).transpose(1, 0, 2).reshape(vertices, -1)
        print("\n| parts | rings smoothed | STED | KG |")
        print("|---:|---:|---:|---:|")
    for k in parts:
        _, label = kmeans2(features, k, minit="++", seed=0)
        for _ in range(6):
            motion = np.zeros((k, frames, 3, 4))
            for j in range(k):
                members = np.where(label == j)[0]
                for f in range(frames):
                    if len(members) < 3:
                        motion[j, f, :, :3] = np.eye(3)
                    else:
                        r, t = kabsch(rest[members], a[f, members])
                        motion[j, f, :, :3], motion[j, f, :, 3] = r, t
            moved = np.einsum("kfij,vj->kfvi", motion[..., :3], rest) + motion[:, :, None, :, 3]
            label = ((moved - a[None]) ** 2).sum((1, 3)).argmin(0)
        for rings in (0, 2, 5):
            weights = np.zeros((vertices, k))
            weights[np.arange(vertices), label] = 1
            for _ in range(rings):
                weights = mean_of_neighbours @ weights
            blended = np.einsum("vk,kfvi->fvi", weights, moved)
            print(f"| {k} | {rings} | {sted(blended):.4f} | {anim.kg(a, blended):.3f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
