"""animcodec's Alembic reader and writer against the reference library (PyAlembic, the
`alembic3d` wheel on PyPI: `pip install alembic3d numpy`), driven by cli/tests/alembic.rs.

  abc_check.py write DIR
      Writes the test archives with alembic3d (uniform, cyclic and acyclic time sampling, a quad
      mesh, an Xform chain with every operation type and a non-inheriting transform, two
      meshes, a SubD, unevenly spaced samples), and for each CASE: DIR/CASE.abc, DIR/CASE.f32
      (the world-space points alembic3d reads at every frame, as float32: P times the product
      of the Xform matrices alembic3d computes, as Imath's multVecMatrix does) and DIR/CASE.json
      (vertices, frames, fps, triangles count). Prints the case names as JSON.
  abc_check.py check FILE.abc EXPECTED.f32
      Opens FILE.abc (written by animcodec) with alembic3d; prints JSON: the meshes found, the
      samples of P, the time per sample, the archive's FramesPerTimeUnit, the face counts, the
      faces, and how many coordinates differ (bitwise) from EXPECTED.f32.
"""
import json
import math
import os
import struct
import sys

import alembic3d
import imath
from alembic3d.Abc import IArchive, ISampleSelector, OArchive, WrapExistingFlag
from alembic3d.AbcCoreAbstract import AcyclicFlag, TimeSampling, TimeSamplingType, TimeVector
from alembic3d.AbcGeom import (IPolyMesh, ISubD, IXform, OPolyMesh, OPolyMeshSchemaSample, OSubD,
                               OSubDSchemaSample, OXform, XformOp, XformOperationType, XformSample)


def v3f(points):
    a = imath.V3fArray(len(points))
    for i, p in enumerate(points):
        a[i] = imath.V3f(*p)
    return a


def ints(values):
    a = imath.IntArray(len(values))
    for i, v in enumerate(values):
        a[i] = v
    return a


def grid_points(t, shift=(0.0, 0.0, 0.0)):
    """A 3x2 grid of points (two quads), waving with t."""
    pts = []
    for j in range(2):
        for i in range(3):
            pts.append((i * 0.5 + shift[0], math.sin(0.7 * t + i) * 0.25 + shift[1], j * 0.5 + 0.1 * t + shift[2]))
    return pts


QUADS = ([0, 3, 4, 1, 1, 4, 5, 2], [4, 4])  # two quads, Alembic (clockwise) order
TRI_QUAD = ([0, 1, 2, 1, 3, 4, 2], [3, 4])  # a triangle and a quad


def write_mesh(parent, name, tsi, frames, points_of, faces, subd=False):
    if subd:
        mesh = OSubD(parent, name)
        sample = OSubDSchemaSample
    else:
        mesh = OPolyMesh(parent, name)
        sample = OPolyMeshSchemaSample
    s = mesh.getSchema()
    s.setTimeSampling(tsi)
    for t in range(frames):
        if t == 0:
            s.set(sample(v3f(points_of(t)), ints(faces[0]), ints(faces[1])))
        elif subd:
            later = sample()
            later.setPositions(v3f(points_of(t)))
            s.set(later)
        else:
            s.set(sample(v3f(points_of(t))))
    return mesh


def op(kind):
    return XformOp(kind, 0)


def xform_sample(ops, inherits=True):
    """An XformSample from [(XformOperationType, [channel values])]."""
    s = XformSample()
    for kind, values in ops:
        o = op(kind)
        for k, v in enumerate(values):
            o.setChannelValue(k, v)
        s.addOp(o)
    s.setInheritsXforms(inherits)
    return s


