"""UsdSkel layers written by usd-core, and usd-core's own evaluation of them. Run by
cli/tests/usd_skel.rs (and cli/tests/blender_scenes.rs for the reference mode):

    python3 skel_check.py write OUTDIR
        Writes OUTDIR/skel.usdc (and its text twin skel.usda, from Usd.Stage.Export): an
        animated Xform above a SkelRoot holding a three-joint Skeleton whose SkelAnimation
        lists its joints in another order; a tube skinned with three influences per point
        (some zero), a geomBindTransform and its own `skel:joints` order; a box bound rigidly
        (constant interpolation) through a binding inherited from the SkelRoot; and, under a
        second SkelRoot, a grid moved by its own xformOp and two blend shapes (one sparse, via
        pointIndices) whose weights the animation lists in another order. Also writes files
        that must be refused: inbetweens.usda (an inbetween shape) and dq.usda
        (dual-quaternion skinning).

    python3 skel_check.py reference FILE OUT.f32
        Evaluates FILE with usd-core's UsdSkel (UsdSkel.Cache, SkeletonQuery.
        ComputeSkinningTransforms, SkinningQuery.ComputeSkinnedPoints, BlendShapeQuery) and
        writes world-space points, float32 little-endian, frame-major (integer time codes
        from startTimeCode to endTimeCode), meshes in traversal order; prints one JSON line
        {"frames", "vertices"}.

    python3 skel_check.py export IN OUT
        Writes the layer IN again as OUT (its format by OUT's extension), with usd-core.
"""

import json
import math
import struct
import sys

from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

FRAMES = 11


def quat(axis, degrees):
    r = Gf.Rotation(Gf.Vec3d(*axis), degrees).GetQuat()
    return Gf.Quatf(r.GetReal(), Gf.Vec3f(r.GetImaginary()))


def grid_mesh(stage, path, nx, ny, size, z=0.0):
    mesh = UsdGeom.Mesh.Define(stage, path)
    pts = [Gf.Vec3f(x * size / (nx - 1), y * size / (ny - 1), z) for y in range(ny) for x in range(nx)]
    counts, idx = [], []
    for y in range(ny - 1):
        for x in range(nx - 1):
            a = y * nx + x
            counts.append(4)
            idx += [a, a + 1, a + nx + 1, a + nx]
    mesh.CreatePointsAttr(Vt.Vec3fArray(pts))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray(counts))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray(idx))
    return mesh, pts


