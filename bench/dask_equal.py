#!/usr/bin/env python3
"""Issue 30 check at a size CI does not run: one animation encoded by independent temporal
blocks on a Dask LocalCluster (`animcodec.encode_distributed`, workers reading the PC2) gives the
bytes of the command line's local encode with the same parameters.

    python3 bench/dask_equal.py ANIMCODEC COLSxROWSxFRAMES [--dir DIR] [--workers N]

Writes `synth flag:COLSxROWSxFRAMES` as a PC2 in DIR, then for each case below runs
`ANIMCODEC encode X.pc2 -c CODEC -p K=V…` and `encode_distributed(X.pc2, CODEC, client=…, **params)`
and compares the bytes. Prints one line per case (blocks, seconds each way, equal or not) and
exits 1 if any differs. Needs the Python package (`pip install ./python`) and `distributed`.
"""
import os
import subprocess
import sys
import time

CASES = [
    ("quant-delta", {"bits": 12}),
    ("hosvd", {"ss": 0.9, "block": 20}),
    ("pca-aoi", {"mode": "svd", "block": 20}),
]


def main():
    args = sys.argv[1:]
    if len(args) < 2:
        sys.exit(__doc__)
    binary, size = args[0], args[1]
    out_dir = args[args.index("--dir") + 1] if "--dir" in args else "/tmp/dask_equal"
    workers = int(args[args.index("--workers") + 1]) if "--workers" in args else 2
    os.makedirs(out_dir, exist_ok=True)
    pc2 = os.path.join(out_dir, f"flag-{size}.pc2")
    subprocess.run([binary, "synth", f"flag:{size}", "-o", pc2, "-f"], check=True, capture_output=True)

    import animcodec
    from animcodec.blocks import block_plan
    from distributed import Client, LocalCluster

    failed = False
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True) as cluster, Client(cluster) as client:
        for codec, params in CASES:
            local = os.path.join(out_dir, f"local-{codec}.anim")
            cmd = [binary, "encode", pc2, "-c", codec, "-o", local, "-f"]
            for k, v in params.items():
                cmd += ["-p", f"{k}={v}"]
            start = time.monotonic()
            subprocess.run(cmd, check=True, capture_output=True)
            local_s = time.monotonic() - start
            start = time.monotonic()
            data = animcodec.encode_distributed(pc2, codec, client=client, **params)
            dask_s = time.monotonic() - start
            plan = block_plan(codec, *_counts(size), **params)
            with open(local, "rb") as f:
                same = f.read() == data
            failed |= not same
            print(
                f"{size} {codec} {params}: {plan['blocks']} blocks, {len(data)} bytes, local {local_s:.1f} s, "
                f"dask ({workers} workers) {dask_s:.1f} s, {'equal' if same else 'DIFFERENT'}",
                flush=True,
            )
            os.remove(local)
    os.remove(pc2)
    obj = os.path.splitext(pc2)[0] + ".obj"
    if os.path.exists(obj):
        os.remove(obj)
    sys.exit(1 if failed else 0)


def _counts(size):
    cols, rows, frames = (int(x) for x in size.split("x"))
    return cols * rows, frames


if __name__ == "__main__":
    main()
