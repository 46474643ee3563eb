#!/usr/bin/env python3
"""Writes the small sample meshes of data/meshes/ that tests/mesh/test_io.cpp reads.

Run from anywhere: python3 data/meshes/make_samples.py. Pure Python, deterministic.

Volume meshes: one bar [0,1] x [0,0.1] x [0,0.1] m cut into 10 x 1 x 1 cubes, each split into
6 Kuhn tets: 60 tets, 44 used nodes, volume 0.01 m^3, in every volume format:
  bar_v2.msh      Gmsh ASCII 2.2: node tags 1..45 (45 is unused), plus triangle/point
                  elements that the reader ignores, and a $PhysicalNames section to skip
  bar_v4.msh      Gmsh ASCII 4.1, the same mesh: non-contiguous node tags in 3 entity blocks,
                  non-contiguous element tags, an $Entities section; same node order, so it
                  reads to the identical VolumeMesh
  bar.node/.ele   TetGen, 1-based, comments, attributes and boundary markers, every tet written
                  with the opposite orientation (the reader flips them all back)
  bar.vtu         VTK XML ASCII with one extra VTK_TRIANGLE cell (ignored)
  bar_inverted.msh  Gmsh 2.2 with element 23 (the 23rd tet) inverted
Surfaces:
  icosphere.off   radius 0.5, 2 subdivisions: 162 vertices, 320 triangles, header comment
  cube.obj        unit cube as 6 quads, 'f a/b/c', 'a//c' and negative indices
  cube.stl        ASCII STL of the unit cube (12 triangles, 36 corners -> 8 vertices)
  cube_binary.stl binary STL of the unit cube whose 80-byte header starts with "solid"
  open_cube.off   unit cube with its top quad missing (open surface)
"""
import math
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def kuhn_bar(nx=10, lx=1.0, ly=0.1, lz=0.1):
    nvx, nvy, nvz = nx + 1, 2, 2
    pts = []
    for k in range(nvz):
        for j in range(nvy):
            for i in range(nvx):
                pts.append((lx * i / nx, ly * j, lz * k))
    perms = [(0, 1, 2), (1, 2, 0), (2, 0, 1), (0, 2, 1), (2, 1, 0), (1, 0, 2)]
    tets = []
    for i in range(nx):
        for p, perm in enumerate(perms):
            code, path = 0, [0]
            for a in perm:
                code |= 1 << a
                path.append(code)
            if p >= 3:  # odd permutation: swap to make it positive
                path[1], path[2] = path[2], path[1]
            tet = []
            for c in path:
                ii, jj, kk = i + (c & 1), (c >> 1) & 1, (c >> 2) & 1
                tet.append(ii + nvx * (jj + nvy * kk))
            tets.append(tet)
    return pts, tets


def vol(p, t):
    a, b, c, d = (p[i] for i in t)
    u = [b[i] - a[i] for i in range(3)]
    v = [c[i] - a[i] for i in range(3)]
    w = [d[i] - a[i] for i in range(3)]
    return (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
            + u[2] * (v[0] * w[1] - v[1] * w[0])) / 6.0


def fmt(x):
    return repr(float(x))


def write(name, text, mode="w"):
    with open(os.path.join(HERE, name), mode) as f:
        f.write(text)


def gmsh_v2(pts, tets, inverted=None):
    unused = (2.0, 2.0, 2.0)
    out = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat",
           "$PhysicalNames", "1", '3 1 "bar"', "$EndPhysicalNames",
           "$Nodes", str(len(pts) + 1)]
    for i, p in enumerate(pts + [unused]):
        out.append(f"{i + 1} {fmt(p[0])} {fmt(p[1])} {fmt(p[2])}")
    out += ["$EndNodes", "$Elements", str(len(tets) + 3)]
    out.append(f"1 15 2 0 1 {len(pts) + 1}")  # point element on the unused node
    out.append("2 2 2 0 1 1 2 13")            # two boundary triangles (ignored)
    out.append("3 2 2 0 1 2 14 13")
    for t, tet in enumerate(tets):
        tet = list(tet)
        if inverted is not None and t + 1 == inverted:
            tet[2], tet[3] = tet[3], tet[2]
        out.append(f"{t + 4} 4 2 1 1 " + " ".join(str(v + 1) for v in tet))
    out.append("$EndElements")
    return "\n".join(out) + "\n"


