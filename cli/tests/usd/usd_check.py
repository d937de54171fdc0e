"""usd-core (Pixar's USD on PyPI) as the reference client of animcodec's USD reader and writer.

Driven by cli/tests/usd.rs:

    python3 usd_check.py write DIR     # usd-core writes case-*-{usda,usdc,usdz,usd} layers (the
                                       # extension is the case name's last part; .usd holds a crate
                                       # file, .usdz a package of one) and, for each, CASE.json (fps,
                                       # vertex/frame counts, triangles) and CASE.f32 (every frame's
                                       # points as usd-core evaluates them, little-endian float32)
    python3 usd_check.py check FILE EXPECTED.f32 FPS
                                       # opens a layer animcodec wrote, compares the points at every
                                       # time sample with EXPECTED (bit for bit), runs the compliance
                                       # checker; prints one JSON object
    python3 usd_check.py export IN OUT # usd-core re-exports a layer (usdc -> usda)

Exit status 0 unless usd-core itself fails; the Rust test asserts on the JSON.
"""

import json
import struct
import sys

from pxr import Gf, Sdf, Usd, UsdGeom, UsdUtils, Vt


def fan(counts, indices, left_handed):
    """Triangles as animcodec reads them: each polygon fanned from its first corner."""
    tris, at = [], 0
    for n in counts:
        f = indices[at : at + n]
        for k in range(1, n - 1):
            tris.append([f[0], f[k + 1], f[k]] if left_handed else [f[0], f[k], f[k + 1]])
        at += n
    return tris


def awkward(i):
    """Float32 values with awkward decimal expansions, negative zero and wide exponents."""
    r = (i * 2654435761) % 1000003
    kinds = [-0.0, r * 1e-7, 1.0 / 3.0 + r, -(r ** 0.5) * 12345.678, 1e30 / (r + 1), r * 0.7, 1.17549435e-38 * (r % 97 + 1)]
    return struct.unpack("<f", struct.pack("<f", kinds[i % len(kinds)]))[0]


def write_cases(out):
    cases = []
    # 1. Two meshes (a triangle strip, a mixed polygon mesh with a left-handed orientation), 6
    #    time samples at 24 codes per second, one layer per format.
    for fmt in ("usda", "usdc"):
        name = f"case-two-meshes-{fmt}"
        stage = Usd.Stage.CreateNew(f"{out}/{name}.{fmt}")
        stage.SetTimeCodesPerSecond(24)
        stage.SetStartTimeCode(0)
        stage.SetEndTimeCode(5)
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
        root = UsdGeom.Xform.Define(stage, "/root")
        stage.SetDefaultPrim(root.GetPrim())
        frames, meshes = 6, []
        strip = UsdGeom.Mesh.Define(stage, "/root/strip")
        strip_counts, strip_idx = [3] * 5, []
        for v in range(5):
            strip_idx += [v, v + 1, v + 2]
        poly = UsdGeom.Mesh.Define(stage, "/root/poly")
        poly_counts, poly_idx = [4, 5, 3], [0, 1, 2, 3, 3, 2, 4, 5, 6, 6, 7, 0]
        poly.CreateOrientationAttr().Set(UsdGeom.Tokens.leftHanded)
        for mesh, nv, counts, idx in ((strip, 7, strip_counts, strip_idx), (poly, 8, poly_counts, poly_idx)):
            mesh.CreateFaceVertexCountsAttr().Set(Vt.IntArray(counts))
            mesh.CreateFaceVertexIndicesAttr().Set(Vt.IntArray(idx))
            meshes.append((mesh, nv, counts, idx))
        write_samples(out, name, stage, meshes, frames, 24.0, offset=1000)
        cases.append(name)
    # 2. One mesh, 40 frames at 30 codes per second, time codes 10, 12, ... (step 2: 15 fps).
    name = "case-step-two-usda"
    stage = Usd.Stage.CreateNew(f"{out}/{name}.usda")
    stage.SetTimeCodesPerSecond(30)
    mesh = UsdGeom.Mesh.Define(stage, "/grid")
    stage.SetDefaultPrim(mesh.GetPrim())
    nv, counts, idx = 30, [], []
    for r in range(4):
        for c in range(5):
            a = r * 6 + c
            counts.append(4)
            idx += [a, a + 1, a + 7, a + 6]
    mesh.CreateFaceVertexCountsAttr().Set(Vt.IntArray(counts))
    mesh.CreateFaceVertexIndicesAttr().Set(Vt.IntArray(idx))
    write_samples(out, name, stage, [(mesh, nv, counts, idx)], 40, 15.0, offset=5000, t0=10, step=2)
    cases.append(name)
    # 3. Mixed sampling in a crate file, large enough that usd-core integer-codes the topology
    #    arrays (16 elements or more): a 24x24 quad grid sampled at every frame, a second mesh
    #    sampled at every other frame (integer points, so the interpolated frames are exact in
    #    any evaluation order) and a static third mesh (a default value, no samples). The same
    #    layer is also written as a .usd (usd-core writes crate content there) and packaged
    #    as a .usdz.
    for ext in ("usdc", "usd"):
        name = f"case-mixed-{ext}"
        write_mixed(out, name, f"{out}/{name}.{ext}")
        cases.append(name)
    from pxr import UsdUtils

    # 4. Transforms: nested Xforms and a mesh with every kind of xformOp (translate, scale,
    #    rotateX/Y/Z and the six rotate orders, orient, transform, !invert!,
    #    !resetXformStack!), half/float/double precision, some time-sampled at a subset of
    #    the frames. Expected points: UsdGeom.XformCache's local-to-world matrix applied to the
    #    points at every frame.
    for ext in ("usda", "usdc"):
        name = f"case-xforms-{ext}"
        write_xforms(out, name, f"{out}/{name}.{ext}")
        cases.append(name)
    name = "case-mixed-usdz"
    if not UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(f"{out}/case-mixed-usdc.usdc"), f"{out}/{name}.usdz"):
        raise SystemExit("usd-core could not write the usdz package")
    for suffix in ("json", "f32"):
        with open(f"{out}/case-mixed-usdc.{suffix}", "rb") as src, open(f"{out}/{name}.{suffix}", "wb") as dst:
            dst.write(src.read())
    cases.append(name)
    print(json.dumps(cases))


