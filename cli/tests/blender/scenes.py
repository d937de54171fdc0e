"""Blender 5 (the bpy module, headless) builds the scenes a studio hands over and exports them
as vertex caches. Run by cli/tests/blender_scenes.rs:

    python3 scenes.py -- OUTDIR ROBOT_GLB

Scenes: `shape_keys` (a grid deformed by two animated shape keys), `robot` (RobotExpressive's
armature-skinned character playing its `Walking` clip, imported with Blender's glTF importer;
skipped when ROBOT_GLB is `-`), `parent` (a cube under an Empty whose location and rotation are
animated), `two_meshes` (a shape-keyed grid and a cube moved by its own object animation). For
each scene NAME: NAME.abc (Alembic), NAME.usdc and NAME.usdz (USD; meshes baked to time-sampled
points: shape keys and armatures are not written as UsdSkel; NAME-skel.usdc with the
exporter's defaults, UsdSkel, for `shape_keys` and `robot`), NAME.f32 (Blender's evaluated
world-space positions, little-endian float32, frame-major, objects in name order, vertices in
mesh order, Blender's Z-up axes) and one JSON line `SCENE {...}` on stdout: frames, fps,
objects (name, vertices).
"""

import json
import math
import struct
import sys

import bpy

args = sys.argv[sys.argv.index("--") + 1 :]
outdir, robot_glb = args[0], args[1]
FPS = 24


def reset(frames):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = FPS, 1.0
    scene.frame_start, scene.frame_end = 1, frames
    return scene


def grid(name, size=8, offset=(0.0, 0.0, 0.0)):
    verts = [(x / (size - 1) * 2 - 1 + offset[0], y / (size - 1) * 2 - 1 + offset[1], offset[2])
             for y in range(size) for x in range(size)]
    faces = [(y * size + x, y * size + x + 1, (y + 1) * size + x + 1, (y + 1) * size + x)
             for y in range(size - 1) for x in range(size - 1)]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def cube(name, location=(0.0, 0.0, 0.0)):
    s = 0.5
    verts = [(x * s, y * s, z * s) for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)]
    faces = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    return obj


def shape_keys(obj, frames):
    obj.shape_key_add(name="Basis")
    wave = obj.shape_key_add(name="wave")
    bulge = obj.shape_key_add(name="bulge")
    for i, v in enumerate(obj.data.vertices):
        x, y, z = v.co
        wave.data[i].co = (x, y, z + 0.4 * math.sin(3 * x))
        bulge.data[i].co = (x * 1.2, y * 1.2, z + 0.3 * (1 - x * x) * (1 - y * y))
    for f in range(1, frames + 1):
        t = (f - 1) / max(frames - 1, 1)
        wave.value = 0.5 + 0.5 * math.sin(2 * math.pi * t)
        wave.keyframe_insert("value", frame=f)
        bulge.value = t
        bulge.keyframe_insert("value", frame=f)


def build(name):
    if name == "shape_keys":
        scene = reset(12)
        shape_keys(grid("sheet"), 12)
    elif name == "parent":
        scene = reset(10)
        rig = bpy.data.objects.new("rig", None)
        scene.collection.objects.link(rig)
        body = cube("body", location=(1.0, 0.0, 0.5))
        body.parent = rig
        for f in range(1, 11):
            rig.location = (0.2 * f, 0.1 * f * f / 10, 0.0)
            rig.rotation_euler = (0.0, 0.1 * f, 0.25 * f)
            rig.keyframe_insert("location", frame=f)
            rig.keyframe_insert("rotation_euler", frame=f)
    elif name == "two_meshes":
        scene = reset(8)
        shape_keys(grid("sheet", size=6), 8)
        box = cube("box", location=(3.0, 0.0, 0.0))
        for f in range(1, 9):
            box.location = (3.0, 0.3 * f, 0.1 * f)
            box.rotation_euler = (0.2 * f, 0.0, 0.0)
            box.scale = (1.0 + 0.05 * f, 1.0, 1.0)
            box.keyframe_insert("location", frame=f)
            box.keyframe_insert("rotation_euler", frame=f)
            box.keyframe_insert("scale", frame=f)
    elif name == "robot":
        scene = reset(1)
        bpy.ops.import_scene.gltf(filepath=robot_glb)
        arm = next(o for o in scene.objects if o.type == "ARMATURE")
        action = bpy.data.actions["Walking"]
        arm.animation_data.action = action
        if hasattr(arm.animation_data, "action_slot") and action.slots:
            arm.animation_data.action_slot = action.slots[0]
        start, end = (int(round(x)) for x in action.frame_range)
        scene.frame_start, scene.frame_end = start, end
    else:
        raise SystemExit(f"unknown scene {name}")
    return scene


def evaluated(scene, path):
    # Visible meshes only: the glTF importer adds a hidden bone-display shape (`Icosphere`),
    # which the exporters leave out too.
    meshes = sorted((o for o in scene.objects if o.type == "MESH" and o.visible_get()), key=lambda o: o.name)
    info = []
    with open(path, "wb") as fh:
        for f in range(scene.frame_start, scene.frame_end + 1):
            scene.frame_set(f)
            depsgraph = bpy.context.evaluated_depsgraph_get()
            for o in meshes:
                ev = o.evaluated_get(depsgraph)
                m = ev.to_mesh()
                coords = []
                for v in m.vertices:
                    coords.extend(ev.matrix_world @ v.co)
                if f == scene.frame_start:
                    info.append({"name": o.name, "vertices": len(m.vertices)})
                fh.write(struct.pack(f"<{len(coords)}f", *coords))
                ev.to_mesh_clear()
    return info


names = ["shape_keys", "parent", "two_meshes"] + ([] if robot_glb == "-" else ["robot"])
for name in names:
    scene = build(name)
    base = f"{outdir}/{name}"
    objects = evaluated(scene, base + ".f32")
    start, end = scene.frame_start, scene.frame_end
    bpy.ops.wm.alembic_export(filepath=base + ".abc", start=start, end=end)
    for ext in ("usdc", "usdz"):
        bpy.ops.wm.usd_export(filepath=f"{base}.{ext}", export_animation=True,
                              export_shapekeys=False, export_armatures=False)
    # The exporter's defaults: shape keys and armatures as UsdSkel (BlendShapes, Skeleton +
    # SkelAnimation), which the reader evaluates.
    if name in ("shape_keys", "robot"):
        bpy.ops.wm.usd_export(filepath=f"{base}-skel.usdc", export_animation=True)
    print("SCENE " + json.dumps({"name": name, "frames": end - start + 1, "fps": FPS, "objects": objects}))
