#!/usr/bin/env python3
"""Issue 26 item 4 benchmark: the cost of quality-targeted rate control, as ratios measured in
one run on one machine.

    rate_bench.py ANIMCODEC INPUT [--target sted=0.05] [--codec hosvd] [--sweep] [--keep DIR]

1. `encode INPUT -c CODEC --target T` (the parameter-space search): wall seconds and the
   parameters it picks;
2. `encode INPUT -c CODEC -p <those parameters>` (one encode, no search): wall seconds;
   ratio 1/2 (issue 26: ≤ 8);
3. with --sweep: `sweep INPUT --ladder` (the single-axis sweep, today's default before issue
   26) and `sweep INPUT` (the envelope sweep, the new default): wall seconds each, ratio
   (issue 26: ≤ 2); --keep DIR keeps their JSON (ladder.json, envelope.json) for rdsummary.py.
Each command runs alone (the search and the sweep use both cores themselves)."""
import json, subprocess, sys, tempfile, time, os


def run(cmd):
    start = time.monotonic()
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    return time.monotonic() - start, out


def as_arg(v):
    return ("true" if v else "false") if isinstance(v, bool) else repr(v) if isinstance(v, float) else str(v)


def main():
    args = sys.argv[1:]
    if len(args) < 2:
        sys.exit(__doc__)
    binary, data = args[0], args[1]
    target = args[args.index("--target") + 1] if "--target" in args else "sted=0.05"
    codec = args[args.index("--codec") + 1] if "--codec" in args else "hosvd"
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "x.anim")
        search_s, text = run([binary, "encode", data, "-c", codec, "--target", target, "-o", out, "-f", "--json"])
        found = json.loads(text)
        params = [f"{k}={as_arg(v)}" for k, v in found["params"].items()]
        one_s, text = run([binary, "encode", data, "-c", codec, "-o", out, "-f", "--json"]
                          + sum((["-p", p] for p in params), []))
        again = json.loads(text)
        assert again["bytes"] == found["bytes"], "the same parameters must give the same stream"
        print(f"{data}: encode -c {codec} --target {target}: {search_s:.2f} s, {len(found['tried'])} points, "
              f"{found['bytes']} bytes ({found['bpvf']:.4f} bpvf, {target.split('=')[0]}={found['reached']:.5f})")
        print(f"  picked: {' '.join(params)}")
        print(f"  one encode at those parameters: {one_s:.2f} s -> search / encode = {search_s / one_s:.2f}")
        if "--sweep" in args:
            keep = args[args.index("--keep") + 1] if "--keep" in args else tmp
            os.makedirs(keep, exist_ok=True)
            ladder_s, _ = run([binary, "sweep", data, "--ladder", "--json", os.path.join(keep, "ladder.json"), "-f"])
            env_s, _ = run([binary, "sweep", data, "--json", os.path.join(keep, "envelope.json"), "-f"])
            print(f"  sweep --ladder: {ladder_s:.1f} s; sweep (envelope): {env_s:.1f} s -> ratio {env_s / ladder_s:.2f}")


if __name__ == "__main__":
    main()
