"""Blender 5 (the `bpy` module from PyPI, headless) as a client of what animcodec writes. Run by
cli/tests/blender.rs:

    python3 evaluate.py -- MODE FILE OBJ FPS OUT FRAME...

MODE pc2: a mesh is built from OBJ's vertices and faces (in file order, no importer axis
conversion) and given a Mesh Cache modifier reading the PC2 FILE (Blender's native axes, frame
start 0). MODE abc / usd: FILE (our .abc / .usdc) is imported with Blender's Alembic / USD
importer. MODE glb: FILE is imported with Blender's glTF importer (shape keys, node animation;
its Y-up to Z-up conversion is undone below). For each FRAME (a scene frame, at FPS), the
depsgraph-evaluated mesh's world-space vertex positions are appended to OUT as little-endian
float32, in our axes (glTF's Y up for glb). Prints one JSON line: what was evaluated.
"""

import json
import struct
import sys

import bpy

args = sys.argv[sys.argv.index("--") + 1 :]
mode, path, obj_path, fps, out = args[0], args[1], args[2], float(args[3]), args[4]
frames = [int(f) for f in args[5:]]

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.render.fps = round(fps)
scene.render.fps_base = round(fps) / fps


def read_obj(p):
    verts, faces = [], []
    with open(p) as fh:
        for line in fh:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                verts.append(tuple(float(x) for x in parts[1:4]))
            elif parts[0] == "f":
                faces.append(tuple(int(x.split("/")[0]) - 1 for x in parts[1:]))
    return verts, faces


if mode == "pc2":
    verts, faces = read_obj(obj_path)
    mesh = bpy.data.meshes.new("cache")
    mesh.from_pydata(verts, [], faces)
    obj = bpy.data.objects.new("cache", mesh)
    scene.collection.objects.link(obj)
    mod = obj.modifiers.new("MeshCache", "MESH_CACHE")
    mod.cache_format = "PC2"
    mod.filepath = path
    mod.frame_start = 0.0
    mod.forward_axis = "POS_Y"
    mod.up_axis = "POS_Z"
    objects = [obj]
    convert = lambda v: (v[0], v[1], v[2])
elif mode == "glb":
    bpy.ops.import_scene.gltf(filepath=path)
    objects = [o for o in scene.objects if o.type == "MESH"]
    # The importer sets each shape key's slider range from the mesh's default weights and
    # clamps animated values to it: reported, not changed (what a user sees).
    report_sliders = []
    for o in objects:
        for kb in o.data.shape_keys.key_blocks if o.data.shape_keys else []:
            report_sliders.append([kb.slider_min, kb.slider_max])
    # The importer turns glTF's Y up into Blender's Z up: (x, y, z) -> (x, -z, y).
    convert = lambda v: (v[0], v[2], -v[1])
elif mode in ("abc", "usd"):
    # Blender's Alembic and USD importers turn the file's Y up into Z up, as the glTF one does.
    if mode == "abc":
        bpy.ops.wm.alembic_import(filepath=path)
    else:
        bpy.ops.wm.usd_import(filepath=path)
    objects = [o for o in scene.objects if o.type == "MESH"]
    convert = lambda v: (v[0], v[2], -v[1])
else:
    raise SystemExit(f"unknown mode {mode}")

report = {"objects": len(objects), "frames": frames, "vertices": []}
with open(out, "wb") as fh:
    for f in frames:
        scene.frame_set(f)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        for o in objects:
            ev = o.evaluated_get(depsgraph)
            m = ev.to_mesh()
            mw = ev.matrix_world
            coords = []
            for v in m.vertices:
                w = mw @ v.co
                coords.extend(convert(w))
            if f == frames[0]:
                report["vertices"].append(len(m.vertices))
            fh.write(struct.pack(f"<{len(coords)}f", *coords))
            ev.to_mesh_clear()
    if mode == "glb":
        report["sliders"] = report_sliders
        report["shape_keys"] = [len(o.data.shape_keys.key_blocks) if o.data.shape_keys else 0 for o in objects]
        acts = [a for a in bpy.data.actions]
        report["action_ranges"] = [list(a.frame_range) for a in acts]
print("BLENDER_RESULT " + json.dumps(report))
