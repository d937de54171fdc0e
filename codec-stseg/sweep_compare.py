#!/usr/bin/env python3
"""Compare two codecs of an `animcodec sweep --csv` file at equal KG and at equal bpvf.

`python3 codec-stseg/sweep_compare.py rd.csv [A B]` (default A = stseg, B = quant-delta) prints,
for KG targets 5 … 0.5, each codec's bpvf (log-KG interpolation along its ladder), and for every
point of A, B's KG and STED at A's bpvf (linear in bpvf, log in the error).
"""
import csv
import math
import sys

path = sys.argv[1]
a, b = (sys.argv[2], sys.argv[3]) if len(sys.argv) > 3 else ("stseg", "quant-delta")
rows = list(csv.DictReader(open(path)))


def points(codec):
    return sorted((float(r["bpvf"]), float(r["kg"]), float(r["sted"])) for r in rows if r["codec"] == codec)


def bpvf_at_kg(pts, kg):
    by_kg = sorted((p[1], p[0]) for p in pts)
    for (k1, b1), (k2, b2) in zip(by_kg, by_kg[1:]):
        if k1 <= kg <= k2:
            t = (math.log(kg) - math.log(k1)) / (math.log(k2) - math.log(k1))
            return b1 + t * (b2 - b1)
    return None


def err_at_bpvf(pts, x, i):
    for p1, p2 in zip(pts, pts[1:]):
        if p1[0] <= x <= p2[0]:
            t = (x - p1[0]) / (p2[0] - p1[0])
            return math.exp(math.log(p1[i]) + t * (math.log(p2[i]) - math.log(p1[i])))
    return None


pa, pb = points(a), points(b)
fmt = lambda v: "-" if v is None else f"{v:.3f}"
print(f"KG target | {a} bpvf | {b} bpvf")
for kg in [5, 3, 2, 1.5, 1, 0.7, 0.5]:
    print(f"{kg} | {fmt(bpvf_at_kg(pa, kg))} | {fmt(bpvf_at_kg(pb, kg))}")
print(f"{a} bpvf | {a} KG | {b} KG at that bpvf | {a} STED | {b} STED at that bpvf")
for x, kg, sted in pa:
    print(f"{x:.3f} | {kg:.3f} | {fmt(err_at_bpvf(pb, x, 1))} | {sted:.4f} | {fmt(err_at_bpvf(pb, x, 2))}")