def gmsh_v4(pts, tets):
    tag = lambda i: 10 * i + 7  # non-contiguous node tags  # noqa: E731
    n = len(pts) + 1
    unused = (2.0, 2.0, 2.0)
    allp = pts + [unused]
    out = ["$MeshFormat", "4.1 0 8", "$EndMeshFormat",
           "$Entities", "1 0 0 1",
           "1 2 2 2",
           "1 0 0 0 1 0.1 0.1 0",
           "$EndEntities",
           "$Nodes", f"3 {n} {tag(0)} {tag(n - 1)}"]
    blocks = [(3, 1, 0, 20), (3, 1, 20, len(pts)), (0, 1, len(pts), n)]
    for dim, ent, b, e in blocks:
        out.append(f"{dim} {ent} 0 {e - b}")
        out += [str(tag(i)) for i in range(b, e)]
        out += [f"{fmt(allp[i][0])} {fmt(allp[i][1])} {fmt(allp[i][2])}" for i in range(b, e)]
    out.append("$EndNodes")
    nel = len(tets) + 3
    out += ["$Elements", f"4 {nel} 1 {1000 + len(tets)}"]
    out += ["0 1 15 1", f"1 {tag(n - 1)}"]
    out += ["2 1 2 2", f"2 {tag(0)} {tag(1)} {tag(12)}", f"3 {tag(1)} {tag(13)} {tag(12)}"]
    half = len(tets) // 2
    for b, e in ((0, half), (half, len(tets))):
        out.append(f"3 1 4 {e - b}")
        for t in range(b, e):
            out.append(f"{1000 + 3 * t} " + " ".join(str(tag(v)) for v in tets[t]))
    out.append("$EndElements")
    return "\n".join(out) + "\n"


def tetgen(pts, tets):
    node = ["# bar.node: written by make_samples.py", f"{len(pts)} 3 1 1  # points dim attrs markers"]
    for i, p in enumerate(pts):
        node.append(f"{i + 1}  {fmt(p[0])} {fmt(p[1])} {fmt(p[2])}  0.5  {1 if p[0] in (0.0, 1.0) else 0}")
    ele = ["# bar.ele: every tet written with the opposite orientation",
           f"{len(tets)} 4 1"]
    for t, tet in enumerate(tets):
        a, b, c, d = tet
        ele.append(f"{t + 1}  {a + 1} {b + 1} {d + 1} {c + 1}  7")
    return "\n".join(node) + "\n", "\n".join(ele) + "\n"


def vtu(pts, tets):
    conn = [v for t in tets for v in t] + [0, 1, 12]
    offsets = [4 * (i + 1) for i in range(len(tets))] + [4 * len(tets) + 3]
    types = [10] * len(tets) + [5]
    ncells = len(tets) + 1
    coords = " ".join(f"{fmt(p[0])} {fmt(p[1])} {fmt(p[2])}" for p in pts)
    return f"""<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">
  <UnstructuredGrid>
    <Piece NumberOfPoints="{len(pts)}" NumberOfCells="{ncells}">
      <Points>
        <DataArray type="Float64" NumberOfComponents="3" format="ascii">{coords}</DataArray>
      </Points>
      <Cells>
        <DataArray type="Int64" Name="connectivity" format="ascii">{" ".join(map(str, conn))}</DataArray>
        <DataArray type="Int64" Name="offsets" format="ascii">{" ".join(map(str, offsets))}</DataArray>
        <DataArray type="UInt8" Name="types" format="ascii">{" ".join(map(str, types))}</DataArray>
      </Cells>
    </Piece>
  </UnstructuredGrid>
</VTKFile>
"""


