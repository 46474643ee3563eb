"""Load a whole tetfsi export into Blender as sequences: the smoke and each surface over time.

    blender -P scripts/blender_load_export.py -- OUT              # Blender's window, loaded
    blender -b --factory-startup -P scripts/blender_load_export.py -- OUT --blend scene.blend

or, in a running Blender, the Text Editor: open this file, set OUT below, Run Script.

- OUT/vdb/fluid_*.vdb become one volume object `fluid` whose file follows the frame (Blender's
  own VDB sequence, as File > Import > OpenVDB with every file selected), with a Principled
  Volume reading the `density` grid; moved by −h/2 on each axis because Blender 3.4 renders
  OpenVDB voxels half a voxel off (scripts/blender_check.py measures it).
- OUT/ply/<name>_<frame>.ply become one mesh object per name whose mesh follows the frame: every
  frame's mesh is imported once (kept with a fake user) and a frame-change handler shows the
  current one. The handler is this file, stored in the .blend as the text `tetfsi_sequences.py`
  with Register on, so it comes back when the .blend is opened with Python scripts allowed
  (Blender asks, or Preferences > Save & Load > Auto Run Python Scripts).
- Blender's frame 1 shows tetfsi's frame 0 (as Blender's VDB sequences count), the scene's
  frame range covers the export, and the frame rate is the export's (1 / the time between the
  first two frames; fps / fps_base when that is not a whole number), so playback is real time.

Axes and units need nothing: tetfsi's scenes are z up in metres, as Blender is.
"""

import glob
import json
import math
import os
import re
import sys

import bpy

OUT = ""  # set this when running from Blender's Text Editor (no command line arguments)
HANDLER = "tetfsi_sequences"
PLY_NAME = re.compile(r"(.+)_(\d{6})\.ply$")


def show_frame(scene, *_):
    """The frame-change handler: each surface object shows its mesh of scene's frame."""
    frame = scene.frame_current - 1  # Blender's frame 1 is tetfsi's frame 0
    for obj in scene.objects:
        prefix = obj.get("tetfsi_meshes")
        if not prefix:
            continue
        numbers = sorted(int(m.name[len(prefix):]) for m in bpy.data.meshes
                         if m.name.startswith(prefix) and m.name[len(prefix):].isdigit())
        if not numbers:
            continue
        shown = max([n for n in numbers if n <= frame] or numbers[:1])
        obj.data = bpy.data.meshes[f"{prefix}{shown:06d}"]


def register():
    handlers = bpy.app.handlers.frame_change_pre
    for h in [h for h in handlers if getattr(h, "__name__", "") == "show_frame"]:
        handlers.remove(h)
    handlers.append(show_frame)


def smoke_material():
    mat = bpy.data.materials.new("tetfsi_smoke")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    for n in list(nodes):
        nodes.remove(n)
    vol = nodes.new("ShaderNodeVolumePrincipled")
    vol.inputs["Density"].default_value = 5.0  # per kg/m³ of smoke and metre: tune to taste
    vol.inputs["Density Attribute"].default_value = "density"
    links.new(vol.outputs["Volume"], nodes.new("ShaderNodeOutputMaterial").inputs["Volume"])
    return mat


def surface_material(name):
    mat = bpy.data.materials.new(f"tetfsi_{name}")
    mat.diffuse_color = (0.05, 0.25, 0.8, 1) if name == "liquid" else (0.8, 0.3, 0.08, 1)
    mat.use_nodes = True
    # Built node by node: the default tree depends on the active object (a Principled Volume
    # when it is a volume).
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    for n in list(nodes):
        nodes.remove(n)
    bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = mat.diffuse_color
    links.new(bsdf.outputs["BSDF"], nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    return mat


def load(out):
    scene = bpy.context.scene
    vdbs = sorted(glob.glob(os.path.join(out, "vdb", "fluid_[0-9]*.vdb")))
    plys = sorted(glob.glob(os.path.join(out, "ply", "*_[0-9]*.ply")))
    if not vdbs and not plys:
        raise SystemExit(f"blender_load_export: {out}: no vdb/fluid_*.vdb and no ply/*.ply")
    last = 0
    if vdbs:
        directory = os.path.dirname(vdbs[0]) + os.sep
        bpy.ops.object.volume_import(filepath=vdbs[0], directory=directory,
                                     files=[{"name": os.path.basename(p)} for p in vdbs])
        obj = bpy.context.view_layer.objects.active
        obj.name = "fluid"
        obj.data.materials.append(smoke_material())
        obj.data.grids.load()
        grid = obj.data.grids.get("density") or (obj.data.grids[0] if len(obj.data.grids)
                                                  else None)
        if grid is not None:
            h = [grid.matrix_object[i][i] for i in range(3)]
            obj.location = [-0.5 * x for x in h]
        last = max(last, len(vdbs) - 1)
    series = {}
    for path in plys:
        match = PLY_NAME.match(os.path.basename(path))
        if match:
            series.setdefault(match.group(1), []).append((int(match.group(2)), path))
    for name, frames in sorted(series.items()):
        prefix = f"tetfsi_{name}_"
        material = surface_material(name)  # one per surface, on each of its meshes
        for number, path in frames:
            before = set(bpy.data.objects)
            bpy.ops.import_mesh.ply(filepath=path)
            for imported in [o for o in bpy.data.objects if o not in before]:
                mesh = imported.data
                bpy.data.objects.remove(imported)
                mesh.name = f"{prefix}{number:06d}"
                mesh.materials.append(material)
                mesh.use_fake_user = True  # kept in the .blend while no object shows it
        obj = bpy.data.objects.new(name, bpy.data.meshes[f"{prefix}{frames[0][0]:06d}"])
        obj["tetfsi_meshes"] = prefix
        scene.collection.objects.link(obj)
        last = max(last, frames[-1][0])
    manifest = os.path.join(out, "export.json")
    if os.path.isfile(manifest):
        with open(manifest) as f:
            times = [fr.get("time") for fr in json.load(f).get("frames", [])]
        if len(times) >= 2 and times[1] > times[0]:
            fps = 1.0 / (times[1] - times[0])  # Blender plays fps / fps_base frames a second
            scene.render.fps = max(int(math.ceil(fps - 1e-9)), 1)
            scene.render.fps_base = scene.render.fps / fps
    scene.frame_start, scene.frame_end = 1, last + 1
    # This file, stored and registered in the .blend: the handler returns when it is opened.
    text = bpy.data.texts.get(HANDLER + ".py") or bpy.data.texts.new(HANDLER + ".py")
    text.from_string(open(__file__).read() if os.path.isfile(__file__) else "")
    text.use_module = True
    register()
    scene.frame_set(scene.frame_start)
    print(f"blender_load_export: {out}: {len(vdbs)} volumes, "
          f"{', '.join(f'{n} ({len(f)} meshes)' for n, f in sorted(series.items())) or 'no meshes'}"
          f"; frames 1-{last + 1} at {scene.render.fps / scene.render.fps_base:.4g} fps")


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    out = argv[0] if argv else OUT
    if not out:
        # The registered text of a .blend being opened (Blender runs it as __main__ too), or a
        # call without OUT: only the handler.
        register()
        print("blender_load_export: the frame handler is registered (to load an export: "
              "blender -P scripts/blender_load_export.py -- OUT [--blend FILE])")
        return
    load(os.path.abspath(out))
    if "--blend" in argv:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(argv[argv.index("--blend") + 1]))


if __name__ == "__main__":
    main()