def write_xforms(out, name, path):
    stage = Usd.Stage.CreateNew(path)
    stage.SetTimeCodesPerSecond(24)
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(5)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    root = UsdGeom.Xform.Define(stage, "/root")
    stage.SetDefaultPrim(root.GetPrim())
    t = root.AddTranslateOp(UsdGeom.XformOp.PrecisionDouble)
    for f in (0, 2, 4):
        t.Set(Gf.Vec3d(1.5 * f, -2.0, 0.25 * f * f), Usd.TimeCode(f))
    root.AddRotateXYZOp(UsdGeom.XformOp.PrecisionFloat).Set(Gf.Vec3f(10, 20, 30))
    root.AddScaleOp(UsdGeom.XformOp.PrecisionHalf).Set(Gf.Vec3h(2, 0.5, 1.5))
    child = UsdGeom.Xform.Define(stage, "/root/child")
    o = child.AddOrientOp(UsdGeom.XformOp.PrecisionFloat)
    o.Set(Gf.Quatf(1, 0, 0, 0), Usd.TimeCode(0))
    o.Set(Gf.Quatf(0.5, 0.5, 0.5, 0.5), Usd.TimeCode(5))
    pivot = child.AddTranslateOp(UsdGeom.XformOp.PrecisionFloat, "pivot")
    pivot.Set(Gf.Vec3f(0.5, 0.25, -1))
    child.AddRotateZYXOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Vec3d(-40, 15, 70))
    child.AddTranslateOp(UsdGeom.XformOp.PrecisionFloat, "pivot", isInverseOp=True)
    m = UsdGeom.Mesh.Define(stage, "/root/child/mesh")
    m.AddTransformOp().Set(Gf.Matrix4d(1, 0.2, 0, 0, 0, 1, 0, 0, 0.1, 0, 1, 0, 3, 4, 5, 1))
    m.AddRotateXOp(UsdGeom.XformOp.PrecisionFloat).Set(33)
    m.AddRotateYOp().Set(-12.5)
    m.AddRotateZOp(UsdGeom.XformOp.PrecisionHalf).Set(45)
    for op, v in ((m.AddRotateXZYOp(), (1, 2, 3)), (m.AddRotateYXZOp(), (4, 5, 6)), (m.AddRotateYZXOp(), (7, 8, 9)), (m.AddRotateZXYOp(), (10, 11, 12))):
        op.Set(Gf.Vec3f(*v))
    reset = UsdGeom.Mesh.Define(stage, "/root/child/reset")
    reset.SetResetXformStack(True)
    reset.AddTranslateOp().Set(Gf.Vec3d(100, 0, 0))
    meshes = []
    for mesh, nv in ((m, 6), (reset, 3)):
        counts = [3] * (nv - 2)
        idx = [i for k in range(nv - 2) for i in (0, k + 1, k + 2)]
        mesh.CreateFaceVertexCountsAttr().Set(Vt.IntArray(counts))
        mesh.CreateFaceVertexIndicesAttr().Set(Vt.IntArray(idx))
        for f in range(6):
            pts = [Gf.Vec3f(awkward(31 * f + 3 * v) % 7, v * 0.5 - f, (v * f) % 3) for v in range(nv)]
            mesh.GetPointsAttr().Set(Vt.Vec3fArray(pts), Usd.TimeCode(f))
        meshes.append((mesh, nv, counts, idx))
    stage.GetRootLayer().Save()
    positions = []
    for f in range(6):
        cache = UsdGeom.XformCache(Usd.TimeCode(f))
        for mesh, _, _, _ in meshes:
            world = cache.GetLocalToWorldTransform(mesh.GetPrim())
            for p in mesh.GetPointsAttr().Get(Usd.TimeCode(f)):
                q = world.Transform(Gf.Vec3d(p[0], p[1], p[2]))
                positions += [q[0], q[1], q[2]]
    write_expected(out, name, meshes, positions, 24.0, 6, transformed=True)


