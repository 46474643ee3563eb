"""Load one frame of a tetfsi export in Blender, check it, and render it with Cycles.

Runs inside Blender, headless:

    blender -b --factory-startup -noaudio --python-exit-code 2 \
        -P scripts/blender_check.py -- OUT --frame N|last --png PATH \
        [--samples S] [--size WxH] [--report JSON] [--blend FILE]

OUT is a run's folder with the export of `tetfsi run` (scene key `output.export`) or of
`tetfsi export OUT`: OUT/export.json, OUT/vdb/fluid_<frame>.vdb, OUT/ply/<name>_<frame>.ply.
Exit code 0 when every check passes; 1 with one line `blender_check: FAIL: ...` on stderr when
a check fails; 2 when the script itself breaks (a traceback, then the one line; Blender returns
2 for an uncaught exception only with --python-exit-code 2, hence that option above).

What is checked, in Blender, against the manifest OUT/export.json:
 (a) the volume: Blender reads the .vdb; its grids include every grid the manifest lists, with
     the same value type and voxel size; the `density` grid's active region as Blender sees it
     (the Volume to Mesh modifier's surface at half the manifest's smallest active value) lies
     within one voxel of the manifest's bounds on each of the six sides; the object's bounding
     box (Blender takes it from the grids' 8³ leaf nodes, not from the active voxels) holds the
     manifest's active voxels and exceeds them by less than one leaf (8 voxels).
 (b) the meshes: each PLY imports with the manifest's vertex and triangle counts (Blender 3.4's
     PLY importer keeps the file's vertices: it merges none), every face a triangle, and the
     vertices exactly the file's (read here with numpy: same order, same axes, no rescaling);
     a body's surface is closed (every edge in two triangles). With a liquid, the `surface`
     level set as Blender meshes it (φ = 0) lies within one voxel of the liquid's PLY.
 (c) the picture: the frame rendered with Cycles on the CPU (a camera framing the smoke and the
     meshes, a sun, a Principled Volume reading `density`) to PATH, and the same view without
     the volume to PATH's `_nosmoke.png`; both PNGs read back and compared (check_image below).

Blender 3.4 (Debian 12's) draws and renders an OpenVDB voxel half a voxel off: it takes voxel
(i, j, k) to cover index space [i, i+1] where OpenVDB (and tetfsi, and Houdini) centres it on
(i, j, k) (measured: a one-voxel grid at index (10, 10, 10), voxel size 1, renders and meshes
centred on (10.5, 10.5, 10.5)). The volume object is therefore moved by −h/2 on each axis so that
the smoke sits where the manifest and the PLY meshes say (`--voxel-shift 0` turns that off).
"""

import argparse
import json
import math
import os
import sys
import time
import traceback

import bpy
import numpy as np
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

PREFIX = "blender_check:"


class CheckFailed(Exception):
    """A check that did not pass: one line, exit code 1."""


# ---- the manifest ------------------------------------------------------------------------
# Every key of export.json this script reads, spelled once here (io/export.cpp's to_json
# writes them). A key may have alternative spellings, tried in order.
KEYS = {
    "frames": ("frames",),
    "frame": ("frame",),
    "step": ("step",),
    "time": ("time",),
    "vdb_file": ("vdb_file", "vdb"),
    "grids": ("grids",),
    "voxel_size": ("voxel_size",),
    "smoke_mass": ("smoke_mass",),
    "meshes": ("meshes",),
    # a grid
    "grid_name": ("name",),
    "grid_type": ("type",),
    "grid_class": ("class", "grid_class"),
    "active_voxels": ("active_voxels",),
    "min": ("min",),
    "max": ("max",),
    "bounds": ("bounds",),
    "unit": ("unit",),
    # a mesh
    "mesh_name": ("name",),
    "mesh_file": ("file",),
    "vertices": ("vertices",),
    "triangles": ("triangles",),
}
_MISSING = object()


def get(obj, key, where, default=_MISSING):
    """obj's value for the logical key `key` (KEYS), or default; fails naming `where`."""
    if not isinstance(obj, dict):
        raise CheckFailed(f"export.json: {where} is not an object")
    for spelling in KEYS[key]:
        if spelling in obj:
            return obj[spelling]
    if default is not _MISSING:
        return default
    raise CheckFailed(f"export.json: {where} has no key {' or '.join(map(repr, KEYS[key]))} "
                      f"(it has {', '.join(sorted(obj)) or 'none'})")


