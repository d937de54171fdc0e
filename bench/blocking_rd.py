#!/usr/bin/env python3
"""Rate-distortion cost of temporal blocking (issue 30): KG of hosvd with `block=B` against the
unblocked encode (`block=0`) at equal bpvf, on a real cache.

For each block size, the hosvd rate ladder (`ss`) is encoded with `--eval`; KG at the bpvf of
each unblocked point is interpolated on the blocked curve (linear in log bpvf, within its span
only) and the ratio reported. Not a test: prints a Markdown table.

    cargo build -p animcodec-cli --release
    python3 bench/blocking_rd.py ../shared/data/samba/samba.pc2 --blocks 88 44 22
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

LADDER = [0.998, 0.995, 0.99, 0.98, 0.97, 0.96, 0.95, 0.94, 0.93, 0.9, 0.85, 0.8, 0.7, 0.5]


def encode(binary, cache, ss, block, out):
    cmd = [binary, "encode", cache, "-c", "hosvd", "-p", f"ss={ss}", "-p", f"block={block}",
           "--eval", "--json", "-f", "-o", out]
    r = subprocess.run(cmd, capture_output=True, text=True, check=True)
    j = json.loads(r.stdout)
    return j["bpvf"], j["kg"]


def interpolate(curve, bpvf):
    """KG at `bpvf` on `curve` (sorted by bpvf), linear in log bpvf; None outside its span."""
    for (b0, k0), (b1, k1) in zip(curve, curve[1:]):
        if b0 <= bpvf <= b1:
            if b1 == b0:
                return min(k0, k1)
            t = (math.log(bpvf) - math.log(b0)) / (math.log(b1) - math.log(b0))
            return k0 + t * (k1 - k0)
    return None


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("cache")
    ap.add_argument("--blocks", type=int, nargs="+", default=[88, 44])
    ap.add_argument("--binary", default=os.environ.get("ANIMCODEC", "target/release/animcodec"))
    ap.add_argument("--ladder", type=float, nargs="+", default=LADDER)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "x.anim")
        curves = {}
        for block in [0] + args.blocks:
            points = [encode(args.binary, args.cache, ss, block, out) for ss in args.ladder]
            curves[block] = sorted(points)
            for ss, (b, k) in zip(args.ladder, points):
                print(f"block={block} ss={ss}: {b:.4f} bpvf, KG {k:.4f} %", file=sys.stderr)
    print("| block | points compared | median KG ratio (blocked / unblocked) | worst | bpvf range |")
    print("|---|---|---|---|---|")
    for block in args.blocks:
        ratios = []
        for b, k in curves[0]:
            kb = interpolate(curves[block], b)
            if kb is not None and k > 0:
                ratios.append((kb / k, b))
        if not ratios:
            print(f"| {block} | 0 | n/a | n/a | curves do not overlap |")
            continue
        rs = sorted(r for r, _ in ratios)
        median = rs[len(rs) // 2] if len(rs) % 2 else 0.5 * (rs[len(rs) // 2 - 1] + rs[len(rs) // 2])
        lo, hi = min(b for _, b in ratios), max(b for _, b in ratios)
        print(f"| {block} | {len(ratios)} | {median:.3f} | {max(rs):.3f} | {lo:.3f}–{hi:.3f} |")
    print("\nraw points (block, bpvf, KG %):")
    for block, pts in curves.items():
        print(f"  {block}: " + ", ".join(f"({b:.3f}, {k:.4f})" for b, k in pts))


if __name__ == "__main__":
    main()
