#!/usr/bin/env python3
"""Frame 0 of horse-gallop: our decoded frame-0 error vs Draco (edgebreaker, level 10) on frame 0 alone.
Usage (from the repository root): python3 codec-hosvd/tools/draco_rest.py DECODED.pc2...  (numpy, DracoPy 2.2.0)"""
import sys, numpy as np
sys.path.insert(0, '../shared/peers')
import anim, DracoPy

A, T = anim.load('../shared/data/horse-gallop')
f0 = A[0].astype(np.float64); diag = anim.bbox_diag(A)
def errs(R):
    d = np.linalg.norm(R - f0, axis=1); return np.sqrt((d**2).mean()) / diag, d.max() / diag
for name in sys.argv[1:]:
    R = anim.load_pc2(name)[0].astype(np.float64); r, m = errs(R)
    print(f'ours {name}: frame 0 rms/diag {r:.3e} max/diag {m:.3e}')
for q in range(8, 17):
    for order in (False, True):
        buf = DracoPy.encode(A[0], T, quantization_bits=q, compression_level=10, preserve_order=order)
        R = np.asarray(DracoPy.decode(buf).points, np.float64).reshape(-1, 3)
        if not order: 
            print(f'draco q={q:2d} preserve_order=False bytes {len(buf):6d}'); continue
        r, m = errs(R); print(f'draco q={q:2d} preserve_order=True  bytes {len(buf):6d} rms/diag {r:.3e} max/diag {m:.3e}')