# OpenVDB's value type names as the manifest writes them -> Blender's VolumeGrid.data_type.
BLENDER_GRID_TYPE = {"float": "FLOAT", "double": "DOUBLE", "int32": "INT", "int64": "INT64",
                     "vec3s": "VECTOR_FLOAT", "vec3d": "VECTOR_DOUBLE", "vec3i": "VECTOR_INT",
                     "bool": "BOOLEAN", "mask": "MASK"}


def as_box(value, where):
    """Bounds as (lo, hi) numpy 3-vectors from [x0, y0, z0, x1, y1, z1] or {min/lo, max/hi}."""
    if isinstance(value, dict):
        lo = value.get("min", value.get("lo"))
        hi = value.get("max", value.get("hi"))
    elif isinstance(value, list) and len(value) == 6:
        lo, hi = value[:3], value[3:]
    else:
        lo = hi = None
    if lo is None or hi is None:
        raise CheckFailed(f"export.json: {where}: expected [x0, y0, z0, x1, y1, z1], got {value!r}")
    return np.array(lo, float), np.array(hi, float)


def as_vec3(value, where):
    if isinstance(value, (int, float)):
        return np.full(3, float(value))
    if isinstance(value, list) and len(value) == 3:
        return np.array(value, float)
    raise CheckFailed(f"export.json: {where}: expected a number or [hx, hy, hz], got {value!r}")


def read_frame(out, number):
    """The manifest's frame `number` as a plain dict of what the checks use."""
    path = os.path.join(out, "export.json")
    try:
        with open(path) as f:
            manifest = json.load(f)
    except OSError as e:
        raise CheckFailed(f"{path}: cannot read it ({e.strerror})")
    except json.JSONDecodeError as e:
        raise CheckFailed(f"{path}: not JSON ({e})")
    frames = get(manifest, "frames", "the top level")
    numbers = [get(f, "frame", f"frames[{i}]") for i, f in enumerate(frames)]
    if not numbers:
        raise CheckFailed(f"{path}: no frames")
    if number is None:  # --frame last
        number = max(numbers)
    if number not in numbers:
        raise CheckFailed(f"{path}: no frame {number} (it has frames {numbers[:3]}..."
                          f"{numbers[-3:]})" if len(numbers) > 6 else
                          f"{path}: no frame {number} (it has frames {numbers})")
    raw = frames[numbers.index(number)]
    where = f"frame {number}"
    grids = []
    for i, g in enumerate(get(raw, "grids", where, [])):
        gw = f"{where}: grids[{i}]"
        grids.append({
            "name": get(g, "grid_name", gw), "type": get(g, "grid_type", gw),
            "class": get(g, "grid_class", gw, ""),
            "active_voxels": int(get(g, "active_voxels", gw)),
            "min": float(get(g, "min", gw)), "max": float(get(g, "max", gw)),
            "bounds": as_box(get(g, "bounds", gw), gw + ": bounds"),
            "unit": get(g, "unit", gw, "")})
    meshes = []
    for i, m in enumerate(get(raw, "meshes", where, [])):
        mw = f"{where}: meshes[{i}]"
        meshes.append({"name": get(m, "mesh_name", mw), "file": get(m, "mesh_file", mw),
                       "vertices": int(get(m, "vertices", mw)),
                       "triangles": int(get(m, "triangles", mw))})
    vdb = get(raw, "vdb_file", where, "")
    return {"frame": number, "step": get(raw, "step", where), "time": get(raw, "time", where),
            "vdb_file": os.path.join(out, vdb) if vdb else "",
            "voxel_size": as_vec3(get(raw, "voxel_size", where), where + ": voxel_size")
            if vdb else None,
            "smoke_mass": get(raw, "smoke_mass", where, None),
            "grids": grids, "meshes": meshes}


# ---- the scene ---------------------------------------------------------------------------

def clear_scene():
    """An empty scene (factory start-up has a cube, a camera and a light)."""
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    for coll in (bpy.data.meshes, bpy.data.volumes, bpy.data.materials, bpy.data.cameras,
                 bpy.data.lights):
        for block in list(coll):
            coll.remove(block)


def link(obj):
    bpy.context.scene.collection.objects.link(obj)
    return obj


def world_box(obj):
    """The world-space axis-aligned box of obj's bounding box corners."""
    corners = np.array([(obj.matrix_world @ Vector(c))[:] for c in obj.bound_box])
    return corners.min(0), corners.max(0)