def write_cases(out):
    cases = {}
    T = XformOperationType

    # Uniform 24 fps, two quads under the top object, 6 frames.
    path = os.path.join(out, "quads-uniform.abc")
    arch = OArchive(path)
    tsi = arch.addTimeSampling(TimeSampling(1.0 / 24.0, 0.0))
    m = write_mesh(arch.getTop(), "quads", tsi, 6, grid_points, QUADS)
    del m, arch
    cases["quads-uniform"] = {"fps": 24.0}

    # Acyclic sampling at 30 fps (times listed), a triangle and a quad.
    path = os.path.join(out, "acyclic.abc")
    arch = OArchive(path)
    times = TimeVector()
    for i in range(5):
        times.append(1.0 + i / 30.0)
    tsi = arch.addTimeSampling(TimeSampling(TimeSamplingType(AcyclicFlag.kAcyclic), times))
    m = write_mesh(arch.getTop(), "mixed", tsi, 5, lambda t: grid_points(t)[:5], TRI_QUAD)
    del m, arch
    cases["acyclic"] = {"fps": 30.0}

    # Cyclic sampling: two times per cycle of 1/12 s, i.e. every 1/24 s.
    path = os.path.join(out, "cyclic.abc")
    arch = OArchive(path)
    times = TimeVector()
    times.append(0.0)
    times.append(1.0 / 24.0)
    tsi = arch.addTimeSampling(TimeSampling(TimeSamplingType(2, 1.0 / 12.0), times))
    m = write_mesh(arch.getTop(), "quads", tsi, 7, grid_points, QUADS)
    del m, arch
    cases["cyclic"] = {"fps": 24.0}

    # An Xform chain: /rig (translate + rotateY + rotate about an axis, animated) /rig/arm
    # (scale + matrix + rotateX + rotateZ, constant) /rig/arm/quads; and /rig/free (translate,
    # not inheriting) /rig/free/tri, a second mesh: merged, or chosen with --object.
    path = os.path.join(out, "xform-chain.abc")
    arch = OArchive(path)
    tsi = arch.addTimeSampling(TimeSampling(1.0 / 25.0, 0.0))
    rig = OXform(arch.getTop(), "rig")
    rig.getSchema().setTimeSampling(tsi)
    arm = OXform(rig, "arm")
    arm.getSchema().setTimeSampling(tsi)
    free = OXform(rig, "free")
    free.getSchema().setTimeSampling(tsi)
    frames = 5
    matrix = [1.0, 0.2, 0.0, 0.0, 0.0, 0.9, 0.1, 0.0, 0.3, 0.0, 1.1, 0.0, 0.5, -0.25, 2.0, 1.0]
    for t in range(frames):
        rig.getSchema().set(xform_sample([
            (T.kTranslateOperation, [0.1 * t, 1.0, -2.0]),
            (T.kRotateYOperation, [15.0 * t]),
            (T.kRotateOperation, [1.0, 1.0, 0.0, 10.0 + 3.0 * t]),
        ]))
        arm.getSchema().set(xform_sample([
            (T.kScaleOperation, [2.0, 0.5, 1.5]),
            (T.kMatrixOperation, matrix),
            (T.kRotateXOperation, [30.0]),
            (T.kRotateZOperation, [-45.0]),
        ]))
        free.getSchema().set(xform_sample([(T.kTranslateOperation, [3.0, 0.0, 0.25 * t])], inherits=False))
    q = write_mesh(arm, "quads", tsi, frames, grid_points, QUADS)
    tri = write_mesh(free, "tri", tsi, frames, lambda t: grid_points(t, (1.0, 2.0, 3.0))[:3], ([0, 2, 1], [3]))
    del q, tri, rig, arm, free, arch
    cases["xform-chain"] = {"fps": 25.0}
    cases["xform-chain-tri"] = {"fps": 25.0, "file": "xform-chain", "object": "/rig/free/tri"}

    # A SubD (its control mesh) under an animated Xform, and a static PolyMesh beside it: the
    # static one holds its points at every frame.
    path = os.path.join(out, "subd.abc")
    arch = OArchive(path)
    tsi = arch.addTimeSampling(TimeSampling(1.0 / 24.0, 0.0))
    x = OXform(arch.getTop(), "x")
    x.getSchema().setTimeSampling(tsi)
    for t in range(4):
        x.getSchema().set(xform_sample([(T.kTranslateOperation, [0.0, 0.5 * t, 0.0])]))
    sd = write_mesh(x, "cage", tsi, 4, grid_points, QUADS, subd=True)
    still = write_mesh(arch.getTop(), "still", tsi, 1, lambda t: [(0, 0, 0), (1, 0, 0), (0, 1, 0)], ([0, 2, 1], [3]))
    del sd, still, x, arch
    cases["subd"] = {"fps": 24.0}

    # Unevenly spaced samples: refused (one frame rate).
    path = os.path.join(out, "uneven.abc")
    arch = OArchive(path)
    times = TimeVector()
    for x in (0.0, 0.1, 0.5):
        times.append(x)
    tsi = arch.addTimeSampling(TimeSampling(TimeSamplingType(AcyclicFlag.kAcyclic), times))
    m = write_mesh(arch.getTop(), "tri", tsi, 3, lambda t: grid_points(t)[:3], ([0, 2, 1], [3]))
    del m, arch

    names = []
    for case, meta in cases.items():
        file = os.path.join(out, meta.get("file", case) + ".abc")
        points, frames, vertices, triangles = world_points(file, meta.get("object"))
        with open(os.path.join(out, case + ".f32"), "wb") as f:
            f.write(struct.pack("<%df" % len(points), *points))
        meta.update({"abc": file, "frames": frames, "vertices": vertices, "triangles": triangles})
        with open(os.path.join(out, case + ".json"), "w") as f:
            json.dump(meta, f)
        names.append(case)
    return names