def write_mixed(out, name, path):
    stage = Usd.Stage.CreateNew(path)
    stage.SetTimeCodesPerSecond(25)
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(8)
    root = UsdGeom.Xform.Define(stage, "/root")
    stage.SetDefaultPrim(root.GetPrim())
    n = 24
    grid = UsdGeom.Mesh.Define(stage, "/root/grid")
    counts, idx = [], []
    for r in range(n):
        for c in range(n):
            a = r * (n + 1) + c
            counts.append(4)
            idx += [a, a + 1, a + n + 2, a + n + 1]
    grid.CreateFaceVertexCountsAttr().Set(Vt.IntArray(counts))
    grid.CreateFaceVertexIndicesAttr().Set(Vt.IntArray(idx))
    nv = (n + 1) * (n + 1)
    for f in range(9):
        pts = [Gf.Vec3f(awkward(7 * f + 3 * v), awkward(7 * f + 3 * v + 1), awkward(7 * f + 3 * v + 2)) for v in range(nv)]
        grid.GetPointsAttr().Set(Vt.Vec3fArray(pts), Usd.TimeCode(f))
    half = UsdGeom.Mesh.Define(stage, "/root/half")
    half.CreateFaceVertexCountsAttr().Set(Vt.IntArray([3, 3]))
    half.CreateFaceVertexIndicesAttr().Set(Vt.IntArray([0, 1, 2, 2, 1, 3]))
    for f in range(0, 9, 2):
        half.GetPointsAttr().Set(Vt.Vec3fArray([Gf.Vec3f(v + f, -2 * f, 3 * v - f) for v in range(4)]), Usd.TimeCode(f))
    static = UsdGeom.Mesh.Define(stage, "/root/static")
    static.CreateFaceVertexCountsAttr().Set(Vt.IntArray([3]))
    static.CreateFaceVertexIndicesAttr().Set(Vt.IntArray([0, 2, 1]))
    static.GetPointsAttr().Set(Vt.Vec3fArray([Gf.Vec3f(0.1, 0.2, 0.3), Gf.Vec3f(1, 0, 0), Gf.Vec3f(0, 1e-7, 0)]))
    stage.GetRootLayer().Save()
    meshes = [(grid, nv, counts, idx), (half, 4, [3, 3], [0, 1, 2, 2, 1, 3]), (static, 3, [3], [0, 2, 1])]
    positions = []
    for f in range(9):
        for mesh, _, _, _ in meshes:
            for p in mesh.GetPointsAttr().Get(Usd.TimeCode(f)):
                positions += [p[0], p[1], p[2]]
    write_expected(out, name, meshes, positions, 25.0, 9)


def write_samples(out, name, stage, meshes, frames, fps, offset, t0=0, step=1):
    positions = []
    for f in range(frames):
        base = offset + f * 97
        for mesh, nv, _, _ in meshes:
            pts = [Gf.Vec3f(awkward(base + 3 * v), awkward(base + 3 * v + 1), awkward(base + 3 * v + 2)) for v in range(nv)]
            mesh.GetPointsAttr().Set(Vt.Vec3fArray(pts), Usd.TimeCode(t0 + f * step))
            base += 3 * nv
            for p in pts:
                positions += [p[0], p[1], p[2]]
    stage.GetRootLayer().Save()
    write_expected(out, name, meshes, positions, fps, frames)


def write_expected(out, name, meshes, positions, fps, frames, transformed=False):
    tris, offset_v = [], 0
    for mesh, nv, counts, idx in meshes:
        left = mesh.GetOrientationAttr().Get() == UsdGeom.Tokens.leftHanded
        tris += [[i + offset_v for i in t] for t in fan(counts, idx, left)]
        offset_v += nv
    with open(f"{out}/{name}.json", "w") as fh:
        meta = {"fps": fps, "frames": frames, "vertices": offset_v, "triangles": tris, "transformed": transformed}
        json.dump(meta, fh)
    with open(f"{out}/{name}.f32", "wb") as fh:
        fh.write(struct.pack(f"<{len(positions)}f", *positions))


