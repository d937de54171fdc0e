# Builds glTF fixtures with KHR_draco_mesh_compression for cli/tests/gltf_draco.rs, encoded and
# decoded by Google's Draco library through DracoPy (`pip install DracoPy`).
#
#   python make_fixture.py OUT_DIR [NX NY]
#
# For each Draco compression level 0 (sequential), 7 and 10 (EdgeBreaker), with 14-bit
# positions: a bent NX × NY grid (default 24 × 16; small ones seed the read_gltf fuzz corpus), skinned to two joints (JOINTS_0 / WEIGHTS_0 as Draco generic
# attributes with unique ids 5 and 6, so the extension's attribute map is not the identity)
# with one uncompressed morph target and an animation (joint rotation + morph weight), written
# twice:
#   draco_L.glb  the primitive as Draco data only (accessors without bufferView),
#   plain_L.glb  the same primitive uncompressed, holding what DracoPy decodes from that Draco
#                data (points, faces, joints, weights), value for value.
# The morph target displacement is a function of each decoded point, so it matches Draco's
# point order (Draco may reorder and remove points). Prints one line `FIXTURE {json}`: per
# level the file names, decoded point and face counts, the Draco bytes' range in draco_L.glb
# and the largest distance of a decoded point from the original grid.
import json
import math
import struct
import sys

import DracoPy
import numpy as np

out = sys.argv[1]
NX, NY = (int(sys.argv[2]), int(sys.argv[3])) if len(sys.argv) > 3 else (24, 16)
xs, ys = np.meshgrid(np.linspace(0.0, 2.0, NX), np.linspace(0.0, 1.0, NY))
grid = np.stack([xs.ravel(), ys.ravel(), 0.1 * np.sin(3.0 * xs.ravel())], axis=1).astype(np.float32)
faces = []
for j in range(NY - 1):
    for i in range(NX - 1):
        a = j * NX + i
        faces += [[a, a + 1, a + NX], [a + 1, a + NX + 1, a + NX]]
faces = np.array(faces, dtype=np.uint32)
# Joint 1 takes over along x.
w1 = np.clip(grid[:, 0] - 0.5, 0.0, 1.0)
joints = np.tile(np.array([0, 1, 0, 0], dtype=np.uint16), (len(grid), 1))
weights = np.stack([1.0 - w1, w1, 0 * w1, 0 * w1], axis=1).astype(np.float32)


def pad(b, fill=b"\0"):
    return b + fill * (-len(b) % 4)


def glb(doc, bin_):
    j = pad(json.dumps(doc, separators=(",", ":")).encode(), b" ")
    b = pad(bin_)
    head = struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(j) + 8 + len(b))
    return head + struct.pack("<I4s", len(j), b"JSON") + j + struct.pack("<I4s", len(b), b"BIN\0") + b, 12 + 8 + len(j) + 8


