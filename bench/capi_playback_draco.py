"""Draco's per-frame decode at the KG of each animcodec stream, merged into capi_playback's table.

    python3 bench/capi_playback_draco.py TABLE.md ORIGINAL.pc2 MESH.obj NAME=DECODED.pc2 ...

TABLE.md is the Markdown table `capi_playback` printed for the streams NAME.anim; ORIGINAL.pc2
(with MESH.obj, its triangles) is the animation they were encoded from; DECODED.pc2 is each
stream's `animcodec decode`. For each stream: its KG against the original (the consensus form:
per-frame centroid, x100, as `animcodec eval` and ../shared/peers compute it), then Google Draco
(DracoPy 2.2.0) encoding every frame as a static mesh (compression level 10, vertex order kept,
as the peers' measurement ran it) at the fewest quantization bits (8..20) whose KG is at most the
stream's, on up to SAMPLE frames spread over the sequence; and the time DracoPy.decode takes per
frame there (best of 3 passes). Prints the table with the columns KG, Draco bits, Draco µs and
player/Draco and random/Draco (below 1: animcodec is faster than Draco's per-frame decode).
"""
import struct
import sys
import time

import numpy as np

SAMPLE = 24


def load_pc2(path):
    with open(path, "rb") as fh:
        head = fh.read(32)
        assert head[:12] == b"POINTCACHE2\0", path
        _, v, _, _, f = struct.unpack("<iiffi", head[12:32])
        return np.frombuffer(fh.read(), "<f4").reshape(f, v, 3)


def load_obj_faces(path):
    faces = []
    with open(path) as fh:
        for line in fh:
            if line.startswith("f "):
                idx = [int(t.split("/")[0]) - 1 for t in line.split()[1:]]
                faces.extend([idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1))
    return np.asarray(faces, np.uint32)


def kg(a, b):
    a = a.astype(np.float64)
    b = b.astype(np.float64)
    return 100.0 * np.linalg.norm(a - b) / np.linalg.norm(a - a.mean(axis=1, keepdims=True))


class Draco:
    """Draco per frame on a sample of the original's frames, one encode per bit depth."""

    def __init__(self, original, faces):
        import DracoPy

        self.dracopy = DracoPy
        step = max(1, len(original) // SAMPLE)
        self.frames = original[::step][:SAMPLE]
        self.faces = faces
        self.by_bits = {}

    def at(self, bits):
        if bits not in self.by_bits:
            bufs = [
                self.dracopy.encode(f, self.faces, quantization_bits=bits, compression_level=10, preserve_order=True)
                for f in self.frames
            ]
            decoded = np.stack([np.asarray(self.dracopy.decode(b).points, np.float32).reshape(-1, 3) for b in bufs])
            best = float("inf")
            for _ in range(3):
                t = time.perf_counter()
                for b in bufs:
                    self.dracopy.decode(b)
                best = min(best, (time.perf_counter() - t) / len(bufs))
            self.by_bits[bits] = (kg(self.frames, decoded), best, sum(map(len, bufs)) / len(bufs))
        return self.by_bits[bits]

    def matching(self, target):
        for bits in range(8, 21):
            err, secs, _ = self.at(bits)
            if err <= target:
                return bits, err, secs
        return None


def main():
    table, original, obj = sys.argv[1:4]
    decoded = dict(arg.split("=", 1) for arg in sys.argv[4:])
    orig = load_pc2(original)
    draco = Draco(orig, load_obj_faces(obj))
    lines = [l.rstrip("\n") for l in open(table, encoding="utf-8") if l.startswith("|")]
    head = [c.strip() for c in lines[0].strip("|").split("|")]
    col = {name: i for i, name in enumerate(head)}
    out = [
        "| stream | codec | frames/packet | KG | player µs | random µs | memcpy µs | random/player "
        "| Draco bits (KG) | Draco µs | player/Draco | random/Draco |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for line in lines[2:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        stream = cells[col["stream"]].removesuffix(".anim")
        player, random = float(cells[col["player µs"]]), float(cells[col["random µs"]])
        err = kg(orig, load_pc2(decoded[stream]))
        match = draco.matching(err)
        if match is None:
            dcells = "none ≤ 20 bits | – | – | –"
        else:
            bits, derr, secs = match
            us = secs * 1e6
            dcells = f"{bits} ({derr:.3f}) | {us:.1f} | {player / us:.2f} | {random / us:.2f}"
        out.append(
            f"| {stream} | {cells[col['codec']]} | {cells[col['frames/packet']]} | {err:.3f} | {player:.1f} "
            f"| {random:.1f} | {cells[col['memcpy µs']]} | {cells[col['random/player']]} | {dcells} |"
        )
    print("\n".join(out))


if __name__ == "__main__":
    main()