def fmt3(v):
    return "(" + ", ".join(f"{x:.4g}" for x in v) + ")"


def load_volume(frame, voxel_shift):
    """The frame's .vdb as a volume object; checks (a) on its grids. Returns (obj, h)."""
    path = frame["vdb_file"]
    if not os.path.isfile(path):
        raise CheckFailed(f"{path}: missing (listed in export.json for frame {frame['frame']})")
    vol = bpy.data.volumes.new("fluid")
    vol.filepath = path
    if not vol.grids.load():
        raise CheckFailed(f"{path}: Blender cannot read it: {vol.grids.error_message}")
    obj = link(bpy.data.objects.new("fluid", vol))
    blender_grids = {g.name: g for g in vol.grids}
    h = frame["voxel_size"]
    for g in frame["grids"]:
        bg = blender_grids.get(g["name"])
        if bg is None:
            raise CheckFailed(f"{path}: Blender finds no grid '{g['name']}' (it finds "
                              f"{', '.join(sorted(blender_grids)) or 'none'})")
        want = BLENDER_GRID_TYPE.get(g["type"])
        if want is not None and bg.data_type != want:
            raise CheckFailed(f"{path}: grid '{g['name']}' is {bg.data_type} in Blender, "
                              f"{g['type']} in export.json")
        scale = np.array([bg.matrix_object[i][i] for i in range(3)])
        if not np.allclose(scale, h, rtol=1e-5):
            raise CheckFailed(f"{path}: grid '{g['name']}' has voxels of {fmt3(scale)} m in "
                              f"Blender, {fmt3(h)} m in export.json")
    obj.location = Vector(-voxel_shift * h)
    bpy.context.view_layer.update()
    return obj, h


def volume_to_mesh_points(obj, grid, threshold):
    """The vertices (#, 3; world, m) of Blender's Volume to Mesh of grid `grid` of the volume
    object at `threshold` (a fog volume: the surface around the values above it; a level set:
    its φ = threshold surface)."""
    mesh_obj = link(bpy.data.objects.new(f"{grid}_surface", bpy.data.meshes.new(grid)))
    mod = mesh_obj.modifiers.new("volume_to_mesh", "VOLUME_TO_MESH")
    mod.object = obj
    mod.grid_name = grid
    mod.resolution_mode = "GRID"
    mod.threshold = threshold
    mod.adaptivity = 0.0
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = mesh_obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    co = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", co)
    evaluated.to_mesh_clear()
    bpy.data.objects.remove(mesh_obj)
    return co.reshape(-1, 3)


def check_volume_bounds(obj, frame, h, voxel_shift):
    """(a) The volume's extent against the manifest's bounds; returns the density grid's box."""
    path = frame["vdb_file"]
    active = [g for g in frame["grids"] if g["active_voxels"] > 0]
    if active:
        # Blender's bounding box of a volume: the union over its grids of their leaf nodes'
        # voxel centres (OpenVDB's evalLeafBoundingBox), in object space. It holds every
        # active voxel's centre and exceeds their box by at most 7 voxels on a side.
        lo_c = np.min([g["bounds"][0] + h / 2 for g in active], axis=0)
        hi_c = np.max([g["bounds"][1] - h / 2 for g in active], axis=0)
        corners = np.array([c[:] for c in obj.bound_box])
        lo_b, hi_b = corners.min(0), corners.max(0)
        eps = 1e-3 * h
        bad = ((lo_b > lo_c + eps) | (lo_b < lo_c - 7 * h - eps) |
               (hi_b < hi_c - eps) | (hi_b > hi_c + 7 * h + eps))
        if bad.any():
            raise CheckFailed(
                f"{path}: Blender's bounding box {fmt3(lo_b)}-{fmt3(hi_b)} m does not hold the "
                f"active voxels' centres {fmt3(lo_c)}-{fmt3(hi_c)} m within one 8-voxel leaf")
    density = next((g for g in frame["grids"] if g["name"] == "density"), None)
    if density is None or density["active_voxels"] == 0:
        return None
    # The density grid as Blender reads its values: the Volume to Mesh modifier's surface at
    # half the smallest active value wraps exactly the active voxels (the background is 0), so
    # its box must lie within one voxel of the manifest's (the active voxels' outer faces).
    threshold = 0.5 * density["min"]
    co = volume_to_mesh_points(obj, "density", threshold)
    if co.size == 0:
        raise CheckFailed(f"{path}: Blender's Volume to Mesh finds no density above "
                          f"{threshold:.3g} (export.json: {density['active_voxels']} active "
                          f"voxels, {density['min']:.3g} to {density['max']:.3g})")
    co = co.reshape(-1, 3)
    lo_m, hi_m = co.min(0), co.max(0)
    lo_d, hi_d = density["bounds"]
    off = np.max(np.abs(np.concatenate([lo_m - lo_d, hi_m - hi_d])) / np.concatenate([h, h]))
    if off > 1.0:
        raise CheckFailed(
            f"{path}: the density Blender reads spans {fmt3(lo_m)}-{fmt3(hi_m)} m, export.json "
            f"says {fmt3(lo_d)}-{fmt3(hi_d)} m: {off:.2f} voxels apart (at most 1)")
    print(f"{PREFIX} density: Blender's extent {fmt3(lo_m)}-{fmt3(hi_m)} m, export.json's "
          f"{fmt3(lo_d)}-{fmt3(hi_d)} m, {off:.2f} voxels apart at most")
    return lo_d, hi_d, off


PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "<i2",
             "int16": "<i2", "ushort": "<u2", "uint16": "<u2", "int": "<i4", "int32": "<i4",
             "uint": "<u4", "uint32": "<u4", "float": "<f4", "float32": "<f4",
             "double": "<f8", "float64": "<f8"}


def read_ply_points(path):
    """The vertices' x, y, z of a binary little-endian PLY whose vertex element comes first
    and has scalar properties only (as write_ply writes them), else None: what Blender's
    importer is compared against."""
    with open(path, "rb") as f:
        header = []
        while True:
            line = f.readline()
            if not line:
                return None
            line = line.decode("ascii", "replace").strip()
            header.append(line.split())
            if line == "end_header":
                break
        if ["format", "binary_little_endian", "1.0"] not in header:
            return None
        elements = [i for i, w in enumerate(header) if w[:1] == ["element"]]
        if not elements or header[elements[0]][1] != "vertex":
            return None
        count = int(header[elements[0]][2])
        fields = []
        for w in header[elements[0] + 1:]:
            if w[:1] != ["property"]:
                break
            if len(w) != 3 or w[1] not in PLY_TYPES:
                return None  # a list property in the vertex element: not our layout
            fields.append((w[2], PLY_TYPES[w[1]]))
        data = np.fromfile(f, dtype=np.dtype(fields), count=count)
    if len(data) != count or not {"x", "y", "z"} <= set(data.dtype.names):
        return None
    return np.stack([data["x"], data["y"], data["z"]], axis=1).astype(float)


def load_meshes(out, frame):
    """(b) Each PLY of the frame imported and counted; returns [(name, obj)]."""
    objects = []
    for m in frame["meshes"]:
        path = os.path.join(out, m["file"])
        if not os.path.isfile(path):
            raise CheckFailed(f"{path}: missing (listed in export.json for frame "
                              f"{frame['frame']})")
        before = set(bpy.data.objects)
        result = bpy.ops.import_mesh.ply(filepath=path)
        new = [o for o in bpy.data.objects if o not in before and o.type == "MESH"]
        if result != {"FINISHED"} or len(new) != 1:
            raise CheckFailed(f"{path}: Blender's PLY importer failed ({result})")
        obj = new[0]
        mesh = obj.data
        nv, nf = len(mesh.vertices), len(mesh.polygons)
        if nv != m["vertices"] or nf != m["triangles"]:
            raise CheckFailed(f"{path}: Blender imports {nv} vertices and {nf} faces, export.json "
                              f"says {m['vertices']} and {m['triangles']}")
        sizes = np.empty(nf, np.int32)
        mesh.polygons.foreach_get("loop_total", sizes)
        if nf and (sizes != 3).any():
            raise CheckFailed(f"{path}: {int((sizes != 3).sum())} faces are not triangles")
        co = np.empty(nv * 3)
        mesh.vertices.foreach_get("co", co)
        if not np.isfinite(co).all():
            raise CheckFailed(f"{path}: non-finite vertex coordinates")
        # Blender's vertices are the file's, in its order and axes (no merging, no axis swap).
        points = read_ply_points(path)
        if points is not None:
            off = float(np.abs(co.reshape(-1, 3) - points).max()) if nv else 0.0
            # float32 in Blender: a file of doubles is rounded to float.
            if len(points) != nv or off > 1e-6 * max(1.0, float(np.abs(points).max())):
                raise CheckFailed(f"{path}: Blender's vertices differ from the file's "
                                  f"(by up to {off:.3g} m)" if len(points) == nv else
                                  f"{path}: the file has {len(points)} vertices")
        # A body's surface is the boundary of its tets: closed, every edge in two triangles (a
        # renderer's inside and outside, a volume or glass material, depend on it). The liquid's
        # is its free surface, closed by caps on the box's walls; open edges are counted only.
        loops = np.empty(nf * 3, np.int64)
        mesh.loops.foreach_get("vertex_index", loops)
        tri = loops.reshape(-1, 3)
        edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
        _, uses = np.unique(edges, axis=0, return_counts=True)
        open_edges, odd_edges = int((uses == 1).sum()), int((uses > 2).sum())
        if m["name"] != "liquid" and (open_edges or odd_edges):
            raise CheckFailed(f"{path}: the surface is not closed: {open_edges} edges in one "
                              f"triangle, {odd_edges} in more than two")
        obj.name = m["name"]
        objects.append((m["name"], obj))
        print(f"{PREFIX} {m['file']}: {nv} vertices, {nf} triangles"
              + (", the file's coordinates" if points is not None else
                 " (coordinates not compared: not write_ply's layout)")
              + (f", {open_edges} open edges" if open_edges else ", closed"))
    return objects