def write(path, points, tri, jts, wts, draco):
    """One GLB: node 0 the skinned mesh, nodes 1 → 2 the joints, an animation rotating joint 2
    and driving the morph weight. `draco`: (bytes, {name: unique id}) or None."""
    target = np.stack([0 * points[:, 0], 0 * points[:, 0], 0.2 * np.cos(2.0 * points[:, 0])], axis=1).astype(np.float32)
    ibm = np.array([np.eye(4), np.eye(4)], dtype=np.float32)
    ibm[1][3][0] = -1.0  # column-major: translation (-1, 0, 0)
    keys = np.array([0.0, 0.5, 1.0], dtype=np.float32)
    s = math.sin(0.4)
    rotations = np.array([[0, 0, 0, 1], [0, 0, s, math.cos(0.4)], [0, 0, 0, 1]], dtype=np.float32)
    morph = np.array([0.0, 1.0, 0.25], dtype=np.float32)
    bin_ = b""
    views, accessors = [], []

    def view(data):
        nonlocal bin_
        bin_ = pad(bin_)
        views.append({"buffer": 0, "byteOffset": len(bin_), "byteLength": len(data)})
        bin_ += data
        return len(views) - 1

    def accessor(arr, ctype, kind, with_view=True, minmax=False):
        a = {"componentType": ctype, "count": len(arr), "type": kind}
        if with_view:
            a["bufferView"] = view(np.ascontiguousarray(arr).tobytes())
        if minmax:
            a["min"] = [float(x) for x in np.atleast_1d(arr.min(axis=0))]
            a["max"] = [float(x) for x in np.atleast_1d(arr.max(axis=0))]
        accessors.append(a)
        return len(accessors) - 1

    plain = draco is None
    prim = {
        "attributes": {
            "POSITION": accessor(points, 5126, "VEC3", plain, True),
            "JOINTS_0": accessor(jts, 5123, "VEC4", plain),
            "WEIGHTS_0": accessor(wts, 5126, "VEC4", plain),
        },
        "indices": accessor(tri.reshape(-1), 5125, "SCALAR", plain),
        "targets": [{"POSITION": accessor(target, 5126, "VEC3", True, True)}],
        "mode": 4,
    }
    doc = {"asset": {"version": "2.0"}}
    draco_range = None
    if draco is not None:
        data, ids = draco
        v = view(data)
        draco_range = views[v]["byteOffset"]
        prim["extensions"] = {"KHR_draco_mesh_compression": {"bufferView": v, "attributes": ids}}
        doc["extensionsUsed"] = doc["extensionsRequired"] = ["KHR_draco_mesh_compression"]
    ibm_a = accessor(ibm.reshape(2, 16), 5126, "MAT4")
    t_a = accessor(keys, 5126, "SCALAR", True, True)
    r_a = accessor(rotations, 5126, "VEC4")
    m_a = accessor(morph, 5126, "SCALAR")
    doc.update({
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0, "skin": 0}, {"children": [2]}, {"translation": [1.0, 0.0, 0.0]}],
        "meshes": [{"primitives": [prim], "weights": [0.0]}],
        "skins": [{"joints": [1, 2], "inverseBindMatrices": ibm_a}],
        "animations": [{
            "channels": [
                {"sampler": 0, "target": {"node": 2, "path": "rotation"}},
                {"sampler": 1, "target": {"node": 0, "path": "weights"}},
            ],
            "samplers": [{"input": t_a, "output": r_a}, {"input": t_a, "output": m_a}],
        }],
        "buffers": [{"byteLength": len(pad(bin_))}],
        "bufferViews": views,
        "accessors": accessors,
    })
    data, bin_start = glb(doc, bin_)
    with open(path, "wb") as f:
        f.write(data)
    if draco_range is None:
        return None
    return [bin_start + draco_range, len(draco[0])]


report = {}
for level in (0, 7, 10):
    encoded = DracoPy.encode(
        grid, faces, quantization_bits=14, compression_level=level, generic_attributes={5: joints, 6: weights}
    )
    decoded = DracoPy.decode(encoded)
    position_id = next(a["unique_id"] for a in decoded.attributes if a["attribute_type"] == 0)
    points = np.asarray(decoded.points, dtype=np.float32)
    tri = np.asarray(decoded.faces, dtype=np.uint32)
    jts = np.asarray(decoded.get_attribute_by_unique_id(5)["data"]).astype(np.uint16)
    wts = np.asarray(decoded.get_attribute_by_unique_id(6)["data"]).astype(np.float32)
    ids = {"POSITION": position_id, "JOINTS_0": 5, "WEIGHTS_0": 6}
    draco_range = write(f"{out}/draco_{level}.glb", points, tri, jts, wts, (encoded, ids))
    write(f"{out}/plain_{level}.glb", points, tri, jts, wts, None)
    nearest = np.sqrt(((points[:, None, :] - grid[None, :, :]) ** 2).sum(-1)).min(axis=1).max()
    report[level] = {
        "draco": f"draco_{level}.glb",
        "plain": f"plain_{level}.glb",
        "points": len(points),
        "faces": len(tri),
        "draco_range": draco_range,
        "max_quantization_error": float(nearest),
        "extent": float((grid.max(axis=0) - grid.min(axis=0)).max()),
    }
print("FIXTURE " + json.dumps(report))
