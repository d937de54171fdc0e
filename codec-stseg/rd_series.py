#!/usr/bin/env python3
"""Per-series summary of `animcodec sweep --json` output (stseg): bpvf needed at
KG <= 2 / 0.5 / 0.1 and STED <= 0.1 / 0.05 / 0.02 by rdsummary.py's log-log interpolation
(`bpvf_at`), per series (so `--series stseg:coding=paper` is its own row), plus the check
"SERIES beats quant-delta at every KG from 2 to 0.1" on a 25-point log grid.
Usage: python3 codec-stseg/rd_series.py FILE.json... [--peers ../shared/peers]"""
import json, math, os, sys
from collections import defaultdict

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '../../shared/peers'))
from rdsummary import bpvf_at  # noqa: E402

KG = (2.0, 0.5, 0.1)
STED = (0.1, 0.05, 0.02)
GRID = [2.0 * (0.05 ** (i / 24)) for i in range(25)]  # 2 .. 0.1


def fmt(x):
    return f'{x:.2f}' if x else '–'


def main():
    args = [a for a in sys.argv[1:]]
    peers = None
    if '--peers' in args:
        i = args.index('--peers')
        peers = args[i + 1]
        del args[i:i + 2]
    for path in args:
        d = json.load(open(path))
        series = defaultdict(list)
        for r in d['rows']:
            series[r.get('series') or r['codec']].append(r)
        name = os.path.basename(d.get('input', path))
        print(f'== {name}')
        print('| series | KG ≤ 2 / 0.5 / 0.1 | STED ≤ 0.1 / 0.05 / 0.02 |')
        print('|---|---|---|')
        for s, rows in series.items():
            kg = [(r['bpvf'], r['kg']) for r in rows]
            st = [(r['bpvf'], r['sted']) for r in rows if r.get('sted') is not None]
            print(f'| {s} | ' + ' / '.join(fmt(bpvf_at(kg, t)) for t in KG) + ' | '
                  + ' / '.join(fmt(bpvf_at(st, t)) for t in STED) + ' |')
        if peers:
            stem = os.path.splitext(name)[0]
            pf = os.path.join(peers, stem + '.json')
            if os.path.exists(pf):
                fam = defaultdict(list)
                for r in json.load(open(pf))['rows']:
                    if r.get('sted') is not None:
                        fam[r.get('peer') or r.get('codec')].append((r['bpvf'], r['sted']))
                best = [min((b for b in (bpvf_at(p, t) for p in fam.values()) if b), default=None) for t in STED]
                print(f'| best peer (STED) | | ' + ' / '.join(fmt(b) for b in best) + ' |')
        qd = [(r['bpvf'], r['kg']) for r in series.get('quant-delta', [])]
        if qd:
            for s, rows in series.items():
                if s == 'quant-delta':
                    continue
                kg = [(r['bpvf'], r['kg']) for r in rows]
                ratios = []
                for t in GRID:
                    a, b = bpvf_at(kg, t), bpvf_at(qd, t)
                    ratios.append(None if a is None or b is None else b / a)
                ok = all(r is not None and r > 1 for r in ratios)
                known = [r for r in ratios if r is not None]
                worst = min(known) if known else None
                print(f'{s} vs quant-delta, KG 2 .. 0.1 ({len(GRID)} targets): '
                      f'{"beats at every KG" if ok else "does NOT beat at every KG"}; '
                      f'quant-delta/series bpvf min {fmt(worst)}' + ('' if len(known) == len(GRID) else
                                                                    f' ({len(GRID) - len(known)} targets out of range)'))
        print()


if __name__ == '__main__':
    main()
