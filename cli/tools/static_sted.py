#!/usr/bin/env python3
"""What STED and KG give a "codec" that drops all motion: frame 0 repeated for every frame.

    static_sted.py PEERS_DIR NAME...

For each NAME (data in PEERS_DIR/../data/NAME/NAME.pc2 + .obj), prints the STED (the metric
author's tool's value, PEERS_DIR/sted_np.py, its default parameters) and the KG of the
animation against its own frame 0 repeated. Issue 26 asks for >= 3x fewer bits than the best
peer at STED <= 0.1, 0.05, 0.02: where this static stand-in already meets a STED target, that
target does not measure motion (STED's temporal term is weighted by c ~ 1e-4), and a codec
could "meet" it by sending one frame. animcodec's codecs are not tuned to do so; this script
shows where the STED rows need reading with that in mind."""
import os
import sys

import numpy as np


def main():
    if len(sys.argv) < 3:
        print(__doc__, file=sys.stderr)
        return 2
    peers = os.path.abspath(sys.argv[1])
    sys.path.insert(0, peers)
    import anim
    import sted_np

    print("| animation | frames × vertices | STED of frame 0 repeated | KG (%) |")
    print("|---|---|---|---|")
    for name in sys.argv[2:]:
        positions, faces = anim.load(os.path.join(peers, "..", "data", name), name)
        static = np.repeat(positions[:1], positions.shape[0], axis=0)
        sted = sted_np.sted(positions, static, faces)
        kg = anim.kg(positions, static)
        print(f"| {name} | {positions.shape[0]} × {positions.shape[1]} | {sted:.4f} | {kg:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