def icosphere(subdiv=2, radius=0.5):
    t = (1.0 + math.sqrt(5.0)) / 2.0
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t),
         (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    v = [tuple(c / math.sqrt(sum(x * x for x in p)) for c in p) for p in v]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
         (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(subdiv):
        cache, nf = {}, []

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                p = [(v[a][i] + v[b][i]) / 2 for i in range(3)]
                n = math.sqrt(sum(x * x for x in p))
                v.append(tuple(x / n for x in p))
                cache[key] = len(v) - 1
            return cache[key]
        for a, b, c in f:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            nf += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        f = nf
    v = [tuple(radius * x for x in p) for p in v]
    return v, f


CUBE_V = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
# Outward quads (counter-clockwise seen from outside), zero-based.
CUBE_Q = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]


def cube_tris():
    return [(q[0], q[i], q[i + 1]) for q in CUBE_Q for i in (1, 2)]


def off(vs, fs, comment):
    out = ["OFF", f"# {comment}", f"{len(vs)} {len(fs)} 0"]
    out += [" ".join(fmt(c) for c in p) for p in vs]
    out += [f"{len(f)} " + " ".join(map(str, f)) for f in fs]
    return "\n".join(out) + "\n"


def obj_cube():
    out = ["# unit cube: quads, mixed face-vertex formats, negative indices", "o cube"]
    out += [f"v {p[0]} {p[1]} {p[2]}" for p in CUBE_V]
    out += ["vt 0 0", "vn 0 0 1"]
    for n, q in enumerate(CUBE_Q):
        if n == 0:
            out.append("f " + " ".join(str(i + 1) for i in q))
        elif n == 1:
            out.append("f " + " ".join(f"{i + 1}/1/1" for i in q))
        elif n == 2:
            out.append("f " + " ".join(f"{i + 1}//1" for i in q))
        else:  # negative: relative to the 8 vertices defined so far
            out.append("f " + " ".join(f"{i - 8}/1" for i in q))
    return "\n".join(out) + "\n"


def normal(a, b, c):
    u = [b[i] - a[i] for i in range(3)]
    v = [c[i] - a[i] for i in range(3)]
    n = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
    ln = math.sqrt(sum(x * x for x in n))
    return tuple(x / ln for x in n)


def stl_ascii():
    out = ["solid cube"]
    for t in cube_tris():
        a, b, c = (CUBE_V[i] for i in t)
        n = normal(a, b, c)
        out.append(f"  facet normal {n[0]} {n[1]} {n[2]}")
        out.append("    outer loop")
        for p in (a, b, c):
            out.append(f"      vertex {p[0]:e} {p[1]:e} {p[2]:e}")
        out += ["    endloop", "  endfacet"]
    out.append("endsolid cube")
    return "\n".join(out) + "\n"


def stl_binary():
    tris = cube_tris()
    data = b"solid cube (binary; this header must not fool the reader)".ljust(80, b" ")
    data += struct.pack("<I", len(tris))
    for t in tris:
        a, b, c = (CUBE_V[i] for i in t)
        data += struct.pack("<12fH", *normal(a, b, c), *a, *b, *c, 0)
    return data


def main():
    pts, tets = kuhn_bar()
    assert all(vol(pts, t) > 0 for t in tets)
    assert abs(sum(vol(pts, t) for t in tets) - 0.01) < 1e-15
    write("bar_v2.msh", gmsh_v2(pts, tets))
    write("bar_v4.msh", gmsh_v4(pts, tets))
    write("bar_inverted.msh", gmsh_v2(pts, tets, inverted=23))
    node, ele = tetgen(pts, tets)
    write("bar.node", node)
    write("bar.ele", ele)
    write("bar.vtu", vtu(pts, tets))
    v, f = icosphere()
    write("icosphere.off", off(v, f, "icosphere, radius 0.5, 2 subdivisions"))
    write("cube.obj", obj_cube())
    write("cube.stl", stl_ascii())
    write("cube_binary.stl", stl_binary(), "wb")
    write("open_cube.off", off(CUBE_V, CUBE_Q[:1] + CUBE_Q[2:], "unit cube without its top"))


if __name__ == "__main__":
    main()
