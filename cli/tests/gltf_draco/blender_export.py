# Re-exports a glTF file with Blender's glTF exporter twice: plain, and with Draco mesh
# compression (`export_draco_mesh_compression_enable`, the exporter's "Compression" checkbox,
# default settings: level 6, 14 position bits), for cli/tests/gltf_draco.rs.
#
#   python blender_export.py SRC.glb PLAIN.glb DRACO.glb [CLIP ...]
#
# Runs under Blender as a Python module (`pip install bpy`). With CLIP names, every other
# action is deleted before the export, so only those clips are written. Prints one line
# `EXPORT_RESULT {json}` with the exported animation names.
import json
import sys

import bpy

src, plain, draco, *clips = sys.argv[1:]


def load():
    """A fresh scene holding SRC (only CLIP actions, when given): each export starts from one,
    since an export leaves the scene changed (the exporter assigns each action in turn) and a
    second export from the same scene plays differently."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=src)
    if clips:
        missing = [c for c in clips if c not in bpy.data.actions]
        if missing:
            raise SystemExit(f"no action named {missing} in {src}")
        for action in list(bpy.data.actions):
            if action.name not in clips:
                bpy.data.actions.remove(action)
    return sorted(a.name for a in bpy.data.actions)


for path, compress in [(plain, False), (draco, True)]:
    kept = load()
    bpy.ops.export_scene.gltf(
        filepath=path,
        export_format="GLB",
        export_draco_mesh_compression_enable=compress,
    )
print("EXPORT_RESULT " + json.dumps({"actions": kept, "blender": bpy.app.version_string}))