def write(outdir):
    stage = Usd.Stage.CreateInMemory()
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(FRAMES - 1)
    stage.SetTimeCodesPerSecond(24)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    world = UsdGeom.Xform.Define(stage, "/World")
    move = world.AddTranslateOp()
    turn = world.AddRotateYOp()
    for f in range(FRAMES):
        move.Set(Gf.Vec3d(0.1 * f, 0.0, -0.05 * f), f)
        turn.Set(4.0 * f, f)

    # --- Skinning: a three-joint chain along +X.
    root = UsdSkel.Root.Define(stage, "/World/Rig")
    skel = UsdSkel.Skeleton.Define(stage, "/World/Rig/Skel")
    joints = ["hip", "hip/knee", "hip/knee/ankle"]
    skel.CreateJointsAttr(joints)
    rest = [Gf.Matrix4d().SetTranslate(Gf.Vec3d(0.2, 0, 0)), Gf.Matrix4d().SetTranslate(Gf.Vec3d(1, 0, 0)),
            Gf.Matrix4d().SetTranslate(Gf.Vec3d(1, 0, 0))]
    bind = [rest[0], rest[1] * rest[0], rest[2] * rest[1] * rest[0]]
    skel.CreateRestTransformsAttr(Vt.Matrix4dArray(rest))
    skel.CreateBindTransformsAttr(Vt.Matrix4dArray(bind))
    anim = UsdSkel.Animation.Define(stage, "/World/Rig/Skel/Anim")
    # The animation lists the joints in another order than the Skeleton.
    order = [2, 0, 1]
    anim.CreateJointsAttr([joints[i] for i in order])
    tr, ro, sc = anim.CreateTranslationsAttr(), anim.CreateRotationsAttr(), anim.CreateScalesAttr()
    for f in range(FRAMES):
        t = [Gf.Vec3f(0.2, 0.05 * f, 0), Gf.Vec3f(1, 0, 0), Gf.Vec3f(1, 0, 0.02 * f)]
        r = [quat((0, 0, 1), 3.0 * f), quat((0, 0, 1), 6.0 * f), quat((0, 1, 0), -5.0 * f)]
        s = [Gf.Vec3h(1, 1, 1), Gf.Vec3h(1, 1, 1), Gf.Vec3h(1 + 0.03 * f, 1, 1)]
        tr.Set(Vt.Vec3fArray([t[i] for i in order]), f)
        ro.Set(Vt.QuatfArray([r[i] for i in order]), f)
        sc.Set(Vt.Vec3hArray([s[i] for i in order]), f)
    UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])
    # The SkelRoot binds the Skeleton for every prim below it (inherited binding).
    UsdSkel.BindingAPI.Apply(root.GetPrim()).CreateSkeletonRel().SetTargets([skel.GetPath()])

    tube, pts = grid_mesh(stage, "/World/Rig/Tube", 13, 3, 2.4)
    binding = UsdSkel.BindingAPI.Apply(tube.GetPrim())
    # The mesh's own joint order, reversed: index 0 is the ankle.
    binding.CreateJointsAttr([joints[2], joints[1], joints[0]])
    k = 3
    indices, weights = [], []
    for p in pts:
        x = p[0] - 0.0
        w_hip = max(0.0, 1.0 - abs(x - 0.0) / 1.2)
        w_knee = max(0.0, 1.0 - abs(x - 1.2) / 1.2)
        w_ankle = max(0.0, 1.0 - abs(x - 2.4) / 1.2)
        total = w_hip + w_knee + w_ankle
        indices += [2, 1, 0]
        weights += [w_hip / total, w_knee / total, w_ankle / total]
    binding.CreateJointIndicesPrimvar(False, k).Set(Vt.IntArray(indices))
    binding.CreateJointWeightsPrimvar(False, k).Set(Vt.FloatArray(weights))
    # Points authored 0.2 left of where they were bound.
    binding.CreateGeomBindTransformAttr(Gf.Matrix4d().SetTranslate(Gf.Vec3d(0.2, -0.1, 0)))

    box, _ = grid_mesh(stage, "/World/Rig/Box", 2, 2, 0.3, z=0.1)
    binding = UsdSkel.BindingAPI.Apply(box.GetPrim())
    binding.CreateJointIndicesPrimvar(True, 1).Set(Vt.IntArray([2]))
    binding.CreateJointWeightsPrimvar(True, 1).Set(Vt.FloatArray([1.0]))

    # --- Blend shapes, under their own SkelRoot.
    root2 = UsdSkel.Root.Define(stage, "/World/Face")
    skel2 = UsdSkel.Skeleton.Define(stage, "/World/Face/Skel")
    skel2.CreateJointsAttr(["j"])
    skel2.CreateRestTransformsAttr(Vt.Matrix4dArray([Gf.Matrix4d(1)]))
    skel2.CreateBindTransformsAttr(Vt.Matrix4dArray([Gf.Matrix4d(1)]))
    anim2 = UsdSkel.Animation.Define(stage, "/World/Face/Skel/Anim")
    anim2.CreateBlendShapesAttr(["smile", "wave"])
    wattr = anim2.CreateBlendShapeWeightsAttr()
    for f in range(FRAMES):
        wattr.Set(Vt.FloatArray([f / (FRAMES - 1), math.sin(f * 0.7)]), f)
    UsdSkel.BindingAPI.Apply(skel2.GetPrim()).CreateAnimationSourceRel().SetTargets([anim2.GetPath()])
    face, fpts = grid_mesh(stage, "/World/Face/Grid", 6, 5, 1.0)
    face.AddTranslateOp().Set(Gf.Vec3d(0, 2, 0))
    binding = UsdSkel.BindingAPI.Apply(face.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skel2.GetPath()])
    binding.CreateBlendShapesAttr(["wave", "smile"])
    wave = UsdSkel.BlendShape.Define(stage, "/World/Face/Grid/wave")
    wave.CreateOffsetsAttr(Vt.Vec3fArray([Gf.Vec3f(0, 0, 0.2 * math.sin(p[0] * 4)) for p in fpts]))
    smile = UsdSkel.BlendShape.Define(stage, "/World/Face/Grid/smile")
    sparse = [1, 2, 3, 4, 7, 10]
    smile.CreatePointIndicesAttr(Vt.IntArray(sparse))
    smile.CreateOffsetsAttr(Vt.Vec3fArray([Gf.Vec3f(0, 0.1 + 0.01 * i, 0.05) for i in sparse]))
    binding.CreateBlendShapeTargetsRel().SetTargets([wave.GetPath(), smile.GetPath()])

    stage.GetRootLayer().Export(f"{outdir}/skel.usdc")
    stage.GetRootLayer().Export(f"{outdir}/skel.usda")

    # --- Files to refuse.
    smile.CreateInbetween("half").SetOffsets(Vt.Vec3fArray([Gf.Vec3f(0, 0.05, 0)] * len(sparse)))
    smile.GetInbetween("half").SetWeight(0.5)
    stage.GetRootLayer().Export(f"{outdir}/inbetweens.usda")
    smile.GetPrim().RemoveProperty("inbetweens:half")
    UsdSkel.BindingAPI(tube.GetPrim()).CreateSkinningMethodAttr().Set(UsdSkel.Tokens.dualQuaternion)
    stage.GetRootLayer().Export(f"{outdir}/dq.usda")