def check_liquid_surface(volume, frame, h, liquid):
    """The `surface` level set as Blender meshes it (φ = 0) against the liquid's PLY: their
    boxes within one voxel on each side (both are the liquid's surface at one frame)."""
    grid = next((g for g in frame["grids"] if g["name"] == "surface"), None)
    if grid is None or grid["active_voxels"] == 0 or liquid is None:
        return None
    path = frame["vdb_file"]
    co = volume_to_mesh_points(volume, "surface", 0.0)
    if co.size == 0:
        raise CheckFailed(f"{path}: Blender's Volume to Mesh finds no φ = 0 surface in the "
                          f"level set 'surface' (export.json: {grid['active_voxels']} active "
                          f"voxels, {grid['min']:.3g} to {grid['max']:.3g} m)")
    lo_m, hi_m = co.min(0), co.max(0)
    lo_l, hi_l = world_box(liquid)
    off = np.max(np.abs(np.concatenate([lo_m - lo_l, hi_m - hi_l])) / np.concatenate([h, h]))
    if off > 1.0:
        raise CheckFailed(
            f"{path}: the level set 'surface' as Blender meshes it spans {fmt3(lo_m)}-"
            f"{fmt3(hi_m)} m, the liquid's PLY {fmt3(lo_l)}-{fmt3(hi_l)} m: {off:.2f} voxels "
            f"apart (at most 1)")
    print(f"{PREFIX} surface: Blender's φ = 0 surface {fmt3(lo_m)}-{fmt3(hi_m)} m, the liquid's "
          f"PLY {fmt3(lo_l)}-{fmt3(hi_l)} m, {off:.2f} voxels apart at most")
    return off


def smoke_material(density, scale=None):
    """A Principled Volume reading the `density` grid, scaled (unless `scale` is given) so that
    the densest smoke across the smoke's narrowest extent has an optical depth of about 10
    (a dense core, a thin halo where the density falls off)."""
    if scale is None:
        lo, hi = density["bounds"]
        thickness = max(float(np.min(hi - lo)), 1e-6)
        scale = 10.0 / (max(density["max"], 1e-12) * thickness)
    mat = bpy.data.materials.new("smoke")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    for n in list(nodes):
        nodes.remove(n)
    out = nodes.new("ShaderNodeOutputMaterial")
    vol = nodes.new("ShaderNodeVolumePrincipled")
    vol.inputs["Color"].default_value = (0.85, 0.85, 0.85, 1.0)
    vol.inputs["Density"].default_value = scale
    vol.inputs["Density Attribute"].default_value = "density"
    links.new(vol.outputs["Volume"], out.inputs["Volume"])
    return mat, scale


