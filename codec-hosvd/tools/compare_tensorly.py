#!/usr/bin/env python3
"""Dev aid (not a test): our unquantized truncated HO-SVD against tensorly's, same ranks, one run.

    pip install tensorly numpy
    cargo build --release -p codec-hosvd --example truncation_error
    python3 codec-hosvd/tools/compare_tensorly.py [DATA_DIR] [NAME ...]

For each animation and rank pair (v, 3, f) it runs
  * ours: target/release/examples/truncation_error (Gram-matrix HO-SVD, Alg. 1 of the paper),
    timed inside the binary (decomposition + reconstruction) and as wall time of the process;
  * tensorly: tucker(T, rank=[v, 3, f], n_iter_max=0, init="svd") — the plain truncated HO-SVD
    (SVD of each unfolding, no HOOI sweep), reconstructed with tucker_to_tensor, in float64,
and prints both Frobenius errors ||T - T^||_F and their relative difference. The tensor is
T[k, j, t] (vertices x 3 x frames) as in section 2.1 of the paper; no motion removal on either side.
"""
import json
import os
import subprocess
import sys
import time

import numpy as np
import tensorly as tl
from tensorly.decomposition import tucker

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BIN = os.path.join(ROOT, "target", "release", "examples", "truncation_error")
PAIRS = {"samba": [(4, 55), (10, 14), (25, 41), (50, 70), (100, 100)],
         "horse-gallop": [(2, 48), (7, 15), (14, 30), (28, 46)]}


def read_pc2(path):
    with open(path, "rb") as fh:
        head = fh.read(32)
        assert head[:12] == b"POINTCACHE2\0", path
        k = int.from_bytes(head[16:20], "little", signed=True)
        f = int.from_bytes(head[28:32], "little", signed=True)
        data = np.frombuffer(fh.read(k * f * 12), dtype="<f4").reshape(f, k, 3)
    return data


def main():
    data_dir = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "..", "shared", "data")
    names = sys.argv[2:] or ["samba", "horse-gallop"]
    if not os.path.exists(BIN):
        sys.exit(f"build first: cargo build --release -p codec-hosvd --example truncation_error ({BIN})")
    print("| animation | (v, f) | ours ||T-T^|| (f32 rec) | ours sqrt(|T|^2-|C|^2) | tensorly ||T-T^|| | rel. diff (rec) | rel. diff (energy) | ours s | ours wall s | tensorly s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in names:
        path = os.path.join(data_dir, name, f"{name}.pc2")
        if not os.path.exists(path):
            print(f"SKIP {name}: {path} not found")
            continue
        frames = read_pc2(path)
        tensor = np.ascontiguousarray(frames.transpose(1, 2, 0).astype(np.float64))  # K x 3 x F
        for v, f in PAIRS.get(name, [(5, 5), (20, 20)]):
            t0 = time.perf_counter()
            out = subprocess.run([BIN, path, str(v), str(f)], check=True, capture_output=True, text=True).stdout
            wall = time.perf_counter() - t0
            ours = json.loads(out.strip().splitlines()[-1])
            t0 = time.perf_counter()
            core, factors = tucker(tl.tensor(tensor), rank=[v, 3, f], n_iter_max=0, init="svd")
            rec = tl.tucker_to_tensor((core, factors))
            err_tl = float(np.linalg.norm(tensor - rec))
            secs_tl = time.perf_counter() - t0
            rel_rec = abs(ours["err_reconstruction"] - err_tl) / err_tl
            rel_energy = abs(ours["err_energy"] - err_tl) / err_tl
            print(f"| {name} | ({v}, {f}) | {ours['err_reconstruction']:.9e} | {ours['err_energy']:.9e} | {err_tl:.9e} | "
                  f"{rel_rec:.1e} | {rel_energy:.1e} | {ours['seconds']:.3f} | {wall:.3f} | {secs_tl:.3f} |", flush=True)


if __name__ == "__main__":
    main()
