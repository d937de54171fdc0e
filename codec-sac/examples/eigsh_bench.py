"""Independent eigensolver for the sac benchmark: scipy eigsh in shift-invert mode on the
matrices dumped by `sac_bench --dump-laplacian DIR` (same stiffness L and lumped mass M).

usage: python3 eigsh_bench.py DIR NAME K
Prints the solve time and the k smallest generalized eigenvalues' summary, and writes all k
eigenvalues (ascending, one per line) to DIR/NAME.K.eig.txt so sac_bench --eigen compares them
with its own solver's, measured in the same run.
"""
import sys
import time

import numpy as np
import scipy.io
import scipy.sparse as sp
from scipy.sparse.linalg import eigsh

d, name, k = sys.argv[1], sys.argv[2], int(sys.argv[3])
L = scipy.io.mmread(f"{d}/{name}.L.mtx").tocsc()
m = np.loadtxt(f"{d}/{name}.M.txt")
M = sp.diags(m).tocsc()
area = m.sum()
sigma = -1e-2 / area  # the same shift as sac: L + (1e-2/area) M
t = time.perf_counter()
vals, vecs = eigsh(L, k=k, M=M, sigma=sigma, which="LM")
dt = time.perf_counter() - t
vals = np.sort(vals)
print(f"  scipy eigsh shift-invert (k={k}): {dt:.3f} s; eigenvalues first {vals[0]:.3e} second {vals[1]:.3e} last {vals[-1]:.3e}")
np.savetxt(f"{d}/{name}.{k}.eig.txt", vals, fmt="%.17e")