def surface_material(name, color, roughness):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    # Built node by node: the default tree depends on the active object (a Principled Volume
    # when it is a volume).
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    for n in list(nodes):
        nodes.remove(n)
    bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    links.new(bsdf.outputs["BSDF"], nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    return mat


def frame_camera(lo, hi, width, height):
    """A camera looking at the box lo-hi from the front (−y), a little from −x and above
    (z up, as in tetfsi's scenes), far enough back for the box's bounding sphere to fit."""
    centre = (lo + hi) / 2
    radius = max(float(np.linalg.norm(hi - lo)) / 2, 1e-3)
    cam = bpy.data.cameras.new("camera")
    cam.lens = 35.0
    cam.sensor_fit = "AUTO"
    # The smaller of the two angles of view (AUTO fits the sensor width to the longer side).
    fov = cam.angle * min(width, height) / max(width, height)
    direction = Vector((-0.35, -1.0, 0.45)).normalized()
    distance = 1.1 * radius / math.sin(fov / 2)
    obj = link(bpy.data.objects.new("camera", cam))
    obj.location = Vector(centre) + distance * direction
    obj.rotation_euler = (-direction).to_track_quat("-Z", "Y").to_euler()
    cam.clip_start = distance / 100
    cam.clip_end = distance * 10
    bpy.context.scene.camera = obj
    return obj


def set_up_render(scene, width, height, samples):
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.seed = 0
    import _cycles  # Debian's Blender 3.4 has no OpenImageDenoise: no denoiser then
    scene.cycles.use_denoising = bool(getattr(_cycles, "with_openimagedenoise", False))
    scene.cycles.max_bounces = 4
    scene.cycles.volume_bounces = 0
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.image_settings.color_depth = "8"
    scene.view_settings.view_transform = "Standard"
    world = bpy.data.worlds.new("world")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.01, 0.012, 0.02, 1)
    scene.world = world
    sun = bpy.data.lights.new("sun", "SUN")
    sun.energy = 4.0
    sun_obj = link(bpy.data.objects.new("sun", sun))
    # From above, in front and a little to the camera's left: the smoke and the sheets' faces
    # turned to the camera are lit.
    sun_obj.rotation_euler = Vector((0.3, 0.8, -1.0)).to_track_quat("-Z", "Y").to_euler()


def render_to(scene, path):
    scene.render.filepath = path
    t0 = time.monotonic()
    bpy.ops.render.render(write_still=True)
    if not os.path.isfile(path):
        raise CheckFailed(f"{path}: Cycles wrote no picture")
    return time.monotonic() - t0


def read_png(path):
    """A PNG as an (height, width) array of luminance in 0..1 (of its 8-bit sRGB values;
    row 0 at the bottom, as Blender and world_to_camera_view count)."""
    img = bpy.data.images.load(path, check_existing=False)
    w, hgt = img.size
    px = np.empty(w * hgt * 4, np.float32)
    img.pixels.foreach_get(px)
    bpy.data.images.remove(img)
    px = px.reshape(hgt, w, 4)
    return 0.2126 * px[..., 0] + 0.7152 * px[..., 1] + 0.0722 * px[..., 2]


def projected_rect(scene, cam, lo, hi, width, height, margin_px):
    """The pixel rectangle (x0, y0, x1, y1, half open, row 0 at the bottom) of the box lo-hi
    seen by cam, grown by margin_px."""
    corners = [Vector((x, y, z)) for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
               for z in (lo[2], hi[2])]
    uv = np.array([world_to_camera_view(scene, cam, c)[:2] for c in corners])
    x0 = max(int(math.floor(uv[:, 0].min() * width)) - margin_px, 0)
    x1 = min(int(math.ceil(uv[:, 0].max() * width)) + margin_px, width)
    y0 = max(int(math.floor(uv[:, 1].min() * height)) - margin_px, 0)
    y1 = min(int(math.ceil(uv[:, 1].max() * height)) + margin_px, height)
    return x0, y0, x1, y1


# The picture's checks and their thresholds (luminance in 0..1 of the 8-bit sRGB values):
#  - VISIBLE: the smoke changes the picture. Rendered twice with the same seed and samples,
#    with and without the volume (which casts no shadow, so it can only change the pixels whose
#    camera ray crosses it), the pixels that differ by more than CHANGED (0.05, 13 of 255 grey
#    levels; Cycles' noise at 16 samples in a pixel whose ray misses the volume is exactly 0,
#    since its path and random numbers are the same) cover at least VISIBLE_FRACTION (10 %) of
#    the smoke's projected rectangle: smoke of optical depth ~10 across the jet fills much of it.
#  - PLACED: at least PLACED_FRACTION (98 %) of the total change |with − without| lies inside
#    the projection of the manifest's density box grown by one voxel (Cycles interpolates
#    trilinearly: density reaches half a voxel past the active voxels' faces) and 2 pixels.
#  - BRIGHTER: the smoke is lit: the brightest tenth of the rectangle's changed pixels is
#    brighter than the four 8 × 8 corners of the picture (the empty background) by BRIGHTER
#    (0.15), and those corners are background: unchanged by the smoke and darker than 0.2
#    (the world's colour is 0.01-0.02 linear, about 0.11 once encoded as sRGB).
CHANGED = 0.05
VISIBLE_FRACTION = 0.10
PLACED_FRACTION = 0.98
BRIGHTER = 0.15
DARK_CORNER = 0.2