def meshes_of(obj, chain, found):
    """Depth-first: (mesh object, schema reader, [IXform ancestors from the root])."""
    for i in range(obj.getNumChildren()):
        child = obj.getChild(i)
        md = child.getMetaData()
        if IXform.matches(md):
            meshes_of(child, chain + [IXform(child, WrapExistingFlag.kWrapExisting)], found)
            continue
        if IPolyMesh.matches(md):
            found.append((child, IPolyMesh(child, WrapExistingFlag.kWrapExisting).getSchema(), chain))
        elif ISubD.matches(md):
            found.append((child, ISubD(child, WrapExistingFlag.kWrapExisting).getSchema(), chain))
        meshes_of(child, chain, found)


def world_points(file, selected):
    """The points alembic3d reads, in world space, at every frame time of the meshes."""
    arch = IArchive(file)
    found = []
    meshes_of(arch.getTop(), [], found)
    if selected:
        found = [f for f in found if f[0].getFullName() == selected]
    times = set()
    for _, schema, chain in found:
        ts = schema.getTimeSampling()
        for i in range(schema.getNumSamples()):
            times.add(ts.getSampleTime(i))
        for x in chain:
            xs = x.getSchema()
            if not xs.isConstant():
                for i in range(xs.getNumSamples()):
                    times.add(xs.getTimeSampling().getSampleTime(i))
    times = sorted(times)
    out = []
    vertices = 0
    triangles = 0
    for _, schema, chain in found:
        ts = schema.getTimeSampling()
        s0 = schema.getValue(ISampleSelector(ts.getSampleTime(0), ISampleSelector.TimeIndexType.kNearIndex))
        vertices += len(s0.getPositions())
        triangles += sum(c - 2 for c in s0.getFaceCounts())
    for t in times:
        for _, schema, chain in found:
            sel = ISampleSelector(t, ISampleSelector.TimeIndexType.kFloorIndex)
            pts = schema.getValue(sel).getPositions()
            world = None
            for x in chain:
                xs = x.getSchema()
                sample = xs.getValue(ISampleSelector(t, ISampleSelector.TimeIndexType.kFloorIndex))
                local = sample.getMatrix()
                if world is None or not sample.getInheritsXforms():
                    world = local
                else:
                    world = local * world
            for p in pts:
                if world is None:
                    out += [p[0], p[1], p[2]]
                else:
                    q = imath.V3d(p[0], p[1], p[2]) * world
                    out += [q[0], q[1], q[2]]
    return out, len(times), vertices, triangles


def check(file, expected_file):
    with open(expected_file, "rb") as f:
        raw = f.read()
    expected = struct.unpack("<%df" % (len(raw) // 4), raw)
    arch = IArchive(file)
    found = []
    meshes_of(arch.getTop(), [], found)
    result = {"meshes": [f[0].getFullName() for f in found]}
    obj, schema, chain = found[0]
    ts = schema.getTimeSampling()
    n = schema.getNumSamples()
    result["samples"] = n
    result["time_per_sample"] = ts.getTimeSamplingType().getTimePerCycle()
    result["uniform"] = ts.getTimeSamplingType().isUniform()
    result["topology"] = str(schema.getTopologyVariance())
    md = arch.getTop().getMetaData()
    result["archive_metadata"] = md.serialize()
    first = schema.getValue(ISampleSelector(ts.getSampleTime(0), ISampleSelector.TimeIndexType.kNearIndex))
    result["face_counts"] = sorted(set(first.getFaceCounts()))
    idx = list(first.getFaceIndices())
    result["faces"] = [idx[i:i + 3] for i in range(0, len(idx), 3)]
    result["chain"] = [str(x.getSchema().getValue().getMatrix()) for x in chain]
    differing = 0
    checked = 0
    k = 0
    for i in range(n):
        # An int argument would be taken as a time in seconds: select by the sample's time.
        near = ISampleSelector(ts.getSampleTime(i), ISampleSelector.TimeIndexType.kNearIndex)
        pts = schema.getValue(near).getPositions()
        for p in pts:
            for c in range(3):
                mine = struct.unpack("<f", struct.pack("<f", p[c]))[0]
                if k >= len(expected) or struct.pack("<f", mine) != struct.pack("<f", expected[k]):
                    differing += 1
                k += 1
                checked += 1
    result["coordinates_checked"] = checked
    result["coordinates_differing"] = differing + abs(len(expected) - checked)
    return result


if __name__ == "__main__":
    if sys.argv[1] == "write":
        print(json.dumps(write_cases(sys.argv[2])))
    elif sys.argv[1] == "check":
        print(json.dumps(check(sys.argv[2], sys.argv[3])))
    else:
        sys.exit("usage: abc_check.py write DIR | check FILE.abc EXPECTED.f32")