def reference(path, out):
    stage = Usd.Stage.Open(path)
    cache = UsdSkel.Cache()
    queries = {}
    for prim in stage.Traverse():
        if prim.IsA(UsdSkel.Root):
            root = UsdSkel.Root(prim)
            cache.Populate(root, Usd.PrimDefaultPredicate)
            for binding in cache.ComputeSkelBindings(root, Usd.PrimDefaultPredicate):
                skel_query = cache.GetSkelQuery(binding.GetSkeleton())
                for skinning in binding.GetSkinningTargets():
                    queries[skinning.GetPrim().GetPath()] = (skel_query, skinning)
    meshes = [p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    start, end = int(stage.GetStartTimeCode()), int(stage.GetEndTimeCode())
    vertices = 0
    with open(out, "wb") as fh:
        for t in range(start, end + 1):
            xf = UsdGeom.XformCache(t)
            for prim in meshes:
                points = UsdGeom.Mesh(prim).GetPointsAttr().Get(t)
                world = xf.GetLocalToWorldTransform(prim)
                if prim.GetPath() in queries:
                    skel_query, skinning = queries[prim.GetPath()]
                    anim = skel_query.GetAnimQuery()
                    if skinning.HasBlendShapes() and anim:
                        shapes = UsdSkel.BlendShapeQuery(UsdSkel.BindingAPI(prim))
                        weights = anim.ComputeBlendShapeWeights(t)
                        mapper = skinning.GetBlendShapeMapper()
                        if mapper:
                            weights = mapper.Remap(weights)
                        sub, bs_idx, sub_idx = shapes.ComputeSubShapeWeights(weights)
                        shapes.ComputeDeformedPoints(sub, bs_idx, sub_idx, shapes.ComputeBlendShapePointIndices(),
                                                     shapes.ComputeSubShapePointOffsets(), points)
                    if skinning.HasJointInfluences():
                        xforms = skel_query.ComputeSkinningTransforms(t)
                        assert skinning.ComputeSkinnedPoints(xforms, points, t), prim.GetPath()
                        world = xf.GetLocalToWorldTransform(skel_query.GetPrim())
                coords = []
                for p in points:
                    coords.extend(world.Transform(Gf.Vec3d(p)))
                if t == start:
                    vertices += len(points)
                fh.write(struct.pack(f"<{len(coords)}f", *coords))
    print(json.dumps({"frames": end - start + 1, "vertices": vertices}))


if __name__ == "__main__":
    if sys.argv[1] == "write":
        write(sys.argv[2])
    elif sys.argv[1] == "export":
        assert Sdf.Layer.FindOrOpen(sys.argv[2]).Export(sys.argv[3])
    else:
        reference(sys.argv[2], sys.argv[3])