def check_image(png, png_nosmoke, rect):
    """(c) The rendered PNG against the one without smoke; returns the figures."""
    lum, lum0 = read_png(png), read_png(png_nosmoke)
    diff = np.abs(lum - lum0)
    x0, y0, x1, y1 = rect
    inside = np.zeros(lum.shape, bool)
    inside[y0:y1, x0:x1] = True
    area = int(inside.sum())
    changed = diff > CHANGED
    visible = float((changed & inside).sum()) / max(area, 1)
    total = float(diff.sum())
    placed = float(diff[inside].sum()) / total if total > 0 else 0.0
    c = 8
    corners = np.concatenate([lum[:c, :c].ravel(), lum[:c, -c:].ravel(),
                              lum[-c:, :c].ravel(), lum[-c:, -c:].ravel()])
    corner_change = float(np.concatenate([diff[:c, :c].ravel(), diff[:c, -c:].ravel(),
                                          diff[-c:, :c].ravel(), diff[-c:, -c:].ravel()]).max())
    smoke_pixels = np.sort(lum[changed & inside])[::-1]
    bright = float(smoke_pixels[:max(len(smoke_pixels) // 10, 1)].mean()) if len(
        smoke_pixels) else 0.0
    figures = {"rect": [x0, y0, x1, y1], "changed_fraction_in_rect": visible,
               "change_inside_rect": placed, "smoke_brightest_tenth": bright,
               "background_corners": float(corners.mean()), "corner_change": corner_change}
    print(f"{PREFIX} picture: {100 * visible:.1f} % of the smoke's rectangle {x0}-{x1} x "
          f"{y0}-{y1} px changed by the smoke (> {CHANGED}), {100 * placed:.2f} % of the change "
          f"inside it, smoke {bright:.3f} against background corners {corners.mean():.3f}")
    if visible < VISIBLE_FRACTION:
        raise CheckFailed(f"{png}: the smoke changes {100 * visible:.1f} % of its projected "
                          f"rectangle (at least {100 * VISIBLE_FRACTION:.0f} % expected)")
    if placed < PLACED_FRACTION:
        raise CheckFailed(f"{png}: {100 * (1 - placed):.1f} % of the smoke's change to the "
                          f"picture lies outside its projected bounds (at most "
                          f"{100 * (1 - PLACED_FRACTION):.0f} % expected)")
    if corners.mean() > DARK_CORNER or corner_change > CHANGED:
        raise CheckFailed(f"{png}: the corners are not background (luminance "
                          f"{corners.mean():.3f}, changed by the smoke by {corner_change:.3f})")
    if bright < corners.mean() + BRIGHTER:
        raise CheckFailed(f"{png}: the smoke ({bright:.3f}) is not brighter than the background "
                          f"({corners.mean():.3f}) by {BRIGHTER}")
    return figures


# ---- main --------------------------------------------------------------------------------

def parse_args(argv):
    p = argparse.ArgumentParser(prog="blender -b -P scripts/blender_check.py --",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("out", help="the run's folder (OUT/export.json)")
    p.add_argument("--frame", required=True, help="the frame number (0, 1, ...) or 'last'")
    p.add_argument("--png", required=True, help="the picture to write")
    p.add_argument("--samples", type=int, default=16)
    p.add_argument("--size", default="320x240", help="WxH pixels")
    p.add_argument("--voxel-shift", type=float, default=0.5,
                   help="move the volume by −shift voxels on each axis (0.5: Blender 3.4 "
                        "renders OpenVDB voxels half a voxel off)")
    p.add_argument("--density-scale", type=float,
                   help="the Principled Volume's density per kg/m³ of smoke (default: an optical "
                        "depth of about 10 across the smoke)")
    p.add_argument("--report", help="write the checks' figures to this JSON file")
    p.add_argument("--blend", help="save the scene to this .blend file (to look at it)")
    args = p.parse_args(argv)
    try:
        w, h = (int(x) for x in args.size.lower().split("x"))
        assert w >= 16 and h >= 16
    except (ValueError, AssertionError):
        p.error(f"--size {args.size}: expected WxH, at least 16x16")
    args.width, args.height = w, h
    if args.frame == "last":
        args.frame = None
    else:
        try:
            args.frame = int(args.frame)
        except ValueError:
            p.error(f"--frame {args.frame}: expected a frame number or 'last'")
    return args


def main(argv):
    args = parse_args(argv)
    t0 = time.monotonic()
    frame = read_frame(args.out, args.frame)
    report = {"frame": frame["frame"], "step": frame["step"], "time": frame["time"],
              "blender": bpy.app.version_string}
    clear_scene()
    scene = bpy.context.scene

    boxes = []  # what the camera frames: the smoke and the meshes
    volume = density_box = None
    density = next((g for g in frame["grids"] if g["name"] == "density"), None)
    if frame["vdb_file"]:
        volume, h = load_volume(frame, args.voxel_shift)
        found = check_volume_bounds(volume, frame, h, args.voxel_shift)
        if found:
            density_box = found[:2]
            boxes.append(density_box)
            report["density_extent_voxels_off"] = found[2]
        report["grids"] = [g.name for g in volume.data.grids]
    meshes = load_meshes(args.out, frame)
    report["meshes"] = {name: [len(o.data.vertices), len(o.data.polygons)] for name, o in meshes}
    bpy.context.view_layer.update()
    boxes += [world_box(o) for _, o in meshes]
    if volume is not None:
        off = check_liquid_surface(volume, frame, h, dict(meshes).get("liquid"))
        if off is not None:
            report["surface_extent_voxels_off"] = off
    if not boxes:
        raise CheckFailed(f"frame {frame['frame']}: nothing to render (no smoke, no mesh)")

    if volume is not None:
        if density_box is not None:
            mat, scale = smoke_material(density, args.density_scale)
            volume.data.materials.append(mat)
            report["density_scale"] = scale
        else:
            volume.hide_render = True  # no smoke this frame (a liquid's grids, or none yet)
        volume.visible_shadow = False  # the smoke changes only the pixels it covers
    for name, obj in meshes:
        liquid = name == "liquid"
        obj.data.materials.append(surface_material(
            name, (0.05, 0.25, 0.8) if liquid else (0.8, 0.3, 0.08), 0.2 if liquid else 0.6))

    lo = np.min([b[0] for b in boxes], axis=0)
    hi = np.max([b[1] for b in boxes], axis=0)
    cam = frame_camera(lo, hi, args.width, args.height)
    set_up_render(scene, args.width, args.height, args.samples)
    png = os.path.abspath(args.png)
    os.makedirs(os.path.dirname(png), exist_ok=True)
    if args.blend:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(args.blend))
    report["render_s"] = render_to(scene, png)
    print(f"{PREFIX} rendered {png} ({args.width}x{args.height}, {args.samples} samples) in "
          f"{report['render_s']:.1f} s")
    if density_box is not None:
        png0 = os.path.splitext(png)[0] + "_nosmoke.png"
        volume.hide_render = True
        report["render_nosmoke_s"] = render_to(scene, png0)
        vlo, vhi = density_box[0] - h, density_box[1] + h
        rect = projected_rect(scene, cam, vlo, vhi, args.width, args.height, 2)
        report["picture"] = check_image(png, png0, rect)
    else:
        print(f"{PREFIX} frame {frame['frame']} has no smoke (density: no active voxels): "
              f"the picture's smoke checks are skipped")
    report["total_s"] = time.monotonic() - t0
    if args.report:
        with open(args.report, "w") as f:
            json.dump(report, f, indent=1)
    print(f"{PREFIX} OK: frame {frame['frame']} (step {frame['step']}, t = {frame['time']} s): "
          f"{len(report.get('grids', []))} grids, {len(meshes)} meshes, {png} "
          f"({report['total_s']:.1f} s)")


if __name__ == "__main__":
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    try:
        main(argv)
    except CheckFailed as e:
        sys.stdout.flush()
        print(f"{PREFIX} FAIL: {e}", file=sys.stderr)
        sys.exit(1)
    except SystemExit:
        raise
    except Exception as e:  # a bug here, or Blender's: the traceback, then one line
        traceback.print_exc()
        sys.stdout.flush()
        print(f"{PREFIX} ERROR: {type(e).__name__}: {e}", file=sys.stderr)
        sys.exit(2)