def check(path, expected_path, fps):
    result = {"errors": []}
    stage = Usd.Stage.Open(path)
    if stage is None:
        print(json.dumps({"errors": ["usd-core cannot open the layer"]}))
        return
    with open(expected_path, "rb") as fh:
        raw = fh.read()
    expected = struct.unpack(f"<{len(raw) // 4}f", raw)
    meshes = [UsdGeom.Mesh(p) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    result["meshes"] = len(meshes)
    result["time_codes_per_second"] = stage.GetTimeCodesPerSecond()
    result["frames_per_second"] = stage.GetFramesPerSecond()
    result["start_time_code"] = stage.GetStartTimeCode()
    result["end_time_code"] = stage.GetEndTimeCode()
    result["up_axis"] = str(UsdGeom.GetStageUpAxis(stage))
    result["meters_per_unit"] = UsdGeom.GetStageMetersPerUnit(stage)
    result["default_prim"] = str(stage.GetDefaultPrim().GetPath())
    result["format"] = stage.GetRootLayer().GetFileFormat().formatId
    mesh = meshes[0]
    times = mesh.GetPointsAttr().GetTimeSamples()
    result["time_samples"] = len(times)
    per_frame = len(expected) // max(len(times), 1)
    differing, checked = 0, 0
    for k, t in enumerate(times):
        pts = mesh.GetPointsAttr().Get(t)
        want = expected[k * per_frame : (k + 1) * per_frame]
        got = [c for p in pts for c in (p[0], p[1], p[2])]
        if len(got) != len(want):
            result["errors"].append(f"time {t}: {len(got)} coordinates, expected {len(want)}")
            continue
        for a, b in zip(got, want):
            checked += 1
            if struct.pack("<f", a) != struct.pack("<f", b):
                differing += 1
        # The extent must bound the points (UsdGeom's own computation).
        ext = mesh.GetExtentAttr().Get(t)
        computed = UsdGeom.PointBased.ComputeExtent(pts)
        if ext is None or list(ext[0]) != list(computed[0]) or list(ext[1]) != list(computed[1]):
            result["errors"].append(f"time {t}: extent {ext} differs from UsdGeom's {computed}")
    result["coordinates_checked"] = checked
    result["coordinates_differing"] = differing
    result["times"] = [float(t) for t in times[:3]]
    counts = list(mesh.GetFaceVertexCountsAttr().Get())
    indices = list(mesh.GetFaceVertexIndicesAttr().Get())
    result["triangles"] = fan(counts, indices, mesh.GetOrientationAttr().Get() == UsdGeom.Tokens.leftHanded)
    # The checks `usdchecker` runs: usd-core 25.x+ (here 26.11) runs them through the
    # UsdValidation framework (every registered validator); older releases had the Python
    # UsdUtils.ComplianceChecker, used when present.
    errors, warnings, failed = [], [], []
    if hasattr(UsdUtils, "ComplianceChecker"):
        checker = UsdUtils.ComplianceChecker()
        checker.CheckCompliance(path)
        errors, failed, warnings = list(checker.GetErrors()), list(checker.GetFailedChecks()), list(checker.GetWarnings())
        result["checker"] = "UsdUtils.ComplianceChecker"
    else:
        from pxr import UsdValidation

        validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
        for e in UsdValidation.ValidationContext(validators).Validate(stage):
            text = f"{e.GetName()}: {e.GetMessage()}"
            kind = e.GetType()
            if kind == UsdValidation.ValidationErrorType.Error:
                errors.append(text)
            elif kind == UsdValidation.ValidationErrorType.Warn:
                warnings.append(text)
            elif kind != UsdValidation.ValidationErrorType.Info:
                failed.append(text)
        result["checker"] = f"UsdValidation ({len(validators)} validators)"
    result["compliance_errors"] = errors
    result["compliance_failed_checks"] = failed
    result["compliance_warnings"] = warnings
    print(json.dumps(result))


def main():
    cmd = sys.argv[1]
    if cmd == "write":
        write_cases(sys.argv[2])
    elif cmd == "check":
        check(sys.argv[2], sys.argv[3], float(sys.argv[4]))
    elif cmd == "export":
        layer = Sdf.Layer.FindOrOpen(sys.argv[2])
        layer.Export(sys.argv[3])
    else:
        raise SystemExit(f"unknown command {cmd}")


if __name__ == "__main__":
    main()
